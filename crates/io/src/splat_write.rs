//! antimatter15 `.splat` writer, the inverse of the reader: 32-byte records of f32 position, f32
//! linear scale, RGBA8 colour (SH0 as display colour, opacity as alpha), u8 quaternion w,x,y,z.

use std::io::{self, Write};

use splat2tiles_core::splat::{Splats, sh::SH_C0};

/// Appends `splats` as `.splat` records (the format has no header, so any number of calls
/// concatenate); higher SH coefficients are not representable and are dropped.
pub fn write_splat_records(splats: &Splats, w: &mut impl Write) -> io::Result<()> {
    splats.check_lengths();
    const CHUNK: usize = 8192;
    let mut buf: Vec<u8> = Vec::with_capacity(CHUNK.min(splats.len().max(1)) * 32);
    let byte = |v: f32| (v * 255.0).round().clamp(0.0, 255.0) as u8;
    let quat = |v: f32| (v * 128.0 + 128.0).round().clamp(0.0, 255.0) as u8;
    for start in (0..splats.len()).step_by(CHUNK) {
        buf.clear();
        for i in start..(start + CHUNK).min(splats.len()) {
            for v in splats.positions[i] {
                buf.extend_from_slice(&(v as f32).to_le_bytes());
            }
            for v in splats.scales[i] {
                buf.extend_from_slice(&v.to_le_bytes());
            }
            for c in splats.sh0[i] {
                buf.push(byte(c * SH_C0 + 0.5));
            }
            buf.push(byte(splats.opacities[i]));
            let [x, y, z, qw] = splats.rotations[i];
            buf.extend([quat(qw), quat(x), quat(y), quat(z)]);
        }
        w.write_all(&buf)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use splat2tiles_core::splat::Splat;

    #[test]
    fn records_read_back_within_the_format_precision() {
        let mut s = Splats::new(0);
        for i in 0..100 {
            let t = i as f32 / 100.0;
            let q = splat2tiles_core::splat::normalize_quat([t - 0.5, 0.3, -0.2, 0.9]);
            s.push(
                Splat {
                    position: [i as f64 * 0.5, -3.25, 1e3 + t as f64],
                    scale: [0.01 + t, 0.2, 1.5],
                    rotation: q,
                    opacity: t,
                    sh0: [(t - 0.5) * 2.0, 0.1, -0.7],
                },
                &[],
            );
        }
        let mut bytes = Vec::new();
        write_splat_records(&s, &mut bytes).unwrap();
        assert_eq!(bytes.len(), 100 * 32);
        let back = crate::read_bytes("t.splat", &bytes).unwrap().splats;
        assert_eq!(back.len(), 100);
        for i in 0..100 {
            for a in 0..3 {
                assert!((back.positions[i][a] - s.positions[i][a]).abs() < 1e-3);
                assert_eq!(back.scales[i][a], s.scales[i][a]);
                assert!((back.sh0[i][a] - s.sh0[i][a]).abs() < 1.0 / 255.0 / SH_C0);
            }
            assert!((back.opacities[i] - s.opacities[i]).abs() <= 0.5 / 255.0 + 1e-6);
            let dot: f32 = (0..4)
                .map(|k| back.rotations[i][k] * s.rotations[i][k])
                .sum();
            assert!(dot.abs() > 0.99, "rotation {i}: dot {dot}");
        }
    }
}
