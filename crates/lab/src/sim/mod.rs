//! Trace-driven streaming simulation: the real client over a simulated transport (bandwidth from
//! a trace, RTT, overheads), camera traces, session logs and their summaries.

pub mod learn;
pub mod mirror;
pub mod misses;
pub mod network;
pub mod report;
pub mod score;
pub mod session;
pub mod stream_city;
pub mod summary;
pub mod svg;
pub mod tcn_data;
pub mod transport;

pub use session::{SessionLog, SessionOptions, run_session};
pub use splat2tiles_stream::trace::Trace;
pub use transport::{NetModel, SimTransport};
