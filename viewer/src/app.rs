//! The native window (winit 0.30): first-person controls (WASD, Q/E, F walk/fly, drag to look,
//! shift faster), tiles streamed for the moving camera, a status line (with the camera) per second.

use std::collections::HashSet;
use std::path::Path;
use std::sync::Arc;

use anyhow::Context;
use glam::DVec3;
use splat2tiles_core::camera::Camera;
use splat2tiles_stream::geom::ViewPose;
use winit::application::ApplicationHandler;
use winit::event::{ElementState, MouseButton, WindowEvent};
use winit::event_loop::{ActiveEventLoop, ControlFlow, EventLoop};
use winit::keyboard::{KeyCode, PhysicalKey};
use winit::window::{Window, WindowId};

use splat2tiles_core::view_spec::{ViewSpec, is_georeferenced};
use splat2tiles_render::view::{CameraRequest, resolve_camera};
use splat2tiles_stream::client::native::Driver;

use crate::headless::ViewArgs;
use crate::renderer::{RendererConfig, SplatRenderer};

use crate::nav::{Mode, speed_at};

/// Speed factor while Shift is held.
pub const FAST: f64 = 5.0;
/// Mouse look, radians per pixel dragged.
pub const LOOK_RAD_PER_PX: f64 = 0.004;

/// First-person camera state in the tileset frame (z up).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FlyCamera {
    /// Pose (position, yaw, pitch).
    pub pose: ViewPose,
    /// Vertical field of view, degrees.
    pub fov_y_deg: f64,
    /// Height of the content's ground (lowest z of the root boxes, tileset frame).
    pub ground_z: f64,
    /// Walk (horizontal, height kept) or fly (along the view, Q/E vertical).
    pub mode: Mode,
}

impl FlyCamera {
    /// Speed in metres per second without Shift: proportional to the height above the ground.
    pub fn speed(&self) -> f64 {
        speed_at(self.pose.pos.z - self.ground_z)
    }

    /// Moves by the keys held for `dt` seconds: `fwd`/`right`/`up` in {-1, 0, 1}.
    pub fn step(&mut self, fwd: f64, right: f64, up: f64, fast: bool, dt: f64) {
        if !(dt.is_finite() && dt > 0.0) {
            return;
        }
        let speed = self.speed() * if fast { FAST } else { 1.0 } * dt;
        let [x, _, z] = self.pose.basis();
        let flat = DVec3::new(z.x, z.y, 0.0).normalize_or(DVec3::X);
        let side = DVec3::new(x.x, x.y, 0.0).normalize_or(DVec3::Y);
        let dir = match self.mode {
            Mode::Walk => flat * fwd + side * right,
            Mode::Fly => z * fwd + side * right + DVec3::Z * up,
        };
        self.pose.pos += dir * speed;
    }

    /// Turns by a mouse drag of `(dx, dy)` pixels (pitch clamped short of the poles).
    pub fn look(&mut self, dx: f64, dy: f64) {
        self.pose.yaw -= dx * LOOK_RAD_PER_PX;
        self.pose.pitch = (self.pose.pitch - dy * LOOK_RAD_PER_PX).clamp(-1.5, 1.5);
    }

    /// The pinhole camera for a `width x height` frame, `root` mapping the tileset frame to world.
    pub fn camera(&self, width: u32, height: u32, root: glam::DMat4) -> Camera {
        Camera::from_pose(
            width.max(1),
            height.max(1),
            self.fov_y_deg,
            root * self.pose.world_from_camera(),
        )
    }
}

struct Gfx {
    window: Arc<Window>,
    surface: wgpu::Surface<'static>,
    device: wgpu::Device,
    queue: wgpu::Queue,
    config: wgpu::SurfaceConfiguration,
    renderer: SplatRenderer,
    adapter: String,
}

struct App {
    size: (u32, u32),
    driver: Driver,
    pending: Vec<splat2tiles_stream::client::SceneUpdate>,
    /// Layers whose opacities the renderer holds (layered tilesets).
    scene: crate::layered::SceneSync,
    fly: FlyCamera,
    root: glam::DMat4,
    cfg: RendererConfig,
    gfx: Option<Gfx>,
    error: Option<anyhow::Error>,
    keys: HashSet<KeyCode>,
    dragging: bool,
    last_cursor: Option<(f64, f64)>,
    last_frame: f64,
    log_at: f64,
    frames: u32,
    bytes_at_log: u64,
    /// `--record`: the camera path since the window opened (12 Hz) and its start time.
    record: Option<(crate::record::Recorder, f64)>,
}

impl App {
    fn init(&mut self, el: &ActiveEventLoop) -> anyhow::Result<Gfx> {
        let window = Arc::new(
            el.create_window(
                Window::default_attributes()
                    .with_title("splat2tiles-viewer")
                    .with_inner_size(winit::dpi::PhysicalSize::new(self.size.0, self.size.1)),
            )
            .context("cannot open a window")?,
        );
        let instance = wgpu::Instance::new(wgpu::InstanceDescriptor::new_with_display_handle(
            Box::new(el.owned_display_handle()),
        ));
        let surface = instance
            .create_surface(window.clone())
            .context("cannot create a surface for the window")?;
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            compatible_surface: Some(&surface),
            ..Default::default()
        }))
        .map_err(|e| anyhow::anyhow!("{e}"))
        .context("no GPU adapter can present to this window")?;
        let (device, queue) = pollster::block_on(crate::gpu::request_device(&adapter))?;
        let size = window.inner_size();
        let mut config = surface
            .get_default_config(&adapter, size.width.max(1), size.height.max(1))
            .context("the surface is not supported by the adapter")?;
        // The reference writes linear values straight to 8 bits: prefer a non-sRGB format.
        let caps = surface.get_capabilities(&adapter);
        if let Some(f) = caps.formats.iter().find(|f| !f.is_srgb()) {
            config.format = *f;
        }
        surface.configure(&device, &config);
        let renderer = SplatRenderer::new(&device, &queue, config.format, self.cfg);
        let i = adapter.get_info();
        Ok(Gfx {
            window,
            surface,
            device,
            queue,
            config,
            renderer,
            adapter: format!("{:?} / {}", i.backend, i.name),
        })
    }

    fn frame(&mut self) {
        let now = crate::clock::now_ms() / 1e3;
        let dt = (now - self.last_frame).clamp(0.0, 0.25);
        self.last_frame = now;
        let k = |c| self.keys.contains(&c) as i32 as f64;
        let fwd = k(KeyCode::KeyW) - k(KeyCode::KeyS);
        let right = k(KeyCode::KeyD) - k(KeyCode::KeyA);
        let up = k(KeyCode::KeyE) - k(KeyCode::KeyQ);
        let fast =
            self.keys.contains(&KeyCode::ShiftLeft) || self.keys.contains(&KeyCode::ShiftRight);
        self.fly.step(fwd, right, up, fast, dt);
        if let Some((rec, t0)) = self.record.as_mut() {
            rec.record(ViewPose {
                t: now - *t0,
                ..self.fly.pose
            });
        }
        let Some(g) = self.gfx.as_mut() else { return };
        let cam = self.fly.camera(g.config.width, g.config.height, self.root);
        let mut ups = std::mem::take(&mut self.pending);
        ups.extend(self.driver.tick(now, &cam));
        if let Err(e) = self.scene.apply(
            &mut g.renderer,
            &g.device,
            &g.queue,
            self.driver.client(),
            ups,
            now,
        ) {
            // The stored opacities stay; the tileset is at fault, not the viewer.
            eprintln!("layer error: {e}");
        }
        let frame = match g.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(f)
            | wgpu::CurrentSurfaceTexture::Suboptimal(f) => f,
            wgpu::CurrentSurfaceTexture::Outdated | wgpu::CurrentSurfaceTexture::Lost => {
                g.surface.configure(&g.device, &g.config);
                return;
            }
            _ => return,
        };
        let view = frame
            .texture
            .create_view(&wgpu::TextureViewDescriptor::default());
        let stats = g.renderer.render(&g.device, &g.queue, &view, &cam, now);
        g.queue.present(frame);
        self.frames += 1;
        if now - self.log_at >= 1.0 {
            let span = now - self.log_at;
            let cs = self.driver.stats();
            eprintln!(
                "{:.1} fps | {} resident splats in {} tiles | cache {:.1} MiB (GPU {:.1} MiB) | bandwidth {:.2} MB/s est., {:.2} MB/s received | {} pending fetches | sort {:.1} ms | {} | {} {:.1} m/s --camera {}",
                self.frames as f64 / span,
                stats.resident,
                stats.tiles,
                cs.cache_bytes as f64 / 1048576.0,
                g.renderer.gpu_bytes() as f64 / 1048576.0,
                cs.bandwidth / 1e6,
                cs.bytes_received.saturating_sub(self.bytes_at_log) as f64 / span / 1e6,
                cs.pending_fetches,
                stats.sort_ms,
                g.adapter,
                self.fly.mode.as_str(),
                self.fly.speed(),
                camera_spec(&cam, self.root),
            );
            for e in &cs.last_errors {
                eprintln!("stream error: {e}");
            }
            self.log_at = now;
            self.frames = 0;
            self.bytes_at_log = cs.bytes_received;
        }
    }
}

impl ApplicationHandler for App {
    fn resumed(&mut self, el: &ActiveEventLoop) {
        if self.gfx.is_some() {
            return;
        }
        match self.init(el) {
            Ok(g) => {
                g.window.request_redraw();
                self.gfx = Some(g);
            }
            Err(e) => {
                self.error = Some(e);
                el.exit();
            }
        }
    }

    fn window_event(&mut self, el: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        match event {
            WindowEvent::CloseRequested => el.exit(),
            WindowEvent::Resized(size) => {
                if let Some(g) = self.gfx.as_mut()
                    && size.width > 0
                    && size.height > 0
                {
                    g.config.width = size.width;
                    g.config.height = size.height;
                    g.surface.configure(&g.device, &g.config);
                    self.driver.set_viewport(size.width, size.height);
                }
            }
            WindowEvent::KeyboardInput { event, .. } => {
                if let PhysicalKey::Code(code) = event.physical_key {
                    if code == KeyCode::Escape {
                        el.exit();
                    } else if code == KeyCode::KeyF {
                        if event.state == ElementState::Pressed && !event.repeat {
                            self.fly.mode = self.fly.mode.toggled();
                        }
                    } else if event.state == ElementState::Pressed {
                        self.keys.insert(code);
                    } else {
                        self.keys.remove(&code);
                    }
                }
            }
            WindowEvent::MouseInput {
                state,
                button: MouseButton::Left,
                ..
            } => self.dragging = state == ElementState::Pressed,
            WindowEvent::CursorMoved { position, .. } => {
                let p = (position.x, position.y);
                if self.dragging
                    && let Some(last) = self.last_cursor
                {
                    self.fly.look(p.0 - last.0, p.1 - last.1);
                }
                self.last_cursor = Some(p);
            }
            WindowEvent::RedrawRequested => {
                self.frame();
                if let Some(g) = &self.gfx {
                    g.window.request_redraw();
                }
            }
            _ => {}
        }
    }
}

/// `cam` as a `--camera` spec: `geo:` for a georeferenced tileset (ECEF root), else `look-at:`
/// with the tileset's up.
pub fn camera_spec(cam: &Camera, root: glam::DMat4) -> String {
    if is_georeferenced(root) {
        ViewSpec::geo_of(cam).to_string()
    } else {
        let up = root.transform_vector3(DVec3::Z).normalize_or(DVec3::Z);
        ViewSpec::look_at_of(cam, up).to_string()
    }
}

/// Opens the window on `url` (a path, `file://` or `http://` tileset.json), starting at the camera
/// of `v` (as `splat2tiles render` resolves it against the tileset's root box). `record`: the
/// camera path is written there as a trace CSV when the window closes (whole or not at all).
pub fn run_window(url: &str, v: &ViewArgs, record: Option<&Path>) -> anyhow::Result<()> {
    let (w, h) = (v.width.unwrap_or(1280), v.height.unwrap_or(720));
    let mut driver = crate::stream::driver(url, w, h, v.fov, v.max_sse, v.prefetch);
    let (pending, _) =
        crate::stream::bootstrap(&mut driver, url, crate::clock::now_ms() / 1e3, 30.0)?;
    let (bounds, up_default) = crate::stream::world_bounds(&driver);
    let up = match &v.up_axis {
        Some(s) => splat2tiles_core::camera::parse_axis(s)
            .with_context(|| format!("--up-axis '{s}': expected one of +x,-x,+y,-y,+z,-z"))?,
        None => up_default,
    };
    let req = CameraRequest {
        camera: v.camera.clone(),
        auto_view: v.auto_view,
        width: Some(w),
        height: Some(h),
        fov: v.fov,
    };
    let start = resolve_camera(&req, up, bounds)?;
    let root = driver.client().root_transform();
    // Back to the tileset frame (z up) for the first-person pose.
    let local = root.inverse() * start.world_from_camera;
    let pos = local.w_axis.truncate();
    let fwd = local.z_axis.truncate();
    let cat = driver.client().catalog();
    let ground_z = cat
        .roots
        .iter()
        .filter_map(|&i| cat.tiles.get(i))
        .flat_map(|t| t.bbox.corners())
        .map(|c| c.z)
        .fold(f64::INFINITY, f64::min);
    let fly = FlyCamera {
        pose: ViewPose::looking_at(0.0, pos, pos + fwd),
        fov_y_deg: v.fov,
        ground_z: if ground_z.is_finite() { ground_z } else { 0.0 },
        mode: Mode::Fly,
    };
    let cfg = RendererConfig {
        background: v.background_rgb()?,
        max_sh_degree: v.sh_degree.unwrap_or(3),
        ..RendererConfig::default()
    };
    let event_loop = EventLoop::new().context("no display to open a window on")?;
    event_loop.set_control_flow(ControlFlow::Poll);
    let now = crate::clock::now_ms() / 1e3;
    let mut app = App {
        size: (w, h),
        driver,
        pending,
        scene: crate::layered::SceneSync::default(),
        fly,
        root,
        cfg,
        gfx: None,
        error: None,
        keys: HashSet::new(),
        dragging: false,
        last_cursor: None,
        last_frame: now,
        log_at: now,
        frames: 0,
        bytes_at_log: 0,
        record: record.map(|_| {
            let h = crate::headless::recording_headers(url, v.fov, w, h);
            (crate::record::Recorder::at_trace_rate(&h), now)
        }),
    };
    let ran = event_loop.run_app(&mut app).context("window event loop");
    // The path walked so far is kept even when the window ended on an error.
    if let (Some(path), Some((rec, _))) = (record, &app.record)
        && !rec.is_empty()
    {
        crate::record::write_atomic(path, &rec.csv())?;
        eprintln!(
            "splat2tiles-viewer: recorded {} poses ({:.1} s) -> {}",
            rec.len(),
            rec.duration(),
            path.display()
        );
    }
    ran?;
    match app.error {
        Some(e) => Err(e),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(z: f64, pitch: f64, mode: Mode) -> FlyCamera {
        FlyCamera {
            pose: ViewPose {
                t: 0.0,
                pos: DVec3::new(0.0, 0.0, z),
                yaw: 0.0,
                pitch,
            },
            fov_y_deg: 50.0,
            ground_z: 0.0,
            mode,
        }
    }

    #[test]
    fn walk_keeps_the_eye_height_under_any_pitch() {
        for pitch in [-1.5, -0.8, -0.1, 0.0, 0.4, 1.5] {
            let mut f = at(1.7, pitch, Mode::Walk);
            f.step(1.0, 0.0, 0.0, false, 0.5);
            f.step(0.0, 1.0, 1.0, true, 0.5);
            f.step(-1.0, -1.0, -1.0, false, 0.2);
            assert!(
                (f.pose.pos.z - 1.7).abs() < 1e-12,
                "pitch {pitch}: {:?}",
                f.pose.pos
            );
            assert!(
                f.pose.pos.truncate().length() > 1.0,
                "pitch {pitch}: did not move"
            );
        }
        // Flying along a pitched view changes the height; F toggles the mode.
        let mut f = at(10.0, -0.5, Mode::Walk);
        f.mode = f.mode.toggled();
        f.step(1.0, 0.0, 0.0, false, 0.1);
        assert!(f.pose.pos.z < 10.0);
    }

    #[test]
    fn speed_scales_with_height_and_the_camera_is_finite() {
        let moved = |z: f64| {
            let mut f = at(z, 0.3, Mode::Walk);
            f.step(1.0, 0.0, 0.0, false, 0.1);
            f.pose.pos.truncate().length() / 0.1
        };
        assert!((moved(400.0) / moved(40.0) - 10.0).abs() < 1e-9);
        assert!((moved(1.7) - speed_at(0.0)).abs() < 1e-9);
        let mut f = at(1.7, 0.3, Mode::Fly);
        f.step(0.0, 0.0, 1.0, true, 0.5);
        assert!((f.pose.pos.z - (1.7 + speed_at(1.7) * FAST * 0.5)).abs() < 1e-9);
        f.step(1.0, 0.0, 0.0, false, f64::NAN);
        f.look(100.0, -1e6);
        assert!(f.pose.pitch <= 1.5 && f.pose.yaw < 0.0);
        let cam = f.camera(64, 32, glam::DMat4::IDENTITY);
        assert_eq!((cam.width, cam.height), (64, 32));
        assert!(cam.world_from_camera.is_finite());
        // The status line's camera reproduces the view.
        let spec = camera_spec(&cam, glam::DMat4::IDENTITY);
        let back = ViewSpec::parse(&spec)
            .unwrap()
            .camera(64, 32, 50.0, DVec3::Z);
        assert!(
            back.world_from_camera
                .abs_diff_eq(cam.world_from_camera, 1e-9),
            "{spec}"
        );
    }
}
