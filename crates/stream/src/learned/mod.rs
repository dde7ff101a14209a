//! The learned trajectory predictor of TileSplat (sec. 3.3, App. C): a causal dilated TCN encoder
//! with an LSTM decoder and Gaussian outputs, trained offline (`tools/tcn/`), run by a small
//! pure-Rust forward pass over the weights of its ONNX export.

pub mod model;
mod net;
mod onnx;
pub mod smooth;
pub mod window;

pub use model::{RawOutput, TcnPredictor, TrajectoryModel, decode};
