//! Shareable camera views as text: `look-at:EX,EY,EZ:TX,TY,TZ[:UX,UY,UZ]` (world coordinates) or
//! `geo:LON,LAT,HEIGHT:HEADING,PITCH` (degrees, metres; ECEF worlds), parsed and formatted.

use glam::{DMat4, DVec3};

use super::camera::{Camera, look_at_pose};
use crate::frame::geo::Geodetic;

/// A camera view written as text: what `--camera` / `camera=` take and the viewers' stats report.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ViewSpec {
    /// Eye looking at a target; image up as close to `up` as possible (default: the scene's up).
    LookAt {
        /// Eye position (world).
        eye: DVec3,
        /// A point the view centre passes through (world).
        target: DVec3,
        /// Up direction, when given.
        up: Option<DVec3>,
    },
    /// Eye at a geodetic position (WGS84) looking along a heading (degrees clockwise from north)
    /// and pitch (degrees above the local horizontal); the world is ECEF.
    Geo {
        /// Longitude, degrees east.
        lon: f64,
        /// Latitude, degrees north.
        lat: f64,
        /// Height above the ellipsoid, metres.
        height: f64,
        /// Degrees clockwise from north.
        heading: f64,
        /// Degrees above the horizontal.
        pitch: f64,
    },
}

/// Parses `N` comma-separated finite numbers.
fn numbers<const N: usize>(s: &str, what: &str) -> Result<[f64; N], String> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    if parts.len() != N {
        return Err(format!(
            "{what}: expected {N} comma-separated numbers, got '{s}'"
        ));
    }
    let mut out = [0.0; N];
    for (o, p) in out.iter_mut().zip(&parts) {
        *o = p
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| format!("{what}: '{p}' is not a finite number"))?;
    }
    Ok(out)
}

fn vec3(s: &str, what: &str) -> Result<DVec3, String> {
    numbers::<3>(s, what).map(DVec3::from_array)
}

impl ViewSpec {
    /// Parses `look-at:EX,EY,EZ:TX,TY,TZ[:UX,UY,UZ]` or `geo:LON,LAT,HEIGHT:HEADING,PITCH`.
    pub fn parse(s: &str) -> Result<ViewSpec, String> {
        let s = s.trim();
        if let Some(rest) = s.strip_prefix("look-at:") {
            let parts: Vec<&str> = rest.split(':').collect();
            if !(2..=3).contains(&parts.len()) {
                return Err(format!(
                    "camera '{s}': expected look-at:EX,EY,EZ:TX,TY,TZ[:UX,UY,UZ]"
                ));
            }
            let eye = vec3(parts[0], "look-at eye")?;
            let target = vec3(parts[1], "look-at target")?;
            if eye == target {
                return Err(format!("camera '{s}': the eye and the target coincide"));
            }
            let up = match parts.get(2) {
                Some(u) => {
                    let u = vec3(u, "look-at up")?;
                    if u.length_squared() == 0.0 {
                        return Err(format!("camera '{s}': the up vector is zero"));
                    }
                    Some(u)
                }
                None => None,
            };
            return Ok(ViewSpec::LookAt { eye, target, up });
        }
        if let Some(rest) = s.strip_prefix("geo:") {
            let Some((pos, dir)) = rest.split_once(':') else {
                return Err(format!(
                    "camera '{s}': expected geo:LON,LAT,HEIGHT:HEADING,PITCH"
                ));
            };
            let [lon, lat, height] = numbers::<3>(pos, "geo position")?;
            let [heading, pitch] = numbers::<2>(dir, "geo heading,pitch")?;
            if !(-90.0..=90.0).contains(&lat) {
                return Err(format!("camera '{s}': latitude {lat} outside [-90, 90]"));
            }
            if !(-90.0..=90.0).contains(&pitch) {
                return Err(format!("camera '{s}': pitch {pitch} outside [-90, 90]"));
            }
            return Ok(ViewSpec::Geo {
                lon,
                lat,
                height,
                heading,
                pitch,
            });
        }
        Err(format!(
            "camera '{s}': expected look-at:EX,EY,EZ:TX,TY,TZ[:UX,UY,UZ] or geo:LON,LAT,HEIGHT:HEADING,PITCH"
        ))
    }

    /// The camera-to-world pose (OpenCV axes); `default_up` serves a look-at without up.
    pub fn pose(&self, default_up: DVec3) -> DMat4 {
        match *self {
            ViewSpec::LookAt { eye, target, up } => {
                look_at_pose(eye, target, up.unwrap_or(default_up))
            }
            ViewSpec::Geo {
                lon,
                lat,
                height,
                heading,
                pitch,
            } => {
                let g = Geodetic { lon, lat, height };
                let eye = g.to_ecef();
                let enu = g.enu_axes();
                let (h, p) = (heading.to_radians(), pitch.to_radians());
                let fwd =
                    (enu.x_axis * h.sin() + enu.y_axis * h.cos()) * p.cos() + enu.z_axis * p.sin();
                // Axes from the direction itself (eye + fwd would round at ECEF magnitudes).
                let mut pose = look_at_pose(DVec3::ZERO, fwd, enu.z_axis);
                pose.w_axis = eye.extend(1.0);
                pose
            }
        }
    }

    /// The camera of `width x height` pixels and `fov_y_deg` for this view.
    pub fn camera(&self, width: u32, height: u32, fov_y_deg: f64, default_up: DVec3) -> Camera {
        Camera::from_pose(width, height, fov_y_deg, self.pose(default_up))
    }

    /// The look-at spec of `cam`: its eye, the point one unit ahead, and `up`.
    pub fn look_at_of(cam: &Camera, up: DVec3) -> ViewSpec {
        let eye = cam.center();
        ViewSpec::LookAt {
            eye,
            target: eye + cam.rotation().z_axis,
            up: Some(up),
        }
    }

    /// The geodetic spec of `cam` in an ECEF world: eye position, heading and pitch.
    pub fn geo_of(cam: &Camera) -> ViewSpec {
        let eye = cam.center();
        let g = Geodetic::from_ecef(eye);
        let enu = g.enu_axes();
        let f = cam.rotation().z_axis;
        let pitch = f.dot(enu.z_axis).clamp(-1.0, 1.0).asin().to_degrees();
        let heading = f
            .dot(enu.x_axis)
            .atan2(f.dot(enu.y_axis))
            .to_degrees()
            .rem_euclid(360.0);
        ViewSpec::Geo {
            lon: g.lon,
            lat: g.lat,
            height: g.height,
            heading,
            pitch,
        }
    }
}

/// `x` with at most `decimals` decimals, trailing zeros dropped, and no negative zero.
fn short_decimal(x: f64, decimals: usize) -> String {
    let s = format!("{x:.decimals$}");
    let s = if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.')
    } else {
        &s
    };
    if s == "-0" { "0".into() } else { s.into() }
}

impl ViewSpec {
    /// The spec for people to read and copy (overlays, logs): positions to the millimetre,
    /// directions to 1e-4, geodetic angles to about a centimetre on the ground (1e-7 degrees)
    /// and heading and pitch to 0.01 degrees. It parses back to within those steps.
    pub fn short(&self) -> String {
        let v = |p: DVec3, d: usize| {
            format!(
                "{},{},{}",
                short_decimal(p.x, d),
                short_decimal(p.y, d),
                short_decimal(p.z, d)
            )
        };
        match self {
            ViewSpec::LookAt { eye, target, up } => {
                let mut s = format!("look-at:{}:{}", v(*eye, 3), v(*target, 3));
                if let Some(u) = up {
                    s += &format!(":{}", v(*u, 4));
                }
                s
            }
            ViewSpec::Geo {
                lon,
                lat,
                height,
                heading,
                pitch,
            } => format!(
                "geo:{},{},{}:{},{}",
                short_decimal(*lon, 7),
                short_decimal(*lat, 7),
                short_decimal(*height, 3),
                short_decimal(*heading, 2),
                short_decimal(*pitch, 2)
            ),
        }
    }
}

impl std::fmt::Display for ViewSpec {
    /// Shortest round-trip decimal forms: parsing the text gives back the same numbers.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let v = |p: DVec3| format!("{},{},{}", p.x, p.y, p.z);
        match self {
            ViewSpec::LookAt { eye, target, up } => {
                write!(f, "look-at:{}:{}", v(*eye), v(*target))?;
                if let Some(u) = up {
                    write!(f, ":{}", v(*u))?;
                }
                Ok(())
            }
            ViewSpec::Geo {
                lon,
                lat,
                height,
                heading,
                pitch,
            } => write!(f, "geo:{lon},{lat},{height}:{heading},{pitch}"),
        }
    }
}

/// Whether a tileset's root transform places it on the Earth (an ECEF translation): geodetic
/// camera specs are reported for such worlds.
pub fn is_georeferenced(root_transform: DMat4) -> bool {
    root_transform.w_axis.truncate().length() > 6.0e6
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn short_form_is_short_and_parses_back_within_its_steps() {
        let spec = ViewSpec::LookAt {
            eye: DVec3::new(1.234_567_890_123, -0.000_01, 20.0),
            target: DVec3::new(0.1 + 0.2, 2.5, -3.999_999_9),
            up: Some(DVec3::new(0.0, -1.0e-9, 1.0)),
        };
        let short = spec.short();
        assert_eq!(short, "look-at:1.235,0,20:0.3,2.5,-4:0,0,1");
        let ViewSpec::LookAt { eye, target, up } = ViewSpec::parse(&short).unwrap() else {
            panic!("{short} is a look-at");
        };
        assert!(
            (eye - DVec3::new(1.234_567_890_123, -0.000_01, 20.0))
                .abs()
                .max_element()
                < 5e-4
        );
        assert!((target - DVec3::new(0.3, 2.5, -4.0)).abs().max_element() < 5e-4);
        assert_eq!(up, Some(DVec3::Z));
        let geo = ViewSpec::Geo {
            lon: 2.294_512_345_678_9,
            lat: -48.858_4,
            height: 35.000_000_01,
            heading: 359.999,
            pitch: -12.345_678,
        };
        assert_eq!(geo.short(), "geo:2.2945123,-48.8584,35:360,-12.35");
        assert!(ViewSpec::parse(&geo.short()).is_ok());
    }

    fn close(a: DMat4, b: DMat4, tol: f64) -> bool {
        a.to_cols_array()
            .iter()
            .zip(b.to_cols_array())
            .all(|(x, y)| (x - y).abs() <= tol * (1.0 + y.abs()))
    }

    #[test]
    fn text_round_trips_exactly() {
        for s in [
            "look-at:1.5,-2,3.25:0,0,0",
            "look-at:108.53943574978291,16.595741659404457,83.09350091984423:0,0.1,-7:0,0,1",
            "geo:2.2945,48.8584,36.7:90,-12.5",
        ] {
            let v = ViewSpec::parse(s).unwrap();
            assert_eq!(v.to_string(), s);
            assert_eq!(ViewSpec::parse(&v.to_string()).unwrap(), v);
        }
    }

    #[test]
    fn camera_round_trips_through_look_at_and_geo() {
        let cam = Camera::look_at(
            320,
            240,
            50.0,
            DVec3::new(12.0, -40.0, 1.7),
            DVec3::new(30.0, 5.0, -3.0),
            DVec3::Z,
        );
        let spec = ViewSpec::look_at_of(&cam, DVec3::Z);
        let back = ViewSpec::parse(&spec.to_string())
            .unwrap()
            .camera(320, 240, 50.0, DVec3::X);
        assert!(close(back.world_from_camera, cam.world_from_camera, 1e-12));
        assert_eq!((back.fx, back.cx), (cam.fx, cam.cx));

        let g = ViewSpec::Geo {
            lon: 2.2945,
            lat: 48.8584,
            height: 120.0,
            heading: 300.0,
            pitch: -35.0,
        };
        let cam = g.camera(320, 240, 50.0, DVec3::Z);
        let again = ViewSpec::geo_of(&cam);
        let cam2 = ViewSpec::parse(&again.to_string())
            .unwrap()
            .camera(320, 240, 50.0, DVec3::Z);
        // Positions in ECEF (6.4e6 m): a micrometre; axes: 1e-9.
        assert!((cam2.center() - cam.center()).length() < 1e-6);
        assert!(close(
            DMat4::from_mat3(cam2.rotation()),
            DMat4::from_mat3(cam.rotation()),
            1e-9
        ));
        let ViewSpec::Geo { heading, pitch, .. } = again else {
            panic!("not geo")
        };
        assert!(
            (heading - 300.0).abs() < 1e-9 && (pitch + 35.0).abs() < 1e-9,
            "{heading} {pitch} {again}"
        );
    }

    #[test]
    fn geo_heading_zero_looks_north_and_pitch_down_looks_down() {
        let north = ViewSpec::parse("geo:0,0,0:0,0").unwrap().pose(DVec3::Z);
        // At lon 0, lat 0 north is ECEF +z.
        assert!((north.z_axis.truncate() - DVec3::Z).length() < 1e-9);
        let down = ViewSpec::parse("geo:0,0,100:0,-89").unwrap().pose(DVec3::Z);
        assert!(down.z_axis.truncate().dot(DVec3::X) < -0.99);
    }

    #[test]
    fn bad_specs_are_refused_with_a_reason() {
        for s in [
            "",
            "look-at:1,2,3",
            "look-at:1,2:3,4,5",
            "look-at:1,2,3:1,2,3",
            "look-at:0,0,0:1,1,1:0,0,0",
            "look-at:nan,0,0:1,1,1",
            "geo:1,2:3,4",
            "geo:0,95,0:0,0",
            "geo:0,0,0:0,120",
            "orbit:1",
        ] {
            assert!(ViewSpec::parse(s).is_err(), "{s} accepted");
        }
    }
}
