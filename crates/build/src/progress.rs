//! Progress of long work reported as events: a stage begins (with a step count, or none for an
//! unknown length), steps complete, it ends. The front end draws them (the CLI's bars).

use std::sync::Arc;

/// Receives the progress of a conversion.
pub trait Progress: Send + Sync + std::fmt::Debug {
    /// A stage called `label` begins, of `total` steps (`None`: unknown, e.g. reading a file).
    fn begin(&self, label: &str, total: Option<u64>) -> Box<dyn Stage>;
}

/// One stage in progress.
pub trait Stage: Send + Sync {
    /// `n` more steps are done.
    fn advance(&self, n: u64);
    /// The stage is over (drawn progress disappears).
    fn finish(&self);
}

/// Where a conversion reports progress: nowhere by default.
pub type ProgressSink = Option<Arc<dyn Progress>>;

/// A stage of `sink` (a stage that reports to nobody when there is none).
pub fn begin(sink: &ProgressSink, label: &str, total: Option<u64>) -> Box<dyn Stage> {
    match sink {
        Some(p) => p.begin(label, total),
        None => Box::new(Silent),
    }
}

struct Silent;

impl Stage for Silent {
    fn advance(&self, _: u64) {}
    fn finish(&self) {}
}
