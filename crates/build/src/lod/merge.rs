//! One cluster of Gaussians -> one representative Gaussian (TileSplat eq. 2): opacity-weighted
//! means of centre and SH, alpha* = sum(a^2)/sum(a) raised to keep the members' coverage, and a
//! shape by moment matching or axis cover.
#![allow(clippy::needless_range_loop)] // dense small-matrix maths reads best indexed

use super::math::{covariance, decompose_covariance, markley_average, mat_to_quat, quat_to_mat};
use glam::{DMat3, DVec3};
use splat2tiles_core::splat::{Splat, Splats};

/// How the shape (rotation + scales) of a merged Gaussian is chosen.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum MergeRule {
    /// Covariance moment matching: Sigma* = sum w (Sigma_i + d_i d_i^T) / sum w, eigen-decomposed
    /// into rotation and scales.
    #[default]
    Moment,
    /// TileSplat's cover: rotation = Markley's weighted quaternion average; per axis of that frame,
    /// half the extent of the member centres +/- their standard deviations along the axis.
    Axis,
}

splat2tiles_core::named!(MergeRule {
    Moment => ("moment", "Covariance moment matching: Sigma* = sum w (Sigma_i + d_i d_i^T) / sum w, eigen-decomposed into rotation and scales."),
    Axis => ("axis", "TileSplat's cover: rotation = Markley's weighted quaternion average; per axis of that frame, half the extent of the member centres +/- their standard deviations along the axis."),
});

impl MergeRule {
    /// The option value (`moment` or `axis`).
    pub fn as_str(self) -> &'static str {
        match self {
            MergeRule::Moment => "moment",
            MergeRule::Axis => "axis",
        }
    }
}

/// Weights of the members: their opacities, or equal weights when those sum to (almost) zero.
fn weights(splats: &Splats, members: &[usize]) -> Vec<f64> {
    let w: Vec<f64> = members
        .iter()
        .map(|&i| {
            let a = splats.opacities[i] as f64;
            if a.is_finite() { a.max(0.0) } else { 0.0 }
        })
        .collect();
    let total: f64 = w.iter().sum();
    if total > 1e-12 {
        w
    } else {
        vec![1.0; members.len()]
    }
}

/// Merges the splats `members` of `splats` into one splat, appended to `out` (same SH degree).
/// Returns the opacity-weighted mean distance of the members' centres from the merged centre.
///
/// Opacity: eq. 2's `sum(a^2)/sum(a)`, raised to the members' opacity mass (`a` times the
/// product of the two largest scales, summed) over the merged splat's, but never above the
/// coverage of the members' union `1 - prod(1 - a)`: a tiled surface stays opaque from afar.
/// (Its area here is undilated; [`merge_drawn`] models a viewer's low-pass filter.)
///
/// A single member is copied exactly. Never produces NaN from finite input: zero total opacity
/// falls back to equal weights, degenerate covariances to zero scales along the flat axes.
pub fn merge_into(splats: &Splats, members: &[usize], rule: MergeRule, out: &mut Splats) -> f64 {
    merge_drawn(splats, members, rule, 0.0, out)
}

/// Footprint area (product of the two largest standard deviations) of a splat with `scales`
/// once `dilation` (a variance) is added to every axis: what a rasterizer's low-pass filter
/// makes of it.
fn drawn_area(scales: [f64; 3], dilation: f64) -> f64 {
    let mut v = scales.map(|x| if x.is_finite() { x.abs() } else { 0.0 });
    v.sort_by(|a, b| b.total_cmp(a));
    if dilation > 0.0 {
        ((v[0] * v[0] + dilation) * (v[1] * v[1] + dilation)).sqrt()
    } else {
        v[0] * v[1]
    }
}

/// [`merge_into`] for a merged splat first drawn from where a viewer's pixel low-pass filter
/// adds `dilation` (a world-space variance) to every member's footprint.
pub fn merge_drawn(
    splats: &Splats,
    members: &[usize],
    rule: MergeRule,
    dilation: f64,
    out: &mut Splats,
) -> f64 {
    let dilation = if dilation.is_finite() {
        dilation.max(0.0)
    } else {
        0.0
    };
    assert!(!members.is_empty(), "empty cluster");
    if members.len() == 1 {
        out.push_from(splats, members[0]);
        return 0.0;
    }
    let w = weights(splats, members);
    let wsum: f64 = w.iter().sum();
    let pos = |i: usize| DVec3::from_array(splats.positions[i]);
    // Centre relative to the first member, so large coordinates keep their precision.
    let origin = pos(members[0]);
    let mean_rel = members
        .iter()
        .zip(&w)
        .map(|(&i, &wi)| (pos(i) - origin) * wi)
        .sum::<DVec3>()
        / wsum;
    let mu = origin + mean_rel;

    let mut sh0 = [0.0f64; 3];
    let k = splats.rest_per_splat();
    let mut rest = vec![[0.0f64; 3]; k];
    let mut a2 = 0.0;
    let mut a1 = 0.0;
    for (&i, &wi) in members.iter().zip(&w) {
        for c in 0..3 {
            sh0[c] += wi * splats.sh0[i][c] as f64;
        }
        for (acc, r) in rest.iter_mut().zip(splats.rest_of(i)) {
            for c in 0..3 {
                acc[c] += wi * r[c] as f64;
            }
        }
        let a = (splats.opacities[i] as f64).clamp(0.0, 1.0);
        a2 += a * a;
        a1 += a;
    }
    let alpha = if a1 > 1e-12 {
        a2 / a1
    } else {
        a1 / members.len() as f64
    };

    let (rot, scale) = match rule {
        MergeRule::Moment => {
            let mut cov = DMat3::ZERO;
            for (&i, &wi) in members.iter().zip(&w) {
                let d = pos(i) - mu;
                let outer = DMat3::from_cols(d * d.x, d * d.y, d * d.z);
                cov += (covariance(splats.scales[i], splats.rotations[i]) + outer) * wi;
            }
            let (r, s) = decompose_covariance(cov * (1.0 / wsum));
            (mat_to_quat(r), s)
        }
        MergeRule::Axis => {
            let quats: Vec<[f64; 4]> = members
                .iter()
                .map(|&i| splats.rotations[i].map(|c| c as f64))
                .collect();
            let q = markley_average(&quats, &w);
            let r = quat_to_mat(q.map(|c| c as f32));
            let axes = [r.x_axis, r.y_axis, r.z_axis];
            let mut lo = DVec3::splat(f64::INFINITY);
            let mut hi = DVec3::splat(f64::NEG_INFINITY);
            for &i in members {
                let cov = covariance(splats.scales[i], splats.rotations[i]);
                let d = pos(i) - mu;
                for (a, e) in axes.iter().enumerate() {
                    let centre = d.dot(*e);
                    let sd = e.dot(cov * *e).max(0.0).sqrt();
                    lo[a] = lo[a].min(centre - sd);
                    hi[a] = hi[a].max(centre + sd);
                }
            }
            (q, (hi - lo) * 0.5)
        }
    };
    let finite_or = |v: f64, f: f64| if v.is_finite() { v } else { f };
    // Coverage: the merged splat's opacity mass (alpha x its two largest scales' product, each
    // widened by the viewer's low-pass `dilation`) matches the members' total, never above their
    // union's coverage nor below eq. 2's alpha.
    let area = |s: [f64; 3]| drawn_area(s, dilation);
    let merged_area = area([scale.x, scale.y, scale.z]);
    let mut mass = 0.0;
    let mut clear = 1.0;
    for &i in members {
        let a = (splats.opacities[i] as f64).clamp(0.0, 1.0);
        mass += a * area(splats.scales[i].map(|x| x as f64));
        clear *= 1.0 - a;
    }
    let alpha = if merged_area > 0.0 && mass.is_finite() {
        (mass / merged_area).min(1.0 - clear).max(alpha)
    } else {
        alpha
    };
    out.push(
        Splat {
            position: mu.to_array(),
            scale: [0, 1, 2].map(|a| finite_or(scale[a], 0.0) as f32),
            rotation: rot.map(|c| c as f32),
            opacity: finite_or(alpha, 0.0).clamp(0.0, 1.0) as f32,
            sh0: sh0.map(|v| finite_or(v / wsum, 0.0) as f32),
        },
        &rest
            .iter()
            .map(|r| r.map(|v| finite_or(v / wsum, 0.0) as f32))
            .collect::<Vec<_>>(),
    );
    members
        .iter()
        .zip(&w)
        .map(|(&i, &wi)| wi * pos(i).distance(mu))
        .sum::<f64>()
        / wsum
}

/// Merges a whole set into one splat (convenience for tests and tools).
pub fn merge_all(splats: &Splats, rule: MergeRule) -> Splats {
    let members: Vec<usize> = (0..splats.len()).collect();
    let mut out = Splats::with_capacity(splats.sh_degree, 1);
    merge_into(splats, &members, rule, &mut out);
    out
}
