//! Static tile residency for the native front-ends: re-runs `splat2tiles render`'s SSE selection
//! for the current camera and loads new tiles on a background thread (insert/remove updates).

use std::collections::{HashMap, HashSet};
use std::path::PathBuf;
use std::sync::mpsc::{Receiver, Sender, channel};

use glam::DMat4;
use splat2tiles::render::camera::Camera;
use splat2tiles::render::cli::{content_model, select_tiles};
use splat2tiles::splat::Splats;
use splat2tiles::tiling::load::LoadedTileset;

/// A change of the resident set for the renderer.
#[derive(Debug)]
pub enum TileUpdate {
    /// A tile's splats arrived: insert them (fades in).
    Insert {
        /// Renderer id.
        id: u64,
        /// Tile-local splats.
        splats: Box<Splats>,
        /// Tile-to-world matrix.
        tile_to_world: DMat4,
    },
    /// A tile left the selection: remove it (fades out).
    Remove {
        /// Renderer id.
        id: u64,
    },
}

type Loaded = (u64, PathBuf, Result<(Splats, [f64; 16], u64), String>);

/// Keeps the tiles selected for the camera resident, loading them off the render thread.
pub struct StaticTiles {
    ts: std::sync::Arc<LoadedTileset>,
    max_sse: f64,
    /// Selected and loaded (or loading) tiles by content path.
    ids: HashMap<PathBuf, u64>,
    loaded: HashSet<u64>,
    next_id: u64,
    jobs: Option<Sender<(u64, PathBuf)>>,
    results: Receiver<Loaded>,
    pending: usize,
    /// Removals held back while loads are in flight (no hole while children arrive).
    deferred: Vec<u64>,
    bytes_read: u64,
    errors: Vec<String>,
}

impl StaticTiles {
    /// Residency over `ts` with the given SSE threshold (pixels); starts the loader thread.
    pub fn new(ts: LoadedTileset, max_sse: f64) -> Self {
        let (jobs, job_rx) = channel::<(u64, PathBuf)>();
        let (res_tx, results) = channel::<Loaded>();
        let spawned = std::thread::Builder::new()
            .name("tile-loader".into())
            .spawn(move || {
                while let Ok((id, path)) = job_rx.recv() {
                    let r = std::fs::read(&path)
                        .map_err(|e| format!("{}: cannot read: {e}", path.display()))
                        .and_then(|b| {
                            let n = b.len() as u64;
                            splat2tiles::variants::decode_variant(&b)
                                .map(|(s, node)| (s, node, n))
                                .map_err(|e| format!("{}: {e}", path.display()))
                        });
                    if res_tx.send((id, path, r)).is_err() {
                        break;
                    }
                }
            })
            .is_ok();
        StaticTiles {
            ts: std::sync::Arc::new(ts),
            max_sse,
            ids: HashMap::new(),
            loaded: HashSet::new(),
            next_id: 0,
            jobs: spawned.then_some(jobs),
            results,
            pending: 0,
            deferred: Vec::new(),
            bytes_read: 0,
            errors: Vec::new(),
        }
    }

    /// The tileset.
    pub fn tileset(&self) -> &LoadedTileset {
        &self.ts
    }

    /// Loads in flight.
    pub fn pending(&self) -> usize {
        self.pending
    }

    /// Tile bytes read so far.
    pub fn bytes_read(&self) -> u64 {
        self.bytes_read
    }

    /// Load errors so far (each names the file).
    pub fn errors(&self) -> &[String] {
        &self.errors
    }

    /// Re-selects for `cam`: queues loads of newly selected tiles; returns inserts of every load
    /// finished since the last call (blocking until all are done when `wait`) and, once no load
    /// is in flight, removals of the tiles no longer selected.
    pub fn update(&mut self, cam: &Camera, wait: bool) -> Vec<TileUpdate> {
        let picked: HashSet<PathBuf> = select_tiles(&self.ts, cam, self.max_sse)
            .into_iter()
            .collect();
        let mut out = Vec::new();
        let gone: Vec<PathBuf> = self
            .ids
            .keys()
            .filter(|p| !picked.contains(*p))
            .cloned()
            .collect();
        for p in gone {
            if let Some(id) = self.ids.remove(&p)
                && self.loaded.remove(&id)
            {
                self.deferred.push(id);
            }
        }
        for p in picked {
            if self.ids.contains_key(&p) {
                continue;
            }
            let id = self.next_id;
            self.next_id += 1;
            self.ids.insert(p.clone(), id);
            match &self.jobs {
                Some(tx) if tx.send((id, p.clone())).is_ok() => self.pending += 1,
                _ => self
                    .errors
                    .push(format!("{}: loader thread unavailable", p.display())),
            }
        }
        loop {
            let got = if wait && self.pending > 0 {
                self.results.recv().ok()
            } else {
                self.results.try_recv().ok()
            };
            let Some((id, path, r)) = got else { break };
            self.pending = self.pending.saturating_sub(1);
            // A tile deselected while loading is dropped.
            if self.ids.get(&path) != Some(&id) {
                continue;
            }
            match r {
                Ok((splats, node, n)) => {
                    self.bytes_read += n;
                    self.loaded.insert(id);
                    out.push(TileUpdate::Insert {
                        id,
                        splats: Box::new(splats),
                        tile_to_world: content_model(&self.ts, &node),
                    });
                }
                Err(e) => self.errors.push(e),
            }
        }
        if self.pending == 0 {
            out.extend(self.deferred.drain(..).map(|id| TileUpdate::Remove { id }));
        }
        out
    }
}
