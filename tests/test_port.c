/* Tests of the hand-written port fake that unit tests link in place of hardware. */
#include "magcal_port_fake.h"
#include "unity.h"

void setUp(void) { magcal_port_fake_reset(); }
void tearDown(void) {}

static void test_fake_serves_queued_samples_then_no_data(void)
{
    magcal_vec3_t v = {1.0f, 2.0f, 3.0f}, out = {0};
    TEST_ASSERT_EQUAL_INT(0, magcal_port_fake_push_mag(v));
    TEST_ASSERT_EQUAL_INT(0, magcal_port_fake_push_mag_status(MAGCAL_ERR_TIMEOUT));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_port_mag_read(&out));
    TEST_ASSERT_EQUAL_FLOAT(2.0f, out.y);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_TIMEOUT, magcal_port_mag_read(&out));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NO_DATA, magcal_port_mag_read(&out));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_port_mag_read(NULL));
    TEST_ASSERT_EQUAL_UINT(4u, magcal_port_fake_mag_calls());
}

static void test_fake_clock_is_monotonic_with_step(void)
{
    magcal_port_fake_set_clock_step(25u);
    TEST_ASSERT_EQUAL_UINT32(0u, magcal_port_millis());
    TEST_ASSERT_EQUAL_UINT32(25u, magcal_port_millis());
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_fake_serves_queued_samples_then_no_data);
    RUN_TEST(test_fake_clock_is_monotonic_with_step);
    return UNITY_END();
}
