//! The workspace's structure: no `use` cycle between sibling modules anywhere in any package
//! (`crate::a` naming `crate::b` and back, or `super::x` and `super::y` inside one module,
//! through any path). Cargo already refuses cycles between crates; this catches them inside one.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Every `.rs` file under `dir`.
fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap().flatten() {
        let p = e.path();
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

/// Module path of a source file under `src` (`lib.rs` and `main.rs` are the crate root, `a.rs`
/// and `a/mod.rs` are `a`, `a/b.rs` is `a::b`); `None` for `src/bin` (crates of their own).
fn module_path(src: &Path, file: &Path) -> Option<Vec<String>> {
    let rel = file.strip_prefix(src).ok()?;
    let mut parts: Vec<String> = rel
        .components()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect();
    if parts.first().is_some_and(|p| p == "bin") {
        return None;
    }
    let last = parts.pop()?;
    let stem = last.trim_end_matches(".rs");
    if !(matches!(stem, "mod") || (parts.is_empty() && matches!(stem, "lib" | "main"))) {
        parts.push(stem.to_string());
    }
    Some(parts)
}

/// The leading identifier of `s`.
fn ident(s: &str) -> String {
    s.chars()
        .take_while(|c| c.is_alphanumeric() || *c == '_')
        .collect()
}

/// The paths a `use` or expression names from position `rest` on (after `crate::`, `super::`
/// or `self::`), groups `{a, b::c}` expanded: each as its segments.
fn paths_from(rest: &str) -> Vec<Vec<String>> {
    let mut head = vec![];
    let mut at = rest;
    loop {
        if let Some(group) = at.strip_prefix('{') {
            let mut depth = 0usize;
            let mut end = group.len();
            for (i, c) in group.char_indices() {
                match c {
                    '{' => depth += 1,
                    '}' if depth == 0 => {
                        end = i;
                        break;
                    }
                    '}' => depth -= 1,
                    _ => {}
                }
            }
            let body = &group[..end];
            let mut out = vec![];
            let mut depth = 0usize;
            let mut from = 0;
            for (i, c) in body.char_indices().chain([(body.len(), ',')]) {
                match c {
                    '{' => depth += 1,
                    '}' => depth = depth.saturating_sub(1),
                    ',' if depth == 0 => {
                        for tail in paths_from(body[from..i.min(body.len())].trim()) {
                            let mut p = head.clone();
                            p.extend(tail);
                            out.push(p);
                        }
                        from = i + 1;
                    }
                    _ => {}
                }
            }
            return out;
        }
        let id = ident(at);
        if id.is_empty() {
            return vec![head];
        }
        at = &at[id.len()..];
        head.push(id);
        match at.strip_prefix("::") {
            Some(next) => at = next,
            None => return vec![head],
        }
    }
}

/// The modules a file at module path `here` names through `crate::`, `super::` and `self::`
/// paths (as absolute module paths, cut at the last segment in `known`); unit tests
/// (`#[cfg(test)]` onwards) left out.
fn module_refs(
    text: &str,
    here: &[String],
    known: &BTreeSet<Vec<String>>,
) -> BTreeSet<Vec<String>> {
    let code = text.split("#[cfg(test)]").next().unwrap_or("");
    let mut out = BTreeSet::new();
    for start in ["crate::", "super::", "self::"] {
        for (i, _) in code.match_indices(start) {
            let before = &code[..i];
            if before.ends_with(|c: char| c.is_alphanumeric() || c == '_' || c == '$' || c == ':') {
                continue;
            }
            let mut base: Vec<String> = match start {
                "crate::" => vec![],
                "self::" => here.to_vec(),
                _ => here[..here.len().saturating_sub(1)].to_vec(),
            };
            let mut rest = &code[i + start.len()..];
            while let Some(r) = rest.strip_prefix("super::") {
                base.pop();
                rest = r;
            }
            for tail in paths_from(rest) {
                let mut full = base.clone();
                let mut best = full.clone();
                for seg in tail {
                    full.push(seg);
                    if known.contains(&full) {
                        best = full.clone();
                    }
                }
                out.insert(best);
            }
        }
    }
    out
}

/// The module graphs of one crate's `src`: per parent module, its child modules -> the sibling
/// modules they (or anything inside them) name. The crate root's graph holds the top-level
/// modules.
fn graphs(src: &Path) -> BTreeMap<Vec<String>, BTreeMap<String, BTreeSet<String>>> {
    let mut files = vec![];
    rust_files(src, &mut files);
    let files: Vec<(Vec<String>, PathBuf)> = files
        .into_iter()
        .filter_map(|f| Some((module_path(src, &f)?, f)))
        .collect();
    let known: BTreeSet<Vec<String>> = files.iter().map(|(m, _)| m.clone()).collect();
    let mut g: BTreeMap<Vec<String>, BTreeMap<String, BTreeSet<String>>> = BTreeMap::new();
    for (here, f) in &files {
        let text = std::fs::read_to_string(f).unwrap();
        for target in module_refs(&text, here, &known) {
            let common = here.iter().zip(&target).take_while(|(a, b)| a == b).count();
            if common < here.len() && common < target.len() {
                g.entry(here[..common].to_vec())
                    .or_default()
                    .entry(here[common].clone())
                    .or_default()
                    .insert(target[common].clone());
            }
        }
    }
    g
}

/// A cycle through `start` in `g`, if any (depth-first search).
fn cycle_from(g: &BTreeMap<String, BTreeSet<String>>, start: &str) -> Option<Vec<String>> {
    let mut stack = vec![(start.to_string(), vec![start.to_string()])];
    let mut seen = BTreeSet::new();
    while let Some((at, path)) = stack.pop() {
        for next in g.get(&at).into_iter().flatten() {
            if next == start {
                return Some(path.clone());
            }
            if g.contains_key(next) && seen.insert(next.clone()) {
                let mut p = path.clone();
                p.push(next.clone());
                stack.push((next.clone(), p));
            }
        }
    }
    None
}

/// Every cycle found in the packages `packages` (folders with a `src`), as
/// "package: parent::{a -> b -> a}" (parent `crate` for top-level modules).
fn cycles(packages: &[PathBuf]) -> Vec<String> {
    let mut found = vec![];
    for pkg in packages {
        let src = pkg.join("src");
        if !src.is_dir() {
            continue;
        }
        let name = pkg.file_name().unwrap_or_default().to_string_lossy();
        for (parent, g) in graphs(&src) {
            let parent = if parent.is_empty() {
                "crate".to_string()
            } else {
                parent.join("::")
            };
            for m in g.keys() {
                if let Some(c) = cycle_from(&g, m) {
                    found.push(format!("{name}: {parent}::{{{} -> {m}}}", c.join(" -> ")));
                }
            }
        }
    }
    found
}

/// The workspace's packages: the root (the binary), `crates/*`, the viewers.
fn packages() -> Vec<PathBuf> {
    let root = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
        .canonicalize()
        .unwrap();
    let mut out = vec![
        root.to_path_buf(),
        root.join("viewer"),
        root.join("viewer/web"),
    ];
    for e in std::fs::read_dir(root.join("crates")).unwrap().flatten() {
        out.push(e.path());
    }
    out
}

#[test]
fn no_module_cycles_inside_any_crate() {
    let found = cycles(&packages());
    assert!(found.is_empty(), "module cycles:\n{}", found.join("\n"));
}

#[test]
fn a_cycle_is_found() {
    let tmp = tempfile::tempdir().unwrap();
    let src = tmp.path().join("demo/src");
    std::fs::create_dir_all(src.join("a")).unwrap();
    std::fs::write(src.join("lib.rs"), "pub mod a;\npub mod b;\npub mod c;\n").unwrap();
    std::fs::write(src.join("a/mod.rs"), "use crate::{b::X, c};\n").unwrap();
    std::fs::write(
        src.join("b.rs"),
        "pub struct X;\nfn f() { crate::c::g(); }\n",
    )
    .unwrap();
    std::fs::write(src.join("c.rs"), "pub fn g() { let _ = crate::a::Y; }\n").unwrap();
    let found = cycles(&[tmp.path().join("demo")]);
    assert!(!found.is_empty(), "a -> b -> c -> a not found");
    assert!(found[0].starts_with("demo: "), "{found:?}");
    // Without c's use of a, no cycle.
    std::fs::write(
        src.join("c.rs"),
        "pub fn g() {}\n// crate::a::Y in a comment counts too\n",
    )
    .unwrap();
    assert!(
        !cycles(&[tmp.path().join("demo")]).is_empty(),
        "comments are read as code (conservative)"
    );
    std::fs::write(src.join("c.rs"), "pub fn g() {}\n").unwrap();
    assert!(cycles(&[tmp.path().join("demo")]).is_empty());
}

#[test]
fn a_cycle_between_sibling_files_is_found() {
    let tmp = tempfile::tempdir().unwrap();
    let pkg = tmp.path().join("demo");
    let src = pkg.join("src");
    std::fs::create_dir_all(src.join("a")).unwrap();
    std::fs::write(src.join("lib.rs"), "pub mod a;\n").unwrap();
    std::fs::write(src.join("a/mod.rs"), "mod x;\nmod y;\nmod z;\n").unwrap();
    std::fs::write(src.join("a/x.rs"), "use super::y::Y;\n").unwrap();
    std::fs::write(src.join("a/z.rs"), "pub struct Z;\n").unwrap();
    std::fs::write(src.join("a/y.rs"), "pub struct Y;\n").unwrap();
    assert!(cycles(std::slice::from_ref(&pkg)).is_empty());
    // y names z and z names x (by its absolute path): x -> y -> z -> x.
    std::fs::write(src.join("a/y.rs"), "pub struct Y;\nuse super::{z::Z};\n").unwrap();
    std::fs::write(src.join("a/z.rs"), "fn f() { crate::a::x::g(); }\n").unwrap();
    let found = cycles(std::slice::from_ref(&pkg));
    assert!(
        found.iter().any(|c| c.starts_with("demo: a::{")),
        "{found:?}"
    );
    // A child naming its parent (super::*) or the parent naming a child is no cycle.
    std::fs::write(src.join("a/z.rs"), "use super::*;\n").unwrap();
    assert!(cycles(std::slice::from_ref(&pkg)).is_empty());
}
