//! splat2tiles-viewer: a wgpu renderer for splat2tiles tilesets that runs on WebGL2-class devices
//! (paged attribute textures, one global CPU radix sort), plus headless and windowed front-ends.
//!
//! The library ([`SplatRenderer`], [`RendererConfig`], [`FrameStats`]) builds for wasm32 without
//! the `native` feature; the headless modes, the window and the command line are native only.

pub mod alloc;
#[cfg(feature = "native")]
pub mod app;
mod attr_tex;
#[cfg(feature = "native")]
pub mod cli;
pub mod clock;
pub mod gpu;
#[cfg(feature = "native")]
pub mod headless;
pub mod layered;
pub mod nav;
pub mod record;
pub mod renderer;
pub mod sort;
mod sort_job;
#[cfg(feature = "native")]
pub mod stream;

pub use renderer::{FrameStats, RendererConfig, SplatRenderer};
