//! Latency of one 30 s trajectory prediction (TileSplat App. C.5: 18 ms on CPU) with the
//! committed TCN and view model (`stream::learned`), against linear extrapolation, one thread.
//!
//! Run: `taskset -c 0 cargo bench --bench tcn [-- NAME=FILE.onnx ...]` (one core). Prints ms
//! per prediction (min, median) over 200 calls after 10 warm-up calls, and the model load time;
//! each `NAME=FILE.onnx` (e.g. the App. C.4 sizes `tools/tcn/train.py` writes) is timed the same.

use splat2tiles_stream::learned::window::straight_walk;
use splat2tiles_stream::learned::{LearnedPredictor, TcnPredictor, TrajectoryModel};
use splat2tiles_stream::predict::{LinearExtrapolation, Predictor};
use std::time::Instant;

fn time(p: &mut dyn Predictor, runs: usize) -> (f64, f64) {
    let h = straight_walk(10.0, 1.4);
    for _ in 0..10 {
        std::hint::black_box(p.predict_uncertain(&h, 30.0, 0.5));
    }
    let mut ms: Vec<f64> = (0..runs)
        .map(|_| {
            let t = Instant::now();
            std::hint::black_box(p.predict_uncertain(&h, 30.0, 0.5));
            t.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    ms.sort_by(f64::total_cmp);
    (ms[0], ms[ms.len() / 2])
}

fn main() {
    let t = Instant::now();
    let mut tcn = match TcnPredictor::committed() {
        Ok(p) => p,
        Err(e) => {
            eprintln!("tcn bench: {e}");
            std::process::exit(2);
        }
    };
    println!(
        "model load (decode and checks): {:.1} ms",
        t.elapsed().as_secs_f64() * 1e3
    );
    let (min, med) = time(&mut tcn, 200);
    println!("tcn 30 s prediction (60 steps): min {min:.2} ms, median {med:.2} ms");
    let (min, med) = time(&mut LearnedPredictor::committed(), 200);
    println!(
        "learned 30 s prediction (60 steps, 12 turned views): min {min:.3} ms, median {med:.3} ms"
    );
    let (min, med) = time(&mut LinearExtrapolation::default(), 200);
    println!("linear 30 s prediction: min {min:.3} ms, median {med:.3} ms");
    // cargo bench adds `--bench`; every NAME=FILE argument is a further model to time.
    for arg in std::env::args().skip(1).filter(|a| !a.starts_with("--")) {
        let Some((name, file)) = arg.split_once('=') else {
            eprintln!("tcn bench: '{arg}': expected NAME=FILE.onnx");
            std::process::exit(2);
        };
        let mut p = match TrajectoryModel::from_file(std::path::Path::new(file)) {
            Ok(m) => TcnPredictor::new(m),
            Err(e) => {
                eprintln!("tcn bench: {e}");
                std::process::exit(2);
            }
        };
        let (min, med) = time(&mut p, 200);
        println!("{name} 30 s prediction (60 steps): min {min:.2} ms, median {med:.2} ms");
    }
}
