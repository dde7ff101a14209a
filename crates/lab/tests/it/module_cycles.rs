//! The workspace's structure: no `use` cycle between the top-level modules of any crate
//! (`crate::a` naming `crate::b` and back, through any path). Cargo already refuses cycles
//! between crates; this catches them inside one.

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

/// The top-level modules named after `crate::` in `text` (also inside `crate::{a, b::c}`),
/// unit tests (`#[cfg(test)]` onwards) left out.
fn crate_refs(text: &str) -> BTreeSet<String> {
    let code = text.split("#[cfg(test)]").next().unwrap_or("");
    let ident = |s: &str| -> String {
        s.chars()
            .take_while(|c| c.is_alphanumeric() || *c == '_')
            .collect()
    };
    let mut out = BTreeSet::new();
    for (i, _) in code.match_indices("crate::") {
        if i > 0 && code[..i].ends_with(|c: char| c.is_alphanumeric() || c == '_' || c == '$') {
            continue;
        }
        let rest = &code[i + "crate::".len()..];
        if let Some(group) = rest.strip_prefix('{') {
            let body = &group[..group.find('}').unwrap_or(group.len())];
            out.extend(
                body.split(',')
                    .map(|s| ident(s.trim()))
                    .filter(|s| !s.is_empty()),
            );
        } else {
            out.insert(ident(rest));
        }
    }
    out
}

/// The module graph of one crate's `src`: top-level module -> modules it names.
fn graph(src: &Path) -> BTreeMap<String, BTreeSet<String>> {
    let mut files = vec![];
    rust_files(src, &mut files);
    let mut g: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for f in files {
        let rel = f.strip_prefix(src).unwrap();
        let top = rel
            .components()
            .next()
            .unwrap()
            .as_os_str()
            .to_string_lossy();
        let top = top.trim_end_matches(".rs").to_string();
        if matches!(top.as_str(), "lib" | "main" | "bin") {
            continue;
        }
        let refs = crate_refs(&std::fs::read_to_string(&f).unwrap());
        g.entry(top.clone())
            .or_default()
            .extend(refs.into_iter().filter(|r| *r != top));
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

/// Every cycle found in the crates under `crates`, as "crate: a -> b -> a".
fn cycles(crates: &Path) -> Vec<String> {
    let mut found = vec![];
    for e in std::fs::read_dir(crates).unwrap().flatten() {
        let src = e.path().join("src");
        if !src.is_dir() {
            continue;
        }
        let g = graph(&src);
        for m in g.keys() {
            if let Some(c) = cycle_from(&g, m) {
                found.push(format!(
                    "{}: {} -> {m}",
                    e.file_name().to_string_lossy(),
                    c.join(" -> ")
                ));
            }
        }
    }
    found
}

#[test]
fn no_module_cycles_inside_any_crate() {
    let crates = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.."));
    let found = cycles(crates);
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
    let found = cycles(tmp.path());
    assert!(!found.is_empty(), "a -> b -> c -> a not found");
    assert!(found[0].starts_with("demo: "), "{found:?}");
    // Without c's use of a, no cycle.
    std::fs::write(
        src.join("c.rs"),
        "pub fn g() {}\n// crate::a::Y in a comment counts too\n",
    )
    .unwrap();
    assert!(
        !cycles(tmp.path()).is_empty(),
        "comments are read as code (conservative)"
    );
    std::fs::write(src.join("c.rs"), "pub fn g() {}\n").unwrap();
    assert!(cycles(tmp.path()).is_empty());
}
