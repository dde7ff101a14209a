//! Image metrics: SSIM (Wang et al. 2004) computed exactly as scikit-image's
//! `structural_similarity(gaussian_weights=True, sigma=1.5, use_sample_covariance=False)`, and PSNR.
//!
//! SSIM details (scikit-image 0.26, checked against its output by `tests/render_metrics.rs`):
//! each RGB channel is filtered with a separable Gaussian (sigma 1.5, truncated at 3.5 sigma: an
//! 11-tap kernel normalised to sum 1) using scipy's `reflect` boundary (`d c b a | a b c d |
//! d c b a`); `ux, uy, uxx, uyy, uxy` are the filtered `x, y, x^2, y^2, x y`; variances are
//! population ones (`uxx - ux^2`); `C1 = (0.01 R)^2`, `C2 = (0.03 R)^2` with data range `R = 1`;
//! the SSIM map is averaged over the image with a 5-pixel border cropped away ('valid' region of
//! the 11x11 window), then the three channel means are averaged.

use super::image::Image;

/// Gaussian window sigma.
pub const SSIM_SIGMA: f64 = 1.5;
/// Window truncation in sigmas (scikit-image's value, giving 11 taps).
pub const SSIM_TRUNCATE: f64 = 3.5;
/// SSIM constant K1.
pub const SSIM_K1: f64 = 0.01;
/// SSIM constant K2.
pub const SSIM_K2: f64 = 0.03;

/// Why two images cannot be compared.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum MetricError {
    /// The images differ in size.
    #[error("image sizes differ: {a_width}x{a_height} vs {b_width}x{b_height}")]
    SizeMismatch {
        /// Width of the first image.
        a_width: u32,
        /// Height of the first image.
        a_height: u32,
        /// Width of the second image.
        b_width: u32,
        /// Height of the second image.
        b_height: u32,
    },
    /// SSIM's 11x11 window does not fit in the image.
    #[error("image {width}x{height} is smaller than the 11x11 SSIM window")]
    TooSmall {
        /// Width.
        width: u32,
        /// Height.
        height: u32,
    },
}

fn check_sizes(a: &Image, b: &Image) -> Result<(), MetricError> {
    if a.width != b.width || a.height != b.height {
        return Err(MetricError::SizeMismatch {
            a_width: a.width,
            a_height: a.height,
            b_width: b.width,
            b_height: b.height,
        });
    }
    Ok(())
}

/// The normalised 1D Gaussian kernel scipy's `gaussian_filter` uses (radius `int(3.5 s + 0.5)`).
fn kernel() -> Vec<f64> {
    let r = (SSIM_TRUNCATE * SSIM_SIGMA + 0.5) as i64;
    let w: Vec<f64> = (-r..=r)
        .map(|x| (-0.5 * (x * x) as f64 / (SSIM_SIGMA * SSIM_SIGMA)).exp())
        .collect();
    let s: f64 = w.iter().sum();
    w.into_iter().map(|v| v / s).collect()
}

/// scipy `reflect` mode index: `d c b a | a b c d | d c b a`.
fn reflect(i: i64, n: i64) -> usize {
    let m = i.rem_euclid(2 * n);
    (if m >= n { 2 * n - 1 - m } else { m }) as usize
}

/// Separable Gaussian filter of a `w x h` plane (rows of length `w`): axis 0 (down columns) first,
/// then axis 1 (along rows), as scipy does.
fn gaussian_filter(src: &[f64], w: usize, h: usize, k: &[f64]) -> Vec<f64> {
    let r = (k.len() / 2) as i64;
    let mut tmp = vec![0.0; w * h];
    for y in 0..h {
        for x in 0..w {
            let mut acc = 0.0;
            for (j, kv) in k.iter().enumerate() {
                let yy = reflect(y as i64 + j as i64 - r, h as i64);
                acc += kv * src[yy * w + x];
            }
            tmp[y * w + x] = acc;
        }
    }
    let mut out = vec![0.0; w * h];
    for y in 0..h {
        for x in 0..w {
            let mut acc = 0.0;
            for (j, kv) in k.iter().enumerate() {
                let xx = reflect(x as i64 + j as i64 - r, w as i64);
                acc += kv * tmp[y * w + xx];
            }
            out[y * w + x] = acc;
        }
    }
    out
}

/// Mean SSIM of two single-channel `w x h` planes with values in [0, 1] (data range 1).
pub fn ssim_plane(x: &[f64], y: &[f64], w: usize, h: usize) -> f64 {
    let k = kernel();
    let pad = k.len() / 2;
    let xx: Vec<f64> = x.iter().map(|v| v * v).collect();
    let yy: Vec<f64> = y.iter().map(|v| v * v).collect();
    let xy: Vec<f64> = x.iter().zip(y).map(|(a, b)| a * b).collect();
    let ux = gaussian_filter(x, w, h, &k);
    let uy = gaussian_filter(y, w, h, &k);
    let uxx = gaussian_filter(&xx, w, h, &k);
    let uyy = gaussian_filter(&yy, w, h, &k);
    let uxy = gaussian_filter(&xy, w, h, &k);
    let c1 = SSIM_K1 * SSIM_K1;
    let c2 = SSIM_K2 * SSIM_K2;
    let mut sum = 0.0;
    let mut count = 0usize;
    for row in pad..h - pad {
        for col in pad..w - pad {
            let i = row * w + col;
            let (mx, my) = (ux[i], uy[i]);
            let vx = uxx[i] - mx * mx;
            let vy = uyy[i] - my * my;
            let vxy = uxy[i] - mx * my;
            let a1 = 2.0 * mx * my + c1;
            let a2 = 2.0 * vxy + c2;
            let b1 = mx * mx + my * my + c1;
            let b2 = vx + vy + c2;
            sum += (a1 * a2) / (b1 * b2);
            count += 1;
        }
    }
    sum / count as f64
}

/// One channel of an image as f64.
fn channel(img: &Image, ch: usize) -> Vec<f64> {
    img.data
        .iter()
        .skip(ch)
        .step_by(3)
        .map(|&v| v as f64)
        .collect()
}

/// Mean SSIM over the three channels (see the module doc for the exact definition).
pub fn ssim(a: &Image, b: &Image) -> Result<f64, MetricError> {
    check_sizes(a, b)?;
    let win = 2 * (SSIM_TRUNCATE * SSIM_SIGMA + 0.5) as u32 + 1;
    if a.width < win || a.height < win {
        return Err(MetricError::TooSmall {
            width: a.width,
            height: a.height,
        });
    }
    let (w, h) = (a.width as usize, a.height as usize);
    let per: Vec<f64> = (0..3)
        .map(|ch| ssim_plane(&channel(a, ch), &channel(b, ch), w, h))
        .collect();
    Ok(per.iter().sum::<f64>() / 3.0)
}

/// Mean squared error over all pixels and channels.
pub fn mse(a: &Image, b: &Image) -> Result<f64, MetricError> {
    check_sizes(a, b)?;
    let n = a.data.len().max(1);
    let s: f64 = a
        .data
        .iter()
        .zip(&b.data)
        .map(|(&x, &y)| {
            let d = x as f64 - y as f64;
            d * d
        })
        .sum();
    Ok(s / n as f64)
}

/// PSNR in dB for data range 1: `10 log10(1 / MSE)`; infinite for identical images.
pub fn psnr(a: &Image, b: &Image) -> Result<f64, MetricError> {
    let m = mse(a, b)?;
    Ok(if m == 0.0 {
        f64::INFINITY
    } else {
        10.0 * (1.0 / m).log10()
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kernel_is_scipys() {
        let k = kernel();
        assert_eq!(k.len(), 11);
        assert!((k.iter().sum::<f64>() - 1.0).abs() < 1e-15);
        assert!(k[5] > k[4] && k[0] == k[10]);
    }

    #[test]
    fn reflect_matches_scipy_rule() {
        let n = 4;
        let got: Vec<usize> = (-5..9).map(|i| reflect(i, n)).collect();
        assert_eq!(got, vec![3, 3, 2, 1, 0, 0, 1, 2, 3, 3, 2, 1, 0, 0]);
    }

    #[test]
    fn identical_images() {
        let mut img = Image::filled(16, 12, [0.2, 0.4, 0.6]);
        img.data[40] = 0.9;
        assert!((ssim(&img, &img).unwrap() - 1.0).abs() < 1e-12);
        assert_eq!(psnr(&img, &img).unwrap(), f64::INFINITY);
        let other = Image::filled(16, 11, [0.0; 3]);
        assert!(matches!(
            ssim(&img, &other),
            Err(MetricError::SizeMismatch { .. })
        ));
        let small = Image::filled(10, 30, [0.0; 3]);
        assert!(matches!(
            ssim(&small, &small),
            Err(MetricError::TooSmall { .. })
        ));
    }
}
