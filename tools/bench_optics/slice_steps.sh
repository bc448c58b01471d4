#!/bin/sh
# Instructions of every step call of the sliced 2-D density stage (callgrind, host):
#   tools/bench_optics/slice_steps.sh BUILD_DIR filter|thin ring|parked|burst N [BUDGET]
# prints the largest and the total over the step calls, and the one-shot call's total.
set -eu
bin="$1/tools/bench_optics/slice_bench"
what="$2"; data="$3"; n="$4"; budget="${5:-6000}"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
valgrind --tool=callgrind --callgrind-out-file="$tmp/cg" \
    --toggle-collect="magcal_optics_${what}_step" --dump-after="magcal_optics_${what}_step" \
    "$bin" "$what" "$data" "$n" "$budget" >"$tmp/out" 2>"$tmp/err"
cat "$tmp/out"
for f in "$tmp"/cg.*; do sed -n 's/^summary: //p' "$f"; done | sort -n >"$tmp/steps"
valgrind --tool=callgrind --callgrind-out-file="$tmp/one" --toggle-collect="magcal_optics_${what}" \
    "$bin" "$what" "$data" "$n" 0 >/dev/null 2>&1
one=$(sed -n 's/^summary: //p' "$tmp/one")
awk -v one="$one" -v b="$budget" '$1 > 0 { s += $1; c += 1; if ($1 > m) m = $1 }
    END { printf "steps %d at budget %s: largest %d host instr, total %d; one-shot %d (overhead %.1f %%)\n",
          c, b, m, s, one, 100.0 * (s - one) / one }' "$tmp/steps"
