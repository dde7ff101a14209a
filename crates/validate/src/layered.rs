//! Layered content (`spec/layered-content.md`): once any content declares `SPLAT2TILES_layer`,
//! the tileset must refine by ADD, the root must carry the base layer, and every other content
//! must be a layer of its own level whose deltas (for its parent and, format v2, for ancestors
//! on its path) match those layers' splats and stay in range.
//!
//! Runs after the structural checks, when they found no error, over the tiles `tiling::load`
//! finds; a content that is not a readable, uncompressed glb is skipped here (the content checks
//! report it).

use super::context::Ctx;
use super::issues::{Issue, Severity};
use splat2tiles_tiles::encode::glb::{GlbError, parse_json, read_glb};
use splat2tiles_tiles::encode::tile::ATTR_POSITION;
use splat2tiles_tiles::layers::glb::{LayerInfo, read_layer};
use splat2tiles_tiles::layers::{DELTA_SUM_TOLERANCE, EXTENSION};
use splat2tiles_tiles::tiling::TileKey;
use splat2tiles_tiles::tiling::load::load_tileset;
use std::collections::BTreeMap;
use std::path::Path;

/// What one content says about its layer.
struct Content {
    /// Issue path prefix (`file#`).
    name: String,
    /// Splats of its splat primitive (`POSITION` count).
    splats: u64,
    /// Its layer, or why the extension could not be read.
    layer: Result<Option<LayerInfo>, GlbError>,
    /// The file (decoded again only when positive deltas may raise its opacities above 1).
    path: std::path::PathBuf,
}

fn read_content(path: &Path, name: String, limit: u64) -> Option<Content> {
    let size = std::fs::metadata(path).ok()?.len();
    if size > limit {
        return None;
    }
    let bytes = std::fs::read(path).ok()?;
    let chunks = read_glb(&bytes).ok()?;
    let doc = parse_json(&chunks).ok()?;
    let splats = doc
        .meshes
        .iter()
        .flat_map(|m| &m.primitives)
        .find_map(|p| {
            p.extensions.as_ref()?.gaussian_splatting.as_ref()?;
            let a = *p.attributes.get(ATTR_POSITION)?;
            Some(doc.accessors.get(a as usize)?.count)
        })?;
    let layer = read_layer(&bytes);
    Some(Content {
        name,
        splats,
        layer,
        path: path.to_path_buf(),
    })
}

/// Checks the layered form of the tileset in `file` (a `tileset.json` on disk), once the
/// structural checks found no error: the tile walk (`tiling::load`) trusts the structure
/// (its availability and subtree sizes) that those checks bound on hostile input.
pub(crate) fn validate(ctx: &mut Ctx<'_>, file: &Path) {
    // Nothing layered among the checked contents: no second walk over every content (on a
    // city that would read gigabytes again).
    if !ctx.layered_seen || ctx.issues.iter().any(|i| i.severity == Severity::Error) {
        return;
    }
    let Ok(ts) = load_tileset(file) else {
        return;
    };
    let limit = ctx.opts.max_decompressed_bytes;
    let mut contents: BTreeMap<TileKey, Content> = BTreeMap::new();
    for t in &ts.tiles {
        let Some(path) = &t.content else { continue };
        let name = path
            .strip_prefix(&ctx.root)
            .unwrap_or(path)
            .display()
            .to_string();
        if let Some(c) = read_content(path, name, limit) {
            contents.insert(t.key, c);
        }
    }
    if !contents.values().any(|c| !matches!(c.layer, Ok(None))) {
        return;
    }
    let refine = ts.tileset.root.refine.as_deref().unwrap_or("");
    if refine != "ADD" {
        ctx.push(Issue::LAYER_REFINE_NOT_ADD(
            format!("{}#/root/refine", ctx.file),
            format!("contents declare {EXTENSION} but the implicit root refines by '{refine}'; layers are drawn together (ADD)"),
        ));
    }
    match contents.get(&TileKey::ROOT) {
        Some(Content {
            layer: Ok(Some(l)), ..
        }) if l.level == 0
            && l.parent_opacity_delta.is_none()
            && l.ancestor_opacity_deltas.is_empty() => {}
        Some(c) => ctx.push(Issue::LAYER_BASE_MISSING(
            c.name.clone(),
            "the root tile's content is not a base layer (level 0, no parentOpacityDelta)",
        )),
        None => ctx.push(Issue::LAYER_BASE_MISSING(
            format!("{}#/root/content", ctx.file),
            "the root tile has no readable content to serve as the base layer",
        )),
    }
    // Per parent: the sum of its children's deltas, per parent splat.
    let mut sums: BTreeMap<TileKey, Vec<f32>> = BTreeMap::new();
    for (&key, c) in &contents {
        if key == TileKey::ROOT {
            continue;
        }
        for (target, d) in layer_deltas(ctx, key, c, &contents) {
            let s = sums.entry(target).or_insert_with(|| vec![0.0; d.len()]);
            for (a, d) in s.iter_mut().zip(d) {
                *a += d;
            }
        }
    }
    for (parent, s) in sums {
        delta_sum_rules(ctx, &contents[&parent], &s);
    }
}

/// The enhancement layer `c` on tile `key`: its extension, level and deltas checked; returns
/// the deltas that pass, each with the tile it adjusts (the parent, then ancestors).
fn layer_deltas<'c>(
    ctx: &mut Ctx<'_>,
    key: TileKey,
    c: &'c Content,
    contents: &BTreeMap<TileKey, Content>,
) -> Vec<(TileKey, &'c [f32])> {
    let ext = format!("{}#/meshes/*/primitives/*/extensions/{EXTENSION}", c.name);
    let layer = match &c.layer {
        Err(why @ GlbError::Invalid { path, .. }) if path.contains("/sparse") => {
            ctx.push(Issue::LAYER_SPARSE_INVALID(
                format!("{}#{path}", c.name),
                why.to_string(),
            ));
            return vec![];
        }
        Err(why) => {
            ctx.push(Issue::LAYER_EXTENSION_INVALID(
                c.name.clone(),
                why.to_string(),
            ));
            return vec![];
        }
        Ok(None) => {
            ctx.push(Issue::LAYER_EXTENSION_INVALID(
                c.name.clone(),
                format!("a content of a layered tileset without {EXTENSION}"),
            ));
            return vec![];
        }
        Ok(Some(l)) => l,
    };
    if layer.level != key.level {
        ctx.push(Issue::LAYER_LEVEL_MISMATCH(
            format!("{ext}/level"),
            format!("level {} on a tile of level {}", layer.level, key.level),
        ));
    }
    let Some(deltas) = &layer.parent_opacity_delta else {
        ctx.push(Issue::LAYER_EXTENSION_INVALID(
            ext,
            "an enhancement layer needs parentOpacityDelta",
        ));
        return vec![];
    };
    let apath = format!(
        "{}#{}",
        c.name,
        layer.delta_accessor_path.as_deref().unwrap_or("")
    );
    let Some(parent) = key.parent() else {
        return vec![];
    };
    let Some(pc) = contents.get(&parent) else {
        ctx.push(Issue::LAYER_PARENT_MISSING(
            c.name.clone(),
            format!(
                "parent tile {}/{}/{}/{} has no readable content to adjust",
                parent.level, parent.x, parent.y, parent.z
            ),
        ));
        return vec![];
    };
    if deltas.len() as u64 != pc.splats {
        ctx.push(Issue::LAYER_DELTA_COUNT_MISMATCH(
            format!("{apath}/count"),
            format!(
                "{} deltas but the parent layer {} holds {} splats",
                deltas.len(),
                pc.name,
                pc.splats
            ),
        ));
        return vec![];
    }
    if !delta_values_ok(ctx, &apath, deltas) {
        return vec![];
    }
    let mut carried = vec![(parent, deltas.as_slice())];
    for (n, a) in layer.ancestor_opacity_deltas.iter().enumerate() {
        let epath = format!("{ext}/ancestorOpacityDeltas/{n}");
        let apath = format!("{}#{}", c.name, a.accessor_path);
        if u64::from(a.level) + 1 >= u64::from(key.level) {
            ctx.push(Issue::LAYER_ANCESTOR_INVALID(
                format!("{epath}/level"),
                format!(
                    "ancestor level {} on a layer of level {}: must be below {} (the parent's deltas go in parentOpacityDelta)",
                    a.level,
                    key.level,
                    key.level.saturating_sub(1)
                ),
            ));
            continue;
        }
        let anc = key.ancestor(a.level);
        let Some(ac) = contents.get(&anc) else {
            ctx.push(Issue::LAYER_ANCESTOR_INVALID(
                format!("{epath}/level"),
                format!(
                    "ancestor tile {}/{}/{}/{} has no readable content to adjust",
                    anc.level, anc.x, anc.y, anc.z
                ),
            ));
            continue;
        };
        if a.deltas.len() as u64 != ac.splats {
            ctx.push(Issue::LAYER_DELTA_COUNT_MISMATCH(
                format!("{apath}/count"),
                format!(
                    "{} deltas but the ancestor layer {} holds {} splats",
                    a.deltas.len(),
                    ac.name,
                    ac.splats
                ),
            ));
            continue;
        }
        if delta_values_ok(ctx, &apath, &a.deltas) {
            carried.push((anc, &a.deltas));
        }
    }
    carried
}

/// The summed deltas `s` that content `c`'s descendant layers give its splats: none may fade a
/// splat below zero, and (with every layer drawn) none should raise one above an opacity of 1.
fn delta_sum_rules(ctx: &mut Ctx<'_>, c: &Content, s: &[f32]) {
    if let Some((i, v)) = s
        .iter()
        .enumerate()
        .find(|(_, v)| **v < -1.0 - DELTA_SUM_TOLERANCE)
    {
        ctx.push(Issue::LAYER_DELTA_SUM_OUT_OF_RANGE(
            c.name.clone(),
            format!("the deltas its descendant layers give splat {i} add up to {v} (below -1): it would be faded below zero"),
        ));
    }
    // Positive sums: with every layer drawn, o * (1 + sum) above 1 is capped (drawn at 1).
    if !s.iter().any(|v| *v > 0.0) {
        return;
    }
    let Some(tile) = std::fs::read(&c.path)
        .ok()
        .and_then(|b| splat2tiles_tiles::encode::read_tile_glb(&b).ok())
    else {
        return;
    };
    let over: Vec<(usize, f32)> = tile
        .splats
        .opacities
        .iter()
        .zip(s)
        .map(|(o, d)| o * (1.0 + d))
        .enumerate()
        .filter(|(_, a)| *a > 1.0 + DELTA_SUM_TOLERANCE)
        .collect();
    if let Some(&(i, a)) = over.first() {
        ctx.push(Issue::LAYER_OPACITY_ABOVE_ONE(
            c.name.clone(),
            format!(
                "{} splats reach an opacity above 1 with every descendant layer drawn (capped at 1), the first splat {i} at {a}",
                over.len()
            ),
        ));
    }
}

/// Whether every delta is finite; reports `LAYER_DELTA_OUT_OF_RANGE` on the accessor at `apath`
/// otherwise. Single deltas may be below -1 (format v2: a LapisGS splat whose opacity rose at
/// one level may fall by more than its stored opacity at a later one); their sums per splat
/// are checked against -1.
fn delta_values_ok(ctx: &mut Ctx<'_>, apath: &str, deltas: &[f32]) -> bool {
    let ok = |v: &f32| v.is_finite();
    let Some((i, v)) = deltas.iter().enumerate().find(|(_, v)| !ok(v)) else {
        return true;
    };
    let bad = deltas.iter().filter(|v| !ok(v)).count();
    ctx.push(Issue::LAYER_DELTA_OUT_OF_RANGE(
        apath.to_string(),
        format!("{bad} deltas are not finite, the first at index {i}: {v}"),
    ));
    false
}
