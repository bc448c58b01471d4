/* The calibrator's use of the HAL port, checked with CMock's generated mock (built only with
 * MAGCAL_USE_CMOCK=ON; test_calibrator.c checks the same path with the hand-written fake).
 * Strict expectations: poll() reads exactly one magnetometer sample per call, never the
 * accelerometer or the clock, stores x/y of a good sample and passes port failures through
 * without storing anything; poll_n() reads the indexed port the same way. */
#include <math.h>

#include "Mockmagcal_port.h"
#include "magcal/calibrator.h"
#include "unity.h"

#define CAP 64u
static magcal_calibrator_t g_cal;
static magcal_vec2_t g_buf[CAP];
static uint8_t g_work[MAGCAL_CALIBRATOR_WORKSPACE_LEN(CAP)];

void setUp(void)
{
    magcal_calibrator_cfg_t cfg = MAGCAL_CALIBRATOR_CFG_DEFAULT;
    cfg.min_spacing_deg = 0.0f; /* store every sample: the test counts them */
    cfg.max_per_bin = 0u;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_init(&g_cal, &cfg, g_buf, CAP, g_work, sizeof g_work));
}
void tearDown(void) {}

void test_poll_good_sample_stores_xy(void)
{
    magcal_vec3_t v = {12.5f, -3.25f, 40.0f};
    magcal_port_mag_read_ExpectAnyArgsAndReturn(MAGCAL_OK);
    magcal_port_mag_read_ReturnThruPtr_out(&v);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_poll(&g_cal));
    TEST_ASSERT_EQUAL_UINT(1u, (unsigned)magcal_calibrator_count(&g_cal));
    TEST_ASSERT_EQUAL_FLOAT(12.5f, g_buf[0].x);
    TEST_ASSERT_EQUAL_FLOAT(-3.25f, g_buf[0].y);
}

void test_poll_port_errors_pass_through_and_store_nothing(void)
{
    magcal_port_mag_read_ExpectAnyArgsAndReturn(MAGCAL_ERR_TIMEOUT);
    magcal_port_mag_read_ExpectAnyArgsAndReturn(MAGCAL_ERR_PORT);
    magcal_port_mag_read_ExpectAnyArgsAndReturn(MAGCAL_ERR_NO_DATA);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_TIMEOUT, magcal_calibrator_poll(&g_cal));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_PORT, magcal_calibrator_poll(&g_cal));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NO_DATA, magcal_calibrator_poll(&g_cal));
    TEST_ASSERT_EQUAL_UINT(0u, (unsigned)magcal_calibrator_count(&g_cal));
}

void test_poll_nonfinite_sample_is_rejected(void)
{
    magcal_vec3_t v = {NAN, 1.0f, 0.0f};
    magcal_port_mag_read_ExpectAnyArgsAndReturn(MAGCAL_OK);
    magcal_port_mag_read_ReturnThruPtr_out(&v);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_calibrator_poll(&g_cal));
    TEST_ASSERT_EQUAL_UINT(0u, (unsigned)magcal_calibrator_count(&g_cal));
}

/* poll_n() reads through magcal_port_mag_read_n() only (never the single-sensor read), once per
 * call, and refuses an index beyond MAGCAL_PORT_MAX_SENSORS without calling the port at all. */
void test_poll_n_reads_through_indexed_port_only(void)
{
    magcal_vec3_t v = {7.0f, 8.0f, 9.0f};
    magcal_port_mag_read_n_ExpectAnyArgsAndReturn(MAGCAL_OK);
    magcal_port_mag_read_n_ReturnThruPtr_out(&v);
    magcal_port_mag_read_n_ExpectAnyArgsAndReturn(MAGCAL_ERR_ARG);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_poll_n(&g_cal, 1u));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_calibrator_poll_n(&g_cal, 3u));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_calibrator_poll_n(&g_cal, (uint8_t)MAGCAL_PORT_MAX_SENSORS));
    TEST_ASSERT_EQUAL_UINT(1u, (unsigned)magcal_calibrator_count(&g_cal));
    TEST_ASSERT_EQUAL_FLOAT(7.0f, g_buf[0].x);
}
