//! What a viewer draws from layers: each layer's splats at their effective opacity (the
//! stored one, times the layer's blend factor, faded by its drawn child layers' deltas), the
//! occupancy rule, and the blend factor of LapisGS eq. 4 taken from the screen-space error.

use super::OCCUPANCY_THRESHOLD;
use crate::splat::Splats;

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
}

/// Why layers cannot be composed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ComposeError {
    /// A parent index does not point at an earlier layer.
    #[error("layer {0}: its parent must be an earlier layer")]
    BadParent(usize),
    /// A layer with a parent has no deltas, or their count is not the parent's splat count.
    #[error("layer {layer}: {deltas} deltas for a parent of {parent} splats")]
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
/// `T_L * o_i * max(0, 1 + sum over drawn child layers c of t_c * delta_c[i])`.
pub fn effective_opacities(layers: &[DrawnLayer<'_>]) -> Result<Vec<Vec<f32>>, ComposeError> {
    let mut cumulative = vec![1.0f32; layers.len()];
    let mut fade: Vec<Vec<f32>> = layers.iter().map(|l| vec![1.0; l.splats.len()]).collect();
    for (k, l) in layers.iter().enumerate() {
        let t = if l.blend.is_finite() {
            l.blend.clamp(0.0, 1.0)
        } else {
            0.0
        };
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
                    *f += t * if di.is_finite() {
                        di.clamp(-1.0, 0.0)
                    } else {
                        0.0
                    };
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
                .map(|(&o, f)| c * o * f.max(0.0))
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
    use crate::splat::Splat;

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
            },
            DrawnLayer {
                splats: &a,
                parent: Some(0),
                deltas: Some(&da),
                blend: 0.5,
            },
            DrawnLayer {
                splats: &b,
                parent: Some(0),
                deltas: Some(&db),
                blend: 1.0,
            },
            DrawnLayer {
                splats: &g,
                parent: Some(1),
                deltas: Some(&dg),
                blend: 1.0,
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
    fn mismatched_layers_are_refused() {
        let base = splats(&[0.8, 0.5]);
        let a = splats(&[0.6]);
        let bad = [
            DrawnLayer {
                splats: &base,
                parent: None,
                deltas: None,
                blend: 1.0,
            },
            DrawnLayer {
                splats: &a,
                parent: Some(0),
                deltas: Some(&[-1.0]),
                blend: 1.0,
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
        }];
        assert_eq!(
            effective_opacities(&forward),
            Err(ComposeError::BadParent(0))
        );
    }
}
