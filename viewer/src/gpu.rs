//! Device set-up with WebGL2-class limits, and offscreen rendering with read-back into the CPU
//! reference's [`Image`] (linear RGB, `Rgba8Unorm` target: no sRGB encoding on either side).

use anyhow::{Context, bail};
use splat2tiles_render::Image;

/// The format of offscreen frames: plain 8-bit, like the reference's PNGs.
pub const OFFSCREEN_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;

/// Limits the viewer asks for: WebGL2's, with the adapter's texture size (for big windows).
pub fn viewer_limits(adapter: &wgpu::Adapter) -> wgpu::Limits {
    wgpu::Limits::downlevel_webgl2_defaults().using_resolution(adapter.limits())
}

/// Requests a device and queue from `adapter` with [`viewer_limits`].
pub async fn request_device(
    adapter: &wgpu::Adapter,
) -> anyhow::Result<(wgpu::Device, wgpu::Queue)> {
    adapter
        .request_device(&wgpu::DeviceDescriptor {
            label: Some("splat2tiles-viewer"),
            required_features: wgpu::Features::empty(),
            required_limits: viewer_limits(adapter),
            ..Default::default()
        })
        .await
        .context("the adapter refused a device with WebGL2-class limits")
}

/// A device without any window.
pub struct Headless {
    /// The adapter picked (from `WGPU_BACKEND`/`WGPU_ADAPTER_NAME` when set).
    pub adapter: wgpu::Adapter,
    /// The device.
    pub device: wgpu::Device,
    /// Its queue.
    pub queue: wgpu::Queue,
}

impl Headless {
    /// `backend / name / type` of the adapter, for logs.
    pub fn adapter_name(&self) -> String {
        let i = self.adapter.get_info();
        format!("{:?} / {} / {:?}", i.backend, i.name, i.device_type)
    }
}

/// Opens the default adapter (environment overrides honoured) without a surface.
#[cfg(not(target_arch = "wasm32"))]
pub fn headless() -> anyhow::Result<Headless> {
    let instance =
        wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
    let adapter = pollster::block_on(wgpu::util::initialize_adapter_from_env_or_default(
        &instance, None,
    ))
    .map_err(|e| anyhow::anyhow!("{e}"))
    .context(
        "no GPU adapter found (no GPU here? install Mesa's software Vulkan: \
         apt-get install mesa-vulkan-drivers libvulkan1)",
    )?;
    let (device, queue) = pollster::block_on(request_device(&adapter))?;
    Ok(Headless {
        adapter,
        device,
        queue,
    })
}

/// An offscreen colour target of [`OFFSCREEN_FORMAT`] with a read-back buffer.
pub struct Offscreen {
    /// The texture rendered into.
    pub texture: wgpu::Texture,
    /// Its view.
    pub view: wgpu::TextureView,
    readback: wgpu::Buffer,
    width: u32,
    height: u32,
    padded_row: u32,
}

impl Offscreen {
    /// A `width x height` target (both at least 1).
    pub fn new(device: &wgpu::Device, width: u32, height: u32) -> anyhow::Result<Self> {
        let max = device.limits().max_texture_dimension_2d;
        if width == 0 || height == 0 || width > max || height > max {
            bail!("frame size {width}x{height} outside 1..={max}");
        }
        let texture = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("offscreen frame"),
            size: wgpu::Extent3d {
                width,
                height,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: OFFSCREEN_FORMAT,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        });
        let view = texture.create_view(&wgpu::TextureViewDescriptor::default());
        let padded_row = (width * 4).div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT)
            * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
        let readback = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("offscreen read-back"),
            size: padded_row as u64 * height as u64,
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        Ok(Offscreen {
            texture,
            view,
            readback,
            width,
            height,
            padded_row,
        })
    }

    /// Copies the frame to the CPU (waits for the GPU) as linear RGB in [0, 1].
    pub fn read(&self, device: &wgpu::Device, queue: &wgpu::Queue) -> anyhow::Result<Image> {
        let mut enc = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("read-back"),
        });
        enc.copy_texture_to_buffer(
            self.texture.as_image_copy(),
            wgpu::TexelCopyBufferInfo {
                buffer: &self.readback,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(self.padded_row),
                    rows_per_image: Some(self.height),
                },
            },
            wgpu::Extent3d {
                width: self.width,
                height: self.height,
                depth_or_array_layers: 1,
            },
        );
        queue.submit([enc.finish()]);
        let slice = self.readback.slice(..);
        let (tx, rx) = std::sync::mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |r| {
            let _ = tx.send(r);
        });
        device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| anyhow::anyhow!("device poll failed: {e}"))?;
        rx.recv()
            .context("read-back callback never ran")?
            .map_err(|e| anyhow::anyhow!("read-back mapping failed: {e}"))?;
        let mut rgb = Vec::with_capacity((self.width * self.height * 3) as usize);
        {
            let data = slice
                .get_mapped_range()
                .map_err(|e| anyhow::anyhow!("read-back range: {e}"))?;
            for row in data
                .chunks(self.padded_row as usize)
                .take(self.height as usize)
            {
                for px in row[..(self.width * 4) as usize].chunks_exact(4) {
                    rgb.extend_from_slice(&px[..3]);
                }
            }
        }
        self.readback.unmap();
        Ok(Image::from_rgb8(self.width, self.height, &rgb))
    }
}
