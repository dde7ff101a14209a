//! Serde structs for the glTF 2.0 JSON subset that splat tiles write and read (glTF 2.0 sec. 5).
//! Own structs because `gltf-json` rejects the namespaced `KHR_gaussian_splatting:*` attributes.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};
use serde_json::{Map, Value};

/// Name of the splat extension, on primitives and in `extensionsUsed`.
pub const KHR_GAUSSIAN_SPLATTING: &str = "KHR_gaussian_splatting";
/// The SPZ v2 compression child extension (decoding it is not this module's job).
pub const KHR_GAUSSIAN_SPLATTING_SPZ_2: &str = "KHR_gaussian_splatting_compression_spz_2";
/// This project's codebook compression child extension (spec/codebook-variant.md; only
/// splat2tiles' viewers decode it).
pub const S2T_GAUSSIAN_SPLATTING_CODEBOOK: &str = "S2T_gaussian_splatting_compression_codebook";
/// Vendor (ratified) bufferView compression extension with filters.
pub const EXT_MESHOPT_COMPRESSION: &str = "EXT_meshopt_compression";
/// Core glTF quantized vertex attributes extension.
pub const KHR_MESH_QUANTIZATION: &str = "KHR_mesh_quantization";
/// `bufferView.target` for vertex attribute data.
pub const TARGET_ARRAY_BUFFER: u32 = 34962;
/// `primitive.mode` POINTS.
pub const MODE_POINTS: u32 = 0;
/// `primitive.mode` default when absent (TRIANGLES).
pub const MODE_DEFAULT: u32 = 4;

fn is_zero(v: &u64) -> bool {
    *v == 0
}

fn is_false(v: &bool) -> bool {
    !*v
}

/// A glTF document (the top-level object); unknown members of every object are ignored.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "camelCase")]
pub struct Gltf {
    /// Required `asset` object.
    pub asset: Asset,
    /// Default scene index.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scene: Option<u32>,
    /// Scenes.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub scenes: Vec<Scene>,
    /// Nodes.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub nodes: Vec<Node>,
    /// Meshes.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub meshes: Vec<Mesh>,
    /// Accessors.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub accessors: Vec<Accessor>,
    /// Buffer views.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub buffer_views: Vec<BufferView>,
    /// Buffers.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub buffers: Vec<Buffer>,
    /// Extensions used anywhere in the document.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub extensions_used: Vec<String>,
    /// Extensions a client must support to load the document.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub extensions_required: Vec<String>,
    /// Top-level extension objects.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub extensions: Option<Map<String, Value>>,
    /// Application data.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub extras: Option<Value>,
}

/// The `asset` object.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "camelCase")]
pub struct Asset {
    /// glTF version, `"2.0"`.
    pub version: String,
    /// Tool that wrote the file.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub generator: Option<String>,
    /// Copyright message.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub copyright: Option<String>,
    /// Minimum glTF version a client must support.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub min_version: Option<String>,
    /// Application data.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub extras: Option<Value>,
}

/// A scene: its root nodes.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "camelCase")]
pub struct Scene {
    /// Root node indices.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub nodes: Vec<u32>,
    /// Name.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
}

/// A node: a local transform (either `matrix` or TRS), an optional mesh and children.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "camelCase")]
pub struct Node {
    /// Child node indices.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub children: Vec<u32>,
    /// Mesh index.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mesh: Option<u32>,
    /// Local transform, column-major.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub matrix: Option<[f64; 16]>,
    /// Translation (TRS form).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub translation: Option<[f64; 3]>,
    /// Rotation quaternion x, y, z, w (TRS form).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rotation: Option<[f64; 4]>,
    /// Scale (TRS form).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scale: Option<[f64; 3]>,
    /// Name.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
}

/// A mesh: a list of primitives.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "camelCase")]
pub struct Mesh {
    /// Primitives.
    pub primitives: Vec<Primitive>,
    /// Name.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
}

/// A mesh primitive: attribute semantics to accessor indices, mode and extensions.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "camelCase")]
pub struct Primitive {
    /// Attribute semantic -> accessor index (sorted by name, a stable order).
    pub attributes: BTreeMap<String, u32>,
    /// Index accessor.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub indices: Option<u32>,
    /// Material index.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub material: Option<u32>,
    /// Topology; absent means TRIANGLES (4).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mode: Option<u32>,
    /// Primitive extensions.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub extensions: Option<PrimitiveExtensions>,
}

/// The `extensions` object of a primitive: the splat extension typed, any other kept as JSON.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct PrimitiveExtensions {
    /// `KHR_gaussian_splatting`, when present.
    #[serde(
        rename = "KHR_gaussian_splatting",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    pub gaussian_splatting: Option<KhrGaussianSplatting>,
    /// Every other extension object.
    #[serde(flatten)]
    pub other: Map<String, Value>,
}

/// The `KHR_gaussian_splatting` primitive extension object.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "camelCase")]
pub struct KhrGaussianSplatting {
    /// Kernel, required by the spec (`"ellipse"`); optional here to read older files.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub kernel: Option<String>,
    /// Colour space, required by the spec; optional here to read older files.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub color_space: Option<String>,
    /// Projection (default `"perspective"`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub projection: Option<String>,
    /// Sorting method (default `"cameraDistance"`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sorting_method: Option<String>,
    /// Child extensions (compression and the like).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub extensions: Option<Map<String, Value>>,
}

/// Accessor element type.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "UPPERCASE")]
pub enum AccessorType {
    /// One component.
    Scalar,
    /// Two components.
    Vec2,
    /// Three components.
    Vec3,
    /// Four components.
    Vec4,
    /// 2x2 matrix.
    Mat2,
    /// 3x3 matrix.
    Mat3,
    /// 4x4 matrix.
    Mat4,
}

impl AccessorType {
    /// Number of components per element.
    pub fn components(self) -> usize {
        match self {
            AccessorType::Scalar => 1,
            AccessorType::Vec2 => 2,
            AccessorType::Vec3 => 3,
            AccessorType::Vec4 => 4,
            AccessorType::Mat2 => 4,
            AccessorType::Mat3 => 9,
            AccessorType::Mat4 => 16,
        }
    }
}

/// Accessor component type (the glTF GL enum values).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ComponentType {
    /// 5120, signed byte.
    I8,
    /// 5121, unsigned byte.
    U8,
    /// 5122, signed short.
    I16,
    /// 5123, unsigned short.
    U16,
    /// 5125, unsigned int (indices only).
    U32,
    /// 5126, float.
    F32,
}

impl ComponentType {
    /// The type for a glTF `componentType` code.
    pub fn from_code(code: u32) -> Option<Self> {
        Some(match code {
            5120 => ComponentType::I8,
            5121 => ComponentType::U8,
            5122 => ComponentType::I16,
            5123 => ComponentType::U16,
            5125 => ComponentType::U32,
            5126 => ComponentType::F32,
            _ => return None,
        })
    }

    /// The glTF `componentType` code.
    pub fn code(self) -> u32 {
        match self {
            ComponentType::I8 => 5120,
            ComponentType::U8 => 5121,
            ComponentType::I16 => 5122,
            ComponentType::U16 => 5123,
            ComponentType::U32 => 5125,
            ComponentType::F32 => 5126,
        }
    }

    /// Size of one component in bytes.
    pub fn size(self) -> usize {
        match self {
            ComponentType::I8 | ComponentType::U8 => 1,
            ComponentType::I16 | ComponentType::U16 => 2,
            ComponentType::U32 | ComponentType::F32 => 4,
        }
    }
}

/// An accessor: a typed view of elements in a buffer view.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "camelCase")]
pub struct Accessor {
    /// Buffer view; absent means all zeros (or data supplied by an extension).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub buffer_view: Option<u32>,
    /// Offset of the first element inside the buffer view.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub byte_offset: u64,
    /// Component type code (see [`ComponentType`]).
    pub component_type: u32,
    /// Integer components map to `[0, 1]` / `[-1, 1]`.
    #[serde(default, skip_serializing_if = "is_false")]
    pub normalized: bool,
    /// Number of elements.
    pub count: u64,
    /// Element type.
    #[serde(rename = "type")]
    pub kind: AccessorType,
    /// Per-component minimum.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub min: Option<Vec<f64>>,
    /// Per-component maximum.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max: Option<Vec<f64>>,
    /// Sparse storage (kept as JSON; not decoded here).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sparse: Option<Value>,
    /// Name.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
}

/// A buffer view: a byte range of a buffer, optionally strided.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "camelCase")]
pub struct BufferView {
    /// Buffer index.
    pub buffer: u32,
    /// Offset into the buffer.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub byte_offset: u64,
    /// Length in bytes.
    pub byte_length: u64,
    /// Distance between the starts of consecutive elements (vertex data only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub byte_stride: Option<u32>,
    /// GL buffer target hint.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub target: Option<u32>,
    /// Name.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// Extensions (e.g. `EXT_meshopt_compression`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub extensions: Option<Map<String, Value>>,
}

/// A buffer; without `uri` in a glb it is the BIN chunk.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "camelCase")]
pub struct Buffer {
    /// Length in bytes.
    pub byte_length: u64,
    /// External or data URI.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub uri: Option<String>,
    /// Name.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// Extensions (e.g. the `EXT_meshopt_compression` fallback flag).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub extensions: Option<Map<String, Value>>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tolerates_unknown_members_and_keeps_other_extensions() {
        let text = r#"{
            "asset": {"version": "2.0", "somethingNew": 1},
            "meshes": [{"primitives": [{
                "attributes": {"POSITION": 0, "KHR_gaussian_splatting:SCALE": 1},
                "mode": 0,
                "extensions": {
                    "KHR_gaussian_splatting": {"kernel": "ellipse", "colorSpace": "lin_rec709_display", "future": true},
                    "EXT_other": {"a": 1}
                }
            }], "weights": [1]}],
            "accessors": [{"componentType": 5126, "count": 2, "type": "VEC3", "extras": {}}],
            "unknownTopLevel": [1, 2]
        }"#;
        let g: Gltf = serde_json::from_str(text).unwrap();
        let p = &g.meshes[0].primitives[0];
        let ext = p.extensions.as_ref().unwrap();
        let ks = ext.gaussian_splatting.as_ref().unwrap();
        assert_eq!(ks.color_space.as_deref(), Some("lin_rec709_display"));
        assert!(ext.other.contains_key("EXT_other"));
        assert_eq!(g.accessors[0].kind, AccessorType::Vec3);
        assert_eq!(g.accessors[0].buffer_view, None);
    }

    #[test]
    fn omits_defaults_when_writing() {
        let a = Accessor {
            buffer_view: Some(0),
            byte_offset: 0,
            component_type: 5126,
            normalized: false,
            count: 1,
            kind: AccessorType::Scalar,
            min: None,
            max: None,
            sparse: None,
            name: None,
        };
        let s = serde_json::to_string(&a).unwrap();
        assert_eq!(
            s,
            r#"{"bufferView":0,"componentType":5126,"count":1,"type":"SCALAR"}"#
        );
    }
}
