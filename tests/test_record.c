/* Unity tests of the flash record (record.h): byte layout against golden bytes made by an
 * independent implementation (tools/golden/make_record_golden.py: Python struct + zlib.crc32),
 * round trips, every single-bit flip refused, version/magic/length mismatches, content checks,
 * and a real calibration restored from its record giving the same heading bit for bit.
 * Portable: also runs on the QEMU Cortex-M4F target (little-endian there too, but the encoding
 * never depends on the host's byte order: it is written byte by byte). */
#include <math.h>
#include <string.h>

#include "magcal/calibrator.h"
#include "magcal/record.h"
#include "record_golden.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

/* The records of tools/golden/make_record_golden.py, as C values (dyadic, exact in binary32). */
static magcal_record_t rec2d(void)
{
    magcal_record_t r;
    memset(&r, 0, sizeof r);
    r.kind = MAGCAL_RECORD_KIND_2D;
    r.unit = MAGCAL_RECORD_UNIT_RAW;
    r.sensor_id = 0x11223344u;
    r.created = 1764547200u;
    r.n_used = 220u;
    r.est_heading_err_deg = 0.25f;
    r.radius = 0.234375f;
    r.residual_rms = 0.009765625f;
    r.coverage = 270.0f;
    r.cal2d.offset.x = 0.021484375f;
    r.cal2d.offset.y = 0.0390625f;
    r.cal2d.m[0][0] = 0.9921875f;
    r.cal2d.m[0][1] = 0.0625f;
    r.cal2d.m[1][0] = 0.0625f;
    r.cal2d.m[1][1] = 1.0078125f;
    r.cal2d.radius = 0.234375f;
    r.cal2d.magic = MAGCAL_CAL2D_MAGIC;
    return r;
}

static magcal_record_t rec3d(void)
{
    static const float g[3][3] = {{1.03125f, 0.015625f, -0.03125f},
                                  {0.015625f, 0.96875f, 0.0078125f},
                                  {-0.03125f, 0.0078125f, 1.0f}};
    magcal_record_t r;
    memset(&r, 0, sizeof r);
    r.kind = MAGCAL_RECORD_KIND_3D;
    r.unit = MAGCAL_RECORD_UNIT_UT;
    r.sensor_id = 0xA5A5F00Du;
    r.created = 1764547201u;
    r.n_used = 1500u;
    r.est_heading_err_deg = NAN;
    r.radius = 48.5f;
    r.residual_rms = 0.375f;
    r.coverage = 0.875f;
    memcpy(r.cal3d.g, g, sizeof g);
    r.cal3d.v.x = 12.5f;
    r.cal3d.v.y = -7.25f;
    r.cal3d.v.z = 30.125f;
    r.cal3d.field = 48.5f;
    return r;
}

static void put_u16(uint8_t *p, unsigned v)
{
    p[0] = (uint8_t)(v & 0xFFu);
    p[1] = (uint8_t)(v >> 8);
}

/* Recompute the CRC of a record edited on purpose (a writer of another layout, a faulty writer). */
static void reseal(uint8_t *b)
{
    uint32_t crc = magcal_record_crc32(b, MAGCAL_RECORD_LEN - 4u);
    b[92] = (uint8_t)(crc & 0xFFu);
    b[93] = (uint8_t)((crc >> 8) & 0xFFu);
    b[94] = (uint8_t)((crc >> 16) & 0xFFu);
    b[95] = (uint8_t)(crc >> 24);
}

static void test_record_crc32_check_value_matches_standard(void)
{
    static const uint8_t k_check[9] = {'1', '2', '3', '4', '5', '6', '7', '8', '9'};
    TEST_ASSERT_EQUAL_HEX32(0xCBF43926u, magcal_record_crc32(k_check, sizeof k_check));
    TEST_ASSERT_EQUAL_HEX32(0x00000000u, magcal_record_crc32(NULL, 0u));
}

static void test_record_len_macro_is_the_layout(void)
{
    TEST_ASSERT_EQUAL_UINT(96u, MAGCAL_RECORD_LEN);
    TEST_ASSERT_EQUAL_UINT(MAGCAL_RECORD_LEN, sizeof k_record_golden_2d);
}

static void test_record_pack_2d_matches_golden_little_endian_bytes(void)
{
    magcal_record_t r = rec2d();
    uint8_t b[MAGCAL_RECORD_LEN];
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_record_pack(&r, b, sizeof b));
    TEST_ASSERT_EQUAL_HEX8_ARRAY(k_record_golden_2d, b, MAGCAL_RECORD_LEN);
    /* spot checks of the documented layout: "MCRD", sensor id LE at 12, 1.0078125f at 60 */
    TEST_ASSERT_EQUAL_HEX8('M', b[0]);
    TEST_ASSERT_EQUAL_HEX8('D', b[3]);
    TEST_ASSERT_EQUAL_HEX8(0x44u, b[12]);
    TEST_ASSERT_EQUAL_HEX8(0x11u, b[15]);
    TEST_ASSERT_EQUAL_HEX8(0x3Fu, b[63]); /* 0x3F810000 */
    TEST_ASSERT_EQUAL_HEX8(0x81u, b[62]);
}

static void test_record_pack_3d_matches_golden_little_endian_bytes(void)
{
    magcal_record_t r = rec3d();
    uint8_t b[MAGCAL_RECORD_LEN];
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_record_pack(&r, b, sizeof b));
    TEST_ASSERT_EQUAL_HEX8_ARRAY(k_record_golden_3d, b, MAGCAL_RECORD_LEN);
}

static void test_record_unpack_golden_round_trip_exact(void)
{
    magcal_record_t want2 = rec2d();
    magcal_record_t want3 = rec3d();
    magcal_record_t got;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_record_unpack(k_record_golden_2d, MAGCAL_RECORD_LEN, &got));
    TEST_ASSERT_EQUAL_INT(MAGCAL_RECORD_KIND_2D, got.kind);
    TEST_ASSERT_EQUAL_HEX32(want2.sensor_id, got.sensor_id);
    TEST_ASSERT_EQUAL_UINT32(want2.created, got.created);
    TEST_ASSERT_EQUAL_UINT32(want2.n_used, got.n_used);
    TEST_ASSERT_EQUAL_MEMORY(&want2.cal2d, &got.cal2d, sizeof got.cal2d); /* bit-exact, magic set */
    TEST_ASSERT_TRUE(got.est_heading_err_deg == want2.est_heading_err_deg);
    TEST_ASSERT_TRUE(got.coverage == want2.coverage);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_record_unpack(k_record_golden_3d, MAGCAL_RECORD_LEN, &got));
    TEST_ASSERT_EQUAL_INT(MAGCAL_RECORD_KIND_3D, got.kind);
    TEST_ASSERT_EQUAL_INT(MAGCAL_RECORD_UNIT_UT, got.unit);
    TEST_ASSERT_EQUAL_MEMORY(&want3.cal3d, &got.cal3d, sizeof got.cal3d);
    TEST_ASSERT_TRUE(got.est_heading_err_deg != got.est_heading_err_deg); /* NaN: not estimated */
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_record_validate(k_record_golden_3d, MAGCAL_RECORD_LEN));
}

/* Every one of the 768 single-bit flips of a record is refused, and the output is untouched. */
static void check_every_bit_flip_refused(const uint8_t *golden)
{
    uint8_t b[MAGCAL_RECORD_LEN];
    magcal_record_t out;
    magcal_record_t sentinel;
    unsigned bit;
    unsigned n_crc = 0u;
    memset(&sentinel, 0x5A, sizeof sentinel);
    for (bit = 0u; bit < 8u * MAGCAL_RECORD_LEN; ++bit) {
        magcal_status_t st;
        memcpy(b, golden, sizeof b);
        b[bit / 8u] = (uint8_t)(b[bit / 8u] ^ (1u << (bit % 8u)));
        out = sentinel;
        st = magcal_record_unpack(b, sizeof b, &out);
        if (st == MAGCAL_OK) {
            TEST_FAIL_MESSAGE("a single-bit flip was accepted");
        }
        TEST_ASSERT_TRUE(st == MAGCAL_ERR_CRC || st == MAGCAL_ERR_VERSION);
        TEST_ASSERT_EQUAL_MEMORY(&sentinel, &out, sizeof out);
        n_crc += (st == MAGCAL_ERR_CRC) ? 1u : 0u;
    }
    /* header flips (magic, version, length: 64 bits) are VERSION; every other flip is CRC */
    TEST_ASSERT_EQUAL_UINT(8u * MAGCAL_RECORD_LEN - 64u, n_crc);
}

static void test_record_every_single_bit_flip_2d_refused(void) { check_every_bit_flip_refused(k_record_golden_2d); }

static void test_record_every_single_bit_flip_3d_refused(void) { check_every_bit_flip_refused(k_record_golden_3d); }

static void test_record_version_mismatch_refused(void)
{
    uint8_t b[MAGCAL_RECORD_LEN];
    magcal_record_t out;
    /* layout version 2 with a valid CRC: a record of another layout */
    memcpy(b, k_record_golden_2d, sizeof b);
    put_u16(b + 4, 2u);
    reseal(b);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_VERSION, magcal_record_unpack(b, sizeof b, &out));
    /* version 0, other length, other magic */
    put_u16(b + 4, 0u);
    reseal(b);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_VERSION, magcal_record_unpack(b, sizeof b, &out));
    memcpy(b, k_record_golden_3d, sizeof b);
    put_u16(b + 6, 128u);
    reseal(b);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_VERSION, magcal_record_unpack(b, sizeof b, &out));
    memcpy(b, k_record_golden_3d, sizeof b);
    b[0] = 'X';
    reseal(b);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_VERSION, magcal_record_unpack(b, sizeof b, &out));
    /* erased flash (0xFF) and zeroed flash */
    memset(b, 0xFF, sizeof b);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_VERSION, magcal_record_validate(b, sizeof b));
    memset(b, 0x00, sizeof b);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_VERSION, magcal_record_validate(b, sizeof b));
}

static void test_record_valid_crc_bad_contents_refused(void)
{
    uint8_t b[MAGCAL_RECORD_LEN];
    magcal_record_t r;
    /* a faulty writer: mirrored axis (m[1][1] = -1.0078125: det < 0) sealed with a valid CRC */
    memcpy(b, k_record_golden_2d, sizeof b);
    b[63] = 0xBFu;
    reseal(b);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_DEGENERATE, magcal_record_unpack(b, sizeof b, &r));
    /* unknown kind, unknown unit, non-zero reserved bytes, non-zero 2-D tail */
    memcpy(b, k_record_golden_2d, sizeof b);
    b[8] = 7u;
    reseal(b);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_record_unpack(b, sizeof b, &r));
    memcpy(b, k_record_golden_2d, sizeof b);
    b[9] = 9u;
    reseal(b);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_record_unpack(b, sizeof b, &r));
    memcpy(b, k_record_golden_2d, sizeof b);
    b[10] = 1u;
    reseal(b);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_record_unpack(b, sizeof b, &r));
    memcpy(b, k_record_golden_2d, sizeof b);
    b[80] = 1u;
    reseal(b);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_record_unpack(b, sizeof b, &r));
    /* 3-D: field NaN (0x7FC00000 at offset 88) */
    memcpy(b, k_record_golden_3d, sizeof b);
    b[88] = 0x00u;
    b[89] = 0x00u;
    b[90] = 0xC0u;
    b[91] = 0x7Fu;
    reseal(b);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_record_unpack(b, sizeof b, &r));
}

/* The 2-D record keeps the continuous calibrator's tilt compensation (record.h tilt_k,
 * tilt_levelled: offsets 68 and 72, formerly zero, so a record written before reads k 0): a round
 * trip is exact; a levelled flag without a k, a flag other than 0.0 / 1.0, a non-finite k and a
 * 3-D record with a k are refused; the golden record (zeros there) reads k 0, not levelled. */
static void test_record_2d_tilt_compensation_round_trip(void)
{
    uint8_t b[MAGCAL_RECORD_LEN];
    magcal_record_t r = rec2d();
    magcal_record_t back;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_record_unpack(k_record_golden_2d, sizeof k_record_golden_2d, &back));
    TEST_ASSERT_EQUAL_FLOAT(0.0f, back.tilt_k);
    TEST_ASSERT_EQUAL_UINT8(0u, back.tilt_levelled);
    r.tilt_k = -41.26902770996094f;
    r.tilt_levelled = 1u;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_record_pack(&r, b, sizeof b));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_record_unpack(b, sizeof b, &back));
    TEST_ASSERT_EQUAL_UINT32(0u, memcmp(&r.tilt_k, &back.tilt_k, sizeof r.tilt_k)); /* bit-exact */
    TEST_ASSERT_EQUAL_UINT8(1u, back.tilt_levelled);
    TEST_ASSERT_EQUAL_UINT8(0x3Fu, b[75]); /* 1.0f, little-endian, at offset 72 */
    TEST_ASSERT_EQUAL_UINT8(0x80u, b[74]);
    b[74] = 0x00u; /* the flag 0.5f: neither 0 nor 1 */
    b[75] = 0x3Fu;
    reseal(b);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_record_unpack(b, sizeof b, &back));
    r.tilt_k = 0.0f; /* levelled without a k */
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_record_pack(&r, b, sizeof b));
    r.tilt_k = INFINITY;
    r.tilt_levelled = 0u;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_record_pack(&r, b, sizeof b));
    r = rec3d();
    r.tilt_k = -40.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_record_pack(&r, b, sizeof b));
}

static void test_record_pack_bad_input_returns_status(void)
{
    uint8_t b[MAGCAL_RECORD_LEN];
    uint8_t before[MAGCAL_RECORD_LEN];
    magcal_record_t r = rec2d();
    memset(b, 0xEE, sizeof b);
    memcpy(before, b, sizeof b);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_record_pack(NULL, b, sizeof b));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_record_pack(&r, NULL, sizeof b));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_WORKSPACE, magcal_record_pack(&r, b, sizeof b - 1u));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_record_unpack(NULL, sizeof b, &r));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_WORKSPACE, magcal_record_unpack(k_record_golden_2d, 95u, &r));
    r.cal2d.radius = 0.0f; /* unknown radius: the adoption rule (c) needs it */
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_record_pack(&r, b, sizeof b));
    r = rec2d();
    r.cal2d.m[0][1] = NAN;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_record_pack(&r, b, sizeof b));
    r = rec2d();
    r.cal2d.magic = 0u;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NOT_INITIALISED, magcal_record_pack(&r, b, sizeof b));
    r = rec2d();
    r.coverage = 361.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_record_pack(&r, b, sizeof b));
    r = rec2d();
    r.est_heading_err_deg = INFINITY;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_record_pack(&r, b, sizeof b));
    r = rec2d();
    r.n_used = 0u;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_record_pack(&r, b, sizeof b));
    r = rec3d();
    r.cal3d.g[2][2] = -1.0f; /* mirrored z */
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_DEGENERATE, magcal_record_pack(&r, b, sizeof b));
    r = rec3d();
    r.coverage = 1.5f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_record_pack(&r, b, sizeof b));
    TEST_ASSERT_EQUAL_HEX8_ARRAY(before, b, sizeof b); /* nothing written on failure */
}

/* A real calibration (the calibrator on a synthetic ring with known hard and soft iron) stored and
 * restored gives the same heading bit for bit; the record of a non-adopting run is refused. */
#define CAP 128u
static magcal_calibrator_t g_cal;
static magcal_vec2_t g_buf[CAP];
static MAGCAL_CALIBRATOR_WORKSPACE_DECLARE(g_work, CAP);

static void test_record_from_report_restores_same_heading(void)
{
    magcal_calibrator_cfg_t cfg = MAGCAL_CALIBRATOR_CFG_DEFAULT;
    magcal_cal2d_t current = MAGCAL_CAL2D_IDENTITY;
    magcal_cal_report_t rep;
    magcal_record_t rec;
    magcal_record_t back;
    uint8_t b[MAGCAL_RECORD_LEN];
    unsigned i;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_init(&g_cal, &cfg, g_buf, CAP, g_work, sizeof g_work));
    for (i = 0u; i < 100u; ++i) {
        /* field 40 units, hard iron (12, -7), soft iron 1.2 x 0.9 rotated 30 deg; exact points */
        float t = 6.2831853f * (float)i / 100.0f;
        float u = 48.0f * cosf(t);
        float v = 36.0f * sinf(t);
        magcal_vec2_t p;
        p.x = 12.0f + 0.8660254f * u - 0.5f * v;
        p.y = -7.0f + 0.5f * u + 0.8660254f * v;
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_push(&g_cal, p));
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_run(&g_cal, &current, &rep));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_record_from_report(&rec, &rep, 0x0001001Eu, MAGCAL_RECORD_UNIT_RAW, 42u));
    TEST_ASSERT_FLOAT_WITHIN(0.5f, 41.57f, rec.radius); /* sqrt(48 * 36) */
    TEST_ASSERT_EQUAL_UINT32(100u, rec.n_used);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_record_pack(&rec, b, sizeof b));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_record_unpack(b, sizeof b, &back));
    TEST_ASSERT_EQUAL_MEMORY(&current, &back.cal2d, sizeof current);
    for (i = 0u; i < 36u; ++i) {
        float t = 6.2831853f * (float)i / 36.0f;
        magcal_vec2_t raw;
        float h0 = -1.0f;
        float h1 = -2.0f;
        raw.x = 12.0f + 0.8660254f * 48.0f * cosf(t) - 0.5f * 36.0f * sinf(t);
        raw.y = -7.0f + 0.5f * 48.0f * cosf(t) + 0.8660254f * 36.0f * sinf(t);
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_heading_compute(&current, raw, 0.0f, &h0, NULL));
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_heading_compute(&back.cal2d, raw, 0.0f, &h1, NULL));
        TEST_ASSERT_TRUE(h0 == h1);
    }
    rep.adopted = 0u;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_STATE, magcal_record_from_report(&rec, &rep, 1u, MAGCAL_RECORD_UNIT_RAW, 42u));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_record_from_report(NULL, &rep, 1u, MAGCAL_RECORD_UNIT_RAW, 42u));
}

static void test_record_from_ellipsoid_has_no_heading_estimate(void)
{
    magcal_ellipsoid_result_t res;
    magcal_record_t want = rec3d();
    magcal_record_t rec;
    uint8_t b[MAGCAL_RECORD_LEN];
    memset(&res, 0, sizeof res);
    res.cal = want.cal3d;
    res.residual_rms = want.residual_rms;
    res.coverage = want.coverage;
    res.n_used = want.n_used;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_record_from_ellipsoid(&rec, &res, want.sensor_id, MAGCAL_RECORD_UNIT_UT,
                                                                  want.created));
    TEST_ASSERT_TRUE(rec.est_heading_err_deg != rec.est_heading_err_deg);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_record_pack(&rec, b, sizeof b));
    TEST_ASSERT_EQUAL_HEX8_ARRAY(k_record_golden_3d, b, MAGCAL_RECORD_LEN);
    res.cal.field = 0.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_record_from_ellipsoid(&rec, &res, 1u, MAGCAL_RECORD_UNIT_UT, 1u));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_record_crc32_check_value_matches_standard);
    RUN_TEST(test_record_len_macro_is_the_layout);
    RUN_TEST(test_record_pack_2d_matches_golden_little_endian_bytes);
    RUN_TEST(test_record_pack_3d_matches_golden_little_endian_bytes);
    RUN_TEST(test_record_unpack_golden_round_trip_exact);
    RUN_TEST(test_record_every_single_bit_flip_2d_refused);
    RUN_TEST(test_record_every_single_bit_flip_3d_refused);
    RUN_TEST(test_record_version_mismatch_refused);
    RUN_TEST(test_record_valid_crc_bad_contents_refused);
    RUN_TEST(test_record_pack_bad_input_returns_status);
    RUN_TEST(test_record_2d_tilt_compensation_round_trip);
    RUN_TEST(test_record_from_report_restores_same_heading);
    RUN_TEST(test_record_from_ellipsoid_has_no_heading_estimate);
    return UNITY_END();
}
