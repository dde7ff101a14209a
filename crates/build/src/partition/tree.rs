//! The scalable optimiser: an exact DP over the implicit quadtree/octree of a `2^d` grid choosing
//! per node "one streaming unit here" or "split into the children", minimising SGSS's objective.
//!
//! The objective is a sum of per-cuboid costs ([`CostModel::cuboid_cost`]), so the best
//! hierarchical partition of a node is the cheaper of the node as one unit and the best partitions
//! of its children: optimal among the partitions an implicit tiling can express. Cost: one pass
//! over every view's needed cells per level plus O(nodes); no cuboid enumeration.

use super::cost::CostModel;
use super::grid::Cuboid;
use splat2tiles_tiles::tiling::partition::{Scheme, TileKey};

/// A DP result: the chosen units (tree nodes) and the objective they reach.
#[derive(Debug, Clone, PartialEq)]
pub struct TreePlan {
    /// Subdivision of the tree.
    pub scheme: Scheme,
    /// Depth of the basic cells (the grid is `2^depth` cells per subdivided axis).
    pub depth: u32,
    /// Chosen units holding splats, keys relative to the grid's root, in Morton order per level.
    pub units: Vec<TileKey>,
    /// Every chosen node (empty ones too) as a cuboid of cells: an exact cover of the grid.
    pub cover: Vec<Cuboid>,
    /// The DP's objective (equals `model.score(&cover).objective` up to rounding).
    pub objective: f64,
}

/// The tree depth of the model's grid under `scheme`: `dims = [2^d, 2^d, 2^d]` (octree) or
/// `[2^d, 2^d, 1]` (quadtree); errors otherwise.
pub fn tree_depth(model: &CostModel, scheme: Scheme) -> Result<u32, String> {
    let [nx, ny, nz] = model.grid.dims;
    let ok = nx.is_power_of_two()
        && nx == ny
        && match scheme {
            Scheme::Octree => nz == nx,
            Scheme::Quadtree => nz == 1,
        };
    if !ok {
        return Err(format!(
            "a {} needs a 2^d grid, got {nx}x{ny}x{nz}",
            scheme.as_str().to_lowercase()
        ));
    }
    Ok(nx.trailing_zeros())
}

/// The cuboid of cells under node `key` of a depth-`depth` tree.
pub fn node_cuboid(scheme: Scheme, depth: u32, key: TileKey) -> Cuboid {
    let s = 1u32 << (depth - key.level);
    let sz = if scheme == Scheme::Octree { s } else { 1 };
    let lo = [key.x * s, key.y * s, key.z * sz];
    Cuboid {
        lo,
        hi: [lo[0] + s, lo[1] + s, lo[2] + sz],
    }
}

/// Per level, the dense node index of `(x, y, z)`.
fn node_index(scheme: Scheme, level: u32, x: u32, y: u32, z: u32) -> usize {
    let n = 1usize << level;
    let zz = if scheme == Scheme::Octree {
        z as usize
    } else {
        0
    };
    x as usize + n * (y as usize + n * zz)
}

/// `sum_v p_v / C_v` over the views needing a cell under each node, per level (index by
/// [`node_index`]).
fn waste_weights(model: &CostModel, scheme: Scheme, depth: u32) -> Vec<Vec<f64>> {
    let levels = depth as usize + 1;
    let nodes = |l: u32| (1usize << (scheme.dims() * l)).max(1);
    let mut w: Vec<Vec<f64>> = (0..=depth).map(|l| vec![0.0; nodes(l)]).collect();
    // Stamp per node: the last view that added to it (so each view adds once per node).
    let mut stamp: Vec<Vec<u32>> = (0..=depth).map(|l| vec![u32::MAX; nodes(l)]).collect();
    for (vi, (v, &need)) in model.views.iter().zip(&model.c_v).enumerate() {
        let add = v.weight / need as f64;
        for &cell in &v.cells {
            let [x, y, z] = model.grid.coords(cell as usize);
            for l in (0..levels as u32).rev() {
                let sh = depth - l;
                let zl = if scheme == Scheme::Octree { z >> sh } else { 0 };
                let i = node_index(scheme, l, x >> sh, y >> sh, zl);
                if stamp[l as usize][i] == vi as u32 {
                    break; // this node and its ancestors already counted for this view
                }
                stamp[l as usize][i] = vi as u32;
                w[l as usize][i] += add;
            }
        }
    }
    w
}

/// The best hierarchical partition of the model's grid. A node holding more than `max_unit`
/// splats is never a unit unless it is a basic cell (it cannot be split further here).
pub fn optimise(
    model: &CostModel,
    scheme: Scheme,
    max_unit: Option<u64>,
) -> Result<TreePlan, String> {
    let depth = tree_depth(model, scheme)?;
    let w = waste_weights(model, scheme, depth);
    let inv_dmax = if model.c_dmax == 0 {
        0.0
    } else {
        1.0 / model.c_dmax as f64
    };
    let side = |l: u32| 1u32 << l;
    let zside = |l: u32| {
        if scheme == Scheme::Octree {
            1u32 << l
        } else {
            1
        }
    };
    // best[l][i] and whether node i of level l is a unit.
    let mut best: Vec<Vec<f64>> = Vec::with_capacity(depth as usize + 1);
    let mut unit: Vec<Vec<bool>> = Vec::with_capacity(depth as usize + 1);
    for l in (0..=depth).rev() {
        let n = (side(l) as usize).pow(2) * zside(l) as usize;
        let mut b = vec![0.0; n];
        let mut u = vec![true; n];
        for z in 0..zside(l) {
            for y in 0..side(l) {
                for x in 0..side(l) {
                    let key = TileKey { level: l, x, y, z };
                    let i = node_index(scheme, l, x, y, z);
                    let count = model.grid.count(&node_cuboid(scheme, depth, key));
                    let own = if count == 0 {
                        0.0
                    } else {
                        inv_dmax + count as f64 * w[l as usize][i]
                    };
                    if l == depth {
                        b[i] = own;
                        continue;
                    }
                    let below = &best[best.len() - 1];
                    let split: f64 = (0..scheme.arity() as u32)
                        .map(|c| {
                            let (cx, cy, cz) =
                                (2 * x + (c & 1), 2 * y + (c >> 1 & 1), 2 * z + (c >> 2 & 1));
                            below[node_index(scheme, l + 1, cx, cy, cz)]
                        })
                        .sum();
                    let allowed = max_unit.is_none_or(|m| count <= m);
                    if allowed && own <= split {
                        b[i] = own;
                    } else {
                        b[i] = split;
                        u[i] = false;
                    }
                }
            }
        }
        best.push(b);
        unit.push(u);
    }
    best.reverse();
    unit.reverse();
    // Walk down from the root collecting the units.
    let mut units = Vec::new();
    let mut cover = Vec::new();
    let mut stack = vec![TileKey::ROOT];
    while let Some(k) = stack.pop() {
        let i = node_index(scheme, k.level, k.x, k.y, k.z);
        if unit[k.level as usize][i] {
            let c = node_cuboid(scheme, depth, k);
            if model.grid.count(&c) > 0 {
                units.push(k);
            }
            cover.push(c);
            continue;
        }
        for c in (0..scheme.arity() as u32).rev() {
            stack.push(TileKey {
                level: k.level + 1,
                x: 2 * k.x + (c & 1),
                y: 2 * k.y + (c >> 1 & 1),
                z: 2 * k.z + (c >> 2 & 1),
            });
        }
    }
    units.sort_by_key(|k| (k.level, scheme.encode(k.x, k.y, k.z)));
    Ok(TreePlan {
        scheme,
        depth,
        units,
        cover,
        objective: best[0][0],
    })
}

/// The uniform partition into every node of `level` (level = depth: the basic cuboids).
pub fn uniform(scheme: Scheme, depth: u32, level: u32) -> Vec<Cuboid> {
    let l = level.min(depth);
    let zs = if scheme == Scheme::Octree {
        1u32 << l
    } else {
        1
    };
    let mut out = Vec::new();
    for z in 0..zs {
        for y in 0..1u32 << l {
            for x in 0..1u32 << l {
                out.push(node_cuboid(scheme, depth, TileKey { level: l, x, y, z }));
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::partition::cost::View;
    use crate::partition::grid::Grid;
    use splat2tiles_core::rng::SplitMix64;

    /// A random model over a `2^d` grid: sparse counts, views needing small random boxes.
    fn random_model(scheme: Scheme, d: u32, seed: u64) -> CostModel {
        let mut r = SplitMix64::new(seed);
        let n = 1u32 << d;
        let nz = if scheme == Scheme::Octree { n } else { 1 };
        let cells = (n * n * nz) as usize;
        let counts = (0..cells)
            .map(|_| {
                if r.f64() < 0.4 {
                    0
                } else {
                    (r.f64() * 1000.0) as u64
                }
            })
            .collect();
        let g = Grid::new([n, n, nz], counts).unwrap();
        let views = (0..12)
            .map(|_| {
                let lo = [0, 1, 2].map(|a| (r.f64() * g.dims[a] as f64) as u32);
                let hi = [0, 1, 2].map(|a| lo[a] + 1 + (r.f64() * 2.0) as u32);
                let cells = (0..g.len() as u32)
                    .filter(|&i| {
                        let c = g.coords(i as usize);
                        (0..3).all(|a| lo[a] <= c[a] && c[a] < hi[a])
                    })
                    .collect();
                View {
                    weight: 0.5 + r.f64(),
                    cells,
                }
            })
            .collect();
        CostModel::new(g, views).unwrap()
    }

    /// Every hierarchical partition's objective, by recursion (tiny trees only).
    fn brute(model: &CostModel, scheme: Scheme, depth: u32, k: TileKey) -> f64 {
        let own = model.cuboid_cost(&node_cuboid(scheme, depth, k));
        if k.level == depth {
            return own;
        }
        let split: f64 = (0..scheme.arity() as u32)
            .map(|c| {
                let ck = TileKey {
                    level: k.level + 1,
                    x: 2 * k.x + (c & 1),
                    y: 2 * k.y + (c >> 1 & 1),
                    z: 2 * k.z + (c >> 2 & 1),
                };
                brute(model, scheme, depth, ck)
            })
            .sum();
        own.min(split)
    }

    #[test]
    fn dp_is_the_best_hierarchical_partition_and_scores_what_it_claims() {
        for (scheme, d) in [(Scheme::Quadtree, 3), (Scheme::Octree, 2)] {
            for seed in 0..6 {
                let m = random_model(scheme, d, seed);
                let plan = optimise(&m, scheme, None).unwrap();
                let s = m.score(&plan.cover).unwrap();
                assert!(
                    (s.objective - plan.objective).abs() < 1e-9,
                    "{s:?} vs {}",
                    plan.objective
                );
                let b = brute(&m, scheme, d, TileKey::ROOT);
                assert!(
                    (b - plan.objective).abs() < 1e-9,
                    "{b} vs {}",
                    plan.objective
                );
                // Never worse than the uniform partitions.
                for l in 0..=d {
                    let u = m.score(&uniform(scheme, d, l)).unwrap().objective;
                    assert!(
                        plan.objective <= u + 1e-9,
                        "level {l}: {u} < {}",
                        plan.objective
                    );
                }
                assert_eq!(plan.units.len() as u64, s.vtests);
            }
        }
    }

    #[test]
    fn a_unit_cap_forces_splits() {
        let m = random_model(Scheme::Quadtree, 3, 9);
        let plan = optimise(&m, Scheme::Quadtree, Some(1500)).unwrap();
        for k in &plan.units {
            let c = m.grid.count(&node_cuboid(Scheme::Quadtree, 3, *k));
            assert!(c <= 1500 || k.level == 3, "{k:?} holds {c}");
        }
        // With no views the waste vanishes and one unit is best (when it fits).
        let g = m.grid.clone();
        let none = CostModel::new(g, vec![]).unwrap();
        let p = optimise(&none, Scheme::Quadtree, None).unwrap();
        assert_eq!(p.units, vec![TileKey::ROOT]);
        assert!(
            tree_depth(
                &CostModel::new(Grid::new([4, 2, 1], vec![0; 8]).unwrap(), vec![]).unwrap(),
                Scheme::Quadtree
            )
            .is_err()
        );
    }
}
