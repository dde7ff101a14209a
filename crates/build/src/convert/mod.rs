//! The conversion pipeline, one module per stage, data flowing one way: chunked read (`source`)
//! -> `frame` -> `spill` -> `region` (leaves, then LOD parents) -> `top` -> `tileset`.
//!
//! Everything is written into a staging folder renamed into place at the end; the working set
//! stays within `--memory-limit` (ARCHITECTURE.md "Out-of-core conversion").

mod frame;
mod lapis;
mod layered;
mod merge;
mod options;
mod part;
mod part_files;
mod plan;
mod region;
mod route;
mod shard;
mod shard_checks;
mod source;
mod spill;
mod spill_records;
mod store;
mod tileset;
mod top;

use crate::lod::LEAF_SIZE_DIVISOR;
use crate::output::{OutputError, Staging};
use frame::{FrameAccum, Layout};
pub use lapis::{LapisReport, import_lapisgs};
use layered::layer_tree;
pub use merge::{MergeReport, merge_parts};
pub use options::{ConvertError, ConvertOptions, ConvertReport, NonFinitePolicy, SchemeChoice};
pub use part::{PartPhase, PartReport, convert_part};
pub use plan::{MAX_PARTS, PLAN_VERSION, PlanReport, make_plan};
use rayon::prelude::*;
use region::{GroupLeaves, RegionCtx};
pub use route::{MAX_ROUTE_CHUNKS, MAX_ROUTE_PARTS, RouteReport, route_input};
pub use shard_checks::{check_part_bytes, check_plan_bytes, check_samples_bytes};
use source::Input;
use spill::Spiller;
use spill_records::{Codec, SpillFormat};
use splat2tiles_core::frame::geo::Geodetic;
use splat2tiles_core::frame::{UpAxis, source_to_tileset};
use splat2tiles_core::splat::Splats;
use splat2tiles_io::{self as io, ChunkedInput, Scene};
use splat2tiles_tiles::tiling::TileKey;
use std::collections::HashMap;
use std::panic::resume_unwind;
use std::path::Path;
use std::time::Instant;
use tileset::{
    TreeTile, build_tree, finish_tree, tileset_json, write_subtrees, write_tileset_json,
};

/// Folder of the spill files inside the staging folder (removed before the output is committed).
const SPILL_DIR: &str = ".spill";

/// Spacing samples the default leaf radius is the median of (about; see [`region`]).
const SPACING_SAMPLES: u64 = 4096;

/// Stops the pipeline when an interrupt arrived (polled between tiles).
fn check_interrupt() -> Result<(), ConvertError> {
    if crate::output::interrupted() {
        Err(OutputError::Interrupted.into())
    } else {
        Ok(())
    }
}

fn io_err<'a>(
    path: &'a Path,
    what: &'static str,
) -> impl FnOnce(std::io::Error) -> ConvertError + 'a {
    move |source| ConvertError::Io {
        path: path.to_path_buf(),
        what,
        source,
    }
}

/// Reads `input` and writes its tileset to the folder `output` (atomically). Binary PLY and
/// `.splat` files are read in chunks, never whole; other inputs through the whole-file readers.
pub fn convert(
    input: &Path,
    output: &Path,
    opts: &ConvertOptions,
) -> Result<ConvertReport, ConvertError> {
    let start = Instant::now();
    let source = match ChunkedInput::open(input)? {
        Some(c) => Input::Chunked(c),
        None => {
            let spinner = crate::progress::begin(
                &opts.progress,
                &format!("reading {}", input.display()),
                None,
            );
            let scene = io::read_path_limited(input, opts.memory_limit)?;
            spinner.finish();
            Input::Memory(scene)
        }
    };
    let mut report = run(source, &input.display().to_string(), output, opts)?;
    report.seconds = start.elapsed().as_secs_f64();
    Ok(report)
}

/// Writes the tileset of an already-read scene to `output`; `name` names the input in errors.
pub fn convert_scene(
    scene: Scene,
    name: &str,
    output: &Path,
    opts: &ConvertOptions,
) -> Result<ConvertReport, ConvertError> {
    run(Input::Memory(scene), name, output, opts)
}

/// The up axis of `input` (`--up-axis`, else its format's default), the source -> tileset
/// rotation (with `--heading`) and the memory budget of converting it: shared by a conversion
/// and a plan.
fn frame_and_budget(input: &Input, opts: &ConvertOptions) -> (UpAxis, glam::DMat3, Budget) {
    let up = opts.up_axis.unwrap_or_else(|| {
        input
            .format()
            .default_up_axis()
            .parse()
            .unwrap_or(UpAxis::NegY)
    });
    let budget = Budget::new(
        opts.memory_limit,
        input.sh_degree(),
        opts.max_splats_per_tile,
    );
    (up, source_to_tileset(up, opts.heading_deg), budget)
}

/// How the memory limit is shared out between the stages (see ARCHITECTURE.md).
#[derive(Debug, Clone, Copy)]
struct Budget {
    /// Records decoded per input chunk.
    chunk: usize,
    /// Most splats one group of regions holds in memory.
    cap: u64,
    /// Bytes of spill write buffers in one routing pass.
    write_budget: usize,
}

impl Budget {
    fn new(limit: u64, degree: u8, max_splats: usize) -> Budget {
        let splat = splat2tiles_io::limits::splat_bytes(degree);
        Budget {
            chunk: (limit / 64 / (3 * splat)).clamp(1024, 1 << 18) as usize,
            cap: splat2tiles_io::limits::region_splats(limit, degree).max(max_splats as u64),
            write_budget: (limit / 16).clamp(1 << 20, 256 << 20) as usize,
        }
    }
}

/// Builds each group in order while the next one is read on a second thread: `load` (reading
/// and decoding a group) leaves a core idle at the end of every level of the build, and two
/// loaded groups fit the region budget (`limits::region_bytes_per_splat`). Errors and panics
/// of a read surface when that group's turn comes; `take` gets each build's result in order.
fn read_ahead<G: Send, L: Send, T>(
    groups: Vec<G>,
    load: impl Fn(G) -> Result<L, ConvertError> + Sync,
    mut build: impl FnMut(L) -> Result<T, ConvertError>,
    mut take: impl FnMut(T),
) -> Result<(), ConvertError> {
    let mut groups = groups.into_iter();
    let mut next = groups.next().map(&load);
    while let Some(loaded) = next.take() {
        let loaded = loaded?;
        let (built, ahead) = std::thread::scope(|s| {
            let ahead = groups.next().map(|g| s.spawn(|| load(g)));
            let built = build(loaded);
            let ahead = ahead.map(|h| h.join().unwrap_or_else(|e| resume_unwind(e)));
            (built, ahead)
        });
        next = ahead;
        take(built?);
    }
    Ok(())
}

/// What the frame pass counted.
#[derive(Debug, Default)]
struct Counts {
    finite: u64,
    dropped: u64,
    first_bad: Option<u64>,
    repaired: usize,
    overflowed: usize,
}

/// The pipeline: frame pass, spill, regions (leaves, then parents), top levels, tileset.
fn run(
    input: Input,
    name: &str,
    output: &Path,
    opts: &ConvertOptions,
) -> Result<ConvertReport, ConvertError> {
    let start = Instant::now();
    if opts.layers {
        layered::check_options(opts)?;
    }
    let (up, a, budget) = frame_and_budget(&input, opts);
    let degree = input.sh_degree();

    // Frame stage: one pass for the non-finite policy, the bounds and the georeferenced root.
    // A chunked scene that fits the budget is kept from this pass (not decoded a second time).
    let hold = matches!(input, Input::Chunked(_)) && input.len() <= budget.cap;
    let (acc, counts, held) = frame_pass(&input, a, opts, budget.chunk, hold)?;
    let mut report = ConvertReport {
        splats_in: input.len() as usize,
        repaired_rotations: counts.repaired,
        overflowed_scales: counts.overflowed,
        sh_degree: degree,
        up_axis: up.to_string(),
        ..Default::default()
    };
    report.dropped_non_finite = check_counts(&counts, &input, name, opts)?;
    report
        .stage_seconds
        .push(("frame", start.elapsed().as_secs_f64()));
    let layout = Layout::new(&acc, a, opts);
    report.scheme = layout.scheme.as_str().to_string();

    let staging = Staging::prepare(output)?;
    let dir = staging.path().to_path_buf();
    let relocate = |e: ConvertError| e.relocated(&dir, output);
    let codec = Codec::new(degree);
    let format = SpillFormat::for_input(&input);

    // Spill stage: regions that fit the budget (one in memory when the whole scene does).
    let spinner = crate::progress::begin(&opts.progress, "partitioning", None);
    let mut spiller = Spiller::new(
        name,
        opts.memory_limit,
        &layout,
        format.clone(),
        dir.join(SPILL_DIR),
        budget.cap,
        budget.chunk,
        budget.write_budget,
    );
    spiller.all_finite = counts.dropped == 0;
    let mut split_plan: Option<crate::partition::plan::SplitPlan> = None;
    if opts.partition.is_some() && counts.finite > budget.cap {
        return Err(ConvertError::Partition {
            file: name.to_string(),
            why: format!(
                "needs the scene in memory ({} splats; --memory-limit fits {})",
                counts.finite, budget.cap
            ),
        });
    }
    let groups = if counts.finite <= budget.cap {
        let (group, plan) = whole_scene(input, held, &counts, &layout, opts, name)?;
        split_plan = plan;
        vec![group]
    } else {
        drop(held);
        let groups = spiller.split(&input, counts.finite).map_err(relocate)?;
        drop(input);
        groups
    };
    spinner.finish();
    report.spill_bytes = spiller.bytes;
    report
        .stage_seconds
        .push(("spill", start.elapsed().as_secs_f64()));
    report.regions = groups.iter().map(|g| g.regions.len()).sum();

    // Region stage, pass 1: leaves.
    let cx = RegionCtx {
        layout: &layout,
        opts,
        dir: &dir,
        nn_step: counts.finite.div_ceil(SPACING_SAMPLES).max(1) as usize,
        write_leaves: true,
        must_split: split_plan.as_ref().map(|p| &p.must_split),
    };
    let leaf_bar =
        crate::progress::begin(&opts.progress, "writing leaves", Some(groups.len() as u64));
    let mut built: Vec<GroupLeaves> = Vec::with_capacity(groups.len());
    let mut leaves: HashMap<TileKey, TreeTile> = HashMap::new();
    let mut spacing = Vec::new();
    let mut index_map = Vec::new();
    read_ahead(
        groups,
        |g| region::load_group_input(g, &format),
        |loaded| region::build_leaves(loaded, &cx),
        |mut gl| {
            leaves.extend(std::mem::take(&mut gl.tiles));
            spacing.append(&mut gl.spacing);
            index_map.append(&mut gl.index_map);
            built.push(gl);
            leaf_bar.advance(1);
        },
    )
    .map_err(relocate)?;
    leaf_bar.finish();
    report
        .stage_seconds
        .push(("leaves", start.elapsed().as_secs_f64()));
    report_leaves(&leaves, &mut report);
    let mut tree = build_tree(leaves);

    // Region stage, pass 2, and the top stage: LOD parents.
    if opts.lod.enabled {
        let lod = Lod {
            cx: &cx,
            format: &format,
            codec,
            degree,
            start,
        };
        lod.build(built, &mut spacing, &mut tree, &mut report)
            .map_err(relocate)?;
    } else {
        drop(built);
    }
    let spill = dir.join(SPILL_DIR);
    if spill.exists() {
        std::fs::remove_dir_all(&spill)
            .map_err(io_err(&spill, "removing spill files"))
            .map_err(relocate)?;
    }
    finish_tree(&mut tree);
    report.tiles = tree.len();
    if opts.variants.deferred_utility() {
        tileset::measure_utilities(&mut tree, layout.scheme, &dir, &opts.variants, &mut report)
            .map_err(relocate)?;
        report
            .stage_seconds
            .push(("utilities", start.elapsed().as_secs_f64()));
    }

    if opts.layers {
        layer_tree(&mut tree, layout.scheme, &dir, &mut report).map_err(relocate)?;
        report
            .stage_seconds
            .push(("layers", start.elapsed().as_secs_f64()));
    }

    // Tileset stage.
    write_tileset(&tree, &layout, opts, &dir, &mut report, name).map_err(relocate)?;
    report.notes = staging.commit()?;
    report
        .stage_seconds
        .push(("tileset", start.elapsed().as_secs_f64()));
    if opts.keep_index_map {
        report.leaves = index_map;
    }
    report.partition = split_plan;
    report.seconds = start.elapsed().as_secs_f64();
    Ok(report)
}

/// What the leaves put on the report: levels, content tiles and their facts, splats, bytes.
fn report_leaves(leaves: &HashMap<TileKey, TreeTile>, report: &mut ConvertReport) {
    report.levels = leaves.keys().map(|k| k.level + 1).max().unwrap_or(1);
    report.content_tiles = leaves.len();
    report.contents = leaves
        .iter()
        .filter_map(|(k, t)| t.facts.clone().map(|f| (*k, f)))
        .collect();
    report.contents.sort_by_key(|(k, _)| *k);
    report.splats_out = leaves.values().map(|t| t.splat_count as usize).sum();
    report.bytes = leaves.values().map(|t| t.bytes).sum();
}

/// The whole scene as one region in memory: the splats kept by the frame pass, or the scene
/// already read (moved, not copied, when every splat is finite); with `--partition`, the split
/// plan over them.
fn whole_scene(
    input: Input,
    held: Splats,
    counts: &Counts,
    layout: &Layout,
    opts: &ConvertOptions,
    name: &str,
) -> Result<(spill::Group, Option<crate::partition::plan::SplitPlan>), ConvertError> {
    let s = match input {
        Input::Chunked(_) => held,
        Input::Memory(scene) if counts.dropped == 0 => scene.splats,
        Input::Memory(scene) => {
            let finite: Vec<usize> = (0..scene.splats.len())
                .filter(|&i| scene.splats.is_finite(i))
                .collect();
            scene.splats.select(&finite)
        }
    };
    let mut split_plan = None;
    if let Some(req) = &opts.partition {
        let unit: Vec<[f64; 3]> = s.positions.par_iter().map(|p| layout.unit(*p)).collect();
        let world: Vec<glam::DVec3> = s
            .positions
            .par_iter()
            .map(|p| layout.to_tileset(*p))
            .collect();
        let plan = crate::partition::plan::split_plan(
            req,
            layout.scheme,
            layout.depth(),
            &unit,
            &world,
            opts.max_splats_per_tile as u64,
        )
        .map_err(|why| ConvertError::Partition {
            file: name.to_string(),
            why,
        })?;
        split_plan = Some(plan);
    }
    Ok((spill::whole(s, counts.finite), split_plan))
}

/// The LOD stages: parents of each group's leaves (region pass 2), then the top levels above
/// the regions.
struct Lod<'a> {
    cx: &'a RegionCtx<'a>,
    format: &'a SpillFormat,
    codec: Codec,
    degree: u8,
    /// When the conversion started (the report's stage times count from it).
    start: Instant,
}

impl Lod<'_> {
    /// Builds every LOD parent and puts it in `tree`.
    fn build(
        &self,
        built: Vec<GroupLeaves>,
        spacing: &mut [f64],
        tree: &mut std::collections::BTreeMap<TileKey, TreeTile>,
        report: &mut ConvertReport,
    ) -> Result<(), ConvertError> {
        let (cx, opts) = (self.cx, self.cx.opts);
        let t0 = Instant::now();
        let r = opts.lod.radius.unwrap_or_else(|| {
            default_radius(
                spacing,
                cx.layout.tile_edge(report.levels.saturating_sub(1)),
                cx.layout.tile_edge(0),
            )
        });
        let lod_bar =
            crate::progress::begin(&opts.progress, "building LOD", Some(built.len() as u64));
        let mut parents = std::collections::BTreeMap::new();
        let mut roots = Vec::new();
        let spill = cx.dir.join(SPILL_DIR);
        std::fs::create_dir_all(&spill).map_err(io_err(&spill, "creating folder"))?;
        let store = store::ContentStore::create(spill.join("contents.bin"), self.codec)?;
        read_ahead(
            built,
            |g| region::load_group(g, self.format),
            |loaded| region::build_parents(loaded, r, &store, cx),
            |(p, rc)| {
                parents.extend(p);
                roots.extend(rc);
                lod_bar.advance(1);
            },
        )?;
        lod_bar.finish();
        report
            .stage_seconds
            .push(("parents", self.start.elapsed().as_secs_f64()));
        parents.extend(top::build_top(&roots, &store, self.degree, r, cx, &|_| {
            false
        })?);
        drop(store);
        report
            .stage_seconds
            .push(("top", self.start.elapsed().as_secs_f64()));
        apply_parents(tree, parents, report);
        report.lod_radius = r;
        report.lod_seconds = t0.elapsed().as_secs_f64();
        Ok(())
    }
}

/// Writes the subtrees, then `tileset.json` (which describes the report so far), into `dir`;
/// their count and bytes go on the report.
fn write_tileset(
    tree: &std::collections::BTreeMap<TileKey, TreeTile>,
    layout: &Layout,
    opts: &ConvertOptions,
    dir: &Path,
    report: &mut ConvertReport,
    name: &str,
) -> Result<(), ConvertError> {
    let subtree_levels = opts.subtree_levels_for(layout.scheme, report.levels);
    let (subtrees, subtree_bytes) = write_subtrees(tree, layout.scheme, subtree_levels, dir)?;
    report.subtrees = subtrees;
    report.bytes += subtree_bytes;
    let mut tileset = tileset_json(
        tree,
        layout,
        report.levels,
        subtree_levels,
        report,
        name,
        &opts.variants,
    );
    if opts.layers {
        tileset.root.refine = Some("ADD".into());
    }
    report.bytes += write_tileset_json(&tileset, dir)?;
    Ok(())
}

/// The frame pass: every splat once, for the non-finite policy, the bounds and the
/// georeferenced root; with `hold`, the finite splats are kept (a scene that fits the budget).
fn frame_pass(
    input: &Input,
    a: glam::DMat3,
    opts: &ConvertOptions,
    chunk: usize,
    hold: bool,
) -> Result<(FrameAccum, Counts, Splats), ConvertError> {
    let degree = input.sh_degree();
    let mut acc = FrameAccum::new(opts.origin.is_some());
    let enu = opts.origin.map(Geodetic::enu_to_ecef);
    let mut counts = Counts::default();
    let mut held = Splats::with_capacity(degree, if hold { input.len() as usize } else { 0 });
    input.for_each_raw(chunk, |ch| {
        check_interrupt()?;
        let s = ch.splats;
        let keep: Vec<bool> = (0..s.len())
            .into_par_iter()
            .map(|i| s.is_finite(i))
            .collect();
        let kept = keep.iter().filter(|k| **k).count() as u64;
        if counts.first_bad.is_none() && kept < s.len() as u64 {
            counts.first_bad = keep.iter().position(|k| !k).map(|i| ch.first + i as u64);
        }
        counts.finite += kept;
        counts.dropped += s.len() as u64 - kept;
        counts.repaired += ch.repaired_rotations;
        counts.overflowed += ch.overflowed_scales;
        acc.add(s, &keep, a, enu);
        if hold {
            if kept == s.len() as u64 {
                crate::lod::append(&mut held, s);
            } else {
                let finite: Vec<usize> = (0..s.len()).filter(|&i| keep[i]).collect();
                crate::lod::append(&mut held, &s.select(&finite));
            }
        }
        Ok(())
    })?;
    Ok((acc, counts, held))
}

/// Applies the non-finite policy and refuses an input without finite splats; returns the
/// splats dropped.
fn check_counts(
    counts: &Counts,
    input: &Input,
    name: &str,
    opts: &ConvertOptions,
) -> Result<usize, ConvertError> {
    let mut dropped = 0;
    if let Some(i) = counts.first_bad {
        match opts.non_finite {
            NonFinitePolicy::Fail => {
                let note = if counts.overflowed > 0 {
                    format!(
                        " ({} splats have finite log-scales too large for exp(), e.g. above 88.7: \
                         their scale overflows)",
                        counts.overflowed
                    )
                } else {
                    String::new()
                };
                return Err(ConvertError::NonFinite {
                    file: name.to_string(),
                    location: input.locator().describe(i as usize),
                    index: i as usize,
                    note,
                });
            }
            NonFinitePolicy::Drop => dropped = counts.dropped as usize,
        }
    }
    if counts.finite == 0 {
        let why = if dropped > 0 && counts.overflowed > 0 {
            format!(
                " (all {} splats had NaN or infinite values; {} of them are finite in the file but \
                 have log-scales too large for exp(), e.g. above 88.7, so their scale overflows)",
                dropped, counts.overflowed
            )
        } else if dropped > 0 {
            format!(" (all {dropped} splats had NaN or infinite values)")
        } else {
            " (the file holds zero splats)".to_string()
        };
        return Err(ConvertError::Empty {
            file: name.to_string(),
            why,
        });
    }
    Ok(dropped)
}

/// Gives the tree its LOD parents with content (boxes, errors, facts) and counts them in the
/// report; parents that are no real level of detail keep no content (`tiling::levels`).
fn apply_parents(
    tree: &mut std::collections::BTreeMap<TileKey, TreeTile>,
    parents: std::collections::BTreeMap<TileKey, region::WrittenParent>,
    report: &mut ConvertReport,
) {
    for (key, p) in parents {
        let Some((facts, lo, hi)) = p.content else {
            continue;
        };
        let t = tree.get_mut(&key).expect("parents are tree tiles");
        t.splat_count = facts.splat_count;
        t.bytes = facts.bytes;
        t.has_content = true;
        t.error = p.error;
        t.lo = t.lo.min(lo);
        t.hi = t.hi.max(hi);
        report.content_tiles += 1;
        report.parent_splats += facts.splat_count as usize;
        report.bytes += facts.bytes;
        report.contents.push((key, facts.clone()));
        t.facts = Some(facts);
    }
    report.contents.sort_by_key(|(k, _)| *k);
}

/// The default leaf radius `r`: the deepest leaf tile's edge divided by [`LEAF_SIZE_DIVISOR`],
/// but never below the median nearest-neighbour spacing of the sampled splats (each measured
/// within its own leaf, so the value is the same however the scene is split into regions).
fn default_radius(spacing: &mut [f64], deepest_edge: f64, root_size: f64) -> f64 {
    let from_tiles = deepest_edge / LEAF_SIZE_DIVISOR;
    let nn = if spacing.is_empty() {
        0.0
    } else {
        let mid = spacing.len() / 2;
        *spacing.select_nth_unstable_by(mid, |a, b| a.total_cmp(b)).1
    };
    let r = from_tiles.max(nn);
    if r.is_finite() && r > 0.0 {
        r
    } else {
        1e-6_f64.max(root_size * 1e-6)
    }
}
