//! The learned predictor's input and target windows: history resampled at 12 Hz, future at 2 Hz,
//! both in the frame of the current pose (origin at its position, x along its heading).
//!
//! One definition for the training export (`examples/tcn_windows.rs`), the evaluation and the
//! inference, so the model sees in the client exactly what it was trained on.

use crate::geom::{ViewPose, wrap_angle};
use crate::predict::sample_trace;
use glam::DVec3;

/// History samples fed to the model (TileSplat App. C.5: 60 states, 5 s at 12 Hz).
pub const HISTORY_STEPS: usize = 60;
/// History sampling rate (Hz).
pub const HISTORY_HZ: f64 = 12.0;
/// Seconds of history the model reads.
pub const HISTORY_S: f64 = (HISTORY_STEPS - 1) as f64 / HISTORY_HZ;
/// Predicted steps (reduced from 12 Hz to 2 Hz over 30 s to fit CPU training).
pub const FUTURE_STEPS: usize = 60;
/// Seconds between predicted steps.
pub const FUTURE_STEP_S: f64 = 0.5;
/// Input channels per history step: x, y, z (current-pose frame, m), cos and sin of the yaw
/// relative to the current yaw, pitch (rad).
pub const IN_CHANNELS: usize = 6;
/// Target channels per future step: x, y, z (current-pose frame, m), cos and sin of the relative
/// yaw. The model outputs a mean and a log-variance for each.
pub const OUT_CHANNELS: usize = 5;

/// Maps world poses into the frame of `origin` (and back).
#[derive(Debug, Clone, Copy)]
pub struct LocalFrame {
    /// The current pose.
    pub origin: ViewPose,
}

impl LocalFrame {
    /// A world position in the local frame (x ahead, y left, z up).
    pub fn to_local(&self, p: DVec3) -> DVec3 {
        let d = p - self.origin.pos;
        let (s, c) = self.origin.yaw.sin_cos();
        DVec3::new(c * d.x + s * d.y, -s * d.x + c * d.y, d.z)
    }

    /// A local position back in the world.
    pub fn to_world(&self, l: DVec3) -> DVec3 {
        let (s, c) = self.origin.yaw.sin_cos();
        self.origin.pos + DVec3::new(c * l.x - s * l.y, s * l.x + c * l.y, l.z)
    }

    /// A relative yaw given as (cos, sin) back to a world yaw.
    pub fn yaw_to_world(&self, cos: f64, sin: f64) -> f64 {
        wrap_angle(self.origin.yaw + sin.atan2(cos))
    }
}

/// The model input for the history ending at its last pose: `HISTORY_STEPS x IN_CHANNELS`
/// row-major (oldest first), history before the first pose clamped to it. `None` on an empty
/// history.
pub fn input_window(history: &[ViewPose]) -> Option<(LocalFrame, Vec<f32>)> {
    let last = *history.last()?;
    let frame = LocalFrame { origin: last };
    let mut out = Vec::with_capacity(HISTORY_STEPS * IN_CHANNELS);
    for k in 0..HISTORY_STEPS {
        let t = last.t - (HISTORY_STEPS - 1 - k) as f64 / HISTORY_HZ;
        let p = sample_trace(history, t)?;
        let l = frame.to_local(p.pos);
        let dy = wrap_angle(p.yaw - last.yaw);
        for v in [l.x, l.y, l.z, dy.cos(), dy.sin(), p.pitch] {
            out.push(v as f32);
        }
    }
    Some((frame, out))
}

/// The training target after `frame`'s pose: `FUTURE_STEPS x OUT_CHANNELS` row-major, sampled
/// from `trace` (which must reach `FUTURE_STEPS * FUTURE_STEP_S` seconds past the pose).
pub fn target_window(trace: &[ViewPose], frame: &LocalFrame) -> Option<Vec<f32>> {
    let end = trace.last()?.t;
    let t0 = frame.origin.t;
    if end + 1e-9 < t0 + FUTURE_STEPS as f64 * FUTURE_STEP_S {
        return None;
    }
    let mut out = Vec::with_capacity(FUTURE_STEPS * OUT_CHANNELS);
    for k in 1..=FUTURE_STEPS {
        let p = sample_trace(trace, t0 + k as f64 * FUTURE_STEP_S)?;
        let l = frame.to_local(p.pos);
        let dy = wrap_angle(p.yaw - frame.origin.yaw);
        for v in [l.x, l.y, l.z, dy.cos(), dy.sin()] {
            out.push(v as f32);
        }
    }
    Some(out)
}

/// Window anchor times of a trace: every `stride_s` from `HISTORY_S` after its start while the
/// future window fits.
pub fn anchors(trace: &[ViewPose], stride_s: f64) -> Vec<f64> {
    let (Some(a), Some(b)) = (trace.first(), trace.last()) else {
        return vec![];
    };
    let mut out = vec![];
    let mut t = a.t + HISTORY_S;
    let last = b.t - FUTURE_STEPS as f64 * FUTURE_STEP_S;
    while stride_s > 0.0 && t <= last + 1e-9 {
        out.push(t);
        t += stride_s;
    }
    out
}

/// The trace up to and including time `t` (the last pose interpolated at `t`).
pub fn history_until(trace: &[ViewPose], t: f64) -> Vec<ViewPose> {
    let i = trace.partition_point(|p| p.t < t);
    let mut h = trace[..i].to_vec();
    if let Some(p) = sample_trace(trace, t) {
        h.push(p);
    }
    h
}

/// A steady walk along +x at `speed` m/s for `secs` at 12 Hz, eyes at 1.7 m: the fixed history
/// the benchmarks and the web viewer's self-check time and sanity-check the model on.
pub fn straight_walk(secs: f64, speed: f64) -> Vec<ViewPose> {
    let n = (secs.clamp(0.0, 3600.0) * HISTORY_HZ) as usize;
    (0..=n)
        .map(|i| {
            let t = i as f64 / HISTORY_HZ;
            ViewPose {
                t,
                pos: DVec3::new(speed * t, 5.0, 1.7),
                yaw: 0.0,
                pitch: 0.0,
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn walk(v: DVec3, yaw: f64, secs: f64) -> Vec<ViewPose> {
        (0..=(secs * 12.0) as usize)
            .map(|i| {
                let t = i as f64 / 12.0;
                ViewPose {
                    t,
                    pos: DVec3::new(10.0, -4.0, 1.7) + v * t,
                    yaw,
                    pitch: 0.1,
                }
            })
            .collect()
    }

    #[test]
    fn a_straight_walk_is_along_local_x_whatever_its_heading() {
        for yaw in [0.0f64, 1.0, -2.5] {
            let v = DVec3::new(yaw.cos(), yaw.sin(), 0.0) * 1.5;
            let tr = walk(v, yaw, 40.0);
            let t0 = anchors(&tr, 1.0)[0];
            assert!((t0 - HISTORY_S).abs() < 1e-9);
            let h = history_until(&tr, t0);
            let (frame, x) = input_window(&h).unwrap();
            assert_eq!(x.len(), HISTORY_STEPS * IN_CHANNELS);
            // Oldest sample: 1.5 m/s * HISTORY_S behind, on the x axis; yaw relative 0.
            assert!((x[0] as f64 + 1.5 * HISTORY_S).abs() < 1e-4, "{}", x[0]);
            assert!(x[1].abs() < 1e-4 && (x[3] - 1.0).abs() < 1e-6 && x[4].abs() < 1e-6);
            let y = target_window(&tr, &frame).unwrap();
            let k = FUTURE_STEPS - 1;
            assert!((y[k * OUT_CHANNELS] as f64 - 1.5 * 30.0).abs() < 1e-3);
            let back = frame.to_world(frame.to_local(DVec3::new(3.0, 2.0, 1.0)));
            assert!(back.distance(DVec3::new(3.0, 2.0, 1.0)) < 1e-9);
        }
    }

    #[test]
    fn no_target_past_the_end_and_no_anchor_on_a_short_trace() {
        let tr = walk(DVec3::X, 0.0, 20.0);
        assert!(anchors(&tr, 1.0).is_empty());
        let frame = LocalFrame { origin: tr[60] };
        assert!(target_window(&tr, &frame).is_none());
        assert!(input_window(&[]).is_none());
    }
}
