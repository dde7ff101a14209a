//! antimatter15 `.splat` reader: 32-byte records of f32 position, f32 linear scale, RGBA8 colour
//! and a u8 quaternion in w,x,y,z order ((b - 128) / 128); no header, no higher SH.

use rayon::prelude::*;

use super::error::{Ctx, ReadError, ReadErrorKind};
use super::{InputFormat, Locator, Scene};
use splat2tiles_core::splat::{self, Splats, sh::SH_C0};

/// One decoded record: position, scale, rotation, opacity, sh0, whether the rotation was repaired.
type Decoded = ([f64; 3], [f32; 3], [f32; 4], f32, [f32; 3], bool);

/// Bytes per splat.
const RECORD: usize = 32;

#[inline(always)]
fn f32_at(r: &[u8], off: usize) -> f32 {
    f32::from_le_bytes([r[off], r[off + 1], r[off + 2], r[off + 3]])
}

/// Checks the splat count a `.splat` file of `total` bytes implies against the memory limit.
pub(crate) fn check_declared(cx: &Ctx, total: u64) -> Result<(), ReadError> {
    cx.check_memory(0, total / RECORD as u64, 0, total)
}

/// Bytes per `.splat` record.
pub(crate) const RECORD_BYTES: usize = RECORD;

/// Decodes whole 32-byte records (a trailing partial record is ignored); returns the splats and
/// how many quaternions were zero and became the identity.
pub(crate) fn decode_chunk(bytes: &[u8]) -> (Splats, usize) {
    let n = bytes.len() / RECORD;
    let decoded: Vec<Decoded> = bytes[..n * RECORD]
        .par_chunks(RECORD)
        .map(|r| {
            let pos = [
                f32_at(r, 0) as f64,
                f32_at(r, 4) as f64,
                f32_at(r, 8) as f64,
            ];
            let scale = [f32_at(r, 12), f32_at(r, 16), f32_at(r, 20)];
            let dc = |c: u8| (c as f32 / 255.0 - 0.5) / SH_C0;
            let sh0 = [dc(r[24]), dc(r[25]), dc(r[26])];
            let opacity = r[27] as f32 / 255.0;
            let q = |b: u8| (b as f32 - 128.0) / 128.0;
            let raw = [q(r[29]), q(r[30]), q(r[31]), q(r[28])];
            let repaired = raw.iter().all(|v| *v == 0.0);
            (
                pos,
                scale,
                splat::normalize_quat(raw),
                opacity,
                sh0,
                repaired,
            )
        })
        .collect();
    let mut s = Splats::with_capacity(0, n);
    let mut repaired = 0;
    for (p, sc, r, o, d, fixed) in decoded {
        s.positions.push(p);
        s.scales.push(sc);
        s.rotations.push(r);
        s.opacities.push(o);
        s.sh0.push(d);
        repaired += fixed as usize;
    }
    (s, repaired)
}

/// Appends to `out` the centres of the records that start every `step` bytes of `bytes` (`step`
/// at least 32): the positions [`decode_chunk`] gives, the other fields undecoded.
pub(crate) fn decode_positions(bytes: &[u8], step: usize, out: &mut Vec<[f64; 3]>) {
    out.par_extend(
        bytes
            .par_chunks_exact(step.max(RECORD))
            .with_min_len(4096)
            .map(|r| {
                [
                    f32_at(r, 0) as f64,
                    f32_at(r, 4) as f64,
                    f32_at(r, 8) as f64,
                ]
            }),
    );
}

/// Reads a `.splat` body (its length must be a multiple of 32).
pub(crate) fn read(cx: &Ctx, bytes: &[u8]) -> Result<Scene, ReadError> {
    let whole = bytes.len() / RECORD * RECORD;
    if whole != bytes.len() {
        return Err(cx.at(
            whole as u64,
            ReadErrorKind::Truncated {
                what: format!(
                    "a .splat file is 32-byte records; {} bytes end in a partial record",
                    bytes.len()
                ),
                unit: "bytes",
                expected: (whole + RECORD) as u64,
                actual: bytes.len() as u64,
            },
        ));
    }
    check_declared(cx, bytes.len() as u64)?;
    let (s, repaired) = decode_chunk(bytes);
    Ok(Scene {
        splats: s,
        format: InputFormat::Splat,
        locator: Locator::Records {
            start: 0,
            stride: RECORD as u64,
        },
        repaired_rotations: repaired,
        overflowed_scales: 0,
    })
}
