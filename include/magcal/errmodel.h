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
 */
#ifndef MAGCAL_ERRMODEL_H
#define MAGCAL_ERRMODEL_H

#include <stddef.h>
#include <stdint.h>

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

/**
 * @brief Adaptive fit: orders 1, 2, ... until max |residual| < threshold_deg.
 *
 * The order is also capped by the data: N <= M - 1 (poly), K <= (M - 1)/2 (Fourier).
 * @param[in]  cfg          options (MAGCAL_ERRMODEL_CFG_DEFAULT).
 * @param[in]  psi_c_deg    m compass headings, degrees (wrapped to [0, 360) internally).
 * @param[in]  psi_ref_deg  m reference magnetic headings, degrees.
 * @param[in]  m            number of pairs, >= 2 (poly) or >= 3 (Fourier).
 * @param[out] model        the accepted model; untouched on failure.
 * @param[out] stats        optional (may be NULL): filled on success and on
 *                          MAGCAL_ERR_THRESHOLD (the last order tried and its residuals).
 * @return MAGCAL_OK; MAGCAL_ERR_NULL; MAGCAL_ERR_ARG (cfg out of range); MAGCAL_ERR_NONFINITE;
 *         MAGCAL_ERR_TOO_FEW_POINTS; MAGCAL_ERR_SPREAD (order-1 system singular: headings not
 *         spread); MAGCAL_ERR_THRESHOLD (max order, or the order the data allow, reached, or a
 *         higher order became ill-conditioned, without meeting the threshold).
 *
 * @code
 * float comp[24], ref[24];                         // filled during calibration
 * magcal_errmodel_cfg_t cfg = MAGCAL_ERRMODEL_CFG_DEFAULT;
 * magcal_errmodel_t model;
 * float psi;
 * if (magcal_errmodel_fit(&cfg, comp, ref, 24u, &model, NULL) == MAGCAL_OK) {
 *     (void)magcal_errmodel_apply(&model, 123.0f, &psi);
 * }
 * @endcode
 */
magcal_status_t magcal_errmodel_fit(const magcal_errmodel_cfg_t *cfg, const float *psi_c_deg,
                                    const float *psi_ref_deg, size_t m, magcal_errmodel_t *model,
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

#ifdef __cplusplus
}
#endif

#endif /* MAGCAL_ERRMODEL_H */
