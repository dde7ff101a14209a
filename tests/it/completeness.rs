//! Completeness of the cut: at the default screen-space error, every object that the full-detail
//! scene (all leaves) shows is drawn by the tiles a REPLACE traversal selects, on generated cities.
//!
//! The cities are copies of the repository's sample scene (`samples/plant.splat`, every 16th
//! splat) laid out flat and sparse, dense, and as towers, local and georeferenced. Each city is
//! converted with the library, then rendered by the CPU reference renderer from overview, far,
//! mid, street and inside cameras: once with the tiles selected at `maxSse` 16 and once with every
//! leaf (`maxSse` 0). An object counts as visible when its projected box holds at least
//! [`MIN_INK`] pixels' worth of colour in the full render, and as present when the cut's render
//! holds at least [`MIN_SHARE`] of that ink there; the two renders must also reach [`MIN_SSIM`].

use crate::common;

use glam::{DMat3, DMat4, DQuat, DVec3};
use rayon::prelude::*;
use splat2tiles_build::convert::{ConvertOptions, SchemeChoice, convert_scene};
use splat2tiles_core::camera::{Camera, look_at_pose};
use splat2tiles_core::frame::UpAxis;
use splat2tiles_core::frame::geo::Geodetic;
use splat2tiles_core::splat::Splats;
use splat2tiles_lab::city::city_scene;
use splat2tiles_render::image::Image;
use splat2tiles_render::metrics::ssim;
use splat2tiles_render::raster::{RenderOptions, render};
use splat2tiles_tiles::geometry::{content_model, select_tiles};
use splat2tiles_tiles::tiling::load::{LoadedTileset, load_tileset};
use splat2tiles_validate::{ValidateOptions, validate_tileset};
use std::path::Path;

/// Default screen-space error of the clients (CesiumJS, our viewers, `render`).
const MAX_SSE: f64 = 16.0;
/// Colour (summed over a box, in pixels of full contrast) that makes an object visible.
const MIN_INK: f64 = 4.0;
/// Share of an object's full-detail ink the cut must draw in its box. A distant object drawn by
/// a level of detail is dimmer than its leaves: every sub-pixel leaf splat is widened to the
/// rasterizer's 0.3 px^2 low-pass at its full opacity, a few merged splats cannot carry that
/// much opacity (20-30% of the ink at 1-3 px per object); an object the cut does not draw at
/// all keeps only what its neighbours spill into its box.
const MIN_SHARE: f64 = 0.1;
/// SSIM of the cut's render against the full-detail render, every camera.
const MIN_SSIM: f64 = 0.90;
const WIDTH: u32 = 480;
const HEIGHT: u32 = 360;

/// One placed copy of the sample: its world box (1st-99th percentile of its splat centres).
#[derive(Debug, Clone, Copy)]
struct Object {
    lo: DVec3,
    hi: DVec3,
}

struct City {
    splats: Splats,
    objects: Vec<Object>,
    /// Street-level eye and where it looks (between objects).
    street: (DVec3, DVec3),
}

/// Appends `src` turned by `heading` about z, scaled by `k` and moved to `at`; returns its box.
fn place(out: &mut Splats, src: &Splats, heading: f64, k: f64, at: DVec3) -> Object {
    let rot = DMat3::from_rotation_z(heading);
    let q = DQuat::from_rotation_z(heading);
    let mut xs = Vec::with_capacity(src.len());
    for i in 0..src.len() {
        let p = rot * (DVec3::from_array(src.positions[i]) * k) + at;
        let r = src.rotations[i];
        let qi = DQuat::from_xyzw(r[0] as f64, r[1] as f64, r[2] as f64, r[3] as f64);
        let n = (q * qi).normalize();
        out.positions.push(p.to_array());
        out.scales
            .push(src.scales[i].map(|v| (v as f64 * k) as f32));
        out.rotations
            .push([n.x as f32, n.y as f32, n.z as f32, n.w as f32]);
        out.opacities.push(src.opacities[i]);
        out.sh0.push(src.sh0[i]);
        xs.push(p);
    }
    let pct = |axis: usize, q: f64| {
        let mut v: Vec<f64> = xs.iter().map(|p| p[axis]).collect();
        v.sort_by(f64::total_cmp);
        v[((v.len() - 1) as f64 * q) as usize]
    };
    Object {
        lo: DVec3::new(pct(0, 0.01), pct(1, 0.01), pct(2, 0.01)),
        hi: DVec3::new(pct(0, 0.99), pct(1, 0.99), pct(2, 0.99)),
    }
}

/// A `side` x `side` grid of copies `spacing` apart, each `size` (min, max) metres across and
/// stacked `stack` (min, max) high; jittered by a quarter of the spacing.
fn city(side: usize, spacing: f64, size: (f64, f64), stack: (usize, usize), seed: u64) -> City {
    let src = common::plant_sample(16);
    let mut rng = common::Rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1);
    let mut splats = Splats::new(src.sh_degree);
    let mut objects = vec![];
    for gy in 0..side {
        for gx in 0..side {
            let jitter = DVec3::new(rng.f() - 0.5, rng.f() - 0.5, 0.0) * 0.5 * spacing;
            let base = DVec3::new(gx as f64 * spacing, gy as f64 * spacing, 0.0) + jitter;
            let levels = stack.0 + ((stack.1 - stack.0 + 1) as f64 * rng.f()) as usize;
            let mut z = 0.0;
            for _ in 0..levels.max(1) {
                let k = size.0 + (size.1 - size.0) * rng.f();
                let o = place(
                    &mut splats,
                    &src,
                    rng.f() * std::f64::consts::TAU,
                    k,
                    base + DVec3::Z * z,
                );
                z = o.hi.z;
                objects.push(o);
            }
        }
    }
    let mid = (side as f64 - 1.0) * 0.5;
    let street_y = (mid.floor() + 0.5) * spacing;
    City {
        splats,
        objects,
        street: (
            DVec3::new(-0.5 * spacing, street_y, 2.0),
            DVec3::new(side as f64 * spacing, street_y, 2.0),
        ),
    }
}

/// The cameras of a city in its input frame: overview, far, mid, street, inside an object.
fn cameras(c: &City) -> Vec<(&'static str, Camera)> {
    let lo = c.objects.iter().fold(DVec3::MAX, |a, o| a.min(o.lo));
    let hi = c.objects.iter().fold(DVec3::MIN, |a, o| a.max(o.hi));
    let centre = (lo + hi) * 0.5;
    let extent = (hi - lo).length();
    let cam = |eye: DVec3, at: DVec3| {
        Camera::from_pose(WIDTH, HEIGHT, 60.0, look_at_pose(eye, at, DVec3::Z))
    };
    let o = c.objects[c.objects.len() / 2];
    let o_mid = (o.lo + o.hi) * 0.5;
    vec![
        (
            "overview",
            cam(centre + DVec3::new(0.0, -0.55, 0.85) * extent, centre),
        ),
        (
            "far",
            cam(centre + DVec3::new(-1.6, -1.9, 0.35) * extent, centre),
        ),
        (
            "mid",
            cam(centre + DVec3::new(0.35, -0.45, 0.12) * extent, centre),
        ),
        ("street", cam(c.street.0, c.street.1)),
        ("inside", cam(o_mid, o_mid + DVec3::new(1.0, 0.3, 0.0))),
    ]
}

/// Renders the contents `select_tiles` picks at `max_sse` for `cam` (given in the input frame;
/// `frame` maps it to the tileset's world frame).
fn render_cut(ts: &LoadedTileset, frame: DMat4, cam: &Camera, max_sse: f64) -> (Image, usize) {
    let world = Camera {
        world_from_camera: frame * cam.world_from_camera,
        ..*cam
    };
    let picked = select_tiles(ts, &world, max_sse);
    let contents: Vec<(Splats, DMat4)> = picked
        .iter()
        .map(|p| {
            let (s, node) = splat2tiles_tiles::variants::decode_variant(&std::fs::read(p).unwrap())
                .unwrap_or_else(|e| panic!("{}: {e}", p.display()));
            (s, content_model(ts, &node))
        })
        .collect();
    let refs: Vec<(&Splats, DMat4)> = contents.iter().map(|(s, m)| (s, *m)).collect();
    (
        render(&refs, &world, &RenderOptions::default()),
        picked.len(),
    )
}

/// Colour of `img` summed over `o`'s projected box (black background), in full-contrast pixels;
/// `None` when the box is not wholly in front of the camera.
fn ink(img: &Image, cam: &Camera, o: &Object) -> Option<f64> {
    let (mut x0, mut y0, mut x1, mut y1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
    for i in 0..8 {
        let p = DVec3::new(
            if i & 1 == 0 { o.lo.x } else { o.hi.x },
            if i & 2 == 0 { o.lo.y } else { o.hi.y },
            if i & 4 == 0 { o.lo.z } else { o.hi.z },
        );
        let [x, y] = cam.project(p)?;
        (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x), y1.max(y));
    }
    let clamp = |v: f64, n: u32| (v.round().max(0.0) as i64).min(n as i64 - 1);
    let (xa, xb) = (clamp(x0 - 2.0, img.width), clamp(x1 + 2.0, img.width));
    let (ya, yb) = (clamp(y0 - 2.0, img.height), clamp(y1 + 2.0, img.height));
    if x1 < 0.0 || y1 < 0.0 || x0 >= img.width as f64 || y0 >= img.height as f64 {
        return Some(0.0);
    }
    let mut sum = 0.0;
    for y in ya..=yb {
        for x in xa..=xb {
            let p = img.get(x as u32, y as u32);
            sum += p.iter().fold(0.0f32, |m, &v| m.max(v)) as f64;
        }
    }
    Some(sum)
}

/// What one camera found: objects visible in the full render and missing from the cut, SSIM.
struct Finding {
    camera: &'static str,
    visible: usize,
    missing: Vec<usize>,
    /// Smallest share of its full-detail ink that the cut draws, over the visible objects.
    min_share: f64,
    ssim: f64,
    tiles: usize,
}

/// Converts `c` (georeferenced at `origin` when given) and checks every camera.
fn check_city(
    name: &str,
    c: &City,
    origin: Option<Geodetic>,
    scheme: SchemeChoice,
) -> Vec<Finding> {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join(name);
    let opts = ConvertOptions {
        max_splats_per_tile: 2048,
        up_axis: Some(UpAxis::PosZ),
        origin,
        scheme,
        ..ConvertOptions::default()
    };
    convert_scene(city_scene(c.splats.clone()), name, &out, &opts).unwrap();
    let report = validate_tileset(&out.join("tileset.json"), &ValidateOptions::default()).unwrap();
    assert!(
        report.num_errors + report.num_warnings == 0,
        "{name}: validate: {:?}",
        report.issues
    );
    let ts = load_tileset(&out.join("tileset.json")).unwrap();
    let passes = common::assert_levels_complete(&ts);
    let root = ts.tiles.iter().find(|t| t.key.parent().is_none()).unwrap();
    println!(
        "{name}: {:?}, {} tiles ({passes} pass-throughs), root error {:.2}, tileset error {:.2}",
        ts.scheme,
        ts.tiles.len(),
        root.geometric_error,
        ts.tileset.geometric_error
    );
    // The input frame is the tileset's root frame (local ENU when georeferenced).
    let frame = ts.root_transform;
    cameras(c)
        .into_par_iter()
        .map(|(label, cam)| {
            let (full, _) = render_cut(&ts, frame, &cam, 0.0);
            let (cut, tiles) = render_cut(&ts, frame, &cam, MAX_SSE);
            if let Some(d) = std::env::var_os("COMPLETENESS_DEBUG") {
                let d = Path::new(&d);
                full.save_png(&d.join(format!("{name}_{label}_full.png")))
                    .unwrap();
                cut.save_png(&d.join(format!("{name}_{label}_cut.png")))
                    .unwrap();
            }
            let mut visible = 0;
            let mut missing = vec![];
            let mut min_share = f64::INFINITY;
            for (i, o) in c.objects.iter().enumerate() {
                let (Some(f), Some(k)) = (ink(&full, &cam, o), ink(&cut, &cam, o)) else {
                    continue;
                };
                if f >= MIN_INK {
                    visible += 1;
                    min_share = min_share.min(k / f);
                    if k < MIN_SHARE * f {
                        if std::env::var_os("COMPLETENESS_DEBUG").is_some() {
                            println!("{name}/{label}: object {i} ink {f:.1} full, {k:.1} cut");
                        }
                        missing.push(i);
                    }
                }
            }
            Finding {
                camera: label,
                visible,
                missing,
                min_share,
                ssim: ssim(&full, &cut).unwrap(),
                tiles,
            }
        })
        .collect()
}

/// Runs [`check_city`] and fails with a table of every camera that misses objects or SSIM.
fn assert_complete(name: &str, c: &City, origin: Option<Geodetic>) {
    assert_complete_as(name, c, origin, SchemeChoice::Auto);
}

/// [`assert_complete`] with the subdivision of a local build forced.
fn assert_complete_as(name: &str, c: &City, origin: Option<Geodetic>, scheme: SchemeChoice) {
    let findings = check_city(name, c, origin, scheme);
    let mut bad = vec![];
    for f in &findings {
        let line = format!(
            "{name}/{}: {} of {} visible objects missing {:?}, least ink share {:.3}, SSIM {:.4}, \
             {} tiles drawn",
            f.camera,
            f.missing.len(),
            f.visible,
            f.missing,
            f.min_share,
            f.ssim,
            f.tiles
        );
        println!("{line}");
        if !f.missing.is_empty() || f.ssim < MIN_SSIM {
            bad.push(line);
        }
    }
    assert!(
        findings.iter().map(|f| f.visible).sum::<usize>() > 0,
        "{name}: no camera sees an object (the harness is broken)"
    );
    assert!(bad.is_empty(), "incomplete cuts:\n{}", bad.join("\n"));
}

const ORIGIN: Geodetic = Geodetic {
    lon: 8.5417,
    lat: 47.3769,
    height: 400.0,
};

#[test]
fn flat_sparse_city_local() {
    assert_complete("flat_sparse", &city(5, 200.0, (7.0, 16.0), (1, 1), 1), None);
}

#[test]
fn flat_sparse_city_local_octree() {
    let c = city(5, 200.0, (7.0, 16.0), (1, 1), 1);
    assert_complete_as("flat_sparse_octree", &c, None, SchemeChoice::Octree);
}

#[test]
fn flat_sparse_city_georeferenced() {
    let c = city(5, 200.0, (7.0, 16.0), (1, 1), 2);
    assert_complete("flat_sparse_georef", &c, Some(ORIGIN));
}

#[test]
fn dense_city_local() {
    assert_complete("dense", &city(8, 22.0, (8.0, 16.0), (1, 1), 3), None);
}

#[test]
fn dense_city_georeferenced() {
    let c = city(8, 22.0, (8.0, 16.0), (1, 1), 4);
    assert_complete("dense_georef", &c, Some(ORIGIN));
}

#[test]
fn tall_city_local() {
    assert_complete("tall", &city(4, 60.0, (8.0, 14.0), (2, 6), 5), None);
}

#[test]
fn tall_sparse_city_georeferenced() {
    let c = city(3, 250.0, (8.0, 14.0), (3, 6), 6);
    assert_complete("tall_sparse_georef", &c, Some(ORIGIN));
}
