/*
 * Tests of the 2-D calibration pipeline object (calibrator.h) on synthetic dumps with known truth
 * (tools/gen_dump.py: tests/data/synthetic/<scenario>.csv), on recorded LSM9DS1 flat turns
 * (tests/data/real, Apache-2.0), on bad input and through the port fake.
 *
 * Metric (algorithms.md 9): heading RMS over the verification rows [n_cal, n) of a dump, with the
 * adopted calibration, against heading_ref_deg; compared with the dump's floor_deg = the same RMS
 * with the TRUE calibration applied to the same noisy rows.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "magcal/calibrator.h"
#include "magcal_port_fake.h"
#include "test_dumps.h"
#include "unity.h"

#define CAP MAGCAL_MAX_SAMPLES

static magcal_calibrator_t g_cal;
static magcal_vec2_t g_buf[CAP];
static uint32_t g_work[(MAGCAL_CALIBRATOR_WORKSPACE_LEN(CAP) + 3u) / 4u];

void setUp(void) {}
void tearDown(void) {}

/* What one pipeline run on a synthetic dump gave. */
typedef struct {
    magcal_status_t st;
    magcal_cal_report_t rep;
    magcal_cal2d_t cal;
    double rms_deg;    /* heading RMS on the verification rows */
    double ratio;      /* rms / floor */
    size_t n_out;      /* true outliers */
    size_t caught;     /* true outliers flagged */
    size_t n_in;       /* true inliers */
    size_t false_rej;  /* true inliers flagged */
} run_t;

static double recall(const run_t *r)
{
    return r->n_out ? (double)r->caught / (double)r->n_out : 1.0;
}

static double false_rate(const run_t *r)
{
    return r->n_in ? (double)r->false_rej / (double)r->n_in : 0.0;
}

static magcal_vec2_t row(const magcal_test_dump_t *d, size_t i)
{
    magcal_vec2_t p;
    p.x = d->mx[i];
    p.y = d->my[i];
    return p;
}

/* Heading RMS of calibration c over rows [from, to) against heading_ref_deg. */
static double heading_rms(const magcal_test_dump_t *d, const magcal_cal2d_t *c, size_t from, size_t to)
{
    double ss = 0.0;
    size_t i;
    for (i = from; i < to; ++i) {
        float h;
        double e;
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_heading_compute(c, row(d, i), 0.0f, &h, NULL));
        e = fmod((double)h - (double)d->heading_ref_deg[i] + 540.0, 360.0) - 180.0;
        ss += e * e;
    }
    return sqrt(ss / (double)(to - from));
}

static void run_dump(const magcal_test_dump_t *d, const magcal_calibrator_cfg_t *cfg, run_t *r)
{
    size_t i;
    size_t n_cal;
    magcal_cal2d_t ident = MAGCAL_CAL2D_IDENTITY;
    TEST_ASSERT_NOT_NULL(d->truth);
    n_cal = d->truth->n_cal;
    memset(r, 0, sizeof *r);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_init(&g_cal, cfg, g_buf, CAP, g_work, sizeof g_work));
    for (i = 0; i < n_cal; ++i) {
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_push(&g_cal, row(d, i)));
    }
    r->cal = ident;
    r->st = magcal_calibrator_run(&g_cal, &r->cal, &r->rep);
    if (r->st != MAGCAL_OK) {
        r->rms_deg = INFINITY;
        r->ratio = INFINITY;
        return;
    }
    r->rms_deg = heading_rms(d, &r->cal, n_cal, d->n);
    r->ratio = r->rms_deg / (double)d->truth->floor_deg;
    for (i = 0; i < n_cal; ++i) {
        int inl = 1;
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_inlier(&g_cal, i, &inl));
        if (d->outlier[i] > 0.5f) {
            r->n_out++;
            r->caught += inl ? 0u : 1u;
        } else {
            r->n_in++;
            r->false_rej += inl ? 1u : 0u;
        }
    }
    r->false_rej = r->n_in - r->false_rej; /* counted inliers kept above */
}

static const magcal_test_dump_t *const g_scen[] = {
    &dump_synthetic_clean,        &dump_synthetic_heavy_noise,  &dump_synthetic_outliers_10,
    &dump_synthetic_outliers_25,  &dump_synthetic_outliers_35,  &dump_synthetic_raw_counts,
    &dump_synthetic_hard_iron_5x, &dump_synthetic_soft_iron_strong, &dump_synthetic_arc_300,
    &dump_synthetic_n60,          &dump_synthetic_near_ring,    &dump_synthetic_spikes,
};
#define N_SCEN (sizeof g_scen / sizeof g_scen[0])

/* ---------------------------------------------------------------- default pipeline on every scenario */

/* Default (automatic) parameters: heading RMS <= 1.2 x floor, recall >= 90 %, false rejections
 * <= 5 % of the inliers, on every synthetic scenario. */
static void test_run_every_scenario_default_within_1p2_floor(void)
{
    size_t s;
    magcal_calibrator_cfg_t cfg = MAGCAL_CALIBRATOR_CFG_DEFAULT;
    printf("\n%-34s %6s %8s %8s %6s %7s %7s %5s %5s\n", "scenario (default pipeline)", "status", "rms_deg",
           "floor", "ratio", "recall", "falsrej", "filt", "cons");
    for (s = 0; s < N_SCEN; ++s) {
        const magcal_test_dump_t *d = g_scen[s];
        run_t r;
        run_dump(d, &cfg, &r);
        printf("%-34s %6d %8.4f %8.4f %6.3f %7.3f %7.4f %5u %5u\n", d->name, (int)r.st, r.rms_deg,
               (double)d->truth->floor_deg, r.ratio, recall(&r), false_rate(&r),
               (unsigned)r.rep.rejected_filter, (unsigned)r.rep.rejected_consensus);
    }
    for (s = 0; s < N_SCEN; ++s) {
        const magcal_test_dump_t *d = g_scen[s];
        run_t r;
        run_dump(d, &cfg, &r);
        TEST_ASSERT_EQUAL_INT_MESSAGE(MAGCAL_OK, r.st, d->name);
        TEST_ASSERT_TRUE_MESSAGE(r.ratio <= 1.2, d->name);
        TEST_ASSERT_TRUE_MESSAGE(recall(&r) >= 0.90, d->name);
        TEST_ASSERT_TRUE_MESSAGE(false_rate(&r) <= 0.05, d->name);
        TEST_ASSERT_EQUAL_UINT8(1u, r.rep.adopted);
        TEST_ASSERT_EQUAL_INT(MAGCAL_CALIBRATOR_CALIBRATED, magcal_calibrator_state(&g_cal));
    }
}

/* Plain least squares (no filter, no consensus) fails the outlier scenarios: status not OK or
 * heading RMS > 3 x floor; OPTICS only (no consensus) numbers are printed for comparison. */
static void test_run_outlier_scenarios_plain_ls_fails(void)
{
    static const magcal_test_dump_t *const outl[] = {&dump_synthetic_outliers_10, &dump_synthetic_outliers_25,
                                                     &dump_synthetic_outliers_35, &dump_synthetic_near_ring,
                                                     &dump_synthetic_spikes};
    size_t s;
    magcal_calibrator_cfg_t ls = MAGCAL_CALIBRATOR_CFG_DEFAULT;
    magcal_calibrator_cfg_t opt = MAGCAL_CALIBRATOR_CFG_DEFAULT;
    ls.filter = MAGCAL_FILTER_NONE;
    ls.use_consensus = 0u;
    /* the comparison is about the fit: let every gate but the conic type pass */
    ls.max_residual_rel = 1.0e9f;
    ls.min_axis_ratio = 0.0f;
    ls.max_outlier_frac = 1.0f;
    opt.use_consensus = 0u;
    opt.max_residual_rel = 1.0e9f;
    opt.min_axis_ratio = 0.0f;
    printf("\n%-34s %8s %8s %8s %8s\n", "scenario", "LS st", "LS ratio", "OPT st", "OPTratio");
    for (s = 0; s < sizeof outl / sizeof outl[0]; ++s) {
        run_t a;
        run_t b;
        run_dump(outl[s], &ls, &a);
        run_dump(outl[s], &opt, &b);
        printf("%-34s %8d %8.2f %8d %8.2f\n", outl[s]->name, (int)a.st, a.ratio, (int)b.st, b.ratio);
        TEST_ASSERT_TRUE_MESSAGE(a.st != MAGCAL_OK || a.ratio > 3.0, outl[s]->name);
    }
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_run_every_scenario_default_within_1p2_floor);
    RUN_TEST(test_run_outlier_scenarios_plain_ls_fails);
    return UNITY_END();
}
