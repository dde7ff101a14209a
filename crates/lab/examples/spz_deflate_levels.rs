//! Low's gzip stream: bytes against time of each deflate level on the Low (SPZ v2) payload of
//! the shared scenes and the peers bench's generated SH3 scene.
//!
//! Run: `cargo run --release --example spz_deflate_levels` (about 1 min). Each scene is one tile
//! as the peers bench encodes it (`variants::LOW_SPZ`); prints B/splat of the gzip member and the
//! fastest of 3 runs in ms, for flate2 (zlib-rs) at levels 6 and 9 and libdeflate at 1-12.
//! `LEVELS_PLY=target/tmp-big/variants_speed/generated_1000000_sh3.ply` adds one tile of that
//! scene (the `variants_speed` bench's input, kept by `VARIANTS_SPEED_KEEP=1`): its splats with x
//! and z in the lowest tenth of their range.

#[path = "../benches/common/mod.rs"]
mod common;
// Only its `core_box` is used here.
#[allow(dead_code)]
#[path = "../benches/peer_views/mod.rs"]
mod peer_views;

use std::io::{Read, Write};

use libdeflater::{CompressionLvl, Compressor};
use peer_views::core_box;
use splat2tiles_io::read_path;
use splat2tiles_tiles::encode::spz2::{spz2_payload, write_spz2_glb};
use splat2tiles_tiles::encode::tile::IDENTITY;
use splat2tiles_tiles::variants::{LOW_SPZ, relative};

/// Fastest of three runs of `f`, in ms, and its output length.
fn timed(mut f: impl FnMut() -> usize) -> (usize, f64) {
    let mut best = f64::INFINITY;
    let mut len = 0;
    for _ in 0..3 {
        let t = std::time::Instant::now();
        len = f();
        best = best.min(t.elapsed().as_secs_f64() * 1e3);
    }
    (len, best)
}

fn main() {
    let dir =
        std::path::PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../..")).join("data/scenes");
    println!("| scene | coder | level | B/splat | ms |");
    println!("|---|---|---:|---:|---:|");
    let extra = std::env::var("LEVELS_PLY").ok();
    let mut files = vec!["plant.splat", "donut_fused_sh0.ply", "biker.spz", "sh3"];
    files.extend(extra.as_deref());
    for f in files {
        let splats = if extra.as_deref() == Some(f) {
            let all = read_path(std::path::Path::new(f)).unwrap().splats;
            let (lo, hi) = all.bounds().unwrap();
            let corner = |p: &[f64; 3]| {
                [0, 2]
                    .iter()
                    .all(|&a| p[a] <= lo[a] + 0.1 * (hi[a] - lo[a]))
            };
            let keep: Vec<usize> = (0..all.len())
                .filter(|&i| corner(&all.positions[i]))
                .collect();
            all.select(&keep)
        } else if f == "sh3" {
            common::peers_sh3(&read_path(&dir.join("plant.splat")).unwrap().splats)
        } else {
            read_path(&dir.join(f)).unwrap().splats
        };
        let (lo, hi) = core_box(&splats);
        let rel = relative(&splats, ((lo + hi) * 0.5).to_array());
        // The payload exactly as the Low tile stores it (storage order, the tile's position
        // step), inflated back from the tile.
        let glb = write_spz2_glb(&rel, [0.0; 3], IDENTITY, &LOW_SPZ).unwrap();
        let payload = spz2_payload(&glb).unwrap().expect("an SPZ_2 tile");
        let mut raw = vec![];
        flate2::read::GzDecoder::new(&payload[..])
            .read_to_end(&mut raw)
            .unwrap();
        let n = rel.len() as f64;
        for level in [6, 9] {
            let (len, ms) = timed(|| {
                let mut e =
                    flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::new(level));
                e.write_all(&raw).unwrap();
                e.finish().unwrap().len()
            });
            println!(
                "| {f} | flate2 (zlib-rs) | {level} | {:.3} | {ms:.0} |",
                len as f64 / n
            );
        }
        for level in 1..=12 {
            let mut c = Compressor::new(CompressionLvl::new(level).unwrap());
            let mut out = vec![0u8; c.gzip_compress_bound(raw.len())];
            let (len, ms) = timed(|| c.gzip_compress(&raw, &mut out).unwrap());
            println!(
                "| {f} | libdeflate | {level} | {:.3} | {ms:.0} |",
                len as f64 / n
            );
        }
    }
}
