//! The native viewer's streaming path on a generated city (`splat2tiles::splat::city`, copies of
//! the shared scenes, `../shared/scenes/README.md`), local and georeferenced: the frame drawn
//! from what the client streamed matches the CPU reference of the same camera and tile selection.

mod common;

use std::path::{Path, PathBuf};

use glam::{DMat4, DVec3};
use splat2tiles::convert::{ConvertOptions, convert_scene};
use splat2tiles::frame::UpAxis;
use splat2tiles::frame::geo::Geodetic;
use splat2tiles::render::Camera;
use splat2tiles::render::camera::auto_views_with;
use splat2tiles::render::metrics::ssim;
use splat2tiles::splat::city::{CityLayout, city_scene, generate_city, shared_sources};
use splat2tiles_viewer::gpu::{OFFSCREEN_FORMAT, Offscreen};
use splat2tiles_viewer::headless::{load_instances, open_tileset};
use splat2tiles_viewer::renderer::{RendererConfig, SplatRenderer};
use splat2tiles_viewer::stream::{apply_updates, bootstrap, driver, world_bounds};

use common::*;

/// A city of `n` splats converted into `dir/name` (z up; georeferenced with `origin`).
fn city(dir: &Path, name: &str, n: usize, origin: Option<Geodetic>) -> PathBuf {
    let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/scenes");
    let sources = shared_sources(&scenes).expect("shared scenes");
    let layout = CityLayout {
        splats: n,
        ..CityLayout::default()
    };
    let out = dir.join(name);
    let opts = ConvertOptions {
        up_axis: Some(UpAxis::PosZ),
        origin,
        ..ConvertOptions::default()
    };
    convert_scene(
        city_scene(generate_city(&sources, &layout)),
        name,
        &out,
        &opts,
    )
    .expect("convert city");
    out.join("tileset.json")
}

/// The frame the native streaming path draws for `cam` once the client is idle and fades are
/// over, with the number of splats resident.
fn streamed_frame(url: &str, cam: &Camera, max_sse: f64) -> (splat2tiles::render::Image, usize) {
    let g = gpu();
    let mut d = driver(url, cam.width, cam.height, 50.0, max_sse);
    let (early, mut clock) = bootstrap(&mut d, url, 0.0, 60.0).expect("tileset loads");
    let cfg = RendererConfig {
        blocking_sort: true,
        ..RendererConfig::default()
    };
    let mut r = SplatRenderer::new(&g.device, &g.queue, OFFSCREEN_FORMAT, cfg);
    apply_updates(&mut r, &g.device, &g.queue, early, 0.0);
    for _ in 0..20_000 {
        let ups = d.tick(clock, cam);
        apply_updates(&mut r, &g.device, &g.queue, ups, 0.0);
        if d.is_idle() {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(2));
        clock += 0.002;
    }
    assert!(d.is_idle(), "the client never settled: {:?}", d.stats());
    let target = Offscreen::new(&g.device, cam.width, cam.height).unwrap();
    let stats = r.render(&g.device, &g.queue, &target.view, cam, 100.0);
    let _ = world_bounds(&d);
    (target.read(&g.device, &g.queue).unwrap(), stats.resident)
}

#[test]
fn scratch_stream_frame() {
    let base = Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/tmp-big");
    for name in ["local", "geo"] {
        let ts = base.join(name).join("tileset.json");
        let lt = open_tileset(&ts).unwrap();
        let url = ts.to_str().unwrap();
        let (b, up) = {
            let mut d = driver(url, 320, 240, 50.0, 16.0);
            let _ = bootstrap(&mut d, url, 0.0, 60.0).unwrap();
            world_bounds(&d)
        };
        let (lo, hi) = b.unwrap();
        let cam = auto_views_with(lo, hi, up, 320, 240, 50.0)[0];
        let picked = splat2tiles::render::cli::select_tiles(&lt, &cam, 16.0);
        let inst = load_instances(&lt, &picked).unwrap();
        let cpu = reference(&inst, &cam, &Default::default());
        let (img, n) = streamed_frame(url, &cam, 16.0);
        img.save_png(&base.join(format!("{name}_stream.png")))
            .unwrap();
        println!("{name}: {n} splats SSIM {}", ssim(&cpu, &img).unwrap());
        println!("cam {:?}", cam);
    }
    let _ = (
        DMat4::IDENTITY,
        DVec3::ZERO,
        city as fn(&Path, &str, usize, Option<Geodetic>) -> PathBuf,
    );
}
