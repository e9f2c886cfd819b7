# Shared by the colmap_*.sh scripts (sourced, not run).
# run NAME CMD...: run one step with its output in $LOGS/NAME.log and its wall time appended
# to $TIMES (both set by the calling script); on failure, print the log's tail and exit 1.
run() {
    local name=$1
    shift
    local t0 t1
    t0=$(date +%s.%N)
    echo "[$(date -u +%H:%M:%S)] $name: $*"
    if ! "$@" >"$LOGS/$name.log" 2>&1; then
        echo "step $name failed; see $LOGS/$name.log" >&2
        tail -20 "$LOGS/$name.log" >&2
        exit 1
    fi
    t1=$(date +%s.%N)
    printf '%s\t%.2f\n' "$name" "$(echo "$t1 - $t0" | bc)" >>"$TIMES"
}

# try NAME CMD...: like run, but a failing command only returns its status (logged and timed).
try() {
    local name=$1
    shift
    local t0 t1 status=0
    t0=$(date +%s.%N)
    echo "[$(date -u +%H:%M:%S)] $name: $*"
    "$@" >"$LOGS/$name.log" 2>&1 || status=$?
    t1=$(date +%s.%N)
    printf '%s\t%.2f\n' "$name" "$(echo "$t1 - $t0" | bc)" >>"$TIMES"
    return $status
}
