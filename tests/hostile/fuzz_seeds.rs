//! The seeds of the fuzz targets for the newer surfaces (`limited`, `http_head`, `output_marker`,
//! `plan`, `part`, `samples`, `loader`), and every prefix of them, through the same entry points:
//! errors, never panics.

use std::path::Path;

fn seeds(target: &str) -> Vec<Vec<u8>> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fuzz/seeds")
        .join(target);
    let v: Vec<Vec<u8>> = std::fs::read_dir(&dir)
        .unwrap()
        .flatten()
        .map(|e| std::fs::read(e.path()).unwrap())
        .collect();
    assert!(!v.is_empty(), "no seeds in {}", dir.display());
    v
}

/// Prefix lengths: all of the first 600 bytes, then 64 spread cuts.
fn cuts(len: usize) -> Vec<usize> {
    let mut c: Vec<usize> = (0..=len.min(600)).collect();
    c.extend((1..=64).map(|i| len * i / 64));
    c
}

#[test]
fn limited_seeds_and_prefixes_never_panic() {
    let tmp = tempfile::tempdir().unwrap();
    for seed in seeds("limited") {
        for n in cuts(seed.len()) {
            let [pick, lim, body @ ..] = &seed[..n] else {
                continue;
            };
            let name = ["fuzz.ply", "fuzz.splat", "fuzz.spz", "fuzz.bin"][(*pick & 3) as usize];
            let limit = 4096u64 << (*lim % 16);
            let _ = splat2tiles_io::read_bytes_limited(name, body, limit);
            let path = tmp.path().join(name);
            std::fs::write(&path, body).unwrap();
            let _ = splat2tiles_io::read_path_limited(&path, limit);
        }
    }
}

#[test]
fn http_head_seeds_and_prefixes_never_panic() {
    for seed in seeds("http_head") {
        for n in cuts(seed.len()) {
            let mut r = std::io::BufReader::with_capacity(7, &seed[..n]);
            while let Ok(h) = splat2tiles_serve::http::read_head(&mut r) {
                let _ = (h.keep_alive(), h.has_body());
            }
        }
    }
}

#[test]
fn marker_seeds_and_prefixes_decide_without_panicking() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    std::fs::create_dir_all(out.join("tiles")).unwrap();
    std::fs::write(out.join("tileset.json"), "{}").unwrap();
    for seed in seeds("output_marker") {
        for n in cuts(seed.len()) {
            std::fs::write(
                out.join(splat2tiles_build::output::marker::MARKER),
                &seed[..n],
            )
            .unwrap();
            let ok = splat2tiles_build::output::guard::check_target(&out).is_ok();
            // Only a complete marker listing both entries lets the folder be replaced.
            if ok {
                assert!(serde_json::from_slice::<serde_json::Value>(&seed[..n]).is_ok());
            }
        }
    }
}

/// A seed split at its first NUL byte (plan or tileset JSON, then the second file).
fn split_nul(seed: &[u8]) -> (&[u8], &[u8]) {
    match seed.iter().position(|b| *b == 0) {
        Some(i) => (&seed[..i], &seed[i + 1..]),
        None => (seed, &[]),
    }
}

#[test]
fn sharded_file_seeds_are_accepted_and_their_prefixes_refused_without_panicking() {
    use splat2tiles_build::convert::{check_part_bytes, check_plan_bytes, check_samples_bytes};
    for seed in seeds("plan") {
        check_plan_bytes(&seed).expect("the plan seed is a valid plan");
        for n in cuts(seed.len()).into_iter().filter(|&n| n < seed.len()) {
            assert!(
                check_plan_bytes(&seed[..n]).is_err(),
                "a {n}-byte prefix passed"
            );
        }
    }
    for (target, check) in [
        ("part", check_part_bytes as fn(&[u8], &[u8]) -> _),
        ("samples", check_samples_bytes),
    ] {
        for seed in seeds(target) {
            let (plan, file) = split_nul(&seed);
            check(plan, file).unwrap_or_else(|e| panic!("the {target} seed: {e}"));
            for n in cuts(file.len()).into_iter().filter(|&n| n < file.len()) {
                assert!(
                    check(plan, &file[..n]).is_err(),
                    "{target}: a {n}-byte prefix passed"
                );
            }
        }
    }
}

#[test]
fn loader_seeds_parse_and_their_prefixes_never_panic() {
    use splat2tiles_tiles::tiling::TileKey;
    use splat2tiles_tiles::tiling::load::{parse_subtree_tiles, parse_tileset_json};
    for seed in seeds("loader") {
        let (json, subtree) = split_nul(&seed);
        let root = parse_tileset_json(json).expect("the seed's tileset.json parses");
        let tiles = parse_subtree_tiles(&root, TileKey::ROOT, subtree).expect("its root subtree");
        assert!(!tiles.tiles.is_empty());
        for n in cuts(subtree.len()) {
            let _ = parse_subtree_tiles(&root, TileKey::ROOT, &subtree[..n]);
        }
        for n in cuts(json.len()) {
            let _ = parse_tileset_json(&json[..n]);
        }
    }
}
