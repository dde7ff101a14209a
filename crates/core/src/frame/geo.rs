//! Earth maths for georeferenced scenes only: WGS84 geodetic <-> ECEF, the local ENU frame at an
//! origin, and Web-Mercator tile keys (TileSplat eq. 1) with latitudes clamped short of the poles.

use glam::{DMat3, DMat4, DVec3};

/// WGS84 semi-major axis (m).
pub const WGS84_A: f64 = 6_378_137.0;
/// WGS84 flattening.
pub const WGS84_F: f64 = 1.0 / 298.257_223_563;
/// Largest latitude Web-Mercator represents (degrees): atan(sinh(pi)).
pub const MERCATOR_MAX_LAT: f64 = 85.051_128_779_806_59;

fn e2() -> f64 {
    WGS84_F * (2.0 - WGS84_F)
}

/// A geodetic position: longitude and latitude in degrees, height in metres above the ellipsoid.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Geodetic {
    /// Longitude, degrees east.
    pub lon: f64,
    /// Latitude, degrees north.
    pub lat: f64,
    /// Height above the WGS84 ellipsoid, metres.
    pub height: f64,
}

impl Geodetic {
    /// Parses `lon,lat[,height]`, checking ranges.
    pub fn parse(s: &str) -> Result<Geodetic, String> {
        let parts: Vec<&str> = s.split(',').map(str::trim).collect();
        if !(2..=3).contains(&parts.len()) {
            return Err(format!("origin '{s}': expected lon,lat[,height]"));
        }
        let num = |t: &str, what: &str| -> Result<f64, String> {
            let v: f64 = t
                .parse()
                .map_err(|_| format!("origin '{s}': {what} '{t}' is not a number"))?;
            if v.is_finite() {
                Ok(v)
            } else {
                Err(format!("origin '{s}': {what} must be finite"))
            }
        };
        let lon = num(parts[0], "longitude")?;
        let lat = num(parts[1], "latitude")?;
        let height = if parts.len() == 3 {
            num(parts[2], "height")?
        } else {
            0.0
        };
        if !(-180.0..=180.0).contains(&lon) {
            return Err(format!("origin '{s}': longitude {lon} outside [-180, 180]"));
        }
        if !(-90.0..=90.0).contains(&lat) {
            return Err(format!("origin '{s}': latitude {lat} outside [-90, 90]"));
        }
        Ok(Geodetic { lon, lat, height })
    }

    /// Earth-centred, Earth-fixed coordinates (m).
    pub fn to_ecef(self) -> DVec3 {
        let (lon, lat) = (self.lon.to_radians(), self.lat.to_radians());
        let (sl, cl) = lat.sin_cos();
        let n = WGS84_A / (1.0 - e2() * sl * sl).sqrt();
        DVec3::new(
            (n + self.height) * cl * lon.cos(),
            (n + self.height) * cl * lon.sin(),
            (n * (1.0 - e2()) + self.height) * sl,
        )
    }

    /// Geodetic coordinates of an ECEF point (iterative, sub-millimetre; finite at the poles
    /// and at the Earth's centre).
    pub fn from_ecef(p: DVec3) -> Geodetic {
        let e2 = e2();
        let r = (p.x * p.x + p.y * p.y).sqrt();
        let lon = p.y.atan2(p.x).to_degrees();
        if r < 1e-9 {
            // On the polar axis: latitude is +-90 (or 0 at the centre).
            let b = WGS84_A * (1.0 - WGS84_F);
            let lat = if p.z >= 0.0 { 90.0 } else { -90.0 };
            return Geodetic {
                lon,
                lat,
                height: p.z.abs() - b,
            };
        }
        // Height by the form that stays well conditioned near the poles.
        let height_at = |lat: f64| {
            let (s, c) = lat.sin_cos();
            r * c + p.z * s - WGS84_A * (1.0 - e2 * s * s).sqrt()
        };
        let mut lat = p.z.atan2(r * (1.0 - e2));
        for _ in 0..10 {
            let s = lat.sin();
            let n = WGS84_A / (1.0 - e2 * s * s).sqrt();
            let next = p.z.atan2(r * (1.0 - e2 * n / (n + height_at(lat))));
            let done = (next - lat).abs() < 1e-15;
            lat = next;
            if done {
                break;
            }
        }
        let height = height_at(lat);
        Geodetic {
            lon,
            lat: lat.to_degrees(),
            height,
        }
    }

    /// Rotation whose columns are the east, north and up unit vectors at this place (in ECEF).
    pub fn enu_axes(self) -> DMat3 {
        let (lon, lat) = (self.lon.to_radians(), self.lat.to_radians());
        let (so, co) = lon.sin_cos();
        let (sa, ca) = lat.sin_cos();
        let east = DVec3::new(-so, co, 0.0);
        let north = DVec3::new(-sa * co, -sa * so, ca);
        let up = DVec3::new(ca * co, ca * so, sa);
        DMat3::from_cols(east, north, up)
    }

    /// The ENU -> ECEF transform at this place (3D Tiles root `transform`).
    pub fn enu_to_ecef(self) -> DMat4 {
        let r = self.enu_axes();
        DMat4::from_cols(
            r.x_axis.extend(0.0),
            r.y_axis.extend(0.0),
            r.z_axis.extend(0.0),
            self.to_ecef().extend(1.0),
        )
    }
}

/// Web-Mercator normalised coordinates in [0, 1): x grows east from -180 deg, y grows south from
/// the top edge (the slippy-map convention). Latitudes beyond +-85.05 deg are clamped.
pub fn mercator_unit(lon: f64, lat: f64) -> (f64, f64) {
    let lat = lat.clamp(-MERCATOR_MAX_LAT, MERCATOR_MAX_LAT).to_radians();
    let x = (lon + 180.0) / 360.0;
    let y = (1.0 - (lat.tan() + 1.0 / lat.cos()).ln() / std::f64::consts::PI) / 2.0;
    (x.clamp(0.0, 1.0), y.clamp(0.0, 1.0))
}

/// Web-Mercator tile key (zoom, x, y) holding a place (TileSplat eq. 1).
pub fn mercator_key(lon: f64, lat: f64, zoom: u32) -> (u32, u32, u32) {
    let (x, y) = mercator_unit(lon, lat);
    let n = (1u64 << zoom) as f64;
    let max = (1u64 << zoom) - 1;
    let tx = ((x * n).floor() as u64).min(max) as u32;
    let ty = ((y * n).floor() as u64).min(max) as u32;
    (zoom, tx, ty)
}

/// West, south, east, north edges (degrees) of a Web-Mercator tile.
pub fn mercator_tile_bounds(zoom: u32, x: u32, y: u32) -> [f64; 4] {
    let n = (1u64 << zoom) as f64;
    let lon = |tx: f64| tx / n * 360.0 - 180.0;
    let lat = |ty: f64| {
        (std::f64::consts::PI * (1.0 - 2.0 * ty / n))
            .sinh()
            .atan()
            .to_degrees()
    };
    [
        lon(x as f64),
        lat(y as f64 + 1.0),
        lon(x as f64 + 1.0),
        lat(y as f64),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ecef_round_trip_including_poles() {
        for (lon, lat, h) in [
            (0.0, 0.0, 0.0),
            (2.35, 48.85, 35.0),
            (-122.4, 37.8, -20.0),
            (179.9, -89.999, 1000.0),
            (45.0, 90.0, 10.0),
            (-10.0, -90.0, 0.0),
        ] {
            let g = Geodetic {
                lon,
                lat,
                height: h,
            };
            let back = Geodetic::from_ecef(g.to_ecef());
            assert!((back.lat - lat).abs() < 1e-9, "{lat} -> {back:?}");
            assert!((back.height - h).abs() < 1e-4, "{h} -> {back:?}");
            if lat.abs() < 89.0 {
                assert!((back.lon - lon).abs() < 1e-9);
            }
        }
        let centre = Geodetic::from_ecef(DVec3::ZERO);
        assert!(centre.lat.is_finite() && centre.height.is_finite());
    }

    #[test]
    fn enu_axes_orthonormal_and_up_is_outward() {
        let g = Geodetic {
            lon: 13.4,
            lat: 52.5,
            height: 0.0,
        };
        let r = g.enu_axes();
        assert!((r.determinant() - 1.0).abs() < 1e-12);
        let up = r.z_axis;
        let p = g.to_ecef();
        assert!(up.dot(p.normalize()) > 0.99);
        let m = g.enu_to_ecef();
        let one_up = m.transform_point3(DVec3::new(0.0, 0.0, 1.0));
        let back = Geodetic::from_ecef(one_up);
        assert!((back.height - 1.0).abs() < 1e-6);
    }

    #[test]
    fn mercator_keys_known_values_and_poles() {
        // Zoom 0 is the whole world; Greenwich / equator sits on the zoom-1 corner (1, 1).
        assert_eq!(mercator_key(0.0, 0.0, 0), (0, 0, 0));
        assert_eq!(mercator_key(0.0, -0.0001, 1), (1, 1, 1));
        assert_eq!(mercator_key(-0.0001, 0.0001, 1), (1, 0, 0));
        // The slippy-map key of a well-known place (Berlin at zoom 10).
        assert_eq!(mercator_key(13.4050, 52.5200, 10), (10, 550, 335));
        // Poles and beyond-range latitudes clamp to the edge rows, never NaN.
        assert_eq!(mercator_key(10.0, 90.0, 5).2, 0);
        assert_eq!(mercator_key(10.0, -90.0, 5).2, 31);
        assert_eq!(mercator_key(180.0, 0.0, 4).1, 15);
        let (x, y) = mercator_unit(0.0, 90.0);
        assert!(x.is_finite() && y.is_finite());
        let b = mercator_tile_bounds(10, 550, 335);
        assert!(
            b[0] <= 13.405 && 13.405 <= b[2] && b[1] <= 52.52 && 52.52 <= b[3],
            "{b:?}"
        );
        let world = mercator_tile_bounds(0, 0, 0);
        assert!((world[3] - MERCATOR_MAX_LAT).abs() < 1e-9);
    }

    #[test]
    fn origin_parsing() {
        let g = Geodetic::parse("2.35, 48.85, 35").unwrap();
        assert_eq!((g.lon, g.lat, g.height), (2.35, 48.85, 35.0));
        assert_eq!(Geodetic::parse("2,3").unwrap().height, 0.0);
        for bad in ["", "1", "a,b", "200,0", "0,91", "1,2,3,4", "nan,0", "inf,0"] {
            assert!(Geodetic::parse(bad).is_err(), "{bad}");
        }
    }
}
