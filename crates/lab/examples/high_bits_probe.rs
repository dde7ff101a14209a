//! High bit-depth candidates against TileSplat Table 6 Best on the three SH0 scenes, with the
//! peers bench's views, renders and SSIM (`benches/peers.rs`).
//!
//! Run: `PROBE_CANDS="21,12,11,12,11;18,12,10,12,11" cargo run --release --example
//! high_bits_probe` (each candidate: position, rotation, scale, opacity, SH0 bits; the rest as
//! `HIGH`); `PROBE_SCENES=donut` runs one scene; `PROBE_LOW="18,16,15"` adds Low (SPZ v2 as
//! `variants::LOW_SPZ` with a fixed step) at each number of position bits, then `LOW_SPZ` itself. Prints wire B/splat (file or gzip -6,
//! the smaller) and the mean SSIM framed / at 4x zoom, to 5 and to 12 decimals.
//! `PROBE_ROT=nearest` rounds Low's rotation bytes instead of fitting them to the covariance.
//! `PROBE_SH="high:c:8:3;medium:v:4:2"` adds the peers bench's generated SH3 scene with every
//! Table 6 level, our SPZ v2 writer, High, Medium and each higher-SH candidate
//! (`base:mode:bits:SH degree`; mode v = `ExpMode::SharedVector`, c = `SharedComponent`).

#[path = "../benches/common/mod.rs"]
mod common;
#[path = "../benches/peer_views/mod.rs"]
mod peer_views;

use peer_views::{ZOOMS, framed, render_all, view_scores, zoomed};
use splat2tiles_core::frame::UpAxis;
use splat2tiles_core::splat::Splats;
use splat2tiles_io::read_path;
use splat2tiles_render::{Camera, Image};
use splat2tiles_tiles::encode::exp_filter::ExpMode;
use splat2tiles_tiles::encode::meshopt::{HIGH, MEDIUM, MeshoptLevel, write_meshopt_glb};
use splat2tiles_tiles::encode::spz_rotation::RotationFit;
use splat2tiles_tiles::encode::spz2::{SpzOptions, encode_spz_v2, gzip, write_spz2_glb};
use splat2tiles_tiles::encode::table6;
use splat2tiles_tiles::encode::tile::IDENTITY;
use splat2tiles_tiles::variants::{LOW_SPZ, decode_variant};

fn main() {
    let dir =
        std::path::PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../..")).join("data/scenes");
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
    // Higher-SH candidates, `base:mode:bits:degree` (base high|medium, mode v = one exponent per
    // coefficient's RGB, c = fixed point over the tile), on the generated SH3 scene only.
    let sh_cands: Vec<(String, MeshoptLevel)> = std::env::var("PROBE_SH")
        .unwrap_or_default()
        .split(';')
        .filter(|c| !c.is_empty())
        .map(|c| {
            let v: Vec<&str> = c.split(':').collect();
            let base = if v[0] == "high" { HIGH } else { MEDIUM };
            let mode = if v[1] == "c" {
                ExpMode::SharedComponent
            } else {
                ExpMode::SharedVector
            };
            let l = MeshoptLevel {
                sh_rest_mode: mode,
                sh_rest_bits: v[2].parse().unwrap(),
                max_sh_degree: v[3].parse().unwrap(),
                ..base
            };
            (c.to_string(), l)
        })
        .collect();
    // `PROBE_ROT=nearest`: Low's rotation bytes rounded, not fitted to the covariance.
    let low_spz = SpzOptions {
        rotation_fit: match std::env::var("PROBE_ROT").as_deref() {
            Ok("nearest") => RotationFit::Nearest,
            _ => RotationFit::Covariance,
        },
        ..LOW_SPZ
    };
    let mut files = vec!["donut_fused_sh0.ply", "plant.splat", "biker.spz"];
    if !sh_cands.is_empty() {
        files.push("sh3");
    }
    for f in files {
        if !only.is_empty() && !f.contains(&only) {
            continue;
        }
        let t0 = std::time::Instant::now();
        let (splats, up) = if f == "sh3" {
            let plant = read_path(&dir.join("plant.splat")).unwrap().splats;
            (common::peers_sh3(&plant), "-y".parse::<UpAxis>().unwrap())
        } else {
            let sc = read_path(&dir.join(f)).unwrap();
            let up: UpAxis = sc.format.default_up_axis().parse().unwrap();
            (sc.splats, up)
        };
        let (rel, views) = framed(&splats, up);
        let n = rel.len() as f64;
        let cams: Vec<Vec<Camera>> = ZOOMS.iter().map(|&z| zoomed(&views, z)).collect();
        let base: Vec<Vec<Image>> = cams.iter().map(|c| render_all(&rel, c)).collect();
        let report = |label: &str, file: &[u8], dec: &Splats| {
            let wire = file.len().min(gzip(file).len()) as f64 / n;
            let s = [0, 1].map(|k| view_scores(&base[k], dec, &cams[k]).ssim);
            println!(
                "{f} | {label} | {wire:.2} | {:.5} | {:.5} | raw {:.12} {:.12}",
                s[0], s[1], s[0], s[1]
            );
        };
        for (name, bits) in table6::LEVELS {
            if name != "best" && f != "sh3" {
                continue;
            }
            let enc = table6::encode(&rel, &bits);
            report(
                &format!("table6 {name}"),
                &enc,
                &table6::decode(&enc).unwrap(),
            );
        }
        let mut levels: Vec<(String, MeshoptLevel)> = vec![("high (current)".into(), HIGH)];
        if f == "sh3" {
            let spz = encode_spz_v2(&rel, [0.0; 3], &SpzOptions::default());
            let dec = splat2tiles_io::read_bytes("v2.spz", &spz).unwrap().splats;
            report("spz v2 (ours)", &spz, &dec);
            levels.push(("medium (current)".into(), MEDIUM));
            levels.extend(sh_cands.iter().cloned());
        }
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
                ..low_spz
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
            let fb = splat2tiles_tiles::encode::spz2::spz_fractional_bits(&rel, max_abs, &low_spz);
            let glb = write_spz2_glb(&rel, [0.0; 3], IDENTITY, &low_spz).unwrap();
            let (dec, _) = decode_variant(&glb).unwrap();
            report(&format!("low (LOW_SPZ: {fb} fractional bits)"), &glb, &dec);
        }
        eprintln!("{f}: {:.0} s", t0.elapsed().as_secs_f64());
    }
}
