#!/bin/bash
# Sharded conversion benchmark (BENCHMARKS.md "Sharded conversion"): one single-machine run and
# Ray runs in 1, 2 and 4 parts of INPUT, each output compared file by file with the single run.
# Usage: tools/shard_bench.sh INPUT [WORKDIR] (needs target/release/splat2tiles and Ray in
# target/ray-venv, as .ci/run installs it; WORKDIR, default target/tmp-big/shard, is emptied).
set -u
ROOT=$(cd "$(dirname "$0")/.." && pwd)
IN=$(realpath "$1")
D=${2:-$ROOT/target/tmp-big/shard}
B=$ROOT/target/release/splat2tiles
PY=$ROOT/target/ray-venv/bin/python
rm -rf "$D"; mkdir -p "$D"; cd "$D" || exit 2
echo "== single $(date -u +%T) load $(cut -d' ' -f1-3 /proc/loadavg)"
/usr/bin/time -v "$B" convert "$IN" -o single --memory-limit 2GiB --json -q > single.json 2> single.time
grep -E "Elapsed|Maximum resident" single.time
(cd single && find . -type f | sort | xargs sha256sum) > single.sha
for spec in "1 2" "2 1" "4 1"; do
  set -- $spec; N=$1; C=$2
  echo "== $N parts $(date -u +%T) load $(cut -d' ' -f1-3 /proc/loadavg)"
  t0=$(date +%s.%N)
  RAY_memory_monitor_refresh_ms=0 "$PY" "$ROOT/tools/splat2tiles_ray.py" "$IN" -o out$N --parts $N \
    --work work$N --binary "$B" --memory-limit 2GiB --num-cpus 2 --cpus-per-task $C --json \
    > ray$N.json 2> ray$N.err
  echo "rc $? wall $(python3 -c "print(round($(date +%s.%N) - $t0, 1))")"
  (cd out$N && find . -type f | sort | xargs sha256sum) > out$N.sha
  cmp -s single.sha out$N.sha && echo "identical to single" || echo "DIFFERS from single"
  rm -rf out$N work$N
done
rm -rf single
echo "== done $(date -u +%T); step reports in $D/ray*.json"
