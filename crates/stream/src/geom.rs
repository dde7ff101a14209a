//! Geometry of the client: camera poses (position + yaw/pitch, TileSplat's state), intrinsics,
//! oriented tile boxes and the view frustum, all in the tileset frame (z up).

use glam::{DMat4, DVec3};

/// A camera state at time `t`: position and heading (TileSplat sec. 3.3.1: `[p, theta]`, plus
/// pitch). Yaw is measured in the x-y plane from +x towards +y, pitch upwards from it (radians).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ViewPose {
    /// Seconds.
    pub t: f64,
    /// Position in the tileset frame (metres).
    pub pos: DVec3,
    /// Yaw in radians.
    pub yaw: f64,
    /// Pitch in radians (positive looks up).
    pub pitch: f64,
}

impl ViewPose {
    /// Unit viewing direction.
    pub fn forward(&self) -> DVec3 {
        let (sy, cy) = self.yaw.sin_cos();
        let (sp, cp) = self.pitch.sin_cos();
        DVec3::new(cp * cy, cp * sy, sp)
    }

    /// Camera axes (right, down, forward) in the OpenCV convention used by `render::Camera`.
    pub fn basis(&self) -> [DVec3; 3] {
        let z = self.forward();
        let mut x = z.cross(DVec3::Z);
        if x.length_squared() < 1e-18 {
            x = DVec3::new(self.yaw.sin(), -self.yaw.cos(), 0.0);
        }
        let x = x.normalize();
        let y = z.cross(x);
        [x, y, z]
    }

    /// World-from-camera pose (columns: right, down, forward, position).
    pub fn world_from_camera(&self) -> DMat4 {
        let [x, y, z] = self.basis();
        DMat4::from_cols(
            x.extend(0.0),
            y.extend(0.0),
            z.extend(0.0),
            self.pos.extend(1.0),
        )
    }

    /// A pose at `pos` looking at `target`.
    pub fn looking_at(t: f64, pos: DVec3, target: DVec3) -> ViewPose {
        let d = (target - pos).normalize_or(DVec3::X);
        ViewPose {
            t,
            pos,
            yaw: d.y.atan2(d.x),
            pitch: d.z.clamp(-1.0, 1.0).asin(),
        }
    }

    /// Linear interpolation (yaw along the shorter arc).
    pub fn lerp(&self, o: &ViewPose, s: f64) -> ViewPose {
        let dyaw = wrap_angle(o.yaw - self.yaw);
        ViewPose {
            t: self.t + (o.t - self.t) * s,
            pos: self.pos.lerp(o.pos, s),
            yaw: self.yaw + dyaw * s,
            pitch: self.pitch + (o.pitch - self.pitch) * s,
        }
    }
}

/// Wraps an angle to (-pi, pi].
pub fn wrap_angle(a: f64) -> f64 {
    let t = std::f64::consts::TAU;
    let mut r = a.rem_euclid(t);
    if r > std::f64::consts::PI {
        r -= t;
    }
    r
}

/// Camera intrinsics the client plans with.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Intrinsics {
    /// Vertical field of view, degrees.
    pub fov_y_deg: f64,
    /// Width / height.
    pub aspect: f64,
    /// Viewport height in pixels (for screen-space error).
    pub height_px: f64,
    /// Near plane distance.
    pub near: f64,
    /// Far plane distance.
    pub far: f64,
}

impl Default for Intrinsics {
    fn default() -> Self {
        Intrinsics {
            fov_y_deg: 50.0,
            aspect: 16.0 / 9.0,
            height_px: 720.0,
            near: 0.05,
            far: 1000.0,
        }
    }
}

impl Intrinsics {
    /// Focal length in pixels.
    pub fn focal_px(&self) -> f64 {
        self.height_px / (2.0 * (self.fov_y_deg.to_radians() * 0.5).tan())
    }
}

/// An oriented box: centre and three half-axis vectors (the 3D Tiles `box` layout).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Obb {
    /// Centre.
    pub center: DVec3,
    /// Half axes.
    pub half: [DVec3; 3],
}

impl Obb {
    /// From a 3D Tiles `box` (12 numbers).
    pub fn from_3dtiles(b: &[f64; 12]) -> Obb {
        Obb {
            center: DVec3::new(b[0], b[1], b[2]),
            half: [
                DVec3::new(b[3], b[4], b[5]),
                DVec3::new(b[6], b[7], b[8]),
                DVec3::new(b[9], b[10], b[11]),
            ],
        }
    }

    /// An axis-aligned box.
    pub fn aabb(lo: DVec3, hi: DVec3) -> Obb {
        let h = (hi - lo) * 0.5;
        Obb {
            center: (lo + hi) * 0.5,
            half: [
                DVec3::new(h.x, 0.0, 0.0),
                DVec3::new(0.0, h.y, 0.0),
                DVec3::new(0.0, 0.0, h.z),
            ],
        }
    }

    /// The 8 corners.
    pub fn corners(&self) -> [DVec3; 8] {
        std::array::from_fn(|i| {
            let s = |k: usize| if i >> k & 1 == 1 { 1.0 } else { -1.0 };
            self.center + self.half[0] * s(0) + self.half[1] * s(1) + self.half[2] * s(2)
        })
    }

    /// Volume.
    pub fn volume(&self) -> f64 {
        8.0 * self.half[0].cross(self.half[1]).dot(self.half[2]).abs()
    }

    /// Radius of the bounding sphere.
    pub fn radius(&self) -> f64 {
        (self.half[0] + self.half[1] + self.half[2])
            .length()
            .max((self.half[0] - self.half[1] + self.half[2]).length())
            .max((self.half[0] + self.half[1] - self.half[2]).length())
            .max((-self.half[0] + self.half[1] + self.half[2]).length())
    }

    /// Distance from `p` to the box (0 inside).
    pub fn distance(&self, p: DVec3) -> f64 {
        let d = p - self.center;
        let mut q = DVec3::ZERO;
        let mut acc = 0.0;
        for a in &self.half {
            let len = a.length();
            if len < 1e-12 {
                continue;
            }
            let u = a / len;
            let c = d.dot(u);
            let excess = (c.abs() - len).max(0.0);
            acc += excess * excess;
            q += u * c;
        }
        // Component of d orthogonal to all axes (degenerate boxes) counts fully.
        let ortho = (d - q).length_squared();
        (acc + ortho.max(0.0)).sqrt()
    }

    /// Axis-aligned bounds.
    pub fn aabb_bounds(&self) -> (DVec3, DVec3) {
        let e = self.half[0].abs() + self.half[1].abs() + self.half[2].abs();
        (self.center - e, self.center + e)
    }
}

/// A view frustum (pyramid cut by near and far planes) in the tileset frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frustum {
    /// Apex (camera centre).
    pub apex: DVec3,
    /// Right, down, forward unit axes.
    pub axes: [DVec3; 3],
    /// tan of the half horizontal field of view.
    pub tx: f64,
    /// tan of the half vertical field of view.
    pub ty: f64,
    /// Near distance.
    pub near: f64,
    /// Far distance.
    pub far: f64,
    /// Inward plane normals and offsets (n . p + d >= 0 inside): near, far, left, right, top,
    /// bottom.
    pub planes: [(DVec3, f64); 6],
}

impl Frustum {
    /// The frustum of a pose with given intrinsics.
    pub fn new(pose: &ViewPose, k: &Intrinsics) -> Frustum {
        let axes = pose.basis();
        let ty = (k.fov_y_deg.to_radians() * 0.5).tan();
        let tx = ty * k.aspect;
        let [r, d, f] = axes;
        let a = pose.pos;
        let plane = |n: DVec3| {
            let n = n.normalize();
            (n, -n.dot(a))
        };
        let near_n = f;
        let far_n = -f;
        let planes = [
            (near_n, -near_n.dot(a) - k.near),
            (far_n, -far_n.dot(a) + k.far),
            plane(r + f * tx),  // x >= -z tx
            plane(-r + f * tx), // x <= z tx
            plane(d + f * ty),
            plane(-d + f * ty),
        ];
        Frustum {
            apex: a,
            axes,
            tx,
            ty,
            near: k.near,
            far: k.far,
            planes,
        }
    }

    /// World point to camera coordinates (x right, y down, z forward).
    pub fn to_camera(&self, p: DVec3) -> DVec3 {
        let v = p - self.apex;
        DVec3::new(
            v.dot(self.axes[0]),
            v.dot(self.axes[1]),
            v.dot(self.axes[2]),
        )
    }

    /// Whether a point is inside.
    pub fn contains(&self, p: DVec3) -> bool {
        self.planes.iter().all(|(n, d)| n.dot(p) + d >= 0.0)
    }

    /// The 8 corners in camera coordinates (near 4, then far 4).
    pub fn camera_corners(&self) -> [DVec3; 8] {
        std::array::from_fn(|i| {
            let z = if i < 4 { self.near } else { self.far };
            let sx = if i & 1 == 1 { 1.0 } else { -1.0 };
            let sy = if i & 2 == 2 { 1.0 } else { -1.0 };
            DVec3::new(sx * z * self.tx, sy * z * self.ty, z)
        })
    }
}
