//! Scoring a streaming session as the papers mean it: the cut each view needs (from the whole
//! tileset, not the client's partial view of it), cache hits over first-time tile entries, the
//! SSIM of what the client draws against that cut at Best, new-region events, TGQ and waste.
//!
//! Definitions (TileSplat sec. 4.4.2):
//! - **needed cut**: [`splat2tiles_tiles::select::select_cut`] over every available tile at the
//!   camera's viewport (the client's own rule, given all subtrees).
//! - **CHR**: a tile *enters* when it is in the needed cut and was not at the previous tick. An
//!   entry is a hit when the client holds the tile (any variant) at that tick. Entries of the
//!   first non-empty cut (the cold start), first-time entries and re-entries are counted apart.
//! - **quality**: SSIM of the client's drawn tiles (the variants it holds, parents standing in
//!   for missing children) against the needed cut at Best, rendered at a reduced viewport.
//! - **events**: the first tick, and every tick where at least `new_fraction` of the needed cut
//!   was never needed before (a new street) or the view turned by `turn_deg` within 1 s; events
//!   closer than `min_gap_s` to the previous one are merged into it.
//! - **TGQ**: seconds from an event to the first quality sample >= the threshold (0.90).
//! - **WD**: content downloads completed for tiles in no needed cut from the download's end on.

use super::session::SessionLog;
use anyhow::Context;
use glam::{DMat4, DVec3};
use splat2tiles_core::splat::Splats;
use splat2tiles_render::{Camera, Image, RenderOptions, render, ssim};
use splat2tiles_stream::catalog::Level;
use splat2tiles_tiles::select::{CutTree, box_sphere, select_cut};
use splat2tiles_tiles::tiling::TileKey;
use splat2tiles_tiles::tiling::load::LoadedTileset;
use std::collections::{HashMap, HashSet};
use std::path::Path;

/// A tileset as the scorer sees it: every available tile, its sphere, and decoded content.
pub struct Truth {
    ts: LoadedTileset,
    roots: Vec<usize>,
    children: Vec<Vec<usize>>,
    spheres: Vec<Option<(DVec3, f64)>>,
    index: HashMap<TileKey, usize>,
    content: HashMap<(usize, Level), (Splats, DMat4)>,
    /// The layer each decoded Best content declares (layered tilesets; its opacity deltas).
    deltas: HashMap<usize, Option<splat2tiles_tiles::layers::glb::LayerInfo>>,
}

impl CutTree for Truth {
    fn roots(&self) -> &[usize] {
        &self.roots
    }
    fn children(&self, i: usize) -> &[usize] {
        &self.children[i]
    }
    fn sphere(&self, i: usize) -> Option<(DVec3, f64)> {
        self.spheres[i]
    }
    fn geometric_error(&self, i: usize) -> f64 {
        self.ts.tiles[i].geometric_error
    }
    fn has_content(&self, i: usize) -> bool {
        self.ts.tiles[i].content.is_some()
    }
}

impl Truth {
    /// Reads `tileset.json` and every subtree below it.
    pub fn load(tileset_json: &Path) -> anyhow::Result<Truth> {
        let ts = splat2tiles_tiles::tiling::load::load_tileset(tileset_json)
            .with_context(|| tileset_json.display().to_string())?;
        let index: HashMap<TileKey, usize> = ts
            .tiles
            .iter()
            .enumerate()
            .map(|(i, t)| (t.key, i))
            .collect();
        let mut children = vec![vec![]; ts.tiles.len()];
        let mut roots = vec![];
        for (i, t) in ts.tiles.iter().enumerate() {
            match t.key.parent().and_then(|p| index.get(&p)) {
                Some(&p) => children[p].push(i),
                None => roots.push(i),
            }
        }
        let spheres = ts
            .tiles
            .iter()
            .map(|t| t.bounding_box.map(|b| box_sphere(&b, &ts.root_transform)))
            .collect();
        Ok(Truth {
            ts,
            roots,
            children,
            spheres,
            index,
            content: HashMap::new(),
            deltas: HashMap::new(),
        })
    }

    /// Number of available tiles.
    pub fn len(&self) -> usize {
        self.ts.tiles.len()
    }

    /// Whether the tileset has no tiles.
    pub fn is_empty(&self) -> bool {
        self.ts.tiles.is_empty()
    }

    /// Root transform (tileset frame to world): a trace pose's camera is this times its pose.
    pub fn root_transform(&self) -> DMat4 {
        self.ts.root_transform
    }

    /// Box of every tile (world frame), as `render --auto-view` frames it.
    pub fn bounds(&self) -> Option<(DVec3, DVec3)> {
        splat2tiles_tiles::geometry::tileset_bounds(&self.ts)
    }

    /// The cut `cam` needs at `max_sse` (frustum-culled), as tile keys.
    pub fn needed(&self, cam: &Camera, max_sse: f64) -> Vec<TileKey> {
        select_cut(self, cam, max_sse, true, |_| true)
            .into_iter()
            .map(|i| self.ts.tiles[i].key)
            .collect()
    }

    /// The cut a client with `cfg`'s viewport and SSE threshold needs at `pose` (tileset frame).
    pub fn needed_at(
        &self,
        cfg: &splat2tiles_stream::client::ClientConfig,
        pose: &splat2tiles_stream::ViewPose,
    ) -> Vec<TileKey> {
        let cam = Camera::from_pose(
            cfg.width,
            cfg.height,
            cfg.fov_y_deg,
            self.root_transform() * pose.world_from_camera(),
        );
        self.needed(&cam, cfg.max_sse)
    }

    /// [`Self::needed_at`] of every tick's pose of a session.
    pub fn needed_per_tick(
        &self,
        cfg: &splat2tiles_stream::client::ClientConfig,
        log: &SessionLog,
    ) -> Vec<Vec<TileKey>> {
        log.ticks
            .iter()
            .map(|t| self.needed_at(cfg, &t.pose))
            .collect()
    }

    /// Decodes (once) the content of `key` at `level`.
    fn decode(&mut self, key: TileKey, level: Level) -> anyhow::Result<Option<usize>> {
        let Some(&i) = self.index.get(&key) else {
            return Ok(None);
        };
        if self.ts.tiles[i].content.is_none() {
            return Ok(None);
        }
        if !self.content.contains_key(&(i, level)) {
            let v = splat2tiles_tiles::variants::ALL[level.index()];
            let p = self.ts.dir.join(splat2tiles_tiles::variants::content_uri(
                self.ts.scheme,
                key,
                v,
            ));
            let bytes = std::fs::read(&p).with_context(|| p.display().to_string())?;
            let (splats, node) = splat2tiles_tiles::variants::decode_variant(&bytes)
                .with_context(|| p.display().to_string())?;
            let m = splat2tiles_tiles::geometry::content_model(&self.ts, &node);
            if level == Level::Best {
                let layer = splat2tiles_tiles::layers::glb::read_layer(&bytes)
                    .with_context(|| p.display().to_string())?;
                self.deltas.insert(i, layer);
            }
            self.content.insert((i, level), (splats, m));
        }
        Ok(Some(i))
    }

    /// Renders `tiles` (each at its level) from `cam` on black.
    pub fn render(&mut self, tiles: &[(TileKey, Level)], cam: &Camera) -> anyhow::Result<Image> {
        let mut have = vec![];
        for &(k, l) in tiles {
            if let Some(i) = self.decode(k, l)? {
                have.push((i, l));
            }
        }
        let inst: Vec<(&Splats, DMat4)> = have
            .iter()
            .map(|k| {
                let (s, m) = &self.content[k];
                (s, *m)
            })
            .collect();
        Ok(render(&inst, cam, &RenderOptions::default()))
    }

    /// The layers `cam` needs from a layered tileset at `max_sse` (frustum-culled ADD
    /// selection over every available tile, `select_add`), parents first, with blend factors.
    pub fn needed_layers(&self, cam: &Camera, max_sse: f64) -> Vec<(TileKey, f32)> {
        splat2tiles_tiles::select::select_add(self, cam, max_sse, true, |_| true)
            .into_iter()
            .map(|p| (self.ts.tiles[p.tile].key, p.blend))
            .collect()
    }

    /// Renders layers (Best contents of a layered tileset, parents before children, each with
    /// its blend factor) from `cam` on black at their effective opacities
    /// (`layers::blend::drawn_layers`); with `fade` false the parent-opacity deltas are ignored
    /// (every layer at its stored opacity times its cumulative blend, as a viewer without layer
    /// support would draw them, but blended). A layer whose parent is not listed is an error.
    pub fn render_layers(
        &mut self,
        layers: &[(TileKey, f32)],
        cam: &Camera,
        fade: bool,
    ) -> anyhow::Result<Image> {
        let mut picked: Vec<(usize, Option<usize>, f32)> = vec![];
        let mut at: HashMap<TileKey, usize> = HashMap::new();
        for &(k, blend) in layers {
            let Some(i) = self.decode(k, Level::Best)? else {
                anyhow::bail!("layer {k:?}: no such content");
            };
            let parent = match k.parent().filter(|_| k != TileKey::ROOT) {
                Some(p) => Some(
                    *at.get(&p)
                        .with_context(|| format!("layer {k:?}: its parent is not drawn"))?,
                ),
                None => None,
            };
            at.insert(k, picked.len());
            picked.push((i, parent, blend));
        }
        let zeros: Vec<Vec<f32>> = picked
            .iter()
            .map(|&(_, p, _)| {
                p.map_or(vec![], |p| {
                    vec![0.0; self.content[&(picked[p].0, Level::Best)].0.len()]
                })
            })
            .collect();
        let ancestors: Vec<Vec<splat2tiles_tiles::layers::blend::AncestorDelta<'_>>> = picked
            .iter()
            .map(|&(i, _, _)| match fade {
                true => splat2tiles_tiles::layers::view::ancestor_deltas(
                    self.ts.tiles[i].key.level,
                    self.deltas[&i].as_ref(),
                ),
                false => vec![],
            })
            .collect();
        let dl: Vec<splat2tiles_tiles::layers::blend::DrawnLayer<'_>> = picked
            .iter()
            .zip(&zeros)
            .zip(&ancestors)
            .map(
                |((&(i, parent, blend), z), a)| splat2tiles_tiles::layers::blend::DrawnLayer {
                    splats: &self.content[&(i, Level::Best)].0,
                    parent,
                    deltas: parent.map(|_| {
                        match (
                            fade,
                            self.deltas[&i]
                                .as_ref()
                                .and_then(|l| l.parent_opacity_delta.as_ref()),
                        ) {
                            (true, Some(d)) => d.as_slice(),
                            _ => z.as_slice(),
                        }
                    }),
                    blend: if parent.is_some() { blend } else { 1.0 },
                    ancestors: a,
                },
            )
            .collect();
        let drawn = splat2tiles_tiles::layers::blend::drawn_layers(&dl)?;
        let inst: Vec<(&Splats, DMat4)> = drawn
            .iter()
            .zip(&picked)
            .map(|(s, &(i, _, _))| (s, self.content[&(i, Level::Best)].1))
            .collect();
        Ok(render(&inst, cam, &RenderOptions::default()))
    }

    /// Quality of a drawn set for `cam`: SSIM at `width` x `height` of `drawn` against
    /// `needed` at Best (1.0 without rendering when they are the same tiles, all Best).
    pub fn quality(
        &mut self,
        needed: &[TileKey],
        drawn: &[(TileKey, Level)],
        cam: &Camera,
        width: u32,
        height: u32,
    ) -> anyhow::Result<f64> {
        if drawn_is_needed_at_best(needed, drawn) {
            return Ok(1.0);
        }
        let small = cam.resized(width, height);
        let best: Vec<(TileKey, Level)> = needed.iter().map(|k| (*k, Level::Best)).collect();
        let reference = self.render(&best, &small)?;
        let got = self.render(drawn, &small)?;
        Ok(ssim(&got, &reference)?)
    }
}

/// Whether `drawn` is exactly the `needed` tiles, every one at Best (its quality is 1 without
/// rendering).
pub fn drawn_is_needed_at_best(needed: &[TileKey], drawn: &[(TileKey, Level)]) -> bool {
    let mut a: Vec<TileKey> = needed.to_vec();
    let mut b: Vec<TileKey> = drawn
        .iter()
        .filter(|(_, l)| *l == Level::Best)
        .map(|(k, _)| *k)
        .collect();
    a.sort_unstable();
    b.sort_unstable();
    a == b && b.len() == drawn.len()
}

/// Hits out of entries.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Ratio {
    /// Entries that found the tile held.
    pub hits: u64,
    /// Entries.
    pub n: u64,
}

impl Ratio {
    /// Hits / entries (`None` without entries).
    pub fn rate(&self) -> Option<f64> {
        (self.n > 0).then(|| self.hits as f64 / self.n as f64)
    }
}

/// Cache hits, counted apart by kind of entry.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Chr {
    /// Entries of the first non-empty cut (the cold start).
    pub initial: Ratio,
    /// First-time entries after the first tick: the CHR the papers mean.
    pub first: Ratio,
    /// Entries of tiles needed before, left and needed again.
    pub reentry: Ratio,
    /// The first-time entries from the end of the warm-up on: the first tick after the first
    /// one whose whole needed cut was held (until then the link still carries the first view,
    /// and no predictor can prefetch); a subset of `first`.
    pub warm: Ratio,
}

/// One tick as the scorer needs it.
#[derive(Debug, Clone, Copy)]
pub struct TickView<'a> {
    /// Seconds.
    pub t: f64,
    /// The needed cut.
    pub needed: &'a [TileKey],
    /// Tiles the client holds (any variant).
    pub resident: &'a [TileKey],
}

/// The tiles the client held (any variant) at each tick of `log`.
pub fn held_tiles(log: &SessionLog) -> Vec<Vec<TileKey>> {
    log.ticks
        .iter()
        .map(|t| t.resident.iter().map(|r| r.0).collect())
        .collect()
}

/// One [`TickView`] per tick of `log`: its time, the tick's `needed` cut and `held` tiles.
pub fn tick_views<'a>(
    log: &SessionLog,
    needed: impl IntoIterator<Item = &'a [TileKey]>,
    held: &'a [Vec<TileKey>],
) -> Vec<TickView<'a>> {
    log.ticks
        .iter()
        .zip(needed.into_iter().zip(held))
        .map(|(t, (n, r))| TickView {
            t: t.t,
            needed: n,
            resident: r,
        })
        .collect()
}

/// Where the warm-up ends: first-time entries after it are [`Chr::warm`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum WarmUp {
    /// After the first tick whose whole needed cut was held: depends on the client (one that
    /// leaves holes in view unrepaired moves it).
    CutHeld,
    /// Entries at ticks later than this time (seconds), the same for every client: e.g.
    /// [`link_warm_up`].
    At(f64),
}

/// The time the link needs for the first non-empty cut: its first tick, one round trip and
/// the cut's bytes (`bytes` per tile, e.g. its Low variant) at `bytes_per_s`. A warm-up that no
/// client can move; infinite without a non-empty cut or a positive rate.
pub fn link_warm_up(
    ticks: &[TickView],
    bytes: impl Fn(&TileKey) -> u64,
    bytes_per_s: f64,
    rtt_s: f64,
) -> f64 {
    let Some(first) = ticks.iter().find(|t| !t.needed.is_empty()) else {
        return f64::INFINITY;
    };
    if bytes_per_s.is_nan() || bytes_per_s <= 0.0 {
        return f64::INFINITY;
    }
    let cut: u64 = first.needed.iter().map(bytes).sum();
    first.t + rtt_s.max(0.0) + cut as f64 / bytes_per_s
}

/// CHR over a session's ticks (see the module docs), warm from the first tick whose whole
/// needed cut was held ([`WarmUp::CutHeld`]).
pub fn cache_hits(ticks: &[TickView]) -> Chr {
    cache_hits_with(ticks, WarmUp::CutHeld)
}

/// CHR over a session's ticks with the given end of the warm-up.
pub fn cache_hits_with(ticks: &[TickView], warm_up: WarmUp) -> Chr {
    let mut out = Chr::default();
    let mut ever: HashSet<TileKey> = HashSet::new();
    let mut prev: HashSet<TileKey> = HashSet::new();
    let mut started = false;
    let mut warm = false;
    for tick in ticks {
        let held: HashSet<TileKey> = tick.resident.iter().copied().collect();
        let now: HashSet<TileKey> = tick.needed.iter().copied().collect();
        for key in &now {
            if prev.contains(key) {
                continue;
            }
            let hit = held.contains(key) as u64;
            let r = if !started {
                &mut out.initial
            } else if ever.contains(key) {
                &mut out.reentry
            } else {
                let warm = match warm_up {
                    WarmUp::CutHeld => warm,
                    WarmUp::At(at) => tick.t > at,
                };
                if warm {
                    out.warm.n += 1;
                    out.warm.hits += hit;
                }
                &mut out.first
            };
            r.n += 1;
            r.hits += hit;
        }
        warm |= started && !now.is_empty() && now.iter().all(|k| held.contains(k));
        started |= !now.is_empty();
        ever.extend(now.iter().copied());
        prev = now;
    }
    out
}

/// Event detection settings (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EventRule {
    /// Share of the needed cut never needed before that makes a new-region event.
    pub new_fraction: f64,
    /// Yaw change within 1 s that makes a turn event (degrees).
    pub turn_deg: f64,
    /// Events closer than this to the previous one are merged (s).
    pub min_gap_s: f64,
}

impl Default for EventRule {
    fn default() -> Self {
        EventRule {
            new_fraction: 0.3,
            turn_deg: 45.0,
            min_gap_s: 3.0,
        }
    }
}

/// Times of new-region events: the first tick, then entries into unseen parts and turns.
/// `yaw_deg[k]` is tick `k`'s heading.
pub fn events(ticks: &[TickView], yaw_deg: &[f64], rule: &EventRule) -> Vec<f64> {
    let mut out: Vec<f64> = vec![];
    let mut ever: HashSet<TileKey> = HashSet::new();
    let mut back = 0usize;
    for (k, tick) in ticks.iter().enumerate() {
        let fresh = tick.needed.iter().filter(|k| !ever.contains(k)).count();
        let new_region =
            !tick.needed.is_empty() && fresh as f64 >= rule.new_fraction * tick.needed.len() as f64;
        while back < k && ticks[back].t < tick.t - 1.0 {
            back += 1;
        }
        let turned = match (yaw_deg.get(back), yaw_deg.get(k)) {
            (Some(a), Some(b)) => {
                let d = (b - a + 180.0).rem_euclid(360.0) - 180.0;
                d.abs() >= rule.turn_deg
            }
            _ => false,
        };
        let first = k == 0;
        if (first || new_region || turned)
            && out.last().is_none_or(|&e| tick.t - e >= rule.min_gap_s)
        {
            out.push(tick.t);
        }
        ever.extend(tick.needed.iter().copied());
    }
    out
}

/// Per event: seconds until the first quality sample `(t, ssim)` at or after it reaches
/// `threshold`, `None` when none does before the next event (or the end).
pub fn time_to_quality(events: &[f64], quality: &[(f64, f64)], threshold: f64) -> Vec<Option<f64>> {
    events
        .iter()
        .enumerate()
        .map(|(j, &e)| {
            let end = events.get(j + 1).copied().unwrap_or(f64::INFINITY);
            quality
                .iter()
                .find(|(t, q)| *t >= e && *t < end && *q >= threshold)
                .map(|(t, _)| t - e)
        })
        .collect()
}

/// Downloads for tiles never needed.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Waste {
    /// Completed content downloads.
    pub tiles: u64,
    /// Their bytes.
    pub bytes: u64,
    /// Of them, for tiles never in a needed cut.
    pub wasted_tiles: u64,
    /// Their bytes.
    pub wasted_bytes: u64,
}

/// WD over completed downloads `(tile, bytes, end time)`: wasted when the tile is in no needed
/// cut at or after the end.
pub fn wasted(downloads: &[(TileKey, u64, f64)], ticks: &[TickView]) -> Waste {
    let mut last: HashMap<TileKey, f64> = HashMap::new();
    for t in ticks {
        for k in t.needed {
            last.insert(*k, t.t);
        }
    }
    let mut w = Waste::default();
    for &(k, b, end) in downloads {
        w.tiles += 1;
        w.bytes += b;
        if last.get(&k).is_none_or(|&t| t < end) {
            w.wasted_tiles += 1;
            w.wasted_bytes += b;
        }
    }
    w
}

#[cfg(test)]
mod tests {
    use super::*;

    fn key(x: u32) -> TileKey {
        TileKey {
            level: 1,
            x,
            y: 0,
            z: 0,
        }
    }

    #[test]
    fn entries_are_split_into_initial_first_time_and_reentries() {
        let (a, b, c) = ([key(0)], [key(0), key(1)], [key(2)]);
        let ticks = [
            // t0: a enters with nothing held (initial miss).
            TickView {
                t: 0.0,
                needed: &a,
                resident: &[],
            },
            // t1: key1 enters, held (first-time hit); key0 stays (not an entry).
            TickView {
                t: 1.0,
                needed: &b,
                resident: &b,
            },
            // t2: key2 enters, not held (first-time miss).
            TickView {
                t: 2.0,
                needed: &c,
                resident: &b,
            },
            // t3: key0 comes back, held (re-entry hit); key1 comes back, not held (miss).
            TickView {
                t: 3.0,
                needed: &b,
                resident: &a,
            },
        ];
        let chr = cache_hits(&ticks);
        assert_eq!(chr.initial, Ratio { hits: 0, n: 1 });
        assert_eq!(chr.first, Ratio { hits: 1, n: 2 });
        assert_eq!(chr.reentry, Ratio { hits: 1, n: 2 });
        // Warm from t1 on (its whole cut held): the t2 miss counts, the t1 hit does not.
        assert_eq!(chr.warm, Ratio { hits: 0, n: 1 });
        // A warm-up at a fixed time: entries at ticks after it, whatever the client held.
        let at = |t: f64| cache_hits_with(&ticks, WarmUp::At(t)).warm;
        assert_eq!(at(0.5), Ratio { hits: 1, n: 2 });
        assert_eq!(at(1.0), Ratio { hits: 0, n: 1 });
        assert_eq!(at(f64::INFINITY), Ratio::default());
        // The link's warm-up: first non-empty cut's tick + round trip + its bytes at the rate.
        let w = link_warm_up(&ticks, |_| 500, 1000.0, 0.04);
        assert!((w - 0.54).abs() < 1e-12, "{w}");
        assert_eq!(link_warm_up(&ticks, |_| 500, 0.0, 0.04), f64::INFINITY);
        assert_eq!(link_warm_up(&ticks, |_| 500, f64::NAN, 0.04), f64::INFINITY);
        assert_eq!(link_warm_up(&[], |_| 500, 1000.0, 0.04), f64::INFINITY);
        assert_eq!(chr.first.rate(), Some(0.5));
        assert_eq!(Ratio::default().rate(), None);
    }

    #[test]
    fn events_fire_on_new_regions_and_turns_not_on_steady_views() {
        let (a, b) = ([key(0), key(1)], [key(2), key(3)]);
        let mut ticks = vec![];
        let mut yaw = vec![];
        for k in 0..120 {
            let t = k as f64 / 12.0;
            // Steady on `a` for 4 s, then a new street `b`.
            ticks.push(TickView {
                t,
                needed: if t < 4.0 { &a } else { &b },
                resident: &[],
            });
            // Then at 7 s a quick 90-degree turn over half a second.
            yaw.push(if t < 7.0 {
                0.0
            } else {
                ((t - 7.0) * 180.0).min(90.0)
            });
        }
        let ev = events(&ticks, &yaw, &EventRule::default());
        assert_eq!(ev.len(), 3, "{ev:?}");
        assert_eq!(ev[0], 0.0);
        assert!((ev[1] - 4.0).abs() < 0.1, "{ev:?}");
        assert!(ev[2] > 7.0 && ev[2] < 7.6, "{ev:?}");
    }

    #[test]
    fn tgq_is_per_event_and_none_when_quality_never_comes() {
        let q = [(0.0, 0.5), (1.0, 0.95), (5.0, 0.2), (6.0, 0.5)];
        let t = time_to_quality(&[0.0, 5.0], &q, 0.9);
        assert_eq!(t, vec![Some(1.0), None]);
    }

    #[test]
    fn waste_counts_downloads_of_tiles_not_needed_after_they_arrive() {
        let a = [key(0)];
        let ticks = [TickView {
            t: 0.0,
            needed: &a,
            resident: &[],
        }];
        // key(5) is never needed; key(0) arrives after its last tick in view.
        let w = wasted(
            &[(key(0), 100, 0.0), (key(5), 40, 0.0), (key(0), 7, 1.0)],
            &ticks,
        );
        assert_eq!(
            (w.tiles, w.bytes, w.wasted_tiles, w.wasted_bytes),
            (3, 147, 2, 47)
        );
    }
}
