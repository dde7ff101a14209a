//! Layering a converted tileset's contents in place: the root's content becomes the base layer
//! and every other content a layer carrying the opacity deltas of its parent's splats.
//!
//! Parents are processed in parallel; each file is written once (temporary file, then renamed),
//! so a parent decoded while its own file is being replaced reads one whole version.

use super::deltas::{LayerPoints, parent_deltas};
use super::glb::add_layer;
use crate::encode::{GlbError, read_tile_glb};
use crate::tiling::TileKey;
use glam::{DMat4, DVec3};
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Why contents could not be layered.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum LayerError {
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The OS error.
        source: std::io::Error,
    },
    /// A content could not be decoded or re-encoded.
    #[error("{path}: {source}")]
    Glb {
        /// The file.
        path: PathBuf,
        /// What was wrong.
        source: GlbError,
    },
    /// A tile has content but its parent has none (no LOD parents).
    #[error(
        "tile {level}/{x}/{y}/{z} has content but its parent has none: layered content needs a layer in every ancestor (build with LOD)"
    )]
    MissingParent {
        /// Level.
        level: u32,
        /// x.
        x: u32,
        /// y.
        y: u32,
        /// z.
        z: u32,
    },
    /// Layers were asked for with options they do not support.
    #[error("--layers: {0}")]
    Unsupported(String),
    /// The root tile has no content, so there is no base layer.
    #[error("the root tile has no content: a layered tileset needs a base layer")]
    MissingBase,
}

/// A decoded layer: file bytes and splat centres and opacities in the glTF world frame.
struct Loaded {
    bytes: Vec<u8>,
    centres: Vec<[f64; 3]>,
    opacities: Vec<f32>,
}

fn load(path: &Path) -> Result<Loaded, LayerError> {
    let bytes = std::fs::read(path).map_err(|source| LayerError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let tile = read_tile_glb(&bytes).map_err(|source| LayerError::Glb {
        path: path.to_path_buf(),
        source,
    })?;
    let m = DMat4::from_cols_array(&tile.node_matrix);
    let centres = tile
        .splats
        .positions
        .iter()
        .map(|p| m.transform_point3(DVec3::from_array(*p)).to_array())
        .collect();
    Ok(Loaded {
        bytes,
        centres,
        opacities: tile.splats.opacities,
    })
}

/// Writes `bytes` to `path` through a temporary file renamed over it.
fn replace(path: &Path, bytes: &[u8]) -> Result<(), LayerError> {
    let io = |source| LayerError::Io {
        path: path.to_path_buf(),
        source,
    };
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".layer-tmp");
    let tmp = PathBuf::from(tmp);
    std::fs::write(&tmp, bytes).map_err(io)?;
    std::fs::rename(&tmp, path).map_err(io)
}

fn encode(path: &Path, bytes: &[u8], level: u32, d: Option<&[f32]>) -> Result<Vec<u8>, LayerError> {
    add_layer(bytes, level, d).map_err(|source| LayerError::Glb {
        path: path.to_path_buf(),
        source,
    })
}

/// Rewrites every content in `contents` (tile -> its glb) as a layer: the root's as the base,
/// each other one with its parent's opacity deltas ([`parent_deltas`], centres compared in
/// the glTF world frame of the tiles' node matrices). Returns each file's new size.
pub fn layer_contents(
    contents: &BTreeMap<TileKey, PathBuf>,
) -> Result<BTreeMap<TileKey, u64>, LayerError> {
    let root = contents
        .get(&TileKey::ROOT)
        .ok_or(LayerError::MissingBase)?;
    let mut groups: BTreeMap<TileKey, Vec<TileKey>> = BTreeMap::new();
    for &k in contents.keys() {
        if let Some(p) = k.parent() {
            if !contents.contains_key(&p) {
                return Err(LayerError::MissingParent {
                    level: k.level,
                    x: k.x,
                    y: k.y,
                    z: k.z,
                });
            }
            groups.entry(p).or_default().push(k);
        }
    }
    let mut sizes = BTreeMap::new();
    let base = std::fs::read(root).map_err(|source| LayerError::Io {
        path: root.clone(),
        source,
    })?;
    let base = encode(root, &base, 0, None)?;
    replace(root, &base)?;
    sizes.insert(TileKey::ROOT, base.len() as u64);
    let groups: Vec<(TileKey, Vec<TileKey>)> = groups.into_iter().collect();
    let written: Vec<Vec<(TileKey, u64)>> = groups
        .par_iter()
        .map(|(parent, kids)| {
            let p = load(&contents[parent])?;
            let loaded: Vec<Loaded> = kids
                .iter()
                .map(|k| load(&contents[k]))
                .collect::<Result<_, _>>()?;
            let points: Vec<LayerPoints<'_>> = loaded
                .iter()
                .map(|l| LayerPoints {
                    centres: &l.centres,
                    opacities: &l.opacities,
                })
                .collect();
            let deltas = parent_deltas(
                LayerPoints {
                    centres: &p.centres,
                    opacities: &p.opacities,
                },
                &points,
            );
            let mut out = Vec::with_capacity(kids.len());
            for ((k, l), d) in kids.iter().zip(&loaded).zip(&deltas) {
                let path = &contents[k];
                let bytes = encode(path, &l.bytes, k.level, Some(d))?;
                replace(path, &bytes)?;
                out.push((*k, bytes.len() as u64));
            }
            Ok(out)
        })
        .collect::<Result<_, LayerError>>()?;
    sizes.extend(written.into_iter().flatten());
    Ok(sizes)
}
