//! The tileset format: implicit tiling and subtrees, glTF `KHR_gaussian_splatting` glb encode and
//! decode, quality variants, layered content and the tileset geometry viewers and clients share.

pub mod encode;
pub mod geometry;
pub mod layers;
pub mod select;
pub mod tiling;
pub mod variants;
