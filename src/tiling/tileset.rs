//! `tileset.json` of 3D Tiles 1.1 as serde structs (the subset we write, tolerant of the rest
//! when reading), plus the metadata schema our implicit tilesets declare.

use serde::{Deserialize, Serialize};
use serde_json::{Value, json};

/// Root object of `tileset.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "camelCase")]
pub struct Tileset {
    /// Asset information.
    pub asset: Asset,
    /// Error (m) when the whole tileset is not rendered.
    pub geometric_error: f64,
    /// The root tile.
    pub root: Tile,
    /// Metadata schema (classes of tile and content metadata).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub schema: Option<Value>,
    /// Tileset-level metadata entity (`class` + `properties`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub metadata: Option<Value>,
    /// Extensions used.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub extensions_used: Vec<String>,
    /// Extensions required.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub extensions_required: Vec<String>,
    /// Extensions.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub extensions: Option<Value>,
    /// Application data.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub extras: Option<Value>,
}

/// `asset`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "camelCase")]
pub struct Asset {
    /// 3D Tiles version, "1.1".
    pub version: String,
    /// Producer.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub generator: Option<String>,
    /// Application version of this tileset.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tileset_version: Option<String>,
}

/// A bounding volume: exactly one of box, region, sphere.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(rename_all = "camelCase")]
pub struct BoundingVolume {
    /// Oriented box: centre, then x, y, z half-axis vectors.
    #[serde(rename = "box", skip_serializing_if = "Option::is_none")]
    pub box_: Option<Vec<f64>>,
    /// West, south, east, north (radians), min and max height (m).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub region: Option<Vec<f64>>,
    /// Centre and radius.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sphere: Option<Vec<f64>>,
}

/// A tile's content.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "camelCase")]
pub struct Content {
    /// URI or, on an implicit root, a template with {level}, {x}, {y}, {z}.
    pub uri: String,
}

/// The `implicitTiling` object.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "camelCase")]
pub struct ImplicitTiling {
    /// "QUADTREE" or "OCTREE".
    pub subdivision_scheme: String,
    /// Levels per subtree file.
    pub subtree_levels: u32,
    /// Levels in the whole tree.
    pub available_levels: u32,
    /// Subtree URI template.
    pub subtrees: Content,
}

/// A tile.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "camelCase")]
pub struct Tile {
    /// Volume enclosing the tile and its descendants.
    pub bounding_volume: BoundingVolume,
    /// Error (m) introduced if this tile is rendered and its children are not.
    pub geometric_error: f64,
    /// "ADD" or "REPLACE".
    #[serde(skip_serializing_if = "Option::is_none")]
    pub refine: Option<String>,
    /// Column-major 4x4 transform to the parent's frame.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub transform: Option<Vec<f64>>,
    /// Content.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub content: Option<Content>,
    /// Implicit tiling, on an implicit root.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub implicit_tiling: Option<ImplicitTiling>,
    /// Explicit children.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub children: Vec<Tile>,
}

/// Name of the tile metadata class.
pub const TILE_CLASS: &str = "tile";
/// Name of the content metadata class.
pub const CONTENT_CLASS: &str = "splatContent";

/// The metadata schema our tilesets declare: tight tile boxes and geometric errors (standard
/// semantics that override the implicit ones), per-content splat counts and quality variants.
pub fn schema() -> Value {
    let mut s = base_schema();
    let (variants_class, content_props) = crate::variants::schema_properties();
    s["classes"][crate::variants::VARIANTS_CLASS] = variants_class;
    if let (Some(props), Some(extra)) = (
        s["classes"][CONTENT_CLASS]["properties"].as_object_mut(),
        content_props.as_object(),
    ) {
        props.extend(extra.clone());
    }
    s
}

fn base_schema() -> Value {
    json!({
        "id": "splat2tiles",
        "classes": {
            TILE_CLASS: {
                "description": "Per-tile values overriding those implicit tiling derives.",
                "properties": {
                    "boundingBox": {
                        "description": "Tight box around the splat centres of the tile and its descendants.",
                        "type": "SCALAR", "componentType": "FLOAT64", "array": true, "count": 12,
                        "semantic": "TILE_BOUNDING_BOX"
                    },
                    "geometricError": {
                        "description": "Error in metres when this tile is rendered instead of its children.",
                        "type": "SCALAR", "componentType": "FLOAT64",
                        "semantic": "TILE_GEOMETRIC_ERROR"
                    }
                }
            },
            CONTENT_CLASS: {
                "description": "Facts about one KHR_gaussian_splatting tile content.",
                "properties": {
                    "splatCount": {
                        "description": "Number of Gaussians in the content.",
                        "type": "SCALAR", "componentType": "UINT32"
                    }
                }
            }
        }
    })
}
