/*
 * Tests of the 2-D correction and heading (algorithms.md 0, 1.1, 1.2, 2.4).
 * Conventions: x right, y forward; heading clockwise from north in [0, 360); a level field at
 * heading psi reads h = H0 (-sin psi, cos psi); declination east positive.
 */
#include <float.h>
#include <math.h>
#include <string.h>

#include "magcal/heading.h"
#include "test_util.h"
#include "unity.h"

#define PI_D 3.14159265358979323846

void setUp(void) {}
void tearDown(void) {}

static magcal_vec2_t field_at(double psi_deg, double h0)
{
    magcal_vec2_t h;
    h.x = (float)(-h0 * sin(psi_deg * PI_D / 180.0));
    h.y = (float)(h0 * cos(psi_deg * PI_D / 180.0));
    return h;
}

static void test_heading_from_field_eight_compass_points(void)
{
    /* N, NE, E, SE, S, SW, W, NW; facing east the field points out of the left side (x < 0). */
    static const float expect[8] = {0.0f, 45.0f, 90.0f, 135.0f, 180.0f, 225.0f, 270.0f, 315.0f};
    size_t i;
    for (i = 0; i < 8; ++i) {
        float deg = -1.0f;
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK,
                              magcal_heading_from_field(field_at(45.0 * (double)i, 20.0), &deg));
        TEST_ASSERT_FLOAT_WITHIN(1e-4f, expect[i], deg);
    }
    {
        magcal_vec2_t east = {-1.0f, 0.0f};
        float deg = -1.0f;
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_heading_from_field(east, &deg));
        TEST_ASSERT_FLOAT_WITHIN(1e-5f, 90.0f, deg);
    }
}

static void test_heading_from_field_all_headings_match_truth(void)
{
    /* 0.1 deg steps over the full circle, any scale: error below 1e-3 deg (float32 atan2). */
    size_t i;
    for (i = 0; i < 3600; ++i) {
        double psi = 0.1 * (double)i;
        float deg;
        TEST_ASSERT_EQUAL_INT(
            MAGCAL_OK, magcal_heading_from_field(field_at(psi, i % 2u ? 0.5 : 30000.0), &deg));
        TEST_ASSERT_TRUE(deg >= 0.0f && deg < 360.0f);
        TEST_ASSERT_FLOAT_WITHIN(1e-3f, 0.0f, (float)test_angle_diff_deg(deg, psi));
    }
}

static void test_heading_from_field_wraps_to_half_open_range(void)
{
    magcal_vec2_t h;
    float deg = -1.0f;
    /* just west of north: atan2 gives -tiny, and -tiny + 360 rounds to 360.0f: must read 0 */
    h.x = 1e-9f;
    h.y = 1.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_heading_from_field(h, &deg));
    TEST_ASSERT_TRUE(deg < 360.0f);
    TEST_ASSERT_EQUAL_FLOAT(0.0f, deg);
    /* -0 in x: +0 out, never -0 */
    h.x = -0.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_heading_from_field(h, &deg));
    TEST_ASSERT_TRUE(1.0f / deg > 0.0f);
    /* a resolvable angle just below 360 stays just below 360 */
    h.x = 1e-3f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_heading_from_field(h, &deg));
    TEST_ASSERT_FLOAT_WITHIN(1e-4f, 359.94270f, deg);
    /* due south from both sides of the branch cut */
    h.x = 0.0f;
    h.y = -1.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_heading_from_field(h, &deg));
    TEST_ASSERT_FLOAT_WITHIN(1e-4f, 180.0f, deg);
    h.x = -0.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_heading_from_field(h, &deg));
    TEST_ASSERT_FLOAT_WITHIN(1e-4f, 180.0f, deg);
}

static void test_heading_from_field_bad_input_returns_status(void)
{
    magcal_vec2_t h = {0.0f, 0.0f};
    float deg = 123.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ZERO_FIELD, magcal_heading_from_field(h, &deg));
    h.x = 1e-30f; /* |h|^2 underflows: no direction */
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ZERO_FIELD, magcal_heading_from_field(h, &deg));
    h.x = 1e-15f; /* tiny but resolvable: a unit problem, not ours */
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_heading_from_field(h, &deg));
    TEST_ASSERT_FLOAT_WITHIN(1e-4f, 270.0f, deg);
    h.x = 3e38f; /* huge is fine */
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_heading_from_field(h, &deg));
    deg = 123.0f;
    h.x = NAN;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_heading_from_field(h, &deg));
    h.x = 0.0f;
    h.y = -INFINITY;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_heading_from_field(h, &deg));
    TEST_ASSERT_EQUAL_FLOAT(123.0f, deg); /* untouched on failure */
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_heading_from_field(h, NULL));
}

static void test_cal2d_validate_identity_and_corruptions(void)
{
    magcal_cal2d_t id = MAGCAL_CAL2D_IDENTITY;
    magcal_cal2d_t c;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cal2d_validate(&id));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_cal2d_validate(NULL));
    TEST_ASSERT_EQUAL_UINT(32u, (unsigned)sizeof(magcal_cal2d_t)); /* flash layout: 8 floats */
    memset(&c, 0xFF, sizeof c);                                    /* erased flash */
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NOT_INITIALISED, magcal_cal2d_validate(&c));
    memset(&c, 0, sizeof c);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NOT_INITIALISED, magcal_cal2d_validate(&c));
    c = id;
    c.m[1][1] = -1.0f; /* mirrored y axis: heading would run backwards */
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_DEGENERATE, magcal_cal2d_validate(&c));
    c = id;
    c.m[0][0] = 0.0f; /* singular */
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_DEGENERATE, magcal_cal2d_validate(&c));
    c = id;
    c.offset.y = NAN;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_cal2d_validate(&c));
    c = id;
    c.radius = -1.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_cal2d_validate(&c));
}

static void test_correct_apply_computes_m_times_raw_minus_offset(void)
{
    magcal_cal2d_t c = MAGCAL_CAL2D_IDENTITY;
    magcal_vec2_t raw = {110.0f, -40.0f};
    magcal_vec2_t h = {7.0f, 7.0f};
    c.offset.x = 100.0f;
    c.offset.y = -50.0f;
    c.m[0][0] = 2.0f;
    c.m[0][1] = 0.5f;
    c.m[1][0] = -0.25f;
    c.m[1][1] = 1.5f;
    /* u = (10, 10): h = (2*10 + 0.5*10, -0.25*10 + 1.5*10) = (25, 12.5) */
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_correct_apply(&c, raw, &h));
    TEST_ASSERT_FLOAT_WITHIN(1e-5f, 25.0f, h.x);
    TEST_ASSERT_FLOAT_WITHIN(1e-5f, 12.5f, h.y);
    raw.x = INFINITY;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_correct_apply(&c, raw, &h));
    TEST_ASSERT_FLOAT_WITHIN(1e-5f, 25.0f, h.x); /* untouched */
    raw.x = 3e38f;                               /* overflow of M u */
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_correct_apply(&c, raw, &h));
    c.magic = 0u;
    raw.x = 0.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NOT_INITIALISED, magcal_correct_apply(&c, raw, &h));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_correct_apply(NULL, raw, &h));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_correct_apply(&c, raw, NULL));
}

static void test_heading_compute_inverse_distortion_recovers_truth(void)
{
    /* Calibration = exact inverse of a known distortion Hm = T H + b: heading equals truth. */
    test_distortion_t d;
    magcal_cal2d_t c = MAGCAL_CAL2D_IDENTITY;
    double det;
    size_t i;
    d.h0 = 250.0f;
    d.t[0][0] = 1.2f;
    d.t[0][1] = 0.15f;
    d.t[1][0] = -0.05f;
    d.t[1][1] = 0.85f;
    d.bx = -3000.0f;
    d.by = 1200.0f;
    det = (double)d.t[0][0] * d.t[1][1] - (double)d.t[0][1] * d.t[1][0];
    c.offset.x = d.bx;
    c.offset.y = d.by;
    c.m[0][0] = (float)(d.t[1][1] / det);
    c.m[0][1] = (float)(-d.t[0][1] / det);
    c.m[1][0] = (float)(-d.t[1][0] / det);
    c.m[1][1] = (float)(d.t[0][0] / det);
    c.radius = 250.0f;
    for (i = 0; i < 72; ++i) {
        uint32_t rng = 1u;
        double psi = 5.0 * (double)i + 0.37;
        magcal_vec2_t raw = test_distorted_sample(&d, psi, 0.0, &rng);
        float mag, tru;
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_heading_compute(&c, raw, 0.0f, &mag, &tru));
        TEST_ASSERT_FLOAT_WITHIN(2e-3f, 0.0f, (float)test_angle_diff_deg(mag, psi));
        TEST_ASSERT_EQUAL_FLOAT(mag, tru);
    }
}

static void test_heading_compute_declination_gives_true_heading(void)
{
    magcal_cal2d_t c = MAGCAL_CAL2D_IDENTITY;
    float mag = -1.0f, tru = -1.0f;
    /* magnetic 350 + 15 east = 5; magnetic 10 - 15 (west) = 355; exact 180 stays 180 */
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK,
                          magcal_heading_compute(&c, field_at(350.0, 1.0), 15.0f, &mag, &tru));
    TEST_ASSERT_FLOAT_WITHIN(1e-4f, 350.0f, mag);
    TEST_ASSERT_FLOAT_WITHIN(1e-4f, 5.0f, tru);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK,
                          magcal_heading_compute(&c, field_at(10.0, 1.0), -15.0f, &mag, &tru));
    TEST_ASSERT_FLOAT_WITHIN(1e-4f, 10.0f, mag);
    TEST_ASSERT_FLOAT_WITHIN(1e-4f, 355.0f, tru);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK,
                          magcal_heading_compute(&c, field_at(90.0, 1.0), 90.0f, &mag, &tru));
    TEST_ASSERT_FLOAT_WITHIN(1e-4f, 180.0f, tru);
    /* magnetic 0 + declination 0 -> 0; -180 and +180 declinations both give 180 from north */
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK,
                          magcal_heading_compute(&c, field_at(0.0, 1.0), -180.0f, &mag, &tru));
    TEST_ASSERT_FLOAT_WITHIN(1e-4f, 180.0f, tru);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK,
                          magcal_heading_compute(&c, field_at(180.0, 1.0), 180.0f, &mag, &tru));
    TEST_ASSERT_TRUE(tru >= 0.0f && tru < 360.0f);
    TEST_ASSERT_FLOAT_WITHIN(1e-4f, 0.0f, (float)test_angle_diff_deg(tru, 0.0));
    /* a sum that rounds to 360 reads 0: magnetic 0, declination -1e-6 (and +tiny west of north) */
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK,
                          magcal_heading_compute(&c, field_at(0.0, 1.0), -1e-6f, &mag, &tru));
    TEST_ASSERT_TRUE(tru >= 0.0f && tru < 360.0f);
    TEST_ASSERT_FLOAT_WITHIN(1e-4f, 0.0f, (float)test_angle_diff_deg(tru, 0.0));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK,
                          magcal_heading_compute(&c, field_at(359.99999, 1.0), 1e-6f, &mag, &tru));
    TEST_ASSERT_TRUE(tru >= 0.0f && tru < 360.0f);
    TEST_ASSERT_FLOAT_WITHIN(1e-4f, 0.0f, (float)test_angle_diff_deg(tru, 0.0));
    /* true_deg is optional */
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK,
                          magcal_heading_compute(&c, field_at(33.0, 1.0), 5.0f, &mag, NULL));
    TEST_ASSERT_FLOAT_WITHIN(1e-4f, 33.0f, mag);
}

static void test_heading_compute_true_heading_in_half_open_range(void)
{
    /* Sweep magnetic heading and declination: true heading always in [0, 360) and correct. */
    magcal_cal2d_t c = MAGCAL_CAL2D_IDENTITY;
    int i, j;
    for (i = 0; i < 360; i += 7) {
        for (j = -180; j <= 180; j += 15) {
            float mag, tru;
            TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_heading_compute(&c, field_at((double)i, 40.0),
                                                                    (float)j, &mag, &tru));
            TEST_ASSERT_TRUE(tru >= 0.0f && tru < 360.0f);
            TEST_ASSERT_FLOAT_WITHIN(1e-3f, 0.0f, (float)test_angle_diff_deg(tru, (double)(i + j)));
        }
    }
}

static void test_heading_compute_bad_input_returns_status(void)
{
    magcal_cal2d_t c = MAGCAL_CAL2D_IDENTITY;
    magcal_vec2_t raw = {0.0f, 1.0f};
    float mag = 77.0f, tru = 77.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_heading_compute(NULL, raw, 0.0f, &mag, &tru));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_heading_compute(&c, raw, 0.0f, NULL, &tru));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_heading_compute(&c, raw, NAN, &mag, &tru));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_heading_compute(&c, raw, 181.0f, &mag, &tru));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_heading_compute(&c, raw, -180.5f, &mag, &tru));
    raw.y = NAN;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_heading_compute(&c, raw, 0.0f, &mag, &tru));
    /* raw exactly at the offset: zero field */
    raw.x = 0.0f;
    raw.y = 0.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ZERO_FIELD, magcal_heading_compute(&c, raw, 0.0f, &mag, &tru));
    /* known radius: a field of 1e-4 of it is "zero"; 1e-2 of it is not */
    c.radius = 100.0f;
    raw.y = 0.01f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ZERO_FIELD, magcal_heading_compute(&c, raw, 0.0f, &mag, &tru));
    raw.y = 1.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_heading_compute(&c, raw, 0.0f, &mag, &tru));
    TEST_ASSERT_FLOAT_WITHIN(1e-5f, 0.0f, mag);
    mag = 77.0f;
    tru = 77.0f;
    c.m[0][0] = -1.0f; /* mirrored: rejected */
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_DEGENERATE, magcal_heading_compute(&c, raw, 0.0f, &mag, &tru));
    TEST_ASSERT_EQUAL_FLOAT(77.0f, mag);
    TEST_ASSERT_EQUAL_FLOAT(77.0f, tru);
}

/* magcal_heading_get: the same heading as magcal_heading_compute, and a flag that tells a heading
 * from an unfitted calibration (radius 0: MAGCAL_CAL2D_IDENTITY) from a calibrated one. */
static void test_heading_get_flags_uncalibrated_identity(void)
{
    magcal_cal2d_t id = MAGCAL_CAL2D_IDENTITY;
    magcal_cal2d_t c = MAGCAL_CAL2D_IDENTITY;
    magcal_heading_t hd;
    magcal_heading_t keep;
    float mag, tru;
    magcal_vec2_t raw = field_at(123.0, 30.0);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_heading_get(&id, raw, 10.0f, &hd));
    TEST_ASSERT_EQUAL_UINT8(MAGCAL_HEADING_FLAG_UNCALIBRATED, hd.flags);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_heading_compute(&id, raw, 10.0f, &mag, &tru));
    TEST_ASSERT_EQUAL_FLOAT(mag, hd.magnetic_deg);
    TEST_ASSERT_EQUAL_FLOAT(tru, hd.true_deg);
    TEST_ASSERT_FLOAT_WITHIN(1e-3f, 123.0f, hd.magnetic_deg);
    TEST_ASSERT_FLOAT_WITHIN(1e-3f, 133.0f, hd.true_deg);
    /* a fitted calibration states its radius: no flag */
    c.offset.x = 2.0f;
    c.radius = 30.0f;
    raw.x += 2.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_heading_get(&c, raw, -5.0f, &hd));
    TEST_ASSERT_EQUAL_UINT8(0u, hd.flags);
    TEST_ASSERT_FLOAT_WITHIN(1e-3f, 123.0f, hd.magnetic_deg);
    TEST_ASSERT_FLOAT_WITHIN(1e-3f, 118.0f, hd.true_deg);
    /* failures: a status, the result untouched */
    keep = hd;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_heading_get(&c, raw, 0.0f, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_heading_get(NULL, raw, 0.0f, &hd));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_heading_get(&c, raw, 200.0f, &hd));
    c.magic = 0u;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NOT_INITIALISED, magcal_heading_get(&c, raw, 0.0f, &hd));
    TEST_ASSERT_EQUAL_FLOAT(keep.magnetic_deg, hd.magnetic_deg);
    TEST_ASSERT_EQUAL_FLOAT(keep.true_deg, hd.true_deg);
    TEST_ASSERT_EQUAL_UINT8(keep.flags, hd.flags);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_heading_from_field_eight_compass_points);
    RUN_TEST(test_heading_from_field_all_headings_match_truth);
    RUN_TEST(test_heading_from_field_wraps_to_half_open_range);
    RUN_TEST(test_heading_from_field_bad_input_returns_status);
    RUN_TEST(test_cal2d_validate_identity_and_corruptions);
    RUN_TEST(test_correct_apply_computes_m_times_raw_minus_offset);
    RUN_TEST(test_heading_compute_inverse_distortion_recovers_truth);
    RUN_TEST(test_heading_compute_declination_gives_true_heading);
    RUN_TEST(test_heading_compute_true_heading_in_half_open_range);
    RUN_TEST(test_heading_compute_bad_input_returns_status);
    RUN_TEST(test_heading_get_flags_uncalibrated_identity);
    return UNITY_END();
}
