//! TEST-ONLY reader for antimatter15 `.splat` files (32 B/splat), used by the render tests and
//! benches until `splat2tiles::io` lands; not a production reader (no locators, no validation).

use splat2tiles::splat::{Splat, Splats, sh};

/// Path of the shared plant scene (113,648 splats).
pub const PLANT: &str = "/work/shared/scenes/plant.splat";

/// Decodes `.splat` bytes: pos f32x3, linear scale f32x3, RGBA u8, quaternion u8x4 (w,x,y,z).
pub fn parse_splat(bytes: &[u8]) -> Splats {
    assert_eq!(bytes.len() % 32, 0, ".splat size is not a multiple of 32");
    let n = bytes.len() / 32;
    let mut s = Splats::with_capacity(0, n);
    let f = |b: &[u8], k: usize| f32::from_le_bytes(b[4 * k..4 * k + 4].try_into().unwrap());
    for rec in bytes.chunks_exact(32) {
        let rgba = &rec[24..28];
        let q = &rec[28..32];
        let qf = |b: u8| (b as f32 - 128.0) / 128.0;
        let rot = splat2tiles::splat::normalize_quat([qf(q[1]), qf(q[2]), qf(q[3]), qf(q[0])]);
        s.push(
            Splat {
                position: [f(rec, 0) as f64, f(rec, 1) as f64, f(rec, 2) as f64],
                scale: [f(rec, 3), f(rec, 4), f(rec, 5)],
                rotation: rot,
                opacity: rgba[3] as f32 / 255.0,
                sh0: sh::color_to_sh0([
                    rgba[0] as f32 / 255.0,
                    rgba[1] as f32 / 255.0,
                    rgba[2] as f32 / 255.0,
                ]),
            },
            &[],
        );
    }
    s
}

/// Reads a `.splat` file.
pub fn read_splat(path: &str) -> Splats {
    parse_splat(&std::fs::read(path).unwrap_or_else(|e| panic!("{path}: {e}")))
}
