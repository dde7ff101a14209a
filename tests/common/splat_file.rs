//! The shared scenes for the render tests and benches, read through the production reader
//! (`splat2tiles_io`); paths are relative to the crate so CI's checkout finds them.

use splat2tiles_core::splat::Splats;
use std::path::PathBuf;

/// File name of the shared plant scene (113,648 splats).
pub const PLANT: &str = "plant.splat";

/// Path of a shared scene (`data/scenes/NAME` beside the crate).
pub fn shared_scene(name: &str) -> PathBuf {
    {
        let mut p = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
        while !p.join("samples/plant.splat").is_file() && p.pop() {}
        p
    }
    .join("data/scenes")
    .join(name)
}

/// Reads a shared scene by file name, panicking with the reader's message on failure.
pub fn read_splat(name: &str) -> Splats {
    splat2tiles_io::read_path(&shared_scene(name))
        .unwrap_or_else(|e| panic!("{e}"))
        .splats
}
