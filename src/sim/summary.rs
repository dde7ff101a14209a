//! Summaries of a [`SessionLog`]: cache hits over first-time view entries and wasted downloads,
//! read from what the real client needed, held and fetched (the tables of `simulate`).

use std::collections::{BTreeMap, BTreeSet};

use super::session::SessionLog;
use super::transport::Outcome;
use crate::tiling::TileKey;

/// Totals of one session.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Summary {
    /// Tiles entering the view set for the first time after the first view (the cold start,
    /// when the first view set appears, is counted apart).
    pub entries: usize,
    /// Of those, resident at the tick they entered.
    pub hits: usize,
    /// Tiles of the first view set.
    pub first_view_tiles: usize,
    /// Re-entries (a tile coming back into the view set).
    pub reentries: usize,
    /// Of those, resident.
    pub reentry_hits: usize,
    /// Completed content downloads.
    pub fetched: usize,
    /// Of those, whose tile is never in the view set from their end on.
    pub wasted: usize,
    /// Body bytes of the completed content downloads.
    pub fetched_bytes: u64,
    /// Of those, wasted.
    pub wasted_bytes: u64,
    /// Body bytes delivered over the session.
    pub bytes_down: u64,
}

impl Summary {
    /// Cache hit rate over first-time entries (1 when there were none).
    pub fn chr(&self) -> f64 {
        ratio(self.hits, self.entries)
    }
    /// Wasted share of completed downloads, in tiles.
    pub fn wd_tiles(&self) -> f64 {
        if self.fetched == 0 {
            0.0
        } else {
            self.wasted as f64 / self.fetched as f64
        }
    }
    /// Wasted share of completed downloads, in bytes.
    pub fn wd_bytes(&self) -> f64 {
        if self.fetched_bytes == 0 {
            0.0
        } else {
            self.wasted_bytes as f64 / self.fetched_bytes as f64
        }
    }
}

fn ratio(a: usize, b: usize) -> f64 {
    if b == 0 { 1.0 } else { a as f64 / b as f64 }
}

/// Summarises a session (see [`Summary`]).
pub fn summarize(log: &SessionLog) -> Summary {
    let mut s = Summary::default();
    let mut seen: BTreeSet<TileKey> = BTreeSet::new();
    let mut prev: BTreeSet<TileKey> = BTreeSet::new();
    let mut started = false;
    // Last tick time each tile is in the view set.
    let mut last_in_view: BTreeMap<TileKey, f64> = BTreeMap::new();
    for tick in &log.ticks {
        let resident: BTreeSet<TileKey> = tick.resident.iter().map(|r| r.0).collect();
        let now: BTreeSet<TileKey> = tick.view_set.iter().copied().collect();
        for k in &now {
            last_in_view.insert(*k, tick.t);
            if prev.contains(k) {
                continue;
            }
            if !started {
                s.first_view_tiles += 1;
            } else if seen.contains(k) {
                s.reentries += 1;
                s.reentry_hits += resident.contains(k) as usize;
            } else {
                s.entries += 1;
                s.hits += resident.contains(k) as usize;
            }
        }
        started |= !now.is_empty();
        seen.extend(now.iter().copied());
        prev = now;
    }
    for r in &log.requests {
        let (Some(key), Outcome::Done, Some(end)) = (r.key, r.outcome, r.end_s) else {
            continue;
        };
        s.fetched += 1;
        s.fetched_bytes += r.bytes;
        if last_in_view.get(&key).is_none_or(|&t| t < end) {
            s.wasted += 1;
            s.wasted_bytes += r.bytes;
        }
    }
    s.bytes_down = log.ticks.last().map_or(0, |t| t.bytes_down);
    s
}
