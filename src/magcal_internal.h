/*
 * Cross-module internals of magcal. Not installed, not part of the public API.
 * Tests may include it (tests/ adds src/ to their include path).
 */
#ifndef MAGCAL_INTERNAL_H
#define MAGCAL_INTERNAL_H

#include <stddef.h>
#include <stdint.h>

#include "magcal/config.h"
#include "magcal/status.h"
#include "magcal/types.h"

#ifdef __cplusplus
extern "C" {
#endif

#define MAGCAL_PI_F 3.14159265358979323846f
#define MAGCAL_DEG_PER_RAD_F 57.29577951308232f
#define MAGCAL_RAD_PER_DEG_F 0.017453292519943295f

/** Largest system order solved by magcal_ldlt_solve (10 for the general quadric). */
#define MAGCAL_LDLT_MAX_N 12u

/**
 * Solve the symmetric positive definite system N x = r in place (float32, LDL^T).
 * The matrix is equilibrated first (N' = D^-1/2 N D^-1/2) so the relative pivot test
 * `d_j < tau` detects rank deficiency regardless of column scaling (algorithms.md 3.2).
 *
 * @param[in,out] a   n*n row-major matrix; only the lower triangle is read; destroyed
 *                    (the strict upper triangle is scratch, D ends on the diagonal).
 * @param[in,out] b   right-hand side of length n; overwritten with the solution.
 * @param n           order, 1..MAGCAL_LDLT_MAX_N.
 * @param tau         relative pivot threshold (1e-6f is a good float32 default).
 * @param[out] min_pivot optional (may be NULL): smallest equilibrated pivot, a cheap
 *                    reciprocal-condition indicator.
 * @return MAGCAL_OK, MAGCAL_ERR_ARG (n out of range), MAGCAL_ERR_NONFINITE,
 *         MAGCAL_ERR_DEGENERATE (zero diagonal: a column of zeros), MAGCAL_ERR_ILL_CONDITIONED
 *         (a pivot below tau).
 */
magcal_status_t magcal_ldlt_solve(float *a, float *b, size_t n, float tau, float *min_pivot);

/**
 * The two halves of magcal_ldlt_solve for several right-hand sides (n >= 3): factor `a` once
 * (equilibration, LDL^T, the same pivot test and statuses), then solve in place for each b with
 * magcal_ldlt_subst. Each solve gives exactly the numbers of magcal_ldlt_solve on a fresh copy.
 */
magcal_status_t magcal_ldlt_factor(float *a, size_t n, float tau, float *min_pivot);
/** Solve with a matrix factored by magcal_ldlt_factor; MAGCAL_ERR_ILL_CONDITIONED on a non-finite x. */
magcal_status_t magcal_ldlt_subst(const float *a, float *b, size_t n);

/**
 * One observation's rank-1 update of least-squares normal equations in the layout
 * magcal_ldlt_solve reads: a[e*n + k] += w[e] w[k] for k <= e (the lower triangle of the n*n
 * row-major matrix only), b[e] += w[e] y. Row by row, the rhs after each row (the order of the
 * additions, hence the float sums, is that of the loops it replaced).
 */
static inline void magcal_normal_add(float *a, float *b, const float *w, size_t n, float y)
{
    size_t e;
    size_t k;
    for (e = 0u; e < n; ++e) {
        for (k = 0u; k <= e; ++k) {
            a[e * n + k] += w[e] * w[k];
        }
        b[e] += w[e] * y;
    }
}

/** True when v is neither NaN nor +/-Inf (works with -ffast-math off, no libm needed). */
static inline int magcal_isfinite_f(float v) { return (v == v) && (v - v == 0.0f); }

/**
 * Misalignment of a caller-provided buffer: the address of p modulo align (align a power of
 * two, 1..16). The one place where a pointer becomes an integer (MISRA 11.6, deviation D9).
 */
size_t magcal_misalign(const void *p, size_t align);

/** Kahan-compensated float32 accumulation: *sum += v, *comp carries the lost low-order part. */
static inline void magcal_kahan_add(float *sum, float *comp, float v)
{
    const float y = v - *comp;
    const float t = *sum + y;
    *comp = (t - *sum) - y;
    *sum = t;
}

/** Determinant of a 3x3 matrix by cofactors of the first row. */
float magcal_det3(float a[3][3]);

/** Largest order accepted by magcal_jacobi_sym (3x3 shape matrices, 4x4 information matrices). */
#define MAGCAL_JACOBI_MAX_N 4u

/** Cyclic sweeps of magcal_jacobi_sym before it reports MAGCAL_ERR_NOT_CONVERGED. */
#define MAGCAL_JACOBI_SWEEPS 12u

/**
 * Cyclic Jacobi eigendecomposition of a symmetric n x n matrix (row-major, destroyed):
 * a = E diag(w) E^T, eigenvectors in the columns of e (row-major n x n). Stops when the squared
 * off-diagonal mass is <= 1e-14 of the squared Frobenius norm.
 *
 * @return MAGCAL_OK, MAGCAL_ERR_ARG (n outside 1..MAGCAL_JACOBI_MAX_N),
 *         MAGCAL_ERR_NOT_CONVERGED (MAGCAL_JACOBI_SWEEPS sweeps were not enough).
 */
magcal_status_t magcal_jacobi_sym(float *a, size_t n, float *w, float *e);

/** Wrap an angle in degrees to (-180, 180]. Input must be finite. */
float magcal_wrap180_deg(float a);

/** Wrap an angle in degrees to [0, 360). Input must be finite. */
float magcal_wrap360_deg(float a);

/** atan2(y, x) in radians, [-pi, pi], within 2e-5 degree of the exact value (src/fit/linalg.c); finite input. */
float magcal_atan2f(float y, float x);

/**
 * Deterministic PRNG (xorshift32). State must be non-zero; 0 is replaced by a fixed constant.
 * Returns a value uniformly distributed in [0, bound) for bound >= 1 (bound 0 gives 0).
 */
uint32_t magcal_prng_next(uint32_t *state, uint32_t bound);

#ifdef __cplusplus
}
#endif

#endif /* MAGCAL_INTERNAL_H */
