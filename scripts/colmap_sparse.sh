#!/usr/bin/env bash
# Photos -> COLMAP sparse model (binary + text) -> undistorted dense workspace, CPU only.
# Made for internet collections: any mix of cameras, sizes, orientations and colour modes.
#
# Usage: scripts/colmap_sparse.sh IMAGE_DIR OUT_DIR [--max-size PX] [--camera-model MODEL]
#            [--cameras per-photo|per-model|single] [--max-features N]
#            [--matcher exhaustive|sequential] [--dense-size PX]
#
#   --dense-size PX      undistorted photos at most PX on the longer side (default: as given)
#   --cameras per-photo  (default) one camera (intrinsics) per photo: internet photos come
#                        from different cameras and zoom settings
#             per-model  one camera per EXIF make + model + focal length + image size; photos
#                        without EXIF make/model keep their own
#             single     one camera for all (every photo must have the same size)
#
# Steps (each timed, one log per step in OUT_DIR/logs/):
#   0. photos_prepare.py   -> OUT_DIR/images: EXIF orientation applied, grey/CMYK/16-bit/alpha
#                             converted to 8-bit RGB, downscaled to --max-size; undecodable
#                             files skipped and listed (OUT_DIR/manifest.json)
#   1. feature_extractor   (SIFT on the CPU, camera model SIMPLE_RADIAL by default, at most
#                          --max-features keypoints per photo, COLMAP's 8192 by default)
#      1b. (per-model) photos of one EXIF camera and size made to share one camera
#   2. exhaustive_matcher  (or sequential_matcher) on the CPU
#   3. mapper              (at least 3 photos per model; several models when the photos fall
#                          apart); when the largest model misses photos, 3b reruns the mapper
#                          with relaxed thresholds and the model with more photos is kept
#                          -> OUT_DIR/sparse/0 (binary): always the largest model
#   4. model_converter     -> OUT_DIR/sparse/0-txt (text copy of the same model)
#   5. image_undistorter   -> OUT_DIR/dense/{images,sparse} (PINHOLE model, undistorted photos)
#   6. model_converter     -> OUT_DIR/dense/sparse-txt (text copy of the undistorted model)
#   7. model_analyzer      -> OUT_DIR/logs/7-model_analyzer*.log (COLMAP's own statistics)
#   8. registration        -> OUT_DIR/registration.json and OUT_DIR/unregistered.txt: photos
#                             given, decoded, registered in the kept model, and the rest
#
# Needs Debian's `colmap` (3.8, built without CUDA) and python3-pil; installs them with
# apt-get when missing. Runs headless (QT_QPA_PLATFORM=offscreen).
set -euo pipefail

usage() {
    sed -n 5,7p "$0" >&2
    exit 2
}

[[ $# -ge 2 ]] || usage
IMAGE_DIR=$(realpath "$1")
OUT_DIR=$2
shift 2
MAX_SIZE=0
CAMERA_MODEL="SIMPLE_RADIAL"
CAMERAS=per-photo
MAX_FEATURES=8192
MATCHER=exhaustive
DENSE_SIZE=-1
while [[ $# -gt 0 ]]; do
    [[ $# -ge 2 ]] || usage
    case "$1" in
    --max-size) MAX_SIZE=$2 ;;
    --max-features) MAX_FEATURES=$2 ;;
    --dense-size) DENSE_SIZE=$2 ;;
    --camera-model) CAMERA_MODEL=$2 ;;
    --cameras)
        CAMERAS=$2
        [[ $CAMERAS == per-photo || $CAMERAS == per-model || $CAMERAS == single ]] || usage
        ;;
    --matcher)
        MATCHER=$2
        [[ $MATCHER == exhaustive || $MATCHER == sequential ]] || usage
        ;;
    *) usage ;;
    esac
    shift 2
done
[[ -d $IMAGE_DIR ]] || {
    echo "$IMAGE_DIR: not a folder of photos" >&2
    exit 1
}

export QT_QPA_PLATFORM=offscreen
SCRIPTS=$(cd "$(dirname "$0")" && pwd)

# Tools: install when missing (Debian/Ubuntu).
need_apt=()
command -v colmap >/dev/null 2>&1 || need_apt+=(colmap)
command -v bc >/dev/null 2>&1 || need_apt+=(bc)
/usr/bin/python3 -c "import PIL" >/dev/null 2>&1 || need_apt+=(python3-pil)
if [[ ${#need_apt[@]} -gt 0 ]]; then
    echo "installing ${need_apt[*]} with apt-get"
    apt-get update
    DEBIAN_FRONTEND=noninteractive apt-get install -y "${need_apt[@]}"
fi

# An OUT_DIR that holds anything must be one this script made (it has logs/timings.tsv):
# what it replaces below is then its own earlier output.
if [[ -d $OUT_DIR && -n $(ls -A "$OUT_DIR") && ! -f $OUT_DIR/logs/timings.tsv ]]; then
    echo "$OUT_DIR: not empty and not made by colmap_sparse.sh (no logs/timings.tsv);" \
        "choose an empty or new folder" >&2
    exit 1
fi
mkdir -p "$OUT_DIR/logs"
OUT_DIR=$(realpath "$OUT_DIR")
# Only what this script writes is replaced.
rm -rf "$OUT_DIR/images" "$OUT_DIR/sparse" "$OUT_DIR/sparse-relaxed" "$OUT_DIR/dense" \
    "$OUT_DIR/database.db" "$OUT_DIR/manifest.json" "$OUT_DIR/registration.json" \
    "$OUT_DIR/unregistered.txt"
mkdir -p "$OUT_DIR/images" "$OUT_DIR/sparse"
LOGS=$OUT_DIR/logs
TIMES=$LOGS/timings.tsv
printf 'step\tseconds\n' >"$TIMES"

# run NAME CMD...: one step, its output in logs/NAME.log, its wall time in timings.tsv.
# shellcheck source=steps.sh
source "$(dirname "$(realpath "${BASH_SOURCE[0]}")")/steps.sh"

# 0. Upright 8-bit RGB photos in OUT_DIR/images.
run 0-prepare_images /usr/bin/python3 "$SCRIPTS/photos_prepare.py" "$IMAGE_DIR" \
    "$OUT_DIR/images" --max-size "$MAX_SIZE" --manifest "$OUT_DIR/manifest.json"
grep -h "skipped" "$LOGS/0-prepare_images.log" || true

DB=$OUT_DIR/database.db

# 1. Features; one camera per photo unless asked otherwise.
SINGLE=0
[[ $CAMERAS == single ]] && SINGLE=1
run 1-feature_extractor colmap feature_extractor \
    --database_path "$DB" --image_path "$OUT_DIR/images" \
    --ImageReader.single_camera "$SINGLE" --ImageReader.camera_model "$CAMERA_MODEL" \
    --SiftExtraction.use_gpu 0 --SiftExtraction.num_threads 2 \
    --SiftExtraction.max_num_features "$MAX_FEATURES"
if [[ $CAMERAS == per-model ]]; then
    run 1b-group_cameras /usr/bin/python3 - "$DB" "$OUT_DIR/manifest.json" <<'EOF'
# Photos with the same EXIF make, model, focal length and size share the first one's camera.
import json, sqlite3, sys
db, manifest = sys.argv[1], json.load(open(sys.argv[2]))
key = {}
for p in manifest["photos"]:
    if p["make"] or p["model"]:
        key[p["name"]] = (p["make"], p["model"], p["focal_mm"], p["focal_35mm"], tuple(p["size"]))
con = sqlite3.connect(db)
first = {}
for image_id, name, camera_id in con.execute("SELECT image_id, name, camera_id FROM images ORDER BY image_id"):
    k = key.get(name)
    if k is None:
        continue
    if k in first:
        con.execute("UPDATE images SET camera_id=? WHERE image_id=?", (first[k], image_id))
    else:
        first[k] = camera_id
con.execute("DELETE FROM cameras WHERE camera_id NOT IN (SELECT camera_id FROM images)")
con.commit()
n = con.execute("SELECT COUNT(*) FROM cameras").fetchone()[0]
m = con.execute("SELECT COUNT(*) FROM images").fetchone()[0]
print(f"{m} photos share {n} cameras")
EOF
fi

# 2. Matching.
run "2-${MATCHER}_matcher" colmap "${MATCHER}_matcher" \
    --database_path "$DB" --SiftMatching.use_gpu 0 --SiftMatching.num_threads 2

# largest_model DIR: prints "N PATH" for the model under DIR with the most photos ("0 ").
largest_model() {
    local best="" best_n=0 m n
    for m in "$1"/*/; do
        [[ -f $m/images.bin ]] || continue
        n=$(od -An -tu8 -N8 "$m/images.bin" | tr -d ' ')
        if ((n > best_n)); then best=$m best_n=$n; fi
    done
    echo "$best_n $best"
}

# 3. Mapper; 3b. relaxed thresholds when photos are missing from the largest model.
N_PHOTOS=$(find "$OUT_DIR/images" -maxdepth 1 -type f | wc -l)
mkdir -p "$OUT_DIR/sparse-default"
try 3-mapper colmap mapper \
    --database_path "$DB" --image_path "$OUT_DIR/images" \
    --output_path "$OUT_DIR/sparse-default" \
    --Mapper.num_threads 2 --Mapper.min_model_size 3 || true
read -r N_DEFAULT BEST < <(largest_model "$OUT_DIR/sparse-default") || true
echo "mapper: largest model has $N_DEFAULT of $N_PHOTOS photos"
if ((N_DEFAULT < N_PHOTOS)); then
    mkdir -p "$OUT_DIR/sparse-relaxed"
    try 3b-mapper_relaxed colmap mapper \
        --database_path "$DB" --image_path "$OUT_DIR/images" \
        --output_path "$OUT_DIR/sparse-relaxed" --Mapper.num_threads 2 \
        --Mapper.init_min_num_inliers 30 --Mapper.init_min_tri_angle 2 \
        --Mapper.abs_pose_min_num_inliers 10 --Mapper.abs_pose_min_inlier_ratio 0.1 \
        --Mapper.min_num_matches 10 --Mapper.min_model_size 3 || true
    read -r N_RELAXED BEST_RELAXED < <(largest_model "$OUT_DIR/sparse-relaxed") || true
    echo "relaxed mapper: largest model has $N_RELAXED of $N_PHOTOS photos"
    if ((N_RELAXED > N_DEFAULT)); then
        BEST=$BEST_RELAXED
    fi
fi
[[ -n $BEST ]] || {
    echo "$IMAGE_DIR: no 3 photos register together (too few shared features; see" \
        "$LOGS/3-mapper.log and $LOGS/3b-mapper_relaxed.log)" >&2
    exit 1
}
mkdir -p "$OUT_DIR/sparse/0"
cp "$BEST"/*.bin "$OUT_DIR/sparse/0/"
rm -rf "$OUT_DIR/sparse-default" "$OUT_DIR/sparse-relaxed"

# 4. Text copy of the distorted model.
mkdir -p "$OUT_DIR/sparse/0-txt"
run 4-model_converter colmap model_converter \
    --input_path "$OUT_DIR/sparse/0" --output_path "$OUT_DIR/sparse/0-txt" --output_type TXT

# 5-6. Undistorted workspace (PINHOLE) and its text copy.
run 5-image_undistorter colmap image_undistorter \
    --image_path "$OUT_DIR/images" --input_path "$OUT_DIR/sparse/0" \
    --output_path "$OUT_DIR/dense" --output_type COLMAP --max_image_size "$DENSE_SIZE"
mkdir -p "$OUT_DIR/dense/sparse-txt"
run 6-model_converter colmap model_converter \
    --input_path "$OUT_DIR/dense/sparse" --output_path "$OUT_DIR/dense/sparse-txt" --output_type TXT

# 7. COLMAP's own statistics (mean reprojection error) of both models.
run 7-model_analyzer colmap model_analyzer --path "$OUT_DIR/sparse/0"
run 7-model_analyzer-dense colmap model_analyzer --path "$OUT_DIR/dense/sparse"

# 8. Which photos made it.
run 8-registration /usr/bin/python3 - "$OUT_DIR" <<'EOF'
import json, pathlib, sys
out = pathlib.Path(sys.argv[1])
manifest = json.loads((out / "manifest.json").read_text())
rows = [l for l in (out / "sparse" / "0-txt" / "images.txt").read_text().splitlines()
        if l and not l.startswith("#")][0::2]
registered = sorted(l.split(None, 9)[9] for l in rows)
decoded = [p["name"] for p in manifest["photos"]]
missing = sorted(set(decoded) - set(registered))
given = len(decoded) + len(manifest["skipped"])
r = dict(photos_given=given, photos_decoded=len(decoded), registered=len(registered),
         registered_fraction=len(registered) / given if given else 0.0,
         cameras=sum(1 for l in (out / "sparse" / "0-txt" / "cameras.txt").read_text().splitlines()
                     if l and not l.startswith("#")),
         unregistered=missing, skipped=manifest["skipped"], registered_names=registered)
(out / "registration.json").write_text(json.dumps(r, indent=1) + "\n")
lines = [f"{n}\tnot in the largest model" for n in missing]
lines += [f"{s['source']}\t{s['reason']}" for s in manifest["skipped"]]
(out / "unregistered.txt").write_text("".join(l + "\n" for l in lines))
print(f"registered {len(registered)} of {given} photos ({r['registered_fraction']:.0%}), "
      f"{r['cameras']} cameras")
for l in lines:
    print("  left out: " + l.replace("\t", ": "))
EOF

echo "done: $OUT_DIR"
cat "$TIMES"
cat "$LOGS/8-registration.log"
grep -h -i -E "registered|reprojection" "$LOGS"/7-model_analyzer*.log || true
