//! 3D Metadata checks (3D Tiles 1.1 "Metadata", 3D Metadata Specification): the schema's classes
//! and properties, built-in semantics, and reading property-table columns as numbers.

pub(crate) mod entity;

use super::context::Ctx;
use super::issues::Issue;
use serde_json::Value;
use std::collections::{BTreeMap, HashMap};

/// One class property as far as the validator needs it.
#[derive(Debug, Clone, Default)]
pub(crate) struct Prop {
    /// SCALAR, VECn, MATn, STRING, BOOLEAN or ENUM.
    pub kind: String,
    /// Component type of numeric types.
    pub component: Option<String>,
    /// Whether values are arrays.
    pub array: bool,
    /// Fixed array length.
    pub count: Option<u64>,
    /// Built-in semantic, if any.
    pub semantic: Option<String>,
    /// Every entity must give a value.
    pub required: bool,
    /// Integer components are normalized to [0, 1] / [-1, 1].
    pub normalized: bool,
    /// Enum of an ENUM property.
    pub enum_type: Option<String>,
    /// `offset`, `scale`, `min`, `max` and `noData` as declared.
    pub offset: Option<Value>,
    /// See `offset`.
    pub scale: Option<Value>,
    /// See `offset`.
    pub min: Option<Value>,
    /// See `offset`.
    pub max: Option<Value>,
    /// See `offset`.
    pub no_data: Option<Value>,
}

impl Prop {
    /// Bytes per row for fixed-size numeric properties; `None` for strings, booleans, enums,
    /// variable-length arrays.
    pub fn row_bytes(&self) -> Option<u64> {
        let comps = match self.kind.as_str() {
            "SCALAR" => 1,
            "VEC2" => 2,
            "VEC3" => 3,
            "VEC4" => 4,
            "MAT2" => 4,
            "MAT3" => 9,
            "MAT4" => 16,
            _ => return None,
        };
        let size = component_size(self.component.as_deref()?)?;
        let n = if self.array { self.count? } else { 1 };
        Some(size * comps * n)
    }
}

/// Size of a metadata component type in bytes.
pub(crate) fn component_size(c: &str) -> Option<u64> {
    Some(match c {
        "INT8" | "UINT8" => 1,
        "INT16" | "UINT16" => 2,
        "INT32" | "UINT32" | "FLOAT32" => 4,
        "INT64" | "UINT64" | "FLOAT64" => 8,
        _ => return None,
    })
}

/// The classes of a schema.
#[derive(Debug, Clone, Default)]
pub(crate) struct Schema {
    /// Class name -> property name -> property.
    pub classes: HashMap<String, BTreeMap<String, Prop>>,
    /// Enum name -> its value names.
    pub enums: HashMap<String, Vec<String>>,
    /// Whether the tileset has a schema at all (inline or by URI).
    pub present: bool,
    /// Number of entries of the tileset's `groups` (targets of `content.group`).
    pub groups: usize,
}

const TYPES: &[&str] = &[
    "SCALAR", "VEC2", "VEC3", "VEC4", "MAT2", "MAT3", "MAT4", "STRING", "BOOLEAN", "ENUM",
];
const COMPONENTS: &[&str] = &[
    "INT8", "UINT8", "INT16", "UINT16", "INT32", "UINT32", "INT64", "UINT64", "FLOAT32", "FLOAT64",
];

fn is_identifier(s: &str) -> bool {
    let mut c = s.chars();
    matches!(c.next(), Some(f) if f.is_ascii_alphabetic() || f == '_')
        && c.all(|x| x.is_ascii_alphanumeric() || x == '_')
}

/// The semantics of the 3D Metadata Semantic Reference (general, tileset, tile and content),
/// with `TILESET_TILE_COUNT` of the 3DTILES_metadata draft that 1.0 tilesets use.
const KNOWN_SEMANTICS: &[&str] = &[
    "ID",
    "NAME",
    "DESCRIPTION",
    "ATTRIBUTION_IDS",
    "ATTRIBUTION_STRINGS",
    "TILESET_FEATURE_ID_LABELS",
    "TILESET_CRS_GEOCENTRIC",
    "TILESET_CRS_COORDINATE_EPOCH",
    "TILESET_TILE_COUNT",
    "TILE_BOUNDING_BOX",
    "TILE_BOUNDING_REGION",
    "TILE_BOUNDING_SPHERE",
    "TILE_BOUNDING_S2_CELL",
    "TILE_MINIMUM_HEIGHT",
    "TILE_MAXIMUM_HEIGHT",
    "TILE_HORIZON_OCCLUSION_POINT",
    "TILE_GEOMETRIC_ERROR",
    "TILE_REFINE",
    "TILE_TRANSFORM",
    "CONTENT_BOUNDING_BOX",
    "CONTENT_BOUNDING_REGION",
    "CONTENT_BOUNDING_SPHERE",
    "CONTENT_BOUNDING_S2_CELL",
    "CONTENT_MINIMUM_HEIGHT",
    "CONTENT_MAXIMUM_HEIGHT",
    "CONTENT_HORIZON_OCCLUSION_POINT",
    "CONTENT_FEATURE_ID_LABELS",
    "CONTENT_URI",
    "CONTENT_GROUP_ID",
];

/// What a built-in semantic requires: (array count, None = not an array).
fn semantic_shape(semantic: &str) -> Option<Option<u64>> {
    Some(match semantic {
        "TILE_BOUNDING_BOX" | "CONTENT_BOUNDING_BOX" => Some(12),
        "TILE_BOUNDING_REGION" | "CONTENT_BOUNDING_REGION" => Some(6),
        "TILE_BOUNDING_SPHERE" | "CONTENT_BOUNDING_SPHERE" => Some(4),
        "TILE_GEOMETRIC_ERROR"
        | "TILE_MINIMUM_HEIGHT"
        | "TILE_MAXIMUM_HEIGHT"
        | "CONTENT_MINIMUM_HEIGHT"
        | "CONTENT_MAXIMUM_HEIGHT" => None,
        _ => return None,
    })
}

/// Validates a `schema` object; returns what later checks need.
pub(crate) fn validate_schema(ctx: &mut Ctx<'_>, v: &Value, path: &str) -> Schema {
    let mut schema = Schema {
        present: true,
        ..Schema::default()
    };
    let Some(obj) = v.as_object() else {
        ctx.push(Issue::TYPE_MISMATCH(path, "schema must be an object"));
        return schema;
    };
    if let Some(enums) = obj.get("enums") {
        schema.enums = entity::validate_enums(ctx, enums, &format!("{path}/enums"));
    }
    // "id ... MUST match ^[a-zA-Z_][a-zA-Z0-9_]*$".
    match obj.get("id") {
        None => ctx.push(Issue::PROPERTY_MISSING(path, "schema 'id' is required")),
        Some(Value::String(id)) if is_identifier(id) => {}
        Some(Value::String(id)) => ctx.push(Issue::IDENTIFIER_NOT_VALID(
            format!("{path}/id"),
            format!("'{id}' does not match ^[a-zA-Z_][a-zA-Z0-9_]*$"),
        )),
        Some(_) => ctx.push(Issue::TYPE_MISMATCH(
            format!("{path}/id"),
            "id must be a string",
        )),
    }
    let Some(classes) = obj.get("classes") else {
        return schema;
    };
    let Some(classes) = classes.as_object() else {
        ctx.push(Issue::TYPE_MISMATCH(
            format!("{path}/classes"),
            "classes must be an object",
        ));
        return schema;
    };
    for (cname, class) in classes {
        let cp = format!("{path}/classes/{cname}");
        if !is_identifier(cname) {
            ctx.push(Issue::IDENTIFIER_NOT_VALID(
                cp.clone(),
                format!("class name '{cname}' is not an identifier"),
            ));
        }
        let mut props = BTreeMap::new();
        let Some(properties) = class.get("properties") else {
            schema.classes.insert(cname.clone(), props);
            continue;
        };
        let Some(properties) = properties.as_object() else {
            ctx.push(Issue::TYPE_MISMATCH(
                format!("{cp}/properties"),
                "properties must be an object",
            ));
            continue;
        };
        for (pname, p) in properties {
            let pp = format!("{cp}/properties/{pname}");
            if !is_identifier(pname) {
                ctx.push(Issue::IDENTIFIER_NOT_VALID(
                    pp.clone(),
                    format!("property name '{pname}' is not an identifier"),
                ));
            }
            let prop = class_property(ctx, p, &pp, &schema.enums);
            entity::check_definition(ctx, &prop, &pp);
            props.insert(pname.clone(), prop);
        }
        schema.classes.insert(cname.clone(), props);
    }
    schema
}

/// One class property's definition (`type`, `componentType`, `enumType` against the schema's
/// `enums`, `count`, `semantic`), read into a `Prop`.
fn class_property(
    ctx: &mut Ctx<'_>,
    p: &Value,
    pp: &str,
    enums: &HashMap<String, Vec<String>>,
) -> Prop {
    let mut prop = Prop::default();
    match p.get("type").and_then(Value::as_str) {
        Some(t) if TYPES.contains(&t) => prop.kind = t.to_string(),
        Some(t) => ctx.push(Issue::CLASS_PROPERTY_TYPE_ERROR(
            format!("{pp}/type"),
            format!("type '{t}' is not one of {TYPES:?}"),
        )),
        None => ctx.push(Issue::PROPERTY_MISSING(pp, "property 'type' is required")),
    }
    let numeric = matches!(
        prop.kind.as_str(),
        "SCALAR" | "VEC2" | "VEC3" | "VEC4" | "MAT2" | "MAT3" | "MAT4"
    );
    match p.get("componentType").and_then(Value::as_str) {
        _ if prop.kind.is_empty() => {}
        Some(c) if COMPONENTS.contains(&c) && numeric => prop.component = Some(c.into()),
        Some(c) if COMPONENTS.contains(&c) => ctx.push(Issue::CLASS_PROPERTY_TYPE_ERROR(
            format!("{pp}/componentType"),
            format!("componentType '{c}' is not allowed on type {}", prop.kind),
        )),
        Some(c) => ctx.push(Issue::CLASS_PROPERTY_TYPE_ERROR(
            format!("{pp}/componentType"),
            format!("componentType '{c}' is not one of {COMPONENTS:?}"),
        )),
        None if numeric => ctx.push(Issue::CLASS_PROPERTY_TYPE_ERROR(
            pp,
            format!("type {} requires a componentType", prop.kind),
        )),
        None => {}
    }
    match p.get("enumType") {
        None if prop.kind == "ENUM" => ctx.push(Issue::CLASS_PROPERTY_TYPE_ERROR(
            pp,
            "type ENUM requires enumType",
        )),
        Some(Value::String(e)) if prop.kind == "ENUM" => {
            if !enums.contains_key(e) {
                ctx.push(Issue::CLASS_PROPERTY_TYPE_ERROR(
                    format!("{pp}/enumType"),
                    format!("enum '{e}' is not defined in the schema's enums"),
                ));
            }
            prop.enum_type = Some(e.clone());
        }
        Some(_) if prop.kind == "ENUM" => ctx.push(Issue::TYPE_MISMATCH(
            format!("{pp}/enumType"),
            "enumType must be a string",
        )),
        Some(_) => ctx.push(Issue::CLASS_PROPERTY_TYPE_ERROR(
            format!("{pp}/enumType"),
            "enumType is only allowed on type ENUM",
        )),
        None => {}
    }
    prop.required = p.get("required").and_then(Value::as_bool).unwrap_or(false);
    prop.normalized = p
        .get("normalized")
        .and_then(Value::as_bool)
        .unwrap_or(false);
    for (key, slot) in [
        ("offset", &mut prop.offset),
        ("scale", &mut prop.scale),
        ("min", &mut prop.min),
        ("max", &mut prop.max),
        ("noData", &mut prop.no_data),
    ] {
        *slot = p.get(key).cloned();
    }
    prop.array = p.get("array").and_then(Value::as_bool).unwrap_or(false);
    if let Some(c) = p.get("count") {
        match c.as_u64() {
            Some(n) if n >= 2 && prop.array => prop.count = Some(n),
            Some(_) if !prop.array => ctx.push(Issue::CLASS_PROPERTY_TYPE_ERROR(
                format!("{pp}/count"),
                "count is only allowed when array is true",
            )),
            _ => ctx.push(Issue::CLASS_PROPERTY_TYPE_ERROR(
                format!("{pp}/count"),
                "count must be an integer >= 2",
            )),
        }
    }
    if let Some(s) = p.get("semantic").and_then(Value::as_str) {
        prop.semantic = Some(s.to_string());
        if !KNOWN_SEMANTICS.contains(&s) {
            ctx.push(Issue::METADATA_SEMANTIC_UNKNOWN(
                format!("{pp}/semantic"),
                format!(
                    "'{s}' is not a semantic of the 3D Metadata Semantic Reference: clients give it no meaning"
                ),
            ));
        }
        if let Some(shape) = semantic_shape(s) {
            let float = matches!(prop.component.as_deref(), Some("FLOAT32" | "FLOAT64"));
            let ok = prop.kind == "SCALAR"
                && float
                && match shape {
                    Some(n) => prop.array && prop.count == Some(n),
                    None => !prop.array,
                };
            if !ok {
                let want = match shape {
                    Some(n) => format!("a SCALAR FLOAT32/FLOAT64 array of count {n}"),
                    None => "a single SCALAR FLOAT32/FLOAT64".to_string(),
                };
                ctx.push(Issue::METADATA_SEMANTIC_INVALID(
                    format!("{pp}/semantic"),
                    format!("semantic {s} requires {want}"),
                ));
            }
        }
    }
    prop
}

/// Decodes `n` numbers of a numeric component type from little-endian bytes.
pub(crate) fn numbers(bytes: &[u8], component: &str, n: usize) -> Option<Vec<f64>> {
    let size = component_size(component)? as usize;
    if bytes.len() < n.checked_mul(size)? {
        return None;
    }
    Some(
        bytes
            .chunks_exact(size)
            .take(n)
            .map(|b| match component {
                "INT8" => b[0] as i8 as f64,
                "UINT8" => b[0] as f64,
                "INT16" => i16::from_le_bytes([b[0], b[1]]) as f64,
                "UINT16" => u16::from_le_bytes([b[0], b[1]]) as f64,
                "INT32" => i32::from_le_bytes(b.try_into().expect("4")) as f64,
                "UINT32" => u32::from_le_bytes(b.try_into().expect("4")) as f64,
                "FLOAT32" => f32::from_le_bytes(b.try_into().expect("4")) as f64,
                "INT64" => i64::from_le_bytes(b.try_into().expect("8")) as f64,
                "UINT64" => u64::from_le_bytes(b.try_into().expect("8")) as f64,
                _ => f64::from_le_bytes(b.try_into().expect("8")),
            })
            .collect(),
    )
}
