//! The order High, Medium and Low store a tile's splats in: Morton (Z-order) of their
//! tile-relative positions, so the codecs see neighbours (these variants are decoded whole).

use crate::tiling::morton::encode3;
use splat2tiles_core::splat::{Splats, sh_rest_count};

/// Largest cell index per axis of the Morton codes (21 bits per axis).
const CELLS: f64 = ((1u32 << 21) - 1) as f64;

/// Indices of `relative` (tile-relative positions as the tile stores them, f32) in Morton order
/// over their bounding box, ties in input order. Recomputable by a reader from Best's positions,
/// which are these f32 values exactly. Non-finite coordinates sort as cell 0.
pub fn storage_order(relative: &[[f32; 3]]) -> Vec<usize> {
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for p in relative {
        for a in 0..3 {
            if p[a].is_finite() {
                lo[a] = lo[a].min(p[a]);
                hi[a] = hi[a].max(p[a]);
            }
        }
    }
    let cell = |v: f32, a: usize| -> u32 {
        let extent = hi[a] as f64 - lo[a] as f64;
        let t = if extent > 0.0 {
            (v as f64 - lo[a] as f64) / extent
        } else {
            0.0
        };
        // NaN casts to 0; the clamp keeps every other value in range.
        (t.clamp(0.0, 1.0) * CELLS) as u32
    };
    let mut keyed: Vec<(u64, usize)> = relative
        .iter()
        .enumerate()
        .map(|(i, p)| (encode3(cell(p[0], 0), cell(p[1], 1), cell(p[2], 2)), i))
        .collect();
    // (key, index) pairs are distinct: an unstable sort gives the stable order.
    keyed.sort_unstable();
    keyed.into_iter().map(|(_, i)| i).collect()
}

/// The tile-relative f32 positions a tile stores for `splats` around `centre`.
pub fn relative_f32(splats: &Splats, centre: [f64; 3]) -> Vec<[f32; 3]> {
    splats
        .positions
        .iter()
        .map(|p| [0, 1, 2].map(|a| (p[a] - centre[a]) as f32))
        .collect()
}

/// `splats` in storage order around `centre` (SH kept up to `degree`), and that order: splat `j`
/// is the caller's `order[j]`.
pub fn in_storage_order(splats: &Splats, centre: [f64; 3], degree: u8) -> (Vec<usize>, Splats) {
    let order = storage_order(&relative_f32(splats, centre));
    let stored = gather(splats, &order, degree);
    (order, stored)
}

/// `splats` in `order`, keeping only the SH coefficients up to `degree` (at most the input's).
pub fn gather(splats: &Splats, order: &[usize], degree: u8) -> Splats {
    let degree = degree.min(splats.sh_degree);
    let (k_in, k) = (splats.rest_per_splat(), sh_rest_count(degree));
    let mut sh_rest = Vec::with_capacity(order.len() * k);
    if k > 0 {
        for &i in order {
            sh_rest.extend_from_slice(&splats.sh_rest[i * k_in..i * k_in + k]);
        }
    }
    Splats {
        positions: order.iter().map(|&i| splats.positions[i]).collect(),
        scales: order.iter().map(|&i| splats.scales[i]).collect(),
        rotations: order.iter().map(|&i| splats.rotations[i]).collect(),
        opacities: order.iter().map(|&i| splats.opacities[i]).collect(),
        sh0: order.iter().map(|&i| splats.sh0[i]).collect(),
        sh_degree: degree,
        sh_rest,
    }
}

/// Splats stored in `order` (splat `j` is the caller's `order[j]`) back in the caller's order.
pub fn in_caller_order(stored: &Splats, order: &[usize]) -> Splats {
    let mut inverse = vec![0usize; order.len()];
    for (j, &i) in order.iter().enumerate() {
        inverse[i] = j;
    }
    stored.select(&inverse)
}

/// A High or Medium tile's splats as read back, put in the order of the same tile's Best as read
/// back (`best`: the caller's order; its f32 positions give the storage order again).
pub fn in_best_order(stored: &Splats, best: &Splats) -> Splats {
    let relative: Vec<[f32; 3]> = best.positions.iter().map(|p| p.map(|v| v as f32)).collect();
    in_caller_order(stored, &storage_order(&relative))
}

/// A variant of a tile as read back (`candidate`) lined up splat for splat with the tile's Best
/// as read back: High and Medium are stored in Morton order ([`in_best_order`]), Low and tiles
/// written before that in Best's order; whichever order puts the candidate's positions nearer
/// Best's is returned. `None` when the two do not hold as many splats.
pub fn aligned_to_best(candidate: &Splats, best: &Splats) -> Option<Splats> {
    if candidate.len() != best.len() {
        return None;
    }
    let distance = |c: &Splats| -> f64 {
        c.positions
            .iter()
            .zip(&best.positions)
            .map(|(a, b)| (0..3).map(|k| (a[k] - b[k]).abs()).sum::<f64>())
            .sum()
    };
    let reordered = in_best_order(candidate, best);
    // NaN distances (non-finite positions) keep the stored order.
    Some(if distance(&reordered) < distance(candidate) {
        reordered
    } else {
        candidate.clone()
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use splat2tiles_core::splat::Splat;

    #[test]
    fn orders_by_z_curve_and_keeps_ties_in_input_order() {
        // Corners of a unit cube: Morton order is x fastest, then y, then z.
        let p = [
            [1.0, 1.0, 1.0],
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 0.0],
        ];
        assert_eq!(storage_order(&p), vec![1, 4, 2, 3, 0]);
    }

    #[test]
    fn degenerate_boxes_and_non_finite_values_do_not_panic() {
        assert_eq!(storage_order(&[]), Vec::<usize>::new());
        assert_eq!(storage_order(&[[5.0; 3]; 3]), vec![0, 1, 2]);
        let p = [
            [f32::NAN, 1.0, 0.0],
            [0.0, f32::INFINITY, 0.0],
            [1.0, 0.0, 0.0],
        ];
        let mut o = storage_order(&p);
        o.sort();
        assert_eq!(o, vec![0, 1, 2]);
    }

    #[test]
    fn gather_then_caller_order_round_trips() {
        let mut s = Splats::new(3);
        for i in 0..50 {
            let f = i as f32;
            s.push(
                Splat {
                    position: [(i * 7 % 13) as f64, (i % 5) as f64, -(i as f64)],
                    scale: [f, f + 1.0, f + 2.0],
                    rotation: [0.0, 0.0, 0.0, 1.0],
                    opacity: 0.5,
                    sh0: [f; 3],
                },
                &(0..15).map(|c| [f + c as f32; 3]).collect::<Vec<_>>(),
            );
        }
        let order = storage_order(&relative_f32(&s, [0.0; 3]));
        let stored = gather(&s, &order, 3);
        let back = in_caller_order(&stored, &order);
        assert_eq!(back.positions, s.positions);
        assert_eq!(back.sh_rest, s.sh_rest);
        let two = gather(&s, &order, 2);
        assert_eq!(two.sh_rest.len(), 50 * 8);
        assert_eq!(
            two.sh_rest[..8],
            s.sh_rest[order[0] * 15..order[0] * 15 + 8]
        );
    }
}
