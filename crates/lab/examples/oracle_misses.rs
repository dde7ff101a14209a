//! Two measurements on the full streaming city (minutes each; they print the BENCHMARKS.md
//! tables): why the oracle still misses first-time entries (`misses`), and the causes of those
//! misses along the city traces (`causes`). Needs `STREAM_CITY_DIR`, a city built by the
//! `stream_city` example (241 MiB):
//! `STREAM_CITY_DIR=DIR cargo run --profile test -p splat2tiles-lab --example oracle_misses -- misses|causes`.

use std::path::PathBuf;

use splat2tiles_lab::sim::misses::{breakdown, breakdown_with};
use splat2tiles_lab::sim::score::{Ratio, Truth, WarmUp, cache_hits, cache_hits_with, held_tiles};
use splat2tiles_lab::sim::score::{link_warm_up, tick_views};
use splat2tiles_lab::sim::session::{SessionOptions, run_session};
use splat2tiles_lab::sim::stream_city::{CitySpec, StreetGrid};
use splat2tiles_lab::sim::transport::NetModel;
use splat2tiles_stream::client::{ClientConfig, PredictorKind};
use splat2tiles_stream::predict::Oracle;
use splat2tiles_tiles::tiling::TileKey;

/// The scenes of the repository (`data/scenes`).
fn scenes() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../..")).join("data/scenes")
}

fn main() {
    match std::env::args().nth(1).as_deref() {
        Some("misses") => oracle_misses_on_the_full_city(),
        Some("causes") => oracle_miss_causes_on_the_city_traces(),
        _ => {
            eprintln!("usage: oracle_misses misses|causes (with STREAM_CITY_DIR set)");
            std::process::exit(2);
        }
    }
}

/// The full-city measurement behind BENCHMARKS "Streaming city": why the oracle
/// misses first-time entries there (`STREAM_CITY_DIR` = a city built by
/// `cargo run --release --example stream_city -- DIR`; the first street walk and flight of the
/// test split, 60 s, 10 Mbit/s, 32 MiB and 1 GiB budgets).
fn oracle_misses_on_the_full_city() {
    use splat2tiles_lab::sim::stream_city::{flight, street_walk};
    let dir = std::env::var("STREAM_CITY_DIR").expect("STREAM_CITY_DIR");
    let dir = std::path::PathBuf::from(dir);
    let scenes = scenes();
    let spec = CitySpec::default();
    let sources = splat2tiles_lab::sim::stream_city::city_sources(&scenes, spec.stride).unwrap();
    let grid = StreetGrid::of(&sources, &spec.layout());
    let truth = Truth::load(&dir.join("tileset.json")).unwrap();
    let ts = splat2tiles_tiles::tiling::load::load_tileset(&dir.join("tileset.json")).unwrap();
    let meta = splat2tiles_tiles::variants::content_variant_metadata(&ts);
    for budget in [32u64 << 20, 1 << 30] {
        let cfg = ClientConfig {
            max_concurrent: 4,
            predictor: PredictorKind::Reactive,
            memory_budget_bytes: budget,
            ..ClientConfig::default()
        };
        for trace in [street_walk(&grid, 18, 60.0), flight(&grid, 37, 60.0)] {
            let opts = SessionOptions {
                predictor: Some(Box::new(Oracle {
                    trace: trace.poses.clone(),
                })),
                ..SessionOptions::default()
            };
            let log = run_session(
                &dir,
                cfg.clone(),
                &trace.poses,
                &NetModel::constant(10.0, 0.04),
                opts,
            );
            let needed = truth.needed_per_tick(&cfg, &log);
            let resident = held_tiles(&log);
            let views = tick_views(&log, needed.iter().map(Vec::as_slice), &resident);
            let w = breakdown(&log, &views);
            let c = cache_hits(&views);
            // What the link would have to carry: the bytes of the tiles entering the needed cut
            // for the first time after the first tick, per second of the trace.
            let mut ever: std::collections::HashSet<TileKey> =
                needed.first().into_iter().flatten().copied().collect();
            let mut entering = [0u64; 4];
            for n in &needed[1..] {
                for k in n {
                    if ever.insert(*k) {
                        let b = meta.get(k).map_or([0; 4], |m| m.1);
                        for (e, b) in entering.iter_mut().zip(b) {
                            *e += b as u64;
                        }
                    }
                }
            }
            let secs = trace.poses.last().map_or(1.0, |p| p.t) - trace.poses[0].t;
            let mbps = |b: u64| b as f64 * 8.0 / 1e6 / secs.max(1e-9);
            eprintln!(
                "  first-time CHR {}/{}, after warm-up {}/{}, cold start {}/{}; tiles entering \
                 need {:.1} Mbit/s at Best, {:.1} at Low (first cut {} tiles)",
                c.first.hits,
                c.first.n,
                c.warm.hits,
                c.warm.n,
                c.initial.hits,
                c.initial.n,
                mbps(entering[0]),
                mbps(entering[3]),
                needed.first().map_or(0, Vec::len)
            );
            assert!(w.entries > 0 && w.misses <= w.entries, "{w:?}");
            // Repeated downloads: requests per (tile, level), bytes of completed ones.
            let mut per: std::collections::HashMap<_, (u32, u32, u64)> =
                std::collections::HashMap::new();
            for r in &log.requests {
                if let (Some(k), Some(l)) = (r.key, r.level) {
                    let e = per.entry((k, l)).or_default();
                    e.0 += 1;
                    e.1 += (r.outcome == splat2tiles_lab::sim::transport::Outcome::Done) as u32;
                    e.2 += r.bytes;
                }
            }
            let tiles: std::collections::HashSet<_> = per.keys().map(|(k, _)| *k).collect();
            let resumed = log.requests.iter().filter(|r| r.range_start > 0).count();
            eprintln!(
                "  {} (tile, level) pairs over {} tiles; {} requested more than once, {} completed \
                 more than once; {resumed} resumed requests",
                per.len(),
                tiles.len(),
                per.values().filter(|v| v.0 > 1).count(),
                per.values().filter(|v| v.1 > 1).count()
            );
            let lead =
                w.in_flight_lead_s.iter().sum::<f64>() / w.in_flight_lead_s.len().max(1) as f64;
            let mb = log.ticks.last().map_or(0, |t| t.bytes_down) as f64 / 1e6;
            eprintln!(
                "budget {} MiB, {}: {} misses of {}: evicted {}, in flight {} (mean lead {lead:.2} s), refused {}, late {}, never {}; outside the client's view {}, ancestor held {}; first 5 s {}; {mb:.1} MB, {} evictions, {} aborts, {} requests",
                budget >> 20,
                trace.header("kind").unwrap_or("?"),
                w.misses,
                w.entries,
                w.evicted,
                w.in_flight,
                w.refused,
                w.late,
                w.never,
                w.outside_client_view,
                w.ancestor_held,
                w.at_s.iter().filter(|&&t| t < 5.0).count(),
                log.evictions,
                log.aborts,
                log.requests.len()
            );
        }
    }
    // SGSS Table 3's setup: bytes the oracle receives on a 20 s dolly at 200 Mbit/s with a
    // budget that holds the city (as the full download does), against the whole city at Best.
    let (lo2, hi2) = grid.extent();
    let (lo, hi) = (
        glam::DVec3::new(lo2.x, lo2.y, 0.0),
        glam::DVec3::new(hi2.x, hi2.y, 20.0),
    );
    let full: u64 = meta.values().map(|(_, b, _)| b[0] as u64).sum();
    for seed in 1..=3u64 {
        let tr = splat2tiles_stream::trace::dolly("stream-city", lo, hi, seed, "test");
        let cfg = ClientConfig {
            max_concurrent: 4,
            predictor: PredictorKind::Reactive,
            memory_budget_bytes: 256 << 20,
            ..ClientConfig::default()
        };
        let opts = SessionOptions {
            predictor: Some(Box::new(Oracle {
                trace: tr.poses.clone(),
            })),
            ..SessionOptions::default()
        };
        let log = run_session(&dir, cfg, &tr.poses, &NetModel::constant(200.0, 0.04), opts);
        let got = log.ticks.last().map_or(0, |t| t.bytes_down);
        let done: std::collections::HashSet<_> = log
            .requests
            .iter()
            .filter(|r| r.outcome == splat2tiles_lab::sim::transport::Outcome::Done)
            .filter_map(|r| Some((r.key?, r.level?)))
            .collect();
        let tiles: std::collections::HashSet<_> = done.iter().map(|d| d.0).collect();
        eprintln!(
            "dolly {seed}: oracle received {:.1} MB of {:.1} MB (full Best), {} (tile, level)              completed over {} tiles, {} evictions",
            got as f64 / 1e6,
            full as f64 / 1e6,
            done.len(),
            tiles.len(),
            log.evictions
        );
    }
}

/// Why the oracle misses first-time entries after the warm-up on the six traces of
/// `simulate --experiment city` (its sessions: 10 Mbit/s, 40 ms RTT, the experiment's budget, or
/// `BUDGET_MIB`), one row per trace; the reactive client's CHR beside it. Needs `STREAM_CITY_DIR`
/// (a city built by `cargo run --release --example stream_city -- DIR`) and
/// the human traces under `data/` (read through `sim::split`).
#[expect(
    clippy::too_many_lines,
    reason = "a measurement run by hand: one straight script that prints its table"
)]
fn oracle_miss_causes_on_the_city_traces() {
    use splat2tiles_lab::experiments::simulate_city::{BUDGET, label, session, table4_traces};
    use splat2tiles_lab::sim::misses::Cause;
    use splat2tiles_stream::plan::Planner;
    use splat2tiles_stream::predict::sample_trace;
    use std::collections::HashMap;
    let dir = std::path::PathBuf::from(std::env::var("STREAM_CITY_DIR").expect("STREAM_CITY_DIR"));
    let budget = std::env::var("BUDGET_MIB")
        .ok()
        .map_or(BUDGET, |m| m.parse::<u64>().expect("BUDGET_MIB") << 20);
    let scenes = scenes();
    let spec = CitySpec::default();
    let sources = splat2tiles_lab::sim::stream_city::city_sources(&scenes, spec.stride).unwrap();
    let grid = StreetGrid::of(&sources, &spec.layout());
    let truth = Truth::load(&dir.join("tileset.json")).unwrap();
    let nav = std::path::Path::new(splat2tiles_lab::sim::stream_city::NAVIGATION_DIR);
    let eval = splat2tiles_lab::sim::stream_city::evaluation_set(&grid, nav).unwrap();
    // `SPLIT=val` (or `train`) runs the same choice of traces from that split instead of the
    // evaluation's test split: a rule designed while reading this breakdown is checked there.
    use splat2tiles_stream::split::Split;
    let split = match std::env::var("SPLIT").as_deref() {
        Ok("val") => Some(Split::Val),
        Ok("train") => Some(Split::Train),
        _ => None,
    };
    let traces = match split {
        Some(split) => splat2tiles_lab::experiments::simulate_city::pick_traces(
            &splat2tiles_lab::sim::stream_city::trace_set(&grid, nav, split).unwrap(),
        ),
        None => table4_traces(&eval),
    };
    let cfg = ClientConfig::default();
    let net = NetModel::constant(10.0, 0.04);
    eprintln!(
        "budget {} MiB; misses after the warm-up (the time the link needs for the first cut at Low, `sim::score::link_warm_up`) by cause (first match: evicted, in flight at \
         the entry, aborted, downloaded but refused, requested after the entry, never \
         requested); the not-requested-before-entry ones split by what the client's plans \
         before the entry knew of the tile: wanted by a plan / in a predicted view but left out \
         by the planner / in no predicted view although the scorer's cut at one of the \
         predictor's sample poses holds it / in no predicted view and in no sampled cut",
        budget >> 20
    );
    eprintln!(
        "| trace | oracle after warm-up | reactive after warm-up | evicted | in flight (mean lead s) | aborted | refused | late | never | not asked: planned | predicted, not planned | cut differs | between samples | needed 1 tick | < 0.5 s | outside client view |"
    );
    eprintln!("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    let mut sums = [0u64; 13];
    let (mut oracle_all, mut reactive_all) = (Ratio::default(), Ratio::default());
    // The oracle's CHR over every first-time entry (the warm-up included).
    let mut oracle_first = Ratio::default();
    let lw_meta = splat2tiles_tiles::variants::content_variant_metadata(
        &splat2tiles_tiles::tiling::load::load_tileset(&dir.join("tileset.json")).unwrap(),
    );
    for tr in traces {
        // `ONLY=<part of a trace label>` runs that trace alone.
        if std::env::var("ONLY").is_ok_and(|o| !label(&tr).contains(&o)) {
            continue;
        }
        let needed: Vec<Vec<TileKey>> = tr.poses.iter().map(|p| truth.needed_at(&cfg, p)).collect();
        let warm = |log: &splat2tiles_lab::sim::session::SessionLog| {
            let resident = held_tiles(log);
            let views = tick_views(log, needed.iter().map(Vec::as_slice), &resident);
            // Warm from the time the link needs for the first cut at Low (`sim::score`).
            let warm_at = link_warm_up(
                &views,
                |k| lw_meta.get(k).map_or(0, |m| m.1[3] as u64),
                1.25e6,
                0.04,
            );
            let chr = cache_hits_with(&views, WarmUp::At(warm_at));
            (
                (chr.warm, chr.first),
                breakdown_with(log, &views, WarmUp::At(warm_at)),
            )
        };
        let knob = |k: &str| std::env::var(k).ok().map(|v| v.parse::<f64>().unwrap());
        let tuned = [
            "PREDICT_STEP",
            "URGENT",
            "LATENCY",
            "PLAN_STEP",
            "REPLAN",
            "HORIZON",
            "PLANNER",
            "SET_ASIDE",
            "LOW_UNDER_OVERLOAD",
        ]
        .iter()
        .any(|k| knob(k).is_some());
        let run = |p: &str| {
            if !tuned {
                return session(&dir, &tr, p, Planner::Dp, &net, budget);
            }
            let mut c = ClientConfig {
                max_concurrent: 4,
                predictor: PredictorKind::from_name(p).unwrap_or(PredictorKind::Reactive),
                memory_budget_bytes: budget,
                ..ClientConfig::default()
            };
            if let Some(v) = knob("PREDICT_STEP") {
                c.predict_step_s = v;
            }
            if let Some(v) = knob("URGENT") {
                c.plan.urgent_s = v;
            }
            if let Some(v) = knob("LATENCY") {
                c.plan.latency_s = v;
            }
            if let Some(v) = knob("PLAN_STEP") {
                c.plan.step_s = v;
            }
            if let Some(v) = knob("REPLAN") {
                c.replan_s = v;
            }
            if let Some(v) = knob("HORIZON") {
                c.predict_horizon_s = v;
            }
            if let Some(v) = knob("PLANNER") {
                c.plan.planner = Planner::ALL[v as usize];
            }
            if let Some(v) = knob("SET_ASIDE") {
                c.set_aside_late = v != 0.0;
            }
            if let Some(v) = knob("LOW_UNDER_OVERLOAD") {
                c.low_under_overload = v != 0.0;
            }
            let opts = SessionOptions {
                predictor: (p == "oracle").then(|| {
                    Box::new(Oracle {
                        trace: tr.poses.clone(),
                    }) as Box<dyn splat2tiles_stream::predict::Predictor + Send>
                }),
                ..SessionOptions::default()
            };
            run_session(&dir, c, &tr.poses, &net, opts)
        };
        let oracle = run("oracle");
        // `SECOND=linear` (or another predictor) in place of reactive in the second column.
        let second = std::env::var("SECOND").unwrap_or_else(|_| "reactive".into());
        let reactive = run(&second);
        let ((ow, of), why) = warm(&oracle);
        let ((rw, _), _) = warm(&reactive);
        eprintln!(
            "  {}: plans trusting the deadlines (0 with SET_ASIDE=0) (under overload or setting aside): \
             oracle {}/{} ({}), \
             {second} {}/{} ({})",
            label(&tr),
            oracle.trusted_plans,
            oracle.plans,
            oracle.overload_plans,
            reactive.trusted_plans,
            reactive.plans,
            reactive.overload_plans
        );
        oracle_first.hits += of.hits;
        oracle_first.n += of.n;
        let plan_times: Vec<f64> = {
            let mut v: Vec<f64> = oracle.ticks.iter().map(|t| t.last_plan_s).collect();
            v.dedup();
            v
        };
        let (horizon, step) = (cfg.predict_horizon_s, cfg.predict_step_s);
        let mut cut_at: HashMap<u64, Vec<TileKey>> = HashMap::new();
        let mut c = [0u64; 13];
        let mut lead = vec![];
        // Per planned-but-late miss: first plan before the entry, due after it, asked after it,
        // requests in flight meanwhile.
        type Late = (f64, f64, f64, f64);
        let mut planned_late: Vec<Late> = vec![];
        let dt = if tr.poses.len() > 1 {
            (tr.poses[tr.poses.len() - 1].t - tr.poses[0].t) / (tr.poses.len() - 1) as f64
        } else {
            1.0
        };
        for m in why.list.iter().filter(|m| m.warm) {
            let i = match m.cause {
                Cause::Evicted => 0,
                Cause::InFlight => 1,
                Cause::Aborted => 2,
                Cause::Refused => 3,
                Cause::Late => 4,
                Cause::Never => 5,
            };
            c[i] += 1;
            if m.cause == Cause::InFlight {
                lead.push(m.t - m.first_request.unwrap_or(m.t));
            }
            if matches!(m.cause, Cause::Late | Cause::Never) {
                if let (Some(due), Some(fp)) = (m.planned_due, m.first_planned) {
                    c[6] += 1;
                    let busy: Vec<usize> = oracle
                        .ticks
                        .iter()
                        .filter(|t| t.t >= fp && t.t < m.t)
                        .map(|t| t.in_flight)
                        .collect();
                    planned_late.push((
                        m.t - fp,
                        due - m.t,
                        m.first_request.map_or(f64::NAN, |r| r - m.t),
                        busy.iter().sum::<usize>() as f64 / busy.len().max(1) as f64,
                    ));
                } else if m.predicted_at.is_some() {
                    c[7] += 1;
                } else {
                    let sampled = plan_times
                        .iter()
                        .filter(|&&p| p <= m.t && p > m.t - horizon)
                        .flat_map(|&p| {
                            (1..=(horizon / step) as usize).map(move |k| p + k as f64 * step)
                        })
                        .any(|s| {
                            let cut = cut_at.entry(s.to_bits()).or_insert_with(|| {
                                sample_trace(&tr.poses, s)
                                    .map_or(vec![], |p| truth.needed_at(&cfg, &p))
                            });
                            cut.contains(&m.key)
                        });
                    c[if sampled { 8 } else { 9 }] += 1;
                }
            }
            c[10] += (m.dwell_ticks == 1) as u64;
            c[11] += ((m.dwell_ticks as f64) * dt < 0.5) as u64;
            c[12] += !m.in_client_view as u64;
        }
        if !planned_late.is_empty() {
            let med = |f: &dyn Fn(&Late) -> f64| {
                let mut v: Vec<f64> = planned_late
                    .iter()
                    .map(f)
                    .filter(|x| x.is_finite())
                    .collect();
                v.sort_by(f64::total_cmp);
                v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
            };
            eprintln!(
                "  {}: {} planned but not asked before the entry: median first plan {:.2} s before \
                 it, due {:+.2} s after it, asked {:+.2} s after it, requests in flight meanwhile \
                 {:.2} (of {}); {} evictions, {} aborts, {} requests",
                label(&tr),
                planned_late.len(),
                med(&|x| x.0),
                med(&|x| x.1),
                med(&|x| x.2),
                med(&|x| x.3),
                4,
                oracle.evictions,
                oracle.aborts,
                oracle.requests.len()
            );
        }
        if std::env::var("DETAIL").is_ok() {
            let (mut in_last, mut rank, mut open_up, mut open_new, mut open_due) =
                (0, 0.0, 0, 0, 0.0);
            let mut n = 0;
            let mut open_lvl = [0u32; 4];
            for m in why
                .list
                .iter()
                .filter(|m| m.warm && matches!(m.cause, Cause::Late | Cause::Never))
            {
                let j = oracle.ticks.partition_point(|t| t.t < m.t);
                let prev = &oracle.ticks[j.saturating_sub(1)];
                if let Some(r) = prev.planned.iter().position(|x| x.0 == m.key) {
                    in_last += 1;
                    rank += r as f64 / prev.planned.len() as f64;
                }
                n += 1;
                for r in oracle.requests.iter().filter(|r| {
                    r.key.is_some() && r.start_s <= m.t && r.end_s.is_none_or(|e| e > m.t)
                }) {
                    let k = r.key.unwrap();
                    if prev.resident.iter().any(|x| x.0 == k) {
                        open_up += 1
                    } else {
                        open_new += 1
                    }
                    open_lvl[r.level.map_or(0, |l| l.index())] += 1;
                    if let Some(d) = prev.planned.iter().find(|x| x.0 == k) {
                        open_due += d.1 - m.t;
                    }
                }
            }
            let mut bins = [(0u32, 0u32); 12];
            for m in why.list.iter().filter(|m| m.warm) {
                bins[((m.t - tr.poses[0].t) / 5.0).min(11.0) as usize].1 += 1;
            }
            {
                let mut ever = std::collections::HashSet::new();
                for (k, n) in needed.iter().enumerate() {
                    for key in n {
                        if ever.insert(*key) && k > 0 {
                            bins[((tr.poses[k].t - tr.poses[0].t) / 5.0).min(11.0) as usize].0 += 1;
                        }
                    }
                }
            }
            eprintln!("  DETAIL first-time entries / warm misses per 5 s: {bins:?}");
            // Earliest-deadline-first at Low over a 10 Mbit/s link with perfect foresight from
            // the first tick: the first cut due at t0, every first-time entry at its tick.
            let ts =
                splat2tiles_tiles::tiling::load::load_tileset(&dir.join("tileset.json")).unwrap();
            let meta = splat2tiles_tiles::variants::content_variant_metadata(&ts);
            for lvl in [3usize, 0] {
                let mut jobs: Vec<(f64, u64)> = vec![];
                let mut ever = std::collections::HashSet::new();
                for (k, n) in needed.iter().enumerate() {
                    for key in n {
                        if ever.insert(*key) {
                            jobs.push((
                                tr.poses[k].t,
                                meta.get(key).map_or(0, |m| m.1[lvl] as u64),
                            ));
                        }
                    }
                }
                // Perfect foresight from the first tick, the first cut (t = 0 entries, late
                // whatever a client does) set aside: the fewest late first-time entries any
                // client can reach over this link (Moore-Hodgson over every later entry).
                for first_cut_first in [false, true] {
                    let t0 = tr.poses[0].t;
                    // Or the first cut fetched first (a client that shows the first view).
                    let cut: u64 = jobs.iter().filter(|j| j.0 <= t0).map(|j| j.1).sum();
                    let start = t0
                        + if first_cut_first {
                            cut as f64 / 1.25e6
                        } else {
                            0.0
                        };
                    let late = fewest_late(jobs.iter().filter(|j| j.0 > t0), start);
                    eprintln!(
                        "  DETAIL level {lvl}: fewest late first-time entries from t0, the first cut {}: {late} of {}",
                        if first_cut_first {
                            "fetched first"
                        } else {
                            "set aside"
                        },
                        jobs.iter().filter(|j| j.0 > t0).count()
                    );
                }
                // From the oracle's warm-up tick on, the link free, only the later entries.
                let warm_at = needed
                    .iter()
                    .zip(&oracle.ticks)
                    .skip(1)
                    .find(|(n, t)| {
                        !n.is_empty() && n.iter().all(|k| t.resident.iter().any(|r| r.0 == *k))
                    })
                    .map_or(f64::INFINITY, |(_, t)| t.t);
                let jobs: Vec<(f64, u64)> = jobs.into_iter().filter(|j| j.0 > warm_at).collect();
                let (late, late_s) = (fewest_late(&jobs, warm_at), 0.0);
                for until in [12.0, 15.0, 20.0] {
                    let due: u64 = jobs
                        .iter()
                        .filter(|j| j.0 <= tr.poses[0].t + until)
                        .map(|j| j.1)
                        .sum();
                    eprintln!(
                        "  DETAIL level {lvl}: {} KB of first entries in ({warm_at:.1}, {until}] s; the link carries {} KB",
                        due / 1000,
                        ((tr.poses[0].t + until - warm_at) * 1250.0) as u64
                    );
                }
                // Every tile needed after the warm-up and not held at it (first-time entries and
                // re-entries of tiles missed before it), due at its first tick after the warm-up.
                {
                    let wt = oracle.ticks.iter().find(|t| t.t >= warm_at);
                    let held: std::collections::HashSet<TileKey> = wt
                        .map(|t| t.resident.iter().map(|r| r.0).collect())
                        .unwrap_or_default();
                    let mut seen2 = std::collections::HashSet::new();
                    let mut jobs2: Vec<(f64, u64, bool)> = vec![];
                    let first_jobs: std::collections::HashSet<(u64, u64)> =
                        jobs.iter().map(|j| (j.0.to_bits(), j.1)).collect();
                    for (k, n) in needed.iter().enumerate() {
                        let t = tr.poses[k].t;
                        if t <= warm_at {
                            continue;
                        }
                        for key in n {
                            if !held.contains(key) && seen2.insert(*key) {
                                let b = meta.get(key).map_or(0, |m| m.1[lvl] as u64);
                                jobs2.push((t, b, first_jobs.contains(&(t.to_bits(), b))));
                            }
                        }
                    }
                    let plain: Vec<(f64, u64)> = jobs2.iter().map(|j| (j.0, j.1)).collect();
                    let kb: u64 = plain.iter().map(|j| j.1).sum::<u64>() / 1000;
                    let (mut clock3, mut late3, mut late3_first) = (warm_at, 0, 0);
                    for (due, b, first) in &jobs2 {
                        clock3 += *b as f64 / 1.25e6;
                        if clock3 > *due + 1e-9 {
                            late3 += 1;
                            late3_first += usize::from(*first);
                        }
                    }
                    eprintln!(
                        "  DETAIL level {lvl}: the same, EDF with every job fetched: {late3} late ({late3_first} first-time)"
                    );
                    eprintln!(
                        "  DETAIL level {lvl}: first-time entries and re-entries of tiles not held at the warm-up: {} jobs ({} first-time), {kb} KB, fewest late {}",
                        jobs2.len(),
                        jobs2.iter().filter(|j| j.2).count(),
                        fewest_late(&plain, warm_at)
                    );
                }
                // The same, every job fetched (a client that repairs what it missed).
                let (mut clock2, mut late2) = (warm_at, 0);
                for (due, b) in &jobs {
                    clock2 += *b as f64 / 1.25e6;
                    if clock2 > *due + 1e-9 {
                        late2 += 1;
                    }
                }
                eprintln!(
                    "  DETAIL EDF level {lvl}, every entry fetched: {late2} of {} late",
                    jobs.len()
                );
                eprintln!(
                    "  DETAIL EDF level {lvl} from warm-up {warm_at:.1} s: {late} of {} first entries late (max {late_s:.1} s)",
                    jobs.len()
                );
            }
            eprintln!("  DETAIL open requests at late misses by level {open_lvl:?}");
            let t0 = tr.poses[0].t;
            {
                // Finished content downloads per second by when their tile first entered the
                // needed cut: before the request, after its end (lead in s), or never.
                let mut entry: HashMap<TileKey, f64> = HashMap::new();
                for (k, n) in needed.iter().enumerate() {
                    for key in n {
                        entry.entry(*key).or_insert(tr.poses[k].t);
                    }
                }
                let mut seen = std::collections::HashSet::new();
                for sec in (0..20).step_by(2) {
                    let (a, b) = (t0 + sec as f64, t0 + sec as f64 + 2.0);
                    let (mut before, mut never, mut refetch, mut leads) = (0, 0, 0, vec![]);
                    let (mut before_view, mut before_again) = (0, 0);
                    let (mut kb, mut n_done, mut aborted) = (0u64, 0u64, 0u64);
                    for r in oracle
                        .requests
                        .iter()
                        .filter(|r| r.key.is_some() && r.end_s.is_some_and(|e| e >= a && e < b))
                    {
                        if r.outcome == splat2tiles_lab::sim::transport::Outcome::Done {
                            kb += r.bytes / 1000;
                            n_done += 1;
                        } else {
                            aborted += 1;
                        }
                    }
                    eprintln!(
                        "  DETAIL {sec:2} s: done {n_done} ({} KB mean), ended otherwise {aborted}",
                        kb / n_done.max(1)
                    );
                    for r in oracle.requests.iter().filter(|r| {
                        r.outcome == splat2tiles_lab::sim::transport::Outcome::Done
                            && r.end_s.is_some_and(|e| e >= a && e < b)
                    }) {
                        let Some(k) = r.key else { continue };
                        if !seen.insert(k) {
                            refetch += 1;
                            continue;
                        }
                        match entry.get(&k) {
                            None => never += 1,
                            Some(&e) if e <= r.start_s => {
                                before += 1;
                                let at = tr.poses.partition_point(|p| p.t < r.start_s);
                                let needed_at =
                                    |j: usize| needed.get(j).is_some_and(|n| n.contains(&k));
                                if needed_at(at) {
                                    before_view += 1;
                                } else if (at..needed.len()).any(needed_at) {
                                    before_again += 1;
                                }
                                if std::env::var("DETAIL_BEFORE").is_ok() && (10..14).contains(&sec)
                                {
                                    let ti = oracle
                                        .ticks
                                        .partition_point(|t| t.t <= r.start_s)
                                        .saturating_sub(1);
                                    let tk = &oracle.ticks[ti];
                                    let next = (at..needed.len())
                                        .find(|&j| needed_at(j))
                                        .map(|j| tr.poses[j].t - r.start_s);
                                    let due =
                                        tk.planned.iter().find(|p| p.0 == k).map(|p| p.1 - tk.t);
                                    let pred =
                                        tk.predicted.iter().find(|p| p.0 == k).map(|p| p.1 - tk.t);
                                    eprintln!(
                                        "  DETAIL_BEFORE start {:.2} tile {k:?} level {:?} client view {} planned due {due:?} predicted {pred:?} scorer next needs in {next:?} entered {:.2}",
                                        r.start_s - t0,
                                        r.level,
                                        tk.view_set.contains(&k),
                                        e - t0
                                    );
                                }
                            }
                            Some(&e) => leads.push(e - r.end_s.unwrap()),
                        }
                    }
                    leads.sort_by(f64::total_cmp);
                    let q = |f: f64| {
                        leads
                            .get((f * leads.len() as f64) as usize)
                            .copied()
                            .unwrap_or(f64::NAN)
                    };
                    eprintln!(
                        "  DETAIL {sec:2}-{} s: first downloads: entered before {before} (in view at the request {before_view}, needed again later {before_again}), never {never}, later {} (lead s p10/p50/p90 {:.1}/{:.1}/{:.1}); repeat downloads {refetch}",
                        sec + 2,
                        leads.len(),
                        q(0.1),
                        q(0.5),
                        q(0.9)
                    );
                }
            }
            for sec in 0..20 {
                let (a, b) = (t0 + sec as f64, t0 + sec as f64 + 1.0);
                let mut new_b = [0u64; 4];
                let mut up_b = 0u64;
                for r in oracle.requests.iter().filter(|r| {
                    r.outcome == splat2tiles_lab::sim::transport::Outcome::Done
                        && r.end_s.is_some_and(|e| e >= a && e < b)
                }) {
                    let (Some(k), Some(l)) = (r.key, r.level) else {
                        continue;
                    };
                    let at = oracle.ticks.partition_point(|t| t.t <= r.start_s);
                    if at > 0 && oracle.ticks[at - 1].resident.iter().any(|x| x.0 == k) {
                        up_b += r.bytes
                    } else {
                        new_b[l.index()] += r.bytes
                    }
                }
                let ms = why.list.iter().filter(|m| m.t >= a && m.t < b).count();
                let ent = bins.len();
                let _ = ent;
                eprintln!(
                    "  DETAIL {sec:2} s: new KB by level {:?}, upgrade KB {}, misses {ms}",
                    new_b.map(|x| x / 1000),
                    up_b / 1000
                );
            }
            for sec in [5.0, 6.0, 7.0, 8.0, 9.0, 10.0, 11.0, 12.0, 13.0] {
                let j = oracle.ticks.partition_point(|t| t.t - tr.poses[0].t < sec);
                let tk = &oracle.ticks[j.min(oracle.ticks.len() - 1)];
                let held: std::collections::HashSet<_> = tk.resident.iter().map(|r| r.0).collect();
                let pred: Vec<_> = tk
                    .predicted
                    .iter()
                    .filter(|p| !held.contains(&p.0))
                    .collect();
                let soon = |d: f64| d - tk.t;
                let planned: std::collections::HashSet<_> =
                    tk.planned.iter().map(|p| p.0).collect();
                let missing_pred = pred.len();
                let missing_planned = pred.iter().filter(|p| planned.contains(&p.0)).count();
                let pred5 = pred.iter().filter(|p| soon(p.1) < 5.0).count();
                let planned5 = pred
                    .iter()
                    .filter(|p| soon(p.1) < 5.0 && planned.contains(&p.0))
                    .count();
                let unplanned: Vec<_> = pred
                    .iter()
                    .filter(|p| soon(p.1) < 5.0 && !planned.contains(&p.0))
                    .collect();
                let open = unplanned
                    .iter()
                    .filter(|p| {
                        oracle.requests.iter().any(|r| {
                            r.key == Some(p.0)
                                && r.start_s <= tk.t
                                && r.end_s.is_none_or(|e| e > tk.t)
                        })
                    })
                    .count();
                let ever_req = unplanned
                    .iter()
                    .filter(|p| {
                        oracle
                            .requests
                            .iter()
                            .any(|r| r.key == Some(p.0) && r.start_s <= tk.t)
                    })
                    .count();
                let dues: Vec<String> = unplanned
                    .iter()
                    .take(8)
                    .map(|p| format!("{:.1}", soon(p.1)))
                    .collect();
                eprintln!(
                    "  DETAIL   unplanned due < 5 s: {}, open request {open}, requested before {ever_req}; dues {dues:?}",
                    unplanned.len()
                );
                eprintln!(
                    "  DETAIL t={sec}: last plan {:.2}, predicted not held {missing_pred} (due < 5 s: {pred5}), of them planned {missing_planned} ({planned5}); planned total {}, held {}",
                    tk.last_plan_s - tr.poses[0].t,
                    tk.planned.len(),
                    held.len()
                );
            }
            let est: Vec<f64> = oracle
                .ticks
                .iter()
                .skip(oracle.ticks.len() / 10)
                .map(|t| t.bandwidth_estimate * 8e-6)
                .collect();
            eprintln!(
                "  DETAIL estimate mean {:.2} Mbit/s, min {:.2}, max {:.2}",
                est.iter().sum::<f64>() / est.len().max(1) as f64,
                est.iter().copied().fold(f64::INFINITY, f64::min),
                est.iter().copied().fold(0.0, f64::max)
            );
            eprintln!(
                "  DETAIL {}: {n} late/never misses: in the plan of the tick before {in_last} (mean rank {:.2}); requests open at those entries: {open_up} upgrades, {open_new} new, mean due {:.2} s after entry",
                label(&tr),
                rank / in_last.max(1) as f64,
                open_due / (open_up + open_new).max(1) as f64
            );
        }
        // What the link carried: completed bytes by level, and how many were upgrades of a tile
        // held at the request's start.
        let mut by_level = [0u64; 4];
        let mut upgrade_bytes = 0u64;
        for r in &oracle.requests {
            let (Some(k), Some(l)) = (r.key, r.level) else {
                continue;
            };
            by_level[l.index()] += r.bytes;
            let at = oracle.ticks.partition_point(|t| t.t <= r.start_s);
            if at > 0 && oracle.ticks[at - 1].resident.iter().any(|x| x.0 == k) {
                upgrade_bytes += r.bytes;
            }
        }
        eprintln!(
            "  {}: MB received by level Best/High/Medium/Low {:?}, upgrades {:.1} MB",
            label(&tr),
            by_level.map(|b| (b as f64 / 1e5).round() / 10.0),
            upgrade_bytes as f64 / 1e6
        );
        let mean_lead = lead.iter().sum::<f64>() / lead.len().max(1) as f64;
        eprintln!(
            "| {} | {} | {} | {} | {} ({mean_lead:.2}) | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            label(&tr),
            pct(ow),
            pct(rw),
            c[0],
            c[1],
            c[2],
            c[3],
            c[4],
            c[5],
            c[6],
            c[7],
            c[8],
            c[9],
            c[10],
            c[11],
            c[12]
        );
        oracle_all.hits += ow.hits;
        oracle_all.n += ow.n;
        reactive_all.hits += rw.hits;
        reactive_all.n += rw.n;
        for (s, v) in sums.iter_mut().zip(c) {
            *s += v;
        }
        assert!(ow.hits <= ow.n && why.misses <= why.entries, "{why:?}");
    }
    eprintln!(
        "| all | {} | {} | {} |",
        pct(oracle_all),
        pct(reactive_all),
        sums.map(|v| v.to_string()).join(" | ")
    );
    eprintln!("oracle over every first-time entry: {}", pct(oracle_first));
}

/// Moore-Hodgson: the fewest late jobs `(due s, bytes)`, in deadline order, on a 10 Mbit/s link
/// free from `start_s` (earliest deadline first, dropping the largest job whenever the schedule
/// runs late).
fn fewest_late<'a>(jobs: impl IntoIterator<Item = &'a (f64, u64)>, start_s: f64) -> usize {
    let (mut clock, mut late) = (start_s, 0);
    let mut heap = std::collections::BinaryHeap::new();
    for (due, b) in jobs {
        clock += *b as f64 / 1.25e6;
        heap.push(*b);
        if clock > *due + 1e-9 {
            clock -= heap.pop().unwrap() as f64 / 1.25e6;
            late += 1;
        }
    }
    late
}

/// `hits/n (pct%)` of a hit ratio, as the tables print it.
fn pct(r: Ratio) -> String {
    format!(
        "{}/{} ({:.1}%)",
        r.hits,
        r.n,
        100.0 * r.rate().unwrap_or(0.0)
    )
}
