//! Which folders `convert` may write into: absent, empty, or an earlier splat2tiles output whose
//! marker lists everything in it. Anything else is refused, naming the folder and what it holds.

use super::OutputError;
use super::marker::{self, MARKER};
use std::path::Path;

/// Most entry names a refusal lists.
const SHOWN: usize = 6;

/// Checks that `target` may be (re)placed by a new output; `Ok(true)` when it exists.
pub fn check_target(target: &Path) -> Result<bool, OutputError> {
    let refuse = |why: String| OutputError::Refused {
        path: target.to_path_buf(),
        why,
    };
    let meta = match std::fs::symlink_metadata(target) {
        Ok(m) => m,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(false),
        Err(e) => return Err(OutputError::io(target, "inspecting the output folder", e)),
    };
    if meta.file_type().is_symlink() {
        return Err(refuse(
            "is a symbolic link; give the folder it points to, or another -o".into(),
        ));
    }
    if !meta.is_dir() {
        return Err(refuse(
            "exists and is not a folder; refusing to replace it".into(),
        ));
    }
    let mut names = Vec::new();
    for e in std::fs::read_dir(target)
        .map_err(|e| OutputError::io(target, "listing the output folder", e))?
    {
        let e = e.map_err(|e| OutputError::io(target, "listing the output folder", e))?;
        let mut name = e.file_name().to_string_lossy().into_owned();
        if e.file_type().is_ok_and(|t| t.is_dir()) {
            name.push('/');
        }
        names.push(name);
    }
    if names.is_empty() {
        return Ok(true);
    }
    names.sort();
    let Some(m) = marker::read(target) else {
        return Err(refuse(format!(
            "refusing to write into a folder that is not empty and is not an earlier splat2tiles \
             output (no {MARKER}); it holds {}. Choose another -o or empty the folder",
            list(&names)
        )));
    };
    let foreign: Vec<String> = names
        .into_iter()
        .filter(|n| {
            let bare = n.trim_end_matches('/');
            bare != MARKER && !m.entries.contains(bare)
        })
        .collect();
    if !foreign.is_empty() {
        return Err(refuse(format!(
            "an earlier splat2tiles output, but it also holds {} which splat2tiles did not write; \
             refusing to replace it (move those elsewhere or choose another -o)",
            list(&foreign)
        )));
    }
    Ok(true)
}

/// `a, b, c (and 4 more)`.
fn list(names: &[String]) -> String {
    let mut s = names
        .iter()
        .take(SHOWN)
        .map(String::as_str)
        .collect::<Vec<_>>()
        .join(", ");
    if names.len() > SHOWN {
        s.push_str(&format!(" (and {} more)", names.len() - SHOWN));
    }
    s
}
