//! First-person camera controls of the web viewer: WASD/QE movement (walk or fly, speed relative
//! to the height above the content) and yaw/pitch looking around the scene's up axis.

use glam::DVec3;
use splat2tiles_core::camera::Camera;
use std::collections::HashSet;

/// Pitch stays this far from straight up/down so the view basis never degenerates.
const MAX_PITCH_DEG: f64 = 89.0;
pub use splat2tiles_viewer::nav::{MIN_SPEED_HEIGHT, Mode, SPEED_PER_HEIGHT};

/// A first-person camera: eye, yaw/pitch about `up`, held keys, image size and field of view.
#[derive(Debug, Clone)]
pub struct FirstPerson {
    /// Eye position (world).
    pub eye: DVec3,
    /// Heading in degrees about `up` (0 along `east`).
    pub yaw_deg: f64,
    /// Elevation in degrees above the horizontal plane.
    pub pitch_deg: f64,
    /// World up (unit).
    pub up: DVec3,
    east: DVec3,
    north: DVec3,
    /// Height of the content's ground along `up` (`up . p` of its lowest point).
    pub ground: f64,
    /// Walk or fly.
    pub mode: Mode,
    /// Image size.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Vertical field of view, degrees.
    pub fov_y_deg: f64,
    keys: HashSet<String>,
    fast: bool,
    /// The camera given at construction, used verbatim until the user moves or looks.
    exact: Option<Camera>,
}

impl FirstPerson {
    /// Controls starting at `camera` (its eye and viewing direction) with `up` as the world up and
    /// the content's ground at `up . p == ground`; flying.
    pub fn from_camera(camera: &Camera, up: DVec3, fov_y_deg: f64, ground: f64) -> Self {
        let up = up.try_normalize().unwrap_or(DVec3::Z);
        let helper = if up.x.abs() < 0.9 { DVec3::X } else { DVec3::Y };
        let east = (helper - up * helper.dot(up)).normalize();
        let north = up.cross(east);
        let forward = camera.world_from_camera.z_axis.truncate();
        let forward = forward.try_normalize().unwrap_or(north);
        let pitch = forward.dot(up).clamp(-1.0, 1.0).asin().to_degrees();
        let yaw = forward.dot(north).atan2(forward.dot(east)).to_degrees();
        FirstPerson {
            eye: camera.center(),
            yaw_deg: yaw,
            pitch_deg: pitch.clamp(-MAX_PITCH_DEG, MAX_PITCH_DEG),
            up,
            east,
            north,
            ground: if ground.is_finite() { ground } else { 0.0 },
            mode: Mode::Fly,
            width: camera.width,
            height: camera.height,
            fov_y_deg,
            keys: HashSet::new(),
            fast: false,
            exact: Some(*camera),
        }
    }

    /// Unit viewing direction.
    pub fn forward(&self) -> DVec3 {
        let (y, p) = (self.yaw_deg.to_radians(), self.pitch_deg.to_radians());
        (self.east * y.cos() + self.north * y.sin()) * p.cos() + self.up * p.sin()
    }

    /// Height of the eye above the content's ground, metres.
    pub fn height_above_ground(&self) -> f64 {
        self.eye.dot(self.up) - self.ground
    }

    /// Movement speed in world units per second without Shift: proportional to the height above
    /// the ground, at least [`MIN_SPEED_HEIGHT`]'s.
    pub fn speed(&self) -> f64 {
        splat2tiles_viewer::nav::speed_at(self.height_above_ground())
    }

    /// Switches between walking and flying.
    pub fn toggle_mode(&mut self) {
        self.mode = self.mode.toggled();
    }

    /// Records a key press or release (`KeyboardEvent.code` names: "KeyW", "KeyQ", ...).
    pub fn key(&mut self, code: &str, down: bool, shift: bool) {
        self.fast = shift;
        if down {
            self.keys.insert(code.to_string());
        } else {
            self.keys.remove(code);
        }
    }

    /// Forgets every held key (the window lost focus).
    pub fn release_keys(&mut self) {
        self.keys.clear();
    }

    /// Turns by `dyaw` degrees (positive: to the left) and `dpitch` degrees (positive: up).
    pub fn look(&mut self, dyaw_deg: f64, dpitch_deg: f64) {
        if !(dyaw_deg.is_finite() && dpitch_deg.is_finite()) {
            return;
        }
        if dyaw_deg == 0.0 && dpitch_deg == 0.0 {
            return;
        }
        self.exact = None;
        self.yaw_deg = (self.yaw_deg + dyaw_deg).rem_euclid(360.0);
        self.pitch_deg = (self.pitch_deg + dpitch_deg).clamp(-MAX_PITCH_DEG, MAX_PITCH_DEG);
    }

    /// Moves for `dt` seconds with the held keys; true when the eye moved.
    pub fn advance(&mut self, dt: f64) -> bool {
        if !(dt.is_finite() && dt > 0.0) {
            return false;
        }
        let y = self.yaw_deg.to_radians();
        let level = self.east * y.cos() + self.north * y.sin();
        let (f, vertical) = match self.mode {
            Mode::Walk => (level, DVec3::ZERO),
            Mode::Fly => (self.forward(), self.up),
        };
        let right = level.cross(self.up).try_normalize().unwrap_or(self.east);
        let mut dir = DVec3::ZERO;
        for (code, d) in [
            ("KeyW", f),
            ("KeyS", -f),
            ("KeyD", right),
            ("KeyA", -right),
            ("KeyE", vertical),
            ("KeyQ", -vertical),
        ] {
            if self.keys.contains(code) {
                dir += d;
            }
        }
        let Some(dir) = dir.try_normalize() else {
            return false;
        };
        let speed = self.speed() * if self.fast { 4.0 } else { 1.0 };
        self.eye += dir * speed * dt.min(0.25);
        self.exact = None;
        true
    }

    /// Changes the image size, keeping the view.
    pub fn resize(&mut self, width: u32, height: u32) {
        self.width = width.max(1);
        self.height = height.max(1);
        self.exact = self.exact.map(|c| c.resized(self.width, self.height));
    }

    /// The current camera.
    pub fn camera(&self) -> Camera {
        if let Some(c) = self.exact {
            return c;
        }
        Camera::look_at(
            self.width,
            self.height,
            self.fov_y_deg,
            self.eye,
            self.eye + self.forward(),
            self.up,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn start() -> FirstPerson {
        let cam = Camera::look_at(
            64,
            48,
            50.0,
            DVec3::new(5.0, 0.0, 1.0),
            DVec3::ZERO,
            DVec3::Z,
        );
        // Eye 1 m up, ground at z = -1: 2 m above the ground, speed 2 m/s.
        FirstPerson::from_camera(&cam, DVec3::Z, 50.0, -1.0)
    }

    #[test]
    fn starts_at_the_given_camera_and_reproduces_it_after_a_full_turn() {
        let mut fp = start();
        let c0 = fp.camera();
        fp.look(180.0, 0.0);
        let away = fp.camera();
        assert!(
            away.world_from_camera
                .z_axis
                .truncate()
                .dot(c0.world_from_camera.z_axis.truncate())
                < -0.9
        );
        fp.look(-180.0, 0.0);
        let back = fp.camera();
        let d =
            (back.world_from_camera - c0.world_from_camera).abs_diff_eq(glam::DMat4::ZERO, 1e-9);
        assert!(
            d,
            "{:?} vs {:?}",
            back.world_from_camera, c0.world_from_camera
        );
    }

    #[test]
    fn keys_move_along_the_view_and_up() {
        let mut fp = start();
        let e0 = fp.eye;
        fp.key("KeyW", true, false);
        assert!(fp.advance(0.2));
        let moved = fp.eye - e0;
        assert!((moved.length() - 0.4).abs() < 1e-9);
        // A long stall (tab in the background) moves at most a quarter second's worth.
        let e1 = fp.eye;
        assert!(fp.advance(10.0));
        assert!(((fp.eye - e1).length() - 0.5).abs() < 1e-9);
        assert!(moved.normalize().dot(fp.forward()) > 0.999);
        fp.key("KeyW", false, false);
        fp.key("KeyE", true, true);
        let e1 = fp.eye;
        let speed = fp.speed();
        assert!(fp.advance(0.1));
        assert!(((fp.eye - e1).dot(DVec3::Z) - 0.4 * speed).abs() < 1e-9);
        fp.release_keys();
        assert!(!fp.advance(0.1));
    }

    #[test]
    fn hostile_inputs_keep_the_camera_finite() {
        let mut fp = start();
        fp.look(f64::NAN, 3.0);
        fp.look(0.0, 1e9);
        assert!(fp.pitch_deg <= MAX_PITCH_DEG);
        fp.key("KeyW", true, false);
        assert!(!fp.advance(f64::INFINITY));
        assert!(fp.advance(1e9));
        let c = fp.camera();
        assert!(
            c.world_from_camera
                .to_cols_array()
                .iter()
                .all(|v| v.is_finite())
        );
        let mut deg = FirstPerson::from_camera(&c, DVec3::ZERO, 50.0, f64::NAN);
        assert!(deg.speed().is_finite() && deg.speed() > 0.0);
        deg.look(1.0, 1.0);
        assert!(
            deg.camera()
                .world_from_camera
                .to_cols_array()
                .iter()
                .all(|v| v.is_finite())
        );
    }

    #[test]
    fn walk_keeps_the_eye_height_under_any_pitch() {
        for pitch in [-89.0, -60.0, -10.0, 0.0, 30.0, 89.0] {
            let mut fp = start();
            fp.toggle_mode();
            assert_eq!(fp.mode, Mode::Walk);
            fp.look(37.0, pitch - fp.pitch_deg);
            let z0 = fp.eye.z;
            for key in ["KeyW", "KeyS", "KeyA", "KeyD", "KeyE", "KeyQ"] {
                fp.key(key, true, false);
                fp.advance(0.2);
                fp.key(key, false, false);
            }
            fp.key("KeyW", true, true);
            let e = fp.eye;
            assert!(fp.advance(0.25));
            assert!((fp.eye - e).length() > 0.1, "pitch {pitch}: walking moved");
            assert!(
                (fp.eye.z - z0).abs() < 1e-12,
                "pitch {pitch}: height changed"
            );
        }
        // Flying along a pitched view changes the height.
        let mut fp = start();
        fp.look(0.0, -30.0 - fp.pitch_deg);
        let z0 = fp.eye.z;
        fp.key("KeyW", true, false);
        fp.advance(0.2);
        assert!(fp.eye.z < z0 - 0.1);
    }

    #[test]
    fn speed_scales_with_the_height_above_the_content() {
        let at = |h: f64| {
            let cam = Camera::look_at(
                64,
                48,
                50.0,
                DVec3::new(0.0, 0.0, h),
                DVec3::new(1.0, 0.0, h),
                DVec3::Z,
            );
            let mut fp = FirstPerson::from_camera(&cam, DVec3::Z, 50.0, 0.0);
            fp.toggle_mode();
            fp.key("KeyW", true, false);
            let e = fp.eye;
            fp.advance(0.1);
            (fp.eye - e).length() / 0.1
        };
        assert!((at(500.0) - 500.0 * SPEED_PER_HEIGHT).abs() < 1e-6);
        assert!((at(50.0) - 50.0 * SPEED_PER_HEIGHT).abs() < 1e-6);
        assert!((at(500.0) / at(50.0) - 10.0).abs() < 1e-9);
        // At street level (and below the ground) the walking speed floor holds.
        assert!((at(1.7) - MIN_SPEED_HEIGHT * SPEED_PER_HEIGHT).abs() < 1e-9);
        assert!((at(-5.0) - MIN_SPEED_HEIGHT * SPEED_PER_HEIGHT).abs() < 1e-9);
    }
}
