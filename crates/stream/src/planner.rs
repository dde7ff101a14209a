//! One planning step of the client (TileSplat App. C.5 steps 4-6): predicted poses -> visible
//! tiles per pose (hierarchical culling) -> first visibility time per tile -> deadlines ->
//! quality selection. Tiles visible now get the deadline `urgent_s`; resident tiles are offered as
//! upgrades whose utility is the gain over the resident level.

use super::catalog::{LEVELS, Level, TileCatalog, Variant};
use super::geom::{Intrinsics, ViewPose};
use super::plan::{Candidate, Fetch, Plan, PlanRequest, Planner};
use super::visibility::{VisTest, cull_hierarchical};

/// Most DP time steps a plan uses (horizon / step is cut to it): 200 s at 10 ms.
pub const MAX_PLAN_STEPS: usize = 20_000;

/// Settings of a planning step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlanStepConfig {
    /// Camera intrinsics.
    pub intrinsics: Intrinsics,
    /// Screen-space error threshold in pixels for LOD refinement.
    pub max_sse: f64,
    /// Frustum test.
    pub vis_test: VisTest,
    /// Time step of the link forecast the DP plans over (s); the DP itself runs over bytes.
    pub step_s: f64,
    /// DP horizon (s).
    pub horizon_s: f64,
    /// Deadline given to tiles visible now (s).
    pub urgent_s: f64,
    /// Algorithm.
    pub planner: Planner,
    /// Round trip per request (s).
    pub latency_s: f64,
    /// Requests the client keeps in flight: their round trips overlap, so the plan charges
    /// `latency_s / concurrency` per request and keeps the first `latency_s * (1 - 1 /
    /// concurrency)` of the link free of new bytes (the first request still waits a whole round
    /// trip). 1 (the default): requests one after another, each paying its round trip.
    pub concurrency: usize,
    /// Byte bins of the DP ([`PlanRequest::bins`]; 0: the default).
    pub bins: usize,
}

impl Default for PlanStepConfig {
    fn default() -> Self {
        PlanStepConfig {
            intrinsics: Intrinsics::default(),
            max_sse: 16.0,
            vis_test: VisTest::Planes,
            step_s: 0.1,
            horizon_s: 30.0,
            urgent_s: 1.0,
            planner: Planner::Dp,
            latency_s: 0.0,
            concurrency: 1,
            bins: 0,
        }
    }
}

/// First time (seconds after `current.t`) each tile is visible along `current` followed by
/// `predicted`; sorted by tile index.
pub fn first_visibility(
    cat: &TileCatalog,
    current: &ViewPose,
    predicted: &[ViewPose],
    cfg: &PlanStepConfig,
) -> Vec<(usize, f64)> {
    let mut first = vec![f64::INFINITY; cat.tiles.len()];
    let mut vis = Vec::new();
    for p in std::iter::once(current).chain(predicted.iter()) {
        vis.clear();
        cull_hierarchical(cat, p, &cfg.intrinsics, cfg.max_sse, cfg.vis_test, &mut vis);
        let dt = (p.t - current.t).max(0.0);
        for &i in &vis {
            if dt < first[i] {
                first[i] = dt;
            }
        }
    }
    first
        .iter()
        .enumerate()
        .filter(|(_, t)| t.is_finite())
        .map(|(i, t)| (i, *t))
        .collect()
}

/// A full planning step. `bandwidth` is the estimate in bytes/s, `resident` the level held per
/// tile, `memory_budget` the bytes the new downloads may take. Returns the candidates and the
/// plan; tiles visible now that the planner could not fit are appended at Low (they are needed
/// whatever the deadline says).
pub fn plan_step(
    cat: &TileCatalog,
    current: &ViewPose,
    predicted: &[ViewPose],
    cfg: &PlanStepConfig,
    bandwidth: f64,
    resident: impl Fn(usize) -> Option<Level>,
    memory_budget: u64,
) -> (Vec<Candidate>, Plan) {
    let firsts = first_visibility(cat, current, predicted, cfg);
    plan_visible(
        cat,
        current.pos,
        &firsts,
        cfg,
        bandwidth,
        resident,
        memory_budget,
    )
}

/// What the planner knows of the link when it plans.
#[derive(Debug, Clone, PartialEq)]
pub struct LinkForecast {
    /// `(seconds from now, bytes/s)` pieces, sorted, the first from 0, the last holding to the
    /// horizon: `EwmaBandwidth::forecast`, or `bandwidth::future_pieces` of the trace for an
    /// oracle network.
    pub pieces: Vec<(f64, f64)>,
    /// Bytes still to arrive for requests already issued; the link carries them first.
    pub in_flight_bytes: u64,
}

impl LinkForecast {
    /// A constant rate, nothing in flight.
    pub fn constant(bytes_per_s: f64) -> Self {
        LinkForecast {
            pieces: vec![(0.0, bytes_per_s)],
            in_flight_bytes: 0,
        }
    }

    /// The link as the DP sees it: bytes/s per step of `cfg.step_s` over `steps` steps, with
    /// the in-flight bytes and the front round trip (see [`PlanStepConfig::concurrency`]) taken
    /// off the front.
    pub fn steps(&self, cfg: &PlanStepConfig, steps: usize) -> Vec<f64> {
        let mut r = super::bandwidth::per_step(&self.pieces, cfg.step_s, steps);
        super::bandwidth::deduct_in_flight(&mut r, cfg.step_s, self.in_flight_bytes);
        let c = cfg.concurrency.max(1) as f64;
        let gap = cfg.latency_s.max(0.0) * (1.0 - 1.0 / c);
        if gap > 0.0 && cfg.step_s > 0.0 {
            for (i, v) in r.iter_mut().enumerate() {
                let a = i as f64 * cfg.step_s;
                if a >= gap {
                    break;
                }
                *v *= ((a + cfg.step_s - gap) / cfg.step_s).clamp(0.0, 1.0);
            }
        }
        r
    }
}

/// The quality-selection half of [`plan_step`] for visibility computed by the caller: `firsts`
/// holds `(tile, seconds until first visible)` (0 = visible now), `pos` is the camera position
/// (tileset frame) for distances. Tiles visible now that the planner could not fit are appended
/// at Low.
pub fn plan_visible(
    cat: &TileCatalog,
    pos: glam::DVec3,
    firsts: &[(usize, f64)],
    cfg: &PlanStepConfig,
    bandwidth: f64,
    resident: impl Fn(usize) -> Option<Level>,
    memory_budget: u64,
) -> (Vec<Candidate>, Plan) {
    plan_visible_link(
        cat,
        pos,
        firsts,
        cfg,
        &LinkForecast::constant(bandwidth),
        resident,
        memory_budget,
    )
}

/// [`plan_visible`] over a [`LinkForecast`]: piecewise bandwidth, bytes in flight, and the round
/// trip as [`PlanStepConfig::latency_s`] and [`PlanStepConfig::concurrency`] say.
pub fn plan_visible_link(
    cat: &TileCatalog,
    pos: glam::DVec3,
    firsts: &[(usize, f64)],
    cfg: &PlanStepConfig,
    link: &LinkForecast,
    resident: impl Fn(usize) -> Option<Level>,
    memory_budget: u64,
) -> (Vec<Candidate>, Plan) {
    // By first visibility: the DP orders candidates by deadline, ties by input order, and every
    // tile due within `urgent_s` gets that deadline; in the caller's tile order a tile entering
    // in 0.1 s waited behind ones entering in 0.9 s (the oracle's late misses).
    let mut order: Vec<(usize, f64)> = firsts.to_vec();
    order.sort_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)));
    let mut cands = Vec::with_capacity(order.len());
    for (tile, tf) in order {
        let Some(t) = cat.tiles.get(tile) else {
            continue;
        };
        let base = resident(tile).map(|l| t.variants[l.index()].utility);
        if resident(tile) == Some(Level::Best) {
            continue;
        }
        let variants: [Variant; LEVELS] = std::array::from_fn(|j| {
            let v = t.variants[j];
            Variant {
                bytes: v.bytes,
                utility: match base {
                    Some(b) => (v.utility - b).max(0.0),
                    None => v.utility,
                },
            }
        });
        if base.is_some() && variants.iter().all(|v| v.utility <= 0.0) {
            continue;
        }
        cands.push(Candidate {
            tile,
            deadline: tf.max(cfg.urgent_s),
            distance: t.bbox.distance(pos),
            variants,
        });
    }
    // Bounded: the link forecast holds one rate per step.
    let steps = (cfg.horizon_s / cfg.step_s)
        .round()
        .clamp(1.0, MAX_PLAN_STEPS as f64) as usize;
    let simple = link.pieces.len() == 1 && link.in_flight_bytes == 0 && cfg.concurrency <= 1;
    let bw = if simple {
        vec![link.pieces[0].1]
    } else {
        link.steps(cfg, steps)
    };
    let req = PlanRequest {
        candidates: &cands,
        bandwidth: &bw,
        step_s: cfg.step_s,
        horizon_steps: steps,
        memory_budget,
        latency_s: cfg.latency_s / cfg.concurrency.max(1) as f64,
        bins: cfg.bins,
    };
    let mut plan = cfg.planner.solve(&req);
    let mut chosen = vec![false; cands.len()];
    for f in &plan.fetches {
        chosen[f.candidate] = true;
    }
    for (ci, c) in cands.iter().enumerate() {
        if !chosen[ci] && c.deadline <= cfg.urgent_s && resident(c.tile).is_none() {
            let v = c.variants[Level::Low.index()];
            plan.fetches.push(Fetch {
                candidate: ci,
                level: Level::Low,
                finish_s: f64::INFINITY,
            });
            plan.bytes += v.bytes;
        }
    }
    (cands, plan)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plan::solve_dp;
    use crate::{EwmaBandwidth, TileCatalog};
    use glam::DVec3;

    /// One 1 MB tile first visible in 1.5 s; the link carries its Best in 1 s.
    fn one_tile() -> (TileCatalog, f64, PlanStepConfig) {
        let cat = TileCatalog::synthetic(1, (1.0, 1.0), 7);
        let rate = cat.tiles[0].variants[0].bytes as f64;
        let cfg = PlanStepConfig {
            step_s: 0.01,
            horizon_s: 10.0,
            ..PlanStepConfig::default()
        };
        (cat, rate, cfg)
    }

    fn plan(cat: &TileCatalog, cfg: &PlanStepConfig, link: &LinkForecast) -> Plan {
        plan_visible_link(cat, DVec3::ZERO, &[(0, 1.5)], cfg, link, |_| None, u64::MAX).1
    }

    #[test]
    fn bytes_in_flight_come_first() {
        let (cat, rate, cfg) = one_tile();
        let free = plan(&cat, &cfg, &LinkForecast::constant(rate));
        assert_eq!(free.fetches.len(), 1);
        assert_eq!(free.fetches[0].level, Level::Best);
        // 0.4 s of bytes still arriving: Best would finish at 1.4, still on time.
        let mut link = LinkForecast::constant(rate);
        link.in_flight_bytes = (rate * 0.4) as u64;
        assert_eq!(plan(&cat, &cfg, &link).fetches[0].level, Level::Best);
        // 0.6 s: Best would be late (1.6 s), a smaller level is chosen.
        link.in_flight_bytes = (rate * 0.6) as u64;
        let p = plan(&cat, &cfg, &link);
        assert_eq!(p.fetches.len(), 1);
        assert_ne!(p.fetches[0].level, Level::Best);
        // 2 s in flight: nothing new can arrive by 1.5 s.
        link.in_flight_bytes = (rate * 2.0) as u64;
        assert!(plan(&cat, &cfg, &link).fetches.is_empty());
    }

    #[test]
    fn the_round_trip_is_charged_once_per_concurrent_batch() {
        let (cat, rate, mut cfg) = one_tile();
        cfg.latency_s = 0.6;
        // One request at a time: Best takes 1.0 + 0.6 > 1.5 s, so a smaller level is chosen and
        // finishes no earlier than its round trip.
        let p = plan(&cat, &cfg, &LinkForecast::constant(rate));
        assert_eq!(p.fetches.len(), 1);
        assert_ne!(p.fetches[0].level, Level::Best);
        assert!(p.fetches[0].finish_s >= 0.6);
        // Four in flight: the first request still waits 0.45 + 0.15 = 0.6 s of round trip.
        cfg.concurrency = 4;
        let link = LinkForecast::constant(rate);
        let r = link.steps(&cfg, 100);
        assert!(r[..44].iter().all(|&v| v == 0.0) && r[44] < 1.0 && r[45] == rate);
        let p = plan(&cat, &cfg, &link);
        assert_ne!(p.fetches[0].level, Level::Best);
        // Without a round trip, Best.
        cfg.latency_s = 0.0;
        assert_eq!(plan(&cat, &cfg, &link).fetches[0].level, Level::Best);
    }

    #[test]
    fn piecewise_bandwidth_reaches_the_plan() {
        let (cat, rate, cfg) = one_tile();
        // Nothing for 1 s, then 10x: Best arrives at 1.1 s, on time.
        let late = LinkForecast {
            pieces: vec![(0.0, 0.0), (1.0, 10.0 * rate)],
            in_flight_bytes: 0,
        };
        let p = plan(&cat, &cfg, &late);
        assert_eq!(p.fetches[0].level, Level::Best);
        // The same mean rate as a constant would say Best arrives at 0.18 s; a link that dies
        // after 0.5 s leaves room only for what fits before.
        let dying = LinkForecast {
            pieces: vec![(0.0, rate * 0.5), (0.5, 0.0)],
            in_flight_bytes: 0,
        };
        let p = plan(&cat, &cfg, &dying);
        assert!(p.fetches.iter().all(|f| f.level != Level::Best));
        // The estimator's forecast as pieces: the estimate (1.43 x) says Best arrives in 0.7 s,
        // but the last window measured 0.1 x and the forecast climbs back only gradually
        // (0.69 MB by 1.5 s), so the plan takes a smaller level.
        let mut e = EwmaBandwidth::new(rate * 0.2, 0.3, 0.5);
        e.record(rate * 2.0, 1.0);
        e.tick(0.5);
        e.record(rate * 0.1, 1.0);
        e.tick(1.0);
        let f = LinkForecast {
            pieces: e.forecast(cfg.horizon_s),
            in_flight_bytes: 0,
        };
        assert!(f.pieces.len() > 1);
        let with = plan(&cat, &cfg, &f);
        let flat = plan(&cat, &cfg, &LinkForecast::constant(e.estimate()));
        assert_eq!(flat.fetches[0].level, Level::Best);
        assert_eq!(with.fetches.len(), 1);
        assert_ne!(with.fetches[0].level, Level::Best);
    }

    /// No step caps the fetches per second: tiles of 5-20 KB at 10 Mbit/s (62-250 per second)
    /// all due in 1 s fill the link whatever the forecast's step (a DP over 100 ms steps held
    /// 10 of them).
    #[test]
    fn small_tiles_fill_the_link_at_any_step() {
        let v = |b: u64, u: f64| crate::catalog::Variant {
            bytes: b,
            utility: u,
        };
        let cands: Vec<Candidate> = (0..80)
            .map(|i| Candidate {
                tile: i,
                deadline: 1.0,
                distance: 0.0,
                variants: [
                    v(20_000, 1.0),
                    v(15_000, 0.9),
                    v(10_000, 0.8),
                    v(5_000, 0.5),
                ],
            })
            .collect();
        let plan = |step_s: f64| {
            solve_dp(&PlanRequest {
                candidates: &cands,
                bandwidth: &[1.25e6],
                step_s,
                horizon_steps: (2.0 / step_s).round() as usize,
                memory_budget: u64::MAX,
                latency_s: 0.0,
                bins: 0,
            })
        };
        for step in [0.1, 0.01] {
            let p = plan(step);
            assert_eq!(p.fetches.len(), 80, "step {step}");
            // 1.25 MB by the deadline: within a bin's rounding per download of full.
            assert!(p.bytes <= 1_250_000 && p.bytes > 1_150_000, "{}", p.bytes);
            assert!(p.fetches.iter().all(|f| f.finish_s <= 1.0 + 1e-9));
        }
    }
}
