//! The native driver (worker threads, reqwest, files) streaming the plant tileset to idle over
//! `splat2tiles serve` on a loopback port and from disk: same tiles and splats as the files.

mod common;

use common::{bin, scene};
use glam::{DMat4, DVec3};
use splat2tiles_build::convert::{ConvertOptions, convert};
use splat2tiles_core::camera::Camera;
use splat2tiles_core::splat::Splats;
use splat2tiles_stream::Level;
use splat2tiles_stream::client::native::Driver;
use splat2tiles_stream::client::{
    Action, ClientConfig, PredictorKind, SceneUpdate, StreamClient, timeline,
};
use splat2tiles_tiles::encode::read_tile_glb;
use splat2tiles_tiles::geometry::{content_model, select_tiles};
use splat2tiles_tiles::tiling::TileKey;
use splat2tiles_tiles::tiling::load::{LoadedTileset, load_tileset};
use splat2tiles_tiles::variants::{Variant, VariantOptions, content_uri};
use std::collections::{BTreeMap, HashMap};
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// `splat2tiles serve DIR --port 0`, killed on drop.
struct Served {
    child: Child,
    port: u16,
}

impl Drop for Served {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn serve(dir: &Path) -> Served {
    let mut child = Command::new(bin())
        .args(["serve", dir.to_str().unwrap(), "--port", "0", "--quiet"])
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("start splat2tiles serve");
    let mut out = BufReader::new(child.stdout.take().unwrap());
    let port = loop {
        let mut line = String::new();
        if out.read_line(&mut line).unwrap() == 0 {
            let _ = child.kill();
            panic!("splat2tiles serve exited before printing its URL");
        }
        if let Some(rest) = line.split("http://127.0.0.1:").nth(1) {
            let digits: String = rest.chars().take_while(char::is_ascii_digit).collect();
            break digits.parse::<u16>().unwrap();
        }
    };
    Served { child, port }
}

fn convert_plant(out: &Path) {
    let opts = ConvertOptions {
        max_splats_per_tile: 8192,
        variants: VariantOptions {
            variants: vec![Variant::Best, Variant::Low],
            measure_utility: false,
            ..VariantOptions::default()
        },
        ..ConvertOptions::default()
    };
    convert(&scene("plant.splat"), out, &opts).expect("convert plant.splat");
}

fn camera(ts: &LoadedTileset, dir: DVec3, dist: f64) -> Camera {
    let root = ts.tiles.iter().find(|t| t.key == TileKey::ROOT).unwrap();
    let b = root.bounding_box.unwrap();
    let c = DVec3::new(b[0], b[1], b[2]);
    let r = (DVec3::new(b[3], b[4], b[5])
        + DVec3::new(b[6], b[7], b[8])
        + DVec3::new(b[9], b[10], b[11]))
    .length();
    Camera::look_at(1280, 720, 50.0, c + dir.normalize() * r * dist, c, DVec3::Z)
}

type Scene = HashMap<u64, (TileKey, Level, Splats, DMat4)>;

fn apply(scene: &mut Scene, ups: Vec<SceneUpdate>) {
    for u in ups {
        match u {
            SceneUpdate::Insert {
                tile,
                key,
                level,
                splats,
                tile_to_world,
            } => {
                assert!(
                    scene
                        .insert(tile, (key, level, splats, tile_to_world))
                        .is_none()
                );
            }
            SceneUpdate::Append { tile, splats } => {
                let o = scene.get_mut(&tile).expect("append to a live id");
                for i in 0..splats.len() {
                    o.2.push_from(&splats, i);
                }
            }
            SceneUpdate::Remove { tile } => {
                assert!(scene.remove(&tile).is_some());
            }
        }
    }
}

fn stream_cfg() -> ClientConfig {
    ClientConfig {
        levels: vec![Level::Best],
        predictor: PredictorKind::Reactive,
        max_concurrent: 4,
        ..ClientConfig::default()
    }
}

/// Ticks the driver in real time along `cams` (each for `per` seconds; the last until idle).
fn stream(url: &str, cams: &[Camera], per: f64) -> (Scene, Driver) {
    stream_with(url, cams, per, false)
}

/// [`stream`], recording the client's inputs when `record` is set.
fn stream_with(url: &str, cams: &[Camera], per: f64, record: bool) -> (Scene, Driver) {
    let mut d = Driver::new(url, stream_cfg());
    if record {
        d.record();
    }
    let mut scene = Scene::new();
    let t0 = Instant::now();
    let mut k = 0;
    let mut seg_start = 0.0;
    loop {
        let now = t0.elapsed().as_secs_f64();
        if k + 1 < cams.len() && now - seg_start > per {
            k += 1;
            seg_start = now;
        }
        let ups = d.tick(now, &cams[k]);
        apply(&mut scene, ups);
        if k + 1 == cams.len() && d.is_idle() {
            // One more tick: the plan after the last completion asks for nothing.
            std::thread::sleep(Duration::from_millis(5));
            let ups = d.tick(t0.elapsed().as_secs_f64(), &cams[k]);
            apply(&mut scene, ups);
            if d.is_idle() {
                break;
            }
        }
        assert!(now < 120.0, "not idle after 120 s: {:?}", d.stats());
        std::thread::sleep(Duration::from_millis(2));
    }
    (scene, d)
}

/// The scene holds exactly the `select_tiles` tiles with the files' splats and matrices.
fn assert_matches_disk(scene: &Scene, ts: &LoadedTileset, cam: &Camera) {
    let want: Vec<PathBuf> = select_tiles(ts, cam, 16.0);
    let got: BTreeMap<PathBuf, &(TileKey, Level, Splats, DMat4)> = scene
        .values()
        .map(|o| (ts.dir.join(content_uri(ts.scheme, o.0, Variant::Best)), o))
        .collect();
    assert_eq!(
        got.keys().cloned().collect::<Vec<_>>(),
        want,
        "scene tiles vs select_tiles"
    );
    for (path, (_, level, splats, m)) in got {
        assert_eq!(*level, Level::Best);
        let t = read_tile_glb(&std::fs::read(&path).unwrap()).unwrap();
        assert_eq!(splats.len(), t.splats.len(), "{}", path.display());
        for i in 0..splats.len() {
            assert_eq!(
                splats.get(i),
                t.splats.get(i),
                "{} splat {i}",
                path.display()
            );
            assert_eq!(splats.rest_of(i), t.splats.rest_of(i));
        }
        assert!(m.abs_diff_eq(content_model(ts, &t.node_matrix), 1e-12));
    }
}

#[test]
fn streams_the_plant_over_http_and_from_disk_to_the_same_splats() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("plant");
    convert_plant(&dir);
    let ts = load_tileset(&dir.join("tileset.json")).unwrap();
    let cam = camera(&ts, DVec3::new(1.0, -1.0, 0.6), 2.5);
    assert!(select_tiles(&ts, &cam, 16.0).len() > 1);
    let served = serve(&dir);
    let http = format!("http://127.0.0.1:{}/tileset.json", served.port);
    let (scene, d) = stream(&http, std::slice::from_ref(&cam), 0.0);
    let st = d.stats();
    assert_eq!(st.errors, 0, "{:?}", st.last_errors);
    assert!(st.bytes_received > 0 && st.bandwidth > 0.0);
    assert_matches_disk(&scene, &ts, &cam);
    drop(d);
    // Same through file:// and a plain path.
    for url in [
        format!("file://{}", dir.join("tileset.json").display()),
        dir.join("tileset.json").display().to_string(),
    ] {
        let (scene, d) = stream(&url, std::slice::from_ref(&cam), 0.0);
        assert_eq!(d.stats().errors, 0, "{url}: {:?}", d.stats().last_errors);
        assert_matches_disk(&scene, &ts, &cam);
    }
}

#[test]
fn http_stream_survives_looking_away_and_back() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("plant");
    convert_plant(&dir);
    let ts = load_tileset(&dir.join("tileset.json")).unwrap();
    let cam = camera(&ts, DVec3::new(1.0, -1.0, 0.6), 2.5);
    let target = camera(&ts, DVec3::new(1.0, -1.0, 0.6), 0.0).center();
    let away = Camera::look_at(
        1280,
        720,
        50.0,
        cam.center(),
        cam.center() * 2.0 - target,
        DVec3::Z,
    );
    let served = serve(&dir);
    let http = format!("http://127.0.0.1:{}/tileset.json", served.port);
    // Toggle every 30 ms: transfers are aborted (paused) and resumed with Range + If-Range.
    let cams = [cam, away, cam, away, cam, away, cam, away, cam, away, cam];
    let (scene, d) = stream(&http, &cams, 0.03);
    let st = d.stats();
    assert_eq!(st.errors, 0, "{:?}", st.last_errors);
    assert_matches_disk(&scene, &ts, &cam);
    eprintln!(
        "aborts {}, resumes {}, restarts {}, bytes {}",
        st.aborts, st.resumes, st.restarts, st.bytes_received
    );
}

/// The client's decisions are a function of its input timeline: the native driver's recorded
/// session over HTTP (pauses and resumes included), replayed through a fresh client, gives the
/// same actions at every update (no timing assertion: whatever timeline the machine produced).
#[test]
fn native_session_replays_to_the_same_decisions() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("plant");
    convert_plant(&dir);
    let ts = load_tileset(&dir.join("tileset.json")).unwrap();
    let cam = camera(&ts, DVec3::new(1.0, -1.0, 0.6), 2.5);
    let target = camera(&ts, DVec3::new(1.0, -1.0, 0.6), 0.0).center();
    let away = Camera::look_at(
        1280,
        720,
        50.0,
        cam.center(),
        cam.center() * 2.0 - target,
        DVec3::Z,
    );
    let served = serve(&dir);
    let http = format!("http://127.0.0.1:{}/tileset.json", served.port);
    let cams = [cam, away, cam, away, cam];
    let (_, mut d) = stream_with(&http, &cams, 0.03, true);
    let rec = d.take_recording().expect("recording");
    drop(d);
    let fetches = rec
        .actions
        .iter()
        .flatten()
        .filter(|a| matches!(a, Action::Fetch(_)))
        .count();
    assert!(fetches > 3 && rec.inputs.len() > rec.actions.len());
    let mut fresh = StreamClient::new(&http, stream_cfg());
    let replayed = timeline::replay(&mut fresh, &rec.inputs);
    assert_eq!(replayed.len(), rec.actions.len());
    for (k, (a, b)) in rec.actions.iter().zip(&replayed).enumerate() {
        assert_eq!(a, b, "update {k}");
    }
}
