//! The conversion pipeline: read a scene, move it into the tileset frame, partition it, write one
//! glb per leaf, the subtrees and `tileset.json` into a temporary folder, then rename it into place.

use crate::frame::geo::{Geodetic, mercator_unit};
use crate::frame::mercator::{MAX_ZOOM, MercatorKey};
use crate::frame::region::RegionBuilder;
use crate::frame::{UpAxis, node_matrix, source_to_tileset};
use crate::io::{self, ReadError, Scene};
use crate::lod::{LodOptions, ParentTile, build_parents, default_leaf_radius};
use crate::output::{OutputError, Staging};
use crate::splat::Splats;
use crate::splat::importance::sort_indices_by_importance;
use crate::tiling::extent::reaches;
use crate::tiling::levels::{keeps_content, monotone_errors};
use crate::tiling::subtree::{self, Column, SubtreeData, Table};
use crate::tiling::tileset::{self, Asset, BoundingVolume, Content, ImplicitTiling, Tile, Tileset};
use crate::tiling::{Partition, Scheme, TileKey, partition};
use crate::variants::{self, ContentError, ContentFacts, VariantOptions, write_tile_contents};
use glam::{DMat3, DVec3};
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;
use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// What to do with splats holding NaN or infinite values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum NonFinitePolicy {
    /// Drop them and report how many were dropped.
    Drop,
    /// Refuse the input, naming the first bad splat.
    Fail,
}

/// Which subdivision to use for a local (not georeferenced) scene.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum SchemeChoice {
    /// Quadtree when the scene is flat (vertical extent < 1/4 of the horizontal), else octree.
    Auto,
    /// Always an octree.
    Octree,
    /// Always a quadtree.
    Quadtree,
}

/// Settings of one conversion.
#[derive(Debug, Clone)]
pub struct ConvertOptions {
    /// Most splats a leaf tile may hold (unless coincident splats cannot be separated).
    pub max_splats_per_tile: usize,
    /// Deepest level of the tree (local scenes) or deepest Web-Mercator zoom (georeferenced).
    pub max_depth: Option<u32>,
    /// Up axis of the input; `None` takes the format's usual one.
    pub up_axis: Option<UpAxis>,
    /// Turn about the up axis, degrees.
    pub heading_deg: f64,
    /// Georeference the scene at this place (ENU frame, Web-Mercator quadtree).
    pub origin: Option<Geodetic>,
    /// Subdivision of local scenes.
    pub scheme: SchemeChoice,
    /// NaN/Inf handling.
    pub non_finite: NonFinitePolicy,
    /// Levels per subtree file; `None` picks 6 (quadtree) or 4 (octree).
    pub subtree_levels: Option<u32>,
    /// Keep each leaf's splat indices in the report (for tests and tools).
    pub keep_index_map: bool,
    /// Draw progress bars (they hide themselves when stderr is not a terminal).
    pub progress: bool,
    /// Level of detail: parents by weighted clustering of their children.
    pub lod: LodOptions,
    /// Quality variants per tile, target profile, utility measurement.
    pub variants: VariantOptions,
    /// Memory budget in bytes (`--memory-limit`): inputs whose in-memory conversion is
    /// estimated above it are refused before anything is allocated.
    pub memory_limit: u64,
}

impl Default for ConvertOptions {
    fn default() -> Self {
        ConvertOptions {
            max_splats_per_tile: 32_768,
            max_depth: None,
            up_axis: None,
            heading_deg: 0.0,
            origin: None,
            scheme: SchemeChoice::Auto,
            non_finite: NonFinitePolicy::Drop,
            subtree_levels: None,
            keep_index_map: false,
            progress: false,
            lod: LodOptions::default(),
            variants: VariantOptions::default(),
            memory_limit: crate::limits::MemoryLimit::machine_default().bytes(),
        }
    }
}

/// What a conversion did.
#[derive(Debug, Clone, Default)]
pub struct ConvertReport {
    /// Splats read.
    pub splats_in: usize,
    /// Splats written over all leaf tiles.
    pub splats_out: usize,
    /// Splats dropped for NaN/Inf values.
    pub dropped_non_finite: usize,
    /// Zero or non-finite quaternions replaced by the identity while reading.
    pub repaired_rotations: usize,
    /// Splats whose finite log-scales overflow `exp` (counted among the non-finite ones).
    pub overflowed_scales: usize,
    /// SH degree of the output.
    pub sh_degree: u8,
    /// Up axis used.
    pub up_axis: String,
    /// "QUADTREE" or "OCTREE".
    pub scheme: String,
    /// Tiles in the tree (with or without content).
    pub tiles: usize,
    /// Tiles with content.
    pub content_tiles: usize,
    /// `availableLevels`.
    pub levels: u32,
    /// Subtree files written.
    pub subtrees: usize,
    /// Bytes of all files written.
    pub bytes: u64,
    /// Wall-clock seconds.
    pub seconds: f64,
    /// Per leaf: key and the indices of its splats in the (finite) input, in tile order.
    pub leaves: Vec<(TileKey, Vec<usize>)>,
    /// Leaf clustering radius `r` used by the LOD build (0 without LOD).
    pub lod_radius: f64,
    /// Splats over all parent (LOD) tiles.
    pub parent_splats: usize,
    /// Wall-clock seconds of the LOD build (clustering and writing parents).
    pub lod_seconds: f64,
    /// Per content tile: what its variants cost and are worth.
    pub contents: Vec<(TileKey, ContentFacts)>,
    /// Notes about the output folder (leftovers of interrupted runs cleaned, an earlier result
    /// that could not be deleted); the command line prints them on stderr.
    pub notes: Vec<String>,
}

/// Why a conversion failed. Nothing is left at the output path when it does.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ConvertError {
    /// The input could not be read.
    #[error(transparent)]
    Read(#[from] ReadError),
    /// A splat holds NaN/Inf and the policy is to fail.
    #[error(
        "{file}: {location}: splat {index} has a NaN or infinite value{note} (use --non-finite drop to skip such splats)"
    )]
    NonFinite {
        /// Input file.
        file: String,
        /// Where in the file.
        location: String,
        /// Splat index.
        index: usize,
        /// Extra explanation (finite log-scales that overflow).
        note: String,
    },
    /// No splat is left to tile.
    #[error("{file}: no splats to convert{why}")]
    Empty {
        /// Input file.
        file: String,
        /// Extra explanation.
        why: String,
    },
    /// The output cannot be written.
    #[error("{path}: {what}: {source}")]
    Io {
        /// Path involved.
        path: PathBuf,
        /// What was being done.
        what: &'static str,
        /// The OS error.
        source: std::io::Error,
    },
    /// A tile's contents could not be written.
    #[error(transparent)]
    Content(#[from] ContentError),
    /// The output path is not something we may replace.
    #[error("{path}: {why}")]
    Output {
        /// Path involved.
        path: PathBuf,
        /// Why not.
        why: String,
    },
    /// The output folder is refused, busy, unwritable, or the run was interrupted.
    #[error(transparent)]
    Out(#[from] OutputError),
}

impl ConvertError {
    /// Whether an interrupt (Ctrl-C, SIGTERM) stopped the run.
    pub fn is_interrupt(&self) -> bool {
        matches!(self, ConvertError::Out(OutputError::Interrupted))
    }

    /// Names the user's output path instead of the staging folder in file errors.
    fn relocated(self, staging: &Path, output: &Path) -> Self {
        let swap = |p: PathBuf| match p.strip_prefix(staging) {
            Ok(rel) => output.join(rel),
            Err(_) => p,
        };
        match self {
            ConvertError::Io { path, what, source } => ConvertError::Io {
                path: swap(path),
                what,
                source,
            },
            ConvertError::Content(ContentError::Io { path, source }) => {
                ConvertError::Content(ContentError::Io {
                    path: swap(path),
                    source,
                })
            }
            e => e,
        }
    }
}

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

/// Reads `input` and writes its tileset to the folder `output` (atomically).
pub fn convert(
    input: &Path,
    output: &Path,
    opts: &ConvertOptions,
) -> Result<ConvertReport, ConvertError> {
    let start = Instant::now();
    let spinner = spinner(opts.progress, format!("reading {}", input.display()));
    let scene = io::read_path_limited(input, opts.memory_limit)?;
    spinner.finish_and_clear();
    let mut report = convert_scene(scene, &input.display().to_string(), output, opts)?;
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
    let start = Instant::now();
    let up = opts.up_axis.unwrap_or_else(|| {
        scene
            .format
            .default_up_axis()
            .parse()
            .unwrap_or(UpAxis::NegY)
    });
    let mut splats = scene.splats;
    let mut report = ConvertReport {
        splats_in: splats.len(),
        repaired_rotations: scene.repaired_rotations,
        overflowed_scales: scene.overflowed_scales,
        sh_degree: splats.sh_degree,
        up_axis: up.to_string(),
        ..Default::default()
    };
    if let Some(i) = splats.first_non_finite() {
        match opts.non_finite {
            NonFinitePolicy::Fail => {
                let note = if scene.overflowed_scales > 0 {
                    format!(
                        " ({} splats have finite log-scales too large for exp(), e.g. above 88.7: \
                         their scale overflows)",
                        scene.overflowed_scales
                    )
                } else {
                    String::new()
                };
                return Err(ConvertError::NonFinite {
                    file: name.to_string(),
                    location: scene.locator.describe(i),
                    index: i,
                    note,
                });
            }
            NonFinitePolicy::Drop => report.dropped_non_finite = splats.drop_non_finite(),
        }
    }
    if splats.is_empty() {
        let why = if report.dropped_non_finite > 0 && scene.overflowed_scales > 0 {
            format!(
                " (all {} splats had NaN or infinite values; {} of them are finite in the file but \
                 have log-scales too large for exp(), e.g. above 88.7, so their scale overflows)",
                report.dropped_non_finite, scene.overflowed_scales
            )
        } else if report.dropped_non_finite > 0 {
            format!(
                " (all {} splats had NaN or infinite values)",
                report.dropped_non_finite
            )
        } else {
            " (the file holds zero splats)".to_string()
        };
        return Err(ConvertError::Empty {
            file: name.to_string(),
            why,
        });
    }

    let staging = Staging::prepare(output)?;
    let dir = staging.path().to_path_buf();
    let relocate = |e: ConvertError| e.relocated(&dir, output);
    let a = source_to_tileset(up, opts.heading_deg);
    let layout = Layout::new(&splats, a, opts);
    let part = partition(
        &layout.unit,
        layout.scheme,
        opts.max_splats_per_tile,
        layout.max_depth,
    );
    report.scheme = layout.scheme.as_str().to_string();
    report.levels = part.levels;
    let mut part = part;
    // Importance order inside every leaf (SGSS eq. 7); the index map follows it.
    part.leaves
        .par_iter_mut()
        .for_each(|l| sort_indices_by_importance(&splats, &mut l.indices));

    let tiles = write_leaves(&splats, &layout, &part, &dir, opts).map_err(relocate)?;
    report.content_tiles = tiles.len();
    report.contents = tiles
        .iter()
        .filter_map(|(k, t)| t.facts.clone().map(|f| (*k, f)))
        .collect();
    report.contents.sort_by_key(|(k, _)| *k);
    report.splats_out = tiles.values().map(|t| t.splat_count as usize).sum();
    report.bytes = tiles.values().map(|t| t.bytes).sum();
    let mut tree = build_tree(tiles);
    if opts.lod.enabled {
        let t0 = Instant::now();
        let r = opts.lod.radius.unwrap_or_else(|| {
            default_leaf_radius(
                &splats.positions,
                layout.tile_edge(0),
                part.levels.saturating_sub(1),
            )
        });
        let diagonals: HashMap<TileKey, f64> = tree
            .iter()
            .map(|(k, t)| (*k, (t.hi - t.lo).length()))
            .collect();
        let parents =
            write_parents(&splats, &layout, &part, r, &diagonals, opts, &dir).map_err(relocate)?;
        for (key, p) in parents {
            // Parents that are no real level of detail keep no content (tiling::levels).
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
        report.lod_radius = r;
        report.lod_seconds = t0.elapsed().as_secs_f64();
    }
    finish_tree(&mut tree);
    report.tiles = tree.len();

    let subtree_levels = opts
        .subtree_levels
        .unwrap_or(match layout.scheme {
            Scheme::Quadtree => 6,
            Scheme::Octree => 4,
        })
        .clamp(1, part.levels.max(1));
    let (subtrees, subtree_bytes) =
        write_subtrees(&tree, layout.scheme, subtree_levels, &dir).map_err(relocate)?;
    report.subtrees = subtrees;
    report.bytes += subtree_bytes;

    let tileset = tileset_json(
        &tree,
        &layout,
        &part,
        subtree_levels,
        &report,
        name,
        &opts.variants,
    );
    let json = serde_json::to_vec_pretty(&tileset).expect("tileset serialises");
    let path = dir.join("tileset.json");
    std::fs::write(&path, &json)
        .map_err(io_err(&path, "writing"))
        .map_err(relocate)?;
    report.bytes += json.len() as u64;

    report.notes = staging.commit()?;
    if opts.keep_index_map {
        report.leaves = part
            .leaves
            .into_iter()
            .map(|l| (l.key, l.indices))
            .collect();
    }
    report.seconds = start.elapsed().as_secs_f64();
    Ok(report)
}

/// Where the tree lives: the tileset frame, the root volume and each splat's unit coordinates.
struct Layout {
    /// Rotation source -> tileset frame.
    a: DMat3,
    /// Splat centres in the tileset frame.
    pos_t: Vec<DVec3>,
    /// Centres in unit coordinates of the root volume.
    unit: Vec<[f64; 3]>,
    scheme: Scheme,
    max_depth: u32,
    /// Root bounding volume.
    root_volume: BoundingVolume,
    /// Root transform (georeferenced only).
    transform: Option<[f64; 16]>,
    /// Web-Mercator tile of the implicit root (georeferenced only).
    mercator_root: Option<MercatorKey>,
}

impl Layout {
    /// Edge length of a tile at `level`: the root box's largest (horizontal for quadtrees) edge
    /// halved per level; for georeferenced scenes the Web-Mercator tile width at the origin.
    fn tile_edge(&self, level: u32) -> f64 {
        let root = match (self.mercator_root, &self.root_volume.box_) {
            (Some(m), _) => {
                let [_, south, _, north] = m.bounds_deg();
                let lat = (0.5 * (south + north)).to_radians();
                2.0 * std::f64::consts::PI * 6_378_137.0 * lat.cos() / 2f64.powi(m.zoom as i32)
            }
            (None, Some(b)) => {
                let z = if self.scheme == Scheme::Octree {
                    b[11]
                } else {
                    0.0
                };
                2.0 * b[3].max(b[7]).max(z)
            }
            (None, None) => 1.0,
        };
        root / 2f64.powi(level as i32)
    }

    fn new(splats: &Splats, a: DMat3, opts: &ConvertOptions) -> Layout {
        let pos_t: Vec<DVec3> = splats
            .positions
            .par_iter()
            .map(|p| a * DVec3::from_array(*p))
            .collect();
        let (lo, hi) = bounds(&pos_t);
        match opts.origin {
            Some(origin) => {
                // Georeferenced: ENU at the origin; the implicit root is the smallest
                // Web-Mercator tile holding the scene (spec/georeferencing.md), its volume the
                // tight region of the splats' visible reach.
                let enu = origin.enu_to_ecef();
                let geo: Vec<Geodetic> = pos_t
                    .par_iter()
                    .map(|p| Geodetic::from_ecef(enu.transform_point3(*p)))
                    .collect();
                let merc: Vec<(f64, f64)> = geo
                    .par_iter()
                    .map(|g| mercator_unit(g.lon, g.lat))
                    .collect();
                let max_zoom = opts.max_depth.unwrap_or(MAX_ZOOM).min(MAX_ZOOM);
                let root = MercatorKey::containing(&merc, max_zoom);
                let unit = merc
                    .par_iter()
                    .map(|&(x, y)| {
                        let [u, v] = root.local_unit(x, y);
                        [u, v, 0.5]
                    })
                    .collect();
                let reach = reaches(splats, a);
                let region = geo
                    .par_iter()
                    .zip(reach.par_iter())
                    .fold(RegionBuilder::default, |mut b, (g, e)| {
                        b.add(*g, e.length());
                        b
                    })
                    .reduce(RegionBuilder::default, RegionBuilder::merge)
                    .finish()
                    .expect("a scene has splats");
                Layout {
                    a,
                    pos_t,
                    unit,
                    scheme: Scheme::Quadtree,
                    max_depth: max_zoom - root.zoom,
                    root_volume: BoundingVolume {
                        region: Some(region.to_vec()),
                        ..Default::default()
                    },
                    transform: Some(enu.to_cols_array()),
                    mercator_root: Some(root),
                }
            }
            None => {
                let ext = hi - lo;
                let horizontal = ext.x.max(ext.y);
                let scheme = match opts.scheme {
                    SchemeChoice::Octree => Scheme::Octree,
                    SchemeChoice::Quadtree => Scheme::Quadtree,
                    SchemeChoice::Auto if ext.z < 0.25 * horizontal => Scheme::Quadtree,
                    SchemeChoice::Auto => Scheme::Octree,
                };
                let (centre, half) = padded_box(lo, hi);
                let min = centre - half;
                let size = half * 2.0;
                let unit = pos_t
                    .par_iter()
                    .map(|p| {
                        let u = (*p - min) / size;
                        [u.x, u.y, if scheme == Scheme::Octree { u.z } else { 0.5 }]
                    })
                    .collect();
                Layout {
                    a,
                    pos_t,
                    unit,
                    scheme,
                    max_depth: opts.max_depth.unwrap_or(16).min(scheme.max_depth()),
                    root_volume: BoundingVolume {
                        box_: Some(box_array(centre, half)),
                        ..Default::default()
                    },
                    transform: None,
                    mercator_root: None,
                }
            }
        }
    }
}

fn bounds(p: &[DVec3]) -> (DVec3, DVec3) {
    p.iter().fold(
        (DVec3::splat(f64::MAX), DVec3::splat(f64::MIN)),
        |(lo, hi), q| (lo.min(*q), hi.max(*q)),
    )
}

/// Centre and half extents of a box, with flat axes padded so the box is never degenerate.
fn padded_box(lo: DVec3, hi: DVec3) -> (DVec3, DVec3) {
    let centre = (lo + hi) * 0.5;
    let half = (hi - lo) * 0.5;
    let floor = (half.max_element() * 1e-3).max(1e-6 * (1.0 + centre.abs().max_element()));
    (centre, half.max(DVec3::splat(floor)))
}

fn box_array(centre: DVec3, half: DVec3) -> Vec<f64> {
    vec![
        centre.x, centre.y, centre.z, half.x, 0.0, 0.0, 0.0, half.y, 0.0, 0.0, 0.0, half.z,
    ]
}

/// A tile of the tree: its tight box in the tileset frame and, for leaves, its content facts.
#[derive(Debug, Clone)]
struct TreeTile {
    lo: DVec3,
    hi: DVec3,
    splat_count: u32,
    bytes: u64,
    has_content: bool,
    is_leaf: bool,
    /// Geometric error of a parent with content (its clustering radius).
    error: f64,
    /// Per-variant facts of the content, when the tile has content.
    facts: Option<ContentFacts>,
}

/// Writes one tile's contents centred on its splats: `pts` are their centres in the tileset
/// frame; returns the tight box there and what was written.
fn write_centred(
    layout: &Layout,
    scheme: Scheme,
    key: TileKey,
    tile: &Splats,
    pts: &[DVec3],
    dir: &Path,
    opts: &ConvertOptions,
) -> Result<(DVec3, DVec3, ContentFacts), ConvertError> {
    check_interrupt()?;
    let (lo, hi) = bounds(pts);
    let centre_s = layout.a.transpose() * ((lo + hi) * 0.5);
    let facts = write_tile_contents(
        dir,
        scheme,
        key,
        tile,
        centre_s.to_array(),
        node_matrix(layout.a, centre_s),
        &opts.variants,
    )?;
    Ok((lo, hi, facts))
}

fn write_leaves(
    splats: &Splats,
    layout: &Layout,
    part: &Partition,
    dir: &Path,
    opts: &ConvertOptions,
) -> Result<HashMap<TileKey, TreeTile>, ConvertError> {
    let bar = bar(opts.progress, part.leaves.len() as u64, "writing tiles");
    let tiles: Result<Vec<(TileKey, TreeTile)>, ConvertError> = part
        .leaves
        .par_iter()
        .map(|leaf| {
            let tile = splats.select(&leaf.indices);
            let pts: Vec<DVec3> = leaf.indices.iter().map(|&i| layout.pos_t[i]).collect();
            let (lo, hi, facts) =
                write_centred(layout, part.scheme, leaf.key, &tile, &pts, dir, opts)?;
            bar.inc(1);
            Ok((
                leaf.key,
                TreeTile {
                    lo,
                    hi,
                    splat_count: facts.splat_count,
                    bytes: facts.bytes,
                    has_content: true,
                    is_leaf: true,
                    error: 0.0,
                    facts: Some(facts),
                },
            ))
        })
        .collect();
    bar.finish_and_clear();
    Ok(tiles?.into_iter().collect())
}

/// Adds every ancestor of the leaves, with boxes that enclose their descendants.
fn build_tree(leaves: HashMap<TileKey, TreeTile>) -> BTreeMap<TileKey, TreeTile> {
    let mut tree: BTreeMap<TileKey, TreeTile> = leaves.into_iter().collect();
    let keys: Vec<TileKey> = tree.keys().copied().collect();
    for key in keys {
        let (lo, hi) = (tree[&key].lo, tree[&key].hi);
        let mut k = key;
        while let Some(p) = k.parent() {
            let t = tree.entry(p).or_insert(TreeTile {
                lo,
                hi,
                splat_count: 0,
                bytes: 0,
                has_content: false,
                is_leaf: false,
                error: 0.0,
                facts: None,
            });
            t.lo = t.lo.min(lo);
            t.hi = t.hi.max(hi);
            k = p;
        }
    }
    tree
}

/// A tile's own geometric error: 0 for leaves (full detail); for LOD parents, the clustering
/// radius they were built with (no merged splat moved further than that from its members'
/// reach); for tiles without content, the diagonal of their box (rendering nothing misses
/// everything below).
fn own_error(t: &TreeTile) -> f64 {
    if t.is_leaf {
        0.0
    } else if t.has_content {
        t.error.max(1e-9)
    } else {
        (t.hi - t.lo).length().max(1e-6)
    }
}

/// The geometric error written for a tile (its own, raised to its descendants' by
/// [`finish_tree`]).
fn geometric_error(t: &TreeTile) -> f64 {
    t.error
}

/// Last pass over the tree: every box encloses its descendants' and its own content's centres,
/// and errors are the tiles' own raised so they never grow downwards.
fn finish_tree(tree: &mut BTreeMap<TileKey, TreeTile>) {
    let keys: Vec<TileKey> = tree.keys().rev().copied().collect();
    for k in &keys {
        if let Some(p) = k.parent() {
            let (lo, hi) = (tree[k].lo, tree[k].hi);
            if let Some(t) = tree.get_mut(&p) {
                t.lo = t.lo.min(lo);
                t.hi = t.hi.max(hi);
            }
        }
    }
    let mut errors: BTreeMap<TileKey, f64> = tree.iter().map(|(k, t)| (*k, own_error(t))).collect();
    monotone_errors(&mut errors);
    for (k, t) in tree.iter_mut() {
        t.error = errors[k];
    }
}

/// What the tree keeps of a parent tile: its content (facts and the box of its merged centres)
/// when it is a real level of detail, and its clustering radius.
struct WrittenParent {
    content: Option<(ContentFacts, DVec3, DVec3)>,
    error: f64,
}

/// Builds every parent tile by clustering its children's splats (see [`crate::lod`]) and writes
/// each that is a real level of detail ([`keeps_content`] against its box diagonal in
/// `diagonals`) through the same per-tile writer as the leaves (every requested quality
/// variant), centred on its merged splats.
fn write_parents(
    splats: &Splats,
    layout: &Layout,
    part: &Partition,
    r: f64,
    diagonals: &HashMap<TileKey, f64>,
    opts: &ConvertOptions,
    dir: &Path,
) -> Result<BTreeMap<TileKey, WrittenParent>, ConvertError> {
    let index: HashMap<TileKey, &[usize]> = part
        .leaves
        .iter()
        .map(|l| (l.key, l.indices.as_slice()))
        .collect();
    let keys: Vec<TileKey> = part.leaves.iter().map(|l| l.key).collect();
    build_parents(
        &keys,
        splats.sh_degree,
        r,
        opts.max_splats_per_tile,
        opts.lod.merge,
        |k| splats.select(index[&k]),
        |p: &ParentTile| {
            let diagonal = diagonals.get(&p.key).copied().unwrap_or(f64::INFINITY);
            if !keeps_content(p.splats.len(), p.radius, diagonal, opts.max_splats_per_tile) {
                return Ok(WrittenParent {
                    content: None,
                    error: p.radius,
                });
            }
            let pts: Vec<DVec3> = p
                .splats
                .positions
                .iter()
                .map(|q| layout.a * DVec3::from_array(*q))
                .collect();
            let (lo, hi, facts) =
                write_centred(layout, part.scheme, p.key, &p.splats, &pts, dir, opts)?;
            Ok(WrittenParent {
                content: Some((facts, lo, hi)),
                error: p.radius,
            })
        },
    )
}

fn subtree_path(scheme: Scheme, k: TileKey) -> String {
    match scheme {
        Scheme::Octree => format!("subtrees/{}/{}/{}/{}.subtree", k.level, k.x, k.y, k.z),
        Scheme::Quadtree => format!("subtrees/{}/{}/{}.subtree", k.level, k.x, k.y),
    }
}

fn write_subtrees(
    tree: &BTreeMap<TileKey, TreeTile>,
    scheme: Scheme,
    levels: u32,
    dir: &Path,
) -> Result<(usize, u64), ConvertError> {
    let arity = scheme.arity();
    let n_tiles = subtree::tile_count(arity, levels) as usize;
    let n_children = arity.pow(levels) as usize;
    // Group tiles by the root of the subtree holding them.
    let mut groups: BTreeMap<TileKey, Vec<TileKey>> = BTreeMap::new();
    for &k in tree.keys() {
        let root_level = k.level / levels * levels;
        groups.entry(k.ancestor(root_level)).or_default().push(k);
    }
    let mut child_roots: BTreeMap<TileKey, Vec<TileKey>> = BTreeMap::new();
    for &r in groups.keys().filter(|r| r.level >= levels) {
        child_roots
            .entry(r.ancestor(r.level - levels))
            .or_default()
            .push(r);
    }
    let mut files = 0;
    let mut bytes = 0;
    for (root, members) in &groups {
        check_interrupt()?;
        let mut tiles = vec![false; n_tiles];
        let mut contents = vec![false; n_tiles];
        let mut child_subtrees = vec![false; n_children];
        let mut rows: Vec<(u64, TileKey)> = Vec::with_capacity(members.len());
        for &k in members {
            let rl = k.level - root.level;
            let rel = |c: u32, r: u32| c - (r << rl);
            let m = scheme.encode(rel(k.x, root.x), rel(k.y, root.y), rel(k.z, root.z));
            let idx = subtree::tile_index(arity, rl, m);
            tiles[idx as usize] = true;
            contents[idx as usize] = tree[&k].has_content;
            rows.push((idx, k));
        }
        // Child subtrees: the subtree roots one level below this subtree's last level.
        for child in child_roots.get(root).into_iter().flatten() {
            let rel = |c: u32, r: u32| c - (r << levels);
            let m = scheme.encode(
                rel(child.x, root.x),
                rel(child.y, root.y),
                rel(child.z, root.z),
            );
            child_subtrees[m as usize] = true;
        }
        rows.sort_by_key(|(i, _)| *i);
        let boxes: Vec<f64> = rows
            .iter()
            .flat_map(|(_, k)| {
                let t = &tree[k];
                let (c, h) = padded_box(t.lo, t.hi);
                box_array(c, h)
            })
            .collect();
        let errors: Vec<f64> = rows
            .iter()
            .map(|(_, k)| geometric_error(&tree[k]))
            .collect();
        let with_content: Vec<&TreeTile> = rows
            .iter()
            .map(|(_, k)| &tree[k])
            .filter(|t| t.has_content)
            .collect();
        let counts: Vec<u32> = with_content.iter().map(|t| t.splat_count).collect();
        let variant_bytes: Vec<u32> = with_content
            .iter()
            .flat_map(|t| t.facts.as_ref().map_or([0; 4], |f| f.variant_bytes))
            .collect();
        let variant_utility: Vec<f32> = with_content
            .iter()
            .flat_map(|t| t.facts.as_ref().map_or([-1.0; 4], |f| f.variant_utility))
            .collect();
        let data = SubtreeData {
            tiles,
            contents,
            child_subtrees,
            tile_metadata: Some(Table {
                class: tileset::TILE_CLASS.into(),
                count: rows.len() as u64,
                columns: vec![
                    ("boundingBox".into(), Column::F64(boxes)),
                    ("geometricError".into(), Column::F64(errors)),
                ],
            }),
            content_metadata: (!counts.is_empty()).then(|| Table {
                class: tileset::CONTENT_CLASS.into(),
                count: counts.len() as u64,
                columns: vec![
                    ("splatCount".into(), Column::U32(counts)),
                    ("variantBytes".into(), Column::U32(variant_bytes)),
                    ("variantUtility".into(), Column::F32(variant_utility)),
                ],
            }),
        };
        let encoded = subtree::write_subtree(&data);
        let path = dir.join(subtree_path(scheme, *root));
        if let Some(parent) = path.parent() {
            std::fs::create_dir_all(parent).map_err(io_err(parent, "creating folder"))?;
        }
        std::fs::write(&path, &encoded).map_err(io_err(&path, "writing"))?;
        files += 1;
        bytes += encoded.len() as u64;
    }
    Ok((files, bytes))
}

fn tileset_json(
    tree: &BTreeMap<TileKey, TreeTile>,
    layout: &Layout,
    part: &Partition,
    subtree_levels: u32,
    report: &ConvertReport,
    name: &str,
    variant_opts: &VariantOptions,
) -> Tileset {
    let root = &tree[&TileKey::ROOT];
    let root_error = geometric_error(root);
    let scheme = part.scheme;
    let template = |kind: &str, ext: &str| match scheme {
        Scheme::Octree => format!("{kind}/{{level}}/{{x}}/{{y}}/{{z}}.{ext}"),
        Scheme::Quadtree => format!("{kind}/{{level}}/{{x}}/{{y}}.{ext}"),
    };
    let input_name = Path::new(name)
        .file_name()
        .map(|f| f.to_string_lossy().into_owned())
        .unwrap_or_default();
    Tileset {
        asset: Asset {
            version: "1.1".into(),
            generator: Some(format!("splat2tiles {}", env!("CARGO_PKG_VERSION"))),
            tileset_version: None,
        },
        // Never below the root's own error (a georeferenced root is a zoom-0 LOD tile whose
        // clustering radius can exceed the scene's extent).
        geometric_error: (root.hi - root.lo).length().max(root_error).max(1e-6),
        root: Tile {
            bounding_volume: layout.root_volume.clone(),
            geometric_error: root_error,
            refine: Some("REPLACE".into()),
            transform: layout.transform.map(|t| t.to_vec()),
            content: Some(Content {
                uri: variants::uri_template(scheme, variant_opts.profile.default_variant()),
            }),
            implicit_tiling: Some(ImplicitTiling {
                subdivision_scheme: scheme.as_str().into(),
                subtree_levels,
                available_levels: part.levels,
                subtrees: Content {
                    uri: template("subtrees", "subtree"),
                },
            }),
            children: vec![],
        },
        schema: Some(tileset::schema()),
        metadata: Some(tileset::with_mercator_root(
            variants::tileset_metadata(scheme, variant_opts),
            layout.mercator_root,
        )),
        extensions_used: match variant_opts.profile {
            variants::Profile::Cesium => vec!["3DTILES_content_gltf".into()],
            variants::Profile::Default => vec![],
        },
        extensions_required: vec![],
        extensions: match variant_opts.profile {
            variants::Profile::Cesium => Some(variants::cesium_content_gltf()),
            variants::Profile::Default => None,
        },
        extras: Some(serde_json::json!({
            "splat2tiles": {
                "input": input_name,
                "splats": report.splats_out,
                "shDegree": report.sh_degree,
                "upAxis": report.up_axis,
                "georeferenced": layout.transform.is_some(),
            }
        })),
    }
}

fn bar(show: bool, len: u64, msg: &'static str) -> ProgressBar {
    if !show {
        return ProgressBar::hidden();
    }
    let b = ProgressBar::new(len);
    b.set_style(
        ProgressStyle::with_template("{msg:>14} [{bar:40}] {pos}/{len} ({eta})")
            .expect("valid template")
            .progress_chars("=> "),
    );
    b.set_message(msg);
    b
}

fn spinner(show: bool, msg: String) -> ProgressBar {
    if !show {
        return ProgressBar::hidden();
    }
    let s = ProgressBar::new_spinner();
    s.set_message(msg);
    s.enable_steady_tick(std::time::Duration::from_millis(120));
    s
}
