//! The memory limit of `convert` (`--memory-limit SIZE`): size parsing, the default derived from
//! physical RAM, the estimate of what holding a declared input in memory costs, and the budget
//! of the out-of-core converter's regions.
//!
//! Defined once here: the whole-file readers (ascii PLY, SPZ) refuse inputs whose estimate
//! exceeds the limit (before allocating); the chunked pipeline sizes its regions to it.

/// Largest default limit, whatever the machine.
pub const DEFAULT_CAP: u64 = 4 << 30;
/// Default when the machine does not say how much memory it has.
const UNKNOWN_RAM_DEFAULT: u64 = DEFAULT_CAP;

/// A memory budget in bytes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MemoryLimit(pub u64);

impl MemoryLimit {
    /// The default: half of physical RAM, at most [`DEFAULT_CAP`].
    pub fn machine_default() -> MemoryLimit {
        MemoryLimit(
            physical_memory()
                .map(|m| (m / 2).min(DEFAULT_CAP))
                .unwrap_or(UNKNOWN_RAM_DEFAULT),
        )
    }

    /// Parses `64MiB`, `2GiB`, `1.5GB`, `4096` (bytes); binary and decimal units, case-insensitive.
    pub fn parse(s: &str) -> Result<MemoryLimit, String> {
        let bytes = parse_size::parse_size(s.trim())
            .map_err(|e| format!("'{s}': not a size ({e}); write e.g. 512MiB or 2GiB"))?;
        if bytes < 1 << 20 {
            return Err(format!("'{s}': the memory limit must be at least 1MiB"));
        }
        Ok(MemoryLimit(bytes))
    }

    /// The limit in bytes.
    pub fn bytes(self) -> u64 {
        self.0
    }
}

impl std::fmt::Display for MemoryLimit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&human(self.0))
    }
}

/// Bytes as `1.50 GiB`, `64.0 MiB` or `512 B`.
pub fn human(b: u64) -> String {
    const K: f64 = 1024.0;
    let f = b as f64;
    if f >= K * K * K {
        format!("{:.2} GiB", f / (K * K * K))
    } else if f >= K * K {
        format!("{:.1} MiB", f / (K * K))
    } else if f >= K {
        format!("{:.1} KiB", f / K)
    } else {
        format!("{b} B")
    }
}

/// Physical memory of this machine in bytes (Linux `/proc/meminfo`), if known.
pub fn physical_memory() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemTotal:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    kib.checked_mul(1024)
}

/// Bytes one splat of SH degree `degree` takes in [`splat2tiles_core::splat::Splats`].
pub fn splat_bytes(degree: u8) -> u64 {
    // f64 position, f32 scale, rotation, opacity, DC colour, and the higher SH (RGB f32 each).
    24 + 12 + 16 + 4 + 12 + 12 * splat2tiles_core::splat::sh_rest_count(degree.min(3)) as u64
}

/// Estimated peak bytes of converting `count` splats of SH degree `degree` in memory, when
/// `held` bytes of input (the file, decompressed arrays) are held while decoding: the splats, a
/// decoded copy while reading, the tiling frame's positions, unit coordinates and indices (56
/// bytes a splat) and the per-tile copies. Measured against peak RSS in `tests/hostile`.
pub fn in_memory_estimate(count: u64, degree: u8, held: u64) -> u64 {
    let per = splat_bytes(degree).saturating_mul(2).saturating_add(56);
    count.saturating_mul(per).saturating_add(held)
}

/// Bytes the converter's working set takes per splat of a region in memory: in pass 1 the
/// splats, input indices, unit coordinates, Morton codes and sort orders; in pass 2 the group
/// being built (splats, leaf order, the LOD's copies) and the next group, read ahead.
pub fn region_bytes_per_splat(degree: u8) -> u64 {
    2 * splat_bytes(degree) + 112
}

/// Bytes of `limit` kept aside from the regions: the program and its threads, input chunks,
/// spill write buffers, the tile facts and the region roots' contents (see ARCHITECTURE.md).
pub fn reserved_bytes(limit: u64) -> u64 {
    (40 << 20) + limit / 4
}

/// Most splats of SH degree `degree` one region (group of regions) may hold under `limit`
/// (at least 1; the converter raises it to the leaf budget).
pub fn region_splats(limit: u64, degree: u8) -> u64 {
    (limit.saturating_sub(reserved_bytes(limit)) / region_bytes_per_splat(degree)).max(1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_binary_and_decimal_sizes() {
        assert_eq!(MemoryLimit::parse("64MiB").unwrap().bytes(), 64 << 20);
        assert_eq!(MemoryLimit::parse("2GiB").unwrap().bytes(), 2 << 30);
        assert_eq!(MemoryLimit::parse("2gib").unwrap().bytes(), 2 << 30);
        assert_eq!(MemoryLimit::parse("1.5GB").unwrap().bytes(), 1_500_000_000);
        assert!(MemoryLimit::parse("lots").is_err());
        assert!(
            MemoryLimit::parse("12")
                .unwrap_err()
                .contains("at least 1MiB")
        );
    }

    #[test]
    fn default_is_capped_and_estimates_grow_with_count_and_degree() {
        let d = MemoryLimit::machine_default().bytes();
        assert!((1 << 20..=DEFAULT_CAP).contains(&d));
        assert_eq!(splat_bytes(0), 68);
        assert_eq!(splat_bytes(3), 68 + 12 * 15);
        assert!(in_memory_estimate(10, 3, 0) > in_memory_estimate(10, 0, 0));
        assert_eq!(in_memory_estimate(u64::MAX, 3, 5), u64::MAX);
        assert_eq!(human(64 << 20), "64.0 MiB");
    }

    #[test]
    fn region_budget_leaves_the_reserve_and_shrinks_with_the_sh_degree() {
        let l = 2u64 << 30;
        let n0 = region_splats(l, 0);
        assert!(n0 * region_bytes_per_splat(0) + reserved_bytes(l) <= l);
        assert!(n0 > 5_000_000, "{n0}");
        assert!(region_splats(l, 3) < n0 / 2);
        // Below the reserve there is still room for one splat (the converter raises it to the
        // leaf budget).
        assert_eq!(region_splats(1 << 20, 0), 1);
    }
}
