//! `--layers`: the staged contents rewritten as layers (`layers::build`) before the subtrees
//! are written, so the stored sizes are those of the layered files.

use super::tileset::TreeTile;
use super::{ConvertError, ConvertOptions, ConvertReport};
use crate::variants::{Variant, content_uri};
use splat2tiles_tiles::layers::build::{LayerError, layer_contents};
use splat2tiles_tiles::tiling::{Scheme, TileKey};
use std::collections::BTreeMap;
use std::path::Path;

/// Refuses options layered content does not support: no LOD (parents without content) and
/// variants other than Best (the layer extension is written into Best contents only).
pub(super) fn check_options(opts: &ConvertOptions) -> Result<(), ConvertError> {
    if !opts.lod.enabled {
        return Err(LayerError::Unsupported(
            "needs LOD parents (drop --no-lod): every ancestor of a layer must carry one".into(),
        )
        .into());
    }
    if opts.variants.written() != [Variant::Best] {
        return Err(LayerError::Unsupported(
            "writes the Best variant only (drop --variants and use the default --profile)".into(),
        )
        .into());
    }
    Ok(())
}

/// Layers every content of `tree` in `dir` and updates the stored byte counts.
pub(super) fn layer_tree(
    tree: &mut BTreeMap<TileKey, TreeTile>,
    scheme: Scheme,
    dir: &Path,
    report: &mut ConvertReport,
) -> Result<(), ConvertError> {
    let contents: BTreeMap<TileKey, std::path::PathBuf> = tree
        .iter()
        .filter(|(_, t)| t.has_content)
        .map(|(k, _)| (*k, dir.join(content_uri(scheme, *k, Variant::Best))))
        .collect();
    let sizes = layer_contents(&contents)?;
    for (k, size) in sizes {
        let t = tree.get_mut(&k).expect("layered tiles come from the tree");
        let Some(f) = t.facts.as_mut() else { continue };
        let old = f.variant_bytes[Variant::Best.index()] as u64;
        let size32 = u32::try_from(size).map_err(|_| {
            LayerError::Unsupported(format!("tile {k:?}: layered content over 4 GiB"))
        })?;
        f.variant_bytes[Variant::Best.index()] = size32;
        f.bytes = (f.bytes + size).saturating_sub(old);
        t.bytes = (t.bytes + size).saturating_sub(old);
        report.bytes = (report.bytes + size).saturating_sub(old);
    }
    Ok(())
}
