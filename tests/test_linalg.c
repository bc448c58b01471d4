/* Tests of the shared float32 kernels in src/fit/linalg.c (internal API, magcal_internal.h). */
#include <float.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "magcal_internal.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

static void test_ldlt_solve_spd5_matches_known_solution(void)
{
    /* N = A^T A for a fixed A with x_true = (1,-2,3,-4,5): b = N x_true. */
    static const float a_rows[7][5] = {
        {1, 2, 0, 1, 3}, {0, 1, 4, 1, 1}, {2, 0, 1, 3, 1}, {1, 1, 1, 1, 1},
        {3, -1, 2, 0, 1}, {0, 2, -1, 1, 2}, {1, 0, 0, 2, -1}};
    static const float x_true[5] = {1, -2, 3, -4, 5};
    float n[25] = {0};
    float b[5] = {0};
    size_t i, j, k;
    for (k = 0; k < 7; ++k) {
        float y = 0.0f;
        for (i = 0; i < 5; ++i) {
            y += a_rows[k][i] * x_true[i];
        }
        for (i = 0; i < 5; ++i) {
            b[i] += a_rows[k][i] * y;
            for (j = 0; j < 5; ++j) {
                n[i * 5 + j] += a_rows[k][i] * a_rows[k][j];
            }
        }
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ldlt_solve(n, b, 5, 1e-6f, NULL));
    for (i = 0; i < 5; ++i) {
        TEST_ASSERT_FLOAT_WITHIN(1e-4f, x_true[i], b[i]);
    }
}

static void test_ldlt_solve_rank_deficient_returns_ill_conditioned(void)
{
    /* Two identical columns: rank 1 (after equilibration pivot 2 is exactly 0). */
    float n[4] = {4.0f, 4.0f, 4.0f, 4.0f};
    float b[2] = {1.0f, 1.0f};
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ILL_CONDITIONED, magcal_ldlt_solve(n, b, 2, 1e-6f, NULL));
}

static void test_ldlt_solve_bad_input_returns_status(void)
{
    float n[4] = {1.0f, 0.0f, 0.0f, NAN};
    float b[2] = {1.0f, 1.0f};
    float z[4] = {0.0f, 0.0f, 0.0f, 1.0f};
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_ldlt_solve(n, b, 2, 1e-6f, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_DEGENERATE, magcal_ldlt_solve(z, b, 2, 1e-6f, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_ldlt_solve(z, b, 0, 1e-6f, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_ldlt_solve(z, b, MAGCAL_LDLT_MAX_N + 1u, 1e-6f, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_ldlt_solve(NULL, b, 2, 1e-6f, NULL));
}

static void test_wrap_angles_to_documented_ranges(void)
{
    TEST_ASSERT_FLOAT_WITHIN(1e-4f, 180.0f, magcal_wrap180_deg(-180.0f));
    TEST_ASSERT_FLOAT_WITHIN(1e-4f, 180.0f, magcal_wrap180_deg(540.0f));
    TEST_ASSERT_FLOAT_WITHIN(1e-4f, -170.0f, magcal_wrap180_deg(190.0f));
    TEST_ASSERT_FLOAT_WITHIN(1e-4f, 10.0f, magcal_wrap180_deg(-350.0f));
    TEST_ASSERT_FLOAT_WITHIN(1e-4f, 0.0f, magcal_wrap360_deg(360.0f));
    TEST_ASSERT_FLOAT_WITHIN(1e-4f, 350.0f, magcal_wrap360_deg(-10.0f));
    TEST_ASSERT_FLOAT_WITHIN(1e-4f, 0.0f, magcal_wrap360_deg(-1e-9f));
    TEST_ASSERT_TRUE(magcal_wrap360_deg(-1e-9f) < 360.0f);
}

/* The former libm forms, the reference: fmodf is exact, so the wraps must match it bit for bit. */
static float ref_wrap180(float a)
{
    float r = fmodf(a, 360.0f);
    if (r > 180.0f) {
        r -= 360.0f;
    } else if (r <= -180.0f) {
        r += 360.0f;
    }
    return r;
}

static float ref_wrap360(float a)
{
    float r = fmodf(a, 360.0f);
    if (r < 0.0f) {
        r += 360.0f;
    }
    if (r >= 360.0f) {
        r = 0.0f;
    }
    return r;
}

static uint32_t bits_of(float f)
{
    uint32_t u;
    memcpy(&u, &f, sizeof u);
    return u;
}

static void check_wraps_bitwise(float a)
{
    if (bits_of(magcal_wrap180_deg(a)) != bits_of(ref_wrap180(a)) ||
        bits_of(magcal_wrap360_deg(a)) != bits_of(ref_wrap360(a))) {
        char msg[64];
        snprintf(msg, sizeof msg, "a = %.9g (0x%08lx)", (double)a, (unsigned long)bits_of(a));
        TEST_FAIL_MESSAGE(msg);
    }
}

/* The fmodf-free wraps (exact long division) equal the fmodf forms for every float tried: every
 * 1/4096 degree over [-1080, 1080], and a stride through all finite bit patterns of both signs
 * (subnormals to FLT_MAX), plus the edges. */
static void test_wrap_without_fmodf_matches_fmodf_bit_for_bit(void)
{
    static const float edge[] = {0.0f,    -0.0f,      360.0f,     -360.0f,    720.0f,  -720.0f,
                                 180.0f,  -180.0f,    540.0f,     -540.0f,    1e-45f,  -1e-45f,
                                 FLT_MAX, -FLT_MAX,   359.99997f, -359.99997f, 1e30f,  -1e30f,
                                 16777216.0f, -16777216.0f, 3.4e38f};
    int32_t i;
    uint32_t u;
    size_t k;
    for (k = 0u; k < sizeof edge / sizeof edge[0]; ++k) {
        check_wraps_bitwise(edge[k]);
    }
    for (i = -1080 * 4096; i <= 1080 * 4096; ++i) {
        check_wraps_bitwise((float)i * (1.0f / 4096.0f));
    }
    for (u = 0u; u <= 0x7F7FFFFFu; u += 9973u) {
        float f;
        memcpy(&f, &u, sizeof f);
        check_wraps_bitwise(f);
        check_wraps_bitwise(-f);
    }
    TEST_ASSERT_TRUE(isnan(magcal_wrap360_deg(INFINITY)));
    TEST_ASSERT_TRUE(isnan(magcal_wrap180_deg(-INFINITY)));
    TEST_ASSERT_TRUE(isnan(magcal_wrap360_deg(NAN)));
}

/* magcal_atan2f against the double atan2 on a dense sweep: 2^22 directions around the circle at
 * radii 1..1000, and a stride through all positive finite bit patterns against x in
 * {+-1, 3.7e-3, -2e5, 1e-30} both ways round. Measured maximum 1.57e-5 degree (2.75e-7 rad, where
 * the result is near +-pi: a float ulp there is 2.4e-7 rad); glibc's atan2f is 1.44e-5 degree off
 * the double atan2 on the same sweep. */
static void test_atan2_matches_libm_within_bound(void)
{
    static const float xs[] = {1.0f, -1.0f, 3.7e-3f, -2e5f, 1e-30f};
    const double pi = 3.14159265358979323846;
    double maxe = 0.0;
    uint32_t i;
    uint32_t u;
    size_t k;
    for (i = 0u; i < (1u << 22); ++i) {
        const double a = -pi + 2.0 * pi * (double)i / (double)(1u << 22);
        const float r = (float)(1.0 + (double)((i * 2654435761u) % 1000u));
        const float y = (float)((double)r * sin(a));
        const float x = (float)((double)r * cos(a));
        const double e = fabs((double)magcal_atan2f(y, x) - atan2((double)y, (double)x));
        maxe = (e > maxe) ? e : maxe;
    }
    for (u = 0u; u < 0x7F800000u; u += 7919u) {
        float y;
        memcpy(&y, &u, sizeof y);
        for (k = 0u; k < sizeof xs / sizeof xs[0]; ++k) {
            double e = fabs((double)magcal_atan2f(y, xs[k]) - atan2((double)y, (double)xs[k]));
            maxe = (e > maxe) ? e : maxe;
            e = fabs((double)magcal_atan2f(xs[k], y) - atan2((double)xs[k], (double)y));
            maxe = (e > maxe) ? e : maxe;
        }
    }
    TEST_ASSERT_TRUE(maxe * 180.0 / pi <= 2.0e-5);
    /* signed zeros and the axes as atan2 */
    TEST_ASSERT_EQUAL_UINT32(bits_of(-3.1415926536f), bits_of(magcal_atan2f(-0.0f, -1.0f)));
    TEST_ASSERT_EQUAL_UINT32(bits_of(3.1415926536f), bits_of(magcal_atan2f(0.0f, -0.0f)));
    TEST_ASSERT_EQUAL_UINT32(bits_of(-0.0f), bits_of(magcal_atan2f(-0.0f, 2.0f)));
    TEST_ASSERT_EQUAL_UINT32(bits_of(0.0f), bits_of(magcal_atan2f(0.0f, 0.0f)));
    TEST_ASSERT_EQUAL_UINT32(bits_of(1.5707963268f), bits_of(magcal_atan2f(5.0f, 0.0f)));
    TEST_ASSERT_EQUAL_UINT32(bits_of(-1.5707963268f), bits_of(magcal_atan2f(-5.0f, -0.0f)));
    TEST_ASSERT_TRUE(isnan(magcal_atan2f(NAN, 1.0f)));
    /* infinities as atan2 (C99 F.9.1.4; fuzz_calibrator found inf / inf giving NaN) */
    for (k = 0u; k < 4u; ++k) {
        const float y = ((k & 1u) != 0u) ? -INFINITY : INFINITY;
        const float x = ((k & 2u) != 0u) ? -INFINITY : INFINITY;
        TEST_ASSERT_EQUAL_UINT32(bits_of((float)atan2((double)y, (double)x)), bits_of(magcal_atan2f(y, x)));
        TEST_ASSERT_EQUAL_UINT32(bits_of((float)atan2((double)y, 3.0)), bits_of(magcal_atan2f(y, 3.0f)));
        TEST_ASSERT_EQUAL_UINT32(bits_of((float)atan2(-2.0, (double)x)), bits_of(magcal_atan2f(-2.0f, x)));
    }
}

static void test_prng_is_deterministic_and_bounded(void)
{
    uint32_t s1 = 12345u, s2 = 12345u;
    uint32_t hist[10] = {0};
    size_t i;
    for (i = 0; i < 10000; ++i) {
        uint32_t a = magcal_prng_next(&s1, 10u);
        TEST_ASSERT_EQUAL_UINT32(a, magcal_prng_next(&s2, 10u));
        TEST_ASSERT_TRUE(a < 10u);
        hist[a]++;
    }
    for (i = 0; i < 10; ++i) { /* uniform within 10 % (binomial sd is 3 %) */
        TEST_ASSERT_UINT32_WITHIN(100u, 1000u, hist[i]);
    }
}

static void test_status_str_names_every_code(void)
{
    int c;
    for (c = 0; c >= (int)MAGCAL_ERR_SHAPE_CHANGED; --c) {
        TEST_ASSERT_NOT_EQUAL(0, strcmp("unknown", magcal_status_str((magcal_status_t)c)));
    }
    TEST_ASSERT_EQUAL_STRING("unknown", magcal_status_str((magcal_status_t)2));
    TEST_ASSERT_NOT_EQUAL(0, strcmp("unknown", magcal_status_str(MAGCAL_IN_PROGRESS)));
    TEST_ASSERT_EQUAL_STRING("ok", magcal_status_str(MAGCAL_OK));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_ldlt_solve_spd5_matches_known_solution);
    RUN_TEST(test_ldlt_solve_rank_deficient_returns_ill_conditioned);
    RUN_TEST(test_ldlt_solve_bad_input_returns_status);
    RUN_TEST(test_wrap_angles_to_documented_ranges);
    RUN_TEST(test_wrap_without_fmodf_matches_fmodf_bit_for_bit);
    RUN_TEST(test_atan2_matches_libm_within_bound);
    RUN_TEST(test_prng_is_deterministic_and_bounded);
    RUN_TEST(test_status_str_names_every_code);
    return UNITY_END();
}
