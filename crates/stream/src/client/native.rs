//! Blocking native driver of the sans-IO [`StreamClient`]: worker threads fetch `http://` URLs
//! (reqwest, no TLS) and local files (`file://` or plain paths) with Range / If-Range.
//!
//! [`Driver::tick`] never blocks: it feeds the chunks the workers streamed back through a channel
//! to the client, then runs [`StreamClient::update`] and hands the new fetches to the workers;
//! an abort raises the transfer's cancel flag, and its worker drops the response (closing the
//! connection) before the next chunk.

use std::collections::{HashMap, VecDeque};
use std::io::{Read, Seek, SeekFrom};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, Sender, channel};
use std::sync::{Arc, Condvar, Mutex};
use std::thread::JoinHandle;

use super::timeline::Input;
use super::{
    Action, ClientConfig, ClientStats, FetchRequest, RequestId, SceneUpdate, StreamClient,
};
use splat2tiles_core::camera::Camera;

/// Bytes per chunk a worker reads before handing it over.
pub const CHUNK_BYTES: usize = 64 * 1024;

/// What a worker reports about a transfer.
#[derive(Debug)]
enum Event {
    Response {
        id: RequestId,
        status: u16,
        etag: Option<String>,
        range_start: Option<u64>,
        total: Option<u64>,
    },
    Data(RequestId, Vec<u8>),
    Done(RequestId),
    Error(RequestId, String),
}

struct Job {
    req: FetchRequest,
    cancel: Arc<AtomicBool>,
}

#[derive(Default)]
struct Queue {
    jobs: VecDeque<Job>,
    closed: bool,
}

/// Runs a [`StreamClient`] with a pool of fetching threads.
pub struct Driver {
    client: StreamClient,
    queue: Arc<(Mutex<Queue>, Condvar)>,
    events: Receiver<Event>,
    cancels: HashMap<RequestId, Arc<AtomicBool>>,
    workers: Vec<JoinHandle<()>>,
    recording: Option<Recording>,
}

/// What a recording driver saw: the client's inputs in order and the actions of each update.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Recording {
    /// Every call made on the client, in order.
    pub inputs: Vec<Input>,
    /// The actions each `Update` input returned.
    pub actions: Vec<Vec<Action>>,
}

impl std::fmt::Debug for Driver {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Driver")
            .field("client", &self.client)
            .field("workers", &self.workers.len())
            .finish_non_exhaustive()
    }
}

impl Driver {
    /// A driver for the tileset at `url` (`http://`, `file://` or a path) with
    /// `cfg.max_concurrent` worker threads.
    pub fn new(url: &str, cfg: ClientConfig) -> Self {
        let n = cfg.max_concurrent.max(1);
        let client = StreamClient::new(url, cfg);
        let queue = Arc::new((Mutex::new(Queue::default()), Condvar::new()));
        let (tx, rx) = channel();
        let workers = (0..n)
            .map(|_| {
                let q = Arc::clone(&queue);
                let tx = tx.clone();
                std::thread::spawn(move || worker(q, tx))
            })
            .collect();
        Driver {
            client,
            queue,
            events: rx,
            cancels: HashMap::new(),
            workers,
            recording: None,
        }
    }

    /// Records every client input and the actions of each update from now on (replayable with
    /// [`super::timeline::replay`]).
    pub fn record(&mut self) {
        self.recording.get_or_insert_with(Recording::default);
    }

    /// Takes what was recorded since [`Self::record`] (recording goes on).
    pub fn take_recording(&mut self) -> Option<Recording> {
        self.recording.as_mut().map(std::mem::take)
    }

    /// One non-blocking step at time `now_s`: delivers what the workers received, updates the
    /// client with `camera`, starts and aborts transfers; returns the scene updates.
    pub fn tick(&mut self, now_s: f64, camera: &Camera) -> Vec<SceneUpdate> {
        while let Ok(ev) = self.events.try_recv() {
            let input = match ev {
                Event::Response {
                    id,
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
                Event::Data(id, bytes) => Input::Data {
                    id,
                    t: now_s,
                    bytes,
                },
                Event::Done(id) => {
                    self.cancels.remove(&id);
                    Input::Done { id, t: now_s }
                }
                Event::Error(id, message) => {
                    self.cancels.remove(&id);
                    Input::Error {
                        id,
                        t: now_s,
                        message,
                    }
                }
            };
            input.apply(&mut self.client);
            if let Some(r) = self.recording.as_mut() {
                r.inputs.push(input);
            }
        }
        let actions = self.client.update(now_s, camera);
        if let Some(r) = self.recording.as_mut() {
            r.inputs.push(Input::Update {
                t: now_s,
                camera: *camera,
            });
            r.actions.push(actions.clone());
        }
        for a in actions {
            match a {
                Action::Fetch(req) => {
                    let cancel = Arc::new(AtomicBool::new(false));
                    self.cancels.insert(req.id, Arc::clone(&cancel));
                    let (m, cv) = &*self.queue;
                    let mut q = m.lock().unwrap_or_else(|e| e.into_inner());
                    // Higher priority first among the queued jobs.
                    let at = q
                        .jobs
                        .iter()
                        .position(|j| j.req.priority < req.priority)
                        .unwrap_or(q.jobs.len());
                    q.jobs.insert(at, Job { req, cancel });
                    cv.notify_one();
                }
                Action::Abort { id } => {
                    if let Some(c) = self.cancels.remove(&id) {
                        c.store(true, Ordering::Relaxed);
                    }
                }
            }
        }
        self.client.take_updates()
    }

    /// The client's counters.
    pub fn stats(&self) -> ClientStats {
        self.client.stats()
    }

    /// The client is idle and no transfer is running.
    pub fn is_idle(&self) -> bool {
        self.client.is_idle() && self.cancels.is_empty()
    }

    /// The wrapped client (resident tiles, drawn tiles, catalog).
    pub fn client(&self) -> &StreamClient {
        &self.client
    }

    /// A new viewport size in pixels ([`StreamClient::set_viewport`]).
    pub fn set_viewport(&mut self, width: u32, height: u32) {
        self.client.set_viewport(width, height);
    }
}

impl Drop for Driver {
    fn drop(&mut self) {
        for c in self.cancels.values() {
            c.store(true, Ordering::Relaxed);
        }
        {
            let (m, cv) = &*self.queue;
            let mut q = m.lock().unwrap_or_else(|e| e.into_inner());
            q.closed = true;
            q.jobs.clear();
            cv.notify_all();
        }
        for w in self.workers.drain(..) {
            let _ = w.join();
        }
    }
}

fn worker(queue: Arc<(Mutex<Queue>, Condvar)>, tx: Sender<Event>) {
    let http = reqwest::blocking::Client::builder()
        .timeout(None)
        .build()
        .ok();
    loop {
        let job = {
            let (m, cv) = &*queue;
            let mut q = m.lock().unwrap_or_else(|e| e.into_inner());
            loop {
                if q.closed {
                    return;
                }
                if let Some(j) = q.jobs.pop_front() {
                    break j;
                }
                q = cv.wait(q).unwrap_or_else(|e| e.into_inner());
            }
        };
        if job.cancel.load(Ordering::Relaxed) {
            continue;
        }
        let id = job.req.id;
        let res = if is_http(&job.req.url) {
            match &http {
                Some(c) => fetch_http(c, &job, &tx),
                None => Err("HTTP client could not be built".to_string()),
            }
        } else {
            fetch_file(&job, &tx)
        };
        let ev = match res {
            Ok(true) => Event::Done(id),
            Ok(false) => continue, // cancelled
            Err(e) => Event::Error(id, e),
        };
        if tx.send(ev).is_err() {
            return;
        }
    }
}

fn is_http(url: &str) -> bool {
    url.get(..7)
        .is_some_and(|s| s.eq_ignore_ascii_case("http://"))
        || url
            .get(..8)
            .is_some_and(|s| s.eq_ignore_ascii_case("https://"))
}

/// Streams `r` in chunks to the channel; `Ok(false)` when cancelled.
fn pump(mut r: impl Read, job: &Job, tx: &Sender<Event>) -> Result<bool, String> {
    let mut buf = vec![0u8; CHUNK_BYTES];
    loop {
        if job.cancel.load(Ordering::Relaxed) {
            return Ok(false);
        }
        let n = match r.read(&mut buf) {
            Ok(0) => return Ok(true),
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(e.to_string()),
        };
        if tx.send(Event::Data(job.req.id, buf[..n].to_vec())).is_err() {
            return Ok(false);
        }
    }
}

fn fetch_http(
    c: &reqwest::blocking::Client,
    job: &Job,
    tx: &Sender<Event>,
) -> Result<bool, String> {
    let mut rb = c.get(&job.req.url);
    if job.req.range_start > 0 {
        rb = rb.header(
            reqwest::header::RANGE,
            format!("bytes={}-", job.req.range_start),
        );
        if let Some(tag) = &job.req.if_range {
            rb = rb.header(reqwest::header::IF_RANGE, tag.as_str());
        }
    }
    let resp = rb.send().map_err(|e| e.to_string())?;
    let status = resp.status().as_u16();
    let h = resp.headers();
    let text = |name: reqwest::header::HeaderName| {
        h.get(name)
            .and_then(|v| v.to_str().ok())
            .map(str::to_string)
    };
    let etag = text(reqwest::header::ETAG);
    let (range_start, total) = match text(reqwest::header::CONTENT_RANGE) {
        Some(cr) if status == 206 => crate::client::url::parse_content_range(&cr),
        _ => (None, resp.content_length()),
    };
    if tx
        .send(Event::Response {
            id: job.req.id,
            status,
            etag,
            range_start,
            total,
        })
        .is_err()
    {
        return Ok(false);
    }
    if status != 200 && status != 206 {
        return Ok(true); // the client recorded the error from the status; body not needed
    }
    pump(resp, job, tx)
}

fn fetch_file(job: &Job, tx: &Sender<Event>) -> Result<bool, String> {
    let url = &job.req.url;
    let path = url.strip_prefix("file://").unwrap_or(url);
    let send_status = |status: u16| {
        tx.send(Event::Response {
            id: job.req.id,
            status,
            etag: None,
            range_start: None,
            total: None,
        })
        .is_ok()
    };
    let mut f = match std::fs::File::open(path) {
        Ok(f) => f,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            return Ok(send_status(404));
        }
        Err(e) => return Err(format!("{path}: {e}")),
    };
    let meta = f.metadata().map_err(|e| format!("{path}: {e}"))?;
    if !meta.is_file() {
        return Ok(send_status(404));
    }
    let len = meta.len();
    let mtime = meta
        .modified()
        .ok()
        .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
        .map_or(0, |d| d.as_nanos());
    let etag = format!("\"{len:x}-{mtime:x}\"");
    let start = job.req.range_start;
    let ranged = start > 0 && start < len && job.req.if_range.as_deref().is_none_or(|t| t == etag);
    if ranged {
        f.seek(SeekFrom::Start(start))
            .map_err(|e| format!("{path}: {e}"))?;
    }
    let ev = Event::Response {
        id: job.req.id,
        status: if ranged { 206 } else { 200 },
        etag: Some(etag),
        range_start: ranged.then_some(start),
        total: Some(len),
    };
    if tx.send(ev).is_err() {
        return Ok(false);
    }
    pump(f.take(len - if ranged { start } else { 0 }), job, tx)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn content_range_parsing() {
        assert_eq!(
            crate::client::url::parse_content_range("bytes 100-199/1000"),
            (Some(100), Some(1000))
        );
        assert_eq!(
            crate::client::url::parse_content_range("bytes 5-9/*"),
            (Some(5), None)
        );
        assert_eq!(
            crate::client::url::parse_content_range("items 1-2/3"),
            (None, None)
        );
        assert!(is_http("HTTP://x/y") && !is_http("file:///x") && !is_http("/tmp/x"));
    }
}
