//! Training windows for the learned trajectory predictor (`stream::learned`) cut from traces, and
//! the per-horizon ADE/FDE and tile coverage of predictors on traces (TileSplat Table 3, Fig. 10).
//!
//! The traces come only through [`splat2tiles_stream::split`]'s sets: the export writes the tuning set's train
//! and val windows; the evaluation takes whatever set its caller was allowed to build.

use splat2tiles_stream::learned::smooth::{Kalman, kalman};
use splat2tiles_stream::learned::window::{
    FUTURE_STEP_S, FUTURE_STEPS, HISTORY_STEPS, IN_CHANNELS, OUT_CHANNELS, anchors, history_until,
    input_window, target_window,
};
use splat2tiles_stream::predict::{Predictor, sample_trace};
use splat2tiles_stream::trace::Trace;
use std::io::Write;
use std::path::Path;

/// The kind of a trace: `human` (a real session: `kind` header `eyenav`, or none), else its
/// `kind` header (`street_walk`, `flight`).
pub fn trace_kind(t: &Trace) -> &str {
    match t.header("kind") {
        Some("eyenav") | None => "human",
        Some(k) => k,
    }
}

/// Kinds in the order of their codes in exported windows.
pub const KINDS: [&str; 3] = ["human", "street_walk", "flight"];

/// Input and target windows of a set of traces.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Windows {
    /// Inputs, `HISTORY_STEPS x IN_CHANNELS` per window.
    pub x: Vec<f32>,
    /// Targets, `FUTURE_STEPS x OUT_CHANNELS` per window.
    pub y: Vec<f32>,
    /// Index into [`KINDS`] per window.
    pub kind: Vec<u8>,
}

impl Windows {
    /// Number of windows.
    pub fn len(&self) -> usize {
        self.kind.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.kind.is_empty()
    }
}

/// Every window of `traces` at anchors `stride_s` apart, the history cut at 10 s as the client
/// keeps it; with `smooth`, the history Kalman-filtered first (the targets stay raw).
pub fn windows(traces: &[Trace], stride_s: f64, smooth: Option<&Kalman>) -> Windows {
    let mut w = Windows::default();
    for t in traces {
        let code = KINDS.iter().position(|k| *k == trace_kind(t)).unwrap_or(0) as u8;
        for a in anchors(&t.poses, stride_s) {
            let mut h = client_history(&t.poses, a);
            if let Some(k) = smooth {
                h = kalman(&h, k);
            }
            let Some((frame, x)) = input_window(&h) else {
                continue;
            };
            let Some(y) = target_window(&t.poses, &frame) else {
                continue;
            };
            w.x.extend(x);
            w.y.extend(y);
            w.kind.push(code);
        }
    }
    w
}

/// The history a client holds at `t`: the last 10 s.
fn client_history(
    trace: &[splat2tiles_stream::ViewPose],
    t: f64,
) -> Vec<splat2tiles_stream::ViewPose> {
    let mut h = history_until(trace, t);
    let drop = h.iter().take_while(|p| p.t < t - 10.0).count();
    h.drain(..drop);
    h
}

/// Writes `NAME.x.f32`, `NAME.y.f32` (little-endian f32) and `NAME.json` (shapes, kinds) into
/// `dir`; files are written to a temporary name and renamed, so a failure leaves no partial file.
pub fn write_windows(dir: &Path, name: &str, w: &Windows) -> Result<(), String> {
    let put = |file: String, bytes: &[u8]| -> Result<(), String> {
        let path = dir.join(&file);
        let tmp = dir.join(format!("{file}.tmp"));
        let r = std::fs::File::create(&tmp)
            .and_then(|mut f| f.write_all(bytes).and_then(|_| f.sync_all()))
            .and_then(|_| std::fs::rename(&tmp, &path));
        if let Err(e) = r {
            let _ = std::fs::remove_file(&tmp);
            return Err(format!("{}: {e}", path.display()));
        }
        Ok(())
    };
    let f32s = |v: &[f32]| v.iter().flat_map(|f| f.to_le_bytes()).collect::<Vec<u8>>();
    put(format!("{name}.x.f32"), &f32s(&w.x))?;
    put(format!("{name}.y.f32"), &f32s(&w.y))?;
    let meta = serde_json::json!({
        "windows": w.len(),
        "x_shape": [w.len(), HISTORY_STEPS, IN_CHANNELS],
        "y_shape": [w.len(), FUTURE_STEPS, OUT_CHANNELS],
        "future_step_s": FUTURE_STEP_S,
        "kinds": KINDS,
        "kind": w.kind,
    });
    put(format!("{name}.json"), meta.to_string().as_bytes())
}

/// Horizons (s) of the table.
pub const HORIZONS: [f64; 6] = [5.0, 10.0, 15.0, 20.0, 25.0, 30.0];

/// Mean errors of one predictor over windows: ADE (mean 3-D position error over the steps up to
/// the horizon) and FDE (error at the horizon), per [`HORIZONS`] entry, and mean seconds per call.
#[derive(Debug, Clone, PartialEq)]
pub struct ErrorRow {
    /// Predictor name.
    pub name: String,
    /// Windows evaluated.
    pub windows: usize,
    /// ADE per horizon (m).
    pub ade: [f64; 6],
    /// FDE per horizon (m).
    pub fde: [f64; 6],
    /// Mean wall-clock milliseconds per prediction (host-dependent; not for tests).
    pub ms_per_call: f64,
}

/// Evaluates `p` on every window of `traces` (`stride_s` apart) with the client's 10 s history;
/// predictions cover 30 s at 0.5 s. A missing step (a predictor answering fewer poses) counts
/// as the last pose it gave held (or the current pose if none).
pub fn evaluate(p: &mut dyn Predictor, traces: &[Trace], stride_s: f64) -> ErrorRow {
    let n = FUTURE_STEPS;
    let mut sum = vec![0.0f64; n];
    let mut windows = 0usize;
    let mut secs = 0.0f64;
    for t in traces {
        for a in anchors(&t.poses, stride_s) {
            let h = client_history(&t.poses, a);
            let Some(now) = h.last().copied() else {
                continue;
            };
            let clock = std::time::Instant::now();
            let pred = p.predict(&h, n as f64 * FUTURE_STEP_S, FUTURE_STEP_S);
            secs += clock.elapsed().as_secs_f64();
            let mut held = now.pos;
            for (k, s) in sum.iter_mut().enumerate() {
                let tk = a + (k + 1) as f64 * FUTURE_STEP_S;
                if let Some(q) = pred.get(k) {
                    held = q.pos;
                }
                let truth = sample_trace(&t.poses, tk).map_or(now.pos, |q| q.pos);
                *s += held.distance(truth);
            }
            windows += 1;
        }
    }
    let mean: Vec<f64> = sum.iter().map(|s| s / windows.max(1) as f64).collect();
    let mut ade = [0.0; 6];
    let mut fde = [0.0; 6];
    for (i, h) in HORIZONS.iter().enumerate() {
        let k = ((h / FUTURE_STEP_S).round() as usize).clamp(1, n);
        ade[i] = mean[..k].iter().sum::<f64>() / k as f64;
        fde[i] = mean[k - 1];
    }
    ErrorRow {
        name: p.name().to_string(),
        windows,
        ade,
        fde,
        ms_per_call: 1e3 * secs / windows.max(1) as f64,
    }
}

/// Tile coverage per [`HORIZONS`] entry (TileSplat Table 3): over windows `stride_s` apart, the
/// mean fraction of the tiles in the needed cut of the true pose at `now + h` that are in the
/// current view's cut or the cut of a pose `p` predicted up to `now + h` (0.5 s steps): what a
/// client prefetching along the prediction would hold, ignoring bandwidth and eviction.
/// `cut` gives a pose's needed cut; windows whose true cut is empty are skipped. Also returns
/// the windows counted per horizon.
pub fn coverage<K: std::hash::Hash + Eq + Copy>(
    p: &mut dyn Predictor,
    traces: &[Trace],
    stride_s: f64,
    cut: &mut dyn FnMut(&splat2tiles_stream::ViewPose) -> Vec<K>,
) -> ([f64; 6], [usize; 6]) {
    let mut sum = [0.0f64; 6];
    let mut count = [0usize; 6];
    for t in traces {
        for a in anchors(&t.poses, stride_s) {
            let h = client_history(&t.poses, a);
            let Some(now) = h.last().copied() else {
                continue;
            };
            let pred = p.predict(&h, FUTURE_STEPS as f64 * FUTURE_STEP_S, FUTURE_STEP_S);
            let mut held: std::collections::HashSet<K> = cut(&now).into_iter().collect();
            let mut next = 0;
            for (i, hz) in HORIZONS.iter().enumerate() {
                while let Some(q) = pred.get(next).filter(|q| q.t <= a + hz + 1e-9) {
                    held.extend(cut(q));
                    next += 1;
                }
                let Some(truth) = sample_trace(&t.poses, a + hz) else {
                    continue;
                };
                let need = cut(&truth);
                if need.is_empty() {
                    continue;
                }
                let hit = need.iter().filter(|k| held.contains(k)).count();
                sum[i] += hit as f64 / need.len() as f64;
                count[i] += 1;
            }
        }
    }
    let mut out = [0.0; 6];
    for i in 0..6 {
        out[i] = sum[i] / count[i].max(1) as f64;
    }
    (out, count)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;
    use splat2tiles_stream::ViewPose;
    use splat2tiles_stream::predict::{ConstantVelocity, Reactive};

    fn line(seed: u64, v: f64) -> Trace {
        Trace {
            headers: vec![
                ("kind".into(), "street_walk".into()),
                ("seed".into(), seed.to_string()),
            ],
            poses: (0..=12 * 50)
                .map(|i| ViewPose {
                    t: i as f64 / 12.0,
                    pos: DVec3::new(v * i as f64 / 12.0, 0.0, 1.7),
                    yaw: 0.0,
                    pitch: 0.0,
                })
                .collect(),
        }
    }

    #[test]
    fn constant_velocity_is_exact_on_a_line_and_reactive_is_off_by_the_distance_walked() {
        let tr = [line(1, 2.0)];
        let cv = evaluate(&mut ConstantVelocity::default(), &tr, 1.0);
        assert!(cv.windows > 5);
        assert!(cv.fde[5] < 1e-6, "{cv:?}");
        let r = evaluate(&mut Reactive, &tr, 1.0);
        // Held at the current pose: error at 30 s is 60 m, mean over 0.5..5 s is 5.5 m.
        assert!(
            (r.fde[5] - 60.0).abs() < 1e-6 && (r.ade[0] - 5.5).abs() < 1e-6,
            "{r:?}"
        );
    }

    #[test]
    fn a_prediction_on_the_path_covers_the_future_cut_and_no_prediction_does_not() {
        // A pose's "cut": the 10 m cells of x from 0 to 20 m ahead of it.
        let mut cut = |p: &ViewPose| -> Vec<i64> {
            let c = (p.pos.x / 10.0).floor() as i64;
            (c..=c + 2).collect()
        };
        let tr = [line(1, 2.0)];
        let (cv, n) = coverage(&mut ConstantVelocity::default(), &tr, 1.0, &mut cut);
        assert!(n.iter().all(|&n| n > 5));
        assert!(cv.iter().all(|c| (c - 1.0).abs() < 1e-9), "{cv:?}");
        // Reactive holds the current cells only: 2 m/s for 5 s = 10 m moved, about two of the
        // three cells still held at 5 s; none from 30 s (60 m ahead).
        let (r, _) = coverage(&mut Reactive, &tr, 1.0, &mut cut);
        assert!((0.6..=0.7).contains(&r[0]) && r[5] == 0.0, "{r:?}");
    }

    #[test]
    fn real_sessions_are_human_and_synthetic_traces_keep_their_kind() {
        let mut t = line(3, 1.0);
        assert_eq!(trace_kind(&t), "street_walk");
        t.headers[0].1 = "eyenav".into();
        assert_eq!(trace_kind(&t), "human");
        t.headers.remove(0);
        assert_eq!(trace_kind(&t), "human");
    }

    #[test]
    fn windows_are_written_whole_with_their_kinds() {
        let w = windows(&[line(2, 1.0)], 1.0, None);
        assert_eq!(w.len(), 16);
        assert_eq!(w.x.len(), w.len() * HISTORY_STEPS * IN_CHANNELS);
        assert_eq!(w.kind[0], 1);
        let dir = tempfile::tempdir().unwrap();
        write_windows(dir.path(), "train", &w).unwrap();
        let y = std::fs::read(dir.path().join("train.y.f32")).unwrap();
        assert_eq!(y.len(), w.y.len() * 4);
        let meta: serde_json::Value =
            serde_json::from_slice(&std::fs::read(dir.path().join("train.json")).unwrap()).unwrap();
        assert_eq!(meta["windows"], w.len());
        assert!(write_windows(&dir.path().join("missing"), "train", &w).is_err());
    }
}
