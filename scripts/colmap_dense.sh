#!/usr/bin/env bash
# Undistorted COLMAP workspace -> depth/normal maps (CPU) -> fused points -> cleaned Poisson mesh.
#
# Usage: scripts/colmap_dense.sh OUT_DIR [--poisson-depth D] [--min-num-pixels N]
#                                [--max-normal-error DEG] [--trim-factor F] [--min-component F]
#                                [--neighbours K] [--max-angle DEG] [--clahe C] [--geom-views N]
#                                [--min-views F] [--target-faces N] [--venv DIR]
#
# OUT_DIR is a project folder that scripts/colmap_sparse.sh (or colmap_workspace.sh) made:
# OUT_DIR/dense/{images,sparse,stereo} from `colmap image_undistorter --output_type COLMAP`.
# Debian's COLMAP 3.8 has no CUDA, so patch_match_stereo is replaced by
# scripts/depth_sgbm.py (OpenCV semi-global matching on rectified pairs; see its header).
#
# Steps (each timed into OUT_DIR/logs/timings.tsv, one log each in OUT_DIR/logs/):
#   30-depth_sgbm      -> dense/stereo/{depth_maps,normal_maps}/NAME.geometric.bin (COLMAP arrays;
#                         photos equalised by CLAHE --clahe 2, depth limited to the sparse
#                         points' range in each view: no sky, no far background)
#   31-stereo_fusion   -> dense/fused.ply (+ fused.ply.vis), --input_type geometric
#   32-poisson_mesher  -> dense/meshed-poisson-raw.ply (screened Poisson, no density trim:
#                         with sparse fused points COLMAP's trim removes the whole surface)
#   33-mesh_clean      -> dense/meshed-poisson.ply (scripts/depth_mesh_clean.py: faces far from
#                         the fused points removed, the mesh cropped to what --min-views of
#                         the cameras see (0.3 = 30%) inside the sparse points' box, floating
#                         components under --min-component of the largest dropped, then
#                         vertex-clustered to about --target-faces faces, 0 = keep all)
#
# Defaults measured on examples/buddha-mixed (2026-11-25, 11 registered photos at 1024 px):
# CLAHE 2 fuses 78,793 points against 63,016 without; --geom-views 1 before fusion changed
# nothing (62,507: stereo_fusion makes the same check); Poisson depth 8 leaves 6,153 vertices,
# depth 9 with the crop and 80,000 target faces 25,460 vertices in 4 components.
#
# Python packages come from scripts/requirements-depth.txt, installed when missing into a venv
# (default ~/.cache/relight-cpc/venv; python3-venv is installed with apt-get when missing).
set -euo pipefail

usage() {
    sed -n 3,6p "$0" >&2
    exit 2
}

[[ $# -ge 1 ]] || usage
OUT_DIR=$(realpath "$1")
shift
POISSON_DEPTH=9
MIN_NUM_PIXELS=2
MAX_NORMAL_ERROR=25
TRIM_FACTOR=6
MIN_COMPONENT=0.05
NEIGHBOURS=4
MAX_ANGLE=45
CLAHE=2
GEOM_VIEWS=0
MIN_VIEWS=0.3
TARGET_FACES=80000
VENV=${RELIGHT_VENV:-$HOME/.cache/relight-cpc/venv}
while [[ $# -gt 0 ]]; do
    [[ $# -ge 2 ]] || usage
    case "$1" in
    --poisson-depth) POISSON_DEPTH=$2 ;;
    --min-num-pixels) MIN_NUM_PIXELS=$2 ;;
    --max-normal-error) MAX_NORMAL_ERROR=$2 ;;
    --trim-factor) TRIM_FACTOR=$2 ;;
    --min-component) MIN_COMPONENT=$2 ;;
    --neighbours) NEIGHBOURS=$2 ;;
    --max-angle) MAX_ANGLE=$2 ;;
    --clahe) CLAHE=$2 ;;
    --geom-views) GEOM_VIEWS=$2 ;;
    --min-views) MIN_VIEWS=$2 ;;
    --target-faces) TARGET_FACES=$2 ;;
    --venv) VENV=$2 ;;
    *) usage ;;
    esac
    shift 2
done

SCRIPTS=$(cd "$(dirname "$0")" && pwd)
DENSE=$OUT_DIR/dense
[[ -f $DENSE/sparse/images.bin && -d $DENSE/images ]] || {
    echo "$DENSE: no undistorted workspace (dense/sparse/images.bin, dense/images/)" >&2
    exit 1
}
export QT_QPA_PLATFORM=offscreen
LOGS=$OUT_DIR/logs
TIMES=$LOGS/timings.tsv
mkdir -p "$LOGS"
[[ -f $TIMES ]] || printf 'step\tseconds\n' >"$TIMES"

# run NAME CMD...: one step, its output in logs/NAME.log, its wall time in timings.tsv.
# shellcheck source=steps.sh
source "$(dirname "$(realpath "${BASH_SOURCE[0]}")")/steps.sh"

# Tools: colmap (apt), a venv with the Python packages.
need_apt=()
command -v colmap >/dev/null 2>&1 || need_apt+=(colmap)
command -v bc >/dev/null 2>&1 || need_apt+=(bc)
/usr/bin/python3 -c "import venv, ensurepip" >/dev/null 2>&1 || need_apt+=(python3-venv)
if [[ ${#need_apt[@]} -gt 0 ]]; then
    echo "installing ${need_apt[*]} with apt-get"
    apt-get update
    DEBIAN_FRONTEND=noninteractive apt-get install -y "${need_apt[@]}"
fi
PY=$VENV/bin/python
if ! "$PY" -c "import cv2, numpy, scipy" >/dev/null 2>&1; then
    echo "creating the Python environment $VENV"
    /usr/bin/python3 -m venv "$VENV"
    "$VENV/bin/pip" install -q -r "$SCRIPTS/requirements-depth.txt"
fi

# 30. Depth and normal maps on the CPU.
rm -f "$DENSE"/stereo/depth_maps/*.bin "$DENSE"/stereo/normal_maps/*.bin
run 30-depth_sgbm "$PY" "$SCRIPTS/depth_sgbm.py" "$DENSE" \
    --neighbours "$NEIGHBOURS" --max-angle "$MAX_ANGLE" --min-consistent 1 \
    --clahe "$CLAHE" --geom-views "$GEOM_VIEWS"

# 31. COLMAP's own fusion of the geometric maps.
run 31-stereo_fusion colmap stereo_fusion \
    --workspace_path "$DENSE" --workspace_format COLMAP --input_type geometric \
    --output_path "$DENSE/fused.ply" \
    --StereoFusion.min_num_pixels "$MIN_NUM_PIXELS" \
    --StereoFusion.max_normal_error "$MAX_NORMAL_ERROR" \
    --StereoFusion.num_threads 2

# 32. Screened Poisson surface.
run 32-poisson_mesher colmap poisson_mesher \
    --input_path "$DENSE/fused.ply" --output_path "$DENSE/meshed-poisson-raw.ply" \
    --PoissonMeshing.depth "$POISSON_DEPTH" --PoissonMeshing.trim 0 \
    --PoissonMeshing.num_threads 2

# 33. Trim far from the points, crop to the shared view, drop floating components.
CROP=()
[[ $MIN_VIEWS != 0 ]] && CROP=(--workspace "$DENSE" --min-views "$MIN_VIEWS")
run 33-mesh_clean "$PY" "$SCRIPTS/depth_mesh_clean.py" \
    "$DENSE/meshed-poisson-raw.ply" "$DENSE/meshed-poisson.ply" --points "$DENSE/fused.ply" \
    --trim-factor "$TRIM_FACTOR" --min-component "$MIN_COMPONENT" --target-faces "$TARGET_FACES" \
    "${CROP[@]}"

tail -n 1 "$LOGS/33-mesh_clean.log" >"$LOGS/mesh_stats.json"
echo "dense done: $DENSE/fused.ply, $DENSE/meshed-poisson.ply"
grep -h "Number of fused points" "$LOGS/31-stereo_fusion.log" || true
cat "$LOGS/mesh_stats.json"
