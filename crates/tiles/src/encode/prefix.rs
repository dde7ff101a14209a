//! Partial-download decoding of prefix-renderable (interleaved) splat tiles: the complete leading
//! splats held by a byte prefix of a glb, and how many bytes they used (`spec/prefix-layout.md`).

use super::glb::{CHUNK_BIN, CHUNK_JSON, GLB_MAGIC, GlbError, write_gltf_glb};
use super::gltf::Gltf;
use super::tile_read::read_tile_glb;
use splat2tiles_core::splat::Splats;

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
    let bin_header = 20usize.saturating_add(json_len);
    if prefix.len() < bin_header.saturating_add(8) {
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
        first_record: (bin_header + 8)
            .saturating_add(usize::try_from(view.byte_offset).unwrap_or(usize::MAX)),
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
    let bin = &prefix[layout.first_record..consumed];
    let (splats, _) = decode_records(&layout.doc, bin, k)?;
    Ok((splats, consumed))
}

/// Decodes `k` whole splat records (`records.len() == k * stride`) with the tile's JSON cut to
/// them; also returns the splat node's world matrix.
fn decode_records(full: &Gltf, records: &[u8], k: usize) -> Result<(Splats, [f64; 16]), GlbError> {
    // A glb of just these records: same JSON with counts and lengths cut to k, view at offset 0.
    let mut doc = full.clone();
    for a in &mut doc.accessors {
        a.count = k as u64;
    }
    doc.buffer_views[0].byte_offset = 0;
    doc.buffer_views[0].byte_length = records.len() as u64;
    doc.buffers[0].byte_length = records.len() as u64;
    let glb = write_gltf_glb(&doc, Some(records))?;
    let t = read_tile_glb(&glb)?;
    Ok((t.splats, t.node_matrix))
}

/// Incremental decoder of one interleaved tile arriving in chunks (a streamed download).
///
/// Each [`push`](Self::push) returns only the splats completed by that chunk, in tile order: a
/// record cut across chunks is kept and completed by the next one, and no record is decoded twice.
#[derive(Debug, Clone, Default)]
pub struct PrefixStream {
    /// Bytes received but not yet decoded (the header before the layout is known, then at most
    /// one partial record).
    pending: Vec<u8>,
    /// The tile's layout, once its header, JSON and BIN chunk header have arrived.
    layout: Option<PrefixLayout>,
    /// Bytes still to skip before splat 0's record (header and any view offset).
    skip: usize,
    /// Splats returned so far.
    decoded: usize,
    /// Bytes pushed so far.
    received: u64,
    /// World matrix of the splat node, once a splat has been decoded.
    node_matrix: Option<[f64; 16]>,
}

impl PrefixStream {
    /// An empty stream, before the first byte of the glb.
    pub fn new() -> Self {
        Self::default()
    }

    /// Appends the next chunk of the glb and returns the splats it completed (maybe none).
    ///
    /// Bytes after the last record (chunk padding) are ignored. After an error the stream is in
    /// an unspecified state and should be dropped.
    pub fn push(&mut self, chunk: &[u8]) -> Result<Splats, GlbError> {
        self.received += chunk.len() as u64;
        self.pending.extend_from_slice(chunk);
        if self.layout.is_none() {
            let Some(layout) = prefix_layout(&self.pending)? else {
                return Ok(Splats::new(0));
            };
            if layout.stride == 0 {
                return Err(GlbError::unsupported(
                    "/bufferViews/0/byteStride",
                    "byteStride 0 cannot hold splat records",
                ));
            }
            self.skip = layout.first_record;
            self.layout = Some(layout);
        }
        let Some(layout) = &self.layout else {
            return Ok(Splats::new(0));
        };
        let dropped = self.skip.min(self.pending.len());
        self.pending.drain(..dropped);
        self.skip -= dropped;
        let left = layout.count - self.decoded;
        let k = (self.pending.len() / layout.stride).min(left);
        if k == 0 {
            if left == 0 {
                self.pending.clear();
            }
            return Ok(Splats::new(sh_degree_of(&layout.doc)));
        }
        let (splats, node) = decode_records(&layout.doc, &self.pending[..k * layout.stride], k)?;
        self.node_matrix = Some(node);
        self.pending.drain(..k * layout.stride);
        self.decoded += k;
        if self.decoded == layout.count {
            self.pending.clear();
        }
        Ok(splats)
    }

    /// Splats returned by [`push`](Self::push) so far.
    pub fn decoded(&self) -> usize {
        self.decoded
    }

    /// Splats in the whole tile, once the header has arrived.
    pub fn total(&self) -> Option<usize> {
        self.layout.as_ref().map(|l| l.count)
    }

    /// Bytes pushed so far (where a resumed download's `Range: bytes=N-` starts).
    pub fn received(&self) -> u64 {
        self.received
    }

    /// World matrix of the tile's splat node (column-major), known once a splat was decoded.
    pub fn node_matrix(&self) -> Option<[f64; 16]> {
        self.node_matrix
    }

    /// True once every splat of the tile has been returned.
    pub fn is_complete(&self) -> bool {
        self.total() == Some(self.decoded)
    }
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::encode::tile::{IDENTITY, TileLayout, try_write_tile_glb};
    use splat2tiles_core::splat::{Splat, sh_rest_count};

    /// `n` deterministic, distinct splats of SH degree `deg`.
    fn scene(n: usize, deg: u8) -> Splats {
        let mut s = Splats::with_capacity(deg, n);
        let rest = sh_rest_count(deg);
        for i in 0..n {
            let f = i as f32;
            let splat = Splat {
                position: [
                    f as f64 * 0.01,
                    (f * 0.37).sin() as f64,
                    (f * 0.11).cos() as f64,
                ],
                scale: [0.01 + f * 1e-4, 0.02, 0.03],
                rotation: splat2tiles_core::splat::normalize_quat([f.sin(), 0.2, 0.3, 1.0]),
                opacity: 0.1 + (i % 80) as f32 * 0.01,
                sh0: [f * 0.001, -0.5, 0.25],
            };
            let r: Vec<[f32; 3]> = (0..rest)
                .map(|c| [c as f32 * 0.01, f * 1e-3, -0.1])
                .collect();
            s.push(splat, &r);
        }
        s
    }

    /// Pushes `glb` cut at `cuts` (sorted) and returns everything the stream yielded.
    fn stream(glb: &[u8], cuts: &[usize]) -> (Splats, PrefixStream) {
        let mut st = PrefixStream::new();
        let mut all: Option<Splats> = None;
        let mut at = 0;
        for &c in cuts.iter().chain(std::iter::once(&glb.len())) {
            let new = st.push(&glb[at..c]).unwrap();
            at = c;
            let acc = all.get_or_insert_with(|| Splats::new(new.sh_degree));
            if acc.is_empty() {
                *acc = Splats::new(new.sh_degree);
            }
            if !new.is_empty() {
                assert_eq!(acc.sh_degree, new.sh_degree);
                for i in 0..new.len() {
                    acc.push_from(&new, i);
                }
            }
            assert_eq!(acc.len(), st.decoded());
        }
        (all.unwrap_or_else(|| Splats::new(0)), st)
    }

    fn assert_same(a: &Splats, b: &Splats) {
        assert_eq!(a.len(), b.len());
        for i in 0..a.len() {
            assert_eq!(a.get(i), b.get(i), "splat {i}");
            assert_eq!(a.rest_of(i), b.rest_of(i), "SH of splat {i}");
        }
    }

    #[test]
    fn chunked_pushes_at_random_cuts_yield_the_whole_tile_once() {
        for (n, deg) in [(1usize, 0u8), (37, 1), (400, 3)] {
            let glb =
                try_write_tile_glb(&scene(n, deg), [0.5; 3], IDENTITY, TileLayout::Interleaved)
                    .unwrap();
            let full = read_tile_glb(&glb).unwrap().splats;
            let mut seed = 0x9e37_79b9_7f4a_7c15u64 ^ n as u64;
            for round in 0..40 {
                let pieces = 1 + round % 25;
                let mut cuts: Vec<usize> = (0..pieces)
                    .map(|_| {
                        seed ^= seed << 13;
                        seed ^= seed >> 7;
                        seed ^= seed << 17;
                        (seed % (glb.len() as u64 + 1)) as usize
                    })
                    .collect();
                cuts.sort_unstable();
                let (got, st) = stream(&glb, &cuts);
                assert!(st.is_complete(), "n {n} cuts {cuts:?}");
                assert_eq!(st.total(), Some(n));
                assert_eq!(st.received(), glb.len() as u64);
                assert_eq!(got.sh_degree, full.sh_degree);
                assert_same(&got, &full);
            }
            // Byte by byte: every record is cut at every offset.
            let every: Vec<usize> = (1..glb.len()).collect();
            assert_same(&stream(&glb, &every).0, &full);
        }
    }

    #[test]
    fn stream_agrees_with_decode_prefix_at_each_step() {
        let glb =
            try_write_tile_glb(&scene(50, 2), [0.0; 3], IDENTITY, TileLayout::Interleaved).unwrap();
        let mut st = PrefixStream::new();
        for end in (0..=glb.len()).step_by(97).chain([glb.len()]) {
            let at = st.received() as usize;
            st.push(&glb[at..end]).unwrap();
            let (part, _) = decode_prefix(&glb[..end]).unwrap();
            assert_eq!(st.decoded(), part.len(), "prefix of {end} bytes");
        }
        assert!(st.is_complete());
        // Bytes past the end of the tile are ignored, not decoded as splats.
        assert!(st.push(&[0u8; 64]).unwrap().is_empty());
        assert_eq!(st.decoded(), 50);
    }

    #[test]
    fn stream_rejects_what_is_not_an_interleaved_glb() {
        let mut st = PrefixStream::new();
        assert!(st.push(b"not a glb at all, clearly").is_err());
        let glb =
            try_write_tile_glb(&scene(5, 0), [0.0; 3], IDENTITY, TileLayout::Separate).unwrap();
        assert!(PrefixStream::new().push(&glb).is_err());
    }
}
