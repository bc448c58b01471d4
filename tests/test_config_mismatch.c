/* A caller really compiled with other limits than the library: this translation unit gets
 * MAGCAL_COVERAGE_BINS=8 and MAGCAL_SWING_COG_BINS=12 (tests/CMakeLists.txt), the library its
 * defaults, so magcal_calibrator_t is 56 bytes shorter here (the overrun of issue 15) and
 * magcal_swing_cog_t differs too. Every stateful init must refuse with
 * MAGCAL_ERR_CONFIG_MISMATCH and write nothing past (or into) the caller's instance. */
#include <string.h>

#include "magcal.h"
#include "unity.h"

#if MAGCAL_COVERAGE_BINS != 8u || MAGCAL_SWING_COG_BINS != 12u
#error "tests/CMakeLists.txt compiles this test with MAGCAL_COVERAGE_BINS=8u MAGCAL_SWING_COG_BINS=12u"
#endif

void setUp(void) {}
void tearDown(void) {}

#define CAP 64u
/* the instance with a guard zone behind it: a library that wrote its own (larger) layout would
 * change the guard */
static struct {
    magcal_calibrator_t cal;
    uint8_t guard[256];
} g_c;
static struct {
    magcal_swing_cog_t cog;
    uint8_t guard[1024];
} g_s;
static struct {
    magcal_aided_t aided;
    uint8_t guard[64];
} g_a;
static magcal_vec2_t g_buf[CAP];
static MAGCAL_CALIBRATOR_WORKSPACE_DECLARE(g_work, CAP);

static void test_calibrator_init_other_limits_returns_config_mismatch(void)
{
    const magcal_calibrator_cfg_t cfg = MAGCAL_CALIBRATOR_CFG_DEFAULT;
    static uint8_t before[sizeof g_c];
    memset(&g_c, 0x3C, sizeof g_c);
    memcpy(before, &g_c, sizeof g_c);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_CONFIG_MISMATCH,
                          magcal_calibrator_init(&g_c.cal, &cfg, g_buf, CAP, g_work, sizeof g_work));
    TEST_ASSERT_EQUAL_MEMORY(before, &g_c, sizeof g_c);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_CONFIG_MISMATCH, magcal_config_check());
}

static void test_swing_cog_init_other_limits_returns_config_mismatch(void)
{
    const magcal_swing_cog_cfg_t cfg = MAGCAL_SWING_COG_CFG_DEFAULT;
    static uint8_t before[sizeof g_s];
    memset(&g_s, 0x3C, sizeof g_s);
    memcpy(before, &g_s, sizeof g_s);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_CONFIG_MISMATCH, magcal_swing_cog_init(&g_s.cog, &cfg));
    TEST_ASSERT_EQUAL_MEMORY(before, &g_s, sizeof g_s);
}

/* magcal_aided_t has the same layout here, but the fingerprint says the build differs. */
static void test_aided_init_other_limits_returns_config_mismatch(void)
{
    const magcal_aided_cfg_t cfg = MAGCAL_AIDED_CFG_DEFAULT;
    static uint8_t before[sizeof g_a];
    memset(&g_a, 0x3C, sizeof g_a);
    memcpy(before, &g_a, sizeof g_a);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_CONFIG_MISMATCH, magcal_aided_init(&g_a.aided, &cfg));
    TEST_ASSERT_EQUAL_MEMORY(before, &g_a, sizeof g_a);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_calibrator_init_other_limits_returns_config_mismatch);
    RUN_TEST(test_swing_cog_init_other_limits_returns_config_mismatch);
    RUN_TEST(test_aided_init_other_limits_returns_config_mismatch);
    return UNITY_END();
}
