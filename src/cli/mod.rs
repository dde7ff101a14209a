//! Command-line front ends of the library: argument structs (clap) and one `run` per command,
//! so that `main.rs` only parses and maps results to exit codes.

#[macro_use]
pub mod out;

pub mod convert;
pub mod import_lapisgs;
pub mod progress;
pub mod render;
pub mod serve;
pub mod stats;
pub mod stderr_log;
pub mod validate;

/// Exit code when the command could not do its work (bad input, I/O failure).
pub const EXIT_FAILURE: i32 = 2;
/// Exit code when a check ran and found errors.
pub const EXIT_FINDINGS: i32 = 1;

/// How to run this program again from the current folder, for the commands that hints suggest:
/// `splat2tiles` when that name on `PATH` is this executable (installed), else its path (relative
/// to the current folder when inside it, e.g. `target/release/splat2tiles` under `cargo run`).
pub fn program() -> String {
    const NAME: &str = "splat2tiles";
    let Some(exe) = std::env::current_exe()
        .ok()
        .and_then(|e| std::fs::canonicalize(e).ok())
    else {
        return NAME.into();
    };
    let on_path = std::env::var_os("PATH").is_some_and(|paths| {
        std::env::split_paths(&paths)
            .map(|d| d.join(format!("{NAME}{}", std::env::consts::EXE_SUFFIX)))
            .find(|c| c.is_file())
            .and_then(|c| std::fs::canonicalize(c).ok())
            .is_some_and(|c| c == exe)
    });
    if on_path {
        return NAME.into();
    }
    let cwd = std::env::current_dir()
        .ok()
        .and_then(|d| std::fs::canonicalize(d).ok());
    let shown = match cwd.as_deref().and_then(|d| exe.strip_prefix(d).ok()) {
        Some(rel) => rel.to_path_buf(),
        None => exe,
    };
    let s = shown.display().to_string();
    // A path with spaces is quoted so that the suggested line can be pasted.
    if s.contains(char::is_whitespace) {
        format!("'{s}'")
    } else {
        s
    }
}

/// A clap parser of a [`Named`](splat2tiles_core::named::Named) option: its names as the possible
/// values, each with its help line.
pub fn named<T: splat2tiles_core::named::Named + Clone + Send + Sync>()
-> impl clap::builder::TypedValueParser<Value = T> {
    use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};
    PossibleValuesParser::new(
        T::ALL
            .iter()
            .map(|v| PossibleValue::new(v.name()).help(v.help().trim_end_matches('.'))),
    )
    // The possible values are exactly T's names.
    .map(|s| T::from_name(&s).unwrap_or(T::ALL[0]))
}

/// Installs the Ctrl-C / SIGTERM handler of the commands that write tilesets: without a
/// conversion writing it exits with 130 at once; during one it asks the pipeline to stop (the
/// unfinished output is removed, then the command exits with 130); a second signal exits at once.
pub fn install_interrupt_handler() {
    use splat2tiles_build::output::{Interrupt, interrupt};
    let _ = ctrlc::set_handler(|| match interrupt() {
        Interrupt::Idle => {
            eprintln!("splat2tiles: interrupted");
            std::process::exit(130);
        }
        Interrupt::Again => {
            eprintln!(
                "splat2tiles: interrupted again; exiting now (the next run into this output removes what is left)"
            );
            std::process::exit(130);
        }
        Interrupt::Stopping => eprintln!(
            "splat2tiles: interrupting; stopping the workers and removing the unfinished output"
        ),
    });
}
