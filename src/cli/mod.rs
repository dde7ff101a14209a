//! Command-line front ends of the library: argument structs (clap) and one `run` per command,
//! so that `main.rs` only parses and maps results to exit codes.

pub mod convert;
pub mod import_lapisgs;
pub mod serve;
pub mod render;
pub mod shard;
pub mod stats;
pub mod validate;

/// Exit code when the command could not do its work (bad input, I/O failure).
pub const EXIT_FAILURE: i32 = 2;
/// Exit code when a check ran and found errors.
pub const EXIT_FINDINGS: i32 = 1;
