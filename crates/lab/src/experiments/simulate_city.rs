//! `simulate --experiment city`: TileSplat Tables 4 and 5 and SGSS Table 3 on the streaming city
//! (`sim::stream_city`), the shipped client over the simulated transport, scored by `sim::score`.
//!
//! Setup (every number goes into the table headers): the default city (1.5M splats, 716 tiles,
//! 104.5 MiB of Best) georeferenced at `stream_city::DEFAULT_ORIGIN`; the client at 1280x720,
//! 50 deg, SSE 16, 4 requests in flight, a [`BUDGET`] memory budget (smaller than the city and
//! than what a 60 s trace downloads), 40 ms RTT. Traces: the test split
//! (`stream_city::evaluation_set`; `--split val`: the tuning split's val traces), the first
//! [`TRACE_S`] s of [`PER_KIND`] each of the human sessions (every [`HUMAN_EVERY`]-th), the
//! street walks and the flights. Real networks: the first HSDPA and FCC logs (`sim::network`),
//! each scaled to a mean of 10 Mbit/s and looped.

use super::SimulateArgs;
use crate::sim::network::{Network, log_files, read_log};
use crate::sim::report::{self, GOOD, QH, QW, TGQ_HZ, TGQ_WINDOW_S, quality, session_numbers, tgq};
use crate::sim::score::{Chr, Ratio, Truth, Waste};
use crate::sim::session::SessionLog;
use crate::sim::stream_city::{
    BuiltCity, CitySpec, DEFAULT_ORIGIN, build_city, evaluation_set, tuning_set,
};
use crate::sim::svg::{Series, write_time_plots};
use crate::sim::transport::NetModel;
use anyhow::Context;
use glam::DVec3;
use splat2tiles_render::Image;
use splat2tiles_stream::catalog::Level;
use splat2tiles_stream::client::ClientConfig;
use splat2tiles_stream::plan::Planner;
use splat2tiles_stream::split::EvaluationSet;
use splat2tiles_stream::trace::{self, Trace};
use splat2tiles_tiles::tiling::TileKey;
use std::collections::{HashMap, HashSet};
use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

/// Client memory budget (bytes): below the city's 104.5 MiB of Best and below what one 60 s
/// trace downloads at 10 Mbit/s (40-75 MB), so eviction acts (at 64 MiB it never did).
pub const BUDGET: u64 = 32 << 20;
/// Client memory budget of SGSS Table 3 (bytes): holds the whole city at Best, as the full
/// download it is compared with does (with [`BUDGET`] the dolly's evictions re-download tiles).
pub const TABLE3_BUDGET: u64 = 256 << 20;
/// Seconds of each trace simulated.
pub const TRACE_S: f64 = 60.0;
/// Every this many human test sessions one is used.
pub const HUMAN_EVERY: usize = 22;
/// Traces of each kind (human, walk, flight) at most.
pub const PER_KIND: usize = 2;
/// Seconds of each trace in Table 5 (20 sessions per trace).
const TABLE5_S: f64 = 30.0;
/// Quality samples per second on the plot trace.
const QUALITY_HZ: f64 = 1.0;

/// The Table 4 predictors; "tcn" is TileSplat's TCN (the committed reference model), "learned"
/// the view model with its turned views (`stream::learned::view_model`); "oracle, mirrored"
/// is the oracle of the trace turned 180 degrees about its start: a damaged predictor the setup
/// must rank below the oracle.
const PREDICTORS: [&str; 7] = [
    "reactive",
    "constant-velocity",
    "linear",
    "tcn",
    "learned",
    "oracle",
    "oracle, mirrored",
];

/// One session of `predictor` (a `PREDICTORS` name) planned by `planner`
/// ([`report::session`] on the trace's poses).
pub fn session(
    dir: &Path,
    tr: &Trace,
    predictor: &str,
    planner: Planner,
    net: &NetModel,
    budget: u64,
) -> SessionLog {
    report::session(dir, &tr.poses, predictor, planner, net, budget)
}

/// A trace cut to its first `s` seconds.
fn truncated(tr: &Trace, s: f64) -> Trace {
    let t0 = tr.poses.first().map_or(0.0, |p| p.t);
    Trace {
        headers: tr.headers.clone(),
        poses: tr
            .poses
            .iter()
            .copied()
            .filter(|p| p.t - t0 <= s + 1e-9)
            .collect(),
    }
}

/// The traces of Table 4 from the evaluation set: the first [`TRACE_S`] s of [`PER_KIND`] human
/// sessions (every [`HUMAN_EVERY`]-th), street walks and flights, in that order.
pub fn table4_traces(eval: &EvaluationSet) -> Vec<Trace> {
    pick_traces(eval.traces())
}

/// [`table4_traces`]'s choice from any list of traces (e.g. a tuning split's, to check a rule
/// on traces the evaluation does not use).
pub fn pick_traces(traces: &[Trace]) -> Vec<Trace> {
    let of = |kind: &'static str| {
        traces
            .iter()
            .filter(move |t| t.header("kind") == Some(kind))
    };
    let mut traces: Vec<Trace> = of("eyenav")
        .step_by(HUMAN_EVERY)
        .take(PER_KIND)
        .map(|t| truncated(t, TRACE_S))
        .collect();
    for kind in ["street_walk", "flight"] {
        traces.extend(of(kind).take(PER_KIND).map(|t| truncated(t, TRACE_S)));
    }
    traces
}

/// A trace's short name for the tables.
pub fn label(tr: &Trace) -> String {
    let kind = tr.header("kind").unwrap_or("trace");
    match (kind, tr.header("source"), tr.header("seed")) {
        ("eyenav", Some(src), _) => src.split_once(' ').map_or(src, |p| p.1).to_string(),
        (_, _, Some(seed)) => format!("{kind} {seed}"),
        _ => kind.to_string(),
    }
}

/// What the scorer keeps of one trace: the needed cut per tick (shared by every session on it).
struct Scored {
    trace: Trace,
    needed: Vec<Vec<TileKey>>,
    /// Reference renders (the needed cut at Best) by tick, shared across sessions.
    refs: HashMap<usize, Image>,
}

fn needed_cuts(truth: &Truth, tr: &Trace) -> Vec<Vec<TileKey>> {
    report::needed_cuts(truth, &ClientConfig::default(), &tr.poses)
}

/// Utility held at first-time entries: the sum over entries of the utility of the level held
/// (0 when missed), and the entries (Table 5's "utility" and "miss").
fn entry_utility(
    log: &SessionLog,
    needed: &[Vec<TileKey>],
    util: &HashMap<TileKey, [f32; 4]>,
) -> (f64, Ratio) {
    let mut ever: HashSet<TileKey> = HashSet::new();
    let mut prev: HashSet<TileKey> = HashSet::new();
    let (mut sum, mut r) = (0.0, Ratio::default());
    let mut started = false;
    for (t, n) in log.ticks.iter().zip(needed) {
        let held: HashMap<TileKey, Level> = t.resident.iter().copied().collect();
        let now: HashSet<TileKey> = n.iter().copied().collect();
        for k in &now {
            if !started || prev.contains(k) || ever.contains(k) {
                continue;
            }
            r.n += 1;
            if let Some(l) = held.get(k) {
                r.hits += 1;
                sum += util.get(k).map_or(0.0, |u| u[l.index()] as f64);
            }
        }
        started |= !now.is_empty();
        ever.extend(now.iter().copied());
        prev = now;
    }
    (sum, r)
}

/// Sums of one Table 4 row over traces.
#[derive(Default)]
struct Row4 {
    chr: Chr,
    waste: Waste,
    tgq: Vec<Option<f64>>,
    tgq_cold: Vec<Option<f64>>,
    mb: f64,
    evictions: u64,
    sessions: usize,
}

pub(super) fn add_ratio(a: &mut Ratio, b: Ratio) {
    a.hits += b.hits;
    a.n += b.n;
}

pub(super) fn pct(r: Ratio) -> String {
    match r.rate() {
        Some(x) => format!("{:.1}% ({}/{})", 100.0 * x, r.hits, r.n),
        None => "-".into(),
    }
}

/// Mean TGQ with events not reaching the threshold within the window counted as the window.
pub(super) fn tgq_cell(v: &[Option<f64>]) -> String {
    match report::tgq_mean(v) {
        None => "- (0 events)".into(),
        Some((mean, missed)) => format!(
            "{mean:.2} ({} events, {missed} > {TGQ_WINDOW_S} s)",
            v.len()
        ),
    }
}

/// The networks of Table 5: constant links and the scaled real logs (name, model, note).
fn networks(args: &SimulateArgs, until: f64) -> anyhow::Result<Vec<(String, NetModel)>> {
    let mut out: Vec<(String, NetModel)> = [100.0, 50.0, 10.0]
        .iter()
        .map(|&m| (format!("{m} Mbps"), NetModel::constant(m, 0.04)))
        .collect();
    for net in [Network::Hsdpa, Network::Fcc] {
        let files = log_files(&args.networks, net).map_err(anyhow::Error::msg)?;
        let f = files
            .first()
            .with_context(|| format!("no {} log in {}", net.dir(), args.networks.display()))?;
        let raw = read_log(f, 1.0).map_err(anyhow::Error::msg)?;
        let scale = 10e6 / 8.0 / raw.mean_bytes_per_s().max(1.0);
        let tr = read_log(f, scale).map_err(anyhow::Error::msg)?;
        let mut m = NetModel::constant(10.0, 0.04);
        m.bandwidth = tr.looped(until + 1.0);
        let name = f.file_name().and_then(|n| n.to_str()).unwrap_or("log");
        out.push((
            format!(
                "{} `{name}` (mean {:.2} Mbps x {scale:.2})",
                net.dir(),
                raw.mean_bytes_per_s() * 8.0 / 1e6
            ),
            m,
        ));
    }
    Ok(out)
}

/// Table 4's inputs besides the traces: the city, the Low bytes per tile (for the warm-up),
/// the traces' names, the trace plotted and the traces TGQ is measured on.
struct Table4<'a> {
    dir: &'a Path,
    low_bytes: &'a HashMap<TileKey, u64>,
    names: &'a [String],
    plot_trace: usize,
    tgq_traces: Vec<usize>,
}

/// Table 4's sums per predictor, the plotted series and the quality samples rendered.
struct Table4Out {
    rows: Vec<Row4>,
    plot_q: Vec<Series>,
    plot_b: Vec<Series>,
    samples: usize,
}

impl Table4<'_> {
    /// Every predictor on every trace at 10 Mbps with the DP planner.
    fn run(&self, truth: &mut Truth, scored: &mut [Scored]) -> anyhow::Result<Table4Out> {
        let mut out = Table4Out {
            rows: (0..PREDICTORS.len()).map(|_| Row4::default()).collect(),
            plot_q: vec![],
            plot_b: vec![],
            samples: 0,
        };
        for (ti, sc) in scored.iter_mut().enumerate() {
            let t_trace = Instant::now();
            for (pi, p) in PREDICTORS.iter().enumerate() {
                self.one(truth, sc, ti, p, pi, &mut out)?;
            }
            sc.refs.clear();
            eprintln!(
                "simulate: city table 4 trace {ti} ({}) in {:.1} s",
                self.names[ti],
                t_trace.elapsed().as_secs_f64()
            );
        }
        Ok(out)
    }

    /// Predictor `p` (row `pi`) on trace `ti`: its cache hits, waste and bytes; quality over
    /// time on the plotted trace, TGQ on the TGQ traces.
    fn one(
        &self,
        truth: &mut Truth,
        sc: &mut Scored,
        ti: usize,
        p: &str,
        pi: usize,
        out: &mut Table4Out,
    ) -> anyhow::Result<()> {
        let net10 = NetModel::constant(10.0, 0.04);
        let t_s = Instant::now();
        let log = session(self.dir, &sc.trace, p, Planner::Dp, &net10, BUDGET);
        let session_s = t_s.elapsed().as_secs_f64();
        // Warm from the time the link needs for the first cut at Low (the same for every
        // predictor and planner).
        let n = session_numbers(&log, &sc.needed, self.low_bytes, &net10);
        let (c, w) = (n.chr, n.waste);
        eprintln!(
            "simulate: city {p} on {}: session {session_s:.1} s",
            self.names[ti]
        );
        let r = &mut out.rows[pi];
        add_ratio(&mut r.chr.initial, c.initial);
        add_ratio(&mut r.chr.first, c.first);
        add_ratio(&mut r.chr.reentry, c.reentry);
        add_ratio(&mut r.chr.warm, c.warm);
        r.waste.tiles += w.tiles;
        r.waste.bytes += w.bytes;
        r.waste.wasted_tiles += w.wasted_tiles;
        r.waste.wasted_bytes += w.wasted_bytes;
        r.mb += n.bytes_down as f64 / 1e6;
        r.evictions += n.evictions;
        r.sessions += 1;
        if ti == self.plot_trace && p != "oracle, mirrored" {
            let t0 = log.ticks.first().map_or(0.0, |t| t.t);
            let mut q = vec![];
            let mut next = t0;
            let t_q = Instant::now();
            for k in 0..log.ticks.len() {
                if log.ticks[k].t + 1e-9 >= next {
                    next += 1.0 / QUALITY_HZ;
                    q.push((
                        log.ticks[k].t - t0,
                        quality(truth, &sc.needed, &mut sc.refs, &log, k)?,
                    ));
                }
            }
            eprintln!(
                "simulate: city {p}: {} quality samples in {:.1} s",
                q.len(),
                t_q.elapsed().as_secs_f64()
            );
            out.samples += q.len();
            out.plot_q.push((p.to_string(), q));
            out.plot_b.push((
                p.to_string(),
                log.ticks
                    .iter()
                    .map(|t| (t.t - t0, t.bytes_down as f64 / 1e6))
                    .collect(),
            ));
        }
        if self.tgq_traces.contains(&ti) {
            let t_q = Instant::now();
            let (cold, later, n) = tgq(truth, &sc.needed, &mut sc.refs, &log)?;
            eprintln!(
                "simulate: city {p} TGQ on {}: cold {cold:?}, events {later:?} ({n} samples in {:.1} s)",
                self.names[ti],
                t_q.elapsed().as_secs_f64()
            );
            out.samples += n;
            let r = &mut out.rows[pi];
            r.tgq_cold.push(cold);
            r.tgq.extend(later);
        }
        Ok(())
    }
}

/// Table 5: the planners in the client loop (linear predictor) on the first trace of each
/// kind, shorter, over every network.
fn table5(
    args: &SimulateArgs,
    dir: &Path,
    scored: &[Scored],
    util: &HashMap<TileKey, [f32; 4]>,
) -> anyhow::Result<String> {
    let mut md = String::new();
    let nets = networks(args, TABLE5_S)?;
    let short: Vec<Scored> = [0, PER_KIND, 2 * PER_KIND]
        .iter()
        .filter_map(|&i| scored.get(i))
        .map(|sc| {
            let trace = truncated(&sc.trace, TABLE5_S);
            Scored {
                needed: sc.needed[..trace.poses.len()].to_vec(),
                trace,
                refs: HashMap::new(),
            }
        })
        .collect();
    let short_names: Vec<String> = short.iter().map(|s| label(&s.trace)).collect();
    let _ = writeln!(
        md,
        "### TileSplat Table 5 on the city (planners in the client loop, linear predictor)\n\nUtility = sum over first-time entries of the utility (the tiles' measured SSIM utilities) of the level held at the entry, 0 when missed; Avg. quality = utility per entry; Miss = first-time entries not held; Util/MB = utility per MB received. Sums over {} (first {TABLE5_S} s each).\n\n| network | method | utility | avg. quality | miss | MB | util/MB |\n|---|---|---:|---:|---:|---:|---:|",
        short_names.join(", ")
    );
    for (nname, net) in &nets {
        for planner in Planner::ALL {
            let (mut u, mut r, mut mb) = (0.0, Ratio::default(), 0.0);
            for sc in &short {
                let log = session(dir, &sc.trace, "linear", planner, net, BUDGET);
                let (su, sr) = entry_utility(&log, &sc.needed, util);
                u += su;
                add_ratio(&mut r, sr);
                mb += log.ticks.last().map_or(0, |t| t.bytes_down) as f64 / 1e6;
            }
            let _ = writeln!(
                md,
                "| {nname} | {} | {u:.1} | {:.3} | {:.1}% | {mb:.1} | {:.2} |",
                planner.name(),
                u / r.n.max(1) as f64,
                100.0 * (1.0 - r.rate().unwrap_or(0.0)),
                u / mb.max(1e-9)
            );
        }
        eprintln!("simulate: city table 5 {nname} done");
    }
    Ok(md)
}

/// SGSS Table 3: bytes streamed on dolly traces at 200 Mbps against the full download.
fn table3(args: &SimulateArgs, dir: &Path, city: &BuiltCity) -> String {
    let mut md = String::new();
    let (lo2, hi2) = city.grid.extent();
    let (lo, hi) = (
        DVec3::new(lo2.x, lo2.y, 0.0),
        DVec3::new(hi2.x, hi2.y, 20.0),
    );
    let full = city.variant_bytes[0] as f64 / 1e6;
    let _ = writeln!(
        md,
        "\n### SGSS Table 3 on the city: bytes on 20 s dolly traces (200 Mbps)\n\nFull = every tile at Best ({full:.1} MB). Streamed = body bytes received in 20 s, memory budget {} MiB (holds the city; with {} MiB the oracle's evictions re-download tiles).\n\n| dolly seed | full download | reactive | linear | oracle |\n|---|---:|---:|---:|---:|",
        TABLE3_BUDGET >> 20,
        BUDGET >> 20
    );
    let net200 = NetModel::constant(200.0, 0.04);
    for seed in 0..3u64 {
        let tr = trace::dolly("stream-city", lo, hi, args.seed + seed, "test");
        let mut cells = vec![];
        for p in ["reactive", "linear", "oracle"] {
            let log = session(dir, &tr, p, Planner::Dp, &net200, TABLE3_BUDGET);
            let mb = log.ticks.last().map_or(0, |t| t.bytes_down) as f64 / 1e6;
            cells.push(format!("{mb:.2} MB ({:.1}%)", 100.0 * mb / full));
        }
        let _ = writeln!(
            md,
            "| {} | {full:.1} MB | {} |",
            args.seed + seed,
            cells.join(" | ")
        );
    }
    md
}

/// The traces `--split` names: the evaluation's test traces, or the tuning split's val traces.
fn city_split(
    args: &SimulateArgs,
    grid: &crate::sim::stream_city::StreetGrid,
) -> anyhow::Result<(&'static str, Vec<Trace>)> {
    Ok(match args.split.as_str() {
        "val" => {
            let set = tuning_set(grid, &args.navigation).map_err(anyhow::Error::msg)?;
            ("val", set.val().to_vec())
        }
        _ => {
            let eval = evaluation_set(grid, &args.navigation).map_err(anyhow::Error::msg)?;
            ("test", eval.traces().to_vec())
        }
    })
}

/// Runs the city experiment; returns its markdown.
pub(super) fn city(args: &SimulateArgs) -> anyhow::Result<String> {
    let start = Instant::now();
    let dir = args.out.join("city");
    let origin = splat2tiles_core::frame::geo::Geodetic::parse(DEFAULT_ORIGIN)
        .map_err(anyhow::Error::msg)?;
    let spec = CitySpec::default();
    let city: BuiltCity = build_city(&args.scenes, &dir, &spec, Some(origin))?;
    eprintln!("simulate: city {}", city.summary());
    let mut truth = Truth::load(&dir.join("tileset.json"))?;
    let ts = splat2tiles_tiles::tiling::load::load_tileset(&dir.join("tileset.json"))?;
    let meta = splat2tiles_tiles::variants::content_variant_metadata(&ts);
    let low_bytes: HashMap<TileKey, u64> = meta
        .iter()
        .map(|(k, (_, b, _))| (*k, b[Level::Low.index()] as u64))
        .collect();
    let util: HashMap<TileKey, [f32; 4]> = meta.into_iter().map(|(k, (_, _, u))| (k, u)).collect();
    let (split, all) = city_split(args, &city.grid)?;
    let humans = all
        .iter()
        .filter(|t| t.header("kind") == Some("eyenav"))
        .count();
    let traces = pick_traces(&all);
    let mut scored: Vec<Scored> = traces
        .into_iter()
        .map(|trace| Scored {
            needed: needed_cuts(&truth, &trace),
            trace,
            refs: HashMap::new(),
        })
        .collect();
    let names: Vec<String> = scored.iter().map(|s| label(&s.trace)).collect();
    eprintln!(
        "simulate: city traces ({} of {} {split} humans, every {HUMAN_EVERY}th): {}",
        humans.div_ceil(HUMAN_EVERY),
        humans,
        names.join(", ")
    );
    let mut md = String::new();
    let best_mib = city.variant_bytes[0] as f64 / (1u64 << 20) as f64;
    let _ = writeln!(
        md,
        "## Streaming city\n\nCity: {} (`sim::stream_city`, seed {}, origin {DEFAULT_ORIGIN}). Client: 1280x720, 50 deg, SSE 16, 4 requests in flight, memory budget {} MiB (the city has {best_mib:.1} MiB of Best), 40 ms RTT, 400 B/request. Traces ({split} split only, first {TRACE_S} s each): {}.\n",
        city.summary(),
        spec.seed,
        BUDGET >> 20,
        names.join(", ")
    );
    // Table 4.
    let plot_trace = scored
        .iter()
        .position(|s| s.trace.header("kind") == Some("street_walk"))
        .unwrap_or(0);
    // TGQ on the first street walk and the first flight (rendering costs about 1 s a sample).
    let tgq_traces: Vec<usize> = ["street_walk", "flight"]
        .iter()
        .filter_map(|k| {
            scored
                .iter()
                .position(|s| s.trace.header("kind") == Some(*k))
        })
        .collect();
    let tgq_names: Vec<String> = tgq_traces.iter().map(|&i| names[i].clone()).collect();
    let pname = names[plot_trace].clone();
    let t4 = Table4 {
        dir: &dir,
        low_bytes: &low_bytes,
        names: &names,
        plot_trace,
        tgq_traces,
    };
    let Table4Out {
        rows,
        plot_q,
        plot_b,
        samples,
    } = t4.run(&mut truth, &mut scored)?;
    let _ = writeln!(
        md,
        "### TileSplat Table 4 on the city (10 Mbps, DC-DP)\n\nCHR over first-time entries into the needed cut (`sim::score`: the whole tileset's cut at the client's viewport), the cold start (entries of the first non-empty cut) and re-entries apart; after warm-up = the first-time entries after the time the link needs to carry the first cut at Low plus one round trip (`sim::score::link_warm_up`; until then the link still carries the first view, whatever the predictor; the same time for every predictor, where the earlier rule, the first tick whose whole needed cut was held, moved with a client that leaves holes in view unrepaired); TGQ per new-region event (>= 30% unseen tiles, or a 45 deg turn in 1 s; merged within 3 s) on {} (rendering costs about 1 s a sample here): seconds to SSIM >= {GOOD} at {QW}x{QH} against the needed cut at Best, sampled at {TGQ_HZ} Hz from the event until reached, the next event or {TGQ_WINDOW_S} s (not reached: counted as {TGQ_WINDOW_S} s); the cold start (the first tick's event) apart; WD = completed downloads of tiles in no needed cut from their end on. Sums over the {} traces.\n\n| predictor | CHR first-time | after warm-up | cold start | re-entries | TGQ (s) | TGQ cold start (s) | WD tiles | WD bytes | MB | evictions |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
        tgq_names.join(" and "),
        scored.len()
    );
    for (p, r) in PREDICTORS.iter().zip(&rows) {
        let _ = writeln!(
            md,
            "| {p} | {} | {} | {} | {} | {} | {} | {} | {} | {:.1} | {} |",
            pct(r.chr.first),
            pct(r.chr.warm),
            pct(r.chr.initial),
            pct(r.chr.reentry),
            tgq_cell(&r.tgq),
            tgq_cell(&r.tgq_cold),
            report::percent(r.waste.wasted_tiles, r.waste.tiles),
            report::percent(r.waste.wasted_bytes, r.waste.bytes),
            r.mb,
            r.evictions
        );
    }
    write_time_plots(
        &args.plots,
        "city",
        &format!("city, {pname}, 10 Mbps"),
        "SSIM of the drawn cut vs the needed cut at Best",
        &plot_q,
        &plot_b,
    )?;
    let _ = writeln!(
        md,
        "\nPlots: `docs/city_quality.svg` (SSIM at {QUALITY_HZ} Hz), `docs/city_bytes.svg` ({pname}, 10 Mbps). Quality samples rendered: {samples}.\n"
    );
    md.push_str(&table5(args, &dir, &scored, &util)?);
    md.push_str(&table3(args, &dir, &city));
    let _ = writeln!(
        md,
        "\nWall time of the whole experiment: {:.0} s.\n",
        start.elapsed().as_secs_f64()
    );
    Ok(md)
}
