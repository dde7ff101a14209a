//! The viewer's integration tests in one executable (one link of wgpu and the workspace instead
//! of one per file): GPU against the CPU reference, the command line, cities, layers, hard cases.

#[path = "../common/mod.rs"]
mod common;

mod city;
mod cli;
mod golden;
mod layered;
mod robustness;
