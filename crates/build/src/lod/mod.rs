//! Level of detail: parent tiles built bottom-up by opacity-weighted clustering of their children's
//! splats (TileSplat sec. 3.1.2, eq. 2), each parent aiming at a fixed share of the tile budget.
//!
//! A parent clusters the union of its children's splats into about [`target_count`] splats
//! (half the tile budget, at most a fifth of its input; [`count_cap`] is the hard limit, and the
//! root's target) with one radius chosen from the input's grid occupancy (`radius`), its error
//! at least [`MIN_RADIUS_GROWTH`] times its children's. Its geometric error is
//! [`ERROR_PER_RADIUS`] times the radius it used; merged splats keep the opacity mass they are
//! drawn with at that distance ([`DRAWN_DILATION_PER_RADIUS2`]). Every parent's work is bounded
//! by its input (at most arity x budget splats), so the whole build is linear in the scene size.

pub mod cluster;
pub mod eval;
pub mod math;
pub mod merge;
pub mod radius;
pub mod views;

pub use cluster::{Clustered, cluster, cluster_drawn, cluster_to_budget, cluster_to_target};
pub use merge::{MergeRule, merge_all, merge_drawn, merge_into};

use eval::MAX_SSE;
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use rayon::prelude::*;
use splat2tiles_core::splat::Splats;
use splat2tiles_core::splat::importance::importance_order;
use splat2tiles_render::raster::LOW_PASS;
use splat2tiles_tiles::tiling::TileKey;
use std::collections::{BTreeMap, HashMap};

/// Divisor of the deepest leaf tile's size giving the default leaf radius `r` (see
/// [`default_leaf_radius`]).
pub const LEAF_SIZE_DIVISOR: f64 = 16.0;

/// A parent aims at the tile budget divided by this many splats.
pub const TARGET_DIVISOR: usize = 2;

/// A parent keeps at most this share of its input, so every level is a real reduction.
pub const MAX_KEEP: f64 = 0.25;

/// A parent's geometric error is at least its children's largest times this, so errors grow
/// strictly up the tree (a larger floor would let one sparse child coarsen its whole parent).
pub const MIN_RADIUS_GROWTH: f64 = 1.25;

/// A parent's geometric error is its clustering radius times this, so it is drawn from where its
/// clustering radius spans `MAX_SSE / ERROR_PER_RADIUS` (about 2.7) viewer pixels. Measured on a
/// generated 5M city at the viewer's pixel scale (BENCHMARKS.md "Level of detail on generated
/// cities"), 4 radii left levels 1 and 2 at SSIM 0.889 and 0.909 from the air; 6 lifts every level
/// with parents to 0.90 or more, at the cost of streaming more bytes at a given distance.
pub const ERROR_PER_RADIUS: f64 = 6.0;

/// World-space variance, per squared clustering radius, that a viewer's rasterizer adds to every
/// splat where a parent is first drawn: at its switching distance one pixel spans
/// `error / MAX_SSE` (`lod::eval::MAX_SSE`, 16 px), and 3DGS rasterizers (the reference renderer,
/// every web viewer) add `LOW_PASS` = 0.3 px^2 to each projected covariance. Sub-pixel leaves are
/// drawn that wide with their full opacity; merged splats keep the opacity mass they are drawn
/// with (`merge::merge_drawn`).
pub const DRAWN_DILATION_PER_RADIUS2: f64 =
    LOW_PASS * (ERROR_PER_RADIUS / MAX_SSE) * (ERROR_PER_RADIUS / MAX_SSE);

/// How many splats a parent whose children hold `input` splats aims at:
/// `min(budget / TARGET_DIVISOR, 0.8 * input * MAX_KEEP)`, at least 1 (below [`count_cap`], so
/// that an estimate a little over the target rarely needs a second clustering).
pub fn target_count(input: usize, budget: usize) -> usize {
    let share = (budget / TARGET_DIVISOR).max(1);
    let keep = (input as f64 * MAX_KEEP * 0.8).ceil() as usize;
    share.min(keep).max(1)
}

/// Most splats a parent whose children hold `input` splats may keep (a hard limit):
/// `min(budget, ceil(input * MAX_KEEP))`, at least 1.
pub fn count_cap(input: usize, budget: usize) -> usize {
    let keep = (input as f64 * MAX_KEEP).ceil() as usize;
    budget.min(keep).max(1)
}

/// Settings of the LOD build.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LodOptions {
    /// Build parents at all (off: parents stay empty, as before LOD existed).
    pub enabled: bool,
    /// Shape rule for merged splats.
    pub merge: MergeRule,
    /// Leaf clustering radius `r` in scene units; `None` derives it from the data.
    pub radius: Option<f64>,
}

impl Default for LodOptions {
    fn default() -> Self {
        LodOptions {
            enabled: true,
            merge: MergeRule::default(),
            radius: None,
        }
    }
}

/// One built parent tile.
#[derive(Debug, Clone)]
pub struct ParentTile {
    /// Its key.
    pub key: TileKey,
    /// Merged splats, in descending importance order.
    pub splats: Splats,
    /// Its geometric error: [`ERROR_PER_RADIUS`] times the clustering radius it used (the field
    /// keeps its historical name).
    pub radius: f64,
    /// Clustering radius used.
    pub cluster_radius: f64,
    /// Mean displacement of the merged input splats.
    pub mean_displacement: f64,
    /// Splats gathered from the children.
    pub input: usize,
    /// It passed its single child's content through (`ParentParams::pass_through`): a
    /// pass-through tile, written without content.
    pub passed_through: bool,
}

/// Median distance from a splat centre to its nearest other centre, over a deterministic sample
/// of at most 4096 splats; `None` when fewer than two distinct centres exist.
pub fn median_nn_spacing(positions: &[[f64; 3]]) -> Option<f64> {
    if positions.len() < 2 {
        return None;
    }
    let o = positions[0];
    let pts: Vec<[f64; 3]> = positions
        .iter()
        .map(|p| [p[0] - o[0], p[1] - o[1], p[2] - o[2]])
        .collect();
    let tree = ImmutableKdTree::<f64, 3>::new_from_slice(&pts).ok()?;
    let step = (pts.len() / 4096).max(1);
    let mut d: Vec<f64> = (0..pts.len())
        .step_by(step)
        .filter_map(|i| {
            tree.query(&pts[i])
                .nearest_n::<SquaredEuclidean<f64>>(std::num::NonZero::new(2).unwrap())
                .execute()
                .into_iter()
                .map(|r| r.distance)
                .find(|&d2| d2 > 0.0)
                .map(f64::sqrt)
        })
        .collect();
    if d.is_empty() {
        return None;
    }
    let mid = d.len() / 2;
    let (_, m, _) = d.select_nth_unstable_by(mid, |a, b| a.total_cmp(b));
    Some(*m)
}

/// The default leaf radius `r`: the deepest leaf tile's edge (`root_size / 2^deepest_level`)
/// divided by [`LEAF_SIZE_DIVISOR`], but never below the median nearest-neighbour spacing (so the
/// first parent level always merges neighbours). Parents use it only when their children's
/// centres give no radius (all coincident); see [`build_parent`].
pub fn default_leaf_radius(positions: &[[f64; 3]], root_size: f64, deepest_level: u32) -> f64 {
    let from_tiles = root_size / 2f64.powi(deepest_level as i32) / LEAF_SIZE_DIVISOR;
    let nn = median_nn_spacing(positions).unwrap_or(0.0);
    let r = from_tiles.max(nn);
    if r.is_finite() && r > 0.0 {
        r
    } else {
        1e-6_f64.max(root_size * 1e-6)
    }
}

/// Appends every splat of `b` to `a` (same SH degree).
pub fn append(a: &mut Splats, b: &Splats) {
    assert_eq!(a.sh_degree, b.sh_degree, "SH degrees differ");
    a.positions.extend_from_slice(&b.positions);
    a.scales.extend_from_slice(&b.scales);
    a.rotations.extend_from_slice(&b.rotations);
    a.opacities.extend_from_slice(&b.opacities);
    a.sh0.extend_from_slice(&b.sh0);
    a.sh_rest.extend_from_slice(&b.sh_rest);
}

/// One child's content as input to its parent's clustering.
#[derive(Debug, Clone, Copy)]
pub struct ChildContent<'a> {
    /// The child's splats (a leaf's, or a built parent's merged splats).
    pub splats: &'a Splats,
    /// The child's geometric error, [`ParentTile::radius`] (0 for a leaf).
    pub radius: f64,
}

/// What one parent's clustering depends on besides its children's content.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParentParams {
    /// Leaf clustering radius `r` (scene units): the radius used when the children's centres
    /// give none (all coincident) and no child has a radius.
    pub leaf_radius: f64,
    /// Levels between this parent and the deepest leaf below it (>= 1); informational, the
    /// count target does not depend on it.
    pub levels_above_deepest: u32,
    /// Tile budget (most splats a parent may hold).
    pub budget: usize,
    /// Shape rule for merged splats.
    pub rule: MergeRule,
    /// A tile below the root with a single child passes that child's content and error through
    /// (the tile is a pass-through without content, `tiling::levels::keeps_content`); off for
    /// layered builds, where every tile holds a layer of its own.
    pub pass_through: bool,
}

/// Builds one parent from its children's content: a pure, deterministic function of the inputs
/// (children in the order given), so in-memory and region-by-region builds agree byte for byte.
/// With `params.pass_through`, a tile below the root with a single child passes that child's
/// content and error through.
pub fn build_parent(
    key: TileKey,
    sh_degree: u8,
    children: &[ChildContent<'_>],
    params: &ParentParams,
) -> ParentTile {
    // A single child below the root: the tile is a pass-through, written without content
    // (`tiling::levels::keeps_content`), so its child's content goes up unchanged and a chain of
    // such tiles neither thins the content nor grows the error.
    if let [only] = children
        && params.pass_through
        && !splat2tiles_tiles::tiling::levels::keeps_content(key, 1)
    {
        return ParentTile {
            key,
            splats: only.splats.clone(),
            radius: only.radius,
            cluster_radius: only.radius / ERROR_PER_RADIUS,
            mean_displacement: 0.0,
            input: only.splats.len(),
            passed_through: true,
        };
    }
    let mut input = Splats::new(sh_degree);
    let mut child_radius = 0.0f64;
    for c in children {
        append(&mut input, c.splats);
        child_radius = child_radius.max(c.radius);
    }
    // The root (the coarsest level, shown from every distance beyond its own switching distance)
    // aims at its cap: a finer root switches nearer, where the scene's objects still span
    // enough pixels to be recognised.
    let cap = count_cap(input.len(), params.budget);
    let target = if key.parent().is_none() {
        cap
    } else {
        target_count(input.len(), params.budget)
    };
    let c = cluster_to_target(
        &input,
        target,
        child_radius * MIN_RADIUS_GROWTH / ERROR_PER_RADIUS,
        params.leaf_radius,
        cap,
        params.rule,
        DRAWN_DILATION_PER_RADIUS2,
    );
    let order = importance_order(&c.splats);
    ParentTile {
        key,
        splats: c.splats.select(&order),
        radius: c.radius * ERROR_PER_RADIUS,
        cluster_radius: c.radius,
        mean_displacement: c.mean_displacement,
        input: input.len(),
        passed_through: false,
    }
}

/// Builds every ancestor of `leaves` bottom-up up to `root` (their subtree's root; nothing
/// above it: a region's parents, the levels above it are built from the region roots), each
/// with `params` (its `levels_above_deepest` set per tile).
/// `leaf_splats(key)` gives a leaf's splats;
/// `sink` receives each parent as soon as it is built (in parallel within a level) and returns
/// what the caller wants to keep per tile. Returns those values keyed by tile.
pub fn build_parents<T, E, L, S>(
    root: TileKey,
    leaves: &[TileKey],
    sh_degree: u8,
    params: ParentParams,
    leaf_splats: L,
    sink: S,
) -> Result<BTreeMap<TileKey, T>, E>
where
    T: Send,
    E: Send,
    L: Fn(TileKey) -> Splats + Sync,
    S: Fn(&ParentTile) -> Result<T, E> + Sync,
{
    // Deepest leaf level under every tile, and each tile's children.
    let mut deepest: HashMap<TileKey, u32> = HashMap::new();
    let mut children: BTreeMap<TileKey, Vec<TileKey>> = BTreeMap::new();
    let is_leaf: std::collections::HashSet<TileKey> = leaves.iter().copied().collect();
    for &leaf in leaves {
        deepest.insert(leaf, leaf.level);
        let mut k = leaf;
        while k != root
            && let Some(p) = k.parent()
        {
            let e = deepest.entry(p).or_insert(leaf.level);
            *e = (*e).max(leaf.level);
            let kids = children.entry(p).or_default();
            if !kids.contains(&k) {
                kids.push(k);
            }
            k = p;
        }
    }
    let max_level = children.keys().map(|k| k.level).max();
    let mut built: HashMap<TileKey, ParentTile> = HashMap::new();
    let mut out = BTreeMap::new();
    let Some(max_level) = max_level else {
        return Ok(out);
    };
    for level in (0..=max_level).rev() {
        let keys: Vec<TileKey> = children
            .keys()
            .filter(|k| k.level == level && !is_leaf.contains(k))
            .copied()
            .collect();
        let made: Vec<Result<(ParentTile, T), E>> = keys
            .par_iter()
            .map(|&key| {
                let leaves_here: Vec<Option<Splats>> = children[&key]
                    .iter()
                    .map(|c| (!built.contains_key(c)).then(|| leaf_splats(*c)))
                    .collect();
                let kids: Vec<ChildContent<'_>> = children[&key]
                    .iter()
                    .zip(&leaves_here)
                    .map(|(c, leaf)| match (built.get(c), leaf) {
                        (Some(p), _) => ChildContent {
                            splats: &p.splats,
                            radius: p.radius,
                        },
                        (None, Some(s)) => ChildContent {
                            splats: s,
                            radius: 0.0,
                        },
                        (None, None) => unreachable!("a child is a leaf or a built parent"),
                    })
                    .collect();
                let params = ParentParams {
                    levels_above_deepest: deepest[&key] - key.level,
                    ..params
                };
                let tile = build_parent(key, sh_degree, &kids, &params);
                let v = sink(&tile)?;
                Ok((tile, v))
            })
            .collect();
        for k in &keys {
            for c in &children[k] {
                built.remove(c);
            }
        }
        for m in made {
            let (tile, v) = m?;
            out.insert(tile.key, v);
            built.insert(tile.key, tile);
        }
    }
    Ok(out)
}
