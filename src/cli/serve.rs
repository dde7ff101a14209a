//! `splat2tiles serve` and `splat2tiles view`: serve a tileset folder over HTTP (and, for `view`,
//! the web viewer at `/viewer/`), print the URL, and run until Ctrl-C.

use anyhow::{Context, bail};
use clap::Args;
use splat2tiles_serve::{Mount, ServeError, ServeOptions, Server};
use std::io::Write;
use std::net::{IpAddr, Ipv4Addr, SocketAddr};
use std::path::{Path, PathBuf};

/// Most connections kept at once, one thread each (browsers keep 6 per host open and idle);
/// when full, waiting connections are evicted (`serve::admission`).
const THREADS: usize = 512;
/// Most of them one client address may have busy answering at once: clients of one address
/// that read slowly leave the other three quarters to everyone else.
const PER_ADDRESS: usize = THREADS / 4;
/// The port `view` tries first when none is given.
const VIEW_PORT: u16 = 8080;

/// Arguments of `serve`.
#[derive(Debug, Args)]
pub struct ServeArgs {
    /// The folder to serve (a converted tileset).
    pub dir: PathBuf,
    /// Port to listen on; 0 picks a free one (printed).
    #[arg(long, default_value_t = 8080)]
    pub port: u16,
    /// Address to listen on; loopback unless given (e.g. `--bind 0.0.0.0` for the network).
    #[arg(long, default_value_t = IpAddr::V4(Ipv4Addr::LOCALHOST))]
    pub bind: IpAddr,
    /// No log line per request.
    #[arg(short, long)]
    pub quiet: bool,
}

/// Arguments of `view`.
#[derive(Debug, Args)]
pub struct ViewArgs {
    /// The tileset folder (holding `tileset.json`).
    pub dir: PathBuf,
    /// Port to listen on; 0 picks a free one (printed) [default: 8080, or a free port when 8080
    /// is taken, e.g. by another `view`].
    #[arg(long)]
    pub port: Option<u16>,
    /// Address to listen on; loopback unless given.
    #[arg(long, default_value_t = IpAddr::V4(Ipv4Addr::LOCALHOST))]
    pub bind: IpAddr,
    /// Print the URL without opening a browser.
    #[arg(long)]
    pub no_open: bool,
    /// The web viewer's folder (`index.html` and the wasm-bindgen output in `pkg/`)
    /// [default: `splat2tiles-web/` beside the executable (what `viewer/web/build.sh --install`
    /// writes), else `../share/splat2tiles/web` from it, else the source tree's `viewer/web`].
    #[arg(long)]
    pub web_dir: Option<PathBuf>,
    /// No log line per request.
    #[arg(short, long)]
    pub quiet: bool,
}

/// The base URL of a server listening on `addr` (loopback shown for an unspecified address).
fn base_url(addr: SocketAddr) -> String {
    let shown = if addr.ip().is_unspecified() {
        SocketAddr::new(IpAddr::V4(Ipv4Addr::LOCALHOST), addr.port())
    } else {
        addr
    };
    format!("http://{shown}/")
}

/// Binds, prints `lines` (with the URL) on stdout, then serves until Ctrl-C.
fn run_server(
    mounts: Vec<Mount>,
    bind: IpAddr,
    port: u16,
    quiet: bool,
    after_bind: impl FnOnce(&str),
) -> anyhow::Result<()> {
    run_server_fallback(mounts, bind, port, false, quiet, after_bind)
}

/// [`run_server`]; with `fallback`, a taken port is replaced by a free one (with a note).
fn run_server_fallback(
    mounts: Vec<Mount>,
    bind: IpAddr,
    port: u16,
    fallback: bool,
    quiet: bool,
    after_bind: impl FnOnce(&str),
) -> anyhow::Result<()> {
    let opts = |port| ServeOptions {
        bind,
        port,
        quiet,
        threads: THREADS,
        per_address: PER_ADDRESS,
    };
    let server = match Server::bind(mounts.clone(), opts(port)) {
        Err(ServeError::Bind { in_use: true, .. }) if fallback => {
            eprintln!(
                "splat2tiles: port {port} is taken (another `view` or server?); using a free port"
            );
            Server::bind(mounts, opts(0))?
        }
        r => r?,
    };
    let stop = server.stop_handle();
    ctrlc::set_handler(move || stop.stop()).context("cannot install the Ctrl-C handler")?;
    after_bind(&base_url(server.addr()));
    server.run();
    eprintln!("splat2tiles: stopped");
    Ok(())
}

/// Prints a line on stdout and flushes it at once (tests and scripts read the port from it).
fn say(line: &str) {
    let mut out = std::io::stdout().lock();
    let _ = writeln!(out, "{line}");
    let _ = out.flush();
}

/// Runs `serve`.
pub fn run_serve(args: &ServeArgs) -> anyhow::Result<()> {
    let mount = Mount::new("/", &args.dir)?;
    let shown = args.dir.display().to_string();
    run_server(vec![mount], args.bind, args.port, args.quiet, |url| {
        say(&format!("serving {shown} at {url}"));
        if !args.bind.is_loopback() {
            eprintln!(
                "splat2tiles: listening on {} (reachable from the network)",
                args.bind
            );
        }
    })
}

/// How to get a web viewer, for the errors that find none.
const BUILD_VIEWER: &str = "build it in the source tree with `viewer/web/build.sh` (it writes \
    viewer/web/pkg/; `--install` also copies the viewer beside the installed splat2tiles), or \
    point --web-dir at a built viewer";

/// The web viewer's folder: `given`, else the first built one of [`web_dir_candidates`].
pub fn find_web_dir(given: Option<&Path>) -> anyhow::Result<PathBuf> {
    if let Some(web) = given {
        check_web_dir(web)?;
        return Ok(web.to_path_buf());
    }
    let candidates = web_dir_candidates();
    if let Some(found) = candidates.iter().find(|c| check_web_dir(c).is_ok()) {
        return Ok(found.clone());
    }
    let looked: Vec<String> = candidates.iter().map(|c| c.display().to_string()).collect();
    bail!(
        "no built web viewer found (looked in {}); {BUILD_VIEWER}",
        looked.join(", ")
    )
}

/// Where `view` looks for the web viewer, in order: `splat2tiles-web/` beside the executable,
/// `../share/splat2tiles/web` from its folder (a `PREFIX/bin` + `PREFIX/share` install), and the
/// source tree this binary was built from.
pub fn web_dir_candidates() -> Vec<PathBuf> {
    let mut out = Vec::new();
    if let Some(dir) = std::env::current_exe()
        .ok()
        .and_then(|e| std::fs::canonicalize(e).ok())
        .and_then(|e| e.parent().map(Path::to_path_buf))
    {
        out.push(dir.join("splat2tiles-web"));
        if let Some(prefix) = dir.parent() {
            out.push(prefix.join("share/splat2tiles/web"));
        }
    }
    out.push(Path::new(env!("CARGO_MANIFEST_DIR")).join("viewer/web"));
    out
}

/// Checks that `web` holds a built viewer: `index.html` and the wasm-bindgen `pkg/`.
pub fn check_web_dir(web: &Path) -> anyhow::Result<()> {
    let how = BUILD_VIEWER;
    if !web.join("index.html").is_file() {
        bail!(
            "{}: no web viewer here (index.html missing); {how}",
            web.display()
        );
    }
    if !web.join("pkg").is_dir() {
        bail!(
            "{}: the web viewer is not built (pkg/ missing); {how}",
            web.display()
        );
    }
    Ok(())
}

/// The scene files (by extension) directly in `dir`, sorted.
fn scenes_in(dir: &Path) -> Vec<PathBuf> {
    let mut found: Vec<PathBuf> = std::fs::read_dir(dir)
        .into_iter()
        .flatten()
        .flatten()
        .map(|e| e.path())
        .filter(|p| {
            p.is_file()
                && p.extension()
                    .and_then(|e| e.to_str())
                    .is_some_and(|e| ["ply", "splat", "spz"].contains(&&*e.to_ascii_lowercase()))
        })
        .collect();
    found.sort();
    found
}

/// What to run instead of viewing `dir`, which holds no tileset: a command `convert` accepts
/// (it refuses to write into a folder of other files, so those get a fresh output folder).
fn convert_first(dir: &Path, me: &str) -> String {
    let fresh = |stem: &str| Path::new("out").join(stem).display().to_string();
    if let Some(scene) = scenes_in(dir).first() {
        let stem = scene
            .file_stem()
            .map_or_else(|| "scene".into(), |s| s.to_string_lossy().into_owned());
        let out = fresh(&stem);
        return format!(
            "it holds a scene; convert it, then view the result: `{me} convert {} -o {out} && {me} view {out}`",
            scene.display()
        );
    }
    let empty_or_absent = std::fs::read_dir(dir).map_or(true, |mut d| d.next().is_none());
    let out = if empty_or_absent {
        dir.display().to_string()
    } else {
        fresh("scene")
    };
    format!("convert a scene first: `{me} convert SCENE -o {out} && {me} view {out}`")
}

/// Runs `view`.
pub fn run_view(args: &ViewArgs) -> anyhow::Result<()> {
    if !args.dir.join("tileset.json").is_file() {
        bail!(
            "{}: no tileset.json here; {}",
            args.dir.display(),
            convert_first(&args.dir, &super::program())
        );
    }
    let web_dir = find_web_dir(args.web_dir.as_deref())?;
    let mounts = vec![
        Mount::new("/", &args.dir)?,
        Mount::new("/viewer/", &web_dir)?,
    ];
    let shown = args.dir.display().to_string();
    let port = args.port.unwrap_or(VIEW_PORT);
    let fallback = args.port.is_none();
    run_server_fallback(mounts, args.bind, port, fallback, args.quiet, |url| {
        let page = format!("{url}viewer/index.html?tileset=/tileset.json");
        say(&format!("serving {shown} at {url}"));
        say(&format!("viewer: {page}"));
        if !args.no_open {
            open_browser(&page);
        }
    })
}

/// Opens `url` with `$BROWSER` or the platform's opener; on failure only prints a note.
fn open_browser(url: &str) {
    let program = match std::env::var("BROWSER") {
        Ok(b) if !b.trim().is_empty() => b,
        _ if cfg!(target_os = "macos") => "open".to_string(),
        _ => "xdg-open".to_string(),
    };
    let spawned = std::process::Command::new(&program)
        .arg(url)
        .stdin(std::process::Stdio::null())
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn();
    match spawned {
        // Reap it in the background so it does not linger as a zombie.
        Ok(mut child) => {
            std::thread::spawn(move || child.wait());
        }
        Err(e) => eprintln!("splat2tiles: could not open a browser ({program}: {e}); open {url}"),
    }
}
