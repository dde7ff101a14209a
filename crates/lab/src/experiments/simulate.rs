//! `splat2tiles-lab simulate`: the streaming experiments side by side with the papers (TileSplat
//! Tables 4-5, SGSS Table 3, frustum-test false positives), trace generation, and their tables
//! (markdown) and plots (SVG). Deterministic for a fixed `--seed`.

use crate::sim::session::{SessionLog, SessionOptions, TickLog, run_session};
use crate::sim::summary::{Summary, summarize};
use crate::sim::svg::{Series, write_time_plots};
use crate::sim::transport::NetModel;
use anyhow::Context;
use glam::{DMat4, DVec3};
use splat2tiles_core::rng::SplitMix64;
use splat2tiles_core::splat::Splats;
use splat2tiles_render::{Camera, Image, RenderOptions, render, ssim};
use splat2tiles_stream::catalog::{Level, TileCatalog};
use splat2tiles_stream::client::{ClientConfig, PredictorKind};
use splat2tiles_stream::geom::{Frustum, Intrinsics, ViewPose};
use splat2tiles_stream::plan::{Candidate, PlanRequest, Planner, execute};
use splat2tiles_stream::predict::Oracle;
use splat2tiles_stream::trace::{self, Trace};
use splat2tiles_stream::visibility::VisTest;
use splat2tiles_tiles::tiling::TileKey;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

pub use super::SimulateArgs;

/// A tiled real scene ready for simulation.
struct Scene {
    name: String,
    /// The tileset folder the client streams.
    dir: PathBuf,
    /// Tileset frame to world.
    root: DMat4,
    cat: TileCatalog,
    /// Per content tile: the decoded content of each variant (Best, High, Medium, Low).
    content: BTreeMap<TileKey, Vec<(Splats, DMat4)>>,
}

fn load_scene(file: &Path, work: &Path, max_splats: u32) -> anyhow::Result<Scene> {
    let name = file
        .file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or("scene")
        .split('_')
        .next()
        .unwrap_or("scene")
        .to_string();
    let out = work.join(format!("tiles_{name}"));
    // All four variants, with measured sizes and utilities, for the planner to choose from.
    let opts = splat2tiles_build::convert::ConvertOptions {
        max_splats_per_tile: max_splats as usize,
        variants: splat2tiles_tiles::variants::VariantOptions {
            variants: splat2tiles_tiles::variants::ALL.to_vec(),
            ..Default::default()
        },
        ..Default::default()
    };
    splat2tiles_build::convert::convert(file, &out, &opts)
        .with_context(|| file.display().to_string())?;
    let ts = splat2tiles_tiles::tiling::load::load_tileset(&out.join("tileset.json"))?;
    let cat = TileCatalog::from_loaded(&ts.tiles, |t| {
        t.content
            .as_ref()
            .and_then(|p| std::fs::metadata(p).ok())
            .map(|m| m.len())
    })
    .with_measured(
        &splat2tiles_tiles::variants::content_variant_metadata(&ts)
            .into_iter()
            .map(|(k, (_, bytes, util))| (k, (bytes, util)))
            .collect(),
    );
    let mut content = BTreeMap::new();
    for t in &cat.tiles {
        let lt = ts
            .tiles
            .iter()
            .find(|l| l.key == t.key)
            .expect("same tiles");
        if let (Some(_), true) = (&lt.content, t.has_content) {
            {
                let mut per_variant = Vec::with_capacity(splat2tiles_tiles::variants::ALL.len());
                for v in splat2tiles_tiles::variants::ALL {
                    let p = ts.dir.join(splat2tiles_tiles::variants::content_uri(
                        ts.scheme, t.key, v,
                    ));
                    let bytes = std::fs::read(&p).with_context(|| p.display().to_string())?;
                    let (splats, node) = splat2tiles_tiles::variants::decode_variant(&bytes)
                        .with_context(|| p.display().to_string())?;
                    let m = splat2tiles_tiles::geometry::content_model(&ts, &node);
                    per_variant.push((splats, m));
                }
                content.insert(t.key, per_variant);
            }
        }
    }
    Ok(Scene {
        name,
        dir: out,
        root: ts.root_transform,
        cat,
        content,
    })
}

/// SSIM render size: a quarter of the client's 1280x720 viewport per side.
const W: u32 = 320;
const H: u32 = 180;

/// The render camera of a pose (tileset frame) at `W` x `H`, the client's field of view.
fn camera(s: &Scene, p: &ViewPose) -> Camera {
    Camera::from_pose(W, H, 50.0, s.root * p.world_from_camera())
}

/// Renders `tiles`, each with the content of the level it names.
fn render_tiles(s: &Scene, p: &ViewPose, tiles: impl Iterator<Item = (TileKey, Level)>) -> Image {
    let inst: Vec<(&Splats, DMat4)> = tiles
        .filter_map(|(k, l)| {
            let (splats, m) = s.content.get(&k)?.get(l.index())?;
            Some((splats, *m))
        })
        .collect();
    render(&inst, &camera(s, p), &RenderOptions::default())
}

/// SSIM of what the client drew at a tick against its view set fully resident at Best (None
/// before the client has a view set: nothing to compare, not a perfect frame).
fn tick_ssim(s: &Scene, t: &TickLog) -> Option<f64> {
    if t.view_set.is_empty() {
        return None;
    }
    let drawn = render_tiles(s, &t.pose, t.drawn.iter().map(|d| (d.0, d.1)));
    let best = render_tiles(s, &t.pose, t.view_set.iter().map(|k| (*k, Level::Best)));
    ssim(&drawn, &best).ok()
}

fn mbps(b: f64) -> f64 {
    b * 1e6 / 8.0
}

/// Runs `simulate`.
pub fn run(args: &SimulateArgs) -> anyhow::Result<()> {
    std::fs::create_dir_all(&args.out)?;
    std::fs::create_dir_all(&args.plots)?;
    let all = args.experiment == "all";
    let want = |e: &str| all || args.experiment == e;
    let mut md = String::new();
    let needs_scenes = want("table5") || want("table4") || want("dolly") || want("traces");
    let mut scenes = vec![];
    if needs_scenes {
        for f in ["plant.splat", "donut_fused_sh0.ply", "biker.spz"] {
            let t0 = Instant::now();
            let s = load_scene(&args.scenes.join(f), &args.out, args.max_splats)?;
            eprintln!(
                "simulate: {} -> {} content tiles, {:.1} MB (Best) in {:.1} s",
                f,
                s.cat.content_tiles().count(),
                s.cat.total_bytes(Level::Best) as f64 / 1e6,
                t0.elapsed().as_secs_f64()
            );
            scenes.push(s);
        }
    }
    if want("table5") {
        md.push_str(&table5(args.seed, &scenes));
    }
    if want("table4") {
        md.push_str(&table4(args, &scenes)?);
    }
    if want("dolly") {
        md.push_str(&dolly_table(args.seed, &scenes));
    }
    if want("visibility") {
        md.push_str(&visibility_table(args.seed));
    }
    if want("traces") {
        write_traces(args, &scenes)?;
    }
    if args.experiment == "city" {
        md.push_str(&super::simulate_city::city(args)?);
    }
    if args.experiment == "thrift" {
        md.push_str(&super::simulate_thrift::thrift(args)?);
    }
    if args.experiment == "layers" {
        md.push_str(&super::simulate_layers::layers(args)?);
    }
    let path = args.out.join("streaming.md");
    std::fs::write(&path, &md)?;
    print!("{md}");
    eprintln!("simulate: tables -> {}", path.display());
    Ok(())
}

/// TileSplat Table 5: planners on 30-tile instances at several bandwidths.
fn table5(seed: u64, scenes: &[Scene]) -> String {
    let mut md = String::new();
    let instances = 20;
    let synthetic = |s: u64| TileCatalog::synthetic(30, (2.0, 6.0), s);
    let pool: Vec<(usize, usize)> = scenes
        .iter()
        .enumerate()
        .flat_map(|(si, s)| s.cat.content_tiles().map(move |i| (si, i)))
        .collect();
    let real = |s: u64| {
        let mut rng = SplitMix64::new(s);
        let mut tiles = vec![];
        for _ in 0..30 {
            let (si, i) = pool[rng.below(pool.len())];
            let mut t = scenes[si].cat.tiles[i].clone();
            t.parent = None;
            t.children.clear();
            tiles.push(t);
        }
        TileCatalog {
            roots: (0..tiles.len()).collect(),
            tiles,
            source: scenes[0].cat.source,
        }
    };
    type MakeCat<'a> = Box<dyn Fn(u64) -> TileCatalog + 'a>;
    let settings: Vec<(&str, MakeCat, Vec<f64>)> = vec![
        (
            "synthetic (paper setting: 30 tiles, Best 2-6 MB: the paper's implied 4 MB mean, 120 MB / 30 tiles from its Util/MB; deadlines U(5,30) s, 4 levels)",
            Box::new(synthetic),
            vec![100.0, 50.0, 10.0],
        ),
        (
            "real tile sizes and measured variant utilities (30 tiles drawn from the 3 shared scenes at 4096 splats/tile)",
            Box::new(real),
            vec![100.0, 10.0, 1.0, 0.5, 0.25],
        ),
    ];
    let _ = writeln!(
        md,
        "### TileSplat Table 5: quality selection under deadlines\n\nMean of {instances} random instances per row (seed {seed}). Plans are executed over the same constant link (no latency): a tile counts only if complete by its deadline; Miss = tiles not complete by their deadline (late or skipped); Util/MB = on-time utility per MB downloaded; Time = one solve (this machine, release, mean).\n"
    );
    for (label, make, bws) in &settings {
        let _ = writeln!(
            md,
            "{label}:\n\n| bandwidth | method | utility | avg quality | miss % | util/MB | time (ms) |\n|---|---|---:|---:|---:|---:|---:|"
        );
        for &bw in bws {
            for planner in Planner::ALL {
                let (mut u, mut miss, mut mb, mut ms) = (0.0, 0.0, 0.0, 0.0);
                for k in 0..instances {
                    let s = seed.wrapping_mul(1000).wrapping_add(k);
                    let cat = make(s);
                    let mut rng = SplitMix64::new(s ^ 0xDEAD);
                    let cands: Vec<Candidate> = cat
                        .tiles
                        .iter()
                        .enumerate()
                        .map(|(i, t)| Candidate {
                            tile: i,
                            deadline: rng.range(5.0, 30.0),
                            distance: t.bbox.distance(DVec3::ZERO),
                            variants: t.variants,
                        })
                        .collect();
                    let link = [mbps(bw)];
                    let req = PlanRequest {
                        candidates: &cands,
                        bandwidth: &link,
                        step_s: 0.1,
                        horizon_steps: 300,
                        memory_budget: u64::MAX,
                        latency_s: 0.0,
                        bins: 0,
                    };
                    let reps = 5;
                    let t0 = Instant::now();
                    let mut plan = planner.solve(&req);
                    for _ in 1..reps {
                        plan = std::hint::black_box(planner.solve(&req));
                    }
                    ms += t0.elapsed().as_secs_f64() * 1e3 / reps as f64;
                    let o = execute(&req, &plan, &link);
                    u += o.utility;
                    miss += o.misses as f64 / cands.len() as f64;
                    mb += if o.bytes > 0 {
                        o.utility / (o.bytes as f64 / 1e6)
                    } else {
                        0.0
                    };
                }
                let n = instances as f64;
                let _ = writeln!(
                    md,
                    "| {bw} Mbps | {} | {:.2} | {:.3} | {:.1} | {:.4} | {:.3} |",
                    planner.name(),
                    u / n,
                    u / n / 30.0,
                    100.0 * miss / n,
                    mb / n,
                    ms / n
                );
            }
        }
        md.push('\n');
    }
    md
}

fn scene_traces(s: &Scene, seed: u64) -> Vec<Trace> {
    let (lo, hi) = s.cat.bounds();
    let diag = (hi - lo).truncate().length();
    let c = (lo + hi) * 0.5;
    vec![
        trace::orbital(&s.name, lo, hi, seed, "test"),
        trace::walk(&s.name, lo, hi, c.z, 0.08 * diag, 60.0, seed, "test"),
        trace::walk(&s.name, lo, hi, c.z, 0.08 * diag, 60.0, seed + 1, "test"),
    ]
}

/// Client settings of the experiments: 1280x720 at 50 degrees, 4 requests in flight, the
/// App. C.5 fallback within 0.3 x the scene's diagonal.
fn client_config(s: &Scene, predictor: PredictorKind) -> ClientConfig {
    let (lo, hi) = s.cat.bounds();
    ClientConfig {
        max_concurrent: 4,
        predictor,
        fallback_radius_m: 0.3 * (hi - lo).length(),
        ..ClientConfig::default()
    }
}

/// The predictors compared: the client's five kinds and the oracle of the trace.
const PREDICTORS: [&str; 6] = [
    "reactive",
    "constant-velocity",
    "linear",
    "tcn",
    "learned",
    "oracle",
];

/// One session of `predictor` (a [`PREDICTORS`] name) on `tr` over `net`.
fn session(s: &Scene, tr: &Trace, predictor: &str, net: &NetModel) -> SessionLog {
    let (kind, oracle) = match PredictorKind::from_name(predictor) {
        Some(kind) => (kind, false),
        None => (PredictorKind::Reactive, true),
    };
    let opts = SessionOptions {
        predictor: oracle.then(|| {
            Box::new(Oracle {
                trace: tr.poses.clone(),
            }) as Box<dyn splat2tiles_stream::predict::Predictor + Send>
        }),
        record_inputs: false,
    };
    run_session(&s.dir, client_config(s, kind), &tr.poses, net, opts)
}

/// One table row's inputs: a session, its summary and its SSIM samples `(t, ssim)` at 1 Hz.
struct Row {
    sum: Summary,
    ssim: Vec<(f64, f64)>,
    bytes: Vec<(f64, f64)>,
    aborts: u64,
    resumes: u64,
}

/// TileSplat Table 4: predictors driving the real client over the simulated link.
fn table4(args: &SimulateArgs, scenes: &[Scene]) -> anyhow::Result<String> {
    let bw = 4.0;
    let net = NetModel::constant(bw, 0.04);
    let mut md = String::new();
    let _ = writeln!(
        md,
        "### TileSplat Table 4: prediction in the client loop\n\nThe shipped client (`client::StreamClient`, 1280x720, 50 deg, 4 requests in flight, replan every 2.5 s, on a view-set change, a >20% speed change or an unwanted view tile; the App. C.5 fallback for every predictor: 5 s, radius 0.3 x scene diagonal, Medium) over the simulated transport: shared scenes tiled at {} splats/tile, {bw} Mbps, 40 ms RTT, 400 B/request, 16 KiB chunks; traces: SGSS orbital (80 s) + 2 walks (60 s) per scene, 12 Hz. CHR over first-time view-set entries after the first view (re-entries apart); WD = completed downloads whose tile is never in the view set afterwards; SSIM of the drawn tiles against the same view set at Best, {W}x{H}, 1 Hz (0 until the client has a view set); TGQ = first sample with SSIM >= 0.9, from the trace start. Mean over scenes and traces.\n\n| predictor | CHR | re-entry hits | TGQ (s) | WD (tiles) | WD (bytes) | mean SSIM | MB | aborts | resumes |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
        args.max_splats,
    );
    let mut rows: Vec<Vec<Row>> = (0..PREDICTORS.len()).map(|_| vec![]).collect();
    let mut plot_q: Vec<Series> = vec![];
    let mut plot_b: Vec<Series> = vec![];
    for s in scenes {
        for (ti, tr) in scene_traces(s, args.seed).iter().enumerate() {
            for (pi, name) in PREDICTORS.iter().enumerate() {
                let log = session(s, tr, name, &net);
                let t0 = tr.poses.first().map_or(0.0, |p| p.t);
                let mut next = t0;
                let mut ssim_s = vec![];
                let mut bytes_s = vec![];
                for t in &log.ticks {
                    if t.t + 1e-9 >= next {
                        next += 1.0;
                        ssim_s.push((t.t - t0, tick_ssim(s, t).unwrap_or(0.0)));
                        bytes_s.push((t.t - t0, t.bytes_down as f64 / 1e6));
                    }
                }
                if s.name == "plant" && ti == 1 {
                    plot_q.push((name.to_string(), ssim_s.clone()));
                    plot_b.push((name.to_string(), bytes_s.clone()));
                }
                rows[pi].push(Row {
                    sum: summarize(&log),
                    ssim: ssim_s,
                    bytes: bytes_s,
                    aborts: log.aborts,
                    resumes: log.resumes,
                });
            }
            eprintln!("simulate: table4 {} trace {ti} done", s.name);
        }
    }
    for (name, rs) in PREDICTORS.iter().zip(&rows) {
        let n = rs.len().max(1) as f64;
        let m = |f: &dyn Fn(&Row) -> f64| rs.iter().map(f).sum::<f64>() / n;
        let tgq: Vec<f64> = rs
            .iter()
            .filter_map(|r| r.ssim.iter().find(|q| q.1 >= 0.9).map(|q| q.0))
            .collect();
        let (re, re_hits) = rs.iter().fold((0, 0), |a, r| {
            (a.0 + r.sum.reentries, a.1 + r.sum.reentry_hits)
        });
        let _ = writeln!(
            md,
            "| {name} | {:.1}% | {} | {} | {:.1}% | {:.1}% | {:.3} | {:.2} | {:.1} | {:.1} |",
            100.0 * m(&|r| r.sum.chr()),
            if re == 0 {
                "-".to_string()
            } else {
                format!("{:.1}% of {re}", 100.0 * re_hits as f64 / re as f64)
            },
            if tgq.is_empty() {
                "-".to_string()
            } else {
                format!(
                    "{:.1}{}",
                    tgq.iter().sum::<f64>() / tgq.len() as f64,
                    if tgq.len() < rs.len() {
                        format!(" ({} of {} sessions)", tgq.len(), rs.len())
                    } else {
                        String::new()
                    }
                )
            },
            100.0 * m(&|r| r.sum.wd_tiles()),
            100.0 * m(&|r| r.sum.wd_bytes()),
            m(&|r| r.ssim.iter().map(|q| q.1).sum::<f64>() / r.ssim.len().max(1) as f64),
            m(&|r| r.bytes.last().map_or(0.0, |b| b.1)),
            m(&|r| r.aborts as f64),
            m(&|r| r.resumes as f64),
        );
    }
    write_time_plots(
        &args.plots,
        "stream",
        "plant, walk 1, 4 Mbps",
        "SSIM of the drawn tiles vs the view set at Best",
        &plot_q,
        &plot_b,
    )?;
    md.push_str("\nPlots: `docs/stream_quality.svg` (SSIM over time), `docs/stream_bytes.svg` (bytes over time).\n\n");
    Ok(md)
}

/// SGSS Table 3: bytes downloaded on dolly traces vs the full scene.
fn dolly_table(seed: u64, scenes: &[Scene]) -> String {
    let mut md = String::new();
    let _ = writeln!(
        md,
        "### SGSS Table 3: data downloaded on 20 s dolly traces (200 Mbps)\n\nFull = every tile at Best (the real content bytes). Streamed = body bytes the client received in 20 s over the simulated transport (40 ms RTT), per predictor.\n\n| scene | full download | reactive | linear | oracle |\n|---|---:|---:|---:|---:|"
    );
    let net = NetModel::constant(200.0, 0.04);
    for s in scenes {
        let (lo, hi) = s.cat.bounds();
        let tr = trace::dolly(&s.name, lo, hi, seed, "test");
        let full = s.cat.total_bytes(Level::Best) as f64 / 1e6;
        let mut cells = vec![];
        for p in ["reactive", "linear", "oracle"] {
            let log = session(s, &tr, p, &net);
            let mb = log.ticks.last().map_or(0, |t| t.bytes_down) as f64 / 1e6;
            cells.push(format!("{mb:.2} MB ({:+.1}%)", 100.0 * (mb / full - 1.0)));
        }
        let _ = writeln!(md, "| {} | {full:.2} MB | {} |", s.name, cells.join(" | "));
    }
    md.push('\n');
    md
}

/// False positives / negatives of the frustum tests against the exact SAT.
fn visibility_table(seed: u64) -> String {
    let mut rng = SplitMix64::new(seed);
    let k = Intrinsics {
        far: 300.0,
        ..Intrinsics::default()
    };
    let tests = [VisTest::Planes, VisTest::CornerAny, VisTest::Sgss];
    let mut fp = [0usize; 3];
    let mut fneg = [0usize; 3];
    let (mut pos, mut neg) = (0usize, 0usize);
    let mut ns = [0.0f64; 4];
    let n = 200_000;
    let boxes: Vec<splat2tiles_stream::geom::Obb> = (0..n)
        .map(|_| {
            let c = DVec3::new(
                rng.range(-150.0, 150.0),
                rng.range(-150.0, 150.0),
                rng.range(-5.0, 15.0),
            );
            let h = DVec3::new(
                rng.range(1.0, 20.0),
                rng.range(1.0, 20.0),
                rng.range(1.0, 10.0),
            );
            splat2tiles_stream::geom::Obb::aabb(c - h, c + h)
        })
        .collect();
    let poses: Vec<ViewPose> = (0..n)
        .map(|_| ViewPose {
            t: 0.0,
            pos: DVec3::new(rng.range(-50.0, 50.0), rng.range(-50.0, 50.0), 1.7),
            yaw: rng.range(-std::f64::consts::PI, std::f64::consts::PI),
            pitch: rng.range(-0.3, 0.3),
        })
        .collect();
    let frusta: Vec<Frustum> = poses.iter().map(|p| Frustum::new(p, &k)).collect();
    let t0 = Instant::now();
    let exact: Vec<bool> = (0..n)
        .map(|i| VisTest::Exact.visible(&frusta[i], &boxes[i]))
        .collect();
    ns[3] = t0.elapsed().as_secs_f64() * 1e9 / n as f64;
    for e in &exact {
        if *e { pos += 1 } else { neg += 1 }
    }
    for (ti, t) in tests.iter().enumerate() {
        let t0 = Instant::now();
        let v: Vec<bool> = (0..n).map(|i| t.visible(&frusta[i], &boxes[i])).collect();
        ns[ti] = t0.elapsed().as_secs_f64() * 1e9 / n as f64;
        for i in 0..n {
            match (v[i], exact[i]) {
                (true, false) => fp[ti] += 1,
                (false, true) => fneg[ti] += 1,
                _ => {}
            }
        }
    }
    let mut md = String::new();
    let _ = writeln!(
        md,
        "### Frustum tests against the exact SAT\n\n{n} random (pose, box) pairs (seed {seed}; boxes 2-40 m within 150 m, eye height 1.7 m, 50 deg fov, 16:9, far 300 m); {pos} truly visible, {neg} not.\n\n| test | false positives (% of invisible) | false negatives (% of visible) | ns/test |\n|---|---:|---:|---:|"
    );
    for (ti, t) in tests.iter().enumerate() {
        let _ = writeln!(
            md,
            "| {} | {:.2}% | {:.2}% | {:.0} |",
            t.name(),
            100.0 * fp[ti] as f64 / neg.max(1) as f64,
            100.0 * fneg[ti] as f64 / pos.max(1) as f64,
            ns[ti]
        );
    }
    let _ = writeln!(md, "| exact SAT | 0 | 0 | {:.0} |\n", ns[3]);
    md
}

/// Writes the committed traces and the split file.
fn write_traces(args: &SimulateArgs, scenes: &[Scene]) -> anyhow::Result<()> {
    std::fs::create_dir_all(&args.traces)?;
    let mut split =
        String::from("# trace file, split (train: predictors may learn from it; test: never)\n");
    let mut save = |t: &Trace, file: &str| -> anyhow::Result<()> {
        std::fs::write(args.traces.join(file), t.to_csv())?;
        let _ = writeln!(split, "{file},{}", t.header("split").unwrap_or("test"));
        Ok(())
    };
    for s in scenes {
        let (lo, hi) = s.cat.bounds();
        let diag = (hi - lo).truncate().length();
        let c = (lo + hi) * 0.5;
        // Split by scene: biker is held out entirely; plant and donut walks train.
        let sp = if s.name == "biker" { "test" } else { "train" };
        save(
            &trace::orbital(&s.name, lo, hi, args.seed, "test"),
            &format!("{}_orbital.csv", s.name),
        )?;
        save(
            &trace::dolly(&s.name, lo, hi, args.seed, "test"),
            &format!("{}_dolly.csv", s.name),
        )?;
        for w in 0..2 {
            save(
                &trace::walk(&s.name, lo, hi, c.z, 0.08 * diag, 60.0, args.seed + w, sp),
                &format!("{}_walk{}.csv", s.name, w + 1),
            )?;
        }
    }
    // City: 20 x 20 displaced copies of plant's tiles, 30 m apart, in the ENU frame at --origin.
    let city = scenes[0].cat.tiled_copies(400, 30.0);
    let (lo, hi) = city.bounds();
    for w in 0..2u64 {
        let mut t = trace::walk(
            "city",
            lo,
            hi,
            1.7 + lo.z,
            1.4,
            120.0,
            args.seed + 10 + w,
            if w == 0 { "train" } else { "test" },
        );
        t.headers.push(("origin".into(), args.origin.clone()));
        save(&t, &format!("city_walk{}.csv", w + 1))?;
    }
    std::fs::write(args.traces.join("split.csv"), split)?;
    eprintln!("simulate: traces -> {}", args.traces.display());
    Ok(())
}
