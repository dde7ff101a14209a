//! Scene reconciliation: which tiles are drawn (resident, ancestors, progressive partial
//! downloads) and the Insert / Append / Remove updates that bring the renderer in line.

use super::*;

impl StreamClient {
    /// Inserts the splats decoded so far of a tile's download as a new drawable.
    pub(super) fn show_partial(&mut self, tile: usize) {
        let Some(d) = self.state[tile].download.as_ref() else {
            return;
        };
        if d.shown || d.stream.is_none() {
            return;
        }
        let mut s = PrefixStream::new();
        let Ok(splats) = s.push(&d.bytes) else {
            return;
        };
        let Some(node) = s.node_matrix() else {
            return;
        };
        if splats.is_empty() {
            return;
        }
        let m = self.tile_to_world(&node);
        let d = self.state[tile].download.as_mut().expect("checked above");
        d.shown = true;
        let (sid, level) = (d.id, d.level);
        self.add_object(sid, tile, level, splats, m);
    }

    /// Emits a new drawable `sid` for `tile` and records its splat count.
    pub(super) fn add_object(
        &mut self,
        sid: u64,
        tile: usize,
        level: Level,
        splats: Splats,
        m: DMat4,
    ) {
        self.scene_splats.insert(sid, splats.len() as u64);
        self.updates.push(SceneUpdate::Insert {
            tile: sid,
            key: self.info[tile].key,
            level,
            splats,
            tile_to_world: m,
        });
    }

    pub(super) fn remove_object(&mut self, sid: u64) {
        self.layer_data.remove(&sid);
        if self.scene_splats.remove(&sid).is_some() {
            self.updates.push(SceneUpdate::Remove { tile: sid });
        }
    }

    /// Brings the scene in line with the drawn set (see the module docs).
    pub(super) fn reconcile_scene(&mut self) {
        let n = self.info.len();
        let mut drawn = vec![false; n];
        // Layered: a layer of the view set is drawn when it is resident and its parent layer is
        // drawn (the view set lists parents first); nothing stands in for a missing layer.
        for &v in self.view.iter().filter(|_| self.layered) {
            drawn[v] = self.cache.level(v).is_some()
                && self.catalog.tiles[v].parent.is_none_or(|p| drawn[p]);
        }
        for &v in self.view.iter().filter(|_| !self.layered) {
            if self.cache.level(v).is_some() {
                drawn[v] = true;
                continue;
            }
            let resident = self
                .catalog
                .ancestors(v)
                .find(|&p| self.cache.level(p).is_some());
            if let Some(p) = resident {
                drawn[p] = true;
            } else {
                let mut stack = self.catalog.tiles[v].children.clone();
                while let Some(c) = stack.pop() {
                    if self.cache.level(c).is_some() {
                        drawn[c] = true;
                    } else {
                        stack.extend(self.catalog.tiles[c].children.iter().copied());
                    }
                }
            }
        }
        // Insert what must be drawn first (the renderer cross-fades), then remove.
        for (i, &draw) in drawn.iter().enumerate() {
            let level = self.cache.level(i);
            let shown = self.state[i].shown;
            if draw
                && let Some(l) = level
                && shown.is_none_or(|(_, sl)| sl != l)
            {
                self.show_resident(i, l);
            }
        }
        for (i, &draw) in drawn.iter().enumerate() {
            if !draw && let Some((sid, _)) = self.state[i].shown.take() {
                self.remove_object(sid);
            }
            // Progressive drawables only for tiles of the view set with nothing resident.
            let show_partial = self.in_view[i] && self.cache.level(i).is_none();
            let partial_shown = self.state[i].download.as_ref().is_some_and(|d| d.shown);
            if partial_shown && !show_partial {
                let fresh = self.next_scene;
                let d = self.state[i].download.as_mut().expect("checked above");
                let old = d.id;
                d.shown = false;
                d.id = fresh;
                self.next_scene += 1;
                self.remove_object(old);
            } else if !partial_shown && show_partial {
                self.show_partial(i);
            }
        }
        self.drawn = drawn;
    }

    pub(super) fn show_resident(&mut self, i: usize, level: Level) {
        let Some(bytes) = self.state[i].content.as_ref() else {
            return;
        };
        match splat2tiles_tiles::variants::decode_variant(bytes) {
            Ok((splats, node)) => {
                let sid = self.next_scene;
                if self.layered {
                    match splat2tiles_tiles::layers::glb::read_layer(bytes) {
                        Ok(layer) => {
                            self.layer_data.insert(sid, (splats.clone(), layer));
                        }
                        Err(e) => {
                            let msg = format!("tile {:?}: layer: {e}", self.info[i].key);
                            self.cache.remove(&self.catalog, i);
                            self.state[i].content = None;
                            self.backoff(i, msg, true);
                            return;
                        }
                    }
                }
                self.next_scene += 1;
                let m = self.tile_to_world(&node);
                self.add_object(sid, i, level, splats, m);
                if let Some((old, _)) = self.state[i].shown.replace((sid, level)) {
                    self.remove_object(old);
                }
            }
            Err(e) => {
                let msg = format!("tile {:?}: {e}", self.info[i].key);
                self.cache.remove(&self.catalog, i);
                self.state[i].content = None;
                self.backoff(i, msg, true);
            }
        }
    }
}
