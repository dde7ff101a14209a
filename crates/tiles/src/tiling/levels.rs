//! Which parent tiles carry a level-of-detail content, and geometric errors that never grow down
//! the tree and never let a traversal stop at a tile without content (spec/georeferencing.md).

use super::TileKey;
use std::collections::{BTreeMap, HashMap};

/// Whether a built parent is written with its content: the root always, and every tile with
/// two or more children. A tile below the root with a single child is a pass-through: written
/// without content, with its parent's bounding box and geometric error, so a
/// REPLACE traversal refines it exactly when it refines the parent and never stops there with
/// nothing to draw. Every other tile holds an approximation of everything below it, however few
/// splats that takes: a distant object is drawn as a blob of merged splats, never dropped.
pub fn keeps_content(key: TileKey, children: usize) -> bool {
    key.parent().is_none() || children != 1
}

/// Children of every tile of `keys` (a tree: every key's ancestors are in it).
pub fn child_counts<'a>(keys: impl IntoIterator<Item = &'a TileKey>) -> HashMap<TileKey, usize> {
    let mut n = HashMap::new();
    for k in keys {
        if let Some(p) = k.parent() {
            *n.entry(p).or_insert(0) += 1;
        }
    }
    n
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
    fn content_everywhere_but_single_child_chains() {
        assert!(keeps_content(TileKey::ROOT, 1));
        assert!(keeps_content(TileKey::ROOT, 4));
        assert!(keeps_content(key(3, 1, 2), 2));
        assert!(!keeps_content(key(3, 1, 2), 1));
        let keys = [TileKey::ROOT, key(1, 0, 0), key(1, 1, 0), key(2, 0, 0)];
        let n = child_counts(&keys);
        assert_eq!(n[&TileKey::ROOT], 2);
        assert_eq!(n[&key(1, 0, 0)], 1);
        assert!(!n.contains_key(&key(2, 0, 0)));
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
