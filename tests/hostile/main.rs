//! Hostile situations and inputs, generated at test time (no committed blobs): output folders
//! that are not ours, concurrent and interrupted runs, decompression bombs, sparse and endless
//! files, overflowing values, slow HTTP clients, and the README's first command in a plain clone.

#[path = "../common/mod.rs"]
mod common;

#[cfg(unix)]
mod build_script;
mod busy_port;
mod fuzz_seeds;
mod inputs;
mod lapis;
mod loader;
mod memory;
mod output;
mod plain_clone;
mod render_output;
mod serve_soak;
mod sharded;
mod signal;
mod spill;
mod stdout;

use std::path::Path;
use std::process::{Command, Output};

/// Runs `splat2tiles convert ARGS...`.
pub fn convert(args: &[&str]) -> Output {
    Command::new(common::bin())
        .arg("convert")
        .args(args)
        .args(["--quiet", "--no-utility"])
        .output()
        .expect("run splat2tiles convert")
}

/// Converts a small generated scene (`DIR/in.splat`, 2000 splats) into `DIR/ts`; returns `DIR/ts`.
pub fn small_tileset(dir: &Path) -> std::path::PathBuf {
    let input = dir.join("in.splat");
    inputs::write_splat(&input, 2000);
    let out = dir.join("ts");
    let o = convert(&[input.to_str().unwrap(), "-o", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    out
}

/// Asserts that `splat2tiles validate TILESET` exits 0 (its report is the failure message).
pub fn assert_valid(tileset: &Path) {
    let v = Command::new(common::bin())
        .arg("validate")
        .arg(tileset)
        .output()
        .expect("run splat2tiles validate");
    assert_eq!(
        v.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&v.stdout)
    );
}

/// Stderr of a finished command as text.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Hidden entries (staging, lock, moved-aside folders) in `dir`.
pub fn hidden(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with('.'))
        .collect();
    v.sort();
    v
}

/// Whether `chattr +i` works here (root ignores permission bits, so tests that need a file
/// operation to fail use the immutable attribute instead).
pub fn set_immutable(path: &Path, on: bool) -> bool {
    Command::new("chattr")
        .arg(if on { "+i" } else { "-i" })
        .arg(path)
        .output()
        .is_ok_and(|o| o.status.success())
}
