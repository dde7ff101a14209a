//! Transfers: starting, pausing (keeping bytes) and resuming downloads with Range + If-Range,
//! response handling, retries with backoff, and freeing memory for the budget.

use super::*;

/// Doublings of the retry delay after memory refusals (at most 2^3 = 8 replan periods).
const MAX_REFUSAL_DOUBLINGS: u32 = 3;

/// A prefetch is paused for another want only when due this many seconds after it.
const PREEMPT_GUARD_S: f64 = 2.0;

impl StreamClient {
    pub(super) fn pause(&mut self, tile: usize, actions: &mut Vec<Action>) {
        let Some(d) = self.state[tile].download.as_mut() else {
            return;
        };
        let Some(req) = d.req else {
            return;
        };
        self.requests.remove(&req);
        actions.push(Action::Abort { id: req });
        if d.total.is_some_and(|t| d.bytes.len() as u64 == t) {
            // Every byte has arrived and only the end of the body has not: finish the tile
            // instead of pausing it (a resume would ask for the empty range past the end, which
            // a server answers 416).
            self.content_done(req, tile);
            return;
        }
        d.req = None;
        self.stats.aborts += 1;
        if !d.resumable {
            // No validator: bytes cannot be resumed safely.
            self.drop_download(tile);
        }
    }

    pub(super) fn drop_download(&mut self, tile: usize) {
        if let Some(d) = self.state[tile].download.take() {
            if let Some(r) = d.req {
                self.requests.remove(&r);
                self.pending_actions.push(Action::Abort { id: r });
            }
            if d.shown {
                self.remove_object(d.id);
            }
        }
    }

    pub(super) fn schedule(&mut self, actions: &mut Vec<Action>) {
        let wanted: HashMap<usize, Level> = self.wanted.iter().map(|w| (w.tile, w.level)).collect();
        // Pause downloads no longer wanted (or wanted at another level); a cover no longer
        // wanted is dropped: the view it stood in for is drawn or gone, and its bytes kept would
        // wait for a bare view of the same place.
        for i in 0..self.state.len() {
            let Some(d) = &self.state[i].download else {
                continue;
            };
            if d.req.is_some() && wanted.get(&i) != Some(&d.level) {
                let cover = d.cover;
                self.pause(i, actions);
                if cover {
                    self.drop_download(i);
                }
            }
        }
        let wants = self.wanted.clone();
        for w in wants {
            let s = &self.state[w.tile];
            if s.given_up || self.now < s.retry_at {
                continue;
            }
            if self.cache.level(w.tile).is_some_and(|l| l <= w.level) {
                continue;
            }
            if self.downloading(w.tile) {
                continue;
            }
            if self.in_flight(true) >= self.cfg.max_concurrent {
                // An upgrade of a held tile never pauses a download of a missing one.
                if self.cache.level(w.tile).is_some() {
                    break;
                }
                // Earliest deadline first: a want pauses (bytes kept) the in-flight prefetch
                // due latest, only when that one is due more than PREEMPT_GUARD_S after it.
                // Pausing the lowest-priority prefetch for every tile in view aborted more than
                // half the requests, and with no preemption between prefetches ones
                // due in 8 s held every slot while ones due in 1 s waited.
                // An upgrade in flight (its tile is drawn at a lower level meanwhile) gives way
                // to a missing tile first: with upgrades of the view never paused, four Best
                // upgrades held the link while tiles about to enter waited.
                let flying = |v: &&Want| self.downloading(v.tile);
                let upgrade = self
                    .wanted
                    .iter()
                    .filter(flying)
                    .filter(|v| self.cache.level(v.tile).is_some())
                    .min_by(|a, b| a.priority.total_cmp(&b.priority))
                    .map(|v| v.tile);
                // A hole drawn coarsely gives way to the wants before it, and takes no slot
                // from a prefetch.
                let covered = || {
                    self.wanted
                        .iter()
                        .filter(|v| v.covered && !w.covered && !w.late)
                        .filter(flying)
                        .min_by(|a, b| a.priority.total_cmp(&b.priority))
                        .map(|v| v.tile)
                };
                let victim = upgrade.or_else(covered).or_else(|| {
                    self.wanted
                        .iter()
                        .filter(|v| !w.covered && !v.in_view)
                        .filter(|v| v.deadline > w.deadline + PREEMPT_GUARD_S)
                        .filter(flying)
                        .max_by(|a, b| a.deadline.total_cmp(&b.deadline))
                        .map(|v| v.tile)
                });
                match victim {
                    Some(v) => self.pause(v, actions),
                    None => break,
                }
            }
            self.start(w, actions);
        }
    }

    pub(super) fn start(&mut self, w: Want, actions: &mut Vec<Action>) {
        let Some(url) = self.info[w.tile].urls[w.level.index()].clone() else {
            return;
        };
        if self.state[w.tile]
            .download
            .as_ref()
            .is_some_and(|d| d.level != w.level)
        {
            self.drop_download(w.tile);
        }
        // A download that cannot fit the budget (its size is in the subtree's metadata) is not
        // started: it would be refused on arrival and its bytes thrown away.
        let size = self.catalog.tiles[w.tile].variants[w.level.index()].bytes;
        let kept = self.state[w.tile]
            .download
            .as_ref()
            .map_or(0, |d| d.bytes.len() as u64);
        if size > 0 && !self.make_room(size.saturating_sub(kept)) {
            self.stats.rejected += 1;
            let msg = format!(
                "tile {:?}: does not fit the memory budget, not fetched",
                self.info[w.tile].key
            );
            self.retry_later(w.tile, msg);
            return;
        }
        let id = self.new_request(ReqKind::Content(w.tile));
        let progressive = self.progressive[w.level.index()];
        let fresh_scene = self.next_scene;
        let st = &mut self.state[w.tile];
        let d = st.download.get_or_insert_with(|| Download {
            level: w.level,
            id: fresh_scene,
            req: None,
            bytes: vec![],
            etag: None,
            total: None,
            stream: progressive.then(PrefixStream::new),
            shown: false,
            resumable: false,
            cover: false,
        });
        if d.id == fresh_scene {
            self.next_scene += 1;
        }
        d.req = Some(id);
        d.cover = w.cover;
        let resume = !d.bytes.is_empty() && d.etag.is_some();
        if !resume {
            d.bytes.clear();
            d.stream = progressive.then(PrefixStream::new);
        } else {
            self.stats.resumes += 1;
        }
        actions.push(Action::Fetch(FetchRequest {
            id,
            url,
            range_start: if resume { d.bytes.len() as u64 } else { 0 },
            if_range: if resume { d.etag.clone() } else { None },
            priority: w.priority,
        }));
    }

    /// The response head of a request: status, `ETag`, the start of `Content-Range` (206) and
    /// the full length of the resource when known.
    pub fn on_response(
        &mut self,
        id: RequestId,
        status: u16,
        etag: Option<&str>,
        content_range_start: Option<u64>,
        total_len: Option<u64>,
    ) {
        let Some(req) = self.requests.get_mut(&id) else {
            return;
        };
        req.responded = true;
        let kind = req.kind;
        let ok = status == 200 || (status == 206 && content_range_start.unwrap_or(0) == 0);
        match kind {
            ReqKind::Tileset | ReqKind::Subtree(_) => {
                if !ok {
                    self.requests.remove(&id);
                    self.pending_actions.push(Action::Abort { id });
                    self.boot_failed(kind, format!("HTTP {status}"));
                }
            }
            ReqKind::Content(tile) => {
                let Some(d) = self.state[tile].download.as_mut() else {
                    return;
                };
                match status {
                    200 => {
                        if !d.bytes.is_empty() {
                            // Validator changed (or no range support): restart cleanly.
                            self.stats.restarts += 1;
                            d.bytes.clear();
                            d.stream = d.stream.as_ref().map(|_| PrefixStream::new());
                            if d.shown {
                                d.shown = false;
                                let old = d.id;
                                d.id = self.next_scene;
                                self.next_scene += 1;
                                self.remove_object(old);
                            }
                        }
                        let d = self.state[tile].download.as_mut().expect("checked above");
                        d.total = total_len;
                        d.etag = etag.map(str::to_string);
                        d.resumable = d.etag.is_some();
                    }
                    206 if content_range_start == Some(d.bytes.len() as u64) => {
                        d.total = total_len;
                        if let Some(e) = etag {
                            d.etag = Some(e.to_string());
                        }
                    }
                    _ => {
                        let url = self.info[tile].urls[d.level.index()].clone();
                        let msg = format!(
                            "HTTP {status} for {}{}",
                            url.unwrap_or_default(),
                            if status == 206 {
                                " (Content-Range does not start where asked)"
                            } else {
                                ""
                            }
                        );
                        self.requests.remove(&id);
                        self.pending_actions.push(Action::Abort { id });
                        if let Some(d) = self.state[tile].download.as_mut() {
                            d.req = None;
                        }
                        self.content_failed(tile, msg, true);
                    }
                }
            }
        }
    }

    /// The next chunk of a response body (chunks arrive in order).
    pub fn on_data(&mut self, id: RequestId, chunk: &[u8], now_s: f64) {
        self.advance(now_s);
        let Some(req) = self.requests.get_mut(&id) else {
            return;
        };
        self.stats.bytes_received += chunk.len() as u64;
        self.bw.record(chunk.len() as f64, 0.0);
        match req.kind {
            ReqKind::Tileset | ReqKind::Subtree(_) => {
                if req.body.len() + chunk.len() > MAX_BOOTSTRAP_BYTES {
                    let kind = req.kind;
                    self.requests.remove(&id);
                    self.pending_actions.push(Action::Abort { id });
                    self.boot_failed(kind, "body too large".into());
                } else {
                    req.body.extend_from_slice(chunk);
                }
            }
            ReqKind::Content(tile) => self.content_data(id, tile, chunk),
        }
    }

    pub(super) fn content_data(&mut self, id: RequestId, tile: usize, chunk: &[u8]) {
        let Some(d) = self.state[tile].download.as_mut() else {
            return;
        };
        if d.req != Some(id) {
            return;
        }
        d.bytes.extend_from_slice(chunk);
        if let Some(total) = d.total
            && d.bytes.len() as u64 > total
        {
            let msg = format!("tile {:?}: body longer than announced", self.info[tile].key);
            self.abort_failed(tile, id, msg);
            return;
        }
        let pushed = d.stream.as_mut().map(|s| s.push(chunk));
        match pushed {
            Some(Err(e)) => {
                let msg = format!("tile {:?}: bad glb: {e}", self.info[tile].key);
                self.abort_failed(tile, id, msg);
                return;
            }
            Some(Ok(new)) if !new.is_empty() => {
                if d.shown {
                    let sid = d.id;
                    *self.scene_splats.entry(sid).or_default() += new.len() as u64;
                    self.updates.push(SceneUpdate::Append {
                        tile: sid,
                        splats: new,
                    });
                } else if self.in_view[tile] && self.cache.level(tile).is_none() {
                    self.show_partial(tile);
                }
            }
            _ => {}
        }
        if self.held_bytes() > self.cfg.memory_budget_bytes && !self.make_room(0) {
            self.stats.rejected += 1;
            let msg = format!(
                "tile {:?}: memory budget exceeded while downloading",
                self.info[tile].key
            );
            self.requests.remove(&id);
            self.pending_actions.push(Action::Abort { id });
            self.drop_download(tile);
            self.retry_later(tile, msg);
        }
    }

    /// Memory could not hold a tile: retry later (not a failure), after a replan period doubled
    /// per refusal since the tile was last stored, up to 8 periods. Without the doubling a view
    /// that needs more than the budget re-downloaded its tiles every period (the 50M walk at
    /// budgetMB 8: 2,235 tile downloads, 1 GB in 83 s, for 9 tiles held).
    pub(super) fn retry_later(&mut self, tile: usize, msg: String) {
        if self.stats.last_errors.len() >= KEPT_ERRORS {
            self.stats.last_errors.remove(0);
        }
        self.stats.last_errors.push(msg);
        let s = &mut self.state[tile];
        let periods = f64::powi(2.0, s.refusals.min(MAX_REFUSAL_DOUBLINGS) as i32);
        s.refusals = s.refusals.saturating_add(1);
        s.retry_at = self.now + self.cfg.replan_s.max(0.1) * periods;
        self.dirty = true;
    }

    pub(super) fn abort_failed(&mut self, tile: usize, id: RequestId, msg: String) {
        self.requests.remove(&id);
        self.pending_actions.push(Action::Abort { id });
        if let Some(d) = self.state[tile].download.as_mut() {
            d.req = None;
        }
        self.content_failed(tile, msg, true);
    }

    /// A content download failed: error, bytes dropped, retry with backoff.
    pub(super) fn content_failed(&mut self, tile: usize, msg: String, count_error: bool) {
        self.drop_download(tile);
        self.backoff(tile, msg, count_error);
    }

    pub(super) fn backoff(&mut self, tile: usize, msg: String, count_error: bool) {
        if count_error {
            self.error(msg);
        }
        let s = &mut self.state[tile];
        s.failures += 1;
        if s.failures > self.cfg.max_retries {
            s.given_up = true;
        } else {
            s.retry_at = self.now + self.cfg.retry_base_s * f64::powi(2.0, s.failures as i32 - 1);
        }
        self.dirty = true;
    }

    /// The body of a request is complete.
    pub fn on_done(&mut self, id: RequestId, now_s: f64) {
        self.advance(now_s);
        let Some(req) = self.requests.remove(&id) else {
            return;
        };
        match req.kind {
            ReqKind::Tileset => match parse_tileset_json(&req.body) {
                Ok(root) => self.init_root(root),
                Err(e) => self.boot_failed(ReqKind::Tileset, format!("bad tileset.json: {e}")),
            },
            ReqKind::Subtree(k) => {
                let Some(root) = self.root.as_ref() else {
                    return;
                };
                match parse_subtree_tiles(root, k, &req.body) {
                    Ok(p) => self.subtree_loaded(k, p),
                    Err(e) => self.subtree_failed(k, format!("bad subtree: {e}")),
                }
            }
            ReqKind::Content(tile) => self.content_done(id, tile),
        }
    }

    pub(super) fn content_done(&mut self, id: RequestId, tile: usize) {
        let Some(d) = self.state[tile].download.as_mut() else {
            return;
        };
        if d.req != Some(id) {
            return;
        }
        d.req = None;
        let key = self.info[tile].key;
        if let Some(total) = d.total
            && (d.bytes.len() as u64) < total
        {
            let msg = format!(
                "tile {key:?}: truncated body ({} of {total} bytes)",
                d.bytes.len()
            );
            if d.resumable {
                // Keep the bytes: the retry resumes with a Range request.
                self.backoff(tile, msg, true);
            } else {
                self.content_failed(tile, msg, true);
            }
            return;
        }
        // Check the content decodes (progressive: every splat arrived).
        let check = match &d.stream {
            Some(s) if s.is_complete() => Ok(()),
            Some(s) => Err(format!(
                "truncated or malformed tile ({} of {:?} splats)",
                s.decoded(),
                s.total()
            )),
            None => splat2tiles_tiles::variants::decode_variant(&d.bytes)
                .map(|_| ())
                .map_err(|e| e.to_string()),
        };
        if let Err(e) = check {
            self.content_failed(tile, format!("tile {key:?}: {e}"), true);
            return;
        }
        let Some(d) = self.state[tile].download.take() else {
            return;
        };
        let bytes = d.bytes.len() as u64;
        let visible: Vec<bool> = (0..self.info.len())
            .map(|i| self.in_view[i] || self.drawn[i])
            .collect();
        // Room for the tile among the other partial downloads.
        self.cache.config.capacity_bytes = self
            .cfg
            .memory_budget_bytes
            .saturating_sub(self.partial_bytes());
        let pos = self.history.last().map_or(DVec3::ZERO, |p| p.pos);
        let ctx = EvictContext {
            catalog: &self.catalog,
            pos,
            now: self.now,
            visible: &visible,
        };
        let res = self.cache.insert(tile, d.level, bytes, &ctx);
        self.dirty = true;
        match res {
            Inserted::Stored(victims) => {
                for v in victims {
                    self.state[v].content = None;
                    if let Some((sid, _)) = self.state[v].shown.take() {
                        self.remove_object(sid);
                    }
                }
                let st = &mut self.state[tile];
                st.content = Some(d.bytes);
                st.failures = 0;
                st.refusals = 0;
                if d.shown {
                    let old = st.shown.replace((d.id, d.level));
                    if let Some((sid, _)) = old {
                        self.remove_object(sid);
                    }
                }
            }
            Inserted::Kept => {
                if d.shown {
                    self.remove_object(d.id);
                }
            }
            Inserted::Rejected => {
                if d.shown {
                    self.remove_object(d.id);
                }
                self.stats.rejected += 1;
                self.retry_later(tile, format!("tile {key:?}: memory budget"));
            }
        }
    }

    /// The request failed in transport (connection reset, timeout, CORS...).
    pub fn on_error(&mut self, id: RequestId, message: &str, now_s: f64) {
        self.advance(now_s);
        let Some(req) = self.requests.remove(&id) else {
            return;
        };
        match req.kind {
            ReqKind::Tileset | ReqKind::Subtree(_) => self.boot_failed(req.kind, message.into()),
            ReqKind::Content(tile) => {
                let key = self.info[tile].key;
                let Some(d) = self.state[tile].download.as_mut() else {
                    return;
                };
                if d.req != Some(id) {
                    return;
                }
                d.req = None;
                let msg = format!("tile {key:?}: {message}");
                if d.resumable {
                    self.backoff(tile, msg, true);
                } else {
                    self.content_failed(tile, msg, true);
                }
            }
        }
    }

    /// Frees held bytes until `need` more fit the budget: paused downloads first (largest
    /// first), then resident tiles neither drawn nor in view (farthest first, no resident
    /// descendant). Returns whether they fit.
    pub(super) fn make_room(&mut self, need: u64) -> bool {
        let budget = self.cfg.memory_budget_bytes;
        // Seconds to each tile's next predicted use (infinity: none), built at the first
        // eviction and kept for the rest (the prediction does not change meanwhile).
        let mut next: Option<Vec<f64>> = None;
        while self.held_bytes() + need > budget {
            let paused = (0..self.state.len())
                .filter(|&i| {
                    self.state[i]
                        .download
                        .as_ref()
                        .is_some_and(|d| d.req.is_none() && !d.bytes.is_empty())
                })
                .max_by_key(|&i| self.state[i].download.as_ref().map_or(0, |d| d.bytes.len()));
            if let Some(i) = paused {
                self.drop_download(i);
                continue;
            }
            let pos = self.history.last().map_or(DVec3::ZERO, |p| p.pos);
            // The tile needed again last (Belady with the prediction): tiles no predicted view
            // holds first, farthest first; then the ones predicted latest. By distance alone the
            // flights evicted tiles prefetched for the road ahead (11-14 of flight
            // 37's misses after warm-up were evicted before they entered).
            let next = next.get_or_insert_with(|| {
                let mut v = vec![f64::INFINITY; self.info.len()];
                for &(i, dt) in &self.predicted {
                    v[i] = dt;
                }
                v
            });
            let victim = eviction_victim(
                self.cache
                    .resident()
                    .map(|(i, _)| i)
                    .filter(|&i| !self.in_view[i] && !self.drawn[i])
                    .filter(|&i| !self.has_resident_descendant(i))
                    .map(|i| (i, next[i], self.catalog.tiles[i].bbox.distance(pos))),
            );
            match victim {
                Some(v) => {
                    self.cache.remove(&self.catalog, v);
                    self.cache.evictions += 1;
                    self.state[v].content = None;
                    if let Some((sid, _)) = self.state[v].shown.take() {
                        self.remove_object(sid);
                    }
                }
                None => return false,
            }
        }
        true
    }

    pub(super) fn has_resident_descendant(&self, tile: usize) -> bool {
        let mut stack = self.catalog.tiles[tile].children.clone();
        while let Some(c) = stack.pop() {
            if self.cache.level(c).is_some() {
                return true;
            }
            stack.extend(self.catalog.tiles[c].children.iter().copied());
        }
        false
    }
}

/// The tile to evict among `(tile, seconds to its next predicted use (infinity: none), distance)`:
/// the one needed again last, farthest first among equals, then the higher index (NaN counts as
/// needed now and near).
fn eviction_victim(candidates: impl Iterator<Item = (usize, f64, f64)>) -> Option<usize> {
    let key = |v: f64| if v.is_nan() { f64::NEG_INFINITY } else { v };
    candidates
        .max_by(|a, b| {
            key(a.1)
                .total_cmp(&key(b.1))
                .then(key(a.2).total_cmp(&key(b.2)))
                .then(a.0.cmp(&b.0))
        })
        .map(|c| c.0)
}

#[cfg(test)]
mod tests {
    use super::eviction_victim;

    #[test]
    fn evicts_the_tile_needed_again_last_then_the_farthest() {
        // A far tile the prediction needs in 2 s stays; a near one never predicted goes.
        let c = [(0, 2.0, 500.0), (1, f64::INFINITY, 10.0), (2, 8.0, 20.0)];
        assert_eq!(eviction_victim(c.into_iter()), Some(1));
        // Without a prediction (all infinite): the farthest, as before.
        let c = [(0, f64::INFINITY, 5.0), (1, f64::INFINITY, 50.0)];
        assert_eq!(eviction_victim(c.into_iter()), Some(1));
        // All predicted: the latest use.
        let c = [(0, 1.0, 90.0), (1, 6.5, 1.0), (2, 3.0, 40.0)];
        assert_eq!(eviction_victim(c.into_iter()), Some(1));
        // NaN never wins over a finite key; ties go to the higher tile index; none: none.
        let c = [(3, f64::NAN, f64::NAN), (4, 0.5, 1.0), (2, 0.5, 1.0)];
        assert_eq!(eviction_victim(c.into_iter()), Some(4));
        assert_eq!(eviction_victim(std::iter::empty()), None);
    }
}
