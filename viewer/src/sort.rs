//! Depth ordering of all resident splats: sortable float keys and a stable CPU LSD radix sort of
//! (key, value) pairs, 11-bit digits, skipping passes whose digit is the same for every key.

/// Bits per radix digit (three passes cover a 32-bit key).
pub const DIGIT_BITS: u32 = 11;
const BUCKETS: usize = 1 << DIGIT_BITS;
const PASSES: usize = 32_usize.div_ceil(DIGIT_BITS as usize);

/// Maps an `f32` to a `u32` whose unsigned order is [`f32::total_cmp`]'s order
/// (`-NaN < -inf < .. < -0 < +0 < .. < +inf < +NaN`).
#[inline]
pub fn float_key(f: f32) -> u32 {
    let b = f.to_bits();
    if b & 0x8000_0000 != 0 {
        !b
    } else {
        b | 0x8000_0000
    }
}

/// Key that puts larger depths first (back-to-front drawing) under an ascending sort.
#[inline]
pub fn back_to_front_key(depth: f32) -> u32 {
    !float_key(depth)
}

/// Reusable buffers of the radix sort, so that repeated sorts allocate nothing.
#[derive(Debug, Default, Clone)]
pub struct RadixSorter {
    /// Scratch (key << 32 | value) pairs, ping-pong partner of the working array.
    tmp: Vec<u64>,
    /// Working (key << 32 | value) pairs.
    pairs: Vec<u64>,
}

impl RadixSorter {
    /// An empty sorter.
    pub fn new() -> Self {
        Self::default()
    }

    /// Bytes currently held by the sorter's buffers.
    pub fn bytes(&self) -> usize {
        (self.tmp.capacity() + self.pairs.capacity()) * 8
    }

    /// Sorts `values` by `keys` ascending, stably (equal keys keep their input order), and writes
    /// the sorted values into `out` (cleared first). `keys` and `values` must have equal lengths;
    /// extra entries of the longer one are ignored.
    pub fn sort(&mut self, keys: &[u32], values: &[u32], out: &mut Vec<u32>) {
        let n = keys.len().min(values.len());
        self.pairs.clear();
        self.pairs.extend(
            keys[..n]
                .iter()
                .zip(&values[..n])
                .map(|(&k, &v)| ((k as u64) << 32) | v as u64),
        );
        self.sort_pairs();
        out.clear();
        out.extend(self.pairs.iter().map(|&p| p as u32));
    }

    /// Sorts `(key, value)` pairs given as `key << 32 | value` (values ride along).
    pub fn sort_packed(&mut self, pairs: &mut Vec<u64>) {
        std::mem::swap(&mut self.pairs, pairs);
        self.sort_pairs();
        std::mem::swap(&mut self.pairs, pairs);
    }

    fn sort_pairs(&mut self) {
        let n = self.pairs.len();
        if n < 2 {
            return;
        }
        // All digit histograms in one read of the keys.
        let mut hist = [[0u32; BUCKETS]; PASSES];
        for &p in &self.pairs {
            let k = (p >> 32) as u32;
            for (pass, h) in hist.iter_mut().enumerate() {
                h[((k >> (pass as u32 * DIGIT_BITS)) as usize) & (BUCKETS - 1)] += 1;
            }
        }
        // Scratch keeps its length between sorts: no zero-fill of n pairs per call.
        if self.tmp.len() < n {
            self.tmp.resize(n, 0);
        }
        for (pass, h) in hist.iter().enumerate() {
            // Every key has the same digit: this pass would not move anything.
            if h.iter().any(|&c| c as usize == n) {
                continue;
            }
            let mut offs = [0u32; BUCKETS];
            let mut sum = 0u32;
            for (o, &c) in offs.iter_mut().zip(h.iter()) {
                *o = sum;
                sum += c;
            }
            let shift = 32 + pass as u32 * DIGIT_BITS;
            let dst = &mut self.tmp[..n];
            for &p in &self.pairs {
                let d = ((p >> shift) as usize) & (BUCKETS - 1);
                let o = &mut offs[d];
                dst[*o as usize] = p;
                *o += 1;
            }
            std::mem::swap(&mut self.pairs, &mut self.tmp);
            self.pairs.truncate(n);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lcg(s: &mut u64) -> u32 {
        *s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (*s >> 32) as u32
    }

    fn check(keys: &[u32]) {
        let values: Vec<u32> = (0..keys.len() as u32).collect();
        let mut out = Vec::new();
        RadixSorter::new().sort(keys, &values, &mut out);
        let mut expect = values.clone();
        expect.sort_by_key(|&i| keys[i as usize]); // stable
        assert_eq!(out, expect);
    }

    #[test]
    fn equals_stable_sort_on_random_and_narrow_keys() {
        let mut s = 7u64;
        for n in [0usize, 1, 2, 3, 100, 5000, 70_000] {
            let wide: Vec<u32> = (0..n).map(|_| lcg(&mut s)).collect();
            check(&wide);
            // Few distinct keys: many ties, stability matters; high digits constant (skipped).
            let narrow: Vec<u32> = (0..n).map(|_| lcg(&mut s) % 7).collect();
            check(&narrow);
            // Only the top digit varies.
            let top: Vec<u32> = (0..n).map(|_| lcg(&mut s) & 0xC000_0000).collect();
            check(&top);
        }
        check(&[5; 1000]);
    }

    #[test]
    fn float_keys_follow_total_cmp() {
        let vals = [
            f32::NAN,
            -f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            0.0,
            -0.0,
            1.0,
            -1.0,
            1e-40,
            -1e-40,
            3.3e38,
            -3.3e38,
            0.2,
            1e6,
            -7.25,
        ];
        for &a in &vals {
            for &b in &vals {
                assert_eq!(
                    float_key(a).cmp(&float_key(b)),
                    a.total_cmp(&b),
                    "{a} vs {b}"
                );
            }
        }
        assert!(float_key(-0.0) < float_key(0.0));
        // Back-to-front: the farther splat first; NaN (positive) sorts before everything.
        let mut depths = vec![1.0f32, -2.0, 10.0, 0.0, -0.0, f32::NAN, 5.0, 10.0];
        let keys: Vec<u32> = depths.iter().map(|&d| back_to_front_key(d)).collect();
        let idx: Vec<u32> = (0..depths.len() as u32).collect();
        let mut out = Vec::new();
        RadixSorter::new().sort(&keys, &idx, &mut out);
        let mut expect = idx.clone();
        expect.sort_by(|&a, &b| depths[b as usize].total_cmp(&depths[a as usize]));
        assert_eq!(out, expect);
        assert_eq!(out[1..3], [2, 7], "equal depths keep input order");
        depths.clear();
    }

    #[test]
    fn packed_sort_matches_and_mismatched_lengths_are_cut() {
        let mut s = 3u64;
        let keys: Vec<u32> = (0..10_000).map(|_| lcg(&mut s) % 1000).collect();
        let mut packed: Vec<u64> = keys
            .iter()
            .enumerate()
            .map(|(i, &k)| ((k as u64) << 32) | i as u64)
            .collect();
        let mut sorter = RadixSorter::new();
        sorter.sort_packed(&mut packed);
        let mut out = Vec::new();
        sorter.sort(&keys, &(0..10_000).collect::<Vec<u32>>(), &mut out);
        assert_eq!(packed.iter().map(|&p| p as u32).collect::<Vec<_>>(), out);
        sorter.sort(&keys, &[1, 2], &mut out);
        assert_eq!(out.len(), 2);
        assert!(sorter.bytes() > 0);
    }
}
