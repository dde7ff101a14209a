//! The converter's side of view-optimised partitioning: from the splat centres and a tuning set of
//! traces, the tree DP's choice as the set of tiles that must be split (`convert --partition`).
//!
//! The basic cuboids are the tree's cells at `depth`; a cell's box is the AABB of its centres in
//! the tileset frame (what the client culls with: tight tile boxes). A view needs the non-empty
//! cells its frustum meets up to `range_m` (the distance within which it needs full detail).

use super::cost::{CostModel, View};
use super::grid::Grid;
use super::tree::optimise;
use glam::DVec3;
use splat2tiles_stream::geom::{Frustum, Intrinsics, Obb};
use splat2tiles_stream::split::TuningSet;
use splat2tiles_stream::trace::Trace;
use splat2tiles_stream::visibility::{exact_test, planes_test};
use splat2tiles_tiles::tiling::partition::{Scheme, TileKey};
use std::collections::BTreeSet;
use std::path::Path;

/// What `--partition views:DIR` asks for.
#[derive(Debug, Clone)]
pub struct PartitionRequest {
    /// The view distribution: train and val traces only.
    pub views: TuningSet,
    /// Tree depth of the basic cuboids; `None`: [`default_depth`].
    pub depth: Option<u32>,
    /// Full-detail distance of a view (the frustum's far plane), metres.
    pub range_m: f64,
    /// One view per this many seconds of each trace.
    pub every_s: f64,
}

/// Default basic-cuboid depth: 2^20 cells at most (quadtree 10, octree 6).
pub fn default_depth(scheme: Scheme) -> u32 {
    match scheme {
        Scheme::Quadtree => 10,
        Scheme::Octree => 6,
    }
}

/// The most trace files and bytes `views:DIR` reads.
pub const MAX_TRACE_FILES: usize = 10_000;
/// Largest trace file read.
pub const MAX_TRACE_BYTES: u64 = 64 << 20;

/// Reads every `*.csv` trace under `dir` (sorted by name) into a tuning set; a test-split trace,
/// an unreadable or malformed file is an error naming it.
pub fn load_trace_dir(dir: &Path) -> Result<TuningSet, String> {
    let rd = std::fs::read_dir(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let mut files = Vec::new();
    for e in rd {
        let p = e.map_err(|e| format!("{}: {e}", dir.display()))?.path();
        if p.extension().is_some_and(|x| x == "csv") {
            files.push(p);
            if files.len() > MAX_TRACE_FILES {
                return Err(format!(
                    "{}: more than {MAX_TRACE_FILES} traces",
                    dir.display()
                ));
            }
        }
    }
    files.sort();
    if files.is_empty() {
        return Err(format!("{}: no *.csv traces", dir.display()));
    }
    let mut set = TuningSet::new();
    for f in files {
        let len = std::fs::metadata(&f)
            .map_err(|e| format!("{}: {e}", f.display()))?
            .len();
        if len > MAX_TRACE_BYTES {
            return Err(format!(
                "{}: {len} bytes, over {MAX_TRACE_BYTES}",
                f.display()
            ));
        }
        let text = std::fs::read_to_string(&f).map_err(|e| format!("{}: {e}", f.display()))?;
        let t = Trace::from_csv(&text).map_err(|e| format!("{}: {e}", f.display()))?;
        set.admit(t).map_err(|e| format!("{}: {e}", f.display()))?;
    }
    Ok(set)
}

/// The optimiser's result for the converter.
#[derive(Debug, Clone, Default)]
pub struct SplitPlan {
    /// Tiles the partition must split (strict ancestors of the chosen units).
    pub must_split: BTreeSet<TileKey>,
    /// Chosen units holding splats.
    pub units: usize,
    /// Views used (C_v > 0).
    pub views: usize,
    /// The DP's objective and that of the basic cuboids (R_vtest + sum R_waste).
    pub objective: f64,
    /// Objective of the basic cuboids (every non-empty cell a unit).
    pub basic_objective: f64,
}

/// Cell of unit coordinates at `depth` (as `tiling::partition::code_of` quantises).
fn cell_of(u: [f64; 3], scheme: Scheme, depth: u32) -> [u32; 3] {
    let n = (1u64 << depth) as f64;
    let max = (1u64 << depth) - 1;
    let q = |v: f64| {
        let c = (v * n).floor();
        if c.is_nan() || c < 0.0 {
            0
        } else {
            (c as u64).min(max) as u32
        }
    };
    [
        q(u[0]),
        q(u[1]),
        if scheme == Scheme::Octree { q(u[2]) } else { 0 },
    ]
}

/// The cells of `boxes` (index, box, radius; sorted by centre x, the largest radius `r_max`) a
/// camera needs: the frustum (far = `f.far`) meets the box. Only boxes whose centre x lies
/// within `far + r_max` of the camera are looked at (a binary search), in cell order.
fn needed(boxes: &[(u32, Obb, f64)], r_max: f64, f: &Frustum) -> Vec<u32> {
    let reach = f.far + r_max;
    let a = boxes.partition_point(|(_, b, _)| b.center.x < f.apex.x - reach);
    let z = boxes.partition_point(|(_, b, _)| b.center.x <= f.apex.x + reach);
    let mut out: Vec<u32> = boxes[a..z.max(a)]
        .iter()
        .filter(|(_, b, r)| (b.center - f.apex).length() <= f.far + r)
        .filter(|(_, b, _)| planes_test(f, b) && exact_test(f, b))
        .map(|(i, _, _)| *i)
        .collect();
    out.sort_unstable();
    out
}

/// Plans the splits for splats at unit coordinates `unit` (root volume) and tileset-frame
/// positions `world`; a node over `max_unit` splats is always split (the tile budget).
pub fn split_plan(
    req: &PartitionRequest,
    scheme: Scheme,
    max_depth: u32,
    unit: &[[f64; 3]],
    world: &[DVec3],
    max_unit: u64,
) -> Result<SplitPlan, String> {
    if !(req.range_m.is_finite() && req.range_m > 0.0 && req.every_s.is_finite()) {
        return Err(format!(
            "range {} and sampling interval {} must be finite (range > 0)",
            req.range_m, req.every_s
        ));
    }
    let depth = req
        .depth
        .unwrap_or(default_depth(scheme))
        .min(max_depth)
        .min(default_depth(scheme) + 2);
    let n = 1u32 << depth;
    let nz = if scheme == Scheme::Octree { n } else { 1 };
    let dims = [n, n, nz];
    let cells = (n as usize) * (n as usize) * nz as usize;
    let mut counts = vec![0u64; cells];
    let mut lo = vec![DVec3::splat(f64::MAX); cells];
    let mut hi = vec![DVec3::splat(f64::MIN); cells];
    for (u, w) in unit.iter().zip(world) {
        let c = cell_of(*u, scheme, depth);
        let i = c[0] as usize + n as usize * (c[1] as usize + n as usize * c[2] as usize);
        counts[i] += 1;
        lo[i] = lo[i].min(*w);
        hi[i] = hi[i].max(*w);
    }
    let mut boxes: Vec<(u32, Obb, f64)> = (0..cells)
        .filter(|&i| counts[i] > 0)
        .map(|i| {
            let b = Obb::aabb(lo[i], hi[i]);
            let r = b.radius();
            (i as u32, b, r)
        })
        .collect();
    boxes.sort_by(|a, b| a.1.center.x.total_cmp(&b.1.center.x).then(a.0.cmp(&b.0)));
    let r_max = boxes.iter().map(|b| b.2).fold(0.0, f64::max);
    let grid = Grid::new(dims, counts)?;
    let mut views = Vec::new();
    for t in req.views.train().iter().chain(req.views.val()) {
        let base = Intrinsics {
            far: req.range_m,
            ..Intrinsics::default()
        };
        let k = super::views::trace_intrinsics(t, &base);
        for p in super::views::sample_poses(std::slice::from_ref(t), req.every_s) {
            views.push(View {
                weight: 1.0,
                cells: needed(&boxes, r_max, &Frustum::new(&p, &k)),
            });
        }
    }
    let model = CostModel::new(grid, views)?;
    let plan = optimise(&model, scheme, Some(max_unit))?;
    let basic = model.basic_objective();
    let mut must_split = BTreeSet::new();
    for u in &plan.units {
        let mut k = *u;
        while let Some(p) = k.parent() {
            if !must_split.insert(p) {
                break;
            }
            k = p;
        }
    }
    Ok(SplitPlan {
        must_split,
        units: plan.units.len(),
        views: model.views.len(),
        objective: plan.objective,
        basic_objective: basic,
    })
}
