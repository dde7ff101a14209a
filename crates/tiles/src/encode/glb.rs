//! GLB 2.0 framing (glTF 2.0 sec. 4.4 "Binary glTF Layout"): a 12-byte header, a JSON chunk padded
//! with spaces and an optional BIN chunk padded with zeros; the reader checks every length first.

use super::gltf::Gltf;

/// `glTF` magic, the first four bytes of every glb.
pub const GLB_MAGIC: [u8; 4] = *b"glTF";
/// The only glb container version.
pub const GLB_VERSION: u32 = 2;
/// Chunk type of the JSON chunk (`JSON` little-endian).
pub const CHUNK_JSON: u32 = 0x4E4F_534A;
/// Chunk type of the binary chunk (`BIN\0` little-endian).
pub const CHUNK_BIN: u32 = 0x004E_4942;
const HEADER_LEN: usize = 12;
const CHUNK_HEADER_LEN: usize = 8;

/// Why a glb could not be written or read; every variant names a byte offset or a JSON pointer.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GlbError {
    /// Fewer bytes than a header or chunk header needs.
    #[error("byte {offset}: truncated: {what} needs {needed} bytes, {available} left")]
    Truncated {
        /// Where the structure starts.
        offset: u64,
        /// Which structure.
        what: &'static str,
        /// Bytes it needs.
        needed: u64,
        /// Bytes left in the input.
        available: u64,
    },
    /// The first four bytes are not `glTF`.
    #[error("byte 0: not a glb: magic {found:02x?} is not \"glTF\"")]
    BadMagic {
        /// The four bytes found.
        found: [u8; 4],
    },
    /// The container version is not 2.
    #[error("byte 4: glb version {found} is not supported (only 2)")]
    BadVersion {
        /// Version found.
        found: u32,
    },
    /// The header's total length disagrees with the input size.
    #[error("byte 8: header length {declared} differs from the input size {actual}")]
    LengthMismatch {
        /// Length in the header.
        declared: u64,
        /// Bytes actually given.
        actual: u64,
    },
    /// A chunk's length runs past the end of the glb.
    #[error("byte {offset}: chunk length {length} runs past the end ({available} bytes left)")]
    ChunkPastEnd {
        /// Offset of the chunk header.
        offset: u64,
        /// Declared chunk length.
        length: u64,
        /// Bytes left after the chunk header.
        available: u64,
    },
    /// A chunk has a type that is not allowed where it is.
    #[error("byte {offset}: chunk type {found:#010x} where {expected} was expected")]
    BadChunkType {
        /// Offset of the chunk header.
        offset: u64,
        /// Type found.
        found: u32,
        /// What was expected.
        expected: &'static str,
    },
    /// The JSON chunk does not parse as glTF JSON.
    #[error("byte {offset}: JSON chunk does not parse as glTF: {message}")]
    Json {
        /// Offset of the error in the glb (approximate to the JSON token).
        offset: u64,
        /// The parser's message.
        message: String,
    },
    /// The glTF is well-formed JSON but breaks a rule this reader relies on.
    #[error("{path}: {what}")]
    Invalid {
        /// JSON pointer of the offending value (e.g. `/accessors/3/count`).
        path: String,
        /// What is wrong.
        what: String,
    },
    /// The glTF is valid but uses a feature this reader does not decode.
    #[error("{path}: not supported: {what}")]
    Unsupported {
        /// JSON pointer of the feature.
        path: String,
        /// What it is.
        what: String,
    },
    /// Refused on writing: a tile with no splat.
    #[error("refusing to write a tile without splats")]
    EmptyTile,
    /// Refused on writing: splat `index` holds a NaN or infinite value.
    #[error("splat {index}: non-finite value (JSON min/max and validators cannot carry it)")]
    NonFinite {
        /// Index of the first bad splat.
        index: usize,
    },
    /// Refused on writing: the glb would exceed the 4 GiB container limit.
    #[error("glb of {bytes} bytes exceeds the 4 GiB container limit")]
    TooLarge {
        /// Size that was needed.
        bytes: u64,
    },
}

impl GlbError {
    /// Shorthand for [`GlbError::Invalid`].
    pub fn invalid(path: impl Into<String>, what: impl Into<String>) -> Self {
        GlbError::Invalid {
            path: path.into(),
            what: what.into(),
        }
    }

    /// Shorthand for [`GlbError::Unsupported`].
    pub fn unsupported(path: impl Into<String>, what: impl Into<String>) -> Self {
        GlbError::Unsupported {
            path: path.into(),
            what: what.into(),
        }
    }
}

/// The chunks of a glb, borrowed from the input.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct GlbChunks<'a> {
    /// JSON chunk payload (with its trailing space padding).
    pub json: &'a [u8],
    /// Offset of the JSON payload in the glb.
    pub json_offset: usize,
    /// BIN chunk payload (with its zero padding), if present.
    pub bin: Option<&'a [u8]>,
    /// Offset of the BIN payload in the glb (0 when absent).
    pub bin_offset: usize,
}

fn pad4(n: usize) -> usize {
    (4 - n % 4) % 4
}

/// Frames `json` and an optional `bin` payload as a glb (JSON padded with spaces, BIN with zeros).
pub fn write_glb(json: &[u8], bin: Option<&[u8]>) -> Result<Vec<u8>, GlbError> {
    let json_len = json.len() + pad4(json.len());
    let bin_len = bin.map(|b| b.len() + pad4(b.len()));
    let total = (HEADER_LEN + CHUNK_HEADER_LEN + json_len) as u64
        + bin_len.map_or(0, |l| (CHUNK_HEADER_LEN + l) as u64);
    let total32 = u32::try_from(total).map_err(|_| GlbError::TooLarge { bytes: total })?;
    let mut out = Vec::with_capacity(total as usize);
    out.extend_from_slice(&GLB_MAGIC);
    out.extend_from_slice(&GLB_VERSION.to_le_bytes());
    out.extend_from_slice(&total32.to_le_bytes());
    out.extend_from_slice(&(json_len as u32).to_le_bytes());
    out.extend_from_slice(&CHUNK_JSON.to_le_bytes());
    out.extend_from_slice(json);
    out.resize(out.len() + pad4(json.len()), b' ');
    if let (Some(bin), Some(bin_len)) = (bin, bin_len) {
        out.extend_from_slice(&(bin_len as u32).to_le_bytes());
        out.extend_from_slice(&CHUNK_BIN.to_le_bytes());
        out.extend_from_slice(bin);
        out.resize(out.len() + pad4(bin.len()), 0);
    }
    debug_assert_eq!(out.len() as u64, total);
    Ok(out)
}

/// Serialises `doc` and frames it with `bin` as a glb.
pub fn write_gltf_glb(doc: &Gltf, bin: Option<&[u8]>) -> Result<Vec<u8>, GlbError> {
    let json = serde_json::to_vec(doc).expect("glTF structs always serialise");
    write_glb(&json, bin)
}

fn u32_at(bytes: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([bytes[at], bytes[at + 1], bytes[at + 2], bytes[at + 3]])
}

/// Reads one chunk header at `at`; returns (type, payload range).
fn chunk_at(bytes: &[u8], at: usize) -> Result<(u32, usize, usize), GlbError> {
    let left = bytes.len() - at;
    if left < CHUNK_HEADER_LEN {
        return Err(GlbError::Truncated {
            offset: at as u64,
            what: "chunk header",
            needed: CHUNK_HEADER_LEN as u64,
            available: left as u64,
        });
    }
    let length = u32_at(bytes, at) as usize;
    let kind = u32_at(bytes, at + 4);
    let start = at + CHUNK_HEADER_LEN;
    let available = bytes.len() - start;
    if length > available {
        return Err(GlbError::ChunkPastEnd {
            offset: at as u64,
            length: length as u64,
            available: available as u64,
        });
    }
    Ok((kind, start, start + length))
}

/// Splits a glb into its chunks, checking header, lengths and chunk order; never panics.
///
/// Chunks of unknown type after the JSON chunk are skipped, as glTF 2.0 requires of clients.
pub fn read_glb(bytes: &[u8]) -> Result<GlbChunks<'_>, GlbError> {
    if bytes.len() < HEADER_LEN {
        if bytes.len() >= 4 && bytes[..4] != GLB_MAGIC {
            return Err(GlbError::BadMagic {
                found: [bytes[0], bytes[1], bytes[2], bytes[3]],
            });
        }
        return Err(GlbError::Truncated {
            offset: 0,
            what: "glb header",
            needed: HEADER_LEN as u64,
            available: bytes.len() as u64,
        });
    }
    if bytes[..4] != GLB_MAGIC {
        return Err(GlbError::BadMagic {
            found: [bytes[0], bytes[1], bytes[2], bytes[3]],
        });
    }
    let version = u32_at(bytes, 4);
    if version != GLB_VERSION {
        return Err(GlbError::BadVersion { found: version });
    }
    let declared = u32_at(bytes, 8) as u64;
    if declared != bytes.len() as u64 {
        return Err(GlbError::LengthMismatch {
            declared,
            actual: bytes.len() as u64,
        });
    }
    let (kind, json_start, json_end) = chunk_at(bytes, HEADER_LEN)?;
    if kind != CHUNK_JSON {
        return Err(GlbError::BadChunkType {
            offset: HEADER_LEN as u64,
            found: kind,
            expected: "JSON",
        });
    }
    let mut chunks = GlbChunks {
        json: &bytes[json_start..json_end],
        json_offset: json_start,
        bin: None,
        bin_offset: 0,
    };
    let mut at = json_end;
    let mut index = 1;
    while at < bytes.len() {
        let (kind, start, end) = chunk_at(bytes, at)?;
        match kind {
            CHUNK_BIN if index == 1 => {
                chunks.bin = Some(&bytes[start..end]);
                chunks.bin_offset = start;
            }
            CHUNK_BIN | CHUNK_JSON => {
                return Err(GlbError::BadChunkType {
                    offset: at as u64,
                    found: kind,
                    expected: "no second JSON chunk, BIN only as the second chunk",
                });
            }
            _ => {}
        }
        at = end;
        index += 1;
    }
    Ok(chunks)
}

/// Byte offset inside `text` of a 1-based (line, column) position.
fn line_col_offset(text: &[u8], line: usize, column: usize) -> usize {
    let mut at = 0;
    for _ in 1..line {
        match text[at..].iter().position(|&b| b == b'\n') {
            Some(p) => at += p + 1,
            None => return text.len(),
        }
    }
    (at + column.saturating_sub(1)).min(text.len())
}

/// Parses the JSON chunk as a glTF document; errors carry the glb byte offset.
pub fn parse_json(chunks: &GlbChunks<'_>) -> Result<Gltf, GlbError> {
    serde_json::from_slice(chunks.json).map_err(|e| GlbError::Json {
        offset: (chunks.json_offset + line_col_offset(chunks.json, e.line(), e.column())) as u64,
        message: e.to_string(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn framing_pads_and_round_trips() {
        let glb = write_glb(br#"{"a":1}"#, Some(&[1, 2, 3, 4, 5])).unwrap();
        assert_eq!(glb.len() % 4, 0);
        assert_eq!(&glb[..4], b"glTF");
        assert_eq!(u32_at(&glb, 8) as usize, glb.len());
        let c = read_glb(&glb).unwrap();
        assert_eq!(c.json, b"{\"a\":1} ");
        assert_eq!(c.json_offset, 20);
        assert_eq!(c.bin.unwrap(), &[1, 2, 3, 4, 5, 0, 0, 0]);
        assert_eq!(c.bin_offset % 4, 0);
        let no_bin = write_glb(b"{}", None).unwrap();
        assert_eq!(read_glb(&no_bin).unwrap().bin, None);
    }

    #[test]
    fn header_errors() {
        assert!(matches!(
            read_glb(b"glTF\x02\0\0"),
            Err(GlbError::Truncated { offset: 0, .. })
        ));
        assert!(matches!(
            read_glb(b"PK\x03\x04 some zip"),
            Err(GlbError::BadMagic { .. })
        ));
        let mut glb = write_glb(b"{}", None).unwrap();
        glb[4] = 1;
        assert_eq!(read_glb(&glb), Err(GlbError::BadVersion { found: 1 }));
        glb[4] = 2;
        glb[8] = glb[8].wrapping_add(4);
        assert!(matches!(
            read_glb(&glb),
            Err(GlbError::LengthMismatch { .. })
        ));
    }

    #[test]
    fn chunk_errors() {
        let mut glb = write_glb(b"{}  ", Some(&[0; 8])).unwrap();
        // JSON chunk length far past the end (u32::MAX must not overflow anything).
        let saved = glb[12..16].to_vec();
        glb[12..16].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(matches!(
            read_glb(&glb),
            Err(GlbError::ChunkPastEnd { offset: 12, .. })
        ));
        glb[12..16].copy_from_slice(&saved);
        // BIN first.
        glb[16..20].copy_from_slice(&CHUNK_BIN.to_le_bytes());
        assert!(matches!(
            read_glb(&glb),
            Err(GlbError::BadChunkType { offset: 12, .. })
        ));
        glb[16..20].copy_from_slice(&CHUNK_JSON.to_le_bytes());
        // BIN chunk length past the end.
        glb[24..28].copy_from_slice(&9u32.to_le_bytes());
        assert!(matches!(
            read_glb(&glb),
            Err(GlbError::ChunkPastEnd { offset: 24, .. })
        ));
    }

    #[test]
    fn json_errors_carry_offsets() {
        let glb = write_glb(b"{\"asset\":\n {\"version\": 2.0x}}", None).unwrap();
        let c = read_glb(&glb).unwrap();
        match parse_json(&c) {
            Err(GlbError::Json { offset, .. }) => assert!((20..glb.len() as u64).contains(&offset)),
            other => panic!("expected a JSON error, got {other:?}"),
        }
    }

    #[test]
    fn every_truncation_is_an_error_not_a_panic() {
        let glb = write_glb(br#"{"asset":{"version":"2.0"}}"#, Some(&[7; 12])).unwrap();
        for n in 0..glb.len() {
            assert!(read_glb(&glb[..n]).is_err(), "prefix of {n} bytes");
        }
    }
}
