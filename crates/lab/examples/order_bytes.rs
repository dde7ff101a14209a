//! What splat order costs in bytes: High, Medium and Low of each shared SH0 scene encoded as one
//! tile in the file's order, in importance order (Best's, as `convert` stored every variant
//! before High, Medium and Low moved to Morton order), Morton order within importance blocks, and
//! Morton order (what the High, Medium and Low writers now store).
//!
//! Run: `cargo run --release --example order_bytes` (no renders: the same splats in another
//! order render the same; prints wire B/splat, the smaller of file and gzip -6).

use splat2tiles_core::splat::Splats;
use splat2tiles_core::splat::importance::importance_order;
use splat2tiles_io::read_path;
use splat2tiles_tiles::encode::meshopt::{HIGH, MEDIUM, write_meshopt_glb_as_given};
use splat2tiles_tiles::encode::spz2::{gzip, write_spz2_glb_as_given};
use splat2tiles_tiles::encode::storage_order::storage_order;
use splat2tiles_tiles::encode::tile::IDENTITY;
use splat2tiles_tiles::variants::{LOW_SPZ, relative};

/// Splat indices in importance order, each run of `block` of them in the writer's Morton order
/// (`encode::storage_order`).
fn morton_order(s: &Splats, block: usize) -> Vec<usize> {
    let mut out = vec![];
    for chunk in importance_order(s).chunks(block) {
        let rel: Vec<[f32; 3]> = chunk
            .iter()
            .map(|&i| s.positions[i].map(|v| v as f32))
            .collect();
        out.extend(storage_order(&rel).into_iter().map(|j| chunk[j]));
    }
    out
}

fn main() {
    let dir =
        std::path::PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../..")).join("data/scenes");
    println!("| scene | order | High | Medium | Low |");
    println!("|---|---|---:|---:|---:|");
    for f in ["plant.splat", "donut_fused_sh0.ply", "biker.spz"] {
        let sc = read_path(&dir.join(f)).unwrap();
        let (lo, hi) = sc.splats.bounds().unwrap();
        let centre = [0, 1, 2].map(|a| (lo[a] + hi[a]) * 0.5);
        let rel = relative(&sc.splats, centre);
        let n = rel.len();
        let orders: Vec<(String, Vec<usize>)> = vec![
            ("file".into(), (0..n).collect()),
            ("importance".into(), importance_order(&rel)),
            ("Morton in blocks of 256".into(), morton_order(&rel, 256)),
            ("Morton in blocks of 4096".into(), morton_order(&rel, 4096)),
            ("Morton".into(), morton_order(&rel, n)),
        ];
        for (label, order) in orders {
            let s = rel.select(&order);
            let wire = |b: Vec<u8>| b.len().min(gzip(&b).len()) as f64 / n as f64;
            let h = wire(write_meshopt_glb_as_given(&s, [0.0; 3], IDENTITY, &HIGH).unwrap());
            let m = wire(write_meshopt_glb_as_given(&s, [0.0; 3], IDENTITY, &MEDIUM).unwrap());
            let l = wire(write_spz2_glb_as_given(&s, [0.0; 3], IDENTITY, &LOW_SPZ).unwrap());
            println!("| {f} | {label} | {h:.2} | {m:.2} | {l:.2} |");
        }
    }
}
