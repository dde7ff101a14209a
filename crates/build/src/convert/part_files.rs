//! The tile files a part wrote, as its `part.json` lists them (path, size, CRC-32), and the
//! merge's copy of exactly those files, each verified against its record before it is linked.
//!
//! CRC-32 (`crc32fast`, the zlib polynomial) is there to catch a truncated, replaced or edited
//! tile, not an adversary; the size is checked first, so a mismatch is found without reading.

use super::shard::bad;
use super::{ConvertError, io_err};
use serde::{Deserialize, Serialize};
use std::io::Read;
use std::path::{Component, Path, PathBuf};

/// One file of a part folder: its path relative to the folder (`/`-separated), size, CRC-32.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
pub(super) struct FileRec {
    pub(super) path: String,
    pub(super) bytes: u64,
    pub(super) crc32: u32,
}

/// What [`link_listed`] linked or copied.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Linked {
    /// Files.
    pub(super) files: u64,
    /// Their bytes.
    pub(super) bytes: u64,
    /// Bytes copied (where a hard link was not possible).
    pub(super) copied_bytes: u64,
}

/// The size and CRC-32 of `path`, read in 1 MiB blocks.
fn checksum(path: &Path) -> Result<(u64, u32), ConvertError> {
    let mut f = std::fs::File::open(path).map_err(io_err(path, "reading"))?;
    let mut h = crc32fast::Hasher::new();
    let mut buf = vec![0u8; 1 << 20];
    let mut total = 0u64;
    loop {
        let n = f.read(&mut buf).map_err(io_err(path, "reading"))?;
        if n == 0 {
            break;
        }
        h.update(&buf[..n]);
        total += n as u64;
    }
    Ok((total, h.finalize()))
}

/// Every regular file under `dir/sub`, as records relative to `dir`, sorted by path; a link or
/// anything but files and folders is refused.
pub(super) fn list_files(dir: &Path, sub: &str) -> Result<Vec<FileRec>, ConvertError> {
    let mut out = Vec::new();
    let root = dir.join(sub);
    if !root.exists() {
        return Ok(out);
    }
    let mut stack = vec![(root, sub.to_string())];
    while let Some((d, rel)) = stack.pop() {
        for e in std::fs::read_dir(&d).map_err(io_err(&d, "reading folder"))? {
            let e = e.map_err(io_err(&d, "reading folder"))?;
            let name = e.file_name();
            let Some(name) = name.to_str() else {
                return Err(bad(&e.path(), None, "a file name that is not UTF-8"));
            };
            let r = format!("{rel}/{name}");
            let t = e.file_type().map_err(io_err(&e.path(), "reading"))?;
            if t.is_dir() {
                stack.push((e.path(), r));
            } else if t.is_file() {
                let (bytes, crc32) = checksum(&e.path())?;
                out.push(FileRec {
                    path: r,
                    bytes,
                    crc32,
                });
            } else {
                return Err(bad(&e.path(), None, "not a file or folder (a link?)"));
            }
        }
    }
    out.sort_by(|a, b| a.path.cmp(&b.path));
    Ok(out)
}

/// `rel` as a path inside a folder: relative, only plain names (no `..`, no root, no drive).
fn inside(rel: &str) -> Option<PathBuf> {
    let p = Path::new(rel);
    let plain = p.components().all(|c| matches!(c, Component::Normal(_)));
    (plain && !rel.is_empty()).then(|| p.to_path_buf())
}

/// Whether `rel` is a plain relative path (what a part may list).
pub(super) fn is_plain(rel: &str) -> bool {
    inside(rel).is_some()
}

/// Hard-links (or, across file systems, copies) each listed file of `part_dir` into `to`,
/// after checking it is a regular file of the recorded size and CRC-32; nothing else of the
/// part folder is carried over, and a file already in `to` (two parts' tile) is refused.
pub(super) fn link_listed(
    part_dir: &Path,
    part_file: &Path,
    files: &[FileRec],
    to: &Path,
) -> Result<Linked, ConvertError> {
    let mut done = Linked::default();
    for rec in files {
        super::check_interrupt()?;
        let rel = inside(&rec.path).ok_or_else(|| {
            bad(
                part_file,
                None,
                format!(
                    "listed file '{}' is not a plain path inside the part",
                    rec.path
                ),
            )
        })?;
        let (src, dst) = (part_dir.join(&rel), to.join(&rel));
        let meta = std::fs::symlink_metadata(&src).map_err(io_err(&src, "reading"))?;
        if !meta.is_file() {
            return Err(bad(&src, None, "not a regular file (a link?); refused"));
        }
        if meta.len() != rec.bytes {
            return Err(bad(
                &src,
                None,
                format!(
                    "{} bytes where {} lists {}",
                    meta.len(),
                    part_file.display(),
                    rec.bytes
                ),
            ));
        }
        let (_, crc) = checksum(&src)?;
        if crc != rec.crc32 {
            return Err(bad(
                &src,
                None,
                format!(
                    "its CRC-32 is {crc:08x} where {} lists {:08x} (changed since the part was built)",
                    part_file.display(),
                    rec.crc32
                ),
            ));
        }
        if let Some(parent) = dst.parent() {
            std::fs::create_dir_all(parent).map_err(io_err(parent, "creating folder"))?;
        }
        if dst.exists() {
            return Err(bad(&src, None, "a tile of two parts (parts overlap?)"));
        }
        if std::fs::hard_link(&src, &dst).is_err() {
            std::fs::copy(&src, &dst).map_err(io_err(&src, "copying"))?;
            done.copied_bytes += rec.bytes;
        }
        done.files += 1;
        done.bytes += rec.bytes;
    }
    Ok(done)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lists_checks_and_links_only_what_is_listed() {
        let part = tempfile::tempdir().unwrap();
        std::fs::create_dir_all(part.path().join("tiles/1")).unwrap();
        std::fs::write(part.path().join("tiles/1/0.glb"), b"tile one").unwrap();
        std::fs::write(part.path().join("tiles/2.glb"), b"tile two").unwrap();
        let list = list_files(part.path(), "tiles").unwrap();
        let names: Vec<&str> = list.iter().map(|r| r.path.as_str()).collect();
        assert_eq!(names, ["tiles/1/0.glb", "tiles/2.glb"]);
        // An unlisted file is not carried over.
        std::fs::write(part.path().join("tiles/notes.txt"), b"x").unwrap();
        let out = tempfile::tempdir().unwrap();
        let pf = part.path().join("part.json");
        let done = link_listed(part.path(), &pf, &list, out.path()).unwrap();
        assert_eq!(done.files, 2);
        assert!(out.path().join("tiles/1/0.glb").is_file());
        assert!(!out.path().join("tiles/notes.txt").exists());
    }

    #[test]
    fn refuses_a_changed_truncated_missing_or_escaping_file() {
        let part = tempfile::tempdir().unwrap();
        std::fs::create_dir_all(part.path().join("tiles")).unwrap();
        let tile = part.path().join("tiles/0.glb");
        std::fs::write(&tile, b"abcdefgh").unwrap();
        let list = list_files(part.path(), "tiles").unwrap();
        let pf = part.path().join("part.json");
        let attempt = |list: &[FileRec]| {
            let out = tempfile::tempdir().unwrap();
            link_listed(part.path(), &pf, list, out.path())
                .unwrap_err()
                .to_string()
        };
        std::fs::write(&tile, b"abcdefgX").unwrap();
        assert!(attempt(&list).contains("CRC-32"));
        std::fs::write(&tile, b"abc").unwrap();
        assert!(attempt(&list).contains("3 bytes where"));
        std::fs::remove_file(&tile).unwrap();
        assert!(attempt(&list).contains("0.glb"));
        let escaping = [FileRec {
            path: "../x".into(),
            bytes: 0,
            crc32: 0,
        }];
        assert!(attempt(&escaping).contains("not a plain path"));
    }
}
