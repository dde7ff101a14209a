//! The tree DP's optimality gap against SGSS's exact ILP (microlp) on random small grids: prints
//! per grid the DP/ILP objective ratio distribution and how often the ILP optimum is hierarchical.
//!
//! `cargo run --release --example partition_gap [SEEDS]` (default 40 seeds per grid).

#[path = "../../../tests/partition/ilp.rs"]
mod ilp;

use splat2tiles_build::partition::optimise;
use splat2tiles_tiles::tiling::partition::Scheme;
use std::time::Instant;

fn main() {
    let seeds: u64 = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(40);
    println!(
        "| grid | views | instances | ILP optimum hierarchical | DP = ILP | DP/ILP median | p90 | max | ILP s (mean) | DP s (mean) |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    for (scheme, d, aligned) in [
        (Scheme::Quadtree, 2, false),
        (Scheme::Quadtree, 3, false),
        (Scheme::Octree, 1, false),
        (Scheme::Octree, 2, false),
        (Scheme::Quadtree, 3, true),
        (Scheme::Octree, 2, true),
    ] {
        let mut ratios = Vec::new();
        let (mut hier, mut equal) = (0, 0);
        let (mut t_ilp, mut t_dp) = (0.0, 0.0);
        for seed in 0..seeds {
            let m = ilp::random_model(scheme, d, 10, 1000 + seed, aligned);
            let t = Instant::now();
            let (cover, best) = ilp::solve_ilp(&m).expect("ILP");
            t_ilp += t.elapsed().as_secs_f64();
            let t = Instant::now();
            let dp = optimise(&m, scheme, None).expect("DP").objective;
            t_dp += t.elapsed().as_secs_f64();
            if ilp::is_hierarchical(&m, scheme, d, &cover) {
                hier += 1;
            }
            if (dp - best).abs() < 1e-6 {
                equal += 1;
            }
            ratios.push(dp / best);
        }
        ratios.sort_by(f64::total_cmp);
        let q = |p: f64| ratios[((ratios.len() - 1) as f64 * p).round() as usize];
        let n = 1u32 << d;
        let nz = if scheme == Scheme::Octree { n } else { 1 };
        println!(
            "| {n}x{n}x{nz} {} | {} | {seeds} | {hier} | {equal} | {:.4} | {:.4} | {:.4} | {:.4} | {:.6} |",
            scheme.as_str().to_lowercase(),
            if aligned {
                "tree nodes"
            } else {
                "10 random boxes"
            },
            q(0.5),
            q(0.9),
            q(1.0),
            t_ilp / seeds as f64,
            t_dp / seeds as f64,
        );
    }
}
