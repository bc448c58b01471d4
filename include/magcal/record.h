/**
 * @file record.h
 * @brief The flash record of a stored calibration (2-D magcal_cal2d_t or 3-D
 *        magcal_ellipsoid_cal_t): fixed size, versioned, little-endian, CRC-32 protected.
 *
 * A calibration the firmware keeps across power cycles is written as MAGCAL_RECORD_LEN bytes
 * and checked on every restore: one flipped bit, a blank or half-written page, a record of
 * another layout version or of another sensor is refused before the calibration is used.
 *
 * Byte layout, layout version 1 (all multi-byte fields little-endian whatever the host; floats
 * are IEEE-754 binary32 bit patterns):
 *
 * | offset | size | field |
 * | --- | --- | --- |
 * | 0  | 4 | magic MAGCAL_RECORD_MAGIC, bytes "MCRD" |
 * | 4  | 2 | layout version MAGCAL_RECORD_VERSION |
 * | 6  | 2 | record length MAGCAL_RECORD_LEN |
 * | 8  | 1 | kind (magcal_record_kind_t: 2 = 2-D, 3 = 3-D) |
 * | 9  | 1 | unit of the raw samples (magcal_record_unit_t) |
 * | 10 | 2 | reserved, 0 |
 * | 12 | 4 | sensor id (chosen by the firmware) |
 * | 16 | 4 | creation stamp (chosen by the firmware, e.g. Unix seconds) |
 * | 20 | 4 | samples used by the fit (n) |
 * | 24 | 4 | float est_heading_err_deg (NaN: not estimated) |
 * | 28 | 4 | float radius (2-D: sqrt(r1 r2), raw units; 3-D: field F, output units) |
 * | 32 | 4 | float residual_rms (the fit's RMS residual, same unit as radius) |
 * | 36 | 4 | float coverage (2-D: covered arc, degrees; 3-D: filled direction cells, 0..1, 0 = not measured) |
 * | 40 | 52 | calibration: 2-D offset.x, offset.y, m[0][0], m[0][1], m[1][0], m[1][1], radius, tilt_k, tilt_levelled (as 0.0 or 1.0), then 16 zero bytes; 3-D g[0][0]..g[2][2] row-major, v.x, v.y, v.z, field |
 * | 92 | 4 | CRC-32 (IEEE 802.3: reflected 0xEDB88320, init and final XOR 0xFFFFFFFF) of bytes 0..91 |
 *
 * CRC-32 detects every error of up to 3 bits and every burst up to 32 bits in a 96-byte record,
 * so every single-bit flip is refused (tested bit by bit in tests/test_record.c).
 *
 * Workflow (README "Storing a calibration"): the firmware (or `magcal-replay --export-record`)
 * packs a calibration with magcal_record_pack() and writes the bytes to flash; at boot it reads
 * them back with magcal_record_unpack(), checks kind and sensor id, and uses the calibration,
 * else starts from MAGCAL_CAL2D_IDENTITY and calibrates.
 *
 * @code
 * #include "magcal/record.h"
 *
 * static uint8_t page[MAGCAL_RECORD_LEN];          // read from flash at boot
 * static magcal_cal2d_t cal = MAGCAL_CAL2D_IDENTITY;
 *
 * void restore(uint32_t my_sensor_id)
 * {
 *     magcal_record_t rec;
 *     if (magcal_record_unpack(page, sizeof page, &rec) == MAGCAL_OK &&
 *         rec.kind == MAGCAL_RECORD_KIND_2D && rec.sensor_id == my_sensor_id) {
 *         cal = rec.cal2d;                          // checked: CRC, version, contents
 *     }
 * }
 *
 * void store(const magcal_cal_report_t *rep, uint32_t my_sensor_id, uint32_t now_s)
 * {
 *     magcal_record_t rec;
 *     if (magcal_record_from_report(&rec, rep, my_sensor_id, MAGCAL_RECORD_UNIT_RAW, now_s) == MAGCAL_OK &&
 *         magcal_record_pack(&rec, page, sizeof page) == MAGCAL_OK) {
 *         // erase + program `page` into flash
 *     }
 * }
 * @endcode
 */
#ifndef MAGCAL_RECORD_H
#define MAGCAL_RECORD_H

#include <stddef.h>
#include <stdint.h>

#include "magcal/calibrator.h"
#include "magcal/ellipsoid.h"
#include "magcal/heading.h"
#include "magcal/status.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Record magic: the bytes 'M' 'C' 'R' 'D' at offset 0 (little-endian uint32). */
#define MAGCAL_RECORD_MAGIC 0x4452434Du
/** Layout version of this header's byte layout; a record of another version is refused. */
#define MAGCAL_RECORD_VERSION 1u
/** Bytes of every record (both kinds): size the flash page buffer with it. */
#define MAGCAL_RECORD_LEN 96u

/** What the record holds. */
typedef enum {
    MAGCAL_RECORD_KIND_2D = 2, /**< magcal_cal2d_t (level heading, calibrator.h) */
    MAGCAL_RECORD_KIND_3D = 3  /**< magcal_ellipsoid_cal_t (ellipsoid.h, aided.h) */
} magcal_record_kind_t;

/** Unit of the raw samples the calibration applies to (what the port delivers). */
typedef enum {
    MAGCAL_RECORD_UNIT_RAW = 0,   /**< sensor counts (LSB) or an unspecified consistent unit */
    MAGCAL_RECORD_UNIT_UT = 1,    /**< microtesla */
    MAGCAL_RECORD_UNIT_NT = 2,    /**< nanotesla */
    MAGCAL_RECORD_UNIT_GAUSS = 3, /**< gauss */
    MAGCAL_RECORD_UNIT_MGAUSS = 4 /**< milligauss */
} magcal_record_unit_t;

/** Decoded record. Only the calibration member of `kind` is meaningful (the other is zero). */
typedef struct {
    magcal_record_kind_t kind;
    magcal_record_unit_t unit;
    uint32_t sensor_id;        /**< chosen by the firmware: e.g. part id + bus address, or a serial */
    uint32_t created;          /**< chosen by the firmware: e.g. Unix seconds, or a boot counter */
    uint32_t n_used;           /**< samples in the final fit */
    float est_heading_err_deg; /**< estimated heading error, degrees (>= 0); NaN: not estimated */
    float radius;              /**< 2-D: sqrt(r1 r2), raw units; 3-D: field F, output units (> 0) */
    float residual_rms;        /**< RMS residual of the fit, unit of radius (>= 0) */
    float coverage;            /**< 2-D: covered arc in degrees (0..360]; 3-D: filled fraction of the
                                    direction cells [0..1], 0 = not measured (aided estimator) */
    magcal_cal2d_t cal2d;      /**< kind 2-D: the calibration (magic MAGCAL_CAL2D_MAGIC) */
    float tilt_k;              /**< kind 2-D, the continuous calibrator's tilt compensation
                                    (magcal_cont_tilt_state / magcal_cont_restore_tilt): the
                                    vertical field in raw units, 0 = not known (a record written
                                    before this field existed reads 0: its bytes were zero) */
    uint8_t tilt_levelled;     /**< kind 2-D: 1 = the calibration was fitted on (or confirmed on)
                                    tilt-levelled samples; 0 otherwise (and always when tilt_k is 0) */
    magcal_ellipsoid_cal_t cal3d; /**< kind 3-D: h = G (m - V), |h| = field */
} magcal_record_t;

/**
 * @brief CRC-32 (IEEE 802.3, the zlib/Ethernet one) of n bytes; "123456789" gives 0xCBF43926.
 * @param[in] data bytes (may be NULL only when n is 0).
 * @param[in] n    number of bytes.
 * @return the CRC.
 */
uint32_t magcal_record_crc32(const uint8_t *data, size_t n);

/**
 * @brief Fill a 2-D record from a report of an adopting magcal_calibrator_run() (report->cal and
 *        its quality figures).
 * @param[out] rec       record; written only on MAGCAL_OK.
 * @param[in]  report    report with status MAGCAL_OK and adopted == 1.
 * @param[in]  sensor_id firmware's sensor identity.
 * @param[in]  unit      unit of the raw samples.
 * @param[in]  created   creation stamp.
 * @return MAGCAL_OK; MAGCAL_ERR_NULL; MAGCAL_ERR_STATE (the report is not of an adopted
 *         calibration); any status of magcal_record_check().
 */
magcal_status_t magcal_record_from_report(magcal_record_t *rec, const magcal_cal_report_t *report,
                                          uint32_t sensor_id, magcal_record_unit_t unit,
                                          uint32_t created);

/**
 * @brief Fill a 3-D record from a magcal_ellipsoid_fit() result (est_heading_err_deg = NaN: the
 *        3-D fit gives no heading-error estimate).
 * @return MAGCAL_OK; MAGCAL_ERR_NULL; any status of magcal_record_check(). rec written only on OK.
 */
magcal_status_t magcal_record_from_ellipsoid(magcal_record_t *rec, const magcal_ellipsoid_result_t *res,
                                             uint32_t sensor_id, magcal_record_unit_t unit,
                                             uint32_t created);

/**
 * @brief Check the contents of a decoded record (what pack() requires and unpack() enforces).
 * @return MAGCAL_OK; MAGCAL_ERR_NULL; MAGCAL_ERR_ARG (unknown kind or unit, quality figure out of
 *         its documented range); MAGCAL_ERR_NONFINITE (a calibration value or quality figure
 *         other than est_heading_err_deg is NaN/Inf); 2-D: any status of magcal_cal2d_validate()
 *         and MAGCAL_ERR_ARG when cal2d.radius is 0 (unknown: the adoption rule needs it);
 *         3-D: MAGCAL_ERR_DEGENERATE (det G <= 0), MAGCAL_ERR_ARG (field <= 0).
 */
magcal_status_t magcal_record_check(const magcal_record_t *rec);

/**
 * @brief Encode a record into its MAGCAL_RECORD_LEN flash bytes (layout in the file comment).
 * @param[in]  rec     record (checked with magcal_record_check()).
 * @param[out] out     MAGCAL_RECORD_LEN bytes; written only on MAGCAL_OK.
 * @param[in]  out_len bytes at out.
 * @return MAGCAL_OK; MAGCAL_ERR_NULL; MAGCAL_ERR_WORKSPACE (out_len < MAGCAL_RECORD_LEN); any status
 *         of magcal_record_check().
 */
magcal_status_t magcal_record_pack(const magcal_record_t *rec, uint8_t *out, size_t out_len);

/**
 * @brief Decode and check flash bytes. Order of the checks: length, magic and layout version
 *        (a record of another layout cannot be CRC-checked by this one), CRC, contents.
 * @param[in]  buf  bytes read from flash.
 * @param[in]  len  bytes at buf (>= MAGCAL_RECORD_LEN; extra bytes are ignored).
 * @param[out] out  decoded record; may be NULL (validate only); written only on MAGCAL_OK.
 * @return MAGCAL_OK; MAGCAL_ERR_NULL (buf NULL); MAGCAL_ERR_WORKSPACE (len < MAGCAL_RECORD_LEN);
 *         MAGCAL_ERR_VERSION (magic, layout version or length field is not this one's: blank
 *         flash, another record, another layout); MAGCAL_ERR_CRC (corrupted bytes);
 *         MAGCAL_ERR_ARG (non-zero reserved bytes) or any status of magcal_record_check()
 *         (a record written by a faulty writer with a valid CRC).
 */
magcal_status_t magcal_record_unpack(const uint8_t *buf, size_t len, magcal_record_t *out);

/** @brief Validate flash bytes without decoding them: magcal_record_unpack(buf, len, NULL). */
magcal_status_t magcal_record_validate(const uint8_t *buf, size_t len);

#ifdef __cplusplus
}
#endif

#endif /* MAGCAL_RECORD_H */
