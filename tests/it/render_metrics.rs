//! SSIM and PSNR against scikit-image 0.26 reference values (`tests/data/render/metric_vectors.json`,
//! written by `tools/gen_metric_vectors.py`); the test itself needs no Python.

use serde::Deserialize;
use splat2tiles_render::{Image, psnr, ssim};

#[derive(Deserialize)]
struct Vectors {
    cases: Vec<Case>,
}

#[derive(Deserialize)]
struct Case {
    name: String,
    width: u32,
    height: u32,
    a: Vec<f32>,
    b: Vec<f32>,
    ssim: f64,
    psnr: f64,
}

#[test]
fn ssim_and_psnr_match_scikit_image() {
    let text = std::fs::read_to_string("tests/data/render/metric_vectors.json").unwrap();
    let v: Vectors = serde_json::from_str(&text).unwrap();
    assert!(v.cases.len() >= 6, "corpus guard: {} cases", v.cases.len());
    for c in &v.cases {
        let a = Image {
            width: c.width,
            height: c.height,
            data: c.a.clone(),
        };
        let b = Image {
            width: c.width,
            height: c.height,
            data: c.b.clone(),
        };
        let s = ssim(&a, &b).unwrap();
        let p = psnr(&a, &b).unwrap();
        assert!(
            (s - c.ssim).abs() < 1e-4,
            "{}: ssim {s} vs {}",
            c.name,
            c.ssim
        );
        assert!(
            (p - c.psnr).abs() < 1e-4,
            "{}: psnr {p} vs {}",
            c.name,
            c.psnr
        );
        // Symmetric.
        assert!((ssim(&b, &a).unwrap() - s).abs() < 1e-12);
    }
}
