//! The browser holding a city (not a test): the web viewer walks a generated city
//! along a real head trace in headless Chromium, and a full-download peer is given the same city.
//!
//! Run: `cargo bench --bench city_walk -- CITY.splat [CITY.splat ...]` (SH0 cities written by
//! `cargo bench --bench city` with `CITY_KEEP=1`: `target/city-bench/city-N-sh0.splat`), or
//! `cargo bench --bench city_walk -- plot` to redraw `docs/city-walk.svg` from the samples in
//! `target/`. Per city: converts it with the release binary (`--memory-limit 2GiB`) into
//! `CITY_WALK_DIR` (default `target/tmp-big/city-walk`) unless already there, serves it with
//! `splat2tiles view`, runs `tests/js/city_walk.mjs` (trace `CITY_WALK_TRACE`, default EyeNavGS
//! `data/navigation-traces/nyc/user101_nyc.csv`, placed as a street-level walk at the city's
//! centre: horizontal x`CITY_WALK_SCALE` (20), eye 1.7 m above the ground z = 0; `budgetMB`
//! `CITY_WALK_BUDGET_MB` (256); canvas `CITY_WALK_SIZE` (640x360)), then for each format of
//! `CITY_WALK_PEER_FORMATS` (default `compressed.ply,ply`; empty: no peer) converts the city to
//! that one file with `@playcanvas/splat-transform` unless already there and runs
//! `tests/js/city_peer.mjs` (PlayCanvas engine; first frame within `CITY_WALK_PEER_TIMEOUT` s,
//! default 600). Writes `target/city-walk-NAME-BUDGETMB.{csv,json,png}`,
//! `target/city-peer-NAME-FORMAT.{csv,json,png}`, `target/city-walk.md` (the table) and
//! `docs/city-walk.svg`; deletes the tileset and the peer files unless `CITY_WALK_KEEP=1`.

mod common;
use common::release_binary;
use serde_json::Value;
use splat2tiles_lab::sim::svg::{Series, line_chart, panels};
use std::fmt::Write as _;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::Instant;

fn root() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
}

fn env_or(key: &str, default: &str) -> String {
    std::env::var(key).unwrap_or_else(|_| default.to_string())
}

/// `splat2tiles view DIR` on a free port, killed on drop.
struct Viewing {
    child: Child,
    base: String,
}

impl Drop for Viewing {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn view(bin: &Path, dir: &Path, log: &Path) -> Viewing {
    let mut child = Command::new(bin)
        .args(["view", dir.to_str().unwrap(), "--port", "0", "--no-open"])
        .arg("--web-dir")
        .arg(root().join("viewer/web"))
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(std::fs::File::create(log).unwrap())
        .spawn()
        .expect("start splat2tiles view");
    let stdout = child.stdout.take().expect("piped stdout");
    let mut viewing = Viewing {
        child,
        base: String::new(),
    };
    let mut out = BufReader::new(stdout);
    loop {
        let mut line = String::new();
        if out.read_line(&mut line).unwrap_or(0) == 0 {
            panic!("splat2tiles view exited; see {}", log.display());
        }
        if let Some(rest) = line.split("http://127.0.0.1:").nth(1) {
            let port: String = rest.chars().take_while(char::is_ascii_digit).collect();
            viewing.base = format!("http://127.0.0.1:{port}/");
            return viewing;
        }
    }
}

/// Runs `node SCRIPT ARGS`, returns its JSON output (also written to `json`).
fn node(script: &str, args: &[String], json: &Path) -> Value {
    let o = Command::new("node")
        .arg(root().join("tests/js").join(script))
        .args(args)
        .output()
        .expect("node");
    let text = String::from_utf8_lossy(&o.stdout);
    std::fs::write(json, text.as_bytes()).unwrap();
    serde_json::from_str(&text).unwrap_or_else(|e| {
        panic!(
            "{script} printed no JSON ({e}):\n{text}\n{}",
            String::from_utf8_lossy(&o.stderr)
        )
    })
}

fn mib(v: &Value) -> String {
    match v.as_f64() {
        Some(b) => format!("{:.0} MiB", b / 1048576.0),
        None => "-".into(),
    }
}

/// Walks one city and runs the peer on it; returns the table rows.
#[expect(
    clippy::too_many_lines,
    reason = "a measurement run by hand: one straight script that prints its table"
)]
fn run_city(bin: &Path, input: &Path) -> String {
    let name = input
        .file_name()
        .unwrap()
        .to_string_lossy()
        .trim_end_matches(".splat")
        .to_string();
    let work = root().join(env_or("CITY_WALK_DIR", "target/tmp-big/city-walk"));
    std::fs::create_dir_all(&work).unwrap();
    let target = root().join("target");
    let trace = root().join(env_or(
        "CITY_WALK_TRACE",
        "data/navigation-traces/nyc/user101_nyc.csv",
    ));
    let budget = env_or("CITY_WALK_BUDGET_MB", "256");
    let scale = env_or("CITY_WALK_SCALE", "20");
    let keep = std::env::var_os("CITY_WALK_KEEP").is_some();
    let (width, height) = env_or("CITY_WALK_SIZE", "640x360")
        .split_once('x')
        .map(|(w, h)| (w.to_string(), h.to_string()))
        .expect("CITY_WALK_SIZE: WIDTHxHEIGHT");
    let common = |csv: &Path| -> Vec<String> {
        vec![
            "--width".into(),
            width.clone(),
            "--height".into(),
            height.clone(),
            "--trace".into(),
            trace.to_string_lossy().into(),
            "--csv".into(),
            csv.to_string_lossy().into(),
            "--scale".into(),
            scale.clone(),
            // benches/city.rs puts every block's ground at y = 0 of the .splat: z = 0 here.
            "--ground".into(),
            "0".into(),
        ]
    };

    // 1. The tiled city.
    let tiles = work.join(&name);
    let mut convert_s = None;
    if !tiles.join("tileset.json").is_file() {
        let t = Instant::now();
        let st = Command::new(bin)
            .args(["convert", "--quiet", "--memory-limit", "2GiB", "-o"])
            .arg(&tiles)
            .arg(input)
            .status()
            .expect("convert");
        assert!(st.success(), "convert {} failed", input.display());
        convert_s = Some(t.elapsed().as_secs_f64());
    }
    // The peers place the trace from the root box: keep tileset.json after the tiles go.
    let tiles_json = target.join(format!("city-walk-{name}.tileset.json"));
    std::fs::copy(tiles.join("tileset.json"), &tiles_json).unwrap();
    // 2. The walk.
    let walk_name = format!("{name}-{budget}MB");
    let walk_csv = target.join(format!("city-walk-{walk_name}.csv"));
    let walk = {
        let viewing = view(
            bin,
            &tiles,
            &target.join(format!("city-walk-{walk_name}.view.log")),
        );
        let mut args = vec![viewing.base.clone()];
        args.extend(common(&walk_csv));
        args.extend(["--budget-mb".into(), budget.clone(), "--shot".into()]);
        args.push(
            target
                .join(format!("city-walk-{walk_name}.png"))
                .to_string_lossy()
                .into(),
        );
        node(
            "city_walk.mjs",
            &args,
            &target.join(format!("city-walk-{walk_name}.json")),
        )
    };
    let tiles_bytes = dir_bytes(&tiles);
    let m = &walk["max"];
    let mut rows = String::new();
    let _ = writeln!(
        rows,
        "| {name} | splat2tiles web viewer, budgetMB {budget} ({:.0} MiB tileset{}) | {} | {:.1} s walk, {:.0} m, {} frames, longest stall {} samples{} | {} | {} | {} | {} | {} |",
        tiles_bytes as f64 / 1048576.0,
        convert_s.map_or(String::new(), |s| format!(", converted in {s:.0} s")),
        if walk["ok"] == true {
            "walked"
        } else {
            "FAILED"
        },
        walk["traceSeconds"].as_f64().unwrap_or(0.0),
        walk["pathMetres"].as_f64().unwrap_or(0.0),
        walk["framesDuringWalk"],
        walk["longestStallSamples"],
        match walk["cacheWithinBudget"].as_bool() {
            Some(true) => ", cache within budget",
            _ => ", cache OVER budget",
        },
        m["residentSplats"],
        mib(&m["cacheBytes"]),
        mib(&m["gpuBytes"]),
        mib(&m["jsHeapUsed"]),
        mib(&m["browserPss"]),
    );
    if !keep {
        let _ = std::fs::remove_dir_all(&tiles);
    }

    // 3. The peer: the same city as one file, in each format asked for.
    let formats = env_or("CITY_WALK_PEER_FORMATS", "compressed.ply,ply");
    for ext in formats.split(',').map(str::trim).filter(|e| !e.is_empty()) {
        let file = work.join(format!("{name}.{ext}"));
        let tag = ext.replace('.', "-");
        let mut transform_s = None;
        if !file.is_file() {
            let t = Instant::now();
            let st = Command::new(root().join("tests/js/node_modules/.bin/splat-transform"))
                .args(["-q", "-w"])
                .arg(input)
                .arg(&file)
                .status()
                .expect("splat-transform (npm ci --prefix tests/js)");
            assert!(
                st.success(),
                "splat-transform failed on {}",
                input.display()
            );
            transform_s = Some(t.elapsed().as_secs_f64());
        }
        let peer_csv = target.join(format!("city-peer-{name}-{tag}.csv"));
        let mut args = vec![file.to_string_lossy().into()];
        args.extend(common(&peer_csv));
        args.extend([
            "--tileset".into(),
            tiles_json.to_string_lossy().into(),
            "--timeout".into(),
            env_or("CITY_WALK_PEER_TIMEOUT", "600"),
            "--shot".into(),
            target
                .join(format!("city-peer-{name}-{tag}.png"))
                .to_string_lossy()
                .into(),
        ]);
        let peer = node(
            "city_peer.mjs",
            &args,
            &target.join(format!("city-peer-{name}-{tag}.json")),
        );
        let file_bytes = std::fs::metadata(&file).map(|m| m.len()).unwrap_or(0);
        if !keep {
            let _ = std::fs::remove_file(&file);
        }
        let pm = &peer["max"];
        let _ = writeln!(
            rows,
            "| {name} | PlayCanvas {} full download ({:.0} MiB .{ext}{}) | {}{} | first frame {} | all | - | {} (VRAM) | {} | {} |",
            peer["engine"].as_str().unwrap_or("?"),
            file_bytes as f64 / 1048576.0,
            transform_s.map_or(String::new(), |s| format!(", splat-transform {s:.0} s")),
            peer["outcome"].as_str().unwrap_or("?"),
            peer["peer"]["errors"]
                .as_array()
                .and_then(|e| e.first())
                .and_then(|e| e.as_str())
                .map_or(String::new(), |e| format!(": {e}")),
            peer["timeToFirstFrameSeconds"]
                .as_f64()
                .map_or("none".into(), |s| format!("{s:.1} s")),
            mib(&pm["vramBytes"]),
            mib(&pm["jsHeapUsed"]),
            mib(&pm["browserPss"]),
        );
    }
    rows
}

fn dir_bytes(dir: &Path) -> u64 {
    let mut n = 0;
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).into_iter().flatten().flatten() {
            match e.file_type() {
                Ok(t) if t.is_dir() => stack.push(e.path()),
                Ok(_) => n += e.metadata().map(|m| m.len()).unwrap_or(0),
                Err(_) => {}
            }
        }
    }
    n
}

/// Columns `names` of a CSV written by the walk scripts (x = first column, seconds).
fn read_csv(path: &Path, names: &[&str]) -> Vec<Vec<(f64, f64)>> {
    let text = std::fs::read_to_string(path).unwrap_or_default();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap_or_default().split(',').collect();
    let idx: Vec<Option<usize>> = names
        .iter()
        .map(|n| header.iter().position(|h| h == n))
        .collect();
    let mut out = vec![vec![]; names.len()];
    for line in lines {
        let v: Vec<&str> = line.split(',').collect();
        let Some(t) = v.first().and_then(|s| s.parse::<f64>().ok()) else {
            continue;
        };
        for (o, i) in out.iter_mut().zip(&idx) {
            if let Some(y) = i.and_then(|i| v.get(i)).and_then(|s| s.parse::<f64>().ok()) {
                o.push((t, y));
            }
        }
    }
    out
}

/// `docs/city-walk.svg`: per walked city, the viewer's memory over the walk and its resident
/// splats and frames; per peer run, its memory until it ended.
fn plot() {
    let target = root().join("target");
    let files = |prefix: &str| -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(&target)
            .unwrap()
            .flatten()
            .filter_map(|e| {
                let n = e.file_name().to_string_lossy().into_owned();
                n.strip_prefix(prefix)
                    .and_then(|n| n.strip_suffix(".csv"))
                    .map(String::from)
            })
            .collect();
        v.sort();
        v
    };
    let mb = |s: Vec<(f64, f64)>| -> Vec<(f64, f64)> {
        s.into_iter().map(|(x, y)| (x, y / 1048576.0)).collect()
    };
    let named = |labels: &[&str], data: Vec<Vec<(f64, f64)>>| -> Vec<Series> {
        labels
            .iter()
            .zip(data)
            .map(|(l, d)| (l.to_string(), mb(d)))
            .collect()
    };
    let mut charts = vec![];
    for name in files("city-walk-") {
        let csv = target.join(format!("city-walk-{name}.csv"));
        let data = read_csv(
            &csv,
            &[
                "budget_bytes",
                "cache_bytes",
                "gpu_bytes",
                "wasm_bytes",
                "js_heap_used",
                "browser_pss",
            ],
        );
        let labels = [
            "budgetMB",
            "cache",
            "GPU (viewer's count)",
            "wasm memory",
            "JS heap",
            "browser PSS",
        ];
        charts.push(line_chart(
            &format!("web viewer walking {name}: memory"),
            "seconds into the walk",
            "MiB",
            &named(&labels, data),
            None,
        ));
        let d = read_csv(&csv, &["resident_splats", "frames"]);
        let series: Vec<Series> = vec![
            (
                "resident splats / 1000".into(),
                d[0].iter().map(|&(x, y)| (x, y / 1000.0)).collect(),
            ),
            ("frames drawn".into(), d[1].clone()),
        ];
        charts.push(line_chart(
            &format!("web viewer walking {name}: splats, frames"),
            "seconds into the walk",
            "count",
            &series,
            None,
        ));
    }
    for name in files("city-peer-") {
        let data = read_csv(
            &target.join(format!("city-peer-{name}.csv")),
            &["vram_bytes", "js_heap_used", "browser_pss"],
        );
        let labels = ["VRAM (PlayCanvas's count)", "JS heap", "browser PSS"];
        charts.push(line_chart(
            &format!("PlayCanvas, {name}: memory"),
            "seconds since page load",
            "MiB",
            &named(&labels, data),
            None,
        ));
    }
    std::fs::write(root().join("docs/city-walk.svg"), panels(&charts, 2)).unwrap();
}

fn main() {
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with("--"))
        .collect();
    if args.is_empty() {
        eprintln!(
            "usage: cargo bench --bench city_walk -- CITY.splat [CITY.splat ...] | plot (see the top of benches/city_walk.rs)"
        );
        std::process::exit(2);
    }
    if args.iter().any(|a| a != "plot") {
        let bin = release_binary();
        let mut table = String::from(
            "| city | viewer | outcome | walk / first frame | max resident splats | max cache | max GPU | max JS heap | max browser PSS |\n|---|---|---|---|---|---|---|---|---|\n",
        );
        for a in args.iter().filter(|a| *a != "plot") {
            let rows = run_city(&bin, Path::new(a));
            print!("{rows}");
            table.push_str(&rows);
        }
        std::fs::write(root().join("target/city-walk.md"), &table).unwrap();
        println!("{table}");
    }
    plot();
}
