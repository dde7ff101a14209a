//! Bootstrap of the client: `tileset.json` (variant URI templates, transforms), the root and
//! child subtree files (requests, retries), and the tiles they add to the catalog.

use super::*;

impl StreamClient {
    /// Issues the fetches of the subtrees in `keys` that are due (not loaded, not in flight,
    /// not waiting for a retry), while request slots are free.
    pub(super) fn request_subtrees(&mut self, keys: &[TileKey], actions: &mut Vec<Action>) {
        let Some(template) = self.root.as_ref().map(|r| r.subtree_template.clone()) else {
            return;
        };
        for &k in keys {
            let now = self.now;
            let Some(slot) = self.subtrees.get(&k) else {
                continue;
            };
            if slot.loaded || slot.given_up || slot.inflight || now < slot.retry_at {
                continue;
            }
            // Subtree files have their own `max_concurrent` slots: behind tile downloads that
            // kept every slot busy they arrived after the tiles they list entered the view
            // (most of the oracle's misses on the full-city walk were "late").
            if self.in_flight(false) >= self.cfg.max_concurrent {
                break;
            }
            let uri = expand_template(&template, k);
            match url::resolve(&self.base, &uri) {
                Ok(u) => {
                    let id = self.new_request(ReqKind::Subtree(k));
                    if let Some(slot) = self.subtrees.get_mut(&k) {
                        slot.inflight = true;
                    }
                    actions.push(Action::Fetch(FetchRequest {
                        id,
                        url: u,
                        range_start: 0,
                        if_range: None,
                        priority: 1.0,
                    }));
                }
                Err(e) => {
                    self.error(format!("subtree URI refused, not fetched: {e}"));
                    if let Some(slot) = self.subtrees.get_mut(&k) {
                        slot.given_up = true;
                    }
                    if k == TileKey::ROOT {
                        self.phase = Phase::Failed;
                    }
                }
            }
        }
    }

    /// A subtree arrived: its tiles join the catalog, its child subtrees become fetchable.
    pub(super) fn subtree_loaded(
        &mut self,
        key: TileKey,
        parsed: splat2tiles_tiles::tiling::load::SubtreeTiles,
    ) {
        if let Some(slot) = self.subtrees.get_mut(&key) {
            slot.loaded = true;
            slot.inflight = false;
        }
        self.add_tiles(parsed.tiles);
        for c in parsed.child_subtrees {
            if self.subtrees.len() >= MAX_TILES {
                break;
            }
            if let (Some(leaf), false) = (c.parent(), self.subtrees.contains_key(&c)) {
                self.subtrees.insert(c, SubtreeSlot::default());
                self.by_leaf.entry(leaf).or_default().push(c);
            }
        }
        if matches!(self.phase, Phase::RootSubtree) {
            self.phase = if self.info.is_empty() {
                self.error("no tile could be read from the tileset".into());
                Phase::Failed
            } else {
                Phase::Ready
            };
        }
        self.dirty = true;
    }

    pub(super) fn subtree_failed(&mut self, key: TileKey, msg: String) {
        self.error(format!("subtree {key:?}: {msg}"));
        let (max, base, now) = (self.cfg.max_retries, self.cfg.retry_base_s, self.now);
        let Some(slot) = self.subtrees.get_mut(&key) else {
            return;
        };
        slot.inflight = false;
        slot.failures += 1;
        if slot.failures > max {
            slot.given_up = true;
            if key == TileKey::ROOT {
                self.phase = Phase::Failed;
            }
        } else {
            slot.retry_at = now + base * f64::powi(2.0, slot.failures as i32 - 1);
        }
        self.dirty = true;
    }

    /// Takes the parts of `tileset.json` the client needs: variant URI templates (refusing
    /// the ones leaving the base), transforms; then waits for the root subtree.
    pub(super) fn init_root(&mut self, root: ImplicitRoot) {
        // Variant URI templates: tileset metadata `variantUris`, else content.uri as the
        // default variant (format unknown: decoded whole, never progressively).
        let meta = root
            .tileset
            .metadata
            .as_ref()
            .and_then(|m| m.get("properties"));
        let uris: Option<Vec<String>> = meta
            .and_then(|p| p.get("variantUris"))
            .and_then(|v| v.as_array())
            .map(|a| {
                a.iter()
                    .map(|s| s.as_str().unwrap_or("").to_string())
                    .collect()
            });
        self.default_variant = meta
            .and_then(|p| p.get("defaultVariant"))
            .and_then(|v| v.as_u64())
            .map_or(0, |v| (v as usize).min(LEVELS - 1));
        let mut templates: [Option<String>; LEVELS] = Default::default();
        match &uris {
            Some(u) if u.len() == LEVELS => {
                for (j, t) in u.iter().enumerate() {
                    if !t.is_empty() {
                        templates[j] = Some(t.clone());
                    }
                }
                self.progressive[Level::Best.index()] = true;
            }
            _ => templates[self.default_variant] = root.content_template.clone(),
        }
        if let Some(tpl) = &root.content_template
            && let Err(e) = url::resolve(&self.base, &expand_template(tpl, TileKey::ROOT))
        {
            self.error(format!("content.uri template refused, never fetched: {e}"));
        }
        // Layered content (`spec/layered-content.md`): ADD refinement at the implicit root.
        // Variants do not apply to it (`convert --layers` writes Best only, and a layer's
        // deltas describe its parent's Best splats), and a prefix of a layer lacks the deltas,
        // which follow the splats: whole Best files only, drawn once complete.
        self.layered = root.tileset.root.refine.as_deref() == Some("ADD");
        if self.layered {
            let best = templates[Level::Best.index()]
                .take()
                .or_else(|| root.content_template.clone());
            templates = Default::default();
            templates[Level::Best.index()] = best;
            self.progressive = [false; LEVELS];
            if !self.cfg.levels.contains(&Level::Best) {
                self.error("layered tileset: Best is not among the allowed levels".into());
            }
        }
        for (j, t) in templates.iter_mut().enumerate() {
            if !self.cfg.levels.contains(&Level::from_index(j)) {
                *t = None;
                continue;
            }
            if let Some(tpl) = t.as_deref()
                && let Err(e) = url::resolve(&self.base, &expand_template(tpl, TileKey::ROOT))
            {
                let msg = format!(
                    "{} content URI template refused, never fetched: {e}",
                    Level::from_index(j).name()
                );
                self.error(msg);
                *t = None;
            }
        }
        self.templates = templates;
        self.root_transform = root.root_transform;
        self.inv_root = root.root_transform.inverse();
        if !self.inv_root.is_finite() {
            self.error("root transform is not invertible".into());
            self.phase = Phase::Failed;
            return;
        }
        self.tile_to_world_base =
            root.root_transform * DMat4::from_mat3(splat2tiles_core::frame::y_up_to_z_up());
        self.root = Some(Box::new(root));
        self.subtrees.insert(TileKey::ROOT, SubtreeSlot::default());
        self.phase = Phase::RootSubtree;
    }

    /// Appends the tiles of a subtree to the catalog (parents before children; a tile whose
    /// parent is unknown, other than the root, is skipped).
    pub(super) fn add_tiles(&mut self, mut tiles: Vec<SubtreeTile>) {
        tiles.sort_by_key(|t| (t.key.level, t.key.z, t.key.y, t.key.x));
        for st in tiles {
            if self.index.contains_key(&st.key) {
                continue;
            }
            if self.info.len() >= MAX_TILES {
                self.error(format!("more than {MAX_TILES} tiles: the rest is ignored"));
                return;
            }
            let parent = st.key.parent().and_then(|p| self.index.get(&p).copied());
            if parent.is_none() && st.key != TileKey::ROOT {
                continue;
            }
            let best_guess = st
                .variant_bytes
                .map(|b| b.iter().copied().max().unwrap_or(0) as u64)
                .unwrap_or_else(|| st.splat_count.unwrap_or(16384) as u64 * 70)
                .max(1);
            let stand_in = stand_in_variants(best_guess);
            let mut urls: [Option<String>; LEVELS] = Default::default();
            let mut variants = [Variant {
                bytes: 0,
                utility: 0.0,
            }; LEVELS];
            for j in 0..LEVELS {
                let written = match st.variant_bytes {
                    Some(b) => b[j] > 0,
                    None => j == self.default_variant,
                };
                let bytes = st
                    .variant_bytes
                    .map(|b| b[j] as u64)
                    .filter(|b| *b > 0)
                    .unwrap_or(stand_in[j].bytes.max(1));
                let util = st
                    .variant_utility
                    .map(|u| u[j] as f64)
                    .filter(|u| *u >= 0.0 && u.is_finite())
                    .unwrap_or(STAND_IN_UTILITY[j]);
                let url = match (&self.templates[j], written && st.content_uri.is_some()) {
                    (Some(tpl), true) => {
                        url::resolve(&self.base, &expand_template(tpl, st.key)).ok()
                    }
                    _ => None,
                };
                variants[j] = Variant {
                    bytes,
                    utility: if url.is_some() { util.max(1e-6) } else { 0.0 },
                };
                urls[j] = url;
            }
            let sphere = st
                .bounding_box
                .map(|b| splat2tiles_tiles::select::box_sphere(&b, &self.root_transform));
            let me = self.catalog.tiles.len();
            let splats = st.splat_count.unwrap_or(0) as u64;
            self.catalog.tiles.push(CatalogTile {
                key: st.key,
                parent,
                children: vec![],
                bbox: st
                    .bounding_box
                    .map(|b| Obb::from_3dtiles(&b))
                    .unwrap_or(Obb::aabb(DVec3::ZERO, DVec3::ZERO)),
                geometric_error: st.geometric_error,
                splats,
                has_content: urls.iter().any(|u| u.is_some()),
                variants,
            });
            match parent {
                Some(p) => self.catalog.tiles[p].children.push(me),
                None => self.catalog.roots.push(me),
            }
            self.index.insert(st.key, me);
            self.info.push(TileInfo {
                key: st.key,
                urls,
                sphere,
                splats,
            });
            self.state.push(TileState::default());
            self.in_view.push(false);
            self.drawn.push(false);
            self.blend.push(0.0);
        }
    }

    pub(super) fn boot_failed(&mut self, kind: ReqKind, msg: String) {
        match kind {
            ReqKind::Tileset => {
                self.error(format!("{}: {msg}", self.tileset_url));
                self.boot_failures += 1;
                if self.boot_failures > self.cfg.max_retries {
                    self.phase = Phase::Failed;
                } else {
                    self.boot_retry_at = self.now
                        + self.cfg.retry_base_s * f64::powi(2.0, self.boot_failures as i32 - 1);
                }
            }
            ReqKind::Subtree(k) => self.subtree_failed(k, msg),
            ReqKind::Content(_) => {}
        }
    }
}
