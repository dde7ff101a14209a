//! Helpers shared by the render integration tests: the test-only `.splat` reader and small
//! generated scenes.

#![allow(dead_code)]

pub mod scenes;
pub mod splat_file;
