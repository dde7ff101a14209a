//! SPZ v2 rotation bytes chosen for the splat's shape: among the 27 byte triples around the
//! rounded `x, y, z`, the one whose decoded quaternion gives the covariance nearest the splat's.

use splat2tiles_core::splat::normalize_quat;
use splat2tiles_io::spz::v2_rotation;

/// How the SPZ v2 writer picks a splat's three rotation bytes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum RotationFit {
    /// Each of `x, y, z` rounded to the nearest byte (the SPZ library's writer).
    Nearest,
    /// The byte triple within one step of the rounded one whose decoded rotation (the reader
    /// derives `w = sqrt(1 - |xyz|^2)`) gives the covariance `R S^2 R^T` nearest the splat's
    /// (Frobenius norm); the rounded triple on ties and for round splats.
    #[default]
    Covariance,
}

/// How far the covariance of `d` (a decoded rotation) is from the splat's, to first order: the
/// vector part `v` of `conj(q) d` is half the rotation between them in the splat's own frame,
/// and turning by `2 v_k` about its axis `k` changes `R S^2 R^T` by `2 v_k (s_i^2 - s_j^2)` in
/// the two entries `ij` and `ji` (Frobenius norm). `weight[k]` holds `(s_i^2 - s_j^2)^2`.
fn shape_error(q: [f32; 4], d: [f32; 4], weight: [f32; 3]) -> f32 {
    let (w, dw) = (q[3], d[3]);
    // conj(q) = (-x, -y, -z, w); the product's vector part is w d - dw q - q x d.
    let v = [
        w * d[0] - dw * q[0] - (q[1] * d[2] - q[2] * d[1]),
        w * d[1] - dw * q[1] - (q[2] * d[0] - q[0] * d[2]),
        w * d[2] - dw * q[2] - (q[0] * d[1] - q[1] * d[0]),
    ];
    weight[0] * v[0] * v[0] + weight[1] * v[1] * v[1] + weight[2] * v[2] * v[2]
}

/// Largest over smallest scale below which a splat counts as round: its rotation barely shows,
/// so the rounded bytes are kept without a search.
const ROUND: f32 = 1.01;

/// A triple replaces the best so far only below this fraction of its error.
const TIE: f32 = 0.999;

/// The three SPZ v2 rotation bytes of the rotation `q` (x, y, z, w; any norm) of a splat with
/// linear `scale`.
pub fn rotation_bytes(q: [f32; 4], scale: [f32; 3], fit: RotationFit) -> [u8; 3] {
    let mut q = normalize_quat(q);
    if q[3] < 0.0 {
        q = q.map(|v| -v);
    }
    let nearest = [0, 1, 2].map(|k| (q[k] * 127.5 + 127.5).round().clamp(0.0, 255.0) as i32);
    let as_bytes = |b: [i32; 3]| b.map(|v| v as u8);
    let s = scale.map(f32::abs);
    let (lo, hi) = (s[0].min(s[1]).min(s[2]), s[0].max(s[1]).max(s[2]));
    // Without a finite shape there is nothing to fit; past this test `hi > 0`.
    if fit == RotationFit::Nearest || s.iter().any(|v| !v.is_finite()) || hi <= lo * ROUND {
        return as_bytes(nearest);
    }
    // Squared scales relative to the largest: the error compares shapes, whatever the size.
    let d = s.map(|v| (v / hi) * (v / hi));
    let weight = [
        (d[1] - d[2]) * (d[1] - d[2]),
        (d[0] - d[2]) * (d[0] - d[2]),
        (d[0] - d[1]) * (d[0] - d[1]),
    ];
    // The rounded triple as a reader takes it; the others only where |xyz| <= 1, so every
    // reader derives the same unit quaternion from them.
    let rounded = shape_error(q, v2_rotation(as_bytes(nearest)), weight);
    if rounded == 0.0 {
        return as_bytes(nearest);
    }
    // The vector part of conj(q) c is `M c - c_w q_xyz` with `M c = w c - q_xyz x c`, linear in
    // the components of c: tabled per axis and step (-1, 0, +1), with their squares.
    let (w, v) = (q[3], [q[0], q[1], q[2]]);
    let mut part = [[[0f32; 3]; 3]; 3];
    let mut sq = [[f32::INFINITY; 3]; 3];
    for k in 0..3 {
        for (j, step) in (-1..=1).enumerate() {
            let b = nearest[k] + step;
            if !(0..=255).contains(&b) {
                continue;
            }
            let c = b as f32 / 127.5 - 1.0;
            let mut e = [0f32; 3];
            e[k] = c;
            // w e - v x e
            part[k][j] = [
                w * e[0] - (v[1] * e[2] - v[2] * e[1]),
                w * e[1] - (v[2] * e[0] - v[0] * e[2]),
                w * e[2] - (v[0] * e[1] - v[1] * e[0]),
            ];
            sq[k][j] = c * c;
        }
    }
    // Index 9 i + 3 j + k of the best triple so far; 13 is the rounded one.
    let mut arg = 13;
    let mut least = rounded * TIE;
    for i in 0..3 {
        let (ni, pi) = (sq[0][i], part[0][i]);
        for j in 0..3 {
            let nij = ni + sq[1][j];
            let pij = [
                pi[0] + part[1][j][0],
                pi[1] + part[1][j][1],
                pi[2] + part[1][j][2],
            ];
            for k in 0..3 {
                let n2 = nij + sq[2][k];
                // Out of range (infinite) or |xyz| > 1: not a candidate.
                if n2 > 1.0 {
                    continue;
                }
                let cw = (1.0 - n2).sqrt();
                let c = part[2][k];
                let p0 = pij[0] + c[0] - cw * v[0];
                let p1 = pij[1] + c[1] - cw * v[1];
                let p2 = pij[2] + c[2] - cw * v[2];
                let e = weight[0] * p0 * p0 + weight[1] * p1 * p1 + weight[2] * p2 * p2;
                // Ties (within rounding) keep the rounded triple, so round-trips stay exact.
                if e < least {
                    least = e * TIE;
                    arg = 9 * i + 3 * j + k;
                }
            }
        }
    }
    let off = [arg / 9, arg / 3 % 3, arg % 3].map(|o| o as i32 - 1);
    as_bytes([0, 1, 2].map(|a| nearest[a] + off[a]))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn decode(b: [u8; 3]) -> [f64; 4] {
        v2_rotation(b).map(f64::from)
    }

    /// Upper triangle (xx, yy, zz, xy, xz, yz) of `R diag(s2) R^T` for the unit quaternion `q`.
    fn covariance(q: [f64; 4], s2: [f64; 3]) -> [f64; 6] {
        let [x, y, z, w] = q;
        let r = [
            [
                1.0 - 2.0 * (y * y + z * z),
                2.0 * (x * y - w * z),
                2.0 * (x * z + w * y),
            ],
            [
                2.0 * (x * y + w * z),
                1.0 - 2.0 * (x * x + z * z),
                2.0 * (y * z - w * x),
            ],
            [
                2.0 * (x * z - w * y),
                2.0 * (y * z + w * x),
                1.0 - 2.0 * (x * x + y * y),
            ],
        ];
        let e = |i: usize, j: usize| (0..3).map(|k| r[i][k] * s2[k] * r[j][k]).sum::<f64>();
        [e(0, 0), e(1, 1), e(2, 2), e(0, 1), e(0, 2), e(1, 2)]
    }

    /// Squared Frobenius distance of two covariances given as upper triangles.
    fn distance2(a: &[f64; 6], b: &[f64; 6]) -> f64 {
        let d = |k: usize| a[k] - b[k];
        d(0) * d(0) + d(1) * d(1) + d(2) * d(2) + 2.0 * (d(3) * d(3) + d(4) * d(4) + d(5) * d(5))
    }

    fn err(q: [f32; 4], s: [f32; 3], b: [u8; 3]) -> f64 {
        let q = normalize_quat(q).map(f64::from);
        let q = if q[3] < 0.0 { q.map(|v| -v) } else { q };
        let hi = s.iter().fold(0f32, |m, v| m.max(*v)) as f64;
        let s2 = s.map(|v| (v as f64 / hi).powi(2));
        distance2(&covariance(decode(b), s2), &covariance(q, s2))
    }

    #[test]
    fn never_worse_than_rounding_and_better_near_w_zero() {
        // Near w = 0 rounding x, y, z moves w the most: the search must find a closer shape.
        let mut gained = 0;
        let mut n = 0;
        for i in 0..400 {
            let t = i as f32 * 0.0157;
            let q = [
                t.cos() * 0.7,
                t.sin() * 0.7,
                0.7 * (t * 3.0).sin(),
                0.01 + 0.002 * i as f32,
            ];
            let s = [0.1, 0.01, 0.002];
            let near = rotation_bytes(q, s, RotationFit::Nearest);
            let fit = rotation_bytes(q, s, RotationFit::Covariance);
            let (en, ef) = (err(q, s, near), err(q, s, fit));
            assert!(ef <= en + 1e-12, "{q:?}: {ef} > {en}");
            gained += (ef < 0.5 * en) as usize;
            n += 1;
        }
        assert!(gained * 4 > n, "only {gained} of {n} improved twofold");
    }

    #[test]
    fn the_first_order_error_matches_the_covariance_distance() {
        // Turning by 2 v_k about axis k moves two off-diagonal entries by 2 v_k (s_i^2 - s_j^2)
        // each: the exact squared distance is 8 times the weighted sum, to first order.
        let s = [1.0f32, 0.3, 0.05];
        let d = s.map(|v| (v * v) as f64);
        let weight = [
            (d[1] - d[2]).powi(2),
            (d[0] - d[2]).powi(2),
            (d[0] - d[1]).powi(2),
        ];
        let weight = weight.map(|v| v as f32);
        for i in 0..50 {
            let t = i as f32 * 0.37;
            let q = normalize_quat([t.sin(), 0.4 * t.cos(), 0.3, 0.8]);
            let tiny = [0.004 * t.cos(), -0.003 * (2.0 * t).sin(), 0.002, 0.0];
            let p = normalize_quat([q[0] + tiny[0], q[1] + tiny[1], q[2] + tiny[2], q[3]]);
            let exact = distance2(
                &covariance(p.map(f64::from), d),
                &covariance(q.map(f64::from), d),
            );
            let approx = 8.0 * shape_error(q, p, weight) as f64;
            assert!(exact > 0.0 && approx.is_finite());
            assert!(
                (approx - exact).abs() <= 0.05 * exact,
                "{i}: {approx} vs {exact}"
            );
        }
    }

    #[test]
    fn round_and_degenerate_splats_keep_the_rounded_bytes() {
        let q = [0.3, -0.2, 0.5, 0.78];
        let near = rotation_bytes(q, [1.0; 3], RotationFit::Nearest);
        for s in [
            [1.0; 3],
            [0.0; 3],
            [f32::NAN, 1.0, 1.0],
            [f32::INFINITY, 1.0, 0.5],
        ] {
            assert_eq!(rotation_bytes(q, s, RotationFit::Covariance), near, "{s:?}");
        }
        // Zero and non-finite quaternions read as the identity.
        for q in [[0.0; 4], [f32::NAN; 4]] {
            assert_eq!(
                rotation_bytes(q, [1.0, 0.1, 0.01], RotationFit::Covariance),
                [128, 128, 128]
            );
        }
    }

    #[test]
    fn decoded_triples_stay_within_unit_length() {
        // A rotation by 180 degrees about a diagonal: w = 0 and |xyz| = 1.
        let q = [0.57735, 0.57735, 0.57735, 0.0];
        let b = rotation_bytes(q, [1.0, 0.05, 0.01], RotationFit::Covariance);
        let d = decode(b);
        let n = d.iter().map(|v| v * v).sum::<f64>();
        assert!((n - 1.0).abs() < 1e-6, "{d:?}");
    }
}
