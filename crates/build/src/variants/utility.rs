//! Utility of a quality variant (spec/quality-variants.md): mean SSIM against Best over 8 views
//! at the tile's switching distance, rendered in the window the tile covers in a 1280x720 viewer.

use glam::DVec3;

use crate::lod::eval::{VIEWER_HEIGHT, switching_distance, viewer_focal};
use splat2tiles_core::camera::{DEFAULT_FOV_Y_DEG, DEFAULT_WIDTH, box_radius, orbit_views};
use splat2tiles_core::splat::Splats;
use splat2tiles_render::metrics::mse;
use splat2tiles_render::{Camera, Image, RenderOptions, render_splats, ssim};

/// Neutral mid-grey behind the tile: dark and bright splats both show against it.
pub const BACKGROUND: [f32; 3] = [0.5; 3];

/// Geometric error a tile is viewed at, per unit of its bounding-sphere radius (half the
/// diagonal of its splat-centre box), when its real one is unknown (a tileset of one leaf).
/// About the median of (the tile's own geometric error, or its parent's for a leaf) / radius
/// over the content tiles of the shared scenes, rounded down (`tests/variants_utility.rs`,
/// `correlation_table`, prints it).
pub const VIEW_ERROR_PER_RADIUS: f64 = 0.1;

/// What `utilityMethod` in the tileset metadata says when utilities are rendered.
pub const METHOD: &str = "frame-v4: exp(-(1000 x (1 - SSIM) + 10000 x MSE)), SSIM and MSE vs Best of the whole \
    1280x720 frame, mean of 8 views (30 deg elevation, 45 deg azimuth steps) of a 1280x720 viewer with 50 \
    deg vertical fov at the tile's switching distance (its geometric error, a leaf's parent's; 0.1 x the \
    radius of its splat-centre box when it has none; 16 px screen-space error), rendered in the square \
    window around the tile's bounding sphere (the rest of the frame is background in both), mid-grey \
    background, reference CPU renderer (spec/quality-variants.md)";

/// Smallest window side, pixels (SSIM needs at least its 11-pixel Gaussian window).
pub const MIN_WINDOW: u32 = 24;

/// Where a tile is looked at from: its splat-centre box, the up direction and the geometric
/// error that sets the viewing distance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ViewSetup {
    /// Lower corner of the splat-centre box.
    pub lo: DVec3,
    /// Upper corner of the splat-centre box.
    pub hi: DVec3,
    /// Up direction (image up).
    pub up: DVec3,
    /// Geometric error the tile is viewed at (its switching distance follows from it).
    pub error: f64,
}

impl ViewSetup {
    /// The setup for a tile whose geometric error is unknown: `VIEW_ERROR_PER_RADIUS * radius`.
    pub fn estimated(lo: DVec3, hi: DVec3, up: DVec3) -> Self {
        let r = box_radius(lo, hi);
        ViewSetup {
            lo,
            hi,
            up,
            error: VIEW_ERROR_PER_RADIUS * r,
        }
    }

    /// The setup around `reference`'s splat-centre box viewed at geometric error `error`, or at
    /// [`VIEW_ERROR_PER_RADIUS`] times its radius when that is not positive; `None` when the
    /// reference has no splats.
    pub fn around(reference: &Splats, up: DVec3, error: f64) -> Option<Self> {
        let (lo, hi) = reference.bounds()?;
        Some(ViewSetup::from_box(
            DVec3::from_array(lo),
            DVec3::from_array(hi),
            up,
            error,
        ))
    }

    /// [`Self::around`] a splat-centre box `lo..hi` known already.
    pub fn from_box(lo: DVec3, hi: DVec3, up: DVec3, error: f64) -> Self {
        let s = ViewSetup::estimated(lo, hi, up);
        if error > 0.0 && error.is_finite() {
            ViewSetup { error, ..s }
        } else {
            s
        }
    }

    /// Distance of the eye from the box centre: the switching distance (from the bounding
    /// sphere) plus the sphere's radius, as `lod::eval` measures LOD parents.
    pub fn eye_distance(&self) -> f64 {
        switching_distance(self.error.max(0.0)) + box_radius(self.lo, self.hi)
    }

    /// The 8 full 1280x720 viewer frames (50 deg vertical field of view): azimuth 45 k degrees,
    /// elevation 30 degrees, looking at the box centre from [`Self::eye_distance`].
    pub fn full_frames(&self) -> Vec<Camera> {
        orbit_views(
            (self.lo + self.hi) * 0.5,
            self.up,
            self.eye_distance(),
            DEFAULT_WIDTH,
            VIEWER_HEIGHT,
            DEFAULT_FOV_Y_DEG,
        )
    }

    /// Side (pixels) of the square window around the image centre that holds the tile's
    /// bounding sphere, 10% margin, at least [`MIN_WINDOW`], at most the frame.
    pub fn window_side(&self) -> u32 {
        let r = box_radius(self.lo, self.hi);
        let d = self.eye_distance();
        let s = (r / d).clamp(0.0, 0.999);
        let rho = viewer_focal() * s / (1.0 - s * s).sqrt();
        let side = (2.2 * rho).ceil();
        let side = if side.is_finite() {
            side as u32
        } else {
            u32::MAX
        };
        side.clamp(MIN_WINDOW, VIEWER_HEIGHT)
    }

    /// The 8 views cropped to [`Self::window_side`]: the same pixels the full frames show of
    /// the tile, without the background around it.
    pub fn windows(&self) -> Vec<Camera> {
        let side = self.window_side();
        self.full_frames()
            .into_iter()
            .map(|c| crop(&c, side, side))
            .collect()
    }
}

/// The central `w x h` pixels of `cam`'s image, as a camera of its own.
pub fn crop(cam: &Camera, w: u32, h: u32) -> Camera {
    let (w, h) = (w.min(cam.width), h.min(cam.height));
    let x0 = ((cam.width - w) / 2) as f64;
    let y0 = ((cam.height - h) / 2) as f64;
    Camera {
        width: w,
        height: h,
        cx: cam.cx - x0,
        cy: cam.cy - y0,
        ..*cam
    }
}

/// The renderer settings of the utility: the exact reference, grey background.
pub fn render_options() -> RenderOptions {
    RenderOptions {
        background: BACKGROUND,
        ..Default::default()
    }
}

/// What the renders of a candidate show against the reference's, averaged over the views.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Score {
    /// Mean SSIM over the whole window.
    pub ssim: f64,
    /// Root-mean-square error of the pixel values over the whole window (data range 1).
    pub rmse: f64,
    /// Mean SSIM over the tile's footprint: the pixels whose SSIM window holds a pixel that
    /// either render draws (everywhere else both show plain background and SSIM is 1).
    pub ssim_footprint: f64,
    /// Root-mean-square error over the pixels either render draws.
    pub rmse_footprint: f64,
    /// Mean SSIM of the whole 1280x720 frame the window was cut from (outside the window both
    /// renders show plain background, where SSIM is 1).
    pub ssim_frame: f64,
    /// Mean squared error of the whole 1280x720 frame.
    pub mse_frame: f64,
}

/// Radius of SSIM's Gaussian window (`render::metrics`: sigma 1.5, truncated at 3.5 sigma).
const SSIM_RADIUS: usize = 5;

/// Share of the full frame's valid SSIM pixels (those whose whole 11-px window lies inside the
/// image) that a `w x h` window holds, and share of the frame's pixels.
fn frame_shares(w: usize, h: usize) -> (f64, f64) {
    let valid = |n: usize| n.saturating_sub(2 * SSIM_RADIUS) as f64;
    let (fw, fh) = (DEFAULT_WIDTH as usize, VIEWER_HEIGHT as usize);
    (
        (valid(w) * valid(h) / (valid(fw) * valid(fh))).min(1.0),
        ((w * h) as f64 / (fw * fh) as f64).min(1.0),
    )
}

/// Window, footprint and frame statistics of one view: (SSIM, MSE) over the window, over the
/// footprint and over the full frame (see [`Score`]).
fn view_score(a: &Image, b: &Image) -> [f64; 6] {
    let [s, m, s_fp, m_fp] = window_score(a, b);
    let (ssim_share, pixel_share) = frame_shares(a.width as usize, a.height as usize);
    [
        s,
        m,
        s_fp,
        m_fp,
        1.0 - (1.0 - s) * ssim_share,
        m * pixel_share,
    ]
}

/// Window and footprint statistics of one view: (SSIM, MSE) over the window and over the
/// footprint.
fn window_score(a: &Image, b: &Image) -> [f64; 4] {
    let s = ssim(a, b).unwrap_or(0.0);
    let m = mse(a, b).unwrap_or(1.0);
    let (w, h) = (a.width as usize, a.height as usize);
    if a.data.len() != 3 * w * h || b.data.len() != a.data.len() {
        return [s, m, s, m];
    }
    let drawn: Vec<bool> = (0..w * h)
        .map(|i| {
            (0..3).any(|c| a.data[3 * i + c] != BACKGROUND[c] || b.data[3 * i + c] != BACKGROUND[c])
        })
        .collect();
    let drawn_count = drawn.iter().filter(|d| **d).count();
    if drawn_count == 0 {
        return [1.0, 0.0, 1.0, 0.0];
    }
    // Pixels of the valid SSIM region whose window touches a drawn pixel (a box dilation).
    let r = SSIM_RADIUS;
    let mut rows = vec![false; w * h];
    for y in 0..h {
        for x in 0..w {
            let (x0, x1) = (x.saturating_sub(r), (x + r + 1).min(w));
            rows[y * w + x] = drawn[y * w + x0..y * w + x1].iter().any(|d| *d);
        }
    }
    let (mut valid, mut near) = (0usize, 0usize);
    for y in r..h.saturating_sub(r) {
        for x in r..w.saturating_sub(r) {
            valid += 1;
            near += (y - r..=y + r).any(|yy| rows[yy * w + x]) as usize;
        }
    }
    let ssim_fp = if near == 0 {
        1.0
    } else {
        1.0 - (1.0 - s) * valid as f64 / near as f64
    };
    let mse_fp = m * (w * h) as f64 / drawn_count as f64;
    [s, m, ssim_fp, mse_fp]
}

/// Each candidate's renders against `reference`'s over `cams`, averaged over the views.
pub fn scores(reference: &Splats, candidates: &[&Splats], cams: &[Camera]) -> Vec<Score> {
    let opts = render_options();
    let base: Vec<Image> = cams
        .iter()
        .map(|c| render_splats(reference, c, &opts))
        .collect();
    let n = cams.len().max(1) as f64;
    candidates
        .iter()
        .map(|s| {
            let mut acc = [0.0; 6];
            for (c, b) in cams.iter().zip(&base) {
                let v = view_score(b, &render_splats(s, c, &opts));
                acc[0] += v[0];
                acc[1] += v[1].sqrt();
                acc[2] += v[2];
                acc[3] += v[3].sqrt();
                acc[4] += v[4];
                acc[5] += v[5];
            }
            Score {
                ssim: acc[0] / n,
                rmse: acc[1] / n,
                ssim_footprint: acc[2] / n,
                rmse_footprint: acc[3] / n,
                ssim_frame: acc[4] / n,
                mse_frame: acc[5] / n,
            }
        })
        .collect()
}

/// Mean SSIM of each candidate's renders against `reference`'s over `cams`.
pub fn mean_ssim(reference: &Splats, candidates: &[&Splats], cams: &[Camera]) -> Vec<f64> {
    scores(reference, candidates, cams)
        .into_iter()
        .map(|s| s.ssim)
        .collect()
}

/// Utility exponent per unit of frame SSIM lost (see [`utility_of`]).
pub const SSIM_SCALE: f64 = 1000.0;

/// Utility exponent per unit of frame MSE (see [`utility_of`]).
pub const MSE_SCALE: f64 = 10000.0;

/// The utility of a score: `exp(-(SSIM_SCALE (1 - frame SSIM) + MSE_SCALE frame MSE))`, in
/// (0, 1], 1 for a candidate identical to Best. Over the whole viewer frame at the switching
/// distance, so a tile loses in proportion to the pixels its losses cover there (what the
/// frame's SSIM sees); the MSE term sees the colour shifts SSIM hardly sees (its luminance term
/// is relative to the squared mean). Damage a viewer sees costs at least 0.05
/// (`tests/variants_utility.rs`).
pub fn utility_of(s: Score) -> f64 {
    (-(SSIM_SCALE * (1.0 - s.ssim_frame).max(0.0) + MSE_SCALE * s.mse_frame.max(0.0)))
        .exp()
        .clamp(0.0, 1.0)
}

/// The utility of each candidate against `reference` (tile-relative splats, Best), seen from
/// `setup`'s windows.
pub fn utilities(reference: &Splats, candidates: &[&Splats], setup: &ViewSetup) -> Vec<f64> {
    scores(reference, candidates, &setup.windows())
        .into_iter()
        .map(utility_of)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn window_is_the_centre_of_the_full_frame() {
        let s = ViewSetup {
            lo: DVec3::splat(-1.0),
            hi: DVec3::splat(1.0),
            up: DVec3::Z,
            error: 0.5,
        };
        let full = s.full_frames();
        let win = s.windows();
        assert_eq!(full.len(), 8);
        let side = s.window_side();
        assert!(side > MIN_WINDOW && side < VIEWER_HEIGHT, "{side}");
        // The box corners project inside the window, at the same place as in the full frame
        // shifted by the crop offset.
        for (f, w) in full.iter().zip(&win) {
            for corner in [
                DVec3::splat(-1.0),
                DVec3::splat(1.0),
                DVec3::new(1.0, -1.0, 1.0),
            ] {
                let a = f.project(corner).unwrap();
                let b = w.project(corner).unwrap();
                let dx = (f.width - w.width) / 2;
                let dy = (f.height - w.height) / 2;
                assert!((a[0] - dx as f64 - b[0]).abs() < 1e-9);
                assert!((a[1] - dy as f64 - b[1]).abs() < 1e-9);
                assert!(b[0] > 0.0 && b[0] < side as f64 && b[1] > 0.0 && b[1] < side as f64);
            }
        }
        assert!(METHOD.contains(&format!(
            "exp(-({SSIM_SCALE} x (1 - SSIM) + {MSE_SCALE} x MSE))"
        )));
        assert!(METHOD.contains(&format!("{VIEW_ERROR_PER_RADIUS} x the")));
        // Further away (larger error): a smaller window.
        let far = ViewSetup { error: 2.0, ..s };
        assert!(far.window_side() < side);
    }

    #[test]
    fn footprint_scores_ignore_the_background_around_the_tile() {
        // A 40x40 window of background with a 4x4 patch drawn in one image only.
        let bg = Image::filled(40, 40, BACKGROUND);
        let mut drawn = bg.clone();
        for y in 18..22 {
            for x in 18..22 {
                let i = 3 * (y * 40 + x);
                drawn.data[i..i + 3].copy_from_slice(&[0.6, 0.5, 0.5]);
            }
        }
        let [s, m, s_fp, m_fp, s_frame, m_frame] = view_score(&bg, &drawn);
        // RMSE over the 16 drawn pixels: one channel off by 0.1 -> MSE 0.01 / 3 there.
        assert!((m_fp - 0.01 / 3.0).abs() < 1e-6, "{m_fp}");
        assert!((m - 0.01 / 3.0 * 16.0 / 1600.0).abs() < 1e-8, "{m}");
        // SSIM: the valid region is 30x30 = 900 pixels, the footprint the 14x14 around the
        // patch (its 4x4 dilated by the 5-px window radius).
        assert!(s < 1.0 && s_fp < s);
        assert!(((1.0 - s_fp) - (1.0 - s) * 900.0 / 196.0).abs() < 1e-9);
        // The full 1280x720 frame: 900 of its 1270 x 710 valid SSIM pixels are the window's,
        // 1600 of its 921600 pixels.
        assert!(((1.0 - s_frame) - (1.0 - s) * 900.0 / (1270.0 * 710.0)).abs() < 1e-12);
        assert!((m_frame - m * 1600.0 / 921600.0).abs() < 1e-15);
        // Identical images: a perfect score.
        assert_eq!(view_score(&drawn, &drawn), [1.0, 0.0, 1.0, 0.0, 1.0, 0.0]);
        let perfect = Score {
            ssim: 1.0,
            rmse: 0.0,
            ssim_footprint: 1.0,
            rmse_footprint: 0.0,
            ssim_frame: 1.0,
            mse_frame: 0.0,
        };
        assert_eq!(utility_of(perfect), 1.0);
        let worse = Score {
            ssim_frame: 0.9999,
            ..perfect
        };
        assert!((utility_of(worse) - (-SSIM_SCALE * 1e-4).exp()).abs() < 1e-9);
    }
}
