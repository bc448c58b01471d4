/*
 * Host/target cross-check: float32 results computed through the library, printed as
 * `XCHECK <name> <value> [<abs tol>]` lines. The cross build runs this program on the host and on
 * the emulated Cortex-M4F and compares the lines (tools/target/xcheck_compare.py, ctest
 * `test_xcheck_host_vs_target`); names ending in `_deg` are compared as angles. Each case also
 * asserts against known truth, so the program is an ordinary Unity test on either side.
 *
 * To add a module (calibrator, heading): compute through its public API on fixed data and call
 * xcheck_emit() for every value worth comparing; the default tolerance is 1e-3 (deg for headings).
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "magcal/ellipse.h"
#include "magcal/heading.h"
#include "magcal_internal.h"
#include "test_util.h"
#include "unity.h"

#define XCHECK_RING_N 72u

void setUp(void) {}
void tearDown(void) {}

static void xcheck_emit(const char *name, float value)
{
    printf("XCHECK %s %.9g\n", name, (double)value);
}

/* Circle (hard-iron) fit with the library's LDL^T solver: |m|^2 = 2 bx x + 2 by y + c,
 * normal equations accumulated in float32 on centred data, then headings through the fit. */
static void test_ldlt_solve_circle_fit_headings_match_truth(void)
{
    static const test_distortion_t dist = {45.0f, {{1.0f, 0.0f}, {0.0f, 1.0f}}, 12.5f, -30.25f};
    magcal_vec2_t m[XCHECK_RING_N];
    float psi[XCHECK_RING_N];
    float n[9] = {0};
    float r[3] = {0};
    float minp = 0.0f;
    float mx0 = 0.0f, my0 = 0.0f;
    float bx, by, radius;
    double worst = 0.0;
    char name[32];
    size_t k, i, j;

    test_make_ring(&dist, XCHECK_RING_N, 3.0, 360.0, 0.05, 2024u, m, psi);
    for (k = 0; k < XCHECK_RING_N; ++k) {
        mx0 += m[k].x / (float)XCHECK_RING_N;
        my0 += m[k].y / (float)XCHECK_RING_N;
    }
    for (k = 0; k < XCHECK_RING_N; ++k) {
        float x = m[k].x - mx0, y = m[k].y - my0;
        float row[3];
        row[0] = 2.0f * x;
        row[1] = 2.0f * y;
        row[2] = 1.0f;
        for (i = 0; i < 3; ++i) {
            r[i] += row[i] * (x * x + y * y);
            for (j = 0; j < 3; ++j) {
                n[i * 3 + j] += row[i] * row[j];
            }
        }
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ldlt_solve(n, r, 3, 1e-6f, &minp));
    bx = r[0] + mx0;
    by = r[1] + my0;
    radius = sqrtf(r[2] + r[0] * r[0] + r[1] * r[1]);
    /* noise sigma 0.05 on radius 45 over 72 points: centre and radius within 0.05 */
    TEST_ASSERT_FLOAT_WITHIN(0.05f, dist.bx, bx);
    TEST_ASSERT_FLOAT_WITHIN(0.05f, dist.by, by);
    TEST_ASSERT_FLOAT_WITHIN(0.05f, dist.h0, radius);
    xcheck_emit("ring_bx", bx);
    xcheck_emit("ring_by", by);
    xcheck_emit("ring_radius", radius);
    xcheck_emit("ring_min_pivot", minp);
    for (k = 0; k < XCHECK_RING_N; ++k) {
        float hx = m[k].x - bx, hy = m[k].y - by;
        float h = magcal_wrap360_deg(atan2f(-hx, hy) * MAGCAL_DEG_PER_RAD_F);
        double e = fabs(test_angle_diff_deg((double)h, (double)psi[k]));
        if (e > worst) {
            worst = e;
        }
        (void)snprintf(name, sizeof name, "ring_heading_%02u_deg", (unsigned)k);
        xcheck_emit(name, h);
    }
    /* 0.05 noise on a 45 radius: about 0.064 deg rms per sample, < 0.3 deg worst of 72 */
    TEST_ASSERT_TRUE(worst < 0.3);
}

/* Hard + soft iron (symmetric T, so the symmetric whitening recovers the true heading exactly):
 * magcal_ellipse_fit -> magcal_ellipse_to_cal -> magcal_heading_compute on every sample. */
static void test_heading_compute_fitted_ellipse_ring_matches_truth(void)
{
    static const test_distortion_t dist = {40.0f, {{1.2f, 0.15f}, {0.15f, 0.85f}}, -210.0f, 95.5f};
    magcal_vec2_t m[XCHECK_RING_N];
    float psi[XCHECK_RING_N];
    magcal_ellipse_t e;
    magcal_cal2d_t cal;
    double worst = 0.0;
    char name[32];
    size_t k;

    test_make_ring(&dist, XCHECK_RING_N, 1.0, 360.0, 0.05, 77u, m, psi);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_fit(m, XCHECK_RING_N, NULL, &e));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_to_cal(&e, MAGCAL_CORR_SYMMETRIC, 40.0f, &cal));
    /* noise 0.05 on semi-axes about 34..49 over 72 points: centre within 0.05 */
    TEST_ASSERT_FLOAT_WITHIN(0.05f, dist.bx, e.center.x);
    TEST_ASSERT_FLOAT_WITHIN(0.05f, dist.by, e.center.y);
    xcheck_emit("ellipse_x0", e.center.x);
    xcheck_emit("ellipse_y0", e.center.y);
    xcheck_emit("ellipse_r1", e.semi_minor);
    xcheck_emit("ellipse_r2", e.semi_major);
    xcheck_emit("ellipse_theta_rad", e.angle_rad);
    for (k = 0; k < XCHECK_RING_N; ++k) {
        float mag = 0.0f, tru = 0.0f;
        double err;
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_heading_compute(&cal, m[k], 4.5f, &mag, &tru));
        err = fabs(test_angle_diff_deg((double)mag, (double)psi[k]));
        if (err > worst) {
            worst = err;
        }
        (void)snprintf(name, sizeof name, "ellipse_heading_%02u_deg", (unsigned)k);
        xcheck_emit(name, mag);
        (void)snprintf(name, sizeof name, "ellipse_true_%02u_deg", (unsigned)k);
        xcheck_emit(name, tru);
    }
    /* about 0.08 deg rms per sample from the noise; worst of 72 well under 0.5 deg */
    TEST_ASSERT_TRUE(worst < 0.5);
}

/* A fixed 6x6 SPD system with a known solution (N = A^T A, b = N x_true). */
static void test_ldlt_solve_spd6_matches_known_solution(void)
{
    static const float x_true[6] = {0.5f, -1.25f, 2.0f, 3.5f, -0.75f, 1.0f};
    float a[36];
    float n[36] = {0};
    float b[6] = {0};
    char name[32];
    size_t i, j, k;
    for (i = 0; i < 6; ++i) {
        for (j = 0; j < 6; ++j) {
            a[i * 6 + j] = (i == j) ? 4.0f : 1.0f / (float)(1u + i + 2u * j);
        }
    }
    for (i = 0; i < 6; ++i) {
        for (j = 0; j < 6; ++j) {
            for (k = 0; k < 6; ++k) {
                n[i * 6 + j] += a[k * 6 + i] * a[k * 6 + j];
            }
        }
    }
    for (i = 0; i < 6; ++i) {
        for (j = 0; j < 6; ++j) {
            b[i] += n[i * 6 + j] * x_true[j];
        }
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ldlt_solve(n, b, 6, 1e-6f, NULL));
    for (i = 0; i < 6; ++i) {
        TEST_ASSERT_FLOAT_WITHIN(1e-4f, x_true[i], b[i]);
        (void)snprintf(name, sizeof name, "ldlt6_x%u", (unsigned)i);
        xcheck_emit(name, b[i]);
    }
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_ldlt_solve_circle_fit_headings_match_truth);
    RUN_TEST(test_heading_compute_fitted_ellipse_ring_matches_truth);
    RUN_TEST(test_ldlt_solve_spd6_matches_known_solution);
    return UNITY_END();
}
