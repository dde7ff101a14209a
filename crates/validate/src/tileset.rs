//! `tileset.json` rules (3D Tiles 1.1 "Tileset", "Tile", "Bounding volumes", "Geometric error",
//! "Transforms", "Refinement"): one function per spec object, each continuing after a failure.

mod archive;
mod external;
mod implicit;

use super::content::validate_glb;
use super::context::{Ctx, MAX_CACHED_CENTRES};
use super::declarations::declarations;
use super::issues::{Issue, Severity};
use super::metadata::entity::entity;
use super::metadata::{Schema, validate_schema};
use super::volume::{Volume, parse_box, parse_region, parse_sphere};
use external::external;
use glam::{DMat3, DMat4};
use serde_json::Value;

/// Reads an array of numbers; reports TYPE_MISMATCH when it is not one.
pub(crate) fn numbers(ctx: &mut Ctx<'_>, v: &Value, path: &str) -> Option<Vec<f64>> {
    let Some(a) = v.as_array() else {
        ctx.push(Issue::TYPE_MISMATCH(path, "expected an array of numbers"));
        return None;
    };
    let out: Option<Vec<f64>> = a.iter().map(Value::as_f64).collect();
    if out.is_none() {
        ctx.push(Issue::ARRAY_ELEMENT_TYPE_MISMATCH(
            path,
            "expected an array of numbers: an element is not a number",
        ));
    }
    out
}

/// Reads a required non-negative number (geometricError and the like).
fn non_negative(ctx: &mut Ctx<'_>, obj: &Value, key: &str, path: &str) -> Option<f64> {
    match obj.get(key) {
        None => {
            ctx.push(Issue::PROPERTY_MISSING(
                path,
                format!("'{key}' is required"),
            ));
            None
        }
        Some(v) => match v.as_f64() {
            None => {
                ctx.push(Issue::TYPE_MISMATCH(
                    format!("{path}/{key}"),
                    format!("'{key}' must be a number"),
                ));
                None
            }
            Some(x) if x < 0.0 => {
                ctx.push(Issue::VALUE_NOT_IN_RANGE(
                    format!("{path}/{key}"),
                    format!("{key} {x} is negative"),
                ));
                Some(x)
            }
            Some(x) => Some(x),
        },
    }
}

/// Validates a `boundingVolume` object: exactly one valid box, region or sphere.
pub(crate) fn bounding_volume(ctx: &mut Ctx<'_>, v: &Value, path: &str) -> Option<Volume> {
    let Some(obj) = v.as_object() else {
        ctx.push(Issue::TYPE_MISMATCH(
            path,
            "boundingVolume must be an object",
        ));
        return None;
    };
    let mut found = None;
    let mut kinds = 0;
    for (key, parse, len) in [
        ("box", parse_box as fn(&[f64]) -> Result<Volume, String>, 12),
        ("region", parse_region, 6),
        ("sphere", parse_sphere, 4),
    ] {
        let Some(val) = obj.get(key) else { continue };
        kinds += 1;
        let p = format!("{path}/{key}");
        let Some(nums) = numbers(ctx, val, &p) else {
            continue;
        };
        if nums.len() != len {
            ctx.push(Issue::ARRAY_LENGTH_MISMATCH(
                p,
                format!("a {key} has {len} numbers, not {}", nums.len()),
            ));
            continue;
        }
        match parse(&nums) {
            Ok(vol) => found = found.or(Some(vol)),
            Err(why) => ctx.push(Issue::BOUNDING_VOLUME_INVALID(p, why)),
        }
    }
    if let Some(s2) = obj
        .get("extensions")
        .and_then(|e| e.get("3DTILES_bounding_volume_S2"))
    {
        kinds += 1;
        s2_volume(
            ctx,
            s2,
            &format!("{path}/extensions/3DTILES_bounding_volume_S2"),
        );
    }
    if kinds == 0 {
        ctx.push(Issue::BOUNDING_VOLUME_INVALID(
            path,
            "a bounding volume needs a box, a region, a sphere or an S2 cell",
        ));
    }
    found
}

/// Validates the `3DTILES_bounding_volume_S2` object: a hexadecimal cell token and heights
/// (its geometry is not used for containment checks).
fn s2_volume(ctx: &mut Ctx<'_>, v: &Value, path: &str) {
    match v.get("token").map(Value::as_str) {
        Some(Some(t))
            if (1..=16).contains(&t.len()) && t.chars().all(|c| c.is_ascii_hexdigit()) => {}
        Some(Some(t)) => ctx.push(Issue::BOUNDING_VOLUME_INVALID(
            format!("{path}/token"),
            format!("S2 token '{t}' is not 1 to 16 hexadecimal digits"),
        )),
        Some(None) => ctx.push(Issue::TYPE_MISMATCH(
            format!("{path}/token"),
            "the S2 token must be a string",
        )),
        None => ctx.push(Issue::PROPERTY_MISSING(
            path,
            "an S2 volume needs a string 'token'",
        )),
    }
    let mut h = |k: &str| match v.get(k).map(Value::as_f64) {
        Some(Some(x)) => Some(x),
        Some(None) => {
            ctx.push(Issue::TYPE_MISMATCH(
                format!("{path}/{k}"),
                format!("the S2 {k} must be a number"),
            ));
            None
        }
        None => {
            ctx.push(Issue::PROPERTY_MISSING(
                path,
                format!("an S2 volume needs a number '{k}'"),
            ));
            None
        }
    };
    if let (Some(lo), Some(hi)) = (h("minimumHeight"), h("maximumHeight"))
        && lo > hi
    {
        ctx.push(Issue::BOUNDING_VOLUME_INVALID(
            path,
            format!("minimumHeight {lo} is greater than maximumHeight {hi}"),
        ));
    }
}

/// Validates a tile `transform`; returns it when usable.
fn transform(ctx: &mut Ctx<'_>, v: &Value, path: &str) -> Option<DMat4> {
    let nums = numbers(ctx, v, path)?;
    if nums.len() != 16 {
        ctx.push(Issue::ARRAY_LENGTH_MISMATCH(
            path,
            format!("a transform has 16 numbers, not {}", nums.len()),
        ));
        return None;
    }
    let m = DMat4::from_cols_slice(&nums);
    if !m.is_finite() {
        ctx.push(Issue::TRANSFORM_INVALID(
            path,
            "the transform holds a non-finite number",
        ));
        return None;
    }
    // Column-major: the last row is elements 3, 7, 11, 15.
    if [nums[3], nums[7], nums[11], nums[15]] != [0.0, 0.0, 0.0, 1.0] {
        ctx.push(Issue::TRANSFORM_NOT_AFFINE(
            path,
            format!(
                "the last row is ({}, {}, {}, {}), not (0, 0, 0, 1): the transform must be affine",
                nums[3], nums[7], nums[11], nums[15]
            ),
        ));
        return None;
    }
    if DMat3::from_mat4(m).determinant() == 0.0 {
        ctx.push(Issue::TRANSFORM_SINGULAR(
            path,
            "the transform's 3x3 part has determinant 0: content collapses (allowed, but invisible)",
        ));
    }
    Some(m)
}

/// Where a tile sits: its parent's geometric error, world transform and place in the walk.
#[derive(Clone, Copy)]
pub(crate) struct Parent {
    /// Parent's geometric error.
    pub error: Option<f64>,
    /// World transform of the parent (tileset frame to ECEF for georeferenced tilesets).
    pub world: DMat4,
    /// The parent's index in `Ctx::cut` (`None` above the root).
    pub cut: Option<usize>,
    /// The parent and its ancestors refine by REPLACE (true above the root).
    pub replace: bool,
}

/// Checks a tile's `refine`; false when it says ADD (true for REPLACE, inherited or unreadable).
fn refine_replaces(ctx: &mut Ctx<'_>, refine: Option<&Value>, path: &str, is_root: bool) -> bool {
    match refine {
        Some(Value::String(r)) if r == "ADD" || r == "REPLACE" => r == "REPLACE",
        Some(Value::String(r))
            if r.eq_ignore_ascii_case("ADD") || r.eq_ignore_ascii_case("REPLACE") =>
        {
            ctx.push(Issue::TILE_REFINE_WRONG_CASE(
                format!("{path}/refine"),
                format!(
                    "refine '{r}' must be upper case: '{}'",
                    r.to_ascii_uppercase()
                ),
            ));
            r.eq_ignore_ascii_case("REPLACE")
        }
        Some(Value::String(r)) => {
            ctx.push(Issue::VALUE_NOT_IN_LIST(
                format!("{path}/refine"),
                format!("refine '{r}' is not ADD or REPLACE"),
            ));
            true
        }
        Some(_) => {
            ctx.push(Issue::TYPE_MISMATCH(
                format!("{path}/refine"),
                "refine must be a string",
            ));
            true
        }
        None => {
            if is_root {
                ctx.push(Issue::TILE_REFINE_MISSING_IN_ROOT(
                    path,
                    "the root tile must say refine ADD or REPLACE",
                ));
            }
            true
        }
    }
}

/// Validates one tile and its subtree of explicit children.
pub(crate) fn tile(
    ctx: &mut Ctx<'_>,
    v: &Value,
    path: &str,
    parent: Parent,
    is_root: bool,
    schema: &Schema,
    depth: usize,
) {
    let Some(obj) = v.as_object() else {
        if is_root {
            ctx.push(Issue::TYPE_MISMATCH(path, "a tile must be an object"));
        } else {
            ctx.push(Issue::ARRAY_ELEMENT_TYPE_MISMATCH(
                path,
                "an element of children is not a tile object",
            ));
        }
        return;
    };
    let volume = match obj.get("boundingVolume") {
        Some(bv) => bounding_volume(ctx, bv, &format!("{path}/boundingVolume")),
        None => {
            ctx.push(Issue::PROPERTY_MISSING(
                path,
                "'boundingVolume' is required",
            ));
            None
        }
    };
    let error = non_negative(ctx, v, "geometricError", path);
    // "the geometricError of a tile SHOULD NOT be larger than the one of its parent" (warning).
    if let (Some(e), Some(p)) = (error, parent.error)
        && e > p
    {
        ctx.push(Issue::TILE_GEOMETRIC_ERRORS_INCONSISTENT(
            format!("{path}/geometricError"),
            format!("geometricError {e} is larger than the parent's {p}"),
        ));
    }
    let replace = refine_replaces(ctx, obj.get("refine"), path, is_root) && parent.replace;
    let local = obj
        .get("transform")
        .and_then(|t| transform(ctx, t, &format!("{path}/transform")))
        .unwrap_or(DMat4::IDENTITY);
    let world = parent.world * local;

    if let Some(vrv) = obj.get("viewerRequestVolume") {
        bounding_volume(ctx, vrv, &format!("{path}/viewerRequestVolume"));
    }
    if let Some(m) = obj.get("metadata")
        && !obj.contains_key("implicitTiling")
    {
        entity(ctx, schema, m, &format!("{path}/metadata"));
    }
    if obj.contains_key("content") && obj.contains_key("contents") {
        ctx.push(Issue::ONE_OF_ERROR(
            path,
            "a tile has either content or contents, not both",
        ));
    }
    let has_content = obj.contains_key("content") || obj.contains_key("contents");
    let mut here = None;
    if let Some(it) = obj.get("implicitTiling") {
        let at = Parent {
            error,
            world,
            cut: parent.cut,
            replace,
        };
        implicit::validate(ctx, v, it, path, volume, at, schema);
    } else {
        here = super::cut::record(
            ctx,
            super::cut::CutTile {
                path: path.to_string(),
                parent: parent.cut,
                content: has_content,
                volume,
                world,
                error,
                replace,
            },
        );
        let contents: Vec<(String, &Value)> = match (obj.get("content"), obj.get("contents")) {
            (Some(c), _) => vec![(format!("{path}/content"), c)],
            (None, Some(Value::Array(cs))) => cs
                .iter()
                .enumerate()
                .map(|(i, c)| (format!("{path}/contents/{i}"), c))
                .collect(),
            (None, Some(_)) => {
                ctx.push(Issue::TYPE_MISMATCH(
                    format!("{path}/contents"),
                    "contents must be an array of content objects",
                ));
                vec![]
            }
            _ => vec![],
        };
        for (cp, c) in contents {
            content(ctx, c, &cp, volume, world, schema);
        }
    }
    if let Some(children) = obj.get("children") {
        let Some(children) = children.as_array() else {
            ctx.push(Issue::TYPE_MISMATCH(
                format!("{path}/children"),
                "children must be an array",
            ));
            return;
        };
        if children.is_empty() {
            // Read as a leaf; the schema's minItems asks leaves to leave children out.
            ctx.push(Issue::ARRAY_LENGTH_UNEXPECTED(
                format!("{path}/children"),
                "an empty children array: a leaf tile should omit children",
            ));
        }
        if depth > 256 {
            ctx.push(Issue::VALUE_NOT_IN_RANGE(
                path,
                "tile tree deeper than 256 levels: not descended",
            ));
            return;
        }
        for (i, c) in children.iter().enumerate() {
            tile(
                ctx,
                c,
                &format!("{path}/children/{i}"),
                Parent {
                    error,
                    world,
                    cut: here,
                    replace,
                },
                false,
                schema,
                depth + 1,
            );
        }
    }
}

/// Validates one content object of an explicit tile: its bounding volume (inside the tile's),
/// metadata, group, and the file its URI names.
fn content(
    ctx: &mut Ctx<'_>,
    c: &Value,
    cp: &str,
    volume: Option<Volume>,
    world: DMat4,
    schema: &Schema,
) {
    if !c.is_object() {
        ctx.push(Issue::TYPE_MISMATCH(cp, "a content must be an object"));
        return;
    }
    let cvol = c
        .get("boundingVolume")
        .and_then(|b| bounding_volume(ctx, b, &format!("{cp}/boundingVolume")));
    if let (Some(outer), Some(inner)) = (volume, cvol)
        && let Some(excess) = outer.contains(&inner)
        && excess > 1e-6
    {
        ctx.push(Issue::CONTENT_BOUNDING_VOLUME_NOT_IN_TILE(
            format!("{cp}/boundingVolume"),
            format!(
                "the content bounding volume reaches outside the tile's (by {excess:.3e} of its size)"
            ),
        ));
    }
    if let Some(m) = c.get("metadata") {
        entity(ctx, schema, m, &format!("{cp}/metadata"));
    }
    match c.get("group") {
        None => {}
        Some(g) => match g.as_u64() {
            Some(i) if (i as usize) < schema.groups => {}
            Some(i) => ctx.push(Issue::VALUE_NOT_IN_RANGE(
                format!("{cp}/group"),
                format!(
                    "group {i} does not exist (the tileset has {} groups)",
                    schema.groups
                ),
            )),
            None => ctx.push(Issue::TYPE_MISMATCH(
                format!("{cp}/group"),
                "group must be a non-negative integer index into the tileset's groups",
            )),
        },
    }
    let Some(uri) = c.get("uri") else {
        ctx.push(Issue::PROPERTY_MISSING(cp, "content 'uri' is required"));
        return;
    };
    let Some(uri) = uri.as_str() else {
        ctx.push(Issue::TYPE_MISMATCH(
            format!("{cp}/uri"),
            "uri must be a string",
        ));
        return;
    };
    content_file(ctx, uri, &format!("{cp}/uri"), cvol.or(volume), world);
}

/// What a JSON content is.
enum JsonContent {
    /// An external tileset (also anything unreadable: its validation reports why).
    Tileset,
    /// glTF JSON (`.gltf`, or top-level glTF arrays such as meshes and buffers).
    Gltf,
    /// GeoJSON (`.geojson`, or a top-level GeoJSON `type`), as `MAXAR_content_geojson` uses.
    GeoJson,
}

/// The top-level members that tell JSON contents apart; the rest is skipped unparsed.
#[derive(serde::Deserialize)]
#[allow(non_snake_case)]
struct JsonTop {
    root: Option<serde::de::IgnoredAny>,
    geometricError: Option<serde::de::IgnoredAny>,
    asset: Option<serde::de::IgnoredAny>,
    meshes: Option<serde::de::IgnoredAny>,
    scenes: Option<serde::de::IgnoredAny>,
    nodes: Option<serde::de::IgnoredAny>,
    buffers: Option<serde::de::IgnoredAny>,
    accessors: Option<serde::de::IgnoredAny>,
    bufferViews: Option<serde::de::IgnoredAny>,
    #[serde(rename = "type")]
    kind: Option<Value>,
}

/// Tells an external tileset from glTF JSON and GeoJSON by its name and top-level members
/// (read without building the document: an external tileset is parsed once, by its own check).
fn json_content_kind(bytes: &[u8], lower_uri: &str) -> JsonContent {
    const GEOJSON_TYPES: [&str; 9] = [
        "FeatureCollection",
        "Feature",
        "Point",
        "MultiPoint",
        "LineString",
        "MultiLineString",
        "Polygon",
        "MultiPolygon",
        "GeometryCollection",
    ];
    if lower_uri.ends_with(".gltf") {
        return JsonContent::Gltf;
    }
    // Anything unreadable here (bad syntax, past serde_json's 128 levels, duplicate members) is
    // left to the external tileset's own bounded parse, which reports it.
    let Ok(top) = serde_json::from_slice::<JsonTop>(bytes) else {
        return JsonContent::Tileset;
    };
    if top.root.is_some() || top.geometricError.is_some() {
        return JsonContent::Tileset;
    }
    let gltf = [
        &top.meshes,
        &top.scenes,
        &top.nodes,
        &top.buffers,
        &top.accessors,
        &top.bufferViews,
    ];
    if gltf.iter().any(|m| m.is_some()) {
        return JsonContent::Gltf;
    }
    let geojson_type = top
        .kind
        .as_ref()
        .and_then(Value::as_str)
        .is_some_and(|t| GEOJSON_TYPES.contains(&t));
    if geojson_type || (lower_uri.ends_with(".geojson") && top.asset.is_none()) {
        return JsonContent::GeoJson;
    }
    JsonContent::Tileset
}

/// Validates one content file and that its splats lie inside `volume`.
pub(crate) fn content_file(
    ctx: &mut Ctx<'_>,
    uri: &str,
    path: &str,
    volume: Option<Volume>,
    world: DMat4,
) {
    let lower = uri
        .split(['?', '#'])
        .next()
        .unwrap_or("")
        .to_ascii_lowercase();
    if ctx.gltf_undeclared && (lower.ends_with(".glb") || lower.ends_with(".gltf")) {
        ctx.gltf_undeclared = false;
        ctx.push(Issue::EXTENSION_FOUND_BUT_NOT_USED(
            path,
            "a glTF content in a 3D Tiles 1.0 tileset needs 3DTILES_content_gltf in extensionsUsed",
        ));
    }
    let Some(file) = ctx.resolve(uri, path) else {
        return;
    };
    if let Some(cached) = ctx.contents.get(&file) {
        // Checked already from another tile: only its place in this tile's volume is new.
        if let (Some(geom), Some(volume)) = (cached.clone(), volume) {
            containment(ctx, uri, &geom, &volume, &world);
        }
        return;
    }
    ctx.contents.insert(file.clone(), None);
    let Some(bytes) = ctx.read(&file, uri) else {
        return;
    };
    let json = super::json::is_object_text(&bytes).then(|| json_content_kind(&bytes, &lower));
    if let Some(JsonContent::Tileset) = json {
        external(ctx, &file, &bytes, uri, path, world);
        return;
    }
    if bytes.starts_with(b"PK\x03\x04") {
        folded(ctx, uri, path, |ctx| {
            archive::archive(ctx, &file, &bytes, uri, path, world);
        });
        return;
    }
    let geom = folded(ctx, uri, path, |ctx| content_data(ctx, &bytes, uri, json));
    drop(bytes);
    let Some(geom) = geom else { return };
    let geom = std::rc::Rc::new(geom);
    if ctx.cached_centres + geom.centres.len() <= MAX_CACHED_CENTRES {
        ctx.cached_centres += geom.centres.len();
        ctx.contents.insert(file, Some(geom.clone()));
    }
    let Some(volume) = volume else { return };
    containment(ctx, uri, &geom, &volume, &world);
}

/// Checks one content's own data (everything but an external tileset, which
/// [`external`] checks): a glb's splat geometry comes back for the containment check.
fn content_data(
    ctx: &mut Ctx<'_>,
    bytes: &[u8],
    uri: &str,
    json: Option<JsonContent>,
) -> Option<super::context::ContentGeom> {
    if let Some(kind) = json {
        match kind {
            JsonContent::Gltf => {
                let extent = ctx.opts.check_extent;
                return super::content::validate_gltf_json(ctx, bytes, uri, extent);
            }
            JsonContent::GeoJson => ctx.push(Issue::CONTENT_DATA_NOT_CHECKED(
                uri,
                "a GeoJSON content (MAXAR_content_geojson): not validated",
            )),
            JsonContent::Tileset => {}
        }
        return None;
    }
    if [&b"b3dm"[..], b"i3dm", b"pnts", b"cmpt"]
        .iter()
        .any(|m| bytes.starts_with(m))
    {
        super::legacy::legacy_content(ctx, bytes, uri);
        return None;
    }
    let extent = ctx.opts.check_extent;
    validate_glb(ctx, bytes, uri, extent)
}

/// Runs `check` on one content with the issues set aside: what it finds becomes the causes of
/// one CONTENT_VALIDATION_* issue on the referring tile (`path`), as the reference validator
/// reports a content's issues.
fn folded<R>(ctx: &mut Ctx<'_>, uri: &str, path: &str, check: impl FnOnce(&mut Ctx<'_>) -> R) -> R {
    let saved = std::mem::take(&mut ctx.issues);
    let out = check(ctx);
    let causes = std::mem::replace(&mut ctx.issues, saved);
    let summary = |what: &str| format!("content '{uri}' has {what} (see causes)");
    let issue = match causes.iter().map(|i| i.severity).min() {
        None => return out,
        Some(Severity::Error) => Issue::CONTENT_VALIDATION_ERROR(path, summary("errors")),
        Some(Severity::Warning) => Issue::CONTENT_VALIDATION_WARNING(path, summary("warnings")),
        Some(Severity::Info) => Issue::CONTENT_VALIDATION_INFO(path, summary("notes")),
    };
    // Pushed directly: its causes were already counted against the issue limit.
    ctx.issues.push(issue.with_causes(causes));
    out
}

/// Checks that splat centres (and, with --check-extent, 3-sigma ellipsoids) lie in `volume`.
pub(crate) fn containment(
    ctx: &mut Ctx<'_>,
    uri: &str,
    geom: &super::context::ContentGeom,
    volume: &Volume,
    world: &DMat4,
) {
    // Tolerance: glb positions are f32 relative to the tile; boxes are f64.
    const EPS: f64 = 1e-5;
    let mut outside = 0usize;
    let mut first = None;
    let mut worst = 0.0f64;
    for (i, p) in geom.centres.iter().enumerate() {
        let e = volume.excess(*p, world, |_| 0.0);
        if e > EPS {
            outside += 1;
            first.get_or_insert(i);
            worst = worst.max(e);
        }
    }
    if let Some(i) = first {
        ctx.push(Issue::CONTENT_OUTSIDE_BOUNDING_VOLUME(
            uri,
            format!(
                "{outside} of {} splat centres lie outside the tile's bounding volume; first: splat {i} at {:?} (by {worst:.3e} of the volume's size)",
                geom.centres.len(),
                geom.centres[i].to_array()
            ),
        ));
    }
    if let Some(shapes) = &geom.shapes {
        let mut out = 0usize;
        for (p, s) in geom.centres.iter().zip(shapes) {
            let reach = |u: glam::DVec3| 3.0 * (s.transpose() * u).length();
            if volume.excess(*p, world, reach) > EPS {
                out += 1;
            }
        }
        if out > 0 {
            ctx.push(Issue::CONTENT_EXTENT_OUTSIDE_BOUNDING_VOLUME(
                uri,
                format!(
                    "{out} of {} splats reach outside the tile's bounding volume at 3 sigma",
                    shapes.len()
                ),
            ));
        }
    }
}

/// Validates a whole tileset JSON document; `world` places its root (identity for the top
/// tileset, the referring tile's transform for an external one).
pub(crate) fn tileset(ctx: &mut Ctx<'_>, v: &Value, world: DMat4) {
    let path = ctx.at("");
    let path = path.as_str();
    if !v.is_object() {
        ctx.push(Issue::TYPE_MISMATCH(
            path,
            "a tileset JSON must hold an object",
        ));
        return;
    }
    ctx.variant_templates = variant_templates(v);
    asset(ctx, v, path);
    if let Some(p) = v.get("properties") {
        legacy_properties(ctx, p, &format!("{path}/properties"));
    }
    let error = non_negative(ctx, v, "geometricError", path);
    let declared = declarations(ctx, v);
    let outer_below = std::mem::take(&mut ctx.found_below);
    if v.get("schema").is_some() && v.get("schemaUri").is_some() {
        ctx.push(Issue::ONE_OF_ERROR(
            path,
            "a tileset has either schema or schemaUri, not both",
        ));
    }
    let mut schema = match (v.get("schema"), v.get("schemaUri")) {
        (Some(s), _) => validate_schema(ctx, s, &format!("{path}/schema")),
        (None, Some(Value::String(uri))) => {
            let p = format!("{path}/schemaUri");
            let bytes = ctx.resolve(uri, &p).and_then(|f| ctx.read(&f, uri));
            match bytes.and_then(|b| super::json::parse(ctx, &b, uri)) {
                Some(s) => validate_schema(ctx, &s, &format!("{uri}#")),
                None => Schema {
                    present: true,
                    ..Schema::default()
                },
            }
        }
        (None, Some(_)) => {
            ctx.push(Issue::TYPE_MISMATCH(
                format!("{path}/schemaUri"),
                "schemaUri must be a string",
            ));
            Schema::default()
        }
        _ => Schema::default(),
    };
    match v.get("groups") {
        None => {}
        Some(Value::Array(groups)) => {
            schema.groups = groups.len();
            for (i, g) in groups.iter().enumerate() {
                entity(ctx, &schema, g, &format!("{path}/groups/{i}"));
            }
        }
        Some(_) => ctx.push(Issue::TYPE_MISMATCH(
            format!("{path}/groups"),
            "groups must be an array of metadata entities",
        )),
    }
    if let Some(m) = v.get("metadata") {
        entity(ctx, &schema, m, &format!("{path}/metadata"));
    }
    if let Some(st) = v.get("statistics") {
        statistics(ctx, &schema, st, &format!("{path}/statistics"));
    }
    match v.get("root") {
        None => ctx.push(Issue::PROPERTY_MISSING(path, "'root' is required")),
        Some(root) => {
            // An external tileset walked from this one's contents has its own tree.
            let outer = std::mem::take(&mut ctx.cut);
            let outer_truncated = std::mem::take(&mut ctx.cut_truncated);
            let at = Parent {
                error,
                world,
                cut: None,
                replace: true,
            };
            tile(ctx, root, &format!("{path}/root"), at, true, &schema, 0);
            let tiles = std::mem::replace(&mut ctx.cut, outer);
            super::cut::check(ctx, &tiles);
            ctx.cut_truncated = outer_truncated;
        }
    }
    let below = std::mem::replace(&mut ctx.found_below, outer_below);
    super::declarations::unfound(ctx, &declared, &below);
    // What this tileset and those below it use, for the tileset that refers to this one.
    ctx.found_below
        .extend(declared.found.into_iter().chain(below));
}

/// Validates `asset`: an object with a string `version` ("1.0" or "1.1") and an optional
/// string `tilesetVersion`.
fn asset(ctx: &mut Ctx<'_>, v: &Value, path: &str) {
    let Some(a) = v.get("asset") else {
        ctx.push(Issue::PROPERTY_MISSING(path, "'asset' is required"));
        return;
    };
    if !a.is_object() {
        ctx.push(Issue::TYPE_MISMATCH(
            format!("{path}/asset"),
            "asset must be an object",
        ));
        return;
    }
    match a.get("version") {
        None => ctx.push(Issue::PROPERTY_MISSING(
            format!("{path}/asset"),
            "'version' is required",
        )),
        Some(Value::String(s)) if s == "1.0" || s == "1.1" => {}
        Some(Value::String(s)) => ctx.push(Issue::ASSET_VERSION_UNKNOWN(
            format!("{path}/asset/version"),
            format!("version '{s}' is neither 1.0 nor 1.1"),
        )),
        Some(_) => ctx.push(Issue::TYPE_MISMATCH(
            format!("{path}/asset/version"),
            "version must be a string",
        )),
    }
    if let Some(tv) = a.get("tilesetVersion")
        && !tv.is_string()
    {
        ctx.push(Issue::TYPE_MISMATCH(
            format!("{path}/asset/tilesetVersion"),
            "tilesetVersion must be a string",
        ));
    }
}

/// Validates the legacy 3D Tiles 1.0 `properties`: each entry has numbers `minimum` <= `maximum`.
fn legacy_properties(ctx: &mut Ctx<'_>, v: &Value, path: &str) {
    let Some(props) = v.as_object() else {
        ctx.push(Issue::TYPE_MISMATCH(path, "properties must be an object"));
        return;
    };
    for (name, p) in props {
        let pp = format!("{path}/{name}");
        if !p.is_object() {
            ctx.push(Issue::TYPE_MISMATCH(
                pp,
                "a properties entry must be an object with minimum and maximum",
            ));
            continue;
        }
        let mut bound = |key: &str| match p.get(key) {
            None => {
                ctx.push(Issue::PROPERTY_MISSING(
                    pp.clone(),
                    format!("'{key}' is required"),
                ));
                None
            }
            Some(x) => {
                if x.as_f64().is_none() {
                    ctx.push(Issue::TYPE_MISMATCH(
                        format!("{pp}/{key}"),
                        format!("{key} must be a number"),
                    ));
                }
                x.as_f64()
            }
        };
        if let (Some(lo), Some(hi)) = (bound("minimum"), bound("maximum"))
            && lo > hi
        {
            ctx.push(Issue::VALUE_NOT_IN_RANGE(
                format!("{pp}/minimum"),
                format!("minimum {lo} is greater than maximum {hi}"),
            ));
        }
    }
}

/// Validates `statistics`: its classes and their properties exist in the schema.
fn statistics(ctx: &mut Ctx<'_>, schema: &Schema, v: &Value, path: &str) {
    let Some(classes) = v.get("classes").and_then(Value::as_object) else {
        ctx.push(Issue::TYPE_MISMATCH(
            format!("{path}/classes"),
            "statistics needs an object 'classes'",
        ));
        return;
    };
    if classes.is_empty() {
        ctx.push(Issue::ARRAY_LENGTH_MISMATCH(
            format!("{path}/classes"),
            "statistics classes, when present, must name at least one class",
        ));
    }
    for (cname, c) in classes {
        let cp = format!("{path}/classes/{cname}");
        if !c.is_object() {
            ctx.push(Issue::TYPE_MISMATCH(
                cp,
                "a class's statistics must be an object",
            ));
            continue;
        }
        if c.get("properties")
            .and_then(Value::as_object)
            .is_some_and(|p| p.is_empty())
        {
            ctx.push(Issue::ARRAY_LENGTH_MISMATCH(
                format!("{cp}/properties"),
                "statistics properties, when present, must name at least one property",
            ));
        }
        let Some(props) = schema.classes.get(cname) else {
            ctx.push(Issue::METADATA_CLASS_UNKNOWN(
                cp,
                format!("statistics for class '{cname}', which the schema does not define"),
            ));
            continue;
        };
        if let Some(ps) = c.get("properties").and_then(Value::as_object) {
            for (pname, st) in ps {
                if !props.contains_key(pname) {
                    ctx.push(Issue::METADATA_PROPERTY_UNKNOWN(
                        format!("{cp}/properties/{pname}"),
                        format!("class '{cname}' has no property '{pname}'"),
                    ));
                    continue;
                }
                let num = |k: &str| st.get(k).and_then(Value::as_f64);
                if let (Some(lo), Some(hi)) = (num("min"), num("max"))
                    && lo > hi
                {
                    ctx.push(Issue::VALUE_NOT_IN_RANGE(
                        format!("{cp}/properties/{pname}/min"),
                        format!("statistics min {lo} is greater than max {hi}"),
                    ));
                }
            }
        }
    }
}

/// Written quality variants declared by a `splatVariants` tileset metadata entity: (name, URI
/// template) pairs, skipping variants whose template is empty (not written).
fn variant_templates(v: &Value) -> Vec<(String, String)> {
    let Some(m) = v
        .get("metadata")
        .filter(|m| m.get("class").and_then(Value::as_str) == Some("splatVariants"))
    else {
        return vec![];
    };
    let props = &m["properties"];
    let names = props["variantNames"].as_array();
    let uris = props["variantUris"].as_array();
    match (names, uris) {
        (Some(n), Some(u)) => n
            .iter()
            .zip(u)
            .filter_map(|(n, u)| Some((n.as_str()?.to_string(), u.as_str()?.to_string())))
            .filter(|(_, u)| !u.is_empty())
            .collect(),
        _ => vec![],
    }
}
