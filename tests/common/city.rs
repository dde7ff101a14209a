//! A generated `.splat` city for the sharded-conversion tests: blocks of different densities
//! and towers, so regions, units and parts split unevenly.

use super::Rng;
use std::io::Write;
use std::path::Path;

/// Writes `n` splats as a `.splat` city: 16 x 16 blocks of 50 m of growing density, a tower
/// every 7th block (regions and parts split unevenly).
pub fn write_city_splat(path: &Path, n: usize, seed: u64) {
    let f = std::fs::File::create(path).unwrap();
    let mut w = std::io::BufWriter::with_capacity(1 << 20, f);
    let mut r = Rng(seed);
    for i in 0..n {
        let block = ((i as u64).wrapping_mul(2654435761) % 256) as f64;
        let (bx, by) = ((block % 16.0) * 50.0, (block / 16.0).floor() * 50.0);
        let tall = if (block as u64).is_multiple_of(7) {
            60.0
        } else {
            8.0
        };
        let p = [
            (bx + r.range(0.0, 40.0)) as f32,
            (by + r.range(0.0, 40.0)) as f32,
            -(r.range(0.0, tall)) as f32,
        ];
        let s = r.range(0.02, 0.4) as f32;
        for v in p.iter().chain(&[s, s * 0.8, s * 0.5]) {
            w.write_all(&v.to_le_bytes()).unwrap();
        }
        let bytes: Vec<u8> = (0..8).map(|_| (r.f() * 255.0) as u8).collect();
        w.write_all(&bytes).unwrap();
    }
    w.flush().unwrap();
}
