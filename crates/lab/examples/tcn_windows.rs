//! Exports the learned predictor's training windows (train and val of the streaming city's tuning
//! set: real sessions placed in the city, street walks, flights) for `tools/tcn/train.py`.
//!
//! Run: `cargo run --release --example tcn_windows -- TRACES_DIR OUT_DIR [--stride S] [--kalman]`
//! (TRACES_DIR: the shared human traces; OUT_DIR gets `train.*` and `val.*`; stride 0.5 s;
//! `--kalman`: histories filtered by `stream::learned::smooth` first, App. C.1).
//! Test scenes and seeds never reach it: the traces come through `sim::stream_city::tuning_set`.

use splat2tiles_lab::sim::stream_city::{StreetGrid, tuning_set};
use splat2tiles_lab::sim::tcn_data::{windows, write_windows};
use splat2tiles_stream::learned::smooth::Kalman;
use std::path::PathBuf;

/// The street grid the windows are cut in (the default city's pitch; its size only bounds where
/// walks and flights go, and the windows are relative to the current pose).
pub const GRID: StreetGrid = StreetGrid {
    spacing: 24.0,
    side: 8,
};

fn run() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (mut pos, mut stride, mut smooth) = (vec![], 0.5f64, None);
    let mut i = 0;
    while i < args.len() {
        if args[i] == "--stride" {
            let v = args.get(i + 1).ok_or("--stride needs a value")?;
            stride = v.parse().map_err(|e| format!("--stride '{v}': {e}"))?;
            if !(0.05..=60.0).contains(&stride) {
                return Err(format!("--stride {v}: expected 0.05..=60"));
            }
            i += 2;
        } else if args[i] == "--kalman" {
            smooth = Some(Kalman::default());
            i += 1;
        } else {
            pos.push(PathBuf::from(&args[i]));
            i += 1;
        }
    }
    let [root, out] = pos.as_slice() else {
        return Err("usage: tcn_windows TRACES_DIR OUT_DIR [--stride S] [--kalman]".into());
    };
    std::fs::create_dir_all(out).map_err(|e| format!("{}: {e}", out.display()))?;
    let set = tuning_set(&GRID, root)?;
    for (name, traces) in [("train", set.train()), ("val", set.val())] {
        let w = windows(traces, stride, smooth.as_ref());
        write_windows(out, name, &w)?;
        println!("{name}: {} traces, {} windows", traces.len(), w.len());
    }
    Ok(())
}

fn main() {
    if let Err(e) = run() {
        eprintln!("tcn_windows: {e}");
        std::process::exit(2);
    }
}
