//! Hierarchical tile cache (TileSplat sec. 3.5, eq. 19): capacity in bytes; victims are taken
//! first from tiles far away (> `far_m`) or out of the frustum, deepest first (parents last);
//! a tile is never evicted while one of its descendants is resident (it covers their missing
//! siblings), nor while it is visible. Hysteresis against flicker: a resident tile is never
//! replaced by a lower level, and tiles seen within `hold_s` are evicted only after all others.

use super::catalog::{Level, TileCatalog};
use glam::DVec3;
use std::collections::BTreeMap;

/// Cache settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CacheConfig {
    /// Capacity in bytes (TileSplat: 1 GB).
    pub capacity_bytes: u64,
    /// Distance beyond which a tile is an eviction candidate (TileSplat: 150 m).
    pub far_m: f64,
    /// Seconds after a tile was last visible during which it is evicted only as a last resort.
    pub hold_s: f64,
}

impl Default for CacheConfig {
    fn default() -> Self {
        CacheConfig {
            capacity_bytes: 1 << 30,
            far_m: 150.0,
            hold_s: 5.0,
        }
    }
}

/// One resident tile.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Entry {
    /// Resident level.
    pub level: Level,
    /// Bytes it takes.
    pub bytes: u64,
    /// Last time it was visible (or inserted).
    pub last_visible: f64,
}

/// What the cache needs to know about the present view to pick victims.
#[derive(Debug, Clone, Copy)]
pub struct EvictContext<'a> {
    /// The tile tree.
    pub catalog: &'a TileCatalog,
    /// Camera position.
    pub pos: DVec3,
    /// Current time.
    pub now: f64,
    /// Per tile index: visible now.
    pub visible: &'a [bool],
}

/// Result of an insertion.
#[derive(Debug, Clone, PartialEq)]
pub enum Inserted {
    /// Stored; these tiles were evicted to make room.
    Stored(Vec<usize>),
    /// Already resident at this level or better (kept as is).
    Kept,
    /// Not enough evictable room: not stored.
    Rejected,
}

/// The cache.
#[derive(Debug, Clone, PartialEq)]
pub struct Cache {
    /// Settings.
    pub config: CacheConfig,
    entries: BTreeMap<usize, Entry>,
    used: u64,
    /// Tiles evicted so far.
    pub evictions: u64,
}

impl Cache {
    /// An empty cache.
    pub fn new(config: CacheConfig) -> Self {
        Cache {
            config,
            entries: BTreeMap::new(),
            used: 0,
            evictions: 0,
        }
    }

    /// Bytes in use.
    pub fn used(&self) -> u64 {
        self.used
    }

    /// Resident entry of a tile.
    pub fn get(&self, tile: usize) -> Option<&Entry> {
        self.entries.get(&tile)
    }

    /// Resident level of a tile.
    pub fn level(&self, tile: usize) -> Option<Level> {
        self.entries.get(&tile).map(|e| e.level)
    }

    /// Resident tiles in index order.
    pub fn resident(&self) -> impl Iterator<Item = (usize, &Entry)> {
        self.entries.iter().map(|(k, v)| (*k, v))
    }

    /// Number of resident tiles.
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// Whether nothing is resident.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    /// Marks tiles as visible at `now`.
    pub fn touch(&mut self, tiles: &[usize], now: f64) {
        for t in tiles {
            if let Some(e) = self.entries.get_mut(t) {
                e.last_visible = now;
            }
        }
    }

    fn has_resident_descendant(&self, cat: &TileCatalog, tile: usize) -> bool {
        let mut stack: Vec<usize> = cat.tiles[tile].children.clone();
        while let Some(c) = stack.pop() {
            if self.entries.contains_key(&c) {
                return true;
            }
            stack.extend(cat.tiles[c].children.iter().copied());
        }
        false
    }

    /// Eviction rank of a resident tile (smaller goes first), or `None` when it may not go.
    fn rank(&self, ctx: &EvictContext, tile: usize, e: &Entry) -> Option<(u8, i64, i64, i64)> {
        if ctx.visible.get(tile).copied().unwrap_or(false) {
            return None;
        }
        if self.has_resident_descendant(ctx.catalog, tile) {
            return None;
        }
        let t = &ctx.catalog.tiles[tile];
        let dist = t.bbox.distance(ctx.pos);
        let in_e = dist > self.config.far_m || !ctx.visible.get(tile).copied().unwrap_or(false);
        let recent = ctx.now - e.last_visible < self.config.hold_s;
        let class = match (in_e, recent) {
            (true, false) => 0,
            (true, true) => 1,
            _ => 2,
        };
        Some((
            class,
            -(t.depth() as i64),
            -(dist * 1000.0) as i64,
            (e.last_visible * 1000.0) as i64,
        ))
    }

    /// Stores `tile` at `level` taking `bytes`, evicting as needed (see the module docs).
    pub fn insert(
        &mut self,
        tile: usize,
        level: Level,
        bytes: u64,
        ctx: &EvictContext,
    ) -> Inserted {
        let old = self.entries.get(&tile).copied();
        if let Some(o) = old
            && o.level <= level
        {
            return Inserted::Kept;
        }
        let old_bytes = old.map_or(0, |o| o.bytes);
        if bytes > self.config.capacity_bytes {
            return Inserted::Rejected;
        }
        // Choose victims on a scratch copy, commit only when they make enough room.
        let mut scratch = self.clone();
        scratch.entries.remove(&tile);
        scratch.used -= old_bytes;
        let mut victims = vec![];
        while scratch.used + bytes > self.config.capacity_bytes {
            let best = scratch
                .entries
                .iter()
                .filter_map(|(&k, e)| scratch.rank(ctx, k, e).map(|r| (r, k)))
                .min();
            let Some((_, k)) = best else {
                return Inserted::Rejected;
            };
            let e = scratch.entries.remove(&k).expect("present");
            scratch.used -= e.bytes;
            victims.push(k);
        }
        scratch.entries.insert(
            tile,
            Entry {
                level,
                bytes,
                last_visible: ctx.now,
            },
        );
        scratch.used += bytes;
        scratch.evictions += victims.len() as u64;
        *self = scratch;
        Inserted::Stored(victims)
    }

    /// Removes a tile (if it may go: no resident descendant). Returns whether it was removed.
    pub fn remove(&mut self, cat: &TileCatalog, tile: usize) -> bool {
        if self.has_resident_descendant(cat, tile) {
            return false;
        }
        match self.entries.remove(&tile) {
            Some(e) => {
                self.used -= e.bytes;
                true
            }
            None => false,
        }
    }
}
