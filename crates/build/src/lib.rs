//! Building tilesets: conversion (in memory, out of core, sharded), LOD parents, partitioning,
//! the quality variants' writer and safe output folders.

pub mod convert;
pub mod lod;
pub mod output;
pub mod partition;
pub mod progress;
pub mod variants;
