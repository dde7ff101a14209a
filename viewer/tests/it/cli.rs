//! The `splat2tiles-viewer` binary: headless static frame (same camera and selection as
//! `splat2tiles render`), headless camera trace with tiles fading in, and errors naming the file.

use std::process::Command;

use crate::common::*;
use glam::DVec3;
use splat2tiles_build::convert::ConvertOptions;
use splat2tiles_render::{Camera, Image, metrics};
use splat2tiles_stream::geom::ViewPose;
use splat2tiles_stream::trace::Trace;
use splat2tiles_tiles::geometry::tileset_bounds;
use splat2tiles_viewer::headless::{ViewArgs, open_tileset};

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_splat2tiles-viewer"))
}

#[test]
fn headless_static_and_trace_frames() {
    let dir = tempfile::tempdir().unwrap();
    let ts = convert_to(
        &scene("plant.splat"),
        dir.path(),
        &ConvertOptions::default(),
    );
    // 1. Static: the frame matches the CPU reference of the same selection.
    let out = dir.path().join("static");
    let o = bin()
        .arg(&ts)
        .args([
            "--headless",
            "--auto-view",
            "5",
            "--width",
            "320",
            "--height",
            "180",
        ])
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(
        stdout.contains("splats") && stdout.contains("ms"),
        "{stdout}"
    );
    let gpu = Image::load_png(&out.join("frame_0000.png")).unwrap();
    let v = ViewArgs {
        auto_view: Some(5),
        width: Some(320),
        height: Some(180),
        ..ViewArgs::default()
    };
    let (inst, cam) = tileset_view(&ts, &v);
    let cpu = reference(&inst, &cam, &Default::default());
    let s = metrics::ssim(&cpu, &gpu).unwrap();
    println!("binary static frame vs reference: SSIM {s:.5}");
    assert!(s >= 0.98);

    // 2. Trace streamed through the client: 4 poses closing in on the plant, then the last one
    // held for 1 s (refined tiles cross-fade with their parents, then the fades are over).
    let loaded = open_tileset(&ts).unwrap();
    let (lo, hi) = tileset_bounds(&loaded).unwrap();
    let inv = loaded.root_transform.inverse();
    let (lo, hi) = (inv.transform_point3(lo), inv.transform_point3(hi));
    let c = (lo + hi) * 0.5;
    let r = (hi - lo).length() * 0.5;
    let poses: Vec<ViewPose> = [0.0, 0.1, 0.5, 1.0, 2.0]
        .iter()
        .enumerate()
        .map(|(k, &t)| {
            let pos = c + DVec3::new(3.0 * r - 0.4 * r * k.min(3) as f64, 0.0, 0.8 * r);
            ViewPose::looking_at(t, pos, c)
        })
        .collect();
    let trace = Trace {
        headers: vec![
            ("splat2tiles-trace".into(), "1".into()),
            ("fov_y_deg".into(), "50".into()),
        ],
        poses: poses.clone(),
    };
    let csv = dir.path().join("trace.csv");
    std::fs::write(&csv, trace.to_csv()).unwrap();
    let out = dir.path().join("trace");
    let o = bin()
        .arg(&ts)
        .args(["--headless", "--width", "320", "--height", "180"])
        .arg("--camera-trace")
        .arg(&csv)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    println!("{}", String::from_utf8_lossy(&o.stdout));
    let frames: Vec<Image> = (0..5)
        .map(|k| Image::load_png(&out.join(format!("frame_{k:04}.png"))).unwrap())
        .collect();
    assert_eq!(
        mean(&frames[0]),
        0.0,
        "tiles inserted at t=0 start transparent"
    );
    assert!(mean(&frames[1]) > 0.0 && mean(&frames[1]) < mean(&frames[2]) * 0.9);
    // The held pose (every fade over) matches the reference for the trace's pose re-read
    // from the CSV (4 decimals).
    let back = Trace::from_csv(&std::fs::read_to_string(&csv).unwrap()).unwrap();
    let last = back.poses[4];
    let cam = Camera::from_pose(
        320,
        180,
        50.0,
        loaded.root_transform * last.world_from_camera(),
    );
    let picked = splat2tiles_tiles::geometry::select_tiles(&loaded, &cam, 16.0);
    let inst = splat2tiles_viewer::headless::load_instances(&loaded, &picked).unwrap();
    let cpu = reference(&inst, &cam, &Default::default());
    let s = metrics::ssim(&cpu, &frames[4]).unwrap();
    println!("trace last frame vs reference: SSIM {s:.5}");
    assert!(s >= 0.98);
}

#[test]
fn trace_streams_over_http() {
    let dir = tempfile::tempdir().unwrap();
    let ts = convert_to(
        &scene("plant.splat"),
        dir.path(),
        &ConvertOptions::default(),
    );
    let mount = splat2tiles_serve::Mount::new("/", ts.parent().unwrap()).unwrap();
    let server = splat2tiles_serve::Server::bind(
        vec![mount],
        splat2tiles_serve::ServeOptions {
            bind: std::net::IpAddr::V4(std::net::Ipv4Addr::LOCALHOST),
            port: 0,
            quiet: true,
            threads: 2,
            per_address: 2,
        },
    )
    .unwrap();
    let addr = server.addr();
    let stop = server.stop_handle();
    let th = std::thread::spawn(move || server.run());
    let loaded = open_tileset(&ts).unwrap();
    let (lo, hi) = tileset_bounds(&loaded).unwrap();
    let c = loaded
        .root_transform
        .inverse()
        .transform_point3((lo + hi) * 0.5);
    let r = (hi - lo).length() * 0.5;
    let trace = Trace {
        headers: vec![("splat2tiles-trace".into(), "1".into())],
        poses: vec![
            ViewPose::looking_at(0.0, c + DVec3::new(0.0, 2.5 * r, 0.5 * r), c),
            ViewPose::looking_at(1.0, c + DVec3::new(0.0, 2.5 * r, 0.5 * r), c),
        ],
    };
    let csv = dir.path().join("trace.csv");
    std::fs::write(&csv, trace.to_csv()).unwrap();
    let out = dir.path().join("http");
    let o = bin()
        .arg(format!("http://{addr}/tileset.json"))
        .args(["--headless", "--width", "160", "--height", "96"])
        .arg("--camera-trace")
        .arg(&csv)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    stop.stop();
    th.join().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let last = Image::load_png(&out.join("frame_0001.png")).unwrap();
    assert!(mean(&last) > 0.01, "tiles streamed over HTTP are drawn");
    // A server that is not there: a clear error naming the URL, exit 2.
    let o = bin()
        .arg(format!("http://{addr}/tileset.json"))
        .args(["--headless", "--camera-trace"])
        .arg(&csv)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("tileset.json"));
}

#[test]
fn errors_name_the_file_and_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("nope/tileset.json");
    let o = bin()
        .arg(&missing)
        .args(["--headless", "--auto-view", "0", "--out"])
        .arg(dir.path())
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("nope/tileset.json"), "{err}");
    // Headless without a camera or an output folder is refused before any work.
    let o = bin().arg(&missing).arg("--headless").output().unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--out"));
    let bad_trace = dir.path().join("t.csv");
    std::fs::write(&bad_trace, "not a trace").unwrap();
    let ts = dir.path().join("tileset.json");
    std::fs::write(&ts, "{}").unwrap();
    let o = bin()
        .arg(&ts)
        .args(["--headless", "--camera-trace"])
        .arg(&bad_trace)
        .arg("--out")
        .arg(dir.path())
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("t.csv"));
}

/// `--record` with `--headless --camera-trace`: the CSV written holds the poses drawn, which are
/// the input trace's (the first poses of `traces/plant_dolly.csv`); a folder is refused before any
/// work, and `--record` without a camera trace in the headless mode is refused.
#[test]
fn record_writes_the_drawn_camera_path() {
    let dir = tempfile::tempdir().unwrap();
    let ts = convert_to(
        &scene("plant.splat"),
        dir.path(),
        &ConvertOptions::default(),
    );
    let repo = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let dolly = std::fs::read_to_string(repo.join("traces/plant_dolly.csv")).unwrap();
    let mut input = Trace::from_csv(&dolly).unwrap();
    input.poses.truncate(6);
    let csv = dir.path().join("dolly6.csv");
    std::fs::write(&csv, input.to_csv()).unwrap();
    let rec = dir.path().join("recorded.csv");
    let o = bin()
        .arg(&ts)
        .args(["--headless", "--width", "96", "--height", "54"])
        .arg("--camera-trace")
        .arg(&csv)
        .arg("--out")
        .arg(dir.path().join("frames"))
        .arg("--record")
        .arg(&rec)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let got = Trace::from_csv(&std::fs::read_to_string(&rec).unwrap()).unwrap();
    assert_eq!(got.header("kind"), Some("recorded"));
    assert_eq!(got.header("fov_y_deg"), Some("50"));
    assert_eq!(got.poses.len(), 6);
    for (a, b) in got.poses.iter().zip(&input.poses) {
        assert!((a.t - b.t).abs() < 1e-4, "{a:?} vs {b:?}");
        assert!((a.pos - b.pos).length() < 1e-3, "{a:?} vs {b:?}");
        assert!((a.yaw - b.yaw).abs() < 1e-4 && (a.pitch - b.pitch).abs() < 1e-4);
    }
    // A folder as PATH: exit 2 before rendering anything.
    let out = dir.path().join("refused");
    let o = bin()
        .arg(&ts)
        .args(["--headless", "--camera-trace"])
        .arg(&csv)
        .arg("--out")
        .arg(&out)
        .arg("--record")
        .arg(dir.path())
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("is a folder"));
    assert!(!out.exists(), "nothing rendered");
    let o = bin()
        .arg(&ts)
        .args(["--headless", "--auto-view", "0", "--out"])
        .arg(&out)
        .arg("--record")
        .arg(&rec)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--camera-trace"));
}
