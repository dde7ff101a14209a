//! Parsing of tileset JSON of any reasonable depth: nesting is counted first (bounded, without
//! recursion), then serde_json parses on a growable stack (`serde_stacker`) with no fixed limit.

use super::context::Ctx;
use super::issues::Issue;
use serde::Deserialize;
use serde_json::Value;

/// Deepest array/object nesting parsed (an explicit tree of ~500 tile levels).
pub(crate) const MAX_JSON_DEPTH: usize = 1024;

/// Deepest nesting of arrays and objects in `bytes`, counted outside strings; stops counting
/// (returns a value above `limit`) as soon as `limit` is passed.
pub(crate) fn nesting_depth(bytes: &[u8], limit: usize) -> usize {
    let (mut depth, mut max, mut in_str, mut escaped) = (0usize, 0usize, false, false);
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
                if depth > max {
                    max = depth;
                    if max > limit {
                        return max;
                    }
                }
            }
            b']' | b'}' => depth = depth.saturating_sub(1),
            _ => {}
        }
    }
    max
}

/// Parses JSON of at most [`MAX_JSON_DEPTH`] levels; reports JSON_NESTING_TOO_DEEP or
/// JSON_PARSE_ERROR (at `name`) otherwise.
pub(crate) fn parse(ctx: &mut Ctx<'_>, bytes: &[u8], name: &str) -> Option<Value> {
    let depth = nesting_depth(bytes, MAX_JSON_DEPTH);
    if depth > MAX_JSON_DEPTH {
        ctx.push(Issue::JSON_NESTING_TOO_DEEP(
            name,
            format!("arrays and objects nest deeper than {MAX_JSON_DEPTH} levels; not parsed"),
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
        assert_eq!(nesting_depth(br#"{"a":[1,{"b":"[[[\"{"}]}"#, 100), 3);
        assert_eq!(nesting_depth(b"[[[[[[", 3), 4);
        assert_eq!(nesting_depth(b"]]]]", 3), 0);
    }
}
