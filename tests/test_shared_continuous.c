/*
 * The continuous 2-D calibrator (continuous.h) on every shared real planar recording in the x, y
 * plane (MAGCAL_SHARED_DIR/data/real, READMEs), WHOLE and in stream order: one push + STEPS_PER_ROW
 * steps per row at the default configuration (a sliced solve is ~1000 steps) and, after the last
 * row, steps until the solve under way ends (vn100_car_circles_b starts parked). Each must end with an
 * adopted calibration whose radius spread std/mean over every non-glitch row drops by at least
 * min(5, 0.9 x ref_drop), ref_drop = the drop of the plain float64 least-squares ellipse of all
 * rows (tools/ref_real_spread.py, as tests/test_shared_calibrator.c).
 * (hmc5883l_mpu6050_vertical_axis_turns_set1 turns in the (x, z) plane: not a stream case here.)
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "magcal/continuous.h"
#include "test_csv.h"
#include "test_util.h"
#include "unity.h"

#define SLOTS MAGCAL_CONT_SLOTS(36u, 8u)
#define MAX_ROWS 8192u
#define STEPS_PER_ROW 4u /* step() calls per row: a control loop at 4 x the sample rate */

static magcal_intake_slot_t g_slots[SLOTS];
static magcal_vec2_t g_buf[SLOTS];
static MAGCAL_CALIBRATOR_WORKSPACE_DECLARE(g_work, SLOTS);
static magcal_cont_t g_cc;
static magcal_vec2_t g_rows[MAX_ROWS];
static uint8_t g_glitch[MAX_ROWS];
static double g_t[MAX_ROWS];
static double g_cells[MAX_ROWS * 4u];

void setUp(void) {}
void tearDown(void) {}

/* Read t, x, y, glitch; rows with a non-finite x or y are skipped (not fed). */
static size_t read_csv(const char *path)
{
    const char *cols[4] = {"mx", "my", "glitch", "t"}; /* glitch, t optional */
    size_t nr = test_read_csv(path, cols, 4u, 2u, g_cells, MAX_ROWS);
    size_t i;
    size_t n = 0u;
    for (i = 0u; i < nr; ++i) {
        const double *r = &g_cells[i * 4u];
        if (isfinite(r[0]) && isfinite(r[1])) {
            g_rows[n].x = (float)r[0];
            g_rows[n].y = (float)r[1];
            g_glitch[n] = (uint8_t)(r[2] > 0.5); /* NaN (no column) compares false */
            g_t[n] = r[3];
            ++n;
        }
    }
    return n;
}

static void check_stream(const char *name, double ref_drop)
{
    char path[512];
    size_t n, i;
    unsigned k;
    magcal_cont_cfg_t cfg = MAGCAL_CONT_CFG_DEFAULT;
    magcal_cal2d_t ident = MAGCAL_CAL2D_IDENTITY;
    unsigned trusted = 0u;
    long first = -1;
    double raw, cor, want;
    snprintf(path, sizeof path, "%s/data/real/%s/data.csv", MAGCAL_SHARED_DIR, name);
    n = read_csv(path);
    TEST_ASSERT_TRUE(n >= 20u);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_init(&g_cc, &cfg, NULL, g_slots, SLOTS, g_buf, g_work, sizeof g_work));
    for (i = 0u; i < n; ++i) {
        magcal_vec3_t m = {g_rows[i].x, g_rows[i].y, 0.0f};
        magcal_cont_heading_t hd;
        uint32_t t_ms = isfinite(g_t[i]) && isfinite(g_t[0]) ? (uint32_t)((g_t[i] - g_t[0]) * 1000.0) : (uint32_t)(i * 20u);
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_push(&g_cc, &m, t_ms));
        for (k = 0u; k < STEPS_PER_ROW; ++k) {
            if (magcal_cont_step(&g_cc) == MAGCAL_CONT_ADOPTED && first < 0) {
                first = (long)i;
            }
        }
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_heading(&g_cc, &m, 0.0f, &hd));
        trusted += hd.trust == MAGCAL_TRUST_OK ? 1u : 0u;
    }
    /* after the recording the firmware's loop goes on (no pushes) until the calibrator has nothing
     * left to do: no solve under way and 256 steps in a row IDLE (a refused or failed solve may be
     * followed by one on the samples stored while it ran; its sliced coverage count takes a few
     * steps) */
    {
        unsigned idle = 0u;
        for (k = 0u; k < 100000u && idle < 256u; ++k) {
            const magcal_cont_outcome_t o = magcal_cont_step(&g_cc);
            if (o == MAGCAL_CONT_ADOPTED && first < 0) {
                first = (long)n;
            }
            idle = (o == MAGCAL_CONT_IDLE && g_cc.stage == 0u) ? idle + 1u : 0u;
        }
    }
    raw = test_radius_spread(&ident, g_rows, g_glitch, n);
    cor = g_cc.generation > 0u ? test_radius_spread(&g_cc.cal, g_rows, g_glitch, n) : INFINITY;
    want = 0.9 * ref_drop < 5.0 ? 0.9 * ref_drop : 5.0;
    printf("%-34s rows %5u trusted %5u first adoption row %5ld generation %u changes %u  spread %.4f -> %.4f "
           "x%5.1f (float64 LS x%5.1f, need x%.1f)  est err %.2f deg\n",
           name, (unsigned)n, trusted, first, (unsigned)g_cc.generation, (unsigned)g_cc.changes, raw, cor,
           raw / cor, ref_drop, want, (double)g_cc.adopted_err);
    TEST_ASSERT_TRUE_MESSAGE(g_cc.generation >= 1u, name);
    TEST_ASSERT_TRUE_MESSAGE(raw / cor >= want, name);
}

/* ref_drop values: tools/ref_real_spread.py (as tests/test_shared_calibrator.c). */
static void test_cont_shared_planar_recordings_calibrate_in_stream_order(void)
{
    check_stream("hmc5883l_esphome_flat_turns", 18.713);
    check_stream("lsm9ds1_pmodnav_flat_turns", 4.884);
    check_stream("lsm9ds1_pmodnav_driver_glitches", 2.505);
    check_stream("jremington_magcal2d_turn", 73.883);
    check_stream("vn100_car_circles_a", 10.352);
    check_stream("vn100_car_circles_b", 7.858);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_cont_shared_planar_recordings_calibrate_in_stream_order);
    return UNITY_END();
}
