//! Bounding volumes as the validator sees them (3D Tiles 1.1 "Bounding volumes"): parsing and
//! validity of box / region / sphere, implicit subdivision, and point containment.

use glam::{DMat4, DVec3};
use splat2tiles_core::frame::geo::Geodetic;
use std::f64::consts::{FRAC_PI_2, PI};

/// A parsed bounding volume.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Volume {
    /// Centre and three half-axis vectors.
    Box { c: DVec3, axes: [DVec3; 3] },
    /// west, south, east, north (rad), min and max height (m).
    Region([f64; 6]),
    /// Centre and radius.
    Sphere { c: DVec3, r: f64 },
}

/// Checks a box's 12 numbers; `Err` says why it is invalid.
pub(crate) fn parse_box(v: &[f64]) -> Result<Volume, String> {
    if v.len() != 12 {
        return Err(format!("a box has 12 numbers, not {}", v.len()));
    }
    if v.iter().any(|x| !x.is_finite()) {
        return Err("a box holds a non-finite number".into());
    }
    let c = DVec3::new(v[0], v[1], v[2]);
    let axes = [
        DVec3::new(v[3], v[4], v[5]),
        DVec3::new(v[6], v[7], v[8]),
        DVec3::new(v[9], v[10], v[11]),
    ];
    let lens = axes.map(|a| a.length());
    if lens.contains(&0.0) {
        return Err("a box half-axis has zero length (degenerate box)".into());
    }
    let det = axes[0].dot(axes[1].cross(axes[2])) / (lens[0] * lens[1] * lens[2]);
    if det.abs() < 1e-9 {
        return Err("the box half-axes are coplanar (degenerate box)".into());
    }
    Ok(Volume::Box { c, axes })
}

/// Checks a region's 6 numbers.
pub(crate) fn parse_region(v: &[f64]) -> Result<Volume, String> {
    if v.len() != 6 {
        return Err(format!("a region has 6 numbers, not {}", v.len()));
    }
    let [w, s, e, n, lo, hi] = [v[0], v[1], v[2], v[3], v[4], v[5]];
    if v.iter().any(|x| !x.is_finite()) {
        return Err("a region holds a non-finite number".into());
    }
    if !(-PI..=PI).contains(&w) || !(-PI..=PI).contains(&e) {
        return Err(format!("west {w} / east {e} must be within [-pi, pi]"));
    }
    if !(-FRAC_PI_2..=FRAC_PI_2).contains(&s) || !(-FRAC_PI_2..=FRAC_PI_2).contains(&n) {
        return Err(format!(
            "south {s} / north {n} must be within [-pi/2, pi/2]"
        ));
    }
    if s > n {
        return Err(format!("south {s} is greater than north {n}"));
    }
    if lo > hi {
        return Err(format!(
            "minimum height {lo} is greater than maximum height {hi}"
        ));
    }
    Ok(Volume::Region([w, s, e, n, lo, hi]))
}

/// Checks a sphere's 4 numbers.
pub(crate) fn parse_sphere(v: &[f64]) -> Result<Volume, String> {
    if v.len() != 4 {
        return Err(format!("a sphere has 4 numbers, not {}", v.len()));
    }
    if v.iter().any(|x| !x.is_finite()) {
        return Err("a sphere holds a non-finite number".into());
    }
    if v[3] < 0.0 {
        return Err(format!("sphere radius {} is negative", v[3]));
    }
    Ok(Volume::Sphere {
        c: DVec3::new(v[0], v[1], v[2]),
        r: v[3],
    })
}

impl Volume {
    /// The volume of the implicit tile (`level`, `x`, `y`, `z`) below this root volume
    /// (halved per axis per level; quadtrees keep z / heights whole).
    pub fn subdivide(&self, octree: bool, level: u32, x: u32, y: u32, z: u32) -> Volume {
        let n = f64::powi(2.0, level as i32);
        let unit = |i: u32| -1.0 + (2.0 * i as f64 + 1.0) / n;
        match *self {
            Volume::Box { c, axes } => {
                let (uz, sz) = if octree { (unit(z), n) } else { (0.0, 1.0) };
                Volume::Box {
                    c: c + axes[0] * unit(x) + axes[1] * unit(y) + axes[2] * uz,
                    axes: [axes[0] / n, axes[1] / n, axes[2] / sz],
                }
            }
            Volume::Region([w, s, e, nn, lo, hi]) => {
                let span = if e >= w { e - w } else { e + 2.0 * PI - w };
                let dl = span / n;
                let dp = (nn - s) / n;
                let wx = w + dl * x as f64;
                let wrap = |a: f64| if a > PI { a - 2.0 * PI } else { a };
                let (lo2, hi2) = if octree {
                    let dh = (hi - lo) / n;
                    (lo + dh * z as f64, lo + dh * (z as f64 + 1.0))
                } else {
                    (lo, hi)
                };
                Volume::Region([
                    wrap(wx),
                    s + dp * y as f64,
                    wrap(wx + dl),
                    s + dp * (y as f64 + 1.0),
                    lo2,
                    hi2,
                ])
            }
            Volume::Sphere { .. } => *self,
        }
    }

    /// How far outside the volume `p` lies (<= 0 inside), in units of the volume's size for
    /// boxes and spheres, radians/metres for regions. `to_ecef` maps the tile frame to ECEF
    /// (used by regions only). `margin` is extra reach along every direction (3-sigma extent).
    pub fn excess(&self, p: DVec3, to_ecef: &DMat4, reach: impl Fn(DVec3) -> f64) -> f64 {
        match *self {
            Volume::Box { c, axes } => {
                let d = p - c;
                axes.iter()
                    .map(|a| {
                        let len = a.length();
                        let u = *a / len;
                        (d.dot(u).abs() + reach(u)) / len - 1.0
                    })
                    .fold(f64::MIN, f64::max)
            }
            Volume::Sphere { c, r } => {
                let d = p - c;
                let dist = d.length();
                let u = if dist > 0.0 { d / dist } else { DVec3::X };
                (dist + reach(u)) / r.max(f64::MIN_POSITIVE) - 1.0
            }
            Volume::Region([w, s, e, n, lo, hi]) => {
                let g = Geodetic::from_ecef(to_ecef.transform_point3(p));
                let (lon, lat) = (g.lon.to_radians(), g.lat.to_radians());
                let lon_out = if e >= w {
                    (w - lon).max(lon - e)
                } else if lon >= w || lon <= e {
                    -1.0
                } else {
                    (lon - e).min(w - lon)
                };
                let lat_out = (s - lat).max(lat - n);
                let h_out = (lo - g.height).max(g.height - hi) / (hi - lo).abs().max(1.0);
                lon_out.max(lat_out).max(h_out)
            }
        }
    }
}

impl Volume {
    /// How far `inner` reaches outside `self` (<= 0 when contained), in the units of
    /// [`Volume::excess`]; `None` when the two kinds are not compared (a region with a box or
    /// sphere, or a region crossing the antimeridian). Both volumes are in the same frame.
    pub fn contains(&self, inner: &Volume) -> Option<f64> {
        let id = DMat4::IDENTITY;
        match (*self, *inner) {
            (Volume::Region(o), Volume::Region(i)) => {
                if o[0] > o[2] || i[0] > i[2] {
                    return None;
                }
                let h = (o[5] - o[4]).abs().max(1.0);
                Some(
                    [
                        o[0] - i[0],
                        i[2] - o[2],
                        o[1] - i[1],
                        i[3] - o[3],
                        (o[4] - i[4]) / h,
                        (i[5] - o[5]) / h,
                    ]
                    .into_iter()
                    .fold(f64::MIN, f64::max),
                )
            }
            (Volume::Region(_), _) | (_, Volume::Region(_)) => None,
            (outer, Volume::Sphere { c, r }) => Some(outer.excess(c, &id, |_| r)),
            (outer, Volume::Box { c, axes }) => {
                let mut worst = f64::MIN;
                for k in 0..8 {
                    let s = |b: usize| if k >> b & 1 == 1 { 1.0 } else { -1.0 };
                    let p = c + axes[0] * s(0) + axes[1] * s(1) + axes[2] * s(2);
                    worst = worst.max(outer.excess(p, &id, |_| 0.0));
                }
                Some(worst)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn boxes_regions_spheres() {
        let b = parse_box(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 2.0, 0.0, 0.0, 0.0, 3.0]).unwrap();
        let id = DMat4::IDENTITY;
        assert!(b.excess(DVec3::new(0.9, 1.9, -2.9), &id, |_| 0.0) < 0.0);
        assert!(b.excess(DVec3::new(1.1, 0.0, 0.0), &id, |_| 0.0) > 0.0);
        let child = b.subdivide(true, 1, 1, 0, 1);
        assert!(child.excess(DVec3::new(0.5, -1.0, 1.5), &id, |_| 0.0) <= 1e-12);
        assert!(parse_box(&[0.0; 12]).is_err());
        assert!(parse_box(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 2.0, 0.0, 0.0, 0.0, 0.0, 1.0]).is_err());
        assert!(parse_region(&[-1.0, -0.5, 1.0, 0.5, 0.0, 10.0]).is_ok());
        assert!(parse_region(&[-4.0, -0.5, 1.0, 0.5, 0.0, 10.0]).is_err());
        assert!(parse_region(&[-1.0, 0.5, 1.0, -0.5, 0.0, 10.0]).is_err());
        assert!(parse_sphere(&[0.0, 0.0, 0.0, -1.0]).is_err());
        assert!(parse_sphere(&[0.0, 0.0, 0.0, 0.0]).is_ok());
    }

    #[test]
    fn containment_of_volumes() {
        let b = parse_box(&[0.0, 0.0, 0.0, 2.0, 0.0, 0.0, 0.0, 2.0, 0.0, 0.0, 0.0, 2.0]).unwrap();
        let small =
            parse_box(&[1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]).unwrap();
        let shifted =
            parse_box(&[1.5, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]).unwrap();
        assert!(b.contains(&small).unwrap() <= 1e-12);
        assert!(b.contains(&shifted).unwrap() > 0.2);
        let s = parse_sphere(&[0.0, 0.0, 0.0, 1.0]).unwrap();
        assert!(b.contains(&s).unwrap() < 0.0);
        assert!(s.contains(&b).unwrap() > 0.0);
        let r = parse_region(&[-1.0, -0.5, 1.0, 0.5, 0.0, 10.0]).unwrap();
        let ri = parse_region(&[-0.5, -0.5, 0.5, 0.6, 0.0, 10.0]).unwrap();
        assert!(r.contains(&ri).unwrap() > 0.0);
        assert!(r.contains(&r).unwrap() <= 0.0);
        assert_eq!(r.contains(&b), None);
    }
}
