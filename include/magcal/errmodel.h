/**
 * @file errmodel.h
 * @brief Adaptive heading-error models (the indoor heading-correction patent and its periodic
 *        alternative): the order is raised from 1 until the largest residual at the calibration
 *        headings is below a threshold.
 *
 * - MAGCAL_ERRMODEL_POLY: `delta(psi_c) = sum_{k=0..N} c_k T_k(t)`, t = psi_c/180 - 1 in [-1, 1)
 *   (psi_c in degrees [0, 360)), T_k the Chebyshev polynomials. This spans the same space as the
 *   patent's `sum c_k psi^k` but is well conditioned in float32. NOT periodic: delta(0) differs
 *   from delta(360) (a jump at north), and it oscillates between the calibration headings as N
 *   grows (algorithms.md 5.2).
 * - MAGCAL_ERRMODEL_FOURIER: `delta(psi_c) = a_0 + sum_{k=1..K} (a_k cos k psi_c + b_k sin k psi_c)`,
 *   periodic and continuous by construction; K = 2 is the classical swing model (5.3).
 *   Recommended default.
 *
 * Deviation convention as in swing.h: delta = wrap(psi_ref - psi_c) in degrees, regressor psi_c
 * (the measured heading), correction psi = psi_c + delta(psi_c).
 *
 * Against the indoor heading patent: it defines the heading error as measured minus true,
 * e = psi_c - psi_ref = -delta, as a power series in the measured heading in RADIANS,
 * e(phi) = sum_j a_j phi^j, phi in [0, 2 pi), and prints the coefficients highest power first
 * (its embodiment: N = 4, [-0.0068, 0.0944, -0.3545, 0.2051, 0.2844]). The product fits
 * Chebyshev polynomials in degrees; magcal_errmodel_poly_to_power() and
 * magcal_errmodel_poly_from_power() convert between the two (sign, unit and basis).
 */
#ifndef MAGCAL_ERRMODEL_H
#define MAGCAL_ERRMODEL_H

#include <stddef.h>
#include <stdint.h>

#include "magcal/config.h"
#include "magcal/status.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Largest polynomial order N (N + 1 coefficients; bounded by the 12x12 solver). */
#define MAGCAL_ERRMODEL_MAX_POLY_ORDER 11u
/** Largest Fourier order K (2K + 1 coefficients). */
#define MAGCAL_ERRMODEL_MAX_FOURIER_ORDER 5u
/** Coefficient storage of a model. */
#define MAGCAL_ERRMODEL_MAX_COEF 12u

/** Model family. */
typedef enum {
    MAGCAL_ERRMODEL_POLY = 0,   /**< Chebyshev polynomial in t = psi/180 - 1 (the patent's model) */
    MAGCAL_ERRMODEL_FOURIER = 1 /**< Fourier series in psi (periodic; recommended) */
} magcal_errmodel_kind_t;

/** Coefficient order of a power series (the patent prints MAGCAL_ERRMODEL_POWER_DESCENDING). */
typedef enum {
    MAGCAL_ERRMODEL_POWER_ASCENDING = 0, /**< a_0, a_1, ..., a_N */
    MAGCAL_ERRMODEL_POWER_DESCENDING = 1 /**< a_N, ..., a_1, a_0 (MATLAB polyfit order) */
} magcal_errmodel_power_order_t;

/** A fitted model. */
typedef struct {
    magcal_errmodel_kind_t kind;
    uint8_t order;                          /**< N (poly) or K (Fourier) */
    /** poly: c_0..c_N (Chebyshev T_k); Fourier: a_0, a_1, b_1, a_2, b_2, ... (degrees) */
    float coef[MAGCAL_ERRMODEL_MAX_COEF];
} magcal_errmodel_t;

/** Options of the adaptive fit. */
typedef struct {
    magcal_errmodel_kind_t kind;
    float threshold_deg; /**< stop when max |residual| at the points < this, degrees. > 0 */
    uint8_t max_order;   /**< 1..MAGCAL_ERRMODEL_MAX_POLY_ORDER (poly) / _FOURIER_ORDER (Fourier) */
    float pivot_tau;     /**< relative pivot threshold of magcal_ldlt_solve. > 0 */
} magcal_errmodel_cfg_t;

/** Defaults: Fourier, threshold 0.1 deg, max order 5, solver tau 1e-6. */
#define MAGCAL_ERRMODEL_CFG_DEFAULT {MAGCAL_ERRMODEL_FOURIER, 0.1f, 5u, 1e-6f}

/** Fit diagnostics. */
typedef struct {
    uint8_t order;       /**< last order tried (the accepted one on success) */
    float max_abs_deg;   /**< largest |residual| at the points for that order */
    float rms_deg;       /**< RMS residual at the points for that order */
} magcal_errmodel_stats_t;

/** Workspace bytes of magcal_errmodel_fit (any order up to the maximum): the normal matrix
 *  (MAGCAL_ERRMODEL_MAX_COEF squared floats) and its right-hand side, off the stack (issue 14). */
#define MAGCAL_ERRMODEL_WORKSPACE_LEN                                                              \
    (((size_t)MAGCAL_ERRMODEL_MAX_COEF * MAGCAL_ERRMODEL_MAX_COEF + MAGCAL_ERRMODEL_MAX_COEF) *    \
     sizeof(float))
/** Declare `name` as a correctly aligned workspace of MAGCAL_ERRMODEL_WORKSPACE_LEN bytes. */
#define MAGCAL_ERRMODEL_WORKSPACE_DECLARE(name)                                                    \
    MAGCAL_WORKSPACE_DECLARE(name, MAGCAL_ERRMODEL_WORKSPACE_LEN)

#if MAGCAL_CFG_ENABLE_PAPER
/**
 * @brief Adaptive fit: orders 1, 2, ... until max |residual| < threshold_deg.
 *
 * The order is also capped by the data: N <= M - 1 (poly), K <= (M - 1)/2 (Fourier).
 * @param[in]  cfg          options (MAGCAL_ERRMODEL_CFG_DEFAULT).
 * @param[in]  psi_c_deg    m compass headings, degrees (wrapped to [0, 360) internally).
 * @param[in]  psi_ref_deg  m reference magnetic headings, degrees.
 * @param[in]  m            number of pairs, >= 2 (poly) or >= 3 (Fourier).
 * @param[out] work         scratch, 4-byte aligned, >= MAGCAL_ERRMODEL_WORKSPACE_LEN bytes (the
 *                          normal equations; nothing kept between calls).
 * @param[in]  work_len     bytes at work.
 * @param[out] model        the accepted model; untouched on failure.
 * @param[out] stats        optional (may be NULL): filled on success and on
 *                          MAGCAL_ERR_THRESHOLD (the last order tried and its residuals).
 * @return MAGCAL_OK; MAGCAL_ERR_NULL (also work NULL); MAGCAL_ERR_ALIGNMENT (work not 4-byte
 *         aligned); MAGCAL_ERR_WORKSPACE (work_len < MAGCAL_ERRMODEL_WORKSPACE_LEN);
 *         MAGCAL_ERR_ARG (cfg out of range); MAGCAL_ERR_NONFINITE;
 *         MAGCAL_ERR_TOO_FEW_POINTS; MAGCAL_ERR_SPREAD (order-1 system singular: headings not
 *         spread); MAGCAL_ERR_THRESHOLD (max order, or the order the data allow, reached, or a
 *         higher order became ill-conditioned, without meeting the threshold).
 *
 * @code
 * float comp[24], ref[24];                         // filled during calibration
 * static MAGCAL_ERRMODEL_WORKSPACE_DECLARE(work);  // 624 B, shared with other background work
 * magcal_errmodel_cfg_t cfg = MAGCAL_ERRMODEL_CFG_DEFAULT;
 * magcal_errmodel_t model;
 * float psi;
 * if (magcal_errmodel_fit(&cfg, comp, ref, 24u, work, sizeof work, &model, NULL) == MAGCAL_OK) {
 *     (void)magcal_errmodel_apply(&model, 123.0f, &psi);
 * }
 * @endcode
 */
magcal_status_t magcal_errmodel_fit(const magcal_errmodel_cfg_t *cfg, const float *psi_c_deg,
                                    const float *psi_ref_deg, size_t m, void *work,
                                    size_t work_len, magcal_errmodel_t *model,
                                    magcal_errmodel_stats_t *stats);

/**
 * @brief Evaluate delta(psi_c) in degrees.
 * @param[in]  model      fitted model.
 * @param[in]  psi_c_deg  compass heading, degrees (wrapped to [0, 360) first).
 * @param[out] delta_deg  deviation, degrees; untouched on failure.
 * @return MAGCAL_OK; MAGCAL_ERR_NULL; MAGCAL_ERR_ARG (kind or order out of range);
 *         MAGCAL_ERR_NONFINITE.
 */
magcal_status_t magcal_errmodel_eval(const magcal_errmodel_t *model, float psi_c_deg,
                                     float *delta_deg);

/**
 * @brief Corrected heading psi = wrap360(psi_c + delta(psi_c)).
 * @return as magcal_errmodel_eval.
 */
magcal_status_t magcal_errmodel_apply(const magcal_errmodel_t *model, float psi_c_deg,
                                      float *psi_deg);

/**
 * @brief Export a polynomial model as the patent's power series: error e = measured - true in
 *        radians, e(phi) = sum_j a_j phi^j with phi the measured heading in radians.
 *
 * Exact algebra (T_k(phi/pi - 1) expanded in powers of phi, times -pi/180) in float32. The power
 * basis is ill conditioned: its terms cancel at phi = 2 pi, so accuracy falls as N grows (the
 * patent's N = 4 curve round-trips to 7e-5 deg in test_errmodel). Use the export to compare with
 * a document, not as the run-time model.
 * @param[in]  model  MAGCAL_ERRMODEL_POLY model.
 * @param[in]  order  coefficient order of coef_rad.
 * @param[out] coef_rad N + 1 coefficients, radians per radian^j; untouched on failure.
 * @param[in]  cap    capacity of coef_rad, >= N + 1 (MAGCAL_ERRMODEL_MAX_COEF always suffices).
 * @param[out] n_coef N + 1.
 * @return MAGCAL_OK; MAGCAL_ERR_NULL; MAGCAL_ERR_ARG (not a POLY model, order out of range, or
 *         cap too small); MAGCAL_ERR_NONFINITE (a coefficient, or the result, is NaN/Inf).
 */
magcal_status_t magcal_errmodel_poly_to_power(const magcal_errmodel_t *model,
                                              magcal_errmodel_power_order_t order, float *coef_rad,
                                              size_t cap, size_t *n_coef);

/**
 * @brief Load the patent's power series (error = measured - true, radians, measured heading in
 *        radians) as a polynomial model (delta = reference - measured, degrees, Chebyshev).
 * @param[in]  coef_rad a_0..a_N (or a_N..a_0, see order).
 * @param[in]  n_coef   N + 1, 2..MAGCAL_ERRMODEL_MAX_POLY_ORDER + 1 (the patent: N != 0).
 * @param[in]  order    coefficient order of coef_rad.
 * @param[out] model    MAGCAL_ERRMODEL_POLY model of order N; untouched on failure.
 * @return MAGCAL_OK; MAGCAL_ERR_NULL; MAGCAL_ERR_ARG (n_coef or order out of range);
 *         MAGCAL_ERR_NONFINITE.
 */
magcal_status_t magcal_errmodel_poly_from_power(const float *coef_rad, size_t n_coef,
                                                magcal_errmodel_power_order_t order,
                                                magcal_errmodel_t *model);
#endif /* MAGCAL_CFG_ENABLE_PAPER */

#ifdef __cplusplus
}
#endif

#endif /* MAGCAL_ERRMODEL_H */
