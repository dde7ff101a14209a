//! Splat tiles as glb: writes `Splats` as one `KHR_gaussian_splatting` POINTS primitive (layout in
//! ARCHITECTURE.md "glb tile layout") and reads any conforming KHR_gaussian_splatting glb back.

use glam::{DMat4, DQuat, DVec3};

use super::glb::{GlbError, parse_json, read_glb, write_gltf_glb};
use super::gltf::{
    Accessor, AccessorType, Asset, Buffer, BufferView, ComponentType, Gltf, KHR_GAUSSIAN_SPLATTING,
    KHR_GAUSSIAN_SPLATTING_SPZ_2, KHR_MESH_QUANTIZATION, KhrGaussianSplatting, MODE_DEFAULT,
    MODE_POINTS, Mesh, Node, Primitive, PrimitiveExtensions, Scene, TARGET_ARRAY_BUFFER,
};
use crate::splat::sh::{color_to_sh0, dc_color, srgb_to_linear};
use crate::splat::{Splats, normalize_quat, sh_rest_count};

/// `asset.generator` of the tiles we write.
pub const GENERATOR: &str = concat!("splat2tiles ", env!("CARGO_PKG_VERSION"));
/// The 4x4 identity, column-major.
pub const IDENTITY: [f64; 16] = [
    1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0,
];
/// Kernel we write (the only one the base extension defines).
pub const KERNEL_ELLIPSE: &str = "ellipse";
/// Display-referred sRGB colour space (what 3DGS trainers produce).
pub const COLOR_SPACE_SRGB: &str = "srgb_rec709_display";
/// Display-referred linear colour space.
pub const COLOR_SPACE_LINEAR: &str = "lin_rec709_display";
/// Core position attribute.
pub const ATTR_POSITION: &str = "POSITION";
/// Core colour attribute (the fallback for clients without the extension).
pub const ATTR_COLOR_0: &str = "COLOR_0";
/// Rotation attribute (VEC4 x, y, z, w).
pub const ATTR_ROTATION: &str = "KHR_gaussian_splatting:ROTATION";
/// Linear scale attribute (VEC3).
pub const ATTR_SCALE: &str = "KHR_gaussian_splatting:SCALE";
/// Opacity attribute (SCALAR in [0, 1]).
pub const ATTR_OPACITY: &str = "KHR_gaussian_splatting:OPACITY";

/// Attribute name of SH coefficient `coef` (0..=2*degree, m ascending) of `degree` (0..=3).
pub fn sh_attribute(degree: u8, coef: u8) -> String {
    format!("KHR_gaussian_splatting:SH_DEGREE_{degree}_COEF_{coef}")
}

/// How attribute data is laid out in the buffer.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum TileLayout {
    /// One tightly packed, 4-byte aligned bufferView per attribute.
    #[default]
    Separate,
    /// One strided bufferView holding every attribute of a splat contiguously (splat order kept),
    /// so any byte prefix of the BIN chunk holds complete leading splats (`spec/prefix-layout.md`).
    Interleaved,
}

/// A tile decoded from a glb.
#[derive(Debug, Clone, PartialEq)]
pub struct DecodedTile {
    /// The splats; positions are the `POSITION` values (tile-relative, before the node matrix).
    pub splats: Splats,
    /// World matrix of the splat primitive's node, column-major (identity when absent).
    pub node_matrix: [f64; 16],
    /// `colorSpace` of the extension (`srgb_rec709_display` when the file omits it).
    pub color_space: String,
    /// `kernel` of the extension (`ellipse` when the file omits it).
    pub kernel: String,
    /// `asset.generator`, if any.
    pub generator: Option<String>,
    /// Whether the primitive carries `COLOR_0`.
    pub has_color0: bool,
    /// Tolerated departures from the spec (fallbacks used, values clamped or normalised).
    pub warnings: Vec<String>,
}

/// One attribute's data, ready to be laid out.
pub(crate) struct Column {
    pub(crate) semantic: String,
    kind: AccessorType,
    component: ComponentType,
    normalized: bool,
    pub(crate) data: Vec<u8>,
    min_max: Option<(Vec<f64>, Vec<f64>)>,
}

impl Column {
    fn floats(semantic: String, kind: AccessorType, values: impl Iterator<Item = f32>) -> Self {
        let mut data = Vec::with_capacity(values.size_hint().0 * 4);
        for v in values {
            data.extend_from_slice(&v.to_le_bytes());
        }
        Column {
            semantic,
            kind,
            component: ComponentType::F32,
            normalized: false,
            data,
            min_max: None,
        }
    }

    fn element_bytes(&self) -> usize {
        self.kind.components() * self.component.size()
    }
}

fn round_unorm8(v: f32) -> u8 {
    (v.clamp(0.0, 1.0) * 255.0).round() as u8
}

/// The attribute columns of a tile, in accessor order.
pub(crate) fn columns(splats: &Splats, centre: [f64; 3]) -> Vec<Column> {
    let n = splats.len();
    let rel: Vec<[f32; 3]> = splats
        .positions
        .iter()
        .map(|p| [0, 1, 2].map(|a| (p[a] - centre[a]) as f32))
        .collect();
    let mut lo = rel[0];
    let mut hi = rel[0];
    for p in &rel {
        for a in 0..3 {
            lo[a] = lo[a].min(p[a]);
            hi[a] = hi[a].max(p[a]);
        }
    }
    let mut position = Column::floats(
        ATTR_POSITION.into(),
        AccessorType::Vec3,
        rel.iter().flatten().copied(),
    );
    // f32 -> f64 is exact, so the JSON numbers equal the stored floats.
    position.min_max = Some((lo.map(f64::from).to_vec(), hi.map(f64::from).to_vec()));

    let mut cols = vec![
        position,
        Column::floats(
            ATTR_ROTATION.into(),
            AccessorType::Vec4,
            splats.rotations.iter().flatten().copied(),
        ),
        Column::floats(
            ATTR_SCALE.into(),
            AccessorType::Vec3,
            splats.scales.iter().flatten().copied(),
        ),
        Column::floats(
            ATTR_OPACITY.into(),
            AccessorType::Scalar,
            splats.opacities.iter().copied(),
        ),
        Column::floats(
            sh_attribute(0, 0),
            AccessorType::Vec3,
            splats.sh0.iter().flatten().copied(),
        ),
    ];
    let k = splats.rest_per_splat();
    for degree in 1..=splats.sh_degree {
        for coef in 0..=2 * degree {
            let j = (degree as usize).pow(2) - 1 + coef as usize;
            cols.push(Column::floats(
                sh_attribute(degree, coef),
                AccessorType::Vec3,
                (0..n).flat_map(|i| splats.sh_rest[i * k + j]),
            ));
        }
    }
    cols.push(Column {
        semantic: ATTR_COLOR_0.into(),
        kind: AccessorType::Vec4,
        component: ComponentType::U8,
        normalized: true,
        data: color_bytes(splats),
        min_max: None,
    });
    cols
}

/// The `COLOR_0` column's bytes (linear DC colour and opacity as unorm8 RGBA), on its own for
/// the encoders that quantise every other column themselves (meshopt).
pub(crate) fn color_bytes(splats: &Splats) -> Vec<u8> {
    let mut color = Vec::with_capacity(splats.len() * 4);
    for (sh0, &a) in splats.sh0.iter().zip(&splats.opacities) {
        let c = dc_color(*sh0).map(srgb_to_linear);
        color.extend_from_slice(&[
            round_unorm8(c[0]),
            round_unorm8(c[1]),
            round_unorm8(c[2]),
            round_unorm8(a),
        ]);
    }
    color
}

/// Lays the columns out one bufferView each; returns the views, accessors and buffer bytes.
fn layout_separate(cols: &[Column], count: usize) -> (Vec<BufferView>, Vec<Accessor>, Vec<u8>) {
    let total: usize = cols.iter().map(|c| c.data.len().next_multiple_of(4)).sum();
    let mut bin = Vec::with_capacity(total);
    let mut views = Vec::with_capacity(cols.len());
    let mut accessors = Vec::with_capacity(cols.len());
    for (i, c) in cols.iter().enumerate() {
        debug_assert_eq!(c.data.len(), c.element_bytes() * count);
        bin.resize(bin.len().next_multiple_of(4), 0);
        views.push(BufferView {
            buffer: 0,
            byte_offset: bin.len() as u64,
            byte_length: c.data.len() as u64,
            byte_stride: None,
            target: Some(TARGET_ARRAY_BUFFER),
            ..Default::default()
        });
        bin.extend_from_slice(&c.data);
        accessors.push(Accessor {
            buffer_view: Some(i as u32),
            byte_offset: 0,
            component_type: c.component.code(),
            normalized: c.normalized,
            count: count as u64,
            kind: c.kind,
            min: c.min_max.as_ref().map(|m| m.0.clone()),
            max: c.min_max.as_ref().map(|m| m.1.clone()),
            sparse: None,
            name: None,
        });
    }
    bin.resize(bin.len().next_multiple_of(4), 0);
    (views, accessors, bin)
}

/// Lays the columns out as one strided bufferView (all element sizes are multiples of 4, so
/// every accessor offset and the stride are too, as glTF requires of vertex attributes).
fn layout_interleaved(cols: &[Column], count: usize) -> (Vec<BufferView>, Vec<Accessor>, Vec<u8>) {
    let stride: usize = cols.iter().map(Column::element_bytes).sum();
    debug_assert!(cols.iter().all(|c| c.element_bytes() % 4 == 0) && stride <= 252);
    let mut bin = vec![0u8; stride * count];
    let mut accessors = Vec::with_capacity(cols.len());
    let mut offset = 0;
    for c in cols {
        let e = c.element_bytes();
        for (i, src) in c.data.chunks_exact(e).enumerate() {
            bin[i * stride + offset..i * stride + offset + e].copy_from_slice(src);
        }
        accessors.push(Accessor {
            buffer_view: Some(0),
            byte_offset: offset as u64,
            component_type: c.component.code(),
            normalized: c.normalized,
            count: count as u64,
            kind: c.kind,
            min: c.min_max.as_ref().map(|m| m.0.clone()),
            max: c.min_max.as_ref().map(|m| m.1.clone()),
            sparse: None,
            name: None,
        });
        offset += e;
    }
    let views = vec![BufferView {
        buffer: 0,
        byte_length: bin.len() as u64,
        byte_stride: Some(stride as u32),
        target: Some(TARGET_ARRAY_BUFFER),
        name: Some("splats (interleaved, prefix-renderable)".into()),
        ..Default::default()
    }];
    (views, accessors, bin)
}

/// The one-node, one-mesh, one-POINTS-primitive document every splat tile shares; `children`
/// are child extensions of `KHR_gaussian_splatting` (compression), `buffers` the buffers.
#[allow(clippy::too_many_arguments)]
pub(crate) fn splat_document(
    attributes: std::collections::BTreeMap<String, u32>,
    accessors: Vec<Accessor>,
    buffer_views: Vec<BufferView>,
    buffers: Vec<Buffer>,
    node_matrix: [f64; 16],
    children: Option<serde_json::Map<String, serde_json::Value>>,
    extensions_used: Vec<String>,
    extensions_required: Vec<String>,
) -> Gltf {
    Gltf {
        asset: Asset {
            version: "2.0".into(),
            generator: Some(GENERATOR.into()),
            ..Default::default()
        },
        scene: Some(0),
        scenes: vec![Scene {
            nodes: vec![0],
            name: None,
        }],
        nodes: vec![Node {
            mesh: Some(0),
            matrix: (node_matrix != IDENTITY).then_some(node_matrix),
            ..Default::default()
        }],
        meshes: vec![Mesh {
            primitives: vec![Primitive {
                attributes,
                mode: Some(MODE_POINTS),
                extensions: Some(PrimitiveExtensions {
                    gaussian_splatting: Some(KhrGaussianSplatting {
                        kernel: Some(KERNEL_ELLIPSE.into()),
                        color_space: Some(COLOR_SPACE_SRGB.into()),
                        extensions: children,
                        ..Default::default()
                    }),
                    other: Default::default(),
                }),
                ..Default::default()
            }],
            name: None,
        }],
        accessors,
        buffer_views,
        buffers,
        extensions_used,
        extensions_required,
        ..Default::default()
    }
}

/// Refuses what no tile writer can store: no splat, non-finite values, relative positions that
/// overflow f32.
pub(crate) fn check_writable(splats: &Splats, centre: [f64; 3]) -> Result<(), GlbError> {
    splats.check_lengths();
    if splats.is_empty() {
        return Err(GlbError::EmptyTile);
    }
    if let Some(index) = splats.first_non_finite() {
        return Err(GlbError::NonFinite { index });
    }
    if let Some(index) = splats
        .positions
        .iter()
        .position(|p| (0..3).any(|a| !((p[a] - centre[a]) as f32).is_finite()))
    {
        return Err(GlbError::NonFinite { index });
    }
    Ok(())
}

/// Writes a splat tile as glb: `POSITION` = splat centre - `centre` (subtracted in f64), one node
/// with `node_matrix` (column-major; omitted when identity), all attributes float plus `COLOR_0`.
///
/// # Panics
/// When [`try_write_tile_glb`] refuses: no splat, a non-finite value, or more than 4 GiB.
pub fn write_tile_glb(splats: &Splats, centre: [f64; 3], node_matrix: [f64; 16]) -> Vec<u8> {
    try_write_tile_glb(splats, centre, node_matrix, TileLayout::Separate)
        .unwrap_or_else(|e| panic!("write_tile_glb: {e}"))
}

/// [`write_tile_glb`] with a chosen layout, refusing empty tiles, non-finite values (including a
/// relative position that overflows f32) and glbs over 4 GiB instead of panicking.
pub fn try_write_tile_glb(
    splats: &Splats,
    centre: [f64; 3],
    node_matrix: [f64; 16],
    layout: TileLayout,
) -> Result<Vec<u8>, GlbError> {
    check_writable(splats, centre)?;
    let n = splats.len();
    // Per splat: 12 + 16 + 12 + 4 + 12 * (1 + rest) + 4 bytes; refuse before allocating.
    let per_splat = 60 + 12 * sh_rest_count(splats.sh_degree) as u64;
    let bytes = per_splat.saturating_mul(n as u64);
    if bytes > u32::MAX as u64 {
        return Err(GlbError::TooLarge { bytes });
    }
    let cols = columns(splats, centre);
    let (buffer_views, accessors, bin) = match layout {
        TileLayout::Separate => layout_separate(&cols, n),
        TileLayout::Interleaved => layout_interleaved(&cols, n),
    };
    let attributes = cols
        .iter()
        .enumerate()
        .map(|(i, c)| (c.semantic.clone(), i as u32))
        .collect();
    let doc = splat_document(
        attributes,
        accessors,
        buffer_views,
        vec![Buffer {
            byte_length: bin.len() as u64,
            ..Default::default()
        }],
        node_matrix,
        None,
        vec![KHR_GAUSSIAN_SPLATTING.into()],
        vec![],
    );
    write_gltf_glb(&doc, Some(&bin))
}

/// Which component types an attribute accepts (KHR_gaussian_splatting "Attributes" table).
#[derive(Clone, Copy)]
enum Allowed {
    /// Float only (SH, POSITION without KHR_mesh_quantization).
    Float,
    /// Float or any 8/16-bit integer, normalized or not (POSITION with KHR_mesh_quantization).
    Quantized,
    /// Float, signed byte/short normalized.
    Rotation,
    /// Float, (un)signed byte/short, normalized or not. The ratified text lists unsigned types,
    /// an earlier draft signed ones: both are read.
    Scale,
    /// Float, unsigned byte/short normalized (OPACITY, COLOR_0).
    Unorm,
}

impl Allowed {
    fn accepts(self, ct: ComponentType, normalized: bool) -> bool {
        use ComponentType::*;
        match (self, ct) {
            (_, F32) => !normalized,
            (_, U32) => false,
            (Allowed::Float, _) => false,
            (Allowed::Quantized | Allowed::Scale, _) => true,
            (Allowed::Rotation, I8 | I16) => normalized,
            (Allowed::Unorm, U8 | U16) => normalized,
            _ => false,
        }
    }
}

fn decode_component(ct: ComponentType, normalized: bool, b: &[u8]) -> f32 {
    match ct {
        ComponentType::F32 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]),
        ComponentType::I8 => {
            let v = b[0] as i8 as f32;
            if normalized { (v / 127.0).max(-1.0) } else { v }
        }
        ComponentType::U8 => {
            let v = b[0] as f32;
            if normalized { v / 255.0 } else { v }
        }
        ComponentType::I16 => {
            let v = i16::from_le_bytes([b[0], b[1]]) as f32;
            if normalized {
                (v / 32767.0).max(-1.0)
            } else {
                v
            }
        }
        ComponentType::U16 => {
            let v = u16::from_le_bytes([b[0], b[1]]) as f32;
            if normalized { v / 65535.0 } else { v }
        }
        ComponentType::U32 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f32,
    }
}

/// The decoding context: document, binary chunk and where the primitive sits.
struct Ctx<'a> {
    doc: &'a Gltf,
    bin: Option<&'a [u8]>,
    prim_path: String,
}

impl Ctx<'_> {
    /// Decodes accessor `index` (named by `semantic`) into `count * comps` floats.
    fn accessor(
        &self,
        semantic: &str,
        index: u32,
        kinds: &[AccessorType],
        allowed: Allowed,
        expect_count: Option<usize>,
    ) -> Result<(Vec<f32>, usize), GlbError> {
        let apath = format!("/accessors/{index}");
        let acc = self.doc.accessors.get(index as usize).ok_or_else(|| {
            GlbError::invalid(
                format!("{}/attributes/{semantic}", self.prim_path),
                format!("accessor {index} does not exist"),
            )
        })?;
        if !kinds.contains(&acc.kind) {
            return Err(GlbError::invalid(
                format!("{apath}/type"),
                format!("{semantic} must be {kinds:?}, found {:?}", acc.kind),
            ));
        }
        let ct = ComponentType::from_code(acc.component_type)
            .filter(|ct| allowed.accepts(*ct, acc.normalized))
            .ok_or_else(|| {
                GlbError::invalid(
                    format!("{apath}/componentType"),
                    format!(
                        "{semantic}: componentType {} (normalized {}) is not allowed",
                        acc.component_type, acc.normalized
                    ),
                )
            })?;
        if acc.sparse.is_some() {
            return Err(GlbError::unsupported(
                format!("{apath}/sparse"),
                "sparse accessors",
            ));
        }
        let count = usize::try_from(acc.count)
            .ok()
            .filter(|&c| c > 0)
            .ok_or_else(|| GlbError::invalid(format!("{apath}/count"), "count must be >= 1"))?;
        if let Some(want) = expect_count
            && count != want
        {
            return Err(GlbError::invalid(
                format!("{apath}/count"),
                format!("{semantic} has {count} elements, POSITION has {want}"),
            ));
        }
        let comps = acc.kind.components();
        let elem = comps * ct.size();
        let Some(view_index) = acc.buffer_view else {
            // glTF: an accessor without bufferView reads as zeros. Only allowed once POSITION
            // (which must have data) has bounded the count, so this cannot allocate without limit.
            if expect_count.is_none() {
                return Err(GlbError::unsupported(
                    format!("{apath}/bufferView"),
                    "POSITION without a bufferView (data held by an extension)",
                ));
            }
            return Ok((vec![0.0; count * comps], comps));
        };
        let vpath = format!("/bufferViews/{view_index}");
        let view = self
            .doc
            .buffer_views
            .get(view_index as usize)
            .ok_or_else(|| {
                GlbError::invalid(
                    format!("{apath}/bufferView"),
                    format!("bufferView {view_index} does not exist"),
                )
            })?;
        let data = self.view_bytes(view, &vpath)?;
        let stride = match view.byte_stride {
            None => elem,
            Some(s) if (s as usize) >= elem => s as usize,
            Some(s) => {
                return Err(GlbError::invalid(
                    format!("{vpath}/byteStride"),
                    format!("byteStride {s} is less than the element size {elem}"),
                ));
            }
        };
        let needed = (count as u64 - 1)
            .checked_mul(stride as u64)
            .and_then(|v| v.checked_add(elem as u64))
            .and_then(|v| v.checked_add(acc.byte_offset));
        if needed.is_none_or(|n| n > data.len() as u64) {
            return Err(GlbError::invalid(
                apath,
                format!(
                    "byteOffset {} + {count} elements of {elem} bytes (stride {stride}) run past \
                     the end of bufferView {view_index} ({} bytes)",
                    acc.byte_offset,
                    data.len()
                ),
            ));
        }
        let data = &data[acc.byte_offset as usize..];
        let cs = ct.size();
        let mut out = Vec::with_capacity(count * comps);
        if ct == ComponentType::F32 {
            // Floats (every Best tile, packed or interleaved): element by element, without the
            // per-component dispatch. `needed` above bounds the last element.
            out.resize(count * comps, 0.0);
            for (o, e) in out.chunks_exact_mut(comps).zip(data.chunks(stride)) {
                for (v, b) in o.iter_mut().zip(e[..elem].chunks_exact(4)) {
                    *v = f32::from_le_bytes([b[0], b[1], b[2], b[3]]);
                }
            }
            return Ok((out, comps));
        }
        for i in 0..count {
            let e = &data[i * stride..i * stride + elem];
            for c in 0..comps {
                out.push(decode_component(
                    ct,
                    acc.normalized,
                    &e[c * cs..(c + 1) * cs],
                ));
            }
        }
        Ok((out, comps))
    }

    /// The bytes of a bufferView, checked against its buffer and the BIN chunk.
    fn view_bytes(&self, view: &BufferView, vpath: &str) -> Result<&[u8], GlbError> {
        let bpath = format!("/buffers/{}", view.buffer);
        let buffer = self.doc.buffers.get(view.buffer as usize).ok_or_else(|| {
            GlbError::invalid(
                format!("{vpath}/buffer"),
                format!("buffer {} does not exist", view.buffer),
            )
        })?;
        if view.buffer != 0 || buffer.uri.is_some() {
            return Err(GlbError::unsupported(
                bpath,
                "buffers other than the glb BIN chunk (external or data URIs)",
            ));
        }
        let bin = self
            .bin
            .ok_or_else(|| GlbError::invalid(&bpath, "the glb has no BIN chunk"))?;
        if buffer.byte_length > bin.len() as u64 {
            return Err(GlbError::invalid(
                format!("{bpath}/byteLength"),
                format!(
                    "byteLength {} exceeds the BIN chunk ({} bytes)",
                    buffer.byte_length,
                    bin.len()
                ),
            ));
        }
        let end = view.byte_offset.checked_add(view.byte_length);
        if end.is_none_or(|e| e > buffer.byte_length) {
            return Err(GlbError::invalid(
                vpath,
                format!(
                    "byteOffset {} + byteLength {} run past the end of buffer {} ({} bytes)",
                    view.byte_offset, view.byte_length, view.buffer, buffer.byte_length
                ),
            ));
        }
        Ok(&bin[view.byte_offset as usize..(view.byte_offset + view.byte_length) as usize])
    }
}

/// Local transform of a node (matrix, or T * R * S), column-major.
fn local_matrix(node: &Node) -> DMat4 {
    if let Some(m) = node.matrix {
        return DMat4::from_cols_array(&m);
    }
    let t = node.translation.map_or(DVec3::ZERO, DVec3::from_array);
    let s = node.scale.map_or(DVec3::ONE, DVec3::from_array);
    let r = node
        .rotation
        .map(DQuat::from_array)
        .filter(|q| q.length_squared() > 0.0)
        .map_or(DQuat::IDENTITY, |q| q.normalize());
    DMat4::from_scale_rotation_translation(s, r, t)
}

/// Every (mesh index, world matrix) placed by the default scene (or scene 0).
fn placed_meshes(doc: &Gltf) -> Result<Vec<(usize, DMat4, String)>, GlbError> {
    let roots: Vec<u32> =
        match doc
            .scene
            .map(|s| s as usize)
            .or(if doc.scenes.is_empty() { None } else { Some(0) })
        {
            Some(s) => doc
                .scenes
                .get(s)
                .ok_or_else(|| GlbError::invalid("/scene", format!("scene {s} does not exist")))?
                .nodes
                .clone(),
            // No scene: every node that is nobody's child is a root.
            None => {
                let mut is_child = vec![false; doc.nodes.len()];
                for n in &doc.nodes {
                    for &c in &n.children {
                        if let Some(f) = is_child.get_mut(c as usize) {
                            *f = true;
                        }
                    }
                }
                (0..doc.nodes.len() as u32)
                    .filter(|&i| !is_child[i as usize])
                    .collect()
            }
        };
    let mut visited = vec![false; doc.nodes.len()];
    let mut stack: Vec<(u32, DMat4)> = roots.iter().rev().map(|&r| (r, DMat4::IDENTITY)).collect();
    let mut out = Vec::new();
    while let Some((i, parent)) = stack.pop() {
        let path = format!("/nodes/{i}");
        let node = doc
            .nodes
            .get(i as usize)
            .ok_or_else(|| GlbError::invalid(&path, "node does not exist"))?;
        if std::mem::replace(&mut visited[i as usize], true) {
            return Err(GlbError::invalid(
                path,
                "node reached twice (a cycle or a shared child)",
            ));
        }
        let world = parent * local_matrix(node);
        if let Some(m) = node.mesh {
            if m as usize >= doc.meshes.len() {
                return Err(GlbError::invalid(
                    format!("{path}/mesh"),
                    format!("mesh {m} does not exist"),
                ));
            }
            out.push((m as usize, world, path));
        }
        for &c in node.children.iter().rev() {
            stack.push((c, world));
        }
    }
    Ok(out)
}

/// sRGB encoding (linear -> display), the inverse of [`srgb_to_linear`].
fn linear_to_srgb(v: f32) -> f32 {
    if v <= 0.003_130_8 {
        v * 12.92
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// Reads a `KHR_gaussian_splatting` glb: ours or any other conforming writer's (any stride and
/// offset, every component type the extension allows, optional SH degrees and `COLOR_0`).
///
/// The one splat primitive placed by the default scene is decoded; its node's world matrix is
/// returned as `node_matrix`. Allocations stay proportional to the input size.
pub fn read_tile_glb(bytes: &[u8]) -> Result<DecodedTile, GlbError> {
    let chunks = read_glb(bytes)?;
    let doc = parse_json(&chunks)?;
    for (i, ext) in doc.extensions_required.iter().enumerate() {
        if ext != KHR_GAUSSIAN_SPLATTING && ext != KHR_MESH_QUANTIZATION {
            return Err(GlbError::unsupported(
                format!("/extensionsRequired/{i}"),
                format!("required extension {ext}"),
            ));
        }
    }
    let mut warnings = Vec::new();

    // Find the splat primitive(s) through the scene graph.
    let mut found = Vec::new();
    for (m, world, node_path) in placed_meshes(&doc)? {
        for (p, prim) in doc.meshes[m].primitives.iter().enumerate() {
            let ext = prim
                .extensions
                .as_ref()
                .and_then(|e| e.gaussian_splatting.as_ref());
            if let Some(ext) = ext {
                found.push((m, p, prim, ext, world, node_path.clone()));
            }
        }
    }
    if found.is_empty() {
        return Err(GlbError::invalid(
            "/meshes",
            "no primitive placed by the scene has the KHR_gaussian_splatting extension",
        ));
    }
    if found.len() > 1 {
        return Err(GlbError::unsupported(
            found[1].5.clone(),
            format!(
                "{} placed splat primitives (this reader decodes one per tile)",
                found.len()
            ),
        ));
    }
    let (m, p, prim, ext, world, _) = found.swap_remove(0);
    let prim_path = format!("/meshes/{m}/primitives/{p}");
    let mode = prim.mode.unwrap_or(MODE_DEFAULT);
    if mode != MODE_POINTS {
        return Err(GlbError::invalid(
            format!("{prim_path}/mode"),
            format!("mode {mode}: KHR_gaussian_splatting primitives must be POINTS (0)"),
        ));
    }
    if prim.indices.is_some() {
        return Err(GlbError::unsupported(
            format!("{prim_path}/indices"),
            "indexed splat primitives",
        ));
    }
    if let Some(children) = &ext.extensions
        && let Some(name) = children.keys().next()
    {
        let what = if name == KHR_GAUSSIAN_SPLATTING_SPZ_2 {
            "SPZ-compressed splats (decode with the SPZ reader)".to_string()
        } else {
            format!("child extension {name}")
        };
        return Err(GlbError::unsupported(
            format!("{prim_path}/extensions/{KHR_GAUSSIAN_SPLATTING}/extensions/{name}"),
            what,
        ));
    }
    let kernel = ext.kernel.clone().unwrap_or_else(|| {
        warnings.push("kernel missing; read as ellipse".into());
        KERNEL_ELLIPSE.into()
    });
    let color_space = ext.color_space.clone().unwrap_or_else(|| {
        warnings.push("colorSpace missing; read as srgb_rec709_display".into());
        COLOR_SPACE_SRGB.into()
    });

    let ctx = Ctx {
        doc: &doc,
        bin: chunks.bin,
        prim_path: prim_path.clone(),
    };
    let attr = |name: &str| prim.attributes.get(name).copied();
    let required = |name: &str| {
        attr(name).ok_or_else(|| {
            GlbError::invalid(
                format!("{prim_path}/attributes"),
                format!("missing required attribute {name}"),
            )
        })
    };
    use AccessorType::{Scalar, Vec3, Vec4};

    let quantized = doc
        .extensions_used
        .iter()
        .any(|e| e == KHR_MESH_QUANTIZATION);
    let pos_allowed = if quantized {
        Allowed::Quantized
    } else {
        Allowed::Float
    };
    let (pos, _) = ctx.accessor(
        ATTR_POSITION,
        required(ATTR_POSITION)?,
        &[Vec3],
        pos_allowed,
        None,
    )?;
    let n = pos.len() / 3;
    let (rot, _) = ctx.accessor(
        ATTR_ROTATION,
        required(ATTR_ROTATION)?,
        &[Vec4],
        Allowed::Rotation,
        Some(n),
    )?;
    let (scale, _) = ctx.accessor(
        ATTR_SCALE,
        required(ATTR_SCALE)?,
        &[Vec3],
        Allowed::Scale,
        Some(n),
    )?;
    let color = attr(ATTR_COLOR_0)
        .map(|i| ctx.accessor(ATTR_COLOR_0, i, &[Vec3, Vec4], Allowed::Unorm, Some(n)))
        .transpose()?;
    let opacity = match attr(ATTR_OPACITY) {
        Some(i) => {
            ctx.accessor(ATTR_OPACITY, i, &[Scalar], Allowed::Unorm, Some(n))?
                .0
        }
        None => match &color {
            Some((c, 4)) => {
                warnings.push("OPACITY missing; taken from COLOR_0 alpha".into());
                c.chunks_exact(4).map(|c| c[3]).collect()
            }
            _ => {
                return Err(GlbError::invalid(
                    format!("{prim_path}/attributes"),
                    format!("missing required attribute {ATTR_OPACITY} (and no COLOR_0 alpha)"),
                ));
            }
        },
    };
    let sh0_name = sh_attribute(0, 0);
    let sh0: Vec<[f32; 3]> = match attr(&sh0_name) {
        Some(i) => {
            let (v, _) = ctx.accessor(&sh0_name, i, &[Vec3], Allowed::Float, Some(n))?;
            v.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect()
        }
        None => match &color {
            Some((c, comps)) => {
                warnings.push(format!("{sh0_name} missing; derived from COLOR_0"));
                let srgb = color_space != COLOR_SPACE_LINEAR;
                c.chunks_exact(*comps)
                    .map(|c| {
                        let rgb = [c[0], c[1], c[2]];
                        color_to_sh0(if srgb { rgb.map(linear_to_srgb) } else { rgb })
                    })
                    .collect()
            }
            None => {
                return Err(GlbError::invalid(
                    format!("{prim_path}/attributes"),
                    format!("missing {sh0_name} and no COLOR_0 to fall back on"),
                ));
            }
        },
    };

    // SH degree: the highest degree whose coefficients (and all lower ones) are all present.
    let mut degree = 0u8;
    for l in 1..=3u8 {
        let present = (0..=2 * l)
            .filter(|&c| attr(&sh_attribute(l, c)).is_some())
            .count();
        if present == 0 {
            break;
        }
        if present as u8 != 2 * l + 1 || degree != l - 1 {
            warnings.push(format!(
                "SH degree {l} has {present} of {} coefficients; degrees from {l} up ignored",
                2 * l + 1
            ));
            break;
        }
        degree = l;
    }
    let k = sh_rest_count(degree);
    let mut sh_rest = vec![[0f32; 3]; n * k];
    for l in 1..=degree {
        for c in 0..=2 * l {
            let name = sh_attribute(l, c);
            let index = attr(&name).expect("presence checked above");
            let (v, _) = ctx.accessor(&name, index, &[Vec3], Allowed::Float, Some(n))?;
            let j = (l as usize).pow(2) - 1 + c as usize;
            for (i, t) in v.chunks_exact(3).enumerate() {
                sh_rest[i * k + j] = [t[0], t[1], t[2]];
            }
        }
    }

    // Normalise rotations that are not unit (quantised ones); keep float unit ones bit-exact.
    let mut renormalised = 0usize;
    let rotations: Vec<[f32; 4]> = rot
        .chunks_exact(4)
        .map(|q| {
            let q = [q[0], q[1], q[2], q[3]];
            let n2: f64 = q.iter().map(|&v| v as f64 * v as f64).sum();
            if (n2.sqrt() - 1.0).abs() > 1e-4 {
                renormalised += 1;
                normalize_quat(q)
            } else {
                q
            }
        })
        .collect();
    if renormalised > 0 {
        warnings.push(format!(
            "{renormalised} rotations were not unit quaternions; normalised"
        ));
    }
    let mut clamped = 0usize;
    let opacities: Vec<f32> = opacity
        .into_iter()
        .map(|a| {
            if (0.0..=1.0).contains(&a) || a.is_nan() {
                a
            } else {
                clamped += 1;
                a.clamp(0.0, 1.0)
            }
        })
        .collect();
    if clamped > 0 {
        warnings.push(format!("{clamped} opacities outside [0, 1]; clamped"));
    }
    let negative = scale.iter().filter(|&&s| s < 0.0).count();
    if negative > 0 {
        warnings.push(format!(
            "{negative} negative scale components (the spec wants linear, non-negative)"
        ));
    }

    let splats = Splats {
        positions: pos
            .chunks_exact(3)
            .map(|c| [c[0] as f64, c[1] as f64, c[2] as f64])
            .collect(),
        scales: scale.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
        rotations,
        opacities,
        sh0,
        sh_degree: degree,
        sh_rest,
    };
    splats.check_lengths();
    Ok(DecodedTile {
        splats,
        node_matrix: world.to_cols_array(),
        color_space,
        kernel,
        generator: doc.asset.generator.clone(),
        has_color0: color.is_some(),
        warnings,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::splat::Splat;

    fn one_splat() -> Splats {
        let mut s = Splats::new(1);
        s.push(
            Splat {
                position: [10.0, 20.0, 30.0],
                scale: [0.1, 0.2, 0.3],
                rotation: [0.0, 0.0, 0.0, 1.0],
                opacity: 0.5,
                sh0: [0.0, 1.0, -1.0],
            },
            &[[0.1, 0.2, 0.3], [0.4, 0.5, 0.6], [0.7, 0.8, 0.9]],
        );
        s
    }

    #[test]
    fn color0_is_linear_dc_with_opacity_alpha() {
        let cols = columns(&one_splat(), [0.0; 3]);
        let c = cols.iter().find(|c| c.semantic == ATTR_COLOR_0).unwrap();
        let want = dc_color([0.0, 1.0, -1.0]).map(|v| round_unorm8(srgb_to_linear(v)));
        assert_eq!(c.data, vec![want[0], want[1], want[2], 128]);
        // 0.5 display -> ~0.214 linear -> 55.
        assert_eq!(want[0], 55);
    }

    #[test]
    fn refuses_empty_and_non_finite() {
        let empty = Splats::new(0);
        assert_eq!(
            try_write_tile_glb(&empty, [0.0; 3], IDENTITY, TileLayout::Separate),
            Err(GlbError::EmptyTile)
        );
        let mut s = one_splat();
        s.sh_rest[1][2] = f32::NAN;
        assert_eq!(
            try_write_tile_glb(&s, [0.0; 3], IDENTITY, TileLayout::Separate),
            Err(GlbError::NonFinite { index: 0 })
        );
        let s = one_splat();
        assert_eq!(
            try_write_tile_glb(&s, [-1e300, 0.0, 0.0], IDENTITY, TileLayout::Separate),
            Err(GlbError::NonFinite { index: 0 })
        );
    }

    #[test]
    fn trs_nodes_and_hierarchy_compose() {
        let doc = Gltf {
            scenes: vec![Scene {
                nodes: vec![0],
                name: None,
            }],
            nodes: vec![
                Node {
                    children: vec![1],
                    translation: Some([1.0, 2.0, 3.0]),
                    ..Default::default()
                },
                Node {
                    mesh: Some(0),
                    scale: Some([2.0, 2.0, 2.0]),
                    ..Default::default()
                },
            ],
            meshes: vec![Mesh::default()],
            ..Default::default()
        };
        let placed = placed_meshes(&doc).unwrap();
        assert_eq!(placed.len(), 1);
        let m = placed[0].1.to_cols_array();
        assert_eq!(m[0], 2.0);
        assert_eq!(&m[12..15], &[1.0, 2.0, 3.0]);
    }

    #[test]
    fn quantized_components_decode() {
        assert_eq!(decode_component(ComponentType::I8, true, &[0x81]), -1.0);
        assert_eq!(decode_component(ComponentType::I8, true, &[0x80]), -1.0);
        assert_eq!(decode_component(ComponentType::U8, true, &[255]), 1.0);
        assert_eq!(
            decode_component(ComponentType::U16, true, &[0xff, 0xff]),
            1.0
        );
        assert_eq!(
            decode_component(ComponentType::I16, true, &32767i16.to_le_bytes()),
            1.0
        );
        assert_eq!(decode_component(ComponentType::U8, false, &[7]), 7.0);
        assert!(Allowed::Rotation.accepts(ComponentType::I8, true));
        assert!(!Allowed::Rotation.accepts(ComponentType::I8, false));
        assert!(!Allowed::Float.accepts(ComponentType::U8, true));
        assert!(Allowed::Scale.accepts(ComponentType::U16, false));
        assert!(!Allowed::Unorm.accepts(ComponentType::U8, false));
    }
}
