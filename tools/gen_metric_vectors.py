#!/usr/bin/env python3
"""Generates tests/data/render/metric_vectors.json: small deterministic RGB image pairs and the
SSIM/PSNR scikit-image gives for them (the reference the Rust metrics are tested against).

Usage: pip install scikit-image numpy && python3 tools/gen_metric_vectors.py
SSIM call: structural_similarity(a, b, gaussian_weights=True, sigma=1.5,
use_sample_covariance=False, data_range=1.0, channel_axis=2); PSNR: peak_signal_noise_ratio(a, b,
data_range=1.0). Images are float64 in [0, 1], rounded to 4 decimals before scoring so that the
JSON holds exactly the values scored.
"""
import json
import os

import numpy as np
import skimage
from skimage.metrics import peak_signal_noise_ratio, structural_similarity


def pattern(h, w, phase):
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    r = 0.5 + 0.4 * np.sin(0.35 * x + phase) * np.cos(0.23 * y)
    g = (x + 2 * y) / (w + 2 * h)
    b = 0.5 + 0.5 * np.sin(0.1 * x * y + phase)
    return np.stack([r, g, b], axis=2)


def clip_round(a):
    return np.round(np.clip(a, 0.0, 1.0), 4)


def main():
    rng = np.random.default_rng(20240611)
    cases = []
    h, w = 20, 24
    base = clip_round(pattern(h, w, 0.0))
    cases.append(("pattern_vs_noisy", base, clip_round(base + rng.normal(0, 0.05, base.shape))))
    cases.append(("pattern_vs_shifted", base, clip_round(base * 0.8 + 0.1)))
    cases.append(("pattern_vs_phase", base, clip_round(pattern(h, w, 0.7))))
    cases.append(("random_vs_random", clip_round(rng.random((h, w, 3))), clip_round(rng.random((h, w, 3)))))
    flat = np.full((h, w, 3), 0.3)
    cases.append(("flat_vs_near_flat", clip_round(flat), clip_round(flat + rng.normal(0, 0.01, flat.shape))))
    small = clip_round(pattern(11, 13, 0.3))
    cases.append(("small_11x13", small, clip_round(small[::-1, :, :] * 0.9)))
    out = {
        "generator": "tools/gen_metric_vectors.py",
        "scikit_image": skimage.__version__,
        "numpy": np.__version__,
        "cases": [],
    }
    for name, a, b in cases:
        ssim = structural_similarity(a, b, gaussian_weights=True, sigma=1.5,
                                     use_sample_covariance=False, data_range=1.0, channel_axis=2)
        psnr = peak_signal_noise_ratio(a, b, data_range=1.0)
        out["cases"].append({
            "name": name,
            "height": a.shape[0],
            "width": a.shape[1],
            "a": [round(float(v), 4) for v in a.reshape(-1)],
            "b": [round(float(v), 4) for v in b.reshape(-1)],
            "ssim": float(ssim),
            "psnr": float(psnr),
        })
    path = os.path.join(os.path.dirname(__file__), "..", "tests", "data", "render", "metric_vectors.json")
    with open(path, "w") as f:
        json.dump(out, f, separators=(",", ":"))
        f.write("\n")
    for c in out["cases"]:
        print(f'{c["name"]}: ssim={c["ssim"]:.6f} psnr={c["psnr"]:.4f}')


if __name__ == "__main__":
    main()
