//! Scene input and output: detects the format (magic bytes first, extension second) and reads
//! trainer PLY (ascii, binary LE/BE), antimatter15 `.splat` and Niantic SPZ v2-v4 into `Splats`.
//!
//! Readers produce the conventions of `ARCHITECTURE.md` (linear scales, post-sigmoid opacity,
//! unit x,y,z,w quaternions, SH in glTF order), keep positions in the file's own frame, keep
//! NaN/Inf (except in quaternions, which become the identity and are counted), and never panic or
//! allocate beyond what the input size justifies. Errors print `FILE: byte N: what is wrong`.
//! Trailing bytes after the declared data are an error, not a warning.

pub mod bounded;
mod chunked;
mod error;
pub mod limits;
mod ply;
mod ply_header;
mod ply_write;
mod splat_file;
mod splat_write;
pub mod spz;
mod whole_file;

pub use spz::MAX_SPZ_POINTS;

use std::fmt;
use std::path::Path;

use crate::limits::MemoryLimit;
use splat2tiles_core::splat::Splats;

pub use bounded::{BoundedReadError, FileKind, read_file, read_text};
pub use chunked::{Chunk, ChunkedInput};
pub use error::{Location, ReadError, ReadErrorKind};
pub use ply_write::{PlyWriter, write_ply};
pub use splat_write::write_splat_records;
pub use whole_file::{destination, write_at, write_whole};

/// The text encoding of a PLY body.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PlyEncoding {
    /// `format ascii 1.0`.
    Ascii,
    /// `format binary_little_endian 1.0`.
    BinaryLittleEndian,
    /// `format binary_big_endian 1.0`.
    BinaryBigEndian,
}

/// The kind of file a scene came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum InputFormat {
    /// A trainer (INRIA-layout) PLY.
    Ply {
        /// Body encoding.
        encoding: PlyEncoding,
    },
    /// An antimatter15 `.splat` (32 bytes per splat).
    Splat,
    /// A Niantic SPZ.
    Spz {
        /// The header's version (2, 3 or 4).
        version: u32,
    },
}

impl InputFormat {
    /// The `--up-axis` a scene of this format usually has: `-y` (COLMAP frame) for PLY and
    /// `.splat`, `+y` for SPZ (stored RUB).
    pub fn default_up_axis(&self) -> &'static str {
        match self {
            InputFormat::Ply { .. } | InputFormat::Splat => "-y",
            InputFormat::Spz { .. } => "+y",
        }
    }
}

impl fmt::Display for InputFormat {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            InputFormat::Ply { encoding } => {
                let e = match encoding {
                    PlyEncoding::Ascii => "ascii",
                    PlyEncoding::BinaryLittleEndian => "binary little endian",
                    PlyEncoding::BinaryBigEndian => "binary big endian",
                };
                write!(f, "PLY ({e})")
            }
            InputFormat::Splat => write!(f, ".splat"),
            InputFormat::Spz { version } => write!(f, "SPZ v{version}"),
        }
    }
}

/// Maps a splat index back to where it sits in the input, for messages about bad splats.
#[derive(Debug, Clone, PartialEq)]
pub enum Locator {
    /// Fixed-size binary records: splat `i` starts at `start + i * stride`.
    Records {
        /// Byte offset of the first record.
        start: u64,
        /// Record size in bytes.
        stride: u64,
    },
    /// Ascii PLY: the 1-based line of each splat.
    Lines(Vec<u64>),
    /// Column-wise compressed data (SPZ): only the index is meaningful.
    Index,
}

impl Locator {
    /// A human location for splat `i`, e.g. `byte 1234`, `line 57` or `splat 12`.
    pub fn describe(&self, i: usize) -> String {
        match self {
            Locator::Records { start, stride } => {
                let off = (i as u64)
                    .checked_mul(*stride)
                    .and_then(|o| o.checked_add(*start));
                match off {
                    Some(o) => format!("byte {o}"),
                    None => format!("splat {i}"),
                }
            }
            Locator::Lines(lines) => match lines.get(i) {
                Some(l) => format!("line {l}"),
                None => format!("splat {i}"),
            },
            Locator::Index => format!("splat {i}"),
        }
    }
}

/// A scene as read from one file.
#[derive(Debug, Clone)]
pub struct Scene {
    /// The Gaussians, in the file's own frame.
    pub splats: Splats,
    /// What the file was.
    pub format: InputFormat,
    /// Where each splat came from.
    pub locator: Locator,
    /// Quaternions that were zero or non-finite and were replaced by the identity.
    pub repaired_rotations: usize,
    /// Splats whose log-scales are finite in the file but too large for `exp` in f32 (their
    /// linear scale is infinite): named separately so reports do not blame the file for NaN/Inf.
    pub overflowed_scales: usize,
}

/// Reads a scene file under the machine's default memory limit; the path is what errors print.
pub fn read_path(path: &Path) -> Result<Scene, ReadError> {
    read_path_limited(path, MemoryLimit::machine_default().bytes())
}

/// Longest prefix read before the format and the declared size are checked (a PLY header is at
/// most [`ply_header::MAX_HEADER_BYTES`]).
const HEAD_BYTES: u64 = 1 << 20;

/// Reads a scene file, refusing before allocating when converting it would take more than
/// `limit` bytes: the magic bytes and the declared size (PLY header, `.splat` length) are checked
/// on a bounded prefix first, and no more than `limit` bytes are ever read (devices and pipes
/// included).
pub fn read_path_limited(path: &Path, limit: u64) -> Result<Scene, ReadError> {
    use std::io::Read;
    let name = path.display().to_string();
    let cx = error::Ctx { name: &name, limit };
    let io_err = |e| cx.whole(ReadErrorKind::Io(e));
    let file = std::fs::File::open(path).map_err(io_err)?;
    let meta = file.metadata().map_err(io_err)?;
    if meta.is_dir() {
        return Err(cx.whole(ReadErrorKind::Io(std::io::Error::new(
            std::io::ErrorKind::IsADirectory,
            "is a folder, not a scene file",
        ))));
    }
    // Regular files tell their size; devices and pipes do not (read up to the limit then).
    let known_len = meta.is_file().then_some(meta.len());
    let mut reader = file;
    let mut bytes = Vec::new();
    (&mut reader)
        .take(HEAD_BYTES)
        .read_to_end(&mut bytes)
        .map_err(io_err)?;
    let kind = detect(&cx, &bytes)?;
    let total = known_len.unwrap_or(bytes.len() as u64);
    match kind {
        Kind::Ply => ply_header::check_declared(&cx, &bytes, total)?,
        Kind::Splat => splat_file::check_declared(&cx, total)?,
        // Compressed: the declared count is checked once the header is decompressed.
        Kind::Spz if total > limit => {
            return Err(cx.whole(ReadErrorKind::OverMemoryLimit {
                count: None,
                estimated: total,
                limit,
            }));
        }
        Kind::Spz => {}
    }
    if let Some(len) = known_len {
        bytes.reserve_exact(len.saturating_sub(bytes.len() as u64).min(limit) as usize);
    }
    let room = limit.saturating_sub(bytes.len() as u64).saturating_add(1);
    (&mut reader)
        .take(room)
        .read_to_end(&mut bytes)
        .map_err(io_err)?;
    if bytes.len() as u64 > limit {
        return Err(cx.whole(ReadErrorKind::OverMemoryLimit {
            count: None,
            estimated: bytes.len() as u64,
            limit,
        }));
    }
    read_detected(&cx, kind, &bytes)
}

/// Reads a scene held in memory under the machine's default memory limit; `name` is what errors
/// print and its extension is the fallback for format detection.
pub fn read_bytes(name: &str, bytes: &[u8]) -> Result<Scene, ReadError> {
    read_bytes_limited(name, bytes, MemoryLimit::machine_default().bytes())
}

/// [`read_bytes`] with an explicit memory limit in bytes (declared counts are checked against
/// it before anything is allocated or decompressed).
pub fn read_bytes_limited(name: &str, bytes: &[u8], limit: u64) -> Result<Scene, ReadError> {
    let cx = error::Ctx { name, limit };
    let kind = detect(&cx, bytes)?;
    read_detected(&cx, kind, bytes)
}

/// The reader a file's first bytes (or, without magic bytes, its extension) call for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    Ply,
    Spz,
    Splat,
}

fn read_detected(cx: &error::Ctx, kind: Kind, bytes: &[u8]) -> Result<Scene, ReadError> {
    match kind {
        Kind::Ply => ply::read(cx, bytes),
        Kind::Spz => spz::read(cx, bytes),
        Kind::Splat => splat_file::read(cx, bytes),
    }
}

/// Detects the format from the magic bytes, then the extension (`.splat` has no magic).
fn detect(cx: &error::Ctx, bytes: &[u8]) -> Result<Kind, ReadError> {
    if bytes.is_empty() {
        return Err(cx.whole(ReadErrorKind::Empty));
    }
    if bytes.starts_with(b"ply\n") || bytes.starts_with(b"ply\r\n") {
        return Ok(Kind::Ply);
    }
    if bytes.starts_with(&[0x1f, 0x8b])
        || bytes.starts_with(&spz::ZSTD_MAGIC)
        || bytes.starts_with(&spz::NGSP_MAGIC)
    {
        return Ok(Kind::Spz);
    }
    let ext = Path::new(cx.name)
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase());
    match ext.as_deref() {
        Some("splat") => Ok(Kind::Splat),
        Some("ply") => Err(cx.at(
            0,
            ReadErrorKind::UnknownFormat("a .ply file must start with the line 'ply'".into()),
        )),
        Some("spz") => Err(cx.at(
            0,
            ReadErrorKind::UnknownFormat(
                "a .spz file must start with gzip, zstd or NGSP magic bytes".into(),
            ),
        )),
        _ => {
            let head: Vec<String> = bytes.iter().take(4).map(|b| format!("{b:02x}")).collect();
            Err(cx.at(
                0,
                ReadErrorKind::UnknownFormat(format!(
                    "first bytes {}; expected a PLY, .splat or SPZ file",
                    head.join(" ")
                )),
            ))
        }
    }
}

/// Little-endian u32 at `off` (caller checked the length).
pub(crate) fn le_u32(b: &[u8], off: usize) -> u32 {
    u32::from_le_bytes([b[off], b[off + 1], b[off + 2], b[off + 3]])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn locator_describes() {
        let l = Locator::Records {
            start: 100,
            stride: 32,
        };
        assert_eq!(l.describe(2), "byte 164");
        assert_eq!(Locator::Lines(vec![5, 7]).describe(1), "line 7");
        assert_eq!(Locator::Index.describe(12), "splat 12");
    }

    #[test]
    fn detection_prefers_magic_over_extension() {
        // A PLY named .splat is still read as PLY.
        let ply = b"ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nend_header\n";
        let e = read_bytes("x.splat", ply).unwrap_err();
        assert!(matches!(e.kind(), ReadErrorKind::MissingProperty(_)), "{e}");
        let e = read_bytes("x.bin", b"hello").unwrap_err();
        assert!(matches!(e.kind(), ReadErrorKind::UnknownFormat(_)), "{e}");
        assert_eq!(InputFormat::Splat.default_up_axis(), "-y");
        assert_eq!(InputFormat::Spz { version: 4 }.default_up_axis(), "+y");
    }
}
