//! Generated LapisGS-like level files (`import-lapisgs` tests): each level keeps the previous
//! level's splats in order, changes some of their opacities, and appends its own.

use splat2tiles_core::splat::Splats;
use std::path::{Path, PathBuf};

/// LapisGS-like levels over `all` (each level = the first `sizes[k]` splats): level `k` keeps
/// level `k-1`'s splats in order, changes the opacity of those `change(k, i)` selects (to a new
/// value in [0.02, 0.99]), and appends its own. Returns each level's splats.
pub fn levels(all: &Splats, sizes: &[usize], change: impl Fn(usize, usize) -> bool) -> Vec<Splats> {
    let mut out: Vec<Splats> = vec![];
    for (k, &n) in sizes.iter().enumerate() {
        let mut s = all.select(&(0..n).collect::<Vec<_>>());
        if k > 0 {
            let prev = &out[k - 1];
            for i in 0..prev.len() {
                s.opacities[i] = if change(k, i) {
                    0.02 + 0.97 * (((i * 7919 + k * 104_729) % 1000) as f32 / 1000.0)
                } else {
                    prev.opacities[i]
                };
            }
        }
        out.push(s);
    }
    out
}

/// Writes each level as `dir/level{k}.ply`; returns the paths, coarse to fine.
pub fn write_levels(dir: &Path, lv: &[Splats]) -> Vec<PathBuf> {
    lv.iter()
        .enumerate()
        .map(|(k, s)| {
            let p = dir.join(format!("level{k}.ply"));
            super::write_ply_file(&p, s);
            p
        })
        .collect()
}

/// The dense set of the import tests: 3 levels (600 / 2000 / 5000 SH-1 splats over a 10 x 10 x 6
/// box), half the earlier splats changing opacity at each level; returns the levels and files.
pub fn dense(dir: &Path) -> (Vec<Splats>, Vec<PathBuf>) {
    let all = super::random_splats(5000, 1, 10.0, 21);
    let lv = levels(&all, &[600, 2000, 5000], |k, i| (i + k) % 2 == 0);
    let files = write_levels(dir, &lv);
    (lv, files)
}
