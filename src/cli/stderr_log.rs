//! The library crates' `log` records on stderr: the server's access log as it is, warnings and
//! errors as `splat2tiles: warning: ...`; nothing below `Info`, and `Info` only for the access log.

use log::{Level, LevelFilter, Log, Metadata, Record};

/// The stderr logger the binary installs.
struct Stderr;

impl Log for Stderr {
    fn enabled(&self, m: &Metadata<'_>) -> bool {
        m.level() <= Level::Warn
            || (m.level() == Level::Info && m.target() == splat2tiles_serve::ACCESS_LOG)
    }

    fn log(&self, r: &Record<'_>) {
        if !self.enabled(r.metadata()) {
            return;
        }
        match r.level() {
            Level::Error => eprintln!("splat2tiles: error: {}", r.args()),
            Level::Warn => eprintln!("splat2tiles: warning: {}", r.args()),
            _ => eprintln!("{}", r.args()),
        }
    }

    fn flush(&self) {}
}

static LOGGER: Stderr = Stderr;

/// Installs the logger (once; a second call changes nothing).
pub fn install() {
    if log::set_logger(&LOGGER).is_ok() {
        log::set_max_level(LevelFilter::Info);
    }
}
