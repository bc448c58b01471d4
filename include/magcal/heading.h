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
 * @code
 * #include "magcal/heading.h"
 *
 * static magcal_cal2d_t cal = MAGCAL_CAL2D_IDENTITY;   // until a calibration exists
 *
 * void on_sample(magcal_vec2_t raw, float declination_deg)
 * {
 *     magcal_heading_t hd;
 *     if (magcal_heading_get(&cal, raw, declination_deg, &hd) == MAGCAL_OK &&
 *         (hd.flags & MAGCAL_HEADING_FLAG_UNCALIBRATED) == 0u) {
 *         // use hd.magnetic_deg / hd.true_deg, both in [0, 360)
 *     }
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

/** One heading with the facts a consumer needs to trust it. */
typedef struct {
    float magnetic_deg; /**< magnetic heading in [0, 360) */
    float true_deg;     /**< wrap360(magnetic + declination) in [0, 360) */
    uint8_t flags;      /**< MAGCAL_HEADING_FLAG_* bits; 0 = from a fitted calibration */
} magcal_heading_t;

/**
 * @brief As magcal_heading_compute(), into one result that also says whether the calibration was
 *        ever fitted.
 *
 * A calibration with radius 0 (MAGCAL_CAL2D_IDENTITY, or a hand-made one that does not state its
 * field radius) gives a heading, but flags it MAGCAL_HEADING_FLAG_UNCALIBRATED: on a vehicle the
 * raw heading can be off by up to 180 degrees. Every calibration from magcal_ellipse_to_cal() or
 * magcal_calibrator_run() has radius > 0 and flags 0.
 * @param[in]  c               calibration.
 * @param[in]  raw             raw level horizontal sample (x right, y forward), raw units.
 * @param[in]  declination_deg magnetic declination, east positive, in [-180, 180].
 * @param[out] out             result; untouched on failure.
 * @return every status of magcal_heading_compute() (MAGCAL_ERR_NULL also for out NULL).
 */
magcal_status_t magcal_heading_get(const magcal_cal2d_t *c, magcal_vec2_t raw, float declination_deg,
                                   magcal_heading_t *out);

#ifdef __cplusplus
}
#endif

#endif /* MAGCAL_HEADING_H */
