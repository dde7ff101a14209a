//! Calibrated estimate of a variant's utility without rendering: per-splat differences from Best
//! (colour, opacity, position, scale, rotation), weighted by what each splat covers of the frame.

use glam::{DQuat, DVec3};

use super::utility::ViewSetup;
use crate::lod::eval::{VIEWER_HEIGHT, viewer_focal};
use splat2tiles_core::camera::DEFAULT_WIDTH;
use splat2tiles_core::splat::Splats;
use splat2tiles_render::raster::LOW_PASS;

/// Coverage-weighted squared differences of a candidate from the reference, per kind, as a mean
/// over the viewer's 1280x720 frame.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Features {
    /// View-averaged colour (DC and higher SH over all directions), per channel.
    pub colour: f64,
    /// Opacity.
    pub opacity: f64,
    /// Centre displacement over the splat's on-screen standard deviation.
    pub position: f64,
    /// Relative change of the on-screen standard deviations, per axis.
    pub scale: f64,
    /// Rotation angle (radians) times the splat's anisotropy.
    pub rotation: f64,
}

impl Features {
    /// The features as an array, in [`WEIGHTS`] order.
    pub fn to_array(self) -> [f64; 5] {
        [
            self.colour,
            self.opacity,
            self.position,
            self.scale,
            self.rotation,
        ]
    }
}

/// What `utilityMethod` in the tileset metadata says when utilities are estimated.
pub const METHOD: &str = "frame-v4-estimate: no renders; exp(-sum_k w_k F_k), with F_k the coverage-weighted \
    squared per-splat difference from Best in view-averaged colour, opacity, position, scale and rotation \
    as a mean over the 1280x720 frame of the frame-v4 views, w_k ranking like the 1280x720 frames and \
    scaled to frame-v4 on the shared scenes (spec/quality-variants.md)";

/// Names of the features, in [`WEIGHTS`] order.
pub const FEATURE_NAMES: [&str; 5] = ["colour", "opacity", "position", "scale", "rotation"];

/// Loss (`-ln utility`) per unit of each feature, fitted over every content tile and variant of
/// the shared scenes and the generated SH3 scene by `tools/fit_estimate_weights.py` on the
/// correlation table's CSV: the direction maximises the smallest per-scene Spearman correlation
/// with the 1280x720 frames' SSIM, the scale matches the rendered utility
/// ([`super::utility::utilities`]) in least squares. Its measured agreement, in sample and with
/// each scene left out of the fit, is in BENCHMARKS.md, "Quality variants".
pub const WEIGHTS: [f64; 5] = [1052.46, 19052.6, 2104.68, 0.0, 2314.71];

/// The coverage-weighted features of `candidate` against `reference` (same splats in the same
/// order, tile-relative), seen as [`ViewSetup`] sees them. `None` when the counts differ.
pub fn features(reference: &Splats, candidate: &Splats, setup: &ViewSetup) -> Option<Features> {
    let n = reference.len();
    if candidate.len() != n {
        return None;
    }
    if n == 0 {
        return Some(Features::default());
    }
    // World size of one pixel at the tile centre, and the window's area in pixels.
    let pixel = setup.eye_distance() / viewer_focal();
    let side = setup.window_side() as f64;
    let window = side * side;
    let dilation = LOW_PASS * pixel * pixel;
    let inv_4pi = 1.0 / (4.0 * std::f64::consts::PI);
    let mut acc = [0.0f64; 5];
    let mut coverage = 0.0f64;
    for i in 0..n {
        let s = reference.scales[i].map(|v| (v as f64).abs());
        let sc = candidate.scales[i].map(|v| (v as f64).abs());
        // On-screen variances per axis (world units), the renderer's low-pass included.
        let var = s.map(|v| v * v + dilation);
        let mut sorted = var;
        sorted.sort_by(f64::total_cmp);
        // Projected area (pixels) of the two largest axes, times opacity: what the splat covers.
        let area = 2.0 * std::f64::consts::PI * (sorted[1] * sorted[2]).sqrt() / (pixel * pixel);
        let alpha = reference.opacities[i].clamp(0.0, 1.0) as f64;
        let w = alpha * area.min(window);
        if !(w.is_finite() && w > 0.0) {
            continue;
        }
        coverage += w;
        // Colour: the mean over view directions of the squared colour difference (the SH
        // basis is orthonormal over the sphere), averaged over channels.
        let c2 = colour_diff2(reference, candidate, i);
        acc[0] += w * c2 * inv_4pi / 3.0;
        let da = alpha - candidate.opacities[i].clamp(0.0, 1.0) as f64;
        acc[1] += w * da * da;
        let dp =
            DVec3::from_array(reference.positions[i]) - DVec3::from_array(candidate.positions[i]);
        let mean_var = (var[0] + var[1] + var[2]) / 3.0;
        acc[2] += w * dp.length_squared() / mean_var;
        let mut ds = 0.0;
        for a in 0..3 {
            let d = s[a] - sc[a];
            ds += d * d / var[a];
        }
        acc[3] += w * ds / 3.0;
        let qa = quat(reference.rotations[i]);
        let qb = quat(candidate.rotations[i]);
        let angle = qa.angle_between(qb);
        let aniso = (sorted[2].sqrt() - sorted[0].sqrt()) / sorted[2].sqrt();
        acc[4] += w * (angle * aniso).powi(2);
    }
    // Mean over the window (splats stacked deeper than the window hide each other), then over
    // the frame (the rest of it is background in both renders).
    let norm = coverage.max(window) * (DEFAULT_WIDTH as f64 * VIEWER_HEIGHT as f64) / window;
    let f = acc.map(|v| v / norm);
    Some(Features {
        colour: f[0],
        opacity: f[1],
        position: f[2],
        scale: f[3],
        rotation: f[4],
    })
}

/// Squared colour difference of splat `i` between two versions of a tile, summed over the SH
/// coefficients (missing bands count as zero) and channels: over the view sphere the SH basis is
/// orthonormal, so this is the mean squared colour difference up to a constant.
pub(super) fn colour_diff2(reference: &Splats, candidate: &Splats, i: usize) -> f64 {
    let (rest_ref, rest_cand) = (sh_rest_len(reference), sh_rest_len(candidate));
    let a = &reference.sh_rest[i * rest_ref..(i + 1) * rest_ref];
    let b = &candidate.sh_rest[i * rest_cand..(i + 1) * rest_cand];
    let mut c2 = 0.0;
    for ch in 0..3 {
        let d = (reference.sh0[i][ch] - candidate.sh0[i][ch]) as f64;
        c2 += d * d;
    }
    // In coefficient order as one loop over both would add them (a band only one side has is
    // its square): the same sum, without a branch per coefficient.
    let m = rest_ref.min(rest_cand);
    for (a, b) in a[..m].iter().zip(&b[..m]) {
        for ch in 0..3 {
            let d = a[ch] as f64 - b[ch] as f64;
            c2 += d * d;
        }
    }
    for t in a[m..].iter().chain(&b[m..]) {
        for v in t {
            let v = *v as f64;
            c2 += v * v;
        }
    }
    c2
}

/// Higher SH triples per splat.
fn sh_rest_len(s: &Splats) -> usize {
    s.sh_rest.len() / s.len().max(1)
}

/// A normalised quaternion (identity for a degenerate one).
fn quat(q: [f32; 4]) -> DQuat {
    let q = DQuat::from_xyzw(q[0] as f64, q[1] as f64, q[2] as f64, q[3] as f64);
    if q.length_squared() > 0.0 && q.is_finite() {
        q.normalize()
    } else {
        DQuat::IDENTITY
    }
}

/// The predicted loss (`-ln utility`) of features `f` under `weights`.
pub fn predicted_loss(f: &Features, weights: &[f64; 5]) -> f64 {
    f.to_array()
        .iter()
        .zip(weights)
        .map(|(v, w)| w * v.max(0.0))
        .sum()
}

/// The estimated utility of each candidate against `reference` (tile-relative Best), seen from
/// `setup`: `exp(-predicted loss)`; 1 for a candidate equal to Best, 0 for one that does not
/// hold the same splats.
pub fn estimated_utilities(
    reference: &Splats,
    candidates: &[&Splats],
    setup: &ViewSetup,
) -> Vec<f64> {
    candidates
        .iter()
        .map(|c| match features(reference, c, setup) {
            Some(f) => (-predicted_loss(&f, &WEIGHTS)).exp().clamp(0.0, 1.0),
            // Not the same splats: nothing to compare splat by splat.
            None => 0.0,
        })
        .collect()
}
