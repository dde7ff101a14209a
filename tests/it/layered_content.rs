//! Layered content (`spec/layered-content.md`, LapisGS sec. 3.1-3.3): `convert --layers` output
//! validates, its layers reproduce the finer level once every child layer is in, and a level
//! change rendered frame by frame blends continuously where a hard (REPLACE) swap jumps.

use crate::common;

use splat2tiles_build::convert::{ConvertOptions, SchemeChoice, convert};
use splat2tiles_core::camera::auto_views_with;
use splat2tiles_core::splat::Splats;
use splat2tiles_render::image::Image;
use splat2tiles_render::metrics::ssim;
use splat2tiles_render::raster::{RenderOptions, render};
use splat2tiles_tiles::encode::read_tile_glb;
use splat2tiles_tiles::geometry::{content_model, select_tiles, tileset_bounds, tileset_up};
use splat2tiles_tiles::layers::blend::{DrawnLayer, drawn_layers};
use splat2tiles_tiles::layers::glb::read_layer;
use splat2tiles_tiles::layers::view::{is_layered, layered_instances};
use splat2tiles_tiles::tiling::TileKey;
use splat2tiles_tiles::tiling::load::{LoadedTileset, load_tileset};
use splat2tiles_validate::{ValidateOptions, validate_tileset};
use std::path::Path;

/// Most SSIM one frame of a level change may lose against the previous one.
const SSIM_STEP: f64 = 0.02;
/// Frames over which the blend factor goes from 0 to 1.
const FRAMES: usize = 10;

/// A generated SH-1 scene (6000 splats, 400 per leaf) converted with `layers`.
fn converted(dir: &Path, layers: bool) -> std::path::PathBuf {
    let ply = dir.join("scene.ply");
    common::write_ply_file(&ply, &common::random_splats(6000, 1, 10.0, 7));
    let out = dir.join(if layers { "layered" } else { "plain" });
    let opts = ConvertOptions {
        max_splats_per_tile: 400,
        scheme: SchemeChoice::Octree,
        subtree_levels: Some(2),
        layers,
        progress: None,
        ..ConvertOptions::default()
    };
    convert(&ply, &out, &opts).expect("convert");
    out.join("tileset.json")
}

fn content(ts: &LoadedTileset, key: TileKey) -> Vec<u8> {
    let t = ts.tiles.iter().find(|t| t.key == key).expect("tile");
    std::fs::read(t.content.as_ref().expect("content")).unwrap()
}

#[test]
fn layered_output_validates_and_its_layers_reproduce_the_finer_level() {
    let dir = tempfile::tempdir().unwrap();
    let path = converted(dir.path(), true);
    let report = validate_tileset(&path, &ValidateOptions::default()).unwrap();
    assert!(report.codes().is_empty(), "{}", report.to_text("layered"));
    let ts = load_tileset(&path).unwrap();
    assert!(is_layered(&ts));
    assert_eq!(ts.tileset.root.refine.as_deref(), Some("ADD"));

    let root_bytes = content(&ts, TileKey::ROOT);
    let root = read_tile_glb(&root_bytes).unwrap();
    let base = read_layer(&root_bytes).unwrap().expect("base layer");
    assert_eq!((base.level, base.parent_opacity_delta.is_none()), (0, true));
    let kids: Vec<(Splats, Vec<f32>)> = ts
        .tiles
        .iter()
        .filter(|t| t.key.level == 1 && t.content.is_some())
        .map(|t| {
            let b = std::fs::read(t.content.as_ref().unwrap()).unwrap();
            let l = read_layer(&b).unwrap().expect("layer");
            assert_eq!(l.level, 1);
            (
                read_tile_glb(&b).unwrap().splats,
                l.parent_opacity_delta.unwrap(),
            )
        })
        .collect();
    assert!(kids.len() >= 2, "the root has {} child layers", kids.len());
    // Every root splat is handed over entirely to its children.
    for i in 0..root.splats.len() {
        let sum: f32 = kids.iter().map(|(_, d)| d[i]).sum();
        assert!(
            (sum + 1.0).abs() < 1e-4,
            "root splat {i}: deltas add up to {sum}"
        );
    }
    // Every child layer fully in: the base vanishes (occupancy rule) and the drawn splats are
    // exactly the finer level's.
    let mut layers = vec![DrawnLayer {
        splats: &root.splats,
        parent: None,
        deltas: None,
        blend: 1.0,
        ancestors: &[],
    }];
    for (s, d) in &kids {
        layers.push(DrawnLayer {
            splats: s,
            parent: Some(0),
            deltas: Some(d),
            blend: 1.0,
            ancestors: &[],
        });
    }
    let drawn = drawn_layers(&layers).unwrap();
    assert_eq!(drawn[0].len(), 0, "base splats left");
    for (d, (s, _)) in drawn[1..].iter().zip(&kids) {
        let kept: Vec<usize> = (0..s.len())
            .filter(|&i| s.opacities[i] >= splat2tiles_tiles::layers::OCCUPANCY_THRESHOLD)
            .collect();
        assert_eq!(*d, s.select(&kept));
    }
    // Half-way, a root splat keeps half of what the children take from it.
    for l in &mut layers[1..] {
        l.blend = 0.5;
    }
    let half = splat2tiles_tiles::layers::blend::effective_opacities(&layers).unwrap();
    for (i, &o) in root.splats.opacities.iter().enumerate().take(50) {
        assert!((half[0][i] - 0.5 * o).abs() < 1e-5, "{} vs {o}", half[0][i]);
    }

    // Splats and metadata are those of the plain conversion; only the layer extension differs.
    let plain = load_tileset(&converted(dir.path(), false)).unwrap();
    assert!(!is_layered(&plain));
    for (a, b) in plain.tiles.iter().zip(&ts.tiles) {
        assert_eq!((a.key, a.splat_count), (b.key, b.splat_count));
        let sa = read_tile_glb(&std::fs::read(a.content.as_ref().unwrap()).unwrap()).unwrap();
        let sb = read_tile_glb(&std::fs::read(b.content.as_ref().unwrap()).unwrap()).unwrap();
        assert_eq!(sa.splats, sb.splats);
    }
}

/// Screen-space error of the root as `render::cli::select_tiles` computes it.
fn root_sse(ts: &LoadedTileset, cam: &splat2tiles_core::camera::Camera) -> f64 {
    let t = ts.tiles.iter().find(|t| t.key == TileKey::ROOT).unwrap();
    let (c, r) =
        splat2tiles_tiles::select::box_sphere(t.bounding_box.as_ref().unwrap(), &ts.root_transform);
    t.geometric_error * cam.fy / (c.distance(cam.center()) - r).max(1e-9)
}

fn replace_frame(
    ts: &LoadedTileset,
    cam: &splat2tiles_core::camera::Camera,
    max_sse: f64,
) -> Image {
    let inst: Vec<(Splats, glam::DMat4)> = select_tiles(ts, cam, max_sse)
        .iter()
        .map(|p| {
            let t = read_tile_glb(&std::fs::read(p).unwrap()).unwrap();
            let m = content_model(ts, &t.node_matrix);
            (t.splats, m)
        })
        .collect();
    let refs: Vec<(&Splats, glam::DMat4)> = inst.iter().map(|(s, m)| (s, *m)).collect();
    render(&refs, cam, &RenderOptions::default())
}

#[test]
fn a_level_change_blends_frame_by_frame_where_a_hard_swap_jumps() {
    let dir = tempfile::tempdir().unwrap();
    let ts = load_tileset(&converted(dir.path(), true)).unwrap();
    let (lo, hi) = tileset_bounds(&ts).unwrap();
    let cam = auto_views_with(lo, hi, tileset_up(&ts), 192, 108, 50.0).remove(1);
    // Same camera; the refinement threshold goes from the root's screen-space error to half of
    // it, so the root's children blend in with t = k / FRAMES (eq. 4 over the error).
    let s0 = root_sse(&ts, &cam);
    let mut layered = vec![];
    let mut swapped = vec![];
    for k in 0..=FRAMES {
        let max_sse = s0 / (1.0 + k as f64 / FRAMES as f64);
        let inst = layered_instances(&ts, &cam, max_sse).unwrap();
        let refs: Vec<(&Splats, glam::DMat4)> = inst.iter().map(|(s, m)| (s, *m)).collect();
        layered.push(render(&refs, &cam, &RenderOptions::default()));
        swapped.push(replace_frame(&ts, &cam, max_sse));
    }
    let steps = |frames: &[Image]| -> Vec<f64> {
        frames
            .windows(2)
            .map(|w| ssim(&w[0], &w[1]).unwrap())
            .collect()
    };
    let blended = steps(&layered);
    let hard = steps(&swapped);
    eprintln!("layered neighbour SSIM: {blended:.4?}");
    eprintln!("REPLACE neighbour SSIM: {hard:.4?}");
    let whole = ssim(&layered[0], &layered[FRAMES]).unwrap();
    eprintln!("first vs last layered frame: {whole:.4}");
    // The change is real: jumping from the first frame to the last one loses more than a step.
    assert!(whole < 1.0 - SSIM_STEP, "level change too small: {whole}");
    // Blended: no frame differs from its neighbour by more than the step.
    for (k, s) in blended.iter().enumerate() {
        assert!(
            *s >= 1.0 - SSIM_STEP,
            "layered frame {k} -> {}: SSIM {s}",
            k + 1
        );
    }
    // Hard swap (REPLACE selection over the same frames): some frame jumps by more.
    let worst = hard.iter().copied().fold(1.0, f64::min);
    assert!(worst < 1.0 - SSIM_STEP, "REPLACE never jumped: {hard:?}");
    // The first frame is the root alone in both; the last layered frame is the children's.
    assert_eq!(layered[0].data, swapped[0].data);
}

/// The command line: `convert --layers` writes a tileset `validate` passes and `render` draws as
/// layers; `--layers` with `--no-lod` (parents without content) is refused before any output.
#[test]
fn cli_converts_validates_and_renders_layers() {
    let dir = tempfile::tempdir().unwrap();
    let ply = dir.path().join("scene.ply");
    common::write_ply_file(&ply, &common::random_splats(3000, 0, 10.0, 3));
    let out = dir.path().join("layered");
    let run = |args: &[&str]| {
        std::process::Command::new(common::bin())
            .args(args)
            .output()
            .unwrap()
    };
    let ply_s = ply.to_str().unwrap();
    let out_s = out.to_str().unwrap();
    let o = run(&[
        "convert",
        ply_s,
        "-o",
        out_s,
        "--max-splats",
        "500",
        "--layers",
        "-q",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let ts = out.join("tileset.json");
    let o = run(&["validate", ts.to_str().unwrap()]);
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stdout)
    );
    let png = dir.path().join("view.png");
    let o = run(&[
        "render",
        ts.to_str().unwrap(),
        "--auto-view",
        "0",
        "--width",
        "96",
        "--height",
        "64",
        "-o",
        png.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(err.contains(" layers of "), "{err}");

    let refused = dir.path().join("refused");
    let o = run(&[
        "convert",
        ply_s,
        "-o",
        refused.to_str().unwrap(),
        "--layers",
        "--no-lod",
        "-q",
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(!refused.exists());
    let o = run(&[
        "convert",
        ply_s,
        "-o",
        refused.to_str().unwrap(),
        "--layers",
        "--profile",
        "cesium",
        "-q",
    ]);
    assert_eq!(
        o.status.code(),
        Some(2),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(String::from_utf8_lossy(&o.stderr).contains("--layers"));
    assert!(!refused.exists());
}
