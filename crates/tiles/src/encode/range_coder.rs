//! Adaptive binary range coder (the LZMA scheme: 11-bit probabilities, carry propagation through
//! a cached byte) with bit-tree symbol models; the entropy coder of the codebook variant.

/// Bits of a probability.
const PROB_BITS: u32 = 11;
/// The probability one means (`1 << PROB_BITS`).
const PROB_ONE: u16 = 1 << PROB_BITS;
/// How fast a probability follows the bits it codes (it moves 1/32 of the way per bit).
const ADAPT_SHIFT: u32 = 5;
/// The range is renormalised below this.
const TOP: u32 = 1 << 24;

/// An adaptive probability that the next bit is 0, starting at one half.
#[derive(Debug, Clone, Copy)]
pub struct Prob(u16);

impl Default for Prob {
    fn default() -> Self {
        Prob(PROB_ONE / 2)
    }
}

/// Writes bits under adaptive probabilities into a byte stream.
#[derive(Debug)]
pub struct Encoder {
    low: u64,
    range: u32,
    cache: u8,
    cache_size: u64,
    out: Vec<u8>,
}

impl Default for Encoder {
    fn default() -> Self {
        Encoder {
            low: 0,
            range: u32::MAX,
            cache: 0,
            cache_size: 1,
            out: Vec::new(),
        }
    }
}

impl Encoder {
    /// Codes `bit` under `p` and adapts `p` to it.
    pub fn bit(&mut self, p: &mut Prob, bit: bool) {
        let bound = (self.range >> PROB_BITS) * u32::from(p.0);
        if bit {
            self.low += u64::from(bound);
            self.range -= bound;
            p.0 -= p.0 >> ADAPT_SHIFT;
        } else {
            self.range = bound;
            p.0 += (PROB_ONE - p.0) >> ADAPT_SHIFT;
        }
        while self.range < TOP {
            self.range <<= 8;
            self.shift_low();
        }
    }

    /// Codes the low `count` bits of `value` (most significant first) at probability one half.
    pub fn direct(&mut self, value: u64, count: u32) {
        for i in (0..count).rev() {
            self.range >>= 1;
            if (value >> i) & 1 == 1 {
                self.low += u64::from(self.range);
            }
            while self.range < TOP {
                self.range <<= 8;
                self.shift_low();
            }
        }
    }

    fn shift_low(&mut self) {
        if self.low < 0xFF00_0000 || self.low > 0xFFFF_FFFF {
            let carry = (self.low >> 32) as u8;
            let mut byte = self.cache;
            loop {
                self.out.push(byte.wrapping_add(carry));
                byte = 0xFF;
                self.cache_size -= 1;
                if self.cache_size == 0 {
                    break;
                }
            }
            self.cache = (self.low >> 24) as u8;
        }
        self.cache_size += 1;
        self.low = (self.low & 0x00FF_FFFF) << 8;
    }

    /// The coded bytes (flushes the coder's state).
    pub fn finish(mut self) -> Vec<u8> {
        for _ in 0..5 {
            self.shift_low();
        }
        self.out
    }
}

/// The stream ended before the decoder had read what its bits need.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Truncated;

/// Reads what an [`Encoder`] wrote, under the same sequence of probabilities.
#[derive(Debug)]
pub struct Decoder<'a> {
    data: &'a [u8],
    at: usize,
    range: u32,
    code: u32,
}

impl<'a> Decoder<'a> {
    /// A decoder over `data` (an [`Encoder::finish`] output).
    pub fn new(data: &'a [u8]) -> Result<Self, Truncated> {
        let head = data.get(..5).ok_or(Truncated)?;
        let code = u32::from_be_bytes([head[1], head[2], head[3], head[4]]);
        Ok(Decoder {
            data,
            at: 5,
            range: u32::MAX,
            code,
        })
    }

    fn normalize(&mut self) -> Result<(), Truncated> {
        while self.range < TOP {
            let b = *self.data.get(self.at).ok_or(Truncated)?;
            self.at += 1;
            self.range <<= 8;
            self.code = (self.code << 8) | u32::from(b);
        }
        Ok(())
    }

    /// The next bit under `p` (adapting `p` as the encoder did).
    pub fn bit(&mut self, p: &mut Prob) -> Result<bool, Truncated> {
        let bound = (self.range >> PROB_BITS) * u32::from(p.0);
        let bit = if self.code < bound {
            self.range = bound;
            p.0 += (PROB_ONE - p.0) >> ADAPT_SHIFT;
            false
        } else {
            self.code -= bound;
            self.range -= bound;
            p.0 -= p.0 >> ADAPT_SHIFT;
            true
        };
        self.normalize()?;
        Ok(bit)
    }

    /// `count` bits at probability one half, most significant first.
    pub fn direct(&mut self, count: u32) -> Result<u64, Truncated> {
        let mut v = 0u64;
        for _ in 0..count {
            self.range >>= 1;
            let bit = self.code >= self.range;
            if bit {
                self.code -= self.range;
            }
            v = (v << 1) | u64::from(bit);
            self.normalize()?;
        }
        Ok(v)
    }
}

/// An adaptive model of `bits`-bit symbols: a binary tree of probabilities, one per prefix.
#[derive(Debug, Clone)]
pub struct BitTree {
    bits: u32,
    probs: Vec<Prob>,
}

impl BitTree {
    /// A model of symbols below `1 << bits` (at most 16 bits), every symbol equally likely.
    pub fn new(bits: u32) -> Self {
        let bits = bits.min(16);
        BitTree {
            bits,
            probs: vec![Prob::default(); 1 << bits],
        }
    }

    /// Codes `symbol` (its low `bits` bits).
    pub fn encode(&mut self, e: &mut Encoder, symbol: u32) {
        let mut node = 1usize;
        for i in (0..self.bits).rev() {
            let b = (symbol >> i) & 1 == 1;
            e.bit(&mut self.probs[node], b);
            node = (node << 1) | usize::from(b);
        }
    }

    /// The next symbol.
    pub fn decode(&mut self, d: &mut Decoder<'_>) -> Result<u32, Truncated> {
        let mut node = 1usize;
        for _ in 0..self.bits {
            let b = d.bit(&mut self.probs[node])?;
            node = (node << 1) | usize::from(b);
        }
        Ok((node - (1 << self.bits)) as u32)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use splat2tiles_core::rng::SplitMix64 as Rng;

    #[test]
    fn symbols_bits_and_direct_bits_come_back_in_order() {
        let mut rng = Rng::new(7);
        let syms: Vec<u32> = (0..20_000)
            .map(|i| {
                if i % 3 == 0 {
                    rng.below(256) as u32
                } else {
                    17
                }
            })
            .collect();
        let mut e = Encoder::default();
        let mut t = BitTree::new(8);
        let mut p = Prob::default();
        for (i, &s) in syms.iter().enumerate() {
            t.encode(&mut e, s);
            e.bit(&mut p, i % 5 == 0);
            e.direct(i as u64 * 0x9E37_79B9, 37);
        }
        let out = e.finish();
        let mut d = Decoder::new(&out).unwrap();
        let mut t = BitTree::new(8);
        let mut p = Prob::default();
        for (i, &s) in syms.iter().enumerate() {
            assert_eq!(t.decode(&mut d).unwrap(), s, "symbol {i}");
            assert_eq!(d.bit(&mut p).unwrap(), i % 5 == 0);
            let want = (i as u64 * 0x9E37_79B9) & ((1 << 37) - 1);
            assert_eq!(d.direct(37).unwrap(), want);
        }
    }

    #[test]
    fn a_skewed_source_codes_near_its_entropy() {
        // Two symbols of three in four are 17: entropy about 1.0 + 8/3 bits of the others'.
        let mut rng = Rng::new(3);
        let mut e = Encoder::default();
        let mut t = BitTree::new(8);
        let n = 100_000;
        for i in 0..n {
            let s = if i % 4 == 0 {
                rng.below(256) as u32
            } else {
                17
            };
            t.encode(&mut e, s);
        }
        let bits = e.finish().len() as f64 * 8.0 / n as f64;
        // H = -(0.75+1/1024) log2(0.75+1/1024) - 255/1024 log2(1/1024) = 2.80 bits.
        assert!(bits > 2.7 && bits < 3.0, "{bits} bits a symbol");
    }

    #[test]
    fn a_cut_stream_is_an_error_not_a_panic() {
        let mut e = Encoder::default();
        let mut t = BitTree::new(8);
        let mut rng = Rng::new(1);
        for _ in 0..1000 {
            t.encode(&mut e, rng.below(256) as u32);
        }
        let out = e.finish();
        let cut = &out[..out.len() / 2];
        let mut d = Decoder::new(cut).unwrap();
        let mut t = BitTree::new(8);
        let r: Result<Vec<u32>, _> = (0..1000).map(|_| t.decode(&mut d)).collect();
        assert_eq!(r, Err(Truncated));
        assert!(Decoder::new(&out[..3]).is_err());
    }
}
