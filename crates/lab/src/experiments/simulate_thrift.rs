//! `simulate --experiment thrift`: what each prefetch setting (`client::Prefetch`) costs in bytes
//! and buys in cache hits and time to quality, on dollies over one district of the streaming city.
//!
//! SGSS Table 3 compares the bytes a streaming client receives on 20 s dolly shots with the full
//! download of the scene. A dolly framing the whole city sees nearly every tile, so no client can
//! save much there; these dollies frame a district a third of the city across (the rest of the
//! city stays in view behind it, at the coarse levels its distance needs). The district's place
//! is drawn from the seed alone, before any client runs. Each row reports the bytes of the tiles
//! the dolly's needed cuts ever hold at Best ("seen"): what a client that fetched exactly those
//! once would receive.

use super::SimulateArgs;
use super::simulate_city::{TRACE_S, add_ratio, label, pct, pick_traces, table4_traces, tgq_cell};
use crate::sim::report::{self, session_numbers};
use crate::sim::score::{Chr, Truth, Waste};
use crate::sim::session::run_session;
use crate::sim::stream_city::{
    BuiltCity, CitySpec, DEFAULT_ORIGIN, StreetGrid, build_city, evaluation_set, trace_set,
};
use crate::sim::svg::{Series, marked_chart};
use crate::sim::transport::NetModel;
use glam::DVec3;
use splat2tiles_core::rng::SplitMix64;
use splat2tiles_render::Image;
use splat2tiles_stream::catalog::Level;
use splat2tiles_stream::client::{ClientConfig, Prefetch};
use splat2tiles_stream::plan::Planner;
use splat2tiles_stream::split::Split;
use splat2tiles_stream::trace::{self, Trace};
use splat2tiles_tiles::tiling::TileKey;
use std::collections::{HashMap, HashSet};
use std::fmt::Write as _;
use std::time::Instant;

/// Side of a dolly's district as a fraction of the city's side.
pub const DISTRICT_FRACTION: f64 = 1.0 / 3.0;
/// Dollies per run (seeds `--seed`, `--seed + 1`, ...).
pub const DOLLIES: u64 = 6;
/// The predictors compared.
const PREDICTORS: [&str; 2] = ["linear", "oracle"];
/// The settings of the curve: no prefetch, then 1.5, 4 and 10 s ahead, each with every upgrade
/// and with upgrades only for at least 0.01 utility (the named settings are among them).
fn settings() -> Vec<(String, Prefetch)> {
    let mut v = vec![(
        "0 s (view only)".to_string(),
        Prefetch {
            ahead_s: 0.0,
            ..Prefetch::EAGER
        },
    )];
    for (ahead_s, max_sigma_m) in [(1.5, 5.0), (4.0, 10.0), (10.0, 20.0)] {
        for upgrade_gain in [0.0, 0.01] {
            let p = Prefetch {
                ahead_s,
                max_sigma_m,
                upgrade_gain,
            };
            let mut name = if upgrade_gain > 0.0 {
                format!("{ahead_s} s, upgrades for >= {upgrade_gain}")
            } else {
                format!("{ahead_s} s, every upgrade")
            };
            if let Some((n, _)) = Prefetch::NAMED.iter().find(|(_, q)| *q == p) {
                name = format!("**{n}**: {name}");
            }
            v.push((name, p));
        }
    }
    v
}

/// A dolly over a district: a square [`DISTRICT_FRACTION`] of the city's side, placed by `seed`
/// (uniform over the city, clamped inside it), 0-20 m high, shot as `trace::dolly` shoots a
/// whole scene.
pub fn district_dolly(grid: &StreetGrid, seed: u64) -> Trace {
    let (lo, hi) = grid.extent();
    let side = (hi - lo) * DISTRICT_FRACTION;
    let mut rng = SplitMix64::new(seed ^ 0x7468_7269_6674);
    let x = lo.x + rng.f64() * (hi.x - lo.x - side.x);
    let y = lo.y + rng.f64() * (hi.y - lo.y - side.y);
    let a = DVec3::new(x, y, 0.0);
    let b = DVec3::new(x + side.x, y + side.y, 20.0);
    trace::dolly("stream-city-district", a, b, seed, "test")
}

/// Sums of one (network, predictor, setting) cell over the dollies.
#[derive(Default)]
struct Cell {
    chr: Chr,
    waste: Waste,
    bytes: u64,
    /// Body bytes received per level (Best, High, Medium, Low; aborted requests included).
    by_level: [u64; 4],
    tgq: Vec<Option<f64>>,
    tgq_cold: Vec<Option<f64>>,
    /// Sum over ticks and needed tiles held of the held level's utility, and that count.
    utility: (f64, u64),
}

/// One dolly as the scorer needs it.
struct Dolly {
    trace: Trace,
    needed: Vec<Vec<TileKey>>,
    refs: HashMap<usize, Image>,
    /// Bytes at Best of every tile its needed cuts hold.
    seen: u64,
}

/// The city and what scoring on it needs.
struct City {
    dir: std::path::PathBuf,
    built: BuiltCity,
    truth: Truth,
    low: HashMap<TileKey, u64>,
    best: HashMap<TileKey, u64>,
    util: HashMap<TileKey, [f32; 4]>,
}

impl City {
    fn build(args: &SimulateArgs) -> anyhow::Result<City> {
        let dir = args.out.join("city");
        let origin = splat2tiles_core::frame::geo::Geodetic::parse(DEFAULT_ORIGIN)
            .map_err(anyhow::Error::msg)?;
        let built = build_city(&args.scenes, &dir, &CitySpec::default(), Some(origin))?;
        eprintln!("simulate: city {}", built.summary());
        let truth = Truth::load(&dir.join("tileset.json"))?;
        let ts = splat2tiles_tiles::tiling::load::load_tileset(&dir.join("tileset.json"))?;
        let meta = splat2tiles_tiles::variants::content_variant_metadata(&ts);
        let bytes = |l: Level| -> HashMap<TileKey, u64> {
            meta.iter()
                .map(|(k, (_, b, _))| (*k, b[l.index()] as u64))
                .collect()
        };
        let (low, best) = (bytes(Level::Low), bytes(Level::Best));
        let util = meta.iter().map(|(k, (_, _, u))| (*k, *u)).collect();
        Ok(City {
            dir,
            built,
            truth,
            low,
            best,
            util,
        })
    }

    /// `trace` with its needed cuts and the Best bytes of every tile they hold.
    fn scored(&self, trace: Trace) -> Dolly {
        let needed = report::needed_cuts(&self.truth, &ClientConfig::default(), &trace.poses);
        let ever: HashSet<TileKey> = needed.iter().flatten().copied().collect();
        let seen = ever
            .iter()
            .map(|k| self.best.get(k).copied().unwrap_or(0))
            .sum();
        Dolly {
            trace,
            needed,
            refs: HashMap::new(),
            seen,
        }
    }
}

/// One table row of a cell.
fn row(net: &str, p: &str, setting: &str, c: &Cell, full: u64) -> String {
    let got = 100.0 * c.bytes as f64 / full.max(1) as f64;
    let utility = if c.utility.1 > 0 {
        format!("{:.5}", c.utility.0 / c.utility.1 as f64)
    } else {
        "-".into()
    };
    format!(
        "| {net} | {p} | {setting} | {:.1} MB ({got:.1}%) | {} | {} | {} | {} | {:.1}% | {utility} | {} | {} |",
        c.bytes as f64 / 1e6,
        c.by_level
            .map(|b| format!("{:.1}", b as f64 / 1e6))
            .join(" / "),
        pct(c.chr.warm),
        pct(c.chr.first),
        pct(c.chr.reentry),
        100.0 * c.waste.wasted_bytes as f64 / c.waste.bytes.max(1) as f64,
        tgq_cell(&c.tgq),
        tgq_cell(&c.tgq_cold),
    )
}

/// Runs the thrift experiment; returns its markdown (and writes `thrift_curve.svg` to the
/// plots folder).
pub(super) fn thrift(args: &SimulateArgs) -> anyhow::Result<String> {
    let start = Instant::now();
    let mut city = City::build(args)?;
    let full = city.built.variant_bytes[Level::Best.index()];
    let dollies: Vec<Dolly> = (0..DOLLIES)
        .map(|i| city.scored(district_dolly(&city.built.grid, args.seed + i)))
        .collect();
    let nav = &args.navigation;
    let eval = evaluation_set(&city.built.grid, nav).map_err(anyhow::Error::msg)?;
    let walks: Vec<Dolly> = table4_traces(&eval)
        .into_iter()
        .map(|t| city.scored(t))
        .collect();
    let val = trace_set(&city.built.grid, nav, Split::Val).map_err(anyhow::Error::msg)?;
    let val: Vec<Dolly> = pick_traces(&val)
        .into_iter()
        .map(|t| city.scored(t))
        .collect();
    let nets = [
        ("200 Mbps", NetModel::constant(200.0, 0.04)),
        ("10 Mbps", NetModel::constant(10.0, 0.04)),
    ];
    let named: Vec<(String, Prefetch)> = Prefetch::NAMED
        .iter()
        .map(|(n, p)| (n.to_string(), *p))
        .collect();
    let mut md = header(args, &city.built, &dollies, full);
    let mut plot: Vec<Series> = vec![];
    let walks_md = traces_header("the Table 4 traces (test split", &walks);
    let val_md = traces_header(
        "the same choice of traces from the validation split (the named settings only; where a choice made on the test traces is checked",
        &val,
    );
    // Dollies at both rates (with TGQ); the Table 4 traces at 10 Mbps (many more first-time
    // entries; no TGQ); the validation traces.
    let mut parts = [
        (
            "dollies",
            dollies,
            &nets[..],
            true,
            settings(),
            String::new(),
        ),
        (
            "Table 4 traces",
            walks,
            &nets[1..],
            false,
            settings(),
            walks_md,
        ),
        ("validation traces", val, &nets[1..], false, named, val_md),
    ];
    for (what, traces, nets, tgq, settings, head) in parts.iter_mut() {
        md.push_str(head);
        let n = traces.len() as u64;
        for (nname, net) in nets.iter() {
            for p in PREDICTORS {
                let mut points = vec![];
                for (sname, setting) in settings.iter() {
                    let c = cell(&mut city, traces, p, *setting, net, *tgq)?;
                    let line = row(nname, p, sname, &c, full * n);
                    eprintln!("{line}");
                    md.push_str(&line);
                    md.push('\n');
                    if let Some(r) = c.chr.warm.rate() {
                        points.push((100.0 * c.bytes as f64 / (full * n).max(1) as f64, 100.0 * r));
                    }
                    eprintln!(
                        "simulate: thrift {what} {nname} {p} {sname} done ({:.0} s)",
                        start.elapsed().as_secs_f64()
                    );
                }
                plot.push((format!("{what}, {p}, {nname}"), points));
            }
        }
    }
    let svg = marked_chart(
        "Prefetch settings: bytes against cache hits",
        "bytes received (% of one full download at Best per trace)",
        "CHR, first-time entries after warm-up (%)",
        &plot,
    );
    let path = args.plots.join("thrift_curve.svg");
    std::fs::write(&path, svg)?;
    let _ = writeln!(
        md,
        "\nPlot: `{}`. Wall time {:.0} s.",
        path.display(),
        start.elapsed().as_secs_f64()
    );
    Ok(md)
}

/// The heading of a table on other traces: `what` names them (an open parenthesis that the
/// heading closes after the trace names).
fn traces_header(what: &str, traces: &[Dolly]) -> String {
    let names: Vec<String> = traces.iter().map(|w| label(&w.trace)).collect();
    format!(
        "\nThe same settings on {what}, first {TRACE_S} s each: {}), 10 Mbps, the same client and budget; the traces move through the city, so most of their entries are first-time ones.\n\n| network | predictor | prefetch | received | by level (MB, Best / High / Medium / Low) | CHR after warm-up | CHR first-time | re-entries | WD bytes | utility held | TGQ (s) | TGQ cold start (s) |\n|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n",
        names.join(", ")
    )
}

/// The table's heading: setup, dollies and what each saw.
fn header(args: &SimulateArgs, city: &BuiltCity, dollies: &[Dolly], full: u64) -> String {
    let mut md = String::new();
    let _ = writeln!(
        md,
        "\n### Prefetch settings on district dollies (SGSS Table 3's setting, a district in view)\n\nCity: {}. Client: 1280x720, 50 deg, SSE 16, 4 requests in flight, memory budget {} MiB (holds the city), 40 ms RTT, DC-DP. Full = every tile at Best ({:.1} MB).",
        city.summary(),
        super::simulate_city::TABLE3_BUDGET >> 20,
        full as f64 / 1e6
    );
    let seen: u64 = dollies.iter().map(|d| d.seen).sum();
    let _ = writeln!(
        md,
        "- all {} dollies: {:.1} MB seen at Best, {:.1}% of {} full downloads",
        dollies.len(),
        seen as f64 / 1e6,
        100.0 * seen as f64 / (full * dollies.len() as u64).max(1) as f64,
        dollies.len()
    );
    for d in dollies {
        let _ = writeln!(
            md,
            "- dolly seed {}: its needed cuts hold {} tiles, {:.1} MB at Best ({:.1}% of the full download)",
            d.trace.header("seed").unwrap_or("?"),
            d.needed.iter().flatten().collect::<HashSet<_>>().len(),
            d.seen as f64 / 1e6,
            100.0 * d.seen as f64 / full.max(1) as f64
        );
    }
    let _ = writeln!(
        md,
        "\nSums over the {} dollies (seeds from {}); received as a share of one full download per dolly. CHR as in Table 4 (first-time entries into the needed cut; after warm-up = after the link's time for the first cut at Low plus one round trip); WD = bytes of completed downloads of tiles in no needed cut from their end on; utility held = mean over ticks and held tiles of the needed cut of the held variant's utility (the tileset's metadata; Best = 1); TGQ as in Table 4 (s to SSIM >= 0.9 per new-region event; the cold start apart).\n\n| network | predictor | prefetch | received | by level (MB, Best / High / Medium / Low) | CHR after warm-up | CHR first-time | re-entries | WD bytes | utility held | TGQ (s) | TGQ cold start (s) |\n|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
        dollies.len(),
        args.seed
    );
    md
}

/// One (network, predictor, setting) over every trace of `traces` (TGQ rendered when `tgq`).
fn cell(
    city: &mut City,
    traces: &mut [Dolly],
    predictor: &str,
    prefetch: Prefetch,
    net: &NetModel,
    tgq: bool,
) -> anyhow::Result<Cell> {
    let mut c = Cell::default();
    for d in traces.iter_mut() {
        let base = ClientConfig {
            max_concurrent: 4,
            prefetch,
            ..ClientConfig::default()
        };
        let (cfg, opts) = report::client_setup(
            base,
            &d.trace.poses,
            predictor,
            Planner::Dp,
            super::simulate_city::TABLE3_BUDGET,
        );
        let log = run_session(&city.dir, cfg, &d.trace.poses, net, opts);
        let n = session_numbers(&log, &d.needed, &city.low, net);
        add_ratio(&mut c.chr.warm, n.chr.warm);
        add_ratio(&mut c.chr.first, n.chr.first);
        add_ratio(&mut c.chr.reentry, n.chr.reentry);
        add_ratio(&mut c.chr.initial, n.chr.initial);
        c.waste.bytes += n.waste.bytes;
        c.waste.wasted_bytes += n.waste.wasted_bytes;
        c.bytes += n.bytes_down;
        for r in &log.requests {
            if let Some(l) = r.level {
                c.by_level[l.index()] += r.bytes;
            }
        }
        let u = held_utility(&log, &d.needed, &city.util);
        c.utility.0 += u.0;
        c.utility.1 += u.1;
        if tgq {
            let (cold, events, _) = report::tgq(&mut city.truth, &d.needed, &mut d.refs, &log)?;
            c.tgq.extend(events);
            c.tgq_cold.push(cold);
        }
    }
    Ok(c)
}

/// Over every tick, the utility (the tileset's per-variant utility metadata) of the level held
/// for each tile of the needed cut the client holds: the sum and the count.
fn held_utility(
    log: &crate::sim::session::SessionLog,
    needed: &[Vec<TileKey>],
    util: &HashMap<TileKey, [f32; 4]>,
) -> (f64, u64) {
    let (mut sum, mut n) = (0.0, 0);
    for (t, cut) in log.ticks.iter().zip(needed) {
        let held: HashMap<TileKey, Level> = t.resident.iter().copied().collect();
        for k in cut {
            if let (Some(l), Some(u)) = (held.get(k), util.get(k)) {
                sum += u[l.index()] as f64;
                n += 1;
            }
        }
    }
    (sum, n)
}
