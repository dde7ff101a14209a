//! The learned trajectory predictor of TileSplat (sec. 3.3, App. C): a causal dilated TCN encoder
//! with an LSTM decoder and Gaussian outputs, trained offline (`tools/tcn/`), run with tract.

pub mod model;
pub mod window;

pub use model::{RawOutput, TcnPredictor, TrajectoryModel, decode};
