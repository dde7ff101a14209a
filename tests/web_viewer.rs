//! The web viewer end to end: `splat2tiles view` serves a converted shared scene and the built
//! viewer (`viewer/web/build.sh`), headless Chromium (SwiftShader WebGL2) streams it through a
//! throttled network, pauses tiles by turning away and resumes them with HTTP Range, and the final
//! screenshot is compared with the CPU reference renderer (`splat2tiles render`) on the same camera.
//! Missing Chromium, npm packages or the built viewer fail the test (CI installs/builds them).

mod common;

use common::*;
use serde_json::Value;
use splat2tiles::render::image::Image;
use splat2tiles::render::metrics::ssim;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};

/// Screenshot vs reference SSIM the viewer must reach. SwiftShader's WebGL2 rasterises the same
/// quads as lavapipe; what differs from the CPU reference is 8-bit blending and edge rounding.
const MIN_SSIM: f64 = 0.98;

/// A running `splat2tiles view`, killed on drop.
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

fn web_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("viewer/web")
}

fn require_harness() {
    require_node_modules();
    assert!(
        js_dir().join("node_modules/playwright-core").is_dir(),
        "tests/js/node_modules/playwright-core is missing: run `npm ci --prefix tests/js`"
    );
    require_chromium();
    assert!(
        web_dir().join("pkg/splat2tiles_web_bg.wasm").is_file(),
        "the web viewer is not built: run viewer/web/build.sh"
    );
}

/// Starts `splat2tiles view DIR --port 0 --no-open` and reads the server's base URL.
fn view(dir: &Path, log: &Path) -> Viewing {
    let mut child = Command::new(bin())
        .args(["view", dir.to_str().unwrap(), "--port", "0", "--no-open"])
        .arg("--web-dir")
        .arg(web_dir())
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(std::fs::File::create(log).unwrap())
        .spawn()
        .expect("start splat2tiles view");
    let stdout = child.stdout.take();
    // Owned by the guard from here on: any panic below kills and reaps the server.
    let mut viewing = Viewing {
        child,
        base: String::new(),
    };
    let mut out = BufReader::new(stdout.expect("piped stdout"));
    loop {
        let mut line = String::new();
        if out.read_line(&mut line).unwrap_or(0) == 0 {
            panic!(
                "splat2tiles view exited before printing its URL; stderr:\n{}",
                std::fs::read_to_string(log).unwrap_or_default()
            );
        }
        if let Some(rest) = line.split("http://127.0.0.1:").nth(1) {
            let port: String = rest.chars().take_while(char::is_ascii_digit).collect();
            viewing.base = format!("http://127.0.0.1:{port}/");
            return viewing;
        }
    }
}

fn run(cmd: &mut Command) -> String {
    let o = cmd.output().unwrap();
    assert!(
        o.status.success(),
        "{cmd:?} failed:\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn u(v: &Value) -> u64 {
    v.as_u64()
        .unwrap_or_else(|| panic!("not an unsigned number: {v}"))
}

#[test]
fn web_viewer_streams_pauses_resumes_and_matches_the_reference() {
    require_harness();
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("donut");
    run(Command::new(bin())
        .arg("convert")
        .arg(scene("donut_fused_sh0.ply"))
        .arg("-o")
        .arg(&dir));
    let (w, h) = (480u32, 360u32);
    let reference = tmp.path().join("reference.png");
    let note = run(Command::new(bin())
        .arg("render")
        .arg(dir.join("tileset.json"))
        .args(["--auto-view", "0", "--width", &w.to_string()])
        .args(["--height", &h.to_string(), "-o"])
        .arg(&reference));
    // "rendered K of N tiles, S splats (...)": what the viewer must hold once settled.
    let splats: u64 = note
        .split(" tiles, ")
        .nth(1)
        .and_then(|s| s.split(' ').next())
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("no splat count in: {note}"));

    let viewing = view(&dir, &tmp.path().join("view.log"));
    let shot = tmp.path().join("web.png");
    let o = Command::new("node")
        .arg(js_dir().join("web_viewer.mjs"))
        .arg(&viewing.base)
        .arg("--shot")
        .arg(&shot)
        .args(["--width", &w.to_string(), "--height", &h.to_string()])
        .output()
        .expect("cannot run `node` (install Node >= 20)");
    let stdout = String::from_utf8_lossy(&o.stdout);
    let v: Value = serde_json::from_str(&stdout).unwrap_or_else(|e| {
        panic!(
            "web_viewer.mjs printed no JSON ({e}):\n{stdout}\n{}",
            String::from_utf8_lossy(&o.stderr)
        )
    });
    drop(viewing);
    assert!(o.status.success() && v["ok"] == true, "run failed: {v:#}");
    assert_eq!(
        v["problems"],
        Value::Array(vec![]),
        "console problems: {v:#}"
    );

    // Paused tiles came back as 206 answers to Range + If-Range requests, and nothing failed.
    let responses = v["responses"].as_array().unwrap();
    let resumed: Vec<&Value> = responses
        .iter()
        .filter(|r| r["status"] == 206 && r["range"].is_string() && r["ifRange"].is_string())
        .collect();
    assert!(!resumed.is_empty(), "no tile was resumed with Range: {v:#}");
    assert!(
        !v["abortedRequests"].as_array().unwrap().is_empty(),
        "no fetch was aborted when the view turned away: {v:#}"
    );
    let failed: Vec<&Value> = responses
        .iter()
        .filter(|r| u(&r["status"]) >= 400)
        .collect();
    assert!(failed.is_empty(), "failed requests: {failed:?}");
    let fin = &v["final"];
    assert!(u(&fin["paused"]) == 0 && u(&fin["errors"]) == 0, "{fin:#}");
    assert_eq!(u(&fin["residentSplats"]), splats, "{fin:#}");

    let a = Image::load_png(&shot).unwrap();
    let b = Image::load_png(&reference).unwrap();
    assert_eq!((a.width, a.height), (w, h), "screenshot size");
    let s = ssim(&a, &b).unwrap();
    eprintln!(
        "web viewer vs reference: SSIM {s:.4} ({} resumed by Range, {} splats)",
        resumed.len(),
        splats
    );
    assert!(
        s >= MIN_SSIM,
        "SSIM {s:.4} < {MIN_SSIM}: {}",
        shot.display()
    );
}

/// High and Medium (EXT_meshopt_compression, decoded by the pure-Rust decoder in wasm) stream,
/// decode and render in headless Chromium like the native decode of the same variant: every
/// splat resident and the picture matching a reference render of a tileset whose content
/// template points at that variant.
#[test]
fn web_viewer_decodes_high_and_medium_like_the_native_decoder() {
    require_harness();
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("donut");
    run(Command::new(bin())
        .arg("convert")
        .arg(scene("donut_fused_sh0.ply"))
        .args(["--variants", "all", "--no-utility", "-o"])
        .arg(&dir));
    let (w, h) = (480u32, 360u32);
    for level in ["high", "medium"] {
        // The native reference: the same tileset with content.uri on this variant's files.
        let native = tmp.path().join(format!("native-{level}"));
        std::fs::create_dir_all(&native).unwrap();
        let ts = std::fs::read_to_string(dir.join("tileset.json")).unwrap();
        assert!(ts.contains("tiles/best/"), "no Best content template");
        let ts_native = dir.join(format!("tileset-{level}.json"));
        std::fs::write(
            &ts_native,
            ts.replace("tiles/best/", &format!("tiles/{level}/")),
        )
        .unwrap();
        let reference = native.join("reference.png");
        let note = run(Command::new(bin())
            .arg("render")
            .arg(&ts_native)
            .args(["--auto-view", "0", "--width", &w.to_string()])
            .args(["--height", &h.to_string(), "-o"])
            .arg(&reference));
        std::fs::remove_file(&ts_native).unwrap();
        let splats: u64 = note
            .split(" tiles, ")
            .nth(1)
            .and_then(|s| s.split(' ').next())
            .and_then(|s| s.parse().ok())
            .unwrap_or_else(|| panic!("no splat count in: {note}"));

        let viewing = view(&dir, &tmp.path().join(format!("view-{level}.log")));
        let shot = native.join("web.png");
        let o = Command::new("node")
            .arg(js_dir().join("web_viewer.mjs"))
            .arg(&viewing.base)
            .arg("--shot")
            .arg(&shot)
            .args(["--width", &w.to_string(), "--height", &h.to_string()])
            .args(["--levels", level])
            .output()
            .expect("cannot run `node` (install Node >= 20)");
        let stdout = String::from_utf8_lossy(&o.stdout);
        let v: Value = serde_json::from_str(&stdout).unwrap_or_else(|e| {
            panic!(
                "web_viewer.mjs printed no JSON ({e}):\n{stdout}\n{}",
                String::from_utf8_lossy(&o.stderr)
            )
        });
        drop(viewing);
        assert!(
            o.status.success() && v["ok"] == true,
            "{level}: run failed: {v:#}"
        );
        assert_eq!(
            v["problems"],
            Value::Array(vec![]),
            "{level}: console problems: {v:#}"
        );
        let responses = v["responses"].as_array().unwrap();
        assert!(
            responses.iter().any(|r| r["url"]
                .as_str()
                .is_some_and(|u| u.contains(&format!("/tiles/{level}/")))),
            "{level}: no {level} tile was fetched: {v:#}"
        );
        assert!(
            !responses.iter().any(|r| r["url"]
                .as_str()
                .is_some_and(|u| u.contains("/tiles/best/"))),
            "{level}: Best tiles were fetched although only {level} was allowed"
        );
        let fin = &v["final"];
        assert!(u(&fin["errors"]) == 0, "{level}: {fin:#}");
        assert_eq!(u(&fin["residentSplats"]), splats, "{level}: {fin:#}");
        let a = Image::load_png(&shot).unwrap();
        let b = Image::load_png(&reference).unwrap();
        let s = ssim(&a, &b).unwrap();
        eprintln!("web viewer {level} vs native {level}: SSIM {s:.4} ({splats} splats)");
        assert!(
            s >= MIN_SSIM,
            "{level}: SSIM {s:.4} < {MIN_SSIM}: {}",
            shot.display()
        );
    }
}
