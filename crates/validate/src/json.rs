//! Parsing of tileset JSON of any reasonable depth and size: nesting and values are counted
//! first (bounded, without recursion), then serde_json parses on a growable stack (`serde_stacker`).

use super::context::Ctx;
use super::issues::Issue;
use serde::Deserialize;
use serde_json::Value;

/// Deepest array/object nesting parsed (an explicit tree of ~500 tile levels).
pub(crate) const MAX_JSON_DEPTH: usize = 1024;

/// Most JSON values parsed in one document: a parsed value costs about 50-100 bytes, whatever
/// its text takes (`[],` is 3 bytes of text), so this caps the parse at a few hundred MiB.
pub(crate) const MAX_JSON_VALUES: u64 = 4_000_000;

/// Whether `bytes` look like a JSON object: the first byte that is not blank is `{`.
pub(crate) fn is_object_text(bytes: &[u8]) -> bool {
    bytes.iter().find(|b| !b.is_ascii_whitespace()) == Some(&b'{')
}

/// The nesting depth and the value count of a JSON text, counted outside strings.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Shape {
    /// Deepest array/object nesting.
    pub depth: usize,
    /// Values: arrays and objects, plus one per `,` and `:` (an upper bound of the scalars).
    pub values: u64,
}

/// The [`Shape`] of `bytes`; stops (returning what it counted so far, above the limit) as soon
/// as the depth passes `depth_limit` or the values pass `value_limit`.
pub(crate) fn shape(bytes: &[u8], depth_limit: usize, value_limit: u64) -> Shape {
    let (mut depth, mut in_str, mut escaped) = (0usize, false, false);
    let mut out = Shape {
        depth: 0,
        values: 1,
    };
    for &b in bytes {
        if in_str {
            match b {
                _ if escaped => escaped = false,
                b'\\' => escaped = true,
                b'"' => in_str = false,
                _ => {}
            }
            continue;
        }
        match b {
            b'"' => in_str = true,
            b'[' | b'{' => {
                depth += 1;
                out.depth = out.depth.max(depth);
                out.values += 1;
            }
            b']' | b'}' => depth = depth.saturating_sub(1),
            b',' | b':' => out.values += 1,
            _ => continue,
        }
        if out.depth > depth_limit || out.values > value_limit {
            return out;
        }
    }
    out
}

/// Parses JSON of at most [`MAX_JSON_DEPTH`] levels and [`MAX_JSON_VALUES`] values; reports
/// JSON_NESTING_TOO_DEEP, JSON_TOO_LARGE or JSON_PARSE_ERROR (at `name`) otherwise.
pub(crate) fn parse(ctx: &mut Ctx<'_>, bytes: &[u8], name: &str) -> Option<Value> {
    let shape = shape(bytes, MAX_JSON_DEPTH, MAX_JSON_VALUES);
    if shape.depth > MAX_JSON_DEPTH {
        ctx.push(Issue::JSON_NESTING_TOO_DEEP(
            name,
            format!("arrays and objects nest deeper than {MAX_JSON_DEPTH} levels; not parsed"),
        ));
        return None;
    }
    if shape.values > MAX_JSON_VALUES {
        ctx.push(Issue::JSON_TOO_LARGE(
            name,
            format!("more than {MAX_JSON_VALUES} JSON values (counted before parsing); not parsed"),
        ));
        return None;
    }
    let mut de = serde_json::Deserializer::from_slice(bytes);
    de.disable_recursion_limit();
    let value = Value::deserialize(serde_stacker::Deserializer::new(&mut de));
    match value.and_then(|v| de.end().map(|()| v)) {
        Ok(v) => Some(v),
        Err(e) => {
            ctx.push(Issue::JSON_PARSE_ERROR(
                format!("{name}@line {} column {}", e.line(), e.column()),
                e.to_string(),
            ));
            None
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn depth_is_counted_outside_strings_and_bounded() {
        assert_eq!(
            shape(br#"{"a":[1,{"b":"[[[\"{"}]}"#, 100, u64::MAX).depth,
            3
        );
        assert_eq!(shape(b"[[[[[[", 3, u64::MAX).depth, 4);
        assert_eq!(shape(b"]]]]", 3, u64::MAX).depth, 0);
    }

    #[test]
    fn values_are_counted_outside_strings_and_bounded() {
        let s = shape(br#"{"a":[1,2,{"b":"x,y:z"}],"c":null}"#, 100, 100);
        // 1 + 3 containers + 3 colons + 3 commas.
        assert_eq!(
            s,
            Shape {
                depth: 3,
                values: 10
            }
        );
        let wide = "[[],".repeat(1000);
        assert!(shape(wide.as_bytes(), 2000, 500).values > 500);
        assert!(shape(wide.as_bytes(), 2000, 500).values < 520);
    }
}
