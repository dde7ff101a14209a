//! The codebook variant's rate and distortion on the shared SH0 scenes, each as one tile: bytes
//! per splat and object PSNR / crop SSIM (the peers bench's 8 framed views) per encoder setting.
//!
//! Run: `cargo run --release -p splat2tiles-lab --example codebook_probe` (`PROBE_SCENES=biker`
//! for one scene; `PROBE_SWEEP=ablate` scores each attribute's quantization alone).

#[allow(dead_code)]
#[path = "../benches/peer_views/mod.rs"]
mod peer_views;

use peer_views::{framed, render_all, view_scores};
use splat2tiles_core::frame::UpAxis;
use splat2tiles_core::splat::Splats;
use splat2tiles_io::read_path;
use splat2tiles_tiles::encode::codebook::{
    CodebookOptions, Levels, decode_payload, encode_payload, section_sizes,
};
use splat2tiles_tiles::encode::spz2::gzip;
use splat2tiles_tiles::encode::tile::IDENTITY;
use splat2tiles_tiles::variants::{Variant, decode_variant};
use std::path::PathBuf;

/// Named encoder settings of the sweep.
fn settings(sweep: &str) -> Vec<(String, CodebookOptions)> {
    let d = CodebookOptions::default();
    let mut out = vec![("default".to_string(), d)];
    // PROBE_SWEEP=grid: "rot,divisor,scale levels,context" per setting, ';' between.
    if let Some(spec) = sweep.strip_prefix("grid:") {
        out.clear();
        for item in spec.split(';') {
            let v: Vec<f32> = item
                .split(',')
                .map(|x| x.parse().expect("numbers"))
                .collect();
            let o = CodebookOptions {
                rotation_bits: v[0] as u8,
                scale_divisor: v[1],
                // Above 4096: evenly spaced, (value - 4096) / 1000 of the median scale apart.
                scales: if v[2] > 4096.0 {
                    Levels::Relative((v[2] - 4096.0) / 1000.0)
                } else {
                    Levels::KMeans(v[2] as u16)
                },
                context_bits: v[3] as u8,
                linear_scales: v.get(4).is_some_and(|&x| x > 0.0),
                ..d
            };
            out.push((item.to_string(), o));
        }
    }
    out
}

/// `orig` (payload order) with attribute `which` taken from `dec`.
fn with_one(orig: &Splats, dec: &Splats, which: &str) -> Splats {
    let mut s = orig.clone();
    match which {
        "positions" => s.positions = dec.positions.clone(),
        "rotations" => s.rotations = dec.rotations.clone(),
        "scales" => s.scales = dec.scales.clone(),
        "colours" => s.sh0 = dec.sh0.clone(),
        "opacity" => s.opacities = dec.opacities.clone(),
        _ => unreachable!(),
    }
    s
}

fn main() {
    let root = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."));
    let only = std::env::var("PROBE_SCENES").unwrap_or_default();
    let sweep = std::env::var("PROBE_SWEEP").unwrap_or_default();
    println!("| scene | encoding | B/splat | object PSNR (dB) | crop SSIM |");
    println!("|---|---|---:|---:|---:|");
    for f in ["plant.splat", "donut_fused_sh0.ply", "biker.spz"] {
        if !f.contains(&only) {
            continue;
        }
        let sc = read_path(&root.join("data/scenes").join(f)).unwrap();
        let up: UpAxis = sc.format.default_up_axis().parse().unwrap();
        let (rel, cams) = framed(&sc.splats, up);
        let n = rel.len() as f64;
        let base = render_all(&rel, &cams);
        let row = |name: &str, bytes: usize, s: &Splats| {
            let v = view_scores(&base, s, &cams);
            println!(
                "| {f} | {name} | {:.2} | {:.2} | {:.5} |",
                bytes as f64 / n,
                v.object_psnr,
                v.crop_ssim
            );
        };
        let glb = Variant::Low.encode(&rel, [0.0; 3], IDENTITY).unwrap();
        row(
            "Low (SPZ v2)",
            glb.len().min(gzip(&glb).len()),
            &decode_variant(&glb).unwrap().0,
        );
        for (name, o) in settings(&sweep) {
            let t = std::time::Instant::now();
            let (p, order) = encode_payload(&rel, [0.0; 3], &o);
            let enc = t.elapsed().as_secs_f64();
            let t = std::time::Instant::now();
            let dec = decode_payload(&p).unwrap();
            let dt = t.elapsed().as_secs_f64();
            let parts: Vec<String> = section_sizes(&p)
                .unwrap()
                .iter()
                .map(|b| format!("{:.2}", *b as f64 / n))
                .collect();
            row(
                &format!(
                    "codebook {name} (enc {enc:.2} s, dec {dt:.3} s; B/splat {})",
                    parts.join("/")
                ),
                p.len(),
                &dec,
            );
            if std::env::var("PROBE_ABLATE").is_ok() {
                let orig = rel.select(&order);
                for w in ["positions", "rotations", "scales", "colours", "opacity"] {
                    row(
                        &format!("only {w} quantized"),
                        p.len(),
                        &with_one(&orig, &dec, w),
                    );
                }
            }
        }
    }
}
