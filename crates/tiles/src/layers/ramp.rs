//! Time ramp of late layers: a layer whose data reaches the viewer after its blend factor is
//! already above 0 fades in over [`LAYER_RAMP_S`] instead of appearing at once.
//!
//! A viewer keeps one [`LayerRamp`] on its own clock: it notes when each drawable (scene id)
//! is first drawn and scales that layer's blend factor by [`ramp`] of the time since
//! (`spec/layered-content.md`, "Drawing"). The base layer ramps in the same way.

use std::collections::HashMap;

/// Seconds over which a newly drawn layer's blend factor ramps from 0 to its full value.
pub const LAYER_RAMP_S: f64 = 0.25;

/// Fraction of its blend factor a layer first drawn at `arrived_s` gets at `now_s` (seconds,
/// any clock): 0 at arrival and before, linear, 1 from `arrived_s + LAYER_RAMP_S`. A NaN time
/// (or infinite times that leave no difference) gives 1: a broken clock never hides a layer.
pub fn ramp(arrived_s: f64, now_s: f64) -> f32 {
    let dt = now_s - arrived_s;
    if dt.is_nan() {
        return 1.0;
    }
    (dt / LAYER_RAMP_S).clamp(0.0, 1.0) as f32
}

/// The arrival time of each drawn layer, on the viewer's clock.
#[derive(Debug, Clone, Default)]
pub struct LayerRamp {
    arrived: HashMap<u64, f64>,
}

impl LayerRamp {
    /// An empty record.
    pub fn new() -> Self {
        LayerRamp::default()
    }

    /// Notes the layers drawn at `now_s` (scene ids): a new id arrives now, an id no longer
    /// drawn is forgotten (drawn again later, it ramps again). Returns each id's ramp factor
    /// ([`ramp`]) in the order given.
    pub fn observe(&mut self, now_s: f64, ids: &[u64]) -> Vec<f32> {
        self.arrived.retain(|id, _| ids.contains(id));
        ids.iter()
            .map(|id| ramp(*self.arrived.entry(*id).or_insert(now_s), now_s))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ramp_starts_at_arrival_and_reaches_one_after_the_ramp() {
        assert_eq!(ramp(2.0, 1.0), 0.0);
        assert_eq!(ramp(2.0, 2.0), 0.0);
        assert!((ramp(2.0, 2.0 + LAYER_RAMP_S / 2.0) - 0.5).abs() < 1e-6);
        assert_eq!(ramp(2.0, 2.0 + LAYER_RAMP_S), 1.0);
        assert_eq!(ramp(2.0, 100.0), 1.0);
        // Negative clocks are ordinary times.
        assert!((ramp(-1.0, -1.0 + LAYER_RAMP_S / 4.0) - 0.25).abs() < 1e-6);
    }

    #[test]
    fn ramp_is_continuous_in_time() {
        // No step between samples 1 ms apart exceeds the slope's share (1 ms / 0.25 s).
        let mut prev = ramp(0.0, -0.5);
        for k in -499..1000 {
            let r = ramp(0.0, k as f64 * 1e-3);
            assert!(
                (r - prev).abs() <= (1e-3 / LAYER_RAMP_S) as f32 + 1e-6,
                "at {k} ms"
            );
            prev = r;
        }
    }

    #[test]
    fn broken_times_stay_finite() {
        for (a, n) in [
            (f64::NAN, 1.0),
            (0.0, f64::NAN),
            (f64::INFINITY, f64::INFINITY),
            (f64::NEG_INFINITY, 0.0),
            (0.0, f64::NEG_INFINITY),
            (-1e300, 1e300),
        ] {
            let r = ramp(a, n);
            assert!(r.is_finite() && (0.0..=1.0).contains(&r), "{a} {n}: {r}");
        }
        assert_eq!(ramp(f64::NAN, 1.0), 1.0);
        assert_eq!(ramp(f64::NEG_INFINITY, 0.0), 1.0);
        assert_eq!(ramp(0.0, f64::NEG_INFINITY), 0.0);
        let mut r = LayerRamp::new();
        assert_eq!(r.observe(f64::NAN, &[1]), vec![1.0]);
    }

    #[test]
    fn layers_ramp_from_their_first_drawn_frame() {
        let mut r = LayerRamp::new();
        assert_eq!(r.observe(10.0, &[1]), vec![0.0]);
        // Layer 2 arrives later; 1 keeps its own arrival.
        let f = r.observe(10.1, &[1, 2]);
        assert!((f[0] - 0.4).abs() < 1e-5 && f[1] == 0.0, "{f:?}");
        let f = r.observe(10.0 + LAYER_RAMP_S, &[1, 2]);
        assert!(f[0] == 1.0 && (f[1] - 0.6).abs() < 1e-5, "{f:?}");
        let f = r.observe(11.0, &[1, 2]);
        assert_eq!(f, vec![1.0, 1.0]);
        // Dropped, then drawn again: it ramps again from its new arrival.
        r.observe(11.5, &[2]);
        assert_eq!(r.observe(12.0, &[1, 2]), vec![0.0, 1.0]);
    }
}
