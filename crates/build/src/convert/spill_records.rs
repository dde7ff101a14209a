//! Spill records: the byte layout of a splat in a staging file (the wide [`Codec`], or the
//! input's own record plus its index) and reading such files back in bounded chunks.

use super::ConvertError;
use super::source::{Batch, Input, Recs};
use rayon::prelude::*;
use splat2tiles_core::splat::Splats;
use splat2tiles_io::ChunkedInput;
use std::io::{BufReader, Read, Write};
use std::path::Path;

/// Byte layout of one spilled splat: u64 index among the finite input, f64 centre, f32 scale,
/// rotation, opacity, DC colour and the higher SH, little-endian.
#[derive(Debug, Clone, Copy)]
pub(super) struct Codec {
    degree: u8,
    rest: usize,
}

impl Codec {
    /// The codec for splats of SH degree `degree`.
    pub(super) fn new(degree: u8) -> Codec {
        Codec {
            degree,
            rest: splat2tiles_core::splat::sh_rest_count(degree),
        }
    }

    /// SH degree of the records.
    pub(super) fn degree(&self) -> u8 {
        self.degree
    }

    /// Bytes of one record.
    pub(super) fn record_bytes(&self) -> usize {
        8 + 24 + 12 + 16 + 4 + 12 + 12 * self.rest
    }

    /// Appends splat `i` of `s` with input index `idx` to `out`.
    pub(super) fn encode(&self, s: &Splats, i: usize, idx: u64, out: &mut Vec<u8>) {
        out.extend_from_slice(&idx.to_le_bytes());
        for v in s.positions[i] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        let f32s = s.scales[i]
            .iter()
            .chain(&s.rotations[i])
            .chain(std::iter::once(&s.opacities[i]))
            .chain(&s.sh0[i])
            .chain(s.rest_of(i).iter().flatten());
        for v in f32s {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }

    /// Decodes whole records of `bytes`, appending to `s` and `idx`.
    pub(super) fn decode(&self, bytes: &[u8], s: &mut Splats, idx: &mut Vec<u64>) {
        let rb = self.record_bytes();
        let f = |r: &[u8], k: usize| f32::from_le_bytes(r[k..k + 4].try_into().expect("4 bytes"));
        let d = |r: &[u8], k: usize| f64::from_le_bytes(r[k..k + 8].try_into().expect("8 bytes"));
        for r in bytes.chunks_exact(rb) {
            idx.push(u64::from_le_bytes(r[..8].try_into().expect("8 bytes")));
            s.positions.push([d(r, 8), d(r, 16), d(r, 24)]);
            s.scales.push([f(r, 32), f(r, 36), f(r, 40)]);
            s.rotations.push([f(r, 44), f(r, 48), f(r, 52), f(r, 56)]);
            s.opacities.push(f(r, 60));
            s.sh0.push([f(r, 64), f(r, 68), f(r, 72)]);
            for j in 0..self.rest {
                let k = 76 + 12 * j;
                s.sh_rest.push([f(r, k), f(r, k + 4), f(r, k + 8)]);
            }
        }
    }

    /// Writes every splat of `s` (indices `idx`) to `w`.
    pub(super) fn write_all(
        &self,
        s: &Splats,
        idx: &[u64],
        w: &mut impl Write,
    ) -> std::io::Result<()> {
        let mut buf = Vec::with_capacity(self.record_bytes() * 4096);
        for (i, &x) in idx.iter().enumerate() {
            self.encode(s, i, x, &mut buf);
            if buf.len() >= self.record_bytes() * 4096 {
                w.write_all(&buf)?;
                buf.clear();
            }
        }
        w.write_all(&buf)
    }

    /// One pass over a spill file in chunks of at most `records` splats.
    pub(super) fn for_each_chunk(
        &self,
        path: &Path,
        records: usize,
        mut f: impl FnMut(&Splats, &[u64]) -> Result<(), ConvertError>,
    ) -> Result<(), ConvertError> {
        let rb = self.record_bytes();
        read_records(path, rb, records, |bytes| {
            let mut s = Splats::with_capacity(self.degree, bytes.len() / rb);
            let mut idx = Vec::with_capacity(bytes.len() / rb);
            self.decode(bytes, &mut s, &mut idx);
            f(&s, &idx)
        })
    }
}

/// Reads until `buf` is full or the input ends; returns the bytes read.
fn read_full(r: &mut impl Read, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut n = 0;
    while n < buf.len() {
        match r.read(&mut buf[n..]) {
            Ok(0) => break,
            Ok(k) => n += k,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(n)
}

/// What a spill file holds per splat: the wide record of [`Codec`], or the input file's own
/// record followed by the u64 index (lossless: decoding it again gives the same splat, and
/// `.splat` records are 40 bytes where the wide one is 76).
#[derive(Debug, Clone)]
pub(super) enum SpillFormat {
    /// [`Codec`] records.
    Wide(Codec),
    /// The input's records (decoded by the input's own decoder), then the index.
    Raw(ChunkedInput),
}

impl SpillFormat {
    /// The format for `input`: its own records when they are smaller than the wide ones.
    pub(super) fn for_input(input: &Input) -> SpillFormat {
        let wide = Codec::new(input.sh_degree());
        match input.raw_records(wide.record_bytes()) {
            Some(c) => SpillFormat::Raw(c.clone()),
            None => SpillFormat::Wide(wide),
        }
    }

    /// Whether records are the input's own.
    pub(super) fn is_raw(&self) -> bool {
        matches!(self, SpillFormat::Raw(_))
    }

    /// Bytes of one record.
    pub(super) fn record_bytes(&self) -> usize {
        match self {
            SpillFormat::Wide(c) => c.record_bytes(),
            SpillFormat::Raw(c) => c.record_bytes() as usize + 8,
        }
    }

    /// SH degree of the splats.
    fn degree(&self) -> u8 {
        match self {
            SpillFormat::Wide(c) => c.degree(),
            SpillFormat::Raw(c) => c.sh_degree(),
        }
    }

    /// Appends the record of splat `i` of `b` to `out`.
    pub(super) fn encode(&self, b: &Batch<'_>, i: usize, out: &mut Vec<u8>) {
        match (&b.recs, self) {
            (Recs::Splats(s), SpillFormat::Wide(c)) => c.encode(s, i, b.idx[i], out),
            (recs, _) => {
                // Raw batches come only from raw inputs and raw files (see `Spiller::feed`).
                debug_assert!(self.is_raw());
                out.extend_from_slice(recs.raw(i).unwrap_or_default());
                out.extend_from_slice(&b.idx[i].to_le_bytes());
            }
        }
    }

    /// One pass over a spill file as batches of at most `records` (raw records: only the
    /// centres decoded).
    pub(super) fn for_each_batch(
        &self,
        path: &Path,
        records: usize,
        mut f: impl FnMut(Batch<'_>) -> Result<(), ConvertError>,
    ) -> Result<(), ConvertError> {
        match self {
            SpillFormat::Wide(c) => c.for_each_chunk(path, records, |s, idx| {
                f(Batch {
                    positions: &s.positions,
                    idx,
                    recs: Recs::Splats(s),
                })
            }),
            SpillFormat::Raw(c) => {
                let stride = c.record_bytes() as usize;
                let step = stride + 8;
                let mut positions = Vec::with_capacity(records);
                let mut idx = Vec::with_capacity(records);
                read_records(path, step, records, |bytes| {
                    positions.clear();
                    c.decode_positions(bytes, step, &mut positions);
                    idx.clear();
                    idx.extend(bytes.chunks_exact(step).map(|r| u64_at(r, stride)));
                    f(Batch {
                        positions: &positions,
                        idx: &idx,
                        recs: Recs::Raw {
                            bytes,
                            step,
                            stride,
                            sel: None,
                        },
                    })
                })
            }
        }
    }

    /// One pass over a spill file, decoded whole, in chunks of at most `records` splats.
    pub(super) fn for_each_chunk(
        &self,
        path: &Path,
        records: usize,
        mut f: impl FnMut(&Splats, &[u64]) -> Result<(), ConvertError>,
    ) -> Result<(), ConvertError> {
        match self {
            SpillFormat::Wide(c) => c.for_each_chunk(path, records, f),
            SpillFormat::Raw(c) => {
                let stride = c.record_bytes() as usize;
                let step = stride + 8;
                // Each chunk is decoded in one piece per thread (decoding is most of a reread).
                let per = records.div_ceil(rayon::current_num_threads()).max(1);
                read_records(path, step, records, |bytes| {
                    let pieces: Vec<(Splats, Vec<u64>)> = bytes
                        .par_chunks(per * step)
                        .map(|b| {
                            let mut packed = Vec::with_capacity(b.len() / step * stride);
                            let mut idx = Vec::with_capacity(b.len() / step);
                            for r in b.chunks_exact(step) {
                                packed.extend_from_slice(&r[..stride]);
                                idx.push(u64_at(r, stride));
                            }
                            (c.decode(&packed), idx)
                        })
                        .collect();
                    for (s, idx) in &pieces {
                        f(s, idx)?;
                    }
                    Ok(())
                })
            }
        }
    }

    /// Reads a whole spill file of `count` splats.
    pub(super) fn load(&self, path: &Path, count: u64) -> Result<(Splats, Vec<u64>), ConvertError> {
        let mut s = Splats::with_capacity(self.degree(), count as usize);
        let mut idx = Vec::with_capacity(count as usize);
        self.for_each_chunk(path, 65_536, |c, i| {
            crate::lod::append(&mut s, c);
            idx.extend_from_slice(i);
            Ok(())
        })?;
        Ok((s, idx))
    }
}

fn u64_at(r: &[u8], k: usize) -> u64 {
    u64::from_le_bytes(r[k..k + 8].try_into().expect("8 bytes"))
}

/// One pass over a file of `step`-byte records: `f` gets at most `records` whole records at a
/// time (a trailing partial record is ignored).
fn read_records(
    path: &Path,
    step: usize,
    records: usize,
    mut f: impl FnMut(&[u8]) -> Result<(), ConvertError>,
) -> Result<(), ConvertError> {
    let file = std::fs::File::open(path).map_err(super::io_err(path, "reading spill file"))?;
    let mut r = BufReader::with_capacity(1 << 20, file);
    let mut buf = vec![0u8; step * records.max(1)];
    loop {
        let n = read_full(&mut r, &mut buf).map_err(super::io_err(path, "reading spill file"))?;
        if n >= step {
            f(&buf[..n - n % step])?;
        }
        if n < buf.len() {
            return Ok(());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use splat2tiles_core::splat::Splat;

    #[test]
    fn records_round_trip_bit_for_bit() {
        for degree in [0u8, 1, 3] {
            let mut s = Splats::new(degree);
            let rest: Vec<[f32; 3]> = (0..splat2tiles_core::splat::sh_rest_count(degree))
                .map(|j| [j as f32, -0.5, 1e-30])
                .collect();
            for i in 0..5 {
                s.push(
                    Splat {
                        position: [1e7 + i as f64 * 0.1, -3.25, f64::MIN_POSITIVE],
                        scale: [0.1, 0.2, 0.3],
                        rotation: [0.0, 0.6, 0.0, 0.8],
                        opacity: 0.5,
                        sh0: [i as f32, 2.0, -1.0],
                    },
                    &rest,
                );
            }
            let codec = Codec::new(degree);
            let mut bytes = Vec::new();
            codec.write_all(&s, &[9, 8, 7, 6, 5], &mut bytes).unwrap();
            assert_eq!(bytes.len(), 5 * codec.record_bytes());
            let (mut back, mut idx) = (Splats::new(degree), Vec::new());
            codec.decode(&bytes, &mut back, &mut idx);
            assert_eq!(back, s);
            assert_eq!(idx, [9, 8, 7, 6, 5]);
        }
        assert_eq!(Codec::new(0).record_bytes(), 76);
        assert_eq!(Codec::new(3).record_bytes(), 256);
    }
}
