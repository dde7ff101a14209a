//! The simulated client: every trace tick it advances the network (requests with a round trip and
//! per-request overhead, a concurrency limit, the link shared equally by active transfers),
//! updates the EWMA estimate, measures what is visible, and replans every `replan_s` or when the
//! speed changes by more than 20% or a visible tile is neither resident nor requested.

use crate::stream::bandwidth::EwmaBandwidth;
use crate::stream::cache::{Cache, CacheConfig, EvictContext, Inserted};
use crate::stream::catalog::{Level, TileCatalog};
use crate::stream::geom::ViewPose;
use crate::stream::planner::{PlanStepConfig, plan_step};
use crate::stream::predict::{Predictor, needs_fallback, radius_tiles};
use crate::stream::visibility::cull_hierarchical;
use std::collections::VecDeque;

/// Network: piecewise constant bandwidth, round trip, per-request overhead.
#[derive(Debug, Clone, PartialEq)]
pub struct NetModel {
    /// `(start time s, bytes/s)` pieces, sorted; the first applies from 0.
    pub bandwidth: Vec<(f64, f64)>,
    /// Round trip before a response's first byte (s).
    pub rtt_s: f64,
    /// Header bytes per request.
    pub overhead_bytes: u64,
}

impl NetModel {
    /// A constant link of `mbps` megabits per second.
    pub fn constant(mbps: f64, rtt_s: f64) -> Self {
        NetModel {
            bandwidth: vec![(0.0, mbps * 1e6 / 8.0)],
            rtt_s,
            overhead_bytes: 400,
        }
    }

    fn rate(&self, t: f64) -> f64 {
        self.bandwidth
            .iter()
            .rev()
            .find(|(s, _)| *s <= t)
            .or(self.bandwidth.first())
            .map_or(0.0, |p| p.1)
    }

    fn next_change(&self, t: f64) -> f64 {
        self.bandwidth
            .iter()
            .map(|p| p.0)
            .find(|&s| s > t + 1e-12)
            .unwrap_or(f64::INFINITY)
    }
}

/// Client settings.
#[derive(Debug, Clone, PartialEq)]
pub struct SimConfig {
    /// Network.
    pub net: NetModel,
    /// Cache.
    pub cache: CacheConfig,
    /// Planning step settings (planner, DP step, horizon, intrinsics).
    pub plan: PlanStepConfig,
    /// Replan period (s) (TileSplat: every 2-3 s).
    pub replan_s: f64,
    /// Relative speed change that triggers a replan (0.2).
    pub speed_change: f64,
    /// Concurrent requests.
    pub concurrency: usize,
    /// Prediction sampling step (s).
    pub predict_step_s: f64,
    /// Fallback radius (m) of App. C.5 (TileSplat: 100 m).
    pub fallback_radius: f64,
    /// Seconds between quality samples.
    pub sample_s: f64,
}

impl Default for SimConfig {
    fn default() -> Self {
        SimConfig {
            net: NetModel::constant(50.0, 0.04),
            cache: CacheConfig::default(),
            plan: PlanStepConfig::default(),
            replan_s: 2.5,
            speed_change: 0.2,
            concurrency: 4,
            predict_step_s: 0.5,
            fallback_radius: 100.0,
            sample_s: 1.0,
        }
    }
}

/// One sampled frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameSample {
    /// Time (s).
    pub t: f64,
    /// Tiles visible.
    pub visible: usize,
    /// Of which resident.
    pub resident: usize,
    /// Mean utility over visible tiles (0 for missing ones; 1 when nothing is visible).
    pub quality: f64,
    /// SSIM against the full-quality view, when a renderer was given.
    pub ssim: Option<f64>,
    /// Bytes received so far.
    pub bytes: u64,
}

/// Totals of a session.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SimResult {
    /// Sampled frames.
    pub frames: Vec<FrameSample>,
    /// Cache hit rate: share of tile view entries (a tile becoming visible) already resident.
    pub chr: f64,
    /// Time to good quality: first sample with SSIM >= 0.90 (quality >= 0.90 without SSIM).
    pub tgq: Option<f64>,
    /// Wasted downloads: share of completed fetches whose tile is never visible afterwards.
    pub wd: f64,
    /// Same, by bytes.
    pub wd_bytes: f64,
    /// Bytes received (overheads included).
    pub bytes: u64,
    /// Mean sampled quality (utility).
    pub quality: f64,
    /// Mean sampled SSIM.
    pub ssim: Option<f64>,
    /// Share of deadline-bearing fetches completed after their deadline.
    pub miss_rate: f64,
    /// Completed fetches.
    pub fetches: usize,
    /// Planning steps run.
    pub plans: usize,
}

struct Transfer {
    tile: usize,
    level: Level,
    bytes_left: f64,
    lat_left: f64,
    deadline: f64,
}

struct Queued {
    tile: usize,
    level: Level,
    deadline: f64,
}

/// Runs one session over `trace`. `render_ssim(sample_index, pose, cache)` may return the SSIM of
/// the resident view against the full view.
pub fn run_session(
    cat: &TileCatalog,
    trace: &[ViewPose],
    predictor: &mut dyn Predictor,
    cfg: &SimConfig,
    mut render_ssim: impl FnMut(usize, &ViewPose, &Cache) -> Option<f64>,
) -> SimResult {
    let n = cat.tiles.len();
    let k = cfg.plan.intrinsics;
    // Ground truth visibility per tick (and each tile's last visible time, for WD).
    let mut vis_ticks: Vec<Vec<usize>> = Vec::with_capacity(trace.len());
    let mut last_seen = vec![f64::NEG_INFINITY; n];
    for p in trace {
        let mut v = vec![];
        cull_hierarchical(cat, p, &k, cfg.plan.max_sse, cfg.plan.vis_test, &mut v);
        for &i in &v {
            last_seen[i] = p.t;
        }
        vis_ticks.push(v);
    }
    let mut cache = Cache::new(cfg.cache);
    let mut bw = EwmaBandwidth::new(cfg.net.rate(0.0) * 0.5, 0.3, 0.5);
    let mut queue: VecDeque<Queued> = VecDeque::new();
    let mut active: Vec<Transfer> = vec![];
    let mut requested = vec![false; n];
    let mut visible = vec![false; n];
    let mut was_visible = vec![false; n];
    let (mut entries, mut hits) = (0usize, 0usize);
    let mut done: Vec<(usize, f64, u64)> = vec![];
    let (mut with_deadline, mut late) = (0usize, 0usize);
    let mut bytes = 0u64;
    let mut last_plan = f64::NEG_INFINITY;
    let mut plan_speed = 0.0;
    let mut res = SimResult::default();
    let mut next_sample = 0.0;
    let mut sample_idx = 0;
    let mut t_prev = trace.first().map_or(0.0, |p| p.t);
    for (tick, pose) in trace.iter().enumerate() {
        let t = pose.t;
        // 1. Network from t_prev to t.
        let mut tt = t_prev;
        let mut completed: Vec<Transfer> = vec![];
        while tt < t - 1e-12 {
            while active.len() < cfg.concurrency {
                let Some(q) = queue.pop_front() else { break };
                if cache.level(q.tile).is_some_and(|l| l <= q.level) {
                    requested[q.tile] = false;
                    continue;
                }
                let b = cat.tiles[q.tile].variants[q.level.index()].bytes + cfg.net.overhead_bytes;
                active.push(Transfer {
                    tile: q.tile,
                    level: q.level,
                    bytes_left: b as f64,
                    lat_left: cfg.net.rtt_s,
                    deadline: q.deadline,
                });
            }
            let rate = cfg.net.rate(tt);
            let n_data = active.iter().filter(|a| a.lat_left <= 0.0).count();
            let share = if n_data > 0 {
                rate / n_data as f64
            } else {
                0.0
            };
            let mut next = t.min(cfg.net.next_change(tt));
            for a in &active {
                if a.lat_left > 0.0 {
                    next = next.min(tt + a.lat_left.max(1e-9));
                } else if share > 0.0 {
                    next = next.min(tt + (a.bytes_left / share).max(1e-9));
                }
            }
            let step = (next - tt).max(0.0);
            let mut got = 0.0;
            for a in active.iter_mut() {
                if a.lat_left > 0.0 {
                    a.lat_left -= step;
                    if a.lat_left < 1e-9 {
                        a.lat_left = 0.0;
                    }
                } else {
                    let g = (share * step).min(a.bytes_left);
                    a.bytes_left -= g;
                    got += g;
                }
            }
            bw.record(got, if n_data > 0 { step } else { 0.0 });
            bytes += got.round() as u64;
            tt = next;
            let mut i = 0;
            while i < active.len() {
                if active[i].lat_left <= 1e-12 && active[i].bytes_left <= 1e-6 {
                    completed.push(active.swap_remove(i));
                } else {
                    i += 1;
                }
            }
            if active.is_empty() && queue.is_empty() {
                break;
            }
        }
        t_prev = t;
        bw.tick(t);
        // 2. Visibility now.
        for v in visible.iter_mut() {
            *v = false;
        }
        for &i in &vis_ticks[tick] {
            visible[i] = true;
        }
        for tr in completed {
            requested[tr.tile] = false;
            let b = cat.tiles[tr.tile].variants[tr.level.index()].bytes;
            let ctx = EvictContext {
                catalog: cat,
                pos: pose.pos,
                now: t,
                visible: &visible,
            };
            if tr.deadline.is_finite() {
                with_deadline += 1;
                if t > tr.deadline + 1e-9 {
                    late += 1;
                }
            }
            match cache.insert(tr.tile, tr.level, b, &ctx) {
                Inserted::Stored(_) | Inserted::Kept => done.push((tr.tile, t, b)),
                Inserted::Rejected => done.push((tr.tile, f64::INFINITY, b)),
            }
        }
        cache.touch(&vis_ticks[tick], t);
        for &i in &vis_ticks[tick] {
            if !was_visible[i] {
                entries += 1;
                if cache.level(i).is_some() {
                    hits += 1;
                }
            }
        }
        std::mem::swap(&mut was_visible, &mut visible);
        let visible = &was_visible;
        // 3. Replan?
        let speed = speed_at(trace, tick, 0.5);
        let speed_jump = (speed - plan_speed).abs() > cfg.speed_change * plan_speed.max(0.05);
        let missing = vis_ticks[tick]
            .iter()
            .any(|&i| cache.level(i).is_none() && !requested[i]);
        if t - last_plan >= cfg.replan_s || speed_jump || missing {
            last_plan = t;
            plan_speed = speed;
            res.plans += 1;
            let history = &trace[..=tick];
            let in_flight: Vec<usize> = active.iter().map(|a| a.tile).collect();
            for q in queue.drain(..) {
                requested[q.tile] = false;
            }
            for &i in &in_flight {
                requested[i] = true;
            }
            let mut push = |q: Queued, requested: &mut Vec<bool>| {
                if !requested[q.tile] {
                    requested[q.tile] = true;
                    queue.push_back(q);
                }
            };
            if needs_fallback(predictor, history) {
                // App. C.5: radius fetch at Medium until the predictor has its history; tiles
                // in view first.
                for &i in &vis_ticks[tick] {
                    if cache.level(i).is_none() {
                        push(
                            Queued {
                                tile: i,
                                level: Level::Medium,
                                deadline: f64::INFINITY,
                            },
                            &mut requested,
                        );
                    }
                }
                for i in radius_tiles(cat, pose.pos, cfg.fallback_radius) {
                    if cache.level(i).is_none() {
                        push(
                            Queued {
                                tile: i,
                                level: Level::Medium,
                                deadline: f64::INFINITY,
                            },
                            &mut requested,
                        );
                    }
                }
            } else {
                let predicted = predictor.predict(history, cfg.plan.horizon_s, cfg.predict_step_s);
                let pinned: u64 = cache
                    .resident()
                    .filter(|(i, _)| visible[*i])
                    .map(|(_, e)| e.bytes)
                    .sum();
                let budget = cfg.cache.capacity_bytes.saturating_sub(pinned);
                let (cands, plan) = plan_step(
                    cat,
                    pose,
                    &predicted,
                    &cfg.plan,
                    bw.estimate(),
                    |i| cache.level(i),
                    budget,
                );
                for f in &plan.fetches {
                    let c = &cands[f.candidate];
                    push(
                        Queued {
                            tile: c.tile,
                            level: f.level,
                            deadline: t + c.deadline,
                        },
                        &mut requested,
                    );
                }
            }
        }
        // 4. Sample.
        if t + 1e-9 >= next_sample {
            next_sample += cfg.sample_s;
            let vis = &vis_ticks[tick];
            let quality = if vis.is_empty() {
                1.0
            } else {
                vis.iter()
                    .map(|&i| {
                        cache
                            .level(i)
                            .map_or(0.0, |l| cat.tiles[i].variants[l.index()].utility)
                    })
                    .sum::<f64>()
                    / vis.len() as f64
            };
            let ssim = render_ssim(sample_idx, pose, &cache);
            sample_idx += 1;
            res.frames.push(FrameSample {
                t,
                visible: vis.len(),
                resident: vis.iter().filter(|&&i| cache.level(i).is_some()).count(),
                quality,
                ssim,
                bytes,
            });
        }
    }
    res.chr = if entries > 0 {
        hits as f64 / entries as f64
    } else {
        1.0
    };
    let wasted: Vec<&(usize, f64, u64)> = done.iter().filter(|d| last_seen[d.0] < d.1).collect();
    res.fetches = done.len();
    res.wd = if done.is_empty() {
        0.0
    } else {
        wasted.len() as f64 / done.len() as f64
    };
    let all_b: u64 = done.iter().map(|d| d.2).sum();
    res.wd_bytes = if all_b > 0 {
        wasted.iter().map(|d| d.2).sum::<u64>() as f64 / all_b as f64
    } else {
        0.0
    };
    res.bytes = bytes;
    res.miss_rate = if with_deadline > 0 {
        late as f64 / with_deadline as f64
    } else {
        0.0
    };
    let nf = res.frames.len().max(1) as f64;
    res.quality = res.frames.iter().map(|f| f.quality).sum::<f64>() / nf;
    let ss: Vec<f64> = res.frames.iter().filter_map(|f| f.ssim).collect();
    res.ssim = (!ss.is_empty()).then(|| ss.iter().sum::<f64>() / ss.len() as f64);
    res.tgq = res
        .frames
        .iter()
        .find(|f| f.ssim.unwrap_or(f.quality) >= 0.90)
        .map(|f| f.t - trace.first().map_or(0.0, |p| p.t));
    res
}

/// Mean speed over the last `window` seconds ending at `tick`.
fn speed_at(trace: &[ViewPose], tick: usize, window: f64) -> f64 {
    let now = &trace[tick];
    let start = trace[..=tick]
        .iter()
        .rev()
        .find(|p| now.t - p.t >= window)
        .unwrap_or(&trace[0]);
    let dt = now.t - start.t;
    if dt > 1e-9 {
        now.pos.distance(start.pos) / dt
    } else {
        0.0
    }
}
