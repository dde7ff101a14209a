//! Frame stage: one streaming pass gathers what the layout needs from every splat (bounds in the
//! tileset frame, the Web-Mercator root and visible-reach region when georeferenced).
//!
//! The result, [`Layout`], maps any single splat to its tileset-frame centre and unit coordinates
//! of the root volume, so later stages place splats one at a time, chunk by chunk.

use super::{ConvertOptions, SchemeChoice};
use glam::{DMat3, DMat4, DVec3};
use rayon::prelude::*;
use splat2tiles_core::frame::geo::{Geodetic, mercator_unit};
use splat2tiles_core::frame::mercator::{MAX_ZOOM, MercatorKey};
use splat2tiles_core::frame::region::RegionBuilder;
use splat2tiles_core::splat::Splats;
use splat2tiles_tiles::tiling::Scheme;
use splat2tiles_tiles::tiling::extent::reach;
use splat2tiles_tiles::tiling::tileset::BoundingVolume;

/// What the frame pass accumulates over the (finite) splats; merging is order-free (min/max).
#[derive(Debug, Clone, Copy)]
pub(super) struct FrameAccum {
    lo: DVec3,
    hi: DVec3,
    /// Box of the splats' 3-sigma ellipsoids (local scenes' root volume).
    reach_lo: DVec3,
    reach_hi: DVec3,
    merc_lo: (f64, f64),
    merc_hi: (f64, f64),
    region: RegionBuilder,
    georeferenced: bool,
}

impl FrameAccum {
    /// An empty accumulator; `georeferenced` adds the Mercator bounds and the region.
    pub(super) fn new(georeferenced: bool) -> FrameAccum {
        FrameAccum {
            lo: DVec3::splat(f64::MAX),
            hi: DVec3::splat(f64::MIN),
            reach_lo: DVec3::splat(f64::MAX),
            reach_hi: DVec3::splat(f64::MIN),
            merc_lo: (f64::MAX, f64::MAX),
            merc_hi: (f64::MIN, f64::MIN),
            region: RegionBuilder::default(),
            georeferenced,
        }
    }

    fn merge(mut self, o: FrameAccum) -> FrameAccum {
        self.lo = self.lo.min(o.lo);
        self.hi = self.hi.max(o.hi);
        self.reach_lo = self.reach_lo.min(o.reach_lo);
        self.reach_hi = self.reach_hi.max(o.reach_hi);
        self.merc_lo = (
            self.merc_lo.0.min(o.merc_lo.0),
            self.merc_lo.1.min(o.merc_lo.1),
        );
        self.merc_hi = (
            self.merc_hi.0.max(o.merc_hi.0),
            self.merc_hi.1.max(o.merc_hi.1),
        );
        self.region = self.region.merge(o.region);
        self
    }

    /// Adds the splats of `s` whose `keep` flag is set (finite ones), in the frame `a` and, when
    /// georeferenced, the ENU frame `enu`.
    pub(super) fn add(&mut self, s: &Splats, keep: &[bool], a: DMat3, enu: Option<DMat4>) {
        let geo = self.georeferenced;
        let part = (0..s.len())
            .into_par_iter()
            .filter(|&i| keep[i])
            .fold(
                || FrameAccum::new(geo),
                |mut f, i| {
                    let p = a * DVec3::from_array(s.positions[i]);
                    f.lo = f.lo.min(p);
                    f.hi = f.hi.max(p);
                    let three = reach(a, s.scales[i], s.rotations[i], 1.0);
                    f.reach_lo = f.reach_lo.min(p - three);
                    f.reach_hi = f.reach_hi.max(p + three);
                    if let Some(enu) = enu {
                        let g = Geodetic::from_ecef(enu.transform_point3(p));
                        let (x, y) = mercator_unit(g.lon, g.lat);
                        f.merc_lo = (f.merc_lo.0.min(x), f.merc_lo.1.min(y));
                        f.merc_hi = (f.merc_hi.0.max(x), f.merc_hi.1.max(y));
                        let e = reach(a, s.scales[i], s.rotations[i], s.opacities[i]);
                        f.region.add(g, e.length());
                    }
                    f
                },
            )
            .reduce(|| FrameAccum::new(geo), FrameAccum::merge);
        *self = self.merge(part);
    }
}

/// Where the tree lives: the tileset frame, the root volume and the subdivision.
#[derive(Debug, Clone)]
pub(super) struct Layout {
    /// Rotation source -> tileset frame.
    pub(super) a: DMat3,
    pub(super) scheme: Scheme,
    pub(super) max_depth: u32,
    /// Root bounding volume.
    pub(super) root_volume: BoundingVolume,
    /// Root transform (georeferenced only).
    pub(super) transform: Option<[f64; 16]>,
    /// Web-Mercator tile of the implicit root (georeferenced only).
    pub(super) mercator_root: Option<MercatorKey>,
    /// ENU -> ECEF (georeferenced only).
    pub(super) enu: Option<DMat4>,
    /// Local scenes: the root box's minimum corner and size.
    pub(super) min: DVec3,
    pub(super) size: DVec3,
}

impl Layout {
    /// The layout of a scene whose frame pass gave `acc` (at least one splat).
    pub(super) fn new(acc: &FrameAccum, a: DMat3, opts: &ConvertOptions) -> Layout {
        match opts.origin {
            Some(origin) => {
                // Georeferenced: ENU at the origin; the implicit root is the smallest
                // Web-Mercator tile holding the scene (spec/georeferencing.md), its volume the
                // tight region of the splats' visible reach.
                let enu = origin.enu_to_ecef();
                let max_zoom = opts.max_depth.unwrap_or(MAX_ZOOM).min(MAX_ZOOM);
                let root = MercatorKey::containing(&[acc.merc_lo, acc.merc_hi], max_zoom);
                let region = acc.region.finish().expect("a scene has splats");
                Layout {
                    a,
                    scheme: Scheme::Quadtree,
                    max_depth: max_zoom - root.zoom,
                    root_volume: BoundingVolume {
                        region: Some(region.to_vec()),
                        ..Default::default()
                    },
                    transform: Some(enu.to_cols_array()),
                    mercator_root: Some(root),
                    enu: Some(enu),
                    min: DVec3::ZERO,
                    size: DVec3::ONE,
                }
            }
            None => {
                let ext = acc.hi - acc.lo;
                let horizontal = ext.x.max(ext.y);
                let scheme = match opts.scheme {
                    SchemeChoice::Octree => Scheme::Octree,
                    SchemeChoice::Quadtree => Scheme::Quadtree,
                    SchemeChoice::Auto if ext.z < 0.25 * horizontal => Scheme::Quadtree,
                    SchemeChoice::Auto => Scheme::Octree,
                };
                // The root box (and grid) holds every splat's 3-sigma ellipsoid, so even a
                // client that ignores the tiles' own boxes culls nothing visible.
                let (centre, half) = padded_box(acc.reach_lo, acc.reach_hi);
                Layout {
                    a,
                    scheme,
                    max_depth: opts.max_depth.unwrap_or(16).min(scheme.max_depth()),
                    root_volume: BoundingVolume {
                        box_: Some(box_array(centre, half)),
                        ..Default::default()
                    },
                    transform: None,
                    mercator_root: None,
                    enu: None,
                    min: centre - half,
                    size: half * 2.0,
                }
            }
        }
    }

    /// Deepest level the partition may reach (the Morton code depth).
    pub(super) fn depth(&self) -> u32 {
        self.max_depth.min(self.scheme.max_depth())
    }

    /// A splat centre (source frame) in the tileset frame.
    pub(super) fn to_tileset(&self, p: [f64; 3]) -> DVec3 {
        self.a * DVec3::from_array(p)
    }

    /// Unit coordinates of the root volume of a source-frame centre.
    pub(super) fn unit(&self, p: [f64; 3]) -> [f64; 3] {
        let t = self.to_tileset(p);
        match (self.enu, self.mercator_root) {
            (Some(enu), Some(root)) => {
                let g = Geodetic::from_ecef(enu.transform_point3(t));
                let (x, y) = mercator_unit(g.lon, g.lat);
                let [u, v] = root.local_unit(x, y);
                [u, v, 0.5]
            }
            _ => {
                let u = (t - self.min) / self.size;
                [
                    u.x,
                    u.y,
                    if self.scheme == Scheme::Octree {
                        u.z
                    } else {
                        0.5
                    },
                ]
            }
        }
    }

    /// Morton code at [`Layout::depth`] of a source-frame centre.
    pub(super) fn code(&self, p: [f64; 3]) -> u64 {
        splat2tiles_tiles::tiling::partition::code_of(self.unit(p), self.scheme, self.depth())
    }

    /// Edge length of a tile at `level`: the root box's largest (horizontal for quadtrees) edge
    /// halved per level; for georeferenced scenes the Web-Mercator tile width at the origin.
    pub(super) fn tile_edge(&self, level: u32) -> f64 {
        let root = match (self.mercator_root, &self.root_volume.box_) {
            (Some(m), _) => {
                let [_, south, _, north] = m.bounds_deg();
                let lat = (0.5 * (south + north)).to_radians();
                2.0 * std::f64::consts::PI * 6_378_137.0 * lat.cos() / 2f64.powi(m.zoom as i32)
            }
            (None, Some(b)) => {
                let z = if self.scheme == Scheme::Octree {
                    b[11]
                } else {
                    0.0
                };
                2.0 * b[3].max(b[7]).max(z)
            }
            (None, None) => 1.0,
        };
        root / 2f64.powi(level as i32)
    }
}

/// Centre and half extents of a box, with flat axes padded so the box is never degenerate.
pub(super) fn padded_box(lo: DVec3, hi: DVec3) -> (DVec3, DVec3) {
    let centre = (lo + hi) * 0.5;
    let half = (hi - lo) * 0.5;
    let floor = (half.max_element() * 1e-3).max(1e-6 * (1.0 + centre.abs().max_element()));
    (centre, half.max(DVec3::splat(floor)))
}

/// A 3D Tiles `box` array from centre and half extents.
pub(super) fn box_array(centre: DVec3, half: DVec3) -> Vec<f64> {
    vec![
        centre.x, centre.y, centre.z, half.x, 0.0, 0.0, 0.0, half.y, 0.0, 0.0, 0.0, half.z,
    ]
}
