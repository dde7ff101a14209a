//! Morton (Z-order) codes as 3D Tiles implicit tiling orders tiles: x in the least significant
//! bit, then y (then z for octrees); 2D codes for quadtrees, 3D codes for octrees.

/// Spreads the low 32 bits of `v` so that bit i lands at bit 2i.
fn spread2(v: u32) -> u64 {
    let mut x = v as u64;
    x = (x | (x << 16)) & 0x0000_FFFF_0000_FFFF;
    x = (x | (x << 8)) & 0x00FF_00FF_00FF_00FF;
    x = (x | (x << 4)) & 0x0F0F_0F0F_0F0F_0F0F;
    x = (x | (x << 2)) & 0x3333_3333_3333_3333;
    x = (x | (x << 1)) & 0x5555_5555_5555_5555;
    x
}

/// Inverse of [`spread2`].
fn compact2(v: u64) -> u32 {
    let mut x = v & 0x5555_5555_5555_5555;
    x = (x | (x >> 1)) & 0x3333_3333_3333_3333;
    x = (x | (x >> 2)) & 0x0F0F_0F0F_0F0F_0F0F;
    x = (x | (x >> 4)) & 0x00FF_00FF_00FF_00FF;
    x = (x | (x >> 8)) & 0x0000_FFFF_0000_FFFF;
    x = (x | (x >> 16)) & 0x0000_0000_FFFF_FFFF;
    x as u32
}

/// Spreads the low 21 bits of `v` so that bit i lands at bit 3i.
fn spread3(v: u32) -> u64 {
    let mut x = (v as u64) & 0x1F_FFFF;
    x = (x | (x << 32)) & 0x001F_0000_0000_FFFF;
    x = (x | (x << 16)) & 0x001F_0000_FF00_00FF;
    x = (x | (x << 8)) & 0x100F_00F0_0F00_F00F;
    x = (x | (x << 4)) & 0x10C3_0C30_C30C_30C3;
    x = (x | (x << 2)) & 0x1249_2492_4924_9249;
    x
}

/// Inverse of [`spread3`].
fn compact3(v: u64) -> u32 {
    let mut x = v & 0x1249_2492_4924_9249;
    x = (x | (x >> 2)) & 0x10C3_0C30_C30C_30C3;
    x = (x | (x >> 4)) & 0x100F_00F0_0F00_F00F;
    x = (x | (x >> 8)) & 0x001F_0000_FF00_00FF;
    x = (x | (x >> 16)) & 0x001F_0000_0000_FFFF;
    x = (x | (x >> 32)) & 0x1F_FFFF;
    x as u32
}

/// 2D Morton code (x in bit 0).
pub fn encode2(x: u32, y: u32) -> u64 {
    spread2(x) | (spread2(y) << 1)
}

/// Inverse of [`encode2`].
pub fn decode2(code: u64) -> (u32, u32) {
    (compact2(code), compact2(code >> 1))
}

/// 3D Morton code (x in bit 0, then y, then z); 21 bits per axis.
pub fn encode3(x: u32, y: u32, z: u32) -> u64 {
    spread3(x) | (spread3(y) << 1) | (spread3(z) << 2)
}

/// Inverse of [`encode3`].
pub fn decode3(code: u64) -> (u32, u32, u32) {
    (compact3(code), compact3(code >> 1), compact3(code >> 2))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn small_values_by_hand() {
        // x is the least significant bit.
        assert_eq!(encode2(1, 0), 1);
        assert_eq!(encode2(0, 1), 2);
        assert_eq!(encode2(3, 3), 15);
        assert_eq!(encode3(1, 0, 0), 1);
        assert_eq!(encode3(0, 1, 0), 2);
        assert_eq!(encode3(0, 0, 1), 4);
        assert_eq!(encode3(2, 0, 0), 8);
    }

    #[test]
    fn round_trips_at_full_width() {
        let mut s = 0x9E37_79B9u32;
        for _ in 0..10_000 {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            let (x, y) = (s, s.rotate_left(11));
            assert_eq!(decode2(encode2(x, y)), (x, y));
            let (a, b, c) = (s & 0x1F_FFFF, (s >> 5) & 0x1F_FFFF, (s >> 11) & 0x1F_FFFF);
            assert_eq!(decode3(encode3(a, b, c)), (a, b, c));
        }
        let m = 0x1F_FFFF;
        assert_eq!(decode3(encode3(m, m, m)), (m, m, m));
        assert_eq!(decode2(encode2(u32::MAX, u32::MAX)), (u32::MAX, u32::MAX));
    }
}
