//! Everything the commands print on stdout goes through `out!` and `outln!`: a reader that
//! went away (a closed pipe, `| head`) ends the process quietly with 141, as SIGPIPE would; any
//! other failure (a full disk behind a redirect) is an error that exits 2, never a panic.

use std::io::Write;

/// Exit code after stdout's reader went away (128 + SIGPIPE, what a shell reports for a
/// process SIGPIPE ended).
pub const EXIT_BROKEN_PIPE: i32 = 141;

/// Writes `args` to stdout, ending the process on failure (see the module).
pub fn write(args: std::fmt::Arguments<'_>) {
    let mut o = std::io::stdout().lock();
    if let Err(e) = o.write_fmt(args) {
        fail(&e);
    }
}

/// Flushes stdout before the process exits, with the same handling of failures.
pub fn flush() {
    if let Err(e) = std::io::stdout().lock().flush() {
        fail(&e);
    }
}

/// Ends the process after a failed write to stdout.
fn fail(e: &std::io::Error) -> ! {
    if e.kind() == std::io::ErrorKind::BrokenPipe {
        std::process::exit(EXIT_BROKEN_PIPE);
    }
    eprintln!("splat2tiles: cannot write to stdout: {e}");
    std::process::exit(super::EXIT_FAILURE);
}

/// `print!` through `write()`.
macro_rules! out {
    ($($t:tt)*) => {
        $crate::cli::out::write(format_args!($($t)*))
    };
}

/// `println!` through `write()`.
macro_rules! outln {
    () => {
        $crate::cli::out::write(format_args!("\n"))
    };
    ($($t:tt)*) => {
        $crate::cli::out::write(format_args!("{}\n", format_args!($($t)*)))
    };
}

/// Writes `bytes` to the file `path` whole or not at all (`splat2tiles_io::write_whole`),
/// refusing a destination inside the folder `input` (the data the command read), through a
/// symbolic link too.
pub fn write_file(
    path: &std::path::Path,
    bytes: &[u8],
    input: &std::path::Path,
) -> std::io::Result<()> {
    let target = splat2tiles_io::destination(path)?;
    if let Ok(input) = std::fs::canonicalize(input)
        && target.starts_with(&input)
    {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            format!(
                "inside the input {} (it would change what was read)",
                input.display()
            ),
        ));
    }
    splat2tiles_io::write_at(&target, bytes)
}
