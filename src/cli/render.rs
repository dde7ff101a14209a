//! The `render` and `compare` subcommands: argument structs (clap derive) and the functions that
//! run them, so `main.rs` only parses and dispatches.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context;
use glam::DVec3;

use splat2tiles_core::camera;
use splat2tiles_core::splat::Splats;
use splat2tiles_render::image::Image;
use splat2tiles_render::raster::{RenderOptions, render_with_stats};
use splat2tiles_render::view::{CameraRequest, parse_vec3, resolve_camera};
use splat2tiles_render::{metrics, object};
use splat2tiles_tiles::geometry::{
    Instances, finite_bounds, frame_centres, load_instances, select_tiles, tileset_bounds,
    tileset_up,
};

/// Arguments of `splat2tiles render`.
#[derive(Debug, Clone, clap::Args)]
#[command(group(clap::ArgGroup::new("view").required(true).args(["camera", "auto_view"])))]
pub struct RenderArgs {
    /// Scene file (.ply, .splat, .spz) or a tileset (`tileset.json`).
    pub input: PathBuf,
    /// Camera: `PATH/cameras.json[#ID]` (trainer format; first entry without `#ID`) or
    /// `look-at:EX,EY,EZ:TX,TY,TZ[:UX,UY,UZ]` (world coordinates; image up along UX,UY,UZ, else
    /// --up-axis) or `geo:LON,LAT,HEIGHT:HEADING,PITCH` (degrees, metres; georeferenced tilesets,
    /// heading clockwise from north, pitch above the horizontal): the viewers' stats report these.
    #[arg(long)]
    pub camera: Option<String>,
    /// One of the 8 automatic viewpoints around the scene's bounding box (0..=7).
    #[arg(long)]
    pub auto_view: Option<usize>,
    /// Image width [default: 1280, or the cameras.json entry's].
    #[arg(long)]
    pub width: Option<u32>,
    /// Image height [default: 720, or the cameras.json entry's].
    #[arg(long)]
    pub height: Option<u32>,
    /// Vertical field of view in degrees (ignored with cameras.json).
    #[arg(long, default_value_t = camera::DEFAULT_FOV_Y_DEG)]
    pub fov: f64,
    /// Up axis of the scene file: +x,-x,+y,-y,+z,-z [default: -y; +y for .spz].
    #[arg(long, allow_hyphen_values = true)]
    pub up_axis: Option<String>,
    /// Highest SH degree to evaluate [default: all the scene has].
    #[arg(long)]
    pub sh_degree: Option<u8>,
    /// Background colour R,G,B in [0, 1].
    #[arg(long, default_value = "0,0,0")]
    pub background: String,
    /// Output PNG (the name must end in .png).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Tilesets: refine tiles while their screen-space error exceeds this many pixels.
    #[arg(long, default_value_t = 16.0)]
    pub max_sse: f64,
}

/// Arguments of `splat2tiles compare`.
#[derive(Debug, Clone, clap::Args)]
pub struct CompareArgs {
    /// First image (PNG); with --background, the reference whose object is measured.
    pub a: PathBuf,
    /// Second image (PNG), same size.
    pub b: PathBuf,
    /// Print `{"ssim": .., "psnr": ..}` (psnr null when the images are identical), with an
    /// "object" entry when --background is given.
    #[arg(long)]
    pub json: bool,
    /// Background colour R,G,B in [0, 1] of the renders: also measure the object alone, PSNR over
    /// the pixels where the first image differs from this colour and SSIM on a crop framing them
    /// (whole-frame numbers saturate when the object covers a small part of the frame).
    #[arg(long)]
    pub background: Option<String>,
}

/// The object-only metrics of a comparison (`--background`).
#[derive(Debug, Clone, PartialEq)]
pub struct ObjectScores {
    /// PSNR over the object's pixels (infinite when equal; None without object pixels).
    pub psnr: Option<f64>,
    /// SSIM on the crop framing the object (None without object pixels).
    pub ssim: Option<f64>,
    /// Number of object pixels.
    pub pixels: usize,
    /// The crop `[x, y, width, height]`.
    pub crop: Option<[u32; 4]>,
}

/// The default up axis for a scene file: +y for SPZ (RUB), -y otherwise (COLMAP, y down).
pub fn default_up_axis(path: &Path) -> DVec3 {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    if ext.as_deref() == Some("spz") {
        DVec3::Y
    } else {
        -DVec3::Y
    }
}

/// The camera request of these arguments.
impl RenderArgs {
    pub fn camera_request(&self) -> CameraRequest {
        CameraRequest {
            camera: self.camera.clone(),
            auto_view: self.auto_view,
            width: self.width,
            height: self.height,
            fov: self.fov,
        }
    }
}

/// Runs `render`: reads a scene file or a tileset (tiles chosen by screen-space error for the
/// camera), renders with the CPU reference renderer and writes the PNG.
pub fn run_render(args: &RenderArgs) -> anyhow::Result<()> {
    // Checked before the (possibly long) render: render writes PNG and nothing else.
    if !args
        .output
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("png"))
    {
        anyhow::bail!(
            "{}: render writes PNG images; give an output name ending in .png",
            args.output.display()
        );
    }
    let up_arg = match &args.up_axis {
        Some(s) => Some(
            camera::parse_axis(s)
                .with_context(|| format!("--up-axis '{s}': expected one of +x,-x,+y,-y,+z,-z"))?,
        ),
        None => None,
    };
    let background = parse_vec3(&args.background).context("--background")?;
    let opts = RenderOptions {
        background: background.as_vec3().to_array(),
        max_sh_degree: args.sh_degree.unwrap_or(3),
        ..RenderOptions::default()
    };
    let is_tileset = args
        .input
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("json"));
    let (instances, cam, note) = if is_tileset {
        let ts = splat2tiles_tiles::tiling::load::load_tileset(&args.input)?;
        let up = up_arg.unwrap_or_else(|| tileset_up(&ts));
        let (cam, instances) = tileset_view(args, &ts, up)?;
        let what = if splat2tiles_tiles::layers::view::is_layered(&ts) {
            " layers"
        } else {
            ""
        };
        let note = format!("{}{what} of {} tiles, ", instances.len(), ts.tiles.len());
        (instances, cam, note)
    } else {
        let scene = splat2tiles_io::read_path(&args.input)?;
        let up = up_arg.unwrap_or_else(|| default_up_axis(&args.input));
        let cam = resolve_camera(&args.camera_request(), up, finite_bounds(&scene.splats))?;
        (
            vec![(scene.splats, glam::DMat4::IDENTITY)],
            cam,
            String::new(),
        )
    };
    let refs: Vec<(&Splats, glam::DMat4)> = instances.iter().map(|(s, m)| (s, *m)).collect();
    let t0 = Instant::now();
    let (img, stats) = render_with_stats(&refs, &cam, &opts);
    let ms = t0.elapsed().as_secs_f64() * 1e3;
    img.save_png(&args.output)?;
    eprintln!(
        "splat2tiles: rendered {note}{} splats ({} visible, {} skipped non-finite) at {}x{} in {ms:.1} ms -> {}",
        stats.splats,
        stats.visible,
        stats.non_finite,
        cam.width,
        cam.height,
        args.output.display()
    );
    Ok(())
}

/// The camera and the tile contents it sees. `--auto-view` frames the splat centres, as it does
/// for a scene file (so the same K gives the same picture of a scene and of its tileset).
fn tileset_view(
    args: &RenderArgs,
    ts: &splat2tiles_tiles::tiling::load::LoadedTileset,
    up: DVec3,
) -> anyhow::Result<(camera::Camera, Instances)> {
    let req = args.camera_request();
    let cam = resolve_camera(&req, up, tileset_bounds(ts))?;
    if args.auto_view.is_none() {
        return Ok((cam, tileset_instances(ts, &cam, args.max_sse)?));
    }
    frame_centres(
        cam,
        |cam| tileset_instances(ts, cam, args.max_sse),
        |bounds| Ok(resolve_camera(&req, up, Some(bounds))?),
    )
}

/// The contents `cam` selects (refining while the screen-space error exceeds `max_sse`), each
/// with its world matrix; for layered tilesets the ancestors' layers and blended children.
fn tileset_instances(
    ts: &splat2tiles_tiles::tiling::load::LoadedTileset,
    cam: &camera::Camera,
    max_sse: f64,
) -> anyhow::Result<Instances> {
    if splat2tiles_tiles::layers::view::is_layered(ts) {
        // Layered content: ancestors' layers + blended children (spec/layered-content.md).
        return Ok(splat2tiles_tiles::layers::view::layered_instances(
            ts, cam, max_sse,
        )?);
    }
    Ok(load_instances(ts, &select_tiles(ts, cam, max_sse))?)
}

/// SSIM and PSNR of two PNG files, and with a background colour the object-only scores (the
/// object: where `a` differs from the background).
pub fn compare_images(
    a: &Path,
    b: &Path,
    background: Option<[f32; 3]>,
) -> anyhow::Result<(f64, f64, Option<ObjectScores>)> {
    let ia = Image::load_png(a)?;
    let ib = Image::load_png(b)?;
    let what = || format!("{} vs {}", a.display(), b.display());
    let s = metrics::ssim(&ia, &ib).with_context(what)?;
    let p = metrics::psnr(&ia, &ib)?;
    let object = match background {
        None => None,
        Some(bg) => {
            let mask = object::object_mask(&ia, bg);
            Some(ObjectScores {
                psnr: object::masked_psnr(&ia, &ib, &mask).with_context(what)?,
                ssim: object::object_ssim(&ia, &ib, &mask).with_context(what)?,
                pixels: mask.count,
                crop: object::object_crop(&mask).map(|[x0, y0, x1, y1]| [x0, y0, x1 - x0, y1 - y0]),
            })
        }
    };
    Ok((s, p, object))
}

/// Runs `compare`: prints SSIM and PSNR (text or JSON) on stdout.
pub fn run_compare(args: &CompareArgs) -> anyhow::Result<()> {
    let background = match &args.background {
        None => None,
        Some(b) => {
            let v = parse_vec3(b).context("--background")?.as_vec3().to_array();
            if v.iter().any(|c| !(0.0..=1.0).contains(c)) {
                anyhow::bail!("--background {b}: each of R,G,B must lie in [0, 1]");
            }
            Some(v)
        }
    };
    let (s, p, object) = compare_images(&args.a, &args.b, background)?;
    outln!("{}", format_compare(s, p, object.as_ref(), args.json));
    Ok(())
}

/// A PSNR for JSON: null when infinite (identical images) or absent.
fn json_db(p: Option<f64>) -> serde_json::Value {
    match p {
        Some(p) if p.is_finite() => serde_json::json!(p),
        _ => serde_json::Value::Null,
    }
}

/// The `compare` output line(s).
pub fn format_compare(ssim: f64, psnr: f64, object: Option<&ObjectScores>, json: bool) -> String {
    if json {
        let mut v = serde_json::json!({"ssim": ssim, "psnr": json_db(Some(psnr))});
        if let Some(o) = object {
            v["object"] = serde_json::json!({
                "psnr": json_db(o.psnr),
                "ssim": o.ssim,
                "pixels": o.pixels,
                "crop": o.crop,
            });
        }
        return v.to_string();
    }
    let mut out = format!("SSIM {ssim:.6}\nPSNR {psnr:.3} dB");
    if let Some(o) = object {
        let psnr = o
            .psnr
            .map_or("- (no object pixels)".into(), |p| format!("{p:.3} dB"));
        out += &format!("\nobject PSNR {psnr} over {} pixels", o.pixels);
        match (o.ssim, o.crop) {
            (Some(s), Some([x, y, w, h])) => {
                out += &format!("\nobject SSIM {s:.6} on the {w}x{h} crop at {x},{y}")
            }
            _ => out += "\nobject SSIM - (no object pixels)",
        }
    }
    out
}

#[cfg(test)]
#[path = "render_tests.rs"]
mod tests;
