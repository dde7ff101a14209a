//! A taken port: `serve --port N` says to use `--port 0`; `view` without `--port` moves to a free
//! port when 8080 is taken (e.g. by a first `view`).

use super::common::bin;
use std::io::{BufRead, BufReader};
use std::net::TcpListener;
use std::process::{Command, Stdio};

#[test]
fn serve_on_a_taken_port_suggests_port_0() {
    let tmp = tempfile::tempdir().unwrap();
    let held = TcpListener::bind("127.0.0.1:0").unwrap();
    let port = held.local_addr().unwrap().port().to_string();
    let o = Command::new(bin())
        .args([
            "serve",
            tmp.path().to_str().unwrap(),
            "--port",
            &port,
            "--quiet",
        ])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("--port 0"), "{err}");
}

#[test]
fn view_without_a_port_moves_off_a_taken_8080() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    std::fs::create_dir_all(&out).unwrap();
    std::fs::write(out.join("tileset.json"), "{}").unwrap();
    let web = tmp.path().join("web");
    std::fs::create_dir_all(web.join("pkg")).unwrap();
    std::fs::write(web.join("index.html"), "<html></html>").unwrap();
    // Take 8080 unless something else already has it: either way it is busy for `view`.
    let _held = TcpListener::bind("127.0.0.1:8080");
    let mut child = Command::new(bin())
        .args([
            "view",
            out.to_str().unwrap(),
            "--no-open",
            "--quiet",
            "--web-dir",
        ])
        .arg(&web)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    let _ = child.kill();
    let o = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(line.contains("http://127.0.0.1:"), "{line:?}; {err}");
    assert!(!line.contains(":8080/"), "{line}");
    assert!(err.contains("port 8080 is taken"), "{err}");
}
