//! meshopt's EXPONENTIAL filter encoder (`meshopt_encodeFilterExp`) in Rust, byte-identical to
//! the C library for finite input; writes the little-endian words the vertex codec reads.

/// How exponents are shared (meshopt's `meshopt_EncodeExpMode`, the modes the tiles use).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ExpMode {
    /// One exponent per value; a zero keeps the component's previous exponent.
    Separate,
    /// One exponent per vector (its largest).
    SharedVector,
    /// One exponent per component over the whole stream (its largest).
    SharedComponent,
}

/// The smallest exponent meshopt assigns.
const MIN_EXP: i32 = -100;

/// meshopt's `optlog2`: the biased exponent field less 126 (sign ignored).
fn optlog2(v: f32) -> i32 {
    ((v.to_bits() >> 23) & 0xff) as i32 - 127 + 1
}

/// meshopt's `optexp2`: 2^e built from the exponent field.
fn optexp2(e: i32) -> f32 {
    f32::from_bits(((e + 127) as u32) << 23)
}

/// Encodes `data` (finite floats, `N` components per element) with `bits`-bit mantissas
/// (1..=24) under `mode`: 4 bytes per value, element after element.
pub fn encode_exp<const N: usize>(data: &[[f32; N]], bits: i32, mode: ExpMode) -> Vec<u8> {
    debug_assert!((1..=24).contains(&bits));
    let mut component = [if mode == ExpMode::Separate {
        0
    } else {
        MIN_EXP
    }; N];
    if mode == ExpMode::SharedComponent {
        for v in data {
            for (c, &x) in component.iter_mut().zip(v) {
                *c = (*c).max(optlog2(x));
            }
        }
    }
    let mut out = vec![0u8; data.len() * N * 4];
    let elements = data.iter().zip(out.chunks_exact_mut(N * 4));
    match mode {
        ExpMode::SharedComponent => {
            for (v, o) in elements {
                put(o, v, &component, bits);
            }
        }
        ExpMode::SharedVector => {
            for (v, o) in elements {
                let e = v.iter().fold(MIN_EXP, |e, &x| e.max(optlog2(x)));
                put(o, v, &[e; N], bits);
            }
        }
        ExpMode::Separate => {
            for (v, o) in elements {
                for (c, &x) in component.iter_mut().zip(v) {
                    if x != 0.0 {
                        *c = MIN_EXP.max(optlog2(x));
                    }
                }
                put(o, v, &component, bits);
            }
        }
    }
    out
}

/// Writes the words of one element `v` with exponents `exps` into `out` (4 bytes per value).
fn put<const N: usize>(out: &mut [u8], v: &[f32; N], exps: &[i32; N], bits: i32) {
    const MMASK: i32 = (1 << 24) - 1;
    const MMAX: i32 = MMASK >> 1;
    for ((o, &x), &e) in out.chunks_exact_mut(4).zip(v).zip(exps) {
        // The mantissa scaled to a `bits`-bit signed integer, rounded half away from zero in
        // f32 as the C code does, clamped so that rounding up cannot overflow.
        let exp = e - (bits - 1);
        let half = if x >= 0.0 { 0.5f32 } else { -0.5 };
        let m = ((x * optexp2(-exp) + half) as i32).min(MMAX);
        let word = (m & MMASK) as u32 | (exp as u32) << 24;
        o.copy_from_slice(&word.to_le_bytes());
    }
}

#[cfg(all(test, feature = "native"))]
mod tests {
    use super::*;
    use meshopt::EncodeExpMode;

    /// The C filter's words as bytes.
    fn c_exp<const N: usize>(data: &[[f32; N]], bits: i32, mode: EncodeExpMode) -> Vec<u8> {
        meshopt::encode_filter_exp::<N>(data, bits, mode)
            .iter()
            .flatten()
            .flat_map(|w| w.to_le_bytes())
            .collect()
    }

    /// Random floats over many magnitudes (2^-149 to 2^73), with zeros, halves (rounding ties), tiny and
    /// negative values.
    fn values<const N: usize>(n: usize, seed: u64) -> Vec<[f32; N]> {
        let mut x = seed | 1;
        let mut next = move || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x
        };
        (0..n)
            .map(|_| {
                [0; N].map(|_| {
                    let r = next();
                    match r % 7 {
                        0 => 0.0,
                        1 => (r >> 8) as f32 / 2.0f32.powi(24) - 0.5,
                        2 => ((r >> 40) as i32 - 8_000_000) as f32 * 0.5,
                        3 => f32::from_bits(
                            (r >> 32) as u32 & 0x807f_ffff | ((r % 200) as u32 + 1) << 23,
                        ),
                        4 => -f32::from_bits((r >> 32) as u32 & 0x3fff_ffff),
                        _ => ((r >> 11) as f64 / (1u64 << 53) as f64 * 200.0 - 100.0) as f32,
                    }
                })
            })
            .collect()
    }

    /// Byte for byte the C library's filter in every mode the tiles use, at their bit depths
    /// and the extremes, for 1-, 3- and 15-component elements.
    #[test]
    fn matches_the_c_filter() {
        let modes = [
            (ExpMode::Separate, EncodeExpMode::Separate),
            (ExpMode::SharedVector, EncodeExpMode::SharedVector),
            (ExpMode::SharedComponent, EncodeExpMode::SharedComponent),
        ];
        for (ours, theirs) in modes {
            for bits in [1, 4, 6, 9, 10, 11, 12, 16, 18, 24] {
                let v1 = values::<1>(3000, bits as u64);
                assert_eq!(encode_exp(&v1, bits, ours), c_exp(&v1, bits, theirs));
                let v3 = values::<3>(3000, 100 + bits as u64);
                assert_eq!(encode_exp(&v3, bits, ours), c_exp(&v3, bits, theirs));
                let v15 = values::<15>(500, 200 + bits as u64);
                assert_eq!(
                    encode_exp(&v15, bits, ours),
                    c_exp(&v15, bits, theirs),
                    "{ours:?} {bits} bits"
                );
            }
        }
    }
}
