#!/usr/bin/env bash
# Photos -> COLMAP sparse model (binary + text) -> undistorted dense workspace, CPU only.
#
# Usage: scripts/colmap_sparse.sh IMAGE_DIR OUT_DIR [--max-size PX] [--camera-model MODEL]
#                                 [--max-features N]
#
# Steps (each timed, one log per step in OUT_DIR/logs/):
#   0. (with --max-size) downscale the photos so the longer side is at most PX (Pillow, Lanczos)
#      into OUT_DIR/images; without it the photos are copied there unchanged.
#   1. feature_extractor   (SIFT on the CPU, one shared camera, model SIMPLE_RADIAL by default,
#                          at most --max-features keypoints per photo, COLMAP's 8192 by default)
#   2. exhaustive_matcher  (CPU)
#   3. mapper              -> OUT_DIR/sparse/0 (binary)
#   4. model_converter     -> OUT_DIR/sparse/0-txt (text copy of the same model)
#   5. image_undistorter   -> OUT_DIR/dense/{images,sparse} (PINHOLE model, undistorted photos)
#   6. model_converter     -> OUT_DIR/dense/sparse-txt (text copy of the undistorted model)
#   7. model_analyzer      -> OUT_DIR/logs/7-model_analyzer*.log (COLMAP's own statistics)
#
# Needs Debian's `colmap` (3.8, built without CUDA) and python3-pil; installs them with
# apt-get when missing. Runs headless (QT_QPA_PLATFORM=offscreen).
set -euo pipefail

usage() {
    echo "usage: $0 IMAGE_DIR OUT_DIR [--max-size PX] [--camera-model MODEL] [--max-features N]" >&2
    exit 2
}

[[ $# -ge 2 ]] || usage
IMAGE_DIR=$(realpath "$1")
OUT_DIR=$2
shift 2
MAX_SIZE=""
CAMERA_MODEL="SIMPLE_RADIAL"
MAX_FEATURES=8192
while [[ $# -gt 0 ]]; do
    case "$1" in
    --max-size)
        [[ $# -ge 2 ]] || usage
        MAX_SIZE=$2
        shift 2
        ;;
    --max-features)
        [[ $# -ge 2 ]] || usage
        MAX_FEATURES=$2
        shift 2
        ;;
    --camera-model)
        [[ $# -ge 2 ]] || usage
        CAMERA_MODEL=$2
        shift 2
        ;;
    *) usage ;;
    esac
done

export QT_QPA_PLATFORM=offscreen

# Tools: install when missing (Debian/Ubuntu).
need_apt=()
command -v colmap >/dev/null 2>&1 || need_apt+=(colmap)
/usr/bin/python3 -c "import PIL" >/dev/null 2>&1 || need_apt+=(python3-pil)
if [[ ${#need_apt[@]} -gt 0 ]]; then
    echo "installing ${need_apt[*]} with apt-get"
    apt-get update
    DEBIAN_FRONTEND=noninteractive apt-get install -y "${need_apt[@]}"
fi

mkdir -p "$OUT_DIR/logs" "$OUT_DIR/images" "$OUT_DIR/sparse/0" "$OUT_DIR/sparse/0-txt" \
    "$OUT_DIR/dense"
OUT_DIR=$(realpath "$OUT_DIR")
LOGS=$OUT_DIR/logs
TIMES=$LOGS/timings.tsv
printf 'step\tseconds\n' >"$TIMES"

# run NAME CMD...: one step, its output in logs/NAME.log, its wall time in timings.tsv.
# shellcheck source=steps.sh
source "$(dirname "$(realpath "${BASH_SOURCE[0]}")")/steps.sh"

# 0. Photos into OUT_DIR/images (downscaled when asked).
run 0-prepare_images /usr/bin/python3 - "$IMAGE_DIR" "$OUT_DIR/images" "${MAX_SIZE:-0}" <<'EOF'
import pathlib, shutil, sys
from PIL import Image
src, dst, max_size = pathlib.Path(sys.argv[1]), pathlib.Path(sys.argv[2]), int(sys.argv[3])
exts = {".jpg", ".jpeg", ".png", ".tif", ".tiff"}
photos = sorted(p for p in src.iterdir() if p.suffix.lower() in exts)
if not photos:
    sys.exit(f"no photos in {src}")
for p in photos:
    out = dst / p.name
    if max_size <= 0:
        shutil.copy2(p, out)
        print(f"{p.name}: copied")
        continue
    im = Image.open(p)
    exif = im.info.get("exif")
    w, h = im.size
    s = min(1.0, max_size / max(w, h))
    size = (max(1, round(w * s)), max(1, round(h * s)))
    im = im.convert("RGB").resize(size, Image.LANCZOS)
    kw = {"quality": 92}
    if exif:
        kw["exif"] = exif
    im.save(out, **kw)
    print(f"{p.name}: {w}x{h} -> {size[0]}x{size[1]}")
EOF

DB=$OUT_DIR/database.db
rm -f "$DB"

# 1-3. Sparse reconstruction on the CPU.
run 1-feature_extractor colmap feature_extractor \
    --database_path "$DB" --image_path "$OUT_DIR/images" \
    --ImageReader.single_camera 1 --ImageReader.camera_model "$CAMERA_MODEL" \
    --SiftExtraction.use_gpu 0 --SiftExtraction.num_threads 2 \
    --SiftExtraction.max_num_features "$MAX_FEATURES"
run 2-exhaustive_matcher colmap exhaustive_matcher \
    --database_path "$DB" --SiftMatching.use_gpu 0 --SiftMatching.num_threads 2
rm -rf "$OUT_DIR/sparse"/*
mkdir -p "$OUT_DIR/sparse"
run 3-mapper colmap mapper \
    --database_path "$DB" --image_path "$OUT_DIR/images" --output_path "$OUT_DIR/sparse" \
    --Mapper.num_threads 2
[[ -f "$OUT_DIR/sparse/0/images.bin" ]] || {
    echo "mapper produced no model" >&2
    exit 1
}

# 4. Text copy of the distorted model.
mkdir -p "$OUT_DIR/sparse/0-txt"
run 4-model_converter colmap model_converter \
    --input_path "$OUT_DIR/sparse/0" --output_path "$OUT_DIR/sparse/0-txt" --output_type TXT

# 5-6. Undistorted workspace (PINHOLE) and its text copy.
rm -rf "$OUT_DIR/dense"
run 5-image_undistorter colmap image_undistorter \
    --image_path "$OUT_DIR/images" --input_path "$OUT_DIR/sparse/0" \
    --output_path "$OUT_DIR/dense" --output_type COLMAP
mkdir -p "$OUT_DIR/dense/sparse-txt"
run 6-model_converter colmap model_converter \
    --input_path "$OUT_DIR/dense/sparse" --output_path "$OUT_DIR/dense/sparse-txt" --output_type TXT

# 7. COLMAP's own statistics (mean reprojection error) of both models.
run 7-model_analyzer colmap model_analyzer --path "$OUT_DIR/sparse/0"
run 7-model_analyzer-dense colmap model_analyzer --path "$OUT_DIR/dense/sparse"

echo "done: $OUT_DIR"
cat "$TIMES"
grep -h -i -E "registered|reprojection" "$LOGS"/7-model_analyzer*.log || true
