//! TileSplat's Table 6 bit allocation (its Best/High/Medium/Low) as a reference codec: each
//! attribute quantised uniformly over its range in the input and bit-packed column by column.
//!
//! The paper gives only the bit depths; the ranges, the log-space scales and the column order
//! are ours (spec/quality-variants.md, "Peers"). Used by the peer comparison
//! (`benches/peers.rs`), not by the converter.

use splat2tiles_core::splat::{Splat, Splats, normalize_quat, sh_rest_count};

/// Bits per value of each attribute (TileSplat Table 6).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Table6Bits {
    /// Per position coordinate.
    pub position: u8,
    /// Per quaternion component.
    pub rotation: u8,
    /// Per scale axis (quantised in log space).
    pub scale: u8,
    /// Per DC colour channel.
    pub dc: u8,
    /// Per higher SH coefficient and channel.
    pub sh_rest: u8,
    /// Opacity.
    pub opacity: u8,
}

/// Table 6's four levels, in its column order (Best, High, Medium, Low).
pub const LEVELS: [(&str, Table6Bits); 4] = [
    ("best", bits(24, 12, 12, 10, 8, 12)),
    ("high", bits(24, 8, 8, 8, 6, 8)),
    ("medium", bits(24, 6, 6, 6, 5, 6)),
    ("low", bits(24, 4, 4, 4, 4, 4)),
];

const fn bits(
    position: u8,
    rotation: u8,
    scale: u8,
    dc: u8,
    sh_rest: u8,
    opacity: u8,
) -> Table6Bits {
    Table6Bits {
        position,
        rotation,
        scale,
        dc,
        sh_rest,
        opacity,
    }
}

const MAGIC: &[u8; 4] = b"TS6Q";
const HEADER: usize = 4 + 1 + 1 + 6 + 4;

impl Table6Bits {
    /// Bits one splat takes at SH degree `sh_degree` (Table 6's "bytes/primitive" x 8 at degree 3).
    pub fn bits_per_splat(&self, sh_degree: u8) -> u64 {
        3 * self.position as u64
            + 4 * self.rotation as u64
            + 3 * self.scale as u64
            + 3 * self.dc as u64
            + 3 * sh_rest_count(sh_degree) as u64 * self.sh_rest as u64
            + self.opacity as u64
    }

    fn as_array(&self) -> [u8; 6] {
        [
            self.position,
            self.rotation,
            self.scale,
            self.dc,
            self.sh_rest,
            self.opacity,
        ]
    }
}

/// Why a Table 6 payload could not be decoded.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("Table 6 payload, byte {offset}: {what}")]
pub struct Table6Error {
    /// Byte offset of the problem.
    pub offset: usize,
    /// What is wrong.
    pub what: String,
}

fn err(offset: usize, what: impl Into<String>) -> Table6Error {
    Table6Error {
        offset,
        what: what.into(),
    }
}

/// One quantised column: its range and the values' bit depth.
struct Column {
    lo: f32,
    hi: f32,
    bits: u8,
}

impl Column {
    fn of(values: impl Iterator<Item = f32>, bits: u8) -> Self {
        let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
        for v in values {
            lo = lo.min(v);
            hi = hi.max(v);
        }
        if !(lo.is_finite() && hi.is_finite()) {
            (lo, hi) = (0.0, 0.0);
        }
        Column { lo, hi, bits }
    }

    fn quantise(&self, v: f32) -> u32 {
        let max = ((1u64 << self.bits) - 1) as f64;
        let span = self.hi as f64 - self.lo as f64;
        if span <= 0.0 || !v.is_finite() {
            return 0;
        }
        let t = ((v as f64 - self.lo as f64) / span).clamp(0.0, 1.0);
        (t * max).round() as u32
    }

    fn value(&self, q: u32) -> f32 {
        let max = ((1u64 << self.bits) - 1) as f64;
        (self.lo as f64 + q as f64 / max * (self.hi as f64 - self.lo as f64)) as f32
    }
}

/// LSB-first bit packer.
struct BitWriter {
    out: Vec<u8>,
    acc: u64,
    n: u32,
}

impl BitWriter {
    fn put(&mut self, v: u32, bits: u8) {
        self.acc |= (v as u64) << self.n;
        self.n += bits as u32;
        while self.n >= 8 {
            self.out.push(self.acc as u8);
            self.acc >>= 8;
            self.n -= 8;
        }
    }

    fn finish(mut self) -> Vec<u8> {
        if self.n > 0 {
            self.out.push(self.acc as u8);
        }
        self.out
    }
}

/// LSB-first bit reader over a slice whose length was checked beforehand.
struct BitReader<'a> {
    data: &'a [u8],
    pos: usize,
    acc: u64,
    n: u32,
}

impl BitReader<'_> {
    fn get(&mut self, bits: u8) -> u32 {
        while self.n < bits as u32 {
            let b = self.data.get(self.pos).copied().unwrap_or(0);
            self.pos += 1;
            self.acc |= (b as u64) << self.n;
            self.n += 8;
        }
        let v = (self.acc & ((1u64 << bits) - 1)) as u32;
        self.acc >>= bits;
        self.n -= bits as u32;
        v
    }
}

/// The values of every column, column by column, for splat set `s` (scales in log space,
/// quaternions normalised with w >= 0).
fn columns_of(s: &Splats) -> Vec<Vec<f32>> {
    let n = s.len();
    let rest = sh_rest_count(s.sh_degree);
    let mut cols: Vec<Vec<f32>> = Vec::new();
    for a in 0..3 {
        cols.push(s.positions.iter().map(|p| p[a] as f32).collect());
    }
    let quats: Vec<[f32; 4]> = s
        .rotations
        .iter()
        .map(|&q| {
            let q = normalize_quat(q);
            if q[3] < 0.0 { q.map(|c| -c) } else { q }
        })
        .collect();
    for a in 0..4 {
        cols.push(quats.iter().map(|q| q[a]).collect());
    }
    for a in 0..3 {
        cols.push(s.scales.iter().map(|v| v[a].max(1e-30).ln()).collect());
    }
    for a in 0..3 {
        cols.push(s.sh0.iter().map(|v| v[a]).collect());
    }
    for k in 0..rest {
        for a in 0..3 {
            cols.push((0..n).map(|i| s.sh_rest[i * rest + k][a]).collect());
        }
    }
    cols.push(s.opacities.clone());
    cols
}

/// Bit depth of each column in [`columns_of`]'s order.
fn depths(b: &Table6Bits, sh_degree: u8) -> Vec<u8> {
    let mut d = vec![b.position; 3];
    d.extend([b.rotation; 4]);
    d.extend([b.scale; 3]);
    d.extend([b.dc; 3]);
    d.extend(std::iter::repeat_n(b.sh_rest, 3 * sh_rest_count(sh_degree)));
    d.push(b.opacity);
    d
}

/// Encodes `splats` with bit depths `b`: header, per-column f32 range, packed columns.
pub fn encode(splats: &Splats, b: &Table6Bits) -> Vec<u8> {
    let cols = columns_of(splats);
    let depth = depths(b, splats.sh_degree);
    let mut out = Vec::with_capacity(HEADER + cols.len() * 8);
    out.extend_from_slice(MAGIC);
    out.push(1);
    out.push(splats.sh_degree);
    out.extend_from_slice(&b.as_array());
    out.extend_from_slice(&(splats.len() as u32).to_le_bytes());
    let quant: Vec<Column> = cols
        .iter()
        .zip(&depth)
        .map(|(c, &d)| Column::of(c.iter().copied(), d))
        .collect();
    for q in &quant {
        out.extend_from_slice(&q.lo.to_le_bytes());
        out.extend_from_slice(&q.hi.to_le_bytes());
    }
    let mut w = BitWriter { out, acc: 0, n: 0 };
    for (c, q) in cols.iter().zip(&quant) {
        for &v in c {
            w.put(q.quantise(v), q.bits);
        }
    }
    w.finish()
}

/// Decodes a payload of [`encode`]; every length is checked against the payload first.
pub fn decode(bytes: &[u8]) -> Result<Splats, Table6Error> {
    if bytes.len() < HEADER {
        return Err(err(bytes.len(), "shorter than the 16-byte header"));
    }
    if &bytes[..4] != MAGIC {
        return Err(err(0, "not TS6Q"));
    }
    if bytes[4] != 1 {
        return Err(err(4, format!("version {}", bytes[4])));
    }
    let sh_degree = bytes[5];
    if sh_degree > 3 {
        return Err(err(5, format!("SH degree {sh_degree}")));
    }
    for (i, &d) in bytes[6..12].iter().enumerate() {
        if !(1..=24).contains(&d) {
            return Err(err(6 + i, format!("bit depth {d} (1..=24)")));
        }
    }
    let b = bits(bytes[6], bytes[7], bytes[8], bytes[9], bytes[10], bytes[11]);
    let n = u32::from_le_bytes([bytes[12], bytes[13], bytes[14], bytes[15]]) as usize;
    let depth = depths(&b, sh_degree);
    let ranges_end = HEADER + depth.len() * 8;
    if bytes.len() < ranges_end {
        return Err(err(bytes.len(), "column ranges cut short"));
    }
    let need = (n as u64 * b.bits_per_splat(sh_degree)).div_ceil(8);
    if ((bytes.len() - ranges_end) as u64) < need {
        return Err(err(
            bytes.len(),
            format!("{n} splats need {need} bytes of packed values"),
        ));
    }
    let mut quant = Vec::with_capacity(depth.len());
    for (k, &d) in depth.iter().enumerate() {
        let o = HEADER + k * 8;
        let lo = f32::from_le_bytes(bytes[o..o + 4].try_into().unwrap_or([0; 4]));
        let hi = f32::from_le_bytes(bytes[o + 4..o + 8].try_into().unwrap_or([0; 4]));
        if !(lo.is_finite() && hi.is_finite() && lo <= hi) {
            return Err(err(o, format!("column {k} range [{lo}, {hi}]")));
        }
        quant.push(Column { lo, hi, bits: d });
    }
    let mut r = BitReader {
        data: &bytes[ranges_end..],
        pos: 0,
        acc: 0,
        n: 0,
    };
    let cols: Vec<Vec<f32>> = quant
        .iter()
        .map(|q| (0..n).map(|_| q.value(r.get(q.bits))).collect())
        .collect();
    let rest = sh_rest_count(sh_degree);
    let mut s = Splats::with_capacity(sh_degree, n);
    let mut sh = vec![[0f32; 3]; rest];
    // Column-major values: splat i is row i of every column.
    #[allow(clippy::needless_range_loop)]
    for i in 0..n {
        for (k, c) in sh.iter_mut().enumerate() {
            *c = [0, 1, 2].map(|a| cols[13 + 3 * k + a][i]);
        }
        s.push(
            Splat {
                position: [0, 1, 2].map(|a| cols[a][i] as f64),
                rotation: normalize_quat([cols[3][i], cols[4][i], cols[5][i], cols[6][i]]),
                scale: [7, 8, 9].map(|a| cols[a][i].exp()),
                sh0: [10, 11, 12].map(|a| cols[a][i]),
                opacity: cols[13 + 3 * rest][i].clamp(0.0, 1.0),
            },
            &sh,
        );
    }
    Ok(s)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scene(n: usize, degree: u8) -> Splats {
        let mut s = Splats::with_capacity(degree, n);
        let rest = vec![[0.05f32, -0.02, 0.01]; sh_rest_count(degree)];
        for i in 0..n {
            let t = i as f32 / n as f32;
            s.push(
                Splat {
                    position: [t as f64 * 10.0, (1.0 - t) as f64, 3.0],
                    scale: [0.01 + t, 0.02, 0.5],
                    rotation: normalize_quat([t, 0.2, -0.3, 1.0]),
                    opacity: t,
                    sh0: [t, -t, 0.5],
                },
                &rest,
            );
        }
        s
    }

    #[test]
    fn table_six_bytes_per_primitive() {
        // Table 6's last row, at SH degree 3.
        let want = [69.75, 53.75, 45.375, 37.0];
        for ((_, b), w) in LEVELS.iter().zip(want) {
            assert_eq!(b.bits_per_splat(3) as f64 / 8.0, w);
        }
    }

    #[test]
    fn round_trip_within_one_step() {
        for degree in [0u8, 3] {
            let s = scene(257, degree);
            for (_, b) in LEVELS {
                let enc = encode(&s, &b);
                let d = decode(&enc).unwrap();
                assert_eq!(d.len(), s.len());
                let step = |bits: u8, span: f64| span / ((1u64 << bits) - 1) as f64;
                for i in 0..s.len() {
                    // One 24-bit step plus the float32 rounding of the range and the value.
                    assert!((d.positions[i][0] - s.positions[i][0]).abs() <= step(24, 10.0) + 4e-6);
                    assert!(
                        (d.opacities[i] - s.opacities[i]).abs() as f64
                            <= step(b.opacity, 1.0) + 1e-6
                    );
                    assert!((d.sh0[i][0] - s.sh0[i][0]).abs() as f64 <= step(b.dc, 1.0) + 1e-6);
                }
                let payload = enc.len() - HEADER - (14 + 3 * sh_rest_count(degree)) * 8;
                assert_eq!(payload as u64, (257 * b.bits_per_splat(degree)).div_ceil(8));
            }
        }
    }

    #[test]
    fn truncated_and_hostile_payloads_are_errors() {
        let enc = encode(&scene(100, 1), &LEVELS[1].1);
        for cut in [0, 3, 15, 40, enc.len() - 1] {
            assert!(decode(&enc[..cut]).is_err(), "cut at {cut}");
        }
        let mut big = enc.clone();
        big[12..16].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(decode(&big).unwrap_err().what.contains("need"));
        let mut bad = enc.clone();
        bad[8] = 0;
        assert_eq!(decode(&bad).unwrap_err().offset, 8);
        let mut nan = enc;
        nan[HEADER..HEADER + 4].copy_from_slice(&f32::NAN.to_le_bytes());
        assert_eq!(decode(&nan).unwrap_err().offset, HEADER);
    }
}
