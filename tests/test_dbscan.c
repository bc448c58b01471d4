/* Tests of classic DBSCAN (include/magcal/dbscan.h), the baseline of the OPTICS filter. */
#include <math.h>
#include <string.h>

#include "golden_optics.h"
#include "magcal/dbscan.h"
#include "magcal/optics.h"
#include "test_util.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

#define NMAX 600u

static magcal_vec2_t g_pts[NMAX + 1u];
static uint32_t g_work[(MAGCAL_OPTICS_FILTER_WORKSPACE_LEN(NMAX + 1u) + 3u) / 4u];
static int16_t g_lab_b[NMAX];
static int16_t g_lab_g[NMAX];
static int16_t g_lab_o[NMAX];
static uint16_t g_order[NMAX];
static float g_reach[NMAX];
static float g_core[NMAX];
static uint8_t g_is_core[NMAX];
static int16_t g_map[NMAX];

static void make_points(magcal_vec2_t *p, size_t n, uint32_t seed, int ties)
{
    uint32_t rng = seed;
    size_t i;
    for (i = 0; i < n; ++i) {
        double a = 6.283185307179586 * test_rand_uniform(&rng);
        double r = test_rand_uniform(&rng) < 0.85 ? 1.0 + 0.05 * test_rand_normal(&rng)
                                                  : 3.0 * test_rand_uniform(&rng);
        p[i].x = (float)(r * cos(a));
        p[i].y = (float)(r * sin(a));
        if (ties) {
            p[i].x = floorf(p[i].x * 8.0f) / 8.0f;
            p[i].y = floorf(p[i].y * 8.0f) / 8.0f;
        }
        if (i > 0u && test_rand_uniform(&rng) < 0.05) {
            p[i] = p[(size_t)(test_rand_uniform(&rng) * (double)i)];
        }
    }
}

/* Core flags straight from the definition (|N_eps(p)| >= MinPts, p included), O(n^2). */
static void core_flags(const magcal_vec2_t *p, size_t n, float eps, size_t min_pts)
{
    size_t i, j;
    for (i = 0; i < n; ++i) {
        size_t c = 0u;
        for (j = 0; j < n; ++j) {
            float dx = p[j].x - p[i].x, dy = p[j].y - p[i].y;
            c += dx * dx + dy * dy <= eps * eps;
        }
        g_is_core[i] = (uint8_t)(c >= min_pts);
    }
}

/*
 * DBSCAN invariants (Ester et al. 1996) checked against the definition:
 *  - core points: two core points within eps share the label; labels of core points form the
 *    connected components of the core graph (checked by the pairwise rule + the same-partition
 *    comparison with OPTICS below);
 *  - a non-core point within eps of a core point carries the label of one such core point;
 *  - a point within eps of no core point is noise.
 */
static void check_dbscan_invariants(const magcal_vec2_t *p, size_t n, float eps, const int16_t *lab)
{
    size_t i, j;
    for (i = 0; i < n; ++i) {
        int near_core = 0, label_ok = 0;
        for (j = 0; j < n; ++j) {
            float dx = p[j].x - p[i].x, dy = p[j].y - p[i].y;
            if (dx * dx + dy * dy > eps * eps || !g_is_core[j]) {
                continue;
            }
            near_core = 1;
            if (lab[j] == lab[i]) {
                label_ok = 1;
            }
            if (g_is_core[i]) {
                TEST_ASSERT_EQUAL_INT16(lab[j], lab[i]);
            }
        }
        if (near_core) {
            TEST_ASSERT_TRUE(lab[i] >= 0);
            TEST_ASSERT_TRUE(label_ok);
        } else {
            TEST_ASSERT_EQUAL_INT16(MAGCAL_OPTICS_NOISE, lab[i]);
        }
    }
}

/* Same partition of the core points (up to renaming). OPTICS ExtractDBSCAN labels core points
 * exactly like DBSCAN (algorithms.md 4.3; only border points may differ). */
static void check_same_core_partition(size_t n, const int16_t *a, const int16_t *b)
{
    size_t i;
    for (i = 0; i < n; ++i) {
        g_map[i] = -2;
    }
    for (i = 0; i < n; ++i) {
        if (!g_is_core[i]) {
            continue;
        }
        TEST_ASSERT_TRUE(a[i] >= 0 && b[i] >= 0);
        if (g_map[a[i]] == -2) {
            g_map[a[i]] = b[i];
        }
        TEST_ASSERT_EQUAL_INT16(g_map[a[i]], b[i]);
    }
    for (i = 0; i < n; ++i) { /* injective: no two clusters of a merged in b */
        size_t j;
        for (j = i + 1u; j < n; ++j) {
            if (g_map[i] >= 0 && g_map[j] >= 0) {
                TEST_ASSERT_TRUE(g_map[i] != g_map[j]);
            }
        }
    }
}

static void test_dbscan_run_brute_equals_grid_and_satisfies_definition(void)
{
    static const float eps_list[] = {0.5f, 0.25f, 0.125f, 0.08f};
    static const uint16_t mp_list[] = {2u, 4u, 6u};
    uint32_t seed = 3u;
    size_t ie, im, in;
    for (in = 0; in < 3u; ++in) {
        for (ie = 0; ie < 4u; ++ie) {
            for (im = 0; im < 3u; ++im) {
                size_t n = 60u + 200u * in;
                magcal_dbscan_cfg_t c = MAGCAL_DBSCAN_CFG_DEFAULT;
                magcal_neighbors_t used = MAGCAL_NEIGHBORS_BRUTE;
                uint16_t nb = 0u, ng = 0u;
                make_points(g_pts, n, seed, (int)(seed & 1u));
                ++seed;
                c.eps = eps_list[ie];
                c.min_pts = mp_list[im];
                c.neighbors = MAGCAL_NEIGHBORS_BRUTE;
                TEST_ASSERT_EQUAL_INT(
                    MAGCAL_OK,
                    magcal_dbscan_run(&c, g_pts, n, g_work, sizeof g_work, g_lab_b, &nb, NULL));
                c.neighbors = MAGCAL_NEIGHBORS_GRID;
                TEST_ASSERT_EQUAL_INT(
                    MAGCAL_OK,
                    magcal_dbscan_run(&c, g_pts, n, g_work, sizeof g_work, g_lab_g, &ng, &used));
                TEST_ASSERT_EQUAL_INT(MAGCAL_NEIGHBORS_GRID, used);
                TEST_ASSERT_EQUAL_UINT16(nb, ng);
                TEST_ASSERT_EQUAL_INT16_ARRAY(g_lab_b, g_lab_g, n);
                core_flags(g_pts, n, c.eps, c.min_pts);
                check_dbscan_invariants(g_pts, n, c.eps, g_lab_g);
            }
        }
    }
}

static void test_dbscan_run_core_partition_equals_optics_extraction(void)
{
    uint32_t seed;
    for (seed = 1u; seed <= 10u; ++seed) {
        size_t n = 100u + 40u * seed, i;
        float eps_prime = 0.06f + 0.02f * (float)(seed % 5u);
        magcal_optics_cfg_t oc = MAGCAL_OPTICS_CFG_DEFAULT;
        magcal_dbscan_cfg_t dc = MAGCAL_DBSCAN_CFG_DEFAULT;
        uint16_t nd = 0u, no = 0u;
        make_points(g_pts, n, 40u + seed, (int)(seed & 1u));
        oc.eps = 2.0f * eps_prime;
        oc.min_pts = (uint16_t)(3u + seed % 3u);
        dc.eps = eps_prime;
        dc.min_pts = oc.min_pts;
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_optics_run(&oc, g_pts, n, g_work, sizeof g_work,
                                                           g_order, g_reach, g_core, NULL, NULL));
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK,
                              magcal_optics_extract_dbscan(g_order, g_reach, g_core, n, oc.eps,
                                                           eps_prime, g_lab_o, &no));
        TEST_ASSERT_EQUAL_INT(
            MAGCAL_OK, magcal_dbscan_run(&dc, g_pts, n, g_work, sizeof g_work, g_lab_b, &nd, NULL));
        core_flags(g_pts, n, eps_prime, dc.min_pts);
        TEST_ASSERT_EQUAL_UINT16(nd, no);
        check_same_core_partition(n, g_lab_b, g_lab_o);
        for (i = 0; i < n; ++i) {
            if (g_lab_b[i] < 0) { /* DBSCAN noise is noise for the extraction too */
                TEST_ASSERT_EQUAL_INT16(MAGCAL_OPTICS_NOISE, g_lab_o[i]);
            }
        }
    }
}

/* scikit-learn's cluster_optics_dbscan labels (golden) equal DBSCAN(eps', MinPts) on core points. */
static void test_dbscan_run_matches_sklearn_golden_core_points(void)
{
    size_t s;
    for (s = 0; s < GOLDEN_OPTICS_N_SETS; ++s) {
        const golden_optics_set_t *g = &golden_optics_sets[s];
        magcal_dbscan_cfg_t dc = MAGCAL_DBSCAN_CFG_DEFAULT;
        uint16_t nd = 0u;
        dc.eps = g->eps_prime;
        dc.min_pts = g->min_pts;
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_dbscan_run(&dc, g->pts, g->n, g_work, sizeof g_work,
                                                           g_lab_b, &nd, NULL));
        TEST_ASSERT_EQUAL_INT(g->n_clusters, nd);
        core_flags(g->pts, g->n, g->eps_prime, g->min_pts);
        check_same_core_partition(g->n, g_lab_b, g->labels);
    }
}

static void test_dbscan_run_hand_made_border_and_noise(void)
{
    /* Cluster A: 4 points on a 0.5 square (each sees 3 others within 1.0 -> core for MinPts 4).
     * p4 at (1.5,0) is exactly 1.0 from p1 only (inclusive radius): border of A. Cluster B: 4 points around (10,10).
     * p9 far away: noise. eps = 1.0 exactly representable distances. */
    static const magcal_vec2_t p[10] = {{0, 0},         {0.5f, 0}, {0, 0.5f},   {0.5f, 0.5f},
                                        {1.5f, 0},      {10, 10},  {10.5f, 10}, {10, 10.5f},
                                        {10.5f, 10.5f}, {-5, 7}};
    static const int16_t expect[10] = {0, 0, 0, 0, 0, 1, 1, 1, 1, -1};
    magcal_dbscan_cfg_t c = MAGCAL_DBSCAN_CFG_DEFAULT;
    int16_t lab[10];
    uint8_t mask[10];
    uint16_t nc = 0u, w[16], cnt = 0u;
    int16_t id = -3;
    c.eps = 1.0f;
    c.min_pts = 4u;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK,
                          magcal_dbscan_run(&c, p, 10u, g_work, sizeof g_work, lab, &nc, NULL));
    TEST_ASSERT_EQUAL_INT16_ARRAY(expect, lab, 10);
    TEST_ASSERT_EQUAL_UINT16(2u, nc);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK,
                          magcal_optics_largest_cluster(lab, 10u, w, sizeof w, mask, &id, &cnt));
    TEST_ASSERT_EQUAL_INT16(0, id);
    TEST_ASSERT_EQUAL_UINT16(5u, cnt);
    TEST_ASSERT_EQUAL_UINT8(1u, mask[4]);
    TEST_ASSERT_EQUAL_UINT8(0u, mask[9]);
    c.min_pts = 6u; /* nobody is core: all noise */
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK,
                          magcal_dbscan_run(&c, p, 10u, g_work, sizeof g_work, lab, &nc, NULL));
    TEST_ASSERT_EQUAL_UINT16(0u, nc);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ALL_NOISE,
                          magcal_optics_largest_cluster(lab, 10u, w, sizeof w, mask, &id, &cnt));
}

static void test_dbscan_run_bad_input_returns_status(void)
{
    magcal_dbscan_cfg_t c = MAGCAL_DBSCAN_CFG_DEFAULT;
    size_t len = MAGCAL_DBSCAN_WORKSPACE_LEN(50u);
    magcal_neighbors_t used = MAGCAL_NEIGHBORS_GRID;
    make_points(g_pts, 51u, 9u, 0);
    g_lab_b[0] = 99;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG,
                          magcal_dbscan_run(&c, g_pts, 50u, g_work, len, g_lab_b, NULL, NULL));
    c.eps = 0.2f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL,
                          magcal_dbscan_run(NULL, g_pts, 50u, g_work, len, g_lab_b, NULL, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL,
                          magcal_dbscan_run(&c, NULL, 50u, g_work, len, g_lab_b, NULL, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL,
                          magcal_dbscan_run(&c, g_pts, 50u, NULL, len, g_lab_b, NULL, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL,
                          magcal_dbscan_run(&c, g_pts, 50u, g_work, len, NULL, NULL, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_TOO_FEW_POINTS,
                          magcal_dbscan_run(&c, g_pts, 3u, g_work, len, g_lab_b, NULL, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG,
                          magcal_dbscan_run(&c, g_pts, MAGCAL_MAX_SAMPLES + 1u, g_work,
                                            sizeof g_work, g_lab_b, NULL, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_WORKSPACE,
                          magcal_dbscan_run(&c, g_pts, 50u, g_work, len - 1u, g_lab_b, NULL, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_WORKSPACE,
                          magcal_dbscan_run(&c, g_pts, 51u, g_work, len, g_lab_b, NULL, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ALIGNMENT, magcal_dbscan_run(&c, g_pts, 50u, (uint8_t *)g_work + 2,
                                                            len, g_lab_b, NULL, NULL));
    c.min_pts = 1u;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG,
                          magcal_dbscan_run(&c, g_pts, 50u, g_work, len, g_lab_b, NULL, NULL));
    c.min_pts = 4u;
    c.neighbors = (magcal_neighbors_t)3;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG,
                          magcal_dbscan_run(&c, g_pts, 50u, g_work, len, g_lab_b, NULL, NULL));
    c.neighbors = MAGCAL_NEIGHBORS_GRID;
    g_pts[5].x = NAN;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE,
                          magcal_dbscan_run(&c, g_pts, 50u, g_work, len, g_lab_b, NULL, NULL));
    TEST_ASSERT_EQUAL_INT16(99, g_lab_b[0]);
    g_pts[5].x = 0.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK,
                          magcal_dbscan_run(&c, g_pts, 50u, g_work, len, g_lab_b, NULL, &used));
    c.eps = INFINITY; /* one cluster, grid not usable */
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK,
                          magcal_dbscan_run(&c, g_pts, 50u, g_work, len, g_lab_b, NULL, &used));
    TEST_ASSERT_EQUAL_INT(MAGCAL_NEIGHBORS_BRUTE, used);
    TEST_ASSERT_EQUAL_INT16(0, g_lab_b[49]);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_dbscan_run_brute_equals_grid_and_satisfies_definition);
    RUN_TEST(test_dbscan_run_core_partition_equals_optics_extraction);
    RUN_TEST(test_dbscan_run_matches_sklearn_golden_core_points);
    RUN_TEST(test_dbscan_run_hand_made_border_and_noise);
    RUN_TEST(test_dbscan_run_bad_input_returns_status);
    return UNITY_END();
}
