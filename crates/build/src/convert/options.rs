//! What a conversion takes and gives back: its options (non-finite policy, subdivision scheme,
//! budgets, LOD and variant settings), its report, and the errors that stop it.

use std::path::{Path, PathBuf};

use crate::lod::LodOptions;
use crate::output::OutputError;
use crate::variants::{ContentError, ContentFacts, VariantOptions};
use splat2tiles_core::frame::UpAxis;
use splat2tiles_core::frame::geo::Geodetic;
use splat2tiles_io::ReadError;
use splat2tiles_tiles::layers::build::LayerError;
use splat2tiles_tiles::tiling::TileKey;

/// What to do with splats holding NaN or infinite values.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NonFinitePolicy {
    /// Drop them and report how many were dropped.
    Drop,
    /// Refuse the input, naming the first bad splat.
    Fail,
}

splat2tiles_core::named!(NonFinitePolicy {
    Drop => ("drop", "Drop them and report how many were dropped."),
    Fail => ("fail", "Refuse the input, naming the first bad splat."),
});

/// Which subdivision to use for a local (not georeferenced) scene.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SchemeChoice {
    /// Quadtree when the scene is flat (vertical extent < 1/4 of the horizontal), else octree.
    Auto,
    /// Always an octree.
    Octree,
    /// Always a quadtree.
    Quadtree,
}

splat2tiles_core::named!(SchemeChoice {
    Auto => ("auto", "Quadtree when the scene is flat (vertical extent < 1/4 of the horizontal), else octree."),
    Octree => ("octree", "Always an octree."),
    Quadtree => ("quadtree", "Always a quadtree."),
});

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
    /// Where progress goes (none: nowhere).
    pub progress: crate::progress::ProgressSink,
    /// Level of detail: parents by weighted clustering of their children.
    pub lod: LodOptions,
    /// Quality variants per tile, target profile, utility measurement.
    pub variants: VariantOptions,
    /// Memory budget in bytes (`--memory-limit`): the working set of every stage is sized to
    /// it (regions spilled to the staging folder when the scene does not fit); inputs only the
    /// whole-file readers take (ascii PLY, SPZ) are refused when estimated above it.
    pub memory_limit: u64,
    /// View-optimised leaf levels (`--partition views:DIR`, SGSS sec. 3.1): tiles the tree DP
    /// splits are split even under `max_splats_per_tile` (`partition::plan`).
    pub partition: Option<crate::partition::plan::PartitionRequest>,
    /// Layered content (`--layers`, `spec/layered-content.md`): ADD refinement, every content
    /// a layer over its ancestors' with its parent's opacity deltas (needs LOD, Best only).
    pub layers: bool,
}

impl ConvertOptions {
    /// Levels per subtree file for a tree of `levels` levels: `subtree_levels`, or 6 for a
    /// quadtree and 4 for an octree, within 1..=`levels`.
    pub fn subtree_levels_for(
        &self,
        scheme: splat2tiles_tiles::tiling::Scheme,
        levels: u32,
    ) -> u32 {
        self.subtree_levels
            .unwrap_or(match scheme {
                splat2tiles_tiles::tiling::Scheme::Quadtree => 6,
                splat2tiles_tiles::tiling::Scheme::Octree => 4,
            })
            .clamp(1, levels.max(1))
    }
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
            progress: None,
            lod: LodOptions::default(),
            variants: VariantOptions::default(),
            memory_limit: splat2tiles_io::limits::MemoryLimit::machine_default().bytes(),
            partition: None,
            layers: false,
        }
    }
}

/// What a conversion did.
#[derive(Debug, Clone, Default)]
pub struct ConvertReport {
    /// The view-optimised plan (`--partition`), when asked for.
    pub partition: Option<crate::partition::plan::SplitPlan>,
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
    /// Regions (subtrees built as units) the scene was split into (1: in memory).
    pub regions: usize,
    /// Bytes written to spill files in the staging folder (0: in memory).
    pub spill_bytes: u64,
    /// Wall-clock seconds at the end of each stage since the conversion started (frame, spill,
    /// leaves, parents, top, tileset).
    pub stage_seconds: Vec<(&'static str, f64)>,
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
    /// More splats share one cell at the deepest level than the memory limit lets one tile hold.
    #[error(
        "{file}: {count} splats share one cell at the deepest tree level ({level}); a tile holding \
         them all needs more than the memory limit ({limit}); raise --memory-limit or --max-depth"
    )]
    TooDense {
        /// Input file.
        file: String,
        /// Splats in the cell.
        count: u64,
        /// The deepest level.
        level: u32,
        /// The memory limit, human-readable.
        limit: String,
    },
    /// No splat is left to tile.
    /// `--partition` could not be planned.
    #[error("{file}: --partition: {why}")]
    Partition {
        /// Input file.
        file: String,
        /// Why.
        why: String,
    },
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
    /// `--layers`: the contents could not be layered.
    #[error(transparent)]
    Layers(#[from] splat2tiles_tiles::layers::build::LayerError),
    /// `import-lapisgs`: the level files do not form LapisGS levels.
    #[error("{file}: {why}")]
    Lapis {
        /// The level file at fault.
        file: String,
        /// Why (naming the splat and its byte offset where one is at fault).
        why: String,
    },
}

impl ConvertError {
    /// Whether an interrupt (Ctrl-C, SIGTERM) stopped the run.
    pub fn is_interrupt(&self) -> bool {
        matches!(self, ConvertError::Out(OutputError::Interrupted))
    }

    /// Names the user's output path instead of the staging folder in file errors.
    pub(super) fn relocated(self, staging: &Path, output: &Path) -> Self {
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
            ConvertError::Layers(LayerError::Io { path, source }) => {
                ConvertError::Layers(LayerError::Io {
                    path: swap(path),
                    source,
                })
            }
            ConvertError::Layers(LayerError::Glb { path, source }) => {
                ConvertError::Layers(LayerError::Glb {
                    path: swap(path),
                    source,
                })
            }
            e => e,
        }
    }
}
