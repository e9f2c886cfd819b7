#!/usr/bin/env bash
# A folder of photos -> COLMAP workspace with a mesh -> relight-cpc result, in one command.
#
# Usage: scripts/photos.sh PHOTO_DIR --out OUT [--max-size PX] [--dense-size PX]
#            [--cameras per-photo|per-model|single] [--relight BIN] [--from STEP]
#            [dense options of scripts/colmap_dense.sh ...] [-- RUN_OPTIONS...]
#
#   --max-size PX    photos downscaled to at most PX on the longer side for SfM (default 1280)
#   --dense-size PX  undistorted photos (depth maps, mesh sampling, `run`) at most PX (default:
#                    the SfM size; colmap_sparse.sh's option)
#   --cameras        one camera per photo (default), per EXIF model and size, or one for all
#   --relight BIN    the relight-cpc binary (default: relight-cpc on PATH, else the
#                    repository's target/release/relight-cpc, built with cargo when missing)
#   --from STEP      redo STEP (sparse, dense or run) and the steps after it
#   -- RUN_OPTIONS   passed to `relight-cpc run` (e.g. -- --holdout-every 4)
#
# Steps, each with a line when it starts and its wall time when it ends:
#   1/3 sparse  scripts/colmap_sparse.sh PHOTO_DIR OUT/colmap: photos prepared (orientation,
#               colour modes), SIFT, matching, mapper (largest model), undistorted workspace;
#               OUT/colmap/registration.json and unregistered.txt list what was left out
#   2/3 dense   scripts/colmap_dense.sh OUT/colmap: depth maps, fusion, Poisson, mesh cropped
#               to what the photos share -> OUT/colmap/dense/meshed-poisson.ply
#   3/3 run     relight-cpc run OUT/colmap --out OUT/result RUN_OPTIONS
#
# Resuming: a finished step leaves OUT/.steps/NAME.done holding its command line; run again,
# a step whose stamp matches its command line is skipped, so an interrupted run picks up where
# it stopped. A step that runs again (changed options, --from) removes the later steps'
# stamps. OUT/timings.tsv has each step's wall and CPU seconds (/usr/bin/time, all child
# processes; of the run that did it), OUT/photos.log this script's own lines.
set -euo pipefail

usage() {
    sed -n 4,6p "$0" >&2
    exit 2
}

[[ $# -ge 1 ]] || usage
PHOTOS=$1
shift
OUT=""
MAX_SIZE=1280
DENSE_SIZE=""
CAMERAS=per-photo
RELIGHT=""
FROM=""
DENSE_ARGS=()
RUN_ARGS=()
while [[ $# -gt 0 ]]; do
    if [[ $1 == -- ]]; then
        shift
        RUN_ARGS=("$@")
        break
    fi
    [[ $# -ge 2 ]] || usage
    case "$1" in
    --out) OUT=$2 ;;
    --max-size) MAX_SIZE=$2 ;;
    --dense-size) DENSE_SIZE=$2 ;;
    --cameras) CAMERAS=$2 ;;
    --relight) RELIGHT=$2 ;;
    --from)
        FROM=$2
        [[ $FROM == sparse || $FROM == dense || $FROM == run ]] || usage
        ;;
    --poisson-depth | --min-num-pixels | --max-normal-error | --trim-factor | --min-component | \
        --neighbours | --max-angle | --clahe | --geom-views | --min-views | --target-faces | --venv)
        DENSE_ARGS+=("$1" "$2")
        ;;
    *) usage ;;
    esac
    shift 2
done
[[ -n $OUT ]] || usage
[[ -d $PHOTOS ]] || {
    echo "$PHOTOS: not a folder of photos" >&2
    exit 1
}
PHOTOS=$(realpath "$PHOTOS")
SCRIPTS=$(cd "$(dirname "$0")" && pwd)
REPO=$(cd "$SCRIPTS/.." && pwd)
mkdir -p "$OUT/.steps"
OUT=$(realpath "$OUT")
WS=$OUT/colmap
RESULT=$OUT/result
STAMPS=$OUT/.steps
[[ -f $OUT/timings.tsv ]] || printf 'step\twall_s\tcpu_s\n' >"$OUT/timings.tsv"

say() {
    echo "[$(date -u +%H:%M:%S)] $*" | tee -a "$OUT/photos.log"
}

# The photos' names, sizes and times: a changed folder reruns everything.
fingerprint() {
    find "$PHOTOS" -maxdepth 1 -type f -printf '%f %s %T@\n' | sort | md5sum | cut -d' ' -f1
}

STEPS=(sparse dense run)
if [[ -n $FROM ]]; then
    drop=0
    for s in "${STEPS[@]}"; do
        [[ $s == "$FROM" ]] && drop=1
        ((drop)) && rm -f "$STAMPS/$s.done"
    done
fi

# step INDEX NAME CMD...: skip when NAME's stamp holds this command line, else run it (its
# output in OUT/NAME.out), time it and stamp it; later stamps are removed first.
step() {
    local idx=$1 name=$2
    shift 2
    local line
    line="$(printf '%q ' "$@")photos=$(fingerprint)"
    if [[ -f $STAMPS/$name.done && $(cat "$STAMPS/$name.done") == "$line" ]]; then
        say "step $idx $name: finished earlier, skipped (stamp $STAMPS/$name.done)"
        return
    fi
    local later=0 s
    for s in "${STEPS[@]}"; do
        [[ $s == "$name" ]] && later=1
        if ((later)); then
            rm -f "$STAMPS/$s.done"
            # Its timing row and the later steps' rows belong to the run being replaced.
            grep -v -P "^$s\t" "$OUT/timings.tsv" >"$OUT/timings.tsv.new" || true
            mv "$OUT/timings.tsv.new" "$OUT/timings.tsv"
        fi
    done
    say "step $idx $name: $*"
    : >"$OUT/$name.out"
    local t0 wall cpu
    t0=$(date +%s)
    if ! /usr/bin/time -f '%e %U %S' -o "$STAMPS/$name.time" "$@" >>"$OUT/$name.out" 2>&1; then
        say "step $idx $name failed after $(($(date +%s) - t0)) s; last lines of $OUT/$name.out:"
        tail -15 "$OUT/$name.out" >&2
        exit 1
    fi
    read -r wall cpu < <(awk '{printf "%.0f %.0f\n", $1, $2 + $3}' "$STAMPS/$name.time")
    printf '%s\t%s\t%s\n' "$name" "$wall" "$cpu" >>"$OUT/timings.tsv"
    echo "$line" >"$STAMPS/$name.done"
    say "step $idx $name: done in $wall s ($cpu s of CPU)"
}

[[ -x /usr/bin/time ]] || {
    say "installing time with apt-get"
    apt-get update >/dev/null && DEBIAN_FRONTEND=noninteractive apt-get install -y time >/dev/null
}

# The relight-cpc binary.
if [[ -z $RELIGHT ]]; then
    if command -v relight-cpc >/dev/null 2>&1; then
        RELIGHT=$(command -v relight-cpc)
    else
        RELIGHT=$REPO/target/release/relight-cpc
        if [[ ! -x $RELIGHT ]]; then
            say "building relight-cpc (cargo build --release)"
            (cd "$REPO" && cargo build --release --quiet)
        fi
    fi
fi

SPARSE=("$SCRIPTS/colmap_sparse.sh" "$PHOTOS" "$WS" --max-size "$MAX_SIZE" --cameras "$CAMERAS")
[[ -n $DENSE_SIZE ]] && SPARSE+=(--dense-size "$DENSE_SIZE")
step 1/3 sparse "${SPARSE[@]}"
say "$(tail -n +1 "$WS/logs/8-registration.log" | head -1)"

DENSE=("$SCRIPTS/colmap_dense.sh" "$WS" "${DENSE_ARGS[@]}")
step 2/3 dense "${DENSE[@]}"
say "mesh: $(cat "$WS/logs/mesh_stats.json")"

# `run` replaces a folder only with --force: given always, after checking that a result
# already there is one this script made (run.started is written before the first run).
if [[ -e $RESULT && ! -f $STAMPS/run.started ]]; then
    echo "$RESULT exists and was not written by photos.sh; move it away or choose another --out" >&2
    exit 1
fi
touch "$STAMPS/run.started"
RUN=("$RELIGHT" run "$WS" --out "$RESULT" --force "${RUN_ARGS[@]}")
step 3/3 run "${RUN[@]}"

say "result: $RESULT (report.md); workspace: $WS"
column -t "$OUT/timings.tsv" | tee -a "$OUT/photos.log"
