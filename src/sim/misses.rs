//! Why first-time entries missed: each needed tile that entered the view for the first time
//! without being held is put in one cause class from the session's ticks and request log.
//!
//! Causes, first match wins: `evicted` (held at an earlier tick), `in_flight` (a request for it
//! was open at the entry: the lead time is reported), `refused` (a download of it completed
//! before the entry but it was never held), `late` (first requested after the entry) or `never`.
//! Apart from the cause, an entry is `outside_client_view` when the client's own view set at
//! that tick lacks the tile (culling or unread subtrees), and `ancestor_held` when a coarser tile
//! above it was held (what draws in its place).

use std::collections::{HashMap, HashSet};

use crate::tiling::TileKey;

use super::score::TickView;
use super::session::SessionLog;

/// Counts of missed first-time entries by cause (see the module docs).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MissBreakdown {
    /// First-time entries (after the first tick).
    pub entries: u64,
    /// Of them, misses.
    pub misses: u64,
    /// Held at an earlier tick, gone at the entry.
    pub evicted: u64,
    /// A request was open at the entry.
    pub in_flight: u64,
    /// Seconds from the open request's start to the entry, one per `in_flight` miss.
    pub in_flight_lead_s: Vec<f64>,
    /// Downloaded before the entry but never held (memory refusal).
    pub refused: u64,
    /// First requested after the entry.
    pub late: u64,
    /// Seconds from the entry to the first request, one per `late` miss.
    pub late_delay_s: Vec<f64>,
    /// Never requested.
    pub never: u64,
    /// Entry time of every miss (s).
    pub at_s: Vec<f64>,
    /// Misses whose tile was not in the client's own view set at that tick.
    pub outside_client_view: u64,
    /// Misses with a coarser ancestor held.
    pub ancestor_held: u64,
}

impl MissBreakdown {
    /// Adds another session's counts.
    pub fn add(&mut self, o: &MissBreakdown) {
        self.entries += o.entries;
        self.misses += o.misses;
        self.evicted += o.evicted;
        self.in_flight += o.in_flight;
        self.in_flight_lead_s.extend(&o.in_flight_lead_s);
        self.refused += o.refused;
        self.late += o.late;
        self.late_delay_s.extend(&o.late_delay_s);
        self.never += o.never;
        self.at_s.extend(&o.at_s);
        self.outside_client_view += o.outside_client_view;
        self.ancestor_held += o.ancestor_held;
    }
}

/// Classifies the missed first-time entries of `log` scored on `ticks` (one per log tick, same
/// order; the entry rules of [`super::score::cache_hits`]).
pub fn breakdown(log: &SessionLog, ticks: &[TickView]) -> MissBreakdown {
    let mut requests: HashMap<TileKey, Vec<(f64, Option<f64>)>> = HashMap::new();
    for r in &log.requests {
        if let Some(k) = r.key {
            requests.entry(k).or_default().push((r.start_s, r.end_s));
        }
    }
    let mut out = MissBreakdown::default();
    let mut ever_needed: HashSet<TileKey> = HashSet::new();
    let mut ever_held: HashSet<TileKey> = HashSet::new();
    let mut prev: HashSet<TileKey> = HashSet::new();
    let mut started = false;
    for (tick, tl) in ticks.iter().zip(&log.ticks) {
        let held: HashSet<TileKey> = tick.resident.iter().copied().collect();
        let now: HashSet<TileKey> = tick.needed.iter().copied().collect();
        for &key in &now {
            if prev.contains(&key) || !started || ever_needed.contains(&key) {
                continue;
            }
            out.entries += 1;
            if held.contains(&key) {
                continue;
            }
            out.misses += 1;
            let t = tick.t;
            out.at_s.push(t);
            let reqs = requests.get(&key).map_or(&[][..], |v| v.as_slice());
            if ever_held.contains(&key) {
                out.evicted += 1;
            } else if let Some(&(s, _)) = reqs
                .iter()
                .find(|(s, e)| *s <= t && e.is_none_or(|e| e > t))
            {
                out.in_flight += 1;
                out.in_flight_lead_s.push(t - s);
            } else if reqs.iter().any(|(s, e)| *s <= t && e.is_some()) {
                out.refused += 1;
            } else if let Some(&(s, _)) = reqs.iter().find(|(s, _)| *s > t) {
                out.late += 1;
                out.late_delay_s.push(s - t);
            } else {
                out.never += 1;
            }
            if !tl.view_set.contains(&key) {
                out.outside_client_view += 1;
            }
            let mut a = key.parent();
            while let Some(p) = a {
                if held.contains(&p) {
                    out.ancestor_held += 1;
                    break;
                }
                a = p.parent();
            }
        }
        started |= !now.is_empty();
        ever_needed.extend(now.iter().copied());
        ever_held.extend(held.iter().copied());
        prev = now;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::session::{RequestLog, TickLog};
    use crate::sim::transport::Outcome;
    use crate::stream::geom::ViewPose;
    use glam::DVec3;

    fn key(x: u32) -> TileKey {
        TileKey {
            level: 3,
            x,
            y: 0,
            z: 0,
        }
    }

    fn tick(t: f64, view_set: &[TileKey]) -> TickLog {
        TickLog {
            t,
            pose: ViewPose {
                t,
                pos: DVec3::ZERO,
                yaw: 0.0,
                pitch: 0.0,
            },
            view_set: view_set.to_vec(),
            resident: vec![],
            drawn: vec![],
            layers: vec![],
            bytes_down: 0,
            wire_bytes: 0,
            bandwidth_estimate: 0.0,
            cache_bytes: 0,
            in_flight: 0,
            plans: 0,
        }
    }

    fn req(k: TileKey, start_s: f64, end_s: Option<f64>) -> RequestLog {
        RequestLog {
            key: Some(k),
            level: None,
            url: String::new(),
            range_start: 0,
            start_s,
            end_s,
            bytes: 0,
            outcome: Outcome::Done,
        }
    }

    #[test]
    fn each_missed_first_entry_gets_one_cause() {
        let k: Vec<TileKey> = (0..6).map(key).collect();
        // t0: k0 (cold start, not scored). t1: k1..k5 enter; k0 is held from t0 on.
        let needed0 = [k[0]];
        let needed1 = [k[0], k[1], k[2], k[3], k[4], k[5]];
        let held0 = [k[0], k[1]];
        let held1 = [k[0], TileKey::ROOT];
        let log = SessionLog {
            ticks: vec![tick(0.0, &needed0), tick(1.0, &[k[0], k[1], k[2]])],
            requests: vec![
                req(k[1], 0.0, Some(0.5)), // held at t0, gone at t1: evicted
                req(k[2], 0.7, None),      // open at t1: in flight, lead 0.3
                req(k[3], 0.2, Some(0.6)), // done before t1, never held: refused
                req(k[4], 1.5, Some(2.0)), // asked 0.5 s after the entry: late
            ],
            ..SessionLog::default()
        };
        let views = [
            TickView {
                t: 0.0,
                needed: &needed0,
                resident: &held0,
            },
            TickView {
                t: 1.0,
                needed: &needed1,
                resident: &held1,
            },
        ];
        let b = breakdown(&log, &views);
        assert_eq!((b.entries, b.misses), (5, 5));
        assert_eq!(
            (b.evicted, b.in_flight, b.refused, b.late, b.never),
            (1, 1, 1, 1, 1)
        );
        assert!((b.in_flight_lead_s[0] - 0.3).abs() < 1e-12);
        assert!((b.late_delay_s[0] - 0.5).abs() < 1e-12);
        // k3, k4, k5 are not in the client's view set at t1; the root is above every miss.
        assert_eq!((b.outside_client_view, b.ancestor_held), (3, 5));
        assert_eq!(b.at_s, vec![1.0; 5]);
    }
}
