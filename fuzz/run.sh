#!/bin/sh
# Runs every fuzz target for SECONDS (default 300) one at a time on one core, seeding each corpus
# from fuzz/seeds/<target>/; logs go to fuzz/logs/<target>.log. Needs cargo-fuzz; on a stable
# toolchain RUSTC_BOOTSTRAP=1 lets cargo-fuzz pass its -Z sanitizer flags.
set -eu
cd "$(dirname "$0")"
SECONDS_PER_TARGET="${1:-300}"
mkdir -p logs
for t in ${TARGETS:-ply spz splat glb subtree tileset limited http_head output_marker plan part samples loader}; do
  mkdir -p "corpus/$t"
  cp -n seeds/$t/* "corpus/$t/" 2>/dev/null || true
  RUSTC_BOOTSTRAP=1 cargo fuzz run -O "$t" "corpus/$t" -- \
    -max_total_time="$SECONDS_PER_TARGET" -jobs=1 -workers=1 -max_len=65536 -rss_limit_mb=2048 \
    > "logs/$t.log" 2>&1 || echo "$t: fuzzer exited with $? (see fuzz/logs/$t.log)"
  # With -jobs, libFuzzer writes the job's own output to fuzz-0.log.
  [ -f fuzz-0.log ] && mv fuzz-0.log "logs/$t.job.log"
  grep -hE "(DONE|Done [0-9]+ runs|ERROR|SUMMARY|crash-)" "logs/$t.log" "logs/$t.job.log" 2>/dev/null | tail -3 || true
done
