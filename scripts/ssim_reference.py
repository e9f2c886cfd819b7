#!/usr/bin/env python3
"""Reference SSIM values from scikit-image for src/report/metrics.rs's tests.

Writes tests/fixtures/metrics/ssim_reference.json: two small images given by closed-form
patterns (no random numbers, values rounded to 6 decimals before use, so the Rust test
reads exactly the inputs scikit-image saw) and scikit-image's

    structural_similarity(a, b, gaussian_weights=True, sigma=1.5,
                          use_sample_covariance=False, data_range=1, full=True)

for a grey pair (the full SSIM map and its mean) and for an RGB pair (channel_axis=2,
the mean). scikit-image's mean leaves out a border of (11 - 1) / 2 = 5 pixels; its map
mirrors the image at its borders (scipy.ndimage mode 'reflect'). The Rust test compares
its map to within 1e-9 (float64 both sides; the filters sum the same 11 taps in another
order, so only rounding differs).

Versions used: Python 3.11, scikit-image 0.26.0, scipy 1.17.1, numpy 2.4.6
(`pip install scikit-image==0.26.0`). Run from the repository root:

    python3 scripts/ssim_reference.py
"""

import json
import math
import pathlib

import numpy as np
import skimage
from skimage.metrics import structural_similarity

OUT = pathlib.Path("tests/fixtures/metrics/ssim_reference.json")


def pattern(w, h, phase):
    """A smooth pattern with fine detail in [0, 1]."""
    img = np.zeros((h, w))
    for y in range(h):
        for x in range(w):
            v = 0.5 + 0.3 * math.sin(0.7 * x + 0.3 * y + phase) * math.cos(0.45 * y - phase)
            v += 0.15 * math.cos(1.9 * x - 1.1 * y + 2 * phase)
            img[y, x] = min(1.0, max(0.0, v))
    return np.round(img, 6)


def main():
    w, h = 24, 20
    a = pattern(w, h, 0.0)
    b = np.round(np.clip(0.8 * a + 0.1 + 0.05 * pattern(w, h, 1.3), 0, 1), 6)
    kw = dict(gaussian_weights=True, sigma=1.5, use_sample_covariance=False, data_range=1)
    mean, full = structural_similarity(a, b, full=True, **kw)

    rw, rh = 16, 14
    ra = np.stack([pattern(rw, rh, p) for p in (0.2, 0.9, 1.7)], axis=2)
    rb = np.stack([pattern(rw, rh, p) for p in (0.3, 0.7, 2.0)], axis=2)
    rmean = structural_similarity(ra, rb, channel_axis=2, **kw)

    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(json.dumps({
        "generator": "scripts/ssim_reference.py",
        "skimage": skimage.__version__,
        "grey": {
            "width": w, "height": h,
            "a": a.flatten().tolist(), "b": b.flatten().tolist(),
            "map": full.flatten().tolist(), "mean": float(mean),
        },
        "rgb": {
            "width": rw, "height": rh,
            "a": ra.flatten().tolist(), "b": rb.flatten().tolist(),
            "mean": float(rmean),
        },
    }) + "\n")
    print(f"wrote {OUT}: grey mean {mean:.6f}, rgb mean {rmean:.6f}")


if __name__ == "__main__":
    main()
