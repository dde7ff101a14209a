//! Hostile-input regression tests for the validator and the readers the fuzz targets call: every
//! fuzz seed and every prefix of it must give a report or an error, never a panic. Crash inputs
//! found by fuzzing (RELIABILITY.md) are added to `fuzz/seeds/<target>/` and replayed here.

use splat2tiles_validate::{
    ValidateOptions, validate_glb_bytes, validate_subtree_bytes, validate_tileset_bytes,
};
use std::path::Path;

fn seeds(target: &str) -> Vec<(String, Vec<u8>)> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fuzz/seeds")
        .join(target);
    let mut out: Vec<(String, Vec<u8>)> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .flatten()
        .map(|e| {
            (
                e.file_name().to_string_lossy().into_owned(),
                std::fs::read(e.path()).unwrap(),
            )
        })
        .collect();
    out.sort();
    assert!(!out.is_empty(), "no seeds for {target}");
    out
}

/// Prefix lengths to try: all of them for small inputs, a spread for large ones.
fn cuts(len: usize) -> Vec<usize> {
    if len <= 1024 {
        (0..len).collect()
    } else {
        (0..len).step_by(len / 512).collect()
    }
}

#[test]
fn glb_seeds_and_prefixes_never_panic() {
    let opts = ValidateOptions::default();
    for (name, bytes) in seeds("glb") {
        let r = validate_glb_bytes(&bytes, &opts);
        assert_eq!(r.num_errors, 0, "{name}: {}", r.to_text(&name));
        for n in cuts(bytes.len()) {
            let _ = splat2tiles_tiles::encode::read_tile_glb(&bytes[..n]);
            let r = validate_glb_bytes(&bytes[..n], &opts);
            assert!(r.num_errors > 0, "{name}: prefix {n} accepted");
        }
    }
}

#[test]
fn subtree_seeds_and_prefixes_never_panic() {
    let opts = ValidateOptions::default();
    for (_, bytes) in seeds("subtree") {
        for n in cuts(bytes.len()).into_iter().chain([bytes.len()]) {
            let _ = splat2tiles_tiles::tiling::subtree::read_subtree(&bytes[..n]);
            for octree in [false, true] {
                for levels in 1..=4 {
                    let _ = validate_subtree_bytes(&bytes[..n], octree, levels, &opts);
                }
            }
        }
    }
}

/// The `tileset` fuzz target's input layout: tileset JSON, NUL, external tileset `e.json`, NUL,
/// content `c.bin`, written into `dir` and validated.
fn replay_tileset(dir: &Path, data: &[u8], opts: &ValidateOptions) {
    let mut parts = data.splitn(3, |b| *b == 0);
    let main = parts.next().unwrap_or_default();
    std::fs::write(dir.join("e.json"), parts.next().unwrap_or_default()).unwrap();
    std::fs::write(dir.join("c.bin"), parts.next().unwrap_or_default()).unwrap();
    let _ = validate_tileset_bytes(main, dir, opts);
}

#[test]
fn tileset_seeds_and_prefixes_never_panic() {
    let opts = ValidateOptions::default();
    let dir = tempfile::tempdir().unwrap();
    for (name, bytes) in seeds("tileset") {
        // Each seed's main tileset parses and is followed into its external tileset and content.
        let main = bytes.split(|b| *b == 0).next().unwrap();
        assert!(
            serde_json::from_slice::<serde_json::Value>(main).is_ok(),
            "{name}: the seed's tileset is not JSON"
        );
        for n in cuts(bytes.len()).into_iter().chain([bytes.len()]) {
            replay_tileset(dir.path(), &bytes[..n], &opts);
        }
    }
}

#[test]
fn scene_seeds_and_prefixes_never_panic() {
    for (target, ext) in [("ply", "ply"), ("spz", "spz"), ("splat", "splat")] {
        for (_, bytes) in seeds(target) {
            for n in cuts(bytes.len()).into_iter().chain([bytes.len()]) {
                let _ = splat2tiles_io::read_bytes(&format!("seed.{ext}"), &bytes[..n]);
            }
        }
    }
}

/// Crash inputs found by fuzzing (`fuzz/regressions/<target>/crash-*`, see RELIABILITY.md).
#[test]
fn fuzz_crash_regressions_replay_cleanly() {
    let opts = ValidateOptions::default();
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz/regressions");
    let mut n = 0;
    let scratch = tempfile::tempdir().unwrap();
    for target in ["ply", "spz", "splat", "glb", "subtree", "tileset"] {
        for e in std::fs::read_dir(dir.join(target))
            .into_iter()
            .flatten()
            .flatten()
        {
            let bytes = std::fs::read(e.path()).unwrap();
            n += 1;
            match target {
                "glb" => {
                    let _ = splat2tiles_tiles::encode::read_tile_glb(&bytes);
                    let _ = validate_glb_bytes(&bytes, &opts);
                }
                "subtree" => {
                    let _ = splat2tiles_tiles::tiling::subtree::read_subtree(&bytes);
                    let _ = validate_subtree_bytes(
                        &bytes,
                        bytes.first().is_some_and(|b| b & 1 == 1),
                        1 + u32::from(bytes.get(1).copied().unwrap_or(0) % 4),
                        &opts,
                    );
                }
                "tileset" => replay_tileset(scratch.path(), &bytes, &opts),
                ext => {
                    let _ = splat2tiles_io::read_bytes(&format!("crash.{ext}"), &bytes);
                }
            }
        }
    }
    assert!(
        n >= 1,
        "the glb crash of 2026-11-22 must stay in the corpus"
    );
}

/// The first fuzz crash: a SCALE accessor typed SCALAR (reported as ACCESSOR_TYPE_INVALID) was
/// then read as VEC3, past the end of its data (crates/validate/src/content.rs, fixed).
#[test]
fn r_fuzz_glb_wrongly_typed_attribute_is_reported_not_read() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fuzz/regressions/glb/crash-1cf7a1582a61af25fe3ba96b1504d834a505c333");
    let r = validate_glb_bytes(&std::fs::read(path).unwrap(), &ValidateOptions::default());
    assert!(r.num_errors > 0);
}

/// A fuzz crash of the `tileset` target: a legacy (b3dm/i3dm/pnts/cmpt) tile whose byteLength is
/// shorter than its header was cut to byteLength and then read at byte 12: index out of bounds
/// (crates/validate/src/legacy.rs; fixed: such a header is BINARY_INVALID_LENGTH, nothing more is read).
#[test]
fn r_fuzz_tileset_legacy_byte_length_below_header_is_reported_not_read() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fuzz/regressions/tileset/crash-971ee15f31cae682fa1f019f4199995c875812ff");
    let dir = tempfile::tempdir().unwrap();
    replay_tileset(
        dir.path(),
        &std::fs::read(path).unwrap(),
        &ValidateOptions::default(),
    );
}
