//! Small dense linear algebra for merging Gaussians: a cyclic Jacobi eigen solver for symmetric
//! matrices, Markley's weighted quaternion average, and quaternion <-> rotation matrix in f64.
#![allow(clippy::needless_range_loop)] // dense small-matrix maths reads best indexed

use glam::{DMat3, DQuat, DVec3};

/// Eigen-decomposition of a symmetric `N x N` matrix (cyclic Jacobi rotations, f64).
///
/// Returns the eigenvalues in descending order and the matching unit eigenvectors as the columns
/// of the second value (`vectors[row][col]`). Only the upper triangle is trusted; non-finite
/// input yields the identity decomposition of a zero matrix rather than NaN.
pub fn symmetric_eigen<const N: usize>(m: [[f64; N]; N]) -> ([f64; N], [[f64; N]; N]) {
    let mut a = m;
    for i in 0..N {
        for j in 0..i {
            a[i][j] = a[j][i];
        }
    }
    let mut v = [[0.0; N]; N];
    for (i, row) in v.iter_mut().enumerate() {
        row[i] = 1.0;
    }
    if a.iter().flatten().any(|x| !x.is_finite()) {
        return ([0.0; N], v);
    }
    let scale = a.iter().flatten().fold(0.0f64, |s, x| s.max(x.abs()));
    if scale > 0.0 {
        for _sweep in 0..64 {
            let off: f64 = (0..N)
                .flat_map(|i| (i + 1..N).map(move |j| (i, j)))
                .map(|(i, j)| a[i][j] * a[i][j])
                .sum();
            if off <= (1e-30 * scale * scale).max(f64::MIN_POSITIVE) {
                break;
            }
            for p in 0..N {
                for q in p + 1..N {
                    let apq = a[p][q];
                    if apq.abs() <= f64::MIN_POSITIVE {
                        continue;
                    }
                    let theta = (a[q][q] - a[p][p]) / (2.0 * apq);
                    let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
                    let t = if theta == 0.0 { 1.0 } else { t };
                    let c = 1.0 / (t * t + 1.0).sqrt();
                    let s = t * c;
                    for k in 0..N {
                        let akp = a[k][p];
                        let akq = a[k][q];
                        a[k][p] = c * akp - s * akq;
                        a[k][q] = s * akp + c * akq;
                    }
                    for k in 0..N {
                        let apk = a[p][k];
                        let aqk = a[q][k];
                        a[p][k] = c * apk - s * aqk;
                        a[q][k] = s * apk + c * aqk;
                    }
                    for row in v.iter_mut() {
                        let vp = row[p];
                        let vq = row[q];
                        row[p] = c * vp - s * vq;
                        row[q] = s * vp + c * vq;
                    }
                }
            }
        }
    }
    // Sort descending by eigenvalue (stable: ties keep column order, so the result is
    // deterministic).
    let mut order: [usize; N] = std::array::from_fn(|i| i);
    order.sort_by(|&x, &y| a[y][y].total_cmp(&a[x][x]));
    let values = order.map(|k| a[k][k]);
    let mut vectors = [[0.0; N]; N];
    for (col, &k) in order.iter().enumerate() {
        for row in 0..N {
            vectors[row][col] = v[row][k];
        }
    }
    (values, vectors)
}

/// Markley's weighted quaternion average: the unit eigenvector of `sum w q q^T` with the largest
/// eigenvalue. Sign-invariant (`q` and `-q` count as the same rotation); the result is put in the
/// hemisphere of the heaviest input. Quaternions are `[x, y, z, w]`; weights must be >= 0 (all
/// zero or non-finite weights fall back to equal weights); empty input gives the identity.
pub fn markley_average(quats: &[[f64; 4]], weights: &[f64]) -> [f64; 4] {
    debug_assert_eq!(quats.len(), weights.len());
    if quats.is_empty() {
        return [0.0, 0.0, 0.0, 1.0];
    }
    let total: f64 = weights.iter().sum();
    let uniform = !(total.is_finite() && total > 0.0);
    let mut m = [[0.0f64; 4]; 4];
    let mut heaviest = (0, f64::MIN);
    for (k, (q, &w)) in quats.iter().zip(weights).enumerate() {
        let w = if uniform { 1.0 } else { w.max(0.0) };
        let n = q.iter().map(|c| c * c).sum::<f64>().sqrt();
        if !(n.is_finite() && n > 0.0) {
            continue;
        }
        let q = q.map(|c| c / n);
        if w > heaviest.1 {
            heaviest = (k, w);
        }
        for i in 0..4 {
            for j in i..4 {
                m[i][j] += w * q[i] * q[j];
            }
        }
    }
    let (_, vecs) = symmetric_eigen(m);
    let mut out = [vecs[0][0], vecs[1][0], vecs[2][0], vecs[3][0]];
    let n = out.iter().map(|c| c * c).sum::<f64>().sqrt();
    if !(n.is_finite() && n > 0.0) {
        return [0.0, 0.0, 0.0, 1.0];
    }
    out = out.map(|c| c / n);
    let h = quats[heaviest.0];
    if out.iter().zip(h).map(|(a, b)| a * b).sum::<f64>() < 0.0 {
        out = out.map(|c| -c);
    }
    out
}

/// Rotation matrix of a unit quaternion `[x, y, z, w]` (normalised here; zero -> identity).
pub fn quat_to_mat(q: [f32; 4]) -> DMat3 {
    let q = DQuat::from_xyzw(q[0] as f64, q[1] as f64, q[2] as f64, q[3] as f64);
    let n = q.length();
    if !(n.is_finite() && n > 0.0) {
        return DMat3::IDENTITY;
    }
    DMat3::from_quat(q / n)
}

/// Unit quaternion `[x, y, z, w]` of a rotation matrix (columns orthonormal, det +1).
pub fn mat_to_quat(m: DMat3) -> [f64; 4] {
    let q = DQuat::from_mat3(&m).normalize();
    if q.is_finite() {
        [q.x, q.y, q.z, q.w]
    } else {
        [0.0, 0.0, 0.0, 1.0]
    }
}

/// Covariance `R diag(s^2) R^T` of a Gaussian with linear scales `s` and rotation `q`.
pub fn covariance(scale: [f32; 3], q: [f32; 4]) -> DMat3 {
    let r = quat_to_mat(q);
    let s = DVec3::new(scale[0] as f64, scale[1] as f64, scale[2] as f64);
    r * DMat3::from_diagonal(s * s) * r.transpose()
}

/// Rotation (columns = principal axes, det +1) and linear scales of a covariance matrix.
/// Negative eigenvalues (round-off) are clamped to zero.
pub fn decompose_covariance(c: DMat3) -> (DMat3, DVec3) {
    let a = [
        [c.x_axis.x, c.y_axis.x, c.z_axis.x],
        [c.x_axis.y, c.y_axis.y, c.z_axis.y],
        [c.x_axis.z, c.y_axis.z, c.z_axis.z],
    ];
    let (vals, vecs) = symmetric_eigen(a);
    let col = |k: usize| DVec3::new(vecs[0][k], vecs[1][k], vecs[2][k]);
    let (x, y) = (col(0), col(1));
    // Build a right-handed frame: the third axis is the cross product (same line as col(2)).
    let z = x.cross(y);
    let r = DMat3::from_cols(x, y, z);
    let s = DVec3::new(vals[0], vals[1], vals[2]).max(DVec3::ZERO);
    (r, DVec3::new(s.x.sqrt(), s.y.sqrt(), s.z.sqrt()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn jacobi_diagonalises_a_known_matrix() {
        let (vals, vecs) = symmetric_eigen([[2.0, 1.0, 0.0], [1.0, 2.0, 0.0], [0.0, 0.0, 5.0]]);
        assert!((vals[0] - 5.0).abs() < 1e-12);
        assert!((vals[1] - 3.0).abs() < 1e-12);
        assert!((vals[2] - 1.0).abs() < 1e-12);
        let v1 = DVec3::new(vecs[0][1], vecs[1][1], vecs[2][1]);
        assert!((v1.dot(DVec3::new(1.0, 1.0, 0.0).normalize()).abs() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn jacobi_rejects_non_finite() {
        let (vals, _) = symmetric_eigen([[f64::NAN, 0.0], [0.0, 1.0]]);
        assert!(vals.iter().all(|v| v.is_finite()));
    }

    #[test]
    fn covariance_round_trip() {
        let q = splat2tiles_core::splat::normalize_quat([0.3, -0.2, 0.5, 0.8]);
        let c = covariance([0.5, 2.0, 0.1], q);
        let (r, s) = decompose_covariance(c);
        let back = r * DMat3::from_diagonal(s * s) * r.transpose();
        assert!((back - c).to_cols_array().iter().all(|d| d.abs() < 1e-9));
        assert!((r.determinant() - 1.0).abs() < 1e-9);
        assert!((s.x - 2.0).abs() < 1e-7 && (s.z - 0.1).abs() < 1e-7);
    }
}
