#!/bin/sh
# Instruction counts of one magcal_calibrator_run() at capacity MAGCAL_MAX_SAMPLES for each
# scenario of bound_calibrator.c (docs/reliability.md "Bounded execution").
#   tools/fuzz/bound_calibrator.sh [OUT_DIR] [SCENARIO...]
# Builds the library sources and the driver with the host gcc at -O2 (x86-64 instructions; the
# Cortex-M4F count must be measured on target, e.g. with DWT->CYCCNT around the same call).
set -eu
SRC=$(cd "$(dirname "$0")/../.." && pwd)
OUT=${1:-$SRC/build/bound}
[ $# -gt 0 ] && shift
SCEN=${*:-"ring ring_noisy disc annulus_wide ring_plus_disc ring_cluster45 ring_spikes45 ring_far_outliers grid_lattice ring_noisy_lattice clumps2 clumps3 clumps4 clumps5 clumps6 clumps8 clumps6_wide ring_half_clumps3 ring_eps_huge_minpts4 ring_eps_huge ring_classic_eps_huge_iter2000 spikes45_iter2000"}
mkdir -p "$OUT"
LIBSRC=$(ls "$SRC"/src/*.c "$SRC"/src/adopt/*.c "$SRC"/src/heading/*.c "$SRC"/src/filter/*.c "$SRC"/src/fit/*.c | grep -v calibrator_poll)
# shellcheck disable=SC2086
${CC:-gcc} -std=c99 -O2 -g -I"$SRC/include" -I"$SRC/port" -I"$SRC/src" -o "$OUT/bound_calibrator" \
    "$SRC/tools/fuzz/bound_calibrator.c" $LIBSRC -lm
printf '%-32s %-42s %12s\n' scenario "status, used, eps', MinPts" "Ir in run()"
for s in $SCEN; do
    res=$(valgrind --tool=callgrind --toggle-collect=magcal_calibrator_run \
          --callgrind-out-file="$OUT/callgrind.$s.out" "$OUT/bound_calibrator" "$s" 2>/dev/null)
    ir=$(sed -n 's/^totals: *\([0-9]*\).*/\1/p' "$OUT/callgrind.$s.out")
    printf '%-32s %-42s %12s\n' "$s" "$(echo "$res" | cut -d' ' -f2-)" "$ir"
done
