//! Keeps `schema/splat2tiles-metadata.schema.json` (JSON Schema 2020-12) in sync with the schema
//! `tiling::tileset::schema()` emits, and `spec/validation.md` in sync with the issue catalogue.

use serde_json::Value;
use splat2tiles_tiles::tiling::tileset::schema;
use splat2tiles_validate::CATALOGUE;
use std::path::Path;

/// Checks `v` against the subset of JSON Schema keywords the document uses; returns the errors.
fn check(s: &Value, v: &Value, path: &str, errors: &mut Vec<String>) {
    if let Some(c) = s.get("const")
        && c != v
    {
        errors.push(format!("{path}: {v} is not const {c}"));
    }
    if let Some(e) = s.get("enum").and_then(Value::as_array)
        && !e.contains(v)
    {
        errors.push(format!("{path}: {v} not in enum"));
    }
    let type_ok = match s.get("type").and_then(Value::as_str) {
        Some("object") => v.is_object(),
        Some("string") => v.is_string(),
        Some("array") => v.is_array(),
        Some("number") => v.is_number(),
        Some("boolean") => v.is_boolean(),
        Some(other) => panic!("keyword type {other} not supported by this checker"),
        None => true,
    };
    if !type_ok {
        errors.push(format!("{path}: wrong type"));
        return;
    }
    let Some(obj) = v.as_object() else { return };
    for r in s
        .get("required")
        .and_then(Value::as_array)
        .into_iter()
        .flatten()
    {
        if !obj.contains_key(r.as_str().unwrap()) {
            errors.push(format!("{path}: missing {r}"));
        }
    }
    let props = s.get("properties").and_then(Value::as_object);
    for (k, val) in obj {
        match props.and_then(|p| p.get(k)) {
            Some(sub) => check(sub, val, &format!("{path}/{k}"), errors),
            None if s.get("additionalProperties") == Some(&Value::Bool(false)) => {
                errors.push(format!("{path}: unexpected property {k}"))
            }
            None => {}
        }
    }
}

#[test]
fn emitted_metadata_schema_validates_against_the_json_schema() {
    let path =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("schema/splat2tiles-metadata.schema.json");
    let doc: Value = serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    assert_eq!(
        doc["$schema"],
        "https://json-schema.org/draft/2020-12/schema"
    );
    let mut errors = Vec::new();
    check(&doc, &schema(), "", &mut errors);
    assert!(errors.is_empty(), "{errors:#?}");
    // And the checker does reject a drifted schema.
    let mut drifted = schema();
    drifted["classes"]["tile"]["properties"]["boundingBox"]["count"] = 11.into();
    let mut errors = Vec::new();
    check(&doc, &drifted, "", &mut errors);
    assert_eq!(errors.len(), 1, "{errors:?}");
}

#[test]
fn spec_lists_every_issue_code() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("spec/validation.md");
    let text = std::fs::read_to_string(path).unwrap();
    for (code, sev, _) in CATALOGUE {
        let row = text
            .lines()
            .find(|l| l.starts_with(&format!("| `{code}` |")))
            .unwrap_or_else(|| panic!("spec/validation.md has no row for {code}"));
        assert!(
            row.contains(&format!("| {sev} |")),
            "{code}: severity {sev} not in {row}"
        );
    }
}
