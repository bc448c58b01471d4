/*
 * Tests of the 2-D correction and heading (algorithms.md 0, 1.1, 1.2, 2.4).
 * Conventions: x right, y forward; heading clockwise from north in [0, 360); a level field at
 * heading psi reads h = H0 (-sin psi, cos psi); declination east positive.
 */
#include <float.h>
#include <math.h>
#include <string.h>

#include <stdio.h>

#include "magcal/calibrator.h"
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
    /* the trust state agrees with the flags */
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_heading_get(&id, raw, 0.0f, &hd));
    TEST_ASSERT_EQUAL_UINT8(MAGCAL_TRUST_UNCALIBRATED, hd.trust);
    TEST_ASSERT_TRUE(hd.field_rel != hd.field_rel); /* NaN: no radius to compare with */
}

/* ---- heading trust ----------------------------------------------------------------------- */

#define TRUST_CAP 400u
#define TRUST_ROWS 6000u /* 120 s at 50 Hz */
static magcal_calibrator_t g_tcal;
static magcal_vec2_t g_tbuf[TRUST_CAP];
static uint32_t g_twork[(MAGCAL_CALIBRATOR_WORKSPACE_LEN(TRUST_CAP) + 3u) / 4u];

/* Known installation: radius 40 (uT), soft iron axis ratio about 0.8, hard iron (12, -7). */
static const test_distortion_t k_dist = {40.0f, {{1.05f, 0.12f}, {0.12f, 0.85f}}, 12.0f, -7.0f};

/* Calibrate k_dist from a full noisy ring with the calibrator (the residual it reports is the
 * one the trust thresholds are built from). */
static void calibrate_known(double sigma, uint32_t seed, magcal_cal2d_t *cal, magcal_cal_report_t *rep)
{
    magcal_calibrator_cfg_t cfg = MAGCAL_CALIBRATOR_CFG_DEFAULT;
    magcal_vec2_t pts[TRUST_CAP];
    magcal_cal2d_t cur = MAGCAL_CAL2D_IDENTITY;
    size_t i;
    cfg.min_spacing_deg = 0.0f;
    cfg.max_per_bin = 0u;
    test_make_ring(&k_dist, TRUST_CAP, 3.0, 360.0, sigma, seed, pts, NULL);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_init(&g_tcal, &cfg, g_tbuf, TRUST_CAP, g_twork,
                                                            sizeof g_twork));
    for (i = 0; i < TRUST_CAP; ++i) {
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_push(&g_tcal, pts[i]));
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_run(&g_tcal, &cur, rep));
    *cal = cur;
}

typedef struct {
    size_t dist_rows, dist_flagged, clean_rows, clean_flagged, ok_rows;
    double ok_err2; /* sum of squared heading errors of OK rows vs truth (constant offset removed) */
} trust_stats_t;

/*
 * A drive of TRUST_ROWS rows at 50 Hz with fresh noise (seed): heading turning at a varying rate,
 * four transient disturbances of 2, 3, 4 and 5 s where the field is 30 % stronger (a passing
 * truck), the rest clean. Every row is judged with `t` (NULL: generic band); counts by truth.
 */
static void drive_trust(const magcal_cal2d_t *cal, const magcal_trust_t *t, double sigma, uint32_t seed,
                        double gain, trust_stats_t *s)
{
    static const size_t d_start[4] = {700u, 1900u, 3300u, 4700u};
    static const size_t d_len[4] = {100u, 150u, 200u, 250u};
    test_distortion_t strong = k_dist;
    uint32_t rng = seed;
    double psi = 17.0;
    double offset = 0.0;
    size_t i;
    memset(s, 0, sizeof *s);
    strong.h0 = (float)(k_dist.h0 * gain);
    for (i = 0; i < TRUST_ROWS; ++i) {
        int disturbed = 0;
        size_t k;
        magcal_vec2_t raw;
        magcal_heading_t hd;
        for (k = 0; k < 4u; ++k) {
            disturbed |= (i >= d_start[k] && i < d_start[k] + d_len[k]);
        }
        psi += 0.6 * sin((double)i * 0.002) + 0.2; /* deg per row: straights and turns */
        raw = test_distorted_sample(disturbed ? &strong : &k_dist, psi, sigma, &rng);
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_heading_get_trusted(cal, t, raw, 0.0f, &hd));
        TEST_ASSERT_EQUAL_UINT8(magcal_trust_from_flags(hd.flags), hd.trust);
        if (disturbed) {
            s->dist_rows++;
            s->dist_flagged += (hd.trust == MAGCAL_TRUST_DISTURBED);
        } else {
            double e;
            s->clean_rows++;
            s->clean_flagged += (hd.trust != MAGCAL_TRUST_OK);
            if (hd.trust == MAGCAL_TRUST_OK) {
                /* the calibration's heading differs from the truth by a constant rotation
                 * (correction form): take it from the first OK row */
                e = test_angle_diff_deg(hd.magnetic_deg, fmod(psi, 360.0));
                if (s->ok_rows == 0u) {
                    offset = e;
                }
                e = test_angle_diff_deg(e, offset);
                s->ok_err2 += e * e;
                s->ok_rows++;
            }
        }
    }
}

/* The trust thresholds come from the calibration's own residual: a passing truck (+30 % field
 * for 2 to 5 s) is flagged on >= 90 % of its rows, clean noisy rows on <= 2 %, at two noise
 * levels (1 % and 3 % of the radius per axis). The OK rows keep the calibration's accuracy. */
static void test_heading_get_trusted_truck_flagged_clean_passes(void)
{
    static const double sigmas[2] = {0.4, 1.2};
    size_t j;
    for (j = 0; j < 2u; ++j) {
        magcal_cal2d_t cal;
        magcal_cal_report_t rep;
        magcal_trust_cfg_t tc = MAGCAL_TRUST_CFG_DEFAULT;
        magcal_trust_t t;
        trust_stats_t s;
        double recall, false_rate, rms;
        char msg[160];
        calibrate_known(sigmas[j], 101u + (uint32_t)j, &cal, &rep);
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_trust_init(&t, &tc, rep.residual_rel));
        drive_trust(&cal, &t, sigmas[j], 9001u + (uint32_t)j, 1.3, &s);
        recall = (double)s.dist_flagged / (double)s.dist_rows;
        false_rate = (double)s.clean_flagged / (double)s.clean_rows;
        rms = sqrt(s.ok_err2 / (double)s.ok_rows);
        snprintf(msg, sizeof msg,
                 "sigma %.1f: residual_rel %.4f tol_rel %.4f recall %.4f (%u/%u) false %.4f (%u/%u) "
                 "OK rms %.3f deg",
                 sigmas[j], (double)rep.residual_rel, (double)t.tol_rel, recall,
                 (unsigned)s.dist_flagged, (unsigned)s.dist_rows, false_rate,
                 (unsigned)s.clean_flagged, (unsigned)s.clean_rows, rms);
        printf("%s\n", msg);
        TEST_ASSERT_TRUE_MESSAGE(recall >= 0.90, msg);
        TEST_ASSERT_TRUE_MESSAGE(false_rate <= 0.02, msg);
        /* tolerance = k x residual (the residual estimates the per-axis noise over R) */
        TEST_ASSERT_FLOAT_WITHIN(0.25f * (float)(sigmas[j] / 40.0), (float)(sigmas[j] / 40.0),
                                 rep.residual_rel);
        TEST_ASSERT_FLOAT_WITHIN(1e-6f, fmaxf(3.0f * rep.residual_rel, 0.01f), t.tol_rel);
        /* trusted rows are accurate: noise sigma/R rad ~ 0.6 / 1.7 deg RMS, well below 3x */
        TEST_ASSERT_TRUE_MESSAGE(rms < 3.0 * (sigmas[j] / 40.0) * 57.2958, msg);
    }
}

/* A disturbance inside the tolerance (+1 % field, below k x residual) is not flagged: the
 * detector measures magnitude, so a stronger disturbance is needed to be seen. The recall rises
 * with the disturbance: >= 90 % from +10 % at 1 % noise. */
static void test_heading_get_trusted_small_disturbance_below_tolerance(void)
{
    magcal_cal2d_t cal;
    magcal_cal_report_t rep;
    magcal_trust_cfg_t tc = MAGCAL_TRUST_CFG_DEFAULT;
    magcal_trust_t t;
    trust_stats_t s;
    calibrate_known(0.4, 101u, &cal, &rep);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_trust_init(&t, &tc, rep.residual_rel));
    drive_trust(&cal, &t, 0.4, 77u, 1.01, &s);
    TEST_ASSERT_TRUE((double)s.dist_flagged / (double)s.dist_rows < 0.05);
    drive_trust(&cal, &t, 0.4, 78u, 1.10, &s);
    TEST_ASSERT_TRUE((double)s.dist_flagged / (double)s.dist_rows >= 0.90);
    drive_trust(&cal, &t, 0.4, 79u, 0.80, &s); /* a weaker field (shielding) is flagged too */
    TEST_ASSERT_TRUE((double)s.dist_flagged / (double)s.dist_rows >= 0.90);
}

/* Without a context (magcal_heading_get), the generic 15 % band: +30 % flagged, clean passes. */
static void test_heading_get_generic_band_flags_truck(void)
{
    magcal_cal2d_t cal;
    magcal_cal_report_t rep;
    trust_stats_t s;
    calibrate_known(0.4, 101u, &cal, &rep);
    drive_trust(&cal, NULL, 0.4, 9001u, 1.3, &s);
    TEST_ASSERT_TRUE((double)s.dist_flagged / (double)s.dist_rows >= 0.90);
    TEST_ASSERT_EQUAL_UINT(0u, (unsigned)s.clean_flagged); /* 15 % is 15 sigma here */
}

/* CHANGED is set and cleared by the context's owner, and wins over DISTURBED; UNCALIBRATED wins
 * over everything. */
static void test_trust_set_changed_marks_every_heading(void)
{
    magcal_cal2d_t cal;
    magcal_cal2d_t id = MAGCAL_CAL2D_IDENTITY;
    magcal_cal_report_t rep;
    magcal_trust_cfg_t tc = MAGCAL_TRUST_CFG_DEFAULT;
    magcal_trust_t t;
    magcal_heading_t hd;
    test_distortion_t strong = k_dist;
    uint32_t rng = 5u;
    magcal_vec2_t clean, loud;
    calibrate_known(0.4, 101u, &cal, &rep);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_trust_init(&t, &tc, rep.residual_rel));
    strong.h0 = 52.0f;
    clean = test_distorted_sample(&k_dist, 40.0, 0.0, &rng);
    loud = test_distorted_sample(&strong, 40.0, 0.0, &rng);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_heading_get_trusted(&cal, &t, clean, 0.0f, &hd));
    TEST_ASSERT_EQUAL_UINT8(MAGCAL_TRUST_OK, hd.trust);
    TEST_ASSERT_EQUAL_UINT8(0u, hd.flags);
    TEST_ASSERT_FLOAT_WITHIN(0.01f, 1.0f, hd.field_rel);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_heading_get_trusted(&cal, &t, loud, 0.0f, &hd));
    TEST_ASSERT_EQUAL_UINT8(MAGCAL_TRUST_DISTURBED, hd.trust);
    TEST_ASSERT_FLOAT_WITHIN(0.01f, 1.3f, hd.field_rel);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_trust_set_changed(&t, 1u));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_heading_get_trusted(&cal, &t, clean, 0.0f, &hd));
    TEST_ASSERT_EQUAL_UINT8(MAGCAL_TRUST_CHANGED, hd.trust);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_heading_get_trusted(&cal, &t, loud, 0.0f, &hd));
    TEST_ASSERT_EQUAL_UINT8(MAGCAL_TRUST_CHANGED, hd.trust);
    TEST_ASSERT_EQUAL_UINT8(MAGCAL_HEADING_FLAG_CHANGED | MAGCAL_HEADING_FLAG_DISTURBED, hd.flags);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_heading_get_trusted(&id, &t, clean, 0.0f, &hd));
    TEST_ASSERT_EQUAL_UINT8(MAGCAL_TRUST_UNCALIBRATED, hd.trust);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_trust_set_changed(&t, 0u));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_heading_get_trusted(&cal, &t, clean, 0.0f, &hd));
    TEST_ASSERT_EQUAL_UINT8(MAGCAL_TRUST_OK, hd.trust);
    TEST_ASSERT_EQUAL_STRING("ok", magcal_trust_str(MAGCAL_TRUST_OK));
    TEST_ASSERT_EQUAL_STRING("uncalibrated", magcal_trust_str(MAGCAL_TRUST_UNCALIBRATED));
    TEST_ASSERT_EQUAL_STRING("disturbed", magcal_trust_str(MAGCAL_TRUST_DISTURBED));
    TEST_ASSERT_EQUAL_STRING("changed", magcal_trust_str(MAGCAL_TRUST_CHANGED));
    TEST_ASSERT_EQUAL_STRING("unknown", magcal_trust_str((magcal_trust_state_t)9));
    /* |h| / R beyond float: +Inf and DISTURBED, never a clamped ratio that reads plausible */
    cal = id;
    cal.radius = 1e-30f;
    loud.x = 1e30f;
    loud.y = 2e30f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_heading_get_trusted(&cal, &t, loud, 0.0f, &hd));
    TEST_ASSERT_EQUAL_UINT8(MAGCAL_TRUST_DISTURBED, hd.trust);
    TEST_ASSERT_TRUE(isinf(hd.field_rel) && hd.field_rel > 0.0f);
}

static void test_trust_init_bad_input_returns_status(void)
{
    magcal_trust_cfg_t tc = MAGCAL_TRUST_CFG_DEFAULT;
    magcal_trust_t t;
    magcal_trust_t keep;
    uint8_t f = 0xFFu;
    memset(&t, 0, sizeof t);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NOT_INITIALISED, magcal_trust_set_changed(&t, 1u));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NOT_INITIALISED, magcal_trust_judge(&t, 1.0f, NAN, &f));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_trust_init(NULL, &tc, 0.01f));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_trust_init(&t, NULL, 0.01f));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_trust_init(&t, &tc, -0.01f));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_trust_init(&t, &tc, NAN));
    tc.k = 0.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_trust_init(&t, &tc, 0.01f));
    tc.k = 3.0f;
    tc.floor_rel = 1.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_trust_init(&t, &tc, 0.01f));
    tc.floor_rel = 0.01f;
    tc.incl_floor_deg = 91.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_trust_init(&t, &tc, 0.01f));
    tc.incl_floor_deg = 5.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_trust_init(&t, &tc, 0.02f));
    TEST_ASSERT_FLOAT_WITHIN(1e-7f, 0.06f, t.tol_rel);
    TEST_ASSERT_FLOAT_WITHIN(1e-4f, 5.0f, t.incl_tol_deg); /* 0.06 rad = 3.4 deg < floor */
    keep = t;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_trust_set_changed(&t, 2u));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_trust_set_inclination(&t, 91.0f));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_trust_set_inclination(&t, NAN));
    TEST_ASSERT_EQUAL_MEMORY(&keep, &t, sizeof t);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_trust_judge(&t, 1.0f, NAN, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_trust_judge(&t, -1.0f, NAN, &f));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_trust_judge(&t, INFINITY, NAN, &f));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_trust_judge(&t, 1.0f, INFINITY, &f));
    TEST_ASSERT_EQUAL_UINT8(0xFFu, f);
    /* the boundary: exactly inside passes, just outside is disturbed */
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_trust_judge(&t, 1.059f, NAN, &f));
    TEST_ASSERT_EQUAL_UINT8(0u, f);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_trust_judge(&t, 0.939f, NAN, &f));
    TEST_ASSERT_EQUAL_UINT8(MAGCAL_HEADING_FLAG_DISTURBED, f);
    /* inclination is checked only once an expected one is set, and only when measured */
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_trust_judge(&t, 1.0f, 40.0f, &f));
    TEST_ASSERT_EQUAL_UINT8(0u, f);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_trust_set_inclination(&t, 60.0f));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_trust_judge(&t, 1.0f, 54.9f, &f));
    TEST_ASSERT_EQUAL_UINT8(MAGCAL_HEADING_FLAG_DISTURBED, f);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_trust_judge(&t, 1.0f, 64.0f, &f));
    TEST_ASSERT_EQUAL_UINT8(0u, f);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_trust_judge(&t, 1.0f, NAN, &f));
    TEST_ASSERT_EQUAL_UINT8(0u, f);
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
    RUN_TEST(test_heading_get_trusted_truck_flagged_clean_passes);
    RUN_TEST(test_heading_get_trusted_small_disturbance_below_tolerance);
    RUN_TEST(test_heading_get_generic_band_flags_truck);
    RUN_TEST(test_trust_set_changed_marks_every_heading);
    RUN_TEST(test_trust_init_bad_input_returns_status);
    return UNITY_END();
}
