//! Routing step of a sharded conversion (`convert IN --plan PLAN --route DIR [--route-chunk C
//! --route-chunks K]`): the input read once, each part's splats written to its own file.
//!
//! Routing chunk C of K reads the records `[C*n/K, (C+1)*n/K)` of the input (binary PLY and
//! `.splat` records have fixed sizes; an input read whole, such as SPZ, is routed in one chunk)
//! and writes `DIR/chunk-C/part-I.spill` for every part I (spill records, `spill_records`, with
//! the splat's index among the finite input splats, in input order) and `route.json`. The chunk
//! folder is written through a staging folder (`crate::output::Staging`), so it is whole or
//! absent, and a rerun replaces it.
//! A part built with `--route DIR` reads its files of every chunk, in chunk order, and never
//! the input.

use super::plan::{
    Plan, fingerprint, fingerprint_ranges, input_bytes_read, open_input, read_ranges, unhex,
};
use super::shard::{bad, parse, read_bounded};
use super::source::Input;
use super::spill_records::{Codec, SpillFormat};
use super::{Budget, ConvertError, check_interrupt, io_err};
use crate::output::Staging;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use splat2tiles_io::ChunkedInput;
use std::io::{BufWriter, Read, Write};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Version of `route.json`.
const ROUTE_VERSION: u32 = 1;
/// The description of a routed chunk inside its folder.
const ROUTE_FILE: &str = "route.json";
/// Most routing chunks.
pub const MAX_ROUTE_CHUNKS: usize = 4096;
/// Most parts a plan may have to be routed (one file open per part while routing).
pub const MAX_ROUTE_PARTS: usize = 512;
/// Largest `route.json` read (a count per part).
const MAX_ROUTE_JSON: u64 = 1 << 20;

/// `route.json`.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
struct RouteFile {
    splat2tiles_route: u32,
    /// Digest of the plan.
    plan: String,
    chunk: usize,
    chunks: usize,
    /// The input records routed, `[first, end)`.
    records: [u64; 2],
    /// Records are the input's own plus the index (else the wide spill record).
    raw: bool,
    record_bytes: u64,
    /// Splats written for each part.
    parts: Vec<u64>,
}

/// What routing one chunk did.
#[derive(Debug, Clone, Default)]
pub struct RouteReport {
    /// Input records of the chunk.
    pub records: u64,
    /// Finite splats routed.
    pub splats: u64,
    /// Bytes of the routed files written.
    pub bytes: u64,
    /// Bytes read from the input file.
    pub input_bytes_read: u64,
    /// Wall-clock seconds.
    pub seconds: f64,
    /// Notes about the chunk's folder.
    pub notes: Vec<String>,
}

/// The name of chunk `c`'s folder.
fn chunk_dir(dir: &Path, c: usize) -> PathBuf {
    dir.join(format!("chunk-{c}"))
}

/// The spill file of `part` in a chunk folder.
fn part_file(chunk: &Path, part: usize) -> PathBuf {
    chunk.join(format!("part-{part}.spill"))
}

/// Opens the planned input for routing chunk `range` of `chunks`: from the plan's header when
/// it has one (only the records are read; the first chunk reads the header too and checks it),
/// else the file's own first bytes. Returns the input and the bytes read besides its passes.
fn open_planned(
    plan: &Plan,
    path: &Path,
    first: bool,
    memory_limit: u64,
) -> Result<(Input, u64), ConvertError> {
    let p = &plan.file.input;
    let Some(header) = p.header.as_deref().and_then(unhex) else {
        return Ok((open_input(path, memory_limit)?, 0));
    };
    let c = ChunkedInput::from_header(path, &header, p.bytes)?.ok_or_else(|| {
        bad(
            path,
            None,
            "the plan's header is no binary PLY or .splat header",
        )
    })?;
    let mut read = 0;
    if first && !header.is_empty() {
        let mut got = vec![0u8; header.len()];
        std::fs::File::open(path)
            .and_then(|mut f| f.read_exact(&mut got))
            .map_err(io_err(path, "reading"))?;
        read = got.len() as u64;
        if got != header {
            let at = got.iter().zip(&header).position(|(a, b)| a != b);
            return Err(bad(
                path,
                at.map(|a| a as u64),
                format!(
                    "not the input of plan {}: its header differs",
                    plan.path.display()
                ),
            ));
        }
    }
    Ok((Input::Chunked(c), read))
}

/// Routes chunk `chunk` of `chunks` of the input `input_path` of the plan at `plan_path` into
/// `dir/chunk-C` (see the module documentation).
pub fn route_input(
    input_path: &Path,
    plan_path: &Path,
    dir: &Path,
    chunk: usize,
    chunks: usize,
    memory_limit: u64,
) -> Result<RouteReport, ConvertError> {
    let start = Instant::now();
    let plan = Plan::load(plan_path)?;
    let p = &plan.file.input;
    if chunks == 0 || chunks > MAX_ROUTE_CHUNKS || chunk >= chunks {
        return Err(bad(
            plan_path,
            None,
            format!("routing chunk {chunk} of {chunks}: expected 1 to {MAX_ROUTE_CHUNKS} chunks"),
        ));
    }
    let parts = plan.file.parts;
    if parts > MAX_ROUTE_PARTS {
        return Err(bad(
            plan_path,
            None,
            format!("{parts} parts: routing writes at most {MAX_ROUTE_PARTS} parts' files"),
        ));
    }
    if p.blocks.is_empty() {
        return Err(bad(
            plan_path,
            None,
            "the plan has no block checksums to check the input with; make the plan again",
        ));
    }
    let bytes = std::fs::metadata(input_path)
        .map_err(io_err(input_path, "reading"))?
        .len();
    let n = p.splats;
    let range = chunk as u64 * n / chunks as u64..(chunk as u64 + 1) * n / chunks as u64;
    let (input, header_read) = open_planned(&plan, input_path, range.start == 0, memory_limit)?;
    if bytes != p.bytes || input.len() != n || input.sh_degree() != p.sh_degree {
        return Err(plan.other_input(input_path, bytes, &input));
    }
    if chunks > 1 && (p.dropped > 0 || matches!(input, Input::Memory(_))) {
        return Err(bad(
            input_path,
            None,
            "routing in several chunks needs a binary PLY or .splat input without NaN/Inf \
             splats; route it in one chunk (--route-chunks 1)",
        ));
    }
    let ranges = fingerprint_ranges(bytes);
    if let Input::Chunked(c) = &input {
        c.keep(&ranges);
    }
    let format = SpillFormat::for_input(&input);
    let budget = Budget::new(memory_limit, p.sh_degree, plan.file.options.max_splats);
    let target = chunk_dir(dir, chunk);
    crate::output::check_not_over_inputs(&target, &[input_path, plan_path])?;
    let staging = Staging::prepare(&target)?;
    let staged = staging.path().to_path_buf();
    let relocate = |e: ConvertError| e.relocated(&staged, &target);
    let counts = write_parts(
        &plan,
        input_path,
        &input,
        range.clone(),
        &format,
        &staged,
        &budget,
    )
    .map_err(relocate)?;
    let fingerprint_read = check_blocks(&plan, input_path, &input, &ranges, chunks)?;
    let route = RouteFile {
        splat2tiles_route: ROUTE_VERSION,
        plan: plan.id.clone(),
        chunk,
        chunks,
        records: [range.start, range.end],
        raw: format.is_raw(),
        record_bytes: format.record_bytes() as u64,
        parts: counts.clone(),
    };
    let path = staged.join(ROUTE_FILE);
    let json = serde_json::to_vec(&route).expect("route records serialise");
    std::fs::write(&path, json)
        .map_err(io_err(&path, "writing"))
        .map_err(relocate)?;
    // A rerun replaces the chunk's earlier folder.
    let notes = staging.commit()?;
    let splats: u64 = counts.iter().sum();
    Ok(RouteReport {
        records: range.end - range.start,
        splats,
        bytes: splats * format.record_bytes() as u64,
        input_bytes_read: input_bytes_read(&input, bytes) + header_read + fingerprint_read,
        seconds: start.elapsed().as_secs_f64(),
        notes,
    })
}

/// One pass over the records `range` of `input` writing each finite splat to the file of the
/// part whose unit holds it; returns the splats written per part.
fn write_parts(
    plan: &Plan,
    input_path: &Path,
    input: &Input,
    range: std::ops::Range<u64>,
    format: &SpillFormat,
    staging: &Path,
    budget: &Budget,
) -> Result<Vec<u64>, ConvertError> {
    let layout = &plan.layout;
    let scheme = layout.scheme;
    let dims = scheme.dims();
    let depth = layout.depth();
    let g = super::spill::histogram_levels(dims, depth);
    // Part of every histogram cell (units are subtrees within the histogram's levels).
    let mut part_of = vec![u32::MAX; 1usize << (dims * g)];
    for &(key, _, part) in &plan.units {
        let shift = dims * (g - key.level);
        let first = (scheme.encode(key.x, key.y, key.z) << shift) as usize;
        part_of[first..first + (1usize << shift)].fill(part as u32);
    }
    let parts = plan.file.parts;
    let per_file = (budget.write_budget / parts.max(1)).clamp(8 << 10, 4 << 20);
    let mut paths = Vec::with_capacity(parts);
    let mut writers = Vec::with_capacity(parts);
    for i in 0..parts {
        let path = part_file(staging, i);
        let f = std::fs::File::create(&path).map_err(io_err(&path, "creating"))?;
        writers.push(BufWriter::with_capacity(per_file, f));
        paths.push(path);
    }
    let mut counts = vec![0u64; parts];
    let mut rec = Vec::with_capacity(format.record_bytes());
    let mut dest: Vec<u32> = Vec::new();
    let all_finite = plan.file.input.dropped == 0;
    input.for_each_batch_in(range, budget.chunk, format.is_raw(), all_finite, |b| {
        check_interrupt()?;
        b.positions
            .par_iter()
            .map(|p| part_of[(layout.code(*p) >> (dims * (depth - g))) as usize])
            .collect_into_vec(&mut dest);
        for (i, &part) in dest.iter().enumerate() {
            let part = part as usize;
            if part >= parts {
                // Only a changed input puts a splat outside every unit; name its record.
                let at = match input {
                    Input::Chunked(c) if all_finite => Some(c.byte_range(b.idx[i]..b.idx[i] + 1)),
                    _ => None,
                };
                return Err(bad(
                    input_path,
                    at.map(|r| r.start),
                    format!(
                        "splat {} lies in no unit of plan {} (the input changed?)",
                        b.idx[i],
                        plan.path.display()
                    ),
                ));
            }
            rec.clear();
            format.encode(&b, i, &mut rec);
            writers[part]
                .write_all(&rec)
                .map_err(io_err(&paths[part], "writing"))?;
            counts[part] += 1;
        }
        Ok(())
    })?;
    for (w, p) in writers.into_iter().zip(&paths) {
        let f = w
            .into_inner()
            .map_err(|e| e.into_error())
            .map_err(io_err(p, "writing"))?;
        f.sync_all().map_err(io_err(p, "writing"))?;
    }
    Ok(counts)
}

/// Checks the input against the plan's fingerprint: each block the pass read whole against
/// its checksum (a chunk of several), or the whole fingerprint (one chunk; blocks the pass did
/// not read are read). Returns the bytes read for it.
fn check_blocks(
    plan: &Plan,
    path: &Path,
    input: &Input,
    ranges: &[(u64, u64)],
    chunks: usize,
) -> Result<u64, ConvertError> {
    let p = &plan.file.input;
    let foreign = |at: Option<u64>| plan.other_content(path, at);
    let Input::Chunked(c) = input else {
        let (print, read) = fingerprint(path)?;
        return if print == p.fingerprint {
            Ok(read)
        } else {
            Err(foreign(None))
        };
    };
    let kept = c.kept();
    let (blocks, read) = if chunks == 1 {
        read_ranges(path, ranges, kept)?
    } else {
        (kept.into_iter().map(Option::unwrap_or_default).collect(), 0)
    };
    for ((b, crc), &(at, n)) in blocks.iter().zip(&p.blocks).zip(ranges) {
        if b.len() as u64 == n && crc32fast::hash(b) != *crc {
            return Err(foreign(Some(at)));
        }
    }
    Ok(read)
}

/// A part's routed files in `dir`, in input order, checked against the plan (every chunk
/// present once, from this plan, their ranges covering the input, the part's files of the
/// sizes their counts give, the part's splat count the plan's), and the records' format.
pub(super) fn routed_files(
    plan: &Plan,
    input_path: &Path,
    dir: &Path,
    part: usize,
) -> Result<(Vec<PathBuf>, SpillFormat), ConvertError> {
    let p = &plan.file.input;
    let first = read_route(plan, dir, 0)?;
    let chunks = first.chunks;
    let mut files = Vec::with_capacity(chunks);
    let mut next = 0u64;
    let mut splats = 0u64;
    let (raw, record_bytes) = (first.raw, first.record_bytes);
    for c in 0..chunks {
        let r = if c == 0 {
            first.clone()
        } else {
            read_route(plan, dir, c)?
        };
        let path = chunk_dir(dir, c).join(ROUTE_FILE);
        if r.chunks != chunks || r.records[0] != next || r.records[1] < r.records[0] {
            return Err(bad(
                &path,
                None,
                format!("chunk {c}: not of the same routing as chunk 0 ({chunks} chunks)"),
            ));
        }
        if r.raw != raw || r.record_bytes != record_bytes {
            return Err(bad(&path, None, "records of another format than chunk 0's"));
        }
        next = r.records[1];
        let file = part_file(&chunk_dir(dir, c), part);
        let len = std::fs::metadata(&file)
            .map_err(io_err(&file, "reading"))?
            .len();
        let want = r.parts[part].saturating_mul(record_bytes);
        if len != want {
            return Err(bad(
                &file,
                Some(len.min(want)),
                format!("{len} bytes where route.json gives {want}"),
            ));
        }
        splats += r.parts[part];
        files.push(file);
    }
    if next != p.splats {
        return Err(bad(
            dir,
            None,
            format!(
                "the routed chunks cover {next} of the input's {} splats",
                p.splats
            ),
        ));
    }
    let planned: u64 = plan.units.iter().filter(|u| u.2 == part).map(|u| u.1).sum();
    if splats != planned {
        return Err(bad(
            dir,
            None,
            format!("part {part}: {splats} splats routed, {planned} planned"),
        ));
    }
    let format = if raw {
        let header = p.header.as_deref().and_then(unhex).ok_or_else(|| {
            bad(
                dir,
                None,
                "raw records, but the plan keeps no input header to decode them",
            )
        })?;
        let c = ChunkedInput::from_header(input_path, &header, p.bytes)?
            .ok_or_else(|| bad(dir, None, "the plan's header is no binary PLY or .splat"))?;
        SpillFormat::Raw(c)
    } else {
        SpillFormat::Wide(Codec::new(p.sh_degree))
    };
    if format.record_bytes() as u64 != record_bytes {
        return Err(bad(
            dir,
            None,
            format!(
                "records of {record_bytes} bytes; the plan's input gives {}",
                format.record_bytes()
            ),
        ));
    }
    Ok((files, format))
}

/// Reads and checks `route.json` of chunk `c` in `dir`.
fn read_route(plan: &Plan, dir: &Path, c: usize) -> Result<RouteFile, ConvertError> {
    let path = chunk_dir(dir, c).join(ROUTE_FILE);
    if !path.is_file() {
        return Err(bad(
            &path,
            None,
            "missing: route every chunk first (`convert IN --plan PLAN --route DIR`)",
        ));
    }
    let bytes = read_bounded(&path, MAX_ROUTE_JSON)?;
    let r: RouteFile = parse(&path, &bytes)?;
    if r.splat2tiles_route != ROUTE_VERSION {
        return Err(bad(
            &path,
            None,
            format!(
                "route version {}; this splat2tiles reads version {ROUTE_VERSION}",
                r.splat2tiles_route
            ),
        ));
    }
    if r.plan != plan.id {
        return Err(bad(
            &path,
            None,
            format!("routed for another plan than {}", plan.path.display()),
        ));
    }
    if r.chunk != c
        || r.chunks == 0
        || r.chunks > MAX_ROUTE_CHUNKS
        || r.parts.len() != plan.file.parts
    {
        return Err(bad(
            &path,
            None,
            format!(
                "expected chunk {c} of at most {MAX_ROUTE_CHUNKS} with {} parts",
                plan.file.parts
            ),
        ));
    }
    Ok(r)
}
