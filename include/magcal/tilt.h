/**
 * @file tilt.h
 * @brief Accelerometer tilt compensation: roll and pitch from gravity, the calibrated 3-axis
 *        field rotated into the level frame, and the tilt-compensated magnetic heading.
 *
 * Conventions (algorithms.md section 6):
 * - body frame x right, y forward, z up; attitude `C_b^ENU = R_z(-psi) R_x(theta) R_y(phi)`:
 *   heading psi about up (clockwise positive), then pitch theta about the right axis x (nose up
 *   positive), then roll phi about the forward axis y (right side down positive);
 * - the accelerometer measures specific force in g (it reads (0, 0, +1) when level and at rest):
 *   `theta = atan2(fy, sqrt(fx^2 + fz^2))`, `phi = atan2(-fx, fz)`;
 * - level field `m_L = R_x(theta) R_y(phi) m`, heading `psi = atan2(-Lx, Ly)` in degrees [0, 360)
 *   from magnetic north (add the declination for a true heading).
 *
 * The field passed in must already be calibrated in 3-D (hard and soft iron removed, e.g. by the
 * ellipsoid module): a 2-D calibration is only valid while the sensor turns level.
 * The module is stateless: every function is reentrant.
 */
#ifndef MAGCAL_TILT_H
#define MAGCAL_TILT_H

#include "magcal/heading.h"
#include "magcal/status.h"
#include "magcal/types.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Runtime gates of the tilt compensation (validated on every call). */
typedef struct {
    /** |f| below this (g) is free fall: no gravity reference. Range (0, 1). */
    float free_fall_g;
    /** | |f| - 1 g | above this (g) means the device is accelerating: attitude not trusted. > 0. */
    float accel_norm_tol_g;
    /** |pitch| above this (deg) makes heading ill-conditioned (gimbal). Range (0, 90). */
    float max_pitch_deg;
    /**
     * Smallest horizontal share of the field, sqrt(Lx^2 + Ly^2) / |m|, that still defines a
     * heading (0.02 rejects inclinations above about 88.9 deg and a zero field). Range [0, 1).
     */
    float min_horiz_ratio;
} magcal_tilt_cfg_t;

/** Defaults: free fall below 0.3 g, 0.08 g norm tolerance, pitch limit 80 deg, ratio 0.02. */
#define MAGCAL_TILT_CFG_DEFAULT {0.3f, 0.08f, 80.0f, 0.02f}

/** Roll and pitch in degrees (see the file comment for the rotation order and signs). */
typedef struct {
    float roll_deg;  /**< phi, rotation about the forward axis y, right side down positive, (-180, 180] */
    float pitch_deg; /**< theta, rotation about the right axis x, nose up positive, [-90, 90] */
} magcal_tilt_t;

/**
 * @brief Roll and pitch from one quasi-static accelerometer sample.
 * @param[in]  cfg      gates (MAGCAL_TILT_CFG_DEFAULT works without tuning).
 * @param[in]  accel_g  specific force in g, body frame x right, y forward, z up.
 * @param[out] att      roll and pitch in degrees; untouched on failure.
 * @return MAGCAL_OK; MAGCAL_ERR_NULL; MAGCAL_ERR_ARG (cfg value out of range);
 *         MAGCAL_ERR_NONFINITE (NaN/Inf component); MAGCAL_ERR_FREE_FALL (|f| < free_fall_g);
 *         MAGCAL_ERR_ACCEL_NORM (| |f| - 1 | > accel_norm_tol_g); MAGCAL_ERR_GIMBAL
 *         (|pitch| > max_pitch_deg).
 */
magcal_status_t magcal_tilt_attitude(const magcal_tilt_cfg_t *cfg, const magcal_vec3_t *accel_g,
                                     magcal_tilt_t *att);

/**
 * @brief Rotate a calibrated body-frame field into the level frame: m_L = R_x(theta) R_y(phi) m.
 * @param[in]  att    roll and pitch in degrees (from magcal_tilt_attitude or any other source).
 * @param[in]  mag    calibrated field, body frame, any unit.
 * @param[out] level  (Lx, Ly, Lz): x right and y forward of the level (heading) frame, z up;
 *                    same unit as mag; untouched on failure.
 * @return MAGCAL_OK; MAGCAL_ERR_NULL; MAGCAL_ERR_NONFINITE.
 */
magcal_status_t magcal_tilt_level_field(const magcal_tilt_t *att, const magcal_vec3_t *mag,
                                        magcal_vec3_t *level);

/**
 * @brief Tilt-compensated magnetic heading from one accelerometer and one calibrated field sample.
 * @param[in]  cfg          gates (MAGCAL_TILT_CFG_DEFAULT works without tuning).
 * @param[in]  accel_g      specific force in g, body frame.
 * @param[in]  mag          calibrated field, body frame, any unit.
 * @param[out] heading_deg  magnetic heading, degrees [0, 360); untouched on failure.
 * @param[out] att          optional (may be NULL): the roll and pitch used; untouched on failure.
 * @return MAGCAL_OK; MAGCAL_ERR_NULL; MAGCAL_ERR_ARG; MAGCAL_ERR_NONFINITE; MAGCAL_ERR_FREE_FALL;
 *         MAGCAL_ERR_ACCEL_NORM; MAGCAL_ERR_GIMBAL; MAGCAL_ERR_ZERO_FIELD (|m| = 0 or horizontal
 *         share below min_horiz_ratio).
 *
 * @code
 * magcal_tilt_cfg_t cfg = MAGCAL_TILT_CFG_DEFAULT;
 * magcal_vec3_t f = {0.0f, 0.0f, 1.0f};          // level, at rest (g)
 * magcal_vec3_t m = {-10.0f, 17.3f, -30.0f};     // calibrated field (uT)
 * float psi;
 * if (magcal_tilt_heading(&cfg, &f, &m, &psi, NULL) == MAGCAL_OK) {
 *     // psi = 30.03 deg
 * }
 * @endcode
 */
magcal_status_t magcal_tilt_heading(const magcal_tilt_cfg_t *cfg, const magcal_vec3_t *accel_g,
                                    const magcal_vec3_t *mag, float *heading_deg, magcal_tilt_t *att);

/**
 * @brief Tilt-compensated heading with its trust state: magnitude and inclination of the
 *        calibrated field judged against the 3-D calibration (heading.h, magcal_trust_judge()).
 *
 * `field_rel` = |mag| / field; the inclination (down positive) = atan2(-Lz, sqrt(Lx^2 + Ly^2)) of
 * the level field. With an expected inclination in `t` (magcal_trust_set_inclination()) a sample
 * whose inclination is off by more than the context's tolerance is DISTURBED as well: this
 * catches a disturbance that bends the field without changing its length.
 * @param[in]  cfg             tilt gates (MAGCAL_TILT_CFG_DEFAULT).
 * @param[in]  t               trust context of the 3-D calibration (built from residual_rms /
 *                             field), or NULL (generic band, no inclination check).
 * @param[in]  accel_g         specific force in g, body frame.
 * @param[in]  mag             calibrated field (magcal_ellipsoid_apply()), body frame.
 * @param[in]  field           the calibration's field magnitude F (magcal_ellipsoid_cal_t::field),
 *                             same unit as mag; 0 = uncalibrated (flag UNCALIBRATED, no judgement).
 * @param[in]  declination_deg east positive, [-180, 180].
 * @param[out] out             heading, trust, field_rel, inclination_deg; untouched on failure.
 * @return every status of magcal_tilt_heading(); MAGCAL_ERR_NULL (out); MAGCAL_ERR_ARG (field < 0,
 *         |declination| > 180); MAGCAL_ERR_NONFINITE (field, declination);
 *         MAGCAL_ERR_NOT_INITIALISED (t bad magic).
 */
magcal_status_t magcal_tilt_heading_get(const magcal_tilt_cfg_t *cfg, const magcal_trust_t *t,
                                        const magcal_vec3_t *accel_g, const magcal_vec3_t *mag,
                                        float field, float declination_deg, magcal_heading_t *out);

#ifdef __cplusplus
}
#endif

#endif /* MAGCAL_TILT_H */
