//! URL handling of the streaming client: the base of a tileset URL and the resolution of the
//! relative URIs a tileset names, refusing anything that would leave that base.

/// Why a URI named by the tileset was refused.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum UrlError {
    /// Absolute URL, scheme, host-relative path, drive letter or UNC path.
    #[error("'{0}' is not a relative URI (absolute URLs, schemes and rooted paths are refused)")]
    NotRelative(String),
    /// `..` climbs above the tileset's folder.
    #[error("'{0}' climbs out of the tileset's base with '..'")]
    Escapes(String),
    /// Characters we do not fetch: percent escapes, backslashes, query, fragment, controls.
    #[error("'{0}' holds characters the client refuses (%, \\, ?, #, whitespace or controls)")]
    BadCharacters(String),
    /// Empty URI.
    #[error("empty URI")]
    Empty,
}

/// The base of a URL or path: everything up to and including its last `/` (query and fragment
/// dropped); empty when there is no `/`.
pub fn base_of(url: &str) -> &str {
    let end = url.find(['?', '#']).unwrap_or(url.len());
    let url = &url[..end];
    match url.rfind('/') {
        Some(i) => &url[..=i],
        None => "",
    }
}

/// Resolves `rel` (a URI from `tileset.json` or a template expansion) against `base` (from
/// [`base_of`]); the result always starts with `base`. `.` segments and empty segments are
/// dropped and `..` is allowed only while it stays inside the base.
pub fn resolve(base: &str, rel: &str) -> Result<String, UrlError> {
    if rel.is_empty() {
        return Err(UrlError::Empty);
    }
    if rel.contains("://") || rel.starts_with('/') || rel.contains(':') {
        return Err(UrlError::NotRelative(rel.to_string()));
    }
    if rel
        .chars()
        .any(|c| matches!(c, '%' | '\\' | '?' | '#') || c.is_whitespace() || c.is_control())
    {
        return Err(UrlError::BadCharacters(rel.to_string()));
    }
    let mut segs: Vec<&str> = Vec::new();
    for s in rel.split('/') {
        match s {
            "" | "." => {}
            ".." => {
                if segs.pop().is_none() {
                    return Err(UrlError::Escapes(rel.to_string()));
                }
            }
            s => segs.push(s),
        }
    }
    if segs.is_empty() {
        return Err(UrlError::Empty);
    }
    Ok(format!("{base}{}", segs.join("/")))
}

/// `bytes START-END/TOTAL` -> (START, TOTAL).
pub fn parse_content_range(v: &str) -> (Option<u64>, Option<u64>) {
    let Some(rest) = v.trim().strip_prefix("bytes ") else {
        return (None, None);
    };
    let (range, total) = rest.split_once('/').unwrap_or((rest, "*"));
    let start = range
        .split_once('-')
        .and_then(|(a, _)| a.trim().parse().ok());
    (start, total.trim().parse().ok())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base_and_resolution() {
        assert_eq!(
            base_of("http://h:8/a/ts/tileset.json?k=1"),
            "http://h:8/a/ts/"
        );
        assert_eq!(base_of("/tmp/ts/tileset.json"), "/tmp/ts/");
        assert_eq!(base_of("tileset.json"), "");
        let b = "http://h:8/a/ts/";
        assert_eq!(
            resolve(b, "tiles/best/0/0/0/0.glb").unwrap(),
            "http://h:8/a/ts/tiles/best/0/0/0/0.glb"
        );
        assert_eq!(
            resolve(b, "./x/../y//z.glb").unwrap(),
            "http://h:8/a/ts/y/z.glb"
        );
        for bad in [
            "../x.glb",
            "a/../../x",
            "/etc/passwd",
            "http://evil/y.glb",
            "//evil/y.glb",
            "file:///etc/passwd",
            "C:\\x",
            "a\\..\\..\\x",
            "%2e%2e/x",
            "a/b?x=1",
            "",
            ".",
            "a/..",
        ] {
            assert!(resolve(b, bad).is_err(), "{bad}");
        }
    }
}
