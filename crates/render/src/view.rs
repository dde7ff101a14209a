//! Where a render looks from: the camera of a `--camera` spec (look-at, geo or cameras.json
//! entry) or an automatic viewpoint, at a requested size and field of view.

use glam::DVec3;
use splat2tiles_core::camera::{self, Camera};
use splat2tiles_core::view_spec::ViewSpec;

/// Why a camera request could not be resolved (the message names the argument or file).
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct ViewError(String);

/// A camera as the `render` command and the viewers take it.
#[derive(Debug, Clone, Default)]
pub struct CameraRequest {
    /// `look-at:...`, `geo:...` or `cameras.json[#id]`.
    pub camera: Option<String>,
    /// Index of an automatic viewpoint (`camera::AUTO_VIEW_COUNT` of them).
    pub auto_view: Option<usize>,
    /// Image width (default 1280, or the cameras.json entry's).
    pub width: Option<u32>,
    /// Image height (default 720, or the cameras.json entry's).
    pub height: Option<u32>,
    /// Vertical field of view in degrees.
    pub fov: f64,
}

/// Parses `X,Y,Z` (three finite comma-separated numbers).
pub fn parse_vec3(s: &str) -> Result<DVec3, ViewError> {
    let v: Vec<f64> = s
        .split(',')
        .map(|t| t.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|e| {
            ViewError(format!(
                "'{s}': expected three comma-separated numbers: {e}"
            ))
        })?;
    match v[..] {
        [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok(DVec3::new(x, y, z)),
        _ => Err(ViewError(format!(
            "'{s}': expected three finite comma-separated numbers"
        ))),
    }
}

/// Resolves the camera of `req` for a scene with the given up direction and centre bounds.
pub fn resolve_camera(
    req: &CameraRequest,
    up: DVec3,
    bounds: Option<(DVec3, DVec3)>,
) -> Result<Camera, ViewError> {
    let fail = |m: String| Err(ViewError(m));
    let (w, h) = (req.width.unwrap_or(1280), req.height.unwrap_or(720));
    if w == 0 || h == 0 {
        return fail(format!("image size must be positive, got {w}x{h}"));
    }
    if !(req.fov > 0.0 && req.fov < 180.0) {
        return fail(format!(
            "--fov must be in (0, 180) degrees, got {}",
            req.fov
        ));
    }
    if let Some(k) = req.auto_view {
        if k >= camera::AUTO_VIEW_COUNT {
            return fail(format!(
                "--auto-view {k}: there are {} views (0..=7)",
                camera::AUTO_VIEW_COUNT
            ));
        }
        let (lo, hi) = bounds.unwrap_or((DVec3::splat(-1.0), DVec3::splat(1.0)));
        return Ok(camera::auto_views_with(lo, hi, up, w, h, req.fov)[k]);
    }
    let Some(spec) = req.camera.as_deref() else {
        return fail("give --camera or --auto-view".into());
    };
    if spec.starts_with("look-at:") || spec.starts_with("geo:") {
        let view = ViewSpec::parse(spec).map_err(ViewError)?;
        return Ok(view.camera(w, h, req.fov, up));
    }
    let (path, id) = match spec.rsplit_once('#') {
        Some((p, id)) => match id.parse::<i64>() {
            Ok(n) => (p, Some(n)),
            Err(e) => return fail(format!("{spec}: camera id '{id}' is not an integer: {e}")),
        },
        None => (spec, None),
    };
    let text = std::fs::read_to_string(path)
        .map_err(|e| ViewError(format!("{path}: cannot read: {e}")))?;
    let cams = camera::parse_cameras_json(&text)
        .map_err(|e| ViewError(format!("{path}: bad cameras.json: {e}")))?;
    let entry = match id {
        Some(id) => cams.iter().find(|c| c.id == id),
        None => cams.first(),
    };
    let Some(entry) = entry else {
        return fail(format!("{spec}: no such camera"));
    };
    let cam = entry.to_camera();
    Ok(match (req.width, req.height) {
        (None, None) => cam,
        _ => cam.resized(
            req.width.unwrap_or(cam.width),
            req.height.unwrap_or(cam.height),
        ),
    })
}
