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
//! * **Layered tilesets** (`spec/layered-content.md`, detected at bootstrap by ADD refinement
//!   at the implicit root): the view set is the ADD selection (`stream::select::select_add`:
//!   every tile reached; a tile over `max_sse` brings in its children, each with the blend
//!   factor of its error); only whole Best files are fetched (variants do not apply to layers,
//!   and a prefix lacks the deltas), coarser levels first; a layer is drawn when it and every
//!   ancestor layer are resident, never in place of a missing one.
//!   [`StreamClient::layers`] and [`StreamClient::layer_opacities`] give each drawn layer's
//!   blend factor and its splats' effective opacities (`layers::blend`).
//! * **Memory**: `memory_budget_bytes` bounds the content bytes the client holds (resident tiles'
//!   glb bytes, kept so hidden tiles can be shown again, plus partial downloads kept for resume).
//! * **Pause/resume** (SGSS 3.3): a download whose tile is no longer wanted, or that is
//!   out-prioritised by a tile in view, is aborted and keeps its bytes; resumed with
//!   `range_start = bytes kept` and `if_range = ETag`; a 206 continues, a 200 restarts cleanly.

mod api;
mod bootstrap;
mod deadline_record;
#[cfg(feature = "native")]
pub mod native;
mod planning;
mod scene;
mod selection;
pub mod timeline;
mod transfers;
pub mod updates;
pub mod url;

pub use api::{
    Action, ClientConfig, ClientStats, FetchRequest, LayerDraw, PredictorKind, Prefetch,
    SceneUpdate,
};
use deadline_record::DeadlineRecord;
use selection::camera_ok;

use std::collections::{HashMap, HashSet};

use glam::{DMat4, DVec3};

use crate::bandwidth::EwmaBandwidth;
use crate::cache::{Cache, CacheConfig, EvictContext, Inserted};
use crate::catalog::{
    CatalogTile, LEVELS, Level, STAND_IN_UTILITY, TileCatalog, Variant, stand_in_variants,
};
use crate::geom::{Frustum, Obb, ViewPose};
use crate::planner::{LinkForecast, PlanStepConfig, plan_visible_link};
use crate::predict::{
    BLEND_SIGMA_M, ConstantVelocity, LinearExtrapolation, Predictor, Reactive, confident_poses,
    needs_fallback, radius_tiles,
};
use crate::priority::priority;
use splat2tiles_core::camera::Camera;
use splat2tiles_core::splat::Splats;
use splat2tiles_tiles::encode::prefix::PrefixStream;
use splat2tiles_tiles::tiling::TileKey;
use splat2tiles_tiles::tiling::load::{
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

/// Time step (s) of the link forecast the client's DP plans over. The DP itself runs over bytes
/// (`stream::plan`), so the step no longer caps the fetches a plan holds; it only sets how finely
/// a changing forecast and the deadlines are read (the DP's grid was once this step:
/// TileSplat's 0.1 s held a plan to 100 fetches on a 275-tile burst).
pub const PLAN_STEP_S: f64 = 0.02;

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
    /// Started as the coarse cover of a bare view (`Want::cover`): dropped, not paused, once
    /// no longer wanted.
    cover: bool,
}

#[derive(Debug, Default)]
struct TileState {
    download: Option<Download>,
    /// Content bytes of the resident level (mirrors the cache entry).
    content: Option<Vec<u8>>,
    /// Drawable of the complete content: scene id and level.
    shown: Option<(u64, Level)>,
    failures: u32,
    /// Downloads refused by the memory budget since the tile was last stored.
    refusals: u32,
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
    /// Seconds until the tile is needed (0: in view).
    deadline: f64,
    /// Set aside under overload with trusted deadlines (`ClientConfig::set_aside_late`): it
    /// cannot be on time without making others late, so it goes after the ones that can.
    late: bool,
    /// An ancestor asked at Low to draw holes in view coarsely (`ClientConfig::cover_up`).
    cover: bool,
    /// A hole in view drawn by a resident ancestor or one on the way: it goes after the
    /// prefetches.
    covered: bool,
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
    /// Time of the first view (start of the fallback period).
    first_view: Option<f64>,
    /// Camera speed when the last plan was made.
    plan_speed: f64,
    requests: HashMap<RequestId, Request>,
    next_req: RequestId,
    next_scene: u64,
    pending_actions: Vec<Action>,
    updates: Vec<SceneUpdate>,
    scene_splats: HashMap<u64, u64>,
    in_view: Vec<bool>,
    view: Vec<usize>,
    drawn: Vec<bool>,
    /// Layered tileset (ADD refinement at the implicit root): selection by ADD, Best only.
    layered: bool,
    /// Blend factor of each tile of the view set (layered; 0 elsewhere).
    blend: Vec<f32>,
    /// Per drawable of a layered tileset: its stored splats and its parent-opacity deltas.
    layer_data: HashMap<u64, (Splats, Option<splat2tiles_tiles::layers::glb::LayerInfo>)>,
    wanted: Vec<Want>,
    /// The last plan's predicted views: tile and seconds until first seen (0: in view).
    predicted: Vec<(usize, f64)>,
    /// How often the predictor's deadlines came true (kept only with `set_aside_late`).
    deadlines: DeadlineRecord,
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

/// The predictor the client runs for `kind` (the committed models for `tcn` and `learned`).
pub fn predictor_of(kind: PredictorKind) -> Box<dyn Predictor + Send> {
    match kind {
        PredictorKind::Reactive => Box::new(Reactive),
        PredictorKind::ConstantVelocity => Box::new(ConstantVelocity::default()),
        PredictorKind::Linear => Box::new(LinearExtrapolation::default()),
        // The committed model always loads (tests load it); were it ever unusable, linear.
        PredictorKind::Tcn => match crate::learned::TcnPredictor::committed() {
            Ok(p) => Box::new(p),
            Err(_) => Box::new(LinearExtrapolation::default()),
        },
        PredictorKind::Learned => Box::new(crate::learned::LearnedPredictor::committed()),
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
                source: crate::catalog::VariantSource::StandIn,
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
            first_view: None,
            plan_speed: 0.0,
            requests: HashMap::new(),
            next_req: 1,
            next_scene: 1,
            pending_actions: vec![],
            updates: vec![],
            scene_splats: HashMap::new(),
            in_view: vec![],
            view: vec![],
            drawn: vec![],
            layered: false,
            blend: vec![],
            layer_data: HashMap::new(),
            wanted: vec![],
            predicted: vec![],
            deadlines: DeadlineRecord::default(),
            last_plan: f64::NEG_INFINITY,
            dirty: true,
            now: 0.0,
            stats: ClientStats::default(),
        }
    }

    /// A client whose planner uses `predictor` instead of [`ClientConfig::predictor`] (an
    /// oracle in simulation, a learned model): the fallback rule applies to it when it needs pose history.
    pub fn with_predictor(
        tileset_url: &str,
        cfg: ClientConfig,
        predictor: Box<dyn Predictor + Send>,
    ) -> Self {
        let mut c = StreamClient::new(tileset_url, cfg);
        c.predictor = predictor;
        c
    }

    /// Name of the predictor in use.
    pub fn predictor_name(&self) -> &str {
        self.predictor.name()
    }

    /// The tile and level a content request in flight fetches (None for other requests).
    pub fn request_content(&self, id: RequestId) -> Option<(TileKey, Level)> {
        match self.requests.get(&id)?.kind {
            ReqKind::Content(t) => Some((self.info[t].key, self.state[t].download.as_ref()?.level)),
            _ => None,
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

    /// Whether the tileset is layered (ADD refinement at the implicit root,
    /// `spec/layered-content.md`): the client selects, fetches and draws layers.
    pub fn is_layered(&self) -> bool {
        self.layered
    }

    /// The layers drawn (layered tilesets; empty otherwise), parents before children: each
    /// with its scene id, its parent's index in this list and its blend factor.
    pub fn layers(&self) -> Vec<LayerDraw> {
        if !self.layered {
            return vec![];
        }
        let mut at = HashMap::new();
        let mut out = vec![];
        for &v in &self.view {
            let Some((sid, _)) = self.state[v].shown.filter(|_| self.drawn[v]) else {
                continue;
            };
            let parent = self.catalog.tiles[v]
                .parent
                .and_then(|p| at.get(&p).copied());
            at.insert(v, out.len());
            out.push(LayerDraw {
                key: self.info[v].key,
                scene_id: sid,
                parent,
                blend: if parent.is_some() { self.blend[v] } else { 1.0 },
            });
        }
        out
    }

    /// The opacity each drawn layer's splats are drawn with (scene id, one value per splat in
    /// the drawable's order): `layers::blend::effective_opacities` of [`Self::layers`] (each
    /// layer's parent deltas and, format v2, its ancestor deltas), and 0 for splats under the
    /// occupancy threshold. A layer whose deltas do not match its parent
    /// (count, or none on a layer with a parent) is an error naming the tile; a content
    /// without the layer extension in an ADD tileset fades nothing (an ordinary ADD tile).
    pub fn layer_opacities(&self) -> Result<Vec<(u64, Vec<f32>)>, String> {
        self.layer_opacities_of(&self.layers())
    }

    /// [`Self::layer_opacities`] of `layers`: [`Self::layers`] with blend factors a viewer
    /// changed (a time ramp, `layers::ramp`, or a test's hard swap). A scene id that is not a
    /// decoded layer, or a parent index that is not an earlier layer, is an error naming the tile.
    pub fn layer_opacities_of(&self, layers: &[LayerDraw]) -> Result<Vec<(u64, Vec<f32>)>, String> {
        let zeros: Vec<Vec<f32>> = layers
            .iter()
            .map(|l| match l.parent {
                Some(p) => vec![
                    0.0;
                    layers
                        .get(p)
                        .and_then(|q| self.layer_data.get(&q.scene_id))
                        .map_or(0, |d| d.0.len())
                ],
                None => vec![],
            })
            .collect();
        let mut drawn = Vec::with_capacity(layers.len());
        let mut ancestors = Vec::with_capacity(layers.len());
        for l in layers {
            let (_, info) = self
                .layer_data
                .get(&l.scene_id)
                .ok_or_else(|| format!("tile {:?}: layer not decoded", l.key))?;
            ancestors.push(splat2tiles_tiles::layers::view::ancestor_deltas(
                l.key.level,
                info.as_ref(),
            ));
        }
        for ((l, z), a) in layers.iter().zip(&zeros).zip(&ancestors) {
            let (splats, info) = &self.layer_data[&l.scene_id];
            let deltas = info
                .as_ref()
                .and_then(|i| i.parent_opacity_delta.as_deref());
            drawn.push(splat2tiles_tiles::layers::blend::DrawnLayer {
                splats,
                parent: l.parent,
                deltas: l.parent.map(|_| deltas.unwrap_or(z)),
                blend: l.blend,
                ancestors: a,
            });
        }
        let ops = splat2tiles_tiles::layers::blend::effective_opacities(&drawn).map_err(|e| {
            let k = match e {
                splat2tiles_tiles::layers::blend::ComposeError::BadParent(k)
                | splat2tiles_tiles::layers::blend::ComposeError::BadAncestor(k)
                | splat2tiles_tiles::layers::blend::ComposeError::DeltaCount { layer: k, .. } => k,
            };
            format!("tile {:?}: {e}", layers[k].key)
        })?;
        Ok(layers
            .iter()
            .zip(ops)
            .map(|(l, mut o)| {
                for x in &mut o {
                    if *x < splat2tiles_tiles::layers::OCCUPANCY_THRESHOLD {
                        *x = 0.0;
                    }
                }
                (l.scene_id, o)
            })
            .collect())
    }

    /// The last plan's wants: tile, level and the time it is due (plan time + deadline; the
    /// plan's time for tiles in view), in the order they are requested.
    pub fn planned(&self) -> Vec<(TileKey, Level, f64)> {
        self.wanted
            .iter()
            .map(|w| (self.info[w.tile].key, w.level, self.last_plan + w.deadline))
            .collect()
    }

    /// The tiles the last plan's predicted views (and the view) selected, with the time each is
    /// first seen (plan time + seconds), before the planner chose among them.
    pub fn predicted(&self) -> Vec<(TileKey, f64)> {
        self.predicted
            .iter()
            .map(|&(i, dt)| (self.info[i].key, self.last_plan + dt))
            .collect()
    }

    /// Time of the last plan (seconds, the clock of [`Self::update`]).
    pub fn last_plan_s(&self) -> f64 {
        self.last_plan
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

    /// A new viewport size in pixels (the window was resized): the planner's intrinsics follow
    /// it (selection uses the camera of each update already). Zero sizes count as 1.
    pub fn set_viewport(&mut self, width: u32, height: u32) {
        self.cfg.width = width;
        self.cfg.height = height;
        self.cfg.plan.intrinsics.height_px = height.max(1) as f64;
        self.cfg.plan.intrinsics.aspect = width.max(1) as f64 / height.max(1) as f64;
        self.dirty = true;
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

    /// Whether a content download of `tile` is in flight (not paused).
    fn downloading(&self, tile: usize) -> bool {
        self.state[tile]
            .download
            .as_ref()
            .is_some_and(|d| d.req.is_some())
    }

    /// Requests in flight for tile contents (`content`) or for tileset and subtree files.
    fn in_flight(&self, content: bool) -> usize {
        self.requests
            .values()
            .filter(|r| matches!(r.kind, ReqKind::Content(_)) == content)
            .count()
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
}
