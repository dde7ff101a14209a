//! Simulated transport: serves a tileset folder's files to a [`splat2tiles_stream::client::StreamClient`] over a
//! network model (piecewise bandwidth, RTT, per-request overhead, link shared equally), event-driven.
//!
//! Time only moves through [`SimTransport::next`]; transfers are kept in request-id order, so a
//! run is a pure function of its inputs (no clock, no threads, no hash-map order). A request waits
//! one RTT for its response head, then its header overhead and body bytes share the link equally
//! with the other transfers past their RTT; the body reaches the client in chunks of
//! [`NetModel::chunk_bytes`] (the last one shorter), then the request is done. Ranges follow HTTP:
//! `Range` with a matching `If-Range` gets a 206 from that byte, anything else a 200.

use std::collections::{BTreeMap, VecDeque};
use std::path::{Path, PathBuf};
use std::sync::Arc;

use splat2tiles_stream::client::timeline::Input;
use splat2tiles_stream::client::{Action, FetchRequest, RequestId};

/// Largest file the transport serves (bytes); bigger ones answer a transport error.
pub const MAX_FILE_BYTES: u64 = 1 << 30;

/// Network: piecewise constant bandwidth, round trip, per-request overhead, chunking.
#[derive(Debug, Clone, PartialEq)]
pub struct NetModel {
    /// `(start time s, bytes/s)` pieces sorted by start; the first applies from -inf (a trace
    /// reader in `sim::network` produces this type).
    pub bandwidth: Vec<(f64, f64)>,
    /// Round trip before a response's head (s).
    pub rtt_s: f64,
    /// Header bytes per request (sent over the link before the body).
    pub overhead_bytes: u64,
    /// Body bytes per delivered chunk.
    pub chunk_bytes: usize,
}

impl NetModel {
    /// A constant link of `mbps` megabits per second, 400 B per request, 16 KiB chunks.
    pub fn constant(mbps: f64, rtt_s: f64) -> Self {
        NetModel {
            bandwidth: vec![(0.0, mbps * 1e6 / 8.0)],
            rtt_s,
            overhead_bytes: 400,
            chunk_bytes: 16 << 10,
        }
    }

    /// Bytes/s at time `t` (0 for a negative or non-finite piece).
    pub fn rate(&self, t: f64) -> f64 {
        let r = self
            .bandwidth
            .iter()
            .rev()
            .find(|(s, _)| *s <= t)
            .or(self.bandwidth.first())
            .map_or(0.0, |p| p.1);
        if r.is_finite() && r > 0.0 { r } else { 0.0 }
    }

    /// The first piece start after `t` (infinity if none).
    pub fn next_change(&self, t: f64) -> f64 {
        self.bandwidth
            .iter()
            .map(|p| p.0)
            .find(|&s| s > t)
            .unwrap_or(f64::INFINITY)
    }
}

/// What the transport hands to the client for one request.
#[derive(Debug, Clone, PartialEq)]
pub enum NetEvent {
    /// Response head (`on_response`).
    Response {
        /// HTTP status.
        status: u16,
        /// ETag.
        etag: Option<String>,
        /// Start of Content-Range (206).
        range_start: Option<u64>,
        /// Full length of the resource.
        total: Option<u64>,
    },
    /// Body chunk (`on_data`).
    Data(Vec<u8>),
    /// Body complete (`on_done`).
    Done,
    /// Transport failure (`on_error`).
    Error(String),
}

/// One event at a time for a request.
#[derive(Debug, Clone, PartialEq)]
pub struct Delivery {
    /// Seconds.
    pub t: f64,
    /// Request.
    pub id: RequestId,
    /// The event.
    pub event: NetEvent,
}

impl Delivery {
    /// The client input this delivery is (what a native HTTP driver would feed it).
    pub fn into_input(self) -> Input {
        let Delivery { t, id, event } = self;
        match event {
            NetEvent::Response {
                status,
                etag,
                range_start,
                total,
            } => Input::Response {
                id,
                status,
                etag,
                range_start,
                total,
            },
            NetEvent::Data(bytes) => Input::Data { id, t, bytes },
            NetEvent::Done => Input::Done { id, t },
            NetEvent::Error(message) => Input::Error { id, t, message },
        }
    }
}

/// How a request ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Outcome {
    /// Still running when the session ended.
    Open,
    /// Body complete.
    Done,
    /// Aborted by the client.
    Aborted,
    /// Non-2xx status or transport error.
    Failed,
}

/// The transport's record of one request.
#[derive(Debug, Clone, PartialEq)]
pub struct TransferLog {
    /// Request id.
    pub id: RequestId,
    /// URL fetched.
    pub url: String,
    /// First byte asked for.
    pub range_start: u64,
    /// Issue time (s).
    pub start_s: f64,
    /// End time (done, aborted or failed).
    pub end_s: Option<f64>,
    /// Body bytes delivered to the client.
    pub bytes: u64,
    /// How it ended.
    pub outcome: Outcome,
}

struct Transfer {
    id: RequestId,
    body: Arc<[u8]>,
    /// First body byte served.
    offset: usize,
    /// Body bytes handed to the client.
    delivered: usize,
    head_at: f64,
    head: Option<NetEvent>,
    /// Wire bytes received so far (overhead first, then body).
    wire: f64,
    overhead: f64,
}

impl Transfer {
    fn len(&self) -> usize {
        self.body.len() - self.offset
    }
    fn received(&self) -> usize {
        ((self.wire - self.overhead).max(0.0).floor() as usize).min(self.len())
    }
    /// Wire bytes at which the next chunk (or the end) is complete.
    fn target(&self, chunk: usize) -> f64 {
        self.overhead + (self.delivered + chunk).min(self.len()) as f64
    }
    fn in_data(&self) -> bool {
        self.head.is_none()
    }
}

/// Serves the files under one folder over a [`NetModel`] (see the module docs).
pub struct SimTransport {
    root: String,
    net: NetModel,
    now: f64,
    files: BTreeMap<String, Result<Arc<[u8]>, String>>,
    active: Vec<Transfer>,
    ready: VecDeque<Delivery>,
    log: Vec<TransferLog>,
    log_at: BTreeMap<RequestId, usize>,
    wire_bytes: f64,
}

impl std::fmt::Debug for SimTransport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SimTransport")
            .field("root", &self.root)
            .field("now", &self.now)
            .field("active", &self.active.len())
            .finish_non_exhaustive()
    }
}

/// FNV-1a of the bytes as a quoted ETag.
fn etag_of(bytes: &[u8]) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in bytes {
        h = (h ^ *b as u64).wrapping_mul(0x100_0000_01b3);
    }
    format!("\"{h:016x}\"")
}

impl SimTransport {
    /// Serves the files under `root`, whose URL is its path (`root/tileset.json` is the tileset
    /// URL to give the client: [`Self::tileset_url`]).
    pub fn new(root: &Path, net: NetModel) -> Self {
        let mut root = root.to_string_lossy().into_owned();
        if !root.ends_with('/') {
            root.push('/');
        }
        SimTransport {
            root,
            net,
            now: 0.0,
            files: BTreeMap::new(),
            active: vec![],
            ready: VecDeque::new(),
            log: vec![],
            log_at: BTreeMap::new(),
            wire_bytes: 0.0,
        }
    }

    /// The URL of `tileset.json` under the root.
    pub fn tileset_url(&self) -> String {
        format!("{}tileset.json", self.root)
    }

    /// Transport time (s).
    pub fn now(&self) -> f64 {
        self.now
    }

    /// Bytes carried by the link so far (overheads included).
    pub fn wire_bytes(&self) -> u64 {
        self.wire_bytes.round() as u64
    }

    /// Requests in flight.
    pub fn in_flight(&self) -> usize {
        self.active.len()
    }

    /// Every request issued so far, in issue order.
    pub fn log(&self) -> &[TransferLog] {
        &self.log
    }

    /// Sets the clock to `t` when it is later (before the first request, or between events).
    pub fn set_time(&mut self, t: f64) {
        if t.is_finite() && t > self.now && self.active.is_empty() && self.ready.is_empty() {
            self.now = t;
        }
    }

    fn file(&mut self, url: &str) -> Option<Result<Arc<[u8]>, String>> {
        let rel = url.strip_prefix(&self.root)?;
        if rel.split('/').any(|s| s == ".." || s.is_empty()) {
            return None;
        }
        if let Some(f) = self.files.get(url) {
            return Some(f.clone());
        }
        let path = PathBuf::from(url);
        let read = match std::fs::metadata(&path) {
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return None,
            Err(e) => Err(format!("{url}: {e}")),
            Ok(m) if !m.is_file() => return None,
            Ok(m) if m.len() > MAX_FILE_BYTES => Err(format!(
                "{url}: {} bytes, more than the {MAX_FILE_BYTES} served",
                m.len()
            )),
            Ok(_) => std::fs::read(&path)
                .map(Arc::from)
                .map_err(|e| format!("{url}: {e}")),
        };
        self.files.insert(url.to_string(), read.clone());
        Some(read)
    }

    /// Performs the client's actions at the current time: starts fetches, drops aborted ones.
    pub fn apply(&mut self, actions: &[Action]) {
        for a in actions {
            match a {
                Action::Fetch(req) => self.start(req),
                Action::Abort { id } => {
                    self.active.retain(|t| t.id != *id);
                    self.ready.retain(|d| d.id != *id);
                    self.end(*id, Outcome::Aborted);
                }
            }
        }
    }

    fn end(&mut self, id: RequestId, outcome: Outcome) {
        if let Some(&i) = self.log_at.get(&id)
            && self.log[i].outcome == Outcome::Open
        {
            self.log[i].outcome = outcome;
            self.log[i].end_s = Some(self.now);
        }
    }

    fn start(&mut self, req: &FetchRequest) {
        self.log_at.insert(req.id, self.log.len());
        self.log.push(TransferLog {
            id: req.id,
            url: req.url.clone(),
            range_start: req.range_start,
            start_s: self.now,
            end_s: None,
            bytes: 0,
            outcome: Outcome::Open,
        });
        let head_at = self.now + self.net.rtt_s.max(0.0);
        let (body, offset, head): (Arc<[u8]>, usize, NetEvent) = match self.file(&req.url) {
            None => (
                Arc::from(&b""[..]),
                0,
                NetEvent::Response {
                    status: 404,
                    etag: None,
                    range_start: None,
                    total: Some(0),
                },
            ),
            Some(Err(e)) => (Arc::from(&b""[..]), 0, NetEvent::Error(e)),
            Some(Ok(body)) => {
                let etag = etag_of(&body);
                let len = body.len() as u64;
                let start = req.range_start;
                let ranged =
                    start > 0 && start < len && req.if_range.as_deref().is_none_or(|t| t == etag);
                let head = NetEvent::Response {
                    status: if ranged { 206 } else { 200 },
                    etag: Some(etag),
                    range_start: ranged.then_some(start),
                    total: Some(len),
                };
                (body, if ranged { start as usize } else { 0 }, head)
            }
        };
        let t = Transfer {
            id: req.id,
            body,
            offset,
            delivered: 0,
            head_at,
            head: Some(head),
            wire: 0.0,
            overhead: self.net.overhead_bytes as f64,
        };
        let at = self.active.partition_point(|a| a.id < t.id);
        self.active.insert(at, t);
    }

    /// The next event no later than `until`, advancing the clock to it; `None` when nothing
    /// happens before `until` (the clock is then at `until`).
    pub fn next(&mut self, until: f64) -> Option<Delivery> {
        loop {
            if let Some(d) = self.ready.pop_front() {
                return Some(d);
            }
            if self.now >= until {
                return None;
            }
            let chunk = self.net.chunk_bytes.max(1);
            let rate = self.net.rate(self.now);
            let n_data = self.active.iter().filter(|t| t.in_data()).count();
            let share = if n_data > 0 {
                rate / n_data as f64
            } else {
                0.0
            };
            let mut next = until.min(self.net.next_change(self.now));
            for t in &self.active {
                if !t.in_data() {
                    next = next.min(t.head_at);
                } else if share > 0.0 {
                    let need = (t.target(chunk) - t.wire).max(0.0);
                    next = next.min(self.now + need / share);
                }
            }
            let next = next.max(self.now);
            let dt = next - self.now;
            for t in self.active.iter_mut().filter(|t| t.in_data()) {
                let goal = t.target(chunk);
                let got = (share * dt).min(goal - t.wire).max(0.0);
                t.wire += got;
                self.wire_bytes += got;
                // Float slack: a transfer whose step ends at its chunk boundary lands on it.
                if goal - t.wire < 1e-6 * goal.max(1.0) {
                    self.wire_bytes += goal - t.wire;
                    t.wire = goal;
                }
            }
            self.now = next;
            self.collect(chunk);
        }
    }

    /// Queues the events due now, in request-id order; drops finished transfers.
    fn collect(&mut self, chunk: usize) {
        let now = self.now;
        let mut finished = vec![];
        for t in self.active.iter_mut() {
            if t.head.is_some() {
                if t.head_at > now {
                    continue;
                }
                let head = t.head.take().expect("checked above");
                let ok = matches!(
                    head,
                    NetEvent::Response {
                        status: 200 | 206,
                        ..
                    }
                );
                let is_response = matches!(head, NetEvent::Response { .. });
                self.ready.push_back(Delivery {
                    t: now,
                    id: t.id,
                    event: head,
                });
                if !ok {
                    // Error, or a non-2xx head followed by the end of its (ignored) body.
                    if is_response {
                        self.ready.push_back(Delivery {
                            t: now,
                            id: t.id,
                            event: NetEvent::Done,
                        });
                    }
                    finished.push((t.id, Outcome::Failed, 0));
                    continue;
                }
            }
            if !t.in_data() {
                continue;
            }
            let got = t.received();
            while got >= (t.delivered + chunk).min(t.len()) && t.delivered < t.len() {
                let end = (t.delivered + chunk).min(t.len());
                let a = t.offset + t.delivered;
                let b = t.offset + end;
                self.ready.push_back(Delivery {
                    t: now,
                    id: t.id,
                    event: NetEvent::Data(t.body[a..b].to_vec()),
                });
                t.delivered = end;
            }
            if t.delivered >= t.len() && t.wire >= t.target(chunk) - 1e-9 {
                self.ready.push_back(Delivery {
                    t: now,
                    id: t.id,
                    event: NetEvent::Done,
                });
                finished.push((t.id, Outcome::Done, t.delivered as u64));
            }
        }
        // Data delivered so far counts in the log even if the transfer is aborted later.
        for t in &self.active {
            if let Some(&i) = self.log_at.get(&t.id) {
                self.log[i].bytes = t.delivered as u64;
            }
        }
        for (id, outcome, bytes) in finished {
            self.active.retain(|t| t.id != id);
            if let Some(&i) = self.log_at.get(&id) {
                self.log[i].bytes = bytes;
            }
            self.end(id, outcome);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fetch(id: RequestId, url: String, range_start: u64, if_range: Option<String>) -> Action {
        Action::Fetch(FetchRequest {
            id,
            url,
            range_start,
            if_range,
            priority: 1.0,
        })
    }

    /// Runs until nothing is left; returns every delivery.
    fn drain(t: &mut SimTransport) -> Vec<Delivery> {
        let until = t.now() + 100.0;
        std::iter::from_fn(|| t.next(until)).collect()
    }

    fn net(bytes_per_s: f64) -> NetModel {
        NetModel {
            bandwidth: vec![(0.0, bytes_per_s)],
            rtt_s: 0.1,
            overhead_bytes: 1000,
            chunk_bytes: 4000,
        }
    }

    #[test]
    fn shares_the_link_chunks_bodies_and_honours_ranges_and_aborts() {
        let dir = tempfile::tempdir().unwrap();
        let body: Vec<u8> = (0..10_000u32).map(|i| (i * 7) as u8).collect();
        std::fs::write(dir.path().join("a.bin"), &body).unwrap();
        std::fs::write(dir.path().join("b.bin"), &body).unwrap();
        let mut t = SimTransport::new(dir.path(), net(1e4));
        let url = |n: &str| format!("{}/{n}", dir.path().display());
        // Alone: RTT, then 1000 + 10000 bytes at 10 kB/s.
        t.apply(&[fetch(1, url("a.bin"), 0, None)]);
        let ev = drain(&mut t);
        let done = ev.iter().find(|d| d.event == NetEvent::Done).unwrap();
        assert!((done.t - 1.2).abs() < 1e-9, "{}", done.t);
        let data: Vec<u8> = ev
            .iter()
            .filter_map(|d| match &d.event {
                NetEvent::Data(b) => Some(b.clone()),
                _ => None,
            })
            .flatten()
            .collect();
        assert_eq!(data, body);
        assert_eq!(
            ev.iter()
                .filter(|d| matches!(d.event, NetEvent::Data(_)))
                .count(),
            3
        );
        let NetEvent::Response { etag, .. } = &ev[0].event else {
            panic!("{:?}", ev[0]);
        };
        // Two at once share the link: both end at 1.2 + 0.1 + 2 * 1.1.
        let t0 = t.now();
        t.apply(&[
            fetch(2, url("a.bin"), 0, None),
            fetch(3, url("b.bin"), 0, None),
        ]);
        let ends: Vec<f64> = drain(&mut t)
            .iter()
            .filter(|d| d.event == NetEvent::Done)
            .map(|d| d.t - t0)
            .collect();
        assert_eq!(ends.len(), 2);
        assert!(ends.iter().all(|e| (e - 2.3).abs() < 1e-9), "{ends:?}");
        // A resume with the right validator gets a 206 from its byte; a wrong one a 200.
        t.apply(&[
            fetch(4, url("a.bin"), 6000, etag.clone()),
            fetch(5, url("a.bin"), 6000, Some("\"other\"".into())),
        ]);
        let ev = drain(&mut t);
        let heads: Vec<&NetEvent> = ev
            .iter()
            .filter(|d| matches!(d.event, NetEvent::Response { .. }))
            .map(|d| &d.event)
            .collect();
        assert!(matches!(
            heads[0],
            NetEvent::Response {
                status: 206,
                range_start: Some(6000),
                ..
            }
        ));
        assert!(matches!(heads[1], NetEvent::Response { status: 200, .. }));
        let got4: usize = ev
            .iter()
            .filter(|d| d.id == 4)
            .map(|d| match &d.event {
                NetEvent::Data(b) => b.len(),
                _ => 0,
            })
            .sum();
        assert_eq!(got4, 4000);
        // An abort stops the transfer: nothing more for it, logged as aborted.
        t.apply(&[fetch(6, url("a.bin"), 0, None)]);
        let first = t.next(t.now() + 100.0).unwrap();
        assert_eq!(first.id, 6);
        t.apply(&[Action::Abort { id: 6 }]);
        assert!(drain(&mut t).is_empty());
        let log = t.log().last().unwrap();
        assert_eq!((log.id, log.outcome), (6, Outcome::Aborted));
        // Outside the root or missing: 404, then the end.
        t.apply(&[
            fetch(7, "/etc/passwd".into(), 0, None),
            fetch(8, url("../x"), 0, None),
            fetch(9, url("missing"), 0, None),
        ]);
        let ev = drain(&mut t);
        assert_eq!(ev.len(), 6);
        assert!(
            ev.iter()
                .step_by(2)
                .all(|d| matches!(d.event, NetEvent::Response { status: 404, .. }))
        );
        assert!(t.log()[6..].iter().all(|l| l.outcome == Outcome::Failed));
    }

    #[test]
    fn follows_piecewise_bandwidth() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("a.bin"), vec![1u8; 9000]).unwrap();
        let mut n = net(1e4);
        // 10 kB/s until 0.5 s, nothing until 1.5 s, then 20 kB/s.
        n.bandwidth = vec![(0.0, 1e4), (0.5, 0.0), (1.5, 2e4)];
        let mut t = SimTransport::new(dir.path(), n);
        t.apply(&[fetch(1, format!("{}/a.bin", dir.path().display()), 0, None)]);
        let done = drain(&mut t)
            .into_iter()
            .find(|d| d.event == NetEvent::Done)
            .unwrap();
        // 4000 B by 0.5 s, then 6000 B from 1.5 s at 20 kB/s.
        assert!((done.t - 1.8).abs() < 1e-9, "{}", done.t);
        assert_eq!(t.wire_bytes(), 10_000);
    }
}
