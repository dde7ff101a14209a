//! Helpers of the viewer's integration tests: the shared scenes, conversion into a temporary
//! tileset, the GPU (fails loudly without an adapter) and GPU-vs-CPU comparisons.
#![allow(dead_code)]

use std::path::{Path, PathBuf};

use glam::DMat4;
use splat2tiles_build::convert::{ConvertOptions, convert};
use splat2tiles_core::splat::Splats;
use splat2tiles_render::raster::{RenderOptions, render};
use splat2tiles_render::{Camera, Image, metrics};
use splat2tiles_viewer::gpu::Headless;
use splat2tiles_viewer::headless::{
    ViewArgs, load_instances, open_tileset, render_instances, tileset_camera,
};
use splat2tiles_viewer::renderer::{FrameStats, RendererConfig};

/// A shared scene (`<repo>/data/scenes/NAME`); panics clearly when it is missing.
pub fn scene(name: &str) -> PathBuf {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../data/scenes")
        .join(name);
    assert!(p.is_file(), "missing shared scene {}", p.display());
    p
}

/// The GPU; a missing adapter fails the test (install mesa-vulkan-drivers) instead of skipping.
pub fn gpu() -> Headless {
    splat2tiles_viewer::gpu::headless()
        .expect("no wgpu adapter: apt-get install mesa-vulkan-drivers libvulkan1 (lavapipe)")
}

/// Converts `input` into `dir/ts` with default options; returns the tileset path.
pub fn convert_to(input: &Path, dir: &Path, opts: &ConvertOptions) -> PathBuf {
    let out = dir.join("ts");
    convert(input, &out, opts).expect("convert");
    out.join("tileset.json")
}

/// A tileset's instances (tiles selected as `splat2tiles render` does) and the camera.
pub fn tileset_view(tileset: &Path, v: &ViewArgs) -> (Vec<(Splats, DMat4)>, Camera) {
    let ts = open_tileset(tileset).unwrap();
    let cam = tileset_camera(&ts, v).unwrap();
    let picked = splat2tiles_tiles::geometry::select_tiles(&ts, &cam, v.max_sse);
    assert!(!picked.is_empty(), "no tile selected");
    (load_instances(&ts, &picked).unwrap(), cam)
}

/// The CPU reference image of `instances`, quantised to 8 bits like the GPU frame.
pub fn reference(instances: &[(Splats, DMat4)], cam: &Camera, opts: &RenderOptions) -> Image {
    let refs: Vec<(&Splats, DMat4)> = instances.iter().map(|(s, m)| (s, *m)).collect();
    render(&refs, cam, opts).quantized()
}

/// GPU frame of `instances`.
pub fn gpu_frame(
    g: &Headless,
    instances: &[(Splats, DMat4)],
    cam: &Camera,
    cfg: RendererConfig,
) -> (Image, FrameStats) {
    render_instances(g, instances, cam, cfg).expect("gpu render")
}

/// SSIM of GPU vs CPU for the same instances; saves both PNGs under `dir` for inspection.
pub fn compare(
    g: &Headless,
    instances: &[(Splats, DMat4)],
    cam: &Camera,
    name: &str,
    dir: &Path,
) -> f64 {
    let cpu = reference(instances, cam, &RenderOptions::default());
    let (img, stats) = gpu_frame(g, instances, cam, RendererConfig::default());
    assert!(stats.drawn > 0, "{name}: nothing drawn");
    let _ = cpu.save_png(&dir.join(format!("{name}_cpu.png")));
    let _ = img.save_png(&dir.join(format!("{name}_gpu.png")));
    let s = metrics::ssim(&cpu, &img).unwrap();
    let p = metrics::psnr(&cpu, &img).unwrap();
    println!(
        "{name}: SSIM {s:.5} PSNR {p:.2} dB ({} splats, {}x{})",
        stats.resident, cam.width, cam.height
    );
    s
}

/// Mean of all channels (to tell an empty frame from a drawn one).
pub fn mean(img: &Image) -> f64 {
    img.data.iter().map(|&v| v as f64).sum::<f64>() / img.data.len().max(1) as f64
}
