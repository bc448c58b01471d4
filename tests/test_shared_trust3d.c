/*
 * The 3-D trust gates (issue 12, docs/calibration_3d.md "Trust gates") on the real recordings in
 * MAGCAL_SHARED_DIR/data/real (registered only when that directory exists):
 *  - every rest phase of broad_mocap_stationary_magnet (rows with movement == 0: start, two
 *    10 s breaks, end) alone: NO_MOTION with every model (before: OK, quadric9, F = 1.7 uT);
 *  - every full 3-D tumble recording still calibrates with AUTO (quadric9), with a residual
 *    below 5 % F;
 *  - rotation about one axis: the level car circles vn100_car_circles_a/_b and the two turns of
 *    hmc5883l_mpu6050_vertical_axis_turns_set1 / hmc5883l_esphome_flat_turns: SINGLE_AXIS with
 *    every model.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "magcal/ellipsoid.h"
#include "test_csv.h"
#include "unity.h"

/* magcal_ellipsoid_fit's fixed scratch (the workspace-free fit: no per-sample storage) */
static magcal_ellipsoid_fit_scratch_t g_fit_scratch;

#define MAX_ROWS 65536u

static magcal_vec3_t g_rows[MAX_ROWS];
static double g_cells[MAX_ROWS * 4u];
static double g_move[MAX_ROWS];

void setUp(void) {}
void tearDown(void) {}

static const magcal_ellipsoid_model_t MODELS[4] = {MAGCAL_ELLIPSOID_MODEL_AUTO, MAGCAL_ELLIPSOID_MODEL_QUADRIC9,
                                                   MAGCAL_ELLIPSOID_MODEL_QUADRIC10, MAGCAL_ELLIPSOID_MODEL_SPHERE};
static const char *const MODEL_NAME[4] = {"auto", "quadric9", "quadric10", "sphere"};

/* mx, my, mz (and movement, optional) of data/real/<name>/data.csv, finite rows only. */
static size_t read_rec(const char *name)
{
    static const char *const cols[4] = {"mx", "my", "mz", "movement"};
    char path[512];
    size_t nr, i, n = 0u;
    (void)snprintf(path, sizeof path, "%s/data/real/%s/data.csv", MAGCAL_SHARED_DIR, name);
    nr = test_read_csv(path, cols, 4u, 3u, g_cells, MAX_ROWS);
    for (i = 0u; i < nr; ++i) {
        const double *r = &g_cells[i * 4u];
        if (isfinite(r[0]) && isfinite(r[1]) && isfinite(r[2])) {
            g_rows[n].x = (float)r[0];
            g_rows[n].y = (float)r[1];
            g_rows[n].z = (float)r[2];
            g_move[n] = r[3];
            ++n;
        }
    }
    return n;
}

static void test_trust3d_shared_broad_rest_phases_return_no_motion(void)
{
    size_t n = read_rec("broad_mocap_stationary_magnet"), i = 0u, phases = 0u;
    TEST_ASSERT_TRUE(n > 10000u);
    while (i < n) {
        size_t j = i;
        int k;
        while (j < n && (g_move[j] == 0.0) == (g_move[i] == 0.0)) {
            ++j;
        }
        if (g_move[i] == 0.0) {
            for (k = 0; k < 4; ++k) {
                magcal_ellipsoid_cfg_t cfg = MAGCAL_ELLIPSOID_CFG_DEFAULT;
                magcal_ellipsoid_result_t r;
                magcal_status_t st;
                cfg.model = MODELS[k];
                st = magcal_ellipsoid_fit(&g_rows[i], j - i, &cfg, &g_fit_scratch, &r);
                printf("broad rest phase rows %5u..%5u (%4u) %-9s: %s\n", (unsigned)i, (unsigned)(j - 1u),
                       (unsigned)(j - i), MODEL_NAME[k], magcal_status_str(st));
                TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NO_MOTION, st);
            }
            phases++;
        }
        i = j;
    }
    TEST_ASSERT_EQUAL_UINT(4u, (unsigned)phases); /* start, two breaks, end (README) */
}

static void test_trust3d_shared_full_tumbles_still_calibrate(void)
{
    static const char *const names[] = {"broad_mocap_stationary_magnet", "ellipsoid_fit_python_sample",
                                        "fxos8700_tumble",               "hmc5883l_mpu6050_tumble_set2",
                                        "hmc58x3_magneto_sample_tumble", "lsm303d_altimu10v3_tumble",
                                        "lsm9ds1_adafruit_tumble",       "lsm9ds1_pmodnav_tumble",
                                        "qmc5883l_tumble"};
    size_t d;
    for (d = 0; d < sizeof names / sizeof names[0]; ++d) {
        const magcal_ellipsoid_cfg_t cfg = MAGCAL_ELLIPSOID_CFG_DEFAULT;
        magcal_ellipsoid_result_t r;
        size_t n = read_rec(names[d]);
        magcal_status_t st = magcal_ellipsoid_fit(g_rows, n, &cfg, &g_fit_scratch, &r);
        if (st == MAGCAL_OK) {
            printf("%-32s n %5u: ok %s, residual %.2f %% F, centre std %.4f F, shape std %.4f, motion SNR %.0f, "
                   "coverage %.2f, rejected %u\n",
                   names[d], (unsigned)n, (r.model == MAGCAL_ELLIPSOID_MODEL_QUADRIC9) ? "quadric9" : "other",
                   100.0 * (double)(r.residual_rms / r.cal.field), (double)r.centre_std_rel, (double)r.shape_std,
                   (double)r.motion_snr, (double)r.coverage, (unsigned)r.n_rejected);
        } else {
            printf("%-32s n %5u: %s\n", names[d], (unsigned)n, magcal_status_str(st));
        }
        TEST_ASSERT_EQUAL_INT_MESSAGE(MAGCAL_OK, st, names[d]);
        TEST_ASSERT_EQUAL_INT(MAGCAL_ELLIPSOID_MODEL_QUADRIC9, r.model);
        TEST_ASSERT_TRUE(r.residual_rms < 0.05f * r.cal.field);
    }
}

static void test_trust3d_shared_single_axis_turns_return_single_axis(void)
{
    static const char *const names[] = {"vn100_car_circles_a", "vn100_car_circles_b",
                                        "hmc5883l_mpu6050_vertical_axis_turns_set1", "hmc5883l_esphome_flat_turns"};
    size_t d;
    int k;
    for (d = 0; d < sizeof names / sizeof names[0]; ++d) {
        size_t n = read_rec(names[d]);
        TEST_ASSERT_TRUE(n > 100u);
        for (k = 0; k < 4; ++k) {
            magcal_ellipsoid_cfg_t cfg = MAGCAL_ELLIPSOID_CFG_DEFAULT;
            magcal_ellipsoid_result_t r;
            magcal_status_t st;
            cfg.model = MODELS[k];
            st = magcal_ellipsoid_fit(g_rows, n, &cfg, &g_fit_scratch, &r);
            printf("%-42s n %5u %-9s: %s\n", names[d], (unsigned)n, MODEL_NAME[k], magcal_status_str(st));
            TEST_ASSERT_EQUAL_INT_MESSAGE(MAGCAL_ERR_SINGLE_AXIS, st, names[d]);
        }
    }
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_trust3d_shared_broad_rest_phases_return_no_motion);
    RUN_TEST(test_trust3d_shared_full_tumbles_still_calibrate);
    RUN_TEST(test_trust3d_shared_single_axis_turns_return_single_axis);
    return UNITY_END();
}
