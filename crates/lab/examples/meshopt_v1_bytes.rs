//! What KHR_meshopt_compression's vertex codec version 1 would save on High and Medium: each
//! scene as one tile (as the peers bench encodes it), every `EXT_meshopt_compression` stream
//! decoded to its filtered bytes and encoded again at version 1 (not adopted).
//!
//! Run: `cargo run --release --example meshopt_v1_bytes` (under a minute). Prints B/splat of the
//! tile's JSON and binary chunk, as stored and gzipped (`gzip -6`), at version 0 (what we write)
//! and at version 1, levels 2 (upstream's default) and 3.

#[path = "../benches/common/mod.rs"]
mod common;
// Only its `core_box` is used here.
#[allow(dead_code)]
#[path = "../benches/peer_views/mod.rs"]
mod peer_views;

use meshoptimizer_rs::codec::{VertexEncoding, decode_vertex_buffer, encode_vertex_buffer};
use meshoptimizer_rs::{Limits, Workspace};
use peer_views::core_box;
use splat2tiles_build::variants::relative;
use splat2tiles_io::read_path;
use splat2tiles_tiles::encode::glb::read_glb;
use splat2tiles_tiles::encode::meshopt::{HIGH, MEDIUM, write_meshopt_glb};
use splat2tiles_tiles::encode::spz2::gzip;
use splat2tiles_tiles::encode::tile::IDENTITY;

/// The tile's JSON and binary chunk with each compressed stream re-encoded at `version`/`level`
/// (version 0: as written).
fn rewritten(glb: &[u8], version: u8, level: u8) -> Vec<u8> {
    let chunks = read_glb(glb).unwrap();
    let json: serde_json::Value = serde_json::from_slice(chunks.json).unwrap();
    let bin = chunks.bin.unwrap();
    let mut out = chunks.json.to_vec();
    let mut ws = Workspace::new(Limits::default());
    for view in json["bufferViews"].as_array().unwrap() {
        let Some(ext) = view["extensions"].get("EXT_meshopt_compression") else {
            continue;
        };
        let at = ext["byteOffset"].as_u64().unwrap_or(0) as usize;
        let src = &bin[at..at + ext["byteLength"].as_u64().unwrap() as usize];
        if version == 0 {
            out.extend_from_slice(src);
            continue;
        }
        let (count, stride) = (
            ext["count"].as_u64().unwrap() as usize,
            ext["byteStride"].as_u64().unwrap() as usize,
        );
        let filtered = decode_vertex_buffer(count, stride, src, &mut ws).unwrap();
        let encoding = VertexEncoding::new(version, level).unwrap();
        out.extend(encode_vertex_buffer(&filtered, count, stride, encoding, &mut ws).unwrap());
    }
    out
}

fn main() {
    let dir =
        std::path::PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../..")).join("data/scenes");
    println!("| scene | variant | v0 (as written) | v1 level 2 | v1 level 3 |");
    println!("|---|---|---|---|---|");
    for f in ["plant.splat", "donut_fused_sh0.ply", "biker.spz", "sh3"] {
        let splats = if f == "sh3" {
            common::peers_sh3(&read_path(&dir.join("plant.splat")).unwrap().splats)
        } else {
            read_path(&dir.join(f)).unwrap().splats
        };
        let (lo, hi) = core_box(&splats);
        let rel = relative(&splats, ((lo + hi) * 0.5).to_array());
        let n = rel.len() as f64;
        for (name, level) in [("high", HIGH), ("medium", MEDIUM)] {
            let glb = write_meshopt_glb(&rel, [0.0; 3], IDENTITY, &level).unwrap();
            let cell = |v: u8, l: u8| {
                let b = rewritten(&glb, v, l);
                format!(
                    "{:.2} / {:.2}",
                    b.len() as f64 / n,
                    gzip(&b).len() as f64 / n
                )
            };
            println!(
                "| {f} | {name} | {} | {} | {} |",
                cell(0, 0),
                cell(1, 2),
                cell(1, 3)
            );
        }
    }
}
