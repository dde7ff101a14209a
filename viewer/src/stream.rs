//! Streaming for the native front-ends: splat2tiles' sans-IO client run by its native driver
//! (file and HTTP fetches on worker threads), its scene updates fed to the renderer.

use anyhow::bail;
use glam::{DMat4, DVec3};
use splat2tiles_core::camera::Camera;
use splat2tiles_stream::client::native::Driver;
use splat2tiles_stream::client::{ClientConfig, Prefetch, SceneUpdate};

/// Applies scene updates to the renderer at time `now_s` (inserts fade in, removes fade out,
/// appends grow a tile being downloaded); a client's frames go through
/// [`crate::layered::SceneSync`], which also draws layered tilesets.
pub use crate::layered::apply_scene_updates as apply_updates;

/// A driver for `url` (path, `file://` or `http://`) planning for `width x height` frames.
pub fn driver(
    url: &str,
    width: u32,
    height: u32,
    fov_y_deg: f64,
    max_sse: f64,
    prefetch: Prefetch,
) -> Driver {
    Driver::new(
        url,
        ClientConfig {
            width,
            height,
            fov_y_deg,
            max_sse,
            prefetch,
            ..ClientConfig::default()
        },
    )
}

/// Ticks `d` (with a placeholder camera) until the tileset and its subtrees are loaded, on a clock
/// starting at `start_s`; errors name the URL. Returns the scene updates produced meanwhile and
/// the clock at the end.
pub fn bootstrap(
    d: &mut Driver,
    url: &str,
    start_s: f64,
    timeout_s: f64,
) -> anyhow::Result<(Vec<SceneUpdate>, f64)> {
    let t0 = crate::clock::now_ms();
    let cam = Camera::from_pose(64, 64, 50.0, DMat4::IDENTITY);
    let mut updates = Vec::new();
    loop {
        let waited = (crate::clock::now_ms() - t0) / 1e3;
        let now = start_s + waited;
        updates.extend(d.tick(now, &cam));
        let s = d.stats();
        if s.ready {
            return Ok((updates, now));
        }
        if d.is_idle() {
            bail!(
                "{url}: cannot load the tileset: {}",
                s.last_errors.join("; ")
            );
        }
        if waited > timeout_s {
            bail!("{url}: tileset not loaded after {timeout_s} s");
        }
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
}

/// World-space bounds of the root tiles' boxes and the tileset's up direction (root +z).
pub fn world_bounds(d: &Driver) -> (Option<(DVec3, DVec3)>, DVec3) {
    let c = d.client();
    let root = c.root_transform();
    let up = root
        .transform_vector3(DVec3::Z)
        .try_normalize()
        .unwrap_or(DVec3::Z);
    let cat = c.catalog();
    let mut b: Option<(DVec3, DVec3)> = None;
    for &i in &cat.roots {
        let Some(t) = cat.tiles.get(i) else { continue };
        for p in t.bbox.corners() {
            let w = root.transform_point3(p);
            b = Some(match b {
                Some((lo, hi)) => (lo.min(w), hi.max(w)),
                None => (w, w),
            });
        }
    }
    (b, up)
}
