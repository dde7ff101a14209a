//! `splat2tiles-viewer`: parses the command line and dispatches (logic lives in the library).
//! Exit status 0 on success, 2 when it could not run.

use clap::Parser;

fn main() {
    let cli = splat2tiles_viewer::cli::Cli::parse();
    if let Err(e) = splat2tiles_viewer::cli::run(&cli) {
        eprintln!("splat2tiles-viewer: {e:#}");
        std::process::exit(2);
    }
}
