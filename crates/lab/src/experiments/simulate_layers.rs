//! `simulate --experiment layers`: layered (LapisGS) vs independent-variant streaming on the
//! same scenes, traces and link: bytes and SSIM over time of what the client draws.
//!
//! Each shared scene is converted twice at the same tile size: plain with all four variants
//! (the REPLACE client picks variants) and with `--layers` (the client selects ADD, Best only).
//! The same client settings run both over the same traces and link. Every second the drawn
//! set is rendered at 320x180 and compared (SSIM) with the full Best cut the pose needs (the
//! plain tileset's `select_cut` over every tile, all Best): the variant client's drawn tiles at
//! their levels; the layered client's drawn layers at their effective opacities (blend factors
//! and deltas); the same layers with the deltas ignored (a damaged viewer, to show the score
//! sees the fading); and every layer the pose needs held (what the layered client converges to).

use super::SimulateArgs;
use crate::sim::score::Truth;
use crate::sim::session::{SessionLog, SessionOptions, run_session};
use crate::sim::svg::{Series, write_time_plots};
use crate::sim::transport::NetModel;
use anyhow::Context;
use splat2tiles_render::{Camera, ssim};
use splat2tiles_stream::catalog::{Level, TileCatalog};
use splat2tiles_stream::client::{ClientConfig, PredictorKind};
use splat2tiles_stream::trace::{self, Trace};
use splat2tiles_tiles::tiling::TileKey;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// SSIM render size (a quarter of the client's 1280x720 per side, as `table4`).
const W: u32 = 320;
const H: u32 = 180;
/// Seconds between SSIM samples.
const SAMPLE_S: f64 = 1.0;
/// Quality threshold of the "time to quality" column (the scorer's TGQ threshold).
const GOOD: f64 = 0.9;
/// Link rates compared (Mbps).
const MBPS: [f64; 2] = [4.0, 1.0];

/// Samples of one session: `(t, MB received, SSIM)` per sample, per drawing.
#[derive(Default)]
struct Samples {
    mb: Vec<(f64, f64)>,
    ssim: Vec<(f64, f64)>,
}

impl Samples {
    fn mean(&self) -> f64 {
        self.ssim.iter().map(|s| s.1).sum::<f64>() / self.ssim.len().max(1) as f64
    }
    fn first_good(&self) -> Option<f64> {
        self.ssim.iter().find(|s| s.1 >= GOOD).map(|s| s.0)
    }
    fn mean_until(&self, t: f64) -> f64 {
        let early: Vec<f64> = self
            .ssim
            .iter()
            .filter(|s| s.0 < t - 1e-9)
            .map(|s| s.1)
            .collect();
        early.iter().sum::<f64>() / early.len().max(1) as f64
    }
    fn at(&self, t: f64) -> f64 {
        self.ssim
            .iter()
            .rev()
            .find(|s| s.0 <= t + 1e-9)
            .map_or(0.0, |s| s.1)
    }
    fn total_mb(&self) -> f64 {
        self.mb.last().map_or(0.0, |b| b.1)
    }
}

fn convert_scene(file: &Path, out: &Path, max_splats: u32, layers: bool) -> anyhow::Result<()> {
    let opts = splat2tiles_build::convert::ConvertOptions {
        max_splats_per_tile: max_splats as usize,
        layers,
        progress: None,
        variants: splat2tiles_tiles::variants::VariantOptions {
            variants: if layers {
                vec![splat2tiles_tiles::variants::Variant::Best]
            } else {
                splat2tiles_tiles::variants::ALL.to_vec()
            },
            ..Default::default()
        },
        ..Default::default()
    };
    splat2tiles_build::convert::convert(file, out, &opts)
        .with_context(|| file.display().to_string())?;
    Ok(())
}

/// The small camera a pose is scored with (the client's viewport and field of view, resized).
fn small_camera(truth: &Truth, cfg: &ClientConfig, pose: &splat2tiles_stream::ViewPose) -> Camera {
    Camera::from_pose(
        cfg.width,
        cfg.height,
        cfg.fov_y_deg,
        truth.root_transform() * pose.world_from_camera(),
    )
}

/// Scores both sessions of one trace: variant client, layered client, layered without deltas,
/// layered with every needed layer held.
fn score(
    plain: &mut Truth,
    layered: &mut Truth,
    cfg: &ClientConfig,
    var: &SessionLog,
    lay: &SessionLog,
) -> anyhow::Result<[Samples; 4]> {
    let mut out: [Samples; 4] = Default::default();
    let t0 = var.ticks.first().map_or(0.0, |t| t.t);
    let mut next = t0;
    for (tv, tl) in var.ticks.iter().zip(&lay.ticks) {
        if tv.t + 1e-9 < next {
            continue;
        }
        next += SAMPLE_S;
        let t = tv.t - t0;
        let full = small_camera(plain, cfg, &tv.pose);
        let cam = full.resized(W, H);
        let needed = plain.needed(&full, cfg.max_sse);
        let best: Vec<(TileKey, Level)> = needed.iter().map(|k| (*k, Level::Best)).collect();
        let reference = plain.render(&best, &cam)?;
        let drawn: Vec<(TileKey, Level)> = tv.drawn.iter().map(|d| (d.0, d.1)).collect();
        let held = layered.needed_layers(&full, cfg.max_sse);
        let images = [
            plain.render(&drawn, &cam)?,
            layered.render_layers(&tl.layers, &cam, true)?,
            layered.render_layers(&tl.layers, &cam, false)?,
            layered.render_layers(&held, &cam, true)?,
        ];
        let bytes = [tv.bytes_down, tl.bytes_down, tl.bytes_down, tl.bytes_down];
        for ((s, img), b) in out.iter_mut().zip(&images).zip(bytes) {
            let q = if needed.is_empty() {
                0.0
            } else {
                ssim(img, &reference)?
            };
            s.ssim.push((t, q));
            s.mb.push((t, b as f64 / 1e6));
        }
    }
    Ok(out)
}

const DRAWINGS: [&str; 4] = [
    "variants (REPLACE)",
    "layers (ADD, blended)",
    "layers, deltas ignored (damaged)",
    "layers, every needed layer held",
];

/// Content bytes a session received per level (Best, High, Medium, Low), in MB.
fn mb_by_level(log: &SessionLog) -> String {
    let mut b = [0u64; 4];
    for r in &log.requests {
        if let Some(l) = r.level {
            b[l.index()] += r.bytes;
        }
    }
    b.map(|x| format!("{:.2}", x as f64 / 1e6)).join(" / ")
}

/// Runs the experiment; returns its markdown.
pub fn layers(args: &SimulateArgs) -> anyhow::Result<String> {
    let mut md = String::new();
    let _ = writeln!(
        md,
        "### Layered vs independent-variant streaming\n\nShared scenes tiled at {} splats/tile, converted plain with all four variants and with `--layers`; the shipped client (1280x720, 50 deg, 4 requests in flight, linear predictor, App. C.5 fallback within 0.3 x the scene diagonal) over the simulated link ({MBPS:?} Mbps, 40 ms RTT); traces: SGSS orbital + 2 walks per scene (seed {}). SSIM at {W}x{H} every {SAMPLE_S} s against the full Best cut of the pose (plain tileset, every tile available); 'first >= {GOOD}' = first sample at or above it; content MB by level = Best / High / Medium / Low.\n\n| scene | trace | Mbps | drawing | MB received | content MB by level | mean SSIM | mean SSIM, first 10 s | SSIM at 5 s | first >= {GOOD} (s) |\n|---|---|---:|---|---:|---|---:|---:|---:|---:|",
        args.max_splats, args.seed
    );
    let mut plot_q: Vec<Series> = vec![];
    let mut plot_b: Vec<Series> = vec![];
    let mut sums = [[(0.0f64, 0.0f64, 0.0f64, 0usize); 2]; 4];
    for f in ["plant.splat", "biker.spz"] {
        let file = args.scenes.join(f);
        let name = f.split('.').next().unwrap_or(f).to_string();
        let plain_dir: PathBuf = args.out.join(format!("layers_{name}_variants"));
        let layer_dir: PathBuf = args.out.join(format!("layers_{name}_layers"));
        convert_scene(&file, &plain_dir, args.max_splats, false)?;
        convert_scene(&file, &layer_dir, args.max_splats, true)?;
        let mut plain = Truth::load(&plain_dir.join("tileset.json"))?;
        let mut layered = Truth::load(&layer_dir.join("tileset.json"))?;
        let ts = splat2tiles_tiles::tiling::load::load_tileset(&plain_dir.join("tileset.json"))?;
        let (lo, hi) = TileCatalog::from_loaded(&ts.tiles, |_| Some(1)).bounds();
        let diag = (hi - lo).truncate().length();
        let c = (lo + hi) * 0.5;
        let traces: Vec<Trace> = vec![
            trace::orbital(&name, lo, hi, args.seed, "test"),
            trace::walk(&name, lo, hi, c.z, 0.08 * diag, 60.0, args.seed, "test"),
            trace::walk(&name, lo, hi, c.z, 0.08 * diag, 60.0, args.seed + 1, "test"),
        ];
        let cfg = ClientConfig {
            max_concurrent: 4,
            predictor: PredictorKind::Linear,
            fallback_radius_m: 0.3 * (hi - lo).length(),
            ..ClientConfig::default()
        };
        for mbps in MBPS {
            let net = NetModel::constant(mbps, 0.04);
            for (ti, tr) in traces.iter().enumerate() {
                let run = |dir: &Path| {
                    run_session(dir, cfg.clone(), &tr.poses, &net, SessionOptions::default())
                };
                let var = run(&plain_dir);
                let lay = run(&layer_dir);
                anyhow::ensure!(
                    lay.errors == 0 && var.errors == 0,
                    "{name} trace {ti}: client errors (variants {}, layers {})",
                    var.errors,
                    lay.errors
                );
                let samples = score(&mut plain, &mut layered, &cfg, &var, &lay)?;
                let trace_name = if ti == 0 {
                    "orbital".to_string()
                } else {
                    format!("walk {ti}")
                };
                let levels = [
                    mb_by_level(&var),
                    mb_by_level(&lay),
                    "same".into(),
                    "same".into(),
                ];
                for (((d, s), sum), lv) in DRAWINGS
                    .iter()
                    .zip(&samples)
                    .zip(sums.iter_mut())
                    .zip(&levels)
                {
                    let _ = writeln!(
                        md,
                        "| {name} | {trace_name} | {mbps} | {d} | {:.2} | {lv} | {:.4} | {:.4} | {:.4} | {} |",
                        s.total_mb(),
                        s.mean(),
                        s.mean_until(10.0),
                        s.at(5.0),
                        s.first_good().map_or("-".into(), |t| format!("{t:.0}")),
                    );
                    let k = usize::from(mbps < 4.0);
                    sum[k].0 += s.total_mb();
                    sum[k].1 += s.mean();
                    sum[k].2 += s.mean_until(10.0);
                    sum[k].3 += 1;
                }
                if name == "plant" && ti == 1 && mbps == 1.0 {
                    for (d, s) in DRAWINGS.iter().zip(&samples) {
                        plot_q.push((d.to_string(), s.ssim.clone()));
                        plot_b.push((d.to_string(), s.mb.clone()));
                    }
                }
                eprintln!("simulate: layers {name} {trace_name} {mbps} Mbps done");
            }
        }
    }
    let _ = writeln!(
        md,
        "\n| Mbps | drawing | mean MB per session | mean SSIM | mean SSIM, first 10 s |\n|---:|---|---:|---:|---:|"
    );
    for (k, mbps) in MBPS.iter().enumerate() {
        for (d, s) in DRAWINGS.iter().zip(&sums) {
            let (mb, q, q10, n) = s[k];
            let n = n.max(1) as f64;
            let _ = writeln!(
                md,
                "| {mbps} | {d} | {:.2} | {:.4} | {:.4} |",
                mb / n,
                q / n,
                q10 / n
            );
        }
    }
    write_time_plots(
        &args.plots,
        "layers",
        "plant, walk 1, 1 Mbps",
        "SSIM of the drawn set vs the full Best cut",
        &plot_q,
        &plot_b,
    )?;
    md.push_str(
        "\nPlots: `docs/layers_quality.svg` (SSIM over time), `docs/layers_bytes.svg` (bytes over time).\n\n",
    );
    Ok(md)
}
