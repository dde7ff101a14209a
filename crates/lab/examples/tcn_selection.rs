//! Mean-only vs uncertainty-aware tile selection with the TCN (TileSplat App.
//! C.5): the shipped client over the simulated transport, scored by `sim::score` (CHR over
//! first-time entries, WD, MB), with reactive and linear beside it.
//!
//! Run: `cargo run --release --example tcn_selection -- TRACES_DIR [--city DIR] [--seconds S]
//! [--every N]`. Without `--city` the small city of `tests/sim_city.rs` (200k splats, stride 16,
//! seed 3, 4,096 splats per leaf; `data/scenes/README.md`) is built in a temporary folder
//! under `target/tmp-big/` and removed after; with it, a city built by `cargo run --release
//! --example stream_city -- DIR` (its grid: `CitySpec::default()`). Traces: the test split
//! (`sim::stream_city::evaluation_set`) on that city's streets, the first S s (60) of every N-th
//! (5th) human session and of every street walk and flight. 10 Mbit/s, 40 ms RTT, 4 requests in
//! flight, 1280x720, 256 MiB budget (as tests/sim_city.rs).
//!
//! "tcn (sigma)" is the client's `PredictorKind::Tcn`: predicted poses whose sigma exceeds
//! `BLEND_SIGMA_M` are dropped and the radius rule (App. C.5) joins in; "tcn (mean only)" is the
//! same model with its sigma ignored (every mean pose planned for, never the radius rule).

use splat2tiles_lab::sim::score::{
    Ratio, Truth, Waste, cache_hits, held_tiles, tick_views, wasted,
};
use splat2tiles_lab::sim::session::{SessionOptions, run_session};
use splat2tiles_lab::sim::stream_city::{
    CitySpec, StreetGrid, build_city, city_sources, evaluation_set,
};
use splat2tiles_lab::sim::tcn_data::trace_kind;
use splat2tiles_lab::sim::transport::{NetModel, Outcome};
use splat2tiles_stream::ViewPose;
use splat2tiles_stream::client::{ClientConfig, PredictorKind};
use splat2tiles_stream::learned::TcnPredictor;
use splat2tiles_stream::predict::{BLEND_SIGMA_M, Predictor, Uncertain};
use splat2tiles_stream::trace::Trace;
use splat2tiles_tiles::tiling::TileKey;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};

/// The TCN with its sigma kept or dropped, counting the predictions that had a pose above
/// `BLEND_SIGMA_M` (where the uncertainty-aware client blends in the radius rule).
struct Tcn {
    inner: TcnPredictor,
    mean_only: bool,
    calls: Arc<AtomicUsize>,
    uncertain: Arc<AtomicUsize>,
}

impl Predictor for Tcn {
    fn name(&self) -> &str {
        if self.mean_only {
            "tcn (mean only)"
        } else {
            "tcn (sigma)"
        }
    }
    fn min_history_s(&self) -> f64 {
        self.inner.min_history_s()
    }
    fn predict(&mut self, h: &[ViewPose], horizon: f64, step: f64) -> Vec<ViewPose> {
        self.inner.predict(h, horizon, step)
    }
    fn predict_uncertain(&mut self, h: &[ViewPose], horizon: f64, step: f64) -> Vec<Uncertain> {
        let mut out = self.inner.predict_uncertain(h, horizon, step);
        self.calls.fetch_add(1, Ordering::Relaxed);
        if out.iter().any(|u| u.sigma_m > BLEND_SIGMA_M) {
            self.uncertain.fetch_add(1, Ordering::Relaxed);
        }
        if self.mean_only {
            out.iter_mut().for_each(|u| u.sigma_m = 0.0);
        }
        out
    }
}

/// Sums over sessions of one client setup.
#[derive(Default)]
struct Row {
    chr: Ratio,
    waste: Waste,
    mb: f64,
    calls: usize,
    uncertain: usize,
}

/// Adds one session's CHR over first-time entries, WD and MB to `row`.
fn score(
    truth: &Truth,
    cfg: &ClientConfig,
    log: &splat2tiles_lab::sim::session::SessionLog,
    row: &mut Row,
) {
    let needed = truth.needed_per_tick(cfg, log);
    let resident = held_tiles(log);
    let views = tick_views(log, needed.iter().map(Vec::as_slice), &resident);
    let c = cache_hits(&views);
    row.chr.hits += c.first.hits;
    row.chr.n += c.first.n;
    let downloads: Vec<(TileKey, u64, f64)> = log
        .requests
        .iter()
        .filter(|r| r.outcome == Outcome::Done)
        .filter_map(|r| Some((r.key?, r.bytes, r.end_s?)))
        .collect();
    let w = wasted(&downloads, &views);
    row.waste.tiles += w.tiles;
    row.waste.bytes += w.bytes;
    row.waste.wasted_tiles += w.wasted_tiles;
    row.waste.wasted_bytes += w.wasted_bytes;
    row.mb += log.ticks.last().map_or(0, |t| t.bytes_down) as f64 / 1e6;
}

fn run() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (mut nav, mut city, mut seconds, mut every) = (None, None, 60.0f64, 5usize);
    let mut i = 0;
    while i < args.len() {
        let val = |k: usize| {
            args.get(k + 1)
                .cloned()
                .ok_or(format!("{} needs a value", args[k]))
        };
        match args[i].as_str() {
            "--city" => city = Some(PathBuf::from(val(i)?)),
            "--seconds" => {
                let v = val(i)?;
                seconds = v.parse().map_err(|e| format!("--seconds '{v}': {e}"))?;
                if !(6.0..=600.0).contains(&seconds) {
                    return Err(format!("--seconds {v}: expected 6..=600"));
                }
            }
            "--every" => {
                let v = val(i)?;
                every = v.parse().map_err(|e| format!("--every '{v}': {e}"))?;
                every = every.max(1);
            }
            a => {
                nav = Some(PathBuf::from(a));
                i += 1;
                continue;
            }
        }
        i += 2;
    }
    let nav =
        nav.ok_or("usage: tcn_selection TRACES_DIR [--city DIR] [--seconds S] [--every N]")?;
    let scenes = Path::new("data/scenes");
    let tmp = PathBuf::from("target/tmp-big/tcn_selection");
    let (dir, grid, built) = match city {
        Some(d) => {
            let spec = CitySpec::default();
            let sources = city_sources(scenes, spec.stride).map_err(|e| format!("{e:#}"))?;
            let grid = StreetGrid::of(&sources, &spec.layout());
            (d, grid, false)
        }
        None => {
            let spec = CitySpec::small();
            if tmp.exists() {
                return Err(format!(
                    "{} exists (left by an earlier run?)",
                    tmp.display()
                ));
            }
            let c =
                build_city(scenes, &tmp.join("city"), &spec, None).map_err(|e| format!("{e:#}"))?;
            eprintln!("small city: {}", c.summary());
            (c.dir.clone(), c.grid, true)
        }
    };
    let result = measure(&dir, &grid, &nav, seconds, every);
    if built {
        let _ = std::fs::remove_dir_all(&tmp);
    }
    result
}

fn measure(
    dir: &Path,
    grid: &StreetGrid,
    nav: &Path,
    seconds: f64,
    every: usize,
) -> Result<(), String> {
    let truth = Truth::load(&dir.join("tileset.json")).map_err(|e| format!("{e:#}"))?;
    let set = evaluation_set(grid, nav)?;
    let mut humans = 0usize;
    let traces: Vec<Trace> = set
        .traces()
        .iter()
        .filter(|t| {
            if trace_kind(t) != "human" {
                return true;
            }
            humans += 1;
            (humans - 1).is_multiple_of(every)
        })
        .map(|t| {
            let t0 = t.poses.first().map_or(0.0, |p| p.t);
            Trace {
                headers: t.headers.clone(),
                poses: t
                    .poses
                    .iter()
                    .copied()
                    .filter(|p| p.t - t0 <= seconds + 1e-9)
                    .collect(),
            }
        })
        .collect();
    let net = NetModel::constant(10.0, 0.04);
    let cfg = CitySpec::small_client;
    let setups = ["reactive", "linear", "tcn (sigma)", "tcn (mean only)"];
    println!(
        "| traces | client | CHR first-time | WD tiles | WD MB | MB | predictions with a pose over {BLEND_SIGMA_M} m sigma |"
    );
    println!("|---|---|---:|---:|---:|---:|---:|");
    for kind in ["human", "street_walk", "flight"] {
        let sel: Vec<&Trace> = traces.iter().filter(|t| trace_kind(t) == kind).collect();
        if sel.is_empty() {
            continue;
        }
        for setup in setups {
            let mut row = Row::default();
            for tr in &sel {
                let calls = Arc::new(AtomicUsize::new(0));
                let uncertain = Arc::new(AtomicUsize::new(0));
                let (c, opts) = match setup {
                    "reactive" => (cfg(PredictorKind::Reactive), SessionOptions::default()),
                    "linear" => (cfg(PredictorKind::Linear), SessionOptions::default()),
                    _ => {
                        let p = Tcn {
                            inner: TcnPredictor::committed()?,
                            mean_only: setup == "tcn (mean only)",
                            calls: calls.clone(),
                            uncertain: uncertain.clone(),
                        };
                        let opts = SessionOptions {
                            predictor: Some(Box::new(p)),
                            ..SessionOptions::default()
                        };
                        (cfg(PredictorKind::Tcn), opts)
                    }
                };
                let log = run_session(dir, c.clone(), &tr.poses, &net, opts);
                score(&truth, &c, &log, &mut row);
                row.calls += calls.load(Ordering::Relaxed);
                row.uncertain += uncertain.load(Ordering::Relaxed);
            }
            let pct = |a: u64, b: u64| 100.0 * a as f64 / b.max(1) as f64;
            let blend = if setup.starts_with("tcn") {
                format!("{} of {}", row.uncertain, row.calls)
            } else {
                "-".into()
            };
            println!(
                "| {kind} ({}) | {setup} | {}/{} = {:.3} | {} of {} ({:.1}%) | {:.2} ({:.1}%) | {:.2} | {blend} |",
                sel.len(),
                row.chr.hits,
                row.chr.n,
                row.chr.rate().unwrap_or(0.0),
                row.waste.wasted_tiles,
                row.waste.tiles,
                pct(row.waste.wasted_tiles, row.waste.tiles),
                row.waste.wasted_bytes as f64 / 1e6,
                pct(row.waste.wasted_bytes, row.waste.bytes),
                row.mb
            );
        }
    }
    Ok(())
}

fn main() {
    if let Err(e) = run() {
        eprintln!("tcn_selection: {e}");
        std::process::exit(2);
    }
}
