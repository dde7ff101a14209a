//! Streaming client core: visibility, priorities, bandwidth estimate, deadline-constrained quality
//! selection (DP + baselines), hierarchical cache and trajectory predictors; pure logic, no I/O.
//!
//! Everything here works on plain data ([`TileCatalog`], [`ViewPose`], times as `f64` seconds
//! passed in by the caller), so the native viewer, the wasm viewer and the simulator (`sim`)
//! share it. No `std::fs`, no threads, no clocks.

pub mod bandwidth;
pub mod cache;
pub mod catalog;
pub mod client;
pub mod eyenav;
pub mod geom;
pub mod learned;
pub mod plan;
pub mod planner;
pub mod predict;
pub mod priority;
pub mod split;
pub mod trace;
pub mod visibility;

pub use bandwidth::EwmaBandwidth;
pub use cache::{Cache, CacheConfig, EvictContext};
pub use catalog::{CatalogTile, LEVELS, Level, TileCatalog, Variant, VariantSource};
pub use geom::{Frustum, Intrinsics, Obb, ViewPose};
pub use plan::{Candidate, Fetch, Plan, PlanRequest, Planner};
pub use planner::{LinkForecast, PlanStepConfig, first_visibility, plan_step, plan_visible_link};
pub use predict::{ConstantVelocity, LinearExtrapolation, Oracle, Predictor, Reactive, Uncertain};
pub use visibility::{VisTest, cull_hierarchical};
