//! The reference renderer's view of a layered tileset: the layers a camera draws (every tile
//! reached, ADD), each child's blend factor from its parent's screen-space error (eq. 4), and
//! their splats at effective opacity, ready for `render::raster::render`.

use super::blend::{AncestorDelta, DrawnLayer, blend_factor, drawn_layers};
use super::glb::read_layer;
use crate::encode::read_tile_glb;
use crate::tiling::TileKey;
use crate::tiling::load::CONTENT_FILE;
use crate::tiling::load::LoadedTileset;
use glam::DMat4;
use splat2tiles_core::camera::Camera;
use splat2tiles_core::splat::Splats;
use splat2tiles_io::bounded::read_file;
use std::path::PathBuf;

/// One layer a camera draws.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewLayer {
    /// Its tile.
    pub key: TileKey,
    /// Its content file.
    pub path: PathBuf,
    /// Index of its parent layer in the same list (`None`: the base).
    pub parent: Option<usize>,
    /// Its blend factor.
    pub blend: f32,
}

/// Whether `ts` is layered: the implicit root refines by ADD and its content declares
/// `SPLAT2TILES_layer`.
pub fn is_layered(ts: &LoadedTileset) -> bool {
    if ts.tileset.root.refine.as_deref() != Some("ADD") {
        return false;
    }
    let Some(path) = ts.root_index().and_then(|i| ts.tiles[i].content.as_ref()) else {
        return false;
    };
    read_file(path, CONTENT_FILE)
        .ok()
        .is_some_and(|b| matches!(read_layer(&b), Ok(Some(_))))
}

/// The layers `cam` draws: from the root, every tile reached is drawn; a tile whose
/// screen-space error exceeds `max_sse` brings in its children with blend factor
/// `blend_factor(its error, max_sse)`, ancestors before descendants.
pub fn select_layers(ts: &LoadedTileset, cam: &Camera, max_sse: f64) -> Vec<ViewLayer> {
    let children = ts.children();
    let Some(root) = ts.root_index() else {
        return vec![];
    };
    let Some(path) = ts.tiles[root].content.clone() else {
        return vec![];
    };
    let mut out = vec![ViewLayer {
        key: TileKey::ROOT,
        path,
        parent: None,
        blend: 1.0,
    }];
    let mut tile_of = vec![root];
    let mut next = 0;
    while next < out.len() {
        let i = tile_of[next];
        let s = crate::geometry::tile_sse(ts, i, cam);
        if s > max_sse
            && let Some(kids) = children.get(&ts.tiles[i].key)
        {
            let t = blend_factor(s, max_sse);
            let mut kids = kids.clone();
            kids.sort_by_key(|&k| ts.tiles[k].key);
            for k in kids {
                if let Some(path) = ts.tiles[k].content.clone()
                    && t > 0.0
                {
                    out.push(ViewLayer {
                        key: ts.tiles[k].key,
                        path,
                        parent: Some(next),
                        blend: t,
                    });
                    tile_of.push(k);
                }
            }
        }
        next += 1;
    }
    out
}

/// Why a layered cut could not be drawn (the message names the file).
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct LayerViewError(String);

/// The splats `cam` draws from layered `ts` (effective opacities, occupancy rule applied), each
/// with its content's model matrix.
pub fn layered_instances(
    ts: &LoadedTileset,
    cam: &Camera,
    max_sse: f64,
) -> Result<Vec<(Splats, DMat4)>, LayerViewError> {
    let picked = select_layers(ts, cam, max_sse);
    let mut decoded = Vec::with_capacity(picked.len());
    for l in &picked {
        let at = |e: &dyn std::fmt::Display| LayerViewError(format!("{}: {e}", l.path.display()));
        let bytes = read_file(&l.path, CONTENT_FILE).map_err(|e| LayerViewError(e.to_string()))?;
        let tile = read_tile_glb(&bytes).map_err(|e| at(&e))?;
        let layer = read_layer(&bytes).map_err(|e| at(&e))?;
        decoded.push((tile, layer));
    }
    let ancestors: Vec<Vec<AncestorDelta<'_>>> = picked
        .iter()
        .zip(&decoded)
        .map(|(l, (_, layer))| ancestor_deltas(l.key.level, layer.as_ref()))
        .collect();
    let layers: Vec<DrawnLayer<'_>> = picked
        .iter()
        .zip(&decoded)
        .zip(&ancestors)
        .map(|((l, (tile, layer)), a)| DrawnLayer {
            splats: &tile.splats,
            parent: l.parent,
            deltas: layer
                .as_ref()
                .and_then(|x| x.parent_opacity_delta.as_deref()),
            blend: l.blend,
            ancestors: a,
        })
        .collect();
    let drawn = drawn_layers(&layers).map_err(|e| {
        let at = match &e {
            super::blend::ComposeError::BadParent(k)
            | super::blend::ComposeError::BadAncestor(k)
            | super::blend::ComposeError::DeltaCount { layer: k, .. } => picked[*k].path.display(),
        };
        LayerViewError(format!("{at}: {e}"))
    })?;
    Ok(drawn
        .into_iter()
        .zip(&decoded)
        .map(|(s, (tile, _))| (s, crate::geometry::content_model(ts, &tile.node_matrix)))
        .collect())
}

/// The ancestor deltas of a layer at tile level `level` (format v2), each as the number of
/// generations up to its ancestor; empty for a v1 layer or none. An ancestor level at or
/// above `level` (refused by `read_layer`) gives `up` 0, which composing refuses.
pub fn ancestor_deltas(
    level: u32,
    layer: Option<&super::glb::LayerInfo>,
) -> Vec<AncestorDelta<'_>> {
    layer.map_or(vec![], |l| {
        l.ancestor_opacity_deltas
            .iter()
            .map(|a| AncestorDelta {
                up: level.saturating_sub(a.level) as usize,
                deltas: &a.deltas,
            })
            .collect()
    })
}
