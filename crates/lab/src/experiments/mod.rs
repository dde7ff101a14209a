//! The streaming experiments behind `splat2tiles-lab simulate`: the papers' tables on the shared
//! scenes, the generated city and layered content, written as Markdown, CSV and SVG plots.

pub mod simulate;
pub mod simulate_city;
mod simulate_layers;
pub mod simulate_thrift;
pub mod simulate_tool;
pub mod tool_args;
pub mod tool_report;

use std::path::PathBuf;

/// Arguments of `simulate`.
#[derive(Debug, clap::Args)]
pub struct SimulateArgs {
    /// Which experiment: table5, table4, dolly, visibility, traces, city, thrift, layers or all
    /// (all but city, thrift and layers); not used with --tileset.
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
    /// Traces of experiment `city`: `test` (the evaluation) or `val` (the tuning split's
    /// validation traces, where rules are chosen; the same choice of six).
    #[arg(long, default_value = "test", value_parser = ["test", "val"])]
    pub split: String,
    /// HSDPA and FCC throughput logs (experiment `city`; `data/network-traces/README.md`).
    #[arg(long, default_value = "data/network-traces")]
    pub networks: PathBuf,
    /// Splats per tile when tiling the shared scenes.
    #[arg(long, default_value_t = 4096)]
    pub max_splats: u32,
    /// Simulate the client on this tileset (a folder, its tileset.json, or an http:// URL)
    /// instead of running an experiment; needs --trace.
    #[arg(long, help_heading = "Your own tileset")]
    pub tileset: Option<String>,
    /// Camera path: a splat2tiles-trace v1 CSV or an EyeNavGS CSV (spec/camera-trace.md).
    #[arg(long, help_heading = "Your own tileset")]
    pub trace: Option<PathBuf>,
    /// Bandwidth log (lines `TIME_S MBPS`, looped); replaces --bandwidth.
    #[arg(long, help_heading = "Your own tileset")]
    pub network: Option<PathBuf>,
    /// Constant link rate (e.g. 10Mbit, 500kbit, 1Gbit).
    #[arg(long, default_value = "10Mbit", help_heading = "Your own tileset")]
    pub bandwidth: String,
    /// Round trip per request (e.g. 40ms).
    #[arg(long, default_value = "40ms", help_heading = "Your own tileset")]
    pub rtt: String,
    /// Predictor: reactive, constant-velocity, linear, tcn, learned or oracle (the trace itself).
    #[arg(long, default_value = "linear", help_heading = "Your own tileset")]
    pub predictor: String,
    /// Planner: dc-dp, greedy-deadline, greedy-quality or distance-based.
    #[arg(long, default_value = "dc-dp", help_heading = "Your own tileset")]
    pub planner: String,
    /// Client memory budget (e.g. 256MiB).
    #[arg(long, default_value = "256MiB", help_heading = "Your own tileset")]
    pub budget: String,
    /// Client viewport in pixels.
    #[arg(long, default_value = "1280x720", help_heading = "Your own tileset")]
    pub viewport: String,
    /// What the client fetches ahead and again: balanced (10 s ahead, a held tile fetched again
    /// only for >= 0.01 utility; the client's default), thrifty (1.5 s, the same upgrades),
    /// eager (10 s, every upgrade), or seconds ahead with eager's upgrades.
    #[arg(long, default_value = "balanced", help_heading = "Your own tileset")]
    pub prefetch: String,
    /// Requests in flight at most.
    #[arg(long, default_value_t = 4, help_heading = "Your own tileset")]
    pub max_concurrent: usize,
    /// Quality samples per second (rendered; 0: no quality, no TGQ).
    #[arg(long, default_value_t = 1.0, help_heading = "Your own tileset")]
    pub quality_hz: f64,
    /// Where report.md, report.json and the plots go.
    #[arg(
        long,
        default_value = "target/sim/report",
        help_heading = "Your own tileset"
    )]
    pub report_dir: PathBuf,
    /// EyeNavGS traces: tileset-frame position of the session's start, x,y,z (default: the
    /// centre of the tileset's content bounds at their lowest z).
    #[arg(long, allow_hyphen_values = true, help_heading = "Your own tileset")]
    pub anchor: Option<String>,
    /// EyeNavGS traces: rotation of the path about z, degrees.
    #[arg(
        long,
        default_value_t = 0.0,
        allow_hyphen_values = true,
        help_heading = "Your own tileset"
    )]
    pub heading: f64,
    /// EyeNavGS traces: horizontal scale of the path.
    #[arg(long, default_value_t = 1.0, help_heading = "Your own tileset")]
    pub h_scale: f64,
    /// EyeNavGS traces: eye height above the anchor, metres.
    #[arg(long, default_value_t = 1.7, help_heading = "Your own tileset")]
    pub eye_height: f64,
}
