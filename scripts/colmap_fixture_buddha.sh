#!/usr/bin/env bash
# Rebuild tests/fixtures/colmap-buddha from the Buddha photos with real COLMAP (CPU only).
#
# Usage: scripts/colmap_fixture_buddha.sh [DATA_DIR] [WORK_DIR]
#   DATA_DIR  folder holding photos/buddha-gray (default: ../shared/data relative to the repo)
#   WORK_DIR  scratch folder for the full COLMAP run (default: a fresh mktemp -d)
#
# Picks 8 of the 30 grayscale views (the 8 most strongly matched neighbours, chosen from an
# exhaustive match of all 30 at 512 px), runs scripts/colmap_sparse.sh on them at 512 px,
# and copies into the fixture only what tests need: the downscaled photos, the distorted
# model (sparse/0, binary + text side by side), the undistorted workspace (dense/images,
# dense/sparse binary + text) and COLMAP's own model_analyzer output and step timings.
set -euo pipefail

REPO=$(cd "$(dirname "$0")/.." && pwd)
DATA_DIR=${1:-$REPO/../shared/data}
WORK_DIR=${2:-$(mktemp -d)}
FIXTURE=$REPO/tests/fixtures/colmap-buddha
VIEWS="00010 00018 00019 00021 00026 00043 00056 00066"

SRC=$WORK_DIR/photos
mkdir -p "$SRC"
for v in $VIEWS; do
    cp "$DATA_DIR/photos/buddha-gray/$v.jpg" "$SRC/"
done

"$REPO/scripts/colmap_sparse.sh" "$SRC" "$WORK_DIR/colmap" --max-size 512 --cameras single

OUT=$WORK_DIR/colmap
rm -rf "$FIXTURE/images" "$FIXTURE/sparse" "$FIXTURE/dense" "$FIXTURE/logs"
mkdir -p "$FIXTURE/images" "$FIXTURE/sparse/0" "$FIXTURE/dense/images" "$FIXTURE/dense/sparse" \
    "$FIXTURE/logs"
cp "$OUT"/images/*.jpg "$FIXTURE/images/"
cp "$OUT"/sparse/0/*.bin "$OUT"/sparse/0-txt/*.txt "$FIXTURE/sparse/0/"
cp "$OUT"/dense/images/*.jpg "$FIXTURE/dense/images/"
cp "$OUT"/dense/sparse/*.bin "$OUT"/dense/sparse-txt/*.txt "$FIXTURE/dense/sparse/"
cp "$OUT"/logs/7-model_analyzer.log "$OUT"/logs/7-model_analyzer-dense.log \
    "$OUT"/logs/timings.tsv "$FIXTURE/logs/"
du -sh "$FIXTURE"
