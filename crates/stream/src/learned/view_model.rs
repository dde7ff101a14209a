//! The learned view predictor: per-horizon linear models over features of the pose history that
//! predict the yaw, the pitch and a correction to linear extrapolation's position (fitted offline).
//!
//! The features are in the frame of the current pose and scale with the motion (velocities, no
//! absolute positions), so one model serves a person walking and a camera flying; yaw features
//! change sign under a left-right mirror and the yaw model has no intercept, so it predicts a
//! mirrored history mirrored. The weights (`view_model.json`) come from
//! `splat2tiles_lab::sim::learn` on the tuning split only.

use crate::geom::{ViewPose, wrap_angle};
use crate::predict::{LinearExtrapolation, Predictor, sample_trace};
use glam::DVec3;
use serde::{Deserialize, Serialize};

/// The committed weights (`cargo run --release -p splat2tiles-lab --example view_model_train`).
pub const VIEW_MODEL_JSON: &str = include_str!("view_model.json");

/// Default [`LearnedPredictor::hedge_sigmas`].
pub const DEFAULT_HEDGE_SIGMAS: f64 = 3.0;

/// Default [`LearnedPredictor::hedge_horizon_s`].
pub const DEFAULT_HEDGE_HORIZON_S: f64 = 3.0;

/// Seconds between the model's horizons (its outputs are at `k * HORIZON_STEP_S`, k >= 1).
pub const HORIZON_STEP_S: f64 = 0.25;
/// Horizons the model predicts (up to 10 s).
pub const HORIZONS: usize = 40;
/// Seconds of history the features read.
pub const HISTORY_S: f64 = 5.0;
/// Sampling step of the history when features are computed (seconds).
const SAMPLE_S: f64 = 1.0 / 12.0;
/// Speed (m/s) below which the direction of travel says little about the view.
const SLOW_M_S: f64 = 0.3;
/// Windows (seconds) of the yaw rates.
pub const YAW_WINDOWS: [f64; 5] = [0.25, 0.5, 1.0, 2.0, 4.0];
/// Windows (seconds) of the velocities.
pub const VEL_WINDOWS: [f64; 4] = [0.5, 1.0, 2.0, 4.0];

/// Yaw features: rates over [`YAW_WINDOWS`], mean offset over 2 and 5 s, direction of travel over
/// 1 and 3 s (each weighted by how fast the camera moves).
pub const YAW_FEATURES: usize = 9;
/// Pitch features: pitch, changes over 0.5, 1, 2 s, mean offset over 5 s, and 1.
pub const PITCH_FEATURES: usize = 6;
/// Position features: forward and left velocity over [`VEL_WINDOWS`] (current yaw's frame), and
/// the 1 s velocity times the 1 s yaw rate (a turn bends the path).
pub const POS_FEATURES: usize = 10;

/// The features of one history (see the constants above).
#[derive(Debug, Clone, PartialEq)]
pub struct Features {
    /// Yaw features (odd under a left-right mirror).
    pub yaw: [f64; YAW_FEATURES],
    /// Pitch features (even under a mirror).
    pub pitch: [f64; PITCH_FEATURES],
    /// Position features: even ones first (forward), then odd ones (left).
    pub pos: [f64; POS_FEATURES],
}

/// Where `Features::pos` changes sign under a left-right mirror.
pub const POS_ODD: [bool; POS_FEATURES] = [
    false, false, false, false, true, true, true, true, true, false,
];

/// Unwrapped yaw relative to the current one and pitch, `HISTORY_S` back at `SAMPLE_S`
/// (index 0 = now), and positions.
fn resampled(history: &[ViewPose]) -> Option<Vec<ViewPose>> {
    let last = *history.last()?;
    let n = (HISTORY_S / SAMPLE_S).round() as usize;
    let mut out = Vec::with_capacity(n + 1);
    let mut prev_yaw = 0.0f64;
    for i in 0..=n {
        let t = last.t - i as f64 * SAMPLE_S;
        let p = sample_trace(history, t)?;
        let rel = prev_yaw + wrap_angle(p.yaw - last.yaw - prev_yaw);
        prev_yaw = rel;
        out.push(ViewPose { yaw: rel, ..p });
    }
    Some(out)
}

/// The history's features; `None` on an empty history.
pub fn features(history: &[ViewPose]) -> Option<Features> {
    let r = resampled(history)?;
    let now = r[0];
    let at = |s: f64| r[((s / SAMPLE_S).round() as usize).min(r.len() - 1)];
    let mean = |s: f64, f: &dyn Fn(&ViewPose) -> f64| {
        let k = ((s / SAMPLE_S).round() as usize).min(r.len() - 1);
        r[..=k].iter().map(f).sum::<f64>() / (k + 1) as f64
    };
    let (sy, cy) = last_yaw(history).sin_cos();
    // World displacement into the current yaw's frame (x ahead, y left).
    let local = |d: DVec3| (cy * d.x + sy * d.y, -sy * d.x + cy * d.y);
    let travel = |s: f64| {
        let (x, y) = local(now.pos - at(s).pos);
        let speed = x.hypot(y) / s;
        let w = (speed / SLOW_M_S).min(1.0);
        if w <= 0.0 { 0.0 } else { w * y.atan2(x) }
    };
    let mut yaw = [0.0; YAW_FEATURES];
    for (f, &w) in yaw.iter_mut().zip(&YAW_WINDOWS) {
        *f = -at(w).yaw / w;
    }
    yaw[5] = mean(2.0, &|p| p.yaw);
    yaw[6] = mean(HISTORY_S, &|p| p.yaw);
    yaw[7] = travel(1.0);
    yaw[8] = travel(3.0);
    let pitch = [
        now.pitch,
        now.pitch - at(0.5).pitch,
        now.pitch - at(1.0).pitch,
        now.pitch - at(2.0).pitch,
        mean(HISTORY_S, &|p| p.pitch) - now.pitch,
        1.0,
    ];
    let mut pos = [0.0; POS_FEATURES];
    for (k, &w) in VEL_WINDOWS.iter().enumerate() {
        let (x, y) = local(now.pos - at(w).pos);
        pos[k] = x / w;
        pos[4 + k] = y / w;
    }
    let rate1 = yaw[2];
    pos[8] = pos[1] * rate1;
    pos[9] = pos[5] * rate1;
    Some(Features { yaw, pitch, pos })
}

fn last_yaw(history: &[ViewPose]) -> f64 {
    history.last().map_or(0.0, |p| p.yaw)
}

/// The targets of one history at horizon `h`, given the pose then (`future`) and linear
/// extrapolation's (`linear`): the yaw change, the pitch change, and the position correction
/// (forward, left, up) in the current yaw's frame.
pub fn targets(now: &ViewPose, future: &ViewPose, linear: &ViewPose) -> [f64; 5] {
    let (s, c) = now.yaw.sin_cos();
    let d = future.pos - linear.pos;
    [
        wrap_angle(future.yaw - now.yaw),
        future.pitch - now.pitch,
        c * d.x + s * d.y,
        -s * d.x + c * d.y,
        d.z,
    ]
}

/// The fitted weights: per horizon, one row of weights per output.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ViewModel {
    /// What the weights were fitted on (traces, windows, ridge), for reports.
    pub trained_on: String,
    /// Yaw change weights, `HORIZONS x YAW_FEATURES`.
    pub yaw: Vec<Vec<f64>>,
    /// Pitch change weights, `HORIZONS x PITCH_FEATURES`.
    pub pitch: Vec<Vec<f64>>,
    /// Forward correction weights, `HORIZONS x POS_FEATURES`.
    pub forward: Vec<Vec<f64>>,
    /// Left correction weights, `HORIZONS x POS_FEATURES`.
    pub left: Vec<Vec<f64>>,
    /// Residual yaw RMS on the validation split per horizon (radians).
    pub yaw_rms: Vec<f64>,
    /// The expected absolute yaw error of this history, per horizon: weights over
    /// [`spread_features`], `HORIZONS x SPREAD_FEATURES`.
    pub yaw_spread: Vec<Vec<f64>>,
}

/// Features of the yaw error's size: 1 and the yaw features' magnitudes.
pub const SPREAD_FEATURES: usize = YAW_FEATURES + 1;

/// The features the yaw error's size is predicted from.
pub fn spread_features(f: &Features) -> [f64; SPREAD_FEATURES] {
    std::array::from_fn(|i| if i == 0 { 1.0 } else { f.yaw[i - 1].abs() })
}

/// Why a weights file was refused.
#[derive(Debug, thiserror::Error)]
pub enum ViewModelError {
    /// Not the JSON of a [`ViewModel`].
    #[error("{name}: {source}")]
    Json {
        /// The file.
        name: String,
        /// The parser's error.
        source: serde_json::Error,
    },
    /// A table of the wrong shape or with a non-finite weight.
    #[error("{name}: `{table}` must be {rows} rows of {cols} finite numbers")]
    Shape {
        /// The file.
        name: String,
        /// The table.
        table: &'static str,
        /// Rows expected.
        rows: usize,
        /// Columns expected.
        cols: usize,
    },
}

impl ViewModel {
    /// Parses and checks a weights file (`name` is used in errors).
    pub fn from_json(text: &str, name: &str) -> Result<ViewModel, ViewModelError> {
        let m: ViewModel = serde_json::from_str(text).map_err(|source| ViewModelError::Json {
            name: name.to_string(),
            source,
        })?;
        let check = |table: &'static str, t: &[Vec<f64>], cols: usize| {
            let ok = t.len() == HORIZONS
                && t.iter()
                    .all(|r| r.len() == cols && r.iter().all(|w| w.is_finite()));
            ok.then_some(()).ok_or(ViewModelError::Shape {
                name: name.to_string(),
                table,
                rows: HORIZONS,
                cols,
            })
        };
        check("yaw", &m.yaw, YAW_FEATURES)?;
        check("pitch", &m.pitch, PITCH_FEATURES)?;
        check("forward", &m.forward, POS_FEATURES)?;
        check("left", &m.left, POS_FEATURES)?;
        check("yaw_spread", &m.yaw_spread, SPREAD_FEATURES)?;
        if m.yaw_rms.len() != HORIZONS || !m.yaw_rms.iter().all(|v| v.is_finite()) {
            return Err(ViewModelError::Shape {
                name: name.to_string(),
                table: "yaw_rms",
                rows: 1,
                cols: HORIZONS,
            });
        }
        Ok(m)
    }

    /// The committed weights (parsed once per process).
    pub fn committed() -> &'static ViewModel {
        static MODEL: std::sync::OnceLock<ViewModel> = std::sync::OnceLock::new();
        MODEL.get_or_init(|| {
            ViewModel::from_json(VIEW_MODEL_JSON, "view_model.json (committed)").unwrap_or_else(
                |e| unreachable!("the committed weights are checked by a test: {e}"),
            )
        })
    }

    /// The outputs (yaw change, pitch change, forward, left correction, yaw sigma) at horizon
    /// index `k`.
    pub fn outputs(&self, f: &Features, k: usize) -> [f64; 5] {
        let dot = |w: &[f64], x: &[f64]| w.iter().zip(x).map(|(a, b)| a * b).sum::<f64>();
        // A Gaussian's sigma is sqrt(pi / 2) times its mean absolute deviation.
        let sigma = dot(&self.yaw_spread[k], &spread_features(f)).max(0.0) * 1.2533;
        [
            dot(&self.yaw[k], &f.yaw),
            dot(&self.pitch[k], &f.pitch),
            dot(&self.forward[k], &f.pos),
            dot(&self.left[k], &f.pos),
            sigma,
        ]
    }
}

/// The learned predictor: linear extrapolation's path corrected by the model, the model's yaw and
/// pitch. Horizons between the model's are interpolated; past its last, held.
#[derive(Debug, Clone)]
pub struct LearnedPredictor {
    model: ViewModel,
    linear: LinearExtrapolation,
    /// Besides the mean pose, poses turned this many yaw sigmas (the model's expected yaw error
    /// for this history at that horizon) to either side are predicted: the views the client
    /// should be ready for.
    pub hedge_sigmas: f64,
    /// Seconds ahead up to which those turned poses are predicted (further out the path itself
    /// is uncertain, and what they show is mostly never seen).
    pub hedge_horizon_s: f64,
    /// Turned poses on each side, evenly spaced out to [`Self::hedge_sigmas`].
    pub hedge_poses: usize,
}

impl LearnedPredictor {
    /// A predictor running `model`.
    pub fn new(model: ViewModel) -> Self {
        LearnedPredictor {
            model,
            linear: LinearExtrapolation::default(),
            hedge_sigmas: DEFAULT_HEDGE_SIGMAS,
            hedge_horizon_s: DEFAULT_HEDGE_HORIZON_S,
            hedge_poses: 1,
        }
    }

    /// The predictor with the committed weights.
    pub fn committed() -> Self {
        LearnedPredictor::new(ViewModel::committed().clone())
    }
}

impl Predictor for LearnedPredictor {
    fn name(&self) -> &str {
        "learned"
    }

    fn min_history_s(&self) -> f64 {
        self.linear.min_history
    }

    fn predict(&mut self, history: &[ViewPose], horizon: f64, step: f64) -> Vec<ViewPose> {
        let lin = self.linear.predict(history, horizon, step);
        let (Some(now), Some(f)) = (history.last().copied(), features(history)) else {
            return lin;
        };
        let outs: Vec<[f64; 5]> = (0..HORIZONS).map(|k| self.model.outputs(&f, k)).collect();
        let (s, c) = now.yaw.sin_cos();
        let half_pi = std::f64::consts::FRAC_PI_2 - 1e-3;
        let mut out = Vec::with_capacity(lin.len() * 3);
        for p in lin {
            let o = interpolate(&outs, p.t - now.t);
            let d = DVec3::new(c * o[2] - s * o[3], s * o[2] + c * o[3], 0.0);
            let mean = ViewPose {
                t: p.t,
                pos: p.pos + d,
                yaw: wrap_angle(now.yaw + o[0]),
                pitch: (now.pitch + o[1]).clamp(-half_pi, half_pi),
            };
            out.push(mean);
            let turn = self.hedge_sigmas * o[4];
            if turn > 0.0 && p.t - now.t <= self.hedge_horizon_s + 1e-9 {
                let n = self.hedge_poses.max(1);
                for j in 1..=n {
                    let a = turn * j as f64 / n as f64;
                    for side in [-1.0, 1.0] {
                        out.push(ViewPose {
                            yaw: wrap_angle(mean.yaw + side * a),
                            ..mean
                        });
                    }
                }
            }
        }
        out
    }
}

/// The outputs at `h` seconds: linear between the model's horizons, zero before the first (at
/// 0 s nothing has changed), the last one past the end.
fn interpolate(outs: &[[f64; 5]], h: f64) -> [f64; 5] {
    let x = h / HORIZON_STEP_S;
    if !x.is_finite() || x <= 0.0 {
        return [0.0; 5];
    }
    let k = x.floor() as usize; // outs[k - 1] is at k * step
    let at = |k: usize| {
        if k == 0 {
            [0.0; 5]
        } else {
            outs[(k - 1).min(outs.len() - 1)]
        }
    };
    let (a, b, s) = (at(k), at(k + 1), x - k as f64);
    std::array::from_fn(|i| a[i] + (b[i] - a[i]) * s)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A walk at `speed` m/s along `heading` (radians) with the view swinging `swing` radians
    /// each side of it every 4 s, at 12 Hz for `secs`.
    fn walk(speed: f64, heading: f64, swing: f64, secs: f64) -> Vec<ViewPose> {
        let n = (secs * 12.0) as usize;
        (0..=n)
            .map(|i| {
                let t = i as f64 / 12.0;
                let d = DVec3::new(heading.cos(), heading.sin(), 0.0) * speed * t;
                ViewPose {
                    t,
                    pos: DVec3::new(10.0, -4.0, 1.7) + d,
                    yaw: wrap_angle(heading + swing * (t * std::f64::consts::PI / 2.0).sin()),
                    pitch: -0.1,
                }
            })
            .collect()
    }

    fn mirror(h: &[ViewPose]) -> Vec<ViewPose> {
        h.iter()
            .map(|p| ViewPose {
                pos: DVec3::new(p.pos.x, -p.pos.y, p.pos.z),
                yaw: wrap_angle(-p.yaw),
                ..*p
            })
            .collect()
    }

    #[test]
    fn the_committed_weights_load_and_were_fitted_on_the_tuning_split() {
        let m = ViewModel::from_json(VIEW_MODEL_JSON, "view_model.json").unwrap();
        assert!(m.trained_on.contains("tuning split"), "{}", m.trained_on);
        assert!(
            m.yaw_rms.iter().all(|&r| r > 0.0 && r < 4.0),
            "{:?}",
            m.yaw_rms
        );
        // The yaw error grows with the horizon.
        assert!(m.yaw_rms[HORIZONS - 1] > m.yaw_rms[0]);
    }

    #[test]
    fn a_weights_file_of_the_wrong_shape_or_with_nan_is_refused_by_name() {
        let mut v: serde_json::Value = serde_json::from_str(VIEW_MODEL_JSON).unwrap();
        v["pitch"][3] = serde_json::json!([1.0]);
        let e = ViewModel::from_json(&v.to_string(), "w.json").unwrap_err();
        assert_eq!(
            e.to_string(),
            format!("w.json: `pitch` must be {HORIZONS} rows of {PITCH_FEATURES} finite numbers")
        );
        let text = VIEW_MODEL_JSON.replacen("\"yaw_rms\": [", "\"yaw_rms\": [NaN, ", 1);
        let e = ViewModel::from_json(&text, "w.json").unwrap_err();
        assert!(e.to_string().starts_with("w.json: "), "{e}");
        assert!(ViewModel::from_json("{", "w.json").is_err());
    }

    #[test]
    fn a_mirrored_history_is_predicted_mirrored() {
        let h = walk(1.4, 0.3, 0.6, 8.0);
        let mut p = LearnedPredictor::committed();
        // The turned views come in the other order: compare by time, then yaw.
        let sorted = |mut v: Vec<ViewPose>| {
            v.sort_by(|a, b| a.t.total_cmp(&b.t).then(a.yaw.total_cmp(&b.yaw)));
            v
        };
        let a = sorted(p.predict(&h, 10.0, 0.5));
        let b = sorted(mirror(&p.predict(&mirror(&h), 10.0, 0.5)));
        assert_eq!(a.len(), b.len());
        for (a, b) in a.iter().zip(b) {
            assert!((a.pos - b.pos).length() < 1e-6, "{a:?} {b:?}");
            assert!(wrap_angle(a.yaw - b.yaw).abs() < 1e-6, "{a:?} {b:?}");
            assert!((a.pitch - b.pitch).abs() < 1e-9);
        }
    }

    #[test]
    fn a_steady_walk_is_predicted_ahead_with_turned_views_only_near_now() {
        let h = walk(1.4, 1.0, 0.0, 8.0);
        let now = h[h.len() - 1];
        let mut p = LearnedPredictor::committed();
        let out = p.predict(&h, 10.0, 0.5);
        // 20 steps, each within the hedge horizon with two turned views beside the mean.
        let near = (DEFAULT_HEDGE_HORIZON_S / 0.5) as usize;
        assert_eq!(out.len(), 20 + 2 * near);
        let at5 = out
            .iter()
            .rfind(|q| (q.t - now.t - 5.0).abs() < 1e-9)
            .unwrap();
        let ahead = (at5.pos - now.pos).dot(DVec3::new(1f64.cos(), 1f64.sin(), 0.0));
        assert!((5.0..9.0).contains(&ahead), "{ahead} m ahead at 5 s");
        for q in out
            .iter()
            .filter(|q| q.t - now.t > DEFAULT_HEDGE_HORIZON_S + 1e-9)
        {
            assert!(wrap_angle(q.yaw - now.yaw).abs() < 0.3, "{q:?}");
        }
    }

    #[test]
    fn degenerate_histories_give_finite_predictions() {
        let still = |n: usize, pos: DVec3| -> Vec<ViewPose> {
            (0..n)
                .map(|i| ViewPose {
                    t: i as f64 / 12.0,
                    pos,
                    yaw: 3.1,
                    pitch: 1.5,
                })
                .collect()
        };
        let far = DVec3::new(6.4e6, -3.2e6, 1e4);
        let mut gap = walk(200.0, -2.0, 1.5, 8.0);
        gap.retain(|p| p.t < 1.0 || p.t > 7.5);
        let cases: Vec<(&str, Vec<ViewPose>)> = vec![
            ("one pose", still(1, DVec3::ZERO)),
            ("standing still", still(90, DVec3::ZERO)),
            ("far from the origin", still(90, far)),
            ("fast with a gap", gap),
            ("same time twice", {
                let mut h = still(10, DVec3::ONE);
                h.push(h[9]);
                h
            }),
        ];
        let mut p = LearnedPredictor::committed();
        for (name, h) in cases {
            let out = p.predict(&h, 10.0, 0.5);
            assert!(!out.is_empty(), "{name}");
            for q in &out {
                let ok = q.pos.is_finite() && q.yaw.is_finite() && q.pitch.is_finite();
                assert!(
                    ok && q.pitch.abs() < std::f64::consts::FRAC_PI_2,
                    "{name}: {q:?}"
                );
            }
        }
        assert!(p.predict(&[], 10.0, 0.5).is_empty());
    }
}
