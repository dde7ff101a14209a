//! glb content checks: GLB framing (glTF 2.0 sec. 4.4), extensions, node placements; then the
//! buffers (`glb_buffers`) and each `KHR_gaussian_splatting` primitive (`splat_primitive`).

use super::context::{ContentGeom, Ctx};
use super::issues::Issue;
use glam::{DMat4, DQuat, DVec3};
use splat2tiles_tiles::encode::glb::{GlbChunks, GlbError, parse_json, read_glb};
use splat2tiles_tiles::encode::gltf::{Gltf, KHR_GAUSSIAN_SPLATTING, KHR_MESH_QUANTIZATION};

fn glb_issue(name: &str, e: GlbError) -> Issue {
    match e {
        GlbError::Json { offset, message } => {
            Issue::JSON_PARSE_ERROR(format!("{name}@byte {offset}"), message)
        }
        GlbError::Truncated { offset, .. }
        | GlbError::ChunkPastEnd { offset, .. }
        | GlbError::BadChunkType { offset, .. } => {
            Issue::GLB_INVALID(format!("{name}@byte {offset}"), e.to_string())
        }
        // The bytes found are not echoed: the file may be anything (a secret behind a link).
        GlbError::BadMagic { .. } => Issue::GLB_INVALID(
            format!("{name}@byte 0"),
            "not a glb: the first four bytes are not \"glTF\"",
        ),
        GlbError::BadVersion { .. } => Issue::GLB_INVALID(format!("{name}@byte 4"), e.to_string()),
        GlbError::LengthMismatch { .. } => {
            Issue::GLB_INVALID(format!("{name}@byte 8"), e.to_string())
        }
        other => Issue::GLB_INVALID(name, other.to_string()),
    }
}

/// World matrices of the nodes placing each mesh (default scene; identity if unplaced).
fn mesh_placements(doc: &Gltf) -> Vec<(usize, DMat4)> {
    let mut out = Vec::new();
    let scene = doc.scene.unwrap_or(0) as usize;
    let roots: Vec<u32> = match doc.scenes.get(scene) {
        Some(s) => s.nodes.clone(),
        None => (0..doc.nodes.len() as u32).collect(),
    };
    let mut stack: Vec<(u32, DMat4, usize)> = roots
        .iter()
        .rev()
        .map(|&n| (n, DMat4::IDENTITY, 0))
        .collect();
    let mut visits = 0usize;
    while let Some((n, parent, depth)) = stack.pop() {
        visits += 1;
        // Guard against cycles and absurd graphs in hostile input.
        if depth > 64 || visits > 1 << 16 {
            break;
        }
        let Some(node) = doc.nodes.get(n as usize) else {
            continue;
        };
        let local = match node.matrix {
            Some(m) => DMat4::from_cols_array(&m),
            None => {
                let t = node.translation.map_or(DVec3::ZERO, DVec3::from_array);
                let r = node.rotation.map_or(DQuat::IDENTITY, |q| {
                    DQuat::from_xyzw(q[0], q[1], q[2], q[3]).normalize()
                });
                let s = node.scale.map_or(DVec3::ONE, DVec3::from_array);
                DMat4::from_scale_rotation_translation(s, r, t)
            }
        };
        let world = parent * local;
        if let Some(m) = node.mesh {
            out.push((m as usize, world));
        }
        for &c in node.children.iter().rev() {
            stack.push((c, world, depth + 1));
        }
    }
    out
}

/// Validates one glb. Returns the splat geometry when it could be decoded (for containment).
pub(crate) fn validate_glb(
    ctx: &mut Ctx<'_>,
    bytes: &[u8],
    name: &str,
    want_shapes: bool,
) -> Option<ContentGeom> {
    let chunks = match read_glb(bytes) {
        Ok(c) => c,
        Err(e) => {
            ctx.push(glb_issue(name, e));
            return None;
        }
    };
    validate_gltf(ctx, &chunks, name, want_shapes)
}

/// Validates one glTF JSON content (`.gltf`): the same checks as a glb's, with every buffer
/// read from its `uri` (a data URI or a file beside the content).
pub(crate) fn validate_gltf_json(
    ctx: &mut Ctx<'_>,
    bytes: &[u8],
    name: &str,
    want_shapes: bool,
) -> Option<ContentGeom> {
    let chunks = GlbChunks {
        json: bytes,
        json_offset: 0,
        bin: None,
        bin_offset: 0,
    };
    validate_gltf(ctx, &chunks, name, want_shapes)
}

/// The checks of a glTF asset once framed: JSON, extension declarations, buffers, then either
/// the plain glTF structure or each splat primitive.
fn validate_gltf(
    ctx: &mut Ctx<'_>,
    chunks: &GlbChunks<'_>,
    name: &str,
    want_shapes: bool,
) -> Option<ContentGeom> {
    let doc = match parse_json(chunks) {
        Ok(d) => d,
        Err(e) => {
            ctx.push(glb_issue(name, e));
            return None;
        }
    };
    let at = |p: &str| format!("{name}#{p}");
    // Extension members the typed structs drop: meshopt-compressed bufferViews (their bytes are
    // not attribute data) and meshopt fallback buffers (which hold no data at all).
    let raw: serde_json::Value = serde_json::from_slice(chunks.json).unwrap_or_default();
    let meshopt = |v: &serde_json::Value| {
        v.get("extensions")
            .and_then(|e| e.as_object())
            .is_some_and(|e| e.keys().any(|k| k.contains("meshopt_compression")))
    };
    let fallback_buffers: Vec<bool> = (0..doc.buffers.len())
        .map(|i| meshopt(&raw["buffers"][i]))
        .collect();
    let meshopt_views: Vec<bool> = (0..doc.buffer_views.len())
        .map(|i| meshopt(&raw["bufferViews"][i]))
        .collect();

    if doc
        .extensions_used
        .iter()
        .any(|e| e == splat2tiles_tiles::layers::EXTENSION)
    {
        ctx.layered_seen = true;
    }
    // Extensions: required => used; every extension object present => used.
    for (i, ext) in doc.extensions_required.iter().enumerate() {
        if !doc.extensions_used.contains(ext) {
            ctx.push(Issue::EXTENSION_REQUIRED_BUT_NOT_USED(
                at(&format!("/extensionsRequired/{i}")),
                format!("'{ext}' is required but not listed in extensionsUsed"),
            ));
        }
    }

    undeclared_extensions(ctx, &doc, &raw, name);
    let buffers = super::glb_buffers::check_buffers(ctx, &doc, chunks.bin, &fallback_buffers, name);

    // Find the splat primitives.
    let placements = mesh_placements(&doc);
    let mut splat_prims = Vec::new();
    for (m, mesh) in doc.meshes.iter().enumerate() {
        for (p, prim) in mesh.primitives.iter().enumerate() {
            if let Some(ext) = prim
                .extensions
                .as_ref()
                .and_then(|e| e.gaussian_splatting.as_ref())
            {
                splat_prims.push((m, p, prim, ext));
            }
        }
    }
    let declares_splats = doc
        .extensions_used
        .iter()
        .any(|e| e == KHR_GAUSSIAN_SPLATTING);
    if splat_prims.is_empty() && !declares_splats {
        // A plain glTF (meshes, points): framing, buffers and bufferViews were checked above.
        super::gltf_core::check_structure(ctx, &raw, name);
        ctx.push(Issue::CONTENT_DATA_NOT_CHECKED(
            name,
            "a glTF without KHR_gaussian_splatting: its framing, buffers, bufferViews, accessors, meshes, nodes, scenes, materials, textures, samplers, images and lights were checked, not its animations, skins or data values",
        ));
        return None;
    }
    if splat_prims.is_empty() {
        ctx.push(Issue::SPLAT_PRIMITIVE_MISSING(
            at("/meshes"),
            "no mesh primitive has the KHR_gaussian_splatting extension",
        ));
        return None;
    }
    let quantized = doc
        .extensions_used
        .iter()
        .any(|e| e == KHR_MESH_QUANTIZATION);

    let mut geom = ContentGeom::default();
    let mut decoded_any = false;
    for (m, p, prim, ext) in splat_prims {
        let decoded = super::splat_primitive::check(
            ctx,
            &super::splat_primitive::Glb {
                doc: &doc,
                name,
                buffers: &buffers,
                meshopt_views: &meshopt_views,
                placements: &placements,
                quantized,
            },
            (m, p, prim, ext),
            want_shapes,
            &mut geom,
        );
        decoded_any |= decoded;
    }
    decoded_any.then_some(geom)
}

/// Every extension object in the glTF JSON `raw` must be named in its `extensionsUsed` (glTF 2.0
/// sec. 3.12; the Khronos validator's UNDECLARED_EXTENSION).
fn undeclared_extensions(ctx: &mut Ctx<'_>, doc: &Gltf, raw: &serde_json::Value, name: &str) {
    let (found, _) = super::declarations::found_extensions(raw);
    for (ext, pointer) in found {
        if !doc.extensions_used.contains(&ext) {
            ctx.push(Issue::EXTENSION_FOUND_BUT_NOT_USED(
                format!("{name}#{pointer}"),
                format!("'{ext}' is used but not listed in the glTF's extensionsUsed"),
            ));
        }
    }
}
