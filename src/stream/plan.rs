//! Deadline-constrained quality selection (TileSplat sec. 3.4, eqs. 12-18) and the baselines of
//! its Table 5 (Greedy-Deadline, Greedy-Quality, Distance-Based).
//!
//! DP: candidates sorted by deadline (ties by input order) are downloaded one after another over
//! one link whose rate is piecewise constant per time step `delta` (eq. 12 via the prefix sums
//! `C(tau)` of `B(t) delta`). `U(i, tau)` is the best utility of the first `i` candidates with
//! every chosen download finished by step `tau`:
//! `U(i,tau) = max(U(i,tau-1), U(i-1,tau), max_j U(i-1, sigma_ij(tau)) + u_ij if tau <= D_i)`,
//! where `sigma_ij(tau)` is the latest start with `C(tau - L) - C(sigma) >= s_ij` (`L` = request
//! latency in steps) and `D_i` the deadline step. The first term (idle link) makes "complete by
//! tau" monotone, which eq. 18 as printed omits. Answer `U(N, T)`, back-tracked to a fetch list.
//! Memory (eq. 16) enters as a Lagrange multiplier on bytes, found by bisection, only when the
//! unconstrained optimum exceeds the budget (then the answer is feasible, not proven optimal).

use super::catalog::{LEVELS, Level, Variant};

/// A tile the planner may fetch.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Candidate {
    /// Caller's tile id.
    pub tile: usize,
    /// Seconds from now by which the download must be complete (predicted first visibility).
    pub deadline: f64,
    /// Distance from the camera (Distance-Based baseline).
    pub distance: f64,
    /// Variants, best first.
    pub variants: [Variant; LEVELS],
}

/// A planning problem.
#[derive(Debug, Clone, PartialEq)]
pub struct PlanRequest<'a> {
    /// Candidates (any order).
    pub candidates: &'a [Candidate],
    /// Estimated bytes/s per time step from now (piecewise constant); the last value extends
    /// to the horizon, an empty slice means zero bandwidth.
    pub bandwidth: &'a [f64],
    /// Time step `delta` in seconds (TileSplat: 0.1).
    pub step_s: f64,
    /// Horizon in steps (TileSplat: 600).
    pub horizon_steps: usize,
    /// Bytes the chosen downloads may take in total (eq. 16); `u64::MAX` for none.
    pub memory_budget: u64,
    /// Fixed time per request (round trip) in seconds.
    pub latency_s: f64,
}

/// One chosen download.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fetch {
    /// Index into the request's candidates.
    pub candidate: usize,
    /// Chosen level.
    pub level: Level,
    /// Planned completion, seconds from now.
    pub finish_s: f64,
}

/// A planner's answer: downloads in order.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Plan {
    /// Downloads, in the order to issue them.
    pub fetches: Vec<Fetch>,
    /// Planned utility (sum of the chosen variants' utilities).
    pub utility: f64,
    /// Planned bytes.
    pub bytes: u64,
}

/// Quality-selection algorithms.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Planner {
    /// Deadline-constrained dynamic program (TileSplat DC-DP).
    Dp,
    /// Deadline order; per tile the best level that still meets its deadline, else Low.
    GreedyDeadline,
    /// Deadline order; always Best.
    GreedyQuality,
    /// Distance order; level by distance quartile (nearest Best .. farthest Low).
    DistanceBased,
}

impl Planner {
    /// All planners.
    pub const ALL: [Planner; 4] = [
        Planner::Dp,
        Planner::GreedyDeadline,
        Planner::GreedyQuality,
        Planner::DistanceBased,
    ];

    /// Name for tables.
    pub fn name(self) -> &'static str {
        match self {
            Planner::Dp => "DC-DP",
            Planner::GreedyDeadline => "Greedy-Deadline",
            Planner::GreedyQuality => "Greedy-Quality",
            Planner::DistanceBased => "Distance-Based",
        }
    }

    /// Solves a request.
    pub fn solve(self, req: &PlanRequest) -> Plan {
        match self {
            Planner::Dp => solve_dp(req),
            Planner::GreedyDeadline => greedy(req, Order::Deadline, Pick::BestOnTime),
            Planner::GreedyQuality => greedy(req, Order::Deadline, Pick::Best),
            Planner::DistanceBased => greedy(req, Order::Distance, Pick::ByDistance),
        }
    }
}

/// Prefix sums `C(tau) = sum_{k < tau} B(k) delta`, `tau = 0..=T`.
pub fn capacity_prefix(bandwidth: &[f64], step_s: f64, steps: usize) -> Vec<f64> {
    let mut c = Vec::with_capacity(steps + 1);
    c.push(0.0);
    let mut acc = 0.0;
    for k in 0..steps {
        let b = bandwidth
            .get(k)
            .or(bandwidth.last())
            .copied()
            .unwrap_or(0.0)
            .max(0.0);
        acc += b * step_s;
        c.push(acc);
    }
    c
}

fn deadline_step(deadline: f64, step_s: f64, t: usize) -> i64 {
    if deadline.is_nan() || deadline < 0.0 || step_s <= 0.0 {
        return -1;
    }
    ((deadline / step_s + 1e-9).floor() as i64).min(t as i64)
}

fn latency_steps(req: &PlanRequest) -> usize {
    if req.step_s > 0.0 && req.latency_s > 0.0 {
        (req.latency_s / req.step_s - 1e-9).ceil() as usize
    } else {
        0
    }
}

/// Deadline order (ties by index).
fn deadline_order(c: &[Candidate]) -> Vec<usize> {
    let mut o: Vec<usize> = (0..c.len()).collect();
    o.sort_by(|&a, &b| c[a].deadline.total_cmp(&c[b].deadline).then(a.cmp(&b)));
    o
}

const SKIP: u8 = 0;
const IDLE: u8 = 255;

/// Latest start `sigma <= tau - lat` with `C(tau - lat) - C(sigma) >= s`.
fn latest_start(c: &[f64], tau: usize, lat: usize, s: f64) -> Option<usize> {
    if tau < lat {
        return None;
    }
    let end = tau - lat;
    let need = c[end] - s;
    if need < -1e-9 * s.max(1.0) {
        return None;
    }
    // Largest sigma in 0..=end with c[sigma] <= need (c non-decreasing).
    let k = c[..=end].partition_point(|&v| v <= need + 1e-9 * s.max(1.0));
    Some(k.saturating_sub(1))
}

/// Solves the DP for utilities `u - lambda * bytes` (lambda = 0: eq. 13 exactly).
fn dp_core(req: &PlanRequest, order: &[usize], lambda: f64) -> Vec<(usize, usize, usize)> {
    let t = req.horizon_steps;
    let c = capacity_prefix(req.bandwidth, req.step_s, t);
    let lat = latency_steps(req);
    let n = order.len();
    let mut prev = vec![0.0f64; t + 1];
    let mut cur = vec![0.0f64; t + 1];
    let mut choice = vec![SKIP; n * (t + 1)];
    for (row, &ci) in order.iter().enumerate() {
        let cand = &req.candidates[ci];
        let d = deadline_step(cand.deadline, req.step_s, t);
        cur.copy_from_slice(&prev);
        let ch = &mut choice[row * (t + 1)..(row + 1) * (t + 1)];
        if d >= 0 {
            let d = d as usize;
            // Cheapest level first so that ties keep the smaller download.
            for j in (0..LEVELS).rev() {
                let v = cand.variants[j];
                let w = v.utility - lambda * v.bytes as f64;
                if w <= 0.0 {
                    continue;
                }
                let s = v.bytes as f64;
                let mut sigma = 0usize;
                for tau in lat..=d {
                    let end = tau - lat;
                    if c[end] + 1e-9 * s.max(1.0) < s {
                        continue;
                    }
                    // Two pointers: sigma only moves forward as tau grows.
                    while sigma < end && c[end] - c[sigma + 1] + 1e-9 * s.max(1.0) >= s {
                        sigma += 1;
                    }
                    let val = prev[sigma] + w;
                    if val > cur[tau] + 1e-12 {
                        cur[tau] = val;
                        ch[tau] = (j + 1) as u8;
                    }
                }
            }
        }
        for tau in 1..=t {
            if cur[tau - 1] > cur[tau] + 1e-12 {
                cur[tau] = cur[tau - 1];
                ch[tau] = IDLE;
            }
        }
        std::mem::swap(&mut prev, &mut cur);
    }
    // Back-track from (n, T).
    let mut picks = vec![];
    let mut tau = t;
    let mut row = n;
    while row > 0 {
        let code = choice[(row - 1) * (t + 1) + tau];
        match code {
            IDLE => tau -= 1,
            SKIP => row -= 1,
            j => {
                let j = (j - 1) as usize;
                let ci = order[row - 1];
                let s = req.candidates[ci].variants[j].bytes as f64;
                let start = latest_start(&c, tau, lat, s).expect("chosen download fits");
                picks.push((ci, j, tau));
                tau = start;
                row -= 1;
            }
        }
    }
    picks.reverse();
    picks
}

fn to_plan(req: &PlanRequest, picks: &[(usize, usize, usize)]) -> Plan {
    let mut p = Plan::default();
    for &(ci, j, tau) in picks {
        let v = req.candidates[ci].variants[j];
        p.fetches.push(Fetch {
            candidate: ci,
            level: Level::from_index(j),
            finish_s: tau as f64 * req.step_s,
        });
        p.utility += v.utility;
        p.bytes += v.bytes;
    }
    p
}

/// The deadline-constrained DP (see the module docs).
pub fn solve_dp(req: &PlanRequest) -> Plan {
    let order = deadline_order(req.candidates);
    let plan = to_plan(req, &dp_core(req, &order, 0.0));
    if plan.bytes <= req.memory_budget {
        return plan;
    }
    // Memory binding: bisection on the price of a byte.
    let max_ratio = req
        .candidates
        .iter()
        .flat_map(|c| c.variants.iter())
        .filter(|v| v.bytes > 0)
        .map(|v| v.utility / v.bytes as f64)
        .fold(0.0, f64::max);
    let (mut lo, mut hi) = (0.0, max_ratio * 1.000001 + 1e-300);
    let mut best = Plan::default();
    for _ in 0..40 {
        let mid = 0.5 * (lo + hi);
        let p = to_plan(req, &dp_core(req, &order, mid));
        if p.bytes <= req.memory_budget {
            if p.utility > best.utility + 1e-12 {
                best = p;
            }
            hi = mid;
        } else {
            lo = mid;
        }
    }
    best
}

enum Order {
    Deadline,
    Distance,
}

enum Pick {
    BestOnTime,
    Best,
    ByDistance,
}

/// Completion time (seconds from now) of `s` bytes started at `start_s`, or infinity.
fn finish_time(c: &[f64], step_s: f64, start_s: f64, s: f64) -> f64 {
    let t = c.len() - 1;
    let k = (start_s / step_s).floor() as usize;
    if k >= t {
        return f64::INFINITY;
    }
    let frac = start_s / step_s - k as f64;
    let rate_k = (c[k + 1] - c[k]) / step_s;
    let base = c[k] + frac * rate_k * step_s;
    let target = base + s;
    if s <= 0.0 {
        return start_s;
    }
    let m = c.partition_point(|&v| v < target - 1e-9 * s.max(1.0));
    if m > t {
        return f64::INFINITY;
    }
    let m = m.max(1);
    let rate = (c[m] - c[m - 1]) / step_s;
    if rate <= 0.0 {
        return m as f64 * step_s;
    }
    (m as f64 - (c[m] - target) / (rate * step_s)) * step_s
}

fn greedy(req: &PlanRequest, order: Order, pick: Pick) -> Plan {
    let cands = req.candidates;
    let t = req.horizon_steps;
    let c = capacity_prefix(req.bandwidth, req.step_s, t);
    let idx = match order {
        Order::Deadline => deadline_order(cands),
        Order::Distance => {
            let mut o: Vec<usize> = (0..cands.len()).collect();
            o.sort_by(|&a, &b| {
                cands[a]
                    .distance
                    .total_cmp(&cands[b].distance)
                    .then(a.cmp(&b))
            });
            o
        }
    };
    let n = idx.len().max(1);
    let mut p = Plan::default();
    let mut clock = 0.0f64;
    for (rank, &ci) in idx.iter().enumerate() {
        let cand = &cands[ci];
        let fin = |j: usize| {
            finish_time(&c, req.step_s, clock, cand.variants[j].bytes as f64) + req.latency_s
        };
        let j = match pick {
            Pick::Best => 0,
            Pick::ByDistance => (rank * LEVELS / n).min(LEVELS - 1),
            Pick::BestOnTime => (0..LEVELS)
                .filter(|&j| fin(j) <= cand.deadline + 1e-9)
                .max_by(|&a, &b| {
                    cand.variants[a]
                        .utility
                        .total_cmp(&cand.variants[b].utility)
                        .then(b.cmp(&a))
                })
                .unwrap_or(LEVELS - 1),
        };
        let v = cand.variants[j];
        if p.bytes + v.bytes > req.memory_budget {
            continue;
        }
        let f = fin(j);
        if !f.is_finite() {
            continue;
        }
        clock = f;
        p.fetches.push(Fetch {
            candidate: ci,
            level: Level::from_index(j),
            finish_s: f,
        });
        p.utility += v.utility;
        p.bytes += v.bytes;
    }
    p
}

/// What happens when a plan is executed over a (true) link: downloads one after another.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Outcome {
    /// Utility of downloads complete by their deadline.
    pub utility: f64,
    /// Candidates not complete by their deadline (late or never fetched).
    pub misses: usize,
    /// Bytes downloaded (late ones included).
    pub bytes: u64,
}

/// Executes `plan` over the link `bandwidth` (bytes/s per step; same layout as the request's)
/// and scores it.
pub fn execute(req: &PlanRequest, plan: &Plan, bandwidth: &[f64]) -> Outcome {
    let c = capacity_prefix(bandwidth, req.step_s, req.horizon_steps * 4 + 1);
    let mut clock = 0.0;
    let mut on_time = vec![false; req.candidates.len()];
    let mut o = Outcome::default();
    for f in &plan.fetches {
        let cand = &req.candidates[f.candidate];
        let v = cand.variants[f.level.index()];
        let fin = finish_time(&c, req.step_s, clock, v.bytes as f64) + req.latency_s;
        if !fin.is_finite() {
            break;
        }
        clock = fin;
        o.bytes += v.bytes;
        if fin <= cand.deadline + 1e-6 {
            o.utility += v.utility;
            on_time[f.candidate] = true;
        }
    }
    o.misses = on_time.iter().filter(|&&x| !x).count();
    o
}
