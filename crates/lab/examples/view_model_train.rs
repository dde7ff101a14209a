//! Fits the learned view predictor (`stream::learned::view_model`) on the streaming city's tuning
//! split and prints its errors on the val traces per ridge factor; writes the chosen weights.
//!
//! `cargo run --release -p splat2tiles-lab --example view_model_train -- OUT.json [RIDGE...]`
//! (default ridges 1e-4 1e-3 1e-2 1e-1; the one with the lowest val yaw error is written). The
//! committed model: `OUT.json` = `crates/stream/src/learned/view_model.json`.

use splat2tiles_lab::sim::learn::{fit, score, tuning_samples};
use splat2tiles_lab::sim::stream_city::{CitySpec, NAVIGATION_DIR, StreetGrid, tuning_set};
use std::path::PathBuf;
use std::time::Instant;

fn main() -> anyhow::Result<()> {
    let mut args = std::env::args().skip(1);
    let out = PathBuf::from(
        args.next()
            .ok_or_else(|| anyhow::anyhow!("usage: OUT.json [RIDGE...]"))?,
    );
    let mut ridges: Vec<f64> = args.map(|a| a.parse()).collect::<Result<_, _>>()?;
    if ridges.is_empty() {
        ridges = vec![1e-4, 1e-3, 1e-2, 1e-1];
    }
    let root = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."));
    let spec = CitySpec::default();
    let sources =
        splat2tiles_lab::sim::stream_city::city_sources(&root.join("data/scenes"), spec.stride)?;
    let grid = StreetGrid::of(&sources, &spec.layout());
    let set = tuning_set(&grid, &root.join(NAVIGATION_DIR)).map_err(anyhow::Error::msg)?;
    let start = Instant::now();
    let stride = 0.25;
    let (train, val) = tuning_samples(&set, stride);
    eprintln!(
        "{} train windows ({} traces), {} val windows ({} traces) in {:.1} s",
        train.len(),
        set.train().len(),
        val.len(),
        set.val().len(),
        start.elapsed().as_secs_f64()
    );
    let mut best = None;
    println!(
        "| ridge | yaw MAE 1 / 2 / 5 / 10 s (deg; holding) | position error 1 / 5 / 10 s (m; linear) | fit s |"
    );
    println!("|---:|---|---|---:|");
    for &r in &ridges {
        let t = Instant::now();
        let trained_on = format!(
            "stream city tuning split: {} train traces, {} windows every {stride} s; ridge {r}",
            set.train().len(),
            train.len()
        );
        let m = fit(&train, &val, r, &trained_on);
        let fit_s = t.elapsed().as_secs_f64();
        let s = score(&m, &val);
        let at = |h: f64| ((h / 0.25).round() as usize) - 1;
        let deg = |k: usize| {
            format!(
                "{:.1} ({:.1})",
                s.yaw_mae[k].0.to_degrees(),
                s.yaw_mae[k].1.to_degrees()
            )
        };
        let met = |k: usize| format!("{:.2} ({:.2})", s.pos_mae[k].0, s.pos_mae[k].1);
        println!(
            "| {r} | {} / {} / {} / {} | {} / {} / {} | {fit_s:.1} |",
            deg(at(1.0)),
            deg(at(2.0)),
            deg(at(5.0)),
            deg(at(10.0)),
            met(at(1.0)),
            met(at(5.0)),
            met(at(10.0))
        );
        let yaw: f64 = s.yaw_mae.iter().map(|e| e.0).sum();
        if best.as_ref().is_none_or(|(b, _)| yaw < *b) {
            best = Some((yaw, m));
        }
    }
    if let Some((_, m)) = best {
        std::fs::write(&out, serde_json::to_string_pretty(&m)? + "\n")?;
        eprintln!("wrote {} ({})", out.display(), m.trained_on);
    }
    Ok(())
}
