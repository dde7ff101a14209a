//! Top stage: the LOD parents above the region roots, built bottom-up from the roots' contents
//! with [`crate::lod::build_parent`], children in the same (Morton) order and with the same
//! parameters as a whole-scene build, so the result does not depend on the region split.

use super::ConvertError;
use super::region::{RegionCtx, RootContent, WrittenParent, write_parent};
use super::store::ContentStore;
use crate::lod::{ChildContent, ParentParams, ParentTile, build_parent};
use rayon::prelude::*;
use splat2tiles_tiles::tiling::TileKey;
use std::collections::{BTreeMap, HashMap};

/// Builds and writes every tile above the region roots `roots` (in Morton order, disjoint
/// subtrees) up to the root, or up to the first tile `ceiling` holds (the units of a sharded
/// part); nothing when one region covers the whole tree.
pub(super) fn build_top(
    roots: &[RootContent],
    store: &ContentStore,
    sh_degree: u8,
    r: f64,
    cx: &RegionCtx<'_>,
    ceiling: &dyn Fn(TileKey) -> bool,
) -> Result<BTreeMap<TileKey, WrittenParent>, ConvertError> {
    let mut deepest: HashMap<TileKey, u32> = HashMap::new();
    let mut children: BTreeMap<TileKey, Vec<TileKey>> = BTreeMap::new();
    for root in roots {
        let mut k = root.key;
        while !ceiling(k)
            && let Some(p) = k.parent()
        {
            let e = deepest.entry(p).or_insert(root.deepest);
            *e = (*e).max(root.deepest);
            let kids = children.entry(p).or_default();
            if !kids.contains(&k) {
                kids.push(k);
            }
            k = p;
        }
    }
    let mut out = BTreeMap::new();
    let Some(max_level) = children.keys().map(|k| k.level).max() else {
        return Ok(out);
    };
    for level in (0..=max_level).rev() {
        let keys: Vec<TileKey> = children
            .keys()
            .filter(|k| k.level == level)
            .copied()
            .collect();
        let made: Vec<Result<(TileKey, WrittenParent), ConvertError>> = keys
            .par_iter()
            .map(|&key| {
                let mut loaded = Vec::with_capacity(children[&key].len());
                for c in &children[&key] {
                    let content = store.get(*c)?.ok_or_else(|| ConvertError::Io {
                        path: "content store".into(),
                        what: "finding a region root's content",
                        source: std::io::Error::other(format!("tile {c:?} was never stored")),
                    })?;
                    loaded.push(content);
                }
                let kids: Vec<ChildContent<'_>> = loaded
                    .iter()
                    .map(|(s, radius)| ChildContent {
                        splats: s,
                        radius: *radius,
                    })
                    .collect();
                let params = ParentParams {
                    levels_above_deepest: deepest[&key] - key.level,
                    ..cx.parent_params(r)
                };
                let tile: ParentTile = build_parent(key, sh_degree, &kids, &params);
                drop(loaded);
                let w = write_parent(&tile, cx)?;
                store.put(key, &tile.splats, tile.radius)?;
                Ok((key, w))
            })
            .collect();
        for m in made {
            let (key, w) = m?;
            out.insert(key, w);
        }
    }
    Ok(out)
}
