//! Niantic SPZ reader: v2/v3 (a gzip stream holding a 16-byte NGSP header then the attribute
//! arrays) and v4 (a plain 32-byte NGSP header, extension zone, table of contents, one ZSTD
//! stream per attribute). Layout checked against nianticlabs/spz `load-spz.cc`.
//!
//! Attribute arrays, in order: positions (3 x 24-bit signed fixed point, `fractionalBits`),
//! alphas (u8, post-sigmoid opacity * 255), colours (u8, `(b/255 - 0.5) / 0.15` = DC
//! coefficient), scales (u8, `exp(b/16 - 10)`), rotations (v2: 3 x u8 `x,y,z = b/127.5 - 1`, w
//! derived non-negative; v3+: 4-byte "smallest three": 2-bit index of the largest component, then
//! three 10-bit fields, sign bit + 9-bit magnitude scaled by 1/sqrt 2), SH (u8, `(b - 128)/128`,
//! per splat coefficient-major with RGB interleaved: already glTF order). Positions stay in SPZ's
//! RUB frame. Decompression is bounded by what the header's point count implies, so bombs fail
//! instead of exhausting memory.

use std::io::Read;

use rayon::prelude::*;

use super::error::{Ctx, ReadError, ReadErrorKind};
use super::{InputFormat, Locator, Scene, le_u32};
use splat2tiles_core::splat::{self, Splats, sh_rest_count};

/// Magic bytes `NGSP` (0x5053474e little endian).
pub(crate) const NGSP_MAGIC: [u8; 4] = *b"NGSP";
/// Magic bytes of a ZSTD frame.
pub(crate) const ZSTD_MAGIC: [u8; 4] = [0x28, 0xb5, 0x2f, 0xfd];
/// Most points accepted (upstream's own reader stops at 10 million).
pub const MAX_SPZ_POINTS: u64 = 1 << 26;
/// Largest ratio DEFLATE can reach (about 1032:1), used to reject impossible point counts.
const DEFLATE_MAX_RATIO: u64 = 1032;
/// Largest ratio ZSTD can reach (RLE blocks: about 32768:1).
const ZSTD_MAX_RATIO: u64 = 1 << 15;
/// Room allowed for v2/v3 extension records between the header and the arrays.
const EXT_SLACK: u64 = 1 << 20;
/// Header flag: the file carries extension records.
const FLAG_EXTENSIONS: u8 = 0x2;

/// The fields shared by every header version.
#[derive(Debug, Clone, Copy)]
struct Header {
    version: u32,
    n: usize,
    degree: u8,
    fractional_bits: u8,
    flags: u8,
}

impl Header {
    /// Byte sizes of the arrays: positions, alphas, colours, scales, rotations, SH.
    fn sizes(&self) -> [u64; 6] {
        let n = self.n as u64;
        let rot = if self.version >= 3 { 4 } else { 3 };
        let sh = sh_rest_count(self.degree) as u64 * 3;
        [n * 9, n, n * 3, n * 3, n * rot, n * sh]
    }

    fn data_len(&self) -> u64 {
        self.sizes().iter().sum()
    }
}

const STREAM_NAMES: [&str; 6] = ["positions", "alphas", "colors", "scales", "rotations", "sh"];

/// Parses magic, version, count, degree, fractional bits and flags of a 16- or 32-byte header;
/// `base` is the offset errors print for byte 0 of `h`, `note` a suffix such as "(decompressed)".
fn parse_common(cx: &Ctx, h: &[u8], base: u64, note: &str) -> Result<Header, ReadError> {
    if h[..4] != NGSP_MAGIC {
        return Err(cx.header(base, format!("missing SPZ magic NGSP{note}")));
    }
    let version = le_u32(h, 4);
    let n = le_u32(h, 8) as u64;
    if n > MAX_SPZ_POINTS {
        return Err(cx.at(
            base + 8,
            ReadErrorKind::TooMany {
                what: "SPZ point count".into(),
                count: n,
                limit: MAX_SPZ_POINTS,
            },
        ));
    }
    let degree = h[12];
    if degree > 3 {
        return Err(cx.at(
            base + 12,
            ReadErrorKind::Unsupported(format!("SPZ SH degree {degree} (at most 3)")),
        ));
    }
    Ok(Header {
        version,
        n: n as usize,
        degree,
        fractional_bits: h[13],
        flags: h[14],
    })
}

/// Reads an SPZ file of any supported version.
pub(crate) fn read(cx: &Ctx, bytes: &[u8]) -> Result<Scene, ReadError> {
    if bytes.starts_with(&NGSP_MAGIC) {
        if bytes.len() < 16 {
            return Err(truncated(cx, 0, "SPZ header", 16, bytes.len() as u64));
        }
        return match le_u32(bytes, 4) {
            4 => read_v4(cx, bytes),
            // An uncompressed legacy payload (some tools write it so).
            2 | 3 => {
                let h = parse_common(cx, bytes, 0, "")?;
                cx.check_memory(8, h.n as u64, h.degree, bytes.len() as u64)?;
                decode_legacy(cx, h, &bytes[16..], "")
            }
            v => Err(cx.at(4, ReadErrorKind::Unsupported(format!("SPZ version {v}")))),
        };
    }
    let zstd = bytes.starts_with(&ZSTD_MAGIC);
    let decoder: Box<dyn Read + '_> = if zstd {
        zstd_reader(cx, bytes)?
    } else {
        Box::new(flate2::read::GzDecoder::new(bytes))
    };
    let (what, ratio) = if zstd {
        ("zstd", ZSTD_MAX_RATIO)
    } else {
        ("gzip", DEFLATE_MAX_RATIO)
    };
    let note = " (decompressed)";
    let derr = |e: std::io::Error| cx.whole(ReadErrorKind::Decompress(format!("{what}: {e}")));
    let mut dec = decoder;
    let mut head = Vec::with_capacity(16);
    (&mut dec).take(16).read_to_end(&mut head).map_err(derr)?;
    if head.len() < 16 {
        return Err(truncated(
            cx,
            head.len() as u64,
            "SPZ header (decompressed)",
            16,
            head.len() as u64,
        ));
    }
    let h = parse_common(cx, &head, 0, note)?;
    if !matches!(h.version, 2 | 3) {
        return Err(cx.at(
            4,
            ReadErrorKind::Unsupported(format!("SPZ version {} inside a {what} stream", h.version)),
        ));
    }
    let data = h.data_len();
    let most = (bytes.len() as u64)
        .saturating_mul(ratio)
        .saturating_add(4096);
    if data > most {
        return Err(cx.at(
            8,
            ReadErrorKind::Decompress(format!(
                "{} points need {data} bytes{note}, more than a {}-byte {what} stream can hold",
                h.n,
                bytes.len()
            )),
        ));
    }
    // Before anything more is decompressed: the arrays and the splats must fit the memory limit
    // (an exact-size bomb passes the ratio check above).
    cx.check_memory(
        8,
        h.n as u64,
        h.degree,
        (bytes.len() as u64).saturating_add(data),
    )?;
    let slack = if h.flags & FLAG_EXTENSIONS != 0 {
        EXT_SLACK
    } else {
        0
    };
    let mut body = Vec::with_capacity(data.min(1 << 26) as usize);
    let cap = data + slack;
    dec.take(cap + 1).read_to_end(&mut body).map_err(derr)?;
    if body.len() as u64 > cap {
        return Err(cx.at(
            16 + cap,
            ReadErrorKind::Decompress(format!(
                "the {what} stream holds more than the {data} bytes{} that {} points need; \
                 stopped decompressing there (a decompression bomb, or a wrong point count)",
                if slack > 0 {
                    format!(" (+{slack} of extension records)")
                } else {
                    String::new()
                },
                h.n
            )),
        ));
    }
    decode_legacy(cx, h, &body, note)
}

fn truncated(cx: &Ctx, at: u64, what: &str, expected: u64, actual: u64) -> ReadError {
    cx.at(
        at,
        ReadErrorKind::Truncated {
            what: what.to_string(),
            unit: "bytes",
            expected,
            actual,
        },
    )
}

/// Decodes a v2/v3 payload `body` (everything after the 16-byte header).
fn decode_legacy(cx: &Ctx, h: Header, body: &[u8], note: &str) -> Result<Scene, ReadError> {
    if !matches!(h.version, 2 | 3) {
        return Err(cx.at(
            4,
            ReadErrorKind::Unsupported(format!("SPZ version {}", h.version)),
        ));
    }
    let data = h.data_len();
    let have = body.len() as u64;
    if have < data {
        return Err(truncated(
            cx,
            16 + have,
            &format!("SPZ arrays for {} points{note}", h.n),
            16 + data,
            16 + have,
        ));
    }
    let extra = (have - data) as usize;
    if extra > 0 && h.flags & FLAG_EXTENSIONS == 0 {
        return Err(cx.at(
            16 + data,
            ReadErrorKind::TrailingData {
                extra: extra as u64,
                unit: "bytes",
                what: format!("SPZ array{note}"),
            },
        ));
    }
    if extra as u64 > EXT_SLACK {
        return Err(cx.at(
            16,
            ReadErrorKind::Decompress(format!(
                "more than {EXT_SLACK} bytes of extension records or trailing data{note}"
            )),
        ));
    }
    // Extension records sit between the header and the arrays; their content is not needed.
    let mut arrays = Vec::with_capacity(6);
    let mut off = extra;
    for size in h.sizes() {
        arrays.push(&body[off..off + size as usize]);
        off += size as usize;
    }
    Ok(build(h, &arrays))
}

/// Reads a v4 file: 32-byte header, extensions up to `tocByteOffset`, TOC, ZSTD streams.
fn read_v4(cx: &Ctx, bytes: &[u8]) -> Result<Scene, ReadError> {
    let len = bytes.len() as u64;
    if bytes.len() < 32 {
        return Err(truncated(cx, 0, "SPZ v4 header", 32, len));
    }
    let h = parse_common(cx, bytes, 0, "")?;
    let num_streams = bytes[15] as usize;
    let toc = le_u32(bytes, 16) as u64;
    if toc < 32 || toc > len {
        return Err(cx.header(16, format!("SPZ v4 TOC offset {toc} outside 32..={len}")));
    }
    let toc_end = toc + num_streams as u64 * 16;
    if toc_end > len {
        return Err(truncated(
            cx,
            toc,
            &format!("SPZ v4 TOC of {num_streams} streams"),
            toc_end - toc,
            len - toc,
        ));
    }
    let sizes = h.sizes();
    let expected: &[u64] = if h.degree > 0 { &sizes } else { &sizes[..5] };
    if h.n > 0 && num_streams != expected.len() {
        return Err(cx.header(
            15,
            format!(
                "SPZ v4 with SH degree {} needs {} streams, header says {num_streams}",
                h.degree,
                expected.len()
            ),
        ));
    }
    let mut streams = Vec::with_capacity(num_streams);
    let mut off = toc_end;
    #[allow(clippy::needless_range_loop)] // i is also the stream number in messages
    for i in 0..num_streams {
        let e = (toc + i as u64 * 16) as usize;
        let comp = u64::from_le_bytes(bytes[e..e + 8].try_into().expect("8 bytes"));
        let raw = u64::from_le_bytes(bytes[e + 8..e + 16].try_into().expect("8 bytes"));
        let want = if h.n == 0 {
            0
        } else {
            expected.get(i).copied().unwrap_or(0)
        };
        let name = STREAM_NAMES.get(i).copied().unwrap_or("extra");
        if raw != want {
            return Err(cx.header(
                e as u64 + 8,
                format!(
                    "SPZ v4 stream {i} ({name}): TOC says {raw} bytes, {} points need {want}",
                    h.n
                ),
            ));
        }
        let end = off.checked_add(comp).filter(|e| *e <= len).ok_or_else(|| {
            truncated(
                cx,
                off,
                &format!("SPZ v4 stream {i} ({name})"),
                comp,
                len - off,
            )
        })?;
        streams.push((i, off, &bytes[off as usize..end as usize], raw));
        off = end;
    }
    if off != len {
        return Err(cx.at(
            off,
            ReadErrorKind::TrailingData {
                extra: len - off,
                unit: "bytes",
                what: "SPZ v4 stream".into(),
            },
        ));
    }
    let raw_total: u64 = streams.iter().map(|s| s.3).sum();
    cx.check_memory(8, h.n as u64, h.degree, len.saturating_add(raw_total))?;
    let decoded: Vec<Vec<u8>> = streams
        .par_iter()
        .map(|&(i, at, comp, raw)| unzstd(cx, i, at, comp, raw))
        .collect::<Result<_, _>>()?;
    let empty: &[u8] = &[];
    let arrays: Vec<&[u8]> = (0..6)
        .map(|i| decoded.get(i).map_or(empty, |v| v.as_slice()))
        .collect();
    let mut scene = build(h, &arrays);
    scene.format = InputFormat::Spz { version: 4 };
    Ok(scene)
}

/// A zstd decoder over `bytes`.
#[cfg(feature = "native")]
fn zstd_reader<'a>(cx: &Ctx, bytes: &'a [u8]) -> Result<Box<dyn Read + 'a>, ReadError> {
    let d = zstd::stream::read::Decoder::with_buffer(bytes)
        .map_err(|e| cx.whole(ReadErrorKind::Decompress(format!("zstd: {e}"))))?;
    Ok(Box::new(d))
}

/// Without the native codecs zstd streams (SPZ v4) are refused.
#[cfg(not(feature = "native"))]
fn zstd_reader<'a>(cx: &Ctx, _bytes: &'a [u8]) -> Result<Box<dyn Read + 'a>, ReadError> {
    Err(cx.whole(ReadErrorKind::Unsupported(
        "zstd (SPZ v4) needs the native build of splat2tiles".into(),
    )))
}

/// Decompresses one v4 stream into exactly `raw` bytes, never holding more than `raw + 1`.
fn unzstd(cx: &Ctx, i: usize, at: u64, comp: &[u8], raw: u64) -> Result<Vec<u8>, ReadError> {
    let name = STREAM_NAMES.get(i).copied().unwrap_or("extra");
    let err = |m: String| {
        cx.at(
            at,
            ReadErrorKind::Decompress(format!("SPZ v4 stream {i} ({name}): {m}")),
        )
    };
    if raw == 0 && comp.is_empty() {
        return Ok(Vec::new());
    }
    let dec = zstd_reader(cx, comp).map_err(|e| err(e.to_string()))?;
    let mut out = Vec::with_capacity(raw.min(1 << 26) as usize);
    dec.take(raw + 1)
        .read_to_end(&mut out)
        .map_err(|e| err(e.to_string()))?;
    if out.len() as u64 != raw {
        return Err(err(format!(
            "decompressed to {}{} bytes, TOC says {raw}",
            out.len(),
            if out.len() as u64 > raw { "+" } else { "" }
        )));
    }
    Ok(out)
}

/// Decodes the six arrays (already checked to have the header's sizes) into a scene.
fn build(h: Header, a: &[&[u8]]) -> Scene {
    let n = h.n;
    let (pos, alpha, color, scale, rot, sh) = (a[0], a[1], a[2], a[3], a[4], a[5]);
    let inv = 0.5f64.powi(h.fractional_bits as i32);
    let mut s = Splats::with_capacity(h.degree, n);
    let fixed24 = |b: &[u8]| -> f64 {
        let v = (b[0] as i32) | ((b[1] as i32) << 8) | ((b[2] as i32) << 16);
        ((v << 8) >> 8) as f64 * inv
    };
    s.positions.extend(
        pos.chunks_exact(9)
            .map(|p| [fixed24(&p[0..3]), fixed24(&p[3..6]), fixed24(&p[6..9])]),
    );
    s.opacities.extend(alpha.iter().map(|&b| b as f32 / 255.0));
    let dc = |b: &u8| (*b as f32 / 255.0 - 0.5) / 0.15;
    s.sh0.extend(
        color
            .chunks_exact(3)
            .map(|c| [dc(&c[0]), dc(&c[1]), dc(&c[2])]),
    );
    let sc = |b: &u8| (*b as f32 / 16.0 - 10.0).exp();
    s.scales.extend(
        scale
            .chunks_exact(3)
            .map(|c| [sc(&c[0]), sc(&c[1]), sc(&c[2])]),
    );
    let mut repaired = 0;
    if h.version >= 3 {
        s.rotations.extend(rot.chunks_exact(4).map(|r| {
            let q = smallest_three(le_u32(r, 0));
            repaired += q.iter().all(|v| *v == 0.0) as usize;
            splat::normalize_quat(q)
        }));
    } else {
        s.rotations
            .extend(rot.chunks_exact(3).map(|r| v2_rotation([r[0], r[1], r[2]])));
    }
    let q8 = |b: u8| (b as f32 - 128.0) / 128.0;
    s.sh_rest
        .extend(sh.chunks_exact(3).map(|t| [q8(t[0]), q8(t[1]), q8(t[2])]));
    s.check_lengths();
    Scene {
        splats: s,
        format: InputFormat::Spz { version: h.version },
        locator: Locator::Index,
        repaired_rotations: repaired,
        overflowed_scales: 0,
    }
}

/// Decodes SPZ v2 rotation bytes: `x, y, z = b / 127.5 - 1`, `w = sqrt(1 - |xyz|^2)` clamped at
/// 0, normalised (also the model the writer fits its bytes to, `encode::spz_rotation`).
pub fn v2_rotation(b: [u8; 3]) -> [f32; 4] {
    let [x, y, z] = b.map(|v| v as f32 / 127.5 - 1.0);
    let w = (1.0 - (x * x + y * y + z * z)).max(0.0).sqrt();
    splat::normalize_quat([x, y, z, w])
}

/// Decodes a "smallest three" quaternion into `[x, y, z, w]`.
fn smallest_three(mut comp: u32) -> [f32; 4] {
    const MASK: u32 = (1 << 9) - 1;
    let largest = (comp >> 30) as usize;
    let mut q = [0.0f32; 4];
    let mut sum = 0.0f32;
    for i in (0..4).rev() {
        if i == largest {
            continue;
        }
        let mag = comp & MASK;
        let neg = (comp >> 9) & 1 == 1;
        comp >>= 10;
        let v = std::f32::consts::FRAC_1_SQRT_2 * mag as f32 / MASK as f32;
        q[i] = if neg { -v } else { v };
        sum += q[i] * q[i];
    }
    q[largest] = (1.0 - sum).max(0.0).sqrt();
    q
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn smallest_three_decodes_identity_and_signs() {
        // Largest = w (index 3), the other three zero.
        assert_eq!(smallest_three(3 << 30), [0.0, 0.0, 0.0, 1.0]);
        // Largest = x (index 0); fields from the top: y, z, w. Put w = -0.5 exactly-ish.
        let mag = (0.5 / std::f32::consts::FRAC_1_SQRT_2 * 511.0).round() as u32;
        let comp = (1 << 9) | mag; // largest index 0 in the top bits; lowest field is w
        let q = smallest_three(comp);
        assert!((q[3] + 0.5).abs() < 2e-3, "{q:?}");
        assert!((q[0] - (1.0f32 - q[3] * q[3]).sqrt()).abs() < 1e-6);
        assert_eq!([q[1], q[2]], [0.0, 0.0]);
    }
}
