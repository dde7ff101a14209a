//! The native viewer on a generated city (`splat2tiles_lab::city`, copies of every 8th splat
//! of the shared scenes, `data/scenes/README.md`), local and georeferenced: overview (also at
//! maxSse 64: coarse root splats only) and street view, headless from the tile selection of
//! `splat2tiles render` and from what the streaming client fetched, vs the CPU reference.

use std::path::{Path, PathBuf};

use glam::DVec3;
use splat2tiles_build::convert::{ConvertOptions, convert_scene};
use splat2tiles_core::frame::UpAxis;
use splat2tiles_core::frame::geo::Geodetic;
use splat2tiles_lab::city::{CityLayout, city_scene, generate_city, shared_sources};
use splat2tiles_render::metrics::ssim;
use splat2tiles_render::{Camera, Image};
use splat2tiles_stream::client::Prefetch;
use splat2tiles_viewer::gpu::{Headless, OFFSCREEN_FORMAT, Offscreen};
use splat2tiles_viewer::headless::{ViewArgs, open_tileset, tileset_camera};
use splat2tiles_viewer::renderer::{RendererConfig, SplatRenderer};
use splat2tiles_viewer::stream::{apply_updates, bootstrap, driver};

use crate::common::*;

const ORIGIN: &str = "2.2945,48.8584,35";

/// A 60,000-splat city converted into `dir/name` (z up, at most 16,384 splats per tile: one
/// renderer page), georeferenced at [`ORIGIN`] when `geo`; returns `tileset.json`.
fn city(dir: &Path, name: &str, geo: bool) -> PathBuf {
    let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/scenes");
    let sources: Vec<_> = shared_sources(&scenes)
        .expect("shared scenes")
        .iter()
        .map(|s| s.select(&(0..s.len()).step_by(8).collect::<Vec<_>>()))
        .collect();
    let layout = CityLayout {
        splats: 60_000,
        ..CityLayout::default()
    };
    let out = dir.join(name);
    let opts = ConvertOptions {
        up_axis: Some(UpAxis::PosZ),
        origin: geo.then(|| Geodetic::parse(ORIGIN).unwrap()),
        max_splats_per_tile: 16_384,
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

/// The frame the native streaming path draws for `cam` once the client is idle and the fades
/// are over, and the splats resident.
fn streamed_frame(g: &Headless, url: &str, cam: &Camera, max_sse: f64) -> (Image, usize) {
    let mut d = driver(
        url,
        cam.width,
        cam.height,
        cam.fov_y_deg(),
        max_sse,
        Prefetch::BALANCED,
    );
    let (early, mut clock) = bootstrap(&mut d, url, 0.0, 60.0).expect("tileset loads");
    let cfg = RendererConfig {
        blocking_sort: true,
        ..RendererConfig::default()
    };
    let mut r = SplatRenderer::new(&g.device, &g.queue, OFFSCREEN_FORMAT, cfg);
    apply_updates(&mut r, &g.device, &g.queue, early, 0.0);
    let start = std::time::Instant::now();
    loop {
        let ups = d.tick(clock, cam);
        apply_updates(&mut r, &g.device, &g.queue, ups, 0.0);
        if d.is_idle() || start.elapsed().as_secs() > 120 {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(2));
        clock += 0.002;
    }
    assert!(d.is_idle(), "the client never settled: {:?}", d.stats());
    let target = Offscreen::new(&g.device, cam.width, cam.height).unwrap();
    // Long after every insert and remove: fades are over.
    let stats = r.render(&g.device, &g.queue, &target.view, cam, 1e6);
    (target.read(&g.device, &g.queue).unwrap(), stats.resident)
}

#[test]
fn city_overview_and_street_match_the_reference_from_selection_and_stream() {
    let tmp = tempfile::tempdir().unwrap();
    let g = gpu();
    let local = city(tmp.path(), "local", false);
    let geo = city(tmp.path(), "geo", true);
    // Street level: 1.7 m above the ground, south edge of the city, looking north.
    let ts = open_tileset(&local).unwrap();
    let (lo, hi) = splat2tiles_tiles::geometry::tileset_bounds(&ts).unwrap();
    let (x, y) = (0.5 * (lo.x + hi.x), lo.y - 2.0);
    let street = format!("look-at:{x},{y},1.7:{x},{},1.7:0,0,1", y + 10.0);
    let eye = Geodetic::parse(ORIGIN)
        .unwrap()
        .enu_to_ecef()
        .transform_point3(DVec3::new(x, y, 1.7));
    let e = Geodetic::from_ecef(eye);
    let geo_street = format!("geo:{},{},{}:0,0", e.lon, e.lat, e.height);
    let cases: [(&Path, Option<&str>, f64, &str); 5] = [
        (&local, None, 16.0, "local-overview"),
        (&local, None, 64.0, "local-overview-sse64"),
        (&local, Some(&street), 16.0, "local-street"),
        (&geo, None, 16.0, "geo-overview"),
        (&geo, Some(&geo_street), 16.0, "geo-street"),
    ];
    for (ts_path, spec, max_sse, name) in cases {
        let v = ViewArgs {
            camera: spec.map(str::to_string),
            auto_view: spec.is_none().then_some(0),
            width: Some(320),
            height: Some(240),
            max_sse,
            ..ViewArgs::default()
        };
        let ts = open_tileset(ts_path).unwrap();
        let cam = tileset_camera(&ts, &v).unwrap();
        let (inst, _) = tileset_view(ts_path, &v);
        let cpu = reference(&inst, &cam, &Default::default());
        let mean = mean(&cpu);
        assert!(mean > 0.01, "{name}: the reference frame is empty ({mean})");
        let selected = compare(&g, &inst, &cam, name, tmp.path());
        let (frame, resident) = streamed_frame(&g, ts_path.to_str().unwrap(), &cam, max_sse);
        let streamed = ssim(&cpu, &frame).unwrap();
        let splats: usize = inst.iter().map(|(s, _)| s.len()).sum();
        println!(
            "{name}: SSIM from selection {selected:.4}, from stream {streamed:.4} ({resident} of {splats} splats)"
        );
        assert!(
            resident > 0 && resident <= splats,
            "{name}: {resident} resident"
        );
        assert!(selected >= 0.95, "{name}: selection SSIM {selected}");
        assert!(streamed >= 0.95, "{name}: streamed SSIM {streamed}");
    }
}
