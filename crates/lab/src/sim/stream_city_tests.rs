//! Tests of the streaming city: a small city generated, converted and checked for streets, four
//! variants and reproducibility; the traces' geometry; the split of the trace set.

use super::*;
use splat2tiles_stream::split::{eyenav_scene_of, split_of};

fn root() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
}

fn scenes() -> PathBuf {
    root().join("data/scenes")
}

fn nav() -> PathBuf {
    root().join("data/navigation-traces")
}

/// Deletes a test's folder however the test ends.
struct RemoveOnDrop(PathBuf);

impl Drop for RemoveOnDrop {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn small() -> CitySpec {
    CitySpec {
        splats: 60_000,
        stride: 64,
        seed: 3,
        max_splats_per_tile: 2048,
    }
}

fn grid(spec: &CitySpec) -> StreetGrid {
    StreetGrid::of(
        &city_sources(&scenes(), spec.stride).unwrap(),
        &spec.layout(),
    )
}

/// A small city (`data/scenes/README.md` content): streets stay (almost) clear, the
/// conversion writes four variants, georeferenced, the same bytes twice.
#[test]
fn small_city_has_streets_four_variants_and_is_reproducible() {
    if !scenes().exists() {
        eprintln!("skipped: no shared scenes");
        return;
    }
    let spec = small();
    let g = grid(&spec);
    assert!(g.side >= 3, "{g:?}");
    let splats = generate_city(
        &city_sources(&scenes(), spec.stride).unwrap(),
        &spec.layout(),
    );
    let on_street = splats
        .positions
        .iter()
        .filter(|p| g.street_distance(DVec2::new(p[0], p[1])) < 2.0)
        .count();
    assert!(
        on_street * 100 < splats.len() * 3,
        "{on_street} of {} splats within 2 m of a street centre line",
        splats.len()
    );
    let tmp = root().join(format!("target/tmp-stream-city-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&tmp);
    let _cleanup = RemoveOnDrop(tmp.clone());
    let origin = Some(Geodetic::parse(DEFAULT_ORIGIN).unwrap());
    let a = build_city(&scenes(), &tmp.join("a/city"), &spec, origin).unwrap();
    let b = build_city(&scenes(), &tmp.join("b/city"), &spec, origin).unwrap();
    assert_eq!(a.splats, 60_000);
    assert!(a.content_tiles > 20, "{}", a.content_tiles);
    assert!(
        a.variant_bytes.iter().all(|&v| v > 0),
        "{:?}",
        a.variant_bytes
    );
    assert!(a.variant_bytes[0] > a.variant_bytes[3]);
    assert_eq!(a.variant_bytes, b.variant_bytes);
    assert_eq!(a.bytes, b.bytes);
    let ta = std::fs::read_to_string(a.dir.join("tileset.json")).unwrap();
    let tb = std::fs::read_to_string(b.dir.join("tileset.json")).unwrap();
    assert_eq!(ta, tb);
    assert!(ta.contains("transform"), "georeferenced: root transform");
    // The tileset frame is the generator's (ENU at the origin): the catalogue's boxes cover the
    // generated splats and are not shifted from them horizontally (they reach metres beyond:
    // splat extents and box orientations), so traces in that frame walk through the tiles.
    let ts = splat2tiles_tiles::tiling::load::load_tileset(&a.dir.join("tileset.json")).unwrap();
    let cat = splat2tiles_stream::TileCatalog::from_loaded(&ts.tiles, |_| Some(1));
    let (lo, hi) = cat.bounds();
    let (slo, shi) = splats.bounds().unwrap();
    for k in 0..3 {
        assert!(
            lo[k] <= slo[k]
                && hi[k] >= shi[k]
                && (k == 2 || ((lo[k] + hi[k]) - (slo[k] + shi[k])).abs() < 10.0),
            "axis {k}: catalogue {lo} {hi}, splats {slo:?} {shi:?}"
        );
    }
    // Walking reveals new tiles: street walks keep meeting tiles they had not seen (this small
    // city is seen almost whole from most streets: no occlusion in the culling; the full city's
    // numbers are in BENCHMARKS.md).
    let late: Vec<(usize, usize)> = (0..3)
        .map(|seed| revealed(&cat, &street_walk(&g, seed, 120.0), 30.0))
        .collect();
    assert!(
        late.iter().map(|l| l.0).sum::<usize>() >= 10,
        "(first seen after 30 s, seen) per walk: {late:?}"
    );
}

#[test]
fn street_walks_keep_to_the_streets_and_reach_new_blocks() {
    let g = StreetGrid {
        spacing: 24.0,
        side: 6,
    };
    for seed in 0..6 {
        let t = street_walk(&g, seed, 120.0);
        assert_eq!(t.poses.len(), 1441);
        let mut nodes = std::collections::HashSet::new();
        for w in t.poses.windows(2) {
            let p = w[1].pos.truncate();
            assert!(
                g.street_distance(p) < 1e-6,
                "seed {seed}: {p} off the street"
            );
            let v = (w[1].pos - w[0].pos).length() * TRACE_HZ;
            assert!(v <= WALK_SPEED * 1.001, "seed {seed}: {v} m/s");
            assert_eq!(w[1].pos.z, EYE_HEIGHT);
            nodes.insert(((p.x / 24.0).round() as i64, (p.y / 24.0).round() as i64));
        }
        let (lo, hi) = g.extent();
        assert!(
            t.poses
                .iter()
                .all(|p| p.pos.x >= lo.x - 1e-9 && p.pos.y <= hi.y + 1e-9)
        );
        // 120 s at 1.4 m/s with pauses and turns: several blocks.
        assert!(nodes.len() >= 4, "seed {seed}: {} cells", nodes.len());
        assert_eq!(split_of(&t).unwrap(), synthetic_split(seed));
    }
    assert_eq!(street_walk(&g, 4, 30.0), street_walk(&g, 4, 30.0));
    assert_ne!(street_walk(&g, 4, 30.0), street_walk(&g, 5, 30.0));
}

#[test]
fn flights_stay_over_the_city_at_altitude() {
    let g = StreetGrid {
        spacing: 24.0,
        side: 6,
    };
    for seed in FLIGHT_SEEDS.take(5) {
        let t = flight(&g, seed, 60.0);
        for w in t.poses.windows(2) {
            let z = w[1].pos.z;
            assert!((FLIGHT_ALTITUDE - 5.0..=FLIGHT_ALTITUDE + 5.0).contains(&z));
            let v = (w[1].pos - w[0].pos).truncate().length() * TRACE_HZ;
            assert!(v <= FLIGHT_SPEED * 1.001);
            assert!(w[1].pitch < -0.2 && w[1].pitch > -0.7);
        }
        let (lo, hi) = g.extent();
        let margin = 30.0;
        assert!(t.poses.iter().all(|p| p.pos.x > lo.x - margin
            && p.pos.x < hi.x + margin
            && p.pos.y > lo.y - margin
            && p.pos.y < hi.y + margin));
    }
}

/// The city's trace set per split (`data/navigation-traces/README.md`): the evaluation set
/// holds only test scenes (nyc, truck) and test seeds; the tuning set none of them.
#[test]
fn trace_sets_split_by_scene() {
    if !nav().exists() {
        eprintln!("skipped: no navigation traces");
        return;
    }
    let g = StreetGrid {
        spacing: 24.0,
        side: 6,
    };
    let eval = evaluation_set(&g, &nav()).unwrap();
    // 44 sessions + 3 walks + 3 flights.
    assert_eq!(eval.traces().len(), 50);
    for t in eval.traces() {
        assert_eq!(split_of(t).unwrap(), Split::Test);
        if let Some(s) = eyenav_scene_of(t) {
            assert!(s == "nyc" || s == "truck", "{s}");
            // Placed at street level: starts on a street, eyes near 1.7 m.
            assert!(g.street_distance(t.poses[0].pos.truncate()) < 1e-9);
            assert!((t.poses[0].pos.z - EYE_HEIGHT).abs() < 1.0);
        }
    }
    let tune = tuning_set(&g, &nav()).unwrap();
    // 7 train scenes x 22 + 14 walks + 14 flights; 1 val scene x 22 + 3 + 3.
    assert_eq!((tune.train().len(), tune.val().len()), (182, 28));
    for t in tune.train().iter().chain(tune.val()) {
        assert_ne!(split_of(t).unwrap(), Split::Test);
        if let Some(s) = eyenav_scene_of(t) {
            assert!(s != "nyc" && s != "truck", "{s}");
        }
    }
}
