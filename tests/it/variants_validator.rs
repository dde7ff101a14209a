//! Khronos glTF-Validator over every variant of every tile (SH3 and SH0 scenes, both profiles):
//! no errors and no warnings, with only `MESH_PRIMITIVE_INVALID_ATTRIBUTE` ignored.

use crate::common::*;
use std::path::Path;
use std::process::Command;

#[test]
fn khronos_validator_accepts_every_variant() {
    let js = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/js");
    assert!(
        js.join("node_modules/gltf-validator").is_dir(),
        "run `npm ci --prefix tests/js` first"
    );
    let tmp = tempfile::tempdir().unwrap();
    let sh3 = tmp.path().join("sh3.ply");
    write_ply_file(&sh3, &random_splats(3000, 3, 5.0, 11));
    let mut files = vec![];
    for (name, input, extra) in [
        ("sh3", sh3.clone(), &["--variants", "all"][..]),
        (
            "donut",
            scene("donut_fused_sh0.ply"),
            &["--variants", "all"][..],
        ),
        ("cesium", sh3, &["--profile", "cesium"][..]),
    ] {
        let out = tmp.path().join(name);
        let o = Command::new(bin())
            .arg("convert")
            .arg(&input)
            .arg("-o")
            .arg(&out)
            .args(["--max-splats", "20000", "--no-utility", "-q"])
            .args(extra)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        files.extend(files_under(&out, "glb"));
    }
    for v in ["best", "high", "medium", "low"] {
        assert!(
            files
                .iter()
                .any(|f| f.to_string_lossy().contains(&format!("/{v}/"))),
            "no {v} tile"
        );
    }
    let o = Command::new("node")
        .arg(js.join("validate_glb.mjs"))
        .args(&files)
        .output()
        .expect("node runs");
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "validator errors:\n{stdout}");
    for line in stdout.lines() {
        let r: serde_json::Value = serde_json::from_str(line).unwrap();
        assert_eq!(r["numErrors"], 0, "{line}");
        assert_eq!(r["numWarnings"], 0, "{line}");
    }
}
