//! The `splat2tiles` command line: parses arguments, dispatches to the library's command
//! runners and turns their results into exit codes (0 ok, 1 findings, 2 could not run).

use clap::{Parser, Subcommand};
mod cli;

use cli::render as render_cli;

/// Make huge 3D Gaussian Splatting scenes streamable: OGC 3D Tiles 1.1 of glTF
/// KHR_gaussian_splatting tiles.
#[derive(Debug, Parser)]
#[command(name = "splat2tiles", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Convert a PLY, .splat or .spz scene into an implicit 3D Tiles 1.1 tileset.
    Convert(cli::convert::ConvertArgs),
    /// Import LapisGS-trained levels (one PLY per level, coarse to fine) as a layered tileset.
    #[command(name = "import-lapisgs")]
    ImportLapisgs(cli::import_lapisgs::ImportLapisArgs),
    /// Merge the parts of a sharded conversion (`convert --plan`) into one tileset.
    Merge(cli::convert::shard::MergeArgs),
    /// Check a tileset (JSON, subtrees, metadata, every KHR_gaussian_splatting glb) and report issues.
    Validate(cli::validate::ValidateArgs),
    /// Render a scene file or a tileset with the CPU reference renderer to a PNG.
    Render(render_cli::RenderArgs),
    /// Print SSIM and PSNR between two PNG images.
    Compare(render_cli::CompareArgs),
    /// Print a tileset's per-level table: tiles, splats, bytes, mean geometric error.
    Stats(cli::stats::StatsArgs),
    /// Serve a tileset folder over HTTP (ranges, ETags, precompressed files, CORS) until Ctrl-C.
    Serve(cli::serve::ServeArgs),
    /// Serve a tileset and the web viewer, and open the viewer in a browser.
    View(cli::serve::ViewArgs),
}

fn main() {
    let args = Cli::parse();
    cli::stderr_log::install();
    let code = match args.command {
        Command::Convert(a) => cli::convert::run(a),
        Command::ImportLapisgs(a) => cli::import_lapisgs::run(a),
        Command::Merge(a) => cli::convert::shard::run_merge(a),
        Command::Validate(a) => cli::validate::run(a),
        Command::Render(a) => report(render_cli::run_render(&a)),
        Command::Compare(a) => report(render_cli::run_compare(&a)),
        Command::Stats(a) => cli::stats::run(a),
        Command::Serve(a) => report(cli::serve::run_serve(&a)),
        Command::View(a) => report(cli::serve::run_view(&a)),
    };
    cli::out::flush();
    std::process::exit(code);
}

fn report(result: anyhow::Result<()>) -> i32 {
    match result {
        Ok(()) => 0,
        Err(e) => {
            eprintln!("splat2tiles: {e:#}");
            cli::EXIT_FAILURE
        }
    }
}
