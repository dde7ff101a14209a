//! meshopt's vertex codec encoder, bitstream version 0 (the `EXT_meshopt_compression` ATTRIBUTES
//! mode), in Rust: byte-identical to meshoptimizer's `meshopt_encodeVertexBufferLevel(.., 0)`.
// The C encoder measures each 16-byte group byte by byte for every width; this one counts a
// group's bytes at or above each width's sentinel eight at a time (SWAR), for every target.

/// First byte of a version-0 stream.
const HEADER: u8 = 0xa0;
/// Bytes of vertex data per block.
const BLOCK_BYTES: usize = 8192;
/// Most vertices per block.
const BLOCK_MAX: usize = 256;
/// Bytes per group (one 2-bit header entry each).
const GROUP: usize = 16;
/// Smallest tail (zero padding, then the first vertex) of a version-0 stream.
const TAIL_MIN: usize = 32;
/// Bit widths of the header entries 0..=3 in version 0.
const BITS: [u32; 4] = [0, 2, 4, 8];

/// Vertices per block at `stride` bytes each (meshopt's `getVertexBlockSize`).
fn block_size(stride: usize) -> usize {
    ((BLOCK_BYTES / stride) & !(GROUP - 1)).min(BLOCK_MAX)
}

/// Encodes `data` (`data.len() / stride` vertices of `stride` bytes; `stride` a multiple of 4 in
/// 4..=256) as a version-0 vertex stream.
///
/// # Panics
/// When `stride` is outside that range or `data` is not whole vertices (a caller's bug: the
/// tile writers pass their own streams).
pub fn encode_vertex_buffer_v0(data: &[u8], stride: usize) -> Vec<u8> {
    assert!(
        (4..=256).contains(&stride)
            && stride.is_multiple_of(4)
            && data.len().is_multiple_of(stride),
        "vertex stride {stride} for {} bytes",
        data.len()
    );
    let count = data.len() / stride;
    let bs = block_size(stride);
    // Header; per block and byte column the group headers and at most a literal per group; the
    // tail; a group of slack for the unconditional stores of `encode_bytes`.
    let columns = count.div_ceil(bs) * stride;
    let bound = 1 + columns * ((bs / GROUP).div_ceil(4) + bs) + TAIL_MIN.max(stride) + GROUP;
    let mut out = vec![0u8; bound];
    out[0] = HEADER;
    let mut pos = 1;
    let first = &data[..stride.min(data.len())];
    let mut last = [0u8; 256];
    last[..first.len()].copy_from_slice(first);
    // Four byte columns at a time (strides are multiples of 4): their deltas from the previous
    // vertex, zigzagged, computed in one u32 per vertex.
    let mut deltas = [[0u8; BLOCK_MAX]; 4];
    #[cfg(target_arch = "x86_64")]
    let mut deltas16 = [[0u8; BLOCK_MAX]; GROUP];
    for block in data.chunks(bs * stride) {
        let n = block.len() / stride;
        let aligned = n.next_multiple_of(GROUP);
        // Past the block's vertices the groups hold zeros.
        for column in &mut deltas {
            column[n..aligned].fill(0);
        }
        #[allow(unused_mut)]
        let mut k0 = 0;
        // Sixteen byte columns at a time where the stride holds them (x86_64: SSE2).
        #[cfg(target_arch = "x86_64")]
        while k0 + GROUP <= stride {
            // SAFETY: SSE2 is part of every x86_64 target.
            unsafe { sse2::deltas16(block, stride, k0, &last, &mut deltas16) };
            for column in &deltas16 {
                pos = encode_column(&mut out, pos, &column[..aligned]);
            }
            k0 += GROUP;
        }
        for k in (k0..stride).step_by(4) {
            let word = |b: &[u8]| u32::from_le_bytes(b[k..k + 4].try_into().expect("4 bytes"));
            let mut p = word(&last);
            for (i, row) in block.chunks_exact(stride).enumerate() {
                let v = word(row);
                let z = zigzag_bytes(sub_bytes(v, p)).to_le_bytes();
                for (column, z) in deltas.iter_mut().zip(z) {
                    column[i] = z;
                }
                p = v;
            }
            for column in &deltas {
                pos = encode_column(&mut out, pos, &column[..aligned]);
            }
        }
        last[..stride].copy_from_slice(&block[(n - 1) * stride..]);
    }
    let pad = TAIL_MIN.saturating_sub(stride);
    out[pos..pos + pad].fill(0);
    pos += pad;
    out[pos..pos + stride].fill(0);
    out[pos..pos + first.len()].copy_from_slice(first);
    out.truncate(pos + stride);
    out
}

#[cfg(target_arch = "x86_64")]
/// The zigzagged deltas of sixteen byte columns at once, transposed in SSE2 registers (part of
/// the x86_64 baseline: no runtime check).
mod sse2 {
    use super::{BITS, BLOCK_MAX, GROUP, pack2};
    use std::arch::x86_64::{
        __m128i, _mm_add_epi8, _mm_and_si128, _mm_cmpeq_epi8, _mm_cmpgt_epi8, _mm_cvtsi128_si64,
        _mm_loadu_si128, _mm_max_epu8, _mm_min_epu8, _mm_movemask_epi8, _mm_or_si128,
        _mm_packus_epi16, _mm_set1_epi8, _mm_set1_epi16, _mm_setzero_si128, _mm_slli_epi16,
        _mm_srli_epi16, _mm_srli_si128, _mm_storeu_si128, _mm_sub_epi8, _mm_unpackhi_epi8,
        _mm_unpacklo_epi8, _mm_xor_si128,
    };

    /// The 16 bytes of `b`.
    #[target_feature(enable = "sse2")]
    fn load(b: &[u8; GROUP]) -> __m128i {
        // SAFETY: `b` is 16 readable bytes; the load is unaligned.
        unsafe { _mm_loadu_si128(b.as_ptr().cast()) }
    }

    /// Writes `v` into `out`.
    #[target_feature(enable = "sse2")]
    fn store(v: __m128i, out: &mut [u8; GROUP]) {
        // SAFETY: `out` is 16 writable bytes; the store is unaligned.
        unsafe { _mm_storeu_si128(out.as_mut_ptr().cast(), v) }
    }

    /// meshopt's byte zigzag (`(x << 1) ^ -(x >> 7)`) in each byte.
    #[target_feature(enable = "sse2")]
    fn zigzag(d: __m128i) -> __m128i {
        _mm_xor_si128(_mm_add_epi8(d, d), _mm_cmpgt_epi8(_mm_setzero_si128(), d))
    }

    /// Transposes 16 rows of 16 bytes: each interleaving round rotates the 8-bit index (row,
    /// column) of every byte left by one, so four rounds swap row and column.
    #[target_feature(enable = "sse2")]
    fn transpose(x: &mut [__m128i; GROUP]) {
        for _ in 0..4 {
            let mut y = [_mm_setzero_si128(); GROUP];
            for i in 0..GROUP / 2 {
                y[2 * i] = _mm_unpacklo_epi8(x[i], x[i + GROUP / 2]);
                y[2 * i + 1] = _mm_unpackhi_epi8(x[i], x[i + GROUP / 2]);
            }
            *x = y;
        }
    }

    /// Byte columns `k..k + 16` of the block's vertices (`stride` bytes each; `last` the vertex
    /// before the block) as zigzagged deltas from the previous vertex, one column per row of
    /// `out`, zero past the block's vertices up to the next whole group.
    #[target_feature(enable = "sse2")]
    pub(super) fn deltas16(
        block: &[u8],
        stride: usize,
        k: usize,
        last: &[u8; 256],
        out: &mut [[u8; BLOCK_MAX]; GROUP],
    ) {
        let n = block.len() / stride;
        let mut prev = load(last[k..k + GROUP].try_into().expect("16 bytes"));
        for g in (0..n).step_by(GROUP) {
            let mut x = [_mm_setzero_si128(); GROUP];
            for (j, x) in x.iter_mut().enumerate().take(n - g) {
                let at = (g + j) * stride + k;
                let r = load(block[at..at + GROUP].try_into().expect("16 bytes"));
                *x = zigzag(_mm_sub_epi8(r, prev));
                prev = r;
            }
            transpose(&mut x);
            for (column, v) in out.iter_mut().zip(x) {
                store(v, (&mut column[g..g + GROUP]).try_into().expect("16 bytes"));
            }
        }
    }

    /// [`super::encode_bytes`] with a group's widths measured, capped and packed in SSE2
    /// registers; the same bytes (`tests::sse2_groups_match_the_scalar_ones`).
    #[target_feature(enable = "sse2")]
    pub(super) fn encode_bytes(out: &mut [u8], mut pos: usize, buffer: &[u8]) -> usize {
        let groups = buffer.len() / GROUP;
        let header = pos;
        out[pos..pos + groups.div_ceil(4)].fill(0);
        pos += groups.div_ceil(4);
        let mut last_bits = u32::MAX;
        let (three, fifteen) = (_mm_set1_epi8(3), _mm_set1_epi8(15));
        for (g, group) in buffer.chunks_exact(GROUP).enumerate() {
            let group: &[u8; GROUP] = group.try_into().expect("16 bytes");
            let x = load(group);
            // Bit j set where byte j is at or above the sentinel (zero bytes: all set).
            let at_least = |t: __m128i| _mm_movemask_epi8(_mm_cmpeq_epi8(_mm_max_epu8(x, t), x));
            let (over2, over4) = (at_least(three) as u32, at_least(fifteen) as u32);
            let zero = _mm_movemask_epi8(_mm_cmpeq_epi8(x, _mm_setzero_si128())) == 0xffff;
            let sizes = [
                if zero { 0 } else { usize::MAX },
                GROUP * 2 / 8 + over2.count_ones() as usize,
                GROUP * 4 / 8 + over4.count_ones() as usize,
            ];
            let (mut best, mut best_size) = (3usize, GROUP);
            for (bitk, &size) in sizes.iter().enumerate() {
                if size < best_size
                    || (size == best_size && BITS[bitk] == last_bits && BITS[best] != 8)
                {
                    best = bitk;
                    best_size = size;
                }
            }
            out[header + g / 4] |= (best << ((g % 4) * 2)) as u8;
            let bits = BITS[best];
            last_bits = bits;
            let over = match bits {
                0 => continue,
                8 => {
                    store(
                        x,
                        (&mut out[pos..pos + GROUP]).try_into().expect("16 bytes"),
                    );
                    pos += GROUP;
                    continue;
                }
                2 => {
                    // Every byte capped at 3, four to a byte by the scalar multiply.
                    let c = _mm_min_epu8(x, three);
                    let halves = [c, _mm_srli_si128::<8>(c)].map(|h| _mm_cvtsi128_si64(h) as u64);
                    for h in halves {
                        out[pos..pos + 2].copy_from_slice(&pack2(h));
                        pos += 2;
                    }
                    over2
                }
                _ => {
                    // Every byte capped at 15; byte pairs (a, b) become (a << 4) | b.
                    let c = _mm_min_epu8(x, fifteen);
                    let pairs = _mm_or_si128(_mm_slli_epi16::<4>(c), _mm_srli_epi16::<8>(c));
                    let packed =
                        _mm_packus_epi16(_mm_and_si128(pairs, _mm_set1_epi16(0xff)), pairs);
                    let low = _mm_cvtsi128_si64(packed) as u64;
                    out[pos..pos + 8].copy_from_slice(&low.to_le_bytes());
                    pos += 8;
                    over4
                }
            };
            // The bytes at or above the sentinel, in order, whole.
            let mut m = over;
            while m != 0 {
                out[pos] = group[m.trailing_zeros() as usize];
                pos += 1;
                m &= m - 1;
            }
        }
        pos
    }
}

/// Two bytes holding the eight 2-bit values of `c` (bytes at most 3), four per byte with the
/// first in the top bits: one multiply gathers bytes 0..4 of each half at bits 30, 28, 26, 24
/// (no two terms overlap).
fn pack2(c: u64) -> [u8; 2] {
    const GATHER: u64 = (1 << 30) | (1 << 20) | (1 << 10) | 1;
    [c & 0xffff_ffff, c >> 32].map(|half| ((half * GATHER) >> 24) as u8)
}

/// `a - b` in each byte (wrapping, no borrow between bytes).
fn sub_bytes(a: u32, b: u32) -> u32 {
    const HIGH: u32 = 0x8080_8080;
    ((a | HIGH).wrapping_sub(b & !HIGH)) ^ ((a ^ !b) & HIGH)
}

/// meshopt's byte zigzag (`(x << 1) ^ -(x >> 7)`) in each byte.
fn zigzag_bytes(x: u32) -> u32 {
    ((x << 1) & 0xfefe_fefe) ^ (((x >> 7) & 0x0101_0101) * 0xff)
}

/// [`encode_bytes`], in SSE2 on x86_64.
fn encode_column(out: &mut [u8], pos: usize, buffer: &[u8]) -> usize {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: SSE2 is part of every x86_64 target.
    return unsafe { sse2::encode_bytes(out, pos, buffer) };
    #[cfg(not(target_arch = "x86_64"))]
    encode_bytes(out, pos, buffer)
}

/// Bytes 0x80 where the byte of `w` is at least `0x80 - t` (`t` repeated in every byte).
fn at_least(w: u64, t: u64) -> u64 {
    const LOW7: u64 = 0x7f7f_7f7f_7f7f_7f7f;
    const HIGH: u64 = 0x8080_8080_8080_8080;
    // The low 7 bits plus `t` carry into bit 7 exactly when they reach the threshold; bytes
    // with bit 7 set are above any threshold. No byte's sum leaves its byte.
    (((w & LOW7) + t) | w) & HIGH
}

/// Writes one byte column of a block (a multiple of [`GROUP`] bytes) at `pos` of `out` and
/// returns the end: 2-bit headers, then each group at the width that is shortest (ties go to the
/// previous group's width, never replacing literals), as meshopt's `encodeBytes` with version
/// 0's widths. Stores up to [`GROUP`] bytes past the end (`out` has the slack).
#[cfg_attr(target_arch = "x86_64", allow(dead_code))]
fn encode_bytes(out: &mut [u8], mut pos: usize, buffer: &[u8]) -> usize {
    const REP: u64 = 0x0101_0101_0101_0101;
    let groups = buffer.len() / GROUP;
    let header = pos;
    out[pos..pos + groups.div_ceil(4)].fill(0);
    pos += groups.div_ceil(4);
    let mut last_bits = u32::MAX;
    for (g, group) in buffer.chunks_exact(GROUP).enumerate() {
        let w = [0, 8].map(|o| u64::from_le_bytes(group[o..o + 8].try_into().expect("8 bytes")));
        // Bytes at or above the 2- and 4-bit sentinels (3, 15) go out whole after the packed ones.
        let over2 = w.map(|w| at_least(w, (0x80 - 3) * REP));
        let over4 = w.map(|w| at_least(w, (0x80 - 15) * REP));
        let sizes = [
            if w[0] | w[1] == 0 { 0 } else { usize::MAX },
            GROUP * 2 / 8 + (over2[0].count_ones() + over2[1].count_ones()) as usize,
            GROUP * 4 / 8 + (over4[0].count_ones() + over4[1].count_ones()) as usize,
        ];
        let (mut best, mut best_size) = (3usize, GROUP);
        for (bitk, &size) in sizes.iter().enumerate() {
            if size < best_size || (size == best_size && BITS[bitk] == last_bits && BITS[best] != 8)
            {
                best = bitk;
                best_size = size;
            }
        }
        out[header + g / 4] |= (best << ((g % 4) * 2)) as u8;
        let bits = BITS[best];
        let (over, sentinel) = match bits {
            0 => {
                last_bits = bits;
                continue;
            }
            8 => {
                out[pos..pos + GROUP].copy_from_slice(group);
                pos += GROUP;
                last_bits = bits;
                continue;
            }
            2 => (over2, 3u8),
            _ => (over4, 15u8),
        };
        // Every byte capped at the sentinel.
        let capped: [u64; 2] = [0, 1].map(|h| {
            let m = (over[h] >> 7) * 0xff;
            (w[h] & !m) | ((sentinel as u64 * REP) & m)
        });
        for c in capped {
            if bits == 2 {
                out[pos..pos + 2].copy_from_slice(&pack2(c));
                pos += 2;
            } else {
                for j in 0..4 {
                    let pair = c >> (16 * j);
                    out[pos] = (((pair & 0xf) << 4) | ((pair >> 8) & 0xf)) as u8;
                    pos += 1;
                }
            }
        }
        for &b in group {
            out[pos] = b;
            pos += (b >= sentinel) as usize;
        }
        last_bits = bits;
    }
    pos
}

#[cfg(all(test, feature = "native"))]
mod tests {
    use super::*;

    /// meshoptimizer's own encoder (the C library), version 0.
    fn c_encode(data: &[u8], stride: usize) -> Vec<u8> {
        let count = data.len() / stride;
        // SAFETY: the bound is computed for this count and stride; the encoder writes at most
        // `bound` bytes into `out` and reads `count * stride` bytes of `data`.
        unsafe {
            let bound = meshopt::ffi::meshopt_encodeVertexBufferBound(count, stride);
            let mut out = vec![0u8; bound];
            let n = meshopt::ffi::meshopt_encodeVertexBufferLevel(
                out.as_mut_ptr(),
                out.len(),
                data.as_ptr().cast(),
                count,
                stride,
                2,
                0,
            );
            out.truncate(n);
            out
        }
    }

    /// The SSE2 column encoder writes what the scalar one writes, on columns whose groups take
    /// every width (zero, 2- and 4-bit with and without literals, raw) and tie between widths.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn sse2_groups_match_the_scalar_ones() {
        let mut x = 0x2545_F491_4F6C_DD1Du64;
        let mut next = move || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x
        };
        for groups in [1usize, 3, 4, 5, 16] {
            for _ in 0..200 {
                // Each group's bytes below one of these bounds (1: a zero group).
                let mut column = vec![];
                for _ in 0..groups {
                    let r = [1u64, 2, 3, 4, 15, 16, 17, 256][(next() % 8) as usize];
                    column.extend((0..GROUP).map(|_| (next() % r) as u8));
                }
                let (mut a, mut b) = (vec![0u8; 1024], vec![0u8; 1024]);
                let na = encode_bytes(&mut a, 3, &column);
                // SAFETY: SSE2 is part of every x86_64 target.
                let nb = unsafe { sse2::encode_bytes(&mut b, 3, &column) };
                assert_eq!(a[..na], b[..nb], "{column:?}");
            }
        }
    }

    /// Byte for byte the C encoder's output at every stride the tiles use and others, on
    /// random bytes, on smooth data, on data whose deltas sit at the width boundaries (ties
    /// between widths, zero groups) and on quantised floats.
    #[test]
    fn matches_the_c_encoder() {
        let mut x = 0x9E37_79B9_7F4A_7C15u64;
        let mut next = move || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x
        };
        for stride in [4usize, 8, 12, 16, 36, 48, 96, 100, 180, 252, 256] {
            for count in [0usize, 1, 15, 16, 17, 255, 256, 257, 700, 4099] {
                for pattern in 0..4 {
                    let mut data: Vec<u8> = (0..count * stride).map(|_| next() as u8).collect();
                    match pattern {
                        // Smooth: small deltas.
                        1 => {
                            for i in stride..data.len() {
                                data[i] = data[i - stride].wrapping_add(data[i] % 3);
                            }
                        }
                        // Deltas from a few ranges around the 2- and 4-bit sentinels.
                        2 => {
                            for i in stride..data.len() {
                                let r = [0u64, 1, 2, 7, 8, 40][(next() % 6) as usize];
                                data[i] = data[i - stride].wrapping_add((next() % (r + 1)) as u8);
                            }
                        }
                        // Quantised floats (the EXPONENTIAL filter's words).
                        3 => {
                            for w in data.chunks_exact_mut(4) {
                                let v = ((next() % 2000) as f32 - 1000.0) * 0.01;
                                w.copy_from_slice(&v.to_le_bytes());
                            }
                        }
                        _ => {}
                    }
                    assert_eq!(
                        encode_vertex_buffer_v0(&data, stride),
                        c_encode(&data, stride),
                        "stride {stride} count {count} pattern {pattern}"
                    );
                }
            }
        }
    }
}
