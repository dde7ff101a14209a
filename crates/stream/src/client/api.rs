//! What the streaming client's caller sets and gets: its configuration and predictor choice, the
//! actions it asks for (fetch, abort), the scene updates it hands the renderer, and its stats.

use glam::DMat4;

use super::{PLAN_STEP_S, RequestId};
use crate::catalog::Level;
use crate::planner::PlanStepConfig;
use splat2tiles_core::splat::Splats;
use splat2tiles_tiles::tiling::TileKey;

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
    /// TileSplat's learned TCN + LSTM with uncertainty (`stream::learned`; after 5 s of history,
    /// the radius rule blended in where it is uncertain).
    Tcn,
    /// The learned view model (`stream::learned::view_model`): linear extrapolation's path
    /// corrected, the view's yaw and pitch predicted (after 5 s of history; reactive before).
    Learned,
}

impl PredictorKind {
    /// The kind a name stands for (`reactive`, `constant-velocity`, `linear`, `tcn`, `learned`).
    pub fn from_name(name: &str) -> Option<PredictorKind> {
        match name {
            "reactive" => Some(PredictorKind::Reactive),
            "constant-velocity" => Some(PredictorKind::ConstantVelocity),
            "linear" => Some(PredictorKind::Linear),
            "tcn" => Some(PredictorKind::Tcn),
            "learned" => Some(PredictorKind::Learned),
            _ => None,
        }
    }
}

/// How far ahead the client fetches what its predictor says will be seen: the data-thrift knob.
/// Tiles predicted to enter the view later than [`Self::ahead_s`], or only at predicted poses
/// whose one-sigma position uncertainty exceeds [`Self::max_sigma_m`], are not fetched ahead
/// (the view set itself is always fetched). The bound is the prediction's horizon and
/// confidence, not the free bandwidth: a fast link does not make an eager client of a thrifty one.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Prefetch {
    /// Seconds ahead of now that predicted first visibilities are fetched (at most the
    /// predictor's horizon, [`ClientConfig::predict_horizon_s`]).
    pub ahead_s: f64,
    /// Predicted poses more uncertain than this (metres, one sigma) are not planned for.
    pub max_sigma_m: f64,
    /// Utility (the tileset's per-variant SSIM utility, Best = 1) that a better level must add
    /// to a held tile for the tile to be fetched again: 0 upgrades whenever the planner asks (the
    /// variant ladder is climbed on a fast link), infinity never (every tile downloaded once).
    pub upgrade_gain: f64,
}

impl Prefetch {
    /// Everything the predictor's whole horizon shows, poses up to App. C.5's 20 m sigma, and
    /// every upgrade the planner asks for (the variant ladder climbed whenever the link allows).
    pub const EAGER: Prefetch = Prefetch {
        ahead_s: 10.0,
        max_sigma_m: crate::predict::BLEND_SIGMA_M,
        upgrade_gain: 0.0,
    };
    /// Eager's horizon and sigma bound, and a tile fetched again only for at least 0.01
    /// utility: the cache hits of eager (within 0.4 points on the city's test traces) for about
    /// half its bytes (BENCHMARKS.md, "Data thrift"). The default.
    pub const BALANCED: Prefetch = Prefetch {
        ahead_s: 10.0,
        max_sigma_m: crate::predict::BLEND_SIGMA_M,
        upgrade_gain: 0.01,
    };
    /// The next 1.5 s, poses up to 5 m sigma, upgrades as balanced: what is about to be seen,
    /// little more (the fewest bytes; fewer cache hits where the camera moves far).
    pub const THRIFTY: Prefetch = Prefetch {
        ahead_s: 1.5,
        max_sigma_m: 5.0,
        upgrade_gain: 0.01,
    };

    /// The named settings, in order of bytes fetched.
    pub const NAMED: [(&'static str, Prefetch); 3] = [
        ("thrifty", Prefetch::THRIFTY),
        ("balanced", Prefetch::BALANCED),
        ("eager", Prefetch::EAGER),
    ];

    /// The setting a name stands for: `thrifty`, `balanced`, `eager`, or a number of seconds
    /// ahead (e.g. `2.5`, with eager's sigma bound and upgrades).
    pub fn from_name(name: &str) -> Option<Prefetch> {
        if let Some((_, p)) = Prefetch::NAMED.iter().find(|(n, _)| *n == name) {
            return Some(*p);
        }
        let s: f64 = name.trim_end_matches('s').parse().ok()?;
        (s.is_finite() && s >= 0.0).then_some(Prefetch {
            ahead_s: s,
            ..Prefetch::EAGER
        })
    }
}

impl Default for Prefetch {
    fn default() -> Self {
        Prefetch::EAGER
    }
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
    /// Tile-content requests in flight at most (tileset and subtree files have as many more).
    pub max_concurrent: usize,
    /// Levels the client may download (the wasm build decodes only Best and Low).
    pub levels: Vec<Level>,
    /// Replan period in seconds (also replans when the view set changes, a download ends, the
    /// speed changes by more than [`Self::replan_speed_change`], or a tile of the view set is
    /// neither resident nor wanted).
    pub replan_s: f64,
    /// Relative change of the camera speed (over 0.5 s) since the last plan that replans (0.2).
    pub replan_speed_change: f64,
    /// Seconds from the first view during which a predictor that needs pose history is replaced
    /// by the fallback rule of TileSplat App. C.5 (the view set, plus the tiles within
    /// [`Self::fallback_radius_m`] at Medium); 5 s. Predictors that need no history (reactive,
    /// an oracle) never fall back, as the paper's rule reads ("if the prediction model has not
    /// yet accumulated sufficient history").
    pub fallback_s: f64,
    /// Radius of the fallback rule in tileset-frame metres (TileSplat: 100 m; 0: view set only).
    pub fallback_radius_m: f64,
    /// Planner settings (forecast step, byte bins, horizon, urgent deadline, algorithm, latency).
    pub plan: PlanStepConfig,
    /// Bandwidth estimate (bytes/s) before the first measurement.
    pub initial_bandwidth: f64,
    /// Trajectory predictor.
    pub predictor: PredictorKind,
    /// Seconds ahead the predicted poses reach.
    pub predict_horizon_s: f64,
    /// Seconds between predicted poses.
    pub predict_step_s: f64,
    /// How far ahead predicted tiles are fetched, and which upgrades ([`Prefetch::BALANCED`]).
    pub prefetch: Prefetch,
    /// When the link cannot carry the missing tiles (in view: due now; predicted: due at their
    /// first predicted view) by their deadlines even at Low (earliest deadline first over the
    /// forecast), ask the prefetches at Low: coverage before quality, upgrades later (on by
    /// default; chosen on the validation traces, BENCHMARKS.md).
    pub low_under_overload: bool,
    /// Under that overload, and when the predictor's recent deadlines came true
    /// (`deadline_record`), the missing tiles Moore-Hodgson sets aside (the largest ones whose
    /// bytes make others late) are requested after the ones that can still be on time, repairs
    /// of holes in view included: the fewest late entries. On by default since it raised the
    /// oracle on the validation traces and leaves predictors whose deadlines miss untouched
    /// (BENCHMARKS.md, "Moore-Hodgson").
    pub set_aside_late: bool,
    /// Coarse cover of a bare view (at least half of the view set with nothing drawn: a cold
    /// start or a jump): the ancestor this many levels above each hole (further up past tiles
    /// without content) is asked at Low before anything else when it costs fewer bytes than the
    /// holes it covers; and holes drawn by a resident ancestor (or one on the way) are requested
    /// after the prefetches: what enters next before the detail of what is already drawn
    /// coarsely. 0: off. 1 by default (chosen on the validation traces, BENCHMARKS.md).
    pub cover_up: u32,
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
            replan_speed_change: 0.2,
            fallback_s: 5.0,
            fallback_radius_m: 0.0,
            plan: PlanStepConfig {
                step_s: PLAN_STEP_S,
                ..PlanStepConfig::default()
            },
            initial_bandwidth: 2.0e6,
            predictor: PredictorKind::Linear,
            predict_horizon_s: 10.0,
            predict_step_s: 0.5,
            prefetch: Prefetch::BALANCED,
            low_under_overload: true,
            set_aside_late: true,
            cover_up: 1,
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

/// One layer a client draws (layered tilesets, [`super::StreamClient::layers`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LayerDraw {
    /// Its tile.
    pub key: TileKey,
    /// Its drawable's scene id.
    pub scene_id: u64,
    /// Index of its parent layer in the same list (`None`: the base layer).
    pub parent: Option<usize>,
    /// Its blend factor `t` (LapisGS eq. 4 over the parent's screen-space error; 1 for the base).
    pub blend: f32,
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
    /// Plans made (replans included).
    pub plans: u64,
    /// Plans made while the predictor's recent deadlines had come true often enough to set
    /// aside prefetches that cannot be on time (`deadline_record`, kept only with
    /// `ClientConfig::set_aside_late`; 0 without it).
    pub trusted_plans: u64,
    /// Plans made while the link could not carry the missing prefetches by their deadlines
    /// even at Low (`planning::overloaded`).
    pub overload_plans: u64,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn prefetch_names_and_seconds() {
        assert_eq!(Prefetch::from_name("thrifty"), Some(Prefetch::THRIFTY));
        assert_eq!(Prefetch::from_name("balanced"), Some(Prefetch::BALANCED));
        assert_eq!(Prefetch::from_name("eager"), Some(Prefetch::EAGER));
        let p = Prefetch::from_name("2.5s").unwrap();
        assert_eq!((p.ahead_s, p.upgrade_gain), (2.5, 0.0));
        assert_eq!(Prefetch::from_name("0").unwrap().ahead_s, 0.0);
        for bad in ["", "-1", "NaN", "inf", "fast"] {
            assert_eq!(Prefetch::from_name(bad), None, "{bad}");
        }
        assert_eq!(ClientConfig::default().prefetch, Prefetch::BALANCED);
        // Named settings fetch more in order: a longer horizon, then every upgrade.
        let n = Prefetch::NAMED.map(|(_, p)| (p.ahead_s, -p.upgrade_gain));
        assert!(n.windows(2).all(|w| w[0] < w[1]), "{n:?}");
    }
}
