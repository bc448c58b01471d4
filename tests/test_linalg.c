/* Tests of the shared float32 kernels in src/fit/linalg.c (internal API, magcal_internal.h). */
#include <math.h>
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
    for (c = 0; c >= (int)MAGCAL_ERR_INCONSISTENT; --c) {
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
    RUN_TEST(test_prng_is_deterministic_and_bounded);
    RUN_TEST(test_status_str_names_every_code);
    return UNITY_END();
}
