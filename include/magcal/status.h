/**
 * @file status.h
 * @brief Status codes shared by every magcal module.
 *
 * `MAGCAL_OK` is 0; every other result is a specific negative code whose value is stable across
 * releases (firmware may log or store it). Fallible functions return a status and write their
 * results through out-pointers; on failure they leave caller-owned results untouched unless the
 * function's documentation says otherwise.
 *
 * Convention for normal outcomes. Every non-OK code means "the result you asked for was not
 * produced", but a few of them are expected outcomes of a working system, not faults of the
 * caller, the data or the hardware; they keep the MAGCAL_ERR_ prefix (the values are stable and
 * shared with released firmware) and magcal_status_is_outcome() tells them apart:
 *  - MAGCAL_ERR_NOT_BETTER: the new calibration passed every gate and the adoption rule kept the
 *    caller's (better or equally good) one: nothing to do, nothing to log as an error;
 *  - MAGCAL_ERR_GATED: a sample or epoch adds no information (or is rejected by a documented gate):
 *    not stored, keep feeding;
 *  - MAGCAL_ERR_NO_DATA: the (replayed) data source is exhausted;
 *  - MAGCAL_ERR_NOT_CONVERGED: an estimate is still converging (aided): ask again later.
 * MAGCAL_IN_PROGRESS (+1, the only positive code) is returned only by the *_step() functions of
 * time-sliced work: the budget of this call is spent, the work is not finished, call again.
 * Every other negative code is a fault or a refusal the firmware should log and act on.
 */
#ifndef MAGCAL_STATUS_H
#define MAGCAL_STATUS_H

#ifdef __cplusplus
extern "C" {
#endif

/** Result of a magcal call. Values are stable: append new codes, never renumber. */
typedef enum {
    MAGCAL_IN_PROGRESS = 1,           /**< a time-sliced call did its budget of work: call its step again (not an error) */
    MAGCAL_OK = 0,                    /**< success */
    MAGCAL_ERR_NULL = -1,             /**< a required pointer argument is NULL */
    MAGCAL_ERR_ARG = -2,              /**< an argument or config value is out of its documented range */
    MAGCAL_ERR_WORKSPACE = -3,        /**< caller workspace/buffer smaller than the size macro requires */
    MAGCAL_ERR_NONFINITE = -4,        /**< input contains NaN or +/-Inf */
    MAGCAL_ERR_TOO_FEW_POINTS = -5,   /**< fewer samples than the model needs */
    MAGCAL_ERR_DEGENERATE = -6,       /**< degenerate geometry: identical or collinear points, rank deficient system */
    MAGCAL_ERR_COVERAGE = -7,         /**< arc coverage below the configured minimum */
    MAGCAL_ERR_HYPERBOLA = -8,        /**< fitted conic is a hyperbola (4B - A^2 < 0) */
    MAGCAL_ERR_PARABOLA = -9,         /**< fitted conic is a parabola (4B - A^2 == 0 within tolerance) */
    MAGCAL_ERR_IMAGINARY = -10,       /**< fitted conic is an imaginary or point ellipse (K <= 0) */
    MAGCAL_ERR_ILL_CONDITIONED = -11, /**< normal equations too badly conditioned for float32 (pivot test) */
    MAGCAL_ERR_BUFFER_FULL = -12,     /**< sample buffer at capacity; sample not stored */
    MAGCAL_ERR_ALL_NOISE = -13,       /**< density filter found no cluster (every point is noise) */
    MAGCAL_ERR_TOO_MANY_OUTLIERS = -14, /**< outlier stages rejected more than the configured fraction */
    MAGCAL_ERR_RADIUS_RANGE = -15,    /**< fitted field radius outside the configured plausible range */
    MAGCAL_ERR_AXIS_RATIO = -16,      /**< ellipse axis ratio beyond the configured limit */
    MAGCAL_ERR_RESIDUAL = -17,        /**< fit residual RMS relative to radius above the configured limit */
    MAGCAL_ERR_NOT_BETTER = -18,      /**< new calibration passed the gates but the adoption rule kept the old one */
    MAGCAL_ERR_PORT = -19,            /**< the HAL port reported a read error */
    MAGCAL_ERR_TIMEOUT = -20,         /**< the HAL port timed out (no data ready) */
    MAGCAL_ERR_NO_DATA = -21,         /**< no more data (end of a replayed dump) */
    MAGCAL_ERR_STATE = -22,           /**< call not allowed in the object's current state */
    MAGCAL_ERR_NOT_INITIALISED = -23, /**< object not initialised (or corrupted) */
    MAGCAL_ERR_FREE_FALL = -24,       /**< accelerometer norm near zero: no gravity reference */
    MAGCAL_ERR_ACCEL_NORM = -25,      /**< accelerometer norm too far from 1 g: not quasi-static */
    MAGCAL_ERR_GIMBAL = -26,          /**< pitch too close to +/-90 deg: heading ill-conditioned */
    MAGCAL_ERR_SPREAD = -27,          /**< reference headings too few or too badly spread for the model */
    MAGCAL_ERR_THRESHOLD = -28,       /**< adaptive model reached its maximum order without meeting the threshold */
    MAGCAL_ERR_OUT_OF_VALIDITY = -29, /**< date (or position) outside the geomagnetic model's validity */
    MAGCAL_ERR_NOT_ELLIPSOID = -30,   /**< fitted quadric is not an ellipsoid */
    MAGCAL_ERR_UNOBSERVABLE = -31,    /**< excitation too poor: part of the model is unobservable */
    MAGCAL_ERR_NOT_CONVERGED = -32,   /**< iterative solver did not converge within its bound */
    MAGCAL_ERR_ZERO_FIELD = -33,      /**< field vector too small to define a heading */
    MAGCAL_ERR_GATED = -34,           /**< epoch rejected by a gate (field magnitude, DOP, rate) */
    MAGCAL_ERR_NO_MOTION = -35,       /**< samples do not move: the sensor was at rest (noise around one point) */
    MAGCAL_ERR_SINGLE_AXIS = -36,     /**< samples sweep one cone (rotation about one axis only, e.g. level turns): 3-D centre unobservable along it */
    MAGCAL_ERR_FIELD_MAGNITUDE = -37, /**< fitted field magnitude outside the band around the expected field */
    MAGCAL_ERR_CONFIG_MISMATCH = -38, /**< caller compiled with other compile-time limits (struct layout) than the library */
    MAGCAL_ERR_ALIGNMENT = -39,       /**< caller buffer not aligned as its declaration helper requires */
    MAGCAL_ERR_CRC = -40,             /**< stored record fails its CRC (corrupted flash) */
    MAGCAL_ERR_VERSION = -41,         /**< stored record has another magic or layout version */
    MAGCAL_ERR_SATURATED = -42,       /**< sample at the sensor's declared range limit (a saturated axis): refused */
    MAGCAL_ERR_INCONSISTENT = -43,    /**< the samples do not describe one installation (a store mixing two): refused */
    MAGCAL_ERR_SHAPE_CHANGED = -44    /**< fresh samples do not fit the installed soft-iron shape (offset-only relearn refused) */
} magcal_status_t;

/**
 * @brief Short, constant, human-readable name of a status ("ok", "hyperbola", ...).
 * @param[in] status any value; unknown values give "unknown".
 * @return pointer to a static string, never NULL.
 */
const char *magcal_status_str(magcal_status_t status);

/**
 * @brief Is `status` MAGCAL_OK or one of the normal outcomes listed in the file comment
 *        (NOT_BETTER, GATED, NO_DATA, NOT_CONVERGED)?
 * @return 1 for those, 0 for every fault or refusal (and for unknown values).
 */
int magcal_status_is_outcome(magcal_status_t status);

#ifdef __cplusplus
}
#endif

#endif /* MAGCAL_STATUS_H */
