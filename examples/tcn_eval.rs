//! Table 3 of TileSplat on our data: ADE/FDE per horizon (5..30 s) and latency of the trajectory
//! predictors on the streaming city's val or test traces, per kind (human, street walk, flight).
//!
//! Run: `cargo run --release --example tcn_eval -- TRACES_DIR [--split val|test] [--stride S]
//! [--model NAME=FILE.onnx]...` (default: val, 2 s, the committed TCN as `tcn`). Test traces come
//! only through `sim::stream_city::evaluation_set`; val through `tuning_set`.

use splat2tiles::sim::Trace;
use splat2tiles::sim::stream_city::{StreetGrid, evaluation_set, tuning_set};
use splat2tiles::sim::tcn_data::{HORIZONS, evaluate, trace_kind};
use splat2tiles::stream::learned::{TcnPredictor, TrajectoryModel};
use splat2tiles::stream::predict::{ConstantVelocity, LinearExtrapolation, Predictor, Reactive};
use std::path::PathBuf;

/// The grid of `examples/tcn_windows.rs`.
const GRID: StreetGrid = StreetGrid {
    spacing: 24.0,
    side: 8,
};

struct Named(String, TcnPredictor);

impl Predictor for Named {
    fn name(&self) -> &str {
        &self.0
    }
    fn predict(
        &mut self,
        h: &[splat2tiles::stream::ViewPose],
        horizon: f64,
        step: f64,
    ) -> Vec<splat2tiles::stream::ViewPose> {
        self.1.predict(h, horizon, step)
    }
}

fn run() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (mut root, mut split, mut stride) = (None, "val".to_string(), 2.0f64);
    let mut models: Vec<(String, PathBuf)> = vec![];
    let mut i = 0;
    while i < args.len() {
        let val = |k: usize| {
            args.get(k + 1)
                .cloned()
                .ok_or(format!("{} needs a value", args[k]))
        };
        match args[i].as_str() {
            "--split" => split = val(i)?,
            "--stride" => {
                let v = val(i)?;
                stride = v.parse().map_err(|e| format!("--stride '{v}': {e}"))?;
                if !(0.05..=60.0).contains(&stride) {
                    return Err(format!("--stride {v}: expected 0.05..=60"));
                }
            }
            "--model" => {
                let v = val(i)?;
                let (n, f) = v
                    .split_once('=')
                    .ok_or(format!("--model '{v}': NAME=FILE"))?;
                models.push((n.to_string(), PathBuf::from(f)));
            }
            a => {
                root = Some(PathBuf::from(a));
                i += 1;
                continue;
            }
        }
        i += 2;
    }
    let root = root
        .ok_or("usage: tcn_eval TRACES_DIR [--split val|test] [--stride S] [--model NAME=FILE]")?;
    let traces: Vec<Trace> = match split.as_str() {
        "val" => tuning_set(&GRID, &root)?.val().to_vec(),
        "test" => evaluation_set(&GRID, &root)?.traces().to_vec(),
        s => return Err(format!("--split {s}: expected val or test")),
    };
    let mut preds: Vec<Box<dyn Predictor>> = vec![
        Box::new(Reactive),
        Box::new(ConstantVelocity::default()),
        Box::new(LinearExtrapolation::default()),
    ];
    if models.is_empty() {
        preds.push(Box::new(Named("tcn".into(), TcnPredictor::committed()?)));
    }
    for (n, f) in models {
        let bytes = std::fs::read(&f).map_err(|e| format!("{}: {e}", f.display()))?;
        let m = TrajectoryModel::load(&bytes, &f.display().to_string())?;
        preds.push(Box::new(Named(n, TcnPredictor::new(m))));
    }
    let hs: Vec<String> = HORIZONS.iter().map(|h| format!("{h} s")).collect();
    println!(
        "| traces | predictor | windows | ADE {} | FDE {} | ms/prediction |",
        hs.join(" | ADE "),
        hs.join(" | FDE ")
    );
    println!("|---|---|---:|{}---:|", "---:|".repeat(12));
    for kind in ["human", "street_walk", "flight"] {
        let sel: Vec<Trace> = traces
            .iter()
            .filter(|t| trace_kind(t) == kind)
            .cloned()
            .collect();
        if sel.is_empty() {
            continue;
        }
        for p in preds.iter_mut() {
            let r = evaluate(p.as_mut(), &sel, stride);
            let f = |v: &[f64; 6]| {
                v.iter()
                    .map(|x| format!("{x:.2}"))
                    .collect::<Vec<_>>()
                    .join(" | ")
            };
            println!(
                "| {split} {kind} ({}) | {} | {} | {} | {} | {:.2} |",
                sel.len(),
                r.name,
                r.windows,
                f(&r.ade),
                f(&r.fde),
                r.ms_per_call
            );
        }
    }
    Ok(())
}

fn main() {
    if let Err(e) = run() {
        eprintln!("tcn_eval: {e}");
        std::process::exit(2);
    }
}
