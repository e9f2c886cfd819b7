#!/usr/bin/env bash
# Rebuild tests/fixtures/colmap-synth: a known-truth synth scene through real COLMAP (CPU only).
#
# Usage: scripts/colmap_fixture_synth.sh [WORK_DIR] [--fixture DIR]
#   WORK_DIR       scratch folder for the renders and the full COLMAP run (default: mktemp -d)
#   --fixture DIR  where the small copy goes (default: tests/fixtures/colmap-synth; give a
#                  scratch folder to compare a rerun with the committed fixture)
#
# 1. `relight-cpc synth spot-textured` renders 24 photos at 640x480 (Spot on a ground plane,
#    two materials in a noise pattern, the courtyard map, static: the same light in every photo).
# 2. The true camera centres (C = -R^T t from the truth's images.txt) go to centres.txt.
# 3. scripts/colmap_workspace.sh on the photos with --centres: SIFT, exhaustive matching,
#    mapper, undistortion, model_aligner into the truth frame, SGBM depth, stereo_fusion,
#    poisson_mesher, cleaning.
# 4. The fixture keeps what `relight-cpc run` and `inspect` need, small:
#    colmap/      the aligned model undistorted again at 160 px (`image_undistorter
#                 --max_image_size 160`: PNG photos + dense/sparse, binary only: the text
#                 copy would add 1.9 MB, mostly keypoints without a 3D point), the
#                 cleaned mesh vertex-clustered to ~12K faces, 5,000 of the fused points,
#                 COLMAP's logs and summary.json, and truth/ (manifest, materials, and the
#                 held-out photos' maps, `run` reads only those, each distinct map once)
#    truth/       the same scene rendered by synth at 160x120 (same seed, so the same cameras
#                 and lights; 300 sparse points): the perfect-truth workspace (its mesh is
#                 the true surface)
set -euo pipefail

REPO=$(cd "$(dirname "$0")/.." && pwd)
WORK=""
FIXTURE=$REPO/tests/fixtures/colmap-synth
while [[ $# -gt 0 ]]; do
    case "$1" in
    --fixture)
        FIXTURE=$(realpath -m "$2")
        shift 2
        ;;
    *)
        WORK=$1
        shift
        ;;
    esac
done
WORK=${WORK:-$(mktemp -d)}
mkdir -p "$WORK"
WORK=$(realpath "$WORK")
export QT_QPA_PLATFORM=offscreen
BIN=${RELIGHT_CPC:-$REPO/target/release/relight-cpc}
[[ -x $BIN ]] || (cd "$REPO" && cargo build --release)
SCENE=spot-textured
SYNTH=(--photos 24 --seed 1 --spp 2 --light-samples 32)
FIX_SIZE=160

# ---- 1. photos with known truth.
if [[ ! -f $WORK/synth/truth/manifest.json ]]; then
    /usr/bin/time -f "synth: %e s" "$BIN" synth "$SCENE" "$WORK/synth" --width 640 --height 480 \
        "${SYNTH[@]}"
fi

# ---- 2. true camera centres.
python3 - "$WORK/synth/sparse/images.txt" >"$WORK/centres.txt" <<'EOF'
import sys
rows = [l.split() for l in open(sys.argv[1]) if l.strip() and not l.startswith("#")][0::2]
for t in rows:
    w, x, y, z = map(float, t[1:5])
    tv = list(map(float, t[5:8]))
    r = [[1 - 2*y*y - 2*z*z, 2*x*y - 2*w*z, 2*x*z + 2*w*y],
         [2*x*y + 2*w*z, 1 - 2*x*x - 2*z*z, 2*y*z - 2*w*x],
         [2*x*z - 2*w*y, 2*y*z + 2*w*x, 1 - 2*x*x - 2*y*y]]
    c = [-sum(r[i][j] * tv[i] for i in range(3)) for j in range(3)]
    print(t[9], *("%.9f" % v for v in c))
EOF

# ---- 3. COLMAP (REUSE=1 keeps a finished run in WORK_DIR and only redoes step 4).
if [[ ${REUSE:-0} != 1 || ! -f $WORK/colmap/summary.json ]]; then
    rm -rf "$WORK/colmap"
    "$REPO/scripts/colmap_workspace.sh" "$WORK/synth/images" "$WORK/colmap" \
        --centres "$WORK/centres.txt" --cameras single
fi
OUT=$WORK/colmap

# ---- 4. the small copy.
rm -rf "$WORK/small"
colmap image_undistorter --image_path "$OUT/images" --input_path "$OUT/sparse/0" \
    --output_path "$WORK/small" --output_type COLMAP --max_image_size $FIX_SIZE \
    >"$OUT/logs/40-image_undistorter-small.log" 2>&1
mkdir -p "$WORK/small/sparse-txt"
colmap model_converter --input_path "$WORK/small/sparse" --output_path "$WORK/small/sparse-txt" \
    --output_type TXT >/dev/null 2>&1
rm -rf "$WORK/truth-small"
"$BIN" synth "$SCENE" "$WORK/truth-small" --width $FIX_SIZE --height $((FIX_SIZE * 3 / 4)) \
    "${SYNTH[@]}" --points 300

rm -rf "$FIXTURE/colmap" "$FIXTURE/truth"
C=$FIXTURE/colmap
mkdir -p "$C/dense/images" "$C/dense/sparse" "$C/logs" "$C/truth/env"
cp "$WORK"/small/images/*.png "$C/dense/images/"
cp "$WORK"/small/sparse/*.bin "$C/dense/sparse/"
cp "$OUT"/logs/{26-model_analyzer.log,22-model_aligner.log,align_transform.txt,timings.tsv} \
    "$OUT"/logs/{mesh_stats.json,40-image_undistorter-small.log} "$OUT/summary.json" "$C/logs/"
cp "$WORK/centres.txt" "$C/logs/"
copy_truth() { # SRC_TRUTH DST_TRUTH: manifest, materials, the held-out photos' maps (`run`
    # reads no other), identical maps stored once (the manifest's `env` entries then point
    # to the one copy: with the scene's static light, all of them do).
    mkdir -p "$2/env"
    cp "$1/materials.json" "$2/"
    python3 - "$1" "$2" <<'EOF'
import hashlib, json, pathlib, shutil, sys
src, dst = pathlib.Path(sys.argv[1]), pathlib.Path(sys.argv[2])
m = json.loads((src / "manifest.json").read_text())
digest = [hashlib.sha256((src / p["env"]).read_bytes()).hexdigest() for p in m["photos"]]
first = {}
for p, d in zip(m["photos"], digest):
    if d not in first and p["held_out"]:
        first[d] = p["env"]
        shutil.copy2(src / p["env"], dst / p["env"])
for p, d in zip(m["photos"], digest):
    p["env"] = first.get(d, p["env"])
(dst / "manifest.json").write_text(json.dumps(m, indent=2, ensure_ascii=False) + "\n")
EOF
}
copy_truth "$WORK/synth/truth" "$C/truth"
VENV=${RELIGHT_VENV:-$HOME/.cache/relight-cpc/venv}
PYTHONPATH=$REPO/scripts "$VENV/bin/python" - "$OUT" "$C" <<'EOF'
import json, pathlib, sys
import numpy as np
import depth_mesh_clean as mc
ws, fx = pathlib.Path(sys.argv[1]), pathlib.Path(sys.argv[2])
pts, _ = mc.read_ply(ws / "dense" / "fused.ply")
idx = np.sort(np.random.default_rng(7).choice(len(pts), min(5000, len(pts)), replace=False))
mc.write_ply(fx / "dense" / "fused.ply", pts[idx])
verts, faces = mc.read_ply(ws / "dense" / "meshed-poisson.ply")
nv, nf = len(verts), len(faces)
if len(faces) > 12000:
    verts, faces = mc.cluster_decimate(verts, faces, 12000)
    verts, faces = mc.compact(verts, faces)
mc.write_ply(fx / "dense" / "meshed-poisson.ply", verts, faces)
print(json.dumps(dict(fused_points=len(pts), fused_points_kept=len(idx), mesh=[nv, nf],
                      mesh_kept=[len(verts), len(faces)])))
EOF

T=$FIXTURE/truth
mkdir -p "$T/images" "$T/sparse" "$T/dense"
cp "$WORK"/truth-small/images/*.png "$T/images/"
cp "$WORK"/truth-small/sparse/*.txt "$T/sparse/"
cp "$WORK/truth-small/dense/meshed-poisson.ply" "$T/dense/"
copy_truth "$WORK/truth-small/truth" "$T/truth"
du -sh "$FIXTURE"/*
