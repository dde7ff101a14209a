//! Plan of a sharded conversion (`convert IN --plan PLAN.json --parts N`): one cheap pass for
//! the frame (bounds, root, layout) and one for a histogram of cells, which split the tree into
//! units (disjoint subtrees) given to N parts balanced by splat count.
//!
//! The plan file is versioned JSON holding everything a part or the merge needs that depends on
//! the whole scene; floats are exact (`shard::F`). A bad plan is refused with its byte offset.

use super::frame::Layout;
use super::shard::{F, arr_key, bad, digest, f3, key_arr, parse, read_bounded, v3, write_atomic};
use super::source::Input;
use super::spill::{count_cells, histogram_levels, prefix_sums};
use super::spill_records::SpillFormat;
use super::{
    ConvertError, ConvertOptions, check_counts, check_interrupt, frame_and_budget, frame_pass,
};
use crate::lod::{LodOptions, MergeRule};
use crate::variants::{Profile, Variant, VariantOptions};
use glam::{DMat3, DMat4};
use serde::{Deserialize, Serialize};
use splat2tiles_core::frame::UpAxis;
use splat2tiles_core::frame::mercator::MercatorKey;
use splat2tiles_core::named::Named;
use splat2tiles_io::{self as io, ChunkedInput};
use splat2tiles_tiles::tiling::tileset::BoundingVolume;
use splat2tiles_tiles::tiling::{Scheme, TileKey};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Version of the plan file format.
pub const PLAN_VERSION: u32 = 2;

/// Most parts a plan may have.
pub const MAX_PARTS: usize = 1 << 16;

/// Largest plan file read (a plan lists at most a few units per part).
const MAX_PLAN_BYTES: u64 = 256 << 20;

/// Units per part aimed at: more units balance the parts better.
const UNITS_PER_PART: u64 = 4;

/// The plan file.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
pub(super) struct PlanFile {
    pub(super) splat2tiles_plan: u32,
    pub(super) input: PlanInput,
    pub(super) options: PlanOptions,
    pub(super) layout: LayoutRec,
    pub(super) parts: usize,
    pub(super) units: Vec<UnitRec>,
    /// `[cell, splats]` of every occupied cell of the first routing histogram (Morton order),
    /// so parts route without counting again.
    pub(super) histogram: Vec<[u64; 2]>,
}

/// What the plan knows of its input (a part refuses another file).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
pub(super) struct PlanInput {
    /// File name (the tileset's `extras`).
    pub(super) name: String,
    pub(super) bytes: u64,
    pub(super) splats: u64,
    pub(super) finite: u64,
    pub(super) dropped: u64,
    pub(super) sh_degree: u8,
    /// [`fingerprint`] of the input file.
    pub(super) fingerprint: String,
    /// The CRC-32 of each of the fingerprint's blocks (the routing step checks the blocks it
    /// reads against them).
    #[serde(default)]
    pub(super) blocks: Vec<u32>,
    /// The file's bytes before its first record, as hex, for a binary PLY or `.splat` input
    /// whose records start within [`MAX_HEADER_BYTES`] (routing steps decode with it).
    #[serde(default)]
    pub(super) header: Option<String>,
}

/// Longest input header a plan keeps.
pub(super) const MAX_HEADER_BYTES: usize = 64 << 10;

/// Blocks [`fingerprint`] reads, evenly spaced over the file.
const FINGERPRINT_BLOCKS: u64 = 64;
/// Bytes of each block.
const FINGERPRINT_BLOCK: u64 = 64 << 10;

/// The byte ranges (offset, length) [`fingerprint`] reads of a file of `len` bytes: 64 blocks
/// of 64 KiB spread evenly over it (all of it when smaller than 4 MiB).
pub(super) fn fingerprint_ranges(len: u64) -> Vec<(u64, u64)> {
    let span = FINGERPRINT_BLOCKS * FINGERPRINT_BLOCK;
    let starts: Vec<u64> = if len <= span {
        (0..len.div_ceil(FINGERPRINT_BLOCK))
            .map(|i| i * FINGERPRINT_BLOCK)
            .collect()
    } else {
        let last = len - FINGERPRINT_BLOCK;
        (0..FINGERPRINT_BLOCKS)
            .map(|i| last / (FINGERPRINT_BLOCKS - 1) * i)
            .collect()
    };
    starts
        .into_iter()
        .map(|at| (at, (len - at).min(FINGERPRINT_BLOCK)))
        .collect()
}

/// The fingerprint of a file of `len` bytes from the bytes of its [`fingerprint_ranges`], and
/// the CRC-32 of each block.
pub(super) fn fingerprint_of(len: u64, blocks: &[Vec<u8>]) -> (String, Vec<u32>) {
    let mut h = crc32fast::Hasher::new();
    for b in blocks {
        h.update(b);
    }
    let crcs = blocks.iter().map(|b| crc32fast::hash(b)).collect();
    (format!("crc32-64x64k:{len}:{:08x}", h.finalize()), crcs)
}

/// Reads the ranges of `path` that `have` lacks (`None`); returns every range's bytes and the
/// bytes read.
pub(super) fn read_ranges(
    path: &Path,
    ranges: &[(u64, u64)],
    have: Vec<Option<Vec<u8>>>,
) -> Result<(Vec<Vec<u8>>, u64), ConvertError> {
    use std::io::{Read, Seek, SeekFrom};
    let mut file = None;
    let mut read = 0u64;
    let mut out = Vec::with_capacity(ranges.len());
    for (&(at, n), got) in ranges.iter().zip(have) {
        if let Some(b) = got {
            out.push(b);
            continue;
        }
        let io = super::io_err(path, "reading");
        if file.is_none() {
            file = Some(std::fs::File::open(path).map_err(io)?);
        }
        let f = file.as_mut().expect("opened");
        let mut buf = vec![0u8; n as usize];
        f.seek(SeekFrom::Start(at))
            .and_then(|_| f.read_exact(&mut buf))
            .map_err(super::io_err(path, "reading"))?;
        read += n;
        out.push(buf);
    }
    Ok((out, read))
}

/// A fingerprint of the content of `path`: the CRC-32 of 64 blocks of 64 KiB spread evenly
/// over the file (all of it when smaller than 4 MiB), as hex. It tells apart two files of the
/// same size and splat count (a mirrored or re-ordered copy changes the bytes of every block)
/// at the cost of reading 4 MiB, not the whole input. Also returns the bytes read.
pub(super) fn fingerprint(path: &Path) -> Result<(String, u64), ConvertError> {
    let len = std::fs::metadata(path)
        .map_err(super::io_err(path, "reading"))?
        .len();
    let ranges = fingerprint_ranges(len);
    let (blocks, read) = read_ranges(path, &ranges, vec![None; ranges.len()])?;
    Ok((fingerprint_of(len, &blocks).0, read))
}

/// The one field read before a plan is parsed whole (every other field is skipped unread).
#[derive(Deserialize)]
struct Probe {
    #[serde(rename = "splat2tilesPlan")]
    version: Option<u64>,
}

/// The conversion options every part and the merge use.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
pub(super) struct PlanOptions {
    pub(super) max_splats: usize,
    pub(super) subtree_levels: Option<u32>,
    pub(super) up_axis: String,
    pub(super) lod: bool,
    pub(super) lod_merge: String,
    pub(super) lod_radius: Option<F>,
    pub(super) profile: String,
    pub(super) variants: Vec<String>,
    pub(super) measure_utility: bool,
    pub(super) utility_renders: bool,
}

/// The layout (`frame::Layout`), exactly.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
pub(super) struct LayoutRec {
    a: Vec<F>,
    scheme: String,
    max_depth: u32,
    root_box: Option<Vec<F>>,
    root_region: Option<Vec<F>>,
    transform: Option<Vec<F>>,
    mercator_root: Option<[u32; 3]>,
    enu: Option<Vec<F>>,
    min: [F; 3],
    size: [F; 3],
}

/// One unit: a subtree built by one part.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
pub(super) struct UnitRec {
    /// `[level, x, y, z]`.
    pub(super) key: [u32; 4],
    pub(super) splats: u64,
    pub(super) part: usize,
}

/// What making a plan did.
#[derive(Debug, Clone, Default)]
pub struct PlanReport {
    /// Finite splats in the input.
    pub splats: u64,
    /// Units (subtrees) the tree was split into.
    pub units: usize,
    /// Splats per part.
    pub part_splats: Vec<u64>,
    /// Splats dropped for NaN/Inf values.
    pub dropped_non_finite: u64,
    /// Bytes read from the input file (both passes, the first bytes and the fingerprint).
    pub input_bytes_read: u64,
    /// Wall-clock seconds.
    pub seconds: f64,
}

/// A plan read back and checked.
#[derive(Debug, Clone)]
pub(super) struct Plan {
    pub(super) file: PlanFile,
    /// Digest of the plan file's bytes (parts and merge check they share it).
    pub(super) id: String,
    pub(super) path: PathBuf,
    pub(super) layout: Layout,
    /// Units, keys parsed, in file (Morton) order.
    pub(super) units: Vec<(TileKey, u64, usize)>,
    /// Prefix sums of the histogram's cells.
    pub(super) prefix: Vec<u64>,
}

/// Opens an input for a sharded step: chunked when it can be, else read whole under the limit.
pub(super) fn open_input(path: &Path, memory_limit: u64) -> Result<Input, ConvertError> {
    Ok(match ChunkedInput::open(path)? {
        Some(c) => Input::Chunked(c),
        None => Input::Memory(io::read_path_limited(path, memory_limit)?),
    })
}

fn name_of<T: Named>(v: &T) -> String {
    v.name().to_string()
}

/// Writes the plan of converting `input` in `parts` parts with `opts` to the file `plan`.
pub fn make_plan(
    input_path: &Path,
    plan: &Path,
    parts: usize,
    opts: &ConvertOptions,
) -> Result<PlanReport, ConvertError> {
    let start = Instant::now();
    if parts == 0 || parts > MAX_PARTS {
        return Err(bad(
            plan,
            None,
            format!("{parts} parts: expected 1 to {MAX_PARTS}"),
        ));
    }
    refuse_foreign(plan)?;
    let name = input_path.display().to_string();
    let bytes = std::fs::metadata(input_path)
        .map_err(super::io_err(input_path, "reading"))?
        .len();
    let input = open_input(input_path, opts.memory_limit)?;
    let (up, a, budget) = frame_and_budget(&input, opts);
    let degree = input.sh_degree();
    // The fingerprint's blocks are taken from the first pass's reads.
    let ranges = fingerprint_ranges(bytes);
    if let Input::Chunked(c) = &input {
        c.keep(&ranges);
    }
    let (acc, counts, _) = frame_pass(&input, a, opts, budget.chunk, false)?;
    let kept = match &input {
        Input::Chunked(c) => c.kept(),
        Input::Memory(_) => vec![None; ranges.len()],
    };
    let (blocks, fingerprint_read) = read_ranges(input_path, &ranges, kept)?;
    let (fingerprint, block_crcs) = fingerprint_of(bytes, &blocks);
    drop(blocks);
    let dropped = check_counts(&counts, &input, &name, opts)? as u64;
    let layout = Layout::new(&acc, a, opts);

    // Histogram of the cells the routing histogram of every part uses (`spill::route`).
    let scheme = layout.scheme;
    let dims = scheme.dims();
    let depth = layout.depth();
    let g = histogram_levels(dims, depth);
    let cells = 1usize << (dims * g);
    let mut hist = vec![0u64; cells];
    let format = SpillFormat::for_input(&input);
    let mut of: Vec<u32> = Vec::new();
    input.for_each_batch(budget.chunk, format.is_raw(), counts.dropped == 0, |b| {
        check_interrupt()?;
        count_cells(&mut hist, &mut of, b.positions, |p| {
            (layout.code(p) >> (dims * (depth - g))) as usize
        });
        Ok(())
    })?;
    let prefix = prefix_sums(&hist);
    let histogram: Vec<[u64; 2]> = hist
        .iter()
        .enumerate()
        .filter(|(_, c)| **c > 0)
        .map(|(i, c)| [i as u64, *c])
        .collect();
    drop(hist);
    // Units top-down: a subtree that fits the unit cap (its parent does not, and the cap is at
    // least a leaf's budget, so the whole-scene partition reaches it), or a histogram cell.
    let cap = counts
        .finite
        .div_ceil(parts as u64 * UNITS_PER_PART)
        .max(opts.max_splats_per_tile as u64);
    let mut units: Vec<(TileKey, u64)> = Vec::new();
    let mut stack = vec![(0u32, 0usize, cells)];
    while let Some((l, a, n)) = stack.pop() {
        let count = prefix[a + n] - prefix[a];
        if count == 0 {
            continue;
        }
        if count <= cap || l == g {
            let (x, y, z) = scheme.decode((a >> (dims * (g - l))) as u64);
            units.push((TileKey { level: l, x, y, z }, count));
            continue;
        }
        let step = n >> dims;
        for c in (0..scheme.arity() as usize).rev() {
            stack.push((l + 1, a + c * step, step));
        }
    }
    // Consecutive units per part, each part about `finite / parts` splats.
    let total = counts.finite;
    let mut before = 0u64;
    let mut part_splats = vec![0u64; parts];
    let unit_recs: Vec<UnitRec> = units
        .iter()
        .map(|&(key, count)| {
            let mid = before as u128 * 2 + count as u128;
            let part =
                ((mid * parts as u128) / (2 * total as u128)).min(parts as u128 - 1) as usize;
            before += count;
            part_splats[part] += count;
            UnitRec {
                key: key_arr(key),
                splats: count,
                part,
            }
        })
        .collect();
    let file = PlanFile {
        splat2tiles_plan: PLAN_VERSION,
        input: PlanInput {
            name: input_path
                .file_name()
                .map(|f| f.to_string_lossy().into_owned())
                .unwrap_or_default(),
            bytes,
            fingerprint,
            blocks: block_crcs,
            header: match &input {
                Input::Chunked(c) => c.header().filter(|h| h.len() <= MAX_HEADER_BYTES).map(hex),
                Input::Memory(_) => None,
            },
            splats: input.len(),
            finite: counts.finite,
            dropped,
            sh_degree: degree,
        },
        options: PlanOptions {
            max_splats: opts.max_splats_per_tile,
            subtree_levels: opts.subtree_levels,
            up_axis: up.to_string(),
            lod: opts.lod.enabled,
            lod_merge: name_of(&opts.lod.merge),
            lod_radius: opts.lod.radius.map(F),
            profile: name_of(&opts.variants.profile),
            variants: opts.variants.variants.iter().map(name_of).collect(),
            measure_utility: opts.variants.measure_utility,
            utility_renders: opts.variants.utility_renders,
        },
        layout: layout_rec(&layout),
        parts,
        units: unit_recs,
        histogram,
    };
    let json = serde_json::to_vec_pretty(&file).expect("plan serialises");
    write_atomic(plan, &json)?;
    Ok(PlanReport {
        splats: counts.finite,
        units: units.len(),
        part_splats,
        dropped_non_finite: dropped,
        input_bytes_read: input_bytes_read(&input, bytes) + fingerprint_read,
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// Bytes read from the file of `input` (`bytes` long) so far: what its passes read, or the
/// whole file for an input read whole.
pub(super) fn input_bytes_read(input: &Input, bytes: u64) -> u64 {
    match input {
        Input::Chunked(c) => c.bytes_read(),
        Input::Memory(_) => bytes,
    }
}

/// `bytes` as lowercase hex.
pub(super) fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// Back from [`hex`]; `None` for anything but pairs of hex digits.
pub(super) fn unhex(s: &str) -> Option<Vec<u8>> {
    if !s.len().is_multiple_of(2) {
        return None;
    }
    (0..s.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(s.get(i..i + 2)?, 16).ok())
        .collect()
}

/// Refuses to replace a file at `plan` that is not a plan (nothing of the user's is replaced).
fn refuse_foreign(plan: &Path) -> Result<(), ConvertError> {
    match std::fs::symlink_metadata(plan) {
        Err(_) => Ok(()),
        Ok(m) if !m.is_file() => Err(bad(plan, None, "exists and is not a file")),
        Ok(m) if m.len() > MAX_PLAN_BYTES => Err(bad(
            plan,
            None,
            "exists and is not a splat2tiles plan; not replaced",
        )),
        Ok(_) => {
            let bytes = std::fs::read(plan).map_err(super::io_err(plan, "reading"))?;
            let v: Option<Probe> = serde_json::from_slice(&bytes).ok();
            if v.is_some_and(|p| p.version.is_some()) {
                Ok(())
            } else {
                Err(bad(
                    plan,
                    None,
                    "exists and is not a splat2tiles plan; not replaced",
                ))
            }
        }
    }
}

fn layout_rec(l: &Layout) -> LayoutRec {
    let fs = |v: &[f64]| v.iter().map(|x| F(*x)).collect::<Vec<F>>();
    LayoutRec {
        a: fs(&l.a.to_cols_array()),
        scheme: l.scheme.as_str().to_string(),
        max_depth: l.max_depth,
        root_box: l.root_volume.box_.as_deref().map(fs),
        root_region: l.root_volume.region.as_deref().map(fs),
        transform: l.transform.as_ref().map(|t| fs(t)),
        mercator_root: l.mercator_root.map(|m| [m.zoom, m.x, m.y]),
        enu: l.enu.map(|e| fs(&e.to_cols_array())),
        min: f3(l.min),
        size: f3(l.size),
    }
}

/// Exactly `n` finite floats.
fn floats<const N: usize>(v: &[F], what: &str) -> Result<[f64; N], String> {
    if v.len() != N || v.iter().any(|x| !x.0.is_finite()) {
        return Err(format!("layout.{what}: expected {N} finite numbers"));
    }
    Ok(std::array::from_fn(|i| v[i].0))
}

fn layout_of(r: &LayoutRec) -> Result<Layout, String> {
    let scheme = match r.scheme.as_str() {
        "QUADTREE" => Scheme::Quadtree,
        "OCTREE" => Scheme::Octree,
        s => return Err(format!("layout.scheme: '{s}' (QUADTREE or OCTREE)")),
    };
    if r.max_depth > scheme.max_depth() {
        return Err(format!(
            "layout.maxDepth: {} (at most {})",
            r.max_depth,
            scheme.max_depth()
        ));
    }
    let a = DMat3::from_cols_array(&floats::<9>(&r.a, "a")?);
    let min = v3(&r.min);
    let size = v3(&r.size);
    if !min.is_finite() || !size.is_finite() || size.min_element() <= 0.0 {
        return Err("layout.min/size: expected finite numbers, sizes above 0".into());
    }
    let root_volume = BoundingVolume {
        box_: match &r.root_box {
            Some(b) => Some(floats::<12>(b, "rootBox")?.to_vec()),
            None => None,
        },
        region: match &r.root_region {
            Some(b) => Some(floats::<6>(b, "rootRegion")?.to_vec()),
            None => None,
        },
        sphere: None,
    };
    if root_volume.box_.is_some() == root_volume.region.is_some() {
        return Err("layout: expected one of rootBox and rootRegion".into());
    }
    let transform = match &r.transform {
        Some(t) => Some(floats::<16>(t, "transform")?),
        None => None,
    };
    let enu = match &r.enu {
        Some(t) => Some(DMat4::from_cols_array(&floats::<16>(t, "enu")?)),
        None => None,
    };
    let mercator_root = r
        .mercator_root
        .map(|[zoom, x, y]| MercatorKey { zoom, x, y });
    if enu.is_some() != mercator_root.is_some() || (enu.is_some() && scheme != Scheme::Quadtree) {
        return Err("layout: a georeferenced layout has enu and mercatorRoot, quadtree".into());
    }
    if let Some(m) = mercator_root
        && (m.zoom > 30 || m.x as u64 >= 1 << m.zoom || m.y as u64 >= 1 << m.zoom)
    {
        return Err(format!(
            "layout.mercatorRoot: {:?} is no Web-Mercator tile",
            [m.zoom, m.x, m.y]
        ));
    }
    Ok(Layout {
        a,
        scheme,
        max_depth: r.max_depth,
        root_volume,
        transform,
        mercator_root,
        enu,
        min,
        size,
    })
}

fn enum_of<T: Named>(s: &str, what: &str) -> Result<T, String> {
    T::from_name(&s.to_ascii_lowercase())
        .ok_or_else(|| format!("options.{what}: unknown value '{s}'"))
}

impl Plan {
    /// Reads and checks the plan at `path`.
    pub(super) fn load(path: &Path) -> Result<Plan, ConvertError> {
        let bytes = read_bounded(path, MAX_PLAN_BYTES)?;
        Self::from_bytes(path, &bytes)
    }

    /// Parses and checks plan `bytes` read from `path` (named in errors).
    pub(super) fn from_bytes(path: &Path, bytes: &[u8]) -> Result<Plan, ConvertError> {
        let probe: Probe = parse(path, bytes)?;
        match probe.version {
            Some(v) if v == PLAN_VERSION as u64 => {}
            Some(v) => {
                return Err(bad(
                    path,
                    None,
                    format!("plan version {v}; this splat2tiles reads version {PLAN_VERSION}"),
                ));
            }
            None => {
                return Err(bad(
                    path,
                    None,
                    "not a splat2tiles plan (no splat2tilesPlan)",
                ));
            }
        }
        let file: PlanFile = parse(path, bytes)?;
        let invalid = |why: String| bad(path, None, format!("invalid plan: {why}"));
        let layout = layout_of(&file.layout).map_err(invalid)?;
        let o = &file.options;
        enum_of::<MergeRule>(&o.lod_merge, "lodMerge").map_err(invalid)?;
        enum_of::<Profile>(&o.profile, "profile").map_err(invalid)?;
        for v in &o.variants {
            enum_of::<Variant>(v, "variants").map_err(invalid)?;
        }
        o.up_axis
            .parse::<UpAxis>()
            .map_err(|e| invalid(format!("options.upAxis: {e}")))?;
        if o.max_splats == 0 || o.max_splats > 16_777_216 {
            return Err(invalid(format!("options.maxSplats: {}", o.max_splats)));
        }
        if o.subtree_levels.is_some_and(|l| !(1..=16).contains(&l)) {
            return Err(invalid("options.subtreeLevels: expected 1 to 16".into()));
        }
        if o.lod_radius
            .is_some_and(|r| !(r.0.is_finite() && r.0 > 0.0))
        {
            return Err(invalid(
                "options.lodRadius: expected a positive number".into(),
            ));
        }
        if file.input.sh_degree > 3 {
            return Err(invalid(format!("input.shDegree: {}", file.input.sh_degree)));
        }
        let nblocks = fingerprint_ranges(file.input.bytes).len();
        if !(file.input.blocks.is_empty() || file.input.blocks.len() == nblocks) {
            return Err(invalid(format!(
                "input.blocks: {} checksums, {nblocks} blocks",
                file.input.blocks.len()
            )));
        }
        if let Some(h) = &file.input.header
            && (h.len() > 2 * MAX_HEADER_BYTES || unhex(h).is_none())
        {
            return Err(invalid(format!(
                "input.header: expected at most {MAX_HEADER_BYTES} bytes as hex"
            )));
        }
        if file.parts == 0 || file.parts > MAX_PARTS {
            return Err(invalid(format!("parts: {} (1 to {MAX_PARTS})", file.parts)));
        }
        // Units: valid keys within the routing histogram's levels, disjoint, in Morton order,
        // parts non-decreasing, splats adding up to the input's.
        let scheme = layout.scheme;
        let dims = scheme.dims();
        let g = histogram_levels(dims, layout.depth());
        let cells = 1usize << (dims * g);
        let mut hist = vec![0u64; cells];
        let mut last_cell = None;
        for (i, &[cell, count]) in file.histogram.iter().enumerate() {
            if cell >= cells as u64 || last_cell.is_some_and(|l| l >= cell) || count == 0 {
                return Err(invalid(format!(
                    "histogram[{i}]: cells must be below {cells}, increasing, with splats"
                )));
            }
            last_cell = Some(cell);
            hist[cell as usize] = count;
        }
        let mut prefix = vec![0u64; cells + 1];
        for i in 0..cells {
            prefix[i + 1] = prefix[i].saturating_add(hist[i]);
        }
        drop(hist);
        if prefix[cells] != file.input.finite {
            return Err(invalid(format!(
                "the histogram holds {} splats, the input {}",
                prefix[cells], file.input.finite
            )));
        }
        let mut units = Vec::with_capacity(file.units.len());
        let mut end = 0u64;
        let mut last_part = 0usize;
        let mut total = 0u64;
        for (i, u) in file.units.iter().enumerate() {
            let key = arr_key(u.key, g, scheme == Scheme::Octree).ok_or_else(|| {
                invalid(format!(
                    "units[{i}].key {:?}: not a tile within {g} levels",
                    u.key
                ))
            })?;
            let shift = dims * (g - key.level);
            let first = scheme.encode(key.x, key.y, key.z) << shift;
            if first < end {
                return Err(invalid(format!(
                    "units[{i}]: overlaps or precedes the unit before it"
                )));
            }
            end = first + (1u64 << shift);
            if prefix[end as usize] - prefix[first as usize] != u.splats {
                return Err(invalid(format!(
                    "units[{i}]: {} splats where the histogram has {}",
                    u.splats,
                    prefix[end as usize] - prefix[first as usize]
                )));
            }
            if u.part >= file.parts || u.part < last_part {
                return Err(invalid(format!(
                    "units[{i}].part {}: parts must be below {} and non-decreasing",
                    u.part, file.parts
                )));
            }
            last_part = u.part;
            total = total.saturating_add(u.splats);
            units.push((key, u.splats, u.part));
        }
        if total != file.input.finite {
            return Err(invalid(format!(
                "units hold {total} splats, the input {}",
                file.input.finite
            )));
        }
        Ok(Plan {
            file,
            id: digest(bytes),
            path: path.to_path_buf(),
            layout,
            units,
            prefix,
        })
    }

    /// The conversion options of the plan, with this machine's memory limit.
    pub(super) fn options(
        &self,
        memory_limit: u64,
        progress: crate::progress::ProgressSink,
    ) -> ConvertOptions {
        let o = &self.file.options;
        ConvertOptions {
            max_splats_per_tile: o.max_splats,
            max_depth: Some(self.layout.max_depth),
            up_axis: o.up_axis.parse().ok(),
            subtree_levels: o.subtree_levels,
            progress,
            lod: LodOptions {
                enabled: o.lod,
                merge: enum_of(&o.lod_merge, "").unwrap_or_default(),
                radius: o.lod_radius.map(|r| r.0),
            },
            variants: VariantOptions {
                profile: enum_of(&o.profile, "").unwrap_or_default(),
                variants: o
                    .variants
                    .iter()
                    .filter_map(|v| enum_of(v, "").ok())
                    .collect(),
                measure_utility: o.measure_utility,
                utility_renders: o.utility_renders,
            },
            memory_limit,
            ..Default::default()
        }
    }

    /// The units of part `part`, in Morton order.
    pub(super) fn units_of(&self, part: usize) -> Vec<TileKey> {
        self.units
            .iter()
            .filter(|u| u.2 == part)
            .map(|u| u.0)
            .collect()
    }

    /// Refuses an input other than the one planned (size, splat count, SH degree, fingerprint);
    /// returns the bytes the fingerprint read.
    pub(super) fn check_input(&self, path: &Path, input: &Input) -> Result<u64, ConvertError> {
        let bytes = std::fs::metadata(path)
            .map_err(super::io_err(path, "reading"))?
            .len();
        let p = &self.file.input;
        let same = bytes == p.bytes && input.len() == p.splats && input.sh_degree() == p.sh_degree;
        let (print, read) = if same {
            fingerprint(path)?
        } else {
            (String::new(), 0)
        };
        if same && print != p.fingerprint {
            return Err(self.other_content(path, None));
        }
        if !same {
            return Err(self.other_input(path, bytes, input));
        }
        Ok(read)
    }

    /// The error for `path`, whose size and splat count are the planned input's but whose
    /// content (fingerprint) differs, at byte `at` where known.
    pub(super) fn other_content(&self, path: &Path, at: Option<u64>) -> ConvertError {
        bad(
            path,
            at,
            format!(
                "not the input of plan {}: the same size and splat count, other content \
                 (fingerprint {} planned)",
                self.path.display(),
                self.file.input.fingerprint
            ),
        )
    }

    /// The error for `path` (`bytes` long, read as `input`) when its size, splat count or SH
    /// degree differs from the planned input's.
    pub(super) fn other_input(&self, path: &Path, bytes: u64, input: &Input) -> ConvertError {
        let p = &self.file.input;
        bad(
            path,
            None,
            format!(
                "not the input of plan {} ({} bytes, {} splats, SH degree {} planned; {bytes} \
                 bytes, {} splats, SH degree {} here)",
                self.path.display(),
                p.bytes,
                p.splats,
                p.sh_degree,
                input.len(),
                input.sh_degree()
            ),
        )
    }
}
