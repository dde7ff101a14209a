//! Reads an implicit tileset back: `tileset.json`, then every reachable subtree, giving each
//! available tile's key, content path, tight box and geometric error (for tests, render, stream).

use super::subtree::{self, Subtree};
use super::tileset::Tileset;
use super::{Scheme, TileKey};
use glam::DMat4;
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

/// Why a tileset could not be loaded.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum LoadError {
    /// A file could not be read.
    #[error("{path}: {source}")]
    Io {
        /// File.
        path: PathBuf,
        /// OS error.
        source: std::io::Error,
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

fn read(path: &Path) -> Result<Vec<u8>, LoadError> {
    std::fs::read(path).map_err(|source| LoadError::Io {
        path: path.to_path_buf(),
        source,
    })
}

fn f64_rows(s: &Subtree, table: u32, prop: &str, width: usize) -> Option<Vec<Vec<f64>>> {
    let t = s.json.property_tables.get(table as usize)?;
    let bytes = s.view(t.properties.get(prop)?.values)?;
    let n = t.count as usize;
    if bytes.len() < n * width * 8 {
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
    if bytes.len() < n * 4 {
        return None;
    }
    Some(
        (0..n)
            .map(|r| u32::from_le_bytes(bytes[r * 4..r * 4 + 4].try_into().expect("4 bytes")))
            .collect(),
    )
}

/// Loads `tileset.json` and walks its subtrees.
pub fn load_tileset(path: &Path) -> Result<LoadedTileset, LoadError> {
    let bytes = read(path)?;
    let tileset: Tileset = serde_json::from_slice(&bytes).map_err(|e| LoadError::Json {
        path: path.to_path_buf(),
        msg: e.to_string(),
    })?;
    let dir = path.parent().unwrap_or(Path::new(".")).to_path_buf();
    let unsupported = |msg: &str| LoadError::Unsupported {
        path: path.to_path_buf(),
        msg: msg.to_string(),
    };
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
    let content_template = tileset.root.content.as_ref().map(|c| c.uri.clone());
    let root_transform = match &tileset.root.transform {
        Some(t) if t.len() == 16 => DMat4::from_cols_slice(t),
        Some(_) => return Err(unsupported("root transform must have 16 numbers")),
        None => DMat4::IDENTITY,
    };
    let arity = scheme.arity();
    let n_tiles = subtree::tile_count(arity, levels) as usize;
    let mut tiles = Vec::new();
    let mut queue = vec![TileKey::ROOT];
    while let Some(root) = queue.pop() {
        if root.level >= implicit.available_levels {
            continue;
        }
        let uri = expand_template(&implicit.subtrees.uri, root);
        let spath = resolve_inside(&dir, &uri).ok_or_else(|| {
            unsupported(&format!("subtree URI '{uri}' leaves the tileset folder"))
        })?;
        let s = subtree::read_subtree(&read(&spath)?).map_err(|source| LoadError::Subtree {
            path: spath.clone(),
            source,
        })?;
        let bad = |msg: &str| LoadError::Unsupported {
            path: spath.clone(),
            msg: msg.to_string(),
        };
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
        let counts = s
            .json
            .content_metadata
            .as_ref()
            .and_then(|v| v.first().copied())
            .and_then(|t| u32_rows(&s, t, "splatCount"));
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
            let implicit_error = tileset.root.geometric_error / f64::powi(2.0, key.level as i32);
            let has_content = content[idx];
            let content_path = match (&content_template, has_content) {
                (Some(t), true) => {
                    let uri = expand_template(t, key);
                    Some(resolve_inside(&dir, &uri).ok_or_else(|| {
                        unsupported(&format!("content URI '{uri}' leaves the tileset folder"))
                    })?)
                }
                _ => None,
            };
            tiles.push(LoadedTile {
                key,
                content: content_path,
                bounding_box: boxes
                    .as_ref()
                    .and_then(|b| b.get(row))
                    .map(|v| v.as_slice().try_into().expect("12 values")),
                geometric_error: errors
                    .as_ref()
                    .and_then(|e| e.get(row))
                    .map(|v| v[0])
                    .unwrap_or(implicit_error),
                splat_count: if has_content {
                    counts.as_ref().and_then(|c| c.get(content_row)).copied()
                } else {
                    None
                },
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
        for (m, _) in children.iter().enumerate().filter(|(_, b)| **b) {
            let (x, y, z) = scheme.decode(m as u64);
            queue.push(TileKey {
                level: root.level + levels,
                x: (root.x << levels) + x,
                y: (root.y << levels) + y,
                z: (root.z << levels) + z,
            });
        }
    }
    Ok(LoadedTileset {
        dir,
        tileset,
        scheme,
        root_transform,
        tiles,
    })
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
