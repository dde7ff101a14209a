//! SGSS priority weight (eqs. 9-10): density of Gaussians x share of the viewport over the
//! camera-space depth of the box centre, on a log10 scale; `P >= 1` means high fetch priority.

use super::geom::{Frustum, Obb};

/// Fraction of the viewport covered by the box's projection (the bounding rectangle of the
/// projected corners, clipped to the screen); boxes reaching behind the camera count as their
/// clipped rectangle with those corners pushed to the screen edge. This is `V_v^(c)` of eq. 9.
pub fn viewport_share(f: &Frustum, b: &Obb) -> f64 {
    let mut lo = [f64::MAX; 2];
    let mut hi = [f64::MIN; 2];
    let mut any_front = false;
    for c in b.corners() {
        let p = f.to_camera(c);
        let (u, v) = if p.z > 1e-9 {
            any_front = true;
            (p.x / (p.z * f.tx), p.y / (p.z * f.ty))
        } else {
            (p.x.signum() * 1e9, p.y.signum() * 1e9)
        };
        lo = [lo[0].min(u), lo[1].min(v)];
        hi = [hi[0].max(u), hi[1].max(v)];
    }
    if !any_front {
        return 0.0;
    }
    let w = (hi[0].min(1.0) - lo[0].max(-1.0)).max(0.0);
    let h = (hi[1].min(1.0) - lo[1].max(-1.0)).max(0.0);
    w * h / 4.0
}

/// Eq. 9: `PW = rho * V / (z + eps)` with `rho` = splats per cubic metre of the box and `z` the
/// camera-space depth of the box centre (clamped at 0).
pub fn priority_weight(f: &Frustum, b: &Obb, splats: u64) -> f64 {
    const EPS: f64 = 1e-3;
    let rho = splats as f64 / b.volume().max(1e-9);
    let z = f.to_camera(b.center).z.max(0.0);
    rho * viewport_share(f, b) / (z + EPS)
}

/// Eq. 10: `P = log10(PW)` (negative infinity for an invisible box).
pub fn priority(f: &Frustum, b: &Obb, splats: u64) -> f64 {
    priority_weight(f, b, splats).log10()
}
