//! The integration tests of splat2tiles in one executable (one link of the workspace instead of
//! one per file): the CLI, conversion, formats, rendering, streaming and validation suites.

#[path = "../common/mod.rs"]
mod common;

mod client_layered;
mod client_stream;
mod codebook_variant;
mod compare_cli;
mod completeness;
mod conformance;
mod convert;
mod convert_ooc;
mod convert_parts;
mod external;
mod georeferencing;
mod glb_khronos_validator;
mod glb_roundtrip;
mod glb_splat_transform;
mod io_readers;
mod lapis_import;
mod layered_content;
mod lod_hierarchy;
mod lod_levels;
mod lod_merge;
mod partition_convert;
mod partition_ilp;
mod render_metrics;
mod render_raster;
mod render_reference;
mod stream_cache;
mod stream_plan;
mod validate_cli;
mod validate_hostile;
mod validate_outputs;
mod validate_robustness;
mod validate_schema;
mod variants_curve;
mod variants_estimate;
mod variants_prefix;
mod variants_quality;
mod variants_utility;
mod variants_validator;
