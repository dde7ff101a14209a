//! Deadline-constrained quality selection (TileSplat sec. 3.4, eqs. 12-18) and the baselines of
//! its Table 5 (Greedy-Deadline, Greedy-Quality, Distance-Based).
//!
//! DP: candidates sorted by deadline (ties by input order) are downloaded one after another over
//! one link whose rate is piecewise constant per time step `delta`, so the link has carried
//! `C(t)` bytes by time `t` (eq. 12 via the prefix sums of `B(t) delta`, linear within a step).
//! A chosen set meets its deadlines exactly when, in deadline order, the work up to and including
//! each download (its bytes plus every earlier one's, each with a per-request overhead: the
//! request latency at the link's rate) is at most `C(D_i)`. The DP runs over that work in byte
//! bins (`bins` of them over `C(T)`; sizes round up to whole bins, capacities down, so the answer
//! is always feasible): `U(i, w)` is the best utility of the first `i` candidates within work `w`,
//! `U(i,w) = max(U(i-1,w), max_j U(i-1, w - s_ij) + u_ij)` for `w <= cap_i`, and
//! `max(U(i-1,w), U(i,cap_i))` above it. Answer `U(N, K)`, back-tracked to a fetch list whose
//! finish times are `C^-1` of the exact work. Unlike a DP over time steps (eq. 18), a download
//! does not take a whole step: at 10 Mbit/s a 100 ms step capped a plan at 10 downloads a second,
//! while here many small tiles share the link as they would.
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
    /// Byte resolution of the DP: the link's capacity over the horizon is cut into this many
    /// bins (at least one byte each); 0 means [`DEFAULT_BINS`].
    pub bins: usize,
}

/// Byte bins of the DP unless a request says otherwise (`cargo bench --bench dp_step`: within
/// 1% of 65,536 bins' utility on the 10 Mbit/s problems).
pub const DEFAULT_BINS: usize = 4096;

/// Most cells (candidates x bins) a DP holds: the bins shrink to fit (32 MiB of back-pointers).
pub const MAX_DP_CELLS: usize = 32 << 20;

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

    /// The planner a name stands for, case-insensitive: `dc-dp` (or `dp`), `greedy-deadline`,
    /// `greedy-quality`, `distance-based` (the names of [`Self::name`] lowercased).
    pub fn from_name(name: &str) -> Option<Planner> {
        let n = name.trim().to_ascii_lowercase();
        if n == "dp" {
            return Some(Planner::Dp);
        }
        Planner::ALL
            .into_iter()
            .find(|p| p.name().to_ascii_lowercase() == n)
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

/// The link's cumulative bytes at `t` seconds (linear within a step; flat past the horizon).
fn capacity_at(c: &[f64], step_s: f64, t: f64) -> f64 {
    if t.is_nan() || t <= 0.0 || step_s <= 0.0 || c.len() < 2 {
        return 0.0;
    }
    let x = t / step_s;
    let k = x.floor() as usize;
    if k + 1 >= c.len() {
        return c[c.len() - 1];
    }
    c[k] + (x - k as f64) * (c[k + 1] - c[k])
}

/// Inverse of [`capacity_at`]: the first time the link has carried `w` bytes (infinity if never
/// within the horizon).
fn time_for(c: &[f64], step_s: f64, w: f64) -> f64 {
    if w <= 0.0 {
        return 0.0;
    }
    let m = c.partition_point(|&v| v < w);
    if m >= c.len() {
        return f64::INFINITY;
    }
    let (lo, hi) = (c[m - 1], c[m]);
    let f = if hi > lo { (w - lo) / (hi - lo) } else { 1.0 };
    ((m - 1) as f64 + f.clamp(0.0, 1.0)) * step_s
}

/// Per-request overhead in bytes: the request latency at the mean rate of the link's busy steps.
pub fn overhead_bytes(req: &PlanRequest, c: &[f64]) -> f64 {
    if req.latency_s.is_nan() || req.latency_s <= 0.0 || req.step_s <= 0.0 {
        return 0.0;
    }
    let busy = c.windows(2).filter(|w| w[1] > w[0]).count();
    if busy == 0 {
        return 0.0;
    }
    req.latency_s * c[c.len() - 1] / (busy as f64 * req.step_s)
}

/// Deadline order (ties by index).
fn deadline_order(c: &[Candidate]) -> Vec<usize> {
    let mut o: Vec<usize> = (0..c.len()).collect();
    o.sort_by(|&a, &b| c[a].deadline.total_cmp(&c[b].deadline).then(a.cmp(&b)));
    o
}

const SKIP: u8 = 0;
const CAP: u8 = 255;

/// The DP's byte grid for a request: cumulative capacity per step, bin size, bin count and the
/// per-request overhead.
struct Grid {
    c: Vec<f64>,
    bin: f64,
    bins: usize,
    overhead: f64,
}

impl Grid {
    fn of(req: &PlanRequest) -> Grid {
        let c = capacity_prefix(req.bandwidth, req.step_s, req.horizon_steps);
        let total = c[c.len() - 1];
        let want = if req.bins == 0 {
            DEFAULT_BINS
        } else {
            req.bins
        };
        let want = want.min(MAX_DP_CELLS / req.candidates.len().max(1)).max(1);
        let bin = (total / want as f64).max(1.0);
        let bins = if total.is_finite() && total >= 1.0 {
            ((total / bin).floor() as usize).min(want)
        } else {
            0
        };
        let overhead = overhead_bytes(req, &c);
        Grid {
            c,
            bin,
            bins,
            overhead,
        }
    }

    /// Work of one download in bins (bytes plus overhead, rounded up).
    fn size(&self, bytes: u64) -> usize {
        let w = ((bytes as f64 + self.overhead) / self.bin - 1e-9).ceil();
        if w.is_finite() && w < self.bins as f64 + 1.0 {
            (w as usize).max(1)
        } else {
            usize::MAX
        }
    }

    /// Last bin a download due at `deadline` seconds may end in (`None`: passed or NaN).
    fn cap(&self, deadline: f64, step_s: f64) -> Option<usize> {
        if deadline.is_nan() || deadline < 0.0 {
            return None;
        }
        let w = capacity_at(&self.c, step_s, deadline);
        Some(((w / self.bin + 1e-9).floor() as usize).min(self.bins))
    }
}

/// Solves the DP for utilities `u - lambda * bytes` (lambda = 0: the plan of eq. 13); returns
/// `(candidate, level)` in download order.
fn dp_core(req: &PlanRequest, grid: &Grid, order: &[usize], lambda: f64) -> Vec<(usize, usize)> {
    let k = grid.bins;
    let n = order.len();
    if k == 0 || n == 0 {
        return vec![];
    }
    let mut prev = vec![0.0f64; k + 1];
    let mut cur = vec![0.0f64; k + 1];
    let mut choice = vec![SKIP; n * (k + 1)];
    let mut caps = vec![0usize; n];
    for (row, &ci) in order.iter().enumerate() {
        let cand = &req.candidates[ci];
        cur.copy_from_slice(&prev);
        let ch = &mut choice[row * (k + 1)..(row + 1) * (k + 1)];
        let Some(cap) = grid.cap(cand.deadline, req.step_s) else {
            caps[row] = 0;
            std::mem::swap(&mut prev, &mut cur);
            continue;
        };
        caps[row] = cap;
        // Cheapest level first so that ties keep the smaller download.
        for j in (0..LEVELS).rev() {
            let v = cand.variants[j];
            let w = v.utility - lambda * v.bytes as f64;
            let s = grid.size(v.bytes);
            if w <= 0.0 || s > cap {
                continue;
            }
            for x in s..=cap {
                let val = prev[x - s] + w;
                if val > cur[x] + 1e-12 {
                    cur[x] = val;
                    ch[x] = (j + 1) as u8;
                }
            }
        }
        // Past the deadline's capacity: at best what fitted by it.
        let at_cap = cur[cap];
        for x in cap + 1..=k {
            if at_cap > cur[x] + 1e-12 {
                cur[x] = at_cap;
                ch[x] = CAP;
            }
        }
        std::mem::swap(&mut prev, &mut cur);
    }
    // Back-track from (n, K).
    let mut picks = vec![];
    let mut x = k;
    let mut row = n;
    while row > 0 {
        match choice[(row - 1) * (k + 1) + x] {
            SKIP => row -= 1,
            CAP => x = caps[row - 1],
            j => {
                let j = (j - 1) as usize;
                let ci = order[row - 1];
                picks.push((ci, j));
                x -= grid.size(req.candidates[ci].variants[j].bytes);
                row -= 1;
            }
        }
    }
    picks.reverse();
    picks
}

/// The plan of `picks` (download order), finishing when the link has carried their exact work.
fn to_plan(req: &PlanRequest, grid: &Grid, picks: &[(usize, usize)]) -> Plan {
    let mut p = Plan::default();
    let mut work = 0.0;
    for &(ci, j) in picks {
        let v = req.candidates[ci].variants[j];
        work += v.bytes as f64 + grid.overhead;
        p.fetches.push(Fetch {
            candidate: ci,
            level: Level::from_index(j),
            finish_s: time_for(&grid.c, req.step_s, work),
        });
        p.utility += v.utility;
        p.bytes += v.bytes;
    }
    p
}

/// The deadline-constrained DP (see the module docs).
pub fn solve_dp(req: &PlanRequest) -> Plan {
    let order = deadline_order(req.candidates);
    let grid = Grid::of(req);
    let plan = to_plan(req, &grid, &dp_core(req, &grid, &order, 0.0));
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
        let p = to_plan(req, &grid, &dp_core(req, &grid, &order, mid));
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

#[cfg(test)]
mod tests {
    use super::Planner;

    #[test]
    fn planner_names_round_trip() {
        for p in Planner::ALL {
            assert_eq!(Planner::from_name(p.name()), Some(p));
            assert_eq!(Planner::from_name(&p.name().to_lowercase()), Some(p));
        }
        assert_eq!(Planner::from_name("DC-DP"), Some(Planner::Dp));
        assert_eq!(Planner::from_name("dp"), Some(Planner::Dp));
        assert_eq!(
            Planner::from_name("greedy-deadline"),
            Some(Planner::GreedyDeadline)
        );
        assert_eq!(Planner::from_name("greedy"), None);
        assert_eq!(Planner::from_name(""), None);
    }
}
