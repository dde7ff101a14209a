//! Reference-image test: `splat2tiles render data/scenes/plant.splat --auto-view 0` (at
//! 320x240) must match the committed `tests/data/render/plant_view0.png` with SSIM >= 0.99, and
//! so must the same view rendered from a converted tileset refined to its leaves (LOD parents,
//! chosen by screen-space error, must stay above 0.85). `S2T_BLESS=1` rewrites the PNG.

use crate::common;

use splat2tiles_render::{Image, ssim};
use std::path::Path;
use std::process::Command;

const REF: &str = "tests/data/render/plant_view0.png";

fn render(input: &Path, out: &Path, extra: &[&str]) {
    let o = Command::new(common::bin())
        .arg("render")
        .arg(input)
        .args(["--auto-view", "0", "--width", "320", "--height", "240"])
        .args(extra)
        .arg("-o")
        .arg(out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

#[test]
fn plant_view0_matches_reference() {
    let tmp = tempfile::tempdir().unwrap();
    let png = tmp.path().join("a.png");
    render(&common::scene("plant.splat"), &png, &[]);
    if std::env::var_os("S2T_BLESS").is_some() {
        std::fs::copy(&png, REF).unwrap();
    }
    let img = Image::load_png(&png).unwrap();
    assert!(img.data.iter().all(|v| v.is_finite()));
    let reference = Image::load_png(Path::new(REF)).unwrap();
    let s = ssim(&img, &reference).unwrap();
    assert!(s >= 0.99, "SSIM {s} against {REF}");
}

#[test]
fn converted_tileset_renders_like_the_scene() {
    let tmp = tempfile::tempdir().unwrap();
    let convert = |out: &Path, max_splats: &str| {
        let o = Command::new(common::bin())
            .arg("convert")
            .arg(common::scene("plant.splat"))
            .args(["--max-splats", max_splats, "-o"])
            .arg(out)
            .output()
            .unwrap();
        assert!(o.status.success());
    };
    let out = tmp.path().join("ts");
    convert(&out, "10000");
    // The reference: the scene as one tile. Tile boxes hold every splat's 3-sigma ellipsoid, so
    // a tileset's automatic view frames more than the scene file's (centres) does; one tile of
    // the same splats has the same root box, hence the same camera.
    let one = tmp.path().join("one");
    convert(&one, "200000");
    let ref_png = tmp.path().join("one.png");
    render(&one.join("tileset.json"), &ref_png, &["--max-sse", "0"]);
    let reference = Image::load_png(&ref_png).unwrap();
    // Refined to the leaves (--max-sse 0): the tiles hold exactly the scene.
    let png = tmp.path().join("t.png");
    render(&out.join("tileset.json"), &png, &["--max-sse", "0"]);
    let s = ssim(&Image::load_png(&png).unwrap(), &reference).unwrap();
    assert!(
        s >= 0.99,
        "tileset render SSIM {s} against the one-tile render"
    );
    // Default selection (16 px) may draw LOD parents at this small size: still close (the root
    // alone, 2,280 of 113,648 splats, measured 0.968).
    let png = tmp.path().join("lod.png");
    render(&out.join("tileset.json"), &png, &[]);
    let s = ssim(&Image::load_png(&png).unwrap(), &reference).unwrap();
    assert!(s >= 0.85, "LOD render SSIM {s} against the one-tile render");
}
