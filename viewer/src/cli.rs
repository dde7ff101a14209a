//! Command line of `splat2tiles-viewer`: the clap struct, its validation into a mode, and the
//! dispatch to the headless renderer or the window.

use std::path::PathBuf;

use anyhow::bail;

use crate::headless::{ViewArgs, run_static, run_trace};
use splat2tiles_stream::client::Prefetch;

/// View a splat2tiles tileset: in a window, or headless into PNG files.
#[derive(Debug, Clone, clap::Parser)]
#[command(name = "splat2tiles-viewer", version, about)]
pub struct Cli {
    /// `tileset.json` (a path, or an http:// URL in window/trace modes).
    pub tileset: String,
    /// Render offscreen into --out instead of opening a window.
    #[arg(long)]
    pub headless: bool,
    /// Camera: `PATH/cameras.json[#ID]` or `look-at:EX,EY,EZ:TX,TY,TZ` (as `splat2tiles render`).
    #[arg(long, conflicts_with = "auto_view")]
    pub camera: Option<String>,
    /// One of the 8 automatic viewpoints around the tileset (0..=7).
    #[arg(long)]
    pub auto_view: Option<usize>,
    /// Image width [default: 1280, or the cameras.json entry's].
    #[arg(long)]
    pub width: Option<u32>,
    /// Image height [default: 720, or the cameras.json entry's].
    #[arg(long)]
    pub height: Option<u32>,
    /// Vertical field of view in degrees.
    #[arg(long, default_value_t = splat2tiles_core::camera::DEFAULT_FOV_Y_DEG)]
    pub fov: f64,
    /// Up axis override: +x,-x,+y,-y,+z,-z [default: the tileset's +z].
    #[arg(long, allow_hyphen_values = true)]
    pub up_axis: Option<String>,
    /// Highest SH degree to evaluate [default: all the tiles have].
    #[arg(long)]
    pub sh_degree: Option<u8>,
    /// Background colour R,G,B in [0, 1].
    #[arg(long, default_value = "0,0,0")]
    pub background: String,
    /// Refine tiles while their screen-space error exceeds this many pixels.
    #[arg(long, default_value_t = 16.0)]
    pub max_sse: f64,
    /// Headless: render one frame per pose of this camera trace (splat2tiles trace CSV).
    #[arg(long, conflicts_with_all = ["camera", "auto_view"])]
    pub camera_trace: Option<PathBuf>,
    /// Output folder of the headless modes (frame_0000.png, ...).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// What the streaming client fetches ahead and again: balanced (10 s ahead, a held tile
    /// fetched again only for >= 0.01 utility), thrifty (1.5 s, the same upgrades), eager (10 s,
    /// every upgrade), or seconds ahead with eager's upgrades.
    #[arg(long, default_value = "balanced", value_parser = parse_prefetch)]
    pub prefetch: Prefetch,
    /// Record the camera path (12 Hz, at most one hour) to this CSV (splat2tiles trace, for
    /// `splat2tiles-lab simulate --trace`), written when the window closes; with
    /// --camera-trace, the poses drawn.
    #[arg(long, value_name = "PATH")]
    pub record: Option<PathBuf>,
}

impl Cli {
    /// The camera/selection arguments shared by every mode.
    pub fn view_args(&self) -> ViewArgs {
        ViewArgs {
            camera: self.camera.clone(),
            // Without a camera the window starts at the first automatic viewpoint.
            auto_view: self.auto_view.or(self.camera.is_none().then_some(0)),
            width: self.width,
            height: self.height,
            fov: self.fov,
            up_axis: self.up_axis.clone(),
            sh_degree: self.sh_degree,
            background: self.background.clone(),
            max_sse: self.max_sse,
            prefetch: self.prefetch,
        }
    }
}

fn parse_prefetch(s: &str) -> Result<Prefetch, String> {
    Prefetch::from_name(s).ok_or_else(|| {
        format!("'{s}': expected thrifty, balanced, eager or seconds ahead (e.g. 2.5)")
    })
}

/// Runs the parsed command line.
pub fn run(cli: &Cli) -> anyhow::Result<()> {
    if let Some(path) = &cli.record {
        if cli.headless && cli.camera_trace.is_none() {
            bail!("--record works in the window and with --headless --camera-trace");
        }
        // Refused before the session, not after it.
        crate::record::check_path(path)?;
    }
    if cli.headless {
        let Some(out) = &cli.out else {
            bail!("--headless needs --out DIR");
        };
        if let Some(trace) = &cli.camera_trace {
            let s = run_trace(
                &cli.tileset,
                trace,
                &cli.view_args(),
                out,
                cli.record.as_deref(),
            )?;
            println!(
                "splat2tiles-viewer: {} | {} frames, peak {} resident splats, {:.1} MB streamed, {:.1} ms/frame -> {}",
                s.adapter,
                s.frames,
                s.peak_resident,
                s.bytes_read as f64 / 1e6,
                s.mean_ms,
                out.display()
            );
            for e in &s.errors {
                eprintln!("splat2tiles-viewer: tile error: {e}");
            }
            return Ok(());
        }
        if cli.camera.is_none() && cli.auto_view.is_none() {
            bail!("--headless needs --camera SPEC or --auto-view N");
        }
        let s = run_static(&PathBuf::from(&cli.tileset), &cli.view_args(), out)?;
        println!(
            "splat2tiles-viewer: {} | {} of {} tiles, {} splats ({} drawn) | {:.1} ms (sort {:.1} ms) -> {}",
            s.adapter,
            s.tiles.0,
            s.tiles.1,
            s.splats,
            s.stats.drawn,
            s.ms,
            s.stats.sort_ms,
            s.png.display()
        );
        return Ok(());
    }
    crate::app::run_window(&cli.tileset, &cli.view_args(), cli.record.as_deref())
}
