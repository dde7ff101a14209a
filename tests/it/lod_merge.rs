//! Merging clusters of Gaussians into one: numerical stability (zero opacity, single members,
//! antipodal quaternions, mixed huge/tiny scales, coincident centres) and known analytic answers.

use glam::{DMat3, DQuat, DVec3};
use splat2tiles_build::lod::math::{covariance, markley_average};
use splat2tiles_build::lod::{MergeRule, cluster, cluster_to_budget, merge_all, merge_drawn};
use splat2tiles_core::splat::{Splat, Splats};

const RULES: [MergeRule; 2] = [MergeRule::Moment, MergeRule::Axis];

fn splat(p: [f64; 3], s: [f32; 3], q: [f32; 4], a: f32, c: f32) -> Splat {
    Splat {
        position: p,
        scale: s,
        rotation: q,
        opacity: a,
        sh0: [c, -c, 0.5 * c],
    }
}

fn set(deg: u8, items: &[Splat]) -> Splats {
    let mut s = Splats::new(deg);
    for (k, it) in items.iter().enumerate() {
        let rest = vec![[k as f32 * 0.1, -0.2, 0.3]; s.rest_per_splat()];
        s.push(*it, &rest);
    }
    s
}

fn assert_finite(s: &Splats) {
    s.check_lengths();
    for i in 0..s.len() {
        assert!(s.is_finite(i), "splat {i} not finite: {:?}", s.get(i));
        let q = s.rotations[i];
        let n: f32 = q.iter().map(|v| v * v).sum::<f32>().sqrt();
        assert!((n - 1.0).abs() < 1e-4, "unit quaternion: {q:?}");
        assert!((0.0..=1.0).contains(&s.opacities[i]));
        assert!(s.scales[i].iter().all(|v| *v >= 0.0));
    }
}

fn quat_z(deg: f64) -> [f32; 4] {
    let q = DQuat::from_rotation_z(deg.to_radians());
    [q.x as f32, q.y as f32, q.z as f32, q.w as f32]
}

fn cov_of(s: &Splats, i: usize) -> DMat3 {
    covariance(s.scales[i], s.rotations[i])
}

#[test]
fn zero_total_opacity_falls_back_to_unweighted_means() {
    for rule in RULES {
        let s = set(
            1,
            &[
                splat([0.0, 0.0, 0.0], [0.1; 3], quat_z(0.0), 0.0, 1.0),
                splat([2.0, 0.0, 0.0], [0.1; 3], quat_z(10.0), 0.0, 3.0),
                splat([4.0, 0.0, 0.0], [0.1; 3], quat_z(20.0), 1e-30, 5.0),
            ],
        );
        let m = merge_all(&s, rule);
        assert_finite(&m);
        assert!(
            (m.positions[0][0] - 2.0).abs() < 1e-9,
            "{:?}",
            m.positions[0]
        );
        assert!((m.sh0[0][0] - 3.0).abs() < 1e-5);
        assert!(m.opacities[0] < 1e-6);
    }
}

#[test]
fn single_splat_cluster_is_an_exact_copy() {
    for rule in RULES {
        let s = set(
            3,
            &[splat(
                [1e6, -3.5, 7.25],
                [0.3, 0.01, 2.0],
                [0.0, 0.0, -0.6, -0.8],
                0.42,
                0.7,
            )],
        );
        assert_eq!(merge_all(&s, rule), s);
        // And through the clustering with any radius.
        assert_eq!(cluster(&s, 10.0, rule).splats, s);
    }
}

#[test]
fn antipodal_quaternions_average_to_the_rotation() {
    let q = splat2tiles_core::splat::normalize_quat([0.2, -0.4, 0.1, 0.8]);
    let neg = q.map(|v| -v);
    let avg = markley_average(&[q.map(|v| v as f64), neg.map(|v| v as f64)], &[0.5, 0.5]);
    let dot: f64 = avg.iter().zip(q).map(|(a, b)| a * b as f64).sum();
    assert!((dot.abs() - 1.0).abs() < 1e-6, "{avg:?} vs {q:?}");
    // Merged with the axis rule, two coincident splats with q and -q keep the rotation.
    let s = set(
        0,
        &[
            splat([0.0; 3], [1.0, 0.5, 0.2], q, 0.5, 0.0),
            splat([0.0; 3], [1.0, 0.5, 0.2], neg, 0.5, 0.0),
        ],
    );
    for rule in RULES {
        let m = merge_all(&s, rule);
        assert_finite(&m);
        let c = cov_of(&m, 0);
        let want = cov_of(&s, 0);
        let err = (c - want)
            .to_cols_array()
            .iter()
            .fold(0.0f64, |a, d| a.max(d.abs()));
        if rule == MergeRule::Moment {
            assert!(err < 1e-5, "moment: covariance kept, err {err}");
        } else {
            let d: f32 = m.rotations[0].iter().zip(q).map(|(a, b)| a * b).sum();
            assert!((d.abs() - 1.0).abs() < 1e-5, "axis: rotation kept");
            assert!(err < 1e-5, "axis: coincident cover = the splat, err {err}");
        }
    }
}

#[test]
fn markley_weighted_average_about_one_axis() {
    // Equal weights: the midpoint rotation.
    let a = quat_z(0.0).map(|v| v as f64);
    let b = quat_z(90.0).map(|v| v as f64);
    let m = markley_average(&[a, b], &[1.0, 1.0]);
    let want = quat_z(45.0);
    for k in 0..4 {
        assert!((m[k] - want[k] as f64).abs() < 1e-6, "{m:?} vs {want:?}");
    }
    // Weights 3:1. In quaternion space the eigenvector sits at alpha from `a` with
    // tan(2 alpha) = w2 sin(2 phi) / (w1 + w2 cos(2 phi)), phi = 45 deg (half the 90 deg turn):
    // tan(2 alpha) = 1/3, so the rotation angle is 2 alpha = atan(1/3) = 18.435 deg.
    let m = markley_average(&[a, b], &[3.0, 1.0]);
    let angle = 2.0 * m[2].atan2(m[3]).to_degrees();
    assert!(
        (angle - (1.0f64 / 3.0).atan().to_degrees()).abs() < 1e-6,
        "{angle}"
    );
    assert!(m[0].abs() < 1e-9 && m[1].abs() < 1e-9, "stays about z");
    // Zero weights: equal weights.
    let m = markley_average(&[a, b], &[0.0, 0.0]);
    assert!((2.0 * m[2].atan2(m[3]).to_degrees() - 45.0).abs() < 1e-6);
}

#[test]
fn moment_matching_reproduces_one_gaussian_and_two_side_by_side() {
    let q = splat2tiles_core::splat::normalize_quat([0.3, 0.1, -0.5, 0.7]);
    // Two identical copies at the same place: the same Gaussian.
    let g = splat([1.0, 2.0, 3.0], [0.5, 0.2, 0.05], q, 0.8, 0.3);
    let s = set(2, &[g, g]);
    let m = merge_all(&s, MergeRule::Moment);
    assert_finite(&m);
    let err = (cov_of(&m, 0) - cov_of(&s, 0))
        .to_cols_array()
        .iter()
        .fold(0.0f64, |a, d| a.max(d.abs()));
    assert!(err < 1e-6, "covariance kept: {err}");
    assert_eq!(m.positions[0], g.position);
    // Two coincident copies cover like their union: alpha* = 1 - 0.2^2 (above eq. 2's 0.8, below
    // the opacity mass 1.6).
    assert!((m.opacities[0] - 0.96).abs() < 1e-6, "{}", m.opacities[0]);
    // Two equal isotropic Gaussians at x = +/- a: Sigma* = s^2 I + diag(a^2, 0, 0).
    let (sd, a) = (0.3f64, 1.5f64);
    let s = set(
        0,
        &[
            splat([-a, 0.0, 0.0], [sd as f32; 3], quat_z(0.0), 0.6, 0.0),
            splat([a, 0.0, 0.0], [sd as f32; 3], quat_z(33.0), 0.6, 0.0),
        ],
    );
    let m = merge_all(&s, MergeRule::Moment);
    assert_finite(&m);
    let want = DMat3::from_diagonal(DVec3::new(sd * sd + a * a, sd * sd, sd * sd));
    let err = (cov_of(&m, 0) - want)
        .to_cols_array()
        .iter()
        .fold(0.0f64, |x, d| x.max(d.abs()));
    assert!(
        err < 1e-5,
        "analytic covariance, err {err}: {:?}",
        m.scales[0]
    );
    let mut sc = m.scales[0];
    sc.sort_by(|x, y| y.total_cmp(x));
    assert!((sc[0] as f64 - (sd * sd + a * a).sqrt()).abs() < 1e-5);
    assert!(m.positions[0].iter().all(|v| v.abs() < 1e-12));
}

#[test]
fn axis_cover_spans_the_members() {
    // Two unit spheres 4 apart along x, same rotation: half extent 3 along x, 1 across.
    let s = set(
        0,
        &[
            splat([-2.0, 0.0, 0.0], [1.0; 3], quat_z(0.0), 0.5, 0.0),
            splat([2.0, 0.0, 0.0], [1.0; 3], quat_z(0.0), 0.5, 0.0),
        ],
    );
    let m = merge_all(&s, MergeRule::Axis);
    assert_finite(&m);
    let sc = m.scales[0];
    assert!(
        (sc[0] - 3.0).abs() < 1e-5 && (sc[1] - 1.0).abs() < 1e-5,
        "{sc:?}"
    );
}

#[test]
fn huge_and_tiny_scales_mixed() {
    for rule in RULES {
        let s = set(
            1,
            &[
                splat([0.0; 3], [1e6, 1e-7, 1e-7], quat_z(30.0), 0.9, 0.1),
                splat(
                    [1e-6, 0.0, 0.0],
                    [1e-9, 1e-9, 1e-9],
                    quat_z(-60.0),
                    0.01,
                    0.2,
                ),
                splat([0.0, 1e3, 0.0], [1e-12, 5e5, 0.0], quat_z(90.0), 0.5, 0.3),
                splat([0.0; 3], [0.0; 3], [0.0, 0.0, 0.0, 1.0], 1.0, 0.4),
            ],
        );
        let m = merge_all(&s, rule);
        assert_finite(&m);
        assert!(
            m.scales[0].iter().any(|v| *v > 1e5),
            "{rule:?}: {:?}",
            m.scales[0]
        );
    }
}

#[test]
fn coincident_centres_collapse_and_stay_finite() {
    for rule in RULES {
        let items: Vec<Splat> = (0..500)
            .map(|k| {
                splat(
                    [5.0, 5.0, 5.0],
                    [0.01 * (1 + k % 7) as f32; 3],
                    quat_z(k as f64),
                    (k % 10) as f32 / 10.0,
                    k as f32 * 1e-3,
                )
            })
            .collect();
        let s = set(2, &items);
        let c = cluster(&s, 1e-3, rule);
        assert_finite(&c.splats);
        assert_eq!(c.splats.len(), 1, "all coincident: one cluster");
        assert_eq!(c.splats.positions[0], [5.0, 5.0, 5.0]);
        // A zero radius merges nothing.
        let c0 = cluster(&s, 0.0, rule);
        assert_eq!(c0.splats.len(), 500);
        assert_finite(&c0.splats);
    }
}

#[test]
fn budget_doubles_the_radius_until_it_fits() {
    let items: Vec<Splat> = (0..1000)
        .map(|k| {
            splat(
                [(k % 10) as f64, (k / 10 % 10) as f64, (k / 100) as f64],
                [0.2; 3],
                quat_z(0.0),
                0.5,
                0.0,
            )
        })
        .collect();
    let s = set(0, &items);
    let c = cluster_to_budget(&s, 0.1, 50, MergeRule::Moment);
    assert!(c.splats.len() <= 50, "{}", c.splats.len());
    assert!(c.radius >= 1.6, "radius grew by doubling: {}", c.radius);
    let k = (c.radius / 0.1).log2();
    assert!((k - k.round()).abs() < 1e-9, "a power of two times r: {k}");
    assert_finite(&c.splats);
    // Opacity: never below eq. 2's sum a^2 / sum a = 0.5 for equal opacities (clusters stacked
    // in depth may add coverage, up to their union's), never above 1.
    assert!(
        c.splats
            .opacities
            .iter()
            .all(|&a| (0.5 - 1e-6..=1.0).contains(&a))
    );
}

#[test]
fn a_tiled_surface_keeps_its_coverage() {
    // 16 splats of opacity 0.6 tiling a 4 x 4 patch (scale 0.5, spacing 0.5): together they
    // cover it almost opaquely; eq. 2 alone (sum a^2 / sum a = 0.6) would let the merged splat
    // show the background through it.
    for rule in RULES {
        let items: Vec<Splat> = (0..16)
            .map(|k| {
                splat(
                    [(k % 4) as f64 * 0.5, (k / 4) as f64 * 0.5, 0.0],
                    [0.5, 0.5, 0.01],
                    quat_z(0.0),
                    0.6,
                    0.0,
                )
            })
            .collect();
        let m = merge_all(&set(0, &items), rule);
        assert_finite(&m);
        assert!(m.opacities[0] > 0.9, "{rule:?}: alpha {}", m.opacities[0]);
        assert!(m.opacities[0] <= 1.0);
    }
}

/// Sum over the image of the red channel (light on a black background).
fn light(s: &Splats, cam: &splat2tiles_core::camera::Camera) -> f64 {
    let img = splat2tiles_render::render_splats(s, cam, &Default::default());
    let mut sum = 0.0;
    for y in 0..img.height {
        for x in 0..img.width {
            sum += img.get(x, y)[0] as f64;
        }
    }
    sum
}

#[test]
fn a_merged_splat_draws_as_much_light_as_its_sub_pixel_members_at_its_switching_distance() {
    // 100 splats of opacity 0.5 and scale 0.01 on a 10 x 10 grid of spacing 0.1 (a 1 m patch),
    // seen face-on from where one pixel spans 0.0625: each member is far below a pixel, so the
    // rasterizer's 0.3 px^2 low-pass widens it to about 0.57 px with its full opacity (1.6 px
    // apart, they hardly overlap). A merged splat that ignores this (opacity mass from the
    // members' own areas) keeps eq. 2's alpha 0.5 and draws about two thirds of their light;
    // modelling the low-pass at that pixel size (variance 0.3 px^2) matches them.
    let pixel = 0.0625;
    let items: Vec<Splat> = (0..100)
        .map(|k| {
            splat(
                [(k % 10) as f64 * 0.1, (k / 10) as f64 * 0.1, 0.0],
                [0.01, 0.01, 0.001],
                quat_z(0.0),
                0.5,
                // colour 1 in every channel: sh0 = 0.5 / SH_C0
                0.5 / splat2tiles_core::splat::sh::SH_C0,
            )
        })
        .collect();
    let s = set(0, &items);
    let (w, fov) = (96u32, 50.0f64);
    let focal = splat2tiles_core::camera::fov_to_focal(fov, w);
    let centre = DVec3::new(0.45, 0.45, 0.0);
    let cam = splat2tiles_core::camera::Camera::look_at(
        w,
        w,
        fov,
        centre + DVec3::Z * (pixel * focal),
        centre,
        DVec3::Y,
    );
    let leaves = light(&s, &cam);
    let members: Vec<usize> = (0..s.len()).collect();
    let merged = |dilation: f64| {
        let mut out = Splats::new(0);
        merge_drawn(&s, &members, MergeRule::Moment, dilation, &mut out);
        assert_finite(&out);
        light(&out, &cam)
    };
    let plain = merged(0.0);
    let drawn = merged(splat2tiles_render::raster::LOW_PASS * pixel * pixel);
    println!(
        "light: members {leaves:.1}, merged {drawn:.1}, merged ignoring the low-pass {plain:.1}"
    );
    assert!(
        (drawn / leaves - 1.0).abs() < 0.15,
        "modelled low-pass: {drawn} against the members' {leaves}"
    );
    assert!(
        plain / leaves < 0.75,
        "without the low-pass the merged splat is too faint: {plain} against {leaves}"
    );
}
