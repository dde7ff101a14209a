//! CPU reference renderer (exact 3DGS EWA splatting), pinhole cameras with automatic viewpoints,
//! and SSIM/PSNR: the ground truth every quality number of the project is measured with.
//!
//! Entry points: [`render`] (instances of splat sets with model matrices, seen by a [`Camera`]),
//! [`auto_views`], [`ssim`] and [`psnr`], and their object-only forms in [`object`]. See `raster`
//! for the exact rules followed.

pub mod image;
pub mod metrics;
pub mod object;
pub mod raster;
pub mod view;

pub use image::{Image, ImageError};
pub use metrics::{MetricError, psnr, ssim};
pub use raster::{DepthSort, RenderOptions, RenderStats, render, render_splats, render_with_stats};
pub use splat2tiles_core::camera::{Camera, auto_views, auto_views_with};
