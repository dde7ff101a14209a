//! Candidates for a rung below Low (a 4-6 B/splat variant with visible but graceful loss): each
//! shared SH0 scene as one tile, encoded as Low (SPZ v2 in glb) whole, on an importance prefix of
//! its splats, or on the scene clustered to fewer splats as the LOD parents are (`lod::
//! cluster_to_target` with the drawn dilation); scored like the peers bench (8 framed views at
//! 1280x720 on grey: object PSNR pooled over the views, crop SSIM, whole-frame SSIM) against the
//! float scene, bytes as sent (the file or its gzip, the smaller) per input splat.
//!
//! Run: `cargo run --release -p splat2tiles-lab --example ladder_probe` (`LADDER_SCENES=biker`
//! for one scene; `LADDER_KEEP=0.5,0.3` the kept fractions). Prints a Markdown table.

#[allow(dead_code)]
#[path = "../benches/peer_views/mod.rs"]
mod peer_views;

use peer_views::{framed, render_all, view_scores};
use splat2tiles_build::lod::{DRAWN_DILATION_PER_RADIUS2, MergeRule, cluster_to_target};
use splat2tiles_core::frame::UpAxis;
use splat2tiles_core::splat::Splats;
use splat2tiles_core::splat::importance::importance_order;
use splat2tiles_io::read_path;
use splat2tiles_tiles::encode::spz2::gzip;
use splat2tiles_tiles::encode::tile::IDENTITY;
use splat2tiles_tiles::variants::{Variant, decode_variant};
use std::path::PathBuf;

/// Low's bytes as sent for `s` and what its decode scores against `base` from `cams`.
fn score(
    s: &Splats,
    base: &[splat2tiles_render::Image],
    cams: &[splat2tiles_render::Camera],
) -> (usize, peer_views::ViewScores) {
    let glb = Variant::Low.encode(s, [0.0; 3], IDENTITY).unwrap();
    let (dec, _) = decode_variant(&glb).unwrap();
    (
        glb.len().min(gzip(&glb).len()),
        view_scores(base, &dec, cams),
    )
}

fn main() {
    let root = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."));
    let only = std::env::var("LADDER_SCENES").unwrap_or_default();
    let keep: Vec<f64> = std::env::var("LADDER_KEEP")
        .unwrap_or_else(|_| "0.5,0.3,0.2".into())
        .split(',')
        .map(|v| v.parse().expect("LADDER_KEEP: fractions"))
        .collect();
    println!(
        "| scene | candidate | splats kept | B/splat (per input splat) | object PSNR (dB) | crop SSIM | whole-frame SSIM |"
    );
    println!("|---|---|---:|---:|---:|---:|---:|");
    for f in ["plant.splat", "donut_fused_sh0.ply", "biker.spz"] {
        if !f.contains(&only) {
            continue;
        }
        let sc = read_path(&root.join("data/scenes").join(f)).unwrap();
        let up: UpAxis = sc.format.default_up_axis().parse().unwrap();
        let (rel, cams) = framed(&sc.splats, up);
        let n = rel.len();
        let base = render_all(&rel, &cams);
        let tile = rel.select(&importance_order(&rel));
        let row = |name: String, s: &Splats| {
            let (bytes, v) = score(s, &base, &cams);
            println!(
                "| {f} | {name} | {:.2} | {:.2} | {:.2} | {:.5} | {:.5} |",
                s.len() as f64 / n as f64,
                bytes as f64 / n as f64,
                v.object_psnr,
                v.crop_ssim,
                v.ssim
            );
        };
        row("Low".into(), &tile);
        for &k in &keep {
            let m = ((n as f64 * k).round() as usize).max(1);
            let prefix: Vec<usize> = (0..m).collect();
            row(format!("Low, importance prefix {k}"), &tile.select(&prefix));
            let c = cluster_to_target(
                &rel,
                m,
                0.0,
                1e-3,
                m,
                MergeRule::default(),
                DRAWN_DILATION_PER_RADIUS2,
            );
            let order = importance_order(&c.splats);
            row(format!("Low, clustered to {k}"), &c.splats.select(&order));
        }
    }
}
