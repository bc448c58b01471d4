#!/bin/sh
# Build the libFuzzer harnesses and run each one for SECONDS (default 20; CI: 20 -> 100 s total).
#   tools/fuzz/run_fuzz.sh [SECONDS] [HARNESS...]
# Environment: BUILD_DIR (default build/fuzz), CC (default clang), MAGCAL_SHARED_DIR (optional
# extra dumps for the seed corpus), FUZZ_FLAGS (extra libFuzzer flags, e.g. -workers=1 -jobs=1).
# Exit status: 0 when no harness crashed, 1 on any crash/leak/timeout/invariant failure (the
# reproducer is left in $BUILD_DIR/tools/fuzz/artifacts/), 2 on a build error.
set -eu
SECS=${1:-20}
[ $# -gt 0 ] && shift
HARNESSES=${*:-"replay_csv calibrator cluster 3d cont cont3"}
SRC=$(cd "$(dirname "$0")/../.." && pwd)
BUILD_DIR=${BUILD_DIR:-$SRC/build/fuzz}
CC=${CC:-clang}
export CC

shared_arg=""
if [ -n "${MAGCAL_SHARED_DIR:-}" ]; then
    shared_arg="-DMAGCAL_SHARED_DIR=$MAGCAL_SHARED_DIR"
fi
cmake -S "$SRC" -B "$BUILD_DIR" -DMAGCAL_FUZZ=ON -DBUILD_TESTING=OFF -DCMAKE_BUILD_TYPE=RelWithDebInfo \
      $shared_arg >"$BUILD_DIR.configure.log" 2>&1 || { cat "$BUILD_DIR.configure.log"; exit 2; }
targets=""
for h in $HARNESSES; do targets="$targets fuzz_$h"; done
# shellcheck disable=SC2086
cmake --build "$BUILD_DIR" -j2 --target $targets fuzz_corpus || exit 2

FZ=$BUILD_DIR/tools/fuzz
mkdir -p "$FZ/artifacts"
fail=0
for h in $HARNESSES; do
    case $h in
        replay_csv) maxlen=8192 ;;
        3d) maxlen=9200 ;;      # ~1300 synthetic epochs (7 bytes) + header
        cont) maxlen=16384 ;;   # ~1000 push ops (15 bytes) + the other ops + header
        cont3) maxlen=12000 ;;  # ~1000 synthetic pushes (8 bytes) + steps + header
        *) maxlen=8300 ;;       # 1024 float32 samples + header
    esac
    work=$FZ/work/$h            # grows across runs; seeds stay in $FZ/corpus/$h
    mkdir -p "$work"
    log=$FZ/fuzz_$h.log
    echo "== fuzz_$h for ${SECS}s (log $log)"
    # shellcheck disable=SC2086
    if "$FZ/fuzz_$h" -max_total_time="$SECS" -timeout=25 -max_len=$maxlen -print_final_stats=1 \
           -artifact_prefix="$FZ/artifacts/$h-" ${FUZZ_FLAGS:-} "$work" "$FZ/corpus/$h" >"$log" 2>&1; then
        grep -E '^#[0-9]+ +DONE|stat::number_of_executed_units' "$log" || true
    else
        echo "FAIL: fuzz_$h crashed; reproducer in $FZ/artifacts/$h-*"
        grep -E 'ERROR|FUZZ INVARIANT|runtime error|SUMMARY' "$log" | head -20
        fail=1
    fi
done
exit $fail
