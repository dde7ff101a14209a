//! SGSS Table 2 and the bandwidth comparison on the streaming city (`sim::stream_city`): the
//! uniform tiling (leaves by `--max-splats` only) against the view-optimised one (`--partition`,
//! views from the tuning split), streamed by the real client in the simulator on test traces.
//!
//! A measurement (minutes; prints the BENCHMARKS.md table):
//! `cargo run --profile test -p splat2tiles-lab --example partition_city`. `PARTITION_CITY_STEP=N`
//! streams every N-th test trace (default 8). Reads `data/scenes` and
//! the human traces under `data/` (read through `sim::split`).

use splat2tiles_build::convert::{ConvertOptions, convert_scene};
use splat2tiles_build::partition::plan::PartitionRequest;
use splat2tiles_core::camera::Camera;
use splat2tiles_core::frame::UpAxis;
use splat2tiles_core::frame::geo::Geodetic;
use splat2tiles_lab::city::{city_scene, generate_city};
use splat2tiles_lab::sim::score::Truth;
use splat2tiles_lab::sim::stream_city::{
    CitySpec, DEFAULT_ORIGIN, StreetGrid, city_sources, evaluation_set, tuning_set,
};
use splat2tiles_lab::sim::{NetModel, SessionOptions, run_session};
use splat2tiles_stream::client::ClientConfig;
use splat2tiles_tiles::select::{CutTree, select_cut};
use std::cell::Cell;
use std::path::{Path, PathBuf};

/// Counts the sphere tests (visibility tests) a selection makes.
struct Counting<'a>(&'a Truth, Cell<u64>);

impl CutTree for Counting<'_> {
    fn roots(&self) -> &[usize] {
        self.0.roots()
    }
    fn children(&self, i: usize) -> &[usize] {
        self.0.children(i)
    }
    fn sphere(&self, i: usize) -> Option<(glam::DVec3, f64)> {
        self.1.set(self.1.get() + 1);
        self.0.sphere(i)
    }
    fn geometric_error(&self, i: usize) -> f64 {
        self.0.geometric_error(i)
    }
    fn has_content(&self, i: usize) -> bool {
        self.0.has_content(i)
    }
}

/// Removes the folder however the test ends.
struct Cleanup(PathBuf);
impl Drop for Cleanup {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn content_tiles(dir: &Path) -> (usize, u64) {
    let ts = splat2tiles_tiles::tiling::load::load_tileset(&dir.join("tileset.json")).unwrap();
    let c: Vec<_> = ts.tiles.iter().filter_map(|t| t.content.as_ref()).collect();
    let bytes = c.iter().map(|p| std::fs::metadata(p).unwrap().len()).sum();
    (c.len(), bytes)
}

fn main() {
    let root = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."));
    let work = root.join("target/tmp-big/partition-city");
    let _ = std::fs::remove_dir_all(&work);
    std::fs::create_dir_all(&work).unwrap();
    let _clean = Cleanup(work.clone());
    let nav = root.join(splat2tiles_lab::sim::stream_city::NAVIGATION_DIR);
    let step: usize = std::env::var("PARTITION_CITY_STEP")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(8);
    let spec = CitySpec::default();
    let sources = city_sources(&root.join("data/scenes"), spec.stride).unwrap();
    let layout = spec.layout();
    let grid = StreetGrid::of(&sources, &layout);
    let splats = generate_city(&sources, &layout);
    let base = ConvertOptions {
        up_axis: Some(UpAxis::PosZ),
        origin: Some(Geodetic::parse(DEFAULT_ORIGIN).unwrap()),
        max_splats_per_tile: spec.max_splats_per_tile,
        ..ConvertOptions::default()
    };
    let planned = ConvertOptions {
        partition: Some(PartitionRequest {
            views: tuning_set(&grid, &nav).unwrap(),
            depth: Some(9),
            range_m: 60.0,
            every_s: 2.0,
        }),
        ..base.clone()
    };
    let mut rows = vec![];
    let tests = evaluation_set(&grid, &nav).unwrap();
    let traces: Vec<_> = tests.traces().iter().step_by(step).collect();
    for (name, opts) in [
        ("uniform (--max-splats 8192)", base),
        ("optimised (--partition)", planned),
    ] {
        let dir = work.join(if opts.partition.is_some() {
            "planned"
        } else {
            "uniform"
        });
        let t = std::time::Instant::now();
        let r = convert_scene(city_scene(splats.clone()), "city", &dir, &opts).unwrap();
        let convert_s = t.elapsed().as_secs_f64();
        let (tiles, bytes) = content_tiles(&dir);
        let truth = Truth::load(&dir.join("tileset.json")).unwrap();
        let counting = Counting(&truth, Cell::new(0));
        let cfg = ClientConfig::default();
        let net = NetModel::constant(100.0, 0.04);
        let (mut down, mut ticks, mut vtests, mut cut) = (0u64, 0usize, 0u64, 0usize);
        for tr in &traces {
            let log = run_session(
                &dir,
                cfg.clone(),
                &tr.poses,
                &net,
                SessionOptions::default(),
            );
            down += log.ticks.last().map_or(0, |t| t.bytes_down);
            ticks += log.ticks.len();
            for p in &tr.poses {
                let cam = Camera::from_pose(
                    cfg.width,
                    cfg.height,
                    cfg.fov_y_deg,
                    truth.root_transform() * p.world_from_camera(),
                );
                cut += select_cut(&counting, &cam, cfg.max_sse, true, |_| true).len();
            }
        }
        vtests += counting.1.get();
        let frames = traces.iter().map(|t| t.poses.len()).sum::<usize>().max(1);
        let plan = r
            .partition
            .as_ref()
            .map(|p| format!("{} units, {} views", p.units, p.views))
            .unwrap_or_default();
        rows.push(format!(
            "| {name} | {tiles} | {:.1} MiB | {:.1} | {:.1} | {:.1} MiB | {:.1} KiB | {convert_s:.1} s | {plan} |",
            bytes as f64 / (1 << 20) as f64,
            vtests as f64 / frames as f64,
            cut as f64 / frames as f64,
            down as f64 / (1 << 20) as f64 / traces.len() as f64,
            down as f64 / 1024.0 / ticks.max(1) as f64,
        ));
    }
    println!(
        "{} test traces (every {step}-th), 100 Mbit/s, 40 ms RTT",
        traces.len()
    );
    println!(
        "| tiling | content tiles | Best bytes | visibility tests / frame | cut tiles / frame | downloaded / trace | downloaded / frame | convert | plan |"
    );
    println!("|---|---:|---:|---:|---:|---:|---:|---:|---|");
    for r in rows {
        println!("{r}");
    }
}
