//! 3D Tiles 1.0 tile formats (b3dm, i3dm, pnts, cmpt): headers, byte lengths, 8-byte alignment,
//! feature table JSON and its required globals, and the embedded glb checked as any glTF.

use super::content::validate_glb;
use super::context::Ctx;
use super::issues::Issue;
use serde_json::Value;

/// Deepest nesting of composite (cmpt) tiles followed.
const MAX_CMPT_DEPTH: usize = 8;

fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

/// Validates one b3dm / i3dm / pnts / cmpt content named `name`.
pub(crate) fn legacy_content(ctx: &mut Ctx<'_>, bytes: &[u8], name: &str) {
    tile(ctx, bytes, name, 0);
}

fn tile(ctx: &mut Ctx<'_>, b: &[u8], name: &str, depth: usize) {
    let magic = &b[..4.min(b.len())];
    let header = match magic {
        b"b3dm" | b"pnts" => 28,
        b"i3dm" => 32,
        b"cmpt" => 16,
        _ => {
            ctx.push(Issue::BINARY_INVALID(
                format!("{name}@byte 0"),
                "not a b3dm, i3dm, pnts or cmpt tile, nor a glb inside a cmpt (bad magic)",
            ));
            return;
        }
    };
    let kind = String::from_utf8_lossy(magic).into_owned();
    if b.len() < header {
        ctx.push(Issue::BINARY_INVALID_LENGTH(
            format!("{name}@byte 0"),
            format!(
                "{} bytes is shorter than the {header}-byte {kind} header",
                b.len()
            ),
        ));
        return;
    }
    let version = u32_at(b, 4);
    if version != 1 {
        ctx.push(Issue::BINARY_INVALID(
            format!("{name}@byte 4"),
            format!("{kind} version {version} is not 1"),
        ));
        return;
    }
    let byte_length = u32_at(b, 8) as usize;
    if byte_length != b.len() {
        ctx.push(Issue::BINARY_INVALID_LENGTH(
            format!("{name}@byte 8"),
            format!(
                "byteLength {byte_length} differs from the {} bytes of the tile",
                b.len()
            ),
        ));
        if byte_length > b.len() {
            return;
        }
    }
    if byte_length < header {
        ctx.push(Issue::BINARY_INVALID_LENGTH(
            format!("{name}@byte 8"),
            format!("byteLength {byte_length} is shorter than the {header}-byte {kind} header"),
        ));
        return;
    }
    let b = &b[..byte_length];
    if kind == "cmpt" {
        composite(ctx, b, name, depth);
        return;
    }
    let lens: Vec<usize> = (0..4).map(|i| u32_at(b, 12 + 4 * i) as usize).collect();
    let body: usize = lens.iter().sum();
    if header + body > byte_length {
        ctx.push(Issue::BINARY_INVALID_LENGTH(
            format!("{name}@byte 12"),
            format!(
                "the feature and batch tables ({body} bytes) run past byteLength {byte_length}"
            ),
        ));
        return;
    }
    let (ft, bt) = tables(ctx, b, header, &lens, name);
    properties(ctx, (&ft, &bt), &kind, &lens, name);
    let global = |ft: &Value, ctx: &mut Ctx<'_>, key: &str| {
        if ft.is_object() && ft.get(key).and_then(Value::as_u64).is_none() {
            ctx.push(Issue::PROPERTY_MISSING(
                format!("{name}@byte {header}"),
                format!("the {kind} feature table needs an integer {key}"),
            ));
        }
    };
    let position = |ft: &Value, ctx: &mut Ctx<'_>| {
        if ft.is_object() && ft.get("POSITION").is_none() && ft.get("POSITION_QUANTIZED").is_none()
        {
            ctx.push(Issue::PROPERTY_MISSING(
                format!("{name}@byte {header}"),
                format!("the {kind} feature table needs POSITION or POSITION_QUANTIZED"),
            ));
        }
    };
    let payload = &b[header + body..];
    match kind.as_str() {
        "b3dm" => {
            global(&ft, ctx, "BATCH_LENGTH");
            glb_payload(ctx, payload, name, header + body);
        }
        "i3dm" => {
            global(&ft, ctx, "INSTANCES_LENGTH");
            position(&ft, ctx);
            semantics(
                ctx,
                &ft,
                I3DM,
                "INSTANCES_LENGTH",
                (header + lens[0], lens[1]),
                name,
            );
            match u32_at(b, 28) {
                1 => glb_payload(ctx, payload, name, header + body),
                0 => glb_by_uri(ctx, payload, name, header + body),
                f => ctx.push(Issue::BINARY_INVALID(
                    format!("{name}@byte 28"),
                    format!("gltfFormat {f} is neither 0 (uri) nor 1 (embedded glb)"),
                )),
            }
        }
        _ => {
            global(&ft, ctx, "POINTS_LENGTH");
            position(&ft, ctx);
            semantics(
                ctx,
                &ft,
                PNTS,
                "POINTS_LENGTH",
                (header + lens[0], lens[1]),
                name,
            );
        }
    }
}

/// The feature and batch tables of a b3dm / i3dm / pnts whose header is `header` bytes and whose
/// table lengths are `lens`: their 8-byte alignment and JSON; returns the feature table JSON and
/// the batch table JSON (`Null` when absent or when it does not parse).
fn tables(
    ctx: &mut Ctx<'_>,
    b: &[u8],
    header: usize,
    lens: &[usize],
    name: &str,
) -> (Value, Value) {
    // Feature table JSON, feature table binary, batch table JSON, batch table binary: the JSON
    // parts are padded so that each part after the first starts on an 8-byte boundary.
    let mut at = header;
    for (i, what) in [
        "feature table JSON",
        "feature table binary",
        "batch table JSON",
        "batch table binary",
    ]
    .iter()
    .enumerate()
    {
        // A binary part must start aligned even when it is empty (as Cesium's validator
        // checks); the batch table JSON only when present.
        let binary = i % 2 == 1;
        if i > 0 && (binary || lens[i] > 0) && !at.is_multiple_of(8) {
            ctx.push(Issue::BINARY_INVALID_ALIGNMENT(
                format!("{name}@byte {at}"),
                format!("the {what} starts at byte {at}, not on an 8-byte boundary"),
            ));
        }
        at += lens[i];
    }
    let bt_at = header + lens[0] + lens[1];
    let bt = match serde_json::from_slice::<Value>(&b[bt_at..bt_at + lens[2]]) {
        _ if lens[2] == 0 => Value::Null,
        Ok(v) => v,
        Err(e) => {
            ctx.push(Issue::JSON_PARSE_ERROR(
                format!("{name}@byte {bt_at}"),
                format!("batch table JSON: {e}"),
            ));
            Value::Null
        }
    };
    let ft_json = &b[header..header + lens[0]];
    if ft_json.is_empty() {
        return (Value::Object(Default::default()), bt);
    }
    let ft = serde_json::from_slice(ft_json).unwrap_or_else(|e| {
        ctx.push(Issue::JSON_PARSE_ERROR(
            format!("{name}@byte {header}"),
            format!("feature table JSON: {e}"),
        ));
        Value::Null
    });
    (ft, bt)
}

/// The feature table's and batch table's properties (`legacy_tables`), counted by the format's
/// length global (a pnts batch table by BATCH_LENGTH when present).
fn properties(
    ctx: &mut Ctx<'_>,
    (ft, bt): (&Value, &Value),
    kind: &str,
    lens: &[usize],
    name: &str,
) {
    let count_key = match kind {
        "b3dm" => "BATCH_LENGTH",
        "i3dm" => "INSTANCES_LENGTH",
        _ => "POINTS_LENGTH",
    };
    let Some(count) = ft.get(count_key).and_then(Value::as_u64) else {
        return;
    };
    super::legacy_tables::feature_table(ctx, ft, kind, count, lens[1], name);
    let features = match kind {
        "pnts" => ft
            .get("BATCH_LENGTH")
            .and_then(Value::as_u64)
            .unwrap_or(count),
        _ => count,
    };
    super::legacy_tables::batch_table(ctx, bt, features, lens[3], name);
}

/// Per-instance / per-point feature table semantics: (name, bytes per element, alignment).
/// BATCH_ID's size comes from its componentType (default UNSIGNED_SHORT).
const I3DM: &[(&str, usize, usize)] = &[
    ("POSITION", 12, 4),
    ("POSITION_QUANTIZED", 6, 2),
    ("NORMAL_UP", 12, 4),
    ("NORMAL_RIGHT", 12, 4),
    ("NORMAL_UP_OCT32P", 4, 2),
    ("NORMAL_RIGHT_OCT32P", 4, 2),
    ("SCALE", 4, 4),
    ("SCALE_NON_UNIFORM", 12, 4),
    ("BATCH_ID", 2, 2),
];
const PNTS: &[(&str, usize, usize)] = &[
    ("POSITION", 12, 4),
    ("POSITION_QUANTIZED", 6, 2),
    ("RGBA", 4, 1),
    ("RGB", 3, 1),
    ("RGB565", 2, 2),
    ("NORMAL", 12, 4),
    ("NORMAL_OCT16P", 2, 1),
    ("BATCH_ID", 2, 2),
];

/// Checks that each binary semantic of the feature table (`{"byteOffset": N}`) lies inside the
/// feature table's binary body (`body` = its start in the file and its length) for `count_key`
/// elements and starts aligned to its component size (3D Tiles 1.0 Feature Table).
fn semantics(
    ctx: &mut Ctx<'_>,
    ft: &Value,
    table: &[(&str, usize, usize)],
    count_key: &str,
    body: (usize, usize),
    name: &str,
) {
    let Some(count) = ft.get(count_key).and_then(Value::as_u64) else {
        return;
    };
    for &(semantic, size, align) in table {
        let Some(offset) = ft.get(semantic).and_then(|p| p.get("byteOffset")) else {
            continue;
        };
        let (size, align) = match ft.pointer(&format!("/{semantic}/componentType")) {
            Some(Value::String(c)) if semantic == "BATCH_ID" => match c.as_str() {
                "UNSIGNED_BYTE" => (1, 1),
                "UNSIGNED_INT" => (4, 4),
                _ => (2, 2),
            },
            _ => (size, align),
        };
        let Some(offset) = offset.as_u64() else {
            ctx.push(Issue::TYPE_MISMATCH(
                format!("{name}@byte {}", body.0),
                format!("{semantic}.byteOffset must be a non-negative integer"),
            ));
            continue;
        };
        let at = format!("{name}@byte {}", (body.0 as u64).saturating_add(offset));
        if !offset.is_multiple_of(align as u64) {
            ctx.push(Issue::BINARY_INVALID_ALIGNMENT(
                at.clone(),
                format!("{semantic} starts at byteOffset {offset}, not a multiple of {align}"),
            ));
        }
        let end = count
            .checked_mul(size as u64)
            .and_then(|n| n.checked_add(offset));
        if end.is_none_or(|e| e > body.1 as u64) {
            ctx.push(Issue::BINARY_INVALID_LENGTH(
                at,
                format!(
                    "{semantic}: {count} x {size} bytes from byteOffset {offset} run past the \
                     {}-byte feature table binary",
                    body.1
                ),
            ));
        }
    }
}

/// Checks the glb embedded at byte `offset` of a b3dm / i3dm as any glTF.
fn glb_payload(ctx: &mut Ctx<'_>, payload: &[u8], name: &str, offset: usize) {
    if payload.is_empty() {
        ctx.push(Issue::BINARY_INVALID_LENGTH(
            format!("{name}@byte {offset}"),
            "no embedded glb after the tables",
        ));
        return;
    }
    if !offset.is_multiple_of(8) {
        ctx.push(Issue::BINARY_INVALID_ALIGNMENT(
            format!("{name}@byte {offset}"),
            format!("the embedded glb starts at byte {offset}, not on an 8-byte boundary"),
        ));
    }
    validate_glb(ctx, unpadded_glb(payload), &format!("{name}@glb"), false);
}

/// Checks the glTF (glb or JSON) an i3dm with `gltfFormat` 0 names: `payload` (at byte `offset`) is its URI,
/// relative to the i3dm, padded with spaces or zeros.
fn glb_by_uri(ctx: &mut Ctx<'_>, payload: &[u8], name: &str, offset: usize) {
    let uri = std::str::from_utf8(payload)
        .map(|u| u.trim_end_matches([' ', '\0']))
        .unwrap_or("");
    if uri.is_empty() {
        ctx.push(Issue::BINARY_INVALID(
            format!("{name}@byte {offset}"),
            "gltfFormat 0 needs a UTF-8 glTF URI after the tables; there is none",
        ));
        return;
    }
    let rel = super::uri::in_folder(&super::uri::folder_of(name), uri);
    let at = format!("{name}@byte {offset}");
    let Some(bytes) = ctx.resolve(&rel, &at).and_then(|f| ctx.read(&f, &rel)) else {
        return;
    };
    if super::json::is_object_text(&bytes) {
        super::content::validate_gltf_json(ctx, &bytes, &rel, false);
    } else {
        validate_glb(ctx, unpadded_glb(&bytes), &rel, false);
    }
}

/// The glb at the start of `payload` without the zero padding (fewer than 8 bytes) that brings
/// its tile's byteLength to a multiple of 8; `payload` itself when its glb header says otherwise.
fn unpadded_glb(payload: &[u8]) -> &[u8] {
    if payload.len() < 12 || &payload[..4] != b"glTF" {
        return payload;
    }
    let len = u32_at(payload, 8) as usize;
    let padding = payload.len().checked_sub(len);
    match padding {
        Some(p) if len >= 12 && p < 8 && payload[len..].iter().all(|&b| b == 0) => &payload[..len],
        _ => payload,
    }
}

/// The inner tiles of a composite tile.
fn composite(ctx: &mut Ctx<'_>, b: &[u8], name: &str, depth: usize) {
    if depth >= MAX_CMPT_DEPTH {
        ctx.push(Issue::BINARY_INVALID(
            format!("{name}@byte 0"),
            format!("composite tiles nest deeper than {MAX_CMPT_DEPTH}; not followed"),
        ));
        return;
    }
    let count = u32_at(b, 12) as usize;
    let mut at = 16;
    for i in 0..count {
        if at + 12 > b.len() {
            ctx.push(Issue::BINARY_INVALID_LENGTH(
                format!("{name}@byte {at}"),
                format!("inner tile {i} of {count} starts past the end"),
            ));
            return;
        }
        let len = u32_at(b, at + 8) as usize;
        if len < 12 || at + len > b.len() {
            ctx.push(Issue::BINARY_INVALID_LENGTH(
                format!("{name}@byte {}", at + 8),
                format!("inner tile {i} byteLength {len} runs past the composite tile"),
            ));
            return;
        }
        if !at.is_multiple_of(8) {
            ctx.push(Issue::BINARY_INVALID_ALIGNMENT(
                format!("{name}@byte {at}"),
                format!("inner tile {i} starts at byte {at}, not on an 8-byte boundary"),
            ));
        }
        let inner = &b[at..at + len];
        let inner_name = format!("{name}@tile {i}");
        if inner.starts_with(b"glTF") {
            // A glb inner tile: its 12-byte header has the layout of the others.
            validate_glb(ctx, unpadded_glb(inner), &inner_name, false);
        } else {
            tile(ctx, inner, &inner_name, depth + 1);
        }
        at += len;
    }
}
