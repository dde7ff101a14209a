//! Small generated scenes for the render tests: single splats, a deterministic random cloud, and
//! a camera at the origin looking down +z.

use glam::{DMat4, DVec3};
use splat2tiles_core::camera::Camera;
use splat2tiles_core::splat::{Splat, Splats, sh};

/// One splat with identity rotation and a colour given directly in [0, 1].
pub fn splat(pos: [f64; 3], scale: [f32; 3], opacity: f32, rgb: [f32; 3]) -> Splat {
    Splat {
        position: pos,
        scale,
        rotation: [0.0, 0.0, 0.0, 1.0],
        opacity,
        sh0: sh::color_to_sh0(rgb),
    }
}

/// A degree-0 set from splats.
pub fn set(items: &[Splat]) -> Splats {
    let mut s = Splats::new(0);
    for &it in items {
        s.push(it, &[]);
    }
    s
}

/// A `w x h` camera at the origin looking down +z (identity pose) with focal `f` and the
/// principal point at the centre of pixel `(w/2, h/2)` (so a splat on the axis lands there).
pub fn axis_camera(w: u32, h: u32, f: f64) -> Camera {
    Camera {
        width: w,
        height: h,
        fx: f,
        fy: f,
        cx: (w / 2) as f64 + 0.5,
        cy: (h / 2) as f64 + 0.5,
        world_from_camera: DMat4::IDENTITY,
    }
}

/// Deterministic pseudo-random numbers in [0, 1) (64-bit LCG).
pub struct Lcg(pub u64);

impl Lcg {
    /// Next value in [0, 1).
    pub fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// `n` random anisotropic splats of SH degree `deg` in a box of half-size 1 centred at `centre`,
/// with random non-zero higher SH.
pub fn random_cloud(n: usize, deg: u8, centre: DVec3, seed: u64) -> Splats {
    let mut r = Lcg(seed);
    let mut s = Splats::with_capacity(deg, n);
    let k = s.rest_per_splat();
    for _ in 0..n {
        let q = [
            r.next() - 0.5,
            r.next() - 0.5,
            r.next() - 0.5,
            r.next() - 0.5,
        ]
        .map(|v| v as f32);
        let item = Splat {
            position: [
                centre.x + 2.0 * r.next() - 1.0,
                centre.y + 2.0 * r.next() - 1.0,
                centre.z + 2.0 * r.next() - 1.0,
            ],
            scale: [
                0.02 + 0.1 * r.next(),
                0.02 + 0.1 * r.next(),
                0.01 + 0.05 * r.next(),
            ]
            .map(|v| v as f32),
            rotation: splat2tiles_core::splat::normalize_quat(q),
            opacity: (0.2 + 0.8 * r.next()) as f32,
            sh0: [r.next(), r.next(), r.next()].map(|v| ((v - 0.5) * 3.0) as f32),
        };
        let rest: Vec<[f32; 3]> = (0..k)
            .map(|_| [r.next(), r.next(), r.next()].map(|v| ((v - 0.5) * 0.6) as f32))
            .collect();
        s.push(item, &rest);
    }
    s
}
