//! The seeds of the fuzz targets for the newer surfaces (`limited`, `http_head`, `output_marker`),
//! and every prefix of them, through the same entry points: errors, never panics.

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
