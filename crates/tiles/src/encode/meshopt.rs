//! Quantized splat tiles through `EXT_meshopt_compression` (High / Medium variants): float
//! attributes through its EXPONENTIAL filter, rotations through QUATERNION (the reader:
//! `meshopt_read`).
// Without `native` only the (pure-Rust) decoder remains: the encoder needs the C library.
#![cfg_attr(not(feature = "native"), allow(unused_imports, dead_code))]

use std::collections::BTreeMap;

use serde_json::{Map, Value, json};

use super::exp_filter::{ExpMode, encode_exp};
use super::glb::{GlbError, write_gltf_glb};
use super::gltf::{
    Accessor, AccessorType, Buffer, BufferView, ComponentType, EXT_MESHOPT_COMPRESSION,
    KHR_GAUSSIAN_SPLATTING, TARGET_ARRAY_BUFFER,
};
#[cfg(feature = "native")]
use super::storage_order::{in_caller_order, in_storage_order};
use super::tile::{
    ATTR_OPACITY, ATTR_POSITION, ATTR_ROTATION, ATTR_SCALE, check_writable, sh_attribute,
    splat_document,
};
use splat2tiles_core::splat::Splats;

pub use super::meshopt_read::{decompress_meshopt_glb, filter_in_place};

/// Bit depths of one level. Positions and DC colour are fixed point over the tile (the
/// EXPONENTIAL filter with one exponent per component for the whole stream, as Table 6 quantises
/// over the range); scales and opacity keep a mantissa of their own (relative precision); higher
/// SH share an exponent per coefficient triple; rotations go through the QUATERNION filter.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MeshoptLevel {
    /// POSITION bits, sign included, over the largest |coordinate| of the tile per axis.
    pub position_bits: i32,
    /// ROTATION bits per component (4..=16), stored as normalized i16.
    pub rotation_bits: i32,
    /// SCALE mantissa bits, one exponent per component.
    pub scale_bits: i32,
    /// OPACITY mantissa bits.
    pub opacity_bits: i32,
    /// SH degree 0 bits, sign included, over the largest |value| of the tile per channel.
    pub sh0_bits: i32,
    /// Higher SH bits: the mantissa with [`ExpMode::SharedVector`] (one exponent for the RGB of
    /// each coefficient), sign included over the largest |value| per channel with
    /// [`ExpMode::SharedComponent`] (fixed point over the tile).
    pub sh_rest_bits: i32,
    /// How the higher SH share exponents.
    pub sh_rest_mode: ExpMode,
    /// Highest SH degree kept (lower of this and the input's).
    pub max_sh_degree: u8,
}

/// The High variant's bit depths: both SSIMs of Table 6's Best (framed and 4x zoom) for fewer
/// bytes on the three SH0 scenes; 21 position bits and 11 scale bits are what its 24-bit
/// positions over the scene's range and 12-bit log scales needed (BENCHMARKS.md, "High reaches
/// Table 6 Best").
pub const HIGH: MeshoptLevel = MeshoptLevel {
    position_bits: 21,
    rotation_bits: 12,
    scale_bits: 11,
    opacity_bits: 12,
    sh0_bits: 11,
    sh_rest_bits: 6,
    sh_rest_mode: ExpMode::SharedVector,
    max_sh_degree: 3,
};

/// The Medium variant's bit depths. Scale, opacity and DC colour stay fine (9 / 10 / 10 bits):
/// with fewer (6 / 6 / 7 bits) Medium drew further from Best than Low on SPZ-sourced scenes
/// (biker), whose 8-bit grids Low keeps exactly (`tests/variants_quality.rs`).
pub const MEDIUM: MeshoptLevel = MeshoptLevel {
    position_bits: 16,
    rotation_bits: 9,
    scale_bits: 9,
    opacity_bits: 10,
    sh0_bits: 10,
    sh_rest_bits: 4,
    sh_rest_mode: ExpMode::SharedVector,
    max_sh_degree: 2,
};

/// One compressed stream: its decoded bytes (already filtered), stride, filter, accessors.
struct Stream {
    data: Vec<u8>,
    stride: usize,
    filter: &'static str,
    /// (semantic, type, component, normalized, byte offset in the element, min/max)
    accessors: Vec<AccSpec>,
}

struct AccSpec {
    semantic: String,
    kind: AccessorType,
    component: ComponentType,
    normalized: bool,
    offset: usize,
    min_max: Option<(Vec<f64>, Vec<f64>)>,
}

fn spec(semantic: String, kind: AccessorType, component: ComponentType, offset: usize) -> AccSpec {
    AccSpec {
        semantic,
        kind,
        component,
        normalized: false,
        offset,
        min_max: None,
    }
}

#[cfg(feature = "native")]
/// Encodes floats with the EXPONENTIAL filter (the Rust port, byte-identical to the C one);
/// returns the filtered bytes.
fn exp3(v: &[[f32; 3]], bits: i32, mode: ExpMode) -> Vec<u8> {
    encode_exp(v, bits, mode)
}

#[cfg(feature = "native")]
/// Applies the EXPONENTIAL filter's decoding to a copy (what a client will see).
fn unfilter_exp(mut bytes: Vec<u8>) -> Vec<f32> {
    filter_in_place(&mut bytes, 4, "EXPONENTIAL");
    bytes
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect()
}

#[cfg(feature = "native")]
fn min_max3(v: &[f32]) -> (Vec<f64>, Vec<f64>) {
    let mut lo = [f32::MAX; 3];
    let mut hi = [f32::MIN; 3];
    for p in v.chunks_exact(3) {
        for a in 0..3 {
            lo[a] = lo[a].min(p[a]);
            hi[a] = hi[a].max(p[a]);
        }
    }
    (lo.map(f64::from).to_vec(), hi.map(f64::from).to_vec())
}

#[cfg(feature = "native")]
/// Encodes a meshopt ATTRIBUTES stream (bitstream version 0, the one EXT_meshopt_compression
/// allows): the Rust port of the C encoder, byte-identical to it ([`super::vertex_codec`]).
fn encode_attributes(data: &[u8], stride: usize) -> Vec<u8> {
    super::vertex_codec::encode_vertex_buffer_v0(data, stride)
}

#[cfg(feature = "native")]
/// The streams of a tile at `level`.
fn streams(splats: &Splats, centre: [f64; 3], level: &MeshoptLevel) -> Vec<Stream> {
    let n = splats.len();
    use AccessorType::{Scalar, Vec3, Vec4};
    use ComponentType::{F32, I16};
    let rel: Vec<[f32; 3]> = splats
        .positions
        .iter()
        .map(|p| [0, 1, 2].map(|a| (p[a] - centre[a]) as f32))
        .collect();
    let pos_bytes = exp3(&rel, level.position_bits, ExpMode::SharedComponent);
    let pos_dec = unfilter_exp(pos_bytes.clone());
    let mut pos = spec(ATTR_POSITION.into(), Vec3, F32, 0);
    pos.min_max = Some(min_max3(&pos_dec));

    let quats = meshopt::encode_filter_quat(&splats.rotations, level.rotation_bits);
    let mut rot_bytes = Vec::with_capacity(quats.len() * 8);
    for v in quats.iter().flatten() {
        rot_bytes.extend_from_slice(&v.to_le_bytes());
    }
    let mut rot = spec(ATTR_ROTATION.into(), Vec4, I16, 0);
    rot.normalized = true;

    let scale_bytes = exp3(&splats.scales, level.scale_bits, ExpMode::Separate);
    let op: Vec<[f32; 1]> = splats.opacities.iter().map(|&a| [a]).collect();
    let op_bytes = encode_exp(&op, level.opacity_bits, ExpMode::Separate);
    let sh0_bytes = exp3(&splats.sh0, level.sh0_bits, ExpMode::SharedComponent);

    let mut out = vec![
        Stream {
            data: pos_bytes,
            stride: 12,
            filter: "EXPONENTIAL",
            accessors: vec![pos],
        },
        Stream {
            data: rot_bytes,
            stride: 8,
            filter: "QUATERNION",
            accessors: vec![rot],
        },
        Stream {
            data: scale_bytes,
            stride: 12,
            filter: "EXPONENTIAL",
            accessors: vec![spec(ATTR_SCALE.into(), Vec3, F32, 0)],
        },
        Stream {
            data: op_bytes,
            stride: 4,
            filter: "EXPONENTIAL",
            accessors: vec![spec(ATTR_OPACITY.into(), Scalar, F32, 0)],
        },
        Stream {
            data: sh0_bytes,
            stride: 12,
            filter: "EXPONENTIAL",
            accessors: vec![spec(sh_attribute(0, 0), Vec3, F32, 0)],
        },
    ];
    let degree = splats.sh_degree.min(level.max_sh_degree);
    if degree > 0 {
        let k_in = splats.rest_per_splat();
        let k = splat2tiles_core::splat::sh_rest_count(degree);
        // Every coefficient kept (High at SH3): the input's own array, without a copy.
        let bytes = if k == k_in {
            exp3(&splats.sh_rest, level.sh_rest_bits, level.sh_rest_mode)
        } else {
            let kept: Vec<[f32; 3]> = (0..n)
                .flat_map(|i| splats.sh_rest[i * k_in..i * k_in + k].iter().copied())
                .collect();
            exp3(&kept, level.sh_rest_bits, level.sh_rest_mode)
        };
        let mut accs = vec![];
        for l in 1..=degree {
            for c in 0..=2 * l {
                let j = (l as usize).pow(2) - 1 + c as usize;
                accs.push(spec(sh_attribute(l, c), Vec3, F32, j * 12));
            }
        }
        out.push(Stream {
            data: bytes,
            stride: 12 * k,
            filter: "EXPONENTIAL",
            accessors: accs,
        });
    }
    // No COLOR_0: the point-cloud fallback is optional, a client that cannot decode
    // EXT_meshopt_compression (required here) draws nothing anyway, and it cost 3.6-3.9 B/splat.
    out
}

/// Without the native codecs meshopt tiles cannot be written.
#[cfg(not(feature = "native"))]
pub fn write_meshopt_glb(
    _splats: &Splats,
    _centre: [f64; 3],
    _node_matrix: [f64; 16],
    _level: &MeshoptLevel,
) -> Result<Vec<u8>, GlbError> {
    Err(GlbError::invalid(
        "/extensionsUsed",
        "EXT_meshopt_compression needs the native build of splat2tiles",
    ))
}

/// Without the native codecs meshopt tiles cannot be written.
#[cfg(not(feature = "native"))]
pub fn write_meshopt_glb_stored(
    splats: &Splats,
    centre: [f64; 3],
    node_matrix: [f64; 16],
    level: &MeshoptLevel,
    _decode: bool,
) -> Result<(Vec<u8>, Option<Splats>), GlbError> {
    write_meshopt_glb_and_decoded(splats, centre, node_matrix, level).map(|(g, d)| (g, Some(d)))
}

/// Without the native codecs meshopt tiles cannot be written.
#[cfg(not(feature = "native"))]
pub fn write_meshopt_glb_and_decoded(
    splats: &Splats,
    centre: [f64; 3],
    node_matrix: [f64; 16],
    level: &MeshoptLevel,
) -> Result<(Vec<u8>, Splats), GlbError> {
    write_meshopt_glb(splats, centre, node_matrix, level).map(|g| (g, Splats::new(0)))
}

/// Writes a splat tile compressed with `EXT_meshopt_compression` (required; the uncompressed
/// layout lives in a fallback buffer without data) at the bit depths of `level`, its splats in
/// Morton order of their positions (`super::storage_order`), not the caller's.
#[cfg(feature = "native")]
pub fn write_meshopt_glb(
    splats: &Splats,
    centre: [f64; 3],
    node_matrix: [f64; 16],
    level: &MeshoptLevel,
) -> Result<Vec<u8>, GlbError> {
    Ok(encode_stored(splats, centre, node_matrix, level)?.glb)
}

/// [`write_meshopt_glb`] with the splats in the caller's order rather than Morton order (to
/// measure what the order is worth: `examples/order_bytes.rs`).
#[cfg(feature = "native")]
pub fn write_meshopt_glb_as_given(
    splats: &Splats,
    centre: [f64; 3],
    node_matrix: [f64; 16],
    level: &MeshoptLevel,
) -> Result<Vec<u8>, GlbError> {
    Ok(encode_meshopt(splats, centre, node_matrix, level)?.0)
}

/// [`write_meshopt_glb_as_given`] for a tile the caller already put in storage order
/// ([`super::storage_order`], once for several variants), with the splats it decodes to (in the
/// same order) when `decode`.
#[cfg(feature = "native")]
pub fn write_meshopt_glb_stored(
    splats: &Splats,
    centre: [f64; 3],
    node_matrix: [f64; 16],
    level: &MeshoptLevel,
    decode: bool,
) -> Result<(Vec<u8>, Option<Splats>), GlbError> {
    let (glb, filtered) = encode_meshopt(splats, centre, node_matrix, level)?;
    let degree = splats.sh_degree.min(level.max_sh_degree);
    Ok((glb, decode.then(|| unfiltered_splats(filtered, degree))))
}

/// A tile encoded in storage order: the glb, its filtered streams and the order.
#[cfg(feature = "native")]
struct EncodedStored {
    glb: Vec<u8>,
    filtered: Vec<Vec<u8>>,
    order: Vec<usize>,
}

/// [`encode_meshopt`] of `splats` in storage order (Morton order of the tile-relative positions:
/// `super::storage_order`).
#[cfg(feature = "native")]
fn encode_stored(
    splats: &Splats,
    centre: [f64; 3],
    node_matrix: [f64; 16],
    level: &MeshoptLevel,
) -> Result<EncodedStored, GlbError> {
    // Errors name the caller's splat index: checked before reordering.
    check_writable(splats, centre)?;
    let (order, stored) = in_storage_order(splats, centre, level.max_sh_degree);
    let (glb, filtered) = encode_meshopt(&stored, centre, node_matrix, level)?;
    Ok(EncodedStored {
        glb,
        filtered,
        order,
    })
}

/// [`write_meshopt_glb`] and the tile-relative splats that [`super::read_tile_glb`] reads from
/// [`decompress_meshopt_glb`] of it, bit for bit (`tests::decoded_matches_the_reader`), built
/// from the filtered streams where they were made (no vertex-codec decode, no plain glb) and put
/// back in the caller's order, splat `i` decoded from the caller's splat `i`.
#[cfg(feature = "native")]
pub fn write_meshopt_glb_and_decoded(
    splats: &Splats,
    centre: [f64; 3],
    node_matrix: [f64; 16],
    level: &MeshoptLevel,
) -> Result<(Vec<u8>, Splats), GlbError> {
    let EncodedStored {
        glb,
        filtered,
        order,
    } = encode_stored(splats, centre, node_matrix, level)?;
    let degree = splats.sh_degree.min(level.max_sh_degree);
    let stored = unfiltered_splats(filtered, degree);
    Ok((glb, in_caller_order(&stored, &order)))
}

/// The splats held by [`streams`]' filtered bytes (in their order), converted as the glb reader
/// converts the accessors: f32 as is, normalized i16 rotations over 32767 and renormalised when
/// not unit within 1e-4, opacities clamped into [0, 1].
#[cfg(feature = "native")]
fn unfiltered_splats(filtered: Vec<Vec<u8>>, degree: u8) -> Splats {
    // Each stream unfiltered in place, then read as triples (or single floats).
    let unfilter = |mut bytes: Vec<u8>, stride: usize| -> Vec<u8> {
        filter_in_place(&mut bytes, stride, "EXPONENTIAL");
        bytes
    };
    let f32_at = |b: &[u8], a: usize| {
        f32::from_le_bytes([b[4 * a], b[4 * a + 1], b[4 * a + 2], b[4 * a + 3]])
    };
    let triples = |bytes: Vec<u8>| -> Vec<[f32; 3]> {
        bytes
            .chunks_exact(12)
            .map(|e| [0, 1, 2].map(|a| f32_at(e, a)))
            .collect()
    };
    let mut it = filtered.into_iter();
    let mut next = || it.next().unwrap_or_default();
    let positions = unfilter(next(), 12)
        .chunks_exact(12)
        .map(|e| [0, 1, 2].map(|a| f32_at(e, a) as f64))
        .collect();
    let mut rot = next();
    filter_in_place(&mut rot, 8, "QUATERNION");
    let rotations = rot
        .chunks_exact(8)
        .map(|e| {
            let q = [0, 1, 2, 3]
                .map(|c| (i16::from_le_bytes([e[2 * c], e[2 * c + 1]]) as f32 / 32767.0).max(-1.0));
            let n2: f64 = q.iter().map(|&v| v as f64 * v as f64).sum();
            if (n2.sqrt() - 1.0).abs() > 1e-4 {
                splat2tiles_core::splat::normalize_quat(q)
            } else {
                q
            }
        })
        .collect();
    let scales = triples(unfilter(next(), 12));
    let opacities = unfilter(next(), 4)
        .chunks_exact(4)
        .map(|b| {
            let a = f32_at(b, 0);
            if a.is_nan() { a } else { a.clamp(0.0, 1.0) }
        })
        .collect();
    let sh0 = triples(unfilter(next(), 12));
    let k = splat2tiles_core::splat::sh_rest_count(degree);
    let sh_rest = if k > 0 {
        triples(unfilter(next(), 12 * k))
    } else {
        vec![]
    };
    let s = Splats {
        positions,
        scales,
        rotations,
        opacities,
        sh0,
        sh_degree: degree,
        sh_rest,
    };
    s.check_lengths();
    s
}

/// The meshopt glb and each compressed bufferView's filtered bytes (before the vertex codec).
#[cfg(feature = "native")]
fn encode_meshopt(
    splats: &Splats,
    centre: [f64; 3],
    node_matrix: [f64; 16],
    level: &MeshoptLevel,
) -> Result<(Vec<u8>, Vec<Vec<u8>>), GlbError> {
    check_writable(splats, centre)?;
    let n = splats.len();
    let streams = streams(splats, centre, level);
    // The compressed streams are smaller than the filtered ones: no reallocation.
    let mut bin = Vec::with_capacity(streams.iter().map(|s| s.data.len() + 4).sum());
    let mut views = Vec::new();
    let mut accessors = Vec::new();
    let mut attributes = BTreeMap::new();
    let mut fallback_len = 0u64;
    let mut filtered = Vec::new();
    for (vi, s) in streams.into_iter().enumerate() {
        let compressed = encode_attributes(&s.data, s.stride);
        bin.resize(bin.len().next_multiple_of(4), 0);
        let mut ext = Map::new();
        let mut obj = json!({
            "buffer": 0, "byteOffset": bin.len(), "byteLength": compressed.len(),
            "byteStride": s.stride, "count": n, "mode": "ATTRIBUTES",
        });
        if s.filter != "NONE" {
            obj["filter"] = Value::from(s.filter);
        }
        ext.insert(EXT_MESHOPT_COMPRESSION.into(), obj);
        bin.extend_from_slice(&compressed);
        views.push(BufferView {
            buffer: 1,
            byte_offset: fallback_len,
            byte_length: s.data.len() as u64,
            byte_stride: Some(s.stride as u32),
            target: Some(TARGET_ARRAY_BUFFER),
            extensions: Some(ext),
            ..Default::default()
        });
        fallback_len += s.data.len().next_multiple_of(4) as u64;
        for a in s.accessors {
            attributes.insert(a.semantic.clone(), accessors.len() as u32);
            accessors.push(Accessor {
                buffer_view: Some(vi as u32),
                byte_offset: a.offset as u64,
                component_type: a.component.code(),
                normalized: a.normalized,
                count: n as u64,
                kind: a.kind,
                min: a.min_max.as_ref().map(|m| m.0.clone()),
                max: a.min_max.map(|m| m.1),
                sparse: None,
                name: None,
            });
        }
        filtered.push(s.data);
    }
    bin.resize(bin.len().next_multiple_of(4), 0);
    let mut fallback = Map::new();
    fallback.insert(EXT_MESHOPT_COMPRESSION.into(), json!({ "fallback": true }));
    let buffers = vec![
        Buffer {
            byte_length: bin.len() as u64,
            ..Default::default()
        },
        Buffer {
            byte_length: fallback_len,
            extensions: Some(fallback),
            ..Default::default()
        },
    ];
    let doc = splat_document(
        attributes,
        accessors,
        views,
        buffers,
        node_matrix,
        None,
        vec![
            KHR_GAUSSIAN_SPLATTING.into(),
            EXT_MESHOPT_COMPRESSION.into(),
        ],
        vec![EXT_MESHOPT_COMPRESSION.into()],
    );
    Ok((write_gltf_glb(&doc, Some(&bin))?, filtered))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::encode::meshopt_read::decode_attributes;
    use crate::encode::storage_order::{relative_f32, storage_order};

    /// xorshift64 bytes.
    fn random_bytes(n: usize, seed: u64) -> Vec<u8> {
        let mut x = seed | 1;
        (0..n)
            .map(|_| {
                x ^= x << 13;
                x ^= x >> 7;
                x ^= x << 17;
                (x >> 24) as u8
            })
            .collect()
    }

    /// The pure-Rust decoder against the C encoder (and the C decoder), byte for byte, on random
    /// and on smooth data at every stride the tiles use.
    #[cfg(feature = "native")]
    #[test]
    fn rust_decoder_matches_the_c_codec() {
        for (stride, seed) in [(4, 1), (8, 2), (12, 3), (36, 4), (96, 5), (180, 6), (16, 7)] {
            for count in [1usize, 15, 16, 17, 255, 256, 257, 1000, 4099] {
                let mut data = random_bytes(count * stride, seed * 1000 + count as u64);
                if count % 2 == 0 {
                    // Smooth: small deltas, the case the codec compresses.
                    for i in stride..data.len() {
                        data[i] = data[i - stride].wrapping_add(data[i] % 3);
                    }
                }
                let enc = encode_attributes(&data, stride);
                let rust = decode_attributes(&enc, count, stride).expect("rust decode");
                assert_eq!(rust, data, "stride {stride} count {count}");
                let mut c = vec![0u8; count * stride];
                // SAFETY: `c` holds count * stride bytes.
                let rc = unsafe {
                    meshopt::ffi::meshopt_decodeVertexBuffer(
                        c.as_mut_ptr().cast(),
                        count,
                        stride,
                        enc.as_ptr(),
                        enc.len(),
                    )
                };
                assert_eq!(rc, 0);
                assert_eq!(c, rust);
            }
        }
        // Truncated or damaged streams are refused, never a panic.
        let data = random_bytes(12 * 300, 9);
        let enc = encode_attributes(&data, 12);
        for cut in [0, 1, 13, enc.len() / 2, enc.len() - 1] {
            assert!(
                decode_attributes(&enc[..cut], 300, 12).is_none(),
                "cut {cut}"
            );
        }
        let mut bad = enc.clone();
        bad[0] = 0x7f;
        assert!(decode_attributes(&bad, 300, 12).is_none());
    }

    /// The Rust EXPONENTIAL decode filter against the C one, byte for byte, on random words and
    /// on what our encoder writes; QUATERNION on encoder output within 1 unit of 32767.
    #[cfg(feature = "native")]
    #[test]
    fn rust_filters_match_the_c_filters() {
        // QUATERNION on random words is left out: most are not encodings (the C library's SIMD
        // and scalar paths round those differently); encoder output is checked below.
        for (filter, stride) in [("EXPONENTIAL", 4), ("EXPONENTIAL", 12), ("EXPONENTIAL", 36)] {
            for count in [1usize, 7, 64, 1001] {
                let mut words = random_bytes(count * stride, count as u64 + stride as u64);
                if filter == "EXPONENTIAL" {
                    // Exponents of real data: small signed bytes in the top byte of each word.
                    for w in words.chunks_exact_mut(4) {
                        w[3] = (w[3] as i8 / 8) as u8;
                    }
                }
                let mut rust = words.clone();
                assert!(filter_in_place(&mut rust, stride, filter));
                let mut c = words.clone();
                // SAFETY: `c` holds count * stride bytes; the filters stay inside it.
                unsafe {
                    if filter == "EXPONENTIAL" {
                        meshopt::ffi::meshopt_decodeFilterExp(
                            c.as_mut_ptr().cast(),
                            count * stride / 4,
                            4,
                        );
                    } else {
                        meshopt::ffi::meshopt_decodeFilterQuat(
                            c.as_mut_ptr().cast(),
                            count,
                            stride,
                        );
                    }
                }
                assert_eq!(rust, c, "{filter} stride {stride} count {count}");
            }
        }
        // What the tiles hold: encoder output of real values.
        let v: Vec<[f32; 3]> = (0..500)
            .map(|i| [i as f32 * 0.37 - 9.0, (i as f32).sin(), 1e-3 * i as f32])
            .collect();
        let enc = encode_exp(&v, 11, ExpMode::SharedVector);
        let mut rust = enc.clone();
        assert!(filter_in_place(&mut rust, 12, "EXPONENTIAL"));
        let mut c = enc;
        // SAFETY: as above.
        unsafe { meshopt::ffi::meshopt_decodeFilterExp(c.as_mut_ptr().cast(), c.len() / 4, 4) };
        assert_eq!(rust, c);
        let r = random_bytes(2000 * 4, 77);
        let q: Vec<[f32; 4]> = r
            .chunks_exact(4)
            .map(|b| {
                splat2tiles_core::splat::normalize_quat([0, 1, 2, 3].map(|k| b[k] as f32 - 127.5))
            })
            .collect();
        for bits in [4, 9, 12, 16] {
            let enc: Vec<u8> = meshopt::encode_filter_quat(&q, bits)
                .iter()
                .flatten()
                .flat_map(|v| v.to_le_bytes())
                .collect();
            let mut rust = enc.clone();
            assert!(filter_in_place(&mut rust, 8, "QUATERNION"));
            let mut c = enc;
            // SAFETY: as above.
            unsafe { meshopt::ffi::meshopt_decodeFilterQuat(c.as_mut_ptr().cast(), q.len(), 8) };
            // The C library's SIMD path rounds some components 1 unit (of 32767) differently
            // from its scalar reference, which the Rust port follows.
            let i16s = |b: &[u8]| -> Vec<i32> {
                b.chunks_exact(2)
                    .map(|w| i16::from_le_bytes([w[0], w[1]]) as i32)
                    .collect()
            };
            let (r, c) = (i16s(&rust), i16s(&c));
            let worst = r.iter().zip(&c).map(|(a, b)| (a - b).abs()).max().unwrap();
            let same = r.iter().zip(&c).filter(|(a, b)| a == b).count();
            assert!(worst <= 1, "{bits} bits: differs by {worst}");
            assert!(
                same * 10 >= r.len() * 9,
                "{bits} bits: {same} of {} equal",
                r.len()
            );
        }
    }
    use crate::encode::read_tile_glb;
    use crate::encode::tile::IDENTITY;
    use splat2tiles_core::splat::{Splat, normalize_quat};

    /// What [`write_meshopt_glb_and_decoded`] returns is what the reader decodes from the glb
    /// (vertex codec, filters, accessors), bit for bit: both levels, every SH degree, opacities
    /// at and beyond the ends, positions far from the centre.
    #[cfg(feature = "native")]
    #[test]
    fn decoded_matches_the_reader() {
        let mut rng = splat2tiles_core::rng::SplitMix64::new(0x2545_F491_4F6C_DD1Du64);
        let mut f = move || rng.f64();
        for degree in 0..=3u8 {
            let mut s = Splats::new(degree);
            let k = splat2tiles_core::splat::sh_rest_count(degree);
            for i in 0..700 {
                let splat = Splat {
                    position: [6.4e6 + f() * 80.0, -3.0e5 + f(), f() * 1e-3],
                    scale: [1e-4 + f() as f32, f() as f32 * 3.0 + 1e-6, 0.01],
                    rotation: normalize_quat([f() as f32 - 0.5, f() as f32, -(f() as f32), 0.3]),
                    opacity: [0.0, 1.0, f() as f32][i % 3],
                    sh0: [f() as f32 - 0.5, 2.0 * f() as f32, -(f() as f32)],
                };
                let rest: Vec<[f32; 3]> = (0..k).map(|_| [f() as f32 - 0.5; 3]).collect();
                s.push(splat, &rest);
            }
            let centre = [6.4e6 + 40.0, -3.0e5, 0.0];
            for level in [HIGH, MEDIUM] {
                let (glb, decoded) =
                    write_meshopt_glb_and_decoded(&s, centre, IDENTITY, &level).unwrap();
                let read = read_tile_glb(&decompress_meshopt_glb(&glb).unwrap())
                    .unwrap()
                    .splats;
                // Stored in Morton order; given back in the caller's.
                let order = storage_order(&relative_f32(&s, centre));
                assert_eq!(
                    decoded,
                    in_caller_order(&read, &order),
                    "SH degree {degree}, {level:?}"
                );
                let stored: Vec<_> = order.iter().map(|&i| s.positions[i]).collect();
                let moved = stored.iter().zip(&read.positions);
                assert!(
                    moved
                        .map(|(a, b)| (a[0] - centre[0] - b[0]).abs())
                        .all(|d| d < 1e-2)
                );
            }
        }
    }

    #[test]
    fn high_and_medium_decode_within_their_bit_depths() {
        let mut s = Splats::new(3);
        for i in 0..300 {
            let f = i as f32 / 300.0;
            s.push(
                Splat {
                    position: [f as f64 * 4.0 - 2.0, (f * 7.0).sin() as f64, 0.3],
                    scale: [0.01 + f * 0.1, 0.02, 0.5],
                    rotation: normalize_quat([f - 0.5, 0.3, -0.2, 0.7 - f]),
                    opacity: f,
                    sh0: [f - 0.5, 1.0, -1.2],
                },
                &[[0.1 * f, -0.2, 0.3]; 15],
            );
        }
        for (level, tol) in [(HIGH, 1e-4), (MEDIUM, 1e-3)] {
            let glb = write_meshopt_glb(&s, [0.0; 3], IDENTITY, &level).unwrap();
            let plain = decompress_meshopt_glb(&glb).unwrap();
            let d = read_tile_glb(&plain).unwrap().splats;
            let d = in_caller_order(&d, &storage_order(&relative_f32(&s, [0.0; 3])));
            assert_eq!(d.len(), 300);
            assert_eq!(d.sh_degree, level.max_sh_degree.min(3));
            for i in 0..300 {
                let (a, b) = (s.get(i), d.get(i));
                for k in 0..3 {
                    assert!((a.position[k] - b.position[k]).abs() < 2.0 * 2.0 * tol);
                    let rel = (a.scale[k] - b.scale[k]).abs() / a.scale[k];
                    assert!(rel < 0.05, "scale {i} {k}: {rel}");
                }
                let dot: f32 = (0..4).map(|k| a.rotation[k] * b.rotation[k]).sum();
                assert!(dot.abs() > 0.99, "rotation {i}: {dot}");
                assert!((a.opacity - b.opacity).abs() < 0.05);
            }
        }
    }

    #[test]
    fn fixed_point_sh_rest_keeps_an_absolute_step() {
        // Coefficients from 1e-4 to 0.5: fixed point over the tile rounds the small ones to zero
        // and keeps every one within half a step; one exponent per coefficient's RGB keeps the
        // small ones to their own relative step.
        // Odd splats 0.0025-0.4975, even ones 1e-4, the last 0.5: the tile's largest |value|.
        let mut s = Splats::new(1);
        for i in 0..=200 {
            let c = match i {
                200 => 0.5,
                _ if i % 2 == 0 => 1e-4,
                _ => 0.5 * i as f32 / 200.0,
            };
            s.push(
                Splat {
                    position: [i as f64 * 0.01, 0.0, 0.0],
                    scale: [0.01; 3],
                    rotation: [0.0, 0.0, 0.0, 1.0],
                    opacity: 0.5,
                    sh0: [0.1; 3],
                },
                &[[c, -c, c]; 3],
            );
        }
        let decode = |mode| {
            let level = MeshoptLevel {
                sh_rest_mode: mode,
                sh_rest_bits: 8,
                ..HIGH
            };
            let glb = write_meshopt_glb(&s, [0.0; 3], IDENTITY, &level).unwrap();
            let d = read_tile_glb(&decompress_meshopt_glb(&glb).unwrap())
                .unwrap()
                .splats;
            in_caller_order(&d, &storage_order(&relative_f32(&s, [0.0; 3])))
        };
        let fixed = decode(ExpMode::SharedComponent);
        // The exponent is a power of two: 0.5 lies in [2^-1, 2^0), so 8 bits with the sign
        // give a step of 2^0 / 2^7.
        let step = 1.0 / 128.0;
        for (a, b) in s.sh_rest.iter().zip(&fixed.sh_rest) {
            for k in 0..3 {
                assert!((a[k] - b[k]).abs() <= step * 0.5 + 1e-6, "{a:?} -> {b:?}");
                if a[k].abs() < step * 0.25 {
                    assert_eq!(b[k], 0.0, "{a:?} -> {b:?}");
                }
            }
        }
        let relative = decode(ExpMode::SharedVector);
        let tiny = relative
            .sh_rest
            .iter()
            .filter(|c| c[0].abs() > 0.0 && c[0].abs() < 1e-3);
        assert_eq!(
            tiny.count(),
            100 * 3,
            "the small coefficients keep their own exponent"
        );
    }
}
