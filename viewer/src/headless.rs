//! Headless rendering of a tileset: the same camera resolution and tile selection as
//! `splat2tiles render`, drawn by [`SplatRenderer`] offscreen and written as PNG.

use std::path::{Path, PathBuf};

use anyhow::Context;
use glam::DMat4;
use splat2tiles_core::camera::{self, Camera};
use splat2tiles_core::splat::Splats;
use splat2tiles_render::Image;
use splat2tiles_render::view::{CameraRequest, parse_vec3, resolve_camera};
use splat2tiles_stream::client::Prefetch;
use splat2tiles_tiles::geometry::{
    Instances, frame_centres, select_tiles, tileset_bounds, tileset_up,
};
use splat2tiles_tiles::tiling::load::{LoadedTileset, load_tileset};

use crate::gpu::{Headless, OFFSCREEN_FORMAT, Offscreen};
use crate::renderer::{FrameStats, RendererConfig, SplatRenderer};

/// What the headless modes need to place the camera, as `splat2tiles render` takes it.
#[derive(Debug, Clone)]
pub struct ViewArgs {
    /// `PATH/cameras.json[#ID]` or `look-at:EX,EY,EZ:TX,TY,TZ`.
    pub camera: Option<String>,
    /// Automatic viewpoint 0..=7 around the tileset's root box.
    pub auto_view: Option<usize>,
    /// Image width (default 1280, or the cameras.json entry's).
    pub width: Option<u32>,
    /// Image height (default 720, or the cameras.json entry's).
    pub height: Option<u32>,
    /// Vertical field of view, degrees.
    pub fov: f64,
    /// Up axis override (`+z`, `-y`, ...).
    pub up_axis: Option<String>,
    /// Highest SH degree evaluated.
    pub sh_degree: Option<u8>,
    /// Background `R,G,B` in [0, 1].
    pub background: String,
    /// Screen-space error threshold of the tile selection, pixels.
    pub max_sse: f64,
    /// How far ahead the streaming client fetches predicted tiles.
    pub prefetch: Prefetch,
}

impl Default for ViewArgs {
    fn default() -> Self {
        ViewArgs {
            camera: None,
            auto_view: Some(0),
            width: None,
            height: None,
            fov: camera::DEFAULT_FOV_Y_DEG,
            up_axis: None,
            sh_degree: None,
            background: "0,0,0".into(),
            max_sse: 16.0,
            prefetch: Prefetch::BALANCED,
        }
    }
}

impl ViewArgs {
    fn camera_request(&self) -> CameraRequest {
        CameraRequest {
            camera: self.camera.clone(),
            auto_view: self.auto_view,
            width: self.width,
            height: self.height,
            fov: self.fov,
        }
    }

    /// The background colour.
    pub fn background_rgb(&self) -> anyhow::Result<[f32; 3]> {
        Ok(parse_vec3(&self.background)
            .context("--background")?
            .as_vec3()
            .to_array())
    }
}

/// Loads `tileset.json` (errors name the file).
pub fn open_tileset(path: &Path) -> anyhow::Result<LoadedTileset> {
    load_tileset(path).context("cannot load the tileset")
}

/// The camera `splat2tiles render` would use for this tileset and these arguments: an auto view
/// frames the splat centres of the tiles it selects ([`frame_centres`]).
pub fn tileset_camera(ts: &LoadedTileset, v: &ViewArgs) -> anyhow::Result<Camera> {
    Ok(tileset_view(ts, v)?.0)
}

/// [`tileset_camera`] with the contents it selects (tile paths, decoded instances).
pub fn tileset_view(
    ts: &LoadedTileset,
    v: &ViewArgs,
) -> anyhow::Result<(Camera, Vec<PathBuf>, Instances)> {
    let up = match &v.up_axis {
        Some(s) => camera::parse_axis(s)
            .with_context(|| format!("--up-axis '{s}': expected one of +x,-x,+y,-y,+z,-z"))?,
        None => tileset_up(ts),
    };
    let req = v.camera_request();
    let cam = resolve_camera(&req, up, tileset_bounds(ts))?;
    let picked = select_tiles(ts, &cam, v.max_sse);
    if v.auto_view.is_none() {
        let instances = load_instances(ts, &picked)?;
        return Ok((cam, picked, instances));
    }
    let (cam, instances) = frame_centres(
        cam,
        |cam| load_instances(ts, &select_tiles(ts, cam, v.max_sse)),
        |bounds| Ok(resolve_camera(&req, up, Some(bounds))?),
    )?;
    Ok((cam, select_tiles(ts, &cam, v.max_sse), instances))
}

/// Reads and decodes tile contents (any variant) with their tile-to-world matrices.
pub fn load_instances(ts: &LoadedTileset, paths: &[PathBuf]) -> anyhow::Result<Instances> {
    Ok(splat2tiles_tiles::geometry::load_instances(ts, paths)?)
}

/// Renders `instances` seen by `cam` once (tiles fully faded in, sort finished) and reads the
/// frame back.
pub fn render_instances(
    gpu: &Headless,
    instances: &[(Splats, DMat4)],
    cam: &Camera,
    cfg: RendererConfig,
) -> anyhow::Result<(Image, FrameStats)> {
    let cfg = RendererConfig {
        blocking_sort: true,
        ..cfg
    };
    let mut r = SplatRenderer::new(&gpu.device, &gpu.queue, OFFSCREEN_FORMAT, cfg);
    for (i, (s, m)) in instances.iter().enumerate() {
        r.insert_tile(&gpu.device, &gpu.queue, i as u64, s, *m, 0.0);
    }
    let target = Offscreen::new(&gpu.device, cam.width, cam.height)?;
    let stats = r.render(
        &gpu.device,
        &gpu.queue,
        &target.view,
        cam,
        cfg.fade_s.max(0.0),
    );
    let img = target.read(&gpu.device, &gpu.queue)?;
    Ok((img, stats))
}

/// Result of [`run_static`].
#[derive(Debug, Clone)]
pub struct StaticSummary {
    /// Adapter description.
    pub adapter: String,
    /// Tiles drawn and tiles in the tileset.
    pub tiles: (usize, usize),
    /// Splats uploaded.
    pub splats: usize,
    /// Wall time of upload + sort + draw + read-back, ms.
    pub ms: f64,
    /// The PNG written.
    pub png: PathBuf,
    /// Stats of the frame.
    pub stats: FrameStats,
}

/// `--headless` with `--camera`/`--auto-view`: one frame to `out/frame_0000.png`.
pub fn run_static(tileset: &Path, v: &ViewArgs, out: &Path) -> anyhow::Result<StaticSummary> {
    let ts = open_tileset(tileset)?;
    let (cam, picked, instances) = tileset_view(&ts, v)?;
    let gpu = crate::gpu::headless()?;
    let cfg = RendererConfig {
        background: v.background_rgb()?,
        max_sh_degree: v.sh_degree.unwrap_or(3),
        ..RendererConfig::default()
    };
    let t0 = crate::clock::now_ms();
    let (img, stats) = render_instances(&gpu, &instances, &cam, cfg)?;
    let ms = crate::clock::now_ms() - t0;
    std::fs::create_dir_all(out).with_context(|| format!("{}: cannot create", out.display()))?;
    let png = out.join("frame_0000.png");
    img.save_png(&png)
        .with_context(|| format!("{}: cannot write", png.display()))?;
    Ok(StaticSummary {
        adapter: gpu.adapter_name(),
        tiles: (picked.len(), ts.tiles.len()),
        splats: stats.resident,
        ms,
        png,
        stats,
    })
}

/// Result of [`run_trace`].
#[derive(Debug, Clone)]
pub struct TraceSummary {
    /// Adapter description.
    pub adapter: String,
    /// Frames written.
    pub frames: usize,
    /// Most splats resident at once.
    pub peak_resident: usize,
    /// Bytes the client received.
    pub bytes_read: u64,
    /// Mean wall time per frame (streaming until idle, sort, draw, read-back, PNG), ms.
    pub mean_ms: f64,
    /// The client's last errors (each names the URL).
    pub errors: Vec<String>,
}

/// Most wall-clock seconds spent streaming for one pose before its frame is drawn anyway.
pub const POSE_SETTLE_S: f64 = 30.0;

/// `--headless --camera-trace FILE`: one PNG per pose (`frame_0000.png`, ...) while the tiles
/// stream through splat2tiles' client (`url`: a path, `file://` or `http://`).
///
/// Time: the client runs on the trace's clock, `max(pose time, clock so far)`, advanced by the
/// wall time spent waiting (its bandwidth estimate needs real durations); for each pose it is
/// ticked until idle (all it wants for that pose is resident) or [`POSE_SETTLE_S`]. The renderer
/// (fades) runs on the pose times alone: what arrives while waiting at pose k is inserted at pose
/// k's time and the frame is drawn at it, so frames do not depend on how fast the machine is.
///
/// `record`: the poses drawn are also written there as a trace CSV (`--record`), whole or not at
/// all, once every frame is written.
pub fn run_trace(
    url: &str,
    trace_path: &Path,
    v: &ViewArgs,
    out: &Path,
    record: Option<&Path>,
) -> anyhow::Result<TraceSummary> {
    let text = std::fs::read_to_string(trace_path)
        .with_context(|| format!("{}: cannot read", trace_path.display()))?;
    let trace = splat2tiles_stream::trace::Trace::from_csv(&text)
        .map_err(|e| anyhow::anyhow!("{}: {e}", trace_path.display()))?;
    if trace.poses.is_empty() {
        anyhow::bail!("{}: the trace has no pose", trace_path.display());
    }
    let fov = trace
        .header("fov_y_deg")
        .and_then(|s| s.parse::<f64>().ok())
        .filter(|f| *f > 0.0 && *f < 180.0)
        .unwrap_or(v.fov);
    let (w, h) = (v.width.unwrap_or(1280), v.height.unwrap_or(720));
    let gpu = crate::gpu::headless()?;
    let cfg = RendererConfig {
        background: v.background_rgb()?,
        max_sh_degree: v.sh_degree.unwrap_or(3),
        blocking_sort: true,
        ..RendererConfig::default()
    };
    let mut r = SplatRenderer::new(&gpu.device, &gpu.queue, OFFSCREEN_FORMAT, cfg);
    let target = Offscreen::new(&gpu.device, w, h)?;
    let mut d = crate::stream::driver(url, w, h, fov, v.max_sse, v.prefetch);
    let (early, t_boot) = crate::stream::bootstrap(&mut d, url, trace.poses[0].t, POSE_SETTLE_S)?;
    let t_first = trace.poses[0].t;
    crate::stream::apply_updates(&mut r, &gpu.device, &gpu.queue, early, t_first);
    let root = d.client().root_transform();
    std::fs::create_dir_all(out).with_context(|| format!("{}: cannot create", out.display()))?;
    let wall0 = crate::clock::now_ms();
    let mut clock = t_boot;
    let mut t_render = t_first;
    let mut peak = 0;
    let mut scene = crate::layered::SceneSync::default();
    let mut rec = crate::record::Recorder::new(0.0, &recording_headers(url, fov, w, h));
    for (k, pose) in trace.poses.iter().enumerate() {
        rec.record(*pose);
        clock = clock.max(pose.t);
        let cam = Camera::from_pose(w, h, fov, root * pose.world_from_camera());
        // Fades run on the trace's own times (kept monotonic).
        t_render = t_render.max(pose.t);
        let start = crate::clock::now_ms();
        let mut last = start;
        loop {
            let ups = d.tick(clock, &cam);
            scene
                .apply(&mut r, &gpu.device, &gpu.queue, d.client(), ups, t_render)
                .map_err(|e| anyhow::anyhow!("{url}: {e}"))?;
            if d.is_idle() || (crate::clock::now_ms() - start) / 1e3 > POSE_SETTLE_S {
                break;
            }
            std::thread::sleep(std::time::Duration::from_millis(1));
            let now = crate::clock::now_ms();
            clock += (now - last) / 1e3;
            last = now;
        }
        let stats = r.render(&gpu.device, &gpu.queue, &target.view, &cam, t_render);
        peak = peak.max(stats.resident);
        let png = out.join(format!("frame_{k:04}.png"));
        target
            .read(&gpu.device, &gpu.queue)?
            .save_png(&png)
            .with_context(|| format!("{}: cannot write", png.display()))?;
    }
    if let Some(path) = record {
        crate::record::write_atomic(path, &rec.csv())?;
    }
    let n = trace.poses.len();
    let s = d.stats();
    Ok(TraceSummary {
        adapter: gpu.adapter_name(),
        frames: n,
        peak_resident: peak,
        bytes_read: s.bytes_received,
        mean_ms: (crate::clock::now_ms() - wall0) / n as f64,
        errors: s.last_errors,
    })
}

/// The headers of a native `--record` CSV: the viewer, the tileset, the field of view and aspect.
pub fn recording_headers(url: &str, fov: f64, w: u32, h: u32) -> Vec<(&'static str, String)> {
    vec![
        ("viewer", "splat2tiles-viewer".into()),
        ("tileset", url.into()),
        ("fov_y_deg", format!("{fov}")),
        ("aspect", format!("{:.4}", w as f64 / h.max(1) as f64)),
    ]
}
