//! `splat2tiles-lab`: the measurement commands that are not part of the product (the streaming
//! experiments behind BENCHMARKS.md's tables), as `splat2tiles-lab simulate ...`.

use clap::{Parser, Subcommand};
use splat2tiles_lab::experiments::simulate;

/// Measurements of splat2tiles: the trace-driven streaming experiments.
#[derive(Debug, Parser)]
#[command(name = "splat2tiles-lab", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Run the streaming experiments (trace-driven client simulator) and write tables and plots,
    /// or, with --tileset and --trace, the client on your own tileset and camera path.
    Simulate(simulate::SimulateArgs),
}

fn main() {
    let Command::Simulate(a) = Cli::parse().command;
    let done = if a.tileset.is_some() {
        splat2tiles_lab::experiments::simulate_tool::run_tool(&a).map(|run| {
            // A closed stdout (`| head`) is not an error of the simulation.
            use std::io::Write as _;
            let mut out = std::io::stdout().lock();
            let _ = write!(out, "{}", run.summary);
            let _ = writeln!(out, "report: {}", a.report_dir.join("report.md").display());
        })
    } else {
        simulate::run(&a)
    };
    if let Err(e) = done {
        eprintln!("splat2tiles-lab: {e:#}");
        std::process::exit(2);
    }
}
