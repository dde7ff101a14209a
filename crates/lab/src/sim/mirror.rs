//! Copies an `http://` implicit tileset into a local folder for the simulator (whose transport
//! reads files): `tileset.json`, every reachable subtree and every written variant's content.
//!
//! Bounded like `tiling::load::load_tileset`: each file within its kind's size cap, at most
//! `MAX_LOADED_TILES` tiles and [`MAX_TOTAL_BYTES`] in all, every URI relative and inside the
//! tileset's folder, each subtree fetched once.

use anyhow::{Context, bail};
use splat2tiles_io::bounded::FileKind;
use splat2tiles_tiles::tiling::TileKey;
use splat2tiles_tiles::tiling::load::{
    CONTENT_FILE, ImplicitRoot, MAX_LOADED_TILES, SUBTREE_FILE, TILESET_JSON, expand_template,
    parse_subtree_tiles, parse_tileset_json, resolve_inside,
};
use std::collections::HashSet;
use std::io::Read;
use std::path::{Component, Path, PathBuf};
use std::time::Duration;

/// Most bytes a mirror downloads in all.
pub const MAX_TOTAL_BYTES: u64 = 16 << 30;

/// What a mirror fetched.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct MirrorStats {
    /// Files written.
    pub files: usize,
    /// Their bytes.
    pub bytes: u64,
    /// Available tiles listed.
    pub tiles: usize,
}

/// The folder URL of a tileset URL (`.../tileset.json` or a folder), ending in `/`, and the
/// tileset JSON's file name.
fn split_url(url: &str) -> (String, String) {
    let url = url.split(['?', '#']).next().unwrap_or(url);
    match url.rsplit_once('/') {
        Some((base, file)) if file.ends_with(".json") => (format!("{base}/"), file.to_string()),
        _ => (
            format!("{}/", url.trim_end_matches('/')),
            "tileset.json".into(),
        ),
    }
}

struct Fetcher {
    http: reqwest::blocking::Client,
    base: String,
    dir: PathBuf,
    stats: MirrorStats,
}

impl Fetcher {
    /// Fetches `uri` (relative to the base) into the same place under `dir`; returns its bytes.
    fn get(&mut self, uri: &str, kind: FileKind) -> anyhow::Result<Vec<u8>> {
        let path = resolve_inside(&self.dir, uri)
            .with_context(|| format!("URI '{uri}' is absolute or leaves the tileset's folder"))?;
        let rel: Vec<String> = path
            .strip_prefix(&self.dir)
            .unwrap_or(&path)
            .components()
            .filter_map(|c| match c {
                Component::Normal(s) => s.to_str().map(str::to_string),
                _ => None,
            })
            .collect();
        let url = format!("{}{}", self.base, rel.join("/"));
        let resp = self
            .http
            .get(&url)
            .send()
            .with_context(|| format!("GET {url}"))?;
        if !resp.status().is_success() {
            bail!("GET {url}: HTTP {}", resp.status());
        }
        let mut buf = vec![];
        resp.take(kind.limit + 1)
            .read_to_end(&mut buf)
            .with_context(|| format!("GET {url}"))?;
        if buf.len() as u64 > kind.limit {
            bail!("GET {url}: {} larger than {} bytes", kind.name, kind.limit);
        }
        self.stats.bytes += buf.len() as u64;
        if self.stats.bytes > MAX_TOTAL_BYTES {
            bail!("the tileset is larger than {MAX_TOTAL_BYTES} bytes");
        }
        if let Some(p) = path.parent() {
            std::fs::create_dir_all(p).with_context(|| p.display().to_string())?;
        }
        std::fs::write(&path, &buf).with_context(|| path.display().to_string())?;
        self.stats.files += 1;
        Ok(buf)
    }
}

/// The content URI templates per level (Best..Low) the client would fetch: the tileset
/// metadata's `variantUris` when it has four, and the root content template.
fn templates(root: &ImplicitRoot) -> ([Option<String>; 4], Option<String>) {
    let uris = root
        .tileset
        .metadata
        .as_ref()
        .and_then(|m| m.get("properties"))
        .and_then(|p| p.get("variantUris"))
        .and_then(|v| v.as_array())
        .filter(|a| a.len() == 4);
    let mut out: [Option<String>; 4] = Default::default();
    if let Some(a) = uris {
        for (j, u) in a.iter().enumerate() {
            out[j] = u.as_str().filter(|s| !s.is_empty()).map(str::to_string);
        }
    }
    (out, root.content_template.clone())
}

/// Mirrors the tileset at `url` into `dir` (created; files already there are overwritten).
pub fn mirror(url: &str, dir: &Path) -> anyhow::Result<MirrorStats> {
    let (base, file) = split_url(url);
    let http = reqwest::blocking::Client::builder()
        .timeout(Duration::from_secs(120))
        .build()
        .context("HTTP client")?;
    std::fs::create_dir_all(dir).with_context(|| dir.display().to_string())?;
    let mut f = Fetcher {
        http,
        base,
        dir: dir.to_path_buf(),
        stats: MirrorStats::default(),
    };
    let json = f.get(&file, TILESET_JSON)?;
    if file != "tileset.json" {
        std::fs::write(dir.join("tileset.json"), &json)?;
    }
    let root = parse_tileset_json(&json).map_err(|e| anyhow::anyhow!("{url}: {e}"))?;
    let (variants, content) = templates(&root);
    let mut seen: HashSet<TileKey> = HashSet::new();
    let mut queue = vec![TileKey::ROOT];
    while let Some(sroot) = queue.pop() {
        if sroot.level >= root.available_levels || !seen.insert(sroot) {
            continue;
        }
        let uri = expand_template(&root.subtree_template, sroot);
        let bytes = f.get(&uri, SUBTREE_FILE)?;
        let st = parse_subtree_tiles(&root, sroot, &bytes)
            .map_err(|e| anyhow::anyhow!("{}{uri}: {e}", f.base))?;
        f.stats.tiles += st.tiles.len();
        if f.stats.tiles > MAX_LOADED_TILES {
            bail!("{url}: more than {MAX_LOADED_TILES} available tiles");
        }
        for t in &st.tiles {
            if t.content_uri.is_none() {
                continue;
            }
            let mut uris: Vec<String> = vec![];
            for (j, tpl) in variants.iter().enumerate() {
                let written = t.variant_bytes.is_some_and(|b| b[j] > 0);
                if let (Some(tpl), true) = (tpl, written) {
                    uris.push(expand_template(tpl, t.key));
                }
            }
            if let Some(tpl) = &content {
                uris.push(expand_template(tpl, t.key));
            }
            uris.sort();
            uris.dedup();
            for u in uris {
                f.get(&u, CONTENT_FILE)?;
            }
        }
        queue.extend(st.child_subtrees);
    }
    Ok(f.stats)
}

#[cfg(test)]
mod tests {
    use super::split_url;

    #[test]
    fn urls_split_into_folder_and_file() {
        let s = |u: &str| split_url(u);
        assert_eq!(
            s("http://h:1/a/tileset.json"),
            ("http://h:1/a/".into(), "tileset.json".into())
        );
        assert_eq!(
            s("http://h:1/a/"),
            ("http://h:1/a/".into(), "tileset.json".into())
        );
        assert_eq!(
            s("http://h:1"),
            ("http://h:1/".into(), "tileset.json".into())
        );
        assert_eq!(
            s("http://h/x/other.json?k=1"),
            ("http://h/x/".into(), "other.json".into())
        );
    }
}
