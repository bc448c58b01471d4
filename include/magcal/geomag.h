/**
 * @file geomag.h
 * @brief Geomagnetic main-field models (WMM2025, IGRF-14): expected Earth field, declination,
 *        inclination and their secular variation at a place and date, in float32.
 *
 * The spherical-harmonic synthesis follows algorithms.md section 8: WGS 84 geodetic position ->
 * geocentric spherical, Schmidt semi-normalised Legendre functions by recurrence (order m outer,
 * degree n inner, O(N) memory on the stack, no tables in RAM), the pole handled with
 * Q = P / cos(phi'), and the geocentric vector rotated back to the geodetic north/east/down frame.
 * Coefficient tables are const (flash); with `--gc-sections` a firmware that references only
 * `magcal_geomag_wmm2025` does not link the IGRF table, and the reverse.
 *
 * Conventions and units:
 * - inputs: geodetic latitude (deg, north +), longitude (deg, east +), height above the WGS 84
 *   **ellipsoid** in km (a GNSS ellipsoidal height, not a height above mean sea level), decimal
 *   year (e.g. 2027.5; see magcal_geomag_decimal_year());
 * - outputs: X north, Y east, Z down (nT) in the local geodetic frame (NED, not the body frame);
 *   declination D east positive, inclination I down positive (deg); true heading =
 *   magnetic heading + D;
 * - dates outside a model's validity are rejected (MAGCAL_ERR_OUT_OF_VALIDITY), never
 *   extrapolated.
 *
 * A decimal year held in a float has a resolution of 2^-13 year (about 1 h) near 2025: the
 * secular variation (< 200 nT/yr) moves the field by less than 0.03 nT in that time.
 *
 * @code
 * #include "magcal/geomag.h"
 *
 * // magnetic_heading_deg from the compass; GNSS fix: lat, lon, ellipsoidal height; date.
 * float true_heading_deg = magnetic_heading_deg;
 * magcal_geomag_result_t f;
 * float year;
 * if (magcal_geomag_decimal_year(2026, 3, 15, &year) == MAGCAL_OK &&
 *     magcal_geomag_eval(&magcal_geomag_wmm2025, 48.1f, 11.6f, 0.52f, year, &f) == MAGCAL_OK &&
 *     f.zone == MAGCAL_GEOMAG_ZONE_NORMAL) {
 *     true_heading_deg = magnetic_heading_deg + f.decl_deg;  // then wrap to [0, 360)
 * }
 * @endcode
 */
#ifndef MAGCAL_GEOMAG_H
#define MAGCAL_GEOMAG_H

#include <stdint.h>

#include "magcal/config.h"
#include "magcal/status.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Largest spherical-harmonic degree any model may have (IGRF-14 main field: 13). */
#define MAGCAL_GEOMAG_NMAX 13u

/** Number of packed coefficients (g and h) of a degree-n model: n (n + 2). */
#define MAGCAL_GEOMAG_NCOEF(n) ((n) * ((n) + 2u))

/** Horizontal intensity below which the WMM report defines the blackout zone (nT). */
#define MAGCAL_GEOMAG_BLACKOUT_H_NT 2000.0f

/** Horizontal intensity below which the WMM report defines the caution zone (nT). */
#define MAGCAL_GEOMAG_CAUTION_H_NT 6000.0f

/** |geodetic latitude| above which the grid variation is reported (deg, polar regions). */
#define MAGCAL_GEOMAG_GRID_LAT_DEG 55.0f

/** Smallest geocentric radius accepted by magcal_geomag_eval_geocentric() (km). */
#define MAGCAL_GEOMAG_RADIUS_MIN_KM 6000.0f

/** Largest geocentric radius accepted by magcal_geomag_eval_geocentric() (km). */
#define MAGCAL_GEOMAG_RADIUS_MAX_KM 8000.0f

/**
 * A main-field model: const coefficient tables generated from the official files by
 * tools/geomag/cof2c.py. Treat every field as read-only; use the provided instances.
 *
 * Coefficients of one epoch are packed by degree n = 1..nmax_e: g_n^0, then g_n^m, h_n^m for
 * m = 1..n (index of g_n^0 is n^2 - 1). Between epochs the model is interpolated linearly; from
 * the last epoch on, the secular variation `sv` (nT/yr) is applied.
 */
typedef struct {
    const char *name;            /**< model name, e.g. "WMM-2025" */
    const float *coef;           /**< main-field coefficients of every epoch, packed (nT) */
    const uint16_t *epoch_start; /**< index in coef of each epoch's first coefficient */
    const uint8_t *epoch_nmax;   /**< degree of each epoch (trailing zero degrees trimmed) */
    const float *sv;             /**< secular variation after the last epoch, packed (nT/yr) */
    float epoch_first;           /**< first epoch (decimal year) */
    float epoch_step;            /**< years between epochs (unused with one epoch) */
    float valid_from;            /**< first valid date (decimal year, inclusive) */
    float valid_to;              /**< last valid date (decimal year, inclusive) */
    float height_min_km;         /**< lowest height above the ellipsoid accepted (km) */
    float height_max_km;         /**< highest height above the ellipsoid accepted (km) */
    uint8_t n_epochs;            /**< number of epochs (>= 1) */
    uint8_t nmax;                /**< largest degree of any epoch (<= MAGCAL_GEOMAG_NMAX) */
    uint8_t sv_nmax;             /**< degree of `sv` (<= nmax) */
} magcal_geomag_model_t;

#if MAGCAL_CFG_ENABLE_GEOMAG
/**
 * World Magnetic Model WMM2025 (NOAA NCEI / BGS): degree 12, epoch 2025.0, valid 2025.0-2030.0,
 * heights -1 km to 850 km above the WGS 84 ellipsoid (the range the WMM report states).
 */
extern const magcal_geomag_model_t magcal_geomag_wmm2025;

/**
 * IGRF-14 (IAGA V-MOD): DGRF/IGRF epochs 1900.0-2025.0 every 5 years (degree 10 before 2000,
 * 13 from 2000), linear interpolation, secular variation (degree 8) for 2025.0-2030.0.
 * Valid 1900.0-2030.0; heights -1 km to 850 km above the ellipsoid (the WMM range; IGRF states
 * none).
 */
extern const magcal_geomag_model_t magcal_geomag_igrf14;
#endif /* MAGCAL_CFG_ENABLE_GEOMAG */

/** Reliability of the declination, from the horizontal intensity H (WMM report definition). */
typedef enum {
    MAGCAL_GEOMAG_ZONE_NORMAL = 0,  /**< H >= 6000 nT */
    MAGCAL_GEOMAG_ZONE_CAUTION = 1, /**< 2000 nT <= H < 6000 nT: compass degraded */
    MAGCAL_GEOMAG_ZONE_BLACKOUT = 2 /**< H < 2000 nT: compass unreliable */
} magcal_geomag_zone_t;

/** Field elements at one place and date (geodetic north/east/down frame). */
typedef struct {
    float x_nt;            /**< X, north component (nT) */
    float y_nt;            /**< Y, east component (nT) */
    float z_nt;            /**< Z, down component (nT) */
    float h_nt;            /**< H = sqrt(X^2 + Y^2), horizontal intensity (nT) */
    float f_nt;            /**< F = sqrt(H^2 + Z^2), total intensity (nT) */
    float decl_deg;        /**< D = atan2(Y, X), declination, east positive (deg, (-180, 180]) */
    float incl_deg;        /**< I = atan2(Z, H), inclination, down positive (deg) */
    float grid_var_deg;    /**< grid variation D -/+ longitude (deg, (-180, 180]) when
                                `polar` is 1, else equal to decl_deg */
    float x_dot_nt_yr;     /**< dX/dt (nT/yr) */
    float y_dot_nt_yr;     /**< dY/dt (nT/yr) */
    float z_dot_nt_yr;     /**< dZ/dt (nT/yr) */
    float h_dot_nt_yr;     /**< dH/dt (nT/yr) */
    float f_dot_nt_yr;     /**< dF/dt (nT/yr) */
    float decl_dot_deg_yr; /**< dD/dt (deg/yr); 0 where H == 0 */
    float incl_dot_deg_yr; /**< dI/dt (deg/yr); 0 where F == 0 */
    magcal_geomag_zone_t zone; /**< blackout / caution flag from H */
    uint8_t polar;         /**< 1 when |lat| > MAGCAL_GEOMAG_GRID_LAT_DEG (grid_var_deg is the
                                grid variation D - lon north, D + lon south) */
} magcal_geomag_result_t;

#if MAGCAL_CFG_ENABLE_GEOMAG
/**
 * @brief Evaluate a main-field model at a geodetic position and date.
 *
 * @param[in] model      model (&magcal_geomag_wmm2025 or &magcal_geomag_igrf14).
 * @param[in] lat_deg    geodetic latitude (deg), -90..90 inclusive (the poles are handled).
 * @param[in] lon_deg    longitude (deg, east +), -360..360 (any value in range is reduced).
 * @param[in] height_km  height above the WGS 84 ellipsoid (km), within the model's
 *                       [height_min_km, height_max_km].
 * @param[in] year       decimal year, within [valid_from, valid_to] of the model.
 * @param[out] out       field elements; untouched on failure.
 * @return MAGCAL_OK;
 *         MAGCAL_ERR_NULL (model or out NULL);
 *         MAGCAL_ERR_NONFINITE (an input is NaN or +/-Inf);
 *         MAGCAL_ERR_ARG (|lat| > 90, |lon| > 360, height outside the model's range, or a
 *         model descriptor with nmax > MAGCAL_GEOMAG_NMAX or no epoch);
 *         MAGCAL_ERR_OUT_OF_VALIDITY (year outside the model's validity).
 */
magcal_status_t magcal_geomag_eval(const magcal_geomag_model_t *model, float lat_deg,
                                   float lon_deg, float height_km, float year,
                                   magcal_geomag_result_t *out);

/**
 * @brief Evaluate a model at a geocentric spherical position: the vector in the geocentric
 *        (spherical) north/east/down frame, as in the IGRF test values, and its rates.
 *
 * @param[in] model      model.
 * @param[in] lat_gc_deg geocentric latitude (deg), -90..90 (= 90 - geocentric colatitude).
 * @param[in] lon_deg    longitude (deg, east +), -360..360.
 * @param[in] radius_km  geocentric radius (km), MAGCAL_GEOMAG_RADIUS_MIN_KM..._MAX_KM.
 * @param[in] year       decimal year within the model's validity.
 * @param[out] xyz_nt    X' (north), Y' (east), Z' (down, towards the centre) in nT; untouched on
 *                       failure.
 * @param[out] xyz_dot_nt_yr  rates of the same components (nT/yr); may be NULL.
 * @return MAGCAL_OK, MAGCAL_ERR_NULL, MAGCAL_ERR_NONFINITE, MAGCAL_ERR_ARG (latitude, longitude
 *         or radius out of range, bad model), MAGCAL_ERR_OUT_OF_VALIDITY.
 */
magcal_status_t magcal_geomag_eval_geocentric(const magcal_geomag_model_t *model,
                                              float lat_gc_deg, float lon_deg, float radius_km,
                                              float year, float xyz_nt[3], float xyz_dot_nt_yr[3]);

/**
 * @brief Decimal year of a calendar date at 00:00 UTC (Gregorian):
 *        year + (day_of_year - 1) / days_in_year.
 * @param[in] year   1900..2100.
 * @param[in] month  1..12.
 * @param[in] day    1..days in that month.
 * @param[out] out   decimal year; untouched on failure.
 * @return MAGCAL_OK, MAGCAL_ERR_NULL, MAGCAL_ERR_ARG (date out of range or invalid).
 */
magcal_status_t magcal_geomag_decimal_year(int year, int month, int day, float *out);
#endif /* MAGCAL_CFG_ENABLE_GEOMAG */

#ifdef __cplusplus
}
#endif

#endif /* MAGCAL_GEOMAG_H */
