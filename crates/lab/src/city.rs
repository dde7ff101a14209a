//! Generated city scenes for tests and benchmarks: displaced, rotated and scaled copies of real
//! scenes (brought to z up) on a jittered grid of blocks, deterministic for a given seed.

use glam::{DMat3, DQuat, DVec3};
use splat2tiles_core::frame::UpAxis;
use splat2tiles_core::splat::Splats;
use splat2tiles_io::{InputFormat, Locator, PlyEncoding, Scene, read_path};
use std::path::Path;

/// Layout of a generated city.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CityLayout {
    /// Splats in the city (the last copy is cut short to reach it exactly).
    pub splats: usize,
    /// Distance between neighbouring blocks (scene units, metres).
    pub spacing: f64,
    /// Horizontal size a copy is scaled to before its own random factor (metres).
    pub block: f64,
    /// Seed of the placement, rotation and scale of every copy.
    pub seed: u64,
    /// Random shift of a copy from its grid point, as a fraction of `spacing` (each axis).
    pub jitter: f64,
    /// A copy's size is `block` times a uniform factor in `[scale.0, scale.1)`.
    pub scale: (f64, f64),
    /// Turn copies only by multiples of 90 degrees (footprints stay axis-aligned squares, so
    /// `spacing - block * scale.1` is a street between them).
    pub quarter_turns: bool,
}

impl Default for CityLayout {
    fn default() -> Self {
        CityLayout {
            splats: 1_000_000,
            spacing: 30.0,
            block: 16.0,
            seed: 15,
            jitter: 0.25,
            scale: (0.6, 1.6),
            quarter_turns: false,
        }
    }
}

/// A splitmix64 step: the deterministic random numbers of the layout.
fn next(state: &mut u64) -> u64 {
    *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// A uniform number in `[0, 1)`.
fn unit(state: &mut u64) -> f64 {
    (next(state) >> 11) as f64 / (1u64 << 53) as f64
}

/// Brings a scene stored with `up` as its up axis to z up, its ground (2nd percentile of height)
/// at z = 0, its horizontal median at the origin, and its horizontal size (2nd-98th percentile
/// span) to 1. Rotations follow; SH beyond degree 0 is kept as is.
pub fn normalise_source(splats: &Splats, up: UpAxis) -> Splats {
    let m = up.to_z_up();
    let pts: Vec<DVec3> = splats
        .positions
        .iter()
        .map(|p| m * DVec3::from_array(*p))
        .collect();
    let pct = |axis: usize, q: f64| -> f64 {
        let mut v: Vec<f64> = pts.iter().map(|p| p[axis]).collect();
        if v.is_empty() {
            return 0.0;
        }
        let i = ((v.len() - 1) as f64 * q).round() as usize;
        let (_, x, _) = v.select_nth_unstable_by(i, |a, b| a.total_cmp(b));
        *x
    };
    let centre = DVec3::new(pct(0, 0.5), pct(1, 0.5), pct(2, 0.02));
    let span = (pct(0, 0.98) - pct(0, 0.02)).max(pct(1, 0.98) - pct(1, 0.02));
    let k = if span > 0.0 && span.is_finite() {
        1.0 / span
    } else {
        1.0
    };
    transform(splats, &pts, DMat3::IDENTITY, centre, k, DVec3::ZERO, m)
}

/// `out = rot * (p - centre) * k + offset` for positions already rotated into `pts`; scales times
/// `k`; rotations pre-multiplied by `frame_rot` (the rotation that produced `pts`) then `rot`.
fn transform(
    s: &Splats,
    pts: &[DVec3],
    rot: DMat3,
    centre: DVec3,
    k: f64,
    offset: DVec3,
    frame_rot: DMat3,
) -> Splats {
    let q = DQuat::from_mat3(&(rot * frame_rot)).normalize();
    let mut out = s.clone();
    for (i, p) in pts.iter().enumerate() {
        out.positions[i] = (rot * ((*p - centre) * k) + offset).to_array();
        out.scales[i] = s.scales[i].map(|v| (v as f64 * k) as f32);
        let r = s.rotations[i];
        let qi = DQuat::from_xyzw(r[0] as f64, r[1] as f64, r[2] as f64, r[3] as f64);
        let n = (q * qi).normalize();
        out.rotations[i] = [n.x as f32, n.y as f32, n.z as f32, n.w as f32];
    }
    out
}

/// Copies per row of the grid [`generate_city`] lays out for `sources` (0 without splats).
pub fn grid_side(sources: &[Splats], layout: &CityLayout) -> usize {
    let sizes: usize = sources.iter().map(|s| s.len()).sum();
    if sizes == 0 {
        return 0;
    }
    let mean = sizes as f64 / sources.len() as f64;
    let copies = (layout.splats as f64 / mean).ceil().max(1.0) as usize;
    (copies as f64).sqrt().ceil() as usize
}

/// A city of `layout.splats` splats: copies of the normalised `sources` (see
/// [`normalise_source`]) taken in turn, each turned by a random heading (a random multiple of 90
/// degrees with `quarter_turns`), scaled to `block * [scale.0, scale.1)` and placed on a square
/// grid of `spacing` (copy `c` at `(c % side, c / side)`, `side = ceil(sqrt(copies))`) with a
/// jitter of `jitter * spacing`.
/// All sources must share one SH degree; returns an empty set without sources.
pub fn generate_city(sources: &[Splats], layout: &CityLayout) -> Splats {
    let sh = sources.first().map(|s| s.sh_degree).unwrap_or(0);
    let mut out = Splats::with_capacity(sh, layout.splats);
    let sizes: usize = sources.iter().map(|s| s.len()).sum();
    if sizes == 0 || sources.iter().any(|s| s.sh_degree != sh) {
        return out;
    }
    let side = grid_side(sources, layout);
    let mut state = layout.seed;
    let mut c = 0usize;
    while out.len() < layout.splats {
        let src = &sources[c % sources.len()];
        let (gx, gy) = ((c % side) as f64, (c / side) as f64);
        let jitter = layout.spacing * layout.jitter;
        let offset = DVec3::new(
            gx * layout.spacing + (unit(&mut state) - 0.5) * 2.0 * jitter,
            gy * layout.spacing + (unit(&mut state) - 0.5) * 2.0 * jitter,
            0.0,
        );
        let turn = unit(&mut state);
        let heading = if layout.quarter_turns {
            (turn * 4.0).floor() * std::f64::consts::FRAC_PI_2
        } else {
            turn * std::f64::consts::TAU
        };
        let (s0, s1) = layout.scale;
        let k = layout.block * (s0 + (s1 - s0) * unit(&mut state));
        let pts: Vec<DVec3> = src
            .positions
            .iter()
            .map(|p| DVec3::from_array(*p))
            .collect();
        let copy = transform(
            src,
            &pts,
            DMat3::from_rotation_z(heading),
            DVec3::ZERO,
            k,
            offset,
            DMat3::IDENTITY,
        );
        let take = (layout.splats - out.len()).min(copy.len());
        for i in 0..take {
            out.push_from(&copy, i);
        }
        c += 1;
    }
    out
}

/// The three shared scenes of `scenes_dir` (`plant.splat`, `donut_fused_sh0.ply`, `biker.spz`;
/// `data/scenes/README.md`), each normalised with its format's usual up axis.
pub fn shared_sources(scenes_dir: &Path) -> anyhow::Result<Vec<Splats>> {
    ["plant.splat", "donut_fused_sh0.ply", "biker.spz"]
        .iter()
        .map(|name| {
            let path = scenes_dir.join(name);
            let scene = read_path(&path).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
            let up: UpAxis = scene
                .format
                .default_up_axis()
                .parse()
                .unwrap_or(UpAxis::NegY);
            Ok(normalise_source(&scene.splats, up))
        })
        .collect()
}

/// A generated city as a scene for `convert_scene` (z up: convert it with `--up-axis +z`).
pub fn city_scene(splats: Splats) -> Scene {
    Scene {
        splats,
        format: InputFormat::Ply {
            encoding: PlyEncoding::BinaryLittleEndian,
        },
        locator: Locator::Index,
        repaired_rotations: 0,
        overflowed_scales: 0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use splat2tiles_core::splat::Splat;

    fn source() -> Splats {
        let mut s = Splats::new(0);
        for i in 0..100 {
            s.push(
                Splat {
                    // y-down scene: height along -y.
                    position: [(i % 10) as f64, -((i / 50) as f64), (i / 10) as f64],
                    scale: [0.1, 0.2, 0.3],
                    rotation: [0.0, 0.0, 0.0, 1.0],
                    opacity: 0.5,
                    sh0: [0.1, 0.2, 0.3],
                },
                &[],
            );
        }
        s
    }

    #[test]
    fn city_has_the_requested_size_and_is_deterministic() {
        let src = normalise_source(&source(), UpAxis::NegY);
        let z: Vec<f64> = src.positions.iter().map(|p| p[2]).collect();
        assert!(z.iter().all(|&v| (-1e-9..=1.0).contains(&v)), "{z:?}");
        let layout = CityLayout {
            splats: 1234,
            ..CityLayout::default()
        };
        let a = generate_city(std::slice::from_ref(&src), &layout);
        let b = generate_city(std::slice::from_ref(&src), &layout);
        assert_eq!(a.len(), 1234);
        assert_eq!(a, b);
        let (lo, hi) = a.bounds().unwrap();
        assert!(hi[0] - lo[0] > layout.spacing, "copies spread over blocks");
        let other = generate_city(&[src], &CityLayout { seed: 16, ..layout });
        assert_ne!(a.positions, other.positions);
        for q in &a.rotations {
            let n: f32 = q.iter().map(|c| c * c).sum();
            assert!((n - 1.0).abs() < 1e-4);
        }
    }
}
