//! A static HTTP/1.1 file server for tilesets and the web viewer (`splat2tiles serve` / `view`):
//! GET/HEAD/OPTIONS, single byte ranges, strong ETags, precompressed `.br`/`.gz` siblings, CORS.
//!
//! HTTP framing (request heads, keep-alive, Content-Length) is [`http`]'s, one thread per
//! connection (tiny_http was dropped: its connection pool left a burst of browser connections
//! unanswered until an idle one closed); this module decides the answer ([`answer`], a pure
//! function of the request and the files). Range requests on a precompressed answer refer to the encoded bytes,
//! whose ETag differs from the identity file's, so a download resumed with `If-Range` either
//! continues the same encoded bytes or restarts with a full 200.

/// `log` target of the access log: one line per request (method, target, status, bytes sent),
/// emitted at `Info` unless `ServeOptions::quiet`; the binary prints them on stderr.
pub const ACCESS_LOG: &str = "splat2tiles_serve::access";

pub mod admission;
mod connection;
pub mod http;
pub mod range;
pub mod resolve;

use admission::Admission;

use range::{RangeRequest, parse_range};
use resolve::{Refusal, inside, segments};
use std::ffi::OsString;
use std::fs::File;
use std::net::{IpAddr, SocketAddr, TcpListener};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, UNIX_EPOCH};

/// Why a server could not start.
#[derive(Debug, thiserror::Error)]
pub enum ServeError {
    /// A folder to serve is missing or unreadable.
    #[error("{path}: cannot serve this folder: {source}")]
    Root {
        /// The folder.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The address could not be bound.
    #[error("cannot listen on {addr}: {message}{}", if *.in_use { " (another server uses this port; pass --port 0 to pick a free one, or another --port)" } else { "" })]
    Bind {
        /// Address and port asked for.
        addr: SocketAddr,
        /// The OS's reason.
        message: String,
        /// The port is taken (`EADDRINUSE`).
        in_use: bool,
    },
}

/// One served folder at a URL prefix (`/` or e.g. `/viewer/`).
#[derive(Debug, Clone)]
pub struct Mount {
    /// URL path segments before the folder's files (`[]` for `/`, `["viewer"]` for `/viewer/`).
    pub prefix: Vec<String>,
    /// The folder, canonical (symlinks resolved), so that containment checks are exact.
    pub root: PathBuf,
}

impl Mount {
    /// Mounts `root` at the URL prefix `at` (`"/"`, `"/viewer/"`); the folder must exist.
    pub fn new(at: &str, root: &Path) -> Result<Self, ServeError> {
        let canon = root.canonicalize().map_err(|source| ServeError::Root {
            path: root.to_path_buf(),
            source,
        })?;
        if !canon.is_dir() {
            return Err(ServeError::Root {
                path: root.to_path_buf(),
                source: std::io::Error::new(std::io::ErrorKind::NotADirectory, "not a folder"),
            });
        }
        let prefix = at
            .split('/')
            .filter(|s| !s.is_empty())
            .map(str::to_string)
            .collect();
        Ok(Mount {
            prefix,
            root: canon,
        })
    }
}

/// The request methods the server distinguishes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    /// GET.
    Get,
    /// HEAD: GET's headers, no body.
    Head,
    /// OPTIONS (CORS preflight).
    Options,
    /// Anything else: 405.
    Other,
}

/// What [`answer`] needs of a request: method, raw target, and header lookup.
#[derive(Debug, Clone)]
pub struct Request {
    /// The method.
    pub method: Method,
    /// The request target as sent (`/tiles/a.glb?x`), still percent-encoded.
    pub target: String,
    /// Header fields as sent (names compared case-insensitively).
    pub headers: Vec<(String, String)>,
}

impl Request {
    /// The first value of header `name`.
    pub fn header(&self, name: &str) -> Option<&str> {
        self.headers
            .iter()
            .find(|(k, _)| k.eq_ignore_ascii_case(name))
            .map(|(_, v)| v.as_str())
    }
}

/// A response body.
#[derive(Debug)]
pub enum Body {
    /// No body bytes (304, 416, OPTIONS).
    Empty,
    /// A short text (error messages).
    Text(String),
    /// `len` bytes of `file` from `start`.
    File {
        /// The open file.
        file: File,
        /// First byte sent.
        start: u64,
        /// Bytes sent.
        len: u64,
    },
}

/// The answer to one request: status, header fields and body.
#[derive(Debug)]
pub struct Reply {
    /// HTTP status code.
    pub status: u16,
    /// Header fields (Content-Length is derived from the body by the HTTP layer).
    pub headers: Vec<(&'static str, String)>,
    /// Body; for HEAD and 304 [`Reply::length`] still reports the GET length.
    pub body: Body,
    /// Content-Length to announce (the GET body's for HEAD and 304).
    pub length: u64,
}

impl Reply {
    fn new(status: u16) -> Self {
        Reply {
            status,
            headers: Vec::new(),
            body: Body::Empty,
            length: 0,
        }
    }

    fn text(status: u16, msg: &str) -> Self {
        let mut r = Reply::new(status);
        r.headers
            .push(("Content-Type", "text/plain; charset=utf-8".into()));
        r.length = msg.len() as u64 + 1;
        r.body = Body::Text(format!("{msg}\n"));
        r
    }

    /// The value of header `name` in this reply.
    pub fn header(&self, name: &str) -> Option<&str> {
        self.headers
            .iter()
            .find(|(k, _)| k.eq_ignore_ascii_case(name))
            .map(|(_, v)| v.as_str())
    }
}

/// Headers a page on another origin may read (`fetch` of ranges needs these).
const EXPOSED: &str = "Content-Range, Content-Length, Content-Encoding, ETag, Accept-Ranges";
/// Methods served.
const ALLOW: &str = "GET, HEAD, OPTIONS";
/// Request headers a cross-origin page may send.
const ALLOWED_HEADERS: &str = "Range, If-Range, If-None-Match, If-Modified-Since, Accept-Encoding";

/// Content type of a file by its extension (of the identity name for `.gz`/`.br` siblings).
pub fn content_type(path: &Path) -> &'static str {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase();
    match ext.as_str() {
        "json" | "map" => "application/json",
        "glb" => "model/gltf-binary",
        "gltf" => "model/gltf+json",
        "subtree" => "application/octet-stream",
        "html" | "htm" => "text/html; charset=utf-8",
        "js" | "mjs" => "text/javascript; charset=utf-8",
        "wasm" => "application/wasm",
        "css" => "text/css; charset=utf-8",
        "png" => "image/png",
        "jpg" | "jpeg" => "image/jpeg",
        "svg" => "image/svg+xml",
        "ico" => "image/x-icon",
        "txt" | "md" => "text/plain; charset=utf-8",
        "gz" => "application/gzip",
        _ => "application/octet-stream",
    }
}

/// Whether an `Accept-Encoding` value admits `coding` (`q=0` refuses; `*` covers the rest).
pub fn accepts_encoding(header: Option<&str>, coding: &str) -> bool {
    let Some(header) = header else {
        return false;
    };
    let mut star = false;
    for item in header.split(',') {
        let mut parts = item.split(';');
        let name = parts.next().unwrap_or("").trim();
        let q = parts
            .filter_map(|p| {
                let (k, v) = p.split_once('=')?;
                k.trim()
                    .eq_ignore_ascii_case("q")
                    .then(|| v.trim().parse::<f32>().unwrap_or(0.0))
            })
            .next()
            .unwrap_or(1.0);
        let ok = q > 0.0;
        if name.eq_ignore_ascii_case(coding) || (coding == "gzip" && name == "x-gzip") {
            return ok;
        }
        if name == "*" {
            star = ok;
        }
    }
    star
}

/// Precompressed siblings, preferred first: (Content-Encoding, file suffix).
const ENCODINGS: [(&str, &str); 2] = [("br", "br"), ("gzip", "gz")];

/// `path` with `.suffix` appended to its file name.
fn with_suffix(path: &Path, suffix: &str) -> PathBuf {
    let mut s: OsString = path.as_os_str().to_owned();
    s.push(".");
    s.push(suffix);
    PathBuf::from(s)
}

/// The strong ETag of a file's current version (inode, size and mtime, plus the encoding).
fn etag(meta: &std::fs::Metadata, coding: Option<&str>) -> String {
    let mtime = meta
        .modified()
        .ok()
        .and_then(|t| t.duration_since(UNIX_EPOCH).ok())
        .map_or(0, |d| d.as_nanos());
    #[cfg(unix)]
    let ino = std::os::unix::fs::MetadataExt::ino(meta);
    #[cfg(not(unix))]
    let ino = 0u64;
    let suffix = coding.map(|c| format!("-{c}")).unwrap_or_default();
    format!("\"{ino:x}-{:x}-{mtime:x}{suffix}\"", meta.len())
}

/// Whether an `If-None-Match` value matches `tag` (weak comparison, `*` matches any).
fn none_match_hits(header: &str, tag: &str) -> bool {
    let strip = |t: &str| t.trim().trim_start_matches("W/").to_string();
    header.trim() == "*" || header.split(',').any(|t| strip(t) == strip(tag))
}

/// Percent-encodes one path segment for a `Location` header.
fn encode_segment(s: &str) -> String {
    let mut out = String::new();
    for b in s.bytes() {
        if b.is_ascii_alphanumeric() || b"-._~!$&'()*+,;=:@".contains(&b) {
            out.push(b as char);
        } else {
            out.push_str(&format!("%{b:02X}"));
        }
    }
    out
}

/// The reply to `req` from the files under `mounts` (longest matching prefix wins).
pub fn answer(mounts: &[Mount], req: &Request) -> Reply {
    let mut reply = answer_inner(mounts, req);
    reply
        .headers
        .push(("Access-Control-Allow-Origin", "*".into()));
    reply
        .headers
        .push(("Access-Control-Expose-Headers", EXPOSED.into()));
    reply
}

fn answer_inner(mounts: &[Mount], req: &Request) -> Reply {
    match req.method {
        Method::Get | Method::Head => {}
        Method::Options => {
            // 200, not 204: the HTTP layer always sends a Content-Length, which a 204 must not carry.
            let mut r = Reply::new(200);
            r.headers.push(("Allow", ALLOW.into()));
            r.headers
                .push(("Access-Control-Allow-Methods", ALLOW.into()));
            r.headers
                .push(("Access-Control-Allow-Headers", ALLOWED_HEADERS.into()));
            r.headers.push(("Access-Control-Max-Age", "86400".into()));
            return r;
        }
        Method::Other => {
            let mut r = Reply::text(405, "method not allowed: GET, HEAD and OPTIONS only");
            r.headers.push(("Allow", ALLOW.into()));
            return r;
        }
    }
    let (segs, trailing) = match segments(&req.target) {
        Ok(s) => s,
        Err(refusal) => return refused(&refusal),
    };
    let Some(mount) = mounts
        .iter()
        .filter(|m| segs.starts_with(&m.prefix))
        .max_by_key(|m| m.prefix.len())
    else {
        return Reply::text(404, "not found");
    };
    let rest = &segs[mount.prefix.len()..];
    let mut path = mount.root.clone();
    path.extend(rest);
    match inside(&mount.root, &path) {
        Ok(real) if real.is_dir() => {
            if !trailing && !segs.is_empty() {
                let mut r = Reply::text(301, "moved: add a trailing slash");
                let loc: Vec<String> = segs.iter().map(|s| encode_segment(s)).collect();
                r.headers.push(("Location", format!("/{}/", loc.join("/"))));
                return r;
            }
            match inside(&mount.root, &real.join("index.html")) {
                Ok(index) if index.is_file() => serve_file(&mount.root, &index, req),
                Ok(_) | Err(Refusal::NotFound) => Reply::text(404, "not found (no index.html)"),
                Err(e) => refused(&e),
            }
        }
        Ok(real) if real.is_file() => serve_file(&mount.root, &real, req),
        Ok(_) => Reply::text(404, "not found"),
        // Only a precompressed copy may exist (e.g. `a.glb.gz` without `a.glb`).
        Err(Refusal::NotFound) if !trailing => serve_file(&mount.root, &path, req),
        Err(e) => refused(&e),
    }
}

fn refused(r: &Refusal) -> Reply {
    match r {
        Refusal::BadRequest(why) => Reply::text(400, &format!("bad request: {why}")),
        Refusal::Forbidden(why) => Reply::text(403, &format!("forbidden: {why}")),
        Refusal::NotFound => Reply::text(404, "not found"),
    }
}

/// Serves the file at `path` (canonical, or absent when only a `.gz`/`.br` sibling exists).
fn serve_file(root: &Path, path: &Path, req: &Request) -> Reply {
    let accept = req.header("Accept-Encoding");
    let mut has_sibling = false;
    let mut chosen: Option<(&str, PathBuf)> = None;
    for (coding, suffix) in ENCODINGS {
        if let Ok(p) = inside(root, &with_suffix(path, suffix))
            && p.is_file()
        {
            has_sibling = true;
            if chosen.is_none() && accepts_encoding(accept, coding) {
                chosen = Some((coding, p));
            }
        }
    }
    let identity_exists = path.is_file();
    let (coding, file_path) = match chosen {
        Some((c, p)) => (Some(c), p),
        None if identity_exists => (None, path.to_path_buf()),
        None if has_sibling => {
            return Reply::text(
                406,
                "not acceptable: only a precompressed copy exists and the request's \
                 Accept-Encoding does not admit its encoding",
            );
        }
        None => return Reply::text(404, "not found"),
    };
    let file = match File::open(&file_path) {
        Ok(f) => f,
        Err(_) => return Reply::text(404, "not found (unreadable)"),
    };
    let meta = match file.metadata() {
        Ok(m) if m.is_file() => m,
        _ => return Reply::text(404, "not found"),
    };
    let len = meta.len();
    let tag = etag(&meta, coding);
    let mut r = Reply::new(200);
    r.headers.push(("Content-Type", content_type(path).into()));
    r.headers.push(("Accept-Ranges", "bytes".into()));
    r.headers.push(("ETag", tag.clone()));
    r.headers.push(("Cache-Control", "no-cache".into()));
    if let Some(c) = coding {
        r.headers.push(("Content-Encoding", c.into()));
    }
    if has_sibling {
        r.headers.push(("Vary", "Accept-Encoding".into()));
    }
    if let Some(inm) = req.header("If-None-Match")
        && none_match_hits(inm, &tag)
    {
        r.status = 304;
        r.length = len;
        return r;
    }
    let range = match req.header("Range") {
        // If-Range: the range applies only to the version the client already holds (strong match).
        Some(_) if req.header("If-Range").is_some_and(|v| v.trim() != tag) => RangeRequest::Whole,
        Some(h) => parse_range(h, len),
        None => RangeRequest::Whole,
    };
    let (start, n) = match range {
        RangeRequest::Whole => (0, len),
        RangeRequest::Part { start, end } => {
            r.status = 206;
            r.headers
                .push(("Content-Range", format!("bytes {start}-{}/{len}", end - 1)));
            (start, end - start)
        }
        RangeRequest::Unsatisfiable => {
            r.status = 416;
            r.headers.push(("Content-Range", format!("bytes */{len}")));
            return r;
        }
    };
    r.length = n;
    r.body = Body::File {
        file,
        start,
        len: n,
    };
    r
}

/// Options of a running server.
#[derive(Debug, Clone)]
pub struct ServeOptions {
    /// Address to listen on (loopback unless asked otherwise).
    pub bind: IpAddr,
    /// Port; 0 picks a free one.
    pub port: u16,
    /// No per-request log line.
    pub quiet: bool,
    /// Most connections kept at once (one thread each); beyond that a newcomer evicts a waiting
    /// connection, or gets 503 when all are busy answering.
    pub threads: usize,
    /// Most connections of one client address busy answering at once (a request beyond it
    /// gets 503 with `Retry-After`).
    pub per_address: usize,
}

/// Connections the kernel queues before `accept` (std's default of 128 overflowed under a burst
/// of a thousand connections, and each overflow costs the client a 1 s SYN retransmit).
const BACKLOG: i32 = 4096;

/// A listening socket on `addr` with an accept queue of `backlog` (capped by the kernel's
/// `somaxconn`).
fn listen(addr: SocketAddr, backlog: i32) -> std::io::Result<TcpListener> {
    use socket2::{Domain, Socket, Type};
    let socket = Socket::new(Domain::for_address(addr), Type::STREAM, None)?;
    #[cfg(unix)]
    socket.set_reuse_address(true)?;
    socket.bind(&addr.into())?;
    socket.listen(backlog)?;
    Ok(socket.into())
}

/// Stops a running [`Server`] from another thread (Ctrl-C handler, tests).
#[derive(Debug, Clone)]
pub struct StopHandle {
    stop: Arc<AtomicBool>,
    addr: SocketAddr,
}

impl StopHandle {
    /// Asks the server to stop; [`Server::run`] returns within a fraction of a second.
    pub fn stop(&self) {
        self.stop.store(true, Ordering::SeqCst);
        // Wake the blocking accept.
        let mut wake = self.addr;
        if wake.ip().is_unspecified() {
            wake.set_ip(match wake.ip() {
                IpAddr::V4(_) => IpAddr::V4(std::net::Ipv4Addr::LOCALHOST),
                IpAddr::V6(_) => IpAddr::V6(std::net::Ipv6Addr::LOCALHOST),
            });
        }
        let _ = std::net::TcpStream::connect_timeout(&wake, Duration::from_secs(1));
    }
}

/// A bound server, not yet answering.
pub struct Server {
    listener: TcpListener,
    mounts: Arc<Vec<Mount>>,
    addr: SocketAddr,
    opts: ServeOptions,
    stop: Arc<AtomicBool>,
}

impl Server {
    /// Binds `opts.bind:opts.port` for `mounts`.
    pub fn bind(mounts: Vec<Mount>, opts: ServeOptions) -> Result<Self, ServeError> {
        let want = SocketAddr::new(opts.bind, opts.port);
        let bind_err = |e: std::io::Error| ServeError::Bind {
            addr: want,
            in_use: e.kind() == std::io::ErrorKind::AddrInUse,
            message: e.to_string(),
        };
        let listener = listen(want, BACKLOG).map_err(bind_err)?;
        let addr = listener.local_addr().map_err(bind_err)?;
        Ok(Server {
            listener,
            mounts: Arc::new(mounts),
            addr,
            opts,
            stop: Arc::new(AtomicBool::new(false)),
        })
    }

    /// The address actually listened on (the port chosen for port 0).
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// A handle that stops [`Server::run`].
    pub fn stop_handle(&self) -> StopHandle {
        StopHandle {
            stop: self.stop.clone(),
            addr: self.addr,
        }
    }

    /// Accepts connections until stopped, each answered on its own thread (keep-alive). When
    /// full, a newcomer evicts a waiting connection ([`admission`]); 503 only when all are busy.
    pub fn run(self) {
        let admission = Admission::new(self.opts.threads, self.opts.per_address);
        for conn in self.listener.incoming() {
            if self.stop.load(Ordering::SeqCst) {
                break;
            }
            let stream = match conn {
                Ok(s) => s,
                Err(e) => {
                    if !self.opts.quiet {
                        log::warn!("serve: accept failed: {e}");
                    }
                    // E.g. out of file descriptors: don't spin.
                    std::thread::sleep(Duration::from_millis(20));
                    continue;
                }
            };
            let ip = stream
                .peer_addr()
                .map(|a| a.ip())
                .unwrap_or(IpAddr::V4(std::net::Ipv4Addr::UNSPECIFIED));
            let Some(ticket) = admission.admit(ip, &stream) else {
                let _ = stream.set_write_timeout(Some(Duration::from_secs(1)));
                let mut w = std::io::BufWriter::new(&stream);
                let msg = b"too many connections\n";
                let _ = http::write_response(
                    &mut w,
                    503,
                    &[("Retry-After", "1".into())],
                    msg.len() as u64,
                    false,
                    Some(&mut &msg[..]),
                );
                continue;
            };
            let (mounts, stop) = (self.mounts.clone(), self.stop.clone());
            let quiet = self.opts.quiet;
            // A failed spawn drops the closure, its stream and ticket: the client sees a close.
            let _ = std::thread::Builder::new()
                .name("serve-conn".into())
                .spawn(move || connection::serve(stream, &ticket, &mounts, quiet, &stop));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn accept_encoding_honours_q_and_star() {
        assert!(accepts_encoding(Some("gzip, deflate, br"), "br"));
        assert!(accepts_encoding(Some("GZIP"), "gzip"));
        assert!(accepts_encoding(Some("x-gzip"), "gzip"));
        assert!(accepts_encoding(Some("br;q=0.5"), "br"));
        assert!(!accepts_encoding(Some("br;q=0"), "br"));
        assert!(!accepts_encoding(Some("br; q=0.000"), "br"));
        assert!(accepts_encoding(Some("*"), "gzip"));
        assert!(!accepts_encoding(Some("*, gzip;q=0"), "gzip"));
        assert!(!accepts_encoding(Some("*;q=0"), "br"));
        assert!(!accepts_encoding(Some("identity"), "gzip"));
        assert!(!accepts_encoding(Some("gzip;q=nonsense"), "gzip"));
        assert!(!accepts_encoding(None, "gzip"));
    }

    #[test]
    fn content_types_by_extension() {
        let t = |p: &str| content_type(Path::new(p));
        assert_eq!(t("a/tileset.json"), "application/json");
        assert_eq!(t("x.GLB"), "model/gltf-binary");
        assert_eq!(t("0.subtree"), "application/octet-stream");
        assert_eq!(t("pkg/v_bg.wasm"), "application/wasm");
        assert!(t("index.html").starts_with("text/html"));
        assert!(t("v.js").starts_with("text/javascript"));
        assert!(t("s.css").starts_with("text/css"));
        assert_eq!(t("i.png"), "image/png");
        assert_eq!(t("noext"), "application/octet-stream");
    }

    #[test]
    fn if_none_match_lists_and_weak_tags() {
        assert!(none_match_hits("\"a\"", "\"a\""));
        assert!(none_match_hits("\"x\", W/\"a\"", "\"a\""));
        assert!(none_match_hits(" * ", "\"a\""));
        assert!(!none_match_hits("\"b\"", "\"a\""));
        assert!(!none_match_hits("", "\"a\""));
    }

    #[test]
    fn answers_without_a_socket() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("t.json"), b"{}").unwrap();
        let mounts = [Mount::new("/", dir.path()).unwrap()];
        let req = |method, target: &str, headers: &[(&str, &str)]| Request {
            method,
            target: target.into(),
            headers: headers
                .iter()
                .map(|(k, v)| (k.to_string(), v.to_string()))
                .collect(),
        };
        let r = answer(&mounts, &req(Method::Get, "/t.json", &[]));
        assert_eq!((r.status, r.length), (200, 2));
        assert_eq!(r.header("Access-Control-Allow-Origin"), Some("*"));
        let r = answer(
            &mounts,
            &req(Method::Head, "/t.json", &[("range", "bytes=1-")]),
        );
        assert_eq!((r.status, r.length), (206, 1));
        assert_eq!(r.header("content-range"), Some("bytes 1-1/2"));
        assert_eq!(
            answer(&mounts, &req(Method::Other, "/t.json", &[])).status,
            405
        );
        assert_eq!(
            answer(&mounts, &req(Method::Get, "/%2e%2e/x", &[])).status,
            403
        );
        assert_eq!(
            answer(&mounts, &req(Method::Get, "t.json", &[])).status,
            400
        );
        assert!(Mount::new("/", &dir.path().join("missing")).is_err());
    }
}
