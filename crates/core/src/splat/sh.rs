//! Real spherical harmonics as 3DGS and KHR_gaussian_splatting use them (Condon-Shortley phase,
//! coefficients by degree then m ascending): constants, evaluation and the DC colour fallback.

/// Y_0^0 normalisation: colour = SH_C0 * sh0 + 0.5.
pub const SH_C0: f32 = 0.282_094_8;
/// Degree-1 constant.
pub const SH_C1: f32 = 0.488_602_52;
/// Degree-2 constants, m = -2..2.
pub const SH_C2: [f32; 5] = [
    1.092_548_5,
    -1.092_548_5,
    0.315_391_57,
    -1.092_548_5,
    0.546_274_2,
];
/// Degree-3 constants, m = -3..3.
pub const SH_C3: [f32; 7] = [
    -0.590_043_6,
    2.890_611_4,
    -0.457_045_8,
    0.373_176_33,
    -0.457_045_8,
    1.445_305_7,
    -0.590_043_6,
];

/// Basis values for a unit direction `d`, up to `degree`, in glTF coefficient order; index 0 is
/// the DC term. Returns how many entries of `out` were written ((degree+1)^2).
pub fn basis(degree: u8, d: [f32; 3], out: &mut [f32; 16]) -> usize {
    let [x, y, z] = d;
    out[0] = SH_C0;
    if degree == 0 {
        return 1;
    }
    out[1] = -SH_C1 * y;
    out[2] = SH_C1 * z;
    out[3] = -SH_C1 * x;
    if degree == 1 {
        return 4;
    }
    let (xx, yy, zz) = (x * x, y * y, z * z);
    let (xy, yz, xz) = (x * y, y * z, x * z);
    out[4] = SH_C2[0] * xy;
    out[5] = SH_C2[1] * yz;
    out[6] = SH_C2[2] * (2.0 * zz - xx - yy);
    out[7] = SH_C2[3] * xz;
    out[8] = SH_C2[4] * (xx - yy);
    if degree == 2 {
        return 9;
    }
    out[9] = SH_C3[0] * y * (3.0 * xx - yy);
    out[10] = SH_C3[1] * xy * z;
    out[11] = SH_C3[2] * y * (4.0 * zz - xx - yy);
    out[12] = SH_C3[3] * z * (2.0 * zz - 3.0 * xx - 3.0 * yy);
    out[13] = SH_C3[4] * x * (4.0 * zz - xx - yy);
    out[14] = SH_C3[5] * z * (xx - yy);
    out[15] = SH_C3[6] * x * (xx - 3.0 * yy);
    16
}

/// View-dependent colour of one splat: `sh0` and `rest` (glTF order) evaluated for the unit
/// direction `d` from the camera to the splat, plus 0.5, negatives clamped to 0 (not above 1).
pub fn eval_color(degree: u8, sh0: [f32; 3], rest: &[[f32; 3]], d: [f32; 3]) -> [f32; 3] {
    let mut b = [0f32; 16];
    let n = basis(degree, d, &mut b);
    let mut c = [b[0] * sh0[0], b[0] * sh0[1], b[0] * sh0[2]];
    for (k, coef) in rest.iter().take(n - 1).enumerate() {
        for ch in 0..3 {
            c[ch] += b[k + 1] * coef[ch];
        }
    }
    c.map(|v| (v + 0.5).max(0.0))
}

/// The view-independent (DC) colour clamped to [0, 1]: the `COLOR_0` fallback before any
/// transfer function.
pub fn dc_color(sh0: [f32; 3]) -> [f32; 3] {
    sh0.map(|v| (SH_C0 * v + 0.5).clamp(0.0, 1.0))
}

/// The SH DC coefficient that gives a colour in [0, 1] (inverse of the DC part of `dc_color`).
pub fn color_to_sh0(c: [f32; 3]) -> [f32; 3] {
    c.map(|v| (v - 0.5) / SH_C0)
}

/// sRGB transfer function (display-encoded -> linear), for the `COLOR_0` fallback.
pub fn srgb_to_linear(v: f32) -> f32 {
    if v <= 0.04045 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dc_only_is_view_independent() {
        let a = eval_color(0, [1.0, -1.0, 0.0], &[], [0.0, 0.0, 1.0]);
        let b = eval_color(0, [1.0, -1.0, 0.0], &[], [1.0, 0.0, 0.0]);
        assert_eq!(a, b);
        assert!((a[0] - (SH_C0 + 0.5)).abs() < 1e-6);
        assert_eq!(a[2], 0.5);
    }

    #[test]
    fn degree1_hand_values() {
        // Only the m=0 (z) coefficient of the red channel set: colour varies with d.z.
        let rest = [[0.0; 3], [1.0, 0.0, 0.0], [0.0; 3]];
        let up = eval_color(1, [0.0; 3], &rest, [0.0, 0.0, 1.0]);
        let side = eval_color(1, [0.0; 3], &rest, [1.0, 0.0, 0.0]);
        assert!((up[0] - (0.5 + SH_C1)).abs() < 1e-6);
        assert!((side[0] - 0.5).abs() < 1e-6);
        // m=-1 carries -C1*y (Condon-Shortley phase).
        let rest = [[1.0, 0.0, 0.0], [0.0; 3], [0.0; 3]];
        let c = eval_color(1, [0.0; 3], &rest, [0.0, 1.0, 0.0]);
        assert!((c[0] - (0.5 - SH_C1)).abs() < 1e-6);
    }

    #[test]
    #[allow(clippy::needless_range_loop)] // a Gram matrix reads best with indices
    fn basis_is_orthonormal_numerically() {
        // Monte-Carlo-free check: integrate products over a Fibonacci sphere.
        let n = 20000;
        let mut gram = [[0f64; 16]; 16];
        for i in 0..n {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let r = (1.0 - z * z).sqrt();
            let phi = i as f64 * std::f64::consts::PI * (3.0 - 5f64.sqrt());
            let d = [(r * phi.cos()) as f32, (r * phi.sin()) as f32, z as f32];
            let mut b = [0f32; 16];
            basis(3, d, &mut b);
            for (row, ba) in gram.iter_mut().zip(b) {
                for (g, bc) in row.iter_mut().zip(b) {
                    *g += ba as f64 * bc as f64;
                }
            }
        }
        let w = 4.0 * std::f64::consts::PI / n as f64;
        for (a, row) in gram.iter().enumerate() {
            for (c, g) in row.iter().enumerate() {
                let v = g * w;
                let want = if a == c { 1.0 } else { 0.0 };
                assert!((v - want).abs() < 2e-3, "gram[{a}][{c}] = {v}");
            }
        }
    }
}
