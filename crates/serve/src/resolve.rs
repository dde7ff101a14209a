//! Request target -> file under a served root, refusing every way out of it: `..` (plain or
//! percent-encoded), NUL, backslashes, non-origin targets and symlinks that lead outside the root.

use std::path::{Path, PathBuf};

/// Why a request target names no servable file.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Refusal {
    /// Not an origin-form path (`/…`) or a broken percent escape: 400.
    BadRequest(&'static str),
    /// A way out of the root (`..`, NUL, `\`, a symlink leading outside): 403.
    Forbidden(&'static str),
    /// Nothing there (or a directory without `index.html`): 404.
    NotFound,
}

/// Decodes `%XX` escapes of a request path into bytes; `None` on a broken escape.
fn percent_decode(s: &str) -> Option<Vec<u8>> {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%' {
            let hex = b.get(i + 1..i + 3)?;
            if !hex.iter().all(u8::is_ascii_hexdigit) {
                return None;
            }
            out.push(u8::from_str_radix(std::str::from_utf8(hex).ok()?, 16).ok()?);
            i += 3;
        } else {
            out.push(b[i]);
            i += 1;
        }
    }
    Some(out)
}

/// The decoded path of a request target (query and fragment dropped), as `/`-separated
/// segments with `.` and empty ones removed, plus whether it ended in `/`.
///
/// Decoding happens before splitting, so `..%2f` and `%2e%2e` are seen as the `..` they are.
pub fn segments(target: &str) -> Result<(Vec<String>, bool), Refusal> {
    let path = target.split(['?', '#']).next().unwrap_or("");
    if !path.starts_with('/') {
        return Err(Refusal::BadRequest(
            "request target is not an absolute path",
        ));
    }
    let bytes = percent_decode(path).ok_or(Refusal::BadRequest("broken percent escape"))?;
    if bytes.contains(&0) {
        return Err(Refusal::Forbidden("NUL in path"));
    }
    let path = String::from_utf8(bytes).map_err(|_| Refusal::BadRequest("path is not UTF-8"))?;
    if path.contains('\\') {
        return Err(Refusal::Forbidden("backslash in path"));
    }
    let mut out = Vec::new();
    for seg in path.split('/') {
        match seg {
            "" | "." => {}
            ".." => return Err(Refusal::Forbidden("'..' in path")),
            s => out.push(s.to_string()),
        }
    }
    let dir = path.ends_with('/');
    Ok((out, dir))
}

/// A regular file inside `root` (canonical) named by `segs`, with symlinks resolved and checked
/// to stay inside `root`; a directory yields its `index.html` or [`Refusal::NotFound`].
pub fn file_under(root: &Path, segs: &[String]) -> Result<PathBuf, Refusal> {
    let mut p = root.to_path_buf();
    p.extend(segs);
    let real = inside(root, &p)?;
    if real.is_dir() {
        let index = inside(root, &real.join("index.html"))?;
        return if index.is_file() {
            Ok(index)
        } else {
            Err(Refusal::NotFound)
        };
    }
    if real.is_file() {
        Ok(real)
    } else {
        Err(Refusal::NotFound)
    }
}

/// `p` with symlinks resolved, refused when that leaves `root`.
pub fn inside(root: &Path, p: &Path) -> Result<PathBuf, Refusal> {
    let real = p.canonicalize().map_err(|_| Refusal::NotFound)?;
    if real.starts_with(root) {
        Ok(real)
    } else {
        Err(Refusal::Forbidden("path leads outside the served folder"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn segs(t: &str) -> Result<Vec<String>, Refusal> {
        segments(t).map(|(s, _)| s)
    }

    #[test]
    fn plain_and_encoded_paths_split_into_segments() {
        assert_eq!(segs("/a/b.glb").unwrap(), ["a", "b.glb"]);
        assert_eq!(segs("/a//./b?x=1#f").unwrap(), ["a", "b"]);
        assert_eq!(segs("/a%20b/c%2Fd").unwrap(), ["a b", "c", "d"]);
        assert_eq!(segs("/").unwrap(), Vec::<String>::new());
        assert!(segments("/dir/").unwrap().1);
        assert!(!segments("/dir").unwrap().1);
    }

    #[test]
    fn every_way_out_is_refused() {
        for t in [
            "/../Cargo.toml",
            "/%2e%2e/Cargo.toml",
            "/%2E%2E/x",
            "/tiles/..%2f..%2fsecret",
            "/a/%2e%2e%2f%2e%2e%2fetc/passwd",
            "/a/..",
            "/a%00b",
            "/a%5c..%5cb",
            "/a\\b",
        ] {
            assert!(
                matches!(segs(t), Err(Refusal::Forbidden(_))),
                "{t}: {:?}",
                segs(t)
            );
        }
        for t in [
            "",
            "/%+1",
            "Cargo.toml",
            "http://x/y",
            "*",
            "/%",
            "/%zz",
            "/%c3",
        ] {
            assert!(
                matches!(segs(t), Err(Refusal::BadRequest(_))),
                "{t}: {:?}",
                segs(t)
            );
        }
    }

    #[test]
    fn symlinks_may_not_lead_outside_the_root() {
        let outer = tempfile::tempdir().unwrap();
        let root = outer.path().join("root");
        std::fs::create_dir_all(root.join("sub")).unwrap();
        std::fs::write(outer.path().join("secret"), "s").unwrap();
        std::fs::write(root.join("sub/a.txt"), "a").unwrap();
        let root = root.canonicalize().unwrap();
        let s = |v: &[&str]| v.iter().map(|x| x.to_string()).collect::<Vec<_>>();
        assert!(file_under(&root, &s(&["sub", "a.txt"])).is_ok());
        assert_eq!(file_under(&root, &s(&["sub"])), Err(Refusal::NotFound));
        assert_eq!(file_under(&root, &s(&["nope"])), Err(Refusal::NotFound));
        #[cfg(unix)]
        {
            std::os::unix::fs::symlink(outer.path().join("secret"), root.join("leak")).unwrap();
            std::os::unix::fs::symlink(outer.path(), root.join("up")).unwrap();
            std::os::unix::fs::symlink(root.join("sub/a.txt"), root.join("ok")).unwrap();
            assert!(matches!(
                file_under(&root, &s(&["leak"])),
                Err(Refusal::Forbidden(_))
            ));
            assert!(matches!(
                file_under(&root, &s(&["up", "secret"])),
                Err(Refusal::Forbidden(_))
            ));
            assert!(file_under(&root, &s(&["ok"])).is_ok());
        }
        std::fs::write(root.join("sub/index.html"), "i").unwrap();
        assert!(
            file_under(&root, &s(&["sub"]))
                .unwrap()
                .ends_with("index.html")
        );
    }
}
