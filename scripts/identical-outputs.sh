#!/usr/bin/env bash
# Writes the outputs of a fixed set of conversions (default, --variants all, --layers,
# georeferenced, sharded + merge of a generated city) with the binary BIN into OUT, so that two
# builds can be compared byte for byte: `diff -r OUT_A OUT_B`.
# Usage: scripts/identical-outputs.sh BIN OUT
set -euo pipefail
bin=$(realpath "$1")
out=$2
here=$(cd "$(dirname "$0")/.." && pwd)
mkdir -p "$out"
out=$(realpath "$out")
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
plant="$here/samples/plant.splat"
# A generated .splat city: 200,000 splats in 8 x 8 blocks of growing density, towers in every
# 5th block (fixed seed: the same bytes every run).
python3 - "$work/city.splat" <<'PY'
import random, struct, sys
r = random.Random(7)
with open(sys.argv[1], "wb") as f:
    for i in range(200_000):
        b = (i * 2654435761) % 64
        bx, by = (b % 8) * 50.0, (b // 8) * 50.0
        tall = 60.0 if b % 5 == 0 else 8.0
        s = r.uniform(0.02, 0.4)
        f.write(struct.pack("<6f", bx + r.uniform(0, 40), by + r.uniform(0, 40),
                            -r.uniform(0, tall), s, s * 0.8, s * 0.5))
        f.write(bytes([r.randrange(256), r.randrange(256), r.randrange(256), r.randrange(64, 256)]))
        f.write(bytes([r.randrange(256) for _ in range(4)]))
PY
run() { "$bin" "$@" -q; }
run convert "$plant" -o "$out/default"
run convert "$plant" -o "$out/variants-all" --variants all
run convert "$plant" -o "$out/layers" --layers
run convert "$plant" -o "$out/georeferenced" --origin 8.5417,47.3769,400 --profile cesium
run convert "$work/city.splat" -o "$out/city"
run convert "$work/city.splat" --plan "$work/plan.json" --parts 3
parts=()
for i in 0 1 2; do
  run convert "$work/city.splat" --plan "$work/plan.json" --part $i --phase samples -o "$work/s$i"
done
for i in 0 1 2; do
  run convert "$work/city.splat" --plan "$work/plan.json" --part $i -o "$work/p$i" \
    --samples "$work/s0" "$work/s1" "$work/s2"
  parts+=("$work/p$i")
done
run merge "$work/plan.json" "${parts[@]}" -o "$out/city-sharded"
echo "wrote $(find "$out" -type f | wc -l) files under $out"
