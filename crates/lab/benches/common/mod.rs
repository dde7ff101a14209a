//! Helpers shared by the bench binaries that drive the CLI (one process per run, so peak RSS is
//! that run's alone), and the generated inputs they share.
#![allow(dead_code)] // each bench binary uses only some of them

use std::path::{Path, PathBuf};
use std::process::Command;

use splat2tiles_core::splat::{Splat, Splats, sh_rest_count};

/// Builds the release `splat2tiles` binary and returns its path (honours `CARGO_TARGET_DIR`).
pub fn release_binary() -> PathBuf {
    let root = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."));
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

/// Writes `n` random SH3 splats (fixed seed) as a trainer PLY; all `n` are held in memory
/// first (about 250 B each).
pub fn generate_sh3_ply(path: &Path, n: usize) {
    let mut f = uniform(0x2545_F491_4F6C_DD1D);
    let mut all = Splats::with_capacity(3, n);
    for _ in 0..n {
        let s = Splat {
            position: [f() * 100.0, f() * 30.0, f() * 100.0],
            scale: [0.01 + f() as f32 * 0.1; 3],
            rotation: splat2tiles_core::splat::normalize_quat([
                f() as f32 - 0.5,
                f() as f32 - 0.5,
                f() as f32 - 0.5,
                f() as f32 - 0.5,
            ]),
            opacity: f() as f32,
            sh0: [f() as f32 - 0.5; 3],
        };
        let rest: Vec<[f32; 3]> = (0..sh_rest_count(3))
            .map(|_| [(f() - 0.5) as f32 * 0.2; 3])
            .collect();
        all.push(s, &rest);
    }
    let file = std::fs::File::create(path).unwrap();
    splat2tiles_io::write_ply(&all, std::io::BufWriter::new(file)).unwrap();
}

/// The SH3 scene of the peers bench and its probes: every 4th splat of [`plant_sh3`] (28,412
/// splats; splat-transform's SOG palette would not finish on all of them).
pub fn peers_sh3(plant: &Splats) -> Splats {
    let sh3 = plant_sh3(plant);
    let quarter: Vec<usize> = (0..sh3.len()).step_by(4).collect();
    sh3.select(&quarter)
}

/// The plant with small random SH1-3 coefficients (|c| <= 0.08), the generated SH3
/// scene of the variant benches (xorshift, seed 99).
pub fn plant_sh3(plant: &Splats) -> Splats {
    let mut s = plant.clone();
    let mut f = uniform(99);
    s.sh_degree = 3;
    s.sh_rest = (0..s.len() * 15)
        .map(|_| [0, 1, 2].map(|_| (f() * 0.16 - 0.08) as f32))
        .collect();
    s
}

/// Uniform numbers in [0, 1) from a xorshift64 generator started at `seed` (non-zero).
pub fn uniform(seed: u64) -> impl FnMut() -> f64 {
    let mut x = seed;
    move || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        (x >> 11) as f64 / (1u64 << 53) as f64
    }
}
