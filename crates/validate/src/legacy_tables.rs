//! Feature and batch table properties of b3dm, i3dm and pnts tiles (3D Tiles 1.0 Feature Table
//! and Batch Table): every property known to its format, of the right shape, inside its binary.

use super::context::Ctx;
use super::issues::Issue;
use serde_json::Value;

/// How a feature table property is stored: components per element, bytes per component in the
/// binary body, and whether it is one value for the whole tile (`global`) or one per feature.
#[derive(Clone, Copy)]
struct Def {
    components: usize,
    bytes: usize,
    global: bool,
    boolean: bool,
}

const fn per(components: usize, bytes: usize) -> Def {
    Def {
        components,
        bytes,
        global: false,
        boolean: false,
    }
}

const fn global(components: usize, bytes: usize) -> Def {
    Def {
        components,
        bytes,
        global: true,
        boolean: false,
    }
}

const FLAG: Def = Def {
    components: 1,
    bytes: 1,
    global: true,
    boolean: true,
};

/// The feature table properties each format defines (BATCH_ID's size follows its
/// componentType, checked by the semantics pass).
fn definition(kind: &str, name: &str) -> Option<Def> {
    let common = match name {
        "RTC_CENTER" => Some(global(3, 4)),
        _ => None,
    };
    let specific = match (kind, name) {
        ("b3dm", "BATCH_LENGTH") => Some(global(1, 4)),
        ("i3dm", "INSTANCES_LENGTH") | ("pnts", "POINTS_LENGTH" | "BATCH_LENGTH") => {
            Some(global(1, 4))
        }
        ("i3dm" | "pnts", "QUANTIZED_VOLUME_OFFSET" | "QUANTIZED_VOLUME_SCALE") => {
            Some(global(3, 4))
        }
        ("i3dm", "EAST_NORTH_UP") => Some(FLAG),
        ("i3dm" | "pnts", "POSITION") | ("i3dm", "NORMAL_UP" | "NORMAL_RIGHT") => Some(per(3, 4)),
        ("i3dm" | "pnts", "POSITION_QUANTIZED") => Some(per(3, 2)),
        ("i3dm", "NORMAL_UP_OCT32P" | "NORMAL_RIGHT_OCT32P") => Some(per(2, 2)),
        ("i3dm", "SCALE") => Some(per(1, 4)),
        ("i3dm", "SCALE_NON_UNIFORM") | ("pnts", "NORMAL") => Some(per(3, 4)),
        ("i3dm" | "pnts", "BATCH_ID") => Some(per(1, 2)),
        ("pnts", "CONSTANT_RGBA") => Some(global(4, 1)),
        ("pnts", "RGBA") => Some(per(4, 1)),
        ("pnts", "RGB") => Some(per(3, 1)),
        ("pnts", "RGB565") => Some(per(1, 2)),
        ("pnts", "NORMAL_OCT16P") => Some(per(2, 1)),
        _ => None,
    };
    specific.or(common)
}

/// Checks every member of the feature table `ft` of a `kind` tile with `count` features: a
/// property its format defines, a global stored as a number / array / boolean of its size or in
/// the binary body (`body_len` bytes), per-feature arrays of `count` elements, and the pairs a
/// format requires together.
pub(crate) fn feature_table(
    ctx: &mut Ctx<'_>,
    ft: &Value,
    kind: &str,
    count: u64,
    body_len: usize,
    at: &str,
) {
    let Some(members) = ft.as_object() else {
        return;
    };
    for (name, v) in members {
        if name == "extensions" || name == "extras" {
            continue;
        }
        let Some(def) = definition(kind, name) else {
            ctx.push(Issue::CONTENT_JSON_INVALID(
                at,
                format!("'{name}' is not a {kind} feature table property"),
            ));
            continue;
        };
        if let Some(why) = shape(def, v, count, body_len) {
            ctx.push(Issue::CONTENT_JSON_INVALID(
                at,
                format!("feature table property '{name}' {why}"),
            ));
        }
    }
    let has = |k: &str| members.contains_key(k);
    let mut pairs = vec![
        ("POSITION_QUANTIZED", "QUANTIZED_VOLUME_OFFSET"),
        ("POSITION_QUANTIZED", "QUANTIZED_VOLUME_SCALE"),
    ];
    if kind == "i3dm" {
        pairs.extend([
            ("NORMAL_UP", "NORMAL_RIGHT"),
            ("NORMAL_RIGHT", "NORMAL_UP"),
            ("NORMAL_UP_OCT32P", "NORMAL_RIGHT_OCT32P"),
            ("NORMAL_RIGHT_OCT32P", "NORMAL_UP_OCT32P"),
        ]);
    }
    if kind == "pnts" {
        pairs.push(("BATCH_ID", "BATCH_LENGTH"));
    }
    for (with, needs) in pairs {
        if has(with) && !has(needs) {
            ctx.push(Issue::CONTENT_JSON_INVALID(
                at,
                format!("the {kind} feature table has {with} but not {needs}, which it requires"),
            ));
        }
    }
}

/// Why the value `v` of a property stored as `def` is malformed, if it is.
fn shape(def: Def, v: &Value, count: u64, body_len: usize) -> Option<String> {
    let items = if def.global { 1 } else { count };
    if def.boolean {
        return (!v.is_boolean()).then(|| "must be a boolean".to_string());
    }
    if let Some(offset) = v.get("byteOffset") {
        let Some(offset) = offset.as_u64() else {
            return Some("has a byteOffset that is not a non-negative integer".into());
        };
        // Per-feature binaries are checked with their componentType by the semantics pass.
        let end = items
            .checked_mul((def.components * def.bytes) as u64)
            .and_then(|n| n.checked_add(offset));
        return (def.global && end.is_none_or(|e| e > body_len as u64)).then(|| {
            format!("runs past the {body_len}-byte feature table binary from byteOffset {offset}")
        });
    }
    let want = (def.components as u64).saturating_mul(items);
    if def.global && want == 1 {
        return (!v.is_number()).then(|| "must be a number".to_string());
    }
    match v.as_array() {
        None => Some("must be an array or a binary body reference ({\"byteOffset\": N})".into()),
        Some(a) if a.len() as u64 != want => {
            Some(format!("must hold {want} numbers, not {}", a.len()))
        }
        Some(a) if !a.iter().all(Value::is_number) => Some("must hold numbers only".into()),
        Some(_) => None,
    }
}

/// Components of a batch table binary property's `type`.
fn components(t: &str) -> Option<u64> {
    match t {
        "SCALAR" => Some(1),
        "VEC2" => Some(2),
        "VEC3" => Some(3),
        "VEC4" => Some(4),
        _ => None,
    }
}

/// Bytes of a batch table binary property's `componentType`.
fn component_bytes(c: &str) -> Option<u64> {
    match c {
        "BYTE" | "UNSIGNED_BYTE" => Some(1),
        "SHORT" | "UNSIGNED_SHORT" => Some(2),
        "INT" | "UNSIGNED_INT" | "FLOAT" => Some(4),
        "DOUBLE" => Some(8),
        _ => None,
    }
}

/// Checks every property of the batch table `bt` of a tile with `features` features: a JSON
/// array of one value per feature, or a binary reference with a valid type and componentType,
/// aligned to its component size and inside the `binary_len`-byte batch table binary.
pub(crate) fn batch_table(
    ctx: &mut Ctx<'_>,
    bt: &Value,
    features: u64,
    binary_len: usize,
    at: &str,
) {
    let Some(members) = bt.as_object() else {
        return;
    };
    let draco = bt.pointer("/extensions/3DTILES_draco_point_compression/properties");
    for (name, v) in members {
        if name == "extensions" || name == "extras" || draco.and_then(|d| d.get(name)).is_some() {
            continue;
        }
        if let Some(why) = batch_property(v, features, binary_len) {
            ctx.push(Issue::CONTENT_JSON_INVALID(
                at,
                format!("batch table property '{name}' {why}"),
            ));
        }
    }
}

/// Why the batch table property `v` is malformed, if it is.
fn batch_property(v: &Value, features: u64, binary_len: usize) -> Option<String> {
    let Some(offset) = v.get("byteOffset") else {
        return match v.as_array() {
            None => Some("must be an array or a binary body reference".into()),
            Some(a) if a.len() as u64 != features => {
                Some(format!("has {} values for {features} features", a.len()))
            }
            Some(_) => None,
        };
    };
    let Some(offset) = offset.as_u64() else {
        return Some("has a byteOffset that is not a non-negative integer".into());
    };
    let Some(n) = v.get("type").and_then(Value::as_str).and_then(components) else {
        return Some("needs a type of SCALAR, VEC2, VEC3 or VEC4".into());
    };
    let Some(size) = v
        .get("componentType")
        .and_then(Value::as_str)
        .and_then(component_bytes)
    else {
        return Some("needs a componentType (BYTE ... DOUBLE)".into());
    };
    if !offset.is_multiple_of(size) {
        return Some(format!(
            "starts at byteOffset {offset}, not a multiple of {size}"
        ));
    }
    let end = features
        .checked_mul(n * size)
        .and_then(|b| b.checked_add(offset));
    end.is_none_or(|e| e > binary_len as u64).then(|| {
        format!("runs past the {binary_len}-byte batch table binary from byteOffset {offset}")
    })
}
