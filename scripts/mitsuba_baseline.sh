#!/usr/bin/env bash
# Runs scripts/mitsuba_baseline.py (a Mitsuba 3 differentiable-rendering peer, issue 26
# item 4) in a virtual environment under .tools/mitsuba-venv, creating it on first use
# with the pinned PyPI packages below (~150 MB).
#
#   scripts/mitsuba_baseline.sh WORKSPACE [--relight-report OUT/report.json] [--out DIR] ...
#   scripts/mitsuba_baseline.sh WORKSPACE --check     # arguments and workspace only
#
# Mitsuba's LLVM variant (llvm_ad_rgb, CPU) loads the system's LLVM shared library at run
# time. Dr.Jit 1.5 needs a recent one: LLVM 14 and 15 abort with "LLVM ERROR: Cannot
# select: ... fminimum"; LLVM 19 works (Debian 12: `apt-get install libllvm19`). Unless
# DRJIT_LIBLLVM_PATH is set, the newest libLLVM-N.so (N ≥ 16) found is used.
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(dirname "$here")"
venv="${MITSUBA_VENV:-$root/.tools/mitsuba-venv}"

for arg in "$@"; do
  if [[ "$arg" == "--check" ]]; then
    exec python3 "$here/mitsuba_baseline.py" "$@"
  fi
done

if [[ ! -x "$venv/bin/python" ]] || ! "$venv/bin/python" -c "import mitsuba, drjit, numpy" 2>/dev/null; then
  echo "installing Mitsuba into $venv" >&2
  python3 -m venv "$venv"
  "$venv/bin/pip" install --quiet "mitsuba==3.9.1" "drjit==1.5.0" "numpy>=1.24"
fi

if [[ -z "${DRJIT_LIBLLVM_PATH:-}" ]]; then
  best=""
  best_n=0
  for lib in /usr/lib/x86_64-linux-gnu/libLLVM-*.so /usr/lib/aarch64-linux-gnu/libLLVM-*.so /usr/lib/llvm-*/lib/libLLVM*.so; do
    [[ -e "$lib" ]] || continue
    n="$(basename "$lib" | sed -E 's/^libLLVM-?([0-9]+).*/\1/')"
    [[ "$n" =~ ^[0-9]+$ ]] || n="$(echo "$lib" | sed -E 's#.*/llvm-([0-9]+)/.*#\1#')"
    [[ "$n" =~ ^[0-9]+$ ]] || continue
    if (( n >= 16 && n > best_n )); then
      best="$lib"
      best_n="$n"
    fi
  done
  if [[ -z "$best" ]]; then
    echo "error: no LLVM shared library of version 16 or newer found; Mitsuba's LLVM variant needs one" >&2
    echo "       (Debian 12: apt-get install libllvm19; or set DRJIT_LIBLLVM_PATH)" >&2
    exit 2
  fi
  export DRJIT_LIBLLVM_PATH="$best"
fi

exec "$venv/bin/python" "$here/mitsuba_baseline.py" "$@"
