//! Predictors side by side on the streaming city's Table 4 protocol (10 Mbit/s, DC-DP, the
//! experiment's budget), on the traces of one split: CHR after warm-up, first-time, re-entries, WD.
//!
//! `STREAM_CITY_DIR=DIR SPLIT=val|train|test cargo run --release -p splat2tiles-lab --example
//! predictor_race -- linear learned ...`. Names: `simulate`'s predictors and the oracle;
//! `learned=FILE` (a view model's weights); `MODEL@SIGMAS,HORIZON_S[,POSES]` (a view model with
//! those turned views; MODEL is `learned`, `learned=FILE` or an ablation: `fixed-fan`,
//! `learned-fixed-fan`, `learned-held-yaw`); the diagnostic mixes `pos:A+ang:B` (A's positions
//! with B's yaw and pitch). `ONLY=label` runs one trace, `ALL=1` every trace of the split (its
//! first 60 s); `NETWORK=hsdpa|fcc` a real log instead of 10 Mbit/s (`NETWORKS=DIR` another
//! folder of logs); `NAVIGATION=DIR` other human traces. Tune on `val`; `test` is for the final
//! table only.

use splat2tiles_lab::experiments::simulate_city::{BUDGET, label, pick_traces};
use splat2tiles_lab::sim::report::{client_setup, needed_cuts, session_numbers};
use splat2tiles_lab::sim::score::{Ratio, Truth};
use splat2tiles_lab::sim::session::run_session;
use splat2tiles_lab::sim::stream_city::{CitySpec, NAVIGATION_DIR, StreetGrid, trace_set};
use splat2tiles_lab::sim::transport::NetModel;
use splat2tiles_stream::catalog::Level;
use splat2tiles_stream::client::{ClientConfig, PredictorKind, predictor_of};
use splat2tiles_stream::geom::ViewPose;
use splat2tiles_stream::plan::Planner;
use splat2tiles_stream::predict::{Oracle, Predictor};
use splat2tiles_stream::split::Split;
use splat2tiles_stream::trace::Trace;
use splat2tiles_tiles::tiling::TileKey;
use std::collections::HashMap;
use std::path::PathBuf;

/// A's positions with B's angles (which error costs the cache hits).
struct Mix {
    name: String,
    pos: Box<dyn Predictor + Send>,
    ang: Box<dyn Predictor + Send>,
}

impl Predictor for Mix {
    fn name(&self) -> &str {
        &self.name
    }
    fn min_history_s(&self) -> f64 {
        self.pos.min_history_s().max(self.ang.min_history_s())
    }
    fn predict(&mut self, h: &[ViewPose], horizon: f64, step: f64) -> Vec<ViewPose> {
        let p = self.pos.predict(h, horizon, step);
        let a = self.ang.predict(h, horizon, step);
        p.into_iter()
            .zip(a)
            .map(|(p, a)| ViewPose {
                yaw: a.yaw,
                pitch: a.pitch,
                ..p
            })
            .collect()
    }
}

fn one(name: &str, poses: &[ViewPose]) -> Box<dyn Predictor + Send> {
    match name {
        "oracle" => Box::new(Oracle {
            trace: poses.to_vec(),
        }),
        _ => predictor_of(
            PredictorKind::from_name(name).unwrap_or_else(|| panic!("unknown predictor {name}")),
        ),
    }
}

fn predictor(name: &str, poses: &[ViewPose]) -> Box<dyn Predictor + Send> {
    // A view model with its turned views: `MODEL@...`, or `learned=FILE` with the defaults.
    let view_model = name
        .split_once('@')
        .or_else(|| name.starts_with("learned=").then_some((name, "")));
    if let Some((model, hedge)) = view_model {
        let model = match model.strip_prefix("learned=") {
            Some(path) => splat2tiles_stream::learned::ViewModel::from_json(
                &std::fs::read_to_string(path).unwrap(),
                path,
            )
            .unwrap(),
            None => ablation(model),
        };
        let mut p = splat2tiles_stream::learned::LearnedPredictor::new(model);
        let mut it = hedge.split(',').filter(|v| !v.is_empty());
        p.hedge_sigmas = it.next().map_or(p.hedge_sigmas, |v| v.parse().unwrap());
        p.hedge_horizon_s = it.next().map_or(p.hedge_horizon_s, |v| v.parse().unwrap());
        p.hedge_poses = it.next().map_or(p.hedge_poses, |v| v.parse().unwrap());
        return Box::new(p);
    }
    if let Some((p, a)) = name
        .strip_prefix("pos:")
        .and_then(|r| r.split_once("+ang:"))
    {
        return Box::new(Mix {
            name: name.to_string(),
            pos: one(p, poses),
            ang: one(a, poses),
        });
    }
    one(name, poses)
}

/// 10 Mbit/s, or with `NETWORK=hsdpa|fcc` the first such log scaled to a mean of 10 Mbit/s and
/// looped (Table 5's real networks).
fn network(root: &std::path::Path) -> NetModel {
    use splat2tiles_lab::sim::network::{Network, log_files, read_log};
    let mut m = NetModel::constant(10.0, 0.04);
    let net = match std::env::var("NETWORK").as_deref() {
        Ok("hsdpa") => Network::Hsdpa,
        Ok("fcc") => Network::Fcc,
        _ => return m,
    };
    let dir = std::env::var("NETWORKS").map_or(root.join("data/network-traces"), PathBuf::from);
    let f = log_files(&dir, net)
        .unwrap()
        .into_iter()
        .next()
        .expect("no log");
    let raw = read_log(&f, 1.0).unwrap();
    let scale = 10e6 / 8.0 / raw.mean_bytes_per_s().max(1.0);
    m.bandwidth = read_log(&f, scale).unwrap().looped(61.0);
    eprintln!("network {} x {scale:.2}", f.display());
    m
}

/// The committed view model (`learned`) or one of its ablations: `fixed-fan` (no history
/// features: linear's path, the yaw held, a fan as wide as the model's val RMS yaw error at each
/// horizon), `learned-fixed-fan` (the model's mean, that fan), `learned-held-yaw` (the model with
/// the yaw held: its fan around the current yaw).
fn ablation(name: &str) -> splat2tiles_stream::learned::ViewModel {
    let mut m = splat2tiles_stream::learned::ViewModel::committed().clone();
    let zero = |t: &mut Vec<Vec<f64>>| t.iter_mut().flatten().for_each(|w| *w = 0.0);
    let fixed = |m: &mut splat2tiles_stream::learned::ViewModel| {
        for (row, rms) in m.yaw_spread.iter_mut().zip(&m.yaw_rms) {
            row.iter_mut().for_each(|w| *w = 0.0);
            // `outputs` turns a mean absolute error into a sigma (x 1.2533).
            row[0] = rms / 1.2533;
        }
    };
    match name {
        "learned" => {}
        "fixed-fan" => {
            for t in [&mut m.yaw, &mut m.pitch, &mut m.forward, &mut m.left] {
                zero(t);
            }
            fixed(&mut m);
        }
        "learned-fixed-fan" => fixed(&mut m),
        "learned-held-yaw" => zero(&mut m.yaw),
        _ => panic!("unknown view model {name}"),
    }
    m
}

#[derive(Default)]
struct Sum {
    warm: Ratio,
    first: Ratio,
    re: Ratio,
    wd_tiles: (u64, u64),
    wd_bytes: (u64, u64),
    mb: f64,
}

fn pct(r: Ratio) -> String {
    format!(
        "{:.1}% ({}/{})",
        100.0 * r.rate().unwrap_or(0.0),
        r.hits,
        r.n
    )
}

fn main() {
    let names: Vec<String> = std::env::args().skip(1).collect();
    let dir = PathBuf::from(std::env::var("STREAM_CITY_DIR").expect("STREAM_CITY_DIR"));
    let split = std::env::var("SPLIT")
        .ok()
        .and_then(|s| Split::parse(&s))
        .expect("SPLIT=train|val|test");
    let root = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."));
    let spec = CitySpec::default();
    let sources =
        splat2tiles_lab::sim::stream_city::city_sources(&root.join("data/scenes"), spec.stride)
            .unwrap();
    let grid = StreetGrid::of(&sources, &spec.layout());
    let truth = Truth::load(&dir.join("tileset.json")).unwrap();
    let ts = splat2tiles_tiles::tiling::load::load_tileset(&dir.join("tileset.json")).unwrap();
    let low: HashMap<TileKey, u64> = splat2tiles_tiles::variants::content_variant_metadata(&ts)
        .iter()
        .map(|(k, (_, b, _))| (*k, b[Level::Low.index()] as u64))
        .collect();
    let nav = std::env::var("NAVIGATION").map_or(root.join(NAVIGATION_DIR), PathBuf::from);
    let all = trace_set(&grid, &nav, split).unwrap();
    // `ALL=1`: every trace of the split (its first 60 s), not only Table 4's six.
    let traces = if std::env::var("ALL").is_ok() {
        all.iter()
            .map(|t| Trace {
                headers: t.headers.clone(),
                poses: t
                    .poses
                    .iter()
                    .copied()
                    .filter(|p| p.t <= t.poses[0].t + 60.0)
                    .collect(),
            })
            .collect()
    } else {
        pick_traces(&all)
    };
    let net = network(&root);
    let mut sums: Vec<Sum> = names.iter().map(|_| Sum::default()).collect();
    for tr in &traces {
        if std::env::var("ONLY").is_ok_and(|o| !label(tr).contains(&o)) {
            continue;
        }
        let base = ClientConfig {
            max_concurrent: 4,
            ..ClientConfig::default()
        };
        let needed = needed_cuts(&truth, &base, &tr.poses);
        for (name, s) in names.iter().zip(&mut sums) {
            let (cfg, mut opts) =
                client_setup(base.clone(), &tr.poses, "reactive", Planner::Dp, BUDGET);
            opts.predictor = Some(predictor(name, &tr.poses));
            let log = run_session(&dir, cfg, &tr.poses, &net, opts);
            let n = session_numbers(&log, &needed, &low, &net);
            eprintln!(
                "{:<14} {name:<28} warm {:<18} first {:<18} re {:<18} WD {}/{}",
                label(tr),
                pct(n.chr.warm),
                pct(n.chr.first),
                pct(n.chr.reentry),
                n.waste.wasted_tiles,
                n.waste.tiles
            );
            for (a, b) in [
                (&mut s.warm, n.chr.warm),
                (&mut s.first, n.chr.first),
                (&mut s.re, n.chr.reentry),
            ] {
                a.hits += b.hits;
                a.n += b.n;
            }
            s.wd_tiles.0 += n.waste.wasted_tiles;
            s.wd_tiles.1 += n.waste.tiles;
            s.wd_bytes.0 += n.waste.wasted_bytes;
            s.wd_bytes.1 += n.waste.bytes;
            s.mb += n.bytes_down as f64 / 1e6;
        }
    }
    println!("| predictor | after warm-up | first-time | re-entries | WD tiles | WD bytes | MB |");
    println!("|---|---:|---:|---:|---:|---:|---:|");
    for (name, s) in names.iter().zip(&sums) {
        println!(
            "| {name} | {} | {} | {} | {:.1}% | {:.1}% | {:.1} |",
            pct(s.warm),
            pct(s.first),
            pct(s.re),
            100.0 * s.wd_tiles.0 as f64 / s.wd_tiles.1.max(1) as f64,
            100.0 * s.wd_bytes.0 as f64 / s.wd_bytes.1.max(1) as f64,
            s.mb
        );
    }
}
