#!/bin/bash
# Sharded conversion benchmark (BENCHMARKS.md "Sharded conversion"): one single-machine run and
# Ray runs of INPUT in each part count of PARTS, each output compared file by file with the
# single run, and per run the input bytes the steps read (their inputReadBytes) against its size.
# Usage: tools/shard_bench.sh INPUT [WORKDIR] (needs target/release/splat2tiles and Ray in
# target/ray-venv, as .ci/run installs it; WORKDIR, default target/tmp-big/shard, is emptied).
# PARTS (default "1 2 4"): part counts, one CPU per task except 2 for a single part;
# ROUTE (default: the driver's, one routing task per part): --route-chunks, 0 for no routing.
set -u
ROOT=$(cd "$(dirname "$0")/.." && pwd)
IN=$(realpath "$1")
D=${2:-$ROOT/target/tmp-big/shard}
B=$ROOT/target/release/splat2tiles
PY=$ROOT/target/ray-venv/bin/python
PARTS=${PARTS:-1 2 4}
ROUTE_ARGS=()
[ -n "${ROUTE:-}" ] && ROUTE_ARGS=(--route-chunks "$ROUTE")
rm -rf "$D"; mkdir -p "$D"; cd "$D" || exit 2
echo "== single $(date -u +%T) load $(cut -d' ' -f1-3 /proc/loadavg)"
/usr/bin/time -v "$B" convert "$IN" -o single --memory-limit 2GiB --json -q > single.json 2> single.time
grep -E "Elapsed|Maximum resident" single.time
(cd single && find . -type f | sort | xargs sha256sum) > single.sha
for N in $PARTS; do
  C=1; [ "$N" = 1 ] && C=2
  echo "== $N parts $(date -u +%T) load $(cut -d' ' -f1-3 /proc/loadavg)"
  t0=$(date +%s.%N)
  RAY_memory_monitor_refresh_ms=0 "$PY" "$ROOT/tools/splat2tiles_ray.py" "$IN" -o out$N --parts $N \
    --work work$N --binary "$B" --memory-limit 2GiB --num-cpus 2 --cpus-per-task $C \
    "${ROUTE_ARGS[@]}" --json > ray$N.json 2> ray$N.err
  echo "rc $? wall $(python3 -c "print(round($(date +%s.%N) - $t0, 1))")"
  (cd out$N && find . -type f | sort | xargs sha256sum) > out$N.sha
  cmp -s single.sha out$N.sha && echo "identical to single" || echo "DIFFERS from single"
  python3 - "$IN" ray$N.json <<'PY'
import json, os, sys
size = os.path.getsize(sys.argv[1])
r = json.load(open(sys.argv[2]))
steps = [r["plan"], *r.get("route", []), *r["samples"], *r["build"], r["merge"]]
read = sum(s.get("inputReadBytes", 0) for s in steps)
rchar = sum(s.get("readBytes") or 0 for s in steps)
span = lambda k: "-".join(f"{v:.1f}" for v in sorted({min(s["seconds"] for s in r[k]), max(s["seconds"] for s in r[k])})) if r.get(k) else "-"
print(f"input read {read} of {size} bytes ({read / size:.3f}x); all steps rchar {rchar / 1e9:.2f} GB; "
      f"plan {r['plan']['seconds']:.1f} s, route {span('route')} s, samples {span('samples')} s, "
      f"build {span('build')} s per task, merge {r['merge']['seconds']:.1f} s; "
      f"driver {r['seconds']['total']:.1f} s")
PY
  rm -rf out$N work$N
done
rm -rf single
echo "== done $(date -u +%T); step reports in $D/ray*.json"
