//! The native viewer on a layered tileset (`spec/layered-content.md`): streamed through the
//! client and drawn by the GPU renderer during a camera dolly across a level change, frame by
//! frame no frame differs from its neighbour by more than an SSIM step, where the same dolly with
//! the blend disabled (hard swap) does; a blended frame matches the CPU reference's layered render.

use std::path::{Path, PathBuf};

use splat2tiles_build::convert::{ConvertOptions, SchemeChoice, convert};
use splat2tiles_core::camera::auto_views_with;
use splat2tiles_core::splat::{Splat, Splats};
use splat2tiles_render::metrics::ssim;
use splat2tiles_render::raster::{RenderOptions, render};
use splat2tiles_render::{Camera, Image};
use splat2tiles_stream::client::Prefetch;
use splat2tiles_tiles::geometry::{tileset_bounds, tileset_up};
use splat2tiles_tiles::layers::view::{is_layered, layered_instances};
use splat2tiles_tiles::tiling::TileKey;
use splat2tiles_tiles::tiling::load::{LoadedTileset, load_tileset};
use splat2tiles_viewer::gpu::{Headless, OFFSCREEN_FORMAT, Offscreen};
use splat2tiles_viewer::layered::{BlendMode, SceneSync};
use splat2tiles_viewer::renderer::{RendererConfig, SplatRenderer};
use splat2tiles_viewer::stream::{bootstrap, driver};

use crate::common::gpu;

/// Most SSIM one frame of the dolly may lose against the previous one (as the reference
/// renderer's continuity test, `tests/layered_content.rs`).
const SSIM_STEP: f64 = 0.02;
/// The refinement threshold (pixels).
const MAX_SSE: f64 = 16.0;
/// Frames of the dolly; the root's screen-space error grows geometrically over them.
const FRAMES: usize = 40;
/// The root's screen-space error at the first and the last frame, in units of `MAX_SSE`: the
/// root's child layers blend in over `[1, 2]` (`layers::blend::BLEND_BAND`).
const SSE_FROM: f64 = 0.8;
const SSE_TO: f64 = 2.4;
/// Seconds between frames (the renderer's and the ramp's clock).
const FRAME_DT: f64 = 0.1;
/// Frames the first pose is held before the dolly (the base layer ramps in from nothing: the
/// scene appearing, not a level change, so these frames are not checked) and the last pose after
/// it (the late-layer ramps finish).
const HOLD: usize = 4;
const W: u32 = 256;
const H: u32 = 144;
const FOV: f64 = 50.0;

/// A deterministic SH-1 cloud of 6,000 splats in a 10 x 10 x 6 m box converted with
/// `--layers` (400 splats per leaf, octree, two levels per subtree file) into `dir/layered`.
fn layered_tileset(dir: &Path) -> PathBuf {
    let mut r = 7u64;
    let mut next = move |lo: f64, hi: f64| {
        r = r
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        lo + (hi - lo) * ((r >> 11) as f64 / (1u64 << 53) as f64)
    };
    let mut s = Splats::with_capacity(1, 6000);
    for _ in 0..6000 {
        let q = [0; 4].map(|_| next(-1.0, 1.0) as f32);
        let item = Splat {
            position: [next(0.0, 10.0), next(0.0, 10.0), next(0.0, 6.0)],
            scale: [0; 3].map(|_| next(0.01, 0.5) as f32),
            rotation: splat2tiles_core::splat::normalize_quat(q),
            opacity: next(0.02, 0.99) as f32,
            sh0: [0; 3].map(|_| next(-1.5, 1.5) as f32),
        };
        let rest: Vec<[f32; 3]> = (0..3)
            .map(|_| [0; 3].map(|_| next(-0.3, 0.3) as f32))
            .collect();
        s.push(item, &rest);
    }
    let ply = dir.join("cloud.ply");
    let f = std::fs::File::create(&ply).unwrap();
    splat2tiles_io::write_ply(&s, std::io::BufWriter::new(f)).unwrap();
    let out = dir.join("layered");
    let opts = ConvertOptions {
        max_splats_per_tile: 400,
        scheme: SchemeChoice::Octree,
        subtree_levels: Some(2),
        layers: true,
        progress: None,
        ..ConvertOptions::default()
    };
    convert(&ply, &out, &opts).expect("convert --layers");
    out.join("tileset.json")
}

/// The dolly: cameras looking at the root's bounding sphere from the direction of auto view 1,
/// at the distances where the root's screen-space error goes from `SSE_FROM` to `SSE_TO` times
/// `MAX_SSE` (geometrically), the first and the last pose held for `HOLD` frames.
fn dolly(ts: &LoadedTileset) -> Vec<Camera> {
    let (lo, hi) = tileset_bounds(ts).unwrap();
    let up = tileset_up(ts);
    let view = auto_views_with(lo, hi, up, W, H, FOV).remove(1);
    let root = ts.tiles.iter().find(|t| t.key == TileKey::ROOT).unwrap();
    let (c, r) = splat2tiles_tiles::select::box_sphere(
        root.bounding_box.as_ref().unwrap(),
        &ts.root_transform,
    );
    let dir = (view.center() - c).normalize();
    let cams: Vec<Camera> = (0..=FRAMES)
        .map(|k| {
            let s = MAX_SSE * SSE_FROM * (SSE_TO / SSE_FROM).powf(k as f64 / FRAMES as f64);
            let d = root.geometric_error * view.fy / s + r;
            Camera::look_at(W, H, FOV, c + dir * d, c, up)
        })
        .collect();
    let mut held = vec![cams[0]; HOLD];
    held.extend(&cams);
    held.extend(std::iter::repeat_n(cams[FRAMES], HOLD));
    held
}

/// One frame of the streamed dolly: the image and the drawn layers' blend factors (client's,
/// and as drawn after the ramp or the hard swap).
struct Frame {
    image: Image,
    client_blend: Vec<f32>,
    drawn_blend: Vec<f32>,
}

/// Streams `url` along `cams` through the viewer's native path (driver, `SceneSync`, renderer):
/// at each pose the client is ticked until idle (all it wants is held), then the frame is drawn
/// at the pose's time (`FRAME_DT` apart).
fn stream_dolly(g: &Headless, url: &str, cams: &[Camera], mode: BlendMode) -> Vec<Frame> {
    let mut d = driver(url, W, H, FOV, MAX_SSE, Prefetch::BALANCED);
    let (early, mut clock) = bootstrap(&mut d, url, 0.0, 60.0).expect("tileset loads");
    let cfg = RendererConfig {
        blocking_sort: true,
        ..RendererConfig::default()
    };
    let mut r = SplatRenderer::new(&g.device, &g.queue, OFFSCREEN_FORMAT, cfg);
    let target = Offscreen::new(&g.device, W, H).unwrap();
    let mut sync = SceneSync::new(mode);
    sync.apply(&mut r, &g.device, &g.queue, d.client(), early, 0.0)
        .unwrap();
    let mut frames = vec![];
    for (k, cam) in cams.iter().enumerate() {
        let t = k as f64 * FRAME_DT;
        clock = clock.max(t);
        let start = std::time::Instant::now();
        loop {
            let ups = d.tick(clock, cam);
            sync.apply(&mut r, &g.device, &g.queue, d.client(), ups, t)
                .unwrap();
            if d.is_idle() || start.elapsed().as_secs() > 60 {
                break;
            }
            std::thread::sleep(std::time::Duration::from_millis(1));
            clock += 0.001;
        }
        assert!(d.is_idle(), "frame {k}: the client never settled");
        let s = d.stats();
        assert_eq!(s.errors, 0, "{:?}", s.last_errors);
        let drawn_blend = sync
            .apply(&mut r, &g.device, &g.queue, d.client(), vec![], t)
            .unwrap()
            .iter()
            .map(|l| l.blend)
            .collect();
        let client_blend = d.client().layers().iter().map(|l| l.blend).collect();
        r.render(&g.device, &g.queue, &target.view, cam, t);
        frames.push(Frame {
            image: target.read(&g.device, &g.queue).unwrap(),
            client_blend,
            drawn_blend,
        });
    }
    frames
}

fn steps(frames: &[Frame]) -> Vec<f64> {
    frames
        .windows(2)
        .map(|w| ssim(&w[0].image, &w[1].image).unwrap())
        .collect()
}

#[test]
fn a_streamed_level_change_blends_frame_by_frame_where_a_hard_swap_jumps() {
    let dir = tempfile::tempdir().unwrap();
    let path = layered_tileset(dir.path());
    let ts = load_tileset(&path).unwrap();
    assert!(is_layered(&ts));
    let cams = dolly(&ts);
    let url = path.to_str().unwrap();
    let g = gpu();

    let blended = stream_dolly(&g, url, &cams, BlendMode::Continuous);
    let hard = stream_dolly(&g, url, &cams, BlendMode::HardSwap);
    let (sb, sh) = (steps(&blended[HOLD..]), steps(&hard[HOLD..]));
    let worst = |s: &[f64]| s.iter().copied().fold(1.0, f64::min);
    println!("blended neighbour SSIM: {sb:.4?}");
    println!("hard-swap neighbour SSIM: {sh:.4?}");
    println!(
        "worst neighbour SSIM: blended {:.4}, hard swap {:.4}; first vs last blended frame {:.4}",
        worst(&sb),
        worst(&sh),
        ssim(&blended[HOLD].image, &blended.last().unwrap().image).unwrap()
    );
    // The dolly crosses a level change: the first frame draws the base alone, the last one a
    // deeper level with every layer fully in; some frame draws a layer partly blended in.
    assert_eq!(blended[HOLD].client_blend, vec![1.0]);
    assert_eq!(blended[HOLD].drawn_blend, vec![1.0]);
    let last = blended.last().unwrap();
    assert!(last.client_blend.len() > 1 && last.drawn_blend == last.client_blend);
    assert!(
        blended
            .iter()
            .any(|f| f.drawn_blend.iter().any(|&b| b > 0.1 && b < 0.9)),
        "no frame blends a layer partly in"
    );
    for (k, s) in sb.iter().enumerate() {
        assert!(
            *s >= 1.0 - SSIM_STEP,
            "blended frame {k} -> {}: SSIM {s}",
            k + 1
        );
    }
    // The control: the same dolly without blending jumps by more than the step somewhere.
    assert!(
        worst(&sh) < 1.0 - SSIM_STEP,
        "the hard swap never jumped: {sh:?}"
    );

    // Blended frames match the CPU reference renderer's layered render of the same camera: the
    // first frame where a layer is partly in and no ramp is running, and the last frame.
    let mid = blended
        .iter()
        .position(|f| {
            f.drawn_blend == f.client_blend && f.client_blend.iter().any(|&b| b > 0.2 && b < 0.8)
        })
        .expect("a settled partly blended frame");
    for k in [mid, blended.len() - 1] {
        let inst = layered_instances(&ts, &cams[k], MAX_SSE).unwrap();
        let refs: Vec<(&Splats, glam::DMat4)> = inst.iter().map(|(s, m)| (s, *m)).collect();
        let cpu = render(&refs, &cams[k], &RenderOptions::default()).quantized();
        let s = ssim(&cpu, &blended[k].image).unwrap();
        let _ = cpu.save_png(&dir.path().join(format!("cpu_{k}.png")));
        println!(
            "frame {k}: {} layers, blend {:?}, SSIM vs the reference {s:.4}",
            blended[k].client_blend.len(),
            blended[k].client_blend
        );
        assert!(s >= 0.97, "frame {k}: SSIM vs the reference {s}");
    }
}

/// Late layers (`splat2tiles_tiles::layers::ramp`): with the camera already deep in the blend band and
/// a slow link, child layers arrive while their blend factor is well above 0; the viewer draws
/// each from 0 at its first frame up to the client's factor `LAYER_RAMP_S` later, never stepping
/// more per frame than the ramp's slope allows, where the client's factor alone pops.
#[test]
fn late_layers_ramp_in_over_time_instead_of_popping() {
    use splat2tiles_lab::sim::transport::{NetModel, SimTransport};
    use splat2tiles_stream::client::{Action, ClientConfig, StreamClient};
    use splat2tiles_tiles::layers::ramp::LAYER_RAMP_S;
    use std::collections::HashMap;

    let dir = tempfile::tempdir().unwrap();
    let path = layered_tileset(dir.path());
    let ts = load_tileset(&path).unwrap();
    // The dolly pose nearest a root error of 1.6 x MAX_SSE: its children at t = 0.59.
    let cams = dolly(&ts);
    let k = (FRAMES as f64 * (1.6 / SSE_FROM).ln() / (SSE_TO / SSE_FROM).ln()).round() as usize;
    let cam = cams[HOLD + k];
    let mut net = SimTransport::new(path.parent().unwrap(), NetModel::constant(2.0, 0.05));
    let cfg = ClientConfig {
        width: W,
        height: H,
        fov_y_deg: FOV,
        max_sse: MAX_SSE,
        ..ClientConfig::default()
    };
    let mut client = StreamClient::new(&net.tileset_url(), cfg);
    let mut sync = SceneSync::new(BlendMode::Continuous);
    // The control mode on the same frames: no ramp, each child at 0 or 1 by its factor.
    let mut hard = SceneSync::new(BlendMode::HardSwap);
    let dt = 1.0 / 60.0;
    // Per scene id: first frame time, client factor then, last drawn factor.
    let mut seen: HashMap<u64, (f64, f32, f32)> = HashMap::new();
    let mut late = 0;
    let mut arrivals = vec![];
    let mut reached = 0;
    for frame in 0..(20.0 / dt) as usize {
        let t = frame as f64 * dt;
        while let Some(d) = net.next(t) {
            let a: Vec<Action> = d.into_input().apply(&mut client);
            net.apply(&a);
        }
        let a = client.update(t, &cam);
        net.apply(&a);
        let _ = client.take_updates();
        let want = client.layers();
        let drawn = sync.drawn_layers(&client, t);
        let swapped = hard.drawn_layers(&client, t);
        assert!(!hard.ramping());
        let ramping = drawn.iter().zip(&want).any(|(d, c)| d.blend < c.blend);
        assert_eq!(sync.ramping(), ramping, "at {t} s");
        for (c, l) in want.iter().zip(&swapped) {
            assert_eq!(l.blend, if c.blend >= 0.5 { 1.0 } else { 0.0 });
        }
        for (c, l) in want.iter().zip(&drawn) {
            match seen.get_mut(&l.scene_id) {
                None => {
                    assert_eq!(l.blend, 0.0, "{:?} drawn at once", c.key);
                    if c.parent.is_some() && c.blend > 0.3 {
                        late += 1;
                        arrivals.push((t, c.blend));
                    }
                    seen.insert(l.scene_id, (t, c.blend, 0.0));
                }
                Some((t0, c0, last)) => {
                    // The camera is still: the client's factor stays; the drawn one ramps.
                    assert_eq!(c.blend, *c0);
                    let slope = *c0 * (dt / LAYER_RAMP_S) as f32 + 1e-5;
                    assert!(
                        l.blend >= *last && l.blend - *last <= slope,
                        "{:?}: {} -> {}",
                        c.key,
                        last,
                        l.blend
                    );
                    if t - *t0 >= LAYER_RAMP_S + 1e-9 {
                        assert_eq!(l.blend, c.blend, "{:?} after the ramp", c.key);
                    }
                    if l.blend == c.blend && *last < c.blend {
                        reached += 1;
                    }
                    *last = l.blend;
                }
            }
        }
    }
    println!(
        "{} layers drawn, {late} child layers arrived with a blend factor > 0.3, {reached} ramped up to it",
        seen.len()
    );
    println!("late arrivals (s, client blend factor): {arrivals:.3?}");
    assert!(late >= 2, "no layer arrived late ({late})");
    assert_eq!(reached, seen.len(), "every layer reaches its factor");
}
