//! `TileCatalog`: the plain-data view of a tileset the client plans over (tile tree, boxes,
//! geometric errors, and per tile four quality variants with byte size and utility).
//!
//! Until the variant metadata of the LOD/variants work lands, [`Variant`]s built from a real
//! tileset are a **stand-in**: the content file's real size is taken as Best and the other levels
//! are scaled by TileSplat Table 6 (69.75 / 53.75 / 45.375 / 37 B per splat); utilities are the
//! paper's figures (1.0 / 0.98 / 0.95 / 0.90). [`VariantSource`] records which one a catalog holds.

use super::geom::Obb;
use glam::{DMat4, DVec3};
use splat2tiles_core::rng::SplitMix64;
use splat2tiles_tiles::tiling::TileKey;
use splat2tiles_tiles::tiling::load::LoadedTile;
use std::collections::HashMap;

/// Number of quality levels per tile.
pub const LEVELS: usize = 4;

/// A quality level (TileSplat Table 6), best first.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Level {
    /// Full quality.
    Best = 0,
    /// High.
    High = 1,
    /// Medium (SSIM > 0.95 in the paper).
    Medium = 2,
    /// Low (SSIM 0.88-0.92 in the paper).
    Low = 3,
}

impl Level {
    /// All levels, best first.
    pub const ALL: [Level; LEVELS] = [Level::Best, Level::High, Level::Medium, Level::Low];

    /// Level from an index 0..4 (best first).
    pub fn from_index(i: usize) -> Level {
        Level::ALL[i.min(LEVELS - 1)]
    }

    /// Index 0..4, best first.
    pub fn index(self) -> usize {
        self as usize
    }

    /// Short name.
    pub fn name(self) -> &'static str {
        ["best", "high", "medium", "low"][self as usize]
    }
}

/// TileSplat Table 6 bytes per splat of Best/High/Medium/Low (before gzip, SH3).
pub const TABLE6_BYTES_PER_SPLAT: [f64; LEVELS] = [69.75, 53.75, 45.375, 37.0];
/// Stand-in utilities of Best/High/Medium/Low (TileSplat: Medium > 0.95, Low 0.88-0.92).
pub const STAND_IN_UTILITY: [f64; LEVELS] = [1.0, 0.98, 0.95, 0.90];

/// One downloadable version of a tile.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Variant {
    /// Bytes on the wire.
    pub bytes: u64,
    /// Utility in [0, 1] (SSIM of the variant against Best, TileSplat eq. 3).
    pub utility: f64,
}

/// Where a catalog's variant sizes and utilities come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum VariantSource {
    /// Measured per variant (subtree content metadata).
    Measured,
    /// Best = real content size; other levels scaled by Table 6; utilities = paper figures.
    StandIn,
    /// Generated (the paper's synthetic setting).
    Synthetic,
}

impl VariantSource {
    /// Label for reports.
    pub fn label(self) -> &'static str {
        match self {
            VariantSource::Measured => "measured",
            VariantSource::StandIn => "STAND-IN (real Best bytes, Table 6 ratios, paper utilities)",
            VariantSource::Synthetic => "synthetic",
        }
    }
}

/// One tile of the catalog.
#[derive(Debug, Clone, PartialEq)]
pub struct CatalogTile {
    /// Implicit address.
    pub key: TileKey,
    /// Parent tile index, `None` for a root.
    pub parent: Option<usize>,
    /// Child tile indices.
    pub children: Vec<usize>,
    /// Oriented box in the tileset frame.
    pub bbox: Obb,
    /// Geometric error in metres.
    pub geometric_error: f64,
    /// Splats in the content (0 when unknown or no content).
    pub splats: u64,
    /// Whether the tile has content to download.
    pub has_content: bool,
    /// Best, High, Medium, Low.
    pub variants: [Variant; LEVELS],
}

impl CatalogTile {
    /// Depth in the tree (0 at a root).
    pub fn depth(&self) -> u32 {
        self.key.level
    }
}

/// The tiles a client may fetch, as a tree.
#[derive(Debug, Clone, PartialEq)]
pub struct TileCatalog {
    /// All tiles; parents come before their children.
    pub tiles: Vec<CatalogTile>,
    /// Root tile indices.
    pub roots: Vec<usize>,
    /// Provenance of the variants.
    pub source: VariantSource,
}

impl TileCatalog {
    /// Replaces stand-in variants by measured ones (bytes and utility per Best, High, Medium,
    /// Low, as the converter stores them in content metadata) for every tile that has all four;
    /// the catalog becomes `Measured` when every content tile got them.
    pub fn with_measured(mut self, measured: &HashMap<TileKey, ([u32; 4], [f32; 4])>) -> Self {
        let mut all = true;
        for t in self.tiles.iter_mut().filter(|t| t.has_content) {
            match measured.get(&t.key) {
                Some((bytes, util))
                    if bytes.iter().all(|b| *b > 0) && util.iter().all(|u| *u >= 0.0) =>
                {
                    t.variants = std::array::from_fn(|j| Variant {
                        bytes: bytes[j] as u64,
                        utility: util[j] as f64,
                    });
                }
                _ => all = false,
            }
        }
        if all && self.tiles.iter().any(|t| t.has_content) {
            self.source = VariantSource::Measured;
        }
        self
    }
}

/// Stand-in variants from the real Best size (Table 6 ratios, paper utilities).
pub fn stand_in_variants(best_bytes: u64) -> [Variant; LEVELS] {
    std::array::from_fn(|j| Variant {
        bytes: (best_bytes as f64 * TABLE6_BYTES_PER_SPLAT[j] / TABLE6_BYTES_PER_SPLAT[0]).round()
            as u64,
        utility: STAND_IN_UTILITY[j],
    })
}

impl TileCatalog {
    /// Builds the catalog from a loaded tileset's tiles. Boxes stay in the tileset frame (the
    /// root transform is not applied: poses are given in that frame too). `content_bytes` gives
    /// the real size of a tile's content (e.g. the file length); variants are the stand-in.
    pub fn from_loaded(
        tiles: &[LoadedTile],
        mut content_bytes: impl FnMut(&LoadedTile) -> Option<u64>,
    ) -> TileCatalog {
        let mut order: Vec<usize> = (0..tiles.len()).collect();
        order.sort_by_key(|&i| {
            let k = tiles[i].key;
            (k.level, k.z, k.y, k.x)
        });
        let mut index: HashMap<TileKey, usize> = HashMap::new();
        let mut out: Vec<CatalogTile> = Vec::with_capacity(tiles.len());
        let mut roots = vec![];
        for &i in &order {
            let t = &tiles[i];
            let bytes = if t.content.is_some() {
                content_bytes(t).unwrap_or(0)
            } else {
                0
            };
            let bbox = t
                .bounding_box
                .map(|b| Obb::from_3dtiles(&b))
                .unwrap_or(Obb::aabb(DVec3::ZERO, DVec3::ZERO));
            let parent = t.key.parent().and_then(|p| index.get(&p).copied());
            let me = out.len();
            index.insert(t.key, me);
            match parent {
                Some(p) => out[p].children.push(me),
                None => roots.push(me),
            }
            out.push(CatalogTile {
                key: t.key,
                parent,
                children: vec![],
                bbox,
                geometric_error: t.geometric_error,
                splats: t.splat_count.unwrap_or(0) as u64,
                has_content: t.content.is_some() && bytes > 0,
                variants: stand_in_variants(bytes),
            });
        }
        TileCatalog {
            tiles: out,
            roots,
            source: VariantSource::StandIn,
        }
    }

    /// The ancestors of `tile`, its parent first and its root last.
    pub fn ancestors(&self, tile: usize) -> impl Iterator<Item = usize> + '_ {
        std::iter::successors(self.tiles[tile].parent, |&p| self.tiles[p].parent)
    }

    /// Tiles with content.
    pub fn content_tiles(&self) -> impl Iterator<Item = usize> + '_ {
        (0..self.tiles.len()).filter(|&i| self.tiles[i].has_content)
    }

    /// Bytes of every content tile at `level` (the full-scene download at that level).
    pub fn total_bytes(&self, level: Level) -> u64 {
        self.content_tiles()
            .map(|i| self.tiles[i].variants[level.index()].bytes)
            .sum()
    }

    /// Axis-aligned bounds of all content boxes.
    pub fn bounds(&self) -> (DVec3, DVec3) {
        let mut lo = DVec3::splat(f64::MAX);
        let mut hi = DVec3::splat(f64::MIN);
        for i in self.content_tiles() {
            let (a, b) = self.tiles[i].bbox.aabb_bounds();
            lo = lo.min(a);
            hi = hi.max(b);
        }
        if lo.x > hi.x {
            (DVec3::ZERO, DVec3::ZERO)
        } else {
            (lo, hi)
        }
    }

    /// A catalog of `copies` displaced copies of `self` on a square grid with `spacing` metres
    /// between copy origins (a generated "city" of real tiles); keys get the copy index in `z`'s
    /// high bits so they stay distinct.
    pub fn tiled_copies(&self, copies: usize, spacing: f64) -> TileCatalog {
        let side = (copies as f64).sqrt().ceil().max(1.0) as usize;
        let (lo, hi) = self.bounds();
        let centre = (lo + hi) * 0.5;
        let mut tiles = Vec::with_capacity(self.tiles.len() * copies);
        let mut roots = vec![];
        for c in 0..copies {
            let off = DVec3::new(
                (c % side) as f64 * spacing,
                (c / side) as f64 * spacing,
                0.0,
            ) - DVec3::new(centre.x, centre.y, 0.0);
            let base = tiles.len();
            for t in &self.tiles {
                let mut t = t.clone();
                t.bbox.center += off;
                t.parent = t.parent.map(|p| p + base);
                t.children.iter_mut().for_each(|k| *k += base);
                t.key.z |= (c as u32) << 16;
                tiles.push(t);
            }
            roots.extend(self.roots.iter().map(|r| r + base));
        }
        TileCatalog {
            tiles,
            roots,
            source: self.source,
        }
    }

    /// The paper's synthetic setting (TileSplat sec. 4.5): `n` flat tiles (no hierarchy) at 4
    /// levels; Best sizes uniform in `best_mb` (MB), other levels by Table 6 ratios with +-5%
    /// jitter, utilities 1.0 / 0.98 / 0.95 / 0.90 with +-0.01 jitter (lower levels only); tiles
    /// are 10 m cubes spread along a 200 m street.
    pub fn synthetic(n: usize, best_mb: (f64, f64), seed: u64) -> TileCatalog {
        let mut rng = SplitMix64::new(seed);
        let tiles = (0..n)
            .map(|i| {
                let best = rng.range(best_mb.0, best_mb.1) * 1e6;
                let variants = std::array::from_fn(|j| {
                    let jitter = if j == 0 { 1.0 } else { rng.range(0.95, 1.05) };
                    let u = if j == 0 {
                        1.0
                    } else {
                        (STAND_IN_UTILITY[j] + rng.range(-0.01, 0.01)).min(0.999)
                    };
                    Variant {
                        bytes: (best * TABLE6_BYTES_PER_SPLAT[j] / TABLE6_BYTES_PER_SPLAT[0]
                            * jitter) as u64,
                        utility: u,
                    }
                });
                let c = DVec3::new(rng.range(0.0, 200.0), rng.range(-20.0, 20.0), 5.0);
                CatalogTile {
                    key: TileKey {
                        level: 0,
                        x: i as u32,
                        y: 0,
                        z: 0,
                    },
                    parent: None,
                    children: vec![],
                    bbox: Obb::aabb(c - DVec3::splat(5.0), c + DVec3::splat(5.0)),
                    geometric_error: 0.0,
                    splats: (best / TABLE6_BYTES_PER_SPLAT[0]) as u64,
                    has_content: true,
                    variants,
                }
            })
            .collect();
        TileCatalog {
            tiles,
            roots: (0..n).collect(),
            source: VariantSource::Synthetic,
        }
    }
}

/// Applies an affine transform to an oriented box (centre and half axes).
pub fn transform_obb(m: DMat4, b: &Obb) -> Obb {
    Obb {
        center: m.transform_point3(b.center),
        half: b.half.map(|a| m.transform_vector3(a)),
    }
}
