//! Helpers shared by the integration tests: where the shared scenes are, the CLI binary,
//! seeded generated scenes, and decoding a whole tileset back into splats.
#![allow(dead_code)]

pub mod city;
pub mod lapis;
pub mod objects;
pub mod scenes;
pub mod splat_file;

use glam::{DMat3, DMat4, DVec3};
use splat2tiles_core::splat::{Splat, Splats, sh_rest_count};
use splat2tiles_tiles::encode::read_tile_glb;
use splat2tiles_tiles::tiling::TileKey;
use splat2tiles_tiles::tiling::load::load_tileset;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// Every file under `dir`, relative path -> bytes (for byte-identity checks of whole outputs).
pub fn tree_files(dir: &Path) -> std::collections::BTreeMap<PathBuf, Vec<u8>> {
    let mut out = std::collections::BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                out.insert(
                    p.strip_prefix(dir).unwrap().to_path_buf(),
                    std::fs::read(&p).unwrap(),
                );
            }
        }
    }
    out
}

/// Asserts that `a` and `b` hold the same files with the same bytes.
pub fn assert_same_files(a: &Path, b: &Path) {
    let (fa, fb) = (tree_files(a), tree_files(b));
    assert_eq!(
        fa.keys().collect::<Vec<_>>(),
        fb.keys().collect::<Vec<_>>(),
        "same file names"
    );
    for (k, v) in &fa {
        assert!(v == &fb[k], "{} differs", k.display());
    }
}

/// Asserts that `validate --check-extent` finds no error and no warning in the tileset at `out`.
pub fn assert_valid_with_extents(out: &Path) {
    let o = std::process::Command::new(bin())
        .arg("validate")
        .arg(out.join("tileset.json"))
        .arg("--check-extent")
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success() && text.contains("(0 errors, 0 warnings"),
        "validate: {text}{}",
        String::from_utf8_lossy(&o.stderr)
    );
}

/// The repository's scenes (`data/scenes`, with their README and licences).
pub fn scenes() -> PathBuf {
    repo().join("data/scenes")
}

/// A shared scene by file name; panics with a clear message when the folder is missing.
pub fn scene(name: &str) -> PathBuf {
    let p = scenes().join(name);
    assert!(p.is_file(), "missing scene {} (data/scenes)", p.display());
    p
}

/// The repository's root (the `splat2tiles` package), from whichever package's tests run.
pub fn repo() -> PathBuf {
    let mut p = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    while !p.join("samples/plant.splat").is_file() && p.pop() {}
    p
}

/// The built `splat2tiles` binary (beside this test executable's folder when another package's
/// tests run: `cargo test --workspace` builds every binary).
pub fn bin() -> PathBuf {
    match option_env!("CARGO_BIN_EXE_splat2tiles") {
        Some(p) => PathBuf::from(p),
        None => sibling_bin("splat2tiles"),
    }
}

/// A workspace binary in the target folder of the running test executable (`target/P/deps/..`).
pub fn sibling_bin(name: &str) -> PathBuf {
    let exe = std::env::current_exe().expect("the test executable's path");
    let dir = exe.parent().and_then(Path::parent).expect("target/PROFILE");
    dir.join(format!("{name}{}", std::env::consts::EXE_SUFFIX))
}

/// A tiny deterministic generator (xorshift) for test scenes.
pub struct Rng(pub u64);

impl Rng {
    /// Uniform in [0, 1).
    pub fn f(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
    /// Uniform in [a, b).
    pub fn range(&mut self, a: f64, b: f64) -> f64 {
        a + (b - a) * self.f()
    }
}

/// `n` random splats of SH degree `deg` with non-zero higher SH, spread over a box of `size`.
pub fn random_splats(n: usize, deg: u8, size: f64, seed: u64) -> Splats {
    let mut r = Rng(seed.max(1));
    let mut s = Splats::with_capacity(deg, n);
    for _ in 0..n {
        let q = [
            r.range(-1.0, 1.0) as f32,
            r.range(-1.0, 1.0) as f32,
            r.range(-1.0, 1.0) as f32,
            r.range(-1.0, 1.0) as f32,
        ];
        let rot = splat2tiles_core::splat::normalize_quat(q);
        let splat = Splat {
            position: [
                r.range(0.0, size),
                r.range(0.0, size),
                r.range(0.0, size * 0.6),
            ],
            scale: [
                r.range(0.001, 0.05) as f32 * size as f32,
                r.range(0.001, 0.05) as f32 * size as f32,
                r.range(0.001, 0.05) as f32 * size as f32,
            ],
            rotation: rot,
            opacity: r.range(0.02, 0.99) as f32,
            sh0: [
                r.range(-1.5, 1.5) as f32,
                r.range(-1.5, 1.5) as f32,
                r.range(-1.5, 1.5) as f32,
            ],
        };
        let rest: Vec<[f32; 3]> = (0..sh_rest_count(deg))
            .map(|_| {
                [
                    r.range(-0.3, 0.3) as f32,
                    r.range(-0.3, 0.3) as f32,
                    r.range(-0.3, 0.3) as f32,
                ]
            })
            .collect();
        s.push(splat, &rest);
    }
    s
}

/// Writes `splats` as a trainer PLY file.
pub fn write_ply_file(path: &Path, splats: &Splats) {
    let f = std::fs::File::create(path).expect("create ply");
    splat2tiles_io::write_ply(splats, std::io::BufWriter::new(f)).expect("write ply");
}

/// A decoded content tile: splats with positions back in the source frame.
pub struct DecodedLeaf {
    /// Splats, positions in the source frame (tile centre added back).
    pub splats: Splats,
}

/// Decodes every content tile of a tileset, keyed by tile; positions are returned in the source
/// frame (`node matrix = R * [I | c_S]`, so `c_S = R^T t`).
pub fn decode_tileset(tileset: &Path) -> HashMap<TileKey, DecodedLeaf> {
    let ts = load_tileset(tileset).expect("load tileset");
    let mut out = HashMap::new();
    for t in ts.tiles.iter() {
        let Some(path) = &t.content else { continue };
        let bytes = std::fs::read(path).expect("read glb");
        let tile = read_tile_glb(&bytes).expect("decode glb");
        let m = DMat4::from_cols_array(&tile.node_matrix);
        let r = DMat3::from_mat4(m);
        let c = r.transpose() * m.w_axis.truncate();
        let mut splats = tile.splats;
        for p in splats.positions.iter_mut() {
            *p = (DVec3::from_array(*p) + c).to_array();
        }
        out.insert(t.key, DecodedLeaf { splats });
    }
    out
}

/// Decodes the leaf tiles only (tiles without children): with LOD parents holding merged splats,
/// the leaves are where every input splat lives.
pub fn decode_leaves(tileset: &Path) -> HashMap<TileKey, DecodedLeaf> {
    let ts = load_tileset(tileset).expect("load tileset");
    let parents: std::collections::HashSet<TileKey> =
        ts.tiles.iter().filter_map(|t| t.key.parent()).collect();
    let mut all = decode_tileset(tileset);
    all.retain(|k, _| !parents.contains(k));
    all
}

/// Every file under `dir` (recursively) whose extension is `ext`, sorted; empty if `dir` is missing.
pub fn files_under(dir: &Path, ext: &str) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).into_iter().flatten().flatten() {
            let p = e.path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|x| x == ext) {
                out.push(p);
            }
        }
    }
    out.sort();
    out
}

/// The node harness folder (`tests/js`: Khronos glTF-Validator, splat-transform).
pub fn js_dir() -> PathBuf {
    repo().join("tests/js")
}

/// Fails (never skips) when the node harness is not installed.
pub fn require_node_modules() {
    let nm = js_dir().join("node_modules");
    assert!(
        nm.join("gltf-validator").is_dir() && nm.join("@playcanvas/splat-transform").is_dir(),
        "tests/js/node_modules is missing: run `npm ci --prefix tests/js` (the .ci/run script does)"
    );
}

/// Fails (never skips) when there is no Chromium for the browser tests (`$CHROMIUM` or Debian's).
pub fn require_chromium() {
    let chromium = std::env::var_os("CHROMIUM")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("/usr/bin/chromium"));
    assert!(
        chromium.is_file(),
        "no Chromium at {} (apt-get install chromium, or set CHROMIUM)",
        chromium.display()
    );
}

/// The plant with small random SH degree 1-3 coefficients (|c| <= 0.08): the generated SH3 scene.
pub fn plant_sh3() -> splat2tiles_io::Scene {
    let mut sc = splat2tiles_io::read_path(&scene("plant.splat")).unwrap();
    let mut r = Rng(99);
    sc.splats.sh_degree = 3;
    sc.splats.sh_rest = (0..sc.splats.len() * 15)
        .map(|_| [0, 1, 2].map(|_| r.range(-0.08, 0.08) as f32))
        .collect();
    sc
}

/// Ranks (1-based, ties averaged).
pub fn ranks(v: &[f64]) -> Vec<f64> {
    let mut idx: Vec<usize> = (0..v.len()).collect();
    idx.sort_by(|&a, &b| v[a].total_cmp(&v[b]));
    let mut out = vec![0.0; v.len()];
    let mut i = 0;
    while i < idx.len() {
        let mut j = i;
        while j + 1 < idx.len() && v[idx[j + 1]] == v[idx[i]] {
            j += 1;
        }
        for k in i..=j {
            out[idx[k]] = (i + j) as f64 / 2.0 + 1.0;
        }
        i = j + 1;
    }
    out
}

/// Spearman rank correlation (Pearson correlation of the ranks).
pub fn spearman(a: &[f64], b: &[f64]) -> f64 {
    let (ra, rb) = (ranks(a), ranks(b));
    let n = ra.len() as f64;
    let (ma, mb) = (ra.iter().sum::<f64>() / n, rb.iter().sum::<f64>() / n);
    let cov: f64 = ra.iter().zip(&rb).map(|(x, y)| (x - ma) * (y - mb)).sum();
    let va: f64 = ra.iter().map(|x| (x - ma).powi(2)).sum();
    let vb: f64 = rb.iter().map(|y| (y - mb).powi(2)).sum();
    cov / (va * vb).sqrt()
}

/// The level rule (spec/georeferencing.md "Levels"): every tile without content is a
/// pass-through, below the root with a single child and its parent's bounding box and geometric
/// error, so a REPLACE traversal never stops at it; errors never grow downwards. Returns the
/// number of pass-throughs.
pub fn assert_levels_complete(ts: &splat2tiles_tiles::tiling::load::LoadedTileset) -> usize {
    let by_key: HashMap<TileKey, &splat2tiles_tiles::tiling::load::LoadedTile> =
        ts.tiles.iter().map(|t| (t.key, t)).collect();
    let children = splat2tiles_tiles::tiling::levels::child_counts(ts.tiles.iter().map(|t| &t.key));
    let mut passes = 0;
    for t in &ts.tiles {
        if let Some(p) = t.key.parent().map(|p| by_key[&p]) {
            assert!(
                t.geometric_error <= p.geometric_error,
                "{:?} error {} above its parent's {}",
                t.key,
                t.geometric_error,
                p.geometric_error
            );
        }
        if t.content.is_some() {
            continue;
        }
        let p = t.key.parent().map(|p| by_key[&p]);
        let p = p.unwrap_or_else(|| panic!("the root {:?} has no content", t.key));
        assert_eq!(
            children.get(&t.key),
            Some(&1),
            "{:?} has no content and not exactly one child",
            t.key
        );
        assert_eq!(
            t.bounding_box, p.bounding_box,
            "pass-through {:?} box",
            t.key
        );
        assert_eq!(
            t.geometric_error, p.geometric_error,
            "pass-through {:?} error",
            t.key
        );
        passes += 1;
    }
    passes
}

/// The repository's sample scene (`samples/plant.splat`, CC-BY-4.0), every `step`-th splat,
/// normalised for generated cities (z up, ground at 0, horizontal size 1).
pub fn plant_sample(step: usize) -> Splats {
    let path = repo().join("samples/plant.splat");
    let scene = splat2tiles_io::read_path(&path).unwrap();
    let order: Vec<usize> = (0..scene.splats.len()).step_by(step).collect();
    splat2tiles_lab::city::normalise_source(
        &scene.splats.select(&order),
        splat2tiles_core::frame::UpAxis::NegY,
    )
}

/// Runs `splat2tiles convert INPUT -o OUT -q EXTRA...` and requires success (stderr in the panic).
pub fn convert_file(input: &Path, out: &Path, extra: &[&str]) {
    let o = std::process::Command::new(bin())
        .arg("convert")
        .arg(input)
        .arg("-o")
        .arg(out)
        .arg("-q")
        .args(extra)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// The "look at it:" hint in `convert`'s summary (`stdout`): the whole hint and the words of the
/// render command it suggests (`PROGRAM render TILESET --auto-view 0 -o view.png`).
pub fn convert_hint(stdout: &str) -> (String, Vec<String>) {
    let hint = stdout
        .lines()
        .find_map(|l| l.trim().strip_prefix("look at it: "))
        .unwrap_or_else(|| panic!("no hint in {stdout}"));
    let render = hint
        .split("(or: ")
        .nth(1)
        .unwrap_or_else(|| panic!("no render command in the hint {hint}"))
        .trim_end_matches(')');
    let words = render.split_whitespace().map(str::to_string).collect();
    (hint.to_string(), words)
}
