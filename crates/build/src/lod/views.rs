//! Each level's cut of a written LOD hierarchy against all leaves, seen from street-level and
//! aerial cameras placed where a client would first show that level (its switching distance).
//!
//! The cut of level `L` is what a client shows when it stops refining at `L`: every content tile
//! at `L`, leaves above it, and below a level-`L` tile without content the first content on each
//! path. A camera direction (azimuth, elevation) from the scene's centre is walked out until every
//! tile of the cut with an error `e > 0` lies at least `switching_distance(e)` beyond its
//! bounding sphere. Images have the pixel scale of a `width x 3/4 width` frame with the viewer's
//! 50 degree vertical field of view (by default 960x720: the 1280x720 viewer's own pixels, so
//! the renderer's 0.3 px^2 low-pass filter widens sub-pixel splats exactly as in the viewer),
//! cropped to the scene's bounding sphere so that empty background does not inflate the SSIM.

use super::eval::EvalError;
use super::eval::{MAX_SSE, VIEWER_HEIGHT, parents_of, sphere, switching_distance};
use glam::{DMat4, DVec3};
use splat2tiles_core::camera::{DEFAULT_FOV_Y_DEG, fov_to_focal};
use splat2tiles_core::splat::Splats;
use splat2tiles_render::{Camera, Image, RenderOptions, render, ssim};
use splat2tiles_tiles::encode::read_tile_glb;
use splat2tiles_tiles::geometry::{content_model, select_tiles};
use splat2tiles_tiles::tiling::TileKey;
use splat2tiles_tiles::tiling::load::{LoadedTileset, load_tileset};
use std::collections::{BTreeMap, HashMap, HashSet};
use std::path::{Path, PathBuf};

/// Frame width whose 3:4 height is the intended viewer's ([`VIEWER_HEIGHT`]): images at the
/// viewer's own pixel scale. A smaller frame widens every splat by the renderer's fixed
/// 0.3 px^2 low-pass in larger pixels, which the viewer never does (at 256 px a sub-pixel leaf is
/// drawn 3.75 times wider than on screen).
pub const VIEWER_PIXEL_WIDTH: u32 = VIEWER_HEIGHT * 4 / 3;

/// A camera kind: elevation of the viewing direction above the horizon.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ViewKind {
    /// Near the ground, looking across the scene (2 degrees).
    Street,
    /// From above at 55 degrees.
    Aerial,
}

impl ViewKind {
    /// Elevation of the camera seen from the scene centre, degrees.
    pub fn elevation_deg(self) -> f64 {
        match self {
            ViewKind::Street => 2.0,
            ViewKind::Aerial => 55.0,
        }
    }

    /// Lower-case name (`street`, `aerial`).
    pub fn as_str(self) -> &'static str {
        match self {
            ViewKind::Street => "street",
            ViewKind::Aerial => "aerial",
        }
    }
}

/// Settings of the per-level view measurement.
#[derive(Debug, Clone)]
pub struct ViewOptions {
    /// Image width (height follows at 3:4); [`VIEWER_PIXEL_WIDTH`] gives the viewer's pixel scale.
    pub width: u32,
    /// Azimuths per camera kind (evenly spaced, starting at 30 degrees).
    pub azimuths: usize,
    /// Write the first azimuth's cut and reference images of every level here as PNGs.
    pub pictures: Option<PathBuf>,
    /// Drop every second splat of this level's tiles (a deliberately damaged level, to show the
    /// measurement can fail).
    pub damage_level: Option<u32>,
    /// Every geometric error times this when placing cameras (1: the written errors).
    pub error_scale: f64,
}

impl Default for ViewOptions {
    fn default() -> Self {
        ViewOptions {
            width: VIEWER_PIXEL_WIDTH,
            azimuths: 2,
            pictures: None,
            damage_level: None,
            error_scale: 1.0,
        }
    }
}

/// SSIM of one level's cut from both camera kinds.
#[derive(Debug, Clone, PartialEq)]
pub struct LevelViews {
    /// Tree level.
    pub level: u32,
    /// Content tiles of the cut at this level.
    pub cut_tiles: usize,
    /// Splats of the cut.
    pub cut_splats: u64,
    /// Lowest SSIM over the street-level azimuths.
    pub street_ssim: f64,
    /// Lowest SSIM over the aerial azimuths.
    pub aerial_ssim: f64,
    /// Camera distance from the scene centre of the first street view.
    pub street_distance: f64,
}

struct Tile {
    splats: Splats,
    model: DMat4,
    centre: DVec3,
    radius: f64,
    error: f64,
}

/// The keys of level `level`'s cut (see the module comment).
pub fn cut_keys(
    content: &BTreeMap<TileKey, f64>,
    parents: &HashSet<TileKey>,
    level: u32,
) -> Vec<TileKey> {
    content
        .keys()
        .filter(|k| {
            if k.level < level {
                return !parents.contains(k);
            }
            // At or below the level: no content on the path from the level down to it.
            let mut a = **k;
            while a.level > level {
                let Some(p) = a.parent() else { break };
                if content.contains_key(&p) {
                    return false;
                }
                a = p;
            }
            true
        })
        .copied()
        .collect()
}

/// Smallest `s >= 0` with `|w + s u| >= rho` (u unit), i.e. how far along `u` from a point at
/// `w` relative to a sphere's centre one must go to be `rho` away from that centre.
fn exit_distance(w: DVec3, u: DVec3, rho: f64) -> f64 {
    let b = w.dot(u);
    let disc = b * b - w.length_squared() + rho * rho;
    if disc <= 0.0 {
        return 0.0;
    }
    (-b + disc.sqrt()).max(0.0)
}

/// Loads `tileset` and measures every level with parent content (see the module comment).
pub fn evaluate_views(tileset: &Path, opts: &ViewOptions) -> Result<Vec<LevelViews>, EvalError> {
    let ts = load_tileset(tileset)?;
    let parents = parents_of(&ts);
    let up = splat2tiles_tiles::geometry::tileset_up(&ts);
    let mut tiles: BTreeMap<TileKey, Tile> = BTreeMap::new();
    for t in &ts.tiles {
        let (Some(path), Some(b)) = (&t.content, t.bounding_box) else {
            continue;
        };
        let tile = read_tile_glb(
            &std::fs::read(path).map_err(|e| EvalError(format!("{}: {e}", path.display())))?,
        )?;
        let (centre, radius) = sphere(&ts, &b);
        tiles.insert(
            t.key,
            Tile {
                model: content_model(&ts, &tile.node_matrix),
                splats: tile.splats,
                centre,
                radius,
                error: t.geometric_error,
            },
        );
    }
    let (scene_c, scene_r) = scene_sphere(&ts)?;
    let content: BTreeMap<TileKey, f64> = tiles.iter().map(|(k, t)| (*k, t.error)).collect();
    let leaves: Vec<&Tile> = tiles
        .iter()
        .filter(|(k, _)| !parents.contains(k))
        .map(|(_, t)| t)
        .collect();
    let levels: Vec<u32> = {
        let mut l: Vec<u32> = tiles
            .keys()
            .filter(|k| parents.contains(k))
            .map(|k| k.level)
            .collect();
        l.dedup();
        l
    };
    // A horizontal frame around `up`.
    let east = up.any_orthonormal_vector();
    let north = up.cross(east);
    let width = opts.width.max(16);
    let height = (width * 3 / 4).max(12);
    let focal = fov_to_focal(DEFAULT_FOV_Y_DEG, height);
    let ro = RenderOptions::default();
    let mut out = Vec::new();
    for level in levels {
        let keys = cut_keys(&content, &parents, level);
        let damaged: HashMap<TileKey, Splats> = keys
            .iter()
            .filter(|k| opts.damage_level == Some(level) && k.level == level)
            .map(|k| {
                let s = &tiles[k].splats;
                let keep: Vec<usize> = (0..s.len()).step_by(2).collect();
                (*k, s.select(&keep))
            })
            .collect();
        let cut: Vec<(&Splats, DMat4)> = keys
            .iter()
            .map(|k| (damaged.get(k).unwrap_or(&tiles[k].splats), tiles[k].model))
            .collect();
        let reference: Vec<(&Splats, DMat4)> =
            leaves.iter().map(|t| (&t.splats, t.model)).collect();
        let mut row = LevelViews {
            level,
            cut_tiles: keys.len(),
            cut_splats: cut.iter().map(|(s, _)| s.len() as u64).sum(),
            street_ssim: 1.0,
            aerial_ssim: 1.0,
            street_distance: 0.0,
        };
        for kind in [ViewKind::Street, ViewKind::Aerial] {
            for a in 0..opts.azimuths.max(1) {
                let az = (30.0 + 360.0 * a as f64 / opts.azimuths.max(1) as f64).to_radians();
                let el = kind.elevation_deg().to_radians();
                let u = (east * az.cos() + north * az.sin()) * el.cos() + up * el.sin();
                let s = keys
                    .iter()
                    .map(|k| &tiles[k])
                    .filter(|t| t.error > 0.0)
                    .map(|t| {
                        exit_distance(
                            scene_c - t.centre,
                            u,
                            t.radius + switching_distance(t.error * opts.error_scale),
                        )
                    })
                    .fold(scene_r * 0.01, f64::max);
                let eye = scene_c + u * s;
                // The full frame's pixel scale, cropped to the scene sphere (never below 64 px).
                let max_half = (DEFAULT_FOV_Y_DEG * 0.5).to_radians();
                let half = if s > scene_r {
                    ((scene_r / s).asin() * 1.1).min(max_half)
                } else {
                    max_half
                };
                let span = 2.0 * focal * half.tan();
                let w = (span.ceil() as u32).clamp(64.min(width), width);
                let h = (span.ceil() as u32).clamp(48.min(height), height);
                let fov = (2.0 * ((h as f64 * 0.5) / focal).atan()).to_degrees();
                let cam = Camera::look_at(w, h, fov, eye, scene_c, up);
                let img_cut = render(&cut, &cam, &ro);
                let img_ref = render(&reference, &cam, &ro);
                let v = ssim(&img_cut, &img_ref)?;
                match kind {
                    ViewKind::Street => {
                        row.street_ssim = row.street_ssim.min(v);
                        if a == 0 {
                            row.street_distance = s;
                        }
                    }
                    ViewKind::Aerial => row.aerial_ssim = row.aerial_ssim.min(v),
                }
                if a == 0
                    && let Some(dir) = &opts.pictures
                {
                    std::fs::create_dir_all(dir)?;
                    save(
                        &img_cut,
                        &dir.join(format!("level{level}-{}.png", kind.as_str())),
                    )?;
                    save(
                        &img_ref,
                        &dir.join(format!("level{level}-{}-leaves.png", kind.as_str())),
                    )?;
                }
            }
        }
        out.push(row);
    }
    Ok(out)
}

/// Content bytes the intended viewer (1280x720, 50 degrees, [`MAX_SSE`] px) loads looking at the
/// scene's centre from the first street and aerial directions at each of `distances` times the
/// scene's bounding radius, with every geometric error times `error_scale`: what a larger error
/// per clustering radius would cost in streamed bytes. Rows: (kind, distance multiple, bytes).
pub fn viewer_bytes(
    tileset: &Path,
    distances: &[f64],
    error_scale: f64,
) -> Result<Vec<(ViewKind, f64, u64)>, EvalError> {
    let ts = load_tileset(tileset)?;
    let up = splat2tiles_tiles::geometry::tileset_up(&ts);
    let (scene_c, scene_r) = scene_sphere(&ts)?;
    let east = up.any_orthonormal_vector();
    let north = up.cross(east);
    let mut sizes: HashMap<PathBuf, u64> = HashMap::new();
    let mut out = Vec::new();
    for kind in [ViewKind::Street, ViewKind::Aerial] {
        let az = 30f64.to_radians();
        let el = kind.elevation_deg().to_radians();
        let u = (east * az.cos() + north * az.sin()) * el.cos() + up * el.sin();
        for &m in distances {
            let cam = Camera::look_at(
                VIEWER_HEIGHT * 16 / 9,
                VIEWER_HEIGHT,
                DEFAULT_FOV_Y_DEG,
                scene_c + u * (scene_r * m),
                scene_c,
                up,
            );
            let mut bytes = 0;
            for path in select_tiles(&ts, &cam, MAX_SSE / error_scale) {
                bytes += match sizes.get(&path) {
                    Some(&b) => b,
                    None => {
                        let b = std::fs::metadata(&path)
                            .map_err(|e| EvalError(format!("{}: {e}", path.display())))?
                            .len();
                        sizes.insert(path, b);
                        b
                    }
                };
            }
            out.push((kind, m, bytes));
        }
    }
    Ok(out)
}

fn save(img: &Image, path: &Path) -> Result<(), EvalError> {
    img.save_png(path)
        .map_err(|e| EvalError(format!("{}: {e}", path.display())))
}

/// World-space centre and bounding-sphere radius of the root tile's box (the whole scene).
fn scene_sphere(ts: &LoadedTileset) -> Result<(DVec3, f64), EvalError> {
    let root = ts
        .root_index()
        .and_then(|i| ts.tiles[i].bounding_box)
        .ok_or_else(|| EvalError("root has no bounding box".into()))?;
    Ok(sphere(ts, &root))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn key(level: u32, x: u32, y: u32) -> TileKey {
        TileKey { level, x, y, z: 0 }
    }

    #[test]
    fn cut_takes_the_first_content_on_each_path() {
        // Root with content; (1,0,0) with content over two leaves; (1,1,0) without content over
        // a parent (2,2,0) with content over leaves; leaf (1,0,1) directly.
        let mut content = BTreeMap::new();
        for k in [
            TileKey::ROOT,
            key(1, 0, 0),
            key(2, 0, 0),
            key(2, 1, 0),
            key(2, 2, 0),
            key(3, 4, 0),
            key(3, 5, 0),
            key(1, 0, 1),
        ] {
            content.insert(k, 1.0);
        }
        let parents: HashSet<TileKey> = [TileKey::ROOT, key(1, 0, 0), key(1, 1, 0), key(2, 2, 0)]
            .into_iter()
            .collect();
        assert_eq!(cut_keys(&content, &parents, 0), vec![TileKey::ROOT]);
        assert_eq!(
            cut_keys(&content, &parents, 1),
            vec![key(1, 0, 0), key(1, 0, 1), key(2, 2, 0)]
        );
        assert_eq!(
            cut_keys(&content, &parents, 2),
            vec![key(1, 0, 1), key(2, 0, 0), key(2, 1, 0), key(2, 2, 0)]
        );
    }

    #[test]
    fn default_frame_has_the_viewers_pixel_scale() {
        // The renderer's low-pass is 0.3 px^2 whatever the image size, so only frames at the
        // viewer's focal length widen sub-pixel splats as the viewer does.
        let w = ViewOptions::default().width;
        let focal = fov_to_focal(DEFAULT_FOV_Y_DEG, w * 3 / 4);
        assert!(
            (focal - super::super::eval::viewer_focal()).abs() < 1e-9,
            "{focal}"
        );
    }

    #[test]
    fn exit_distance_leaves_the_sphere() {
        let u = DVec3::X;
        assert!((exit_distance(DVec3::ZERO, u, 2.0) - 2.0).abs() < 1e-12);
        // Starting 1 behind the centre along u: 3 to get 2 past it.
        assert!((exit_distance(-DVec3::X, u, 2.0) - 3.0).abs() < 1e-12);
        // Already outside and moving away.
        assert_eq!(exit_distance(DVec3::X * 5.0, u, 2.0), 0.0);
    }
}
