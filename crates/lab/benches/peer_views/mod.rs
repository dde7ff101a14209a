//! The peers bench's views and score, shared with `examples/high_bits_probe.rs`: the box around
//! the scene's core, the renders, the 1x / 4x view sets and the mean SSIM against a base.

use glam::DVec3;
use rayon::prelude::*;
use splat2tiles_build::variants::utility::render_options;
use splat2tiles_core::splat::Splats;
use splat2tiles_render::{Camera, Image, render_splats, ssim};

/// The box holding the 0.5%..99.5% quantiles of the centres on each axis (floaters far out
/// would otherwise shrink the scene to a few pixels of the frame).
pub fn core_box(s: &Splats) -> (DVec3, DVec3) {
    let mut lo = [0.0; 3];
    let mut hi = [0.0; 3];
    for a in 0..3 {
        let mut v: Vec<f64> = s.positions.iter().map(|p| p[a]).collect();
        v.sort_by(f64::total_cmp);
        let q = |f: f64| v[((v.len() - 1) as f64 * f).round() as usize];
        lo[a] = q(0.005);
        hi[a] = q(0.995);
    }
    (DVec3::from_array(lo), DVec3::from_array(hi))
}

/// The renders of `s` from `cams` (the reference renderer's options, in parallel).
pub fn render_all(s: &Splats, cams: &[Camera]) -> Vec<Image> {
    let opts = render_options();
    cams.par_iter()
        .map(|c| render_splats(s, c, &opts))
        .collect()
}

/// Focal-length factors of the two view sets: the scene framed (1x) and its centre magnified
/// 4x (the same eyes; detail a viewer sees close up, where quantisation shows).
pub const ZOOMS: [f64; 2] = [1.0, 4.0];

/// `cams` with their focal length multiplied by `z`.
pub fn zoomed(cams: &[Camera], z: f64) -> Vec<Camera> {
    cams.iter()
        .map(|c| Camera {
            fx: c.fx * z,
            fy: c.fy * z,
            ..*c
        })
        .collect()
}

/// Mean SSIM of `s` rendered from `cams` against `base` (0 for a failed comparison).
pub fn mean_ssim(base: &[Image], s: &Splats, cams: &[Camera]) -> f64 {
    let imgs = render_all(s, cams);
    let sum: f64 = base
        .iter()
        .zip(&imgs)
        .map(|(a, b)| ssim(a, b).unwrap_or(0.0))
        .sum();
    sum / base.len() as f64
}
