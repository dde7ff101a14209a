//! glTF 2.0 / glb encoding of splat tiles with `KHR_gaussian_splatting`: own JSON structs,
//! GLB framing, and the tile writer and reader (layout in ARCHITECTURE.md "glb tile layout").

pub mod glb;
pub mod gltf;
pub mod tile;

pub use glb::GlbError;
pub use tile::{DecodedTile, TileLayout, read_tile_glb, try_write_tile_glb, write_tile_glb};
