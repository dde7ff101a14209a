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
}
