//! Bytes of a whole LOD output against splat-transform's Streamed SOG of the same scene, counted
//! both ways: every tile or chunk (LOD parents included) and the leaves only (the full-detail
//! splats, what a single SOG file holds), per input splat.
//!
//! Ours: `splat2tiles convert --variants all --no-utility` (the release binary), each variant's
//! content files summed over every tile and over the tiles without children; the output's other
//! files (tileset.json, subtrees) once, in "every tile". Each file counts as sent: the file or its gzip -6, the
//! smaller (SPZ and meshopt content gain from gzip; SOG's WebP does not). Theirs: the scene as a
//! PLY, decimated by `--decimate 50%` per level until a level would hold fewer than 8k splats
//! (SuperSplat halves per level; splat-transform's smallest chunk is 8k), then bundled as
//! `lod-meta.json` with `-l` tags (`-g cpu` throughout); LOD 0's chunks are the leaves.
//!
//! The codebook variant (spec/codebook-variant.md) is one more row: each tile's Best content
//! re-encoded with `write_codebook_glb`'s defaults.
//!
//! Run: `npm install --prefix target/st37 @playcanvas/splat-transform@3.7.0` once, then
//! `cargo run --release -p splat2tiles-lab --example lod_bytes` (it builds the release CLI;
//! `LOD_SCENES=plant` for one scene). Prints a Markdown table.

#[path = "../benches/common/mod.rs"]
mod common;
// Only its views and scores are used here.
#[allow(dead_code)]
#[path = "../benches/peer_views/mod.rs"]
mod peer_views;

use splat2tiles_core::camera::{DEFAULT_FOV_Y_DEG, auto_views_with};
use splat2tiles_core::splat::Splats;
use splat2tiles_io::{read_path, write_ply};
use splat2tiles_tiles::encode::codebook_glb::write_codebook_glb;
use splat2tiles_tiles::encode::spz2::gzip;
use std::collections::{BTreeMap, HashSet};
use std::path::{Path, PathBuf};
use std::process::Command;

fn root() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
}

/// Bytes sent for one file: the file or its gzip -6, the smaller.
fn sent(path: &Path) -> u64 {
    let b = std::fs::read(path).unwrap();
    b.len().min(gzip(&b).len()) as u64
}

/// Every file under `dir`.
fn files(dir: &Path) -> Vec<PathBuf> {
    let mut out = vec![];
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                out.push(p);
            }
        }
    }
    out.sort();
    out
}

/// Our output's sent bytes: per variant in `variants::ALL`'s order (name, every tile, leaves
/// only), the other files, and the splats of every tile.
fn ours(bin: &Path, scene: &Path, out: &Path) -> (Vec<(String, u64, u64)>, u64, u64) {
    let st = Command::new(bin)
        .arg("convert")
        .arg(scene)
        .arg("-o")
        .arg(out)
        .args(["--variants", "all", "--no-utility", "--quiet"])
        .status()
        .expect("the release splat2tiles");
    assert!(st.success(), "convert {}", scene.display());
    let ts = splat2tiles_tiles::tiling::load::load_tileset(&out.join("tileset.json")).unwrap();
    let parents: HashSet<_> = ts.tiles.iter().filter_map(|t| t.key.parent()).collect();
    let mut per: BTreeMap<usize, (u64, u64)> = BTreeMap::new();
    let mut counted = HashSet::new();
    for t in &ts.tiles {
        for (k, v) in splat2tiles_tiles::variants::ALL.into_iter().enumerate() {
            let p = ts.dir.join(splat2tiles_tiles::variants::content_uri(
                ts.scheme, t.key, v,
            ));
            if !p.exists() {
                continue;
            }
            let b = sent(&p);
            counted.insert(p);
            let e = per.entry(k).or_default();
            e.0 += b;
            if !parents.contains(&t.key) {
                e.1 += b;
            }
        }
    }
    // The codebook variant of each tile, from its lossless Best content (not yet a variant the
    // converter writes): one more row.
    let (mut cb_all, mut cb_leaves) = (0, 0);
    let (mut ref_leaves, mut cb_decoded): (Option<Splats>, Option<Splats>) = (None, None);
    for t in &ts.tiles {
        let best = ts.dir.join(splat2tiles_tiles::variants::content_uri(
            ts.scheme,
            t.key,
            splat2tiles_tiles::variants::Variant::Best,
        ));
        let Ok(glb) = std::fs::read(&best) else {
            continue;
        };
        let (rel, m) = splat2tiles_tiles::variants::decode_variant(&glb).unwrap();
        let (cb, dec) = write_codebook_glb(&rel, [0.0; 3], m, &Default::default()).unwrap();
        let b = cb.len().min(gzip(&cb).len()) as u64;
        cb_all += b;
        if !parents.contains(&t.key) {
            cb_leaves += b;
            append_placed(&mut ref_leaves, &rel, m);
            append_placed(&mut cb_decoded, &dec, m);
        }
    }
    per.insert(splat2tiles_tiles::variants::ALL.len(), (cb_all, cb_leaves));
    let (r, c) = (ref_leaves.unwrap(), cb_decoded.unwrap());
    let (lo, hi) = peer_views::core_box(&r);
    let cams = auto_views_with(lo, hi, glam::DVec3::Y, 1280, 720, DEFAULT_FOV_Y_DEG);
    let v = peer_views::view_scores(&peer_views::render_all(&r, &cams), &c, &cams);
    eprintln!(
        "{}: codebook leaves against Best leaves, 8 framed views: object PSNR {:.2} dB, crop SSIM {:.5}",
        scene.display(),
        v.object_psnr,
        v.crop_ssim
    );
    let other = files(out)
        .iter()
        .filter(|p| !counted.contains(*p))
        .map(|p| sent(p))
        .sum();
    let splats = splat2tiles_tiles::variants::content_variant_metadata(&ts)
        .values()
        .map(|m| m.0 as u64)
        .sum();
    let mut names: Vec<String> = splat2tiles_tiles::variants::ALL
        .iter()
        .map(|v| v.name().to_string())
        .collect();
    names.push("codebook (S2T, from Best)".into());
    let per = per
        .into_iter()
        .map(|(k, (a, l))| (names[k].clone(), a, l))
        .collect();
    (per, other, splats)
}

/// Appends `tile` (tile-relative) placed by its node matrix `m` (rotation and translation) to
/// `all`.
fn append_placed(all: &mut Option<Splats>, tile: &Splats, m: [f64; 16]) {
    let m = glam::DMat4::from_cols_array(&m);
    let r = glam::DQuat::from_mat3(&glam::DMat3::from_mat4(m));
    let mut t = tile.clone();
    for p in &mut t.positions {
        *p = m.transform_point3(glam::DVec3::from_array(*p)).to_array();
    }
    for q in &mut t.rotations {
        let qq = r * glam::DQuat::from_xyzw(q[0] as f64, q[1] as f64, q[2] as f64, q[3] as f64);
        *q = [qq.x as f32, qq.y as f32, qq.z as f32, qq.w as f32];
    }
    match all {
        Some(a) => (0..t.len()).for_each(|i| a.push_from(&t, i)),
        None => *all = Some(t),
    }
}

/// Runs splat-transform 3.7.0 with `args` on the CPU (no GPU here).
fn splat_transform(args: &[&str]) {
    let cli = root().join("target/st37/node_modules/@playcanvas/splat-transform/bin/cli.mjs");
    assert!(cli.exists(), "{}: see the run line", cli.display());
    let st = Command::new("node")
        .arg(&cli)
        .args(["-q", "-w", "-g", "cpu"])
        .args(args)
        .status()
        .unwrap();
    assert!(st.success(), "splat-transform {args:?}");
}

/// Streamed SOG's sent bytes: (every chunk and the index, LOD 0's chunks), and the levels' sizes.
fn theirs(ply: &Path, n: usize, dir: &Path) -> (u64, u64, Vec<usize>) {
    let mut levels = vec![ply.to_path_buf()];
    let mut counts = vec![n];
    while counts[counts.len() - 1] / 2 >= 8192 {
        let next = dir.join(format!("lod{}.ply", levels.len()));
        let prev = levels[levels.len() - 1].to_str().unwrap().to_string();
        splat_transform(&[&prev, "--decimate", "50%", next.to_str().unwrap()]);
        counts.push(read_path(&next).unwrap().splats.len());
        levels.push(next);
    }
    let out = dir.join("sog");
    std::fs::create_dir_all(&out).unwrap();
    let mut args: Vec<String> = vec![];
    for (k, l) in levels.iter().enumerate() {
        args.extend([l.to_str().unwrap().to_string(), "-l".into(), k.to_string()]);
    }
    args.push(out.join("lod-meta.json").to_str().unwrap().to_string());
    splat_transform(&args.iter().map(String::as_str).collect::<Vec<_>>());
    let meta: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("lod-meta.json")).unwrap()).unwrap();
    // LOD 0's chunks: the directories of the tree's leaves at lod 0, by the index's filenames.
    let names: Vec<String> = meta["filenames"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap().to_string())
        .collect();
    let lod0: HashSet<PathBuf> = lod0_files(&meta["tree"], &names)
        .into_iter()
        .map(|f| out.join(f).parent().unwrap().to_path_buf())
        .collect();
    let (mut all, mut leaves) = (0, 0);
    for f in files(&out) {
        let b = sent(&f);
        all += b;
        if f.parent().is_some_and(|d| lod0.contains(d)) {
            leaves += b;
        }
    }
    (all, leaves, counts)
}

/// The filenames the tree's nodes give for LOD 0 (`lods: {"0": {"file": index, ...}}`).
fn lod0_files(node: &serde_json::Value, names: &[String]) -> Vec<String> {
    let mut out = vec![];
    if let Some(f) = node["lods"]["0"]["file"].as_u64() {
        out.push(names[f as usize].clone());
    }
    for c in node["children"].as_array().into_iter().flatten() {
        out.extend(lod0_files(c, names));
    }
    out
}

fn main() {
    let only = std::env::var("LOD_SCENES").unwrap_or_default();
    let bin = common::release_binary();
    println!(
        "| scene | splats | ours: variant | every tile B/splat | leaves B/splat | our splats, all tiles / input | Streamed SOG every chunk B/splat | LOD 0 chunks B/splat | SOG splats, all levels / input |"
    );
    println!("|---|---:|---|---:|---:|---:|---:|---:|---:|");
    for f in ["plant.splat", "donut_fused_sh0.ply", "biker.spz"] {
        if !f.contains(&only) {
            continue;
        }
        let scene = root().join("data/scenes").join(f);
        let tmp = tempfile::tempdir().unwrap();
        let splats = read_path(&scene).unwrap().splats;
        let n = splats.len();
        let (per, other, our_splats) = ours(&bin, &scene, &tmp.path().join("ours"));
        let ply = tmp.path().join("scene.ply");
        write_ply(
            &splats,
            std::io::BufWriter::new(std::fs::File::create(&ply).unwrap()),
        )
        .unwrap();
        let (all, lod0, counts) = theirs(&ply, n, tmp.path());
        let b = |x: u64| x as f64 / n as f64;
        let sog_splats: usize = counts.iter().sum();
        for (v, every, leaves) in &per {
            println!(
                "| {f} | {n} | {v} | {:.2} | {:.2} | {:.3} | {:.2} | {:.2} | {:.3} ({} levels) |",
                b(every + other),
                b(*leaves),
                our_splats as f64 / n as f64,
                b(all),
                b(lod0),
                sog_splats as f64 / n as f64,
                counts.len()
            );
        }
    }
}
