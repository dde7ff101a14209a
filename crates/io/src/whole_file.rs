//! Files written whole or not at all: a temporary file beside the destination, synced, then
//! renamed over it; through a symbolic link the link's target is the destination.

use std::io::{Error, ErrorKind, Write};
use std::path::{Path, PathBuf};

/// Where a file written to `path` lands: an existing regular file (through any symbolic link)
/// resolved, a new name inside its resolved folder. An existing destination that is not a
/// regular file (a device, a FIFO, a folder) is refused.
pub fn destination(path: &Path) -> std::io::Result<PathBuf> {
    match std::fs::metadata(path) {
        Ok(m) if m.is_file() => std::fs::canonicalize(path),
        Ok(_) => Err(Error::new(
            ErrorKind::InvalidInput,
            "not a regular file (a file is written only to a new or regular file)",
        )),
        Err(e) if e.kind() == ErrorKind::NotFound => {
            let name = path
                .file_name()
                .ok_or_else(|| Error::new(ErrorKind::InvalidInput, "not a file name"))?;
            let parent = match path.parent() {
                Some(p) if !p.as_os_str().is_empty() => p,
                _ => Path::new("."),
            };
            Ok(std::fs::canonicalize(parent)?.join(name))
        }
        Err(e) => Err(e),
    }
}

/// Writes `bytes` to `target`, a path [`destination`] returned: to a temporary file beside it
/// (created new), synced, then renamed over it; the temporary file is removed on failure.
pub fn write_at(target: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let name = target
        .file_name()
        .ok_or_else(|| Error::new(ErrorKind::InvalidInput, "not a file name"))?;
    let tmp = target.with_file_name(format!(
        ".{}.{}.tmp",
        name.to_string_lossy(),
        std::process::id()
    ));
    let written = (|| {
        let mut f = std::fs::File::create_new(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        std::fs::rename(&tmp, target)
    })();
    if written.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    written
}

/// Writes `bytes` to `path` whole or not at all ([`destination`], then [`write_at`]).
pub fn write_whole(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    write_at(&destination(path)?, bytes)
}
