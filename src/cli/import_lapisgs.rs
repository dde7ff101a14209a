//! `splat2tiles import-lapisgs`: LapisGS-trained levels (one PLY per level) into a layered
//! tileset (format v2, `spec/layered-content.md`), with a summary of what was carried or dropped.

use super::convert::FrameArgs;
use clap::Args;
use splat2tiles_build::convert::{ConvertOptions, import_lapisgs};
use std::path::PathBuf;

/// Arguments of `import-lapisgs`.
#[derive(Debug, Args)]
#[command(
    after_help = "Each level's PLY must start with the previous level's splats, equal in every
property but opacity (LapisGS freezes them and trains only their opacity); the
level-k file's new splats follow. Give the files coarse to fine, e.g.:
  splat2tiles import-lapisgs res8/point_cloud.ply res4/point_cloud.ply \\
      res2/point_cloud.ply res1/point_cloud.ply -o lapis/
LapisGS level k becomes tree level k (ADD refinement, one layer per tile); the
opacity later levels give earlier splats becomes SPLAT2TILES_layer deltas."
)]
pub struct ImportLapisArgs {
    /// The levels' PLY files, coarsest (the base layer) first.
    #[arg(required = true, num_args = 1..)]
    pub levels: Vec<PathBuf>,
    /// Output folder: absent, empty, or an earlier splat2tiles output (replaced only when the new
    /// one is complete); nothing is written when a level is refused.
    #[arg(short, long)]
    pub output: PathBuf,
    #[command(flatten)]
    pub frame: FrameArgs,
    /// Print the summary as one JSON object.
    #[arg(long)]
    pub json: bool,
    /// No summary.
    #[arg(short, long)]
    pub quiet: bool,
}

/// Runs `import-lapisgs`; returns the process exit code.
pub fn run(args: ImportLapisArgs) -> i32 {
    if let Err(why) = args.frame.check() {
        eprintln!("splat2tiles: {why}");
        return super::EXIT_FAILURE;
    }
    let opts = args.frame.apply(ConvertOptions {
        layers: true,
        ..ConvertOptions::default()
    });
    crate::cli::install_interrupt_handler();
    match import_lapisgs(&args.levels, &args.output, &opts) {
        Ok(r) => {
            if args.json {
                let v = serde_json::json!({
                    "levels": args.levels, "output": args.output,
                    "levelSplats": r.level_splats, "scheme": r.scheme,
                    "tiles": r.tiles, "contentTiles": r.content_tiles,
                    "placeholders": r.placeholders, "deltas": r.deltas,
                    "rerouted": r.rerouted, "dropped": r.dropped,
                    "bytes": r.bytes, "seconds": r.seconds,
                });
                outln!("{v}");
            } else if !args.quiet {
                outln!(
                    "imported {} LapisGS levels ({} splats per level) into {}",
                    r.level_splats.len(),
                    r.level_splats
                        .iter()
                        .map(|n| n.to_string())
                        .collect::<Vec<_>>()
                        .join(" / "),
                    args.output.display()
                );
                outln!(
                    "  {} tiles ({} layers, {} of them zero-opacity placeholders), {} scheme, {} bytes, {:.1} s",
                    r.tiles,
                    r.content_tiles,
                    r.placeholders,
                    r.scheme,
                    r.bytes,
                    r.seconds
                );
                outln!(
                    "  {} opacity changes of earlier splats written as deltas ({} by a layer other than the one whose cell holds the splat), {} dropped",
                    r.deltas,
                    r.rerouted,
                    r.dropped
                );
            }
            0
        }
        Err(e) => {
            eprintln!("splat2tiles: {e}");
            super::EXIT_FAILURE
        }
    }
}
