//! The tileset loader of `render` and `stats`, and `validate`'s walk, on hostile tilesets made
//! from a small converted one: a subtree file that names itself, one content named by every
//! tile, a device or a FIFO where a file should be, and a `tileset.json` of millions of values.
//! Each command runs under a 512 MiB data limit (`prlimit --data`) and a deadline.

use super::common::bin;
use super::inputs::write_splat;
use super::{convert, stderr};
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

/// The data (heap) limit every command of this file runs under: an allocation past it fails
/// and the command aborts, which the exit-code checks below catch.
const DATA_LIMIT: &str = "--data=536870912";

/// How long a command may run before it counts as hung (it is killed).
const DEADLINE: Duration = Duration::from_secs(60);

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Runs `splat2tiles ARGS...` under [`DATA_LIMIT`] (where `prlimit` exists) and [`DEADLINE`].
fn limited(args: &[&str]) -> Output {
    let mut cmd = if Path::new("/usr/bin/prlimit").exists() {
        let mut c = Command::new("/usr/bin/prlimit");
        c.arg(DATA_LIMIT).arg(bin());
        c
    } else {
        Command::new(bin())
    };
    let mut child = cmd
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > DEADLINE {
            child.kill().unwrap();
            panic!("splat2tiles {args:?} still running after {DEADLINE:?}");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    child.wait_with_output().unwrap()
}

/// A converted scene of several levels, one level per subtree file: `DIR/ts`.
fn leveled_tileset(dir: &Path) -> PathBuf {
    let input = dir.join("in.splat");
    write_splat(&input, 4000);
    let out = dir.join("ts");
    let o = convert(&[
        s(&input),
        "-o",
        s(&out),
        "--max-splats",
        "256",
        "--subtree-levels",
        "1",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    out
}

/// Rewrites `ts/tileset.json` through `edit`.
fn edit_tileset(ts: &Path, edit: impl FnOnce(&mut serde_json::Value)) {
    let p = ts.join("tileset.json");
    let mut v: serde_json::Value = serde_json::from_slice(&std::fs::read(&p).unwrap()).unwrap();
    edit(&mut v);
    std::fs::write(&p, serde_json::to_vec(&v).unwrap()).unwrap();
}

/// `render` and `stats` of `ts` exit 2 with one message holding every needle.
fn assert_loader_refuses(ts: &Path, needles: &[&str]) {
    let json = ts.join("tileset.json");
    let png = ts.parent().unwrap().join("view.png");
    for args in [
        vec![
            "render",
            s(&json),
            "-o",
            s(&png),
            "--auto-view",
            "0",
            "--width",
            "64",
            "--height",
            "48",
        ],
        vec!["stats", s(&json)],
    ] {
        let o = limited(&args);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        for n in needles {
            assert!(err.contains(n), "{args:?} says '{n}': {err}");
        }
        assert!(!png.exists(), "{args:?} wrote a picture");
    }
}

/// `validate` of `ts` finishes (exit 1: errors found) and reports `code`.
fn assert_validate_reports(ts: &Path, code: &str) {
    let o = limited(&["validate", s(ts)]);
    let out = String::from_utf8_lossy(&o.stdout);
    assert_eq!(o.status.code(), Some(1), "{out}{}", stderr(&o));
    assert!(out.contains(code), "reports {code}: {out}");
}

#[test]
fn a_subtree_file_naming_itself_is_refused_by_the_loader_and_walked_once_by_validate() {
    let tmp = tempfile::tempdir().unwrap();
    let ts = leveled_tileset(tmp.path());
    edit_tileset(&ts, |v| {
        let it = &mut v["root"]["implicitTiling"];
        it["subtrees"]["uri"] = "subtrees/0/0/0/0.subtree".into();
        it["availableLevels"] = 21.into();
    });
    assert_loader_refuses(&ts, &["subtrees/0/0/0/0.subtree", "subtree of both tile"]);
    assert_validate_reports(&ts, "IMPLICIT_TILING_ERROR");
}

#[test]
fn one_content_named_by_every_tile_is_refused_by_the_loader_and_read_once_by_validate() {
    let tmp = tempfile::tempdir().unwrap();
    let ts = leveled_tileset(tmp.path());
    edit_tileset(&ts, |v| {
        v["root"]["content"]["uri"] = "tiles/best/0/0/0/0.glb".into();
    });
    assert_loader_refuses(&ts, &["0.glb", "content of both tile"]);
    // The root's splats lie outside the children's boxes: reported, once per tile at most.
    let o = limited(&["validate", s(&ts)]);
    assert!(matches!(o.status.code(), Some(0 | 1)), "{}", stderr(&o));
}

#[cfg(unix)]
#[test]
fn a_device_or_a_fifo_in_place_of_a_file_is_refused_without_reading_it() {
    let tmp = tempfile::tempdir().unwrap();
    let ts = leveled_tileset(tmp.path());
    // The root content: a link to /dev/zero (endless).
    let root_tile = ts.join("tiles/best/0/0/0/0.glb");
    std::fs::remove_file(&root_tile).unwrap();
    std::os::unix::fs::symlink("/dev/zero", &root_tile).unwrap();
    assert_loader_refuses_render(&ts, &["0.glb", "not a regular file"]);
    // The root subtree: a FIFO nobody writes (a read would wait forever).
    let root_subtree = ts.join("subtrees/0/0/0/0.subtree");
    std::fs::remove_file(&root_subtree).unwrap();
    let made = Command::new("mkfifo").arg(&root_subtree).status().unwrap();
    assert!(made.success());
    assert_loader_refuses(&ts, &["0.subtree", "not a regular file"]);
    assert_validate_reports(&ts, "IO_ERROR");
}

/// `render` of `ts`, drawing the root only, exits 2 with one message holding every needle
/// (`stats` reads no content).
fn assert_loader_refuses_render(ts: &Path, needles: &[&str]) {
    let png = ts.parent().unwrap().join("view.png");
    let o = limited(&[
        "render",
        s(&ts.join("tileset.json")),
        "-o",
        s(&png),
        "--auto-view",
        "0",
        "--max-sse",
        "1e9",
    ]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    for n in needles {
        assert!(err.contains(n), "says '{n}': {err}");
    }
    assert!(!png.exists());
}

/// A `tileset.json` whose `extras` hold 7 million empty arrays (20 MB of text, several GiB
/// once parsed into JSON values).
fn bloat_tileset(ts: &Path) {
    let p = ts.join("tileset.json");
    let text = std::fs::read_to_string(&p).unwrap();
    let body = text.trim_end().strip_suffix('}').unwrap();
    let mut out = String::with_capacity(21 << 20);
    out.push_str(body);
    out.push_str(",\"extras\":[");
    out.push_str(&"[],".repeat(7_000_000));
    out.push_str("[]]}");
    std::fs::write(&p, out).unwrap();
}

#[test]
fn a_tileset_json_of_millions_of_values_is_refused_before_it_is_parsed() {
    let tmp = tempfile::tempdir().unwrap();
    let ts = leveled_tileset(tmp.path());
    bloat_tileset(&ts);
    assert_loader_refuses(&ts, &["tileset.json", "tileset JSON may have"]);
    assert_validate_reports(&ts, "JSON_TOO_LARGE");
}
