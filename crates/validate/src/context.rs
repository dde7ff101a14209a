//! The validation context: options, the tileset folder, the issues found so far, and reading of
//! files named by URIs (inside the folder only; gzip/zstd decompressed under size limits).

use super::issues::Issue;
use super::uri::{Resolved, resolve_uri};
use super::volume::Volume;
use glam::{DMat3, DMat4, DVec3};
use std::io::Read;
use std::path::{Path, PathBuf};

/// What `validate` checks and how far it trusts its input.
#[derive(Debug, Clone, PartialEq)]
pub struct ValidateOptions {
    /// Remote URIs become a WARNING (never fetched) instead of an ERROR.
    pub allow_remote: bool,
    /// Also check that each splat's 3-sigma ellipsoid stays inside its tile (WARNING).
    pub check_extent: bool,
    /// Largest decompressed size of one gzip/zstd file, in bytes.
    pub max_decompressed_bytes: u64,
    /// Largest decompressed/compressed ratio of one file (beyond 1 MiB of output).
    pub max_decompression_ratio: u64,
    /// Allowed `| |q| - 1 |` of float ROTATION quaternions.
    pub rotation_tolerance: f64,
    /// Folder that URIs may resolve into (a served root); `None`: the tileset's own folder.
    /// Relative `../` URIs are legal in 3D Tiles: widen the root to validate such tilesets.
    pub root: Option<PathBuf>,
    /// Deepest chain of external tilesets followed (tileset -> external -> external ...).
    pub max_external_depth: usize,
}

impl Default for ValidateOptions {
    fn default() -> Self {
        ValidateOptions {
            allow_remote: false,
            check_extent: false,
            max_decompressed_bytes: 1 << 30,
            max_decompression_ratio: 2048,
            rotation_tolerance: 1e-3,
            root: None,
            max_external_depth: 16,
        }
    }
}

/// Shared state of one validation run.
pub(crate) struct Ctx<'a> {
    /// Folder that relative URIs of the tileset being checked resolve against.
    pub dir: PathBuf,
    /// Folder every URI must resolve inside (`--root`, else the top tileset's folder), and its
    /// canonical form (symbolic links resolved) when it exists.
    pub root: PathBuf,
    /// Canonical `root`, used to refuse symbolic links that lead outside it.
    pub root_real: Option<PathBuf>,
    /// Name of the tileset JSON being checked, relative to `root` (prefix of issue paths).
    pub file: String,
    /// Canonical paths of the tileset JSON files being checked, outermost first (cycles).
    pub chain: Vec<PathBuf>,
    /// External tilesets already checked (each is validated once per run).
    pub visited: std::collections::HashSet<PathBuf>,
    /// Extensions found in the external tilesets walked from the tileset being checked (their
    /// own objects and those of the tilesets they refer to): that tileset must declare them too.
    pub found_below: std::collections::BTreeSet<String>,
    /// Per external tileset checked: the extensions found in it and below it (a tileset
    /// referenced again passes them up without being walked again).
    pub found_in: std::collections::HashMap<PathBuf, std::collections::BTreeSet<String>>,
    /// Issues pushed in the whole run, nested external tilesets included (bounded).
    pub pushed: usize,
    /// The tileset being checked is 3D Tiles 1.0 without `3DTILES_content_gltf` declared: a glTF
    /// content is then reported (once).
    pub gltf_undeclared: bool,
    /// Options.
    pub opts: &'a ValidateOptions,
    /// Issues found so far.
    pub issues: Vec<Issue>,
    /// An in-memory file standing in for the disk (single-file validation and fuzzing).
    pub memory: Option<(PathBuf, Vec<u8>)>,
    /// The files of the 3tz archives being validated, at `ARCHIVE/NAME`.
    pub archive: std::collections::HashMap<PathBuf, Vec<u8>>,
    /// The 3tz archives being validated (outermost first): nothing under them is on disk.
    pub archives: Vec<PathBuf>,
    /// Quality-variant URI templates (name, template) declared by the tileset's `splatVariants`
    /// metadata (spec/quality-variants.md): each content tile's variant files are checked too.
    pub variant_templates: Vec<(String, String)>,
    /// A content checked so far lists `SPLAT2TILES_layer` in its `extensionsUsed`: only then does
    /// the layered pass walk the tiles and read their contents again (`layered::validate`).
    pub layered_seen: bool,
    /// The tiles of the tileset document being walked, for the completeness rule
    /// (`cut::check`, run when its walk ends).
    pub cut: Vec<CutTile>,
    /// More tiles than `cut::MAX_TILES` were walked in this document: the rule is skipped.
    pub cut_truncated: bool,
    /// Content files checked so far (resolved paths), with their splat geometry while it fits
    /// in [`MAX_CACHED_CENTRES`]: a content reached again from another tile is checked once,
    /// and only its containment in the new tile's volume is checked again.
    pub contents: std::collections::HashMap<PathBuf, Option<std::rc::Rc<ContentGeom>>>,
    /// Splat centres held in `contents`.
    pub cached_centres: usize,
}

/// Most splat centres [`Ctx::contents`] keeps (their shapes included: about 100 bytes each).
pub(crate) const MAX_CACHED_CENTRES: usize = 1 << 22;

/// Splat geometry of one content, in the tile frame (after the node matrix and y-up -> z-up).
#[derive(Debug, Default)]
pub(crate) struct ContentGeom {
    /// Splat centres.
    pub centres: Vec<DVec3>,
    /// Per splat, the linear part mapping the unit sphere onto its 1-sigma ellipsoid.
    pub shapes: Option<Vec<DMat3>>,
}

/// Most issues one report lists (hostile inputs can produce millions).
pub(crate) const MAX_ISSUES: usize = 10_000;

/// gzip magic.
const GZIP: [u8; 2] = [0x1f, 0x8b];
/// zstd frame magic.
const ZSTD: [u8; 4] = [0x28, 0xb5, 0x2f, 0xfd];

impl<'a> Ctx<'a> {
    /// A context for the tileset in `dir`.
    pub fn new(dir: PathBuf, opts: &'a ValidateOptions) -> Self {
        let dir = super::uri::lexical(&dir);
        let root = opts
            .root
            .as_deref()
            .map_or_else(|| dir.clone(), super::uri::lexical);
        let root_real = std::fs::canonicalize(&root).ok();
        Ctx {
            dir,
            root,
            root_real,
            file: "tileset.json".to_string(),
            chain: Vec::new(),
            visited: std::collections::HashSet::new(),
            found_below: Default::default(),
            found_in: Default::default(),
            pushed: 0,
            gltf_undeclared: false,
            opts,
            issues: Vec::new(),
            memory: None,
            archive: Default::default(),
            archives: Vec::new(),
            variant_templates: Vec::new(),
            layered_seen: false,
            cut: Vec::new(),
            cut_truncated: false,
            contents: Default::default(),
            cached_centres: 0,
        }
    }

    /// Records an issue; beyond [`MAX_ISSUES`] one ISSUES_TRUNCATED note replaces the rest.
    pub fn push(&mut self, issue: Issue) {
        self.pushed += 1;
        match self.pushed {
            n if n <= MAX_ISSUES => self.issues.push(issue),
            n if n == MAX_ISSUES + 1 => self.issues.push(Issue::ISSUES_TRUNCATED(
                "",
                format!("more than {MAX_ISSUES} issues; the rest are not listed"),
            )),
            _ => {}
        }
    }

    /// Issue path of a JSON pointer inside the tileset being checked: `FILE#/pointer`.
    pub fn at(&self, pointer: &str) -> String {
        format!("{}#{pointer}", self.file)
    }

    /// Resolves `uri` (found at `path`) inside the tileset folder, reporting why not.
    pub fn resolve(&mut self, uri: &str, path: &str) -> Option<PathBuf> {
        let lower = uri.to_ascii_lowercase();
        let remote = lower.contains("://") || lower.starts_with("data:");
        if remote {
            if self.opts.allow_remote {
                self.push(Issue::URI_REMOTE_NOT_VALIDATED(
                    path,
                    format!("'{uri}' is remote; it was not fetched"),
                ));
            } else {
                self.push(Issue::URI_REMOTE(
                    path,
                    format!(
                        "'{uri}' is remote; use --allow-remote to accept it (it is never fetched)"
                    ),
                ));
            }
            return None;
        }
        match resolve_uri(&self.root, &self.dir, uri) {
            Resolved::Inside(p) => Some(p),
            Resolved::Outside => {
                self.push(Issue::URI_OUTSIDE_TILESET(
                    path,
                    format!(
                        "'{uri}' is absolute or climbs out of the folder {} (pass --root to validate a wider served root)",
                        self.root.display()
                    ),
                ));
                None
            }
            Resolved::Invalid(why) => {
                self.push(Issue::URI_INVALID(path, format!("'{uri}': {why}")));
                None
            }
        }
    }

    /// Where `uri` leads when it stays inside the root, reporting nothing.
    pub fn lookup(&self, uri: &str) -> Option<PathBuf> {
        match resolve_uri(&self.root, &self.dir, uri) {
            Resolved::Inside(p) => Some(p),
            _ => None,
        }
    }

    /// Reads a file, decompressing gzip/zstd under the limits; `name` is its path in issues.
    pub fn read(&mut self, file: &Path, name: &str) -> Option<Vec<u8>> {
        if let Some((p, bytes)) = &self.memory
            && p == file
        {
            let bytes = bytes.clone();
            return self.decompress(bytes, name);
        }
        if self.in_archive(file) {
            let Some(bytes) = self.archive.get(file).cloned() else {
                self.push(Issue::IO_ERROR(name, "no such entry in the 3tz archive"));
                return None;
            };
            return self.decompress(bytes, name);
        }
        let real = match self.checked(file) {
            Ok(real) => real,
            Err(Refused::Outside(why)) => {
                self.push(Issue::URI_OUTSIDE_TILESET(name, why));
                return None;
            }
            Err(Refused::Io(why)) => {
                self.push(Issue::IO_ERROR(name, why));
                return None;
            }
        };
        match read_bounded(&real, self.opts.max_decompressed_bytes) {
            Ok(bytes) => self.decompress(bytes, name),
            Err(e) => {
                self.push(Issue::IO_ERROR(name, format!("cannot read: {e}")));
                None
            }
        }
    }

    /// The real path of `file` when it may be read: a regular file of bounded size that stays
    /// inside the root once symbolic links are resolved. Nothing of the file is read.
    pub fn checked(&self, file: &Path) -> Result<PathBuf, Refused> {
        let real =
            std::fs::canonicalize(file).map_err(|e| Refused::Io(format!("cannot read: {e}")))?;
        // Fail closed: without a resolvable root nothing is known to be inside it.
        let Some(root) = &self.root_real else {
            return Err(Refused::Io(format!(
                "the folder {} cannot be resolved; not read",
                self.root.display()
            )));
        };
        if !real.starts_with(root) {
            return Err(Refused::Outside(format!(
                "a symbolic link leads out of the folder {}; not read",
                self.root.display()
            )));
        }
        let meta =
            std::fs::metadata(&real).map_err(|e| Refused::Io(format!("cannot read: {e}")))?;
        if !meta.is_file() {
            return Err(Refused::Io(
                "not a regular file (a folder, device or pipe); not read".into(),
            ));
        }
        let limit = self.opts.max_decompressed_bytes;
        if meta.len() > limit {
            return Err(Refused::Io(format!(
                "{} bytes is larger than the limit of {limit} bytes (--max-decompressed-mib); not read",
                meta.len()
            )));
        }
        Ok(real)
    }

    /// Whether `file` exists (in memory or on disk) as a regular file.
    pub fn exists(&self, file: &Path) -> bool {
        self.memory.as_ref().is_some_and(|(p, _)| p == file)
            || self.archive.contains_key(file)
            || (!self.in_archive(file) && file.is_file())
    }

    /// Whether `file` lies inside a 3tz archive being validated (so never on disk).
    pub fn in_archive(&self, file: &Path) -> bool {
        self.archives.iter().any(|a| file.starts_with(a))
    }

    /// Decompresses `bytes` when they start with gzip or zstd magic; other bytes pass through.
    pub fn decompress(&mut self, bytes: Vec<u8>, name: &str) -> Option<Vec<u8>> {
        match decompress_limited(&bytes, self.opts) {
            Ok(Some(out)) => Some(out),
            Ok(None) => Some(bytes),
            Err(DecompressError::Limit(limit)) => {
                self.push(Issue::DECOMPRESSION_LIMIT_EXCEEDED(
                    name,
                    format!(
                        "{} compressed bytes expand beyond {limit} bytes (limit of --max-decompressed / ratio {})",
                        bytes.len(),
                        self.opts.max_decompression_ratio
                    ),
                ));
                None
            }
            Err(DecompressError::Corrupt(e)) => {
                self.push(Issue::IO_ERROR(
                    name,
                    format!("corrupt compressed stream: {e}"),
                ));
                None
            }
        }
    }
}

/// Why a file named by a URI is not read.
#[derive(Debug)]
pub(crate) enum Refused {
    /// It resolves (through a symbolic link) outside the root.
    Outside(String),
    /// It is missing, not a regular file, or too large.
    Io(String),
}

/// Reads at most `limit` bytes of a regular file (a file that grew since its size was checked
/// is refused rather than read without bound).
fn read_bounded(file: &Path, limit: u64) -> std::io::Result<Vec<u8>> {
    let f = std::fs::File::open(file)?;
    let mut out = Vec::new();
    f.take(limit.saturating_add(1)).read_to_end(&mut out)?;
    if out.len() as u64 > limit {
        return Err(std::io::Error::other(format!(
            "larger than the limit of {limit} bytes"
        )));
    }
    Ok(out)
}

/// Why a compressed input was refused.
#[derive(Debug)]
pub(crate) enum DecompressError {
    /// Output would exceed this many bytes.
    Limit(u64),
    /// The stream is malformed.
    Corrupt(std::io::Error),
}

/// Decompresses gzip or zstd input under the limits; `Ok(None)` when the input is not compressed.
pub(crate) fn decompress_limited(
    bytes: &[u8],
    opts: &ValidateOptions,
) -> Result<Option<Vec<u8>>, DecompressError> {
    let by_ratio = (bytes.len() as u64)
        .saturating_mul(opts.max_decompression_ratio)
        .max(1 << 20);
    let limit = by_ratio.min(opts.max_decompressed_bytes);
    let reader: Box<dyn Read + '_> = if bytes.starts_with(&GZIP) {
        Box::new(flate2::read::MultiGzDecoder::new(bytes))
    } else if bytes.starts_with(&ZSTD) {
        Box::new(zstd::stream::read::Decoder::new(bytes).map_err(DecompressError::Corrupt)?)
    } else {
        return Ok(None);
    };
    let mut out = Vec::new();
    reader
        .take(limit + 1)
        .read_to_end(&mut out)
        .map_err(DecompressError::Corrupt)?;
    if out.len() as u64 > limit {
        return Err(DecompressError::Limit(limit));
    }
    Ok(Some(out))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    #[test]
    fn zstd_bomb_is_refused_without_expanding_it() {
        let mut enc = zstd::stream::write::Encoder::new(Vec::new(), 19).unwrap();
        let zeros = vec![0u8; 1 << 20];
        for _ in 0..64 {
            enc.write_all(&zeros).unwrap();
        }
        let bomb = enc.finish().unwrap();
        let opts = ValidateOptions::default();
        assert!(matches!(
            decompress_limited(&bomb, &opts),
            Err(DecompressError::Limit(_))
        ));
        let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
        gz.write_all(b"{\"a\":1}").unwrap();
        let small = gz.finish().unwrap();
        assert_eq!(
            decompress_limited(&small, &opts).unwrap().unwrap(),
            b"{\"a\":1}"
        );
        assert!(decompress_limited(b"plain", &opts).unwrap().is_none());
    }
}

/// One tile of the walk, as the rule needs it.
#[derive(Debug, Clone)]
pub(crate) struct CutTile {
    /// Where the tile is, for the report (JSON pointer or subtree tile key).
    pub path: String,
    /// Index of the parent tile in the walk's list (`None` for the root).
    pub parent: Option<usize>,
    /// The tile has a content (any content: a glb, an external tileset, several contents).
    pub content: bool,
    /// Its bounding volume, when valid.
    pub volume: Option<Volume>,
    /// Its world transform.
    pub world: DMat4,
    /// Its geometric error, when valid.
    pub error: Option<f64>,
    /// The tile and every ancestor refine by REPLACE (under ADD an ancestor's content stays
    /// drawn, so the rule does not judge the subtree).
    pub replace: bool,
}
