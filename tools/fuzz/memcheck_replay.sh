#!/bin/sh
# valgrind memcheck of magcal-replay on every bundled dump (tests/data/real/*.csv and
# tests/data/synthetic/*.csv), with the JSON report and the per-row headings CSV enabled so every
# code path of the tool runs. Fails on any memcheck error or leak (definite, indirect, possible).
#   tools/fuzz/memcheck_replay.sh BUILD_DIR          (a normal host build, e.g. build/dev)
set -eu
BUILD_DIR=${1:?usage: memcheck_replay.sh BUILD_DIR}
SRC=$(cd "$(dirname "$0")/../.." && pwd)
EXE=$BUILD_DIR/tools/replay/magcal-replay
[ -x "$EXE" ] || { echo "memcheck_replay.sh: $EXE not built"; exit 2; }
command -v valgrind >/dev/null || { echo "memcheck_replay.sh: valgrind not installed"; exit 2; }
OUT=$BUILD_DIR/memcheck
mkdir -p "$OUT"
fail=0
n=0
for dump in "$SRC"/tests/data/real/*.csv "$SRC"/tests/data/synthetic/*.csv; do
    name=$(basename "$dump" .csv)
    n=$((n + 1))
    # exit 0 (calibrated) and 3 (calibration failed: a legitimate result) are both fine here;
    # valgrind's own error exit code is 99 so it cannot be confused with the tool's.
    set +e
    valgrind --quiet --error-exitcode=99 --leak-check=full --show-leak-kinds=definite,indirect,possible \
             --errors-for-leak-kinds=definite,indirect,possible --track-origins=yes \
             --log-file="$OUT/$name.valgrind.txt" \
             "$EXE" --json --headings "$OUT/$name.headings.csv" "$dump" >"$OUT/$name.json" 2>"$OUT/$name.stderr"
    rc=$?
    set -e
    if [ $rc -eq 99 ] || [ -s "$OUT/$name.valgrind.txt" ]; then
        echo "FAIL $name: memcheck errors ($OUT/$name.valgrind.txt)"
        cat "$OUT/$name.valgrind.txt"
        fail=1
    elif [ $rc -ne 0 ] && [ $rc -ne 3 ]; then
        echo "FAIL $name: magcal-replay exit $rc"
        cat "$OUT/$name.stderr"
        fail=1
    else
        echo "ok   $name (exit $rc)"
    fi
done
echo "memcheck: $n dumps, $([ $fail -eq 0 ] && echo clean || echo FAILED)"
exit $fail
