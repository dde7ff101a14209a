//! `tileset.json` of 3D Tiles 1.1 as serde structs (the subset we write, tolerant of the rest
//! when reading), plus the metadata schema our implicit tilesets declare.

use serde::{Deserialize, Serialize};
use serde_json::{Value, json};
use splat2tiles_core::frame::mercator::MercatorKey;

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
    let (variants_class, content_props) = super::variant_schema::schema_properties();
    s["classes"][super::variant_schema::VARIANTS_CLASS] = variants_class;
    // The tileset entity's one class also carries the Web-Mercator root of georeferenced
    // tilesets (optional properties; spec/georeferencing.md).
    if let (Some(props), Some(extra)) = (
        s["classes"][super::variant_schema::VARIANTS_CLASS]["properties"].as_object_mut(),
        mercator_root_properties().as_object(),
    ) {
        props.extend(extra.clone());
    }
    if let (Some(props), Some(extra)) = (
        s["classes"][CONTENT_CLASS]["properties"].as_object_mut(),
        content_props.as_object(),
    ) {
        props.extend(extra.clone());
    }
    s
}

/// Tileset metadata properties naming the Web-Mercator tile of a georeferenced implicit root:
/// implicit tile (level, x, y) is Mercator tile (zoom + level, x0 * 2^level + x,
/// y0 * 2^level + 2^level - 1 - y).
fn mercator_root_properties() -> Value {
    let prop = |what: &str| {
        json!({
            "description": what,
            "type": "SCALAR", "componentType": "UINT32"
        })
    };
    json!({
        MERCATOR_ZOOM: prop("Georeferenced tilesets: Web-Mercator zoom of the implicit root tile (implicit level L is zoom + L)."),
        MERCATOR_X: prop("Georeferenced tilesets: Web-Mercator column of the implicit root (x grows east; implicit x at level L is column - x0 * 2^L)."),
        MERCATOR_Y: prop("Georeferenced tilesets: Web-Mercator row of the implicit root (slippy-map y grows south; implicit y grows north: row = y0 * 2^L + 2^L - 1 - y)."),
    })
}

/// Tileset metadata property: Web-Mercator zoom of the implicit root (georeferenced only).
pub const MERCATOR_ZOOM: &str = "mercatorRootZoom";
/// Tileset metadata property: Web-Mercator column of the implicit root.
pub const MERCATOR_X: &str = "mercatorRootX";
/// Tileset metadata property: Web-Mercator row (slippy-map, y south) of the implicit root.
pub const MERCATOR_Y: &str = "mercatorRootY";

/// Adds the Web-Mercator root key (when there is one) to a tileset metadata entity.
pub fn with_mercator_root(mut entity: Value, root: Option<MercatorKey>) -> Value {
    if let (Some(k), Some(props)) = (
        root,
        entity.get_mut("properties").and_then(Value::as_object_mut),
    ) {
        props.insert(MERCATOR_ZOOM.into(), k.zoom.into());
        props.insert(MERCATOR_X.into(), k.x.into());
        props.insert(MERCATOR_Y.into(), k.y.into());
    }
    entity
}

/// The Web-Mercator root key a tileset's metadata declares, if all three properties are there.
pub fn mercator_root(tileset: &Tileset) -> Option<MercatorKey> {
    let props = tileset.metadata.as_ref()?.get("properties")?;
    let get = |name: &str| {
        props
            .get(name)?
            .as_u64()
            .and_then(|v| u32::try_from(v).ok())
    };
    Some(MercatorKey {
        zoom: get(MERCATOR_ZOOM)?,
        x: get(MERCATOR_X)?,
        y: get(MERCATOR_Y)?,
    })
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
