//! Conversion throughput and peak memory, end to end through the CLI binary (one process per
//! input, so peak RSS is that conversion's alone): the three shared scenes and a generated
//! 1M-splat SH3 trainer PLY (248 B/splat, about the size of a small real capture).
//!
//! Run: `cargo bench --bench convert` (builds the release binary first).

mod common;
use common::{generate_sh3_ply, release_binary};
use std::path::Path;
use std::process::Command;

fn main() {
    let bin = release_binary();
    let tmp = tempfile::tempdir().unwrap();
    let scenes = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../..")).join("data/scenes");
    let big = tmp.path().join("generated_1m_sh3.ply");
    generate_sh3_ply(&big, 1_000_000);
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
