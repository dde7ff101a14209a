//! `import-lapisgs` (spec/layered-content.md, "Importing LapisGS-trained layers"): generated
//! LapisGS-like levels import into a layered v2 tileset that validates, draws each level's
//! opacities exactly (eq. 4 between levels), renders like the last level's PLY, and refuses
//! files that break the prefix rule without leaving output.

use crate::common;

use crate::common::lapis::{dense, levels, write_levels};

use splat2tiles_build::convert::{ConvertOptions, LapisReport, SchemeChoice, import_lapisgs};
use splat2tiles_core::camera::auto_views_with;
use splat2tiles_core::splat::Splats;
use splat2tiles_render::metrics::ssim;
use splat2tiles_render::raster::{RenderOptions, render};
use splat2tiles_tiles::geometry::finite_bounds;
use splat2tiles_tiles::layers::blend::{DrawnLayer, effective_opacities};
use splat2tiles_tiles::layers::glb::{LayerInfo, read_layer};
use splat2tiles_tiles::layers::view::ancestor_deltas;
use splat2tiles_tiles::tiling::TileKey;
use splat2tiles_tiles::tiling::load::load_tileset;
use splat2tiles_validate::{ValidateOptions, validate_tileset};
use std::collections::{BTreeMap, HashMap};
use std::path::Path;

fn opts() -> ConvertOptions {
    ConvertOptions {
        scheme: SchemeChoice::Octree,
        subtree_levels: Some(2),
        layers: true,
        progress: None,
        ..ConvertOptions::default()
    }
}

/// An imported tileset's layers, parents first: key, splats (source frame), layer.
struct Imported {
    tiles: Vec<(TileKey, Splats, LayerInfo)>,
}

fn imported(tileset: &Path) -> Imported {
    let ts = load_tileset(tileset).unwrap();
    let decoded = common::decode_tileset(tileset);
    let mut tiles: BTreeMap<TileKey, (Splats, LayerInfo)> = BTreeMap::new();
    for t in &ts.tiles {
        let Some(p) = &t.content else { continue };
        let bytes = std::fs::read(p).unwrap();
        let layer = read_layer(&bytes)
            .unwrap()
            .expect("every content is a layer");
        assert_eq!(layer.level, t.key.level);
        tiles.insert(t.key, (decoded[&t.key].splats.clone(), layer));
    }
    let mut v: Vec<(TileKey, Splats, LayerInfo)> =
        tiles.into_iter().map(|(k, (s, l))| (k, s, l)).collect();
    v.sort_by_key(|(k, _, _)| (k.level, *k));
    Imported { tiles: v }
}

impl Imported {
    /// Effective opacities of the layers up to `max_level`, layer at level `l` drawn at
    /// `blend(l)`.
    fn effective(&self, max_level: u32, blend: impl Fn(u32) -> f32) -> Vec<(TileKey, Vec<f32>)> {
        let picked: Vec<&(TileKey, Splats, LayerInfo)> = self
            .tiles
            .iter()
            .filter(|(k, _, _)| k.level <= max_level)
            .collect();
        let at: HashMap<TileKey, usize> = picked
            .iter()
            .enumerate()
            .map(|(i, (k, _, _))| (*k, i))
            .collect();
        let anc: Vec<_> = picked
            .iter()
            .map(|(k, _, l)| ancestor_deltas(k.level, Some(l)))
            .collect();
        let layers: Vec<DrawnLayer<'_>> = picked
            .iter()
            .zip(&anc)
            .map(|((k, s, l), a)| DrawnLayer {
                splats: s,
                parent: k.parent().map(|p| at[&p]),
                deltas: l.parent_opacity_delta.as_deref(),
                blend: blend(k.level),
                ancestors: a,
            })
            .collect();
        let ops = effective_opacities(&layers).unwrap();
        picked.iter().map(|(k, _, _)| *k).zip(ops).collect()
    }

    /// Each imported splat's index in the level files (matched on its exact DC colour), or
    /// `None` for a placeholder (stored opacity 0).
    fn origin(&self, all: &Splats, max_level: u32) -> HashMap<(TileKey, usize), usize> {
        let key = |c: [f32; 3]| c.map(f32::to_bits);
        let by: HashMap<[u32; 3], usize> = (0..all.len()).map(|i| (key(all.sh0[i]), i)).collect();
        let mut out = HashMap::new();
        for (k, s, _) in self.tiles.iter().filter(|(k, _, _)| k.level <= max_level) {
            for j in 0..s.len() {
                if s.opacities[j] > 0.0 {
                    out.insert((*k, j), by[&key(s.sh0[j])]);
                }
            }
        }
        out
    }
}

/// Asserts that the drawn opacity of every splat of the levels up to `max_level` is `want(i)`.
fn assert_opacities(
    imp: &Imported,
    all: &Splats,
    max_level: u32,
    blend: impl Fn(u32) -> f32,
    want: impl Fn(usize) -> f32,
) -> usize {
    let origin = imp.origin(all, max_level);
    let mut seen = vec![false; all.len()];
    for (k, ops) in imp.effective(max_level, blend) {
        for (j, &o) in ops.iter().enumerate() {
            let Some(&i) = origin.get(&(k, j)) else {
                assert_eq!(o, 0.0, "a placeholder of {k:?} is drawn");
                continue;
            };
            assert!(!seen[i], "splat {i} imported twice");
            seen[i] = true;
            assert!(
                (o - want(i)).abs() <= 1e-5,
                "splat {i} in {k:?}: drawn at {o}, want {}",
                want(i)
            );
        }
    }
    seen.iter().filter(|s| **s).count()
}

#[test]
fn import_validates_and_draws_every_level_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let (lv, files) = dense(dir.path());
    let out = dir.path().join("lapis");
    let r: LapisReport = import_lapisgs(&files, &out, &opts()).unwrap();
    assert_eq!(r.level_splats, vec![600, 2000, 5000]);
    assert_eq!((r.dropped, r.placeholders), (0, 0), "{r:?}");
    // Half of the earlier splats change at each level: 300 at level 1, 1000 at level 2.
    assert_eq!(r.deltas, 300 + 1000, "{r:?}");
    let tileset = out.join("tileset.json");
    let report = validate_tileset(&tileset, &ValidateOptions::default()).unwrap();
    assert!(report.codes().is_empty(), "{}", report.to_text("lapis"));
    let ts = load_tileset(&tileset).unwrap();
    assert_eq!(ts.tileset.root.refine.as_deref(), Some("ADD"));

    let imp = imported(&tileset);
    let last = &lv[2];
    // Every layer drawn fully: each splat at its opacity in the last level's file, none missing.
    let n = assert_opacities(&imp, last, 2, |_| 1.0, |i| last.opacities[i]);
    assert_eq!(n, 5000);
    // Levels 0 and 1 only: level 1's file.
    let n = assert_opacities(&imp, &lv[1], 1, |_| 1.0, |i| lv[1].opacities[i]);
    assert_eq!(n, 2000);
    // Level 2 half blended in (eq. 4): earlier splats at the midpoint of levels 1 and 2, level
    // 2's own splats at half their opacity.
    assert_opacities(
        &imp,
        last,
        2,
        |l| if l == 2 { 0.5 } else { 1.0 },
        |i| {
            if i < 2000 {
                0.5 * (lv[1].opacities[i] + last.opacities[i])
            } else {
                0.5 * last.opacities[i]
            }
        },
    );
    // Some level-2 layer carries ancestor (level 0) deltas, and some delta accessor is sparse.
    assert!(
        imp.tiles
            .iter()
            .any(|(_, _, l)| l.ancestor_opacity_deltas.iter().any(|a| a.level == 0))
    );
    let sparse = common::files_under(&out, "glb").iter().any(|p| {
        let b = std::fs::read(p).unwrap();
        let c = splat2tiles_tiles::encode::glb::read_glb(&b).unwrap();
        String::from_utf8_lossy(c.json).contains("\"sparse\"")
    });
    assert!(sparse, "no sparse delta accessor written");

    // A CPU render of the import (every layer, effective opacities) equals one of the last PLY.
    let mut drawn = vec![];
    for ((_, s, _), (_, ops)) in imp.tiles.iter().zip(imp.effective(2, |_| 1.0)) {
        let mut s = s.clone();
        s.opacities = ops;
        drawn.push(s);
    }
    let scene = splat2tiles_io::read_path(&files[2]).unwrap().splats;
    let (lo, hi) = finite_bounds(&scene).unwrap();
    let id = glam::DMat4::IDENTITY;
    for cam in auto_views_with(lo, hi, glam::DVec3::NEG_Y, 160, 120, 50.0) {
        let a = render(&[(&scene, id)], &cam, &RenderOptions::default());
        let refs: Vec<(&Splats, glam::DMat4)> = drawn.iter().map(|s| (s, id)).collect();
        let b = render(&refs, &cam, &RenderOptions::default());
        let q = ssim(&a, &b).unwrap();
        assert!(q >= 0.999, "SSIM {q}");
    }
}

/// Level 1 adds splats only at x < 3.5 and level 2 only at x > 6.5: level 2's layers need
/// placeholder parents, earlier splats whose level-2 cell is empty are carried by the nearest
/// level-2 layer, and level-1 splats (no level-2 layer below their tile) lose their level-2
/// change, which the report counts.
#[test]
fn sparse_levels_get_placeholders_and_report_dropped_changes() {
    let dir = tempfile::tempdir().unwrap();
    let base = common::random_splats(400, 0, 10.0, 5);
    let west_all = common::random_splats(3000, 0, 10.0, 6);
    let west: Vec<usize> = (0..3000)
        .filter(|&i| west_all.positions[i][0] < 3.5)
        .take(300)
        .collect();
    let w = west_all.select(&west);
    let east_all = common::random_splats(3000, 0, 10.0, 8);
    let east: Vec<usize> = (0..3000)
        .filter(|&i| east_all.positions[i][0] > 6.5)
        .take(500)
        .collect();
    let e = east_all.select(&east);
    let mut all = base.clone();
    for s in [&w, &e] {
        for i in 0..s.len() {
            all.push_from(s, i);
        }
    }
    let lv = levels(&all, &[400, 700, 1200], |_, i| i % 3 == 0);
    let files = write_levels(dir.path(), &lv);
    let out = dir.path().join("lapis");
    let r = import_lapisgs(&files, &out, &opts()).unwrap();
    // Level-1 splats changed at level 2: indices 400..700 with i % 3 == 0.
    let lost = (400..700).filter(|i| i % 3 == 0).count();
    assert_eq!(r.dropped, lost, "{r:?}");
    assert!(r.placeholders >= 1 && r.rerouted >= 1, "{r:?}");
    let report = validate_tileset(&out.join("tileset.json"), &ValidateOptions::default()).unwrap();
    assert!(report.codes().is_empty(), "{}", report.to_text("lapis"));
    // Everything else is drawn at the last level's opacity; the dropped ones keep level 1's.
    let imp = imported(&out.join("tileset.json"));
    let n = assert_opacities(
        &imp,
        &lv[2],
        2,
        |_| 1.0,
        |i| {
            if (400..700).contains(&i) {
                lv[1].opacities[i]
            } else {
                lv[2].opacities[i]
            }
        },
    );
    assert_eq!(n, 1200);
}

#[test]
fn a_level_breaking_the_prefix_rule_is_refused_with_file_splat_and_byte() {
    let dir = tempfile::tempdir().unwrap();
    let all = common::random_splats(900, 1, 10.0, 3);
    let mut lv = levels(&all, &[300, 900], |_, i| i % 2 == 0);
    lv[1].scales[17][0] *= 1.5;
    let files = write_levels(dir.path(), &lv);
    let out = dir.path().join("out");
    let o = std::process::Command::new(common::bin())
        .arg("import-lapisgs")
        .args(&files)
        .arg("-o")
        .arg(&out)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("level1.ply") && err.contains("splat 17") && err.contains("byte "),
        "{err}"
    );
    assert!(err.contains("scale"), "{err}");
    assert!(!out.exists(), "output left behind");
    // Fewer splats than the previous level: refused too.
    let o = std::process::Command::new(common::bin())
        .arg("import-lapisgs")
        .args([&files[1], &files[0]])
        .arg("-o")
        .arg(&out)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("level0.ply") && err.contains("fewer"), "{err}");
    assert!(!out.exists());
    // The valid pair through the CLI: a summary with the counts.
    let ok = levels(&all, &[300, 900], |_, i| i % 2 == 0);
    let files = write_levels(dir.path(), &ok);
    let o = std::process::Command::new(common::bin())
        .arg("import-lapisgs")
        .args(&files)
        .arg("-o")
        .arg(&out)
        .arg("--json")
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["levelSplats"], serde_json::json!([300, 900]));
    assert_eq!(v["dropped"], serde_json::json!(0));
    common::assert_valid_with_extents(&out);
}

/// LapisGS eq. 4 frame by frame: level 2 blended in with t = 0, 0.1, ..., 1 (CPU reference
/// renders at 160x120); neighbouring frames stay within an SSIM step of 0.02 while the first and
/// last frames differ by more (the change is real), and t = 0 / t = 1 render as levels 1 / 2.
#[test]
fn blending_in_a_level_changes_frames_continuously() {
    let dir = tempfile::tempdir().unwrap();
    let (lv, files) = dense(dir.path());
    let out = dir.path().join("lapis");
    import_lapisgs(&files, &out, &opts()).unwrap();
    let imp = imported(&out.join("tileset.json"));
    let (lo, hi) = finite_bounds(&lv[2]).unwrap();
    let cam = auto_views_with(lo, hi, glam::DVec3::NEG_Y, 160, 120, 50.0)
        .into_iter()
        .nth(1)
        .unwrap();
    let id = glam::DMat4::IDENTITY;
    let frame = |t: f32| {
        let mut drawn = vec![];
        for ((_, s, _), (_, ops)) in imp
            .tiles
            .iter()
            .zip(imp.effective(2, |l| if l == 2 { t } else { 1.0 }))
        {
            let mut s = s.clone();
            s.opacities = ops;
            drawn.push(s);
        }
        let refs: Vec<(&Splats, glam::DMat4)> = drawn.iter().map(|s| (s, id)).collect();
        render(&refs, &cam, &RenderOptions::default())
    };
    let frames: Vec<_> = (0..=10).map(|i| frame(i as f32 / 10.0)).collect();
    let mut worst = 1.0f64;
    for w in frames.windows(2) {
        worst = worst.min(ssim(&w[0], &w[1]).unwrap());
    }
    let ends = ssim(&frames[0], &frames[10]).unwrap();
    eprintln!("worst neighbour SSIM {worst:.4}, first vs last {ends:.4}");
    assert!(worst >= 0.98, "a step of SSIM {worst}");
    assert!(
        ends < worst,
        "first vs last {ends} is no bigger a change than a step"
    );
    let level = |k: usize| render(&[(&lv[k], id)], &cam, &RenderOptions::default());
    assert!(ssim(&frames[0], &level(1)).unwrap() >= 0.999);
    assert!(ssim(&frames[10], &level(2)).unwrap() >= 0.999);
}

/// The other tilings: a quadtree and a georeferenced (Web-Mercator) import of the dense set
/// validate and still draw the last level exactly.
#[test]
fn quadtree_and_georeferenced_imports_validate_and_draw_the_last_level() {
    let dir = tempfile::tempdir().unwrap();
    let (lv, files) = dense(dir.path());
    let origin = splat2tiles_core::frame::geo::Geodetic::parse("2.2945,48.8584,35").unwrap();
    for (name, o) in [
        (
            "quad",
            ConvertOptions {
                scheme: SchemeChoice::Quadtree,
                ..opts()
            },
        ),
        (
            "geo",
            ConvertOptions {
                origin: Some(origin),
                ..opts()
            },
        ),
    ] {
        let out = dir.path().join(name);
        let r = import_lapisgs(&files, &out, &o).unwrap();
        assert_eq!(r.scheme, "QUADTREE", "{name}");
        let tileset = out.join("tileset.json");
        let report = validate_tileset(&tileset, &ValidateOptions::default()).unwrap();
        assert!(
            report.codes().is_empty(),
            "{name}: {}",
            report.to_text(name)
        );
        let imp = imported(&tileset);
        let n = assert_opacities(&imp, &lv[2], 2, |_| 1.0, |i| lv[2].opacities[i]);
        assert_eq!((n, r.dropped), (5000, 0), "{name}: {r:?}");
    }
}
