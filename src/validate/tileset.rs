//! `tileset.json` rules (3D Tiles 1.1 "Tileset", "Tile", "Bounding volumes", "Geometric error",
//! "Transforms", "Refinement"): one function per spec object, each continuing after a failure.

use super::content::validate_glb;
use super::context::Ctx;
use super::implicit;
use super::issues::Issue;
use super::metadata::{Schema, validate_schema};
use super::volume::{Volume, parse_box, parse_region, parse_sphere};
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
        ctx.push(Issue::TYPE_MISMATCH(path, "expected an array of numbers"));
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
    if kinds == 0 {
        ctx.push(Issue::BOUNDING_VOLUME_INVALID(
            path,
            "a bounding volume needs a box, a region or a sphere",
        ));
    }
    found
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
    let det = DMat3::from_mat4(m).determinant();
    if !m.is_finite() || det == 0.0 || !det.is_finite() {
        ctx.push(Issue::TRANSFORM_INVALID(
            path,
            "the transform is not invertible (its 3x3 part has determinant 0)",
        ));
        return None;
    }
    Some(m)
}

/// Where a tile sits: its parent's geometric error and world transform.
#[derive(Clone, Copy)]
pub(crate) struct Parent {
    /// Parent's geometric error.
    pub error: Option<f64>,
    /// World transform of the parent (tileset frame to ECEF for georeferenced tilesets).
    pub world: DMat4,
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
        ctx.push(Issue::TYPE_MISMATCH(path, "a tile must be an object"));
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
    match obj.get("refine") {
        Some(Value::String(r)) if r == "ADD" || r == "REPLACE" => {}
        Some(Value::String(r)) => ctx.push(Issue::VALUE_NOT_IN_LIST(
            format!("{path}/refine"),
            format!("refine '{r}' is not ADD or REPLACE"),
        )),
        Some(_) => ctx.push(Issue::TYPE_MISMATCH(
            format!("{path}/refine"),
            "refine must be a string",
        )),
        None if is_root => ctx.push(Issue::TILE_REFINE_MISSING_IN_ROOT(
            path,
            "the root tile must say refine ADD or REPLACE",
        )),
        None => {}
    }
    let local = obj
        .get("transform")
        .and_then(|t| transform(ctx, t, &format!("{path}/transform")))
        .unwrap_or(DMat4::IDENTITY);
    let world = parent.world * local;

    if let Some(it) = obj.get("implicitTiling") {
        implicit::validate(ctx, v, it, path, volume, world, error, schema);
    } else {
        let contents: Vec<(String, &Value)> = match (obj.get("content"), obj.get("contents")) {
            (Some(c), _) => vec![(format!("{path}/content"), c)],
            (None, Some(Value::Array(cs))) => cs
                .iter()
                .enumerate()
                .map(|(i, c)| (format!("{path}/contents/{i}"), c))
                .collect(),
            _ => vec![],
        };
        for (cp, c) in contents {
            let cvol = c
                .get("boundingVolume")
                .and_then(|b| bounding_volume(ctx, b, &format!("{cp}/boundingVolume")));
            let Some(uri) = c.get("uri") else {
                ctx.push(Issue::PROPERTY_MISSING(cp, "content 'uri' is required"));
                continue;
            };
            let Some(uri) = uri.as_str() else {
                ctx.push(Issue::TYPE_MISMATCH(
                    format!("{cp}/uri"),
                    "uri must be a string",
                ));
                continue;
            };
            content_file(ctx, uri, &format!("{cp}/uri"), volume.or(cvol), world);
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
                Parent { error, world },
                false,
                schema,
                depth + 1,
            );
        }
    }
}

/// Validates one content file and that its splats lie inside `volume`.
pub(crate) fn content_file(
    ctx: &mut Ctx<'_>,
    uri: &str,
    path: &str,
    volume: Option<Volume>,
    world: DMat4,
) {
    let Some(file) = ctx.resolve(uri, path) else {
        return;
    };
    let Some(bytes) = ctx.read(&file, uri) else {
        return;
    };
    let other_format = [&b"b3dm"[..], b"i3dm", b"pnts", b"cmpt", b"{"]
        .iter()
        .any(|m| bytes.starts_with(m));
    if other_format && !uri.to_ascii_lowercase().ends_with(".glb") {
        ctx.push(Issue::CONTENT_DATA_NOT_CHECKED(
            uri,
            "content is not a glb (b3dm, i3dm, pnts, cmpt or JSON); only glb contents are validated",
        ));
        return;
    }
    let extent = ctx.opts.check_extent;
    let Some(geom) = validate_glb(ctx, &bytes, uri, extent) else {
        return;
    };
    let Some(volume) = volume else { return };
    containment(ctx, uri, &geom, &volume, &world);
}

/// Checks that splat centres (and, with --check-extent, 3-sigma ellipsoids) lie in `volume`.
pub(crate) fn containment(
    ctx: &mut Ctx<'_>,
    uri: &str,
    geom: &super::content::ContentGeom,
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

/// Validates the whole `tileset.json` document.
pub(crate) fn tileset(ctx: &mut Ctx<'_>, v: &Value) {
    let path = "tileset.json#";
    if !v.is_object() {
        ctx.push(Issue::TYPE_MISMATCH(
            path,
            "tileset.json must hold an object",
        ));
        return;
    }
    ctx.variant_templates = variant_templates(v);
    match v.get("asset") {
        None => ctx.push(Issue::PROPERTY_MISSING(path, "'asset' is required")),
        Some(a) => match a.get("version") {
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
        },
    }
    let error = non_negative(ctx, v, "geometricError", path);
    let used: Vec<&str> = v
        .get("extensionsUsed")
        .and_then(Value::as_array)
        .map(|a| a.iter().filter_map(Value::as_str).collect())
        .unwrap_or_default();
    if let Some(req) = v.get("extensionsRequired").and_then(Value::as_array) {
        for (i, r) in req.iter().enumerate() {
            if let Some(r) = r.as_str()
                && !used.contains(&r)
            {
                ctx.push(Issue::EXTENSION_REQUIRED_BUT_NOT_USED(
                    format!("{path}/extensionsRequired/{i}"),
                    format!("'{r}' is required but not in extensionsUsed"),
                ));
            }
        }
    }
    if let Some(exts) = v.get("extensions").and_then(Value::as_object) {
        for name in exts.keys() {
            if !used.contains(&name.as_str()) {
                ctx.push(Issue::EXTENSION_FOUND_BUT_NOT_USED(
                    format!("{path}/extensions/{name}"),
                    format!("extension '{name}' is not in extensionsUsed"),
                ));
            }
        }
    }
    let schema = match (v.get("schema"), v.get("schemaUri")) {
        (Some(s), _) => validate_schema(ctx, s, &format!("{path}/schema")),
        (None, Some(Value::String(uri))) => {
            let p = format!("{path}/schemaUri");
            let bytes = ctx.resolve(uri, &p).and_then(|f| ctx.read(&f, uri));
            match bytes.map(|b| serde_json::from_slice::<Value>(&b)) {
                Some(Ok(s)) => validate_schema(ctx, &s, &format!("{uri}#")),
                Some(Err(e)) => {
                    ctx.push(Issue::JSON_PARSE_ERROR(uri.as_str(), e.to_string()));
                    Schema::default()
                }
                None => Schema::default(),
            }
        }
        _ => Schema::default(),
    };
    match v.get("root") {
        None => ctx.push(Issue::PROPERTY_MISSING(path, "'root' is required")),
        Some(root) => tile(
            ctx,
            root,
            &format!("{path}/root"),
            Parent {
                error,
                world: DMat4::IDENTITY,
            },
            true,
            &schema,
            0,
        ),
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
