//! One `KHR_gaussian_splatting` primitive of a glb: the extension's properties, its attribute set
//! and SH completeness, each accessor's type and bounds, the data values, and its splat geometry.

use super::context::{ContentGeom, Ctx};
use super::glb_buffers::Buffers;
use super::issues::Issue;
use std::collections::BTreeMap;

use glam::{DMat3, DMat4, DQuat, DVec3};
use splat2tiles_tiles::encode::gltf::{
    Accessor, AccessorType, BufferView, ComponentType, Gltf, KHR_GAUSSIAN_SPLATTING,
    KHR_GAUSSIAN_SPLATTING_SPZ_2, KhrGaussianSplatting, MODE_DEFAULT, MODE_POINTS, Primitive,
    S2T_GAUSSIAN_SPLATTING_CODEBOOK,
};

const SPLAT: &str = "KHR_gaussian_splatting:";
const ROTATION: &str = "KHR_gaussian_splatting:ROTATION";
const SCALE: &str = "KHR_gaussian_splatting:SCALE";
const OPACITY: &str = "KHR_gaussian_splatting:OPACITY";

/// An accessor whose bytes were checked to lie inside their buffer.
struct View<'b> {
    bytes: &'b [u8],
    stride: usize,
    comp: ComponentType,
    n: usize,
    normalized: bool,
    count: usize,
}

impl View<'_> {
    /// Component `j` of element `i`, normalized integers decoded to [0,1] / [-1,1].
    fn get(&self, i: usize, j: usize) -> f64 {
        let o = i * self.stride + j * self.comp.size();
        let b = &self.bytes[o..o + self.comp.size()];
        let raw = match self.comp {
            ComponentType::I8 => b[0] as i8 as f64,
            ComponentType::U8 => b[0] as f64,
            ComponentType::I16 => i16::from_le_bytes([b[0], b[1]]) as f64,
            ComponentType::U16 => u16::from_le_bytes([b[0], b[1]]) as f64,
            ComponentType::U32 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            ComponentType::F32 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
        };
        if !self.normalized {
            return raw;
        }
        match self.comp {
            ComponentType::I8 => (raw / 127.0).max(-1.0),
            ComponentType::U8 => raw / 255.0,
            ComponentType::I16 => (raw / 32767.0).max(-1.0),
            ComponentType::U16 => raw / 65535.0,
            _ => raw,
        }
    }
}

/// What the glb-level checks found, shared by its splat primitives.
pub(super) struct Glb<'a> {
    /// The parsed glTF JSON.
    pub doc: &'a Gltf,
    /// The glb's name in issue paths.
    pub name: &'a str,
    /// Buffer bytes and usable bufferViews.
    pub buffers: &'a Buffers,
    /// Per bufferView: meshopt-compressed (its bytes are not attribute data).
    pub meshopt_views: &'a [bool],
    /// World matrices of the nodes placing each mesh.
    pub placements: &'a [(usize, DMat4)],
    /// `KHR_mesh_quantization` is used (quantized POSITION allowed).
    pub quantized: bool,
}

/// Checks splat primitive `p` of mesh `m` and appends its geometry (every placement of the
/// mesh, shapes when `want_shapes`) to `geom`; true when its geometry could be decoded.
pub(super) fn check(
    ctx: &mut Ctx<'_>,
    g: &Glb<'_>,
    (m, p, prim, ext): (usize, usize, &Primitive, &KhrGaussianSplatting),
    want_shapes: bool,
    geom: &mut ContentGeom,
) -> bool {
    let name = g.name;
    let at = |p: &str| format!("{name}#{p}");
    let pp = format!("/meshes/{m}/primitives/{p}");
    let ep = format!("{pp}/extensions/{KHR_GAUSSIAN_SPLATTING}");
    let compressed = check_extension(ctx, name, &pp, &ep, prim, ext);
    let attrs = &prim.attributes;
    check_attribute_set(ctx, name, &pp, attrs, compressed);
    let views = check_accessors(ctx, g, &pp, attrs, compressed);
    let codebook = ext
        .extensions
        .as_ref()
        .and_then(|c| c.get(S2T_GAUSSIAN_SPLATTING_CODEBOOK));
    if let Some(child) = codebook {
        let cp = format!("{ep}/extensions/{S2T_GAUSSIAN_SPLATTING_CODEBOOK}");
        if let Some(s) = check_codebook(ctx, g, &cp, child, prim) {
            let splat = |i: usize| {
                let p = DVec3::from_array(s.positions[i]);
                let [x, y, z, w] = s.rotations[i].map(f64::from);
                let sc = DVec3::from_array(s.scales[i].map(f64::from));
                (p, shape_of(Some(DQuat::from_xyzw(x, y, z, w)), Some(sc)))
            };
            return gather_geometry(g.placements, m, (s.len(), &splat), want_shapes, geom);
        }
    } else if compressed {
        ctx.push(Issue::CONTENT_DATA_NOT_CHECKED(
            at(&ep),
            "attribute data is inside a compression extension; values were not decoded",
        ));
    }
    check_values(ctx, g.doc, name, &pp, attrs, &views);

    // Geometry for containment: every placement of this mesh.
    let get = |want: &str| {
        views
            .iter()
            .find(|(a, _)| *a == want)
            .and_then(|(_, v)| v.as_ref())
    };
    let count_ok = views
        .iter()
        .filter_map(|(_, v)| v.as_ref().map(|v| v.count))
        .all(|c| Some(c) == get("POSITION").map(|p| p.count));
    let Some(pos) = get("POSITION") else {
        return false;
    };
    if !count_ok || pos.n != 3 {
        return false;
    }
    // Wrongly typed attributes were reported above; their values are not used.
    let rot = get(ROTATION).filter(|r| r.n == 4);
    let scale = get(SCALE).filter(|s| s.n == 3);
    let splat = |i: usize| {
        let p = DVec3::new(pos.get(i, 0), pos.get(i, 1), pos.get(i, 2));
        let q = rot.map(|r| DQuat::from_xyzw(r.get(i, 0), r.get(i, 1), r.get(i, 2), r.get(i, 3)));
        let sv = scale.map(|s| DVec3::new(s.get(i, 0), s.get(i, 1), s.get(i, 2)));
        (p, shape_of(q, sv))
    };
    gather_geometry(g.placements, m, (pos.count, &splat), want_shapes, geom)
}

/// Decodes a codebook payload (child object `child` at `cp`) and checks its splat count and
/// positions against the POSITION accessor; the decoded splats when they agree.
fn check_codebook(
    ctx: &mut Ctx<'_>,
    g: &Glb<'_>,
    cp: &str,
    child: &serde_json::Value,
    prim: &Primitive,
) -> Option<splat2tiles_core::splat::Splats> {
    let at = |p: &str| format!("{}#{p}", g.name);
    let invalid = |ctx: &mut Ctx<'_>, what: String| {
        ctx.push(Issue::SPLAT_CODEBOOK_PAYLOAD_INVALID(at(cp), what));
        None
    };
    let Some(v) = child.get("bufferView").and_then(|v| v.as_u64()) else {
        return invalid(ctx, "bufferView is missing or not an index".into());
    };
    let bytes = g.doc.buffer_views.get(v as usize).and_then(|bv| {
        let ok = *g.buffers.views_ok.get(v as usize)?;
        let data = g.buffers.data.get(bv.buffer as usize)?.as_ref()?;
        let start = usize::try_from(bv.byte_offset).ok()?;
        let len = usize::try_from(bv.byte_length).ok()?;
        ok.then(|| data.get(start..start.checked_add(len)?))
            .flatten()
    });
    let Some(bytes) = bytes else {
        return invalid(
            ctx,
            format!("bufferView {v} is missing or outside its buffer"),
        );
    };
    let splats = match splat2tiles_tiles::encode::codebook::decode_payload(bytes) {
        Ok(s) => s,
        Err(e) => return invalid(ctx, e.to_string()),
    };
    let acc = prim
        .attributes
        .get("POSITION")
        .and_then(|&i| g.doc.accessors.get(i as usize));
    let acc = acc?;
    if acc.count != splats.len() as u64 {
        ctx.push(Issue::SPLAT_CODEBOOK_COUNT_MISMATCH(
            at(cp),
            format!(
                "the payload holds {} splats, POSITION's count is {}",
                splats.len(),
                acc.count
            ),
        ));
        return None;
    }
    if let (Some(lo), Some(hi)) = (&acc.min, &acc.max)
        && let Some((dlo, dhi)) = splats.bounds()
    {
        let outside = (0..3).any(|a| {
            let tol = 1e-5
                * (hi.get(a).copied().unwrap_or(0.0) - lo.get(a).copied().unwrap_or(0.0))
                    .abs()
                    .max(1e-6);
            lo.get(a).is_some_and(|&l| dlo[a] < l - tol)
                || hi.get(a).is_some_and(|&h| dhi[a] > h + tol)
        });
        if outside {
            ctx.push(Issue::SPLAT_CODEBOOK_COUNT_MISMATCH(
                at(cp),
                format!("decoded positions span {dlo:?}..{dhi:?}, outside POSITION min/max"),
            ));
            return None;
        }
    }
    Some(splats)
}

/// The extension object's properties (mode, kernel, colorSpace, projection, sortingMethod) and
/// its child extensions; true when a child extension compresses the attribute data.
fn check_extension(
    ctx: &mut Ctx<'_>,
    name: &str,
    pp: &str,
    ep: &str,
    prim: &Primitive,
    ext: &KhrGaussianSplatting,
) -> bool {
    let at = |p: &str| format!("{name}#{p}");
    // "mode MUST be POINTS".
    let mode = prim.mode.unwrap_or(MODE_DEFAULT);
    if mode != MODE_POINTS {
        ctx.push(Issue::SPLAT_MODE_NOT_POINTS(
            at(&format!("{pp}/mode")),
            format!("mode {mode}: a KHR_gaussian_splatting primitive must be POINTS (0)"),
        ));
    }
    // "kernel" and "colorSpace" are required.
    match ext.kernel.as_deref() {
        None => ctx.push(Issue::PROPERTY_MISSING(
            at(ep),
            "'kernel' is required (\"ellipse\")",
        )),
        Some("ellipse") => {}
        Some(k) => ctx.push(Issue::VALUE_NOT_IN_LIST(
            at(&format!("{ep}/kernel")),
            format!("kernel '{k}' is not \"ellipse\""),
        )),
    }
    match ext.color_space.as_deref() {
        None => ctx.push(Issue::PROPERTY_MISSING(
            at(ep),
            "'colorSpace' is required (srgb_rec709_display or lin_rec709_display)",
        )),
        Some("srgb_rec709_display" | "lin_rec709_display") => {}
        Some(c) => ctx.push(Issue::VALUE_NOT_IN_LIST(
            at(&format!("{ep}/colorSpace")),
            format!("colorSpace '{c}' is not srgb_rec709_display or lin_rec709_display"),
        )),
    }
    if let Some(v) = ext.projection.as_deref()
        && v != "perspective"
    {
        ctx.push(Issue::VALUE_NOT_IN_LIST(
            at(&format!("{ep}/projection")),
            format!("projection '{v}' is not \"perspective\""),
        ));
    }
    if let Some(v) = ext.sorting_method.as_deref()
        && v != "cameraDistance"
    {
        ctx.push(Issue::VALUE_NOT_IN_LIST(
            at(&format!("{ep}/sortingMethod")),
            format!("sortingMethod '{v}' is not \"cameraDistance\""),
        ));
    }
    // Declarations of these extensions are checked for the whole glTF (content.rs).
    ext.extensions
        .iter()
        .flat_map(|e| e.keys())
        .any(|child| child == KHR_GAUSSIAN_SPLATTING_SPZ_2 || child.contains("compression"))
}

/// Required attributes present, names the extension defines, SH degrees complete.
fn check_attribute_set(
    ctx: &mut Ctx<'_>,
    name: &str,
    pp: &str,
    attrs: &BTreeMap<String, u32>,
    compressed: bool,
) {
    let at = |p: &str| format!("{name}#{p}");
    let mut required = vec!["POSITION", ROTATION, SCALE, OPACITY];
    // SPZ_2 tiles carry DC colour in COLOR_0 (spec/validation.md, deviation D1).
    if !compressed {
        required.push("KHR_gaussian_splatting:SH_DEGREE_0_COEF_0");
    }
    for r in required {
        if !attrs.contains_key(r) {
            ctx.push(Issue::SPLAT_ATTRIBUTE_MISSING(
                at(&format!("{pp}/attributes")),
                format!("required attribute {r} is missing"),
            ));
        }
    }
    let mut sh = [[false; 7]; 4];
    for name_attr in attrs.keys().filter(|k| k.starts_with(SPLAT)) {
        let rest = &name_attr[SPLAT.len()..];
        if matches!(rest, "ROTATION" | "SCALE" | "OPACITY") {
            continue;
        }
        let parsed = rest.strip_prefix("SH_DEGREE_").and_then(|r| {
            let (d, c) = r.split_once("_COEF_")?;
            let (d, c): (usize, usize) = (d.parse().ok()?, c.parse().ok()?);
            (d <= 3 && c <= 2 * d).then_some((d, c))
        });
        match parsed {
            Some((d, c)) => sh[d][c] = true,
            None => ctx.push(Issue::SPLAT_ATTRIBUTE_UNKNOWN(
                at(&format!("{pp}/attributes/{name_attr}")),
                format!("{name_attr} is not an attribute KHR_gaussian_splatting defines"),
            )),
        }
    }
    let top = (0..4).rev().find(|&d| sh[d].iter().any(|&b| b));
    if let Some(top) = top {
        for (d, coefs) in sh.iter().enumerate().take(top + 1) {
            // Degree 0 may be absent in SPZ_2 tiles (DC colour in COLOR_0).
            if d == 0 && compressed && !coefs[0] {
                continue;
            }
            let missing: Vec<usize> = (0..=2 * d).filter(|&c| !coefs[c]).collect();
            if !missing.is_empty() {
                ctx.push(Issue::SPLAT_SH_INCOMPLETE(
                    at(&format!("{pp}/attributes")),
                    format!(
                        "SH degree {d} lacks coefficients {missing:?} (degree {top} is present; degrees must be complete and lower degrees present)"
                    ),
                ));
            }
        }
    }
}

/// Whether attribute `attr` may have element type `n` of component type `comp` (normalized
/// `nz`; `quantized`: `KHR_mesh_quantization` is used).
fn type_allowed(
    attr: &str,
    n: AccessorType,
    comp: ComponentType,
    nz: bool,
    quantized: bool,
) -> bool {
    use AccessorType as T;
    use ComponentType as C;
    match attr {
        "POSITION" => n == T::Vec3 && (comp == C::F32 || (quantized && comp != C::U32)),
        ROTATION => n == T::Vec4 && (comp == C::F32 || (nz && matches!(comp, C::I8 | C::I16))),
        SCALE => n == T::Vec3 && (comp == C::F32 || matches!(comp, C::U8 | C::U16)),
        OPACITY => n == T::Scalar && (comp == C::F32 || (nz && matches!(comp, C::U8 | C::U16))),
        "COLOR_0" => {
            matches!(n, T::Vec3 | T::Vec4)
                && (comp == C::F32 || (nz && matches!(comp, C::U8 | C::U16)))
        }
        a if a.starts_with("KHR_gaussian_splatting:SH_") => n == T::Vec3 && comp == C::F32 && !nz,
        _ => true,
    }
}

/// The accessor's place in its bufferView (`ap`: the accessor's issue path): stride at least an
/// element, offsets aligned to the component and to 4 bytes, every element inside the view;
/// returns the start in the buffer and the stride.
fn view_layout(
    ctx: &mut Ctx<'_>,
    ap: &str,
    acc: &Accessor,
    view: &BufferView,
    bv: u32,
    attr: &str,
    comp: ComponentType,
) -> Option<(u64, usize)> {
    let elem = comp.size() * acc.kind.components();
    let stride = view.byte_stride.map_or(elem, |s| s as usize);
    if stride < elem {
        ctx.push(Issue::ACCESSOR_OUT_OF_BOUNDS(
            ap.to_string(),
            format!("byteStride {stride} is smaller than the {elem}-byte element"),
        ));
        return None;
    }
    let start = view.byte_offset + acc.byte_offset;
    if !start.is_multiple_of(comp.size() as u64)
        || !acc.byte_offset.is_multiple_of(comp.size() as u64)
    {
        ctx.push(Issue::ACCESSOR_ALIGNMENT_INVALID(
            format!("{ap}/byteOffset"),
            format!(
                "offset {start} in the buffer is not a multiple of the {}-byte component",
                comp.size()
            ),
        ));
        return None;
    }
    if !start.is_multiple_of(4) || !stride.is_multiple_of(4) {
        ctx.push(Issue::ACCESSOR_ALIGNMENT_INVALID(
            format!("{ap}/byteOffset"),
            format!(
                "vertex attribute {attr} starts at buffer offset {start} with stride {stride}: both must be multiples of 4"
            ),
        ));
        return None;
    }
    let need = if acc.count == 0 {
        Some(0)
    } else {
        (acc.count - 1)
            .checked_mul(stride as u64)
            .and_then(|x| x.checked_add(elem as u64))
            .and_then(|x| x.checked_add(acc.byte_offset))
    };
    if need.is_none_or(|need| need > view.byte_length) {
        ctx.push(Issue::ACCESSOR_OUT_OF_BOUNDS(
            ap.to_string(),
            format!(
                "{} elements of {elem} bytes (stride {stride}) from byteOffset {} do not fit the {}-byte bufferView {bv}",
                acc.count, acc.byte_offset, view.byte_length
            ),
        ));
        return None;
    }
    Some((start, stride))
}

/// Each attribute's accessor: type allowed for the attribute, counts agree, bytes inside the
/// bufferView and aligned, min/max on POSITION; returns the readable ones (`None`: no
/// bufferView, implicit zeros).
fn check_accessors<'a>(
    ctx: &mut Ctx<'_>,
    g: &Glb<'a>,
    pp: &str,
    attrs: &'a BTreeMap<String, u32>,
    compressed: bool,
) -> Vec<(&'a str, Option<View<'a>>)> {
    let Glb {
        doc,
        name,
        buffers,
        meshopt_views,
        quantized,
        ..
    } = *g;
    let (views_ok, buffers) = (&buffers.views_ok, &buffers.data);
    let at = |p: &str| format!("{name}#{p}");
    let mut count: Option<(u64, &str)> = None;
    let mut views: Vec<(&str, Option<View<'_>>)> = Vec::new();
    for (attr, &ai) in attrs {
        let path = format!("{pp}/attributes/{attr}");
        let Some(acc) = doc.accessors.get(ai as usize) else {
            ctx.push(Issue::GLTF_REFERENCE_INVALID(
                at(&path),
                format!("accessor {ai} does not exist"),
            ));
            continue;
        };
        let ap = format!("/accessors/{ai}");
        match count {
            None => count = Some((acc.count, attr)),
            Some((c, first)) if c != acc.count => ctx.push(Issue::ACCESSOR_COUNT_MISMATCH(
                at(&format!("{ap}/count")),
                format!("{attr} has {} elements but {first} has {c}", acc.count),
            )),
            _ => {}
        }
        let Some(comp) = ComponentType::from_code(acc.component_type) else {
            ctx.push(Issue::VALUE_NOT_IN_LIST(
                at(&format!("{ap}/componentType")),
                format!(
                    "componentType {} is not a glTF component type",
                    acc.component_type
                ),
            ));
            continue;
        };
        let (n, nz) = (acc.kind, acc.normalized);
        let allowed = type_allowed(attr, n, comp, nz, quantized);
        if !allowed {
            ctx.push(Issue::ACCESSOR_TYPE_INVALID(
                at(&ap),
                format!(
                    "{attr} may not be {:?} componentType {}{}",
                    n,
                    acc.component_type,
                    if nz { " normalized" } else { "" }
                ),
            ));
        }
        if acc.count == 0 {
            ctx.push(Issue::VALUE_NOT_IN_RANGE(
                at(&format!("{ap}/count")),
                "accessor count must be at least 1",
            ));
        }
        let Some(bv) = acc.buffer_view else {
            if !compressed && acc.sparse.is_none() {
                // No bufferView and no extension supplying data: all zeros. Allowed by glTF,
                // but a splat tile of zeros is never intended; rotations of zeros are not unit.
                views.push((attr, None));
            }
            continue;
        };
        let Some(view) = doc.buffer_views.get(bv as usize) else {
            ctx.push(Issue::GLTF_REFERENCE_INVALID(
                at(&format!("{ap}/bufferView")),
                format!("bufferView {bv} does not exist"),
            ));
            continue;
        };
        if !views_ok[bv as usize] {
            continue;
        }
        if meshopt_views[bv as usize] {
            ctx.push(Issue::CONTENT_DATA_NOT_CHECKED(
                at(&ap),
                format!("{attr} is in a meshopt-compressed bufferView; values were not decoded"),
            ));
            continue;
        }
        let Some((start, stride)) = view_layout(ctx, &at(&ap), acc, view, bv, attr, comp) else {
            continue;
        };
        let Some(Some(buf)) = buffers.get(view.buffer as usize) else {
            continue;
        };
        let Some(bytes) = buf.get(start as usize..(view.byte_offset + view.byte_length) as usize)
        else {
            continue;
        };
        views.push((
            attr,
            Some(View {
                bytes,
                stride,
                comp,
                n: n.components(),
                normalized: nz,
                count: acc.count as usize,
            }),
        ));
        // min / max (required on POSITION).
        let (min, max) = (acc.min.as_ref(), acc.max.as_ref());
        if attr == "POSITION" && (min.is_none() || max.is_none()) {
            ctx.push(Issue::ACCESSOR_MIN_MAX_MISSING(
                at(&ap),
                "POSITION accessors must declare min and max",
            ));
        }
    }
    views
}

/// The values: finite, declared min/max match the data, opacities in [0, 1], scales
/// non-negative, rotations unit.
fn check_values(
    ctx: &mut Ctx<'_>,
    doc: &Gltf,
    name: &str,
    pp: &str,
    attrs: &BTreeMap<String, u32>,
    views: &[(&str, Option<View<'_>>)],
) {
    let at = |p: &str| format!("{name}#{p}");
    for (attr, v) in views {
        let Some(v) = v else { continue };
        let ai = attrs[*attr];
        let acc = &doc.accessors[ai as usize];
        let ap = format!("/accessors/{ai}");
        let mut lo = vec![f64::INFINITY; v.n];
        let mut hi = vec![f64::NEG_INFINITY; v.n];
        let mut non_finite = None;
        for i in 0..v.count {
            for j in 0..v.n {
                let x = v.get(i, j);
                if !x.is_finite() {
                    non_finite.get_or_insert(i);
                    continue;
                }
                lo[j] = lo[j].min(x);
                hi[j] = hi[j].max(x);
            }
        }
        if let Some(i) = non_finite {
            ctx.push(Issue::ACCESSOR_NON_FINITE(
                at(&ap),
                format!("{attr}: element {i} holds NaN or infinity"),
            ));
        }
        for (which, declared, actual) in [("min", &acc.min, &lo), ("max", &acc.max, &hi)] {
            let Some(d) = declared else { continue };
            let close = d.len() == v.n
                && d.iter().zip(actual.iter()).all(|(d, a)| {
                    (*d as f32 == *a as f32) || (d - a).abs() <= 1e-6 * a.abs().max(1.0)
                });
            if !close && non_finite.is_none() {
                ctx.push(Issue::ACCESSOR_MIN_MAX_MISMATCH(
                    at(&format!("{ap}/{which}")),
                    format!("{attr}: declared {which} {d:?} but the data gives {actual:?}"),
                ));
            }
        }
        let mut bad: Option<(usize, f64)> = None;
        let mut n_bad = 0usize;
        let mut flag = |i: usize, val: f64| {
            n_bad += 1;
            bad.get_or_insert((i, val));
        };
        match *attr {
            OPACITY => {
                for i in 0..v.count {
                    let x = v.get(i, 0);
                    if !(0.0..=1.0).contains(&x) {
                        flag(i, x);
                    }
                }
                if let Some((i, x)) = bad {
                    ctx.push(Issue::SPLAT_OPACITY_OUT_OF_RANGE(
                        at(&ap),
                        format!("{n_bad} of {} opacities outside [0, 1]; first: element {i} = {x} (store the post-sigmoid value)", v.count),
                    ));
                }
            }
            SCALE if v.n == 3 => {
                for i in 0..v.count {
                    for j in 0..3 {
                        let x = v.get(i, j);
                        if !(x >= 0.0 && x.is_finite()) {
                            flag(i, x);
                            break;
                        }
                    }
                }
                if let Some((i, x)) = bad {
                    ctx.push(Issue::SPLAT_SCALE_INVALID(
                        at(&ap),
                        format!("{n_bad} of {} scales negative or non-finite; first: element {i} has {x} (scales are linear: exp() a log-space scale)", v.count),
                    ));
                }
            }
            ROTATION if v.n == 4 => {
                let tol = match (v.comp, v.normalized) {
                    (ComponentType::I8, true) => 0.02,
                    (ComponentType::I16, true) => ctx.opts.rotation_tolerance.max(2e-4),
                    _ => ctx.opts.rotation_tolerance,
                };
                for i in 0..v.count {
                    let len = (0..4).map(|j| v.get(i, j).powi(2)).sum::<f64>().sqrt();
                    if (len - 1.0).abs() > tol || len.is_nan() {
                        flag(i, len);
                    }
                }
                if let Some((i, len)) = bad {
                    ctx.push(Issue::SPLAT_ROTATION_NOT_UNIT(
                        at(&ap),
                        format!("{n_bad} of {} quaternions are not unit within {tol}; first: element {i} has length {len}", v.count),
                    ));
                }
            }
            _ => {}
        }
    }
    for (attr, v) in views {
        if v.is_none() && *attr == ROTATION {
            ctx.push(Issue::SPLAT_ROTATION_NOT_UNIT(
                at(&format!("{pp}/attributes/{attr}")),
                "ROTATION has no bufferView: its implicit zeros are not unit quaternions",
            ));
        }
    }
}

/// Appends the splat centres (and shapes when `want_shapes`) of mesh `m` in its first 16
/// placements, in the tile frame (node matrix, then y-up -> z-up); true when any was appended.
/// The local shape (rotation times scales) of a splat; zero without both.
fn shape_of(q: Option<DQuat>, scale: Option<DVec3>) -> DMat3 {
    match (q, scale) {
        (Some(q), Some(s)) => {
            let q = if q.length() > 0.0 {
                q.normalize()
            } else {
                DQuat::IDENTITY
            };
            DMat3::from_quat(q) * DMat3::from_diagonal(s.abs())
        }
        _ => DMat3::ZERO,
    }
}

fn gather_geometry(
    placements: &[(usize, DMat4)],
    m: usize,
    (count, splat): (usize, &dyn Fn(usize) -> (DVec3, DMat3)),
    want_shapes: bool,
    geom: &mut ContentGeom,
) -> bool {
    let mut decoded = false;
    let y_to_z = DMat4::from_cols_array(&[
        1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0,
    ]);
    let mut worlds: Vec<DMat4> = placements
        .iter()
        .filter(|(mm, _)| *mm == m)
        .map(|(_, w)| *w)
        .collect();
    if worlds.is_empty() {
        worlds.push(DMat4::IDENTITY);
    }
    // A mesh placed many times is checked in its first 16 placements (memory stays bounded).
    worlds.truncate(16);
    for w in worlds {
        let full = y_to_z * w;
        let lin = DMat3::from_mat4(full);
        for i in 0..count {
            let (p, shape) = splat(i);
            if !p.is_finite() {
                continue;
            }
            geom.centres.push(full.transform_point3(p));
            if want_shapes {
                geom.shapes.get_or_insert_with(Vec::new).push(lin * shape);
            }
        }
        decoded = true;
    }
    decoded
}
