#!/usr/bin/env bash
# End-to-end check of the COLMAP scripts on an awkward photo folder, figures to a file.
#
# Usage: scripts/colmap_check_mixed.sh [WORK_DIR] [-- RUN_OPTIONS...]
#
# Runs scripts/photos.sh on examples/buddha-mixed/photos (13 real photos with rotated EXIF
# orientations, grey, CMYK, 16-bit PNG, other sizes and aspect ratios, one exposure change,
# plus a truncated file and a noise image; see its README) into WORK_DIR (default: a fresh
# mktemp -d; an earlier WORK_DIR resumes), then scripts/photos_check.py: registration, mesh
# figures, per-step wall and CPU seconds, and the registered camera centres against the
# dataset's own calibration (fails above 15% of the rig radius). Writes
# bench-results/colmap-buddha-mixed.md. COLMAP-heavy (minutes on 2 cores): not part of
# `cargo test`.
set -euo pipefail

REPO=$(cd "$(dirname "$0")/.." && pwd)
WORK=${1:-$(mktemp -d)}
[[ $# -ge 1 ]] && shift
[[ ${1:-} == -- ]] && shift
RUN_ARGS=("$@")
[[ ${#RUN_ARGS[@]} -gt 0 ]] || RUN_ARGS=(--holdout-every 4)
EXAMPLE=$REPO/examples/buddha-mixed
CMD="scripts/photos.sh examples/buddha-mixed/photos --out WORK -- ${RUN_ARGS[*]}"
"$REPO/scripts/photos.sh" "$EXAMPLE/photos" --out "$WORK" -- "${RUN_ARGS[@]}"
VENV=${RELIGHT_VENV:-$HOME/.cache/relight-cpc/venv}
mkdir -p "$REPO/bench-results"
"$VENV/bin/python" "$REPO/scripts/photos_check.py" "$WORK" \
    --report "$REPO/bench-results/colmap-buddha-mixed.md" \
    --calibration "$EXAMPLE/calibration.txt" --command "$CMD ($(date -u +%F), $(nproc) cores)"
