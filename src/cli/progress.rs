//! The command line's progress bars: draws the build's progress events with indicatif (a bar
//! for a stage of known length, a spinner otherwise), on a terminal only.

use std::io::IsTerminal;
use std::sync::Arc;

use indicatif::{ProgressBar, ProgressStyle};
use splat2tiles_build::progress::{Progress, ProgressSink, Stage};

/// Bars on stderr.
#[derive(Debug)]
struct Bars;

impl Progress for Bars {
    fn begin(&self, label: &str, total: Option<u64>) -> Box<dyn Stage> {
        let b = match total {
            Some(len) => {
                let b = ProgressBar::new(len);
                if let Ok(style) =
                    ProgressStyle::with_template("{msg:>14} [{bar:40}] {pos}/{len} ({eta})")
                {
                    b.set_style(style.progress_chars("=> "));
                }
                b
            }
            None => {
                let s = ProgressBar::new_spinner();
                s.enable_steady_tick(std::time::Duration::from_millis(120));
                s
            }
        };
        b.set_message(label.to_string());
        Box::new(Bar(b))
    }
}

struct Bar(ProgressBar);

impl Stage for Bar {
    fn advance(&self, n: u64) {
        self.0.inc(n);
    }
    fn finish(&self) {
        self.0.finish_and_clear();
    }
}

/// Bars unless `quiet` or stderr is not a terminal.
pub fn bars(quiet: bool) -> ProgressSink {
    (!quiet && std::io::stderr().is_terminal()).then(|| Arc::new(Bars) as Arc<dyn Progress>)
}
