//! Extension declarations of a tileset JSON (3D Tiles 1.1 "Extensions"): `extensionsUsed` and
//! `extensionsRequired` are unique strings, every extension object anywhere is declared, every
//! declared extension is found, and required extensions this validator cannot check are named.

use super::context::Ctx;
use super::issues::Issue;
use serde_json::Value;
use std::collections::{BTreeMap, BTreeSet};

/// Extensions whose rules this validator applies (or that need no object in the tileset).
const KNOWN: &[&str] = &[
    "3DTILES_bounding_volume_S2",
    "3DTILES_content_gltf",
    "3DTILES_implicit_tiling",
    "3DTILES_metadata",
    "3DTILES_multiple_contents",
    // GeoJSON contents are told apart from tilesets and noted, not checked inside.
    "MAXAR_content_geojson",
    // Its declaration rules are checked and each archive's tileset is validated (archive.rs).
    "MAXAR_content_3tz",
];

/// Extensions declared without any object in the tileset JSON (they act on the content; see
/// [`unfound`] for `3DTILES_content_gltf`).
const WITHOUT_OBJECT: &[&str] = &["MAXAR_content_3tz", "MAXAR_content_geojson"];

/// Extensions that change how contents must be read, so a client without them cannot load the
/// tileset: when used they must also be required (as Cesium's validator requires).
const MUST_BE_REQUIRED: &[&str] = &["MAXAR_content_3tz"];

/// Every extension name found as a key of an `extensions` object, with the first JSON pointer
/// where it appears, and the pointers of `extensions` members that are not objects and of
/// `extras` that are not objects (marked "extras") (iterative
/// walk: the JSON is depth-bounded, but no recursion is needed).
#[allow(clippy::type_complexity)]
pub(crate) fn found_extensions(
    root: &Value,
) -> (BTreeMap<String, String>, Vec<(String, &'static str)>) {
    let mut out = BTreeMap::new();
    let mut bad = Vec::new();
    let mut stack: Vec<(&Value, String)> = vec![(root, String::new())];
    while let Some((v, ptr)) = stack.pop() {
        match v {
            Value::Object(m) => {
                for (k, child) in m {
                    let p = format!("{ptr}/{}", k.replace('~', "~0").replace('/', "~1"));
                    if k == "extensions"
                        && let Some(exts) = child.as_object()
                    {
                        for name in exts.keys() {
                            out.entry(name.clone())
                                .or_insert_with(|| format!("{p}/{name}"));
                        }
                    } else if k == "extensions" {
                        bad.push((p.clone(), "extensions must be an object"));
                    }
                    if k == "extras" && !child.is_object() {
                        bad.push((p.clone(), "extras"));
                    }
                    if k == "extensions"
                        && let Some(exts) = child.as_object()
                    {
                        for (name, e) in exts {
                            if !e.is_object() {
                                bad.push((format!("{p}/{name}"), "an extension must be an object"));
                            }
                        }
                    }
                    stack.push((child, p));
                }
            }
            Value::Array(a) => {
                for (i, child) in a.iter().enumerate() {
                    stack.push((child, format!("{ptr}/{i}")));
                }
            }
            _ => {}
        }
    }
    (out, bad)
}

/// Reads `key` as an array of unique strings; reports type errors and duplicates.
/// `base` is the JSON pointer of the object holding the array.
fn names<'v>(ctx: &mut Ctx<'_>, v: &'v Value, base: &str, key: &str) -> Vec<&'v str> {
    let Some(a) = v.get(key) else {
        return vec![];
    };
    let Some(a) = a.as_array() else {
        ctx.push(Issue::TYPE_MISMATCH(
            ctx.at(&format!("{base}/{key}")),
            format!("{key} must be an array of strings"),
        ));
        return vec![];
    };
    if a.is_empty() {
        ctx.push(Issue::ARRAY_LENGTH_MISMATCH(
            ctx.at(&format!("{base}/{key}")),
            format!("{key}, when present, must not be empty"),
        ));
    }
    let mut out: Vec<&str> = Vec::new();
    for (i, e) in a.iter().enumerate() {
        match e.as_str() {
            None => ctx.push(Issue::TYPE_MISMATCH(
                ctx.at(&format!("{base}/{key}/{i}")),
                format!("{key} must hold strings"),
            )),
            Some(s) if out.contains(&s) => ctx.push(Issue::ARRAY_ELEMENT_NOT_UNIQUE(
                ctx.at(&format!("{base}/{key}/{i}")),
                format!("'{s}' is listed twice in {key}"),
            )),
            Some(s) => out.push(s),
        }
    }
    out
}

/// What [`declarations`] read from a tileset JSON, for [`unfound`] once the external tilesets
/// are walked.
pub(crate) struct Declared {
    /// The names in `extensionsUsed`.
    pub used: Vec<String>,
    /// The extensions whose objects appear in the tileset JSON.
    pub found: BTreeSet<String>,
    /// `asset.version` is "1.0".
    pub v1_0: bool,
}

/// Checks the declarations of the tileset JSON `v`. Also sets `ctx.gltf_undeclared` for a 1.0
/// tileset that neither uses nor requires `3DTILES_content_gltf` (a required-but-unused one is
/// reported here, once).
pub(crate) fn declarations(ctx: &mut Ctx<'_>, v: &Value) -> Declared {
    let used = names(ctx, v, "", "extensionsUsed");
    let required = names(ctx, v, "", "extensionsRequired");
    if let Some(gltf) = v.pointer("/extensions/3DTILES_content_gltf") {
        content_gltf(ctx, gltf);
    }
    for (i, r) in required.iter().enumerate() {
        if !used.contains(r) {
            ctx.push(Issue::EXTENSION_REQUIRED_BUT_NOT_USED(
                ctx.at(&format!("/extensionsRequired/{i}")),
                format!("'{r}' is required but not in extensionsUsed"),
            ));
        }
    }
    for (i, u) in used.iter().enumerate().filter(|(_, u)| !KNOWN.contains(u)) {
        let required = if required.contains(u) {
            ", and it is required: clients without it must refuse the tileset"
        } else {
            ""
        };
        ctx.push(Issue::EXTENSION_NOT_SUPPORTED(
            ctx.at(&format!("/extensionsUsed/{i}")),
            format!("this validator does not know '{u}': its objects are not checked{required}"),
        ));
    }
    // A 3D Tiles 1.0 tileset with glTF contents needs 3DTILES_content_gltf: clients of 1.0 read
    // only b3dm/i3dm/pnts/cmpt, so it must be required too (as Cesium's validator checks).
    let v1_0 = v.pointer("/asset/version").and_then(Value::as_str) == Some("1.0");
    const GLTF: &str = "3DTILES_content_gltf";
    ctx.gltf_undeclared = v1_0 && !used.contains(&GLTF) && !required.contains(&GLTF);
    for (i, u) in used.iter().enumerate() {
        let must = MUST_BE_REQUIRED.contains(u) || (v1_0 && *u == GLTF);
        if must && !required.contains(u) {
            ctx.push(Issue::EXTENSION_REQUIRED_BUT_NOT_DECLARED(
                ctx.at(&format!("/extensionsUsed/{i}")),
                format!(
                    "'{u}' changes how contents are read: it must be in extensionsRequired too"
                ),
            ));
        }
    }
    let (found, bad) = found_extensions(v);
    for (at, why) in bad {
        if why == "extras" {
            ctx.push(Issue::EXTRAS_UNEXPECTED_TYPE(
                ctx.at(&at),
                "extras SHOULD be an object (key/value pairs) for portability",
            ));
        } else {
            ctx.push(Issue::TYPE_MISMATCH(ctx.at(&at), why));
        }
    }
    for (name, at) in &found {
        if !used.contains(&name.as_str()) {
            ctx.push(Issue::EXTENSION_FOUND_BUT_NOT_USED(
                ctx.at(at),
                format!("extension '{name}' is used here but not in extensionsUsed"),
            ));
        }
    }
    Declared {
        used: used.into_iter().map(str::to_string).collect(),
        found: found.into_keys().collect(),
        v1_0,
    }
}

/// The `3DTILES_content_gltf` object: its `extensionsUsed` and `extensionsRequired` (the glTF
/// extensions the contents use) are unique strings, and every required one is also used.
fn content_gltf(ctx: &mut Ctx<'_>, gltf: &Value) {
    const BASE: &str = "/extensions/3DTILES_content_gltf";
    let used = names(ctx, gltf, BASE, "extensionsUsed");
    let required = names(ctx, gltf, BASE, "extensionsRequired");
    for (i, r) in required.iter().enumerate() {
        if !used.contains(r) {
            ctx.push(Issue::EXTENSION_REQUIRED_BUT_NOT_USED(
                ctx.at(&format!("{BASE}/extensionsRequired/{i}")),
                format!("glTF extension '{r}' is required but not in extensionsUsed"),
            ));
        }
    }
}

/// After the walk of a tileset: every extension found in the external tilesets below it
/// (`below`) must be in its `used` too, and every extension it declares must be found in it or
/// below it (3D Tiles 1.1 "Extensions": a tileset declares what it and its external tilesets use).
/// In a 3D Tiles 1.0 tileset `3DTILES_content_gltf` needs no object: its glTF contents use it;
/// in 1.1 glTF contents need no extension, so only its object uses it.
pub(crate) fn unfound(ctx: &mut Ctx<'_>, declared: &Declared, below: &BTreeSet<String>) {
    let Declared { used, found, v1_0 } = declared;
    for name in below {
        if !used.contains(name) && !found.contains(name) {
            ctx.push(Issue::EXTENSION_FOUND_BUT_NOT_USED(
                ctx.at(""),
                format!(
                    "extension '{name}' is used in an external tileset this one refers to, but \
                     not in this tileset's extensionsUsed"
                ),
            ));
        }
    }
    for (i, u) in used.iter().enumerate() {
        let without_object = match u.as_str() {
            "3DTILES_content_gltf" => *v1_0,
            u => WITHOUT_OBJECT.contains(&u),
        };
        if !found.contains(u) && !below.contains(u) && !without_object {
            ctx.push(Issue::EXTENSION_USED_BUT_NOT_FOUND(
                ctx.at(&format!("/extensionsUsed/{i}")),
                format!(
                    "'{u}' is in extensionsUsed but no object of the tileset or of its external \
                     tilesets uses it"
                ),
            ));
        }
    }
}
