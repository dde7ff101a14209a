//! 3D Metadata values in JSON (3D Metadata "JSON Format", 3D Tiles 1.1 "Metadata"): one check for
//! every entity (tileset, tile, group, content), enums, and the value rules of class properties.

use super::{Prop, Schema};
use crate::context::Ctx;
use crate::issues::Issue;
use serde_json::Value;
use std::collections::{HashMap, HashSet};

/// Number of numeric components of one element of `kind`; `None` for non-numeric types.
fn components(kind: &str) -> Option<usize> {
    Some(match kind {
        "SCALAR" => 1,
        "VEC2" => 2,
        "VEC3" => 3,
        "VEC4" | "MAT2" => 4,
        "MAT3" => 9,
        "MAT4" => 16,
        _ => return None,
    })
}

/// Inclusive range of an integer component type; `None` for floats.
fn int_range(component: &str) -> Option<(f64, f64)> {
    Some(match component {
        "INT8" => (-128.0, 127.0),
        "UINT8" => (0.0, 255.0),
        "INT16" => (-32768.0, 32767.0),
        "UINT16" => (0.0, 65535.0),
        "INT32" => (-2_147_483_648.0, 2_147_483_647.0),
        "UINT32" => (0.0, 4_294_967_295.0),
        "INT64" => (-9.223_372_036_854_776e18, 9.223_372_036_854_776e18),
        "UINT64" => (0.0, 1.844_674_407_370_955_2e19),
        _ => return None,
    })
}

/// A normalized integer as a float ("Normalized Values").
fn normalize(x: f64, component: &str) -> f64 {
    match int_range(component) {
        Some((lo, hi)) if lo < 0.0 => (x / hi).max(-1.0),
        Some((_, hi)) => x / hi,
        None => x,
    }
}

/// Every number in `v`, depth first (a scalar, a vector, an array of vectors...).
fn flat(v: &Value, out: &mut Vec<f64>) {
    match v {
        Value::Number(n) => out.push(n.as_f64().unwrap_or(f64::NAN)),
        Value::Array(a) => a.iter().for_each(|e| flat(e, out)),
        _ => {}
    }
}

/// Validates a schema's `enums`; returns each enum's value names.
pub(crate) fn validate_enums(
    ctx: &mut Ctx<'_>,
    v: &Value,
    path: &str,
) -> HashMap<String, Vec<String>> {
    let mut out = HashMap::new();
    let Some(enums) = v.as_object() else {
        ctx.push(Issue::TYPE_MISMATCH(path, "enums must be an object"));
        return out;
    };
    for (name, e) in enums {
        let ep = format!("{path}/{name}");
        let value_type = match e.get("valueType") {
            None => "UINT16",
            Some(Value::String(t)) if int_range(t).is_some() => t.as_str(),
            Some(_) => {
                ctx.push(Issue::VALUE_NOT_IN_LIST(
                    format!("{ep}/valueType"),
                    "valueType must be one of the integer component types",
                ));
                "INT64"
            }
        };
        let (lo, hi) = int_range(value_type).unwrap_or((f64::MIN, f64::MAX));
        let Some(values) = e.get("values").and_then(Value::as_array) else {
            ctx.push(Issue::PROPERTY_MISSING(
                ep,
                "an enum needs an array of values",
            ));
            continue;
        };
        if values.is_empty() {
            ctx.push(Issue::ARRAY_LENGTH_MISMATCH(
                format!("{ep}/values"),
                "an enum needs at least one value",
            ));
        }
        let (mut names, mut seen_names, mut seen_values) = (vec![], HashSet::new(), HashSet::new());
        for (i, ev) in values.iter().enumerate() {
            let vp = format!("{ep}/values/{i}");
            let name = ev.get("name").and_then(Value::as_str);
            let value = ev.get("value").and_then(Value::as_i64);
            let (Some(n), Some(x)) = (name, value) else {
                ctx.push(Issue::TYPE_MISMATCH(
                    vp,
                    "an enum value needs a string name and an integer value",
                ));
                continue;
            };
            if !seen_names.insert(n) || !seen_values.insert(x) {
                ctx.push(Issue::ARRAY_ELEMENT_NOT_UNIQUE(
                    vp.clone(),
                    format!("enum value '{n}' = {x} repeats a name or a value"),
                ));
            }
            if (x as f64) < lo || (x as f64) > hi {
                ctx.push(Issue::VALUE_NOT_IN_RANGE(
                    format!("{vp}/value"),
                    format!("{x} does not fit the enum's valueType {value_type}"),
                ));
            }
            names.push(n.to_string());
        }
        out.insert(name.clone(), names);
    }
    out
}

/// Checks the value-related fields of a class property definition (normalized, offset, scale,
/// min, max: allowed types and shapes).
pub(crate) fn check_definition(ctx: &mut Ctx<'_>, p: &Prop, path: &str) {
    let comp = p.component.as_deref().unwrap_or("");
    let integer = int_range(comp).is_some();
    if p.normalized && !integer {
        ctx.push(Issue::CLASS_PROPERTY_TYPE_ERROR(
            format!("{path}/normalized"),
            "normalized is only allowed on integer component types",
        ));
    }
    let transformable = !integer || p.normalized;
    let fixed = !p.array || p.count.is_some();
    for (key, v) in [
        ("offset", &p.offset),
        ("scale", &p.scale),
        ("min", &p.min),
        ("max", &p.max),
    ] {
        let Some(v) = v else { continue };
        let allowed = components(&p.kind).is_some()
            && fixed
            && (transformable || matches!(key, "min" | "max"));
        if !allowed {
            ctx.push(Issue::CLASS_PROPERTY_TYPE_ERROR(
                format!("{path}/{key}"),
                format!(
                    "{key} is only allowed on numeric types{}",
                    if matches!(key, "offset" | "scale") {
                        " with a float component type or normalized, not variable-length arrays"
                    } else {
                        ", not variable-length arrays"
                    }
                ),
            ));
            continue;
        }
        let mut nums = vec![];
        flat(v, &mut nums);
        let want = components(&p.kind).unwrap_or(1) * p.count.unwrap_or(1) as usize;
        if nums.len() != want || !shape_ok(p, v, true) {
            ctx.push(Issue::CLASS_PROPERTY_TYPE_ERROR(
                format!("{path}/{key}"),
                format!("{key} must have the structure of one value ({want} numbers)"),
            ));
        }
    }
    if let (Some(lo), Some(hi)) = (&p.min, &p.max) {
        let (mut a, mut b) = (vec![], vec![]);
        flat(lo, &mut a);
        flat(hi, &mut b);
        if a.len() == b.len() && a.iter().zip(&b).any(|(x, y)| x > y) {
            ctx.push(Issue::CLASS_PROPERTY_TYPE_ERROR(
                format!("{path}/min"),
                "min is greater than max",
            ));
        }
    }
}

/// Whether `v` has the JSON structure of one value of `p` (numbers only when `numeric_only`).
fn shape_ok(p: &Prop, v: &Value, numeric_only: bool) -> bool {
    let element = |e: &Value| match components(&p.kind) {
        Some(1) => e.is_number(),
        Some(n) => e
            .as_array()
            .is_some_and(|a| a.len() == n && a.iter().all(Value::is_number)),
        None if numeric_only => false,
        None => true,
    };
    if p.array {
        v.as_array()
            .is_some_and(|a| p.count.is_none_or(|c| a.len() as u64 == c) && a.iter().all(element))
    } else {
        element(v)
    }
}

/// Validates one metadata entity (`{"class": ..., "properties": {...}}`) at `path`.
pub(crate) fn entity(ctx: &mut Ctx<'_>, schema: &Schema, v: &Value, path: &str) {
    let Some(obj) = v.as_object() else {
        ctx.push(Issue::TYPE_MISMATCH(path, "metadata must be an object"));
        return;
    };
    let class = match obj.get("class") {
        Some(Value::String(c)) => c,
        Some(_) => {
            ctx.push(Issue::TYPE_MISMATCH(
                format!("{path}/class"),
                "class must be a string",
            ));
            return;
        }
        None => {
            ctx.push(Issue::PROPERTY_MISSING(
                path,
                "metadata 'class' is required",
            ));
            return;
        }
    };
    let Some(props) = schema.classes.get(class) else {
        ctx.push(Issue::METADATA_CLASS_UNKNOWN(
            format!("{path}/class"),
            if schema.present {
                format!("class '{class}' is not defined in the schema")
            } else {
                format!("class '{class}' is used but the tileset has no schema")
            },
        ));
        return;
    };
    let values = match obj.get("properties") {
        None => None,
        Some(Value::Object(m)) => Some(m),
        Some(_) => {
            ctx.push(Issue::TYPE_MISMATCH(
                format!("{path}/properties"),
                "properties must be an object",
            ));
            return;
        }
    };
    for (name, p) in props {
        let given = values.and_then(|m| m.get(name));
        if p.required && given.is_none() {
            ctx.push(Issue::METADATA_VALUE_REQUIRED_BUT_MISSING(
                format!("{path}/properties"),
                format!("required property '{name}' of class '{class}' has no value"),
            ));
        }
    }
    for (name, val) in values.into_iter().flatten() {
        let vp = format!("{path}/properties/{name}");
        match props.get(name) {
            None => ctx.push(Issue::METADATA_PROPERTY_UNKNOWN(
                vp,
                format!("class '{class}' has no property '{name}'"),
            )),
            Some(p) => value(ctx, schema, p, val, &vp),
        }
    }
}

/// Validates one property value against its definition.
fn value(ctx: &mut Ctx<'_>, schema: &Schema, p: &Prop, v: &Value, path: &str) {
    let mismatch = |ctx: &mut Ctx<'_>, why: String| {
        ctx.push(Issue::METADATA_VALUE_TYPE_MISMATCH(path, why));
    };
    let elements: Vec<&Value> = if p.array {
        let Some(a) = v.as_array() else {
            return mismatch(ctx, format!("an array of {} is expected", p.kind));
        };
        if let Some(c) = p.count
            && a.len() as u64 != c
        {
            return mismatch(
                ctx,
                format!(
                    "the array has {} elements, not the class's count {c}",
                    a.len()
                ),
            );
        }
        a.iter().collect()
    } else {
        vec![v]
    };
    let comp = p.component.as_deref().unwrap_or("");
    for (i, e) in elements.iter().enumerate() {
        let at = if p.array {
            format!(" (element {i})")
        } else {
            String::new()
        };
        let ok = match p.kind.as_str() {
            "STRING" => e.is_string(),
            "BOOLEAN" => e.is_boolean(),
            "ENUM" => match (
                e.as_str(),
                p.enum_type.as_ref().and_then(|t| schema.enums.get(t)),
            ) {
                (Some(name), Some(names)) if !names.iter().any(|n| n == name) => {
                    return mismatch(
                        ctx,
                        format!(
                            "'{name}' is not a value of enum '{}'{at}",
                            p.enum_type.as_deref().unwrap_or("")
                        ),
                    );
                }
                (s, _) => s.is_some(),
            },
            kind => {
                let n = components(kind).unwrap_or(1);
                let mut nums = vec![];
                let shaped = if n == 1 {
                    e.is_number()
                } else {
                    e.as_array()
                        .is_some_and(|a| a.len() == n && a.iter().all(Value::is_number))
                };
                flat(e, &mut nums);
                if shaped && let Some((lo, hi)) = int_range(comp) {
                    if let Some(x) = nums
                        .iter()
                        .find(|x| x.fract() != 0.0 || **x < lo || **x > hi)
                    {
                        return mismatch(ctx, format!("{x} is not a {comp} integer{at}"));
                    }
                } else if shaped
                    && comp == "FLOAT32"
                    && let Some(x) = nums.iter().find(|x| x.abs() > f32::MAX as f64)
                {
                    return mismatch(ctx, format!("{x} does not fit FLOAT32{at}"));
                }
                shaped
            }
        };
        if !ok {
            let want = match p.kind.as_str() {
                "STRING" => "a string".to_string(),
                "BOOLEAN" => "a boolean".to_string(),
                "ENUM" => "an enum value name (a string)".to_string(),
                "SCALAR" => "a number".to_string(),
                k => format!("an array of {} numbers ({k})", components(k).unwrap_or(1)),
            };
            return mismatch(ctx, format!("{want} is expected{at}"));
        }
    }
    range(ctx, p, v, path);
}

/// Checks numeric values against `min` / `max`, which bound the values after the transforms
/// (3D Metadata "min": normalization, then offset and scale, which apply to float and normalized
/// components); `noData` values are exempt.
fn range(ctx: &mut Ctx<'_>, p: &Prop, v: &Value, path: &str) {
    if (p.min.is_none() && p.max.is_none()) || components(&p.kind).is_none() {
        return;
    }
    if p.no_data.as_ref() == Some(v) {
        return;
    }
    let comp = p.component.as_deref().unwrap_or("");
    let mut nums = vec![];
    flat(v, &mut nums);
    let list = |o: &Option<Value>| {
        o.as_ref().map(|o| {
            let mut x = vec![];
            flat(o, &mut x);
            x
        })
    };
    if p.normalized || comp.starts_with("FLOAT") {
        let (off, sc) = (list(&p.offset), list(&p.scale));
        for (i, x) in nums.iter_mut().enumerate() {
            let o = off.as_ref().and_then(|o| o.get(i)).copied().unwrap_or(0.0);
            let s = sc.as_ref().and_then(|s| s.get(i)).copied().unwrap_or(1.0);
            let raw = if p.normalized {
                normalize(*x, comp)
            } else {
                *x
            };
            *x = o + s * raw;
        }
    }
    for (bound, below) in [(&p.min, true), (&p.max, false)] {
        let Some(b) = list(bound) else { continue };
        if b.len() != nums.len() {
            continue;
        }
        if let Some((i, (x, l))) = nums
            .iter()
            .zip(&b)
            .enumerate()
            .find(|(_, (x, l))| if below { x < l } else { x > l })
        {
            ctx.push(Issue::METADATA_VALUE_NOT_IN_RANGE(
                path,
                format!(
                    "component {i}: {x} is {} the property's {} {l}",
                    if below { "below" } else { "above" },
                    if below { "min" } else { "max" }
                ),
            ));
            return;
        }
    }
}

/// Checks the rows of a binary property-table column (`rows` values of `p`, little-endian in
/// `bytes`) against the class's `min` / `max` with the same rule as JSON entities ([`range`]);
/// reports the first row out of range (one issue per column, so a broken table stays readable).
pub(crate) fn table_range(ctx: &mut Ctx<'_>, p: &Prop, bytes: &[u8], rows: u64, path: &str) {
    if (p.min.is_none() && p.max.is_none()) || p.row_bytes().is_none() {
        return;
    }
    let comp = p.component.as_deref().unwrap_or("FLOAT64");
    let per = components(&p.kind).unwrap_or(1)
        * if p.array {
            p.count.unwrap_or(1) as usize
        } else {
            1
        };
    let Some(rows) = usize::try_from(rows).ok() else {
        return;
    };
    let Some(nums) = rows
        .checked_mul(per)
        .and_then(|n| super::numbers(bytes, comp, n))
    else {
        return;
    };
    let integer = int_range(comp).is_some();
    let json = |x: f64| -> Value {
        if integer && x.fract() == 0.0 && x.abs() < 9.0e15 {
            Value::from(x as i64)
        } else {
            Value::from(x)
        }
    };
    let before = ctx.issues.len();
    for (r, row) in nums.chunks_exact(per.max(1)).enumerate() {
        let v = if per == 1 && !p.array {
            json(row[0])
        } else {
            Value::Array(row.iter().map(|x| json(*x)).collect())
        };
        range(ctx, p, &v, &format!("{path}/{r}"));
        if ctx.issues.len() > before {
            return;
        }
    }
}
