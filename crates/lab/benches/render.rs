//! Reference-renderer benchmark (not a test): ms/frame at 1280x720 for plant.splat and a generated
//! 1M-splat scene, and the accuracy/time trade-off of each `RenderOptions` knob.
//!
//! Run: `cargo bench --bench render` (release). Timed: one full `render` call (projection, sort,
//! binning, compositing; no PNG encoding), fastest of several runs after a warm-up, with rayon's
//! default thread count. Trade-off: plant.splat given synthetic SH degree 3 (so that SH
//! truncation matters), each knob varied alone, SSIM of the 8-bit image against the exact render.
//! Writes `target/render_bench.md` (the table pasted into BENCHMARKS.md) and
//! `docs/render_tradeoff.svg`.

#[path = "../../../tests/common/splat_file.rs"]
mod splat_file;

use std::fmt::Write as _;
use std::time::Instant;

use glam::{DMat4, DVec3};
use splat2tiles_core::splat::Splats;
use splat2tiles_render::{
    Camera, DepthSort, Image, RenderOptions, auto_views_with, render, render_with_stats, ssim,
};

const W: u32 = 1280;
const H: u32 = 720;
/// Timing rounds of the trade-off table.
const ROUNDS: usize = 5;

/// Fastest of `runs` timed calls after a warm-up (the minimum is the least disturbed by other
/// processes sharing the cores).
fn min_ms(runs: usize, mut f: impl FnMut() -> Image) -> (f64, Image) {
    let img = f(); // warm-up
    let mut best = f64::INFINITY;
    for _ in 0..runs {
        let t0 = Instant::now();
        std::hint::black_box(f());
        best = best.min(t0.elapsed().as_secs_f64() * 1e3);
    }
    (best, img)
}

/// Plant with deterministic synthetic higher SH: uniform in +-0.3, +-0.15, +-0.08 for degrees
/// 1, 2, 3 (trained scenes have small, decreasing higher coefficients).
fn with_synthetic_sh3(s: &Splats) -> Splats {
    let mut out = Splats::with_capacity(3, s.len());
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = move || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0) as f32
    };
    for i in 0..s.len() {
        let rest: Vec<[f32; 3]> = (0..15)
            .map(|k| {
                let amp = if k < 3 {
                    0.3
                } else if k < 8 {
                    0.15
                } else {
                    0.08
                };
                [next() * amp, next() * amp, next() * amp]
            })
            .collect();
        out.push(s.get(i), &rest);
    }
    out
}

fn plant_camera(s: &Splats) -> Camera {
    let (lo, hi) = s.bounds().unwrap();
    auto_views_with(DVec3::from(lo), DVec3::from(hi), -DVec3::Y, W, H, 50.0)[0]
}

/// SSIM-vs-time scatter: x = ms/frame, y = 1 - SSIM on a log scale (the exact render, 0, is drawn
/// on the bottom edge); points are numbered, with the legend on the right.
fn svg(points: &[(String, f64, f64)]) -> String {
    let tmax = points.iter().map(|p| p.1).fold(0.0, f64::max);
    let tmin = points.iter().map(|p| p.1).fold(f64::INFINITY, f64::min);
    let (x0, x1) = ((tmin * 0.9).floor(), (tmax * 1.05).ceil());
    let (l0, l1) = (-6.0f64, -1.0f64); // log10(1 - SSIM) range
    let (pw, ph, left, right, top, bottom) = (860.0, 420.0, 70.0, 500.0, 50.0, 360.0);
    let sx = |x: f64| left + (x - x0) / (x1 - x0) * (right - left);
    let sy = |err: f64| {
        let l = if err > 0.0 {
            err.log10().clamp(l0, l1)
        } else {
            l0
        };
        bottom - (l - l0) / (l1 - l0) * (bottom - top)
    };
    let mut s = String::new();
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{pw}" height="{ph}" font-family="sans-serif" font-size="12">"#
    );
    let _ = writeln!(s, r#"<rect width="100%" height="100%" fill="white"/>"#);
    let _ = writeln!(
        s,
        r#"<text x="{}" y="24" text-anchor="middle" font-size="14">CPU reference renderer: error vs time per knob (plant + synthetic SH3, {W}x{H})</text>"#,
        pw / 2.0
    );
    let _ = writeln!(
        s,
        r#"<line x1="{left}" y1="{bottom}" x2="{right}" y2="{bottom}" stroke="black"/><line x1="{left}" y1="{top}" x2="{left}" y2="{bottom}" stroke="black"/>"#
    );
    for i in 0..=4 {
        let x = x0 + (x1 - x0) * i as f64 / 4.0;
        let _ = writeln!(
            s,
            r#"<text x="{:.1}" y="{:.1}" text-anchor="middle">{x:.0}</text>"#,
            sx(x),
            bottom + 16.0
        );
    }
    for l in (l0 as i32)..=(l1 as i32) {
        let y = sy(10f64.powi(l));
        let _ = writeln!(
            s,
            r#"<line x1="{left}" y1="{y:.1}" x2="{right}" y2="{y:.1}" stroke="lightgray"/><text x="{:.1}" y="{:.1}" text-anchor="end">1e{l}</text>"#,
            left - 6.0,
            y + 4.0
        );
    }
    let _ = writeln!(
        s,
        r#"<text x="{}" y="{}" text-anchor="middle">time per frame (ms)</text><text x="18" y="{}" transform="rotate(-90 18 {})" text-anchor="middle">1 - SSIM vs exact (log; exact on the axis)</text>"#,
        (left + right) / 2.0,
        bottom + 36.0,
        (top + bottom) / 2.0,
        (top + bottom) / 2.0
    );
    for (k, (label, t, q)) in points.iter().enumerate() {
        let (x, y) = (sx(*t), sy(1.0 - q));
        let _ = writeln!(
            s,
            r#"<circle cx="{x:.1}" cy="{y:.1}" r="4" fill="steelblue"/><text x="{:.1}" y="{:.1}" font-size="10">{}</text>"#,
            x + 5.0,
            y - 5.0,
            k + 1
        );
        let _ = writeln!(
            s,
            r#"<text x="{:.1}" y="{:.1}">{}. {label}: {t:.1} ms, SSIM {q:.5}</text>"#,
            right + 20.0,
            top + 16.0 * k as f64,
            k + 1
        );
    }
    s.push_str("</svg>\n");
    s
}

/// Times one scene (fastest of `runs`), appends its table row and logs it.
fn scene_row(
    md: &mut String,
    name: &str,
    instances: &[(&Splats, DMat4)],
    cam: &Camera,
    opts: &RenderOptions,
    runs: usize,
) {
    let (ms, _) = min_ms(runs, || render(instances, cam, opts));
    let (_, stats) = render_with_stats(instances, cam, opts);
    let _ = writeln!(
        md,
        "| {name} | {} | {} | {} | {ms:.1} | {:.1} / {:.1} / {:.1} |",
        stats.splats,
        stats.visible,
        stats.tile_pairs,
        stats.project_ms,
        stats.sort_ms,
        stats.composite_ms
    );
    eprintln!("{name}: {ms:.1} ms");
}

#[expect(
    clippy::too_many_lines,
    reason = "a measurement run by hand: one straight script that prints its table"
)]
fn main() {
    let threads = rayon::current_num_threads();
    let plant = splat_file::read_splat(splat_file::PLANT);
    let cam = plant_camera(&plant);
    let exact = RenderOptions::default();
    let mut md = String::new();
    let _ = writeln!(
        md,
        "Machine: {threads} rayon threads. Frame {W}x{H}, auto-view 0 (up -y), exact options.\n"
    );
    let _ = writeln!(
        md,
        "| scene | splats | visible | tile pairs | ms/frame (min of 5) | project / sort / composite ms (one run) |"
    );
    let _ = writeln!(md, "|---|---:|---:|---:|---:|---|");
    scene_row(
        &mut md,
        "plant.splat",
        &[(&plant, DMat4::IDENTITY)],
        &cam,
        &exact,
        5,
    );
    for (name, up) in [("donut_fused_sh0.ply", -DVec3::Y), ("biker.spz", DVec3::Y)] {
        let scene = splat_file::read_splat(name);
        let (lo, hi) = scene.bounds().unwrap();
        let c = auto_views_with(DVec3::from(lo), DVec3::from(hi), up, W, H, 50.0)[0];
        scene_row(&mut md, name, &[(&scene, DMat4::IDENTITY)], &c, &exact, 5);
    }

    // ~1M splats: 9 instances of plant on a 3x3 grid (model matrices), framed as a whole.
    let (lo, hi) = plant.bounds().unwrap();
    let ext = DVec3::from(hi) - DVec3::from(lo);
    let models: Vec<DMat4> = (0..9)
        .map(|k| {
            let off = DVec3::new((k % 3) as f64 - 1.0, 0.0, (k / 3) as f64 - 1.0) * ext * 0.8;
            DMat4::from_translation(off)
        })
        .collect();
    let inst: Vec<(&Splats, DMat4)> = models.iter().map(|&m| (&plant, m)).collect();
    let big_lo = DVec3::from(lo) - ext * 0.8;
    let big_hi = DVec3::from(hi) + ext * 0.8;
    let big_cam = auto_views_with(big_lo, big_hi, -DVec3::Y, W, H, 50.0)[0];
    scene_row(
        &mut md,
        "9 x plant (instances, generated)",
        &inst,
        &big_cam,
        &exact,
        3,
    );

    // Trade-off on plant with synthetic SH3.
    let sh3 = with_synthetic_sh3(&plant);
    let one = |o: &RenderOptions| render(&[(&sh3, DMat4::IDENTITY)], &cam, o);
    let variants: Vec<(String, RenderOptions)> = vec![
        ("exact (SH3, 3 sigma, exact sort, T 1e-4)".into(), exact),
        (
            "SH degree 2".into(),
            RenderOptions {
                max_sh_degree: 2,
                ..exact
            },
        ),
        (
            "SH degree 1".into(),
            RenderOptions {
                max_sh_degree: 1,
                ..exact
            },
        ),
        (
            "SH degree 0".into(),
            RenderOptions {
                max_sh_degree: 0,
                ..exact
            },
        ),
        (
            "footprint 2.5 sigma".into(),
            RenderOptions {
                footprint_sigma: 2.5,
                ..exact
            },
        ),
        (
            "footprint 2 sigma".into(),
            RenderOptions {
                footprint_sigma: 2.0,
                ..exact
            },
        ),
        (
            "sort 65536 buckets".into(),
            RenderOptions {
                sort: DepthSort::Buckets(65536),
                ..exact
            },
        ),
        (
            "sort 4096 buckets".into(),
            RenderOptions {
                sort: DepthSort::Buckets(4096),
                ..exact
            },
        ),
        (
            "sort 256 buckets".into(),
            RenderOptions {
                sort: DepthSort::Buckets(256),
                ..exact
            },
        ),
        (
            "early stop T < 1e-3".into(),
            RenderOptions {
                min_transmittance: 1e-3,
                ..exact
            },
        ),
        (
            "early stop T < 1e-2".into(),
            RenderOptions {
                min_transmittance: 1e-2,
                ..exact
            },
        ),
        (
            "early stop T < 5e-2".into(),
            RenderOptions {
                min_transmittance: 5e-2,
                ..exact
            },
        ),
        (
            "fast: SH1, 2 sigma, 4096 buckets, T < 1e-2".into(),
            RenderOptions {
                max_sh_degree: 1,
                footprint_sigma: 2.0,
                sort: DepthSort::Buckets(4096),
                min_transmittance: 1e-2,
                ..exact
            },
        ),
    ];
    let _ = writeln!(
        md,
        "\nTrade-off (plant.splat + synthetic SH degree 3, {W}x{H}, auto-view 0; SSIM of the 8-bit \
         image against the exact render; fastest of {ROUNDS} round-robin runs):\n"
    );
    let _ = writeln!(md, "| variant | ms/frame | vs exact | SSIM | PSNR (dB) |");
    let _ = writeln!(md, "|---|---:|---:|---:|---:|");
    // Round-robin timing (each round times every variant once) so that load from other
    // processes spreads over all variants; keep each variant's fastest round.
    let images: Vec<Image> = variants.iter().map(|(_, o)| one(o)).collect();
    let mut best = vec![f64::INFINITY; variants.len()];
    for _ in 0..ROUNDS {
        for (b, (_, o)) in best.iter_mut().zip(&variants) {
            let t0 = Instant::now();
            std::hint::black_box(one(o));
            *b = b.min(t0.elapsed().as_secs_f64() * 1e3);
        }
    }
    let t_ref = best[0];
    let ref_q = images[0].quantized();
    let mut points = Vec::new();
    for (((name, _), img), &t) in variants.iter().zip(&images).zip(&best) {
        let q = img.quantized();
        let s = ssim(&q, &ref_q).unwrap();
        let p = splat2tiles_render::psnr(&q, &ref_q).unwrap();
        let p_txt = if p.is_finite() {
            format!("{p:.2}")
        } else {
            "inf".into()
        };
        let _ = writeln!(
            md,
            "| {name} | {t:.1} | {:.2}x | {s:.5} | {p_txt} |",
            t / t_ref
        );
        eprintln!("{name}: {t:.1} ms, SSIM {s:.5}");
        let short = name.split(" (").next().unwrap_or(name).to_string();
        points.push((short, t, s));
    }
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/../..");
    std::fs::create_dir_all(format!("{root}/docs")).unwrap();
    std::fs::write(format!("{root}/docs/render_tradeoff.svg"), svg(&points)).unwrap();
    std::fs::write(format!("{root}/target/render_bench.md"), &md).unwrap();
    println!("{md}");
}
