//! Whole-file reads with a size cap, for every small file the tools read (tileset JSON, subtrees,
//! tile content, plans, parts, samples, traces): regular files only, memory reserved fallibly.
//!
//! A FIFO, a device (`/dev/zero`) or a folder is refused before it is opened, so a read never
//! blocks on a pipe nor runs on forever; the size is checked against the cap before reading and
//! again while reading (a file that grows is cut at the cap and refused), and the buffer is
//! reserved with `try_reserve_exact`, so a claim the memory cannot hold is an error, not an abort.

use std::io::Read;
use std::path::{Path, PathBuf};

/// Why a bounded read failed; every variant names the file.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum BoundedReadError {
    /// The file could not be opened or read.
    #[error("{}: {source}", path.display())]
    Io {
        /// File.
        path: PathBuf,
        /// OS error.
        source: std::io::Error,
    },
    /// Not a regular file (a FIFO, a device, a folder, a socket).
    #[error("{}: not a regular file (only regular files are read)", path.display())]
    NotRegular {
        /// File.
        path: PathBuf,
    },
    /// Larger than the cap for its kind of file.
    #[error("{}: {size} bytes, more than the {limit} a {kind} may have", path.display())]
    TooLarge {
        /// File.
        path: PathBuf,
        /// Its size (or the bytes read when it grew while being read).
        size: u64,
        /// The cap.
        limit: u64,
        /// What kind of file it is (names the cap in the message).
        kind: &'static str,
    },
    /// The buffer could not be reserved.
    #[error("{}: cannot reserve {size} bytes of memory to read it", path.display())]
    OutOfMemory {
        /// File.
        path: PathBuf,
        /// Bytes asked for.
        size: u64,
    },
}

/// A cap for one kind of file: its name in messages and its largest size in bytes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FileKind {
    /// What the file is ("tileset JSON", "subtree file", ...).
    pub name: &'static str,
    /// Largest accepted size in bytes.
    pub limit: u64,
}

impl FileKind {
    /// A kind named `name` capped at `limit` bytes.
    pub const fn new(name: &'static str, limit: u64) -> Self {
        Self { name, limit }
    }
}

/// Reads all of `path`, a regular file of at most `kind.limit` bytes.
pub fn read_file(path: &Path, kind: FileKind) -> Result<Vec<u8>, BoundedReadError> {
    let io = |source| BoundedReadError::Io {
        path: path.to_path_buf(),
        source,
    };
    // Metadata first: opening a FIFO for reading would block until a writer appears.
    let meta = std::fs::metadata(path).map_err(io)?;
    if !meta.is_file() {
        return Err(BoundedReadError::NotRegular {
            path: path.to_path_buf(),
        });
    }
    let file = std::fs::File::open(path).map_err(io)?;
    // The file that was opened, not the name looked at above (it may have been replaced).
    let size = file.metadata().map_err(io)?;
    if !size.is_file() {
        return Err(BoundedReadError::NotRegular {
            path: path.to_path_buf(),
        });
    }
    let too_large = |size| BoundedReadError::TooLarge {
        path: path.to_path_buf(),
        size,
        limit: kind.limit,
        kind: kind.name,
    };
    let size = size.len();
    if size > kind.limit {
        return Err(too_large(size));
    }
    let mut bytes = Vec::new();
    bytes
        .try_reserve_exact(usize::try_from(size).unwrap_or(usize::MAX))
        .map_err(|_| BoundedReadError::OutOfMemory {
            path: path.to_path_buf(),
            size,
        })?;
    file.take(kind.limit.saturating_add(1))
        .read_to_end(&mut bytes)
        .map_err(io)?;
    if bytes.len() as u64 > kind.limit {
        return Err(too_large(bytes.len() as u64));
    }
    Ok(bytes)
}

/// [`read_file`] as UTF-8 text; invalid UTF-8 is an [`BoundedReadError::Io`] of kind
/// `InvalidData` that names the byte offset.
pub fn read_text(path: &Path, kind: FileKind) -> Result<String, BoundedReadError> {
    let bytes = read_file(path, kind)?;
    String::from_utf8(bytes).map_err(|e| {
        let at = e.utf8_error().valid_up_to();
        BoundedReadError::Io {
            path: path.to_path_buf(),
            source: std::io::Error::new(
                std::io::ErrorKind::InvalidData,
                format!("byte {at}: not UTF-8 text"),
            ),
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const SMALL: FileKind = FileKind::new("test file", 8);

    #[test]
    fn reads_a_small_regular_file() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a");
        std::fs::write(&p, b"12345678").unwrap();
        assert_eq!(read_file(&p, SMALL).unwrap(), b"12345678");
        assert_eq!(read_text(&p, SMALL).unwrap(), "12345678");
    }

    #[test]
    fn refuses_a_file_over_the_cap_naming_it() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("big");
        std::fs::write(&p, b"123456789").unwrap();
        let e = read_file(&p, SMALL).unwrap_err();
        assert!(
            matches!(e, BoundedReadError::TooLarge { size: 9, .. }),
            "{e}"
        );
        let msg = e.to_string();
        assert!(msg.contains("big") && msg.contains("test file"), "{msg}");
    }

    #[test]
    fn refuses_folders_devices_and_fifos_without_blocking() {
        let dir = tempfile::tempdir().unwrap();
        let e = read_file(dir.path(), SMALL).unwrap_err();
        assert!(matches!(e, BoundedReadError::NotRegular { .. }), "{e}");
        #[cfg(unix)]
        {
            let e = read_file(Path::new("/dev/zero"), SMALL).unwrap_err();
            assert!(matches!(e, BoundedReadError::NotRegular { .. }), "{e}");
            let fifo = dir.path().join("fifo");
            let made = std::process::Command::new("mkfifo").arg(&fifo).status();
            if made.is_ok_and(|s| s.success()) {
                let e = read_file(&fifo, SMALL).unwrap_err();
                assert!(matches!(e, BoundedReadError::NotRegular { .. }), "{e}");
            }
        }
    }

    #[test]
    fn invalid_utf8_names_the_offset() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("t");
        std::fs::write(&p, b"ab\xffc").unwrap();
        let msg = read_text(&p, SMALL).unwrap_err().to_string();
        assert!(msg.contains("byte 2"), "{msg}");
    }
}
