#!/bin/sh
# Instruction counts of magcal_calibrator_run() on the emulated Cortex-M4F (QEMU mps2-an386,
# -icount shift=0: one instruction per virtual ns; CMSDK timer at 25 MHz -> 40 instructions per
# tick). Same scenarios and library flags as the firmware build (-Os, hard float).
#   tools/fuzz/bound_m4f.sh [OUT_DIR]
# Executed Thumb instructions, not cycles: on silicon multiply the count by the measured CPI
# (loads, FP divide/sqrt and flash wait states cost more than one cycle).
set -eu
SRC=$(cd "$(dirname "$0")/../.." && pwd)
OUT=${1:-$SRC/build/bound-m4f}
mkdir -p "$OUT"
T=$SRC/cmake/target
FLAGS="-mcpu=cortex-m4 -mthumb -mfloat-abi=hard -mfpu=fpv4-sp-d16 -Os -std=c99 -ffunction-sections -fdata-sections"
LIBSRC=$(ls "$SRC"/src/*.c "$SRC"/src/adopt/*.c "$SRC"/src/heading/*.c "$SRC"/src/filter/*.c "$SRC"/src/fit/*.c | grep -v calibrator_poll)
# shellcheck disable=SC2086
arm-none-eabi-gcc $FLAGS -DMAGCAL_BOUND_M4F -I"$SRC/include" -I"$SRC/port" -I"$SRC/src" \
    -o "$OUT/bound_calibrator.elf" "$SRC/tools/fuzz/bound_calibrator.c" $LIBSRC "$T/startup_mps2_an386.c" \
    -T"$T/mps2_an386.ld" -nostartfiles --specs=rdimon.specs -Wl,--wrap=_exit -Wl,--gc-sections -lm
timeout 600 qemu-system-arm -M mps2-an386 -icount shift=0 -display none -monitor none -serial null \
    -semihosting-config enable=on,target=native -kernel "$OUT/bound_calibrator.elf"
