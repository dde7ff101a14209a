//! The 3-sigma reach of splats: half extents, along the tileset frame's axes, of the box around
//! each splat's 3-sigma ellipsoid, so tile boxes and regions enclose what renderers draw.

use crate::splat::Splats;
use glam::{DMat3, DQuat, DVec3};
use rayon::prelude::*;

/// Half extents along the axes of the frame `a` maps into of the box around the 3-sigma ellipsoid
/// of a splat with linear `scale` and unit `rotation` (x, y, z, w) given in the source frame.
/// Zero for non-finite input.
pub fn reach(a: DMat3, scale: [f32; 3], rotation: [f32; 4]) -> DVec3 {
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
    let e = 3.0 * DVec3::new(r.x_axis.length(), r.y_axis.length(), r.z_axis.length());
    if e.is_finite() { e } else { DVec3::ZERO }
}

/// [`reach`] of every splat of `splats` in the frame `a` maps into.
pub fn reaches(splats: &Splats, a: DMat3) -> Vec<DVec3> {
    splats
        .scales
        .par_iter()
        .zip(splats.rotations.par_iter())
        .map(|(s, r)| reach(a, *s, *r))
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
        let e = reach(DMat3::IDENTITY, [1.0, 2.0, 0.5], [0.0, 0.0, 0.0, 1.0]);
        assert!((e - DVec3::new(3.0, 6.0, 1.5)).length() < 1e-12, "{e}");
        // A quarter turn about z swaps the x and y extents.
        let h = std::f64::consts::FRAC_1_SQRT_2 as f32;
        let e = reach(DMat3::IDENTITY, [1.0, 2.0, 0.5], [0.0, 0.0, h, h]);
        assert!((e - DVec3::new(6.0, 3.0, 1.5)).length() < 1e-5, "{e}");
        // The frame rotation applies too (y-down source, z-up target: y extent goes to z).
        let a = DMat3::from_rotation_x(-std::f64::consts::FRAC_PI_2);
        let e = reach(a, [1.0, 2.0, 0.5], [0.0, 0.0, 0.0, 1.0]);
        assert!((e - DVec3::new(3.0, 1.5, 6.0)).length() < 1e-12, "{e}");
        // 45 deg about z: a sphere's box stays the same, an ellipse's grows on both axes.
        let q = glam::Quat::from_rotation_z(std::f32::consts::FRAC_PI_4);
        let e = reach(DMat3::IDENTITY, [1.0, 0.0, 0.0], q.to_array());
        let want = 3.0 * std::f64::consts::FRAC_1_SQRT_2;
        assert!((e.x - want).abs() < 1e-6 && (e.y - want).abs() < 1e-6 && e.z.abs() < 1e-9);
        // Garbage in: no reach, never NaN.
        let e = reach(DMat3::IDENTITY, [f32::NAN, 1.0, 1.0], [0.0, 0.0, 0.0, 0.0]);
        assert_eq!(e, DVec3::ZERO);
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
