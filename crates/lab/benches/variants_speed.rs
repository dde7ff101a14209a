//! What `--variants all` (encode + utilities) costs against the Best-only conversion of the
//! same input: generated SH3 trainer PLYs of 1M and 5M splats, release CLI binary, one process
//! per conversion. Inputs and outputs live under `target/tmp-big/` and are deleted afterwards.
//!
//! Run: `cargo bench --bench variants_speed` (`VARIANTS_SPEED_SIZES=1000000` to pick sizes,
//! `VARIANTS_SPEED_RUNS=3` for the runs per size, `VARIANTS_SPEED_KEEP=1` to keep the inputs).

mod common;
use common::{generate_sh3_ply, release_binary};
use std::path::Path;
use std::process::Command;

/// Converts `input` with `extra` arguments; returns (seconds, content tiles, output bytes, CPU
/// seconds: user + system, from `/usr/bin/time`; NaN without it).
fn convert(bin: &Path, input: &Path, out: &Path, extra: &[&str]) -> (f64, u64, f64, f64) {
    let time = Path::new("/usr/bin/time");
    let cpu_file = out.with_extension("cpu");
    let mut cmd = if time.exists() {
        let mut c = Command::new(time);
        c.args(["-f", "%U %S", "-o"]).arg(&cpu_file).arg(bin);
        c
    } else {
        Command::new(bin)
    };
    let o = cmd
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
    let cpu = std::fs::read_to_string(&cpu_file)
        .ok()
        .map(|t| {
            t.split_whitespace()
                .filter_map(|v| v.parse::<f64>().ok())
                .sum()
        })
        .unwrap_or(f64::NAN);
    let _ = std::fs::remove_file(&cpu_file);
    (
        v["seconds"].as_f64().unwrap(),
        v["contentTiles"].as_u64().unwrap_or(0),
        v["bytes"].as_f64().unwrap_or(f64::NAN),
        cpu,
    )
}

/// The 1-minute load average (`/proc/loadavg`), or NaN where it cannot be read.
fn load_average() -> f64 {
    std::fs::read_to_string("/proc/loadavg")
        .ok()
        .and_then(|s| s.split_whitespace().next().and_then(|v| v.parse().ok()))
        .unwrap_or(f64::NAN)
}

fn main() {
    let bin = release_binary();
    let root = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."));
    let dir = root.join("target/tmp-big/variants_speed");
    std::fs::create_dir_all(&dir).unwrap();
    let sizes: Vec<usize> = std::env::var("VARIANTS_SPEED_SIZES")
        .unwrap_or_else(|_| "1000000,5000000".into())
        .split(',')
        .map(|s| s.trim().parse().unwrap())
        .collect();
    let runs: usize = std::env::var("VARIANTS_SPEED_RUNS")
        .ok()
        .and_then(|s| s.trim().parse().ok())
        .unwrap_or(3)
        .max(1);
    let keep = std::env::var_os("VARIANTS_SPEED_KEEP").is_some();
    println!(
        "| run | splats | content tiles | Best only s | all variants s | ratio | all, no utility s | output MB (all) | CPU s Best / all (ratio) | load average (1 min) before / after |"
    );
    println!("|---:|---:|---:|---:|---:|---:|---:|---:|---|---|");
    for n in sizes {
        let input = dir.join(format!("generated_{n}_sh3.ply"));
        if !input.exists() {
            generate_sh3_ply(&input, n);
        }
        let out = dir.join("out");
        let (mut min_best, mut min_all) = (f64::INFINITY, f64::INFINITY);
        for run in 1..=runs {
            let before = load_average();
            let (best, tiles, _, cpu_best) = convert(&bin, &input, &out, &[]);
            let (all, _, bytes, cpu_all) = convert(&bin, &input, &out, &["--variants", "all"]);
            let (no_u, _, _, _) =
                convert(&bin, &input, &out, &["--variants", "all", "--no-utility"]);
            println!(
                "| {run} | {n} | {tiles} | {best:.2} | {all:.2} | {:.2} | {no_u:.2} | {:.0} | {cpu_best:.2} / {cpu_all:.2} ({:.2}) | {before:.2} / {:.2} |",
                all / best,
                bytes / 1e6,
                cpu_all / cpu_best,
                load_average()
            );
            min_best = min_best.min(best);
            min_all = min_all.min(all);
        }
        // The fastest run of each is the one least slowed by whatever else the machine ran.
        println!(
            "| min | {n} | | {min_best:.2} | {min_all:.2} | {:.2} | | | | fastest of {runs} runs each |",
            min_all / min_best
        );
        if !keep {
            std::fs::remove_file(&input).unwrap();
        }
    }
    if !keep {
        let _ = std::fs::remove_dir(&dir);
    }
}
