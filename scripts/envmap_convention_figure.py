"""Draw docs/images/envmap-convention.png: the run's lat-long layout against Blender's.

    python3 -m pip install matplotlib && python3 scripts/envmap_convention_figure.py

Top: relight-cpc's lat-long map (envmaps/NAME.latlong.exr, render --env): column 0 at
azimuth 0 (+X), azimuth growing to the right through +Y, -X, -Y; row 0 straight up (+Z).
Bottom: the same directions in Blender's world image (export --envmaps): +X at the centre,
azimuth growing to the left. Formulas in docs/envmap-convention.md.
"""
import math
import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

AXES = [("+X", 0.0, "tab:red"), ("+Y", 90.0, "tab:green"), ("-X", 180.0, "tab:red"), ("-Y", 270.0, "tab:green")]


def ours(phi_deg):
    return (phi_deg / 360.0) % 1.0


def blender(phi_deg):
    return (0.5 - phi_deg / 360.0) % 1.0


fig, axs = plt.subplots(2, 1, figsize=(9, 6.4))
for ax, (title, col) in zip(axs, [("relight-cpc lat-long (run's envmaps/, render --env)", ours),
                                  ("Blender world image (export --envmaps)", blender)]):
    ax.set_xlim(0, 1)
    ax.set_ylim(1, 0)
    ax.set_title(title)
    ax.axhline(0.5, color="0.6", lw=1, ls="--")
    ax.text(0.005, 0.49, "horizon (θ = 90°)", fontsize=8, color="0.4", va="bottom")
    ax.text(0.5, 0.04, "up: +Z (e_z, world up), row 0", ha="center", va="top", fontsize=9)
    ax.text(0.5, 0.97, "down: -Z, last row", ha="center", va="bottom", fontsize=9)
    for name, phi, c in AXES:
        u = col(phi)
        ax.axvline(u, color=c, lw=1.5)
        ax.text(u + 0.005, 0.6, f"{name}\nφ = {phi:.0f}°", color=c, fontsize=10)
    # Azimuth direction arrow.
    a, b = col(20.0), col(70.0)
    ax.annotate("", xy=(b, 0.8), xytext=(a, 0.8), arrowprops=dict(arrowstyle="->", lw=2))
    ax.text((a + b) / 2, 0.86, "azimuth φ grows", ha="center", fontsize=9)
    ax.set_xticks([0, 0.25, 0.5, 0.75, 1.0])
    ax.set_xlabel("u (fraction of image width)")
    ax.set_yticks([0, 0.5, 1.0])
    ax.set_ylabel("v (from top)")
fig.tight_layout()
out = os.path.join(os.path.dirname(__file__), "..", "docs", "images", "envmap-convention.png")
fig.savefig(out, dpi=90)
print(out)
