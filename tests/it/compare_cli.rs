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

/// `render SCENE --auto-view K` and `render TILESET --auto-view K` of its conversion frame the
/// same splat centres, so they draw the same picture (the root's bounding volume, which also
/// holds the splats' extents, framed the tileset from further away: SSIM 0.941 on the plant).
#[test]
fn a_scene_and_its_tileset_have_the_same_auto_views() {
    let dir = tempfile::tempdir().unwrap();
    let scene = crate::common::scene("plant.splat");
    let out = dir.path().join("ts");
    crate::common::convert_file(&scene, &out, &["--no-utility"]);
    let exe = crate::common::bin();
    for k in ["0", "5"] {
        let render = |input: &std::path::Path, png: &str| {
            let png = dir.path().join(png);
            let o = Command::new(&exe)
                .arg("render")
                .arg(input)
                .args(["--auto-view", k, "--width", "160", "--height", "120", "-o"])
                .arg(&png)
                .output()
                .unwrap();
            assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
            Image::load_png(&png).unwrap()
        };
        let a = render(&scene, "scene.png");
        let b = render(&out.join("tileset.json"), "tileset.png");
        let ssim = splat2tiles_render::metrics::ssim(&a, &b).unwrap();
        assert!(ssim >= 0.99, "auto view {k}: SSIM {ssim}");
    }
}
