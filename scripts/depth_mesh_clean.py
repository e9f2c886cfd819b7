#!/usr/bin/env python3
"""Clean a Poisson surface against the fused points it came from, and optionally shrink it.

Screened Poisson reconstruction (COLMAP's `poisson_mesher`) closes the surface everywhere,
so it invents sheets far from any measured point and small bubbles around stray points.
This step:
1. trims: drops every face with a vertex farther than --trim-factor * s from the nearest
   fused point, where s is the median distance of a fused point to its nearest other fused
   point (the sampling spacing), so the threshold follows the data's own resolution;
2. removes floating components: faces are joined through shared vertices; components with
   fewer than --min-component (fraction of the largest component's faces) are dropped;
3. (with --workspace) crops to what the photos share: a face is kept when each of its
   vertices lies inside the box of the sparse points (those seen by at least 3 photos, 1st to
   99th percentile per axis, widened by --box-margin of the box's size on each side) and
   in front of, inside the image of, and within the sparse points' depth range (1st..99th
   percentile, widened by a factor 1.5) of at least --min-views cameras (a fraction of the
   cameras when below 1). This drops the sky, far background and the sheets Poisson closes
   behind the object, which no photo sees;
   then (after trimming and cropping) components are counted again, --min-component 1
   keeps the largest alone;
4. (optionally) decimates to about --target-faces faces with vertex clustering on a regular
   grid (each cell's vertices merged into their mean; faces that collapse are dropped);
5. drops unreferenced vertices and writes a binary little-endian PLY (x, y, z as float,
   red/green/blue when the input has them, `vertex_indices` as uchar/int lists).

It can also thin a fused point cloud for a small fixture (--thin-points N: N points picked
with a fixed seed, all properties kept) and reports the figures as one JSON line.

Usage: depth_mesh_clean.py MESH_IN MESH_OUT --points FUSED.ply [--trim-factor 4]
       [--min-component 0.05] [--workspace DENSE --min-views 0.5 --box-margin 0.1]
       [--target-faces N] [--thin-points N --thin-out OUT.ply]
Needs numpy and scipy (scripts/requirements-depth.txt).
"""

import argparse
import json
import pathlib
import sys

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
    "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}


def read_ply(path):
    """Vertices as a structured array, faces as an (F, 3) int array (triangles only)."""
    with open(path, "rb") as f:
        data = f.read()
    end = data.find(b"end_header")
    if not data.startswith(b"ply") or end < 0:
        sys.exit(f"{path}: not a PLY file")
    body = data[data.index(b"\n", end) + 1:]
    header = data[:end].decode("ascii", "replace").splitlines()
    fmt, elems = None, []
    for line in header:
        tok = line.split()
        if not tok:
            continue
        if tok[0] == "format":
            fmt = tok[1]
        elif tok[0] == "element":
            elems.append([tok[1], int(tok[2]), []])
        elif tok[0] == "property":
            elems[-1][2].append(tok[1:])
    if fmt not in ("binary_little_endian", "ascii"):
        sys.exit(f"{path}: PLY format {fmt} not handled here")
    verts, faces = None, np.zeros((0, 3), np.int64)
    if fmt == "ascii":
        rows = body.decode().split("\n")
        pos = 0
        for name, n, props in elems:
            lines = rows[pos:pos + n]
            pos += n
            if name == "vertex":
                dt = np.dtype([(p[1], PLY_TYPES[p[0]]) for p in props])
                arr = np.array([tuple(l.split()[: len(props)]) for l in lines], dtype=dt)
                verts = arr
            elif name == "face":
                faces = np.array([[int(x) for x in l.split()[1:4]] for l in lines], np.int64)
        return verts, faces
    pos = 0
    for name, n, props in elems:
        if props and props[0][0] == "list":
            cnt_t, idx_t = PLY_TYPES[props[0][1]], PLY_TYPES[props[0][2]]
            dt = np.dtype([("n", cnt_t), ("v", idx_t, 3)])
            arr = np.frombuffer(body, dtype=dt, count=n, offset=pos)
            if n and np.any(arr["n"] != 3):
                sys.exit(f"{path}: element {name}: only triangles are handled")
            pos += dt.itemsize * n
            if name == "face":
                faces = arr["v"].astype(np.int64)
        else:
            dt = np.dtype([(p[1], "<" + PLY_TYPES[p[0]]) for p in props])
            arr = np.frombuffer(body, dtype=dt, count=n, offset=pos)
            pos += dt.itemsize * n
            if name == "vertex":
                verts = arr
    if verts is None:
        sys.exit(f"{path}: no vertex element")
    return verts, faces


def write_ply(path, verts, faces=None):
    names = verts.dtype.names
    inv = {v: k for k, v in PLY_TYPES.items() if k in ("char", "uchar", "short", "ushort",
                                                       "int", "uint", "float", "double")}
    lines = ["ply", "format binary_little_endian 1.0", f"element vertex {len(verts)}"]
    for nm in names:
        lines.append(f"property {inv[verts.dtype[nm].str[1:]]} {nm}")
    if faces is not None:
        lines += [f"element face {len(faces)}", "property list uchar int vertex_indices"]
    lines.append("end_header")
    with open(path, "wb") as f:
        f.write(("\n".join(lines) + "\n").encode())
        f.write(np.ascontiguousarray(verts).tobytes())
        if faces is not None:
            fd = np.zeros(len(faces), dtype=[("n", "u1"), ("v", "<i4", 3)])
            fd["n"] = 3
            fd["v"] = faces
            f.write(fd.tobytes())


def xyz(arr):
    return np.stack([arr["x"], arr["y"], arr["z"]], 1).astype(np.float64)


def components(nv, faces):
    """Component label per face (faces joined through shared vertices)."""
    nf = len(faces)
    rows = np.repeat(np.arange(nf), 3)
    g = coo_matrix((np.ones(3 * nf), (rows, faces.ravel())), shape=(nf, nv)).tocsr()
    adj = (g @ g.T).tocsr()
    _, lab = connected_components(adj, directed=False)
    return lab


def compact(verts, faces):
    used = np.zeros(len(verts), bool)
    used[faces.ravel()] = True
    remap = -np.ones(len(verts), np.int64)
    remap[used] = np.arange(used.sum())
    return verts[used], remap[faces]


def cluster_decimate(verts, faces, target_faces):
    """Vertex clustering on a grid sized so that about target_faces faces survive."""
    p = xyz(verts)
    lo, hi = p.min(0), p.max(0)
    # Surface meshes: faces ~ 2 * occupied cells; search the cell size by bisection.
    a, b = 1e-6 * np.linalg.norm(hi - lo), np.linalg.norm(hi - lo)
    best = None
    for _ in range(30):
        cell = np.sqrt(a * b)
        key = np.floor((p - lo) / cell).astype(np.int64)
        _, cid = np.unique(key, axis=0, return_inverse=True)
        cid = cid.ravel()
        f2 = cid[faces]
        keep = (f2[:, 0] != f2[:, 1]) & (f2[:, 1] != f2[:, 2]) & (f2[:, 0] != f2[:, 2])
        f2 = np.unique(np.sort(f2[keep], 1), axis=0, return_index=True)[1]
        nf = len(f2)
        best = (cell, cid, keep)
        if abs(nf - target_faces) < 0.05 * target_faces:
            break
        if nf > target_faces:
            a = cell
        else:
            b = cell
    cell, cid, keep = best
    ncl = cid.max() + 1
    out = np.zeros(ncl, dtype=verts.dtype)
    cnt = np.bincount(cid, minlength=ncl).astype(np.float64)
    for nm in verts.dtype.names:
        s = np.bincount(cid, weights=verts[nm].astype(np.float64), minlength=ncl) / cnt
        out[nm] = np.round(s) if verts.dtype[nm].kind in "iu" else s
    fk = cid[faces][keep]
    # Keep the original orientation of each surviving face; drop duplicates.
    _, first = np.unique(np.sort(fk, 1), axis=0, return_index=True)
    return out, fk[np.sort(first)]


def shared_view(p, dense, min_views, box_margin):
    """Boolean per point: inside the sparse points' box and seen by enough cameras."""
    sys.dont_write_bytecode = True  # no __pycache__ left in scripts/
    sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
    from depth_sgbm import read_cameras_bin, read_images_bin, read_points3d_bin

    sp = pathlib.Path(dense) / "sparse"
    cams = read_cameras_bin(sp / "cameras.bin")
    imgs = read_images_bin(sp / "images.bin")
    pts = read_points3d_bin(sp / "points3D.bin")
    seen = {}
    for im in imgs.values():
        for pid in im["point_ids"]:
            seen[pid] = seen.get(pid, 0) + 1
    S = np.array([pts[k] for k, n in seen.items() if n >= 3 and k in pts]).reshape(-1, 3)
    if len(S) < 10:
        S = np.array(list(pts.values())).reshape(-1, 3)
    lo, hi = np.percentile(S, 1, axis=0), np.percentile(S, 99, axis=0)
    pad = box_margin * (hi - lo)
    keep = np.all((p >= lo - pad) & (p <= hi + pad), axis=1)
    need = min_views if min_views >= 1 else max(1, int(np.ceil(min_views * len(imgs))))
    views = np.zeros(len(p), np.int32)
    for im in imgs.values():
        w, h, K = cams[im["cam"]]
        pc = im["R"] @ p.T + im["t"][:, None]
        z = pc[2]
        Xs = np.array([pts[k] for k in im["point_ids"] if k in pts]).reshape(-1, 3)
        zs = (im["R"] @ Xs.T + im["t"][:, None])[2]
        zs = zs[zs > 0]
        zlo, zhi = (np.percentile(zs, 1) / 1.5, np.percentile(zs, 99) * 1.5) if len(zs) else (0, np.inf)
        with np.errstate(divide="ignore", invalid="ignore"):
            u = K[0, 0] * pc[0] / z + K[0, 2]
            v = K[1, 1] * pc[1] / z + K[1, 2]
        views += (z > zlo) & (z < zhi) & (u >= 0) & (u < w) & (v >= 0) & (v < h)
    return keep & (views >= need), need


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("mesh_in")
    ap.add_argument("mesh_out")
    ap.add_argument("--points", required=True)
    ap.add_argument("--trim-factor", type=float, default=4.0)
    ap.add_argument("--min-component", type=float, default=0.05)
    ap.add_argument("--target-faces", type=int, default=0)
    ap.add_argument("--workspace", help="undistorted dense folder (DENSE/sparse/*.bin): crop "
                    "the mesh to what the cameras share")
    ap.add_argument("--min-views", type=float, default=0.5)
    ap.add_argument("--box-margin", type=float, default=0.1)
    ap.add_argument("--thin-points", type=int, default=0)
    ap.add_argument("--thin-out")
    args = ap.parse_args()

    verts, faces = read_ply(args.mesh_in)
    pts, _ = read_ply(args.points)
    P = xyz(pts)
    tree = cKDTree(P)
    spacing = float(np.median(tree.query(P, k=2)[0][:, 1]))
    stats = dict(fused_points=len(P), spacing=spacing, mesh_in_vertices=len(verts),
                 mesh_in_faces=len(faces))

    # 1. Trim far from the points.
    dist = tree.query(xyz(verts))[0]
    thr = args.trim_factor * spacing
    faces = faces[np.all(dist[faces] <= thr, 1)]
    stats["faces_after_trim"] = len(faces)
    # 3. What the photos share (before counting components: the crop can split the surface).
    if args.workspace:
        ok, need = shared_view(xyz(verts), args.workspace, args.min_views, args.box_margin)
        faces = faces[np.all(ok[faces], 1)]
        stats["faces_after_crop"] = len(faces)
        stats["crop_min_views"] = need
    # 2. Floating components.
    if len(faces):
        lab = components(len(verts), faces)
        sizes = np.bincount(lab)
        keep = sizes[lab] >= args.min_component * sizes.max()
        stats["components"] = int(len(sizes))
        stats["components_kept"] = int(np.sum(sizes >= args.min_component * sizes.max()))
        faces = faces[keep]
    verts, faces = compact(verts, faces)
    # 4. Decimation.
    if args.target_faces and len(faces) > args.target_faces:
        verts, faces = cluster_decimate(verts, faces, args.target_faces)
        verts, faces = compact(verts, faces)
    write_ply(args.mesh_out, verts, faces)
    d = tree.query(xyz(verts))[0]
    stats.update(mesh_vertices=len(verts), mesh_faces=len(faces),
                 vertex_to_points_mean=float(d.mean()) if len(d) else None,
                 vertex_to_points_p95=float(np.percentile(d, 95)) if len(d) else None)
    if args.thin_points and args.thin_out:
        rng = np.random.default_rng(7)
        n = min(args.thin_points, len(pts))
        idx = np.sort(rng.choice(len(pts), n, replace=False))
        write_ply(args.thin_out, pts[idx])
        stats["thinned_points"] = n
    print(json.dumps(stats))


if __name__ == "__main__":
    main()
