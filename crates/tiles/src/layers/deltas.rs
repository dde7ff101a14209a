//! Opacity deltas of a parent layer's splats, one array per child layer, derived from our LOD:
//! each parent splat fades out in proportion to the opacity mass its child layers bring back.
//!
//! A child splat is attributed to its nearest parent splat (the clustering merged it into a
//! nearby one); parent splat `i` receiving mass `m_c` from child `c` out of `M` in all gets
//! `delta_c[i] = -m_c / M`. A parent splat no child splat is nearest to is given entirely
//! (`-1`) to the child holding the splat nearest to it. So every parent splat's deltas add up
//! to -1: with all child layers fully drawn the parent layer vanishes and the finer level is
//! reproduced exactly.

use kiddo::{ImmutableKdTree, SquaredEuclidean};

/// One layer's splats for attribution: centres in a frame shared by parent and children (the
/// tileset or glTF world frame) and opacities.
#[derive(Debug, Clone, Copy)]
pub struct LayerPoints<'a> {
    /// Splat centres.
    pub centres: &'a [[f64; 3]],
    /// Splat opacities in [0, 1].
    pub opacities: &'a [f32],
}

fn tree(points: &[[f64; 3]], origin: [f64; 3]) -> Option<ImmutableKdTree<f64, 3>> {
    let rel: Vec<[f64; 3]> = points
        .iter()
        .map(|p| [p[0] - origin[0], p[1] - origin[1], p[2] - origin[2]])
        .collect();
    ImmutableKdTree::new_from_slice(&rel).ok()
}

fn rel(p: [f64; 3], o: [f64; 3]) -> [f64; 3] {
    [p[0] - o[0], p[1] - o[1], p[2] - o[2]]
}

/// The deltas of `parent`'s splats for each of `children` (same order): `out[c][i]` in
/// [-1, 0], and `sum_c out[c][i] = -1` for every `i` when some child has splats (all 0 when no
/// child has any). Non-finite centres or opacities count as mass 0 and are never nearest.
pub fn parent_deltas(parent: LayerPoints<'_>, children: &[LayerPoints<'_>]) -> Vec<Vec<f32>> {
    let n = parent.centres.len();
    let mut out = vec![vec![0.0f32; n]; children.len()];
    let finite = |p: &[f64; 3]| p.iter().all(|v| v.is_finite());
    let origin = parent
        .centres
        .iter()
        .find(|p| finite(p))
        .copied()
        .unwrap_or([0.0; 3]);
    // Parent splats with finite centres, in a KD-tree (indices map back through `pidx`).
    let pidx: Vec<usize> = (0..n).filter(|&i| finite(&parent.centres[i])).collect();
    let ppts: Vec<[f64; 3]> = pidx.iter().map(|&i| parent.centres[i]).collect();
    let Some(ptree) = tree(&ppts, origin).filter(|_| !ppts.is_empty()) else {
        return out;
    };
    let mut mass = vec![vec![0.0f64; n]; children.len()];
    let mut total = vec![0.0f64; n];
    for (c, child) in children.iter().enumerate() {
        for (p, &a) in child.centres.iter().zip(child.opacities) {
            if !finite(p) {
                continue;
            }
            let w = if a.is_finite() {
                a.max(0.0) as f64
            } else {
                0.0
            };
            let nn = ptree
                .query(&rel(*p, origin))
                .nearest_one::<SquaredEuclidean<f64>>()
                .execute();
            let i = pidx[nn.item as usize];
            mass[c][i] += w;
            total[i] += w;
        }
    }
    // Parent splats nobody's mass reached: given to the child holding the nearest splat.
    let mut all: Vec<[f64; 3]> = vec![];
    let mut owner: Vec<usize> = vec![];
    for (c, child) in children.iter().enumerate() {
        for p in child.centres.iter().filter(|p| finite(p)) {
            all.push(*p);
            owner.push(c);
        }
    }
    let ctree = if total.iter().any(|&t| t <= 0.0) && !all.is_empty() {
        tree(&all, origin)
    } else {
        None
    };
    for i in 0..n {
        if total[i] > 0.0 {
            for c in 0..children.len() {
                out[c][i] = (-(mass[c][i] / total[i])).clamp(-1.0, 0.0) as f32;
            }
        } else if let Some(t) = &ctree {
            let q = if finite(&parent.centres[i]) {
                rel(parent.centres[i], origin)
            } else {
                [0.0; 3]
            };
            let nn = t.query(&q).nearest_one::<SquaredEuclidean<f64>>().execute();
            out[owner[nn.item as usize]][i] = -1.0;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shares_follow_the_nearest_parent_and_sum_to_minus_one() {
        let parent = [[0.0, 0.0, 0.0], [10.0, 0.0, 0.0], [50.0, 0.0, 0.0]];
        let pa = [0.9f32; 3];
        // Child 0 near parent 0 (mass 0.6) and parent 1 (0.1); child 1 near parent 1 (0.3).
        let c0 = [[0.1, 0.0, 0.0], [9.0, 0.0, 0.0]];
        let a0 = [0.6f32, 0.1];
        let c1 = [[11.0, 0.0, 0.0], [45.0, 100.0, 0.0]];
        let a1 = [0.3f32, 0.0];
        let d = parent_deltas(
            LayerPoints {
                centres: &parent,
                opacities: &pa,
            },
            &[
                LayerPoints {
                    centres: &c0,
                    opacities: &a0,
                },
                LayerPoints {
                    centres: &c1,
                    opacities: &a1,
                },
            ],
        );
        assert_eq!(d[0][0], -1.0);
        assert_eq!(d[1][0], 0.0);
        assert!((d[0][1] + 0.25).abs() < 1e-6, "{:?}", d);
        assert!((d[1][1] + 0.75).abs() < 1e-6, "{:?}", d);
        // Parent 2 got only zero mass (child 1's transparent splat): the nearest splat's
        // child (child 1's (11,0,0), 39 away; child 0's (9,0,0) is 41 away) takes it.
        assert_eq!(d[0][2], 0.0);
        assert_eq!(d[1][2], -1.0);
        for (a, b) in d[0].iter().zip(&d[1]) {
            assert!((a + b + 1.0).abs() < 1e-6);
        }
    }

    #[test]
    fn no_children_no_fade() {
        let parent = [[0.0, 0.0, 0.0]];
        let d = parent_deltas(
            LayerPoints {
                centres: &parent,
                opacities: &[1.0],
            },
            &[LayerPoints {
                centres: &[],
                opacities: &[],
            }],
        );
        assert_eq!(d, vec![vec![0.0]]);
    }
}
