//! Importance of a splat inside its tile (SGSS eq. 7): opacity times (volume / reference
//! volume)^0.1, and the descending order every tile is written in so prefixes hold what matters.

use super::Splats;

/// Exponent of the volume term (SGSS eq. 7).
pub const VOLUME_EXPONENT: f64 = 0.1;

/// Volume term of splat `i`: the product of its three linear scales (f64, >= 0).
pub fn volume(splats: &Splats, i: usize) -> f64 {
    let s = splats.scales[i];
    (s[0] as f64 * s[1] as f64 * s[2] as f64).abs()
}

/// Reference volume of a set: the median of [`volume`] over its splats. A zero or non-finite
/// median (empty set, all-degenerate splats) falls back to 1.
pub fn reference_volume(splats: &Splats) -> f64 {
    let mut v: Vec<f64> = (0..splats.len()).map(|i| volume(splats, i)).collect();
    if v.is_empty() {
        return 1.0;
    }
    let mid = v.len() / 2;
    let (_, m, _) = v.select_nth_unstable_by(mid, |a, b| a.total_cmp(b));
    if m.is_finite() && *m > 0.0 { *m } else { 1.0 }
}

/// Importance scores of every splat: `opacity * (volume / v_ref)^0.1` (opacity is already
/// post-sigmoid in [`Splats`], so it is SGSS's `sigmoid(o)`). Never NaN: non-finite inputs score 0.
pub fn importance_scores(splats: &Splats, v_ref: f64) -> Vec<f64> {
    let v_ref = if v_ref.is_finite() && v_ref > 0.0 {
        v_ref
    } else {
        1.0
    };
    (0..splats.len())
        .map(|i| {
            let a = splats.opacities[i] as f64;
            let s = a.max(0.0) * (volume(splats, i) / v_ref).powf(VOLUME_EXPONENT);
            if s.is_finite() { s } else { 0.0 }
        })
        .collect()
}

/// Indices of `splats` by descending importance (reference volume = the set's median volume);
/// ties keep the original index order, so the order is deterministic.
pub fn importance_order(splats: &Splats) -> Vec<usize> {
    let scores = importance_scores(splats, reference_volume(splats));
    let mut order: Vec<usize> = (0..splats.len()).collect();
    order.sort_by(|&a, &b| scores[b].total_cmp(&scores[a]).then(a.cmp(&b)));
    order
}

/// Reorders `indices` (into `splats`) by descending importance of the splats they name, with the
/// reference volume taken over those splats; ties keep the current order.
pub fn sort_indices_by_importance(splats: &Splats, indices: &mut Vec<usize>) {
    let tile = splats.select(indices);
    let order = importance_order(&tile);
    *indices = order.into_iter().map(|k| indices[k]).collect();
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::splat::Splat;

    fn set(items: &[(f32, f32)]) -> Splats {
        let mut s = Splats::new(0);
        for &(opacity, scale) in items {
            s.push(
                Splat {
                    position: [0.0; 3],
                    scale: [scale; 3],
                    rotation: [0.0, 0.0, 0.0, 1.0],
                    opacity,
                    sh0: [0.0; 3],
                },
                &[],
            );
        }
        s
    }

    #[test]
    fn opaque_and_large_first_ties_by_index() {
        let s = set(&[(0.1, 1.0), (0.9, 1.0), (0.9, 1.0), (0.9, 2.0), (0.0, 5.0)]);
        assert_eq!(importance_order(&s), vec![3, 1, 2, 0, 4]);
    }

    #[test]
    fn degenerate_volumes_never_nan() {
        let s = set(&[
            (0.5, 0.0),
            (0.5, 0.0),
            (f32::NAN, 1.0),
            (0.7, f32::INFINITY),
        ]);
        let scores = importance_scores(&s, reference_volume(&s));
        assert!(scores.iter().all(|v| v.is_finite()));
        assert_eq!(importance_order(&s).len(), 4);
        assert_eq!(reference_volume(&Splats::new(0)), 1.0);
    }

    #[test]
    fn sorting_indices_matches_order() {
        let s = set(&[(0.2, 1.0), (0.8, 1.0), (0.5, 1.0)]);
        let mut idx = vec![2, 0, 1];
        sort_indices_by_importance(&s, &mut idx);
        assert_eq!(idx, vec![1, 2, 0]);
    }
}
