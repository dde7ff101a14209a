//! Measuring a written LOD hierarchy: per-level counts (tiles, splats, bytes, geometric error) and
//! SSIM of coarse levels against full detail at their switching distance (reference renderer).
//!
//! "Switching distance" of a geometric error `e` is where the screen-space error of the tile
//! reaches [`MAX_SSE`] pixels for the intended viewer (1280x720, 50 deg vertical field of view,
//! the renderer's default camera): `D = e * f / 16` with `f` = that viewer's focal length. Images
//! are rendered smaller (same field of view) to keep the measurement fast.

/// Why an evaluation could not run (the message names the file).
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct EvalError(pub String);

macro_rules! eval_error_from {
    ($($t:ty),+) => {$(
        impl From<$t> for EvalError {
            fn from(e: $t) -> Self {
                EvalError(e.to_string())
            }
        }
    )+};
}
eval_error_from!(
    std::io::Error,
    splat2tiles_render::MetricError,
    splat2tiles_render::ImageError,
    splat2tiles_tiles::tiling::load::LoadError,
    splat2tiles_tiles::encode::GlbError
);

use glam::{DMat4, DVec3};
use splat2tiles_core::camera::{DEFAULT_FOV_Y_DEG, fov_to_focal};
use splat2tiles_core::splat::Splats;
use splat2tiles_render::{Camera, RenderOptions, auto_views_with, render, ssim};
use splat2tiles_tiles::encode::read_tile_glb;
use splat2tiles_tiles::geometry::{box_corners, content_model};
use splat2tiles_tiles::tiling::TileKey;
use splat2tiles_tiles::tiling::load::{LoadedTileset, load_tileset};
use std::collections::{BTreeMap, HashMap, HashSet};
use std::path::Path;

/// Screen-space error threshold the viewer refines at (the `select_tiles` default), pixels.
pub const MAX_SSE: f64 = 16.0;
/// Image height of the intended viewer, pixels.
pub const VIEWER_HEIGHT: u32 = 720;

/// Focal length (pixels) of the intended viewer.
pub fn viewer_focal() -> f64 {
    fov_to_focal(DEFAULT_FOV_Y_DEG, VIEWER_HEIGHT)
}

/// Distance (from a tile's bounding sphere) at which a tile of geometric error `e` is replaced by
/// its children: `e * f / MAX_SSE`.
pub fn switching_distance(e: f64) -> f64 {
    e * viewer_focal() / MAX_SSE
}

/// One row of the per-level table read from a tileset.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LevelRow {
    /// Tree level (0 = root).
    pub level: u32,
    /// Tiles with content at this level.
    pub tiles: usize,
    /// Of those, leaves (no children).
    pub leaves: usize,
    /// Splats over the level's content tiles.
    pub splats: u64,
    /// Bytes of the level's content files.
    pub bytes: u64,
    /// Mean geometric error of the level's content tiles.
    pub mean_geometric_error: f64,
    /// Parent (non-leaf) content tiles at this level.
    pub parent_tiles: usize,
    /// Splats over those parents.
    pub parent_splats: u64,
    /// Splats over those parents' children (what they were clustered from).
    pub children_splats: u64,
}

/// Keys of the tiles that have children.
pub(crate) fn parents_of(ts: &LoadedTileset) -> HashSet<TileKey> {
    ts.tiles.iter().filter_map(|t| t.key.parent()).collect()
}

/// The per-level table of a loaded tileset: counts from subtree metadata (glb read only when the
/// metadata lacks a splat count), bytes from the content files' sizes.
pub fn level_table(ts: &LoadedTileset) -> Result<Vec<LevelRow>, EvalError> {
    let parents = parents_of(ts);
    let mut rows: BTreeMap<u32, LevelRow> = BTreeMap::new();
    let mut counts: HashMap<TileKey, u64> = HashMap::new();
    for t in &ts.tiles {
        let Some(path) = &t.content else { continue };
        let row = rows.entry(t.key.level).or_insert_with(|| LevelRow {
            level: t.key.level,
            ..Default::default()
        });
        row.tiles += 1;
        row.leaves += usize::from(!parents.contains(&t.key));
        let bytes = std::fs::metadata(path)
            .map_err(|e| EvalError(format!("{}: {e}", path.display())))?
            .len();
        row.bytes += bytes;
        let n = match t.splat_count {
            Some(n) => n as u64,
            None => {
                let b = std::fs::read(path)
                    .map_err(|e| EvalError(format!("{}: {e}", path.display())))?;
                read_tile_glb(&b)
                    .map_err(|e| EvalError(format!("{}: {e}", path.display())))?
                    .splats
                    .len() as u64
            }
        };
        row.splats += n;
        counts.insert(t.key, n);
        if parents.contains(&t.key) {
            row.parent_tiles += 1;
            row.parent_splats += n;
        }
        row.mean_geometric_error += t.geometric_error;
    }
    for (k, n) in &counts {
        if let Some(p) = k.parent()
            && counts.contains_key(&p)
            && let Some(row) = rows.get_mut(&p.level)
        {
            row.children_splats += n;
        }
    }
    for r in rows.values_mut() {
        r.mean_geometric_error /= r.tiles.max(1) as f64;
    }
    Ok(rows.into_values().collect())
}

/// Settings of the SSIM measurement.
#[derive(Debug, Clone, Copy)]
pub struct EvalOptions {
    /// Rendered image width.
    pub width: u32,
    /// Rendered image height.
    pub height: u32,
    /// Viewpoints per measurement (taken evenly from the 8 automatic views).
    pub views: usize,
    /// Also measure every parent against its children (one render pair per parent and view).
    pub parent_pairs: bool,
}

impl Default for EvalOptions {
    fn default() -> Self {
        EvalOptions {
            width: 256,
            height: 192,
            views: 4,
            parent_pairs: true,
        }
    }
}

/// SSIM numbers of one level.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LevelQuality {
    /// The level's table row.
    pub row: LevelRow,
    /// Mean over the level's parent tiles and views of SSIM(parent alone, its children together)
    /// seen from the parent's switching distance; `None` for levels without parents.
    pub parent_ssim: Option<f64>,
    /// Lowest such SSIM over the level's parents and views.
    pub parent_ssim_min: Option<f64>,
    /// Mean over views of SSIM(cut at this level, all leaves), cameras at this level's switching
    /// distance (largest geometric error of the level) beyond the scene's bounding sphere.
    pub cut_ssim: Option<f64>,
    /// Lowest cut SSIM over the views.
    pub cut_ssim_min: Option<f64>,
    /// That switching distance.
    pub cut_distance: Option<f64>,
}

struct Decoded {
    splats: Splats,
    model: DMat4,
}

/// World-space centre and bounding-sphere radius of a tile's box.
pub(crate) fn sphere(ts: &LoadedTileset, b: &[f64; 12]) -> (DVec3, f64) {
    let corners = box_corners(b).map(|c| ts.root_transform.transform_point3(c));
    let c = corners.iter().copied().sum::<DVec3>() / 8.0;
    let r = corners.iter().map(|p| p.distance(c)).fold(0.0, f64::max);
    (c, r)
}

/// Cameras looking at `c` from the directions of the automatic views, at `dist` from `c`.
fn cameras(c: DVec3, up: DVec3, dist: f64, opts: &EvalOptions) -> Vec<Camera> {
    let all = auto_views_with(
        c - DVec3::ONE,
        c + DVec3::ONE,
        up,
        opts.width,
        opts.height,
        DEFAULT_FOV_Y_DEG,
    );
    let n = opts.views.clamp(1, all.len());
    (0..n)
        .map(|i| {
            let cam = all[i * all.len() / n];
            let dir = (cam.center() - c).normalize_or(DVec3::X);
            Camera::look_at(
                opts.width,
                opts.height,
                DEFAULT_FOV_Y_DEG,
                c + dir * dist,
                c,
                up,
            )
        })
        .collect()
}

fn ssim_of(a: &[&Decoded], b: &[&Decoded], cams: &[Camera]) -> Result<Vec<f64>, EvalError> {
    let ro = RenderOptions::default();
    let ia: Vec<(&Splats, DMat4)> = a.iter().map(|d| (&d.splats, d.model)).collect();
    let ib: Vec<(&Splats, DMat4)> = b.iter().map(|d| (&d.splats, d.model)).collect();
    cams.iter()
        .map(|cam| Ok(ssim(&render(&ia, cam, &ro), &render(&ib, cam, &ro))?))
        .collect()
}

fn mean_min(v: &[f64]) -> (Option<f64>, Option<f64>) {
    if v.is_empty() {
        return (None, None);
    }
    (
        Some(v.iter().sum::<f64>() / v.len() as f64),
        Some(v.iter().copied().fold(f64::INFINITY, f64::min)),
    )
}

/// Loads `tileset` (a `tileset.json`) and measures every level (see [`LevelQuality`]).
pub fn evaluate(tileset: &Path, opts: &EvalOptions) -> Result<Vec<LevelQuality>, EvalError> {
    let ts = load_tileset(tileset)?;
    let rows = level_table(&ts)?;
    let parents = parents_of(&ts);
    let up = splat2tiles_tiles::geometry::tileset_up(&ts);
    let mut tiles: HashMap<TileKey, Decoded> = HashMap::new();
    for t in &ts.tiles {
        let Some(path) = &t.content else { continue };
        let tile = read_tile_glb(&std::fs::read(path)?)?;
        let model = content_model(&ts, &tile.node_matrix);
        tiles.insert(
            t.key,
            Decoded {
                splats: tile.splats,
                model,
            },
        );
    }
    let info: HashMap<TileKey, &splat2tiles_tiles::tiling::load::LoadedTile> =
        ts.tiles.iter().map(|t| (t.key, t)).collect();
    let leaves: Vec<&splat2tiles_tiles::tiling::load::LoadedTile> = ts
        .tiles
        .iter()
        .filter(|t| t.content.is_some() && !parents.contains(&t.key))
        .collect();
    let root = info
        .get(&TileKey::ROOT)
        .and_then(|t| t.bounding_box)
        .ok_or_else(|| EvalError("root has no bounding box metadata".into()))?;
    let (scene_c, scene_r) = sphere(&ts, &root);
    let all_leaves: Vec<&Decoded> = leaves.iter().map(|t| &tiles[&t.key]).collect();

    let mut out = Vec::new();
    for row in rows {
        let level = row.level;
        // Parent vs children, each parent at its own switching distance.
        let mut pv = Vec::new();
        for t in ts
            .tiles
            .iter()
            .filter(|t| opts.parent_pairs && t.key.level == level)
        {
            if !parents.contains(&t.key) || !tiles.contains_key(&t.key) {
                continue;
            }
            let kids: Vec<&Decoded> = ts
                .tiles
                .iter()
                .filter(|c| c.key.parent() == Some(t.key))
                .filter_map(|c| tiles.get(&c.key))
                .collect();
            let Some(b) = t.bounding_box else { continue };
            let (c, r) = sphere(&ts, &b);
            let cams = cameras(c, up, switching_distance(t.geometric_error) + r, opts);
            pv.extend(ssim_of(&[&tiles[&t.key]], &kids, &cams)?);
        }
        let (parent_ssim, parent_ssim_min) = mean_min(&pv);
        // The cut: this level's tiles plus leaves above it, against all leaves.
        let level_tiles: Vec<&splat2tiles_tiles::tiling::load::LoadedTile> = ts
            .tiles
            .iter()
            .filter(|t| t.key.level == level && t.content.is_some())
            .collect();
        let has_parents = level_tiles.iter().any(|t| parents.contains(&t.key));
        let (mut cut_ssim, mut cut_ssim_min, mut cut_distance) = (None, None, None);
        if has_parents {
            let e = level_tiles
                .iter()
                .map(|t| t.geometric_error)
                .fold(0.0, f64::max);
            let d = switching_distance(e);
            let cut: Vec<&Decoded> = level_tiles
                .iter()
                .map(|t| &tiles[&t.key])
                .chain(
                    leaves
                        .iter()
                        .filter(|t| t.key.level < level)
                        .map(|t| &tiles[&t.key]),
                )
                .collect();
            let cams = cameras(scene_c, up, d + scene_r, opts);
            let v = ssim_of(&cut, &all_leaves, &cams)?;
            (cut_ssim, cut_ssim_min) = mean_min(&v);
            cut_distance = Some(d);
        }
        out.push(LevelQuality {
            row,
            parent_ssim,
            parent_ssim_min,
            cut_ssim,
            cut_ssim_min,
            cut_distance,
        });
    }
    Ok(out)
}
