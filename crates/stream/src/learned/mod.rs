//! Learned trajectory predictors: the view model (per-horizon linear corrections, `view_model`)
//! and TileSplat's TCN + LSTM (sec. 3.3, App. C; `tools/tcn/`, run from its ONNX export's weights).

pub mod model;
mod net;
mod onnx;
pub mod smooth;
pub mod view_model;
pub mod window;

pub use model::{RawOutput, TcnPredictor, TrajectoryModel, decode};
pub use view_model::{LearnedPredictor, ViewModel};
