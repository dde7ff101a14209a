//! `import-lapisgs`: LapisGS-trained levels (one 3DGS PLY per level, coarse to fine, each level
//! starting with the previous level's splats) written as layered content, format v2.
//!
//! LapisGS level `k` becomes implicit tree level `k` over the last level's bounds: level 0's
//! splats are the root's base layer, level `k`'s new splats go to the level-`k` cell holding their
//! centre. The opacity a later level gives an earlier splat becomes a delta
//! `(o_k - o_{k-1}) / o_own` carried by the level-`k` layer whose cell holds the splat's centre
//! (else the nearest level-`k` layer below the splat's own tile; else it is dropped and
//! counted). A content tile whose parent cell has no splats of its own level gets a placeholder
//! parent content: one copy of one of its splats at opacity 0, which draws nothing at any blend
//! (`spec/layered-content.md`, "Importing LapisGS-trained layers").

use super::frame::{FrameAccum, Layout};
use super::tileset::{
    TreeTile, build_tree, finish_tree, tileset_json, write_subtrees, write_tileset_json,
};
use super::{ConvertError, ConvertOptions, ConvertReport, io_err, region};
use crate::output::Staging;
use crate::variants::{Variant, content_uri};
use splat2tiles_core::frame::geo::Geodetic;
use splat2tiles_core::frame::{UpAxis, source_to_tileset};
use splat2tiles_core::splat::Splats;
use splat2tiles_io::{self as io, Scene};
use splat2tiles_tiles::layers::build::LayerError;
use splat2tiles_tiles::layers::glb::add_layer_v2;
use splat2tiles_tiles::tiling::TileKey;
use splat2tiles_tiles::tiling::partition::code_of;
use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// What an import did.
#[derive(Debug, Clone, Default)]
pub struct LapisReport {
    /// Splats of each level's file.
    pub level_splats: Vec<usize>,
    /// Tiles of the implicit tree, and those with content.
    pub tiles: usize,
    /// Tiles with content (layers).
    pub content_tiles: usize,
    /// Placeholder contents (one zero-opacity splat) given to parents of layers that had none.
    pub placeholders: usize,
    /// Opacity changes of earlier splats written as deltas.
    pub deltas: usize,
    /// Of those, the ones carried by a layer whose cell does not hold the splat's centre (that
    /// cell had no content; the nearest layer below the splat's own tile carries it).
    pub rerouted: usize,
    /// Opacity changes that no layer could carry (no layer of that level below the splat's own
    /// tile), or that cannot be expressed (a splat stored at opacity 0 that a later level raises).
    pub dropped: usize,
    /// Bytes written (contents, subtrees, tileset.json).
    pub bytes: u64,
    /// Subdivision used.
    pub scheme: String,
    /// Wall-clock seconds.
    pub seconds: f64,
}

/// Why a set of levels is not LapisGS-layered.
fn refuse(file: &Path, why: String) -> ConvertError {
    ConvertError::Lapis {
        file: file.display().to_string(),
        why,
    }
}

/// Checks that `cur` (level `k`'s file) starts with `prev`'s splats, equal in every property but
/// opacity (bitwise, after decoding).
fn check_prefix(
    prev: &Scene,
    cur: &Scene,
    prev_file: &Path,
    cur_file: &Path,
) -> Result<(), ConvertError> {
    let (p, c) = (&prev.splats, &cur.splats);
    if c.len() < p.len() {
        return Err(refuse(
            cur_file,
            format!(
                "{} splats, fewer than the {} of the previous level {}: each level must start with the previous level's splats",
                c.len(),
                p.len(),
                prev_file.display()
            ),
        ));
    }
    if c.sh_degree != p.sh_degree {
        return Err(refuse(
            cur_file,
            format!(
                "SH degree {} differs from the previous level's {} ({})",
                c.sh_degree,
                p.sh_degree,
                prev_file.display()
            ),
        ));
    }
    for i in 0..p.len() {
        let what = if p.positions[i] != c.positions[i] {
            "position"
        } else if p.scales[i] != c.scales[i] {
            "scale"
        } else if p.rotations[i] != c.rotations[i] {
            "rotation"
        } else if p.sh0[i] != c.sh0[i] || p.rest_of(i) != c.rest_of(i) {
            "colour (SH)"
        } else {
            continue;
        };
        return Err(refuse(
            cur_file,
            format!(
                "splat {i} ({}): its {what} differs from splat {i} of the previous level {}: a LapisGS level keeps every earlier splat unchanged but for its opacity",
                cur.locator.describe(i),
                prev_file.display()
            ),
        ));
    }
    Ok(())
}

/// The level-`level` cell holding source-frame centre `p`.
fn cell(layout: &Layout, p: [f64; 3], level: u32) -> TileKey {
    let (x, y, z) = layout
        .scheme
        .decode(code_of(layout.unit(p), layout.scheme, level));
    TileKey { level, x, y, z }
}

/// Squared distance in root-unit coordinates from `u` to the centre of cell `k`.
fn cell_distance(u: [f64; 3], k: TileKey, octree: bool) -> f64 {
    let s = 0.5f64.powi(k.level as i32);
    let c = [
        (k.x as f64 + 0.5) * s,
        (k.y as f64 + 0.5) * s,
        (k.z as f64 + 0.5) * s,
    ];
    let dz = if octree { u[2] - c[2] } else { 0.0 };
    (u[0] - c[0]).powi(2) + (u[1] - c[1]).powi(2) + dz * dz
}

/// The levels read: each level's opacities (coarse to fine) and the last (finest) scene.
struct Levels {
    opacities: Vec<Vec<f32>>,
    last: Scene,
}

impl Levels {
    /// Reads `inputs` in order. Only the previous level's scene is kept while reading (for the
    /// prefix rule); of the others, their opacities.
    fn read(inputs: &[PathBuf], memory_limit: u64) -> Result<Levels, ConvertError> {
        let mut opacities: Vec<Vec<f32>> = Vec::with_capacity(inputs.len());
        let mut prev: Option<Scene> = None;
        for (k, f) in inputs.iter().enumerate() {
            let s = io::read_path_limited(f, memory_limit)?;
            if let Some(i) = (0..s.splats.len()).find(|&i| !s.splats.is_finite(i)) {
                return Err(refuse(
                    f,
                    format!(
                        "splat {i} ({}) has a NaN or infinite value: an imported level cannot drop splats (later levels index them)",
                        s.locator.describe(i)
                    ),
                ));
            }
            if let Some(p) = &prev {
                check_prefix(p, &s, &inputs[k - 1], f)?;
            }
            opacities.push(s.splats.opacities.clone());
            prev = Some(s);
        }
        let (Some(last), Some(last_file)) = (prev, inputs.last()) else {
            return Err(ConvertError::Empty {
                file: "import-lapisgs".into(),
                why: ": no level files given".into(),
            });
        };
        if last.splats.is_empty() {
            return Err(ConvertError::Empty {
                file: last_file.display().to_string(),
                why: String::new(),
            });
        }
        Ok(Levels { opacities, last })
    }

    /// Splats of each level.
    fn counts(&self) -> Vec<usize> {
        self.opacities.iter().map(Vec::len).collect()
    }
}

/// Where each splat goes: its own level's cell, the tiles' contents, and placeholders.
struct Cells {
    /// Each splat's own level (the first level that has it).
    own: Vec<usize>,
    /// Splats of each tile with content.
    contents: BTreeMap<TileKey, Vec<usize>>,
    /// Each splat's tile.
    home: Vec<TileKey>,
    /// A parent without content gets one copy (opacity 0) of a child's splat.
    placeholders: BTreeMap<TileKey, usize>,
    /// Index of every splat in its tile's content.
    index: Vec<usize>,
    /// Layers of each level under each tile, for deltas whose own cell has no layer.
    below: HashMap<(TileKey, u32), Vec<TileKey>>,
}

impl Cells {
    fn new(layout: &Layout, s: &Splats, counts: &[usize]) -> Cells {
        let n = s.len();
        let own: Vec<usize> = (0..n)
            .map(|i| {
                counts
                    .iter()
                    .position(|&c| i < c)
                    .expect("i < the last count")
            })
            .collect();
        let mut contents: BTreeMap<TileKey, Vec<usize>> = BTreeMap::new();
        let mut home: Vec<TileKey> = Vec::with_capacity(n);
        for (i, (p, &l)) in s.positions.iter().zip(&own).enumerate() {
            let k = cell(layout, *p, l as u32);
            contents.entry(k).or_default().push(i);
            home.push(k);
        }
        // Deepest level first, so a placeholder made for a level gets its own parent in turn:
        // every tile with a layer then has a parent with a layer, up to the root.
        let mut placeholders: BTreeMap<TileKey, usize> = BTreeMap::new();
        for level in (1..counts.len() as u32).rev() {
            let keys: Vec<TileKey> = contents
                .keys()
                .chain(placeholders.keys())
                .filter(|k| k.level == level)
                .copied()
                .collect();
            for k in keys {
                let p = k.parent().expect("level > 0");
                if !contents.contains_key(&p) && !placeholders.contains_key(&p) {
                    let from = contents
                        .get(&k)
                        .map(|v| v[0])
                        .unwrap_or_else(|| placeholders[&k]);
                    placeholders.insert(p, from);
                }
            }
        }
        // Placeholders come after nothing: they are alone in their tile.
        let mut index = vec![0usize; n];
        for ids in contents.values() {
            for (j, &i) in ids.iter().enumerate() {
                index[i] = j;
            }
        }
        let mut below: HashMap<(TileKey, u32), Vec<TileKey>> = HashMap::new();
        for k in contents.keys().chain(placeholders.keys()) {
            for l in 0..k.level {
                below.entry((k.ancestor(l), k.level)).or_default().push(*k);
            }
        }
        Cells {
            own,
            contents,
            home,
            placeholders,
            index,
            below,
        }
    }

    /// Splats in tile `k` (a placeholder's one, or none).
    fn tile_len(&self, k: &TileKey) -> usize {
        self.contents
            .get(k)
            .map_or_else(|| usize::from(self.placeholders.contains_key(k)), Vec::len)
    }

    /// Whether tile `k` has a layer.
    fn has(&self, k: &TileKey) -> bool {
        self.contents.contains_key(k) || self.placeholders.contains_key(k)
    }

    /// Every tile with a layer.
    fn keys(&self) -> Vec<TileKey> {
        self.contents
            .keys()
            .chain(self.placeholders.keys())
            .copied()
            .collect()
    }
}

/// Opacity deltas per carrying layer, per ancestor level, dense over that ancestor's splats.
type Carried = BTreeMap<TileKey, BTreeMap<u32, Vec<f32>>>;

/// The deltas: each opacity change between consecutive levels, relative to the splat's stored
/// opacity, carried by the layer of the level that changes it (or the nearest one below).
fn carry_deltas(
    layout: &Layout,
    cells: &Cells,
    levels: &Levels,
    report: &mut LapisReport,
) -> Carried {
    let (s, opacities) = (&levels.last.splats, &levels.opacities);
    let octree = layout.scheme == splat2tiles_tiles::tiling::Scheme::Octree;
    let mut carried = Carried::new();
    for k in 1..opacities.len() {
        for i in 0..opacities[k - 1].len() {
            let (o_prev, o_k) = (opacities[k - 1][i], opacities[k][i]);
            if o_prev == o_k {
                continue;
            }
            let stored = opacities[cells.own[i]][i];
            if stored <= 0.0 {
                report.dropped += 1;
                continue;
            }
            let h = cells.home[i];
            let mut target = cell(layout, s.positions[i], k as u32);
            if !cells.has(&target) {
                let u = layout.unit(s.positions[i]);
                let Some(t) = cells.below.get(&(h, k as u32)).and_then(|v| {
                    v.iter().copied().min_by(|a, b| {
                        cell_distance(u, *a, octree).total_cmp(&cell_distance(u, *b, octree))
                    })
                }) else {
                    report.dropped += 1;
                    continue;
                };
                target = t;
                report.rerouted += 1;
            }
            let d = ((f64::from(o_k) - f64::from(o_prev)) / f64::from(stored)) as f32;
            let len = cells.tile_len(&h);
            carried
                .entry(target)
                .or_default()
                .entry(h.level)
                .or_insert_with(|| vec![0.0; len])[cells.index[i]] += d;
            report.deltas += 1;
        }
    }
    carried
}

/// Geometric error of a level-k layer: the 3-sigma radius (median over level k+1's new splats)
/// of the detail that refining brings, and at least twice level k+1's error (LapisGS trains
/// each level at half the resolution of the next, so each level is refined twice as far away
/// as the next one).
fn level_errors(s: &Splats, counts: &[usize]) -> Vec<f64> {
    let levels = counts.len();
    let mut level_error = vec![0.0f64; levels];
    for (k, e) in level_error.iter_mut().enumerate().take(levels - 1) {
        let mut r: Vec<f32> = (counts[k]..counts[k + 1])
            .map(|i| 3.0 * s.scales[i].iter().fold(0.0f32, |m, &v| m.max(v)))
            .collect();
        r.sort_by(f32::total_cmp);
        *e = r.get(r.len() / 2).map_or(0.0, |&v| f64::from(v)).max(1e-9);
    }
    for k in (0..levels.saturating_sub(2)).rev() {
        level_error[k] = level_error[k].max(2.0 * level_error[k + 1]);
    }
    level_error
}

/// Writes every layer's glb into `dir` (its splats at their own level's opacity, then the
/// layer extension with its deltas); returns the finished tree.
fn write_layers(
    layout: &Layout,
    cells: &Cells,
    levels: &Levels,
    carried: &Carried,
    dir: &Path,
    opts: &ConvertOptions,
) -> Result<BTreeMap<TileKey, TreeTile>, ConvertError> {
    let (s, opacities) = (&levels.last.splats, &levels.opacities);
    let level_error = level_errors(s, &levels.counts());
    let mut tiles: HashMap<TileKey, TreeTile> = HashMap::new();
    let keys = cells.keys();
    let parents: std::collections::HashSet<TileKey> =
        keys.iter().filter_map(|k| k.parent()).collect();
    for k in keys {
        let tile = match cells.contents.get(&k) {
            Some(ids) => {
                let mut t = s.select(ids);
                for (j, &i) in ids.iter().enumerate() {
                    t.opacities[j] = opacities[cells.own[i]][i];
                }
                t
            }
            None => {
                let mut t = s.select(&[cells.placeholders[&k]]);
                t.opacities[0] = 0.0;
                t
            }
        };
        let (lo, hi, mut facts) = region::write_centred(layout, k, &tile, dir, opts, false)?;
        let path = dir.join(content_uri(layout.scheme, k, Variant::Best));
        let bytes = std::fs::read(&path).map_err(io_err(&path, "reading"))?;
        let mut parent = None;
        let mut anc: Vec<(u32, &[f32])> = vec![];
        if let Some(p) = k.parent() {
            parent = Some(vec![0.0f32; cells.tile_len(&p)]);
            if let Some(c) = carried.get(&k) {
                for (&j, d) in c {
                    if j + 1 == k.level {
                        parent = Some(d.clone());
                    } else {
                        anc.push((j, d));
                    }
                }
            }
        }
        let layered = add_layer_v2(&bytes, k.level, parent.as_deref(), &anc).map_err(|source| {
            LayerError::Glb {
                path: path.clone(),
                source,
            }
        })?;
        std::fs::write(&path, &layered).map_err(io_err(&path, "writing"))?;
        let size = layered.len() as u64;
        let old = facts.variant_bytes[Variant::Best.index()] as u64;
        facts.variant_bytes[Variant::Best.index()] = u32::try_from(size).map_err(|_| {
            LayerError::Unsupported(format!("tile {k:?}: layered content over 4 GiB"))
        })?;
        facts.bytes = (facts.bytes + size).saturating_sub(old);
        let mut t = TreeTile::leaf(lo, hi, facts);
        if parents.contains(&k) {
            t.is_leaf = false;
            t.error = level_error[k.level as usize];
        }
        tiles.insert(k, t);
    }
    let mut tree = build_tree(tiles);
    finish_tree(&mut tree);
    Ok(tree)
}

/// Imports LapisGS levels `inputs` (coarse to fine) into a layered tileset at `output`
/// (atomically: nothing is left there on error). Uses `opts`' frame (up axis, heading, origin),
/// scheme, subtree levels, memory limit and variants (Best only).
pub fn import_lapisgs(
    inputs: &[PathBuf],
    output: &Path,
    opts: &ConvertOptions,
) -> Result<LapisReport, ConvertError> {
    let start = Instant::now();
    if opts.variants.written() != [Variant::Best] {
        return Err(LayerError::Unsupported(
            "writes the Best variant only (drop --variants and use the default --profile)".into(),
        )
        .into());
    }
    let read = Levels::read(inputs, opts.memory_limit)?;
    let last_file = inputs.last().expect("Levels::read refuses no inputs");
    let counts = read.counts();
    let levels = counts.len();
    let last = &read.last;
    let up = opts.up_axis.unwrap_or_else(|| {
        last.format
            .default_up_axis()
            .parse()
            .unwrap_or(UpAxis::NegY)
    });
    let a = source_to_tileset(up, opts.heading_deg);
    let mut acc = FrameAccum::new(opts.origin.is_some());
    acc.add(
        &last.splats,
        &vec![true; last.splats.len()],
        a,
        opts.origin.map(Geodetic::enu_to_ecef),
    );
    let layout = Layout::new(&acc, a, opts);
    if (levels as u32 - 1) > layout.depth() {
        return Err(refuse(
            last_file,
            format!(
                "{levels} levels need a tree of depth {} but --max-depth allows {}",
                levels - 1,
                layout.depth()
            ),
        ));
    }
    let s = &last.splats;
    let n = s.len();
    let cells = Cells::new(&layout, s, &counts);
    let mut report = LapisReport {
        level_splats: counts.clone(),
        scheme: layout.scheme.as_str().to_string(),
        placeholders: cells.placeholders.len(),
        ..Default::default()
    };
    let carried = carry_deltas(&layout, &cells, &read, &mut report);

    let staging = Staging::prepare(output)?;
    let dir = staging.path().to_path_buf();
    let relocate = |e: ConvertError| e.relocated(&dir, output);
    let tree = write_layers(&layout, &cells, &read, &carried, &dir, opts).map_err(relocate)?;
    let subtree_levels = opts.subtree_levels_for(layout.scheme, levels as u32);
    let (_, subtree_bytes) =
        write_subtrees(&tree, layout.scheme, subtree_levels, &dir).map_err(relocate)?;
    let content_bytes: u64 = tree.values().map(|t| t.bytes).sum();
    let convert_report = ConvertReport {
        splats_in: n,
        splats_out: n + cells.placeholders.len(),
        sh_degree: s.sh_degree,
        up_axis: up.to_string(),
        scheme: report.scheme.clone(),
        levels: levels as u32,
        contents: tree
            .iter()
            .filter_map(|(k, t)| t.facts.clone().map(|f| (*k, f)))
            .collect(),
        ..Default::default()
    };
    let mut tileset = tileset_json(
        &tree,
        &layout,
        levels as u32,
        subtree_levels,
        &convert_report,
        &last_file.display().to_string(),
        &opts.variants,
    );
    tileset.root.refine = Some("ADD".into());
    let json_bytes = write_tileset_json(&tileset, &dir).map_err(relocate)?;
    staging.commit()?;
    report.tiles = tree.len();
    report.content_tiles = tree.values().filter(|t| t.has_content).count();
    report.bytes = content_bytes + subtree_bytes + json_bytes;
    report.seconds = start.elapsed().as_secs_f64();
    Ok(report)
}
