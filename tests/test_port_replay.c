/* Tests of the replay port (port/replay): array serving, injected errors, clock. */
#include "magcal_port_replay.h"
#include "unity.h"

static const magcal_vec3_t k_mag[5] = {{1, 0, 0}, {2, 0, 0}, {3, 0, 0}, {4, 0, 0}, {5, 0, 0}};
static const magcal_vec3_t k_acc[5] = {{0, 0, 1}, {0, 0, 1}, {0, 0, 1}, {0, 0, 1}, {0, 0, 1}};
static const uint32_t k_t[5] = {100, 110, 120, 130, 140};

void setUp(void) { magcal_port_replay_start(k_mag, k_acc, k_t, 5u, 10u); }
void tearDown(void) {}

static void test_replay_serves_rows_in_order_then_no_data(void)
{
    magcal_vec3_t v;
    float expect = 1.0f;
    while (magcal_port_mag_read(&v) == MAGCAL_OK) {
        TEST_ASSERT_EQUAL_FLOAT(expect, v.x);
        expect += 1.0f;
    }
    TEST_ASSERT_EQUAL_FLOAT(6.0f, expect);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NO_DATA, magcal_port_mag_read(&v));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_port_accel_read(&v));
    TEST_ASSERT_EQUAL_FLOAT(1.0f, v.z);
}

static void test_replay_injected_error_consumes_its_row(void)
{
    magcal_vec3_t v;
    TEST_ASSERT_EQUAL_INT(0, magcal_port_replay_inject_mag(1u, MAGCAL_ERR_PORT));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_port_mag_read(&v));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_PORT, magcal_port_mag_read(&v));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_port_mag_read(&v));
    TEST_ASSERT_EQUAL_FLOAT(3.0f, v.x);
    TEST_ASSERT_EQUAL_UINT32(120u, magcal_port_millis());
}

static void test_replay_periodic_timeouts(void)
{
    magcal_vec3_t v;
    int fails = 0, oks = 0;
    magcal_port_replay_inject_mag_every(2u, MAGCAL_ERR_TIMEOUT);
    for (;;) {
        magcal_status_t st = magcal_port_mag_read(&v);
        if (st == MAGCAL_ERR_NO_DATA) {
            break;
        }
        if (st == MAGCAL_ERR_TIMEOUT) {
            fails++;
        } else {
            oks++;
        }
    }
    TEST_ASSERT_EQUAL_INT(2, fails);
    TEST_ASSERT_EQUAL_INT(3, oks);
}

static void test_replay_without_timestamps_uses_period(void)
{
    magcal_vec3_t v;
    magcal_port_replay_start(k_mag, NULL, NULL, 5u, 20u);
    (void)magcal_port_mag_read(&v);
    (void)magcal_port_mag_read(&v);
    (void)magcal_port_mag_read(&v);
    TEST_ASSERT_EQUAL_UINT32(40u, magcal_port_millis());
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NO_DATA, magcal_port_accel_read(&v));
}

/* The replay port is one source: sensor 0 is the same stream as magcal_port_mag_read(), any
 * other index is refused without consuming a row. */
static void test_replay_mag_read_n_is_sensor_zero_only(void)
{
    magcal_vec3_t v;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_port_mag_read(&v));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_port_mag_read_n(1u, &v));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_port_mag_read_n(0u, &v));
    TEST_ASSERT_EQUAL_FLOAT(2.0f, v.x);
    TEST_ASSERT_EQUAL_UINT(2u, (unsigned)magcal_port_replay_position());
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_replay_serves_rows_in_order_then_no_data);
    RUN_TEST(test_replay_injected_error_consumes_its_row);
    RUN_TEST(test_replay_periodic_timeouts);
    RUN_TEST(test_replay_without_timestamps_uses_period);
    RUN_TEST(test_replay_mag_read_n_is_sensor_zero_only);
    return UNITY_END();
}
