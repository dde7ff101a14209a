//! `splat2tiles compare` through the binary: JSON output, and a size mismatch is exit code 2.

use splat2tiles_render::Image;
use std::process::Command;

#[test]
fn compare_prints_json_and_refuses_different_sizes() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o.png");
    Image::filled(64, 48, [0.2; 3]).save_png(&out).unwrap();
    // Through the binary: compare prints JSON; a size mismatch is exit code 2.
    let other = dir.path().join("other.png");
    Image::filled(64, 48, [0.5; 3]).save_png(&other).unwrap();
    let exe = crate::common::bin();
    let o = Command::new(&exe)
        .args(["compare", "--json"])
        .arg(&out)
        .arg(&other)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(v["ssim"].as_f64().unwrap() < 1.0 && v["psnr"].as_f64().is_some());
    let small = dir.path().join("small.png");
    Image::filled(32, 48, [0.5; 3]).save_png(&small).unwrap();
    let o = Command::new(&exe)
        .arg("compare")
        .arg(&out)
        .arg(&small)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
}
