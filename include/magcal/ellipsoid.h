/**
 * @file ellipsoid.h
 * @brief 3-D magnetometer calibration by a least-squares ellipsoid (general quadric) fit.
 *
 * Model (algorithms.md 7.1/7.2): raw field `m = W h + V + noise`, where h is the true field in body
 * axes (x right, y forward, z up) and `|h| = F`. The fit finds the offset V and a correction matrix
 * `G = W^-1` (up to a left rotation, which no attitude-free fit can observe), with
 * `G^T G = Q`, `(m - V)^T Q (m - V) = F^2`. Apply it with `h = G (m - V)`.
 *
 * Models:
 * - 9-parameter quadric (d = -1) after centring and scaling (default),
 * - 10-parameter quadric (smallest eigenvector of D^T D by inverse iteration),
 * - 4-parameter sphere (hard iron only, G = (F/R) I), used automatically (model AUTO) when the
 *   direction coverage is too poor for the full model (and then held to a 1 % F residual).
 *
 * Coverage: the directions of `m - c` around the provisional centre c (the sphere-fit centre) are
 * binned in 12 azimuth x 6 equal-area elevation cells (bands of equal z/|m - c|); coverage is the
 * filled fraction of the 72 cells, in [0, 1].
 *
 * Outliers: after each fit, samples whose total-field residual `| |G(m - V)| - F |` exceeds
 * `outlier_k` times the robust sigma (1.4826 x median |r|) of the kept residuals, found by histogram
 * refinement without storage (never less than `outlier_floor_rel * F`), are
 * dropped and the model is fitted again, at most `max_refits` times. No per-sample storage is needed:
 * the sample array is read again on each pass (2 + 2 * refits passes at most). The gate of the final
 * pass (the calibration it was computed with, which is the fit BEFORE the last refit, and its
 * threshold) is returned in the result, so magcal_ellipsoid_outliers() can give the per-sample mask
 * afterwards without storage inside the fit.
 *
 * Trust gates (issue 12, docs/calibration_3d.md "Trust gates"): an OK is a promise, so every model,
 * AUTO and forced, must also pass, after the fit:
 * - motion: the samples' RMS spread about their mean >= `min_motion_snr` x the noise (the best of
 *   the fit's residual, the algebraic quadric's and a median-scaled sphere's), else
 *   MAGCAL_ERR_NO_MOTION (the sensor was at rest; noise around one point gives about 2.5);
 * - observability: predicted 1-sigma error (robust sandwich covariance of the linearised model)
 *   of V along its worst direction <= `max_centre_std_rel` x F and of the worst soft-iron term
 *   <= `max_shape_std`, else MAGCAL_ERR_SINGLE_AXIS when the corrected field directions lie on one
 *   cone (rotation about one axis: level turns, a turntable) and MAGCAL_ERR_ILL_CONDITIONED
 *   otherwise (a narrow band of directions, or too few samples for the noise);
 * - residual: residual RMS <= `max_residual_rel` x F (quadrics) or `max_residual_rel_sphere` x F
 *   (sphere: unmodelled soft iron shows only here), else MAGCAL_ERR_RESIDUAL;
 * - field (optional): `field_expected` > 0 and the raw radius outside the band:
 *   MAGCAL_ERR_FIELD_MAGNITUDE.
 * What to do: NO_MOTION -> rotate the sensor through many orientations; SINGLE_AXIS -> also turn
 * about another axis (pitch and roll), or use the 2-D calibrator (calibrator.h) or the aided module
 * (aided.h) when the vehicle cannot; ILL_CONDITIONED -> more orientations or more samples (the
 * error falls as 1/sqrt(n)); RESIDUAL -> outliers or disturbances (run the density stage,
 * optics.h), or, for the sphere, soft iron: rotate over more directions for the full model;
 * FIELD_MAGNITUDE -> wrong unit, wrong expected field, or iron next to the sensor.
 *
 * Units: any consistent raw unit for m; G maps raw units to the unit of `cfg.field` (e.g. LSB to uT).
 * All arithmetic is float32 with (blocked) Kahan-compensated sums; the matrices live in a caller's
 * fixed scratch (magcal_ellipsoid_fit) or workspace (magcal_ellipsoid_fit_ws), <= 512 B of stack
 * (tools/stack/budgets.txt). Time-sliced: magcal_ellipsoid_fit_begin / magcal_ellipsoid_fit_step
 * (docs/calibration_3d.md "Time-sliced fit"), of which both one-shot calls are begin + one step.
 *
 * The complete 3-D calibration, magcal_ellipsoid_calibrate(), adds the density stage (optics.h,
 * magcal_optics_filter3) only when a pre-test fit of all samples shows a gross outlier.
 */
#ifndef MAGCAL_ELLIPSOID_H
#define MAGCAL_ELLIPSOID_H

#include <stddef.h>
#include <stdint.h>

#include "magcal/config.h"
#include "magcal/optics.h"
#include "magcal/status.h"
#include "magcal/types.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Number of azimuth cells of the coverage measure. */
#define MAGCAL_ELLIPSOID_COV_AZ 12u
/** Number of (equal-area) elevation bands of the coverage measure. */
#define MAGCAL_ELLIPSOID_COV_EL 6u

/** A 3-D calibration: `h = G (m - V)`. Shared with the aided module (aided.h). */
typedef struct {
    float g[3][3];   /**< correction matrix G, row-major: h_i = sum_j g[i][j] (m_j - v_j) */
    magcal_vec3_t v; /**< offset V (hard iron + sensor bias), raw units, body axes */
    float field;     /**< F: magnitude of the corrected field h, output units */
} magcal_ellipsoid_cal_t;

/** Which model to fit. */
typedef enum {
    MAGCAL_ELLIPSOID_MODEL_AUTO = 0, /**< 9-parameter quadric if coverage allows, else sphere */
    MAGCAL_ELLIPSOID_MODEL_QUADRIC9 = 1,  /**< 9-parameter quadric (d = -1), coverage not gated */
    MAGCAL_ELLIPSOID_MODEL_QUADRIC10 = 2, /**< 10-parameter quadric (||v|| = 1), coverage not gated */
    MAGCAL_ELLIPSOID_MODEL_SPHERE = 3     /**< 4-parameter sphere (hard iron only), coverage not gated */
} magcal_ellipsoid_model_t;

/** How G is taken from Q (both satisfy G^T G = Q). */
typedef enum {
    MAGCAL_ELLIPSOID_SQRT_SYMMETRIC = 0, /**< G = Q^(1/2), symmetric (3x3 Jacobi eigen-decomposition) */
    MAGCAL_ELLIPSOID_SQRT_CHOLESKY = 1   /**< G = U, upper triangular, Q = U^T U */
} magcal_ellipsoid_sqrt_t;

/** Fit configuration. Start from MAGCAL_ELLIPSOID_CFG_DEFAULT (fields are only ever appended). */
typedef struct {
    magcal_ellipsoid_model_t model;    /**< model to fit (default AUTO) */
    magcal_ellipsoid_sqrt_t sqrt_method; /**< square root of Q (default SYMMETRIC) */
    float field;               /**< F > 0: output magnitude (e.g. WMM |B| in uT); 0: choose F so det(G) = 1 */
    float min_coverage_full;   /**< AUTO: coverage needed for the 9-parameter model, [0,1] (default 0.45) */
    float min_coverage_sphere; /**< AUTO: coverage needed for the sphere, [0,1] (default 0.20); below: MAGCAL_ERR_COVERAGE */
    float outlier_k;           /**< outlier gate in robust-sigma (1.4826 MAD) multiples; 0 disables rejection (default 3) */
    float outlier_floor_rel;   /**< outlier gate never below this fraction of F (default 0.005) */
    uint32_t max_refits;       /**< refits after outlier rejection, 0..8 (default 5) */
    float max_reject_frac;     /**< more rejected than this fraction: MAGCAL_ERR_TOO_MANY_OUTLIERS (default 0.25) */
    float pivot_tau;           /**< relative LDL^T pivot threshold (default 1e-6) */
    /* ---- trust gates (issue 12): every model, AUTO and forced; 0 disables a gate ---- */
    float min_motion_snr;      /**< NO_MOTION when the samples' RMS spread about their mean is below this many
                                    noise sigmas (best of the fit's residual, the algebraic quadric's and a
                                    median-scaled sphere's, raw units); noise around one point gives ~2.5
                                    (default 4) */
    float max_centre_std_rel;  /**< observability: predicted 1-sigma error of V along its worst direction,
                                    through G (output units), relative to F; above: SINGLE_AXIS (corrected
                                    directions on one cone) or ILL_CONDITIONED (default 0.005) */
    float max_shape_std;       /**< observability: predicted 1-sigma error of the worst soft-iron term of G
                                    (relative, ~ radians of heading); above: as max_centre_std_rel
                                    (default 0.008; the sphere has no such term) */
    float max_residual_rel;    /**< quadric models: residual RMS / F above: MAGCAL_ERR_RESIDUAL (default 0.05) */
    float max_residual_rel_sphere; /**< sphere model: residual RMS / F above: MAGCAL_ERR_RESIDUAL (default 0.01:
                                    unmodelled soft iron of 3.5 %, ~1 deg of heading, leaves ~1 % F) */
    float field_expected;      /**< > 0: expected |B| in the unit of the samples (e.g. magcal_geomag_eval in uT
                                    for a uT sensor); the fitted raw radius F / det(G)^(1/3) must lie in
                                    [field_band_lo, field_band_hi] x field_expected, else
                                    MAGCAL_ERR_FIELD_MAGNITUDE. 0: no check (default) */
    float field_band_lo;       /**< lower bound of the field band, relative (default 0.85, as ArduPilot) */
    float field_band_hi;       /**< upper bound of the field band, relative (default 1.4, as ArduPilot) */
} magcal_ellipsoid_cfg_t;

/** Defaults that work without tuning. */
#define MAGCAL_ELLIPSOID_CFG_DEFAULT                                                                \
    {                                                                                               \
        MAGCAL_ELLIPSOID_MODEL_AUTO, MAGCAL_ELLIPSOID_SQRT_SYMMETRIC, 0.0f, 0.45f, 0.20f, 3.0f,     \
            0.005f, 5u, 0.25f, 1e-6f, 4.0f, 0.005f, 0.008f, 0.05f, 0.01f, 0.0f, 0.85f, 1.4f         \
    }

/** Result of a fit. */
typedef struct {
    magcal_ellipsoid_cal_t cal;     /**< V, G, F */
    float residual_rms;             /**< RMS of |G(m - V)| - F over the kept samples, output units */
    float coverage;                 /**< filled fraction of the 12 x 6 direction cells, [0, 1] */
    float min_pivot;                /**< smallest equilibrated LDL^T pivot (reciprocal-condition hint) */
    size_t n_used;                  /**< samples in the final fit */
    size_t n_rejected;              /**< samples dropped as outliers */
    magcal_ellipsoid_model_t model; /**< model actually fitted (never AUTO) */
    /** Calibration the final outlier gate was evaluated with (the fit before the last refit; equal
     *  to `cal` when no gate was applied). Input of magcal_ellipsoid_outliers(). */
    magcal_ellipsoid_cal_t gate_cal;
    /** Final outlier gate, output units: a sample is an outlier when | |G_gate (m - V_gate)| -
     *  F_gate | >= gate_thr. 0: no gate was applied (outlier_k == 0, max_refits == 0 or nothing
     *  was ever rejected), every sample was used. */
    float gate_thr;
    /* ---- trust diagnostics (issue 12); like every field, written only on MAGCAL_OK: to see the
     *      value that made a gate refuse, fit again with that gate set to 0 ---- */
    float motion_snr;     /**< RMS spread of the samples about their mean / noise sigma (raw units) */
    float centre_std_rel; /**< predicted 1-sigma error of V along its worst direction (through G) / F;
                               +Inf when that direction is not observable at all */
    float shape_std;      /**< predicted 1-sigma error of the worst soft-iron term of G (relative); 0 for
                               the sphere, +Inf when not observable */
    float planarity;      /**< sqrt(smallest / middle eigenvalue) of the samples' 3-D scatter: ~0 for one
                               rotation axis (a circle), ~1 for a sphere */
    float field_raw;      /**< fitted raw radius F / det(G)^(1/3), unit of the samples */
} magcal_ellipsoid_result_t;

/** Fixed part of MAGCAL_ELLIPSOID_FIT_WORKSPACE_LEN: the packed 10x10 normal matrix, the solver
 *  matrix, the observability pass's 9x9 inverse and sums, the median histogram, the time-sliced
 *  fit's state (magcal_ellipsoid_fit_step), 8-byte aligned
 *  inside the 4-byte aligned workspace (static assert in src/fit/ellipsoid.c). */
#define MAGCAL_ELLIPSOID_FIT_SCRATCH_BYTES 3264u
/** The fixed scratch of magcal_ellipsoid_fit (caller memory; contents private). 64-bit words:
 *  the scratch holds pointers and size_t, so it is 8-byte aligned (no union: MISRA 19.2). */
typedef struct {
    uint64_t words_[(MAGCAL_ELLIPSOID_FIT_SCRATCH_BYTES + 7u) / 8u];
} magcal_ellipsoid_fit_scratch_t;

/**
 * Time-sliced magcal_ellipsoid_fit_ws (the contract of docs/calibration_3d.md "Time-sliced fit"):
 * the fit's state lives in its workspace (the scratch of MAGCAL_ELLIPSOID_FIT_WORKSPACE_LEN);
 * this handle in the caller's memory only points at it. Fields are private.
 */
typedef struct {
    void *s_;         /* the fit's scratch (inside the workspace) */
    uint32_t used_;   /* estimated M4F instructions charged by the last step */
    int32_t status_;  /* MAGCAL_IN_PROGRESS until the fit ends, then its status */
} magcal_ellipsoid_fit_slice_t;

#if MAGCAL_CFG_ENABLE_3D
/**
 * @brief Fit V and G to raw 3-D field samples.
 *
 * A fixed scratch, no per-sample storage: `scratch` (MAGCAL_ELLIPSOID_FIT_SCRATCH_BYTES, caller
 * memory: issue 13's 512 B of stack) holds the matrices and every pass recomputes the residuals.
 * magcal_ellipsoid_fit_ws gives the same result bit for bit with half the instructions when the
 * caller can also give 5 B per sample; both are begin + step(UINT32_MAX) of the sliced fit.
 *
 * @param[in]  m    n raw samples (body axes x right, y forward, z up; any unit).
 * @param[in]  n    number of samples (>= 4 for the sphere, >= 10 for the quadrics; the sphere needs
 *                  coverage anyway, so in practice use >= 50).
 * @param[in]  cfg  configuration (MAGCAL_ELLIPSOID_CFG_DEFAULT).
 * @param[out] scratch the fit's scratch (caller memory, e.g. static; contents undefined after).
 * @param[out] out  result; written only on MAGCAL_OK.
 * @return MAGCAL_OK;
 *         MAGCAL_ERR_NULL (m, cfg, scratch or out NULL);
 *         MAGCAL_ERR_ARG (config out of range);
 *         MAGCAL_ERR_NONFINITE (a sample is NaN/Inf);
 *         MAGCAL_ERR_TOO_FEW_POINTS (n below the model's minimum, also after outlier rejection);
 *         MAGCAL_ERR_DEGENERATE (all samples identical);
 *         MAGCAL_ERR_COVERAGE (AUTO: coverage below min_coverage_sphere, samples neither at rest
 *         nor planar);
 *         MAGCAL_ERR_NO_MOTION (samples are noise around one point: rotate the sensor);
 *         MAGCAL_ERR_SINGLE_AXIS (rotation about one axis: offset unobservable along it; turn
 *         about another axis, or use the 2-D / aided calibration);
 *         MAGCAL_ERR_ILL_CONDITIONED (normal equations fail the pivot test, or the predicted error
 *         of V or G is above max_centre_std_rel / max_shape_std: too little rotation or too few
 *         samples for the noise);
 *         MAGCAL_ERR_RESIDUAL (residual RMS above max_residual_rel(_sphere) x F);
 *         MAGCAL_ERR_FIELD_MAGNITUDE (field_expected set and the fitted raw radius outside
 *         [field_band_lo, field_band_hi] x field_expected);
 *         MAGCAL_ERR_NOT_ELLIPSOID (quadric is not an ellipsoid: k <= 0 or A_q/k not positive definite);
 *         MAGCAL_ERR_NOT_CONVERGED (Jacobi eigen-decomposition of Q did not converge);
 *         MAGCAL_ERR_TOO_MANY_OUTLIERS (rejected fraction above max_reject_frac).
 *
 * @code
 * static magcal_vec3_t samples[600];            // filled by the application
 * static magcal_ellipsoid_fit_scratch_t scratch;
 * const magcal_ellipsoid_cfg_t cfg = MAGCAL_ELLIPSOID_CFG_DEFAULT;
 * magcal_ellipsoid_result_t fit;
 * magcal_vec3_t h;
 * if (magcal_ellipsoid_fit(samples, 600u, &cfg, &scratch, &fit) == MAGCAL_OK) {
 *     (void)magcal_ellipsoid_apply(&fit.cal, &samples[0], &h);   // h = G (m - V)
 * }
 * @endcode
 */
magcal_status_t magcal_ellipsoid_fit(const magcal_vec3_t *m, size_t n, const magcal_ellipsoid_cfg_t *cfg,
                                     magcal_ellipsoid_fit_scratch_t *scratch,
                                     magcal_ellipsoid_result_t *out);

/** Workspace bytes of magcal_ellipsoid_fit_ws for n samples: the scratch + per sample its residual
 *  (4 B) and its outlier-gate verdict (1 B). */
#define MAGCAL_ELLIPSOID_FIT_WORKSPACE_LEN(n)                                                       \
    ((size_t)MAGCAL_ELLIPSOID_FIT_SCRATCH_BYTES + (size_t)(n) * (sizeof(float) + 1u))
/** Declare `name` as a correctly aligned workspace of MAGCAL_ELLIPSOID_FIT_WORKSPACE_LEN(n) bytes. */
#define MAGCAL_ELLIPSOID_FIT_WORKSPACE_DECLARE(name, n)                                             \
    MAGCAL_WORKSPACE_DECLARE(name, MAGCAL_ELLIPSOID_FIT_WORKSPACE_LEN(n))

/**
 * @brief magcal_ellipsoid_fit with its scratch in the caller's workspace (issue 14): the same
 *        result bit for bit, <= 512 B of stack (magcal_ellipsoid_fit keeps the 2.3 KB scratch on
 *        its own stack), and about half the instructions (each sample's residual is stored once
 *        per fit instead of being recomputed by every pass of the outlier gate and its median).
 *
 * @param[in]  m        n raw samples (as magcal_ellipsoid_fit).
 * @param[in]  n        number of samples.
 * @param[in]  cfg      configuration (MAGCAL_ELLIPSOID_CFG_DEFAULT).
 * @param[out] work     scratch, 4-byte aligned, >= MAGCAL_ELLIPSOID_FIT_WORKSPACE_LEN(n) bytes.
 * @param[in]  work_len bytes at work.
 * @param[out] out      result; written only on MAGCAL_OK.
 * @return every status of magcal_ellipsoid_fit; MAGCAL_ERR_NULL also for work NULL;
 *         MAGCAL_ERR_ALIGNMENT (work not 4-byte aligned); MAGCAL_ERR_WORKSPACE (work_len too small).
 *
 * @code
 * static magcal_vec3_t samples[600];            // filled by the application
 * static MAGCAL_ELLIPSOID_FIT_WORKSPACE_DECLARE(work, 600u);
 * const magcal_ellipsoid_cfg_t cfg = MAGCAL_ELLIPSOID_CFG_DEFAULT;
 * magcal_ellipsoid_result_t fit;
 * if (magcal_ellipsoid_fit_ws(samples, 600u, &cfg, work, sizeof work, &fit) == MAGCAL_OK) {
 *     // fit.cal: h = G (m - V)
 * }
 * @endcode
 */
magcal_status_t magcal_ellipsoid_fit_ws(const magcal_vec3_t *m, size_t n,
                                        const magcal_ellipsoid_cfg_t *cfg, void *work,
                                        size_t work_len, magcal_ellipsoid_result_t *out);


/**
 * @brief Start a time-sliced magcal_ellipsoid_fit_ws (O(1): checks the pointers and the
 *        workspace, stores the inputs; the configuration is checked by the first step).
 * @param[out] s        slice handle, caller memory.
 * @param[in]  m        n raw samples; must stay unchanged until the fit has finished.
 * @param[in]  n        number of samples.
 * @param[in]  cfg      configuration; must stay unchanged until the fit has finished.
 * @param[out] work     as magcal_ellipsoid_fit_ws; holds the fit's state until it has finished.
 * @param[in]  work_len bytes at work.
 * @param[out] out      result, written by the last step only on MAGCAL_OK.
 * @return MAGCAL_OK (call magcal_ellipsoid_fit_step); MAGCAL_ERR_NULL; MAGCAL_ERR_ALIGNMENT;
 *         MAGCAL_ERR_WORKSPACE.
 */
magcal_status_t magcal_ellipsoid_fit_begin(magcal_ellipsoid_fit_slice_t *s, const magcal_vec3_t *m,
                                           size_t n, const magcal_ellipsoid_cfg_t *cfg, void *work,
                                           size_t work_len, magcal_ellipsoid_result_t *out);

/**
 * @brief Do at most about `budget` estimated Cortex-M4F instructions of the fit started by
 *        magcal_ellipsoid_fit_begin (at least one unit of work per call, so any budget >= 1 makes
 *        progress; the largest unit is one small solve of about 3,000 instructions, except the
 *        forced MAGCAL_ELLIPSOID_MODEL_QUADRIC10's inverse iteration, which is one unit).
 * @param[in,out] s      slice handle.
 * @param[in]     budget estimated M4F instructions for this call (0 counts as 1).
 * @return MAGCAL_IN_PROGRESS while work remains; then exactly the status (and *out, bit for bit)
 *         of magcal_ellipsoid_fit_ws, returned again by any further call; MAGCAL_ERR_NULL (s NULL);
 *         MAGCAL_ERR_ARG (s not started by a successful begin).
 */
magcal_status_t magcal_ellipsoid_fit_step(magcal_ellipsoid_fit_slice_t *s, uint32_t budget);

/**
 * @brief Per-sample outlier mask of a fit: classify each sample with the fit's final gate.
 *
 * Applies exactly the gate of the final pass of magcal_ellipsoid_fit (res->gate_cal,
 * res->gate_thr): sample k is an outlier when | |G_gate (m_k - V_gate)| - F_gate | >= gate_thr,
 * with the same float32 arithmetic as the fit. On the fit's own input (same m, same n) the count
 * equals res->n_rejected and the flagged samples are exactly those left out of res->cal. On other
 * samples it applies the same gate (e.g. to screen new data with the calibration's own criterion).
 *
 * @param[in]  res        result of a successful magcal_ellipsoid_fit.
 * @param[in]  m          n raw samples (same unit and axes as the fit's input).
 * @param[in]  n          number of samples (>= 1).
 * @param[out] outlier    n flags: 1 = outlier, 0 = kept; written only on MAGCAL_OK.
 * @param[out] n_outliers number of flags set; written only on MAGCAL_OK.
 * @return MAGCAL_OK;
 *         MAGCAL_ERR_NULL (res, m, outlier or n_outliers NULL);
 *         MAGCAL_ERR_TOO_FEW_POINTS (n == 0);
 *         MAGCAL_ERR_ARG (res->gate_thr negative or NaN, or res->gate_cal not finite: not a result
 *         of magcal_ellipsoid_fit);
 *         MAGCAL_ERR_NONFINITE (a sample is NaN/Inf).
 *
 * @code
 * #define N_SAMPLES 600u
 * static magcal_vec3_t samples[N_SAMPLES];      // filled by the application
 * static uint8_t flag[N_SAMPLES];
 * const magcal_ellipsoid_cfg_t cfg = MAGCAL_ELLIPSOID_CFG_DEFAULT;
 * magcal_ellipsoid_result_t fit;
 * size_t n_out;
 * if (magcal_ellipsoid_fit(samples, N_SAMPLES, &cfg, &fit) == MAGCAL_OK &&
 *     magcal_ellipsoid_outliers(&fit, samples, N_SAMPLES, flag, &n_out) == MAGCAL_OK) {
 *     // n_out == fit.n_rejected; flag[k] == 1 for the samples the fit dropped
 * }
 * @endcode
 */
magcal_status_t magcal_ellipsoid_outliers(const magcal_ellipsoid_result_t *res,
                                          const magcal_vec3_t *m, size_t n, uint8_t *outlier,
                                          size_t *n_outliers);

/**
 * @brief Apply a calibration: h = G (m - V).
 * @param[in]  cal calibration (from magcal_ellipsoid_fit or the aided module).
 * @param[in]  m   raw sample, body axes.
 * @param[out] h   corrected field, body axes, unit of cal->field; written only on MAGCAL_OK.
 * @return MAGCAL_OK, MAGCAL_ERR_NULL, MAGCAL_ERR_NONFINITE (m or cal not finite).
 */
magcal_status_t magcal_ellipsoid_apply(const magcal_ellipsoid_cal_t *cal, const magcal_vec3_t *m, magcal_vec3_t *h);

/**
 * @brief Direction coverage of samples around a centre: filled fraction of 12 x 6 cells.
 * @param[in]  m        n samples.
 * @param[in]  n        number of samples (>= 1).
 * @param[in]  centre   centre c (e.g. a provisional V); samples within 1e-6 of c (relative) are skipped.
 * @param[out] coverage fraction in [0, 1]; written only on MAGCAL_OK.
 * @return MAGCAL_OK, MAGCAL_ERR_NULL, MAGCAL_ERR_TOO_FEW_POINTS (n == 0), MAGCAL_ERR_NONFINITE.
 */
magcal_status_t magcal_ellipsoid_coverage(const magcal_vec3_t *m, size_t n, const magcal_vec3_t *centre,
                                          float *coverage);
#endif /* MAGCAL_CFG_ENABLE_3D */

/* ---- the complete 3-D calibration: pre-test -> density stage when needed -> fit (issue 14) ---- */

/** When magcal_ellipsoid_calibrate runs the OPTICS density stage (magcal_optics_filter3). */
typedef enum {
    MAGCAL_ELLIPSOID_DENSITY_AUTO = 0,   /**< only when the pre-test finds a gross outlier (default) */
    MAGCAL_ELLIPSOID_DENSITY_ALWAYS = 1, /**< always (the composition of issue 6) */
    MAGCAL_ELLIPSOID_DENSITY_NEVER = 2   /**< never: the fit's own residual gate only */
} magcal_ellipsoid_density_t;

/** Configuration of magcal_ellipsoid_calibrate. Start from MAGCAL_ELLIPSOID_CALIBRATE_CFG_DEFAULT. */
typedef struct {
    magcal_ellipsoid_cfg_t fit;       /**< the fit (MAGCAL_ELLIPSOID_CFG_DEFAULT) */
    magcal_optics_cfg_t density;      /**< the density stage (MAGCAL_OPTICS_CFG_DEFAULT: automatic parameters) */
    magcal_ellipsoid_density_t mode;  /**< when the density stage runs (default AUTO) */
    float pretest_max_rel;            /**< AUTO: the density stage is skipped when the fit of ALL samples is
                                           MAGCAL_OK and no sample's | |G(m - V)| - F | exceeds this x F
                                           (default 0.15: the bursts, glitches and spikes the density stage
                                           exists for sit >= 0.3 F off the shell); (0, 1] */
} magcal_ellipsoid_calibrate_cfg_t;

/** Defaults that work without tuning. */
#define MAGCAL_ELLIPSOID_CALIBRATE_CFG_DEFAULT                                                      \
    {                                                                                               \
        MAGCAL_ELLIPSOID_CFG_DEFAULT, MAGCAL_OPTICS_CFG_DEFAULT, MAGCAL_ELLIPSOID_DENSITY_AUTO, 0.15f \
    }

/** What magcal_ellipsoid_calibrate did besides the fit. */
typedef struct {
    uint32_t density_ran;           /**< 1: the density stage ran and the fit saw only its inliers */
    size_t n_density_rejected;      /**< samples the density stage removed (0 when it did not run) */
    float pretest_max_rel;          /**< largest | |G(m - V)| - F | / F of the pre-test fit over all samples;
                                         NaN when no pre-test fit was made or it failed */
    magcal_optics_result_t density; /**< the density stage's parameters (valid when density_ran) */
} magcal_ellipsoid_calibrate_info_t;

/** Time-sliced magcal_ellipsoid_calibrate: its state in the caller's memory (fields private). */
typedef struct {
    const magcal_ellipsoid_calibrate_cfg_t *cfg_;
    const magcal_vec3_t *m_;
    size_t n_;
    uint8_t *work_;
    size_t work_len_;
    uint8_t *inlier_;
    magcal_ellipsoid_result_t *out_;
    magcal_ellipsoid_calibrate_info_t *info_;
    magcal_ellipsoid_fit_slice_t fit_;
    magcal_optics3_slice_t density_; /* the time-sliced density stage (magcal_optics_filter3_step) */
    size_t k_;
    size_t nk_;
    size_t fit_off_;
    float mx_;
    uint32_t used_;  /* estimated M4F instructions charged by the last step */
    int32_t status_;
    uint8_t phase_;
    int8_t pre_st_;
} magcal_ellipsoid_calibrate_slice_t;

/** Bytes of magcal_ellipsoid_calibrate's workspace that hold the pre-test's result. */
#define MAGCAL_ELLIPSOID_CALIBRATE_RESULT_SLOT ((sizeof(magcal_ellipsoid_result_t) + 7u) / 8u * 8u)
/** @cond INTERNAL */
#define MAGCAL_ELLIPSOID_CALIBRATE_INFO_SLOT_ ((sizeof(magcal_ellipsoid_calibrate_info_t) + 7u) / 8u * 8u)
/** @endcond */
/** The result slot + the slot of the info when the caller passes info = NULL + the one-shot call's
 *  slice state (all off the stack), 8-byte aligned inside a 4-byte aligned workspace (+4 B). */
#define MAGCAL_ELLIPSOID_CALIBRATE_SLOTS                                                            \
    (4u + MAGCAL_ELLIPSOID_CALIBRATE_RESULT_SLOT + MAGCAL_ELLIPSOID_CALIBRATE_INFO_SLOT_ +          \
     (sizeof(magcal_ellipsoid_calibrate_slice_t) + 7u) / 8u * 8u)
/** Workspace bytes of magcal_ellipsoid_calibrate for n samples: the pre-test's result and info, the inlier
 *  copy (n x 12 B), then the larger of the density stage's MAGCAL_OPTICS3_FILTER_WORKSPACE_LEN(n)
 *  and the fit's MAGCAL_ELLIPSOID_FIT_WORKSPACE_LEN(n) (issue 14: the fit's matrices are here, not
 *  on the stack). */
#define MAGCAL_ELLIPSOID_CALIBRATE_WORKSPACE_LEN(n)                                                 \
    (MAGCAL_ELLIPSOID_CALIBRATE_SLOTS + (size_t)(n) * sizeof(magcal_vec3_t) +                       \
     ((MAGCAL_OPTICS3_FILTER_WORKSPACE_LEN(n) > MAGCAL_ELLIPSOID_FIT_WORKSPACE_LEN(n))              \
          ? MAGCAL_OPTICS3_FILTER_WORKSPACE_LEN(n)                                                  \
          : MAGCAL_ELLIPSOID_FIT_WORKSPACE_LEN(n)))
/** Declare `name` as a correctly aligned workspace of MAGCAL_ELLIPSOID_CALIBRATE_WORKSPACE_LEN(n) bytes. */
#define MAGCAL_ELLIPSOID_CALIBRATE_WORKSPACE_DECLARE(name, n)                                       \
    MAGCAL_WORKSPACE_DECLARE(name, MAGCAL_ELLIPSOID_CALIBRATE_WORKSPACE_LEN(n))

#if MAGCAL_CFG_ENABLE_3D
/**
 * @brief One complete 3-D calibration: a cheap pre-test, the density stage only when the data show
 *        gross outliers, then the ellipsoid fit (docs/calibration_3d.md, docs/performance.md).
 *
 * AUTO: the fit of all n samples is the pre-test; it is returned as it is when MAGCAL_OK and every
 * sample lies within pretest_max_rel x F of its shell (the density stage would find nothing the
 * fit's own residual gate does not). Otherwise (any gross outlier, or the pre-test fit failed) the
 * result is exactly that of ALWAYS: magcal_optics_filter3 on all samples, then magcal_ellipsoid_fit
 * on its inliers, so bursts and glitches get the density stage they need.
 *
 * @param[in]  cfg      configuration (MAGCAL_ELLIPSOID_CALIBRATE_CFG_DEFAULT).
 * @param[in]  m        n raw samples (as magcal_ellipsoid_fit).
 * @param[in]  n        number of samples (>= 10; <= MAGCAL_MAX_SAMPLES when the density stage may run).
 * @param[out] work     scratch, 4-byte aligned, >= MAGCAL_ELLIPSOID_CALIBRATE_WORKSPACE_LEN(n) bytes
 *                      (the fit's scratch too: magcal_ellipsoid_fit_ws).
 * @param[in]  work_len bytes at work.
 * @param[out] inlier   NULL, or n flags: 1 = given to the fit (kept by the density stage, or every
 *                      sample when it did not run); written only on MAGCAL_OK.
 * @param[out] out      the fit; written only on MAGCAL_OK (out->n_used etc. count the fit's input).
 * @param[out] info     NULL, or what was done; written on MAGCAL_OK and on a failure of the fit.
 * @return MAGCAL_OK; MAGCAL_ERR_NULL (cfg, m, work or out NULL); MAGCAL_ERR_ARG (mode or
 *         pretest_max_rel out of range, or a stage's config invalid); MAGCAL_ERR_ALIGNMENT (work not
 *         4-byte aligned); MAGCAL_ERR_WORKSPACE (work_len too small); every status of
 *         magcal_optics_filter3 (density stage) and
 *         of magcal_ellipsoid_fit.
 *
 * @code
 * #define N3 320u
 * static magcal_vec3_t samples[N3];             // filled by the application
 * static MAGCAL_ELLIPSOID_CALIBRATE_WORKSPACE_DECLARE(work, N3);
 * const magcal_ellipsoid_calibrate_cfg_t cfg = MAGCAL_ELLIPSOID_CALIBRATE_CFG_DEFAULT;
 * magcal_ellipsoid_result_t fit;
 * if (magcal_ellipsoid_calibrate(&cfg, samples, N3, work, sizeof work, NULL, &fit, NULL) == MAGCAL_OK) {
 *     // fit.cal: h = G (m - V)
 * }
 * @endcode
 */
magcal_status_t magcal_ellipsoid_calibrate(const magcal_ellipsoid_calibrate_cfg_t *cfg,
                                           const magcal_vec3_t *m, size_t n, void *work,
                                           size_t work_len, uint8_t *inlier,
                                           magcal_ellipsoid_result_t *out,
                                           magcal_ellipsoid_calibrate_info_t *info);

/**
 * @brief Start a time-sliced magcal_ellipsoid_calibrate (O(1): the checks of the one-shot call,
 *        the info cleared; the fit configurations are checked by the steps).
 * @param[out] s slice state, caller memory (kept until the calibration has finished); the other
 *               parameters as magcal_ellipsoid_calibrate, and m, cfg, work, inlier, out, info
 *               must stay valid (m and cfg unchanged) until it has finished.
 * @return MAGCAL_OK (call magcal_ellipsoid_calibrate_step); MAGCAL_ERR_NULL; MAGCAL_ERR_ARG;
 *         MAGCAL_ERR_ALIGNMENT; MAGCAL_ERR_WORKSPACE (as magcal_ellipsoid_calibrate).
 */
magcal_status_t magcal_ellipsoid_calibrate_begin(magcal_ellipsoid_calibrate_slice_t *s,
                                                 const magcal_ellipsoid_calibrate_cfg_t *cfg,
                                                 const magcal_vec3_t *m, size_t n, void *work,
                                                 size_t work_len, uint8_t *inlier,
                                                 magcal_ellipsoid_result_t *out,
                                                 magcal_ellipsoid_calibrate_info_t *info);

/**
 * @brief Do at most about `budget` estimated Cortex-M4F instructions of the calibration (at least
 *        one unit per call). The fits are sliced (magcal_ellipsoid_fit_step), and so is the
 *        density stage (magcal_optics_filter3_step, only when the pre-test finds a gross outlier,
 *        or mode ALWAYS), within the same budget.
 * @return MAGCAL_IN_PROGRESS while work remains; then exactly the status and outputs of
 *         magcal_ellipsoid_calibrate, returned again by any further call; MAGCAL_ERR_NULL (s NULL);
 *         MAGCAL_ERR_ARG (s not started by a successful begin).
 */
magcal_status_t magcal_ellipsoid_calibrate_step(magcal_ellipsoid_calibrate_slice_t *s, uint32_t budget);

/**
 * @brief 1 while a time-sliced calibration is in its density stage (its steps are many small
 *        visits, so a caller sharing a step's budget with other work can give it all but what
 *        that work's next piece costs), else 0 (also for s NULL).
 */
uint32_t magcal_ellipsoid_calibrate_in_density(const magcal_ellipsoid_calibrate_slice_t *s);
#endif /* MAGCAL_CFG_ENABLE_3D */

#ifdef __cplusplus
}
#endif

#endif /* MAGCAL_ELLIPSOID_H */
