//! glb buffers and bufferViews: each buffer's bytes (the BIN chunk or an external file, byte
//! lengths checked) and whether each bufferView lies inside its buffer with a valid stride.

use super::context::Ctx;
use super::issues::Issue;
use splat2tiles_tiles::encode::gltf::Gltf;

/// What the buffer checks found: the bytes behind each buffer and the bufferViews that are usable.
pub(super) struct Buffers {
    /// Bytes of each buffer; `None` where unreadable or a meshopt fallback buffer (no data).
    pub data: Vec<Option<Vec<u8>>>,
    /// Per bufferView: inside its buffer, with a valid byteStride.
    pub views_ok: Vec<bool>,
}

/// Checks the buffers and bufferViews of the glb `name` (BIN chunk `bin`; `fallback_buffers[i]`:
/// buffer `i` is a meshopt fallback) and reads the buffers' bytes.
pub(super) fn check_buffers(
    ctx: &mut Ctx<'_>,
    doc: &Gltf,
    bin: Option<&[u8]>,
    fallback_buffers: &[bool],
    name: &str,
) -> Buffers {
    let at = |p: &str| format!("{name}#{p}");
    // Buffers: buffer 0 without uri is the BIN chunk.
    let mut buffers: Vec<Option<Vec<u8>>> = Vec::with_capacity(doc.buffers.len().min(1024));
    for (i, b) in doc.buffers.iter().enumerate() {
        let path = at(&format!("/buffers/{i}"));
        if fallback_buffers[i] && b.uri.is_none() {
            buffers.push(None);
            continue;
        }
        let data = match (&b.uri, i, bin) {
            (None, 0, Some(bin)) => {
                if b.byte_length > bin.len() as u64 || bin.len() as u64 - b.byte_length > 3 {
                    ctx.push(Issue::BUFFERS_INCONSISTENT(
                        format!("{path}/byteLength"),
                        format!(
                            "byteLength {} does not match the {}-byte BIN chunk (up to 3 bytes of padding)",
                            b.byte_length,
                            bin.len()
                        ),
                    ));
                }
                Some(bin[..(b.byte_length.min(bin.len() as u64) as usize)].to_vec())
            }
            (None, _, _) => {
                ctx.push(Issue::BUFFERS_INCONSISTENT(
                    path,
                    "a buffer without uri must be buffer 0 and the glb must have a BIN chunk",
                ));
                None
            }
            (Some(uri), _, _) => {
                read_uri_buffer(ctx, &super::uri::folder_of(name), uri, b.byte_length, &path)
            }
        };
        buffers.push(data);
    }

    // Buffer views inside their buffers.
    let mut views_ok = vec![false; doc.buffer_views.len()];
    for (i, v) in doc.buffer_views.iter().enumerate() {
        let path = at(&format!("/bufferViews/{i}"));
        let Some(b) = doc.buffers.get(v.buffer as usize) else {
            ctx.push(Issue::GLTF_REFERENCE_INVALID(
                format!("{path}/buffer"),
                format!("buffer {} does not exist", v.buffer),
            ));
            continue;
        };
        let end = v.byte_offset.checked_add(v.byte_length);
        if end.is_none_or(|e| e > b.byte_length) {
            ctx.push(Issue::BUFFERS_INCONSISTENT(
                path.clone(),
                format!(
                    "bytes {}..+{} run past the {}-byte buffer {}",
                    v.byte_offset, v.byte_length, b.byte_length, v.buffer
                ),
            ));
            continue;
        }
        if let Some(s) = v.byte_stride
            && (!(4..=252).contains(&s) || s % 4 != 0)
        {
            ctx.push(Issue::VALUE_NOT_IN_RANGE(
                format!("{path}/byteStride"),
                format!("byteStride {s} must be a multiple of 4 in 4..=252"),
            ));
            continue;
        }
        views_ok[i] = true;
    }
    Buffers {
        data: buffers,
        views_ok,
    }
}

/// Reads the buffer file `uri` (relative to the folder `dir`, itself relative to the root) that
/// the buffer at JSON path `path` names, and reports a `byteLength` larger than the file.
pub(super) fn read_uri_buffer(
    ctx: &mut Ctx<'_>,
    dir: &str,
    uri: &str,
    byte_length: u64,
    path: &str,
) -> Option<Vec<u8>> {
    if uri.len() >= 5 && uri[..5].eq_ignore_ascii_case("data:") {
        return data_uri(ctx, uri, byte_length, path);
    }
    let rel = super::uri::in_folder(dir, uri);
    let data = ctx
        .resolve(&rel, &format!("{path}/uri"))
        .and_then(|f| ctx.read(&f, &rel));
    if let Some(d) = &data
        && (d.len() as u64) < byte_length
    {
        ctx.push(Issue::BUFFERS_INCONSISTENT(
            format!("{path}/byteLength"),
            format!(
                "byteLength {byte_length} exceeds the {} bytes of '{uri}'",
                d.len()
            ),
        ));
    }
    data
}

/// The bytes of a buffer embedded as a base64 data URI (`data:MEDIATYPE;base64,DATA`, the form
/// glTF 2.0 sec. 3.6.1.1 allows), checked against `byteLength` as a file would be.
fn data_uri(ctx: &mut Ctx<'_>, uri: &str, byte_length: u64, path: &str) -> Option<Vec<u8>> {
    use base64::Engine;
    let at = format!("{path}/uri");
    let Some((head, payload)) = uri.split_once(',') else {
        ctx.push(Issue::URI_INVALID(
            at,
            "a data URI without ',' before its data",
        ));
        return None;
    };
    if !head.to_ascii_lowercase().ends_with(";base64") {
        ctx.push(Issue::URI_INVALID(
            at,
            "a glTF buffer data URI must be base64-encoded (';base64,')",
        ));
        return None;
    }
    let data = match base64::engine::general_purpose::STANDARD.decode(payload) {
        Ok(d) => d,
        Err(e) => {
            ctx.push(Issue::URI_INVALID(
                at,
                format!("the base64 data does not decode: {e}"),
            ));
            return None;
        }
    };
    if (data.len() as u64) < byte_length {
        ctx.push(Issue::BUFFERS_INCONSISTENT(
            format!("{path}/byteLength"),
            format!(
                "byteLength {byte_length} exceeds the {} bytes of the data URI",
                data.len()
            ),
        ));
    }
    Some(data)
}
