//! The browser's side of the sans-IO client: each `FetchRequest` becomes a Fetch API call with an
//! AbortController, a fetch priority and `Range`/`If-Range` when resuming; body chunks stream in.

use std::cell::RefCell;
use std::collections::{HashMap, HashSet};
use std::rc::Rc;

use js_sys::{Reflect, Uint8Array};
use splat2tiles_core::camera::Camera;
use splat2tiles_stream::client::{Action, FetchRequest, RequestId, StreamClient};
use wasm_bindgen::{JsCast, JsValue};
use wasm_bindgen_futures::JsFuture;
use web_sys::{
    AbortController, Headers, ReadableStreamDefaultReader, RequestCache, RequestInit, Response,
};

/// What the page's fetches and frames share: the client and the requests in flight.
pub struct Shared {
    /// The streaming client.
    pub client: StreamClient,
    /// Abort handles of the requests in flight.
    inflight: HashMap<RequestId, AbortController>,
    /// Requests aborted by the client whose tasks have not finished yet.
    aborted: HashSet<RequestId>,
    /// Requests aborted.
    pub aborts: u64,
    /// The camera of the last frame: a finished request runs the client's update with it, so
    /// the next requests start then, not only at the next frame (frames can be seconds apart).
    pub camera: Option<Camera>,
}

impl Shared {
    /// Wraps a client.
    pub fn new(client: StreamClient) -> Self {
        Shared {
            client,
            inflight: HashMap::new(),
            aborted: HashSet::new(),
            aborts: 0,
            camera: None,
        }
    }

    /// Requests in flight.
    pub fn in_flight(&self) -> usize {
        self.inflight.len()
    }
}

/// Seconds on the page's clock (the one requestAnimationFrame uses).
pub fn now_s() -> f64 {
    web_sys::window()
        .and_then(|w| w.performance())
        .map(|p| p.now() / 1000.0)
        .unwrap_or(0.0)
}

/// Starts `req` in the background.
pub fn start(shared: &Rc<RefCell<Shared>>, req: FetchRequest) {
    let controller = match AbortController::new() {
        Ok(c) => c,
        Err(e) => {
            let msg = format!("cannot create an AbortController: {e:?}");
            shared.borrow_mut().client.on_error(req.id, &msg, now_s());
            return;
        }
    };
    shared
        .borrow_mut()
        .inflight
        .insert(req.id, controller.clone());
    let shared = shared.clone();
    wasm_bindgen_futures::spawn_local(async move {
        let result = transfer(&shared, &req, &controller).await;
        let mut s = shared.borrow_mut();
        s.inflight.remove(&req.id);
        if s.aborted.remove(&req.id) {
            return;
        }
        match result {
            Ok(()) => s.client.on_done(req.id, now_s()),
            Err(msg) => s
                .client
                .on_error(req.id, &format!("{}: {msg}", req.url), now_s()),
        }
        // A slot is free: let the client use it now rather than at the next frame.
        let actions = match s.camera {
            Some(cam) => s.client.update(now_s(), &cam),
            None => vec![],
        };
        drop(s);
        dispatch(&shared, actions);
    });
}

/// Carries out the client's actions: fetches started, requests aborted.
pub fn dispatch(shared: &Rc<RefCell<Shared>>, actions: Vec<Action>) {
    for a in actions {
        match a {
            Action::Fetch(req) => start(shared, req),
            Action::Abort { id } => abort(shared, id),
        }
    }
}

/// Aborts a request in flight (the client keeps what arrived and may resume it with Range).
pub fn abort(shared: &Rc<RefCell<Shared>>, id: RequestId) {
    let mut s = shared.borrow_mut();
    if let Some(c) = s.inflight.get(&id).cloned() {
        s.aborted.insert(id);
        s.aborts += 1;
        drop(s);
        c.abort();
    }
}

fn js_err(e: JsValue) -> String {
    e.as_string()
        .or_else(|| {
            Reflect::get(&e, &"message".into())
                .ok()
                .and_then(|m| m.as_string())
        })
        .unwrap_or_else(|| format!("{e:?}"))
}

async fn transfer(
    shared: &Rc<RefCell<Shared>>,
    req: &FetchRequest,
    controller: &AbortController,
) -> Result<(), String> {
    let window = web_sys::window().ok_or("no window")?;
    let init = RequestInit::new();
    init.set_method("GET");
    init.set_signal(Some(&controller.signal()));
    // The client keeps its own bytes and resumes with Range itself. Chromium's HTTP cache would
    // otherwise hold a truncated entry for an aborted body and make the next request for the same
    // URL wait on that entry's cache lock.
    init.set_cache(RequestCache::NoStore);
    let headers = Headers::new().map_err(js_err)?;
    if req.range_start > 0 {
        headers
            .set("Range", &format!("bytes={}-", req.range_start))
            .map_err(js_err)?;
        if let Some(etag) = &req.if_range {
            headers.set("If-Range", etag).map_err(js_err)?;
        }
    }
    init.set_headers(&headers);
    // Fetch priority (Chromium, Safari): tiles in view first. Not in web-sys's stable API yet.
    let priority = if req.priority >= 0.5 { "high" } else { "low" };
    let _ = Reflect::set(&init, &"priority".into(), &priority.into());
    let resp: Response = JsFuture::from(window.fetch_with_str_and_init(&req.url, &init))
        .await
        .map_err(js_err)?
        .dyn_into()
        .map_err(js_err)?;
    let status = resp.status();
    let h = resp.headers();
    let etag = h.get("ETag").ok().flatten();
    let (mut start, mut total) = (None, None);
    if status == 206 {
        if let Some(cr) = h.get("Content-Range").ok().flatten() {
            (start, total) = splat2tiles_stream::client::url::parse_content_range(&cr);
        }
    } else {
        total = h
            .get("Content-Length")
            .ok()
            .flatten()
            .and_then(|v| v.trim().parse().ok());
    }
    {
        let mut s = shared.borrow_mut();
        if s.aborted.contains(&req.id) {
            return Ok(());
        }
        s.client
            .on_response(req.id, status, etag.as_deref(), start, total);
    }
    let Some(body) = resp.body() else {
        return Ok(());
    };
    let reader: ReadableStreamDefaultReader = body.get_reader().unchecked_into();
    loop {
        let chunk = JsFuture::from(reader.read()).await.map_err(js_err)?;
        if Reflect::get(&chunk, &"done".into())
            .ok()
            .and_then(|d| d.as_bool())
            .unwrap_or(true)
        {
            return Ok(());
        }
        let value: Uint8Array = Reflect::get(&chunk, &"value".into())
            .map_err(js_err)?
            .dyn_into()
            .map_err(js_err)?;
        let bytes = value.to_vec();
        let mut s = shared.borrow_mut();
        if s.aborted.contains(&req.id) {
            return Ok(());
        }
        s.client.on_data(req.id, &bytes, now_s());
    }
}
