//! Summaries of a [`SessionLog`]: cache hits over first-time view entries and wasted downloads,
//! read from what the real client needed, held and fetched (the tables of `simulate`).

use super::score::{cache_hits, held_tiles, tick_views, wasted};
use super::session::SessionLog;
use super::transport::Outcome;
use splat2tiles_tiles::tiling::TileKey;

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

/// Summarises a session (see [`Summary`]) against the client's own view sets, with the rules of
/// [`super::score`].
pub fn summarize(log: &SessionLog) -> Summary {
    let resident = held_tiles(log);
    let views = tick_views(
        log,
        log.ticks.iter().map(|t| t.view_set.as_slice()),
        &resident,
    );
    let c = cache_hits(&views);
    let downloads: Vec<(TileKey, u64, f64)> = log
        .requests
        .iter()
        .filter_map(|r| match (r.key, r.outcome, r.end_s) {
            (Some(k), Outcome::Done, Some(end)) => Some((k, r.bytes, end)),
            _ => None,
        })
        .collect();
    let w = wasted(&downloads, &views);
    Summary {
        entries: c.first.n as usize,
        hits: c.first.hits as usize,
        first_view_tiles: c.initial.n as usize,
        reentries: c.reentry.n as usize,
        reentry_hits: c.reentry.hits as usize,
        fetched: w.tiles as usize,
        wasted: w.wasted_tiles as usize,
        fetched_bytes: w.bytes,
        wasted_bytes: w.wasted_bytes,
        bytes_down: log.ticks.last().map_or(0, |t| t.bytes_down),
    }
}
