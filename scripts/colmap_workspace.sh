#!/usr/bin/env bash
# Photos -> a complete COLMAP workspace with a mesh, on Debian's CPU-only COLMAP 3.8.
#
# Usage: scripts/colmap_workspace.sh IMAGE_DIR OUT_DIR [--max-size PX] [--dense-size PX]
#            [--camera-model MODEL] [--cameras per-photo|per-model|single]
#            [--matcher exhaustive|sequential] [--centres FILE]
#            [dense options of scripts/colmap_dense.sh: --poisson-depth D, --min-num-pixels N,
#             --max-normal-error DEG, --trim-factor F, --min-component F, --neighbours K,
#             --max-angle DEG, --clahe C, --geom-views N, --min-views F, --target-faces N,
#             --venv DIR]
#
#   --max-size PX     photos downscaled so the longer side is at most PX before SfM
#   --dense-size PX   undistorted photos (and so depth maps and the mesh's sampling) at most PX
#   --centres FILE    known camera centres, lines "NAME X Y Z": the model is moved into that
#                     frame with `colmap model_aligner` (similarity, least squares over all
#                     listed photos), the undistorted model with the same transform
#
# What it leaves in OUT_DIR (COLMAP's own project layout, so COLMAP's GUI and
# `relight-cpc inspect OUT_DIR` both open it):
#   images/                       the photos SfM saw (upright 8-bit RGB), manifest.json
#   registration.json, unregistered.txt          photos registered and left out
#   sparse/0/ (binary), sparse/0-txt/ (text)     the distorted model
#   dense/images/, dense/sparse/ (binary), dense/sparse-txt/ (text)   undistorted, PINHOLE
#   dense/stereo/{depth_maps,normal_maps}/NAME.geometric.bin, patch-match.cfg, fusion.cfg
#   dense/fused.ply, dense/meshed-poisson.ply (cleaned), dense/meshed-poisson-raw.ply
#   logs/NN-step.log, logs/timings.tsv (seconds per step), summary.json (the figures)
#
# Steps: 0-8 scripts/colmap_sparse.sh (photos prepared, SIFT on the CPU, matching, mapper with
# a relaxed retry when photos are missing (as with the 13 colour Buddha views, far apart),
# the largest model, text copies, image_undistorter, model_analyzer, registration report).
# --centres adds model_aligner + model_transformer (22-25). scripts/colmap_dense.sh does the
# rest (30-33).
set -euo pipefail

usage() {
    sed -n 3,10p "$0" >&2
    exit 2
}

[[ $# -ge 2 ]] || usage
IMAGE_DIR=$(realpath "$1")
OUT_DIR=$2
shift 2
MAX_SIZE=""
DENSE_SIZE=""
CAMERA_MODEL=SIMPLE_RADIAL
CAMERAS=per-photo
MATCHER=exhaustive
CENTRES=""
DENSE_ARGS=()
while [[ $# -gt 0 ]]; do
    [[ $# -ge 2 ]] || usage
    case "$1" in
    --max-size) MAX_SIZE=$2 ;;
    --dense-size) DENSE_SIZE=$2 ;;
    --camera-model) CAMERA_MODEL=$2 ;;
    --cameras) CAMERAS=$2 ;;
    --matcher)
        MATCHER=$2
        [[ $MATCHER == exhaustive || $MATCHER == sequential ]] || usage
        ;;
    --centres) CENTRES=$(realpath "$2") ;;
    --poisson-depth | --min-num-pixels | --max-normal-error | --trim-factor | --min-component | \
        --neighbours | --max-angle | --clahe | --geom-views | --min-views | --target-faces | \
        --venv) DENSE_ARGS+=("$1" "$2") ;;
    *) usage ;;
    esac
    shift 2
done

SCRIPTS=$(cd "$(dirname "$0")" && pwd)
export QT_QPA_PLATFORM=offscreen
mkdir -p "$OUT_DIR"
OUT_DIR=$(realpath "$OUT_DIR")
T_START=$(date +%s)

# ---- 0-8: the sparse half: photos, features, matching, mapper (largest model, relaxed retry),
# undistortion (at most --dense-size), statistics, registration report.
SPARSE_ARGS=(--camera-model "$CAMERA_MODEL" --cameras "$CAMERAS" --matcher "$MATCHER")
[[ -n $MAX_SIZE ]] && SPARSE_ARGS+=(--max-size "$MAX_SIZE")
[[ -n $DENSE_SIZE ]] && SPARSE_ARGS+=(--dense-size "$DENSE_SIZE")
SPARSE_OUT=$(mktemp)
echo "[$(date -u +%H:%M:%S)] colmap_sparse.sh $IMAGE_DIR $OUT_DIR ${SPARSE_ARGS[*]}"
if ! "$SCRIPTS/colmap_sparse.sh" "$IMAGE_DIR" "$OUT_DIR" "${SPARSE_ARGS[@]}" >"$SPARSE_OUT" 2>&1; then
    mkdir -p "$OUT_DIR/logs"
    mv "$SPARSE_OUT" "$OUT_DIR/logs/00-colmap_sparse.out"
    echo "colmap_sparse.sh failed; see $OUT_DIR/logs/00-colmap_sparse.out" >&2
    tail -20 "$OUT_DIR/logs/00-colmap_sparse.out" >&2
    exit 1
fi
LOGS=$OUT_DIR/logs
TIMES=$LOGS/timings.tsv
mv "$SPARSE_OUT" "$LOGS/00-colmap_sparse.out"
cat "$LOGS/8-registration.log"

# run NAME CMD...: one step, its output in logs/NAME.log, its wall time in timings.tsv.
# shellcheck source=steps.sh
source "$(dirname "$(realpath "${BASH_SOURCE[0]}")")/steps.sh"

# ---- 22-25: into the frame of known camera centres.
if [[ -n $CENTRES ]]; then
    rm -rf "$OUT_DIR/sparse/0-aligned"
    mkdir -p "$OUT_DIR/sparse/0-aligned"
    run 22-model_aligner colmap model_aligner \
        --input_path "$OUT_DIR/sparse/0" --output_path "$OUT_DIR/sparse/0-aligned" \
        --ref_images_path "$CENTRES" --ref_is_gps 0 --alignment_type custom \
        --robust_alignment 0 --transform_path "$LOGS/align_transform.txt"
    cp "$OUT_DIR"/sparse/0-aligned/*.bin "$OUT_DIR/sparse/0/"
    rm -rf "$OUT_DIR/sparse/0-aligned"
    run 23-model_transformer colmap model_transformer \
        --input_path "$OUT_DIR/dense/sparse" --output_path "$OUT_DIR/dense/sparse" \
        --transform_path "$LOGS/align_transform.txt"
    run 24-model_converter colmap model_converter --input_path "$OUT_DIR/sparse/0" \
        --output_path "$OUT_DIR/sparse/0-txt" --output_type TXT
    run 25-model_converter colmap model_converter --input_path "$OUT_DIR/dense/sparse" \
        --output_path "$OUT_DIR/dense/sparse-txt" --output_type TXT
fi

# COLMAP's own statistics of the final undistorted model.
run 26-model_analyzer colmap model_analyzer --path "$OUT_DIR/dense/sparse"

# ---- 30-33: depth maps, fusion, Poisson, cleaning.
"$SCRIPTS/colmap_dense.sh" "$OUT_DIR" "${DENSE_ARGS[@]}"

# ---- Figures.
VENV=${RELIGHT_VENV:-$HOME/.cache/relight-cpc/venv}
for ((i = 0; i < ${#DENSE_ARGS[@]}; i += 2)); do
    [[ ${DENSE_ARGS[i]} == --venv ]] && VENV=${DENSE_ARGS[i + 1]}
done
"$VENV/bin/python" - "$OUT_DIR" "$IMAGE_DIR" "$CENTRES" "$(($(date +%s) - T_START))" <<'EOF' |
import json, pathlib, re, sys
import numpy as np
sys.path.insert(0, str(pathlib.Path(sys.argv[0]).parent))
out, image_dir, centres, total = pathlib.Path(sys.argv[1]), sys.argv[2], sys.argv[3], sys.argv[4]
ana = (out / "logs" / "26-model_analyzer.log").read_text()
def grab(key, cast=float):
    m = re.search(key + r":\s*([0-9.]+)", ana)
    return cast(m.group(1)) if m else None
photos = sorted(p.name for p in pathlib.Path(image_dir).iterdir()
                if p.suffix.lower() in {".jpg", ".jpeg", ".png", ".tif", ".tiff"})
s = dict(photos=len(photos), registered=grab("Registered images", int),
         points3d=grab("Points", int), mean_track_length=grab("Mean track length"),
         mean_reprojection_error_px=grab("Mean reprojection error"))
fus = (out / "logs" / "31-stereo_fusion.log").read_text()
m = re.search(r"Number of fused points:\s*(\d+)", fus)
s["fused_points"] = int(m.group(1)) if m else None
s["mesh"] = json.loads((out / "logs" / "mesh_stats.json").read_text())
s["seconds"] = {l.split("\t")[0]: float(l.split("\t")[1])
                for l in (out / "logs" / "timings.tsv").read_text().splitlines()[1:] if "\t" in l}
s["seconds_total"] = float(total)
if centres:
    import struct
    ref = {}
    for line in open(centres):
        t = line.split()
        if len(t) == 4 and not line.startswith("#"):
            ref[t[0]] = np.array([float(x) for x in t[1:]])
    txt = (out / "sparse" / "0-txt" / "images.txt").read_text().splitlines()
    rows = [l for l in txt if l and not l.startswith("#")][0::2]
    errs = {}
    for l in rows:
        t = l.split()
        q = np.array([float(x) for x in t[1:5]]); tv = np.array([float(x) for x in t[5:8]])
        w, x, y, z = q
        R = np.array([[1-2*y*y-2*z*z, 2*x*y-2*w*z, 2*x*z+2*w*y],
                      [2*x*y+2*w*z, 1-2*x*x-2*z*z, 2*y*z-2*w*x],
                      [2*x*z-2*w*y, 2*y*z+2*w*x, 1-2*x*x-2*y*y]])
        if t[9] in ref:
            errs[t[9]] = float(np.linalg.norm(-R.T @ tv - ref[t[9]]))
    if errs:
        e = np.array(list(errs.values()))
        s["centre_error"] = dict(mean=float(e.mean()), max=float(e.max()), per_image=errs)
s["unregistered"] = sorted(set(photos) - {l.split()[9] for l in
    [l for l in (out / "sparse" / "0-txt" / "images.txt").read_text().splitlines()
     if l and not l.startswith("#")][0::2]})
(out / "summary.json").write_text(json.dumps(s, indent=1) + "\n")
print(json.dumps({k: v for k, v in s.items() if k != "seconds"}, indent=1))
EOF
    cat
echo "workspace: $OUT_DIR"
column -t "$TIMES" 2>/dev/null || cat "$TIMES"
