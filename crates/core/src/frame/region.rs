//! Tight `region` bounding volumes (EPSG:4979: west, south, east, north in radians, heights in
//! metres) around georeferenced content: every point widened by its reach in metres.

use super::geo::Geodetic;

/// Smallest radius of curvature of the WGS84 ellipsoid (the meridional one at the equator, m):
/// a distance over it bounds the angle that distance can span anywhere on Earth.
const MIN_CURVATURE_RADIUS: f64 = 6_335_439.0;

/// Smallest reach (m) a point gets, so a region around one point is never degenerate.
const MIN_REACH: f64 = 1e-3;

/// Incrementally built region around points, each widened by its reach.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RegionBuilder {
    west: f64,
    south: f64,
    east: f64,
    north: f64,
    low: f64,
    high: f64,
}

impl Default for RegionBuilder {
    fn default() -> Self {
        RegionBuilder {
            west: f64::MAX,
            south: f64::MAX,
            east: f64::MIN,
            north: f64::MIN,
            low: f64::MAX,
            high: f64::MIN,
        }
    }
}

impl RegionBuilder {
    /// Adds the ball of radius `reach` (m) around `g`: its latitude and longitude spans are
    /// over-estimated with the smallest radius of curvature (and 1% more for heights below the
    /// ellipsoid), its heights by +-reach.
    pub fn add(&mut self, g: Geodetic, reach: f64) {
        let r = if reach.is_finite() {
            reach.max(MIN_REACH)
        } else {
            MIN_REACH
        };
        let radius = MIN_CURVATURE_RADIUS + g.height.min(0.0);
        let dlat = 1.01 * r / radius.max(1.0);
        let lat = g.lat.to_radians();
        let lon = g.lon.to_radians();
        let south = (lat - dlat).max(-std::f64::consts::FRAC_PI_2);
        let north = (lat + dlat).min(std::f64::consts::FRAC_PI_2);
        let cos = south.cos().min(north.cos());
        let (west, east) = if cos > 1e-9 && dlat / cos < 1.0 {
            let dlon = dlat / cos;
            (lon - dlon, lon + dlon)
        } else {
            (-std::f64::consts::PI, std::f64::consts::PI)
        };
        self.west = self.west.min(west.max(-std::f64::consts::PI));
        self.east = self.east.max(east.min(std::f64::consts::PI));
        self.south = self.south.min(south);
        self.north = self.north.max(north);
        self.low = self.low.min(g.height - r);
        self.high = self.high.max(g.height + r);
    }

    /// Merges another builder's points.
    pub fn merge(mut self, o: RegionBuilder) -> RegionBuilder {
        self.west = self.west.min(o.west);
        self.south = self.south.min(o.south);
        self.east = self.east.max(o.east);
        self.north = self.north.max(o.north);
        self.low = self.low.min(o.low);
        self.high = self.high.max(o.high);
        self
    }

    /// The region `[west, south, east, north, min height, max height]`; `None` without points.
    /// A scene crossing the antimeridian gets the full longitude range (not the tight wrap).
    pub fn finish(self) -> Option<[f64; 6]> {
        (self.west <= self.east).then_some([
            self.west, self.south, self.east, self.north, self.low, self.high,
        ])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn g(lon: f64, lat: f64, height: f64) -> Geodetic {
        Geodetic { lon, lat, height }
    }

    #[test]
    fn region_encloses_each_ball_and_stays_tight() {
        let mut b = RegionBuilder::default();
        assert_eq!(b.finish(), None);
        let origin = g(7.44, 46.95, 550.0);
        b.add(origin, 2.0);
        let r = b.finish().unwrap();
        // Points 2 m east, north and up of the origin (ENU) are inside.
        let enu = origin.enu_to_ecef();
        for d in [
            [2.0, 0.0, 0.0],
            [0.0, -2.0, 0.0],
            [0.0, 0.0, 2.0],
            [-1.4, 1.4, 0.0],
        ] {
            let p = Geodetic::from_ecef(enu.transform_point3(glam::DVec3::from_array(d)));
            let (lon, lat) = (p.lon.to_radians(), p.lat.to_radians());
            assert!(
                r[0] <= lon && lon <= r[2] && r[1] <= lat && lat <= r[3],
                "{d:?} {r:?}"
            );
            assert!(r[4] <= p.height && p.height <= r[5]);
        }
        // ... and the region is not much wider than 4 m either way.
        let width_m = (r[2] - r[0]) * 6_378_137.0 * 46.95f64.to_radians().cos();
        let height_m = (r[3] - r[1]) * 6_378_137.0;
        assert!(width_m < 4.2 && height_m < 4.2, "{width_m} x {height_m}");
        assert_eq!(r[5] - r[4], 4.0);
    }

    #[test]
    fn merge_and_poles() {
        let mut a = RegionBuilder::default();
        a.add(g(10.0, 20.0, 0.0), 1.0);
        let mut b = RegionBuilder::default();
        b.add(g(11.0, 21.0, 5.0), 0.0);
        let r = a.merge(b).finish().unwrap();
        assert!(r[0] < 10f64.to_radians() && r[2] > 11f64.to_radians());
        assert!(r[4] < -0.9 && r[5] > 5.0);
        let mut p = RegionBuilder::default();
        p.add(g(0.0, 90.0, 0.0), 10.0);
        let r = p.finish().unwrap();
        assert_eq!((r[0], r[2]), (-std::f64::consts::PI, std::f64::consts::PI));
        assert!(r[3] <= std::f64::consts::FRAC_PI_2);
    }
}
