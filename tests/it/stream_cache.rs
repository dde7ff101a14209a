//! Cache and visibility checks: capacity never exceeded, parents outlive resident children,
//! no downgrades; the exact frustum test agrees with point sampling and the others' errors.

use glam::DVec3;
use splat2tiles_core::rng::SplitMix64;
use splat2tiles_stream::cache::{Cache, CacheConfig, EvictContext, Inserted};
use splat2tiles_stream::catalog::{Level, TileCatalog};
use splat2tiles_stream::geom::{Frustum, Intrinsics, Obb, ViewPose};
use splat2tiles_stream::visibility::VisTest;
use splat2tiles_tiles::tiling::TileKey;
use splat2tiles_tiles::tiling::load::LoadedTile;

/// A 3-level quadtree catalog (1 + 4 + 16 tiles, all with content) over a 64 m square.
fn tree() -> TileCatalog {
    let mut tiles = vec![];
    for level in 0..3u32 {
        let n = 1u32 << level;
        let size = 64.0 / n as f64;
        for y in 0..n {
            for x in 0..n {
                let c = [(x as f64 + 0.5) * size, (y as f64 + 0.5) * size, 2.0];
                let h = size / 2.0;
                tiles.push(LoadedTile {
                    key: TileKey { level, x, y, z: 0 },
                    content: Some(format!("{level}_{x}_{y}.glb").into()),
                    bounding_box: Some([c[0], c[1], c[2], h, 0.0, 0.0, 0.0, h, 0.0, 0.0, 0.0, 2.0]),
                    geometric_error: 8.0 / n as f64,
                    splat_count: Some(1000),
                });
            }
        }
    }
    TileCatalog::from_loaded(&tiles, |t| Some(1000 + 10 * t.key.level as u64))
}

#[test]
fn cache_never_exceeds_capacity_and_keeps_parents() {
    let cat = tree();
    assert_eq!(cat.tiles.len(), 21);
    let mut rng = SplitMix64::new(1);
    let mut cache = Cache::new(CacheConfig {
        capacity_bytes: 6000,
        far_m: 20.0,
        hold_s: 1.0,
    });
    let mut visible = vec![false; cat.tiles.len()];
    for step in 0..3000 {
        let now = step as f64 * 0.1;
        for v in visible.iter_mut() {
            *v = rng.f64() < 0.1;
        }
        let pos = DVec3::new(rng.range(0.0, 64.0), rng.range(0.0, 64.0), 2.0);
        let tile = rng.below(cat.tiles.len());
        let level = Level::from_index(rng.below(4));
        let bytes = cat.tiles[tile].variants[level.index()].bytes;
        let ctx = EvictContext {
            catalog: &cat,
            pos,
            now,
            visible: &visible,
        };
        let before = cache.level(tile);
        let r = cache.insert(tile, level, bytes, &ctx);
        assert!(cache.used() <= 6000, "over capacity at step {step}");
        if let Inserted::Stored(victims) = &r {
            for v in victims {
                assert!(!visible[*v], "evicted a visible tile");
            }
        }
        if let Some(b) = before {
            // Hysteresis: never a lower level than before (unless it was evicted).
            if let Some(now_level) = cache.level(tile) {
                assert!(now_level <= b.max(level) || now_level == level);
                assert!(now_level <= b);
            }
        }
        let used: u64 = cache.resident().map(|(_, e)| e.bytes).sum();
        assert_eq!(used, cache.used());
    }
    assert!(cache.evictions > 0, "the test never filled the cache");
}

#[test]
fn parent_never_evicted_while_child_resident() {
    let cat = tree();
    let visible = vec![false; cat.tiles.len()];
    let root = cat.roots[0];
    let child = cat.tiles[root].children[0];
    let grandchild = cat.tiles[child].children[0];
    let sizes = |i: usize| cat.tiles[i].variants[0].bytes;
    let cap = sizes(root) + sizes(child) + sizes(grandchild);
    let mut cache = Cache::new(CacheConfig {
        capacity_bytes: cap,
        far_m: 0.0,
        hold_s: 0.0,
    });
    let ctx = EvictContext {
        catalog: &cat,
        pos: DVec3::new(1000.0, 0.0, 0.0),
        now: 10.0,
        visible: &visible,
    };
    for t in [root, child, grandchild] {
        assert!(matches!(
            cache.insert(t, Level::Best, sizes(t), &ctx),
            Inserted::Stored(_)
        ));
    }
    // A new deep tile forces evictions: the grandchild (deepest, no resident descendant) goes
    // before its parent and grandparent.
    let other = cat.tiles[child].children[1];
    match cache.insert(other, Level::Best, sizes(other), &ctx) {
        Inserted::Stored(v) => assert_eq!(v, vec![grandchild]),
        r => panic!("{r:?}"),
    }
    // While `other` (a child of `child`) is resident, `child` and `root` cannot be removed.
    assert!(!cache.remove(&cat, child));
    assert!(!cache.remove(&cat, root));
    assert!(cache.remove(&cat, other));
    assert!(cache.remove(&cat, child));
    // A downgrade is ignored.
    assert_eq!(cache.insert(root, Level::Low, 1, &ctx), Inserted::Kept);
    assert_eq!(cache.level(root), Some(Level::Best));
}

#[test]
fn exact_test_matches_point_sampling_and_planes_is_conservative() {
    let mut rng = SplitMix64::new(9);
    let k = Intrinsics {
        far: 60.0,
        ..Intrinsics::default()
    };
    let mut fp_planes = 0;
    for _ in 0..400 {
        let pose = ViewPose {
            t: 0.0,
            pos: DVec3::new(
                rng.range(-5.0, 5.0),
                rng.range(-5.0, 5.0),
                rng.range(0.0, 3.0),
            ),
            yaw: rng.range(-3.1, 3.1),
            pitch: rng.range(-0.5, 0.5),
        };
        let f = Frustum::new(&pose, &k);
        let c = DVec3::new(
            rng.range(-40.0, 40.0),
            rng.range(-40.0, 40.0),
            rng.range(-5.0, 5.0),
        );
        let b = Obb::aabb(c - DVec3::splat(rng.range(0.5, 6.0)), c + DVec3::splat(2.0));
        let exact = VisTest::Exact.visible(&f, &b);
        // Dense sampling of the box: any sample inside => must be visible.
        let (lo, hi) = b.aabb_bounds();
        let mut hit = false;
        for i in 0..9 {
            for j in 0..9 {
                for l in 0..9 {
                    let p = lo + (hi - lo) * DVec3::new(i as f64, j as f64, l as f64) / 8.0;
                    hit |= f.contains(p);
                }
            }
        }
        if hit {
            assert!(exact, "exact test missed a box with a point inside");
            assert!(VisTest::Planes.visible(&f, &b), "plane test missed");
        }
        if exact {
            assert!(
                VisTest::Planes.visible(&f, &b),
                "plane test must be conservative"
            );
        } else if VisTest::Planes.visible(&f, &b) {
            fp_planes += 1;
        }
        if VisTest::CornerAny.visible(&f, &b) {
            assert!(exact, "a corner inside means visible");
        }
    }
    assert!(fp_planes < 400);
}
