//! The tree DP against SGSS's exact ILP (microlp) on small grids: equal where the ILP's optimum is
//! hierarchical, never better than the ILP, and within a bounded gap elsewhere; the ILP itself is
//! checked against an exhaustive exact-cover search on tiny grids.

#[path = "../partition/ilp.rs"]
mod ilp;

use splat2tiles_build::partition::{CostModel, Grid, View, optimise};
use splat2tiles_tiles::tiling::partition::Scheme;

#[test]
fn the_ilp_finds_the_exhaustive_optimum_on_tiny_grids() {
    for seed in 0..6 {
        let m = ilp::random_model(Scheme::Quadtree, 1, 4, seed, false);
        let (_, obj) = ilp::solve_ilp(&m).unwrap();
        let b = ilp::brute_force(&m);
        assert!((obj - b).abs() < 1e-6, "seed {seed}: ilp {obj} brute {b}");
    }
    // A 3 x 2 x 2 grid (not a tree) too.
    let g = Grid::new(
        [3, 2, 2],
        (0..12).map(|i| (i * 37 % 11) as u64 * 10).collect(),
    )
    .unwrap();
    let views = vec![
        View {
            weight: 1.0,
            cells: vec![0, 1],
        },
        View {
            weight: 2.0,
            cells: vec![5, 11],
        },
        View {
            weight: 1.0,
            cells: vec![6, 7, 8],
        },
    ];
    let m = CostModel::new(g, views).unwrap();
    let (cover, obj) = ilp::solve_ilp(&m).unwrap();
    assert!((obj - ilp::brute_force(&m)).abs() < 1e-6);
    assert!(m.score(&cover).is_ok());
}

#[test]
fn the_dp_matches_the_ilp_when_its_optimum_is_hierarchical() {
    let mut hierarchical = 0;
    let mut cases = 0;
    for (scheme, d) in [
        (Scheme::Quadtree, 2),
        (Scheme::Quadtree, 3),
        (Scheme::Octree, 1),
        (Scheme::Octree, 2),
    ] {
        for seed in 0..6 {
            let m = ilp::random_model(scheme, d, 6, 200 + seed, true);
            let (cover, best) = ilp::solve_ilp(&m).unwrap();
            let plan = optimise(&m, scheme, None).unwrap();
            let dp = m.score(&plan.cover).unwrap().objective;
            assert!(dp >= best - 1e-6, "DP {dp} beats the exact ILP {best}");
            if ilp::is_hierarchical(&m, scheme, d, &cover) {
                hierarchical += 1;
                assert!(
                    (dp - best).abs() < 1e-6,
                    "{scheme:?} d={d} seed {seed}: {dp} vs {best}"
                );
            }
            cases += 1;
        }
    }
    assert!(
        hierarchical >= cases / 3,
        "only {hierarchical} of {cases} optima hierarchical"
    );
}

/// The DP/ILP objective ratio on unaligned random instances: never below 1, bounded above (the
/// `partition_gap` example prints the distribution; BENCHMARKS.md "View-optimised partitioning").
#[test]
fn the_dp_gap_against_the_ilp_is_bounded_on_random_grids() {
    let mut worst: f64 = 1.0;
    for (scheme, d) in [
        (Scheme::Quadtree, 2),
        (Scheme::Quadtree, 3),
        (Scheme::Octree, 1),
    ] {
        for seed in 0..8 {
            let m = ilp::random_model(scheme, d, 10, 100 + seed, false);
            let (_, best) = ilp::solve_ilp(&m).unwrap();
            let dp = optimise(&m, scheme, None).unwrap().objective;
            assert!(dp >= best - 1e-6, "DP {dp} beats the exact ILP {best}");
            worst = worst.max(dp / best);
        }
    }
    // Measured over 40 seeds per grid (partition_gap): worst 1.32 (4x4), 1.36 (8x8), 1.28 (2x2x2).
    assert!(worst < 1.4, "worst DP/ILP ratio {worst}");
}
