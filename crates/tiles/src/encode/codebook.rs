//! The codebook variant's payload (spec/codebook-variant.md): splats in Morton order of a
//! position grid, codebooks for scales, colours and opacity, one adaptive range-coded stream.

use splat2tiles_core::splat::{Splats, sh_rest_count};

use super::range_coder::{BitTree, Decoder, Encoder, Truncated};
use crate::tiling::morton::{decode3, encode3};

/// First bytes of a payload.
pub const MAGIC: [u8; 4] = *b"S2TC";
/// Payload version this module writes and reads.
pub const VERSION: u8 = 1;
/// Most splats one payload may declare (a reader allocates for them before decoding).
pub const MAX_SPLATS: u32 = 1 << 26;
/// Most grid bits per axis (the Morton code holds 21).
pub const MAX_GRID_BITS: u8 = 21;
/// Most entries of a codebook (indices have at most 12 bits).
pub const MAX_LEVELS: usize = 4096;
/// Fixed header bytes before the codebooks.
const HEADER: usize = 36;

/// How a codebook's entries are chosen (the reader only looks them up).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Levels {
    /// Up to `n` entries (at most 4096) by 1-D k-means (Lloyd's, from quantiles) over the values.
    KMeans(u16),
    /// Entries `step` apart over the values' range (at most 4096; the step grows if needed).
    Uniform(f32),
    /// [`Levels::Uniform`] with the step this fraction of the values' median.
    Relative(f32),
}

/// Settings of the codebook encoder.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CodebookOptions {
    /// Highest SH degree written (lower of this and the input's).
    pub max_sh_degree: u8,
    /// The position grid's step is at most the median smallest scale over this.
    pub scale_divisor: f32,
    /// Fewest grid bits per axis over the tile's extent (the step is never coarser).
    pub min_grid_bits: u8,
    /// Most grid bits per axis (the step is never finer); at most [`MAX_GRID_BITS`].
    pub max_grid_bits: u8,
    /// Bits of each of the three smallest quaternion components.
    pub rotation_bits: u8,
    /// Codebook of the scales (the three axes share it), in [`Self::linear_scales`]' domain.
    pub scales: Levels,
    /// Scale codebook over the scales themselves (true) or their natural logs (false).
    pub linear_scales: bool,
    /// Codebook of the DC colour coefficients (the three channels share it).
    pub colours: Levels,
    /// Codebook of the opacities.
    pub opacity: Levels,
    /// Bits of each degree-1 SH coefficient (uniform over the tile's largest |coefficient|).
    pub sh1_bits: u8,
    /// Bits of each degree-2 and degree-3 SH coefficient.
    pub sh_rest_bits: u8,
    /// Bits of the previous splat's index (same channel) that select a codebook index's model.
    pub context_bits: u8,
}

impl Default for CodebookOptions {
    fn default() -> Self {
        CodebookOptions {
            max_sh_degree: 3,
            scale_divisor: 9.0,
            min_grid_bits: 12,
            max_grid_bits: 18,
            rotation_bits: 8,
            scales: Levels::Relative(0.05),
            linear_scales: true,
            colours: Levels::KMeans(256),
            opacity: Levels::Uniform(1.0 / 255.0),
            sh1_bits: 5,
            sh_rest_bits: 4,
            context_bits: 2,
        }
    }
}

/// A payload that cannot be decoded: what is wrong and at which byte of the payload.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("codebook payload byte {offset}: {what}")]
pub struct PayloadError {
    /// Byte offset in the payload.
    pub offset: usize,
    /// What is wrong.
    pub what: String,
}

fn err(offset: usize, what: impl Into<String>) -> PayloadError {
    PayloadError {
        offset,
        what: what.into(),
    }
}

/// The position grid of a tile: `origin + cell * step` per axis.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Grid {
    origin: [f32; 3],
    step: f32,
    bits: u8,
}

/// The grid for tile-relative positions `rel` under `opts`.
fn grid_of(rel: &[[f32; 3]], scales: &[[f32; 3]], opts: &CodebookOptions) -> Grid {
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for p in rel {
        for a in 0..3 {
            lo[a] = lo[a].min(p[a]);
            hi[a] = hi[a].max(p[a]);
        }
    }
    let extent = (0..3).map(|a| f64::from(hi[a] - lo[a])).fold(0.0, f64::max);
    let max_bits = opts.max_grid_bits.clamp(1, MAX_GRID_BITS);
    let min_bits = opts.min_grid_bits.clamp(1, max_bits);
    let cells = |bits: u8| ((1u64 << bits) - 1) as f64;
    let finest = extent / cells(max_bits);
    let coarsest = extent / cells(min_bits);
    let wanted = match super::spz2::median_smallest_scale(scales) {
        Some(m) if opts.scale_divisor > 0.0 => m / f64::from(opts.scale_divisor),
        _ => finest,
    };
    let mut step = wanted.clamp(finest, coarsest.max(finest)) as f32;
    if !(step > 0.0 && step.is_finite()) {
        step = 1.0;
    }
    // The f32 step may round below the extent's need: grow it until every cell fits.
    while (extent / f64::from(step)).round() > cells(max_bits) {
        step = f32::from_bits(step.to_bits() + 1);
    }
    let bits = (1..=MAX_GRID_BITS)
        .find(|&b| (extent / f64::from(step)).round() <= cells(b))
        .unwrap_or(MAX_GRID_BITS);
    Grid {
        origin: lo,
        step,
        bits,
    }
}

impl Grid {
    fn cell(&self, p: [f32; 3]) -> [u32; 3] {
        let top = ((1u64 << self.bits) - 1) as f64;
        [0, 1, 2].map(|a| {
            let t = f64::from(p[a] - self.origin[a]) / f64::from(self.step);
            t.round().clamp(0.0, top) as u32
        })
    }

    fn position(&self, c: (u32, u32, u32)) -> [f32; 3] {
        let c = [c.0, c.1, c.2];
        [0, 1, 2].map(|a| self.origin[a] + c[a] as f32 * self.step)
    }
}

/// A codebook: sorted entries, stored as a table or, when they are evenly spaced, as the first
/// entry and the step (entry `i` is `first + i * step` in f32 arithmetic).
#[derive(Debug, Clone, PartialEq)]
pub struct Book {
    /// The entries, ascending.
    pub entries: Vec<f32>,
    /// `(first, step)` of an evenly spaced book.
    pub uniform: Option<(f32, f32)>,
}

/// Flag of an evenly spaced book in its stored count.
const UNIFORM_FLAG: u16 = 0x8000;

impl Book {
    fn table(entries: Vec<f32>) -> Book {
        Book {
            entries,
            uniform: None,
        }
    }

    fn uniform(first: f32, step: f32, count: usize) -> Book {
        let entries = (0..count).map(|i| first + i as f32 * step).collect();
        Book {
            entries,
            uniform: Some((first, step)),
        }
    }
}

/// The median of `values` (finite, not empty).
fn median(values: &[f32]) -> f32 {
    let mut v = values.to_vec();
    let mid = v.len() / 2;
    *v.select_nth_unstable_by(mid, f32::total_cmp).1
}

/// The codebook for `values` (finite) under `levels`.
pub fn codebook(values: &[f32], levels: Levels) -> Book {
    let (lo, hi) = values
        .iter()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(l, h), &v| {
            (l.min(v), h.max(v))
        });
    if values.is_empty() || lo >= hi {
        return Book::table(vec![if values.is_empty() { 0.0 } else { lo }]);
    }
    let step = match levels {
        Levels::KMeans(k) => {
            return Book::table(kmeans_1d(
                values,
                lo,
                hi,
                usize::from(k).clamp(1, MAX_LEVELS),
            ));
        }
        Levels::Uniform(step) => step,
        Levels::Relative(f) => f * median(values).abs(),
    };
    let span = f64::from(hi) - f64::from(lo);
    let mut step = f64::from(step).max(span / (MAX_LEVELS - 1) as f64) as f32;
    // The f32 step may round below what the span needs: grow it until the top entry reaches hi.
    while f64::from(step) * (MAX_LEVELS - 1) as f64 + f64::from(lo) < f64::from(hi)
        && span / f64::from(step) > (MAX_LEVELS - 1) as f64
    {
        step = f32::from_bits(step.to_bits() + 1);
    }
    let count = ((span / f64::from(step)).ceil() as usize + 1).min(MAX_LEVELS);
    Book::uniform(lo, step, count)
}

/// Lloyd's k-means in one dimension over a 4096-bin histogram of `values` (each bin keeps the
/// sum of its values, so the centroids are exact means), from the values' quantiles.
fn kmeans_1d(values: &[f32], lo: f32, hi: f32, k: usize) -> Vec<f32> {
    let bins_n = (16 * k).max(4096);
    let width = (f64::from(hi) - f64::from(lo)) / bins_n as f64;
    let mut count = vec![0u64; bins_n];
    let mut sum = vec![0f64; bins_n];
    for &v in values {
        let b = ((f64::from(v) - f64::from(lo)) / width)
            .floor()
            .clamp(0.0, (bins_n - 1) as f64) as usize;
        count[b] += 1;
        sum[b] += f64::from(v);
    }
    let bins: Vec<(f64, u64)> = (0..bins_n)
        .filter(|&b| count[b] > 0)
        .map(|b| (sum[b] / count[b] as f64, count[b]))
        .collect();
    if bins.len() <= k {
        return bins.iter().map(|b| b.0 as f32).collect();
    }
    let total: u64 = bins.iter().map(|b| b.1).sum();
    // Quantile initialisation: one centroid per 1/k of the values.
    let mut centres = Vec::with_capacity(k);
    let mut seen = 0u64;
    for &(m, c) in &bins {
        let target = (centres.len() as u64 * 2 + 1) * total / (2 * k as u64);
        seen += c;
        if seen > target && centres.len() < k {
            centres.push(m);
        }
    }
    for _ in 0..12 {
        let mut s = vec![0f64; centres.len()];
        let mut c = vec![0u64; centres.len()];
        let mut j = 0;
        for &(m, n) in &bins {
            while j + 1 < centres.len() && (m - centres[j]).abs() > (m - centres[j + 1]).abs() {
                j += 1;
            }
            s[j] += m * n as f64;
            c[j] += n;
        }
        let next: Vec<f64> = (0..centres.len())
            .filter(|&i| c[i] > 0)
            .map(|i| s[i] / c[i] as f64)
            .collect();
        if next == centres {
            break;
        }
        centres = next;
    }
    centres.iter().map(|&c| c as f32).collect()
}

/// Index of the entry of `book` (sorted) nearest to `v`.
fn nearest(book: &[f32], v: f32) -> u16 {
    let i = book.partition_point(|&e| e < v);
    let best = if i == 0 {
        0
    } else if i >= book.len() {
        book.len() - 1
    } else if (v - book[i - 1]) <= (book[i] - v) {
        i - 1
    } else {
        i
    };
    best as u16
}

/// Bits of an index into a codebook of `len` entries (at least 1).
fn index_bits(len: usize) -> u32 {
    usize::BITS - (len.max(2) - 1).leading_zeros()
}

/// Index models of one codebook-coded channel, one per context: the previous splat's index
/// in that channel, its top `context_bits` bits.
struct IndexModels {
    shift: u32,
    trees: Vec<BitTree>,
}

impl IndexModels {
    fn new(book_len: usize, context_bits: u8) -> Self {
        let bits = index_bits(book_len);
        let ctx = u32::from(context_bits).min(bits);
        IndexModels {
            shift: bits - ctx,
            trees: vec![BitTree::new(bits); 1 << ctx],
        }
    }

    fn tree(&mut self, prev: u16) -> &mut BitTree {
        &mut self.trees[usize::from(prev) >> self.shift]
    }
}

/// Bits of a smallest-three component's value range: `[-1/sqrt 2, 1/sqrt 2]`.
const ROT_RANGE: f32 = std::f32::consts::FRAC_1_SQRT_2;

/// Smallest-three form of a unit quaternion: the largest component's index (made positive) and
/// the other three quantized to `bits`.
fn rotation_symbols(q: [f32; 4], bits: u8) -> (u32, [u32; 3]) {
    let n = q.iter().map(|v| v * v).sum::<f32>().sqrt();
    let q = if n > 0.0 {
        q.map(|v| v / n)
    } else {
        [0.0, 0.0, 0.0, 1.0]
    };
    let big = (0..4).fold(0, |b, i| if q[i].abs() > q[b].abs() { i } else { b });
    let sign = if q[big] < 0.0 { -1.0 } else { 1.0 };
    let top = ((1u32 << bits) - 1) as f32;
    let mut out = [0u32; 3];
    let mut j = 0;
    for (i, v) in q.iter().enumerate() {
        if i != big {
            let t = (v * sign + ROT_RANGE) / (2.0 * ROT_RANGE);
            out[j] = (t * top).round().clamp(0.0, top) as u32;
            j += 1;
        }
    }
    (big as u32, out)
}

fn rotation_of(big: u32, v: [u32; 3], bits: u8) -> [f32; 4] {
    let top = ((1u32 << bits) - 1) as f32;
    let mut q = [0f32; 4];
    let mut j = 0;
    for (i, c) in q.iter_mut().enumerate() {
        if i as u32 != big {
            *c = v[j] as f32 / top * 2.0 * ROT_RANGE - ROT_RANGE;
            j += 1;
        }
    }
    let rest: f32 = q.iter().map(|c| c * c).sum();
    q[big as usize] = (1.0 - rest).max(0.0).sqrt();
    q
}

/// Symbol of an SH coefficient `v` quantized to `bits` over `[-range, range]`.
fn sh_symbol(v: f32, range: f32, bits: u8) -> u32 {
    let top = ((1u32 << bits) - 1) as f32;
    let t = if range > 0.0 {
        (v / range + 1.0) * 0.5
    } else {
        0.5
    };
    (t * top).round().clamp(0.0, top) as u32
}

fn sh_value(s: u32, range: f32, bits: u8) -> f32 {
    let top = ((1u32 << bits) - 1) as f32;
    (s as f32 / top * 2.0 - 1.0) * range
}

/// The tile's splats in payload order: Morton order of their grid cells (ties in input order).
fn payload_order(cells: &[[u32; 3]]) -> Vec<usize> {
    let mut keyed: Vec<(u64, usize)> = cells
        .iter()
        .enumerate()
        .map(|(i, c)| (encode3(c[0], c[1], c[2]), i))
        .collect();
    keyed.sort_unstable();
    keyed.into_iter().map(|(_, i)| i).collect()
}

/// Bits of a Morton delta below its leading one that an adaptive model codes (the rest are
/// coded at probability one half: they are close to uniform).
const TOP_BITS: u32 = 3;

/// Models of the Morton deltas: the delta's bit length given the previous one, and the first
/// bits below its leading one given its length.
struct DeltaModels {
    lengths: Vec<BitTree>,
    tops: Vec<BitTree>,
}

impl DeltaModels {
    fn new() -> Self {
        DeltaModels {
            lengths: vec![BitTree::new(6); 64],
            tops: (0..64u32)
                .map(|len| BitTree::new(len.saturating_sub(1).min(TOP_BITS)))
                .collect(),
        }
    }
}

fn encode_positions(e: &mut Encoder, codes: &[u64]) {
    let mut m = DeltaModels::new();
    let (mut prev, mut prev_len) = (0u64, 0usize);
    for &code in codes {
        let d = code - prev;
        let len = 64 - d.leading_zeros();
        m.lengths[prev_len].encode(e, len);
        if len > 1 {
            let rest = len - 1;
            let t = rest.min(TOP_BITS);
            m.tops[len as usize].encode(e, ((d >> (rest - t)) & ((1 << t) - 1)) as u32);
            e.direct(d & ((1u64 << (rest - t)) - 1), rest - t);
        }
        prev = code;
        prev_len = len as usize;
    }
}

fn decode_positions(d: &mut Decoder<'_>, n: usize, bits: u8) -> Result<Vec<u64>, Truncated> {
    let mut m = DeltaModels::new();
    let limit = 1u64 << (3 * u32::from(bits));
    let (mut prev, mut prev_len) = (0u64, 0usize);
    let mut out = Vec::with_capacity(n);
    for _ in 0..n {
        let len = m.lengths[prev_len].decode(d)?;
        let delta = match len {
            0 => 0,
            1 => 1,
            _ => {
                let rest = len - 1;
                let t = rest.min(TOP_BITS);
                let top = u64::from(m.tops[len as usize].decode(d)?);
                (1u64 << rest) | (top << (rest - t)) | d.direct(rest - t)?
            }
        };
        // A code past the grid decodes as the grid's last code; the validator reports it.
        prev = prev.saturating_add(delta).min(limit - 1);
        prev_len = len as usize;
        out.push(prev);
    }
    Ok(out)
}

/// Writes codebook-coded `symbols` (`channels` per splat, splat-major) with per-channel models
/// selected by the previous splat's index.
fn encode_indices(
    e: &mut Encoder,
    symbols: &[u16],
    channels: usize,
    book_len: usize,
    context_bits: u8,
) {
    let mut models: Vec<IndexModels> = (0..channels)
        .map(|_| IndexModels::new(book_len, context_bits))
        .collect();
    let mut prev = vec![0u16; channels];
    for row in symbols.chunks_exact(channels) {
        for (c, &s) in row.iter().enumerate() {
            models[c].tree(prev[c]).encode(e, u32::from(s));
            prev[c] = s;
        }
    }
}

fn decode_indices(
    d: &mut Decoder<'_>,
    n: usize,
    channels: usize,
    book_len: usize,
    context_bits: u8,
) -> Result<Vec<u16>, Truncated> {
    let mut models: Vec<IndexModels> = (0..channels)
        .map(|_| IndexModels::new(book_len, context_bits))
        .collect();
    let mut prev = vec![0u16; channels];
    let mut out = Vec::with_capacity(n * channels);
    for _ in 0..n {
        for c in 0..channels {
            let s = models[c].tree(prev[c]).decode(d)? as u16;
            out.push(s);
            prev[c] = s;
        }
    }
    Ok(out)
}

/// Writes `(largest index, three values)` rotation symbols.
fn encode_rotations(e: &mut Encoder, rots: &[(u32, [u32; 3])], bits: u8) {
    let mut big = vec![BitTree::new(2); 4];
    let mut vals: Vec<BitTree> = (0..12).map(|_| BitTree::new(u32::from(bits))).collect();
    let mut prev = 0usize;
    for &(b, v) in rots {
        big[prev].encode(e, b);
        for (j, &x) in v.iter().enumerate() {
            vals[b as usize * 3 + j].encode(e, x);
        }
        prev = b as usize;
    }
}

fn decode_rotations(
    d: &mut Decoder<'_>,
    n: usize,
    bits: u8,
) -> Result<Vec<(u32, [u32; 3])>, Truncated> {
    let mut big = vec![BitTree::new(2); 4];
    let mut vals: Vec<BitTree> = (0..12).map(|_| BitTree::new(u32::from(bits))).collect();
    let mut prev = 0usize;
    let mut out = Vec::with_capacity(n);
    for _ in 0..n {
        let b = big[prev].decode(d)?;
        let mut v = [0u32; 3];
        for (j, x) in v.iter_mut().enumerate() {
            *x = vals[b as usize * 3 + j].decode(d)?;
        }
        out.push((b, v));
        prev = b as usize;
    }
    Ok(out)
}

fn sh_bits_of(j: usize, opts_sh1: u8, opts_rest: u8) -> u8 {
    if j < 3 { opts_sh1 } else { opts_rest }.clamp(1, 12)
}

fn put_book(out: &mut Vec<u8>, book: &Book) {
    let n = book.entries.len() as u16;
    match book.uniform {
        Some((first, step)) => {
            out.extend_from_slice(&(n | UNIFORM_FLAG).to_le_bytes());
            out.extend_from_slice(&first.to_le_bytes());
            out.extend_from_slice(&step.to_le_bytes());
        }
        None => {
            out.extend_from_slice(&n.to_le_bytes());
            for v in &book.entries {
                out.extend_from_slice(&v.to_le_bytes());
            }
        }
    }
}

/// Encodes `splats` (positions made relative to `centre`; finite, at least one) as a payload,
/// and the payload's splat order: its splat `j` is the caller's `order[j]`.
pub fn encode_payload(
    splats: &Splats,
    centre: [f64; 3],
    opts: &CodebookOptions,
) -> (Vec<u8>, Vec<usize>) {
    let n = splats.len();
    let degree = splats.sh_degree.min(opts.max_sh_degree);
    let k = sh_rest_count(degree);
    let k_in = splats.rest_per_splat();
    let rel = super::storage_order::relative_f32(splats, centre);
    let grid = grid_of(&rel, &splats.scales, opts);
    let cells: Vec<[u32; 3]> = rel.iter().map(|&p| grid.cell(p)).collect();
    let order = payload_order(&cells);
    let ln_scales: Vec<f32> = splats
        .scales
        .iter()
        .flatten()
        .map(|&s| {
            if opts.linear_scales {
                s.max(0.0)
            } else {
                s.max(1e-30).ln()
            }
        })
        .collect();
    let dc: Vec<f32> = splats.sh0.iter().flatten().copied().collect();
    let scale_book = codebook(&ln_scales, opts.scales);
    let colour_book = codebook(&dc, opts.colours);
    let opacity_book = codebook(&splats.opacities, opts.opacity);
    let sh_range = (0..n)
        .flat_map(|i| splats.sh_rest[i * k_in..i * k_in + k].iter().flatten())
        .fold(0f32, |m, v| m.max(v.abs()));
    let rot_bits = opts.rotation_bits.clamp(2, 12);
    let mut out = Vec::with_capacity(HEADER + 3 * 1026 + n * 12);
    out.extend_from_slice(&MAGIC);
    out.extend_from_slice(&[VERSION, degree, opts.context_bits.min(12), rot_bits]);
    out.extend_from_slice(&(n as u32).to_le_bytes());
    for v in grid.origin.iter().chain([&grid.step]) {
        out.extend_from_slice(&v.to_le_bytes());
    }
    let (sh1, shr) = (
        sh_bits_of(0, opts.sh1_bits, opts.sh_rest_bits),
        sh_bits_of(3, opts.sh1_bits, opts.sh_rest_bits),
    );
    out.extend_from_slice(&[grid.bits, sh1, shr, u8::from(opts.linear_scales)]);
    out.extend_from_slice(&sh_range.to_le_bytes());
    put_book(&mut out, &scale_book);
    put_book(&mut out, &colour_book);
    put_book(&mut out, &opacity_book);
    let (scale_book, colour_book, opacity_book) = (
        scale_book.entries,
        colour_book.entries,
        opacity_book.entries,
    );
    let codes: Vec<u64> = order
        .iter()
        .map(|&i| {
            let c = cells[i];
            encode3(c[0], c[1], c[2])
        })
        .collect();
    let rots: Vec<_> = order
        .iter()
        .map(|&i| rotation_symbols(splats.rotations[i], rot_bits))
        .collect();
    let idx = |book: &[f32], vals: &[f32], ch: usize| -> Vec<u16> {
        order
            .iter()
            .flat_map(|&i| (0..ch).map(move |c| nearest(book, vals[i * ch + c])))
            .collect()
    };
    let ctx = opts.context_bits;
    let section = |f: &dyn Fn(&mut Encoder)| {
        let mut e = Encoder::default();
        f(&mut e);
        e.finish()
    };
    let sections: [Vec<u8>; SECTIONS.len()] = [
        section(&|e| encode_positions(e, &codes)),
        section(&|e| encode_rotations(e, &rots, rot_bits)),
        section(&|e| {
            encode_indices(
                e,
                &idx(&scale_book, &ln_scales, 3),
                3,
                scale_book.len(),
                ctx,
            )
        }),
        section(&|e| encode_indices(e, &idx(&colour_book, &dc, 3), 3, colour_book.len(), ctx)),
        section(&|e| {
            encode_indices(
                e,
                &idx(&opacity_book, &splats.opacities, 1),
                1,
                opacity_book.len(),
                ctx,
            )
        }),
        section(&|e| {
            let mut models: Vec<BitTree> = (0..k)
                .map(|j| BitTree::new(u32::from(sh_bits_of(j, sh1, shr))))
                .collect();
            for &i in &order {
                for (j, t) in splats.sh_rest[i * k_in..i * k_in + k].iter().enumerate() {
                    let bits = sh_bits_of(j, sh1, shr);
                    for &v in t {
                        models[j].encode(e, sh_symbol(v, sh_range, bits));
                    }
                }
            }
        }),
    ];
    for s in &sections {
        out.extend_from_slice(&(s.len() as u32).to_le_bytes());
    }
    for s in &sections {
        out.extend_from_slice(s);
    }
    (out, order)
}

/// The payload's range-coded sections, in order (each its own stream, byte length in the table
/// after the codebooks).
pub const SECTIONS: [&str; 6] = [
    "positions",
    "rotations",
    "scales",
    "colours",
    "opacity",
    "sh",
];

/// The sections of `p` after the codebooks (at `at`): each one's payload offset and bytes.
fn read_sections<'a>(p: &'a [u8], at: &mut usize) -> Result<Vec<(usize, &'a [u8])>, PayloadError> {
    let lens: Vec<(usize, usize)> = SECTIONS
        .iter()
        .map(|name| {
            Ok((
                *at,
                u32::from_le_bytes(take(p, at, &format!("{name} section length"))?) as usize,
            ))
        })
        .collect::<Result<_, PayloadError>>()?;
    let mut out = Vec::with_capacity(SECTIONS.len());
    for (i, (len_at, len)) in lens.into_iter().enumerate() {
        let bytes = p.get(*at..at.saturating_add(len)).ok_or_else(|| {
            err(
                len_at,
                format!(
                    "{} section of {len} bytes runs past the payload's end",
                    SECTIONS[i]
                ),
            )
        })?;
        out.push((*at, bytes));
        *at += len;
    }
    if *at != p.len() {
        return Err(err(
            *at,
            format!("{} bytes after the last section", p.len() - *at),
        ));
    }
    Ok(out)
}

/// Byte size of each section of a payload (in [`SECTIONS`] order).
pub fn section_sizes(p: &[u8]) -> Result<Vec<usize>, PayloadError> {
    read_header(p)?;
    let mut at = HEADER;
    for what in ["scale codebook", "colour codebook", "opacity codebook"] {
        get_book(p, &mut at, what)?;
    }
    Ok(read_sections(p, &mut at)?
        .iter()
        .map(|s| s.1.len())
        .collect())
}

/// Reads a little-endian value of `N` bytes at `at`.
fn take<const N: usize>(p: &[u8], at: &mut usize, what: &str) -> Result<[u8; N], PayloadError> {
    let b = p
        .get(*at..*at + N)
        .ok_or_else(|| err(*at, format!("payload ends inside the {what}")))?;
    *at += N;
    Ok(b.try_into().expect("N bytes"))
}

fn get_book(p: &[u8], at: &mut usize, what: &str) -> Result<Vec<f32>, PayloadError> {
    let start = *at;
    let word = u16::from_le_bytes(take(p, at, what)?);
    let len = usize::from(word & !UNIFORM_FLAG);
    if len == 0 || len > MAX_LEVELS {
        return Err(err(
            start,
            format!("{what} has {len} entries (1..={MAX_LEVELS} allowed)"),
        ));
    }
    if word & UNIFORM_FLAG != 0 {
        let at0 = *at;
        let first = f32::from_le_bytes(take(p, at, what)?);
        let step = f32::from_le_bytes(take(p, at, what)?);
        let book = Book::uniform(first, step, len);
        if !(step >= 0.0 && book.entries.iter().all(|v| v.is_finite())) {
            return Err(err(
                at0,
                format!("{what}: first entry {first}, step {step} (finite, step >= 0)"),
            ));
        }
        return Ok(book.entries);
    }
    (0..len)
        .map(|_| {
            let at0 = *at;
            let v = f32::from_le_bytes(take(p, at, what)?);
            if v.is_finite() {
                Ok(v)
            } else {
                Err(err(at0, format!("{what} entry is not finite")))
            }
        })
        .collect()
}

/// The fixed header of a payload, checked.
struct Header {
    degree: u8,
    context_bits: u8,
    rot_bits: u8,
    count: usize,
    grid: Grid,
    sh1: u8,
    shr: u8,
    sh_range: f32,
    linear_scales: bool,
}

fn read_header(p: &[u8]) -> Result<Header, PayloadError> {
    if p.len() < HEADER {
        return Err(err(
            p.len(),
            format!(
                "payload of {} bytes is shorter than its {HEADER}-byte header",
                p.len()
            ),
        ));
    }
    if p[..4] != MAGIC {
        return Err(err(0, "not a codebook payload (magic is not S2TC)"));
    }
    if p[4] != VERSION {
        return Err(err(
            4,
            format!("version {} (this reader reads {VERSION})", p[4]),
        ));
    }
    let f = |at: usize| f32::from_le_bytes(p[at..at + 4].try_into().expect("4 bytes"));
    let count = u32::from_le_bytes(p[8..12].try_into().expect("4 bytes"));
    // Every splat costs at least about two bits of the stream: a larger count is not a payload.
    let most = (p.len() as u64 * 8).min(u64::from(MAX_SPLATS));
    let h = Header {
        degree: p[5],
        context_bits: p[6],
        rot_bits: p[7],
        count: count as usize,
        grid: Grid {
            origin: [f(12), f(16), f(20)],
            step: f(24),
            bits: p[28],
        },
        sh1: p[29],
        shr: p[30],
        sh_range: f(32),
        linear_scales: p[31] == 1,
    };
    let checks: [(bool, usize, String); 8] = [
        (
            h.degree <= 3,
            5,
            format!("SH degree {} (at most 3)", h.degree),
        ),
        (
            h.context_bits <= 12,
            6,
            format!("{} context bits (at most 12)", h.context_bits),
        ),
        (
            (2..=12).contains(&h.rot_bits),
            7,
            format!("{} rotation bits (2..=12)", h.rot_bits),
        ),
        (
            count >= 1 && u64::from(count) <= most,
            8,
            format!("{count} splats in a {}-byte payload (1..={most})", p.len()),
        ),
        (
            h.grid.origin.iter().all(|v| v.is_finite()),
            12,
            "grid origin is not finite".into(),
        ),
        (
            h.grid.step.is_finite() && h.grid.step > 0.0,
            24,
            format!("grid step {} (finite, > 0)", h.grid.step),
        ),
        (
            (1..=MAX_GRID_BITS).contains(&h.grid.bits),
            28,
            format!("{} grid bits (1..=21)", h.grid.bits),
        ),
        (
            (1..=12).contains(&h.sh1)
                && (1..=12).contains(&h.shr)
                && h.sh_range.is_finite()
                && h.sh_range >= 0.0,
            29,
            "SH bits (1..=12) or range (finite, >= 0) out of bounds".into(),
        ),
    ];
    for (ok, at, what) in checks {
        if !ok {
            return Err(err(at, what));
        }
    }
    if p[31] > 1 {
        return Err(err(
            31,
            format!("scale domain {} (0: natural log, 1: linear)", p[31]),
        ));
    }
    Ok(h)
}

fn lookup(book: &[f32], idx: &[u16], at: usize, what: &str) -> Result<Vec<f32>, PayloadError> {
    idx.iter()
        .map(|&i| {
            book.get(usize::from(i)).copied().ok_or_else(|| {
                err(
                    at,
                    format!("{what} index {i} past its {}-entry codebook", book.len()),
                )
            })
        })
        .collect()
}

/// Decodes a payload into its splats (tile-relative positions, payload order).
pub fn decode_payload(p: &[u8]) -> Result<Splats, PayloadError> {
    let h = read_header(p)?;
    let mut at = HEADER;
    let scale_book = get_book(p, &mut at, "scale codebook")?;
    let colour_book = get_book(p, &mut at, "colour codebook")?;
    let opacity_book = get_book(p, &mut at, "opacity codebook")?;
    let streams = read_sections(p, &mut at)?;
    let n = h.count;
    let cut = |i: usize| {
        let at0 = streams[i].0;
        move |_: Truncated| {
            err(
                at0,
                format!("the {} section ends before its last splat", SECTIONS[i]),
            )
        }
    };
    let dec = |i: usize| Decoder::new(streams[i].1).map_err(cut(i));
    let codes = decode_positions(&mut dec(0)?, n, h.grid.bits).map_err(cut(0))?;
    let rots = decode_rotations(&mut dec(1)?, n, h.rot_bits).map_err(cut(1))?;
    let ctx = h.context_bits;
    let indices = |i: usize, book: &[f32], ch: usize| -> Result<Vec<f32>, PayloadError> {
        let idx = decode_indices(&mut dec(i)?, n, ch, book.len(), ctx).map_err(cut(i))?;
        lookup(book, &idx, streams[i].0, SECTIONS[i])
    };
    let scales = indices(2, &scale_book, 3)?;
    let dc = indices(3, &colour_book, 3)?;
    let alpha = indices(4, &opacity_book, 1)?;
    let k = sh_rest_count(h.degree);
    let mut sh_models: Vec<BitTree> = (0..k)
        .map(|j| BitTree::new(u32::from(sh_bits_of(j, h.sh1, h.shr))))
        .collect();
    let mut sh_rest = Vec::with_capacity(n * k);
    let mut d = dec(5)?;
    for _ in 0..n {
        for (j, m) in sh_models.iter_mut().enumerate() {
            let bits = sh_bits_of(j, h.sh1, h.shr);
            let mut t = [0f32; 3];
            for v in &mut t {
                *v = sh_value(m.decode(&mut d).map_err(cut(5))?, h.sh_range, bits);
            }
            sh_rest.push(t);
        }
    }
    let mut s = Splats::with_capacity(h.degree, n);
    s.positions = codes
        .iter()
        .map(|&c| h.grid.position(decode3(c)).map(f64::from))
        .collect();
    s.rotations = rots
        .iter()
        .map(|&(b, v)| rotation_of(b, v, h.rot_bits))
        .collect();
    let scale = |v: f32| if h.linear_scales { v.max(0.0) } else { v.exp() };
    s.scales = scales
        .chunks_exact(3)
        .map(|c| [scale(c[0]), scale(c[1]), scale(c[2])])
        .collect();
    s.sh0 = dc.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
    s.opacities = alpha.iter().map(|a| a.clamp(0.0, 1.0)).collect();
    s.sh_rest = sh_rest;
    Ok(s)
}

#[cfg(test)]
mod tests {
    use super::*;
    use splat2tiles_core::rng::SplitMix64 as Rng;
    use splat2tiles_core::splat::{Splat, normalize_quat};

    fn scene(n: usize, degree: u8) -> Splats {
        let mut rng = Rng::new(11);
        let mut s = Splats::new(degree);
        for _ in 0..n {
            let q = normalize_quat([0, 1, 2, 3].map(|_| rng.range(-1.0, 1.0) as f32));
            let rest: Vec<[f32; 3]> = (0..sh_rest_count(degree))
                .map(|_| [0; 3].map(|_| rng.range(-0.3, 0.3) as f32))
                .collect();
            s.push(
                Splat {
                    position: [0; 3].map(|_| rng.range(-5.0, 5.0)),
                    scale: [0; 3].map(|_| rng.range(0.01, 0.2) as f32),
                    rotation: q,
                    opacity: rng.f64() as f32,
                    sh0: [0; 3].map(|_| rng.range(-1.5, 1.5) as f32),
                },
                &rest,
            );
        }
        s
    }

    #[test]
    fn every_attribute_comes_back_within_its_quantization() {
        let s = scene(5000, 3);
        let opts = CodebookOptions::default();
        let (p, order) = encode_payload(&s, [1.0, 2.0, 3.0], &opts);
        let d = decode_payload(&p).unwrap();
        assert_eq!(d.len(), s.len());
        assert_eq!(d.sh_degree, 3);
        let h = read_header(&p).unwrap();
        let med = median(&s.scales.iter().flatten().copied().collect::<Vec<_>>());
        for (j, &i) in order.iter().enumerate() {
            for a in 0..3 {
                let want = s.positions[i][a] - [1.0, 2.0, 3.0][a];
                assert!(
                    (d.positions[j][a] - want).abs() <= f64::from(h.grid.step) * 0.51,
                    "position {i}"
                );
                // Evenly spaced, 0.05 of the median scale apart.
                let e = (d.scales[j][a] - s.scales[i][a]).abs();
                assert!(e <= 0.026 * med, "scale {i}: error {e}");
                assert!((d.sh0[j][a] - s.sh0[i][a]).abs() < 0.05, "colour {i}");
            }
            assert!((d.opacities[j] - s.opacities[i]).abs() <= 0.5 / 255.0 + 1e-6);
            let dot: f32 = (0..4).map(|c| d.rotations[j][c] * s.rotations[i][c]).sum();
            assert!(dot.abs() > 0.999, "rotation {i}: |dot| {dot}");
            for (a, b) in d.rest_of(j).iter().zip(s.rest_of(i)) {
                assert!((0..3).all(|c| (a[c] - b[c]).abs() < 0.05), "sh {i}");
            }
        }
    }

    #[test]
    fn degenerate_tiles_round_trip_finite() {
        // One splat; every splat at one point with one scale and colour; a huge extent.
        let one = scene(1, 0);
        let mut same = scene(300, 1);
        for i in 0..same.len() {
            same.positions[i] = [4.0, 4.0, 4.0];
            same.scales[i] = [1e-7, 1e-7, 1e-7];
            same.sh0[i] = [0.25; 3];
        }
        let mut far = scene(300, 0);
        far.positions[0] = [1e7, -1e7, 3e6];
        for s in [one, same, far] {
            let (p, _) = encode_payload(&s, [0.0; 3], &CodebookOptions::default());
            let d = decode_payload(&p).unwrap();
            assert_eq!(d.len(), s.len());
            assert!((0..d.len()).all(|i| d.is_finite(i)));
        }
    }

    #[test]
    fn malformed_payloads_are_errors_with_offsets() {
        let s = scene(2000, 1);
        let (p, _) = encode_payload(&s, [0.0; 3], &CodebookOptions::default());
        let mut bad_magic = p.clone();
        bad_magic[0] = b'X';
        assert_eq!(decode_payload(&bad_magic).unwrap_err().offset, 0);
        let mut huge = p.clone();
        huge[8..12].copy_from_slice(&u32::MAX.to_le_bytes());
        assert_eq!(decode_payload(&huge).unwrap_err().offset, 8);
        let mut nan_step = p.clone();
        nan_step[24..28].copy_from_slice(&f32::NAN.to_le_bytes());
        assert_eq!(decode_payload(&nan_step).unwrap_err().offset, 24);
        let cut = decode_payload(&p[..p.len() - 200]).unwrap_err();
        assert!(cut.what.contains("past the payload"), "{cut}");
        for len in [0, 10, HEADER, HEADER + 1] {
            assert!(decode_payload(&p[..len]).is_err());
        }
    }
}
