//! Trajectory predictors behind one trait (reactive, constant velocity, linear extrapolation,
//! oracle; the learned TCN of TileSplat sec. 3.3 is `stream::learned`) and the App. C.5 rules:
//! until a predictor has its history (5 s), fetch every tile within a radius at Medium quality;
//! where a prediction is too uncertain ([`BLEND_SIGMA_M`]), the radius rule joins it.

use super::catalog::TileCatalog;
use super::geom::{ViewPose, wrap_angle};
use glam::DVec3;

/// Predicts future camera poses from the pose history.
pub trait Predictor {
    /// Name for reports.
    fn name(&self) -> &str;
    /// Seconds of history the predictor needs; before that the fallback rule applies.
    fn min_history_s(&self) -> f64 {
        0.0
    }
    /// Poses at `now + step, now + 2 step, ..., now + horizon` where `now` is the time of the last
    /// history entry (the current pose). An empty answer means "no prediction": plan for the
    /// current view only (reactive).
    fn predict(&mut self, history: &[ViewPose], horizon: f64, step: f64) -> Vec<ViewPose>;
    /// [`predict`](Self::predict) with each pose's horizontal uncertainty. Predictors without a
    /// model of their error report sigma 0 (taken as certain: their plans are unchanged).
    fn predict_uncertain(
        &mut self,
        history: &[ViewPose],
        horizon: f64,
        step: f64,
    ) -> Vec<Uncertain> {
        self.predict(history, horizon, step)
            .into_iter()
            .map(|pose| Uncertain { pose, sigma_m: 0.0 })
            .collect()
    }
}

/// A predicted pose with the predictor's one-sigma horizontal position uncertainty (metres).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Uncertain {
    /// The predicted (mean) pose.
    pub pose: ViewPose,
    /// One sigma of the horizontal position, metres (0: certain or unknown).
    pub sigma_m: f64,
}

/// App. C.5's low-confidence rule: predicted poses whose sigma exceeds this (metres) are not
/// planned for; the radius rule covers the surroundings instead (a fifth of TileSplat's 100 m
/// radius: beyond it the mean pose's frustum says little about what will be seen).
pub const BLEND_SIGMA_M: f64 = 20.0;

/// Splits a prediction by App. C.5's rule: the poses confident enough to plan for (sigma at most
/// `limit_m`) and whether any was too uncertain (then the radius rule is blended in).
pub fn confident_poses(pred: &[Uncertain], limit_m: f64) -> (Vec<ViewPose>, bool) {
    let keep: Vec<ViewPose> = pred
        .iter()
        .filter(|u| u.sigma_m <= limit_m)
        .map(|u| u.pose)
        .collect();
    let uncertain = keep.len() < pred.len();
    (keep, uncertain)
}

/// No prediction: only tiles visible now are fetched (TileSplat-Reactive).
#[derive(Debug, Clone, Default)]
pub struct Reactive;

impl Predictor for Reactive {
    fn name(&self) -> &str {
        "reactive"
    }
    fn predict(&mut self, _: &[ViewPose], _: f64, _: f64) -> Vec<ViewPose> {
        vec![]
    }
}

fn steps(horizon: f64, step: f64) -> usize {
    if step <= 0.0 || horizon <= 0.0 {
        0
    } else {
        (horizon / step + 1e-9).floor() as usize
    }
}

/// Constant velocity: the latest velocity (over `window_s`) continued; heading held.
#[derive(Debug, Clone)]
pub struct ConstantVelocity {
    /// Window over which the velocity is measured.
    pub window_s: f64,
    /// History needed before use (the App. C.5 rule: 5 s).
    pub min_history: f64,
}

impl Default for ConstantVelocity {
    fn default() -> Self {
        ConstantVelocity {
            window_s: 0.25,
            min_history: 5.0,
        }
    }
}

impl Predictor for ConstantVelocity {
    fn name(&self) -> &str {
        "constant-velocity"
    }
    fn min_history_s(&self) -> f64 {
        self.min_history
    }
    fn predict(&mut self, h: &[ViewPose], horizon: f64, step: f64) -> Vec<ViewPose> {
        let Some(last) = h.last().copied() else {
            return vec![];
        };
        let first = h
            .iter()
            .rev()
            .find(|p| last.t - p.t >= self.window_s)
            .or(h.first())
            .copied()
            .unwrap_or(last);
        let dt = last.t - first.t;
        let v = if dt > 1e-9 {
            (last.pos - first.pos) / dt
        } else {
            DVec3::ZERO
        };
        (1..=steps(horizon, step))
            .map(|k| {
                let s = k as f64 * step;
                ViewPose {
                    t: last.t + s,
                    pos: last.pos + v * s,
                    ..last
                }
            })
            .collect()
    }
}

/// Linear extrapolation: least-squares lines through position, yaw (unwrapped) and pitch over the
/// last `window_s` seconds, extended into the future.
#[derive(Debug, Clone)]
pub struct LinearExtrapolation {
    /// Fitting window.
    pub window_s: f64,
    /// History needed before use (the App. C.5 rule: 5 s).
    pub min_history: f64,
}

impl Default for LinearExtrapolation {
    fn default() -> Self {
        LinearExtrapolation {
            window_s: 2.0,
            min_history: 5.0,
        }
    }
}

impl Predictor for LinearExtrapolation {
    fn name(&self) -> &str {
        "linear"
    }
    fn min_history_s(&self) -> f64 {
        self.min_history
    }
    fn predict(&mut self, h: &[ViewPose], horizon: f64, step: f64) -> Vec<ViewPose> {
        let Some(last) = h.last().copied() else {
            return vec![];
        };
        let w: Vec<&ViewPose> = h.iter().filter(|p| last.t - p.t <= self.window_s).collect();
        if w.len() < 2 {
            return (1..=steps(horizon, step))
                .map(|k| ViewPose {
                    t: last.t + k as f64 * step,
                    ..last
                })
                .collect();
        }
        // Unwrap yaw relative to the last sample.
        let ys: Vec<f64> = w
            .iter()
            .map(|p| last.yaw + wrap_angle(p.yaw - last.yaw))
            .collect();
        let n = w.len() as f64;
        let tm = w.iter().map(|p| p.t - last.t).sum::<f64>() / n;
        let stt: f64 = w.iter().map(|p| (p.t - last.t - tm).powi(2)).sum();
        let slope = |f: &dyn Fn(usize) -> f64| -> (f64, f64) {
            let m = (0..w.len()).map(f).sum::<f64>() / n;
            if stt < 1e-12 {
                return (m, 0.0);
            }
            let s = (0..w.len())
                .map(|i| (w[i].t - last.t - tm) * (f(i) - m))
                .sum::<f64>()
                / stt;
            (m - s * tm, s) // value at t = last.t, slope
        };
        let (px, vx) = slope(&|i| w[i].pos.x);
        let (py, vy) = slope(&|i| w[i].pos.y);
        let (pz, vz) = slope(&|i| w[i].pos.z);
        let (yaw0, vyaw) = slope(&|i| ys[i]);
        let (pit0, vpit) = slope(&|i| w[i].pitch);
        let half_pi = std::f64::consts::FRAC_PI_2 - 1e-3;
        (1..=steps(horizon, step))
            .map(|k| {
                let s = k as f64 * step;
                ViewPose {
                    t: last.t + s,
                    pos: DVec3::new(px + vx * s, py + vy * s, pz + vz * s),
                    yaw: wrap_angle(yaw0 + vyaw * s),
                    pitch: (pit0 + vpit * s).clamp(-half_pi, half_pi),
                }
            })
            .collect()
    }
}

/// Perfect knowledge of the future (an upper bound): samples the recorded trace.
#[derive(Debug, Clone)]
pub struct Oracle {
    /// The whole trace, sorted by time.
    pub trace: Vec<ViewPose>,
}

/// The trace's pose at time `t` (linear interpolation, clamped at the ends).
pub fn sample_trace(trace: &[ViewPose], t: f64) -> Option<ViewPose> {
    let first = trace.first()?;
    let last = trace.last()?;
    if t <= first.t {
        return Some(ViewPose { t, ..*first });
    }
    if t >= last.t {
        return Some(ViewPose { t, ..*last });
    }
    let i = trace.partition_point(|p| p.t <= t);
    let (a, b) = (&trace[i - 1], &trace[i]);
    let s = if b.t > a.t {
        (t - a.t) / (b.t - a.t)
    } else {
        0.0
    };
    Some(a.lerp(b, s))
}

impl Predictor for Oracle {
    fn name(&self) -> &str {
        "oracle"
    }
    fn predict(&mut self, h: &[ViewPose], horizon: f64, step: f64) -> Vec<ViewPose> {
        let Some(now) = h.last().map(|p| p.t) else {
            return vec![];
        };
        let end = self.trace.last().map_or(now, |p| p.t);
        (1..=steps(horizon, step))
            .map(|k| now + k as f64 * step)
            .take_while(|&t| t <= end + 1e-9)
            .filter_map(|t| sample_trace(&self.trace, t))
            .collect()
    }
}

/// Seconds covered by the history.
pub fn history_span(h: &[ViewPose]) -> f64 {
    match (h.first(), h.last()) {
        (Some(a), Some(b)) => b.t - a.t,
        _ => 0.0,
    }
}

/// Whether the App. C.5 fallback applies: the predictor wants more history than there is.
pub fn needs_fallback(p: &dyn Predictor, history: &[ViewPose]) -> bool {
    history_span(history) + 1e-9 < p.min_history_s()
}

/// The App. C.5 fallback: content tiles whose box lies within `radius` of `pos` (TileSplat: 100 m,
/// fetched at Medium), nearest first; only the deepest such tiles (no ancestor of a listed tile).
pub fn radius_tiles(cat: &TileCatalog, pos: DVec3, radius: f64) -> Vec<usize> {
    let mut v: Vec<(f64, usize)> = cat
        .content_tiles()
        .filter(|&i| {
            cat.tiles[i]
                .children
                .iter()
                .all(|&c| !cat.tiles[c].has_content)
        })
        .map(|i| (cat.tiles[i].bbox.distance(pos), i))
        .filter(|(d, _)| *d <= radius)
        .collect();
    v.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    v.into_iter().map(|(_, i)| i).collect()
}

#[cfg(test)]
mod uncertainty_tests {
    use super::*;

    fn pose(t: f64) -> ViewPose {
        ViewPose {
            t,
            pos: DVec3::new(t, 0.0, 0.0),
            yaw: 0.0,
            pitch: 0.0,
        }
    }

    #[test]
    fn heuristic_predictors_report_zero_sigma_and_plan_unchanged() {
        let h: Vec<ViewPose> = (0..=72).map(|i| pose(i as f64 / 12.0)).collect();
        let mut lin = LinearExtrapolation::default();
        let plain = lin.predict(&h, 10.0, 0.5);
        let unc = lin.predict_uncertain(&h, 10.0, 0.5);
        assert_eq!(plain.len(), 20);
        assert!(unc.iter().all(|u| u.sigma_m == 0.0));
        let (keep, uncertain) = confident_poses(&unc, BLEND_SIGMA_M);
        assert_eq!(keep, plain);
        assert!(!uncertain);
    }

    #[test]
    fn uncertain_poses_are_dropped_and_flag_the_radius_blend() {
        let pred: Vec<Uncertain> = (1..=6)
            .map(|k| Uncertain {
                pose: pose(k as f64),
                sigma_m: 8.0 * k as f64,
            })
            .collect();
        let (keep, uncertain) = confident_poses(&pred, 20.0);
        assert_eq!(keep.iter().map(|p| p.t).collect::<Vec<_>>(), vec![1.0, 2.0]);
        assert!(uncertain);
    }
}
