//! Trace-driven streaming simulator: a clock-driven client over a network model, using the
//! `stream` core, with the metrics of TileSplat Table 4 (CHR, TGQ, WD) and Table 5.

pub mod client;
pub mod session;
pub mod svg;
pub mod trace;
pub mod transport;

pub use client::{NetModel, SimConfig, SimResult, run_session};
pub use trace::Trace;
