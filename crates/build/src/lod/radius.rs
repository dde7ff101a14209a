//! Choosing a parent's clustering radius from a target splat count: occupied grid cells at every
//! power-of-two cell edge, counted from one sort of Morton codes, predict the clusters of a radius.

use splat2tiles_tiles::tiling::morton::encode3;

/// Finest level of the occupancy grid (21 bits per axis of a 63-bit Morton code).
const LEVELS: usize = 21;

/// Greedy radius-`d` clustering yields about as many clusters as there are occupied cells of edge
/// `CELL_PER_RADIUS * d`: its seeds are `d`-separated (random sequential packing on a plane jams
/// at one seed per `(1.2 d)^2`); measured on generated cities (surfaces with some depth) the
/// clusters match the cells at about 1.4 d.
pub const CELL_PER_RADIUS: f64 = 1.4;

/// How many grid cells a point set occupies at every power-of-two cell edge.
#[derive(Debug, Clone, PartialEq)]
pub struct Occupancy {
    /// Edge of the level-0 cell (the cube holding every point); 0 when all points coincide.
    pub edge: f64,
    /// `counts[j]`: occupied cells of edge `edge / 2^j`, `j = 0..=21` (non-decreasing).
    pub counts: [u64; LEVELS + 1],
}

impl Occupancy {
    /// Counts the occupied cells of `positions` at every level from one sort (O(n log n)).
    pub fn of(positions: &[[f64; 3]]) -> Occupancy {
        let mut counts = [0u64; LEVELS + 1];
        if positions.is_empty() {
            return Occupancy { edge: 0.0, counts };
        }
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for p in positions {
            for ((v, l), h) in p.iter().zip(lo.iter_mut()).zip(hi.iter_mut()) {
                if v.is_finite() {
                    *l = l.min(*v);
                    *h = h.max(*v);
                }
            }
        }
        let edge = (0..3)
            .map(|a| hi[a] - lo[a])
            .filter(|e| e.is_finite())
            .fold(0.0f64, f64::max);
        if !(edge > 0.0 && edge.is_finite()) {
            counts.fill(1);
            return Occupancy { edge: 0.0, counts };
        }
        let cells = ((1u64 << LEVELS) - 1) as f64;
        let q = |v: f64, a: usize| -> u32 {
            let t = ((v - lo[a]) / edge * cells).floor();
            if t.is_finite() {
                t.clamp(0.0, cells) as u32
            } else {
                0
            }
        };
        let mut codes: Vec<u64> = positions
            .iter()
            .map(|p| encode3(q(p[0], 0), q(p[1], 1), q(p[2], 2)))
            .collect();
        codes.sort_unstable();
        // Two neighbours in Morton order fall in different cells of level j exactly when their
        // codes differ above bit 3 * (21 - j): the highest differing bit names the first such j.
        let mut first_split = [0u64; LEVELS + 1];
        for w in codes.windows(2) {
            let x = w[0] ^ w[1];
            if x != 0 {
                let h = 63 - x.leading_zeros() as usize;
                first_split[LEVELS - (h / 3).min(LEVELS)] += 1;
            }
        }
        let mut acc = 1u64;
        for (c, f) in counts.iter_mut().zip(first_split) {
            acc += f;
            *c = acc;
        }
        Occupancy { edge, counts }
    }

    /// Cell edge at which about `target` cells are occupied, interpolating between the two
    /// bracketing levels as a power law; 0 when even the finest level holds fewer (nothing needs
    /// merging), the level-0 edge when `target <= 1`.
    pub fn edge_for(&self, target: f64) -> f64 {
        if self.edge <= 0.0 {
            return 0.0;
        }
        if target <= 1.0 {
            return self.edge;
        }
        let Some(j) = (0..LEVELS).find(|&j| self.counts[j + 1] as f64 > target) else {
            return 0.0;
        };
        let (a, b) = (self.counts[j] as f64, self.counts[j + 1] as f64);
        let frac = if b > a {
            ((target / a).ln() / (b / a).ln()).clamp(0.0, 1.0)
        } else {
            0.0
        };
        self.edge / 2f64.powf(j as f64 + frac)
    }

    /// Local dimension around cell edge `s`: log2 of the growth of the cell count from that edge
    /// to half of it, clamped to [0.5, 3] (about 2 on surfaces, 1 on lines).
    pub fn dimension_at(&self, s: f64) -> f64 {
        if self.edge <= 0.0 || s <= 0.0 {
            return 2.0;
        }
        let j = ((self.edge / s).log2().floor().max(0.0) as usize).min(LEVELS - 1);
        let (a, b) = (self.counts[j] as f64, self.counts[j + 1] as f64);
        (b / a).log2().clamp(0.5, 3.0)
    }
}

/// The clustering radius predicted to leave about `target` clusters of `positions`.
pub fn radius_for_count(occ: &Occupancy, target: usize) -> f64 {
    occ.edge_for(target as f64) / CELL_PER_RADIUS
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_cells_of_a_grid() {
        // A 16 x 16 grid of points, spacing 1, in the z = 0 plane: 256 cells at edge 1.
        let pts: Vec<[f64; 3]> = (0..256)
            .map(|i| [(i % 16) as f64, (i / 16) as f64, 0.0])
            .collect();
        let o = Occupancy::of(&pts);
        assert_eq!(o.edge, 15.0);
        assert_eq!(o.counts[0], 1);
        // Level j has cells of edge 15 / 2^j; from level 4 (edge < 1) every point is alone.
        assert_eq!(o.counts[1], 4);
        assert_eq!(o.counts[4], 256);
        assert_eq!(o.counts[LEVELS], 256);
        assert!(o.counts.windows(2).all(|w| w[0] <= w[1]));
        let e = o.edge_for(64.0);
        assert!(e > 15.0 / 16.0 && e <= 15.0 / 4.0, "{e}");
        assert_eq!(o.edge_for(1000.0), 0.0);
        assert_eq!(o.edge_for(1.0), 15.0);
        let d = o.dimension_at(15.0 / 2.0);
        assert!((d - 2.0).abs() < 0.01, "{d}");
    }

    #[test]
    fn coincident_and_empty_inputs() {
        let o = Occupancy::of(&[[3.0, 3.0, 3.0]; 10]);
        assert_eq!(o.edge, 0.0);
        assert!(o.counts.iter().all(|&c| c == 1));
        assert_eq!(o.edge_for(5.0), 0.0);
        assert_eq!(Occupancy::of(&[]).counts[0], 0);
        let huge = Occupancy::of(&[[-1e308, 0.0, 0.0], [1e308, 0.0, 0.0]]);
        assert_eq!(huge.edge, 0.0, "an infinite extent is treated as no extent");
    }
}
