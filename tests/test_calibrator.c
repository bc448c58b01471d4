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
#include "adopt/calibrator_internal.h"
#include "magcal_port_fake.h"
#include "test_dumps.h"
#include "test_util.h"
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

/* ---------------------------------------------------------------- the truth itself */

/* The floor stored by tools/gen_dump.py (float64) is recomputed here from the truth fields:
 * M = T^-1, offset b, applied to the verification rows; agreement within 1 % (float32 rows). */
static void test_truth_floor_recomputes_in_c(void)
{
    size_t s;
    for (s = 0; s < N_SCEN; ++s) {
        const magcal_test_dump_t *d = g_scen[s];
        const magcal_test_truth_t *t = d->truth;
        magcal_cal2d_t c = MAGCAL_CAL2D_IDENTITY;
        float det = t->t00 * t->t11 - t->t01 * t->t10;
        double rms;
        c.offset.x = t->bx;
        c.offset.y = t->by;
        c.m[0][0] = t->t11 / det;
        c.m[0][1] = -t->t01 / det;
        c.m[1][0] = -t->t10 / det;
        c.m[1][1] = t->t00 / det;
        c.radius = t->h0;
        rms = heading_rms(d, &c, t->n_cal, d->n);
        TEST_ASSERT_FLOAT_WITHIN_MESSAGE(0.01f * t->floor_deg, t->floor_deg, (float)rms, d->name);
        /* the floor is close to the CRLB 57.3 sigma/h0 (noise shaped by M, algorithms.md 9) */
        TEST_ASSERT_TRUE_MESSAGE(rms > 0.5 * 57.2958 * t->sigma / t->h0 && rms < 2.0 * 57.2958 * t->sigma / t->h0,
                                 d->name);
    }
}

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
        printf("%-34s %6d %8.4f %8.4f %6.3f %7.3f %7.4f %5u %5u%s\n", d->name, (int)r.st, r.rms_deg,
               (double)d->truth->floor_deg, r.ratio, recall(&r), false_rate(&r),
               (unsigned)r.rep.rejected_filter, (unsigned)r.rep.rejected_consensus,
               r.rep.filter_fragmented ? " (filter split the ring: consensus drew from all)" : "");
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

/* Every filter choice (OPTICS classic, DBSCAN with automatic eps', none) followed by the consensus
 * meets the same targets on the burst and spike dumps. */
static void test_run_every_filter_choice_within_1p2_floor(void)
{
    static const magcal_test_dump_t *const dumps[] = {&dump_synthetic_outliers_25, &dump_synthetic_outliers_35,
                                                      &dump_synthetic_near_ring, &dump_synthetic_spikes};
    static const magcal_calibrator_filter_t filters[] = {MAGCAL_FILTER_OPTICS_CLASSIC, MAGCAL_FILTER_DBSCAN,
                                                         MAGCAL_FILTER_NONE};
    size_t s, f;
    for (f = 0; f < sizeof filters / sizeof filters[0]; ++f) {
        for (s = 0; s < sizeof dumps / sizeof dumps[0]; ++s) {
            magcal_calibrator_cfg_t cfg = MAGCAL_CALIBRATOR_CFG_DEFAULT;
            run_t r;
            cfg.filter = filters[f];
            run_dump(dumps[s], &cfg, &r);
            printf("filter %d %-34s ratio %.3f recall %.3f false %.4f\n", (int)filters[f], dumps[s]->name, r.ratio,
                   recall(&r), false_rate(&r));
            TEST_ASSERT_EQUAL_INT_MESSAGE(MAGCAL_OK, r.st, dumps[s]->name);
            TEST_ASSERT_TRUE_MESSAGE(r.ratio <= 1.2, dumps[s]->name);
            TEST_ASSERT_TRUE_MESSAGE(recall(&r) >= 0.90, dumps[s]->name);
            TEST_ASSERT_TRUE_MESSAGE(false_rate(&r) <= 0.05, dumps[s]->name);
        }
    }
}

/* ---------------------------------------------------------------- bad input keeps the old calibration */

/* A valid, non-identity calibration to protect. */
static magcal_cal2d_t prev_cal(void)
{
    magcal_cal2d_t c = MAGCAL_CAL2D_IDENTITY;
    c.offset.x = 3.0f;
    c.offset.y = -2.0f;
    c.m[0][0] = 0.9f;
    c.m[0][1] = 0.05f;
    c.m[1][0] = 0.05f;
    c.m[1][1] = 1.1f;
    c.radius = 40.0f;
    return c;
}

/* Run on the stored samples expecting `want`; the previous calibration must be bit-identical. */
static void expect_run_keeps(magcal_status_t want)
{
    magcal_cal2d_t c = prev_cal();
    magcal_cal2d_t ref = prev_cal();
    magcal_cal_report_t rep;
    TEST_ASSERT_EQUAL_INT(want, magcal_calibrator_run(&g_cal, &c, &rep));
    TEST_ASSERT_EQUAL_INT(want, rep.status);
    TEST_ASSERT_EQUAL_UINT8(0u, rep.adopted);
    TEST_ASSERT_EQUAL_MEMORY(&ref, &c, sizeof c);
    TEST_ASSERT_EQUAL_INT(MAGCAL_CALIBRATOR_FAILED, magcal_calibrator_state(&g_cal));
    TEST_ASSERT_EQUAL_INT(want, magcal_calibrator_last_status(&g_cal));
}

static void init_default(void)
{
    magcal_calibrator_cfg_t cfg = MAGCAL_CALIBRATOR_CFG_DEFAULT;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_init(&g_cal, &cfg, g_buf, CAP, g_work, sizeof g_work));
}

/* push the first n calibration rows of a dump */
static void push_rows(const magcal_test_dump_t *d, size_t n)
{
    size_t i;
    for (i = 0; i < n; ++i) {
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_push(&g_cal, row(d, i)));
    }
}

static void test_push_nonfinite_returns_nonfinite_not_stored(void)
{
    magcal_vec2_t p;
    init_default();
    push_rows(&dump_synthetic_clean, 10);
    p.x = NAN;
    p.y = 1.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_calibrator_push(&g_cal, p));
    p.x = 1.0f;
    p.y = INFINITY;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_calibrator_push(&g_cal, p));
    p.y = -INFINITY;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_calibrator_push(&g_cal, p));
    TEST_ASSERT_EQUAL_UINT32((uint32_t)(10u), (uint32_t)magcal_calibrator_count(&g_cal));
    expect_run_keeps(MAGCAL_ERR_TOO_FEW_POINTS); /* 10 < min_samples 20 */
}

static void test_run_identical_points_returns_degenerate_keeps_cal(void)
{
    size_t i;
    magcal_vec2_t p = {12.5f, -3.0f};
    init_default();
    for (i = 0; i < 100; ++i) {
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_push(&g_cal, p));
    }
    expect_run_keeps(MAGCAL_ERR_DEGENERATE);
}

static void test_run_collinear_points_returns_degenerate_keeps_cal(void)
{
    size_t i;
    init_default();
    for (i = 0; i < 100; ++i) {
        magcal_vec2_t p;
        p.x = 5.0f + 0.3f * (float)i;
        p.y = -2.0f + 0.6f * (float)i;
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_push(&g_cal, p));
    }
    expect_run_keeps(MAGCAL_ERR_DEGENERATE);
}

static void test_run_fewer_than_5_points_returns_too_few_keeps_cal(void)
{
    magcal_calibrator_cfg_t cfg = MAGCAL_CALIBRATOR_CFG_DEFAULT;
    cfg.min_samples = 5u;
    cfg.min_coverage_deg = 0.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_init(&g_cal, &cfg, g_buf, CAP, g_work, sizeof g_work));
    push_rows(&dump_synthetic_n60, 4);
    expect_run_keeps(MAGCAL_ERR_TOO_FEW_POINTS);
}

/* 90 degrees of the clean turn (75 of 600 rows over 720 deg): below the default 270 deg. */
static void test_run_short_arc_returns_coverage_names_missing_sector_keeps_cal(void)
{
    magcal_cal2d_t c = prev_cal();
    magcal_cal2d_t ref = prev_cal();
    magcal_cal_report_t rep;
    init_default();
    push_rows(&dump_synthetic_clean, 75);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_COVERAGE, magcal_calibrator_run(&g_cal, &c, &rep));
    TEST_ASSERT_EQUAL_MEMORY(&ref, &c, sizeof c);
    printf("short arc: coverage %.0f deg, missing sector %.0f..%.0f deg\n", (double)rep.coverage_deg,
           (double)rep.missing_start_deg, (double)(rep.missing_start_deg + rep.missing_width_deg));
    /* truth: headings 17..107 deg visited; bins are 10 deg wide, raw angles are distorted by the
     * soft iron (up to ~10 deg here), so allow two bins of slack on each side */
    TEST_ASSERT_FLOAT_WITHIN(30.0f, 90.0f, rep.coverage_deg);
    TEST_ASSERT_FLOAT_WITHIN(30.0f, 270.0f, rep.missing_width_deg);
    TEST_ASSERT_FLOAT_WITHIN(30.0f, 110.0f, rep.missing_start_deg);
}

static void test_push_buffer_full_returns_buffer_full(void)
{
    static magcal_vec2_t small[16];
    static uint32_t w[(MAGCAL_CALIBRATOR_WORKSPACE_LEN(16) + 3u) / 4u];
    magcal_calibrator_cfg_t cfg = MAGCAL_CALIBRATOR_CFG_DEFAULT;
    size_t i;
    /* the default min_samples (20) cannot fit in 16 samples: refused at init */
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_calibrator_init(&g_cal, &cfg, small, 16, w, sizeof w));
    cfg.min_samples = 16u;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_WORKSPACE, magcal_calibrator_init(&g_cal, &cfg, small, 16, w, sizeof w - 4u));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_init(&g_cal, &cfg, small, 16, w, sizeof w));
    for (i = 0; i < 16; ++i) {
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_push(&g_cal, row(&dump_synthetic_clean, i)));
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_BUFFER_FULL, magcal_calibrator_push(&g_cal, row(&dump_synthetic_clean, 16)));
    TEST_ASSERT_EQUAL_UINT32((uint32_t)(16u), (uint32_t)magcal_calibrator_count(&g_cal));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_reset(&g_cal));
    TEST_ASSERT_EQUAL_UINT32((uint32_t)(0u), (uint32_t)magcal_calibrator_count(&g_cal));
}

/* Size macros: one persistent byte per sample (the flags; the two stage masks live in the stage
 * scratch), and the budget of docs/performance.md: workspace + sample buffer <= 24 B/sample at the
 * shipped capacity 1024. */
static void test_workspace_len_capacity_1024_within_24_bytes_per_sample(void)
{
    TEST_ASSERT_EQUAL_UINT32(1024u, (uint32_t)MAGCAL_CALIBRATOR_MASKS_LEN(1024u));
    TEST_ASSERT_EQUAL_UINT32(20u, (uint32_t)MAGCAL_CALIBRATOR_MASKS_LEN(17u));
    TEST_ASSERT_EQUAL_UINT32((uint32_t)(MAGCAL_CONSENSUS_WORKSPACE_LEN(1024u) + 2048u),
                             (uint32_t)MAGCAL_CALIBRATOR_CONSENSUS_LEN(1024u));
    /* the goal is a 32-bit target's (the bench measures it on the M4F: 24 B/sample); a 64-bit
     * host adds the lead that pointer-aligns the run state in a 4-aligned workspace */
    TEST_ASSERT_TRUE(MAGCAL_CALIBRATOR_WORKSPACE_LEN(1024u) + 1024u * sizeof(magcal_vec2_t) <=
                     24u * 1024u + (sizeof(void *) - 4u));
    /* the consensus stage and its masks fit in the stage scratch at every capacity */
    TEST_ASSERT_TRUE(MAGCAL_CALIBRATOR_WORKSPACE_LEN(16u) >=
                     MAGCAL_CALIBRATOR_MASKS_LEN(16u) + MAGCAL_CALIBRATOR_RUN_LEN +
                         MAGCAL_CALIBRATOR_CONSENSUS_LEN(16u));
    TEST_ASSERT_TRUE(MAGCAL_CALIBRATOR_WORKSPACE_LEN(MAGCAL_MAX_SAMPLES) >=
                     MAGCAL_CALIBRATOR_MASKS_LEN(MAGCAL_MAX_SAMPLES) + MAGCAL_CALIBRATOR_RUN_LEN +
                         MAGCAL_CALIBRATOR_CONSENSUS_LEN(MAGCAL_MAX_SAMPLES));
}

static void test_run_tiny_eps_returns_all_noise_keeps_cal(void)
{
    magcal_calibrator_cfg_t cfg = MAGCAL_CALIBRATOR_CFG_DEFAULT;
    cfg.eps = 1.0e-4f; /* far below the 0.2 noise: no point has 4 neighbours */
    cfg.min_pts = 4u;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_init(&g_cal, &cfg, g_buf, CAP, g_work, sizeof g_work));
    push_rows(&dump_synthetic_clean, 600);
    expect_run_keeps(MAGCAL_ERR_ALL_NOISE);
    cfg.filter = MAGCAL_FILTER_DBSCAN;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_init(&g_cal, &cfg, g_buf, CAP, g_work, sizeof g_work));
    push_rows(&dump_synthetic_clean, 600);
    expect_run_keeps(MAGCAL_ERR_ALL_NOISE);
}

static void test_run_spikes_without_rejection_returns_hyperbola_keeps_cal(void)
{
    magcal_calibrator_cfg_t cfg = MAGCAL_CALIBRATOR_CFG_DEFAULT;
    cfg.filter = MAGCAL_FILTER_NONE;
    cfg.use_consensus = 0u;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_init(&g_cal, &cfg, g_buf, CAP, g_work, sizeof g_work));
    push_rows(&dump_synthetic_spikes, 600);
    expect_run_keeps(MAGCAL_ERR_HYPERBOLA);
}

/* Each plausibility gate with its own status (limits set just beyond the truth). */
static void test_run_gates_each_return_own_status_keep_cal(void)
{
    magcal_calibrator_cfg_t cfg = MAGCAL_CALIBRATOR_CFG_DEFAULT;
    cfg.min_axis_ratio = 0.6f; /* truth 0.55 */
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_init(&g_cal, &cfg, g_buf, CAP, g_work, sizeof g_work));
    push_rows(&dump_synthetic_soft_iron_strong, 600);
    expect_run_keeps(MAGCAL_ERR_AXIS_RATIO);

    cfg = (magcal_calibrator_cfg_t)MAGCAL_CALIBRATOR_CFG_DEFAULT;
    cfg.max_radius = 35.0f; /* truth sqrt(1.15*0.85)*40 = 39.5 */
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_init(&g_cal, &cfg, g_buf, CAP, g_work, sizeof g_work));
    push_rows(&dump_synthetic_clean, 600);
    expect_run_keeps(MAGCAL_ERR_RADIUS_RANGE);
    cfg.max_radius = 0.0f;
    cfg.min_radius = 45.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_init(&g_cal, &cfg, g_buf, CAP, g_work, sizeof g_work));
    push_rows(&dump_synthetic_clean, 600);
    expect_run_keeps(MAGCAL_ERR_RADIUS_RANGE);

    cfg = (magcal_calibrator_cfg_t)MAGCAL_CALIBRATOR_CFG_DEFAULT;
    cfg.max_residual_rel = 0.02f; /* heavy noise: sigma/radius = 2/39.5 = 0.05 */
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_init(&g_cal, &cfg, g_buf, CAP, g_work, sizeof g_work));
    push_rows(&dump_synthetic_heavy_noise, 600);
    expect_run_keeps(MAGCAL_ERR_RESIDUAL);

    cfg = (magcal_calibrator_cfg_t)MAGCAL_CALIBRATOR_CFG_DEFAULT;
    cfg.max_outlier_frac = 0.2f; /* 35 % injected */
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_init(&g_cal, &cfg, g_buf, CAP, g_work, sizeof g_work));
    push_rows(&dump_synthetic_outliers_35, 600);
    expect_run_keeps(MAGCAL_ERR_TOO_MANY_OUTLIERS);
}

static void test_init_bad_cfg_returns_arg(void)
{
    magcal_calibrator_cfg_t cfg = MAGCAL_CALIBRATOR_CFG_DEFAULT;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_calibrator_init(NULL, &cfg, g_buf, CAP, g_work, sizeof g_work));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_calibrator_init(&g_cal, &cfg, g_buf, CAP + 1u, g_work, sizeof g_work));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ALIGNMENT,
                          magcal_calibrator_init(&g_cal, &cfg, g_buf, CAP, (uint8_t *)g_work + 1, sizeof g_work - 4u));
    cfg.min_samples = 4u;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_calibrator_init(&g_cal, &cfg, g_buf, CAP, g_work, sizeof g_work));
    cfg = (magcal_calibrator_cfg_t)MAGCAL_CALIBRATOR_CFG_DEFAULT;
    cfg.min_coverage_deg = NAN;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_calibrator_init(&g_cal, &cfg, g_buf, CAP, g_work, sizeof g_work));
    cfg = (magcal_calibrator_cfg_t)MAGCAL_CALIBRATOR_CFG_DEFAULT;
    cfg.min_pts = 1u;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_calibrator_init(&g_cal, &cfg, g_buf, CAP, g_work, sizeof g_work));
    /* min_samples beyond the capacity could never be reached: refused (was accepted) */
    cfg = (magcal_calibrator_cfg_t)MAGCAL_CALIBRATOR_CFG_DEFAULT;
    cfg.min_samples = 600u;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_calibrator_init(&g_cal, &cfg, g_buf, 512u, g_work, sizeof g_work));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_init(&g_cal, &cfg, g_buf, 600u, g_work, sizeof g_work));
    cfg = (magcal_calibrator_cfg_t)MAGCAL_CALIBRATOR_CFG_DEFAULT;
    cfg.max_param_err_ratio = 0.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_calibrator_init(&g_cal, &cfg, g_buf, CAP, g_work, sizeof g_work));
    cfg.max_param_err_ratio = NAN;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_calibrator_init(&g_cal, &cfg, g_buf, CAP, g_work, sizeof g_work));
    cfg = (magcal_calibrator_cfg_t)MAGCAL_CALIBRATOR_CFG_DEFAULT;
    cfg.max_design_factor = 0.5f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_calibrator_init(&g_cal, &cfg, g_buf, CAP, g_work, sizeof g_work));
    cfg = (magcal_calibrator_cfg_t)MAGCAL_CALIBRATOR_CFG_STORE_DEFAULT;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_init(&g_cal, &cfg, g_buf, CAP, g_work, sizeof g_work));
    cfg.pretest = 2u; /* 0 or 1 */
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_calibrator_init(&g_cal, &cfg, g_buf, CAP, g_work, sizeof g_work));
}

/* A failed run reads NaN in every estimate, never 0 (which looked perfect). */
static void test_run_failure_reports_nan_estimates(void)
{
    magcal_cal2d_t c = prev_cal();
    magcal_cal_report_t rep;
    init_default();
    push_rows(&dump_synthetic_clean, 75); /* 90 deg: COVERAGE */
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_COVERAGE, magcal_calibrator_run(&g_cal, &c, &rep));
    TEST_ASSERT_TRUE(isnan(rep.est_heading_err_deg));
    TEST_ASSERT_TRUE(isnan(rep.est_param_err_deg));
    TEST_ASSERT_TRUE(isnan(rep.est_noise_deg));
    TEST_ASSERT_TRUE(isnan(rep.current_err_deg));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ADOPT_NONE, rep.adopt_rule);
    TEST_ASSERT_EQUAL_STRING("none", magcal_adopt_rule_str(rep.adopt_rule));
    TEST_ASSERT_EQUAL_STRING("better", magcal_adopt_rule_str(MAGCAL_ADOPT_BETTER));
    TEST_ASSERT_EQUAL_STRING("stale", magcal_adopt_rule_str(MAGCAL_ADOPT_STALE));
    TEST_ASSERT_EQUAL_STRING("unusable", magcal_adopt_rule_str(MAGCAL_ADOPT_UNUSABLE));
    TEST_ASSERT_EQUAL_STRING("unknown", magcal_adopt_rule_str((magcal_adopt_rule_t)9));
}

/* ---------------------------------------------------------------- adoption rule */

/* Current calibration with the centre off by 4 (10 % of the radius): the new fit is better and
 * adopted; the heading shift reported is the error of the old one, about asin(4/39.5) = 5.8 deg
 * at most (soft iron modulates it: accept 4..8 deg). */
static void test_run_better_fit_adopted_reports_shift(void)
{
    magcal_cal2d_t c;
    magcal_cal_report_t rep;
    run_t r;
    magcal_calibrator_cfg_t cfg = MAGCAL_CALIBRATOR_CFG_DEFAULT;
    run_dump(&dump_synthetic_clean, &cfg, &r);
    c = r.cal;
    c.offset.x += 4.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_run(&g_cal, &c, &rep));
    TEST_ASSERT_EQUAL_UINT8(1u, rep.adopted);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ADOPT_BETTER, rep.adopt_rule);
    TEST_ASSERT_EQUAL_MEMORY(&r.cal, &c, sizeof c);
    printf("adopt: est heading %.4f deg (param %.4f, noise %.4f), current %.3f deg (z %.0f), shift max %.3f rms "
           "%.3f deg\n",
           (double)rep.est_heading_err_deg, (double)rep.est_param_err_deg, (double)rep.est_noise_deg,
           (double)rep.current_err_deg, (double)rep.current_err_z, (double)rep.shift_max_deg,
           (double)rep.shift_rms_deg);
    TEST_ASSERT_TRUE(rep.current_err_deg > MAGCAL_CALIBRATOR_ADOPT_MARGIN * rep.est_param_err_deg);
    /* the estimate of the current error is close to its true error (the shift RMS) */
    TEST_ASSERT_FLOAT_WITHIN(0.2f * rep.shift_rms_deg, rep.shift_rms_deg, rep.current_err_deg);
    TEST_ASSERT_FLOAT_WITHIN(2.0f, 6.0f, rep.shift_max_deg);
    TEST_ASSERT_FLOAT_WITHIN(1.5f, 4.1f, rep.shift_rms_deg); /* 5.8/sqrt(2) */
}

/* Same data, field 1.5x stronger (everything scaled about the centre): the current calibration
 * still makes a circle of it, so the new one is not better, and the radius change (50 %) is not
 * plausible: NOT_BETTER, current bit-identical. The identical re-run is a tie, not an improvement:
 * NOT_BETTER too (a tie never replaces: issue 12), its current error reads ~0 and the shift ~0. */
static void test_run_implausible_radius_not_better_keeps_cal(void)
{
    magcal_cal2d_t c;
    magcal_cal2d_t ref;
    magcal_cal_report_t rep;
    run_t r;
    size_t i;
    magcal_calibrator_cfg_t cfg = MAGCAL_CALIBRATOR_CFG_DEFAULT;
    run_dump(&dump_synthetic_clean, &cfg, &r);
    c = r.cal;
    ref = c;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NOT_BETTER, magcal_calibrator_run(&g_cal, &c, &rep));
    TEST_ASSERT_EQUAL_MEMORY(&ref, &c, sizeof c);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ADOPT_NONE, rep.adopt_rule);
    TEST_ASSERT_TRUE(rep.shift_max_deg < 0.01f);
    TEST_ASSERT_TRUE(rep.current_err_deg < 0.5f * rep.est_param_err_deg);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_reset(&g_cal));
    for (i = 0; i < 600; ++i) {
        magcal_vec2_t p = row(&dump_synthetic_clean, i);
        p.x = r.cal.offset.x + 1.5f * (p.x - r.cal.offset.x);
        p.y = r.cal.offset.y + 1.5f * (p.y - r.cal.offset.y);
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_push(&g_cal, p));
    }
    ref = c;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NOT_BETTER, magcal_calibrator_run(&g_cal, &c, &rep));
    TEST_ASSERT_EQUAL_MEMORY(&ref, &c, sizeof c);
    TEST_ASSERT_EQUAL_UINT8(0u, rep.adopted);
}

/* A corrupted stored calibration (bad magic) is not usable: the new one is adopted. */
static void test_run_corrupted_current_is_replaced(void)
{
    magcal_cal2d_t c = prev_cal();
    magcal_cal_report_t rep;
    init_default();
    push_rows(&dump_synthetic_clean, 600);
    c.magic ^= 0x100u;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NOT_INITIALISED, magcal_cal2d_validate(&c));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_run(&g_cal, &c, &rep));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cal2d_validate(&c));
    TEST_ASSERT_TRUE(isnan(rep.current_err_deg));
}

/* ---------------------------------------------------------------- exactly min_samples */

/* Exactly min_samples (20) clean samples, uniformly spread headings, 1 % noise, 200 seeds: the
 * consensus scale used to include the minimal set's five zero residuals (7.6 % of clean samples
 * rejected, TOO_FEW_POINTS in about half the runs). Now all 20 samples must be kept and the run
 * calibrate (OK) in >= 95 % of the seeds (measured 193/200; a 3.5-sigma threshold alone rejects
 * one of 20 clean samples in ~1 % of runs, and at n = 20 the refits can still settle on a
 * subset). Every OK is checked against the truth: heading RMS on noise-free headings within
 * 3 x the estimate's parameter part + 0.05 deg. */
static void test_run_exactly_min_samples_clean_calibrates(void)
{
    const size_t n = 20u;
    unsigned seed;
    unsigned ok = 0u, all_kept = 0u, too_few = 0u, unobs = 0u;
    test_distortion_t d = {40.0f, {{1.1f, 0.05f}, {0.05f, 0.9f}}, 12.0f, -7.0f};
    magcal_calibrator_cfg_t cfg = MAGCAL_CALIBRATOR_CFG_DEFAULT;
    TEST_ASSERT_EQUAL_UINT16(20u, cfg.min_samples);
    for (seed = 1u; seed <= 200u; ++seed) {
        uint32_t rng = seed * 2654435761u + 1u;
        magcal_cal2d_t c = MAGCAL_CAL2D_IDENTITY;
        magcal_cal_report_t rep;
        magcal_status_t st;
        size_t i;
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_init(&g_cal, &cfg, g_buf, CAP, g_work, sizeof g_work));
        for (i = 0; i < n; ++i) {
            double psi = (i + test_rand_uniform(&rng)) * 360.0 / (double)n;
            TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_push(&g_cal, test_distorted_sample(&d, psi, 0.4, &rng)));
        }
        st = magcal_calibrator_run(&g_cal, &c, &rep);
        if (rep.rejected_consensus == 0u && rep.rejected_filter == 0u && rep.used == n) {
            ++all_kept;
        }
        too_few += st == MAGCAL_ERR_TOO_FEW_POINTS ? 1u : 0u;
        unobs += st == MAGCAL_ERR_UNOBSERVABLE ? 1u : 0u;
        if (st == MAGCAL_OK) {
            double ss = 0.0;
            size_t k;
            ++ok;
            for (k = 0; k < 360u; ++k) {
                float h;
                TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_heading_compute(&c, test_distorted_sample(&d, (double)k, 0.0, &rng),
                                                                        0.0f, &h, NULL));
                ss += test_angle_diff_deg((double)h, (double)k) * test_angle_diff_deg((double)h, (double)k);
            }
            TEST_ASSERT_TRUE(sqrt(ss / 360.0) <= 3.0 * (double)rep.est_param_err_deg + 0.05);
        }
    }
    printf("exactly 20 clean samples, 200 seeds: OK %u, all 20 kept %u, TOO_FEW_POINTS %u, UNOBSERVABLE %u\n", ok,
           all_kept, too_few, unobs);
    TEST_ASSERT_TRUE(all_kept >= 190u);
    TEST_ASSERT_TRUE(ok >= 190u);
}

/* Heading RMS of calibration c against truth d over 360 noise-free headings, degrees. */
static double truth_rms_360(const magcal_cal2d_t *c, const test_distortion_t *d)
{
    double ss = 0.0;
    uint32_t rng = 7u;
    size_t k;
    for (k = 0; k < 360u; ++k) {
        float h;
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK,
                              magcal_heading_compute(c, test_distorted_sample(d, (double)k, 0.0, &rng), 0.0f, &h, NULL));
        ss += test_angle_diff_deg((double)h, (double)k) * test_angle_diff_deg((double)h, (double)k);
    }
    return sqrt(ss / 360.0);
}

/* A store of two installations (issue 13: the 30-min drive seed 1 adopted a compromise): the
 * hard iron moves by (12, -7) (46 % of the radius) between two rings of 60 samples each.
 * (a) both rings seen over the whole circle: the consensus keeps one ring and rejects most of the
 *     other, the consistency gate (store default, 0.35) refuses it as INCONSISTENT in most seeds
 *     (measured 13 of 20; 2 AXIS_RATIO; 5 OK at 4.2..10.2 deg with 23..34 % rejects, below the
 *     gate), the gate off accepts 18; asserted: >= 10 refused, never an OK the gate off refuses,
 *     `current` untouched on every refusal;
 * (b) each installation alone over the same headings: OK and accurate on its truth (3 x the
 *     estimate's parameter part + 0.05 deg), 20 of 20: the gate refuses the mixture, not the data;
 * (c) measured, not asserted (the gate's known gap, docs/calibrator.md "Consistency gate"): the
 *     first installation over 0..170 deg and the second over 150..300 deg meet in a compromise conic
 *     that keeps 90 % of the samples; every seed is OK at about 9.7 deg true error. */
static void test_run_store_of_two_installations_inconsistent(void)
{
    const test_distortion_t d1 = {30.0f, {{1.1f, 0.05f}, {0.05f, 0.9f}}, 12.0f, -7.0f};
    const test_distortion_t d2 = {30.0f, {{1.1f, 0.05f}, {0.05f, 0.9f}}, 24.0f, -14.0f};
    const magcal_calibrator_cfg_t on = MAGCAL_CALIBRATOR_CFG_STORE_DEFAULT;
    magcal_calibrator_cfg_t off = MAGCAL_CALIBRATOR_CFG_STORE_DEFAULT;
    unsigned seed;
    unsigned inconsistent = 0u, on_ok = 0u, off_ok = 0u, arcs_ok = 0u;
    double on_worst = 0.0, arcs_worst = 0.0;
    off.max_inconsistent_frac = 0.0f;
    TEST_ASSERT_EQUAL_FLOAT(0.35f, on.max_inconsistent_frac);
    for (seed = 1u; seed <= 20u; ++seed) {
        int pass;
        magcal_status_t st_off = MAGCAL_OK;
        for (pass = 0; pass < 5; ++pass) {
            /* pass 0: full rings mixed, gate off; 1: gate on; 2, 3: d1 alone, d2 alone; 4: the arcs */
            uint32_t rng = seed * 2654435761u + 11u;
            magcal_cal2d_t c = MAGCAL_CAL2D_IDENTITY;
            const magcal_cal2d_t before = c;
            magcal_cal_report_t rep;
            magcal_status_t st;
            size_t i;
            TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_init(&g_cal, pass == 0 ? &off : &on, g_buf, CAP,
                                                                    g_work, sizeof g_work));
            for (i = 0; i < 120u; ++i) {
                const double u = (double)(i % 60u) + test_rand_uniform(&rng);
                double psi = 6.0 * u; /* 60 samples over the circle per ring */
                const test_distortion_t *d = pass == 2 ? &d1 : (pass == 3 || i >= 60u ? &d2 : &d1);
                if (pass == 4) {
                    psi = i < 60u ? 170.0 * u / 60.0 : 150.0 + 150.0 * u / 60.0;
                }
                TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_push(&g_cal, test_distorted_sample(d, psi, 0.15, &rng)));
            }
            st = magcal_calibrator_run(&g_cal, &c, &rep);
            if (pass == 0) {
                st_off = st;
                off_ok += st == MAGCAL_OK ? 1u : 0u;
            } else if (pass == 1) {
                if (st == MAGCAL_OK) {
                    ++on_ok;
                    on_worst = fmax(on_worst, fmin(truth_rms_360(&c, &d1), truth_rms_360(&c, &d2)));
                    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, st_off);
                } else {
                    TEST_ASSERT_EQUAL_MEMORY(&before, &c, sizeof c); /* untouched */
                    inconsistent += st == MAGCAL_ERR_INCONSISTENT ? 1u : 0u;
                }
            } else if (pass == 4) {
                if (st == MAGCAL_OK) {
                    ++arcs_ok;
                    arcs_worst = fmax(arcs_worst, fmin(truth_rms_360(&c, &d1), truth_rms_360(&c, &d2)));
                }
            } else {
                TEST_ASSERT_EQUAL_INT(MAGCAL_OK, st);
                TEST_ASSERT_TRUE(truth_rms_360(&c, pass == 2 ? &d1 : &d2) <= 3.0 * (double)rep.est_param_err_deg + 0.05);
            }
        }
    }
    printf("two installations, full rings, 20 seeds: INCONSISTENT %u, OK %u (worst %.2f deg; gate off: OK %u); "
           "two arcs meeting (the gap): OK %u, worst %.2f deg\n",
           inconsistent, on_ok, on_worst, off_ok, arcs_ok, arcs_worst);
    TEST_ASSERT_TRUE(inconsistent >= 10u);
    TEST_ASSERT_TRUE(on_ok < off_ok);
}

/* The consistency gate's configuration: 0..1, finite. */
static void test_init_inconsistent_frac_checked(void)
{
    magcal_calibrator_cfg_t cfg = MAGCAL_CALIBRATOR_CFG_DEFAULT;
    TEST_ASSERT_EQUAL_FLOAT(0.0f, cfg.max_inconsistent_frac); /* off for raw buffers */
    cfg.max_inconsistent_frac = 1.5f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_calibrator_init(&g_cal, &cfg, g_buf, CAP, g_work, sizeof g_work));
    cfg.max_inconsistent_frac = -0.1f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_calibrator_init(&g_cal, &cfg, g_buf, CAP, g_work, sizeof g_work));
    cfg.max_inconsistent_frac = NAN;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_calibrator_init(&g_cal, &cfg, g_buf, CAP, g_work, sizeof g_work));
    cfg.max_inconsistent_frac = 1.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_init(&g_cal, &cfg, g_buf, CAP, g_work, sizeof g_work));
    TEST_ASSERT_EQUAL_STRING("samples of more than one installation", magcal_status_str(MAGCAL_ERR_INCONSISTENT));
}

/* ---------------------------------------------------------------- per-sample verdicts */

/* classify() with the final fit and threshold gives exactly the run's per-sample verdict. */
static void test_classify_matches_inlier_flags(void)
{
    run_t r;
    size_t i;
    magcal_calibrator_cfg_t cfg = MAGCAL_CALIBRATOR_CFG_DEFAULT;
    int o;
    size_t flagged = 0u;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_init(&g_cal, &cfg, g_buf, CAP, g_work, sizeof g_work));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_STATE, magcal_calibrator_classify(&g_cal, row(&dump_synthetic_clean, 0), &o));
    run_dump(&dump_synthetic_outliers_25, &cfg, &r);
    for (i = 0; i < 600; ++i) {
        int inl;
        uint8_t f;
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_inlier(&g_cal, i, &inl));
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_classify(&g_cal, row(&dump_synthetic_outliers_25, i), &o));
        TEST_ASSERT_EQUAL_INT(inl, !o);
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_flags(&g_cal, i, &f));
        TEST_ASSERT_TRUE((f & MAGCAL_CALIBRATOR_FLAG_JUDGED) != 0u);
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_calibrator_inlier(&g_cal, 600, &o));
    /* verification rows (never pushed) are all clean: classify accepts them */
    for (i = 600; i < dump_synthetic_outliers_25.n; ++i) {
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_classify(&g_cal, row(&dump_synthetic_outliers_25, i), &o));
        flagged += o ? 1u : 0u;
    }
    /* a 3.5-sigma threshold flags ~0.05 % of clean rows; allow the 5 % false-rejection budget */
    TEST_ASSERT_TRUE(flagged * 20u <= dump_synthetic_outliers_25.n - 600u);
}

/* ---------------------------------------------------------------- information gate, states */

static void test_push_spacing_gate_skips_redundant_samples(void)
{
    magcal_calibrator_cfg_t cfg = MAGCAL_CALIBRATOR_CFG_DEFAULT;
    magcal_cal2d_t c = MAGCAL_CAL2D_IDENTITY;
    size_t i;
    size_t gated = 0u;
    cfg.min_spacing_deg = 3.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_init(&g_cal, &cfg, g_buf, CAP, g_work, sizeof g_work));
    /* a stationary vehicle: one sample stored, the rest gated */
    for (i = 0; i < 50; ++i) {
        magcal_status_t st = magcal_calibrator_push(&g_cal, row(&dump_synthetic_clean, 0));
        TEST_ASSERT_TRUE(st == MAGCAL_OK || st == MAGCAL_ERR_GATED);
    }
    TEST_ASSERT_EQUAL_UINT32((uint32_t)(1u), (uint32_t)magcal_calibrator_count(&g_cal));
    TEST_ASSERT_EQUAL_INT(MAGCAL_CALIBRATOR_COLLECTING, magcal_calibrator_state(&g_cal));
    for (i = 0; i < 600; ++i) {
        magcal_status_t st = magcal_calibrator_push(&g_cal, row(&dump_synthetic_clean, i));
        TEST_ASSERT_TRUE(st == MAGCAL_OK || st == MAGCAL_ERR_GATED);
        gated += st == MAGCAL_ERR_GATED ? 1u : 0u;
    }
    printf("spacing 3 deg: stored %u of 650, coverage %.0f deg\n", (unsigned)magcal_calibrator_count(&g_cal),
           (double)magcal_calibrator_coverage_deg(&g_cal));
    /* 720 deg turned at >= 3 deg spacing: at most ~240 (+ slack for the moving provisional centre) */
    TEST_ASSERT_TRUE(magcal_calibrator_count(&g_cal) <= 300u);
    TEST_ASSERT_TRUE(magcal_calibrator_count(&g_cal) >= 150u);
    TEST_ASSERT_EQUAL_FLOAT(360.0f, magcal_calibrator_coverage_deg(&g_cal));
    TEST_ASSERT_EQUAL_INT(MAGCAL_CALIBRATOR_READY, magcal_calibrator_state(&g_cal));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_run(&g_cal, &c, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_CALIBRATOR_CALIBRATED, magcal_calibrator_state(&g_cal));
}

static void test_push_per_bin_cap_limits_samples(void)
{
    magcal_calibrator_cfg_t cfg = MAGCAL_CALIBRATOR_CFG_DEFAULT;
    size_t i;
    cfg.max_per_bin = 5u;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_init(&g_cal, &cfg, g_buf, CAP, g_work, sizeof g_work));
    for (i = 0; i < 600; ++i) {
        magcal_status_t st = magcal_calibrator_push(&g_cal, row(&dump_synthetic_clean, i));
        TEST_ASSERT_TRUE(st == MAGCAL_OK || st == MAGCAL_ERR_GATED);
    }
    printf("per-bin cap 5: stored %u of 600\n", (unsigned)magcal_calibrator_count(&g_cal));
    /* re-binning around a moving provisional centre may let a few more through early on */
    TEST_ASSERT_TRUE(magcal_calibrator_count(&g_cal) <= 5u * MAGCAL_COVERAGE_BINS + 40u);
    TEST_ASSERT_TRUE(magcal_calibrator_count(&g_cal) >= 4u * MAGCAL_COVERAGE_BINS);
}

/* ---------------------------------------------------------------- port path */

static void test_poll_reads_port_passes_errors_through(void)
{
    size_t i;
    magcal_cal2d_t c = MAGCAL_CAL2D_IDENTITY;
    size_t ok = 0u;
    const magcal_test_dump_t *d = &dump_synthetic_outliers_10;
    magcal_port_fake_reset();
    for (i = 0; i < 600; ++i) {
        magcal_vec3_t v;
        v.x = d->mx[i];
        v.y = d->my[i];
        v.z = -30.0f;
        if (i == 100u) {
            TEST_ASSERT_EQUAL_INT(0, magcal_port_fake_push_mag_status(MAGCAL_ERR_TIMEOUT));
        }
        if (i == 200u) {
            TEST_ASSERT_EQUAL_INT(0, magcal_port_fake_push_mag_status(MAGCAL_ERR_PORT));
        }
        TEST_ASSERT_EQUAL_INT(0, magcal_port_fake_push_mag(v));
    }
    init_default();
    for (i = 0; i < 602; ++i) {
        magcal_status_t st = magcal_calibrator_poll(&g_cal);
        if (i == 100u) {
            TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_TIMEOUT, st);
        } else if (i == 201u) {
            TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_PORT, st);
        } else {
            TEST_ASSERT_EQUAL_INT(MAGCAL_OK, st);
            ++ok;
        }
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NO_DATA, magcal_calibrator_poll(&g_cal));
    TEST_ASSERT_EQUAL_UINT32(600u, (uint32_t)ok);
    TEST_ASSERT_EQUAL_UINT32((uint32_t)(600u), (uint32_t)magcal_calibrator_count(&g_cal));
    TEST_ASSERT_EQUAL_UINT32(603u, (uint32_t)magcal_port_fake_mag_calls());
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_run(&g_cal, &c, NULL));
    TEST_ASSERT_TRUE(heading_rms(d, &c, 600, d->n) <= 1.2 * (double)d->truth->floor_deg);
}

/* ---------------------------------------------------------------- recorded dumps */

/* std/mean of |cal(p)| over the non-glitch rows (identity = raw). */
static magcal_vec2_t g_dump_pts[4096];
static uint8_t g_dump_skip[4096];

static double radius_spread(const magcal_test_dump_t *d, const magcal_cal2d_t *c)
{
    size_t i;
    TEST_ASSERT_TRUE(d->n <= sizeof g_dump_skip);
    for (i = 0; i < d->n; ++i) {
        g_dump_pts[i] = row(d, i);
        g_dump_skip[i] = (uint8_t)(d->glitch != NULL && d->glitch[i] > 0.5f);
    }
    return test_radius_spread(c, g_dump_pts, g_dump_skip, d->n);
}

/*
 * Recorded dump: calibrate on every row (default pipeline), then compare the radius spread
 * std/mean of the non-glitch rows, raw (identity) vs corrected, with the float64 reference of
 * tools/ref_real_spread.py (plain LS ellipse fit of the non-glitch rows, the optimum of an ellipse
 * correction): the corrected spread must be within 5 % of that optimum, the drop >= min_drop.
 * Every row the importer flagged as a glitch must be rejected.
 */
static void real_dump(const magcal_test_dump_t *d, double ref_spread, double min_drop)
{
    magcal_cal2d_t c = MAGCAL_CAL2D_IDENTITY;
    magcal_cal2d_t ident = MAGCAL_CAL2D_IDENTITY;
    magcal_cal_report_t rep;
    size_t i;
    size_t glitches = 0u;
    size_t caught = 0u;
    double raw;
    double cor;
    init_default();
    for (i = 0; i < d->n; ++i) {
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_push(&g_cal, row(d, i)));
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_run(&g_cal, &c, &rep));
    raw = radius_spread(d, &ident);
    cor = radius_spread(d, &c);
    if (d->glitch != NULL) {
        for (i = 0; i < d->n; ++i) {
            if (d->glitch[i] > 0.5f) {
                int inl;
                ++glitches;
                TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_inlier(&g_cal, i, &inl));
                caught += inl ? 0u : 1u;
            }
        }
    }
    printf("%s: n %u used %u (filter -%u, residual -%u), coverage %.0f, spread raw %.4f -> %.4f (x%.1f), "
           "glitches %u/%u rejected, est err %.3f deg\n",
           d->name, (unsigned)d->n, (unsigned)rep.used, (unsigned)rep.rejected_filter,
           (unsigned)rep.rejected_consensus, (double)rep.coverage_deg, raw, cor, raw / cor, (unsigned)caught,
           (unsigned)glitches, (double)rep.est_heading_err_deg);
    TEST_ASSERT_TRUE(cor <= 1.05 * ref_spread);
    TEST_ASSERT_TRUE(raw / cor >= min_drop);
    TEST_ASSERT_EQUAL_UINT32((uint32_t)glitches, (uint32_t)caught);
}

/* Hand-turned board: the best ellipse leaves 2.6 % spread (tilt wobble), so the drop from the raw
 * 12.8 % is at most 4.9x (tools/ref_real_spread.py): the 5x target is not reachable on this
 * recording by any ellipse correction; require 4.5x and the optimum within 5 %. */
static void test_run_lsm9ds1_flat_turns_spread_near_optimum(void)
{
    real_dump(&dump_real_lsm9ds1_pmodnav_flat_turns, 0.02617, 4.5);
}

static void test_run_lsm9ds1_driver_glitches_all_rejected(void)
{
    TEST_ASSERT_NOT_NULL(dump_real_lsm9ds1_pmodnav_driver_glitches.glitch);
    /* reference over the 232 non-glitch rows: raw 0.14727, LS optimum 0.05879 (2.5x) */
    real_dump(&dump_real_lsm9ds1_pmodnav_driver_glitches, 0.05879, 2.3);
}


/* ---------------------------------------------------------------- pre-test (cfg.pretest, issue 14) */

/* One run of d's calibration rows with cfg into *r, its flags into flags (CAP entries). */
static void run_dump_flags(const magcal_test_dump_t *d, const magcal_calibrator_cfg_t *cfg, run_t *r,
                           uint8_t *flags)
{
    size_t i;
    run_dump(d, cfg, r);
    for (i = 0; i < d->truth->n_cal; ++i) {
        flags[i] = 0u;
        (void)magcal_calibrator_flags(&g_cal, i, &flags[i]);
    }
}

/*
 * The pre-test against the full pipeline (cfg.pretest = 0) on every synthetic scenario, against
 * known truth. Clean data (no singular points: clean, heavy noise, raw counts, hard iron 5x,
 * strong soft iron, 300-degree arc, n = 60) takes the short path (report pretest_clean = 1, no
 * filter rejects, filter_eps 0) and meets the same accuracy: heading RMS within 1.2 x the floor
 * and within 2 % of the full pipeline's (measured: identical to 5 digits), the same inliers but at
 * most 1 sample. Every scenario with singular points (10 / 25 / 35 % outliers, spikes,
 * the near-ring cloud) fails the pre-test and gives the full pipeline's status, calibration,
 * report and per-sample flags bit for bit.
 */
static void test_pretest_clean_short_path_dirty_full_path_bit_identical(void)
{
    static const magcal_test_dump_t *const clean[] = {
        &dump_synthetic_clean,        &dump_synthetic_heavy_noise,      &dump_synthetic_raw_counts,
        &dump_synthetic_hard_iron_5x, &dump_synthetic_soft_iron_strong, &dump_synthetic_arc_300,
        &dump_synthetic_n60,
    };
    static const magcal_test_dump_t *const dirty[] = {
        &dump_synthetic_outliers_10, &dump_synthetic_outliers_25, &dump_synthetic_outliers_35,
        &dump_synthetic_spikes,      &dump_synthetic_near_ring,
    };
    static uint8_t f_pre[CAP];
    static uint8_t f_full[CAP];
    magcal_calibrator_cfg_t on = MAGCAL_CALIBRATOR_CFG_STORE_DEFAULT;
    magcal_calibrator_cfg_t off = MAGCAL_CALIBRATOR_CFG_DEFAULT;
    size_t s;
    /* the pre-test alone is compared: the store default's consistency gate (a gate after the fit,
     * tested on its own below) refuses the burst dumps' bursts as second rings */
    on.max_inconsistent_frac = 0.0f;
    TEST_ASSERT_EQUAL_UINT8(1u, on.pretest);  /* the store default */
    TEST_ASSERT_EQUAL_UINT8(0u, off.pretest); /* the default: the full pipeline */
    printf("\n%-34s %9s %9s %8s %6s %6s\n", "pre-test vs full pipeline", "rms pre", "rms full", "floor",
           "used", "full");
    for (s = 0; s < sizeof clean / sizeof clean[0]; ++s) {
        const magcal_test_dump_t *d = clean[s];
        run_t a;
        run_t b;
        int du;
        run_dump_flags(d, &on, &a, f_pre);
        run_dump_flags(d, &off, &b, f_full);
        printf("%-34s %9.5f %9.5f %8.4f %6u %6u\n", d->name, a.rms_deg, b.rms_deg,
               (double)d->truth->floor_deg, (unsigned)a.rep.used, (unsigned)b.rep.used);
        TEST_ASSERT_EQUAL_INT_MESSAGE(MAGCAL_OK, a.st, d->name);
        TEST_ASSERT_EQUAL_INT_MESSAGE(MAGCAL_OK, b.st, d->name);
        TEST_ASSERT_EQUAL_UINT8_MESSAGE(1u, a.rep.pretest_clean, d->name);
        TEST_ASSERT_EQUAL_UINT8_MESSAGE(0u, b.rep.pretest_clean, d->name);
        TEST_ASSERT_EQUAL_UINT16(0u, a.rep.rejected_filter);
        TEST_ASSERT_EQUAL_FLOAT(0.0f, a.rep.filter_eps);
        TEST_ASSERT_TRUE_MESSAGE(a.ratio <= 1.2, d->name);
        TEST_ASSERT_TRUE_MESSAGE(a.rms_deg <= 1.02 * b.rms_deg, d->name);
        TEST_ASSERT_TRUE_MESSAGE(false_rate(&a) <= 0.05, d->name);
        du = (int)a.rep.used - (int)b.rep.used;
        TEST_ASSERT_TRUE_MESSAGE(du >= -1 && du <= 1, d->name);
        TEST_ASSERT_EQUAL_UINT8(1u, a.rep.adopted);
    }
    for (s = 0; s < sizeof dirty / sizeof dirty[0]; ++s) {
        const magcal_test_dump_t *d = dirty[s];
        run_t a;
        run_t b;
        run_dump_flags(d, &on, &a, f_pre);
        run_dump_flags(d, &off, &b, f_full);
        printf("%-34s %9.5f %9.5f %8.4f %6u %6u (full path)\n", d->name, a.rms_deg, b.rms_deg,
               (double)d->truth->floor_deg, (unsigned)a.rep.used, (unsigned)b.rep.used);
        TEST_ASSERT_EQUAL_UINT8_MESSAGE(0u, a.rep.pretest_clean, d->name);
        TEST_ASSERT_EQUAL_INT_MESSAGE(b.st, a.st, d->name);
        TEST_ASSERT_EQUAL_MEMORY_MESSAGE(&b.cal, &a.cal, sizeof a.cal, d->name);
        TEST_ASSERT_EQUAL_MEMORY_MESSAGE(&b.rep, &a.rep, sizeof a.rep, d->name);
        TEST_ASSERT_EQUAL_MEMORY_MESSAGE(f_full, f_pre, d->truth->n_cal, d->name);
    }
}

/* Parked rings (40 / 60 % of the samples at one or two headings, tests/test_optics.c's clump
 * case, n = 200..1000): with the pre-test either the full pipeline's result bit for bit (the
 * consensus on every sample fails the pre-test) or, on the short path, OK within 1.2 x the floor on
 * 360 fresh headings and within 2 % of the full pipeline's heading RMS (never a worse OK).
 * Measured: 23 of 24 take the short path, each with the full pipeline's accuracy (1.0000 x): the
 * consensus' refit on every inlier is what both paths end with; a conic through the clump alone
 * (tests/test_optics.c) leaves far more than n / 16 of the drive rejected and fails the pre-test. */
static const test_distortion_t g_park = {50.0f, {{1.12f, 0.06f}, {0.06f, 0.91f}}, 24.0f, -17.0f};
static magcal_vec2_t g_park_pts[1000];

static double park_heading_true(magcal_vec2_t p)
{
    const test_distortion_t *d = &g_park;
    const double det = (double)d->t[0][0] * d->t[1][1] - (double)d->t[0][1] * d->t[1][0];
    const double x = (double)p.x - d->bx;
    const double y = (double)p.y - d->by;
    const double hx = ((double)d->t[1][1] * x - (double)d->t[0][1] * y) / det;
    const double hy = (-(double)d->t[1][0] * x + (double)d->t[0][0] * y) / det;
    return atan2(-hx, hy) * 57.29577951308232;
}

/* Heading RMS of c on 360 fresh headings of g_park (noise 0.5) over the true calibration's. */
static double park_ratio(const magcal_cal2d_t *c, uint32_t vrng)
{
    double ss = 0.0, sf = 0.0;
    size_t i;
    for (i = 0; i < 360u; ++i) {
        const double psi = (double)i + 0.5;
        const magcal_vec2_t p = test_distorted_sample(&g_park, psi, 0.5, &vrng);
        float h;
        double e;
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_heading_compute(c, p, 0.0f, &h, NULL));
        e = test_angle_diff_deg((double)h, psi);
        ss += e * e;
        e = test_angle_diff_deg(park_heading_true(p), psi);
        sf += e * e;
    }
    return sqrt(ss / sf);
}

static void test_pretest_parked_rings_full_path_or_within_floor(void)
{
    static const size_t ns[] = {200u, 500u, 1000u};
    static const double fracs[] = {0.4, 0.6};
    static uint8_t f_pre[CAP];
    static uint8_t f_full[CAP];
    magcal_calibrator_cfg_t on = MAGCAL_CALIBRATOR_CFG_STORE_DEFAULT;
    magcal_calibrator_cfg_t off = MAGCAL_CALIBRATOR_CFG_DEFAULT;
    unsigned runs = 0u, full = 0u, shortp = 0u;
    double worst = 0.0;
    double worst_vs_full = 0.0;
    size_t in, ifr, two, seed;
    for (in = 0; in < 3u; ++in) {
        for (ifr = 0; ifr < 2u; ++ifr) {
            for (two = 0; two < 2u; ++two) {
                for (seed = 1u; seed <= 2u; ++seed) {
                    const size_t n = ns[in];
                    const size_t n_park = (size_t)(fracs[ifr] * (double)n + 0.5);
                    const size_t n_first = two ? (2u * n_park) / 3u : n_park;
                    uint32_t rng = (uint32_t)(101u * seed + 7u * in + 3u * ifr + two);
                    const double psi1 = 360.0 * test_rand_uniform(&rng);
                    const double psi2 = 360.0 * test_rand_uniform(&rng);
                    magcal_cal2d_t ca = MAGCAL_CAL2D_IDENTITY;
                    magcal_cal2d_t cb = MAGCAL_CAL2D_IDENTITY;
                    magcal_cal_report_t ra;
                    magcal_cal_report_t rb;
                    magcal_status_t sa;
                    magcal_status_t sb;
                    size_t i;
                    for (i = 0; i < n; ++i) {
                        double psi = psi2;
                        if (i < n_first) {
                            psi = psi1;
                        } else if (i < n - n_park + n_first) {
                            psi = psi1 + 450.0 * (double)(i - n_first) / (double)(n - n_park);
                        }
                        g_park_pts[i] = test_distorted_sample(&g_park, psi, 0.5, &rng);
                    }
                    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_init(&g_cal, &off, g_buf, CAP, g_work, sizeof g_work));
                    for (i = 0; i < n; ++i) {
                        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_push(&g_cal, g_park_pts[i]));
                    }
                    sb = magcal_calibrator_run(&g_cal, &cb, &rb);
                    for (i = 0; i < n; ++i) {
                        (void)magcal_calibrator_flags(&g_cal, i, &f_full[i]);
                    }
                    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_init(&g_cal, &on, g_buf, CAP, g_work, sizeof g_work));
                    for (i = 0; i < n; ++i) {
                        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_push(&g_cal, g_park_pts[i]));
                    }
                    sa = magcal_calibrator_run(&g_cal, &ca, &ra);
                    for (i = 0; i < n; ++i) {
                        (void)magcal_calibrator_flags(&g_cal, i, &f_pre[i]);
                    }
                    ++runs;
                    if (ra.pretest_clean == 0u) {
                        ++full;
                        TEST_ASSERT_EQUAL_INT(sb, sa);
                        TEST_ASSERT_EQUAL_MEMORY(&cb, &ca, sizeof ca);
                        TEST_ASSERT_EQUAL_MEMORY(&rb, &ra, sizeof ra);
                        TEST_ASSERT_EQUAL_MEMORY(f_full, f_pre, n);
                    } else {
                        ++shortp;
                    }
                    if (sa == MAGCAL_OK) {
                        const uint32_t vseed = (uint32_t)(977u * seed + 31u * in);
                        const double ratio = park_ratio(&ca, vseed);
                        worst = ratio > worst ? ratio : worst;
                        TEST_ASSERT_TRUE(ratio <= 1.2);
                        if (ra.pretest_clean != 0u) {
                            /* never worse than the full pipeline by more than 2 % */
                            const double rf = sb == MAGCAL_OK ? park_ratio(&cb, vseed) : INFINITY;
                            worst_vs_full = ratio / rf > worst_vs_full ? ratio / rf : worst_vs_full;
                            TEST_ASSERT_TRUE(sb != MAGCAL_OK || ratio <= 1.02 * rf);
                        }
                    }
                }
            }
        }
    }
    printf("parked rings: %u runs, %u full path (bit for bit), %u short path, worst OK %.3f x floor, short path "
           "vs full pipeline at most %.4f x\n", runs, full, shortp, worst, worst_vs_full);
}

/* ---------------------------------------------------------------- time-sliced solve */

/* run() is the sliced solve with an unlimited budget; at budgets 1, 97, 1000 and 6000 the same
 * buffer gives, bit for bit, run()'s status, calibration, report and per-sample flags: every
 * scenario, the default pipeline, no filter, DBSCAN, the plain fit and the default pipeline with
 * the pre-test (both its paths), against the identity and against an installed calibration (the
 * adoption rule's harmonics of `current`). */
static void sliced_case(const magcal_test_dump_t *d, const magcal_calibrator_cfg_t *cfg,
                        const magcal_cal2d_t *installed)
{
    static const uint32_t budgets[] = {1u, 97u, 1000u, 6000u};
    static uint8_t flags_ref[CAP];
    magcal_cal_report_t rep_ref;
    magcal_cal2d_t cal_ref = *installed;
    magcal_status_t st_ref;
    size_t n_cal = d->truth->n_cal;
    size_t i;
    size_t b;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_init(&g_cal, cfg, g_buf, CAP, g_work, sizeof g_work));
    for (i = 0; i < n_cal; ++i) {
        (void)magcal_calibrator_push(&g_cal, row(d, i));
    }
    st_ref = magcal_calibrator_run(&g_cal, &cal_ref, &rep_ref);
    for (i = 0; i < magcal_calibrator_count(&g_cal); ++i) {
        flags_ref[i] = 0u;
        (void)magcal_calibrator_flags(&g_cal, i, &flags_ref[i]);
    }
    for (b = 0u; b < sizeof budgets / sizeof budgets[0]; ++b) {
        magcal_cal_report_t rep;
        magcal_cal2d_t cal = *installed;
        magcal_status_t st;
        unsigned long steps = 0u;
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_init(&g_cal, cfg, g_buf, CAP, g_work, sizeof g_work));
        for (i = 0; i < n_cal; ++i) {
            (void)magcal_calibrator_push(&g_cal, row(d, i));
        }
        /* load_bbox 1: the continuous calibrator's path (bounding box recomputed as a pass) */
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_solve_begin(&g_cal, magcal_calibrator_count(&g_cal), (int)(b & 1u)));
        do {
            memset(&rep, 0xA5, sizeof rep);
            st = magcal_calibrator_solve_step(&g_cal, &cal, budgets[b], &rep);
            TEST_ASSERT_TRUE(++steps < 50000000ul);
        } while (st == MAGCAL_IN_PROGRESS);
        TEST_ASSERT_EQUAL_INT(st_ref, st);
        TEST_ASSERT_EQUAL_MEMORY(&cal_ref, &cal, sizeof cal);
        TEST_ASSERT_EQUAL_MEMORY(&rep_ref, &rep, sizeof rep);
        TEST_ASSERT_EQUAL_INT(magcal_calibrator_last_status(&g_cal), st);
        for (i = 0; i < magcal_calibrator_count(&g_cal); ++i) {
            uint8_t f = 0u;
            (void)magcal_calibrator_flags(&g_cal, i, &f);
            TEST_ASSERT_EQUAL_UINT8(flags_ref[i], f);
        }
        TEST_ASSERT_FALSE(magcal_calibrator_solving(&g_cal));
        TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_STATE, magcal_calibrator_solve_step(&g_cal, &cal, 6000u, NULL));
    }
}

static void test_sliced_solve_matches_run_bit_for_bit(void)
{
    magcal_calibrator_cfg_t cfgs[5];
    magcal_cal2d_t ident = MAGCAL_CAL2D_IDENTITY;
    magcal_cal2d_t none = MAGCAL_CAL2D_IDENTITY;
    magcal_cal2d_t near_truth;
    size_t s;
    size_t c;
    none.radius = 0.0f; /* unusable: the new calibration replaces it */
    for (c = 0u; c < 5u; ++c) {
        magcal_calibrator_cfg_t dflt = MAGCAL_CALIBRATOR_CFG_DEFAULT;
        cfgs[c] = dflt;
    }
    cfgs[1].filter = MAGCAL_FILTER_NONE;
    cfgs[2].filter = MAGCAL_FILTER_DBSCAN;
    cfgs[3].use_consensus = 0u;
    cfgs[4].pretest = 1u; /* the default pipeline with the pre-test (the store default) */
    for (s = 0u; s < N_SCEN; ++s) {
        for (c = 0u; c < 5u; ++c) {
            sliced_case(g_scen[s], &cfgs[c], c == 0u ? &none : &ident);
        }
    }
    /* against a good installed calibration: the full rule (NOT_BETTER or BETTER / STALE) */
    {
        run_t r;
        run_dump(&dump_synthetic_clean, &cfgs[0], &r);
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, r.st);
        near_truth = r.cal;
        near_truth.offset.x += 0.05f;
        sliced_case(&dump_synthetic_outliers_10, &cfgs[0], &near_truth);
        sliced_case(&dump_synthetic_clean, &cfgs[0], &near_truth);
        sliced_case(&dump_synthetic_outliers_10, &cfgs[4], &near_truth); /* pre-test refused */
        sliced_case(&dump_synthetic_clean, &cfgs[4], &near_truth);       /* short path */
    }
}

/* Arc stage (calibrator.h "Arc stage", magcal_calibrator_set_arc): 120 samples spread over arcs of
 * 190 / 220 / 250 deg, noise 1 % of R, hard and soft iron known, 12 seeds each. Off (the default
 * after init): COVERAGE. On (180 deg, tolerance 5 deg, model term 0: the data have no model error):
 * every OK is an arc (report arc 1, est_param_err_deg = est_param_err_deg) whose truth RMS over the
 * WHOLE circle (360 noise-free headings) is <= its bound; a tolerance below every bound (0.02 deg):
 * UNOBSERVABLE with the bound above it, `current` bit-identical; an arc never replaces a full
 * `current` (NOT_BETTER). */
static void test_run_arc_bound_covers_whole_circle(void)
{
    static const double arcs[3] = {190.0, 220.0, 250.0};
    const test_distortion_t d = {40.0f, {{1.1f, 0.05f}, {0.05f, 0.9f}}, 12.0f, -7.0f};
    const magcal_calibrator_cfg_t cfg = MAGCAL_CALIBRATOR_CFG_STORE_DEFAULT;
    unsigned ok = 0u, refused = 0u, cov = 0u, runs = 0u;
    double worst = 1.0e9, ratio_max = 0.0;
    size_t a;
    unsigned seed;
    for (a = 0u; a < 3u; ++a) {
        for (seed = 1u; seed <= 12u; ++seed) {
            int mode;
            for (mode = 0; mode < 4; ++mode) {
                uint32_t rng = seed * 2654435761u + (uint32_t)a;
                magcal_cal2d_t c = MAGCAL_CAL2D_IDENTITY;
                magcal_cal2d_t before;
                magcal_cal_report_t rep;
                magcal_status_t st;
                size_t i;
                const double start = 37.0 * (double)seed;
                TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_init(&g_cal, &cfg, g_buf, CAP, g_work, sizeof g_work));
                if (mode == 1) {
                    magcal_calibrator_set_arc(&g_cal, 180.0f, 5.0f, 0.0f);
                } else if (mode == 2) {
                    magcal_calibrator_set_arc(&g_cal, 180.0f, 0.02f, 0.0f);
                } else if (mode == 3) {
                    magcal_calibrator_set_arc(&g_cal, 180.0f, 5.0f, 0.0f);
                    c.offset.x = 12.0f; /* a full calibration installed (close to the truth) */
                    c.offset.y = -7.0f;
                    c.radius = 40.0f;
                } else {
                    /* off */
                }
                before = c;
                for (i = 0u; i < 120u; ++i) {
                    const double psi = start + arcs[a] * ((double)i + test_rand_uniform(&rng)) / 120.0;
                    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_push(&g_cal, test_distorted_sample(&d, psi, 0.4, &rng)));
                }
                st = magcal_calibrator_run(&g_cal, &c, &rep);
                if (mode == 0) {
                    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_COVERAGE, st);
                    TEST_ASSERT_EQUAL_UINT8(0u, rep.arc);
                    cov++;
                } else if (mode == 1) {
                    runs++;
                    if (st == MAGCAL_OK) {
                        const double tr = truth_rms_360(&c, &d);
                        TEST_ASSERT_EQUAL_UINT8(1u, rep.arc);
                        TEST_ASSERT_TRUE(rep.coverage_deg < 270.0f);
                        TEST_ASSERT_TRUE(rep.est_param_err_deg <= 5.0f);
                        TEST_ASSERT_TRUE(tr <= (double)rep.est_param_err_deg); /* the promise */
                        worst = fmin(worst, (double)rep.est_param_err_deg - tr);
                        ratio_max = fmax(ratio_max, tr / (double)rep.est_param_err_deg);
                        ok++;
                    } else {
                        TEST_ASSERT_EQUAL_MEMORY(&before, &c, sizeof c);
                    }
                } else if (mode == 2) {
                    TEST_ASSERT_EQUAL_MEMORY(&before, &c, sizeof c); /* untouched */
                    if (rep.arc != 0u && st == MAGCAL_ERR_UNOBSERVABLE) {
                        TEST_ASSERT_TRUE(rep.est_param_err_deg > 0.02f);
                        refused++;
                    } else {
                        TEST_ASSERT_TRUE(st != MAGCAL_OK);
                    }
                } else {
                    TEST_ASSERT_TRUE(st != MAGCAL_OK); /* never replaces a full calibration */
                    TEST_ASSERT_EQUAL_MEMORY(&before, &c, sizeof c);
                }
            }
        }
    }
    printf("arc stage, 36 arcs of 190..250 deg: off %u COVERAGE; on %u of %u OK (worst margin bound - truth %.3f deg, "
           "truth / bound <= %.3f); tolerance 0.02 deg: %u refused UNOBSERVABLE\n",
           cov, ok, runs, worst, ratio_max, refused);
    TEST_ASSERT_TRUE(ok >= 30u);
    TEST_ASSERT_TRUE(refused >= 30u);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_truth_floor_recomputes_in_c);
    RUN_TEST(test_run_every_scenario_default_within_1p2_floor);
    RUN_TEST(test_run_outlier_scenarios_plain_ls_fails);
    RUN_TEST(test_run_every_filter_choice_within_1p2_floor);
    RUN_TEST(test_push_nonfinite_returns_nonfinite_not_stored);
    RUN_TEST(test_run_identical_points_returns_degenerate_keeps_cal);
    RUN_TEST(test_run_collinear_points_returns_degenerate_keeps_cal);
    RUN_TEST(test_run_fewer_than_5_points_returns_too_few_keeps_cal);
    RUN_TEST(test_run_short_arc_returns_coverage_names_missing_sector_keeps_cal);
    RUN_TEST(test_push_buffer_full_returns_buffer_full);
    RUN_TEST(test_workspace_len_capacity_1024_within_24_bytes_per_sample);
    RUN_TEST(test_run_tiny_eps_returns_all_noise_keeps_cal);
    RUN_TEST(test_run_spikes_without_rejection_returns_hyperbola_keeps_cal);
    RUN_TEST(test_run_gates_each_return_own_status_keep_cal);
    RUN_TEST(test_init_bad_cfg_returns_arg);
    RUN_TEST(test_run_failure_reports_nan_estimates);
    RUN_TEST(test_run_better_fit_adopted_reports_shift);
    RUN_TEST(test_run_implausible_radius_not_better_keeps_cal);
    RUN_TEST(test_run_corrupted_current_is_replaced);
    RUN_TEST(test_run_exactly_min_samples_clean_calibrates);
    RUN_TEST(test_classify_matches_inlier_flags);
    RUN_TEST(test_push_spacing_gate_skips_redundant_samples);
    RUN_TEST(test_push_per_bin_cap_limits_samples);
    RUN_TEST(test_poll_reads_port_passes_errors_through);
    RUN_TEST(test_run_lsm9ds1_flat_turns_spread_near_optimum);
    RUN_TEST(test_run_lsm9ds1_driver_glitches_all_rejected);
    RUN_TEST(test_sliced_solve_matches_run_bit_for_bit);
    RUN_TEST(test_pretest_clean_short_path_dirty_full_path_bit_identical);
    RUN_TEST(test_pretest_parked_rings_full_path_or_within_floor);
    RUN_TEST(test_run_store_of_two_installations_inconsistent);
    RUN_TEST(test_init_inconsistent_frac_checked);
    RUN_TEST(test_run_arc_bound_covers_whole_circle);
    return UNITY_END();
}
