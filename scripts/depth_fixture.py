#!/usr/bin/env python3
"""Copy the small parts of a colmap_workspace.sh result into a test fixture (< 3 MB).

Kept as they are: dense/images/ (undistorted photos), dense/sparse/ (binary only: the text
copy of the 2D points alone would be ~1 MB), dense/stereo/{fusion,patch-match}.cfg, one depth map (the image with the
most depth pixels) so tests can read COLMAP's array format, COLMAP's model_analyzer log, the
timings and summary.json.
Made smaller, with the way stated in the fixture's README:
- dense/fused.ply: --points points drawn without replacement (numpy seed 7), all properties;
- dense/meshed-poisson.ply: vertex-clustered to about --faces faces
  (scripts/depth_mesh_clean.py, cluster_decimate).

Usage: depth_fixture.py WORKSPACE FIXTURE_DIR [--points 15000] [--faces 12000]
                        [--calibration FILE]
"""

import argparse
import json
import pathlib
import shutil
import sys

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import depth_mesh_clean as mc  # noqa: E402
import depth_sgbm as ds  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("workspace")
    ap.add_argument("fixture")
    ap.add_argument("--points", type=int, default=15000)
    ap.add_argument("--faces", type=int, default=12000)
    ap.add_argument("--calibration", help="a calibration file to copy beside (tests compare)")
    args = ap.parse_args()
    ws, fx = pathlib.Path(args.workspace), pathlib.Path(args.fixture)
    for sub in ("dense", "logs"):
        shutil.rmtree(fx / sub, ignore_errors=True)
    (fx / "dense" / "images").mkdir(parents=True)
    (fx / "dense" / "sparse").mkdir(parents=True)
    (fx / "dense" / "stereo" / "depth_maps").mkdir(parents=True)
    (fx / "logs").mkdir(parents=True)
    for p in sorted((ws / "dense" / "images").iterdir()):
        shutil.copy2(p, fx / "dense" / "images" / p.name)
    for p in sorted((ws / "dense" / "sparse").glob("*.bin")):
        shutil.copy2(p, fx / "dense" / "sparse" / p.name)
    for name in ("fusion.cfg", "patch-match.cfg"):
        shutil.copy2(ws / "dense" / "stereo" / name, fx / "dense" / "stereo" / name)
    best, best_n = None, -1
    for p in sorted((ws / "dense" / "stereo" / "depth_maps").glob("*.geometric.bin")):
        n = int((ds.read_colmap_array(p) > 0).sum())
        if n > best_n:
            best, best_n = p, n
    shutil.copy2(best, fx / "dense" / "stereo" / "depth_maps" / best.name)
    for name in ("26-model_analyzer.log", "timings.tsv", "mesh_stats.json"):
        shutil.copy2(ws / "logs" / name, fx / "logs" / name)
    shutil.copy2(ws / "summary.json", fx / "logs" / "summary.json")

    if args.calibration:
        shutil.copy2(args.calibration, fx / pathlib.Path(args.calibration).name)
    pts, _ = mc.read_ply(ws / "dense" / "fused.ply")
    rng = np.random.default_rng(7)
    n = min(args.points, len(pts))
    idx = np.sort(rng.choice(len(pts), n, replace=False))
    mc.write_ply(fx / "dense" / "fused.ply", pts[idx])
    verts, faces = mc.read_ply(ws / "dense" / "meshed-poisson.ply")
    if len(faces) > args.faces:
        verts, faces = mc.cluster_decimate(verts, faces, args.faces)
        verts, faces = mc.compact(verts, faces)
    mc.write_ply(fx / "dense" / "meshed-poisson.ply", verts, faces)
    size = sum(p.stat().st_size for p in fx.rglob("*") if p.is_file())
    print(json.dumps(dict(fused_points_kept=n, fused_points_total=len(pts),
                          mesh_vertices=len(verts), mesh_faces=len(faces),
                          depth_map=best.name, fixture_bytes=size)))


if __name__ == "__main__":
    main()
