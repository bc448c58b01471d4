/**
 * @file heading.h
 * @brief 2-D hard/soft-iron correction of a level magnetometer and magnetic/true heading.
 *
 * A 2-D calibration maps a raw horizontal sample to a corrected field on a circle
 * (algorithms.md 2.4):
 *
 *     h = M * (raw - offset)        heading = atan2(-h.x, h.y), degrees in [0, 360)
 *
 * Conventions: body frame x right, y forward (z up); heading clockwise seen from above, from
 * magnetic north to the forward (y) axis; declination east positive, true = magnetic + declination.
 * Field units: any consistent unit (raw LSB, uT, ...); `M` maps them to the calibration's output
 * unit (see magcal_cal2d_t::radius). A heading depends only on ratios.
 *
 * The calibration struct is plain data (32 bytes, no pointers) so firmware can store it in flash
 * and restore it; magcal_cal2d_validate() checks a restored copy before use.
 *
 * Heading trust (docs/heading_models.md section 4): every magcal_heading_t carries a trust state
 * judged from the corrected field's magnitude against the calibration, with a tolerance of
 * k x the calibration's own residual held in a magcal_trust_t context (magcal_heading_get_trusted()),
 * or a generic 15 % band without one (magcal_heading_get()).
 *
 * @code
 * #include "magcal/heading.h"
 *
 * static magcal_cal2d_t cal = MAGCAL_CAL2D_IDENTITY;   // until a calibration exists
 *
 * void on_sample(magcal_vec2_t raw, float declination_deg)
 * {
 *     magcal_heading_t hd;
 *     if (magcal_heading_get(&cal, raw, declination_deg, &hd) == MAGCAL_OK &&
 *         hd.trust == MAGCAL_TRUST_OK) {
 *         // use hd.magnetic_deg / hd.true_deg, both in [0, 360)
 *     }
 *     // else hd.trust says why not: uncalibrated, disturbed or changed (magcal_trust_str())
 * }
 * @endcode
 */
#ifndef MAGCAL_HEADING_H
#define MAGCAL_HEADING_H

#include <stdint.h>

#include "magcal/config.h"
#include "magcal/status.h"
#include "magcal/types.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Magic and layout version of magcal_cal2d_t ("MC2" + version byte 0x01). */
#define MAGCAL_CAL2D_MAGIC 0x4D433201u

/* The zero-field gate MAGCAL_HEADING_ZERO_FIELD_FRAC is a build-time setting in magcal/config.h. */

/**
 * A 2-D calibration: h = m * (raw - offset). Plain struct, storable in flash as is.
 * Build it with magcal_ellipse_to_cal() (ellipse.h) or MAGCAL_CAL2D_IDENTITY.
 */
typedef struct {
    magcal_vec2_t offset; /**< hard-iron offset b, raw input units */
    float m[2][2];        /**< soft-iron correction M, row-major (m[row][col]); det > 0 */
    float radius;         /**< expected |h| after correction, output units; 0 = unknown */
    uint32_t magic;       /**< MAGCAL_CAL2D_MAGIC: layout version, checked on restore */
} magcal_cal2d_t;

/** Identity calibration (no offset, M = I, radius unknown): heading from raw axes. */
#define MAGCAL_CAL2D_IDENTITY                                                                      \
    {                                                                                              \
        {0.0f, 0.0f}, {{1.0f, 0.0f}, {0.0f, 1.0f}}, 0.0f, MAGCAL_CAL2D_MAGIC                       \
    }

/**
 * @brief Check a calibration (e.g. one restored from flash) before use.
 * @param[in] c calibration.
 * @return MAGCAL_OK;
 *         MAGCAL_ERR_NULL (c NULL);
 *         MAGCAL_ERR_NOT_INITIALISED (magic is not MAGCAL_CAL2D_MAGIC: blank, corrupted or other version);
 *         MAGCAL_ERR_NONFINITE (a field is NaN/Inf);
 *         MAGCAL_ERR_DEGENERATE (det M <= 0: singular, or mirrored axis = wiring/sign fault);
 *         MAGCAL_ERR_ARG (radius < 0).
 */
magcal_status_t magcal_cal2d_validate(const magcal_cal2d_t *c);

/**
 * @brief Apply a calibration: out = M * (raw - offset).
 * @param[in]  c   calibration (validated on every call).
 * @param[in]  raw raw horizontal sample, x right, y forward, raw units.
 * @param[out] out corrected field, output units; untouched on failure.
 * @return MAGCAL_OK; MAGCAL_ERR_NULL; MAGCAL_ERR_NONFINITE (raw or c non-finite); any status of
 *         magcal_cal2d_validate().
 */
magcal_status_t magcal_correct_apply(const magcal_cal2d_t *c, magcal_vec2_t raw,
                                     magcal_vec2_t *out);

/**
 * @brief Heading of a calibrated, level horizontal field: atan2(-h.x, h.y) in degrees.
 * @param[in]  h           calibrated field, x right, y forward (any unit).
 * @param[out] heading_deg magnetic heading in [0, 360) (360 is never returned, -0 is returned as
 *                         +0); untouched on failure.
 * @return MAGCAL_OK; MAGCAL_ERR_NULL; MAGCAL_ERR_NONFINITE;
 *         MAGCAL_ERR_ZERO_FIELD (h.x^2 + h.y^2 below FLT_MIN, i.e. |h| < 1.1e-19 in any unit:
 *         no direction can be resolved).
 */
magcal_status_t magcal_heading_from_field(magcal_vec2_t h, float *heading_deg);

/**
 * @brief Correct a raw sample and compute magnetic and true heading.
 * @param[in]  c               calibration.
 * @param[in]  raw             raw horizontal sample (x right, y forward), raw units; the sensor
 *                             must be level (use the tilt-compensated 3-D path otherwise).
 * @param[in]  declination_deg magnetic declination, east positive, in [-180, 180].
 * @param[out] magnetic_deg    magnetic heading in [0, 360); required.
 * @param[out] true_deg        true heading = wrap360(magnetic + declination) in [0, 360); may be
 *                             NULL. Outputs are untouched on failure.
 * @return MAGCAL_OK; MAGCAL_ERR_NULL (c or magnetic_deg NULL); MAGCAL_ERR_NONFINITE (raw or
 *         declination); MAGCAL_ERR_ARG (|declination| > 180); any status of
 *         magcal_cal2d_validate(); MAGCAL_ERR_ZERO_FIELD (as magcal_heading_from_field(), or,
 *         when c->radius > 0, |h| < MAGCAL_HEADING_ZERO_FIELD_FRAC * radius).
 * @note MAGCAL_OK says nothing about whether `c` was ever fitted: MAGCAL_CAL2D_IDENTITY (radius 0)
 *       gives the raw heading with MAGCAL_OK. Use magcal_heading_get(), which flags it.
 */
magcal_status_t magcal_heading_compute(const magcal_cal2d_t *c, magcal_vec2_t raw,
                                       float declination_deg, float *magnetic_deg, float *true_deg);

/** magcal_heading_t::flags: the calibration was never fitted (radius 0, e.g.
 *  MAGCAL_CAL2D_IDENTITY): the heading is the raw one, off by the whole hard and soft iron. */
#define MAGCAL_HEADING_FLAG_UNCALIBRATED 0x01u
/** magcal_heading_t::flags: the corrected field's magnitude (or, tilt-compensated, its
 *  inclination) is outside the trust tolerance: a disturbance (a passing truck, a bridge, a
 *  magnet) bends this sample's heading by an unknown amount. */
#define MAGCAL_HEADING_FLAG_DISTURBED 0x02u
/** magcal_heading_t::flags: the owner of the trust context (the calibrator's change detection)
 *  declared the calibration no longer valid for this installation; relearning is under way. */
#define MAGCAL_HEADING_FLAG_CHANGED 0x04u

/**
 * Trust state of one heading, from its flags (magcal_trust_from_flags()). Values are stable
 * (stored in logs and the replay CSV column `trust`). Precedence when several flags are set:
 * UNCALIBRATED, then CHANGED, then DISTURBED. Only MAGCAL_TRUST_OK may be used for navigation.
 */
typedef enum {
    MAGCAL_TRUST_OK = 0,           /**< fitted calibration, field consistent with it */
    MAGCAL_TRUST_UNCALIBRATED = 1, /**< no fitted calibration: raw heading */
    MAGCAL_TRUST_DISTURBED = 2,    /**< field magnitude / inclination off: transient disturbance */
    MAGCAL_TRUST_CHANGED = 3,      /**< installation changed (context marked): relearning */
    MAGCAL_TRUST_COARSE = 4,       /**< continuous calibrator only: field consistent with a coarse
                                        (hard-iron-only) calibration whose heading error is bounded
                                        by its adoption's est_param_err_deg, not by the full
                                        calibration's tolerance (continuous.h "Coarse calibration"),
                                        or with a full one whose error estimate is above
                                        cfg.ok_max_err_deg (continuous.h "OK tolerance"), or in
                                        the second after an install while the transient judge
                                        settles */
    MAGCAL_TRUST_TILTED = 5        /**< continuous calibrator only: with magcal_cont_push_g's
                                        gravity, the sample is tilted away from the tilt the
                                        calibration was fitted at by enough to move the heading by
                                        more than cfg.tilt_trust_deg (continuous.h "Tilt in the
                                        trust"); never given a gravity, raw z shows slopes that can
                                        (or has not yet been measured: continuous.h "Slopes
                                        without gravity") */
} magcal_trust_state_t;

/** One heading with the facts a consumer needs to trust it. */
typedef struct {
    float magnetic_deg;    /**< magnetic heading in [0, 360) */
    float true_deg;        /**< wrap360(magnetic + declination) in [0, 360) */
    float field_rel;       /**< |corrected field| / calibration radius (1 = as calibrated);
                                NaN when the calibration states no radius (uncalibrated);
                                +Inf when the ratio overflows float (then DISTURBED) */
    float inclination_deg; /**< tilt path: inclination of the field, down positive, degrees;
                                NaN on the 2-D path (not measured) */
    uint8_t flags;         /**< MAGCAL_HEADING_FLAG_* bits; 0 = trusted */
    uint8_t trust;         /**< magcal_trust_state_t, = magcal_trust_from_flags(flags) */
} magcal_heading_t;

/**
 * Trust thresholds (docs/heading_models.md, "Heading trust"). A sample is DISTURBED when
 *
 *     | |h| / R - 1 | > tol_rel,   tol_rel = max(k * residual_rel, floor_rel)
 *
 * with R the calibration's radius (or ellipsoid field F) and residual_rel the calibration's own
 * RMS radial residual over R (magcal_cal_report_t::residual_rel, or ellipsoid residual_rms / F).
 * The residual estimates the radial noise sigma of clean samples, so k = 3 flags about 0.3 % of
 * clean Gaussian samples (two-sided 3 sigma) and every +30 % disturbance while residual_rel < 0.1
 * (the calibrator's default max_residual_rel gate). Tilt-compensated, a sample is also DISTURBED
 * when its inclination differs from the expected one by more than
 * max(k * residual_rel in radians, incl_floor_deg): the floor covers the attitude error of an
 * accelerometer-only tilt (0.08 g of vehicle acceleration tilts the gravity estimate by 4.6 deg).
 */
typedef struct {
    float k;              /**< tolerance in residual multiples, > 0 (default 3) */
    float floor_rel;      /**< smallest field tolerance, fraction of R, [0, 1) (default 0.01):
                               a near-perfect fit must not flag ordinary sensor noise */
    float incl_floor_deg; /**< smallest inclination tolerance, degrees, [0, 90] (default 5) */
} magcal_trust_cfg_t;

/** Defaults: k = 3, field floor 1 % of R, inclination floor 5 degrees. */
#define MAGCAL_TRUST_CFG_DEFAULT {3.0f, 0.01f, 5.0f}

/** Field tolerance (fraction of R) used when no trust context is given (magcal_heading_get()):
 *  the calibration's residual is unknown, so a generic band that still catches +30 %. */
#define MAGCAL_TRUST_TOL_REL_NO_CONTEXT 0.15f

/** Magic of an initialised magcal_trust_t. */
#define MAGCAL_TRUST_MAGIC 0x4D435452u

/**
 * Trust context of one calibration, owned by whoever installs the calibration (the application,
 * or the calibrator whose change detection marks it CHANGED). Plain data; fields PRIVATE.
 * Re-initialise it whenever a new calibration is installed (its residual is different).
 */
typedef struct {
    float tol_rel;      /* field tolerance, fraction of R */
    float incl_tol_deg; /* inclination tolerance, degrees */
    float incl_deg;     /* expected inclination, degrees, down positive; NaN = not set */
    uint8_t changed;    /* 1: every heading reads CHANGED */
    uint32_t magic;     /* MAGCAL_TRUST_MAGIC */
} magcal_trust_t;

/**
 * @brief Initialise a trust context from the calibration's own residual.
 * @param[out] t            context; untouched on failure.
 * @param[in]  cfg          thresholds (MAGCAL_TRUST_CFG_DEFAULT works untuned).
 * @param[in]  residual_rel RMS radial residual of the calibration's fit / its radius, >= 0
 *                          (magcal_cal_report_t::residual_rel; ellipsoid residual_rms / field).
 *                          Store it beside a calibration saved to flash.
 * @return MAGCAL_OK; MAGCAL_ERR_NULL; MAGCAL_ERR_NONFINITE (residual_rel or a cfg value, or k x residual_rel
 *         overflows a float);
 *         MAGCAL_ERR_ARG (k <= 0, floor_rel outside [0, 1), incl_floor_deg outside [0, 90],
 *         residual_rel < 0).
 */
magcal_status_t magcal_trust_init(magcal_trust_t *t, const magcal_trust_cfg_t *cfg,
                                  float residual_rel);

/**
 * @brief Set the expected inclination for the tilt-compensated check (e.g. from magcal_geomag,
 *        or the median inclination the 3-D calibration saw).
 * @param[in,out] t        initialised context.
 * @param[in]     incl_deg inclination, down positive, in [-90, 90].
 * @return MAGCAL_OK; MAGCAL_ERR_NULL; MAGCAL_ERR_NOT_INITIALISED; MAGCAL_ERR_NONFINITE;
 *         MAGCAL_ERR_ARG (outside [-90, 90]).
 */
magcal_status_t magcal_trust_set_inclination(magcal_trust_t *t, float incl_deg);

/**
 * @brief Mark (changed = 1) or clear (0) a change of the installation: while marked, every
 *        heading judged with this context reads MAGCAL_TRUST_CHANGED. The calibrator's change
 *        detection calls it; an application may too (e.g. after fitting a new accessory).
 * @return MAGCAL_OK; MAGCAL_ERR_NULL; MAGCAL_ERR_NOT_INITIALISED; MAGCAL_ERR_ARG (changed > 1).
 */
magcal_status_t magcal_trust_set_changed(magcal_trust_t *t, uint8_t changed);

/**
 * @brief Judge one sample's field against the context: the DISTURBED and CHANGED flag bits.
 * @param[in]  t         initialised context, or NULL (tolerance MAGCAL_TRUST_TOL_REL_NO_CONTEXT,
 *                       no inclination check, never CHANGED).
 * @param[in]  field_rel |corrected field| / R, finite, >= 0.
 * @param[in]  incl_deg  measured inclination (degrees, down positive), or NaN when not measured.
 * @param[out] flags     MAGCAL_HEADING_FLAG_DISTURBED / _CHANGED bits (others 0); untouched on
 *                       failure.
 * @return MAGCAL_OK; MAGCAL_ERR_NULL (flags); MAGCAL_ERR_NOT_INITIALISED (t given, bad magic);
 *         MAGCAL_ERR_NONFINITE (field_rel, or incl_deg infinite); MAGCAL_ERR_ARG (field_rel < 0).
 */
magcal_status_t magcal_trust_judge(const magcal_trust_t *t, float field_rel, float incl_deg,
                                   uint8_t *flags);

/** @brief Trust state of a set of MAGCAL_HEADING_FLAG_* bits (precedence: see the enum). */
magcal_trust_state_t magcal_trust_from_flags(uint8_t flags);

/** @brief Short constant name of a trust state: "ok", "uncalibrated", "disturbed", "changed";
 *         "unknown" for other values (the replay CSV column `trust`). */
const char *magcal_trust_str(magcal_trust_state_t s);

/**
 * @brief As magcal_heading_compute(), into one result that also says whether it can be trusted,
 *        with the generic tolerance (no trust context: see magcal_heading_get_trusted()).
 *
 * A calibration with radius 0 (MAGCAL_CAL2D_IDENTITY, or a hand-made one that does not state its
 * field radius) gives a heading, but flags it MAGCAL_HEADING_FLAG_UNCALIBRATED: on a vehicle the
 * raw heading can be off by up to 180 degrees. Every calibration from magcal_ellipse_to_cal() or
 * magcal_calibrator_run() has radius > 0; its headings are flagged DISTURBED when
 * | |h| / radius - 1 | > MAGCAL_TRUST_TOL_REL_NO_CONTEXT.
 * @param[in]  c               calibration.
 * @param[in]  raw             raw level horizontal sample (x right, y forward), raw units.
 * @param[in]  declination_deg magnetic declination, east positive, in [-180, 180].
 * @param[out] out             result; untouched on failure.
 * @return every status of magcal_heading_compute() (MAGCAL_ERR_NULL also for out NULL).
 */
magcal_status_t magcal_heading_get(const magcal_cal2d_t *c, magcal_vec2_t raw, float declination_deg,
                                   magcal_heading_t *out);

/**
 * @brief As magcal_heading_get(), judged against a trust context built from the calibration's
 *        residual (tighter than the generic band, and CHANGED when the context is marked).
 * @param[in]  c   calibration.
 * @param[in]  t   trust context of `c` (magcal_trust_init()), or NULL (= magcal_heading_get()).
 * @param[in]  raw raw level horizontal sample, raw units.
 * @param[in]  declination_deg east positive, [-180, 180].
 * @param[out] out result; untouched on failure.
 * @return every status of magcal_heading_get(); MAGCAL_ERR_NOT_INITIALISED (t bad magic).
 *
 * @code
 * magcal_trust_cfg_t tc = MAGCAL_TRUST_CFG_DEFAULT;
 * magcal_trust_t trust;
 * magcal_trust_init(&trust, &tc, report.residual_rel);   // with the calibration it describes
 * ...
 * magcal_heading_t hd;
 * if (magcal_heading_get_trusted(&cal, &trust, raw, decl, &hd) == MAGCAL_OK &&
 *     hd.trust == MAGCAL_TRUST_OK) {
 *     // navigate on hd.true_deg
 * }
 * @endcode
 */
magcal_status_t magcal_heading_get_trusted(const magcal_cal2d_t *c, const magcal_trust_t *t,
                                           magcal_vec2_t raw, float declination_deg,
                                           magcal_heading_t *out);

#ifdef __cplusplus
}
#endif

#endif /* MAGCAL_HEADING_H */
