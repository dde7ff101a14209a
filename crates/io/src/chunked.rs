//! Chunked input for the out-of-core converter: binary PLY and `.splat` files decoded a bounded
//! number of records at a time, so a pass over a scene holds one chunk, never the whole file.

use rayon::prelude::*;
use std::io::{Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};
use std::sync::Arc;

use super::error::{Ctx, ReadError, ReadErrorKind};
use super::{HEAD_BYTES, InputFormat, Kind, Locator, detect, ply, splat_file};
use splat2tiles_core::splat::Splats;

/// How the records of a chunked input are decoded.
#[derive(Debug, Clone)]
enum Decoder {
    Ply(Arc<ply::BinaryPlan>),
    Splat,
}

/// A scene file read as consecutive chunks of fixed-size records (as many passes as needed).
#[derive(Debug, Clone)]
pub struct ChunkedInput {
    path: PathBuf,
    name: String,
    decoder: Decoder,
    format: InputFormat,
    count: u64,
    start: u64,
    stride: u64,
    sh_degree: u8,
}

/// One chunk of a pass: its first splat's index in the file, the splats, and what decoding noted.
#[derive(Debug)]
pub struct Chunk {
    /// Index of the chunk's first splat in the file.
    pub first: u64,
    /// The decoded splats (file frame, reader conventions; NaN/Inf kept).
    pub splats: Splats,
    /// Quaternions replaced by the identity.
    pub repaired_rotations: usize,
    /// Finite log-scales whose `exp` overflows.
    pub overflowed_scales: usize,
}

impl ChunkedInput {
    /// Opens `path` for chunked reading; `Ok(None)` when the file needs the whole-file reader
    /// (ascii PLY, PLY with list elements or sizes that do not add up, SPZ, pipes), which then
    /// reads it or names what is wrong.
    pub fn open(path: &Path) -> Result<Option<ChunkedInput>, ReadError> {
        let name = path.display().to_string();
        let cx = Ctx {
            name: &name,
            limit: u64::MAX,
        };
        let io_err = |e| cx.whole(ReadErrorKind::Io(e));
        let file = std::fs::File::open(path).map_err(io_err)?;
        let meta = file.metadata().map_err(io_err)?;
        if !meta.is_file() {
            return Ok(None);
        }
        let total = meta.len();
        let mut head = Vec::new();
        file.take(HEAD_BYTES)
            .read_to_end(&mut head)
            .map_err(io_err)?;
        let kind = detect(&cx, &head)?;
        let (decoder, format, count, start, stride, sh_degree) = match kind {
            Kind::Ply => match ply::binary_plan(&cx, &head, total)? {
                Some(p) => {
                    let format = InputFormat::Ply {
                        encoding: p.encoding,
                    };
                    let (count, start, stride, degree) =
                        (p.count, p.start, p.stride as u64, p.degree());
                    (
                        Decoder::Ply(Arc::new(p)),
                        format,
                        count,
                        start,
                        stride,
                        degree,
                    )
                }
                None => return Ok(None),
            },
            Kind::Splat if total > 0 && total % splat_file::RECORD_BYTES as u64 == 0 => (
                Decoder::Splat,
                InputFormat::Splat,
                total / splat_file::RECORD_BYTES as u64,
                0,
                splat_file::RECORD_BYTES as u64,
                0,
            ),
            Kind::Splat | Kind::Spz => return Ok(None),
        };
        Ok(Some(ChunkedInput {
            path: path.to_path_buf(),
            name,
            decoder,
            format,
            count,
            start,
            stride,
            sh_degree,
        }))
    }

    /// Splats in the file.
    pub fn len(&self) -> u64 {
        self.count
    }

    /// Whether the file holds no splat.
    pub fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// SH degree of the splats.
    pub fn sh_degree(&self) -> u8 {
        self.sh_degree
    }

    /// The file's format.
    pub fn format(&self) -> InputFormat {
        self.format
    }

    /// Where splat `i` sits in the file (for messages about bad splats).
    pub fn locator(&self) -> Locator {
        Locator::Records {
            start: self.start,
            stride: self.stride,
        }
    }

    /// Bytes of one record in the file.
    pub fn record_bytes(&self) -> u64 {
        self.stride
    }

    /// One pass over the file: `f` gets consecutive chunks of at most `records` splats, in
    /// file order (each block read is decoded in one piece per thread). Stops at the first
    /// error `f` returns.
    pub fn for_each_chunk<E: From<ReadError>>(
        &self,
        records: usize,
        mut f: impl FnMut(Chunk) -> Result<(), E>,
    ) -> Result<(), E> {
        let stride = self.stride as usize;
        let per = records.div_ceil(rayon::current_num_threads()).max(1) * stride;
        self.for_each_block(records, |first, bytes| {
            let pieces: Vec<(Splats, usize, usize)> = bytes
                .par_chunks(per)
                .map(|b| self.decode_counted(b))
                .collect();
            let mut at = first;
            for (b, (splats, repaired, overflowed)) in bytes.chunks(per).zip(pieces) {
                f(Chunk {
                    first: at,
                    splats,
                    repaired_rotations: repaired,
                    overflowed_scales: overflowed,
                })?;
                at += (b.len() / stride) as u64;
            }
            Ok(())
        })
    }

    /// One pass over the file's undecoded records: `f` gets the index of each block's first
    /// record and at most `records` whole records (decode them with [`ChunkedInput::decode`]).
    pub fn for_each_block<E: From<ReadError>>(
        &self,
        records: usize,
        mut f: impl FnMut(u64, &[u8]) -> Result<(), E>,
    ) -> Result<(), E> {
        let cx = Ctx {
            name: &self.name,
            limit: u64::MAX,
        };
        let io_err = |e| cx.whole(ReadErrorKind::Io(e));
        let mut file = std::fs::File::open(&self.path).map_err(io_err)?;
        file.seek(SeekFrom::Start(self.start)).map_err(io_err)?;
        let records = records.max(1) as u64;
        let mut buf = vec![0u8; (records * self.stride) as usize];
        let mut first = 0u64;
        while first < self.count {
            let n = records.min(self.count - first);
            let bytes = &mut buf[..(n * self.stride) as usize];
            file.read_exact(bytes).map_err(|e| {
                cx.at(
                    self.start + first * self.stride,
                    ReadErrorKind::Io(std::io::Error::new(
                        e.kind(),
                        format!("the file changed while it was read: {e}"),
                    )),
                )
            })?;
            f(first, bytes)?;
            first += n;
        }
        Ok(())
    }

    /// Decodes whole records of this file (a multiple of [`ChunkedInput::record_bytes`]) exactly
    /// as a pass does.
    pub fn decode(&self, recs: &[u8]) -> Splats {
        self.decode_counted(recs).0
    }

    /// Appends to `out` the centres of this file's records that start every `step` bytes of
    /// `recs` (`step` at least [`ChunkedInput::record_bytes`]; other bytes may sit between
    /// records): the positions [`ChunkedInput::decode`] gives, the other fields undecoded.
    pub fn decode_positions(&self, recs: &[u8], step: usize, out: &mut Vec<[f64; 3]>) {
        match &self.decoder {
            Decoder::Ply(p) => ply::decode_positions(p, recs, step, out),
            Decoder::Splat => splat_file::decode_positions(recs, step, out),
        }
    }

    fn decode_counted(&self, recs: &[u8]) -> (Splats, usize, usize) {
        match &self.decoder {
            Decoder::Ply(p) => ply::decode_chunk(p, recs),
            Decoder::Splat => {
                let (s, r) = splat_file::decode_chunk(recs);
                (s, r, 0)
            }
        }
    }
}
