//! The estimated utility as a function of viewing distance: a tile's predicted losses computed
//! when it is written, at a grid of distances, and interpolated once its switching distance is known.

use glam::{DQuat, DVec3};

use super::estimate::{WEIGHTS, colour_diff2};
use super::utility::{MIN_WINDOW, ViewSetup};
use crate::lod::eval::{VIEWER_HEIGHT, viewer_focal};
use splat2tiles_core::camera::{DEFAULT_WIDTH, box_radius};
use splat2tiles_core::splat::Splats;
use splat2tiles_render::raster::LOW_PASS;

/// Eye distances (over the tile's radius) at which the sums are computed: the eye on the
/// bounding sphere (1) out to 1024 radii, doubling. A geometric error `e` puts the eye at
/// `1 + switching_distance(e) / radius` (on the shared scenes' tiles: 2.6 to 1227, median 22).
pub const CURVE_DISTANCES: [f64; 11] = [
    1.0, 2.0, 4.0, 8.0, 16.0, 32.0, 64.0, 128.0, 256.0, 512.0, 1024.0,
];

/// A tile's estimated-utility sums at every one of [`CURVE_DISTANCES`], with the splat-centre
/// box and up direction they are relative to. The loss at a distance is
/// `weighted / max(coverage, window) * window / frame` ([`super::estimate::features`] weighted
/// by [`WEIGHTS`]); the window follows exactly from the distance, so only the two sums, smooth
/// in the distance, are interpolated (the maximum's kink and the window's integer steps are not).
#[derive(Debug, Clone, PartialEq)]
pub struct LossCurve {
    /// Lower corner of the reference's splat-centre box (tile-relative).
    pub lo: [f64; 3],
    /// Upper corner of that box.
    pub hi: [f64; 3],
    /// Up direction the tile is viewed with.
    pub up: [f64; 3],
    /// Coverage-weighted pixels of the reference's splats (`features`' coverage).
    pub coverage: Vec<f64>,
    /// Per variant in [`super::ALL`] order: the weighted sum of its unnormalised features;
    /// `None` for a variant not compared (Best, not written, or not holding the reference's
    /// splats).
    pub weighted: [Option<Vec<f64>>; 4],
}

/// Interpolates `v` (sampled at [`CURVE_DISTANCES`]) at `x` radii: cubic (Catmull-Rom) in
/// log value over log distance where four positive neighbours surround `x`, linear in log value
/// at the ends (extended beyond the grid), linear in the value next to zeros.
fn interpolate(v: &[f64], x: f64) -> Option<f64> {
    let n = CURVE_DISTANCES.len();
    if v.len() != n {
        return None;
    }
    let i = CURVE_DISTANCES[..n - 1]
        .iter()
        .rposition(|&d| d <= x)
        .unwrap_or(0)
        .min(n - 2);
    let (x0, x1) = (CURVE_DISTANCES[i], CURVE_DISTANCES[i + 1]);
    let (l0, l1) = (v[i], v[i + 1]);
    let t = (x / x0).ln() / (x1 / x0).ln();
    let before = i.checked_sub(1).map(|j| v[j]);
    let after = v.get(i + 2).copied();
    Some(match (before, after) {
        (Some(lm), Some(lp))
            if lm > 0.0 && l0 > 0.0 && l1 > 0.0 && lp > 0.0 && (0.0..=1.0).contains(&t) =>
        {
            let [pm, p0, p1, pp] = [lm, l0, l1, lp].map(f64::ln);
            let (t2, t3) = (t * t, t * t * t);
            let v = 0.5
                * (2.0 * p0
                    + (p1 - pm) * t
                    + (2.0 * pm - 5.0 * p0 + 4.0 * p1 - pp) * t2
                    + (3.0 * p0 - pm - 3.0 * p1 + pp) * t3);
            v.exp()
        }
        _ if l0 > 0.0 && l1 > 0.0 => (l0.ln() + t * (l1.ln() - l0.ln())).exp(),
        _ => (l0 + t * (l1 - l0)).max(0.0),
    })
}

impl LossCurve {
    /// Where the tile is viewed from at geometric error `error` ([`ViewSetup::around`] the
    /// reference).
    pub fn setup(&self, error: f64) -> ViewSetup {
        ViewSetup::from_box(
            DVec3::from_array(self.lo),
            DVec3::from_array(self.hi),
            DVec3::from_array(self.up),
            error,
        )
    }

    /// The estimated utility of variant `index` viewed at geometric error `error` (as
    /// [`Self::setup`] views it): `exp(-loss)` from the interpolated sums (`interpolate`).
    /// `None` where the variant was not compared.
    pub fn utility(&self, index: usize, error: f64) -> Option<f64> {
        let weighted = self.weighted.get(index)?.as_ref()?;
        let setup = self.setup(error);
        let radius = box_radius(setup.lo, setup.hi);
        let d = setup.eye_distance();
        let x = (d / radius).max(CURVE_DISTANCES[0]);
        let side = setup.window_side() as f64;
        let window = side * side;
        let norm = interpolate(&self.coverage, x)?.max(window) * frame() / window;
        let loss = interpolate(weighted, x)? / norm;
        Some((-loss).exp().clamp(0.0, 1.0))
    }
}

/// Pixels of the viewer's frame.
fn frame() -> f64 {
    DEFAULT_WIDTH as f64 * VIEWER_HEIGHT as f64
}

/// What one candidate splat differs from the reference splat by, independent of the distance.
#[derive(Clone, Copy)]
struct Diff {
    /// Weighted colour and opacity terms (view-averaged squared colour difference per channel,
    /// squared opacity difference): independent of the distance.
    fixed: f64,
    /// Weighted squared centre displacement (over the on-screen variance at a distance).
    position: f64,
    /// Scale differences per axis.
    scale: [f64; 3],
    /// Weighted squared rotation angle (times the squared anisotropy at a distance).
    rotation: f64,
}

/// The sums of every candidate against `reference` (tile-relative Best, viewed with `up`;
/// candidates in [`super::ALL`] order, `None` where not written) at [`CURVE_DISTANCES`], with
/// the per-splat quantities of [`super::estimate::features`] (summed in another order), so that a grid distance
/// gives its estimate. `None` when the reference has no splats.
pub fn loss_curve(
    reference: &Splats,
    up: DVec3,
    candidates: &[Option<&Splats>; 4],
) -> Option<LossCurve> {
    let (lo, hi) = reference.bounds()?;
    let radius = box_radius(DVec3::from_array(lo), DVec3::from_array(hi));
    let n = reference.len();
    let focal = viewer_focal();
    // Per grid distance: pixel size, dilation and window area, as `features` derives them.
    let grid: Vec<(f64, f64, f64)> = CURVE_DISTANCES
        .iter()
        .map(|&x| {
            let d = x * radius;
            let pixel = d / focal;
            let side = window_side(radius, d) as f64;
            (pixel, LOW_PASS * pixel * pixel, side * side)
        })
        .collect();
    let inv_4pi = 1.0 / (4.0 * std::f64::consts::PI);
    let compared: Vec<(usize, &Splats)> = candidates
        .iter()
        .enumerate()
        .filter_map(|(v, c)| c.filter(|c| c.len() == n).map(|c| (v, c)))
        .collect();
    let g = grid.len();
    // acc[candidate * g + grid]: the weighted sums; coverage per grid distance.
    let mut acc = vec![0.0f64; compared.len() * g];
    let mut coverage = vec![0.0f64; g];
    let mut diffs = vec![
        Diff {
            fixed: 0.0,
            position: 0.0,
            scale: [0.0; 3],
            rotation: 0.0,
        };
        compared.len()
    ];
    for i in 0..n {
        let s = reference.scales[i].map(|v| (v as f64).abs());
        let alpha = reference.opacities[i].clamp(0.0, 1.0) as f64;
        let q_ref = quat(reference.rotations[i]);
        for (diff, (_, cand)) in diffs.iter_mut().zip(&compared) {
            let c2 = colour_diff2(reference, cand, i);
            let da = alpha - cand.opacities[i].clamp(0.0, 1.0) as f64;
            let dp =
                DVec3::from_array(reference.positions[i]) - DVec3::from_array(cand.positions[i]);
            let sc = cand.scales[i].map(|v| (v as f64).abs());
            let angle = q_ref.angle_between(quat(cand.rotations[i]));
            *diff = Diff {
                fixed: WEIGHTS[0] * (c2 * inv_4pi / 3.0) + WEIGHTS[1] * (da * da),
                position: WEIGHTS[2] * dp.length_squared(),
                scale: [0, 1, 2].map(|a| s[a] - sc[a]),
                rotation: WEIGHTS[4] * angle * angle,
            };
        }
        // Adding the same dilation to every axis keeps their order: sort once per splat.
        let mut sorted_s2 = s.map(|v| v * v);
        sorted_s2.sort_by(f64::total_cmp);
        for (j, &(pixel, dilation, window)) in grid.iter().enumerate() {
            let var = s.map(|v| v * v + dilation);
            let sorted = sorted_s2.map(|v| v + dilation);
            let area =
                2.0 * std::f64::consts::PI * (sorted[1] * sorted[2]).sqrt() / (pixel * pixel);
            let w = alpha * area.min(window);
            if !(w.is_finite() && w > 0.0) {
                continue;
            }
            coverage[j] += w;
            let mean_var = (var[0] + var[1] + var[2]) / 3.0;
            let aniso = (sorted[2].sqrt() - sorted[0].sqrt()) / sorted[2].sqrt();
            let aniso2 = aniso * aniso;
            for (c, diff) in diffs.iter().enumerate() {
                // The features' weighted sum (`predicted_loss` before normalisation).
                let mut sum = diff.fixed + diff.position / mean_var + diff.rotation * aniso2;
                if WEIGHTS[3] != 0.0 {
                    let mut ds = 0.0;
                    for (d, v) in diff.scale.iter().zip(var) {
                        ds += d * d / v;
                    }
                    sum += WEIGHTS[3] * ds / 3.0;
                }
                acc[c * g + j] += w * sum;
            }
        }
    }
    let mut weighted: [Option<Vec<f64>>; 4] = Default::default();
    for (c, &(v, _)) in compared.iter().enumerate() {
        weighted[v] = Some(acc[c * g..(c + 1) * g].to_vec());
    }
    Some(LossCurve {
        lo,
        hi,
        up: up.to_array(),
        coverage,
        weighted,
    })
}

/// [`ViewSetup::window_side`] for a sphere of radius `r` seen from distance `d`.
fn window_side(r: f64, d: f64) -> u32 {
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

/// A normalised quaternion (identity for a degenerate one).
fn quat(q: [f32; 4]) -> DQuat {
    let q = DQuat::from_xyzw(q[0] as f64, q[1] as f64, q[2] as f64, q[3] as f64);
    if q.length_squared() > 0.0 && q.is_finite() {
        q.normalize()
    } else {
        DQuat::IDENTITY
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lod::eval::MAX_SSE;
    use crate::variants::estimate::estimated_utilities;
    use splat2tiles_core::splat::Splat;

    /// `n` splats of SH degree 1 from a xorshift generator, and a copy with every attribute
    /// perturbed (a stand-in for a quantised variant).
    fn pair(n: usize, seed: u64, step: f32) -> (Splats, Splats) {
        let mut x = seed;
        let mut f = move || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x >> 11) as f32 / (1u64 << 53) as f32
        };
        let (mut a, mut b) = (Splats::with_capacity(1, n), Splats::with_capacity(1, n));
        for _ in 0..n {
            let s = Splat {
                position: [f() as f64 * 4.0, f() as f64 * 2.0, f() as f64],
                scale: [0.002 + f() * 0.05, 0.002 + f() * 0.02, 0.001 + f() * 0.01],
                rotation: splat2tiles_core::splat::normalize_quat([f(), f() - 0.5, f(), 0.5]),
                opacity: f(),
                sh0: [f() - 0.5, f() - 0.5, f() - 0.5],
            };
            let rest = [[f() * 0.1; 3], [f() * 0.1; 3], [f() * 0.1; 3]];
            a.push(s, &rest);
            let mut q = s;
            q.position = s
                .position
                .map(|p| p + (f() - 0.5) as f64 * step as f64 * 0.01);
            q.scale = s.scale.map(|v| v * (1.0 + (f() - 0.5) * step));
            q.rotation =
                splat2tiles_core::splat::normalize_quat(s.rotation.map(|r| r + (f() - 0.5) * step));
            q.opacity = (s.opacity + (f() - 0.5) * step).clamp(0.0, 1.0);
            q.sh0 = s.sh0.map(|c| c + (f() - 0.5) * step);
            b.push(q, &rest.map(|r| r.map(|c| c + (f() - 0.5) * step)));
        }
        (a, b)
    }

    /// The geometric error that puts the eye at `x` radii.
    fn error_at(curve: &LossCurve, x: f64) -> f64 {
        let r = box_radius(DVec3::from_array(curve.lo), DVec3::from_array(curve.hi));
        (x - 1.0) * r * MAX_SSE / viewer_focal()
    }

    #[test]
    fn grid_distances_give_the_read_back_estimate() {
        let (a, b) = pair(3000, 7, 0.05);
        let up = DVec3::Z;
        let curve = loss_curve(&a, up, &[None, Some(&b), None, None]).unwrap();
        assert!(curve.weighted[0].is_none() && curve.weighted[2].is_none());
        for &x in &CURVE_DISTANCES[1..] {
            let e = error_at(&curve, x);
            let exact = estimated_utilities(&a, &[&b], &ViewSetup::around(&a, up, e).unwrap())[0];
            let got = curve.utility(1, e).unwrap();
            assert!(
                (got.ln() / exact.ln() - 1.0).abs() < 1e-6,
                "x {x}: curve {got} read back {exact}"
            );
        }
    }

    #[test]
    fn between_grid_distances_the_loss_is_interpolated_closely() {
        let (a, b) = pair(3000, 11, 0.05);
        let up = DVec3::Y;
        let curve = loss_curve(&a, up, &[None, None, Some(&b), None]).unwrap();
        let mut worst: f64 = 0.0;
        for x in [1.3, 2.9, 5.8, 11.0, 23.0, 50.0, 100.0, 300.0] {
            let e = error_at(&curve, x);
            let exact = estimated_utilities(&a, &[&b], &ViewSetup::around(&a, up, e).unwrap())[0];
            let got = curve.utility(2, e).unwrap();
            assert!(exact < 1.0 && got < 1.0);
            worst = worst.max((got.ln() / exact.ln() - 1.0).abs());
        }
        assert!(worst < 0.05, "worst relative loss error {worst}");
    }

    #[test]
    fn other_splats_are_not_compared() {
        let (a, b) = pair(100, 3, 0.05);
        let fewer = b.select(&(0..50).collect::<Vec<_>>());
        let curve = loss_curve(&a, DVec3::Z, &[None, Some(&fewer), Some(&a), None]).unwrap();
        assert_eq!(curve.utility(1, 0.1), None);
        assert!(curve.utility(2, 0.1).unwrap() > 1.0 - 1e-12);
        assert!(loss_curve(&Splats::with_capacity(0, 0), DVec3::Z, &[None; 4]).is_none());
    }
}
