/* Deterministic bench data set (see bench_data.c). */
#ifndef MAGCAL_BENCH_DATA_H
#define MAGCAL_BENCH_DATA_H

#include <stddef.h>
#include <stdint.h>

#include "magcal/types.h"

/** Fill pts[0..n-1]; kind[i] = 0 ring sample, 1 scattered, 2 glitch cluster, 3 burst (n >= 16). */
void bench_generate(magcal_vec2_t *pts, uint8_t *kind, size_t n);

#endif /* MAGCAL_BENCH_DATA_H */
