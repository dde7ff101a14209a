//! High bit-depth candidates against TileSplat Table 6 Best on the three SH0 scenes, with the
//! peers bench's views, renders and SSIM (`benches/peers.rs`; issue 16, item 4).
//!
//! Run: `PROBE_CANDS="21,12,11,12,11;18,12,10,12,11" cargo run --release --example
//! high_bits_probe` (each candidate: position, rotation, scale, opacity, SH0 bits; the rest as
//! `HIGH`); `PROBE_SCENES=donut` runs one scene; `PROBE_LOW="18,16,15"` adds Low (SPZ v2 as
//! `variants::LOW_SPZ` with a fixed step) at each number of position bits, then `LOW_SPZ` itself. Prints wire B/splat (file or gzip -6,
//! the smaller) and the mean SSIM framed / at 4x zoom, to 5 and to 12 decimals.

#[path = "../benches/peer_views/mod.rs"]
mod peer_views;

use glam::DVec3;
use peer_views::{ZOOMS, core_box, mean_ssim, render_all, zoomed};
use splat2tiles::encode::meshopt::{HIGH, MeshoptLevel, write_meshopt_glb};
use splat2tiles::encode::spz2::{SpzOptions, gzip, write_spz2_glb};
use splat2tiles::encode::table6;
use splat2tiles::encode::tile::IDENTITY;
use splat2tiles::frame::UpAxis;
use splat2tiles::io::read_path;
use splat2tiles::render::camera::{DEFAULT_FOV_Y_DEG, auto_views_with};
use splat2tiles::render::{Camera, Image};
use splat2tiles::splat::Splats;
use splat2tiles::variants::{LOW_SPZ, decode_variant, relative};

fn main() {
    let dir = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/scenes");
    let only = std::env::var("PROBE_SCENES").unwrap_or_default();
    let cands: Vec<Vec<i32>> = std::env::var("PROBE_CANDS")
        .unwrap_or("18,12,11,12,12".into())
        .split(';')
        .filter(|c| !c.is_empty())
        .map(|c| c.split(',').map(|x| x.parse().unwrap()).collect())
        .collect();
    let lows: Vec<u8> = std::env::var("PROBE_LOW")
        .unwrap_or_default()
        .split(',')
        .filter(|x| !x.is_empty())
        .map(|x| x.parse().unwrap())
        .collect();
    for f in ["donut_fused_sh0.ply", "plant.splat", "biker.spz"] {
        if !only.is_empty() && !f.contains(&only) {
            continue;
        }
        let t0 = std::time::Instant::now();
        let sc = read_path(&dir.join(f)).unwrap();
        let up: UpAxis = sc.format.default_up_axis().parse().unwrap();
        let splats = sc.splats;
        let (lo, hi) = core_box(&splats);
        let centre = ((lo + hi) * 0.5).to_array();
        let rel = relative(&splats, centre);
        let n = rel.len() as f64;
        let up_s = up.to_z_up().transpose() * DVec3::Z;
        let (rlo, rhi) = core_box(&rel);
        let views = auto_views_with(rlo, rhi, up_s, 1280, 720, DEFAULT_FOV_Y_DEG);
        let cams: Vec<Vec<Camera>> = ZOOMS.iter().map(|&z| zoomed(&views, z)).collect();
        let base: Vec<Vec<Image>> = cams.iter().map(|c| render_all(&rel, c)).collect();
        let report = |label: &str, file: &[u8], dec: &Splats| {
            let wire = file.len().min(gzip(file).len()) as f64 / n;
            let s = [0, 1].map(|k| mean_ssim(&base[k], dec, &cams[k]));
            println!(
                "{f} | {label} | {wire:.2} | {:.5} | {:.5} | raw {:.12} {:.12}",
                s[0], s[1], s[0], s[1]
            );
        };
        let bits = table6::LEVELS.iter().find(|(l, _)| *l == "best").unwrap().1;
        let enc = table6::encode(&rel, &bits);
        report("table6 best", &enc, &table6::decode(&enc).unwrap());
        let mut levels: Vec<(String, MeshoptLevel)> = vec![("high (current)".into(), HIGH)];
        for v in &cands {
            let l = MeshoptLevel {
                position_bits: v[0],
                rotation_bits: v[1],
                scale_bits: v[2],
                opacity_bits: v[3],
                sh0_bits: v[4],
                ..HIGH
            };
            levels.push((
                format!(
                    "pos {} rot {} scale {} opac {} sh0 {}",
                    v[0], v[1], v[2], v[3], v[4]
                ),
                l,
            ));
        }
        for (label, l) in levels {
            let glb = write_meshopt_glb(&rel, [0.0; 3], IDENTITY, &l).unwrap();
            let (dec, _) = decode_variant(&glb).unwrap();
            report(&label, &glb, &dec);
        }
        for &bits in &lows {
            let opts = SpzOptions {
                position_bits: bits,
                scale_divisor: 0,
                ..LOW_SPZ
            };
            let glb = write_spz2_glb(&rel, [0.0; 3], IDENTITY, &opts).unwrap();
            let (dec, _) = decode_variant(&glb).unwrap();
            report(&format!("low, position {bits} bits"), &glb, &dec);
        }
        if !lows.is_empty() {
            let max_abs = rel
                .positions
                .iter()
                .flatten()
                .fold(0.0f64, |m, v| m.max(v.abs()));
            let fb = splat2tiles::encode::spz2::spz_fractional_bits(&rel, max_abs, &LOW_SPZ);
            let glb = write_spz2_glb(&rel, [0.0; 3], IDENTITY, &LOW_SPZ).unwrap();
            let (dec, _) = decode_variant(&glb).unwrap();
            report(&format!("low (LOW_SPZ: {fb} fractional bits)"), &glb, &dec);
        }
        eprintln!("{f}: {:.0} s", t0.elapsed().as_secs_f64());
    }
}
