//! Reads an implicit tileset back: `tileset.json`, then every reachable subtree, giving each
//! available tile's key, content path, tight box and geometric error (for tests, render, stream).

use super::subtree::{self, Subtree};
use super::tileset::Tileset;
use super::{Scheme, TileKey};
use glam::DMat4;
use splat2tiles_io::bounded::{BoundedReadError, FileKind, read_file};
use std::collections::HashMap;
use std::path::{Component, Path, PathBuf};

/// One available tile.
#[derive(Debug, Clone, PartialEq)]
pub struct LoadedTile {
    /// Implicit address.
    pub key: TileKey,
    /// Content file (inside the tileset folder), when the tile has content.
    pub content: Option<PathBuf>,
    /// Tight box from `TILE_BOUNDING_BOX` metadata, if present (tileset frame).
    pub bounding_box: Option<[f64; 12]>,
    /// Geometric error (metadata, else the implicit halving rule).
    pub geometric_error: f64,
    /// Splat count from content metadata, if present.
    pub splat_count: Option<u32>,
}

/// An implicit tileset with every available tile listed.
#[derive(Debug, Clone)]
pub struct LoadedTileset {
    /// Folder of `tileset.json`.
    pub dir: PathBuf,
    /// The parsed `tileset.json`.
    pub tileset: Tileset,
    /// Subdivision scheme.
    pub scheme: Scheme,
    /// Root transform (identity when absent).
    pub root_transform: DMat4,
    /// Available tiles, in subtree order.
    pub tiles: Vec<LoadedTile>,
}

impl LoadedTileset {
    /// Index in [`Self::tiles`] of the root tile, if it is available.
    pub fn root_index(&self) -> Option<usize> {
        self.tiles.iter().position(|t| t.key == TileKey::ROOT)
    }

    /// Indices in [`Self::tiles`] of each tile's available children, by parent key.
    pub fn children(&self) -> std::collections::HashMap<TileKey, Vec<usize>> {
        let mut children: std::collections::HashMap<TileKey, Vec<usize>> = Default::default();
        for (i, t) in self.tiles.iter().enumerate() {
            if let Some(p) = t.key.parent() {
                children.entry(p).or_default().push(i);
            }
        }
        children
    }
}

/// Why a tileset could not be loaded.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum LoadError {
    /// A file could not be read: missing, not a regular file, or over its size cap.
    #[error(transparent)]
    Read(#[from] BoundedReadError),
    /// The walk passed one of its bounds: more tiles than [`MAX_LOADED_TILES`], or one subtree
    /// or content file reached from two tiles (a template that does not name each apart).
    #[error("{path}: {msg}")]
    Bound {
        /// File (`tileset.json`, or the file reached twice).
        path: PathBuf,
        /// Which bound.
        msg: String,
    },
    /// JSON did not parse.
    #[error("{path}: {msg}")]
    Json {
        /// File.
        path: PathBuf,
        /// Parser message.
        msg: String,
    },
    /// The tileset is not an implicit tileset we can walk.
    #[error("{path}: {msg}")]
    Unsupported {
        /// File.
        path: PathBuf,
        /// Why.
        msg: String,
    },
    /// A subtree file is malformed.
    #[error("{path}: {source}")]
    Subtree {
        /// File.
        path: PathBuf,
        /// Framing error.
        source: subtree::SubtreeError,
    },
}

/// Substitutes `{level}`, `{x}`, `{y}`, `{z}` in a template URI.
pub fn expand_template(template: &str, k: TileKey) -> String {
    template
        .replace("{level}", &k.level.to_string())
        .replace("{x}", &k.x.to_string())
        .replace("{y}", &k.y.to_string())
        .replace("{z}", &k.z.to_string())
}

/// Resolves a relative URI inside `dir`; `None` when it is absolute, remote or climbs out.
pub fn resolve_inside(dir: &Path, uri: &str) -> Option<PathBuf> {
    if uri.contains("://") || uri.starts_with('/') || uri.starts_with('\\') || uri.contains(':') {
        return None;
    }
    let rel = Path::new(uri);
    let mut depth: i64 = 0;
    for c in rel.components() {
        match c {
            Component::Normal(_) => depth += 1,
            Component::CurDir => {}
            Component::ParentDir => {
                depth -= 1;
                if depth < 0 {
                    return None;
                }
            }
            _ => return None,
        }
    }
    Some(dir.join(rel))
}

/// The size cap of `tileset.json` for the implicit loader (ours are a few kB; parsed JSON takes
/// up to about 20 times its text).
pub const TILESET_JSON: FileKind = FileKind::new("tileset JSON", 16 << 20);
/// The size cap of one subtree file.
pub const SUBTREE_FILE: FileKind = FileKind::new("subtree file", 128 << 20);
/// The size cap of one tile's content (a glb) for the tools that read it whole.
pub const CONTENT_FILE: FileKind = FileKind::new("tile content file", 512 << 20);
/// Most available tiles a loaded tileset may list (what the streaming client also accepts).
pub const MAX_LOADED_TILES: usize = 1 << 20;

/// A tile key as `level/x/y/z` in messages.
fn key_name(k: TileKey) -> String {
    format!("{}/{}/{}/{}", k.level, k.x, k.y, k.z)
}

/// `uri` with `.` dropped and `..` applied, so two spellings of one file compare equal.
fn normalized(uri: &str) -> PathBuf {
    let mut parts: Vec<&std::ffi::OsStr> = Vec::new();
    for c in Path::new(uri).components() {
        match c {
            Component::Normal(p) => parts.push(p),
            Component::ParentDir => {
                parts.pop();
            }
            _ => {}
        }
    }
    parts.iter().collect()
}

fn f64_rows(s: &Subtree, table: u32, prop: &str, width: usize) -> Option<Vec<Vec<f64>>> {
    let t = s.json.property_tables.get(table as usize)?;
    let bytes = s.view(t.properties.get(prop)?.values)?;
    let n = t.count as usize;
    if bytes.len() < n.checked_mul(width * 8)? {
        return None;
    }
    Some(
        (0..n)
            .map(|r| {
                (0..width)
                    .map(|c| {
                        let o = (r * width + c) * 8;
                        f64::from_le_bytes(bytes[o..o + 8].try_into().expect("8 bytes"))
                    })
                    .collect()
            })
            .collect(),
    )
}

fn u32_rows(s: &Subtree, table: u32, prop: &str) -> Option<Vec<u32>> {
    let t = s.json.property_tables.get(table as usize)?;
    let bytes = s.view(t.properties.get(prop)?.values)?;
    let n = t.count as usize;
    if bytes.len() < n.checked_mul(4)? {
        return None;
    }
    Some(
        (0..n)
            .map(|r| u32::from_le_bytes(bytes[r * 4..r * 4 + 4].try_into().expect("4 bytes")))
            .collect(),
    )
}

/// Why `tileset.json` or a subtree could not be parsed (no file names: callers add them).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ParseError {
    /// JSON did not parse.
    #[error("{0}")]
    Json(String),
    /// Not an implicit tileset we can walk, or unreadable subtree contents.
    #[error("{0}")]
    Unsupported(String),
    /// The subtree binary framing is malformed.
    #[error("{0}")]
    Subtree(#[from] subtree::SubtreeError),
}

/// What an implicit-tileset reader needs from `tileset.json` (parsed from bytes, no I/O).
#[derive(Debug, Clone)]
pub struct ImplicitRoot {
    /// The parsed `tileset.json`.
    pub tileset: Tileset,
    /// Subdivision scheme.
    pub scheme: Scheme,
    /// Levels per subtree file (1..=16).
    pub subtree_levels: u32,
    /// Levels in the whole tree.
    pub available_levels: u32,
    /// Subtree URI template (relative to the tileset, unresolved).
    pub subtree_template: String,
    /// Content URI template of the root, when it has content.
    pub content_template: Option<String>,
    /// Root transform (identity when absent).
    pub root_transform: DMat4,
}

/// One available tile as its subtree lists it; the content URI is expanded but not resolved.
#[derive(Debug, Clone, PartialEq)]
pub struct SubtreeTile {
    /// Implicit address.
    pub key: TileKey,
    /// Expanded content URI (relative to the tileset), when the tile has content.
    pub content_uri: Option<String>,
    /// Tight box from `TILE_BOUNDING_BOX` metadata, if present (tileset frame).
    pub bounding_box: Option<[f64; 12]>,
    /// Geometric error (metadata, else the implicit halving rule).
    pub geometric_error: f64,
    /// Splat count from content metadata, if present.
    pub splat_count: Option<u32>,
    /// Bytes per variant (Best, High, Medium, Low; 0 = not written) from content metadata.
    pub variant_bytes: Option<[u32; 4]>,
    /// Utility per variant (-1 = not measured) from content metadata.
    pub variant_utility: Option<[f32; 4]>,
}

/// The tiles of one subtree file and the roots of its available child subtrees.
#[derive(Debug, Clone, PartialEq)]
pub struct SubtreeTiles {
    /// Available tiles, by level then Morton order.
    pub tiles: Vec<SubtreeTile>,
    /// Roots of the child subtrees to read next.
    pub child_subtrees: Vec<TileKey>,
}

/// Parses `tileset.json` bytes of an implicit tileset.
pub fn parse_tileset_json(bytes: &[u8]) -> Result<ImplicitRoot, ParseError> {
    let tileset: Tileset =
        serde_json::from_slice(bytes).map_err(|e| ParseError::Json(e.to_string()))?;
    implicit_root(tileset)
}

/// Checks a parsed `tileset.json` is an implicit tileset we can walk and extracts its parts.
pub fn implicit_root(tileset: Tileset) -> Result<ImplicitRoot, ParseError> {
    let unsupported = |msg: &str| ParseError::Unsupported(msg.to_string());
    let implicit = tileset
        .root
        .implicit_tiling
        .clone()
        .ok_or_else(|| unsupported("the root has no implicitTiling"))?;
    let scheme = match implicit.subdivision_scheme.as_str() {
        "QUADTREE" => Scheme::Quadtree,
        "OCTREE" => Scheme::Octree,
        other => return Err(unsupported(&format!("unknown subdivisionScheme '{other}'"))),
    };
    let levels = implicit.subtree_levels;
    if levels == 0 || levels > 16 {
        return Err(unsupported("subtreeLevels must be within 1..=16 here"));
    }
    if implicit.available_levels > 31 {
        return Err(unsupported("availableLevels must be at most 31 here"));
    }
    let root_transform = match &tileset.root.transform {
        Some(t) if t.len() == 16 && t.iter().all(|v| v.is_finite()) => DMat4::from_cols_slice(t),
        Some(_) => return Err(unsupported("root transform must have 16 finite numbers")),
        None => DMat4::IDENTITY,
    };
    if !tileset.root.geometric_error.is_finite() {
        return Err(unsupported("root geometricError must be finite"));
    }
    Ok(ImplicitRoot {
        content_template: tileset.root.content.as_ref().map(|c| c.uri.clone()),
        subtree_template: implicit.subtrees.uri.clone(),
        scheme,
        subtree_levels: levels,
        available_levels: implicit.available_levels,
        root_transform,
        tileset,
    })
}

fn f32_rows<const W: usize>(s: &Subtree, table: u32, prop: &str) -> Option<Vec<[f32; W]>> {
    let t = s.json.property_tables.get(table as usize)?;
    let bytes = s.view(t.properties.get(prop)?.values)?;
    let n = t.count as usize;
    if bytes.len() < n.checked_mul(W * 4)? {
        return None;
    }
    Some(
        bytes
            .chunks_exact(W * 4)
            .take(n)
            .map(|r| std::array::from_fn(|c| f32::from_le_bytes(word(r, c))))
            .collect(),
    )
}

fn word(b: &[u8], i: usize) -> [u8; 4] {
    [b[i * 4], b[i * 4 + 1], b[i * 4 + 2], b[i * 4 + 3]]
}

fn u32x4_rows(s: &Subtree, table: u32, prop: &str) -> Option<Vec<[u32; 4]>> {
    let t = s.json.property_tables.get(table as usize)?;
    let bytes = s.view(t.properties.get(prop)?.values)?;
    let n = t.count as usize;
    if bytes.len() < n.checked_mul(16)? {
        return None;
    }
    Some(
        bytes
            .chunks_exact(16)
            .take(n)
            .map(|r| std::array::from_fn(|c| u32::from_le_bytes(word(r, c))))
            .collect(),
    )
}

/// Most tiles on a subtree's last level we accept (hostile `subtreeLevels` would allocate).
const MAX_SUBTREE_LEAVES: u64 = 1 << 22;

/// Parses one subtree file (bytes) whose root tile is `root`.
pub fn parse_subtree_tiles(
    ts: &ImplicitRoot,
    root: TileKey,
    bytes: &[u8],
) -> Result<SubtreeTiles, ParseError> {
    let levels = ts.subtree_levels;
    let scheme = ts.scheme;
    let s = subtree::read_subtree(bytes)?;
    let bad = |msg: &str| ParseError::Unsupported(msg.to_string());
    let arity = scheme.arity();
    if arity
        .checked_pow(levels)
        .is_none_or(|n| n > MAX_SUBTREE_LEAVES)
    {
        return Err(bad(
            "subtree too large (more than 2^22 tiles on its last level)",
        ));
    }
    let n_tiles = subtree::tile_count(arity, levels) as usize;
    let avail = s
        .bits(&s.json.tile_availability, n_tiles)
        .ok_or_else(|| bad("tile availability unreadable"))?;
    let content = match s.json.content_availability.first() {
        Some(a) => s
            .bits(a, n_tiles)
            .ok_or_else(|| bad("content availability unreadable"))?,
        None => vec![false; n_tiles],
    };
    let boxes = s
        .json
        .tile_metadata
        .and_then(|t| f64_rows(&s, t, "boundingBox", 12));
    let errors = s
        .json
        .tile_metadata
        .and_then(|t| f64_rows(&s, t, "geometricError", 1));
    let content_table = s
        .json
        .content_metadata
        .as_ref()
        .and_then(|v| v.first().copied());
    let counts = content_table.and_then(|t| u32_rows(&s, t, "splatCount"));
    let vbytes = content_table.and_then(|t| u32x4_rows(&s, t, "variantBytes"));
    let vutil = content_table.and_then(|t| f32_rows::<4>(&s, t, "variantUtility"));
    let mut tiles = Vec::new();
    let mut content_row = 0;
    // Tile indices grow with the level, then the Morton index: rows follow that order.
    let available = (0..levels).flat_map(|rl| {
        let first = subtree::tile_count(arity, rl) as usize;
        (0..arity.pow(rl)).map(move |m| (rl, m, first + m as usize))
    });
    for (row, (rl, m, idx)) in available.filter(|&(_, _, idx)| avail[idx]).enumerate() {
        let (x, y, z) = scheme.decode(m);
        let key = TileKey {
            level: root.level + rl,
            x: (root.x << rl) + x,
            y: (root.y << rl) + y,
            z: (root.z << rl) + z,
        };
        let implicit_error = ts.tileset.root.geometric_error / f64::powi(2.0, key.level as i32);
        let has_content = content[idx];
        let content_uri = match (&ts.content_template, has_content) {
            (Some(t), true) => Some(expand_template(t, key)),
            _ => None,
        };
        fn row_of<T: Copy>(v: &Option<Vec<T>>, has: bool, row: usize) -> Option<T> {
            if has {
                v.as_ref().and_then(|c| c.get(row)).copied()
            } else {
                None
            }
        }
        tiles.push(SubtreeTile {
            key,
            content_uri,
            bounding_box: boxes
                .as_ref()
                .and_then(|b| b.get(row))
                .and_then(|v| v.as_slice().try_into().ok())
                .filter(|b: &[f64; 12]| b.iter().all(|c| c.is_finite())),
            geometric_error: errors
                .as_ref()
                .and_then(|e| e.get(row))
                .map(|v| v[0])
                .filter(|e| e.is_finite())
                .unwrap_or(implicit_error),
            splat_count: row_of(&counts, has_content, content_row),
            variant_bytes: row_of(&vbytes, has_content, content_row),
            variant_utility: row_of(&vutil, has_content, content_row),
        });
        if has_content {
            content_row += 1;
        }
    }
    let children = s
        .bits(
            &s.json.child_subtree_availability,
            arity.pow(levels) as usize,
        )
        .ok_or_else(|| bad("child subtree availability unreadable"))?;
    let mut child_subtrees = vec![];
    if root.level + levels < ts.available_levels {
        for (m, _) in children.iter().enumerate().filter(|(_, b)| **b) {
            let (x, y, z) = scheme.decode(m as u64);
            child_subtrees.push(TileKey {
                level: root.level + levels,
                x: (root.x << levels) + x,
                y: (root.y << levels) + y,
                z: (root.z << levels) + z,
            });
        }
    }
    Ok(SubtreeTiles {
        tiles,
        child_subtrees,
    })
}

/// Loads `tileset.json` and walks its subtrees. Every file is read through
/// [`splat2tiles_io::bounded`] with its kind's cap; the walk lists at most [`MAX_LOADED_TILES`]
/// tiles, and a subtree or content file that two tiles reach is refused (the loop a
/// self-referencing subtree would make, or one content drawn once per tile that names it).
pub fn load_tileset(path: &Path) -> Result<LoadedTileset, LoadError> {
    let bytes = read_file(path, TILESET_JSON)?;
    let root = parse_tileset_json(&bytes).map_err(|e| parsed(path, e))?;
    drop(bytes);
    let dir = path.parent().unwrap_or(Path::new(".")).to_path_buf();
    let mut walk = Walk {
        tileset: path,
        dir: &dir,
        seen: HashMap::new(),
        tiles: Vec::new(),
    };
    let mut queue = vec![TileKey::ROOT];
    while let Some(sroot) = queue.pop() {
        if sroot.level < root.available_levels {
            queue.extend(walk.subtree(&root, sroot)?);
        }
    }
    let tiles = walk.tiles;
    Ok(LoadedTileset {
        dir,
        scheme: root.scheme,
        root_transform: root.root_transform,
        tileset: root.tileset,
        tiles,
    })
}

/// A [`ParseError`] of `path` as a [`LoadError`].
fn parsed(path: &Path, e: ParseError) -> LoadError {
    match e {
        ParseError::Json(msg) => LoadError::Json {
            path: path.to_path_buf(),
            msg,
        },
        ParseError::Unsupported(msg) => LoadError::Unsupported {
            path: path.to_path_buf(),
            msg,
        },
        ParseError::Subtree(source) => LoadError::Subtree {
            path: path.to_path_buf(),
            source,
        },
    }
}

/// The state of [`load_tileset`]'s walk: the files reached so far (by normalised URI, with
/// the tile that reached them) and the tiles listed.
struct Walk<'a> {
    tileset: &'a Path,
    dir: &'a Path,
    seen: HashMap<PathBuf, TileKey>,
    tiles: Vec<LoadedTile>,
}

impl Walk<'_> {
    /// Resolves `uri` (a subtree's or a content's, reached from tile `key`) inside the tileset
    /// folder; refuses a URI that leaves it or a file another tile already reached.
    fn reach(&mut self, what: &str, uri: &str, key: TileKey) -> Result<PathBuf, LoadError> {
        let path = resolve_inside(self.dir, uri).ok_or_else(|| LoadError::Unsupported {
            path: self.tileset.to_path_buf(),
            msg: format!("{what} URI '{uri}' leaves the tileset folder"),
        })?;
        if let Some(first) = self.seen.insert(normalized(uri), key) {
            return Err(LoadError::Bound {
                path,
                msg: format!(
                    "the {what} of both tile {} and tile {}: each tile's {what} must be a file \
                     of its own",
                    key_name(first),
                    key_name(key)
                ),
            });
        }
        Ok(path)
    }

    /// Reads the subtree rooted at `sroot`, lists its tiles, returns its child subtrees.
    fn subtree(&mut self, root: &ImplicitRoot, sroot: TileKey) -> Result<Vec<TileKey>, LoadError> {
        let uri = expand_template(&root.subtree_template, sroot);
        let spath = self.reach("subtree", &uri, sroot)?;
        let bytes = read_file(&spath, SUBTREE_FILE)?;
        let st = parse_subtree_tiles(root, sroot, &bytes).map_err(|e| parsed(&spath, e))?;
        drop(bytes);
        if self.tiles.len() + st.tiles.len() > MAX_LOADED_TILES {
            return Err(LoadError::Bound {
                path: self.tileset.to_path_buf(),
                msg: format!("more than {MAX_LOADED_TILES} available tiles"),
            });
        }
        for t in st.tiles {
            let content = match &t.content_uri {
                Some(uri) => Some(self.reach("content", uri, t.key)?),
                None => None,
            };
            self.tiles.push(LoadedTile {
                key: t.key,
                content,
                bounding_box: t.bounding_box,
                geometric_error: t.geometric_error,
                splat_count: t.splat_count,
            });
        }
        Ok(st.child_subtrees)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn templates_and_escapes() {
        let k = TileKey {
            level: 3,
            x: 1,
            y: 2,
            z: 7,
        };
        assert_eq!(
            expand_template("t/{level}/{x}/{y}/{z}.glb", k),
            "t/3/1/2/7.glb"
        );
        let d = Path::new("/data/ts");
        assert_eq!(resolve_inside(d, "a/b.glb"), Some(d.join("a/b.glb")));
        assert_eq!(resolve_inside(d, "a/../b.glb"), Some(d.join("a/../b.glb")));
        for bad in [
            "../x.glb",
            "a/../../x",
            "/etc/passwd",
            "http://x/y.glb",
            "C:\\x",
            "\\\\srv\\x",
        ] {
            assert_eq!(resolve_inside(d, bad), None, "{bad}");
        }
    }
}
