//! Adaptive partition of splat centres into implicit-tiling leaf tiles: sort by Morton code at
//! the deepest level, then split a code range while it holds more than the leaf budget.

use super::morton;
use rayon::prelude::*;

/// Implicit subdivision scheme.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scheme {
    /// Four children per tile (x, y halved).
    Quadtree,
    /// Eight children per tile (x, y, z halved).
    Octree,
}

impl Scheme {
    /// Axes subdivided: 2 or 3.
    pub fn dims(self) -> u32 {
        match self {
            Scheme::Quadtree => 2,
            Scheme::Octree => 3,
        }
    }

    /// Children per tile: 4 or 8.
    pub fn arity(self) -> u64 {
        1 << self.dims()
    }

    /// Deepest level the Morton codes can address (31 for quadtrees, 21 for octrees).
    pub fn max_depth(self) -> u32 {
        match self {
            Scheme::Quadtree => 31,
            Scheme::Octree => 21,
        }
    }

    /// The `subdivisionScheme` string of 3D Tiles.
    pub fn as_str(self) -> &'static str {
        match self {
            Scheme::Quadtree => "QUADTREE",
            Scheme::Octree => "OCTREE",
        }
    }

    /// Morton code of tile coordinates.
    pub fn encode(self, x: u32, y: u32, z: u32) -> u64 {
        match self {
            Scheme::Quadtree => morton::encode2(x, y),
            Scheme::Octree => morton::encode3(x, y, z),
        }
    }

    /// Tile coordinates of a Morton code (z = 0 for quadtrees).
    pub fn decode(self, code: u64) -> (u32, u32, u32) {
        match self {
            Scheme::Quadtree => {
                let (x, y) = morton::decode2(code);
                (x, y, 0)
            }
            Scheme::Octree => morton::decode3(code),
        }
    }
}

/// A tile address in an implicit tree.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct TileKey {
    /// Level, 0 at the root.
    pub level: u32,
    /// x index at that level.
    pub x: u32,
    /// y index at that level.
    pub y: u32,
    /// z index at that level (0 for quadtrees).
    pub z: u32,
}

impl TileKey {
    /// The root tile.
    pub const ROOT: TileKey = TileKey {
        level: 0,
        x: 0,
        y: 0,
        z: 0,
    };

    /// The parent tile; `None` for the root.
    pub fn parent(self) -> Option<TileKey> {
        (self.level > 0).then(|| TileKey {
            level: self.level - 1,
            x: self.x >> 1,
            y: self.y >> 1,
            z: self.z >> 1,
        })
    }

    /// The ancestor at `level` (self when equal).
    pub fn ancestor(self, level: u32) -> TileKey {
        let d = self.level - level;
        TileKey {
            level,
            x: self.x >> d,
            y: self.y >> d,
            z: self.z >> d,
        }
    }
}

/// One leaf tile and the splats it holds.
#[derive(Debug, Clone, PartialEq)]
pub struct Leaf {
    /// Where the leaf sits.
    pub key: TileKey,
    /// Indices of its splats, in Morton order of their centres.
    pub indices: Vec<usize>,
}

/// The result of partitioning.
#[derive(Debug, Clone, PartialEq)]
pub struct Partition {
    /// Subdivision scheme.
    pub scheme: Scheme,
    /// Leaves in Morton order of their keys at the deepest level.
    pub leaves: Vec<Leaf>,
    /// `availableLevels`: deepest leaf level + 1.
    pub levels: u32,
}

/// Morton code at `depth` of the cell holding unit coordinates `p` (each in [0, 1]; values
/// outside are clamped, NaN goes to 0).
pub fn code_of(p: [f64; 3], scheme: Scheme, depth: u32) -> u64 {
    let cells = (1u64 << depth) as f64;
    let max = (1u64 << depth) - 1;
    let q = |v: f64| -> u32 {
        let c = (v * cells).floor();
        if c.is_nan() || c < 0.0 {
            0
        } else {
            (c as u64).min(max) as u32
        }
    };
    scheme.encode(q(p[0]), q(p[1]), q(p[2]))
}

/// Quantises unit coordinates to integer cells at `depth` and returns their Morton codes.
fn codes(unit: &[[f64; 3]], scheme: Scheme, depth: u32) -> Vec<u64> {
    unit.par_iter()
        .map(|p| code_of(*p, scheme, depth))
        .collect()
}

/// Splits splats (given by their centres in unit coordinates of the root volume) into leaves of
/// at most `max_splats` each, subdividing no deeper than `max_depth` (a leaf at that depth may
/// hold more: coincident splats cannot be separated).
pub fn partition(
    unit: &[[f64; 3]],
    scheme: Scheme,
    max_splats: usize,
    max_depth: u32,
) -> Partition {
    partition_subtree(unit, scheme, max_splats, max_depth, TileKey::ROOT)
}

/// [`partition`] of the splats of one subtree rooted at `root` (all of them in its cell): the
/// same leaves a partition of the whole scene gives inside `root`, provided the whole scene's
/// partition splits `root`'s parent (it holds more than `max_splats`). The out-of-core
/// converter builds each region this way.
pub fn partition_subtree(
    unit: &[[f64; 3]],
    scheme: Scheme,
    max_splats: usize,
    max_depth: u32,
    root: TileKey,
) -> Partition {
    partition_subtree_with(unit, scheme, max_splats, max_depth, root, &|_| false)
}

/// [`partition_subtree`] that also splits every tile `must_split` names (a view-optimised plan,
/// `partition::plan`), while it holds splats and is above the deepest level.
pub fn partition_subtree_with(
    unit: &[[f64; 3]],
    scheme: Scheme,
    max_splats: usize,
    max_depth: u32,
    root: TileKey,
    must_split: &dyn Fn(TileKey) -> bool,
) -> Partition {
    let depth = max_depth.min(scheme.max_depth());
    let code = codes(unit, scheme, depth);
    let mut order: Vec<usize> = (0..unit.len()).collect();
    order.par_sort_unstable_by_key(|&i| (code[i], i));
    let sorted: Vec<u64> = order.iter().map(|&i| code[i]).collect();

    let mut leaves = Vec::new();
    let mut stack = vec![(root.level.min(depth), 0usize, order.len())];
    // Depth-first, children pushed in reverse so leaves come out in Morton order.
    while let Some((level, lo, hi)) = stack.pop() {
        if hi == lo {
            continue;
        }
        let prefix = sorted[lo] >> (scheme.dims() * (depth - level));
        let (x, y, z) = scheme.decode(prefix);
        let key = TileKey { level, x, y, z };
        if (hi - lo <= max_splats.max(1) && !must_split(key)) || level == depth {
            leaves.push(Leaf {
                key,
                indices: order[lo..hi].to_vec(),
            });
            continue;
        }
        let shift = scheme.dims() * (depth - level - 1);
        let mask = scheme.arity() - 1;
        let mut bounds = Vec::with_capacity(scheme.arity() as usize + 1);
        let mut start = lo;
        for child in 0..scheme.arity() {
            let end = lo + sorted[lo..hi].partition_point(|c| (c >> shift) & mask <= child);
            bounds.push((start, end));
            start = end;
        }
        for &(a, b) in bounds.iter().rev() {
            stack.push((level + 1, a, b));
        }
    }
    let levels = leaves.iter().map(|l| l.key.level + 1).max().unwrap_or(1);
    Partition {
        scheme,
        leaves,
        levels,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lcg(seed: &mut u64) -> f64 {
        *seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (*seed >> 11) as f64 / (1u64 << 53) as f64
    }

    fn check_invariants(p: &Partition, unit: &[[f64; 3]], max: usize, depth: u32) {
        let mut seen = vec![false; unit.len()];
        for leaf in &p.leaves {
            assert!(leaf.indices.len() <= max || leaf.key.level == depth);
            let n = 1u32 << leaf.key.level;
            for &i in &leaf.indices {
                assert!(!seen[i], "splat {i} in two leaves");
                seen[i] = true;
                // The splat lies in the leaf's cell.
                let cell = |v: f64| ((v * n as f64).floor() as i64).clamp(0, n as i64 - 1) as u32;
                assert_eq!(cell(unit[i][0]), leaf.key.x);
                assert_eq!(cell(unit[i][1]), leaf.key.y);
                if p.scheme == Scheme::Octree {
                    assert_eq!(cell(unit[i][2]), leaf.key.z);
                }
            }
        }
        assert!(seen.iter().all(|&s| s), "every splat in some leaf");
        // No leaf is an ancestor of another.
        for a in &p.leaves {
            for b in &p.leaves {
                if a.key.level < b.key.level {
                    assert_ne!(b.key.ancestor(a.key.level), a.key);
                }
            }
        }
    }

    #[test]
    fn octree_and_quadtree_invariants() {
        let mut seed = 7;
        let unit: Vec<[f64; 3]> = (0..5000)
            .map(|_| {
                let c = lcg(&mut seed);
                // Clustered: half the points in a small corner.
                let s = if c < 0.5 { 0.05 } else { 1.0 };
                [lcg(&mut seed) * s, lcg(&mut seed) * s, lcg(&mut seed) * s]
            })
            .collect();
        for scheme in [Scheme::Octree, Scheme::Quadtree] {
            let p = partition(&unit, scheme, 100, 12);
            check_invariants(&p, &unit, 100, 12);
            assert!(p.levels > 2);
            assert!(p.leaves.len() > 50);
        }
    }

    #[test]
    fn coincident_points_stop_at_max_depth() {
        let unit = vec![[0.3, 0.3, 0.3]; 50];
        let p = partition(&unit, Scheme::Octree, 10, 6);
        assert_eq!(p.leaves.len(), 1);
        assert_eq!(p.leaves[0].key.level, 6);
        assert_eq!(p.leaves[0].indices.len(), 50);
        check_invariants(&p, &unit, 10, 6);
    }

    #[test]
    fn small_scene_is_one_root_leaf_and_edges_clamp() {
        let unit = vec![[0.0, 0.0, 0.0], [1.0, 1.0, 1.0], [f64::NAN, 2.0, -1.0]];
        let p = partition(&unit, Scheme::Octree, 10, 8);
        assert_eq!(p.leaves.len(), 1);
        assert_eq!(p.leaves[0].key, TileKey::ROOT);
        assert_eq!(p.levels, 1);
        let p = partition(&unit, Scheme::Octree, 1, 3);
        assert_eq!(p.leaves.len(), 3);
        let empty = partition(&[], Scheme::Quadtree, 10, 8);
        assert!(empty.leaves.is_empty());
    }

    #[test]
    fn a_subtree_partition_gives_the_whole_scenes_leaves_inside_it() {
        let mut seed = 5;
        let unit: Vec<[f64; 3]> = (0..6000)
            .map(|_| {
                let s = if lcg(&mut seed) < 0.6 { 0.2 } else { 1.0 };
                [lcg(&mut seed) * s, lcg(&mut seed) * s, lcg(&mut seed) * s]
            })
            .collect();
        let whole = partition(&unit, Scheme::Octree, 50, 10);
        // Every level-2 tile whose parent was split: its splats alone give the same leaves.
        let mut checked = 0;
        for root in whole
            .leaves
            .iter()
            .filter(|l| l.key.level >= 2)
            .map(|l| l.key.ancestor(2))
        {
            let inside: Vec<usize> = (0..unit.len())
                .filter(|&i| {
                    let c = |v: f64| ((v * 4.0).floor() as i64).clamp(0, 3) as u32;
                    (c(unit[i][0]), c(unit[i][1]), c(unit[i][2])) == (root.x, root.y, root.z)
                })
                .collect();
            let sub_unit: Vec<[f64; 3]> = inside.iter().map(|&i| unit[i]).collect();
            let sub = partition_subtree(&sub_unit, Scheme::Octree, 50, 10, root);
            let expect: Vec<(TileKey, Vec<usize>)> = whole
                .leaves
                .iter()
                .filter(|l| l.key.level >= 2 && l.key.ancestor(2) == root)
                .map(|l| (l.key, l.indices.clone()))
                .collect();
            let got: Vec<(TileKey, Vec<usize>)> = sub
                .leaves
                .iter()
                .map(|l| (l.key, l.indices.iter().map(|&k| inside[k]).collect()))
                .collect();
            assert_eq!(got, expect, "{root:?}");
            checked += 1;
        }
        assert!(checked > 8);
    }

    #[test]
    fn deterministic() {
        let mut seed = 1;
        let unit: Vec<[f64; 3]> = (0..3000)
            .map(|_| [lcg(&mut seed), lcg(&mut seed), 0.5])
            .collect();
        assert_eq!(
            partition(&unit, Scheme::Quadtree, 64, 10),
            partition(&unit, Scheme::Quadtree, 64, 10)
        );
    }
}
