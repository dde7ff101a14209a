//! meshopt's vertex codec encoder, bitstream version 0 (the `EXT_meshopt_compression` ATTRIBUTES
//! mode), in Rust: byte-identical to meshoptimizer's `meshopt_encodeVertexBufferLevel(.., 0)`.
// The C encoder measures each 16-byte group four times with scalar loops; this one counts a
// group's out-of-range bytes once per bit width, and was the largest part of the High/Medium cost.

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
        (4..=256).contains(&stride) && stride % 4 == 0 && data.len() % stride == 0,
        "vertex stride {stride} for {} bytes",
        data.len()
    );
    let count = data.len() / stride;
    let bs = block_size(stride);
    // Header, per block and byte a group header and at most the bytes, the tail.
    let bound = 1 + count.div_ceil(bs) * stride * ((bs / GROUP).div_ceil(4) + bs) + TAIL_MIN;
    let mut out = Vec::with_capacity(bound.max(stride + 1));
    out.push(HEADER);
    let first = &data[..stride.min(data.len())];
    let mut last = [0u8; 256];
    last[..first.len()].copy_from_slice(first);
    let mut deltas = [0u8; BLOCK_MAX];
    for block in data.chunks(bs * stride) {
        let n = block.len() / stride;
        let aligned = n.next_multiple_of(GROUP);
        // Past the block's vertices the groups hold zeros.
        deltas[n..aligned].fill(0);
        for k in 0..stride {
            let mut p = last[k];
            for (d, v) in deltas.iter_mut().zip(block[k..].iter().step_by(stride)) {
                let x = v.wrapping_sub(p);
                *d = (x << 1) ^ (0u8.wrapping_sub(x >> 7));
                p = *v;
            }
            encode_bytes(&mut out, &deltas[..aligned]);
        }
        last[..stride].copy_from_slice(&block[(n - 1) * stride..]);
    }
    if stride < TAIL_MIN {
        out.resize(out.len() + TAIL_MIN - stride, 0);
    }
    if count > 0 {
        out.extend_from_slice(first);
    } else {
        out.resize(out.len() + stride, 0);
    }
    out
}

/// Appends one byte column of a block (a multiple of [`GROUP`] bytes): 2-bit headers, then
/// each group at the width that is shortest (ties go to the previous group's width, never
/// replacing literals), as meshopt's `encodeBytes` with version 0's widths.
fn encode_bytes(out: &mut Vec<u8>, buffer: &[u8]) {
    let groups = buffer.len() / GROUP;
    let header = out.len();
    out.resize(header + groups.div_ceil(4), 0);
    let mut last_bits = u32::MAX;
    for (g, group) in buffer.chunks_exact(GROUP).enumerate() {
        let group: &[u8; GROUP] = group.try_into().expect("whole groups");
        let (mut any, mut over2, mut over4) = (0u8, 0usize, 0usize);
        for &b in group {
            any |= b;
            over2 += (b >= 3) as usize;
            over4 += (b >= 15) as usize;
        }
        let sizes = [
            if any == 0 { 0 } else { usize::MAX },
            GROUP * 2 / 8 + over2,
            GROUP * 4 / 8 + over4,
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
        match bits {
            0 => {}
            8 => out.extend_from_slice(group),
            _ => {
                let sentinel = (1u8 << bits) - 1;
                let per = (8 / bits) as usize;
                for chunk in group.chunks_exact(per) {
                    let mut byte = 0u8;
                    for &b in chunk {
                        byte = (byte << bits) | b.min(sentinel);
                    }
                    out.push(byte);
                }
                out.extend(group.iter().filter(|&&b| b >= sentinel));
            }
        }
        last_bits = bits;
    }
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
