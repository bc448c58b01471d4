/*
 * Bad-input tests of the library (docs/reliability.md "Bad input table"): the rows that no
 * module test covers. Each test asserts the specific status and, for the calibrator, that the
 * caller's previous calibration is bit-identical after a failure. Extreme magnitudes (near
 * FLT_MAX, subnormal) are exercised with exact synthetic rings whose truth is known.
 */
#include <float.h>
#include <math.h>
#include <string.h>

#include "magcal/calibrator.h"
#include "magcal/dbscan.h"
#include "magcal/ellipse.h"
#include "magcal/heading.h"
#include "magcal/optics.h"
#include "magcal_port_fake.h"
#include "test_util.h"
#include "unity.h"

#define CAP MAGCAL_MAX_SAMPLES

static magcal_calibrator_t g_cal;
static magcal_vec2_t g_buf[CAP];
static uint32_t g_work[(MAGCAL_CALIBRATOR_WORKSPACE_LEN(CAP) + 3u) / 4u];
static magcal_vec2_t g_pts[CAP];

void setUp(void) {}
void tearDown(void) {}

/* A usable stored calibration the failing runs must leave bit-identical. */
static magcal_cal2d_t previous_cal(void)
{
    magcal_cal2d_t c = MAGCAL_CAL2D_IDENTITY;
    c.offset.x = 12.5f;
    c.offset.y = -7.25f;
    c.m[0][0] = 1.1f;
    c.m[0][1] = 0.05f;
    c.m[1][0] = 0.05f;
    c.m[1][1] = 0.9f;
    c.radius = 40.0f;
    return c;
}

/* Exact axis-aligned ellipse: centre (cx, cy), semi-axes a (x) and b (y), n samples over 360 deg.
 * Sample i sits at parameter t = 2 pi i / n; its true heading after whitening is
 * atan2(-cos t, sin t) (the whitened field is proportional to (cos t, sin t)). */
static void exact_ring(size_t n, float cx, float cy, float a, float b)
{
    size_t i;
    for (i = 0; i < n; ++i) {
        double t = 2.0 * 3.14159265358979323846 * (double)i / (double)n;
        g_pts[i].x = cx + (float)((double)a * cos(t));
        g_pts[i].y = cy + (float)((double)b * sin(t));
    }
}

static double true_heading_deg(size_t i, size_t n)
{
    double t = 2.0 * 3.14159265358979323846 * (double)i / (double)n;
    double h = atan2(-cos(t), sin(t)) * 57.29577951308232;
    return h < 0.0 ? h + 360.0 : h;
}

static void init_default(size_t cap)
{
    magcal_calibrator_cfg_t cfg = MAGCAL_CALIBRATOR_CFG_DEFAULT;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_init(&g_cal, &cfg, g_buf, cap, g_work, sizeof g_work));
}

static void push_all(size_t n)
{
    size_t i;
    for (i = 0; i < n; ++i) {
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_push(&g_cal, g_pts[i]));
    }
}

/* Run on g_pts[0..n) and expect `want`; a failure must leave the previous calibration intact. */
static void expect_run_status_keeps_cal(size_t n, magcal_status_t want)
{
    magcal_cal2d_t cur = previous_cal();
    magcal_cal2d_t before = cur;
    magcal_cal_report_t rep;
    init_default(CAP);
    push_all(n);
    TEST_ASSERT_EQUAL_INT(want, magcal_calibrator_run(&g_cal, &cur, &rep));
    TEST_ASSERT_EQUAL_INT(want, rep.status);
    TEST_ASSERT_EQUAL_UINT8(0u, rep.adopted);
    TEST_ASSERT_EQUAL_MEMORY(&before, &cur, sizeof cur);
    TEST_ASSERT_EQUAL_INT(MAGCAL_CALIBRATOR_FAILED, magcal_calibrator_state(&g_cal));
}

/* Adopted calibration on an exact ring: centre, radius and every heading against the truth. */
static void expect_exact_ring_calibrates(size_t n, float cx, float cy, float a, float b, float out_radius)
{
    magcal_calibrator_cfg_t cfg = MAGCAL_CALIBRATOR_CFG_DEFAULT;
    magcal_cal2d_t cur = MAGCAL_CAL2D_IDENTITY;
    magcal_cal_report_t rep;
    double r_true = sqrt((double)a * (double)b);
    double worst = 0.0;
    double offset_deg;
    size_t i;
    exact_ring(n, cx, cy, a, b);
    cfg.output_radius = out_radius;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_init(&g_cal, &cfg, g_buf, CAP, g_work, sizeof g_work));
    push_all(n);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_run(&g_cal, &cur, &rep));
    /* centre within 1e-4 R, radius within 1e-4 relative (float32 on exact data: ~1e-6) */
    TEST_ASSERT_TRUE(fabs((double)cur.offset.x - (double)cx) <= 1e-4 * r_true);
    TEST_ASSERT_TRUE(fabs((double)cur.offset.y - (double)cy) <= 1e-4 * r_true);
    TEST_ASSERT_TRUE(fabs((double)rep.radius / r_true - 1.0) <= 1e-4);
    if (out_radius > 0.0f) {
        TEST_ASSERT_EQUAL_FLOAT(out_radius, cur.radius);
    }
    /* headings: the symmetric form of an axis-aligned ellipse adds no rotation; allow 0.01 deg */
    {
        float h0;
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_heading_compute(&cur, g_pts[0], 0.0f, &h0, NULL));
        offset_deg = test_angle_diff_deg((double)h0, true_heading_deg(0, n));
    }
    TEST_ASSERT_TRUE(fabs(offset_deg) <= 0.01);
    for (i = 0; i < n; ++i) {
        float h = -1.0f;
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_heading_compute(&cur, g_pts[i], 0.0f, &h, NULL));
        TEST_ASSERT_TRUE(h >= 0.0f && h < 360.0f);
        worst = fmax(worst, fabs(test_angle_diff_deg((double)h, true_heading_deg(i, n))));
    }
    TEST_ASSERT_TRUE(worst <= 0.01);
}

/* ---------------------------------------------------------------- magnitude extremes */

static void test_calibrator_run_ring_radius_1e19_recovers_centre_radius_headings(void)
{
    /* the upper end of the working range: the fit normalises, nothing overflows */
    expect_exact_ring_calibrates(600u, 0.5e19f, -0.3e19f, 1.0e19f, 0.8e19f, 0.0f);
}

static void test_calibrator_run_ring_radius_1e_minus18_recovers_centre_radius_headings(void)
{
    /* near the lower end: coordinates 1e-18, squares 1e-36 still normal floats */
    expect_exact_ring_calibrates(600u, 0.5e-18f, -0.3e-18f, 1.0e-18f, 0.8e-18f, 0.0f);
}

static void test_calibrator_run_ring_radius_1e_minus19_headings_zero_field_unless_output_radius(void)
{
    /* radius 1e-19 calibrates, but with the default output radius sqrt(r1 r2) = 0.9e-19 the
     * corrected |h|^2 is below FLT_MIN and every heading is MAGCAL_ERR_ZERO_FIELD (heading.h);
     * cfg.output_radius = 1 rescales the corrected field and the headings are exact */
    magcal_cal2d_t cur = MAGCAL_CAL2D_IDENTITY;
    float h = -1.0f;
    exact_ring(600u, 0.5e-19f, -0.3e-19f, 1.0e-19f, 0.8e-19f);
    init_default(CAP);
    push_all(600u);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_run(&g_cal, &cur, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ZERO_FIELD, magcal_heading_compute(&cur, g_pts[0], 0.0f, &h, NULL));
    TEST_ASSERT_EQUAL_FLOAT(-1.0f, h);
    expect_exact_ring_calibrates(600u, 0.5e-19f, -0.3e-19f, 1.0e-19f, 0.8e-19f, 1.0f);
}

static void test_calibrator_run_ring_near_flt_max_returns_degenerate_keeps_cal(void)
{
    /* radius 1e20 .. 0.9 FLT_MAX: squared distances overflow; never OK with garbage */
    exact_ring(600u, 0.0f, 0.0f, 1.0e20f, 0.8e20f);
    expect_run_status_keeps_cal(600u, MAGCAL_ERR_DEGENERATE);
    exact_ring(600u, 0.0f, 0.0f, 1.0e37f, 0.8e37f);
    expect_run_status_keeps_cal(600u, MAGCAL_ERR_DEGENERATE);
    exact_ring(600u, 0.0f, 0.0f, 0.9f * FLT_MAX, 0.9f * FLT_MAX);
    expect_run_status_keeps_cal(600u, MAGCAL_ERR_DEGENERATE);
}

static void test_calibrator_run_subnormal_ring_returns_degenerate_keeps_cal(void)
{
    /* radius 1e-40 (subnormal coordinates): squares underflow to 0 */
    exact_ring(600u, 0.0f, 0.0f, 1.0e-40f, 0.8e-40f);
    TEST_ASSERT_TRUE(fabsf(g_pts[0].x) < FLT_MIN && g_pts[0].x != 0.0f);
    expect_run_status_keeps_cal(600u, MAGCAL_ERR_DEGENERATE);
}

static void test_calibrator_run_ring_radius_1e_minus21_returns_ill_conditioned_keeps_cal(void)
{
    /* squares are subnormal (1e-42): the normal equations lose their precision */
    exact_ring(600u, 0.0f, 0.0f, 1.0e-21f, 0.8e-21f);
    expect_run_status_keeps_cal(600u, MAGCAL_ERR_ILL_CONDITIONED);
}

static void test_calibrator_run_subnormal_samples_in_ring_rejected_heading_zero_field(void)
{
    /* a ring of radius 40 plus 20 samples at subnormal coordinates (a sensor reading ~0) */
    magcal_cal2d_t cur = MAGCAL_CAL2D_IDENTITY;
    magcal_cal_report_t rep;
    magcal_vec2_t sub = {1.0e-42f, -1.0e-44f};
    size_t i;
    float mag = -1.0f;
    float tru = -1.0f;
    exact_ring(580u, 3.0f, -2.0f, 40.0f, 32.0f);
    for (i = 580u; i < 600u; ++i) {
        g_pts[i] = sub;
    }
    init_default(CAP);
    push_all(600u);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_run(&g_cal, &cur, &rep));
    TEST_ASSERT_EQUAL_UINT16(20u, rep.outliers);
    for (i = 580u; i < 600u; ++i) {
        int inl = -1;
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_inlier(&g_cal, i, &inl));
        TEST_ASSERT_EQUAL_INT(0, inl);
    }
    /* centre within 1e-4 of the radius despite the 20 rejects */
    TEST_ASSERT_FLOAT_WITHIN(40.0f * 1e-4f, 3.0f, cur.offset.x);
    TEST_ASSERT_FLOAT_WITHIN(40.0f * 1e-4f, -2.0f, cur.offset.y);
    /* raw field of identity calibration at subnormal magnitude: no direction, outputs untouched */
    {
        magcal_cal2d_t id = MAGCAL_CAL2D_IDENTITY;
        TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ZERO_FIELD, magcal_heading_compute(&id, sub, 0.0f, &mag, &tru));
        TEST_ASSERT_EQUAL_FLOAT(-1.0f, mag);
        TEST_ASSERT_EQUAL_FLOAT(-1.0f, tru);
    }
    /* the same sample corrected by the adopted calibration lands near -centre: a valid heading */
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_heading_compute(&cur, sub, 0.0f, &mag, &tru));
    TEST_ASSERT_TRUE(mag >= 0.0f && mag < 360.0f);
}

static void test_ellipse_fit_extreme_magnitudes_return_specific_status(void)
{
    magcal_ellipse_t e;
    magcal_ellipse_t sentinel;
    memset(&e, 0x5A, sizeof e);
    sentinel = e;
    /* spread wider than FLT_MAX: the bounding box width overflows. The points are finite, so
     * this is ILL_CONDITIONED (it was NONFINITE, which the consensus passed on to run()) */
    exact_ring(64u, 0.0f, 0.0f, 0.9f * FLT_MAX, 0.9f * FLT_MAX);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ILL_CONDITIONED, magcal_ellipse_fit(g_pts, 64u, NULL, &e));
    /* ring of radius 1e19 plus one sample 3e19 away: the fit itself succeeds but |p - c|^2
     * overflows in the residual; it returned OK with residual_rms = Inf before (found by
     * fuzz_cluster), now ILL_CONDITIONED */
    exact_ring(64u, 0.0f, 0.0f, 1.0e19f, 0.8e19f);
    g_pts[5].x = 3.0e19f;
    g_pts[5].y = 1.0e19f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ILL_CONDITIONED, magcal_ellipse_fit(g_pts, 64u, NULL, &e));
    /* radius 1e20: documented limit is about 1e15; the pivot test catches it */
    exact_ring(64u, 0.0f, 0.0f, 1.0e20f, 0.8e20f);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ILL_CONDITIONED, magcal_ellipse_fit(g_pts, 64u, NULL, &e));
    /* subnormal ring */
    exact_ring(64u, 0.0f, 0.0f, 1.0e-40f, 0.8e-40f);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_DEGENERATE, magcal_ellipse_fit(g_pts, 64u, NULL, &e));
    TEST_ASSERT_EQUAL_MEMORY(&sentinel, &e, sizeof e);
    /* radius 1e19 works and is exact to float precision */
    exact_ring(64u, 0.0f, 0.0f, 1.0e19f, 0.8e19f);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_fit(g_pts, 64u, NULL, &e));
    TEST_ASSERT_FLOAT_WITHIN(1e-4f, 1.0f, e.semi_major / 1.0e19f);
    TEST_ASSERT_FLOAT_WITHIN(1e-4f, 1.0f, e.semi_minor / 0.8e19f);
}

static void test_heading_compute_overflowing_correction_returns_nonfinite_untouched(void)
{
    magcal_cal2d_t c = MAGCAL_CAL2D_IDENTITY;
    magcal_vec2_t raw = {FLT_MAX, 0.0f};
    float mag = -1.0f;
    float tru = -1.0f;
    /* raw - offset = 2 FLT_MAX overflows to +Inf */
    c.offset.x = -FLT_MAX;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_heading_compute(&c, raw, 0.0f, &mag, &tru));
    /* M (raw - offset) overflows: 1e30 * 1e10 */
    c = (magcal_cal2d_t)MAGCAL_CAL2D_IDENTITY;
    c.m[0][0] = 1.0e30f;
    c.m[1][1] = 1.0e30f;
    raw.x = 1.0e10f;
    raw.y = 1.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_heading_compute(&c, raw, 0.0f, &mag, &tru));
    TEST_ASSERT_EQUAL_FLOAT(-1.0f, mag);
    TEST_ASSERT_EQUAL_FLOAT(-1.0f, tru);
    /* huge but representable field: a normal heading (raw (-3e38, 0) points west: 90 deg) */
    c = (magcal_cal2d_t)MAGCAL_CAL2D_IDENTITY;
    raw.x = -3.0e38f;
    raw.y = 0.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_heading_compute(&c, raw, 0.0f, &mag, &tru));
    TEST_ASSERT_FLOAT_WITHIN(1e-4f, 90.0f, mag);
}

/* ---------------------------------------------------------------- degenerate clouds */

static void test_calibrator_run_two_point_cloud_returns_degenerate_keeps_cal(void)
{
    magcal_ellipse_t e;
    size_t i;
    for (i = 0; i < 200u; ++i) {
        g_pts[i].x = (i % 2u) != 0u ? 1.0f : 25.0f;
        g_pts[i].y = (i % 2u) != 0u ? 5.0f : -13.0f;
    }
    expect_run_status_keeps_cal(200u, MAGCAL_ERR_DEGENERATE);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_DEGENERATE, magcal_ellipse_fit(g_pts, 200u, NULL, &e));
}

static void test_calibrator_run_three_point_cloud_returns_degenerate_keeps_cal(void)
{
    /* three distinct points repeated: not collinear, but no conic is determined */
    magcal_ellipse_t e;
    size_t i;
    for (i = 0; i < 60u; ++i) {
        g_pts[i].x = i % 3u == 0u ? 0.0f : (i % 3u == 1u ? 10.0f : 5.0f);
        g_pts[i].y = i % 3u == 2u ? 8.0f : 0.0f;
    }
    expect_run_status_keeps_cal(60u, MAGCAL_ERR_DEGENERATE);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ILL_CONDITIONED, magcal_ellipse_fit(g_pts, 60u, NULL, &e));
}

static void test_calibrator_run_ring_with_two_far_outliers_calibrates_and_rejects_them(void)
{
    /* two glitch samples 1e5 R away on a diagonal: before the fix the collinearity pre-check
     * ran before the density filter and called the whole set DEGENERATE (eigenvalue ratio 1e-8) */
    magcal_cal2d_t cur = MAGCAL_CAL2D_IDENTITY;
    magcal_cal_report_t rep;
    int inl = -1;
    exact_ring(600u, 3.0f, -2.0f, 40.0f, 32.0f);
    g_pts[0].x = 4.0e6f;
    g_pts[0].y = 4.0e6f;
    g_pts[1].x = -4.0e6f;
    g_pts[1].y = -4.0e6f;
    init_default(CAP);
    push_all(600u);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_run(&g_cal, &cur, &rep));
    TEST_ASSERT_EQUAL_UINT16(2u, rep.outliers);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_inlier(&g_cal, 0u, &inl));
    TEST_ASSERT_EQUAL_INT(0, inl);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_inlier(&g_cal, 1u, &inl));
    TEST_ASSERT_EQUAL_INT(0, inl);
    /* exact ring: centre within 1e-4 of the radius */
    TEST_ASSERT_FLOAT_WITHIN(40.0f * 1e-4f, 3.0f, cur.offset.x);
    TEST_ASSERT_FLOAT_WITHIN(40.0f * 1e-4f, -2.0f, cur.offset.y);
}

static void test_calibrator_run_consensus_sample_at_1e30_is_an_outlier_not_nonfinite(void)
{
    /* one finite sample 1e30 away (e.g. a corrupted float read): the density filter rejects it,
     * but the consensus stage judges every sample and its residual overflows. Before the fix
     * every minimal set was discarded and run() returned MAGCAL_ERR_NONFINITE, a status
     * calibrator.h does not list. */
    magcal_calibrator_cfg_t cfg = MAGCAL_CALIBRATOR_CFG_DEFAULT;
    magcal_cal2d_t cur = MAGCAL_CAL2D_IDENTITY;
    magcal_cal_report_t rep;
    int inl = -1;
    exact_ring(300u, 3.0f, -2.0f, 40.0f, 32.0f);
    g_pts[17].x = 1.0e30f;
    g_pts[17].y = -1.0e30f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_init(&g_cal, &cfg, g_buf, CAP, g_work, sizeof g_work));
    push_all(300u);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_run(&g_cal, &cur, &rep));
    TEST_ASSERT_EQUAL_UINT16(1u, rep.outliers);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_inlier(&g_cal, 17u, &inl));
    TEST_ASSERT_EQUAL_INT(0, inl);
    TEST_ASSERT_FLOAT_WITHIN(40.0f * 1e-4f, 3.0f, cur.offset.x);
    TEST_ASSERT_FLOAT_WITHIN(40.0f * 1e-4f, -2.0f, cur.offset.y);
}

/* ---------------------------------------------------------------- capacity and the port */

static void test_calibrator_run_at_max_samples_then_push_returns_buffer_full(void)
{
    static const test_distortion_t dist = {40.0f, {{1.2f, 0.1f}, {0.1f, 0.85f}}, 15.0f, -9.0f};
    magcal_cal2d_t cur = MAGCAL_CAL2D_IDENTITY;
    magcal_cal_report_t rep;
    magcal_vec2_t extra = {1.0f, 2.0f};
    test_make_ring(&dist, CAP, 0.0, 720.0, 0.2, 11u, g_pts, NULL);
    init_default(CAP);
    push_all(CAP);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_BUFFER_FULL, magcal_calibrator_push(&g_cal, extra));
    TEST_ASSERT_EQUAL_UINT32(CAP, (uint32_t)magcal_calibrator_count(&g_cal));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_run(&g_cal, &cur, &rep));
    TEST_ASSERT_EQUAL_UINT16(CAP, rep.samples);
    /* hard iron (15, -9) within 0.5 (noise 0.2 on radius ~40, 1024 samples) */
    TEST_ASSERT_FLOAT_WITHIN(0.5f, 15.0f, cur.offset.x);
    TEST_ASSERT_FLOAT_WITHIN(0.5f, -9.0f, cur.offset.y);
    /* still full after run(); reset empties it */
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_BUFFER_FULL, magcal_calibrator_push(&g_cal, extra));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_reset(&g_cal));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_push(&g_cal, extra));
}

static void test_calibrator_poll_port_nonfinite_sample_returns_nonfinite_not_stored(void)
{
    magcal_vec3_t v = {1.0f, 2.0f, 3.0f};
    magcal_port_fake_reset();
    TEST_ASSERT_EQUAL_INT(0, magcal_port_fake_push_mag(v));
    v.x = NAN;
    TEST_ASSERT_EQUAL_INT(0, magcal_port_fake_push_mag(v));
    v.x = 1.0f;
    v.y = -INFINITY;
    TEST_ASSERT_EQUAL_INT(0, magcal_port_fake_push_mag(v));
    v.y = 2.0f;
    v.z = NAN; /* z is not used by the 2-D calibrator: stored */
    TEST_ASSERT_EQUAL_INT(0, magcal_port_fake_push_mag(v));
    init_default(CAP);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_poll(&g_cal));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_calibrator_poll(&g_cal));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_calibrator_poll(&g_cal));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_poll(&g_cal));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NO_DATA, magcal_calibrator_poll(&g_cal));
    TEST_ASSERT_EQUAL_UINT32(2u, (uint32_t)magcal_calibrator_count(&g_cal));
}

/* ---------------------------------------------------------------- filter parameters */

static void test_optics_filter_eps_inf_one_cluster_subnormal_eps_arg_tiny_eps_all_noise(void)
{
    static uint8_t mask[200];
    /* eps' must be finite (0 would mean eps' = eps = Inf, rejected with MAGCAL_ERR_ARG) */
    magcal_optics_cfg_t cfg = {INFINITY, 1000.0f, 4u, MAGCAL_OPTICS_IMPROVED, MAGCAL_NEIGHBORS_GRID,
                               MAGCAL_OPTICS_START_INDEX};
    magcal_optics_result_t info;
    size_t i;
    exact_ring(200u, 5.0f, 5.0f, 40.0f, 30.0f);
    /* eps = +Inf: every point is a neighbour of every other one (grid falls back to brute) */
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_optics_filter(&cfg, g_pts, 200u, g_work, sizeof g_work, mask, &info));
    TEST_ASSERT_EQUAL_UINT16(200u, info.n_inliers);
    TEST_ASSERT_EQUAL_INT(MAGCAL_NEIGHBORS_BRUTE, info.neighbors);
    /* eps' = +Inf is rejected */
    memset(mask, 7, sizeof mask);
    cfg.eps_prime = INFINITY;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_optics_filter(&cfg, g_pts, 200u, g_work, sizeof g_work, mask, &info));
    /* subnormal eps (eps^2 underflows to 0): rejected, brute and grid would disagree */
    cfg.eps = 1.0e-45f;
    cfg.eps_prime = 0.0f;
    TEST_ASSERT_TRUE(cfg.eps > 0.0f && cfg.eps < FLT_MIN);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_optics_filter(&cfg, g_pts, 200u, g_work, sizeof g_work, mask, &info));
    /* smallest accepted order of magnitude, 1.2e-19: distinct points 1.1 apart are all noise */
    cfg.eps = 1.2e-19f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ALL_NOISE,
                          magcal_optics_filter(&cfg, g_pts, 200u, g_work, sizeof g_work, mask, &info));
    for (i = 0; i < 200u; ++i) {
        TEST_ASSERT_EQUAL_UINT8(7u, mask[i]); /* untouched on failure */
    }
    /* eps NaN and negative: explicit eps rejected (filter: NaN is not <= 0, so not auto) */
    cfg.eps = NAN;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_optics_filter(&cfg, g_pts, 200u, g_work, sizeof g_work, mask, &info));
}

static void test_dbscan_run_eps_whose_square_overflows_or_underflows_returns_arg(void)
{
    /* two groups of 10 samples, 1e25 apart, each 9e18 wide. eps = 1.9e19 squared overflows to
     * Inf: the brute search called every pair a neighbour (1 cluster) while the grid found 2.
     * Finite eps above sqrt(FLT_MAX) is now rejected; +Inf keeps its documented meaning. */
    static int16_t labels[20];
    static uint16_t order[20];
    static float reach[20], core[20];
    magcal_dbscan_cfg_t dc = {1.8e19f, 4u, MAGCAL_NEIGHBORS_BRUTE};
    magcal_optics_cfg_t oc = {1.9e19f, 0.0f, 4u, MAGCAL_OPTICS_IMPROVED, MAGCAL_NEIGHBORS_BRUTE,
                              MAGCAL_OPTICS_START_INDEX};
    uint16_t n_cl = 0u;
    size_t i;
    for (i = 0; i < 20u; ++i) {
        g_pts[i].x = (i < 10u ? 0.0f : 1.0e25f) + (float)(i % 10u) * 1.0e18f;
        g_pts[i].y = 0.0f;
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_dbscan_run(&dc, g_pts, 20u, g_work, sizeof g_work, labels, &n_cl, NULL));
    TEST_ASSERT_EQUAL_UINT16(2u, n_cl);
    dc.neighbors = MAGCAL_NEIGHBORS_GRID;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_dbscan_run(&dc, g_pts, 20u, g_work, sizeof g_work, labels, &n_cl, NULL));
    TEST_ASSERT_EQUAL_UINT16(2u, n_cl);
    dc.eps = 1.9e19f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_dbscan_run(&dc, g_pts, 20u, g_work, sizeof g_work, labels, &n_cl, NULL));
    dc.neighbors = MAGCAL_NEIGHBORS_BRUTE;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_dbscan_run(&dc, g_pts, 20u, g_work, sizeof g_work, labels, &n_cl, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG,
                          magcal_optics_run(&oc, g_pts, 20u, g_work, sizeof g_work, order, reach, core, NULL, NULL));
    dc.eps = INFINITY;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_dbscan_run(&dc, g_pts, 20u, g_work, sizeof g_work, labels, &n_cl, NULL));
    TEST_ASSERT_EQUAL_UINT16(1u, n_cl);
    /* mirror case found by fuzz_cluster: eps 2.2e-28 (eps^2 underflows to 0) on points 1e-25
     * apart whose d^2 also underflows to 0: brute linked every pair, the grid did not */
    for (i = 0; i < 20u; ++i) {
        g_pts[i].x = (float)i * 1.0e-25f;
        g_pts[i].y = 0.0f;
    }
    dc.eps = 2.2e-28f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_dbscan_run(&dc, g_pts, 20u, g_work, sizeof g_work, labels, &n_cl, NULL));
    oc.eps = 2.2e-28f;
    oc.neighbors = MAGCAL_NEIGHBORS_GRID;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG,
                          magcal_optics_run(&oc, g_pts, 20u, g_work, sizeof g_work, order, reach, core, NULL, NULL));
}

static void test_calibrator_run_dbscan_subnormal_eps_arg_tiny_eps_all_noise_keeps_cal(void)
{
    magcal_calibrator_cfg_t cfg = MAGCAL_CALIBRATOR_CFG_DEFAULT;
    magcal_cal2d_t cur = previous_cal();
    magcal_cal2d_t before = cur;
    cfg.filter = MAGCAL_FILTER_DBSCAN;
    cfg.eps = 1.0e-45f;
    exact_ring(300u, 0.0f, 0.0f, 40.0f, 30.0f);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_init(&g_cal, &cfg, g_buf, CAP, g_work, sizeof g_work));
    push_all(300u);
    /* the DBSCAN stage rejects a subnormal eps (eps^2 underflows): ARG from the stage */
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_calibrator_run(&g_cal, &cur, NULL));
    TEST_ASSERT_EQUAL_MEMORY(&before, &cur, sizeof cur);
    /* eps 1.2e-19 is accepted: every sample is noise */
    cfg.eps = 1.2e-19f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_init(&g_cal, &cfg, g_buf, CAP, g_work, sizeof g_work));
    push_all(300u);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ALL_NOISE, magcal_calibrator_run(&g_cal, &cur, NULL));
    TEST_ASSERT_EQUAL_MEMORY(&before, &cur, sizeof cur);
    /* eps = +Inf and NaN in the configuration */
    cfg.eps = INFINITY;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_calibrator_init(&g_cal, &cfg, g_buf, CAP, g_work, sizeof g_work));
    cfg.eps = -1.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_calibrator_init(&g_cal, &cfg, g_buf, CAP, g_work, sizeof g_work));
    cfg.eps = 0.0f;
    cfg.min_pts = (uint16_t)(MAGCAL_MAX_MIN_PTS + 1u);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_calibrator_init(&g_cal, &cfg, g_buf, CAP, g_work, sizeof g_work));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_calibrator_run_ring_radius_1e19_recovers_centre_radius_headings);
    RUN_TEST(test_calibrator_run_ring_radius_1e_minus18_recovers_centre_radius_headings);
    RUN_TEST(test_calibrator_run_ring_radius_1e_minus19_headings_zero_field_unless_output_radius);
    RUN_TEST(test_calibrator_run_ring_near_flt_max_returns_degenerate_keeps_cal);
    RUN_TEST(test_calibrator_run_subnormal_ring_returns_degenerate_keeps_cal);
    RUN_TEST(test_calibrator_run_ring_radius_1e_minus21_returns_ill_conditioned_keeps_cal);
    RUN_TEST(test_calibrator_run_subnormal_samples_in_ring_rejected_heading_zero_field);
    RUN_TEST(test_ellipse_fit_extreme_magnitudes_return_specific_status);
    RUN_TEST(test_heading_compute_overflowing_correction_returns_nonfinite_untouched);
    RUN_TEST(test_calibrator_run_two_point_cloud_returns_degenerate_keeps_cal);
    RUN_TEST(test_calibrator_run_three_point_cloud_returns_degenerate_keeps_cal);
    RUN_TEST(test_calibrator_run_ring_with_two_far_outliers_calibrates_and_rejects_them);
    RUN_TEST(test_calibrator_run_consensus_sample_at_1e30_is_an_outlier_not_nonfinite);
    RUN_TEST(test_calibrator_run_at_max_samples_then_push_returns_buffer_full);
    RUN_TEST(test_calibrator_poll_port_nonfinite_sample_returns_nonfinite_not_stored);
    RUN_TEST(test_optics_filter_eps_inf_one_cluster_subnormal_eps_arg_tiny_eps_all_noise);
    RUN_TEST(test_dbscan_run_eps_whose_square_overflows_or_underflows_returns_arg);
    RUN_TEST(test_calibrator_run_dbscan_subnormal_eps_arg_tiny_eps_all_noise_keeps_cal);
    return UNITY_END();
}
