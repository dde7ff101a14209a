//! The renderer's output: an RGB f32 image (display-referred values, 1.0 = white), with 8-bit PNG
//! export (values clamped to [0, 1], no transfer function applied) and import.

use std::path::{Path, PathBuf};

/// Errors reading or writing images.
#[derive(Debug, thiserror::Error)]
pub enum ImageError {
    /// The PNG could not be decoded or encoded.
    #[error("{path}: {source}")]
    Png {
        /// File concerned.
        path: PathBuf,
        /// Underlying error.
        source: image::ImageError,
    },
    /// The PNG could not be written where it was asked for (the cause follows as the source).
    #[error("{path}: {what}")]
    Io {
        /// File concerned.
        path: PathBuf,
        /// What was being done.
        what: &'static str,
        /// Underlying error.
        source: std::io::Error,
    },
}

/// An RGB image of f32 values, row-major from the top-left pixel, channels interleaved.
#[derive(Debug, Clone, PartialEq)]
pub struct Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `width * height * 3` values.
    pub data: Vec<f32>,
}

impl Image {
    /// An image filled with one colour.
    pub fn filled(width: u32, height: u32, rgb: [f32; 3]) -> Self {
        let n = width as usize * height as usize;
        let mut data = Vec::with_capacity(n * 3);
        for _ in 0..n {
            data.extend_from_slice(&rgb);
        }
        Image {
            width,
            height,
            data,
        }
    }

    /// The colour of pixel `(x, y)`.
    pub fn get(&self, x: u32, y: u32) -> [f32; 3] {
        let i = (y as usize * self.width as usize + x as usize) * 3;
        [self.data[i], self.data[i + 1], self.data[i + 2]]
    }

    /// Quantises to 8 bits per channel: `round(255 * clamp(v, 0, 1))`, NaN as 0.
    pub fn to_rgb8(&self) -> Vec<u8> {
        self.data.iter().map(|&v| quantize(v)).collect()
    }

    /// An image from 8-bit RGB values (`v / 255`).
    pub fn from_rgb8(width: u32, height: u32, rgb: &[u8]) -> Self {
        assert_eq!(rgb.len(), width as usize * height as usize * 3, "RGB8 size");
        Image {
            width,
            height,
            data: rgb.iter().map(|&b| b as f32 / 255.0).collect(),
        }
    }

    /// The same image quantised to 8 bits and back, as it would be after a PNG round trip.
    pub fn quantized(&self) -> Self {
        Image::from_rgb8(self.width, self.height, &self.to_rgb8())
    }

    /// Writes an 8-bit RGB PNG: encoded in memory, written to a temporary file beside the
    /// destination (through a symbolic link, beside its target), synced, then renamed over it,
    /// so a failed write leaves no partial PNG and an earlier file untouched. An existing
    /// destination that is not a regular file (a device, a FIFO, a folder) is refused.
    pub fn save_png(&self, path: &Path) -> Result<(), ImageError> {
        use image::ImageEncoder as _;
        let mut png = Vec::new();
        image::codecs::png::PngEncoder::new(&mut png)
            .write_image(
                &self.to_rgb8(),
                self.width,
                self.height,
                image::ExtendedColorType::Rgb8,
            )
            .map_err(|source| ImageError::Png {
                path: path.to_owned(),
                source,
            })?;
        splat2tiles_io::write_whole(path, &png).map_err(|source| ImageError::Io {
            path: path.to_owned(),
            what: "writing",
            source,
        })
    }

    /// Reads a PNG (any colour type; alpha is dropped, 16-bit is reduced to 8).
    pub fn load_png(path: &Path) -> Result<Self, ImageError> {
        let img = image::open(path).map_err(|source| ImageError::Png {
            path: path.to_owned(),
            source,
        })?;
        let rgb = img.to_rgb8();
        Ok(Image::from_rgb8(rgb.width(), rgb.height(), rgb.as_raw()))
    }
}

/// One channel value to a byte: clamped to [0, 1], scaled by 255 and rounded; NaN gives 0.
pub fn quantize(v: f32) -> u8 {
    if v.is_nan() {
        return 0;
    }
    (v.clamp(0.0, 1.0) * 255.0).round() as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantize_clamps_and_rounds() {
        assert_eq!(quantize(-1.0), 0);
        assert_eq!(quantize(2.0), 255);
        assert_eq!(quantize(f32::NAN), 0);
        assert_eq!(quantize(0.5), 128);
        assert_eq!(quantize(f32::INFINITY), 255);
    }

    #[test]
    fn png_round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.png");
        let mut img = Image::filled(5, 3, [0.25, 0.5, 1.0]);
        img.data[0] = 0.0;
        img.save_png(&p).unwrap();
        let back = Image::load_png(&p).unwrap();
        assert_eq!(back, img.quantized());
        assert!(Image::load_png(&dir.path().join("missing.png")).is_err());
    }
}
