#!/usr/bin/env python3
"""A differentiable-rendering peer for relight-cpc: Mitsuba 3 (LLVM variant, CPU) fits one
environment map per training photo plus a per-vertex diffuse albedo to the photos of a
COLMAP workspace with Adam, then scores the held-out photos with relight-cpc's `half`
protocol on the same pixels (issue 26, item 4).

Model. Each pixel is rendered by Mitsuba's path-replay integrator (`prb`) with
`max_depth = 2`: direct light only, with shadows, as relight-cpc's model (no
interreflection). The surface is Lambertian with a per-vertex albedo `a_v ∈ [0, 1]³`
(interpolated across triangles, Mitsuba's `mesh_attribute` texture); photo `k` is lit by a
lat-long map `L_k = L0 · e_k`, `e_k ≥ 0` (`L0` = twice the mean observed pixel value, so
that a white surface under `e = 1` matches the photos' mean level; the scale of `e` and `a`
is otherwise free, as in relight-cpc). The emitter is hidden from the camera.

Objective. For the training photos `K`, `Σ_k (1/|K|) · mean_{p ∈ M_k} ‖I_k(p) − y_k(p)‖²`
over the pixels `M_k` that relight-cpc scores: pixel centres whose ray hits the mesh
(relight-cpc rasterises pixel centres) and that are not overexposed (any 8-bit channel at
or above `--clip`, 250 by default, as `relight-cpc run --clip`). Adam (`drjit.opt.Adam`)
on `a` and every `e_k`; after each step `a` is clamped to [0, 1] and `e_k` to ≥ 0.

Held-out photos, protocol `half` (relight-cpc's `src/run/evaluate.rs`): the light is
unknown, so the photo's map is fitted with the albedo frozen, starting from the mean of
the training maps, on the valid pixels left of the middle of the object's bounding box in
x (`mid = (x_min + x_max + 1) / 2` over the pixels whose centre ray hits the mesh); the
error is measured on the valid pixels at or right of `mid`: RMSE over the three channels
after the best global scale `s = Σ y·q / Σ q²` (relight-cpc's `report::compare`), linear
RGB on the photo's [0, 1] scale. relight-cpc fits that light on the vertex observations
whose projection lies left of `mid`; a pixel renderer fits on the pixels left of it.

`--check` validates the workspace and arguments with the Python standard library only
(no Mitsuba), prints what it would do, and exits.

Run through `scripts/mitsuba_baseline.sh`, which installs Mitsuba into `.tools/`.
"""

import argparse
import json
import math
import os
import sys
import time
from pathlib import Path

MITSUBA_VARIANT = "llvm_ad_rgb"


class BaselineError(Exception):
    """A plain-words problem with the input: printed without a traceback."""


# --------------------------------------------------------------------------------------
# Workspace (standard library only, so that --check runs without Mitsuba or numpy)
# --------------------------------------------------------------------------------------


def find_model(root):
    """The sparse model and photo folder, in relight-cpc's order (src/import/workspace.rs):
    dense/sparse + dense/images, sparse + images, sparse/N (lowest N) + images."""
    candidates = [(root / "dense/sparse", root / "dense/images", root / "dense")]
    candidates.append((root / "sparse", root / "images", root / "dense"))
    numbered = sorted(
        (p for p in (root / "sparse").glob("*") if p.is_dir() and p.name.isdigit()),
        key=lambda p: int(p.name),
    )
    candidates += [(p, root / "images", root / "dense") for p in numbered]
    for sparse, images, dense in candidates:
        if (sparse / "cameras.txt").is_file() and (sparse / "images.txt").is_file():
            if not images.is_dir():
                continue
            return sparse, images, dense
        if (sparse / "cameras.bin").is_file():
            raise BaselineError(
                f"{sparse}: the model is in COLMAP's binary format; this script reads the "
                "text format (convert with `colmap model_converter --input_path "
                f"{sparse} --output_path {sparse} --output_type TXT`)"
            )
    raise BaselineError(f"{root}: no COLMAP text model (cameras.txt, images.txt) with its photos")


def read_cameras(path):
    """COLMAP cameras.txt → {id: (width, height, fx, fy, cx, cy)}; pinhole models only."""
    cams = {}
    for lineno, line in enumerate(path.read_text().splitlines(), 1):
        f = line.split()
        if not f or f[0].startswith("#"):
            continue
        try:
            cid, model, w, h = int(f[0]), f[1], int(f[2]), int(f[3])
            prm = [float(x) for x in f[4:]]
        except (ValueError, IndexError):
            raise BaselineError(f"{path}, line {lineno}: not `ID MODEL WIDTH HEIGHT PARAMS...`")
        if model == "SIMPLE_PINHOLE" and len(prm) == 3:
            fx = fy = prm[0]
            cx, cy = prm[1], prm[2]
        elif model == "PINHOLE" and len(prm) == 4:
            fx, fy, cx, cy = prm
        elif model in ("SIMPLE_RADIAL", "RADIAL", "OPENCV") and all(v == 0 for v in prm[4 if model == "OPENCV" else 3 :]):
            fx = prm[0]
            fy = prm[1] if model == "OPENCV" else prm[0]
            cx, cy = (prm[2], prm[3]) if model == "OPENCV" else (prm[1], prm[2])
        else:
            raise BaselineError(
                f"{path}, line {lineno}: camera {cid} is {model} with {len(prm)} parameters; "
                "this script renders pinhole cameras only (undistort the photos first: "
                "`colmap image_undistorter`)"
            )
        if abs(fx - fy) > 1e-3 * fx:
            raise BaselineError(
                f"{path}, line {lineno}: camera {cid} has fx = {fx} and fy = {fy}; Mitsuba's "
                "perspective camera needs square pixels"
            )
        cams[cid] = (w, h, fx, fy, cx, cy)
    return cams


def read_images(path, cams):
    """COLMAP images.txt → [(name, qvec wxyz, tvec, camera id)] in name order."""
    out = []
    lines = path.read_text().splitlines()
    i = 0
    while i < len(lines):
        line = lines[i]
        if not line.strip() or line.startswith("#"):
            i += 1
            continue
        f = line.split()
        try:
            q = [float(x) for x in f[1:5]]
            t = [float(x) for x in f[5:8]]
            cid = int(f[8])
            name = " ".join(f[9:])
        except (ValueError, IndexError):
            raise BaselineError(f"{path}, line {i + 1}: not `ID QW QX QY QZ TX TY TZ CAMERA_ID NAME`")
        if cid not in cams:
            raise BaselineError(f"{path}, line {i + 1}: image {name} uses camera {cid}, not in cameras.txt")
        out.append((name, q, t, cid))
        i += 2  # the POINTS2D line
    return sorted(out, key=lambda r: r[0])


def find_mesh(root, dense, given):
    if given:
        p = Path(given)
        if not p.is_file():
            raise BaselineError(f"{p}: mesh not found")
        return p
    for d in (dense, root):
        for name in ("meshed-poisson.ply", "meshed-delaunay.ply"):
            if (d / name).is_file():
                return d / name
    raise BaselineError(f"{root}: no meshed-poisson.ply or meshed-delaunay.ply (give --mesh)")


def read_json(path):
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError) as e:
        raise BaselineError(f"{path}: not readable JSON ({e})")


def held_out_names(root, names, args):
    """relight-cpc's held-out photos: --holdout, else those of --relight-report, else the
    truth manifest's list, else every 5th photo in name order (the last when that picks
    none and there are two or more; src/run/holdout.rs)."""
    if args.holdout:
        held = [n.strip() for n in args.holdout.split(",") if n.strip()]
        why = "--holdout"
    elif args.relight_report:
        rep = read_json(Path(args.relight_report))
        held = []
        for e in rep.get("holdout", []) if isinstance(rep, dict) else []:
            if isinstance(e, dict) and e.get("image") not in held:
                held.append(e.get("image"))
        why = f"the held-out photos of {args.relight_report}"
    elif (root / "truth/manifest.json").is_file():
        manifest = read_json(root / "truth/manifest.json")
        held = manifest.get("held_out", []) if isinstance(manifest, dict) else []
        why = "truth/manifest.json"
    else:
        held = [n for i, n in enumerate(names) if (i + 1) % 5 == 0]
        if not held and len(names) >= 2:
            held = [names[-1]]
        why = "every 5th photo"
    missing = [n for n in held if n not in names]
    if missing:
        raise BaselineError(f"held-out photos not registered in the model ({why}): {', '.join(missing)}")
    if len(held) >= len(names):
        raise BaselineError(f"every photo is held out ({why}); the fit needs at least one")
    return held, why


def ply_header(path):
    with open(path, "rb") as fh:
        head = fh.read(4096)
    if not head.startswith(b"ply"):
        raise BaselineError(f"{path}: not a PLY file")
    text = head.split(b"end_header", 1)[0].decode("ascii", "replace")
    nv = nf = None
    for line in text.splitlines():
        f = line.split()
        if f[:2] == ["element", "vertex"]:
            nv = int(f[2])
        if f[:2] == ["element", "face"]:
            nf = int(f[2])
    if not nv or not nf:
        raise BaselineError(f"{path}: the PLY header declares no vertices or no faces")
    return nv, nf


class Workspace:
    def __init__(self, args):
        self.root = Path(args.workspace).expanduser()
        if not self.root.is_dir():
            raise BaselineError(f"{self.root}: workspace folder not found")
        sparse, self.images_dir, dense = find_model(self.root)
        self.cams = read_cameras(sparse / "cameras.txt")
        self.images = [
            r for r in read_images(sparse / "images.txt", self.cams) if (self.images_dir / r[0]).is_file()
        ]
        if len(self.images) < 2:
            raise BaselineError(f"{sparse}: fewer than two registered photos found in {self.images_dir}")
        names = [r[0] for r in self.images]
        self.held, self.held_why = held_out_names(self.root, names, args)
        self.train = [n for n in names if n not in self.held]
        self.mesh = find_mesh(self.root, dense, args.mesh)
        self.n_vertices, self.n_faces = ply_header(self.mesh)

    def summary(self):
        w, h = self.cams[self.images[0][3]][:2]
        return (
            f"workspace {self.root}\n  mesh {self.mesh}: {self.n_vertices} vertices, {self.n_faces} faces\n"
            f"  photos: {len(self.train)} training, {len(self.held)} held out ({self.held_why}: "
            f"{', '.join(self.held)}), first {w}×{h}"
        )


# --------------------------------------------------------------------------------------
# Mitsuba scene
# --------------------------------------------------------------------------------------


def quat_to_rot(q):
    w, x, y, z = q
    return [
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ]


def sensor_dict(cam, q, t):
    """Mitsuba perspective sensor of a COLMAP pinhole view. COLMAP: `x_cam = R x_world + t`,
    x right, y down, z forward; Mitsuba's camera looks along +z with +x to the image's left
    and +y up, so `world_from_mitsuba = [Rᵀ · diag(−1, −1, 1) | −Rᵀ t]` (checked for every
    view by [`check_sensor`])."""
    import numpy as np

    w, h, fx, _fy, cx, cy = cam
    r = np.array(quat_to_rot(q))
    m = np.eye(4)
    m[:3, :3] = r.T @ np.diag([-1.0, -1.0, 1.0])
    m[:3, 3] = -r.T @ np.array(t)
    import mitsuba as mi

    return {
        "type": "perspective",
        "fov_axis": "x",
        "fov": math.degrees(2 * math.atan(w / (2 * fx))),
        "principal_point_offset_x": (cx - w / 2) / w,
        "principal_point_offset_y": (cy - h / 2) / h,
        "near_clip": 1e-3,
        "far_clip": 1e4,
        "to_world": mi.ScalarTransform4f(m.tolist()),
        "film": {
            "type": "hdrfilm",
            "width": w,
            "height": h,
            "rfilter": {"type": "box"},
            "pixel_format": "rgb",
        },
    }


def check_sensor(sensor, cam, q, t, name):
    """Rays through three pixels must project back onto them with COLMAP's pinhole model
    (to 0.01 px: float32 ray directions give ~1e-5 px at these sizes)."""
    import mitsuba as mi
    import numpy as np

    w, h, fx, fy, cx, cy = cam
    r = np.array(quat_to_rot(q))
    for u, v in [(0.1 * w, 0.2 * h), (0.8 * w, 0.3 * h), (0.45 * w, 0.9 * h)]:
        ray, _ = sensor.sample_ray(0.0, 0.5, mi.Point2f(u / w, v / h), mi.Point2f(0.5, 0.5))
        o = np.array(ray.o).ravel()
        d = np.array(ray.d).ravel()
        xc = r @ (o + d) + np.array(t)
        pu, pv = fx * xc[0] / xc[2] + cx, fy * xc[1] / xc[2] + cy
        if abs(pu - u) > 0.01 or abs(pv - v) > 0.01:
            raise BaselineError(
                f"{name}: Mitsuba's camera does not reproduce COLMAP's projection "
                f"(pixel ({u:.1f}, {v:.1f}) came back at ({pu:.3f}, {pv:.3f}))"
            )


def load_photo(path, clip):
    """Linear RGB in [0, 1] and the overexposure mask, decoded as relight-cpc does
    (src/import/photo.rs): 8/16-bit PNG/JPEG are sRGB (exact IEC 61966-2-1 curve),
    overexposed where any channel's code ≥ round(clip/255 · max code); EXR is linear."""
    import mitsuba as mi
    import numpy as np

    bmp = mi.Bitmap(str(path))
    a = np.array(bmp)
    if a.ndim == 2:
        a = a[:, :, None]
    if a.shape[2] in (1, 2):
        a = np.repeat(a[:, :, :1], 3, axis=2)
    a = a[:, :, :3]
    if a.dtype in (np.uint8, np.uint16):
        top = 255.0 if a.dtype == np.uint8 else 65535.0
        over = (a.astype(np.float64) >= round(clip / 255.0 * top)).any(axis=2)
        c = a.astype(np.float32) / np.float32(top)
        rgb = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4).astype(np.float32)
    else:
        rgb = a.astype(np.float32)
        over = ~np.isfinite(rgb).all(axis=2)
        rgb[~np.isfinite(rgb)] = 0.0
    return rgb, over


def object_mask(scene, sensor, w, h):
    """Pixels whose centre ray hits the mesh (relight-cpc's raster `face != MAX`)."""
    import drjit as dr
    import mitsuba as mi
    import numpy as np

    idx = dr.arange(mi.UInt32, w * h)
    x = mi.Float(idx % w) + 0.5
    y = mi.Float(idx // w) + 0.5
    ray, _ = sensor.sample_ray(0.0, 0.5, mi.Point2f(x / w, y / h), mi.Point2f(0.5, 0.5))
    return np.array(scene.ray_test(ray)).reshape(h, w)


def compare(truth, pred, mask):
    """relight-cpc's `report::compare`: (RMSE, RMSE after the best global scale, scale, pixels)."""
    import numpy as np

    y = truth[mask].astype(np.float64)
    q = pred[mask].astype(np.float64)
    n = y.shape[0]
    if n == 0:
        return float("nan"), float("nan"), 1.0, 0
    syy, syp, spp = (y * y).sum(), (y * q).sum(), (q * q).sum()
    s = syp / spp if spp > 0 else 1.0
    se = ((y - q) ** 2).sum()
    se_scaled = max(syy - 2 * s * syp + s * s * spp, 0.0)
    return math.sqrt(se / (3 * n)), math.sqrt(se_scaled / (3 * n)), s, n


class Clock:
    """Wall and process CPU seconds (all threads) per phase."""

    def __init__(self):
        self.phases = {}

    def run(self, name, f):
        w0, c0 = time.perf_counter(), time.process_time()
        out = f()
        acc = self.phases.setdefault(name, [0.0, 0.0])
        acc[0] += time.perf_counter() - w0
        acc[1] += time.process_time() - c0
        return out


# --------------------------------------------------------------------------------------
# Fit and evaluation
# --------------------------------------------------------------------------------------


class Scene:
    """The Mitsuba scene: the mesh with its per-vertex albedo, one hidden envmap emitter
    whose texels are swapped per photo, and one sensor per registered photo."""

    def __init__(self, ws, args):
        import drjit as dr
        import mitsuba as mi
        import numpy as np

        mesh = mi.load_dict(
            {
                "type": "ply",
                "filename": str(ws.mesh),
                "bsdf": {
                    "type": "diffuse",
                    "reflectance": {"type": "mesh_attribute", "name": "vertex_albedo"},
                },
            }
        )
        self.n_vertices = mesh.vertex_count()
        mesh.add_attribute("vertex_albedo", 3, dr.full(mi.Float, 0.5, 3 * self.n_vertices))
        env_h = args.env_width // 2
        env = mi.Bitmap(np.ones((env_h, args.env_width, 3), dtype=np.float32))
        scene = {
            "type": "scene",
            "integrator": {"type": "prb", "max_depth": 2, "hide_emitters": True},
            "shape": mesh,
            "emitter": {"type": "envmap", "bitmap": env},
        }
        self.names = []
        for name, q, t, cid in ws.images:
            scene[f"sensor_{len(self.names):04d}"] = sensor_dict(ws.cams[cid], q, t)
            self.names.append(name)
        self.scene = mi.load_dict(scene)
        self.sensors = self.scene.sensors()
        if len(self.sensors) != len(self.names):
            raise BaselineError("Mitsuba did not create one sensor per photo")
        for (name, q, t, cid), sensor in zip(ws.images, self.sensors):
            check_sensor(sensor, ws.cams[cid], q, t, name)
        self.params = mi.traverse(self.scene)
        self.albedo_key = next(k for k in self.params.keys() if k.endswith("vertex_albedo"))
        self.env_key = next(k for k in self.params.keys() if k.endswith("emitter.data") or k == "emitter.data")
        self.env_shape = self.params[self.env_key].shape

    def render(self, k, albedo, env, spp, seed):
        import mitsuba as mi

        self.params[self.albedo_key] = albedo
        self.params[self.env_key] = env
        self.params.update()
        return mi.render(self.scene, self.params, sensor=k, spp=spp, seed=seed)


class Photo:
    def __init__(self, scene, k, path, clip):
        import mitsuba as mi
        import numpy as np

        self.rgb, over = load_photo(path, clip)
        h, w = self.rgb.shape[:2]
        film = scene.sensors[k].film().size()
        if (w, h) != (film[0], film[1]):
            raise BaselineError(f"{path}: {w}×{h} pixels, the model's camera says {film[0]}×{film[1]}")
        self.obj = object_mask(scene.scene, scene.sensors[k], w, h)
        self.valid = self.obj & ~over
        xs = np.nonzero(self.obj.any(axis=0))[0]
        self.mid = 0.5 * (xs.min() + xs.max() + 1) if xs.size else None
        self.ref = mi.TensorXf(self.rgb)

    def weight(self, mask):
        """A TensorXf (H, W, 1) that is 1/|mask| on `mask`, else 0."""
        import mitsuba as mi
        import numpy as np

        n = max(int(mask.sum()), 1)
        return mi.TensorXf((mask.astype(np.float32) / n)[:, :, None])

    def side(self, right):
        import numpy as np

        x = np.arange(self.valid.shape[1])[None, :]
        return self.valid & ((x >= self.mid) == right)


def decay(args, it, n):
    """Learning-rate factor at step `it` of `n`: exponential from 1 to `--lr-decay`.
    Without it the 4-spp gradient noise makes Adam wander once near the optimum (on the
    built-in example the training loss rose by 24% from step 55 to 200 at a constant rate)."""
    return args.lr_decay ** (it / max(n - 1, 1))


def fit_training(scene, photos, train_idx, args, log):
    """Adam on the per-vertex albedo and every training photo's map (module docs)."""
    import drjit as dr
    import mitsuba as mi

    l0 = 2.0 * sum(float(photos[k].rgb[photos[k].valid].mean()) for k in train_idx) / len(train_idx)
    opt = mi.ad.Adam(lr=args.lr_env)
    opt["albedo"] = dr.full(mi.Float, 0.5, 3 * scene.n_vertices)
    opt.set_learning_rate({"albedo": args.lr_albedo})
    for k in train_idx:
        opt[f"e{k}"] = dr.full(mi.TensorXf, 1.0, scene.env_shape)
    weights = {k: photos[k].weight(photos[k].valid) for k in train_idx}
    curve = []
    for it in range(args.iterations):
        f = decay(args, it, args.iterations)
        opt.set_learning_rate({"albedo": args.lr_albedo * f, **{f"e{k}": args.lr_env * f for k in train_idx}})
        total = 0.0
        for j, k in enumerate(train_idx):
            img = scene.render(k, opt["albedo"], l0 * opt[f"e{k}"], args.spp, seed=it * len(photos) + k)
            loss = dr.sum(dr.square(img - photos[k].ref) * weights[k], axis=None) / len(train_idx)
            dr.backward(loss)
            total += loss.array[0] if hasattr(loss, "array") else float(loss[0])
        opt.step()
        opt["albedo"] = dr.clip(opt["albedo"], 0.0, 1.0)
        for k in train_idx:
            opt[f"e{k}"] = dr.maximum(opt[f"e{k}"], 0.0)
        curve.append(total)
        if it % 10 == 0 or it == args.iterations - 1:
            log(f"  iteration {it:4d}: training loss (mean squared error) {total:.6f}")
    albedo = dr.detach(opt["albedo"])
    envs = {k: dr.detach(opt[f"e{k}"]) for k in train_idx}
    return l0, albedo, envs, curve


def fit_half(scene, photo, k, albedo, l0, start, args):
    """Protocol `half`: photo k's map from `start`, albedo frozen, on the left half."""
    import drjit as dr
    import mitsuba as mi

    opt = mi.ad.Adam(lr=args.lr_env)
    opt["e"] = mi.TensorXf(start)
    w = photo.weight(photo.side(right=False))
    for it in range(args.half_iterations):
        opt.set_learning_rate({"e": args.lr_env * decay(args, it, args.half_iterations)})
        img = scene.render(k, albedo, l0 * opt["e"], args.spp, seed=10**6 + it * 1000 + k)
        dr.backward(dr.sum(dr.square(img - photo.ref) * w, axis=None))
        opt.step()
        opt["e"] = dr.maximum(opt["e"], 0.0)
    return dr.detach(opt["e"])


def entry(image, protocol, photo, pred, mask):
    rmse, rmse_scaled, scale, n = compare(photo.rgb, pred, mask)
    return {"image": image, "protocol": protocol, "rmse": rmse, "rmse_scaled": rmse_scaled, "scale": scale, "pixels": n}


def run(ws, args):
    import drjit as dr
    import mitsuba as mi
    import numpy as np

    log = (lambda s: None) if args.quiet else (lambda s: print(s, flush=True))
    clock = Clock()
    if args.threads:
        dr.set_thread_count(args.threads)
    scene = clock.run("load", lambda: Scene(ws, args))
    photos = clock.run(
        "load",
        lambda: [Photo(scene, k, ws.images_dir / n, args.clip) for k, n in enumerate(scene.names)],
    )
    train_idx = [scene.names.index(n) for n in ws.train]
    held_idx = [scene.names.index(n) for n in ws.held]
    log(ws.summary())
    l0, albedo, envs, curve = clock.run("fit", lambda: fit_training(scene, photos, train_idx, args, log))
    mean_env = sum(np.array(envs[k]) for k in train_idx) / len(train_idx)

    train_entries = []
    if not args.no_train_eval:
        for k in train_idx:
            img = clock.run("train renders", lambda: np.array(scene.render(k, albedo, l0 * envs[k], args.eval_spp, seed=7 + k)))
            train_entries.append(entry(scene.names[k], "train", photos[k], img, photos[k].valid))
    held_entries = []
    for k in held_idx:
        ph = photos[k]
        if ph.mid is None:
            log(f"  {scene.names[k]}: the mesh is not in view; skipped")
            continue
        e = clock.run("half fit", lambda: fit_half(scene, ph, k, albedo, l0, mean_env, args))
        img = clock.run("held-out renders", lambda: np.array(scene.render(k, albedo, l0 * e, args.eval_spp, seed=99 + k)))
        held_entries.append(entry(scene.names[k], "half", ph, img, ph.side(right=True)))
        if args.out:
            out = Path(args.out)
            out.mkdir(parents=True, exist_ok=True)
            mi.Bitmap(img.astype(np.float32)).write(str(out / f"{Path(scene.names[k]).stem}.half.exr"))
    return {
        "tool": f"mitsuba {mi.__version__}, drjit {dr.__version__}, variant {mi.variant()}",
        "workspace": str(ws.root),
        "mesh": str(ws.mesh),
        "vertices": scene.n_vertices,
        "training_photos": ws.train,
        "held_out": ws.held,
        "settings": {
            k: getattr(args, k)
            for k in ("iterations", "half_iterations", "spp", "eval_spp", "env_width", "lr_albedo", "lr_env", "lr_decay", "clip", "threads")
        },
        "loss_curve": curve,
        "train": train_entries,
        "train_rmse_scaled": float(np.mean([e["rmse_scaled"] for e in train_entries])) if train_entries else None,
        "holdout": held_entries,
        "mean_half_rmse_scaled": float(np.mean([e["rmse_scaled"] for e in held_entries])) if held_entries else None,
        "phases_wall_cpu_seconds": clock.phases,
    }


def compare_with(report, relight_report_path):
    """Side by side with relight-cpc's `half` entries on the same photos."""
    rc = read_json(Path(relight_report_path))
    theirs = {e["image"]: e for e in rc.get("holdout", []) if e["protocol"] == "half"}
    lines = ["| held-out photo | relight-cpc `half` | Mitsuba `half` | pixels (relight-cpc / Mitsuba) |", "|---|---:|---:|---:|"]
    for e in report["holdout"]:
        t = theirs.get(e["image"])
        rc_txt = f"{t['rmse_scaled']:.4f}" if t else "–"
        px = f"{t['pixels']} / {e['pixels']}" if t else f"– / {e['pixels']}"
        lines.append(f"| {e['image']} | {rc_txt} | {e['rmse_scaled']:.4f} | {px} |")
    return "\n".join(lines)


def parse_args(argv):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("workspace", help="COLMAP workspace folder (as `relight-cpc run WORKSPACE`)")
    p.add_argument("--mesh", help="mesh PLY (default: dense/meshed-poisson.ply, then meshed-delaunay.ply)")
    p.add_argument("--relight-report", help="relight-cpc's report.json: its held-out photos are used, and its `half` figures printed beside")
    p.add_argument("--holdout", help="held-out photo names, comma-separated (default: as relight-cpc)")
    p.add_argument("--iterations", type=int, default=200, help="Adam steps of the training fit (each renders every training photo) [200]")
    p.add_argument("--half-iterations", type=int, default=100, help="Adam steps of each held-out photo's left-half light fit [100]")
    p.add_argument("--spp", type=int, default=4, help="samples per pixel while fitting [4]")
    p.add_argument("--eval-spp", type=int, default=64, help="samples per pixel of the scored renders [64]")
    p.add_argument("--env-width", type=int, default=64, help="lat-long map width in texels (height = width/2) [64]")
    p.add_argument("--lr-albedo", type=float, default=0.02, help="Adam learning rate of the albedo [0.02]")
    p.add_argument("--lr-env", type=float, default=0.05, help="Adam learning rate of the maps, relative to their starting level [0.05]")
    p.add_argument("--lr-decay", type=float, default=0.1, help="learning rate at the last step as a fraction of the first (exponential decay) [0.1]")
    p.add_argument("--clip", type=float, default=250, help="overexposure threshold on the 8-bit scale, as relight-cpc's --clip [250]")
    p.add_argument("--threads", type=int, default=0, help="Dr.Jit worker threads (0 = all cores)")
    p.add_argument("--no-train-eval", action="store_true", help="skip the training photos' RMSE")
    p.add_argument("--out", help="folder for report.json and the held-out renders (EXR)")
    p.add_argument("--check", action="store_true", help="validate the workspace and arguments without Mitsuba, then exit")
    p.add_argument("--quiet", action="store_true")
    a = p.parse_args(argv)
    for name in ("iterations", "half_iterations", "spp", "eval_spp"):
        if getattr(a, name) < 1 and not (name == "iterations" and getattr(a, name) == 0):
            p.error(f"--{name.replace('_', '-')} must be at least 1")
    if a.env_width < 4 or a.env_width % 2:
        p.error("--env-width must be an even number ≥ 4")
    if not (0 < a.clip <= 255):
        p.error("--clip must be in (0, 255]")
    if a.lr_albedo <= 0 or a.lr_env <= 0:
        p.error("learning rates must be positive")
    if not (0 < a.lr_decay <= 1):
        p.error("--lr-decay must be in (0, 1]")
    if a.relight_report and not Path(a.relight_report).is_file():
        p.error(f"{a.relight_report}: relight-cpc report not found")
    return a


def main(argv):
    args = parse_args(argv)
    try:
        ws = Workspace(args)
        if args.check:
            print(ws.summary())
            print(f"check: OK (would fit {args.iterations} Adam steps at {args.spp} spp, variant {MITSUBA_VARIANT})")
            return 0
        try:
            import mitsuba as mi

            mi.set_variant(MITSUBA_VARIANT)
        except ImportError:
            raise BaselineError("Mitsuba is not installed: run scripts/mitsuba_baseline.sh, which installs it")
        except Exception as e:  # the variant needs libLLVM at run time
            raise BaselineError(
                f"Mitsuba's {MITSUBA_VARIANT} variant does not start ({e}); it needs the LLVM "
                "shared library (Debian/Ubuntu: `apt-get install libllvm15`, or set DRJIT_LIBLLVM_PATH)"
            )
        w0, c0 = time.perf_counter(), time.process_time()
        report = run(ws, args)
        report["whole_wall_cpu_seconds"] = [time.perf_counter() - w0, time.process_time() - c0]
    except BaselineError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    text = json.dumps(report, indent=2)
    if args.out:
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        tmp = out / "report.json.tmp"
        tmp.write_text(text)
        os.replace(tmp, out / "report.json")
    summary = {k: report[k] for k in ("mean_half_rmse_scaled", "train_rmse_scaled", "phases_wall_cpu_seconds", "whole_wall_cpu_seconds")}
    print(json.dumps(summary, indent=2))
    for e in report["holdout"]:
        print(f"{e['image']}: half RMSE after scale {e['rmse_scaled']:.4f} on {e['pixels']} pixels")
    if args.relight_report:
        print(compare_with(report, args.relight_report))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
