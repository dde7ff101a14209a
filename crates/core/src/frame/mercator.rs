//! The Web-Mercator root of a georeferenced tileset: the smallest tile (zoom, x, y) holding the
//! scene, unit coordinates below it, and the Mercator key of every implicit tile under it.

use super::geo::mercator_tile_bounds;

/// Deepest Web-Mercator zoom a georeferenced tileset reaches (tile x, y fit in u32; ~4 cm tiles).
pub const MAX_ZOOM: u32 = 30;

/// A Web-Mercator tile key in the slippy-map convention (x grows east, y grows south).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct MercatorKey {
    /// Zoom level (0 = the world).
    pub zoom: u32,
    /// Column, 0 at 180 deg west.
    pub x: u32,
    /// Row, 0 at the northern edge (85.05 deg north).
    pub y: u32,
}

/// Cell of a normalised Mercator coordinate (in [0, 1]) at `zoom`, clamped to the grid.
fn cell(v: f64, zoom: u32) -> u32 {
    let n = 1u64 << zoom;
    let c = (v * n as f64).floor();
    if c.is_nan() || c < 0.0 {
        0
    } else {
        (c as u64).min(n - 1) as u32
    }
}

impl MercatorKey {
    /// The deepest tile (zoom at most `max_zoom`, itself at most [`MAX_ZOOM`]) holding every
    /// point, given as normalised Mercator coordinates `(x, y)` in [0, 1] (see
    /// [`super::geo::mercator_unit`]). The world tile when `points` is empty.
    pub fn containing(points: &[(f64, f64)], max_zoom: u32) -> MercatorKey {
        let (mut x_lo, mut x_hi, mut y_lo, mut y_hi) = (1.0f64, 0.0f64, 1.0f64, 0.0f64);
        for &(x, y) in points {
            x_lo = x_lo.min(x);
            x_hi = x_hi.max(x);
            y_lo = y_lo.min(y);
            y_hi = y_hi.max(y);
        }
        if points.is_empty() {
            return MercatorKey {
                zoom: 0,
                x: 0,
                y: 0,
            };
        }
        // Sharing a cell at zoom z implies sharing it at every coarser zoom: take the deepest.
        let zoom = (0..=max_zoom.min(MAX_ZOOM))
            .rev()
            .find(|&z| cell(x_lo, z) == cell(x_hi, z) && cell(y_lo, z) == cell(y_hi, z))
            .unwrap_or(0);
        MercatorKey {
            zoom,
            x: cell(x_lo, zoom),
            y: cell(y_lo, zoom),
        }
    }

    /// Unit coordinates of a normalised Mercator point inside this tile: `[u, v]` in [0, 1],
    /// `u` growing east and `v` growing north (3D Tiles implicit y grows northwards).
    pub fn local_unit(self, x: f64, y: f64) -> [f64; 2] {
        let n = (1u64 << self.zoom) as f64;
        [x * n - self.x as f64, 1.0 - (y * n - self.y as f64)]
    }

    /// The Mercator key of the implicit tile (`level`, `x`, `y`) under this root: zoom + level,
    /// x0 * 2^level + x, y0 * 2^level + (2^level - 1 - y). `None` past [`MAX_ZOOM`] or outside
    /// the level's grid.
    pub fn key_of(self, level: u32, x: u32, y: u32) -> Option<MercatorKey> {
        let zoom = self.zoom.checked_add(level).filter(|&z| z <= MAX_ZOOM)?;
        let side = 1u64 << level;
        if x as u64 >= side || y as u64 >= side {
            return None;
        }
        Some(MercatorKey {
            zoom,
            x: ((self.x as u64) << level | x as u64) as u32,
            y: ((self.y as u64) << level | (side - 1 - y as u64)) as u32,
        })
    }

    /// West, south, east, north edges of the tile, degrees.
    pub fn bounds_deg(self) -> [f64; 4] {
        mercator_tile_bounds(self.zoom, self.x, self.y)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frame::geo::{mercator_key, mercator_unit};

    #[test]
    fn smallest_tile_holding_a_small_scene() {
        // Two points 50 m apart in Bern: the root is the deepest tile holding both.
        let a = mercator_unit(7.4400, 46.9500);
        let b = mercator_unit(7.4406, 46.9503);
        let k = MercatorKey::containing(&[a, b], MAX_ZOOM);
        // 50 m apart: never in one zoom-20 tile (26 m here); these two straddle a zoom-13 edge,
        // so the root is coarser than the distance alone suggests.
        assert_eq!((k.zoom, k.x, k.y), (12, 2132, 1441));
        for (lon, lat) in [(7.4400, 46.9500), (7.4406, 46.9503)] {
            assert_eq!(mercator_key(lon, lat, k.zoom), (k.zoom, k.x, k.y));
        }
        // One level deeper, the two points fall in different tiles.
        let z = k.zoom + 1;
        assert_ne!(
            mercator_key(7.44, 46.95, z),
            mercator_key(7.4406, 46.9503, z)
        );
        // A single point stops at the deepest zoom allowed.
        assert_eq!(MercatorKey::containing(&[a], 22).zoom, 22);
        // Straddling the prime meridian at the equator forces the world tile.
        let w = MercatorKey::containing(
            &[mercator_unit(-0.001, 0.001), mercator_unit(0.001, -0.001)],
            30,
        );
        assert_eq!((w.zoom, w.x, w.y), (0, 0, 0));
        assert_eq!(MercatorKey::containing(&[], 30).zoom, 0);
    }

    #[test]
    fn implicit_keys_map_to_mercator_keys() {
        let root = MercatorKey::containing(&[mercator_unit(13.405, 52.52)], 10);
        assert_eq!((root.zoom, root.x, root.y), (10, 550, 335));
        assert_eq!(root.key_of(0, 0, 0), Some(root));
        // Implicit y grows north: local (1, 0, 0) is the south-west child (row 2y+1).
        let sw = root.key_of(1, 0, 0).unwrap();
        assert_eq!((sw.zoom, sw.x, sw.y), (11, 1100, 671));
        let ne = root.key_of(1, 1, 1).unwrap();
        assert_eq!((ne.zoom, ne.x, ne.y), (11, 1101, 670));
        // A place's local unit coordinates pick the implicit tile whose Mercator key holds it.
        let (lon, lat) = (13.4102, 52.5163);
        let (x, y) = mercator_unit(lon, lat);
        let [u, v] = root.local_unit(x, y);
        assert!((0.0..=1.0).contains(&u) && (0.0..=1.0).contains(&v));
        for level in [3u32, 9, 20] {
            let n = (1u64 << level) as f64;
            let (lx, ly) = ((u * n).floor() as u32, (v * n).floor() as u32);
            let k = root.key_of(level, lx, ly).unwrap();
            assert_eq!(mercator_key(lon, lat, 10 + level), (k.zoom, k.x, k.y));
        }
        assert_eq!(root.key_of(21, 0, 0), None);
        assert_eq!(root.key_of(2, 4, 0), None);
        let b = root.bounds_deg();
        assert!(b[0] <= 13.405 && 13.405 <= b[2] && b[1] <= 52.52 && 52.52 <= b[3]);
    }
}
