//! End-to-end tests of `splat2tiles convert`: splat totals on the shared scenes, attribute round
//! trips through the glb tiles, georeferencing, and bad input leaving no output behind.

use crate::common::*;
use splat2tiles_build::convert::{ConvertOptions, convert};
use splat2tiles_core::frame::geo::Geodetic;
use splat2tiles_core::splat::Splats;
use splat2tiles_io::read_path;
use splat2tiles_tiles::tiling::load::load_tileset;
use std::path::Path;
use std::process::Command;

fn run_convert(args: &[&str]) -> std::process::Output {
    Command::new(bin())
        .arg("convert")
        .args(args)
        .output()
        .expect("run splat2tiles")
}

#[test]
fn shared_scenes_keep_every_splat() {
    let tmp = tempfile::tempdir().unwrap();
    for (name, count) in [
        ("plant.splat", 113_648usize),
        ("donut_fused_sh0.ply", 45_624),
        ("biker.spz", 152_746),
    ] {
        let out = tmp.path().join(name.replace('.', "_"));
        let o = run_convert(&[
            scene(name).to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--max-splats",
            "20000",
        ]);
        assert!(
            o.status.success(),
            "{name}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        assert!(out.join("tileset.json").is_file());
        let ts = load_tileset(&out.join("tileset.json")).unwrap();
        assert!(ts.tiles.len() > 1, "{name}: more than one tile");
        let subtrees = files_under(&out.join("subtrees"), "subtree");
        assert!(!subtrees.is_empty(), "{name}: subtree files written");
        let parents: std::collections::HashSet<_> =
            ts.tiles.iter().filter_map(|t| t.key.parent()).collect();
        let from_metadata: u64 = ts
            .tiles
            .iter()
            .filter(|t| !parents.contains(&t.key))
            .filter_map(|t| t.splat_count)
            .map(u64::from)
            .sum();
        assert_eq!(from_metadata as usize, count, "{name}: splatCount metadata");
        let decoded = decode_leaves(&out.join("tileset.json"));
        let total: usize = decoded.values().map(|d| d.splats.len()).sum();
        assert_eq!(total, count, "{name}: splats over all leaf tiles");
        // Every content tile (leaves and LOD parents) respects the budget.
        for t in &ts.tiles {
            if let Some(n) = t.splat_count {
                assert!(n <= 20_000, "{name}: leaf {:?} holds {n}", t.key);
            }
        }
        let stdout = String::from_utf8_lossy(&o.stdout);
        assert!(stdout.contains(&count.to_string()), "summary: {stdout}");
    }
}

/// Converts `input` with an index map and checks every splat decoded from the tiles against the
/// reader's output (the documented conversions are the reader's; the tiles must not alter them).
fn assert_round_trip(input: &Path, opts: ConvertOptions) {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("ts");
    let opts = ConvertOptions {
        keep_index_map: true,
        ..opts
    };
    let report = convert(input, &out, &opts).expect("convert");
    let mut source: Splats = read_path(input).expect("read").splats;
    source.drop_non_finite();
    let (lo, hi) = source.bounds().unwrap();
    let size = (0..3).map(|a| hi[a] - lo[a]).fold(0.0f64, f64::max);
    let decoded = decode_tileset(&out.join("tileset.json"));
    let mut checked = 0;
    for (key, indices) in &report.leaves {
        let got = &decoded[key].splats;
        assert_eq!(got.len(), indices.len());
        assert_eq!(got.sh_degree, source.sh_degree);
        for (j, &i) in indices.iter().enumerate() {
            let close = |a: f32, b: f32| (a - b).abs() <= 1e-6 * (1.0f32).max(b.abs());
            for a in 0..3 {
                let d = (got.positions[j][a] - source.positions[i][a]).abs();
                assert!(
                    d <= 1e-5 * size,
                    "{}: splat {i} position off by {d}",
                    input.display()
                );
                assert!(close(got.scales[j][a], source.scales[i][a]), "scale of {i}");
                assert!(close(got.sh0[j][a], source.sh0[i][a]), "sh0 of {i}");
            }
            for a in 0..4 {
                assert!(
                    close(got.rotations[j][a], source.rotations[i][a]),
                    "rotation of {i}"
                );
            }
            assert!(
                close(got.opacities[j], source.opacities[i]),
                "opacity of {i}"
            );
            for (g, s) in got.rest_of(j).iter().zip(source.rest_of(i)) {
                for c in 0..3 {
                    assert!(close(g[c], s[c]), "higher SH of {i}");
                }
            }
            checked += 1;
        }
    }
    assert_eq!(checked, source.len(), "every splat compared");
}

#[test]
fn round_trip_shared_scenes() {
    for name in ["plant.splat", "donut_fused_sh0.ply", "biker.spz"] {
        assert_round_trip(
            &scene(name),
            ConvertOptions {
                max_splats_per_tile: 16_384,
                ..Default::default()
            },
        );
    }
}

#[test]
fn round_trip_generated_sh3_ply() {
    let tmp = tempfile::tempdir().unwrap();
    let ply = tmp.path().join("sh3.ply");
    let splats = random_splats(6000, 3, 20.0, 42);
    write_ply_file(&ply, &splats);
    let read = read_path(&ply).unwrap().splats;
    assert_eq!(read.sh_degree, 3);
    assert!(
        read.sh_rest.iter().flatten().any(|v| v.abs() > 0.01),
        "non-zero higher SH"
    );
    assert_round_trip(
        &ply,
        ConvertOptions {
            max_splats_per_tile: 700,
            ..Default::default()
        },
    );
}

#[test]
fn georeferenced_scene_is_a_mercator_quadtree_with_ecef_root() {
    let tmp = tempfile::tempdir().unwrap();
    let ply = tmp.path().join("city.ply");
    // 2 km wide synthetic district, z-up metres.
    let splats = random_splats(5000, 1, 2000.0, 7);
    write_ply_file(&ply, &splats);
    let origin = Geodetic::parse("13.4050,52.5200,40").unwrap();
    let opts = ConvertOptions {
        origin: Some(origin),
        up_axis: Some("+z".parse().unwrap()),
        max_splats_per_tile: 500,
        keep_index_map: true,
        ..Default::default()
    };
    let out = tmp.path().join("ts");
    let report = convert(&ply, &out, &opts).unwrap();
    assert_eq!(report.scheme, "QUADTREE");
    let ts = load_tileset(&out.join("tileset.json")).unwrap();
    let root = &ts.tileset.root;
    assert!(root.transform.is_some(), "root carries ENU->ECEF");
    assert!(root.bounding_volume.region.is_some());
    // Leaves sit at Web-Mercator zooms that match a 2 km district (zoom 13-20); the implicit
    // root is the Mercator tile the tileset metadata names (spec/georeferencing.md).
    let root_key = splat2tiles_tiles::tiling::tileset::mercator_root(&ts.tileset).unwrap();
    let leaf_zooms: Vec<u32> = report
        .leaves
        .iter()
        .map(|(k, _)| root_key.zoom + k.level)
        .collect();
    assert!(
        leaf_zooms.iter().all(|&z| (12..=22).contains(&z)),
        "{leaf_zooms:?}"
    );
    // A leaf's implicit key maps to the Web-Mercator key (y flipped to grow northwards).
    let src = read_path(&ply).unwrap().splats;
    let enu = origin.enu_to_ecef();
    for (key, idx) in report.leaves.iter().take(5) {
        let p = src.positions[idx[0]];
        let g = Geodetic::from_ecef(enu.transform_point3(glam::DVec3::from_array(p)));
        let m = root_key.key_of(key.level, key.x, key.y).unwrap();
        let (z, x, y) = splat2tiles_core::frame::geo::mercator_key(g.lon, g.lat, m.zoom);
        assert_eq!((z, x, y), (m.zoom, m.x, m.y));
    }
    let total: usize = decode_leaves(&out.join("tileset.json"))
        .values()
        .map(|d| d.splats.len())
        .sum();
    assert_eq!(total, 5000);
}

#[test]
fn local_scheme_follows_the_scene_shape() {
    let tmp = tempfile::tempdir().unwrap();
    let flat = tmp.path().join("flat.ply");
    let mut s = random_splats(3000, 0, 100.0, 3);
    for p in s.positions.iter_mut() {
        p[1] *= 0.01; // y is the vertical axis for the default -y up.
    }
    write_ply_file(&flat, &s);
    let r = convert(&flat, &tmp.path().join("a"), &ConvertOptions::default()).unwrap();
    assert_eq!(r.scheme, "QUADTREE");
    let cube = tmp.path().join("cube.ply");
    write_ply_file(&cube, &random_splats(3000, 0, 100.0, 4));
    let opts = ConvertOptions {
        max_splats_per_tile: 100,
        ..Default::default()
    };
    let r = convert(&cube, &tmp.path().join("b"), &opts).unwrap();
    assert_eq!(r.scheme, "OCTREE");
    assert!(r.levels >= 2);
    let ts = load_tileset(&tmp.path().join("b/tileset.json")).unwrap();
    assert!(
        ts.tileset.root.transform.is_none(),
        "no Earth maths for a local scene"
    );
    assert!(ts.tileset.root.bounding_volume.box_.is_some());
}

// ---- bad input: clear one-line error, exit 2, no output left behind ----

const PROPS: [&str; 14] = [
    "x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity", "scale_0", "scale_1", "scale_2",
    "rot_0", "rot_1", "rot_2", "rot_3",
];

fn ply_bytes(props: &[&str], declared: u64, records: &[Vec<f32>]) -> Vec<u8> {
    let mut h = format!("ply\nformat binary_little_endian 1.0\nelement vertex {declared}\n");
    for p in props {
        h.push_str(&format!("property float {p}\n"));
    }
    h.push_str("end_header\n");
    let mut b = h.into_bytes();
    for r in records {
        for v in r {
            b.extend_from_slice(&v.to_le_bytes());
        }
    }
    b
}

fn record(i: usize) -> Vec<f32> {
    vec![
        i as f32, 0.5, -0.25, 0.1, 0.2, 0.3, 0.0, -3.0, -3.0, -3.0, 1.0, 0.0, 0.0, 0.0,
    ]
}

fn records(n: usize) -> Vec<Vec<f32>> {
    (0..n).map(record).collect()
}

/// Runs convert on `bytes` saved as `name`; asserts a failure naming the file (and `needle`) and
/// that the output folder does not exist afterwards.
fn assert_refused(name: &str, bytes: &[u8], extra: &[&str], needle: &str) {
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join(name);
    std::fs::write(&input, bytes).unwrap();
    let out = tmp.path().join("out");
    let mut args = vec![input.to_str().unwrap(), "-o", out.to_str().unwrap()];
    args.extend_from_slice(extra);
    let o = run_convert(&args);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{name}: exit code; stderr: {err}");
    assert!(err.contains(name), "{name}: error names the file: {err}");
    assert!(err.contains(needle), "{name}: error says '{needle}': {err}");
    assert_eq!(err.trim().lines().count(), 1, "{name}: one line: {err}");
    assert!(!err.contains("panicked"), "{name}: {err}");
    assert!(!out.exists(), "{name}: no output folder after failure");
    let leftovers: Vec<_> = std::fs::read_dir(tmp.path())
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with('.'))
        .collect();
    assert!(
        leftovers.is_empty(),
        "{name}: temporary folders left: {leftovers:?}"
    );
}

#[test]
fn truncated_ply_body() {
    let mut b = ply_bytes(&PROPS, 10, &records(10));
    b.truncate(b.len() - 30);
    assert_refused("truncated.ply", &b, &[], "byte");
}

#[test]
fn ply_count_disagrees_with_size() {
    let b = ply_bytes(&PROPS, 5, &records(10));
    assert_refused("toolong.ply", &b, &[], "byte");
}

#[test]
fn absurd_vertex_count() {
    let b = ply_bytes(&PROPS, 4_000_000_000, &records(2));
    assert_refused("absurd.ply", &b, &[], "byte");
}

#[test]
fn missing_required_property() {
    let props: Vec<&str> = PROPS.iter().copied().filter(|p| *p != "opacity").collect();
    let recs: Vec<Vec<f32>> = (0..3).map(|_| vec![0.0; props.len()]).collect();
    assert_refused(
        "noopacity.ply",
        &ply_bytes(&props, 3, &recs),
        &[],
        "opacity",
    );
}

#[test]
fn unknown_format() {
    assert_refused(
        "mystery.bin",
        b"this is not a splat scene at all",
        &[],
        "format",
    );
}

#[test]
fn zero_splats() {
    assert_refused("empty.ply", &ply_bytes(&PROPS, 0, &[]), &[], "no splats");
}

#[test]
fn splat_file_length_not_multiple_of_32() {
    assert_refused("odd.splat", &[0u8; 70], &[], "32");
}

#[test]
fn truncated_spz() {
    let bytes = std::fs::read(scene("biker.spz")).unwrap();
    assert_refused("cut.spz", &bytes[..bytes.len() / 3], &[], "cut.spz");
}

#[test]
fn nan_fails_with_offset_when_asked_and_is_dropped_by_default() {
    let mut recs = records(6);
    recs[3][1] = f32::NAN;
    let b = ply_bytes(&PROPS, 6, &recs);
    assert_refused("nan.ply", &b, &["--non-finite", "fail"], "byte");
    // Default: dropped and reported.
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("nan.ply");
    std::fs::write(&input, &b).unwrap();
    let out = tmp.path().join("out");
    let o = run_convert(&[input.to_str().unwrap(), "-o", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(stdout.contains("dropped 1 splats"), "{stdout}");
    let total: usize = decode_leaves(&out.join("tileset.json"))
        .values()
        .map(|d| d.splats.len())
        .sum();
    assert_eq!(total, 5);
    // All NaN: nothing left to tile.
    let recs: Vec<Vec<f32>> = (0..3).map(|_| vec![f32::INFINITY; 14]).collect();
    assert_refused("allnan.ply", &ply_bytes(&PROPS, 3, &recs), &[], "NaN");
}

#[test]
fn failed_run_leaves_the_earlier_result_untouched() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    let good = tmp.path().join("good.ply");
    std::fs::write(&good, ply_bytes(&PROPS, 8, &records(8))).unwrap();
    let o = run_convert(&[good.to_str().unwrap(), "-o", out.to_str().unwrap()]);
    assert!(o.status.success());
    let before = std::fs::read(out.join("tileset.json")).unwrap();
    let files_before = files_under(&out, "glb").len();
    let bad = tmp.path().join("bad.ply");
    let mut b = ply_bytes(&PROPS, 8, &records(8));
    b.truncate(b.len() - 7);
    std::fs::write(&bad, b).unwrap();
    let o = run_convert(&[bad.to_str().unwrap(), "-o", out.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    assert_eq!(std::fs::read(out.join("tileset.json")).unwrap(), before);
    assert_eq!(files_under(&out, "glb").len(), files_before);
    // A successful re-run replaces it completely.
    let o = run_convert(&[
        scene("donut_fused_sh0.ply").to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success());
    assert_ne!(std::fs::read(out.join("tileset.json")).unwrap(), before);
    // ... and says so (the first run into an absent folder did not).
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains(&format!(
            "replaced the earlier splat2tiles output in {}",
            out.display()
        )),
        "{err}"
    );
}

/// The "look at it" hint's commands, run as printed: from a folder the binary is not in and not
/// on PATH (its path is printed), and with it on PATH (installed: its bare name).
#[test]
fn the_hint_names_the_program_as_it_can_be_run() {
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("in.ply");
    std::fs::write(&input, ply_bytes(&PROPS, 8, &records(8))).unwrap();
    let bin_dir = bin()
        .canonicalize()
        .unwrap()
        .parent()
        .unwrap()
        .to_path_buf();
    for installed in [false, true] {
        let path = if installed {
            format!("{}:/usr/bin:/bin", bin_dir.display())
        } else {
            "/usr/bin:/bin".to_string()
        };
        let o = Command::new(bin())
            .args(["convert", "in.ply", "-o", "out", "--no-utility"])
            .current_dir(tmp.path())
            .env("PATH", &path)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let (hint, words) = convert_hint(&String::from_utf8_lossy(&o.stdout));
        if installed {
            assert!(hint.starts_with("splat2tiles view out "), "{hint}");
            assert_eq!(words[0], "splat2tiles");
        } else {
            assert_eq!(
                Path::new(&words[0]),
                bin().canonicalize().unwrap(),
                "{hint}"
            );
        }
        let o = Command::new(&words[0])
            .args(&words[1..])
            .current_dir(tmp.path())
            .env("PATH", &path)
            .output()
            .unwrap();
        assert!(
            o.status.success(),
            "{hint}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        assert!(tmp.path().join("view.png").is_file());
        std::fs::remove_file(tmp.path().join("view.png")).unwrap();
    }
}

#[test]
fn refuses_to_replace_a_folder_that_is_not_a_tileset() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("precious");
    std::fs::create_dir(&out).unwrap();
    std::fs::write(out.join("notes.txt"), "keep me").unwrap();
    let o = run_convert(&[
        scene("donut_fused_sh0.ply").to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert_eq!(
        std::fs::read_to_string(out.join("notes.txt")).unwrap(),
        "keep me"
    );
}

#[test]
fn help_lists_examples() {
    let o = Command::new(bin())
        .args(["convert", "--help"])
        .output()
        .unwrap();
    let s = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success());
    assert!(s.contains("Examples:") && s.contains("--origin") && s.contains("--up-axis"));
    // The usage shows -o as required; the everyday options come before the sharded ones.
    let usage = s
        .lines()
        .find(|l| l.starts_with("Usage:"))
        .unwrap_or_default();
    assert!(
        usage.starts_with("Usage: splat2tiles convert <INPUT> -o <OUTPUT>"),
        "{usage}"
    );
    // The help line declaring --flag (`  -q, --quiet`, `      --part <PART>`).
    let at = |flag: &str| {
        s.lines()
            .position(|l| {
                let l = l.trim_start();
                let l = l.split_once(", ").map_or(
                    l,
                    |(short, long)| {
                        if short.len() == 2 { long } else { l }
                    },
                );
                l.strip_prefix("--")
                    .and_then(|r| r.strip_prefix(flag))
                    .is_some_and(|r| r.is_empty() || r.starts_with(' '))
            })
            .unwrap_or_else(|| panic!("--{flag} in the help:\n{s}"))
    };
    for everyday in ["max-splats", "variants", "memory-limit", "quiet"] {
        for sharded in ["plan", "parts", "part", "samples"] {
            assert!(at(everyday) < at(sharded), "--{everyday} after --{sharded}");
        }
    }
    assert!(s.contains("Sharded conversion"), "{s}");
}

#[cfg(unix)]
#[test]
fn interrupted_conversion_leaves_nothing_behind() {
    let tmp = tempfile::tempdir().unwrap();
    let ply = tmp.path().join("big.ply");
    write_ply_file(&ply, &random_splats(400_000, 3, 50.0, 9));
    let out = tmp.path().join("out");
    let mut child = Command::new(bin())
        .arg("convert")
        .arg(&ply)
        .arg("-o")
        .arg(&out)
        .args(["--max-splats", "2000"])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // Wait until the staging folder exists, then interrupt.
    let start = std::time::Instant::now();
    let staging_seen = loop {
        let hidden = std::fs::read_dir(tmp.path())
            .unwrap()
            .flatten()
            .any(|e| e.file_name().to_string_lossy().starts_with(".out.s2t-tmp-"));
        if hidden || start.elapsed().as_secs() > 60 {
            break hidden;
        }
        if child.try_wait().unwrap().is_some() {
            break false;
        }
        std::thread::sleep(std::time::Duration::from_millis(2));
    };
    Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    let o = child.wait_with_output().unwrap();
    eprintln!("convert exit status after SIGINT: {:?}", o.status.code());
    let leftovers: Vec<_> = std::fs::read_dir(tmp.path())
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with('.'))
        .collect();
    assert!(
        leftovers.is_empty(),
        "temporary folders left: {leftovers:?}"
    );
    if o.status.success() {
        // Finished before the signal: the output must then be complete.
        assert!(!staging_seen || out.join("tileset.json").is_file());
        assert!(out.join("tileset.json").is_file());
    } else {
        assert_eq!(
            o.status.code(),
            Some(130),
            "{}",
            String::from_utf8_lossy(&o.stderr)
        );
        assert!(!out.exists(), "no partial output after an interrupt");
    }
}
