//! Files the commands write besides tilesets: `render -o` onto destinations that cannot take a
//! PNG and `validate --report` onto the tileset it checks are refused with exit 2, the
//! destination untouched; never "rendered" with nothing written.

use super::common::bin;
use super::inputs::write_splat;
use super::stderr;
use std::path::Path;
use std::process::{Command, Output};

fn render(input: &Path, output: &Path) -> Output {
    Command::new(bin())
        .arg("render")
        .arg(input)
        .arg("-o")
        .arg(output)
        .args(["--width", "64", "--height", "48", "--auto-view", "0"])
        .output()
        .unwrap()
}

#[cfg(target_os = "linux")]
#[test]
fn a_link_to_a_device_and_a_fifo_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("in.splat");
    write_splat(&input, 500);
    let link = tmp.path().join("full.png");
    std::os::unix::fs::symlink("/dev/full", &link).unwrap();
    let fifo = tmp.path().join("fifo.png");
    assert!(
        Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap()
            .success()
    );
    for out in [&link, &fifo] {
        let o = render(&input, out);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{}: {err}", out.display());
        assert!(err.contains("not a regular file"), "{err}");
        assert!(!err.contains("rendered"), "{err}");
        assert!(!err.contains("panicked"), "{err}");
    }
    // The link is still a link, and nothing was left beside it.
    assert!(link.symlink_metadata().unwrap().file_type().is_symlink());
    let names: Vec<String> = std::fs::read_dir(tmp.path())
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    assert!(
        !names.iter().any(|n| n.ends_with(".tmp")),
        "leftovers: {names:?}"
    );
}

#[test]
fn a_png_replaces_an_earlier_file_whole_and_through_a_link() {
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("in.splat");
    write_splat(&input, 500);
    let out = tmp.path().join("out.png");
    std::fs::write(&out, b"an earlier file").unwrap();
    let o = render(&input, &out);
    assert!(o.status.success(), "{}", stderr(&o));
    let png = std::fs::read(&out).unwrap();
    assert!(png.starts_with(b"\x89PNG"), "not a PNG");
    // Through a symbolic link the link's target is replaced and the link kept.
    #[cfg(unix)]
    {
        let link = tmp.path().join("link.png");
        std::os::unix::fs::symlink(&out, &link).unwrap();
        std::fs::write(&out, b"an earlier file").unwrap();
        let o = render(&input, &link);
        assert!(o.status.success(), "{}", stderr(&o));
        assert!(link.symlink_metadata().unwrap().file_type().is_symlink());
        assert_eq!(std::fs::read(&out).unwrap(), png);
    }
}

#[test]
fn an_output_that_is_not_png_is_refused_once_and_nothing_is_written() {
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("in.splat");
    write_splat(&input, 500);
    for name in ["x.jpg", "x", "x.png.tmp"] {
        let out = tmp.path().join(name);
        let o = render(&input, &out);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{name}: {err}");
        assert_eq!(err.matches("ending in .png").count(), 1, "{err}");
        assert_eq!(err.lines().count(), 1, "one error line: {err}");
        assert!(!out.exists(), "{name} was created");
    }
    // Upper case is a PNG name too.
    let o = render(&input, &tmp.path().join("X.PNG"));
    assert!(o.status.success(), "{}", stderr(&o));
}

#[test]
fn render_without_a_camera_names_both_ways_to_give_one() {
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("in.splat");
    write_splat(&input, 500);
    let o = Command::new(bin())
        .arg("render")
        .arg(&input)
        .arg("-o")
        .arg(tmp.path().join("v.png"))
        .output()
        .unwrap();
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("--camera") && err.contains("--auto-view"),
        "{err}"
    );
    assert!(!tmp.path().join("v.png").exists());
}

#[test]
fn a_validation_report_onto_its_tileset_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let ts = super::small_tileset(tmp.path());
    let before = std::fs::read(ts.join("tileset.json")).unwrap();
    for report in [ts.join("tileset.json"), ts.join("report.json")] {
        let o = Command::new(bin())
            .arg("validate")
            .arg(&ts)
            .arg("--report")
            .arg(&report)
            .output()
            .unwrap();
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert!(err.contains("inside the input"), "{err}");
    }
    assert_eq!(std::fs::read(ts.join("tileset.json")).unwrap(), before);
    assert!(!ts.join("report.json").exists());
    // Beside the tileset it is written.
    let beside = tmp.path().join("report.json");
    let o = Command::new(bin())
        .arg("validate")
        .arg(&ts)
        .arg("--report")
        .arg(&beside)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&beside).unwrap()).unwrap();
    assert_eq!(v["numErrors"], 0);
}
