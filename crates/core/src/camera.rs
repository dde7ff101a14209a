//! Pinhole cameras for the reference renderer: OpenCV-style frame (x right, y down, z forward),
//! world-from-camera poses, look-at, the trainer's `cameras.json`, and automatic viewpoints.

use glam::{DMat3, DMat4, DVec3};
use serde::Deserialize;

/// Default image width of [`auto_views`] cameras.
pub const DEFAULT_WIDTH: u32 = 1280;
/// Default image height of [`auto_views`] cameras.
pub const DEFAULT_HEIGHT: u32 = 720;
/// Default vertical field of view of [`auto_views`] cameras, in degrees.
pub const DEFAULT_FOV_Y_DEG: f64 = 50.0;
/// Elevation of the [`auto_views`] viewpoints above the box centre's horizontal plane, in degrees.
pub const AUTO_VIEW_ELEVATION_DEG: f64 = 30.0;
/// Number of [`auto_views`] viewpoints (TileSplat §3.2.2 renders "from 8 viewpoints").
pub const AUTO_VIEW_COUNT: usize = 8;

/// A pinhole camera.
///
/// Convention (the 3DGS trainer's and COLMAP's, called OpenCV-style): in the camera frame x points
/// right, y points **down** and z points **forward** (into the scene); a point is visible when its
/// camera-space z is positive. `world_from_camera` is a rigid transform whose columns are the
/// camera axes and centre in world coordinates. Pixel `(i, j)` covers `[i, i+1) x [j, j+1)` in
/// continuous image coordinates, so its centre is `(i + 0.5, j + 0.5)`; a camera-space point
/// `(x, y, z)` lands at `(fx * x / z + cx, fy * y / z + cy)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Focal length along x, in pixels.
    pub fx: f64,
    /// Focal length along y, in pixels.
    pub fy: f64,
    /// Principal point x in continuous image coordinates (`width / 2` when centred).
    pub cx: f64,
    /// Principal point y in continuous image coordinates (`height / 2` when centred).
    pub cy: f64,
    /// Rigid pose mapping camera coordinates to world coordinates.
    pub world_from_camera: DMat4,
}

/// Focal length in pixels for a field of view (degrees) spanning `size` pixels.
pub fn fov_to_focal(fov_deg: f64, size: u32) -> f64 {
    size as f64 / (2.0 * (fov_deg.to_radians() * 0.5).tan())
}

/// Field of view in degrees spanned by `size` pixels at focal length `focal`.
pub fn focal_to_fov(focal: f64, size: u32) -> f64 {
    2.0 * (size as f64 / (2.0 * focal)).atan().to_degrees()
}

impl Camera {
    /// A camera with a centred principal point, square pixels and the given vertical field of view.
    pub fn from_pose(width: u32, height: u32, fov_y_deg: f64, world_from_camera: DMat4) -> Self {
        let f = fov_to_focal(fov_y_deg, height);
        Camera {
            width,
            height,
            fx: f,
            fy: f,
            cx: width as f64 * 0.5,
            cy: height as f64 * 0.5,
            world_from_camera,
        }
    }

    /// A camera at `eye` looking at `target`, with image "up" (-y) as close to `up` as possible.
    /// Falls back to another up vector when `up` is parallel to the viewing direction.
    pub fn look_at(
        width: u32,
        height: u32,
        fov_y_deg: f64,
        eye: DVec3,
        target: DVec3,
        up: DVec3,
    ) -> Self {
        Camera::from_pose(width, height, fov_y_deg, look_at_pose(eye, target, up))
    }

    /// Camera centre in world coordinates.
    pub fn center(&self) -> DVec3 {
        self.world_from_camera.w_axis.truncate()
    }

    /// Rotation part of the pose (columns: camera x, y, z axes in world coordinates).
    pub fn rotation(&self) -> DMat3 {
        DMat3::from_mat4(self.world_from_camera)
    }

    /// Vertical field of view in degrees.
    pub fn fov_y_deg(&self) -> f64 {
        focal_to_fov(self.fy, self.height)
    }

    /// The same view at another resolution: focal lengths and principal point scale with it.
    pub fn resized(&self, width: u32, height: u32) -> Self {
        let sx = width as f64 / self.width as f64;
        let sy = height as f64 / self.height as f64;
        Camera {
            width,
            height,
            fx: self.fx * sx,
            fy: self.fy * sy,
            cx: self.cx * sx,
            cy: self.cy * sy,
            world_from_camera: self.world_from_camera,
        }
    }

    /// Projects a world point to continuous image coordinates, `None` behind the camera.
    pub fn project(&self, p: DVec3) -> Option<[f64; 2]> {
        let c = self.rotation().transpose() * (p - self.center());
        (c.z > 0.0).then(|| [self.fx * c.x / c.z + self.cx, self.fy * c.y / c.z + self.cy])
    }
}

/// World-from-camera pose for a camera at `eye` looking at `target` (OpenCV-style axes).
pub fn look_at_pose(eye: DVec3, target: DVec3, up: DVec3) -> DMat4 {
    let z = (target - eye).normalize_or(DVec3::Z);
    let mut x = z.cross(up);
    if x.length_squared() < 1e-20 {
        // Looking along `up`: any perpendicular will do; pick one deterministically.
        x = z.cross(z.any_orthonormal_vector());
    }
    let x = x.normalize();
    let y = z.cross(x);
    DMat4::from_cols(x.extend(0.0), y.extend(0.0), z.extend(0.0), eye.extend(1.0))
}

/// One entry of the 3DGS trainer's `cameras.json`.
#[derive(Debug, Clone, Deserialize)]
pub struct CameraJson {
    /// Camera index.
    pub id: i64,
    /// Source image name.
    #[serde(default)]
    pub img_name: String,
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Camera centre in world coordinates.
    pub position: [f64; 3],
    /// World-from-camera rotation, listed by rows.
    pub rotation: [[f64; 3]; 3],
    /// Focal length along x, pixels.
    pub fx: f64,
    /// Focal length along y, pixels.
    pub fy: f64,
}

impl CameraJson {
    /// The camera this entry describes (principal point at the image centre).
    pub fn to_camera(&self) -> Camera {
        let r = self.rotation;
        let col = |j: usize| DVec3::new(r[0][j], r[1][j], r[2][j]);
        let pose = DMat4::from_cols(
            col(0).extend(0.0),
            col(1).extend(0.0),
            col(2).extend(0.0),
            DVec3::from(self.position).extend(1.0),
        );
        Camera {
            width: self.width,
            height: self.height,
            fx: self.fx,
            fy: self.fy,
            cx: self.width as f64 * 0.5,
            cy: self.height as f64 * 0.5,
            world_from_camera: pose,
        }
    }
}

/// Parses the trainer's `cameras.json` (a JSON list of [`CameraJson`]).
pub fn parse_cameras_json(text: &str) -> Result<Vec<CameraJson>, serde_json::Error> {
    serde_json::from_str(text)
}

/// The 8 automatic viewpoints around a box at the default size (1280x720, 50 deg vertical fov).
/// See [`auto_views_with`].
pub fn auto_views(bounds_min: DVec3, bounds_max: DVec3, up: DVec3) -> Vec<Camera> {
    auto_views_with(
        bounds_min,
        bounds_max,
        up,
        DEFAULT_WIDTH,
        DEFAULT_HEIGHT,
        DEFAULT_FOV_Y_DEG,
    )
}

/// The 8 automatic viewpoints around an axis-aligned box.
///
/// TileSplat (§3.2.2, eq. 3) scores a tile by the mean SSIM over "8 viewpoints" without saying
/// where they are; this is our definition. With `u` = normalised `up`, `e1` = the world axis
/// least aligned with `u` (ties: x before y before z, positive sign) made orthogonal to `u`, and
/// `e2 = u x e1`, view `k` (0..8) sits at azimuth `45 k` degrees (from `e1` towards `e2`) and
/// elevation 30 degrees above the box centre `c`, at distance `d = r / sin(f / 2)` from `c`, where
/// `r` is half the box diagonal and `f` the smaller of the horizontal and vertical fields of view:
/// the box's bounding sphere exactly fits the view. Each camera looks at `c` with image-up along
/// `u`. A degenerate box (a point) gets `r = 1`.
pub fn auto_views_with(
    bounds_min: DVec3,
    bounds_max: DVec3,
    up: DVec3,
    width: u32,
    height: u32,
    fov_y_deg: f64,
) -> Vec<Camera> {
    let c = (bounds_min + bounds_max) * 0.5;
    let r = box_radius(bounds_min, bounds_max);
    let fy = fov_y_deg.to_radians();
    let fx = 2.0 * ((width as f64 / height as f64) * (fy * 0.5).tan()).atan();
    let dist = r / (fx.min(fy) * 0.5).sin();
    orbit_views(c, up, dist, width, height, fov_y_deg)
}

/// Half the diagonal of a box, 1 for a degenerate or non-finite box (the radius
/// [`auto_views_with`] frames).
pub fn box_radius(bounds_min: DVec3, bounds_max: DVec3) -> f64 {
    let r = (bounds_max - bounds_min).length() * 0.5;
    if r.is_finite() && r > 0.0 { r } else { 1.0 }
}

/// The 8 viewpoints of [`auto_views_with`] at distance `dist` from `centre`: azimuth `45 k`
/// degrees from `e1` towards `e2`, elevation 30 degrees, looking at `centre` with image-up
/// along `up`.
pub fn orbit_views(
    centre: DVec3,
    up: DVec3,
    dist: f64,
    width: u32,
    height: u32,
    fov_y_deg: f64,
) -> Vec<Camera> {
    let u = up.normalize_or(DVec3::Z);
    let axes = [DVec3::X, DVec3::Y, DVec3::Z];
    let mut a = axes[0];
    for &cand in &axes[1..] {
        if cand.dot(u).abs() < a.dot(u).abs() - 1e-12 {
            a = cand;
        }
    }
    let e1 = (a - a.dot(u) * u).normalize();
    let e2 = u.cross(e1);
    let el = AUTO_VIEW_ELEVATION_DEG.to_radians();
    (0..AUTO_VIEW_COUNT)
        .map(|k| {
            let az = (k as f64 * 45.0).to_radians();
            let h = az.cos() * e1 + az.sin() * e2;
            let eye = centre + dist * (el.cos() * h + el.sin() * u);
            Camera::look_at(width, height, fov_y_deg, eye, centre, u)
        })
        .collect()
}

/// Parses an axis name `+x`, `-x`, `+y`, `-y`, `+z`, `-z` (the sign may be omitted for `+`).
pub fn parse_axis(s: &str) -> Option<DVec3> {
    let s = s.trim();
    let (sign, name) = match s.as_bytes().first()? {
        b'-' => (-1.0, &s[1..]),
        b'+' => (1.0, &s[1..]),
        _ => (1.0, s),
    };
    let v = match name {
        "x" | "X" => DVec3::X,
        "y" | "Y" => DVec3::Y,
        "z" | "Z" => DVec3::Z,
        _ => return None,
    };
    Some(v * sign)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn look_at_axes_follow_opencv_convention() {
        // Eye on -z looking at the origin (+z) with +y up: camera y = world -y, and right-handed
        // x = y cross z = world -x (looking down +z, world +x is on the left).
        let cam = Camera::look_at(100, 80, 60.0, -5.0 * DVec3::Z, DVec3::ZERO, DVec3::Y);
        let r = cam.rotation();
        assert!((r.x_axis + DVec3::X).length() < 1e-12, "{:?}", r.x_axis);
        assert!((r.y_axis + DVec3::Y).length() < 1e-12, "{:?}", r.y_axis);
        assert!((r.z_axis - DVec3::Z).length() < 1e-12, "{:?}", r.z_axis);
        // The target lands on the principal point; a point above it (world +y) lands higher
        // in the image (smaller row), world -x lands to the right.
        let p = cam.project(DVec3::ZERO).unwrap();
        assert_eq!(p, [50.0, 40.0]);
        assert!(cam.project(DVec3::Y).unwrap()[1] < 40.0);
        assert!(cam.project(-DVec3::X).unwrap()[0] > 50.0);
        assert!((r.determinant() - 1.0).abs() < 1e-12, "right-handed");
        assert!(cam.project(-10.0 * DVec3::Z).is_none());
        assert!((cam.fov_y_deg() - 60.0).abs() < 1e-9);
    }

    #[test]
    fn look_at_along_up_is_finite() {
        let pose = look_at_pose(DVec3::Z * 3.0, DVec3::ZERO, DVec3::Z);
        assert!(pose.to_cols_array().iter().all(|v| v.is_finite()));
        let r = DMat3::from_mat4(pose);
        assert!((r.transpose() * r - DMat3::IDENTITY).abs_diff_eq(DMat3::ZERO, 1e-12));
    }

    #[test]
    fn cameras_json_rows_are_world_from_camera() {
        // A camera at (1,2,3) whose rotation is 90 degrees about world y (rows listed).
        let text = r#"[{"id": 0, "img_name": "a", "width": 64, "height": 48,
            "position": [1.0, 2.0, 3.0],
            "rotation": [[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]],
            "fx": 50.0, "fy": 51.0}]"#;
        let cams = parse_cameras_json(text).unwrap();
        let cam = cams[0].to_camera();
        assert_eq!(cam.center(), DVec3::new(1.0, 2.0, 3.0));
        // Camera forward (z) = third column = world (1, 0, 0).
        assert_eq!(cam.rotation().z_axis, DVec3::X);
        let p = cam.project(DVec3::new(11.0, 2.0, 3.0)).unwrap();
        assert_eq!(p, [32.0, 24.0]);
        assert_eq!((cam.fx, cam.fy), (50.0, 51.0));
    }

    #[test]
    fn auto_views_frame_the_box() {
        let lo = DVec3::new(-1.0, -2.0, -0.5);
        let hi = DVec3::new(3.0, 1.0, 0.5);
        for up in [DVec3::Z, -DVec3::Y, DVec3::X] {
            let views = auto_views_with(lo, hi, up, 320, 240, 50.0);
            assert_eq!(views.len(), 8);
            let c = (lo + hi) * 0.5;
            for (k, v) in views.iter().enumerate() {
                // Looks at the centre, sits 30 degrees above it.
                let p = v.project(c).unwrap();
                assert!((p[0] - 160.0).abs() < 1e-9 && (p[1] - 120.0).abs() < 1e-9);
                let dir = (v.center() - c).normalize();
                let el = dir.dot(up).asin().to_degrees();
                assert!((el - 30.0).abs() < 1e-9, "view {k}: elevation {el}");
                // Every box corner is inside the image.
                for i in 0..8 {
                    let corner = DVec3::new(
                        if i & 1 == 0 { lo.x } else { hi.x },
                        if i & 2 == 0 { lo.y } else { hi.y },
                        if i & 4 == 0 { lo.z } else { hi.z },
                    );
                    let q = v.project(corner).unwrap();
                    assert!((0.0..=320.0).contains(&q[0]) && (0.0..=240.0).contains(&q[1]));
                }
                // Image up is along `up`: a point above the centre has a smaller row.
                assert!(v.project(c + 0.1 * up).unwrap()[1] < 120.0);
            }
            // Successive views are 45 degrees apart in azimuth.
            let h = |v: &Camera| {
                let d = v.center() - c;
                (d - d.dot(up) * up).normalize()
            };
            let cos = h(&views[0]).dot(h(&views[1]));
            assert!((cos - 45f64.to_radians().cos()).abs() < 1e-9);
        }
    }

    #[test]
    fn axis_names() {
        assert_eq!(parse_axis("-y"), Some(-DVec3::Y));
        assert_eq!(parse_axis("+z"), Some(DVec3::Z));
        assert_eq!(parse_axis("x"), Some(DVec3::X));
        assert_eq!(parse_axis("w"), None);
        assert_eq!(parse_axis(""), None);
    }
}
