//! Generated inputs for the hostile tests: `.splat` files of any size, PLY headers, SPZ streams.

use std::io::Write;
use std::path::Path;

/// Writes `n` valid `.splat` records (a grid of small opaque splats) to `path`, streamed.
pub fn write_splat(path: &Path, n: usize) {
    let f = std::fs::File::create(path).unwrap();
    let mut w = std::io::BufWriter::with_capacity(1 << 20, f);
    let side = (n as f64).cbrt().ceil() as usize;
    for i in 0..n {
        let (x, y, z) = (i % side, (i / side) % side, i / (side * side));
        let mut rec = [0u8; 32];
        for (k, v) in [
            x as f32 * 0.1,
            y as f32 * 0.1,
            z as f32 * 0.1,
            0.02,
            0.02,
            0.02,
        ]
        .iter()
        .enumerate()
        {
            rec[k * 4..k * 4 + 4].copy_from_slice(&v.to_le_bytes());
        }
        rec[24..28].copy_from_slice(&[(i % 251) as u8, 128, 200, 255]);
        rec[28..32].copy_from_slice(&[255, 128, 128, 128]);
        w.write_all(&rec).unwrap();
    }
    w.flush().unwrap();
}

/// The 14 properties a trainer PLY needs.
pub const PROPS: [&str; 14] = [
    "x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity", "scale_0", "scale_1", "scale_2",
    "rot_0", "rot_1", "rot_2", "rot_3",
];

/// A binary little-endian PLY of `n` records of [`PROPS`], each from `rec(i)`.
pub fn ply(n: usize, rec: impl Fn(usize) -> [f32; 14]) -> Vec<u8> {
    let mut b = format!("ply\nformat binary_little_endian 1.0\nelement vertex {n}\n");
    for p in PROPS {
        b.push_str(&format!("property float {p}\n"));
    }
    b.push_str("end_header\n");
    let mut bytes = b.into_bytes();
    for i in 0..n {
        for v in rec(i) {
            bytes.extend_from_slice(&v.to_le_bytes());
        }
    }
    bytes
}

/// A plain record: position on a line, unit-ish scale, opaque, identity rotation.
pub fn record(i: usize) -> [f32; 14] {
    [
        i as f32 * 0.01,
        0.0,
        0.0,
        0.5,
        0.5,
        0.5,
        3.0,
        -4.0,
        -4.0,
        -4.0,
        1.0,
        0.0,
        0.0,
        0.0,
    ]
}

/// The 16-byte header of a legacy (v2) SPZ payload: `n` points of SH degree `degree`.
pub fn spz_v2_header(n: u32, degree: u8) -> Vec<u8> {
    let mut h = b"NGSP".to_vec();
    h.extend_from_slice(&2u32.to_le_bytes());
    h.extend_from_slice(&n.to_le_bytes());
    h.extend_from_slice(&[degree, 12, 0, 0]);
    h
}

/// Bytes of the v2 arrays for `n` points of SH degree `degree`.
pub fn spz_v2_data_len(n: u64, degree: u8) -> u64 {
    let sh = [0u64, 3, 8, 15][degree as usize] * 3;
    n * (9 + 1 + 3 + 3 + 3 + sh)
}

/// Writes `len` zero bytes through `w` in 1 MiB pieces.
pub fn write_zeros(w: &mut impl Write, mut len: u64) {
    let zeros = vec![0u8; 1 << 20];
    while len > 0 {
        let k = len.min(zeros.len() as u64) as usize;
        w.write_all(&zeros[..k]).unwrap();
        len -= k as u64;
    }
}
