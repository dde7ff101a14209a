//! Merge of a sharded conversion (`splat2tiles merge PLAN.json PART_0 .. PART_N-1 -o OUT`): the
//! parts' tiles linked (or copied) into the output, the levels above the units built from the
//! units' coarsest contents exactly as the single-machine top stage builds them, then the
//! tileset stage (errors, utilities, subtrees, `tileset.json`) over the whole tree.

use super::part::{PART_FILE, PART_VERSION, PartFile, ROOTS_FILE};
use super::part_files::link_listed;
use super::plan::Plan;
use super::region::{RegionCtx, RootContent, WrittenParent};
use super::shard::{arr_key, bad, parse, read_bounded};
use super::spill_records::Codec;
use super::store::ContentStore;
use super::tileset::{
    TreeTile, build_tree, finish_tree, tileset_json, view_error, write_subtrees, write_tileset_json,
};
use super::{ConvertError, ConvertReport, SPILL_DIR, apply_parents, io_err};
use crate::output::Staging;
use splat2tiles_tiles::tiling::{Scheme, TileKey};
use std::collections::{BTreeMap, HashMap, HashSet};
use std::io::Read;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Largest part file read (a few hundred bytes per tile with content).
const MAX_PART_BYTES: u64 = 4 << 30;

/// What a merge did.
#[derive(Debug, Clone, Default)]
pub struct MergeReport {
    /// Tiles in the tree.
    pub tiles: usize,
    /// Tiles built above the units.
    pub top_tiles: usize,
    /// Tile files taken from the parts.
    pub part_files: u64,
    /// Bytes of those files.
    pub part_bytes: u64,
    /// Bytes copied (files that could not be hard-linked: parts on another file system).
    pub copied_bytes: u64,
    /// Bytes of every file of the output.
    pub bytes: u64,
    /// Wall-clock seconds.
    pub seconds: f64,
    /// Notes about the output folder.
    pub notes: Vec<String>,
}

/// Merges the built parts `parts` (folders, any order) of the plan at `plan_path` into the
/// tileset folder `output`.
pub fn merge_parts(
    plan_path: &Path,
    parts: &[PathBuf],
    output: &Path,
    memory_limit: u64,
    progress: crate::progress::ProgressSink,
) -> Result<MergeReport, ConvertError> {
    let start = Instant::now();
    let plan = Plan::load(plan_path)?;
    let n = plan.file.parts;
    if parts.len() != n {
        return Err(bad(
            plan_path,
            None,
            format!("the plan has {n} parts; {} part folders given", parts.len()),
        ));
    }
    let layout = &plan.layout;
    let scheme = layout.scheme;
    let opts = plan.options(memory_limit, progress);
    let degree = plan.file.input.sh_degree;
    let octree = scheme == Scheme::Octree;
    let max_level = layout.depth();

    let (files, radius) = read_parts(&plan, plan_path, parts, opts.lod.enabled, memory_limit)?;
    let mut inputs: Vec<&Path> = vec![plan_path];
    inputs.extend(parts.iter().map(PathBuf::as_path));
    crate::output::check_not_over_inputs(output, &inputs)?;
    let staging = Staging::prepare(output)?;
    let dir = staging.path().to_path_buf();
    let relocate = |e: ConvertError| e.relocated(&dir, output);
    let mut report = MergeReport::default();
    for (f, part_dir) in &files {
        let part_file = part_dir.join(PART_FILE);
        let done = link_listed(part_dir, &part_file, &f.files, &dir).map_err(relocate)?;
        report.part_files += done.files;
        report.part_bytes += done.bytes;
        report.copied_bytes += done.copied_bytes;
    }

    // The tree: every part's leaves, then every parent with content.
    let mut leaves: HashMap<TileKey, TreeTile> = HashMap::new();
    for (f, _) in &files {
        for t in &f.leaves {
            let k = arr_key(t.key, max_level, octree).expect("checked");
            leaves.insert(k, t.leaf());
        }
    }
    let mut conv = ConvertReport {
        sh_degree: degree,
        up_axis: plan.file.options.up_axis.clone(),
        ..Default::default()
    };
    conv.levels = leaves.keys().map(|k| k.level + 1).max().unwrap_or(1);
    conv.splats_out = leaves.values().map(|t| t.splat_count as usize).sum();
    let mut tree = build_tree(leaves);
    let unit_roots: Vec<(TileKey, u32)> = files
        .iter()
        .flat_map(|(f, _)| f.units.iter())
        .map(|u| {
            (
                arr_key(u.key, max_level, octree).expect("checked"),
                u.deepest,
            )
        })
        .collect();
    let mut top_keys: HashSet<TileKey> = HashSet::new();
    if let Some(r) = radius.filter(|_| opts.lod.enabled) {
        let cx = RegionCtx {
            layout,
            opts: &opts,
            dir: &dir,
            nn_step: 1,
            write_leaves: true,
            must_split: None,
        };
        let parents =
            top_levels(&cx, &files, &unit_roots, r, degree, &mut report).map_err(relocate)?;
        for (k, p) in &parents.1 {
            if p.content.is_some() {
                top_keys.insert(*k);
            }
        }
        let mut all = parents.0;
        all.extend(parents.1);
        apply_parents(&mut tree, all, &mut conv);
    }
    finish_tree(&mut tree);
    report.tiles = tree.len();
    if opts.variants.deferred_utility() {
        merge_utilities(
            &mut tree,
            &top_keys,
            &unit_roots,
            &dir,
            scheme,
            &opts.variants,
        )
        .map_err(relocate)?;
    }
    let subtree_levels = opts.subtree_levels_for(scheme, conv.levels);
    write_subtrees(&tree, scheme, subtree_levels, &dir).map_err(relocate)?;
    let tileset = tileset_json(
        &tree,
        layout,
        conv.levels,
        subtree_levels,
        &conv,
        &plan.file.input.name,
        &opts.variants,
    );
    write_tileset_json(&tileset, &dir).map_err(relocate)?;
    report.bytes = super::part::folder_bytes(&dir);
    report.notes = staging.commit()?;
    report.seconds = start.elapsed().as_secs_f64();
    Ok(report)
}

/// The part files with their folders, in part order.
type PartFiles = Vec<(PartFile, PathBuf)>;

/// LOD parents by key.
type Parents = BTreeMap<TileKey, WrittenParent>;

/// Every part file of `parts`, checked against the plan, in part order, and the leaf radius
/// they were built with (the same in every part with units; needed with `lod`).
fn read_parts(
    plan: &Plan,
    plan_path: &Path,
    parts: &[PathBuf],
    lod: bool,
    memory_limit: u64,
) -> Result<(PartFiles, Option<f64>), ConvertError> {
    // A parsed part takes a few times its text: at most a quarter of the memory limit is read.
    let part_cap = MAX_PART_BYTES.min(memory_limit / 4);
    let n = plan.file.parts;
    let mut files: Vec<Option<(PartFile, PathBuf)>> = (0..n).map(|_| None).collect();
    for dir in parts {
        let path = dir.join(PART_FILE);
        let bytes = read_bounded(&path, part_cap)?;
        let f = check_part(plan, plan_path, &path, &bytes)?;
        if files[f.part].is_some() {
            return Err(bad(
                &path,
                None,
                format!(
                    "part {}: expected each of the parts 0 to {} once",
                    f.part,
                    n - 1
                ),
            ));
        }
        let at = f.part;
        files[at] = Some((f, dir.clone()));
    }
    let files: Vec<(PartFile, PathBuf)> = files.into_iter().flatten().collect();
    let radius = files
        .iter()
        .find(|(f, _)| !f.units.is_empty())
        .and_then(|(f, _)| f.leaf_radius)
        .map(|r| r.0);
    if lod {
        for (f, dir) in &files {
            if !f.units.is_empty()
                && f.leaf_radius.map(|r| r.0.to_bits()) != radius.map(f64::to_bits)
            {
                return Err(bad(
                    &dir.join(PART_FILE),
                    None,
                    "built with another leaf radius than part 0's (built from other samples?)",
                ));
            }
        }
    }

    if lod && radius.is_none() {
        return Err(bad(plan_path, None, "no part records a leaf radius"));
    }
    Ok((files, radius))
}

/// Parses part-file `bytes` read from `path` and checks them against `plan` (read from
/// `plan_path`): version, plan, part number, the plan's units, tile keys inside the tree, and
/// plain paths for the listed files.
pub(super) fn check_part(
    plan: &Plan,
    plan_path: &Path,
    path: &Path,
    bytes: &[u8],
) -> Result<PartFile, ConvertError> {
    let n = plan.file.parts;
    let (max_level, octree) = (plan.layout.depth(), plan.layout.scheme == Scheme::Octree);
    let f: PartFile = parse(path, bytes)?;
    if f.splat2tiles_part != PART_VERSION {
        return Err(bad(
            path,
            None,
            format!("part version {}", f.splat2tiles_part),
        ));
    }
    if f.plan != plan.id {
        return Err(bad(
            path,
            None,
            format!("built from another plan than {}", plan_path.display()),
        ));
    }
    if f.part >= n {
        return Err(bad(
            path,
            None,
            format!(
                "part {}: expected each of the parts 0 to {} once",
                f.part,
                n - 1
            ),
        ));
    }
    let planned: Vec<TileKey> = plan.units_of(f.part);
    let keys: Option<Vec<TileKey>> = f
        .units
        .iter()
        .map(|u| arr_key(u.key, max_level, octree))
        .collect();
    if keys.as_ref() != Some(&planned) {
        return Err(bad(
            path,
            None,
            "its units are not the plan's units of the part",
        ));
    }
    for t in f.leaves.iter().chain(&f.parents) {
        if arr_key(t.key, max_level, octree).is_none() {
            return Err(bad(
                path,
                None,
                format!("tile {:?} is not in the tree", t.key),
            ));
        }
    }
    for rec in &f.files {
        if !super::part_files::is_plain(&rec.path) {
            return Err(bad(
                path,
                None,
                format!(
                    "listed file '{}' is not a plain path inside the part",
                    rec.path
                ),
            ));
        }
    }
    Ok(f)
}

/// The levels above the units, built from the units' contents (`ROOTS_FILE` of each part) as
/// the single-machine top stage builds them; returns the parts' parents and the new ones.
fn top_levels(
    cx: &RegionCtx<'_>,
    files: &[(PartFile, PathBuf)],
    unit_roots: &[(TileKey, u32)],
    r: f64,
    degree: u8,
    report: &mut MergeReport,
) -> Result<(Parents, Parents), ConvertError> {
    let (max_level, octree) = (cx.layout.depth(), cx.layout.scheme == Scheme::Octree);
    let codec = Codec::new(degree);
    let spill = cx.dir.join(SPILL_DIR);
    std::fs::create_dir_all(&spill).map_err(io_err(&spill, "creating folder"))?;
    let store = ContentStore::create(spill.join("contents.bin"), codec)?;
    for (f, part_dir) in files {
        load_roots(
            f,
            &part_dir.join(ROOTS_FILE),
            codec,
            (max_level, octree),
            cx.opts.memory_limit,
            &store,
        )?;
    }
    let roots: Vec<RootContent> = unit_roots
        .iter()
        .map(|&(key, deepest)| RootContent { key, deepest })
        .collect();
    let top = super::top::build_top(&roots, &store, degree, r, cx, &|_| false)?;
    drop(store);
    report.top_tiles = top.len();
    let mut parents: BTreeMap<TileKey, WrittenParent> = BTreeMap::new();
    for (f, _) in files {
        for t in &f.parents {
            parents.insert(
                arr_key(t.key, max_level, octree).expect("checked"),
                t.parent(),
            );
        }
    }
    std::fs::remove_dir_all(&spill).map_err(io_err(&spill, "removing spill files"))?;
    Ok((parents, top))
}

/// Utilities of the tiles the parts could not measure: the tiles above them and unit roots that
/// are leaves (viewed at their parent's error, known only now).
fn merge_utilities(
    tree: &mut BTreeMap<TileKey, TreeTile>,
    top_keys: &HashSet<TileKey>,
    unit_roots: &[(TileKey, u32)],
    dir: &Path,
    scheme: Scheme,
    variants: &crate::variants::VariantOptions,
) -> Result<(), ConvertError> {
    let tiles: Vec<_> = tree
        .iter()
        .filter(|(k, t)| {
            top_keys.contains(k) || (t.is_leaf && unit_roots.iter().any(|(u, _)| u == *k))
        })
        .filter_map(|(k, t)| {
            let curve = t.facts.as_ref()?.utility_curve.as_ref();
            Some((*k, view_error(tree, *k), curve))
        })
        .collect();
    let us = crate::variants::measure::measure_utilities(dir, scheme, &tiles, variants)?;
    let keys: Vec<TileKey> = tiles.iter().map(|t| t.0).collect();
    for (k, u) in keys.iter().zip(us) {
        if let Some(f) = tree.get_mut(k).and_then(|t| t.facts.as_mut()) {
            f.variant_utility = u;
        }
    }
    Ok(())
}

/// Puts the units' contents of one part (`roots.bin`, in the order of its units) into `store`.
fn load_roots(
    f: &PartFile,
    path: &Path,
    codec: Codec,
    (max_level, octree): (u32, bool),
    memory_limit: u64,
    store: &ContentStore,
) -> Result<(), ConvertError> {
    let rb = codec.record_bytes() as u64;
    let want = f.units.iter().try_fold(0u64, |a, u| {
        u.content.checked_mul(rb).and_then(|b| a.checked_add(b))
    });
    let file = std::fs::File::open(path).map_err(io_err(path, "reading"))?;
    let len = file.metadata().map_err(io_err(path, "reading"))?.len();
    if want != Some(len) {
        return Err(bad(
            path,
            None,
            format!(
                "{len} bytes where its part file lists {} bytes of unit contents",
                want.map_or("too many".to_string(), |w| w.to_string())
            ),
        ));
    }
    let mut r = std::io::BufReader::with_capacity(1 << 20, file);
    let mut offset = 0u64;
    for u in &f.units {
        let key = arr_key(u.key, max_level, octree).expect("checked");
        // Bounded by the file's length (checked above), which may be sparse: reserved fallibly.
        if u.content * rb > memory_limit / 2 {
            return Err(bad(
                path,
                Some(offset),
                format!(
                    "unit {:?}: {} bytes of content, more than half the memory limit ({memory_limit} bytes)",
                    u.key,
                    u.content * rb
                ),
            ));
        }
        let need = usize::try_from(u.content * rb).unwrap_or(usize::MAX);
        let mut buf = Vec::new();
        buf.try_reserve_exact(need).map_err(|_| {
            bad(
                path,
                Some(offset),
                format!(
                    "unit {:?}: cannot reserve {need} bytes for its content",
                    u.key
                ),
            )
        })?;
        buf.resize(need, 0);
        r.read_exact(&mut buf)
            .map_err(|e| bad(path, Some(offset), e))?;
        offset += buf.len() as u64;
        let mut s =
            splat2tiles_core::splat::Splats::with_capacity(codec.degree(), u.content as usize);
        let mut idx = Vec::with_capacity(u.content as usize);
        codec.decode(&buf, &mut s, &mut idx);
        if !u.radius.0.is_finite() || u.radius.0 < 0.0 {
            return Err(bad(
                path,
                None,
                format!("unit {:?}: radius not a number >= 0", u.key),
            ));
        }
        store.put(key, &s, u.radius.0)?;
    }
    Ok(())
}
