//! Conversion throughput and peak memory, end to end through the CLI binary (one process per
//! input, so peak RSS is that conversion's alone): the three shared scenes and a generated
//! 1M-splat SH3 trainer PLY (248 B/splat, about the size of a small real capture).
//!
//! Run: `cargo bench --bench convert` (builds the release binary first).

mod common;
use common::release_binary;
use splat2tiles::splat::{Splat, Splats, sh_rest_count};
use std::path::Path;
use std::process::Command;

/// Writes `n` random SH3 splats as a trainer PLY, in chunks so memory stays small.
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

fn main() {
    let bin = release_binary();
    let tmp = tempfile::tempdir().unwrap();
    let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/scenes");
    let big = tmp.path().join("generated_1m_sh3.ply");
    generate_ply(&big, 1_000_000);
    let inputs = [
        scenes.join("plant.splat"),
        scenes.join("donut_fused_sh0.ply"),
        scenes.join("biker.spz"),
        big,
    ];
    println!(
        "| input | splats | input MB | output MB | tiles | seconds | splats/s | peak RSS MiB |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    for input in inputs {
        let out = tmp.path().join("out");
        let o = Command::new(&bin)
            .arg("convert")
            .arg(&input)
            .arg("-o")
            .arg(&out)
            .args(["--json", "-q"])
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        let n = v["splatsOut"].as_f64().unwrap();
        let secs = v["seconds"].as_f64().unwrap();
        let in_mb = std::fs::metadata(&input).unwrap().len() as f64 / 1e6;
        println!(
            "| {} | {} | {:.1} | {:.1} | {} | {:.2} | {:.2} M | {:.0} |",
            input.file_name().unwrap().to_string_lossy(),
            n,
            in_mb,
            v["bytes"].as_f64().unwrap() / 1e6,
            v["contentTiles"],
            secs,
            n / secs / 1e6,
            v["peakRssMiB"].as_f64().unwrap_or(f64::NAN)
        );
    }
}
