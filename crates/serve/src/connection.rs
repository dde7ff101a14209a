//! One `serve` connection: request heads read under deadlines (an idle wait for the first byte,
//! then a deadline for the whole head), answers written, keep-alive until the client stops.
//!
//! A client sending its head a byte at a time is cut off at [`HEAD_S`] seconds with 408; while
//! waiting, the connection may be evicted by the accept loop ([`super::admission`]). An answer
//! must leave at [`MIN_RATE`] bytes a second on average after [`GRACE_S`] seconds, or the
//! connection is closed: a client that reads a byte now and then cannot hold it for long.

use super::admission::{Start, Ticket};
use super::{Body, Method, Mount, Request, answer, http};
use std::io::{BufRead, Read, Seek, SeekFrom, Write};
use std::net::TcpStream;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// Seconds an idle keep-alive connection waits for the next request.
pub const IDLE_S: u64 = 30;
/// Seconds a whole request head may take once its first byte arrived.
pub const HEAD_S: u64 = 10;

/// Seconds an answer may take before [`MIN_RATE`] applies.
pub const GRACE_S: u64 = 10;
/// Least average rate (bytes a second) at which the socket must take an answer after the grace.
pub const MIN_RATE: u64 = 4096;

/// Writes to the socket no slower, on average over one answer, than [`MIN_RATE`] after
/// [`GRACE_S`]: each write may wait only until the answer is due at that rate.
struct Paced<'a> {
    stream: &'a TcpStream,
    start: Instant,
    sent: u64,
}

impl Paced<'_> {
    /// Starts the clock of a new answer.
    fn begin(&mut self) {
        self.start = Instant::now();
        self.sent = 0;
    }
}

impl Write for Paced<'_> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let due = self.start
            + Duration::from_secs(GRACE_S)
            + Duration::from_secs_f64(self.sent as f64 / MIN_RATE as f64);
        let left = due.saturating_duration_since(Instant::now());
        if left.is_zero() {
            return Err(std::io::Error::new(
                std::io::ErrorKind::TimedOut,
                format!("the client took under {MIN_RATE} bytes/s"),
            ));
        }
        self.stream
            .set_write_timeout(Some(left.max(Duration::from_millis(1))))?;
        let n = (&mut &*self.stream).write(buf)?;
        self.sent += n as u64;
        Ok(n)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        (&mut &*self.stream).flush()
    }
}

/// Reads from the socket with every read bounded by a deadline.
struct Deadlined<'a> {
    stream: &'a TcpStream,
    deadline: Instant,
}

impl Read for Deadlined<'_> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let left = self.deadline.saturating_duration_since(Instant::now());
        if left.is_zero() {
            return Err(std::io::ErrorKind::TimedOut.into());
        }
        self.stream
            .set_read_timeout(Some(left.max(Duration::from_millis(1))))?;
        self.stream.read(buf)
    }
}

/// Control characters replaced, so a hostile target cannot drive the terminal.
fn printable(s: &str) -> String {
    s.chars()
        .map(|c| if c.is_control() { '?' } else { c })
        .collect()
}

/// Writes a short plain-text error reply and reports it in the log.
fn refuse(
    w: &mut impl std::io::Write,
    status: u16,
    extra: &[(&'static str, String)],
    msg: &str,
    quiet: bool,
) {
    let body = format!("{msg}\n");
    let mut headers = vec![("Content-Type", "text/plain; charset=utf-8".to_string())];
    headers.extend_from_slice(extra);
    let _ = http::write_response(
        w,
        status,
        &headers,
        body.len() as u64,
        false,
        Some(&mut body.as_bytes()),
    );
    if !quiet {
        log::info!(target: crate::ACCESS_LOG, "- - {status} 0 ({msg})");
    }
}

/// Serves one connection: requests one after another while the client keeps it alive.
pub fn serve(stream: TcpStream, ticket: &Ticket, mounts: &[Mount], quiet: bool, stop: &AtomicBool) {
    let _ = stream.set_nodelay(true);
    let mut reader = std::io::BufReader::new(Deadlined {
        stream: &stream,
        deadline: Instant::now() + Duration::from_secs(IDLE_S),
    });
    let mut writer = std::io::BufWriter::with_capacity(
        64 * 1024,
        Paced {
            stream: &stream,
            start: Instant::now(),
            sent: 0,
        },
    );
    while !stop.load(Ordering::SeqCst) {
        ticket.waiting();
        // Idle until the first byte of the next request; then the whole head has HEAD_S.
        reader.get_mut().deadline = Instant::now() + Duration::from_secs(IDLE_S);
        match reader.fill_buf() {
            Ok([]) | Err(_) => return,
            Ok(_) => {}
        }
        reader.get_mut().deadline = Instant::now() + Duration::from_secs(HEAD_S);
        let head = match http::read_head(&mut reader) {
            Ok(h) => h,
            Err(http::HeadError::Closed) => return,
            Err(e) => {
                let (status, msg) = match e {
                    http::HeadError::TooLarge => (431, "request head too large"),
                    http::HeadError::Version => (505, "only HTTP/1.0 and HTTP/1.1"),
                    http::HeadError::Timeout => (408, "request head not complete in time"),
                    http::HeadError::Bad(m) => (400, m),
                    http::HeadError::Closed => return,
                };
                refuse(&mut writer, status, &[], msg, quiet);
                return;
            }
        };
        writer.get_mut().begin();
        match ticket.busy() {
            Start::Granted => {}
            // Evicted while the head arrived: the socket is shut down already.
            Start::Evicted => return,
            Start::OverShare => {
                refuse(
                    &mut writer,
                    503,
                    &[("Retry-After", "1".into())],
                    "too many answers to this address at once",
                    quiet,
                );
                return;
            }
        }
        let method = match head.method.as_str() {
            "GET" => Method::Get,
            "HEAD" => Method::Head,
            "OPTIONS" => Method::Options,
            _ => Method::Other,
        };
        if method == Method::Other {
            // Any other method (POST, PUT, ...): 405 whether or not it carries a body, which
            // is never read, so the connection closes after the answer.
            refuse(
                &mut writer,
                405,
                &[("Allow", super::ALLOW.into())],
                &format!("method {} not allowed", printable(&head.method)),
                quiet,
            );
            return;
        }
        if head.has_body() {
            // Nothing served takes a body, and skipping one safely is not worth the risk.
            refuse(
                &mut writer,
                413,
                &[],
                "request bodies are not accepted",
                quiet,
            );
            return;
        }
        let keep = head.keep_alive();
        let req = Request {
            method,
            target: head.target.clone(),
            headers: head.headers.clone(),
        };
        let reply = answer(mounts, &req);
        let status = reply.status;
        let mut headers = reply.headers;
        headers.push((
            "Server",
            concat!("splat2tiles/", env!("CARGO_PKG_VERSION")).into(),
        ));
        let empty = matches!(reply.body, Body::Empty);
        let mut reader_body: Box<dyn Read> = match reply.body {
            Body::Empty => Box::new(std::io::empty()),
            Body::Text(s) => Box::new(std::io::Cursor::new(s.into_bytes())),
            Body::File {
                mut file,
                start,
                len,
            } => match file.seek(SeekFrom::Start(start)) {
                Ok(_) => Box::new(file.take(len)),
                Err(_) => Box::new(std::io::empty()),
            },
        };
        // HEAD, 304 and the like announce a length but send no body.
        let no_body = empty || method == Method::Head || matches!(status, 204 | 304);
        let result = http::write_response(
            &mut writer,
            status,
            &headers,
            reply.length,
            keep,
            if no_body {
                None
            } else {
                Some(&mut *reader_body)
            },
        );
        if !quiet {
            let (sent, note) = match &result {
                Ok(n) => (*n, String::new()),
                Err(e) => (0, format!(" ({e})")),
            };
            log::info!(
                target: crate::ACCESS_LOG,
                "{} {} {status} {sent}{note}",
                printable(&head.method),
                printable(&head.target)
            );
        }
        if result.is_err() || !keep {
            return;
        }
    }
}
