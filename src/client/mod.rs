//! Sans-IO streaming client: tileset bootstrap, view selection, prediction + deadline DP planning,
//! pause/resume of downloads and scene updates; the caller does the I/O and passes the time in.
//!
//! The caller (native [`native::Driver`], the wasm viewer's Fetch glue, a test transport) runs a
//! loop: [`StreamClient::update`] with the camera returns [`Action`]s (fetch / abort); responses
//! come back through [`StreamClient::on_response`], [`StreamClient::on_data`] (chunks, in order),
//! [`StreamClient::on_done`] or [`StreamClient::on_error`]; [`StreamClient::take_updates`] hands
//! out the [`SceneUpdate`]s for the renderer. No sockets, files, threads or clocks in here.
//!
//! Semantics:
//! * **Bootstrap**: `tileset.json`, then the root subtree; child subtree files are read when a
//!   view (current or predicted) would refine into them (the tile above stays selected until
//!   they arrive). Every URI is resolved against the tileset URL's folder; one leaving it
//!   (`..`, another origin, a scheme, a rooted path, `%`-escapes) is refused with an error.
//! * The **view set** is the REPLACE selection of `render::cli::select_tiles` (refine while
//!   `geometricError * fy / (distance to the bounding sphere) > max_sse`) restricted to tiles whose
//!   bounding sphere meets the camera's frustum.
//! * **Drawn**: each tile of the view set that is resident is drawn; for one that is not, its
//!   nearest resident ancestor stays drawn (else its topmost resident descendants). A Best tile of
//!   the view set that is downloading without a resident level is drawn progressively (Insert then
//!   Appends) beside that ancestor, which is removed once every needed tile is resident.
//! * **Memory**: `memory_budget_bytes` bounds the content bytes the client holds (resident tiles'
//!   glb bytes, kept so hidden tiles can be shown again, plus partial downloads kept for resume).
//! * **Pause/resume** (SGSS 3.3): a download whose tile is no longer wanted, or that is
//!   out-prioritised by a tile in view, is aborted and keeps its bytes; resumed with
//!   `range_start = bytes kept` and `if_range = ETag`; a 206 continues, a 200 restarts cleanly.

#[cfg(feature = "native")]
pub mod native;
pub mod updates;
pub mod url;

use std::collections::{HashMap, HashSet};

use glam::{DMat4, DVec3};

use crate::encode::prefix::PrefixStream;
use crate::render::camera::Camera;
use crate::splat::Splats;
use crate::stream::bandwidth::EwmaBandwidth;
use crate::stream::cache::{Cache, CacheConfig, EvictContext, Inserted};
use crate::stream::catalog::{
    CatalogTile, LEVELS, Level, STAND_IN_UTILITY, TileCatalog, Variant, stand_in_variants,
};
use crate::stream::geom::{Frustum, Obb, ViewPose};
use crate::stream::planner::{PlanStepConfig, plan_visible};
use crate::stream::predict::{
    ConstantVelocity, LinearExtrapolation, Predictor, Reactive, needs_fallback,
};
use crate::stream::priority::priority;
use crate::tiling::TileKey;
use crate::tiling::load::{
    ImplicitRoot, SubtreeTile, expand_template, parse_subtree_tiles, parse_tileset_json,
};

/// Identifies one request issued by the client.
pub type RequestId = u64;

/// Largest `tileset.json` or subtree body accepted (bytes).
pub const MAX_BOOTSTRAP_BYTES: usize = 64 << 20;

/// Most tiles (plus pending subtrees) the bootstrap reads; a hostile tileset stops there.
pub const MAX_TILES: usize = 1 << 20;

/// Error messages kept in [`ClientStats::last_errors`].
const KEPT_ERRORS: usize = 32;

/// Which trajectory predictor feeds the planner.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PredictorKind {
    /// No prediction: plan for the current view only.
    Reactive,
    /// Latest velocity continued (after 5 s of history; reactive before).
    ConstantVelocity,
    /// Least-squares extrapolation over 2 s (after 5 s of history; reactive before).
    #[default]
    Linear,
}

/// Client settings.
#[derive(Debug, Clone, PartialEq)]
pub struct ClientConfig {
    /// Viewport width in pixels (planning intrinsics).
    pub width: u32,
    /// Viewport height in pixels (planning intrinsics).
    pub height: u32,
    /// Vertical field of view in degrees (planning intrinsics).
    pub fov_y_deg: f64,
    /// Refine a tile while its screen-space error exceeds this many pixels.
    pub max_sse: f64,
    /// Skip tiles whose bounding sphere is outside the view frustum (false: the whole
    /// `select_tiles` selection, as `splat2tiles render` draws).
    pub frustum_cull: bool,
    /// Content bytes the client may hold (resident tiles + partial downloads).
    pub memory_budget_bytes: u64,
    /// Requests in flight at most.
    pub max_concurrent: usize,
    /// Levels the client may download (the wasm build decodes only Best and Low).
    pub levels: Vec<Level>,
    /// Replan period in seconds (also replans when the view set changes or a download ends).
    pub replan_s: f64,
    /// Planner settings (DP step, horizon, urgent deadline, algorithm, latency).
    pub plan: PlanStepConfig,
    /// Bandwidth estimate (bytes/s) before the first measurement.
    pub initial_bandwidth: f64,
    /// Trajectory predictor.
    pub predictor: PredictorKind,
    /// Seconds ahead the predicted poses reach.
    pub predict_horizon_s: f64,
    /// Seconds between predicted poses.
    pub predict_step_s: f64,
    /// Retries of a failed request before the tile (or subtree) is given up.
    pub max_retries: u32,
    /// First retry delay in seconds (doubles per failure).
    pub retry_base_s: f64,
}

impl Default for ClientConfig {
    fn default() -> Self {
        let levels = if cfg!(feature = "native") {
            Level::ALL.to_vec()
        } else {
            vec![Level::Best, Level::Low]
        };
        ClientConfig {
            width: 1280,
            height: 720,
            fov_y_deg: 50.0,
            max_sse: 16.0,
            frustum_cull: true,
            memory_budget_bytes: 512 << 20,
            max_concurrent: 6,
            levels,
            replan_s: 2.5,
            plan: PlanStepConfig::default(),
            initial_bandwidth: 2.0e6,
            predictor: PredictorKind::Linear,
            predict_horizon_s: 10.0,
            predict_step_s: 0.5,
            max_retries: 3,
            retry_base_s: 0.5,
        }
    }
}

/// Something the caller must do.
#[derive(Debug, Clone, PartialEq)]
pub enum Action {
    /// Start a GET.
    Fetch(FetchRequest),
    /// Cancel a request in flight; further callbacks for it are ignored.
    Abort {
        /// The request.
        id: RequestId,
    },
}

/// One GET to issue.
#[derive(Debug, Clone, PartialEq)]
pub struct FetchRequest {
    /// Identifies the request in the callbacks.
    pub id: RequestId,
    /// Absolute URL or path (the tileset URL's base + a checked relative URI).
    pub url: String,
    /// First byte wanted (`Range: bytes=N-`); 0 = the whole resource.
    pub range_start: u64,
    /// ETag to send as `If-Range` when resuming.
    pub if_range: Option<String>,
    /// 0..1, higher = sooner; >= 0.5 maps to fetch priority "high", below to "low".
    pub priority: f32,
}

/// A change of the scene for the renderer.
#[derive(Debug, Clone, PartialEq)]
pub enum SceneUpdate {
    /// A new drawable: splats in tile coordinates and their world matrix.
    Insert {
        /// Scene id, unique per insertion (one (tile, level) download or re-show).
        tile: u64,
        /// Implicit address of the tile.
        key: TileKey,
        /// Level of the content.
        level: Level,
        /// Splats (tile-relative positions, as the glb holds them).
        splats: Splats,
        /// Tile to world: root transform * y-up to z-up * glb node matrix.
        tile_to_world: DMat4,
    },
    /// More splats of a drawable being streamed (same frame as its Insert).
    Append {
        /// Scene id.
        tile: u64,
        /// The new splats.
        splats: Splats,
    },
    /// Drop a drawable.
    Remove {
        /// Scene id.
        tile: u64,
    },
}

/// Counters and gauges of a client.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ClientStats {
    /// Bootstrap done (catalog built).
    pub ready: bool,
    /// Tiles in the catalog.
    pub tiles: usize,
    /// Splats in the scene (inserted + appended - removed).
    pub resident_splats: u64,
    /// Drawables in the scene.
    pub scene_objects: usize,
    /// Tiles fully downloaded and held.
    pub resident_tiles: usize,
    /// Content bytes held: resident tiles plus partial downloads.
    pub cache_bytes: u64,
    /// Bandwidth estimate in bytes/s.
    pub bandwidth: f64,
    /// Requests in flight.
    pub pending_fetches: usize,
    /// Body bytes received.
    pub bytes_received: u64,
    /// Errors recorded (HTTP status, refused URI, bad or truncated body, transport).
    pub errors: u64,
    /// The latest error messages (at most 32).
    pub last_errors: Vec<String>,
    /// Downloads paused with bytes kept.
    pub paused_tiles: usize,
    /// Downloads aborted (paused or dropped).
    pub aborts: u64,
    /// Downloads resumed with a Range request.
    pub resumes: u64,
    /// Resumes answered 200 (validator changed): restarted from byte 0.
    pub restarts: u64,
    /// Tiles given up after too many failures.
    pub failed_tiles: usize,
    /// Downloads whose result the memory budget could not hold.
    pub rejected: u64,
    /// Tiles evicted from the cache.
    pub evictions: u64,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum ReqKind {
    Tileset,
    Subtree(TileKey),
    Content(usize),
}

#[derive(Debug)]
struct Request {
    kind: ReqKind,
    body: Vec<u8>,
    responded: bool,
}

/// A download of one (tile, level), in flight or paused.
#[derive(Debug)]
struct Download {
    level: Level,
    /// Scene id its progressive drawable uses.
    id: u64,
    req: Option<RequestId>,
    bytes: Vec<u8>,
    etag: Option<String>,
    total: Option<u64>,
    stream: Option<PrefixStream>,
    shown: bool,
    /// Whether the bytes kept may be resumed (an ETag was given).
    resumable: bool,
}

#[derive(Debug, Default)]
struct TileState {
    download: Option<Download>,
    /// Content bytes of the resident level (mirrors the cache entry).
    content: Option<Vec<u8>>,
    /// Drawable of the complete content: scene id and level.
    shown: Option<(u64, Level)>,
    failures: u32,
    retry_at: f64,
    given_up: bool,
}

/// Static facts of a catalog tile.
#[derive(Debug, Clone)]
struct TileInfo {
    key: TileKey,
    /// Resolved URL per level (None: not written, not allowed or refused).
    urls: [Option<String>; LEVELS],
    /// World-space bounding sphere (centre, radius), if the tile has a box.
    sphere: Option<(DVec3, f64)>,
    splats: u64,
}

#[derive(Debug)]
enum Phase {
    NeedTileset,
    RootSubtree,
    Ready,
    Failed,
}

/// Load state of one subtree file.
#[derive(Debug, Clone, Default)]
struct SubtreeSlot {
    inflight: bool,
    loaded: bool,
    given_up: bool,
    failures: u32,
    retry_at: f64,
}

#[derive(Debug, Clone, Copy)]
struct Want {
    tile: usize,
    level: Level,
    priority: f32,
    in_view: bool,
}

/// The streaming client (see the module docs).
pub struct StreamClient {
    cfg: ClientConfig,
    tileset_url: String,
    base: String,
    phase: Phase,
    boot_failures: u32,
    boot_retry_at: f64,
    root: Option<Box<ImplicitRoot>>,
    templates: [Option<String>; LEVELS],
    default_variant: usize,
    index: HashMap<TileKey, usize>,
    subtrees: HashMap<TileKey, SubtreeSlot>,
    by_leaf: HashMap<TileKey, Vec<TileKey>>,
    subtree_wants: Vec<TileKey>,
    predicted_subtrees: Vec<TileKey>,
    catalog: TileCatalog,
    info: Vec<TileInfo>,
    state: Vec<TileState>,
    root_transform: DMat4,
    inv_root: DMat4,
    tile_to_world_base: DMat4,
    progressive: [bool; LEVELS],
    cache: Cache,
    bw: EwmaBandwidth,
    predictor: Box<dyn Predictor + Send>,
    history: Vec<ViewPose>,
    requests: HashMap<RequestId, Request>,
    next_req: RequestId,
    next_scene: u64,
    pending_actions: Vec<Action>,
    updates: Vec<SceneUpdate>,
    scene_splats: HashMap<u64, u64>,
    in_view: Vec<bool>,
    view: Vec<usize>,
    drawn: Vec<bool>,
    wanted: Vec<Want>,
    last_plan: f64,
    dirty: bool,
    now: f64,
    stats: ClientStats,
}

impl std::fmt::Debug for StreamClient {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("StreamClient")
            .field("tileset_url", &self.tileset_url)
            .field("phase", &self.phase)
            .field("stats", &self.stats())
            .finish_non_exhaustive()
    }
}

fn predictor_of(kind: PredictorKind) -> Box<dyn Predictor + Send> {
    match kind {
        PredictorKind::Reactive => Box::new(Reactive),
        PredictorKind::ConstantVelocity => Box::new(ConstantVelocity::default()),
        PredictorKind::Linear => Box::new(LinearExtrapolation::default()),
    }
}

impl StreamClient {
    /// A client for the tileset at `tileset_url` (http(s) URL, `file://` URL or path); the first
    /// [`update`](Self::update) asks for `tileset.json`.
    pub fn new(tileset_url: &str, cfg: ClientConfig) -> Self {
        let mut cfg = cfg;
        cfg.plan.intrinsics.fov_y_deg = cfg.fov_y_deg;
        cfg.plan.intrinsics.height_px = cfg.height.max(1) as f64;
        cfg.plan.intrinsics.aspect = cfg.width.max(1) as f64 / cfg.height.max(1) as f64;
        cfg.plan.max_sse = cfg.max_sse;
        cfg.max_concurrent = cfg.max_concurrent.max(1);
        let bw = EwmaBandwidth::new(cfg.initial_bandwidth, 0.3, 0.5);
        let cache = Cache::new(CacheConfig {
            capacity_bytes: cfg.memory_budget_bytes,
            ..CacheConfig::default()
        });
        StreamClient {
            predictor: predictor_of(cfg.predictor),
            base: url::base_of(tileset_url).to_string(),
            tileset_url: tileset_url.to_string(),
            cfg,
            phase: Phase::NeedTileset,
            boot_failures: 0,
            boot_retry_at: f64::NEG_INFINITY,
            root: None,
            templates: Default::default(),
            default_variant: 0,
            index: HashMap::new(),
            subtrees: HashMap::new(),
            by_leaf: HashMap::new(),
            subtree_wants: vec![],
            predicted_subtrees: vec![],
            catalog: TileCatalog {
                tiles: vec![],
                roots: vec![],
                source: crate::stream::catalog::VariantSource::StandIn,
            },
            info: vec![],
            state: vec![],
            root_transform: DMat4::IDENTITY,
            inv_root: DMat4::IDENTITY,
            tile_to_world_base: DMat4::IDENTITY,
            progressive: [false; LEVELS],
            cache,
            bw,
            history: vec![],
            requests: HashMap::new(),
            next_req: 1,
            next_scene: 1,
            pending_actions: vec![],
            updates: vec![],
            scene_splats: HashMap::new(),
            in_view: vec![],
            view: vec![],
            drawn: vec![],
            wanted: vec![],
            last_plan: f64::NEG_INFINITY,
            dirty: true,
            now: 0.0,
            stats: ClientStats::default(),
        }
    }

    /// The configuration in use (intrinsics filled from width, height and field of view).
    pub fn config(&self) -> &ClientConfig {
        &self.cfg
    }

    /// The tile catalog (empty until the bootstrap is done); boxes in the tileset frame.
    pub fn catalog(&self) -> &TileCatalog {
        &self.catalog
    }

    /// Root transform of the tileset (tileset frame to world).
    pub fn root_transform(&self) -> DMat4 {
        self.root_transform
    }

    /// Tiles fully downloaded and held, with their level, in catalog order.
    pub fn resident(&self) -> Vec<(TileKey, Level)> {
        self.cache
            .resident()
            .map(|(i, e)| (self.info[i].key, e.level))
            .collect()
    }

    /// Tiles whose complete content is in the scene: key, level, scene id.
    pub fn drawn(&self) -> Vec<(TileKey, Level, u64)> {
        self.state
            .iter()
            .enumerate()
            .filter_map(|(i, s)| s.shown.map(|(id, l)| (self.info[i].key, l, id)))
            .collect()
    }

    /// The view set of the last camera (see the module docs).
    pub fn view_set(&self) -> Vec<TileKey> {
        self.view.iter().map(|&i| self.info[i].key).collect()
    }

    /// Whether scene updates are waiting for [`Self::take_updates`] (a driver that runs
    /// [`Self::update`] between frames has not drawn them yet).
    pub fn has_updates(&self) -> bool {
        !self.updates.is_empty()
    }

    /// Takes the scene updates produced since the last call, in order; a drawable inserted and
    /// removed since then is left out (`updates::coalesce`).
    pub fn take_updates(&mut self) -> Vec<SceneUpdate> {
        updates::coalesce(std::mem::take(&mut self.updates))
    }

    /// Counters and gauges.
    pub fn stats(&self) -> ClientStats {
        let mut s = self.stats.clone();
        s.ready = matches!(self.phase, Phase::Ready);
        s.tiles = self.info.len();
        s.resident_splats = self.scene_splats.values().sum();
        s.scene_objects = self.scene_splats.len();
        s.resident_tiles = self.cache.len();
        s.cache_bytes = self.held_bytes();
        s.bandwidth = self.bw.estimate();
        s.pending_fetches = self.requests.len();
        s.paused_tiles = self
            .state
            .iter()
            .filter(|t| t.download.as_ref().is_some_and(|d| d.req.is_none()))
            .count();
        s.failed_tiles = self.state.iter().filter(|t| t.given_up).count();
        s.evictions = self.cache.evictions;
        s
    }

    /// Nothing in flight, nothing queued, and nothing more wanted for the last camera.
    pub fn is_idle(&self) -> bool {
        if !self.requests.is_empty() || !self.pending_actions.is_empty() {
            return false;
        }
        match self.phase {
            Phase::Failed => true,
            Phase::NeedTileset | Phase::RootSubtree => false,
            Phase::Ready => {
                !self.dirty
                    && self
                        .subtree_wants
                        .iter()
                        .all(|k| self.subtrees.get(k).is_none_or(|s| s.loaded || s.given_up))
                    && self.wanted.iter().all(|w| {
                        let s = &self.state[w.tile];
                        s.given_up || self.cache.level(w.tile).is_some_and(|l| l <= w.level)
                    })
            }
        }
    }

    fn held_bytes(&self) -> u64 {
        self.cache.used() + self.partial_bytes()
    }

    fn partial_bytes(&self) -> u64 {
        self.state
            .iter()
            .filter_map(|t| t.download.as_ref())
            .map(|d| d.bytes.len() as u64)
            .sum()
    }

    fn error(&mut self, msg: String) {
        self.stats.errors += 1;
        if self.stats.last_errors.len() >= KEPT_ERRORS {
            self.stats.last_errors.remove(0);
        }
        self.stats.last_errors.push(msg);
    }

    /// Advances the clock; time with requests in flight counts as link-busy time.
    fn advance(&mut self, now: f64) {
        if !now.is_finite() {
            return;
        }
        if now > self.now {
            if !self.requests.is_empty() {
                self.bw.record(0.0, now - self.now);
            }
            self.now = now;
        }
    }

    fn new_request(&mut self, kind: ReqKind) -> RequestId {
        let id = self.next_req;
        self.next_req += 1;
        self.requests.insert(
            id,
            Request {
                kind,
                body: vec![],
                responded: false,
            },
        );
        id
    }

    /// One step: takes the camera (same world frame as `splat2tiles render`) at time `now_s`,
    /// replans when due and returns the fetches and aborts to perform.
    pub fn update(&mut self, now_s: f64, camera: &Camera) -> Vec<Action> {
        self.advance(now_s);
        self.bw.tick(self.now);
        let mut actions = std::mem::take(&mut self.pending_actions);
        match self.phase {
            Phase::NeedTileset => {
                if self.requests.is_empty() && self.now >= self.boot_retry_at {
                    let id = self.new_request(ReqKind::Tileset);
                    actions.push(Action::Fetch(FetchRequest {
                        id,
                        url: self.tileset_url.clone(),
                        range_start: 0,
                        if_range: None,
                        priority: 1.0,
                    }));
                }
            }
            Phase::RootSubtree => self.request_subtrees(&[TileKey::ROOT], &mut actions),
            Phase::Ready => {
                if camera_ok(camera) {
                    self.stream_step(camera, &mut actions);
                }
            }
            Phase::Failed => {}
        }
        actions
    }

    /// Issues the fetches of the subtrees in `keys` that are due (not loaded, not in flight,
    /// not waiting for a retry), while request slots are free.
    fn request_subtrees(&mut self, keys: &[TileKey], actions: &mut Vec<Action>) {
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
            if self.requests.len() >= self.cfg.max_concurrent {
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
    fn subtree_loaded(&mut self, key: TileKey, parsed: crate::tiling::load::SubtreeTiles) {
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

    fn subtree_failed(&mut self, key: TileKey, msg: String) {
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
    fn init_root(&mut self, root: ImplicitRoot) {
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
            root.root_transform * DMat4::from_mat3(crate::frame::y_up_to_z_up());
        self.root = Some(Box::new(root));
        self.subtrees.insert(TileKey::ROOT, SubtreeSlot::default());
        self.phase = Phase::RootSubtree;
    }

    /// Appends the tiles of a subtree to the catalog (parents before children; a tile whose
    /// parent is unknown, other than the root, is skipped).
    fn add_tiles(&mut self, mut tiles: Vec<SubtreeTile>) {
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
            let sphere = st.bounding_box.map(|b| {
                let corners = crate::render::cli::box_corners(&b)
                    .map(|c| self.root_transform.transform_point3(c));
                let centre = corners.iter().copied().sum::<DVec3>() / 8.0;
                let radius = corners
                    .iter()
                    .map(|c| c.distance(centre))
                    .fold(0.0, f64::max);
                (centre, radius)
            });
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
        }
    }

    /// World matrix of a tile's content given its glb node matrix.
    fn tile_to_world(&self, node: &[f64; 16]) -> DMat4 {
        self.tile_to_world_base * DMat4::from_cols_array(node)
    }

    /// The view set of a camera: REPLACE selection by screen-space error over the bounding
    /// sphere (as `select_tiles`), skipping subtrees whose sphere is outside the frustum; plus
    /// the unread subtree files the selection would refine into (the tile above them is
    /// selected until they are read).
    fn select(&self, cam: &Camera) -> (Vec<usize>, Vec<TileKey>) {
        let eye = cam.center();
        let rot_t = cam.rotation().transpose();
        let mut out = vec![];
        let mut wants = vec![];
        let mut stack: Vec<usize> = self.catalog.roots.iter().rev().copied().collect();
        while let Some(i) = stack.pop() {
            let t = &self.catalog.tiles[i];
            let distance = match self.info[i].sphere {
                Some((c, r)) => {
                    if self.cfg.frustum_cull && !sphere_in_view(cam, rot_t * (c - eye), r) {
                        continue;
                    }
                    (c.distance(eye) - r).max(1e-9)
                }
                None => 1e-9,
            };
            let sse = t.geometric_error * cam.fy / distance;
            let refine = sse > self.cfg.max_sse;
            let before = wants.len();
            if refine && let Some(below) = self.by_leaf.get(&t.key) {
                wants.extend(below.iter().copied().filter(|k| {
                    self.subtrees
                        .get(k)
                        .is_some_and(|s| !s.loaded && !s.given_up)
                }));
            }
            if refine && wants.len() == before && !t.children.is_empty() {
                stack.extend(t.children.iter().rev().copied());
            } else if t.has_content {
                out.push(i);
            }
        }
        (out, wants)
    }

    fn pose_of(&self, cam: &Camera) -> ViewPose {
        let m = self.inv_root * cam.world_from_camera;
        let pos = m.w_axis.truncate();
        let fwd = m.transform_vector3(DVec3::Z).normalize_or(DVec3::X);
        ViewPose {
            t: self.now,
            pos,
            yaw: fwd.y.atan2(fwd.x),
            pitch: fwd.z.clamp(-1.0, 1.0).asin(),
        }
    }

    fn stream_step(&mut self, camera: &Camera, actions: &mut Vec<Action>) {
        let n = self.info.len();
        // 1. Pose history (tileset frame) for the predictor.
        let pose = self.pose_of(camera);
        if self.history.last().is_some_and(|p| p.t >= pose.t) {
            self.history.pop();
        }
        self.history.push(pose);
        let keep_from = self.now - 10.0;
        let drop = self.history.iter().take_while(|p| p.t < keep_from).count();
        self.history.drain(..drop);
        // 2. View set.
        let (view, wants) = self.select(camera);
        self.request_subtrees(&wants, actions);
        self.subtree_wants = wants;
        let changed = view != self.view;
        self.view = view;
        self.in_view = vec![false; n];
        for &i in &self.view {
            self.in_view[i] = true;
        }
        self.cache.touch(&self.view, self.now);
        // 3. Plan.
        if self.dirty || changed || self.now - self.last_plan >= self.cfg.replan_s {
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

    fn usable(&self, i: usize) -> bool {
        let s = &self.state[i];
        !s.given_up && self.info[i].urls.iter().any(|u| u.is_some())
    }

    /// The usable level nearest to `want`: the best one not better than it, else the worst
    /// usable one better than it.
    fn usable_level(&self, i: usize, want: Level) -> Option<Level> {
        let urls = &self.info[i].urls;
        (want.index()..LEVELS)
            .find(|&j| urls[j].is_some())
            .or_else(|| (0..want.index()).rev().find(|&j| urls[j].is_some()))
            .map(Level::from_index)
    }

    fn replan(&mut self, camera: &Camera, pose: &ViewPose) {
        self.last_plan = self.now;
        self.dirty = false;
        self.predicted_subtrees.clear();
        let predicted = if needs_fallback(self.predictor.as_ref(), &self.history) {
            vec![]
        } else {
            self.predictor.predict(
                &self.history,
                self.cfg.predict_horizon_s,
                self.cfg.predict_step_s,
            )
        };
        let mut first = vec![f64::INFINITY; self.info.len()];
        for &i in &self.view {
            first[i] = 0.0;
        }
        for p in &predicted {
            let cam = Camera {
                world_from_camera: self.root_transform * p.world_from_camera(),
                ..*camera
            };
            let dt = (p.t - self.now).max(0.0);
            let (vis, wants) = self.select(&cam);
            for i in vis {
                first[i] = first[i].min(dt);
            }
            for k in wants {
                if !self.predicted_subtrees.contains(&k) {
                    self.predicted_subtrees.push(k);
                }
            }
        }
        let firsts: Vec<(usize, f64)> = first
            .iter()
            .enumerate()
            .filter(|(i, t)| t.is_finite() && self.usable(*i))
            .map(|(i, t)| (i, *t))
            .collect();
        let pinned: u64 = self
            .cache
            .resident()
            .filter(|(i, _)| self.in_view[*i] || self.drawn[*i])
            .map(|(_, e)| e.bytes)
            .sum();
        let budget = self
            .cfg
            .memory_budget_bytes
            .saturating_sub(pinned)
            .saturating_sub(self.partial_bytes());
        let (cands, plan) = plan_visible(
            &self.catalog,
            pose.pos,
            &firsts,
            &self.cfg.plan,
            self.bw.estimate(),
            |i| self.cache.level(i),
            budget,
        );
        let frustum = Frustum::new(pose, &self.cfg.plan.intrinsics);
        let mut wanted: Vec<Want> = vec![];
        let mut seen = HashSet::new();
        for f in &plan.fetches {
            let c = &cands[f.candidate];
            let Some(level) = self.usable_level(c.tile, f.level) else {
                continue;
            };
            if seen.insert(c.tile) {
                wanted.push(self.want(c.tile, level, c.deadline, &frustum));
            }
        }
        // Every tile of the view set is needed whatever the plan says.
        for i in self.view.clone() {
            if self.usable(i)
                && self.cache.level(i).is_none()
                && !seen.contains(&i)
                && let Some(level) = self.usable_level(i, Level::Low)
            {
                seen.insert(i);
                wanted.push(self.want(i, level, 0.0, &frustum));
            }
        }
        // Tiles in view first, by priority; then prefetches in plan (deadline) order.
        wanted.sort_by(|a, b| {
            b.in_view.cmp(&a.in_view).then(if a.in_view {
                b.priority.total_cmp(&a.priority)
            } else {
                std::cmp::Ordering::Equal
            })
        });
        self.wanted = wanted;
    }

    fn want(&self, tile: usize, level: Level, deadline: f64, f: &Frustum) -> Want {
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
        }
    }

    fn pause(&mut self, tile: usize, actions: &mut Vec<Action>) {
        let Some(d) = self.state[tile].download.as_mut() else {
            return;
        };
        let Some(req) = d.req.take() else {
            return;
        };
        self.requests.remove(&req);
        actions.push(Action::Abort { id: req });
        self.stats.aborts += 1;
        if !d.resumable {
            // No validator: bytes cannot be resumed safely.
            self.drop_download(tile);
        }
    }

    fn drop_download(&mut self, tile: usize) {
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

    fn schedule(&mut self, actions: &mut Vec<Action>) {
        let wanted: HashMap<usize, Level> = self.wanted.iter().map(|w| (w.tile, w.level)).collect();
        // Pause downloads no longer wanted (or wanted at another level).
        for i in 0..self.state.len() {
            let Some(d) = &self.state[i].download else {
                continue;
            };
            if d.req.is_some() && wanted.get(&i) != Some(&d.level) {
                self.pause(i, actions);
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
            if s.download.as_ref().is_some_and(|d| d.req.is_some()) {
                continue;
            }
            if self.requests.len() >= self.cfg.max_concurrent {
                if !w.in_view {
                    break;
                }
                // Out-prioritised: pause the in-flight prefetch with the lowest priority.
                let victim = self
                    .wanted
                    .iter()
                    .filter(|v| !v.in_view)
                    .filter(|v| {
                        self.state[v.tile]
                            .download
                            .as_ref()
                            .is_some_and(|d| d.req.is_some())
                    })
                    .min_by(|a, b| a.priority.total_cmp(&b.priority))
                    .map(|v| v.tile);
                match victim {
                    Some(v) => self.pause(v, actions),
                    None => break,
                }
            }
            self.start(w, actions);
        }
    }

    fn start(&mut self, w: Want, actions: &mut Vec<Action>) {
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
        });
        if d.id == fresh_scene {
            self.next_scene += 1;
        }
        d.req = Some(id);
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

    fn content_data(&mut self, id: RequestId, tile: usize, chunk: &[u8]) {
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

    /// Memory could not hold a tile: retry after a replan period (not a failure).
    fn retry_later(&mut self, tile: usize, msg: String) {
        if self.stats.last_errors.len() >= KEPT_ERRORS {
            self.stats.last_errors.remove(0);
        }
        self.stats.last_errors.push(msg);
        self.state[tile].retry_at = self.now + self.cfg.replan_s.max(0.1);
        self.dirty = true;
    }

    /// Inserts the splats decoded so far of a tile's download as a new drawable.
    fn show_partial(&mut self, tile: usize) {
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
    fn add_object(&mut self, sid: u64, tile: usize, level: Level, splats: Splats, m: DMat4) {
        self.scene_splats.insert(sid, splats.len() as u64);
        self.updates.push(SceneUpdate::Insert {
            tile: sid,
            key: self.info[tile].key,
            level,
            splats,
            tile_to_world: m,
        });
    }

    fn remove_object(&mut self, sid: u64) {
        if self.scene_splats.remove(&sid).is_some() {
            self.updates.push(SceneUpdate::Remove { tile: sid });
        }
    }

    fn abort_failed(&mut self, tile: usize, id: RequestId, msg: String) {
        self.requests.remove(&id);
        self.pending_actions.push(Action::Abort { id });
        if let Some(d) = self.state[tile].download.as_mut() {
            d.req = None;
        }
        self.content_failed(tile, msg, true);
    }

    /// A content download failed: error, bytes dropped, retry with backoff.
    fn content_failed(&mut self, tile: usize, msg: String, count_error: bool) {
        self.drop_download(tile);
        self.backoff(tile, msg, count_error);
    }

    fn backoff(&mut self, tile: usize, msg: String, count_error: bool) {
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

    fn boot_failed(&mut self, kind: ReqKind, msg: String) {
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

    fn content_done(&mut self, id: RequestId, tile: usize) {
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
            None => crate::variants::decode_variant(&d.bytes)
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
    fn make_room(&mut self, need: u64) -> bool {
        let budget = self.cfg.memory_budget_bytes;
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
            let victim = self
                .cache
                .resident()
                .map(|(i, _)| i)
                .filter(|&i| !self.in_view[i] && !self.drawn[i])
                .filter(|&i| !self.has_resident_descendant(i))
                .max_by(|&a, &b| {
                    let da = self.catalog.tiles[a].bbox.distance(pos);
                    let db = self.catalog.tiles[b].bbox.distance(pos);
                    da.total_cmp(&db)
                });
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

    fn has_resident_descendant(&self, tile: usize) -> bool {
        let mut stack = self.catalog.tiles[tile].children.clone();
        while let Some(c) = stack.pop() {
            if self.cache.level(c).is_some() {
                return true;
            }
            stack.extend(self.catalog.tiles[c].children.iter().copied());
        }
        false
    }

    /// Brings the scene in line with the drawn set (see the module docs).
    fn reconcile_scene(&mut self) {
        let n = self.info.len();
        let mut drawn = vec![false; n];
        for &v in &self.view {
            if self.cache.level(v).is_some() {
                drawn[v] = true;
                continue;
            }
            let mut a = self.catalog.tiles[v].parent;
            let mut found = false;
            while let Some(p) = a {
                if self.cache.level(p).is_some() {
                    drawn[p] = true;
                    found = true;
                    break;
                }
                a = self.catalog.tiles[p].parent;
            }
            if !found {
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

    fn show_resident(&mut self, i: usize, level: Level) {
        let Some(bytes) = self.state[i].content.as_ref() else {
            return;
        };
        match crate::variants::decode_variant(bytes) {
            Ok((splats, node)) => {
                let sid = self.next_scene;
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

fn camera_ok(c: &Camera) -> bool {
    c.world_from_camera.is_finite()
        && c.fx.is_finite()
        && c.fy.is_finite()
        && c.fx > 0.0
        && c.fy > 0.0
        && c.width > 0
        && c.height > 0
}

/// Whether a sphere (centre in camera coordinates: x right, y down, z forward) meets the
/// camera's viewing pyramid (side planes through the image borders, in front of the camera).
fn sphere_in_view(cam: &Camera, c: DVec3, r: f64) -> bool {
    if c.z < -r {
        return false;
    }
    let (w, h) = (cam.width as f64, cam.height as f64);
    // Inward-facing side planes through the origin: n . p <= 0 inside.
    let planes = [
        DVec3::new(cam.fx, 0.0, -(w - cam.cx)),
        DVec3::new(-cam.fx, 0.0, -cam.cx),
        DVec3::new(0.0, cam.fy, -(h - cam.cy)),
        DVec3::new(0.0, -cam.fy, -cam.cy),
    ];
    planes.iter().all(|n| n.normalize_or_zero().dot(c) <= r)
}
