/*
 * Tests of the consensus (model-residual) outlier stage, consensus.h, on synthetic dumps with known
 * truth (tools/gen_dump.py): outlier recall / false rejections against the dump's outlier column,
 * fitted centre and semi-axes against the truth (b, T), determinism, rescue of density-filter
 * rejects, bad input.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "magcal/consensus.h"
#include "magcal/optics.h"
#include "test_dumps.h"
#include "test_util.h"
#include "unity.h"

#define NMAX 1024u

static magcal_vec2_t g_pts[NMAX];
static uint8_t g_mask[NMAX];
static uint8_t g_cand[NMAX];
static uint32_t g_work[(MAGCAL_CONSENSUS_WORKSPACE_LEN(NMAX) + 3u) / 4u];
static uint32_t g_owork[(MAGCAL_OPTICS_FILTER_WORKSPACE_LEN(NMAX) + 3u) / 4u];

void setUp(void) {}
void tearDown(void) {}

/* calibration rows of a dump into g_pts; returns n_cal */
static size_t load(const magcal_test_dump_t *d)
{
    size_t i;
    size_t n = d->truth->n_cal;
    for (i = 0; i < n; ++i) {
        g_pts[i].x = d->mx[i];
        g_pts[i].y = d->my[i];
    }
    return n;
}

/* truth semi-axes: eigenvalues of the symmetric T times h0 */
static void truth_axes(const magcal_test_truth_t *t, float *r_min, float *r_max)
{
    float tr = t->t00 + t->t11;
    float det = t->t00 * t->t11 - t->t01 * t->t10;
    float disc = sqrtf(0.25f * tr * tr - det);
    *r_min = t->h0 * (0.5f * tr - disc);
    *r_max = t->h0 * (0.5f * tr + disc);
}

static void check_scenario(const magcal_test_dump_t *d, int use_optics)
{
    magcal_consensus_cfg_t cfg = MAGCAL_CONSENSUS_CFG_DEFAULT;
    magcal_consensus_result_t res;
    size_t n = load(d);
    size_t i;
    size_t n_out = 0u, caught = 0u, n_in = 0u, false_rej = 0u;
    float rmin, rmax;
    const uint8_t *cand = NULL;
    if (use_optics) {
        magcal_optics_cfg_t oc = MAGCAL_OPTICS_CFG_DEFAULT;
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_optics_filter(&oc, g_pts, n, g_owork, sizeof g_owork, g_cand, NULL));
        cand = g_cand;
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_consensus_run(&cfg, g_pts, n, cand, g_work, sizeof g_work, g_mask, &res));
    for (i = 0; i < n; ++i) {
        if (d->outlier[i] > 0.5f) {
            ++n_out;
            caught += g_mask[i] ? 0u : 1u;
        } else {
            ++n_in;
            false_rej += g_mask[i] ? 1u : 0u;
        }
    }
    false_rej = n_in - false_rej;
    truth_axes(d->truth, &rmin, &rmax);
    printf("%-34s %s: inliers %u, caught %u/%u, false %u/%u, draws %u valid %u rounds %u, sigma %.4f thr %.4f, "
           "centre err %.4f, axes %.3f/%.3f (truth %.3f/%.3f)\n",
           d->name, use_optics ? "optics+cons" : "cons only ", (unsigned)res.n_inliers, (unsigned)caught,
           (unsigned)n_out, (unsigned)false_rej, (unsigned)n_in, (unsigned)res.draws, (unsigned)res.valid_models,
           (unsigned)res.rounds, (double)res.sigma, (double)res.threshold,
           (double)hypotf(res.fit.center.x - d->truth->bx, res.fit.center.y - d->truth->by),
           (double)res.fit.semi_minor, (double)res.fit.semi_major, (double)rmin, (double)rmax);
    /* recall >= 90 %, false rejections <= 5 % of the inliers */
    TEST_ASSERT_TRUE_MESSAGE(caught * 10u >= n_out * 9u, d->name);
    TEST_ASSERT_TRUE_MESSAGE(false_rej * 20u <= n_in, d->name);
    /* centre and axes: noise sigma 0.2 over >= 390 inliers gives ~0.02 standard error; 0.1 = 5x */
    TEST_ASSERT_FLOAT_WITHIN_MESSAGE(0.1f, d->truth->bx, res.fit.center.x, d->name);
    TEST_ASSERT_FLOAT_WITHIN_MESSAGE(0.1f, d->truth->by, res.fit.center.y, d->name);
    TEST_ASSERT_FLOAT_WITHIN_MESSAGE(0.1f, rmin, res.fit.semi_minor, d->name);
    TEST_ASSERT_FLOAT_WITHIN_MESSAGE(0.1f, rmax, res.fit.semi_major, d->name);
    /* sigma recovers the noise (0.2) within 20 % */
    TEST_ASSERT_FLOAT_WITHIN_MESSAGE(0.04f, d->truth->sigma, res.sigma, d->name);
    TEST_ASSERT_EQUAL_UINT32(res.n_inliers, (uint32_t)(n - n_out - false_rej + (n_out - caught)));
}

static void test_consensus_run_bursts_alone_recall_90_centre_truth(void)
{
    check_scenario(&dump_synthetic_outliers_10, 0);
    check_scenario(&dump_synthetic_outliers_25, 0);
    check_scenario(&dump_synthetic_outliers_35, 0);
    check_scenario(&dump_synthetic_near_ring, 0);
    check_scenario(&dump_synthetic_spikes, 0);
    check_scenario(&dump_synthetic_clean, 0);
}

static void test_consensus_run_after_optics_recall_90_centre_truth(void)
{
    check_scenario(&dump_synthetic_outliers_10, 1);
    check_scenario(&dump_synthetic_outliers_25, 1);
    check_scenario(&dump_synthetic_outliers_35, 1);
    check_scenario(&dump_synthetic_near_ring, 1);
    check_scenario(&dump_synthetic_spikes, 1);
}

/* Field by field: struct padding bytes are unspecified, so memcmp of whole structs is not a
 * determinism check (it failed on uninitialised padding under QEMU and ASan). */
static void assert_same_result(const magcal_consensus_result_t *a, const magcal_consensus_result_t *b)
{
    TEST_ASSERT_EQUAL_MEMORY(&a->fit.center, &b->fit.center, sizeof a->fit.center);
    TEST_ASSERT_EQUAL_MEMORY(&a->fit.semi_minor, &b->fit.semi_minor, sizeof(float));
    TEST_ASSERT_EQUAL_MEMORY(&a->fit.semi_major, &b->fit.semi_major, sizeof(float));
    TEST_ASSERT_EQUAL_MEMORY(&a->fit.angle_rad, &b->fit.angle_rad, sizeof(float));
    TEST_ASSERT_EQUAL_MEMORY(a->fit.coef, b->fit.coef, sizeof a->fit.coef);
    TEST_ASSERT_EQUAL_MEMORY(&a->fit.residual_rms, &b->fit.residual_rms, sizeof(float));
    TEST_ASSERT_EQUAL_MEMORY(&a->sigma, &b->sigma, sizeof(float));
    TEST_ASSERT_EQUAL_MEMORY(&a->threshold, &b->threshold, sizeof(float));
    TEST_ASSERT_EQUAL_MEMORY(&a->best_score, &b->best_score, sizeof(float));
    TEST_ASSERT_EQUAL_UINT16(a->fit.n_used, b->fit.n_used);
    TEST_ASSERT_EQUAL_UINT16(a->n_candidates, b->n_candidates);
    TEST_ASSERT_EQUAL_UINT16(a->n_inliers, b->n_inliers);
    TEST_ASSERT_EQUAL_UINT16(a->n_rescued, b->n_rescued);
    TEST_ASSERT_EQUAL_UINT16(a->n_rejected, b->n_rejected);
    TEST_ASSERT_EQUAL_UINT16(a->draws, b->draws);
    TEST_ASSERT_EQUAL_UINT16(a->valid_models, b->valid_models);
    TEST_ASSERT_EQUAL_UINT16(a->rounds, b->rounds);
}

/* Same seed: bit-identical mask and fit. Another seed: the same inlier set on this data. */
static void test_consensus_run_same_seed_is_deterministic(void)
{
    static uint8_t mask2[NMAX];
    magcal_consensus_cfg_t cfg = MAGCAL_CONSENSUS_CFG_DEFAULT;
    magcal_consensus_result_t a, b;
    size_t n = load(&dump_synthetic_outliers_35);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_consensus_run(&cfg, g_pts, n, NULL, g_work, sizeof g_work, g_mask, &a));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_consensus_run(&cfg, g_pts, n, NULL, g_work, sizeof g_work, mask2, &b));
    TEST_ASSERT_EQUAL_MEMORY(g_mask, mask2, n);
    assert_same_result(&a, &b);
    cfg.seed = 12345u;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_consensus_run(&cfg, g_pts, n, NULL, g_work, sizeof g_work, mask2, &b));
    TEST_ASSERT_EQUAL_MEMORY(g_mask, mask2, n);
}

/* Candidates that leave out every third clean sample: those are judged by residual and taken back. */
static void test_consensus_run_noncandidates_on_ring_are_rescued(void)
{
    magcal_consensus_cfg_t cfg = MAGCAL_CONSENSUS_CFG_DEFAULT;
    magcal_consensus_result_t res;
    size_t n = load(&dump_synthetic_clean);
    size_t i;
    size_t left_out = 0u;
    for (i = 0; i < n; ++i) {
        g_cand[i] = (uint8_t)((i % 3u) != 0u);
        left_out += g_cand[i] ? 0u : 1u;
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_consensus_run(&cfg, g_pts, n, g_cand, g_work, sizeof g_work, g_mask, &res));
    TEST_ASSERT_EQUAL_UINT32((uint32_t)(n - left_out), res.n_candidates);
    /* 3.5 sigma: at most a handful of the 200 left-out samples stay out */
    TEST_ASSERT_TRUE(res.n_rescued >= left_out - 5u);
}

static void test_consensus_run_bad_input_returns_status_outputs_untouched(void)
{
    magcal_consensus_cfg_t cfg = MAGCAL_CONSENSUS_CFG_DEFAULT;
    magcal_consensus_result_t res;
    magcal_consensus_result_t ref;
    size_t n = load(&dump_synthetic_clean);
    size_t i;
    memset(&res, 0xA5, sizeof res);
    memset(&ref, 0xA5, sizeof ref);
    memset(g_mask, 0x5A, n);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_consensus_run(NULL, g_pts, n, NULL, g_work, sizeof g_work, g_mask, &res));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_consensus_run(&cfg, NULL, n, NULL, g_work, sizeof g_work, g_mask, &res));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_consensus_run(&cfg, g_pts, n, NULL, NULL, sizeof g_work, g_mask, &res));
    /* the size macro is exact: one byte less is refused */
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_WORKSPACE,
                          magcal_consensus_run(&cfg, g_pts, n, NULL, g_work, MAGCAL_CONSENSUS_WORKSPACE_LEN(n) - 1u, g_mask, &res));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_TOO_FEW_POINTS, magcal_consensus_run(&cfg, g_pts, 4, NULL, g_work, sizeof g_work, g_mask, &res));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_consensus_run(&cfg, g_pts, NMAX + 1u, NULL, g_work, sizeof g_work, g_mask, &res));
    cfg.max_iter = 0u;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_consensus_run(&cfg, g_pts, n, NULL, g_work, sizeof g_work, g_mask, &res));
    cfg = (magcal_consensus_cfg_t)MAGCAL_CONSENSUS_CFG_DEFAULT;
    cfg.max_thr_rel = cfg.min_thr_rel;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_consensus_run(&cfg, g_pts, n, NULL, g_work, sizeof g_work, g_mask, &res));
    cfg = (magcal_consensus_cfg_t)MAGCAL_CONSENSUS_CFG_DEFAULT;
    cfg.k_sigma = NAN;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_consensus_run(&cfg, g_pts, n, NULL, g_work, sizeof g_work, g_mask, &res));
    cfg = (magcal_consensus_cfg_t)MAGCAL_CONSENSUS_CFG_DEFAULT;
    /* four candidates only */
    memset(g_cand, 0, n);
    g_cand[0] = g_cand[100] = g_cand[200] = g_cand[300] = 1u;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_TOO_FEW_POINTS, magcal_consensus_run(&cfg, g_pts, n, g_cand, g_work, sizeof g_work, g_mask, &res));
    /* a NaN sample */
    g_pts[17].y = NAN;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_consensus_run(&cfg, g_pts, n, NULL, g_work, sizeof g_work, g_mask, &res));
    /* collinear samples: no minimal set and no LS fit is an ellipse */
    for (i = 0; i < 100; ++i) {
        g_pts[i].x = 1.0f + 0.5f * (float)i;
        g_pts[i].y = -3.0f + 0.25f * (float)i;
    }
    {
        magcal_status_t st = magcal_consensus_run(&cfg, g_pts, 100, NULL, g_work, sizeof g_work, g_mask, &res);
        TEST_ASSERT_TRUE(st == MAGCAL_ERR_DEGENERATE || st == MAGCAL_ERR_ILL_CONDITIONED);
    }
    TEST_ASSERT_EQUAL_MEMORY(&ref, &res, sizeof res);
    for (i = 0; i < n; ++i) {
        TEST_ASSERT_EQUAL_HEX8(0x5A, g_mask[i]);
    }
}

/* Exactly 20 clean samples (the default min_samples), 300 seeds: the robust scale used to include
 * the minimal set's five zero residuals (issue 12: 7.6 % of clean samples rejected at n = 20).
 * Now <= 0.6 % of the 6000 clean samples are rejected (measured 0.47 %), and >= 93 % of the runs
 * keep all 20 (measured 286/300). At
 * n = 300 the rejection rate is the 3.5-sigma tail (<= 0.2 %). */
static void small_clean_run(size_t n, unsigned seeds, unsigned *rejected, unsigned *all_kept)
{
    magcal_consensus_cfg_t cfg = MAGCAL_CONSENSUS_CFG_DEFAULT;
    test_distortion_t d = {40.0f, {{1.1f, 0.05f}, {0.05f, 0.9f}}, 12.0f, -7.0f};
    unsigned s;
    *rejected = 0u;
    *all_kept = 0u;
    for (s = 1u; s <= seeds; ++s) {
        uint32_t rng = s * 2654435761u + 7u;
        magcal_consensus_result_t res;
        size_t i;
        for (i = 0; i < n; ++i) {
            double psi = 360.0 * test_rand_uniform(&rng);
            g_pts[i] = test_distorted_sample(&d, psi, 0.4, &rng);
        }
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_consensus_run(&cfg, g_pts, n, NULL, g_work, sizeof g_work, g_mask, &res));
        *rejected += (unsigned)(n - res.n_inliers);
        *all_kept += res.n_inliers == n ? 1u : 0u;
    }
}

static void test_consensus_run_twenty_clean_samples_keeps_them(void)
{
    unsigned rej20, kept20, rej300, kept300;
    small_clean_run(20u, 300u, &rej20, &kept20);
    small_clean_run(300u, 20u, &rej300, &kept300);
    printf("clean samples rejected: n = 20: %u of 6000 (%.2f %%), all kept in %u/300 runs; n = 300: %u of 6000\n",
           rej20, 100.0 * rej20 / 6000.0, kept20, rej300);
    TEST_ASSERT_TRUE(rej20 <= 36u);
    TEST_ASSERT_TRUE(kept20 >= 280u);
    TEST_ASSERT_TRUE(rej300 <= 12u);
}

/* A ring of 5 LSB radius rounded to integers: few distinct values lie almost on a conic, so the
 * median residual fell far below the rounding noise and a third of the clean samples were
 * rejected. With sigma floored at LSB / sqrt(12) the lattice is kept (>= 95 %). */
static void test_consensus_run_quantised_ring_keeps_lattice(void)
{
    magcal_consensus_cfg_t cfg = MAGCAL_CONSENSUS_CFG_DEFAULT;
    magcal_consensus_result_t res;
    test_distortion_t d = {5.0f, {{1.1f, 0.05f}, {0.05f, 0.9f}}, 3.3f, -1.7f};
    unsigned s;
    unsigned worst = 300u;
    for (s = 1u; s <= 20u; ++s) {
        uint32_t rng = s * 40503u + 3u;
        size_t i;
        for (i = 0; i < 300u; ++i) {
            magcal_vec2_t p = test_distorted_sample(&d, 360.0 * test_rand_uniform(&rng), 0.1, &rng);
            g_pts[i].x = floorf(p.x + 0.5f);
            g_pts[i].y = floorf(p.y + 0.5f);
        }
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_consensus_run(&cfg, g_pts, 300u, NULL, g_work, sizeof g_work, g_mask, &res));
        if (res.n_inliers < worst) {
            worst = res.n_inliers;
        }
        TEST_ASSERT_TRUE(res.sigma >= 0.2886f);
    }
    printf("5-LSB quantised ring: worst run keeps %u of 300 samples\n", worst);
    TEST_ASSERT_TRUE(worst >= 285u);
}

/* ---- time-sliced run (slice contract, issue 13) ---- */

static const uint32_t k_budgets[] = {1u, 97u, 1000u, 6000u, UINT32_MAX};

/* The run sliced at budget gives exactly the one-shot status and outputs; returns the number of
 * step calls. *charged gets the sum of the steps' charged estimates. */
static unsigned sliced_matches_oneshot(const magcal_consensus_cfg_t *cfg, size_t n, const uint8_t *cand,
                                       uint32_t budget, uint32_t *charged)
{
    static uint8_t ref_mask[NMAX];
    magcal_consensus_result_t ref, got;
    magcal_consensus_slice_t sl;
    magcal_status_t st_ref, st;
    unsigned steps = 0u;
    uint32_t total = 0u;
    memset(&ref, 0xA5, sizeof ref);
    memset(&got, 0xA5, sizeof got);
    memset(ref_mask, 0x5A, sizeof ref_mask);
    memset(g_mask, 0x5A, sizeof g_mask);
    st_ref = magcal_consensus_run(cfg, g_pts, n, cand, g_work, sizeof g_work, ref_mask, &ref);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_consensus_begin(&sl, cfg, g_pts, n, cand, g_work, sizeof g_work, g_mask, &got));
    do {
        st = magcal_consensus_step(&sl, budget);
        TEST_ASSERT_TRUE(budget == UINT32_MAX || sl.used_ <= budget || sl.used_ <= 3800u);
        total += sl.used_;
        ++steps;
        TEST_ASSERT_TRUE(steps < 20000000u);
    } while (st == MAGCAL_IN_PROGRESS);
    TEST_ASSERT_EQUAL_INT(st_ref, st);
    /* finished: every further step returns the same status and does nothing */
    TEST_ASSERT_EQUAL_INT(st_ref, magcal_consensus_step(&sl, budget));
    TEST_ASSERT_EQUAL_UINT32(0u, sl.used_);
    if (st_ref == MAGCAL_OK) {
        assert_same_result(&ref, &got);
        TEST_ASSERT_EQUAL_MEMORY(&ref.fit.norm_center, &got.fit.norm_center, sizeof ref.fit.norm_center);
        TEST_ASSERT_EQUAL_MEMORY(&ref.fit.norm_scale, &got.fit.norm_scale, sizeof(float));
        TEST_ASSERT_EQUAL_MEMORY(&ref.fit.min_pivot, &got.fit.min_pivot, sizeof(float));
        TEST_ASSERT_EQUAL_MEMORY(ref.fit.qform, got.fit.qform, sizeof ref.fit.qform);
    } else {
        magcal_consensus_result_t untouched;
        memset(&untouched, 0xA5, sizeof untouched);
        TEST_ASSERT_EQUAL_MEMORY(&untouched, &got, sizeof got);
    }
    TEST_ASSERT_EQUAL_MEMORY(ref_mask, g_mask, n);
    *charged = total;
    return steps;
}

/* Every budget on one data set. At 6000 every step but the last spends its budget but less than
 * one visit (the largest, a minimal set, charges 3800): steps <= total / 2200 + 1; from n = 100 on
 * (where the minimal sets are a small part of the run) steps <= 1.25 x total / 6000 + 2. */
static void sliced_all_budgets(const char *name, size_t n, const uint8_t *cand)
{
    magcal_consensus_cfg_t cfg = MAGCAL_CONSENSUS_CFG_DEFAULT;
    magcal_consensus_result_t res;
    uint32_t total = 0u;
    uint32_t charged;
    res.draws = 0u;
    size_t b;
    unsigned steps6000 = 0u;
    for (b = 0u; b < sizeof k_budgets / sizeof k_budgets[0]; ++b) {
        unsigned steps = sliced_matches_oneshot(&cfg, n, cand, k_budgets[b], &charged);
        if (k_budgets[b] == UINT32_MAX) {
            TEST_ASSERT_EQUAL_UINT(1u, steps);
            total = charged;
        }
        if (k_budgets[b] == 6000u) {
            steps6000 = steps;
        }
    }
    printf("%-34s n %4u: one-shot charges %7lu estimated M4F instructions, %4u steps at budget 6000\n", name,
           (unsigned)n, (unsigned long)total, steps6000);
    /* (a run that fails part-way charged its last loop chunk whole in the one-shot call) */
    if (magcal_consensus_run(&cfg, g_pts, n, cand, g_work, sizeof g_work, g_mask, &res) == MAGCAL_OK) {
        TEST_ASSERT_TRUE_MESSAGE((uint64_t)steps6000 * 6000u >= total, name);
    }
    TEST_ASSERT_TRUE_MESSAGE((uint64_t)steps6000 * 2200u <= (uint64_t)total + 2200u, name);
    if (n >= 100u && res.draws > 0u) { /* (res: the successful run above) */
        TEST_ASSERT_TRUE_MESSAGE((uint64_t)steps6000 * 6000u <= (uint64_t)total * 5u / 4u + 12000u, name);
    }
}

static void test_consensus_step_any_budget_matches_run_bit_for_bit(void)
{
    static const magcal_test_dump_t *const dumps[] = {&dump_synthetic_outliers_10, &dump_synthetic_outliers_35,
                                                      &dump_synthetic_near_ring, &dump_synthetic_spikes,
                                                      &dump_synthetic_clean};
    magcal_optics_cfg_t oc = MAGCAL_OPTICS_CFG_DEFAULT;
    size_t d;
    for (d = 0u; d < sizeof dumps / sizeof dumps[0]; ++d) {
        size_t n = load(dumps[d]);
        sliced_all_budgets(dumps[d]->name, n, NULL);
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_optics_filter(&oc, g_pts, n, g_owork, sizeof g_owork, g_cand, NULL));
        sliced_all_budgets(dumps[d]->name, n, g_cand);
    }
}

/* Small, quantised and full-capacity sets, and the failures the steps detect (NaN sample, too few
 * candidates, collinear samples): the same status, outputs untouched. */
static void test_consensus_step_edge_sets_match_run(void)
{
    test_distortion_t d = {5.0f, {{1.1f, 0.05f}, {0.05f, 0.9f}}, 3.3f, -1.7f};
    test_distortion_t big = {40.0f, {{1.1f, 0.05f}, {0.05f, 0.9f}}, 12.0f, -7.0f};
    uint32_t rng = 4242u;
    size_t i;
    for (i = 0; i < 300u; ++i) {
        magcal_vec2_t p = test_distorted_sample(&d, 360.0 * test_rand_uniform(&rng), 0.1, &rng);
        g_pts[i].x = floorf(p.x + 0.5f);
        g_pts[i].y = floorf(p.y + 0.5f);
    }
    sliced_all_budgets("5-LSB quantised ring", 300u, NULL);
    for (i = 0; i < NMAX; ++i) {
        g_pts[i] = test_distorted_sample(&big, 360.0 * test_rand_uniform(&rng), 0.4, &rng);
        if (i % 7u == 3u) { /* 14 % spikes */
            g_pts[i].x += 25.0f;
        }
    }
    sliced_all_budgets("full capacity, spikes", NMAX, NULL);
    sliced_all_budgets("twenty samples", 20u, NULL);
    sliced_all_budgets("five samples", 5u, NULL);
    memset(g_cand, 0, NMAX);
    g_cand[0] = g_cand[100] = g_cand[200] = g_cand[300] = 1u;
    sliced_all_budgets("four candidates (TOO_FEW_POINTS)", 400u, g_cand);
    g_pts[517].x = INFINITY;
    sliced_all_budgets("an Inf sample (NONFINITE)", 600u, NULL);
    for (i = 0; i < 100; ++i) {
        g_pts[i].x = 1.0f + 0.5f * (float)i;
        g_pts[i].y = -3.0f + 0.25f * (float)i;
    }
    sliced_all_budgets("collinear (no ellipse)", 100u, NULL);
}

static void test_consensus_begin_checks_arguments_step_refuses_unstarted(void)
{
    magcal_consensus_cfg_t cfg = MAGCAL_CONSENSUS_CFG_DEFAULT;
    magcal_consensus_result_t res;
    magcal_consensus_slice_t sl;
    size_t n = load(&dump_synthetic_clean);
    memset(&sl, 0, sizeof sl);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_consensus_step(NULL, 6000u));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_consensus_step(&sl, 6000u));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_consensus_begin(NULL, &cfg, g_pts, n, NULL, g_work, sizeof g_work, g_mask, &res));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_consensus_begin(&sl, &cfg, g_pts, n, NULL, g_work, sizeof g_work, NULL, &res));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_WORKSPACE, magcal_consensus_begin(&sl, &cfg, g_pts, n, NULL, g_work,
                                                                       MAGCAL_CONSENSUS_WORKSPACE_LEN(n) - 1u, g_mask, &res));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_TOO_FEW_POINTS, magcal_consensus_begin(&sl, &cfg, g_pts, 4u, NULL, g_work, sizeof g_work, g_mask, &res));
    cfg.refine_iter = 0u;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_consensus_begin(&sl, &cfg, g_pts, n, NULL, g_work, sizeof g_work, g_mask, &res));
}

/* magcal_consensus_limit_rejects: on 10 % singular points (dump_synthetic_outliers_10) a limit of
 * 1 % ends the run early with TOO_MANY_OUTLIERS; a limit above the run's own rejects gives the
 * unlimited run's mask and result bit for bit (the limit only ever ends a run, never changes
 * one); it must be set after begin and before the end, within 1..65535. */
static void test_consensus_limit_rejects_ends_dirty_run_keeps_clean_result(void)
{
    static uint8_t ref_mask[NMAX];
    magcal_consensus_cfg_t cfg = MAGCAL_CONSENSUS_CFG_DEFAULT;
    magcal_consensus_slice_t sl;
    magcal_consensus_result_t ref;
    magcal_consensus_result_t got;
    size_t n = load(&dump_synthetic_outliers_10);
    size_t out;
    magcal_status_t st;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_consensus_run(&cfg, g_pts, n, NULL, g_work, sizeof g_work,
                                                          ref_mask, &ref));
    out = n - (size_t)ref.n_inliers;
    TEST_ASSERT_TRUE(out > n / 20u); /* the scenario's singular points */
    /* a limit of n / 100: ended early */
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_consensus_begin(&sl, &cfg, g_pts, n, NULL, g_work,
                                                            sizeof g_work, g_mask, &got));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_consensus_limit_rejects(&sl, n / 100u));
    do {
        st = magcal_consensus_step(&sl, 6000u);
    } while (st == MAGCAL_IN_PROGRESS);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_TOO_MANY_OUTLIERS, st);
    /* a limit the run never passes: the unlimited result */
    memset(&got, 0, sizeof got);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_consensus_begin(&sl, &cfg, g_pts, n, NULL, g_work,
                                                            sizeof g_work, g_mask, &got));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_consensus_limit_rejects(&sl, n));
    do {
        st = magcal_consensus_step(&sl, 6000u);
    } while (st == MAGCAL_IN_PROGRESS);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, st);
    assert_same_result(&ref, &got);
    TEST_ASSERT_EQUAL_MEMORY(ref_mask, g_mask, n);
    /* arguments: NULL, 0, > 65535, after the end */
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_consensus_limit_rejects(NULL, 5u));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_consensus_limit_rejects(&sl, 5u)); /* ended */
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_consensus_begin(&sl, &cfg, g_pts, n, NULL, g_work,
                                                            sizeof g_work, g_mask, &got));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_consensus_limit_rejects(&sl, 0u));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_consensus_limit_rejects(&sl, 65536u));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_consensus_run_bursts_alone_recall_90_centre_truth);
    RUN_TEST(test_consensus_run_after_optics_recall_90_centre_truth);
    RUN_TEST(test_consensus_run_same_seed_is_deterministic);
    RUN_TEST(test_consensus_run_noncandidates_on_ring_are_rescued);
    RUN_TEST(test_consensus_run_bad_input_returns_status_outputs_untouched);
    RUN_TEST(test_consensus_run_twenty_clean_samples_keeps_them);
    RUN_TEST(test_consensus_run_quantised_ring_keeps_lattice);
    RUN_TEST(test_consensus_step_any_budget_matches_run_bit_for_bit);
    RUN_TEST(test_consensus_step_edge_sets_match_run);
    RUN_TEST(test_consensus_begin_checks_arguments_step_refuses_unstarted);
    RUN_TEST(test_consensus_limit_rejects_ends_dirty_run_keeps_clean_result);
    return UNITY_END();
}
