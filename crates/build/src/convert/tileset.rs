//! Tileset stage: the tree of tile facts (boxes, errors, counts, variant facts) completed and
//! written as implicit-tiling subtree files and `tileset.json`; small, held in memory.

use super::frame::{Layout, box_array, padded_box};
use super::{ConvertError, ConvertReport, check_interrupt, io_err};
use crate::variants::{self, ContentFacts, VariantOptions};
use glam::DVec3;
use splat2tiles_tiles::tiling::levels::{child_counts, keeps_content, monotone_errors};
use splat2tiles_tiles::tiling::subtree::{self, Column, SubtreeData, Table};
use splat2tiles_tiles::tiling::tileset::{self, Asset, Content, ImplicitTiling, Tile, Tileset};
use splat2tiles_tiles::tiling::{Scheme, TileKey};
use std::collections::{BTreeMap, HashMap};
use std::path::Path;

/// A tile of the tree: its tight box in the tileset frame and, for leaves, its content facts.
#[derive(Debug, Clone)]
pub(super) struct TreeTile {
    pub(super) lo: DVec3,
    pub(super) hi: DVec3,
    pub(super) splat_count: u32,
    pub(super) bytes: u64,
    pub(super) has_content: bool,
    pub(super) is_leaf: bool,
    /// Geometric error of a parent with content (its clustering radius).
    pub(super) error: f64,
    /// Per-variant facts of the content, when the tile has content.
    pub(super) facts: Option<ContentFacts>,
}

/// Adds every ancestor of the leaves, with boxes that enclose their descendants.
pub(super) fn build_tree(leaves: HashMap<TileKey, TreeTile>) -> BTreeMap<TileKey, TreeTile> {
    let mut tree: BTreeMap<TileKey, TreeTile> = leaves.into_iter().collect();
    let keys: Vec<TileKey> = tree.keys().copied().collect();
    for key in keys {
        let (lo, hi) = (tree[&key].lo, tree[&key].hi);
        let mut k = key;
        while let Some(p) = k.parent() {
            let t = tree.entry(p).or_insert(TreeTile {
                lo,
                hi,
                splat_count: 0,
                bytes: 0,
                has_content: false,
                is_leaf: false,
                error: 0.0,
                facts: None,
            });
            t.lo = t.lo.min(lo);
            t.hi = t.hi.max(hi);
            k = p;
        }
    }
    tree
}

/// A tile's own geometric error: 0 for leaves (full detail); for LOD parents, the clustering
/// radius they were built with (no merged splat moved further than that from its members'
/// reach); 0 for a pass-through (it takes its parent's in [`finish_tree`]); for other tiles
/// without content (builds without LOD), the diagonal of their box (rendering nothing misses
/// everything below).
fn own_error(t: &TreeTile, pass_through: bool) -> f64 {
    if t.is_leaf || pass_through {
        0.0
    } else if t.has_content {
        t.error.max(1e-9)
    } else {
        (t.hi - t.lo).length().max(1e-6)
    }
}

/// The geometric error written for a tile (its own, raised to its descendants' by
/// [`finish_tree`]).
fn geometric_error(t: &TreeTile) -> f64 {
    t.error
}

/// Last pass over the tree: every box encloses its descendants' and its own content's splats,
/// errors are the tiles' own raised so they never grow downwards, and every pass-through
/// (no content, one child, below the root: `levels::keeps_content`) takes its parent's box and
/// error, so its screen-space error is its parent's for every camera and a traversal that
/// refines the parent refines it too.
pub(super) fn finish_tree(tree: &mut BTreeMap<TileKey, TreeTile>) {
    let keys: Vec<TileKey> = tree.keys().rev().copied().collect();
    for k in &keys {
        if let Some(p) = k.parent() {
            let (lo, hi) = (tree[k].lo, tree[k].hi);
            if let Some(t) = tree.get_mut(&p) {
                t.lo = t.lo.min(lo);
                t.hi = t.hi.max(hi);
            }
        }
    }
    let children = child_counts(tree.keys());
    let passes = |k: &TileKey, t: &TreeTile| {
        !t.has_content && !keeps_content(*k, children.get(k).copied().unwrap_or(0))
    };
    let mut errors: BTreeMap<TileKey, f64> = tree
        .iter()
        .map(|(k, t)| (*k, own_error(t, passes(k, t))))
        .collect();
    monotone_errors(&mut errors);
    // Keys order by level first: a parent is final before its children.
    for k in keys.iter().rev() {
        if passes(k, &tree[k]) {
            let p = &tree[&k.parent().expect("a pass-through has a parent")];
            let (lo, hi, e) = (p.lo, p.hi, p.error);
            let t = tree.get_mut(k).expect("a tree key");
            (t.lo, t.hi, t.error) = (lo, hi, e);
        } else {
            tree.get_mut(k).expect("a tree key").error = errors[k];
        }
    }
}

/// The geometric error a content tile is viewed at: its own, or for a leaf (error 0) its
/// parent's, from whose switching distance on it is drawn (0 for a lone root leaf).
pub(super) fn view_error(tree: &BTreeMap<TileKey, TreeTile>, k: TileKey) -> f64 {
    let own = tree[&k].error;
    if own > 0.0 {
        return own;
    }
    k.parent()
        .and_then(|p| tree.get(&p))
        .map_or(0.0, |p| p.error)
}

/// Measures the variant utilities of every content tile at its real switching distance, once
/// [`finish_tree`] has set the errors (`variants::measure`), when the options defer them; the
/// tree's facts and the report's contents get them.
pub(super) fn measure_utilities(
    tree: &mut BTreeMap<TileKey, TreeTile>,
    scheme: Scheme,
    dir: &Path,
    opts: &VariantOptions,
    report: &mut ConvertReport,
) -> Result<(), ConvertError> {
    if !opts.deferred_utility() {
        return Ok(());
    }
    check_interrupt()?;
    let tiles: Vec<_> = tree
        .iter()
        .filter_map(|(k, t)| {
            Some((
                *k,
                view_error(tree, *k),
                t.facts.as_ref()?.utility_curve.as_ref(),
            ))
        })
        .collect();
    let us = variants::measure::measure_utilities(dir, scheme, &tiles, opts)?;
    let by_key: HashMap<TileKey, [f32; 4]> = tiles.iter().map(|t| t.0).zip(us).collect();
    for (k, t) in tree.iter_mut() {
        if let (Some(f), Some(u)) = (t.facts.as_mut(), by_key.get(k)) {
            f.variant_utility = *u;
        }
    }
    for (k, f) in report.contents.iter_mut() {
        if let Some(u) = by_key.get(k) {
            f.variant_utility = *u;
        }
    }
    Ok(())
}

/// Path of the subtree file rooted at `k`, relative to the output folder.
fn subtree_path(scheme: Scheme, k: TileKey) -> String {
    match scheme {
        Scheme::Octree => format!("subtrees/{}/{}/{}/{}.subtree", k.level, k.x, k.y, k.z),
        Scheme::Quadtree => format!("subtrees/{}/{}/{}.subtree", k.level, k.x, k.y),
    }
}

/// Writes one subtree file per subtree root of the tree; returns the files and bytes written.
pub(super) fn write_subtrees(
    tree: &BTreeMap<TileKey, TreeTile>,
    scheme: Scheme,
    levels: u32,
    dir: &Path,
) -> Result<(usize, u64), ConvertError> {
    let arity = scheme.arity();
    let n_tiles = subtree::tile_count(arity, levels) as usize;
    let n_children = arity.pow(levels) as usize;
    // Group tiles by the root of the subtree holding them.
    let mut groups: BTreeMap<TileKey, Vec<TileKey>> = BTreeMap::new();
    for &k in tree.keys() {
        let root_level = k.level / levels * levels;
        groups.entry(k.ancestor(root_level)).or_default().push(k);
    }
    let mut child_roots: BTreeMap<TileKey, Vec<TileKey>> = BTreeMap::new();
    for &r in groups.keys().filter(|r| r.level >= levels) {
        child_roots
            .entry(r.ancestor(r.level - levels))
            .or_default()
            .push(r);
    }
    let mut files = 0;
    let mut bytes = 0;
    for (root, members) in &groups {
        check_interrupt()?;
        let mut tiles = vec![false; n_tiles];
        let mut contents = vec![false; n_tiles];
        let mut child_subtrees = vec![false; n_children];
        let mut rows: Vec<(u64, TileKey)> = Vec::with_capacity(members.len());
        for &k in members {
            let rl = k.level - root.level;
            let rel = |c: u32, r: u32| c - (r << rl);
            let m = scheme.encode(rel(k.x, root.x), rel(k.y, root.y), rel(k.z, root.z));
            let idx = subtree::tile_index(arity, rl, m);
            tiles[idx as usize] = true;
            contents[idx as usize] = tree[&k].has_content;
            rows.push((idx, k));
        }
        // Child subtrees: the subtree roots one level below this subtree's last level.
        for child in child_roots.get(root).into_iter().flatten() {
            let rel = |c: u32, r: u32| c - (r << levels);
            let m = scheme.encode(
                rel(child.x, root.x),
                rel(child.y, root.y),
                rel(child.z, root.z),
            );
            child_subtrees[m as usize] = true;
        }
        rows.sort_by_key(|(i, _)| *i);
        let boxes: Vec<f64> = rows
            .iter()
            .flat_map(|(_, k)| {
                let t = &tree[k];
                let (c, h) = padded_box(t.lo, t.hi);
                box_array(c, h)
            })
            .collect();
        let errors: Vec<f64> = rows
            .iter()
            .map(|(_, k)| geometric_error(&tree[k]))
            .collect();
        let with_content: Vec<&TreeTile> = rows
            .iter()
            .map(|(_, k)| &tree[k])
            .filter(|t| t.has_content)
            .collect();
        let counts: Vec<u32> = with_content.iter().map(|t| t.splat_count).collect();
        let variant_bytes: Vec<u32> = with_content
            .iter()
            .flat_map(|t| t.facts.as_ref().map_or([0; 4], |f| f.variant_bytes))
            .collect();
        let variant_utility: Vec<f32> = with_content
            .iter()
            .flat_map(|t| t.facts.as_ref().map_or([-1.0; 4], |f| f.variant_utility))
            .collect();
        let data = SubtreeData {
            tiles,
            contents,
            child_subtrees,
            tile_metadata: Some(Table {
                class: tileset::TILE_CLASS.into(),
                count: rows.len() as u64,
                columns: vec![
                    ("boundingBox".into(), Column::F64(boxes)),
                    ("geometricError".into(), Column::F64(errors)),
                ],
            }),
            content_metadata: (!counts.is_empty()).then(|| Table {
                class: tileset::CONTENT_CLASS.into(),
                count: counts.len() as u64,
                columns: vec![
                    ("splatCount".into(), Column::U32(counts)),
                    ("variantBytes".into(), Column::U32(variant_bytes)),
                    ("variantUtility".into(), Column::F32(variant_utility)),
                ],
            }),
        };
        let encoded = subtree::write_subtree(&data);
        let path = dir.join(subtree_path(scheme, *root));
        if let Some(parent) = path.parent() {
            std::fs::create_dir_all(parent).map_err(io_err(parent, "creating folder"))?;
        }
        std::fs::write(&path, &encoded).map_err(io_err(&path, "writing"))?;
        files += 1;
        bytes += encoded.len() as u64;
    }
    Ok((files, bytes))
}

/// Writes `tileset` as `dir/tileset.json`; returns the bytes written.
pub(super) fn write_tileset_json(tileset: &Tileset, dir: &Path) -> Result<u64, ConvertError> {
    let json = serde_json::to_vec_pretty(tileset).expect("tileset serialises");
    let path = dir.join("tileset.json");
    std::fs::write(&path, &json).map_err(io_err(&path, "writing"))?;
    Ok(json.len() as u64)
}

/// The `tileset.json` document of the tree: implicit root, schema, variant metadata, extras.
pub(super) fn tileset_json(
    tree: &BTreeMap<TileKey, TreeTile>,
    layout: &Layout,
    levels: u32,
    subtree_levels: u32,
    report: &ConvertReport,
    name: &str,
    variant_opts: &VariantOptions,
) -> Tileset {
    let root = &tree[&TileKey::ROOT];
    let root_error = geometric_error(root);
    let scheme = layout.scheme;
    let template = |kind: &str, ext: &str| match scheme {
        Scheme::Octree => format!("{kind}/{{level}}/{{x}}/{{y}}/{{z}}.{ext}"),
        Scheme::Quadtree => format!("{kind}/{{level}}/{{x}}/{{y}}.{ext}"),
    };
    let input_name = Path::new(name)
        .file_name()
        .map(|f| f.to_string_lossy().into_owned())
        .unwrap_or_default();
    Tileset {
        asset: Asset {
            version: "1.1".into(),
            generator: Some(format!("splat2tiles {}", env!("CARGO_PKG_VERSION"))),
            tileset_version: None,
        },
        // Never below the root's own error (a georeferenced root is a zoom-0 LOD tile whose
        // clustering radius can exceed the scene's extent).
        geometric_error: (root.hi - root.lo).length().max(root_error).max(1e-6),
        root: Tile {
            bounding_volume: layout.root_volume.clone(),
            geometric_error: root_error,
            refine: Some("REPLACE".into()),
            transform: layout.transform.map(|t| t.to_vec()),
            content: Some(Content {
                uri: variants::uri_template(scheme, variant_opts.profile.default_variant()),
            }),
            implicit_tiling: Some(ImplicitTiling {
                subdivision_scheme: scheme.as_str().into(),
                subtree_levels,
                available_levels: levels,
                subtrees: Content {
                    uri: template("subtrees", "subtree"),
                },
            }),
            children: vec![],
        },
        schema: Some(tileset::schema()),
        metadata: Some(tileset::with_mercator_root(
            variants::tileset_metadata(scheme, variant_opts),
            layout.mercator_root,
        )),
        extensions_used: match variant_opts.profile {
            variants::Profile::Cesium => vec!["3DTILES_content_gltf".into()],
            variants::Profile::Default => vec![],
        },
        extensions_required: vec![],
        extensions: match variant_opts.profile {
            variants::Profile::Cesium => Some(variants::cesium_content_gltf()),
            variants::Profile::Default => None,
        },
        extras: Some(serde_json::json!({
            "splat2tiles": {
                "input": input_name,
                "splats": report.splats_out,
                "shDegree": report.sh_degree,
                "upAxis": report.up_axis,
                "georeferenced": layout.transform.is_some(),
            }
        })),
    }
}

impl TreeTile {
    /// A written leaf: its box and content facts.
    pub(super) fn leaf(lo: DVec3, hi: DVec3, facts: ContentFacts) -> TreeTile {
        TreeTile {
            lo,
            hi,
            splat_count: facts.splat_count,
            bytes: facts.bytes,
            has_content: true,
            is_leaf: true,
            error: 0.0,
            facts: Some(facts),
        }
    }
}
