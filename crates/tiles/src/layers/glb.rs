//! The `SPLAT2TILES_layer` primitive extension in a glb: added to a written tile (FLOAT SCALAR
//! accessors, dense or sparse, at the end of the BIN chunk) and read back with every reference bounded.

use super::EXTENSION;
use crate::encode::glb::{GlbChunks, GlbError, parse_json, read_glb, write_gltf_glb};
use crate::encode::gltf::{Accessor, AccessorType, BufferView, ComponentType, Gltf};
use serde_json::{Value, json};

/// Most values the delta accessors of one layer may declare in all (a sparse or all-zero
/// accessor's count costs no bytes in the file, so counts are bounded here before anything is
/// allocated): 2^24, 64 MiB of deltas per layer.
pub const MAX_DELTA_COUNT: u64 = 1 << 24;

/// A tile's layer, as its glb declares it.
#[derive(Debug, Clone, PartialEq)]
pub struct LayerInfo {
    /// Its level (0: the base layer, the root tile's content).
    pub level: u32,
    /// Opacity delta of each of the parent layer's splats, in the parent's splat order
    /// (absent for the base layer).
    pub parent_opacity_delta: Option<Vec<f32>>,
    /// JSON path of the delta accessor (`/accessors/N`), when present.
    pub delta_accessor_path: Option<String>,
    /// Format v2: opacity deltas for the splats of ancestor layers above the parent, in the
    /// order the extension lists them.
    pub ancestor_opacity_deltas: Vec<AncestorDeltas>,
}

/// One entry of `ancestorOpacityDeltas`: deltas for the ancestor layer at `level`.
#[derive(Debug, Clone, PartialEq)]
pub struct AncestorDeltas {
    /// The ancestor's level (below this layer's level - 1).
    pub level: u32,
    /// One delta per splat of that ancestor's content, in its splat order.
    pub deltas: Vec<f32>,
    /// JSON path of the accessor (`/accessors/N`).
    pub accessor_path: String,
}

/// Index of the primitive (mesh, primitive) carrying `KHR_gaussian_splatting`.
fn splat_primitive(doc: &Gltf) -> Option<(usize, usize)> {
    doc.meshes.iter().enumerate().find_map(|(m, mesh)| {
        mesh.primitives
            .iter()
            .position(|p| {
                p.extensions
                    .as_ref()
                    .is_some_and(|e| e.gaussian_splatting.is_some())
            })
            .map(|p| (m, p))
    })
}

/// Appends `bytes` to `bin` (4-aligned) as a new bufferView of buffer 0; returns its index.
fn push_view(doc: &mut Gltf, bin: &mut Vec<u8>, bytes: &[u8]) -> u32 {
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let offset = bin.len() as u64;
    bin.extend_from_slice(bytes);
    doc.buffer_views.push(BufferView {
        buffer: 0,
        byte_offset: offset,
        byte_length: bytes.len() as u64,
        ..Default::default()
    });
    doc.buffer_views.len() as u32 - 1
}

/// Appends `values` as a FLOAT SCALAR accessor named `name`: tightly packed, or (when
/// `sparse_if_smaller` and fewer bytes) sparse over zeros, with UNSIGNED_INT indices of the
/// non-zero values; no bufferView at all when every value is 0. Returns the accessor index.
fn push_deltas(
    doc: &mut Gltf,
    bin: &mut Vec<u8>,
    values: &[f32],
    name: &str,
    sparse_if_smaller: bool,
) -> usize {
    let nonzero: Vec<usize> = (0..values.len()).filter(|&i| values[i] != 0.0).collect();
    let sparse = sparse_if_smaller && nonzero.len() * 8 < values.len() * 4;
    let mut acc = Accessor {
        buffer_view: None,
        byte_offset: 0,
        component_type: ComponentType::F32.code(),
        normalized: false,
        count: values.len() as u64,
        kind: AccessorType::Scalar,
        min: None,
        max: None,
        sparse: None,
        name: Some(name.into()),
    };
    if !sparse {
        let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
        acc.buffer_view = Some(push_view(doc, bin, &bytes));
    } else if !nonzero.is_empty() {
        let idx: Vec<u8> = nonzero
            .iter()
            .flat_map(|&i| (i as u32).to_le_bytes())
            .collect();
        let val: Vec<u8> = nonzero
            .iter()
            .flat_map(|&i| values[i].to_le_bytes())
            .collect();
        let iv = push_view(doc, bin, &idx);
        let vv = push_view(doc, bin, &val);
        acc.sparse = Some(json!({
            "count": nonzero.len(),
            "indices": {"bufferView": iv, "componentType": ComponentType::U32.code()},
            "values": {"bufferView": vv},
        }));
    }
    doc.accessors.push(acc);
    doc.accessors.len() - 1
}

/// Returns `glb` with its splat primitive marked as layer `level`; `deltas` (the parent
/// layer's opacity deltas, one per parent splat) go into a new accessor after the existing
/// BIN data, so any prefix of the splat data stays where it was. Format v1 (dense deltas only).
pub fn add_layer(glb: &[u8], level: u32, deltas: Option<&[f32]>) -> Result<Vec<u8>, GlbError> {
    write_layer(glb, level, deltas, &[], false)
}

/// [`add_layer`] in format v2: `ancestors` (ancestor level, one delta per splat of that
/// ancestor's content) become `ancestorOpacityDeltas`, and every delta accessor is written
/// sparse where that is smaller (mostly-zero deltas).
pub fn add_layer_v2(
    glb: &[u8],
    level: u32,
    parent: Option<&[f32]>,
    ancestors: &[(u32, &[f32])],
) -> Result<Vec<u8>, GlbError> {
    write_layer(glb, level, parent, ancestors, true)
}

fn write_layer(
    glb: &[u8],
    level: u32,
    deltas: Option<&[f32]>,
    ancestors: &[(u32, &[f32])],
    sparse: bool,
) -> Result<Vec<u8>, GlbError> {
    let chunks = read_glb(glb)?;
    let mut doc = parse_json(&chunks)?;
    let (m, p) = splat_primitive(&doc)
        .ok_or_else(|| GlbError::invalid("/meshes", "no KHR_gaussian_splatting primitive"))?;
    let mut bin = chunks.bin.map(<[u8]>::to_vec).unwrap_or_default();
    let mut ext = json!({ "level": level });
    if deltas.is_some() || !ancestors.is_empty() {
        if doc.buffers.is_empty() || doc.buffers[0].uri.is_some() {
            return Err(GlbError::invalid(
                "/buffers/0",
                "no BIN chunk buffer to extend",
            ));
        }
        if let Some(d) = deltas {
            let a = push_deltas(&mut doc, &mut bin, d, "parentOpacityDelta", sparse);
            ext["parentOpacityDelta"] = json!(a);
        }
        let mut list = vec![];
        for &(j, d) in ancestors {
            let a = push_deltas(&mut doc, &mut bin, d, &format!("opacityDelta{j}"), sparse);
            list.push(json!({"level": j, "accessor": a}));
        }
        if !list.is_empty() {
            ext["ancestorOpacityDeltas"] = Value::Array(list);
        }
        doc.buffers[0].byte_length = bin.len() as u64;
    }
    let prim = &mut doc.meshes[m].primitives[p];
    prim.extensions
        .get_or_insert_with(Default::default)
        .other
        .insert(EXTENSION.into(), ext);
    if !doc.extensions_used.iter().any(|e| e == EXTENSION) {
        doc.extensions_used.push(EXTENSION.into());
    }
    write_gltf_glb(&doc, Some(&bin))
}

/// Reads the layer a glb declares: `Ok(None)` when its splat primitive has no
/// `SPLAT2TILES_layer`; an error naming the JSON path when the extension is malformed (level
/// not a u32, an accessor missing or not an in-bounds FLOAT SCALAR, tightly packed or sparse
/// with in-range, strictly increasing UNSIGNED_INT indices; an ancestor level listed twice).
/// Whether each ancestor level lies below `level - 1` is left to the caller (the validator
/// reports it; composing refuses it).
pub fn read_layer(glb: &[u8]) -> Result<Option<LayerInfo>, GlbError> {
    let chunks = read_glb(glb)?;
    let doc = parse_json(&chunks)?;
    let Some((m, p)) = splat_primitive(&doc) else {
        return Ok(None);
    };
    let path = format!("/meshes/{m}/primitives/{p}/extensions/{EXTENSION}");
    let Some(ext) = doc.meshes[m].primitives[p]
        .extensions
        .as_ref()
        .and_then(|e| e.other.get(EXTENSION))
    else {
        return Ok(None);
    };
    let level = ext
        .get("level")
        .and_then(Value::as_u64)
        .filter(|&l| l <= u32::MAX as u64)
        .ok_or_else(|| {
            GlbError::invalid(format!("{path}/level"), "level must be an integer >= 0")
        })? as u32;
    let mut info = LayerInfo {
        level,
        parent_opacity_delta: None,
        delta_accessor_path: None,
        ancestor_opacity_deltas: vec![],
    };
    let mut budget = MAX_DELTA_COUNT;
    if let Some(acc) = ext.get("parentOpacityDelta") {
        let (deltas, apath) = read_deltas(
            &doc,
            &chunks,
            acc,
            &format!("{path}/parentOpacityDelta"),
            &mut budget,
        )?;
        info.parent_opacity_delta = Some(deltas);
        info.delta_accessor_path = Some(apath);
    }
    if let Some(list) = ext.get("ancestorOpacityDeltas") {
        let lpath = format!("{path}/ancestorOpacityDeltas");
        let list = list
            .as_array()
            .ok_or_else(|| GlbError::invalid(&lpath, "must be an array"))?;
        for (n, e) in list.iter().enumerate() {
            let epath = format!("{lpath}/{n}");
            let j = e
                .get("level")
                .and_then(Value::as_u64)
                .filter(|&j| j <= u32::MAX as u64)
                .ok_or_else(|| {
                    GlbError::invalid(format!("{epath}/level"), "level must be an integer >= 0")
                })? as u32;
            if info.ancestor_opacity_deltas.iter().any(|a| a.level == j) {
                return Err(GlbError::invalid(
                    format!("{epath}/level"),
                    format!("ancestor level {j} is listed twice"),
                ));
            }
            let acc = e.get("accessor").ok_or_else(|| {
                GlbError::invalid(format!("{epath}/accessor"), "an accessor is required")
            })?;
            let (deltas, accessor_path) = read_deltas(
                &doc,
                &chunks,
                acc,
                &format!("{epath}/accessor"),
                &mut budget,
            )?;
            info.ancestor_opacity_deltas.push(AncestorDeltas {
                level: j,
                deltas,
                accessor_path,
            });
        }
    }
    Ok(Some(info))
}

/// `count` u32 or f32 words of bufferView `vi` at `byte_offset`, bounded by the view and the
/// BIN chunk; `at` is the JSON path of the reference.
fn words<'a>(
    doc: &Gltf,
    bin: &'a [u8],
    vi: u64,
    byte_offset: u64,
    count: u64,
    at: &str,
) -> Result<&'a [u8], GlbError> {
    let view = doc.buffer_views.get(vi as usize).ok_or_else(|| {
        GlbError::invalid(
            format!("{at}/bufferView"),
            format!("bufferView {vi} does not exist"),
        )
    })?;
    if view.buffer != 0 || doc.buffers.first().is_none_or(|b| b.uri.is_some()) {
        return Err(GlbError::invalid(
            format!("/bufferViews/{vi}/buffer"),
            "the deltas must lie in the BIN chunk (buffer 0)",
        ));
    }
    if view.byte_stride.is_some_and(|s| s != 4) {
        return Err(GlbError::invalid(
            format!("/bufferViews/{vi}/byteStride"),
            "the deltas must be tightly packed",
        ));
    }
    let bytes = count.checked_mul(4);
    let start = view.byte_offset.checked_add(byte_offset);
    let end = start.zip(bytes).and_then(|(s, b)| s.checked_add(b));
    let in_view = byte_offset
        .checked_add(bytes.unwrap_or(u64::MAX))
        .is_some_and(|e| e <= view.byte_length);
    let (Some(start), Some(end)) = (start, end) else {
        return Err(GlbError::invalid(at, "count overflows"));
    };
    if !in_view || end > bin.len() as u64 || start % 4 != 0 {
        return Err(GlbError::invalid(
            at,
            format!(
                "{count} values at byte {start} do not fit bufferView {vi} / the {}-byte BIN chunk (or are unaligned)",
                bin.len()
            ),
        ));
    }
    Ok(&bin[start as usize..end as usize])
}

fn f32s(b: &[u8]) -> impl Iterator<Item = f32> + '_ {
    b.chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
}

/// Reads the FLOAT SCALAR delta accessor `acc` refers to (dense, sparse, or all zeros without
/// a bufferView); returns its values and its JSON path. `at` is the path of the reference;
/// `budget` is what is left of [`MAX_DELTA_COUNT`] for this layer.
fn read_deltas(
    doc: &Gltf,
    chunks: &GlbChunks<'_>,
    acc: &Value,
    at: &str,
    budget: &mut u64,
) -> Result<(Vec<f32>, String), GlbError> {
    let index = acc
        .as_u64()
        .ok_or_else(|| GlbError::invalid(at, "must be an accessor index"))?;
    let apath = format!("/accessors/{index}");
    let a = doc
        .accessors
        .get(index as usize)
        .ok_or_else(|| GlbError::invalid(at, format!("accessor {index} does not exist")))?;
    if a.kind != AccessorType::Scalar
        || a.component_type != ComponentType::F32.code()
        || a.normalized
    {
        return Err(GlbError::invalid(
            apath,
            "opacity deltas must be a FLOAT SCALAR accessor (not normalized)",
        ));
    }
    if a.count > *budget {
        return Err(GlbError::invalid(
            format!("{apath}/count"),
            format!(
                "{} deltas exceed what is left ({budget}) of the {MAX_DELTA_COUNT} this reader accepts per layer",
                a.count
            ),
        ));
    }
    *budget -= a.count;

    let bin = chunks.bin.unwrap_or(&[]);
    let mut values = match a.buffer_view {
        Some(vi) => f32s(words(doc, bin, vi.into(), a.byte_offset, a.count, &apath)?).collect(),
        None => vec![0.0f32; a.count as usize],
    };
    if let Some(sp) = &a.sparse {
        let spath = format!("{apath}/sparse");
        let n = sp
            .get("count")
            .and_then(Value::as_u64)
            .filter(|&n| n >= 1 && n <= a.count)
            .ok_or_else(|| {
                GlbError::invalid(
                    format!("{spath}/count"),
                    format!(
                        "must be an integer in [1, {}] (the accessor's count)",
                        a.count
                    ),
                )
            })?;
        let view_of = |k: &str| -> Result<(u64, u64), GlbError> {
            let o = sp.get(k);
            let vi = o
                .and_then(|o| o.get("bufferView"))
                .and_then(Value::as_u64)
                .ok_or_else(|| {
                    GlbError::invalid(
                        format!("{spath}/{k}/bufferView"),
                        "a bufferView is required",
                    )
                })?;
            let off = match o.and_then(|o| o.get("byteOffset")) {
                None => 0,
                Some(v) => v.as_u64().ok_or_else(|| {
                    GlbError::invalid(format!("{spath}/{k}/byteOffset"), "must be an integer >= 0")
                })?,
            };
            Ok((vi, off))
        };
        let ct = sp
            .get("indices")
            .and_then(|i| i.get("componentType"))
            .and_then(Value::as_u64);
        if ct != Some(ComponentType::U32.code() as u64) {
            return Err(GlbError::invalid(
                format!("{spath}/indices/componentType"),
                "sparse delta indices must be UNSIGNED_INT (5125)",
            ));
        }
        let (iv, io) = view_of("indices")?;
        let (vv, vo) = view_of("values")?;
        let idx = words(doc, bin, iv, io, n, &format!("{spath}/indices"))?;
        let val = words(doc, bin, vv, vo, n, &format!("{spath}/values"))?;
        let mut prev: Option<u32> = None;
        for (k, (i, v)) in idx
            .chunks_exact(4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .zip(f32s(val))
            .enumerate()
        {
            if u64::from(i) >= a.count || prev.is_some_and(|p| i <= p) {
                return Err(GlbError::invalid(
                    format!("{spath}/indices"),
                    format!(
                        "index {k} is {i}: sparse indices must be strictly increasing and below the count {}",
                        a.count
                    ),
                ));
            }
            prev = Some(i);
            values[i as usize] = v;
        }
    }
    Ok((values, apath))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::encode::glb::write_glb;
    use crate::encode::tile::IDENTITY;
    use crate::encode::write_tile_glb;
    use splat2tiles_core::splat::{Splat, Splats};

    fn tile(n: usize) -> Vec<u8> {
        let mut s = Splats::new(0);
        for i in 0..n {
            s.push(
                Splat {
                    position: [i as f64, 0.0, 0.0],
                    scale: [0.1; 3],
                    rotation: [0.0, 0.0, 0.0, 1.0],
                    opacity: 0.5,
                    sh0: [0.0; 3],
                },
                &[],
            );
        }
        write_tile_glb(&s, [0.0; 3], IDENTITY)
    }

    /// `glb` with its JSON edited by `f`.
    fn edited(glb: &[u8], f: impl FnOnce(&mut Value)) -> Vec<u8> {
        let c = read_glb(glb).unwrap();
        let mut v: Value = serde_json::from_slice(c.json).unwrap();
        f(&mut v);
        write_glb(&serde_json::to_vec(&v).unwrap(), c.bin).unwrap()
    }

    fn ext(v: &mut Value) -> &mut Value {
        &mut v["meshes"][0]["primitives"][0]["extensions"][EXTENSION]
    }

    #[test]
    fn layers_round_trip_and_keep_the_splats() {
        let plain = tile(3);
        assert_eq!(read_layer(&plain).unwrap(), None);
        let base = add_layer(&plain, 0, None).unwrap();
        let l = read_layer(&base).unwrap().unwrap();
        assert_eq!((l.level, l.parent_opacity_delta), (0, None));
        let d = [-1.0f32, -0.5, 0.0, -0.25, -0.75];
        let child = add_layer(&plain, 3, Some(&d)).unwrap();
        let l = read_layer(&child).unwrap().unwrap();
        assert_eq!(l.level, 3);
        assert_eq!(l.parent_opacity_delta.as_deref(), Some(&d[..]));
        let a = crate::encode::read_tile_glb(&plain).unwrap();
        let b = crate::encode::read_tile_glb(&child).unwrap();
        assert_eq!(a.splats, b.splats);
    }

    #[test]
    fn v2_sparse_and_ancestor_deltas_round_trip() {
        let plain = tile(2);
        let mut far = vec![0.0f32; 50];
        far[3] = 2.5;
        far[49] = -1.0;
        let near = [0.25f32, -0.5, 0.0];
        let zeros = [0.0f32; 4];
        let g = add_layer_v2(&plain, 3, Some(&near), &[(0, &far), (1, &zeros)]).unwrap();
        let l = read_layer(&g).unwrap().unwrap();
        assert_eq!(l.level, 3);
        assert_eq!(l.parent_opacity_delta.as_deref(), Some(&near[..]));
        assert_eq!(l.ancestor_opacity_deltas.len(), 2);
        assert_eq!(
            (
                l.ancestor_opacity_deltas[0].level,
                &l.ancestor_opacity_deltas[0].deltas
            ),
            (0, &far)
        );
        assert_eq!(l.ancestor_opacity_deltas[1].deltas, zeros);
        // 2 of 50 non-zero: sparse; all zeros: no bufferView at all.
        let c = read_glb(&g).unwrap();
        let v: Value = serde_json::from_slice(c.json).unwrap();
        let acc = |n: usize| {
            let a = ext_of(&v)["ancestorOpacityDeltas"][n]["accessor"]
                .as_u64()
                .unwrap() as usize;
            v["accessors"][a].clone()
        };
        assert!(acc(0).get("bufferView").is_none());
        assert_eq!(acc(0)["sparse"]["count"], json!(2));
        assert!(acc(1).get("bufferView").is_none() && acc(1).get("sparse").is_none());
        let a = crate::encode::read_tile_glb(&plain).unwrap();
        let b = crate::encode::read_tile_glb(&g).unwrap();
        assert_eq!(a.splats, b.splats);
    }

    /// `glb` with sparse index `k` (in the bufferView `view` picks) set to `val`.
    fn poked_index(glb: &[u8], view: impl Fn(&mut Value) -> usize, k: usize, val: u32) -> Vec<u8> {
        let c = read_glb(glb).unwrap();
        let mut v: Value = serde_json::from_slice(c.json).unwrap();
        let i = view(&mut v);
        let at =
            c.bin_offset + v["bufferViews"][i]["byteOffset"].as_u64().unwrap() as usize + 4 * k;
        let mut out = glb.to_vec();
        out[at..at + 4].copy_from_slice(&val.to_le_bytes());
        out
    }

    fn ext_of(v: &Value) -> &Value {
        &v["meshes"][0]["primitives"][0]["extensions"][EXTENSION]
    }

    #[test]
    fn malformed_v2_entries_are_refused_with_their_path() {
        let mut far = vec![0.0f32; 50];
        far[3] = 2.5;
        far[7] = 1.0;
        let g = add_layer_v2(&tile(2), 3, Some(&[0.0, 0.0]), &[(1, &far)]).unwrap();
        let sparse = |v: &mut Value| {
            let a = ext(v)["ancestorOpacityDeltas"][0]["accessor"]
                .as_u64()
                .unwrap() as usize;
            v["accessors"][a]["sparse"].clone()
        };
        let idx_view =
            |v: &mut Value| sparse(v)["indices"]["bufferView"].as_u64().unwrap() as usize;
        let bad: Vec<(Vec<u8>, &str)> = vec![
            (
                edited(&g, |v| {
                    ext(v)["ancestorOpacityDeltas"][0]["level"] = json!(-2)
                }),
                "/ancestorOpacityDeltas/0/level",
            ),
            (
                edited(&g, |v| ext(v)["ancestorOpacityDeltas"] = json!({})),
                "/ancestorOpacityDeltas",
            ),
            (
                edited(&g, |v| {
                    let e = ext(v)["ancestorOpacityDeltas"][0].clone();
                    ext(v)["ancestorOpacityDeltas"]
                        .as_array_mut()
                        .unwrap()
                        .push(e);
                }),
                "/ancestorOpacityDeltas/1/level",
            ),
            (
                edited(&g, |v| {
                    let a = ext(v)["ancestorOpacityDeltas"][0]["accessor"]
                        .as_u64()
                        .unwrap() as usize;
                    v["accessors"][a]["count"] = json!(5);
                }),
                "/sparse/indices",
            ),
            (
                edited(&g, |v| {
                    let a = ext(v)["ancestorOpacityDeltas"][0]["accessor"]
                        .as_u64()
                        .unwrap() as usize;
                    v["accessors"][a]["count"] = json!(MAX_DELTA_COUNT + 1);
                }),
                "/count",
            ),
            (
                edited(&g, |v| {
                    let a = ext(v)["ancestorOpacityDeltas"][0]["accessor"]
                        .as_u64()
                        .unwrap() as usize;
                    v["accessors"][a]["sparse"]["count"] = json!(3);
                }),
                "/sparse/indices",
            ),
            (
                edited(&g, |v| {
                    let a = ext(v)["ancestorOpacityDeltas"][0]["accessor"]
                        .as_u64()
                        .unwrap() as usize;
                    v["accessors"][a]["sparse"]["indices"]["componentType"] = json!(5123);
                }),
                "/sparse/indices/componentType",
            ),
            (
                // Three all-zero accessors of 2^23 values: no bytes in the file, 96 MiB if read.
                edited(&g, |v| {
                    let n = v["accessors"].as_array().unwrap().len();
                    let list: Vec<Value> = (0..3)
                        .map(|j| json!({"level": j + 10, "accessor": n + j}))
                        .collect();
                    ext(v)["ancestorOpacityDeltas"] = Value::Array(list);
                    for _ in 0..3 {
                        v["accessors"].as_array_mut().unwrap().push(
                            json!({"componentType": 5126, "count": 1u64 << 23, "type": "SCALAR"}),
                        );
                    }
                }),
                "per layer",
            ),
            (poked_index(&g, idx_view, 1, 3), "index 1 is 3"),
            (poked_index(&g, idx_view, 1, 50), "index 1 is 50"),
        ];
        for (i, (b, want)) in bad.iter().enumerate() {
            let e = read_layer(b).expect_err(&format!("case {i}"));
            assert!(e.to_string().contains(want), "case {i}: {e}");
        }
    }

    #[test]
    fn malformed_extensions_are_refused_with_their_path() {
        let child = add_layer(&tile(2), 1, Some(&[-1.0, 0.0])).unwrap();
        let bad = [
            edited(&child, |v| ext(v)["level"] = json!(-1)),
            edited(&child, |v| ext(v)["parentOpacityDelta"] = json!(99)),
            edited(&child, |v| {
                let a = ext(v)["parentOpacityDelta"].as_u64().unwrap() as usize;
                v["accessors"][a]["componentType"] = json!(5123);
            }),
            edited(&child, |v| {
                let a = ext(v)["parentOpacityDelta"].as_u64().unwrap() as usize;
                v["accessors"][a]["count"] = json!(1u64 << 40);
            }),
            edited(&child, |v| {
                let a = ext(v)["parentOpacityDelta"].as_u64().unwrap() as usize;
                v["accessors"][a]["count"] = json!(u64::MAX / 2);
            }),
        ];
        for (i, b) in bad.iter().enumerate() {
            let e = read_layer(b).expect_err(&format!("case {i}"));
            assert!(e.to_string().contains('/'), "case {i}: {e}");
        }
    }
}
