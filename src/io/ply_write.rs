//! Trainer-layout PLY writer (binary little endian, 62 floats for SH degree 3): the inverse of
//! the reader's conversions (log scale, logit opacity, w,x,y,z quaternion, channel-major f_rest).

use std::io::{self, Write};

use crate::splat::{self, Splats};

/// Smallest scale written, so that `ln` stays finite (a zero scale reads back as about 1e-30).
const MIN_SCALE: f32 = 1e-30;
/// Splats encoded per `write_all`.
const CHUNK: usize = 4096;

/// Writes `splats` as a trainer PLY: properties `x y z nx ny nz f_dc_0..2 f_rest_* opacity
/// scale_0..2 rot_0..3`, all float, normals 0.
pub fn write_ply(splats: &Splats, mut w: impl Write) -> io::Result<()> {
    splats.check_lengths();
    let per = splats.rest_per_splat();
    let mut h = String::new();
    h += "ply\nformat binary_little_endian 1.0\n";
    h += &format!("element vertex {}\n", splats.len());
    for n in [
        "x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2",
    ] {
        h += &format!("property float {n}\n");
    }
    for k in 0..per * 3 {
        h += &format!("property float f_rest_{k}\n");
    }
    for n in [
        "opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3",
    ] {
        h += &format!("property float {n}\n");
    }
    h += "end_header\n";
    w.write_all(h.as_bytes())?;

    let floats = 17 + per * 3;
    let mut buf: Vec<u8> = Vec::with_capacity(CHUNK.min(splats.len().max(1)) * floats * 4);
    for start in (0..splats.len()).step_by(CHUNK) {
        buf.clear();
        for i in start..(start + CHUNK).min(splats.len()) {
            let mut put = |v: f32| buf.extend_from_slice(&v.to_le_bytes());
            let p = splats.positions[i];
            p.iter().for_each(|v| put(*v as f32));
            (0..3).for_each(|_| put(0.0));
            splats.sh0[i].iter().for_each(|v| put(*v));
            let rest = splats.rest_of(i);
            for c in 0..3 {
                rest.iter().for_each(|t| put(t[c]));
            }
            put(splat::logit(splats.opacities[i]));
            splats.scales[i]
                .iter()
                .for_each(|s| put(s.max(MIN_SCALE).ln()));
            let [x, y, z, qw] = splats.rotations[i];
            [qw, x, y, z].iter().for_each(|v| put(*v));
        }
        w.write_all(&buf)?;
    }
    w.flush()
}
