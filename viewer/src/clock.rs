//! Monotonic milliseconds that work natively and in the browser (`web-time` on wasm32), for
//! sort timings and frame pacing.

use std::sync::OnceLock;

static START: OnceLock<web_time::Instant> = OnceLock::new();

/// Milliseconds since the first call in this process (monotonic).
pub fn now_ms() -> f64 {
    START
        .get_or_init(web_time::Instant::now)
        .elapsed()
        .as_secs_f64()
        * 1e3
}
