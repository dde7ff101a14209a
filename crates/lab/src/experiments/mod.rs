//! The streaming experiments behind `splat2tiles-lab simulate`: the papers' tables on the shared
//! scenes, the generated city and layered content, written as Markdown, CSV and SVG plots.

pub mod simulate;
pub mod simulate_city;
mod simulate_layers;

use std::path::PathBuf;

/// Arguments of `simulate`.
#[derive(Debug, clap::Args)]
pub struct SimulateArgs {
    /// Which experiment: table5, table4, dolly, visibility, traces, city, layers or all (all but
    /// city and layers).
    #[arg(long, default_value = "all")]
    pub experiment: String,
    /// Folder of the shared scenes (plant.splat, donut_fused_sh0.ply, biker.spz).
    #[arg(long, default_value = "data/scenes")]
    pub scenes: PathBuf,
    /// Where tables (streaming.md) and work files go.
    #[arg(long, default_value = "target/sim")]
    pub out: PathBuf,
    /// Where SVG plots go.
    #[arg(long, default_value = "docs")]
    pub plots: PathBuf,
    /// Where generated trace files go (experiment `traces`).
    #[arg(long, default_value = "traces")]
    pub traces: PathBuf,
    /// Random seed of every generated input.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Origin (lon,lat,height) recorded in the city traces' headers; the city is built in the
    /// local ENU frame there.
    #[arg(long, default_value = "8.5417,47.3769,408")]
    pub origin: String,
    /// Human navigation traces (experiment `city`; read only through `sim::split`).
    #[arg(long, default_value = crate::sim::stream_city::NAVIGATION_DIR)]
    pub navigation: PathBuf,
    /// HSDPA and FCC throughput logs (experiment `city`; `data/network-traces/README.md`).
    #[arg(long, default_value = "data/network-traces")]
    pub networks: PathBuf,
    /// Splats per tile when tiling the shared scenes.
    #[arg(long, default_value_t = 4096)]
    pub max_splats: u32,
}
