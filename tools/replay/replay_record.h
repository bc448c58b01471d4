/* magcal-replay --export-record FILE: the flash record (magcal/record.h) of the calibration a
 * replay produced, i.e. the MAGCAL_RECORD_LEN bytes a firmware programs into flash. */
#ifndef MAGCAL_REPLAY_RECORD_H
#define MAGCAL_REPLAY_RECORD_H

#include <stddef.h>
#include <stdint.h>

#include "magcal/ellipsoid.h"
#include "magcal/heading.h"
#include "magcal/record.h"
#include "replay_report.h"

/** Parse a --sensor-id value (decimal or 0x hex, 0..0xFFFFFFFF). 0 ok, -1 bad. */
int replay_parse_sensor_id(const char *s, uint32_t *out);

/**
 * Write the record of a successful replay to `path`: 2-D from cal2d and r's quality figures,
 * 3-D / aided from cal3. The creation stamp is SOURCE_DATE_EPOCH when set (reproducible
 * output), else the current Unix time. Only a calibration the library returned with MAGCAL_OK
 * is exported. Returns REPLAY_EXIT_OK, REPLAY_EXIT_CAL_FAILED (status not ok: nothing written)
 * or REPLAY_EXIT_OUTPUT (record refused by magcal_record_pack, or the file cannot be written);
 * err says why.
 */
int replay_export_record(const char *path, const replay_report_t *r, const magcal_cal2d_t *cal2d,
                         const magcal_ellipsoid_cal_t *cal3, uint32_t sensor_id, char *err, size_t err_len);

/**
 * Pack `rec` (its creation stamp set here, as replay_export_record sets it) and write its
 * MAGCAL_RECORD_LEN bytes to `path`. REPLAY_EXIT_OK, or REPLAY_EXIT_OUTPUT (refused by
 * magcal_record_pack, or the file cannot be written) with err saying why, prefixed by `opt`.
 */
int replay_record_write(const char *path, const char *opt, magcal_record_t *rec, char *err, size_t err_len);

#endif
