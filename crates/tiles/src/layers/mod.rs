//! Layered progressive content (LapisGS sec. 3.1-3.3) over our LOD tree: a tile's content is its
//! layer, drawn on top of its ancestors' layers whose opacities each child layer adjusts.
//!
//! The form (`SPLAT2TILES_layer` primitive extension, ADD refinement, occupancy and blending
//! rules) is defined in `spec/layered-content.md`; [`glb`] reads and writes it, [`deltas`]
//! derives the opacity deltas from our LOD, [`blend`] composes what a viewer draws, [`ramp`]
//! fades in layers that arrive late, and [`build`] turns a converted tileset folder into a layered one.

pub mod blend;
pub mod build;
pub mod deltas;
pub mod glb;
pub mod ramp;
pub mod view;

/// Name of the glTF primitive extension that marks a layer and carries its parent's deltas.
pub const EXTENSION: &str = "SPLAT2TILES_layer";

/// Occupancy rule (LapisGS sec. 3.2, the 3DGS pruning threshold): a splat whose effective
/// opacity is below this is not drawn.
pub const OCCUPANCY_THRESHOLD: f32 = 0.005;

/// Slack on the sum of one parent splat's deltas over its child layers (which must be >= -1):
/// f32 rounding of shares that add up to exactly one.
pub const DELTA_SUM_TOLERANCE: f32 = 1e-4;
