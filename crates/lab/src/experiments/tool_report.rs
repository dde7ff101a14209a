//! The report of `simulate --tileset`: `report.json` (inputs and results), `report.md` (the same
//! as tables, with the metric definitions of `spec/camera-trace.md`) and SVG plots over time.

use crate::sim::report::{GOOD, QH, QW, SessionNumbers, TGQ_HZ, TGQ_WINDOW_S};
use crate::sim::score::Ratio;
use crate::sim::session::SessionLog;
use crate::sim::summary::Summary;
use crate::sim::svg::line_chart;
use crate::sim::transport::NetModel;
use anyhow::Context;
use serde_json::{Value, json};
use splat2tiles_stream::client::ClientConfig;
use splat2tiles_stream::plan::Planner;
use splat2tiles_stream::trace::Trace;
use std::fmt::Write as _;
use std::path::Path;
use std::path::PathBuf;

/// Everything a tool run reads, resolved from the options.
#[derive(Debug)]
pub struct ToolInputs {
    /// Local tileset folder simulated (the mirror for a URL).
    pub dir: PathBuf,
    /// The tileset as the user named it (folder or URL).
    pub source: String,
    /// The camera path.
    pub trace: Trace,
    /// The trace file.
    pub trace_file: PathBuf,
    /// The link.
    pub net: NetModel,
    /// How the link was given (for the report).
    pub net_desc: String,
    /// Predictor name (`PredictorKind::from_name` or an oracle).
    pub predictor: String,
    /// Prefetch setting as given (`Prefetch::from_name`).
    pub prefetch: String,
    /// Planner.
    pub planner: Planner,
    /// Client memory budget, bytes.
    pub budget: u64,
    /// The client before predictor, planner and budget (viewport, requests in flight).
    pub base: ClientConfig,
    /// Quality samples per second (0: no rendering).
    pub quality_hz: f64,
}

/// What a tool run produced.
#[derive(Debug)]
pub struct ToolRun {
    /// The inputs.
    pub inputs: ToolInputs,
    /// The session.
    pub log: SessionLog,
    /// Its numbers against the needed cuts.
    pub numbers: SessionNumbers,
    /// Against the client's own view sets (`sim::summary`).
    pub own: Summary,
    /// Quality over time `(s, SSIM)` (empty without rendering).
    pub quality: Vec<(f64, f64)>,
    /// TGQ: cold start and later events (`None`: not reached), when quality is rendered.
    pub tgq: Option<(Option<f64>, Vec<Option<f64>>)>,
    /// A few lines for the terminal.
    pub summary: String,
}

/// Version of `report.json`'s layout.
pub const REPORT_VERSION: u32 = 1;

fn ratio(r: Ratio) -> Value {
    json!({ "hits": r.hits, "entries": r.n, "rate": r.rate() })
}

fn tgq_json(v: &[Option<f64>]) -> Value {
    let reached: Vec<f64> = v.iter().flatten().copied().collect();
    let sum: f64 = v.iter().map(|x| x.unwrap_or(TGQ_WINDOW_S)).sum();
    json!({
        "events": v.len(),
        "not_reached": v.len() - reached.len(),
        "mean_s": (!v.is_empty()).then(|| sum / v.len() as f64),
        "per_event_s": v,
    })
}

/// The results part of `report.json` (what the client did and how it scored; no file names).
pub fn results_json(run: &ToolRun) -> Value {
    let n = &run.numbers;
    let o = &run.own;
    let t0 = run.log.ticks.first().map_or(0.0, |t| t.t);
    let bytes: Vec<[f64; 2]> = run
        .log
        .ticks
        .iter()
        .map(|t| [t.t - t0, t.bytes_down as f64])
        .collect();
    let quality: Vec<[f64; 2]> = run.quality.iter().map(|&(t, q)| [t, q]).collect();
    json!({
        "ticks": run.log.ticks.len(),
        "chr": {
            "first_time": ratio(n.chr.first),
            "after_warm_up": ratio(n.chr.warm),
            "cold_start": ratio(n.chr.initial),
            "reentries": ratio(n.chr.reentry),
            "warm_up_end_s": n.warm_at.is_finite().then_some(n.warm_at),
        },
        "chr_client_view_sets": {
            "first_time": json!({ "hits": o.hits, "entries": o.entries, "rate": o.chr() }),
            "reentries": json!({ "hits": o.reentry_hits, "entries": o.reentries }),
            "cold_start_tiles": o.first_view_tiles,
        },
        "tgq": run.tgq.as_ref().map(|(cold, later)| json!({
            "events": tgq_json(later),
            "cold_start_s": cold,
        })),
        "waste": {
            "downloads": n.waste.tiles,
            "download_bytes": n.waste.bytes,
            "wasted_tiles": n.waste.wasted_tiles,
            "wasted_bytes": n.waste.wasted_bytes,
        },
        "stall_ticks": n.stall_ticks,
        "evictions": n.evictions,
        "bytes_received": n.bytes_down,
        "requests": run.log.requests.len(),
        "errors": run.log.errors,
        "bytes_over_time": bytes,
        "quality_over_time": quality,
    })
}

/// The whole `report.json`.
pub fn report_json(run: &ToolRun) -> Value {
    let i = &run.inputs;
    json!({
        "splat2tiles-simulate-report": REPORT_VERSION,
        "inputs": {
            "tileset": i.source,
            "trace": i.trace_file.display().to_string(),
            "trace_duration_s": i.trace.duration(),
            "network": i.net_desc,
            "predictor": i.predictor,
            "prefetch": i.prefetch,
            "planner": i.planner.name(),
            "budget_bytes": i.budget,
            "viewport": [i.base.width, i.base.height],
            "fov_y_deg": i.base.fov_y_deg,
            "max_sse": i.base.max_sse,
            "max_concurrent": i.base.max_concurrent,
            "quality_hz": i.quality_hz,
        },
        "results": results_json(run),
    })
}

fn pct(r: Ratio) -> String {
    match r.rate() {
        Some(x) => format!("{:.1}% ({}/{})", 100.0 * x, r.hits, r.n),
        None => "- (no entries)".into(),
    }
}

/// `report.md`.
pub fn report_md(run: &ToolRun) -> String {
    let (i, n, o) = (&run.inputs, &run.numbers, &run.own);
    let mut md = String::new();
    let _ = writeln!(
        md,
        "# Streaming simulation\n\nTileset `{}`; trace `{}` ({:.1} s, {} ticks); network {}; predictor {}; prefetch {}; planner {}; memory budget {:.1} MiB; viewport {}x{}, {} deg, SSE {}; {} requests in flight. Metric definitions: `spec/camera-trace.md`.\n",
        i.source,
        i.trace_file.display(),
        i.trace.duration(),
        run.log.ticks.len(),
        i.net_desc,
        i.predictor,
        i.prefetch,
        i.planner.name(),
        i.budget as f64 / (1u64 << 20) as f64,
        i.base.width,
        i.base.height,
        i.base.fov_y_deg,
        i.base.max_sse,
        i.base.max_concurrent
    );
    let warm = if n.warm_at.is_finite() {
        format!("{:.2} s", n.warm_at)
    } else {
        "never (no needed cut)".into()
    };
    let _ = writeln!(
        md,
        "| metric | value |\n|---|---:|\n| CHR, first-time entries into the needed cut | {} |\n| CHR after warm-up (ends at {warm}) | {} |\n| CHR, cold start (first non-empty cut) | {} |\n| CHR, re-entries | {} |\n| CHR, first-time entries into the client's own view sets | {} |",
        pct(n.chr.first),
        pct(n.chr.warm),
        pct(n.chr.initial),
        pct(n.chr.reentry),
        pct(Ratio {
            hits: o.hits as u64,
            n: o.entries as u64
        })
    );
    if let Some((cold, later)) = &run.tgq {
        let v = tgq_json(later);
        let _ = writeln!(
            md,
            "| TGQ, mean over {} new-region events (s; {} not reached within {TGQ_WINDOW_S} s count as {TGQ_WINDOW_S}) | {} |\n| TGQ, cold start (s) | {} |",
            v["events"],
            v["not_reached"],
            v["mean_s"]
                .as_f64()
                .map_or("-".into(), |x| format!("{x:.2}")),
            cold.map_or(format!("not reached within {TGQ_WINDOW_S} s"), |x| format!(
                "{x:.2}"
            ))
        );
    }
    let _ = writeln!(
        md,
        "| wasted downloads, tiles | {} of {} ({}) |\n| wasted downloads, bytes | {:.2} MB of {:.2} MB ({}) |\n| stalled ticks | {} of {} |\n| evictions | {} |\n| received | {:.2} MB |\n| requests | {} ({} errors) |",
        n.waste.wasted_tiles,
        n.waste.tiles,
        crate::sim::report::percent(n.waste.wasted_tiles, n.waste.tiles),
        n.waste.wasted_bytes as f64 / 1e6,
        n.waste.bytes as f64 / 1e6,
        crate::sim::report::percent(n.waste.wasted_bytes, n.waste.bytes),
        n.stall_ticks,
        run.log.ticks.len(),
        n.evictions,
        n.bytes_down as f64 / 1e6,
        run.log.requests.len(),
        run.log.errors
    );
    let _ = writeln!(
        md,
        "\nBytes over time: `bytes.svg` and `report.json` (`results.bytes_over_time`)."
    );
    if run.quality.is_empty() {
        let _ = writeln!(md, "Quality was not rendered (`--quality-hz 0`).");
    } else {
        let _ = writeln!(
            md,
            "Quality over time (SSIM at {QW}x{QH} of the drawn tiles against the needed cut at Best, {} Hz; TGQ sampled at {TGQ_HZ} Hz, good = SSIM >= {GOOD}): `quality.svg` and `report.json` (`results.quality_over_time`).",
            i.quality_hz
        );
    }
    md
}

/// Writes `report.json`, `report.md`, `bytes.svg` and (with quality) `quality.svg` into `dir`.
pub fn write(run: &ToolRun, dir: &Path) -> anyhow::Result<()> {
    let put = |name: &str, text: String| {
        let p = dir.join(name);
        std::fs::write(&p, text).with_context(|| p.display().to_string())
    };
    put(
        "report.json",
        serde_json::to_string_pretty(&report_json(run))? + "\n",
    )?;
    put("report.md", report_md(run))?;
    let label = format!("{}, {}", run.inputs.predictor, run.inputs.net_desc);
    let t0 = run.log.ticks.first().map_or(0.0, |t| t.t);
    let bytes = vec![(
        run.inputs.predictor.clone(),
        run.log
            .ticks
            .iter()
            .map(|t| (t.t - t0, t.bytes_down as f64 / 1e6))
            .collect(),
    )];
    put(
        "bytes.svg",
        line_chart(
            &format!("{label}: bytes received"),
            "time (s)",
            "MB",
            &bytes,
            None,
        ),
    )?;
    if !run.quality.is_empty() {
        let q = vec![(run.inputs.predictor.clone(), run.quality.clone())];
        put(
            "quality.svg",
            line_chart(
                &format!("{label}: SSIM of the drawn cut vs the needed cut at Best"),
                "time (s)",
                "SSIM",
                &q,
                Some((0.0, 1.0)),
            ),
        )?;
    }
    Ok(())
}
