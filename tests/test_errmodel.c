/* Tests of the adaptive heading-error models (src/heading/errmodel.c): the indoor patent's polynomial
 * and the periodic Fourier alternative (algorithms.md 5.2, 5.3). */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "magcal/errmodel.h"
#include "test_util.h"
#include "unity.h"

#define D2R (3.14159265358979323846 / 180.0)
#define NPTS 24

/* the fit's normal equations (caller-owned: magcal_errmodel_fit keeps them off its stack) */
static MAGCAL_ERRMODEL_WORKSPACE_DECLARE(g_em_work);

void setUp(void) {}
void tearDown(void) {}

/* algorithms.md 5.1 residual distortion (shear variant used in test_swing.c):
 * Hm = R(-2 deg) (I + S) H + b, S = 0.03 (v v^T - w w^T) along 10 deg, b = 0.05 H0 at 70 deg.
 * Uncorrected max error 5.10 deg; its deviation has harmonics beyond 2 (0.07 deg). */
static double dist_psi_c(double psi_deg)
{
    const double a = -2.0 * D2R, v0 = cos(10.0 * D2R), v1 = sin(10.0 * D2R);
    const double sxx = 0.03 * (v0 * v0 - v1 * v1), sxy = 0.03 * 2.0 * v0 * v1, syy = -sxx;
    const double bx = 0.05 * cos(70.0 * D2R), by = 0.05 * sin(70.0 * D2R);
    double p = psi_deg * D2R, hx = -sin(p), hy = cos(p);
    double ux = (1.0 + sxx) * hx + sxy * hy, uy = sxy * hx + (1.0 + syy) * hy;
    double mx = cos(a) * ux - sin(a) * uy + bx, my = sin(a) * ux + cos(a) * uy + by;
    double r = atan2(-mx, my) / D2R;
    return r < 0.0 ? r + 360.0 : r;
}

/* NPTS random reference headings (uniform), their compass headings. */
static void make_set(uint32_t seed, float *pc, float *pr)
{
    uint32_t rng = seed;
    int k;
    for (k = 0; k < NPTS; ++k) {
        double psi = 360.0 * test_rand_uniform(&rng);
        pr[k] = (float)psi;
        pc[k] = (float)dist_psi_c(psi);
    }
}

/* Max |corrected - truth| over a 0.05-deg grid of true headings (between the points too). */
static double dense_max_error(const magcal_errmodel_t *m)
{
    double worst = 0.0;
    int i;
    for (i = 0; i < 7200; ++i) {
        double psi = 0.05 * i;
        float out = 0.0f;
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_errmodel_apply(m, (float)dist_psi_c(psi), &out));
        worst = fmax(worst, fabs(test_angle_diff_deg(out, psi)));
    }
    return worst;
}

/* Jump of the model at north: |delta(0) - delta(360-)|. */
static double seam_jump(const magcal_errmodel_t *m)
{
    float d0 = 0.0f, d1 = 0.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_errmodel_eval(m, 0.0f, &d0));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_errmodel_eval(m, 359.999f, &d1));
    return fabs((double)d0 - (double)d1);
}

static void test_errmodel_fit_poly_raises_order_until_threshold(void)
{
    /* tau = 0.05 deg: the accepted order passes at the points, the order below does not. */
    float pc[NPTS], pr[NPTS];
    magcal_errmodel_cfg_t cfg = {MAGCAL_ERRMODEL_POLY, 0.05f, MAGCAL_ERRMODEL_MAX_POLY_ORDER, 1e-6f};
    magcal_errmodel_t m, m2;
    magcal_errmodel_stats_t st, st2;
    make_set(7u, pc, pr);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_errmodel_fit(&cfg, pc, pr, NPTS, g_em_work, sizeof g_em_work, &m, &st));
    TEST_ASSERT_EQUAL_UINT8(m.order, st.order);
    TEST_ASSERT_TRUE(st.max_abs_deg < 0.05f);
    TEST_ASSERT_TRUE(m.order >= 5u); /* a 5 deg, two-cycle deviation needs a high degree */
    cfg.max_order = (uint8_t)(m.order - 1u);
    memset(&m2, 0x33, sizeof m2);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_THRESHOLD, magcal_errmodel_fit(&cfg, pc, pr, NPTS, g_em_work, sizeof g_em_work, &m2, &st2));
    TEST_ASSERT_EQUAL_UINT8(m.order - 1u, st2.order);
    TEST_ASSERT_TRUE(st2.max_abs_deg >= 0.05f);
    TEST_ASSERT_EQUAL_HEX8(0x33, ((const unsigned char *)&m2)[0]); /* untouched */
}

/*
 * The patent's failure and the periodic fix, on 20 random sets of 24 headings (tau 0.05 deg):
 * algorithms.md 5.2/5.3 report N = 9, 0.63 deg between points, 0.62 deg seam for the polynomial
 * and K = 3, 0.062 deg for Fourier on one such set.
 */
static double median20(const double *v, double *tmp)
{
    int i, j;
    memcpy(tmp, v, 20 * sizeof *v);
    for (i = 1; i < 20; ++i) { /* insertion sort */
        double x = tmp[i];
        for (j = i; j > 0 && tmp[j - 1] > x; --j) {
            tmp[j] = tmp[j - 1];
        }
        tmp[j] = x;
    }
    return 0.5 * (tmp[9] + tmp[10]);
}

static double max20(const double *v)
{
    double m = v[0];
    int i;
    for (i = 1; i < 20; ++i) {
        m = fmax(m, v[i]);
    }
    return m;
}

static void test_errmodel_poly_fails_at_seam_fourier_does_not(void)
{
    double p_med, f_med, p_seam_med;
    const magcal_errmodel_cfg_t pcfg = {MAGCAL_ERRMODEL_POLY, 0.05f, MAGCAL_ERRMODEL_MAX_POLY_ORDER, 1e-6f};
    const magcal_errmodel_cfg_t fcfg = {MAGCAL_ERRMODEL_FOURIER, 0.05f, MAGCAL_ERRMODEL_MAX_FOURIER_ORDER, 1e-6f};
    double p_err[20], p_seam[20], f_err_max = 0.0, p_err_sorted[20], f_err[20];
    int n_poly_bad = 0, maxN = 0, maxK = 0;
    int s;
    for (s = 0; s < 20; ++s) {
        float pc[NPTS], pr[NPTS];
        magcal_errmodel_t pm, fm;
        double fe;
        make_set(1000u + (uint32_t)s, pc, pr);
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_errmodel_fit(&pcfg, pc, pr, NPTS, g_em_work, sizeof g_em_work, &pm, NULL));
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_errmodel_fit(&fcfg, pc, pr, NPTS, g_em_work, sizeof g_em_work, &fm, NULL));
        p_err[s] = dense_max_error(&pm);
        p_seam[s] = seam_jump(&pm);
        fe = dense_max_error(&fm);
        f_err_max = fmax(f_err_max, fe);
        f_err[s] = fe;
        TEST_ASSERT_TRUE(seam_jump(&fm) < 1e-3); /* periodic: no seam (float rounding only) */
        n_poly_bad += (p_err[s] > 0.15);
        maxN = pm.order > maxN ? pm.order : maxN;
        maxK = fm.order > maxK ? fm.order : maxK;
        if (s == 0) {
            printf("errmodel set 0: poly N=%d max err %.3f deg seam %.3f deg; Fourier K=%d max err "
                   "%.3f deg\n", pm.order, p_err[0], p_seam[0], fm.order, fe);
        }
    }
    p_med = median20(p_err, p_err_sorted);
    f_med = median20(f_err, p_err_sorted);
    p_seam_med = median20(p_seam, p_err_sorted);
    printf("errmodel 20 sets: poly max err median %.3f worst %.3f deg (%d/20 above 3 tau), seam "
           "median %.3f deg, max N %d; Fourier max err median %.3f worst %.3f deg, max K %d\n",
           p_med, max20(p_err), n_poly_bad, p_seam_med, maxN, f_med, f_err_max, maxK);
    /* Both meet tau at the points. Between them Fourier stays near tau (its worst sets have
     * coverage gaps); the polynomial is typically an order of magnitude worse, jumps at north,
     * and explodes where the random set leaves the ends of [0, 360) unsampled. */
    TEST_ASSERT_TRUE(f_med < 0.1);
    TEST_ASSERT_TRUE(f_err_max < 0.25);
    TEST_ASSERT_TRUE(p_med > 2.0 * f_err_max);
    TEST_ASSERT_TRUE(p_seam_med > 2.0 * 0.05);
    TEST_ASSERT_TRUE(max20(p_err) > 5.0);
    TEST_ASSERT_TRUE(n_poly_bad >= 5);
}

static void test_errmodel_fit_fourier_k2_equals_smith_coefficients(void)
{
    /* Deviation exactly A + B sin + C cos + D sin2 + E cos2 in psi_c: K = 1 fails, K = 2 passes
     * with a0 = A, (a1, b1) = (C, B), (a2, b2) = (E, D). */
    static const double c[5] = {1.0, 3.0, -2.0, 0.7, -0.4};
    float pc[NPTS], pr[NPTS];
    magcal_errmodel_cfg_t cfg = MAGCAL_ERRMODEL_CFG_DEFAULT;
    magcal_errmodel_t m;
    uint32_t rng = 99u;
    int k;
    for (k = 0; k < NPTS; ++k) {
        double p = 360.0 * test_rand_uniform(&rng), r = p * D2R;
        pc[k] = (float)p;
        pr[k] = (float)(p + c[0] + c[1] * sin(r) + c[2] * cos(r) + c[3] * sin(2 * r) + c[4] * cos(2 * r));
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_errmodel_fit(&cfg, pc, pr, NPTS, g_em_work, sizeof g_em_work, &m, NULL));
    TEST_ASSERT_EQUAL_UINT8(2u, m.order);
    TEST_ASSERT_FLOAT_WITHIN(1e-4f, 1.0f, m.coef[0]);
    TEST_ASSERT_FLOAT_WITHIN(1e-4f, -2.0f, m.coef[1]);
    TEST_ASSERT_FLOAT_WITHIN(1e-4f, 3.0f, m.coef[2]);
    TEST_ASSERT_FLOAT_WITHIN(1e-4f, -0.4f, m.coef[3]);
    TEST_ASSERT_FLOAT_WITHIN(1e-4f, 0.7f, m.coef[4]);
}

static void test_errmodel_fit_poly_cubic_recovers_chebyshev_coefficients(void)
{
    /* delta = 0.5 + t - 0.3 t^2 + 0.2 t^3, t = psi/180 - 1: Chebyshev (0.35, 1.15, -0.15, 0.05). */
    float pc[12], pr[12];
    magcal_errmodel_cfg_t cfg = {MAGCAL_ERRMODEL_POLY, 1e-3f, 6u, 1e-6f};
    magcal_errmodel_t m;
    float d = 0.0f;
    int k;
    for (k = 0; k < 12; ++k) {
        double p = 30.0 * k + 7.0, t = p / 180.0 - 1.0;
        pc[k] = (float)p;
        pr[k] = (float)(p + 0.5 + t - 0.3 * t * t + 0.2 * t * t * t);
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_errmodel_fit(&cfg, pc, pr, 12u, g_em_work, sizeof g_em_work, &m, NULL));
    TEST_ASSERT_EQUAL_UINT8(3u, m.order);
    TEST_ASSERT_FLOAT_WITHIN(1e-4f, 0.35f, m.coef[0]);
    TEST_ASSERT_FLOAT_WITHIN(1e-4f, 1.15f, m.coef[1]);
    TEST_ASSERT_FLOAT_WITHIN(1e-4f, -0.15f, m.coef[2]);
    TEST_ASSERT_FLOAT_WITHIN(1e-4f, 0.05f, m.coef[3]);
    /* non-periodic by construction: delta(0) = 0.5 - 1 - 0.3 - 0.2 = -1.0, delta(360-) = 1.4 */
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_errmodel_eval(&m, 0.0f, &d));
    TEST_ASSERT_FLOAT_WITHIN(1e-4f, -1.0f, d);
}

static void test_errmodel_fit_bad_input_returns_status(void)
{
    static const float same[5] = {10.0f, 10.0f, 10.0f, 10.0f, 10.0f};
    float pc[NPTS], pr[NPTS];
    magcal_errmodel_cfg_t cfg = MAGCAL_ERRMODEL_CFG_DEFAULT;
    magcal_errmodel_t m;
    magcal_errmodel_stats_t st;
    uint32_t rng = 5u;
    float d;
    int k;
    make_set(3u, pc, pr);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_SPREAD, magcal_errmodel_fit(&cfg, same, same, 5u, g_em_work, sizeof g_em_work, &m, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_TOO_FEW_POINTS, magcal_errmodel_fit(&cfg, pc, pr, 2u, g_em_work, sizeof g_em_work, &m, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_errmodel_fit(&cfg, NULL, pr, NPTS, g_em_work, sizeof g_em_work, &m, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_errmodel_fit(&cfg, pc, pr, NPTS, NULL, sizeof g_em_work, &m, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_WORKSPACE,
                          magcal_errmodel_fit(&cfg, pc, pr, NPTS, g_em_work, MAGCAL_ERRMODEL_WORKSPACE_LEN - 1u, &m, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ALIGNMENT,
                          magcal_errmodel_fit(&cfg, pc, pr, NPTS, (uint8_t *)g_em_work + 1, MAGCAL_ERRMODEL_WORKSPACE_LEN, &m, NULL));
    cfg.max_order = MAGCAL_ERRMODEL_MAX_FOURIER_ORDER + 1u;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_errmodel_fit(&cfg, pc, pr, NPTS, g_em_work, sizeof g_em_work, &m, NULL));
    cfg.max_order = 5u;
    cfg.threshold_deg = 0.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_errmodel_fit(&cfg, pc, pr, NPTS, g_em_work, sizeof g_em_work, &m, NULL));
    cfg.threshold_deg = 0.1f;
    pr[4] = INFINITY;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_errmodel_fit(&cfg, pc, pr, NPTS, g_em_work, sizeof g_em_work, &m, NULL));
    /* 0.2 deg noise, tau 0.05, max order 2 on 12 points: no order meets it */
    for (k = 0; k < 12; ++k) {
        pc[k] = (float)(30.0 * k);
        pr[k] = (float)(30.0 * k + 0.2 * test_rand_normal(&rng));
    }
    cfg.threshold_deg = 0.05f;
    cfg.max_order = 2u;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_THRESHOLD, magcal_errmodel_fit(&cfg, pc, pr, 12u, g_em_work, sizeof g_em_work, &m, &st));
    TEST_ASSERT_EQUAL_UINT8(2u, st.order);
    TEST_ASSERT_TRUE(st.max_abs_deg >= 0.05f);
    /* with 7 points K is capped at (7 - 1)/2 = 3, where 7 coefficients interpolate 7 points */
    cfg.max_order = 5u;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_errmodel_fit(&cfg, pc, pr, 7u, g_em_work, sizeof g_em_work, &m, &st));
    TEST_ASSERT_EQUAL_UINT8(3u, m.order);
    m.kind = (magcal_errmodel_kind_t)9;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_errmodel_eval(&m, 0.0f, &d));
}

/* MAGCAL_ERRMODEL_WORKSPACE_LEN covers the largest system (polynomial N = 11: 12 x 12 + rhs) and
 * the fit stays inside it: a workspace of exactly that length, followed by guard bytes, gives the
 * same model as the static one and the guard is untouched. */
static void test_errmodel_fit_workspace_len_covers_the_largest_order_exactly(void)
{
    static union {
        magcal_workspace_t align;
        uint8_t b[MAGCAL_ERRMODEL_WORKSPACE_LEN + 32u];
    } w;
    magcal_errmodel_cfg_t cfg = MAGCAL_ERRMODEL_CFG_DEFAULT;
    float pc[NPTS];
    float pr[NPTS];
    magcal_errmodel_t m1;
    magcal_errmodel_t m2;
    magcal_errmodel_stats_t s1;
    magcal_errmodel_stats_t s2;
    size_t i;
    TEST_ASSERT_EQUAL_UINT((12u * 12u + 12u) * sizeof(float), MAGCAL_ERRMODEL_WORKSPACE_LEN);
    make_set(3u, pc, pr);
    cfg.kind = MAGCAL_ERRMODEL_POLY;
    cfg.max_order = MAGCAL_ERRMODEL_MAX_POLY_ORDER;
    cfg.threshold_deg = 1e-6f; /* unreachable: every order up to N = 11 is solved */
    (void)memset(w.b, 0xA5, sizeof w.b);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_THRESHOLD,
                          magcal_errmodel_fit(&cfg, pc, pr, NPTS, g_em_work, sizeof g_em_work, &m1, &s1));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_THRESHOLD,
                          magcal_errmodel_fit(&cfg, pc, pr, NPTS, w.b, MAGCAL_ERRMODEL_WORKSPACE_LEN, &m2, &s2));
    TEST_ASSERT_EQUAL_UINT8(MAGCAL_ERRMODEL_MAX_POLY_ORDER, s2.order);
    TEST_ASSERT_EQUAL_UINT8(s1.order, s2.order);
    TEST_ASSERT_EQUAL_FLOAT(s1.max_abs_deg, s2.max_abs_deg);
    TEST_ASSERT_EQUAL_FLOAT(s1.rms_deg, s2.rms_deg);
    for (i = MAGCAL_ERRMODEL_WORKSPACE_LEN; i < sizeof w.b; ++i) {
        TEST_ASSERT_EQUAL_HEX8(0xA5u, w.b[i]);
    }
}

/* ---------------------------------------------------- the indoor patent's embodiment */

/* The patent's published curve (embodiment, N = 4), highest power first as printed (MATLAB
 * polyfit order; ascending order would reach 440 rad at 2 pi): error e = measured - true in
 * radians as a function of the measured heading phi in radians. */
static const float k_patent[5] = {-0.0068f, 0.0944f, -0.3545f, 0.2051f, 0.2844f};

static double patent_e(double phi)
{
    double r = 0.0;
    int j;
    for (j = 0; j < 5; ++j) {
        r = r * phi + (double)k_patent[j];
    }
    return r;
}

/* The embodiment: 12 reference directions 30 deg apart; the measured heading phi satisfies
 * phi = true + e(phi) (fixed point, |e'| < 0.3). */
static void patent_set(float *pc, float *pr)
{
    int k, it;
    for (k = 0; k < 12; ++k) {
        double truth = 30.0 * k * D2R, phi = truth;
        for (it = 0; it < 200; ++it) {
            phi = truth + patent_e(phi);
        }
        pr[k] = (float)(30.0 * k);
        pc[k] = (float)(phi / D2R);
    }
}

static void test_errmodel_patent_embodiment_selects_n4_and_exports_its_coefficients(void)
{
    float pc[12], pr[12], exported[MAGCAL_ERRMODEL_MAX_COEF];
    size_t n = 0, k;
    magcal_errmodel_cfg_t cfg = {MAGCAL_ERRMODEL_POLY, 0.1f, 11u, 1e-6f};
    magcal_errmodel_t m, m3;
    magcal_errmodel_stats_t st, st3;
    double jump;
    float d0 = 0.0f, d360 = 0.0f;
    patent_set(pc, pr);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_errmodel_fit(&cfg, pc, pr, 12u, g_em_work, sizeof g_em_work, &m, &st));
    TEST_ASSERT_EQUAL_INT(4, m.order); /* the adaptive rule selects the patent's N = 4 */
    TEST_ASSERT_TRUE(st.max_abs_deg < 0.01f);
    /* N = 3 misses by 4.4 deg, so every threshold in (0.01, 4.4) deg selects N = 4 */
    cfg.max_order = 3u;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_THRESHOLD, magcal_errmodel_fit(&cfg, pc, pr, 12u, g_em_work, sizeof g_em_work, &m3, &st3));
    TEST_ASSERT_FLOAT_WITHIN(0.05f, 4.42f, st3.max_abs_deg);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_errmodel_poly_to_power(&m, MAGCAL_ERRMODEL_POWER_DESCENDING,
                                                                   exported, MAGCAL_ERRMODEL_MAX_COEF, &n));
    TEST_ASSERT_EQUAL_UINT(5u, n);
    printf("patent embodiment: N = %u (N = 3 max residual %.2f deg); exported", (unsigned)m.order,
           (double)st3.max_abs_deg);
    for (k = 0; k < n; ++k) {
        printf(" %.5f", (double)exported[k]);
        TEST_ASSERT_FLOAT_WITHIN(2e-4f, k_patent[k], exported[k]);
    }
    /* the jump at north the periodic model avoids: e(2 pi) - e(0) of the curve */
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_errmodel_eval(&m, 0.0f, &d0));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_errmodel_eval(&m, 359.9999f, &d360));
    jump = (double)(d0 - d360); /* delta = -e */
    printf("; jump at north %.3f deg (curve %.3f)\n", jump,
           (patent_e(2.0 * 3.14159265358979323846) - patent_e(0.0)) / D2R);
    TEST_ASSERT_FLOAT_WITHIN(0.01f, 6.38f, (float)jump);
}

static void test_errmodel_poly_from_power_loads_the_patent_curve(void)
{
    float asc[5];
    magcal_errmodel_t m, back;
    float round[MAGCAL_ERRMODEL_MAX_COEF];
    size_t n = 0;
    double worst = 0.0;
    int k;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_errmodel_poly_from_power(k_patent, 5u,
                                                                     MAGCAL_ERRMODEL_POWER_DESCENDING, &m));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERRMODEL_POLY, m.kind);
    TEST_ASSERT_EQUAL_INT(4, m.order);
    for (k = 0; k < 3600; ++k) { /* delta = -e in degrees at every measured heading */
        float d = 0.0f;
        double psi = 0.1 * k;
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_errmodel_eval(&m, (float)psi, &d));
        worst = fmax(worst, fabs((double)d + patent_e(psi * D2R) / D2R));
    }
    printf("patent curve loaded: max |delta + e| %.2e deg\n", worst);
    TEST_ASSERT_TRUE(worst < 2e-3);
    for (k = 0; k < 5; ++k) {
        asc[k] = k_patent[4 - k];
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_errmodel_poly_from_power(asc, 5u,
                                                                     MAGCAL_ERRMODEL_POWER_ASCENDING, &back));
    for (k = 0; k < 5; ++k) {
        TEST_ASSERT_FLOAT_WITHIN(1e-5f, m.coef[k], back.coef[k]);
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_errmodel_poly_to_power(&m, MAGCAL_ERRMODEL_POWER_ASCENDING,
                                                                   round, 5u, &n));
    for (k = 0; k < 5; ++k) {
        TEST_ASSERT_FLOAT_WITHIN(1e-5f + 1e-4f * fabsf(asc[k]), asc[k], round[k]);
    }
}

static void test_errmodel_power_bad_input_returns_status(void)
{
    magcal_errmodel_t m;
    float out[MAGCAL_ERRMODEL_MAX_COEF];
    float big[13] = {0};
    size_t n;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_errmodel_poly_from_power(NULL, 5u, MAGCAL_ERRMODEL_POWER_ASCENDING, &m));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_errmodel_poly_from_power(k_patent, 1u, MAGCAL_ERRMODEL_POWER_ASCENDING, &m));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_errmodel_poly_from_power(big, 13u, MAGCAL_ERRMODEL_POWER_ASCENDING, &m));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_errmodel_poly_from_power(k_patent, 5u, (magcal_errmodel_power_order_t)5, &m));
    big[1] = NAN;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_errmodel_poly_from_power(big, 3u, MAGCAL_ERRMODEL_POWER_ASCENDING, &m));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_errmodel_poly_from_power(k_patent, 5u, MAGCAL_ERRMODEL_POWER_DESCENDING, &m));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_errmodel_poly_to_power(&m, MAGCAL_ERRMODEL_POWER_ASCENDING, out, 4u, &n));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_errmodel_poly_to_power(&m, MAGCAL_ERRMODEL_POWER_ASCENDING, NULL, 5u, &n));
    m.kind = MAGCAL_ERRMODEL_FOURIER;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_errmodel_poly_to_power(&m, MAGCAL_ERRMODEL_POWER_ASCENDING, out, 12u, &n));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_errmodel_fit_poly_raises_order_until_threshold);
    RUN_TEST(test_errmodel_poly_fails_at_seam_fourier_does_not);
    RUN_TEST(test_errmodel_fit_fourier_k2_equals_smith_coefficients);
    RUN_TEST(test_errmodel_fit_poly_cubic_recovers_chebyshev_coefficients);
    RUN_TEST(test_errmodel_fit_bad_input_returns_status);
    RUN_TEST(test_errmodel_fit_workspace_len_covers_the_largest_order_exactly);
    RUN_TEST(test_errmodel_patent_embodiment_selects_n4_and_exports_its_coefficients);
    RUN_TEST(test_errmodel_poly_from_power_loads_the_patent_curve);
    RUN_TEST(test_errmodel_power_bad_input_returns_status);
    return UNITY_END();
}
