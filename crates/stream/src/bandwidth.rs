//! Bandwidth estimate for deadlines (TileSplat eq. 11): an exponentially weighted moving average
//! of the throughput measured over fixed windows (500 ms in the paper), fed by the caller's clock.

/// EWMA throughput estimator. Feed received bytes and link-busy time with [`EwmaBandwidth::record`]
/// and call [`EwmaBandwidth::tick`] with the current time; the estimate moves once per window,
/// and only windows in which the link was busy count (idle time says nothing about capacity).
#[derive(Debug, Clone, PartialEq)]
pub struct EwmaBandwidth {
    /// Weight of a new sample (0..1].
    pub alpha: f64,
    /// Window length in seconds (0.5 in TileSplat).
    pub window_s: f64,
    estimate: f64,
    window_start: f64,
    bytes: f64,
    busy_s: f64,
    samples: u64,
    last_sample: f64,
}

impl EwmaBandwidth {
    /// A new estimator starting at `initial` bytes/s.
    pub fn new(initial: f64, alpha: f64, window_s: f64) -> Self {
        EwmaBandwidth {
            alpha,
            window_s,
            estimate: initial.max(0.0),
            window_start: 0.0,
            bytes: 0.0,
            busy_s: 0.0,
            samples: 0,
            last_sample: initial.max(0.0),
        }
    }

    /// Adds `bytes` received while the link was busy for `busy_s` seconds.
    pub fn record(&mut self, bytes: f64, busy_s: f64) {
        self.bytes += bytes.max(0.0);
        self.busy_s += busy_s.max(0.0);
    }

    /// Closes every window that ended by `now`, updating the estimate.
    pub fn tick(&mut self, now: f64) {
        if now - self.window_start < self.window_s {
            return;
        }
        if self.busy_s > 1e-6 {
            let sample = self.bytes / self.busy_s;
            self.last_sample = sample;
            self.estimate = if self.samples == 0 {
                sample
            } else {
                self.alpha * sample + (1.0 - self.alpha) * self.estimate
            };
            self.samples += 1;
        }
        self.bytes = 0.0;
        self.busy_s = 0.0;
        let windows = ((now - self.window_start) / self.window_s).floor();
        self.window_start += windows * self.window_s;
    }

    /// Current estimate in bytes/s.
    pub fn estimate(&self) -> f64 {
        self.estimate
    }

    /// Windows that produced a sample.
    pub fn samples(&self) -> u64 {
        self.samples
    }

    /// The latest window's throughput (bytes/s; the initial estimate before any sample).
    pub fn last_sample(&self) -> f64 {
        self.last_sample
    }

    /// Forecast as `(seconds from now, bytes/s)` pieces over `horizon_s`: the latest window's
    /// rate for one window, then moving towards the EWMA estimate by the same weight per window
    /// as the estimate would if every further window measured the estimate (`rate_k = est +
    /// (last - est)(1 - alpha)^k`), until within 1% of it; the estimate holds after that.
    pub fn forecast(&self, horizon_s: f64) -> Vec<(f64, f64)> {
        let est = self.estimate;
        let mut out = vec![];
        let mut gap = self.last_sample - est;
        let w = if self.window_s > 0.0 {
            self.window_s
        } else {
            0.5
        };
        let keep = (1.0 - self.alpha).clamp(0.0, 1.0);
        let mut t = 0.0;
        // At most 64 pieces: (1 - alpha)^k falls below 1% well before for any alpha >= 0.07.
        while gap.abs() > 0.01 * est.abs().max(1.0) && t < horizon_s && out.len() < 64 {
            out.push((t, (est + gap).max(0.0)));
            gap *= keep;
            t += w;
        }
        out.push((t.min(horizon_s.max(0.0)), est));
        out
    }
}

/// The pieces of `pieces` (`(absolute start s, bytes/s)`, sorted, the first holding from
/// `-inf`) from `now` over `horizon_s`, as `(seconds from now, bytes/s)`: what an oracle network
/// (the trace's future) hands the planner.
pub fn future_pieces(pieces: &[(f64, f64)], now: f64, horizon_s: f64) -> Vec<(f64, f64)> {
    let first = pieces.partition_point(|p| p.0 <= now).saturating_sub(1);
    let mut out = vec![];
    for (k, &(t, r)) in pieces.iter().enumerate().skip(first) {
        let rel = if k == first { 0.0 } else { t - now };
        if rel > horizon_s {
            break;
        }
        out.push((rel.max(0.0), r.max(0.0)));
    }
    if out.is_empty() {
        out.push((0.0, 0.0));
    }
    out
}

/// Bytes/s per step of `step_s` over `steps` steps of the piecewise-constant link `pieces`
/// (`(seconds from now, bytes/s)`, sorted; the first holds from 0, the last to the horizon): the
/// exact mean rate of each step, so that the prefix sums are the link's capacity.
pub fn per_step(pieces: &[(f64, f64)], step_s: f64, steps: usize) -> Vec<f64> {
    let mut out = vec![0.0; steps];
    if pieces.is_empty() || step_s <= 0.0 {
        return out;
    }
    let mut k = 0usize;
    for (i, o) in out.iter_mut().enumerate() {
        let (a, b) = (i as f64 * step_s, (i + 1) as f64 * step_s);
        while k + 1 < pieces.len() && pieces[k + 1].0 <= a {
            k += 1;
        }
        if pieces.get(k + 1).is_none_or(|p| p.0 >= b) {
            // The whole step in one piece: its rate exactly.
            *o = pieces[k].1.max(0.0);
            continue;
        }
        let mut acc = 0.0;
        let mut j = k;
        let mut from = a;
        while from < b {
            let to = pieces.get(j + 1).map_or(b, |p| p.0.clamp(from, b));
            acc += (to - from) * pieces[j].1.max(0.0);
            from = to;
            if j + 1 >= pieces.len() {
                break;
            }
            j += 1;
        }
        *o = acc / step_s;
    }
    out
}

/// Removes `bytes` of capacity from the front of `rates` (bytes/s per step of `step_s`): the
/// link first finishes what is already in flight.
pub fn deduct_in_flight(rates: &mut [f64], step_s: f64, bytes: u64) {
    let mut left = bytes as f64;
    for r in rates.iter_mut() {
        if left <= 0.0 {
            break;
        }
        let cap = *r * step_s;
        let take = cap.min(left);
        *r = (cap - take) / step_s;
        left -= take;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn forecast_starts_at_the_last_window_and_settles_on_the_estimate() {
        let mut e = EwmaBandwidth::new(1000.0, 0.5, 0.5);
        e.record(1000.0, 1.0);
        e.tick(0.5); // first sample: estimate 1000
        e.record(4000.0, 1.0);
        e.tick(1.0); // sample 4000: estimate 2500
        assert_eq!((e.estimate(), e.last_sample()), (2500.0, 4000.0));
        let f = e.forecast(10.0);
        assert_eq!(f[0], (0.0, 4000.0));
        assert_eq!(f[1], (0.5, 3250.0));
        assert_eq!(f.last().unwrap().1, 2500.0);
        assert!(f.windows(2).all(|w| w[1].0 > w[0].0 && w[1].1 <= w[0].1));
        // Settled: one piece.
        let c = EwmaBandwidth::new(800.0, 0.3, 0.5);
        assert_eq!(c.forecast(10.0), vec![(0.0, 800.0)]);
    }

    #[test]
    fn future_pieces_cut_the_trace_at_now() {
        let p = [(0.0, 1.0), (2.0, 2.0), (5.0, 3.0), (20.0, 4.0)];
        assert_eq!(future_pieces(&p, 3.0, 10.0), vec![(0.0, 2.0), (2.0, 3.0)]);
        assert_eq!(future_pieces(&p, 25.0, 10.0), vec![(0.0, 4.0)]);
        assert_eq!(future_pieces(&[], 1.0, 10.0), vec![(0.0, 0.0)]);
    }

    #[test]
    fn per_step_is_the_exact_mean_rate_and_in_flight_bytes_come_off_the_front() {
        let p = [(0.0, 100.0), (0.15, 300.0)];
        let r = per_step(&p, 0.1, 3);
        assert_eq!(r[0], 100.0);
        assert!((r[1] - 200.0).abs() < 1e-9, "{r:?}");
        assert_eq!(r[2], 300.0);
        assert_eq!(per_step(&[(0.0, 7.0)], 0.01, 4), vec![7.0; 4]);
        let mut r = vec![100.0, 100.0, 100.0];
        deduct_in_flight(&mut r, 0.1, 15);
        assert_eq!(r[0], 0.0);
        assert!((r[1] - 50.0).abs() < 1e-9);
        assert_eq!(r[2], 100.0);
    }
}
