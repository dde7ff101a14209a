//! Helpers shared by the render integration tests: the test-only `.splat` reader and small
//! scene builders.

#![allow(dead_code)]

pub mod splat_file;
