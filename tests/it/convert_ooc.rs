//! The out-of-core converter: a scene converted through spill files under a tiny memory limit is
//! byte-identical (every file) to its in-memory conversion, whatever the thread count, and valid.

use crate::common::city::write_city_splat;
use crate::common::*;
use splat2tiles_build::convert::{ConvertOptions, convert};
use splat2tiles_core::splat::Splats;
use splat2tiles_tiles::tiling::TileKey;
use std::path::Path;
use std::process::Command;

fn convert_cli(input: &Path, out: &Path, extra: &[&str]) -> serde_json::Value {
    let o = Command::new(bin())
        .arg("convert")
        .arg(input)
        .arg("-o")
        .arg(out)
        .args(["--no-utility", "--json"])
        .args(extra)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    serde_json::from_slice(&o.stdout).unwrap()
}

/// Tile boxes enclose every splat's 3-sigma ellipsoid, leaves and LOD parents alike:
/// `validate --check-extent` warns about nothing on the shared scenes (data/scenes/README.md),
/// local and georeferenced (before, plant.splat alone gave 9 extent warnings).
#[test]
fn shared_scenes_have_no_extent_warnings() {
    let tmp = tempfile::tempdir().unwrap();
    for (name, extra) in [
        ("plant.splat", &[][..]),
        ("donut_fused_sh0.ply", &["--max-splats", "4096"][..]),
        ("biker.spz", &["--max-splats", "8192"][..]),
        ("plant.splat", &["--origin", "7.44,46.95,550"][..]),
    ] {
        let out = tmp
            .path()
            .join(format!("{}{}", name.replace('.', "_"), extra.len()));
        convert_cli(&scene(name), &out, extra);
        assert_valid_with_extents(&out);
    }
}

/// 2M splats through spill files at 64 MiB give exactly the in-memory output, and it validates.
#[test]
fn two_million_splats_under_64_mib_match_the_in_memory_output() {
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("city.splat");
    write_city_splat(&input, 2_000_000, 15);
    let mem = tmp.path().join("mem");
    let ooc = tmp.path().join("ooc");
    let a = convert_cli(&input, &mem, &[]);
    let b = convert_cli(&input, &ooc, &["--memory-limit", "64MiB"]);
    assert_eq!(
        a["regions"], 1,
        "the default limit holds 2M splats in memory"
    );
    assert_eq!(a["spillBytes"], 0);
    assert!(b["regions"].as_u64().unwrap() > 8, "{b}");
    // Spill files hold the input's own 32-byte records and an 8-byte index (not 76 bytes).
    assert!(b["spillBytes"].as_u64().unwrap() >= 2_000_000 * 40, "{b}");
    assert!(b["spillBytes"].as_u64().unwrap() < 2_000_000 * 76, "{b}");
    assert_eq!(a["splatsOut"], 2_000_000);
    assert_same_files(&mem, &ooc);
    assert_valid_with_extents(&ooc);
    // No spill file or staging folder is left beside or inside the output.
    let names: Vec<_> = std::fs::read_dir(tmp.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(names.len(), 3, "{names:?}");
    assert!(!ooc.join(".spill").exists());
}

fn convert_lib(input: &Path, out: &Path, threads: usize, limit: u64) -> Vec<(TileKey, Vec<usize>)> {
    let opts = ConvertOptions {
        max_splats_per_tile: 1024,
        memory_limit: limit,
        keep_index_map: true,
        variants: splat2tiles_tiles::variants::VariantOptions {
            measure_utility: false,
            ..Default::default()
        },
        ..Default::default()
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    let r = pool.install(|| convert(input, out, &opts)).unwrap();
    assert!(r.parent_splats > 0);
    r.leaves
}

/// Thread count and memory limit (one region in memory, or many spilled) change no byte, nor
/// the index map.
#[test]
fn threads_and_limits_give_identical_bytes() {
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("scene.ply");
    let mut s: Splats = random_splats(40_000, 1, 30.0, 3);
    // Dense clumps so some regions hold several levels and some are single leaves.
    s.positions
        .iter_mut()
        .step_by(3)
        .for_each(|p| *p = [p[0] * 0.05, p[1] * 0.05, p[2] * 0.05]);
    write_ply_file(&input, &s);
    let base = tmp.path().join("base");
    let map = convert_lib(&input, &base, 2, 4 << 30);
    for (threads, limit) in [(1, 4 << 30), (1, 1 << 20), (2, 1 << 20), (2, 48 << 20)] {
        let out = tmp.path().join(format!("t{threads}-{limit}"));
        assert_eq!(convert_lib(&input, &out, threads, limit), map);
        assert_same_files(&base, &out);
    }
    assert_valid_with_extents(&base);
}

/// `--non-finite fail` names the first bad splat's byte offset when it lies in a later chunk of
/// a chunked read; `drop` drops it and converts the rest.
#[test]
fn a_non_finite_splat_deep_in_a_chunked_file_is_named_by_its_offset() {
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("nan.splat");
    write_city_splat(&input, 100_000, 4);
    let mut bytes = std::fs::read(&input).unwrap();
    bytes[32 * 99_000 + 4..32 * 99_000 + 8].copy_from_slice(&f32::NAN.to_le_bytes());
    std::fs::write(&input, &bytes).unwrap();
    let out = tmp.path().join("out");
    let o = Command::new(bin())
        .arg("convert")
        .arg(&input)
        .arg("-o")
        .arg(&out)
        .args(["--non-finite", "fail", "--memory-limit", "1MiB"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains(&format!("byte {}: splat 99000", 32 * 99_000)),
        "{err}"
    );
    assert!(!out.exists());
    let r = convert_cli(
        &input,
        &out,
        &["--memory-limit", "1MiB", "--max-splats", "4096"],
    );
    assert_eq!(r["droppedNonFinite"], 1);
    assert_eq!(r["splatsOut"], 99_999);
}

/// Splats with NaN scattered through a spilled `.splat` file: the routing passes (which then
/// decode whole chunks to find the finite splats and spill their raw records) give the same
/// files and index map as the in-memory conversion.
#[test]
fn non_finite_splats_spilled_as_raw_records_match_the_in_memory_output() {
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("holes.splat");
    write_city_splat(&input, 200_000, 9);
    let mut bytes = std::fs::read(&input).unwrap();
    for i in (17..200_000).step_by(997) {
        bytes[32 * i + 8..32 * i + 12].copy_from_slice(&f32::NAN.to_le_bytes());
    }
    std::fs::write(&input, &bytes).unwrap();
    let base = tmp.path().join("base");
    let map = convert_lib(&input, &base, 2, 4 << 30);
    let out = tmp.path().join("spilled");
    assert_eq!(convert_lib(&input, &out, 2, 1 << 20), map);
    assert_same_files(&base, &out);
    let kept: usize = map.iter().map(|(_, v)| v.len()).sum();
    assert_eq!(kept, 200_000 - (17..200_000).step_by(997).count());
}
