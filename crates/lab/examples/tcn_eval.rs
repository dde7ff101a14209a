//! Table 3 of TileSplat on our data: ADE/FDE per horizon (5..30 s), latency and tile coverage of
//! the trajectory predictors on the streaming city's val or test traces, per kind.
//!
//! Run: `cargo run --release --example tcn_eval -- TRACES_DIR [--split val|test] [--stride S]
//! [--model NAME=FILE.onnx]... [--city DIR]` (default: val, 2 s, the committed TCN as `tcn`).
//! Test traces come only through `sim::stream_city::evaluation_set`; val through `tuning_set`.
//! `--city DIR`: a streaming city built by `cargo run --release --example stream_city -- DIR`
//! (the default `CitySpec`, whose 11 x 11 street grid contains this example's 8 x 8 one, so the
//! traces walk its streets); then a second table gives the tile coverage (`sim::tcn_data::coverage`:
//! the needed cut at the client's default viewport, 1280x720, 50 deg, SSE 16, frustum-culled).
//! The oracle row reads each trace's own future (ADE 0 and coverage 100% by construction,
//! measured as a check of the evaluation).

use splat2tiles_lab::sim::score::Truth;
use splat2tiles_lab::sim::stream_city::{StreetGrid, evaluation_set, tuning_set};
use splat2tiles_lab::sim::tcn_data::{ErrorRow, HORIZONS, coverage, evaluate, trace_kind};
use splat2tiles_stream::ViewPose;
use splat2tiles_stream::client::ClientConfig;
use splat2tiles_stream::learned::{TcnPredictor, TrajectoryModel};
use splat2tiles_stream::predict::{
    ConstantVelocity, LinearExtrapolation, Oracle, Predictor, Reactive,
};
use splat2tiles_stream::trace::Trace;
use splat2tiles_tiles::tiling::TileKey;
use std::path::PathBuf;

/// The grid of `examples/tcn_windows.rs`.
const GRID: StreetGrid = StreetGrid {
    spacing: 24.0,
    side: 8,
};

struct Named(String, TcnPredictor);

/// Tile coverage per horizon and the windows counted per horizon.
type Coverage = ([f64; 6], [usize; 6]);

impl Predictor for Named {
    fn name(&self) -> &str {
        &self.0
    }
    fn predict(
        &mut self,
        h: &[splat2tiles_stream::ViewPose],
        horizon: f64,
        step: f64,
    ) -> Vec<splat2tiles_stream::ViewPose> {
        self.1.predict(h, horizon, step)
    }
}

fn run() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (mut root, mut split, mut stride) = (None, "val".to_string(), 2.0f64);
    let mut city: Option<PathBuf> = None;
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
            "--city" => city = Some(PathBuf::from(val(i)?)),
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
    let root = root.ok_or(
        "usage: tcn_eval TRACES_DIR [--split val|test] [--stride S] [--model NAME=FILE] [--city DIR]",
    )?;
    let truth = match &city {
        Some(d) => Some(Truth::load(&d.join("tileset.json")).map_err(|e| format!("{e:#}"))?),
        None => None,
    };
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
        let m = TrajectoryModel::from_file(&f)?;
        preds.push(Box::new(Named(n, TcnPredictor::new(m))));
    }
    let hs: Vec<String> = HORIZONS.iter().map(|h| format!("{h} s")).collect();
    let f = |v: &[f64; 6], scale: f64| {
        v.iter()
            .map(|x| format!("{:.2}", x * scale))
            .collect::<Vec<_>>()
            .join(" | ")
    };
    let mut errors = String::new();
    let mut covered = String::new();
    for kind in ["human", "street_walk", "flight"] {
        let sel: Vec<Trace> = traces
            .iter()
            .filter(|t| trace_kind(t) == kind)
            .cloned()
            .collect();
        if sel.is_empty() {
            continue;
        }
        let label = format!("{split} {kind} ({})", sel.len());
        let mut rows: Vec<(ErrorRow, Option<Coverage>)> = vec![];
        for p in preds.iter_mut() {
            let r = evaluate(p.as_mut(), &sel, stride);
            let c = truth
                .as_ref()
                .map(|t| coverage(p.as_mut(), &sel, stride, &mut |q| needed(t, q)));
            rows.push((r, c));
        }
        rows.push(oracle_row(&sel, stride, truth.as_ref()));
        for (r, c) in rows {
            errors += &format!(
                "| {label} | {} | {} | {} | {} | {:.2} |\n",
                r.name,
                r.windows,
                f(&r.ade, 1.0),
                f(&r.fde, 1.0),
                r.ms_per_call
            );
            if let Some((c, n)) = c {
                covered += &format!("| {label} | {} | {} | {} |\n", r.name, n[0], f(&c, 100.0));
            }
        }
    }
    println!(
        "| traces | predictor | windows | ADE {} | FDE {} | ms/prediction |",
        hs.join(" | ADE "),
        hs.join(" | FDE ")
    );
    println!("|---|---|---:|{}---:|", "---:|".repeat(12));
    print!("{errors}");
    if truth.is_some() {
        println!(
            "\n| traces | predictor | windows | coverage {} (%) |",
            hs.join(" | coverage ")
        );
        println!("|---|---|---:|{}", "---:|".repeat(6));
        print!("{covered}");
    }
    Ok(())
}

/// The needed cut of `pose` (tileset frame) at the client's default viewport.
fn needed(truth: &Truth, pose: &ViewPose) -> Vec<TileKey> {
    truth.needed_at(&ClientConfig::default(), pose)
}

/// The oracle (each trace's own future) over `sel`: errors and coverage summed per trace,
/// weighted by windows.
fn oracle_row(sel: &[Trace], stride: f64, truth: Option<&Truth>) -> (ErrorRow, Option<Coverage>) {
    let mut row = ErrorRow {
        name: "oracle".into(),
        windows: 0,
        ade: [0.0; 6],
        fde: [0.0; 6],
        ms_per_call: 0.0,
    };
    let mut cov = ([0.0; 6], [0usize; 6]);
    for t in sel {
        let mut o = Oracle {
            trace: t.poses.clone(),
        };
        let r = evaluate(&mut o, std::slice::from_ref(t), stride);
        let w = r.windows as f64;
        for i in 0..6 {
            row.ade[i] += r.ade[i] * w;
            row.fde[i] += r.fde[i] * w;
        }
        row.ms_per_call += r.ms_per_call * w;
        row.windows += r.windows;
        if let Some(tr) = truth {
            let (c, n) = coverage(&mut o, std::slice::from_ref(t), stride, &mut |q| {
                needed(tr, q)
            });
            for i in 0..6 {
                cov.0[i] += c[i] * n[i] as f64;
                cov.1[i] += n[i];
            }
        }
    }
    let w = row.windows.max(1) as f64;
    for i in 0..6 {
        row.ade[i] /= w;
        row.fde[i] /= w;
        cov.0[i] /= cov.1[i].max(1) as f64;
    }
    row.ms_per_call /= w;
    (row, truth.map(|_| cov))
}

fn main() {
    if let Err(e) = run() {
        eprintln!("tcn_eval: {e}");
        std::process::exit(2);
    }
}
