//! Planning glue: one streaming step (pose history, view set, replan, downloads, scene) and the
//! replan that turns predicted views into prioritised wants through the deadline planner.

use super::*;

/// Seconds: a prefetch due this soon is requested before repairs of missed tiles in view.
const PREFETCH_BEFORE_REPAIR_S: f64 = 0.5;

/// Fraction of the view set with nothing drawn (no content, no resident ancestor) from which
/// holes are covered coarsely (`ClientConfig::cover_up`): a cold start or a jump, not the few
/// holes a moving view opens (with the oracle on the validation traces, 0.25, 0.5, 0.75 and 1.0
/// held 1385-1389 of 1529 first-time entries after warm-up; covering every hole held 260 of
/// flight 35's 399 against 283).
const COVER_WHEN_BARE: f64 = 0.5;

/// Request order of a want, smaller first: missing tiles before upgrades of held ones; among
/// each, the coarse covers of holes in view (`Want::cover`), with a prediction (`predicting`) a
/// prefetch due within `PREFETCH_BEFORE_REPAIR_S`, then tiles in view, then the other
/// prefetches, then holes in view drawn coarsely (`Want::covered`), then the tiles set aside
/// under overload (`Want::late`, in view or not).
///
/// - Missing tiles in view before prefetches further out, and upgrades last: with upgrades of
///   the view ahead of prefetches, tiles due in 1 s waited behind Low -> Best upgrades and were
///   requested after they entered (the oracle's "late" misses on the walk).
/// - An imminent prefetch before the repair of a tile already missed in view: the hole is
///   there either way, the prefetch keeps one from opening. On the city's flight 38 (a burst
///   that outruns the link) the oracle held 254/404 of the entries after warm-up with repairs
///   first and 328/404 with this.
/// - A set-aside tile after every other missing one (`ClientConfig::set_aside_late`, under
///   overload with trusted deadlines): Moore-Hodgson's fewest-late rule, earliest deadline
///   first with the jobs that cannot make it set aside. A hole in view that was set aside stays
///   behind the prefetches that can still be on time: with repairs first, every repair pushed
///   the next entries late (walk 15 of the validation traces: earliest deadline first with every
///   job fetched leaves 37 of 209 first-time entries late, Moore-Hodgson 6).
/// - A hole in view that an ancestor draws after every prefetch (`ClientConfig::cover_up`): the
///   view is whole if coarse, and the tiles about to enter are not. With the oracle on the
///   validation traces it held 1386 of 1529 first-time entries after warm-up, against 1370 and
///   1381 with the covered holes behind only the prefetches due within 1 and 3 s, 1363 with the
///   covers and no reordering, and 1372 without covers (test traces: 1290, 1275, 1250, 1277 and
///   1271 of 1325). The price is the time to full quality of the view (BENCHMARKS.md).
fn want_group(w: &Want, held: bool, predicting: bool) -> (bool, u8) {
    let class = if w.cover {
        0
    } else if w.late {
        5
    } else if w.covered {
        4
    } else if predicting && !w.in_view && w.deadline <= PREFETCH_BEFORE_REPAIR_S {
        1
    } else if w.in_view {
        2
    } else {
        3
    };
    (held, class)
}

/// What the overload rules decided for one plan.
struct Overload {
    /// Missing prefetches are asked at Low.
    at_low: bool,
    /// Per tile: set aside by Moore-Hodgson (requested after every other missing tile).
    late: Vec<bool>,
}

impl Overload {
    fn is_late(&self, tile: usize) -> bool {
        self.late[tile]
    }
}

/// The wants of one plan, each tile at most once.
#[derive(Default)]
struct Wants {
    list: Vec<Want>,
    seen: HashSet<usize>,
}

impl Wants {
    /// Adds `w` unless its tile is already wanted; `late` marks it set aside.
    fn push(&mut self, mut w: Want, late: bool) {
        if self.seen.insert(w.tile) {
            w.late = late;
            self.list.push(w);
        }
    }
}

/// The missing prefetches to set aside so that the most of the others arrive by their deadlines
/// at Low: `dues` holds `(seconds until due, Low bytes, tile)`; a tile due at `d` may enter until
/// `d + slack_s` (the prediction's step). Moore-Hodgson over `link`'s per-step capacity (in-flight
/// bytes and the round trip taken off the front): earliest deadline first, and whenever the ones
/// kept so far do not fit by the current deadline, the largest of them is set aside (the fewest
/// late jobs on one machine; the link's cumulative capacity only grows, so bytes stand in for
/// time). Empty when everything fits: then no overload, and a tile the planner left out was left
/// out for its utility, not because it cannot be on time.
fn set_aside(
    dues: &mut Vec<(f64, u64, usize)>,
    link: &LinkForecast,
    cfg: &PlanStepConfig,
    slack_s: f64,
) -> Vec<usize> {
    dues.retain(|d| d.0.is_finite());
    if dues.is_empty() || cfg.step_s.is_nan() || cfg.step_s <= 0.0 {
        return vec![];
    }
    dues.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.2.cmp(&b.2)));
    let slack_s = slack_s.max(0.0);
    let last = dues[dues.len() - 1].0.max(0.0) + slack_s;
    let steps = ((last / cfg.step_s).ceil() as usize).clamp(1, 1 << 20);
    let rates = link.steps(cfg, steps);
    let mut aside = vec![];
    let mut kept = std::collections::BinaryHeap::new();
    let (mut cap, mut need, mut k) = (0.0f64, 0.0f64, 0);
    let mut admit = |d: &(f64, u64, usize), cap: f64, need: &mut f64| {
        *need += d.1 as f64;
        kept.push((d.1, d.2));
        while *need > cap {
            let Some((b, tile)) = kept.pop() else { break };
            *need -= b as f64;
            aside.push(tile);
        }
    };
    for (j, rate) in rates.iter().enumerate() {
        let end = (j + 1) as f64 * cfg.step_s;
        cap += rate.max(0.0) * cfg.step_s;
        while k < dues.len() && dues[k].0.max(0.0) + slack_s <= end + 1e-9 {
            admit(&dues[k], cap, &mut need);
            k += 1;
        }
    }
    for d in &dues[k..] {
        admit(d, cap, &mut need);
    }
    aside
}

/// Whether the link cannot carry every missing prefetch by its deadline even at Low (`dues` as
/// for [`set_aside`], without tiles): earliest deadline first, overloaded when some prefix does
/// not fit.
#[cfg(test)]
fn overloaded(
    dues: &[(f64, u64)],
    link: &LinkForecast,
    cfg: &PlanStepConfig,
    slack_s: f64,
) -> bool {
    let mut d: Vec<(f64, u64, usize)> = dues
        .iter()
        .enumerate()
        .map(|(i, d)| (d.0, d.1, i))
        .collect();
    !set_aside(&mut d, link, cfg, slack_s).is_empty()
}

impl StreamClient {
    pub(super) fn stream_step(&mut self, camera: &Camera, actions: &mut Vec<Action>) {
        let n = self.info.len();
        // 1. Pose history (tileset frame) for the predictor.
        let pose = self.pose_of(camera);
        if self.history.last().is_some_and(|p| p.t >= pose.t) {
            self.history.pop();
        }
        self.history.push(pose);
        self.first_view.get_or_insert(pose.t);
        let keep_from = self.now - 10.0;
        let drop = self.history.iter().take_while(|p| p.t < keep_from).count();
        self.history.drain(..drop);
        // 2. View set (layered: with each layer's blend factor).
        let (view, wants) = if self.layered {
            let (picks, wants) = self.select_layers(camera);
            self.blend = vec![0.0; n];
            for p in &picks {
                self.blend[p.tile] = p.blend;
            }
            (picks.iter().map(|p| p.tile).collect(), wants)
        } else {
            self.select(camera)
        };
        self.request_subtrees(&wants, actions);
        self.subtree_wants = wants;
        let changed = view != self.view;
        // Entries into the view judge the predictor's pending deadlines (the record is kept
        // only for `set_aside_late`, its one reader).
        if self.cfg.set_aside_late {
            let step = self.cfg.predict_step_s;
            for &i in &view {
                if !self.in_view.get(i).copied().unwrap_or(false) {
                    self.deadlines.entered(i, self.now, step);
                }
            }
            self.deadlines.expire(self.now, step);
        }
        self.view = view;
        self.in_view = vec![false; n];
        for &i in &self.view {
            self.in_view[i] = true;
        }
        self.cache.touch(&self.view, self.now);
        // 3. Plan: periodically, on a change of the view set, of the speed, or of the state.
        let speed = self.speed();
        let speed_jump = (speed - self.plan_speed).abs()
            > self.cfg.replan_speed_change * self.plan_speed.max(0.05);
        if self.dirty
            || changed
            || speed_jump
            || self.now - self.last_plan >= self.cfg.replan_s
            || self.view_tile_unwanted()
        {
            self.plan_speed = speed;
            self.replan(camera, &pose);
        }
        // 4. Downloads (subtrees the predicted views need, then tiles).
        let predicted_subtrees = std::mem::take(&mut self.predicted_subtrees);
        self.request_subtrees(&predicted_subtrees, actions);
        self.predicted_subtrees = predicted_subtrees;
        self.schedule(actions);
        // 5. Memory, then the scene.
        self.make_room(0);
        self.reconcile_scene();
    }

    /// Mean camera speed over the last 0.5 s of history (tileset-frame metres per second).
    fn speed(&self) -> f64 {
        let Some(now) = self.history.last() else {
            return 0.0;
        };
        let start = self
            .history
            .iter()
            .rev()
            .find(|p| now.t - p.t >= 0.5)
            .unwrap_or(&self.history[0]);
        let dt = now.t - start.t;
        if dt > 1e-9 {
            now.pos.distance(start.pos) / dt
        } else {
            0.0
        }
    }

    /// Whether a usable tile of the view set is neither resident nor wanted by the last plan.
    fn view_tile_unwanted(&self) -> bool {
        let mut wanted = vec![false; self.info.len()];
        for w in &self.wanted {
            wanted[w.tile] = true;
        }
        self.view
            .iter()
            .any(|&i| !wanted[i] && self.cache.level(i).is_none() && self.usable(i))
    }

    /// Whether the App. C.5 fallback rule replaces the predictor now: for a predictor that
    /// needs pose history (`min_history_s() > 0`, as the paper's learned model does), during the
    /// first `fallback_s` after the first view and while its history is short. A predictor that
    /// needs none (reactive, an oracle reading the trace) never falls back: with the rule for
    /// every predictor the oracle was reactive for 5 s, and those 5 s held all 70 of its 262
    /// missed first-time entries on the small city (tests/sim_city.rs).
    fn in_fallback(&self) -> bool {
        if self.predictor.min_history_s() <= 0.0 {
            return false;
        }
        self.first_view
            .is_none_or(|t0| self.now - t0 + 1e-9 < self.cfg.fallback_s)
            || needs_fallback(self.predictor.as_ref(), &self.history)
    }

    /// Whether tile `i` may be planned: missing, or held at a level that a usable better one
    /// beats by at least the prefetch setting's `upgrade_gain` in utility.
    fn worth_fetching(&self, i: usize) -> bool {
        let gain = self.cfg.prefetch.upgrade_gain;
        let Some(held) = self.cache.level(i) else {
            return true;
        };
        if gain <= 0.0 {
            return true;
        }
        let v = &self.catalog.tiles[i].variants;
        let better = (0..held.index())
            .filter(|&j| self.info[i].urls[j].is_some())
            .map(|j| v[j].utility)
            .fold(f64::NEG_INFINITY, f64::max);
        better - v[held.index()].utility >= gain
    }

    pub(super) fn usable(&self, i: usize) -> bool {
        let s = &self.state[i];
        !s.given_up && self.info[i].urls.iter().any(|u| u.is_some())
    }

    /// The usable level nearest to `want`: the best one not better than it, else the worst
    /// usable one better than it.
    pub(super) fn usable_level(&self, i: usize, want: Level) -> Option<Level> {
        let urls = &self.info[i].urls;
        (want.index()..LEVELS)
            .find(|&j| urls[j].is_some())
            .or_else(|| (0..want.index()).rev().find(|&j| urls[j].is_some()))
            .map(Level::from_index)
    }

    /// Plans: predicts the views over the horizon, runs the deadline planner on the tiles they
    /// show and turns its fetches (and the tiles in view, and the fallback radius) into the
    /// ordered wants.
    pub(super) fn replan(&mut self, camera: &Camera, pose: &ViewPose) {
        self.last_plan = self.now;
        self.stats.plans += 1;
        if self.deadlines.trusted() {
            self.stats.trusted_plans += 1;
        }
        self.dirty = false;
        self.predicted_subtrees.clear();
        let fallback = self.in_fallback();
        let (predicted, uncertain) = if fallback {
            (vec![], false)
        } else {
            // App. C.5: poses too uncertain to plan for give way to the radius rule; the
            // prefetch setting bounds how far ahead and how uncertain a planned pose may be.
            let ahead = self.cfg.predict_horizon_s.min(self.cfg.prefetch.ahead_s);
            confident_poses(
                &self.predictor.predict_uncertain(
                    &self.history,
                    ahead.max(0.0),
                    self.cfg.predict_step_s,
                ),
                BLEND_SIGMA_M.min(self.cfg.prefetch.max_sigma_m),
            )
        };
        let predicting = !predicted.is_empty();
        let first = self.first_visible(camera, &predicted);
        // Deadlines go on the record (judged when the tile enters or the time passes).
        if self.cfg.set_aside_late {
            self.deadlines.set_predicting(predicting);
            for (i, &t) in first.iter().enumerate() {
                if t.is_finite() && !self.in_view[i] {
                    self.deadlines.predicted(i, self.now + t);
                }
            }
        }
        self.predicted = first
            .iter()
            .enumerate()
            .filter(|(_, t)| t.is_finite())
            .map(|(i, t)| (i, *t))
            .collect();
        let flying = self.flying();
        let mut pinned_tile = vec![false; self.info.len()];
        for &(i, _) in &flying {
            pinned_tile[i] = true;
        }
        let firsts: Vec<(usize, f64)> = first
            .iter()
            .enumerate()
            .filter(|(i, t)| t.is_finite() && self.usable(*i) && !pinned_tile[*i])
            .filter(|(i, _)| self.worth_fetching(*i))
            .map(|(i, t)| (i, *t))
            .collect();
        let budget = self.plan_budget();
        let link = LinkForecast {
            pieces: self.bw.forecast(self.cfg.plan.horizon_s),
            in_flight_bytes: self.in_flight_bytes(),
        };
        let step = PlanStepConfig {
            concurrency: self.cfg.max_concurrent,
            ..self.cfg.plan
        };
        let (cands, plan) = plan_visible_link(
            &self.catalog,
            pose.pos,
            &firsts,
            &step,
            &link,
            |i| self.cache.level(i),
            budget,
        );
        let frustum = Frustum::new(pose, &self.cfg.plan.intrinsics);
        let mut wants = Wants::default();
        let covers = self.cover_wants(&frustum, &mut wants);
        let aside = self.overload(&firsts, &link, &step, &covers);
        for f in &plan.fetches {
            let tile = cands[f.candidate].tile;
            // Under overload a missing prefetch comes at Low, as the overload test assumed.
            let asked = if aside.at_low && !self.in_view[tile] && self.cache.level(tile).is_none() {
                Level::Low
            } else {
                f.level
            };
            let Some(level) = self.usable_level(tile, asked) else {
                continue;
            };
            let level = self.resume_level(tile, level);
            // The predicted first visibility, not the planner's deadline (at least `urgent_s`):
            // the wants are requested in this order.
            let late = aside.is_late(tile);
            wants.push(self.want(tile, level, first[tile], &frustum), late);
        }
        // Downloads in flight go on while their tile is in view or predicted within the
        // horizon (a prefetch is not aborted because one plan left it out).
        for (i, level) in flying {
            if first[i].is_finite() && self.usable(i) {
                wants.push(self.want(i, level, first[i], &frustum), false);
            }
        }
        // Every tile of the view set is needed whatever the plan says.
        for i in self.view.clone() {
            if self.usable(i)
                && self.cache.level(i).is_none()
                && !wants.seen.contains(&i)
                && let Some(level) = self.usable_level(i, Level::Low)
            {
                wants.push(self.want(i, level, 0.0, &frustum), aside.is_late(i));
            }
        }
        if (fallback || uncertain) && self.cfg.fallback_radius_m > 0.0 {
            self.radius_wants(pose, budget, &frustum, &mut wants);
        }
        for w in &mut wants.list {
            w.covered = self.covered(w.tile, &covers);
        }
        self.wanted = self.ordered(wants.list, predicting);
    }

    /// The coarse covers of this plan (`ClientConfig::cover_up`): for the holes in view that
    /// nothing resident or on the way draws, their covering ancestors at Low, each only when it
    /// costs fewer bytes than the holes it covers. Returns the covers asked.
    fn cover_wants(&self, frustum: &Frustum, wants: &mut Wants) -> HashSet<usize> {
        let mut holes: std::collections::BTreeMap<usize, u64> = Default::default();
        let mut bare = 0usize;
        for &i in &self.view {
            if self.cache.level(i).is_some() || self.drawn_by_ancestor(i) {
                continue;
            }
            bare += 1;
            if !self.usable(i) {
                continue;
            }
            let (Some(c), Some(low)) = (self.cover_of(i), self.usable_level(i, Level::Low)) else {
                continue;
            };
            *holes.entry(c).or_default() += self.catalog.tiles[i].variants[low.index()].bytes;
        }
        let mut covers = HashSet::new();
        if holes.is_empty() || (bare as f64) < COVER_WHEN_BARE * self.view.len() as f64 {
            return covers;
        }
        for (c, bytes) in holes {
            let Some(level) = self.usable_level(c, Level::Low) else {
                continue;
            };
            if !self.downloading(c) && self.catalog.tiles[c].variants[level.index()].bytes >= bytes
            {
                continue;
            }
            let mut w = self.want(c, level, 0.0, frustum);
            w.cover = true;
            wants.push(w, false);
            covers.insert(c);
        }
        covers
    }

    /// The ancestor `cover_up` levels above `tile`, further up past tiles without content; None
    /// with the rule off or nothing usable above.
    fn cover_of(&self, tile: usize) -> Option<usize> {
        if self.cfg.cover_up == 0 {
            return None;
        }
        let mut up = self.catalog.ancestors(tile);
        let mut a = up.next()?;
        for _ in 1..self.cfg.cover_up {
            match up.next() {
                Some(p) => a = p,
                None => break,
            }
        }
        std::iter::once(a).chain(up).find(|&a| self.usable(a))
    }

    /// Whether a resident ancestor of `tile` is drawn in its place.
    fn drawn_by_ancestor(&self, tile: usize) -> bool {
        self.catalog
            .ancestors(tile)
            .any(|p| self.cache.level(p).is_some())
    }

    /// Whether `tile` is a hole in view that an ancestor draws: resident, downloading, or among
    /// this plan's `covers` (always false with the rule off).
    fn covered(&self, tile: usize, covers: &HashSet<usize>) -> bool {
        if self.cfg.cover_up == 0 || !self.in_view[tile] || self.cache.level(tile).is_some() {
            return false;
        }
        self.catalog
            .ancestors(tile)
            .any(|p| covers.contains(&p) || self.downloading(p) || self.cache.level(p).is_some())
    }

    /// Seconds from now to each tile's first predicted visibility (0 in view, infinite never);
    /// the subtrees the predicted views need go to `predicted_subtrees`.
    fn first_visible(&mut self, camera: &Camera, predicted: &[ViewPose]) -> Vec<f64> {
        let mut first = vec![f64::INFINITY; self.info.len()];
        for &i in &self.view {
            first[i] = 0.0;
        }
        // A tile first seen at a predicted sample may enter any time after the sample before
        // it: due at that earlier sample (with the sample's own time, the oracle's missed
        // tiles were due a median 0.42 s after they entered).
        let mut before = 0.0f64;
        for p in predicted {
            let cam = Camera {
                world_from_camera: self.root_transform * p.world_from_camera(),
                ..*camera
            };
            let dt = (p.t - self.now).max(0.0);
            let due = before.min(dt);
            before = before.max(dt);
            let (vis, wants) = self.select(&cam);
            for i in vis {
                first[i] = first[i].min(due);
            }
            for k in wants {
                if !self.predicted_subtrees.contains(&k) {
                    self.predicted_subtrees.push(k);
                }
            }
        }
        first
    }

    /// Downloads in flight and their levels. Each keeps its level and is not offered to the
    /// planner again (its remaining bytes are the link's `in_flight_bytes`): re-deciding it every
    /// plan switched levels and dropped the partial bytes.
    fn flying(&self) -> Vec<(usize, Level)> {
        self.state
            .iter()
            .enumerate()
            .filter_map(|(i, s)| {
                let d = s.download.as_ref()?;
                d.req.map(|_| (i, d.level))
            })
            .collect()
    }

    /// The memory the planner may fill: the budget less what is drawn or in view and the partial
    /// downloads.
    fn plan_budget(&self) -> u64 {
        let pinned: u64 = self
            .cache
            .resident()
            .filter(|(i, _)| self.in_view[*i] || self.drawn[*i])
            .map(|(_, e)| e.bytes)
            .sum();
        self.cfg
            .memory_budget_bytes
            .saturating_sub(pinned)
            .saturating_sub(self.partial_bytes())
    }

    /// Bytes still to arrive for the requests in flight: the link forecast spends them first.
    fn in_flight_bytes(&self) -> u64 {
        self.state
            .iter()
            .enumerate()
            .filter_map(|(i, s)| {
                let d = s.download.as_ref()?;
                d.req?;
                let size = d
                    .total
                    .unwrap_or(self.catalog.tiles[i].variants[d.level.index()].bytes);
                Some(size.saturating_sub(d.bytes.len() as u64))
            })
            .sum()
    }

    /// The overload rules. When the missing tiles (in view: due now) do not fit by their
    /// deadlines even at Low, the prefetches are asked at Low (coverage before quality), and with
    /// `set_aside_late` and trusted deadlines the ones Moore-Hodgson sets aside go last.
    fn overload(
        &mut self,
        firsts: &[(usize, f64)],
        link: &LinkForecast,
        step: &PlanStepConfig,
        covers: &HashSet<usize>,
    ) -> Overload {
        let dues = |holes: bool| -> Vec<(f64, u64, usize)> {
            firsts
                .iter()
                .filter(|&&(i, t)| {
                    (holes || (t > 0.0 && !self.in_view[i])) && self.cache.level(i).is_none()
                })
                .filter(|&&(i, _)| !self.covered(i, covers))
                .filter_map(|&(i, t)| {
                    let low = self.usable_level(i, Level::Low)?;
                    Some((t, self.catalog.tiles[i].variants[low.index()].bytes, i))
                })
                .collect()
        };
        let slack = self.cfg.predict_step_s;
        // Prefetches alone for the Low rule (every predictor); holes in view too for setting
        // aside (trusted deadlines only).
        let overload = self.cfg.low_under_overload
            && !set_aside(&mut dues(false), link, step, slack).is_empty();
        let aside = if self.cfg.set_aside_late && self.deadlines.trusted() {
            set_aside(&mut dues(true), link, step, slack)
        } else {
            vec![]
        };
        let mut late = vec![false; self.info.len()];
        for &i in &aside {
            late[i] = true;
        }
        let at_low = overload || !aside.is_empty();
        if at_low {
            self.stats.overload_plans += 1;
        }
        Overload { at_low, late }
    }

    /// App. C.5 fallback (and blend, when the prediction is uncertain): the tiles within the
    /// radius at Medium, nearest first, while the memory budget holds them.
    fn radius_wants(&self, pose: &ViewPose, budget: u64, frustum: &Frustum, wants: &mut Wants) {
        let mut room = budget;
        let near = radius_tiles(&self.catalog, pose.pos, self.cfg.fallback_radius_m);
        let n = near.len().max(1) as f64;
        for (k, i) in near.into_iter().enumerate() {
            if wants.seen.contains(&i) || !self.usable(i) || self.cache.level(i).is_some() {
                continue;
            }
            let Some(level) = self.usable_level(i, Level::Medium) else {
                continue;
            };
            let bytes = self.catalog.tiles[i].variants[level.index()].bytes;
            if bytes > room {
                break;
            }
            room -= bytes;
            let deadline = self.cfg.fallback_s * k as f64 / n;
            wants.push(self.want(i, level, deadline, frustum), false);
        }
    }

    /// The request order (`want_group`); within a group, tiles in view by priority and
    /// prefetches by deadline. Layered: a layer is drawn only over its ancestors' layers, so
    /// coarser levels first (the sort is stable: the order above holds within a level).
    fn ordered(&self, mut wanted: Vec<Want>, predicting: bool) -> Vec<Want> {
        let group = |w: &Want| want_group(w, self.cache.level(w.tile).is_some(), predicting);
        wanted.sort_by(|a, b| {
            group(a).cmp(&group(b)).then(if a.in_view {
                b.priority.total_cmp(&a.priority)
            } else {
                a.deadline.total_cmp(&b.deadline)
            })
        });
        if self.layered {
            wanted.sort_by_key(|w| {
                let g = group(w);
                (g.0, g.1, self.info[w.tile].key.level)
            });
        }
        wanted
    }

    /// The level to fetch `tile` at when the plan chose `level`: a paused download of another
    /// level is resumed instead when that level is at least as good or its remaining bytes are
    /// no more than `level`'s (a paused transfer still wanted is resumed, not restarted at
    /// another level: with the size rule alone the plant walk dropped 7% of its bytes).
    fn resume_level(&self, tile: usize, level: Level) -> Level {
        let Some(d) = self.state[tile].download.as_ref() else {
            return level;
        };
        if d.level == level || d.req.is_some() || !d.resumable || d.bytes.is_empty() {
            return level;
        }
        let size = |l: Level| self.catalog.tiles[tile].variants[l.index()].bytes;
        let left = d
            .total
            .unwrap_or(size(d.level))
            .saturating_sub(d.bytes.len() as u64);
        let better_than_resident = self.cache.level(tile).is_none_or(|r| d.level < r);
        if better_than_resident && (d.level <= level || left <= size(level)) {
            d.level
        } else {
            level
        }
    }

    pub(super) fn want(&self, tile: usize, level: Level, deadline: f64, f: &Frustum) -> Want {
        let in_view = self.in_view[tile];
        let t = &self.catalog.tiles[tile];
        let priority = if in_view {
            // SGSS eq. 10: P >= 1 is high priority; squash into 0.5..1.
            let p = priority(f, &t.bbox, self.info[tile].splats.max(1));
            let s = if p.is_finite() {
                1.0 / (1.0 + (-(p - 1.0)).exp())
            } else {
                0.0
            };
            0.5 + 0.5 * s
        } else {
            let h = self.cfg.predict_horizon_s.max(1e-3);
            0.49 * (-deadline.max(0.0) / h).exp()
        };
        Want {
            tile,
            level,
            priority: priority as f32,
            in_view,
            deadline,
            late: false,
            cover: false,
            covered: false,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn want(in_view: bool, deadline: f64, late: bool) -> Want {
        Want {
            tile: 0,
            level: Level::Low,
            priority: 0.5,
            in_view,
            deadline,
            late,
            cover: false,
            covered: false,
        }
    }

    #[test]
    fn overload_is_edf_at_low_against_the_link() {
        let cfg = PlanStepConfig {
            step_s: 0.02,
            latency_s: 0.0,
            ..PlanStepConfig::default()
        };
        // 1 MB/s: 0.5 MB due by 0.5 s (+ 0.5 s slack) fits, 1.2 MB by then does not.
        let link = LinkForecast::constant(1.0e6);
        assert!(!overloaded(&[(0.5, 500_000)], &link, &cfg, 0.5));
        assert!(overloaded(
            &[(0.5, 600_000), (0.2, 600_000)],
            &link,
            &cfg,
            0.5
        ));
        // The same bytes spread to 3 s fit; in-flight bytes come first and tip it over.
        let spread = || vec![(0.5, 600_000), (2.5, 600_000)];
        assert!(!overloaded(&spread(), &link, &cfg, 0.5));
        let busy = LinkForecast {
            in_flight_bytes: 2_000_000,
            ..LinkForecast::constant(1.0e6)
        };
        assert!(overloaded(&spread(), &busy, &cfg, 0.5));
        // Nothing due, non-finite deadlines, a zero step: no overload, no panic.
        assert!(!overloaded(&[], &link, &cfg, 0.5));
        assert!(!overloaded(
            &[(f64::NAN, 1), (f64::INFINITY, 1)],
            &link,
            &cfg,
            0.5
        ));
        let zero = PlanStepConfig { step_s: 0.0, ..cfg };
        assert!(!overloaded(&spread(), &link, &zero, 0.5));
    }

    #[test]
    fn the_planner_follows_a_resized_viewport() {
        let cfg = ClientConfig {
            width: 640,
            height: 480,
            ..ClientConfig::default()
        };
        let mut c = StreamClient::new("tileset.json", cfg);
        assert!((c.cfg.plan.intrinsics.aspect - 640.0 / 480.0).abs() < 1e-12);
        c.dirty = false;
        c.set_viewport(1280, 720);
        assert_eq!(c.cfg.plan.intrinsics.height_px, 720.0);
        assert!((c.cfg.plan.intrinsics.aspect - 1280.0 / 720.0).abs() < 1e-12);
        assert!(c.dirty, "a resize replans");
        // A zero size (a minimised window) stays finite.
        c.set_viewport(0, 0);
        assert_eq!(c.cfg.plan.intrinsics.aspect, 1.0);
        assert_eq!(c.cfg.plan.intrinsics.height_px, 1.0);
    }

    #[test]
    fn set_aside_is_moore_hodgson_the_largest_of_the_kept_goes() {
        let cfg = PlanStepConfig {
            step_s: 0.02,
            latency_s: 0.0,
            ..PlanStepConfig::default()
        };
        let link = LinkForecast::constant(1.0e6);
        // Tile 7 (800 kB by 1.0 s) fits alone; with tile 8 (400 kB by 1.1 s) the two do not,
        // and the larger, earlier one goes: then tile 8 and tile 9 (300 kB by 1.5 s) are on
        // time. Earliest deadline first with every job fetched would have made 8 late.
        let mut dues = vec![(1.0, 300_000, 9), (0.5, 800_000, 7), (0.6, 400_000, 8)];
        assert_eq!(set_aside(&mut dues, &link, &cfg, 0.5), vec![7]);
        // Everything fits: nothing set aside.
        let mut easy = vec![(0.5, 100_000, 1), (2.0, 100_000, 2)];
        assert!(set_aside(&mut easy, &link, &cfg, 0.5).is_empty());
        // A hole in view (due now) that cannot arrive within the slack is set aside before a
        // smaller prefetch that can.
        let mut view = vec![(0.0, 900_000, 3), (0.1, 200_000, 4)];
        assert_eq!(set_aside(&mut view, &link, &cfg, 0.5), vec![3]);
        // Jobs past the forecast's last step still count; none is set aside twice.
        let mut many: Vec<(f64, u64, usize)> = (0..50).map(|i| (0.1, 100_000, i)).collect();
        let aside = set_aside(&mut many, &link, &cfg, 0.5);
        assert_eq!(
            aside.len(),
            44,
            "0.6 s at 1 MB/s holds 6 of 50 tiles of 100 kB"
        );
        let mut sorted = aside.clone();
        sorted.sort_unstable();
        sorted.dedup();
        assert_eq!(sorted.len(), aside.len());
    }

    #[test]
    fn set_aside_wants_go_after_on_time_ones_and_repairs_and_before_upgrades() {
        let soon = want(false, 0.2, false);
        let repair = want(true, 0.0, false);
        let later = want(false, 3.0, false);
        let late = want(false, 0.3, true);
        let g = |w: &Want, held| want_group(w, held, true);
        assert!(g(&soon, false) < g(&repair, false));
        assert!(g(&repair, false) < g(&later, false));
        assert!(g(&later, false) < g(&late, false));
        // Every missing tile, late or not, before any upgrade.
        assert!(g(&late, false) < g(&soon, true));
        // A hole in view that was set aside waits behind the prefetches that can be on time;
        // without a prediction repairs come first.
        assert!(g(&later, false) < g(&want(true, 0.0, true), false));
        assert!(want_group(&repair, false, false) < want_group(&soon, false, false));
    }

    #[test]
    fn covers_go_first_and_holes_drawn_coarsely_after_the_prefetches() {
        let cover = Want {
            cover: true,
            ..want(false, 0.0, false)
        };
        let covered = Want {
            covered: true,
            ..want(true, 0.0, false)
        };
        let soon = want(false, 0.2, false);
        let repair = want(true, 0.0, false);
        let later = want(false, 8.0, false);
        let late = want(false, 0.3, true);
        let g = |w: &Want| want_group(w, false, true);
        assert!(g(&cover) < g(&soon) && g(&soon) < g(&repair));
        assert!(g(&repair) < g(&later) && g(&later) < g(&covered));
        assert!(g(&covered) < g(&late));
        // Still before any upgrade.
        assert!(want_group(&covered, false, true) < want_group(&soon, true, true));
    }
}
