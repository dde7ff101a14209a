//! One part of a sharded conversion (`convert IN --plan PLAN.json --part I -o PART_I`): the
//! part's units (subtrees) built as the single-machine conversion builds them, from the splats
//! inside them only; everything the merge needs goes into the part folder (`part.json`, the
//! units' coarsest contents in `roots.bin`, the tiles).
//!
//! Two phases, because the default leaf radius is a median over every leaf of the scene:
//! `--phase samples` partitions the part and writes its spacing samples and deepest leaf level
//! (no tiles); the build then reads every part's samples (`--samples`) and so uses the very
//! radius a single-machine run computes. The samples phase is skipped when the radius is not
//! needed (`--lod-radius` given, or `--no-lod`).

use super::part_files::{FileRec, list_files};
use super::plan::{Plan, input_bytes_read, open_input};
use super::region::{self, GroupLeaves, RegionCtx, RootContent, WrittenParent};
use super::shard::{F, bad, f3, key_arr, parse, read_bounded, v3};
use super::spill::{Feed, Spiller};
use super::spill_records::{Codec, SpillFormat};
use super::store::ContentStore;
use super::tileset::{TreeTile, build_tree, finish_tree, view_error};
use super::{Budget, ConvertError, SPACING_SAMPLES, SPILL_DIR, default_radius, io_err, read_ahead};
use crate::output::Staging;
use crate::variants::ContentFacts;
use crate::variants::curve::{CURVE_DISTANCES, LossCurve};
use serde::{Deserialize, Serialize};
use splat2tiles_tiles::tiling::TileKey;
use std::collections::{BTreeMap, HashMap, HashSet};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Version of the part and samples files.
pub(super) const PART_VERSION: u32 = 2;

/// The part file inside a built part's folder.
pub(super) const PART_FILE: &str = "part.json";
/// The units' coarsest contents inside a built part's folder.
pub(super) const ROOTS_FILE: &str = "roots.bin";
/// The samples file inside a samples phase's folder.
pub(super) const SAMPLES_FILE: &str = "samples.json";

/// Largest samples file read (about 4,096 samples over all parts, plus one per leaf).
const MAX_SAMPLES_BYTES: u64 = 256 << 20;

/// Which phase of a part to run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PartPhase {
    /// Partition only: spacing samples and deepest leaf level (for the default leaf radius).
    Samples,
    /// Build the part's tiles.
    Build,
}

splat2tiles_core::named!(PartPhase {
    Samples => ("samples", "Partition only: spacing samples and deepest leaf level (for the default leaf radius)."),
    Build => ("build", "Build the part's tiles."),
});

/// What a part (either phase) did.
#[derive(Debug, Clone, Default)]
pub struct PartReport {
    /// Splats of the part (inside its units).
    pub splats: u64,
    /// Units built.
    pub units: usize,
    /// Tiles with content written.
    pub content_tiles: usize,
    /// Bytes of the part folder's files.
    pub bytes: u64,
    /// Bytes written to spill files.
    pub spill_bytes: u64,
    /// Bytes read from the input file (none when the part reads its routed files).
    pub input_bytes_read: u64,
    /// Leaf radius used (build phase with LOD).
    pub leaf_radius: Option<f64>,
    /// Wall-clock seconds.
    pub seconds: f64,
    /// Notes about the output folder.
    pub notes: Vec<String>,
}

/// `samples.json`.
#[derive(Debug, Serialize, Deserialize)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
pub(super) struct SamplesFile {
    splat2tiles_samples: u32,
    plan: String,
    pub(super) part: usize,
    deepest: Option<u32>,
    spacing: Vec<F>,
}

/// `part.json`.
#[derive(Debug, Serialize, Deserialize)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
pub(super) struct PartFile {
    pub(super) splat2tiles_part: u32,
    pub(super) plan: String,
    pub(super) part: usize,
    pub(super) leaf_radius: Option<F>,
    /// The units in Morton order; their contents follow one another in `roots.bin`.
    pub(super) units: Vec<UnitOut>,
    pub(super) leaves: Vec<TileRec>,
    /// LOD parents with content.
    pub(super) parents: Vec<TileRec>,
    /// Every tile file the part wrote (what the merge carries over, each checked first).
    pub(super) files: Vec<FileRec>,
}

/// A built unit: its root's content (`roots.bin`) and the deepest leaf level below it.
#[derive(Debug, Serialize, Deserialize)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
pub(super) struct UnitOut {
    pub(super) key: [u32; 4],
    pub(super) deepest: u32,
    /// Splats of the root's content in `roots.bin` (0 without LOD).
    pub(super) content: u64,
    pub(super) radius: F,
}

/// A tile with content, exactly as the tree holds it before `finish_tree` (no timings).
#[derive(Debug, Serialize, Deserialize)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
pub(super) struct TileRec {
    pub(super) key: [u32; 4],
    pub(super) lo: [F; 3],
    pub(super) hi: [F; 3],
    pub(super) error: F,
    pub(super) splat_count: u32,
    pub(super) variant_bytes: [u32; 4],
    pub(super) variant_utility: [F; 4],
    pub(super) bytes: u64,
    /// The writer's estimated-utility curve (`variants::curve`), for the tiles the merge
    /// measures; absent where none was made (the merge then reads the tile back).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) utility_curve: Option<CurveRec>,
}

/// A [`LossCurve`] stored exactly.
#[derive(Debug, Serialize, Deserialize)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
pub(super) struct CurveRec {
    lo: [F; 3],
    hi: [F; 3],
    up: [F; 3],
    coverage: Vec<F>,
    weighted: [Option<Vec<F>>; 4],
}

impl CurveRec {
    fn new(c: &LossCurve) -> Self {
        let f = |v: [f64; 3]| v.map(F);
        CurveRec {
            lo: f(c.lo),
            hi: f(c.hi),
            up: f(c.up),
            coverage: c.coverage.iter().copied().map(F).collect(),
            weighted: c
                .weighted
                .clone()
                .map(|l| l.map(|l| l.into_iter().map(F).collect())),
        }
    }

    /// The curve; `None` when its grid is not this build's (the tile is then read back).
    fn curve(&self) -> Option<LossCurve> {
        let f = |v: [F; 3]| v.map(|x| x.0);
        if self.coverage.len() != CURVE_DISTANCES.len() {
            return None;
        }
        let mut weighted: [Option<Vec<f64>>; 4] = Default::default();
        for (out, l) in weighted.iter_mut().zip(&self.weighted) {
            if let Some(l) = l {
                if l.len() != CURVE_DISTANCES.len() {
                    return None;
                }
                *out = Some(l.iter().map(|x| x.0).collect());
            }
        }
        Some(LossCurve {
            lo: f(self.lo),
            hi: f(self.hi),
            up: f(self.up),
            coverage: self.coverage.iter().map(|x| x.0).collect(),
            weighted,
        })
    }
}

impl TileRec {
    fn new(key: TileKey, lo: glam::DVec3, hi: glam::DVec3, error: f64, f: &ContentFacts) -> Self {
        TileRec {
            key: key_arr(key),
            lo: f3(lo),
            hi: f3(hi),
            error: F(error),
            splat_count: f.splat_count,
            variant_bytes: f.variant_bytes,
            variant_utility: f.variant_utility.map(|u| F(u as f64)),
            bytes: f.bytes,
            utility_curve: f.utility_curve.as_ref().map(CurveRec::new),
        }
    }

    /// The content facts (encoding times are not kept: the part file is the same on a rerun).
    pub(super) fn facts(&self) -> ContentFacts {
        ContentFacts {
            splat_count: self.splat_count,
            variant_bytes: self.variant_bytes,
            variant_utility: self.variant_utility.map(|u| u.0 as f32),
            encode_seconds: [0.0; 4],
            bytes: self.bytes,
            utility_curve: self.utility_curve.as_ref().and_then(CurveRec::curve),
        }
    }

    /// As a leaf of the tree.
    pub(super) fn leaf(&self) -> TreeTile {
        TreeTile::leaf(v3(&self.lo), v3(&self.hi), self.facts())
    }

    /// As a written parent.
    pub(super) fn parent(&self) -> WrittenParent {
        WrittenParent {
            content: Some((self.facts(), v3(&self.lo), v3(&self.hi))),
            error: self.error.0,
        }
    }
}

/// Runs `phase` of part `part` of the plan at `plan_path` over `input_path` into the folder
/// `output`. The build phase takes every part's samples folder in `samples` when the plan needs
/// the data's leaf radius. With `routed` (the folder of the routing step) the part reads its
/// routed files there, not the input.
#[allow(clippy::too_many_arguments)]
pub fn convert_part(
    input_path: &Path,
    plan_path: &Path,
    part: usize,
    phase: PartPhase,
    samples: &[PathBuf],
    routed: Option<&Path>,
    output: &Path,
    memory_limit: u64,
    progress: crate::progress::ProgressSink,
) -> Result<PartReport, ConvertError> {
    let start = Instant::now();
    let plan = Plan::load(plan_path)?;
    let opts = plan.options(memory_limit, progress);
    let r = leaf_radius(&plan, plan_path, part, phase, &opts, samples)?;
    let (source, format, fingerprint_read) =
        open_source(&plan, input_path, routed, part, memory_limit)?;
    let layout = &plan.layout;
    let degree = plan.file.input.sh_degree;
    let units = plan.units_of(part);
    let unit_set: HashSet<TileKey> = units.iter().copied().collect();

    let mut inputs: Vec<&Path> = vec![input_path, plan_path];
    inputs.extend(samples.iter().map(PathBuf::as_path));
    inputs.extend(routed);
    crate::output::check_not_over_inputs(output, &inputs)?;
    let staging = Staging::prepare(output)?;
    let dir = staging.path().to_path_buf();
    let relocate = |e: ConvertError| e.relocated(&dir, output);
    let (groups, spill_bytes) = split_source(
        &plan,
        &source,
        &format,
        input_path,
        &units,
        &dir,
        memory_limit,
    )
    .map_err(relocate)?;
    let mut report = PartReport {
        splats: groups.iter().map(|g| g.count()).sum(),
        units: units.len(),
        spill_bytes,
        input_bytes_read: match source {
            Source::Input(i) => fingerprint_read + input_bytes_read(&i, plan.file.input.bytes),
            Source::Routed(_) => 0,
        },
        leaf_radius: r,
        ..Default::default()
    };
    let cx = RegionCtx {
        layout,
        opts: &opts,
        dir: &dir,
        nn_step: plan.file.input.finite.div_ceil(SPACING_SAMPLES).max(1) as usize,
        write_leaves: phase == PartPhase::Build,
        must_split: None,
    };
    let mut built: Vec<GroupLeaves> = Vec::with_capacity(groups.len());
    let mut leaves: Vec<(TileKey, TreeTile)> = Vec::new();
    let mut spacing = Vec::new();
    let mut deepest: Option<u32> = None;
    read_ahead(
        groups,
        |g| region::load_group_input(g, &format),
        |loaded| region::build_leaves(loaded, &cx),
        |mut gl| {
            leaves.append(&mut gl.tiles);
            spacing.append(&mut gl.spacing);
            for r in &gl.regions {
                for (k, _) in &r.leaves {
                    deepest = Some(deepest.map_or(k.level, |d| d.max(k.level)));
                }
            }
            built.push(gl);
        },
    )
    .map_err(relocate)?;

    if phase == PartPhase::Samples {
        drop(built);
        let file = SamplesFile {
            splat2tiles_samples: PART_VERSION,
            plan: plan.id.clone(),
            part,
            deepest,
            spacing: spacing.into_iter().map(F).collect(),
        };
        remove_spill(&dir).map_err(relocate)?;
        report.bytes = write_part_json(&dir, SAMPLES_FILE, &file).map_err(relocate)?;
        report.notes = staging.commit()?;
        report.seconds = start.elapsed().as_secs_f64();
        return Ok(report);
    }

    leaves.sort_by_key(|(k, _)| *k);
    let mut leaf_recs: Vec<TileRec> = leaves
        .iter()
        .map(|(k, t)| {
            let f = t.facts.as_ref().expect("leaves have content");
            TileRec::new(*k, t.lo, t.hi, t.error, f)
        })
        .collect();
    report.content_tiles = leaves.len();
    let mut tree = build_tree(leaves.into_iter().collect());
    let unit_deepest = unit_deepest(&tree, &unit_set);
    let mut parent_recs = Vec::new();
    let unit_out;
    if let Some(r) = r {
        let units = Units {
            keys: &units,
            set: &unit_set,
            deepest: &unit_deepest,
        };
        let (parents, out) =
            part_parents(&cx, built, &format, r, degree, &units).map_err(relocate)?;
        unit_out = out;
        for (k, p) in &parents {
            if let Some((facts, lo, hi)) = &p.content {
                parent_recs.push(TileRec::new(*k, *lo, *hi, p.error, facts));
            }
        }
        let mut sink = super::ConvertReport::default();
        super::apply_parents(&mut tree, parents, &mut sink);
        report.content_tiles += sink.contents.len();
    } else {
        drop(built);
        // Without LOD the units carry no content.
        unit_out = units
            .iter()
            .filter_map(|&u| {
                let dp = unit_deepest.get(&u).copied()?;
                Some(UnitOut {
                    key: key_arr(u),
                    deepest: dp,
                    content: 0,
                    radius: F(0.0),
                })
            })
            .collect();
    }
    remove_spill(&dir).map_err(relocate)?;

    // Utilities measured at the tiles' final switching distances: final inside the part for
    // every tile but a unit root that is a leaf (its parent is above the part; the merge
    // measures it).
    if opts.variants.deferred_utility() {
        finish_tree(&mut tree);
        let recs = (&mut leaf_recs[..], &mut parent_recs[..]);
        part_utilities(&tree, recs, &unit_set, &dir, layout.scheme, &opts).map_err(relocate)?;
    }
    let file = PartFile {
        splat2tiles_part: PART_VERSION,
        plan: plan.id.clone(),
        part,
        leaf_radius: r.map(F),
        units: unit_out,
        leaves: leaf_recs,
        parents: parent_recs,
        files: list_files(&dir, "tiles").map_err(relocate)?,
    };
    write_part_json(&dir, PART_FILE, &file).map_err(relocate)?;
    report.bytes = folder_bytes(&dir);
    report.notes = staging.commit()?;
    report.seconds = start.elapsed().as_secs_f64();
    Ok(report)
}

/// Where a part's splats come from.
enum Source {
    /// The input file.
    Input(super::source::Input),
    /// The part's routed files, in input order.
    Routed(Vec<PathBuf>),
}

/// Where part `part` reads its splats: its routed files in `routed`, else the input (checked
/// against the plan); with their spill format and the bytes the input's check read.
fn open_source(
    plan: &Plan,
    input_path: &Path,
    routed: Option<&Path>,
    part: usize,
    memory_limit: u64,
) -> Result<(Source, SpillFormat, u64), ConvertError> {
    Ok(match routed {
        Some(dir) => {
            let (files, format) = super::route::routed_files(plan, input_path, dir, part)?;
            (Source::Routed(files), format, 0)
        }
        None => {
            let input = open_input(input_path, memory_limit)?;
            let read = plan.check_input(input_path, &input)?;
            let format = SpillFormat::for_input(&input);
            (Source::Input(input), format, read)
        }
    })
}

/// The part's splats from `source` split into groups of regions below its `units`, spilled
/// under the staging folder `dir`; with the bytes written to spill files.
fn split_source(
    plan: &Plan,
    source: &Source,
    format: &SpillFormat,
    input_path: &Path,
    units: &[TileKey],
    dir: &Path,
    memory_limit: u64,
) -> Result<(Vec<super::spill::Group>, u64), ConvertError> {
    let name = input_path.display().to_string();
    let o = &plan.file.options;
    let budget = Budget::new(memory_limit, plan.file.input.sh_degree, o.max_splats);
    let mut spiller = Spiller::new(
        &name,
        memory_limit,
        &plan.layout,
        format.clone(),
        dir.join(SPILL_DIR),
        budget.cap,
        budget.chunk,
        budget.write_budget,
    );
    spiller.all_finite = plan.file.input.dropped == 0;
    let feed = match source {
        Source::Input(i) => Feed::Input(i),
        Source::Routed(files) => Feed::Files(files),
    };
    let groups = spiller.split_units(feed, units, &plan.prefix)?;
    Ok((groups, spiller.bytes))
}

/// The leaf radius the build phase of `part` uses (from the plan or every part's samples;
/// `None` in the samples phase or without LOD), once `part` is checked against the plan.
fn leaf_radius(
    plan: &Plan,
    plan_path: &Path,
    part: usize,
    phase: PartPhase,
    opts: &super::ConvertOptions,
    samples: &[PathBuf],
) -> Result<Option<f64>, ConvertError> {
    if part >= plan.file.parts {
        return Err(bad(
            plan_path,
            None,
            format!(
                "part {part}: the plan has parts 0 to {}",
                plan.file.parts - 1
            ),
        ));
    }
    Ok(match (phase, opts.lod.enabled, opts.lod.radius) {
        (PartPhase::Build, true, Some(r)) => Some(r),
        (PartPhase::Build, true, None) => Some(radius_from_samples(plan, samples)?),
        _ => None,
    })
}

/// Writes `value` as JSON to `dir/name`; returns its bytes.
fn write_part_json<T: Serialize>(dir: &Path, name: &str, value: &T) -> Result<u64, ConvertError> {
    let json = serde_json::to_vec(value).expect("part records serialise");
    let path = dir.join(name);
    std::fs::write(&path, &json).map_err(io_err(&path, "writing"))?;
    Ok(json.len() as u64)
}

/// The deepest leaf level below each unit of the part.
fn unit_deepest(
    tree: &BTreeMap<TileKey, TreeTile>,
    unit_set: &HashSet<TileKey>,
) -> HashMap<TileKey, u32> {
    let mut deepest: HashMap<TileKey, u32> = HashMap::new();
    for k in tree.iter().filter(|(_, t)| t.is_leaf).map(|(k, _)| *k) {
        let mut a = Some(k);
        while let Some(u) = a {
            if unit_set.contains(&u) {
                let e = deepest.entry(u).or_insert(k.level);
                *e = (*e).max(k.level);
                break;
            }
            a = u.parent();
        }
    }
    deepest
}

/// The part's units: in plan order, as a set, and the deepest leaf level below each.
struct Units<'a> {
    keys: &'a [TileKey],
    set: &'a HashSet<TileKey>,
    deepest: &'a HashMap<TileKey, u32>,
}

/// The LOD parents of the part's groups up to its units (leaf radius `r`), and the units'
/// contents written in order to `ROOTS_FILE` for the levels the merge builds above them.
fn part_parents(
    cx: &RegionCtx<'_>,
    built: Vec<GroupLeaves>,
    format: &SpillFormat,
    r: f64,
    degree: u8,
    units: &Units<'_>,
) -> Result<(BTreeMap<TileKey, WrittenParent>, Vec<UnitOut>), ConvertError> {
    let spill = cx.dir.join(SPILL_DIR);
    std::fs::create_dir_all(&spill).map_err(io_err(&spill, "creating folder"))?;
    let codec = Codec::new(degree);
    let store = ContentStore::create(spill.join("contents.bin"), codec)?;
    let mut parents: BTreeMap<TileKey, WrittenParent> = BTreeMap::new();
    let mut roots: Vec<RootContent> = Vec::new();
    read_ahead(
        built,
        |g| region::load_group(g, format),
        |loaded| region::build_parents(loaded, r, &store, cx),
        |(p, rc)| {
            parents.extend(p);
            roots.extend(rc);
        },
    )?;
    let in_unit = |k: TileKey| units.set.contains(&k);
    parents.extend(super::top::build_top(
        &roots, &store, degree, r, cx, &in_unit,
    )?);
    let path = cx.dir.join(ROOTS_FILE);
    let f = std::fs::File::create(&path).map_err(io_err(&path, "creating"))?;
    let mut w = std::io::BufWriter::with_capacity(1 << 20, f);
    let mut unit_out = Vec::with_capacity(units.keys.len());
    for &u in units.keys {
        let Some(dp) = units.deepest.get(&u).copied() else {
            continue;
        };
        let (s, radius) = store
            .get(u)?
            .ok_or_else(|| bad(&path, None, format!("unit {u:?} has no stored content")))?;
        codec
            .write_all(&s, &vec![0u64; s.len()], &mut w)
            .map_err(io_err(&path, "writing"))?;
        unit_out.push(UnitOut {
            key: key_arr(u),
            deepest: dp,
            content: s.len() as u64,
            radius: F(radius),
        });
    }
    w.into_inner()
        .map_err(|e| e.into_error())
        .map_err(io_err(&path, "writing"))?;
    Ok((parents, unit_out))
}

/// Utilities measured at the tiles' final switching distances: final inside the part for
/// every tile but a unit root that is a leaf (its parent is above the part; the merge
/// measures it).
fn part_utilities(
    tree: &BTreeMap<TileKey, TreeTile>,
    (leaf_recs, parent_recs): (&mut [TileRec], &mut [TileRec]),
    unit_set: &HashSet<TileKey>,
    dir: &Path,
    scheme: splat2tiles_tiles::tiling::Scheme,
    opts: &super::ConvertOptions,
) -> Result<(), ConvertError> {
    let tiles: Vec<(TileKey, f64, Option<LossCurve>)> = leaf_recs
        .iter()
        .chain(parent_recs.iter())
        .map(|t| (key_of(t.key), t.utility_curve.as_ref()))
        .filter(|(k, _)| !(unit_set.contains(k) && tree[k].is_leaf))
        .map(|(k, c)| (k, view_error(tree, k), c.and_then(CurveRec::curve)))
        .collect();
    let refs: Vec<_> = tiles.iter().map(|(k, e, c)| (*k, *e, c.as_ref())).collect();
    let us = crate::variants::measure::measure_utilities(dir, scheme, &refs, &opts.variants)?;
    let by_key: HashMap<TileKey, [f32; 4]> = tiles.iter().map(|t| t.0).zip(us).collect();
    for t in leaf_recs.iter_mut().chain(parent_recs.iter_mut()) {
        if let Some(u) = by_key.get(&key_of(t.key)) {
            t.variant_utility = u.map(|u| F(u as f64));
        }
    }
    Ok(())
}

/// A key of a part file this process wrote.
fn key_of(a: [u32; 4]) -> TileKey {
    TileKey {
        level: a[0],
        x: a[1],
        y: a[2],
        z: a[3],
    }
}

fn remove_spill(dir: &Path) -> Result<(), ConvertError> {
    let spill = dir.join(SPILL_DIR);
    if spill.exists() {
        std::fs::remove_dir_all(&spill).map_err(io_err(&spill, "removing spill files"))?;
    }
    Ok(())
}

/// Bytes of every file under `dir`.
pub(super) fn folder_bytes(dir: &Path) -> u64 {
    let mut total = 0;
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        let Ok(rd) = std::fs::read_dir(&d) else {
            continue;
        };
        for e in rd.flatten() {
            match e.file_type() {
                Ok(t) if t.is_dir() => stack.push(e.path()),
                Ok(t) if t.is_file() => total += e.metadata().map_or(0, |m| m.len()),
                _ => {}
            }
        }
    }
    total
}

/// Parses samples-file `bytes` read from `path` and checks them against `plan`: version, plan,
/// part number, positive spacings, a deepest level inside the tree.
pub(super) fn check_samples(
    plan: &Plan,
    path: &Path,
    bytes: &[u8],
) -> Result<SamplesFile, ConvertError> {
    let n = plan.file.parts;
    let s: SamplesFile = parse(path, bytes)?;
    if s.splat2tiles_samples != PART_VERSION {
        return Err(bad(
            path,
            None,
            format!("samples version {}", s.splat2tiles_samples),
        ));
    }
    if s.plan != plan.id {
        return Err(bad(
            path,
            None,
            format!("made from another plan than {}", plan.path.display()),
        ));
    }
    if s.part >= n {
        return Err(bad(
            path,
            None,
            format!("part {}: each of the parts 0 to {} once", s.part, n - 1),
        ));
    }
    if s.spacing.iter().any(|x| !(x.0.is_finite() && x.0 > 0.0)) {
        return Err(bad(path, None, "a spacing sample is not a positive number"));
    }
    if s.deepest.is_some_and(|d| d > plan.layout.depth()) {
        return Err(bad(path, None, "deepest level below the plan's deepest"));
    }
    Ok(s)
}

/// The default leaf radius from every part's samples: the single-machine rule over the union
/// of the samples, the deepest leaf level the deepest of all parts'.
fn radius_from_samples(plan: &Plan, folders: &[PathBuf]) -> Result<f64, ConvertError> {
    let n = plan.file.parts;
    if folders.len() != n {
        return Err(bad(
            &plan.path,
            None,
            format!(
                "the build needs the samples of all {n} parts (--samples DIR ..., from \
                 `--phase samples`), got {}",
                folders.len()
            ),
        ));
    }
    let mut seen = vec![false; n];
    let mut spacing = Vec::new();
    let mut deepest: Option<u32> = None;
    for f in folders {
        let path = f.join(SAMPLES_FILE);
        let bytes = read_bounded(&path, MAX_SAMPLES_BYTES)?;
        let s = check_samples(plan, &path, &bytes)?;
        if seen[s.part] {
            return Err(bad(
                &path,
                None,
                format!("part {}: each of the parts 0 to {} once", s.part, n - 1),
            ));
        }
        seen[s.part] = true;
        spacing.extend(s.spacing.into_iter().map(|x| x.0));
        deepest = deepest.max(s.deepest);
    }
    let layout = &plan.layout;
    Ok(default_radius(
        &mut spacing,
        layout.tile_edge(deepest.unwrap_or(0)),
        layout.tile_edge(0),
    ))
}
