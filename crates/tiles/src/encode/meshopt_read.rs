//! Reading `EXT_meshopt_compression` tiles (High / Medium): the vertex-codec decode and the
//! EXPONENTIAL / QUATERNION filters in pure Rust, the same in the native and the web build.

use serde_json::{Value, json};

use super::glb::{GlbError, parse_json, read_glb, write_gltf_glb};
use super::gltf::{Buffer, EXT_MESHOPT_COMPRESSION, Gltf};

/// Why a meshopt stream was refused.
const NO_DECODE: &str = "meshopt stream does not decode";

/// Decodes a meshopt ATTRIBUTES stream (bitstream version 0) into `count * stride` bytes with
/// the pure-Rust port of meshoptimizer (`meshoptimizer-rs`, byte-identical to the C library,
/// which wasm cannot link): the same decoder in the native and the web build. `None` for a
/// malformed stream.
pub(crate) fn decode_attributes(src: &[u8], count: usize, stride: usize) -> Option<Vec<u8>> {
    let mut ws = meshoptimizer_rs::Workspace::new(meshoptimizer_rs::Limits::default());
    meshoptimizer_rs::codec::decode_vertex_buffer(count, stride, src, &mut ws).ok()
}

/// Runs a meshopt decode filter (EXPONENTIAL, QUATERNION; anything else: none) over `data`
/// (`data.len() / stride` elements of `stride` bytes) in place; `false` when the filter refuses
/// the layout.
pub fn filter_in_place(data: &mut [u8], stride: usize, filter: &str) -> bool {
    let count = data.len() / stride.max(1);
    if count == 0 {
        return true;
    }
    let mut ws = meshoptimizer_rs::Workspace::new(meshoptimizer_rs::Limits::default());
    let data = &mut data[..count * stride];
    match filter {
        "EXPONENTIAL" => {
            meshoptimizer_rs::codec::decode_filter_exp(data, count, stride, &mut ws).is_ok()
        }
        "QUATERNION" => {
            meshoptimizer_rs::codec::decode_filter_quat(data, count, stride, &mut ws).is_ok()
        }
        _ => true,
    }
}

/// Reference decoder: turns an `EXT_meshopt_compression` glb into a plain glb (every compressed
/// bufferView decoded and unfiltered into one BIN chunk) that [`super::read_tile_glb`] reads.
/// A glb without the extension is returned unchanged.
pub fn decompress_meshopt_glb(bytes: &[u8]) -> Result<Vec<u8>, GlbError> {
    let chunks = read_glb(bytes)?;
    let mut doc: Gltf = parse_json(&chunks)?;
    if !doc
        .extensions_used
        .iter()
        .any(|e| e == EXT_MESHOPT_COMPRESSION)
    {
        return Ok(bytes.to_vec());
    }
    let bin = chunks.bin.unwrap_or(&[]);
    let mut out = Vec::new();
    for (i, view) in doc.buffer_views.iter_mut().enumerate() {
        let path = format!("/bufferViews/{i}/extensions/{EXT_MESHOPT_COMPRESSION}");
        let ext = view
            .extensions
            .as_mut()
            .and_then(|e| e.remove(EXT_MESHOPT_COMPRESSION));
        out.resize(out.len().next_multiple_of(4), 0);
        let data = match ext {
            Some(ext) => {
                let field = |k: &str| ext.get(k).and_then(Value::as_u64);
                let (Some(off), Some(len), Some(stride), Some(count)) = (
                    field("byteOffset").or(Some(0)),
                    field("byteLength"),
                    field("byteStride"),
                    field("count"),
                ) else {
                    return Err(GlbError::invalid(
                        path,
                        "missing byteLength/byteStride/count",
                    ));
                };
                if field("buffer") != Some(0) || ext.get("mode") != Some(&json!("ATTRIBUTES")) {
                    return Err(GlbError::unsupported(
                        path,
                        "only ATTRIBUTES streams in the BIN chunk",
                    ));
                }
                let src = bin
                    .get(off as usize..(off + len) as usize)
                    .ok_or_else(|| GlbError::invalid(&path, "stream runs past the BIN chunk"))?;
                if count * stride > bytes.len() as u64 * 1032 + 4096 {
                    return Err(GlbError::invalid(
                        &path,
                        "count * byteStride is implausible",
                    ));
                }
                let mut data = decode_attributes(src, count as usize, stride as usize)
                    .ok_or_else(|| GlbError::invalid(&path, NO_DECODE))?;
                let filter = ext.get("filter").and_then(Value::as_str).unwrap_or("NONE");
                if !filter_in_place(&mut data, stride as usize, filter) {
                    return Err(GlbError::invalid(
                        &path,
                        format!("filter {filter} does not fit byteStride {stride}"),
                    ));
                }
                data
            }
            None => {
                let b = if view.buffer == 0 { bin } else { &[][..] };
                b.get(view.byte_offset as usize..(view.byte_offset + view.byte_length) as usize)
                    .ok_or_else(|| GlbError::invalid(format!("/bufferViews/{i}"), "out of range"))?
                    .to_vec()
            }
        };
        view.buffer = 0;
        view.byte_offset = out.len() as u64;
        view.byte_length = data.len() as u64;
        view.extensions = None;
        out.extend_from_slice(&data);
    }
    out.resize(out.len().next_multiple_of(4), 0);
    doc.buffers = vec![Buffer {
        byte_length: out.len() as u64,
        ..Default::default()
    }];
    doc.extensions_used.retain(|e| e != EXT_MESHOPT_COMPRESSION);
    doc.extensions_required
        .retain(|e| e != EXT_MESHOPT_COMPRESSION);
    write_gltf_glb(&doc, Some(&out))
}
