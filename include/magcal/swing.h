/**
 * @file swing.h
 * @brief Classical compass swing: the five-coefficient deviation model
 *        `delta(psi) = A + B sin psi + C cos psi + D sin 2psi + E cos 2psi` fitted by least squares
 *        from reference headings, and a fixed-size accumulator that collects reference headings
 *        from GNSS course over ground on straight, steady legs (or from marked directions).
 *
 * Conventions (algorithms.md section 5): deviation `delta = wrap(psi_ref - psi_c)` in degrees
 * (reference minus measured: the navigator's deviation, added to the compass reading), east positive, where psi_c is the compass (measured) heading and psi_ref the reference MAGNETIC
 * heading (convert a true bearing or COG first: psi_ref = COG - declination, declination east
 * positive). Headings in degrees [0, 360) clockwise from north; deviations wrapped to (-180, 180].
 *
 * Two regressor choices, stored in the model:
 * - MAGCAL_SWING_REG_MEASURED (default): the model is a function of the measured heading, fitted
 *   with psi_c as regressor; apply `psi = psi_c + delta(psi_c)`.
 * - MAGCAL_SWING_REG_REFERENCE: the model is a function of the true heading (fitted with psi_ref
 *   as regressor, e.g. a turntable at equally spaced reference headings); apply by fixed-point
 *   iteration `psi_{j+1} = psi_c + delta(psi_j)`, psi_0 = psi_c, which converges while
 *   |d delta / d psi| < 1 (checked at fit time). See docs/heading_models.md.
 *
 * Sign against the source documents: the compass-swing article (and the indoor heading patent)
 * define the heading ERROR as measured minus true, `e = psi_c - psi_ref = -delta`, and correct
 * with `psi = psi_c - e(psi_c)`. Same basis, same regressor (the measured heading), so an
 * article coefficient set A..E is this model with every coefficient negated:
 * magcal_swing_model_from_error() loads one, magcal_swing_model_to_error() exports one.
 *
 * "Ellipse + swing": correct the raw field with the ellipse calibration first, then fit the swing
 * on the corrected headings; coefficient A then also removes the installation rotation the
 * ellipse cannot see.
 */
#ifndef MAGCAL_SWING_H
#define MAGCAL_SWING_H

#include <stddef.h>
#include <stdint.h>

#include "magcal/config.h"
#include "magcal/status.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Number of coefficients of the classical model (A, B, C, D, E). */
#define MAGCAL_SWING_NCOEF 5u

/** Fewest reference headings a fit accepts. */
#define MAGCAL_SWING_MIN_POINTS 5u

/* MAGCAL_SWING_COG_BINS (bins of the course-over-ground accumulator) is a build-time limit in
 * magcal/config.h. */

/** Which heading is the regressor of the model. */
typedef enum {
    MAGCAL_SWING_REG_MEASURED = 0, /**< delta is a function of the compass heading psi_c */
    MAGCAL_SWING_REG_REFERENCE = 1 /**< delta is a function of the reference heading (inverted at run time) */
} magcal_swing_regressor_t;

/** A fitted deviation model. Coefficients in degrees (the sines and cosines are unitless). */
typedef struct {
    float coef_deg[MAGCAL_SWING_NCOEF];  /**< A, B, C, D, E in degrees */
    magcal_swing_regressor_t regressor;  /**< how to apply it */
    uint8_t iterations;                  /**< fixed-point iterations for REG_REFERENCE (1..16) */
} magcal_swing_model_t;

/** Runtime options of the fit. */
typedef struct {
    /**
     * Spread test: smallest pivot of the LDL^T factorisation of the UN-equilibrated design Gram
     * matrix (1/W) sum w_k g_k g_k^T, g = (1, sin, cos, sin2, cos2). Equally spaced headings give
     * pivots (1, .5, .5, .5, .5); the four cardinal headings give 0 for sin 2psi. Range (0, 0.5].
     */
    float min_spread_pivot;
    /** Relative pivot threshold handed to the equilibrated solver (magcal_ldlt_solve). > 0. */
    float pivot_tau;
    /** Fixed-point iterations stored in REG_REFERENCE models, 1..16. */
    uint8_t iterations;
} magcal_swing_cfg_t;

/** Defaults: spread pivot 0.05, solver tau 1e-6, 5 fixed-point iterations. */
#define MAGCAL_SWING_CFG_DEFAULT {0.05f, 1e-6f, 5u}

/** Fit diagnostics (residuals in degrees at the fitted points). */
typedef struct {
    float rms_deg;         /**< RMS of wrap(delta_k - model) over the points (weighted) */
    float max_abs_deg;     /**< largest |residual| */
    float min_spread_pivot; /**< the spread pivot that was tested */
    size_t n_used;         /**< points with non-zero weight */
} magcal_swing_stats_t;

#if MAGCAL_CFG_ENABLE_SWING
/**
 * @brief Fit A..E by least squares from n pairs of compass and reference headings.
 * @param[in]  cfg          options (MAGCAL_SWING_CFG_DEFAULT).
 * @param[in]  psi_c_deg    n compass headings, degrees (any finite value; wrapped internally).
 * @param[in]  psi_ref_deg  n reference magnetic headings, degrees.
 * @param[in]  weights      optional (NULL = all 1): n non-negative finite weights.
 * @param[in]  n            number of pairs, >= MAGCAL_SWING_MIN_POINTS.
 * @param[in]  regressor    MAGCAL_SWING_REG_MEASURED (psi_c is the regressor) or
 *                          MAGCAL_SWING_REG_REFERENCE (psi_ref is the regressor).
 * @param[out] model        fitted model; untouched on failure.
 * @param[out] stats        optional (may be NULL); filled on success and on MAGCAL_ERR_SPREAD
 *                          (min_spread_pivot) only.
 * @return MAGCAL_OK; MAGCAL_ERR_NULL; MAGCAL_ERR_ARG (cfg, regressor, negative weight);
 *         MAGCAL_ERR_NONFINITE; MAGCAL_ERR_TOO_FEW_POINTS (fewer than 5 points with weight > 0);
 *         MAGCAL_ERR_SPREAD (headings too badly spread: spread pivot or solver pivot test failed);
 *         MAGCAL_ERR_NOT_CONVERGED (REG_REFERENCE model whose slope bound
 *         (|B| + |C| + 2|D| + 2|E|) * pi/180 is >= 0.9, so the inversion may not converge).
 */
magcal_status_t magcal_swing_fit(const magcal_swing_cfg_t *cfg, const float *psi_c_deg,
                                 const float *psi_ref_deg, const float *weights, size_t n,
                                 magcal_swing_regressor_t regressor, magcal_swing_model_t *model,
                                 magcal_swing_stats_t *stats);

/**
 * @brief Evaluate the deviation polynomial at a heading (no inversion).
 * @param[in]  model      fitted model.
 * @param[in]  psi_deg    heading at which to evaluate, degrees.
 * @param[out] delta_deg  A + B sin + C cos + D sin2 + E cos2, degrees; untouched on failure.
 * @return MAGCAL_OK; MAGCAL_ERR_NULL; MAGCAL_ERR_NONFINITE.
 */
magcal_status_t magcal_swing_deviation(const magcal_swing_model_t *model, float psi_deg,
                                       float *delta_deg);

/**
 * @brief Correct a compass heading: psi = psi_c + delta(psi_c) (REG_MEASURED) or the fixed point
 *        of psi = psi_c + delta(psi) (REG_REFERENCE).
 * @param[in]  model      fitted model.
 * @param[in]  psi_c_deg  compass heading, degrees.
 * @param[out] psi_deg    corrected magnetic heading, degrees [0, 360); untouched on failure.
 * @return MAGCAL_OK; MAGCAL_ERR_NULL; MAGCAL_ERR_ARG (unknown regressor or iterations out of
 *         range); MAGCAL_ERR_NONFINITE.
 *
 * @code
 * // 8-position swing: compass readings at the reference headings 0, 45, ..., 315 deg
 * static const float ref[8] = {0, 45, 90, 135, 180, 225, 270, 315};
 * float comp[8];                                   // filled from the compass
 * magcal_swing_cfg_t cfg = MAGCAL_SWING_CFG_DEFAULT;
 * magcal_swing_model_t model;
 * float psi;
 * if (magcal_swing_fit(&cfg, comp, ref, NULL, 8u, MAGCAL_SWING_REG_MEASURED, &model, NULL)
 *     == MAGCAL_OK) {
 *     (void)magcal_swing_apply(&model, comp[0], &psi);
 * }
 * @endcode
 */
magcal_status_t magcal_swing_apply(const magcal_swing_model_t *model, float psi_c_deg,
                                   float *psi_deg);

/**
 * @brief Load a coefficient set given in the source documents' sign (error = measured - true).
 *
 * delta = -e, coefficient by coefficient (exact for either regressor: e(psi) = -delta(psi)).
 * @param[in]  err_coef_deg A..E of e(psi) = A + B sin psi + C cos psi + D sin 2psi + E cos 2psi,
 *                          degrees (the compass-swing article's formula (3)).
 * @param[in]  regressor    which heading psi is (the article's: MAGCAL_SWING_REG_MEASURED).
 * @param[in]  iterations   fixed-point iterations for REG_REFERENCE (1..16; ignored otherwise).
 * @param[out] model        the model in this library's sign; untouched on failure.
 * @return MAGCAL_OK; MAGCAL_ERR_NULL; MAGCAL_ERR_NONFINITE; MAGCAL_ERR_ARG (regressor or
 *         iterations); MAGCAL_ERR_NOT_CONVERGED (REG_REFERENCE set whose slope bound is >= 0.9,
 *         as in magcal_swing_fit()).
 */
magcal_status_t magcal_swing_model_from_error(const float err_coef_deg[MAGCAL_SWING_NCOEF],
                                              magcal_swing_regressor_t regressor,
                                              uint8_t iterations, magcal_swing_model_t *model);

/**
 * @brief Export a model in the source documents' sign (error = measured - true = -delta).
 * @param[in]  model        model (its regressor is unchanged by the conversion).
 * @param[out] err_coef_deg A..E of the error, degrees; untouched on failure.
 * @return MAGCAL_OK; MAGCAL_ERR_NULL; MAGCAL_ERR_NONFINITE.
 */
magcal_status_t magcal_swing_model_to_error(const magcal_swing_model_t *model,
                                            float err_coef_deg[MAGCAL_SWING_NCOEF]);
#endif /* MAGCAL_CFG_ENABLE_SWING */

/* ------------------------------------------------------------------------------------------- */
/* Swing from motion: reference headings from GNSS course over ground on straight, steady legs. */

/** One epoch of the motion swing. */
typedef struct {
    float time_s;     /**< monotonic time, seconds */
    float psi_c_deg;  /**< compass (measured, already ellipse-corrected if used) heading, degrees */
    float cog_deg;    /**< GNSS course over ground, true, degrees */
    float speed_mps;  /**< GNSS ground speed, m/s */
    float decl_deg;   /**< magnetic declination at the position, degrees east positive */
} magcal_swing_epoch_t;

/** Gates of the motion swing. */
typedef struct {
    float min_speed_mps;     /**< slower epochs are rejected (COG is noisy at low speed). > 0 */
    float max_cog_rate_dps;  /**< |dCOG/dt| between consecutive epochs above this ends a leg. > 0 */
    float max_cog_dev_deg;   /**< |COG - leg mean COG| above this ends a leg (slow curves). > 0 */
    float max_gap_s;         /**< time gap between epochs above this ends a leg. > 0 */
    float min_leg_s;         /**< a leg shorter than this is discarded. >= 0 */
    uint16_t min_leg_epochs; /**< a leg with fewer accepted epochs is discarded. >= 2 */
    uint16_t min_bins;       /**< occupied heading bins needed before magcal_swing_cog_fit. >= 5 */
    uint16_t trim_epochs;    /**< epochs dropped at the start of a leg (compass/COG lag after a turn) */
    magcal_swing_cfg_t fit;  /**< options of the final least-squares fit */
} magcal_swing_cog_cfg_t;

/** Defaults: 3 m/s, 3 deg/s (COG noise of 0.5 deg at 1 Hz passes, turns do not), 3 deg, 2 s gap,
 *  10 s legs of >= 10 epochs, 6 bins, trim 2. */
#define MAGCAL_SWING_COG_CFG_DEFAULT                                                               \
    {3.0f, 3.0f, 3.0f, 2.0f, 10.0f, 10u, 6u, 2u, MAGCAL_SWING_CFG_DEFAULT}

/** One heading bin: a weighted mean of per-leg (psi_c, delta) pairs. Private. */
typedef struct {
    float psi_c_off_deg; /**< mean of wrap(psi_c - bin centre) over the legs */
    float delta_deg;     /**< mean of wrap(psi_ref - psi_c) over the legs */
    float weight;        /**< sum of leg weights (accepted epochs); 0 = empty */
    uint16_t legs;       /**< legs merged into this bin */
} magcal_swing_bin_t;

/** Motion-swing accumulator. Allocate statically; every field is private. */
typedef struct {
    magcal_swing_cog_cfg_t cfg;
    magcal_swing_bin_t bins[MAGCAL_SWING_COG_BINS];
    /* current leg (offsets are taken from the leg's first accepted epoch so averaging is wrap-safe) */
    float leg_org_ref_deg;  /* psi_ref = COG - decl of the first accepted epoch */
    float leg_org_psi_deg;  /* psi_c of the first accepted epoch */
    float sum_ref_off;      /* sum of wrap(psi_ref - leg_org_ref) */
    float sum_psi_off;      /* sum of wrap(psi_c - leg_org_psi) */
    float leg_t0_s;         /* time of the first accepted epoch */
    float leg_t1_s;         /* time of the last accepted epoch */
    float last_t_s;         /* time of the previous epoch (any) */
    float last_cog_deg;     /* COG of the previous epoch */
    uint32_t leg_n;         /* epochs accumulated in the leg */
    uint32_t leg_seen;      /* straight epochs seen in the leg, including trimmed ones */
    uint32_t legs_total;    /* committed legs */
    uint32_t magic;         /* init marker */
    uint8_t have_last;      /* last_t_s/last_cog_deg valid */
} magcal_swing_cog_t;

#if MAGCAL_CFG_ENABLE_SWING
/**
 * @brief Initialise the accumulator (all bins empty).
 * @param[out] acc  accumulator.
 * @param[in]  cfg  gates (copied); MAGCAL_SWING_COG_CFG_DEFAULT works without tuning.
 * magcal_swing_cog_init() is a macro passing the caller's MAGCAL_CONFIG_FINGERPRINT and
 * sizeof(magcal_swing_cog_t) (which depends on MAGCAL_SWING_COG_BINS) to the checked function.
 * @return MAGCAL_OK; MAGCAL_ERR_CONFIG_MISMATCH (caller compiled with other config.h limits:
 *         nothing written); MAGCAL_ERR_NULL; MAGCAL_ERR_ARG (cfg value out of range).
 */
magcal_status_t magcal_swing_cog_init_checked(magcal_swing_cog_t *acc, const magcal_swing_cog_cfg_t *cfg,
                                              uint32_t config, size_t inst_size);
#define magcal_swing_cog_init(acc, cfg)                                                            \
    magcal_swing_cog_init_checked((acc), (cfg), MAGCAL_CONFIG_FINGERPRINT, sizeof(magcal_swing_cog_t))

/**
 * @brief Feed one epoch. Epochs that are slow or turning are rejected; a run of accepted epochs
 *        forms a leg, which is averaged and committed to the bin of its mean compass heading when
 *        the run ends (turn, slow-down, gap) and it is long enough.
 * @param[in,out] acc  accumulator.
 * @param[in]     ep   the epoch.
 * @return MAGCAL_OK (epoch accepted into the current leg); MAGCAL_ERR_GATED (rejected: too slow,
 *         turning, or trimmed at the start of a leg); MAGCAL_ERR_NULL; MAGCAL_ERR_NOT_INITIALISED;
 *         MAGCAL_ERR_NONFINITE (epoch ignored, leg closed).
 */
magcal_status_t magcal_swing_cog_add(magcal_swing_cog_t *acc, const magcal_swing_epoch_t *ep);

/**
 * @brief Close the current leg (commit it if long enough). Call at the end of a drive.
 * @return MAGCAL_OK; MAGCAL_ERR_NULL; MAGCAL_ERR_NOT_INITIALISED.
 */
magcal_status_t magcal_swing_cog_flush(magcal_swing_cog_t *acc);

/**
 * @brief Add one known pair, e.g. a marked direction (compass rose, runway heading).
 * @param[in,out] acc          accumulator.
 * @param[in]     psi_c_deg    compass heading, degrees.
 * @param[in]     psi_ref_deg  reference MAGNETIC heading, degrees.
 * @param[in]     weight       weight in "epochs", > 0 (a leg counts its epochs).
 * @return MAGCAL_OK; MAGCAL_ERR_NULL; MAGCAL_ERR_NOT_INITIALISED; MAGCAL_ERR_NONFINITE;
 *         MAGCAL_ERR_ARG (weight <= 0).
 */
magcal_status_t magcal_swing_cog_add_pair(magcal_swing_cog_t *acc, float psi_c_deg,
                                          float psi_ref_deg, float weight);

/**
 * @brief Number of occupied bins and committed legs so far.
 * @return MAGCAL_OK; MAGCAL_ERR_NULL; MAGCAL_ERR_NOT_INITIALISED.
 */
magcal_status_t magcal_swing_cog_count(const magcal_swing_cog_t *acc, size_t *bins, size_t *legs);

/**
 * @brief Fit the swing model (REG_MEASURED) on the occupied bins, one point per bin (equal
 *        weights, so heading coverage rather than time spent decides the fit).
 * @param[in]  acc    accumulator.
 * @param[out] model  fitted model; untouched on failure.
 * @param[out] stats  optional (may be NULL).
 * @return MAGCAL_OK; MAGCAL_ERR_NULL; MAGCAL_ERR_NOT_INITIALISED; MAGCAL_ERR_TOO_FEW_POINTS
 *         (fewer occupied bins than cfg.min_bins); MAGCAL_ERR_SPREAD; the codes of
 *         magcal_swing_fit.
 */
magcal_status_t magcal_swing_cog_fit(const magcal_swing_cog_t *acc, magcal_swing_model_t *model,
                                     magcal_swing_stats_t *stats);
#endif /* MAGCAL_CFG_ENABLE_SWING */

#ifdef __cplusplus
}
#endif

#endif /* MAGCAL_SWING_H */
