//! Metrics over the object instead of the whole frame: PSNR over the pixels where the reference
//! render differs from the background, and SSIM on a crop framing them.
//!
//! An object that covers a small part of the frame leaves most pixels equal to the background in
//! both renders, so whole-frame PSNR and SSIM saturate (57 dB and 0.9997 for codecs whose
//! differences are plain on the object). The mask is taken from the reference only, so both
//! images of a comparison are scored on the same pixels: a codec that paints the background is
//! still charged for it inside the crop, and a codec that loses the object's edge is charged on
//! every masked pixel.

use crate::image::{Image, quantize};
use crate::metrics::{MetricError, ssim};

/// Pixels of the SSIM window's half-width: the crop reaches this far past the masked pixels, so
/// every masked pixel is the centre of a window that the crop holds whole.
const WINDOW_RADIUS: u32 = 5;

/// The object's pixels of a reference render.
#[derive(Debug, Clone, PartialEq)]
pub struct ObjectMask {
    /// Width of the image in pixels.
    pub width: u32,
    /// Height of the image in pixels.
    pub height: u32,
    /// Per pixel, row-major: whether it differs from the background.
    pub pixels: Vec<bool>,
    /// Number of masked pixels.
    pub count: usize,
    /// Smallest box holding every masked pixel: `[x0, y0, x1, y1)` (None when none is).
    pub bounds: Option<[u32; 4]>,
}

/// The pixels of `reference` whose 8-bit value differs from the 8-bit `background` in any channel
/// (the background as a PNG stores it).
pub fn object_mask(reference: &Image, background: [f32; 3]) -> ObjectMask {
    let bg = background.map(quantize);
    let (w, h) = (reference.width, reference.height);
    let mut pixels = Vec::with_capacity(w as usize * h as usize);
    let mut bounds: Option<[u32; 4]> = None;
    for (i, px) in reference.data.chunks_exact(3).enumerate() {
        let on = px.iter().zip(bg).any(|(&v, b)| quantize(v) != b);
        pixels.push(on);
        if on {
            let (x, y) = ((i % w as usize) as u32, (i / w as usize) as u32);
            let b = bounds.get_or_insert([x, y, x + 1, y + 1]);
            b[0] = b[0].min(x);
            b[1] = b[1].min(y);
            b[2] = b[2].max(x + 1);
            b[3] = b[3].max(y + 1);
        }
    }
    let count = pixels.iter().filter(|&&p| p).count();
    ObjectMask {
        width: w,
        height: h,
        pixels,
        count,
        bounds,
    }
}

/// PSNR in dB (data range 1) over the masked pixels' channels: infinite when they are equal,
/// None when the mask is empty.
pub fn masked_psnr(a: &Image, b: &Image, mask: &ObjectMask) -> Result<Option<f64>, MetricError> {
    check(a, b, mask)?;
    if mask.count == 0 {
        return Ok(None);
    }
    let mut sum = 0.0f64;
    for (i, _) in mask.pixels.iter().enumerate().filter(|(_, on)| **on) {
        for ch in 0..3 {
            let d = a.data[i * 3 + ch] as f64 - b.data[i * 3 + ch] as f64;
            sum += d * d;
        }
    }
    let mse = sum / (mask.count * 3) as f64;
    Ok(Some(if mse == 0.0 {
        f64::INFINITY
    } else {
        10.0 * (1.0 / mse).log10()
    }))
}

/// The crop that frames the object: the mask's bounds grown by the SSIM window's half-width on
/// every side, then to at least the window's size, within the image. `[x0, y0, x1, y1)`; None
/// when the mask is empty or the image is smaller than the window.
pub fn object_crop(mask: &ObjectMask) -> Option<[u32; 4]> {
    let [x0, y0, x1, y1] = mask.bounds?;
    let win = 2 * WINDOW_RADIUS + 1;
    if mask.width < win || mask.height < win {
        return None;
    }
    let grow = |lo: u32, hi: u32, size: u32| -> (u32, u32) {
        let mut lo = lo.saturating_sub(WINDOW_RADIUS);
        let mut hi = (hi + WINDOW_RADIUS).min(size);
        while hi - lo < win {
            if lo > 0 {
                lo -= 1;
            } else {
                hi += 1;
            }
        }
        (lo, hi)
    };
    let (x0, x1) = grow(x0, x1, mask.width);
    let (y0, y1) = grow(y0, y1, mask.height);
    Some([x0, y0, x1, y1])
}

/// The part `[x0, y0, x1, y1)` of `img` (the box must lie inside it).
pub fn crop(img: &Image, [x0, y0, x1, y1]: [u32; 4]) -> Image {
    let mut data = Vec::with_capacity((x1 - x0) as usize * (y1 - y0) as usize * 3);
    for y in y0..y1 {
        let row = (y as usize * img.width as usize) * 3;
        data.extend_from_slice(&img.data[row + x0 as usize * 3..row + x1 as usize * 3]);
    }
    Image {
        width: x1 - x0,
        height: y1 - y0,
        data,
    }
}

/// SSIM of `a` and `b` on the crop that frames the object (`object_crop`); None when there is
/// no object.
pub fn object_ssim(a: &Image, b: &Image, mask: &ObjectMask) -> Result<Option<f64>, MetricError> {
    check(a, b, mask)?;
    let Some(c) = object_crop(mask) else {
        return Ok(None);
    };
    ssim(&crop(a, c), &crop(b, c)).map(Some)
}

/// Both images and the mask are the same size.
fn check(a: &Image, b: &Image, mask: &ObjectMask) -> Result<(), MetricError> {
    for (w, h) in [(b.width, b.height), (mask.width, mask.height)] {
        if (a.width, a.height) != (w, h) {
            return Err(MetricError::SizeMismatch {
                a_width: a.width,
                a_height: a.height,
                b_width: w,
                b_height: h,
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::metrics::psnr;

    const GREY: [f32; 3] = [0.5, 0.5, 0.5];

    /// A grey 200x100 frame with a `size`-pixel square of `rgb` at (120, 40).
    fn frame(size: u32, rgb: [f32; 3]) -> Image {
        let mut img = Image::filled(200, 100, GREY);
        for y in 40..40 + size {
            for x in 120..120 + size {
                let i = (y as usize * 200 + x as usize) * 3;
                img.data[i..i + 3].copy_from_slice(&rgb);
            }
        }
        img
    }

    #[test]
    fn the_mask_is_where_the_reference_leaves_the_background() {
        let m = object_mask(&frame(10, [0.9, 0.2, 0.1]), GREY);
        assert_eq!(m.count, 100);
        assert_eq!(m.bounds, Some([120, 40, 130, 50]));
        assert_eq!(object_crop(&m), Some([115, 35, 135, 55]));
        // Below one 8-bit step of the background is background.
        let faint = object_mask(&frame(10, [0.5 + 0.4 / 255.0; 3]), GREY);
        assert_eq!(
            (faint.count, faint.bounds, object_crop(&faint)),
            (0, None, None)
        );
    }

    #[test]
    fn object_metrics_see_what_the_whole_frame_hides() {
        let reference = frame(10, [0.9, 0.2, 0.1]);
        let coded = frame(10, [0.8, 0.3, 0.1]);
        let m = object_mask(&reference, GREY);
        let whole = psnr(&reference, &coded).unwrap();
        let object = masked_psnr(&reference, &coded, &m).unwrap().unwrap();
        // 1/200 of the pixels differ: the whole frame's MSE is 200 times smaller, +23 dB.
        assert!((whole - object - 10.0 * 200f64.log10()).abs() < 1e-9);
        assert!(
            (object - 10.0 * (3.0f64 / 0.02).log10()).abs() < 1e-3,
            "{object}"
        );
        let whole_ssim = ssim(&reference, &coded).unwrap();
        let on_object = object_ssim(&reference, &coded, &m).unwrap().unwrap();
        assert!(
            on_object < whole_ssim && on_object < 0.99,
            "{on_object} vs {whole_ssim}"
        );
        // Equal images: infinite PSNR, SSIM 1.
        assert_eq!(
            masked_psnr(&reference, &reference, &m).unwrap(),
            Some(f64::INFINITY)
        );
        assert_eq!(object_ssim(&reference, &reference, &m).unwrap(), Some(1.0));
    }

    #[test]
    fn a_missing_object_and_edges_and_sizes_are_handled() {
        let reference = frame(10, [0.9, 0.2, 0.1]);
        let m = object_mask(&reference, GREY);
        // A codec that lost the object: finite, low.
        let empty = Image::filled(200, 100, GREY);
        let p = masked_psnr(&reference, &empty, &m).unwrap().unwrap();
        assert!(p.is_finite() && p < 10.0, "{p}");
        // No object: None, not NaN.
        let none = object_mask(&empty, GREY);
        assert_eq!(masked_psnr(&empty, &empty, &none).unwrap(), None);
        assert_eq!(object_ssim(&empty, &empty, &none).unwrap(), None);
        // A single pixel in a corner: the crop is the window's size, inside the image.
        let mut corner = Image::filled(200, 100, GREY);
        corner.data[..3].copy_from_slice(&[1.0, 1.0, 1.0]);
        let c = object_crop(&object_mask(&corner, GREY)).unwrap();
        assert_eq!(c, [0, 0, 11, 11]);
        let mut far = Image::filled(200, 100, GREY);
        let last = far.data.len() - 3;
        far.data[last..].copy_from_slice(&[1.0, 1.0, 1.0]);
        assert_eq!(
            object_crop(&object_mask(&far, GREY)).unwrap(),
            [189, 89, 200, 100]
        );
        // Sizes must agree.
        assert!(masked_psnr(&reference, &Image::filled(20, 10, GREY), &m).is_err());
        assert!(object_ssim(&Image::filled(20, 10, GREY), &reference, &m).is_err());
    }
}
