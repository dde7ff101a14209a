//! The georeferenced streaming city of the issue-19 experiments (real content on a street grid,
//! converted with all four variants) and its trace set per split: human walks, street walks, flights.
//!
//! Content: [`splat::city`](crate::city) copies of the three shared scenes
//! (`data/scenes/README.md`: plant, donut, biker; every `stride`-th splat), each scaled to an
//! 18 m x [0.75, 1) block, turned by a multiple of 90 degrees and centred on a 24 m grid without
//! jitter, so the streets between blocks are at least 6 m wide and a walk down one reveals new
//! blocks. Ground at z = 0; street centre lines at `(k - 0.5) * 24 m` on x and y, `k = 0..=side`.
//! Converted z up (`--up-axis +z`), georeferenced at `--origin` (the positions are the ENU frame
//! of the origin), Best, High, Medium and Low per tile, estimated utilities.
//!
//! Traces (12 Hz, all in the tileset frame; split as in [`splat2tiles_stream::split`]):
//! - EyeNavGS sessions ([`splat2tiles_stream::eyenav`]) at street level: the session's start at a street
//!   intersection chosen from the scene and user, turned by a multiple of 90 degrees, horizontal
//!   offsets x[`HUMAN_H_SCALE`] (the dataset's median 0.23 m/s becomes 1.4 m/s, a walking pace:
//!   people in the VR rooms walked a few metres, a street walk needs tens), eyes 1.7 m above the
//!   ground at the session's median head height. They ignore buildings (no collision).
//! - Street walks at [`WALK_SPEED`] (1.4 m/s): along the street centre lines from intersection to
//!   intersection, turning at corners, pausing, the head looking around.
//! - Flights at [`FLIGHT_SPEED`] (8 m/s) and [`FLIGHT_ALTITUDE`] (40 m), pitched down 15-35 deg.
//!
//! TileSplat (App. C) navigates with WASD/QE and the mouse but states no speeds; 1.4 m/s is the
//! usual human walking pace and 8 m/s a slow drone, both our choice.

use crate::city::{CityLayout, city_scene, generate_city, grid_side, shared_sources};
use glam::{DVec2, DVec3};
use splat2tiles_build::convert::{ConvertOptions, convert_scene};
use splat2tiles_core::frame::UpAxis;
use splat2tiles_core::frame::geo::Geodetic;
use splat2tiles_core::rng::SplitMix64;
use splat2tiles_core::splat::Splats;
use splat2tiles_stream::client::{ClientConfig, PredictorKind};
use splat2tiles_stream::eyenav::{Placement, read_session, session_files};
use splat2tiles_stream::geom::{ViewPose, wrap_angle};
use splat2tiles_stream::split::{EvaluationSet, Split, TuningSet, eyenav_scenes, synthetic_split};
use splat2tiles_stream::trace::{TRACE_HZ, Trace};
use splat2tiles_tiles::variants::{ALL, VariantOptions};
use std::path::{Path, PathBuf};

/// Horizontal scale of the EyeNavGS sessions placed in the city.
pub const HUMAN_H_SCALE: f64 = 6.0;
/// Eye height above the ground (m).
pub const EYE_HEIGHT: f64 = 1.7;
/// Synthetic street-walk speed (m/s).
pub const WALK_SPEED: f64 = 1.4;
/// Synthetic flight speed (m/s).
pub const FLIGHT_SPEED: f64 = 8.0;
/// Synthetic flight altitude above the ground (m).
pub const FLIGHT_ALTITUDE: f64 = 40.0;
/// Where the experiments' city is georeferenced (`lon,lat,height`; Berlin, Alexanderplatz).
pub const DEFAULT_ORIGIN: &str = "13.4132,52.5219,34";
/// Default folder of the EyeNavGS sessions (`data/navigation-traces/README.md`).
pub const NAVIGATION_DIR: &str = "data/navigation-traces";
/// Synthetic walks per 20 seeds (seeds `0..20`, split 14/3/3 by [`synthetic_split`]).
pub const WALK_SEEDS: std::ops::Range<u64> = 0..20;
/// Synthetic flights (seeds `20..40`, split 14/3/3).
pub const FLIGHT_SEEDS: std::ops::Range<u64> = 20..40;

/// What to generate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CitySpec {
    /// Splats in the city (input; parents come on top).
    pub splats: usize,
    /// Every `stride`-th splat of each source scene.
    pub stride: usize,
    /// Layout seed.
    pub seed: u64,
    /// Leaf tile size.
    pub max_splats_per_tile: usize,
}

impl Default for CitySpec {
    /// The experiments' city: the smallest that gives at least 100 MiB of Best tiles (see
    /// BENCHMARKS.md "Streaming city").
    fn default() -> Self {
        CitySpec {
            splats: 1_500_000,
            stride: 8,
            seed: 19,
            max_splats_per_tile: 8192,
        }
    }
}

impl CitySpec {
    /// The small city (200k splats, about 280 content tiles) that `tests/sim_city.rs` pins the
    /// predictor ordering on and `examples/tcn_selection.rs` compares selection rules on.
    pub fn small() -> Self {
        CitySpec {
            splats: 200_000,
            stride: 16,
            seed: 3,
            max_splats_per_tile: 4096,
        }
    }

    /// The client the small city is streamed with (4 requests in flight, 256 MiB, 1280x720),
    /// by `tests/sim_city.rs` and `examples/tcn_selection.rs`, with `predictor`.
    pub fn small_client(predictor: PredictorKind) -> ClientConfig {
        ClientConfig {
            max_concurrent: 4,
            predictor,
            memory_budget_bytes: 256 << 20,
            width: 1280,
            height: 720,
            ..ClientConfig::default()
        }
    }

    /// The layout given to [`generate_city`].
    pub fn layout(&self) -> CityLayout {
        CityLayout {
            splats: self.splats,
            spacing: 24.0,
            block: 18.0,
            seed: self.seed,
            jitter: 0.0,
            scale: (0.75, 1.0),
            quarter_turns: true,
        }
    }
}

/// The street grid of a generated city.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StreetGrid {
    /// Block pitch (m).
    pub spacing: f64,
    /// Blocks per row; street lines `0..=side` on each axis.
    pub side: usize,
}

impl StreetGrid {
    /// The streets of the city `layout` makes of `sources`.
    pub fn of(sources: &[Splats], layout: &CityLayout) -> StreetGrid {
        StreetGrid {
            spacing: layout.spacing,
            side: grid_side(sources, layout),
        }
    }

    /// Position of intersection `(i, j)`, `0..=side` each.
    pub fn node(&self, i: usize, j: usize) -> DVec2 {
        DVec2::new(
            (i as f64 - 0.5) * self.spacing,
            (j as f64 - 0.5) * self.spacing,
        )
    }

    /// Distance from `p` to the nearest street centre line.
    pub fn street_distance(&self, p: DVec2) -> f64 {
        let d = |v: f64| {
            let u = v / self.spacing + 0.5;
            (u - u.round()).abs() * self.spacing
        };
        d(p.x).min(d(p.y))
    }

    /// Lower and upper corners of the area within the outer streets.
    pub fn extent(&self) -> (DVec2, DVec2) {
        (self.node(0, 0), self.node(self.side, self.side))
    }
}

/// The source scenes thinned by `stride` (`data/scenes/`).
pub fn city_sources(scenes_dir: &Path, stride: usize) -> anyhow::Result<Vec<Splats>> {
    let stride = stride.max(1);
    Ok(shared_sources(scenes_dir)?
        .iter()
        .map(|s| s.select(&(0..s.len()).step_by(stride).collect::<Vec<_>>()))
        .collect())
}

/// A converted city.
#[derive(Debug, Clone)]
pub struct BuiltCity {
    /// Tileset folder.
    pub dir: PathBuf,
    /// Its streets.
    pub grid: StreetGrid,
    /// Splats in the input.
    pub splats: usize,
    /// Tiles with content.
    pub content_tiles: usize,
    /// Bytes of each variant over all content tiles (Best, High, Medium, Low).
    pub variant_bytes: [u64; 4],
    /// Bytes of all files written.
    pub bytes: u64,
    /// Seconds to generate the splats.
    pub generate_s: f64,
    /// Seconds to convert them.
    pub convert_s: f64,
}

impl BuiltCity {
    /// One line: splats, blocks, content tiles, bytes per variant and in all, seconds.
    pub fn summary(&self) -> String {
        let mib = |b: u64| b as f64 / (1u64 << 20) as f64;
        format!(
            "{} splats, {}x{} blocks ({} m grid), {} content tiles; Best {:.1} MiB, High {:.1} \
             MiB, Medium {:.1} MiB, Low {:.1} MiB, all files {:.1} MiB; generated in {:.1} s, \
             converted in {:.1} s",
            self.splats,
            self.grid.side,
            self.grid.side,
            self.grid.spacing,
            self.content_tiles,
            mib(self.variant_bytes[0]),
            mib(self.variant_bytes[1]),
            mib(self.variant_bytes[2]),
            mib(self.variant_bytes[3]),
            mib(self.bytes),
            self.generate_s,
            self.convert_s
        )
    }
}

/// Generates the city of `spec` from `scenes_dir` and converts it into `out` (must not exist as
/// anything but an earlier conversion), georeferenced at `origin`, with all four variants.
pub fn build_city(
    scenes_dir: &Path,
    out: &Path,
    spec: &CitySpec,
    origin: Option<Geodetic>,
) -> anyhow::Result<BuiltCity> {
    let t = std::time::Instant::now();
    let sources = city_sources(scenes_dir, spec.stride)?;
    let layout = spec.layout();
    let grid = StreetGrid::of(&sources, &layout);
    let splats = generate_city(&sources, &layout);
    let n = splats.len();
    let generate_s = t.elapsed().as_secs_f64();
    let opts = ConvertOptions {
        up_axis: Some(UpAxis::PosZ),
        origin,
        max_splats_per_tile: spec.max_splats_per_tile,
        variants: VariantOptions {
            variants: ALL.to_vec(),
            ..VariantOptions::default()
        },
        ..ConvertOptions::default()
    };
    let t = std::time::Instant::now();
    let name = out
        .file_name()
        .and_then(|s| s.to_str())
        .unwrap_or("city")
        .to_string();
    let r = convert_scene(city_scene(splats), &name, out, &opts)
        .map_err(|e| anyhow::anyhow!("{}: {e}", out.display()))?;
    let mut variant_bytes = [0u64; 4];
    for (_, f) in &r.contents {
        for (k, b) in variant_bytes.iter_mut().enumerate() {
            *b += f.variant_bytes[k] as u64;
        }
    }
    Ok(BuiltCity {
        dir: out.to_path_buf(),
        grid,
        splats: n,
        content_tiles: r.content_tiles,
        variant_bytes,
        bytes: r.bytes,
        generate_s,
        convert_s: t.elapsed().as_secs_f64(),
    })
}

fn headers(kind: &str, seed: u64, split: Split, extra: &[(&str, String)]) -> Vec<(String, String)> {
    let mut h: Vec<(String, String)> = [
        ("splat2tiles-trace", "1".to_string()),
        ("scene", "stream-city".to_string()),
        ("kind", kind.to_string()),
        ("seed", seed.to_string()),
        ("split", split.name().to_string()),
        ("fov_y_deg", "50".to_string()),
        ("aspect", "1.7778".to_string()),
    ]
    .into_iter()
    .map(|(k, v)| (k.to_string(), v))
    .collect();
    h.extend(extra.iter().map(|(k, v)| (k.to_string(), v.clone())));
    h
}

/// A synthetic street walk (see the module docs) of `duration_s` with `seed`.
pub fn street_walk(grid: &StreetGrid, seed: u64, duration_s: f64) -> Trace {
    let mut rng = SplitMix64::new(seed ^ 0x5745_4c4b);
    let side = grid.side.max(1) as i64;
    let mut node = (
        rng.below(grid.side + 1) as i64,
        rng.below(grid.side + 1) as i64,
    );
    let dirs = [(1i64, 0i64), (0, 1), (-1, 0), (0, -1)];
    let inside = |n: (i64, i64)| (0..=side).contains(&n.0) && (0..=side).contains(&n.1);
    let mut dir = rng.below(4);
    while !inside((node.0 + dirs[dir].0, node.1 + dirs[dir].1)) {
        dir = (dir + 1) % 4;
    }
    let at = |n: (i64, i64)| grid.node(n.0 as usize, n.1 as usize);
    let mut pos = at(node);
    let mut target = (node.0 + dirs[dir].0, node.1 + dirs[dir].1);
    let mut body = (dirs[dir].1 as f64).atan2(dirs[dir].0 as f64);
    let (mut head, mut head_goal, mut head_left) = (0.0f64, 0.0f64, 0.0f64);
    let mut pitch = -0.05f64;
    let (mut speed, mut pause) = (0.0f64, 0.0f64);
    let dt = 1.0 / TRACE_HZ;
    let n = (duration_s * TRACE_HZ).round() as usize;
    let mut poses = Vec::with_capacity(n + 1);
    for i in 0..=n {
        let t = i as f64 * dt;
        head_left -= dt;
        if head_left <= 0.0 {
            // Glances: mostly ahead, sometimes at the buildings either side.
            head_goal = if rng.f64() < 0.6 {
                rng.range(-0.2, 0.2)
            } else {
                rng.range(-1.2, 1.2)
            };
            head_left = rng.range(1.0, 3.0);
        }
        head += (head_goal - head) * 0.1;
        pitch = (pitch + rng.normal() * 0.01).clamp(-0.35, 0.35);
        let goal = at(target);
        let want = (goal.y - pos.y).atan2(goal.x - pos.x);
        let turn = wrap_angle(want - body);
        if pause > 0.0 {
            pause -= dt;
            speed = 0.0;
        } else if turn.abs() > 0.05 {
            // Turning at a corner (90 deg/s), slowing down.
            body = wrap_angle(body + turn.clamp(-1.57 * dt, 1.57 * dt));
            speed *= 0.8;
        } else {
            body = want;
            speed += (WALK_SPEED - speed) * 0.15;
            let d = goal - pos;
            let step = speed * dt;
            if d.length() <= step {
                pos = goal;
                node = target;
                if rng.f64() < 0.2 {
                    pause = rng.range(0.5, 2.5);
                }
                // Straight 50%, left 25%, right 25%; never off the grid, back only at a dead end.
                let r = rng.f64();
                let order = if r < 0.5 {
                    [dir, (dir + 1) % 4, (dir + 3) % 4, (dir + 2) % 4]
                } else if r < 0.75 {
                    [(dir + 1) % 4, dir, (dir + 3) % 4, (dir + 2) % 4]
                } else {
                    [(dir + 3) % 4, dir, (dir + 1) % 4, (dir + 2) % 4]
                };
                dir = order
                    .into_iter()
                    .find(|&k| inside((node.0 + dirs[k].0, node.1 + dirs[k].1)))
                    .unwrap_or((dir + 2) % 4);
                target = (node.0 + dirs[dir].0, node.1 + dirs[dir].1);
            } else {
                pos += d / d.length() * step;
            }
        }
        poses.push(ViewPose {
            t,
            pos: DVec3::new(pos.x, pos.y, EYE_HEIGHT),
            yaw: wrap_angle(body + head),
            pitch,
        });
    }
    Trace {
        headers: headers("street_walk", seed, synthetic_split(seed), &[]),
        poses,
    }
}

/// A synthetic flight (see the module docs) of `duration_s` with `seed`: legs towards random
/// waypoints over the city, turning at 45 deg/s, altitude wandering +-5 m.
pub fn flight(grid: &StreetGrid, seed: u64, duration_s: f64) -> Trace {
    let mut rng = SplitMix64::new(seed ^ 0x464c_5954);
    let (lo, hi) = grid.extent();
    let way = |r: &mut SplitMix64| DVec2::new(r.range(lo.x, hi.x), r.range(lo.y, hi.y));
    let mut pos = way(&mut rng);
    let mut goal = way(&mut rng);
    let mut yaw = (goal.y - pos.y).atan2(goal.x - pos.x);
    let mut pitch = -rng.range(15.0, 35.0).to_radians();
    let mut alt = FLIGHT_ALTITUDE;
    let dt = 1.0 / TRACE_HZ;
    let n = (duration_s * TRACE_HZ).round() as usize;
    let mut poses = Vec::with_capacity(n + 1);
    for i in 0..=n {
        let t = i as f64 * dt;
        let d = goal - pos;
        if d.length() < FLIGHT_SPEED {
            goal = way(&mut rng);
            pitch = -rng.range(15.0, 35.0).to_radians();
        }
        let want = d.y.atan2(d.x);
        let turn = wrap_angle(want - yaw);
        yaw = wrap_angle(yaw + turn.clamp(-0.785 * dt, 0.785 * dt));
        let v = if turn.abs() > 0.5 { 0.5 } else { 1.0 } * FLIGHT_SPEED;
        pos += DVec2::new(yaw.cos(), yaw.sin()) * v * dt;
        alt = (alt + rng.normal() * 0.1).clamp(FLIGHT_ALTITUDE - 5.0, FLIGHT_ALTITUDE + 5.0);
        poses.push(ViewPose {
            t,
            pos: DVec3::new(pos.x, pos.y, alt),
            yaw,
            pitch,
        });
    }
    Trace {
        headers: headers("flight", seed, synthetic_split(seed), &[]),
        poses,
    }
}

/// FNV-1a of a string: a stable per-session seed.
fn fnv(s: &str) -> u64 {
    s.bytes().fold(0xcbf2_9ce4_8422_2325u64, |h, b| {
        (h ^ b as u64).wrapping_mul(0x0100_0000_01b3)
    })
}

/// The placement of EyeNavGS session `user` of `scene` in the city (see the module docs).
pub fn human_placement(grid: &StreetGrid, scene: &str, user: &str) -> Placement {
    let mut rng = SplitMix64::new(fnv(&format!("{scene}/{user}")));
    let (i, j) = (rng.below(grid.side + 1), rng.below(grid.side + 1));
    let a = grid.node(i, j);
    Placement {
        anchor: DVec3::new(a.x, a.y, 0.0),
        heading_deg: 90.0 * rng.below(4) as f64,
        h_scale: HUMAN_H_SCALE,
        eye_height_m: EYE_HEIGHT,
    }
}

/// The EyeNavGS sessions of `split`'s scenes under `nav_root`, placed in the city.
pub fn human_traces(
    grid: &StreetGrid,
    nav_root: &Path,
    split: Split,
) -> Result<Vec<Trace>, String> {
    let mut out = vec![];
    for scene in eyenav_scenes(split) {
        for f in session_files(nav_root, scene)? {
            let s = read_session(&f)?;
            let pl = human_placement(grid, &s.scene, &s.user);
            out.push(s.place(&pl, "stream-city", split.name()));
        }
    }
    Ok(out)
}

/// Every trace of `split` in the city: the EyeNavGS sessions of its scenes, then the street walks
/// (120 s) and flights (60 s) whose seeds fall in it.
pub fn trace_set(grid: &StreetGrid, nav_root: &Path, split: Split) -> Result<Vec<Trace>, String> {
    let mut out = human_traces(grid, nav_root, split)?;
    out.extend(
        WALK_SEEDS
            .filter(|&s| synthetic_split(s) == split)
            .map(|s| street_walk(grid, s, 120.0)),
    );
    out.extend(
        FLIGHT_SEEDS
            .filter(|&s| synthetic_split(s) == split)
            .map(|s| flight(grid, s, 60.0)),
    );
    Ok(out)
}

/// The city's traces anything may be fitted or tuned on (train and val only).
pub fn tuning_set(grid: &StreetGrid, nav_root: &Path) -> Result<TuningSet, String> {
    let mut set = TuningSet::new();
    for split in [Split::Train, Split::Val] {
        for t in trace_set(grid, nav_root, split)? {
            set.admit(t)?;
        }
    }
    Ok(set)
}

/// The city's traces the Table 4 evaluation runs on (test only).
pub fn evaluation_set(grid: &StreetGrid, nav_root: &Path) -> Result<EvaluationSet, String> {
    let mut set = EvaluationSet::new();
    for t in trace_set(grid, nav_root, Split::Test)? {
        set.admit(t)?;
    }
    Ok(set)
}

/// Tiles a walk sees for the first time after `after_s`, and all it sees.
pub fn revealed(cat: &splat2tiles_stream::TileCatalog, t: &Trace, after_s: f64) -> (usize, usize) {
    let cfg = splat2tiles_stream::PlanStepConfig::default();
    let mut first_seen = std::collections::HashMap::new();
    let mut vis = vec![];
    for p in &t.poses {
        splat2tiles_stream::cull_hierarchical(
            cat,
            p,
            &cfg.intrinsics,
            cfg.max_sse,
            cfg.vis_test,
            &mut vis,
        );
        for &i in &vis {
            first_seen.entry(i).or_insert(p.t);
        }
    }
    let late = first_seen.values().filter(|&&s| s > after_s).count();
    (late, first_seen.len())
}

#[cfg(test)]
#[path = "stream_city_tests.rs"]
mod tests;
