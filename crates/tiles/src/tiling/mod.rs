//! The tile hierarchy: adaptive partition into implicit-tiling leaves, Morton indexing, binary
//! subtree files and `tileset.json`.

pub mod extent;
pub mod levels;
pub mod load;
pub mod morton;
pub mod partition;
pub mod subtree;
pub mod tileset;
pub mod variant_schema;

pub use partition::{Leaf, Partition, Scheme, TileKey, partition};
