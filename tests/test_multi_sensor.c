/*
 * Two magnetometers, two calibrators, side by side (issue 13, "Several magnetometers").
 *
 * Two fake sensors (port/fake, indices 0 and 1) see the same vehicle turn through two different
 * installations (known hard and soft iron, different field radius and unit). Each calibrator is
 * polled only with its own index (magcal_calibrator_poll_n) in one interleaved loop, as a
 * firmware super-loop would. Truth: each adopted calibration is checked against its own
 * installation (hard-iron offset, corrected-radius spread, heading RMS vs the true heading), and
 * against the other one (applied to the wrong sensor it is visibly wrong: no silent cross-talk).
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "magcal/calibrator.h"
#include "magcal_port_fake.h"
#include "test_util.h"
#include "unity.h"

#define CAP 400u
#define ROWS 400u

static magcal_calibrator_t g_cal[2];
static magcal_vec2_t g_buf[2][CAP];
static uint32_t g_work[2][(MAGCAL_CALIBRATOR_WORKSPACE_LEN(CAP) + 3u) / 4u];

/* Sensor 0: radius 40 (uT), mild soft iron; sensor 1: radius 300 (LSB), strong soft iron,
 * large offset of the other sign. */
static const test_distortion_t k_inst[2] = {
    {40.0f, {{1.05f, 0.10f}, {0.10f, 0.90f}}, 12.0f, -7.0f},
    {300.0f, {{0.80f, -0.20f}, {-0.20f, 1.15f}}, -250.0f, 410.0f},
};
static const double k_sigma[2] = {0.4, 3.0}; /* 1 % of the radius per axis */

void setUp(void) { magcal_port_fake_reset(); }
void tearDown(void) {}

static void init_both(void)
{
    size_t s;
    for (s = 0; s < 2u; ++s) {
        magcal_calibrator_cfg_t cfg = MAGCAL_CALIBRATOR_CFG_DEFAULT;
        cfg.min_spacing_deg = 0.0f;
        cfg.max_per_bin = 0u;
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_init(&g_cal[s], &cfg, g_buf[s], CAP, g_work[s],
                                                                sizeof g_work[s]));
    }
}

/* Heading RMS (deg) of cal on n fresh samples of installation `inst` against the true heading,
 * the constant rotation of the correction form removed (circular mean of the differences). */
static double heading_rms(const magcal_cal2d_t *cal, size_t inst, uint32_t seed)
{
    uint32_t rng = seed;
    double e[360];
    double sx = 0.0, sy = 0.0, mean, ss = 0.0;
    size_t k;
    for (k = 0; k < 360u; ++k) {
        double psi = (double)k + 0.5;
        magcal_vec2_t raw = test_distorted_sample(&k_inst[inst], psi, k_sigma[inst], &rng);
        float hd;
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_heading_compute(cal, raw, 0.0f, &hd, NULL));
        e[k] = test_angle_diff_deg((double)hd, psi);
        sx += cos(e[k] * 3.14159265358979323846 / 180.0);
        sy += sin(e[k] * 3.14159265358979323846 / 180.0);
    }
    mean = atan2(sy, sx) * 180.0 / 3.14159265358979323846;
    for (k = 0; k < 360u; ++k) {
        double d = test_angle_diff_deg(e[k], mean);
        ss += d * d;
    }
    return sqrt(ss / 360.0);
}

static void test_two_calibrators_two_sensors_each_converge_to_own_truth(void)
{
    uint32_t rng[2] = {1234u, 5678u};
    magcal_cal2d_t cal[2] = {MAGCAL_CAL2D_IDENTITY, MAGCAL_CAL2D_IDENTITY};
    magcal_cal_report_t rep;
    size_t i, s;
    init_both();
    /* the vehicle turns; both sensors sample every row */
    for (i = 0; i < ROWS; ++i) {
        double psi = 5.0 + 360.0 * (double)i / (double)ROWS;
        for (s = 0; s < 2u; ++s) {
            magcal_vec2_t p = test_distorted_sample(&k_inst[s], psi, k_sigma[s], &rng[s]);
            magcal_vec3_t v;
            v.x = p.x;
            v.y = p.y;
            v.z = -20.0f; /* ignored by the 2-D calibrator */
            TEST_ASSERT_EQUAL_INT(0, magcal_port_fake_push_mag_n((uint8_t)s, v));
        }
    }
    /* one super-loop: each calibrator polls its own sensor */
    for (i = 0; i < ROWS; ++i) {
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_poll_n(&g_cal[0], 0u));
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_poll_n(&g_cal[1], 1u));
    }
    TEST_ASSERT_EQUAL_UINT(ROWS, (unsigned)magcal_port_fake_mag_calls_n(0u));
    TEST_ASSERT_EQUAL_UINT(ROWS, (unsigned)magcal_port_fake_mag_calls_n(1u));
    /* both queues drained: the next poll of each reports its own end of data */
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NO_DATA, magcal_calibrator_poll_n(&g_cal[0], 0u));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NO_DATA, magcal_calibrator_poll_n(&g_cal[1], 1u));
    for (s = 0; s < 2u; ++s) {
        double r = (double)k_inst[s].h0;
        double rms_own, rms_other, floor_deg;
        char msg[160];
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_run(&g_cal[s], &cal[s], &rep));
        TEST_ASSERT_EQUAL_UINT(ROWS, rep.samples);
        /* hard iron within 2 % of the radius of its own truth */
        TEST_ASSERT_FLOAT_WITHIN((float)(0.02 * r), k_inst[s].bx, cal[s].offset.x);
        TEST_ASSERT_FLOAT_WITHIN((float)(0.02 * r), k_inst[s].by, cal[s].offset.y);
        /* the corrected ring is round to the noise level (1 %) */
        TEST_ASSERT_TRUE(rep.residual_rel < 0.015f);
        /* heading RMS close to the noise floor: sigma / (radius x smallest singular value) rad */
        floor_deg = k_sigma[s] / (r * 0.7) * 180.0 / 3.14159265358979323846;
        rms_own = heading_rms(&cal[s], s, 99u + (uint32_t)s);
        rms_other = heading_rms(&cal[1u - s], s, 199u + (uint32_t)s);
        snprintf(msg, sizeof msg, "sensor %u: offset (%.2f, %.2f) truth (%.2f, %.2f); heading rms %.3f deg "
                                  "(bound %.3f), with the other sensor's calibration %.1f deg",
                 (unsigned)s, (double)cal[s].offset.x, (double)cal[s].offset.y, (double)k_inst[s].bx,
                 (double)k_inst[s].by, rms_own, floor_deg, rms_other);
        printf("%s\n", msg);
        TEST_ASSERT_TRUE_MESSAGE(rms_own < floor_deg, msg);
        TEST_ASSERT_TRUE_MESSAGE(rms_other > 10.0 * rms_own, msg);
    }
}

/* Polling one sensor never touches the other's queue; bad indices are refused without a read. */
static void test_poll_n_isolates_sensors_and_refuses_bad_index(void)
{
    magcal_vec3_t a = {1.0f, 2.0f, 3.0f};
    magcal_vec3_t b = {-4.0f, 5.0f, 6.0f};
    magcal_vec3_t got;
    init_both();
    TEST_ASSERT_EQUAL_INT(0, magcal_port_fake_push_mag_n(0u, a));
    TEST_ASSERT_EQUAL_INT(0, magcal_port_fake_push_mag_status_n(1u, MAGCAL_ERR_PORT));
    TEST_ASSERT_EQUAL_INT(0, magcal_port_fake_push_mag_n(1u, b));
    TEST_ASSERT_EQUAL_INT(-1, magcal_port_fake_push_mag_n(MAGCAL_PORT_FAKE_SENSORS, a));
    /* a bus error on sensor 1 is sensor 1's: sensor 0 still reads its sample */
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_PORT, magcal_calibrator_poll_n(&g_cal[1], 1u));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_poll_n(&g_cal[0], 0u));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NO_DATA, magcal_calibrator_poll_n(&g_cal[0], 0u));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_port_mag_read_n(1u, &got));
    TEST_ASSERT_EQUAL_FLOAT(-4.0f, got.x);
    /* index out of the library's range: refused before the port is called */
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_calibrator_poll_n(&g_cal[0], (uint8_t)MAGCAL_PORT_MAX_SENSORS));
    /* inside the library's range but a sensor this board lacks: the port says ARG */
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_calibrator_poll_n(&g_cal[0], (uint8_t)MAGCAL_PORT_FAKE_SENSORS));
    TEST_ASSERT_EQUAL_UINT(2u, (unsigned)magcal_port_fake_mag_calls_n(0u));
    TEST_ASSERT_EQUAL_UINT(2u, (unsigned)magcal_port_fake_mag_calls_n(1u));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_calibrator_poll_n(NULL, 0u));
    memset(&g_cal[1], 0, sizeof g_cal[1]);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NOT_INITIALISED, magcal_calibrator_poll_n(&g_cal[1], 1u));
}

/* The single-sensor call is sensor 0: existing firmware (poll()) and poll_n(cal, 0) share a stream. */
static void test_poll_is_sensor_zero(void)
{
    magcal_vec3_t a = {1.0f, 2.0f, 3.0f};
    init_both();
    TEST_ASSERT_EQUAL_INT(0, magcal_port_fake_push_mag(a));
    TEST_ASSERT_EQUAL_INT(0, magcal_port_fake_push_mag_n(0u, a));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_poll(&g_cal[0]));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_poll_n(&g_cal[0], 0u));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NO_DATA, magcal_calibrator_poll(&g_cal[0]));
    TEST_ASSERT_EQUAL_UINT(3u, (unsigned)magcal_port_fake_mag_calls());
    TEST_ASSERT_EQUAL_UINT(0u, (unsigned)magcal_port_fake_mag_calls_n(1u));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_two_calibrators_two_sensors_each_converge_to_own_truth);
    RUN_TEST(test_poll_n_isolates_sensors_and_refuses_bad_index);
    RUN_TEST(test_poll_is_sensor_zero);
    return UNITY_END();
}
