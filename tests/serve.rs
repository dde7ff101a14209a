//! `splat2tiles serve` and `view` end to end: the real binary on `--port 0`, a minimal HTTP/1.1
//! client on std's TcpStream; Best tiles paused and resumed with Range + If-Range reassemble
//! byte-identical, plus content types, 206/416/304, HEAD, traversal refusals, CORS, precompression.

mod common;

use common::{bin, scene};
use splat2tiles_core::splat::Splats;
use splat2tiles_tiles::encode::prefix::PrefixStream;
use splat2tiles_tiles::encode::{decode_prefix, read_tile_glb};
use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::Duration;

/// A running `splat2tiles serve|view` child, killed on drop.
struct Served {
    child: Child,
    port: u16,
    /// Every stdout line up to and including the one with the URL.
    lines: Vec<String>,
}

impl Drop for Served {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Starts the binary with `args` (which must include `--port 0`) and reads the port it prints.
fn start(args: &[&str], log: &Path) -> Served {
    start_with(&bin(), args, log)
}

/// [`start`] with the executable at `program` (a copy of the binary, as if installed there).
fn start_with(program: &Path, args: &[&str], log: &Path) -> Served {
    let mut child = Command::new(program)
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(std::fs::File::create(log).unwrap())
        .spawn()
        .expect("start splat2tiles");
    let mut out = BufReader::new(child.stdout.take().unwrap());
    let mut lines = Vec::new();
    let port = loop {
        let mut line = String::new();
        if out.read_line(&mut line).unwrap() == 0 {
            let _ = child.kill();
            panic!(
                "splat2tiles {args:?} exited before printing its URL; stderr:\n{}",
                std::fs::read_to_string(log).unwrap_or_default()
            );
        }
        let line = line.trim_end().to_string();
        lines.push(line.clone());
        if let Some(rest) = line.split("http://127.0.0.1:").nth(1) {
            let digits: String = rest.chars().take_while(char::is_ascii_digit).collect();
            break digits.parse::<u16>().expect("port in the printed URL");
        }
    };
    if args.first() == Some(&"view") {
        let mut line = String::new();
        out.read_line(&mut line).unwrap();
        lines.push(line.trim_end().to_string());
    }
    assert_ne!(port, 0);
    Served { child, port, lines }
}

fn serve(dir: &Path, log: &Path) -> Served {
    start(
        &["serve", dir.to_str().unwrap(), "--port", "0", "--quiet"],
        log,
    )
}

/// One parsed response.
#[derive(Debug)]
struct Resp {
    status: u16,
    headers: Vec<(String, String)>,
    body: Vec<u8>,
}

impl Resp {
    fn header(&self, name: &str) -> Option<&str> {
        self.headers
            .iter()
            .find(|(k, _)| k.eq_ignore_ascii_case(name))
            .map(|(_, v)| v.as_str())
    }
}

fn connect(port: u16) -> TcpStream {
    let s = TcpStream::connect(("127.0.0.1", port)).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(20))).unwrap();
    s
}

/// Sends a raw request head (target sent as is) and reads the head of the answer, returning the
/// stream positioned at the body.
fn send(
    port: u16,
    method: &str,
    target: &str,
    headers: &[(&str, &str)],
) -> (Resp, BufReader<TcpStream>) {
    let mut s = connect(port);
    let mut req = format!("{method} {target} HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n");
    for (k, v) in headers {
        req.push_str(&format!("{k}: {v}\r\n"));
    }
    req.push_str("\r\n");
    s.write_all(req.as_bytes()).unwrap();
    let mut r = BufReader::new(s);
    let resp = read_answer_head(&mut r, target);
    (resp, r)
}

/// Reads the status line and header fields of an answer (the body is left in `r`).
fn read_answer_head(r: &mut BufReader<TcpStream>, target: &str) -> Resp {
    let mut status_line = String::new();
    r.read_line(&mut status_line).unwrap();
    let status: u16 = status_line
        .split_whitespace()
        .nth(1)
        .and_then(|c| c.parse().ok())
        .unwrap_or_else(|| panic!("bad status line {status_line:?} for {target}"));
    let mut hs = Vec::new();
    loop {
        let mut line = String::new();
        r.read_line(&mut line).unwrap();
        let line = line.trim_end();
        if line.is_empty() {
            break;
        }
        let (k, v) = line.split_once(':').expect("header line");
        hs.push((k.trim().to_string(), v.trim().to_string()));
    }
    Resp {
        status,
        headers: hs,
        body: Vec::new(),
    }
}

/// A whole request: head and body (read to the close); checks Content-Length against the body.
fn get_with(port: u16, method: &str, target: &str, headers: &[(&str, &str)]) -> Resp {
    let (mut resp, mut r) = send(port, method, target, headers);
    r.read_to_end(&mut resp.body).unwrap();
    assert!(
        resp.header("Transfer-Encoding").is_none(),
        "{target}: chunked answer"
    );
    if method == "GET" && resp.status != 304 {
        let cl: usize = resp.header("Content-Length").unwrap().parse().unwrap();
        assert_eq!(cl, resp.body.len(), "{target}: Content-Length vs body");
    }
    resp
}

fn get(port: u16, target: &str) -> Resp {
    get_with(port, "GET", target, &[])
}

/// Starts a GET and "pauses" after `n` body bytes: the connection is dropped mid-body.
fn get_paused(port: u16, target: &str, n: usize) -> (Resp, Vec<u8>) {
    let (resp, mut r) = send(port, "GET", target, &[]);
    let mut part = vec![0u8; n];
    r.read_exact(&mut part).unwrap();
    drop(r);
    (resp, part)
}

/// Converts the shared plant scene into `tmp/ts` with the real binary.
fn convert_plant(tmp: &Path) -> PathBuf {
    let out = tmp.join("ts");
    let st = Command::new(bin())
        .args(["convert", scene("plant.splat").to_str().unwrap(), "-o"])
        .arg(&out)
        .arg("--quiet")
        .status()
        .unwrap();
    assert!(st.success(), "convert plant.splat");
    out
}

fn files_under(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            files_under(&p, out);
        } else {
            out.push(p);
        }
    }
}

fn url_of(root: &Path, file: &Path) -> String {
    let rel = file.strip_prefix(root).unwrap();
    let parts: Vec<_> = rel.iter().map(|c| c.to_str().unwrap()).collect();
    format!("/{}", parts.join("/"))
}

fn assert_same_splats(a: &Splats, b: &Splats, k: usize) {
    if k > 0 {
        assert_eq!(a.sh_degree, b.sh_degree);
    }
    for i in 0..k {
        assert_eq!(a.get(i), b.get(i), "splat {i}");
        assert_eq!(a.rest_of(i), b.rest_of(i), "SH of splat {i}");
    }
}

#[test]
fn best_tiles_paused_and_resumed_with_range_are_byte_identical() {
    let tmp = tempfile::tempdir().unwrap();
    let ts = convert_plant(tmp.path());
    let server = serve(&ts, &tmp.path().join("log"));
    let mut tiles = Vec::new();
    files_under(&ts.join("tiles/best"), &mut tiles);
    tiles.retain(|p| p.extension().is_some_and(|e| e == "glb"));
    tiles.sort();
    assert!(tiles.len() >= 5, "only {} Best tiles", tiles.len());
    for tile in &tiles {
        let target = url_of(&ts, tile);
        let file = std::fs::read(tile).unwrap();
        let len = file.len();
        let full = get(server.port, &target);
        assert_eq!(full.status, 200, "{target}");
        assert_eq!(full.header("Content-Type"), Some("model/gltf-binary"));
        assert_eq!(full.body, file, "{target}: full GET");
        let etag = full.header("ETag").unwrap().to_string();
        assert!(
            etag.starts_with('"') && etag.ends_with('"'),
            "strong ETag {etag}"
        );
        let full_splats = read_tile_glb(&file).unwrap().splats;
        // Pause inside the header, inside the records, and one byte before the end.
        for n in [1, 100, len / 3, len / 2 + 7, len - 1] {
            let (head, first) = get_paused(server.port, &target, n);
            assert_eq!(head.status, 200);
            let resumed = get_with(
                server.port,
                "GET",
                &target,
                &[("Range", &format!("bytes={n}-")), ("If-Range", &etag)],
            );
            assert_eq!(resumed.status, 206, "{target} resumed at {n}");
            assert_eq!(
                resumed.header("Content-Range"),
                Some(format!("bytes {n}-{}/{len}", len - 1).as_str())
            );
            assert_eq!(resumed.header("ETag"), Some(etag.as_str()));
            let mut whole = first.clone();
            whole.extend_from_slice(&resumed.body);
            assert_eq!(whole, file, "{target}: paused at {n} and resumed");
            assert_eq!(whole, full.body);

            // What a viewer decodes before and after the pause.
            let (prefix, _) = decode_prefix(&first).unwrap();
            assert!(prefix.len() <= full_splats.len());
            assert_same_splats(&prefix, &full_splats, prefix.len());
            let mut stream = PrefixStream::new();
            let a = stream.push(&first).unwrap();
            let b = stream.push(&resumed.body).unwrap();
            assert_eq!(a.len(), prefix.len(), "{target}: stream before the pause");
            assert_eq!(a.len() + b.len(), full_splats.len());
            assert!(stream.is_complete());
            let mut joined = a;
            if joined.is_empty() {
                joined = Splats::new(b.sh_degree);
            }
            for i in 0..b.len() {
                joined.push_from(&b, i);
            }
            assert_same_splats(&joined, &full_splats, full_splats.len());
        }
        let reassembled = read_tile_glb(&full.body).unwrap().splats;
        assert_eq!(reassembled.len(), full_splats.len());
        // A stale validator: the range is not applied, the whole current file comes back.
        let stale = get_with(
            server.port,
            "GET",
            &target,
            &[("Range", "bytes=10-"), ("If-Range", "\"stale\"")],
        );
        assert_eq!((stale.status, stale.body.len()), (200, len));
    }
}

/// A small served folder: every content type, an index-less directory, a gz sibling.
fn sample_dir(root: &Path) {
    let w = |p: &str, b: &[u8]| {
        let p = root.join(p);
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        std::fs::write(p, b).unwrap();
    };
    w("tileset.json", b"{\"asset\":{\"version\":\"1.1\"}}");
    w("tiles/a.glb", b"glTF0123456789");
    w("subtrees/0.subtree", b"subt\x01\x02");
    w("index.html", b"<!doctype html><title>x</title>");
    w("app.js", b"console.log(1)");
    w("app.wasm", b"\0asm\x01\0\0\0");
    w("img.png", b"\x89PNG\r\n\x1a\n");
    w("style.css", b"body{}");
    w("data.bin", &(0..=255u8).collect::<Vec<u8>>());
    w("empty/.keep", b"");
}

#[test]
fn content_types_head_and_directories() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path().join("root");
    sample_dir(&root);
    let s = serve(&root, &tmp.path().join("log"));
    for (path, ty) in [
        ("/tileset.json", "application/json"),
        ("/tiles/a.glb", "model/gltf-binary"),
        ("/subtrees/0.subtree", "application/octet-stream"),
        ("/index.html", "text/html"),
        ("/app.js", "text/javascript"),
        ("/app.wasm", "application/wasm"),
        ("/img.png", "image/png"),
        ("/style.css", "text/css"),
    ] {
        let r = get(s.port, path);
        assert_eq!(r.status, 200, "{path}");
        let got = r.header("Content-Type").unwrap();
        assert!(got.starts_with(ty), "{path}: {got}");
        assert_eq!(r.header("Accept-Ranges"), Some("bytes"));
        assert!(r.header("Cache-Control").is_some(), "{path}: Cache-Control");
        let head = get_with(s.port, "HEAD", path, &[]);
        assert_eq!(head.status, 200);
        assert!(head.body.is_empty(), "{path}: HEAD has a body");
        assert_eq!(head.header("Content-Length"), r.header("Content-Length"));
        assert_eq!(head.header("ETag"), r.header("ETag"));
    }
    // A directory serves its index.html, never a listing.
    let index = get(s.port, "/");
    assert_eq!(index.status, 200);
    assert!(index.body.starts_with(b"<!doctype html>"));
    assert_eq!(get(s.port, "/empty/").status, 404);
    assert_eq!(get(s.port, "/tiles/").status, 404);
    assert_eq!(get(s.port, "/missing.json").status, 404);
    let redirect = get(s.port, "/tiles");
    assert_eq!(redirect.status, 301);
    assert_eq!(redirect.header("Location"), Some("/tiles/"));
    assert_eq!(get_with(s.port, "POST", "/tileset.json", &[]).status, 405);
}

#[test]
fn ranges_answer_206_416_and_conditionals_304() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path().join("root");
    sample_dir(&root);
    let s = serve(&root, &tmp.path().join("log"));
    let all: Vec<u8> = (0..=255u8).collect();
    let range = |spec: &str| get_with(s.port, "GET", "/data.bin", &[("Range", spec)]);
    let r = range("bytes=10-19");
    assert_eq!(r.status, 206);
    assert_eq!(r.header("Content-Range"), Some("bytes 10-19/256"));
    assert_eq!(r.body, &all[10..20]);
    let r = range("bytes=250-");
    assert_eq!((r.status, r.body.as_slice()), (206, &all[250..]));
    let r = range("bytes=-6");
    assert_eq!((r.status, r.body.as_slice()), (206, &all[250..]));
    let r = range("bytes=200-9999");
    assert_eq!(r.header("Content-Range"), Some("bytes 200-255/256"));
    for bad in ["bytes=256-", "bytes=1000-2000", "bytes=-0"] {
        let r = range(bad);
        assert_eq!(r.status, 416, "{bad}");
        assert_eq!(r.header("Content-Range"), Some("bytes */256"), "{bad}");
    }
    // Multiple, invalid or foreign ranges: the whole file.
    for whole in ["bytes=0-1,5-6", "bytes=5-2", "5-7", "items=0-1"] {
        let r = range(whole);
        assert_eq!((r.status, r.body.len()), (200, 256), "{whole}");
    }
    let head = get_with(s.port, "HEAD", "/data.bin", &[("Range", "bytes=0-9")]);
    assert_eq!(head.status, 206);
    assert_eq!(head.header("Content-Length"), Some("10"));
    assert!(head.body.is_empty());

    let etag = get(s.port, "/data.bin").header("ETag").unwrap().to_string();
    let nm = get_with(s.port, "GET", "/data.bin", &[("If-None-Match", &etag)]);
    assert_eq!(nm.status, 304);
    assert!(nm.body.is_empty());
    assert_eq!(nm.header("ETag"), Some(etag.as_str()));
    let list = format!("\"other\", W/{etag}");
    let nm = get_with(s.port, "GET", "/data.bin", &[("If-None-Match", &list)]);
    assert_eq!(nm.status, 304, "weak comparison for If-None-Match");
    let miss = get_with(s.port, "GET", "/data.bin", &[("If-None-Match", "\"nope\"")]);
    assert_eq!((miss.status, miss.body.len()), (200, 256));
    // If-Range needs a strong match.
    let weak = format!("W/{etag}");
    let r = get_with(
        s.port,
        "GET",
        "/data.bin",
        &[("Range", "bytes=0-0"), ("If-Range", &weak)],
    );
    assert_eq!(r.status, 200);
    // A changed file gets a new ETag.
    std::thread::sleep(Duration::from_millis(20));
    std::fs::write(root.join("data.bin"), b"changed").unwrap();
    let changed = get(s.port, "/data.bin");
    assert_ne!(changed.header("ETag"), Some(etag.as_str()));
    let r = get_with(
        s.port,
        "GET",
        "/data.bin",
        &[("Range", "bytes=3-"), ("If-Range", &etag)],
    );
    assert_eq!((r.status, r.body.as_slice()), (200, &b"changed"[..]));
}

#[test]
fn every_path_out_of_the_folder_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path().join("root");
    sample_dir(&root);
    let secret = b"TOP-SECRET-CONTENT";
    std::fs::write(tmp.path().join("Cargo.toml"), secret).unwrap();
    std::fs::write(tmp.path().join("secret"), secret).unwrap();
    #[cfg(unix)]
    {
        std::os::unix::fs::symlink(tmp.path().join("secret"), root.join("tiles/leak.glb")).unwrap();
        std::os::unix::fs::symlink(tmp.path(), root.join("up")).unwrap();
    }
    let s = serve(&root, &tmp.path().join("log"));
    let targets = [
        "/../Cargo.toml",
        "/%2e%2e/Cargo.toml",
        "/%2E%2E/%2E%2E/Cargo.toml",
        "/tiles/..%2f..%2fsecret",
        "/tiles/%2e%2e/%2e%2e/secret",
        "/tiles/..%5c..%5csecret",
        "/tiles/leak.glb",
        "/up/secret",
        "/up/Cargo.toml",
        "/secret%00.json",
        &format!("/{}", tmp.path().join("secret").display()),
        "//..//secret",
        "/./../secret",
    ];
    for t in targets {
        let r = get(s.port, t);
        assert!(
            r.status == 403 || r.status == 404,
            "{t}: status {}",
            r.status
        );
        let leaked = r.body.windows(secret.len()).any(|w| w == secret);
        assert!(!leaked, "{t}: secret leaked");
    }
    // Not origin-form, broken escapes, garbage: refused, and the server keeps going.
    for t in ["Cargo.toml", "/%zz", "/%", "http://example.com/../secret"] {
        let r = get(s.port, t);
        assert!((400..500).contains(&r.status), "{t}: {}", r.status);
    }
    let mut raw = connect(s.port);
    raw.write_all(b"\x00\x01garbage\r\n\r\n").unwrap();
    let mut sink = Vec::new();
    let _ = raw.read_to_end(&mut sink);
    assert_eq!(get(s.port, "/tileset.json").status, 200, "server died");
}

#[test]
fn cors_headers_and_preflight() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path().join("root");
    sample_dir(&root);
    let s = serve(&root, &tmp.path().join("log"));
    let r = get_with(
        s.port,
        "GET",
        "/tiles/a.glb",
        &[("Origin", "http://elsewhere.test"), ("Range", "bytes=0-3")],
    );
    assert_eq!(r.status, 206);
    assert_eq!(r.header("Access-Control-Allow-Origin"), Some("*"));
    let exposed = r.header("Access-Control-Expose-Headers").unwrap();
    for h in ["Content-Range", "Content-Length", "ETag", "Accept-Ranges"] {
        assert!(exposed.contains(h), "{h} not exposed: {exposed}");
    }
    assert_eq!(
        get(s.port, "/missing").header("Access-Control-Allow-Origin"),
        Some("*")
    );
    let pre = get_with(
        s.port,
        "OPTIONS",
        "/tiles/a.glb",
        &[
            ("Origin", "http://elsewhere.test"),
            ("Access-Control-Request-Method", "GET"),
            ("Access-Control-Request-Headers", "range, if-range"),
        ],
    );
    assert!((200..300).contains(&pre.status), "preflight {}", pre.status);
    assert!(pre.body.is_empty());
    assert_eq!(pre.header("Access-Control-Allow-Origin"), Some("*"));
    assert!(
        pre.header("Access-Control-Allow-Methods")
            .unwrap()
            .contains("GET")
    );
    let allowed = pre
        .header("Access-Control-Allow-Headers")
        .unwrap()
        .to_ascii_lowercase();
    assert!(
        allowed.contains("range") && allowed.contains("if-range"),
        "{allowed}"
    );
}

fn gzip(data: &[u8]) -> Vec<u8> {
    let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    e.write_all(data).unwrap();
    e.finish().unwrap()
}

#[test]
fn precompressed_siblings_only_when_accepted() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path().join("root");
    sample_dir(&root);
    let plain = std::fs::read(root.join("tileset.json")).unwrap();
    let gz = gzip(&plain);
    std::fs::write(root.join("tileset.json.gz"), &gz).unwrap();
    let only_gz = gzip(b"glTF only compressed");
    std::fs::write(root.join("tiles/z.glb.gz"), &only_gz).unwrap();
    let s = serve(&root, &tmp.path().join("log"));
    let ae = |v: &str| get_with(s.port, "GET", "/tileset.json", &[("Accept-Encoding", v)]);

    let r = ae("gzip, deflate, br");
    assert_eq!(r.header("Content-Encoding"), Some("gzip"));
    assert_eq!(r.header("Content-Type"), Some("application/json"));
    assert_eq!(r.header("Vary"), Some("Accept-Encoding"));
    assert_eq!(r.body, gz);
    let gz_tag = r.header("ETag").unwrap().to_string();
    for refuse in ["identity", "gzip;q=0", "br", "*;q=0", "deflate"] {
        let r = ae(refuse);
        assert_eq!(r.header("Content-Encoding"), None, "{refuse}");
        assert_eq!(r.body, plain, "{refuse}");
        assert_ne!(
            r.header("ETag"),
            Some(gz_tag.as_str()),
            "one ETag per encoding"
        );
    }
    assert_eq!(ae("*").header("Content-Encoding"), Some("gzip"));
    let r = get(s.port, "/tileset.json");
    assert_eq!((r.header("Content-Encoding"), &r.body), (None, &plain));
    assert_eq!(r.header("Vary"), Some("Accept-Encoding"));
    // Ranges on an encoded answer are ranges of the encoded bytes, under the encoded ETag.
    let r = get_with(
        s.port,
        "GET",
        "/tileset.json",
        &[
            ("Accept-Encoding", "gzip"),
            ("Range", "bytes=5-"),
            ("If-Range", &gz_tag),
        ],
    );
    assert_eq!(r.status, 206);
    assert_eq!(r.header("Content-Encoding"), Some("gzip"));
    assert_eq!(r.body, &gz[5..]);
    // Only the .gz exists: served encoded when accepted, 406 otherwise.
    let r = get_with(
        s.port,
        "GET",
        "/tiles/z.glb",
        &[("Accept-Encoding", "gzip")],
    );
    assert_eq!(
        (r.status, r.header("Content-Encoding")),
        (200, Some("gzip"))
    );
    assert_eq!(r.header("Content-Type"), Some("model/gltf-binary"));
    assert_eq!(r.body, only_gz);
    assert_eq!(get(s.port, "/tiles/z.glb").status, 406);
    // The .gz file asked for by name is a plain gzip file.
    let r = get(s.port, "/tiles/z.glb.gz");
    assert_eq!(
        (r.header("Content-Encoding"), r.header("Content-Type")),
        (None, Some("application/gzip"))
    );
}

#[test]
fn concurrent_requests_are_all_answered() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path().join("root");
    sample_dir(&root);
    let big: Vec<u8> = (0..2_000_000u32).map(|i| (i * 7 % 251) as u8).collect();
    std::fs::write(root.join("big.glb"), &big).unwrap();
    let s = serve(&root, &tmp.path().join("log"));
    let port = s.port;
    let threads: Vec<_> = (0..16)
        .map(|i| {
            std::thread::spawn(move || {
                let spec = format!("bytes={}-", i * 1000);
                get_with(port, "GET", "/big.glb", &[("Range", &spec)])
            })
        })
        .collect();
    for (i, t) in threads.into_iter().enumerate() {
        let r = t.join().unwrap();
        assert_eq!(r.status, 206);
        assert_eq!(r.body, &big[i * 1000..]);
    }
}

/// Reads one keep-alive answer (head and exactly Content-Length body bytes) from `r`.
fn read_kept(r: &mut BufReader<TcpStream>) -> (u16, Vec<u8>) {
    let resp = read_answer_head(r, "keep-alive request");
    let len: usize = resp.header("Content-Length").unwrap().parse().unwrap();
    let mut body = vec![0u8; len];
    r.read_exact(&mut body).unwrap();
    (resp.status, body)
}

#[test]
fn a_burst_of_keep_alive_connections_is_answered_on_each() {
    // What a browser does: several connections opened at once and kept open, each reused.
    // (tiny_http's connection pool left some of such a burst unanswered until another closed.)
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path().join("root");
    sample_dir(&root);
    let big: Vec<u8> = (0..300_000u32).map(|i| (i * 13 % 251) as u8).collect();
    std::fs::write(root.join("big.glb"), &big).unwrap();
    let s = serve(&root, &tmp.path().join("log"));
    let port = s.port;
    let conns: Vec<_> = (0..12).map(|_| connect(port)).collect();
    let threads: Vec<_> = conns
        .into_iter()
        .enumerate()
        .map(|(i, mut c)| {
            std::thread::spawn(move || {
                let mut r = BufReader::new(c.try_clone().unwrap());
                let mut got = vec![];
                for k in 0..3 {
                    let from = i * 100 + k * 10;
                    let req =
                        format!("GET /big.glb HTTP/1.1\r\nHost: x\r\nRange: bytes={from}-\r\n\r\n");
                    c.write_all(req.as_bytes()).unwrap();
                    got.push((from, read_kept(&mut r)));
                }
                got
            })
        })
        .collect();
    for t in threads {
        for (from, (status, body)) in t.join().unwrap() {
            assert_eq!(status, 206);
            assert_eq!(body, &big[from..]);
        }
    }
}

/// A stand-in for the built web viewer: index.html and pkg/.
fn fake_web(dir: &Path, with_pkg: bool) {
    std::fs::create_dir_all(dir).unwrap();
    std::fs::write(dir.join("index.html"), "<!doctype html><p>viewer</p>").unwrap();
    if with_pkg {
        std::fs::create_dir_all(dir.join("pkg")).unwrap();
        std::fs::write(dir.join("pkg/viewer_bg.wasm"), b"\0asm\x01\0\0\0").unwrap();
    }
}

fn view_fails(args: &[&str]) -> String {
    let out = Command::new(bin()).arg("view").args(args).output().unwrap();
    assert!(!out.status.success(), "view {args:?} succeeded");
    String::from_utf8_lossy(&out.stderr).into_owned()
}

#[test]
fn view_refuses_a_missing_or_unbuilt_web_viewer() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path().join("root");
    sample_dir(&root);
    let d = root.to_str().unwrap();
    let missing = tmp.path().join("no-web");
    let err = view_fails(&[
        d,
        "--no-open",
        "--port",
        "0",
        "--web-dir",
        missing.to_str().unwrap(),
    ]);
    assert!(err.contains("build.sh") && err.contains("no-web"), "{err}");
    let unbuilt = tmp.path().join("web");
    fake_web(&unbuilt, false);
    let err = view_fails(&[
        d,
        "--no-open",
        "--port",
        "0",
        "--web-dir",
        unbuilt.to_str().unwrap(),
    ]);
    assert!(err.contains("pkg") && err.contains("build.sh"), "{err}");
    // No tileset.json in DIR.
    let empty = tmp.path().join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    fake_web(&unbuilt, true);
    let err = view_fails(&[
        empty.to_str().unwrap(),
        "--no-open",
        "--port",
        "0",
        "--web-dir",
        unbuilt.to_str().unwrap(),
    ]);
    assert!(err.contains("tileset.json"), "{err}");
}

#[test]
fn view_serves_the_tileset_and_the_viewer() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path().join("root");
    sample_dir(&root);
    let web = tmp.path().join("web");
    fake_web(&web, true);
    let s = start(
        &[
            "view",
            root.to_str().unwrap(),
            "--no-open",
            "--quiet",
            "--port",
            "0",
            "--web-dir",
            web.to_str().unwrap(),
        ],
        &tmp.path().join("log"),
    );
    let want = format!(
        "http://127.0.0.1:{}/viewer/index.html?tileset=/tileset.json",
        s.port
    );
    assert!(s.lines.iter().any(|l| l.contains(&want)), "{:?}", s.lines);
    let page = get(s.port, "/viewer/index.html?tileset=/tileset.json");
    assert_eq!(page.status, 200);
    assert!(page.body.ends_with(b"viewer</p>"));
    assert_eq!(
        get(s.port, "/viewer/pkg/viewer_bg.wasm").header("Content-Type"),
        Some("application/wasm")
    );
    assert_eq!(get(s.port, "/viewer/").status, 200);
    assert_eq!(get(s.port, "/viewer").header("Location"), Some("/viewer/"));
    let ts = get(s.port, "/tileset.json");
    assert_eq!(ts.body, std::fs::read(root.join("tileset.json")).unwrap());
    assert_eq!(get(s.port, "/viewer/../tileset.json").status, 403);
}

#[test]
fn an_installed_view_finds_the_viewer_beside_its_executable() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path().join("root");
    sample_dir(&root);
    // `build.sh --install` beside the binary, and a PREFIX/bin + PREFIX/share layout.
    for (exe, web) in [
        ("bin/splat2tiles", "bin/splat2tiles-web"),
        ("prefix/bin/splat2tiles", "prefix/share/splat2tiles/web"),
    ] {
        let exe = tmp.path().join(exe);
        std::fs::create_dir_all(exe.parent().unwrap()).unwrap();
        std::fs::copy(bin(), &exe).unwrap();
        let web = tmp.path().join(web);
        fake_web(&web, true);
        let s = start_with(
            &exe,
            &[
                "view",
                root.to_str().unwrap(),
                "--no-open",
                "--quiet",
                "--port",
                "0",
            ],
            &tmp.path().join("log"),
        );
        let page = get(s.port, "/viewer/index.html");
        assert_eq!(page.status, 200, "{}", web.display());
        // The stand-in, not the source tree's viewer.
        assert!(page.body.ends_with(b"viewer</p>"), "{}", web.display());
        drop(s);
        std::fs::remove_dir_all(&web).unwrap();
    }
}

#[test]
fn view_of_a_folder_without_a_tileset_suggests_a_command_that_works() {
    let tmp = tempfile::tempdir().unwrap();
    // A folder of scenes (like the repository's samples/): convert one into a fresh folder.
    let samples = tmp.path().join("samples");
    std::fs::create_dir_all(&samples).unwrap();
    std::fs::copy(scene("plant.splat"), samples.join("plant.splat")).unwrap();
    std::fs::write(samples.join("README.md"), "licence").unwrap();
    let out = Command::new(bin())
        .args(["view", "samples", "--no-open", "--port", "0"])
        .current_dir(tmp.path())
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(2), "{err}");
    let suggested = err
        .split('`')
        .nth(1)
        .unwrap_or_else(|| panic!("a command in backquotes: {err}"));
    let convert = suggested.split(" && ").next().unwrap();
    let words: Vec<&str> = convert.split_whitespace().collect();
    assert_eq!(
        words[1..],
        ["convert", "samples/plant.splat", "-o", "out/plant"],
        "{err}"
    );
    let o = Command::new(words[0])
        .args(&words[1..])
        .arg("--quiet")
        .current_dir(tmp.path())
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "{suggested}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(tmp.path().join("out/plant/tileset.json").is_file());
    assert!(suggested.ends_with("view out/plant"), "{suggested}");
    // A folder of other files: never suggested as the output (convert would refuse it).
    std::fs::remove_file(samples.join("plant.splat")).unwrap();
    let out = Command::new(bin())
        .args(["view", "samples", "--no-open", "--port", "0"])
        .current_dir(tmp.path())
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(err.contains("-o out/scene"), "{err}");
}
