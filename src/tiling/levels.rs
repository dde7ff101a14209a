//! Which parent tiles carry a level-of-detail content, and geometric errors that never grow down
//! the tree: no chains of near-empty levels above a scene (spec/georeferencing.md).

use super::TileKey;
use std::collections::BTreeMap;

/// Fewest splats a parent (LOD) content holds: 32 (a few kB, less than a request's overhead
/// buys), or the leaf budget when that is smaller.
pub fn content_floor(max_splats_per_tile: usize) -> usize {
    32.min(max_splats_per_tile.max(1))
}

/// Whether a parent whose clustering kept `splats` splats within `radius` is a real level of
/// detail for a tile whose box has diagonal `diagonal`: it holds at least the floor of splats,
/// and the radius is below the diagonal (a client shows a content while its error projects to
/// under its screen-space threshold; with radius >= diagonal the whole tile is that small then,
/// and the content is a blob of a few merged splats).
pub fn keeps_content(
    splats: usize,
    radius: f64,
    diagonal: f64,
    max_splats_per_tile: usize,
) -> bool {
    splats >= content_floor(max_splats_per_tile) && radius < diagonal
}

/// Raises each tile's error to the largest error below it, so errors never grow from a tile to
/// its children (the REPLACE rule refines a tile only while its error is too large on screen).
/// Every key's ancestors must be in the map.
pub fn monotone_errors(errors: &mut BTreeMap<TileKey, f64>) {
    // Keys order by level first: walk from the deepest level up.
    let keys: Vec<TileKey> = errors.keys().rev().copied().collect();
    for k in keys {
        if let Some(p) = k.parent() {
            let e = errors[&k];
            if let Some(pe) = errors.get_mut(&p)
                && *pe < e
            {
                *pe = e;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn key(level: u32, x: u32, y: u32) -> TileKey {
        TileKey { level, x, y, z: 0 }
    }

    #[test]
    fn floor_and_radius_rule() {
        assert_eq!(content_floor(32_768), 32);
        assert_eq!(content_floor(500), 32);
        assert_eq!(content_floor(10), 10);
        assert!(keeps_content(600, 0.1, 2.0, 32_768));
        // A chain tile: a handful of splats merged over a radius larger than the tile.
        assert!(!keeps_content(7, 0.1, 2.0, 32_768));
        assert!(!keeps_content(5000, 3.0, 2.0, 32_768));
    }

    #[test]
    fn errors_never_grow_downwards() {
        let mut e = BTreeMap::new();
        e.insert(TileKey::ROOT, 1.0);
        e.insert(key(1, 0, 0), 4.0);
        e.insert(key(1, 1, 0), 0.5);
        e.insert(key(2, 0, 0), 9.0);
        e.insert(key(2, 3, 1), 0.0);
        monotone_errors(&mut e);
        assert_eq!(e[&key(1, 0, 0)], 9.0);
        assert_eq!(e[&TileKey::ROOT], 9.0);
        assert_eq!(e[&key(1, 1, 0)], 0.5);
        assert_eq!(e[&key(2, 3, 1)], 0.0);
    }
}
