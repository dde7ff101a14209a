//! splat2tiles web viewer: the `splat2tiles-viewer` wgpu renderer (WebGL2 backend) and the sans-IO
//! `splat2tiles_stream::client` streaming core, driven by the browser's Fetch API and requestAnimationFrame.

pub mod controls;

#[cfg(target_arch = "wasm32")]
mod fetch;
#[cfg(target_arch = "wasm32")]
mod viewer;

#[cfg(target_arch = "wasm32")]
pub use viewer::WebViewer;
