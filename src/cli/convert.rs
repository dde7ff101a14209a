//! `splat2tiles convert`: arguments, their checks, and the human or JSON summary printed at the
//! end of a conversion.

pub mod shard;

use super::named;
use clap::Args;
use splat2tiles_build::convert::{ConvertOptions, NonFinitePolicy, SchemeChoice, convert};
use splat2tiles_build::lod::{LodOptions, MergeRule};
use splat2tiles_core::frame::UpAxis;
use splat2tiles_core::frame::geo::Geodetic;
use splat2tiles_core::named::Named;
use splat2tiles_io::limits::MemoryLimit;
use splat2tiles_tiles::variants::{ALL, Profile, Variant, VariantOptions};
use std::path::PathBuf;

/// Arguments of `convert`.
#[derive(Debug, Args)]
#[command(after_help = "Examples:
  splat2tiles convert scene.ply -o out/
  splat2tiles convert scene.splat -o out/ --max-splats 16384
  splat2tiles convert city.ply -o city/ --origin 2.2945,48.8584,35 --up-axis -y --heading 90
Sharded (README \"Converting on a cluster\"):
  splat2tiles convert city.ply --plan plan.json --parts 4
  splat2tiles convert city.ply --plan plan.json --part 0 --phase samples -o s0   (each part)
  splat2tiles convert city.ply --plan plan.json --part 0 --samples s0 s1 s2 s3 -o p0
  splat2tiles merge plan.json p0 p1 p2 p3 -o city/")]
#[command(override_usage = "splat2tiles convert <INPUT> -o <OUTPUT> [OPTIONS]
       splat2tiles convert <INPUT> --plan <PLAN> [--parts <N> | --part <K> -o <OUTPUT>] [OPTIONS]")]
pub struct ConvertArgs {
    /// Input scene: trainer PLY (binary or ascii), antimatter15 .splat, or Niantic .spz (v2-v4).
    pub input: PathBuf,
    /// Output folder (required, except when writing a --plan): absent, empty, or an earlier
    /// splat2tiles output (replaced only when the new one is complete, and said so); any other
    /// folder is refused, never deleted.
    #[arg(short, long, required_unless_present = "plan")]
    pub output: Option<PathBuf>,
    /// Most splats per leaf tile.
    #[arg(long, default_value_t = 32_768, value_parser = clap::value_parser!(u64).range(1..=16_777_216))]
    pub max_splats: u64,
    /// Deepest tree level (local scenes, default 16) or Web-Mercator zoom (georeferenced, default 30).
    #[arg(long, value_parser = clap::value_parser!(u32).range(0..=30))]
    pub max_depth: Option<u32>,
    #[command(flatten)]
    pub frame: FrameArgs,
    /// What to do with splats holding NaN or infinite values.
    #[arg(long, value_parser = named::<NonFinitePolicy>(), default_value = "drop")]
    pub non_finite: NonFinitePolicy,
    /// Do not build level-of-detail parents (parent tiles stay empty).
    #[arg(long)]
    pub no_lod: bool,
    /// How merged LOD splats get their shape: covariance moment matching or TileSplat's axis cover.
    #[arg(long, value_parser = named::<MergeRule>(), default_value = "moment")]
    pub lod_merge: MergeRule,
    /// Fallback LOD clustering radius in scene units, used only where a parent's input centres
    /// all coincide (parents choose their radius from a target splat count)
    /// [default: 1/16 of the deepest leaf tile's edge, at least the median spacing].
    #[arg(long, value_parser = positive_f64)]
    pub lod_radius: Option<f64>,
    /// Target clients: `default` (content.uri -> Best, lossless float) or `cesium` (content.uri ->
    /// Low, SPZ_2, plus the 3DTILES_content_gltf declaration CesiumJS needs to render splats).
    #[arg(long, value_parser = named::<Profile>(), default_value = "default")]
    pub profile: Profile,
    /// Quality variants to write per tile: comma list of best, high, medium, low, or `all`
    /// [default: the profile's default variant only]. Sizes and utilities go into the metadata.
    #[arg(long, value_delimiter = ',', value_parser = parse_variant)]
    pub variants: Vec<Vec<Variant>>,
    /// Do not render tiles to measure variant utilities (stored as -1).
    #[arg(long)]
    pub no_utility: bool,
    /// Measure variant utilities by rendering every tile (the definition; slow) instead of the
    /// calibrated estimate from per-splat differences (spec/quality-variants.md).
    #[arg(long, conflicts_with = "no_utility")]
    pub utility_renders: bool,
    /// Memory budget, e.g. 512MiB or 2GiB: scenes that do not fit are split into regions spilled
    /// to the staging folder (binary PLY, .splat); ascii PLY and SPZ inputs estimated above it are
    /// refused before anything is allocated [default: half the RAM, at most 4GiB].
    #[arg(long, value_parser = MemoryLimit::parse)]
    pub memory_limit: Option<MemoryLimit>,
    /// View-optimised leaf levels (SGSS sec. 3.1): `views:DIR` reads the train/val `*.csv` camera
    /// traces in DIR (a test-split trace is refused) and splits tiles further where the cost
    /// model (visibility tests + wasted downloads) says so. Needs the scene to fit in memory.
    #[arg(long, conflicts_with = "plan", value_parser = parse_partition)]
    pub partition: Option<PathBuf>,
    /// Tree depth of the basic cuboids of --partition [default: 10 quadtree, 6 octree].
    #[arg(long, requires = "partition", value_parser = clap::value_parser!(u32).range(1..=12))]
    pub partition_depth: Option<u32>,
    /// Distance (scene units) within which a --partition view needs full detail.
    #[arg(long, requires = "partition", default_value_t = 200.0, value_parser = positive_f64)]
    pub partition_range: f64,
    /// Layered content (spec/layered-content.md): ADD refinement, each tile's content a layer
    /// drawn over its ancestors', carrying the opacity deltas that fade its parent's splats.
    #[arg(long, conflicts_with_all = ["plan", "no_lod", "variants"])]
    pub layers: bool,
    /// Print the summary as JSON on stdout.
    #[arg(long)]
    pub json: bool,
    /// No progress bars and no summary.
    #[arg(short, long)]
    pub quiet: bool,
    /// Sharded conversion: the plan file. Alone (with --parts), write the plan; with --part,
    /// build that part of it (its conversion options are the plan's).
    #[arg(long, help_heading = SHARDED)]
    pub plan: Option<PathBuf>,
    #[command(flatten, next_help_heading = SHARDED)]
    pub shard: shard::ShardArgs,
}

/// The help heading of the options of a sharded conversion (listed after the everyday ones).
const SHARDED: &str = "Sharded conversion (README \"Converting on a cluster\")";

/// The scene's frame and tiling: options shared by `convert` and `import-lapisgs`.
#[derive(Debug, Args)]
pub struct FrameArgs {
    /// Which input axis points up: +x, -x, +y, -y, +z, -z [default: -y for .ply/.splat, +y for .spz].
    #[arg(long, allow_hyphen_values = true)]
    pub up_axis: Option<UpAxis>,
    /// Turn the scene about its up axis by this many degrees (counter-clockwise from above).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub heading: f64,
    /// Georeference the scene: lon,lat or lon,lat,height (degrees, metres) of its origin. Tiles
    /// then form a Web-Mercator quadtree and the root carries an ECEF transform.
    #[arg(long, value_parser = Geodetic::parse, allow_hyphen_values = true)]
    pub origin: Option<Geodetic>,
    /// Subdivision of local scenes.
    #[arg(long, value_parser = named::<SchemeChoice>(), default_value = "auto")]
    pub scheme: SchemeChoice,
    /// Levels per subtree file [default: 6 for quadtrees, 4 for octrees].
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=16))]
    pub subtree_levels: Option<u32>,
}

impl FrameArgs {
    /// Why these options cannot be used (a heading that is not a finite number), if so.
    pub fn check(&self) -> Result<(), &'static str> {
        if self.heading.is_finite() {
            Ok(())
        } else {
            Err("--heading must be a finite number of degrees")
        }
    }

    /// `opts` with these options set.
    pub fn apply(&self, opts: ConvertOptions) -> ConvertOptions {
        ConvertOptions {
            up_axis: self.up_axis,
            heading_deg: self.heading,
            origin: self.origin,
            scheme: self.scheme,
            subtree_levels: self.subtree_levels,
            ..opts
        }
    }
}

/// The conversion options the arguments ask for.
fn options(args: &ConvertArgs) -> ConvertOptions {
    args.frame.apply(ConvertOptions {
        max_splats_per_tile: args.max_splats as usize,
        max_depth: args.max_depth,
        non_finite: args.non_finite,
        keep_index_map: false,
        progress: super::progress::bars(args.quiet),
        lod: LodOptions {
            enabled: !args.no_lod,
            merge: args.lod_merge,
            radius: args.lod_radius,
        },
        variants: VariantOptions {
            profile: args.profile,
            variants: args.variants.iter().flatten().copied().collect(),
            measure_utility: !args.no_utility,
            utility_renders: args.utility_renders,
        },
        memory_limit: args
            .memory_limit
            .unwrap_or_else(MemoryLimit::machine_default)
            .bytes(),
        partition: None,
        layers: args.layers,
        ..ConvertOptions::default()
    })
}

/// `--partition views:DIR`: the trace folder.
fn parse_partition(s: &str) -> Result<PathBuf, String> {
    s.strip_prefix("views:")
        .filter(|d| !d.is_empty())
        .map(PathBuf::from)
        .ok_or_else(|| format!("'{s}': expected views:DIR (a folder of camera traces)"))
}

/// Runs `convert`; returns the process exit code.
pub fn run(args: ConvertArgs) -> i32 {
    if let Err(why) = args.frame.check() {
        eprintln!("splat2tiles: {why}");
        return super::EXIT_FAILURE;
    }
    let mut opts = options(&args);
    if let Some(dir) = &args.partition {
        match splat2tiles_build::partition::plan::load_trace_dir(dir) {
            Ok(views) => {
                opts.partition = Some(splat2tiles_build::partition::plan::PartitionRequest {
                    views,
                    depth: args.partition_depth,
                    range_m: args.partition_range,
                    every_s: 1.0,
                })
            }
            Err(e) => {
                eprintln!("splat2tiles: --partition: {e}");
                return super::EXIT_FAILURE;
            }
        }
    }
    if let Some(plan) = &args.plan {
        return shard::run(&args, plan, &opts);
    }
    let Some(output) = &args.output else {
        eprintln!("splat2tiles: --output is required");
        return super::EXIT_FAILURE;
    };
    crate::cli::install_interrupt_handler();
    match convert(&args.input, output, &opts) {
        Ok(r) => {
            for note in &r.notes {
                eprintln!("splat2tiles: {note}");
            }
            if args.json {
                let v = serde_json::json!({
                    "input": args.input, "output": args.output,
                    "splatsIn": r.splats_in, "splatsOut": r.splats_out,
                    "droppedNonFinite": r.dropped_non_finite,
                    "repairedRotations": r.repaired_rotations,
                    "overflowedScales": r.overflowed_scales,
                    "shDegree": r.sh_degree, "upAxis": r.up_axis, "scheme": r.scheme,
                    "tiles": r.tiles, "contentTiles": r.content_tiles, "levels": r.levels,
                    "subtrees": r.subtrees, "bytes": r.bytes, "seconds": r.seconds,
                    "parentSplats": r.parent_splats, "lodRadius": r.lod_radius,
                    "lodSeconds": r.lod_seconds,
                    "regions": r.regions, "spillBytes": r.spill_bytes,
                    "stageSeconds": r.stage_seconds.iter()
                        .map(|(k, v)| (k.to_string(), serde_json::json!(v)))
                        .collect::<serde_json::Map<_, _>>(),
                    "variants": variant_summary(&r),
                    "peakRssMiB": peak_rss_mib(),
                });
                outln!("{v}");
            } else if !args.quiet {
                let tileset = output.join("tileset.json");
                outln!(
                    "converted {}: {} splats in, {} out (SH degree {}, up axis {})",
                    args.input.display(),
                    r.splats_in,
                    r.splats_out,
                    r.sh_degree,
                    r.up_axis
                );
                if r.dropped_non_finite > 0 {
                    outln!(
                        "  dropped {} splats with NaN or infinite values",
                        r.dropped_non_finite
                    );
                }
                if r.overflowed_scales > 0 {
                    outln!(
                        "  ({} of them are finite in the file, but their log-scales are too large for exp())",
                        r.overflowed_scales
                    );
                }
                if r.repaired_rotations > 0 {
                    outln!(
                        "  replaced {} zero quaternions by the identity",
                        r.repaired_rotations
                    );
                }
                outln!(
                    "  {} {} tiles ({} with content) over {} levels, {} subtree files, {:.2} MB, {:.2} s",
                    r.tiles,
                    r.scheme.to_lowercase(),
                    r.content_tiles,
                    r.levels,
                    r.subtrees,
                    r.bytes as f64 / 1e6,
                    r.seconds
                );
                if let Some(p) = &r.partition {
                    outln!(
                        "  partition: {} units from {} views (objective {:.4}, basic cuboids {:.4})",
                        p.units,
                        p.views,
                        p.objective,
                        p.basic_objective
                    );
                }
                if r.parent_splats > 0 {
                    outln!(
                        "  LOD: {} splats in parent tiles (leaf radius {:.4}, {:.2} s)",
                        r.parent_splats,
                        r.lod_radius,
                        r.lod_seconds
                    );
                }
                if let Some(v) = variant_summary(&r).as_object().filter(|v| v.len() > 1) {
                    for (name, row) in v {
                        outln!(
                            "  variant {name:<6}: {:7.2} B/splat, utility mean {} worst {}",
                            row["bytesPerSplat"].as_f64().unwrap_or(0.0),
                            fmt_utility(&row["meanUtility"]),
                            fmt_utility(&row["worstUtility"])
                        );
                    }
                }
                outln!("  tileset: {}", tileset.display());
                let me = super::program();
                outln!(
                    "  look at it: {me} view {}   (or: {me} render {} --auto-view 0 -o view.png)",
                    output.display(),
                    tileset.display()
                );
            }
            0
        }
        Err(e) if e.is_interrupt() => {
            eprintln!("splat2tiles: interrupted; no output written");
            130
        }
        Err(e) => {
            eprintln!("splat2tiles: {e}");
            super::EXIT_FAILURE
        }
    }
}

/// Per variant: tiles, bytes, bytes per splat, mean and worst utility over the written tiles.
fn variant_summary(r: &splat2tiles_build::convert::ConvertReport) -> serde_json::Value {
    let mut out = serde_json::Map::new();
    for v in ALL {
        let i = v.index();
        let tiles: Vec<_> = r
            .contents
            .iter()
            .filter(|(_, f)| f.variant_bytes[i] > 0)
            .collect();
        if tiles.is_empty() {
            continue;
        }
        let bytes: u64 = tiles.iter().map(|(_, f)| f.variant_bytes[i] as u64).sum();
        let splats: u64 = tiles.iter().map(|(_, f)| f.splat_count as u64).sum();
        let us: Vec<f64> = tiles
            .iter()
            .map(|(_, f)| f.variant_utility[i] as f64)
            .filter(|u| *u >= 0.0)
            .collect();
        let mean = (!us.is_empty()).then(|| us.iter().sum::<f64>() / us.len() as f64);
        let worst = us.iter().copied().reduce(f64::min);
        out.insert(
            v.name().into(),
            serde_json::json!({
                "tiles": tiles.len(), "bytes": bytes,
                "bytesPerSplat": bytes as f64 / splats.max(1) as f64,
                "meanUtility": mean, "worstUtility": worst,
                "encodeSeconds": tiles.iter().map(|(_, f)| f.encode_seconds[i]).sum::<f64>(),
            }),
        );
    }
    out.into()
}

fn fmt_utility(v: &serde_json::Value) -> String {
    v.as_f64()
        .map_or_else(|| "-".to_string(), |u| format!("{u:.4}"))
}

/// Parses one `--variants` item: a variant name or `all`.
fn parse_variant(s: &str) -> Result<Vec<Variant>, String> {
    if s.eq_ignore_ascii_case("all") {
        return Ok(ALL.to_vec());
    }
    Variant::from_name(&s.to_ascii_lowercase())
        .map(|v| vec![v])
        .ok_or_else(|| format!("unknown variant '{s}' (best, high, medium, low or all)"))
}

/// Peak resident memory of this process in MiB (Linux `VmHWM`), if the OS tells.
pub fn peak_rss_mib() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib / 1024.0)
}

fn positive_f64(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(format!("'{s}': expected a positive number")),
    }
}
