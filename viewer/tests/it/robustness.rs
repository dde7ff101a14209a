//! Hostile splats (NaN, Inf, zero and 1e30 scales, opacity 0 and 1, antipodal quaternions, a
//! splat on the camera plane) render without panic or GPU validation error; the tile life cycle
//! (fade in, append, replace, remove, slot reuse) and the lazy re-sort behave.

use crate::common::*;
use glam::{DMat4, DVec3};
use splat2tiles_core::camera::Camera;
use splat2tiles_core::splat::{Splat, Splats};
use splat2tiles_render::metrics::ssim;
use splat2tiles_viewer::gpu::{OFFSCREEN_FORMAT, Offscreen};
use splat2tiles_viewer::{RendererConfig, SplatRenderer};

fn cam() -> Camera {
    Camera::look_at(
        200,
        150,
        60.0,
        DVec3::new(0.0, -3.0, 0.0),
        DVec3::ZERO,
        DVec3::Z,
    )
}

fn item(pos: [f64; 3], scale: f32, opacity: f32, q: [f32; 4]) -> Splat {
    Splat {
        position: pos,
        scale: [scale; 3],
        rotation: q,
        opacity,
        sh0: [1.0, 0.2, -0.5],
    }
}

/// A handful of ordinary splats in front of the camera.
fn normal() -> Splats {
    let mut s = Splats::new(0);
    for k in 0..9 {
        let x = (k % 3) as f64 * 0.6 - 0.6;
        let z = (k / 3) as f64 * 0.5 - 0.5;
        s.push(item([x, 0.0, z], 0.12, 0.8, [0.0, 0.0, 0.0, 1.0]), &[]);
    }
    s
}

#[test]
fn hostile_splats_render_cleanly() {
    let g = gpu();
    let base = normal();
    let mut hostile = base.clone();
    let id = [0.0, 0.0, 0.0, 1.0];
    let h = std::f32::consts::FRAC_1_SQRT_2;
    let finite_odd = [
        item([0.1, 0.5, 0.1], 0.0, 0.9, id),                 // zero scale
        item([-0.3, 0.2, 0.3], 0.1, 0.0, id),                // opacity 0
        item([0.3, -0.2, -0.3], 0.1, 1.0, id),               // opacity 1
        item([0.0, 0.3, 0.0], 0.1, 0.7, [0.0, 0.0, h, h]),   // +q
        item([0.0, 0.3, 0.0], 0.1, 0.7, [0.0, 0.0, -h, -h]), // -q, same rotation
        item([0.0, -3.0, 0.0], 0.2, 0.9, id),                // at the camera centre
        item([0.5, -3.0, 0.2], 0.2, 0.9, id),                // on the camera plane
        item([0.0, 0.0, 0.0], 0.1, 0.9, [0.0; 4]),           // zero quaternion
    ];
    for s in finite_odd {
        hostile.push(s, &[]);
    }
    let cpu = reference(
        &[(hostile.clone(), DMat4::IDENTITY)],
        &cam(),
        &Default::default(),
    );
    let mut with_bad = hostile.clone();
    let bad = [
        item([f64::NAN, 0.0, 0.0], 0.1, 0.9, id),
        item([0.0, f64::INFINITY, 0.0], 0.1, 0.9, id),
        item([0.0, 0.0, 0.0], f32::NAN, 0.9, id),
        item([0.0, 0.0, 0.0], 0.1, f32::INFINITY, id),
        item([0.0, 0.0, 0.0], 0.1, 0.9, [f32::NAN, 0.0, 0.0, 1.0]),
    ];
    for s in bad {
        with_bad.push(s, &[]);
    }
    let mut sh_nan = item([0.0, 0.0, 0.0], 0.1, 0.9, id);
    sh_nan.sh0 = [f32::NAN, 0.0, 0.0];
    with_bad.push(sh_nan, &[]);
    let (img, stats) = gpu_frame(
        &g,
        &[(with_bad, DMat4::IDENTITY)],
        &cam(),
        RendererConfig::default(),
    );
    assert_eq!(
        stats.skipped_non_finite, 6,
        "every NaN/Inf splat skipped on upload"
    );
    assert!(img.data.iter().all(|v| v.is_finite()));
    let s = ssim(&cpu, &img).unwrap();
    println!("hostile (finite oddities) vs reference: SSIM {s:.5}");
    assert!(s >= 0.98, "SSIM {s}");
    // A 1e30-scale splat (f32 overflow in the projection) is dropped, not smeared as NaN.
    let mut huge = hostile.clone();
    huge.push(item([0.0, 0.0, 0.0], 1e30, 0.9, id), &[]);
    let mut huge2 = huge.clone();
    huge2.push(item([0.2, 0.0, 0.0], 3e38, 0.9, [1e30, 0.0, 0.0, 1.0]), &[]);
    let (img_huge, _) = gpu_frame(&g, &[(huge2, DMat4::IDENTITY)], &cam(), Default::default());
    let (img_plain, _) = gpu_frame(
        &g,
        &[(hostile, DMat4::IDENTITY)],
        &cam(),
        Default::default(),
    );
    assert!(
        img_huge.data == img_plain.data,
        "huge splats must be dropped cleanly"
    );
    assert!(mean(&img_plain) > 0.01, "the ordinary splats are drawn");
    // Degenerate model matrices and cameras: no panic, background.
    let (img_sing, _) = gpu_frame(&g, &[(huge, DMat4::ZERO)], &cam(), Default::default());
    assert_eq!(mean(&img_sing), 0.0);
    let nan_model = DMat4::from_translation(DVec3::new(f64::NAN, 0.0, 0.0));
    let (img_nan, _) = gpu_frame(&g, &[(normal(), nan_model)], &cam(), Default::default());
    assert_eq!(mean(&img_nan), 0.0);
}

/// Renders one frame of `r` at `now` and reads it back.
fn frame(g: &Headless, r: &mut SplatRenderer, now: f64) -> splat2tiles_render::Image {
    let cam = cam();
    let t = Offscreen::new(&g.device, cam.width, cam.height).unwrap();
    r.render(&g.device, &g.queue, &t.view, &cam, now);
    t.read(&g.device, &g.queue).unwrap()
}

/// Renders one frame of `r` at `now`: whether some tile was drawn fading in or out.
fn fading_at(g: &Headless, r: &mut SplatRenderer, now: f64) -> bool {
    let cam = cam();
    let t = Offscreen::new(&g.device, cam.width, cam.height).unwrap();
    r.render(&g.device, &g.queue, &t.view, &cam, now).fading
}

use splat2tiles_viewer::gpu::Headless;

#[test]
fn tiles_fade_append_replace_and_free() {
    let g = gpu();
    let cfg = RendererConfig {
        blocking_sort: true,
        ..RendererConfig::default()
    };
    let mut r = SplatRenderer::new(&g.device, &g.queue, OFFSCREEN_FORMAT, cfg);
    let all = normal();
    let first = all.select(&[0, 1, 2, 3]);
    let rest = all.select(&[4, 5, 6, 7, 8]);
    r.insert_tile(&g.device, &g.queue, 1, &first, DMat4::IDENTITY, 10.0);
    assert_eq!(
        mean(&frame(&g, &mut r, 10.0)),
        0.0,
        "alpha 0 at insert time"
    );
    let half_way = mean(&frame(&g, &mut r, 10.15));
    assert!(fading_at(&g, &mut r, 10.2), "fading in");
    let full_first = mean(&frame(&g, &mut r, 10.3));
    assert!(!fading_at(&g, &mut r, 10.35), "faded in");
    assert!(
        0.0 < half_way && half_way < full_first,
        "{half_way} {full_first}"
    );
    r.append_tile(&g.device, &g.queue, 1, &rest, 10.3);
    assert_eq!(r.resident_splats(), 9);
    let appended = frame(&g, &mut r, 11.0);
    // The same splats inserted at once give the same frame.
    let mut whole = SplatRenderer::new(&g.device, &g.queue, OFFSCREEN_FORMAT, cfg);
    whole.insert_tile(&g.device, &g.queue, 9, &all, DMat4::IDENTITY, 0.0);
    let at_once = frame(&g, &mut whole, 1.0);
    assert!(
        appended.data == at_once.data,
        "append == insert of the whole"
    );
    // Replace: new id fading in (shifted copy), old fading out; mid-way both are drawn.
    let shifted = DMat4::from_translation(DVec3::new(0.0, 0.0, 0.4));
    r.insert_tile(&g.device, &g.queue, 2, &all, shifted, 11.0);
    r.remove_tile(1, 11.0);
    let mid = frame(&g, &mut r, 11.15);
    assert_eq!(r.resident_tiles(), 2);
    assert!(fading_at(&g, &mut r, 11.2), "cross-fade");
    let done = frame(&g, &mut r, 11.4);
    assert_eq!(r.resident_tiles(), 1, "faded-out tile freed");
    assert!(!fading_at(&g, &mut r, 11.45), "cross-fade over");
    assert_eq!(r.resident_splats(), 9);
    assert!(mid.data != done.data && mid.data != appended.data);
    // Slots freed by the removed tile are reused: the page count does not grow.
    let gpu_before = r.gpu_bytes();
    for id in 10..20 {
        r.insert_tile(&g.device, &g.queue, id, &all, DMat4::IDENTITY, 12.0);
        r.remove_tile(id, 12.0);
        frame(&g, &mut r, 13.0);
    }
    assert_eq!(r.gpu_bytes(), gpu_before);
    assert_eq!(r.resident_splats(), 9);
    // Removing everything leaves the background.
    r.remove_tile(2, 14.0);
    // Fading out alone (nothing fading in) is fading too: the tile is resident, not in the scene.
    assert!(fading_at(&g, &mut r, 14.1), "fading out");
    assert_eq!(r.resident_splats(), 9);
    let empty = frame(&g, &mut r, 15.0);
    assert!(!fading_at(&g, &mut r, 15.1), "faded out");
    assert_eq!(mean(&empty), 0.0);
    assert_eq!(r.resident_splats(), 0);
    assert!(r.cpu_bytes() < 1 << 20);
}

#[test]
fn resorts_lazily_and_worker_order_arrives() {
    let g = gpu();
    let all = normal();
    let cam0 = cam();
    let t = Offscreen::new(&g.device, cam0.width, cam0.height).unwrap();
    // Blocking: decisions are deterministic frame by frame.
    let cfg = RendererConfig {
        blocking_sort: true,
        ..RendererConfig::default()
    };
    let mut r = SplatRenderer::new(&g.device, &g.queue, OFFSCREEN_FORMAT, cfg);
    r.insert_tile(&g.device, &g.queue, 1, &all, DMat4::IDENTITY, 0.0);
    let mut at = |c: &Camera, now: f64| r.render(&g.device, &g.queue, &t.view, c, now);
    assert!(at(&cam0, 1.0).sorted, "resident set changed");
    assert!(!at(&cam0, 1.1).sorted, "nothing changed");
    let moved = |d: DVec3| {
        let mut c = cam0;
        c.world_from_camera.w_axis += d.extend(0.0);
        c
    };
    assert!(
        !at(&moved(DVec3::new(1.5, 0.0, 0.0)), 1.2).sorted,
        "1.5 m < 2 m"
    );
    assert!(
        at(&moved(DVec3::new(2.5, 0.0, 0.0)), 1.3).sorted,
        "2.5 m > 2 m"
    );
    // Turning: 10 degrees about the up axis keeps the order, 20 (from the last sort) re-sorts.
    let turned = |deg: f64| {
        let mut c = moved(DVec3::new(2.5, 0.0, 0.0));
        let rot = glam::DMat4::from_rotation_z(deg.to_radians());
        let pos = c.world_from_camera.w_axis;
        c.world_from_camera = rot * c.world_from_camera;
        c.world_from_camera.w_axis = pos;
        c
    };
    assert!(!at(&turned(10.0), 1.4).sorted, "10 deg < 15 deg");
    assert!(at(&turned(20.0), 1.5).sorted, "20 deg > 15 deg");
    // Worker thread (non-blocking): the first frames may draw nothing, the order then arrives.
    let mut w = SplatRenderer::new(
        &g.device,
        &g.queue,
        OFFSCREEN_FORMAT,
        RendererConfig::default(),
    );
    w.insert_tile(&g.device, &g.queue, 7, &all, DMat4::IDENTITY, 0.0);
    let mut drawn = 0;
    for k in 0..2000 {
        let s = w.render(&g.device, &g.queue, &t.view, &cam0, 1.0 + k as f64 * 1e-3);
        drawn = s.drawn;
        if drawn == all.len() {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(1));
    }
    assert_eq!(drawn, all.len(), "the worker's order was applied");
    let img = t.read(&g.device, &g.queue).unwrap();
    assert!(mean(&img) > 0.01);
}
