//! The scene model every stage shares: Gaussians in structure-of-arrays form, with f64 centres
//! and f32 attributes already in the KHR_gaussian_splatting conventions (linear scale, opacity in
//! `[0, 1]`, unit quaternion x,y,z,w, SH coefficients per coefficient as RGB).

pub mod importance;
pub mod sh;

/// Highest spherical-harmonic degree the model carries (glTF and the trainer stop at 3).
pub const MAX_SH_DEGREE: u8 = 3;

/// Selections of at least this many splats are gathered on every core.
const SELECT_PARALLEL: usize = 1 << 16;

/// Number of non-DC SH coefficients (per colour channel) for a degree: 0, 3, 8 or 15.
pub const fn sh_rest_count(degree: u8) -> usize {
    let d = degree as usize;
    (d + 1) * (d + 1) - 1
}

/// A set of Gaussians in one coordinate frame (the frame of the file they came from, until the
/// converter moves them).
///
/// Conventions (those of `KHR_gaussian_splatting`):
/// - `scales`: linear standard deviations along the local axes, non-negative;
/// - `rotations`: unit quaternions `[x, y, z, w]`;
/// - `opacities`: after the sigmoid, in `[0, 1]`;
/// - `sh0`: the DC SH coefficient per channel (colour = 0.2820948 * sh0 + 0.5);
/// - `sh_rest`: `sh_rest_count(sh_degree)` RGB triples per splat, splat-major, coefficients in
///   glTF order (degree 1 m=-1,0,1, then degree 2 m=-2..2, then degree 3 m=-3..3).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Splats {
    /// Centres, f64 so that georeferenced and large scenes keep their precision.
    pub positions: Vec<[f64; 3]>,
    /// Linear scales (standard deviations) along the Gaussian's local axes.
    pub scales: Vec<[f32; 3]>,
    /// Unit quaternions, `[x, y, z, w]`.
    pub rotations: Vec<[f32; 4]>,
    /// Opacity after the sigmoid, in `[0, 1]`.
    pub opacities: Vec<f32>,
    /// DC spherical-harmonic coefficient per channel (RGB).
    pub sh0: Vec<[f32; 3]>,
    /// SH degree of the higher coefficients, 0..=3.
    pub sh_degree: u8,
    /// Higher SH coefficients: `sh_rest_count(sh_degree)` RGB triples per splat.
    pub sh_rest: Vec<[f32; 3]>,
}

/// One splat by value, for building scenes and for tests.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Splat {
    /// Centre.
    pub position: [f64; 3],
    /// Linear scale.
    pub scale: [f32; 3],
    /// Unit quaternion `[x, y, z, w]`.
    pub rotation: [f32; 4],
    /// Opacity in `[0, 1]`.
    pub opacity: f32,
    /// DC SH coefficient.
    pub sh0: [f32; 3],
}

impl Splats {
    /// An empty set with the given SH degree.
    pub fn new(sh_degree: u8) -> Self {
        assert!(sh_degree <= MAX_SH_DEGREE, "SH degree above 3");
        Splats {
            sh_degree,
            ..Default::default()
        }
    }

    /// An empty set with room for `n` splats.
    pub fn with_capacity(sh_degree: u8, n: usize) -> Self {
        assert!(sh_degree <= MAX_SH_DEGREE, "SH degree above 3");
        let rest = sh_rest_count(sh_degree);
        Splats {
            positions: Vec::with_capacity(n),
            scales: Vec::with_capacity(n),
            rotations: Vec::with_capacity(n),
            opacities: Vec::with_capacity(n),
            sh0: Vec::with_capacity(n),
            sh_degree,
            sh_rest: Vec::with_capacity(n * rest),
        }
    }

    /// Number of splats.
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// True when there is no splat.
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// Higher SH triples per splat.
    pub fn rest_per_splat(&self) -> usize {
        sh_rest_count(self.sh_degree)
    }

    /// The higher SH triples of splat `i`.
    pub fn rest_of(&self, i: usize) -> &[[f32; 3]] {
        let k = self.rest_per_splat();
        &self.sh_rest[i * k..(i + 1) * k]
    }

    /// Splat `i` without its higher SH.
    pub fn get(&self, i: usize) -> Splat {
        Splat {
            position: self.positions[i],
            scale: self.scales[i],
            rotation: self.rotations[i],
            opacity: self.opacities[i],
            sh0: self.sh0[i],
        }
    }

    /// Appends one splat; `rest` must hold `rest_per_splat()` triples.
    pub fn push(&mut self, s: Splat, rest: &[[f32; 3]]) {
        assert_eq!(
            rest.len(),
            self.rest_per_splat(),
            "wrong number of SH triples"
        );
        self.positions.push(s.position);
        self.scales.push(s.scale);
        self.rotations.push(s.rotation);
        self.opacities.push(s.opacity);
        self.sh0.push(s.sh0);
        self.sh_rest.extend_from_slice(rest);
    }

    /// Appends splat `i` of `other` (same SH degree).
    pub fn push_from(&mut self, other: &Splats, i: usize) {
        assert_eq!(self.sh_degree, other.sh_degree, "SH degrees differ");
        self.push(other.get(i), other.rest_of(i));
    }

    /// A new set holding the splats at `indices`, in that order (gathered column by column,
    /// on every core when large).
    pub fn select(&self, indices: &[usize]) -> Splats {
        use rayon::prelude::*;
        fn gather<T: Copy + Send + Sync>(src: &[T], indices: &[usize]) -> Vec<T> {
            if indices.len() >= SELECT_PARALLEL {
                let mut out = Vec::with_capacity(indices.len());
                indices
                    .par_iter()
                    .with_min_len(SELECT_PARALLEL / 4)
                    .map(|&i| src[i])
                    .collect_into_vec(&mut out);
                out
            } else {
                indices.iter().map(|&i| src[i]).collect()
            }
        }
        let k = self.rest_per_splat();
        let sh_rest = if k == 0 {
            Vec::new()
        } else {
            let mut out = Vec::with_capacity(indices.len() * k);
            for &i in indices {
                out.extend_from_slice(&self.sh_rest[i * k..(i + 1) * k]);
            }
            out
        };
        Splats {
            positions: gather(&self.positions, indices),
            scales: gather(&self.scales, indices),
            rotations: gather(&self.rotations, indices),
            opacities: gather(&self.opacities, indices),
            sh0: gather(&self.sh0, indices),
            sh_degree: self.sh_degree,
            sh_rest,
        }
    }

    /// Panics unless every array has the length the splat count implies (a programming error).
    pub fn check_lengths(&self) {
        let n = self.len();
        assert_eq!(self.scales.len(), n);
        assert_eq!(self.rotations.len(), n);
        assert_eq!(self.opacities.len(), n);
        assert_eq!(self.sh0.len(), n);
        assert_eq!(self.sh_rest.len(), n * self.rest_per_splat());
    }

    /// True when every value of splat `i` is finite.
    pub fn is_finite(&self, i: usize) -> bool {
        self.positions[i].iter().all(|v| v.is_finite())
            && self.scales[i].iter().all(|v| v.is_finite())
            && self.rotations[i].iter().all(|v| v.is_finite())
            && self.opacities[i].is_finite()
            && self.sh0[i].iter().all(|v| v.is_finite())
            && self.rest_of(i).iter().flatten().all(|v| v.is_finite())
    }

    /// Index of the first splat holding a NaN or infinite value, if any.
    pub fn first_non_finite(&self) -> Option<usize> {
        // Every value finite (what a tile writer is given): whole columns at a time, without
        // the per-splat early exits; only otherwise the splat is looked for.
        let all = |v: &[f32]| v.iter().fold(true, |ok, x| ok & x.is_finite());
        let finite = self
            .positions
            .iter()
            .flatten()
            .fold(true, |ok, x| ok & x.is_finite())
            && all(self.scales.as_flattened())
            && all(self.rotations.as_flattened())
            && all(&self.opacities)
            && all(self.sh0.as_flattened())
            && all(self.sh_rest.as_flattened());
        if finite {
            return None;
        }
        (0..self.len()).find(|&i| !self.is_finite(i))
    }

    /// Removes every splat holding a NaN or infinite value; returns how many were removed.
    pub fn drop_non_finite(&mut self) -> usize {
        let keep: Vec<usize> = (0..self.len()).filter(|&i| self.is_finite(i)).collect();
        let dropped = self.len() - keep.len();
        if dropped > 0 {
            *self = self.select(&keep);
        }
        dropped
    }

    /// Axis-aligned bounds of the centres, `None` when empty.
    pub fn bounds(&self) -> Option<([f64; 3], [f64; 3])> {
        let first = *self.positions.first()?;
        let mut lo = first;
        let mut hi = first;
        for p in &self.positions {
            for a in 0..3 {
                lo[a] = lo[a].min(p[a]);
                hi[a] = hi[a].max(p[a]);
            }
        }
        Some((lo, hi))
    }
}

/// Normalises a quaternion `[x, y, z, w]`; a zero or non-finite one becomes the identity.
pub fn normalize_quat(q: [f32; 4]) -> [f32; 4] {
    let n2 = q.iter().map(|v| (*v as f64) * (*v as f64)).sum::<f64>();
    if !(n2.is_finite() && n2 > 0.0) {
        return [0.0, 0.0, 0.0, 1.0];
    }
    let inv = 1.0 / n2.sqrt();
    [
        (q[0] as f64 * inv) as f32,
        (q[1] as f64 * inv) as f32,
        (q[2] as f64 * inv) as f32,
        (q[3] as f64 * inv) as f32,
    ]
}

/// The logistic sigmoid, stable for large |x|.
pub fn sigmoid(x: f32) -> f32 {
    if x >= 0.0 {
        1.0 / (1.0 + (-x).exp())
    } else {
        let e = x.exp();
        e / (1.0 + e)
    }
}

/// Inverse of [`sigmoid`], clamped so that 0 and 1 map to finite logits.
pub fn logit(p: f32) -> f32 {
    let p = p.clamp(1e-7, 1.0 - 1e-7) as f64;
    (p / (1.0 - p)).ln() as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rest_counts() {
        assert_eq!(
            [0, 1, 2, 3].map(sh_rest_count),
            [0, 3, 8, 15],
            "SH rest counts per degree"
        );
    }

    #[test]
    fn sigmoid_logit_stable_at_extremes() {
        for x in [-1e30f32, -100.0, -1.0, 0.0, 1.0, 100.0, 1e30] {
            let s = sigmoid(x);
            assert!(s.is_finite() && (0.0..=1.0).contains(&s), "{x} -> {s}");
        }
        for p in [0.0f32, 1e-9, 0.25, 0.5, 0.99, 1.0] {
            assert!(logit(p).is_finite());
        }
        assert!((sigmoid(logit(0.3)) - 0.3).abs() < 1e-6);
    }

    #[test]
    fn normalize_degenerate_quats() {
        assert_eq!(normalize_quat([0.0; 4]), [0.0, 0.0, 0.0, 1.0]);
        assert_eq!(
            normalize_quat([f32::NAN, 0.0, 0.0, 1.0]),
            [0.0, 0.0, 0.0, 1.0]
        );
        let q = normalize_quat([0.0, 0.0, 0.0, -2.0]);
        assert_eq!(q, [0.0, 0.0, 0.0, -1.0]);
        let q = normalize_quat([1e-20, 0.0, 0.0, 0.0]);
        assert!(
            (q[0] - 1.0).abs() < 1e-6,
            "tiny but non-zero quats normalise: {q:?}"
        );
    }

    #[test]
    fn drop_non_finite_counts_and_keeps_order() {
        let mut s = Splats::new(1);
        let base = Splat {
            position: [0.0; 3],
            scale: [1.0; 3],
            rotation: [0.0, 0.0, 0.0, 1.0],
            opacity: 0.5,
            sh0: [0.1; 3],
        };
        for i in 0..5 {
            let mut b = base;
            b.position[0] = i as f64;
            let mut rest = [[0.0f32; 3]; 3];
            if i == 3 {
                rest[2][1] = f32::INFINITY;
            }
            if i == 1 {
                b.opacity = f32::NAN;
            }
            s.push(b, &rest);
        }
        assert_eq!(s.first_non_finite(), Some(1));
        assert_eq!(s.drop_non_finite(), 2);
        s.check_lengths();
        let xs: Vec<f64> = s.positions.iter().map(|p| p[0]).collect();
        assert_eq!(xs, vec![0.0, 2.0, 4.0]);
    }
}
