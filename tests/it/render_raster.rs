//! Known-answer, hard-case and determinism tests of the CPU reference rasterizer, on generated
//! splats (analytic 2D profile, compositing order, SH through the renderer, degenerate inputs).

use crate::common::scenes::{Lcg, axis_camera, random_cloud, set, splat};
use glam::{DMat3, DMat4, DQuat, DVec3};
use splat2tiles_core::splat::{Splat, Splats, sh};
use splat2tiles_render::{
    Camera, Image, RenderOptions, render, render_splats, render_with_stats, ssim,
};

fn opts() -> RenderOptions {
    RenderOptions::default()
}

fn max_diff(a: &Image, b: &Image) -> f32 {
    assert_eq!((a.width, a.height), (b.width, b.height));
    a.data
        .iter()
        .zip(&b.data)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max)
}

/// Every value finite and within [0, hi].
fn assert_sane(img: &Image, hi: f32) {
    for (i, v) in img.data.iter().enumerate() {
        assert!(v.is_finite() && *v >= 0.0 && *v <= hi, "value {i} = {v}");
    }
}

#[test]
fn isotropic_gaussian_matches_analytic_profile() {
    let (f, z, s, op) = (50.0f64, 5.0f64, 0.1f32, 0.8f32);
    let rgb = [0.6f32, 0.4, 0.2];
    let cam = axis_camera(64, 64, f);
    let scene = set(&[splat([0.0, 0.0, z], [s; 3], op, rgb)]);
    let img = render_splats(&scene, &cam, &opts());
    // sigma_px^2 = (f s / z)^2 + 0.3 (low-pass); centre on pixel (32, 32).
    let var = (f * s as f64 / z).powi(2) + 0.3;
    let c = sh::eval_color(0, scene.sh0[0], &[], [0.0, 0.0, 1.0]);
    for (dx, dy) in [(0i32, 0i32), (1, 0), (0, 2), (2, 1), (3, 0), (-2, -2)] {
        let d2 = (dx * dx + dy * dy) as f64;
        let alpha = (op as f64 * (-0.5 * d2 / var).exp()).min(0.99);
        let got = img.get((32 + dx) as u32, (32 + dy) as u32);
        for ch in 0..3 {
            let want = if alpha < 1.0 / 255.0 {
                0.0
            } else {
                alpha * c[ch] as f64
            };
            assert!(
                (got[ch] as f64 - want).abs() < 2e-6,
                "pixel offset ({dx},{dy}) ch {ch}: {} vs {want}",
                got[ch]
            );
        }
    }
    // Beyond the 1/255 cut-off the pixel is exactly the background.
    assert_eq!(img.get(36, 32), [0.0; 3]);
    assert!(0.8 * (-0.5 * 16.0 / var).exp() < 1.0 / 255.0);
}

#[test]
fn two_splats_composite_front_to_back() {
    let cam = axis_camera(32, 32, 40.0);
    let (c1, c2) = ([0.9f32, 0.1, 0.2], [0.1f32, 0.8, 0.3]);
    let near = splat([0.0, 0.0, 3.0], [0.3; 3], 0.6, c1);
    let far = splat([0.0, 0.0, 6.0], [0.6; 3], 0.7, c2);
    let bg = [0.2f32, 0.3, 0.4];
    let o = RenderOptions {
        background: bg,
        ..opts()
    };
    // Input order far-then-near: the sort must put `near` first.
    let img = render_splats(&set(&[far, near]), &cam, &o);
    let (a1, a2) = (0.6f32, 0.7f32);
    let got = img.get(16, 16);
    for ch in 0..3 {
        let want = a1 * c1[ch] + (1.0 - a1) * a2 * c2[ch] + (1.0 - a1) * (1.0 - a2) * bg[ch];
        assert!(
            (got[ch] - want).abs() < 1e-5,
            "ch {ch}: {} vs {want}",
            got[ch]
        );
    }
}

#[test]
fn sh_degree1_through_the_renderer_and_model_frame() {
    let cam = axis_camera(32, 32, 40.0);
    let mut s = Splats::new(1);
    // Red gets the m=0 (z) coefficient, green the m=+1 (x) one.
    let rest = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    s.push(
        Splat {
            position: [0.0, 0.0, 5.0],
            scale: [0.5; 3],
            rotation: [0.0, 0.0, 0.0, 1.0],
            opacity: 1.0,
            sh0: [0.0; 3],
        },
        &rest,
    );
    // Opacity 1 is capped to 0.99 at the centre pixel.
    let img = render_splats(&s, &cam, &opts());
    let got = img.get(16, 16);
    let want = [0.99 * (0.5 + sh::SH_C1), 0.99 * 0.5, 0.99 * 0.5];
    for ch in 0..3 {
        assert!((got[ch] - want[ch]).abs() < 1e-6, "{got:?} vs {want:?}");
    }
    // Same splat in a frame rotated -90 deg about y: local x is world z, so the view direction
    // in the splat's frame is +x: red (z) sees 0, green (m=+1 carries -C1 x) sees -C1.
    let model = DMat4::from_rotation_y(-std::f64::consts::FRAC_PI_2);
    let mut local = s.clone();
    local.positions[0] = [5.0, 0.0, 0.0];
    let img = render(&[(&local, model)], &cam, &opts());
    let got = img.get(16, 16);
    let want = [0.99 * 0.5, 0.99 * (0.5 - sh::SH_C1), 0.99 * 0.5];
    for ch in 0..3 {
        assert!((got[ch] - want[ch]).abs() < 1e-6, "{got:?} vs {want:?}");
    }
    // Truncating to degree 0 drops the view dependence.
    let o = RenderOptions {
        max_sh_degree: 0,
        ..opts()
    };
    let got = render_splats(&s, &cam, &o).get(16, 16);
    assert!((got[0] - 0.99 * 0.5).abs() < 1e-6);
}

#[test]
fn deterministic_across_runs_and_thread_counts() {
    let scene = random_cloud(3000, 3, DVec3::new(0.0, 0.0, 4.0), 7);
    let cam = axis_camera(96, 80, 70.0);
    let a = render_splats(&scene, &cam, &opts());
    let b = render_splats(&scene, &cam, &opts());
    assert_eq!(a.data, b.data);
    for threads in [1, 2, 3] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let c = pool.install(|| render_splats(&scene, &cam, &opts()));
        assert!(a.data == c.data, "{threads} threads differ");
    }
    assert_sane(&a, 10.0);
}

#[test]
fn empty_scene_and_empty_image_are_background() {
    let cam = axis_camera(20, 10, 20.0);
    let bg = [0.1, 0.2, 0.3];
    let o = RenderOptions {
        background: bg,
        ..opts()
    };
    let img = render_splats(&Splats::new(0), &cam, &o);
    assert_eq!(img, Image::filled(20, 10, bg));
    let img = render(&[], &cam, &o);
    assert_eq!(img, Image::filled(20, 10, bg));
    let zero = Camera { width: 0, ..cam };
    assert!(render(&[], &zero, &o).data.is_empty());
}

#[test]
fn behind_and_crossing_the_camera_plane() {
    let cam = axis_camera(48, 48, 40.0);
    let bg = [0.25f32; 3];
    let o = RenderOptions {
        background: bg,
        ..opts()
    };
    // Centre behind the camera, and centre in front of the eye but inside the near plane.
    for z in [-3.0, 0.0, 0.1, 0.2] {
        let img = render_splats(
            &set(&[splat([0.0, 0.0, z], [2.0; 3], 0.9, [1.0; 3])]),
            &cam,
            &o,
        );
        assert_eq!(img, Image::filled(48, 48, bg), "z = {z}");
    }
    // Centre just in front, extent crossing the camera plane (and off to the side).
    for x in [0.0, 3.0, 50.0] {
        let img = render_splats(
            &set(&[splat([x, 0.0, 0.5], [2.0; 3], 0.9, [1.0; 3])]),
            &cam,
            &o,
        );
        assert_sane(&img, 1.0);
    }
}

#[test]
fn degenerate_scales_stay_finite() {
    let cam = axis_camera(40, 30, 30.0);
    let rgb = [0.5f32, 0.7, 0.9];
    // Zero scale: a 0.3 px^2 blob; the centre pixel has alpha = opacity.
    let img = render_splats(
        &set(&[splat([0.0, 0.0, 4.0], [0.0; 3], 0.5, rgb)]),
        &cam,
        &opts(),
    );
    assert_sane(&img, 1.0);
    let c = img.get(20, 15);
    assert!((c[1] - 0.5 * 0.7).abs() < 1e-5, "{c:?}");
    // Enormous scale: covers the screen with a constant alpha = opacity.
    let img = render_splats(
        &set(&[splat([0.0, 0.0, 4.0], [1e30; 3], 0.5, rgb)]),
        &cam,
        &opts(),
    );
    assert_sane(&img, 1.0);
    for (x, y) in [(0, 0), (39, 29), (20, 15)] {
        let c = img.get(x, y);
        assert!((c[2] - 0.5 * 0.9).abs() < 1e-5, "({x},{y}): {c:?}");
    }
    // Mixed enormous and tiny axes, in several orientations.
    let mut r = Lcg(3);
    for scale in [
        [1e30, 0.0, 1.0],
        [0.0, 1e30, 0.0],
        [1e30, 1e30, 0.0],
        [0.0, 0.0, 1e30],
    ] {
        let mut items = Vec::new();
        for _ in 0..4 {
            let mut s = splat([0.0, 0.0, 4.0], scale, 0.5, rgb);
            s.rotation = [r.next(), r.next(), r.next(), r.next()].map(|v| (v - 0.5) as f32);
            items.push(s);
        }
        let img = render_splats(&set(&items), &cam, &opts());
        assert_sane(&img, 1.0);
    }
    // Singular covariance (one zero axis), seen face-on and edge-on.
    for scale in [[1.0, 1.0, 0.0], [1.0, 0.0, 1.0], [0.0, 0.0, 1.0]] {
        let img = render_splats(
            &set(&[splat([0.3, 0.0, 4.0], scale, 0.8, rgb)]),
            &cam,
            &opts(),
        );
        assert_sane(&img, 1.0);
        assert!(img.data.iter().any(|&v| v > 0.0), "{scale:?} left no trace");
    }
}

#[test]
fn opacity_extremes() {
    let cam = axis_camera(32, 32, 30.0);
    let img = render_splats(
        &set(&[splat([0.0, 0.0, 3.0], [0.3; 3], 0.0, [1.0; 3])]),
        &cam,
        &opts(),
    );
    assert_eq!(img, Image::filled(32, 32, [0.0; 3]));
    let img = render_splats(
        &set(&[splat([0.0, 0.0, 3.0], [0.3; 3], 1.0, [1.0; 3])]),
        &cam,
        &opts(),
    );
    assert_sane(&img, 1.0);
    assert!((img.get(16, 16)[0] - 0.99).abs() < 1e-6);
}

#[test]
fn quaternion_sign_and_norm_do_not_matter() {
    let cam = axis_camera(64, 48, 50.0);
    let mut base = random_cloud(400, 1, DVec3::new(0.0, 0.0, 3.0), 11);
    let a = render_splats(&base, &cam, &opts());
    let mut neg = base.clone();
    for q in &mut neg.rotations {
        *q = q.map(|v| -v);
    }
    assert_eq!(render_splats(&neg, &cam, &opts()).data, a.data, "q vs -q");
    for q in &mut base.rotations {
        *q = q.map(|v| v * 7.5);
    }
    let b = render_splats(&base, &cam, &opts());
    assert!(
        max_diff(&a, &b) < 1e-4,
        "unnormalised: {}",
        max_diff(&a, &b)
    );
    // A zero quaternion renders as the identity rotation.
    let mut z = set(&[splat([0.0, 0.0, 3.0], [0.5, 0.1, 0.1], 0.8, [1.0; 3])]);
    let id = render_splats(&z, &cam, &opts());
    z.rotations[0] = [0.0; 4];
    assert_eq!(render_splats(&z, &cam, &opts()).data, id.data);
}

#[test]
fn far_from_origin_renders_like_near_origin() {
    let scene = random_cloud(2000, 2, DVec3::new(0.0, 0.0, 0.0), 5);
    let eye = DVec3::new(0.5, -1.0, -3.5);
    let up = -DVec3::Y;
    let near_cam = Camera::look_at(80, 60, 50.0, eye, DVec3::ZERO, up);
    let reference = render_splats(&scene, &near_cam, &opts());
    assert!(reference.data.iter().any(|&v| v > 0.1));
    let off = DVec3::new(1.0e6, -2.0e6, 1.5e6);
    // (a) Positions themselves 1e6 m away, camera moved with them.
    let mut moved = scene.clone();
    for p in &mut moved.positions {
        *p = (DVec3::from(*p) + off).to_array();
    }
    let far_cam = Camera::look_at(80, 60, 50.0, eye + off, off, up);
    let a = render_splats(&moved, &far_cam, &opts());
    assert!(
        max_diff(&a, &reference) < 1e-5,
        "positions: {}",
        max_diff(&a, &reference)
    );
    // (b) Splats near their own origin, placed by a model matrix.
    let b = render(&[(&scene, DMat4::from_translation(off))], &far_cam, &opts());
    assert!(
        max_diff(&b, &reference) < 1e-5,
        "model: {}",
        max_diff(&b, &reference)
    );
}

#[test]
fn model_rotation_and_scale_act_on_the_covariance() {
    let cam = Camera::look_at(
        80,
        64,
        50.0,
        DVec3::new(0.3, -0.5, -4.0),
        DVec3::ZERO,
        -DVec3::Y,
    );
    let scene = random_cloud(800, 0, DVec3::ZERO, 9);
    // Rotation: same as pre-rotating positions and quaternions (degree 0: no SH to rotate).
    let q = DQuat::from_euler(glam::EulerRot::XYZ, 0.4, -0.7, 1.1);
    let mut rotated = scene.clone();
    for i in 0..scene.len() {
        rotated.positions[i] = (q * DVec3::from(scene.positions[i])).to_array();
        let r = scene.rotations[i].map(|v| v as f64);
        let qr = q * DQuat::from_xyzw(r[0], r[1], r[2], r[3]);
        rotated.rotations[i] = [qr.x, qr.y, qr.z, qr.w].map(|v| v as f32);
    }
    let a = render(&[(&scene, DMat4::from_quat(q))], &cam, &opts());
    let b = render_splats(&rotated, &cam, &opts());
    assert!(max_diff(&a, &b) < 1e-3, "rotation: {}", max_diff(&a, &b));
    // Non-uniform scale on axis-aligned splats: same as scaling positions and scales.
    let mut aligned = scene.clone();
    aligned
        .rotations
        .iter_mut()
        .for_each(|r| *r = [0.0, 0.0, 0.0, 1.0]);
    let k = [2.0, 0.5, 1.5];
    let mut scaled = aligned.clone();
    for i in 0..scene.len() {
        for (ax, kv) in k.iter().enumerate() {
            scaled.positions[i][ax] *= kv;
            scaled.scales[i][ax] *= *kv as f32;
        }
    }
    let model = DMat4::from_mat3(DMat3::from_diagonal(DVec3::from(k)));
    let a = render(&[(&aligned, model)], &cam, &opts());
    let b = render_splats(&scaled, &cam, &opts());
    assert!(max_diff(&a, &b) < 1e-3, "scale: {}", max_diff(&a, &b));
    assert!(ssim(&a, &b).unwrap() > 0.9999);
}

#[test]
fn instances_equal_the_merged_set() {
    let cam = axis_camera(64, 64, 60.0);
    let a = random_cloud(300, 1, DVec3::new(-0.5, 0.0, 4.0), 1);
    let b = random_cloud(300, 1, DVec3::new(0.5, 0.0, 4.5), 2);
    let mut merged = a.clone();
    for i in 0..b.len() {
        merged.push_from(&b, i);
    }
    let one = render_splats(&merged, &cam, &opts());
    let two = render(
        &[(&a, DMat4::IDENTITY), (&b, DMat4::IDENTITY)],
        &cam,
        &opts(),
    );
    assert_eq!(one.data, two.data);
}

#[test]
fn non_finite_splats_are_skipped() {
    let cam = axis_camera(48, 48, 40.0);
    let good = splat([0.0, 0.0, 3.0], [0.4; 3], 0.8, [0.2, 0.6, 0.9]);
    let clean = render_splats(&set(&[good]), &cam, &opts());
    let mut bad = vec![good];
    for k in 0..6 {
        let mut s = good;
        match k {
            0 => s.position[0] = f64::NAN,
            1 => s.scale[1] = f32::NAN,
            2 => s.rotation[2] = f32::INFINITY,
            3 => s.opacity = f32::NAN,
            4 => s.sh0[0] = f32::NEG_INFINITY,
            _ => s.position[2] = f64::INFINITY,
        }
        bad.push(s);
    }
    let (img, stats) = render_with_stats(&[(&set(&bad), DMat4::IDENTITY)], &cam, &opts());
    assert_eq!(img.data, clean.data);
    assert_eq!(stats.non_finite, 6);
    assert_eq!(stats.visible, 1);
    // A non-finite model matrix skips its whole instance.
    let mut m = DMat4::IDENTITY;
    m.w_axis.x = f64::NAN;
    let (img, stats) = render_with_stats(&[(&set(&[good]), m)], &cam, &opts());
    assert_eq!(img, Image::filled(48, 48, [0.0; 3]));
    assert_eq!(stats.non_finite, 1);
}
