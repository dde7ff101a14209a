//! splat2tiles: turns 3D Gaussian Splatting scenes into OGC 3D Tiles 1.1 implicit tilesets of
//! glTF 2.0 `KHR_gaussian_splatting` tiles, and renders, validates and streams them.

#[cfg(feature = "native")]
pub mod cli;
pub mod client;
pub mod convert;
pub mod encode;
pub mod frame;
pub mod io;
pub mod layers;
pub mod limits;
pub mod lod;
pub mod output;
pub mod partition;
pub mod render;
#[cfg(feature = "native")]
pub mod serve;
pub mod sim;
pub mod splat;
pub mod stream;
pub mod tiling;
#[cfg(feature = "native")]
pub mod validate;
pub mod variants;
