//! The readers' error type: one line `FILE: byte N: what is wrong` (or `FILE: line N: ...` for
//! ascii PLY, or `FILE: ...` when no offset applies), with a matchable kind behind it.

use std::fmt;

/// Where in the input an error was found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Location {
    /// No useful position (whole-file problems, decompressor failures).
    None,
    /// A byte offset (in the file, or in the decompressed stream where the message says so).
    Byte(u64),
    /// A 1-based line number (ascii PLY).
    Line(u64),
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Location::None => Ok(()),
            Location::Byte(b) => write!(f, "byte {b}: "),
            Location::Line(l) => write!(f, "line {l}: "),
        }
    }
}

/// What went wrong; match on it in tests and callers (the message text is for people).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ReadErrorKind {
    /// The file could not be read.
    #[error("{0}")]
    Io(#[source] std::io::Error),
    /// The file holds no bytes at all.
    #[error("empty file")]
    Empty,
    /// Neither the magic bytes nor the extension name a format we read.
    #[error("unknown format ({0})")]
    UnknownFormat(String),
    /// A malformed header line, field or value.
    #[error("{0}")]
    BadHeader(String),
    /// Required PLY properties are absent.
    #[error("missing required propert{} {}", if .0.len() == 1 { "y" } else { "ies" }, .0.join(", "))]
    MissingProperty(Vec<String>),
    /// The number of `f_rest_*` properties matches no SH degree.
    #[error("{0} f_rest_* properties match no SH degree (expected 0, 9, 24 or 45 for degree 0-3)")]
    BadShCount(usize),
    /// The body is shorter than the header (or the record size) implies.
    #[error("{what}: expected {expected} {unit}, found {actual}")]
    Truncated {
        /// What was being read.
        what: String,
        /// `bytes` or `lines`.
        unit: &'static str,
        /// Bytes the header implies.
        expected: u64,
        /// Bytes actually there.
        actual: u64,
    },
    /// Bytes are left over after everything the header declares (always an error: a file whose
    /// length disagrees with its header is more likely damaged than padded).
    #[error("{extra} unexpected {unit} after the last {what}")]
    TrailingData {
        /// How many bytes (or, for ascii, lines) are extra.
        extra: u64,
        /// `bytes` or `lines`.
        unit: &'static str,
        /// What came last.
        what: String,
    },
    /// A declared count is beyond what this reader accepts.
    #[error("{what} {count} exceeds the limit of {limit}")]
    TooMany {
        /// What was counted.
        what: String,
        /// The declared count.
        count: u64,
        /// The largest accepted.
        limit: u64,
    },
    /// An ascii PLY record is malformed (wrong number of values, unparseable number).
    #[error("{0}")]
    BadRecord(String),
    /// A gzip or zstd stream is corrupt or larger than the header allows.
    #[error("{0}")]
    Decompress(String),
    /// A valid file using something this reader does not support.
    #[error("unsupported: {0}")]
    Unsupported(String),
    /// Converting the input in memory would exceed the memory limit (`--memory-limit`).
    #[error("{}", over_limit(*.count, *.estimated, *.limit))]
    OverMemoryLimit {
        /// Splats the input declares (or implies), when known.
        count: Option<u64>,
        /// Estimated bytes of converting it in memory.
        estimated: u64,
        /// The limit in bytes.
        limit: u64,
    },
}

/// The message of [`ReadErrorKind::OverMemoryLimit`].
fn over_limit(count: Option<u64>, estimated: u64, limit: u64) -> String {
    use crate::limits::human;
    let what = match count {
        Some(n) => format!("{n} declared splats need an estimated {}", human(estimated)),
        None => format!("the input is larger than {}", human(estimated)),
    };
    format!(
        "{what} in memory, more than the memory limit of {} (raise it with --memory-limit SIZE \
         if the machine has the memory)",
        human(limit)
    )
}

/// A reader failure naming the file and, where it applies, the byte offset or line.
#[derive(Debug)]
#[non_exhaustive]
pub struct ReadError {
    /// The name the caller gave the input (a path or a label).
    pub file: String,
    /// Where the problem is.
    pub location: Location,
    /// What the problem is.
    pub kind: ReadErrorKind,
}

impl ReadError {
    /// Builds an error.
    pub fn new(file: &str, location: Location, kind: ReadErrorKind) -> Self {
        ReadError {
            file: file.to_string(),
            location,
            kind,
        }
    }

    /// The kind, for matching.
    pub fn kind(&self) -> &ReadErrorKind {
        &self.kind
    }
}

impl fmt::Display for ReadError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}{}", self.file, self.location, self.kind)
    }
}

impl std::error::Error for ReadError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match &self.kind {
            ReadErrorKind::Io(e) => Some(e),
            _ => None,
        }
    }
}

/// Shorthand used by the readers: an error in `file` at `loc`.
pub(crate) struct Ctx<'a> {
    /// The file name errors print.
    pub name: &'a str,
    /// Memory limit in bytes for holding the input and its splats.
    pub limit: u64,
}

impl Ctx<'_> {
    /// An error at a byte offset.
    pub fn at(&self, byte: u64, kind: ReadErrorKind) -> ReadError {
        ReadError::new(self.name, Location::Byte(byte), kind)
    }

    /// An error at an ascii line.
    pub fn line(&self, line: u64, kind: ReadErrorKind) -> ReadError {
        ReadError::new(self.name, Location::Line(line), kind)
    }

    /// An error without a position.
    pub fn whole(&self, kind: ReadErrorKind) -> ReadError {
        ReadError::new(self.name, Location::None, kind)
    }

    /// Refuses (error at `byte`, where the count is declared) when `count` splats of SH
    /// `degree`, with `held` input bytes in memory, would exceed the memory limit.
    pub fn check_memory(
        &self,
        byte: u64,
        count: u64,
        degree: u8,
        held: u64,
    ) -> Result<(), ReadError> {
        let estimated = crate::limits::in_memory_estimate(count, degree, held);
        if estimated > self.limit {
            return Err(self.at(
                byte,
                ReadErrorKind::OverMemoryLimit {
                    count: Some(count),
                    estimated,
                    limit: self.limit,
                },
            ));
        }
        Ok(())
    }

    /// A `BadHeader` error at a byte offset.
    pub fn header(&self, byte: u64, msg: impl Into<String>) -> ReadError {
        self.at(byte, ReadErrorKind::BadHeader(msg.into()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn display_is_one_line_with_location() {
        let e = ReadError::new(
            "a.ply",
            Location::Byte(12),
            ReadErrorKind::MissingProperty(vec!["x".into(), "opacity".into()]),
        );
        assert_eq!(
            e.to_string(),
            "a.ply: byte 12: missing required properties x, opacity"
        );
        let e = ReadError::new(
            "b.ply",
            Location::Line(3),
            ReadErrorKind::BadRecord("bad".into()),
        );
        assert_eq!(e.to_string(), "b.ply: line 3: bad");
        let e = ReadError::new("c", Location::None, ReadErrorKind::Empty);
        assert_eq!(e.to_string(), "c: empty file");
    }
}
