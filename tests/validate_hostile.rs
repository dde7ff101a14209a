//! `validate` on hostile tilesets (issue 13): external tileset cycles end with an error (no
//! hang), symbolic links out of the folder are refused without reading or echoing the target,
//! percent-encoded URIs resolve, deep explicit trees parse, `--root` admits `../` URIs.

mod common;

use serde_json::{Value, json};
use splat2tiles::validate::{ValidateOptions, validate_tileset};
use std::path::Path;
use std::process::Command;

fn tileset(root: Value) -> Value {
    json!({"asset": {"version": "1.1"}, "geometricError": 10.0, "root": root})
}

fn tile(content: Option<&str>) -> Value {
    let mut t = json!({"boundingVolume": {"box": [0,0,0, 1,0,0, 0,1,0, 0,0,1]},
                       "geometricError": 1.0, "refine": "ADD"});
    if let Some(uri) = content {
        t["content"] = json!({ "uri": uri });
    }
    t
}

fn write(p: &Path, v: &Value) {
    std::fs::create_dir_all(p.parent().unwrap()).unwrap();
    std::fs::write(p, serde_json::to_vec(v).unwrap()).unwrap();
}

fn validate_cli(args: &[&str], tileset: &Path) -> (Option<i32>, String) {
    let o = Command::new(common::bin())
        .arg("validate")
        .args(args)
        .arg(tileset)
        .output()
        .unwrap();
    (
        o.status.code(),
        String::from_utf8_lossy(&o.stdout).into_owned(),
    )
}

#[test]
fn external_cycles_are_errors_with_causes_not_hangs() {
    let d = tempfile::tempdir().unwrap();
    let a = d.path().join("tileset.json");
    write(&a, &tileset(tile(Some("b.json"))));
    write(
        &d.path().join("b.json"),
        &tileset(tile(Some("tileset.json"))),
    );
    let (code, out) = validate_cli(&["--json"], &a);
    assert_eq!(code, Some(1), "{out}");
    let v: Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v["issues"][0]["type"], "EXTERNAL_TILESET_VALIDATION_FAILED");
    assert_eq!(v["issues"][0]["path"], "tileset.json#/root/content/uri");
    let cause = &v["issues"][0]["causes"][0];
    assert_eq!(cause["type"], "EXTERNAL_TILESET_CYCLE");
    assert_eq!(cause["path"], "b.json#/root/content/uri");
    // Self reference.
    write(&a, &tileset(tile(Some("./tileset.json"))));
    let (code, out) = validate_cli(&[], &a);
    assert_eq!(code, Some(1));
    assert!(out.contains("EXTERNAL_TILESET_CYCLE"), "{out}");
}

#[test]
fn symlinks_out_of_the_folder_are_refused_unread() {
    let d = tempfile::tempdir().unwrap();
    // A secret outside the tileset folder, and links to it and to /dev/zero.
    let secret = d.path().join("secret.glb");
    std::fs::write(&secret, b"root:x:0:0:TOP-SECRET-BYTES").unwrap();
    let ts = d.path().join("ts");
    std::fs::create_dir_all(&ts).unwrap();
    std::os::unix::fs::symlink(&secret, ts.join("a.glb")).unwrap();
    std::os::unix::fs::symlink("/dev/zero", ts.join("z.glb")).unwrap();
    // A named pipe inside the folder: opening it for reading would block forever.
    let st = Command::new("mkfifo")
        .arg(ts.join("p.glb"))
        .status()
        .unwrap();
    assert!(st.success());
    let mut root = tile(None);
    root["children"] = json!([
        tile(Some("a.glb")),
        tile(Some("z.glb")),
        tile(Some("p.glb"))
    ]);
    for i in 0..3 {
        root["children"][i]["geometricError"] = json!(0.0);
    }
    write(&ts.join("tileset.json"), &tileset(root));
    let (code, out) = validate_cli(&[], &ts.join("tileset.json"));
    assert_eq!(code, Some(1), "{out}");
    assert_eq!(out.matches("URI_OUTSIDE_TILESET").count(), 2, "{out}");
    assert_eq!(out.matches("not a regular file").count(), 1, "{out}");
    assert!(
        !out.contains("TOP-SECRET") && !out.contains("root:x"),
        "{out}"
    );
    // With --root widened to the parent, the (bad) glb is read and reported as a glb, without
    // echoing its first bytes (not even in hex); /dev/zero stays outside.
    let root_arg = d.path().to_str().unwrap();
    let (code, out) = validate_cli(&["--root", root_arg], &ts.join("tileset.json"));
    assert_eq!(code, Some(1));
    assert!(out.contains("GLB_INVALID"), "{out}");
    assert!(!out.contains("72, 6f") && !out.contains("root:"), "{out}");
    assert_eq!(out.matches("URI_OUTSIDE_TILESET").count(), 1, "{out}");
}

#[test]
fn percent_encoded_uris_resolve_and_dot_dot_escapes_are_outside() {
    let d = tempfile::tempdir().unwrap();
    write(&d.path().join("sub dir/0 x.json"), &tileset(tile(None)));
    let t = d.path().join("tileset.json");
    write(&t, &tileset(tile(Some("sub%20dir/0%20x.json"))));
    let r = validate_tileset(&t, &ValidateOptions::default()).unwrap();
    assert!(r.is_valid(), "{}", r.to_text("t"));
    write(
        &t,
        &tileset(tile(Some("sub%20dir/%2e%2e/%2E%2E/etc/passwd"))),
    );
    let r = validate_tileset(&t, &ValidateOptions::default()).unwrap();
    assert_eq!(r.codes(), ["URI_OUTSIDE_TILESET"], "{}", r.to_text("t"));
}

#[test]
fn explicit_trees_deeper_than_serde_default_parse() {
    let d = tempfile::tempdir().unwrap();
    let t = d.path().join("tileset.json");
    for (levels, ok) in [(100usize, true), (250, true), (5000, false)] {
        let mut text = String::from(r#"{"asset":{"version":"1.1"},"geometricError":9,"root":"#);
        for _ in 1..levels {
            text.push_str(r#"{"boundingVolume":{"sphere":[0,0,0,1]},"geometricError":1,"refine":"ADD","children":["#);
        }
        text.push_str(r#"{"boundingVolume":{"sphere":[0,0,0,1]},"geometricError":0}"#);
        for _ in 1..levels {
            text.push_str("]}");
        }
        text.push('}');
        std::fs::write(&t, text).unwrap();
        let r = validate_tileset(&t, &ValidateOptions::default()).unwrap();
        if ok {
            assert!(r.is_valid(), "{levels}: {}", r.to_text("t"));
        } else {
            assert_eq!(r.codes(), ["JSON_NESTING_TOO_DEEP"], "{levels}");
        }
    }
}
