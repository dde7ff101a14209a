//! DC-DP checks: equals brute force on random small instances (bins of one byte); valid, deterministic answers with
//! zero bandwidth, passed deadlines, ties, an empty list and a binding memory budget.

use splat2tiles_core::rng::SplitMix64;
use splat2tiles_stream::catalog::{LEVELS, Variant};
use splat2tiles_stream::plan::{
    Candidate, Plan, PlanRequest, Planner, capacity_prefix, overhead_bytes, solve_dp,
};

/// The link's cumulative bytes at `t` (linear within a step, flat past the horizon).
fn carried(c: &[f64], step_s: f64, t: f64) -> f64 {
    let x = t / step_s;
    let k = x.floor() as usize;
    if k + 1 >= c.len() {
        return c[c.len() - 1];
    }
    c[k] + (x - k as f64) * (c[k + 1] - c[k])
}

/// Exhaustive search: every assignment of skip/level per candidate, downloaded in deadline order
/// (ties by index) back to back from time 0, each costing its bytes plus the per-request
/// overhead, rounded up to whole bytes (the DP's bins are one byte on these small links);
/// feasible when the work up to each download is within what the link carries by its deadline.
fn brute(req: &PlanRequest) -> f64 {
    let n = req.candidates.len();
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| {
        req.candidates[a]
            .deadline
            .total_cmp(&req.candidates[b].deadline)
            .then(a.cmp(&b))
    });
    let c = capacity_prefix(req.bandwidth, req.step_s, req.horizon_steps);
    assert!(c[c.len() - 1] <= req.bins as f64, "bins of one byte");
    let o = overhead_bytes(req, &c);
    let mut best = 0.0f64;
    let total = (LEVELS + 1).pow(n as u32);
    for code in 0..total {
        let mut x = code;
        let mut work = 0.0;
        let mut util = 0.0;
        let mut bytes = 0u64;
        let mut ok = true;
        for &i in &order {
            let pick = x % (LEVELS + 1);
            x /= LEVELS + 1;
            if pick == 0 {
                continue;
            }
            let v = req.candidates[i].variants[pick - 1];
            work += (v.bytes as f64 + o - 1e-9).ceil().max(1.0);
            let d = req.candidates[i].deadline;
            if d.is_nan() || d < 0.0 || work > (carried(&c, req.step_s, d) + 1e-9).floor() {
                ok = false;
                break;
            }
            util += v.utility;
            bytes += v.bytes;
        }
        if ok && bytes <= req.memory_budget {
            best = best.max(util);
        }
    }
    best
}

fn random_cands(rng: &mut SplitMix64, n: usize) -> Vec<Candidate> {
    (0..n)
        .map(|i| {
            let best = rng.range(1.0, 10.0).round();
            Candidate {
                tile: i,
                deadline: rng.range(0.0, 3.0),
                distance: rng.range(0.0, 100.0),
                variants: std::array::from_fn(|j| Variant {
                    bytes: (best * [1.0, 0.77, 0.65, 0.53][j]).ceil() as u64,
                    utility: [1.0, 0.98, 0.95, 0.90][j] - rng.range(0.0, 0.02) * j as f64,
                }),
            }
        })
        .collect()
}

fn check_valid(req: &PlanRequest, p: &Plan) {
    let mut seen = vec![false; req.candidates.len()];
    let mut prev = 0.0;
    let mut u = 0.0;
    let mut b = 0;
    for f in &p.fetches {
        assert!(!seen[f.candidate], "candidate chosen twice");
        seen[f.candidate] = true;
        assert!(f.finish_s >= prev - 1e-9, "finish times go back");
        prev = f.finish_s;
        let c = &req.candidates[f.candidate];
        assert!(f.finish_s <= c.deadline + 1e-9, "deadline broken");
        u += c.variants[f.level.index()].utility;
        b += c.variants[f.level.index()].bytes;
    }
    assert!((u - p.utility).abs() < 1e-9);
    assert_eq!(b, p.bytes);
    assert!(p.bytes <= req.memory_budget);
}

#[test]
fn dp_equals_brute_force_on_random_instances() {
    let mut rng = SplitMix64::new(7);
    for case in 0..150 {
        let n = 1 + rng.below(5);
        let cands = random_cands(&mut rng, n);
        let bw: Vec<f64> = (0..30).map(|_| rng.range(0.0, 60.0).round()).collect();
        let latency = if case % 3 == 0 { 0.2 } else { 0.0 };
        let req = PlanRequest {
            candidates: &cands,
            bandwidth: &bw,
            step_s: 0.1,
            horizon_steps: 30,
            memory_budget: u64::MAX,
            latency_s: latency,
            bins: 1 << 16,
        };
        let p = solve_dp(&req);
        check_valid(&req, &p);
        let b = brute(&req);
        assert!(
            (p.utility - b).abs() < 1e-9,
            "case {case}: dp {} brute {b}",
            p.utility
        );
    }
}

#[test]
fn dp_with_memory_budget_is_feasible_and_close() {
    let mut rng = SplitMix64::new(11);
    for case in 0..60 {
        let cands = random_cands(&mut rng, 4);
        let bw = [40.0];
        let req = PlanRequest {
            candidates: &cands,
            bandwidth: &bw,
            step_s: 0.1,
            horizon_steps: 30,
            memory_budget: 8 + rng.below(12) as u64,
            latency_s: 0.0,
            bins: 1 << 16,
        };
        let p = solve_dp(&req);
        check_valid(&req, &p);
        let b = brute(&req);
        assert!(p.utility <= b + 1e-9, "case {case}");
        // Lagrangian answers lose at most one tile's utility here.
        assert!(
            p.utility >= b - 1.0 - 1e-9,
            "case {case}: {} vs {b}",
            p.utility
        );
    }
}

fn req_with<'a>(cands: &'a [Candidate], bw: &'a [f64]) -> PlanRequest<'a> {
    PlanRequest {
        candidates: cands,
        bandwidth: bw,
        step_s: 0.1,
        horizon_steps: 50,
        memory_budget: u64::MAX,
        latency_s: 0.0,
        bins: 0,
    }
}

#[test]
fn zero_bandwidth_empty_and_passed_deadlines() {
    let mut rng = SplitMix64::new(3);
    let cands = random_cands(&mut rng, 5);
    for planner in Planner::ALL {
        let p = planner.solve(&req_with(&cands, &[0.0]));
        assert!(p.fetches.is_empty(), "{}", planner.name());
        let p = planner.solve(&req_with(&cands, &[]));
        assert!(p.fetches.is_empty(), "{}", planner.name());
        let p = planner.solve(&req_with(&[], &[100.0]));
        assert_eq!(p, Plan::default());
    }
    let passed: Vec<Candidate> = cands
        .iter()
        .map(|c| Candidate {
            deadline: -1.0,
            ..*c
        })
        .collect();
    let p = solve_dp(&req_with(&passed, &[100.0]));
    assert!(p.fetches.is_empty());
    // NaN deadlines count as passed.
    let nan: Vec<Candidate> = cands
        .iter()
        .map(|c| Candidate {
            deadline: f64::NAN,
            ..*c
        })
        .collect();
    assert!(solve_dp(&req_with(&nan, &[100.0])).fetches.is_empty());
}

#[test]
fn ties_are_deterministic_and_prefer_smaller_downloads() {
    let v = Variant {
        bytes: 10,
        utility: 0.5,
    };
    let same: Vec<Candidate> = (0..6)
        .map(|i| Candidate {
            tile: i,
            deadline: 2.0,
            distance: 1.0,
            variants: [v; LEVELS],
        })
        .collect();
    let bw = [150.0];
    let a = solve_dp(&req_with(&same, &bw));
    let b = solve_dp(&req_with(&same, &bw));
    assert_eq!(a, b);
    // 2 s * 150 B/s = 300 B: all six fit.
    assert_eq!(a.fetches.len(), 6);
    // Equal utility at every level: the cheapest level (Low) is kept.
    let mut levels = same[0].variants;
    levels[0].bytes = 100;
    let one = [Candidate {
        variants: levels,
        ..same[0]
    }];
    let p = solve_dp(&req_with(&one, &bw));
    assert_eq!(p.fetches[0].level.index(), LEVELS - 1);
}

#[test]
fn baselines_respect_memory_and_are_deterministic() {
    let mut rng = SplitMix64::new(5);
    let cands = random_cands(&mut rng, 12);
    let mut req = req_with(&cands, &[30.0]);
    req.memory_budget = 40;
    for planner in Planner::ALL {
        let p = planner.solve(&req);
        assert!(p.bytes <= 40, "{}", planner.name());
        assert_eq!(p, planner.solve(&req));
    }
}
