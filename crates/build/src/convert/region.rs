//! Region stage: one subtree built as a unit from its splats alone: leaves (partition, importance
//! order, contents), then LOD parents up to the region root, bottom-up.
//!
//! Pass 1 ([`build_leaves`]) writes every leaf and keeps the group's splats in leaf order; pass 2
//! ([`build_parents`]) needs the global leaf radius and the leaf boxes, known after pass 1 of
//! every region. A region's output depends only on its splats and global parameters, never on
//! how the scene was split, so the in-memory path (one region) and the spill path agree.

use super::frame::Layout;
use super::spill::{Group, GroupData, RegionSpec};
use super::spill_records::SpillFormat;
use super::store::ContentStore;
use super::tileset::TreeTile;
use super::{ConvertError, ConvertOptions, check_interrupt};
use crate::lod::ParentTile;
use crate::variants::{ContentFacts, TileSlot, write_tile_contents};
use glam::DVec3;
use rayon::prelude::*;
use splat2tiles_core::frame::node_matrix;
use splat2tiles_core::splat::Splats;
use splat2tiles_core::splat::importance::sort_indices_by_importance;
use splat2tiles_tiles::tiling::TileKey;
use splat2tiles_tiles::tiling::extent::{reach, reach_bounds};
use splat2tiles_tiles::tiling::partition::partition_subtree_with;
use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// Most leaf splats a sampled splat's nearest neighbour is searched among.
const NN_SEARCH_CAP: usize = 65_536;

/// What the region stage needs besides a region's splats.
pub(super) struct RegionCtx<'a> {
    pub(super) layout: &'a Layout,
    pub(super) opts: &'a ConvertOptions,
    /// The staging folder (contents go under it).
    pub(super) dir: &'a Path,
    /// Every `nn_step`-th splat of a leaf (importance order) is a spacing sample.
    pub(super) nn_step: usize,
    /// Pass 1 writes the leaves (otherwise it only partitions and samples the spacing: the
    /// first phase of a sharded part, `part`).
    pub(super) write_leaves: bool,
    /// Tiles a view-optimised plan splits (`--partition`; none in sharded conversions).
    pub(super) must_split: Option<&'a std::collections::BTreeSet<TileKey>>,
}

impl RegionCtx<'_> {
    /// The clustering parameters of every parent, with leaf radius `r` (the per-tile level count
    /// is set where each is built).
    pub(super) fn parent_params(&self, r: f64) -> crate::lod::ParentParams {
        crate::lod::ParentParams {
            leaf_radius: r,
            levels_above_deepest: 1,
            budget: self.opts.max_splats_per_tile,
            rule: self.opts.lod.merge,
            pass_through: !self.opts.layers,
        }
    }
}

/// One region after pass 1: its leaves in Morton order with their splat counts.
#[derive(Debug, Clone)]
pub(super) struct RegionLeaves {
    pub(super) spec: RegionSpec,
    pub(super) leaves: Vec<(TileKey, usize)>,
}

/// A group after pass 1.
#[derive(Debug)]
pub(super) struct GroupLeaves {
    pub(super) regions: Vec<RegionLeaves>,
    /// The group's splats and their leaf order (regions in order, leaves in order, importance
    /// order).
    pub(super) data: LeafOrder,
    /// The written leaves.
    pub(super) tiles: Vec<(TileKey, TreeTile)>,
    /// Nearest-neighbour spacing samples.
    pub(super) spacing: Vec<f64>,
    /// Per leaf, the input indices of its splats (only when the report keeps the index map).
    pub(super) index_map: Vec<(TileKey, Vec<usize>)>,
}

/// A group's splats after pass 1: as they were stored (input order), with the positions in
/// them in leaf order. Pass 2 gathers each leaf through the order, so the group is never
/// copied whole into leaf order.
#[derive(Debug)]
pub(super) enum LeafOrder {
    /// In memory.
    Memory {
        /// The splats, input order.
        splats: Splats,
        /// Positions in `splats`, leaf order.
        order: Vec<usize>,
    },
    /// The group's spill file (input order) and an order file (u32 or u64 positions in it,
    /// leaf order).
    Files {
        /// The spill file.
        file: PathBuf,
        /// The order file.
        order: PathBuf,
    },
}

/// Writes one tile's contents centred on its splats; returns the box around their visible
/// 3-sigma ellipsoids in the tileset frame and what was written. `parent`: merged LOD splats.
pub(super) fn write_centred(
    layout: &Layout,
    key: TileKey,
    tile: &Splats,
    dir: &Path,
    opts: &ConvertOptions,
    parent: bool,
) -> Result<(DVec3, DVec3, ContentFacts), ConvertError> {
    check_interrupt()?;
    let pts: Vec<DVec3> = tile
        .positions
        .iter()
        .map(|p| layout.to_tileset(*p))
        .collect();
    let (clo, chi) = pts.iter().fold(
        (DVec3::splat(f64::MAX), DVec3::splat(f64::MIN)),
        |(lo, hi), q| (lo.min(*q), hi.max(*q)),
    );
    let (lo, hi) = reach_bounds(&pts, &three_sigma(tile, layout));
    let centre_s = layout.a.transpose() * ((clo + chi) * 0.5);
    let slot = TileSlot {
        scheme: layout.scheme,
        key,
        parent,
    };
    let facts = write_tile_contents(
        dir,
        slot,
        tile,
        centre_s.to_array(),
        node_matrix(layout.a, centre_s),
        &opts.variants,
    )?;
    Ok((lo, hi, facts))
}

/// Half extents in the tileset frame of every splat's full 3-sigma ellipsoid (what
/// `validate --check-extent` and the 3DGS rasterizers' footprints assume, whatever the opacity).
fn three_sigma(tile: &Splats, layout: &Layout) -> Vec<DVec3> {
    tile.scales
        .iter()
        .zip(&tile.rotations)
        .map(|(s, r)| reach(layout.a, *s, *r, 1.0))
        .collect()
}

/// A group ready for pass 1: its regions, its splats and input indices in input order, and the
/// spill file they came from.
pub(super) struct InputGroup {
    regions: Vec<RegionSpec>,
    splats: Splats,
    idx: Vec<u64>,
    file: Option<PathBuf>,
}

/// Loads a group for pass 1 (or takes it from memory). Independent of the pass 1 of other
/// groups, so it can run while the previous group is being built.
pub(super) fn load_group_input(
    group: Group,
    format: &SpillFormat,
) -> Result<InputGroup, ConvertError> {
    let count = group.count();
    let (splats, idx, file) = match group.data {
        GroupData::Memory(s, idx) => (s, idx, None),
        GroupData::File(p) => {
            let (s, idx) = format.load(&p, count)?;
            (s, idx, Some(p))
        }
    };
    Ok(InputGroup {
        regions: group.regions,
        splats,
        idx,
        file,
    })
}

/// A group after pass 1: its splats as stored, the positions in them in leaf order, and the
/// spill file they came from.
fn load_ordered(
    data: LeafOrder,
    count: u64,
    format: &SpillFormat,
) -> Result<(Splats, Vec<usize>, Option<PathBuf>), ConvertError> {
    match data {
        LeafOrder::Memory { splats, order } => Ok((splats, order, None)),
        LeafOrder::Files { file, order } => {
            let perm = read_order(&order, count)?;
            std::fs::remove_file(&order).map_err(super::io_err(&order, "removing spill file"))?;
            let (s, _idx) = format.load(&file, count)?;
            Ok((s, perm, Some(file)))
        }
    }
}

/// Bytes of one entry of an order file: u32 while a group's positions fit one, else u64.
fn order_bytes(count: u64) -> usize {
    if count <= u32::MAX as u64 { 4 } else { 8 }
}

/// Writes `order` (positions in the spill file, leaf order) to `path`, little-endian.
fn write_order(path: &Path, order: &[usize]) -> Result<(), ConvertError> {
    let wide = order_bytes(order.len() as u64) == 8;
    let f = std::fs::File::create(path).map_err(super::io_err(path, "creating spill file"))?;
    let mut w = std::io::BufWriter::with_capacity(1 << 20, f);
    let mut put = || -> std::io::Result<()> {
        for &i in order {
            if wide {
                std::io::Write::write_all(&mut w, &(i as u64).to_le_bytes())?;
            } else {
                std::io::Write::write_all(&mut w, &(i as u32).to_le_bytes())?;
            }
        }
        std::io::Write::flush(&mut w)
    };
    put().map_err(super::io_err(path, "writing spill file"))
}

/// Reads the order file of a group of `count` splats: a permutation of `0..count`.
fn read_order(path: &Path, count: u64) -> Result<Vec<usize>, ConvertError> {
    let width = order_bytes(count);
    let bytes = std::fs::read(path).map_err(super::io_err(path, "reading spill file"))?;
    let bad = |what: String| ConvertError::Io {
        path: path.to_path_buf(),
        what: "reading spill file",
        source: std::io::Error::new(std::io::ErrorKind::InvalidData, what),
    };
    if bytes.len() as u64 != count * width as u64 {
        return Err(bad(format!(
            "{} bytes where {count} entries of {width} were written (changed by another program?)",
            bytes.len()
        )));
    }
    let order: Vec<usize> = bytes
        .chunks_exact(width)
        .map(|b| {
            if width == 4 {
                u32::from_le_bytes(b.try_into().expect("4 bytes")) as usize
            } else {
                u64::from_le_bytes(b.try_into().expect("8 bytes")) as usize
            }
        })
        .collect();
    if let Some((at, _)) = order.iter().enumerate().find(|(_, i)| **i as u64 >= count) {
        return Err(bad(format!("entry {at} points past the {count} splats")));
    }
    Ok(order)
}

/// First Morton code (at the layout depth) of `key`'s cell.
fn first_code(layout: &Layout, key: TileKey) -> u64 {
    let s = layout.scheme;
    s.encode(key.x, key.y, key.z) << (s.dims() * (layout.depth() - key.level.min(layout.depth())))
}

/// Pass 1 of a group: per region, partition into leaves, importance order, write the leaves;
/// sample the nearest-neighbour spacing; keep the splats in leaf order for pass 2.
pub(super) fn build_leaves(
    group: InputGroup,
    cx: &RegionCtx<'_>,
) -> Result<GroupLeaves, ConvertError> {
    let InputGroup {
        regions: specs,
        splats,
        idx,
        file,
    } = group;
    let layout = cx.layout;
    // Which region each splat belongs to (regions are consecutive Morton ranges).
    let members: Vec<Vec<usize>> = if specs.len() == 1 {
        vec![(0..splats.len()).collect()]
    } else {
        let starts: Vec<u64> = specs.iter().map(|r| first_code(layout, r.key)).collect();
        let which: Vec<usize> = splats
            .positions
            .par_iter()
            .map(|p| {
                starts
                    .partition_point(|&s| s <= layout.code(*p))
                    .saturating_sub(1)
            })
            .collect();
        let mut m = vec![Vec::new(); specs.len()];
        for (i, &w) in which.iter().enumerate() {
            m[w].push(i);
        }
        m
    };
    let mut out = GroupLeaves {
        regions: Vec::with_capacity(specs.len()),
        data: LeafOrder::Memory {
            splats: Splats::new(splats.sh_degree),
            order: Vec::new(),
        },
        tiles: Vec::new(),
        spacing: Vec::new(),
        index_map: Vec::new(),
    };
    let mut order: Vec<usize> = Vec::with_capacity(splats.len());
    for (spec, list) in specs.iter().zip(members) {
        let unit: Vec<[f64; 3]> = list
            .par_iter()
            .map(|&i| layout.unit(splats.positions[i]))
            .collect();
        let part = partition_subtree_with(
            &unit,
            layout.scheme,
            cx.opts.max_splats_per_tile,
            layout.max_depth,
            spec.key,
            &|k| cx.must_split.is_some_and(|m| m.contains(&k)),
        );
        drop(unit);
        let mut leaves: Vec<(TileKey, Vec<usize>)> = part
            .leaves
            .into_iter()
            .map(|l| (l.key, l.indices.into_iter().map(|k| list[k]).collect()))
            .collect();
        // Importance order inside every leaf (SGSS eq. 7); the index map follows it.
        leaves
            .par_iter_mut()
            .for_each(|(_, ind)| sort_indices_by_importance(&splats, ind));
        let written: Result<Vec<(TileKey, TreeTile)>, ConvertError> = leaves
            .par_iter()
            .filter(|_| cx.write_leaves)
            .map(|(key, ind)| {
                let tile = splats.select(ind);
                let (lo, hi, facts) = write_centred(layout, *key, &tile, cx.dir, cx.opts, false)?;
                Ok((*key, TreeTile::leaf(lo, hi, facts)))
            })
            .collect();
        out.tiles.extend(written?);
        let spacing: Vec<f64> = leaves
            .par_iter()
            .flat_map_iter(|(_, ind)| leaf_spacing(&splats, ind, cx.nn_step))
            .collect();
        out.spacing.extend(spacing);
        if cx.opts.keep_index_map {
            out.index_map.extend(
                leaves
                    .iter()
                    .map(|(k, ind)| (*k, ind.iter().map(|&i| idx[i] as usize).collect())),
            );
        }
        out.regions.push(RegionLeaves {
            spec: *spec,
            leaves: leaves.iter().map(|(k, ind)| (*k, ind.len())).collect(),
        });
        for (_, ind) in leaves {
            order.extend(ind);
        }
    }
    out.data = match file {
        _ if !cx.write_leaves => LeafOrder::Memory {
            splats: Splats::new(splats.sh_degree),
            order: Vec::new(),
        },
        None => LeafOrder::Memory { splats, order },
        Some(p) => {
            // The spill file stays; pass 2 reads it again in leaf order (4 bytes per splat
            // written here instead of the whole group again).
            let q = p.with_extension("order");
            write_order(&q, &order)?;
            LeafOrder::Files { file: p, order: q }
        }
    };
    Ok(out)
}

/// Spacing samples of one leaf (`ind` in importance order): for every `step`-th splat, the
/// distance to the nearest other distinct centre among the leaf's first [`NN_SEARCH_CAP`].
/// With many samples a KD-tree (kiddo, as the LOD clustering uses) picks each sample's
/// [`NN_CANDIDATES`] nearest centres and the distance is measured among those; when all of them
/// coincide with the sample (duplicates), or with few samples, the whole pool is scanned. The
/// answers are the scan's.
fn leaf_spacing(s: &Splats, ind: &[usize], step: usize) -> Vec<f64> {
    use kiddo::{ImmutableKdTree, SquaredEuclidean};
    let pool = &ind[..ind.len().min(NN_SEARCH_CAP)];
    let d2 = |p: [f64; 3], j: usize| {
        let q = s.positions[j];
        let d = [p[0] - q[0], p[1] - q[1], p[2] - q[2]];
        d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
    };
    let scan = |p: [f64; 3]| {
        pool.iter()
            .map(|&j| d2(p, j))
            .filter(|&v| v > 0.0)
            .fold(f64::INFINITY, f64::min)
    };
    let samples: Vec<usize> = ind.iter().step_by(step.max(1)).copied().collect();
    let tree = (samples.len() >= TREE_MIN_SAMPLES)
        .then(|| {
            let pts: Vec<[f64; 3]> = pool.iter().map(|&j| s.positions[j]).collect();
            ImmutableKdTree::<f64, 3>::new_from_slice(&pts).ok()
        })
        .flatten();
    let k = std::num::NonZero::new(NN_CANDIDATES).unwrap_or(std::num::NonZero::<usize>::MIN);
    samples
        .into_iter()
        .filter_map(|i| {
            let p = s.positions[i];
            let best = match &tree {
                Some(t) => {
                    let near = t
                        .query(&p)
                        .nearest_n::<SquaredEuclidean<f64>>(k)
                        .execute()
                        .into_iter()
                        .filter_map(|r| pool.get(usize::try_from(r.item).ok()?))
                        .map(|&j| d2(p, j))
                        .filter(|&v| v > 0.0)
                        .fold(f64::INFINITY, f64::min);
                    if near.is_finite() { near } else { scan(p) }
                }
                None => scan(p),
            };
            best.is_finite().then(|| best.sqrt())
        })
        .collect()
}

/// Samples of one leaf from which [`leaf_spacing`] builds a KD-tree instead of scanning.
const TREE_MIN_SAMPLES: usize = 32;
/// Nearest centres a sample's spacing is looked for among (duplicates of it included).
const NN_CANDIDATES: usize = 8;

/// A region root as the levels above see it: its key and the deepest leaf level below it (its
/// content, splats and radius, is in the [`ContentStore`]).
#[derive(Debug, Clone, Copy)]
pub(super) struct RootContent {
    pub(super) key: TileKey,
    pub(super) deepest: u32,
}

/// What the tree keeps of a parent tile: its content (facts and its box) when it is a real
/// level of detail, and its clustering radius.
#[derive(Debug)]
pub(super) struct WrittenParent {
    pub(super) content: Option<(ContentFacts, DVec3, DVec3)>,
    pub(super) error: f64,
}

/// Writes a built parent through the same per-tile writer as the leaves, unless it passed its
/// single child through (`tiling::levels::keeps_content`; never in layered builds, where every
/// tile holds a layer), which the tree completes with its parent's box and error instead.
pub(super) fn write_parent(
    p: &ParentTile,
    cx: &RegionCtx<'_>,
) -> Result<WrittenParent, ConvertError> {
    if p.passed_through {
        return Ok(WrittenParent {
            content: None,
            error: p.radius,
        });
    }
    let (lo, hi, facts) = write_centred(cx.layout, p.key, &p.splats, cx.dir, cx.opts, true)?;
    Ok(WrittenParent {
        content: Some((facts, lo, hi)),
        error: p.radius,
    })
}

/// A group ready for pass 2: its regions, its splats as stored and their leaf order.
pub(super) struct LoadedGroup {
    regions: Vec<RegionLeaves>,
    splats: Splats,
    order: Vec<usize>,
}

/// Loads a group for pass 2 (its spill and order files are read, then removed). Independent of
/// the pass 2 of other groups, so it can run while the previous group is being built.
pub(super) fn load_group(
    group: GroupLeaves,
    format: &SpillFormat,
) -> Result<LoadedGroup, ConvertError> {
    let count: u64 = group.regions.iter().map(|g| g.spec.count).sum();
    let (splats, order, file) = load_ordered(group.data, count, format)?;
    if let Some(p) = file {
        std::fs::remove_file(&p).map_err(super::io_err(&p, "removing spill file"))?;
    }
    Ok(LoadedGroup {
        regions: group.regions,
        splats,
        order,
    })
}

/// Pass 2 of a group: the LOD parents of every region up to its root (through
/// [`crate::lod::build_parents`], children in Morton order), written as they are built.
/// Returns them and each region's root (its content put into `store`).
pub(super) fn build_parents(
    group: LoadedGroup,
    r: f64,
    store: &ContentStore,
    cx: &RegionCtx<'_>,
) -> Result<(BTreeMap<TileKey, WrittenParent>, Vec<RootContent>), ConvertError> {
    let LoadedGroup {
        regions,
        splats,
        order,
    } = group;
    let mut parents = BTreeMap::new();
    let mut roots = Vec::with_capacity(regions.len());
    let mut start = 0usize;
    for region in &regions {
        check_interrupt()?;
        let mut ranges: HashMap<TileKey, (usize, usize)> = HashMap::new();
        for &(k, n) in &region.leaves {
            ranges.insert(k, (start, n));
            start += n;
        }
        let keys: Vec<TileKey> = region.leaves.iter().map(|(k, _)| *k).collect();
        let deepest = keys
            .iter()
            .map(|k| k.level)
            .max()
            .unwrap_or(region.spec.key.level);
        let range_of = |k: TileKey| -> Vec<usize> {
            let (a, n) = ranges[&k];
            order[a..a + n].to_vec()
        };
        let root_key = region.spec.key;
        if keys.len() == 1 && keys[0] == root_key {
            store.put(root_key, &splats.select(&range_of(root_key)), 0.0)?;
            roots.push(RootContent {
                key: root_key,
                deepest,
            });
            continue;
        }
        let root: Mutex<Option<Result<(), ConvertError>>> = Mutex::new(None);
        let built = if cx.opts.lod.enabled {
            crate::lod::build_parents(
                root_key,
                &keys,
                splats.sh_degree,
                cx.parent_params(r),
                |k| splats.select(&range_of(k)),
                |p: &ParentTile| {
                    if p.key == root_key {
                        *root.lock().unwrap_or_else(|e| e.into_inner()) =
                            Some(store.put(root_key, &p.splats, p.radius));
                    }
                    write_parent(p, cx)
                },
            )?
        } else {
            BTreeMap::new()
        };
        parents.extend(built);
        match root.into_inner().unwrap_or_else(|e| e.into_inner()) {
            Some(stored) => stored?,
            None => store.put(root_key, &Splats::new(splats.sh_degree), 0.0)?,
        }
        roots.push(RootContent {
            key: root_key,
            deepest,
        });
    }
    Ok((parents, roots))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// What every sample's spacing must be: the nearest other distinct centre over the pool.
    fn scanned(s: &Splats, ind: &[usize], step: usize) -> Vec<f64> {
        let pool = &ind[..ind.len().min(NN_SEARCH_CAP)];
        ind.iter()
            .step_by(step)
            .filter_map(|&i| {
                let p = s.positions[i];
                let d = pool
                    .iter()
                    .map(|&j| {
                        let q = s.positions[j];
                        let d = [p[0] - q[0], p[1] - q[1], p[2] - q[2]];
                        d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
                    })
                    .filter(|&v| v > 0.0)
                    .fold(f64::INFINITY, f64::min);
                d.is_finite().then(|| d.sqrt())
            })
            .collect()
    }

    #[test]
    fn the_tree_finds_what_the_scan_finds_with_duplicates_and_without_distinct_centres() {
        let mut s = Splats::new(0);
        let mut x = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x >> 11) as f64 / (1u64 << 53) as f64
        };
        for _ in 0..600 {
            s.positions.push([next() * 4.0, next() * 4.0, next()]);
        }
        // Twenty copies of one centre: more than the tree's candidates.
        for _ in 0..20 {
            s.positions.push([1.5, 1.5, 0.5]);
        }
        let ind: Vec<usize> = (0..s.positions.len()).collect();
        for step in [1, 3, 50] {
            assert_eq!(
                leaf_spacing(&s, &ind, step),
                scanned(&s, &ind, step),
                "step {step}"
            );
        }
        // Only copies: no sample has a distinct neighbour.
        let copies: Vec<usize> = (600..620).collect();
        assert!(leaf_spacing(&s, &copies, 1).is_empty());
    }
}
