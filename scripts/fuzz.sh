#!/usr/bin/env bash
# Fuzz the COLMAP text / binary readers, the PLY reader and the EXR environment-map reader
# for a bounded time (issues 8, 23).
#   scripts/fuzz.sh [SECONDS_PER_TARGET=60] [SEED=1] [TARGET...]   (default: every target)
# Uses cargo-fuzz (libFuzzer) when `cargo fuzz` is installed and works on this toolchain
# (stable needs RUSTC_BOOTSTRAP=1 for its -Z flags); otherwise the stable driver
# fuzz/src/bin/mutate.rs (random mutation of the real COLMAP fixture files and PLY meshes).
# Crashing inputs land in fuzz/artifacts/<target>/; the exit status is 1 if any was found.
# Any crash found must become a test (tests/suite/proptest_parsers.rs).
set -euo pipefail
SECS=${1:-60}
SEED=${2:-1}
shift $(( $# < 2 ? $# : 2 ))
TARGETS=${*:-colmap_text colmap_binary ply envmap}
ROOT=$(cd "$(dirname "$0")/.." && pwd)
cd "$ROOT/fuzz"
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$ROOT/target}"
FX="$ROOT/tests/fixtures"
corpus() {
  case $1 in
    colmap_text) ls "$FX"/colmap-buddha/sparse/0/*.txt ;;
    colmap_binary) ls "$FX"/colmap-buddha/sparse/0/*.bin ;;
    ply) ls "$FX"/synth/spot.ply "$FX"/colmap-dense-buddha/dense/meshed-poisson.ply 2>/dev/null ;;
    envmap) ls "$FX"/synth/hdri/studio.exr "$FX"/synth/hdri/night.exr ;;
  esac
}
status=0
if cargo fuzz --version >/dev/null 2>&1; then
  for t in $TARGETS; do
    mkdir -p "corpus/$t"
    for f in $(corpus $t); do
      if [ "$t" = ply ] || [ "$t" = envmap ]; then cp "$f" "corpus/$t/"; else
        for k in 0 1 2; do printf "\\x0$k" | cat - "$f" > "corpus/$t/$k-$(basename "$f")"; done; fi
    done
    RUSTC_BOOTSTRAP=1 cargo fuzz run --features libfuzzer "$t" "corpus/$t" -- \
      -max_total_time="$SECS" -seed="$SEED" -max_len=1000000 || status=1
  done
else
  echo "cargo-fuzz not available: using the stable mutation driver" >&2
  cargo build --release --bin mutate
  for t in $TARGETS; do
    # shellcheck disable=SC2046
    "$CARGO_TARGET_DIR/release/mutate" "$t" "$SECS" "$SEED" $(corpus $t) || status=1
  done
fi
exit $status
