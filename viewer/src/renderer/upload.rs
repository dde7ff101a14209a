//! Moving splats into the renderer's paged attribute textures: growing them, packing a tile's
//! centres, shapes and SH (f16) per page piece, and rewriting a layered tile's opacities.

use std::sync::Arc;

use splat2tiles_core::splat::{Splats, normalize_quat};

use super::{PAGE_ROW, PAGE_SPLATS, SplatRenderer, Tile, gl_array_layers, sh_texels};
use crate::alloc::page_pieces;
use crate::sort_job::Chunk;

/// The f16 bit pattern of `v` (the SH texture's texel format).
fn f16_bits(v: f32) -> u16 {
    half::f16::from_f32(v).to_bits()
}

impl SplatRenderer {
    /// Grows the attribute textures for `pages` pages and SH up to `degree`.
    fn ensure_capacity(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        pages: u32,
        degree: u8,
    ) {
        let layers = self.pos.layers;
        if pages > layers {
            let want = gl_array_layers(
                pages
                    .max(layers.saturating_mul(2))
                    .min(self.cfg.max_pages)
                    .max(pages),
            )
            .min(device.limits().max_texture_array_layers.max(pages));
            self.pos = self.pos.grown(device, queue, "splat centres", 1, want);
            self.shape = self.shape.grown(device, queue, "splat shapes", 2, want);
            let b = self.sh.blocks;
            self.sh = self.sh.grown(device, queue, "splat SH", b, want);
            self.bind_group = None;
        }
        if degree > self.sh_capacity_degree {
            let blocks = sh_texels(degree);
            let l = self.sh.layers;
            self.sh = self.sh.grown(device, queue, "splat SH", blocks, l);
            self.sh_capacity_degree = degree;
            self.bind_group = None;
        }
    }

    /// Replaces the opacities of a resident tile: one value per splat passed in (inserted and
    /// appended, in that order), as a layered tileset's blend factors and deltas make them
    /// (`StreamClient::layer_opacities`). Returns false (nothing written) for an unknown id or
    /// a count that is not the tile's.
    pub fn set_opacities(&mut self, queue: &wgpu::Queue, id: u64, opacities: &[f32]) -> bool {
        let Some(tile) = self.tiles.get(&id) else {
            return false;
        };
        if opacities.len() != tile.inputs {
            return false;
        }
        let positions: Vec<[f32; 3]> = tile
            .chunks
            .iter()
            .flat_map(|c| c.positions.iter().copied())
            .collect();
        let mut k = 0usize;
        for run in &tile.runs {
            for (page, local, len) in page_pieces(*run, PAGE_SPLATS, PAGE_ROW) {
                let mut pos = Vec::with_capacity(len as usize * 16);
                for j in k..k + len as usize {
                    let p = positions[j];
                    let o = opacities[tile.source[j] as usize];
                    pos.extend_from_slice(bytemuck::cast_slice(&[p[0], p[1], p[2], o]));
                }
                k += len as usize;
                self.pos.write(queue, page, local, len, 0, &pos);
            }
        }
        true
    }

    /// Uploads `s` as the next splats of `tile`: skips non-finite splats, refuses all of them
    /// when the page budget is full, and records each uploaded splat's slot and input index.
    pub(super) fn upload(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        tile: &mut Tile,
        s: &Splats,
    ) {
        let n_all = s.len();
        let first_input = tile.inputs;
        tile.inputs += n_all;
        let consistent = s.scales.len() == n_all
            && s.rotations.len() == n_all
            && s.opacities.len() == n_all
            && s.sh0.len() == n_all
            && s.sh_rest.len() == n_all * s.rest_per_splat();
        if !consistent {
            self.skipped += n_all;
            return;
        }
        let keep: Vec<usize> = (0..n_all).filter(|&i| s.is_finite(i)).collect();
        self.skipped += n_all - keep.len();
        if keep.is_empty() {
            return;
        }
        let Ok(n) = u32::try_from(keep.len()) else {
            self.refused += keep.len();
            return;
        };
        let Some(runs) = self.alloc.alloc(n) else {
            self.refused += keep.len();
            return;
        };
        let degree = tile.sh_degree;
        self.ensure_capacity(device, queue, self.alloc.pages(), degree);
        let blocks = self.sh.blocks as usize;
        let rest_n = s.rest_per_splat();
        let d = degree as usize + 1;
        let used_coefs = (d * d).min(1 + rest_n);
        let mut positions = Vec::with_capacity(keep.len());
        let mut slots = Vec::with_capacity(keep.len());
        let mut k = 0usize;
        for run in &runs {
            for (page, local, len) in page_pieces(*run, PAGE_SPLATS, PAGE_ROW) {
                let idx = &keep[k..k + len as usize];
                k += len as usize;
                let mut pos = Vec::with_capacity(idx.len() * 16);
                let mut quat = Vec::with_capacity(idx.len() * 16);
                let mut scale = Vec::with_capacity(idx.len() * 16);
                let mut sh = vec![0u16; idx.len() * blocks * 4];
                for (j, &i) in idx.iter().enumerate() {
                    let p = s.positions[i].map(|v| v as f32);
                    positions.push(p);
                    slots.push(page * PAGE_SPLATS + local + j as u32);
                    pos.extend_from_slice(bytemuck::cast_slice(&[
                        p[0],
                        p[1],
                        p[2],
                        s.opacities[i],
                    ]));
                    quat.extend_from_slice(bytemuck::cast_slice(&normalize_quat(s.rotations[i])));
                    let sc = s.scales[i];
                    scale.extend_from_slice(bytemuck::cast_slice(&[
                        sc[0],
                        sc[1],
                        sc[2],
                        tile.row as f32,
                    ]));
                    // Coefficient-major floats (DC first), texel t of splat j lands in block t.
                    let rest = s.rest_of(i);
                    for c in 0..used_coefs {
                        let rgb = if c == 0 { s.sh0[i] } else { rest[c - 1] };
                        for (ch, v) in rgb.iter().enumerate() {
                            let f = c * 3 + ch;
                            let (t, comp) = (f / 4, f % 4);
                            if t < blocks {
                                sh[(t * idx.len() + j) * 4 + comp] = f16_bits(*v);
                            }
                        }
                    }
                }
                self.pos.write(queue, page, local, len, 0, &pos);
                self.shape.write(queue, page, local, len, 0, &quat);
                self.shape.write(queue, page, local, len, 1, &scale);
                let per_block = idx.len() * 4;
                for t in 0..blocks {
                    let part = &sh[t * per_block..(t + 1) * per_block];
                    self.sh.write(
                        queue,
                        page,
                        local,
                        len,
                        t as u32,
                        bytemuck::cast_slice(part),
                    );
                }
            }
        }
        tile.count += keep.len();
        tile.source
            .extend(keep.iter().map(|&i| (first_input + i) as u32));
        tile.runs.extend(runs);
        tile.chunks.push(Arc::new(Chunk { positions, slots }));
    }
}
