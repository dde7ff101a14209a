//! Files of a sharded conversion (`plan`, `part`, `merge`): exact number encoding, bounded JSON
//! reading with errors naming the file and byte offset, and atomic single-file writes.
//!
//! Floats travel as the hex of their bits, so a plan or part file read back gives the very
//! values the single-machine conversion computes (decimal JSON may round the last bit).

use super::ConvertError;
use serde::de::DeserializeOwned;
use serde::{Deserialize, Deserializer, Serialize, Serializer};
use splat2tiles_tiles::tiling::TileKey;
use std::path::Path;

/// An `f64` stored exactly, as the 16 hex digits of its bits.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct F(pub(super) f64);

impl Serialize for F {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(&format!("{:016x}", self.0.to_bits()))
    }
}

impl<'de> Deserialize<'de> for F {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<F, D::Error> {
        let s = String::deserialize(d)?;
        if s.len() != 16 {
            return Err(serde::de::Error::custom(format!(
                "'{s}': expected 16 hex digits (the bits of a float)"
            )));
        }
        u64::from_str_radix(&s, 16)
            .map(|b| F(f64::from_bits(b)))
            .map_err(|_| serde::de::Error::custom(format!("'{s}': not hex digits")))
    }
}

/// Three exact floats.
pub(super) fn f3(v: glam::DVec3) -> [F; 3] {
    [F(v.x), F(v.y), F(v.z)]
}

/// Back from [`f3`].
pub(super) fn v3(a: &[F; 3]) -> glam::DVec3 {
    glam::DVec3::new(a[0].0, a[1].0, a[2].0)
}

/// A tile key as `[level, x, y, z]`.
pub(super) fn key_arr(k: TileKey) -> [u32; 4] {
    [k.level, k.x, k.y, k.z]
}

/// Back from [`key_arr`]: `None` when the coordinates do not fit the level (or the level is
/// deeper than `max_level`).
pub(super) fn arr_key(a: [u32; 4], max_level: u32, octree: bool) -> Option<TileKey> {
    let [level, x, y, z] = a;
    let fits = |c: u32| level >= 32 || (c as u64) < (1u64 << level);
    (level <= max_level
        && level < 32
        && fits(x)
        && fits(y)
        && (if octree { fits(z) } else { z == 0 }))
    .then_some(TileKey { level, x, y, z })
}

/// 64-bit FNV-1a of `bytes` as hex: names a plan in the files derived from it.
pub(super) fn digest(bytes: &[u8]) -> String {
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    for b in bytes {
        h ^= *b as u64;
        h = h.wrapping_mul(0x0100_0000_01b3);
    }
    format!("{h:016x}")
}

/// A bad file of a sharded conversion: its path, and the byte offset when one is known.
pub(super) fn bad(path: &Path, offset: Option<u64>, why: impl std::fmt::Display) -> ConvertError {
    ConvertError::Output {
        path: path.to_path_buf(),
        why: match offset {
            Some(o) => format!("byte {o}: {why}"),
            None => why.to_string(),
        },
    }
}

/// Reads at most `limit` bytes of `path` through `splat2tiles_io::read_file` (a regular file
/// only; a longer file is refused before it is read), with its errors as [`ConvertError`]s.
pub(super) fn read_bounded(path: &Path, limit: u64) -> Result<Vec<u8>, ConvertError> {
    use splat2tiles_io::BoundedReadError as E;
    let kind = splat2tiles_io::FileKind::new("such a file", limit);
    splat2tiles_io::read_file(path, kind).map_err(|e| match e {
        E::Io { source, .. } => super::io_err(path, "reading")(source),
        E::TooLarge { size, limit, .. } => bad(
            path,
            None,
            format!("{size} bytes, more than the {limit} such a file may have"),
        ),
        E::NotRegular { .. } => bad(
            path,
            None,
            "not a regular file (only regular files are read)",
        ),
        E::OutOfMemory { size, .. } => bad(
            path,
            None,
            format!("cannot reserve {size} bytes of memory to read it"),
        ),
        other => bad(path, None, other),
    })
}

/// Parses JSON `bytes` read from `path`; errors name the byte offset.
pub(super) fn parse<T: DeserializeOwned>(path: &Path, bytes: &[u8]) -> Result<T, ConvertError> {
    serde_json::from_slice(bytes).map_err(|e| {
        let offset = byte_offset(bytes, e.line(), e.column());
        bad(path, Some(offset), e)
    })
}

/// The byte offset of a 1-based line and column (serde_json's error position).
fn byte_offset(bytes: &[u8], line: usize, column: usize) -> u64 {
    let mut at = 0usize;
    for _ in 1..line {
        match bytes[at..].iter().position(|b| *b == b'\n') {
            Some(p) => at += p + 1,
            None => break,
        }
    }
    (at + column.saturating_sub(1)).min(bytes.len()) as u64
}

/// Writes `bytes` to `path` through a temporary file beside it renamed into place, so the file
/// is either the old one or the whole new one.
pub(super) fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), ConvertError> {
    let name = path
        .file_name()
        .ok_or_else(|| bad(path, None, "must name a file"))?
        .to_string_lossy()
        .into_owned();
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => std::path::PathBuf::from("."),
    };
    let tmp = dir.join(format!(".{name}.tmp-{}", std::process::id()));
    let write = || -> std::io::Result<()> {
        use std::io::Write;
        std::fs::create_dir_all(&dir)?;
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    };
    write().map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        ConvertError::Io {
            path: path.to_path_buf(),
            what: "writing",
            source: e,
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn floats_round_trip_bit_for_bit() {
        for x in [0.1f64, -0.0, 1e-308, f64::MAX, 1.0 / 3.0, 6378137.123456789] {
            let j = serde_json::to_string(&F(x)).unwrap();
            let back: F = serde_json::from_str(&j).unwrap();
            assert_eq!(back.0.to_bits(), x.to_bits());
        }
        assert!(serde_json::from_str::<F>("\"12\"").is_err());
        assert!(serde_json::from_str::<F>("\"zzzzzzzzzzzzzzzz\"").is_err());
    }

    #[test]
    fn parse_errors_name_the_byte_offset() {
        let bytes = b"{\n  \"a\": 1,\n  \"b\": x\n}";
        let e = parse::<serde_json::Value>(Path::new("p.json"), bytes).unwrap_err();
        let msg = e.to_string();
        assert!(msg.starts_with("p.json: byte 19:"), "{msg}");
        assert_eq!(bytes[19], b'x');
    }

    #[test]
    fn keys_are_checked_against_their_level() {
        assert!(arr_key([2, 3, 3, 0], 16, false).is_some());
        assert!(arr_key([2, 4, 0, 0], 16, false).is_none());
        assert!(arr_key([2, 0, 0, 1], 16, false).is_none());
        assert!(arr_key([2, 0, 0, 1], 16, true).is_some());
        assert!(arr_key([17, 0, 0, 0], 16, true).is_none());
    }
}
