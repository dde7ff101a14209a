#!/usr/bin/env bash
# Builds the web viewer: the `splat2tiles-web` crate for wasm32 (release), then wasm-bindgen's JS
# glue into viewer/web/pkg/ (what `splat2tiles view` serves at /viewer/). Installs what it needs.
#
# Usage: viewer/web/build.sh [--install [BINDIR]]
#   --install  also copies the built viewer to BINDIR/splat2tiles-web, where an installed
#              `splat2tiles view` finds it (BINDIR: the folder of the `splat2tiles` on PATH, else
#              cargo's install folder, $CARGO_INSTALL_ROOT/bin or ~/.cargo/bin).
set -euo pipefail
root="$(cd "$(dirname "$0")/../.." && pwd)"

install_to=""
case "${1:-}" in
  "") ;;
  --install)
    if [ -n "${2:-}" ]; then
      install_to="$2"
    elif command -v splat2tiles >/dev/null 2>&1; then
      install_to="$(dirname "$(command -v splat2tiles)")"
    else
      install_to="${CARGO_INSTALL_ROOT:-${CARGO_HOME:-$HOME/.cargo}}/bin"
    fi
    case "$install_to" in /*) ;; *) install_to="$PWD/$install_to" ;; esac
    ;;
  -h|--help) sed -n '2,8p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
  *) echo "build.sh: unknown argument '$1' (usage: viewer/web/build.sh [--install [BINDIR]])" >&2; exit 2 ;;
esac
cd "$root"

# Cargo's output folder: CARGO_TARGET_DIR when set (relative to the repository root, as cargo
# takes it from here), else target/.
target_dir="${CARGO_TARGET_DIR:-target}"
case "$target_dir" in /*) ;; *) target_dir="$root/$target_dir" ;; esac

# Each step is announced with the seconds since the start. When stderr is not a terminal (a log,
# CI), where cargo draws no progress bar, a line every 20 s says the step is still running.
started=$SECONDS
step() { echo "build.sh: [$((SECONDS - started)) s] $*"; }
heartbeat=""
start_heartbeat() {
  stop_heartbeat
  if [ ! -t 2 ]; then
    local what="$1"
    (while sleep 20; do echo "build.sh: [$((SECONDS - started)) s] still $what" >&2; done) &
    heartbeat=$!
  fi
}
stop_heartbeat() {
  if [ -n "$heartbeat" ]; then kill "$heartbeat" 2>/dev/null || true; wait "$heartbeat" 2>/dev/null || true; fi
  heartbeat=""
}
trap stop_heartbeat EXIT

# The wasm32 target: installed through rustup when missing; a failure is reported, not hidden.
if ! rustc --print sysroot >/dev/null 2>&1 || \
   [ ! -d "$(rustc --print sysroot)/lib/rustlib/wasm32-unknown-unknown" ]; then
  if ! command -v rustup >/dev/null 2>&1; then
    echo "build.sh: the Rust wasm32-unknown-unknown target is missing and rustup is not installed;" >&2
    echo "build.sh: install Rust with rustup (https://rustup.rs), then rerun" >&2
    exit 1
  fi
  step "adding the Rust wasm32-unknown-unknown target (rustup, about 30 MB)"
  rustup target add wasm32-unknown-unknown || {
    echo "build.sh: 'rustup target add wasm32-unknown-unknown' failed (offline?)" >&2
    exit 1
  }
fi

# wasm-bindgen-cli must be exactly the wasm-bindgen version in Cargo.lock; it is installed once
# into TARGET/tools (no --locked: that pins a webpki-roots version the registry no longer has).
ver=$(awk '$0 == "name = \"wasm-bindgen\"" { getline; gsub(/[^0-9.]/, "", $0); print; exit }' Cargo.lock)
[ -n "$ver" ] || { echo "build.sh: no wasm-bindgen in Cargo.lock" >&2; exit 1; }
tools="$target_dir/tools"
if ! "$tools/bin/wasm-bindgen" --version 2>/dev/null | grep -qF " $ver"; then
  step "installing wasm-bindgen-cli $ver into target/tools (once; about 2 min on 2 cores)"
  start_heartbeat "installing wasm-bindgen-cli"
  # Built unoptimised, without debug info or LTO: 109 s to compile on 2 cores against 230 s at
  # opt-level 1 (285 s with its own profile); on the viewer's wasm it takes 4.5 s instead of
  # 1.4 s and writes byte-identical output (measured on wasm-bindgen 0.2.130).
  CARGO_PROFILE_RELEASE_OPT_LEVEL=0 CARGO_PROFILE_RELEASE_DEBUG=0 CARGO_PROFILE_RELEASE_LTO=false \
    cargo install wasm-bindgen-cli --version "$ver" --root "$tools"
  stop_heartbeat
fi

# No debug info in the shipped wasm (the workspace release profile keeps line tables for perf).
step "building the splat2tiles-web crate for wasm32 (release)"
start_heartbeat "building splat2tiles-web for wasm32"
CARGO_PROFILE_RELEASE_DEBUG=0 cargo build -p splat2tiles-web --release \
  --target wasm32-unknown-unknown
stop_heartbeat
step "generating the JS glue (wasm-bindgen)"
rm -rf viewer/web/pkg.tmp
"$tools/bin/wasm-bindgen" --target web --no-typescript --out-dir viewer/web/pkg.tmp \
  "$target_dir/wasm32-unknown-unknown/release/splat2tiles_web.wasm"
rm -rf viewer/web/pkg && mv viewer/web/pkg.tmp viewer/web/pkg
step "web viewer built: viewer/web/pkg ($(du -sh viewer/web/pkg | cut -f1))"

# The install: index.html and pkg/ into BINDIR/splat2tiles-web, replaced whole (an earlier install
# is recognised by its index.html and pkg/; any other folder of that name is left alone).
if [ -n "$install_to" ]; then
  dest="$install_to/splat2tiles-web"
  if [ -e "$dest" ] && ! { [ -f "$dest/index.html" ] && [ -d "$dest/pkg" ]; }; then
    echo "build.sh: $dest exists and is not an installed web viewer; not replacing it" >&2
    exit 1
  fi
  mkdir -p "$install_to"
  rm -rf "$dest.tmp"
  mkdir "$dest.tmp"
  cp viewer/web/index.html "$dest.tmp/"
  cp -R viewer/web/pkg "$dest.tmp/pkg"
  rm -rf "$dest.old"
  if [ -e "$dest" ]; then mv "$dest" "$dest.old"; fi
  mv "$dest.tmp" "$dest"
  rm -rf "$dest.old"
  step "installed the web viewer into $dest (\`splat2tiles view\` beside it finds it)"
fi
