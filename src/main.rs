//! The `splat2tiles` command line: a thin front over the library.
//! Parses arguments, dispatches to the library's subcommand functions, maps errors to exit code 2.

use clap::{Parser, Subcommand};
use splat2tiles::render::cli as render_cli;

/// Command-line interface.
#[derive(Debug, Parser)]
#[command(name = "splat2tiles", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Commands,
}

/// Subcommands.
#[derive(Debug, Subcommand)]
enum Commands {
    /// Render a scene file with the CPU reference renderer to a PNG.
    Render(render_cli::RenderArgs),
    /// Print SSIM and PSNR between two PNG images.
    Compare(render_cli::CompareArgs),
}

fn main() {
    let cli = Cli::parse();
    let result = match &cli.command {
        Commands::Render(args) => render_cli::run_render(args, &|path| {
            // Scene reading lands with the io module (`splat2tiles::io::read_path`).
            anyhow::bail!(
                "{}: reading scene files is not available yet",
                path.display()
            )
        }),
        Commands::Compare(args) => render_cli::run_compare(args),
    };
    if let Err(e) = result {
        eprintln!("splat2tiles: {e:#}");
        std::process::exit(2);
    }
}
