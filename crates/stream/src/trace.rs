//! Camera traces: the file format (CSV with `#` header lines), SGSS's orbital and dolly shots
//! (sec. 5.1 recipe) and synthetic first-person walks (WASD + mouse at 12 Hz, pauses, turns).
//!
//! File format (`traces/README.md`): lines starting with `#` are `# key: value` headers
//! (`splat2tiles-trace: 1`, `scene`, `kind`, `seed`, `split`, `fov_y_deg`, `aspect`, `origin`),
//! then a `t,x,y,z,yaw_deg,pitch_deg` header row and one row per pose: seconds, position in the
//! tileset frame (z up; the local ENU frame of `origin` for georeferenced scenes), yaw from +x
//! towards +y and pitch upwards, in degrees.

use crate::geom::{ViewPose, wrap_angle};
use glam::DVec3;
use splat2tiles_core::rng::SplitMix64;
use std::fmt::Write as _;

/// Sampling rate of generated traces (TileSplat: 12 Hz).
pub const TRACE_HZ: f64 = 12.0;

/// A camera trace.
#[derive(Debug, Clone, PartialEq)]
pub struct Trace {
    /// `# key: value` headers in order.
    pub headers: Vec<(String, String)>,
    /// Poses sorted by time.
    pub poses: Vec<ViewPose>,
}

impl Trace {
    /// A header's value.
    pub fn header(&self, key: &str) -> Option<&str> {
        self.headers
            .iter()
            .find(|(k, _)| k == key)
            .map(|(_, v)| v.as_str())
    }

    /// Duration in seconds.
    pub fn duration(&self) -> f64 {
        match (self.poses.first(), self.poses.last()) {
            (Some(a), Some(b)) => b.t - a.t,
            _ => 0.0,
        }
    }

    /// Writes the file format.
    pub fn to_csv(&self) -> String {
        let mut s = String::new();
        for (k, v) in &self.headers {
            let _ = writeln!(s, "# {k}: {v}");
        }
        s.push_str("t,x,y,z,yaw_deg,pitch_deg\n");
        for p in &self.poses {
            let _ = writeln!(
                s,
                "{:.4},{:.4},{:.4},{:.4},{:.3},{:.3}",
                p.t,
                p.pos.x,
                p.pos.y,
                p.pos.z,
                p.yaw.to_degrees(),
                p.pitch.to_degrees()
            );
        }
        s
    }

    /// Parses the file format; errors name the line.
    pub fn from_csv(text: &str) -> Result<Trace, String> {
        let mut headers = vec![];
        let mut poses = vec![];
        let mut seen_cols = false;
        for (n, line) in text.lines().enumerate() {
            let line = line.trim();
            if line.is_empty() {
                continue;
            }
            if let Some(h) = line.strip_prefix('#') {
                if let Some((k, v)) = h.split_once(':') {
                    headers.push((k.trim().to_string(), v.trim().to_string()));
                }
                continue;
            }
            if !seen_cols {
                if line != "t,x,y,z,yaw_deg,pitch_deg" {
                    return Err(format!("line {}: expected the column header", n + 1));
                }
                seen_cols = true;
                continue;
            }
            let v: Result<Vec<f64>, _> = line.split(',').map(|f| f.trim().parse::<f64>()).collect();
            let v = v.map_err(|e| format!("line {}: {e}", n + 1))?;
            if v.len() != 6 || v.iter().any(|x| !x.is_finite()) {
                return Err(format!("line {}: expected 6 finite numbers", n + 1));
            }
            if let Some(prev) = poses.last().map(|p: &ViewPose| p.t)
                && v[0] < prev
            {
                return Err(format!("line {}: time goes backwards", n + 1));
            }
            poses.push(ViewPose {
                t: v[0],
                pos: DVec3::new(v[1], v[2], v[3]),
                yaw: v[4].to_radians(),
                pitch: v[5].to_radians(),
            });
        }
        if !headers.iter().any(|(k, _)| k == "splat2tiles-trace") {
            return Err("missing '# splat2tiles-trace: 1' header".into());
        }
        Ok(Trace { headers, poses })
    }
}

fn headers(scene: &str, kind: &str, seed: u64, split: &str) -> Vec<(String, String)> {
    [
        ("splat2tiles-trace", "1".to_string()),
        ("scene", scene.to_string()),
        ("kind", kind.to_string()),
        ("seed", seed.to_string()),
        ("split", split.to_string()),
        ("fov_y_deg", "50".to_string()),
        ("aspect", "1.7778".to_string()),
    ]
    .into_iter()
    .map(|(k, v)| (k.to_string(), v))
    .collect()
}

/// Key poses of SGSS's orbital shot: 40 poses around the box (standing in for the training
/// cameras we do not have), at `radius_scale` x the distance that frames the whole box, elevation
/// wandering between 10 and 35 degrees, each looking near the centre.
pub fn orbit_keys(lo: DVec3, hi: DVec3, radius_scale: f64, seed: u64) -> Vec<DVec3> {
    let mut rng = SplitMix64::new(seed);
    let c = (lo + hi) * 0.5;
    let r = ((hi - lo).length() * 0.5).max(1e-3);
    let dist = r / (25f64.to_radians()).sin() * radius_scale;
    (0..40)
        .map(|k| {
            let az = k as f64 / 40.0 * std::f64::consts::TAU;
            let el = rng.range(10.0, 35.0).to_radians();
            c + dist * DVec3::new(el.cos() * az.cos(), el.cos() * az.sin(), el.sin())
        })
        .collect()
}

fn keyed(keys: &[(DVec3, DVec3)], seg_s: f64) -> Vec<ViewPose> {
    let per = (seg_s * TRACE_HZ).round() as usize;
    let mut out = vec![];
    for w in 0..keys.len().saturating_sub(1) {
        let a = ViewPose::looking_at(w as f64 * seg_s, keys[w].0, keys[w].1);
        let b = ViewPose::looking_at((w + 1) as f64 * seg_s, keys[w + 1].0, keys[w + 1].1);
        for i in 0..per {
            out.push(a.lerp(&b, i as f64 / per as f64));
        }
    }
    if let Some(&(p, t)) = keys.last() {
        out.push(ViewPose::looking_at((keys.len() - 1) as f64 * seg_s, p, t));
    }
    out
}

/// SGSS orbital shot: 40 key poses 2 s apart (80 s), interpolated at 12 Hz.
pub fn orbital(scene: &str, lo: DVec3, hi: DVec3, seed: u64, split: &str) -> Trace {
    let c = (lo + hi) * 0.5;
    let keys: Vec<(DVec3, DVec3)> = orbit_keys(lo, hi, 0.6, seed)
        .into_iter()
        .map(|p| (p, c))
        .collect();
    Trace {
        headers: headers(scene, "orbital", seed, split),
        poses: keyed(&keys, 2.0),
    }
}

/// SGSS dolly shot: from the first to the second key pose in 20 s, interpolated at 12 Hz. The key
/// poses are closer than the orbit's (0.35 x the framing distance) so only part of the scene is
/// in view, as with the training cameras the paper uses.
pub fn dolly(scene: &str, lo: DVec3, hi: DVec3, seed: u64, split: &str) -> Trace {
    let c = (lo + hi) * 0.5;
    let k = orbit_keys(lo, hi, 0.35, seed);
    let keys = [(k[0], c), (k[1].lerp(c, 0.3), c)];
    Trace {
        headers: headers(scene, "dolly", seed, split),
        poses: keyed(&keys, 20.0),
    }
}

/// A synthetic first-person walk inside the box at eye height `eye_z` (WASD + mouse at 12 Hz):
/// segments of walking forward, strafing, turning (mouse yaw 30-90 deg/s) and pausing, with
/// eased speed changes and a turn back inwards near the box edge. `speed` in m/s.
#[allow(clippy::too_many_arguments)] // plain scalar knobs of one generator
pub fn walk(
    scene: &str,
    lo: DVec3,
    hi: DVec3,
    eye_z: f64,
    speed: f64,
    duration_s: f64,
    seed: u64,
    split: &str,
) -> Trace {
    let mut rng = SplitMix64::new(seed);
    let dt = 1.0 / TRACE_HZ;
    let c = (lo + hi) * 0.5;
    let margin = (hi - lo) * 0.1;
    let mut pos = DVec3::new(
        rng.range(lo.x + margin.x, hi.x - margin.x),
        rng.range(lo.y + margin.y, hi.y - margin.y),
        eye_z,
    );
    let mut yaw = (c.y - pos.y).atan2(c.x - pos.x) + rng.range(-0.5, 0.5);
    let mut pitch = rng.range(-0.15, 0.05);
    let mut vel = DVec3::ZERO;
    let (mut mode, mut left, mut yaw_rate) = (0u8, 0.0f64, 0.0f64);
    let mut poses = vec![];
    let n = (duration_s * TRACE_HZ).round() as usize;
    for i in 0..=n {
        let t = i as f64 * dt;
        if left <= 0.0 {
            let r = rng.f64();
            (mode, left) = if r < 0.45 {
                (0, rng.range(1.5, 5.0)) // W
            } else if r < 0.6 {
                (1, rng.range(0.5, 1.5)) // A or D
            } else if r < 0.85 {
                (2, rng.range(0.5, 1.5)) // mouse turn
            } else {
                (3, rng.range(0.5, 2.5)) // pause
            };
            yaw_rate =
                rng.range(30.0, 90.0).to_radians() * if rng.f64() < 0.5 { -1.0 } else { 1.0 };
            if mode == 1 {
                yaw_rate = yaw_rate.signum();
            }
        }
        left -= dt;
        let fwd = DVec3::new(yaw.cos(), yaw.sin(), 0.0);
        let right = DVec3::new(yaw.sin(), -yaw.cos(), 0.0);
        let want = match mode {
            0 => fwd * speed,
            1 => right * speed * 0.6 * yaw_rate.signum(),
            2 => fwd * speed * 0.3,
            _ => DVec3::ZERO,
        };
        vel = vel.lerp(want, 0.25);
        if mode == 2 {
            yaw = wrap_angle(yaw + yaw_rate * dt);
        }
        pitch = (pitch + rng.normal() * 0.01).clamp(-0.4, 0.3);
        let next = pos + vel * dt;
        let inside = next.x > lo.x + margin.x
            && next.x < hi.x - margin.x
            && next.y > lo.y + margin.y
            && next.y < hi.y - margin.y;
        if inside {
            pos = next;
        } else {
            // Near the edge: stop and turn towards the centre (a mouse turn).
            vel = DVec3::ZERO;
            let to_c = (c.y - pos.y).atan2(c.x - pos.x);
            yaw = wrap_angle(yaw + wrap_angle(to_c - yaw).clamp(-0.2, 0.2));
            mode = 2;
            left = left.max(0.3);
        }
        poses.push(ViewPose { t, pos, yaw, pitch });
    }
    Trace {
        headers: headers(scene, "walk", seed, split),
        poses,
    }
}
