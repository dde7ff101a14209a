//! Objects in a screenshot: connected foreground components and the colour inside a box, for
//! the tests that check a cut draws every object a full-detail view shows.

use splat2tiles_render::image::Image;
use std::path::Path;

/// A pixel box (x0, y0, x1, y1), inclusive.
pub type PixelBox = (u32, u32, u32, u32);

/// How far a pixel is from the background `bg` (largest channel difference), or 0 within
/// 12/255 of it (compression and dithering noise).
pub fn ink_against(img: &Image, x: u32, y: u32, bg: f32) -> f64 {
    let p = img.get(x, y);
    let d = p.iter().fold(0.0f32, |m, &v| m.max((v - bg).abs())) as f64;
    if d > 12.0 / 255.0 { d } else { 0.0 }
}

/// Connected (8-neighbour) pixels with `ink(x, y) > 0`, at least 3 of them: their boxes.
pub fn components(img: &Image, ink: impl Fn(u32, u32) -> f64) -> Vec<PixelBox> {
    let (w, h) = (img.width, img.height);
    let mut seen = vec![false; (w * h) as usize];
    let mut out = vec![];
    for start in 0..w * h {
        if seen[start as usize] || ink(start % w, start / w) == 0.0 {
            continue;
        }
        seen[start as usize] = true;
        let (mut stack, mut n) = (vec![start], 0);
        let (mut x0, mut y0, mut x1, mut y1) = (w, h, 0, 0);
        while let Some(i) = stack.pop() {
            let (x, y) = (i % w, i / w);
            n += 1;
            (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x), y1.max(y));
            for dy in -1i64..=1 {
                for dx in -1i64..=1 {
                    let (nx, ny) = (x as i64 + dx, y as i64 + dy);
                    if nx < 0 || ny < 0 || nx >= w as i64 || ny >= h as i64 {
                        continue;
                    }
                    let j = (ny as u32 * w + nx as u32) as usize;
                    if !seen[j] && ink(nx as u32, ny as u32) > 0.0 {
                        seen[j] = true;
                        stack.push(j as u32);
                    }
                }
            }
        }
        if n >= 3 {
            out.push((x0, y0, x1, y1));
        }
    }
    out
}

/// `ink` summed over `b` grown by 2 pixels (clamped to the image).
pub fn box_ink(img: &Image, b: &PixelBox, ink: impl Fn(u32, u32) -> f64) -> f64 {
    let mut s = 0.0;
    for y in b.1.saturating_sub(2)..=(b.3 + 2).min(img.height - 1) {
        for x in b.0.saturating_sub(2)..=(b.2 + 2).min(img.width - 1) {
            s += ink(x, y);
        }
    }
    s
}

/// The objects of `full` (components against background `bg`) that `cut` draws with less than
/// `share` of their ink in the same box; returns (objects, missing).
pub fn missing_objects(
    full: &Image,
    cut: &Image,
    bg: f32,
    share: f64,
) -> (Vec<PixelBox>, Vec<PixelBox>) {
    let objects = components(full, |x, y| ink_against(full, x, y, bg));
    let missing = objects
        .iter()
        .filter(|b| {
            box_ink(cut, b, |x, y| ink_against(cut, x, y, bg))
                < share * box_ink(full, b, |x, y| ink_against(full, x, y, bg))
        })
        .copied()
        .collect();
    (objects, missing)
}

/// Writes a flat sparse city as a PLY at `path`: 16 copies of the sample plant (every 16th
/// splat, 7-16 m wide) on a 200 m grid, z up. Distant objects of such a city are the ones
/// a cut once dropped.
pub fn write_flat_city(path: &Path) {
    use splat2tiles_lab::city::{CityLayout, generate_city};
    let source = super::plant_sample(16);
    let layout = CityLayout {
        splats: source.len() * 16,
        spacing: 200.0,
        block: 7.0,
        scale: (1.0, 2.3),
        ..CityLayout::default()
    };
    let city = generate_city(&[source], &layout);
    let f = std::fs::File::create(path).unwrap();
    splat2tiles_io::write_ply(&city, std::io::BufWriter::new(f)).unwrap();
}
