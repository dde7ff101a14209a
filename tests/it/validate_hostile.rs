//! `validate` on hostile tilesets: external tileset cycles end with an error (no
//! hang), symbolic links out of the folder are refused without reading or echoing the target,
//! percent-encoded URIs resolve, deep explicit trees parse, `--root` admits `../` URIs.

use crate::common;

use serde_json::{Value, json};
use splat2tiles_validate::{ValidateOptions, validate_tileset};
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
    assert_eq!(v["issues"][0]["type"], "EXTERNAL_TILESET_VALIDATION_ERROR");
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

/// A plain glTF (no splat extension) whose numbers are absurd in every way the structure checks
/// read (well-typed JSON, so the typed parse accepts it): each is reported, nothing panics or
/// overflows. Wrongly typed members are a JSON_PARSE_ERROR, also without a panic.
#[test]
fn plain_gltf_with_absurd_numbers_is_reported_not_fatal() {
    use splat2tiles_tiles::encode::glb::write_glb;
    use splat2tiles_validate::validate_glb_bytes;
    let json = json!({
        "asset": {"version": "2.0"},
        "buffers": [{"byteLength": 16}],
        "bufferViews": [
            {"buffer": 0, "byteLength": 16, "byteStride": 4},
            {"buffer": 0, "byteOffset": 4, "byteLength": 12}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": u64::MAX, "type": "VEC3",
             "byteOffset": u64::MAX - 1, "min": [0.0], "max": [1.0, 2.0, 3.0]},
            {"bufferView": 1, "componentType": 5123, "count": 0, "type": "SCALAR"},
            {"bufferView": 4_000_000_000u32, "componentType": 1, "count": 1, "type": "VEC2",
             "normalized": true},
            {"bufferView": 1, "componentType": 5121, "count": 3, "type": "MAT3", "byteOffset": 1}
        ],
        "meshes": [
            {"primitives": [{"attributes": {"POSITION": 0, "COLOR_0": 3, "X": 99},
                             "indices": 3, "mode": 4_000_000_000u32}]},
            {"primitives": []}
        ],
        "nodes": [
            {"mesh": 3, "children": [0, 1, 1, 99]},
            {"children": [2]},
            {"children": [1]}
        ],
        "scenes": [{"nodes": [0, 50]}],
        "scene": 9
    });
    let glb = write_glb(&serde_json::to_vec(&json).unwrap(), Some(&[0u8; 16])).unwrap();
    let report = validate_glb_bytes(&glb, &ValidateOptions::default());
    let codes = report.codes();
    for want in [
        "ACCESSOR_OUT_OF_BOUNDS",
        "ARRAY_LENGTH_MISMATCH",
        "VALUE_NOT_IN_LIST",
        "VALUE_NOT_IN_RANGE",
        "GLTF_REFERENCE_INVALID",
        "ACCESSOR_TYPE_INVALID",
        "ACCESSOR_COUNT_MISMATCH",
        "PROPERTY_MISSING",
    ] {
        assert!(
            codes.iter().any(|c| c == want),
            "{want} missing from {codes:?}"
        );
    }
    assert!(report.issues.iter().all(|i| !i.message.is_empty()));

    let mut typed = json.clone();
    typed["nodes"][0]["matrix"] = json!([1, 2]);
    let glb = write_glb(&serde_json::to_vec(&typed).unwrap(), Some(&[0u8; 16])).unwrap();
    let codes = validate_glb_bytes(&glb, &ValidateOptions::default()).codes();
    assert_eq!(codes, ["JSON_PARSE_ERROR"]);
}
