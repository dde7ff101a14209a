//! The renderer's GPU textures: paged attribute texture arrays (one page of `PAGE_SPLATS` splats
//! per layer, grown by copy) and the per-tile table the vertex shader reads transforms from.

/// Splats per page (one layer of every attribute texture array).
pub const PAGE_SPLATS: u32 = 1 << PAGE_BITS;
/// log2 of [`PAGE_SPLATS`] (the shader splits slot indices with it).
pub const PAGE_BITS: u32 = 14;
/// Splats per texture row of a page (pages are 128 x 128 splats).
pub const PAGE_ROW: u32 = 128;
/// Tiles per row of the tile table texture.
pub const TILES_PER_ROW: u32 = 256;
/// Texels per tile in the tile table.
pub const TILE_TEXELS: u32 = 5;

/// One attribute texture array: `blocks` texels per splat, stored block-major across the row.
pub(crate) struct AttrTex {
    /// The texture array.
    pub(crate) texture: wgpu::Texture,
    format: wgpu::TextureFormat,
    /// Texels per splat.
    pub(crate) blocks: u32,
    /// Array layers (pages).
    pub(crate) layers: u32,
    /// Bytes per texel.
    pub(crate) texel_bytes: u32,
}

impl AttrTex {
    /// An empty array of `layers` pages, `blocks` texels per splat.
    pub(crate) fn new(
        device: &wgpu::Device,
        label: &str,
        format: wgpu::TextureFormat,
        blocks: u32,
        layers: u32,
    ) -> Self {
        let texture = device.create_texture(&wgpu::TextureDescriptor {
            label: Some(label),
            size: wgpu::Extent3d {
                width: PAGE_ROW * blocks,
                height: PAGE_SPLATS / PAGE_ROW,
                depth_or_array_layers: layers,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage: wgpu::TextureUsages::TEXTURE_BINDING
                | wgpu::TextureUsages::COPY_DST
                | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        });
        let texel_bytes = format.block_copy_size(None).unwrap_or(16);
        AttrTex {
            texture,
            format,
            blocks,
            layers,
            texel_bytes,
        }
    }

    /// GPU bytes it holds.
    pub(crate) fn bytes(&self) -> u64 {
        self.texel_bytes as u64 * PAGE_SPLATS as u64 * self.blocks as u64 * self.layers as u64
    }

    /// A bigger copy (more layers and/or blocks) holding this one's contents.
    pub(crate) fn grown(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        label: &str,
        blocks: u32,
        layers: u32,
    ) -> Self {
        let new = AttrTex::new(device, label, self.format, blocks, layers);
        let mut enc = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("grow attribute texture"),
        });
        enc.copy_texture_to_texture(
            self.texture.as_image_copy(),
            new.texture.as_image_copy(),
            wgpu::Extent3d {
                width: PAGE_ROW * self.blocks.min(blocks),
                height: PAGE_SPLATS / PAGE_ROW,
                depth_or_array_layers: self.layers.min(layers),
            },
        );
        queue.submit([enc.finish()]);
        new
    }

    /// Writes `texels` (block `b` of splats `[local, local + n)` of `page`, row-aligned piece).
    pub(crate) fn write(
        &self,
        queue: &wgpu::Queue,
        page: u32,
        local: u32,
        n: u32,
        block: u32,
        data: &[u8],
    ) {
        let x = local % PAGE_ROW;
        let y = local / PAGE_ROW;
        let (w, h) = if n <= PAGE_ROW - x && (x != 0 || n < PAGE_ROW) {
            (n, 1)
        } else {
            (PAGE_ROW, n / PAGE_ROW)
        };
        queue.write_texture(
            wgpu::TexelCopyTextureInfo {
                texture: &self.texture,
                mip_level: 0,
                origin: wgpu::Origin3d {
                    x: block * PAGE_ROW + x,
                    y,
                    z: page,
                },
                aspect: wgpu::TextureAspect::All,
            },
            data,
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(w * self.texel_bytes),
                rows_per_image: Some(h),
            },
            wgpu::Extent3d {
                width: w,
                height: h,
                depth_or_array_layers: 1,
            },
        );
    }
}

/// The per-tile table (a row of `TILES_PER_ROW` tiles, `TILE_TEXELS` texels each).
pub(crate) fn table_texture(device: &wgpu::Device, rows: u32) -> wgpu::Texture {
    device.create_texture(&wgpu::TextureDescriptor {
        label: Some("splat tile table"),
        size: wgpu::Extent3d {
            width: TILES_PER_ROW * TILE_TEXELS,
            height: rows,
            depth_or_array_layers: 1,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::Rgba32Float,
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    })
}
