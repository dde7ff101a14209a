//! One client session and its numbers, shared by the city experiment and `simulate --tileset`:
//! the client set-up, the needed cuts, CHR with the link warm-up, waste, stalls, quality and TGQ.

use super::score::{Chr, EventRule, Truth, WarmUp, Waste, events};
use super::score::{cache_hits_with, link_warm_up};
use super::score::{drawn_is_needed_at_best, held_tiles, tick_views, time_to_quality, wasted};
use super::session::{SessionLog, SessionOptions, run_session};
use super::transport::{NetModel, Outcome};
use glam::DVec3;
use splat2tiles_render::{Image, ssim};
use splat2tiles_stream::catalog::Level;
use splat2tiles_stream::client::{ClientConfig, PredictorKind};
use splat2tiles_stream::geom::ViewPose;
use splat2tiles_stream::plan::Planner;
use splat2tiles_stream::predict::{Oracle, Predictor};
use splat2tiles_tiles::tiling::TileKey;
use std::collections::{HashMap, HashSet};
use std::path::Path;

/// Quality samples per second after an event (TGQ).
pub const TGQ_HZ: f64 = 4.0;
/// Seconds after an event within which TGQ is looked for (not reached: counted as this).
pub const TGQ_WINDOW_S: f64 = 5.0;
/// Quality render size (the client's 1280x720 view at half size).
pub const QW: u32 = 640;
/// Quality render height.
pub const QH: u32 = 360;
/// SSIM counted as good quality.
pub const GOOD: f64 = 0.9;

/// The predictor names [`session`] accepts besides [`PredictorKind::from_name`]'s: the oracle
/// of the trace and the oracle of the trace mirrored about its start.
pub const ORACLES: [&str; 2] = ["oracle", "oracle, mirrored"];

/// A trace mirrored about its first position (heading turned by 180 degrees).
pub fn mirrored(poses: &[ViewPose]) -> Vec<ViewPose> {
    let Some(o) = poses.first().map(|p| p.pos) else {
        return vec![];
    };
    poses
        .iter()
        .map(|p| ViewPose {
            pos: DVec3::new(2.0 * o.x - p.pos.x, 2.0 * o.y - p.pos.y, p.pos.z),
            yaw: p.yaw + std::f64::consts::PI,
            ..*p
        })
        .collect()
}

/// Whether [`session`] knows `predictor` (a [`PredictorKind`] name or one of [`ORACLES`]).
pub fn known_predictor(predictor: &str) -> bool {
    PredictorKind::from_name(predictor).is_some() || ORACLES.contains(&predictor)
}

/// The client of the experiments: `base` (viewport, SSE, ...) with `predictor`'s kind (the
/// oracles run on a reactive config with their own predictor), `planner` and `budget` bytes,
/// and the session options that carry an oracle.
pub fn client_setup(
    base: ClientConfig,
    poses: &[ViewPose],
    predictor: &str,
    planner: Planner,
    budget: u64,
) -> (ClientConfig, SessionOptions) {
    let kind = PredictorKind::from_name(predictor).unwrap_or(PredictorKind::Reactive);
    let oracle: Option<Vec<ViewPose>> = match predictor {
        "oracle" => Some(poses.to_vec()),
        "oracle, mirrored" => Some(mirrored(poses)),
        _ => None,
    };
    let mut cfg = ClientConfig {
        predictor: kind,
        memory_budget_bytes: budget,
        ..base
    };
    cfg.plan.planner = planner;
    let opts = SessionOptions {
        predictor: oracle.map(|trace| Box::new(Oracle { trace }) as Box<dyn Predictor + Send>),
        record_inputs: false,
    };
    (cfg, opts)
}

/// One session of `predictor` planned by `planner` with the experiments' client (the default
/// config with 4 requests in flight).
pub fn session(
    dir: &Path,
    poses: &[ViewPose],
    predictor: &str,
    planner: Planner,
    net: &NetModel,
    budget: u64,
) -> SessionLog {
    let base = ClientConfig {
        max_concurrent: 4,
        ..ClientConfig::default()
    };
    let (cfg, opts) = client_setup(base, poses, predictor, planner, budget);
    run_session(dir, cfg, poses, net, opts)
}

/// The needed cut of `cfg`'s viewport and SSE at every pose.
pub fn needed_cuts(truth: &Truth, cfg: &ClientConfig, poses: &[ViewPose]) -> Vec<Vec<TileKey>> {
    poses.iter().map(|p| truth.needed_at(cfg, p)).collect()
}

/// Completed content downloads `(tile, bytes, end)`.
pub fn downloads(log: &SessionLog) -> Vec<(TileKey, u64, f64)> {
    log.requests
        .iter()
        .filter(|r| r.outcome == Outcome::Done)
        .filter_map(|r| Some((r.key?, r.bytes, r.end_s?)))
        .collect()
}

/// The numbers of one session against the needed cuts.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SessionNumbers {
    /// CHR over entries into the needed cut, warm from [`Self::warm_at`].
    pub chr: Chr,
    /// Completed downloads and those of tiles in no needed cut from their end on.
    pub waste: Waste,
    /// End of the warm-up ([`link_warm_up`] with the tiles' Low bytes), seconds.
    pub warm_at: f64,
    /// Body bytes received over the session.
    pub bytes_down: u64,
    /// Tiles the client evicted.
    pub evictions: u64,
    /// Ticks with a stall ([`stalls`]).
    pub stall_ticks: usize,
}

/// [`SessionNumbers`] of `log` against `needed` (one cut per tick): the warm-up is the time
/// `net` needs at its rate at 0 s for the first cut at Low (`low_bytes` per tile, 0 if absent)
/// plus one round trip, the same for every predictor and planner.
pub fn session_numbers(
    log: &SessionLog,
    needed: &[Vec<TileKey>],
    low_bytes: &HashMap<TileKey, u64>,
    net: &NetModel,
) -> SessionNumbers {
    let held = held_tiles(log);
    let vs = tick_views(log, needed.iter().map(Vec::as_slice), &held);
    let warm_at = link_warm_up(
        &vs,
        |k| low_bytes.get(k).copied().unwrap_or(0),
        net.rate(0.0),
        net.rtt_s,
    );
    let chr = cache_hits_with(&vs, WarmUp::At(warm_at));
    let waste = wasted(&downloads(log), &vs);
    SessionNumbers {
        chr,
        waste,
        warm_at,
        bytes_down: log.ticks.last().map_or(0, |t| t.bytes_down),
        evictions: log.evictions,
        stall_ticks: stalls(log, needed).iter().filter(|&&s| s).count(),
    }
}

/// Per tick: whether it stalled, i.e. a tile of its needed cut had neither itself nor any
/// ancestor drawn (a hole in the picture).
pub fn stalls(log: &SessionLog, needed: &[Vec<TileKey>]) -> Vec<bool> {
    log.ticks
        .iter()
        .zip(needed)
        .map(|(t, n)| {
            let drawn: HashSet<TileKey> = t.drawn.iter().map(|d| d.0).collect();
            n.iter().any(|&k| {
                let mut cur = Some(k);
                while let Some(c) = cur {
                    if drawn.contains(&c) {
                        return false;
                    }
                    cur = c.parent();
                }
                true
            })
        })
        .collect()
}

/// Quality at tick `k` of a session: SSIM at [`QW`]x[`QH`] of what it drew against the needed
/// cut at Best (1 without rendering when it drew exactly that, or nothing was needed). `refs`
/// caches the reference renders by tick (shared across sessions on the same trace).
pub fn quality(
    truth: &mut Truth,
    needed: &[Vec<TileKey>],
    refs: &mut HashMap<usize, Image>,
    log: &SessionLog,
    k: usize,
) -> anyhow::Result<f64> {
    let needed = &needed[k];
    let drawn: Vec<(TileKey, Level)> = log.ticks[k].drawn.iter().map(|d| (d.0, d.1)).collect();
    if needed.is_empty() {
        return Ok(1.0);
    }
    if drawn_is_needed_at_best(needed, &drawn) {
        return Ok(1.0);
    }
    let c = ClientConfig::default();
    let cam = splat2tiles_core::camera::Camera::from_pose(
        c.width,
        c.height,
        c.fov_y_deg,
        truth.root_transform() * log.ticks[k].pose.world_from_camera(),
    )
    .resized(QW, QH);
    if let std::collections::hash_map::Entry::Vacant(e) = refs.entry(k) {
        let best: Vec<(TileKey, Level)> = needed.iter().map(|k| (*k, Level::Best)).collect();
        e.insert(truth.render(&best, &cam)?);
    }
    let got = truth.render(&drawn, &cam)?;
    Ok(ssim(&got, &refs[&k])?)
}

/// TGQ of one session per event (`score::events`): quality sampled at [`TGQ_HZ`] from the event
/// until it reaches [`GOOD`], the next event or [`TGQ_WINDOW_S`] (`None`: not reached). The
/// first event (the cold start) comes back apart. Also returns the samples rendered.
pub fn tgq(
    truth: &mut Truth,
    needed: &[Vec<TileKey>],
    refs: &mut HashMap<usize, Image>,
    log: &SessionLog,
) -> anyhow::Result<(Option<f64>, Vec<Option<f64>>, usize)> {
    let ev = {
        let held = held_tiles(log);
        let vs = tick_views(log, needed.iter().map(Vec::as_slice), &held);
        let yaw: Vec<f64> = log.ticks.iter().map(|t| t.pose.yaw.to_degrees()).collect();
        events(&vs, &yaw, &EventRule::default())
    };
    let mut out = vec![];
    let mut rendered = 0;
    for (j, &e) in ev.iter().enumerate() {
        let end = ev
            .get(j + 1)
            .copied()
            .unwrap_or(f64::INFINITY)
            .min(e + TGQ_WINDOW_S);
        let mut samples = vec![];
        let mut next = e;
        for k in 0..log.ticks.len() {
            let t = log.ticks[k].t;
            if t + 1e-9 < next {
                continue;
            }
            if t >= end {
                break;
            }
            next = t + 1.0 / TGQ_HZ;
            let q = quality(truth, needed, refs, log, k)?;
            rendered += 1;
            samples.push((t, q));
            if q >= GOOD {
                break;
            }
        }
        out.push(time_to_quality(&[e], &samples, GOOD)[0]);
    }
    let cold = if out.is_empty() { None } else { out.remove(0) };
    Ok((cold, out, rendered))
}

/// Mean time to good quality over events, an event that does not reach it within
/// [`TGQ_WINDOW_S`] counted as the window, and how many did not; `None` without events.
pub fn tgq_mean(v: &[Option<f64>]) -> Option<(f64, usize)> {
    if v.is_empty() {
        return None;
    }
    let sum: f64 = v.iter().map(|x| x.unwrap_or(TGQ_WINDOW_S)).sum();
    let missed = v.iter().filter(|x| x.is_none()).count();
    Some((sum / v.len() as f64, missed))
}

/// `a` as a percentage of `b` with one decimal, or "-" when `b` is 0.
pub fn percent(a: u64, b: u64) -> String {
    if b == 0 {
        "-".to_string()
    } else {
        format!("{:.1}%", 100.0 * a as f64 / b as f64)
    }
}
