/* Helpers shared by the tests: deterministic synthetic rings with known truth, error metrics. */
#ifndef MAGCAL_TEST_UTIL_H
#define MAGCAL_TEST_UTIL_H

#include <stddef.h>
#include <stdint.h>

#include "magcal/heading.h"
#include "magcal/types.h"

/** Known 2-D distortion: Hm = T*H + b, H = h0*(-sin psi, cos psi) (algorithms.md 1.1/1.3). */
typedef struct {
    float h0;
    float t[2][2];
    float bx;
    float by;
} test_distortion_t;

/** Deterministic uniform in [0,1) (xorshift32); *state must be non-zero. */
double test_rand_uniform(uint32_t *state);
/** Deterministic standard normal (Box-Muller on test_rand_uniform). */
double test_rand_normal(uint32_t *state);

/** Field seen at heading psi_deg through distortion d, plus N(0, sigma^2) noise per axis. */
magcal_vec2_t test_distorted_sample(const test_distortion_t *d, double psi_deg, double sigma, uint32_t *rng);

/** Fill n samples at headings start + k*arc/n (arc in degrees), with noise. psi_out may be NULL. */
void test_make_ring(const test_distortion_t *d, size_t n, double start_deg, double arc_deg,
                    double sigma, uint32_t seed, magcal_vec2_t *out, float *psi_out);

/** Smallest signed angle difference a-b in degrees, (-180, 180]. */
double test_angle_diff_deg(double a, double b);

/**
 * Radius spread std/mean of |c(p)| over the n points whose skip flag is 0 (skip may be NULL),
 * c applied with magcal_correct_apply (the identity calibration gives the raw spread). Asserts
 * every correction succeeds.
 */
double test_radius_spread(const magcal_cal2d_t *c, const magcal_vec2_t *pts, const uint8_t *skip, size_t n);

#endif
