//! The peers bench's views and scores, shared with the probes in `examples/`: the box around the
//! scene's core, the framed scene, the renders, the 1x / 4x view sets and scores against a base.

use glam::DVec3;
use rayon::prelude::*;
use splat2tiles_build::variants::relative;
use splat2tiles_build::variants::utility::render_options;
use splat2tiles_core::camera::{DEFAULT_FOV_Y_DEG, auto_views_with};
use splat2tiles_core::frame::UpAxis;
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

/// `splats` made relative to the centre of their core box, and the 8 views at 1280x720 that
/// frame that box with `up` (the scene's up axis) up: the bench's 1x view set.
pub fn framed(splats: &Splats, up: UpAxis) -> (Splats, Vec<Camera>) {
    let (lo, hi) = core_box(splats);
    let rel = relative(splats, ((lo + hi) * 0.5).to_array());
    let up_s = up.to_z_up().transpose() * DVec3::Z;
    let (rlo, rhi) = core_box(&rel);
    let cams = auto_views_with(rlo, rhi, up_s, 1280, 720, DEFAULT_FOV_Y_DEG);
    (rel, cams)
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

/// What the renders of `s` from `cams` score against `base` over the whole frame and over the
/// object (`splat2tiles_render::object`: the pixels where the base differs from the grey
/// background, and a crop framing them).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ViewScores {
    /// Mean whole-frame SSIM (0 for a failed comparison).
    pub ssim: f64,
    /// PSNR over the object pixels of every view pooled (one MSE over all of them); infinite when
    /// they are equal, NaN when no view has any.
    pub object_psnr: f64,
    /// Mean SSIM on each view's object crop (views without object pixels left out; NaN if none).
    pub crop_ssim: f64,
}

/// The [`ViewScores`] of `s` seen from `cams` against `base`.
pub fn view_scores(base: &[Image], s: &Splats, cams: &[Camera]) -> ViewScores {
    use splat2tiles_render::object::{masked_psnr, object_mask, object_ssim};
    let imgs = render_all(s, cams);
    let bg = render_options().background;
    let (mut ssim_sum, mut se, mut px, mut crop_sum, mut crops) = (0.0, 0.0, 0usize, 0.0, 0usize);
    for (a, b) in base.iter().zip(&imgs) {
        ssim_sum += ssim(a, b).unwrap_or(0.0);
        let mask = object_mask(a, bg);
        if let Ok(Some(p)) = masked_psnr(a, b, &mask) {
            // Back to the view's MSE, weighted by its object pixels.
            let mse = if p.is_finite() {
                10f64.powf(-p / 10.0)
            } else {
                0.0
            };
            se += mse * mask.count as f64;
            px += mask.count;
        }
        if let Ok(Some(c)) = object_ssim(a, b, &mask) {
            crop_sum += c;
            crops += 1;
        }
    }
    let object_psnr = match (px, se) {
        (0, _) => f64::NAN,
        (_, 0.0) => f64::INFINITY,
        _ => 10.0 * (px as f64 / se).log10(),
    };
    ViewScores {
        ssim: ssim_sum / base.len().max(1) as f64,
        object_psnr,
        crop_ssim: if crops == 0 {
            f64::NAN
        } else {
            crop_sum / crops as f64
        },
    }
}
