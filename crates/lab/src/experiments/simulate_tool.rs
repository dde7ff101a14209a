//! `simulate --tileset DIR|URL --trace CAMERA.csv`: the shipped client on a user's tileset, camera
//! path, network, predictor, planner and budget, reported as `report.md`, `report.json` and plots.
//!
//! The numbers are those of the city experiment (`sim::report`), against the needed cut of the
//! client's viewport at every trace tick; `spec/camera-trace.md` defines them and the trace
//! formats. An `http://` tileset is mirrored first (`sim::mirror`, into `REPORT_DIR/mirror`,
//! removed after the run), since the simulated transport reads local files.

use super::SimulateArgs;
use super::tool_args::parse_viewport;
use super::tool_args::{parse_bytes, parse_duration_s, parse_point, parse_rate_mbps};
pub use super::tool_report::{ToolInputs, ToolRun};
use crate::sim::mirror::mirror;
use crate::sim::network::read_log;
use crate::sim::report::{self, client_setup, known_predictor, session_numbers};
use crate::sim::score::{Ratio, Truth};
use crate::sim::session::run_session;
use crate::sim::summary::summarize;
use crate::sim::transport::NetModel;
use anyhow::{Context, bail};
use splat2tiles_stream::catalog::{Level, TileCatalog};
use splat2tiles_stream::client::{ClientConfig, Prefetch};
use splat2tiles_stream::eyenav::{MAX_FILE_BYTES, Placement, parse_session, read_bounded};
use splat2tiles_stream::plan::Planner;
use splat2tiles_stream::trace::Trace;
use splat2tiles_tiles::tiling::TileKey;
use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Reads a camera path: the splat2tiles-trace v1 CSV, or an EyeNavGS CSV (`t_s,x,y,z,qx,qy,qz,qw`)
/// placed by `pl`.
pub fn read_trace(path: &Path, pl: &Placement) -> anyhow::Result<Trace> {
    let text = read_bounded(path, MAX_FILE_BYTES).map_err(anyhow::Error::msg)?;
    let name = path.display().to_string();
    let first = text.lines().map(str::trim).find(|l| !l.is_empty());
    let eyenav = first.is_some_and(|l| l.trim_start_matches('\u{feff}').starts_with("t_s,"));
    let trace = if eyenav {
        let s = parse_session(&text, &name, "scene", "user").map_err(anyhow::Error::msg)?;
        if s.samples.is_empty() {
            bail!("{name}: no samples");
        }
        s.place(pl, "scene", "user")
    } else {
        Trace::from_csv(&text).map_err(|e| anyhow::anyhow!("{name}: {e}"))?
    };
    if trace.poses.is_empty() {
        bail!("{name}: no poses");
    }
    Ok(trace)
}

/// The link of `--network LOG` (looped to the trace's end) or `--bandwidth`, with `--rtt`.
fn network(args: &SimulateArgs, until_s: f64) -> anyhow::Result<(NetModel, String)> {
    let rtt = parse_duration_s(&args.rtt, "--rtt").map_err(anyhow::Error::msg)?;
    if let Some(log) = &args.network {
        let tr = read_log(log, 1.0).map_err(anyhow::Error::msg)?;
        let mut m = NetModel::constant(1.0, rtt);
        m.bandwidth = tr.looped(until_s + 1.0);
        let desc = format!(
            "log `{}` (mean {:.2} Mbit/s, looped), RTT {:.0} ms",
            log.display(),
            tr.mean_bytes_per_s() * 8.0 / 1e6,
            rtt * 1e3
        );
        return Ok((m, desc));
    }
    let mbps = parse_rate_mbps(&args.bandwidth, "--bandwidth").map_err(anyhow::Error::msg)?;
    let desc = format!("constant {mbps} Mbit/s, RTT {:.0} ms", rtt * 1e3);
    Ok((NetModel::constant(mbps, rtt), desc))
}

/// The EyeNavGS placement the options give; a NaN anchor stands for the default one.
fn placement(args: &SimulateArgs) -> anyhow::Result<Placement> {
    let anchor = match &args.anchor {
        Some(a) => parse_point(a, "--anchor").map_err(anyhow::Error::msg)?,
        None => glam::DVec3::NAN,
    };
    if !(args.h_scale.is_finite() && args.h_scale > 0.0) {
        bail!("--h-scale {}: must be a positive number", args.h_scale);
    }
    if !args.heading.is_finite() || !args.eye_height.is_finite() {
        bail!("--heading and --eye-height must be finite numbers");
    }
    Ok(Placement {
        anchor,
        heading_deg: args.heading,
        h_scale: args.h_scale,
        eye_height_m: args.eye_height,
    })
}

/// Resolves the options into inputs; `dir` is the local tileset folder (a mirror for a URL).
pub fn inputs(args: &SimulateArgs, source: &str, dir: &Path) -> anyhow::Result<ToolInputs> {
    let tileset_json = dir.join("tileset.json");
    let ts = splat2tiles_tiles::tiling::load::load_tileset(&tileset_json)
        .with_context(|| format!("tileset {source}"))?;
    let bounds = TileCatalog::from_loaded(&ts.tiles, |_| Some(1)).bounds();
    let trace_file = args
        .trace
        .clone()
        .context("--trace FILE is needed with --tileset")?;
    let mut pl = placement(args)?;
    if pl.anchor.is_nan() {
        let (lo, hi) = bounds;
        pl.anchor = glam::DVec3::new(0.5 * (lo.x + hi.x), 0.5 * (lo.y + hi.y), lo.z);
    }
    let trace = read_trace(&trace_file, &pl)?;
    let (net, net_desc) = network(args, trace.poses.last().map_or(0.0, |p| p.t))?;
    if !known_predictor(&args.predictor) {
        bail!(
            "--predictor '{}': expected reactive, constant-velocity, linear, tcn, learned or oracle",
            args.predictor
        );
    }
    let planner = Planner::from_name(&args.planner).with_context(|| {
        format!(
            "--planner '{}': expected dc-dp, greedy-deadline, greedy-quality or distance-based",
            args.planner
        )
    })?;
    let budget = parse_bytes(&args.budget, "--budget").map_err(anyhow::Error::msg)?;
    let (width, height) =
        parse_viewport(&args.viewport, "--viewport").map_err(anyhow::Error::msg)?;
    if !(1..=64).contains(&args.max_concurrent) {
        bail!("--max-concurrent {}: must be 1..=64", args.max_concurrent);
    }
    if !(args.quality_hz.is_finite() && (0.0..=60.0).contains(&args.quality_hz)) {
        bail!("--quality-hz {}: must be 0..=60", args.quality_hz);
    }
    let prefetch = Prefetch::from_name(&args.prefetch).with_context(|| {
        format!(
            "--prefetch '{}': expected thrifty, balanced, eager or seconds ahead (e.g. 2.5)",
            args.prefetch
        )
    })?;
    let base = ClientConfig {
        width,
        height,
        max_concurrent: args.max_concurrent,
        prefetch,
        ..ClientConfig::default()
    };
    Ok(ToolInputs {
        dir: dir.to_path_buf(),
        source: source.to_string(),
        trace,
        trace_file,
        net,
        net_desc,
        predictor: args.predictor.clone(),
        prefetch: args.prefetch.clone(),
        planner,
        budget,
        base,
        quality_hz: args.quality_hz,
    })
}

/// Low bytes per tile from the subtrees' content tables (0 when a tileset has no variants).
fn low_bytes(dir: &Path) -> anyhow::Result<HashMap<TileKey, u64>> {
    let ts = splat2tiles_tiles::tiling::load::load_tileset(&dir.join("tileset.json"))?;
    Ok(splat2tiles_tiles::variants::content_variant_metadata(&ts)
        .into_iter()
        .map(|(k, (_, b, _))| (k, b[Level::Low.index()] as u64))
        .collect())
}

/// Runs the client on the inputs and scores it.
pub fn simulate(inp: ToolInputs) -> anyhow::Result<ToolRun> {
    let mut truth = Truth::load(&inp.dir.join("tileset.json"))?;
    let poses = &inp.trace.poses;
    let (cfg, opts) = client_setup(
        inp.base.clone(),
        poses,
        &inp.predictor,
        inp.planner,
        inp.budget,
    );
    let needed = report::needed_cuts(&truth, &cfg, poses);
    let log = run_session(&inp.dir, cfg, poses, &inp.net, opts);
    let numbers = session_numbers(&log, &needed, &low_bytes(&inp.dir)?, &inp.net);
    let own = summarize(&log);
    let mut quality = vec![];
    let mut tgq = None;
    if inp.quality_hz > 0.0 {
        let mut refs = HashMap::new();
        let t0 = log.ticks.first().map_or(0.0, |t| t.t);
        let mut next = t0;
        for k in 0..log.ticks.len() {
            if log.ticks[k].t + 1e-9 >= next {
                next += 1.0 / inp.quality_hz;
                let q = report::quality(&mut truth, &needed, &mut refs, &log, k)?;
                quality.push((log.ticks[k].t - t0, q));
            }
        }
        let (cold, later, _) = report::tgq(&mut truth, &needed, &mut refs, &log)?;
        tgq = Some((cold, later));
    }
    let mut run = ToolRun {
        inputs: inp,
        log,
        numbers,
        own,
        quality,
        tgq,
        summary: String::new(),
    };
    run.summary = summary_lines(&run);
    Ok(run)
}

fn pct(r: Ratio) -> String {
    match r.rate() {
        Some(x) => format!("{:.1}% ({}/{})", 100.0 * x, r.hits, r.n),
        None => "- (0/0)".into(),
    }
}

fn tgq_text(v: &[Option<f64>]) -> String {
    match report::tgq_mean(v) {
        None => "- (0 events)".into(),
        Some((mean, missed)) => format!(
            "{mean:.2} s ({} events, {missed} not reached within {} s)",
            v.len(),
            report::TGQ_WINDOW_S
        ),
    }
}

fn summary_lines(run: &ToolRun) -> String {
    let n = &run.numbers;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{} on {} ({}, {} planner, {:.1} s of trace)",
        run.inputs.predictor,
        run.inputs.source,
        run.inputs.net_desc,
        run.inputs.planner.name(),
        run.inputs.trace.duration()
    );
    let _ = writeln!(
        s,
        "CHR first-time {}, after warm-up {}, re-entries {}",
        pct(n.chr.first),
        pct(n.chr.warm),
        pct(n.chr.reentry)
    );
    let _ = writeln!(
        s,
        "received {:.2} MB, wasted {:.2} MB, {} stalled ticks of {}, {} evictions",
        n.bytes_down as f64 / 1e6,
        n.waste.wasted_bytes as f64 / 1e6,
        n.stall_ticks,
        run.log.ticks.len(),
        n.evictions
    );
    if let Some((cold, later)) = &run.tgq {
        let cold = cold.map_or(
            format!("not reached within {} s", report::TGQ_WINDOW_S),
            |x| format!("{x:.2} s"),
        );
        let _ = writeln!(s, "TGQ {}; cold start {cold}", tgq_text(later));
    }
    s
}

/// Runs the tool for `args` (`--tileset` given) and writes the report into `--report-dir`.
pub fn run_tool(args: &SimulateArgs) -> anyhow::Result<ToolRun> {
    let source = args
        .tileset
        .clone()
        .context("--tileset DIR|URL is needed")?;
    std::fs::create_dir_all(&args.report_dir)
        .with_context(|| format!("--report-dir {}", args.report_dir.display()))?;
    let remote = source.starts_with("http://") || source.starts_with("https://");
    let dir = if remote {
        // The simulated transport reads files: copy the tileset next to the report first.
        let dir = args.report_dir.join("mirror");
        if dir.exists() {
            std::fs::remove_dir_all(&dir).with_context(|| dir.display().to_string())?;
        }
        mirror(&source, &dir).with_context(|| format!("--tileset {source}"))?;
        dir
    } else {
        let p = PathBuf::from(&source);
        if p.is_file() {
            p.parent().map(Path::to_path_buf).unwrap_or_default()
        } else {
            p
        }
    };
    let run = simulate(inputs(args, &source, &dir)?);
    if remote {
        // The mirror was only for this run (keep the report folder small).
        let _ = std::fs::remove_dir_all(&dir);
    }
    let run = run?;
    super::tool_report::write(&run, &args.report_dir)?;
    Ok(run)
}
