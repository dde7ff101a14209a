//! HTTP/1.1 framing for `serve`: request heads read with size and idle limits, keep-alive, and
//! replies written with a Content-Length (never chunked). One thread per connection.

use std::io::{BufRead, Read, Write};

/// Largest request head accepted (request line and header fields).
pub const MAX_HEAD: usize = 16 * 1024;

/// A parsed request head.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Head {
    /// Method token as sent (`GET`).
    pub method: String,
    /// Request target as sent, still percent-encoded.
    pub target: String,
    /// Minor version of HTTP/1.x.
    pub minor: u8,
    /// Header fields in order.
    pub headers: Vec<(String, String)>,
}

/// Why a request head could not be read.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum HeadError {
    /// The peer closed (or went idle past the timeout) before a request began.
    Closed,
    /// The head exceeds [`MAX_HEAD`] (431).
    TooLarge,
    /// Not HTTP/1.0 or HTTP/1.1 (505).
    Version,
    /// Malformed (400), with what was wrong.
    Bad(&'static str),
    /// The head did not arrive before the deadline (408).
    Timeout,
}

impl Head {
    /// The first value of header `name` (case-insensitive).
    pub fn header(&self, name: &str) -> Option<&str> {
        self.headers
            .iter()
            .find(|(k, _)| k.eq_ignore_ascii_case(name))
            .map(|(_, v)| v.as_str())
    }

    /// Whether the connection may carry another request after this one.
    pub fn keep_alive(&self) -> bool {
        let conn = self.header("Connection").unwrap_or("").to_ascii_lowercase();
        let has = |t: &str| conn.split(',').any(|p| p.trim() == t);
        if self.minor == 0 {
            has("keep-alive")
        } else {
            !has("close")
        }
    }

    /// Whether the request announces a body (which `serve` never reads).
    pub fn has_body(&self) -> bool {
        self.header("Transfer-Encoding").is_some()
            || self
                .header("Content-Length")
                .is_some_and(|v| v.trim() != "0")
    }
}

/// Reads one request head (blank lines before it are skipped, as RFC 9112 allows).
pub fn read_head<R: BufRead>(r: &mut R) -> Result<Head, HeadError> {
    let mut buf: Vec<u8> = Vec::new();
    loop {
        let start = buf.len();
        let room = (MAX_HEAD + 1).saturating_sub(buf.len()) as u64;
        let n = match r.by_ref().take(room).read_until(b'\n', &mut buf) {
            Ok(n) => n,
            Err(_) if buf.is_empty() => return Err(HeadError::Closed),
            Err(e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::TimedOut | std::io::ErrorKind::WouldBlock
                ) =>
            {
                return Err(HeadError::Timeout);
            }
            Err(_) => return Err(HeadError::Bad("connection failed inside the request head")),
        };
        if n == 0 {
            return Err(if buf.is_empty() {
                HeadError::Closed
            } else {
                HeadError::Bad("connection closed inside the request head")
            });
        }
        if buf.len() > MAX_HEAD {
            return Err(HeadError::TooLarge);
        }
        let line = &buf[start..];
        if !line.ends_with(b"\n") {
            return Err(HeadError::TooLarge);
        }
        if line == b"\r\n" || line == b"\n" {
            if start == 0 {
                buf.clear();
                continue;
            }
            break;
        }
    }
    parse_head(&buf)
}

/// Parses a complete head (request line, fields, blank line).
pub fn parse_head(bytes: &[u8]) -> Result<Head, HeadError> {
    let text =
        std::str::from_utf8(bytes).map_err(|_| HeadError::Bad("request head is not UTF-8"))?;
    let mut lines = text.split('\n').map(|l| l.strip_suffix('\r').unwrap_or(l));
    let first = lines.next().unwrap_or("");
    let mut parts = first.split(' ');
    let (Some(method), Some(target), Some(version), None) =
        (parts.next(), parts.next(), parts.next(), parts.next())
    else {
        return Err(HeadError::Bad("request line is not METHOD TARGET VERSION"));
    };
    let token = |s: &str| {
        !s.is_empty()
            && s.bytes()
                .all(|b| b.is_ascii_alphanumeric() || b"!#$%&'*+-.^_`|~".contains(&b))
    };
    if !token(method) {
        return Err(HeadError::Bad("bad method"));
    }
    if target.is_empty() || target.bytes().any(|b| b.is_ascii_control()) {
        return Err(HeadError::Bad("bad request target"));
    }
    let minor = match version {
        "HTTP/1.1" => 1,
        "HTTP/1.0" => 0,
        v if v.starts_with("HTTP/") => return Err(HeadError::Version),
        _ => return Err(HeadError::Bad("bad HTTP version")),
    };
    let mut headers = Vec::new();
    for line in lines {
        if line.is_empty() {
            break;
        }
        if line.starts_with([' ', '\t']) {
            return Err(HeadError::Bad("obsolete line folding"));
        }
        let Some((name, value)) = line.split_once(':') else {
            return Err(HeadError::Bad("header field without a colon"));
        };
        if !token(name) {
            return Err(HeadError::Bad("bad header field name"));
        }
        headers.push((name.to_string(), value.trim().to_string()));
    }
    Ok(Head {
        method: method.to_string(),
        target: target.to_string(),
        minor,
        headers,
    })
}

/// Reason phrase of a status code.
pub fn reason(status: u16) -> &'static str {
    match status {
        200 => "OK",
        206 => "Partial Content",
        304 => "Not Modified",
        400 => "Bad Request",
        403 => "Forbidden",
        404 => "Not Found",
        405 => "Method Not Allowed",
        408 => "Request Timeout",
        413 => "Content Too Large",
        416 => "Range Not Satisfiable",
        431 => "Request Header Fields Too Large",
        500 => "Internal Server Error",
        503 => "Service Unavailable",
        505 => "HTTP Version Not Supported",
        _ => "",
    }
}

/// Writes a response: status line, `headers`, `Content-Length: length`, `Connection` and the
/// body (`None` for HEAD/304/416: nothing after the head). Flushes.
pub fn write_response<W: Write>(
    w: &mut W,
    status: u16,
    headers: &[(&str, String)],
    length: u64,
    keep_alive: bool,
    body: Option<&mut dyn Read>,
) -> std::io::Result<u64> {
    let mut head = format!("HTTP/1.1 {status} {}\r\n", reason(status));
    for (k, v) in headers {
        // Header values come from our own code; strip CR/LF anyway so nothing can split them.
        let v: String = v.chars().filter(|c| *c != '\r' && *c != '\n').collect();
        head.push_str(&format!("{k}: {v}\r\n"));
    }
    head.push_str(&format!("Content-Length: {length}\r\n"));
    head.push_str(if keep_alive {
        "Connection: keep-alive\r\n\r\n"
    } else {
        "Connection: close\r\n\r\n"
    });
    w.write_all(head.as_bytes())?;
    let mut sent = 0;
    if let Some(body) = body {
        sent = std::io::copy(&mut body.take(length), w)?;
        if sent != length {
            w.flush()?;
            return Err(std::io::Error::new(
                std::io::ErrorKind::UnexpectedEof,
                format!("body ended after {sent} of {length} bytes"),
            ));
        }
    }
    w.flush()?;
    Ok(sent)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn head(s: &str) -> Result<Head, HeadError> {
        read_head(&mut std::io::Cursor::new(s.as_bytes().to_vec()))
    }

    #[test]
    fn parses_request_line_and_fields() {
        let h =
            head("\r\nGET /a%20b.glb?x=1 HTTP/1.1\r\nHost: h\r\nrAnGe:  bytes=5-\r\n\r\n").unwrap();
        assert_eq!(
            (h.method.as_str(), h.target.as_str(), h.minor),
            ("GET", "/a%20b.glb?x=1", 1)
        );
        assert_eq!(h.header("range"), Some("bytes=5-"));
        assert!(h.keep_alive() && !h.has_body());
        let h = head("GET / HTTP/1.0\nConnection: Keep-Alive\n\n").unwrap();
        assert!(h.keep_alive());
        assert!(!head("GET / HTTP/1.0\r\n\r\n").unwrap().keep_alive());
        assert!(
            !head("GET / HTTP/1.1\r\nConnection: foo, close\r\n\r\n")
                .unwrap()
                .keep_alive()
        );
        assert!(
            head("GET / HTTP/1.1\r\nContent-Length: 3\r\n\r\n")
                .unwrap()
                .has_body()
        );
        assert!(
            head("GET / HTTP/1.1\r\nTransfer-Encoding: chunked\r\n\r\n")
                .unwrap()
                .has_body()
        );
    }

    #[test]
    fn refuses_bad_heads() {
        assert_eq!(head(""), Err(HeadError::Closed));
        assert!(matches!(
            head("GET / HTTP/1.1\r\nHost: h\r\n"),
            Err(HeadError::Bad(_))
        ));
        assert!(matches!(head("GET /\r\n\r\n"), Err(HeadError::Bad(_))));
        assert!(matches!(
            head("GET  / HTTP/1.1\r\n\r\n"),
            Err(HeadError::Bad(_))
        ));
        assert!(matches!(
            head("G(T / HTTP/1.1\r\n\r\n"),
            Err(HeadError::Bad(_))
        ));
        assert_eq!(head("PRI * HTTP/2.0\r\n\r\n"), Err(HeadError::Version));
        assert!(matches!(
            head("GET / HTTP/1.1\r\nA: b\r\n c\r\n\r\n"),
            Err(HeadError::Bad(_))
        ));
        assert!(matches!(
            head("GET / HTTP/1.1\r\nno colon\r\n\r\n"),
            Err(HeadError::Bad(_))
        ));
        assert!(matches!(
            head("GET /\u{1} HTTP/1.1\r\n\r\n"),
            Err(HeadError::Bad(_))
        ));
        let mut bytes = b"GET / HTTP/1.1\r\n".to_vec();
        bytes.extend([0xff, b'\r', b'\n', b'\r', b'\n']);
        assert!(matches!(
            read_head(&mut std::io::Cursor::new(bytes)),
            Err(HeadError::Bad(_))
        ));
        let big = format!("GET / HTTP/1.1\r\nX: {}\r\n\r\n", "a".repeat(MAX_HEAD));
        assert_eq!(head(&big), Err(HeadError::TooLarge));
        let long_line = format!("GET /{} HTTP/1.1", "a".repeat(MAX_HEAD * 2));
        assert_eq!(head(&long_line), Err(HeadError::TooLarge));
    }

    #[test]
    fn writes_content_length_and_connection() {
        let mut out = Vec::new();
        let mut body = std::io::Cursor::new(b"hello world".to_vec());
        let n = write_response(
            &mut out,
            206,
            &[("ETag", "\"x\"\r\nEvil: 1".into())],
            5,
            false,
            Some(&mut body),
        )
        .unwrap();
        assert_eq!(n, 5);
        let s = String::from_utf8(out).unwrap();
        assert_eq!(
            s,
            "HTTP/1.1 206 Partial Content\r\nETag: \"x\"Evil: 1\r\nContent-Length: 5\r\nConnection: close\r\n\r\nhello"
        );
        let mut short = std::io::Cursor::new(b"abc".to_vec());
        let mut out = Vec::new();
        assert!(write_response(&mut out, 200, &[], 10, true, Some(&mut short)).is_err());
    }
}
