//! Why first-time entries missed: each needed tile that entered the view for the first time
//! without being held is put in one cause class from the session's ticks and request log.
//!
//! Causes, first match wins: `evicted` (held at an earlier tick), `in_flight` (a request for it
//! was open at the entry: the lead time is reported), `aborted` (requested before the entry, every
//! such request aborted or failed), `refused` (a download of it completed before the entry but it
//! was never held), `late` (first requested after the entry) or `never`.
//! Apart from the cause, an entry is `outside_client_view` when the client's own view set at
//! that tick lacks the tile (culling or unread subtrees), and `ancestor_held` when a coarser tile
//! above it was held (what draws in its place); each miss is also listed ([`Miss`]) with whether
//! a plan before the entry wanted it, when that plan said it was due, and how many ticks the
//! tile stayed needed.

use std::collections::{HashMap, HashSet};

use splat2tiles_tiles::tiling::TileKey;

use super::score::{TickView, WarmUp};
use super::session::SessionLog;
use super::transport::Outcome;

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
    /// Requested before the entry, every such request aborted or failed.
    pub aborted: u64,
    /// First-time entries after the warm-up (the rule of [`super::score::Chr::warm`]).
    pub warm_entries: u64,
    /// Every miss, in entry order.
    pub list: Vec<Miss>,
}

/// Why a first-time entry missed (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Cause {
    /// Held at an earlier tick, gone at the entry.
    Evicted,
    /// A request was open at the entry.
    InFlight,
    /// Requested before the entry; aborted or failed.
    Aborted,
    /// Downloaded before the entry, never held.
    Refused,
    /// First requested after the entry.
    Late,
    /// Never requested.
    Never,
}

/// One missed first-time entry.
#[derive(Debug, Clone, PartialEq)]
pub struct Miss {
    /// Entry time (s).
    pub t: f64,
    /// The tile.
    pub key: TileKey,
    /// Why.
    pub cause: Cause,
    /// After the warm-up.
    pub warm: bool,
    /// The due time the last plan before the entry that wanted the tile gave it (None: no plan
    /// before the entry wanted it).
    pub planned_due: Option<f64>,
    /// When a plan first wanted the tile (None: none before the entry).
    pub first_planned: Option<f64>,
    /// The first-seen time the last plan before the entry whose predicted views held the tile
    /// gave it (None: no predicted view before the entry held it).
    pub predicted_at: Option<f64>,
    /// The first request's start (any time).
    pub first_request: Option<f64>,
    /// Ticks the tile stayed in the needed cut from the entry on.
    pub dwell_ticks: usize,
    /// In the client's own view set at the entry.
    pub in_client_view: bool,
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
        self.aborted += o.aborted;
        self.warm_entries += o.warm_entries;
        self.list.extend(o.list.iter().cloned());
    }
}

/// Classifies the missed first-time entries of `log` scored on `ticks` (one per log tick, same
/// order; the entry rules of [`super::score::cache_hits`]).
pub fn breakdown(log: &SessionLog, ticks: &[TickView]) -> MissBreakdown {
    breakdown_with(log, ticks, WarmUp::CutHeld)
}

/// [`breakdown`] with the given end of the warm-up ([`Miss::warm`], `warm_entries`).
pub fn breakdown_with(log: &SessionLog, ticks: &[TickView], warm_up: WarmUp) -> MissBreakdown {
    let mut requests: HashMap<TileKey, Vec<(f64, Option<f64>, Outcome)>> = HashMap::new();
    for r in &log.requests {
        if let Some(k) = r.key {
            requests
                .entry(k)
                .or_default()
                .push((r.start_s, r.end_s, r.outcome));
        }
    }
    let sets: Vec<HashSet<TileKey>> = ticks
        .iter()
        .map(|t| t.needed.iter().copied().collect())
        .collect();
    let mut out = MissBreakdown::default();
    let mut ever_needed: HashSet<TileKey> = HashSet::new();
    let mut ever_held: HashSet<TileKey> = HashSet::new();
    let mut planned: HashMap<TileKey, f64> = HashMap::new();
    let mut first_planned: HashMap<TileKey, f64> = HashMap::new();
    let mut predicted: HashMap<TileKey, f64> = HashMap::new();
    let empty = HashSet::new();
    let mut started = false;
    let mut warm = false;
    for (j, (tick, tl)) in ticks.iter().zip(&log.ticks).enumerate() {
        let held: HashSet<TileKey> = tick.resident.iter().copied().collect();
        let now = &sets[j];
        let prev = if j > 0 { &sets[j - 1] } else { &empty };
        for &key in now {
            if prev.contains(&key) || !started || ever_needed.contains(&key) {
                continue;
            }
            let warm = match warm_up {
                WarmUp::CutHeld => warm,
                WarmUp::At(at) => tick.t > at,
            };
            out.entries += 1;
            out.warm_entries += warm as u64;
            if held.contains(&key) {
                continue;
            }
            out.misses += 1;
            let t = tick.t;
            out.at_s.push(t);
            let reqs = requests.get(&key).map_or(&[][..], |v| v.as_slice());
            let before: Vec<&(f64, Option<f64>, Outcome)> =
                reqs.iter().filter(|(s, _, _)| *s <= t).collect();
            let cause = if ever_held.contains(&key) {
                Cause::Evicted
            } else if let Some(&&(s, _, _)) =
                before.iter().find(|(_, e, _)| e.is_none_or(|e| e > t))
            {
                out.in_flight_lead_s.push(t - s);
                Cause::InFlight
            } else if before.iter().any(|(_, _, o)| *o == Outcome::Done) {
                Cause::Refused
            } else if !before.is_empty() {
                Cause::Aborted
            } else if let Some(&(s, _, _)) = reqs.iter().find(|(s, _, _)| *s > t) {
                out.late_delay_s.push(s - t);
                Cause::Late
            } else {
                Cause::Never
            };
            match cause {
                Cause::Evicted => out.evicted += 1,
                Cause::InFlight => out.in_flight += 1,
                Cause::Aborted => out.aborted += 1,
                Cause::Refused => out.refused += 1,
                Cause::Late => out.late += 1,
                Cause::Never => out.never += 1,
            }
            let in_client_view = tl.view_set.contains(&key);
            if !in_client_view {
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
            let dwell_ticks = sets[j..].iter().take_while(|s| s.contains(&key)).count();
            out.list.push(Miss {
                t,
                key,
                cause,
                warm,
                planned_due: planned.get(&key).copied(),
                first_planned: first_planned.get(&key).copied(),
                predicted_at: predicted.get(&key).copied(),
                first_request: reqs.iter().map(|r| r.0).reduce(f64::min),
                dwell_ticks,
                in_client_view,
            });
        }
        warm |= started && !now.is_empty() && now.iter().all(|k| held.contains(k));
        started |= !now.is_empty();
        ever_needed.extend(now.iter().copied());
        ever_held.extend(held.iter().copied());
        // The plan as the client left it at this tick counts for later entries only.
        for &(k, due) in &tl.planned {
            planned.insert(k, due);
            first_planned.entry(k).or_insert(tl.t);
        }
        predicted.extend(tl.predicted.iter().copied());
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::session::{RequestLog, TickLog};
    use glam::DVec3;
    use splat2tiles_stream::geom::ViewPose;

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
            planned: vec![],
            predicted: vec![],
            last_plan_s: 0.0,
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
        let k: Vec<TileKey> = (0..7).map(key).collect();
        // t0: k0 (cold start, not scored). t1: k1..k6 enter; k0 is held from t0 on. The plan
        // left at t0 wants k4 due at 0.8 s; at t2 only k0 and k5 are still needed.
        let needed0 = [k[0]];
        let needed1 = [k[0], k[1], k[2], k[3], k[4], k[5], k[6]];
        let needed2 = [k[0], k[5]];
        let held0 = [k[0], k[1]];
        let held1 = [k[0], TileKey::ROOT];
        let mut t0 = tick(0.0, &needed0);
        t0.planned = vec![(k[4], 0.8)];
        t0.predicted = vec![(k[4], 0.9)];
        let mut aborted = req(k[6], 0.1, Some(0.3)); // requested before, aborted
        aborted.outcome = Outcome::Aborted;
        let log = SessionLog {
            ticks: vec![t0, tick(1.0, &[k[0], k[1], k[2]]), tick(2.0, &[k[0]])],
            requests: vec![
                req(k[1], 0.0, Some(0.5)), // held at t0, gone at t1: evicted
                req(k[2], 0.7, None),      // open at t1: in flight, lead 0.3
                req(k[3], 0.2, Some(0.6)), // done before t1, never held: refused
                req(k[4], 1.5, Some(2.0)), // asked 0.5 s after the entry: late
                aborted,
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
            TickView {
                t: 2.0,
                needed: &needed2,
                resident: &held1,
            },
        ];
        let b = breakdown(&log, &views);
        assert_eq!((b.entries, b.misses), (6, 6));
        assert_eq!(
            (
                b.evicted,
                b.in_flight,
                b.aborted,
                b.refused,
                b.late,
                b.never
            ),
            (1, 1, 1, 1, 1, 1)
        );
        assert!((b.in_flight_lead_s[0] - 0.3).abs() < 1e-12);
        assert!((b.late_delay_s[0] - 0.5).abs() < 1e-12);
        // k3..k6 are not in the client's view set at t1; the root is above every miss.
        assert_eq!((b.outside_client_view, b.ancestor_held), (4, 6));
        assert_eq!(b.at_s, vec![1.0; 6]);
        // Warm from t1 on (the cut of t0 was held), so the entries of t1 are not warm ones.
        assert_eq!(b.warm_entries, 0);
        let m = |x: TileKey| b.list.iter().find(|m| m.key == x).unwrap();
        assert_eq!(m(k[4]).cause, Cause::Late);
        assert_eq!(m(k[4]).planned_due, Some(0.8));
        assert_eq!(m(k[4]).first_planned, Some(0.0));
        assert_eq!(m(k[4]).first_request, Some(1.5));
        assert_eq!(m(k[4]).predicted_at, Some(0.9));
        assert_eq!((m(k[3]).planned_due, m(k[3]).predicted_at), (None, None));
        assert_eq!((m(k[5]).dwell_ticks, m(k[3]).dwell_ticks), (2, 1));
        assert_eq!(m(k[6]).cause, Cause::Aborted);
        assert!(m(k[2]).in_client_view && !m(k[5]).in_client_view);
    }
}
