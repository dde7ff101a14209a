//! `import-lapisgs` on level files that follow the prefix rule exactly but leave cells of the
//! coarser levels empty: the tileset it writes must validate (every layer has a parent layer).

use super::common::lapis::{levels, write_levels};
use splat2tiles_build::convert::{ConvertOptions, SchemeChoice, import_lapisgs};
use splat2tiles_tiles::tiling::TileKey;
use splat2tiles_tiles::tiling::load::load_tileset;
use splat2tiles_validate::{ValidateOptions, validate_tileset};
use std::collections::HashSet;

fn opts() -> ConvertOptions {
    ConvertOptions {
        scheme: SchemeChoice::Octree,
        subtree_levels: Some(2),
        layers: true,
        progress: None,
        ..ConvertOptions::default()
    }
}

/// Six levels whose splats follow the prefix rule exactly (no opacity changes), each level three
/// to forty times the one above: a level's tile often lies under cells of two or more levels
/// above that hold no splat. Each such cell gets a placeholder, so every layer has its parent
/// (without one, validate reports LAYER_PARENT_MISSING for the layers below) and the tileset
/// validates.
#[test]
fn deep_levels_under_empty_cells_get_a_parent_at_every_level() {
    let dir = tempfile::tempdir().unwrap();
    let all = super::common::random_splats(3000, 0, 10.0, 31);
    let lv = levels(&all, &[1, 3, 9, 27, 81, 3000], |_, _| false);
    let files = write_levels(dir.path(), &lv);
    let out = dir.path().join("lapis");
    let r = import_lapisgs(&files, &out, &opts()).unwrap();
    assert!(r.placeholders >= 2, "{r:?}");
    let report = validate_tileset(&out.join("tileset.json"), &ValidateOptions::default()).unwrap();
    assert!(report.codes().is_empty(), "{}", report.to_text("lapis"));
    let ts = load_tileset(&out.join("tileset.json")).unwrap();
    let keys: HashSet<TileKey> = ts
        .tiles
        .iter()
        .filter(|t| t.content.is_some())
        .map(|t| t.key)
        .collect();
    for k in &keys {
        if let Some(p) = k.parent() {
            assert!(keys.contains(&p), "tile {k:?} has no parent layer");
        }
    }
}
