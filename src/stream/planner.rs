//! One planning step of the client (TileSplat App. C.5 steps 4-6): predicted poses -> visible
//! tiles per pose (hierarchical culling) -> first visibility time per tile -> deadlines ->
//! quality selection. Tiles visible now get the deadline `urgent_s`; resident tiles are offered as
//! upgrades whose utility is the gain over the resident level.

use super::catalog::{LEVELS, Level, TileCatalog, Variant};
use super::geom::{Intrinsics, ViewPose};
use super::plan::{Candidate, Fetch, Plan, PlanRequest, Planner};
use super::visibility::{VisTest, cull_hierarchical};

/// Settings of a planning step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlanStepConfig {
    /// Camera intrinsics.
    pub intrinsics: Intrinsics,
    /// Screen-space error threshold in pixels for LOD refinement.
    pub max_sse: f64,
    /// Frustum test.
    pub vis_test: VisTest,
    /// DP time step (s).
    pub step_s: f64,
    /// DP horizon (s).
    pub horizon_s: f64,
    /// Deadline given to tiles visible now (s).
    pub urgent_s: f64,
    /// Algorithm.
    pub planner: Planner,
    /// Round trip per request (s).
    pub latency_s: f64,
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
    let mut cands = Vec::with_capacity(firsts.len());
    for &(tile, tf) in firsts {
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
    let steps = (cfg.horizon_s / cfg.step_s).round().max(1.0) as usize;
    let bw = [bandwidth];
    let req = PlanRequest {
        candidates: &cands,
        bandwidth: &bw,
        step_s: cfg.step_s,
        horizon_steps: steps,
        memory_budget,
        latency_s: cfg.latency_s,
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
