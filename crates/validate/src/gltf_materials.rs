//! glTF 2.0 materials, textures, samplers and images (sec. 3.8-3.9, 5.19-5.26) and the
//! `KHR_lights_punctual` lights of contents without splats: references resolve, values in range.

use super::context::Ctx;
use super::issues::Issue;
use serde_json::Value;

/// Most entries of any array that are inspected (bounds the work on hostile input).
const MAX_ENTRIES: usize = 1 << 16;

/// The texture references a material may hold, under `pbrMetallicRoughness` or at its top.
const TEXTURES: [(&str, &str); 5] = [
    ("/pbrMetallicRoughness", "baseColorTexture"),
    ("/pbrMetallicRoughness", "metallicRoughnessTexture"),
    ("", "normalTexture"),
    ("", "occlusionTexture"),
    ("", "emissiveTexture"),
];

fn entries(v: Option<&Value>) -> &[Value] {
    match v.and_then(Value::as_array) {
        Some(a) => &a[..a.len().min(MAX_ENTRIES)],
        None => &[],
    }
}

/// Reports `v` (at `path`) unless it is a number in `[lo, hi]`.
fn number_in(ctx: &mut Ctx<'_>, v: &Value, lo: f64, hi: f64, path: String, what: &str) {
    match v.as_f64() {
        Some(x) if (lo..=hi).contains(&x) => {}
        Some(x) => ctx.push(Issue::VALUE_NOT_IN_RANGE(
            path,
            format!("{what} {x} is outside [{lo}, {hi}]"),
        )),
        None => ctx.push(Issue::TYPE_MISMATCH(
            path,
            format!("{what} must be a number"),
        )),
    }
}

/// Reports `v` unless it is an array of `n` numbers in `[0, 1]` (a colour factor).
fn factor(ctx: &mut Ctx<'_>, v: &Value, n: usize, path: String, what: &str) {
    let Some(a) = v.as_array() else {
        ctx.push(Issue::TYPE_MISMATCH(
            path,
            format!("{what} must be an array"),
        ));
        return;
    };
    if a.len() != n {
        ctx.push(Issue::ARRAY_LENGTH_MISMATCH(
            path,
            format!("{what} has {} elements, not {n}", a.len()),
        ));
        return;
    }
    for (i, x) in a.iter().enumerate() {
        number_in(ctx, x, 0.0, 1.0, format!("{path}/{i}"), what);
    }
}

/// Reports `v` unless it is an index below `n` (into the glTF array `what`).
fn reference(ctx: &mut Ctx<'_>, v: &Value, n: usize, path: String, what: &str) {
    if v.as_u64().is_none_or(|i| i >= n as u64) {
        ctx.push(Issue::GLTF_REFERENCE_INVALID(
            path,
            format!("{what} {v} does not exist ({n} {what}s)"),
        ));
    }
}

/// Checks materials, textures, samplers and images of the glTF JSON `raw`.
pub(crate) fn check_materials(ctx: &mut Ctx<'_>, raw: &Value, at: &dyn Fn(String) -> String) {
    let textures = entries(raw.get("textures"));
    for (m, mat) in entries(raw.get("materials")).iter().enumerate() {
        let p = format!("/materials/{m}");
        if let Some(pbr) = mat.get("pbrMetallicRoughness") {
            let pp = format!("{p}/pbrMetallicRoughness");
            if let Some(f) = pbr.get("baseColorFactor") {
                factor(
                    ctx,
                    f,
                    4,
                    at(format!("{pp}/baseColorFactor")),
                    "baseColorFactor",
                );
            }
            for key in ["metallicFactor", "roughnessFactor"] {
                if let Some(f) = pbr.get(key) {
                    number_in(ctx, f, 0.0, 1.0, at(format!("{pp}/{key}")), key);
                }
            }
        }
        if let Some(f) = mat.get("emissiveFactor") {
            factor(
                ctx,
                f,
                3,
                at(format!("{p}/emissiveFactor")),
                "emissiveFactor",
            );
        }
        match mat.get("alphaMode").map(|a| a.as_str()) {
            None | Some(Some("OPAQUE" | "MASK" | "BLEND")) => {}
            Some(a) => ctx.push(Issue::VALUE_NOT_IN_LIST(
                at(format!("{p}/alphaMode")),
                format!("alphaMode {a:?} is not OPAQUE, MASK or BLEND"),
            )),
        }
        if let Some(c) = mat.get("alphaCutoff") {
            number_in(
                ctx,
                c,
                0.0,
                f64::MAX,
                at(format!("{p}/alphaCutoff")),
                "alphaCutoff",
            );
        }
        for (under, key) in TEXTURES {
            let Some(info) = mat.pointer(&format!("{under}/{key}")) else {
                continue;
            };
            let tp = format!("{p}{under}/{key}");
            match info.get("index") {
                Some(i) => reference(ctx, i, textures.len(), at(format!("{tp}/index")), "texture"),
                None => ctx.push(Issue::PROPERTY_MISSING(
                    at(tp.clone()),
                    "a texture reference needs an index",
                )),
            }
            if let Some(s) = info.get("strength") {
                number_in(ctx, s, 0.0, 1.0, at(format!("{tp}/strength")), "strength");
            }
        }
    }
    check_textures(ctx, raw, textures, at);
}

/// Texture sources and samplers, sampler filters and wraps, image sources.
fn check_textures(
    ctx: &mut Ctx<'_>,
    raw: &Value,
    textures: &[Value],
    at: &dyn Fn(String) -> String,
) {
    let samplers = entries(raw.get("samplers"));
    let images = entries(raw.get("images"));
    for (t, tex) in textures.iter().enumerate() {
        if let Some(s) = tex.get("sampler") {
            reference(
                ctx,
                s,
                samplers.len(),
                at(format!("/textures/{t}/sampler")),
                "sampler",
            );
        }
        if let Some(s) = tex.get("source") {
            reference(
                ctx,
                s,
                images.len(),
                at(format!("/textures/{t}/source")),
                "image",
            );
        }
    }
    // glTF 2.0 sec. 5.26: the WebGL filter and wrap enums.
    let allowed: [(&str, &[u64]); 4] = [
        ("magFilter", &[9728, 9729]),
        ("minFilter", &[9728, 9729, 9984, 9985, 9986, 9987]),
        ("wrapS", &[33071, 33648, 10497]),
        ("wrapT", &[33071, 33648, 10497]),
    ];
    for (s, sampler) in samplers.iter().enumerate() {
        for (key, values) in allowed {
            if let Some(v) = sampler.get(key)
                && v.as_u64().is_none_or(|x| !values.contains(&x))
            {
                ctx.push(Issue::VALUE_NOT_IN_LIST(
                    at(format!("/samplers/{s}/{key}")),
                    format!("{key} {v} is not one of {values:?}"),
                ));
            }
        }
    }
    let views = entries(raw.get("bufferViews")).len();
    for (i, image) in images.iter().enumerate() {
        let p = format!("/images/{i}");
        match (image.get("uri"), image.get("bufferView")) {
            (Some(_), Some(_)) => ctx.push(Issue::ONE_OF_ERROR(
                at(p),
                "an image has either a uri or a bufferView, not both",
            )),
            (None, None) => ctx.push(Issue::PROPERTY_MISSING(
                at(p),
                "an image needs a uri or a bufferView",
            )),
            (None, Some(v)) => {
                reference(ctx, v, views, at(format!("{p}/bufferView")), "bufferView");
                if !matches!(
                    image.get("mimeType").and_then(Value::as_str),
                    Some("image/jpeg" | "image/png")
                ) {
                    ctx.push(Issue::PROPERTY_MISSING(
                        at(format!("{p}/mimeType")),
                        "an image in a bufferView needs mimeType image/jpeg or image/png",
                    ));
                }
            }
            (Some(_), None) => {}
        }
    }
}

/// Checks the `KHR_lights_punctual` lights of `raw` and the nodes that place them.
pub(crate) fn check_lights(ctx: &mut Ctx<'_>, raw: &Value, at: &dyn Fn(String) -> String) {
    const EXT: &str = "KHR_lights_punctual";
    let lights = entries(raw.pointer(&format!("/extensions/{EXT}/lights")));
    for (l, light) in lights.iter().enumerate() {
        let p = format!("/extensions/{EXT}/lights/{l}");
        let kind = light.get("type").and_then(Value::as_str);
        match kind {
            Some("directional" | "point" | "spot") => {}
            Some(k) => ctx.push(Issue::VALUE_NOT_IN_LIST(
                at(format!("{p}/type")),
                format!("light type '{k}' is not directional, point or spot"),
            )),
            None => ctx.push(Issue::PROPERTY_MISSING(
                at(p.clone()),
                "a light needs a type",
            )),
        }
        if let Some(c) = light.get("color") {
            factor(ctx, c, 3, at(format!("{p}/color")), "color");
        }
        if let Some(i) = light.get("intensity") {
            number_in(
                ctx,
                i,
                0.0,
                f64::MAX,
                at(format!("{p}/intensity")),
                "intensity",
            );
        }
        if let Some(r) = light.get("range")
            && r.as_f64().is_none_or(|r| r <= 0.0)
        {
            ctx.push(Issue::VALUE_NOT_IN_RANGE(
                at(format!("{p}/range")),
                format!("range {r} must be a number above 0"),
            ));
        }
        check_spot(ctx, light, kind == Some("spot"), &p, at);
    }
    for (n, node) in entries(raw.get("nodes")).iter().enumerate() {
        if let Some(l) = node.pointer(&format!("/extensions/{EXT}/light")) {
            let path = at(format!("/nodes/{n}/extensions/{EXT}/light"));
            reference(ctx, l, lights.len(), path, "light");
        }
    }
}

/// A spot light's cone: `spot` required for type spot, 0 <= inner < outer <= pi/2.
fn check_spot(
    ctx: &mut Ctx<'_>,
    light: &Value,
    is_spot: bool,
    p: &str,
    at: &dyn Fn(String) -> String,
) {
    let Some(spot) = light.get("spot") else {
        if is_spot {
            ctx.push(Issue::PROPERTY_MISSING(
                at(p.to_string()),
                "a spot light needs a spot object",
            ));
        }
        return;
    };
    let angle = |key: &str, default: f64| spot.get(key).map_or(Some(default), Value::as_f64);
    let (inner, outer) = (
        angle("innerConeAngle", 0.0),
        angle("outerConeAngle", std::f64::consts::FRAC_PI_4),
    );
    match (inner, outer) {
        (Some(i), Some(o)) if 0.0 <= i && i < o && o <= std::f64::consts::FRAC_PI_2 => {}
        (Some(i), Some(o)) => ctx.push(Issue::VALUE_NOT_IN_RANGE(
            at(format!("{p}/spot")),
            format!("cone angles inner {i}, outer {o}: need 0 <= inner < outer <= pi/2"),
        )),
        _ => ctx.push(Issue::TYPE_MISMATCH(
            at(format!("{p}/spot")),
            "innerConeAngle and outerConeAngle must be numbers",
        )),
    }
}
