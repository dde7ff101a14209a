//! `WebViewer`, the object the page drives: wgpu on the canvas (WebGL2), the streaming client
//! fed by Fetch, first-person controls, and per-frame stats for the overlay and the tests.

use std::cell::RefCell;
use std::rc::Rc;

use glam::DVec3;
use serde_json::json;
use splat2tiles_core::camera::{self, Camera};
use splat2tiles_core::view_spec::{ViewSpec, is_georeferenced};
use splat2tiles_stream::Level;
use splat2tiles_stream::client::{ClientConfig, PredictorKind, Prefetch, StreamClient};
use splat2tiles_viewer::layered::{BlendMode, SceneSync};
use splat2tiles_viewer::record::{Recorder, pose_of};
use splat2tiles_viewer::{RendererConfig, SplatRenderer};
use wasm_bindgen::prelude::*;
use web_sys::HtmlCanvasElement;

use crate::controls::{FirstPerson, Mode};
use crate::fetch::{self, Shared};

/// Page options (the JSON the page passes to `create`).
struct Options {
    auto_view: usize,
    levels: Vec<Level>,
    budget_mb: f64,
    max_sse: f64,
    fov: f64,
    /// Starting view (`camera=`), instead of the automatic viewpoint.
    camera: Option<ViewSpec>,
    /// Start walking instead of flying (`mode=walk`).
    walk: bool,
    /// The trajectory predictor (`predictor=reactive|constant-velocity|linear|tcn|learned`).
    predictor: PredictorKind,
    /// How far ahead predicted tiles are fetched (`prefetch=thrifty|balanced|eager|SECONDS`).
    prefetch: Prefetch,
    /// Layered tilesets: blend levels (`blend=continuous`, default) or swap them at once
    /// (`blend=hard`, the control of the continuity test).
    blend: BlendMode,
    /// Record the camera path from the first frame (`record`, default true; `record=0`: only
    /// once R or `window.splat2tiles.record(true)` starts it).
    record: bool,
}

impl Options {
    fn parse(text: &str) -> Result<Options, String> {
        let v: serde_json::Value =
            serde_json::from_str(text).map_err(|e| format!("options: {e}"))?;
        let num = |k: &str, d: f64| v.get(k).and_then(|x| x.as_f64()).unwrap_or(d);
        let mut levels = vec![];
        for name in v
            .get("levels")
            .and_then(|l| l.as_array())
            .into_iter()
            .flatten()
        {
            let name = name
                .as_str()
                .unwrap_or_default()
                .trim()
                .to_ascii_lowercase();
            let level = match name.as_str() {
                "best" => Level::Best,
                "high" => Level::High,
                "medium" => Level::Medium,
                "low" => Level::Low,
                other => {
                    return Err(format!("unknown level '{other}' (best, high, medium, low)"));
                }
            };
            if !levels.contains(&level) {
                levels.push(level);
            }
        }
        if levels.is_empty() {
            levels = Level::ALL.to_vec();
        }
        let auto_view = num("autoView", 0.0);
        let o = Options {
            auto_view: if auto_view.is_finite() && auto_view >= 0.0 {
                (auto_view as usize).min(camera::AUTO_VIEW_COUNT - 1)
            } else {
                0
            },
            levels,
            budget_mb: num("budgetMB", 512.0),
            max_sse: num("maxSse", 16.0),
            fov: num("fov", camera::DEFAULT_FOV_Y_DEG),
            camera: match v.get("camera").and_then(|c| c.as_str()) {
                Some(c) if !c.trim().is_empty() => Some(ViewSpec::parse(c)?),
                _ => None,
            },
            walk: match v.get("mode").and_then(|m| m.as_str()).unwrap_or("fly") {
                "walk" => true,
                "fly" => false,
                other => return Err(format!("unknown mode '{other}' (walk, fly)")),
            },
            blend: match v
                .get("blend")
                .and_then(|m| m.as_str())
                .unwrap_or("continuous")
            {
                "continuous" => BlendMode::Continuous,
                "hard" => BlendMode::HardSwap,
                other => return Err(format!("unknown blend '{other}' (continuous, hard)")),
            },
            record: v.get("record").and_then(|r| r.as_bool()).unwrap_or(true),
            predictor: {
                let name = v
                    .get("predictor")
                    .and_then(|m| m.as_str())
                    .unwrap_or("linear");
                PredictorKind::from_name(name).ok_or_else(|| {
                    format!("unknown predictor '{name}' (reactive, constant-velocity, linear, tcn, learned)")
                })?
            },
            prefetch: {
                let name = v
                    .get("prefetch")
                    .and_then(|m| m.as_str())
                    .unwrap_or("balanced");
                Prefetch::from_name(name).ok_or_else(|| {
                    format!("unknown prefetch '{name}' (thrifty, balanced, eager, or seconds)")
                })?
            },
        };
        if !(o.budget_mb.is_finite() && o.budget_mb > 0.0) {
            return Err(format!("budgetMB must be positive, got {}", o.budget_mb));
        }
        if !(o.max_sse.is_finite() && o.max_sse > 0.0) {
            return Err(format!("maxSse must be positive, got {}", o.max_sse));
        }
        if !(o.fov > 0.0 && o.fov < 180.0) {
            return Err(format!("fov must be in (0, 180) degrees, got {}", o.fov));
        }
        Ok(o)
    }
}

/// The web viewer: one per canvas.
#[wasm_bindgen]
pub struct WebViewer {
    shared: Rc<RefCell<Shared>>,
    surface: wgpu::Surface<'static>,
    config: wgpu::SurfaceConfiguration,
    device: wgpu::Device,
    queue: wgpu::Queue,
    renderer: SplatRenderer,
    /// The client's scene in the renderer (layered tilesets: blend factors and the ramp).
    scene: SceneSync,
    /// Blend factors of the layers drawn last frame (layered tilesets; empty otherwise).
    layer_blends: Vec<f32>,
    /// Some drawn layer's late-layer ramp is running (`SceneSync::ramping`).
    ramping: bool,
    /// The last layer error reported on the console (each new one is reported once).
    layer_error: Option<String>,
    adapter_info: wgpu::AdapterInfo,
    options: Options,
    controls: Option<FirstPerson>,
    last_frame: Option<f64>,
    /// Exponential mean of the frame interval, seconds.
    frame_dt: f64,
    /// The last frame drew every tile at full opacity (none fading in or out, the sort order
    /// current) and no scene update has been applied since: what `settled` reports.
    steady: bool,
    /// The camera was turned or jumped by script/input and no frame has planned for it yet:
    /// until one has, idle/settled describe the old view and must not be reported.
    view_unplanned: bool,
    frames: u64,
    drawn: usize,
    sort_ms: f64,
    /// The camera path (tileset frame, 12 Hz, at most an hour) and the page time of its first
    /// pose; recorded while `recording`.
    recorder: Recorder,
    recording: bool,
    rec_t0: Option<f64>,
}

fn js(e: impl std::fmt::Display) -> JsValue {
    JsValue::from_str(&e.to_string())
}

#[wasm_bindgen]
impl WebViewer {
    /// Sets up WebGL2 on `canvas` and starts streaming `tileset_url` (absolute URL).
    pub async fn create(
        canvas: HtmlCanvasElement,
        tileset_url: String,
        width: u32,
        height: u32,
        options_json: String,
    ) -> Result<WebViewer, JsValue> {
        let options = Options::parse(&options_json).map_err(js)?;
        let (width, height) = (width.max(1), height.max(1));
        let mut desc = wgpu::InstanceDescriptor::new_without_display_handle();
        desc.backends = wgpu::Backends::GL;
        let instance = wgpu::Instance::new(desc);
        let surface = instance
            .create_surface(wgpu::SurfaceTarget::Canvas(canvas))
            .map_err(|e| js(format!("cannot use the canvas for WebGL2: {e}")))?;
        let adapter = instance
            .request_adapter(&wgpu::RequestAdapterOptions {
                compatible_surface: Some(&surface),
                ..Default::default()
            })
            .await
            .map_err(|e| js(format!("no WebGL2 adapter: {e}")))?;
        let (device, queue) = splat2tiles_viewer::gpu::request_device(&adapter)
            .await
            .map_err(|e| js(format!("{e:#}")))?;
        let caps = surface.get_capabilities(&adapter);
        // Plain 8-bit output like the reference renderer's PNGs (no sRGB re-encoding).
        let format = caps
            .formats
            .iter()
            .copied()
            .find(|f| !f.is_srgb())
            .or_else(|| caps.formats.first().copied())
            .ok_or_else(|| js("the canvas offers no surface format"))?;
        let config = wgpu::SurfaceConfiguration {
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
            format,
            color_space: wgpu::SurfaceColorSpace::Auto,
            width,
            height,
            present_mode: wgpu::PresentMode::Fifo,
            desired_maximum_frame_latency: 2,
            alpha_mode: caps
                .alpha_modes
                .first()
                .copied()
                .unwrap_or(wgpu::CompositeAlphaMode::Opaque),
            view_formats: vec![],
        };
        surface.configure(&device, &config);
        let rcfg = RendererConfig::default();
        let renderer = SplatRenderer::new(&device, &queue, format, rcfg);
        let ccfg = ClientConfig {
            width,
            height,
            fov_y_deg: options.fov,
            max_sse: options.max_sse,
            memory_budget_bytes: (options.budget_mb * 1048576.0) as u64,
            levels: options.levels.clone(),
            predictor: options.predictor,
            prefetch: options.prefetch,
            ..ClientConfig::default()
        };
        let client = StreamClient::new(&tileset_url, ccfg);
        let recorder = Recorder::at_trace_rate(&[
            ("viewer", "splat2tiles-web".to_string()),
            ("tileset", tileset_url.clone()),
            ("fov_y_deg", format!("{}", options.fov)),
            ("aspect", format!("{:.4}", width as f64 / height as f64)),
        ]);
        let recording = options.record;
        Ok(WebViewer {
            shared: Rc::new(RefCell::new(Shared::new(client))),
            surface,
            config,
            device,
            queue,
            renderer,
            scene: SceneSync::new(options.blend),
            layer_blends: Vec::new(),
            ramping: false,
            layer_error: None,
            adapter_info: adapter.get_info(),
            options,
            controls: None,
            last_frame: None,
            frame_dt: 0.0,
            steady: false,
            view_unplanned: false,
            frames: 0,
            drawn: 0,
            sort_ms: 0.0,
            recorder,
            recording,
            rec_t0: None,
        })
    }

    /// Scene bounds (world) and up, once the client has read the tileset: what
    /// `splat2tiles render --auto-view` uses, so both start from the same camera.
    fn scene_frame(&self) -> Option<((DVec3, DVec3), DVec3)> {
        let s = self.shared.borrow();
        if !s.client.stats().ready {
            return None;
        }
        let root_transform = s.client.root_transform();
        let up = root_transform
            .transform_vector3(DVec3::Z)
            .try_normalize()
            .unwrap_or(DVec3::Z);
        let cat = s.client.catalog();
        let root = *cat.roots.first()?;
        let pts: Vec<DVec3> = cat.tiles[root]
            .bbox
            .corners()
            .iter()
            .map(|c| root_transform.transform_point3(*c))
            .collect();
        let lo = pts.iter().fold(DVec3::splat(f64::MAX), |a, p| a.min(*p));
        let hi = pts.iter().fold(DVec3::splat(f64::MIN), |a, p| a.max(*p));
        Some(((lo, hi), up))
    }

    /// Jumps to automatic viewpoint `k` (0..=7) around the scene.
    pub fn auto_view(&mut self, k: usize) {
        let Some(((lo, hi), up)) = self.scene_frame() else {
            return;
        };
        let k = k.min(camera::AUTO_VIEW_COUNT - 1);
        let cam = camera::auto_views_with(
            lo,
            hi,
            up,
            self.config.width,
            self.config.height,
            self.options.fov,
        )[k];
        self.start_at(&cam, up);
    }

    /// The content's ground along `up`: the lowest corner of the root tile's box (in world; not
    /// of its world-axis-aligned bounds, which sit tens of metres lower for an ECEF root).
    fn ground(&self, up: DVec3) -> f64 {
        let s = self.shared.borrow();
        let root_transform = s.client.root_transform();
        let cat = s.client.catalog();
        cat.roots
            .iter()
            .filter_map(|&i| cat.tiles.get(i))
            .flat_map(|t| t.bbox.corners())
            .map(|c| root_transform.transform_point3(c).dot(up))
            .fold(f64::INFINITY, f64::min)
    }

    /// Controls at `cam`; the content's ground is the root box's lowest corner along `up`.
    fn start_at(&mut self, cam: &Camera, up: DVec3) {
        let ground = self.ground(up);
        let mut c = FirstPerson::from_camera(cam, up, self.options.fov, ground);
        if self.options.walk {
            c.mode = Mode::Walk;
        }
        self.controls = Some(c);
        self.view_unplanned = true;
    }

    /// Jumps to a view given as text (`look-at:...` or `geo:...`, as the stats' `camera`).
    pub fn set_camera(&mut self, spec: &str) -> Result<(), JsValue> {
        let view = ViewSpec::parse(spec).map_err(js)?;
        let Some((_, up)) = self.scene_frame() else {
            self.options.camera = Some(view);
            return Ok(());
        };
        let cam = view.camera(self.config.width, self.config.height, self.options.fov, up);
        self.start_at(&cam, up);
        Ok(())
    }

    /// The current view as text (`geo:` for georeferenced tilesets, else `look-at:`).
    pub fn camera_spec(&self) -> String {
        self.view_spec().map(|v| v.to_string()).unwrap_or_default()
    }

    /// The camera as the overlay shows it: [`ViewSpec::short`], millimetres and 0.01 degrees.
    fn camera_short(&self) -> String {
        self.view_spec().map(|v| v.short()).unwrap_or_default()
    }

    /// The camera's spec: geodetic in an Earth-placed tileset, else look-at; `None` before the
    /// tileset is read.
    fn view_spec(&self) -> Option<ViewSpec> {
        let c = self.controls.as_ref()?;
        let cam = c.camera();
        let geo = is_georeferenced(self.shared.borrow().client.root_transform());
        Some(if geo {
            ViewSpec::geo_of(&cam)
        } else {
            ViewSpec::look_at_of(&cam, c.up)
        })
    }

    /// Renders one frame at page time `now_s` (seconds): input, streaming, uploads, draw.
    pub fn frame(&mut self, now_s: f64) -> Result<(), JsValue> {
        let dt = self.last_frame.map(|t| now_s - t).unwrap_or(0.0);
        self.last_frame = Some(now_s);
        if dt > 0.0 {
            self.frame_dt = if self.frame_dt == 0.0 {
                dt
            } else {
                0.9 * self.frame_dt + 0.1 * dt
            };
        }
        if self.controls.is_none() {
            match self.options.camera {
                Some(view) => {
                    if let Some((_, up)) = self.scene_frame() {
                        let cam = view.camera(
                            self.config.width,
                            self.config.height,
                            self.options.fov,
                            up,
                        );
                        self.start_at(&cam, up);
                    }
                }
                None => self.auto_view(self.options.auto_view),
            }
        }
        if let Some(c) = self.controls.as_mut() {
            c.advance(dt);
        }
        let cam = self.camera();
        self.record_pose(now_s, &cam);
        // Streaming: the client decides, the page fetches.
        let actions = {
            let mut s = self.shared.borrow_mut();
            s.camera = Some(cam);
            s.client.update(now_s, &cam)
        };
        self.view_unplanned = false;
        fetch::dispatch(&self.shared, actions);
        let updates = self.shared.borrow_mut().client.take_updates();
        if !updates.is_empty() {
            // Until a frame draws them (this one, unless the surface is lost below).
            self.steady = false;
        }
        // Shared with the native viewer: updates, then layered opacities (blend + ramp).
        let s = self.shared.borrow();
        match self.scene.apply(
            &mut self.renderer,
            &self.device,
            &self.queue,
            &s.client,
            updates,
            now_s,
        ) {
            Ok(drawn) => {
                self.layer_blends = drawn.iter().map(|l| l.blend).collect();
                self.ramping = self.scene.ramping();
            }
            Err(e) => {
                // The stored opacities stay; the tileset is at fault, not the viewer.
                if self.layer_error.as_deref() != Some(e.as_str()) {
                    web_sys::console::error_1(&format!("layer error: {e}").into());
                    self.layer_error = Some(e);
                }
            }
        }
        drop(s);
        let frame = match self.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(f)
            | wgpu::CurrentSurfaceTexture::Suboptimal(f) => f,
            other => {
                // Lost/outdated (e.g. after a resize): reconfigure and draw next frame.
                let _ = other;
                self.surface.configure(&self.device, &self.config);
                return Ok(());
            }
        };
        let view = frame
            .texture
            .create_view(&wgpu::TextureViewDescriptor::default());
        let stats = self
            .renderer
            .render(&self.device, &self.queue, &view, &cam, now_s);
        self.queue.present(frame);
        self.frames += 1;
        self.drawn = stats.drawn;
        self.steady = !stats.fading && !stats.sort_pending;
        if stats.sorted {
            self.sort_ms = stats.sort_ms;
        }
        Ok(())
    }

    /// Adds the camera at page time `now_s` to the recording (once the controls exist: the
    /// first pose is the start camera), in the tileset frame, times from its first pose.
    fn record_pose(&mut self, now_s: f64, cam: &Camera) {
        if !self.recording || self.controls.is_none() {
            return;
        }
        let t0 = *self.rec_t0.get_or_insert(now_s);
        let root = self.shared.borrow().client.root_transform();
        self.recorder
            .record(pose_of(now_s - t0, cam.world_from_camera, root));
    }

    /// The camera path recorded so far as a `splat2tiles-trace: 1` CSV (what
    /// `splat2tiles-lab simulate --trace` replays; `spec/camera-trace.md`).
    pub fn recording_csv(&self) -> String {
        self.recorder.csv()
    }

    /// Starts a new recording (the old one is forgotten) or stops the current one (kept).
    pub fn set_recording(&mut self, on: bool) {
        if on {
            self.recorder.clear();
            self.rec_t0 = None;
        }
        self.recording = on;
    }

    /// The camera path is being recorded.
    pub fn is_recording(&self) -> bool {
        self.recording
    }

    fn camera(&self) -> Camera {
        match &self.controls {
            Some(c) => c.camera(),
            // Before the tileset is read: any camera; the client only asks for tileset.json.
            None => Camera::look_at(
                self.config.width,
                self.config.height,
                self.options.fov,
                DVec3::new(0.0, -10.0, 0.0),
                DVec3::ZERO,
                DVec3::Z,
            ),
        }
    }

    /// A key went down or up (`KeyboardEvent.code`).
    /// F switches between walking and flying.
    pub fn key(&mut self, code: &str, down: bool, shift: bool) {
        if let Some(c) = self.controls.as_mut() {
            if code == "KeyF" {
                if down {
                    c.toggle_mode();
                }
                return;
            }
            c.key(code, down, shift);
        }
    }

    /// Forgets held keys (focus lost).
    pub fn release_keys(&mut self) {
        if let Some(c) = self.controls.as_mut() {
            c.release_keys();
        }
    }

    /// Turns the view by `dyaw_deg` (left) and `dpitch_deg` (up).
    pub fn look(&mut self, dyaw_deg: f64, dpitch_deg: f64) {
        if let Some(c) = self.controls.as_mut() {
            c.look(dyaw_deg, dpitch_deg);
            self.view_unplanned = true;
        }
    }

    /// The canvas changed size.
    pub fn resize(&mut self, width: u32, height: u32) {
        self.config.width = width.max(1);
        self.config.height = height.max(1);
        self.surface.configure(&self.device, &self.config);
        if let Some(c) = self.controls.as_mut() {
            c.resize(self.config.width, self.config.height);
        }
        // The planner's view of the window (a borrow held elsewhere cannot be: JS is one
        // thread, and no borrow outlives a call).
        if let Ok(mut s) = self.shared.try_borrow_mut() {
            s.client.set_viewport(self.config.width, self.config.height);
        }
    }

    fn stats_value(&self) -> serde_json::Value {
        let s = self.shared.borrow();
        let c = s.client.stats();
        json!({
            "ready": c.ready,
            "frames": self.frames,
            "fps": if self.frame_dt > 0.0 { 1.0 / self.frame_dt } else { 0.0 },
            "residentSplats": self.renderer.resident_splats(),
            // Drawables in the renderer (live and fading out; residentTiles is the client's cache).
            "rendererTiles": self.renderer.resident_tiles(),
            "drawn": self.drawn,
            "clientSplats": c.resident_splats,
            "residentTiles": c.resident_tiles,
            "cacheBytes": c.cache_bytes,
            "gpuBytes": self.renderer.gpu_bytes(),
            "rendererCpuBytes": self.renderer.cpu_bytes(),
            "budgetBytes": (self.options.budget_mb * 1048576.0) as u64,
            // The wasm module's linear memory (everything Rust allocated, high-water: wasm
            // memory never shrinks); outside the JS heap the page's metrics report.
            "wasmBytes": core::arch::wasm32::memory_size::<0>() as u64 * 65536,
            "bandwidth": c.bandwidth,
            "pending": c.pending_fetches,
            "inFlight": s.in_flight(),
            "bytesReceived": c.bytes_received,
            "paused": c.paused_tiles,
            "aborts": s.aborts,
            "resumes": c.resumes,
            "restarts": c.restarts,
            "errors": c.errors,
            "lastErrors": c.last_errors,
            "sortMs": self.sort_ms,
            "camera": self.camera_spec(),
            "mode": self.controls.as_ref().map(|c| c.mode).unwrap_or(Mode::Fly).as_str(),
            "speed": self.controls.as_ref().map(|c| c.speed()).unwrap_or(0.0),
            "idle": !self.view_unplanned
                && s.client.is_idle()
                && s.in_flight() == 0
                && !s.client.has_updates(),
            // The frame on screen is final: drawn after every scene update, with no tile fading
            // in or out (a fading-out tile is still resident, though no longer in the cut).
            "settled": !self.view_unplanned
                && !s.client.has_updates()
                && !self.ramping
                && self.steady,
            "layered": s.client.is_layered(),
            "recording": self.recording,
            "recordedPoses": self.recorder.len(),
            "recordedSeconds": self.recorder.duration(),
            "layerBlends": self.layer_blends,
        })
    }

    /// Stats as JSON (for scripts and tests).
    pub fn stats_json(&self) -> String {
        self.stats_value().to_string()
    }

    /// The overlay's text: FPS, resident splats, cache bytes, bandwidth, pending fetches, the
    /// navigation mode and speed, and the camera (what `camera=` takes).
    pub fn overlay(&self) -> String {
        let v = self.stats_value();
        let f = |k: &str| v[k].as_f64().unwrap_or(0.0);
        format!(
            "{:5.1} fps   {:>9} splats   sort {:.1} ms\ncache {:.1} MB   {:.2} MB/s   {} pending   {} paused{}\n{} {:.1} m/s   camera={}\n{}",
            f("fps"),
            v["residentSplats"],
            f("sortMs"),
            f("cacheBytes") / 1048576.0,
            f("bandwidth") / 1048576.0,
            v["pending"],
            v["paused"],
            match v["errors"].as_u64() {
                Some(0) | None => String::new(),
                Some(n) => format!("   {n} errors"),
            },
            v["mode"].as_str().unwrap_or_default(),
            f("speed"),
            self.camera_short(),
            if self.recording {
                format!(
                    "recording the camera path: {:.1} s (R: stop and save)",
                    self.recorder.duration()
                )
            } else {
                format!(
                    "not recording ({} poses kept; R: record anew)",
                    self.recorder.len()
                )
            },
        )
    }

    /// Runs the committed TCN (`stream::learned`) `runs` times on a steady 10 s walk at 1.4 m/s
    /// along +x and answers JSON: the page's predictor, ms per 30 s prediction (mean and min, the
    /// browser's clock) and the predicted advance along x and sideways drift at 5 s (metres).
    pub fn tcn_check(&self, runs: usize) -> Result<String, JsValue> {
        use splat2tiles_stream::learned::TcnPredictor;
        let t0 = clock_ms();
        let mut p = TcnPredictor::committed().map_err(|e| JsValue::from_str(&e))?;
        let load_ms = clock_ms() - t0;
        let out = self.timed_predictions(&mut p, runs, load_ms);
        match &p.last_error {
            Some(e) => Err(JsValue::from_str(e)),
            None => Ok(out),
        }
    }

    /// [`tcn_check`](Self::tcn_check) for the learned view model (`stream::learned::view_model`).
    pub fn learned_check(&self, runs: usize) -> String {
        let t0 = clock_ms();
        let mut p = splat2tiles_stream::learned::LearnedPredictor::committed();
        let load_ms = clock_ms() - t0;
        self.timed_predictions(&mut p, runs, load_ms)
    }

    /// Times `runs` 30 s predictions of `p` on the check's walk; the JSON of the checks above.
    fn timed_predictions(
        &self,
        p: &mut dyn splat2tiles_stream::predict::Predictor,
        runs: usize,
        load_ms: f64,
    ) -> String {
        use splat2tiles_stream::learned::window::straight_walk;
        let h = straight_walk(10.0, 1.4);
        let now = h[h.len() - 1];
        let (mut sum, mut min, mut out) = (0.0, f64::INFINITY, vec![]);
        for _ in 0..runs.clamp(1, 1000) {
            let t = clock_ms();
            out = p.predict_uncertain(&h, 30.0, 0.5);
            let ms = clock_ms() - t;
            sum += ms;
            min = min.min(ms);
        }
        // The first pose predicted for 5 s ahead (the mean; turned views follow it).
        let at5 = out
            .iter()
            .find(|u| (u.pose.t - now.t - 5.0).abs() < 1e-6)
            .map_or(now.pos, |u| u.pose.pos);
        json!({
            "predictor": format!("{:?}", self.options.predictor),
            "steps": out.len(),
            "loadMs": load_ms,
            "meanMs": sum / runs.clamp(1, 1000) as f64,
            "minMs": min,
            "aheadAt5s": at5.x - now.pos.x,
            "sidewaysAt5s": at5.y - now.pos.y,
            "sigmaAt30s": out.last().map_or(0.0, |u| u.sigma_m),
        })
        .to_string()
    }

    /// The adapter and surface as JSON.
    pub fn info(&self) -> String {
        json!({
            "adapter": self.adapter_info.name,
            "backend": format!("{:?}", self.adapter_info.backend),
            "driver": self.adapter_info.driver_info,
            "format": format!("{:?}", self.config.format),
        })
        .to_string()
    }
}

/// The browser's clock (ms).
fn clock_ms() -> f64 {
    web_sys::window()
        .and_then(|w| w.performance())
        .map_or(0.0, |p| p.now())
}
