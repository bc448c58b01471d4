/* Unity tests of the build configuration and version (config.h, magcal.h): the fingerprint sees
 * every integer limit, the checked inits refuse a foreign fingerprint or instance size before
 * writing anything, the workspace declaration helpers are aligned and large enough, and the
 * version has one source. The cross-translation-unit case (a caller really compiled with other
 * limits) is tests/test_config_mismatch.c. */
#include <string.h>

#include "magcal.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

static uint32_t fp_now(void) { return MAGCAL_CONFIG_FINGERPRINT; }

/* MAGCAL_CONFIG_FINGERPRINT expands its macros where it is used: redefine one limit, take the
 * fingerprint, restore. Each limit must change it. */
static void test_config_fingerprint_sees_every_limit(void)
{
    const uint32_t base = fp_now();
    uint32_t f[7];
    size_t i;
    size_t j;
    TEST_ASSERT_EQUAL_HEX32(base, magcal_config_fingerprint());
#undef MAGCAL_MAX_SAMPLES
#define MAGCAL_MAX_SAMPLES 512u
    f[0] = MAGCAL_CONFIG_FINGERPRINT;
#undef MAGCAL_MAX_SAMPLES
#define MAGCAL_MAX_SAMPLES 1024u
#undef MAGCAL_MAX_MIN_PTS
#define MAGCAL_MAX_MIN_PTS 16u
    f[1] = MAGCAL_CONFIG_FINGERPRINT;
#undef MAGCAL_MAX_MIN_PTS
#define MAGCAL_MAX_MIN_PTS 32u
#undef MAGCAL_GRID_MAX_CELLS
#define MAGCAL_GRID_MAX_CELLS 1024u
    f[2] = MAGCAL_CONFIG_FINGERPRINT;
#undef MAGCAL_GRID_MAX_CELLS
#define MAGCAL_GRID_MAX_CELLS 4096u
#undef MAGCAL_COVERAGE_BINS
#define MAGCAL_COVERAGE_BINS 8u
    f[3] = MAGCAL_CONFIG_FINGERPRINT;
#undef MAGCAL_COVERAGE_BINS
#define MAGCAL_COVERAGE_BINS 36u
#undef MAGCAL_SWING_COG_BINS
#define MAGCAL_SWING_COG_BINS 72u
    f[4] = MAGCAL_CONFIG_FINGERPRINT;
#undef MAGCAL_SWING_COG_BINS
#define MAGCAL_SWING_COG_BINS 36u
#undef MAGCAL_CONSENSUS_MAX_ITER
#define MAGCAL_CONSENSUS_MAX_ITER 200u
    f[5] = MAGCAL_CONFIG_FINGERPRINT;
#undef MAGCAL_CONSENSUS_MAX_ITER
#define MAGCAL_CONSENSUS_MAX_ITER 2000u
#undef MAGCAL_CONSENSUS_MAX_REFINE
#define MAGCAL_CONSENSUS_MAX_REFINE 8u
    f[6] = MAGCAL_CONFIG_FINGERPRINT;
#undef MAGCAL_CONSENSUS_MAX_REFINE
#define MAGCAL_CONSENSUS_MAX_REFINE 32u
    TEST_ASSERT_EQUAL_HEX32(base, MAGCAL_CONFIG_FINGERPRINT); /* restored: the defaults again */
    for (i = 0u; i < 7u; ++i) {
        TEST_ASSERT_NOT_EQUAL(base, f[i]);
        for (j = 0u; j < i; ++j) {
            TEST_ASSERT_NOT_EQUAL(f[j], f[i]);
        }
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_config_check());
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_CONFIG_MISMATCH, magcal_config_check_fingerprint(f[3]));
}

#define CAP 64u
static magcal_calibrator_t g_cal;
static magcal_vec2_t g_buf[CAP];
static MAGCAL_CALIBRATOR_WORKSPACE_DECLARE(g_work, CAP);

static void test_init_checked_foreign_config_returns_mismatch_untouched(void)
{
    const magcal_calibrator_cfg_t cfg = MAGCAL_CALIBRATOR_CFG_DEFAULT;
    const magcal_aided_cfg_t acfg = MAGCAL_AIDED_CFG_DEFAULT;
    const magcal_swing_cog_cfg_t scfg = MAGCAL_SWING_COG_CFG_DEFAULT;
    static magcal_aided_t aided;
    static magcal_swing_cog_t cog;
    static uint8_t before[sizeof(magcal_aided_t)];
    const uint32_t bad = MAGCAL_CONFIG_FINGERPRINT ^ 0x100u;
    memset(&g_cal, 0xA5, sizeof g_cal);
    memcpy(before, &g_cal, sizeof g_cal);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_CONFIG_MISMATCH,
                          magcal_calibrator_init_checked(&g_cal, &cfg, g_buf, CAP, g_work, sizeof g_work, bad,
                                                         sizeof g_cal));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_CONFIG_MISMATCH,
                          magcal_calibrator_init_checked(&g_cal, &cfg, g_buf, CAP, g_work, sizeof g_work,
                                                         MAGCAL_CONFIG_FINGERPRINT, sizeof g_cal - 56u));
    TEST_ASSERT_EQUAL_MEMORY(before, &g_cal, sizeof g_cal);
    TEST_ASSERT_EQUAL_INT(MAGCAL_CALIBRATOR_INVALID, magcal_calibrator_state(&g_cal));
    memset(&aided, 0xA5, sizeof aided);
    memcpy(before, &aided, sizeof aided);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_CONFIG_MISMATCH, magcal_aided_init_checked(&aided, &acfg, bad, sizeof aided));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_CONFIG_MISMATCH,
                          magcal_aided_init_checked(&aided, &acfg, MAGCAL_CONFIG_FINGERPRINT, sizeof aided + 4u));
    TEST_ASSERT_EQUAL_MEMORY(before, &aided, sizeof aided);
    memset(&cog, 0xA5, sizeof cog);
    memcpy(before, &cog, sizeof cog);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_CONFIG_MISMATCH, magcal_swing_cog_init_checked(&cog, &scfg, bad, sizeof cog));
    TEST_ASSERT_EQUAL_MEMORY(before, &cog, sizeof cog);
    /* the macros pass this translation unit's values: accepted */
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_init(&g_cal, &cfg, g_buf, CAP, g_work, sizeof g_work));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_aided_init(&aided, &acfg));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_swing_cog_init(&cog, &scfg));
}

static void test_calibrator_state_null_is_invalid_not_failed(void)
{
    magcal_calibrator_t blank;
    memset(&blank, 0, sizeof blank);
    TEST_ASSERT_EQUAL_INT(MAGCAL_CALIBRATOR_INVALID, magcal_calibrator_state(NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_CALIBRATOR_INVALID, magcal_calibrator_state(&blank));
}

/* Declaration helpers: aligned for pointers/float/uint32_t and at least the size macro; a
 * workspace one byte off gets its own status. */
static MAGCAL_OPTICS_FILTER_WORKSPACE_DECLARE(g_wo, 100u);
static MAGCAL_OPTICS3_FILTER_WORKSPACE_DECLARE(g_wo3, 100u);
static MAGCAL_DBSCAN_WORKSPACE_DECLARE(g_wd, 100u);
static MAGCAL_CONSENSUS_WORKSPACE_DECLARE(g_wc, 100u);
static MAGCAL_OPTICS_LARGEST_WORKSPACE_DECLARE(g_wl, 100u);

static void test_workspace_declare_is_aligned_and_large_enough(void)
{
    const magcal_calibrator_cfg_t cfg = MAGCAL_CALIBRATOR_CFG_DEFAULT;
    TEST_ASSERT_TRUE(sizeof g_work >= MAGCAL_CALIBRATOR_WORKSPACE_LEN(CAP));
    TEST_ASSERT_TRUE(sizeof g_work < MAGCAL_CALIBRATOR_WORKSPACE_LEN(CAP) + sizeof(magcal_workspace_t));
    TEST_ASSERT_TRUE(sizeof g_wo >= MAGCAL_OPTICS_FILTER_WORKSPACE_LEN(100u));
    TEST_ASSERT_TRUE(sizeof g_wo3 >= MAGCAL_OPTICS3_FILTER_WORKSPACE_LEN(100u));
    TEST_ASSERT_TRUE(sizeof g_wd >= MAGCAL_DBSCAN_WORKSPACE_LEN(100u));
    TEST_ASSERT_TRUE(sizeof g_wc >= MAGCAL_CONSENSUS_WORKSPACE_LEN(100u));
    TEST_ASSERT_TRUE(sizeof g_wl >= MAGCAL_OPTICS_LARGEST_WORKSPACE_LEN(100u));
    TEST_ASSERT_EQUAL_UINT(0u, (unsigned)((uintptr_t)g_work % sizeof(void *)));
    TEST_ASSERT_EQUAL_UINT(0u, (unsigned)((uintptr_t)g_wo % sizeof(void *)));
    TEST_ASSERT_EQUAL_UINT(0u, (unsigned)((uintptr_t)g_wd % sizeof(void *)));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ALIGNMENT, magcal_calibrator_init(&g_cal, &cfg, g_buf, CAP, (uint8_t *)g_work + 2,
                                                                       sizeof g_work - 4u));
}

static void test_status_is_outcome_only_for_normal_outcomes(void)
{
    int c;
    int n = 0;
    for (c = 1; c >= (int)MAGCAL_ERR_SHAPE_CHANGED; --c) {
        n += magcal_status_is_outcome((magcal_status_t)c);
    }
    TEST_ASSERT_EQUAL_INT(6, n);
    TEST_ASSERT_EQUAL_INT(1, magcal_status_is_outcome(MAGCAL_OK));
    TEST_ASSERT_EQUAL_INT(1, magcal_status_is_outcome(MAGCAL_ERR_NOT_BETTER));
    TEST_ASSERT_EQUAL_INT(1, magcal_status_is_outcome(MAGCAL_ERR_GATED));
    TEST_ASSERT_EQUAL_INT(1, magcal_status_is_outcome(MAGCAL_ERR_NO_DATA));
    TEST_ASSERT_EQUAL_INT(1, magcal_status_is_outcome(MAGCAL_ERR_NOT_CONVERGED));
    TEST_ASSERT_EQUAL_INT(0, magcal_status_is_outcome(MAGCAL_ERR_CONFIG_MISMATCH));
    TEST_ASSERT_EQUAL_INT(1, magcal_status_is_outcome(MAGCAL_IN_PROGRESS));
    TEST_ASSERT_EQUAL_INT(0, magcal_status_is_outcome((magcal_status_t)2));
}

static void test_version_has_one_source(void)
{
    TEST_ASSERT_EQUAL_UINT32(MAGCAL_VERSION, magcal_version());
    TEST_ASSERT_EQUAL_UINT32(MAGCAL_VERSION_MAJOR * 10000u + MAGCAL_VERSION_MINOR * 100u + MAGCAL_VERSION_PATCH,
                             magcal_version());
    TEST_ASSERT_EQUAL_STRING(MAGCAL_VERSION_STRING, magcal_version_str());
#ifdef MAGCAL_PROJECT_VERSION
    TEST_ASSERT_EQUAL_STRING(MAGCAL_PROJECT_VERSION, magcal_version_str()); /* CMake's project(VERSION) */
#endif
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_config_fingerprint_sees_every_limit);
    RUN_TEST(test_init_checked_foreign_config_returns_mismatch_untouched);
    RUN_TEST(test_calibrator_state_null_is_invalid_not_failed);
    RUN_TEST(test_workspace_declare_is_aligned_and_large_enough);
    RUN_TEST(test_status_is_outcome_only_for_normal_outcomes);
    RUN_TEST(test_version_has_one_source);
    return UNITY_END();
}
