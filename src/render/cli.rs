//! The `render` and `compare` subcommands: argument structs (clap derive) and the functions that
//! run them, so `main.rs` only parses and dispatches.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, bail};
use glam::DVec3;

use super::camera::{self, Camera};
use super::image::Image;
use super::metrics;
use super::raster::{RenderOptions, render_with_stats};
use crate::splat::Splats;

/// Arguments of `splat2tiles render`.
#[derive(Debug, Clone, clap::Args)]
pub struct RenderArgs {
    /// Scene file (.ply, .splat, .spz) or a tileset (`tileset.json`).
    pub input: PathBuf,
    /// Camera: `PATH/cameras.json[#ID]` (trainer format; first entry without `#ID`) or
    /// `look-at:EX,EY,EZ:TX,TY,TZ[:UX,UY,UZ]` (world coordinates; image up along UX,UY,UZ, else
    /// --up-axis) or `geo:LON,LAT,HEIGHT:HEADING,PITCH` (degrees, metres; georeferenced tilesets,
    /// heading clockwise from north, pitch above the horizontal): the viewers' stats report these.
    #[arg(
        long,
        conflicts_with = "auto_view",
        required_unless_present = "auto_view"
    )]
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
    /// Output PNG.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Tilesets: refine tiles while their screen-space error exceeds this many pixels.
    #[arg(long, default_value_t = 16.0)]
    pub max_sse: f64,
}

/// Arguments of `splat2tiles compare`.
#[derive(Debug, Clone, clap::Args)]
pub struct CompareArgs {
    /// First image (PNG).
    pub a: PathBuf,
    /// Second image (PNG), same size.
    pub b: PathBuf,
    /// Print `{"ssim": .., "psnr": ..}` (psnr null when the images are identical).
    #[arg(long)]
    pub json: bool,
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

/// Parses `X,Y,Z` (three finite comma-separated numbers).
pub fn parse_vec3(s: &str) -> anyhow::Result<DVec3> {
    let v: Vec<f64> = s
        .split(',')
        .map(|t| t.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .with_context(|| format!("'{s}': expected three comma-separated numbers"))?;
    match v[..] {
        [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok(DVec3::new(x, y, z)),
        _ => bail!("'{s}': expected three finite comma-separated numbers"),
    }
}

/// Resolves the camera of a `render` invocation for a scene with the given centre bounds.
pub fn resolve_camera(
    args: &RenderArgs,
    up: DVec3,
    bounds: Option<(DVec3, DVec3)>,
) -> anyhow::Result<Camera> {
    let (w, h) = (args.width.unwrap_or(1280), args.height.unwrap_or(720));
    if w == 0 || h == 0 {
        bail!("image size must be positive, got {w}x{h}");
    }
    if !(args.fov > 0.0 && args.fov < 180.0) {
        bail!("--fov must be in (0, 180) degrees, got {}", args.fov);
    }
    if let Some(k) = args.auto_view {
        if k >= camera::AUTO_VIEW_COUNT {
            bail!(
                "--auto-view {k}: there are {} views (0..=7)",
                camera::AUTO_VIEW_COUNT
            );
        }
        let (lo, hi) = bounds.unwrap_or((DVec3::splat(-1.0), DVec3::splat(1.0)));
        return Ok(camera::auto_views_with(lo, hi, up, w, h, args.fov)[k]);
    }
    let spec = args
        .camera
        .as_deref()
        .context("give --camera or --auto-view")?;
    if spec.starts_with("look-at:") || spec.starts_with("geo:") {
        let view = super::view_spec::ViewSpec::parse(spec).map_err(|e| anyhow::anyhow!(e))?;
        return Ok(view.camera(w, h, args.fov, up));
    }
    let (path, id) = match spec.rsplit_once('#') {
        Some((p, id)) => (
            p,
            Some(
                id.parse::<i64>()
                    .with_context(|| format!("{spec}: camera id '{id}' is not an integer"))?,
            ),
        ),
        None => (spec, None),
    };
    let text = std::fs::read_to_string(path).with_context(|| format!("{path}: cannot read"))?;
    let cams =
        camera::parse_cameras_json(&text).with_context(|| format!("{path}: bad cameras.json"))?;
    let entry = match id {
        Some(id) => cams.iter().find(|c| c.id == id),
        None => cams.first(),
    }
    .with_context(|| format!("{spec}: no such camera"))?;
    let cam = entry.to_camera();
    Ok(match (args.width, args.height) {
        (None, None) => cam,
        _ => cam.resized(
            args.width.unwrap_or(cam.width),
            args.height.unwrap_or(cam.height),
        ),
    })
}

/// Bounds of the finite splat centres, `None` when there are none.
pub fn finite_bounds(splats: &Splats) -> Option<(DVec3, DVec3)> {
    let mut it = splats
        .positions
        .iter()
        .map(|&p| DVec3::from(p))
        .filter(|p| p.is_finite());
    let first = it.next()?;
    Some(it.fold((first, first), |(lo, hi), p| (lo.min(p), hi.max(p))))
}

/// Runs `render`: reads a scene file or a tileset (tiles chosen by screen-space error for the
/// camera), renders with the CPU reference renderer and writes the PNG.
pub fn run_render(args: &RenderArgs) -> anyhow::Result<()> {
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
        let ts = crate::tiling::load::load_tileset(&args.input)?;
        let up = up_arg.unwrap_or_else(|| tileset_up(&ts));
        let cam = resolve_camera(args, up, tileset_bounds(&ts))?;
        if crate::layers::view::is_layered(&ts) {
            // Layered content: ancestors' layers + blended children (spec/layered-content.md).
            let instances = crate::layers::view::layered_instances(&ts, &cam, args.max_sse)?;
            let note = format!("{} layers of {} tiles, ", instances.len(), ts.tiles.len());
            (instances, cam, note)
        } else {
            let picked = select_tiles(&ts, &cam, args.max_sse);
            let mut instances = Vec::with_capacity(picked.len());
            for path in &picked {
                let bytes = std::fs::read(path)
                    .with_context(|| format!("{}: cannot read", path.display()))?;
                // Any variant: plain, EXT_meshopt_compression or SPZ_2 compressed.
                let (splats, node) = crate::variants::decode_variant(&bytes)
                    .with_context(|| format!("{}", path.display()))?;
                instances.push((splats, content_model(&ts, &node)));
            }
            let note = format!("{} of {} tiles, ", picked.len(), ts.tiles.len());
            (instances, cam, note)
        }
    } else {
        let scene = crate::io::read_path(&args.input)?;
        let up = up_arg.unwrap_or_else(|| default_up_axis(&args.input));
        let cam = resolve_camera(args, up, finite_bounds(&scene.splats))?;
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

/// World matrix of a tile's content: root transform, then glTF y-up -> 3D Tiles z-up, then the
/// glb node matrix.
pub fn content_model(ts: &crate::tiling::load::LoadedTileset, node: &[f64; 16]) -> glam::DMat4 {
    let y_to_z = glam::DMat4::from_mat3(crate::frame::y_up_to_z_up());
    ts.root_transform * y_to_z * glam::DMat4::from_cols_array(node)
}

/// The tileset's up direction in world coordinates (+z of the root frame).
pub fn tileset_up(ts: &crate::tiling::load::LoadedTileset) -> DVec3 {
    ts.root_transform
        .transform_vector3(DVec3::Z)
        .try_normalize()
        .unwrap_or(DVec3::Z)
}

/// World-space (after the root transform) axis-aligned bounds of the root's tight box.
pub fn tileset_bounds(ts: &crate::tiling::load::LoadedTileset) -> Option<(DVec3, DVec3)> {
    let root = &ts.tiles[ts.root_index()?];
    let corners = box_corners(root.bounding_box.as_ref()?);
    let pts: Vec<DVec3> = corners
        .iter()
        .map(|c| ts.root_transform.transform_point3(*c))
        .collect();
    let lo = pts.iter().fold(DVec3::splat(f64::MAX), |a, p| a.min(*p));
    let hi = pts.iter().fold(DVec3::splat(f64::MIN), |a, p| a.max(*p));
    Some((lo, hi))
}

/// The 8 corners of a 3D Tiles box (centre + three half-axis vectors).
pub fn box_corners(b: &[f64; 12]) -> [DVec3; 8] {
    let c = DVec3::new(b[0], b[1], b[2]);
    let axes = [
        DVec3::new(b[3], b[4], b[5]),
        DVec3::new(b[6], b[7], b[8]),
        DVec3::new(b[9], b[10], b[11]),
    ];
    std::array::from_fn(|i| {
        let s = |k: usize| if i >> k & 1 == 1 { 1.0 } else { -1.0 };
        c + axes[0] * s(0) + axes[1] * s(1) + axes[2] * s(2)
    })
}

/// Screen-space error (pixels) of tile `i` seen by `cam`: geometric error * focal / distance
/// from the eye to its box's bounding sphere (1e-9 inside it or without a box).
pub fn tile_sse(ts: &crate::tiling::load::LoadedTileset, i: usize, cam: &Camera) -> f64 {
    let t = &ts.tiles[i];
    let distance = t
        .bounding_box
        .as_ref()
        .map(|b| {
            let (centre, radius) = crate::stream::select::box_sphere(b, &ts.root_transform);
            (centre.distance(cam.center()) - radius).max(1e-9)
        })
        .unwrap_or(1e-9);
    t.geometric_error * cam.fy / distance
}

/// REPLACE-refinement selection: from the root, a tile is refined into its children while its
/// screen-space error (geometric error * focal / distance to its box) exceeds `max_sse` pixels;
/// the content of every tile reached and not refined is drawn.
pub fn select_tiles(
    ts: &crate::tiling::load::LoadedTileset,
    cam: &Camera,
    max_sse: f64,
) -> Vec<PathBuf> {
    let children = ts.children();
    let Some(root) = ts.root_index() else {
        return vec![];
    };
    let mut out = vec![];
    let mut stack = vec![root];
    while let Some(i) = stack.pop() {
        let t = &ts.tiles[i];
        let sse = tile_sse(ts, i, cam);
        match children.get(&t.key) {
            Some(kids) if sse > max_sse => stack.extend(kids.iter().copied()),
            _ => out.extend(t.content.clone()),
        }
    }
    out.sort();
    out
}

/// SSIM and PSNR of two PNG files.
pub fn compare_files(a: &Path, b: &Path) -> anyhow::Result<(f64, f64)> {
    let ia = Image::load_png(a)?;
    let ib = Image::load_png(b)?;
    let s =
        metrics::ssim(&ia, &ib).with_context(|| format!("{} vs {}", a.display(), b.display()))?;
    let p = metrics::psnr(&ia, &ib)?;
    Ok((s, p))
}

/// Runs `compare`: prints SSIM and PSNR (text or JSON) on stdout.
pub fn run_compare(args: &CompareArgs) -> anyhow::Result<()> {
    let (s, p) = compare_files(&args.a, &args.b)?;
    println!("{}", format_compare(s, p, args.json));
    Ok(())
}

/// The `compare` output line(s).
pub fn format_compare(ssim: f64, psnr: f64, json: bool) -> String {
    if json {
        let p = if psnr.is_finite() {
            serde_json::json!(psnr)
        } else {
            serde_json::Value::Null
        };
        serde_json::json!({"ssim": ssim, "psnr": p}).to_string()
    } else {
        format!("SSIM {ssim:.6}\nPSNR {psnr:.3} dB")
    }
}
