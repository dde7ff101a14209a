//! The splat model, coordinate frames, cameras and view specs shared by every splat2tiles crate:
//! plain data and geometry, no I/O (builds for wasm32).

pub mod camera;
pub mod frame;
pub mod named;
pub mod rng;
pub mod splat;
pub mod view_spec;
