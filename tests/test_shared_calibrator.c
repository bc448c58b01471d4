/*
 * The calibration pipeline on every recorded dump in MAGCAL_SHARED_DIR/data/real whose motion is a
 * planar rotation (read from each README): flat turns, a vertical-axis rig whose horizontal plane
 * is (mx, mz), a 324-degree hand turn, car circles. Each dump is read with a small CSV reader,
 * decimated uniformly to at most MAGCAL_MAX_SAMPLES rows, calibrated with the DEFAULT pipeline,
 * and the radius spread std/mean over every (non-glitch) row is compared raw (identity) vs
 * corrected.
 *
 * Expectation per dump: drop >= min(5, 0.95 * ref_drop), where ref_drop is the drop of the plain
 * float64 least-squares ellipse fit of all rows (tools/ref_real_spread.py, an independent
 * implementation): on two hand-turned LSM9DS1 recordings no ellipse correction reaches 5x (tilt
 * wobble and disturbances leave 2.6 % and 5.9 % spread).
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "magcal/calibrator.h"
#include "test_csv.h"
#include "test_util.h"
#include "unity.h"

#define CAP MAGCAL_MAX_SAMPLES
#define MAX_ROWS 8192u

static magcal_calibrator_t g_cal;
static magcal_vec2_t g_buf[CAP];
static uint32_t g_work[(MAGCAL_CALIBRATOR_WORKSPACE_LEN(CAP) + 3u) / 4u];
static magcal_vec2_t g_rows[MAX_ROWS];
static uint8_t g_glitch[MAX_ROWS];

void setUp(void) {}
void tearDown(void) {}

/* Read columns xcol, ycol (and glitch if present) of a uniform CSV; returns the row count. */
static double g_cells[MAX_ROWS * 3u];

static size_t read_csv(const char *path, const char *xcol, const char *ycol)
{
    const char *cols[3] = {xcol, ycol, "glitch"}; /* glitch optional */
    size_t nr = test_read_csv(path, cols, 3u, 2u, g_cells, MAX_ROWS);
    size_t i;
    size_t n = 0u;
    for (i = 0u; i < nr; ++i) {
        const double *r = &g_cells[i * 3u];
        if (isfinite(r[0]) && isfinite(r[1])) {
            g_rows[n].x = (float)r[0];
            g_rows[n].y = (float)r[1];
            g_glitch[n] = (uint8_t)(r[2] > 0.5); /* NaN (no column) compares false */
            ++n;
        }
    }
    return n;
}

static double spread(size_t n, const magcal_cal2d_t *c)
{
    return test_radius_spread(c, g_rows, g_glitch, n);
}

static void check_dump(const char *name, const char *xcol, const char *ycol, double ref_drop)
{
    char path[512];
    size_t n, i, step;
    magcal_calibrator_cfg_t cfg = MAGCAL_CALIBRATOR_CFG_DEFAULT;
    magcal_cal2d_t c = MAGCAL_CAL2D_IDENTITY;
    magcal_cal2d_t ident = MAGCAL_CAL2D_IDENTITY;
    magcal_cal_report_t rep;
    magcal_status_t st;
    double raw, cor, want;
    snprintf(path, sizeof path, "%s/data/real/%s/data.csv", MAGCAL_SHARED_DIR, name);
    n = read_csv(path, xcol, ycol);
    TEST_ASSERT_TRUE(n >= 20u);
    step = (n + CAP - 1u) / CAP;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK,
                          magcal_calibrator_init(&g_cal, &cfg, g_buf, CAP, g_work, sizeof g_work));
    for (i = 0; i < n; i += step) {
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_push(&g_cal, g_rows[i]));
    }
    st = magcal_calibrator_run(&g_cal, &c, &rep);
    raw = spread(n, &ident);
    cor = st == MAGCAL_OK ? spread(n, &c) : INFINITY;
    want = 0.95 * ref_drop < 5.0 ? 0.95 * ref_drop : 5.0;
    printf("%-44s (%s,%s) rows %5u used %4u/%4u (filter -%u, residual -%u) cov %3.0f  spread %.4f "
           "-> %.4f  "
           "x%5.1f (float64 LS x%5.1f, need x%.1f)  est err %.2f deg  st %d\n",
           name, xcol, ycol, (unsigned)n, (unsigned)rep.used, (unsigned)rep.samples,
           (unsigned)rep.rejected_filter, (unsigned)rep.rejected_consensus,
           (double)rep.coverage_deg, raw, cor, raw / cor, ref_drop, want,
           (double)rep.est_heading_err_deg, (int)st);
    TEST_ASSERT_EQUAL_INT_MESSAGE(MAGCAL_OK, st, name);
    TEST_ASSERT_TRUE_MESSAGE(raw / cor >= want, name);
}

/* ref_drop values: tools/ref_real_spread.py on each data.csv (all non-glitch rows). */
static void test_run_shared_planar_dumps_spread_drops(void)
{
    printf("\n");
    check_dump("hmc5883l_esphome_flat_turns", "mx", "my", 18.713);
    check_dump("lsm9ds1_pmodnav_flat_turns", "mx", "my", 4.884);
    check_dump("lsm9ds1_pmodnav_driver_glitches", "mx", "my", 2.505);
    check_dump("hmc5883l_mpu6050_vertical_axis_turns_set1", "mx", "mz", 5.770);
    check_dump("jremington_magcal2d_turn", "mx", "my", 73.883);
    check_dump("vn100_car_circles_a", "mx", "my", 10.352);
    check_dump("vn100_car_circles_b", "mx", "my", 7.858);
}

/*
 * vn100_car_circles_b in stream order, as a firmware fills its buffer: every k-th row until the
 * capacity is full, so the window starts with the 25 s parked phase (about 1000 rows at one
 * heading) and ends after one to two turns; the parked samples are 35..50 % of the window. Before
 * the density stage thinned clumps, the automatic OPTICS parameters kept the parked clump and
 * rejected the turn: of these 4 windows the first two gave TOO_MANY_OUTLIERS (filter -186 of 300,
 * -246 of 400), the third COVERAGE (filter -160 of 800), the last x7.5. Each must calibrate with
 * default settings, the spread over the window's rows dropping >= 5x (measured x6.7 x6.7 x6.7 x7.5).
 */
static void check_window(size_t cap, size_t step)
{
    char path[512];
    size_t n, i, fed = 0u, end;
    magcal_calibrator_cfg_t cfg = MAGCAL_CALIBRATOR_CFG_DEFAULT;
    magcal_cal2d_t c = MAGCAL_CAL2D_IDENTITY;
    magcal_cal2d_t ident = MAGCAL_CAL2D_IDENTITY;
    magcal_cal_report_t rep;
    magcal_status_t st;
    double raw, cor;
    char msg[64];
    snprintf(path, sizeof path, "%s/data/real/vn100_car_circles_b/data.csv", MAGCAL_SHARED_DIR);
    n = read_csv(path, "mx", "my");
    TEST_ASSERT_TRUE(n > cap * step);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK,
                          magcal_calibrator_init(&g_cal, &cfg, g_buf, cap, g_work, sizeof g_work));
    for (i = 0; fed < cap; i += step, ++fed) {
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_push(&g_cal, g_rows[i]));
    }
    end = i;
    st = magcal_calibrator_run(&g_cal, &c, &rep);
    raw = spread(end, &ident);
    cor = st == MAGCAL_OK ? spread(end, &c) : INFINITY;
    printf("vn100_car_circles_b rows [0, %4u) every %2u-th: used %4u/%4u (filter -%u, residual "
           "-%u) cov %3.0f "
           "spread %.4f -> %.4f x%5.1f  st %d\n",
           (unsigned)end, (unsigned)step, (unsigned)rep.used, (unsigned)rep.samples,
           (unsigned)rep.rejected_filter, (unsigned)rep.rejected_consensus,
           (double)rep.coverage_deg, raw, cor, raw / cor, (int)st);
    snprintf(msg, sizeof msg, "capacity %u every %u-th row", (unsigned)cap, (unsigned)step);
    TEST_ASSERT_EQUAL_INT_MESSAGE(MAGCAL_OK, st, msg);
    TEST_ASSERT_TRUE_MESSAGE(raw / cor >= 5.0, msg);
}

static void test_run_vn100_car_circles_b_stream_windows_starting_parked(void)
{
    printf("\n");
    check_window(300u, 8u);
    check_window(400u, 6u);
    check_window(800u, 3u);
    check_window(1024u, 3u);
}

/*
 * Every stream window of vn100_car_circles_b that holds at least one turn after the parked phase
 * (rows [off, off + cap * k) every k-th row, >= 2200 rows): capacities 256..1024, k = 1..16,
 * offsets 0..3. Counted: OK, TOO_MANY_OUTLIERS (the clump kept: must be 0), other refusals; every
 * OK must drop the spread over the window's rows >= 4x (no silent wrong answer).
 * Measured before the thinning: 292 of 322 OK, 15 TOO_MANY_OUTLIERS, 15 COVERAGE; after: 321 OK,
 * 1 COVERAGE (the consensus' residual scale, dominated by the parked samples' small noise, cuts
 * part of the turn: consensus.c, not the density stage).
 */
static void test_run_vn100_car_circles_b_every_stream_window_with_a_turn(void)
{
    static const size_t caps[] = {256u, 300u, 400u, 512u, 600u, 800u, 1024u};
    char path[512];
    size_t n, ci, step, off;
    unsigned tot = 0u, ok = 0u, clump = 0u;
    double worst = INFINITY;
    snprintf(path, sizeof path, "%s/data/real/vn100_car_circles_b/data.csv", MAGCAL_SHARED_DIR);
    n = read_csv(path, "mx", "my");
    for (ci = 0; ci < sizeof caps / sizeof caps[0]; ++ci) {
        for (step = 1u; step <= 16u; ++step) {
            for (off = 0u; off < step && off < 4u; ++off) {
                magcal_calibrator_cfg_t cfg = MAGCAL_CALIBRATOR_CFG_DEFAULT;
                magcal_cal2d_t c = MAGCAL_CAL2D_IDENTITY;
                magcal_cal2d_t ident = MAGCAL_CAL2D_IDENTITY;
                magcal_cal_report_t rep;
                magcal_status_t st;
                size_t i, fed = 0u;
                if (caps[ci] * step < 2200u) {
                    continue;
                }
                TEST_ASSERT_EQUAL_INT(
                    MAGCAL_OK,
                    magcal_calibrator_init(&g_cal, &cfg, g_buf, caps[ci], g_work, sizeof g_work));
                for (i = off; i < n && fed < caps[ci]; i += step, ++fed) {
                    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_push(&g_cal, g_rows[i]));
                }
                st = magcal_calibrator_run(&g_cal, &c, &rep);
                ++tot;
                clump += st == MAGCAL_ERR_TOO_MANY_OUTLIERS;
                if (st == MAGCAL_OK) {
                    const size_t end = i < n ? i : n;
                    const double drop = spread(end, &ident) / spread(end, &c);
                    ++ok;
                    worst = drop < worst ? drop : worst;
                    TEST_ASSERT_TRUE(drop >= 4.0);
                }
            }
        }
    }
    printf(
        "vn100_car_circles_b stream windows with a turn: %u, OK %u (smallest spread drop x%.1f), "
        "TOO_MANY_OUTLIERS %u, other refusals %u\n",
        tot, ok, worst, clump, tot - ok - clump);
    TEST_ASSERT_EQUAL_UINT(322u, tot);
    TEST_ASSERT_EQUAL_UINT(0u, clump);
    TEST_ASSERT_TRUE(ok >= 320u);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_run_shared_planar_dumps_spread_drops);
    RUN_TEST(test_run_vn100_car_circles_b_stream_windows_starting_parked);
    RUN_TEST(test_run_vn100_car_circles_b_every_stream_window_with_a_turn);
    return UNITY_END();
}
