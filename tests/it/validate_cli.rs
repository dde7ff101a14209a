//! `splat2tiles validate` end to end: exit codes (0 valid, 1 errors, 2 unreadable), the JSON report
//! shape (Cesium 3d-tiles-validator style) and `--report`.

use crate::common;

use serde_json::Value;
use std::process::Command;

#[test]
fn exit_codes_json_report_and_report_file() {
    let dir = tempfile::tempdir().unwrap();
    let ply = dir.path().join("s.ply");
    common::write_ply_file(&ply, &common::random_splats(1500, 1, 5.0, 3));
    let out = dir.path().join("ts");
    let st = Command::new(common::bin())
        .args(["convert", "-q", "--max-splats", "300"])
        .arg(&ply)
        .arg("-o")
        .arg(&out)
        .status()
        .unwrap();
    assert!(st.success());
    let tileset = out.join("tileset.json");

    let o = Command::new(common::bin())
        .arg("validate")
        .arg(&tileset)
        .output()
        .unwrap();
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stdout)
    );
    assert!(String::from_utf8_lossy(&o.stdout).contains("valid (0 errors, 0 warnings"));

    let report = dir.path().join("r.json");
    let o = Command::new(common::bin())
        .args(["validate", "--json", "--report"])
        .arg(&report)
        .arg(&out)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(0));
    let v: Value = serde_json::from_slice(&o.stdout).unwrap();
    for k in ["date", "numErrors", "numWarnings", "numInfos", "issues"] {
        assert!(v.get(k).is_some(), "report lacks {k}");
    }
    let file: Value = serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
    assert_eq!(file["numErrors"], 0);

    // One broken rule: exit 1 and the code in the JSON issues.
    let mut ts: Value = serde_json::from_slice(&std::fs::read(&tileset).unwrap()).unwrap();
    ts["root"]["geometricError"] = (-1.0).into();
    std::fs::write(&tileset, serde_json::to_vec(&ts).unwrap()).unwrap();
    let o = Command::new(common::bin())
        .args(["validate", "--json"])
        .arg(&tileset)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1));
    let v: Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["numErrors"], 1);
    assert_eq!(v["issues"][0]["type"], "VALUE_NOT_IN_RANGE");
    assert_eq!(v["issues"][0]["severity"], "ERROR");
    assert_eq!(v["issues"][0]["path"], "tileset.json#/root/geometricError");

    // Cannot read at all: exit 2.
    let o = Command::new(common::bin())
        .arg("validate")
        .arg(dir.path().join("nope/tileset.json"))
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));

    // A file that is not JSON (here a PNG) is unreadable too: exit 2, with the parse error
    // reported where it is.
    let png = dir.path().join("picture.json");
    std::fs::write(&png, b"\x89PNG\r\n\x1a\n\0\0\0\rIHDR").unwrap();
    for json in [false, true] {
        let o = Command::new(common::bin())
            .arg("validate")
            .arg(&png)
            .args(json.then_some("--json"))
            .output()
            .unwrap();
        let out = String::from_utf8_lossy(&o.stdout);
        assert_eq!(o.status.code(), Some(2), "{out}");
        assert!(out.contains("JSON_PARSE_ERROR"), "{out}");
    }
}
