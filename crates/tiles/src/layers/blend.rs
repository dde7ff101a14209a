//! What a viewer draws from layers: each layer's splats at their effective opacity (the
//! stored one, times the layer's blend factor, faded by its drawn child layers' deltas), the
//! occupancy rule, and the blend factor of LapisGS eq. 4 taken from the screen-space error.

use super::OCCUPANCY_THRESHOLD;
use splat2tiles_core::splat::Splats;

/// A child layer blends in while its parent's screen-space error goes from the refinement
/// threshold to this many times it (eq. 4 with the resolutions of adjacent levels replaced by
/// those two screen-space errors).
pub const BLEND_BAND: f64 = 2.0;

/// Eq. 4 over screen-space error: the blend factor `t` of a child layer when its parent layer
/// is seen with screen-space error `parent_sse` (pixels) and the viewer refines at `max_sse`:
/// 0 at `max_sse` and below, 1 from `BLEND_BAND * max_sse`, linear in between.
pub fn blend_factor(parent_sse: f64, max_sse: f64) -> f32 {
    if parent_sse.is_nan() || max_sse.is_nan() || max_sse <= 0.0 {
        return 0.0;
    }
    ((parent_sse - max_sse) / (max_sse * (BLEND_BAND - 1.0))).clamp(0.0, 1.0) as f32
}

/// One layer a viewer draws.
#[derive(Debug, Clone, Copy)]
pub struct DrawnLayer<'a> {
    /// Its splats (stored opacities).
    pub splats: &'a Splats,
    /// Index of its parent layer in the same list (always earlier); `None` for the base layer.
    pub parent: Option<usize>,
    /// Its opacity deltas for the parent layer's splats (`None` for the base layer).
    pub deltas: Option<&'a [f32]>,
    /// Its blend factor `t` in [0, 1] (the base layer: 1).
    pub blend: f32,
    /// Format v2: its deltas for ancestor layers above the parent (`&[]` for v1 layers).
    pub ancestors: &'a [AncestorDelta<'a>],
}

/// A layer's opacity deltas for one ancestor layer above its parent.
#[derive(Debug, Clone, Copy)]
pub struct AncestorDelta<'a> {
    /// How far up the ancestor is: 2 = the grand-parent (the parent's deltas are
    /// [`DrawnLayer::deltas`]).
    pub up: usize,
    /// One delta per splat of that ancestor.
    pub deltas: &'a [f32],
}

/// Why layers cannot be composed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ComposeError {
    /// A parent index does not point at an earlier layer.
    #[error("layer {0}: its parent must be an earlier layer")]
    BadParent(usize),
    /// An ancestor entry points above the base layer (or at the parent itself).
    #[error("layer {0}: an ancestor delta entry points at no ancestor above its parent")]
    BadAncestor(usize),
    /// A layer with a parent has no deltas, or their count is not the parent's (or an
    /// ancestor's) splat count.
    #[error("layer {layer}: {deltas} deltas for a parent/ancestor of {parent} splats")]
    DeltaCount {
        /// The layer.
        layer: usize,
        /// Its deltas (0 when absent).
        deltas: usize,
        /// Its parent's splats.
        parent: usize,
    },
}

/// Effective opacity of every splat of every layer: for layer `L` with cumulative blend
/// `T_L` (the product of the blend factors from the base down to `L`),
/// `T_L * min(1, o_i * max(0, 1 + sum over drawn descendant layers c with deltas for L of
/// (T_c / T_L) * delta_c[i]))`, where `T_c / T_L` is the product of the blend factors below `L`
/// down to `c` (`t_c` for a child, as in format v1). A non-finite delta counts as 0.
pub fn effective_opacities(layers: &[DrawnLayer<'_>]) -> Result<Vec<Vec<f32>>, ComposeError> {
    let blend = |l: &DrawnLayer<'_>| {
        if l.blend.is_finite() {
            l.blend.clamp(0.0, 1.0)
        } else {
            0.0
        }
    };
    let delta = |d: f32| if d.is_finite() { d } else { 0.0 };
    let mut cumulative = vec![1.0f32; layers.len()];
    let mut fade: Vec<Vec<f32>> = layers.iter().map(|l| vec![1.0; l.splats.len()]).collect();
    for (k, l) in layers.iter().enumerate() {
        let t = blend(l);
        match l.parent {
            None => cumulative[k] = t,
            Some(p) if p < k => {
                cumulative[k] = cumulative[p] * t;
                let n = layers[p].splats.len();
                let d = l.deltas.ok_or(ComposeError::DeltaCount {
                    layer: k,
                    deltas: 0,
                    parent: n,
                })?;
                if d.len() != n {
                    return Err(ComposeError::DeltaCount {
                        layer: k,
                        deltas: d.len(),
                        parent: n,
                    });
                }
                for (f, &di) in fade[p].iter_mut().zip(d) {
                    *f += t * delta(di);
                }
                for a in l.ancestors {
                    // Walk up `a.up` generations, multiplying the blend factors passed.
                    if a.up < 2 {
                        return Err(ComposeError::BadAncestor(k));
                    }
                    let (mut at, mut ratio) = (p, t);
                    for _ in 1..a.up {
                        ratio *= blend(&layers[at]);
                        at = layers[at].parent.ok_or(ComposeError::BadAncestor(k))?;
                    }
                    let n = layers[at].splats.len();
                    if a.deltas.len() != n {
                        return Err(ComposeError::DeltaCount {
                            layer: k,
                            deltas: a.deltas.len(),
                            parent: n,
                        });
                    }
                    for (f, &di) in fade[at].iter_mut().zip(a.deltas) {
                        *f += ratio * delta(di);
                    }
                }
            }
            Some(_) => return Err(ComposeError::BadParent(k)),
        }
    }
    Ok(layers
        .iter()
        .zip(fade)
        .zip(&cumulative)
        .map(|((l, f), &c)| {
            l.splats
                .opacities
                .iter()
                .zip(f)
                .map(|(&o, f)| (c * o * f.max(0.0)).min(c))
                .collect()
        })
        .collect())
}

/// The splats each layer draws: its splats at their effective opacity, those under
/// [`OCCUPANCY_THRESHOLD`] left out (the occupancy rule).
pub fn drawn_layers(layers: &[DrawnLayer<'_>]) -> Result<Vec<Splats>, ComposeError> {
    let ops = effective_opacities(layers)?;
    Ok(layers
        .iter()
        .zip(ops)
        .map(|(l, o)| {
            let keep: Vec<usize> = (0..o.len())
                .filter(|&i| o[i] >= OCCUPANCY_THRESHOLD)
                .collect();
            let mut s = l.splats.select(&keep);
            s.opacities = keep.iter().map(|&i| o[i]).collect();
            s
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use splat2tiles_core::splat::Splat;

    fn splats(opacities: &[f32]) -> Splats {
        let mut s = Splats::new(0);
        for (i, &o) in opacities.iter().enumerate() {
            s.push(
                Splat {
                    position: [i as f64, 0.0, 0.0],
                    scale: [0.1; 3],
                    rotation: [0.0, 0.0, 0.0, 1.0],
                    opacity: o,
                    sh0: [0.0; 3],
                },
                &[],
            );
        }
        s
    }

    #[test]
    fn blend_factor_follows_eq4_over_sse() {
        assert_eq!(blend_factor(10.0, 16.0), 0.0);
        assert_eq!(blend_factor(16.0, 16.0), 0.0);
        assert_eq!(blend_factor(24.0, 16.0), 0.5);
        assert_eq!(blend_factor(32.0, 16.0), 1.0);
        assert_eq!(blend_factor(1e9, 16.0), 1.0);
        assert_eq!(blend_factor(f64::NAN, 16.0), 0.0);
    }

    #[test]
    fn children_fade_their_parent_and_nest() {
        let base = splats(&[0.8, 0.5]);
        let a = splats(&[0.6]);
        let b = splats(&[0.4]);
        let g = splats(&[1.0]);
        let da = [-1.0f32, -0.25];
        let db = [0.0f32, -0.75];
        let dg = [-1.0f32];
        let layers = [
            DrawnLayer {
                splats: &base,
                parent: None,
                deltas: None,
                blend: 1.0,
                ancestors: &[],
            },
            DrawnLayer {
                splats: &a,
                parent: Some(0),
                deltas: Some(&da),
                blend: 0.5,
                ancestors: &[],
            },
            DrawnLayer {
                splats: &b,
                parent: Some(0),
                deltas: Some(&db),
                blend: 1.0,
                ancestors: &[],
            },
            DrawnLayer {
                splats: &g,
                parent: Some(1),
                deltas: Some(&dg),
                blend: 1.0,
                ancestors: &[],
            },
        ];
        let o = effective_opacities(&layers).unwrap();
        assert_eq!(o[0], vec![0.8 * 0.5, 0.5 * (1.0 - 0.125 - 0.75)]);
        // a is half blended in and fully faded by g; g inherits a's 0.5.
        assert_eq!(o[1], vec![0.0]);
        assert_eq!(o[2], vec![0.4]);
        assert_eq!(o[3], vec![0.5]);
        // Occupancy: a's faded splat is not drawn.
        let d = drawn_layers(&layers).unwrap();
        assert_eq!(d[1].len(), 0);
        assert_eq!(d[0].len(), 2);
        // Every child fully in: the base vanishes.
        let full = [
            layers[0],
            DrawnLayer {
                blend: 1.0,
                ..layers[1]
            },
            layers[2],
        ];
        let d = drawn_layers(&full).unwrap();
        assert_eq!(d[0].len(), 0);
    }

    #[test]
    fn ancestor_deltas_reproduce_each_level_and_eq4_between() {
        // LapisGS-like: a base splat at 0.2, raised to 0.5 by level 1 and 0.9 by level 2
        // (d = (o_k - o_{k-1}) / o_0), level 1 adds a splat at 0.6 lowered to 0.3 by level 2.
        let base = splats(&[0.2]);
        let l1 = splats(&[0.6]);
        let l2 = splats(&[0.7]);
        let d1 = [(0.5f32 - 0.2) / 0.2];
        let d2 = [(0.3f32 - 0.6) / 0.6];
        let d2_0 = [(0.9f32 - 0.5) / 0.2];
        let anc = [AncestorDelta {
            up: 2,
            deltas: &d2_0,
        }];
        let chain = |t1: f32, t2: f32| {
            let layers = [
                DrawnLayer {
                    splats: &base,
                    parent: None,
                    deltas: None,
                    blend: 1.0,
                    ancestors: &[],
                },
                DrawnLayer {
                    splats: &l1,
                    parent: Some(0),
                    deltas: Some(&d1),
                    blend: t1,
                    ancestors: &[],
                },
                DrawnLayer {
                    splats: &l2,
                    parent: Some(1),
                    deltas: Some(&d2),
                    blend: t2,
                    ancestors: &anc,
                },
            ];
            effective_opacities(&layers).unwrap()
        };
        let close = |a: f32, b: f32| assert!((a - b).abs() < 1e-6, "{a} vs {b}");
        let o = chain(1.0, 1.0);
        close(o[0][0], 0.9);
        close(o[1][0], 0.3);
        close(o[2][0], 0.7);
        // Level 2 half in: every changed opacity is the midpoint of levels 1 and 2 (eq. 4).
        let o = chain(1.0, 0.5);
        close(o[0][0], 0.7);
        close(o[1][0], 0.45);
        close(o[2][0], 0.35);
        // Level 2 not drawn: level 1 exactly.
        let o = chain(1.0, 0.0);
        close(o[0][0], 0.5);
        close(o[1][0], 0.6);
        // A delta raising past 1 is capped at T_L.
        let big = [10.0f32];
        let capped = [
            DrawnLayer {
                splats: &base,
                parent: None,
                deltas: None,
                blend: 1.0,
                ancestors: &[],
            },
            DrawnLayer {
                splats: &l1,
                parent: Some(0),
                deltas: Some(&big),
                blend: 1.0,
                ancestors: &[],
            },
        ];
        assert_eq!(effective_opacities(&capped).unwrap()[0], vec![1.0]);
        // An ancestor entry above the base, or a wrong count, is refused.
        let up3 = [AncestorDelta {
            up: 3,
            deltas: &d2_0,
        }];
        let short = [AncestorDelta { up: 2, deltas: &[] }];
        for (a, want) in [
            (&up3[..], ComposeError::BadAncestor(2)),
            (
                &short[..],
                ComposeError::DeltaCount {
                    layer: 2,
                    deltas: 0,
                    parent: 1,
                },
            ),
        ] {
            let layers = [
                capped[0],
                DrawnLayer {
                    deltas: Some(&d1),
                    ..capped[1]
                },
                DrawnLayer {
                    splats: &l2,
                    parent: Some(1),
                    deltas: Some(&d2),
                    blend: 1.0,
                    ancestors: a,
                },
            ];
            assert_eq!(effective_opacities(&layers), Err(want));
        }
    }

    #[test]
    fn mismatched_layers_are_refused() {
        let base = splats(&[0.8, 0.5]);
        let a = splats(&[0.6]);
        let bad = [
            DrawnLayer {
                splats: &base,
                parent: None,
                deltas: None,
                blend: 1.0,
                ancestors: &[],
            },
            DrawnLayer {
                splats: &a,
                parent: Some(0),
                deltas: Some(&[-1.0]),
                blend: 1.0,
                ancestors: &[],
            },
        ];
        assert_eq!(
            effective_opacities(&bad),
            Err(ComposeError::DeltaCount {
                layer: 1,
                deltas: 1,
                parent: 2
            })
        );
        let forward = [DrawnLayer {
            splats: &a,
            parent: Some(0),
            deltas: None,
            blend: 1.0,
            ancestors: &[],
        }];
        assert_eq!(
            effective_opacities(&forward),
            Err(ComposeError::BadParent(0))
        );
    }
}
