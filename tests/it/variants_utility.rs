//! The variant utility (spec/quality-variants.md, "Utility") sees what a viewer sees: damaged
//! copies of a real tile (half the splats, positions jittered by 1% of the box, colours at 3
//! bits) score at least 0.05 below Best. Scenes: data/scenes (see its README.md).

use crate::common::*;
use glam::DVec3;
use splat2tiles_build::convert::{ConvertOptions, convert_scene};
use splat2tiles_build::variants::curve::loss_curve;
use splat2tiles_build::variants::estimate::{estimated_utilities, features};
use splat2tiles_build::variants::utility::{BACKGROUND, ViewSetup, render_options, scores};
use splat2tiles_core::splat::Splats;
use splat2tiles_core::splat::sh::SH_C0;
use splat2tiles_render::metrics::ssim_plane;
use splat2tiles_render::{Camera, Image, render_splats, ssim};
use splat2tiles_tiles::encode::storage_order::aligned_to_best;
use splat2tiles_tiles::tiling::load::load_tileset;
use splat2tiles_tiles::variants::{
    Variant, VariantOptions, content_uri, decode_variant, up_in_source,
};

/// The largest leaf tile of a shared scene converted at the default tile size: tile-relative
/// Best splats and the up direction of the utility views.
fn largest_tile(name: &str) -> (Splats, DVec3) {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("ts");
    let opts = ConvertOptions {
        variants: VariantOptions {
            measure_utility: false,
            ..Default::default()
        },
        ..Default::default()
    };
    let sc = splat2tiles_io::read_path(&scene(name)).unwrap();
    convert_scene(sc, name, &out, &opts).unwrap();
    let ts = load_tileset(&out.join("tileset.json")).unwrap();
    let t = ts
        .tiles
        .iter()
        .filter(|t| t.content.is_some())
        .max_by_key(|t| (t.key.level, t.splat_count))
        .unwrap();
    let glb = std::fs::read(out.join(content_uri(ts.scheme, t.key, Variant::Best))).unwrap();
    let (s, node) = decode_variant(&glb).unwrap();
    (s, up_in_source(node))
}

/// Every second splat dropped.
fn half(s: &Splats) -> Splats {
    s.select(&(0..s.len()).step_by(2).collect::<Vec<_>>())
}

/// Every position moved by up to 1% of the box size along each axis (uniform).
fn jittered(s: &Splats) -> Splats {
    let (lo, hi) = s.bounds().unwrap();
    let mut out = s.clone();
    let mut r = Rng(7);
    for p in &mut out.positions {
        for a in 0..3 {
            p[a] += r.range(-0.01, 0.01) * (hi[a] - lo[a]);
        }
    }
    out
}

/// DC colours (`0.5 + C0 * sh0`) quantised to 3 bits per channel over [0, 1].
fn colours_3bit(s: &Splats) -> Splats {
    let mut out = s.clone();
    for c in &mut out.sh0 {
        for v in c.iter_mut() {
            let col = (0.5 + SH_C0 * *v).clamp(0.0, 1.0);
            let q = (col * 7.0).round() / 7.0;
            *v = (q - 0.5) / SH_C0;
        }
    }
    out
}

fn check_damage(name: &str) {
    let (tile, up) = largest_tile(name);
    let damaged = [half(&tile), jittered(&tile), colours_3bit(&tile)];
    let mut cands: Vec<&Splats> = vec![&tile];
    cands.extend(damaged.iter());
    let (lo, hi) = tile.bounds().unwrap();
    let setup = ViewSetup::estimated(DVec3::from_array(lo), DVec3::from_array(hi), up);
    let u = splat2tiles_build::variants::utilities(&tile, &cands, &setup);
    let sc = scores(&tile, &cands, &setup.windows());
    eprintln!("{name}: window {} px, scores {sc:?}", setup.window_side());
    eprintln!(
        "{name} ({} splats): same {:.4}, half {:.4}, jitter 1% {:.4}, colours 3 bit {:.4}",
        tile.len(),
        u[0],
        u[1],
        u[2],
        u[3]
    );
    assert_eq!(u[0], 1.0);
    for (what, v) in ["half", "jitter", "3-bit colour"].iter().zip(&u[1..]) {
        assert!(*v <= u[0] - 0.05, "{name}: {what} scores {v}");
    }
}

#[test]
fn damage_costs_plant() {
    check_damage("plant.splat");
}

#[test]
fn damage_costs_donut() {
    check_damage("donut_fused_sh0.ply");
}

#[test]
fn damage_costs_biker() {
    check_damage("biker.spz");
}

#[test]
fn spearman_of_known_orders() {
    assert!((spearman(&[1.0, 2.0, 3.0], &[10.0, 20.0, 30.0]) - 1.0).abs() < 1e-12);
    assert!((spearman(&[1.0, 2.0, 3.0], &[3.0, 2.0, 1.0]) + 1.0).abs() < 1e-12);
    assert_eq!(ranks(&[5.0, 1.0, 5.0]), vec![2.5, 1.0, 2.5]);
}

/// Mean SSIM (`render::ssim`, exactly) of each candidate's full-frame renders against the
/// reference's: the SSIM map is 1 wherever both images are plain background around the pixel's
/// whole Gaussian window, so only the box of non-background pixels (padded by twice the window
/// radius) is computed and the rest counted as 1.
fn full_frame_ssim(reference: &Splats, candidates: &[&Splats], cams: &[Camera]) -> Vec<f64> {
    let opts = render_options();
    let base: Vec<Image> = cams
        .iter()
        .map(|c| render_splats(reference, c, &opts))
        .collect();
    candidates
        .iter()
        .map(|s| {
            let mut total = 0.0;
            for (c, b) in cams.iter().zip(&base) {
                total += padded_ssim(b, &render_splats(s, c, &opts));
            }
            total / cams.len() as f64
        })
        .collect()
}

/// Kernel radius of `render::metrics::ssim` (sigma 1.5, truncated at 3.5 sigma).
const SSIM_PAD: usize = 5;

/// `ssim(a, b)` computed on the box of pixels that differ from the background in either image.
fn padded_ssim(a: &Image, b: &Image) -> f64 {
    let (w, h) = (a.width as usize, a.height as usize);
    let bg = BACKGROUND;
    let mut lo = [usize::MAX; 2];
    let mut hi = [0usize; 2];
    for y in 0..h {
        for x in 0..w {
            let i = 3 * (y * w + x);
            let differs = (0..3).any(|c| a.data[i + c] != bg[c] || b.data[i + c] != bg[c]);
            if differs {
                lo = [lo[0].min(x), lo[1].min(y)];
                hi = [hi[0].max(x), hi[1].max(y)];
            }
        }
    }
    if lo[0] == usize::MAX {
        return 1.0;
    }
    let m = 2 * SSIM_PAD;
    let (x0, y0) = (lo[0].saturating_sub(m), lo[1].saturating_sub(m));
    let (x1, y1) = ((hi[0] + m + 1).min(w), (hi[1] + m + 1).min(h));
    let (cw, ch) = (x1 - x0, y1 - y0);
    let valid = |n: usize| n.saturating_sub(2 * SSIM_PAD) as f64;
    let n_full = valid(w) * valid(h);
    let n_crop = valid(cw) * valid(ch);
    let mut sum = 0.0;
    for c in 0..3 {
        let plane = |img: &Image| -> Vec<f64> {
            let mut v = Vec::with_capacity(cw * ch);
            for y in y0..y1 {
                for x in x0..x1 {
                    v.push(img.data[3 * (y * w + x) + c] as f64);
                }
            }
            v
        };
        let m = ssim_plane(&plane(a), &plane(b), cw, ch);
        sum += (m * n_crop + (n_full - n_crop)) / n_full;
    }
    sum / 3.0
}

#[test]
fn padded_ssim_is_the_full_frame_ssim() {
    let (tile, up) = largest_tile("donut_fused_sh0.ply");
    let (lo, hi) = tile.bounds().unwrap();
    let setup = ViewSetup::estimated(DVec3::from_array(lo), DVec3::from_array(hi), up);
    let cams = setup.full_frames();
    let opts = render_options();
    let a = render_splats(&tile, &cams[1], &opts);
    let b = render_splats(&colours_3bit(&tile), &cams[1], &opts);
    let exact = ssim(&a, &b).unwrap();
    let fast = padded_ssim(&a, &b);
    assert!(
        exact < 1.0 && (exact - fast).abs() < 1e-9,
        "{exact} vs {fast}"
    );
}

/// The correlation table (BENCHMARKS.md "Quality variants"): over every content tile of the
/// shared scenes and the generated SH3 scene, the stored utility against the mean SSIM of the
/// variant's full 1280x720 renders from 8 views at the tile's switching distance (its own
/// geometric error; a leaf's parent's). Run:
/// `cargo test --release --test variants_utility -- --ignored --nocapture correlation_table`.
#[test]
#[ignore = "slow (full-frame renders of every tile); produces the BENCHMARKS.md table"]
#[expect(
    clippy::too_many_lines,
    reason = "a measurement run by hand: one straight script that prints its table"
)]
fn correlation_table() {
    use splat2tiles_tiles::variants::{ALL, content_variant_metadata};
    use std::fmt::Write as _;
    let inputs = [
        (
            "plant.splat",
            splat2tiles_io::read_path(&scene("plant.splat")).unwrap(),
        ),
        (
            "donut_fused_sh0.ply",
            splat2tiles_io::read_path(&scene("donut_fused_sh0.ply")).unwrap(),
        ),
        (
            "biker.spz",
            splat2tiles_io::read_path(&scene("biker.spz")).unwrap(),
        ),
        ("plant + SH1-3 (generated)", plant_sh3()),
    ];
    let mut csv = String::from(
        "scene,level,key,splats,error,radius,variant,bytes,utility,full_ssim,win_ssim_true,win_rmse_true,estimate,f_colour,f_opacity,f_position,f_scale,f_rotation\n",
    );
    let mut table = String::from(
        "| scene | tiles | Spearman (utility vs 1280x720 SSIM) | tiles in order (utility) | tiles in order (1280x720 SSIM) | Spearman (estimate vs 1280x720 SSIM) | tiles in order (estimate) | Spearman (stored estimate, interpolated, vs 1280x720 SSIM) | tiles in order (interpolated) | median error / radius | B/splat per 0.01 utility: High->Best, Medium->High, Low->Medium |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|\n",
    );
    let (mut all_u, mut all_s, mut all_e, mut all_c) = (vec![], vec![], vec![], vec![]);
    let mut failures: Vec<String> = vec![];
    let (mut all_tiles, mut all_in_order) = (0, 0);
    let mut all_ratios: Vec<f64> = vec![];
    for (name, sc) in inputs {
        let tmp = tempfile::tempdir().unwrap();
        let out = tmp.path().join("ts");
        let opts = ConvertOptions {
            variants: VariantOptions {
                variants: ALL.to_vec(),
                utility_renders: true,
                ..Default::default()
            },
            ..Default::default()
        };
        convert_scene(sc, name, &out, &opts).unwrap();
        let ts = load_tileset(&out.join("tileset.json")).unwrap();
        let meta = content_variant_metadata(&ts);
        let errors: std::collections::HashMap<_, _> = ts
            .tiles
            .iter()
            .map(|t| (t.key, t.geometric_error))
            .collect();
        let (mut us, mut ss, mut es, mut ratios) = (vec![], vec![], vec![], vec![]);
        let (mut in_order_u, mut in_order_s, mut in_order_e, mut tiles) = (0, 0, 0, 0);
        let (mut cs, mut in_order_c) = (vec![], 0);
        let mut steps = [(0.0, 0.0); 3];
        for t in ts.tiles.iter().filter(|t| t.content.is_some()) {
            let decoded: Vec<(Splats, [f64; 16])> = ALL
                .iter()
                .map(|&v| {
                    let glb = std::fs::read(out.join(content_uri(ts.scheme, t.key, v))).unwrap();
                    decode_variant(&glb).unwrap()
                })
                .collect();
            let best = &decoded[0].0;
            let Some((lo, hi)) = best.bounds() else {
                continue;
            };
            let (lo, hi) = (DVec3::from_array(lo), DVec3::from_array(hi));
            let mut error = t.geometric_error;
            if error <= 0.0 {
                error = t
                    .key
                    .parent()
                    .and_then(|p| errors.get(&p).copied())
                    .unwrap_or(0.0);
            }
            let radius = (hi - lo).length() * 0.5;
            let setup = ViewSetup {
                lo,
                hi,
                up: up_in_source(decoded[0].1),
                error,
            };
            if error <= 0.0 {
                continue;
            }
            ratios.push(error / radius);
            // High and Medium are stored in Morton order: lined up with Best splat for splat.
            let aligned: Vec<Splats> = decoded[1..]
                .iter()
                .map(|d| aligned_to_best(&d.0, best).unwrap())
                .collect();
            let cands: Vec<&Splats> = aligned.iter().collect();
            let full = full_frame_ssim(best, &cands, &setup.full_frames());
            let est = estimated_utilities(best, &cands, &setup);
            // The estimate's features per variant (for refitting its weights from this CSV).
            let feats: Vec<[f64; 5]> = cands
                .iter()
                .map(|c| features(best, c, &setup).map_or([f64::NAN; 5], |f| f.to_array()))
                .collect();
            es.extend(&est);
            in_order_e += est.windows(2).all(|w| w[0] >= w[1]) as usize;
            // What `convert` stores by default: the estimate interpolated from the writer's
            // curve over viewing distances (`variants::curve`).
            let curve = loss_curve(
                best,
                setup.up,
                &[None, Some(cands[0]), Some(cands[1]), Some(cands[2])],
            )
            .unwrap();
            let interp: Vec<f64> = (1..4).map(|i| curve.utility(i, error).unwrap()).collect();
            cs.extend(&interp);
            in_order_c += interp.windows(2).all(|w| w[0] >= w[1]) as usize;
            let win = scores(best, &cands, &setup.windows());
            let (count, bytes, util) = meta[&t.key];
            let mut full4 = vec![1.0];
            full4.extend(&full);
            for (i, v) in ALL.iter().enumerate() {
                let (fs, ws, wr, e, f) = if i == 0 {
                    (1.0, 1.0, 0.0, 1.0, [0.0; 5])
                } else {
                    let k = i - 1;
                    (full[k], win[k].ssim, win[k].rmse, est[k], feats[k])
                };
                writeln!(
                    csv,
                    "{name},{},{}/{}/{},{count},{error},{radius},{},{},{},{fs},{ws},{wr},{e},{},{},{},{},{}",
                    t.key.level,
                    t.key.x,
                    t.key.y,
                    t.key.z,
                    v.name(),
                    bytes[i],
                    util[i],
                    f[0],
                    f[1],
                    f[2],
                    f[3],
                    f[4]
                )
                .unwrap();
                if i > 0 {
                    us.push(util[i] as f64);
                    ss.push(fs);
                }
            }
            tiles += 1;
            in_order_u += util.windows(2).all(|w| w[0] >= w[1]) as usize;
            in_order_s += full4.windows(2).all(|w| w[0] >= w[1]) as usize;
            for k in 0..3 {
                steps[k].0 += (bytes[k] as f64 - bytes[k + 1] as f64) / count as f64;
                steps[k].1 += (util[k] - util[k + 1]) as f64;
            }
        }
        all_ratios.extend(&ratios);
        ratios.sort_by(f64::total_cmp);
        let rho = spearman(&us, &ss);
        let rho_e = spearman(&es, &ss);
        let rho_c = spearman(&cs, &ss);
        all_e.extend(&es);
        all_c.extend(&cs);
        if rho_c < 0.9 {
            failures.push(format!(
                "{name}: interpolated estimate's Spearman {rho_c:.3} < 0.9"
            ));
        }
        if rho < 0.9 {
            failures.push(format!("{name}: Spearman {rho:.3} < 0.9"));
        }
        all_tiles += tiles;
        all_in_order += in_order_u;
        all_u.extend(&us);
        all_s.extend(&ss);
        let per_point = |k: usize| {
            if steps[k].1 > 0.0 {
                format!("{:.1}", steps[k].0 / (100.0 * steps[k].1))
            } else {
                "n/a (no utility gained)".to_string()
            }
        };
        writeln!(
            table,
            "| {name} | {tiles} | {rho:.3} | {in_order_u} / {tiles} | {in_order_s} / {tiles} | {rho_e:.3} | {in_order_e} / {tiles} | {rho_c:.3} | {in_order_c} / {tiles} | {:.3} | {}, {}, {} |",
            ratios.get(ratios.len() / 2).copied().unwrap_or(f64::NAN),
            per_point(0),
            per_point(1),
            per_point(2),
        )
        .unwrap();
    }
    let rho = spearman(&all_u, &all_s);
    let rho_e = spearman(&all_e, &all_s);
    let rho_c = spearman(&all_c, &all_s);
    all_ratios.sort_by(f64::total_cmp);
    writeln!(
        table,
        "| all | {all_tiles} | {rho:.3} | {all_in_order} / {all_tiles} | | {rho_e:.3} | | {rho_c:.3} | | {:.3} | |",
        all_ratios.get(all_ratios.len() / 2).copied().unwrap_or(f64::NAN),
    )
    .unwrap();
    failures.extend((rho < 0.9).then(|| format!("pooled Spearman {rho:.3} < 0.9")));
    if (all_in_order as f64) < 0.95 * all_tiles as f64 {
        failures.push(format!("{all_in_order} of {all_tiles} tiles in order"));
    }
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"));
    std::fs::write(dir.join("variants_utility.csv"), &csv).unwrap();
    std::fs::write(dir.join("variants_utility.md"), &table).unwrap();
    eprintln!(
        "{table}\n(per-tile rows: {})",
        dir.join("variants_utility.csv").display()
    );
    assert!(failures.is_empty(), "{failures:?}");
}
