//! Helpers shared by the bench binaries that drive the CLI (one process per run, so peak RSS is
//! that run's alone).

use std::path::{Path, PathBuf};
use std::process::Command;

/// Builds the release `splat2tiles` binary and returns its path (honours `CARGO_TARGET_DIR`).
pub fn release_binary() -> PathBuf {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let st = Command::new("cargo")
        .args(["build", "--release", "--bin", "splat2tiles"])
        .current_dir(root)
        .status()
        .expect("cargo build");
    assert!(st.success());
    let target = std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| root.join("target"));
    target.join("release/splat2tiles")
}
