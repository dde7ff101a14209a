//! Sharded conversion front ends: `convert IN --plan PLAN --parts N` (plan), `convert IN --plan
//! PLAN --route DIR [--route-chunk C --route-chunks K]` (routing), `convert IN --plan PLAN
//! --part I [--phase samples] [--route DIR] -o PART_I` (a part) and `merge PLAN PART... -o OUT`.

use super::{ConvertArgs, peak_rss_mib};
use clap::Args;
use splat2tiles_build::convert::{
    ConvertError, ConvertOptions, MAX_PARTS, MAX_ROUTE_CHUNKS, PartPhase, convert_part, make_plan,
    merge_parts, route_input,
};
use splat2tiles_io::limits::MemoryLimit;
use std::path::{Path, PathBuf};

/// Arguments of `convert` for the steps of a sharded conversion.
#[derive(Debug, Args)]
pub struct ShardArgs {
    /// With --plan (and no --part): split the tree into this many parts, balanced by splats.
    #[arg(long, requires = "plan", conflicts_with_all = ["part", "route"],
          value_parser = clap::value_parser!(u64).range(1..=MAX_PARTS as u64))]
    pub parts: Option<u64>,
    /// With --plan (and no --part): read the input once (or chunk --route-chunk of it) and
    /// write each part's splats to its own file in this folder. With --part: read the part's
    /// splats from those files, not from the input.
    #[arg(long, requires = "plan")]
    pub route: Option<PathBuf>,
    /// With --route (routing): the chunk of the input's records to route (0-based).
    #[arg(long, requires = "route", conflicts_with = "part", default_value_t = 0)]
    pub route_chunk: u64,
    /// With --route (routing): chunks the input's records are routed in (each its own step,
    /// which may run in parallel; 1 for SPZ and other inputs read whole).
    #[arg(long, requires = "route", conflicts_with = "part", default_value_t = 1,
          value_parser = clap::value_parser!(u64).range(1..=MAX_ROUTE_CHUNKS as u64))]
    pub route_chunks: u64,
    /// With --plan: build this part (0-based) into --output.
    #[arg(long, requires = "plan", requires = "output")]
    pub part: Option<u64>,
    /// With --part: `samples` writes the part's leaf statistics only (first phase, needed for
    /// the default leaf radius); `build` builds its tiles.
    #[arg(long, value_parser = crate::cli::named::<PartPhase>(), default_value = "build", requires = "part")]
    pub phase: PartPhase,
    /// With --part (build phase): the samples folders of all parts, when the plan needs the
    /// data's leaf radius (no --lod-radius, LOD on).
    #[arg(long, num_args = 1.., requires = "part")]
    pub samples: Vec<PathBuf>,
}

/// Arguments of `merge`.
#[derive(Debug, Args)]
#[command(after_help = "Example:
  splat2tiles merge plan.json p0 p1 p2 p3 -o city/")]
pub struct MergeArgs {
    /// The plan file the parts were built from.
    pub plan: PathBuf,
    /// The built part folders (all of them, any order).
    #[arg(required = true, num_args = 1..)]
    pub parts: Vec<PathBuf>,
    /// Output tileset folder (as for `convert`).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Memory budget (as for `convert`).
    #[arg(long, value_parser = MemoryLimit::parse)]
    pub memory_limit: Option<MemoryLimit>,
    /// Print the summary as JSON on stdout.
    #[arg(long)]
    pub json: bool,
    /// No summary.
    #[arg(short, long)]
    pub quiet: bool,
}

/// Bytes this process read or wrote through system calls so far (Linux `/proc/self/io`
/// `rchar` / `wchar`: files and pipes, cache hits included), if the OS tells.
fn io_bytes(field: &str) -> Option<u64> {
    let io = std::fs::read_to_string("/proc/self/io").ok()?;
    let line = io
        .lines()
        .find(|l| l.starts_with(field) && l[field.len()..].starts_with(':'))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

fn fail(e: ConvertError) -> i32 {
    if e.is_interrupt() {
        eprintln!("splat2tiles: interrupted; no output written");
        130
    } else {
        eprintln!("splat2tiles: {e}");
        crate::cli::EXIT_FAILURE
    }
}

fn notes(notes: &[String]) {
    for n in notes {
        eprintln!("splat2tiles: {n}");
    }
}

/// Runs `convert --plan`: the plan, or one part of it.
pub fn run(args: &ConvertArgs, plan: &Path, opts: &ConvertOptions) -> i32 {
    crate::cli::install_interrupt_handler();
    let s = &args.shard;
    let Some(part) = s.part else {
        if let Some(dir) = &s.route {
            return run_route(args, plan, dir, opts.memory_limit);
        }
        let Some(parts) = s.parts else {
            eprintln!(
                "splat2tiles: --plan needs --parts N (write the plan), --route DIR (route the \
                 input) or --part I (build it)"
            );
            return crate::cli::EXIT_FAILURE;
        };
        return match make_plan(&args.input, plan, parts as usize, opts) {
            Ok(r) => {
                if args.json {
                    let v = serde_json::json!({
                        "plan": plan, "splats": r.splats, "units": r.units,
                        "partSplats": r.part_splats, "droppedNonFinite": r.dropped_non_finite,
                        "inputReadBytes": r.input_bytes_read,
                        "seconds": r.seconds, "peakRssMiB": peak_rss_mib(),
                        "readBytes": io_bytes("rchar"), "writtenBytes": io_bytes("wchar"),
                    });
                    outln!("{v}");
                } else if !args.quiet {
                    outln!(
                        "planned {}: {} splats in {} units, parts of {:?} splats, {:.2} s",
                        args.input.display(),
                        r.splats,
                        r.units,
                        r.part_splats,
                        r.seconds
                    );
                }
                0
            }
            Err(e) => fail(e),
        };
    };
    let output = args
        .output
        .as_deref()
        .expect("clap requires --output with --part");
    let progress = crate::cli::progress::bars(args.quiet);
    match convert_part(
        &args.input,
        plan,
        part as usize,
        s.phase,
        &s.samples,
        s.route.as_deref(),
        output,
        opts.memory_limit,
        progress,
    ) {
        Ok(r) => {
            notes(&r.notes);
            if args.json {
                let v = serde_json::json!({
                    "part": part, "output": output, "splats": r.splats, "units": r.units,
                    "contentTiles": r.content_tiles, "bytes": r.bytes,
                    "spillBytes": r.spill_bytes, "leafRadius": r.leaf_radius,
                    "inputReadBytes": r.input_bytes_read,
                    "seconds": r.seconds, "peakRssMiB": peak_rss_mib(),
                    "readBytes": io_bytes("rchar"), "writtenBytes": io_bytes("wchar"),
                });
                outln!("{v}");
            } else if !args.quiet {
                outln!(
                    "part {part} ({:?}): {} splats in {} units, {} tiles, {:.2} MB, {:.2} s",
                    s.phase,
                    r.splats,
                    r.units,
                    r.content_tiles,
                    r.bytes as f64 / 1e6,
                    r.seconds
                );
            }
            0
        }
        Err(e) => fail(e),
    }
}

/// Runs `convert --plan --route` (no --part): routes one chunk of the input.
fn run_route(args: &ConvertArgs, plan: &Path, dir: &Path, memory_limit: u64) -> i32 {
    let s = &args.shard;
    let (chunk, chunks) = (s.route_chunk as usize, s.route_chunks as usize);
    match route_input(&args.input, plan, dir, chunk, chunks, memory_limit) {
        Ok(r) => {
            notes(&r.notes);
            if args.json {
                let v = serde_json::json!({
                    "route": dir, "chunk": chunk, "chunks": chunks, "records": r.records,
                    "splats": r.splats, "bytes": r.bytes, "inputReadBytes": r.input_bytes_read,
                    "seconds": r.seconds, "peakRssMiB": peak_rss_mib(),
                    "readBytes": io_bytes("rchar"), "writtenBytes": io_bytes("wchar"),
                });
                outln!("{v}");
            } else if !args.quiet {
                outln!(
                    "routed chunk {chunk} of {chunks} of {}: {} splats, {:.2} MB, {:.2} s",
                    args.input.display(),
                    r.splats,
                    r.bytes as f64 / 1e6,
                    r.seconds
                );
            }
            0
        }
        Err(e) => fail(e),
    }
}

/// Runs `merge`; returns the process exit code.
pub fn run_merge(args: MergeArgs) -> i32 {
    crate::cli::install_interrupt_handler();
    let limit = args
        .memory_limit
        .unwrap_or_else(MemoryLimit::machine_default)
        .bytes();
    let progress = crate::cli::progress::bars(args.quiet);
    match merge_parts(&args.plan, &args.parts, &args.output, limit, progress) {
        Ok(r) => {
            notes(&r.notes);
            if args.json {
                let v = serde_json::json!({
                    "output": args.output, "tiles": r.tiles, "topTiles": r.top_tiles,
                    "partFiles": r.part_files, "partBytes": r.part_bytes,
                    "copiedBytes": r.copied_bytes, "bytes": r.bytes, "seconds": r.seconds,
                    "peakRssMiB": peak_rss_mib(),
                    "readBytes": io_bytes("rchar"), "writtenBytes": io_bytes("wchar"),
                });
                outln!("{v}");
            } else if !args.quiet {
                outln!(
                    "merged {} parts into {}: {} tiles ({} built above the parts), {:.2} MB \
                     ({:.2} MB copied, the rest hard-linked), {:.2} s",
                    args.parts.len(),
                    args.output.display(),
                    r.tiles,
                    r.top_tiles,
                    r.bytes as f64 / 1e6,
                    r.copied_bytes as f64 / 1e6,
                    r.seconds
                );
            }
            0
        }
        Err(e) => fail(e),
    }
}
