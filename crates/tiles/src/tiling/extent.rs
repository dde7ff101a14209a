//! The visible reach of splats: half extents, along the tileset frame's axes, of the box around
//! the part of each splat's ellipsoid a renderer draws, so tile boxes and regions enclose it.

use glam::{DMat3, DQuat, DVec3};
use rayon::prelude::*;
use splat2tiles_core::splat::Splats;

/// Sigmas out to which a splat of `opacity` is drawn: the 3-sigma footprint of the 3DGS
/// rasterizers, cut where opacity * exp(-k^2 / 2) falls under 1/255 (fragments below that are
/// skipped), so k = min(3, sqrt(2 ln(255 opacity))), and 0 for splats never visible.
pub fn visible_sigmas(opacity: f32) -> f64 {
    let a = 255.0 * opacity as f64;
    if a.is_finite() && a > 1.0 {
        (2.0 * a.ln()).sqrt().min(3.0)
    } else {
        0.0
    }
}

/// Half extents along the axes of the frame `a` maps into of the box around the visible part
/// (see [`visible_sigmas`]) of the ellipsoid of a splat with linear `scale`, unit `rotation`
/// (x, y, z, w) given in the source frame, and `opacity`. Zero for non-finite input.
pub fn reach(a: DMat3, scale: [f32; 3], rotation: [f32; 4], opacity: f32) -> DVec3 {
    let q = DQuat::from_xyzw(
        rotation[0] as f64,
        rotation[1] as f64,
        rotation[2] as f64,
        rotation[3] as f64,
    );
    let len = q.length();
    let q = if len.is_finite() && len > 0.0 {
        q / len
    } else {
        DQuat::IDENTITY
    };
    // M maps the unit sphere onto the 1-sigma ellipsoid in the target frame; the ellipsoid's
    // half extent along axis i is the length of row i of M.
    let s = DVec3::new(scale[0] as f64, scale[1] as f64, scale[2] as f64).abs();
    let m = a * DMat3::from_quat(q) * DMat3::from_diagonal(s);
    let r = m.transpose();
    let e = visible_sigmas(opacity)
        * DVec3::new(r.x_axis.length(), r.y_axis.length(), r.z_axis.length());
    if e.is_finite() { e } else { DVec3::ZERO }
}

/// [`reach`] of every splat of `splats` in the frame `a` maps into.
pub fn reaches(splats: &Splats, a: DMat3) -> Vec<DVec3> {
    splats
        .scales
        .par_iter()
        .zip(splats.rotations.par_iter())
        .zip(splats.opacities.par_iter())
        .map(|((s, r), o)| reach(a, *s, *r, *o))
        .collect()
}

/// Box (min, max) around centres `pts` widened by their reaches `ext` (same length).
pub fn reach_bounds(pts: &[DVec3], ext: &[DVec3]) -> (DVec3, DVec3) {
    pts.iter().zip(ext).fold(
        (DVec3::splat(f64::MAX), DVec3::splat(f64::MIN)),
        |(lo, hi), (p, e)| (lo.min(*p - *e), hi.max(*p + *e)),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn axis_aligned_and_rotated_reach() {
        let e = reach(DMat3::IDENTITY, [1.0, 2.0, 0.5], [0.0, 0.0, 0.0, 1.0], 1.0);
        assert!((e - DVec3::new(3.0, 6.0, 1.5)).length() < 1e-12, "{e}");
        // A quarter turn about z swaps the x and y extents.
        let h = std::f64::consts::FRAC_1_SQRT_2 as f32;
        let e = reach(DMat3::IDENTITY, [1.0, 2.0, 0.5], [0.0, 0.0, h, h], 1.0);
        assert!((e - DVec3::new(6.0, 3.0, 1.5)).length() < 1e-5, "{e}");
        // The frame rotation applies too (y-down source, z-up target: y extent goes to z).
        let a = DMat3::from_rotation_x(-std::f64::consts::FRAC_PI_2);
        let e = reach(a, [1.0, 2.0, 0.5], [0.0, 0.0, 0.0, 1.0], 1.0);
        assert!((e - DVec3::new(3.0, 1.5, 6.0)).length() < 1e-12, "{e}");
        // 45 deg about z: a sphere's box stays the same, an ellipse's grows on both axes.
        let q = glam::Quat::from_rotation_z(std::f32::consts::FRAC_PI_4);
        let e = reach(DMat3::IDENTITY, [1.0, 0.0, 0.0], q.to_array(), 1.0);
        let want = 3.0 * std::f64::consts::FRAC_1_SQRT_2;
        assert!((e.x - want).abs() < 1e-6 && (e.y - want).abs() < 1e-6 && e.z.abs() < 1e-9);
        // Garbage in: no reach, never NaN.
        let e = reach(
            DMat3::IDENTITY,
            [f32::NAN, 1.0, 1.0],
            [0.0, 0.0, 0.0, 0.0],
            1.0,
        );
        assert_eq!(e, DVec3::ZERO);
        // Faint splats are drawn less far; invisible ones not at all.
        assert_eq!(visible_sigmas(1.0), 3.0);
        let k = visible_sigmas(0.05);
        assert!(
            (k - (2.0 * (255.0f64 * 0.05).ln()).sqrt()).abs() < 1e-6 && k < 2.3,
            "{k}"
        );
        assert!((0.05 * (-k * k / 2.0).exp() - 1.0 / 255.0).abs() < 1e-6);
        assert_eq!(visible_sigmas(0.003), 0.0);
        let e = reach(DMat3::IDENTITY, [1.0, 1.0, 1.0], [0.0, 0.0, 0.0, 1.0], 0.05);
        assert!((e.x - k).abs() < 1e-6);
    }

    #[test]
    fn bounds_enclose_every_reach() {
        let pts = [DVec3::new(0.0, 0.0, 0.0), DVec3::new(10.0, -2.0, 1.0)];
        let ext = [DVec3::splat(1.0), DVec3::new(0.5, 3.0, 0.0)];
        let (lo, hi) = reach_bounds(&pts, &ext);
        assert_eq!(lo, DVec3::new(-1.0, -5.0, -1.0));
        assert_eq!(hi, DVec3::new(10.5, 1.0, 1.0));
    }
}
