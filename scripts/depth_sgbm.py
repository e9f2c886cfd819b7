#!/usr/bin/env python3
"""CPU depth and normal maps for a COLMAP dense workspace, written in COLMAP's own format.

Debian's COLMAP 3.8 has no CUDA, so `patch_match_stereo` refuses to run. This script stands in
for it: it reads the undistorted workspace that `image_undistorter` wrote (DENSE/images,
DENSE/sparse in binary form, PINHOLE or SIMPLE_PINHOLE cameras) and writes

    DENSE/stereo/depth_maps/NAME.geometric.bin    (depth = z in the camera frame, 0 = none)
    DENSE/stereo/normal_maps/NAME.geometric.bin   (unit normal in the camera frame, facing it)
    DENSE/stereo/patch-match.cfg                  (each image and the sources it was matched to)

so that `colmap stereo_fusion --input_type geometric` and `poisson_mesher` can follow.

Method (two-view semi-global matching, median-fused; Hirschmueller 2008 as in OpenCV):
0. (--clahe C > 0) Each photo's grey image is equalised by contrast-limited adaptive
   histogram equalisation (Zuiderveld 1994, OpenCV's CLAHE, 8x8 tiles, clip limit C) before
   matching, so that photos under different light and exposure compare by local structure.
1. Neighbours. For reference image i, the sparse points i sees that project inside image j
   (in front of it) are j's covisible points (shared tracks alone are too few when the views
   are far apart). j qualifies with at least --min-shared of them, a median triangulation
   angle in [--min-angle, --max-angle], and a baseline not along either viewing direction
   (the epipole must stay outside the image); its score is the count times
   exp(-((angle - 20 deg) / 20 deg)^2). The best --neighbours are kept.
2. Rectification. Both cameras are rotated into a common frame R_rect whose x axis is the
   baseline C_j - C_i and whose z axis is the mean viewing direction made orthogonal to it;
   a pixel moves by the homography H = K_n R_rect R^T K^-1 (one focal length f for both,
   its own horizontal offset cx per image, one cy). In that frame a point at rectified depth Z
   appears at x_j = x_i - (f b / Z + cx_i - cx_j), i.e. image i is OpenCV's "left" view.
3. Matching. cv2.StereoSGBM (3-way, block 5, uniqueness 10, left-right check 1 px,
   speckle filter) over the disparity range the covisible sparse points predict, widened by
   25% and 16 px on each side.
4. Back-projection. Each pixel (col, row) of image i (pixel index = coordinate, as COLMAP's
   fusion does) is mapped through H_i, its disparity read (nearest), Z = f b / (d - cx_i + cx_j),
   and the depth along its own ray is z = Z / (R_rect R_i^T K_i^-1 [col, row, 1])_z.
5. Fusion per image. The per-pair depths of a pixel are compared with their median m:
   those within --depth-tol * m of it are averaged; a pixel needs --min-consistent of them
   (fewer when the image has fewer usable pairs). Depths outside the sparse points' depth
   range (1st..99th percentile, widened by a factor 1.5) are dropped, and so are pixels
   without texture (grey-level standard deviation over 7x7 below --min-texture).
6. (--geom-views N > 0) Multi-view agreement: a pixel is kept only when the depth maps of at
   least N other views agree with its depth (see geometric_consistency; COLMAP's fusion
   checks the same again with --StereoFusion.min_num_pixels).
7. Normals. The depth map is median-filtered (5x5), back-projected to points P(col, row),
   and n = (dP/dcol x dP/drow) normalised, averaged over 5x5, oriented toward the camera.

COLMAP array format (src/mvs/mat.h, Mat<float>::Write): the text header
"width&height&channels&", then float32 little-endian, channel after channel, each channel
row after row (element (row, col, c) at c*W*H + row*W + col; COLMAP's read_write_dense.py
reads it as a Fortran-order (W, H, C) array, the same layout).

Usage: depth_sgbm.py DENSE_DIR [--neighbours 4] [--min-angle 3] [--max-angle 60] ...
Needs numpy and opencv-python-headless (scripts/requirements-depth.txt).
"""

import argparse
import math
import pathlib
import struct
import sys
import time

import cv2
import numpy as np

# ----------------------------------------------------------------------------------------
# COLMAP binary model (src/base/reconstruction.cc, ReadCamerasBinary / ReadImagesBinary /
# ReadPoints3DBinary).

CAMERA_PARAMS = {0: ("SIMPLE_PINHOLE", 3), 1: ("PINHOLE", 4)}


def read_cameras_bin(path):
    cams = {}
    with open(path, "rb") as f:
        (n,) = struct.unpack("<Q", f.read(8))
        for _ in range(n):
            cam_id, model_id, w, h = struct.unpack("<iiQQ", f.read(24))
            if model_id not in CAMERA_PARAMS:
                sys.exit(f"{path}: camera {cam_id}: model id {model_id} is not PINHOLE or "
                         "SIMPLE_PINHOLE; run image_undistorter first")
            k = CAMERA_PARAMS[model_id][1]
            p = struct.unpack(f"<{k}d", f.read(8 * k))
            if model_id == 0:
                fx = fy = p[0]
                cx, cy = p[1], p[2]
            else:
                fx, fy, cx, cy = p
            K = np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1.0]])
            cams[cam_id] = (int(w), int(h), K)
    return cams


def qvec_to_rot(q):
    w, x, y, z = q
    return np.array([
        [1 - 2 * y * y - 2 * z * z, 2 * x * y - 2 * w * z, 2 * x * z + 2 * w * y],
        [2 * x * y + 2 * w * z, 1 - 2 * x * x - 2 * z * z, 2 * y * z - 2 * w * x],
        [2 * x * z - 2 * w * y, 2 * y * z + 2 * w * x, 1 - 2 * x * x - 2 * y * y],
    ])


def read_images_bin(path):
    imgs = {}
    with open(path, "rb") as f:
        (n,) = struct.unpack("<Q", f.read(8))
        for _ in range(n):
            image_id = struct.unpack("<i", f.read(4))[0]
            q = struct.unpack("<4d", f.read(32))
            t = np.array(struct.unpack("<3d", f.read(24)))
            cam_id = struct.unpack("<i", f.read(4))[0]
            name = b""
            while True:
                c = f.read(1)
                if c in (b"\x00", b""):
                    break
                name += c
            (n2d,) = struct.unpack("<Q", f.read(8))
            pts = np.frombuffer(f.read(24 * n2d), dtype=[("x", "<f8"), ("y", "<f8"), ("id", "<i8")])
            ids = pts["id"][pts["id"] >= 0]
            imgs[image_id] = dict(name=name.decode(), R=qvec_to_rot(q), t=t, cam=cam_id,
                                  point_ids=set(ids.tolist()))
    return imgs


def read_points3d_bin(path):
    pts = {}
    with open(path, "rb") as f:
        (n,) = struct.unpack("<Q", f.read(8))
        for _ in range(n):
            pid = struct.unpack("<Q", f.read(8))[0]
            xyz = struct.unpack("<3d", f.read(24))
            f.read(3 + 8)  # rgb, error
            (tl,) = struct.unpack("<Q", f.read(8))
            f.read(8 * tl)
            pts[pid] = xyz
    return pts


# ----------------------------------------------------------------------------------------
# COLMAP dense arrays (src/mvs/mat.h).


def write_colmap_array(path, arr):
    """arr: (H, W) or (H, W, C) float32; written channel-planar, rows within a channel."""
    if arr.ndim == 2:
        arr = arr[:, :, None]
    h, w, c = arr.shape
    with open(path, "wb") as f:
        f.write(f"{w}&{h}&{c}&".encode())
        f.write(np.ascontiguousarray(np.transpose(arr, (2, 0, 1))).astype("<f4").tobytes())


def read_colmap_array(path):
    data = pathlib.Path(path).read_bytes()
    parts, pos = [], 0
    for _ in range(3):
        end = data.index(b"&", pos)
        parts.append(int(data[pos:end]))
        pos = end + 1
    w, h, c = parts
    arr = np.frombuffer(data[pos:], dtype="<f4").reshape(c, h, w)
    return np.transpose(arr, (1, 2, 0)).squeeze()


# ----------------------------------------------------------------------------------------
# Geometry.


def centre(img):
    return -img["R"].T @ img["t"]


def covisible(a, b, cams, points):
    """Sparse points image a sees that project inside image b, in front of it (N x 3)."""
    X = np.array([points[p] for p in a["point_ids"] if p in points]).reshape(-1, 3)
    w, h, K = cams[b["cam"]]
    pc = b["R"] @ X.T + b["t"][:, None]
    z = pc[2]
    with np.errstate(divide="ignore", invalid="ignore"):
        u = K[0, 0] * pc[0] / z + K[0, 2]
        v = K[1, 1] * pc[1] / z + K[1, 2]
    ok = (z > 0) & (u >= 0) & (u < w) & (v >= 0) & (v < h)
    return X[ok]


def choose_neighbours(imgs, points, cams, args):
    """For each image id: [(score, j, median angle in degrees)], best first."""
    out = {}
    for i, a in imgs.items():
        ci, zi = centre(a), a["R"][2]
        cands = []
        for j, b in imgs.items():
            if j == i:
                continue
            cj, zj = centre(b), b["R"][2]
            X = covisible(a, b, cams, points)
            if len(X) < args.min_shared:
                continue
            ri = X - ci
            rj = X - cj
            cosang = np.sum(ri * rj, 1) / (np.linalg.norm(ri, axis=1) * np.linalg.norm(rj, axis=1))
            ang = math.degrees(math.acos(float(np.clip(np.median(cosang), -1, 1))))
            if not args.min_angle <= ang <= args.max_angle:
                continue
            base = (cj - ci) / np.linalg.norm(cj - ci)
            # Epipole inside the image: the baseline is close to a viewing direction.
            if abs(base @ zi) > math.cos(math.radians(args.min_epipole_angle)) or \
               abs(base @ zj) > math.cos(math.radians(args.min_epipole_angle)):
                continue
            # Prefer many covisible points and a moderate angle (about 20 degrees).
            score = len(X) * math.exp(-((ang - 20.0) / 20.0) ** 2)
            cands.append((score, j, ang))
        cands.sort(reverse=True)
        out[i] = cands[: args.neighbours]
    return out


def rectify_pair(a, b, cams, max_scale):
    """Common rectifying rotation and the two homographies; None when it degenerates."""
    wa, ha, Ka = cams[a["cam"]]
    wb, hb, Kb = cams[b["cam"]]
    ca, cb = centre(a), centre(b)
    base = cb - ca
    bl = float(np.linalg.norm(base))
    ex = base / bl
    z = a["R"][2] + b["R"][2]
    z = z - (z @ ex) * ex
    if np.linalg.norm(z) < 1e-6:
        return None
    z /= np.linalg.norm(z)
    ey = np.cross(z, ex)
    R_rect = np.stack([ex, ey, z])  # world -> rectified
    f = float(np.mean([Ka[0, 0], Ka[1, 1], Kb[0, 0], Kb[1, 1]]))
    rots = [R_rect @ a["R"].T, R_rect @ b["R"].T]  # camera -> rectified
    corners = []
    for (w, h, K), Rr in zip([(wa, ha, Ka), (wb, hb, Kb)], rots):
        c = np.array([[0, 0, 1], [w - 1, 0, 1], [0, h - 1, 1], [w - 1, h - 1, 1.0]]).T
        r = Rr @ np.linalg.inv(K) @ c
        if np.any(r[2] <= 0.1):
            return None
        corners.append(f * r[:2] / r[2])
    ymin = min(c[1].min() for c in corners)
    ymax = max(c[1].max() for c in corners)
    xmins = [c[0].min() for c in corners]
    widths = [c[0].max() - c[0].min() for c in corners]
    W = int(math.ceil(max(widths))) + 1
    H = int(math.ceil(ymax - ymin)) + 1
    if W > max_scale * max(wa, wb) or H > max_scale * max(ha, hb):
        return None
    cy = -ymin
    cxs = [-xmins[0], -xmins[1]]
    Hs = []
    for (w, h, K), Rr, cx in zip([(wa, ha, Ka), (wb, hb, Kb)], rots, cxs):
        Kn = np.array([[f, 0, cx], [0, f, cy], [0, 0, 1.0]])
        Hs.append(Kn @ Rr @ np.linalg.inv(K))
    return dict(R_rect=R_rect, f=f, bl=bl, cy=cy, cx=cxs, H=Hs, size=(W, H))


def pair_depth(a, b, ga, gb, cams, points, rect, args):
    """Depth map of image a (NaN where unknown) from SGBM against image b."""
    wa, ha, Ka = cams[a["cam"]]
    W, H = rect["size"]
    f, bl, dcx = rect["f"], rect["bl"], rect["cx"][0] - rect["cx"][1]
    # Disparity range predicted by the points both images see.
    shared = covisible(a, b, cams, points)
    Z = (rect["R_rect"] @ (shared - centre(a)).T)[2]
    Z = Z[Z > 0]
    if len(Z) < args.min_shared:
        return None
    d = f * bl / Z + dcx
    lo, hi = np.percentile(d, [1, 99])
    pad = 0.25 * (hi - lo) + 16
    dmin = int(math.floor(lo - pad))
    ndisp = int(math.ceil((hi + pad - dmin) / 16.0)) * 16
    ndisp = max(16, min(ndisp, args.max_disparities))
    la = cv2.warpPerspective(ga, rect["H"][0], (W, H), flags=cv2.INTER_LINEAR)
    rb = cv2.warpPerspective(gb, rect["H"][1], (W, H), flags=cv2.INTER_LINEAR)
    bs = args.block_size
    sgbm = cv2.StereoSGBM_create(
        minDisparity=dmin, numDisparities=ndisp, blockSize=bs,
        P1=8 * bs * bs, P2=32 * bs * bs, disp12MaxDiff=1, uniquenessRatio=10,
        speckleWindowSize=100, speckleRange=2, mode=cv2.STEREO_SGBM_MODE_SGBM_3WAY)
    disp = sgbm.compute(la, rb).astype(np.float32) / 16.0
    disp[disp < dmin] = np.nan
    # Every pixel of image a, through H_a into the rectified image.
    cols, rows = np.meshgrid(np.arange(wa, dtype=np.float64), np.arange(ha, dtype=np.float64))
    pix = np.stack([cols.ravel(), rows.ravel(), np.ones(cols.size)])
    q = rect["H"][0] @ pix
    u = (q[0] / q[2]).reshape(ha, wa).astype(np.float32)
    v = (q[1] / q[2]).reshape(ha, wa).astype(np.float32)
    dd = cv2.remap(disp, u, v, interpolation=cv2.INTER_NEAREST, borderMode=cv2.BORDER_CONSTANT,
                   borderValue=float("nan"))
    denom = dd - dcx
    Zr = np.where(denom > 0, f * bl / np.where(denom > 0, denom, 1), np.nan)
    # Depth along the pixel's own ray: z_cam = Z_rect / (R_rect R_a^T K^-1 [c, r, 1])_z.
    ray = np.linalg.inv(Ka) @ pix
    zr = ((rect["R_rect"] @ a["R"].T)[2] @ ray).reshape(ha, wa)
    depth = Zr / zr
    depth[~np.isfinite(depth) | (depth <= 0)] = np.nan
    return depth


def fuse_depths(stack, tol, min_consistent):
    """Per pixel: mean of the estimates within tol * median of the median; NaN if too few."""
    med = np.nanmedian(stack, axis=0)
    ok = np.abs(stack - med[None]) <= tol * med[None]
    ok &= np.isfinite(stack)
    n = ok.sum(0)
    s = np.where(ok, stack, 0).sum(0)
    out = np.where(n >= min_consistent, s / np.maximum(n, 1), np.nan)
    return out


def normals_from_depth(depth, K):
    """Unit normals (H, W, 3) in the camera frame from a depth map (NaN = unknown)."""
    h, w = depth.shape
    d = np.nan_to_num(depth, nan=0.0).astype(np.float32)
    d = cv2.medianBlur(d, 5)
    d[~np.isfinite(depth)] = 0
    cols, rows = np.meshgrid(np.arange(w, dtype=np.float32), np.arange(h, dtype=np.float32))
    X = (cols - K[0, 2]) / K[0, 0] * d
    Y = (rows - K[1, 2]) / K[1, 1] * d
    P = np.stack([X, Y, d], -1)
    dPu = np.zeros_like(P)
    dPv = np.zeros_like(P)
    dPu[:, 1:-1] = P[:, 2:] - P[:, :-2]
    dPv[1:-1] = P[2:] - P[:-2]
    valid = d > 0
    vu = np.zeros_like(valid)
    vv = np.zeros_like(valid)
    vu[:, 1:-1] = valid[:, 2:] & valid[:, :-2]
    vv[1:-1] = valid[2:] & valid[:-2]
    n = np.cross(dPu, dPv)
    n[~(vu & vv & valid)] = 0
    n = cv2.blur(n, (5, 5))
    norm = np.linalg.norm(n, axis=-1, keepdims=True)
    good = (norm[..., 0] > 1e-12) & valid
    n = np.where(good[..., None], n / np.maximum(norm, 1e-12), 0)
    # Orient toward the camera (n . P < 0).
    flip = np.sum(n * P, -1) > 0
    n[flip] *= -1
    return n.astype(np.float32), good


def geometric_consistency(depths, imgs, cams, tol):
    """Per image: how many other views' depth maps agree with each pixel's depth.

    Pixel (col, row) of image i with depth z is lifted to X = R_i^T (z K_i^-1 [col, row, 1]
    - t_i), projected into image j (x_j = K_j (R_j X + t_j)), and agrees with j when j has a
    depth z_j at the nearest pixel and |z_j - (R_j X + t_j)_z| <= tol * z_j (COLMAP's fusion
    makes the same check with its own threshold, Schoenberger et al. 2016, Sec. 4.4)."""
    counts = {}
    for i, di in depths.items():
        a = imgs[i]
        w, h, Ki = cams[a["cam"]]
        rows, cols = np.nonzero(np.isfinite(di))
        cnt = np.zeros(di.shape, np.int32)
        if len(rows) == 0:
            counts[i] = cnt
            continue
        z = di[rows, cols]
        ray = np.linalg.inv(Ki) @ np.stack([cols, rows, np.ones_like(cols)]).astype(np.float64)
        X = a["R"].T @ (ray * z - a["t"][:, None])
        for j, dj in depths.items():
            if j == i:
                continue
            b = imgs[j]
            wj, hj, Kj = cams[b["cam"]]
            pc = b["R"] @ X + b["t"][:, None]
            zj = pc[2]
            with np.errstate(divide="ignore", invalid="ignore"):
                u = np.rint(Kj[0, 0] * pc[0] / zj + Kj[0, 2])
                v = np.rint(Kj[1, 1] * pc[1] / zj + Kj[1, 2])
            inside = (zj > 0) & (u >= 0) & (u < wj) & (v >= 0) & (v < hj)
            idx = np.nonzero(inside)[0]
            dref = dj[v[idx].astype(np.int64), u[idx].astype(np.int64)]
            ok = np.isfinite(dref) & (np.abs(dref - zj[idx]) <= tol * dref)
            np.add.at(cnt, (rows[idx[ok]], cols[idx[ok]]), 1)
        counts[i] = cnt
    return counts


def image_depth(i, imgs, cams, points, gray, neigh, args):
    """Depth map of image i (NaN = none) fused from its pairs, and the pairs used."""
    a = imgs[i]
    w, h, K = cams[a["cam"]]
    depths, used = [], []
    for _, j, ang in neigh[i]:
        rect = rectify_pair(a, imgs[j], cams, args.max_scale)
        if rect is None:
            continue
        dmap = pair_depth(a, imgs[j], gray[i], gray[j], cams, points, rect, args)
        if dmap is None:
            continue
        depths.append(dmap)
        used.append((imgs[j]["name"], ang, float(np.isfinite(dmap).mean())))
    if not depths:
        return np.full((h, w), np.nan), used
    depth = fuse_depths(np.stack(depths), args.depth_tol, min(args.min_consistent, len(depths)))
    # Sparse points' depth range in this view, widened by 1.5: no sky, no far background.
    Xs = np.array([points[p] for p in a["point_ids"] if p in points]).reshape(-1, 3)
    zs = (a["R"] @ Xs.T + a["t"][:, None])[2]
    zs = zs[zs > 0]
    if len(zs):
        lo, hi = np.percentile(zs, [1, 99])
        depth[(depth < lo / 1.5) | (depth > hi * 1.5)] = np.nan
    # No depth where the reference photo has no texture to match (local standard deviation
    # over 7x7 below --min-texture grey levels): SGBM fills such regions (a black
    # background, a blown-out sky) from its smoothness term alone.
    g = gray[i].astype(np.float32)
    mu = cv2.blur(g, (7, 7))
    sd = np.sqrt(np.maximum(cv2.blur(g * g, (7, 7)) - mu * mu, 0))
    depth[sd < args.min_texture] = np.nan
    return depth, used


def read_grey(path, clahe):
    g = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    if g is None:
        sys.exit(f"{path}: cannot read image")
    return clahe.apply(g) if clahe is not None else g


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("dense_dir")
    ap.add_argument("--neighbours", type=int, default=4)
    ap.add_argument("--min-shared", type=int, default=8)
    ap.add_argument("--min-angle", type=float, default=3.0)
    ap.add_argument("--max-angle", type=float, default=60.0)
    ap.add_argument("--min-epipole-angle", type=float, default=25.0)
    ap.add_argument("--max-scale", type=float, default=3.0,
                    help="skip pairs whose rectified image exceeds this multiple of the photo")
    ap.add_argument("--max-disparities", type=int, default=320)
    ap.add_argument("--block-size", type=int, default=5)
    ap.add_argument("--depth-tol", type=float, default=0.02)
    ap.add_argument("--min-consistent", type=int, default=2)
    ap.add_argument("--min-texture", type=float, default=1.0,
                    help="grey-level standard deviation (7x7) below which no depth is kept")
    ap.add_argument("--clahe", type=float, default=0.0,
                    help="contrast-limited histogram equalisation (clip limit; 0 = off) of "
                    "each photo before matching: photos under different light and exposure")
    ap.add_argument("--geom-views", type=int, default=0,
                    help="keep a pixel only when at least this many other views' depth maps "
                    "agree with it (0 = off)")
    ap.add_argument("--geom-tol", type=float, default=0.01,
                    help="relative depth difference within which two views agree")
    args = ap.parse_args()
    cv2.setNumThreads(2)

    dense = pathlib.Path(args.dense_dir)
    sp = dense / "sparse"
    cams = read_cameras_bin(sp / "cameras.bin")
    imgs = read_images_bin(sp / "images.bin")
    points = read_points3d_bin(sp / "points3D.bin")
    (dense / "stereo" / "depth_maps").mkdir(parents=True, exist_ok=True)
    (dense / "stereo" / "normal_maps").mkdir(parents=True, exist_ok=True)
    neigh = choose_neighbours(imgs, points, cams, args)
    clahe = cv2.createCLAHE(clipLimit=args.clahe, tileGridSize=(8, 8)) if args.clahe > 0 else None
    gray = {i: read_grey(dense / "images" / a["name"], clahe) for i, a in imgs.items()}

    order = sorted(imgs, key=lambda i: imgs[i]["name"])
    depths, used = {}, {}
    for i in order:
        t0 = time.time()
        depths[i], used[i] = image_depth(i, imgs, cams, points, gray, neigh, args)
        pairs = "; ".join(f"{n} {ang:.0f}deg {fr:.0%}" for n, ang, fr in used[i])
        print(f"{imgs[i]['name']}: {len(used[i])} pairs [{pairs}] -> depth on "
              f"{np.isfinite(depths[i]).mean():.1%} of pixels ({time.time() - t0:.1f}s)",
              flush=True)
    if args.geom_views > 0:
        t0 = time.time()
        counts = geometric_consistency(depths, imgs, cams, args.geom_tol)
        for i in order:
            before = np.isfinite(depths[i]).mean()
            depths[i][counts[i] < args.geom_views] = np.nan
            print(f"{imgs[i]['name']}: {before:.1%} -> {np.isfinite(depths[i]).mean():.1%} of "
                  f"pixels agree with >= {args.geom_views} other views", flush=True)
        print(f"multi-view consistency: {time.time() - t0:.1f}s")

    cfg_lines = []
    total_valid = 0
    for i in order:
        a = imgs[i]
        K = cams[a["cam"]][2]
        normals, good = normals_from_depth(depths[i], K)
        depth = np.where(good, depths[i], 0).astype(np.float32)
        write_colmap_array(dense / "stereo" / "depth_maps" / f"{a['name']}.geometric.bin", depth)
        write_colmap_array(dense / "stereo" / "normal_maps" / f"{a['name']}.geometric.bin", normals)
        total_valid += int((depth > 0).sum())
        cfg_lines += [a["name"], ", ".join(u[0] for u in used[i]) if used[i] else "__auto__, 20"]
    (dense / "stereo" / "patch-match.cfg").write_text("\n".join(cfg_lines) + "\n")
    fusion_cfg = dense / "stereo" / "fusion.cfg"
    if not fusion_cfg.exists():  # image_undistorter writes it; a copied workspace may lack it
        fusion_cfg.write_text("".join(imgs[i]["name"] + "\n" for i in order))
    print(f"total depth pixels: {total_valid}")
    if total_valid == 0:
        sys.exit("no depth anywhere: the views may be too far apart for two-view stereo")


if __name__ == "__main__":
    main()
