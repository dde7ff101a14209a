//! One `.subtree` file (3D Tiles 1.1 "Implicit Tiling"): binary/JSON framing, buffers and
//! bufferViews, availability bitstreams, and property-table columns read as numbers.

use super::context::Ctx;
use super::issues::Issue;
use super::metadata::{Schema, numbers};
use splat2tiles_tiles::tiling::subtree::{Availability, SUBTREE_MAGIC, SubtreeJson, bit};

/// Reports the subtree JSON arrays that are present but empty (the schemas say minItems 1).
fn empty_arrays(ctx: &mut Ctx<'_>, json: &[u8], name: &str) {
    let Ok(serde_json::Value::Object(raw)) = serde_json::from_slice(json) else {
        return;
    };
    for key in [
        "buffers",
        "bufferViews",
        "propertyTables",
        "contentAvailability",
        "contentMetadata",
    ] {
        if raw
            .get(key)
            .and_then(serde_json::Value::as_array)
            .is_some_and(Vec::is_empty)
        {
            ctx.push(Issue::ARRAY_LENGTH_MISMATCH(
                format!("{name}#/{key}"),
                format!("{key}, when present, must not be empty"),
            ));
        }
    }
}

/// Parses a `.subtree` file (binary, or JSON with external buffers); framing issues recorded.
pub(crate) fn parse_subtree(
    ctx: &mut Ctx<'_>,
    bytes: &[u8],
    name: &str,
) -> Option<(SubtreeJson, Vec<u8>)> {
    let at = |o: u64| format!("{name}@byte {o}");
    let parse_json = |ctx: &mut Ctx<'_>, json: &[u8], offset: u64| -> Option<SubtreeJson> {
        match serde_json::from_slice::<SubtreeJson>(json) {
            Ok(j) => {
                empty_arrays(ctx, json, name);
                Some(j)
            }
            Err(e) if e.to_string().starts_with("missing field") => {
                ctx.push(Issue::PROPERTY_MISSING(format!("{name}#"), e.to_string()));
                None
            }
            Err(e) => {
                ctx.push(Issue::JSON_PARSE_ERROR(at(offset), e.to_string()));
                None
            }
        }
    };
    if bytes.first() == Some(&b'{') {
        return parse_json(ctx, bytes, 0).map(|j| (j, Vec::new()));
    }
    if bytes.len() < 24 {
        ctx.push(Issue::BINARY_INVALID_LENGTH(
            at(0),
            format!(
                "{} bytes is shorter than the 24-byte subtree header",
                bytes.len()
            ),
        ));
        return None;
    }
    let u32_at = |o: usize| u32::from_le_bytes(bytes[o..o + 4].try_into().expect("4 bytes"));
    let u64_at = |o: usize| u64::from_le_bytes(bytes[o..o + 8].try_into().expect("8 bytes"));
    if u32_at(0) != SUBTREE_MAGIC {
        ctx.push(Issue::BINARY_INVALID(
            at(0),
            format!("magic {:#010x} is not \"subt\" (0x74627573)", u32_at(0)),
        ));
        return None;
    }
    if u32_at(4) != 1 {
        ctx.push(Issue::BINARY_INVALID(
            at(4),
            format!("version {} is not 1", u32_at(4)),
        ));
        return None;
    }
    let (json_len, bin_len) = (u64_at(8), u64_at(16));
    let total = 24u64
        .checked_add(json_len)
        .and_then(|t| t.checked_add(bin_len));
    match total {
        Some(t) if t == bytes.len() as u64 => {}
        Some(t) if t < bytes.len() as u64 => ctx.push(Issue::BINARY_INVALID_LENGTH(
            at(8),
            format!("header declares {t} bytes but the file has {}", bytes.len()),
        )),
        _ => {
            ctx.push(Issue::BINARY_INVALID_LENGTH(
                at(8),
                format!(
                    "jsonByteLength {json_len} + binaryByteLength {bin_len} run past the {}-byte file",
                    bytes.len()
                ),
            ));
            return None;
        }
    }
    // "The JSON chunk MUST be padded with trailing spaces to a multiple of 8 bytes"; the binary
    // chunk likewise with zeros.
    if json_len % 8 != 0 {
        ctx.push(Issue::BINARY_INVALID_ALIGNMENT(
            at(8),
            format!("jsonByteLength {json_len} is not a multiple of 8"),
        ));
    }
    if bin_len % 8 != 0 {
        ctx.push(Issue::BINARY_INVALID_ALIGNMENT(
            at(16),
            format!("binaryByteLength {bin_len} is not a multiple of 8"),
        ));
    }
    let json = &bytes[24..24 + json_len as usize];
    let end = json.iter().rposition(|&b| b == b'}').map_or(0, |p| p + 1);
    if json[end..].iter().any(|&b| b != b' ') {
        ctx.push(Issue::BINARY_INVALID_PADDING(
            at(24 + end as u64),
            "the JSON chunk must be padded with spaces (0x20) only",
        ));
    }
    let j = parse_json(ctx, &json[..end], 24)?;
    let bin = bytes[24 + json_len as usize..24 + (json_len + bin_len) as usize].to_vec();
    Some((j, bin))
}

/// Buffers and bufferViews of one subtree, checked.
pub(crate) struct Views {
    buffers: Vec<Option<Vec<u8>>>,
    /// Per view: buffer, start, end, when valid.
    views: Vec<Option<(usize, usize, usize)>>,
}

impl Views {
    fn get(&self, i: u32) -> Option<&[u8]> {
        let (b, s, e) = (*self.views.get(i as usize)?)?;
        self.buffers.get(b)?.as_ref()?.get(s..e)
    }
}

pub(crate) fn check_views(
    ctx: &mut Ctx<'_>,
    j: &SubtreeJson,
    bin: Vec<u8>,
    name: &str,
    dir_rel: &str,
) -> Views {
    let mut bin = Some(bin);
    let mut buffers = Vec::new();
    for (i, b) in j.buffers.iter().enumerate() {
        let path = format!("{name}#/buffers/{i}");
        match &b.uri {
            None => {
                let data = bin.take();
                match &data {
                    Some(d)
                        if (d.len() as u64) >= b.byte_length
                            && d.len() as u64 - b.byte_length < 8 => {}
                    Some(d) => ctx.push(Issue::BUFFERS_INCONSISTENT(
                        format!("{path}/byteLength"),
                        format!(
                            "byteLength {} does not match the {}-byte binary chunk",
                            b.byte_length,
                            d.len()
                        ),
                    )),
                    None => ctx.push(Issue::BUFFERS_INCONSISTENT(
                        path,
                        "only one buffer may omit uri (the binary chunk)",
                    )),
                }
                buffers.push(data);
            }
            Some(uri) => buffers.push(super::glb_buffers::read_uri_buffer(
                ctx,
                dir_rel,
                uri,
                b.byte_length,
                &path,
            )),
        }
    }
    let mut views = Vec::new();
    for (i, v) in j.buffer_views.iter().enumerate() {
        let path = format!("{name}#/bufferViews/{i}");
        let Some(b) = j.buffers.get(v.buffer as usize) else {
            ctx.push(Issue::BUFFERS_INCONSISTENT(
                format!("{path}/buffer"),
                format!("buffer {} does not exist", v.buffer),
            ));
            views.push(None);
            continue;
        };
        if v.byte_offset % 8 != 0 {
            ctx.push(Issue::BINARY_INVALID_ALIGNMENT(
                format!("{path}/byteOffset"),
                format!("byteOffset {} is not a multiple of 8", v.byte_offset),
            ));
        }
        let end = v.byte_offset.checked_add(v.byte_length);
        if end.is_none_or(|e| e > b.byte_length) {
            ctx.push(Issue::BUFFERS_INCONSISTENT(
                path,
                format!(
                    "bytes {}..+{} run past the {}-byte buffer {}",
                    v.byte_offset, v.byte_length, b.byte_length, v.buffer
                ),
            ));
            views.push(None);
            continue;
        }
        views.push(Some((
            v.buffer as usize,
            v.byte_offset as usize,
            (v.byte_offset + v.byte_length) as usize,
        )));
    }
    Views { buffers, views }
}

/// Expands an availability object to `len` bits, reporting what is wrong with it.
pub(crate) fn availability(
    ctx: &mut Ctx<'_>,
    a: &Availability,
    len: usize,
    views: &Views,
    path: &str,
) -> Option<Vec<bool>> {
    let bits = match (a.bitstream, a.constant) {
        (Some(_), Some(_)) | (None, None) => {
            ctx.push(Issue::AVAILABILITY_INVALID(
                path,
                "an availability must have exactly one of 'bitstream' and 'constant'",
            ));
            return None;
        }
        (None, Some(c)) => {
            if c > 1 {
                ctx.push(Issue::VALUE_NOT_IN_RANGE(
                    format!("{path}/constant"),
                    format!("constant {c} is neither 0 nor 1"),
                ));
                return None;
            }
            vec![c == 1; len]
        }
        (Some(v), None) => {
            let Some(bytes) = views.get(v) else {
                ctx.push(Issue::AVAILABILITY_INVALID(
                    format!("{path}/bitstream"),
                    format!("bufferView {v} is missing or invalid"),
                ));
                return None;
            };
            if bytes.len() != len.div_ceil(8) {
                ctx.push(Issue::AVAILABILITY_INVALID(
                    format!("{path}/bitstream"),
                    format!(
                        "the bitstream has {} bytes; {len} bits need {}",
                        bytes.len(),
                        len.div_ceil(8)
                    ),
                ));
                if bytes.len() < len.div_ceil(8) {
                    return None;
                }
            }
            (0..len).map(|i| bit(bytes, i)).collect()
        }
    };
    let count = bits.iter().filter(|b| **b).count() as u64;
    if let Some(c) = a.available_count
        && c != count
    {
        ctx.push(Issue::SUBTREE_AVAILABILITY_INCONSISTENT(
            format!("{path}/availableCount"),
            format!("availableCount {c} but {count} bits are set"),
        ));
    }
    Some(bits)
}

/// Columns of one property table resolved by semantic: per row, the values.
#[allow(clippy::too_many_arguments)] // one call site; a struct would only rename the arguments
pub(crate) fn table_column(
    ctx: &mut Ctx<'_>,
    j: &SubtreeJson,
    views: &Views,
    schema: &Schema,
    table: u32,
    rows: usize,
    path: &str,
    semantics: &[&str],
) -> Vec<Option<Vec<f64>>> {
    let mut out = vec![None; semantics.len()];
    let Some(t) = j.property_tables.get(table as usize) else {
        ctx.push(Issue::PROPERTY_TABLE_INVALID(
            path,
            format!("property table {table} does not exist"),
        ));
        return out;
    };
    let tp = format!("{path}/propertyTables/{table}");
    if t.count != rows as u64 {
        ctx.push(Issue::PROPERTY_TABLE_COUNT_MISMATCH(
            format!("{tp}/count"),
            format!("count {} but {rows} tiles/contents are available", t.count),
        ));
    }
    let Some(class) = schema.classes.get(&t.class) else {
        ctx.push(Issue::PROPERTY_TABLE_INVALID(
            format!("{tp}/class"),
            format!("class '{}' is not in the tileset schema", t.class),
        ));
        return out;
    };
    for (pname, p) in &t.properties {
        let pp = format!("{tp}/properties/{pname}");
        let Some(prop) = class.get(pname) else {
            ctx.push(Issue::PROPERTY_TABLE_INVALID(
                pp,
                format!("class '{}' has no property '{pname}'", t.class),
            ));
            continue;
        };
        let Some(bytes) = views.get(p.values) else {
            ctx.push(Issue::PROPERTY_TABLE_INVALID(
                format!("{pp}/values"),
                format!("bufferView {} is missing or invalid", p.values),
            ));
            continue;
        };
        let Some(row) = prop.row_bytes() else {
            continue;
        };
        let need = row.saturating_mul(t.count);
        if (bytes.len() as u64) < need {
            ctx.push(Issue::PROPERTY_TABLE_VALUES_INVALID(
                format!("{pp}/values"),
                format!(
                    "{} bytes; {} rows of {row} bytes need {need}",
                    bytes.len(),
                    t.count
                ),
            ));
            continue;
        }
        super::metadata::entity::table_range(ctx, prop, bytes, t.count, &format!("{pp}/values"));
        if let Some(k) = semantics
            .iter()
            .position(|s| prop.semantic.as_deref() == Some(*s))
            && t.count == rows as u64
        {
            let per = (row
                / super::metadata::component_size(prop.component.as_deref().unwrap_or("FLOAT64"))
                    .unwrap_or(8)) as usize;
            out[k] = numbers(
                bytes,
                prop.component.as_deref().unwrap_or("FLOAT64"),
                rows * per,
            );
        }
    }
    out
}
