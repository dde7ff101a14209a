//! Runs the Khronos glTF-Validator (npm `gltf-validator`, via `tests/js/validate_glb.mjs`) over
//! tiles we write and expects zero errors; needs `npm ci --prefix tests/js` once.

use std::path::{Path, PathBuf};
use std::process::Command;

use crate::common;
use splat2tiles_tiles::encode::glb::{parse_json, read_glb, write_gltf_glb};
use splat2tiles_tiles::encode::tile::IDENTITY;
use splat2tiles_tiles::encode::write_tile_glb;

use crate::common::{js_dir, require_node_modules};
use splat2tiles_core::splat::{Splat, Splats, normalize_quat};

fn tile(degree: u8, n: usize) -> Splats {
    let mut s = Splats::with_capacity(degree, n);
    for i in 0..n {
        let t = i as f32 / n as f32;
        let rest: Vec<[f32; 3]> = (0..s.rest_per_splat())
            .map(|k| [0.01 * k as f32 - 0.05, t - 0.5, 0.1])
            .collect();
        s.push(
            Splat {
                position: [100.0 + t as f64, -50.0 + (i % 7) as f64, 3.0 * t as f64],
                scale: [0.01 + t, 0.02, 0.03],
                rotation: normalize_quat([t, 0.2, -0.3, 1.0]),
                opacity: t,
                sh0: [t * 4.0 - 2.0, 0.3, -0.7],
            },
            &rest,
        );
    }
    s
}

#[test]
fn our_tiles_pass_the_khronos_validator() {
    require_node_modules();
    let dir = tempfile::tempdir().unwrap();
    // y-down source frame to glTF y-up, plus the tile centre.
    let m = [
        1.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 100.5, 50.0, -1.5, 1.0,
    ];
    let cases = [
        ("sh0.glb", tile(0, 200), [100.5, -50.0, 1.5], m),
        ("sh3.glb", tile(3, 333), [100.5, -50.0, 1.5], m),
        ("sh1_identity.glb", tile(1, 1), [0.0; 3], IDENTITY),
    ];
    let mut files: Vec<(&str, Vec<u8>)> = cases
        .iter()
        .map(|(name, splats, centre, matrix)| (*name, write_tile_glb(splats, *centre, *matrix)))
        .collect();
    // The codebook variant's container: accessors without bufferView, payload in bufferView 0.
    let codebook = splat2tiles_tiles::encode::codebook_glb::write_codebook_glb(
        &tile(3, 333),
        [100.5, -50.0, 1.5],
        m,
        &Default::default(),
    )
    .unwrap()
    .0;
    files.push(("codebook_sh3.glb", codebook));
    validate_without_errors(dir.path(), &files);
}

/// Writes `files` into `dir`, runs the Khronos validator on them and requires one report per
/// file, each with no failure and no error (warnings and infos are printed, not asserted:
/// UNSUPPORTED_EXTENSION is expected), and a successful exit.
fn validate_without_errors(dir: &Path, files: &[(&str, Vec<u8>)]) {
    let mut paths = Vec::new();
    for (name, bytes) in files {
        let p = dir.join(name);
        std::fs::write(&p, bytes).unwrap();
        paths.push(p);
    }
    let out = run_validator(&paths);
    let stdout = String::from_utf8_lossy(&out.stdout);
    let mut reports = 0;
    for line in stdout.lines() {
        let r: serde_json::Value = serde_json::from_str(line)
            .unwrap_or_else(|e| panic!("validator output is not JSON ({e}): {line}"));
        assert!(
            r.get("failure").is_none(),
            "validator could not run: {line}"
        );
        eprintln!("validator: {line}");
        assert_eq!(r["numErrors"].as_u64(), Some(0), "validator errors: {line}");
        reports += 1;
    }
    assert_eq!(
        reports,
        files.len(),
        "one report per file; stderr: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(out.status.success(), "exit status {:?}", out.status);
}

fn run_validator(paths: &[PathBuf]) -> std::process::Output {
    Command::new("node")
        .arg(js_dir().join("validate_glb.mjs"))
        .args(paths)
        .output()
        .expect("cannot run `node` (install Node >= 20)")
}

/// Layered contents (`spec/layered-content.md`): a base layer and an enhancement layer whose
/// `parentOpacityDelta` accessor follows the splat data in the BIN chunk.
#[test]
fn layered_tiles_pass_the_khronos_validator() {
    use splat2tiles_tiles::layers::glb::{add_layer, read_layer};
    require_node_modules();
    let dir = tempfile::tempdir().unwrap();
    let base = write_tile_glb(&tile(1, 50), [100.5, -50.0, 1.5], IDENTITY);
    let child = write_tile_glb(&tile(3, 33), [100.5, -50.0, 1.5], IDENTITY);
    let deltas: Vec<f32> = (0..50).map(|i| -(i as f32) / 49.0).collect();
    let cases = [
        ("base.glb", add_layer(&base, 0, None).unwrap()),
        ("layer.glb", add_layer(&child, 1, Some(&deltas)).unwrap()),
    ];
    let back = read_layer(&cases[1].1).unwrap().unwrap();
    assert_eq!(back.parent_opacity_delta.as_deref(), Some(&deltas[..]));
    validate_without_errors(dir.path(), &cases);
}

/// Format v2 layers: sparse `parentOpacityDelta` and `ancestorOpacityDeltas` (UNSIGNED_INT
/// indices + FLOAT values in the BIN chunk), positive deltas, and an all-zero accessor without
/// a bufferView.
#[test]
fn v2_layers_with_sparse_and_ancestor_deltas_pass_the_khronos_validator() {
    use splat2tiles_tiles::layers::glb::{add_layer_v2, read_layer};
    require_node_modules();
    let dir = tempfile::tempdir().unwrap();
    let child = write_tile_glb(&tile(1, 40), [100.5, -50.0, 1.5], IDENTITY);
    let mut parent = vec![0.0f32; 60];
    parent[5] = 1.5;
    parent[59] = -0.25;
    let mut grand = vec![0.0f32; 500];
    for i in (0..500).step_by(37) {
        grand[i] = i as f32 / 100.0 - 1.0;
    }
    let zeros = vec![0.0f32; 9];
    let dense: Vec<f32> = (0..60).map(|i| i as f32 / 60.0).collect();
    let cases = [
        (
            "v2_sparse.glb",
            add_layer_v2(&child, 3, Some(&parent), &[(0, &grand), (1, &zeros)]).unwrap(),
        ),
        (
            "v2_dense_parent.glb",
            add_layer_v2(&child, 2, Some(&dense), &[(0, &grand)]).unwrap(),
        ),
    ];
    let back = read_layer(&cases[0].1).unwrap().unwrap();
    assert_eq!(back.parent_opacity_delta.as_deref(), Some(&parent[..]));
    assert_eq!(back.ancestor_opacity_deltas[0].deltas, grand);
    assert_eq!(back.ancestor_opacity_deltas[1].deltas, zeros);
    // The first case really is sparse (the point of this test).
    let c = read_glb(&cases[0].1).unwrap();
    let v: serde_json::Value = serde_json::from_slice(c.json).unwrap();
    let sparse = v["accessors"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|a| a.get("sparse").is_some())
        .count();
    assert_eq!(sparse, 2, "{v}");
    validate_without_errors(dir.path(), &cases);
}

/// Every tile of a LapisGS import (`import-lapisgs`: base, placeholder-free dense levels with
/// parent and ancestor deltas, sparse where that is smaller) passes the Khronos validator.
#[test]
fn lapisgs_import_tiles_pass_the_khronos_validator() {
    use splat2tiles_build::convert::{ConvertOptions, SchemeChoice, import_lapisgs};
    require_node_modules();
    let dir = tempfile::tempdir().unwrap();
    let (_, files) = common::lapis::dense(dir.path());
    let out = dir.path().join("lapis");
    let opts = ConvertOptions {
        scheme: SchemeChoice::Octree,
        layers: true,
        progress: None,
        ..ConvertOptions::default()
    };
    import_lapisgs(&files, &out, &opts).unwrap();
    let tiles: Vec<(String, Vec<u8>)> = common::files_under(&out, "glb")
        .iter()
        .map(|p| {
            let name = p
                .strip_prefix(&out)
                .unwrap()
                .to_string_lossy()
                .replace('/', "_");
            (name, std::fs::read(p).unwrap())
        })
        .collect();
    assert!(tiles.len() > 9, "{} tiles", tiles.len());
    let named: Vec<(&str, Vec<u8>)> = tiles.iter().map(|(n, b)| (n.as_str(), b.clone())).collect();
    validate_without_errors(dir.path(), &named);
}

/// Negative control: the harness must report a real defect (a wrong POSITION max) as an error.
#[test]
fn harness_reports_a_broken_tile() {
    require_node_modules();
    let glb = write_tile_glb(&tile(0, 10), [100.0, -50.0, 0.0], IDENTITY);
    let chunks = read_glb(&glb).unwrap();
    let mut doc = parse_json(&chunks).unwrap();
    doc.accessors[0].max.as_mut().unwrap()[0] += 1.0;
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("bad_max.glb");
    std::fs::write(&p, write_gltf_glb(&doc, chunks.bin).unwrap()).unwrap();
    let out = run_validator(&[p]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    let r: serde_json::Value = serde_json::from_str(stdout.trim()).expect("one JSON line");
    assert!(r["numErrors"].as_u64().unwrap() > 0, "{stdout}");
    assert!(stdout.contains("ACCESSOR_MAX_MISMATCH"), "{stdout}");
    assert_eq!(out.status.code(), Some(1));
}
