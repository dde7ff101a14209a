//! The trained TCN + LSTM trajectory model (TileSplat sec. 3.3, App. C; `tools/tcn/train.py`):
//! its ONNX export's weights run by a small forward pass (`net`), behind [`Predictor`].

use super::net::Net;
use super::onnx::Graph;
use super::window::{
    FUTURE_STEP_S, FUTURE_STEPS, HISTORY_STEPS, IN_CHANNELS, LocalFrame, OUT_CHANNELS, input_window,
};
use crate::geom::ViewPose;
use crate::predict::{Predictor, Uncertain};
use glam::DVec3;
use std::sync::Arc;

/// The committed TCN model (ONNX; trained by `tools/tcn/train.py`, see `tools/tcn/README.md`).
pub const TCN_ONNX: &[u8] = include_bytes!("tcn.onnx");

/// Largest model file accepted.
pub const MAX_MODEL_BYTES: usize = 5 << 20;

/// A loaded model: input `HISTORY_STEPS x IN_CHANNELS`, outputs (mean, log-variance)
/// `FUTURE_STEPS x OUT_CHANNELS` each.
#[derive(Clone)]
pub struct TrajectoryModel {
    net: Arc<Net>,
}

impl std::fmt::Debug for TrajectoryModel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("TrajectoryModel")
    }
}

/// The model's raw answer for one history: means and log-variances, `FUTURE_STEPS x
/// OUT_CHANNELS` row-major each, in the current pose's frame.
#[derive(Debug, Clone, PartialEq)]
pub struct RawOutput {
    /// Means.
    pub mean: Vec<f32>,
    /// Log-variances.
    pub logvar: Vec<f32>,
}

impl TrajectoryModel {
    /// Loads the weights of a `train.py` ONNX export; `name` is used in errors.
    pub fn load(bytes: &[u8], name: &str) -> Result<TrajectoryModel, String> {
        if bytes.len() > MAX_MODEL_BYTES {
            return Err(format!(
                "{name}: {} bytes, more than the {MAX_MODEL_BYTES}-byte model limit",
                bytes.len()
            ));
        }
        let graph = Graph::decode(bytes, name)?;
        let net = Net::from_graph(&graph, IN_CHANNELS, OUT_CHANNELS, name)?;
        Ok(TrajectoryModel { net: Arc::new(net) })
    }

    /// Loads a `train.py` ONNX export from a file, reading at most the model limit (a larger
    /// file is an error naming it, not a read).
    pub fn from_file(path: &std::path::Path) -> Result<TrajectoryModel, String> {
        use std::io::Read;
        let name = path.display().to_string();
        let mut bytes = vec![];
        std::fs::File::open(path)
            .and_then(|f| f.take(MAX_MODEL_BYTES as u64 + 1).read_to_end(&mut bytes))
            .map_err(|e| format!("{name}: {e}"))?;
        TrajectoryModel::load(&bytes, &name)
    }

    /// The committed model (loaded once per process).
    pub fn committed() -> Result<TrajectoryModel, String> {
        static MODEL: std::sync::OnceLock<Result<TrajectoryModel, String>> =
            std::sync::OnceLock::new();
        MODEL
            .get_or_init(|| TrajectoryModel::load(TCN_ONNX, "tcn.onnx (committed)"))
            .clone()
    }

    /// Runs the model on one input window (`HISTORY_STEPS x IN_CHANNELS`).
    pub fn run(&self, input: &[f32]) -> Result<RawOutput, String> {
        if input.len() != HISTORY_STEPS * IN_CHANNELS {
            return Err(format!(
                "trajectory model input has {} values, expected {}",
                input.len(),
                HISTORY_STEPS * IN_CHANNELS
            ));
        }
        let (mean, logvar) = self.net.forward(input, HISTORY_STEPS, FUTURE_STEPS);
        Ok(RawOutput { mean, logvar })
    }
}

/// The predicted trajectory of a raw output: poses at `FUTURE_STEP_S` steps in the world, with
/// the horizontal one-sigma (sqrt of the x and y variances) of each. Pitch is held (the model
/// predicts position and yaw, as TileSplat's 4-D state).
pub fn decode(out: &RawOutput, frame: &LocalFrame) -> Vec<Uncertain> {
    (0..FUTURE_STEPS)
        .map(|k| {
            let m = &out.mean[k * OUT_CHANNELS..(k + 1) * OUT_CHANNELS];
            let v = &out.logvar[k * OUT_CHANNELS..(k + 1) * OUT_CHANNELS];
            let l = DVec3::new(m[0] as f64, m[1] as f64, m[2] as f64);
            let var =
                (v[0] as f64).clamp(-30.0, 30.0).exp() + (v[1] as f64).clamp(-30.0, 30.0).exp();
            Uncertain {
                pose: ViewPose {
                    t: frame.origin.t + (k + 1) as f64 * FUTURE_STEP_S,
                    pos: frame.to_world(l),
                    yaw: frame.yaw_to_world(m[3] as f64, m[4] as f64),
                    pitch: frame.origin.pitch,
                },
                sigma_m: var.sqrt(),
            }
        })
        .collect()
}

/// TileSplat's learned predictor: the model over the last 5 s, App. C.5's fallback before that.
#[derive(Debug, Clone)]
pub struct TcnPredictor {
    model: TrajectoryModel,
    /// History needed before use (App. C.5: 5 s).
    pub min_history: f64,
    /// The last error of the model (then the prediction is empty: reactive).
    pub last_error: Option<String>,
}

impl TcnPredictor {
    /// A predictor with `model`.
    pub fn new(model: TrajectoryModel) -> TcnPredictor {
        TcnPredictor {
            model,
            min_history: 5.0,
            last_error: None,
        }
    }

    /// A predictor with the committed model.
    pub fn committed() -> Result<TcnPredictor, String> {
        Ok(TcnPredictor::new(TrajectoryModel::committed()?))
    }

    /// The full 30 s prediction at 2 Hz for `history` (empty on an empty history).
    pub fn predict_full(&mut self, history: &[ViewPose]) -> Vec<Uncertain> {
        let Some((frame, x)) = input_window(history) else {
            return vec![];
        };
        match self.model.run(&x) {
            Ok(out) => {
                self.last_error = None;
                decode(&out, &frame)
            }
            Err(e) => {
                self.last_error = Some(e);
                vec![]
            }
        }
    }
}

/// Samples a predicted path (after `now` = `start.t`) at `t`, linearly between its poses.
fn sample_path(start: &ViewPose, path: &[Uncertain], t: f64) -> Option<Uncertain> {
    let mut prev = Uncertain {
        pose: *start,
        sigma_m: 0.0,
    };
    for p in path {
        if t <= p.pose.t + 1e-9 {
            let span = p.pose.t - prev.pose.t;
            let s = if span > 1e-12 {
                (t - prev.pose.t) / span
            } else {
                1.0
            };
            let s = s.clamp(0.0, 1.0);
            return Some(Uncertain {
                pose: ViewPose {
                    t,
                    ..prev.pose.lerp(&p.pose, s)
                },
                sigma_m: prev.sigma_m + (p.sigma_m - prev.sigma_m) * s,
            });
        }
        prev = *p;
    }
    None
}

impl Predictor for TcnPredictor {
    fn name(&self) -> &str {
        "tcn"
    }

    fn min_history_s(&self) -> f64 {
        self.min_history
    }

    fn predict(&mut self, history: &[ViewPose], horizon: f64, step: f64) -> Vec<ViewPose> {
        self.predict_uncertain(history, horizon, step)
            .into_iter()
            .map(|u| u.pose)
            .collect()
    }

    fn predict_uncertain(
        &mut self,
        history: &[ViewPose],
        horizon: f64,
        step: f64,
    ) -> Vec<Uncertain> {
        let Some(last) = history.last().copied() else {
            return vec![];
        };
        if step <= 0.0 || horizon <= 0.0 {
            return vec![];
        }
        let path = self.predict_full(history);
        let n = (horizon.min(FUTURE_STEPS as f64 * FUTURE_STEP_S) / step + 1e-9).floor() as usize;
        (1..=n)
            .filter_map(|k| sample_path(&last, &path, last.t + k as f64 * step))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Inputs recorded by `tools/tcn/train.py --parity` with PyTorch's outputs for them.
    #[derive(serde::Deserialize)]
    struct Parity {
        inputs: Vec<Vec<f32>>,
        mean: Vec<Vec<f32>>,
        logvar: Vec<Vec<f32>>,
    }

    /// The largest difference between `m`'s outputs and PyTorch's on the recorded inputs.
    fn worst_difference(m: &TrajectoryModel, parity_json: &str) -> f32 {
        let rec: Parity = serde_json::from_str(parity_json).unwrap();
        assert!(!rec.inputs.is_empty());
        let mut worst = 0.0f32;
        for (i, x) in rec.inputs.iter().enumerate() {
            let out = m.run(x).unwrap();
            assert_eq!(out.mean.len(), rec.mean[i].len());
            for (a, b) in out.mean.iter().zip(&rec.mean[i]) {
                worst = worst.max((a - b).abs());
            }
            for (a, b) in out.logvar.iter().zip(&rec.logvar[i]) {
                worst = worst.max((a - b).abs());
            }
        }
        worst
    }

    #[test]
    fn a_model_file_is_read_only_up_to_the_limit() {
        let dir = tempfile::tempdir().unwrap();
        let ok = dir.path().join("tcn.onnx");
        std::fs::write(&ok, TCN_ONNX).unwrap();
        assert!(TrajectoryModel::from_file(&ok).is_ok());
        let big = dir.path().join("big.onnx");
        std::fs::write(&big, vec![0u8; MAX_MODEL_BYTES + 10]).unwrap();
        let e = TrajectoryModel::from_file(&big).unwrap_err();
        assert!(e.contains("big.onnx") && e.contains("model limit"), "{e}");
        let e = TrajectoryModel::from_file(&dir.path().join("none.onnx")).unwrap_err();
        assert!(e.contains("none.onnx"), "{e}");
    }

    #[test]
    fn the_committed_model_matches_pytorch_on_recorded_inputs() {
        let m = TrajectoryModel::committed().unwrap();
        let worst = worst_difference(&m, include_str!("parity.json"));
        eprintln!("largest difference from PyTorch: {worst:e}");
        assert!(worst <= 1e-4, "largest difference from PyTorch {worst}");
        assert!(TCN_ONNX.len() <= MAX_MODEL_BYTES);
    }

    /// The LSTM-only baseline (`train.py --arch lstm`, Table 3's row; test data only) runs the
    /// 2-layer LSTM encoder path of the forward pass.
    #[test]
    fn the_lstm_only_baseline_matches_pytorch_on_recorded_inputs() {
        let m = TrajectoryModel::load(include_bytes!("lstm_only.onnx"), "lstm_only.onnx").unwrap();
        let worst = worst_difference(&m, include_str!("lstm_only_parity.json"));
        eprintln!("LSTM-only: largest difference from PyTorch: {worst:e}");
        assert!(worst <= 1e-4, "largest difference from PyTorch {worst}");
    }

    #[test]
    fn bad_models_and_inputs_are_errors_not_panics() {
        assert!(
            TrajectoryModel::load(b"not onnx", "x.onnx")
                .unwrap_err()
                .contains("x.onnx")
        );
        let big = vec![0u8; MAX_MODEL_BYTES + 1];
        assert!(
            TrajectoryModel::load(&big, "big.onnx")
                .unwrap_err()
                .contains("limit")
        );
        let m = TrajectoryModel::committed().unwrap();
        assert!(m.run(&[0.0; 5]).is_err());
    }

    #[test]
    fn truncated_weight_files_are_errors_naming_the_file() {
        // Every cut inside the graph (the file ends with its 4-byte opset import).
        let end = TCN_ONNX.len() - 8;
        for n in (0..end).step_by(409).chain([1, end / 2, end - 1]) {
            let e = TrajectoryModel::load(&TCN_ONNX[..n], "cut.onnx").unwrap_err();
            assert!(e.contains("cut.onnx"), "{n}: {e}");
        }
    }

    #[test]
    fn corrupted_weight_files_are_errors_or_models_never_panics() {
        let x = vec![0.25f32; HISTORY_STEPS * IN_CHANNELS];
        let mut errors = 0;
        for at in (0..TCN_ONNX.len()).step_by(263) {
            for flip in [0xffu8, 0x80] {
                let mut bytes = TCN_ONNX.to_vec();
                bytes[at] ^= flip;
                match TrajectoryModel::load(&bytes, "bad.onnx") {
                    Ok(m) => assert_eq!(m.run(&x).unwrap().mean.len(), FUTURE_STEPS * OUT_CHANNELS),
                    Err(e) => {
                        assert!(e.contains("bad.onnx"), "{e}");
                        errors += 1;
                    }
                }
            }
        }
        assert!(errors > 0);
        // A weight of the wrong shape: the first conv's dims [32, 6, 3] made [32, 6, 2].
        let name = b"enc.0.c1.conv.weight";
        let mut bytes = TCN_ONNX.to_vec();
        let at = bytes.windows(name.len()).rposition(|w| w == name).unwrap();
        let dims = [0x08, 32, 0x08, 6, 0x08, 3];
        let d = bytes[..at].windows(6).rposition(|w| w == dims).unwrap();
        bytes[d + 5] = 2;
        let e = TrajectoryModel::load(&bytes, "shape.onnx").unwrap_err();
        assert!(
            e.contains("shape.onnx") && e.contains("enc.0.c1.conv.weight"),
            "{e}"
        );
    }

    #[test]
    fn the_tcn_follows_a_steady_walk_with_an_uncertainty() {
        let mut p = TcnPredictor::committed().unwrap();
        let h = super::super::window::straight_walk(8.0, 1.4);
        let now = *h.last().unwrap();
        let out = p.predict_uncertain(&h, 10.0, 0.5);
        assert_eq!(out.len(), 20);
        assert!(p.last_error.is_none());
        // Ahead along +x after 5 s, not behind or far off to a side.
        let at5 = out[9].pose;
        assert!((at5.t - now.t - 5.0).abs() < 1e-9);
        assert!(
            at5.pos.x > now.pos.x + 2.0,
            "{:?} from {:?}",
            at5.pos,
            now.pos
        );
        assert!((at5.pos.y - now.pos.y).abs() < 3.0, "{:?}", at5.pos);
        assert!(out.iter().all(|u| u.sigma_m.is_finite() && u.sigma_m > 0.0));
        // Horizons past the model's 30 s stop at 30 s; other step sizes are interpolated.
        assert_eq!(p.predict(&h, 45.0, 1.0).len(), 30);
        assert_eq!(p.predict(&h, 10.0, 0.25).len(), 40);
        assert!(p.predict(&[], 10.0, 0.5).is_empty());
    }
}
