//! Chunked input for the out-of-core converter: binary PLY and `.splat` files decoded a bounded
//! number of records at a time, so a pass over a scene holds one chunk, never the whole file.

use rayon::prelude::*;
use std::io::{Read, Seek, SeekFrom};
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

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
    /// The file's first bytes, read when it was opened (passes take records from them).
    head: Arc<Vec<u8>>,
    /// Bytes read from the file so far (by this value and its clones).
    read: Arc<AtomicU64>,
    /// Byte ranges of the file whose bytes passes copy as they read them ([`ChunkedInput::keep`]).
    kept: Arc<Mutex<Vec<Kept>>>,
}

/// One byte range of the file collected as passes read it.
#[derive(Debug)]
struct Kept {
    at: u64,
    bytes: Vec<u8>,
    /// Bytes of the range collected so far (from its start).
    filled: usize,
}

impl Kept {
    /// Copies what continues this range from `bytes`, which sit at file offset `from`.
    fn observe(&mut self, from: u64, bytes: &[u8]) {
        let next = self.at + self.filled as u64;
        let end = from + bytes.len() as u64;
        if self.filled == self.bytes.len() || from > next || end <= next {
            return;
        }
        let n = ((end - next) as usize).min(self.bytes.len() - self.filled);
        let k = (next - from) as usize;
        self.bytes[self.filled..self.filled + n].copy_from_slice(&bytes[k..k + n]);
        self.filled += n;
    }
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
        let read = head.len() as u64;
        let kind = detect(&cx, &head)?;
        let c = Self::from_head(path, kind, head, total)?;
        if let Some(c) = &c {
            c.read.fetch_add(read, Ordering::Relaxed);
        }
        Ok(c)
    }

    /// The chunked input of the file `path` of `total` bytes from its `header` (its bytes
    /// before the first record, as [`ChunkedInput::header`] gives them; none for `.splat`),
    /// without reading the file; `Ok(None)` where [`ChunkedInput::open`] would give `None`.
    /// Passes then read every record from the file.
    pub fn from_header(
        path: &Path,
        header: &[u8],
        total: u64,
    ) -> Result<Option<ChunkedInput>, ReadError> {
        let name = path.display().to_string();
        let cx = Ctx {
            name: &name,
            limit: u64::MAX,
        };
        let kind = if header.is_empty() {
            Kind::Splat
        } else {
            detect(&cx, header)?
        };
        let c = Self::from_head(path, kind, header.to_vec(), total)?;
        if let Some(c) = &c
            && c.start != header.len() as u64
        {
            return Err(cx.at(
                header.len() as u64,
                ReadErrorKind::Io(std::io::Error::other(format!(
                    "the records start at byte {}, not where the given header ends",
                    c.start
                ))),
            ));
        }
        Ok(c)
    }

    fn from_head(
        path: &Path,
        kind: Kind,
        head: Vec<u8>,
        total: u64,
    ) -> Result<Option<ChunkedInput>, ReadError> {
        let name = path.display().to_string();
        let cx = Ctx {
            name: &name,
            limit: u64::MAX,
        };
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
            Kind::Splat if total > 0 && total.is_multiple_of(splat_file::RECORD_BYTES as u64) => (
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
            head: Arc::new(head),
            read: Arc::new(AtomicU64::new(0)),
            kept: Arc::new(Mutex::new(Vec::new())),
        }))
    }

    /// Bytes read from the file so far by this input and its clones (the first bytes read when
    /// it was opened, then what passes read; records that sit in those first bytes are not
    /// read again).
    pub fn bytes_read(&self) -> u64 {
        self.read.load(Ordering::Relaxed)
    }

    /// The file's bytes before its first record, when they were read at open (`None` from
    /// [`ChunkedInput::from_header`] or a header longer than the first bytes read).
    pub fn header(&self) -> Option<&[u8]> {
        self.head.get(..self.start as usize)
    }

    /// Collects the bytes of the file ranges `ranges` (offset, length) as later passes read
    /// them, so they need no read of their own ([`ChunkedInput::kept`]); what was read at open
    /// counts as read.
    pub fn keep(&self, ranges: &[(u64, u64)]) {
        let mut kept = self.kept.lock().expect("kept ranges");
        *kept = ranges
            .iter()
            .map(|&(at, n)| {
                let mut k = Kept {
                    at,
                    bytes: vec![0; n as usize],
                    filled: 0,
                };
                k.observe(0, &self.head);
                k
            })
            .collect();
    }

    /// The bytes of each range given to [`ChunkedInput::keep`]: `Some` when passes read it
    /// whole.
    pub fn kept(&self) -> Vec<Option<Vec<u8>>> {
        let kept = self.kept.lock().expect("kept ranges");
        kept.iter()
            .map(|k| (k.filled == k.bytes.len()).then(|| k.bytes.clone()))
            .collect()
    }

    /// Where the records `range` (record indices) sit in the file: a byte range.
    pub fn byte_range(&self, range: Range<u64>) -> Range<u64> {
        self.start + range.start * self.stride..self.start + range.end * self.stride
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
        f: impl FnMut(u64, &[u8]) -> Result<(), E>,
    ) -> Result<(), E> {
        self.for_each_block_in(0..self.count, records, f)
    }

    /// [`ChunkedInput::for_each_block`] over the records `range` only (record indices, within
    /// the file's).
    pub fn for_each_block_in<E: From<ReadError>>(
        &self,
        range: Range<u64>,
        records: usize,
        mut f: impl FnMut(u64, &[u8]) -> Result<(), E>,
    ) -> Result<(), E> {
        let cx = Ctx {
            name: &self.name,
            limit: u64::MAX,
        };
        let io_err = |e| cx.whole(ReadErrorKind::Io(e));
        let end = range.end.min(self.count);
        let mut first = range.start.min(end);
        let mut file = None;
        let records = records.max(1) as u64;
        let mut buf = vec![0u8; (records.min(end - first).max(1) * self.stride) as usize];
        while first < end {
            let n = records.min(end - first);
            let at = self.start + first * self.stride;
            let bytes = &mut buf[..(n * self.stride) as usize];
            // Records inside the first bytes read at open are taken from them.
            let from_head = (self.head.len() as u64).saturating_sub(at) as usize;
            let from_head = from_head.min(bytes.len());
            if from_head > 0 {
                bytes[..from_head]
                    .copy_from_slice(&self.head[at as usize..at as usize + from_head]);
            }
            if from_head < bytes.len() {
                if file.is_none() {
                    file = Some(std::fs::File::open(&self.path).map_err(io_err)?);
                }
                let fh = file.as_mut().expect("opened");
                let pos = at + from_head as u64;
                fh.seek(SeekFrom::Start(pos)).map_err(io_err)?;
                fh.read_exact(&mut bytes[from_head..]).map_err(|e| {
                    cx.at(
                        pos,
                        ReadErrorKind::Io(std::io::Error::new(
                            e.kind(),
                            format!("the file changed while it was read: {e}"),
                        )),
                    )
                })?;
                self.read
                    .fetch_add((bytes.len() - from_head) as u64, Ordering::Relaxed);
            }
            {
                let mut kept = self.kept.lock().expect("kept ranges");
                for k in kept.iter_mut() {
                    k.observe(at, bytes);
                }
            }
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

#[cfg(test)]
mod tests {
    use super::*;
    use splat2tiles_core::splat::Splat;

    /// A `.splat` file of `n` records; returns its path (in `dir`) and bytes.
    fn splat_file(dir: &Path, n: usize) -> (PathBuf, Vec<u8>) {
        let mut s = Splats::new(0);
        for i in 0..n {
            s.push(
                Splat {
                    position: [i as f64, (i % 7) as f64, -(i as f64)],
                    scale: [0.1; 3],
                    rotation: [0.0, 0.0, 0.0, 1.0],
                    opacity: 0.5,
                    sh0: [0.25; 3],
                },
                &[],
            );
        }
        let mut bytes = Vec::new();
        crate::write_splat_records(&s, &mut bytes).unwrap();
        let path = dir.join("s.splat");
        std::fs::write(&path, &bytes).unwrap();
        (path, bytes)
    }

    /// Passes take the records inside the first bytes from them, so a whole pass reads each
    /// byte of the file once in all; a range pass reads its records only; kept ranges hold the
    /// file's bytes once a pass covered them.
    #[test]
    fn passes_count_what_they_read_and_keep_ranges() {
        let tmp = tempfile::tempdir().unwrap();
        let n = 50_000;
        let (path, bytes) = splat_file(tmp.path(), n);
        let len = bytes.len() as u64;
        let c = ChunkedInput::open(&path).unwrap().unwrap();
        assert_eq!(c.bytes_read(), HEAD_BYTES);
        c.keep(&[(10, 100), (len - 50, 50), (HEAD_BYTES - 5, 10)]);
        let mut seen = Vec::new();
        c.for_each_block(3_000, |first, b| {
            assert_eq!(first * 32, seen.len() as u64);
            seen.extend_from_slice(b);
            Ok::<_, ReadError>(())
        })
        .unwrap();
        assert_eq!(seen, bytes);
        assert_eq!(c.bytes_read(), len, "the first bytes are not read again");
        let kept = c.kept();
        assert_eq!(kept[0].as_deref(), Some(&bytes[10..110]));
        assert_eq!(kept[1].as_deref(), Some(&bytes[len as usize - 50..]));
        assert_eq!(
            kept[2].as_deref(),
            Some(&bytes[HEAD_BYTES as usize - 5..HEAD_BYTES as usize + 5])
        );

        // From the (empty) header: nothing read until a pass, then its range only.
        let r = ChunkedInput::from_header(&path, &[], len).unwrap().unwrap();
        assert_eq!((r.len(), r.bytes_read()), (n as u64, 0));
        r.keep(&[(0, 64), (40_000 * 32 - 8, 16)]);
        let mut got = Vec::new();
        r.for_each_block_in(40_000..45_000, 700, |first, b| {
            assert_eq!(first, 40_000 + got.len() as u64 / 32);
            got.extend_from_slice(b);
            Ok::<_, ReadError>(())
        })
        .unwrap();
        assert_eq!(got, &bytes[40_000 * 32..45_000 * 32]);
        assert_eq!(r.bytes_read(), 5_000 * 32);
        assert_eq!(r.byte_range(40_000..45_000), 40_000 * 32..45_000 * 32);
        // Neither kept range was read whole by that pass.
        assert_eq!(r.kept(), vec![None, None]);
        // A header that is not where the records start is refused.
        assert!(ChunkedInput::from_header(&path, b"ply\n", len).is_err());
    }
}
