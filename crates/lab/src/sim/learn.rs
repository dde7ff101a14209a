//! Fitting the learned view predictor (`stream::learned::view_model`): ridge regression per
//! horizon over every window of the tuning split's train traces, chosen and scored on its val traces.
//!
//! Each motion kind (human sessions, street walks, flights) weighs the same in the fit whatever its
//! number of windows; the position model also sees every window mirrored left-right (the yaw
//! model is mirror-symmetric by construction). Traces arrive only through
//! [`splat2tiles_stream::split::TuningSet`], which refuses test-split traces.

use super::tcn_data::{KINDS, trace_kind};
use splat2tiles_stream::geom::wrap_angle;
use splat2tiles_stream::learned::view_model::{
    Features, HISTORY_S, HORIZON_STEP_S, HORIZONS, PITCH_FEATURES, POS_FEATURES, POS_ODD,
    SPREAD_FEATURES, ViewModel, YAW_FEATURES, features, spread_features, targets,
};
use splat2tiles_stream::predict::{LinearExtrapolation, Predictor, sample_trace};
use splat2tiles_stream::split::TuningSet;
use splat2tiles_stream::trace::Trace;

/// One training window: its kind, features and targets per horizon (yaw, pitch, forward, left,
/// up; `view_model::targets`).
#[derive(Debug, Clone)]
pub struct Sample {
    /// Index into [`KINDS`].
    pub kind: usize,
    /// The history's features.
    pub features: Features,
    /// Targets per horizon.
    pub targets: Vec<[f64; 5]>,
}

/// Every window of `traces` whose history (5 s) and future (10 s) lie inside the trace, one every
/// `stride_s` seconds.
pub fn samples(traces: &[Trace], stride_s: f64) -> Vec<Sample> {
    let mut out = vec![];
    let mut lin = LinearExtrapolation::default();
    let horizon = HORIZONS as f64 * HORIZON_STEP_S;
    for tr in traces {
        let (Some(first), Some(last)) = (tr.poses.first(), tr.poses.last()) else {
            continue;
        };
        let kind = KINDS.iter().position(|k| *k == trace_kind(tr)).unwrap_or(0);
        let mut t = first.t + HISTORY_S + 1.0;
        while t + horizon <= last.t {
            let lo = tr.poses.partition_point(|p| p.t < t - HISTORY_S - 1.0);
            let hi = tr.poses.partition_point(|p| p.t <= t);
            let mut history = tr.poses[lo..hi].to_vec();
            if history.last().is_some_and(|p| p.t < t)
                && let Some(p) = sample_trace(&tr.poses, t)
            {
                history.push(p);
            }
            let (Some(now), Some(f)) = (history.last().copied(), features(&history)) else {
                t += stride_s;
                continue;
            };
            let pred = lin.predict(&history, horizon, HORIZON_STEP_S);
            let targets = (1..=HORIZONS)
                .filter_map(|k| {
                    let future = sample_trace(&tr.poses, now.t + k as f64 * HORIZON_STEP_S)?;
                    Some(targets(&now, &future, pred.get(k - 1)?))
                })
                .collect::<Vec<_>>();
            if targets.len() == HORIZONS {
                out.push(Sample {
                    kind,
                    features: f,
                    targets,
                });
            }
            t += stride_s;
        }
    }
    out
}

/// Normal equations of one linear model with several targets: `X^T W X` and `X^T W Y`.
struct Normal {
    xtx: Vec<f64>,
    xty: Vec<f64>,
    n: usize,
    m: usize,
}

impl Normal {
    fn new(n: usize, m: usize) -> Self {
        Normal {
            xtx: vec![0.0; n * n],
            xty: vec![0.0; n * m],
            n,
            m,
        }
    }

    fn add(&mut self, x: &[f64], y: &[f64], w: f64) {
        for i in 0..self.n {
            for j in 0..self.n {
                self.xtx[i * self.n + j] += w * x[i] * x[j];
            }
            for (k, yk) in y.iter().enumerate().take(self.m) {
                self.xty[i * self.m + k] += w * x[i] * yk;
            }
        }
    }

    /// Ridge solution (`ridge` times each feature's own second moment added to the diagonal, so
    /// the penalty does not depend on the features' units): `m` rows of `n` weights.
    fn solve(&self, ridge: f64) -> Vec<Vec<f64>> {
        let n = self.n;
        let mut a = self.xtx.clone();
        for i in 0..n {
            a[i * n + i] += ridge * self.xtx[i * n + i] + 1e-12;
        }
        let l = cholesky(&a, n);
        (0..self.m)
            .map(|k| {
                let b: Vec<f64> = (0..n).map(|i| self.xty[i * self.m + k]).collect();
                cholesky_solve(&l, n, &b)
            })
            .collect()
    }
}

/// Cholesky factor of a symmetric positive definite `n x n` matrix (row-major, lower). Written
/// out rather than taken from a linear-algebra crate: the systems are at most 10 x 10, solved
/// once per fit.
fn cholesky(a: &[f64], n: usize) -> Vec<f64> {
    let mut l = vec![0.0; n * n];
    for i in 0..n {
        for j in 0..=i {
            let s: f64 = (0..j).map(|k| l[i * n + k] * l[j * n + k]).sum();
            if i == j {
                l[i * n + i] = (a[i * n + i] - s).max(1e-12).sqrt();
            } else {
                l[i * n + j] = (a[i * n + j] - s) / l[j * n + j];
            }
        }
    }
    l
}

fn cholesky_solve(l: &[f64], n: usize, b: &[f64]) -> Vec<f64> {
    let mut y = vec![0.0; n];
    for i in 0..n {
        let s: f64 = (0..i).map(|k| l[i * n + k] * y[k]).sum();
        y[i] = (b[i] - s) / l[i * n + i];
    }
    let mut x = vec![0.0; n];
    for i in (0..n).rev() {
        let s: f64 = (i + 1..n).map(|k| l[k * n + i] * x[k]).sum();
        x[i] = (y[i] - s) / l[i * n + i];
    }
    x
}

/// Per-sample weights that give each kind the same total weight.
fn kind_weights(samples: &[Sample]) -> Vec<f64> {
    let mut count = [0usize; KINDS.len()];
    for s in samples {
        count[s.kind] += 1;
    }
    let kinds = count.iter().filter(|&&c| c > 0).count().max(1) as f64;
    samples
        .iter()
        .map(|s| samples.len() as f64 / (kinds * count[s.kind] as f64))
        .collect()
}

/// Fits the model on `train` with ridge factor `ridge`; `yaw_rms` from `val`.
pub fn fit(train: &[Sample], val: &[Sample], ridge: f64, trained_on: &str) -> ViewModel {
    let w = kind_weights(train);
    let mut yaw = Normal::new(YAW_FEATURES, HORIZONS);
    let mut pitch = Normal::new(PITCH_FEATURES, HORIZONS);
    let mut pos = Normal::new(POS_FEATURES, 2 * HORIZONS);
    for (s, &w) in train.iter().zip(&w) {
        let col = |c: usize| s.targets.iter().map(|t| t[c]).collect::<Vec<f64>>();
        yaw.add(&s.features.yaw, &col(0), w);
        pitch.add(&s.features.pitch, &col(1), w);
        let (fwd, left) = (col(2), col(3));
        pos.add(&s.features.pos, &[fwd.as_slice(), &left].concat(), w);
        // The mirror image: odd features and the left correction change sign.
        let x: Vec<f64> = s
            .features
            .pos
            .iter()
            .zip(POS_ODD)
            .map(|(v, odd)| if odd { -v } else { *v })
            .collect();
        let mirrored: Vec<f64> = left.iter().map(|v| -v).collect();
        pos.add(&x, &[fwd, mirrored].concat(), w);
    }
    let pos_w = pos.solve(ridge);
    let yaw_w = yaw.solve(ridge);
    // The size of the yaw error from the sizes of the yaw features.
    let mut spread = Normal::new(SPREAD_FEATURES, HORIZONS);
    for (s, &w) in train.iter().zip(&w) {
        let e: Vec<f64> = s
            .targets
            .iter()
            .zip(&yaw_w)
            .map(|(t, wk)| {
                let p: f64 = wk.iter().zip(&s.features.yaw).map(|(a, b)| a * b).sum();
                wrap_angle(p - t[0]).abs()
            })
            .collect();
        spread.add(&spread_features(&s.features), &e, w);
    }
    let mut model = ViewModel {
        yaw_spread: spread.solve(ridge),
        trained_on: trained_on.to_string(),
        yaw: yaw_w,
        pitch: pitch.solve(ridge),
        forward: pos_w[..HORIZONS].to_vec(),
        left: pos_w[HORIZONS..].to_vec(),
        yaw_rms: vec![0.0; HORIZONS],
    };
    model.yaw_rms = score(&model, val).yaw_rms;
    model
}

/// Errors of a model on samples (each kind weighted the same).
#[derive(Debug, Clone, PartialEq)]
pub struct Score {
    /// RMS yaw error per horizon (radians).
    pub yaw_rms: Vec<f64>,
    /// Mean absolute yaw error per horizon (radians), the model's and holding the yaw.
    pub yaw_mae: Vec<(f64, f64)>,
    /// Mean horizontal position error per horizon (metres), the model's and linear's.
    pub pos_mae: Vec<(f64, f64)>,
}

/// The model's errors on `samples` against holding the yaw and linear's position.
pub fn score(model: &ViewModel, samples: &[Sample]) -> Score {
    let w = kind_weights(samples);
    let total: f64 = w.iter().sum::<f64>().max(1e-12);
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
    let mut out = Score {
        yaw_rms: vec![0.0; HORIZONS],
        yaw_mae: vec![(0.0, 0.0); HORIZONS],
        pos_mae: vec![(0.0, 0.0); HORIZONS],
    };
    for (s, &w) in samples.iter().zip(&w) {
        let f = &s.features;
        for (k, t) in s.targets.iter().enumerate() {
            let e = wrap_angle(dot(&model.yaw[k], &f.yaw) - t[0]);
            out.yaw_rms[k] += w * e * e;
            out.yaw_mae[k].0 += w * e.abs();
            out.yaw_mae[k].1 += w * t[0].abs();
            let (fx, fy) = (dot(&model.forward[k], &f.pos), dot(&model.left[k], &f.pos));
            out.pos_mae[k].0 += w * (fx - t[2]).hypot(fy - t[3]);
            out.pos_mae[k].1 += w * t[2].hypot(t[3]);
        }
    }
    for k in 0..HORIZONS {
        out.yaw_rms[k] = (out.yaw_rms[k] / total).sqrt();
        out.yaw_mae[k].0 /= total;
        out.yaw_mae[k].1 /= total;
        out.pos_mae[k].0 /= total;
        out.pos_mae[k].1 /= total;
    }
    out
}

/// The tuning set's train and val samples.
pub fn tuning_samples(set: &TuningSet, stride_s: f64) -> (Vec<Sample>, Vec<Sample>) {
    (samples(set.train(), stride_s), samples(set.val(), stride_s))
}
