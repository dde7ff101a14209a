//! Streaming-core benchmark (not a test): one DC-DP solve for 50 tiles x 4 levels x 600 steps
//! (TileSplat reports 35-59 ms for 30 x 4 x 600), and one full planning step for 10,000 tiles.
//!
//! Run: `cargo bench --bench stream` (release). Timed: `solve_dp` alone (fastest of 200 after a
//! warm-up), and `plan_step` (hierarchical culling for the current and 60 predicted poses, first
//! visibility, deadlines, DP over every candidate) over a 100 x 100 grid of 10 m leaf tiles under
//! a quadtree (10,000 content tiles), fastest of 10. One thread.

use std::time::Instant;

use glam::DVec3;
use splat2tiles_core::rng::SplitMix64;
use splat2tiles_stream::catalog::{LEVELS, TileCatalog, Variant};
use splat2tiles_stream::geom::{Intrinsics, ViewPose};
use splat2tiles_stream::plan::{Candidate, PlanRequest, solve_dp};
use splat2tiles_stream::planner::{PlanStepConfig, plan_step};
use splat2tiles_tiles::tiling::TileKey;
use splat2tiles_tiles::tiling::load::LoadedTile;

fn min_ms<T>(runs: usize, mut f: impl FnMut() -> T) -> f64 {
    std::hint::black_box(f());
    (0..runs)
        .map(|_| {
            let t0 = Instant::now();
            std::hint::black_box(f());
            t0.elapsed().as_secs_f64() * 1e3
        })
        .fold(f64::MAX, f64::min)
}

fn grid_city() -> TileCatalog {
    let depth = 7u32; // 128 x 128 cells at the leaves, 10 m each; keep 100 x 100
    let mut tiles = vec![];
    for level in 0..=depth {
        let n = 1u32 << level;
        let size = 1280.0 / n as f64;
        let keep = (100 * n).div_ceil(128);
        for y in 0..keep {
            for x in 0..keep {
                let c = [(x as f64 + 0.5) * size, (y as f64 + 0.5) * size, 10.0];
                tiles.push(LoadedTile {
                    key: TileKey { level, x, y, z: 0 },
                    content: (level == depth).then(|| format!("{x}_{y}.glb").into()),
                    bounding_box: Some([
                        c[0],
                        c[1],
                        c[2],
                        size / 2.0,
                        0.0,
                        0.0,
                        0.0,
                        size / 2.0,
                        0.0,
                        0.0,
                        0.0,
                        10.0,
                    ]),
                    geometric_error: 0.0,
                    splat_count: Some(20_000),
                });
            }
        }
    }
    let mut rng = SplitMix64::new(1);
    TileCatalog::from_loaded(&tiles, |_| Some(rng.range(0.5e6, 2e6) as u64))
}

fn main() {
    // 1. One DP solve: 50 tiles x 4 levels x 600 steps of 0.1 s.
    let mut rng = SplitMix64::new(42);
    let cands: Vec<Candidate> = (0..50)
        .map(|i| {
            let best = rng.range(1e6, 4e6);
            Candidate {
                tile: i,
                deadline: rng.range(5.0, 60.0),
                distance: 0.0,
                variants: std::array::from_fn(|j| Variant {
                    bytes: (best * [1.0, 0.77, 0.65, 0.53][j]) as u64,
                    utility: [1.0, 0.98, 0.95, 0.90][j],
                }),
            }
        })
        .collect();
    let bw = [50e6 / 8.0];
    let req = PlanRequest {
        candidates: &cands,
        bandwidth: &bw,
        step_s: 0.1,
        horizon_steps: 600,
        memory_budget: u64::MAX,
        latency_s: 0.0,
        bins: 0,
    };
    let dp = min_ms(200, || solve_dp(&req));
    let plan = solve_dp(&req);
    println!(
        "DP solve, 50 tiles x {LEVELS} levels x 600 steps: {dp:.3} ms (fastest of 200; {} fetches, utility {:.2})",
        plan.fetches.len(),
        plan.utility
    );

    // 2. Full planning step over 10,000 tiles.
    let cat = grid_city();
    let n_content = cat.content_tiles().count();
    let k = Intrinsics {
        far: 300.0,
        ..Intrinsics::default()
    };
    let cfg = PlanStepConfig {
        intrinsics: k,
        ..PlanStepConfig::default()
    };
    let now = ViewPose {
        t: 0.0,
        pos: DVec3::new(200.0, 500.0, 1.7),
        yaw: 0.3,
        pitch: 0.0,
    };
    let predicted: Vec<ViewPose> = (1..=60)
        .map(|i| {
            let t = i as f64 * 0.5;
            ViewPose {
                t,
                pos: now.pos + DVec3::new(1.4 * t, 0.2 * t, 0.0),
                yaw: 0.3 + 0.02 * t,
                ..now
            }
        })
        .collect();
    let step = min_ms(10, || {
        plan_step(&cat, &now, &predicted, &cfg, 50e6 / 8.0, |_| None, u64::MAX)
    });
    let (cands, plan) = plan_step(&cat, &now, &predicted, &cfg, 50e6 / 8.0, |_| None, u64::MAX);
    println!(
        "planning step, {n_content} content tiles ({} in the tree), 61 poses: {step:.2} ms (fastest of 10; {} candidates, {} fetches)",
        cat.tiles.len(),
        cands.len(),
        plan.fetches.len()
    );
}
