//! Implicit tiling (3D Tiles 1.1 "Implicit Tiling"): the implicitTiling object, template URIs,
//! and a walk over every reachable subtree (each file checked by `subtree_file`) that validates
//! each available tile's content against its volume.

use super::{Parent, content_file};
use crate::context::Ctx;
use crate::cut::{CutTile, record};
use crate::issues::Issue;
use crate::metadata::Schema;
use crate::subtree_file::{Views, availability, check_views, parse_subtree, table_column};
use crate::volume::{Volume, parse_box};
use serde_json::Value;
use splat2tiles_tiles::tiling::load::expand_template;
use splat2tiles_tiles::tiling::subtree::{SubtreeJson, tile_count};
use splat2tiles_tiles::tiling::{Scheme, TileKey};
use std::collections::{HashMap, HashSet};

/// Most subtree files one validation walks.
const MAX_SUBTREES: usize = 1 << 20;

/// Largest number of child-subtree bits walked (N^subtreeLevels); beyond it the walk stops.
const MAX_CHILD_BITS: u64 = 1 << 24;

/// Checks the variables of a template URI against the scheme.
fn template(ctx: &mut Ctx<'_>, uri: &str, path: &str, octree: bool) {
    let allowed: &[&str] = if octree {
        &["level", "x", "y", "z"]
    } else {
        &["level", "x", "y"]
    };
    let mut used = HashSet::new();
    let mut rest = uri;
    while let Some(open) = rest.find('{') {
        let after = &rest[open + 1..];
        let Some(close) = after.find('}') else { break };
        let name = &after[..close];
        if allowed.contains(&name) {
            used.insert(name.to_string());
        } else {
            ctx.push(Issue::TEMPLATE_URI_INVALID_VARIABLE_NAME(
                path,
                format!(
                    "'{{{name}}}' is not one of {allowed:?} ({} scheme)",
                    if octree { "OCTREE" } else { "QUADTREE" }
                ),
            ));
        }
        rest = &after[close + 1..];
    }
    let missing: Vec<&str> = allowed
        .iter()
        .copied()
        .filter(|a| !used.contains(*a))
        .collect();
    if !missing.is_empty() {
        ctx.push(Issue::TEMPLATE_URI_MISSING_VARIABLE_NAME(
            path,
            format!("the template does not use {missing:?}, so different tiles share a URI"),
        ));
    }
}

/// The rules of an implicit root tile itself (no children, metadata or content bounding
/// volumes; contents need a `uri`; no sphere volume); returns its content templates with their
/// JSON paths.
fn root_rules(
    ctx: &mut Ctx<'_>,
    tile: &Value,
    path: &str,
    volume: Option<Volume>,
) -> Vec<(String, String)> {
    // "children, metadata and content.boundingVolume MUST NOT be defined on an implicit root".
    if tile.get("children").is_some() {
        ctx.push(Issue::TILE_IMPLICIT_ROOT_INVALID(
            format!("{path}/children"),
            "an implicit root must not have children",
        ));
    }
    if tile.get("metadata").is_some() {
        ctx.push(Issue::TILE_IMPLICIT_ROOT_INVALID(
            format!("{path}/metadata"),
            "an implicit root must not have metadata",
        ));
    }
    let mut templates = Vec::new();
    let contents: Vec<(String, &Value)> = match (tile.get("content"), tile.get("contents")) {
        (Some(c), _) => vec![(format!("{path}/content"), c)],
        (None, Some(Value::Array(cs))) => cs
            .iter()
            .enumerate()
            .map(|(i, c)| (format!("{path}/contents/{i}"), c))
            .collect(),
        _ => vec![],
    };
    for (cp, c) in &contents {
        if c.get("boundingVolume").is_some() {
            ctx.push(Issue::TILE_IMPLICIT_ROOT_INVALID(
                format!("{cp}/boundingVolume"),
                "content of an implicit root must not have a boundingVolume",
            ));
        }
        match c.get("uri").and_then(Value::as_str) {
            Some(u) => templates.push((format!("{cp}/uri"), u.to_string())),
            None => ctx.push(Issue::PROPERTY_MISSING(
                cp.clone(),
                "content 'uri' is required",
            )),
        }
    }
    if let Some(Volume::Sphere { .. }) = volume {
        ctx.push(Issue::TILE_IMPLICIT_ROOT_INVALID(
            format!("{path}/boundingVolume/sphere"),
            "implicit tiling does not allow sphere bounding volumes (box, region or S2 only)",
        ));
    }
    templates
}

/// The `subtrees` object's `uri` template (`subtrees` is the member, absent or not).
fn subtrees_uri(ctx: &mut Ctx<'_>, subtrees: Option<&Value>, ip: &str) -> Option<String> {
    const WHAT: &str = "'subtrees' must be an object with a string 'uri' template";
    let issue = match subtrees {
        None => Issue::PROPERTY_MISSING(ip, WHAT),
        Some(s) if !s.is_object() => Issue::TYPE_MISMATCH(format!("{ip}/subtrees"), WHAT),
        Some(s) => match s.get("uri") {
            Some(Value::String(u)) => return Some(u.clone()),
            None => Issue::PROPERTY_MISSING(format!("{ip}/subtrees"), WHAT),
            Some(_) => Issue::TYPE_MISMATCH(format!("{ip}/subtrees/uri"), WHAT),
        },
    };
    ctx.push(issue);
    None
}

/// The `implicitTiling` object's rules (scheme, level counts, subtree URI template and the
/// content templates' variables, the walk's limits); returns the scheme, subtree levels,
/// available levels and the subtrees' URI template when they allow a walk.
fn tiling_params(
    ctx: &mut Ctx<'_>,
    it: &Value,
    ip: &str,
    templates: &[(String, String)],
) -> Option<(Scheme, u32, u32, String)> {
    let Some(obj) = it.as_object() else {
        ctx.push(Issue::TYPE_MISMATCH(ip, "implicitTiling must be an object"));
        return None;
    };
    let scheme = match obj.get("subdivisionScheme") {
        Some(Value::String(s)) if s == "QUADTREE" => Some(Scheme::Quadtree),
        Some(Value::String(s)) if s == "OCTREE" => Some(Scheme::Octree),
        Some(s) => {
            ctx.push(Issue::VALUE_NOT_IN_LIST(
                format!("{ip}/subdivisionScheme"),
                format!("{s} is not \"QUADTREE\" or \"OCTREE\""),
            ));
            None
        }
        None => {
            ctx.push(Issue::PROPERTY_MISSING(
                ip.to_string(),
                "'subdivisionScheme' is required",
            ));
            None
        }
    };
    let mut levels = |key: &str| match obj.get(key) {
        None => {
            ctx.push(Issue::PROPERTY_MISSING(
                ip.to_string(),
                format!("'{key}' is required"),
            ));
            None
        }
        Some(v) if !v.is_number() => {
            ctx.push(Issue::TYPE_MISMATCH(
                format!("{ip}/{key}"),
                format!("{key} must be an integer"),
            ));
            None
        }
        Some(v) => match v.as_u64() {
            Some(n) if n >= 1 => Some(n),
            _ => {
                ctx.push(Issue::VALUE_NOT_IN_RANGE(
                    format!("{ip}/{key}"),
                    format!("{key} must be an integer >= 1"),
                ));
                None
            }
        },
    };
    let subtree_levels = levels("subtreeLevels");
    let available_levels = levels("availableLevels");
    let subtrees_uri = subtrees_uri(ctx, obj.get("subtrees"), ip);
    let scheme = scheme?;
    let octree = scheme == Scheme::Octree;
    if let Some(u) = &subtrees_uri {
        template(ctx, u, &format!("{ip}/subtrees/uri"), octree);
    }
    for (p, u) in templates {
        template(ctx, u, p, octree);
    }
    let (Some(sl), Some(al), Some(subtrees_uri)) = (subtree_levels, available_levels, subtrees_uri)
    else {
        return None;
    };
    let arity = scheme.arity();
    let max_level = if octree { 21 } else { 31 };
    if arity
        .checked_pow(sl as u32)
        .is_none_or(|n| n > MAX_CHILD_BITS)
        || al > max_level
    {
        ctx.push(Issue::IMPLICIT_TILING_ERROR(
            ip,
            format!("subtreeLevels {sl} / availableLevels {al} are beyond what this validator walks (N^subtreeLevels <= 2^24, levels <= {max_level})"),
        ));
        return None;
    }
    let (sl, al) = (sl as u32, al as u32);
    Some((scheme, sl, al, subtrees_uri))
}

/// One implicit tileset's walk: what its root fixes, and what the walk has seen so far.
struct Walk<'s> {
    scheme: Scheme,
    /// Subtree levels.
    sl: u32,
    /// Available levels.
    al: u32,
    subtrees_uri: String,
    /// Content templates with their JSON paths.
    templates: Vec<(String, String)>,
    /// The root tile's JSON path.
    path: String,
    volume: Option<Volume>,
    at: Parent,
    schema: &'s Schema,
    /// Geometric error per walked tile (a child's may not exceed its parent's).
    errors: HashMap<TileKey, f64>,
    /// Index in `Ctx::cut` per walked tile.
    walked: HashMap<TileKey, usize>,
    /// Subtree files read so far (resolved), with the subtree root that read each first.
    files: HashMap<std::path::PathBuf, TileKey>,
}

/// One subtree's availabilities, expanded to bits.
struct Available {
    tiles: Vec<bool>,
    layers: Vec<Option<Vec<bool>>>,
    children: Option<Vec<bool>>,
}

/// The implicit tile metadata of one subtree: bounding boxes and geometric errors per row.
struct TileTables {
    table: u32,
    boxes: Option<Vec<f64>>,
    errors: Option<Vec<f64>>,
}

/// Validates an implicit root tile and walks its subtrees; `at` holds the root tile's own
/// geometric error, world transform and refinement, and its parent's place in the walk.
pub(crate) fn validate(
    ctx: &mut Ctx<'_>,
    tile: &Value,
    it: &Value,
    path: &str,
    volume: Option<Volume>,
    at: Parent,
    schema: &Schema,
) {
    let ip = format!("{path}/implicitTiling");
    let templates = root_rules(ctx, tile, path, volume);
    let Some((scheme, sl, al, subtrees_uri)) = tiling_params(ctx, it, &ip, &templates) else {
        return;
    };
    let mut walk = Walk {
        scheme,
        sl,
        al,
        subtrees_uri,
        templates,
        path: path.to_string(),
        volume,
        at,
        schema,
        errors: HashMap::new(),
        walked: HashMap::new(),
        files: HashMap::new(),
    };
    let mut queue = vec![(TileKey::ROOT, true)];
    let mut seen = HashSet::new();
    while let Some((root, is_root)) = queue.pop() {
        if !seen.insert(root) {
            continue;
        }
        if seen.len() > MAX_SUBTREES {
            ctx.push(Issue::IMPLICIT_TILING_ERROR(
                ip.clone(),
                format!("more than {MAX_SUBTREES} subtrees are available; the walk stopped there"),
            ));
            break;
        }
        for child in walk.subtree(ctx, root, is_root) {
            queue.push((child, false));
        }
    }
}

impl Walk<'_> {
    /// Tiles in one subtree.
    fn n_tiles(&self) -> usize {
        tile_count(self.scheme.arity(), self.sl) as usize
    }

    /// Level (relative to the subtree root) and Morton index of a subtree's tile `idx`.
    fn key_of(&self, idx: usize) -> (u32, u64) {
        let arity = self.scheme.arity();
        let mut rl = 0u32;
        while tile_count(arity, rl + 1) as usize <= idx {
            rl += 1;
        }
        let m = (idx - tile_count(arity, rl) as usize) as u64;
        (rl, m)
    }

    /// The absolute key of Morton index `m` at relative level `rl` below subtree `root`.
    fn abs(&self, root: TileKey, rl: u32, m: u64) -> TileKey {
        let (x, y, z) = self.scheme.decode(m);
        TileKey {
            level: root.level + rl,
            x: (root.x << rl) + x,
            y: (root.y << rl) + y,
            z: (root.z << rl) + z,
        }
    }

    /// Validates the subtree rooted at `root` and its available tiles; returns the child
    /// subtrees it marks available.
    fn subtree(&mut self, ctx: &mut Ctx<'_>, root: TileKey, is_root: bool) -> Vec<TileKey> {
        let uri = expand_template(&self.subtrees_uri, root);
        let Some(file) = ctx.resolve(&uri, &format!("{}/implicitTiling/subtrees/uri", self.path))
        else {
            return vec![];
        };
        if let Some(first) = self.files.insert(file.clone(), root) {
            // One file for two subtrees would be walked again below each of its own children.
            let name = |k: TileKey| format!("{}/{}/{}/{}", k.level, k.x, k.y, k.z);
            ctx.push(Issue::IMPLICIT_TILING_ERROR(
                uri,
                format!(
                    "the subtree file of both subtree {} and subtree {}: each subtree needs a \
                     file of its own; walked once",
                    name(first),
                    name(root)
                ),
            ));
            return vec![];
        }
        // Something that is not a regular file (a FIFO, a device) is read below and refused
        // there with its reason; only an absent file is "missing".
        let absent = !ctx.exists(&file)
            && (ctx.memory.is_some()
                || ctx.in_archive(&file)
                || std::fs::symlink_metadata(&file)
                    .is_err_and(|e| e.kind() == std::io::ErrorKind::NotFound));
        if absent {
            if is_root {
                // As Cesium's validator: without its root subtree the implicit root is unusable.
                ctx.push(Issue::TILE_IMPLICIT_ROOT_INVALID(
                    uri,
                    "the root subtree file is missing: the implicit tree cannot be read",
                ));
            } else {
                ctx.push(Issue::SUBTREE_FILE_MISSING(
                    uri,
                    "its parent subtree marks this child subtree available, but there is no file",
                ));
            }
            return vec![];
        }
        let Some(bytes) = ctx.read(&file, &uri) else {
            return vec![];
        };
        let Some((j, bin)) = parse_subtree(ctx, &bytes, &uri) else {
            return vec![];
        };
        let dir_rel = crate::uri::folder_of(&uri);
        let views = check_views(ctx, &j, bin, &uri, &dir_rel);
        let sp = format!("{uri}#");
        let Some(avail) = self.availabilities(ctx, &j, &views, &sp) else {
            return vec![];
        };
        self.tile_rules(ctx, root, &avail, &sp);
        let children = self.child_rules(ctx, root, &avail, &uri, &sp);

        // Property tables.
        let available: Vec<usize> = avail
            .tiles
            .iter()
            .enumerate()
            .filter(|(_, b)| **b)
            .map(|(i, _)| i)
            .collect();
        let mut tables = TileTables {
            table: j.tile_metadata.unwrap_or(0),
            boxes: None,
            errors: None,
        };
        if let Some(t) = j.tile_metadata {
            let semantics = ["TILE_BOUNDING_BOX", "TILE_GEOMETRIC_ERROR"];
            let cols = table_column(
                ctx,
                &j,
                &views,
                self.schema,
                t,
                available.len(),
                &sp,
                &semantics,
            );
            // Columns of the wrong shape were reported by the schema checks; ignore them here.
            tables.boxes = cols[0].clone().filter(|b| b.len() == available.len() * 12);
            tables.errors = cols[1].clone().filter(|e| e.len() == available.len());
        }
        for (c, t) in j.content_metadata.iter().flatten().enumerate() {
            let rows = avail
                .layers
                .get(c)
                .and_then(|l| l.as_ref())
                .map_or(0, |l| l.iter().filter(|b| **b).count());
            table_column(ctx, &j, &views, self.schema, *t, rows, &sp, &[]);
        }
        for (row, &idx) in available.iter().enumerate() {
            self.tile(ctx, root, (row, idx), &avail, &tables, &uri);
        }
        children
    }

    /// Expands the tile, content and child-subtree availabilities (`None`: the tiles' could not
    /// be read, so nothing of the subtree is walked).
    fn availabilities(
        &self,
        ctx: &mut Ctx<'_>,
        j: &SubtreeJson,
        views: &Views,
        sp: &str,
    ) -> Option<Available> {
        let n_tiles = self.n_tiles();
        let tiles = availability(
            ctx,
            &j.tile_availability,
            n_tiles,
            views,
            &format!("{sp}/tileAvailability"),
        )?;
        let mut layers = Vec::new();
        for (c, a) in j.content_availability.iter().enumerate() {
            layers.push(availability(
                ctx,
                a,
                n_tiles,
                views,
                &format!("{sp}/contentAvailability/{c}"),
            ));
        }
        let templates = self.templates.len();
        if layers.len() != templates && !(layers.is_empty() && templates == 0) {
            ctx.push(Issue::SUBTREE_AVAILABILITY_INCONSISTENT(
                format!("{sp}/contentAvailability"),
                format!(
                    "{} content availabilities for {templates} content templates",
                    layers.len(),
                ),
            ));
        }
        let children = availability(
            ctx,
            &j.child_subtree_availability,
            self.scheme.arity().pow(self.sl) as usize,
            views,
            &format!("{sp}/childSubtreeAvailability"),
        );
        Some(Available {
            tiles,
            layers,
            children,
        })
    }

    /// "If a tile is available, its parent tile MUST be available"; content implies tile; no
    /// tile at or beyond `availableLevels`.
    fn tile_rules(&self, ctx: &mut Ctx<'_>, root: TileKey, avail: &Available, sp: &str) {
        let (arity, dims, al) = (self.scheme.arity(), self.scheme.dims(), self.al);
        let tiles = &avail.tiles;
        let mut bad_parent = Vec::new();
        for (idx, _) in tiles.iter().enumerate().filter(|(_, b)| **b) {
            let (rl, m) = self.key_of(idx);
            if rl > 0 && !tiles[tile_count(arity, rl - 1) as usize + (m >> dims) as usize] {
                bad_parent.push(idx);
            }
            if root.level + rl >= al {
                ctx.push(Issue::SUBTREE_AVAILABILITY_INCONSISTENT(
                    format!("{sp}/tileAvailability"),
                    format!(
                        "tile {idx} (level {}) is available but availableLevels is {al}",
                        root.level + rl
                    ),
                ));
                break;
            }
        }
        if let Some(&idx) = bad_parent.first() {
            ctx.push(Issue::SUBTREE_AVAILABILITY_INCONSISTENT(
                format!("{sp}/tileAvailability"),
                format!(
                    "{} available tiles have an unavailable parent; first: tile index {idx}",
                    bad_parent.len()
                ),
            ));
        }
        for (c, layer) in avail.layers.iter().enumerate() {
            let Some(layer) = layer else { continue };
            let orphans = layer.iter().zip(tiles).filter(|(c, t)| **c && !**t).count();
            if orphans > 0 {
                ctx.push(Issue::SUBTREE_AVAILABILITY_INCONSISTENT(
                    format!("{sp}/contentAvailability/{c}"),
                    format!("{orphans} contents are available on unavailable tiles"),
                ));
            }
        }
    }

    /// The child subtrees' rules (parent tile available, within `availableLevels`, no file left
    /// unreferenced); returns the available children to walk.
    fn child_rules(
        &self,
        ctx: &mut Ctx<'_>,
        root: TileKey,
        avail: &Available,
        uri: &str,
        sp: &str,
    ) -> Vec<TileKey> {
        let mut next = Vec::new();
        let Some(children) = &avail.children else {
            return next;
        };
        let (dims, al) = (self.scheme.dims(), self.al);
        let first_last = tile_count(self.scheme.arity(), self.sl - 1) as usize;
        for (m, &set) in children.iter().enumerate() {
            let parent_ok = avail.tiles[first_last + (m >> dims)];
            let key = self.abs(root, self.sl, m as u64);
            if set && !parent_ok {
                ctx.push(Issue::SUBTREE_AVAILABILITY_INCONSISTENT(
                    format!("{sp}/childSubtreeAvailability"),
                    format!("child subtree {m} is available but its parent tile is not"),
                ));
            } else if set && key.level >= al {
                ctx.push(Issue::SUBTREE_AVAILABILITY_INCONSISTENT(
                    format!("{sp}/childSubtreeAvailability"),
                    format!(
                        "child subtree {m} starts at level {} but availableLevels is {al}",
                        key.level
                    ),
                ));
            } else if set {
                next.push(key);
            } else if parent_ok && key.level < al {
                let child_uri = expand_template(&self.subtrees_uri, key);
                if ctx.lookup(&child_uri).is_some_and(|f| f.is_file()) {
                    ctx.push(Issue::SUBTREE_FILE_UNREFERENCED(
                        child_uri,
                        format!(
                            "{uri} marks this child subtree unavailable, so it is never loaded"
                        ),
                    ));
                }
            }
        }
        next
    }

    /// One available tile (`row` in the tile tables, `idx` in the subtree): its geometric error
    /// and volume, its place in the cut, its contents and their quality variants.
    fn tile(
        &mut self,
        ctx: &mut Ctx<'_>,
        root: TileKey,
        (row, idx): (usize, usize),
        avail: &Available,
        tables: &TileTables,
        uri: &str,
    ) {
        let sp = format!("{uri}#");
        let (rl, m) = self.key_of(idx);
        let key = self.abs(root, rl, m);
        let error = match &tables.errors {
            Some(e) => {
                let v = e[row];
                if !(v >= 0.0 && v.is_finite()) {
                    ctx.push(Issue::METADATA_VALUE_INVALID(
                        format!("{sp}/propertyTables/{}", tables.table),
                        format!("TILE_GEOMETRIC_ERROR of tile index {idx} is {v} (must be finite and >= 0)"),
                    ));
                }
                Some(v)
            }
            None => self.at.error.map(|e| e / f64::powi(2.0, key.level as i32)),
        };
        if let (Some(e), Some(parent)) = (error, key.parent().and_then(|p| self.errors.get(&p)))
            && e > *parent
        {
            ctx.push(Issue::TILE_GEOMETRIC_ERRORS_INCONSISTENT(
                format!("{sp}/tileMetadata"),
                format!(
                    "tile {}/{}/{}/{}: geometric error {e} is larger than its parent's {parent}",
                    key.level, key.x, key.y, key.z
                ),
            ));
        }
        if let Some(e) = error {
            self.errors.insert(key, e);
        }
        let octree = self.scheme == Scheme::Octree;
        let tile_volume = match &tables.boxes {
            Some(b) => match parse_box(&b[row * 12..row * 12 + 12]) {
                Ok(v) => Some(v),
                Err(why) => {
                    ctx.push(Issue::METADATA_VALUE_INVALID(
                        format!("{sp}/propertyTables/{}", tables.table),
                        format!("TILE_BOUNDING_BOX of tile index {idx}: {why}"),
                    ));
                    None
                }
            },
            None => self
                .volume
                .map(|v| v.subdivide(octree, key.level, key.x, key.y, key.z)),
        };
        let parent = match key.parent() {
            None => self.at.cut,
            Some(p) => self.walked.get(&p).copied(),
        };
        let world = self.at.world;
        let cut = CutTile {
            path: format!("{uri}#tile {}/{}/{}/{}", key.level, key.x, key.y, key.z),
            parent,
            content: avail
                .layers
                .iter()
                .any(|l| l.as_ref().is_some_and(|l| l[idx])),
            volume: tile_volume,
            world,
            error,
            replace: self.at.replace,
        };
        if let Some(i) = record(ctx, cut) {
            self.walked.insert(key, i);
        }
        for (c, layer) in avail.layers.iter().enumerate() {
            if !layer.as_ref().is_some_and(|l| l[idx]) {
                continue;
            }
            let Some((tp, t)) = self.templates.get(c) else {
                continue;
            };
            let curi = expand_template(t, key);
            content_file(ctx, &curi, tp, tile_volume, world);
            // The tile's other quality variants, declared in the tileset metadata.
            if c == 0 {
                for (name, vt) in ctx.variant_templates.clone() {
                    if &vt != t {
                        let vuri = expand_template(&vt, key);
                        let vp = format!("tileset.json#/metadata/properties/variantUris ({name})");
                        content_file(ctx, &vuri, &vp, tile_volume, world);
                    }
                }
            }
        }
    }
}
