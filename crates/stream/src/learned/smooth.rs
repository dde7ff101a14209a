//! Causal Kalman smoothing of a pose history (TileSplat App. C.1): a constant-velocity filter per
//! position axis, on the unwrapped yaw and on the pitch, run forward only (what a client can do).
//!
//! Measured as an option of the training export (`examples/tcn_windows.rs --kalman`): see
//! BENCHMARKS.md, "Learned trajectory prediction", for whether it helps the model.

use crate::geom::{ViewPose, wrap_angle};

/// Noise settings of the filter: white-acceleration process noise and measurement noise, for
/// positions (metres) and angles (radians).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Kalman {
    /// Position process noise: acceleration spectral density (m^2/s^3).
    pub q_pos: f64,
    /// Position measurement standard deviation (m).
    pub r_pos: f64,
    /// Angle process noise (rad^2/s^3).
    pub q_ang: f64,
    /// Angle measurement standard deviation (rad).
    pub r_ang: f64,
}

impl Default for Kalman {
    /// Head-tracking scale: 1 m/s^2 and 1 rad/s^2 of unmodelled acceleration, 5 cm and 0.02 rad
    /// of measurement jitter.
    fn default() -> Self {
        Kalman {
            q_pos: 1.0,
            r_pos: 0.05,
            q_ang: 1.0,
            r_ang: 0.02,
        }
    }
}

/// One constant-velocity axis: state (value, rate) and its covariance.
#[derive(Debug, Clone, Copy)]
struct Axis {
    x: [f64; 2],
    p: [[f64; 2]; 2],
}

impl Axis {
    fn new(z: f64, r: f64) -> Self {
        // Rate unknown at the start: a wide prior on it.
        Axis {
            x: [z, 0.0],
            p: [[r * r, 0.0], [0.0, 100.0]],
        }
    }

    /// Predict `dt` ahead, then correct with measurement `z`; returns the filtered value.
    fn step(&mut self, dt: f64, z: f64, q: f64, r: f64) -> f64 {
        let [x0, x1] = self.x;
        let p = self.p;
        // F = [[1, dt], [0, 1]]; Q = q [[dt^3/3, dt^2/2], [dt^2/2, dt]].
        let xp = [x0 + dt * x1, x1];
        let p00 = p[0][0] + dt * (p[0][1] + p[1][0]) + dt * dt * p[1][1] + q * dt.powi(3) / 3.0;
        let p01 = p[0][1] + dt * p[1][1] + q * dt * dt / 2.0;
        let p10 = p[1][0] + dt * p[1][1] + q * dt * dt / 2.0;
        let p11 = p[1][1] + q * dt;
        let s = p00 + r * r;
        if !(s.is_finite() && s > 0.0 && z.is_finite()) {
            // Nothing to learn from this sample: keep the prediction if it is sane.
            if xp.iter().all(|v| v.is_finite()) {
                self.x = xp;
            }
            return self.x[0];
        }
        let (k0, k1) = (p00 / s, p10 / s);
        let innov = z - xp[0];
        self.x = [xp[0] + k0 * innov, xp[1] + k1 * innov];
        self.p = [
            [(1.0 - k0) * p00, (1.0 - k0) * p01],
            [p10 - k1 * p00, p11 - k1 * p01],
        ];
        self.x[0]
    }
}

/// The history filtered forward: each output pose depends only on poses up to its time. Times
/// are kept; yaw is unwrapped before filtering and wrapped back. Non-finite samples are skipped
/// by the filter (the prediction stands in for them); an empty history stays empty.
pub fn kalman(history: &[ViewPose], k: &Kalman) -> Vec<ViewPose> {
    let Some(first) = history.first() else {
        return vec![];
    };
    let mut axes = [
        Axis::new(first.pos.x, k.r_pos),
        Axis::new(first.pos.y, k.r_pos),
        Axis::new(first.pos.z, k.r_pos),
    ];
    let mut yaw = Axis::new(first.yaw, k.r_ang);
    let mut pitch = Axis::new(first.pitch, k.r_ang);
    let (mut prev_t, mut prev_yaw_raw, mut yaw_unwrapped) = (first.t, first.yaw, first.yaw);
    let mut out = Vec::with_capacity(history.len());
    out.push(*first);
    for p in &history[1..] {
        // Time steps clamped: repeated or backwards stamps add no motion, a gap adds at most 1 s.
        let dt = (p.t - prev_t).clamp(0.0, 1.0);
        if p.t.is_finite() {
            prev_t = p.t.max(prev_t);
        }
        if p.yaw.is_finite() {
            yaw_unwrapped += wrap_angle(p.yaw - prev_yaw_raw);
            prev_yaw_raw = p.yaw;
        }
        let mut q = *p;
        q.pos.x = axes[0].step(dt, p.pos.x, k.q_pos, k.r_pos);
        q.pos.y = axes[1].step(dt, p.pos.y, k.q_pos, k.r_pos);
        q.pos.z = axes[2].step(dt, p.pos.z, k.q_pos, k.r_pos);
        let y = if p.yaw.is_finite() {
            yaw_unwrapped
        } else {
            f64::NAN
        };
        q.yaw = wrap_angle(yaw.step(dt, y, k.q_ang, k.r_ang));
        q.pitch = pitch.step(dt, p.pitch, k.q_ang, k.r_ang);
        out.push(q);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    fn walk(n: usize, f: impl Fn(f64) -> (DVec3, f64)) -> Vec<ViewPose> {
        (0..n)
            .map(|i| {
                let t = i as f64 / 12.0;
                let (pos, yaw) = f(t);
                ViewPose {
                    t,
                    pos,
                    yaw,
                    pitch: 0.0,
                }
            })
            .collect()
    }

    #[test]
    fn a_steady_walk_passes_through_and_jitter_is_reduced() {
        let clean = walk(240, |t| (DVec3::new(1.4 * t, 2.0, 1.7), 0.3));
        let f = kalman(&clean, &Kalman::default());
        // Constant velocity is the filter's model: after the start-up it tracks exactly.
        let last = f.last().unwrap();
        assert!(
            last.pos.distance(clean.last().unwrap().pos) < 1e-3,
            "{last:?}"
        );
        // Deterministic jitter of 5 cm: the filtered error is well below the raw one.
        let noisy: Vec<ViewPose> = clean
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let mut q = *p;
                q.pos.y += 0.05 * ((i * 7919 % 13) as f64 / 6.0 - 1.0);
                q
            })
            .collect();
        // A filter that trusts its motion model more than the default smooths more.
        let calm = Kalman {
            q_pos: 0.1,
            ..Kalman::default()
        };
        let f = kalman(&noisy, &calm);
        let err = |a: &[ViewPose]| -> f64 {
            a[60..]
                .iter()
                .zip(&clean[60..])
                .map(|(a, b)| a.pos.distance(b.pos))
                .sum::<f64>()
                / (a.len() - 60) as f64
        };
        assert!(
            err(&f) < 0.6 * err(&noisy),
            "{} vs {}",
            err(&f),
            err(&noisy)
        );
        let d = kalman(&noisy, &Kalman::default());
        assert!(err(&d) < err(&noisy), "{} vs {}", err(&d), err(&noisy));
    }

    #[test]
    fn yaw_is_filtered_across_the_wrap_and_output_stays_wrapped() {
        // Turning at 1 rad/s through +-pi.
        let tr = walk(120, |t| (DVec3::ZERO, wrap_angle(2.8 + t)));
        let f = kalman(&tr, &Kalman::default());
        for (a, b) in f.iter().zip(&tr).skip(24) {
            assert!(
                wrap_angle(a.yaw - b.yaw).abs() < 0.02,
                "{} vs {}",
                a.yaw,
                b.yaw
            );
            assert!(a.yaw.abs() <= std::f64::consts::PI + 1e-12);
        }
    }

    #[test]
    fn degenerate_histories_stay_finite() {
        assert!(kalman(&[], &Kalman::default()).is_empty());
        let mut tr = walk(30, |t| (DVec3::new(t, 0.0, 1e6), 0.0));
        tr[10].pos.x = f64::NAN;
        tr[11].yaw = f64::INFINITY;
        tr[12].t = tr[11].t; // repeated stamp
        tr[20].t = tr[19].t - 5.0; // backwards stamp
        tr[25].t += 1e9; // long gap
        let f = kalman(&tr, &Kalman::default());
        assert_eq!(f.len(), tr.len());
        for p in &f {
            assert!(
                p.pos.is_finite() && p.yaw.is_finite() && p.pitch.is_finite(),
                "{p:?}"
            );
        }
    }
}
