//! The `SPLAT2TILES_layer` primitive extension in a glb: added to a written tile (a new FLOAT
//! SCALAR accessor at the end of the BIN chunk) and read back with every reference bounded.

use super::EXTENSION;
use crate::encode::glb::{GlbError, parse_json, read_glb, write_gltf_glb};
use crate::encode::gltf::{Accessor, AccessorType, BufferView, ComponentType, Gltf};
use serde_json::{Value, json};

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

/// Returns `glb` with its splat primitive marked as layer `level`; `deltas` (the parent
/// layer's opacity deltas, one per parent splat) go into a new accessor after the existing
/// BIN data, so any prefix of the splat data stays where it was.
pub fn add_layer(glb: &[u8], level: u32, deltas: Option<&[f32]>) -> Result<Vec<u8>, GlbError> {
    let chunks = read_glb(glb)?;
    let mut doc = parse_json(&chunks)?;
    let (m, p) = splat_primitive(&doc)
        .ok_or_else(|| GlbError::invalid("/meshes", "no KHR_gaussian_splatting primitive"))?;
    let mut bin = chunks.bin.map(<[u8]>::to_vec).unwrap_or_default();
    let mut ext = json!({ "level": level });
    if let Some(d) = deltas {
        if doc.buffers.is_empty() || doc.buffers[0].uri.is_some() {
            return Err(GlbError::invalid(
                "/buffers/0",
                "no BIN chunk buffer to extend",
            ));
        }
        while bin.len() % 4 != 0 {
            bin.push(0);
        }
        let offset = bin.len() as u64;
        for v in d {
            bin.extend_from_slice(&v.to_le_bytes());
        }
        doc.buffer_views.push(BufferView {
            buffer: 0,
            byte_offset: offset,
            byte_length: (d.len() * 4) as u64,
            ..Default::default()
        });
        doc.accessors.push(Accessor {
            buffer_view: Some(doc.buffer_views.len() as u32 - 1),
            byte_offset: 0,
            component_type: ComponentType::F32.code(),
            normalized: false,
            count: d.len() as u64,
            kind: AccessorType::Scalar,
            min: None,
            max: None,
            sparse: None,
            name: Some("parentOpacityDelta".into()),
        });
        ext["parentOpacityDelta"] = json!(doc.accessors.len() - 1);
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
/// not a u32, accessor missing or not an in-bounds, tightly packed FLOAT SCALAR).
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
    let Some(acc) = ext.get("parentOpacityDelta") else {
        return Ok(Some(LayerInfo {
            level,
            parent_opacity_delta: None,
            delta_accessor_path: None,
        }));
    };
    let index = acc.as_u64().ok_or_else(|| {
        GlbError::invalid(
            format!("{path}/parentOpacityDelta"),
            "must be an accessor index",
        )
    })?;
    let apath = format!("/accessors/{index}");
    let a = doc.accessors.get(index as usize).ok_or_else(|| {
        GlbError::invalid(
            format!("{path}/parentOpacityDelta"),
            format!("accessor {index} does not exist"),
        )
    })?;
    if a.kind != AccessorType::Scalar
        || a.component_type != ComponentType::F32.code()
        || a.normalized
        || a.sparse.is_some()
    {
        return Err(GlbError::invalid(
            apath,
            "parentOpacityDelta must be a FLOAT SCALAR accessor without sparse storage",
        ));
    }
    let vi = a.buffer_view.ok_or_else(|| {
        GlbError::invalid(format!("{apath}/bufferView"), "a bufferView is required")
    })?;
    let view = doc.buffer_views.get(vi as usize).ok_or_else(|| {
        GlbError::invalid(
            format!("{apath}/bufferView"),
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
    let bin = chunks.bin.unwrap_or(&[]);
    let bytes = a.count.checked_mul(4);
    let start = view.byte_offset.checked_add(a.byte_offset);
    let end = start.zip(bytes).and_then(|(s, b)| s.checked_add(b));
    let in_view = a
        .byte_offset
        .checked_add(bytes.unwrap_or(u64::MAX))
        .is_some_and(|e| e <= view.byte_length);
    let (Some(start), Some(end)) = (start, end) else {
        return Err(GlbError::invalid(apath, "count overflows"));
    };
    if !in_view || end > bin.len() as u64 || start % 4 != 0 {
        return Err(GlbError::invalid(
            apath,
            format!(
                "{} deltas at byte {start} do not fit its bufferView / the {}-byte BIN chunk (or are unaligned)",
                a.count,
                bin.len()
            ),
        ));
    }
    let deltas = bin[start as usize..end as usize]
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect();
    Ok(Some(LayerInfo {
        level,
        parent_opacity_delta: Some(deltas),
        delta_accessor_path: Some(apath),
    }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::encode::glb::write_glb;
    use crate::encode::tile::IDENTITY;
    use crate::encode::write_tile_glb;
    use crate::splat::{Splat, Splats};

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
