//! Stdout that cannot take the output: a full device gives a clear error and exit 2, a reader
//! that closed the pipe ends the command quietly with 141; neither panics.

use super::common::bin;
use super::small_tileset as tileset;
use std::io::Read;
use std::process::{Command, Stdio};

#[cfg(target_os = "linux")]
#[test]
fn a_full_stdout_is_an_error_not_a_panic() {
    let tmp = tempfile::tempdir().unwrap();
    let ts = tileset(tmp.path());
    let input = tmp.path().join("in.splat");
    let runs: [(&str, Vec<std::ffi::OsString>); 3] = [
        ("stats", vec![ts.clone().into()]),
        ("validate", vec![ts.clone().into()]),
        (
            "convert",
            vec![
                input.into(),
                "-o".into(),
                tmp.path().join("again").into(),
                "--json".into(),
                "--quiet".into(),
            ],
        ),
    ];
    for (cmd, args) in runs {
        let full = std::fs::OpenOptions::new()
            .write(true)
            .open("/dev/full")
            .unwrap();
        let o = Command::new(bin())
            .arg(cmd)
            .args(&args)
            .stdout(full)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{cmd}: {err}");
        assert!(err.contains("cannot write to stdout"), "{cmd}: {err}");
        assert!(!err.contains("panicked"), "{cmd}: {err}");
    }
}

#[test]
fn a_closed_pipe_ends_the_command_quietly() {
    let tmp = tempfile::tempdir().unwrap();
    let ts = tileset(tmp.path());
    let mut child = Command::new(bin())
        .args(["validate", "--json"])
        .arg(&ts)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // The reader goes away before the report is written.
    drop(child.stdout.take());
    let mut err = String::new();
    child
        .stderr
        .take()
        .unwrap()
        .read_to_string(&mut err)
        .unwrap();
    let status = child.wait().unwrap();
    assert!(!err.contains("panicked"), "{err}");
    assert_eq!(status.code(), Some(141), "{err}");
    assert!(err.is_empty(), "a closed pipe is not reported: {err}");
}
