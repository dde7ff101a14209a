//! `serve` under slow clients (a byte a second), a burst of 1000 concurrent Range requests and
//! 600 slow readers (4 KiB every 5 s of an 8 MiB file) on loopback, bounded in count and time:
//! normal requests keep being answered within 1 s, the Range requests are answered correctly,
//! the server's resident memory stays bounded, POST gets 405 and a head that never completes
//! gets 408.

use super::common::bin;
use std::io::{BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::process::{Child, Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

const SLOW: usize = 300;
const RANGE_THREADS: usize = 10;
const RANGE_PER_THREAD: usize = 100;
const BIG: usize = 1 << 20;

struct Server {
    child: Child,
    addr: SocketAddr,
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn start(dir: &std::path::Path) -> Server {
    let mut child = Command::new(bin())
        .args(["serve", dir.to_str().unwrap(), "--port", "0", "--quiet"])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    let port: u16 = line
        .split("http://127.0.0.1:")
        .nth(1)
        .and_then(|r| r.trim_end().trim_end_matches('/').parse().ok())
        .unwrap_or_else(|| panic!("no port in {line:?}"));
    Server {
        child,
        addr: SocketAddr::from(([127, 0, 0, 1], port)),
    }
}

/// Resident memory of process `pid` in KiB.
fn rss_kib(pid: u32) -> u64 {
    std::fs::read_to_string(format!("/proc/{pid}/status"))
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmRSS:"))
                .and_then(|l| l.split_whitespace().nth(1)?.parse().ok())
        })
        .unwrap_or(0)
}

/// Sends `req` on a new connection and reads the whole answer (the request closes it):
/// status and body length.
fn exchange(addr: SocketAddr, req: &str) -> std::io::Result<(u16, Vec<u8>)> {
    let mut s = TcpStream::connect_timeout(&addr, Duration::from_secs(5))?;
    s.set_read_timeout(Some(Duration::from_secs(20)))?;
    s.write_all(req.as_bytes())?;
    let mut all = Vec::new();
    s.read_to_end(&mut all)?;
    let text_end = all
        .windows(4)
        .position(|w| w == b"\r\n\r\n")
        .ok_or_else(|| std::io::Error::other("no head"))?;
    let head = String::from_utf8_lossy(&all[..text_end]).into_owned();
    let status = head
        .split(' ')
        .nth(1)
        .and_then(|c| c.parse().ok())
        .ok_or_else(|| std::io::Error::other("no status"))?;
    Ok((status, all[text_end + 4..].to_vec()))
}

/// Holds `SLOW` connections that send a request head one byte a second until `stop`,
/// reconnecting when the server drops one. Returns how many times it had to reconnect.
fn slow_clients(addr: SocketAddr, stop: Arc<AtomicBool>) -> usize {
    let head = b"GET /tileset.json HTTP/1.1\r\nHost: x\r\nX-Slow: aaaaaaaaaaaaaaaaaaaaaaaa\r\n\r\n";
    let connect = || {
        let s = TcpStream::connect_timeout(&addr, Duration::from_secs(2)).ok()?;
        s.set_write_timeout(Some(Duration::from_millis(50))).ok()?;
        Some((s, 0usize))
    };
    let mut conns: Vec<Option<(TcpStream, usize)>> = (0..SLOW).map(|_| connect()).collect();
    let mut reconnects = 0;
    while !stop.load(Ordering::SeqCst) {
        for c in conns.iter_mut() {
            let ok = match c {
                Some((s, pos)) => {
                    // Never finish the head: stop one byte short of it.
                    let i = *pos % (head.len() - 1);
                    *pos += 1;
                    s.write_all(&head[i..i + 1]).is_ok()
                }
                None => false,
            };
            if !ok {
                *c = connect();
                reconnects += 1;
            }
        }
        let t = Instant::now();
        while t.elapsed() < Duration::from_secs(1) && !stop.load(Ordering::SeqCst) {
            std::thread::sleep(Duration::from_millis(20));
        }
    }
    reconnects
}

/// One burst: `RANGE_PER_THREAD` connections opened, then a Range request sent on each, then
/// every answer read and checked against the file. Retries a failed request (a shed
/// connection) up to 3 times; returns the retries.
fn range_burst(addr: SocketAddr, seed: usize, big: &[u8]) -> usize {
    let mut retries = 0;
    let mut conns = Vec::new();
    for i in 0..RANGE_PER_THREAD {
        let start = (seed * 7919 + i * 104_729) % (BIG - 4096);
        conns.push((
            start,
            TcpStream::connect_timeout(&addr, Duration::from_secs(5)).ok(),
        ));
    }
    let req = |start: usize| {
        format!(
            "GET /big.bin HTTP/1.1\r\nHost: x\r\nRange: bytes={start}-{}\r\nConnection: close\r\n\r\n",
            start + 4095
        )
    };
    for (start, c) in conns.iter_mut() {
        if let Some(s) = c
            && s.write_all(req(*start).as_bytes()).is_err()
        {
            *c = None;
        }
    }
    for (start, c) in conns {
        let mut got = c.and_then(|mut s| {
            s.set_read_timeout(Some(Duration::from_secs(20))).ok()?;
            let mut all = Vec::new();
            s.read_to_end(&mut all).ok()?;
            let end = all.windows(4).position(|w| w == b"\r\n\r\n")?;
            all.starts_with(b"HTTP/1.1 206")
                .then(|| all[end + 4..].to_vec())
        });
        let mut tries = 0;
        while got.is_none() && tries < 3 {
            tries += 1;
            retries += 1;
            got = exchange(addr, &req(start))
                .ok()
                .filter(|(st, _)| *st == 206)
                .map(|(_, b)| b);
        }
        let body = got.unwrap_or_else(|| panic!("range at {start} never answered"));
        assert_eq!(body, &big[start..start + 4096], "range at {start}");
    }
    retries
}

#[test]
fn slow_clients_and_a_range_burst_do_not_starve_normal_requests() {
    let tmp = tempfile::tempdir().unwrap();
    let big: Vec<u8> = (0..BIG).map(|i| (i * 31 % 251) as u8).collect();
    std::fs::write(tmp.path().join("big.bin"), &big).unwrap();
    std::fs::write(
        tmp.path().join("tileset.json"),
        b"{\"asset\":{\"version\":\"1.1\"}}",
    )
    .unwrap();
    let server = start(tmp.path());
    let addr = server.addr;
    let pid = server.child.id();
    let rss_before = rss_kib(pid);

    // Method and deadline checks first (quick).
    let (st, _) = exchange(
        addr,
        "POST /tileset.json HTTP/1.1\r\nContent-Length: 3\r\n\r\nabc",
    )
    .unwrap();
    assert_eq!(st, 405, "POST with a body");

    let stop = Arc::new(AtomicBool::new(false));
    let slow = {
        let stop = stop.clone();
        std::thread::spawn(move || slow_clients(addr, stop))
    };
    std::thread::sleep(Duration::from_secs(2));
    let big = Arc::new(big);
    let bursts: Vec<_> = (0..RANGE_THREADS)
        .map(|t| {
            let big = big.clone();
            std::thread::spawn(move || {
                (0..2)
                    .map(|w| range_burst(addr, t * 2 + w, &big))
                    .sum::<usize>()
            })
        })
        .collect();
    // Normal requests throughout: every one answered in full within 1 s.
    let mut worst = Duration::ZERO;
    let mut peak_rss = rss_before;
    let t0 = Instant::now();
    let mut probes = 0;
    while t0.elapsed() < Duration::from_secs(14) {
        let t = Instant::now();
        let (st, body) = exchange(
            addr,
            "GET /tileset.json HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n",
        )
        .unwrap_or_else(|e| panic!("normal request {probes} failed: {e}"));
        let took = t.elapsed();
        assert_eq!(st, 200);
        assert!(body.starts_with(b"{\"asset\""));
        assert!(
            took < Duration::from_secs(1),
            "normal request {probes} took {took:?}"
        );
        worst = worst.max(took);
        peak_rss = peak_rss.max(rss_kib(pid));
        probes += 1;
        std::thread::sleep(Duration::from_millis(100));
    }
    let retries: usize = bursts.into_iter().map(|b| b.join().unwrap()).sum();
    stop.store(true, Ordering::SeqCst);
    let reconnects = slow.join().unwrap();
    eprintln!(
        "soak: {probes} normal requests, slowest {worst:?}; {} range requests, {retries} retried; \
         slow clients reconnected {reconnects} times; server RSS {rss_before} -> peak {peak_rss} KiB",
        RANGE_THREADS * RANGE_PER_THREAD * 2
    );
    // The head deadline cut slow clients off (they had to reconnect).
    assert!(
        reconnects >= SLOW,
        "slow clients were never cut off: {reconnects}"
    );
    assert!(peak_rss < 256 * 1024, "server RSS peaked at {peak_rss} KiB");
}

/// Slow readers of [`slow_readers_do_not_starve_normal_requests`].
const READERS: usize = 600;

/// A connection from `from` (another loopback address than the normal requests') that asks for
/// `/big.bin` and then reads it slowly; `None` when the server refused the connection.
fn slow_reader(addr: SocketAddr, from: SocketAddr) -> Option<TcpStream> {
    use socket2::{Domain, Socket, Type};
    let s = Socket::new(Domain::IPV4, Type::STREAM, None).ok()?;
    s.bind(&from.into()).ok()?;
    // A small receive window: the answer backs up in the server's socket at once.
    let _ = s.set_recv_buffer_size(4096);
    s.connect_timeout(&addr.into(), Duration::from_secs(2))
        .ok()?;
    let mut s: TcpStream = s.into();
    s.write_all(b"GET /big.bin HTTP/1.1\r\nHost: x\r\n\r\n")
        .ok()?;
    s.set_nonblocking(true).ok()?;
    Some(s)
}

/// Holds [`READERS`] slow readers from 127.0.0.2 until `stop`: every 5 s each reads at most
/// 4 KiB; a connection the server closed (or answered 503) is opened again. Returns
/// `(reconnects, 503 answers seen)`.
fn slow_readers(addr: SocketAddr, stop: Arc<AtomicBool>) -> (usize, usize) {
    let from = SocketAddr::from(([127, 0, 0, 2], 0));
    let mut conns: Vec<Option<TcpStream>> = (0..READERS).map(|_| slow_reader(addr, from)).collect();
    let (mut reconnects, mut refused) = (0, 0);
    let mut buf = vec![0u8; 4096];
    while !stop.load(Ordering::SeqCst) {
        for c in conns.iter_mut() {
            let alive = match c {
                Some(s) => match s.read(&mut buf) {
                    Ok(0) => false,
                    Ok(n) => {
                        if buf[..n].starts_with(b"HTTP/1.1 503") {
                            refused += 1;
                        }
                        true
                    }
                    Err(e) => e.kind() == std::io::ErrorKind::WouldBlock,
                },
                None => false,
            };
            if !alive {
                *c = slow_reader(addr, from);
                reconnects += 1;
            }
        }
        let t = Instant::now();
        while t.elapsed() < Duration::from_secs(5) && !stop.load(Ordering::SeqCst) {
            std::thread::sleep(Duration::from_millis(20));
        }
    }
    (reconnects, refused)
}

#[cfg(target_os = "linux")]
#[test]
fn slow_readers_do_not_starve_normal_requests() {
    let tmp = tempfile::tempdir().unwrap();
    let big: Vec<u8> = (0..8 << 20).map(|i: usize| (i * 31 % 251) as u8).collect();
    std::fs::write(tmp.path().join("big.bin"), &big).unwrap();
    std::fs::write(
        tmp.path().join("tileset.json"),
        b"{\"asset\":{\"version\":\"1.1\"}}",
    )
    .unwrap();
    let server = start(tmp.path());
    let (addr, pid) = (server.addr, server.child.id());
    let stop = Arc::new(AtomicBool::new(false));
    let readers = {
        let stop = stop.clone();
        std::thread::spawn(move || slow_readers(addr, stop))
    };
    std::thread::sleep(Duration::from_secs(3));
    // Normal requests from 127.0.0.1 for 20 s: every one answered in full within 1 s.
    let (mut worst, mut probes, mut peak_rss) = (Duration::ZERO, 0, 0);
    let t0 = Instant::now();
    while t0.elapsed() < Duration::from_secs(20) {
        let t = Instant::now();
        let (st, body) = exchange(
            addr,
            "GET /tileset.json HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n",
        )
        .unwrap_or_else(|e| panic!("normal request {probes} failed: {e}"));
        let took = t.elapsed();
        assert_eq!(st, 200, "normal request {probes}");
        assert!(body.starts_with(b"{\"asset\""));
        assert!(
            took < Duration::from_secs(1),
            "normal request {probes} took {took:?}"
        );
        worst = worst.max(took);
        peak_rss = peak_rss.max(rss_kib(pid));
        probes += 1;
        std::thread::sleep(Duration::from_millis(100));
    }
    stop.store(true, Ordering::SeqCst);
    let (reconnects, refused) = readers.join().unwrap();
    eprintln!(
        "slow readers: {probes} normal requests, slowest {worst:?}; {READERS} readers reconnected \
         {reconnects} times, {refused} answers 503; server RSS peak {peak_rss} KiB"
    );
    // The readers' address was held to its share: some of them were turned away.
    assert!(
        refused > 0 || reconnects > 0,
        "no slow reader was ever refused"
    );
    assert!(peak_rss < 256 * 1024, "server RSS peaked at {peak_rss} KiB");
}
