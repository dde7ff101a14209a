//! `splat2tiles compare` through the binary: JSON output, the object-only scores on a background,
//! and a size mismatch is exit code 2.

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

/// The plant rendered small on grey, against the same render with its colours shifted on the
/// object: whole-frame PSNR hides most of the error, the object scores do not, and they score
/// the pixels the first image's object covers.
#[test]
fn compare_scores_the_object_on_its_background() {
    let dir = tempfile::tempdir().unwrap();
    let exe = crate::common::bin();
    let reference = dir.path().join("ref.png");
    let o = Command::new(&exe)
        .arg("render")
        .arg(crate::common::scene("plant.splat"))
        .args(["--auto-view", "0", "--width", "320", "--height", "240"])
        .args(["--background", "0.5,0.5,0.5", "-o"])
        .arg(&reference)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let img = Image::load_png(&reference).unwrap();
    let grey = (0.5f32 * 255.0).round() / 255.0;
    let mut shifted = img.clone();
    let mut object = 0;
    for px in shifted.data.chunks_exact_mut(3) {
        if px.iter().any(|v| (v - grey).abs() > 0.5 / 255.0) {
            px[0] = (px[0] + 0.05).min(1.0);
            object += 1;
        }
    }
    let coded = dir.path().join("coded.png");
    shifted.save_png(&coded).unwrap();
    let run = |bg: &str| -> serde_json::Value {
        let o = Command::new(&exe)
            .args(["compare", "--json", "--background", bg])
            .arg(&reference)
            .arg(&coded)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        serde_json::from_slice(&o.stdout).unwrap()
    };
    let v = run("0.5,0.5,0.5");
    let (whole, on_object) = (
        v["psnr"].as_f64().unwrap(),
        v["object"]["psnr"].as_f64().unwrap(),
    );
    assert_eq!(v["object"]["pixels"].as_u64().unwrap(), object as u64);
    assert!(
        object > 0 && object < 320 * 240 / 2,
        "{object} object pixels"
    );
    assert!(
        whole > on_object + 3.0,
        "whole {whole} dB, object {on_object} dB"
    );
    let crop = v["object"]["crop"].as_array().unwrap();
    assert!(
        crop[2].as_u64().unwrap() < 320 || crop[3].as_u64().unwrap() < 240,
        "{crop:?}"
    );
    assert!(v["object"]["ssim"].as_f64().unwrap() <= v["ssim"].as_f64().unwrap());
    // A background the render does not have makes every pixel the object: whole-frame scores.
    let w = run("0,0,0");
    assert_eq!(w["object"]["pixels"].as_u64().unwrap(), 320 * 240);
    assert!((w["object"]["psnr"].as_f64().unwrap() - whole).abs() < 1e-9);
    // A malformed background is a usage error naming the option.
    let o = Command::new(&exe)
        .args(["compare", "--background", "grey"])
        .arg(&reference)
        .arg(&coded)
        .output()
        .unwrap();
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("--background"));
}
