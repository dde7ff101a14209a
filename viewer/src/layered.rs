//! The client's scene in the renderer, shared by the native and web viewers: scene updates
//! applied, and for layered tilesets the layers' effective opacities with the late-layer ramp.
//!
//! Layered tilesets (`spec/layered-content.md`, "Viewers"): inserted layers are drawn without
//! the renderer's insert fade; each drawn layer's blend factor (`StreamClient::layers`) is scaled
//! by `splat2tiles_tiles::layers::ramp` of the time since the viewer first drew it, and the resulting
//! effective opacities (`StreamClient::layer_opacities_of`) are written into the renderer.

use splat2tiles_stream::client::{LayerDraw, SceneUpdate, StreamClient};
use splat2tiles_tiles::layers::ramp::LayerRamp;

use crate::renderer::SplatRenderer;

/// How a viewer turns the client's blend factors into drawn opacities.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum BlendMode {
    /// LapisGS eq. 4 blend factors, each ramped in over `layers::ramp::LAYER_RAMP_S`.
    #[default]
    Continuous,
    /// No blending (a control for tests and measurements): a child layer is drawn fully once
    /// its blend factor reaches 0.5 and not at all before, as a REPLACE viewer swaps tiles.
    HardSwap,
}

/// Applies scene updates to the renderer at time `now_s`: inserts (faded in unless
/// `insert_fade` is off), appends (a progressive download growing), removes (faded out).
pub fn apply_scene_updates(
    r: &mut SplatRenderer,
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    updates: Vec<SceneUpdate>,
    now_s: f64,
) {
    for u in updates {
        match u {
            SceneUpdate::Insert {
                tile,
                splats,
                tile_to_world,
                ..
            } => r.insert_tile(device, queue, tile, &splats, tile_to_world, now_s),
            SceneUpdate::Append { tile, splats } => {
                r.append_tile(device, queue, tile, &splats, now_s)
            }
            SceneUpdate::Remove { tile } => r.remove_tile(tile, now_s),
        }
    }
}

/// What a viewer keeps between frames to draw a client's scene.
#[derive(Debug, Clone, Default)]
pub struct SceneSync {
    /// Blending of layered tilesets.
    pub mode: BlendMode,
    ramp: LayerRamp,
    /// The layers (with the blend factors drawn) last written into the renderer.
    last: Vec<LayerDraw>,
    /// Some drawn layer's ramp was below 1 at the last frame.
    ramping: bool,
}

impl SceneSync {
    /// A sync with the given blend mode.
    pub fn new(mode: BlendMode) -> Self {
        SceneSync {
            mode,
            ..SceneSync::default()
        }
    }

    /// One frame at `now_s` (the viewer's clock, seconds): applies `updates` (the client's,
    /// taken this frame), then for a layered client writes the layers' effective opacities
    /// when the layers or their drawn blend factors changed. Returns the layers drawn (empty
    /// for other tilesets). An inconsistent layer (deltas not matching its parent) leaves the
    /// stored opacities and returns the error (naming the tile).
    pub fn apply(
        &mut self,
        r: &mut SplatRenderer,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        client: &StreamClient,
        updates: Vec<SceneUpdate>,
        now_s: f64,
    ) -> Result<&[LayerDraw], String> {
        let layered = client.is_layered();
        r.set_insert_fade(!layered);
        apply_scene_updates(r, device, queue, updates, now_s);
        if !layered {
            return Ok(&[]);
        }
        let layers = self.drawn_layers(client, now_s);
        if layers != self.last {
            self.last = layers;
            for (sid, ops) in client.layer_opacities_of(&self.last)? {
                r.set_opacities(queue, sid, &ops);
            }
        }
        Ok(&self.last)
    }

    /// Whether some layer drawn at the last frame was still ramping in (its opacities change
    /// with time alone; a viewer is not settled yet).
    pub fn ramping(&self) -> bool {
        self.ramping
    }

    /// The client's layers with the blend factors this viewer draws at `now_s`.
    pub fn drawn_layers(&mut self, client: &StreamClient, now_s: f64) -> Vec<LayerDraw> {
        let mut layers = client.layers();
        let ids: Vec<u64> = layers.iter().map(|l| l.scene_id).collect();
        let ramp = self.ramp.observe(now_s, &ids);
        self.ramping = self.mode == BlendMode::Continuous && ramp.iter().any(|&f| f < 1.0);
        for (l, f) in layers.iter_mut().zip(ramp) {
            l.blend = match self.mode {
                BlendMode::Continuous => l.blend * f,
                BlendMode::HardSwap => {
                    if l.blend >= 0.5 {
                        1.0
                    } else {
                        0.0
                    }
                }
            };
        }
        layers
    }
}
