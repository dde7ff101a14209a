//! A plain clone with no data folder beside it works: the README's convert, the hint's render,
//! validate, the web viewer's build and `view` serving it (the built binary stands in for cargo run).

use super::assert_valid;
use super::common::{bin, convert_hint};
use std::path::Path;
use std::process::Command;

/// The first command block of README.md's "Two commands on a fresh machine" section.
fn readme_first_command(readme: &str) -> String {
    let section = readme
        .split("## Two commands on a fresh machine")
        .nth(1)
        .expect("README has the 'Two commands on a fresh machine' section");
    let block = section
        .split("```sh\n")
        .nth(1)
        .and_then(|b| b.split("```").next())
        .expect("a sh code block in that section");
    block.trim().to_string()
}

#[test]
fn readme_first_command_converts_in_a_plain_clone() {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    let tmp = tempfile::tempdir().unwrap();
    let clone = tmp.path().join("splat2tiles");
    let o = Command::new("git")
        .args(["clone", "--quiet", "--no-hardlinks"])
        .arg(repo)
        .arg(&clone)
        .output()
        .expect("git is installed");
    assert!(
        o.status.success(),
        "git clone: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(!tmp.path().join("shared").exists());
    let readme = std::fs::read_to_string(clone.join("README.md")).unwrap();
    let command = readme_first_command(&readme);
    // The convert step: `cargo run --release -- convert ARGS... && ...`.
    let convert = command.split("&&").next().unwrap().trim();
    let args = convert
        .strip_prefix("cargo run --release -- ")
        .unwrap_or_else(|| {
            panic!("README's first command is not `cargo run --release -- ...`: {convert}")
        });
    let args: Vec<&str> = args.split_whitespace().collect();
    assert_eq!(args.first(), Some(&"convert"), "{convert}");
    let input = clone.join(args[1]);
    assert!(input.is_file(), "{} is in the clone", args[1]);
    assert!(!args[1].contains("shared"), "{convert}");
    let o = Command::new(bin())
        .args(&args)
        .arg("--quiet")
        .current_dir(&clone)
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "`{convert}` in a clone: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    let out_flag = args
        .iter()
        .position(|a| *a == "-o")
        .expect("-o in the command");
    let tileset = clone.join(args[out_flag + 1]).join("tileset.json");
    assert_valid(&tileset);
    // The sample ships with its licence.
    let lic = std::fs::read_to_string(clone.join("samples/README.md")).unwrap();
    assert!(lic.contains("CC-BY-4.0") && lic.contains("Marcel Padilla"));

    // The hint's render command, run as printed, then validate.
    let o = Command::new(bin())
        .args(&args)
        .current_dir(&clone)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (_, words) = convert_hint(&String::from_utf8_lossy(&o.stdout));
    let o = Command::new(&words[0])
        .args(&words[1..])
        .current_dir(&clone)
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "`{}`: {}",
        words.join(" "),
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(clone.join("view.png").is_file());
    let o = Command::new(bin())
        .arg("validate")
        .arg(args[out_flag + 1])
        .current_dir(&clone)
        .output()
        .unwrap();
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stdout)
    );

    // The web viewer builds in the clone and `view` serves it.
    build_web_viewer(repo, &clone);
    serve_and_fetch(&clone, Path::new(args[out_flag + 1]));
}

/// Runs the clone's `viewer/web/build.sh` (the README's second step) into a target folder of its
/// own under this repository's `target/` (kept between runs, so only changed crates rebuild),
/// with the wasm-bindgen-cli this repository's build installed (no registry needed).
fn build_web_viewer(repo: &Path, clone: &Path) {
    let tools = repo.join("target/tools");
    assert!(
        tools.join("bin/wasm-bindgen").is_file(),
        "target/tools/bin/wasm-bindgen is missing: run viewer/web/build.sh first (.ci/run does)"
    );
    let target = repo.join("target/plain-clone");
    std::fs::create_dir_all(target.join("tools/bin")).unwrap();
    std::fs::copy(
        tools.join("bin/wasm-bindgen"),
        target.join("tools/bin/wasm-bindgen"),
    )
    .unwrap();
    let o = Command::new("bash")
        .arg(clone.join("viewer/web/build.sh"))
        .current_dir(clone)
        .env("CARGO_TARGET_DIR", &target)
        .env("CARGO_INCREMENTAL", "0")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "build.sh in the clone: {out}\n{err}");
    assert!(out.contains("web viewer built"), "{out}");
    assert!(
        clone
            .join("viewer/web/pkg/splat2tiles_web_bg.wasm")
            .is_file()
    );
}

/// `view` of the clone's output with the clone's viewer: it prints the page and serves the
/// page, the wasm and the tileset.
fn serve_and_fetch(clone: &Path, out: &Path) {
    use std::io::{BufRead, BufReader, Read, Write};
    let mut child = Command::new(bin())
        .arg("view")
        .arg(out)
        .args(["--port", "0", "--no-open", "--quiet", "--web-dir"])
        .arg(clone.join("viewer/web"))
        .current_dir(clone)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
    let page = lines
        .by_ref()
        .map_while(Result::ok)
        .find_map(|l| l.strip_prefix("viewer: ").map(str::to_string));
    let Some(page) = page else {
        let _ = child.kill();
        panic!("view printed no viewer line");
    };
    let addr = page
        .trim_start_matches("http://")
        .split('/')
        .next()
        .unwrap()
        .to_string();
    for path in [
        "/viewer/index.html",
        "/viewer/pkg/splat2tiles_web_bg.wasm",
        "/tileset.json",
    ] {
        let mut s = std::net::TcpStream::connect(&addr).unwrap();
        write!(
            s,
            "GET {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n"
        )
        .unwrap();
        let mut answer = Vec::new();
        s.read_to_end(&mut answer).unwrap();
        let head = String::from_utf8_lossy(&answer[..answer.len().min(64)]).into_owned();
        assert!(head.starts_with("HTTP/1.1 200"), "{path}: {head}");
    }
    let _ = child.kill();
    let _ = child.wait();
}

/// Nothing the tests, examples, benches, tools or CI read lies outside the repository: no source
/// names the shared-data folder beside the clone or the machine's copy of it under `/work`.
/// Comments may (they say where data came from); code, strings and scripts may not.
#[test]
fn no_source_reads_outside_the_repository() {
    // Split so that this file does not name them.
    const NEEDLES: [&str; 2] = [concat!("..", "/shared"), concat!("/work", "/shared")];
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut found = Vec::new();
    let roots = [
        "tests", "src", "crates", "viewer", "tools", "fuzz", "scripts", ".ci",
    ];
    let mut stack: Vec<std::path::PathBuf> = roots.iter().map(|r| repo.join(r)).collect();
    while let Some(p) = stack.pop() {
        let name = p.file_name().map(|n| n.to_string_lossy().into_owned());
        if matches!(
            name.as_deref(),
            Some("node_modules" | "target" | "pkg" | "data")
        ) {
            continue;
        }
        if p.is_dir() {
            stack.extend(std::fs::read_dir(&p).unwrap().flatten().map(|e| e.path()));
            continue;
        }
        let ext = p.extension().and_then(|e| e.to_str()).unwrap_or_default();
        let code = ["rs", "mjs", "js", "sh", "py", "html", "toml"].contains(&ext)
            || p.parent().and_then(Path::file_name) == Some(std::ffi::OsStr::new(".ci"));
        let Ok(text) = std::fs::read_to_string(&p) else {
            continue;
        };
        if !code {
            continue;
        }
        for (i, line) in text.lines().enumerate() {
            let body = line.trim_start();
            let comment = ["//", "#", "*", "/*", "<!--"]
                .iter()
                .any(|c| body.starts_with(c));
            if !comment && NEEDLES.iter().any(|n| line.contains(n)) {
                found.push(format!("{}:{}: {}", p.display(), i + 1, line.trim()));
            }
        }
    }
    assert!(
        found.is_empty(),
        "outside the repository:\n{}",
        found.join("\n")
    );
}
