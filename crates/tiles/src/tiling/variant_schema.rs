//! Metadata schema of the quality variants (`splatVariants` tileset class, per-content variant
//! sizes and utilities): part of the tileset's schema, so it lives with the tiling, not `variants`.

use serde_json::{Value, json};

/// Name of the tileset-level metadata class describing the variants.
pub const VARIANTS_CLASS: &str = "splatVariants";

/// Schema classes the quality variants add: the tileset-level `splatVariants` class and the
/// per-content properties (merged into the content class by `tiling::tileset::schema`).
pub fn schema_properties() -> (Value, Value) {
    let tileset_class = json!({
        "description": "Quality variants of every tile content (spec/quality-variants.md).",
        "properties": {
            "variantNames": {
                "description": "Variant names, in the order of the per-content variant arrays.",
                "type": "STRING", "array": true, "count": 4, "required": true
            },
            "variantUris": {
                "description": "Content URI template of each variant (implicit tiling variables); empty when not written.",
                "type": "STRING", "array": true, "count": 4, "required": true
            },
            "variantFormats": {
                "description": "Container format of each variant.",
                "type": "STRING", "array": true, "count": 4, "required": true
            },
            "defaultVariant": {
                "description": "Index of the variant that content.uri points at.",
                "type": "SCALAR", "componentType": "UINT8", "required": true
            },
            "utilityMethod": {
                "description": "How variantUtility was measured.",
                "type": "STRING", "required": true
            }
        }
    });
    let content_props = json!({
        "variantBytes": {
            "description": "Byte size of each variant's glb (0: not written), in variantNames order.",
            "type": "SCALAR", "componentType": "UINT32", "array": true, "count": 4
        },
        "variantUtility": {
            "description": "Utility of each variant (TileSplat eq. 3, method in the tileset's utilityMethod; Best = 1); -1: not measured.",
            "type": "SCALAR", "componentType": "FLOAT32", "array": true, "count": 4,
            "noData": [-1.0, -1.0, -1.0, -1.0]
        }
    });
    (tileset_class, content_props)
}
