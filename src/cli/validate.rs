//! `splat2tiles validate`: arguments, the run, and the report as text or JSON; exit 0 when no
//! ERROR, 1 when errors were found, 2 when the tileset cannot be read (missing, or not JSON).

use clap::Args;
use splat2tiles_validate::{ValidateOptions, validate_tileset};
use std::path::PathBuf;

/// Arguments of `validate`.
#[derive(Debug, Args)]
#[command(after_help = "Examples:
  splat2tiles validate out/plant/tileset.json
  splat2tiles validate out/plant/tileset.json --json --report report.json")]
pub struct ValidateArgs {
    /// The tileset.json to check (or the folder holding it).
    pub input: PathBuf,
    /// Print the report as JSON (Cesium 3d-tiles-validator shape) instead of text.
    #[arg(long)]
    pub json: bool,
    /// Also write the JSON report to this file.
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Accept remote URIs (a WARNING instead of an ERROR; they are never fetched).
    #[arg(long)]
    pub allow_remote: bool,
    /// Also warn when a splat's 3-sigma ellipsoid reaches outside its tile's volume.
    #[arg(long)]
    pub check_extent: bool,
    /// Largest decompressed size of one gzip/zstd file, in MiB.
    #[arg(long, default_value_t = 1024)]
    pub max_decompressed_mib: u64,
    /// Folder URIs may resolve into (a served root holding several tilesets); default: the
    /// tileset's own folder. `../` URIs are legal in 3D Tiles: widen the root to follow them.
    #[arg(long, value_name = "DIR")]
    pub root: Option<PathBuf>,
    /// Deepest chain of external tilesets followed.
    #[arg(long, default_value_t = 16)]
    pub max_external_depth: usize,
}

/// Runs `validate`; returns the process exit code.
pub fn run(args: ValidateArgs) -> i32 {
    let opts = ValidateOptions {
        allow_remote: args.allow_remote,
        check_extent: args.check_extent,
        max_decompressed_bytes: args.max_decompressed_mib.saturating_mul(1 << 20),
        root: args.root.clone(),
        max_external_depth: args.max_external_depth,
        ..ValidateOptions::default()
    };
    let report = match validate_tileset(&args.input, &opts) {
        Ok(r) => r,
        Err(e) => {
            eprintln!("splat2tiles: {e}");
            return super::EXIT_FAILURE;
        }
    };
    if args.json {
        outln!("{}", report.to_json());
    } else {
        out!("{}", report.to_text(&args.input.display().to_string()));
    }
    // The tileset's folder: a report inside it would change the tileset that was checked.
    let input_dir = if args.input.is_dir() {
        args.input.clone()
    } else {
        args.input
            .parent()
            .filter(|p| !p.as_os_str().is_empty())
            .map_or_else(|| ".".into(), |p| p.to_path_buf())
    };
    if let Some(path) = &args.report
        && let Err(e) = super::out::write_file(path, report.to_json().as_bytes(), &input_dir)
    {
        eprintln!("splat2tiles: {}: {e}", path.display());
        return super::EXIT_FAILURE;
    }
    if report.unreadable {
        // Not a tileset at all (not JSON, or past the parse limits): like a missing file.
        super::EXIT_FAILURE
    } else if report.is_valid() {
        0
    } else {
        super::EXIT_FINDINGS
    }
}
