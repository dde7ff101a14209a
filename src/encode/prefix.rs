//! Partial-download decoding of prefix-renderable (interleaved) splat tiles: the complete leading
//! splats held by a byte prefix of a glb, and how many bytes they used (`spec/prefix-layout.md`).

use super::glb::{CHUNK_BIN, CHUNK_JSON, GLB_MAGIC, GlbError, write_gltf_glb};
use super::gltf::Gltf;
use super::tile::read_tile_glb;
use crate::splat::Splats;

fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

/// Where the splat records of an interleaved tile sit: parsed JSON, offset of the first record
/// in the glb, record size, total records.
#[derive(Debug, Clone)]
pub struct PrefixLayout {
    /// The tile's glTF JSON.
    pub doc: Gltf,
    /// Byte offset (in the glb) of splat 0's record.
    pub first_record: usize,
    /// Bytes per splat record (`byteStride` of the one bufferView).
    pub stride: usize,
    /// Splats in the whole tile.
    pub count: usize,
}

/// Parses what must be complete before any splat can be decoded: the 12-byte header, the whole
/// JSON chunk and the BIN chunk header. `Ok(None)` means "not enough bytes yet".
pub fn prefix_layout(prefix: &[u8]) -> Result<Option<PrefixLayout>, GlbError> {
    if prefix.len() < 20 {
        if prefix.len() >= 4 && prefix[..4] != GLB_MAGIC {
            return Err(GlbError::BadMagic {
                found: [prefix[0], prefix[1], prefix[2], prefix[3]],
            });
        }
        return Ok(None);
    }
    if prefix[..4] != GLB_MAGIC {
        return Err(GlbError::BadMagic {
            found: [prefix[0], prefix[1], prefix[2], prefix[3]],
        });
    }
    let json_len = u32_at(prefix, 12) as usize;
    if u32_at(prefix, 16) != CHUNK_JSON {
        return Err(GlbError::BadChunkType {
            offset: 12,
            found: u32_at(prefix, 16),
            expected: "JSON",
        });
    }
    let bin_header = 20 + json_len;
    if prefix.len() < bin_header + 8 {
        return Ok(None);
    }
    if u32_at(prefix, bin_header + 4) != CHUNK_BIN {
        return Err(GlbError::BadChunkType {
            offset: bin_header as u64,
            found: u32_at(prefix, bin_header + 4),
            expected: "BIN",
        });
    }
    let doc: Gltf =
        serde_json::from_slice(&prefix[20..bin_header]).map_err(|e| GlbError::Json {
            offset: 20,
            message: e.to_string(),
        })?;
    let not_prefix = |what: &str| GlbError::unsupported("/bufferViews", what.to_string());
    if doc.buffer_views.len() != 1 || doc.buffers.len() != 1 {
        return Err(not_prefix(
            "not a prefix-renderable tile (one interleaved bufferView expected)",
        ));
    }
    let view = &doc.buffer_views[0];
    let stride = view
        .byte_stride
        .ok_or_else(|| not_prefix("bufferView 0 has no byteStride"))?;
    let count = doc.accessors.first().map_or(0, |a| a.count) as usize;
    if doc
        .accessors
        .iter()
        .any(|a| a.buffer_view != Some(0) || a.count as usize != count)
    {
        return Err(not_prefix("accessors outside the interleaved bufferView"));
    }
    Ok(Some(PrefixLayout {
        first_record: bin_header + 8 + view.byte_offset as usize,
        stride: stride as usize,
        count,
        doc,
    }))
}

/// Decodes the complete leading splats of a prefix of an interleaved tile glb.
///
/// Returns the splats (positions tile-relative, as `POSITION` holds them) and `consumed`, the
/// byte offset just past the last complete splat record: a client streaming the tile keeps
/// `prefix[consumed..]` (a partial record) and prepends it to the next chunk. Before the JSON
/// chunk and BIN header are complete, no splat is returned and `consumed` is 0.
pub fn decode_prefix(prefix: &[u8]) -> Result<(Splats, usize), GlbError> {
    let Some(layout) = prefix_layout(prefix)? else {
        return Ok((Splats::new(0), 0));
    };
    let have = prefix.len().saturating_sub(layout.first_record) / layout.stride.max(1);
    let k = have.min(layout.count);
    let consumed = if k == 0 {
        layout.first_record.min(prefix.len())
    } else {
        layout.first_record + k * layout.stride
    };
    if k == 0 {
        let degree = sh_degree_of(&layout.doc);
        return Ok((Splats::new(degree), consumed));
    }
    // A glb of the first k records: same JSON with counts and lengths cut to k.
    let mut doc = layout.doc;
    let view_offset = doc.buffer_views[0].byte_offset;
    for a in &mut doc.accessors {
        a.count = k as u64;
    }
    doc.buffer_views[0].byte_length = (k * layout.stride) as u64;
    doc.buffers[0].byte_length = view_offset + (k * layout.stride) as u64;
    let bin_start = layout.first_record - view_offset as usize;
    let bin = &prefix[bin_start..consumed];
    let glb = write_gltf_glb(&doc, Some(bin))?;
    Ok((read_tile_glb(&glb)?.splats, consumed))
}

/// SH degree declared by the primitive's attributes (for an empty result of the right shape).
fn sh_degree_of(doc: &Gltf) -> u8 {
    let Some(p) = doc.meshes.first().and_then(|m| m.primitives.first()) else {
        return 0;
    };
    (1..=3u8)
        .take_while(|&l| {
            (0..=2 * l).all(|c| p.attributes.contains_key(&super::tile::sh_attribute(l, c)))
        })
        .last()
        .unwrap_or(0)
}
