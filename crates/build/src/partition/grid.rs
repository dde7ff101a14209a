//! The voxel grid of SGSS's "basic cuboids": splat counts per cell, axis-aligned cuboids of cells
//! (SGSS's "streaming cuboids") and 3D prefix sums for O(1) counts over any cuboid.

/// A grid of `dims[0] x dims[1] x dims[2]` basic cuboids with a splat count per cell
/// (cell index `x + nx * (y + ny * z)`).
#[derive(Debug, Clone, PartialEq)]
pub struct Grid {
    /// Cells along x, y, z (each at least 1).
    pub dims: [u32; 3],
    /// Splats per cell.
    pub counts: Vec<u64>,
    /// Inclusive prefix sums over `(nx + 1) x (ny + 1) x (nz + 1)` (a zero border first).
    prefix: Vec<u64>,
}

/// The most cells a grid may have (the tree optimiser's dense per-level arrays stay < 1 GiB).
pub const MAX_CELLS: u64 = 1 << 24;

/// An axis-aligned cuboid of cells: `lo` inclusive, `hi` exclusive, per axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Cuboid {
    /// First cell per axis.
    pub lo: [u32; 3],
    /// One past the last cell per axis.
    pub hi: [u32; 3],
}

impl Cuboid {
    /// Number of cells.
    pub fn cells(&self) -> u64 {
        (0..3).map(|a| (self.hi[a] - self.lo[a]) as u64).product()
    }

    /// Whether cell `(x, y, z)` lies inside.
    pub fn contains(&self, c: [u32; 3]) -> bool {
        (0..3).all(|a| self.lo[a] <= c[a] && c[a] < self.hi[a])
    }
}

impl Grid {
    /// A grid from its dimensions and per-cell counts; errors when the sizes disagree, a
    /// dimension is 0 or the grid exceeds [`MAX_CELLS`].
    pub fn new(dims: [u32; 3], counts: Vec<u64>) -> Result<Grid, String> {
        let n: u64 = dims.iter().map(|&d| d as u64).product();
        if dims.contains(&0) || n > MAX_CELLS {
            return Err(format!(
                "grid {}x{}x{} must have 1..={MAX_CELLS} cells",
                dims[0], dims[1], dims[2]
            ));
        }
        if counts.len() as u64 != n {
            return Err(format!(
                "grid {}x{}x{} needs {n} counts, got {}",
                dims[0],
                dims[1],
                dims[2],
                counts.len()
            ));
        }
        let prefix = prefix_sums(dims, |i| counts[i]);
        Ok(Grid {
            dims,
            counts,
            prefix,
        })
    }

    /// Number of cells.
    pub fn len(&self) -> usize {
        self.counts.len()
    }

    /// Whether the grid has no cells (never: dimensions are at least 1).
    pub fn is_empty(&self) -> bool {
        self.counts.is_empty()
    }

    /// Index of cell `(x, y, z)`.
    pub fn index(&self, c: [u32; 3]) -> usize {
        let [nx, ny, _] = self.dims;
        c[0] as usize + nx as usize * (c[1] as usize + ny as usize * c[2] as usize)
    }

    /// Cell coordinates of an index.
    pub fn coords(&self, i: usize) -> [u32; 3] {
        let [nx, ny, _] = self.dims;
        let (nx, ny) = (nx as usize, ny as usize);
        [
            (i % nx) as u32,
            (i / nx % ny) as u32,
            (i / (nx * ny)) as u32,
        ]
    }

    /// The whole grid as one cuboid.
    pub fn whole(&self) -> Cuboid {
        Cuboid {
            lo: [0; 3],
            hi: self.dims,
        }
    }

    /// Splats inside a cuboid (O(1)).
    pub fn count(&self, c: &Cuboid) -> u64 {
        box_sum(&self.prefix, self.dims, c)
    }

    /// Every axis-aligned cuboid of the grid (SGSS eq. 1: `C(nx+1,2) C(ny+1,2) C(nz+1,2)`), in
    /// lexicographic order of (lo, hi).
    pub fn all_cuboids(&self) -> Vec<Cuboid> {
        let ranges = |n: u32| -> Vec<(u32, u32)> {
            (0..n)
                .flat_map(|a| (a + 1..=n).map(move |b| (a, b)))
                .collect()
        };
        let (rx, ry, rz) = (
            ranges(self.dims[0]),
            ranges(self.dims[1]),
            ranges(self.dims[2]),
        );
        let mut out = Vec::with_capacity(rx.len() * ry.len() * rz.len());
        for &(x0, x1) in &rx {
            for &(y0, y1) in &ry {
                for &(z0, z1) in &rz {
                    out.push(Cuboid {
                        lo: [x0, y0, z0],
                        hi: [x1, y1, z1],
                    });
                }
            }
        }
        out
    }
}

/// Inclusive 3D prefix sums of `value(cell index)` with a zero border.
pub(crate) fn prefix_sums(dims: [u32; 3], value: impl Fn(usize) -> u64) -> Vec<u64> {
    let [nx, ny, nz] = dims.map(|d| d as usize);
    let (px, py) = (nx + 1, ny + 1);
    let mut p = vec![0u64; px * py * (nz + 1)];
    let at = |x: usize, y: usize, z: usize| x + px * (y + py * z);
    for z in 1..=nz {
        for y in 1..=ny {
            for x in 1..=nx {
                let v = value((x - 1) + nx * ((y - 1) + ny * (z - 1)));
                p[at(x, y, z)] = v
                    .wrapping_add(p[at(x - 1, y, z)])
                    .wrapping_add(p[at(x, y - 1, z)])
                    .wrapping_add(p[at(x, y, z - 1)])
                    .wrapping_sub(p[at(x - 1, y - 1, z)])
                    .wrapping_sub(p[at(x - 1, y, z - 1)])
                    .wrapping_sub(p[at(x, y - 1, z - 1)])
                    .wrapping_add(p[at(x - 1, y - 1, z - 1)]);
            }
        }
    }
    p
}

/// Sum over a cuboid from [`prefix_sums`] (inclusion-exclusion; exact in wrapping arithmetic).
pub(crate) fn box_sum(p: &[u64], dims: [u32; 3], c: &Cuboid) -> u64 {
    let (px, py) = (dims[0] as usize + 1, dims[1] as usize + 1);
    let at = |x: u32, y: u32, z: u32| p[x as usize + px * (y as usize + py * z as usize)];
    let ([x0, y0, z0], [x1, y1, z1]) = (c.lo, c.hi);
    at(x1, y1, z1)
        .wrapping_sub(at(x0, y1, z1))
        .wrapping_sub(at(x1, y0, z1))
        .wrapping_sub(at(x1, y1, z0))
        .wrapping_add(at(x0, y0, z1))
        .wrapping_add(at(x0, y1, z0))
        .wrapping_add(at(x1, y0, z0))
        .wrapping_sub(at(x0, y0, z0))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_over_cuboids_match_a_direct_sum() {
        let dims = [3, 4, 2];
        let counts: Vec<u64> = (0..24).map(|i| (i * 7 % 5) as u64).collect();
        let g = Grid::new(dims, counts.clone()).unwrap();
        let all = g.all_cuboids();
        assert_eq!(all.len(), 6 * 10 * 3);
        for c in &all {
            let direct: u64 = (0..g.len())
                .filter(|&i| c.contains(g.coords(i)))
                .map(|i| counts[i])
                .sum();
            assert_eq!(g.count(c), direct, "{c:?}");
        }
        assert_eq!(g.count(&g.whole()), counts.iter().sum::<u64>());
        for i in 0..g.len() {
            assert_eq!(g.index(g.coords(i)), i);
        }
    }

    #[test]
    fn bad_sizes_are_refused() {
        assert!(Grid::new([2, 2, 0], vec![]).is_err());
        assert!(Grid::new([2, 2, 1], vec![1; 3]).is_err());
        assert!(Grid::new([1 << 10, 1 << 10, 1 << 10], vec![]).is_err());
    }
}
