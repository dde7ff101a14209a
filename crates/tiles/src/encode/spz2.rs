//! SPZ v2 encoder (Niantic layout, CesiumJS conventions) and `KHR_gaussian_splatting_compression_spz_2`
//! tiles: the SPZ payload in the BIN chunk, accessors without bufferView; reference decoder.

use std::collections::BTreeMap;
use std::io::Write;

use serde_json::{Map, json};

use super::glb::{GlbError, parse_json, read_glb, write_gltf_glb};
use super::gltf::{
    Accessor, AccessorType, Buffer, BufferView, ComponentType, KHR_GAUSSIAN_SPLATTING,
    KHR_GAUSSIAN_SPLATTING_SPZ_2,
};
use super::spz_rotation::{RotationFit, rotation_bytes};
use super::storage_order::{in_caller_order, in_storage_order};
use super::tile::{
    ATTR_COLOR_0, ATTR_OPACITY, ATTR_POSITION, ATTR_ROTATION, ATTR_SCALE, IDENTITY, check_writable,
    sh_attribute, splat_document,
};
use splat2tiles_core::splat::{Splats, sh_rest_count};

/// Settings of the SPZ v2 encoder.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SpzOptions {
    /// Highest SH degree written (lower of this and the input's).
    pub max_sh_degree: u8,
    /// Significant bits of degree-1 SH bytes (upstream default 5).
    pub sh1_bits: u8,
    /// Significant bits of degree-2/3 SH bytes (upstream default 4).
    pub sh_rest_bits: u8,
    /// Bits of the largest |coordinate| (sign included): 24 keeps as many fractional bits as
    /// the 24-bit fixed point holds; fewer drop the finest ones, which gzip cannot compress.
    pub position_bits: u8,
    /// Non-zero: positions may be coarser than `position_bits` (down to `min_position_bits`)
    /// while the step stays at most 1/`scale_divisor` of the median smallest splat scale.
    pub scale_divisor: u16,
    /// Fewest bits of the largest |coordinate| that `scale_divisor` may leave.
    pub min_position_bits: u8,
    /// How the rotation bytes are chosen.
    pub rotation_fit: RotationFit,
}

impl Default for SpzOptions {
    fn default() -> Self {
        SpzOptions {
            max_sh_degree: 3,
            sh1_bits: 5,
            sh_rest_bits: 4,
            position_bits: 24,
            scale_divisor: 0,
            min_position_bits: 24,
            rotation_fit: RotationFit::Covariance,
        }
    }
}

/// Fractional bits of the 24-bit fixed-point positions that keep `position_bits` (at most 24)
/// bits of `max_abs`: the most that fit, less `24 - position_bits`.
pub fn position_fractional_bits(max_abs: f64, position_bits: u8) -> u8 {
    fractional_bits(max_abs).saturating_sub(24u8.saturating_sub(position_bits))
}

/// Fractional bits of `splats`' positions under `opts`: those of `position_bits`, or with a
/// `scale_divisor` the fewest (not below those of `min_position_bits`) whose step
/// `2^-bits` is at most the median smallest scale over `scale_divisor`.
pub fn spz_fractional_bits(splats: &Splats, max_abs: f64, opts: &SpzOptions) -> u8 {
    let fine = position_fractional_bits(max_abs, opts.position_bits);
    if opts.scale_divisor == 0 {
        return fine;
    }
    let coarse = position_fractional_bits(max_abs, opts.min_position_bits.min(opts.position_bits));
    match median_smallest_scale(&splats.scales) {
        Some(m) => {
            let need = (f64::from(opts.scale_divisor) / m)
                .log2()
                .ceil()
                .clamp(0.0, 23.0) as u8;
            need.clamp(coarse, fine)
        }
        None => fine,
    }
}

/// Median over splats of the smallest of the three scales (the thin axis, across which a
/// position error shows first); `None` without splats or when it is not positive and finite.
pub fn median_smallest_scale(scales: &[[f32; 3]]) -> Option<f64> {
    let mut smallest: Vec<f32> = scales.iter().map(|s| s[0].min(s[1]).min(s[2])).collect();
    if smallest.is_empty() {
        return None;
    }
    let mid = smallest.len() / 2;
    let (_, m, _) = smallest.select_nth_unstable_by(mid, f32::total_cmp);
    let m = f64::from(*m);
    (m.is_finite() && m > 1e-20).then_some(m)
}

/// Fractional bits of the 24-bit fixed-point positions: the most that keep `max_abs` in range.
pub fn fractional_bits(max_abs: f64) -> u8 {
    if max_abs.is_nan() || max_abs <= 0.0 {
        return 12;
    }
    let limit = ((1u32 << 23) - 1) as f64;
    (limit / max_abs).log2().floor().clamp(0.0, 23.0) as u8
}

fn q8(v: f32) -> u8 {
    v.round().clamp(0.0, 255.0) as u8
}

/// The SPZ v2 stream before gzip: 16-byte header (`NGSP`, version 2, count, SH degree,
/// fractional bits, flags 0, reserved 0) then positions, alphas, colours, scales, rotations, SH.
/// Positions are `position - centre` (no axis change: CesiumJS uses them as glTF coordinates).
pub fn encode_spz_v2_raw(splats: &Splats, centre: [f64; 3], opts: &SpzOptions) -> Vec<u8> {
    let n = splats.len();
    let degree = splats.sh_degree.min(opts.max_sh_degree);
    let k = sh_rest_count(degree);
    let k_in = splats.rest_per_splat();
    let rel: Vec<[f64; 3]> = splats
        .positions
        .iter()
        .map(|p| [p[0] - centre[0], p[1] - centre[1], p[2] - centre[2]])
        .collect();
    let max_abs = rel.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
    let fb = spz_fractional_bits(splats, max_abs, opts);
    let mut out = Vec::with_capacity(16 + n * (19 + 3 * k));
    out.extend_from_slice(b"NGSP");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(n as u32).to_le_bytes());
    out.extend_from_slice(&[degree, fb, 0, 0]);
    let scale = (1u64 << fb) as f64;
    for p in &rel {
        for v in p {
            let f = (v * scale)
                .round()
                .clamp(-(1 << 23) as f64, ((1 << 23) - 1) as f64) as i32;
            out.extend_from_slice(&f.to_le_bytes()[..3]);
        }
    }
    out.extend(splats.opacities.iter().map(|&a| q8(a * 255.0)));
    for c in &splats.sh0 {
        out.extend(c.iter().map(|&d| q8(d * 0.15 * 255.0 + 127.5)));
    }
    for s in &splats.scales {
        out.extend(s.iter().map(|&v| q8((v.max(1e-30).ln() + 10.0) * 16.0)));
    }
    for (q, s) in splats.rotations.iter().zip(&splats.scales) {
        out.extend(rotation_bytes(*q, *s, opts.rotation_fit));
    }
    let bucket = |v: f32, bits: u8| -> u8 {
        let q = (v * 128.0 + 128.0).round().clamp(0.0, 255.0) as u32;
        let b = 1u32 << (8 - bits.clamp(1, 8));
        (((q + b / 2) / b) * b).min(255) as u8
    };
    for i in 0..n {
        for (j, t) in splats.sh_rest[i * k_in..i * k_in + k].iter().enumerate() {
            let bits = if j < 3 {
                opts.sh1_bits
            } else {
                opts.sh_rest_bits
            };
            out.extend(t.iter().map(|&v| bucket(v, bits)));
        }
    }
    out
}

/// Gzips `raw` at zlib's default level 6 (flate2): what `gzip -6` makes of a file, the
/// transfer-encoding measure of the benches (an SPZ payload itself is [`spz_gzip`]).
pub fn gzip(raw: &[u8]) -> Vec<u8> {
    let mut enc = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    enc.write_all(raw).expect("writing to memory");
    enc.finish().expect("writing to memory")
}

/// libdeflate's level for SPZ payloads. Level 6 made Low payloads 1.1-3.2% smaller than zlib-rs's
/// level 6 in 0.55-0.8x its time, on every scene measured. Level 10 (its near-optimal parser) saves
/// 2.5-4.5% on the shared scenes for 1.6-2.6x zlib-rs's time, but 6x on the generated scene of
/// the `variants_speed` bench, which took `--variants all` past 2x Best-only at 5M splats
/// (BENCHMARKS.md, "Low's gzip stream").
#[cfg(feature = "native")]
const SPZ_DEFLATE_LEVEL: i32 = 6;

/// Gzips an SPZ v2 payload (the container is one gzip member): libdeflate at
/// level 6 in the native build; without it (wasm, which only reads SPZ) flate2 at
/// level 6. Every gzip reader inflates either.
pub fn spz_gzip(raw: &[u8]) -> Vec<u8> {
    #[cfg(feature = "native")]
    {
        use libdeflater::{CompressionLvl, Compressor};
        use std::cell::RefCell;
        thread_local! {
            // One compressor a thread, reused tile after tile.
            static COMPRESSOR: RefCell<Option<Compressor>> = const { RefCell::new(None) };
        }
        COMPRESSOR.with_borrow_mut(|c| {
            let c = c.get_or_insert_with(|| {
                Compressor::new(CompressionLvl::new(SPZ_DEFLATE_LEVEL).expect("level in 0..=12"))
            });
            // The bound covers incompressible input plus the gzip framing, so this cannot fail.
            let mut out = vec![0u8; c.gzip_compress_bound(raw.len())];
            let n = c
                .gzip_compress(raw, &mut out)
                .expect("output sized by the bound");
            out.truncate(n);
            out
        })
    }
    #[cfg(not(feature = "native"))]
    {
        gzip(raw)
    }
}

/// The SPZ v2 file of `splats` ([`spz_gzip`] of [`encode_spz_v2_raw`]).
pub fn encode_spz_v2(splats: &Splats, centre: [f64; 3], opts: &SpzOptions) -> Vec<u8> {
    spz_gzip(&encode_spz_v2_raw(splats, centre, opts))
}

fn float_acc(kind: AccessorType, n: usize) -> Accessor {
    Accessor {
        buffer_view: None,
        byte_offset: 0,
        component_type: ComponentType::F32.code(),
        normalized: false,
        count: n as u64,
        kind,
        min: None,
        max: None,
        sparse: None,
        name: None,
    }
}

/// Writes a `KHR_gaussian_splatting_compression_spz_2` tile: the SPZ v2 payload as bufferView 0,
/// accessors (no bufferView) for POSITION, COLOR_0 (DC colour, opacity in alpha), ROTATION,
/// SCALE, OPACITY and SH degrees 1..=d; no `SH_DEGREE_0_COEF_0` (CesiumJS counts `SH_DEGREE_`
/// attributes to find the degree). POSITION min/max are the decoded payload's. The splats are
/// stored in Morton order of their positions (`super::storage_order`), not the caller's.
///
/// COLOR_0 is declared VEC4 unsigned byte normalized (SPZ v2 stores 8-bit colour and alpha;
/// glTF allows it for COLOR_0). CesiumJS 1.145 requires it: it decodes COLOR_0 into RGBA bytes
/// and views them through the accessor's componentType, so a FLOAT declaration yields a quarter
/// of the colours and its splat texture worker panics ("unreachable"); `tests/interop.rs`.
pub fn write_spz2_glb(
    splats: &Splats,
    centre: [f64; 3],
    node_matrix: [f64; 16],
    opts: &SpzOptions,
) -> Result<Vec<u8>, GlbError> {
    Ok(write_spz2_glb_and_decoded(splats, centre, node_matrix, opts)?.0)
}

/// [`write_spz2_glb`] and the splats its payload decodes to (what [`read_spz2_glb`] reads, put
/// back in the caller's order), decoded from the payload before it is gzipped.
pub fn write_spz2_glb_and_decoded(
    splats: &Splats,
    centre: [f64; 3],
    node_matrix: [f64; 16],
    opts: &SpzOptions,
) -> Result<(Vec<u8>, Splats), GlbError> {
    write_spz2(splats, centre, node_matrix, opts, true)
}

/// [`write_spz2_glb`] with the splats in the caller's order rather than Morton order (to measure
/// what the order is worth: `examples/order_bytes.rs`).
pub fn write_spz2_glb_as_given(
    splats: &Splats,
    centre: [f64; 3],
    node_matrix: [f64; 16],
    opts: &SpzOptions,
) -> Result<Vec<u8>, GlbError> {
    Ok(write_spz2(splats, centre, node_matrix, opts, false)?.0)
}

/// [`write_spz2_glb_as_given`] and the splats it decodes to, in the same (caller's) order: for a
/// caller that put the tile in storage order itself, once for several variants.
pub fn write_spz2_glb_as_given_and_decoded(
    splats: &Splats,
    centre: [f64; 3],
    node_matrix: [f64; 16],
    opts: &SpzOptions,
) -> Result<(Vec<u8>, Splats), GlbError> {
    write_spz2(splats, centre, node_matrix, opts, false)
}

/// The SPZ_2 glb of `splats`, stored in Morton order when `morton`, and its decoded splats in
/// the caller's order.
fn write_spz2(
    splats: &Splats,
    centre: [f64; 3],
    node_matrix: [f64; 16],
    opts: &SpzOptions,
    morton: bool,
) -> Result<(Vec<u8>, Splats), GlbError> {
    // Errors name the caller's splat index: checked before reordering.
    check_writable(splats, centre)?;
    // Stored in Morton order of the tile-relative positions (`super::storage_order`).
    let (raw, order) = if morton {
        let (order, stored) = in_storage_order(splats, centre, opts.max_sh_degree);
        (encode_spz_v2_raw(&stored, centre, opts), Some(order))
    } else {
        (encode_spz_v2_raw(splats, centre, opts), None)
    };
    // The uncompressed SPZ v2 stream reads as the gzipped one does (same bytes, no inflate).
    let decoded = splat2tiles_io::read_bytes("tile.spz", &raw)
        .map_err(|e| GlbError::invalid("/bufferViews/0", e.to_string()))?
        .splats;
    let decoded = match &order {
        Some(order) => in_caller_order(&decoded, order),
        None => decoded,
    };
    let payload = spz_gzip(&raw);
    drop(raw);
    let glb = compressed_glb(
        &decoded,
        payload,
        node_matrix,
        KHR_GAUSSIAN_SPLATTING_SPZ_2,
        true,
    )?;
    Ok((glb, decoded))
}

/// A splat glb whose attributes live in `payload` (bufferView 0), decoded by the child extension
/// `extension` of `KHR_gaussian_splatting`: accessors without bufferView for POSITION (min/max of
/// `decoded`), the DC colour (COLOR_0 as RGBA bytes when `dc_in_color`, as SPZ_2 declares it,
/// else `SH_DEGREE_0_COEF_0`), ROTATION, SCALE, OPACITY and SH degrees 1..=d.
pub(super) fn compressed_glb(
    decoded: &Splats,
    payload: Vec<u8>,
    node_matrix: [f64; 16],
    extension: &str,
    dc_in_color: bool,
) -> Result<Vec<u8>, GlbError> {
    if payload.len() as u64 > u32::MAX as u64 {
        return Err(GlbError::TooLarge {
            bytes: payload.len() as u64,
        });
    }
    let n = decoded.len();
    let (lo, hi) = decoded.bounds().ok_or(GlbError::EmptyTile)?;
    let degree = decoded.sh_degree;
    let mut accessors = vec![];
    let mut attributes = BTreeMap::new();
    let mut add = |name: String, acc: Accessor| {
        attributes.insert(name, accessors.len() as u32);
        accessors.push(acc);
    };
    let mut pos = float_acc(AccessorType::Vec3, n);
    pos.min = Some(lo.to_vec());
    pos.max = Some(hi.to_vec());
    add(ATTR_POSITION.into(), pos);
    if dc_in_color {
        let mut color = float_acc(AccessorType::Vec4, n);
        color.component_type = ComponentType::U8.code();
        color.normalized = true;
        add(ATTR_COLOR_0.into(), color);
    } else {
        add(sh_attribute(0, 0), float_acc(AccessorType::Vec3, n));
    }
    add(ATTR_ROTATION.into(), float_acc(AccessorType::Vec4, n));
    add(ATTR_SCALE.into(), float_acc(AccessorType::Vec3, n));
    add(ATTR_OPACITY.into(), float_acc(AccessorType::Scalar, n));
    for l in 1..=degree {
        for c in 0..=2 * l {
            add(sh_attribute(l, c), float_acc(AccessorType::Vec3, n));
        }
    }
    let mut children = Map::new();
    children.insert(extension.into(), json!({ "bufferView": 0 }));
    let mut bin = payload;
    let len = bin.len();
    bin.resize(len.next_multiple_of(4), 0);
    let exts = vec![KHR_GAUSSIAN_SPLATTING.to_string(), extension.to_string()];
    let doc = splat_document(
        attributes,
        accessors,
        vec![BufferView {
            buffer: 0,
            byte_length: len as u64,
            ..Default::default()
        }],
        vec![Buffer {
            byte_length: bin.len() as u64,
            ..Default::default()
        }],
        node_matrix,
        Some(children),
        exts.clone(),
        exts,
    );
    write_gltf_glb(&doc, Some(&bin))
}

/// A tile whose attributes a compression child extension of `KHR_gaussian_splatting` carries.
pub(crate) struct Compressed {
    /// The child extension's name.
    pub extension: String,
    /// The bytes of its `bufferView`.
    pub payload: Vec<u8>,
    /// The first node's matrix.
    pub matrix: [f64; 16],
}

/// The first of `extensions` that the first primitive's `KHR_gaussian_splatting` has as a child,
/// with its payload and the node matrix (the glb parsed once), if it has one.
pub(crate) fn compressed_content(
    bytes: &[u8],
    extensions: &[&str],
) -> Result<Option<Compressed>, GlbError> {
    let chunks = read_glb(bytes)?;
    let doc = parse_json(&chunks)?;
    let children = doc
        .meshes
        .first()
        .and_then(|m| m.primitives.first())
        .and_then(|p| p.extensions.as_ref())
        .and_then(|e| e.gaussian_splatting.as_ref())
        .and_then(|g| g.extensions.as_ref());
    let found = extensions.iter().find_map(|&e| {
        let v = children?.get(e)?.get("bufferView")?.as_u64()?;
        Some((e, v))
    });
    let Some((extension, v)) = found else {
        return Ok(None);
    };
    let bv = doc
        .buffer_views
        .get(v as usize)
        .ok_or_else(|| GlbError::invalid("/bufferViews", format!("bufferView {v} missing")))?;
    let bin = chunks
        .bin
        .ok_or_else(|| GlbError::invalid("/buffers/0", "no BIN chunk"))?;
    let end = bv.byte_offset.saturating_add(bv.byte_length);
    let range = bv.byte_offset as usize..end.min(usize::MAX as u64) as usize;
    let payload = bin
        .get(range)
        .ok_or_else(|| GlbError::invalid(format!("/bufferViews/{v}"), "past the BIN chunk"))?
        .to_vec();
    let matrix = doc.nodes.first().and_then(|n| n.matrix).unwrap_or(IDENTITY);
    Ok(Some(Compressed {
        extension: extension.to_string(),
        payload,
        matrix,
    }))
}

/// The bytes of bufferView `bufferView` of the child extension `extension` of the first
/// primitive's `KHR_gaussian_splatting`, if the glb has that extension.
pub(super) fn compressed_payload(
    bytes: &[u8],
    extension: &str,
) -> Result<Option<Vec<u8>>, GlbError> {
    Ok(compressed_content(bytes, &[extension])?.map(|c| c.payload))
}

/// The SPZ payload of a `KHR_gaussian_splatting_compression_spz_2` glb, if it is one.
pub fn spz2_payload(bytes: &[u8]) -> Result<Option<Vec<u8>>, GlbError> {
    compressed_payload(bytes, KHR_GAUSSIAN_SPLATTING_SPZ_2)
}

/// The splats (tile-relative, as stored) of an SPZ v2 payload.
pub(crate) fn spz2_splats(payload: &[u8]) -> Result<Splats, GlbError> {
    Ok(splat2tiles_io::read_bytes("tile.spz", payload)
        .map_err(|e| GlbError::invalid("/bufferViews/0", e.to_string()))?
        .splats)
}

/// Reference decoder of our SPZ_2 tiles: splats (tile-relative, as stored) and node matrix.
pub fn read_spz2_glb(bytes: &[u8]) -> Result<(Splats, [f64; 16]), GlbError> {
    let c = compressed_content(bytes, &[KHR_GAUSSIAN_SPLATTING_SPZ_2])?
        .ok_or_else(|| GlbError::invalid("/meshes/0/primitives/0", "no SPZ_2 extension"))?;
    Ok((spz2_splats(&c.payload)?, c.matrix))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::encode::storage_order::{relative_f32, storage_order};
    use splat2tiles_core::splat::{Splat, normalize_quat};

    #[test]
    fn spz_gzip_is_one_gzip_member_that_inflates_back() {
        use std::io::Read;
        // Empty, incompressible and repetitive payloads, the last past one deflate block.
        let mut noise = 0x2545_F491u32;
        let random: Vec<u8> = (0..100_000)
            .map(|_| {
                noise ^= noise << 13;
                noise ^= noise >> 17;
                noise ^= noise << 5;
                noise as u8
            })
            .collect();
        let repeats: Vec<u8> = (0..300_000u32).map(|i| (i % 7) as u8).collect();
        for raw in [vec![], random, repeats] {
            let gz = spz_gzip(&raw);
            assert_eq!(&gz[..2], &[0x1f, 0x8b], "gzip magic");
            let mut back = vec![];
            let mut dec = flate2::bufread::GzDecoder::new(&gz[..]);
            dec.read_to_end(&mut back).unwrap();
            assert_eq!(back, raw);
            // Nothing after the member (a single-member reader sees it all).
            let mut rest = vec![];
            dec.into_inner().read_to_end(&mut rest).unwrap();
            assert!(rest.is_empty());
            // Bounded: incompressible input grows by little more than the gzip framing.
            assert!(gz.len() <= raw.len() + raw.len() / 100 + 64);
        }
    }

    fn scene() -> Splats {
        let mut s = Splats::new(3);
        for i in 0..50 {
            let f = i as f32 / 50.0;
            s.push(
                Splat {
                    position: [10.0 + f as f64, -3.0 * f as f64, 2.0],
                    scale: [0.01 + f * 0.1, 0.02, 0.5],
                    rotation: normalize_quat([f - 0.5, 0.3, -0.2, 0.7 - f]),
                    opacity: f,
                    sh0: [f - 0.5, 1.0, -1.2],
                },
                &[[0.1 * f, -0.2, 0.3]; 15],
            );
        }
        s
    }

    #[test]
    fn spz_v2_round_trips_through_the_reader() {
        let s = scene();
        let centre = [10.5, -1.0, 2.0];
        let opts = SpzOptions::default();
        let bytes = encode_spz_v2(&s, centre, &opts);
        let d = splat2tiles_io::read_bytes("t.spz", &bytes).unwrap().splats;
        assert_eq!((d.len(), d.sh_degree), (50, 3));
        let step = 0.5f64.powi(fractional_bits(1.5) as i32);
        #[allow(clippy::needless_range_loop)] // k indexes five arrays at once
        for i in 0..50 {
            let (a, b) = (s.get(i), d.get(i));
            for k in 0..3 {
                assert!((a.position[k] - centre[k] - b.position[k]).abs() <= step);
                assert!((a.sh0[k] - b.sh0[k]).abs() <= 0.5 / (0.15 * 255.0) + 1e-6);
                let r = (b.scale[k] / a.scale[k]).ln().abs();
                assert!(r <= 0.5 / 16.0 + 1e-5, "scale {i}");
            }
            assert!((a.opacity - b.opacity).abs() <= 0.5 / 255.0 + 1e-6);
            let dot: f32 = (0..4).map(|k| a.rotation[k] * b.rotation[k]).sum();
            assert!(dot.abs() > 0.995, "rotation {i}: {dot}");
            for (x, y) in s.rest_of(i).iter().zip(d.rest_of(i)) {
                for k in 0..3 {
                    // 4 significant bits: buckets of 16/128.
                    assert!((x[k] - y[k]).abs() <= 8.5 / 128.0 + 1e-6, "{x:?} {y:?}");
                }
            }
        }
        let low = encode_spz_v2_raw(
            &s,
            centre,
            &SpzOptions {
                max_sh_degree: 1,
                ..opts
            },
        );
        assert_eq!(low.len(), 16 + 50 * (19 + 9));
    }

    /// Fewer position bits: the header says so, the reader honours it and the error stays
    /// within half a step.
    #[test]
    fn fewer_position_bits_drop_fractional_bits() {
        let s = scene();
        let centre = [10.5, -1.0, 2.0];
        let full = SpzOptions::default();
        let coarse = SpzOptions {
            position_bits: 16,
            ..full
        };
        let max_abs = s
            .positions
            .iter()
            .flat_map(|p| (0..3).map(move |a| (p[a] - centre[a]).abs()))
            .fold(0.0, f64::max);
        let fb = position_fractional_bits(max_abs, 16);
        assert_eq!(fb, fractional_bits(max_abs) - 8);
        let raw = encode_spz_v2_raw(&s, centre, &coarse);
        assert_eq!(raw[13], fb);
        let d = splat2tiles_io::read_bytes("t.spz", &encode_spz_v2(&s, centre, &coarse))
            .unwrap()
            .splats;
        let step = 0.5f64.powi(fb as i32);
        for i in 0..s.len() {
            for (k, c) in centre.iter().enumerate() {
                let e = (s.get(i).position[k] - c - d.get(i).position[k]).abs();
                assert!(e <= step / 2.0 + 1e-9, "{i} {k}: {e} > {step}/2");
            }
        }
        assert_eq!(raw.len(), encode_spz_v2_raw(&s, centre, &full).len());
    }

    /// The size rule the two tests below exercise: 18 to 12 bits, a step of at most 1/6 of the
    /// median smallest scale.
    const RULE: SpzOptions = SpzOptions {
        max_sh_degree: 3,
        sh1_bits: 5,
        sh_rest_bits: 4,
        position_bits: 18,
        scale_divisor: 6,
        min_position_bits: 12,
        rotation_fit: RotationFit::Covariance,
    };

    fn cube_of(n: usize, scale: [f32; 3]) -> Splats {
        let mut s = Splats::new(0);
        for i in 0..n {
            let f = i as f64 / (n.max(2) - 1) as f64;
            s.push(
                Splat {
                    position: [2.0 * f - 1.0, 1.0 - 2.0 * f, 0.5],
                    scale,
                    rotation: [0.0, 0.0, 0.0, 1.0],
                    opacity: 0.5,
                    sh0: [0.0; 3],
                },
                &[],
            );
        }
        s
    }

    /// The scale rule: the coarsest step within 1/divisor of the median smallest scale, no finer
    /// than `position_bits` allow and no coarser than `min_position_bits`.
    #[test]
    fn the_step_follows_the_median_smallest_scale_within_its_bounds() {
        let opts = RULE;
        // max |coordinate| 1: 22 fractional bits fit; 18 bits keep 16, 12 bits keep 10.
        assert_eq!(fractional_bits(1.0), 22);
        let fb = |scale: [f32; 3]| spz_fractional_bits(&cube_of(9, scale), 1.0, &opts);
        // 0.001 / 6 = 1.67e-4: 2^-13 = 1.22e-4 fits, 2^-12 = 2.44e-4 does not.
        assert_eq!(fb([0.001; 3]), 13);
        // The smallest axis sets it.
        assert_eq!(fb([0.1, 0.01, 0.001]), 13);
        assert_eq!(fb([0.001, 0.5, 0.5]), 13);
        // Tiny splats: no finer than 18 bits; huge ones: no coarser than 12.
        assert_eq!(fb([1e-9; 3]), 16);
        assert_eq!(fb([100.0; 3]), 10);
        // Without the rule, 18 bits.
        let fixed = SpzOptions {
            scale_divisor: 0,
            ..opts
        };
        assert_eq!(
            spz_fractional_bits(&cube_of(9, [0.001; 3]), 1.0, &fixed),
            16
        );
        // The encoder writes what the rule says, and positions stay within half a step.
        let s = cube_of(9, [0.001; 3]);
        let raw = encode_spz_v2_raw(&s, [0.0; 3], &opts);
        assert_eq!(raw[13], 13);
        let d = splat2tiles_io::read_bytes("t.spz", &encode_spz_v2(&s, [0.0; 3], &opts))
            .unwrap()
            .splats;
        for i in 0..s.len() {
            for k in 0..3 {
                let e = (s.get(i).position[k] - d.get(i).position[k]).abs();
                assert!(e <= 0.5f64.powi(14) + 1e-12, "{i} {k}: {e}");
            }
        }
    }

    /// Degenerate sizes fall back to `position_bits`: no splats, zero scales, infinite scales.
    #[test]
    fn degenerate_sizes_keep_the_fine_step() {
        let opts = RULE;
        assert_eq!(median_smallest_scale(&[]), None);
        assert_eq!(spz_fractional_bits(&cube_of(0, [0.01; 3]), 1.0, &opts), 16);
        assert_eq!(median_smallest_scale(&[[0.0; 3]; 5]), None);
        assert_eq!(spz_fractional_bits(&cube_of(5, [0.0; 3]), 1.0, &opts), 16);
        assert_eq!(median_smallest_scale(&[[f32::INFINITY; 3]; 5]), None);
        assert_eq!(median_smallest_scale(&[[f32::NAN; 3]; 5]), None);
        assert_eq!(
            spz_fractional_bits(&cube_of(5, [f32::MAX; 3]), 1.0, &opts),
            10
        );
        // A zero extent (one splat at the centre) stays finite and in range.
        let fb = spz_fractional_bits(&cube_of(1, [0.01; 3]), 0.0, &opts);
        assert!(fb <= 23);
        let m = median_smallest_scale(&[[1.0, 2.0, 4.0], [8.0; 3], [0.5; 3]]).unwrap();
        assert_eq!(m, 1.0);
    }

    #[test]
    fn the_decoded_splats_are_the_readers() {
        let s = scene();
        let opts = SpzOptions {
            max_sh_degree: 1,
            ..SpzOptions::default()
        };
        let (glb, decoded) =
            write_spz2_glb_and_decoded(&s, [10.0, 0.0, 2.0], IDENTITY, &opts).unwrap();
        let (read, _) = read_spz2_glb(&glb).unwrap();
        // Stored in Morton order; given back in the caller's.
        let order = storage_order(&relative_f32(&s, [10.0, 0.0, 2.0]));
        assert_ne!(
            order,
            (0..s.len()).collect::<Vec<_>>(),
            "the test scene is not in Morton order"
        );
        assert_eq!(decoded, in_caller_order(&read, &order));
        assert_eq!(
            glb,
            write_spz2_glb(&s, [10.0, 0.0, 2.0], IDENTITY, &opts).unwrap()
        );
    }

    #[test]
    fn spz2_tile_decodes_and_declares_cesium_attributes() {
        let s = scene();
        let glb = write_spz2_glb(&s, [10.0, 0.0, 2.0], IDENTITY, &SpzOptions::default()).unwrap();
        let (d, m) = read_spz2_glb(&glb).unwrap();
        assert_eq!((d.len(), m), (50, IDENTITY));
        let doc = parse_json(&read_glb(&glb).unwrap()).unwrap();
        let a = &doc.meshes[0].primitives[0].attributes;
        assert!(!a.contains_key(&sh_attribute(0, 0)));
        assert_eq!(a.keys().filter(|k| k.contains("SH_DEGREE_")).count(), 15);
        assert!(doc.accessors.iter().all(|x| x.buffer_view.is_none()));
    }
}
