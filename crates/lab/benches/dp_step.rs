//! DC-DP accuracy vs solve time over its byte resolution (not a test): the same
//! planning problems solved with 256 to 65,536 (reference) byte bins over a 10 ms link forecast,
//! each plan executed exactly (continuous time) over the true link, scored by on-time utility and
//! misses.
//!
//! Run: `cargo bench --bench dp_step` (release). Problems: 20 per link, 200 candidates each, Best
//! sizes log-uniform 20-300 KB with the streaming city's measured variant ratios (High 0.51,
//! Medium 0.48, Low 0.30 of Best: `sim::stream_city`, 105.6/53.6/51.2/31.7 MiB), utilities 1 /
//! 0.99 / 0.95 / 0.85 (+-0.01), deadlines: a fifth due in 0.25-1 s, the rest in 0.5-10 s; horizon
//! 10 s (the client's); RTT 40 ms with 4 requests in flight (`PlanStepConfig::concurrency`: the
//! first 30 ms carry no new bytes, 10 ms per request; one row set without RTT). Links: 10 and 50
//! Mbit/s constant, and the
//! HSDPA log `bus.ljansbakken-oslo-report.2010-09-28_1407CEST.log` x10 (a 4G-like link;
//! `data/network-traces/README.md`) from 20 s in, planned on its own future
//! (`bandwidth::future_pieces`, the oracle network). Execution: downloads one after another in
//! plan order, each `bytes` over the true link then its 10 ms; a candidate counts if it is
//! complete by its deadline. Solve time: median of 5 runs per problem, one thread.

use std::time::Instant;

use splat2tiles_core::rng::SplitMix64;
use splat2tiles_lab::sim::network::read_log;
use splat2tiles_stream::bandwidth::future_pieces;
use splat2tiles_stream::catalog::{LEVELS, Variant};
use splat2tiles_stream::plan::{Candidate, Plan, PlanRequest, solve_dp};
use splat2tiles_stream::planner::{LinkForecast, PlanStepConfig};

/// A link of the table: name, `(start s, bytes/s)` pieces, RTT (s).
type Link = (String, Vec<(f64, f64)>, f64);

const HORIZON_S: f64 = 10.0;
const CONCURRENCY: usize = 4;
const BINS: [usize; 6] = [65_536, 256, 1024, 4096, 16_384, 65_536];
const STEP_S: f64 = 0.01;

fn problem(seed: u64) -> Vec<Candidate> {
    let mut rng = SplitMix64::new(seed);
    let ratio = [1.0, 0.51, 0.485, 0.30];
    let util = [1.0, 0.99, 0.95, 0.85];
    (0..200)
        .map(|i| {
            let best = (20e3f64.ln() + rng.f64() * (300e3f64 / 20e3).ln()).exp();
            let variants: [Variant; LEVELS] = std::array::from_fn(|j| Variant {
                bytes: (best * ratio[j]) as u64,
                utility: if j == 0 {
                    1.0
                } else {
                    util[j] + rng.range(-0.01, 0.01)
                },
            });
            let deadline = if rng.f64() < 0.2 {
                rng.range(0.25, 1.0)
            } else {
                rng.range(0.5, HORIZON_S)
            };
            Candidate {
                tile: i,
                deadline,
                distance: 0.0,
                variants,
            }
        })
        .collect()
}

/// Seconds to move `bytes` over `pieces` (`(start s, bytes/s)`) starting at `t0`.
fn transfer_end(pieces: &[(f64, f64)], t0: f64, bytes: f64) -> f64 {
    let mut left = bytes;
    let mut t = t0;
    let mut k = pieces.partition_point(|p| p.0 <= t).saturating_sub(1);
    loop {
        let rate = pieces[k].1;
        let end = pieces.get(k + 1).map_or(f64::INFINITY, |p| p.0);
        let cap = rate * (end - t);
        if cap >= left {
            return if rate > 0.0 { t + left / rate } else { t };
        }
        left -= cap;
        t = end;
        k += 1;
        if k >= pieces.len() {
            return f64::INFINITY;
        }
    }
}

/// Executes `plan` over the true link: (on-time utility, misses).
fn execute(cands: &[Candidate], plan: &Plan, pieces: &[(f64, f64)], rtt: f64) -> (f64, usize) {
    let gap = rtt * (1.0 - 1.0 / CONCURRENCY as f64);
    let per = rtt / CONCURRENCY as f64;
    let mut clock = gap;
    let mut on_time = vec![false; cands.len()];
    let mut utility = 0.0;
    for f in &plan.fetches {
        let c = &cands[f.candidate];
        let v = c.variants[f.level.index()];
        clock = transfer_end(pieces, clock, v.bytes as f64) + per;
        if clock <= c.deadline + 1e-9 {
            utility += v.utility;
            on_time[f.candidate] = true;
        }
    }
    (utility, on_time.iter().filter(|&&x| !x).count())
}

fn main() {
    let root = std::path::PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."));
    let hsdpa = read_log(
        &root.join("data/network-traces/hsdpa/bus.ljansbakken-oslo-report.2010-09-28_1407CEST.log"),
        10.0,
    )
    .expect("HSDPA log");
    let looped = hsdpa.looped(1000.0);
    let links: Vec<Link> = vec![
        ("10 Mbit/s, no RTT".into(), vec![(0.0, 10e6 / 8.0)], 0.0),
        ("10 Mbit/s".into(), vec![(0.0, 10e6 / 8.0)], 0.04),
        ("50 Mbit/s".into(), vec![(0.0, 50e6 / 8.0)], 0.04),
        (
            format!(
                "HSDPA bus log x10 (recorded mean {:.2} Mbit/s)",
                hsdpa.mean_bytes_per_s() * 8.0 / 1e6 / 10.0
            ),
            future_pieces(&looped, 20.0, HORIZON_S + 1.0),
            0.04,
        ),
    ];
    println!(
        "| link | byte bins | on-time utility (% of 65,536 bins) | misses (of 200) | fetches | solve ms (median) |"
    );
    println!("|---|---:|---:|---:|---:|---:|");
    for (name, pieces, rtt) in &links {
        let mut rows = vec![];
        // The first (reference) run also warms the caches; it is not printed.
        for bins in BINS {
            let cfg = PlanStepConfig {
                step_s: STEP_S,
                horizon_s: HORIZON_S,
                latency_s: *rtt,
                concurrency: CONCURRENCY,
                ..PlanStepConfig::default()
            };
            let link = LinkForecast {
                pieces: pieces.clone(),
                in_flight_bytes: 0,
            };
            let steps = (HORIZON_S / cfg.step_s).round() as usize;
            let bw = link.steps(&cfg, steps);
            let (mut util, mut misses, mut fetches, mut times) = (0.0, 0usize, 0usize, vec![]);
            for seed in 0..20u64 {
                let cands = problem(seed);
                let req = PlanRequest {
                    candidates: &cands,
                    bandwidth: &bw,
                    step_s: cfg.step_s,
                    horizon_steps: steps,
                    memory_budget: u64::MAX,
                    latency_s: rtt / CONCURRENCY as f64,
                    bins,
                };
                let mut plan = Plan::default();
                let mut t = vec![];
                for _ in 0..5 {
                    let t0 = Instant::now();
                    plan = std::hint::black_box(solve_dp(&req));
                    t.push(t0.elapsed().as_secs_f64() * 1e3);
                }
                t.sort_by(f64::total_cmp);
                times.push(t[2]);
                let (u, m) = execute(&cands, &plan, pieces, *rtt);
                util += u;
                misses += m;
                fetches += plan.fetches.len();
            }
            times.sort_by(f64::total_cmp);
            rows.push((
                bins,
                util / 20.0,
                misses as f64 / 20.0,
                fetches as f64 / 20.0,
                times[10],
            ));
        }
        let base = rows[0].1;
        for (bins, u, m, f, ms) in rows.into_iter().skip(1) {
            println!(
                "| {name} | {bins} | {u:.1} ({:.1}%) | {m:.1} | {f:.1} | {ms:.2} |",
                100.0 * u / base
            );
        }
    }
}
