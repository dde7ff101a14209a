//! Resolution of the relative URIs of a tileset to files: query and fragment dropped, percent
//! escapes decoded (`%20`, `%2e%2e`), then `.`/`..` applied lexically inside an allowed root.

use percent_encoding::percent_decode_str;
use std::path::{Component, Path, PathBuf};

/// Where a URI leads.
#[derive(Debug, PartialEq)]
pub(crate) enum Resolved {
    /// A path inside the root (not yet checked for symbolic links or existence).
    Inside(PathBuf),
    /// Absolute, or climbs out of the root.
    Outside,
    /// Not a usable relative reference (bad percent-encoding, NUL, empty path).
    Invalid(String),
}

/// `path` made absolute (against the working directory) with `.` and `..` applied lexically.
pub(crate) fn lexical(path: &Path) -> PathBuf {
    let abs = std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf());
    let mut out = PathBuf::new();
    for c in abs.components() {
        match c {
            Component::ParentDir => {
                out.pop();
            }
            Component::CurDir => {}
            other => out.push(other.as_os_str()),
        }
    }
    out
}

/// Resolves `uri`, relative to folder `base`, to a file inside `root` (both lexical, absolute).
pub(crate) fn resolve_uri(root: &Path, base: &Path, uri: &str) -> Resolved {
    // RFC 3986: the path ends at '?' (query) or '#' (fragment).
    let path = uri.split(['?', '#']).next().unwrap_or("");
    // A scheme ("file:", "c:") or an absolute path names something outside the tileset.
    let scheme = path.find(':').is_some_and(|i| !path[..i].contains('/'));
    if scheme || path.starts_with('/') || path.starts_with('\\') {
        return Resolved::Outside;
    }
    let decoded = match percent_decode_str(path).decode_utf8() {
        Ok(d) => d,
        Err(_) => return Resolved::Invalid("percent escapes decode to invalid UTF-8".into()),
    };
    if decoded.contains('\0') {
        return Resolved::Invalid("a percent escape decodes to a NUL byte".into());
    }
    if decoded.is_empty() {
        return Resolved::Invalid("the URI names no file".into());
    }
    if decoded.starts_with('/') || decoded.starts_with('\\') {
        return Resolved::Outside;
    }
    let Ok(rel_base) = base.strip_prefix(root) else {
        return Resolved::Outside;
    };
    let mut parts: Vec<&str> = rel_base
        .components()
        .filter_map(|c| c.as_os_str().to_str())
        .collect();
    for seg in decoded.split('/') {
        match seg {
            "" | "." => {}
            ".." => {
                if parts.pop().is_none() {
                    return Resolved::Outside;
                }
            }
            s => parts.push(s),
        }
    }
    let mut out = root.to_path_buf();
    out.extend(parts);
    Resolved::Inside(out)
}

/// The folder of the file `name` (a path relative to the tileset folder; "" at its top).
pub(crate) fn folder_of(name: &str) -> String {
    Path::new(name)
        .parent()
        .map(|p| p.to_string_lossy().into_owned())
        .unwrap_or_default()
}

/// `uri` as written in a file of the folder `dir` (relative to the tileset folder), made
/// relative to the tileset folder.
pub(crate) fn in_folder(dir: &str, uri: &str) -> String {
    if dir.is_empty() {
        uri.to_string()
    } else {
        format!("{dir}/{uri}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percent_escapes_decode_and_dot_dot_stays_inside_the_root() {
        let root = Path::new("/r");
        let ts = Path::new("/r/a");
        let ok = |p: &str| Resolved::Inside(PathBuf::from(p));
        assert_eq!(resolve_uri(root, root, "0%20x.glb"), ok("/r/0 x.glb"));
        assert_eq!(resolve_uri(root, root, "t/x.glb?v=2#f"), ok("/r/t/x.glb"));
        assert_eq!(resolve_uri(root, ts, "../b/x.glb"), ok("/r/b/x.glb"));
        assert_eq!(
            resolve_uri(root, root, "tiles/%2e%2e/x.glb"),
            ok("/r/x.glb")
        );
        assert_eq!(
            resolve_uri(root, root, "tiles/%2e%2e/%2E%2E/etc/passwd"),
            Resolved::Outside
        );
        assert_eq!(resolve_uri(root, ts, "../../x"), Resolved::Outside);
        assert_eq!(resolve_uri(root, root, "/etc/passwd"), Resolved::Outside);
        assert_eq!(resolve_uri(root, root, "%2Fetc/passwd"), Resolved::Outside);
        assert_eq!(resolve_uri(root, root, "file:x"), Resolved::Outside);
        assert!(matches!(
            resolve_uri(root, root, "a%00b"),
            Resolved::Invalid(_)
        ));
        assert!(matches!(
            resolve_uri(root, root, "%ff"),
            Resolved::Invalid(_)
        ));
        assert_eq!(lexical(Path::new("/a/b/../c/./d")), PathBuf::from("/a/c/d"));
    }
}
