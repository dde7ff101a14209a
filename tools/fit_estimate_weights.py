#!/usr/bin/env python3
"""Refits `variants::estimate::WEIGHTS` from the CSV that the correlation table writes, so the
no-render estimate ranks variants the way the 1280x720 frames do on every scene.

Usage (standard library only):
  cargo test --release --test variants_utility -- --ignored --nocapture correlation_table
  python3 tools/fit_estimate_weights.py target/release/build/../tmp/variants_utility.csv \
      [W_colour W_opacity W_position W_scale W_rotation]

The ranking (the direction of the weight vector) is chosen to maximise the smallest per-scene
Spearman correlation between the estimated loss and 1 - SSIM of the 1280x720 frames (ties broken
by the pooled correlation), by a coordinate search in log space from the given weights, from the
non-negative least-squares fit of the loss to 1 - SSIM, and from each feature alone. The scale
(Spearman does not see it) is then fitted so that exp(-loss) matches the rendered frame-v4
utility in the least-squares sense. It prints the weights, the per-scene correlations, and the
same with each scene left out of the fit (fitted on the others, scored on it).
"""
import csv
import math
import sys

FEATURES = ["f_colour", "f_opacity", "f_position", "f_scale", "f_rotation"]


def ranks(xs):
    """Average ranks (ties share the mean rank), 0-based."""
    order = sorted(range(len(xs)), key=lambda i: xs[i])
    r = [0.0] * len(xs)
    i = 0
    while i < len(order):
        j = i
        while j + 1 < len(order) and xs[order[j + 1]] == xs[order[i]]:
            j += 1
        for k in range(i, j + 1):
            r[order[k]] = (i + j) / 2.0
        i = j + 1
    return r


def pearson(a, b):
    n = len(a)
    if n < 2:
        return float("nan")
    ma, mb = sum(a) / n, sum(b) / n
    cov = sum((x - ma) * (y - mb) for x, y in zip(a, b))
    va = sum((x - ma) ** 2 for x in a)
    vb = sum((y - mb) ** 2 for y in b)
    if va == 0 or vb == 0:
        return 0.0
    return cov / math.sqrt(va * vb)


def spearman(a, b):
    return pearson(ranks(a), ranks(b))


def load(path):
    rows = []
    with open(path, newline="") as f:
        for r in csv.DictReader(f):
            if r["variant"].lower() == "best":
                continue
            feats = [float(r[k]) for k in FEATURES]
            if any(math.isnan(v) for v in feats):
                continue
            rows.append(
                {
                    "scene": r["scene"],
                    "tile": r["key"] + "@" + r["level"],
                    "variant": r["variant"],
                    "f": feats,
                    "ssim": float(r["full_ssim"]),
                    "utility": float(r["utility"]),
                }
            )
    return rows


def loss(row, w):
    return sum(max(v, 0.0) * wk for v, wk in zip(row["f"], w))


def per_scene(rows, w):
    out = {}
    for s in sorted({r["scene"] for r in rows}):
        sel = [r for r in rows if r["scene"] == s]
        # Higher loss should mean lower SSIM: correlate loss with 1 - SSIM.
        out[s] = spearman([loss(r, w) for r in sel], [1.0 - r["ssim"] for r in sel])
    return out


def score(rows, w):
    ps = per_scene(rows, w)
    pooled = spearman([loss(r, w) for r in rows], [1.0 - r["ssim"] for r in rows])
    return (min(ps.values()), pooled)


def nnls_direction(rows):
    """Non-negative least squares of the loss onto 1 - SSIM, on the relative error, by projected
    coordinate descent (5 unknowns)."""
    a = [[v / max(1.0 - r["ssim"], 1e-9) for v in r["f"]] for r in rows]
    b = [1.0] * len(rows)
    w = [0.0] * 5
    for _ in range(2000):
        for k in range(5):
            num = sum(ai[k] * (bi - sum(ai[j] * w[j] for j in range(5) if j != k)) for ai, bi in zip(a, b))
            den = sum(ai[k] * ai[k] for ai in a)
            w[k] = max(0.0, num / den) if den > 0 else 0.0
    return w


def search(rows, starts):
    """Coordinate search in log space maximising (min per-scene Spearman, pooled Spearman)."""
    best_w, best_s = None, None
    for w0 in starts:
        w = [max(v, 0.0) for v in w0]
        if sum(w) == 0:
            continue
        s = score(rows, w)
        step = 4.0
        while step > 1.01:
            improved = False
            for k in range(5):
                for cand in (w[k] * step, w[k] / step, 0.0, (sum(w) / 5.0) if w[k] == 0 else None):
                    if cand is None or cand == w[k]:
                        continue
                    trial = list(w)
                    trial[k] = cand
                    if sum(trial) == 0:
                        continue
                    ts = score(rows, trial)
                    if ts > s:
                        w, s, improved = trial, ts, True
            if not improved:
                step = math.sqrt(step)
        if best_s is None or s > best_s:
            best_w, best_s = w, s
    return best_w, best_s


def fit_scale(rows, w):
    """The factor c minimising sum (exp(-c loss) - utility)^2, by golden-section search on log c."""
    def err(logc):
        c = math.exp(logc)
        return sum((math.exp(-c * loss(r, w)) - r["utility"]) ** 2 for r in rows)

    lo, hi = -30.0, 30.0
    g = (math.sqrt(5) - 1) / 2
    for _ in range(200):
        m1, m2 = hi - g * (hi - lo), lo + g * (hi - lo)
        if err(m1) < err(m2):
            hi = m2
        else:
            lo = m1
    return math.exp((lo + hi) / 2)


def fit(rows, given):
    starts = [nnls_direction(rows)] + [[1.0 if j == k else 0.0 for j in range(5)] for k in range(5)]
    if given:
        starts.insert(0, given)
    w, _ = search(rows, starts)
    c = fit_scale(rows, w)
    return [v * c for v in w]


def in_order(rows, w):
    tiles = {}
    for r in rows:
        tiles.setdefault((r["scene"], r["tile"]), {})[r["variant"].lower()] = math.exp(-loss(r, w))
    ok = sum(1 for t in tiles.values() if 1.0 >= t.get("high", 1) >= t.get("medium", 0) >= t.get("low", 0))
    return ok, len(tiles)


def main():
    if len(sys.argv) < 2:
        print(__doc__)
        sys.exit(2)
    rows = load(sys.argv[1])
    given = [float(v) for v in sys.argv[2:7]] if len(sys.argv) >= 7 else None
    scenes = sorted({r["scene"] for r in rows})
    w = fit(rows, given)
    print("WEIGHTS = [" + ", ".join(f"{v:.6g}" for v in w) + "]  (" + ", ".join(FEATURES) + ")")
    ok, n = in_order(rows, w)
    print(f"tiles in order Best >= High >= Medium >= Low by the estimate: {ok} / {n}")
    print("| scene | Spearman (estimate vs 1280x720 SSIM) | fitted without it | Spearman (estimate vs rendered utility) | mean abs error vs rendered utility |")
    print("|---|---:|---:|---:|---:|")
    for s in scenes:
        sel = [r for r in rows if r["scene"] == s]
        rho = spearman([loss(r, w) for r in sel], [1.0 - r["ssim"] for r in sel])
        w_out = fit([r for r in rows if r["scene"] != s], given)
        rho_out = spearman([loss(r, w_out) for r in sel], [1.0 - r["ssim"] for r in sel])
        rho_u = spearman([-loss(r, w) for r in sel], [r["utility"] for r in sel])
        mae = sum(abs(math.exp(-loss(r, w)) - r["utility"]) for r in sel) / len(sel)
        print(f"| {s} | {rho:.3f} | {rho_out:.3f} | {rho_u:.3f} | {mae:.4f} |")
    pooled = spearman([loss(r, w) for r in rows], [1.0 - r["ssim"] for r in rows])
    pooled_u = spearman([-loss(r, w) for r in rows], [r["utility"] for r in rows])
    mae = sum(abs(math.exp(-loss(r, w)) - r["utility"]) for r in rows) / len(rows)
    print(f"| all | {pooled:.3f} | | {pooled_u:.3f} | {mae:.4f} |")
    if given:
        print("given weights: " + ", ".join(f"{k} {v:.3f}" for k, v in per_scene(rows, given).items()))


if __name__ == "__main__":
    main()
