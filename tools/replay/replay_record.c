/* magcal-replay --export-record (and --stream --save): the replay's calibration as the flash record
 * (record.h). */
#include "replay_record.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "magcal/record.h"

int replay_parse_sensor_id(const char *s, uint32_t *out)
{
    char *end = NULL;
    unsigned long v;
    if (s == NULL || *s == '\0' || *s == '-') {
        return -1;
    }
    errno = 0;
    v = strtoul(s, &end, 0);
    if (errno != 0 || end == s || *end != '\0' || v > 0xFFFFFFFFul) {
        return -1;
    }
    *out = (uint32_t)v;
    return 0;
}

static uint32_t record_stamp(void)
{
    const char *sde = getenv("SOURCE_DATE_EPOCH");
    uint32_t v;
    if (sde != NULL && replay_parse_sensor_id(sde, &v) == 0) {
        return v;
    }
    return (uint32_t)time(NULL);
}

static magcal_record_unit_t unit_of(const replay_report_t *r)
{
    if (r->field_unit != NULL && strcmp(r->mode, "aided") == 0) {
        if (strcmp(r->field_unit, "uT") == 0) {
            return MAGCAL_RECORD_UNIT_UT;
        }
        if (strcmp(r->field_unit, "nT") == 0) {
            return MAGCAL_RECORD_UNIT_NT;
        }
        if (strcmp(r->field_unit, "gauss") == 0) {
            return MAGCAL_RECORD_UNIT_GAUSS;
        }
    }
    return MAGCAL_RECORD_UNIT_RAW; /* 2d / 3d: the dump's own unit */
}

int replay_export_record(const char *path, const replay_report_t *r, const magcal_cal2d_t *cal2d,
                         const magcal_ellipsoid_cal_t *cal3, uint32_t sensor_id, char *err, size_t err_len)
{
    magcal_record_t rec;
    if (r->status_code != (int)MAGCAL_OK) {
        (void)snprintf(err, err_len, "--export-record: the calibration status is %s, not ok: nothing exported",
                       r->status != NULL ? r->status : "unknown");
        return REPLAY_EXIT_CAL_FAILED;
    }
    memset(&rec, 0, sizeof rec);
    rec.unit = unit_of(r);
    rec.sensor_id = sensor_id;
    rec.n_used = (uint32_t)r->n_used;
    if (strcmp(r->mode, "2d") == 0) {
        rec.kind = MAGCAL_RECORD_KIND_2D;
        rec.est_heading_err_deg = (float)r->est_heading_err_deg;
        rec.radius = (float)r->radius;
        rec.residual_rms = (float)r->residual_rms;
        rec.coverage = (float)r->coverage_deg;
        rec.cal2d = *cal2d;
    } else {
        int aided = strcmp(r->mode, "aided") == 0;
        rec.kind = MAGCAL_RECORD_KIND_3D;
        rec.est_heading_err_deg = NAN; /* the 3-D paths give no heading-error estimate */
        rec.radius = cal3->field;
        rec.residual_rms = (float)(aided ? r->resid_rms_aided : r->residual_rms);
        rec.coverage = aided ? 0.0f : (float)r->coverage3; /* 0: not measured */
        rec.cal3d = *cal3;
    }
    return replay_record_write(path, "--export-record", &rec, err, err_len);
}

int replay_record_write(const char *path, const char *opt, magcal_record_t *rec, char *err, size_t err_len)
{
    uint8_t bytes[MAGCAL_RECORD_LEN];
    magcal_status_t st;
    FILE *f;
    int bad;
    rec->created = record_stamp();
    st = magcal_record_pack(rec, bytes, sizeof bytes);
    if (st != MAGCAL_OK) {
        (void)snprintf(err, err_len, "%s: magcal_record_pack refused the calibration: %s", opt, magcal_status_str(st));
        return REPLAY_EXIT_OUTPUT;
    }
    f = fopen(path, "wb");
    bad = (f == NULL);
    if (f != NULL) {
        bad = fwrite(bytes, 1u, sizeof bytes, f) != sizeof bytes;
        bad |= fclose(f) != 0;
    }
    if (bad) {
        (void)snprintf(err, err_len, "%s: cannot write %s: %s", opt, path, strerror(errno));
        return REPLAY_EXIT_OUTPUT;
    }
    return REPLAY_EXIT_OK;
}
