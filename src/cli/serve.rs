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
    /// The web viewer's folder (`index.html` and the wasm-bindgen output in `pkg/`).
    #[arg(long, default_value = concat!(env!("CARGO_MANIFEST_DIR"), "/viewer/web"))]
    pub web_dir: PathBuf,
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

/// Checks that `web` holds a built viewer: `index.html` and the wasm-bindgen `pkg/`.
pub fn check_web_dir(web: &Path) -> anyhow::Result<()> {
    let how = "build it with `viewer/web/build.sh` (wasm-bindgen output goes to viewer/web/pkg/), \
               or point --web-dir at a built viewer";
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

/// Runs `view`.
pub fn run_view(args: &ViewArgs) -> anyhow::Result<()> {
    if !args.dir.join("tileset.json").is_file() {
        bail!(
            "{}: no tileset.json here; convert a scene first (`splat2tiles convert SCENE -o {}`)",
            args.dir.display(),
            args.dir.display()
        );
    }
    check_web_dir(&args.web_dir)?;
    let mounts = vec![
        Mount::new("/", &args.dir)?,
        Mount::new("/viewer/", &args.web_dir)?,
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
