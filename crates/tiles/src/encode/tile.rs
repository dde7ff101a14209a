//! Splat tiles as glb: writes `Splats` as one `KHR_gaussian_splatting` POINTS primitive (layout in
//! ARCHITECTURE.md "glb tile layout"); `tile_read` reads any conforming glb back.

use super::glb::{GlbError, write_gltf_glb};
use super::gltf::{
    Accessor, AccessorType, Asset, Buffer, BufferView, ComponentType, Gltf, KHR_GAUSSIAN_SPLATTING,
    KhrGaussianSplatting, MODE_POINTS, Mesh, Node, Primitive, PrimitiveExtensions, Scene,
    TARGET_ARRAY_BUFFER,
};
use splat2tiles_core::splat::sh::{dc_color, srgb_to_linear};
use splat2tiles_core::splat::{Splats, sh_rest_count};

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
pub fn check_writable(splats: &Splats, centre: [f64; 3]) -> Result<(), GlbError> {
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

#[cfg(test)]
mod tests {
    use super::*;
    use splat2tiles_core::splat::Splat;

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
}
