//! 3D Tiles archives (`MAXAR_content_3tz`): a content that is a zip is opened, its entries held in
//! memory under the archive's path, and the `tileset.json` at its root validated as a tileset.

use crate::context::Ctx;
use crate::issues::Issue;
use std::io::Read;
use std::path::{Path, PathBuf};

/// Most entries one archive may list (a 3tz of a large tileset holds tens of thousands).
const MAX_ENTRIES: usize = 1 << 20;

/// Opens the zip `bytes` (the content `uri`, at `file`) and validates the tileset inside it: its
/// entries are readable at `file/NAME` while it is validated, and dropped afterwards.
pub(crate) fn archive(
    ctx: &mut Ctx<'_>,
    file: &Path,
    bytes: &[u8],
    uri: &str,
    path: &str,
    world: glam::DMat4,
) {
    let Some(entries) = entries(ctx, bytes, uri) else {
        return;
    };
    let inner = file.join("tileset.json");
    let Some(tileset) = entries.get(Path::new("tileset.json")).cloned() else {
        ctx.push(Issue::IO_ERROR(
            uri,
            "a 3tz archive must hold tileset.json at its root; it does not",
        ));
        return;
    };
    let added: Vec<PathBuf> = entries.keys().map(|k| file.join(k)).collect();
    for (name, data) in entries {
        ctx.archive.insert(file.join(name), data);
    }
    ctx.archives.push(file.to_path_buf());
    super::external::external(ctx, &inner, &tileset, uri, path, world);
    ctx.archives.pop();
    for k in added {
        ctx.archive.remove(&k);
    }
}

/// The files of the zip `bytes`, by their path inside it, within the validator's byte limit.
fn entries(
    ctx: &mut Ctx<'_>,
    bytes: &[u8],
    uri: &str,
) -> Option<std::collections::BTreeMap<PathBuf, Vec<u8>>> {
    let mut zip = match zip::ZipArchive::new(std::io::Cursor::new(bytes)) {
        Ok(z) => z,
        Err(e) => {
            ctx.push(Issue::IO_ERROR(
                uri,
                format!("not a readable zip archive: {e}"),
            ));
            return None;
        }
    };
    if zip.len() > MAX_ENTRIES {
        ctx.push(Issue::IO_ERROR(
            uri,
            format!(
                "{} entries: more than the {MAX_ENTRIES} this validator opens",
                zip.len()
            ),
        ));
        return None;
    }
    let mut budget = ctx.opts.max_decompressed_bytes;
    let mut out = std::collections::BTreeMap::new();
    for i in 0..zip.len() {
        let mut entry = match zip.by_index(i) {
            Ok(e) => e,
            Err(e) => {
                ctx.push(Issue::IO_ERROR(
                    format!("{uri}@entry {i}"),
                    format!("cannot open the entry: {e}"),
                ));
                return None;
            }
        };
        if entry.is_dir() {
            continue;
        }
        let name = entry
            .name()
            .map_or_else(|_| format!("entry {i}"), |n| n.into_owned());
        let Some(inside) = entry.enclosed_name() else {
            ctx.push(Issue::URI_OUTSIDE_TILESET(
                format!("{uri}/{name}"),
                "an archive entry whose name is absolute or climbs out of the archive",
            ));
            continue;
        };
        let mut data = Vec::new();
        let read = (&mut entry).take(budget + 1).read_to_end(&mut data);
        match read {
            Ok(n) if n as u64 > budget => {
                ctx.push(Issue::DECOMPRESSION_LIMIT_EXCEEDED(
                    format!("{uri}/{name}"),
                    format!(
                        "the archive's entries expand beyond {} bytes (--max-decompressed-mib)",
                        ctx.opts.max_decompressed_bytes
                    ),
                ));
                return None;
            }
            Ok(n) => budget -= n as u64,
            Err(e) => {
                ctx.push(Issue::IO_ERROR(
                    format!("{uri}/{name}"),
                    format!("cannot read the entry: {e}"),
                ));
                continue;
            }
        }
        out.insert(inside, data);
    }
    Some(out)
}
