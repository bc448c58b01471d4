/**
 * @file calibrator.h
 * @brief The 2-D calibration pipeline a firmware loop uses: collect level samples, reject
 *        singular points, fit the ellipse, gate the result and adopt it only when it is sound.
 *
 * Pipeline of magcal_calibrator_run():
 *  1. pre-checks: enough samples (cfg.min_samples), not all identical;
 *  2. pre-test (cfg.pretest: on in MAGCAL_CALIBRATOR_CFG_STORE_DEFAULT; with the default filter
 *     and the consensus): the
 *     consensus of step 4 on every sample first; when it succeeds, rejects at most
 *     n / MAGCAL_CALIBRATOR_PRETEST_DIV samples and none farther than 6 thresholds from its fit,
 *     the data show nothing the density stage would catch: its inliers stand in for the filter's,
 *     the filter and the thinning are skipped and it is the fit (report pretest_clean = 1);
 *     otherwise the pipeline goes on exactly as without the pre-test (same results bit for bit);
 *     density filter (optics.h / dbscan.h): OPTICS improved + grid with automatic eps, eps' and
 *     MinPts by default; OPTICS classic; DBSCAN; or none. cfg.eps / cfg.min_pts override the
 *     automatic values (DBSCAN with eps = 0 uses the automatic eps'); then the filter inliers
 *     must not be collinear (tested after the filter, so far outliers cannot fake collinearity);
 *  3. coverage pre-gate: every sample, around a hard-iron circle fit of the filter inliers (so a
 *     short arc is reported as COVERAGE, not as whatever conic it happens to fit); when the filter
 *     inliers alone miss the gate (bursts split the ring into arcs, algorithms.md 4.3) the
 *     consensus draws from every sample (report.filter_fragmented = 1);
 *  4. consensus (consensus.h): RANSAC/LMedS minimal ellipse sets, MAD-scaled residual threshold,
 *     refit; every sample is judged by its residual (cfg.use_consensus = 0: a plain
 *     least-squares fit of the filter inliers);
 *  5. gates, each with its own status: consistency (cfg.max_inconsistent_frac: INCONSISTENT when
 *     the residual stage rejects too large a share of the plausible samples, a store holding two
 *     installations), too many outliers, not an ellipse (hyperbola, parabola, imaginary), radius
 *     range, axis ratio, residual, coverage (around the fitted centre);
 *  6. correction (magcal_ellipse_to_cal), the heading-error estimate and the observability gate
 *     (UNOBSERVABLE, below), then the adoption rule (below).
 *
 * Heading-error estimate (radians in the formulas, degrees in the report; docs/calibrator.md).
 * The inliers are corrected by the new calibration; d_i = |h_i| / mean - 1 is fitted by least
 * squares on G = [1, cos phi, sin phi, cos 2phi, sin 2phi] (phi = direction of h_i). A centre error
 * makes a first harmonic of d, a soft-iron error a second, each with the same relative amplitude
 * as the heading error it causes, and the mean square heading error over uniformly spread
 * headings is 1/2 the sum of the four harmonic coefficients squared. With s^2 = the residual
 * variance after the harmonics (dof n - 5), floored by the rounding noise (LSB / sqrt(12) / R,
 * LSB = the data's smallest coordinate step), S = (G^T G)^-1 restricted to the harmonics and
 * dup = used / distinct values:
 *     est_noise_deg       = s                                   (per-sample noise of new data)
 *     est_param_err_deg   = sqrt(1/2 s_p^2 dup tr(S) + bias^2)  (the calibration's own error)
 *     bias^2              = 1/2 (1.5 s^2 n)^2 tr(S^2)           (O(sigma^2) bias of weak designs)
 *     est_heading_err_deg = sqrt(est_noise^2 + est_param^2)      (what a user sees on new data)
 * where s_p^2 counts rounding the residuals do not show 8 times (a lattice's errors are
 * correlated along the ring). design_factor = n |S|_F / 4 (1 for uniformly spread headings).
 * Validated by Monte-Carlo (tests/test_trust2d.c): within [0.5, 2] x the measured heading RMS.
 * Observability gate: est_param_err_deg > cfg.max_param_err_ratio x est_noise_deg (with repeated
 * values: its upper bound x (1 + 1/sqrt(2 (distinct - 5)))), or design_factor >
 * cfg.max_design_factor, or a singular harmonic design gives MAGCAL_ERR_UNOBSERVABLE: the
 * headings (clumps, gaps) or the resolution (a few LSB) do not determine the calibration to
 * better than the per-sample noise; turn through the missing headings (report missing_*) or raise
 * the sensor gain. The default 0.6 keeps the expected heading RMS within 1.17 x the noise floor.
 *
 * Adoption rule. The caller's calibration `current` is replaced only when the new one passes
 * every gate AND one of (report adopt_rule names it):
 *  (a) UNUSABLE: `current` is not a usable calibration (magcal_cal2d_validate fails) or its radius
 *      is 0 (never fitted, e.g. MAGCAL_CAL2D_IDENTITY);
 *  (b) BETTER: current_err_deg > MAGCAL_CALIBRATOR_ADOPT_MARGIN (3) x est_param_err_deg (and
 *      > MAGCAL_CALIBRATOR_ADOPT_MIN_DEG): `current` is clearly worse than the new calibration
 *      by the new data's own estimate;
 *  (c) STALE: `current` is demonstrably wrong on the new data, current_err_z >
 *      MAGCAL_CALIBRATOR_STALE_Z (10: far outside what noise does to a correct calibration: the
 *      installation changed, or `current` came from poorer data), AND the same field strength was
 *      seen (the new inliers corrected by `current` have a mean radius within
 *      cfg.max_radius_change of current->radius) AND the new calibration is not worse
 *      (est_param_err_deg <= current_err_deg).
 * A tie, or a new calibration that is better only within the noise of the comparison, never
 * replaces `current`: run() returns MAGCAL_ERR_NOT_BETTER and `current` is untouched. (Rule (c)
 * is data-based only; ageing of the current calibration over time is not modelled here.)
 * current_err_deg: the same harmonic analysis of `current` on the new inliers, with the noise
 * projection's expectation removed, so noise does not read as error:
 *     current_err_deg = sqrt(max(0, 1/2 |beta_1..4|^2 - 1/2 s_p^2 dup tr(S)))
 *     current_err_z   = (1/2 |beta|^2 - 1/2 s_p^2 dup tr(S)) / sqrt(1/2 tr((s_p^2 dup S)^2))
 * Heading shift if adopted: for headings psi = 0, 5, ..., 355 deg the raw point of the new
 * ellipse that the new calibration maps to psi is corrected with `current` (identity when
 * `current` is unusable); max and RMS of wrap(psi_current - psi).
 *
 * Coarse stage (hard iron only; off unless the continuous calibrator enables it for a solve,
 * continuous.h cfg.coarse_coverage_deg, and only while no full calibration is installed): when
 * the pre-gate coverage is below cfg.min_coverage_deg but at least the coarse coverage, the
 * circle (centre = hard iron, radius; no soft iron) of the filter / pre-test inliers is kept,
 * its inliers re-gated by the consensus's residual threshold (k_sigma x residual RMS, clamped to
 * [min_thr_rel, max_thr_rel] x radius), refitted, gated (min_samples, max_outlier_frac, radius
 * range, max_residual_rel, corrected coverage >= the coarse coverage) and turned into a
 * calibration (offset = centre, matrix = output scale). Its error bound: the harmonic analysis
 * above of the CIRCLE calibration on its own inliers recovers, to first order, its first (centre)
 * and second (unmodelled soft iron) harmonics over the whole circle even though the inliers
 * cover an arc only (the residual of a 3-parameter fit stays in the span of the 5 regressors);
 * noise on the arc inflates tr(S). So
 *     est_param_err_deg = sqrt(1/2 |beta|^2) + 3 sqrt(1/2 s_p^2 dup tr(S)) + bias     (a bound:
 *                         |beta_true| <= |beta| + |noise|, the noise part's 99.5 % quantile)
 * and the coarse calibration passes only when that bound is <= the continuous calibrator's
 * cfg.coarse_max_err_deg (else MAGCAL_ERR_UNOBSERVABLE: the arc does not bound the soft iron
 * well enough); report coarse = 1. Adoption: as (a)..(c) against a coarse `current`; a full
 * calibration replaces a coarse `current` by rule (b) with margin 1 (current_err_deg >=
 * est_param_err_deg: never worse), and a coarse one never replaces a full one.
 *
 * Arc stage (the full ellipse below the coverage gate; off unless the continuous calibrator enables
 * it, continuous.h cfg.arc_coverage_deg, and only while no calibration is installed): when the
 * pre-gate coverage or the corrected coverage is below cfg.min_coverage_deg but at least the arc
 * coverage, the 5-parameter ellipse is fitted and gated as usual (report arc = 1) and, instead of
 * the observability gate, judged by a bound on its heading error over the WHOLE circle, the
 * headings the arc never saw included: the harmonics' covariance C = s_p^2 dup (G^T G)^-1 (the
 * fit's own, first order) gives the heading-error variance w^T C w at 36 headings, w = (-sin phi,
 * cos phi, -sin 2phi, cos 2phi), and
 *     bound (est_param_err_deg) = sqrt(1/2 |beta|^2) + 3 max_phi sqrt(w^T C w) + bias + model
 * (model: the continuous calibrator's cfg.arc_model_deg, what an arc cannot see: a tilt or a
 * vertical-field leak the fit absorbs; the sd part with repeated values times the full gate's
 * upper confidence factor). It passes only when the share of plausible samples the residual stage
 * rejected is <= MAGCAL_CALIBRATOR_ARC_INCONSISTENT (else MAGCAL_ERR_INCONSISTENT) and the bound
 * is <= cfg.arc_max_err_deg (else MAGCAL_ERR_UNOBSERVABLE); est_param_err_deg = the bound (NaN
 * when the solve ended before it). An arc
 * calibration never replaces a full one; a full one replaces it by rule (b) with margin 1.
 *
 * Time-sliced solve (src/adopt/calibrator_solve.c; the continuous calibrator, continuous.h, drives it):
 * run() is one call of the same resumable phases with an unlimited budget (one code path). Each
 * phase keeps its cursor and sums in the workspace (the run state, or the stage scratch when the
 * stage that owns it is done), charges an estimated Cortex-M4F weight per visit and stops when
 * the step's budget is spent: pre-checks, the density filter (optics.h slice), masks, mean /
 * scale / moments and the hard-iron circle, both coverages, thinning and consensus (optics.h,
 * consensus.h slices) or the plain fit (ellipse.h slice), gates, ellipse -> calibration,
 * corrected coverage, distinct values (a resumable shell sort), the harmonics (one 5x5 solve per
 * visit), the shift (one heading per visit), the adoption rule. Exceptions, one-shot inside one
 * step (documented cost, docs/calibrator.md): the DBSCAN filter (auto parameters + DBSCAN +
 * largest cluster) and the automatic radius with a caller's MinPts (magcal_optics_auto_params);
 * the OPTICS filter with the classic order or a caller's eps goes through the same optics.h
 * slice API (sliced as far as optics.h slices it); ellipse -> calibration is one visit (~2,500).
 *
 * Memory: caller-allocated instance, sample buffer (capacity <= MAGCAL_MAX_SAMPLES) and one
 * workspace of MAGCAL_CALIBRATOR_WORKSPACE_LEN(capacity) bytes (4-byte aligned) that also keeps
 * the per-sample outlier flags between run() and the next reset. No heap.
 *
 * Axes: x right, y forward (only x, y of a port sample are used; the sensor must stay level).
 * Units: the sensor's unit (raw LSB, uT, ...); heading degrees clockwise from magnetic north.
 *
 * @code
 * #include "magcal/calibrator.h"
 *
 * #define CAP 512u
 * static magcal_calibrator_t cal;
 * static magcal_vec2_t buf[CAP];
 * static MAGCAL_CALIBRATOR_WORKSPACE_DECLARE(work, CAP);  // aligned, >= the size macro
 * static magcal_cal2d_t stored = MAGCAL_CAL2D_IDENTITY;    // or restored from flash
 *
 * void calibration_task(void)
 * {
 *     magcal_calibrator_cfg_t cfg = MAGCAL_CALIBRATOR_CFG_DEFAULT;
 *     magcal_cal_report_t rep;
 *     (void)magcal_calibrator_init(&cal, &cfg, buf, CAP, work, sizeof work);
 *     while (magcal_calibrator_state(&cal) == MAGCAL_CALIBRATOR_COLLECTING) {
 *         (void)magcal_calibrator_poll(&cal);             // one port sample per call
 *     }
 *     if (magcal_calibrator_run(&cal, &stored, &rep) == MAGCAL_OK) {
 *         // rep.adopted == 1, rep.adopt_rule says why: `stored` holds the new calibration;
 *         // write it to flash; rep.est_heading_err_deg is the heading error to expect
 *     } else if (rep.status == MAGCAL_ERR_UNOBSERVABLE) {
 *         // turn through rep.missing_start_deg .. + rep.missing_width_deg and run again
 *     }
 * }
 * @endcode
 */
#ifndef MAGCAL_CALIBRATOR_H
#define MAGCAL_CALIBRATOR_H

#include <stddef.h>
#include <stdint.h>

#include "magcal/config.h"
#include "magcal/consensus.h"
#include "magcal/dbscan.h"
#include "magcal/ellipse.h"
#include "magcal/heading.h"
#include "magcal/optics.h"
#include "magcal/status.h"
#include "magcal/types.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Larger of two size expressions (compile-time constant for constant arguments). */
#define MAGCAL_CALIBRATOR_MAX_(a, b) ((a) > (b) ? (a) : (b))

/**
 * Bytes of the persistent per-sample byte array (the flags), 4-aligned. The density filter writes
 * its inlier mask straight into it; run() copies that mask and the consensus output mask into the
 * part of the stage scratch the consensus does not use (MAGCAL_CALIBRATOR_CONSENSUS_LEN) and folds
 * them into the flag bits, so only one byte per sample outlives the stages.
 */
#define MAGCAL_CALIBRATOR_MASKS_LEN(cap) (((size_t)(cap) + 3u) & ~(size_t)3u)

/** Scratch of the consensus stage: its workspace, then the filter and consensus masks [cap] each. */
#define MAGCAL_CALIBRATOR_CONSENSUS_LEN(cap)                                                       \
    (MAGCAL_CONSENSUS_WORKSPACE_LEN(cap) + ((2u * (size_t)(cap) + 3u) & ~(size_t)3u))

/**
 * Bytes of the resumable part of the run state (calibrator_solve.c: budget, cursor, phase, and the
 * one slice state of the module running: DBSCAN configuration, density filter, thinning,
 * consensus, plain fit), checked by a static assert there. The prepare and adopt phases keep
 * their accumulators in the stage scratch.
 */
#define MAGCAL_CALIBRATOR_SLICE_LEN                                                                \
    (32u + MAGCAL_CALIBRATOR_MAX_(                                                                 \
               MAGCAL_CALIBRATOR_MAX_(sizeof(magcal_dbscan_cfg_t), sizeof(magcal_consensus_slice_t)), \
               MAGCAL_CALIBRATOR_MAX_(sizeof(magcal_optics_filter_slice_t),                        \
                                      sizeof(magcal_optics_thin_slice_t))))

/**
 * Bytes of the state of one magcal_calibrator_run() kept in the workspace instead of on the stack
 * (the report, the consensus result, the filter's configuration and result, the slice state),
 * 4-aligned.
 */
#define MAGCAL_CALIBRATOR_RUN_LEN                                                                  \
    ((sizeof(magcal_cal_report_t) + sizeof(magcal_consensus_result_t) +                            \
      sizeof(magcal_optics_cfg_t) + sizeof(magcal_optics_result_t) + MAGCAL_CALIBRATOR_SLICE_LEN + \
      (sizeof(void *) - 1u)) & ~(sizeof(void *) - 1u)) /* pointer-aligned: the scratch follows */

/**
 * Workspace bytes for a calibrator of the given capacity: the per-sample flags, the run() state
 * (MAGCAL_CALIBRATOR_RUN_LEN) plus the largest scratch of the stages (OPTICS filter, DBSCAN
 * labels + queue, consensus + its two masks). About 16 bytes per sample at capacity 1024 (the
 * sample buffer itself is 8 bytes per sample, separate).
 */
#define MAGCAL_CALIBRATOR_WORKSPACE_LEN(cap)                                                       \
    (MAGCAL_CALIBRATOR_MASKS_LEN(cap) + (sizeof(void *) - 4u) + MAGCAL_CALIBRATOR_RUN_LEN +        \
     MAGCAL_CALIBRATOR_MAX_(                                                                       \
         MAGCAL_CALIBRATOR_MAX_(MAGCAL_OPTICS_FILTER_WORKSPACE_LEN(cap),                           \
                                MAGCAL_CALIBRATOR_CONSENSUS_LEN(cap)),                             \
         ((2u * (size_t)(cap) + 3u) & ~(size_t)3u) +                                               \
             MAGCAL_CALIBRATOR_MAX_(MAGCAL_DBSCAN_WORKSPACE_LEN(cap),                              \
                                    MAGCAL_OPTICS_LARGEST_WORKSPACE_LEN(cap))))

/** Declare `name` as a correctly aligned workspace for a calibrator of capacity `cap` (config.h). */
#define MAGCAL_CALIBRATOR_WORKSPACE_DECLARE(name, cap)                                             \
    MAGCAL_WORKSPACE_DECLARE(name, MAGCAL_CALIBRATOR_WORKSPACE_LEN(cap))

/** Private: value of magcal_calibrator_t::magic in an initialised instance ("MCAL"). */
#define MAGCAL_CALIBRATOR_MAGIC 0x4D43414Cu

/** Per-sample flag bits (magcal_calibrator_flags()). */
#define MAGCAL_CALIBRATOR_FLAG_FILTER 0x01u   /**< rejected by the density filter */
#define MAGCAL_CALIBRATOR_FLAG_RESIDUAL 0x02u /**< rejected by the residual threshold (final) */
#define MAGCAL_CALIBRATOR_FLAG_JUDGED 0x80u   /**< sample took part in the last run() */

/** Density filter in front of the consensus stage. */
typedef enum {
    MAGCAL_FILTER_OPTICS_GRID = 0,    /**< OPTICS, improved (unordered seeds) + grid search (default) */
    MAGCAL_FILTER_OPTICS_CLASSIC = 1, /**< OPTICS, classic heap ordering, brute-force search */
    MAGCAL_FILTER_DBSCAN = 2,         /**< DBSCAN + largest cluster */
    MAGCAL_FILTER_NONE = 3            /**< no density filter: every sample is a candidate */
} magcal_calibrator_filter_t;

/** Lifecycle of a calibrator. */
typedef enum {
    MAGCAL_CALIBRATOR_COLLECTING = 0, /**< collecting; coverage not complete yet */
    MAGCAL_CALIBRATOR_READY = 1,      /**< coverage >= cfg.min_coverage_deg and >= min_samples: run() */
    MAGCAL_CALIBRATOR_CALIBRATED = 2, /**< last run() adopted a calibration */
    MAGCAL_CALIBRATOR_FAILED = 3,     /**< last run() failed or kept the old one; see last status */
    MAGCAL_CALIBRATOR_INVALID = 4     /**< not a calibrator: NULL, never initialised, or corrupted */
} magcal_calibrator_state_t;

/** Runtime configuration (copied at init; validated there). */
typedef struct {
    magcal_calibrator_filter_t filter; /**< density filter (default OPTICS improved + grid) */
    float eps;            /**< filter radius override, point unit; 0 = automatic (default) */
    uint16_t min_pts;     /**< MinPts override, 2..MAGCAL_MAX_MIN_PTS; 0 = automatic (default) */
    uint8_t use_consensus;  /**< 1 = residual stage after the filter (default), 0 = plain LS fit */
    magcal_consensus_cfg_t consensus; /**< consensus settings (MAGCAL_CONSENSUS_CFG_DEFAULT) */
    float min_spacing_deg;  /**< information gate of push(): minimum angle, around the provisional
                                 centre, from the last stored sample, 0..90 deg; 0 = accept all (default) */
    uint16_t max_per_bin;   /**< cap of stored samples per coverage bin; 0 = no cap (default) */
    uint16_t min_samples;   /**< fewer samples (or inliers) give TOO_FEW_POINTS, >= 5 (default 20) */
    float min_coverage_deg; /**< coverage gate, 0..360 (default 270: 3/4 of a turn) */
    float max_outlier_frac; /**< more rejected than this fraction gives TOO_MANY_OUTLIERS (0.5) */
    float min_axis_ratio;   /**< semi_minor / semi_major below this gives AXIS_RATIO (0.5) */
    float min_radius;       /**< sqrt(r1 r2) below this gives RADIUS_RANGE, point unit; 0 = none */
    float max_radius;       /**< sqrt(r1 r2) above this gives RADIUS_RANGE; 0 = none */
    float max_residual_rel; /**< residual RMS / radius above this gives RESIDUAL (0.1) */
    float max_radius_change;/**< adoption rule (c): relative field-radius change still plausible (0.2) */
    magcal_corr_form_t form;/**< correction form (default MAGCAL_CORR_SYMMETRIC) */
    float output_radius;    /**< rho for magcal_ellipse_to_cal; <= 0: sqrt(r1 r2), point unit (default 0) */
    float max_param_err_ratio; /**< observability gate: est_param_err_deg above this multiple of
                                    est_noise_deg gives UNOBSERVABLE, > 0 (default 0.6) */
    float max_design_factor; /**< observability gate: report design_factor above this gives
                                  UNOBSERVABLE (headings in 4 clumps: 13..19), >= 1 (default 8) */
    uint8_t pretest;         /**< 1 = residual pre-test before the density filter (pipeline step
                                  2; with the default filter, automatic eps and MinPts, and the
                                  consensus): on data without singular points the filter and the
                                  thinning are skipped (report pretest_clean = 1), otherwise the
                                  full pipeline runs exactly as with 0. 0 = always the full
                                  pipeline (MAGCAL_CALIBRATOR_CFG_DEFAULT, for raw buffers where
                                  bursts and glitches are common: the pre-test would be paid on
                                  top); 1 in MAGCAL_CALIBRATOR_CFG_STORE_DEFAULT (the continuous
                                  calibrator's informative store) */
    float max_inconsistent_frac; /**< consistency gate (Pipeline step 5): more than this fraction
                                      of the plausible samples (the density filter's inliers)
                                      rejected by the residual stage gives INCONSISTENT: the data
                                      hold more than one installation (a store that spans a change
                                      of the hard iron; the fit is then a compromise between two
                                      rings). 0..1, 0 = off (MAGCAL_CALIBRATOR_CFG_DEFAULT); 0.35 in
                                      MAGCAL_CALIBRATOR_CFG_STORE_DEFAULT (clean drives' stores:
                                      at most 0.29, stores spanning a hard-iron step: 0.39, 0.43;
                                      docs/calibrator.md "Consistency gate") */
} magcal_calibrator_cfg_t;

/** The defaults with cfg.pretest = pre and cfg.max_inconsistent_frac = inc (private: use the two
 *  defaults below). */
#define MAGCAL_CALIBRATOR_CFG_DEFAULT_PRE_(pre, inc)                                               \
    {                                                                                              \
        MAGCAL_FILTER_OPTICS_GRID, 0.0f, 0u, 1u, MAGCAL_CONSENSUS_CFG_DEFAULT, 0.0f, 0u, 20u,      \
            270.0f, 0.5f, 0.5f, 0.0f, 0.0f, 0.1f, 0.2f, MAGCAL_CORR_SYMMETRIC, 0.0f, 0.6f, 8.0f,   \
            (pre), (inc)                                                                           \
    }

/** Defaults that work without tuning (automatic filter parameters, accept every sample; the full
 *  pipeline on every run: no pre-test; no consistency gate: a raw buffer's glitch bursts can make
 *  a large share of residual rejects). */
#define MAGCAL_CALIBRATOR_CFG_DEFAULT MAGCAL_CALIBRATOR_CFG_DEFAULT_PRE_(0u, 0.0f)

/** The defaults for a store that holds informative ring samples only (the continuous
 *  calibrator's, continuous.h): the pre-test on, so a clean store skips the density stage; the
 *  consistency gate on (a store can span a change of the installation). */
#define MAGCAL_CALIBRATOR_CFG_STORE_DEFAULT MAGCAL_CALIBRATOR_CFG_DEFAULT_PRE_(1u, 0.35f)

/** Pre-test (cfg.pretest): the short path needs the consensus on every sample to reject at most
 *  n / this many samples (6.25 %; a clean drive's store: 0..5 %, a glitch or burst scenario more). */
#define MAGCAL_CALIBRATOR_PRETEST_DIV 16u

/** Adoption rule (b): `current` must be worse than the new calibration by this factor. */
#define MAGCAL_CALIBRATOR_ADOPT_MARGIN 3.0f
/** Adoption rule (c): `current`'s error on the new inliers is "demonstrably" non-zero above this
 *  many standard deviations of its noise-only distribution (report current_err_z). */
#define MAGCAL_CALIBRATOR_STALE_Z 10.0f
/** Rules (b) and (c) need a current error above this (degrees): float32 rounding, not data. */
#define MAGCAL_CALIBRATOR_ADOPT_MIN_DEG 1.0e-3f

/** Arc stage: the consistency gate of an arc (share of the plausible samples the residual stage
 *  rejected, Pipeline step 5), whatever cfg.max_inconsistent_frac: clean arcs of the generated
 *  drives 0..0.13, arcs of a store spanning a hard-iron step 0.20..0.22 (docs/calibrator.md
 *  "Arc stage"). */
#define MAGCAL_CALIBRATOR_ARC_INCONSISTENT 0.15f

/** Which adoption rule installed the new calibration (report adopt_rule). */
typedef enum {
    MAGCAL_ADOPT_NONE = 0,     /**< not adopted (failure, or NOT_BETTER) */
    MAGCAL_ADOPT_UNUSABLE = 1, /**< (a) `current` unusable: invalid, or radius 0 (never fitted) */
    MAGCAL_ADOPT_BETTER = 2,   /**< (b) `current` worse than the new one by MAGCAL_CALIBRATOR_ADOPT_MARGIN */
    MAGCAL_ADOPT_STALE = 3     /**< (c) `current` demonstrably wrong on the new data, same field
                                    radius, new one not worse */
} magcal_adopt_rule_t;

/** What run() did and found. Fields not reached by a failing run are 0, or NaN for the estimates
 *  (est_*, current_err_*): a failed run never reads as a perfect one. */
typedef struct {
    magcal_status_t status;   /**< same as run()'s return value */
    magcal_calibrator_state_t state; /**< state after the run */
    uint8_t adopted;          /**< 1 when `current` was replaced */
    uint16_t samples;         /**< samples in the buffer */
    uint16_t used;            /**< samples in the final fit */
    uint16_t rejected_filter; /**< rejected by the density filter */
    uint16_t rejected_consensus; /**< filter inliers rejected by the residual stage */
    uint16_t rescued_consensus;  /**< filter rejects taken back by the residual stage */
    uint16_t outliers;        /**< final outliers = samples - used */
    float filter_eps;         /**< eps' the density filter used (0 with filter none), point unit */
    uint16_t filter_min_pts;  /**< MinPts the density filter used */
    float coverage_deg;       /**< covered arc, multiple of 360/MAGCAL_COVERAGE_BINS */
    float missing_start_deg;  /**< largest uncovered sector: start, approx. heading deg [0,360) */
    float missing_width_deg;  /**< its width in degrees (0 when the circle is covered) */
    float residual_rms;       /**< RMS residual of the final fit, point unit */
    float residual_rel;       /**< residual_rms / radius */
    float radius;             /**< sqrt(semi_minor * semi_major), point unit */
    float axis_ratio;         /**< semi_minor / semi_major */
    float min_pivot;          /**< smallest equilibrated pivot of the final fit (condition) */
    float threshold;          /**< residual threshold used by classify(), point unit */
    magcal_ellipse_t ellipse; /**< final fit */
    float est_heading_err_deg;  /**< honest heading error a user sees on new data with the new
                                     calibration: noise + parameter error + bias (file comment),
                                     degrees; NaN when the run failed before the estimate */
    float current_err_deg;      /**< error of `current` on the new data, noise removed (file
                                     comment), deg; NaN if unusable or not reached; +Inf if it
                                     maps the new data onto no usable ring */
    float shift_max_deg;        /**< max |heading change| over 0..360 if adopted */
    float shift_rms_deg;        /**< RMS heading change over 0..360 if adopted */
    magcal_cal2d_t cal;         /**< the new calibration (also when not adopted: inspect only) */
    uint8_t filter_fragmented;  /**< 1: the filter inliers alone missed the coverage gate (ring split
                                     into arcs by bursts), so the consensus drew from every sample */
    float est_param_err_deg;    /**< RMS heading error of the new calibration's parameters alone
                                     (centre and soft iron), degrees; NaN before the estimate */
    float est_noise_deg;        /**< per-sample heading noise of the data (incl. quantisation), deg */
    float current_err_z;        /**< significance of current_err_deg: (err^2 - E_noise) / sd_noise */
    uint16_t distinct;          /**< distinct sample values among the inliers (quantisation) */
    float design_factor;        /**< weakness of the headings' design for the calibration: 1 for
                                     uniformly spread headings, large for clumps (file comment) */
    magcal_adopt_rule_t adopt_rule; /**< the rule that installed the new calibration */
    uint8_t pretest_clean;      /**< 1: the pre-test (cfg.pretest) found no outliers beyond its
                                     bound, the density filter and the thinning were skipped and
                                     the consensus on every sample is the fit (rejected_filter 0,
                                     filter_eps 0); 0: the full pipeline ran */
    uint8_t coarse;             /**< 1: a hard-iron-only calibration (circle: centre + radius, no
                                     soft iron) fitted on an arc below cfg.min_coverage_deg
                                     ("Coarse stage" above); est_param_err_deg is then an upper
                                     bound of its heading error over the whole circle, not an
                                     estimate. Only the continuous calibrator enables it. */
    uint8_t arc;                /**< 1: a full ellipse fitted on an arc below cfg.min_coverage_deg
                                     ("Arc stage" above); est_param_err_deg is then its
                                     whole-circle bound (NaN when not reached), an upper bound of
                                     its heading error over the whole circle, not an estimate.
                                     Only the continuous calibrator enables it. (In the padding
                                     behind `coarse`: the report does not grow.) */
} magcal_cal_report_t;

/** @brief Short constant name of an adoption rule ("unusable", "better", ...; "unknown"). */
const char *magcal_adopt_rule_str(magcal_adopt_rule_t rule);

/** Calibrator instance. Allocate it anywhere; every field is PRIVATE (use the functions). */
typedef struct {
    magcal_calibrator_cfg_t cfg;
    magcal_vec2_t *buf;
    size_t capacity;
    size_t n;
    uint8_t *flags;     /* workspace: per-sample flags [capacity] */
    uint8_t *mask_a;    /* workspace (stage scratch, after the filter): filter mask [capacity] */
    uint8_t *mask_b;    /* workspace (stage scratch): consensus inlier mask [capacity] */
    void *run;          /* workspace: run() state (report, consensus result, candidate) */
    void *scratch;      /* workspace: stage scratch */
    size_t scratch_len;
    magcal_vec2_t bb_min; /* bounding box of the stored samples */
    magcal_vec2_t bb_max;
    magcal_vec2_t centre;         /* provisional centre of the coverage bins */
    float centre_tol;             /* re-bin when the bbox midpoint moves more than this */
    uint16_t bins[MAGCAL_COVERAGE_BINS];
    int32_t last_bin_deg10;       /* angle of the last stored sample, 0.1 deg; -1 = none */
    magcal_ellipse_t fit;         /* final fit of the last successful run */
    float threshold;              /* its residual threshold */
    size_t n_judged;              /* samples judged by the last run */
    uint8_t has_fit;
    magcal_calibrator_state_t state;
    magcal_status_t last_status;
    uint32_t magic;
    /* coarse stage (set by the continuous calibrator, calibrator_internal.h
     * magcal_calibrator_set_coarse; 0 after init: off) */
    float coarse_min_cov;         /* coverage that admits the circle fit, deg; 0 = off */
    float coarse_max_err;         /* tolerance of its bound (est_param_err_deg), deg */
    uint8_t current_coarse;       /* 1: `current` passed to the solve is a coarse calibration */
    /* arc stage (set by the continuous calibrator, calibrator_internal.h
     * magcal_calibrator_set_arc; 0 after init: off) */
    float arc_min_cov;            /* coverage that admits an ellipse below cfg.min_coverage_deg, deg; 0 = off */
    float arc_max_err;            /* tolerance of its whole-circle bound, deg */
    float arc_model;              /* model-error term of the bound, deg */
    /* a model-error term of the estimate (set by the continuous calibrator from its store's tilt,
     * calibrator_internal.h magcal_calibrator_set_model; 0 after init) */
    float model_deg;              /* added in quadrature to est_param_err_deg, deg */
} magcal_calibrator_t;

/**
 * @brief Initialise a calibrator on caller storage.
 * @param[out] cal        instance.
 * @param[in]  cfg        configuration (copied); MAGCAL_CALIBRATOR_CFG_DEFAULT works untuned.
 * @param[in]  sample_buf buffer of `capacity` samples owned by the caller.
 * @param[in]  capacity   16..MAGCAL_MAX_SAMPLES.
 * @param[in]  work       workspace, 4-byte aligned, >= MAGCAL_CALIBRATOR_WORKSPACE_LEN(capacity):
 *                        declare it with MAGCAL_CALIBRATOR_WORKSPACE_DECLARE(work, capacity).
 * @param[in]  work_len   bytes at work.
 *
 * magcal_calibrator_init() is a macro: it passes the caller's MAGCAL_CONFIG_FINGERPRINT and
 * sizeof(magcal_calibrator_t) to magcal_calibrator_init_checked(), which refuses a caller compiled
 * with other limits (config.h) before writing anything.
 * @return MAGCAL_OK; MAGCAL_ERR_CONFIG_MISMATCH (caller compiled with other config.h limits than
 *         the library: its magcal_calibrator_t has another layout); MAGCAL_ERR_NULL;
 *         MAGCAL_ERR_ALIGNMENT (work not 4-byte aligned); MAGCAL_ERR_ARG (capacity out of range, a cfg
 *         value out of range: filter enum, eps < 0 or NaN, min_pts 1 or > MAGCAL_MAX_MIN_PTS,
 *         consensus settings, pretest > 1, min_samples < 5, coverage outside 0..360, fractions outside 0..1,
 *         radius limits < 0 or min > max, form enum, max_param_err_ratio <= 0, max_design_factor
 *         < 1, min_samples > capacity); MAGCAL_ERR_NONFINITE (a non-finite
 *         cfg value); MAGCAL_ERR_WORKSPACE (work_len too small). cal untouched on failure.
 */
magcal_status_t magcal_calibrator_init_checked(magcal_calibrator_t *cal, const magcal_calibrator_cfg_t *cfg,
                                               magcal_vec2_t *sample_buf, size_t capacity, void *work,
                                               size_t work_len, uint32_t config, size_t inst_size);
#define magcal_calibrator_init(cal, cfg, sample_buf, capacity, work, work_len)                     \
    magcal_calibrator_init_checked((cal), (cfg), (sample_buf), (capacity), (work), (work_len),     \
                                   MAGCAL_CONFIG_FINGERPRINT, sizeof(magcal_calibrator_t))

/** @brief Forget every sample and the last fit (state COLLECTING). @return MAGCAL_OK; MAGCAL_ERR_NULL;
 *  MAGCAL_ERR_NOT_INITIALISED. */
magcal_status_t magcal_calibrator_reset(magcal_calibrator_t *cal);

/**
 * @brief Offer one level sample (x right, y forward, sensor unit).
 *
 * Information gate (cfg.min_spacing_deg > 0 or cfg.max_per_bin > 0): the angle of p around the
 * provisional centre (mid-range of the stored samples) must differ from the last stored sample's
 * by at least min_spacing_deg, and its coverage bin must hold fewer than max_per_bin samples.
 * With both 0 every finite sample is stored (what the replay harness uses).
 * @return MAGCAL_OK (stored); MAGCAL_ERR_GATED (finite but adds no information: not stored, not a
 *         fault); MAGCAL_ERR_NONFINITE (NaN/Inf: not stored); MAGCAL_ERR_BUFFER_FULL (not stored;
 *         run() or reset()); MAGCAL_ERR_NULL; MAGCAL_ERR_NOT_INITIALISED.
 */
magcal_status_t magcal_calibrator_push(magcal_calibrator_t *cal, magcal_vec2_t p);

/**
 * @brief Read one sample through magcal_port_mag_read() (port/magcal_port.h) and push its x, y.
 * @return any status of magcal_calibrator_push(); the port's status when the read fails
 *         (MAGCAL_ERR_TIMEOUT, MAGCAL_ERR_PORT, MAGCAL_ERR_NO_DATA, ...), nothing stored then.
 */
magcal_status_t magcal_calibrator_poll(magcal_calibrator_t *cal);

/**
 * @brief As magcal_calibrator_poll(), from magnetometer `sensor` through magcal_port_mag_read_n()
 *        (port/magcal_port.h): one calibrator instance per sensor, each polled with its own index.
 * @return MAGCAL_ERR_ARG (sensor >= MAGCAL_PORT_MAX_SENSORS, or a sensor the port lacks); else as
 *         magcal_calibrator_poll().
 */
magcal_status_t magcal_calibrator_poll_n(magcal_calibrator_t *cal, uint8_t sensor);

/**
 * @brief Run the pipeline on the stored samples and apply the adoption rule (file comment).
 * @param[in]     cal     instance (samples are kept; flags and the final fit are updated).
 * @param[in,out] current caller's calibration: read (may be MAGCAL_CAL2D_IDENTITY or invalid);
 *                        replaced ONLY when the new calibration is adopted (then MAGCAL_OK and
 *                        report->adopted = 1); bit-identical otherwise.
 * @param[out]    report  optional (NULL): what happened (always written when non-NULL).
 * @return MAGCAL_OK (adopted); MAGCAL_ERR_NULL (cal or current NULL); MAGCAL_ERR_NOT_INITIALISED;
 *         MAGCAL_ERR_TOO_FEW_POINTS (fewer than cfg.min_samples samples or inliers);
 *         MAGCAL_ERR_DEGENERATE (all samples identical or collinear, or their extent squared underflows
 *         to 0); MAGCAL_ERR_ILL_CONDITIONED also when the extent squared is subnormal (rings below
 *         about 1e-20: float32 distances lose their precision);
 *         MAGCAL_ERR_ALL_NOISE (the density filter found no cluster);
 *         MAGCAL_ERR_COVERAGE (arc below cfg.min_coverage_deg; see report->missing_*);
 *         MAGCAL_ERR_INCONSISTENT (cfg.max_inconsistent_frac: the samples hold more than one
 *         installation); MAGCAL_ERR_TOO_MANY_OUTLIERS; MAGCAL_ERR_HYPERBOLA; MAGCAL_ERR_PARABOLA;
 *         MAGCAL_ERR_IMAGINARY; MAGCAL_ERR_ILL_CONDITIONED; MAGCAL_ERR_RADIUS_RANGE;
 *         MAGCAL_ERR_AXIS_RATIO; MAGCAL_ERR_RESIDUAL; MAGCAL_ERR_UNOBSERVABLE (the observability
 *         gate: clumped headings or a coarse lattice leave the calibration error above
 *         cfg.max_param_err_ratio x the noise); MAGCAL_ERR_NOT_BETTER (gates passed, adoption
 *         rule kept `current`); MAGCAL_ERR_ARG / MAGCAL_ERR_WORKSPACE from a stage (explicit eps or
 *         min_pts the stage rejects).
 */
magcal_status_t magcal_calibrator_run(magcal_calibrator_t *cal, magcal_cal2d_t *current,
                                      magcal_cal_report_t *report);

/**
 * @brief Per-sample verdict of the last run(): is sample i an inlier of the final fit?
 * @param[out] is_inlier 1 inlier, 0 outlier.
 * @return MAGCAL_OK; MAGCAL_ERR_NULL; MAGCAL_ERR_NOT_INITIALISED; MAGCAL_ERR_ARG (i beyond the
 *         samples judged by the last run); MAGCAL_ERR_STATE (no run() reached the final fit).
 */
magcal_status_t magcal_calibrator_inlier(const magcal_calibrator_t *cal, size_t i, int *is_inlier);

/**
 * @brief Flag bits of sample i (MAGCAL_CALIBRATOR_FLAG_*) from the last run().
 * @return as magcal_calibrator_inlier() (flags are available after any run that judged samples).
 */
magcal_status_t magcal_calibrator_flags(const magcal_calibrator_t *cal, size_t i, uint8_t *flags);

/**
 * @brief Judge any sample by its residual to the last final fit, with the same threshold.
 * @param[out] is_outlier 1 when |residual| > threshold.
 * @return MAGCAL_OK; MAGCAL_ERR_NULL; MAGCAL_ERR_NOT_INITIALISED; MAGCAL_ERR_NONFINITE;
 *         MAGCAL_ERR_STATE (no final fit yet).
 */
magcal_status_t magcal_calibrator_classify(const magcal_calibrator_t *cal, magcal_vec2_t p, int *is_outlier);

/** @brief Current state; MAGCAL_CALIBRATOR_INVALID for a NULL, uninitialised or corrupted cal. */
magcal_calibrator_state_t magcal_calibrator_state(const magcal_calibrator_t *cal);

/**
 * @brief Reason of the current state: the status of the last run() (MAGCAL_OK before any run or
 *        after an adoption; e.g. MAGCAL_ERR_COVERAGE in state FAILED). MAGCAL_ERR_NOT_INITIALISED
 *        for a NULL or uninitialised cal.
 */
magcal_status_t magcal_calibrator_last_status(const magcal_calibrator_t *cal);

/** @brief Number of stored samples (0 for NULL). */
size_t magcal_calibrator_count(const magcal_calibrator_t *cal);

/** @brief Live arc coverage of the stored samples around the provisional centre, degrees (0 for NULL). */
float magcal_calibrator_coverage_deg(const magcal_calibrator_t *cal);

#ifdef __cplusplus
}
#endif

#endif /* MAGCAL_CALIBRATOR_H */
