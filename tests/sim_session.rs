//! Simulator checks: sessions are deterministic for a fixed seed, the cache stays within
//! capacity, the oracle is at least as good as reactive on cache hits, and traces round-trip.

use glam::DVec3;
use splat2tiles::sim::client::{NetModel, SimConfig, run_session};
use splat2tiles::sim::trace::{self, Trace};
use splat2tiles::stream::cache::CacheConfig;
use splat2tiles::stream::catalog::TileCatalog;
use splat2tiles::stream::geom::Intrinsics;
use splat2tiles::stream::planner::PlanStepConfig;
use splat2tiles::stream::predict::{LinearExtrapolation, Oracle, Predictor, Reactive};
use splat2tiles::stream::rng::SplitMix64;
use splat2tiles::tiling::TileKey;
use splat2tiles::tiling::load::LoadedTile;

/// 16 x 16 leaf tiles of 10 m under a quadtree.
fn grid() -> TileCatalog {
    let mut tiles = vec![];
    for level in 0..=4u32 {
        let n = 1u32 << level;
        let size = 160.0 / n as f64;
        for y in 0..n {
            for x in 0..n {
                let c = [(x as f64 + 0.5) * size, (y as f64 + 0.5) * size, 3.0];
                let h = size / 2.0;
                tiles.push(LoadedTile {
                    key: TileKey { level, x, y, z: 0 },
                    content: (level == 4).then(|| format!("{x}_{y}.glb").into()),
                    bounding_box: Some([c[0], c[1], c[2], h, 0.0, 0.0, 0.0, h, 0.0, 0.0, 0.0, 3.0]),
                    geometric_error: 0.0,
                    splat_count: Some(1000),
                });
            }
        }
    }
    let mut rng = SplitMix64::new(3);
    TileCatalog::from_loaded(&tiles, |_| Some(rng.range(50e3, 300e3) as u64))
}

fn config() -> SimConfig {
    SimConfig {
        net: NetModel::constant(8.0, 0.04),
        cache: CacheConfig {
            capacity_bytes: 8_000_000,
            far_m: 60.0,
            hold_s: 3.0,
        },
        plan: PlanStepConfig {
            intrinsics: Intrinsics {
                far: 80.0,
                ..Intrinsics::default()
            },
            ..PlanStepConfig::default()
        },
        fallback_radius: 30.0,
        ..SimConfig::default()
    }
}

#[test]
fn sessions_are_deterministic_and_bounded() {
    let cat = grid();
    let (lo, hi) = cat.bounds();
    let tr = trace::walk("grid", lo, hi, 1.7, 1.4, 40.0, 5, "test");
    let cfg = config();
    let run = |p: &mut dyn Predictor| run_session(&cat, &tr.poses, p, &cfg, |_, _, _| None);
    let a = run(&mut LinearExtrapolation::default());
    let b = run(&mut LinearExtrapolation::default());
    assert_eq!(a, b);
    assert!(a.fetches > 0 && a.bytes > 0);
    let reactive = run(&mut Reactive);
    let oracle = run(&mut Oracle {
        trace: tr.poses.clone(),
    });
    assert!(
        oracle.chr + 1e-9 >= reactive.chr,
        "{} < {}",
        oracle.chr,
        reactive.chr
    );
    for f in &oracle.frames {
        assert!(f.resident <= f.visible);
        assert!((0.0..=1.0).contains(&f.quality));
    }
}

#[test]
fn traces_round_trip_and_reject_bad_input() {
    let tr = trace::orbital("x", DVec3::ZERO, DVec3::splat(4.0), 2, "test");
    assert_eq!(tr.poses.len(), 39 * 24 + 1);
    assert!((tr.duration() - 78.0).abs() < 1e-9);
    let back = Trace::from_csv(&tr.to_csv()).unwrap();
    assert_eq!(back.poses.len(), tr.poses.len());
    assert_eq!(back.header("kind"), Some("orbital"));
    for (a, b) in tr.poses.iter().zip(&back.poses) {
        assert!(a.pos.distance(b.pos) < 1e-3);
    }
    assert!(Trace::from_csv("t,x,y,z,yaw_deg,pitch_deg\n0,0,0,0,0,0\n").is_err());
    let bad = "# splat2tiles-trace: 1\nt,x,y,z,yaw_deg,pitch_deg\n1,0,0,0,0,0\n0,0,0,0,0,0\n";
    assert!(Trace::from_csv(bad).unwrap_err().contains("line 4"));
    let d = trace::dolly("x", DVec3::ZERO, DVec3::splat(4.0), 2, "test");
    assert!((d.duration() - 20.0).abs() < 1e-9);
}
