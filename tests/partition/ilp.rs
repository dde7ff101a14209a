//! SGSS's exact ILP (sec. 3.1): one binary per axis-aligned cuboid of the grid, an exact cover of
//! the basic cuboids, minimise the sum of cuboid costs; solved by microlp (pure Rust, via good_lp).
//! Also a brute-force exact-cover search for tiny grids and the random instances of the gap study.

#![allow(dead_code)]

use good_lp::{Expression, Solution, SolverModel, microlp, variable, variables};
use splat2tiles_build::partition::tree::node_cuboid;
use splat2tiles_build::partition::{CostModel, Cuboid, Grid, View};
use splat2tiles_core::rng::SplitMix64;
use splat2tiles_tiles::tiling::partition::{Scheme, TileKey};

/// The ILP's optimal cover and objective.
pub fn solve_ilp(model: &CostModel) -> Result<(Vec<Cuboid>, f64), String> {
    let cuboids = model.grid.all_cuboids();
    let costs: Vec<f64> = cuboids.iter().map(|c| model.cuboid_cost(c)).collect();
    let mut vars = variables!();
    let x: Vec<_> = cuboids
        .iter()
        .map(|_| vars.add(variable().binary()))
        .collect();
    let mut objective = Expression::from(0.0);
    for (xi, &c) in x.iter().zip(&costs) {
        objective += c * *xi;
    }
    let mut lp = vars.minimise(objective).using(microlp);
    // A x = 1: each basic cuboid in exactly one chosen cuboid.
    let mut rows: Vec<Expression> = vec![Expression::from(0.0); model.grid.len()];
    for (c, xi) in cuboids.iter().zip(&x) {
        for z in c.lo[2]..c.hi[2] {
            for y in c.lo[1]..c.hi[1] {
                for xx in c.lo[0]..c.hi[0] {
                    rows[model.grid.index([xx, y, z])] += *xi;
                }
            }
        }
    }
    for r in rows {
        lp = lp.with(r.eq(1.0));
    }
    let sol = lp.solve().map_err(|e| e.to_string())?;
    let chosen: Vec<Cuboid> = cuboids
        .iter()
        .zip(&x)
        .filter(|(_, xi)| sol.value(**xi) > 0.5)
        .map(|(c, _)| *c)
        .collect();
    let obj = model.score(&chosen)?.objective;
    Ok((chosen, obj))
}

/// The best exact cover by exhaustive search (grids of a few cells only).
pub fn brute_force(model: &CostModel) -> f64 {
    fn go(m: &CostModel, covered: &mut Vec<bool>, acc: f64, best: &mut f64) {
        if acc >= *best {
            return;
        }
        let Some(first) = covered.iter().position(|&c| !c) else {
            *best = acc;
            return;
        };
        let lo = m.grid.coords(first);
        let d = m.grid.dims;
        for hz in lo[2] + 1..=d[2] {
            for hy in lo[1] + 1..=d[1] {
                for hx in lo[0] + 1..=d[0] {
                    let c = Cuboid {
                        lo,
                        hi: [hx, hy, hz],
                    };
                    let cells: Vec<usize> = (0..m.grid.len())
                        .filter(|&i| c.contains(m.grid.coords(i)))
                        .collect();
                    if cells.iter().any(|&i| covered[i]) {
                        continue;
                    }
                    cells.iter().for_each(|&i| covered[i] = true);
                    go(m, covered, acc + m.cuboid_cost(&c), best);
                    cells.iter().for_each(|&i| covered[i] = false);
                }
            }
        }
    }
    let mut best = f64::INFINITY;
    go(model, &mut vec![false; model.grid.len()], 0.0, &mut best);
    best
}

/// Whether a cover's objective is reachable by a hierarchical partition: the cost sees only how
/// the non-empty cells are grouped, so it is iff each group's smallest enclosing tree node holds
/// no other group's non-empty cell (those nodes are then disjoint and empty nodes complete them).
pub fn is_hierarchical(model: &CostModel, scheme: Scheme, depth: u32, cover: &[Cuboid]) -> bool {
    let g = &model.grid;
    let group_of = |i: usize| cover.iter().position(|c| c.contains(g.coords(i)));
    for (k, c) in cover.iter().enumerate() {
        let cells: Vec<[u32; 3]> = (0..g.len())
            .filter(|&i| g.counts[i] > 0 && c.contains(g.coords(i)))
            .map(|i| g.coords(i))
            .collect();
        let Some(first) = cells.first() else {
            continue;
        };
        // Smallest node holding every cell: climb until all share the ancestor.
        let mut level = depth;
        let key_at = |p: [u32; 3], l: u32| {
            let sh = depth - l;
            let z = if scheme == Scheme::Octree {
                p[2] >> sh
            } else {
                0
            };
            (p[0] >> sh, p[1] >> sh, z)
        };
        while cells
            .iter()
            .any(|p| key_at(*p, level) != key_at(*first, level))
        {
            level -= 1;
        }
        let (x, y, z) = key_at(*first, level);
        let node = node_cuboid(scheme, depth, TileKey { level, x, y, z });
        let clash = (0..g.len())
            .any(|i| g.counts[i] > 0 && node.contains(g.coords(i)) && group_of(i) != Some(k));
        if clash {
            return false;
        }
    }
    true
}

/// A random instance over a `2^d` grid: clustered splat counts (empty cells, a few dense ones)
/// and `views` views with random probabilities, each needing a random box of 1-3 cells per axis,
/// or (`aligned`) one node each of a random hierarchical partition of the grid (`views` ignored).
pub fn random_model(scheme: Scheme, d: u32, views: usize, seed: u64, aligned: bool) -> CostModel {
    let mut r = SplitMix64::new(seed);
    let n = 1u32 << d;
    let nz = if scheme == Scheme::Octree { n } else { 1 };
    let cells = (n * n * nz) as usize;
    let counts = (0..cells)
        .map(|_| {
            let u = r.f64();
            if u < 0.35 {
                0
            } else if u < 0.85 {
                (r.f64() * 200.0) as u64
            } else {
                (r.f64() * 5000.0) as u64
            }
        })
        .collect();
    let g = Grid::new([n, n, nz], counts).unwrap();
    let boxes: Vec<Cuboid> = if aligned {
        // Split the root with probability 0.9, deeper nodes with 0.5.
        let mut out = Vec::new();
        let mut stack = vec![TileKey::ROOT];
        while let Some(k) = stack.pop() {
            let p = if k.level == 0 { 0.9 } else { 0.5 };
            if k.level < d && r.f64() < p {
                for c in 0..scheme.arity() as u32 {
                    stack.push(TileKey {
                        level: k.level + 1,
                        x: 2 * k.x + (c & 1),
                        y: 2 * k.y + (c >> 1 & 1),
                        z: 2 * k.z + (c >> 2 & 1),
                    });
                }
            } else {
                out.push(node_cuboid(scheme, d, k));
            }
        }
        out
    } else {
        (0..views)
            .map(|_| {
                let lo = [0, 1, 2].map(|a| (r.f64() * g.dims[a] as f64) as u32);
                let hi = [0, 1, 2].map(|a| (lo[a] + 1 + (r.f64() * 3.0) as u32).min(g.dims[a]));
                Cuboid { lo, hi }
            })
            .collect()
    };
    let vs = boxes
        .iter()
        .map(|b| {
            let cells = (0..g.len() as u32)
                .filter(|&i| b.contains(g.coords(i as usize)))
                .collect();
            View {
                weight: 0.2 + r.f64(),
                cells,
            }
        })
        .collect();
    CostModel::new(g, vs).unwrap()
}
