//! Core glTF 2.0 structure checks for contents without splats: accessors inside their buffer
//! views, mesh primitives, nodes (a forest, no cycles), scenes; then materials and lights.

use super::context::Ctx;
use super::issues::Issue;
use serde_json::Value;

/// glTF component types and their sizes in bytes (glTF 2.0 sec. 3.6.2.2).
const COMPONENTS: [(u64, u64); 6] = [
    (5120, 1),
    (5121, 1),
    (5122, 2),
    (5123, 2),
    (5125, 4),
    (5126, 4),
];

/// Accessor types with their component counts (column-padded sizes are handled by `element_size`).
const TYPES: [(&str, u64); 7] = [
    ("SCALAR", 1),
    ("VEC2", 2),
    ("VEC3", 3),
    ("VEC4", 4),
    ("MAT2", 4),
    ("MAT3", 9),
    ("MAT4", 16),
];

/// Most entries of any top-level array that are inspected (bounds the work on hostile input).
const MAX_ENTRIES: usize = 1 << 16;

/// Size of one element, with the 4-byte column alignment glTF requires for 1- and 2-byte matrices.
fn element_size(ty: &str, comp: u64) -> u64 {
    match (ty, comp) {
        ("MAT2", 1) => 8,
        ("MAT3", 1) => 12,
        ("MAT3", 2) => 24,
        _ => TYPES.iter().find(|t| t.0 == ty).map_or(0, |t| t.1) * comp,
    }
}

/// What the structure checks learned about one accessor.
#[derive(Clone, Copy)]
struct Acc<'a> {
    ty: Option<&'a str>,
    comp: Option<u64>,
    count: Option<u64>,
    has_min_max: bool,
}

fn index(v: &Value) -> Option<usize> {
    v.as_u64().and_then(|i| usize::try_from(i).ok())
}

fn entries<'a>(raw: &'a Value, key: &str) -> &'a [Value] {
    match raw.get(key).and_then(Value::as_array) {
        Some(a) => &a[..a.len().min(MAX_ENTRIES)],
        None => &[],
    }
}

/// Checks accessors, meshes, nodes and scenes of the glTF JSON `raw` of content `name`.
pub(crate) fn check_structure(ctx: &mut Ctx<'_>, raw: &Value, name: &str) {
    let at = |p: String| format!("{name}#{p}");
    let views = entries(raw, "bufferViews");
    let accessors = entries(raw, "accessors");
    let mut accs = Vec::with_capacity(accessors.len());
    for (i, a) in accessors.iter().enumerate() {
        accs.push(check_accessor(ctx, a, i, views, &at));
    }
    let meshes = entries(raw, "meshes");
    for (m, mesh) in meshes.iter().enumerate() {
        let prims = mesh.get("primitives").and_then(Value::as_array);
        let Some(prims) = prims.filter(|p| !p.is_empty()) else {
            ctx.push(Issue::PROPERTY_MISSING(
                at(format!("/meshes/{m}/primitives")),
                "a mesh needs a non-empty primitives array",
            ));
            continue;
        };
        for (p, prim) in prims.iter().enumerate().take(MAX_ENTRIES) {
            check_primitive(
                ctx,
                prim,
                &format!("/meshes/{m}/primitives/{p}"),
                &accs,
                raw,
                &at,
            );
        }
    }
    check_nodes(ctx, raw, meshes.len(), &at);
    let nodes = entries(raw, "nodes").len();
    let scenes = entries(raw, "scenes");
    for (s, scene) in scenes.iter().enumerate() {
        for (k, n) in entries(scene, "nodes").iter().enumerate() {
            if index(n).is_none_or(|n| n >= nodes) {
                ctx.push(Issue::GLTF_REFERENCE_INVALID(
                    at(format!("/scenes/{s}/nodes/{k}")),
                    format!("node {n} does not exist ({nodes} nodes)"),
                ));
            }
        }
    }
    if let Some(s) = raw.get("scene")
        && index(s).is_none_or(|s| s >= scenes.len())
    {
        ctx.push(Issue::GLTF_REFERENCE_INVALID(
            at("/scene".into()),
            format!("scene {s} does not exist ({} scenes)", scenes.len()),
        ));
    }
    super::gltf_materials::check_materials(ctx, raw, &at);
    super::gltf_materials::check_lights(ctx, raw, &at);
}

fn check_accessor<'a>(
    ctx: &mut Ctx<'_>,
    a: &'a Value,
    i: usize,
    views: &[Value],
    at: &dyn Fn(String) -> String,
) -> Acc<'a> {
    let path = format!("/accessors/{i}");
    let ty = a.get("type").and_then(Value::as_str);
    let comp = a.get("componentType").and_then(Value::as_u64);
    let count = a.get("count").and_then(Value::as_u64);
    let mut acc = Acc {
        ty: ty.filter(|t| TYPES.iter().any(|x| x.0 == *t)),
        comp: comp.filter(|c| COMPONENTS.iter().any(|x| x.0 == *c)),
        count: count.filter(|c| *c >= 1),
        has_min_max: a.get("min").is_some() && a.get("max").is_some(),
    };
    if acc.ty.is_none() {
        ctx.push(Issue::VALUE_NOT_IN_LIST(
            at(format!("{path}/type")),
            format!("type {} is not one of SCALAR, VEC2-4, MAT2-4", a["type"]),
        ));
    }
    if acc.comp.is_none() {
        ctx.push(Issue::VALUE_NOT_IN_LIST(
            at(format!("{path}/componentType")),
            format!(
                "componentType {} is not one of 5120, 5121, 5122, 5123, 5125, 5126",
                a["componentType"]
            ),
        ));
    }
    if acc.count.is_none() {
        ctx.push(Issue::VALUE_NOT_IN_RANGE(
            at(format!("{path}/count")),
            format!("count {} must be an integer >= 1", a["count"]),
        ));
    }
    if a.get("normalized").and_then(Value::as_bool) == Some(true)
        && matches!(acc.comp, Some(5125 | 5126))
    {
        ctx.push(Issue::VALUE_NOT_IN_RANGE(
            at(format!("{path}/normalized")),
            "normalized is only allowed for 8- and 16-bit integer components",
        ));
    }
    let (Some(ty), Some(comp), Some(count)) = (acc.ty, acc.comp, acc.count) else {
        return acc;
    };
    let n = TYPES.iter().find(|t| t.0 == ty).map_or(0, |t| t.1) as usize;
    for key in ["min", "max"] {
        if let Some(v) = a.get(key) {
            let len = v.as_array().map(Vec::len);
            if len != Some(n) {
                ctx.push(Issue::ARRAY_LENGTH_MISMATCH(
                    at(format!("{path}/{key}")),
                    format!("{key} must hold {n} numbers for a {ty} accessor"),
                ));
                acc.has_min_max = false;
            }
        }
    }
    let Some(view) = a.get("bufferView") else {
        // No bufferView: all zeros (or sparse); nothing to bound.
        return acc;
    };
    let Some(v) = index(view).and_then(|v| views.get(v)) else {
        ctx.push(Issue::GLTF_REFERENCE_INVALID(
            at(format!("{path}/bufferView")),
            format!(
                "bufferView {view} does not exist ({} bufferViews)",
                views.len()
            ),
        ));
        return acc;
    };
    let size = COMPONENTS.iter().find(|c| c.0 == comp).map_or(1, |c| c.1);
    let offset = a.get("byteOffset").and_then(Value::as_u64).unwrap_or(0);
    let view_offset = v.get("byteOffset").and_then(Value::as_u64).unwrap_or(0);
    if !offset.is_multiple_of(size)
        || view_offset
            .checked_add(offset)
            .is_none_or(|o| !o.is_multiple_of(size))
    {
        ctx.push(Issue::ACCESSOR_ALIGNMENT_INVALID(
            at(format!("{path}/byteOffset")),
            format!(
                "byteOffset {offset} (bufferView at {view_offset}) is not a multiple of the {size}-byte component"
            ),
        ));
    }
    let elem = element_size(ty, size);
    let stride = v.get("byteStride").and_then(Value::as_u64).unwrap_or(elem);
    if stride < elem {
        ctx.push(Issue::BUFFERS_INCONSISTENT(
            at(format!("{path}/bufferView")),
            format!(
                "byteStride {stride} of bufferView {view} is less than the {elem}-byte element"
            ),
        ));
        return acc;
    }
    let view_len = v.get("byteLength").and_then(Value::as_u64).unwrap_or(0);
    let end = (count - 1)
        .checked_mul(stride)
        .and_then(|e| e.checked_add(offset))
        .and_then(|e| e.checked_add(elem));
    if end.is_none_or(|e| e > view_len) {
        ctx.push(Issue::ACCESSOR_OUT_OF_BOUNDS(
            at(path),
            format!(
                "{count} elements of {elem} bytes (stride {stride}) from byte {offset} run past the {view_len}-byte bufferView {view}"
            ),
        ));
    }
    acc
}

fn check_primitive(
    ctx: &mut Ctx<'_>,
    prim: &Value,
    path: &str,
    accs: &[Acc<'_>],
    raw: &Value,
    at: &dyn Fn(String) -> String,
) {
    if let Some(mode) = prim.get("mode")
        && mode.as_u64().is_none_or(|m| m > 6)
    {
        ctx.push(Issue::VALUE_NOT_IN_RANGE(
            at(format!("{path}/mode")),
            format!("mode {mode} is not a glTF primitive mode (0..=6)"),
        ));
    }
    let Some(attrs) = prim.get("attributes").and_then(Value::as_object) else {
        ctx.push(Issue::PROPERTY_MISSING(
            at(format!("{path}/attributes")),
            "a primitive needs an attributes object",
        ));
        return;
    };
    let mut counts: Vec<(&str, u64)> = Vec::new();
    for (semantic, a) in attrs.iter().take(MAX_ENTRIES) {
        let Some(acc) = index(a).and_then(|i| accs.get(i)) else {
            ctx.push(Issue::GLTF_REFERENCE_INVALID(
                at(format!("{path}/attributes/{semantic}")),
                format!("accessor {a} does not exist ({} accessors)", accs.len()),
            ));
            continue;
        };
        if let Some(c) = acc.count {
            counts.push((semantic, c));
        }
        if semantic == "POSITION" {
            if acc.ty.is_some_and(|t| t != "VEC3") || acc.comp.is_some_and(|c| c != 5126) {
                ctx.push(Issue::ACCESSOR_TYPE_INVALID(
                    at(format!("{path}/attributes/POSITION")),
                    "POSITION must be a VEC3 float accessor",
                ));
            }
            if !acc.has_min_max {
                ctx.push(Issue::ACCESSOR_MIN_MAX_MISSING(
                    at(format!("{path}/attributes/POSITION")),
                    "a POSITION accessor must define min and max",
                ));
            }
        }
    }
    if let Some(&(first, n)) = counts.first()
        && let Some(&(other, m)) = counts.iter().find(|c| c.1 != n)
    {
        ctx.push(Issue::ACCESSOR_COUNT_MISMATCH(
            at(format!("{path}/attributes")),
            format!("{first} has {n} elements but {other} has {m}: all attributes must have the same count"),
        ));
    }
    if let Some(ix) = prim.get("indices") {
        match index(ix).and_then(|i| accs.get(i)) {
            None => ctx.push(Issue::GLTF_REFERENCE_INVALID(
                at(format!("{path}/indices")),
                format!("accessor {ix} does not exist ({} accessors)", accs.len()),
            )),
            Some(acc) => {
                if acc.ty.is_some_and(|t| t != "SCALAR")
                    || acc.comp.is_some_and(|c| !matches!(c, 5121 | 5123 | 5125))
                {
                    ctx.push(Issue::ACCESSOR_TYPE_INVALID(
                        at(format!("{path}/indices")),
                        "indices must be a SCALAR accessor of unsigned byte, short or int",
                    ));
                }
            }
        }
    }
    if let Some(mat) = prim.get("material") {
        let n = entries(raw, "materials").len();
        if index(mat).is_none_or(|m| m >= n) {
            ctx.push(Issue::GLTF_REFERENCE_INVALID(
                at(format!("{path}/material")),
                format!("material {mat} does not exist ({n} materials)"),
            ));
        }
    }
}

/// Node references and the forest rule: every node has at most one parent and no node is its
/// own ancestor.
fn check_nodes(ctx: &mut Ctx<'_>, raw: &Value, meshes: usize, at: &dyn Fn(String) -> String) {
    let nodes = entries(raw, "nodes");
    let mut parent: Vec<Option<usize>> = vec![None; nodes.len()];
    for (i, node) in nodes.iter().enumerate() {
        if let Some(m) = node.get("mesh")
            && index(m).is_none_or(|m| m >= meshes)
        {
            ctx.push(Issue::GLTF_REFERENCE_INVALID(
                at(format!("/nodes/{i}/mesh")),
                format!("mesh {m} does not exist ({meshes} meshes)"),
            ));
        }
        if let Some(m) = node.get("matrix")
            && m.as_array().map(Vec::len) != Some(16)
        {
            ctx.push(Issue::ARRAY_LENGTH_MISMATCH(
                at(format!("/nodes/{i}/matrix")),
                "matrix must hold 16 numbers",
            ));
        }
        for (k, c) in entries(node, "children").iter().enumerate() {
            let path = at(format!("/nodes/{i}/children/{k}"));
            match index(c).filter(|&c| c < nodes.len()) {
                None => ctx.push(Issue::GLTF_REFERENCE_INVALID(
                    path,
                    format!("node {c} does not exist ({} nodes)", nodes.len()),
                )),
                Some(c) if parent[c].is_some() || c == i => ctx.push(Issue::GLTF_REFERENCE_INVALID(
                    path,
                    format!("node {c} already has a parent or is this node: nodes must form a forest"),
                )),
                Some(c) => parent[c] = Some(i),
            }
        }
    }
    // With at most one parent each, a cycle is a chain that returns to its start.
    let mut state = vec![0u8; nodes.len()]; // 0 unknown, 1 on the current walk, 2 reaches a root
    for start in 0..nodes.len() {
        let mut walk = Vec::new();
        let mut n = start;
        loop {
            match state[n] {
                2 => break,
                1 => {
                    ctx.push(Issue::GLTF_REFERENCE_INVALID(
                        at(format!("/nodes/{n}/children")),
                        format!("node {n} is its own ancestor: nodes must form a forest"),
                    ));
                    break;
                }
                _ => {}
            }
            state[n] = 1;
            walk.push(n);
            match parent[n] {
                Some(p) => n = p,
                None => break,
            }
        }
        for w in walk {
            state[w] = 2;
        }
    }
}
