//! Reference-image test: plant.splat at auto-view 0 (320x240, up -y) must match the committed
//! `tests/data/render/plant_view0.png` with SSIM >= 0.99. `S2T_BLESS=1` rewrites the PNG.

mod common;

use std::path::Path;

use glam::DVec3;
use splat2tiles::render::{Image, RenderOptions, auto_views_with, render_splats, ssim};

const REF: &str = "tests/data/render/plant_view0.png";

#[test]
fn plant_view0_matches_reference() {
    if !Path::new(common::splat_file::PLANT).exists() {
        panic!(
            "{} missing: the shared scenes are required",
            common::splat_file::PLANT
        );
    }
    let splats = common::splat_file::read_splat(common::splat_file::PLANT);
    assert_eq!(splats.len(), 113_648);
    let (lo, hi) = splats.bounds().unwrap();
    let cams = auto_views_with(DVec3::from(lo), DVec3::from(hi), -DVec3::Y, 320, 240, 50.0);
    let img = render_splats(&splats, &cams[0], &RenderOptions::default());
    assert!(img.data.iter().all(|v| v.is_finite()));
    if std::env::var_os("S2T_BLESS").is_some() {
        img.save_png(Path::new(REF)).unwrap();
    }
    let reference = Image::load_png(Path::new(REF)).unwrap();
    let s = ssim(&img.quantized(), &reference).unwrap();
    assert!(s >= 0.99, "SSIM {s} against {REF}");
}
