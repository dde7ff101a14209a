//! SGSS's partition cost (sec. 3.1, eqs. 2-6): visibility tests R_vtest = C_d / C_dmax plus the
//! probability-weighted waste sum_v p_v (splats downloaded for v) / C_v, additive over cuboids.
//!
//! d_v (eq. 2) marks the cuboids holding at least one non-empty basic cuboid that view v needs
//! (an empty one renders nothing); C_v is the splats in those basic cuboids (the least v can download). A view that needs no splat (C_v = 0)
//! has no defined waste ratio and is left out; the other views' probabilities are renormalised.

use super::grid::{Cuboid, Grid};

/// One view of the distribution: its (unnormalised) probability and the basic cuboids it needs.
#[derive(Debug, Clone, PartialEq)]
pub struct View {
    /// Viewing probability (any non-negative weight; renormalised over the kept views).
    pub weight: f64,
    /// Indices of the cells the view needs (sorted, unique).
    pub cells: Vec<u32>,
}

/// The grid, the kept views and the constants of eqs. 3-6.
#[derive(Debug, Clone)]
pub struct CostModel {
    /// The basic cuboids.
    pub grid: Grid,
    /// Kept views (C_v > 0), probabilities normalised to sum 1.
    pub views: Vec<View>,
    /// C_v of each kept view.
    pub c_v: Vec<u64>,
    /// C_dmax (eq. 5): the non-empty basic cuboids.
    pub c_dmax: u64,
    /// Views given and dropped because they need no splat.
    pub dropped_views: usize,
}

/// The terms of the objective for one partition.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Score {
    /// C_d (eq. 4): non-empty streaming cuboids.
    pub vtests: u64,
    /// R_vtest (eq. 6).
    pub r_vtest: f64,
    /// sum_v R_waste^(v) (eq. 3): expected downloaded / needed splats, at least 1.
    pub r_waste: f64,
    /// R_vtest + sum_v R_waste (the ILP's objective).
    pub objective: f64,
    /// Expected splats downloaded per view (sum_v p_v x^T diag(d_v) C_num).
    pub expected_splats: f64,
}

impl CostModel {
    /// The model of `views` over `grid`; errors when a view names a cell outside the grid or a
    /// weight is negative or not finite.
    pub fn new(grid: Grid, views: Vec<View>) -> Result<CostModel, String> {
        let n = grid.len();
        let c_dmax = grid.counts.iter().filter(|&&c| c > 0).count() as u64;
        let mut kept = Vec::new();
        let mut c_v = Vec::new();
        let mut dropped = 0;
        for (k, mut v) in views.into_iter().enumerate() {
            if !(v.weight.is_finite() && v.weight >= 0.0) {
                return Err(format!("view {k}: weight {} is not >= 0", v.weight));
            }
            if let Some(&bad) = v.cells.iter().find(|&&c| c as usize >= n) {
                return Err(format!("view {k}: cell {bad} outside a grid of {n} cells"));
            }
            v.cells.sort_unstable();
            v.cells.dedup();
            // An empty basic cuboid is not needed to render anything.
            v.cells.retain(|&c| grid.counts[c as usize] > 0);
            let need: u64 = v.cells.iter().map(|&c| grid.counts[c as usize]).sum();
            if need == 0 || v.weight == 0.0 {
                dropped += 1;
                continue;
            }
            c_v.push(need);
            kept.push(v);
        }
        let total: f64 = kept.iter().map(|v| v.weight).sum();
        for v in &mut kept {
            v.weight /= total;
        }
        Ok(CostModel {
            grid,
            views: kept,
            c_v,
            c_dmax,
            dropped_views: dropped,
        })
    }

    /// sum_v p_v / C_v over the views that need a cell of `c` (the waste weight per splat of `c`).
    pub fn waste_weight(&self, c: &Cuboid) -> f64 {
        self.views
            .iter()
            .zip(&self.c_v)
            .filter(|(v, _)| {
                v.cells
                    .iter()
                    .any(|&i| c.contains(self.grid.coords(i as usize)))
            })
            .map(|(v, &need)| v.weight / need as f64)
            .sum()
    }

    /// The objective's share of one streaming cuboid: `[non-empty] / C_dmax + count x
    /// waste_weight` (the objective is the sum of these over an exact cover).
    pub fn cuboid_cost(&self, c: &Cuboid) -> f64 {
        let n = self.grid.count(c);
        if n == 0 {
            return 0.0;
        }
        1.0 / self.c_dmax as f64 + n as f64 * self.waste_weight(c)
    }

    /// Scores a partition; errors unless it covers every cell exactly once.
    pub fn score(&self, parts: &[Cuboid]) -> Result<Score, String> {
        let mut covered = vec![false; self.grid.len()];
        for p in parts {
            if (0..3).any(|a| p.lo[a] >= p.hi[a] || p.hi[a] > self.grid.dims[a]) {
                return Err(format!("cuboid {p:?} is empty or leaves the grid"));
            }
            for z in p.lo[2]..p.hi[2] {
                for y in p.lo[1]..p.hi[1] {
                    for x in p.lo[0]..p.hi[0] {
                        let i = self.grid.index([x, y, z]);
                        if std::mem::replace(&mut covered[i], true) {
                            return Err(format!("cell ({x}, {y}, {z}) covered twice"));
                        }
                    }
                }
            }
        }
        if let Some(i) = covered.iter().position(|&c| !c) {
            return Err(format!("cell {:?} not covered", self.grid.coords(i)));
        }
        let vtests = parts.iter().filter(|p| self.grid.count(p) > 0).count() as u64;
        let r_vtest = if self.c_dmax == 0 {
            0.0
        } else {
            vtests as f64 / self.c_dmax as f64
        };
        let mut r_waste = 0.0;
        let mut expected = 0.0;
        for p in parts {
            let n = self.grid.count(p) as f64;
            r_waste += n * self.waste_weight(p);
            expected += n * self.touch_probability(p);
        }
        Ok(Score {
            vtests,
            r_vtest,
            r_waste,
            objective: r_vtest + r_waste,
            expected_splats: expected,
        })
    }

    /// sum_v p_v over the views that need a cell of `c`.
    fn touch_probability(&self, c: &Cuboid) -> f64 {
        self.views
            .iter()
            .filter(|v| {
                v.cells
                    .iter()
                    .any(|&i| c.contains(self.grid.coords(i as usize)))
            })
            .map(|v| v.weight)
            .sum()
    }

    /// The objective of the basic cuboids without enumerating them: R_vtest = 1 and every view
    /// downloads exactly C_v, so sum_v R_waste = 1 (0 for terms without non-empty cells / views).
    pub fn basic_objective(&self) -> f64 {
        let vtest = if self.c_dmax > 0 { 1.0 } else { 0.0 };
        let waste = if self.views.is_empty() { 0.0 } else { 1.0 };
        vtest + waste
    }

    /// The partition into every basic cuboid (`x_base` of eq. 5).
    pub fn basic_partition(&self) -> Vec<Cuboid> {
        (0..self.grid.len())
            .map(|i| {
                let lo = self.grid.coords(i);
                Cuboid {
                    lo,
                    hi: [lo[0] + 1, lo[1] + 1, lo[2] + 1],
                }
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn model() -> CostModel {
        // 2 x 2 x 1: counts 10, 0, 30, 60.
        let g = Grid::new([2, 2, 1], vec![10, 0, 30, 60]).unwrap();
        let views = vec![
            View {
                weight: 3.0,
                cells: vec![0],
            },
            View {
                weight: 1.0,
                cells: vec![3, 2],
            },
            View {
                weight: 5.0,
                cells: vec![1],
            },
        ];
        CostModel::new(g, views).unwrap()
    }

    #[test]
    fn basic_partition_has_waste_one_and_full_vtests() {
        let m = model();
        assert_eq!(m.dropped_views, 1, "the view of the empty cell has C_v = 0");
        assert_eq!(m.c_dmax, 3);
        let s = m.score(&m.basic_partition()).unwrap();
        assert_eq!(s.vtests, 3);
        assert!((s.r_vtest - 1.0).abs() < 1e-12);
        assert!((s.r_waste - 1.0).abs() < 1e-12, "{s:?}");
        assert!((s.objective - m.basic_objective()).abs() < 1e-12);
        // p = 0.75 needs 10, p = 0.25 needs 90.
        assert!((s.expected_splats - (0.75 * 10.0 + 0.25 * 90.0)).abs() < 1e-9);
    }

    #[test]
    fn one_cuboid_wastes_by_the_papers_ratio() {
        let m = model();
        let s = m.score(&[m.grid.whole()]).unwrap();
        assert_eq!(s.vtests, 1);
        // Both views download all 100 splats: 0.75 * 100/10 + 0.25 * 100/90.
        let waste = 0.75 * 10.0 + 0.25 * 100.0 / 90.0;
        assert!((s.r_waste - waste).abs() < 1e-9, "{s:?}");
        assert!((s.objective - (1.0 / 3.0 + waste)).abs() < 1e-9);
        // The objective is the sum of the cuboid costs.
        assert!((m.cuboid_cost(&m.grid.whole()) - s.objective).abs() < 1e-12);
    }

    #[test]
    fn invalid_covers_and_views_are_refused() {
        let m = model();
        let row = |y| Cuboid {
            lo: [0, y, 0],
            hi: [2, y + 1, 1],
        };
        assert!(m.score(&[row(0)]).unwrap_err().contains("not covered"));
        assert!(
            m.score(&[row(0), row(0), row(1)])
                .unwrap_err()
                .contains("twice")
        );
        assert!(m.score(&[row(0), row(1)]).is_ok());
        let g = Grid::new([1, 1, 1], vec![1]).unwrap();
        let bad = View {
            weight: 1.0,
            cells: vec![4],
        };
        assert!(CostModel::new(g.clone(), vec![bad]).is_err());
        let neg = View {
            weight: f64::NAN,
            cells: vec![0],
        };
        assert!(CostModel::new(g, vec![neg]).is_err());
    }
}
