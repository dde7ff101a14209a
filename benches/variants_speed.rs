//! What `--variants all` (encode + utilities) costs against the Best-only conversion of the
//! same input: generated SH3 trainer PLYs of 1M and 5M splats, release CLI binary, one process
//! per conversion. Inputs and outputs live under `target/tmp-big/` and are deleted afterwards.
//!
//! Run: `cargo bench --bench variants_speed` (`VARIANTS_SPEED_SIZES=1000000` to pick sizes).

use splat2tiles::splat::{Splat, Splats, sh_rest_count};
use std::path::{Path, PathBuf};
use std::process::Command;

fn release_binary() -> PathBuf {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let st = Command::new("cargo")
        .args(["build", "--release", "--bin", "splat2tiles"])
        .current_dir(root)
        .status()
        .expect("cargo build");
    assert!(st.success());
    root.join("target/release/splat2tiles")
}

/// Writes `n` random SH3 splats as a trainer PLY (the generator of `benches/convert.rs`: the
/// same seed and distributions), in chunks of 1M so memory stays bounded.
fn generate_ply(path: &Path, n: usize) {
    let mut x = 0x2545_F491_4F6C_DD1Du64;
    let mut f = move || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        (x >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut all = Splats::with_capacity(3, n);
    for _ in 0..n {
        let s = Splat {
            position: [f() * 100.0, f() * 30.0, f() * 100.0],
            scale: [0.01 + f() as f32 * 0.1; 3],
            rotation: splat2tiles::splat::normalize_quat([
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
    splat2tiles::io::write_ply(&all, std::io::BufWriter::new(file)).unwrap();
}

/// Converts `input` with `extra` arguments; returns (seconds, content tiles, output bytes).
fn convert(bin: &Path, input: &Path, out: &Path, extra: &[&str]) -> (f64, u64, f64) {
    let o = Command::new(bin)
        .arg("convert")
        .arg(input)
        .arg("-o")
        .arg(out)
        .args(["--json", "-q"])
        .args(extra)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    std::fs::remove_dir_all(out).unwrap();
    (
        v["seconds"].as_f64().unwrap(),
        v["contentTiles"].as_u64().unwrap_or(0),
        v["bytes"].as_f64().unwrap_or(f64::NAN),
    )
}

fn main() {
    let bin = release_binary();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let dir = root.join("target/tmp-big/variants_speed");
    std::fs::create_dir_all(&dir).unwrap();
    let sizes: Vec<usize> = std::env::var("VARIANTS_SPEED_SIZES")
        .unwrap_or_else(|_| "1000000,5000000".into())
        .split(',')
        .map(|s| s.trim().parse().unwrap())
        .collect();
    println!(
        "| splats | content tiles | Best only s | all variants s | ratio | all, no utility s | output MB (all) |"
    );
    println!("|---:|---:|---:|---:|---:|---:|---:|");
    for n in sizes {
        let input = dir.join(format!("generated_{n}_sh3.ply"));
        generate_ply(&input, n);
        let out = dir.join("out");
        let (best, tiles, _) = convert(&bin, &input, &out, &[]);
        let (all, _, bytes) = convert(&bin, &input, &out, &["--variants", "all"]);
        let (no_u, _, _) = convert(&bin, &input, &out, &["--variants", "all", "--no-utility"]);
        std::fs::remove_file(&input).unwrap();
        println!(
            "| {n} | {tiles} | {best:.2} | {all:.2} | {:.2} | {no_u:.2} | {:.0} |",
            all / best,
            bytes / 1e6
        );
    }
    let _ = std::fs::remove_dir(&dir);
}
