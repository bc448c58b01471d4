/* Flash record of a stored calibration (record.h): explicit little-endian encoding, CRC-32,
 * and the content checks a restored calibration must pass before it is used. */
#include "magcal/record.h"

#include <float.h>
#include <math.h>
#include <string.h>

#include "magcal_internal.h"

/* The encoding copies float bit patterns: they must be IEEE-754 binary32. */
/* cppcheck-suppress misra-c2012-2.3 ; deviation D4: a static assert is an unused typedef */
MAGCAL_STATIC_ASSERT(sizeof(float) == 4u && FLT_MANT_DIG == 24 && FLT_MAX_EXP == 128, float_is_binary32);

#define REC_OFF_MAGIC 0u
#define REC_OFF_VERSION 4u
#define REC_OFF_LEN 6u
#define REC_OFF_KIND 8u
#define REC_OFF_UNIT 9u
#define REC_OFF_RESERVED 10u
#define REC_OFF_SENSOR 12u
#define REC_OFF_CREATED 16u
#define REC_OFF_N 20u
#define REC_OFF_EST 24u
#define REC_OFF_RADIUS 28u
#define REC_OFF_RESID 32u
#define REC_OFF_COVERAGE 36u
#define REC_OFF_CAL 40u
#define REC_CAL_FLOATS 13u /* 3-D: 9 + 3 + 1; 2-D uses the first 7 */
#define REC_OFF_CRC (REC_OFF_CAL + 4u * REC_CAL_FLOATS)
/* cppcheck-suppress misra-c2012-2.3 ; deviation D4: a static assert is an unused typedef */
MAGCAL_STATIC_ASSERT(REC_OFF_CRC + 4u == MAGCAL_RECORD_LEN, record_layout_fills_len);

uint32_t magcal_record_crc32(const uint8_t *data, size_t n)
{
    uint32_t crc = 0xFFFFFFFFu;
    size_t i;
    unsigned b;
    for (i = 0u; i < n; ++i) {
        crc ^= (uint32_t)data[i];
        for (b = 0u; b < 8u; ++b) {
            crc = (crc >> 1) ^ (0xEDB88320u & (0u - (crc & 1u)));
        }
    }
    return crc ^ 0xFFFFFFFFu;
}

static void put_u16(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)(v & 0xFFu);
    p[1] = (uint8_t)((v >> 8) & 0xFFu);
}

static void put_u32(uint8_t *p, uint32_t v)
{
    put_u16(p, v & 0xFFFFu);
    put_u16(p + 2, v >> 16);
}

static void put_f32(uint8_t *p, float f)
{
    uint32_t u;
    /* cppcheck-suppress misra-c2012-21.15 ; deviation D11: float bit pattern of the record */
    (void)memcpy(&u, &f, sizeof u);
    put_u32(p, u);
}

static uint32_t get_u16(const uint8_t *p) { return (uint32_t)p[0] | ((uint32_t)p[1] << 8); }

static uint32_t get_u32(const uint8_t *p) { return get_u16(p) | (get_u16(p + 2) << 16); }

static float get_f32(const uint8_t *p)
{
    uint32_t u = get_u32(p);
    float f;
    /* cppcheck-suppress misra-c2012-21.15 ; deviation D11: float bit pattern of the record */
    (void)memcpy(&f, &u, sizeof f);
    return f;
}

static magcal_status_t check_cal3d(const magcal_ellipsoid_cal_t *c)
{
    float g[3][3];
    size_t i;
    size_t j;
    float det;
    for (i = 0u; i < 3u; ++i) {
        for (j = 0u; j < 3u; ++j) {
            if (!magcal_isfinite_f(c->g[i][j])) {
                return MAGCAL_ERR_NONFINITE;
            }
            g[i][j] = c->g[i][j];
        }
    }
    if (!magcal_isfinite_f(c->v.x) || !magcal_isfinite_f(c->v.y) || !magcal_isfinite_f(c->v.z) ||
        !magcal_isfinite_f(c->field)) {
        return MAGCAL_ERR_NONFINITE;
    }
    det = magcal_det3(g);
    if (!(det > 0.0f) || !magcal_isfinite_f(det)) {
        return MAGCAL_ERR_DEGENERATE; /* singular, or a mirrored axis (wiring/sign fault) */
    }
    return (c->field > 0.0f) ? MAGCAL_OK : MAGCAL_ERR_ARG;
}

magcal_status_t magcal_record_check(const magcal_record_t *rec)
{
    float cov_max;
    if (rec == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if ((rec->kind != MAGCAL_RECORD_KIND_2D && rec->kind != MAGCAL_RECORD_KIND_3D) ||
        (uint32_t)rec->unit > (uint32_t)MAGCAL_RECORD_UNIT_MGAUSS) {
        return MAGCAL_ERR_ARG;
    }
    if (!magcal_isfinite_f(rec->radius) || !magcal_isfinite_f(rec->residual_rms) ||
        !magcal_isfinite_f(rec->coverage) ||
        (rec->est_heading_err_deg == rec->est_heading_err_deg && !magcal_isfinite_f(rec->est_heading_err_deg))) {
        return MAGCAL_ERR_NONFINITE; /* NaN is allowed only for est_heading_err_deg (not estimated) */
    }
    cov_max = (rec->kind == MAGCAL_RECORD_KIND_2D) ? 360.0f : 1.0f;
    if (rec->n_used == 0u || !(rec->radius > 0.0f) || !(rec->residual_rms >= 0.0f) ||
        !(rec->coverage <= cov_max) || rec->est_heading_err_deg < 0.0f ||
        !(rec->coverage > 0.0f || (rec->kind == MAGCAL_RECORD_KIND_3D && rec->coverage == 0.0f))) {
        return MAGCAL_ERR_ARG;
    }
    if (!magcal_isfinite_f(rec->tilt_k) || rec->tilt_levelled > 1u ||
        (rec->tilt_k == 0.0f && rec->tilt_levelled != 0u) ||
        (rec->kind == MAGCAL_RECORD_KIND_3D && rec->tilt_k != 0.0f)) {
        return MAGCAL_ERR_ARG; /* the tilt compensation is 2-D's, and levelled only with a k */
    }
    if (rec->kind == MAGCAL_RECORD_KIND_2D) {
        magcal_status_t st = magcal_cal2d_validate(&rec->cal2d);
        if (st == MAGCAL_OK && !(rec->cal2d.radius > 0.0f)) {
            st = MAGCAL_ERR_ARG; /* radius unknown: the adoption rule (c) needs it */
        }
        return st;
    }
    return check_cal3d(&rec->cal3d);
}

magcal_status_t magcal_record_pack(const magcal_record_t *rec, uint8_t *out, size_t out_len)
{
    uint8_t b[MAGCAL_RECORD_LEN];
    float cal[REC_CAL_FLOATS];
    size_t i;
    magcal_status_t st;
    if (rec == NULL || out == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (out_len < MAGCAL_RECORD_LEN) {
        return MAGCAL_ERR_WORKSPACE;
    }
    st = magcal_record_check(rec);
    if (st != MAGCAL_OK) {
        return st;
    }
    (void)memset(b, 0, sizeof b);
    (void)memset(cal, 0, sizeof cal);
    put_u32(b + REC_OFF_MAGIC, MAGCAL_RECORD_MAGIC);
    put_u16(b + REC_OFF_VERSION, MAGCAL_RECORD_VERSION);
    put_u16(b + REC_OFF_LEN, MAGCAL_RECORD_LEN);
    b[REC_OFF_KIND] = (uint8_t)rec->kind;
    b[REC_OFF_UNIT] = (uint8_t)rec->unit;
    put_u32(b + REC_OFF_SENSOR, rec->sensor_id);
    put_u32(b + REC_OFF_CREATED, rec->created);
    put_u32(b + REC_OFF_N, rec->n_used);
    put_f32(b + REC_OFF_EST, rec->est_heading_err_deg);
    put_f32(b + REC_OFF_RADIUS, rec->radius);
    put_f32(b + REC_OFF_RESID, rec->residual_rms);
    put_f32(b + REC_OFF_COVERAGE, rec->coverage);
    if (rec->kind == MAGCAL_RECORD_KIND_2D) {
        cal[0] = rec->cal2d.offset.x;
        cal[1] = rec->cal2d.offset.y;
        cal[2] = rec->cal2d.m[0][0];
        cal[3] = rec->cal2d.m[0][1];
        cal[4] = rec->cal2d.m[1][0];
        cal[5] = rec->cal2d.m[1][1];
        cal[6] = rec->cal2d.radius;
        cal[7] = rec->tilt_k;
        cal[8] = (rec->tilt_levelled != 0u) ? 1.0f : 0.0f;
    } else {
        for (i = 0u; i < 9u; ++i) {
            cal[i] = rec->cal3d.g[i / 3u][i % 3u];
        }
        cal[9] = rec->cal3d.v.x;
        cal[10] = rec->cal3d.v.y;
        cal[11] = rec->cal3d.v.z;
        cal[12] = rec->cal3d.field;
    }
    for (i = 0u; i < REC_CAL_FLOATS; ++i) {
        put_f32(b + REC_OFF_CAL + 4u * i, cal[i]);
    }
    put_u32(b + REC_OFF_CRC, magcal_record_crc32(b, REC_OFF_CRC));
    (void)memcpy(out, b, sizeof b);
    return MAGCAL_OK;
}

magcal_status_t magcal_record_unpack(const uint8_t *buf, size_t len, magcal_record_t *out)
{
    magcal_record_t r;
    float cal[REC_CAL_FLOATS];
    size_t i;
    magcal_status_t st;
    if (buf == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (len < MAGCAL_RECORD_LEN) {
        return MAGCAL_ERR_WORKSPACE;
    }
    if (get_u32(buf + REC_OFF_MAGIC) != MAGCAL_RECORD_MAGIC ||
        get_u16(buf + REC_OFF_VERSION) != MAGCAL_RECORD_VERSION ||
        get_u16(buf + REC_OFF_LEN) != MAGCAL_RECORD_LEN) {
        return MAGCAL_ERR_VERSION;
    }
    if (get_u32(buf + REC_OFF_CRC) != magcal_record_crc32(buf, REC_OFF_CRC)) {
        return MAGCAL_ERR_CRC;
    }
    if (get_u16(buf + REC_OFF_RESERVED) != 0u) {
        return MAGCAL_ERR_ARG;
    }
    (void)memset(&r, 0, sizeof r);
    if ((buf[REC_OFF_KIND] != (uint8_t)MAGCAL_RECORD_KIND_2D && buf[REC_OFF_KIND] != (uint8_t)MAGCAL_RECORD_KIND_3D) ||
        buf[REC_OFF_UNIT] > (uint8_t)MAGCAL_RECORD_UNIT_MGAUSS) {
        return MAGCAL_ERR_ARG; /* enums are assigned from the known set only */
    }
    r.kind = (buf[REC_OFF_KIND] == (uint8_t)MAGCAL_RECORD_KIND_3D) ? MAGCAL_RECORD_KIND_3D : MAGCAL_RECORD_KIND_2D;
    r.unit = (magcal_record_unit_t)buf[REC_OFF_UNIT];
    r.sensor_id = get_u32(buf + REC_OFF_SENSOR);
    r.created = get_u32(buf + REC_OFF_CREATED);
    r.n_used = get_u32(buf + REC_OFF_N);
    r.est_heading_err_deg = get_f32(buf + REC_OFF_EST);
    r.radius = get_f32(buf + REC_OFF_RADIUS);
    r.residual_rms = get_f32(buf + REC_OFF_RESID);
    r.coverage = get_f32(buf + REC_OFF_COVERAGE);
    for (i = 0u; i < REC_CAL_FLOATS; ++i) {
        cal[i] = get_f32(buf + REC_OFF_CAL + 4u * i);
    }
    if (r.kind == MAGCAL_RECORD_KIND_2D) {
        for (i = 9u; i < REC_CAL_FLOATS; ++i) {
            if (get_u32(buf + REC_OFF_CAL + 4u * i) != 0u) {
                return MAGCAL_ERR_ARG; /* the unused tail of a 2-D record is zero */
            }
        }
        if (!(cal[8] == 0.0f || cal[8] == 1.0f)) {
            return MAGCAL_ERR_ARG;
        }
        r.tilt_k = cal[7];
        r.tilt_levelled = (cal[8] == 1.0f) ? 1u : 0u;
        r.cal2d.offset.x = cal[0];
        r.cal2d.offset.y = cal[1];
        r.cal2d.m[0][0] = cal[2];
        r.cal2d.m[0][1] = cal[3];
        r.cal2d.m[1][0] = cal[4];
        r.cal2d.m[1][1] = cal[5];
        r.cal2d.radius = cal[6];
        r.cal2d.magic = MAGCAL_CAL2D_MAGIC;
    } else {
        for (i = 0u; i < 9u; ++i) {
            r.cal3d.g[i / 3u][i % 3u] = cal[i];
        }
        r.cal3d.v.x = cal[9];
        r.cal3d.v.y = cal[10];
        r.cal3d.v.z = cal[11];
        r.cal3d.field = cal[12];
    }
    st = magcal_record_check(&r);
    if (st == MAGCAL_OK && out != NULL) {
        *out = r;
    }
    return st;
}

magcal_status_t magcal_record_validate(const uint8_t *buf, size_t len)
{
    return magcal_record_unpack(buf, len, NULL);
}

magcal_status_t magcal_record_from_report(magcal_record_t *rec, const magcal_cal_report_t *report,
                                          uint32_t sensor_id, magcal_record_unit_t unit,
                                          uint32_t created)
{
    magcal_record_t r;
    magcal_status_t st;
    if (rec == NULL || report == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (report->status != MAGCAL_OK || report->adopted != 1u) {
        return MAGCAL_ERR_STATE;
    }
    (void)memset(&r, 0, sizeof r);
    r.kind = MAGCAL_RECORD_KIND_2D;
    r.unit = unit;
    r.sensor_id = sensor_id;
    r.created = created;
    r.n_used = report->used;
    r.est_heading_err_deg = report->est_heading_err_deg;
    r.radius = report->radius;
    r.residual_rms = report->residual_rms;
    r.coverage = report->coverage_deg;
    r.cal2d = report->cal;
    st = magcal_record_check(&r);
    if (st == MAGCAL_OK) {
        *rec = r;
    }
    return st;
}

magcal_status_t magcal_record_from_ellipsoid(magcal_record_t *rec, const magcal_ellipsoid_result_t *res,
                                             uint32_t sensor_id, magcal_record_unit_t unit,
                                             uint32_t created)
{
    magcal_record_t r;
    magcal_status_t st;
    if (rec == NULL || res == NULL) {
        return MAGCAL_ERR_NULL;
    }
    (void)memset(&r, 0, sizeof r);
    r.kind = MAGCAL_RECORD_KIND_3D;
    r.unit = unit;
    r.sensor_id = sensor_id;
    r.created = created;
    r.n_used = (res->n_used >= (size_t)0xFFFFFFFFu) ? 0xFFFFFFFFu : (uint32_t)res->n_used;
    r.est_heading_err_deg = NAN;
    r.radius = res->cal.field;
    r.residual_rms = res->residual_rms;
    r.coverage = res->coverage;
    r.cal3d = res->cal;
    st = magcal_record_check(&r);
    if (st == MAGCAL_OK) {
        *rec = r;
    }
    return st;
}
