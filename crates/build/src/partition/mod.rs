//! View-optimised spatial partitioning (SGSS sec. 3.1, eqs. 1-6) within implicit tiling: the cost
//! model over a voxel grid, the view distribution from traces, and the tree DP that scales.
//!
//! The exact ILP over every cuboid of a grid (the paper's formulation) lives with the tests and
//! the `partition_gap` example, which measure the DP's optimality gap against it.

pub mod cost;
pub mod grid;
pub mod plan;
pub mod tree;
pub mod views;

pub use cost::{CostModel, Score, View};
pub use grid::{Cuboid, Grid};
pub use tree::{TreePlan, optimise};
