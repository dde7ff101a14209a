//! Read stage: the input as a sequence of chunks, either decoded from the file a bounded number
//! of records at a time (binary PLY, `.splat`) or one scene already in memory.
//!
//! Every later pass sees the finite splats only, each with its index among the finite splats
//! of the input (the index map of the report and the tie-break that keeps orders identical).

use super::ConvertError;
use splat2tiles_core::splat::Splats;
use splat2tiles_io::{ChunkedInput, InputFormat, Locator, Scene};

/// Where the splats come from.
#[derive(Debug)]
pub(super) enum Input {
    /// A file decoded in chunks.
    Chunked(ChunkedInput),
    /// A scene held in memory.
    Memory(Scene),
}

/// One raw chunk: the index of its first splat in the input and its splats (NaN/Inf included).
pub(super) struct RawChunk<'a> {
    pub(super) first: u64,
    pub(super) splats: &'a Splats,
    pub(super) repaired_rotations: usize,
    pub(super) overflowed_scales: usize,
}

impl Input {
    /// SH degree of the splats.
    pub(super) fn sh_degree(&self) -> u8 {
        match self {
            Input::Chunked(c) => c.sh_degree(),
            Input::Memory(s) => s.splats.sh_degree,
        }
    }

    /// The input's format.
    pub(super) fn format(&self) -> InputFormat {
        match self {
            Input::Chunked(c) => c.format(),
            Input::Memory(s) => s.format,
        }
    }

    /// Where splat `i` of the input sits.
    pub(super) fn locator(&self) -> Locator {
        match self {
            Input::Chunked(c) => c.locator(),
            Input::Memory(s) => s.locator.clone(),
        }
    }

    /// Splats in the input, NaN/Inf included.
    pub(super) fn len(&self) -> u64 {
        match self {
            Input::Chunked(c) => c.len(),
            Input::Memory(s) => s.splats.len() as u64,
        }
    }

    /// One pass over every splat, chunks of at most `records` (a scene in memory is one chunk).
    pub(super) fn for_each_raw(
        &self,
        records: usize,
        mut f: impl FnMut(RawChunk<'_>) -> Result<(), ConvertError>,
    ) -> Result<(), ConvertError> {
        match self {
            Input::Chunked(c) => c.for_each_chunk(records, |ch| {
                f(RawChunk {
                    first: ch.first,
                    splats: &ch.splats,
                    repaired_rotations: ch.repaired_rotations,
                    overflowed_scales: ch.overflowed_scales,
                })
            }),
            Input::Memory(s) => f(RawChunk {
                first: 0,
                splats: &s.splats,
                repaired_rotations: s.repaired_rotations,
                overflowed_scales: s.overflowed_scales,
            }),
        }
    }

    /// One pass over the finite splats: `f` gets each chunk's finite splats and their indices
    /// among the input's finite splats (increasing).
    pub(super) fn for_each_finite(
        &self,
        records: usize,
        mut f: impl FnMut(&Splats, &[u64]) -> Result<(), ConvertError>,
    ) -> Result<(), ConvertError> {
        let mut next = 0u64;
        self.for_each_raw(records, |ch| {
            let s = ch.splats;
            let keep: Vec<usize> = (0..s.len()).filter(|&i| s.is_finite(i)).collect();
            let idx: Vec<u64> = (next..next + keep.len() as u64).collect();
            next += keep.len() as u64;
            if keep.len() == s.len() {
                f(s, &idx)
            } else {
                f(&s.select(&keep), &idx)
            }
        })
    }
}

/// The spill records of a batch's splats.
pub(super) enum Recs<'a> {
    /// Decoded splats (written with the wide spill codec).
    Splats(&'a Splats),
    /// The input file's own records: splat `i`'s is `bytes[k * step..][..stride]`, where `k` is
    /// `sel[i]` (or `i` without a selection).
    Raw {
        bytes: &'a [u8],
        step: usize,
        stride: usize,
        sel: Option<&'a [usize]>,
    },
}

impl Recs<'_> {
    /// The raw record of splat `i` (`None` for decoded splats).
    pub(super) fn raw(&self, i: usize) -> Option<&[u8]> {
        match self {
            Recs::Splats(_) => None,
            Recs::Raw {
                bytes,
                step,
                stride,
                sel,
            } => {
                let k = sel.map_or(i, |s| s[i]);
                Some(&bytes[k * step..k * step + stride])
            }
        }
    }
}

/// What a routing pass sees of a chunk of finite splats: centres, indices among the input's
/// finite splats (increasing), and their records.
pub(super) struct Batch<'a> {
    pub(super) positions: &'a [[f64; 3]],
    pub(super) idx: &'a [u64],
    pub(super) recs: Recs<'a>,
}

impl Input {
    /// The chunked file when the spill files can hold its own records (`Some` for binary PLY
    /// and `.splat` whose record plus an index is smaller than the wide spill record).
    pub(super) fn raw_records(&self, wide_bytes: usize) -> Option<&ChunkedInput> {
        match self {
            Input::Chunked(c) if (c.record_bytes() as usize) + 8 < wide_bytes => Some(c),
            _ => None,
        }
    }

    /// One pass over the finite splats as batches of at most `records`. With `raw` (from
    /// [`Input::raw_records`]) the records are the file's own and, when `all_finite`, only the
    /// centres are decoded; otherwise the splats are decoded whole.
    pub(super) fn for_each_batch(
        &self,
        records: usize,
        raw: bool,
        all_finite: bool,
        f: impl FnMut(Batch<'_>) -> Result<(), ConvertError>,
    ) -> Result<(), ConvertError> {
        self.for_each_batch_in(0..self.len(), records, raw, all_finite, f)
    }

    /// [`Input::for_each_batch`] over the splats `range` of the file only. A range that does
    /// not start at 0 needs `all_finite` (the indices among the finite splats are then the
    /// file's) and a chunked input; a scene in memory is passed whole.
    pub(super) fn for_each_batch_in(
        &self,
        range: std::ops::Range<u64>,
        records: usize,
        raw: bool,
        all_finite: bool,
        mut f: impl FnMut(Batch<'_>) -> Result<(), ConvertError>,
    ) -> Result<(), ConvertError> {
        let whole = range.start == 0 && range.end >= self.len();
        debug_assert!(whole || all_finite);
        let c = match self {
            Input::Chunked(c) if raw || !whole => c,
            _ => {
                return self.for_each_finite(records, |s, idx| {
                    f(Batch {
                        positions: &s.positions,
                        idx,
                        recs: Recs::Splats(s),
                    })
                });
            }
        };
        let stride = c.record_bytes() as usize;
        let mut positions = Vec::with_capacity(records);
        let mut idx = Vec::with_capacity(records);
        let mut next = range.start;
        let per = records.div_ceil(rayon::current_num_threads()).max(1) * stride;
        c.for_each_block_in(range, records, |_, bytes| {
            if !raw {
                // Decoded whole, one piece per thread (finite: `all_finite` holds here).
                use rayon::prelude::*;
                let pieces: Vec<Splats> = bytes.par_chunks(per).map(|b| c.decode(b)).collect();
                for s in &pieces {
                    idx.clear();
                    idx.extend(next..next + s.len() as u64);
                    next += s.len() as u64;
                    f(Batch {
                        positions: &s.positions,
                        idx: &idx,
                        recs: Recs::Splats(s),
                    })?;
                }
                return Ok(());
            }
            positions.clear();
            idx.clear();
            let keep: Option<Vec<usize>> = if all_finite {
                c.decode_positions(bytes, stride, &mut positions);
                None
            } else {
                let s = c.decode(bytes);
                let keep: Vec<usize> = (0..s.len()).filter(|&i| s.is_finite(i)).collect();
                positions.extend(keep.iter().map(|&i| s.positions[i]));
                Some(keep)
            };
            idx.extend(next..next + positions.len() as u64);
            next += positions.len() as u64;
            f(Batch {
                positions: &positions,
                idx: &idx,
                recs: Recs::Raw {
                    bytes,
                    step: stride,
                    stride,
                    sel: keep.as_deref(),
                },
            })
        })
    }
}
