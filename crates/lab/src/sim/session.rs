//! Session runner: the real [`StreamClient`] over a [`SimTransport`] along a camera trace, updated
//! at every trace tick and whenever a response finishes; logs what it needed, held and drew.
//!
//! The trace's poses are in the tileset frame (z up); each becomes a camera of the client's
//! viewport (`width` x `height`, `fov_y_deg`) through the tileset's root transform. Between two
//! ticks the transport's events are delivered in time order; after a `Done` or `Error` the client
//! is updated at once with the camera of the last tick (as the web viewer's `dispatch` does).

use std::path::Path;

use splat2tiles_core::camera::Camera;
use splat2tiles_stream::catalog::Level;
use splat2tiles_stream::client::timeline::Input;
use splat2tiles_stream::client::{Action, ClientConfig, StreamClient};
use splat2tiles_stream::geom::ViewPose;
use splat2tiles_stream::predict::Predictor;
use splat2tiles_tiles::tiling::TileKey;

use super::transport::{Delivery, NetEvent, NetModel, Outcome, SimTransport};

/// What the client had at one trace tick (after its update).
#[derive(Debug, Clone, PartialEq)]
pub struct TickLog {
    /// Seconds.
    pub t: f64,
    /// The camera pose (tileset frame).
    pub pose: ViewPose,
    /// Tiles the view needs ([`StreamClient::view_set`]).
    pub view_set: Vec<TileKey>,
    /// Tiles held with their level ([`StreamClient::resident`]).
    pub resident: Vec<(TileKey, Level)>,
    /// Tiles drawn: key, level, scene id ([`StreamClient::drawn`]).
    pub drawn: Vec<(TileKey, Level, u64)>,
    /// Layers drawn (layered tilesets; empty otherwise), parents first, with their blend
    /// factor ([`StreamClient::layers`]).
    pub layers: Vec<(TileKey, f32)>,
    /// Body bytes delivered to the client so far.
    pub bytes_down: u64,
    /// Bytes the link carried so far (header overheads included).
    pub wire_bytes: u64,
    /// The client's bandwidth estimate (bytes/s).
    pub bandwidth_estimate: f64,
    /// Content bytes the client holds (resident + partial).
    pub cache_bytes: u64,
    /// Requests in flight.
    pub in_flight: usize,
    /// Plans the client made so far.
    pub plans: u64,
    /// The last plan's wants ([`StreamClient::planned`]): tile and due time.
    pub planned: Vec<(TileKey, f64)>,
    /// The last plan's predicted tiles ([`StreamClient::predicted`]): tile and first-seen time.
    pub predicted: Vec<(TileKey, f64)>,
    /// Time of the client's last plan ([`StreamClient::last_plan_s`]).
    pub last_plan_s: f64,
}

/// One request the client issued.
#[derive(Debug, Clone, PartialEq)]
pub struct RequestLog {
    /// Tile of a content request (None: tileset.json or a subtree).
    pub key: Option<TileKey>,
    /// Level of a content request.
    pub level: Option<Level>,
    /// URL.
    pub url: String,
    /// First byte asked for (a resume when > 0).
    pub range_start: u64,
    /// Issue time (s).
    pub start_s: f64,
    /// End time (None: still open at the end of the session).
    pub end_s: Option<f64>,
    /// Body bytes delivered.
    pub bytes: u64,
    /// How it ended.
    pub outcome: Outcome,
}

/// Everything a session produced.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SessionLog {
    /// Predictor name.
    pub predictor: String,
    /// One entry per trace tick.
    pub ticks: Vec<TickLog>,
    /// Requests in issue order.
    pub requests: Vec<RequestLog>,
    /// Client updates run (ticks + response ends).
    pub updates: usize,
    /// Downloads aborted (paused or dropped) by the client.
    pub aborts: u64,
    /// Downloads resumed with a Range request.
    pub resumes: u64,
    /// Tiles evicted from the client's cache.
    pub evictions: u64,
    /// Errors the client recorded.
    pub errors: u64,
    /// Plans the client made.
    pub plans: u64,
    /// Plans made while the client trusted its predictor's deadlines (with `set_aside_late`)
    /// ([`ClientStats::trusted_plans`](splat2tiles_stream::client::ClientStats::trusted_plans)).
    pub trusted_plans: u64,
    /// Plans made under overload ([`ClientStats::overload_plans`](splat2tiles_stream::client::ClientStats::overload_plans)).
    pub overload_plans: u64,
    /// Every client input in order, when [`SessionOptions::record_inputs`] was set.
    pub inputs: Vec<Input>,
    /// The actions of each update, in order, when [`SessionOptions::record_inputs`] was set.
    pub actions: Vec<Vec<Action>>,
}

/// Options of [`run_session`] beyond the client and the network.
#[derive(Default)]
pub struct SessionOptions {
    /// Planner predictor replacing `ClientConfig::predictor` (e.g. an oracle on the trace).
    pub predictor: Option<Box<dyn Predictor + Send>>,
    /// Keep the inputs for replay (memory: every body byte).
    pub record_inputs: bool,
}

impl std::fmt::Debug for SessionOptions {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SessionOptions")
            .field("predictor", &self.predictor.as_ref().map(|p| p.name()))
            .field("record_inputs", &self.record_inputs)
            .finish()
    }
}

/// The camera of `pose` for `client` (tileset frame to world through the root transform).
pub fn camera_of(client: &StreamClient, pose: &ViewPose) -> Camera {
    let c = client.config();
    Camera::from_pose(
        c.width,
        c.height,
        c.fov_y_deg,
        client.root_transform() * pose.world_from_camera(),
    )
}

struct Run {
    client: StreamClient,
    net: SimTransport,
    log: SessionLog,
    record: bool,
}

impl Run {
    fn input(&mut self, i: Input) -> Vec<Action> {
        let a = i.apply(&mut self.client);
        let update = matches!(i, Input::Update { .. });
        if update {
            self.log.updates += 1;
        }
        if self.record {
            self.log.inputs.push(i);
            if update {
                self.log.actions.push(a.clone());
            }
        }
        a
    }

    fn update(&mut self, t: f64, camera: Camera) {
        let actions = self.input(Input::Update { t, camera });
        self.net.apply(&actions);
    }

    fn deliver(&mut self, d: Delivery, pose: Option<&ViewPose>) {
        let t = d.t;
        let end = matches!(d.event, NetEvent::Done | NetEvent::Error(_));
        let input = d.into_input();
        self.input(input);
        if end && let Some(p) = pose {
            let cam = camera_of(&self.client, p);
            self.update(t, cam);
        }
    }
}

/// Runs the client on the tileset in `dir` along `trace` over `net` (see the module docs).
pub fn run_session(
    dir: &Path,
    cfg: ClientConfig,
    trace: &[ViewPose],
    net: &NetModel,
    opts: SessionOptions,
) -> SessionLog {
    let transport = SimTransport::new(dir, net.clone());
    let url = transport.tileset_url();
    let client = match opts.predictor {
        Some(p) => StreamClient::with_predictor(&url, cfg, p),
        None => StreamClient::new(&url, cfg),
    };
    let mut run = Run {
        log: SessionLog {
            predictor: client.predictor_name().to_string(),
            ..SessionLog::default()
        },
        client,
        net: transport,
        record: opts.record_inputs,
    };
    let mut content: Vec<Option<(TileKey, Level)>> = vec![];
    if let Some(p) = trace.first() {
        run.net.set_time(p.t);
    }
    let mut last: Option<&ViewPose> = None;
    for pose in trace {
        while let Some(d) = run.net.next(pose.t) {
            run.deliver(d, last);
            note_requests(&run, &mut content);
        }
        let cam = camera_of(&run.client, pose);
        last = Some(pose);
        run.update(pose.t, cam);
        note_requests(&run, &mut content);
        let s = run.client.stats();
        run.log.ticks.push(TickLog {
            t: pose.t,
            pose: *pose,
            view_set: run.client.view_set(),
            resident: run.client.resident(),
            drawn: run.client.drawn(),
            layers: run
                .client
                .layers()
                .iter()
                .map(|l| (l.key, l.blend))
                .collect(),
            bytes_down: s.bytes_received,
            wire_bytes: run.net.wire_bytes(),
            bandwidth_estimate: s.bandwidth,
            cache_bytes: s.cache_bytes,
            in_flight: run.net.in_flight(),
            plans: s.plans,
            planned: run
                .client
                .planned()
                .into_iter()
                .map(|(k, _, due)| (k, due))
                .collect(),
            predicted: run.client.predicted(),
            last_plan_s: run.client.last_plan_s(),
        });
    }
    let s = run.client.stats();
    run.log.aborts = s.aborts;
    run.log.resumes = s.resumes;
    run.log.evictions = s.evictions;
    run.log.errors = s.errors;
    run.log.plans = s.plans;
    run.log.trusted_plans = s.trusted_plans;
    run.log.overload_plans = s.overload_plans;
    run.log.requests = run
        .net
        .log()
        .iter()
        .enumerate()
        .map(|(i, r)| {
            let (key, level) = content.get(i).copied().flatten().unzip();
            RequestLog {
                key,
                level,
                url: r.url.clone(),
                range_start: r.range_start,
                start_s: r.start_s,
                end_s: r.end_s,
                bytes: r.bytes,
                outcome: r.outcome,
            }
        })
        .collect();
    run.log
}

/// Records the tile and level of the requests issued since the last call (while they are in
/// flight the client can tell).
fn note_requests(run: &Run, content: &mut Vec<Option<(TileKey, Level)>>) {
    for r in &run.net.log()[content.len()..] {
        content.push(run.client.request_content(r.id));
    }
}
