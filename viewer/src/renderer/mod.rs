//! The splat renderer: resident tiles in paged attribute textures, per-tile camera-relative
//! transforms computed in f64 each frame, one global back-to-front sort, instanced quads.
//!
//! Designed for `wgpu::Limits::downlevel_webgl2_defaults()`: no storage buffers, no compute,
//! textures at most 2048 wide, attributes read with `textureLoad` in the vertex shader.

use std::collections::HashMap;
use std::sync::Arc;

use glam::{DMat3, DMat4, DVec3};
use splat2tiles_core::camera::Camera;
use splat2tiles_core::splat::Splats;
use splat2tiles_render::raster::NEAR_Z;

use crate::alloc::{Run, SlotAllocator};
use crate::attr_tex::{AttrTex, table_texture};
use crate::sort_job::{Chunk, SortJob, SortResult, Sorter};

mod pipeline;
mod upload;

pub use crate::attr_tex::{PAGE_BITS, PAGE_ROW, PAGE_SPLATS, TILE_TEXELS, TILES_PER_ROW};
/// Largest 3-sigma footprint (pixels, crude bound) drawn; bigger splats are dropped so that the
/// f32 projection cannot overflow.
pub const MAX_FOOTPRINT_PX: f32 = 1.0e6;

/// A layer count for the attribute texture arrays that WebGL2 binds as `TEXTURE_2D_ARRAY`:
/// wgpu's GL backend picks the GL target from the layer count (1 layer: `TEXTURE_2D`, a multiple
/// of 6 on a square texture: a cube map), and an array view of any other target reads nothing
/// (a scene held in one page drew every splat at its tile's centre, grey). At least 2, never a
/// multiple of 6.
pub const fn gl_array_layers(n: u32) -> u32 {
    let mut n = if n < 2 { 2 } else { n };
    while n % 6 == 0 {
        n += 1;
    }
    n
}

/// Texels of SH data per splat for a degree: `ceil(3 (d+1)^2 / 4)`.
pub const fn sh_texels(degree: u8) -> u32 {
    let d = degree as u32 + 1;
    (3 * d * d).div_ceil(4)
}

// Every texture fits WebGL2's 2048-texel limit, and pages are whole rows.
const _: () = assert!(
    PAGE_ROW * sh_texels(3) <= 2048
        && TILES_PER_ROW * TILE_TEXELS <= 2048
        && PAGE_SPLATS.is_multiple_of(PAGE_ROW)
);

/// Settings of a [`SplatRenderer`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RendererConfig {
    /// Seconds a tile takes to fade in after insert and out after remove.
    pub fade_s: f64,
    /// Re-sort when the camera moved farther than this (metres) since the last sort.
    pub resort_distance: f64,
    /// Re-sort when the view direction turned more than this (degrees) since the last sort.
    pub resort_angle_deg: f64,
    /// Highest SH degree evaluated (and stored).
    pub max_sh_degree: u8,
    /// Clear colour, linear RGB in [0, 1].
    pub background: [f32; 3],
    /// Wait for each needed sort inside `render` (headless and tests); otherwise the frame keeps
    /// the previous order until the worker's new one arrives (native only).
    pub blocking_sort: bool,
    /// Most pages (of [`PAGE_SPLATS`]) to allocate, further capped by the device's
    /// `max_texture_array_layers`.
    pub max_pages: u32,
}

impl Default for RendererConfig {
    fn default() -> Self {
        RendererConfig {
            fade_s: 0.3,
            resort_distance: 2.0,
            resort_angle_deg: 15.0,
            max_sh_degree: 3,
            background: [0.0; 3],
            blocking_sort: false,
            max_pages: 256,
        }
    }
}

/// What one [`SplatRenderer::render`] call did.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FrameStats {
    /// Instances drawn (splats in the current order).
    pub drawn: usize,
    /// Splats resident in the textures (live and fading-out tiles).
    pub resident: usize,
    /// A new order was applied this frame.
    pub sorted: bool,
    /// CPU time of the sort that produced the applied order (keys + radix sort), ms.
    pub sort_ms: f64,
    /// Tiles resident (live and fading out).
    pub tiles: usize,
    /// A sort is running on the worker.
    pub sort_pending: bool,
    /// Splats refused so far because the page budget was full.
    pub refused_splats: usize,
    /// Splats skipped on upload so far for holding NaN/Inf.
    pub skipped_non_finite: usize,
    /// Some tile was drawn part-transparent this frame: fading in, or fading out after a remove.
    pub fading: bool,
}

#[derive(Debug)]
struct Tile {
    row: u32,
    model: DMat4,
    chunks: Vec<Arc<Chunk>>,
    runs: Vec<Run>,
    sh_degree: u8,
    born: f64,
    /// Set by `remove_tile`: the time and the fade-in alpha reached then.
    dying: Option<(f64, f64)>,
    count: usize,
    /// Splats passed in so far (inserted + appended, uploaded or not).
    inputs: usize,
    /// For each uploaded splat, in slot order (the runs'), its index among the inputs.
    source: Vec<u32>,
}

#[repr(C)]
#[derive(Debug, Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct FrameUniform {
    viewport: [f32; 4],
    focal: [f32; 4],
    lim: [f32; 4],
    params: [f32; 4],
}

/// Renders resident splat tiles with WebGL2-compatible wgpu.
pub struct SplatRenderer {
    cfg: RendererConfig,
    pipeline: wgpu::RenderPipeline,
    bgl: wgpu::BindGroupLayout,
    uniform: wgpu::Buffer,
    pos: AttrTex,
    shape: AttrTex,
    sh: AttrTex,
    sh_capacity_degree: u8,
    table: wgpu::Texture,
    table_rows: u32,
    bind_group: Option<wgpu::BindGroup>,
    instances: wgpu::Buffer,
    instance_cap: u64,
    drawn: usize,
    alloc: SlotAllocator,
    tiles: HashMap<u64, Tile>,
    dying: Vec<Tile>,
    free_rows: Vec<u32>,
    next_row: u32,
    /// (resident generation at release, runs, table row) waiting for an order without them.
    pending_free: Vec<(u64, Vec<Run>, u32)>,
    generation: u64,
    order_gen: u64,
    has_order: bool,
    sorter: Sorter,
    last_sort_cam: Option<(DVec3, DVec3)>,
    last_sort_ms: f64,
    refused: usize,
    skipped: usize,
    table_scratch: Vec<f32>,
    /// Inserted tiles fade in over `fade_s` (off for layered tilesets: the layer ramp fades).
    insert_fade: bool,
}

fn instance_buffer(device: &wgpu::Device, cap: u64) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("splat order"),
        size: cap * 4,
        usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

impl SplatRenderer {
    /// A renderer drawing into textures of `target_format`.
    pub fn new(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        target_format: wgpu::TextureFormat,
        cfg: RendererConfig,
    ) -> Self {
        let _ = queue;
        let (pipeline, bgl) = pipeline::splat_pipeline(device, target_format);
        let uniform = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("splat frame uniform"),
            size: std::mem::size_of::<FrameUniform>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let max_pages = cfg
            .max_pages
            .min(device.limits().max_texture_array_layers)
            .max(1);
        let cfg = RendererConfig {
            max_sh_degree: cfg.max_sh_degree.min(3),
            max_pages,
            ..cfg
        };
        let f32x4 = wgpu::TextureFormat::Rgba32Float;
        let layers0 = gl_array_layers(1).min(device.limits().max_texture_array_layers.max(1));
        SplatRenderer {
            cfg,
            pipeline,
            bgl,
            uniform,
            pos: AttrTex::new(device, "splat centres", f32x4, 1, layers0),
            shape: AttrTex::new(device, "splat shapes", f32x4, 2, layers0),
            sh: AttrTex::new(
                device,
                "splat SH",
                wgpu::TextureFormat::Rgba16Float,
                1,
                layers0,
            ),
            sh_capacity_degree: 0,
            table: table_texture(device, 1),
            table_rows: 1,
            bind_group: None,
            instances: instance_buffer(device, 1024),
            instance_cap: 1024,
            drawn: 0,
            alloc: SlotAllocator::new(PAGE_SPLATS, max_pages),
            tiles: HashMap::new(),
            dying: Vec::new(),
            free_rows: Vec::new(),
            next_row: 0,
            pending_free: Vec::new(),
            generation: 0,
            order_gen: 0,
            has_order: false,
            sorter: Sorter::new(),
            last_sort_cam: None,
            last_sort_ms: 0.0,
            refused: 0,
            skipped: 0,
            table_scratch: Vec::new(),
            insert_fade: true,
        }
    }

    /// The configuration in force (page budget capped by the device).
    pub fn config(&self) -> &RendererConfig {
        &self.cfg
    }

    /// Whether tiles inserted from now on fade in over `fade_s` (default) or are drawn at once:
    /// layered tilesets set it off, their layers fade in by blend factor and time ramp
    /// (the `layered` module). Removed tiles fade out either way.
    pub fn set_insert_fade(&mut self, on: bool) {
        self.insert_fade = on;
    }

    /// Adds a tile's splats (tile-local coordinates, as decoded from the glb) with its
    /// tile-to-world matrix; it fades in over `fade_s` (see [`Self::set_insert_fade`]). An id
    /// already resident is replaced at once.
    pub fn insert_tile(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        id: u64,
        splats: &Splats,
        tile_to_world: DMat4,
        now_s: f64,
    ) {
        if let Some(mut old) = self.tiles.remove(&id) {
            old.dying = Some((f64::NEG_INFINITY, 0.0));
            self.dying.push(old);
        }
        let row = match self.free_rows.pop() {
            Some(r) => r,
            None => {
                let r = self.next_row;
                self.next_row += 1;
                r
            }
        };
        let mut tile = Tile {
            row,
            model: tile_to_world,
            chunks: Vec::new(),
            runs: Vec::new(),
            sh_degree: splats.sh_degree.min(self.cfg.max_sh_degree),
            born: if self.insert_fade {
                now_s
            } else {
                f64::NEG_INFINITY
            },
            dying: None,
            count: 0,
            inputs: 0,
            source: Vec::new(),
        };
        self.upload(device, queue, &mut tile, splats);
        self.tiles.insert(id, tile);
        self.generation += 1;
    }

    /// Appends more splats (only the new ones, in tile order) to a resident tile: a progressive
    /// download whose prefix grows. Unknown ids are ignored.
    pub fn append_tile(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        id: u64,
        splats: &Splats,
        now_s: f64,
    ) {
        let _ = now_s;
        let Some(mut tile) = self.tiles.remove(&id) else {
            return;
        };
        tile.sh_degree = tile
            .sh_degree
            .max(splats.sh_degree.min(self.cfg.max_sh_degree));
        self.upload(device, queue, &mut tile, splats);
        self.tiles.insert(id, tile);
        self.generation += 1;
    }

    /// Fades the tile out over `fade_s`, then frees its slots. Unknown ids are ignored.
    pub fn remove_tile(&mut self, id: u64, now_s: f64) {
        if let Some(mut t) = self.tiles.remove(&id) {
            let a = self.fade_in(&t, now_s);
            t.dying = Some((now_s, a));
            self.dying.push(t);
        }
    }

    /// Splats resident on the GPU (live and fading-out tiles).
    pub fn resident_splats(&self) -> usize {
        self.tiles
            .values()
            .chain(&self.dying)
            .map(|t| t.count)
            .sum()
    }

    /// Tiles resident (live and fading-out).
    pub fn resident_tiles(&self) -> usize {
        self.tiles.len() + self.dying.len()
    }

    /// GPU memory held: attribute textures, tile table, order buffer, uniforms.
    pub fn gpu_bytes(&self) -> u64 {
        self.pos.bytes()
            + self.shape.bytes()
            + self.sh.bytes()
            + (TILES_PER_ROW * TILE_TEXELS * self.table_rows) as u64 * 16
            + self.instance_cap * 4
            + std::mem::size_of::<FrameUniform>() as u64
    }

    /// CPU memory kept: per-splat positions and slots, sort buffers, tile table scratch.
    pub fn cpu_bytes(&self) -> u64 {
        let chunks: usize = self
            .tiles
            .values()
            .chain(&self.dying)
            .flat_map(|t| &t.chunks)
            .map(|c| c.positions.capacity() * 12 + c.slots.capacity() * 4)
            .sum();
        // The worker's buffers mirror the inline ones: two u64 arrays of the resident count.
        let worker = self.resident_splats() * 16;
        (chunks + self.sorter.bytes() + worker + self.table_scratch.capacity() * 4) as u64
    }

    /// Bytes of GPU texture memory per allocated splat slot (all attribute textures).
    pub fn texture_bytes_per_slot(&self) -> f64 {
        (self.pos.texel_bytes * self.pos.blocks
            + self.shape.texel_bytes * self.shape.blocks
            + self.sh.texel_bytes * self.sh.blocks) as f64
    }

    fn fade_in(&self, t: &Tile, now: f64) -> f64 {
        if self.cfg.fade_s > 0.0 {
            ((now - t.born) / self.cfg.fade_s).clamp(0.0, 1.0)
        } else {
            1.0
        }
    }

    fn alpha(&self, t: &Tile, now: f64) -> f64 {
        match t.dying {
            None => self.fade_in(t, now),
            Some((since, a0)) => {
                if self.cfg.fade_s > 0.0 && since.is_finite() {
                    a0 * (1.0 - (now - since) / self.cfg.fade_s).clamp(0.0, 1.0)
                } else {
                    0.0
                }
            }
        }
    }

    /// Camera-from-tile rows (f64 -> f32, relative to the camera centre) and the camera centre
    /// in the tile frame; `None` for a non-finite or singular model.
    fn tile_frame(model: DMat4, cam: &Camera) -> Option<([[f32; 4]; 3], [f32; 3])> {
        if !model.is_finite() {
            return None;
        }
        let a = DMat3::from_mat4(model);
        let t = model.w_axis.truncate();
        let c = cam.center();
        let cam_from_world = cam.rotation().transpose();
        let m = cam_from_world * a;
        let b = cam_from_world * (t - c);
        let det = a.determinant();
        if !(det.is_finite() && det.abs() > 1e-300) {
            return None;
        }
        let cl = a.inverse() * (c - t);
        if !cl.is_finite() {
            return None;
        }
        let rows = [0, 1, 2].map(|r| {
            let row = m.row(r);
            [row.x as f32, row.y as f32, row.z as f32, b[r] as f32]
        });
        Some((rows, [cl.x as f32, cl.y as f32, cl.z as f32]))
    }

    fn apply_result(&mut self, queue: &wgpu::Queue, device: &wgpu::Device, r: SortResult) {
        let n = r.order.len() as u64;
        if n > self.instance_cap {
            self.instance_cap = n.next_power_of_two().max(1024);
            self.instances = instance_buffer(device, self.instance_cap);
        }
        if n > 0 {
            queue.write_buffer(&self.instances, 0, bytemuck::cast_slice(&r.order));
        }
        self.drawn = r.order.len();
        self.order_gen = r.generation;
        self.has_order = true;
        self.last_sort_ms = r.ms;
        // Slots of tiles gone before this order was requested can now be reused.
        let mut freed = Vec::new();
        self.pending_free.retain(|(g, runs, row)| {
            if *g <= r.generation {
                freed.push((runs.clone(), *row));
                false
            } else {
                true
            }
        });
        for (runs, row) in freed {
            self.alloc.free(&runs);
            self.free_rows.push(row);
        }
    }

    fn make_job(&self, cam: &Camera) -> SortJob {
        let mut chunks = Vec::new();
        for t in self.tiles.values().chain(&self.dying) {
            let Some((rows, _)) = Self::tile_frame(t.model, cam) else {
                continue;
            };
            for c in &t.chunks {
                chunks.push((c.clone(), rows[2]));
            }
        }
        SortJob {
            generation: self.generation,
            chunks,
        }
    }

    fn needs_sort(&self, cam: &Camera) -> bool {
        if !self.has_order || self.order_gen != self.generation {
            return true;
        }
        let Some((c, f)) = self.last_sort_cam else {
            return true;
        };
        let fwd = cam.rotation().z_axis;
        let moved = cam.center().distance(c) > self.cfg.resort_distance;
        let cos = fwd.dot(f).clamp(-1.0, 1.0);
        let turned = cos.acos().to_degrees() > self.cfg.resort_angle_deg;
        moved || turned
    }

    /// Writes the tile table for `camera` (each tile's camera-relative rows, fade and SH degree;
    /// f64 on the CPU), growing the texture when more rows are needed.
    fn upload_tile_table(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        camera: &Camera,
        now_s: f64,
    ) {
        let rows_needed = self.next_row.div_ceil(TILES_PER_ROW).max(1);
        if rows_needed > self.table_rows {
            let max_rows = device.limits().max_texture_dimension_2d.max(1);
            self.table_rows = rows_needed.next_power_of_two().min(max_rows);
            self.table = table_texture(device, self.table_rows);
            self.bind_group = None;
        }
        let row_floats = (TILES_PER_ROW * TILE_TEXELS * 4) as usize;
        let mut table = std::mem::take(&mut self.table_scratch);
        table.clear();
        table.resize(row_floats * self.table_rows as usize, 0.0);
        let cap_deg = self.sh_capacity_degree;
        for t in self.tiles.values().chain(&self.dying) {
            let Some((rows, cl)) = Self::tile_frame(t.model, camera) else {
                continue;
            };
            let base = (t.row * TILE_TEXELS * 4) as usize;
            if base + 20 > table.len() {
                continue;
            }
            let a = self.alpha(t, now_s) as f32;
            let deg = t.sh_degree.min(cap_deg) as f32;
            let vals: [f32; 20] = [
                rows[0][0], rows[0][1], rows[0][2], rows[0][3], rows[1][0], rows[1][1], rows[1][2],
                rows[1][3], rows[2][0], rows[2][1], rows[2][2], rows[2][3], cl[0], cl[1], cl[2], a,
                deg, 0.0, 0.0, 0.0,
            ];
            table[base..base + 20].copy_from_slice(&vals);
        }
        queue.write_texture(
            self.table.as_image_copy(),
            bytemuck::cast_slice(&table),
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(TILES_PER_ROW * TILE_TEXELS * 16),
                rows_per_image: Some(self.table_rows),
            },
            wgpu::Extent3d {
                width: TILES_PER_ROW * TILE_TEXELS,
                height: self.table_rows,
                depth_or_array_layers: 1,
            },
        );
        self.table_scratch = table;
    }

    /// Creates the bind group when the textures changed since the last one.
    fn ensure_bind_group(&mut self, device: &wgpu::Device) {
        if self.bind_group.is_none() {
            let view = |t: &wgpu::Texture, d| {
                t.create_view(&wgpu::TextureViewDescriptor {
                    dimension: Some(d),
                    ..Default::default()
                })
            };
            let arr = wgpu::TextureViewDimension::D2Array;
            let (v1, v2, v3) = (
                view(&self.pos.texture, arr),
                view(&self.shape.texture, arr),
                view(&self.sh.texture, arr),
            );
            let v4 = view(&self.table, wgpu::TextureViewDimension::D2);
            self.bind_group = Some(device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("splat bind group"),
                layout: &self.bgl,
                entries: &[
                    wgpu::BindGroupEntry {
                        binding: 0,
                        resource: self.uniform.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 1,
                        resource: wgpu::BindingResource::TextureView(&v1),
                    },
                    wgpu::BindGroupEntry {
                        binding: 2,
                        resource: wgpu::BindingResource::TextureView(&v2),
                    },
                    wgpu::BindGroupEntry {
                        binding: 3,
                        resource: wgpu::BindingResource::TextureView(&v3),
                    },
                    wgpu::BindGroupEntry {
                        binding: 4,
                        resource: wgpu::BindingResource::TextureView(&v4),
                    },
                ],
            }));
        }
    }

    /// Renders one frame into `target` (cleared to the background) and returns its stats.
    pub fn render(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        target: &wgpu::TextureView,
        camera: &Camera,
        now_s: f64,
    ) -> FrameStats {
        let mut stats = FrameStats::default();
        // 1. Tiles whose fade-out ended leave the sorted set.
        let mut i = 0;
        while i < self.dying.len() {
            if self.alpha(&self.dying[i], now_s) <= 0.0 {
                let t = self.dying.swap_remove(i);
                self.generation += 1;
                self.pending_free.push((self.generation, t.runs, t.row));
            } else {
                i += 1;
            }
        }
        stats.fading =
            !self.dying.is_empty() || self.tiles.values().any(|t| self.fade_in(t, now_s) < 1.0);
        // 2. Newest order from the worker; then a new sort when needed.
        let blocking = self.cfg.blocking_sort || cfg!(target_arch = "wasm32");
        if let Some(r) = self.sorter.poll(blocking) {
            self.apply_result(queue, device, r);
            stats.sorted = true;
        }
        if camera.width > 0
            && camera.height > 0
            && self.needs_sort(camera)
            && !self.sorter.in_flight
        {
            let job = self.make_job(camera);
            self.last_sort_cam = Some((camera.center(), camera.rotation().z_axis));
            self.sorter.submit(job);
            if let Some(r) = self.sorter.poll(blocking) {
                self.apply_result(queue, device, r);
                stats.sorted = true;
            }
        }
        // 3. Tile table for this camera (f64 on the CPU, camera-relative).
        self.upload_tile_table(device, queue, camera, now_s);
        let (w, h) = (camera.width as f64, camera.height as f64);
        let (fx, fy) = (camera.fx, camera.fy);
        let ext_x = 0.3 * w / (2.0 * fx);
        let ext_y = 0.3 * h / (2.0 * fy);
        let u = FrameUniform {
            viewport: [w as f32, h as f32, 0.0, 0.0],
            focal: [fx as f32, fy as f32, camera.cx as f32, camera.cy as f32],
            lim: [
                (-camera.cx / fx - ext_x) as f32,
                ((w - camera.cx) / fx + ext_x) as f32,
                (-camera.cy / fy - ext_y) as f32,
                ((h - camera.cy) / fy + ext_y) as f32,
            ],
            params: [NEAR_Z as f32, 3.0, MAX_FOOTPRINT_PX, 0.0],
        };
        queue.write_buffer(&self.uniform, 0, bytemuck::bytes_of(&u));
        self.ensure_bind_group(device);
        // 4. Draw.
        let bg = self.cfg.background.map(|v| v as f64);
        let mut enc = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("splat frame"),
        });
        {
            let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("splats"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: target,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color {
                            r: bg[0],
                            g: bg[1],
                            b: bg[2],
                            a: 1.0,
                        }),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: None,
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            if self.drawn > 0
                && let Some(bg) = &self.bind_group
            {
                pass.set_pipeline(&self.pipeline);
                pass.set_bind_group(0, bg, &[]);
                pass.set_vertex_buffer(0, self.instances.slice(..));
                pass.draw(0..4, 0..self.drawn as u32);
            }
        }
        queue.submit([enc.finish()]);
        stats.drawn = self.drawn;
        stats.resident = self.resident_splats();
        stats.tiles = self.resident_tiles();
        stats.sort_ms = self.last_sort_ms;
        stats.sort_pending = self.sorter.in_flight;
        stats.refused_splats = self.refused;
        stats.skipped_non_finite = self.skipped;
        stats
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn array_layer_counts_stay_arrays_on_webgl() {
        assert_eq!(gl_array_layers(0), 2);
        assert_eq!(gl_array_layers(1), 2);
        assert_eq!(gl_array_layers(2), 2);
        assert_eq!(gl_array_layers(5), 5);
        assert_eq!(gl_array_layers(6), 7);
        assert_eq!(gl_array_layers(12), 13);
        for n in 0..2048 {
            let l = gl_array_layers(n);
            assert!(
                l >= n.max(2) && !l.is_multiple_of(6) && l <= n.max(2) + 1,
                "{n} -> {l}"
            );
        }
    }

    #[test]
    fn sh_texel_counts() {
        assert_eq!(
            [0, 1, 2, 3].map(sh_texels),
            [1, 3, 7, 12],
            "3 (d+1)^2 floats in RGBA texels"
        );
    }
}
