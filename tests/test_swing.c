/* Tests of the classical compass swing and the course-over-ground motion swing (src/heading/swing.c).
 * Truth is synthesised in double from known distortions (algorithms.md 1.3, 5.1). */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "magcal/ellipse.h"
#include "magcal/heading.h"
#include "magcal/swing.h"
#include "magcal_internal.h" /* magcal_wrap360_deg: the bins copied out as the former cog fit did */
#include "test_util.h"
#include "unity.h"

#define D2R (3.14159265358979323846 / 180.0)

void setUp(void) {}
void tearDown(void) {}

/* Residual distortion Hm = R(alpha) (I + S) H + b, H = (-sin psi, cos psi) (H0 = 1). */
typedef struct {
    double alpha_deg;
    double sxx, sxy, syy;
    double bx, by;
} dist_t;

/* Compass heading (deg, [0,360)) seen at true magnetic heading psi_deg. */
static double dist_psi_c(const dist_t *d, double psi_deg)
{
    double p = psi_deg * D2R, a = d->alpha_deg * D2R;
    double hx = -sin(p), hy = cos(p);
    double ux = (1.0 + d->sxx) * hx + d->sxy * hy;
    double uy = d->sxy * hx + (1.0 + d->syy) * hy;
    double mx = cos(a) * ux - sin(a) * uy + d->bx;
    double my = sin(a) * ux + cos(a) * uy + d->by;
    double r = atan2(-mx, my) / D2R;
    return r < 0.0 ? r + 360.0 : r;
}

/* Smith model in double. */
static double smith(const double c[5], double psi_deg)
{
    double p = psi_deg * D2R;
    return c[0] + c[1] * sin(p) + c[2] * cos(p) + c[3] * sin(2 * p) + c[4] * cos(2 * p);
}

/* Max over a 0.1-deg grid of true headings of |corrected - truth| for a fitted model, and the
 * max uncorrected error. */
static void dense_errors(const dist_t *d, const magcal_swing_model_t *m, double *max_after,
                         double *max_before)
{
    int i;
    *max_after = 0.0;
    *max_before = 0.0;
    for (i = 0; i < 3600; ++i) {
        double psi = 0.1 * i, pc = dist_psi_c(d, psi);
        float out = 0.0f;
        double e;
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_swing_apply(m, (float)pc, &out));
        e = fabs(test_angle_diff_deg(out, psi));
        *max_after = e > *max_after ? e : *max_after;
        e = fabs(test_angle_diff_deg(pc, psi));
        *max_before = e > *max_before ? e : *max_before;
    }
}

static void test_swing_fit_8pos_equals_closed_form_coefficients(void)
{
    /* Arbitrary deviations at compass headings 0, 45, ..., 315: the least-squares fit must equal
     * the closed-form 8-position formulas of algorithms.md 5.1 (computed here in double). */
    static const double dv[8] = {2.1, 3.4, 1.7, -0.6, -1.9, -0.4, 0.8, 1.3}; /* N NE E SE S SW W NW */
    const double r2 = sqrt(0.5);
    double cf[5];
    float pc[8], pr[8];
    magcal_swing_cfg_t cfg = MAGCAL_SWING_CFG_DEFAULT;
    magcal_swing_model_t m;
    magcal_swing_stats_t st;
    int k;
    for (k = 0; k < 8; ++k) {
        pc[k] = (float)(45.0 * k);
        pr[k] = (float)(45.0 * k + dv[k]);
    }
    cf[0] = (dv[0] + dv[1] + dv[2] + dv[3] + dv[4] + dv[5] + dv[6] + dv[7]) / 8.0;
    cf[1] = (dv[2] - dv[6] + (dv[1] + dv[3] - dv[5] - dv[7]) * r2) / 4.0;
    cf[2] = (dv[0] - dv[4] + (dv[1] - dv[3] - dv[5] + dv[7]) * r2) / 4.0;
    cf[3] = (dv[1] - dv[3] + dv[5] - dv[7]) / 4.0;
    cf[4] = (dv[0] - dv[2] + dv[4] - dv[6]) / 4.0;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK,
                          magcal_swing_fit(&cfg, pc, pr, NULL, 8u, MAGCAL_SWING_REG_MEASURED, &m, &st));
    for (k = 0; k < 5; ++k) {
        TEST_ASSERT_FLOAT_WITHIN(2e-5f, (float)cf[k], m.coef_deg[k]);
    }
    TEST_ASSERT_FLOAT_WITHIN(1e-5f, 0.5f, st.min_spread_pivot);
    TEST_ASSERT_EQUAL_UINT32(8u, (uint32_t)st.n_used);
}

static void test_swing_fit_known_smith_model_recovers_coefficients(void)
{
    /* 11 unequally spaced compass headings, deviation exactly a Smith model in psi_c. */
    static const double truth[5] = {1.5, 4.0, -3.0, 0.8, -0.6};
    static const double hdg[11] = {3, 31, 70, 95, 133, 170, 188, 222, 260, 300, 340};
    float pc[11], pr[11];
    magcal_swing_cfg_t cfg = MAGCAL_SWING_CFG_DEFAULT;
    magcal_swing_model_t m;
    magcal_swing_stats_t st;
    int k;
    for (k = 0; k < 11; ++k) {
        pc[k] = (float)hdg[k];
        pr[k] = (float)fmod(hdg[k] + smith(truth, hdg[k]) + 360.0, 360.0);
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK,
                          magcal_swing_fit(&cfg, pc, pr, NULL, 11u, MAGCAL_SWING_REG_MEASURED, &m, &st));
    for (k = 0; k < 5; ++k) { /* float32 rounding of headings near 360: 1e-4 deg */
        TEST_ASSERT_FLOAT_WITHIN(2e-4f, (float)truth[k], m.coef_deg[k]);
    }
    TEST_ASSERT_TRUE(st.max_abs_deg < 2e-4f);
}

static void test_swing_fit_wraps_deviation_across_north(void)
{
    /* Constant +2 deg deviation with headings straddling 0/360: the fit must see +2, not -358. */
    static const float pc[6] = {359.0f, 58.0f, 118.0f, 178.0f, 238.0f, 298.0f};
    float pr[6];
    float out = 0.0f;
    magcal_swing_cfg_t cfg = MAGCAL_SWING_CFG_DEFAULT;
    magcal_swing_model_t m;
    int k;
    for (k = 0; k < 6; ++k) {
        pr[k] = (float)fmod(pc[k] + 2.0 + 360.0, 360.0); /* 359 -> 1 */
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK,
                          magcal_swing_fit(&cfg, pc, pr, NULL, 6u, MAGCAL_SWING_REG_MEASURED, &m, NULL));
    TEST_ASSERT_FLOAT_WITHIN(1e-4f, 2.0f, m.coef_deg[0]);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_swing_apply(&m, 359.5f, &out));
    TEST_ASSERT_FLOAT_WITHIN(1e-3f, 1.5f, out);
}

static void test_swing_fit_bad_spread_or_input_returns_status_untouched(void)
{
    /* Cardinal headings only: sin 2psi = 0 at all of them (rank 4). */
    static const float card[8] = {0.0f, 90.0f, 180.0f, 270.0f, 0.0f, 90.0f, 180.0f, 270.0f};
    static const float half[6] = {0.0f, 30.0f, 60.0f, 90.0f, 120.0f, 150.0f}; /* pivot 0.015 */
    static const float eight[8] = {0.0f, 45.0f, 90.0f, 135.0f, 180.0f, 225.0f, 270.0f, 315.0f};
    float ref[8];
    float w[8] = {1, 1, 1, 1, 0, 0, 0, 0};
    float bad[8];
    magcal_swing_cfg_t cfg = MAGCAL_SWING_CFG_DEFAULT;
    magcal_swing_model_t m;
    magcal_swing_stats_t st;
    int k;
    memset(&m, 0x5A, sizeof m);
    for (k = 0; k < 8; ++k) {
        ref[k] = eight[k] + 1.0f;
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_SPREAD,
                          magcal_swing_fit(&cfg, card, card, NULL, 8u, MAGCAL_SWING_REG_MEASURED, &m, &st));
    TEST_ASSERT_TRUE(st.min_spread_pivot < 1e-6f);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_SPREAD,
                          magcal_swing_fit(&cfg, half, half, NULL, 6u, MAGCAL_SWING_REG_MEASURED, &m, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_TOO_FEW_POINTS,
                          magcal_swing_fit(&cfg, eight, ref, NULL, 4u, MAGCAL_SWING_REG_MEASURED, &m, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_TOO_FEW_POINTS,
                          magcal_swing_fit(&cfg, eight, ref, w, 8u, MAGCAL_SWING_REG_MEASURED, &m, NULL));
    w[5] = -1.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG,
                          magcal_swing_fit(&cfg, eight, ref, w, 8u, MAGCAL_SWING_REG_MEASURED, &m, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_swing_fit(&cfg, eight, ref, NULL, 8u,
                                                           (magcal_swing_regressor_t)7, &m, NULL));
    memcpy(bad, ref, sizeof bad);
    bad[3] = NAN;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE,
                          magcal_swing_fit(&cfg, eight, bad, NULL, 8u, MAGCAL_SWING_REG_MEASURED, &m, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL,
                          magcal_swing_fit(&cfg, NULL, ref, NULL, 8u, MAGCAL_SWING_REG_MEASURED, &m, NULL));
    cfg.iterations = 0u;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG,
                          magcal_swing_fit(&cfg, eight, ref, NULL, 8u, MAGCAL_SWING_REG_MEASURED, &m, NULL));
    for (k = 0; k < (int)sizeof m; ++k) {
        TEST_ASSERT_EQUAL_HEX8(0x5A, ((const unsigned char *)&m)[k]);
    }
}

static void test_swing_apply_reference_model_inverts_by_fixed_point(void)
{
    /* Model in the TRUE heading: psi_c = psi - delta(psi). Applying must return psi (the fixed
     * point); 5 iterations with slope bound 0.19 leave < 1e-3 deg. */
    static const double truth[5] = {-1.0, 5.0, 3.0, 1.0, -0.5};
    static const float eight[8] = {0.0f, 45.0f, 90.0f, 135.0f, 180.0f, 225.0f, 270.0f, 315.0f};
    float pc[8];
    magcal_swing_cfg_t cfg = MAGCAL_SWING_CFG_DEFAULT;
    magcal_swing_model_t m;
    double worst = 0.0;
    int k;
    for (k = 0; k < 8; ++k) {
        pc[k] = (float)fmod(eight[k] - smith(truth, eight[k]) + 360.0, 360.0);
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK,
                          magcal_swing_fit(&cfg, pc, eight, NULL, 8u, MAGCAL_SWING_REG_REFERENCE, &m, NULL));
    for (k = 0; k < 5; ++k) {
        TEST_ASSERT_FLOAT_WITHIN(2e-4f, (float)truth[k], m.coef_deg[k]);
    }
    for (k = 0; k < 360; ++k) {
        double psi = k + 0.25;
        float out;
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_swing_apply(&m, (float)(psi - smith(truth, psi)), &out));
        worst = fmax(worst, fabs(test_angle_diff_deg(out, psi)));
    }
    TEST_ASSERT_TRUE(worst < 1e-3);
}

static void test_swing_fit_reference_model_too_steep_returns_not_converged(void)
{
    /* B = 60 deg: slope bound 60 pi/180 = 1.05 >= 0.9, the inversion may diverge. */
    static const float eight[8] = {0.0f, 45.0f, 90.0f, 135.0f, 180.0f, 225.0f, 270.0f, 315.0f};
    float pc[8];
    magcal_swing_cfg_t cfg = MAGCAL_SWING_CFG_DEFAULT;
    magcal_swing_model_t m;
    int k;
    for (k = 0; k < 8; ++k) {
        pc[k] = (float)(eight[k] - 60.0 * sin(eight[k] * D2R));
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NOT_CONVERGED,
                          magcal_swing_fit(&cfg, pc, eight, NULL, 8u, MAGCAL_SWING_REG_REFERENCE, &m, NULL));
}

/*
 * 8-position swing on hard + soft iron (+ 2 deg misalignment) with no ellipse correction.
 * Truncation bound (docs/heading_models.md, "Truncation of the five-term model"): with
 * q = (s_yy - s_xx)/2 - i s_xy and beta = (b_y - i b_x)/H0 the deviation as a function of the
 * measured heading is, to second order,
 *   delta(psi_c) = [Smith terms] - 1/2 Im( q beta e^{-3i psi_c} + q^2 e^{-4i psi_c} ) + O(eps^3)
 * so the truncated harmonics have amplitude <= |q| (|q| + |beta|) / 2. In psi_ref the same
 * second-order terms are |q beta| + |q|^2/2. The bound used: 1.5 x the second-order amplitude
 * (the 8 psi_c regressors are not equally spaced, so some truncated content leaks into the
 * fitted coefficients; measured <= 1.14 x over 4000 random distortions) + (|q| + |beta|)^3.
 */
static void check_truncation(const dist_t *dp, const char *name)
{
    const dist_t d = *dp;
    float pc[8], pr[8];
    magcal_swing_cfg_t cfg = MAGCAL_SWING_CFG_DEFAULT;
    magcal_swing_model_t m_c, m_r, m_naive;
    double q, bt, e, b_c, b_r, after_c, after_r, after_naive, before;
    int k;
    q = hypot((d.syy - d.sxx) / 2.0, d.sxy);
    bt = hypot(d.bx, d.by);
    e = q + bt;
    b_c = (1.5 * 0.5 * q * e + e * e * e) / D2R;
    b_r = (1.5 * (q * bt + 0.5 * q * q) + e * e * e) / D2R;
    for (k = 0; k < 8; ++k) { /* device placed at the 8 reference headings */
        pr[k] = (float)(45.0 * k);
        pc[k] = (float)dist_psi_c(&d, 45.0 * k);
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK,
                          magcal_swing_fit(&cfg, pc, pr, NULL, 8u, MAGCAL_SWING_REG_MEASURED, &m_c, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK,
                          magcal_swing_fit(&cfg, pc, pr, NULL, 8u, MAGCAL_SWING_REG_REFERENCE, &m_r, NULL));
    dense_errors(&d, &m_c, &after_c, &before);
    dense_errors(&d, &m_r, &after_r, &before);
    m_naive = m_r; /* reference-regressor coefficients mistaken for a psi_c model */
    m_naive.regressor = MAGCAL_SWING_REG_MEASURED;
    dense_errors(&d, &m_naive, &after_naive, &before);
    printf("swing 8-pos (%s): before %.3f deg; LS in psi_c %.4f (2nd-order %.4f, bound %.4f); "
           "psi_ref+inversion %.4f (bound %.4f); naive %.4f deg\n",
           name, before, after_c, 0.5 * q * e / D2R, b_c, after_r, b_r, after_naive);
    TEST_ASSERT_TRUE(before > 4.0);
    TEST_ASSERT_TRUE(after_c <= b_c);
    TEST_ASSERT_TRUE(after_r <= b_r);
    /* the residual IS the truncation: at least half the second-order amplitude */
    TEST_ASSERT_TRUE(after_c >= 0.5 * 0.5 * q * e / D2R);
    /* same ordering as algorithms.md 5.1 (0.087 / 0.142 / 0.196 deg there) */
    TEST_ASSERT_TRUE(after_c < after_r);
    TEST_ASSERT_TRUE(after_r < after_naive);
    /* first-order meaning: A = -alpha, B = b_y/H0, C = b_x/H0, D = (s_yy - s_xx)/2, E = s_xy
     * (rad -> deg), with a second-order tolerance 2 eps^2 */
    TEST_ASSERT_FLOAT_WITHIN((float)(2.0 * e * e / D2R), (float)-d.alpha_deg, m_c.coef_deg[0]);
    TEST_ASSERT_FLOAT_WITHIN((float)(2.0 * e * e / D2R), (float)(d.by / D2R), m_c.coef_deg[1]);
    TEST_ASSERT_FLOAT_WITHIN((float)(2.0 * e * e / D2R), (float)(d.bx / D2R), m_c.coef_deg[2]);
    TEST_ASSERT_FLOAT_WITHIN((float)(2.0 * e * e / D2R), (float)((d.syy - d.sxx) / 2.0 / D2R), m_c.coef_deg[3]);
    TEST_ASSERT_FLOAT_WITHIN((float)(2.0 * e * e / D2R), (float)(d.sxy / D2R), m_c.coef_deg[4]);
}

static void test_swing_fit_8pos_hard_soft_iron_residual_within_truncation_bound(void)
{
    /* alg. 5.1 setting: 2 deg misalignment, 3 % soft iron, hard iron 0.05 H0 (directions are
     * not given there): (a) rank-one 3 % along 30 deg, b at 70 deg; (b) shear +/-3 % along
     * 10 deg, b at 70 deg, misalignment -2 deg. */
    const double u0 = cos(30.0 * D2R), u1 = sin(30.0 * D2R);
    const double v0 = cos(10.0 * D2R), v1 = sin(10.0 * D2R);
    dist_t d;
    d.alpha_deg = 2.0;
    d.sxx = 0.03 * u0 * u0;
    d.sxy = 0.03 * u0 * u1;
    d.syy = 0.03 * u1 * u1;
    d.bx = 0.05 * cos(70.0 * D2R);
    d.by = 0.05 * sin(70.0 * D2R);
    check_truncation(&d, "rank-one 3%");
    d.alpha_deg = -2.0; /* S = 0.03 (v v^T - w w^T), w = v rotated by 90 deg */
    d.sxx = 0.03 * (v0 * v0 - v1 * v1);
    d.sxy = 0.03 * (2.0 * v0 * v1);
    d.syy = 0.03 * (v1 * v1 - v0 * v0);
    check_truncation(&d, "shear +/-3%");
}


/* Heading of raw sample through a 2-D calibration (magcal_correct_apply + heading_from_field). */
static double cal_heading(const magcal_cal2d_t *c, magcal_vec2_t raw)
{
    magcal_vec2_t h;
    float deg = 0.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_correct_apply(c, raw, &h));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_heading_from_field(h, &deg));
    return deg;
}

/*
 * Ellipse + swing. Truth: Hm = P R(-3 deg) H + b + n, i.e. the sensor is mounted rotated by
 * 3 deg, soft iron P (axes 1.10 and 0.92 along 25 deg), hard iron b = (12, -7) uT, H0 = 20 uT,
 * noise sigma = 0.1 uT per axis (0.29 deg per sample). The symmetric ellipse correction cannot see
 * the rotation (algorithms.md 1.3) and leaves a 3 deg bias; an 8-position swing on the corrected
 * headings (20 samples averaged per position) removes it through A.
 * Floor: heading RMS of the same noisy test samples through the TRUE inverse (alg. 9).
 * Requirement: ellipse + swing RMS <= 1.2 x floor.
 */
static void test_swing_ellipse_plus_swing_removes_mounting_rotation_to_floor(void)
{
    const double a = -3.0 * D2R, pa = 25.0 * D2R, k1 = 1.10, k2 = 0.92;
    double p[2][2], t[2][2], ti[2][2], det;
    test_distortion_t d;
    static magcal_vec2_t ring[360];
    magcal_ellipse_t e;
    magcal_cal2d_t cal, truth_cal;
    magcal_swing_cfg_t cfg = MAGCAL_SWING_CFG_DEFAULT;
    magcal_swing_model_t sw;
    float pc[8], pr[8];
    uint32_t rng = 4242u;
    double s_floor = 0.0, s_ell = 0.0, s_sw = 0.0, bias_ell = 0.0;
    int i, j, k;
    const int ntest = 1440;
    /* P = R(pa) diag(k1, k2) R(pa)^T, T = P R(a) */
    p[0][0] = k1 * cos(pa) * cos(pa) + k2 * sin(pa) * sin(pa);
    p[0][1] = (k1 - k2) * cos(pa) * sin(pa);
    p[1][0] = p[0][1];
    p[1][1] = k1 * sin(pa) * sin(pa) + k2 * cos(pa) * cos(pa);
    for (i = 0; i < 2; ++i) {
        t[i][0] = p[i][0] * cos(a) + p[i][1] * sin(a);
        t[i][1] = -p[i][0] * sin(a) + p[i][1] * cos(a);
    }
    det = t[0][0] * t[1][1] - t[0][1] * t[1][0];
    ti[0][0] = t[1][1] / det;
    ti[0][1] = -t[0][1] / det;
    ti[1][0] = -t[1][0] / det;
    ti[1][1] = t[0][0] / det;
    d.h0 = 20.0f;
    d.bx = 12.0f;
    d.by = -7.0f;
    truth_cal = (magcal_cal2d_t)MAGCAL_CAL2D_IDENTITY;
    truth_cal.offset.x = 12.0f;
    truth_cal.offset.y = -7.0f;
    for (i = 0; i < 2; ++i) {
        for (j = 0; j < 2; ++j) {
            d.t[i][j] = (float)t[i][j];
            truth_cal.m[i][j] = (float)ti[i][j];
        }
    }
    /* calibration turn: 360 noisy samples */
    test_make_ring(&d, 360u, 0.0, 360.0, 0.1, 77u, ring, NULL);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_fit(ring, 360u, NULL, &e));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_to_cal(&e, MAGCAL_CORR_SYMMETRIC, 0.0f, &cal));
    /* 8-position swing on the corrected headings: average 20 corrected vectors per position */
    for (k = 0; k < 8; ++k) {
        double sx = 0.0, sy = 0.0;
        magcal_vec2_t h, mean;
        float deg = 0.0f;
        for (i = 0; i < 20; ++i) {
            TEST_ASSERT_EQUAL_INT(MAGCAL_OK,
                                  magcal_correct_apply(&cal, test_distorted_sample(&d, 45.0 * k, 0.1, &rng), &h));
            sx += h.x;
            sy += h.y;
        }
        mean.x = (float)(sx / 20.0);
        mean.y = (float)(sy / 20.0);
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_heading_from_field(mean, &deg));
        pc[k] = deg;
        pr[k] = (float)(45.0 * k);
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK,
                          magcal_swing_fit(&cfg, pc, pr, NULL, 8u, MAGCAL_SWING_REG_MEASURED, &sw, NULL));
    /* independent test samples at 1440 headings */
    for (i = 0; i < ntest; ++i) {
        double psi = 0.25 * i + 0.1;
        magcal_vec2_t raw = test_distorted_sample(&d, psi, 0.1, &rng);
        double h_ell = cal_heading(&cal, raw);
        float h_sw = 0.0f;
        double e_ell = test_angle_diff_deg(h_ell, psi);
        double e_fl = test_angle_diff_deg(cal_heading(&truth_cal, raw), psi);
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_swing_apply(&sw, (float)h_ell, &h_sw));
        s_floor += e_fl * e_fl;
        s_ell += e_ell * e_ell;
        bias_ell += e_ell;
        e_ell = test_angle_diff_deg(h_sw, psi);
        s_sw += e_ell * e_ell;
    }
    s_floor = sqrt(s_floor / ntest);
    s_ell = sqrt(s_ell / ntest);
    s_sw = sqrt(s_sw / ntest);
    bias_ell /= ntest;
    printf("ellipse+swing: floor RMS %.3f deg; ellipse only RMS %.3f (bias %.3f) deg; "
           "ellipse+swing RMS %.3f deg = %.3f x floor; A = %.3f deg\n",
           s_floor, s_ell, bias_ell, s_sw, s_sw / s_floor, sw.coef_deg[0]);
    TEST_ASSERT_FLOAT_WITHIN(0.3f, 3.0f, (float)fabs(bias_ell)); /* the invisible rotation */
    TEST_ASSERT_TRUE(s_ell > 2.5);
    TEST_ASSERT_FLOAT_WITHIN(0.3f, (float)-bias_ell, sw.coef_deg[0]);
    TEST_ASSERT_TRUE(s_sw <= 1.2 * s_floor);
}

/* ----------------------------------------------------------------------------------------- */
/* Motion swing */

/* Compass heading for true magnetic heading psi under a Smith model in psi_c:
 * solve psi_c + delta(psi_c) = psi by Newton (double). */
static double smith_inverse(const double c[5], double psi)
{
    double x = psi;
    int it;
    for (it = 0; it < 30; ++it) {
        double p = x * D2R;
        double f = x + smith(c, x) - psi;
        double df = 1.0 + D2R * (c[1] * cos(p) - c[2] * sin(p) + 2 * c[3] * cos(2 * p) -
                                 2 * c[4] * sin(2 * p));
        x -= f / df;
    }
    return fmod(x + 720.0, 360.0);
}

static void test_swing_cog_drive_recovers_coefficients_and_rejects_turns(void)
{
    /* 12 straight legs of 40 s at 1 Hz, 15 m/s, turns at 12 deg/s between them, a stop at 0.5 m/s
     * with random COG, and a gentle 2 deg/s curve. COG noise 0.5 deg, compass noise 0.3 deg,
     * declination +3.5 deg. Expected coefficient error: per-leg mean of ~36 epochs has
     * sigma ~0.1 deg, 12 legs give ~0.04 deg on B..E: tolerance 0.25 deg. */
    static const double truth[5] = {1.2, 3.5, -2.5, 0.9, -0.7};
    static const double legs[12] = {10, 42, 75, 103, 138, 171, 199, 232, 262, 291, 318, 347};
    const double decl = 3.5;
    magcal_swing_cog_cfg_t cfg = MAGCAL_SWING_COG_CFG_DEFAULT;
    magcal_swing_cog_t acc;
    magcal_swing_model_t m;
    magcal_swing_stats_t st;
    uint32_t rng = 2024u;
    double t = 0.0, hdg = legs[0];
    size_t nbins = 0u, nlegs = 0u;
    int turning_acc = 0, slow_acc = 0, straight_ok = 0;
    int l, k;
    magcal_swing_epoch_t ep;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_swing_cog_init(&acc, &cfg));
    for (l = 0; l < 12; ++l) {
        double target = legs[l];
        /* turn to the leg heading at 12 deg/s (COG rate far above the 3 deg/s gate) */
        while (fabs(test_angle_diff_deg(target, hdg)) > 12.0) {
            hdg = fmod(hdg + 12.0 + 360.0, 360.0);
            t += 1.0;
            ep.time_s = (float)t;
            ep.cog_deg = (float)fmod(hdg + decl + 0.5 * test_rand_normal(&rng) + 360.0, 360.0);
            ep.psi_c_deg = (float)smith_inverse(truth, hdg);
            ep.speed_mps = 15.0f;
            ep.decl_deg = (float)decl;
            if (magcal_swing_cog_add(&acc, &ep) == MAGCAL_OK) {
                ++turning_acc;
            }
        }
        hdg = target;
        for (k = 0; k < 40; ++k) {
            magcal_status_t s;
            t += 1.0;
            ep.time_s = (float)t;
            ep.cog_deg = (float)fmod(hdg + decl + 0.5 * test_rand_normal(&rng) + 360.0, 360.0);
            ep.psi_c_deg = (float)fmod(smith_inverse(truth, hdg) + 0.3 * test_rand_normal(&rng) + 360.0, 360.0);
            ep.speed_mps = (float)(15.0 + 0.3 * test_rand_normal(&rng));
            ep.decl_deg = (float)decl;
            s = magcal_swing_cog_add(&acc, &ep);
            straight_ok += (s == MAGCAL_OK);
        }
        if (l == 5) { /* a stop: slow, COG meaningless */
            for (k = 0; k < 20; ++k) {
                t += 1.0;
                ep.time_s = (float)t;
                ep.cog_deg = (float)(360.0 * test_rand_uniform(&rng));
                ep.psi_c_deg = (float)smith_inverse(truth, hdg);
                ep.speed_mps = 0.5f;
                if (magcal_swing_cog_add(&acc, &ep) == MAGCAL_OK) {
                    ++slow_acc;
                }
            }
        }
        if (l == 8) { /* gentle curve, 2 deg/s for 20 s (each step passes the rate gate) */
            for (k = 0; k < 20; ++k) {
                hdg += 2.0;
                t += 1.0;
                ep.time_s = (float)t;
                ep.cog_deg = (float)fmod(hdg + decl + 360.0, 360.0);
                ep.psi_c_deg = (float)smith_inverse(truth, hdg);
                ep.speed_mps = 15.0f;
                (void)magcal_swing_cog_add(&acc, &ep);
            }
        }
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_swing_cog_flush(&acc));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_swing_cog_count(&acc, &nbins, &nlegs));
    TEST_ASSERT_EQUAL_INT(0, turning_acc); /* every turning epoch rejected */
    TEST_ASSERT_EQUAL_INT(0, slow_acc);    /* every slow epoch rejected */
    TEST_ASSERT_TRUE(straight_ok >= 12 * 30); /* >= 30 of 40 epochs per leg kept (trim + noise) */
    TEST_ASSERT_EQUAL_UINT32(12u, (uint32_t)nlegs);     /* the curve's pieces are shorter than 10 s */
    TEST_ASSERT_EQUAL_UINT32(12u, (uint32_t)nbins);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_swing_cog_fit(&acc, &m, &st));
    printf("cog swing: coef err A..E = %.3f %.3f %.3f %.3f %.3f deg, residual rms %.3f deg\n",
           m.coef_deg[0] - truth[0], m.coef_deg[1] - truth[1], m.coef_deg[2] - truth[2],
           m.coef_deg[3] - truth[3], m.coef_deg[4] - truth[4], st.rms_deg);
    for (k = 0; k < 5; ++k) {
        TEST_ASSERT_FLOAT_WITHIN(0.25f, (float)truth[k], m.coef_deg[k]);
    }
}

static void test_swing_cog_marked_directions_fit_and_gates(void)
{
    /* Known marked directions (e.g. a compass rose) through add_pair; too few bins first. */
    static const double truth[5] = {-0.8, 2.0, 1.0, -0.5, 0.4};
    magcal_swing_cog_cfg_t cfg = MAGCAL_SWING_COG_CFG_DEFAULT;
    magcal_swing_cog_t acc;
    magcal_swing_model_t m;
    int k;
    memset(&acc, 0, sizeof acc);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NOT_INITIALISED, magcal_swing_cog_fit(&acc, &m, NULL));
    cfg.min_bins = 4u;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_swing_cog_init(&acc, &cfg));
    cfg.min_bins = 6u;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_swing_cog_init(&acc, &cfg));
    for (k = 0; k < 8; ++k) {
        double psi = 45.0 * k + 5.0;
        double pc = smith_inverse(truth, psi);
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_swing_cog_add_pair(&acc, (float)pc, (float)psi, 1.0f));
        if (k == 4) {
            TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_TOO_FEW_POINTS, magcal_swing_cog_fit(&acc, &m, NULL));
        }
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_swing_cog_add_pair(&acc, 1.0f, 2.0f, 0.0f));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_swing_cog_add_pair(&acc, NAN, 2.0f, 1.0f));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_swing_cog_fit(&acc, &m, NULL));
    for (k = 0; k < 5; ++k) {
        TEST_ASSERT_FLOAT_WITHIN(1e-3f, (float)truth[k], m.coef_deg[k]);
    }
}


static void test_swing_cog_table_has_36_bins_and_merges_within_a_bin(void)
{
    /* One pair per 10-deg bin fills MAGCAL_SWING_COG_BINS bins; two pairs in one bin merge into
     * their weighted mean (psi_c 101 w1 and 107 w3 -> 105.5, delta 1 and 3 -> 2.5). */
    magcal_swing_cog_cfg_t cfg = MAGCAL_SWING_COG_CFG_DEFAULT;
    magcal_swing_cog_t acc;
    magcal_swing_model_t m;
    magcal_swing_epoch_t ep = {0.0f, 10.0f, 10.0f, 10.0f, 0.0f};
    size_t nb = 0u, nl = 0u;
    float d = 0.0f;
    int k;
    TEST_ASSERT_EQUAL_UINT32(36u, MAGCAL_SWING_COG_BINS);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_swing_cog_init(&acc, &cfg));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_swing_cog_add_pair(&acc, 101.0f, 102.0f, 1.0f));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_swing_cog_add_pair(&acc, 107.0f, 110.0f, 3.0f));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_swing_cog_count(&acc, &nb, &nl));
    TEST_ASSERT_EQUAL_UINT32(1u, (uint32_t)nb);
    TEST_ASSERT_EQUAL_UINT32(0u, (uint32_t)nl); /* pairs are not legs */
    TEST_ASSERT_FLOAT_WITHIN(1e-4f, 0.5f, acc.bins[10].psi_c_off_deg); /* centre 105 */
    TEST_ASSERT_FLOAT_WITHIN(1e-4f, 2.5f, acc.bins[10].delta_deg);
    for (k = 0; k < 36; ++k) {
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_swing_cog_add_pair(&acc, 10.0f * k + 5.0f, 10.0f * k + 5.0f + 2.5f, 1.0f));
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_swing_cog_count(&acc, &nb, &nl));
    TEST_ASSERT_EQUAL_UINT32(36u, (uint32_t)nb);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_swing_cog_fit(&acc, &m, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_swing_deviation(&m, 200.0f, &d));
    TEST_ASSERT_FLOAT_WITHIN(1e-3f, 2.5f, d); /* constant deviation everywhere */
    /* epochs: NaN closes the leg and is reported; uninitialised accumulator refused */
    ep.cog_deg = NAN;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_swing_cog_add(&acc, &ep));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_swing_cog_add(&acc, NULL));
    memset(&acc, 0, sizeof acc);
    ep.cog_deg = 10.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NOT_INITIALISED, magcal_swing_cog_add(&acc, &ep));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NOT_INITIALISED, magcal_swing_cog_flush(&acc));
}

/* magcal_swing_cog_fit reads the occupied bins in place (issue 14: no copy on its stack); it must
 * give bit for bit what magcal_swing_fit gives on those bins copied out (bin centre + mean offset,
 * psi_ref = psi_c + mean deviation, unweighted), with empty bins in between and across north. */
static void test_swing_cog_fit_equals_fit_on_the_bins_copied_out(void)
{
    static const double truth[5] = {1.3, -2.1, 0.7, 0.45, -0.35};
    const float bin_w = 360.0f / (float)MAGCAL_SWING_COG_BINS;
    magcal_swing_cog_cfg_t cfg = MAGCAL_SWING_COG_CFG_DEFAULT;
    magcal_swing_cog_t acc;
    magcal_swing_model_t m1;
    magcal_swing_model_t m2;
    magcal_swing_stats_t s1;
    magcal_swing_stats_t s2;
    float pc[MAGCAL_SWING_COG_BINS];
    float pr[MAGCAL_SWING_COG_BINS];
    size_t n = 0u;
    size_t i;
    int k;
    uint32_t rng = 11u;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_swing_cog_init(&acc, &cfg));
    for (k = 0; k < 40; ++k) { /* 23 deg steps: some bins twice, some empty; 0.05 deg noise */
        double psi = fmod(23.0 * k + 355.0, 360.0);
        double c = smith_inverse(truth, psi) + 0.05 * test_rand_normal(&rng);
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_swing_cog_add_pair(&acc, (float)c, (float)psi, 1.0f + 0.25f * (float)(k % 3)));
    }
    for (i = 0u; i < MAGCAL_SWING_COG_BINS; ++i) { /* the former implementation's copy */
        const magcal_swing_bin_t *b = &acc.bins[i];
        if (b->weight > 0.0f) {
            pc[n] = magcal_wrap360_deg(((float)i + 0.5f) * bin_w + b->psi_c_off_deg);
            pr[n] = magcal_wrap360_deg(pc[n] + b->delta_deg);
            ++n;
        }
    }
    TEST_ASSERT_TRUE(n >= 20u && n < MAGCAL_SWING_COG_BINS);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_swing_cog_fit(&acc, &m1, &s1));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_swing_fit(&cfg.fit, pc, pr, NULL, n, MAGCAL_SWING_REG_MEASURED, &m2, &s2));
    TEST_ASSERT_EQUAL_MEMORY(m2.coef_deg, m1.coef_deg, sizeof m1.coef_deg);
    TEST_ASSERT_EQUAL_INT(m2.regressor, m1.regressor);
    TEST_ASSERT_EQUAL_UINT8(m2.iterations, m1.iterations);
    TEST_ASSERT_EQUAL_MEMORY(&s2.rms_deg, &s1.rms_deg, sizeof s1.rms_deg);
    TEST_ASSERT_EQUAL_MEMORY(&s2.max_abs_deg, &s1.max_abs_deg, sizeof s1.max_abs_deg);
    TEST_ASSERT_EQUAL_MEMORY(&s2.min_spread_pivot, &s1.min_spread_pivot, sizeof s1.min_spread_pivot);
    TEST_ASSERT_EQUAL_UINT32((uint32_t)n, (uint32_t)s1.n_used);
    for (k = 0; k < 5; ++k) { /* and it is the truth, to the noise */
        TEST_ASSERT_FLOAT_WITHIN(0.05f, (float)truth[k], m1.coef_deg[k]);
    }
}

/* The compass-swing article's sign: error e = measured - true = A + B sin psi_c + ... (its
 * formula (3), regressor the measured heading, 8 positions). A set in that sign loads with
 * magcal_swing_model_from_error and gives back the truth; fitted models export to it. */
static void test_swing_model_from_error_loads_documents_sign(void)
{
    static const float err_doc[5] = {1.5f, -2.0f, 3.2f, 0.8f, -0.6f}; /* e = psi_c - psi_true */
    const double e_d[5] = {1.5, -2.0, 3.2, 0.8, -0.6};
    float psi_c[8], psi_ref[8], back[5];
    magcal_swing_cfg_t cfg = MAGCAL_SWING_CFG_DEFAULT;
    magcal_swing_model_t fitted, loaded, naive;
    double worst_loaded = 0.0, worst_naive = 0.0;
    int k;
    for (k = 0; k < 8; ++k) {
        psi_c[k] = (float)(45.0 * k); /* the article steers to equally spaced MEASURED headings */
        psi_ref[k] = (float)(45.0 * k - smith(e_d, 45.0 * k));
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_swing_fit(&cfg, psi_c, psi_ref, NULL, 8u,
                                                      MAGCAL_SWING_REG_MEASURED, &fitted, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_swing_model_to_error(&fitted, back));
    for (k = 0; k < 5; ++k) {
        TEST_ASSERT_FLOAT_WITHIN(1e-4f, err_doc[k], back[k]);       /* export = document's set */
        TEST_ASSERT_FLOAT_WITHIN(1e-4f, -err_doc[k], fitted.coef_deg[k]); /* delta = -e */
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_swing_model_from_error(err_doc, MAGCAL_SWING_REG_MEASURED,
                                                                   5u, &loaded));
    naive = loaded;
    for (k = 0; k < 5; ++k) {
        naive.coef_deg[k] = err_doc[k]; /* loading the document's numbers without the sign */
    }
    for (k = 0; k < 72; ++k) {
        double truth = 5.0 * k; /* psi_c is the measured heading at truth */
        double pc = truth, dpsi;
        float out;
        int it;
        for (it = 0; it < 50; ++it) {
            pc = truth + smith(e_d, pc); /* psi_c = truth + e(psi_c) */
        }
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_swing_apply(&loaded, (float)pc, &out));
        dpsi = fabs(test_angle_diff_deg(out, truth));
        worst_loaded = dpsi > worst_loaded ? dpsi : worst_loaded;
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_swing_apply(&naive, (float)pc, &out));
        dpsi = fabs(test_angle_diff_deg(out, truth));
        worst_naive = dpsi > worst_naive ? dpsi : worst_naive;
    }
    printf("documents' A..E loaded: max heading error %.2e deg; without the sign flip %.2f deg\n",
           worst_loaded, worst_naive);
    TEST_ASSERT_TRUE(worst_loaded < 1e-3);
    TEST_ASSERT_TRUE(worst_naive > 5.0); /* the mistake doubles the deviation instead */
}

static void test_swing_model_from_error_bad_input_returns_status(void)
{
    float c[5] = {0.0f, 1.0f, 0.0f, 0.0f, 0.0f};
    float big[5] = {0.0f, 40.0f, 20.0f, 0.0f, 0.0f}; /* slope bound 60 deg = 1.05 rad >= 0.9 */
    magcal_swing_model_t m;
    float out[5];
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_swing_model_from_error(NULL, MAGCAL_SWING_REG_MEASURED, 5u, &m));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_swing_model_from_error(c, MAGCAL_SWING_REG_MEASURED, 5u, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_swing_model_from_error(c, (magcal_swing_regressor_t)9, 5u, &m));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_swing_model_from_error(c, MAGCAL_SWING_REG_REFERENCE, 0u, &m));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NOT_CONVERGED,
                          magcal_swing_model_from_error(big, MAGCAL_SWING_REG_REFERENCE, 5u, &m));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_swing_model_from_error(c, MAGCAL_SWING_REG_REFERENCE, 5u, &m));
    TEST_ASSERT_EQUAL_FLOAT(-1.0f, m.coef_deg[1]);
    c[2] = NAN;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_swing_model_from_error(c, MAGCAL_SWING_REG_MEASURED, 5u, &m));
    m.coef_deg[0] = INFINITY;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_swing_model_to_error(&m, out));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_swing_model_to_error(NULL, out));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_swing_fit_8pos_equals_closed_form_coefficients);
    RUN_TEST(test_swing_fit_known_smith_model_recovers_coefficients);
    RUN_TEST(test_swing_fit_wraps_deviation_across_north);
    RUN_TEST(test_swing_fit_bad_spread_or_input_returns_status_untouched);
    RUN_TEST(test_swing_apply_reference_model_inverts_by_fixed_point);
    RUN_TEST(test_swing_fit_reference_model_too_steep_returns_not_converged);
    RUN_TEST(test_swing_fit_8pos_hard_soft_iron_residual_within_truncation_bound);
    RUN_TEST(test_swing_ellipse_plus_swing_removes_mounting_rotation_to_floor);
    RUN_TEST(test_swing_cog_drive_recovers_coefficients_and_rejects_turns);
    RUN_TEST(test_swing_cog_marked_directions_fit_and_gates);
    RUN_TEST(test_swing_cog_table_has_36_bins_and_merges_within_a_bin);
    RUN_TEST(test_swing_cog_fit_equals_fit_on_the_bins_copied_out);
    RUN_TEST(test_swing_model_from_error_loads_documents_sign);
    RUN_TEST(test_swing_model_from_error_bad_input_returns_status);
    return UNITY_END();
}
