/* Tests of the 3-D OPTICS filter (magcal_optics_run3 / auto_params3 / filter3, optics.h). */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "golden_optics3.h"
#include "magcal/ellipsoid.h"
#include "magcal/optics.h"
#include "test_dumps.h"
#include "test_util.h"
#include "test_util3d.h"
#include "unity.h"

/* magcal_ellipsoid_fit's fixed scratch (the workspace-free fit: no per-sample storage) */
static magcal_ellipsoid_fit_scratch_t g_fit_scratch;

void setUp(void) {}
void tearDown(void) {}

#define NMAX 1024u

static magcal_vec3_t g_pts[NMAX + 1u];
static magcal_vec3_t g_in[NMAX];
static uint32_t g_work[(MAGCAL_OPTICS3_FILTER_WORKSPACE_LEN(NMAX + 1u) + 3u) / 4u];
static uint16_t g_order[4][NMAX];
static float g_reach[4][NMAX];
static float g_core[4][NMAX];
static uint16_t g_pred[4][NMAX];
static int16_t g_labels[NMAX];
static uint8_t g_mask[NMAX];
static uint8_t g_mask2[NMAX];
static uint8_t g_is_out[NMAX];

/*
 * Reference ordering written straight from algorithms.md 4.1/4.2: O(n^2) per step, next point =
 * argmin over ALL unprocessed points of (reach, index) (the lowest unprocessed index when every
 * reach is infinite), core by sorting all neighbour distances. Same float32 distance formula as
 * the library, so the outputs must be bit-identical.
 */
static uint16_t r_order[NMAX];
static float r_reach[NMAX];
static float r_core[NMAX];
static uint16_t r_pred[NMAX];
static uint8_t r_done[NMAX];
static float r_d2[NMAX];

static float d2_of(const magcal_vec3_t *a, const magcal_vec3_t *b)
{
    float dx = a->x - b->x, dy = a->y - b->y, dz = a->z - b->z;
    return dx * dx + dy * dy + dz * dz;
}

static void reference_optics3(const magcal_vec3_t *p, size_t n, float eps, size_t min_pts)
{
    const float eps2 = eps * eps;
    size_t i, j, step;
    for (i = 0; i < n; ++i) {
        r_reach[i] = INFINITY;
        r_pred[i] = MAGCAL_OPTICS_NO_PRED;
        r_done[i] = 0u;
    }
    for (step = 0; step < n; ++step) {
        size_t q = n, cnt = 0u;
        float core2 = INFINITY;
        for (i = 0; i < n; ++i) {
            if (!r_done[i] && (q == n || r_reach[i] < r_reach[q])) {
                q = i; /* strict '<' keeps the lowest index among ties */
            }
        }
        r_done[q] = 1u;
        r_order[step] = (uint16_t)q;
        for (j = 0; j < n; ++j) { /* insertion sort of every d^2 <= eps^2 */
            float d2 = d2_of(&p[j], &p[q]);
            if (d2 <= eps2) {
                size_t t = cnt++;
                while (t > 0u && r_d2[t - 1u] > d2) {
                    r_d2[t] = r_d2[t - 1u];
                    --t;
                }
                r_d2[t] = d2;
            }
        }
        if (cnt >= min_pts) {
            core2 = r_d2[min_pts - 1u];
        }
        r_core[q] = sqrtf(core2);
        if (cnt < min_pts) {
            continue;
        }
        for (j = 0; j < n; ++j) {
            float d2 = d2_of(&p[j], &p[q]);
            if (!r_done[j] && d2 <= eps2) {
                float r = d2 > core2 ? sqrtf(d2) : r_core[q];
                if (r < r_reach[j]) {
                    r_reach[j] = r;
                    r_pred[j] = (uint16_t)q;
                }
            }
        }
    }
}

/* variant 0: CLASSIC + BRUTE, 1: IMPROVED + BRUTE, 2: IMPROVED + GRID, 3: CLASSIC + GRID */
static magcal_neighbors_t run_variant(size_t v, const magcal_vec3_t *p, size_t n, float eps,
                                      uint16_t min_pts)
{
    magcal_optics_cfg_t cfg = MAGCAL_OPTICS_CFG_DEFAULT;
    magcal_optics_result_t info;
    cfg.eps = eps;
    cfg.min_pts = min_pts;
    cfg.order = (v == 1u || v == 2u) ? MAGCAL_OPTICS_IMPROVED : MAGCAL_OPTICS_CLASSIC;
    cfg.neighbors = v >= 2u ? MAGCAL_NEIGHBORS_GRID : MAGCAL_NEIGHBORS_BRUTE;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK,
                          magcal_optics_run3(&cfg, p, n, g_work, sizeof g_work, g_order[v],
                                             g_reach[v], g_core[v], g_pred[v], &info));
    if (v < 2u) {
        TEST_ASSERT_EQUAL_INT(MAGCAL_NEIGHBORS_BRUTE, info.neighbors);
    } else if (!isfinite(eps)) {
        TEST_ASSERT_EQUAL_INT(MAGCAL_NEIGHBORS_BRUTE, info.neighbors); /* GRID falls back */
    } else {
        /* GRID, unless all points are equal (checked by the caller) */
    }
    TEST_ASSERT_EQUAL_UINT16(min_pts, info.min_pts);
    return info.neighbors;
}

/* ---- synthetic truth: m = W h + V + noise, |h| = F, h uniform on the sphere --------------- */

#define F_TRUE 50.0
static const double V_TRUE[3] = {12.0, -25.0, 8.0};

static void unit_dir(uint32_t *rng, double u[3])
{
    double s;
    do {
        u[0] = test_rand_normal(rng);
        u[1] = test_rand_normal(rng);
        u[2] = test_rand_normal(rng);
        s = sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
    } while (s < 1e-9);
    u[0] /= s;
    u[1] /= s;
    u[2] /= s;
}

/* V + scale * W (F u) + N(0, sigma^2) per axis */
static magcal_vec3_t shell_point(double w[3][3], const double u[3], double scale, double sigma,
                                 uint32_t *rng)
{
    double m[3];
    int i;
    magcal_vec3_t r;
    for (i = 0; i < 3; ++i) {
        m[i] = V_TRUE[i] + scale * F_TRUE * (w[i][0] * u[0] + w[i][1] * u[1] + w[i][2] * u[2]) +
               sigma * test_rand_normal(rng);
    }
    r.x = (float)m[0];
    r.y = (float)m[1];
    r.z = (float)m[2];
    return r;
}

/* n clean shell samples into g_pts[0..n) (g_is_out cleared) */
static void make_shell(size_t n, double sigma, uint32_t seed)
{
    double w[3][3], u[3];
    uint32_t rng = seed;
    size_t k;
    test_make_w_full(w);
    for (k = 0; k < n; ++k) {
        unit_dir(&rng, u);
        g_pts[k] = shell_point(w, u, 1.0, sigma, &rng);
        g_is_out[k] = 0u;
    }
}

/* ---- tests ---------------------------------------------------------------------------------- */

/* Golden vectors from scikit-learn 1.2.1 (tools/golden/make_optics3_golden.py). Tolerance 1e-4
 * relative on core and on the reachability plot (float32 distances against float64,
 * algorithms.md 4.5); labels at eps' exact. */
static void test_optics_run3_matches_sklearn_golden_vectors(void)
{
    size_t s, i, v;
    for (s = 0; s < GOLDEN_OPTICS3_N_SETS; ++s) {
        const golden_optics3_set_t *g = &golden_optics3_sets[s];
        uint16_t n_clusters = 0u;
        size_t order_same = 0u;
        double max_rel = 0.0;
        for (v = 0; v < 4u; ++v) {
            run_variant(v, g->pts, g->n, g->eps, g->min_pts);
            for (i = 0; i < g->n; ++i) {
                float e = g->core[i];
                if (isinf(e)) {
                    TEST_ASSERT_TRUE(isinf(g_core[v][i]));
                } else {
                    TEST_ASSERT_FLOAT_WITHIN(1e-4f * e + 1e-30f, e, g_core[v][i]);
                    if (e > 0.0f) {
                        double rel = fabs((double)g_core[v][i] - (double)e) / (double)e;
                        max_rel = rel > max_rel ? rel : max_rel;
                    }
                }
            }
            for (i = 0; i < g->n; ++i) { /* reachability plot, position by position */
                float e = g->reach[g->order[i]];
                float a = g_reach[v][g_order[v][i]];
                order_same += g->order[i] == g_order[v][i];
                if (isinf(e)) {
                    TEST_ASSERT_TRUE(isinf(a));
                } else {
                    TEST_ASSERT_FLOAT_WITHIN(1e-4f * e, e, a);
                    if (e > 0.0f) {
                        double rel = fabs((double)a - (double)e) / (double)e;
                        max_rel = rel > max_rel ? rel : max_rel;
                    }
                }
            }
            TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_optics_extract_dbscan(
                                                 g_order[v], g_reach[v], g_core[v], g->n, g->eps,
                                                 g->eps_prime, g_labels, &n_clusters));
            TEST_ASSERT_EQUAL_INT(g->n_clusters, n_clusters);
            TEST_ASSERT_EQUAL_INT16_ARRAY(g->labels, g_labels, g->n);
        }
        printf("golden3 %s: %u/%u ordering positions equal to sklearn's over 4 variants, "
               "max relative core/reach difference %.2e\n",
               g->name, (unsigned)order_same, (unsigned)(4u * g->n), max_rel);
    }
}

/* Random sets (uniform cube, exact duplicates, flat slabs, far outliers), finite and infinite
 * eps, MinPts 2..8: CLASSIC/IMPROVED x BRUTE/GRID are bit-identical to the reference. The eps
 * values give dense grids (0.3, 0.7) and hashed ones (0.15: 343 cells > G = n for n < 343). */
static void test_optics_run3_variants_bit_identical_to_reference(void)
{
    static const float eps_list[4] = {0.15f, 0.3f, 0.7f, INFINITY};
    uint32_t rng = 12345u;
    size_t trial;
    for (trial = 0; trial < 40u; ++trial) {
        const size_t n = 20u + (size_t)(test_rand_uniform(&rng) * 280.0);
        const float eps = eps_list[trial % 4u];
        const uint16_t min_pts = (uint16_t)(2u + trial % 7u);
        size_t i, v;
        for (i = 0; i < n; ++i) {
            if (trial % 3u == 1u && i % 5u == 4u) {
                g_pts[i] = g_pts[i - 1u]; /* exact duplicates: ties everywhere */
            } else {
                g_pts[i].x = (float)test_rand_uniform(&rng);
                g_pts[i].y = (float)test_rand_uniform(&rng);
                g_pts[i].z = (float)(trial % 3u == 2u ? 0.25 * test_rand_uniform(&rng)
                                                      : test_rand_uniform(&rng));
            }
        }
        if (trial % 8u == 1u || trial % 8u == 4u) {
            /* far outliers: more than 2^15 cells per axis, the grid clamps into border cells */
            g_pts[0].x = -1.0e6f;
            g_pts[1].y = 3.0e5f;
            g_pts[2].z = -7.0e5f;
        }
        reference_optics3(g_pts, n, eps, min_pts);
        for (v = 0; v < 4u; ++v) {
            magcal_neighbors_t used = run_variant(v, g_pts, n, eps, min_pts);
            TEST_ASSERT_EQUAL_INT(
                v >= 2u && isfinite(eps) ? MAGCAL_NEIGHBORS_GRID : MAGCAL_NEIGHBORS_BRUTE, used);
            TEST_ASSERT_EQUAL_MEMORY(r_order, g_order[v], n * sizeof r_order[0]);
            TEST_ASSERT_EQUAL_MEMORY(r_reach, g_reach[v], n * sizeof r_reach[0]);
            TEST_ASSERT_EQUAL_MEMORY(r_core, g_core[v], n * sizeof r_core[0]);
            TEST_ASSERT_EQUAL_MEMORY(r_pred, g_pred[v], n * sizeof r_pred[0]);
        }
    }
}

/* Pairs 0.999 eps apart that straddle a cell border, along each axis (cell side eps (1 + 2^-6)
 * from the box corner at the origin): GRID must still find them (a cell side below eps would put
 * b two cells from a and lose the pair). */
static void test_optics_run3_grid_finds_pairs_across_cell_borders(void)
{
    size_t a, v;
    (void)memset(g_pts, 0, 12u * sizeof g_pts[0]);
    for (a = 0; a < 3u; ++a) {
        float *c0 = a == 0u ? &g_pts[1 + 3u * a].x
                            : (a == 1u ? &g_pts[1 + 3u * a].y : &g_pts[1 + 3u * a].z);
        float *c1 = a == 0u ? &g_pts[2 + 3u * a].x
                            : (a == 1u ? &g_pts[2 + 3u * a].y : &g_pts[2 + 3u * a].z);
        *c0 = 0.98f;
        *c1 = 0.98f + 0.999f;
        g_pts[3 + 3u * a].x = 5.0f + (float)a; /* far companions keep the box large */
    }
    g_pts[10].x = 6.0f;
    g_pts[10].y = 6.0f;
    g_pts[11].z = 6.0f;
    reference_optics3(g_pts, 12u, 1.0f, 2u);
    for (v = 0; v < 4u; ++v) {
        run_variant(v, g_pts, 12u, 1.0f, 2u);
        TEST_ASSERT_EQUAL_MEMORY(r_order, g_order[v], 12u * sizeof r_order[0]);
        TEST_ASSERT_EQUAL_MEMORY(r_reach, g_reach[v], 12u * sizeof r_reach[0]);
        TEST_ASSERT_EQUAL_MEMORY(r_core, g_core[v], 12u * sizeof r_core[0]);
    }
    for (a = 0; a < 3u; ++a) { /* b's nearest neighbour is a, 0.999 away */
        TEST_ASSERT_FLOAT_WITHIN(1e-5f, 0.999f, g_core[2][2 + 3u * a]);
    }
}

static void test_optics_run3_all_duplicates_gives_zero_core_and_reach(void)
{
    size_t i, v;
    for (i = 0; i < 20u; ++i) {
        g_pts[i].x = 3.0f;
        g_pts[i].y = -1.0f;
        g_pts[i].z = 7.0f;
    }
    for (v = 0; v < 4u; ++v) {
        TEST_ASSERT_EQUAL_INT(MAGCAL_NEIGHBORS_BRUTE, run_variant(v, g_pts, 20u, 0.5f, 4u));
        TEST_ASSERT_TRUE(isinf(g_reach[v][0]));
        for (i = 0; i < 20u; ++i) {
            TEST_ASSERT_EQUAL_UINT16(i, g_order[v][i]); /* ties broken by index */
            TEST_ASSERT_EQUAL_FLOAT(0.0f, g_core[v][i]);
            if (i > 0u) {
                TEST_ASSERT_EQUAL_FLOAT(0.0f, g_reach[v][i]);
            }
        }
    }
}

/* The one-call filter equals run3 + extract_dbscan + largest_cluster (given parameters and auto). */
static void test_optics_filter3_equals_run_extract_largest(void)
{
    const golden_optics3_set_t *g = &golden_optics3_sets[0];
    magcal_optics_cfg_t cfg = MAGCAL_OPTICS_CFG_DEFAULT;
    magcal_optics_result_t info;
    uint16_t n_clusters, count;
    int16_t id;
    size_t mode;
    for (mode = 0; mode < 2u; ++mode) {
        float eps = g->eps, eps_prime = g->eps_prime;
        uint16_t min_pts = g->min_pts;
        cfg.order = mode == 0u ? MAGCAL_OPTICS_CLASSIC : MAGCAL_OPTICS_IMPROVED;
        if (mode == 0u) {
            cfg.eps = eps;
            cfg.eps_prime = eps_prime;
            cfg.min_pts = min_pts;
        } else {
            cfg.eps = 0.0f; /* auto */
            TEST_ASSERT_EQUAL_INT(MAGCAL_OK,
                                  magcal_optics_auto_params3(g->pts, g->n, g_work, sizeof g_work,
                                                             &eps, &min_pts, &eps_prime));
        }
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_optics_filter3(&cfg, g->pts, g->n, g_work,
                                                               sizeof g_work, g_mask, &info));
        TEST_ASSERT_EQUAL_FLOAT(eps, info.eps);
        TEST_ASSERT_EQUAL_FLOAT(eps_prime, info.eps_prime);
        TEST_ASSERT_EQUAL_UINT16(min_pts, info.min_pts);
        run_variant(1u, g->pts, g->n, eps, min_pts);
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK,
                              magcal_optics_extract_dbscan(g_order[1], g_reach[1], g_core[1], g->n,
                                                           eps, eps_prime, g_labels, &n_clusters));
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK,
                              magcal_optics_largest_cluster(g_labels, g->n, g_work, sizeof g_work,
                                                            g_mask2, &id, &count));
        TEST_ASSERT_EQUAL_MEMORY(g_mask2, g_mask, g->n);
        TEST_ASSERT_EQUAL_UINT16(n_clusters, info.n_clusters);
        TEST_ASSERT_EQUAL_INT16(id, info.largest_id);
        TEST_ASSERT_EQUAL_UINT16(count, info.n_inliers);
    }
}

/* eps' from the rule in optics.h is scale invariant: x1024 (exact in float) scales it exactly;
 * a shift by 1000 R changes it by float rounding only (1e-3 relative: coordinates lose ~10 bits). */
static void test_optics_auto_params3_scale_and_shift_invariant(void)
{
    float e0, e1, e2, p0, p1, p2;
    uint16_t m0, m1, m2;
    size_t i;
    make_shell(300u, 0.25, 77u);
    TEST_ASSERT_EQUAL_INT(
        MAGCAL_OK, magcal_optics_auto_params3(g_pts, 300u, g_work, sizeof g_work, &e0, &m0, &p0));
    for (i = 0; i < 300u; ++i) {
        g_in[i].x = 1024.0f * g_pts[i].x;
        g_in[i].y = 1024.0f * g_pts[i].y;
        g_in[i].z = 1024.0f * g_pts[i].z;
    }
    TEST_ASSERT_EQUAL_INT(
        MAGCAL_OK, magcal_optics_auto_params3(g_in, 300u, g_work, sizeof g_work, &e1, &m1, &p1));
    for (i = 0; i < 300u; ++i) {
        g_in[i].x = g_pts[i].x + 5.0e4f;
        g_in[i].y = g_pts[i].y - 5.0e4f;
        g_in[i].z = g_pts[i].z + 2.5e4f;
    }
    TEST_ASSERT_EQUAL_INT(
        MAGCAL_OK, magcal_optics_auto_params3(g_in, 300u, g_work, sizeof g_work, &e2, &m2, &p2));
    printf("auto3 n=300: eps = %.4f F, eps' = %.4f F, x1024 ratio %.9g, shifted ratio %.6f\n",
           (double)e0 / F_TRUE, (double)p0 / F_TRUE, (double)(p1 / p0), (double)(p2 / p0));
    TEST_ASSERT_EQUAL_UINT16(4u, m0);
    TEST_ASSERT_TRUE(p0 <= e0); /* eps = R (the ordering radius), eps' <= eps */
    TEST_ASSERT_EQUAL_FLOAT(1024.0f * e0, e1);
    TEST_ASSERT_EQUAL_FLOAT(1024.0f * p0, p1);
    TEST_ASSERT_FLOAT_WITHIN(1e-3f * e0, e0, e2);
    TEST_ASSERT_FLOAT_WITHIN(1e-3f * p0, p0, p2);
    /* measured on this set: eps' = 0.505 F (uniform directions, n = 300; docs/optics.md) */
    TEST_ASSERT_TRUE(p0 > 0.3f * (float)F_TRUE && p0 < 0.8f * (float)F_TRUE);
}

/* Clean, uniformly covered shells keep every sample (the factor-3 rule, docs/optics.md "3-D"). */
static void test_optics_filter3_clean_shell_keeps_every_sample(void)
{
    static const size_t ns[4] = {100u, 300u, 600u, 1000u};
    magcal_optics_cfg_t cfg = MAGCAL_OPTICS_CFG_DEFAULT;
    magcal_optics_result_t info;
    size_t t;
    for (t = 0; t < 4u; ++t) {
        make_shell(ns[t], 0.5, (uint32_t)(1000u + t));
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_optics_filter3(&cfg, g_pts, ns[t], g_work,
                                                               sizeof g_work, g_mask, &info));
        TEST_ASSERT_EQUAL_UINT16(ns[t], info.n_inliers);
        TEST_ASSERT_EQUAL_UINT16(1u, info.n_clusters);
    }
}

/* ---- end to end: density filter, then the ellipsoid fit, against known W and V ------------- */

#define E2E_N_SHELL 600u
#define E2E_N_SPIKES 30u /* 5 % of the shell samples */
#define E2E_N_BURST 20u
#define E2E_N (E2E_N_SHELL + E2E_N_SPIKES + E2E_N_BURST)

/*
 * g_pts[0..E2E_N): 600 shell samples (sigma 0.25 = 0.5 % F), 30 scattered singular points
 * (radius about V scaled by 1.7..2.5, or 0..0.3, in random directions) and a burst of 20 samples
 * stuck at one wrong value V + burst_scale * W F u0, inserted at position 200. g_is_out marks
 * the injected outliers.
 */
static void make_e2e(double burst_scale, uint32_t seed)
{
    double w[3][3], u[3], u0[3];
    uint32_t rng = seed;
    size_t k, o = 0u;
    magcal_vec3_t stuck;
    test_make_w_full(w);
    unit_dir(&rng, u0);
    stuck = shell_point(w, u0, burst_scale, 0.0, &rng);
    for (k = 0; k < E2E_N; ++k) {
        if (k >= 200u && k < 200u + E2E_N_BURST) {
            g_pts[k] = stuck;
            g_is_out[k] = 1u;
        } else if (k % 20u == 10u && o < E2E_N_SPIKES) {
            double sc = test_rand_uniform(&rng) < 0.7 ? 1.7 + 0.8 * test_rand_uniform(&rng)
                                                      : 0.3 * test_rand_uniform(&rng);
            unit_dir(&rng, u);
            g_pts[k] = shell_point(w, u, sc, 0.25, &rng);
            g_is_out[k] = 1u;
            ++o;
        } else {
            unit_dir(&rng, u);
            g_pts[k] = shell_point(w, u, 1.0, 0.25, &rng);
            g_is_out[k] = 0u;
        }
    }
    TEST_ASSERT_EQUAL_UINT(E2E_N_SPIKES, o);
}

static double v_err(const magcal_ellipsoid_cal_t *cal)
{
    double dx = cal->v.x - V_TRUE[0], dy = cal->v.y - V_TRUE[1], dz = cal->v.z - V_TRUE[2];
    return sqrt(dx * dx + dy * dy + dz * dz);
}

/* Shape error against the test's truth W (test_make_w_full). */
static double q_err(const magcal_ellipsoid_cal_t *cal)
{
    double w[3][3];
    test_make_w_full(w);
    return test_q_err(cal, w);
}

typedef struct {
    magcal_status_t st_filter;
    magcal_status_t st_fit;
    size_t kept_out;  /* injected outliers kept by the density filter */
    size_t false_rej; /* shell samples rejected by the density filter */
    double v_err, q_err;
    size_t n_used, n_rejected; /* of the fit */
    size_t gate_burst_kept;    /* fit gate only: burst samples the final gate accepts */
    size_t gate_spikes_kept;   /* fit gate only: spikes the final gate accepts */
    magcal_optics_result_t info;
} e2e_t;

static magcal_ellipsoid_cfg_t fit_cfg(void)
{
    magcal_ellipsoid_cfg_t cfg = MAGCAL_ELLIPSOID_CFG_DEFAULT;
    cfg.field = (float)F_TRUE;
    return cfg;
}

/* filter3 (automatic parameters), then magcal_ellipsoid_fit on the kept samples */
static e2e_t run_filter_then_fit(void)
{
    magcal_optics_cfg_t cfg = MAGCAL_OPTICS_CFG_DEFAULT;
    magcal_ellipsoid_cfg_t fcfg = fit_cfg();
    magcal_ellipsoid_result_t fit;
    e2e_t r;
    size_t k, m = 0u;
    (void)memset(&r, 0, sizeof r);
    r.st_filter = magcal_optics_filter3(&cfg, g_pts, E2E_N, g_work, sizeof g_work, g_mask, &r.info);
    if (r.st_filter != MAGCAL_OK) {
        return r;
    }
    for (k = 0; k < E2E_N; ++k) {
        r.kept_out += (g_mask[k] != 0u && g_is_out[k] != 0u) ? 1u : 0u;
        r.false_rej += (g_mask[k] == 0u && g_is_out[k] == 0u) ? 1u : 0u;
        if (g_mask[k] != 0u) {
            g_in[m++] = g_pts[k];
        }
    }
    r.st_fit = magcal_ellipsoid_fit(g_in, m, &fcfg, &g_fit_scratch, &fit);
    if (r.st_fit == MAGCAL_OK) {
        r.v_err = v_err(&fit.cal);
        r.q_err = q_err(&fit.cal);
        r.n_used = fit.n_used;
        r.n_rejected = fit.n_rejected;
    }
    return r;
}

/* the ellipsoid fit's own residual gate (3 x RMS, up to 3 refits) on every sample */
static e2e_t run_fit_only(void)
{
    magcal_ellipsoid_cfg_t fcfg = fit_cfg();
    magcal_ellipsoid_result_t fit;
    e2e_t r;
    (void)memset(&r, 0, sizeof r);
    r.st_fit = magcal_ellipsoid_fit(g_pts, E2E_N, &fcfg, &g_fit_scratch, &fit);
    if (r.st_fit == MAGCAL_OK) {
        size_t k, n_out = 0u;
        r.v_err = v_err(&fit.cal);
        r.q_err = q_err(&fit.cal);
        r.n_used = fit.n_used;
        r.n_rejected = fit.n_rejected;
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK,
                              magcal_ellipsoid_outliers(&fit, g_pts, E2E_N, g_mask2, &n_out));
        for (k = 0; k < E2E_N; ++k) {
            const int burst = k >= 200u && k < 200u + E2E_N_BURST;
            if (g_is_out[k] != 0u && g_mask2[k] == 0u) {
                r.gate_burst_kept += burst ? 1u : 0u;
                r.gate_spikes_kept += burst ? 0u : 1u;
            }
        }
    }
    return r;
}

static void print_e2e(const char *what, const e2e_t *r)
{
    printf("%-28s filter %d (eps' %.2f, clusters %u, kept %u, outliers kept %u, false rej %u) "
           "fit %d: |dV| %.4f, Q err %.2e, used %u, rejected %u, gate keeps burst %u spikes %u\n",
           what, (int)r->st_filter, (double)r->info.eps_prime, (unsigned)r->info.n_clusters,
           (unsigned)r->info.n_inliers, (unsigned)r->kept_out, (unsigned)r->false_rej,
           (int)r->st_fit, r->v_err, r->q_err, (unsigned)r->n_used, (unsigned)r->n_rejected,
           (unsigned)r->gate_burst_kept, (unsigned)r->gate_spikes_kept);
}

/*
 * Tolerances (stated, from 60 seeds measured with this generator, 5 run here): |V - V_true| <
 * 0.15 (0.3 % of F; measured max 0.069), Q error < 6e-3 (measured max 2.9e-3), shell samples
 * rejected by the density stage <= 3 (measured 0 in 60 runs).
 */
#define E2E_SEEDS 5u
#define E2E_TOL_V 0.15
#define E2E_TOL_Q 6e-3
#define E2E_MAX_FALSE_REJ 3u

/*
 * Burst stuck 0.8 R outside the shell (burst_scale 1.8, e.g. a driver glitch): the density stage
 * rejects all 50 injected outliers (30 spikes as noise or small clusters, the 20 identical burst
 * samples as their own cluster) and the fit recovers V and Q.
 * What the density stage adds, measured over 60 seeds: the fit's k x RMS gate alone
 * (outlier_k 3, 3 refits) accepts all 20 burst samples in 60 of 60 runs (per-sample mask from
 * magcal_ellipsoid_outliers; plus 0-16 spikes): the first fit bends towards the 20 identical
 * samples, whose residuals then stay under 3 x RMS (a compromise fit); |dV| = 5.5 median, 11.7
 * max (11-23 % of F), Q error 0.25 median, against 0.030 / 1.4e-3 with the density stage. With
 * the burst stuck at V instead (scale 0), the gate rejects the burst but keeps up to 11 spikes and
 * fails in 6 of 60 runs (|dV| up to 5.7).
 */
static void test_optics_filter3_then_ellipsoid_fit_far_burst_recovers_truth(void)
{
    uint32_t seed;
    for (seed = 1u; seed <= E2E_SEEDS; ++seed) {
        e2e_t f, g;
        make_e2e(1.8, 1000u * seed + 7u);
        f = run_filter_then_fit();
        g = run_fit_only();
        print_e2e("far burst: density + fit", &f);
        print_e2e("far burst: fit gate only", &g);
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, f.st_filter);
        TEST_ASSERT_EQUAL_UINT(0u, f.kept_out); /* all 30 spikes and 20 burst samples rejected */
        TEST_ASSERT_EQUAL_UINT(E2E_N - E2E_N_SPIKES - E2E_N_BURST, f.info.n_inliers + f.false_rej);
        TEST_ASSERT_TRUE(f.false_rej <= E2E_MAX_FALSE_REJ);
        TEST_ASSERT_TRUE(f.info.n_clusters >= 2u); /* the burst is a cluster of its own */
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, f.st_fit);
        TEST_ASSERT_TRUE(f.v_err < E2E_TOL_V);
        TEST_ASSERT_TRUE(f.q_err < E2E_TOL_Q);
        /* never worse than the gate alone */
        TEST_ASSERT_TRUE(g.st_fit != MAGCAL_OK || f.v_err <= g.v_err + 0.01);
    }
}

/*
 * Limit: a burst stuck 0.3 R outside the shell (burst_scale 1.3) lies within eps' (about 0.36 R
 * at n = 600) of shell samples, so the density stage usually merges it with the shell (20 kept in
 * 59 of 60 measured seeds, rejected whole in 1) while it still rejects the 30 spikes; the fit's
 * residual gate then drops the burst, since the spikes no longer inflate the RMS. Measured over
 * 60 seeds: the pipeline gives |dV| <= 0.069; the gate alone fails in 24 of 60 runs (|dV| up to
 * 1.9, the spikes' residuals mask the burst).
 */
static void test_optics_filter3_then_ellipsoid_fit_near_burst_gate_finishes(void)
{
    uint32_t seed;
    for (seed = 1u; seed <= E2E_SEEDS; ++seed) {
        e2e_t f;
        size_t k, spikes_kept = 0u;
        make_e2e(1.3, 1000u * seed + 7u);
        f = run_filter_then_fit();
        print_e2e("near burst: density + fit", &f);
        for (k = 0; k < E2E_N; ++k) {
            spikes_kept +=
                (g_is_out[k] != 0u && (k < 200u || k >= 200u + E2E_N_BURST) && g_mask[k] != 0u)
                    ? 1u
                    : 0u;
        }
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, f.st_filter);
        TEST_ASSERT_EQUAL_UINT(0u, spikes_kept);
        /* the burst is either rejected here or merged whole (the documented limit) */
        TEST_ASSERT_TRUE(f.kept_out == 0u || f.kept_out == E2E_N_BURST);
        TEST_ASSERT_TRUE(f.false_rej <= E2E_MAX_FALSE_REJ);
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, f.st_fit);
        TEST_ASSERT_TRUE(f.kept_out == 0u || f.n_rejected >= E2E_N_BURST); /* then the gate */
        TEST_ASSERT_TRUE(f.v_err < E2E_TOL_V);
        TEST_ASSERT_TRUE(f.q_err < E2E_TOL_Q);
    }
}

/* ---- real recordings -------------------------------------------------------------------- */

static double v_dist(const magcal_ellipsoid_cal_t *a, const magcal_ellipsoid_cal_t *b)
{
    double dx = (double)a->v.x - (double)b->v.x;
    double dy = (double)a->v.y - (double)b->v.y;
    double dz = (double)a->v.z - (double)b->v.z;
    return sqrt(dx * dx + dy * dy + dz * dz);
}

/*
 * Real tumble recordings (tests/data/real: LSM9DS1 534 samples in gauss, the ellipsoid_fit python
 * sample 347 samples in raw counts). No truth is known, so the reference is the default ellipsoid
 * fit of the recording itself. (a) filter3 keeps every recorded sample (measured: 534/534,
 * 347/347, one cluster). (b) Injected: 20 samples stuck at V + 1.8 (m_17 - V) and n/20 spikes
 * (V + 2 (m - V) or V + 0.2 (m - V) of other samples): measured, filter3 rejects 45 of 46 and
 * 37 of 37 and no recorded sample, and the fit on its inliers lands within 4e-5 F of the
 * reference V; the fit's gate alone is off by 4.6 % F (557 of 580 used) and 8.8 % F (375 of
 * 384 used). Tolerances: at most 2 injected samples kept, none lost, |V - V_ref| < 0.2 % F.
 */
static void test_optics_filter3_real_tumbles_keep_samples_and_reject_injected(void)
{
    static const magcal_test_dump_t *const dumps[2] = {&dump_real_lsm9ds1_pmodnav_tumble,
                                                       &dump_real_ellipsoid_fit_python_sample};
    size_t d, i;
    for (d = 0; d < 2u; ++d) {
        magcal_optics_cfg_t cfg = MAGCAL_OPTICS_CFG_DEFAULT;
        magcal_optics_result_t info;
        const magcal_ellipsoid_cfg_t fc = MAGCAL_ELLIPSOID_CFG_DEFAULT;
        magcal_ellipsoid_result_t ref, fit, gate;
        magcal_status_t gst;
        const magcal_test_dump_t *dp = dumps[d];
        size_t nb = dp->n, m = 0u, kept_out = 0u, lost = 0u;
        magcal_vec3_t v;
        for (i = 0; i < dp->n; ++i) {
            g_pts[i].x = dp->mx[i];
            g_pts[i].y = dp->my[i];
            g_pts[i].z = dp->mz[i];
            g_is_out[i] = 0u;
        }
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipsoid_fit(g_pts, dp->n, &fc, &g_fit_scratch, &ref));
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_optics_filter3(&cfg, g_pts, dp->n, g_work,
                                                               sizeof g_work, g_mask, &info));
        TEST_ASSERT_EQUAL_UINT16(dp->n, info.n_inliers); /* (a) */
        v = ref.cal.v;
        for (i = 0; i < 20u + dp->n / 20u; ++i) { /* (b) */
            const size_t src = i < 20u ? 17u : ((i - 20u) * 37u + 5u) % dp->n;
            const float sc = i < 20u ? 1.8f : (i % 3u == 0u ? 0.2f : 2.0f);
            g_pts[nb].x = v.x + sc * (g_pts[src].x - v.x);
            g_pts[nb].y = v.y + sc * (g_pts[src].y - v.y);
            g_pts[nb].z = v.z + sc * (g_pts[src].z - v.z);
            g_is_out[nb] = 1u;
            ++nb;
        }
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_optics_filter3(&cfg, g_pts, nb, g_work,
                                                               sizeof g_work, g_mask, &info));
        for (i = 0; i < nb; ++i) {
            kept_out += (g_mask[i] != 0u && g_is_out[i] != 0u) ? 1u : 0u;
            lost += (g_mask[i] == 0u && g_is_out[i] == 0u) ? 1u : 0u;
            if (g_mask[i] != 0u) {
                g_in[m++] = g_pts[i];
            }
        }
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipsoid_fit(g_in, m, &fc, &g_fit_scratch, &fit));
        /* the fit's own gate alone cannot undo this contamination (|dV| 4.6 / 8.8 % F before
         * issue 12); its trust gates must then refuse, never return that as OK */
        gst = magcal_ellipsoid_fit(g_pts, nb, &fc, &g_fit_scratch, &gate);
        printf("%s: %u samples all kept; %u injected: %u kept, %u recorded lost; |dV|/F "
               "density+fit %.2e, gate only: %s %.2e (%u used)\n",
               dp->name, (unsigned)dp->n, (unsigned)(nb - dp->n), (unsigned)kept_out,
               (unsigned)lost, v_dist(&fit.cal, &ref.cal) / (double)ref.cal.field, magcal_status_str(gst),
               (gst == MAGCAL_OK) ? v_dist(&gate.cal, &ref.cal) / (double)ref.cal.field : -1.0,
               (gst == MAGCAL_OK) ? (unsigned)gate.n_used : 0u);
        TEST_ASSERT_TRUE(gst != MAGCAL_OK || v_dist(&gate.cal, &ref.cal) < 0.02 * (double)ref.cal.field);
        TEST_ASSERT_TRUE(kept_out <= 2u);
        TEST_ASSERT_EQUAL_UINT(0u, lost);
        TEST_ASSERT_TRUE(v_dist(&fit.cal, &ref.cal) < 2e-3 * (double)ref.cal.field);
    }
}

/* ---- bad input --------------------------------------------------------------------------- */

static void fill_sentinels(void)
{
    (void)memset(g_order[0], 0xA5, sizeof g_order[0]);
    (void)memset(g_reach[0], 0xA5, sizeof g_reach[0]);
    (void)memset(g_core[0], 0xA5, sizeof g_core[0]);
    (void)memset(g_mask, 0xA5, sizeof g_mask);
}

static void assert_sentinels(size_t n)
{
    size_t i;
    for (i = 0; i < n; ++i) {
        TEST_ASSERT_EQUAL_HEX16(0xA5A5u, g_order[0][i]);
        TEST_ASSERT_EQUAL_HEX8(0xA5u, g_mask[i]);
    }
    TEST_ASSERT_EACH_EQUAL_HEX8(0xA5u, (const uint8_t *)g_reach[0], n * sizeof(float));
    TEST_ASSERT_EACH_EQUAL_HEX8(0xA5u, (const uint8_t *)g_core[0], n * sizeof(float));
}

static magcal_status_t run3_with(const magcal_optics_cfg_t *cfg, const magcal_vec3_t *p, size_t n,
                                 void *w, size_t wl)
{
    return magcal_optics_run3(cfg, p, n, w, wl, g_order[0], g_reach[0], g_core[0], NULL, NULL);
}

/*
 * Rest phases (issue 12 item 7, 3-D): n samples in stream order, a fraction `frac` at rest (all
 * at one orientation u1, or 2/3 at u1 first and 1/3 at u2 last; noise only), the rest a rotation
 * over uniformly random directions between them. g_is_out[i] = 1 marks the rest samples (genuine,
 * but not the shell's coverage).
 */
static void make_rest_shell(size_t n, double frac, int two, double sigma, uint32_t seed)
{
    double w[3][3], u[3], u1[3], u2[3];
    uint32_t rng = seed;
    const size_t n_rest = (size_t)(frac * (double)n + 0.5);
    const size_t n_first = two ? (2u * n_rest) / 3u : n_rest;
    const size_t n_rot = n - n_rest;
    size_t k;
    test_make_w_full(w);
    unit_dir(&rng, u1);
    unit_dir(&rng, u2);
    for (k = 0; k < n; ++k) {
        if (k < n_first) {
            g_pts[k] = shell_point(w, u1, 1.0, sigma, &rng);
            g_is_out[k] = 1u;
        } else if (k < n_first + n_rot) {
            unit_dir(&rng, u);
            g_pts[k] = shell_point(w, u, 1.0, sigma, &rng);
            g_is_out[k] = 0u;
        } else {
            g_pts[k] = shell_point(w, u2, 1.0, sigma, &rng);
            g_is_out[k] = 1u;
        }
    }
}

/*
 * A rest phase of up to half the samples must not be kept as the shell while the rotation is
 * rejected: the automatic filter keeps >= 95 % of the rotation samples, and filter + ellipsoid
 * fit (model AUTO) either returns OK with the hard iron within 2 % of F and the shape error
 * (test_q_err) at most 0.03, or a non-OK status. To first order the corrected direction turns by
 * at most Q err / 2 rad, so 0.03 bounds the shape's heading error by 0.86 deg (issue 12: 1 deg).
 * n = 300..1000, rest 30..50 % at one or two orientations, noise 0.5 % and 2 % of F, 3 seeds.
 * Measured (108 runs): before the thinning the filter kept < 95 % of the rotation in 20 runs and
 * 20 OK results were wrong (|dV| up to 1.17 F: the rest phase kept as the shell); after it 108 OK,
 * worst |dV| 0.0072 F, Q err 0.0186, filter keeps >= 95 % of the rotation in all.
 */
static void test_optics_filter3_rest_phase_up_to_half_keeps_rotation(void)
{
    static const size_t ns[] = {300u, 600u, 1000u};
    static const double fracs[] = {0.3, 0.4, 0.5};
    static const double sigmas[] = {0.25, 1.0};
    size_t in, ifr, is, two, seed;
    unsigned runs = 0u, ok = 0u, kept_low = 0u, wrong = 0u;
    double worst_v = 0.0, worst_q = 0.0;
    for (in = 0; in < 3u; ++in) {
        for (ifr = 0; ifr < 3u; ++ifr) {
            for (is = 0; is < 2u; ++is) {
                for (two = 0; two < 2u; ++two) {
                    for (seed = 1u; seed <= 3u; ++seed) {
                        const size_t n = ns[in];
                        magcal_optics_cfg_t cfg = MAGCAL_OPTICS_CFG_DEFAULT;
                        magcal_optics_result_t info;
                        magcal_ellipsoid_cfg_t fcfg = fit_cfg();
                        magcal_ellipsoid_result_t fit;
                        magcal_status_t st;
                        size_t k, m = 0u, rot = 0u, kept = 0u;
                        char msg[128];
                        make_rest_shell(n, fracs[ifr], (int)two, sigmas[is],
                                        (uint32_t)(211u * seed + 13u * in + 5u * ifr + two));
                        st = magcal_optics_filter3(&cfg, g_pts, n, g_work, sizeof g_work, g_mask,
                                                   &info);
                        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, st);
                        for (k = 0; k < n; ++k) {
                            rot += g_is_out[k] == 0u;
                            kept += g_is_out[k] == 0u && g_mask[k] != 0u;
                            if (g_mask[k] != 0u) {
                                g_in[m++] = g_pts[k];
                            }
                        }
                        kept_low += kept * 100u < rot * 95u;
                        st = magcal_ellipsoid_fit(g_in, m, &fcfg, &g_fit_scratch, &fit);
                        ++runs;
                        snprintf(msg, sizeof msg, "n %u rest %.0f %% %s sigma %.2f seed %u",
                                 (unsigned)n, 100.0 * fracs[ifr], two ? "two" : "one", sigmas[is],
                                 (unsigned)seed);
                        if (st == MAGCAL_OK) {
                            const double ve = v_err(&fit.cal) / F_TRUE;
                            const double qe = q_err(&fit.cal);
                            ++ok;
                            worst_v = ve > worst_v ? ve : worst_v;
                            worst_q = qe > worst_q ? qe : worst_q;
                            wrong += ve > 0.02 || qe > 0.03;
                            TEST_ASSERT_TRUE_MESSAGE(ve <= 0.02, msg);
                            TEST_ASSERT_TRUE_MESSAGE(qe <= 0.03, msg);
                        }
                    }
                }
            }
        }
    }
    printf("rest phases: %u runs, %u OK (worst |dV| %.4f F, Q err %.2e), %u refused, %u silent "
           "wrong; filter kept < 95 %% of the rotation in %u\n",
           runs, ok, worst_v, worst_q, runs - ok, wrong, kept_low);
    TEST_ASSERT_EQUAL_UINT(0u, kept_low);
    TEST_ASSERT_EQUAL_UINT(runs, ok); /* measured: every run calibrates */
}

static void test_optics_run3_bad_input_returns_specific_status(void)
{
    magcal_optics_cfg_t cfg = MAGCAL_OPTICS_CFG_DEFAULT;
    magcal_optics_cfg_t bad;
    const size_t n = 50u;
    const size_t wl = MAGCAL_OPTICS3_WORKSPACE_LEN(50u);
    uint8_t *w1 = (uint8_t *)g_work + 1;
    cfg.eps = 20.0f;
    make_shell(n, 0.5, 5u);
    fill_sentinels();
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, run3_with(NULL, g_pts, n, g_work, wl));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, run3_with(&cfg, NULL, n, g_work, wl));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, run3_with(&cfg, g_pts, n, NULL, wl));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_optics_run3(&cfg, g_pts, n, g_work, wl, NULL,
                                                              g_reach[0], g_core[0], NULL, NULL));
    TEST_ASSERT_EQUAL_INT(
        MAGCAL_ERR_NULL,
        magcal_optics_run3(&cfg, g_pts, n, g_work, wl, g_order[0], NULL, g_core[0], NULL, NULL));
    TEST_ASSERT_EQUAL_INT(
        MAGCAL_ERR_NULL,
        magcal_optics_run3(&cfg, g_pts, n, g_work, wl, g_order[0], g_reach[0], NULL, NULL, NULL));
    /* eps: 0, negative, NaN, eps^2 underflowing (< 3.4e-21) or overflowing (> 1.8e19) */
    bad = cfg;
    bad.eps = 0.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, run3_with(&bad, g_pts, n, g_work, wl));
    bad.eps = -1.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, run3_with(&bad, g_pts, n, g_work, wl));
    bad.eps = NAN;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, run3_with(&bad, g_pts, n, g_work, wl));
    bad.eps = 1e-21f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, run3_with(&bad, g_pts, n, g_work, wl));
    bad.eps = 1e20f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, run3_with(&bad, g_pts, n, g_work, wl));
    bad = cfg;
    bad.min_pts = 1u;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, run3_with(&bad, g_pts, n, g_work, wl));
    bad.min_pts = (uint16_t)(MAGCAL_MAX_MIN_PTS + 1u);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, run3_with(&bad, g_pts, n, g_work, wl));
    bad = cfg;
    bad.order = (magcal_optics_order_t)2;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, run3_with(&bad, g_pts, n, g_work, wl));
    bad = cfg;
    bad.neighbors = (magcal_neighbors_t)2;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, run3_with(&bad, g_pts, n, g_work, wl));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ALIGNMENT, run3_with(&cfg, g_pts, n, w1, wl));
    /* counts: n < min_pts, n > MAGCAL_MAX_SAMPLES (uint16 indices) */
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_TOO_FEW_POINTS, run3_with(&cfg, g_pts, 3u, g_work, wl));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_TOO_FEW_POINTS, run3_with(&cfg, g_pts, 0u, g_work, wl));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG,
                          run3_with(&cfg, g_pts, MAGCAL_MAX_SAMPLES + 1u, g_work, sizeof g_work));
    /* NaN / Inf in each coordinate */
    g_pts[7].z = NAN;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, run3_with(&cfg, g_pts, n, g_work, wl));
    g_pts[7].z = 0.0f;
    g_pts[49].x = INFINITY;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, run3_with(&cfg, g_pts, n, g_work, wl));
    g_pts[49].x = 0.0f;
    g_pts[0].y = -INFINITY;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, run3_with(&cfg, g_pts, n, g_work, wl));
    g_pts[0].y = 0.0f;
    /* workspace: the macro's length works, one byte less does not */
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_WORKSPACE, run3_with(&cfg, g_pts, n, g_work, wl - 1u));
    assert_sentinels(n);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, run3_with(&cfg, g_pts, n, g_work, wl));
}

static void test_optics_filter3_and_auto_bad_input_returns_specific_status(void)
{
    magcal_optics_cfg_t cfg = MAGCAL_OPTICS_CFG_DEFAULT;
    magcal_optics_cfg_t bad;
    magcal_optics_result_t info;
    const size_t n = 60u;
    const size_t wl = MAGCAL_OPTICS3_FILTER_WORKSPACE_LEN(60u);
    uint8_t *w1 = (uint8_t *)g_work + 2;
    float e = -7.0f, ep = -7.0f;
    uint16_t mp = 77u;
    size_t i;
    make_shell(n, 0.5, 6u);
    fill_sentinels();
    /* filter3, auto mode (eps = 0) */
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL,
                          magcal_optics_filter3(NULL, g_pts, n, g_work, wl, g_mask, &info));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL,
                          magcal_optics_filter3(&cfg, NULL, n, g_work, wl, g_mask, &info));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL,
                          magcal_optics_filter3(&cfg, g_pts, n, NULL, wl, g_mask, &info));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL,
                          magcal_optics_filter3(&cfg, g_pts, n, g_work, wl, NULL, &info));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ALIGNMENT,
                          magcal_optics_filter3(&cfg, g_pts, n, w1, wl, g_mask, &info));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_TOO_FEW_POINTS,
                          magcal_optics_filter3(&cfg, g_pts, 15u, g_work, wl, g_mask, &info));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG,
                          magcal_optics_filter3(&cfg, g_pts, MAGCAL_MAX_SAMPLES + 1u, g_work,
                                                sizeof g_work, g_mask, &info));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_WORKSPACE,
                          magcal_optics_filter3(&cfg, g_pts, n, g_work, wl - 1u, g_mask, &info));
    bad = cfg;
    bad.eps = NAN;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG,
                          magcal_optics_filter3(&bad, g_pts, n, g_work, wl, g_mask, &info));
    bad = cfg;
    bad.order = (magcal_optics_order_t)-1;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG,
                          magcal_optics_filter3(&bad, g_pts, n, g_work, wl, g_mask, &info));
    /* given parameters: eps' > eps, eps' < 0, eps' NaN/Inf, eps out of range, n < min_pts */
    bad = cfg;
    bad.eps = 10.0f;
    bad.eps_prime = 11.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG,
                          magcal_optics_filter3(&bad, g_pts, n, g_work, wl, g_mask, &info));
    bad.eps_prime = -1.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG,
                          magcal_optics_filter3(&bad, g_pts, n, g_work, wl, g_mask, &info));
    bad.eps_prime = NAN;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG,
                          magcal_optics_filter3(&bad, g_pts, n, g_work, wl, g_mask, &info));
    bad.eps = INFINITY;
    bad.eps_prime = 0.0f; /* eps' = eps = inf is not finite */
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG,
                          magcal_optics_filter3(&bad, g_pts, n, g_work, wl, g_mask, &info));
    bad.eps = 1e20f;
    bad.eps_prime = 1.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG,
                          magcal_optics_filter3(&bad, g_pts, n, g_work, wl, g_mask, &info));
    bad.eps = 10.0f;
    bad.min_pts = 8u;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_TOO_FEW_POINTS,
                          magcal_optics_filter3(&bad, g_pts, 7u, g_work, wl, g_mask, &info));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_WORKSPACE,
                          magcal_optics_filter3(&bad, g_pts, n, g_work, wl - 1u, g_mask, &info));
    /* eps below every pair distance: every point is noise */
    bad.eps = 1e-6f;
    bad.eps_prime = 0.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ALL_NOISE,
                          magcal_optics_filter3(&bad, g_pts, n, g_work, wl, g_mask, &info));
    TEST_ASSERT_EQUAL_UINT16(n, info.n_noise);
    g_pts[33].y = NAN;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE,
                          magcal_optics_filter3(&cfg, g_pts, n, g_work, wl, g_mask, &info));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE,
                          magcal_optics_auto_params3(g_pts, n, g_work, wl, &e, &mp, &ep));
    g_pts[33].y = 1.0f;
    /* auto_params3 */
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL,
                          magcal_optics_auto_params3(NULL, n, g_work, wl, &e, &mp, &ep));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL,
                          magcal_optics_auto_params3(g_pts, n, NULL, wl, &e, &mp, &ep));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL,
                          magcal_optics_auto_params3(g_pts, n, g_work, wl, NULL, &mp, &ep));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL,
                          magcal_optics_auto_params3(g_pts, n, g_work, wl, &e, NULL, &ep));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL,
                          magcal_optics_auto_params3(g_pts, n, g_work, wl, &e, &mp, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ALIGNMENT,
                          magcal_optics_auto_params3(g_pts, n, w1, wl, &e, &mp, &ep));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_TOO_FEW_POINTS,
                          magcal_optics_auto_params3(g_pts, 15u, g_work, wl, &e, &mp, &ep));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG,
                          magcal_optics_auto_params3(g_pts, MAGCAL_MAX_SAMPLES + 1u, g_work,
                                                     sizeof g_work, &e, &mp, &ep));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_WORKSPACE,
                          magcal_optics_auto_params3(g_pts, n, g_work, wl - 1u, &e, &mp, &ep));
    /* more than half the samples identical is a rest phase, counted once: 29 shell samples
     * remain, enough for the rule (OK); with only 10 others fewer than 16 distinct cells remain:
     * median radius 0 whatever is thinned */
    for (i = 0; i < 31u; ++i) {
        g_in[i] = g_pts[0];
    }
    for (; i < n; ++i) {
        g_in[i] = g_pts[i];
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_optics_auto_params3(g_in, n, g_work, wl, &e, &mp, &ep));
    e = -7.0f;
    ep = -7.0f;
    mp = 77u;
    for (i = 0; i < 50u; ++i) {
        g_in[i] = g_pts[0];
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_DEGENERATE,
                          magcal_optics_auto_params3(g_in, n, g_work, wl, &e, &mp, &ep));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_DEGENERATE,
                          magcal_optics_filter3(&cfg, g_in, n, g_work, wl, g_mask, &info));
    TEST_ASSERT_EQUAL_FLOAT(-7.0f, e);
    TEST_ASSERT_EQUAL_FLOAT(-7.0f, ep);
    TEST_ASSERT_EQUAL_UINT16(77u, mp);
    assert_sentinels(n);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK,
                          magcal_optics_auto_params3(g_pts, n, g_work, wl, &e, &mp, &ep));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK,
                          magcal_optics_filter3(&cfg, g_pts, n, g_work, wl, g_mask, &info));
}

/* ---- time-sliced filter (magcal_optics_filter3_begin / _step) ------------------------------ */

/* The sliced filter gives the one-shot call's status, mask and info bit for bit at every budget;
 * at budget 6000 a step charges at most one visit over it (the automatic path's largest visit is
 * a heapsort sift, <= 500; the given-parameter path's grid build and output are one unit each,
 * 60 n and 26 n), and the steps are within one of total / 6000 (every step but the last charges
 * the whole budget). */
static void assert_filter3_sliced_same(const magcal_optics_cfg_t *cfg, size_t n, const char *what)
{
    static const uint32_t budgets[5] = {1u, 97u, 1000u, 6000u, UINT32_MAX};
    magcal_optics_result_t ia, ib;
    magcal_status_t sa;
    size_t j;
    const uint32_t over = cfg->eps > 0.0f ? (uint32_t)(60u * n > 1500u ? 60u * n : 1500u) : 500u;
    memset(g_mask, 0x77, n);
    memset(&ia, 0x5A, sizeof ia);
    sa = magcal_optics_filter3(cfg, g_pts, n, g_work, sizeof g_work, g_mask, &ia);
    for (j = 0u; j < 5u; ++j) {
        magcal_optics3_slice_t sl;
        magcal_status_t sb;
        uint32_t steps = 0u, mx = 0u, used = 0u;
        uint64_t total = 0u;
        memset(g_mask2, 0x77, n);
        memset(&ib, 0x5A, sizeof ib);
        TEST_ASSERT_EQUAL_INT_MESSAGE(MAGCAL_OK, magcal_optics_filter3_begin(&sl, cfg, g_pts, n, g_work, sizeof g_work,
                                                                             g_mask2, &ib), what);
        do {
            sb = magcal_optics_filter3_step(&sl, budgets[j], &used);
            total += used;
            mx = used > mx ? used : mx;
            TEST_ASSERT_TRUE(++steps < 50000000u);
        } while (sb == MAGCAL_IN_PROGRESS);
        TEST_ASSERT_EQUAL_INT_MESSAGE(sa, sb, what);
        TEST_ASSERT_EQUAL_MEMORY_MESSAGE(g_mask, g_mask2, n, what);
        TEST_ASSERT_EQUAL_MEMORY_MESSAGE(&ia, &ib, sizeof ia, what);
        TEST_ASSERT_EQUAL_INT(sb, magcal_optics_filter3_step(&sl, budgets[j], &used)); /* final: again */
        TEST_ASSERT_EQUAL_UINT32(0u, used);
        if (budgets[j] == 6000u) {
            printf("  sliced %s n=%u: %u steps at 6000, total %lu estimated, largest %u\n", what, (unsigned)n,
                   (unsigned)steps, (unsigned long)total, (unsigned)mx);
            TEST_ASSERT_TRUE(mx <= 6000u + over);
            TEST_ASSERT_TRUE((uint64_t)steps <= total / 6000u + 1u);
        }
    }
}

static void test_optics_filter3_sliced_any_budget_matches_filter3(void)
{
    magcal_optics_cfg_t cfg = MAGCAL_OPTICS_CFG_DEFAULT;
    make_shell(300u, 0.01, 11u); /* clean shell */
    assert_filter3_sliced_same(&cfg, 300u, "clean shell");
    make_e2e(3.0, 12u); /* far burst and spikes */
    assert_filter3_sliced_same(&cfg, E2E_N, "far burst + spikes");
    make_e2e(1.3, 13u); /* near burst */
    assert_filter3_sliced_same(&cfg, E2E_N, "near burst + spikes");
    make_rest_shell(400u, 0.45, 1, 0.01, 14u); /* two rest phases */
    assert_filter3_sliced_same(&cfg, 400u, "rest phases");
    cfg.start = MAGCAL_OPTICS_START_CORE;
    assert_filter3_sliced_same(&cfg, 400u, "rest phases, START_CORE");
    cfg.start = MAGCAL_OPTICS_START_INDEX;
    cfg.order = MAGCAL_OPTICS_CLASSIC;
    assert_filter3_sliced_same(&cfg, 400u, "rest phases, CLASSIC");
    /* given parameters: grid and brute force, the on-the-fly extraction */
    cfg = (magcal_optics_cfg_t)MAGCAL_OPTICS_CFG_DEFAULT;
    make_e2e(3.0, 15u);
    cfg.eps = 0.3f;
    cfg.eps_prime = 0.2f;
    cfg.min_pts = 5u;
    cfg.neighbors = MAGCAL_NEIGHBORS_GRID;
    assert_filter3_sliced_same(&cfg, E2E_N, "given eps, grid");
    cfg.start = MAGCAL_OPTICS_START_CORE;
    assert_filter3_sliced_same(&cfg, E2E_N, "given eps, grid, START_CORE");
    cfg.neighbors = MAGCAL_NEIGHBORS_BRUTE;
    assert_filter3_sliced_same(&cfg, E2E_N, "given eps, brute, START_CORE");
    /* the largest store: 1024 samples with 10 % spikes */
    cfg = (magcal_optics_cfg_t)MAGCAL_OPTICS_CFG_DEFAULT;
    make_shell(NMAX, 0.01, 16u);
    {
        size_t k;
        for (k = 7u; k < NMAX; k += 10u) {
            g_pts[k].x *= 2.0f;
            g_pts[k].z += 0.5f;
        }
    }
    assert_filter3_sliced_same(&cfg, NMAX, "1024 with spikes");
}

/* The sliced filter's failures: the O(1) checks in begin, the rest (finiteness, workspace) in the
 * first steps, as the one-shot call orders them; a slice not begun is refused. */
static void test_optics_filter3_step_bad_input_returns_specific_status(void)
{
    const magcal_optics_cfg_t cfg = MAGCAL_OPTICS_CFG_DEFAULT;
    magcal_optics3_slice_t sl;
    uint32_t used = 7u;
    make_shell(300u, 0.01, 17u);
    memset(&sl, 0, sizeof sl);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_optics_filter3_step(NULL, 100u, &used));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_optics_filter3_step(&sl, 100u, &used)); /* not begun */
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_optics_filter3_begin(NULL, &cfg, g_pts, 300u, g_work, sizeof g_work, g_mask, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_optics_filter3_begin(&sl, &cfg, g_pts, 300u, g_work, sizeof g_work, NULL, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_optics_filter3_step(&sl, 100u, &used)); /* failed begin */
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_TOO_FEW_POINTS,
                          magcal_optics_filter3_begin(&sl, &cfg, g_pts, 15u, g_work, sizeof g_work, g_mask, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ALIGNMENT, magcal_optics_filter3_begin(&sl, &cfg, g_pts, 300u, (uint8_t *)(void *)g_work + 2,
                                                                            sizeof g_work - 2u, g_mask, NULL));
    /* workspace one byte short: found by the first step, mask untouched */
    memset(g_mask, 0x77, 300u);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_optics_filter3_begin(&sl, &cfg, g_pts, 300u, g_work,
                                                                 MAGCAL_OPTICS3_FILTER_WORKSPACE_LEN(300u) - 1u, g_mask, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_IN_PROGRESS, magcal_optics_filter3_step(&sl, 1u, &used));
    TEST_ASSERT_EQUAL_UINT32(40u, used); /* one finiteness visit (W3_FIN) */
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_WORKSPACE, magcal_optics_filter3_step(&sl, UINT32_MAX, &used));
    TEST_ASSERT_EQUAL_HEX8(0x77, g_mask[0]);
    /* a NaN at the end: the finiteness pass reaches it */
    g_pts[299].y = NAN;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_optics_filter3_begin(&sl, &cfg, g_pts, 300u, g_work, sizeof g_work, g_mask, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_optics_filter3_step(&sl, UINT32_MAX, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_optics_filter3_step(&sl, UINT32_MAX, NULL));
    TEST_ASSERT_EQUAL_HEX8(0x77, g_mask[0]);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_optics_run3_matches_sklearn_golden_vectors);
    RUN_TEST(test_optics_run3_variants_bit_identical_to_reference);
    RUN_TEST(test_optics_run3_grid_finds_pairs_across_cell_borders);
    RUN_TEST(test_optics_run3_all_duplicates_gives_zero_core_and_reach);
    RUN_TEST(test_optics_filter3_equals_run_extract_largest);
    RUN_TEST(test_optics_auto_params3_scale_and_shift_invariant);
    RUN_TEST(test_optics_filter3_clean_shell_keeps_every_sample);
    RUN_TEST(test_optics_filter3_then_ellipsoid_fit_far_burst_recovers_truth);
    RUN_TEST(test_optics_filter3_then_ellipsoid_fit_near_burst_gate_finishes);
    RUN_TEST(test_optics_filter3_real_tumbles_keep_samples_and_reject_injected);
    RUN_TEST(test_optics_filter3_rest_phase_up_to_half_keeps_rotation);
    RUN_TEST(test_optics_run3_bad_input_returns_specific_status);
    RUN_TEST(test_optics_filter3_and_auto_bad_input_returns_specific_status);
    RUN_TEST(test_optics_filter3_sliced_any_budget_matches_filter3);
    RUN_TEST(test_optics_filter3_step_bad_input_returns_specific_status);
    return UNITY_END();
}
