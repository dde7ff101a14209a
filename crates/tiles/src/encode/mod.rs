//! glTF 2.0 / glb encoding of splat tiles with `KHR_gaussian_splatting`: own JSON structs,
//! GLB framing, tile writers (float, interleaved, meshopt, SPZ_2) and their readers.

pub mod codebook;
pub mod codebook_glb;
pub mod exp_filter;
pub mod glb;
pub mod gltf;
pub mod meshopt;
pub mod meshopt_read;
pub mod prefix;
pub mod range_coder;
pub mod spz2;
pub mod spz_rotation;
pub mod storage_order;
pub mod table6;
pub mod tile;
pub mod tile_read;
pub mod vertex_codec;

pub use glb::GlbError;
pub use prefix::decode_prefix;
pub use tile::{TileLayout, try_write_tile_glb, write_tile_glb};
pub use tile_read::{DecodedTile, read_tile_glb};
