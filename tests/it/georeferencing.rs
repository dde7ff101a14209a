//! Georeferenced and local tilesets are tight and chain-free (spec/georeferencing.md): the
//! implicit root is the smallest Web-Mercator tile holding the scene with a region within 2x of
//! the scene, Mercator keys are recoverable from the tileset metadata, no non-leaf content holds
//! fewer than the floor of splats, errors are of the scene's size, positions decode exactly.
//! Uses plant.splat (data/scenes, CC-BY-4.0 Marcel Padilla) and generated scenes.

use crate::common;

use crate::common::*;
use glam::DVec3;
use splat2tiles_build::convert::{ConvertOptions, ConvertReport, convert};
use splat2tiles_core::frame::geo::{Geodetic, mercator_key};
use splat2tiles_core::frame::mercator::MercatorKey;
use splat2tiles_core::frame::{UpAxis, source_to_tileset};
use splat2tiles_core::splat::Splats;
use splat2tiles_io::read_path;
use splat2tiles_tiles::tiling::TileKey;
use splat2tiles_tiles::tiling::extent::{reach_bounds, reaches};
use splat2tiles_tiles::tiling::load::{LoadedTileset, load_tileset};
use splat2tiles_tiles::tiling::tileset::mercator_root;
use std::collections::HashSet;
use std::path::Path;

fn georef(origin: &str, max_splats: usize, up: &str) -> ConvertOptions {
    ConvertOptions {
        origin: Some(Geodetic::parse(origin).unwrap()),
        up_axis: Some(up.parse::<UpAxis>().unwrap()),
        max_splats_per_tile: max_splats,
        keep_index_map: true,
        ..Default::default()
    }
}

/// Splat centres of the input in the tileset frame (ENU at the origin for georeferenced ones)
/// and their visible reaches there.
fn centres_t(input: &Path, up: &str) -> (Vec<DVec3>, Vec<DVec3>) {
    let a = source_to_tileset(up.parse().unwrap(), 0.0);
    let s = read_path(input).unwrap().splats;
    let pos = s
        .positions
        .iter()
        .map(|p| a * DVec3::from_array(*p))
        .collect();
    (pos, reaches(&s, a))
}

/// The level rule: content on every tile but single-child pass-throughs, which carry their
/// parent's box and error; errors never grow downwards.
fn assert_no_near_empty_levels(ts: &LoadedTileset, _max_splats: usize) {
    common::assert_levels_complete(ts);
    assert!(ts.tiles.iter().any(|t| t.content.is_some()));
}

/// `splat2tiles validate` finds no error (exit 0) in a tileset.
fn assert_valid(dir: &Path) {
    let o = std::process::Command::new(bin())
        .arg("validate")
        .arg(dir.join("tileset.json"))
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "{}\n{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
}

/// Extent (east, north, up) of the scene as drawn: centres widened by their visible reach.
fn extent(p: &[DVec3], reach: &[DVec3]) -> DVec3 {
    let (lo, hi) = reach_bounds(p, reach);
    hi - lo
}

/// The georeferenced checks shared by plant and the generated scenes; returns the root key.
fn check_georeferenced(
    out: &Path,
    report: &ConvertReport,
    origin: Geodetic,
    (pos_t, reach): &(Vec<DVec3>, Vec<DVec3>),
    max_splats: usize,
) -> MercatorKey {
    let ts = load_tileset(&out.join("tileset.json")).unwrap();
    let enu = origin.enu_to_ecef();
    let geo: Vec<Geodetic> = pos_t
        .iter()
        .map(|p| Geodetic::from_ecef(enu.transform_point3(*p)))
        .collect();

    // The Mercator root from the tileset metadata: holds every centre, and is the smallest such.
    let root = mercator_root(&ts.tileset).expect("georeferenced tilesets name their Mercator root");
    let keys: HashSet<(u32, u32, u32)> = geo
        .iter()
        .map(|g| mercator_key(g.lon, g.lat, root.zoom))
        .collect();
    assert_eq!(keys.len(), 1, "root {root:?} does not hold every splat");
    assert!(
        keys.contains(&(root.zoom, root.x, root.y)),
        "{root:?} vs {keys:?}"
    );
    if root.zoom < 30 {
        let deeper: HashSet<(u32, u32, u32)> = geo
            .iter()
            .map(|g| mercator_key(g.lon, g.lat, root.zoom + 1))
            .collect();
        assert!(
            deeper.len() > 1,
            "a deeper root than {root:?} would hold the scene"
        );
    }

    // Every leaf's implicit key maps to the Mercator key holding its splats.
    for (key, idx) in &report.leaves {
        let m = root
            .key_of(key.level, key.x, key.y)
            .expect("key below zoom 30");
        for &i in idx.iter().step_by(97) {
            let g = geo[i];
            assert_eq!(
                mercator_key(g.lon, g.lat, m.zoom),
                (m.zoom, m.x, m.y),
                "leaf {key:?}"
            );
        }
    }

    // The root region holds every centre and is within 2x of the scene's extent (as drawn).
    let region = ts
        .tileset
        .root
        .bounding_volume
        .region
        .clone()
        .expect("root region");
    for g in &geo {
        let (lon, lat) = (g.lon.to_radians(), g.lat.to_radians());
        assert!(region[0] <= lon && lon <= region[2] && region[1] <= lat && lat <= region[3]);
        assert!(region[4] <= g.height && g.height <= region[5]);
    }
    let ext = extent(pos_t, reach);
    let lat0 = origin.lat.to_radians();
    let width_m = (region[2] - region[0]) * 6_378_137.0 * lat0.cos();
    let depth_m = (region[3] - region[1]) * 6_378_137.0;
    let height_m = region[5] - region[4];
    let scene_diag = ext.length();
    let region_diag = DVec3::new(width_m, depth_m, height_m).length();
    assert!(
        width_m <= 2.0 * ext.x && depth_m <= 2.0 * ext.y && region_diag <= 2.0 * scene_diag,
        "region {width_m:.2} x {depth_m:.2} x {height_m:.2} m vs scene {ext:.2}"
    );

    // Errors are of the scene's size, not the planet's.
    let root_tile = ts.tiles.iter().find(|t| t.key == TileKey::ROOT).unwrap();
    assert!(
        root_tile.geometric_error <= 2.0 * scene_diag,
        "{}",
        root_tile.geometric_error
    );
    assert!(ts.tileset.geometric_error <= 2.0 * scene_diag);
    assert!(ts.tileset.root.geometric_error <= 2.0 * scene_diag);
    assert_no_near_empty_levels(&ts, max_splats);
    root
}

#[test]
fn plant_at_an_origin_gets_a_tight_mercator_root() {
    let tmp = tempfile::tempdir().unwrap();
    let input = scene("plant.splat");
    let out = tmp.path().join("plant");
    let opts = georef("7.44,46.95,550", 32_768, "-y");
    let report = convert(&input, &out, &opts).unwrap();
    let scene_t = centres_t(&input, "-y");
    let root = check_georeferenced(&out, &report, opts.origin.unwrap(), &scene_t, 32_768);
    // A ~2 m plant sits at zoom 20-25 (a zoom-22 tile is 6.5 m wide at 47 N).
    assert!((18..=26).contains(&root.zoom), "{root:?}");
    // Local tilesets name no Mercator root.
    let local = tmp.path().join("local");
    convert(&input, &local, &ConvertOptions::default()).unwrap();
    let ts = load_tileset(&local.join("tileset.json")).unwrap();
    assert_eq!(mercator_root(&ts.tileset), None);
}

#[test]
fn a_scene_straddling_coarse_tile_edges_has_no_chain_of_near_empty_levels() {
    // 300 m of splats centred on 0 N 0 E: the prime meridian and the equator cut it, so the
    // smallest Mercator tile holding it is the world (zoom 0), 20 levels above its leaves.
    let tmp = tempfile::tempdir().unwrap();
    let ply = tmp.path().join("district.ply");
    let mut s = random_splats(20_000, 0, 300.0, 5);
    for p in s.positions.iter_mut() {
        p[0] -= 150.0;
        p[1] -= 150.0;
    }
    write_ply_file(&ply, &s);
    let out = tmp.path().join("ts");
    let opts = georef("0,0,10", 1000, "+z");
    let report = convert(&ply, &out, &opts).unwrap();
    let root = check_georeferenced(
        &out,
        &report,
        opts.origin.unwrap(),
        &centres_t(&ply, "+z"),
        1000,
    );
    assert_eq!((root.zoom, root.x, root.y), (0, 0, 0));
    // Contents only where the scene has structure: the root (the four quarters of the world
    // meet in it, so every cut starts with a level of detail) and not on the single-child
    // chains of zoom 1..10 below it (a zoom-10 tile is 39 km wide, the scene 0.3 km), which
    // carry the root's box and error.
    let ts = load_tileset(&out.join("tileset.json")).unwrap();
    let root_tile = ts.tiles.iter().find(|t| t.key == TileKey::ROOT).unwrap();
    assert!(
        root_tile.content.is_some(),
        "the root holds a level of detail"
    );
    let shallowest = ts
        .tiles
        .iter()
        .filter(|t| t.content.is_some() && t.key.level > 0)
        .map(|t| t.key.level)
        .min()
        .unwrap();
    assert!(shallowest > 10, "content at level {shallowest}");
    assert!(
        common::assert_levels_complete(&ts) >= 4 * 10,
        "the chains are pass-throughs"
    );
    assert_eq!(report.splats_out, 20_000);
    assert_valid(&out);
}

#[test]
fn a_local_scene_with_an_outlier_has_no_chain_either() {
    // A dense 5 m cluster and one splat 2 km away: the octree root spans 2 km, the cluster
    // sits 8+ levels down a chain of single tiles.
    let tmp = tempfile::tempdir().unwrap();
    let ply = tmp.path().join("outlier.ply");
    let mut s = random_splats(12_000, 0, 5.0, 9);
    let far = random_splats(1, 0, 5.0, 10);
    let mut one = far.get(0);
    one.position = [2000.0, 2000.0, 1000.0];
    s.push(one, &[]);
    write_ply_file(&ply, &s);
    let out = tmp.path().join("ts");
    let opts = ConvertOptions {
        max_splats_per_tile: 800,
        ..Default::default()
    };
    convert(&ply, &out, &opts).unwrap();
    let ts = load_tileset(&out.join("tileset.json")).unwrap();
    assert_no_near_empty_levels(&ts, 800);
    assert_valid(&out);
    // The root box encloses every splat centre, and the levels with content are real ones.
    let b = ts.tileset.root.bounding_volume.box_.clone().unwrap();
    let a = source_to_tileset(UpAxis::NegY, 0.0);
    let s = read_path(&ply).unwrap().splats;
    for p in &s.positions {
        let p = a * DVec3::from_array(*p);
        for ax in 0..3 {
            let (c, h) = (b[ax], b[3 + ax * 4]);
            let tol = 1e-9 * (1.0 + c.abs() + h);
            assert!(p[ax] >= c - h - tol && p[ax] <= c + h + tol);
        }
    }
}

/// Largest distance between input centres and the decoded leaves' centres (source frame).
fn max_decode_error(input: &Splats, out: &Path, report: &ConvertReport) -> f64 {
    let leaves = decode_leaves(&out.join("tileset.json"));
    let mut worst = 0.0f64;
    for (key, idx) in &report.leaves {
        let d = &leaves[key].splats;
        for (j, &i) in idx.iter().enumerate() {
            let e = (DVec3::from_array(d.positions[j]) - DVec3::from_array(input.positions[i]))
                .length();
            worst = worst.max(e);
        }
    }
    worst
}

#[test]
fn positions_stay_exact_anywhere_on_earth() {
    // A 2 km district at places from the equator to 84 N, both sides of the antimeridian.
    let tmp = tempfile::tempdir().unwrap();
    let ply = tmp.path().join("d.ply");
    write_ply_file(&ply, &random_splats(6000, 0, 2000.0, 3));
    // The values the PLY holds (float32), which the tiles must reproduce.
    let s = read_path(&ply).unwrap().splats;
    for origin in [
        "0,0,0",
        "179.99,-45,100",
        "-179.99,60,-50",
        "13.4,84,3000",
        "-70,-50,0",
    ] {
        let out = tmp.path().join(origin.replace([',', '.'], "_"));
        let opts = georef(origin, 500, "+z");
        let report = convert(&ply, &out, &opts).unwrap();
        let worst = max_decode_error(&s, &out, &report);
        // float32 offsets from tile centres: far below a millimetre.
        assert!(worst < 1e-4, "{origin}: {worst} m");
        let ts = load_tileset(&out.join("tileset.json")).unwrap();
        assert_no_near_empty_levels(&ts, 500);
        assert!(ts.tileset.root.bounding_volume.region.is_some());
    }
}
