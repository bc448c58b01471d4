/* Deterministic bench data set (see bench_data.c). */
#ifndef MAGCAL_BENCH_DATA_H
#define MAGCAL_BENCH_DATA_H

#include <stddef.h>
#include <stdint.h>

#include "magcal/aided.h"
#include "magcal/types.h"

/** Fill pts[0..n-1]; kind[i] = 0 ring sample, 1 scattered, 2 glitch cluster, 3 burst (n >= 16). */
void bench_generate(magcal_vec2_t *pts, uint8_t *kind, size_t n);

/** 3-D set of the optics3 / ellipsoid kernels: a noisy ellipsoid shell (uniform directions,
 *  F = 500, offset (300, -200, 150), axes 1.1 / 0.93 / 1.04 x F, sigma 3), 5 % scattered points
 *  (radius x 1.7..2.5) and 3 % one stuck burst 0.8 R outside (n >= 16). */
void bench_generate3(magcal_vec3_t *pts3, size_t n);

/** A clean hand tumble shaped like the shared fxos8700 / lsm9ds1 tumbles (no outliers): F = 50 uT
 *  through a soft-iron matrix (axes ~1.04 / 0.97 / 1.01, 0.03 off-diagonal), offset (28.6, -40,
 *  -27.4) uT, Gaussian noise 0.4 uT, directions along a 6-turn pole-to-pole spiral with jitter. */
void bench_generate_tumble(magcal_vec3_t *pts3, size_t n, uint32_t seed);

/** n epochs of a synthetic road drive for magcal_aided_update: B = (20, 1.2, 44) uT NED, soft iron
 *  + scale W, V = (18, -11, 27) uT, 0.05 uT noise, straight legs of 60 epochs joined by 90-degree
 *  turns, pitch/roll AR(1) with 1 deg RMS, INS errors 0.01 / 0.05 deg, DOP 1.2. */
void bench_generate_drive(magcal_aided_epoch_t *ep, size_t n);

#endif /* MAGCAL_BENCH_DATA_H */
