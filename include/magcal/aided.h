/**
 * @file aided.h
 * @brief Online 3-D magnetometer calibration aided by an INS/GNSS attitude and a reference field.
 *
 * Model (algorithms.md 7.1, 7.3-7.6): `m = W h + V + noise`, `h = C_n^b B_ref`, estimated online from
 * the combined objective of algorithms.md 7.3,
 *   J = sum_i [ |C_b^n G (m_i - V) - B_ref,i|^2 / sigma_v^2 + (|G (m_i - V)| - |B_ref,i|)^2 / sigma_F^2 ],
 * by a recursive Gauss-Newton in information form. Unknowns: the 12 entries of theta (4x3) =
 * [G^T; c~^T], c~ = G (V0 - V)/s, i.e. `h/s = theta^T phi` with the regressor phi = [(m - V0)/s; 1].
 * - vector residual (linear in theta, body axes): three least-squares problems sharing phi, so its
 *   information is Lambda (x) I3 with the 4x4 Lambda = sum phi phi^T (algorithms.md 7.4);
 * - total-field residual: linearised at the estimate in force when the epoch arrives (EKF form,
 *   algorithms.md 7.6): with n = h/|h|, J_F = n (x) phi and the linearised measurement is
 *   n^T theta^T phi = |B_ref|/s, so each epoch adds (n n^T) (x) (phi phi^T) (78 packed floats) and
 *   |B_ref|/s (n (x) phi). It enters once an estimate predicts the field at every heading (the
 *   switch of the calibrated gates below); before that only the vector residual is used.
 * Weights: both residuals carry the same magnetometer noise (the total-field residual is, to first
 * order, the along-field component of the vector residual), so the total-field term is weighted
 * w_F = 1/sigma_F^2 - 1/sigma_v^2 >= 0 (sigma_F = cfg.sigma_f_rel F, sigma_v = cfg.sigma_rel F): the
 * along-field information is then 1/sigma_F^2 and the cross-field one 1/sigma_v^2. With
 * sigma_f_rel >= sigma_rel the estimate equals the vector-only one (MAGCAL_AIDED_OBJ_VECTOR).
 * The information matrices are packed lower triangles (symmetric by construction in float32) with
 * Kahan-compensated sums and optional forgetting. Each solve eigen-decomposes Lambda/N (4x4 Jacobi),
 * freezes the poorly excited directions at the prior (below) and solves the remaining <= 12 x 12
 * system by LDL^T. Memory is fixed (the instance struct) and the work per epoch bounded.
 *
 * Frames and attitude (the standard aerospace ZYX Euler angles of an INS, see algorithms.md 6, 7.1):
 * - body: x right, y forward, z up; the raw field m in body axes;
 * - B_ref: NED components (x north, y east, z down), e.g. WMM at the GNSS position, in the SAME unit
 *   as the output you want (uT or nT); m is expected in that unit too unless `cfg.prior` scales it;
 * - yaw psi: heading of the forward axis, clockwise from (true) north; pitch theta: nose up positive,
 *   rotation about the right axis; roll phi: right side down positive, rotation about the forward axis;
 *   `C_b^ENU = R_z(-psi) R_x(theta) R_y(phi)`, `C_b^NED = P C_b^ENU`, P = [[0,1,0],[1,0,0],[0,0,-1]].
 *   These are numerically the INS's FRD/NED yaw, pitch, roll (C_FRD^NED = R_z(psi) R_y(theta) R_x(phi)).
 *   The attitude, yaw in particular, must NOT come from this magnetometer.
 *
 * Gates (algorithms.md 7.8), checked in this order, each counted: DOP > max_dop; |m - V0| > 1e4 |B_ref|
 * in any axis (RAW: a saturated or corrupted reading, outside the range of the sums); until an
 * estimate predicts every heading (>= min_epochs accepted, at most one direction frozen) the raw
 * magnitude gate through the prior, `| |G0(m - V0)| - |B_ref| | > gate_raw_rel*|B_ref|` (loose: V is
 * unknown); afterwards `| |G(m - V)| - |B_ref| | > gate_field_rel*|B_ref|` and
 * `|C_b^n G(m - V) - B_ref| > gate_vector_rel*|B_ref|`.
 *
 * Observability (algorithms.md 7.7): exactly level yaw-only motion leaves three parameters (the z
 * scale and cross terms against the z offset) unobservable by either residual (both Jacobians lie
 * in span{phi}, so they share the null direction of Lambda). The module eigen-decomposes the
 * per-epoch information matrix of the normalised regressor [(m - V0)/|B|; 1]; a direction whose
 * eigenvalue mu_k is below `min_eig` (sensor noise alone also excites it, so this test does not
 * improve with N) or whose predicted parameter standard deviation `sigma / sqrt(N_eff * mu_k)`
 * exceeds `max_weak_std` is frozen at the prior (cfg.prior, e.g. the factory calibration), for
 * all three body axes and in both residuals, and reported (MAGCAL_ERR_UNOBSERVABLE, MAGCAL_AIDED_FLAG_PRIOR_USED).
 *
 * The result is a magcal_ellipsoid_cal_t: `h = G (m - V)` in body axes, then tilt compensation
 * (algorithms.md 6) gives the heading. G includes the magnetometer-to-INS misalignment.
 */
#ifndef MAGCAL_AIDED_H
#define MAGCAL_AIDED_H

#include <stddef.h>
#include <stdint.h>

#include "magcal/config.h"
#include "magcal/ellipsoid.h"
#include "magcal/status.h"
#include "magcal/types.h"

#ifdef __cplusplus
extern "C" {
#endif

/** One epoch of input. */
typedef struct {
    magcal_vec3_t m;         /**< raw field, body axes (x right, y forward, z up) */
    float roll_rad;          /**< phi: right side down positive, about the forward axis, radians */
    float pitch_rad;         /**< theta: nose up positive, about the right axis, radians, |theta| < pi/2 */
    float yaw_rad;           /**< psi: clockwise from north, radians (any range) */
    magcal_vec3_t b_ref_ned; /**< reference field: x north, y east, z down (same unit as the output) */
    float dop;               /**< GNSS dilution of precision (PDOP or HDOP), >= 0 */
} magcal_aided_epoch_t;

/** Why an epoch was rejected (index into magcal_aided_result_t::gated). */
typedef enum {
    MAGCAL_AIDED_GATE_NONE = 0,   /**< accepted */
    MAGCAL_AIDED_GATE_DOP = 1,    /**< dop > max_dop */
    MAGCAL_AIDED_GATE_RAW = 2,    /**< raw magnitude gate through the prior (no fully observed estimate yet) */
    MAGCAL_AIDED_GATE_FIELD = 3,  /**< calibrated magnitude gate */
    MAGCAL_AIDED_GATE_VECTOR = 4, /**< calibrated vector (direction) gate */
    MAGCAL_AIDED_GATE_COUNT = 5
} magcal_aided_gate_t;

/** Objective minimised by the estimator (algorithms.md 7.3). */
typedef enum {
    MAGCAL_AIDED_OBJ_COMBINED = 0, /**< vector + total-field residual (default) */
    MAGCAL_AIDED_OBJ_VECTOR = 1    /**< vector residual only: the linear solution of algorithms.md 7.4 */
} magcal_aided_objective_t;

/** Result flags. */
#define MAGCAL_AIDED_FLAG_ESTIMATE 0x01u   /**< an estimate exists (>= min_epochs accepted) */
#define MAGCAL_AIDED_FLAG_CONVERGED 0x02u  /**< parameter change below thresholds over a window */
#define MAGCAL_AIDED_FLAG_PRIOR_USED 0x04u /**< at least one direction frozen at the prior */

/** Configuration. Start from MAGCAL_AIDED_CFG_DEFAULT. */
typedef struct {
    float lambda;          /**< forgetting factor in [0.9, 1]; 1 = growing-memory least squares (default 1) */
    float max_dop;         /**< DOP gate (default 3) */
    float gate_raw_rel;    /**< raw gate, fraction of |B_ref| (default 1.0: a sanity check only, V may be as large as F) */
    float gate_field_rel;  /**< calibrated magnitude gate, fraction of F (default 0.05) */
    float gate_vector_rel; /**< calibrated vector gate, fraction of F (default 0.15) */
    float sigma_rel;       /**< assumed vector residual std / F: noise + attitude error x F (default 0.005) */
    float sigma_f_rel;     /**< assumed total-field residual std / F: magnetometer noise + reference-model
                                error, no attitude error (default 0.002); only sigma_rel/sigma_f_rel
                                matters for the estimate */
    magcal_aided_objective_t objective; /**< MAGCAL_AIDED_OBJ_COMBINED (default) or _VECTOR */
    float max_weak_std;    /**< largest predicted std of a parameter direction (G units) (default 0.03) */
    float min_eig;         /**< smallest usable eigenvalue of the per-epoch information matrix of [m/|B|; 1]
                                (default 2e-5: about 0.6 deg RMS tilt at 66 deg inclination, 20x the
                                level-driving value of a 0.05 uT-noise sensor at 50 uT) */
    float noise_rel;       /**< magnetometer white noise std per axis / |B| (e.g. 0.05 uT / 48 uT = 0.001);
                                removes the errors-in-variables shrinkage of weakly excited directions
                                (bias-compensated least squares); 0 = off (default 0) */
    uint32_t min_epochs;   /**< accepted epochs before an estimate exists (>= 8, default 50) */
    uint32_t conv_window;  /**< accepted epochs per convergence window (>= 1, default 50) */
    float conv_dg;         /**< converged: max |dG_ij| over a window below this (default 2e-3) */
    float conv_dv_rel;     /**< converged: |dV| / F over a window below this (default 2e-3) */
    magcal_ellipsoid_cal_t prior; /**< prior / factory calibration (G0, V0; field unused); V0 also centres the data */
    uint32_t still_epochs; /**< stationarity: after this many consecutive accepted epochs whose regressor
                                stays within still_field_rel of the first one, further epochs add no
                                information (counted in n_still, no forgetting, estimate unchanged)
                                until the field leaves that ball; 0 = off (default 50: 1 s at 50 Hz) */
    float still_field_rel; /**< radius of the stationarity ball, max-axis |m - m_anchor| / |B_ref| (> 0,
                                default 0.01: 0.5 uT at 48 uT, about 1.4 deg of yaw at 65 deg inclination,
                                10x the noise of a 0.05 uT sensor); the radius used is
                                max(still_field_rel, 8 noise_rel), so set noise_rel for a noisy sensor */
} magcal_aided_cfg_t;

/** Defaults that work without tuning (prior: G0 = I, V0 = 0: raw data already in the B_ref unit). */
#define MAGCAL_AIDED_CFG_DEFAULT                                                                    \
    {                                                                                               \
        1.0f, 3.0f, 1.0f, 0.05f, 0.15f, 0.005f, 0.002f, MAGCAL_AIDED_OBJ_COMBINED, 0.03f, 2e-5f, 0.0f,  \
            50u, 50u, 2e-3f, 2e-3f,                                                                 \
        {{{1.0f, 0.0f, 0.0f}, {0.0f, 1.0f, 0.0f}, {0.0f, 0.0f, 1.0f}}, {0.0f, 0.0f, 0.0f}, 0.0f},   \
            50u, 0.01f                                                                               \
    }

/** Floats of the solve's scratch inside magcal_aided_t (private; no state between epochs): the
 *  reduced <= 12x12 combined-objective system and its right-hand side, and the eigenvectors of the
 *  4x4 information matrix (whose working copy shares the system's storage). Kept in the instance
 *  so that magcal_aided_update needs <= 512 B of stack (issue 14), not on the caller's stack. */
#define MAGCAL_AIDED_SCRATCH_LEN (12u * 12u + 12u + 4u * 4u)

/** Instance. Allocate statically; all fields are private (read them through magcal_aided_get). */
typedef struct {
    magcal_aided_cfg_t cfg;  /**< private: copy of the configuration */
    uint32_t magic;          /**< private: initialisation marker */
    float scale;             /**< private: normalisation s (|B_ref| of the first accepted epoch) */
    float info[10];          /**< private: information matrix, packed lower triangle of 4x4 */
    float info_c[10];        /**< private: Kahan compensation of info */
    float cross[12];         /**< private: sum phi y^T, 4x3 */
    float cross_c[12];       /**< private: Kahan compensation of cross */
    float yy;                /**< private: sum |y|^2 */
    float yy_c;              /**< private: compensation of yy */
    float f_sum;             /**< private: sum |B_ref| / s (for F) */
    float hf[78];            /**< private: total-field information sum (n n^T) (x) (phi phi^T), packed 12x12 */
    float hf_c[78];          /**< private: Kahan compensation of hf */
    float bf[12];            /**< private: sum |B_ref|/s (n (x) phi) */
    float bf_c[12];          /**< private: Kahan compensation of bf */
    float nn[6];             /**< private: sum n n^T, packed 3x3 (noise compensation of hf) */
    uint32_t n_tf;           /**< private: accepted epochs that entered hf */
    float rf_win;            /**< private: sum of squared total-field residuals in the current window */
    uint32_t rf_win_n;       /**< private: epochs in rf_win */
    float resid_f_rms;       /**< private: RMS total-field residual of the last complete window */
    float theta[12];         /**< private: current solution, 4x3 (normalised) */
    float snap[12];          /**< private: solution at the start of the convergence window */
    magcal_ellipsoid_cal_t cal; /**< private: current calibration */
    float min_eig;           /**< private: smallest eigenvalue of the per-epoch information matrix */
    float weak_std;          /**< private: predicted std along the weakest direction */
    float weak_dir[4];       /**< private: weakest direction (normalised [m; 1] space) */
    float resid_rms;         /**< private: RMS vector residual of the fit, output units */
    uint32_t n_accepted;     /**< private */
    uint32_t n_seen;         /**< private */
    uint32_t gated[MAGCAL_AIDED_GATE_COUNT]; /**< private: counts per gate reason */
    uint32_t win_count;      /**< private: epochs in the current convergence window */
    uint32_t converged_at;   /**< private: accepted-epoch count at first convergence, 0 = never */
    uint32_t n_prior_dirs;   /**< private: directions frozen at the prior */
    uint32_t flags;          /**< private: MAGCAL_AIDED_FLAG_* */
    float still_phi[3];      /**< private: regressor of the first epoch of the current stationary run */
    uint32_t still_run;      /**< private: accepted epochs in the current stationary run */
    uint32_t n_still;        /**< private: epochs passed the gates but held back as stationary */
    float scratch[MAGCAL_AIDED_SCRATCH_LEN]; /**< private: solve scratch (MAGCAL_AIDED_SCRATCH_LEN) */
} magcal_aided_t;

/** Snapshot of the estimate. */
typedef struct {
    magcal_ellipsoid_cal_t cal;  /**< G, V, F (F = mean |B_ref| of the accepted epochs) */
    uint32_t flags;              /**< MAGCAL_AIDED_FLAG_* */
    uint32_t n_accepted;         /**< epochs used */
    uint32_t n_seen;             /**< epochs offered */
    uint32_t gated[MAGCAL_AIDED_GATE_COUNT]; /**< rejected epochs per reason (index 0 unused) */
    uint32_t converged_at;       /**< accepted-epoch count at first convergence, 0 = not yet */
    uint32_t n_prior_dirs;       /**< parameter directions (of 4) frozen at the prior */
    float min_eig;               /**< smallest eigenvalue of the normalised per-epoch information matrix */
    float weak_std;              /**< predicted std of the weakest parameter direction (G units) */
    float resid_rms;             /**< RMS of the vector residual C G (m - V) - B_ref, output units */
    float resid_f_rms;           /**< RMS of |G (m - V)| - |B_ref| over the last complete convergence window,
                                      each epoch with the estimate in force when it arrived (a-priori,
                                      innovation RMS), output units; 0 until a window is complete */
    uint32_t n_total_field;      /**< accepted epochs whose total-field residual entered the objective */
    uint32_t n_still;            /**< epochs that passed the gates but added nothing: stationary (cfg.still_epochs) */
} magcal_aided_result_t;

#if MAGCAL_CFG_ENABLE_AIDED
/**
 * @brief Initialise an instance (validates and copies the configuration).
 * @param[out] inst instance.
 * @param[in]  cfg  configuration (MAGCAL_AIDED_CFG_DEFAULT).
 * magcal_aided_init() is a macro passing the caller's MAGCAL_CONFIG_FINGERPRINT and
 * sizeof(magcal_aided_t) to magcal_aided_init_checked() (config.h).
 * @return MAGCAL_OK, MAGCAL_ERR_CONFIG_MISMATCH (caller compiled with other config.h limits or
 *         another magcal_aided_t layout: nothing written), MAGCAL_ERR_NULL, MAGCAL_ERR_ARG (a value
 *         out of its documented range, or a singular prior G0), MAGCAL_ERR_NONFINITE (non-finite prior).
 */
magcal_status_t magcal_aided_init_checked(magcal_aided_t *inst, const magcal_aided_cfg_t *cfg,
                                          uint32_t config, size_t inst_size);
#define magcal_aided_init(inst, cfg)                                                               \
    magcal_aided_init_checked((inst), (cfg), MAGCAL_CONFIG_FINGERPRINT, sizeof(magcal_aided_t))

/**
 * @brief Offer one epoch: gate it, and if accepted update the estimate (bounded work).
 * @param[in,out] inst   initialised instance.
 * @param[in]     ep     epoch.
 * @param[out]    reason optional (may be NULL): gate that rejected the epoch, or MAGCAL_AIDED_GATE_NONE.
 * Stationarity (docs/calibration_3d.md, "Parking"): a parked vehicle (or one on a long straight) repeats
 * one regressor; summing it for hours would dilute the per-epoch excitation of every other direction
 * until the observability test freezes them at the prior, and with lambda < 1 forget them. Once
 * cfg.still_epochs consecutive accepted epochs stay within cfg.still_field_rel of the first, further
 * epochs of that run return MAGCAL_OK but are only counted (n_still): no sums, no forgetting, no
 * solve; the first epoch outside the ball starts a new run and is used.
 * @return MAGCAL_OK (accepted, or held back as stationary), MAGCAL_ERR_GATED (rejected by a gate; counted, state unchanged otherwise),
 *         MAGCAL_ERR_NULL, MAGCAL_ERR_NOT_INITIALISED, MAGCAL_ERR_NONFINITE (a non-finite input),
 *         MAGCAL_ERR_ARG (dop < 0, |pitch| >= pi/2, |B_ref| not representable in float32 or more than
 *         16x away from the first accepted epoch's |B_ref|: a unit mix-up), MAGCAL_ERR_ZERO_FIELD
 *         (|B_ref| == 0). Rejected epochs (every status but MAGCAL_OK) leave the estimate unchanged.
 */
magcal_status_t magcal_aided_update(magcal_aided_t *inst, const magcal_aided_epoch_t *ep, magcal_aided_gate_t *reason);

/**
 * @brief Read the current estimate.
 * @param[in]  inst initialised instance.
 * @param[out] out  result. Written on MAGCAL_OK, MAGCAL_ERR_UNOBSERVABLE and MAGCAL_ERR_NOT_CONVERGED.
 * @return MAGCAL_OK (converged, every direction observed);
 *         MAGCAL_ERR_UNOBSERVABLE (estimate written, but some directions come from the prior: excitation
 *         too poor, e.g. level yaw-only driving; headings at tilt are only as good as the prior);
 *         MAGCAL_ERR_NOT_CONVERGED (estimate written, observable, not yet converged);
 *         MAGCAL_ERR_TOO_FEW_POINTS (fewer than min_epochs accepted; out untouched);
 *         MAGCAL_ERR_NULL, MAGCAL_ERR_NOT_INITIALISED.
 *
 * @code
 * static magcal_aided_t cal3d;                   // about 2 KiB, sizeof(magcal_aided_t)
 * const magcal_aided_cfg_t cfg = MAGCAL_AIDED_CFG_DEFAULT;
 * magcal_aided_epoch_t ep;                       // filled from the INS, GNSS and WMM every epoch
 * magcal_aided_result_t res;
 * (void)magcal_aided_init(&cal3d, &cfg);
 * // per epoch:
 * (void)magcal_aided_update(&cal3d, &ep, NULL);
 * if (magcal_aided_get(&cal3d, &res) == MAGCAL_OK) {
 *     // h = G (m - V): magcal_ellipsoid_apply(&res.cal, &m, &h), then tilt-compensate
 * }
 * @endcode
 */
magcal_status_t magcal_aided_get(const magcal_aided_t *inst, magcal_aided_result_t *out);

/**
 * @brief Direction cosine matrix C_b^NED (body x right, y forward, z up) from INS Euler angles.
 * @param[in]  roll_rad  phi (right side down positive), radians.
 * @param[in]  pitch_rad theta (nose up positive), radians.
 * @param[in]  yaw_rad   psi (clockwise from north), radians.
 * @param[out] c         row-major 3x3: v_NED = C v_body.
 * @return MAGCAL_OK, MAGCAL_ERR_NULL, MAGCAL_ERR_NONFINITE.
 */
magcal_status_t magcal_aided_dcm(float roll_rad, float pitch_rad, float yaw_rad, float c[3][3]);
#endif /* MAGCAL_CFG_ENABLE_AIDED */

#ifdef __cplusplus
}
#endif

#endif /* MAGCAL_AIDED_H */
