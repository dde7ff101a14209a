//! Greedy radius clustering with a kiddo KD-tree: splats are visited by descending importance and
//! each still unassigned seed takes every unassigned splat within the radius; clusters are merged.

use super::merge::{MergeRule, merge_drawn};
use super::radius::{CELL_PER_RADIUS, Occupancy, radius_for_count};
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use splat2tiles_core::splat::Splats;
use splat2tiles_core::splat::importance::importance_order;

/// The result of clustering one tile's input.
#[derive(Debug, Clone)]
pub struct Clustered {
    /// One splat per cluster, in the order the seeds were visited (descending importance).
    pub splats: Splats,
    /// Radius actually used (after doubling to meet the budget).
    pub radius: f64,
    /// Mean over input splats of the distance from their centre to their cluster's merged centre
    /// (opacity-weighted inside each cluster, then averaged over clusters by member count).
    pub mean_displacement: f64,
}

/// Clusters `splats` within `radius` (same units as the positions) and merges every cluster.
pub fn cluster(splats: &Splats, radius: f64, rule: MergeRule) -> Clustered {
    cluster_drawn(splats, radius, rule, 0.0)
}

/// [`cluster`] whose merged splats model a viewer's pixel low-pass filter of variance
/// `dilation_per_radius2 * radius^2` (see [`merge_drawn`]).
pub fn cluster_drawn(
    splats: &Splats,
    radius: f64,
    rule: MergeRule,
    dilation_per_radius2: f64,
) -> Clustered {
    let n = splats.len();
    let mut out = Splats::with_capacity(splats.sh_degree, n / 2 + 1);
    if n == 0 {
        return Clustered {
            splats: out,
            radius,
            mean_displacement: 0.0,
        };
    }
    let radius = if radius.is_finite() {
        radius.max(0.0)
    } else {
        0.0
    };
    // Coordinates relative to the first centre: small numbers even for georeferenced scenes.
    let o = splats.positions[0];
    let pts: Vec<[f64; 3]> = splats
        .positions
        .iter()
        .map(|p| [p[0] - o[0], p[1] - o[1], p[2] - o[2]])
        .collect();
    let tree = ImmutableKdTree::<f64, 3>::new_from_slice(&pts).expect("finite points");
    let r2 = radius * radius;
    let dilation = dilation_per_radius2 * r2;
    let mut assigned = vec![false; n];
    let mut members: Vec<usize> = Vec::new();
    let mut displacement = 0.0;
    for seed in importance_order(splats) {
        if assigned[seed] {
            continue;
        }
        members.clear();
        members.push(seed);
        assigned[seed] = true;
        if radius > 0.0 {
            let mut near: Vec<usize> = tree
                .query(&pts[seed])
                .within::<SquaredEuclidean<f64>>(r2)
                .unsorted()
                .execute()
                .into_iter()
                .map(|r| r.item as usize)
                .filter(|&i| !assigned[i])
                .collect();
            near.sort_unstable();
            for i in near {
                assigned[i] = true;
                members.push(i);
            }
        }
        displacement +=
            merge_drawn(splats, &members, rule, dilation, &mut out) * members.len() as f64;
    }
    Clustered {
        splats: out,
        radius,
        mean_displacement: displacement / n as f64,
    }
}

/// Clusters with `radius`, doubling it until at most `budget` splats are left (and at least one
/// merge happened when the input was over budget).
pub fn cluster_to_budget(
    splats: &Splats,
    radius: f64,
    budget: usize,
    rule: MergeRule,
) -> Clustered {
    let mut r = if radius.is_finite() && radius > 0.0 {
        radius
    } else {
        f64::MIN_POSITIVE
    };
    loop {
        let c = cluster(splats, r, rule);
        if c.splats.len() <= budget.max(1) || r > 1e300 {
            return c;
        }
        r *= 2.0;
    }
}

/// Relative miss of the target count beyond which [`cluster_to_target`] corrects its radius once.
pub const TARGET_TOLERANCE: f64 = 1.25;

/// Clusters `splats` into about `target` splats (never more than `budget`) with one radius chosen
/// from the input's grid occupancy ([`radius_for_count`]), at least `min_radius`; when the result
/// misses the target by more than [`TARGET_TOLERANCE`], the radius is corrected once by the
/// local dimension of the occupancy. `fallback_radius` is used when the occupancy gives no
/// radius (coincident centres) and `min_radius` is 0. Merged splats model a viewer's low-pass
/// filter of variance `dilation_per_radius2 * d^2` at the radius `d` used ([`cluster_drawn`]).
/// Cost: one sort and usually one or two clusterings, each O(n log n).
pub fn cluster_to_target(
    splats: &Splats,
    target: usize,
    min_radius: f64,
    fallback_radius: f64,
    budget: usize,
    rule: MergeRule,
    dilation_per_radius2: f64,
) -> Clustered {
    let cluster =
        |s: &Splats, d: f64, rule: MergeRule| cluster_drawn(s, d, rule, dilation_per_radius2);
    let positive = |v: f64| v.is_finite() && v > 0.0;
    let min_radius = if positive(min_radius) {
        min_radius
    } else {
        0.0
    };
    let occ = Occupancy::of(&splats.positions);
    let target = target.max(1);
    let mut d = radius_for_count(&occ, target).max(min_radius);
    if !positive(d) {
        d = if positive(fallback_radius) {
            fallback_radius
        } else {
            1e-6
        };
    }
    let mut c = cluster(splats, d, rule);
    let (n, t) = (c.splats.len() as f64, target as f64);
    if n > t * TARGET_TOLERANCE || (n * TARGET_TOLERANCE < t && d > min_radius) {
        let dim = occ.dimension_at(d * CELL_PER_RADIUS);
        let d2 = (d * (n / t).powf(1.0 / dim)).max(min_radius);
        if positive(d2) && d2 != d {
            let c2 = cluster(splats, d2, rule);
            // Keep the correction unless it broke the budget the first radius met.
            if c2.splats.len() <= budget.max(1) || c.splats.len() > budget.max(1) {
                c = c2;
                d = d2;
            }
        }
    }
    // The budget is a hard limit: grow the radius until it holds (rarely taken).
    while c.splats.len() > budget.max(1) && d < 1e300 {
        let ratio = c.splats.len() as f64 / budget.max(1) as f64;
        let dim = occ.dimension_at(d * CELL_PER_RADIUS);
        d *= (ratio.powf(1.0 / dim) * 1.02).max(1.02);
        c = cluster(splats, d, rule);
    }
    c
}
