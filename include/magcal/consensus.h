/**
 * @file consensus.h
 * @brief Model-residual outlier stage after the density filter: deterministic RANSAC/LMedS over
 *        5-point minimal ellipse sets, then a MAD-scaled residual threshold and refit.
 *
 * Why: a density filter (OPTICS/DBSCAN, optics.h) cannot separate singular points that arrive as
 * dense bursts of consecutive samples, or that sit close to the ring (algorithms.md 4.3 caveats).
 * Those points are far from the ellipse in RESIDUAL even when they are dense, so this stage judges
 * every sample by its distance to a robustly found ellipse.
 *
 * Algorithm (all steps bounded, deterministic for a given cfg->seed):
 *  1. Candidates = samples with cand_mask[i] != 0 (the density filter's inliers; NULL = all).
 *     They are sorted by angle around their coordinate-wise median.
 *  2. Up to max_iter draws of a minimal set: 5 candidates spread over the angular order (one
 *     random candidate in each fifth of the order, starting at a random rank: well conditioned
 *     sets even on partial arcs). The conic through them (magcal_ellipse_fit_idx, exact 5-point
 *     path) is kept only if it is an ellipse. Score = median over the samples EXCEPT the five of
 *     the minimal set (their residuals are 0 by construction) of |magcal_ellipse_residual| (least
 *     median of squares: no threshold needed, breakdown 50%), taken on a fixed subsample (every
 *     ceil(n / 64)-th sample: all of them up to n = 64); the best set is then scored on every
 *     sample (best_score). Above 64 samples the draws end early, after at least 16, once
 *     (1 - w^5)^draws <= 0.001 for the best set's inlier fraction w on the subsample
 *     (|r| <= 2.5 LMedS sigmas): the RANSAC bound (issue 14: 2.3x cheaper at n = 288).
 *     If no draw gives an ellipse the least-squares fit of all candidates is the start model.
 *  3. Start: sigma = 1.4826 (1 + 5 / (n - 5)) * score (Rousseeuw & Leroy's finite-sample
 *     factor). Each refit round on k inliers: sigma = max(1.4826 median |r|, RMS |r|) *
 *     sqrt(k / (k - 5)) over the current inliers (the RMS is the efficient scale; the inliers are
 *     already cut at the threshold), and the threshold uses the Student-t quantile of k_sigma,
 *     k_sigma (1 + (k_sigma^2 + 1) / (4 (k - 5))) (k > 10). sigma is floored at LSB / sqrt(12),
 *     LSB = the smallest positive step between the candidates' sorted x or y values (rounding
 *     noise of quantised samples; ~0 for continuous data).
 *     threshold = clamp(that, min_thr_rel * R, max_thr_rel * R) with
 *     R = sqrt(semi_minor * semi_major); inliers = { i : |r_i| <= threshold } over EVERY sample
 *     (a point the density filter rejected but that lies on the ellipse is taken back);
 *     refit on the inliers (magcal_ellipse_fit with the mask), recompute every residual.
 *     Repeat until the inlier set stops changing or refine_iter rounds were done.
 *     Measured (tests/test_consensus.c): 0.47 % of exactly 20 clean samples rejected (was 7.6 %),
 *     all 300 samples of a 5-LSB quantised ring kept.
 *
 * Time-sliced: magcal_consensus_begin() + magcal_consensus_step() run the same algorithm in
 * steps of a bounded number of Cortex-M4F instructions (budget; every loop over the samples, the
 * selections, sorts and refits resume where the last step stopped), with the outputs of
 * magcal_consensus_run() bit for bit; magcal_consensus_run() is begin + one unbounded step.
 *
 * Units: residuals, sigma and threshold in the unit of the points (raw LSB, uT, ...).
 * Axes: x right, y forward.
 *
 * @code
 * static magcal_vec2_t pts[600];                // filled by the caller
 * static uint8_t cand[600], inl[600];           // cand: density filter output (optics.h)
 * static MAGCAL_CONSENSUS_WORKSPACE_DECLARE(work, 600);
 * magcal_consensus_cfg_t cfg = MAGCAL_CONSENSUS_CFG_DEFAULT;
 * magcal_consensus_result_t res;
 * magcal_status_t st = magcal_consensus_run(&cfg, pts, 600, cand, work, sizeof work, inl, &res);
 * // st == MAGCAL_OK: res.fit is the ellipse of the inl[i] == 1 samples
 * @endcode
 */
#ifndef MAGCAL_CONSENSUS_H
#define MAGCAL_CONSENSUS_H

#include <stddef.h>
#include <stdint.h>

#include "magcal/config.h"
#include "magcal/ellipse.h"
#include "magcal/status.h"
#include "magcal/types.h"

#ifdef __cplusplus
extern "C" {
#endif

/* MAGCAL_CONSENSUS_MAX_ITER and MAGCAL_CONSENSUS_MAX_REFINE (limits of the configuration) are
 * build-time limits in magcal/config.h. */

/** @cond INTERNAL */
/* Bytes of the run state kept in the workspace (three ellipse models, the fit slice, the
 * resumable selection and sort, the loop state; off the stack) with its alignment slack;
 * consensus.c checks the size with a static assert. */
#define MAGCAL_CONSENSUS_STATE_LEN_                                                                \
    (3u * sizeof(magcal_ellipse_t) + sizeof(magcal_ellipse_fit_slice_t) + 32u * sizeof(size_t) +   \
     160u)
/** @endcond */

/**
 * Workspace bytes for magcal_consensus_run() / magcal_consensus_begin() on n samples: the run
 * state (three ellipse models: best, current, candidate/refit; the refit's fit slice, the
 * resumable selection and sort, the loop state), |residual| float[n], scratch float[n] (angles,
 * then selection), candidate order uint16[n] (then the working inlier mask), plus alignment slack.
 * 10 bytes per sample + MAGCAL_CONSENSUS_STATE_LEN_ (740 bytes on a 32-bit target).
 */
#define MAGCAL_CONSENSUS_WORKSPACE_LEN(n)                                                          \
    (((((size_t)(n) * 10u) + 3u + 4u) & ~(size_t)3u) + MAGCAL_CONSENSUS_STATE_LEN_)

/** Declare `name` as a correctly aligned workspace of MAGCAL_CONSENSUS_WORKSPACE_LEN(n) bytes (config.h). */
#define MAGCAL_CONSENSUS_WORKSPACE_DECLARE(name, n) MAGCAL_WORKSPACE_DECLARE(name, MAGCAL_CONSENSUS_WORKSPACE_LEN(n))

/** Configuration of the consensus stage (validated by every call). */
typedef struct {
    uint16_t max_iter;    /**< minimal-set draws, 1..MAGCAL_CONSENSUS_MAX_ITER (default 48) */
    uint16_t refine_iter; /**< threshold/refit rounds, 1..MAGCAL_CONSENSUS_MAX_REFINE (default 8) */
    uint32_t seed;        /**< PRNG seed (magcal_prng_next); 0 is replaced by a fixed constant */
    float k_sigma;        /**< threshold in robust sigmas, > 0 (default 3.5) */
    float min_thr_rel;    /**< threshold floor, fraction of the mean radius, >= 0 (default 0.002) */
    float max_thr_rel;    /**< threshold cap, fraction of the mean radius, > min (default 0.25) */
} magcal_consensus_cfg_t;

/** Defaults: work without tuning on rings with up to about 45% singular points. */
#define MAGCAL_CONSENSUS_CFG_DEFAULT { 48u, 8u, 0x9E3779B9u, 3.5f, 0.002f, 0.25f }

/** Result and statistics of one consensus run. */
typedef struct {
    magcal_ellipse_t fit;   /**< final least-squares fit of the inliers */
    float sigma;            /**< residual scale of the inliers (step 3), point unit */
    float threshold;        /**< |residual| <= threshold is an inlier, point unit */
    float best_score;       /**< median |residual| of the best minimal-set model, point unit */
    uint16_t n_candidates;  /**< samples the minimal sets were drawn from */
    uint16_t n_inliers;     /**< final inliers (every sample judged) */
    uint16_t n_rescued;     /**< inliers that were not candidates (density filter rejects taken back) */
    uint16_t n_rejected;    /**< candidates rejected by the residual threshold */
    uint16_t draws;         /**< minimal sets drawn */
    uint16_t valid_models;  /**< minimal sets whose conic was an ellipse */
    uint16_t rounds;        /**< threshold/refit rounds done */
} magcal_consensus_result_t;

/**
 * @brief Robust ellipse fit: RANSAC/LMedS minimal sets from the candidates, residual threshold
 *        over every sample, refit (algorithm in the file comment).
 * @param[in]  cfg        configuration (MAGCAL_CONSENSUS_CFG_DEFAULT works without tuning).
 * @param[in]  pts        n samples, finite, x right / y forward, any unit.
 * @param[in]  n          number of samples, 5..MAGCAL_MAX_SAMPLES.
 * @param[in]  cand_mask  NULL (every sample is a candidate) or n bytes, != 0 = candidate.
 * @param[out] work       scratch, >= MAGCAL_CONSENSUS_WORKSPACE_LEN(n) bytes (any alignment).
 * @param[in]  work_len   bytes at work.
 * @param[out] inlier_mask n bytes: 1 = inlier of the final fit, 0 = outlier. Untouched on failure.
 * @param[out] result     fit and statistics. Untouched on failure.
 * @return MAGCAL_OK;
 *         MAGCAL_ERR_NULL (cfg, pts, work, inlier_mask or result NULL);
 *         MAGCAL_ERR_ARG (a cfg value out of its documented range, n > MAGCAL_MAX_SAMPLES);
 *         MAGCAL_ERR_WORKSPACE (work_len too small);
 *         MAGCAL_ERR_NONFINITE (a NaN/Inf sample);
 *         MAGCAL_ERR_TOO_FEW_POINTS (n < 5, fewer than 5 candidates, or fewer than 5 inliers);
 *         any failure status of magcal_ellipse_fit() when neither a minimal set nor the
 *         candidates give an ellipse (MAGCAL_ERR_DEGENERATE, MAGCAL_ERR_ILL_CONDITIONED,
 *         MAGCAL_ERR_HYPERBOLA, MAGCAL_ERR_PARABOLA, MAGCAL_ERR_IMAGINARY).
 */
magcal_status_t magcal_consensus_run(const magcal_consensus_cfg_t *cfg, const magcal_vec2_t *pts, size_t n,
                                     const uint8_t *cand_mask, void *work, size_t work_len,
                                     uint8_t *inlier_mask, magcal_consensus_result_t *result);

/**
 * Time-sliced consensus run (docs/performance.md "time-sliced work"): the state of one
 * magcal_consensus_run() in caller memory; the bulk of the run state lives in the workspace.
 * Fields are private.
 */
typedef struct {
    void *state_;   /* the run state, aligned at the start of the caller's workspace */
    uint32_t used_; /* estimated M4F instructions charged by the last step (a caller sharing one
                     * budget between stages may read it) */
    uint8_t phase_;
    int8_t status_;
} magcal_consensus_slice_t;

/**
 * @brief Start a time-sliced magcal_consensus_run(): O(1) checks of the arguments (the samples
 *        are checked by the steps), stores the inputs.
 *
 * The inputs (cfg, pts, cand_mask) and the workspace must stay unchanged and alive until the run
 * has finished; inlier_mask is written by the steps (complete only once the run has finished) and
 * result by the last step. Parameters as magcal_consensus_run().
 * @param[out] s slice state, caller memory.
 * @return MAGCAL_OK (call magcal_consensus_step()); MAGCAL_ERR_NULL (s or an argument NULL),
 *         MAGCAL_ERR_ARG, MAGCAL_ERR_TOO_FEW_POINTS (n < 5), MAGCAL_ERR_WORKSPACE as
 *         magcal_consensus_run().
 */
magcal_status_t magcal_consensus_begin(magcal_consensus_slice_t *s, const magcal_consensus_cfg_t *cfg,
                                       const magcal_vec2_t *pts, size_t n, const uint8_t *cand,
                                       void *work, size_t work_len, uint8_t *inlier,
                                       magcal_consensus_result_t *res);

/**
 * @brief Early end for a caller that only wants a nearly clean result (the calibrator's pre-test):
 *        after begin, before the run ends. When a threshold/refit round leaves more than max_out
 *        samples outside the threshold, the run ends there with MAGCAL_ERR_TOO_MANY_OUTLIERS
 *        (outputs as on any failure: inlier_mask incomplete, result unset). Without this call
 *        (the default) a run never ends early.
 * @return MAGCAL_OK; MAGCAL_ERR_NULL; MAGCAL_ERR_ARG (not begun or already ended, or max_out
 *         outside 1..65535).
 */
magcal_status_t magcal_consensus_limit_rejects(magcal_consensus_slice_t *s, size_t max_out);

/**
 * @brief Do at most about budget Cortex-M4F instructions of the run started by
 *        magcal_consensus_begin() (at least one unit of work per call, so any budget >= 1 makes
 *        progress).
 * @param[in,out] s      slice state.
 * @param[in]     budget estimated M4F instructions for this call (MAGCAL_SLICE_BUDGET_DEFAULT).
 * @return MAGCAL_IN_PROGRESS while work remains; then exactly the status and outputs of
 *         magcal_consensus_run() (bit for bit), returned again by any further call;
 *         MAGCAL_ERR_NULL (s NULL); MAGCAL_ERR_ARG (s not started).
 */
magcal_status_t magcal_consensus_step(magcal_consensus_slice_t *s, uint32_t budget);

#ifdef __cplusplus
}
#endif

#endif /* MAGCAL_CONSENSUS_H */
