//! The Ray driver (`tools/splat2tiles_ray.py`) on a local Ray cluster: a generated city in 4
//! parts, one part task killed (SIGKILL, with its splat2tiles process) and retried by Ray, gives
//! the single-machine bytes, validates, and every part stays under its `--memory-limit`. And on
//! a cluster of three Ray nodes on this machine (a head and two workers started with `ray
//! start`, each its own raylet, ports and temp folder), the input routed and the parts pinned
//! to the workers by custom resources, one killed and retried on its worker, the same bytes.
//!
//! Ray comes from PyPI into `target/ray-venv` (`.ci/run` installs it; this test installs it
//! when missing). Skipped, saying why, when `python3` or its `venv` module is absent.

mod common;

use common::city::write_city_splat;
use common::*;
use std::net::TcpListener;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// The tests run one at a time (each starts Ray processes; the machine may have 2 cores).
static RAY_TESTS: Mutex<()> = Mutex::new(());

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

/// The options of every conversion of these tests.
const EXTRA: [&str; 3] = ["--max-splats", "4096", "--no-utility"];

/// A generated city of `n` splats (`seed`) in `dir` and its single-machine conversion with
/// [`EXTRA`]: the input's and the output's paths.
fn city_and_single_run(dir: &Path, n: usize, seed: u64) -> (PathBuf, PathBuf) {
    let input = dir.join("city.splat");
    write_city_splat(&input, n, seed);
    let base = dir.join("base");
    let o = Command::new(bin())
        .arg("convert")
        .arg(&input)
        .arg("-o")
        .arg(&base)
        .args(EXTRA)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    (input, base)
}

#[test]
fn ray_driver_converts_in_four_parts_with_a_killed_task() {
    let _one = RAY_TESTS.lock().unwrap_or_else(|e| e.into_inner());
    let py = match ray_python() {
        Ok(py) => py,
        Err(why) => {
            eprintln!("SKIPPED ray_driver: {why}");
            return;
        }
    };
    let tmp = tempfile::tempdir().unwrap();
    let (input, base) = city_and_single_run(tmp.path(), 300_000, 21);

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
        .args(EXTRA)
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

/// A free TCP port on this machine (free when asked; Ray binds it soon after).
fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// Ray nodes started on this machine under one temporary folder; dropping it kills every
/// process whose command line names that folder (the raylets, the GCS, their workers), failed
/// test or not, and no other Ray process (`ray stop` would stop every Ray on the machine).
struct Cluster {
    ray: PathBuf,
    root: tempfile::TempDir,
    address: String,
    /// The cluster's authentication token (every node and the driver get it).
    token: String,
}

impl Cluster {
    /// A head node (1 CPU) listening on a free port.
    fn head(ray: PathBuf) -> Cluster {
        // Short: Ray's socket paths under it must stay within the 107 bytes of a Unix socket.
        let root = tempfile::Builder::new()
            .prefix("s2t-ray")
            .tempdir_in("/tmp")
            .unwrap();
        let port = free_port();
        // Token authentication on, with a token of its own: `ray start` turns it on whenever
        // `~/.ray/auth_token` exists (a local `ray.init()` writes one), and a node or driver
        // without the head's token is refused.
        let seed = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .unwrap()
            .as_nanos();
        let token = format!("{:032x}", seed ^ ((std::process::id() as u128) << 64));
        let c = Cluster {
            ray,
            root,
            address: format!("127.0.0.1:{port}"),
            token,
        };
        c.start("head", &["--head", &format!("--port={port}")], "{}");
        c
    }

    /// Starts one node (`ray start`) with its own temp folder and ports.
    fn start(&self, name: &str, args: &[&str], resources: &str) {
        let temp = self.root.path().join(name);
        let mut a: Vec<String> = args.iter().map(|s| s.to_string()).collect();
        if args.contains(&"--head") {
            a.push("--include-dashboard=false".into());
        } else {
            a.push(format!("--address={}", self.address));
        }
        a.push(format!("--temp-dir={}", temp.display()));
        a.push("--num-cpus=1".into());
        a.push(format!("--resources={resources}"));
        a.push("--disable-usage-stats".into());
        for flag in [
            "--node-manager-port",
            "--object-manager-port",
            "--dashboard-agent-listen-port",
            "--dashboard-agent-grpc-port",
            "--runtime-env-agent-port",
            "--metrics-export-port",
        ] {
            a.push(format!("{flag}={}", free_port()));
        }
        let o = self
            .env(Command::new(&self.ray).arg("start").args(&a))
            .output()
            .unwrap();
        assert!(
            o.status.success(),
            "ray start {name}: {}{}",
            String::from_utf8_lossy(&o.stdout),
            String::from_utf8_lossy(&o.stderr)
        );
    }

    /// `cmd` with the cluster's environment: its token, no memory monitor.
    fn env<'a>(&self, cmd: &'a mut Command) -> &'a mut Command {
        cmd.env("RAY_AUTH_MODE", "token")
            .env("RAY_AUTH_TOKEN", &self.token)
            .env("RAY_memory_monitor_refresh_ms", "0")
    }

    /// Processes whose command line names the cluster's folder or that hold a file under it
    /// open (Ray's agents rename themselves, `ray::DashboardAgent`, but keep their logs open);
    /// this test's own process excepted.
    fn processes(&self) -> Vec<i32> {
        let root = self.root.path();
        let root_s = root.to_string_lossy().into_owned();
        let mut pids = Vec::new();
        for e in std::fs::read_dir("/proc").unwrap().flatten() {
            let Ok(pid) = e.file_name().to_string_lossy().parse::<i32>() else {
                continue;
            };
            if pid == std::process::id() as i32 {
                continue;
            }
            let cmd = std::fs::read(e.path().join("cmdline")).unwrap_or_default();
            let named = String::from_utf8_lossy(&cmd).contains(&root_s);
            let holds = || {
                std::fs::read_dir(e.path().join("fd"))
                    .into_iter()
                    .flatten()
                    .flatten()
                    .any(|fd| std::fs::read_link(fd.path()).is_ok_and(|t| t.starts_with(root)))
            };
            if named || holds() {
                pids.push(pid);
            }
        }
        pids
    }

    /// Kills the cluster's processes until none is left (a dying raylet's workers may outlive
    /// it briefly) or 30 s have passed; returns how many are left.
    fn stop(&self) -> usize {
        let deadline = Instant::now() + Duration::from_secs(30);
        loop {
            let pids = self.processes();
            if pids.is_empty() || Instant::now() > deadline {
                return pids.len();
            }
            for pid in pids {
                let _ = Command::new("kill").args(["-9", &pid.to_string()]).output();
            }
            std::thread::sleep(Duration::from_millis(200));
        }
    }
}

impl Drop for Cluster {
    fn drop(&mut self) {
        self.stop();
    }
}

#[test]
fn ray_cluster_of_three_nodes_converts_with_pinned_parts_and_a_killed_one() {
    let _one = RAY_TESTS.lock().unwrap_or_else(|e| e.into_inner());
    let py = match ray_python() {
        Ok(py) => py,
        Err(why) => {
            eprintln!("SKIPPED ray_cluster: {why}");
            return;
        }
    };
    let start = Instant::now();
    let tmp = tempfile::tempdir().unwrap();
    let (input, base) = city_and_single_run(tmp.path(), 200_000, 23);

    let cluster = Cluster::head(py.with_file_name("ray"));
    cluster.start("worker_a", &[], r#"{"worker_a": 1}"#);
    cluster.start("worker_b", &[], r#"{"worker_b": 1}"#);
    let out = tmp.path().join("out");
    let work = tmp.path().join("work");
    let mut driver = Command::new(&py);
    let o = cluster
        .env(&mut driver)
        .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("tools/splat2tiles_ray.py"))
        .arg(&input)
        .arg("-o")
        .arg(&out)
        .args(["--parts", "4", "--work"])
        .arg(&work)
        .arg("--binary")
        .arg(bin())
        .args([
            "--part-resources",
            "worker_a,worker_b",
            "--route-chunks",
            "2",
        ])
        .args(["--memory-limit", "256MiB", "--retries", "2", "--json", "--"])
        .args(EXTRA)
        // Part 1's build task (on worker_b) kills its splat2tiles process and itself once.
        .env("SPLAT2TILES_RAY_KILL", "build:1")
        .env("RAY_ADDRESS", &cluster.address)
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
    let marker = std::fs::read_to_string(work.join(".killed-build-1")).expect("the kill hook ran");
    assert_eq!(marker, "running", "part 1 was killed while it ran");
    let build = r["build"].as_array().unwrap();
    let route = r["route"].as_array().unwrap();
    assert_eq!((build.len(), route.len()), (4, 2));
    assert_eq!(build[1]["retried"], true, "part 1 ran again after the kill");
    // Parts 0 and 2 (and routing chunk 0) ran on worker_a's node, 1 and 3 (chunk 1) on
    // worker_b's: two nodes.
    let node = |v: &serde_json::Value| v["node"].as_str().expect("a node id").to_string();
    let a = node(&build[0]);
    let b = node(&build[1]);
    assert_ne!(a, b);
    assert_eq!(node(&build[2]), a);
    assert_eq!(node(&build[3]), b);
    assert_eq!(node(&route[0]), a);
    assert_eq!(node(&route[1]), b);
    for s in r["samples"].as_array().unwrap().iter().chain(build) {
        assert_eq!(
            s["inputReadBytes"], 0,
            "parts read their routed files only: {s}"
        );
    }
    assert_same_files(&base, &out);
    assert!(
        !cluster.processes().is_empty(),
        "the cluster's processes are found"
    );
    assert_eq!(cluster.stop(), 0, "Ray processes left");
    eprintln!(
        "ray cluster test: {:.1} s (driver steps {})",
        start.elapsed().as_secs_f64(),
        r["seconds"]
    );
}
