//! Greedy radius clustering with a kiddo KD-tree: splats are visited by descending importance and
//! each still unassigned seed takes every unassigned splat within the radius; clusters are merged.

use super::merge::{MergeRule, merge_into};
use crate::splat::Splats;
use crate::splat::importance::importance_order;
use kiddo::{ImmutableKdTree, SquaredEuclidean};

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
        displacement += merge_into(splats, &members, rule, &mut out) * members.len() as f64;
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
