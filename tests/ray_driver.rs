//! The Ray driver (`tools/splat2tiles_ray.py`) on a local Ray cluster: a generated city in 4
//! parts, one part task killed (SIGKILL, with its splat2tiles process) and retried by Ray, gives
//! the single-machine bytes, validates, and every part stays under its `--memory-limit`.
//!
//! Ray comes from PyPI into `target/ray-venv` (`.ci/run` installs it; this test installs it
//! when missing). Skipped, saying why, when `python3` or its `venv` module is absent.

mod common;

use common::city::write_city_splat;
use common::*;
use std::path::{Path, PathBuf};
use std::process::Command;

/// The Ray version the driver is tested with (`.ci/run` installs the same).
const RAY: &str = "ray==2.60.0";

/// The virtual environment's python with Ray importable; `Err` says why the test skips (no
/// python3, or one without `venv`, e.g. Debian without python3-venv).
fn ray_python() -> Result<PathBuf, String> {
    let has_python = Command::new("python3")
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success());
    if !has_python {
        return Err("python3 is not installed (the Ray driver needs it)".into());
    }
    let venv = Path::new(env!("CARGO_MANIFEST_DIR")).join("target/ray-venv");
    let py = venv.join("bin/python");
    let has_ray = |py: &Path| {
        Command::new(py)
            .args(["-c", "import ray"])
            .output()
            .is_ok_and(|o| o.status.success())
    };
    if !has_ray(&py) {
        let o = Command::new("python3")
            .args(["-m", "venv"])
            .arg(&venv)
            .output()
            .unwrap();
        if !o.status.success() {
            let _ = std::fs::remove_dir_all(&venv);
            return Err(format!(
                "`python3 -m venv` failed (python3-venv missing?): {}",
                String::from_utf8_lossy(&o.stderr).trim()
            ));
        }
        let o = Command::new(&py)
            .args(["-m", "pip", "install", "-q", RAY])
            .output()
            .unwrap();
        assert!(
            o.status.success(),
            "pip install {RAY}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        assert!(has_ray(&py), "ray not importable after pip install {RAY}");
    }
    Ok(py)
}

#[test]
fn ray_driver_converts_in_four_parts_with_a_killed_task() {
    let py = match ray_python() {
        Ok(py) => py,
        Err(why) => {
            eprintln!("SKIPPED ray_driver: {why}");
            return;
        }
    };
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("city.splat");
    write_city_splat(&input, 300_000, 21);
    let extra = ["--max-splats", "4096", "--no-utility"];
    let base = tmp.path().join("base");
    let o = Command::new(bin())
        .arg("convert")
        .arg(&input)
        .arg("-o")
        .arg(&base)
        .args(extra)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));

    let out = tmp.path().join("out");
    let work = tmp.path().join("work");
    let limit_mib = 64.0;
    let o = Command::new(&py)
        .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("tools/splat2tiles_ray.py"))
        .arg(&input)
        .arg("-o")
        .arg(&out)
        .args(["--parts", "4", "--work"])
        .arg(&work)
        .arg("--binary")
        .arg(bin())
        .args([
            "--memory-limit",
            "64MiB",
            "--num-cpus",
            "2",
            "--retries",
            "2",
            "--json",
            "--",
        ])
        .args(extra)
        // Part 1's build task kills its splat2tiles process and itself on the first attempt.
        .env("SPLAT2TILES_RAY_KILL", "build:1")
        .env("RAY_memory_monitor_refresh_ms", "0")
        .env_remove("RAY_ADDRESS")
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "driver failed: {stdout}{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let r: serde_json::Value =
        serde_json::from_str(stdout.lines().last().expect("a JSON report")).unwrap();
    assert!(work.join(".killed-build-1").exists(), "the kill hook ran");
    let build = r["build"].as_array().unwrap();
    assert_eq!(build.len(), 4);
    for step in build.iter().chain(r["samples"].as_array().unwrap()) {
        let rss = step["peakRssMiB"].as_f64().unwrap();
        assert!(rss < limit_mib, "a part over its --memory-limit: {step}");
    }
    let splats: u64 = build.iter().map(|b| b["splats"].as_u64().unwrap()).sum();
    assert_eq!(splats, 300_000);

    assert_same_files(&base, &out);
    assert_valid_with_extents(&out);
    // No staging folder of the killed attempt is left beside the part.
    let left: Vec<String> = std::fs::read_dir(&work)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains(".s2t-"))
        .collect();
    assert!(left.is_empty(), "{left:?}");
}
