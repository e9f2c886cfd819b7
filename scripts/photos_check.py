#!/usr/bin/env python3
"""Figures of a scripts/photos.sh run, checked against known camera poses when there are any.

Reads OUT/colmap/{registration.json, sparse/0-txt/images.txt, logs/mesh_stats.json},
OUT/timings.tsv and OUT/result/report.json (when `run` finished) and writes one Markdown
file with: photos given / decoded / registered and the ones left out, sparse and mesh
figures, each step's wall and CPU seconds.

With --calibration FILE (lines "NAME P11 .. P34", a 3x4 projection matrix per photo, as the
Buddha dataset's calibration.txt; photos are matched by file stem, since photos_prepare.py
renames PNG sources), the registered camera centres C = -M^-1 p4 (P = [M | p4]) are compared
with COLMAP's (C = -R^T t) after the least-squares similarity that maps COLMAP's onto the
calibration's (Umeyama 1991: rotation from the SVD of the centred cross-covariance, scale
from the variances). Errors are given in % of the rig radius (RMS distance of the reference
centres from their mean), so they do not depend on either frame's units. The check fails
(exit 1) when the largest error exceeds --max-centre-error percent (default 15). Measured on
the 13 Buddha photos (2026-11-25): 0.95% max with one shared camera, 3.05% with one camera per
photo (each focal length and distortion free), 9.2% on examples/buddha-mixed (per-photo
cameras, crops and rescales whose EXIF focal length no longer fits); the limit sits above
that scatter, and a photo registered at a wrong pose is off by a good part of the radius.

Usage: photos_check.py OUT --report FILE.md [--calibration FILE] [--max-centre-error 15]
Needs numpy.
"""

import argparse
import json
import os
import pathlib
import sys

import numpy as np


def qvec_to_rot(q):
    w, x, y, z = q
    return np.array([
        [1 - 2 * y * y - 2 * z * z, 2 * x * y - 2 * w * z, 2 * x * z + 2 * w * y],
        [2 * x * y + 2 * w * z, 1 - 2 * x * x - 2 * z * z, 2 * y * z - 2 * w * x],
        [2 * x * z - 2 * w * y, 2 * y * z + 2 * w * x, 1 - 2 * x * x - 2 * y * y],
    ])


def colmap_centres(images_txt):
    rows = [l for l in images_txt.read_text().splitlines() if l and not l.startswith("#")][0::2]
    out = {}
    for l in rows:
        t = l.split()
        R = qvec_to_rot([float(x) for x in t[1:5]])
        out[pathlib.Path(t[9]).stem] = -R.T @ np.array([float(x) for x in t[5:8]])
    return out


def calibration_centres(path):
    out = {}
    for n, line in enumerate(path.read_text().splitlines(), 1):
        t = line.split()
        if not t or t[0].startswith("#"):
            continue
        if len(t) != 13:
            sys.exit(f"{path}: line {n}: expected a name and 12 numbers, found {len(t)} fields")
        P = np.array([float(x) for x in t[1:]]).reshape(3, 4)
        out[pathlib.Path(t[0]).stem] = -np.linalg.solve(P[:, :3], P[:, 3])
    return out


def similarity(src, dst):
    """s, R, t minimising sum |s R src_i + t - dst_i|^2 (Umeyama)."""
    ms, md = src.mean(0), dst.mean(0)
    a, b = src - ms, dst - md
    U, S, Vt = np.linalg.svd(b.T @ a / len(src))
    D = np.eye(3)
    D[2, 2] = np.sign(np.linalg.det(U @ Vt))
    R = U @ D @ Vt
    s = np.trace(np.diag(S) @ D) / (a ** 2).sum(1).mean()
    return s, R, md - s * R @ ms


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("out")
    ap.add_argument("--report", required=True)
    ap.add_argument("--calibration")
    ap.add_argument("--max-centre-error", type=float, default=15.0)
    ap.add_argument("--command", default="", help="the command that made OUT, for the report")
    args = ap.parse_args()
    out = pathlib.Path(args.out)
    ws = out / "colmap"
    reg = json.loads((ws / "registration.json").read_text())
    mesh = json.loads((ws / "logs" / "mesh_stats.json").read_text())
    lines = ["# photos.sh run: figures", ""]
    if args.command:
        lines += ["Command:", "", "    " + args.command, ""]
    lines += [
        f"- Photos given {reg['photos_given']}, decoded {reg['photos_decoded']}, registered "
        f"{reg['registered']} ({reg['registered_fraction']:.0%}) with {reg['cameras']} cameras.",
        "- Left out: " + (", ".join(reg["unregistered"]) or "none") + "; not decoded: "
        + (", ".join(s["source"] for s in reg["skipped"]) or "none") + ".",
        f"- Fused points {mesh['fused_points']:,}; Poisson mesh {mesh['mesh_in_vertices']:,} "
        f"vertices -> cleaned and cropped {mesh['mesh_vertices']:,} vertices / "
        f"{mesh['mesh_faces']:,} faces in {mesh.get('components_kept', '?')} component(s) "
        f"(of {mesh.get('components', '?')} after trimming and cropping).",
    ]
    failed = False
    if args.calibration:
        ref = calibration_centres(pathlib.Path(args.calibration))
        got = colmap_centres(ws / "sparse" / "0-txt" / "images.txt")
        names = sorted(set(ref) & set(got))
        if len(names) < 3:
            sys.exit(f"{args.calibration}: only {len(names)} registered photos have a pose")
        A = np.array([got[n] for n in names])
        B = np.array([ref[n] for n in names])
        s, R, t = similarity(A, B)
        err = np.linalg.norm((s * (R @ A.T)).T + t - B, axis=1)
        radius = np.sqrt(((B - B.mean(0)) ** 2).sum(1).mean())
        pct = 100 * err / radius
        failed = pct.max() > args.max_centre_error
        lines += [f"- Camera centres against {pathlib.Path(args.calibration).name} "
                  f"({len(names)} photos, similarity-aligned): RMS "
                  f"{np.sqrt((pct ** 2).mean()):.2f}%, max {pct.max():.2f}% of the rig radius "
                  f"({'FAIL' if failed else 'pass'}: limit {args.max_centre_error}%).",
                  "  " + ", ".join(f"{n} {p:.2f}%" for n, p in zip(names, pct))]
    tim = out / "timings.tsv"
    if tim.exists():
        rows = [l.split("\t") for l in tim.read_text().splitlines()[1:] if l.strip()]
        lines += ["", "| step | wall s | CPU s |", "|---|---|---|"]
        lines += [f"| {r[0]} | {r[1]} | {r[2]} |" for r in rows]
        lines += [f"| total | {sum(float(r[1]) for r in rows):.0f} | "
                  f"{sum(float(r[2]) for r in rows):.0f} |"]
        lines += ["", f"Load average when written: {os.getloadavg()[0]:.1f} on {os.cpu_count()} "
                  "cores: on a shared machine the CPU seconds are the comparable figure."]
    rep = out / "result" / "report.json"
    if rep.exists():
        lines += ["", "`run` finished (OUT/result/report.md); its held-out lines:", ""]
        run_out = out / "run.out"
        held = [l for l in run_out.read_text().splitlines() if l.startswith("held out")] \
            if run_out.exists() else []
        lines += ["    " + l for l in held]
    pathlib.Path(args.report).write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
