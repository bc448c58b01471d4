/*
 * Tests of the ellipsoid fit (src/fit/ellipsoid.c) on synthetic data with known truth (double here).
 * Truth: m = W h + V + n, h = C_n^b B_ref, |B_ref| = F (algorithms.md 7.1/7.2).
 */
#include <math.h>
#include <stdio.h>
#include <stddef.h>
#include <string.h>

#include "magcal/ellipsoid.h"
#include "test_util.h"
#include "test_util3d.h"
#include "unity.h"

/* magcal_ellipsoid_fit's fixed scratch (the workspace-free fit: no per-sample storage) */
static magcal_ellipsoid_fit_scratch_t g_fit_scratch;

void setUp(void) {}
void tearDown(void) {}

#define PI_D 3.14159265358979323846
#define D2R (PI_D / 180.0)
#define NFIT 600
#define NOUT 30

/* Reference field (NED, uT): F = 48.37, inclination 65.5 deg, declination 3.4 deg. */
static const double B_NED[3] = {20.0, 1.2, 44.0};
static const double V_TRUE[3] = {18.0, -11.0, 27.0};

static magcal_vec3_t g_m[NFIT + NOUT];
static double g_att[NFIT][3]; /* roll, pitch, yaw (rad) */

/* Symmetric W (soft iron + scale only): then G_sym = W^-1 exactly and headings are comparable. */
static void make_w_sym(double w[3][3])
{
    static double si[3][3] = {{1.08, 0.04, -0.03}, {0.04, 0.95, 0.05}, {-0.03, 0.05, 1.03}};
    memcpy(w, si, sizeof(si));
}

static double f_ref(void)
{
    return sqrt(B_NED[0] * B_NED[0] + B_NED[1] * B_NED[1] + B_NED[2] * B_NED[2]);
}

static magcal_vec3_t sample(double w[3][3], const double v[3], const double att[3], double sigma, uint32_t *rng)
{
    double c[3][3], h[3], m[3];
    int i;
    magcal_vec3_t out;
    test_dcm_ned(att[0], att[1], att[2], c);
    for (i = 0; i < 3; ++i) { /* h = C^T B */
        h[i] = c[0][i] * B_NED[0] + c[1][i] * B_NED[1] + c[2][i] * B_NED[2];
    }
    for (i = 0; i < 3; ++i) {
        m[i] = w[i][0] * h[0] + w[i][1] * h[1] + w[i][2] * h[2] + v[i] + sigma * test_rand_normal(rng);
    }
    out.x = (float)m[0];
    out.y = (float)m[1];
    out.z = (float)m[2];
    return out;
}

/* Attitudes: yaw uniform, pitch and roll uniform in +-max (deg); max >= 180 gives full rotations. */
static void make_set(double w[3][3], size_t n, double max_pitch_deg, double max_roll_deg, double sigma,
                     uint32_t seed)
{
    uint32_t rng = seed;
    size_t k;
    for (k = 0; k < n; ++k) {
        g_att[k][2] = 2.0 * PI_D * test_rand_uniform(&rng);
        g_att[k][1] = (2.0 * test_rand_uniform(&rng) - 1.0) * max_pitch_deg * D2R;
        g_att[k][0] = (2.0 * test_rand_uniform(&rng) - 1.0) * max_roll_deg * D2R;
        if (max_pitch_deg >= 90.0) { /* uniform direction of the pitch axis */
            g_att[k][1] = asin(2.0 * test_rand_uniform(&rng) - 1.0);
        }
        g_m[k] = sample(w, V_TRUE, g_att[k], sigma, &rng);
    }
}

static double v_err(const magcal_ellipsoid_cal_t *cal)
{
    double dx = cal->v.x - V_TRUE[0], dy = cal->v.y - V_TRUE[1], dz = cal->v.z - V_TRUE[2];
    return sqrt(dx * dx + dy * dy + dz * dz);
}

/* Tilt-compensated magnetic heading (deg) of a calibrated body field h (algorithms.md 6). */
static double heading_deg(const double h[3], double roll, double pitch)
{
    double cf = cos(roll), sf = sin(roll), ct = cos(pitch), st = sin(pitch);
    double lx = h[0] * cf + h[2] * sf;
    double ly = h[1] * ct + st * (h[0] * sf - h[2] * cf);
    return atan2(-lx, ly) / D2R;
}

static double heading_rms(size_t n, double g[3][3], const double v[3])
{
    double decl = atan2(B_NED[1], B_NED[0]) / D2R, s = 0;
    size_t k;
    for (k = 0; k < n; ++k) {
        double e[3] = {g_m[k].x - v[0], g_m[k].y - v[1], g_m[k].z - v[2]}, h[3], d;
        int i;
        for (i = 0; i < 3; ++i) {
            h[i] = g[i][0] * e[0] + g[i][1] * e[1] + g[i][2] * e[2];
        }
        d = test_angle_diff_deg(heading_deg(h, g_att[k][0], g_att[k][1]), g_att[k][2] / D2R - decl);
        s += d * d;
    }
    return sqrt(s / (double)n);
}

static magcal_ellipsoid_cfg_t cfg_with_field(void)
{
    magcal_ellipsoid_cfg_t cfg = MAGCAL_ELLIPSOID_CFG_DEFAULT;
    cfg.field = (float)f_ref();
    return cfg;
}

static void test_ellipsoid_fit_random_attitudes_recovers_v_and_q(void)
{
    double w[3][3];
    magcal_ellipsoid_cfg_t cfg = cfg_with_field();
    magcal_ellipsoid_result_t r;
    test_make_w_full(w);
    make_set(w, NFIT, 180.0, 180.0, 0.05, 1234u);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipsoid_fit(g_m, NFIT, &cfg, &g_fit_scratch, &r));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ELLIPSOID_MODEL_QUADRIC9, r.model);
    /* algorithms.md 7.2 (double): 0.001 uT and 1.5e-4; float32 + 3-sigma clipping: 0.02 uT, 1e-3. */
    TEST_ASSERT_TRUE(v_err(&r.cal) < 0.02);
    TEST_ASSERT_TRUE(test_q_err(&r.cal, w) < 1e-3);
    TEST_ASSERT_FLOAT_WITHIN(1e-3f, (float)f_ref(), r.cal.field);
    TEST_ASSERT_TRUE(r.coverage > 0.9f);
    /* Noise 0.05 uT through G (|G| ~ 1): residual RMS near 0.05. */
    TEST_ASSERT_FLOAT_WITHIN(0.02f, 0.05f, r.residual_rms);
    TEST_ASSERT_TRUE(r.n_rejected <= 6u); /* 3-sigma clipping of Gaussian noise: ~0.3 % */
}

static void test_ellipsoid_fit_quadric10_matches_quadric9(void)
{
    double w[3][3];
    magcal_ellipsoid_cfg_t cfg = cfg_with_field();
    magcal_ellipsoid_result_t r9, r10;
    int i, j;
    test_make_w_full(w);
    make_set(w, NFIT, 180.0, 180.0, 0.05, 777u);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipsoid_fit(g_m, NFIT, &cfg, &g_fit_scratch, &r9));
    cfg.model = MAGCAL_ELLIPSOID_MODEL_QUADRIC10;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipsoid_fit(g_m, NFIT, &cfg, &g_fit_scratch, &r10));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ELLIPSOID_MODEL_QUADRIC10, r10.model);
    TEST_ASSERT_TRUE(v_err(&r10.cal) < 0.02);
    TEST_ASSERT_TRUE(test_q_err(&r10.cal, w) < 1e-3);
    /* The two fits differ only in the normalisation constraint (algorithms.md: 2e-5 in double). */
    TEST_ASSERT_FLOAT_WITHIN(0.01f, r9.cal.v.x, r10.cal.v.x);
    TEST_ASSERT_FLOAT_WITHIN(0.01f, r9.cal.v.y, r10.cal.v.y);
    TEST_ASSERT_FLOAT_WITHIN(0.01f, r9.cal.v.z, r10.cal.v.z);
    for (i = 0; i < 3; ++i) {
        for (j = 0; j < 3; ++j) {
            TEST_ASSERT_FLOAT_WITHIN(5e-4f, r9.cal.g[i][j], r10.cal.g[i][j]);
        }
    }
}

static void test_ellipsoid_fit_sqrt_variants_satisfy_gtg_equals_q(void)
{
    double w[3][3], gw[3][3], gd[3][3];
    magcal_ellipsoid_cfg_t cfg = cfg_with_field();
    magcal_ellipsoid_result_t rs, rc;
    int i, j, k;
    test_make_w_full(w);
    make_set(w, NFIT, 180.0, 180.0, 0.05, 99u);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipsoid_fit(g_m, NFIT, &cfg, &g_fit_scratch, &rs));
    cfg.sqrt_method = MAGCAL_ELLIPSOID_SQRT_CHOLESKY;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipsoid_fit(g_m, NFIT, &cfg, &g_fit_scratch, &rc));
    /* symmetric root is symmetric, Cholesky root is upper triangular */
    TEST_ASSERT_FLOAT_WITHIN(1e-5f, rs.cal.g[0][1], rs.cal.g[1][0]);
    TEST_ASSERT_FLOAT_WITHIN(1e-5f, rs.cal.g[0][2], rs.cal.g[2][0]);
    TEST_ASSERT_FLOAT_WITHIN(1e-5f, rs.cal.g[1][2], rs.cal.g[2][1]);
    TEST_ASSERT_EQUAL_FLOAT(0.0f, rc.cal.g[1][0]);
    TEST_ASSERT_EQUAL_FLOAT(0.0f, rc.cal.g[2][0]);
    TEST_ASSERT_EQUAL_FLOAT(0.0f, rc.cal.g[2][1]);
    /* both give the same Q = G^T G */
    for (i = 0; i < 3; ++i) {
        for (j = 0; j < 3; ++j) {
            double qs = 0, qc = 0;
            for (k = 0; k < 3; ++k) {
                qs += (double)rs.cal.g[k][i] * rs.cal.g[k][j];
                qc += (double)rc.cal.g[k][i] * rc.cal.g[k][j];
            }
            TEST_ASSERT_FLOAT_WITHIN(2e-5f, (float)qs, (float)qc);
        }
    }
    /* G W is a rotation (W^-1 up to a left rotation): (GW)^T (GW) = I within 2e-3. */
    for (i = 0; i < 3; ++i) {
        for (j = 0; j < 3; ++j) {
            gd[i][j] = rs.cal.g[i][j];
        }
    }
    test_mat3_mul(gd, w, gw);
    for (i = 0; i < 3; ++i) {
        for (j = 0; j < 3; ++j) {
            double s = 0;
            for (k = 0; k < 3; ++k) {
                s += gw[k][i] * gw[k][j];
            }
            TEST_ASSERT_FLOAT_WITHIN(2e-3f, (i == j) ? 1.0f : 0.0f, (float)s);
        }
    }
}

static void test_ellipsoid_fit_tilted_headings_within_1p2_of_floor(void)
{
    double w[3][3], wi[3][3], g[3][3], v[3];
    magcal_ellipsoid_cfg_t cfg = cfg_with_field();
    magcal_ellipsoid_result_t r;
    double floor_rms, fit_rms;
    int i, j;
    make_w_sym(w);
    make_set(w, NFIT, 180.0, 180.0, 0.1, 4242u);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipsoid_fit(g_m, NFIT, &cfg, &g_fit_scratch, &r));
    /* evaluation set: |pitch|, |roll| <= 40 deg, same noise; floor = true calibration on it */
    make_set(w, NFIT, 40.0, 40.0, 0.1, 5151u);
    test_mat3_inv(w, wi);
    floor_rms = heading_rms(NFIT, wi, V_TRUE);
    for (i = 0; i < 3; ++i) {
        for (j = 0; j < 3; ++j) {
            g[i][j] = r.cal.g[i][j];
        }
    }
    v[0] = r.cal.v.x;
    v[1] = r.cal.v.y;
    v[2] = r.cal.v.z;
    fit_rms = heading_rms(NFIT, g, v);
    TEST_ASSERT_TRUE(floor_rms > 0.05 && floor_rms < 1.0); /* sanity of the floor itself */
    TEST_ASSERT_TRUE(fit_rms <= 1.2 * floor_rms);
}

static void test_ellipsoid_fit_outliers_rejected_by_residual_gate(void)
{
    double w[3][3];
    magcal_ellipsoid_cfg_t cfg = cfg_with_field();
    magcal_ellipsoid_result_t r, rn;
    uint32_t rng = 31337u;
    size_t k;
    test_make_w_full(w);
    make_set(w, NFIT, 180.0, 180.0, 0.05, 2024u);
    /* 5 % outliers: 5..20 uT spikes in random directions added to copies of good samples */
    for (k = 0; k < NOUT; ++k) {
        double mag = 5.0 + 15.0 * test_rand_uniform(&rng);
        double dx = test_rand_normal(&rng), dy = test_rand_normal(&rng), dz = test_rand_normal(&rng);
        double nn = sqrt(dx * dx + dy * dy + dz * dz);
        g_m[NFIT + k] = g_m[k * 17];
        g_m[NFIT + k].x += (float)(mag * dx / nn);
        g_m[NFIT + k].y += (float)(mag * dy / nn);
        g_m[NFIT + k].z += (float)(mag * dz / nn);
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipsoid_fit(g_m, NFIT + NOUT, &cfg, &g_fit_scratch, &r));
    cfg.outlier_k = 0.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipsoid_fit(g_m, NFIT + NOUT, &cfg, &g_fit_scratch, &rn));
    TEST_ASSERT_TRUE(v_err(&r.cal) < 0.03);
    TEST_ASSERT_TRUE(test_q_err(&r.cal, w) < 1.5e-3);
    TEST_ASSERT_TRUE(r.n_rejected >= NOUT && r.n_rejected <= NOUT + 10);
    /* without the gate the same data give a clearly worse fit */
    TEST_ASSERT_EQUAL_UINT32(0u, (uint32_t)rn.n_rejected);
    TEST_ASSERT_TRUE(v_err(&rn.cal) > 5.0 * v_err(&r.cal));
}

static void test_ellipsoid_fit_rejections_above_limit_return_too_many_outliers(void)
{
    /* every 10th sample shifted by 10 uT (10 %): rejecting them exceeds a 5 % limit */
    double w[3][3];
    magcal_ellipsoid_cfg_t cfg = cfg_with_field();
    magcal_ellipsoid_result_t r;
    size_t k;
    test_make_w_full(w);
    make_set(w, NFIT, 180.0, 180.0, 0.05, 606u);
    for (k = 0; k < NFIT; k += 10) {
        g_m[k].x += 10.0f;
    }
    cfg.max_reject_frac = 0.05f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_TOO_MANY_OUTLIERS, magcal_ellipsoid_fit(g_m, NFIT, &cfg, &g_fit_scratch, &r));
    cfg.max_reject_frac = 0.25f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipsoid_fit(g_m, NFIT, &cfg, &g_fit_scratch, &r));
    /* a shift nearly tangent to the sphere barely changes |h|: 58 of the 60 are caught */
    TEST_ASSERT_TRUE(r.n_rejected >= NFIT / 10 - 4 && r.n_rejected <= NFIT / 10 + 6);
    TEST_ASSERT_TRUE(v_err(&r.cal) < 0.03);
}

static void test_ellipsoid_fit_poor_coverage_falls_back_to_sphere(void)
{
    /* hard iron only (W = 0.9 I), tilts limited to +-20 deg: only a band of directions */
    static double w[3][3] = {{0.9, 0, 0}, {0, 0.9, 0}, {0, 0, 0.9}};
    magcal_ellipsoid_cfg_t cfg = cfg_with_field();
    magcal_ellipsoid_result_t r;
    make_set(w, NFIT, 20.0, 20.0, 0.05, 55u);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipsoid_fit(g_m, NFIT, &cfg, &g_fit_scratch, &r));
    TEST_ASSERT_TRUE(r.coverage >= cfg.min_coverage_sphere && r.coverage < cfg.min_coverage_full);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ELLIPSOID_MODEL_SPHERE, r.model);
    TEST_ASSERT_TRUE(v_err(&r.cal) < 0.1);
    TEST_ASSERT_FLOAT_WITHIN(1e-3f, 1.0f / 0.9f, r.cal.g[0][0]);
    TEST_ASSERT_EQUAL_FLOAT(0.0f, r.cal.g[0][1]);
}

static void test_ellipsoid_fit_level_ring_every_model_returns_single_axis(void)
{
    /* Level yaw-only: every direction in one cone (12 of 72 cells); no model is identifiable. With
     * noise the normal equations pass the (scale-free) pivot test: before the trust gates (issue 12)
     * an explicitly requested quadric returned a confident but wrong V (46.7 uT). Now AUTO and every
     * forced model say why: one rotation axis. */
    double w[3][3];
    magcal_ellipsoid_cfg_t cfg = cfg_with_field();
    magcal_ellipsoid_result_t r;
    test_make_w_full(w);
    make_set(w, NFIT, 0.0, 0.0, 0.05, 66u);
    memset(&r, 0xA5, sizeof(r));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_SINGLE_AXIS, magcal_ellipsoid_fit(g_m, NFIT, &cfg, &g_fit_scratch, &r));
    TEST_ASSERT_EQUAL_HEX8(0xA5, ((unsigned char *)&r)[0]); /* untouched on failure */
    cfg.model = MAGCAL_ELLIPSOID_MODEL_QUADRIC9;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_SINGLE_AXIS, magcal_ellipsoid_fit(g_m, NFIT, &cfg, &g_fit_scratch, &r));
    cfg.model = MAGCAL_ELLIPSOID_MODEL_QUADRIC10;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_SINGLE_AXIS, magcal_ellipsoid_fit(g_m, NFIT, &cfg, &g_fit_scratch, &r));
    cfg.model = MAGCAL_ELLIPSOID_MODEL_SPHERE;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_SINGLE_AXIS, magcal_ellipsoid_fit(g_m, NFIT, &cfg, &g_fit_scratch, &r));
    TEST_ASSERT_EQUAL_HEX8(0xA5, ((unsigned char *)&r)[0]);
    /* with the observability gates off the old failure is still there: the gates are what refuse */
    cfg.model = MAGCAL_ELLIPSOID_MODEL_QUADRIC9;
    cfg.max_centre_std_rel = 0.0f;
    cfg.max_shape_std = 0.0f;
    cfg.max_residual_rel = 0.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipsoid_fit(g_m, NFIT, &cfg, &g_fit_scratch, &r));
    TEST_ASSERT_TRUE(v_err(&r.cal) > 5.0);
}

static void test_ellipsoid_fit_hyperboloid_returns_not_ellipsoid(void)
{
    /* x^2 + y^2 - z^2 = 400: a hyperboloid of one sheet */
    magcal_ellipsoid_cfg_t cfg = MAGCAL_ELLIPSOID_CFG_DEFAULT;
    magcal_ellipsoid_result_t r;
    size_t k;
    for (k = 0; k < NFIT; ++k) {
        double t = 2.0 * PI_D * (double)k / 37.0;
        double z = -20.0 + 40.0 * (double)(k % 23) / 22.0;
        double rr = sqrt(400.0 + z * z);
        g_m[k].x = (float)(rr * cos(t) + 5.0);
        g_m[k].y = (float)(rr * sin(t) - 3.0);
        g_m[k].z = (float)z;
    }
    cfg.model = MAGCAL_ELLIPSOID_MODEL_QUADRIC9;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NOT_ELLIPSOID, magcal_ellipsoid_fit(g_m, NFIT, &cfg, &g_fit_scratch, &r));
    cfg.model = MAGCAL_ELLIPSOID_MODEL_QUADRIC10;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NOT_ELLIPSOID, magcal_ellipsoid_fit(g_m, NFIT, &cfg, &g_fit_scratch, &r));
}

static void test_ellipsoid_fit_unknown_field_gives_unit_determinant(void)
{
    double w[3][3];
    magcal_ellipsoid_cfg_t cfg = MAGCAL_ELLIPSOID_CFG_DEFAULT;
    magcal_ellipsoid_result_t r;
    double det, detw;
    test_make_w_full(w);
    make_set(w, NFIT, 180.0, 180.0, 0.05, 8u);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipsoid_fit(g_m, NFIT, &cfg, &g_fit_scratch, &r));
    det = (double)r.cal.g[0][0] * (r.cal.g[1][1] * r.cal.g[2][2] - r.cal.g[1][2] * r.cal.g[2][1]) -
          (double)r.cal.g[0][1] * (r.cal.g[1][0] * r.cal.g[2][2] - r.cal.g[1][2] * r.cal.g[2][0]) +
          (double)r.cal.g[0][2] * (r.cal.g[1][0] * r.cal.g[2][1] - r.cal.g[1][1] * r.cal.g[2][0]);
    TEST_ASSERT_FLOAT_WITHIN(1e-4f, 1.0f, (float)det);
    /* F = geometric mean radius = F_true * det(W)^(1/3) */
    detw = w[0][0] * (w[1][1] * w[2][2] - w[1][2] * w[2][1]) - w[0][1] * (w[1][0] * w[2][2] - w[1][2] * w[2][0]) +
           w[0][2] * (w[1][0] * w[2][1] - w[1][1] * w[2][0]);
    TEST_ASSERT_FLOAT_WITHIN(0.01f, (float)(f_ref() * cbrt(detw)), r.cal.field);
    TEST_ASSERT_TRUE(v_err(&r.cal) < 0.02);
}

static void test_ellipsoid_fit_bad_input_returns_status(void)
{
    magcal_ellipsoid_cfg_t cfg = MAGCAL_ELLIPSOID_CFG_DEFAULT;
    magcal_ellipsoid_result_t r;
    double w[3][3];
    size_t k;
    test_make_w_full(w);
    make_set(w, 100, 180.0, 180.0, 0.05, 3u);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_ellipsoid_fit(NULL, 100, &cfg, &g_fit_scratch, &r));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_ellipsoid_fit(g_m, 100, NULL, &g_fit_scratch, &r));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_ellipsoid_fit(g_m, 100, &cfg, &g_fit_scratch, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_TOO_FEW_POINTS, magcal_ellipsoid_fit(g_m, 3, &cfg, &g_fit_scratch, &r));
    cfg.model = MAGCAL_ELLIPSOID_MODEL_QUADRIC9;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_TOO_FEW_POINTS, magcal_ellipsoid_fit(g_m, 9, &cfg, &g_fit_scratch, &r));
    cfg.max_refits = 99u;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_ellipsoid_fit(g_m, 100, &cfg, &g_fit_scratch, &r));
    cfg.max_refits = 3u;
    cfg.min_coverage_full = 1.5f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_ellipsoid_fit(g_m, 100, &cfg, &g_fit_scratch, &r));
    cfg.min_coverage_full = 0.45f;
    cfg.field = -1.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_ellipsoid_fit(g_m, 100, &cfg, &g_fit_scratch, &r));
    cfg.field = 0.0f;
    cfg.model = (magcal_ellipsoid_model_t)7;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_ellipsoid_fit(g_m, 100, &cfg, &g_fit_scratch, &r));
    cfg.model = MAGCAL_ELLIPSOID_MODEL_AUTO;
    g_m[50].y = NAN;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_ellipsoid_fit(g_m, 100, &cfg, &g_fit_scratch, &r));
    for (k = 0; k < 100; ++k) {
        g_m[k].x = 3.0f;
        g_m[k].y = -2.0f;
        g_m[k].z = 1.0f;
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_DEGENERATE, magcal_ellipsoid_fit(g_m, 100, &cfg, &g_fit_scratch, &r));
}

/* Field magnitude errors of +-(15..40) % (7..19 uT on F = 48 uT) injected at every 20th index (30 of
 * 600): radial, so no gate geometry can miss them. Noise 0.05 uT; the gate floor is 0.005 F = 0.24 uT. */
#define OUT_STRIDE 20u
static void make_radial_outliers(double w[3][3], uint32_t seed)
{
    uint32_t rng = seed;
    size_t k;
    make_set(w, NFIT, 180.0, 180.0, 0.05, seed);
    for (k = 0; k < NFIT; k += OUT_STRIDE) {
        double f = 0.15 + 0.25 * test_rand_uniform(&rng);
        double sgn = ((k / OUT_STRIDE) % 2u == 0u) ? 1.0 : -1.0;
        g_m[k].x = (float)(V_TRUE[0] + (1.0 + sgn * f) * (g_m[k].x - V_TRUE[0]));
        g_m[k].y = (float)(V_TRUE[1] + (1.0 + sgn * f) * (g_m[k].y - V_TRUE[1]));
        g_m[k].z = (float)(V_TRUE[2] + (1.0 + sgn * f) * (g_m[k].z - V_TRUE[2]));
    }
}

static void test_ellipsoid_outliers_injected_indices_all_flagged(void)
{
    static uint8_t flag[NFIT];
    double w[3][3];
    magcal_ellipsoid_cfg_t cfg = cfg_with_field();
    magcal_ellipsoid_result_t r;
    size_t k, n_out = 0u, n_inj = 0u, n_false = 0u;
    double s2 = 0.0;
    test_make_w_full(w);
    make_radial_outliers(w, 2718u);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipsoid_fit(g_m, NFIT, &cfg, &g_fit_scratch, &r));
    TEST_ASSERT_TRUE(r.gate_thr > 0.0f);
    memset(flag, 0xA5, sizeof(flag));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipsoid_outliers(&r, g_m, NFIT, flag, &n_out));
    TEST_ASSERT_EQUAL_UINT32((uint32_t)r.n_rejected, (uint32_t)n_out); /* the fit's own count */
    for (k = 0; k < NFIT; ++k) {
        TEST_ASSERT_TRUE(flag[k] <= 1u);
        if (k % OUT_STRIDE == 0u) {
            TEST_ASSERT_EQUAL_UINT8(1u, flag[k]); /* every injected outlier */
            n_inj++;
        } else if (flag[k] != 0u) {
            n_false++;
        } else {
            double h[3], e[3] = {g_m[k].x - r.cal.v.x, g_m[k].y - r.cal.v.y, g_m[k].z - r.cal.v.z};
            int i;
            for (i = 0; i < 3; ++i) {
                h[i] = r.cal.g[i][0] * e[0] + r.cal.g[i][1] * e[1] + r.cal.g[i][2] * e[2];
            }
            e[0] = sqrt(h[0] * h[0] + h[1] * h[1] + h[2] * h[2]) - r.cal.field;
            s2 += e[0] * e[0];
        }
    }
    TEST_ASSERT_EQUAL_UINT32(NFIT / OUT_STRIDE, (uint32_t)n_inj);
    TEST_ASSERT_TRUE(n_false <= 2u); /* the gate is >= 4.8 sigma of the noise */
    /* the unflagged samples are the fit's kept set: their residual RMS is the reported one (1e-4 rel.) */
    TEST_ASSERT_FLOAT_WITHIN(1e-4f * r.residual_rms, r.residual_rms,
                             (float)sqrt(s2 / (double)(NFIT - n_out)));
    TEST_ASSERT_TRUE(v_err(&r.cal) < 0.03);
}

static void test_ellipsoid_outliers_tangent_shifts_count_equals_n_rejected(void)
{
    /* every 10th sample shifted 10 uT along +x (some nearly tangent): several refits, count must match */
    static uint8_t flag[NFIT];
    double w[3][3];
    magcal_ellipsoid_cfg_t cfg = cfg_with_field();
    magcal_ellipsoid_result_t r;
    size_t k, n_out = 0u, n_hit = 0u;
    test_make_w_full(w);
    make_set(w, NFIT, 180.0, 180.0, 0.05, 606u);
    for (k = 0; k < NFIT; k += 10) {
        g_m[k].x += 10.0f;
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipsoid_fit(g_m, NFIT, &cfg, &g_fit_scratch, &r));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipsoid_outliers(&r, g_m, NFIT, flag, &n_out));
    TEST_ASSERT_EQUAL_UINT32((uint32_t)r.n_rejected, (uint32_t)n_out);
    for (k = 0; k < NFIT; k += 10) {
        n_hit += flag[k];
    }
    TEST_ASSERT_TRUE(n_hit >= NFIT / 10 - 4); /* as the fit test: 58 of the 60 */
}

static void test_ellipsoid_outliers_borderline_errors_count_equals_n_rejected(void)
{
    /* Noise 0.2 uT (gate 3 x RMS ~ 0.6 uT above the floor) and +-1.9 uT magnitude errors on every
     * 10th sample: many samples sit near the gate, so a gate rebuilt from the final calibration
     * instead of the stored gate_cal disagrees with the fit's count (checked: it fails here, 39 vs
     * 38 on one of these seeds); the stored gate must agree on every seed. */
    static uint8_t flag[NFIT];
    double w[3][3];
    magcal_ellipsoid_cfg_t cfg = cfg_with_field();
    magcal_ellipsoid_result_t r;
    uint32_t seed;
    size_t k;
    test_make_w_full(w);
    for (seed = 1u; seed <= 8u; ++seed) {
        uint32_t rng = seed * 7919u;
        size_t n_out = 0u;
        make_set(w, NFIT, 180.0, 180.0, 0.2, seed * 104729u);
        for (k = 0; k < NFIT; k += 10) {
            double f = 1.0 + 0.08 * (test_rand_uniform(&rng) - 0.5);
            g_m[k].x = (float)(V_TRUE[0] + f * (g_m[k].x - V_TRUE[0]));
            g_m[k].y = (float)(V_TRUE[1] + f * (g_m[k].y - V_TRUE[1]));
            g_m[k].z = (float)(V_TRUE[2] + f * (g_m[k].z - V_TRUE[2]));
        }
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipsoid_fit(g_m, NFIT, &cfg, &g_fit_scratch, &r));
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipsoid_outliers(&r, g_m, NFIT, flag, &n_out));
        TEST_ASSERT_EQUAL_UINT32((uint32_t)r.n_rejected, (uint32_t)n_out);
    }
}

static void test_ellipsoid_outliers_clean_data_all_zero(void)
{
    static uint8_t flag[NFIT];
    double w[3][3];
    magcal_ellipsoid_cfg_t cfg = cfg_with_field();
    magcal_ellipsoid_result_t r;
    size_t k, n_out = 99u;
    test_make_w_full(w);
    make_set(w, NFIT, 180.0, 180.0, 0.05, 1234u);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipsoid_fit(g_m, NFIT, &cfg, &g_fit_scratch, &r));
    TEST_ASSERT_EQUAL_UINT32(0u, (uint32_t)r.n_rejected);
    memset(flag, 0xA5, sizeof(flag));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipsoid_outliers(&r, g_m, NFIT, flag, &n_out));
    TEST_ASSERT_EQUAL_UINT32(0u, (uint32_t)n_out);
    for (k = 0; k < NFIT; ++k) {
        TEST_ASSERT_EQUAL_UINT8(0u, flag[k]);
    }
    /* rejection disabled: no gate even with injected outliers (the residual and observability
     * gates refuse such a fit; switched off here to see the mask of a gate-free result) */
    make_radial_outliers(w, 2718u);
    cfg.outlier_k = 0.0f;
    cfg.max_residual_rel = 0.0f;
    cfg.max_centre_std_rel = 0.0f;
    cfg.max_shape_std = 0.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipsoid_fit(g_m, NFIT, &cfg, &g_fit_scratch, &r));
    TEST_ASSERT_EQUAL_FLOAT(0.0f, r.gate_thr);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipsoid_outliers(&r, g_m, NFIT, flag, &n_out));
    TEST_ASSERT_EQUAL_UINT32(0u, (uint32_t)n_out);
    TEST_ASSERT_EQUAL_UINT8(0u, flag[0]);
}

static void test_ellipsoid_outliers_bad_input_returns_status(void)
{
    static uint8_t flag[NFIT];
    double w[3][3];
    magcal_ellipsoid_cfg_t cfg = cfg_with_field();
    magcal_ellipsoid_result_t r, bad;
    size_t n_out = 77u;
    test_make_w_full(w);
    make_radial_outliers(w, 2718u);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipsoid_fit(g_m, NFIT, &cfg, &g_fit_scratch, &r));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL,
                          magcal_ellipsoid_outliers(NULL, g_m, NFIT, flag, &n_out));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_ellipsoid_outliers(&r, NULL, NFIT, flag, &n_out));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_ellipsoid_outliers(&r, g_m, NFIT, NULL, &n_out));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_ellipsoid_outliers(&r, g_m, NFIT, flag, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_TOO_FEW_POINTS,
                          magcal_ellipsoid_outliers(&r, g_m, 0u, flag, &n_out));
    bad = r;
    bad.gate_thr = NAN;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_ellipsoid_outliers(&bad, g_m, NFIT, flag, &n_out));
    bad.gate_thr = -1.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_ellipsoid_outliers(&bad, g_m, NFIT, flag, &n_out));
    bad = r;
    bad.gate_cal.g[1][2] = INFINITY;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_ellipsoid_outliers(&bad, g_m, NFIT, flag, &n_out));
    /* a NaN sample anywhere: outputs untouched */
    memset(flag, 0xA5, sizeof(flag));
    g_m[NFIT - 1].z = NAN;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE,
                          magcal_ellipsoid_outliers(&r, g_m, NFIT, flag, &n_out));
    TEST_ASSERT_EQUAL_HEX8(0xA5, flag[0]);
    TEST_ASSERT_EQUAL_UINT32(77u, (uint32_t)n_out);
}

static void test_ellipsoid_coverage_counts_direction_cells(void)
{
    double w[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    magcal_vec3_t c = {(float)V_TRUE[0], (float)V_TRUE[1], (float)V_TRUE[2]};
    float cov = -1.0f;
    size_t k;
    make_set(w, NFIT, 180.0, 180.0, 0.0, 11u);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipsoid_coverage(g_m, NFIT, &c, &cov));
    TEST_ASSERT_TRUE(cov > 0.95f); /* 600 random directions fill (nearly) all 72 cells */
    for (k = 0; k < 10; ++k) {
        g_m[k].x = c.x + 1.0f;
        g_m[k].y = c.y + 0.1f * (float)k;
        g_m[k].z = c.z + 0.01f;
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipsoid_coverage(g_m, 1, &c, &cov));
    TEST_ASSERT_FLOAT_WITHIN(1e-6f, 1.0f / 72.0f, cov);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_TOO_FEW_POINTS, magcal_ellipsoid_coverage(g_m, 0, &c, &cov));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_ellipsoid_coverage(g_m, 1, NULL, &cov));
}

static void test_ellipsoid_apply_known_matrix_and_offset(void)
{
    magcal_ellipsoid_cal_t cal = {{{2, 0, 0}, {0, 1, 1}, {0, 0, 3}}, {1, 2, 3}, 10};
    magcal_vec3_t m = {2, 4, 5}, h = {0, 0, 0};
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipsoid_apply(&cal, &m, &h));
    TEST_ASSERT_FLOAT_WITHIN(1e-6f, 2.0f, h.x); /* 2*(2-1) */
    TEST_ASSERT_FLOAT_WITHIN(1e-6f, 4.0f, h.y); /* (4-2)+(5-3) */
    TEST_ASSERT_FLOAT_WITHIN(1e-6f, 6.0f, h.z); /* 3*(5-3) */
    m.z = INFINITY;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_ellipsoid_apply(&cal, &m, &h));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_ellipsoid_apply(NULL, &m, &h));
}

/* ---- trust gates (issue 12); the hostile suite is tests/test_trust3d.c ---------------------- */

static void test_ellipsoid_fit_field_band_returns_field_magnitude(void)
{
    /* raw data in uT: the raw radius F / det(G)^(1/3) is compared with field_expected (same unit),
     * whatever output scale cfg.field asks for */
    double w[3][3];
    magcal_ellipsoid_cfg_t cfg = MAGCAL_ELLIPSOID_CFG_DEFAULT;
    magcal_ellipsoid_result_t r;
    const float f = (float)f_ref();
    make_w_sym(w);
    make_set(w, NFIT, 180.0, 180.0, 0.1, 4343u);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipsoid_fit(g_m, NFIT, &cfg, &g_fit_scratch, &r));
    TEST_ASSERT_FLOAT_WITHIN(0.02f * f, f, r.field_raw); /* det W = 1.052: raw radius 49.2 uT */
    cfg.field_expected = f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipsoid_fit(g_m, NFIT, &cfg, &g_fit_scratch, &r));
    cfg.field = 1000.0f; /* output in nT: G absorbs the scale, the raw radius is unchanged */
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipsoid_fit(g_m, NFIT, &cfg, &g_fit_scratch, &r));
    TEST_ASSERT_FLOAT_WITHIN(0.02f * f, f, r.field_raw);
    cfg.field_expected = 0.70f * f; /* raw 1.45 x expected: above the 1.4 band */
    memset(&r, 0xA5, sizeof(r));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_FIELD_MAGNITUDE, magcal_ellipsoid_fit(g_m, NFIT, &cfg, &g_fit_scratch, &r));
    TEST_ASSERT_EQUAL_HEX8(0xA5, ((unsigned char *)&r)[0]);
    cfg.field_expected = 1.25f * f; /* raw 0.81 x expected: below 0.85 */
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_FIELD_MAGNITUDE, magcal_ellipsoid_fit(g_m, NFIT, &cfg, &g_fit_scratch, &r));
    cfg.field_band_lo = 0.75f; /* a wider band admits it */
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipsoid_fit(g_m, NFIT, &cfg, &g_fit_scratch, &r));
    cfg.field_band_lo = 0.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_ellipsoid_fit(g_m, NFIT, &cfg, &g_fit_scratch, &r));
    cfg.field_band_lo = 0.85f;
    cfg.field_band_hi = 0.9f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_ellipsoid_fit(g_m, NFIT, &cfg, &g_fit_scratch, &r));
    cfg.field_band_hi = 1.4f;
    cfg.field_expected = -1.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_ellipsoid_fit(g_m, NFIT, &cfg, &g_fit_scratch, &r));
    cfg.field_expected = NAN;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_ellipsoid_fit(g_m, NFIT, &cfg, &g_fit_scratch, &r));
}

static void test_ellipsoid_fit_at_rest_returns_no_motion(void)
{
    /* one attitude, noise 0.5 uT: every model, and the gate can be switched off */
    static const magcal_ellipsoid_model_t models[4] = {MAGCAL_ELLIPSOID_MODEL_AUTO, MAGCAL_ELLIPSOID_MODEL_QUADRIC9,
                                                       MAGCAL_ELLIPSOID_MODEL_QUADRIC10, MAGCAL_ELLIPSOID_MODEL_SPHERE};
    double w[3][3], att[3] = {0.1, -0.2, 1.0};
    magcal_ellipsoid_cfg_t cfg = MAGCAL_ELLIPSOID_CFG_DEFAULT;
    magcal_ellipsoid_result_t r;
    uint32_t rng = 77u;
    size_t k;
    int i;
    make_w_sym(w);
    for (k = 0; k < NFIT; ++k) {
        g_m[k] = sample(w, V_TRUE, att, 0.5, &rng);
    }
    for (i = 0; i < 4; ++i) {
        cfg.model = models[i];
        memset(&r, 0xA5, sizeof(r));
        TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NO_MOTION, magcal_ellipsoid_fit(g_m, NFIT, &cfg, &g_fit_scratch, &r));
        TEST_ASSERT_EQUAL_HEX8(0xA5, ((unsigned char *)&r)[0]);
    }
    /* the diagnostic: every noise scale says ~2.5 sigma of spread */
    cfg.model = MAGCAL_ELLIPSOID_MODEL_QUADRIC9;
    cfg.min_motion_snr = 0.0f;
    cfg.max_centre_std_rel = 0.0f;
    cfg.max_shape_std = 0.0f;
    cfg.max_residual_rel = 0.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipsoid_fit(g_m, NFIT, &cfg, &g_fit_scratch, &r));
    TEST_ASSERT_TRUE(r.motion_snr > 1.5f && r.motion_snr < 4.0f);
    TEST_ASSERT_TRUE(v_err(&r.cal) > 10.0); /* the answer it used to return as OK */
}

static void test_ellipsoid_fit_sphere_on_soft_iron_returns_residual(void)
{
    /* 5 % stretch along x: the sphere leaves ~0.3 x 5 % = 1.5 % F of residual and up to ~1.4 deg of
     * heading; forced SPHERE is refused, the quadric on the same data is OK */
    static double w[3][3] = {{1.05, 0, 0}, {0, 1.0, 0}, {0, 0, 1.0}};
    magcal_ellipsoid_cfg_t cfg = cfg_with_field();
    magcal_ellipsoid_result_t r;
    make_set(w, NFIT, 180.0, 180.0, 0.05, 5353u);
    cfg.model = MAGCAL_ELLIPSOID_MODEL_SPHERE;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_RESIDUAL, magcal_ellipsoid_fit(g_m, NFIT, &cfg, &g_fit_scratch, &r));
    cfg.max_residual_rel_sphere = 0.05f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipsoid_fit(g_m, NFIT, &cfg, &g_fit_scratch, &r));
    TEST_ASSERT_TRUE(r.residual_rms > 0.01f * r.cal.field && r.residual_rms < 0.02f * r.cal.field);
    cfg.model = MAGCAL_ELLIPSOID_MODEL_AUTO;
    cfg.max_residual_rel_sphere = 0.01f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipsoid_fit(g_m, NFIT, &cfg, &g_fit_scratch, &r));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ELLIPSOID_MODEL_QUADRIC9, r.model);
    TEST_ASSERT_TRUE(v_err(&r.cal) < 0.02);
    /* diagnostics of a good fit: observable, not planar, moving */
    TEST_ASSERT_TRUE(r.centre_std_rel > 0.0f && r.centre_std_rel < 1e-3f);
    TEST_ASSERT_TRUE(r.shape_std > 0.0f && r.shape_std < 1e-3f);
    TEST_ASSERT_TRUE(r.planarity > 0.8f);
    TEST_ASSERT_TRUE(r.motion_snr > 100.0f);
}

static void test_ellipsoid_fit_trust_cfg_out_of_range_returns_arg(void)
{
    magcal_ellipsoid_cfg_t cfg = MAGCAL_ELLIPSOID_CFG_DEFAULT;
    magcal_ellipsoid_result_t r;
    double w[3][3];
    make_w_sym(w);
    make_set(w, 100, 180.0, 180.0, 0.05, 3u);
    cfg.min_motion_snr = -1.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_ellipsoid_fit(g_m, 100, &cfg, &g_fit_scratch, &r));
    cfg.min_motion_snr = 4.0f;
    cfg.max_centre_std_rel = NAN;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_ellipsoid_fit(g_m, 100, &cfg, &g_fit_scratch, &r));
    cfg.max_centre_std_rel = 0.005f;
    cfg.max_shape_std = 2.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_ellipsoid_fit(g_m, 100, &cfg, &g_fit_scratch, &r));
    cfg.max_shape_std = 0.008f;
    cfg.max_residual_rel = -0.1f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_ellipsoid_fit(g_m, 100, &cfg, &g_fit_scratch, &r));
    cfg.max_residual_rel = 0.05f;
    cfg.max_residual_rel_sphere = 1.5f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_ellipsoid_fit(g_m, 100, &cfg, &g_fit_scratch, &r));
    cfg.max_residual_rel_sphere = 0.01f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipsoid_fit(g_m, 100, &cfg, &g_fit_scratch, &r));
}

/* ---- magcal_ellipsoid_calibrate (issue 14): pre-test -> density stage when needed -> fit ---- */
static MAGCAL_ELLIPSOID_CALIBRATE_WORKSPACE_DECLARE(g_cwork, NFIT + NOUT);
static uint8_t g_cin[NFIT + NOUT];

/* Two results equal bit for bit, field by field: the bytes after `model` are padding (a 1-byte
 * enum with arm-none-eabi's short enums), whatever the stack held. */
static void assert_same_result(const magcal_ellipsoid_result_t *a, const magcal_ellipsoid_result_t *b)
{
    const size_t head = offsetof(magcal_ellipsoid_result_t, model) + sizeof a->model;
    const size_t tail = offsetof(magcal_ellipsoid_result_t, gate_cal);
    TEST_ASSERT_EQUAL_MEMORY(a, b, head);
    TEST_ASSERT_EQUAL_MEMORY((const unsigned char *)a + tail, (const unsigned char *)b + tail,
                             sizeof *a - tail);
}

/* Clean tumble: the density stage is skipped and the result is the plain fit, bit for bit. */
static void test_ellipsoid_calibrate_clean_data_skips_density_stage(void)
{
    double w[3][3];
    magcal_ellipsoid_calibrate_cfg_t cc = MAGCAL_ELLIPSOID_CALIBRATE_CFG_DEFAULT;
    magcal_ellipsoid_calibrate_info_t info;
    magcal_ellipsoid_result_t r, rf;
    size_t k;
    test_make_w_full(w);
    make_set(w, 320u, 180.0, 180.0, 0.3, 4242u);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipsoid_fit(g_m, 320u, &cc.fit, &g_fit_scratch, &rf));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK,
                          magcal_ellipsoid_calibrate(&cc, g_m, 320u, g_cwork, sizeof g_cwork, g_cin, &r, &info));
    TEST_ASSERT_EQUAL_UINT32(0u, info.density_ran);
    TEST_ASSERT_EQUAL_UINT32(0u, (uint32_t)info.n_density_rejected);
    TEST_ASSERT_TRUE(info.pretest_max_rel > 0.0f && info.pretest_max_rel <= cc.pretest_max_rel);
    assert_same_result(&rf, &r);
    TEST_ASSERT_TRUE(v_err(&r.cal) < 0.1);
    for (k = 0; k < 320u; ++k) {
        TEST_ASSERT_EQUAL_UINT8(1u, g_cin[k]);
    }
}

/* A stuck burst 80 % outside the shell (5 %): the pre-test sees it, the density stage runs and the
 * result equals the full composition (filter3, then the fit of its inliers) bit for bit. */
static void test_ellipsoid_calibrate_burst_runs_density_stage_as_composition(void)
{
    static magcal_vec3_t kept[NFIT + NOUT];
    static uint8_t mask[NFIT + NOUT];
    static MAGCAL_OPTICS3_FILTER_WORKSPACE_DECLARE(fwork, NFIT + NOUT);
    double w[3][3];
    magcal_ellipsoid_calibrate_cfg_t cc = MAGCAL_ELLIPSOID_CALIBRATE_CFG_DEFAULT;
    magcal_optics_cfg_t oc = MAGCAL_OPTICS_CFG_DEFAULT;
    magcal_ellipsoid_calibrate_info_t info;
    magcal_ellipsoid_result_t r, rf;
    size_t k, nk = 0u;
    test_make_w_full(w);
    make_set(w, NFIT, 180.0, 180.0, 0.3, 777u);
    for (k = 0; k < NOUT; ++k) { /* stuck at 1.8 x the field along one direction */
        g_m[NFIT + k].x = (float)(V_TRUE[0] + 1.8 * f_ref() * 0.48);
        g_m[NFIT + k].y = (float)(V_TRUE[1] - 1.8 * f_ref() * 0.6);
        g_m[NFIT + k].z = (float)(V_TRUE[2] + 1.8 * f_ref() * 0.64);
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipsoid_calibrate(&cc, g_m, NFIT + NOUT, g_cwork, sizeof g_cwork,
                                                                g_cin, &r, &info));
    TEST_ASSERT_EQUAL_UINT32(1u, info.density_ran);
    TEST_ASSERT_TRUE(info.n_density_rejected >= NOUT);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_optics_filter3(&oc, g_m, NFIT + NOUT, fwork, sizeof fwork, mask, NULL));
    for (k = 0; k < NFIT + NOUT; ++k) {
        TEST_ASSERT_EQUAL_UINT8(mask[k], g_cin[k]);
        if (mask[k] != 0u) {
            kept[nk++] = g_m[k];
        }
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipsoid_fit(kept, nk, &cc.fit, &g_fit_scratch, &rf));
    assert_same_result(&rf, &r);
    TEST_ASSERT_TRUE(v_err(&r.cal) < 0.1);
    for (k = NFIT; k < NFIT + NOUT; ++k) {
        TEST_ASSERT_EQUAL_UINT8(0u, g_cin[k]);
    }
}

static void test_ellipsoid_calibrate_bad_input_returns_status(void)
{
    magcal_ellipsoid_calibrate_cfg_t cc = MAGCAL_ELLIPSOID_CALIBRATE_CFG_DEFAULT;
    magcal_ellipsoid_result_t r;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_ellipsoid_calibrate(NULL, g_m, 320u, g_cwork, sizeof g_cwork,
                                                                      NULL, &r, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_ellipsoid_calibrate(&cc, g_m, 320u, NULL, sizeof g_cwork,
                                                                      NULL, &r, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_WORKSPACE,
                          magcal_ellipsoid_calibrate(&cc, g_m, 320u, g_cwork,
                                                     MAGCAL_ELLIPSOID_CALIBRATE_WORKSPACE_LEN(320u) - 1u, NULL,
                                                     &r, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ALIGNMENT,
                          magcal_ellipsoid_calibrate(&cc, g_m, 320u, (uint8_t *)(void *)g_cwork + 1,
                                                     sizeof g_cwork - 1u, NULL, &r, NULL));
    {
        /* 4-byte aligned only: the same result (the result slots align themselves) */
        magcal_ellipsoid_result_t r0, r4;
        double w[3][3];
        uint8_t *w4 = (uint8_t *)(void *)g_cwork + ((((uintptr_t)(void *)g_cwork) % 8u == 0u) ? 4u : 0u);
        test_make_w_full(w);
        make_set(w, 320u, 180.0, 180.0, 0.05, 2024u);
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipsoid_calibrate(&cc, g_m, 320u, g_cwork, sizeof g_cwork, NULL, &r0, NULL));
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipsoid_calibrate(&cc, g_m, 320u, w4, MAGCAL_ELLIPSOID_CALIBRATE_WORKSPACE_LEN(320u),
                                                                    NULL, &r4, NULL));
        assert_same_result(&r0, &r4);
    }
    cc.pretest_max_rel = 0.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_ellipsoid_calibrate(&cc, g_m, 320u, g_cwork, sizeof g_cwork,
                                                                     NULL, &r, NULL));
    cc.pretest_max_rel = 0.15f;
    cc.mode = (magcal_ellipsoid_density_t)3;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_ellipsoid_calibrate(&cc, g_m, 320u, g_cwork, sizeof g_cwork,
                                                                     NULL, &r, NULL));
    /* the size macro: the pre-test's result, the info and the one-shot call's slice state (8-byte slots,
     * aligned: + 4), the inlier copy, then the larger of the density stage's and the fit's workspace */
    TEST_ASSERT_EQUAL_UINT32((uint32_t)(4u + (sizeof(magcal_ellipsoid_result_t) + 7u) / 8u * 8u +
                                        (sizeof(magcal_ellipsoid_calibrate_info_t) + 7u) / 8u * 8u +
                                        (sizeof(magcal_ellipsoid_calibrate_slice_t) + 7u) / 8u * 8u + 320u * sizeof(magcal_vec3_t) +
                                        ((MAGCAL_OPTICS3_FILTER_WORKSPACE_LEN(320u) > MAGCAL_ELLIPSOID_FIT_WORKSPACE_LEN(320u))
                                             ? MAGCAL_OPTICS3_FILTER_WORKSPACE_LEN(320u)
                                             : MAGCAL_ELLIPSOID_FIT_WORKSPACE_LEN(320u))),
                             (uint32_t)MAGCAL_ELLIPSOID_CALIBRATE_WORKSPACE_LEN(320u));
}

/* One data set through both entry points, every model: the same status and, on OK, the same
 * result bit for bit (the workspace only stores what the plain fit recomputes). */
static void assert_fit_ws_same(size_t n, const magcal_ellipsoid_cfg_t *base, int *n_ok)
{
    static const magcal_ellipsoid_model_t models[4] = {MAGCAL_ELLIPSOID_MODEL_AUTO, MAGCAL_ELLIPSOID_MODEL_QUADRIC9,
                                                       MAGCAL_ELLIPSOID_MODEL_QUADRIC10, MAGCAL_ELLIPSOID_MODEL_SPHERE};
    magcal_ellipsoid_cfg_t cfg = *base;
    magcal_ellipsoid_result_t a, b;
    int i;
    for (i = 0; i < 4; ++i) {
        magcal_status_t sa, sb;
        cfg.model = models[i];
        memset(&b, 0x5A, sizeof b);
        sa = magcal_ellipsoid_fit(g_m, n, &cfg, &g_fit_scratch, &a);
        sb = magcal_ellipsoid_fit_ws(g_m, n, &cfg, g_cwork, sizeof g_cwork, &b);
        TEST_ASSERT_EQUAL_INT(sa, sb);
        if (sa == MAGCAL_OK) {
            assert_same_result(&a, &b);
            ++*n_ok;
        } else {
            TEST_ASSERT_EQUAL_HEX8(0x5A, ((unsigned char *)&b)[0]); /* untouched */
        }
    }
}

/* The data sets both bit-for-bit comparisons walk (fit vs fit_ws, sliced vs one-shot), each
 * checked by `check` with the default and the field-gated configuration where it matters: full
 * rotations, radial outliers (several refits of the gate), 10 % shifted (TOO_MANY_OUTLIERS at
 * 5 %, then enough refits), a band (the sphere, ill-conditioned quadrics), a level ring (single
 * axis), few noisy samples. */
typedef void (*fit_check_fn)(size_t n, const magcal_ellipsoid_cfg_t *cfg, int *n_ok);

static void walk_fit_sets(fit_check_fn check, int *n_ok)
{
    double w[3][3];
    static double w_hard[3][3] = {{0.9, 0, 0}, {0, 0.9, 0}, {0, 0, 0.9}};
    const magcal_ellipsoid_cfg_t cfg = cfg_with_field();
    magcal_ellipsoid_cfg_t cfg0 = MAGCAL_ELLIPSOID_CFG_DEFAULT;
    size_t k;
    test_make_w_full(w);
    make_set(w, NFIT, 180.0, 180.0, 0.05, 2024u); /* full rotations */
    check(NFIT, &cfg, n_ok);
    check(NFIT, &cfg0, n_ok);
    make_radial_outliers(w, 4242u); /* outliers: several refits of the gate */
    check(NFIT, &cfg, n_ok);
    for (k = 0; k < NFIT; k += 10) { /* 10 % shifted: TOO_MANY_OUTLIERS at 5 % */
        g_m[k].x += 10.0f;
    }
    cfg0 = cfg;
    cfg0.max_reject_frac = 0.05f;
    check(NFIT, &cfg0, n_ok);
    cfg0.max_refits = 8u;
    cfg0.max_reject_frac = 0.25f;
    check(NFIT, &cfg0, n_ok);
    make_set(w_hard, NFIT, 20.0, 20.0, 0.05, 55u); /* a band: the sphere, ill-conditioned quadrics */
    check(NFIT, &cfg, n_ok);
    make_set(w, NFIT, 0.0, 0.0, 0.05, 77u); /* level ring: single axis */
    check(NFIT, &cfg, n_ok);
    make_set(w, 120u, 180.0, 180.0, 1.0, 99u); /* few noisy samples */
    check(120u, &cfg, n_ok);
}

static void test_ellipsoid_fit_ws_matches_fit_bit_for_bit(void)
{
    int n_ok = 0;
    walk_fit_sets(assert_fit_ws_same, &n_ok);
    TEST_ASSERT_TRUE(n_ok >= 8); /* the comparison covered OK results of several models */
}

static void test_ellipsoid_fit_ws_bad_input_returns_status(void)
{
    const magcal_ellipsoid_cfg_t cfg = MAGCAL_ELLIPSOID_CFG_DEFAULT;
    magcal_ellipsoid_result_t r;
    double w[3][3];
    test_make_w_full(w);
    make_set(w, 320u, 180.0, 180.0, 0.05, 2024u);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_ellipsoid_fit_ws(NULL, 320u, &cfg, g_cwork, sizeof g_cwork, &r));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_ellipsoid_fit_ws(g_m, 320u, NULL, g_cwork, sizeof g_cwork, &r));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_ellipsoid_fit_ws(g_m, 320u, &cfg, NULL, sizeof g_cwork, &r));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_ellipsoid_fit_ws(g_m, 320u, &cfg, g_cwork, sizeof g_cwork, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ALIGNMENT, magcal_ellipsoid_fit_ws(g_m, 320u, &cfg, (uint8_t *)(void *)g_cwork + 1,
                                                                        sizeof g_cwork - 1u, &r));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_WORKSPACE,
                          magcal_ellipsoid_fit_ws(g_m, 320u, &cfg, g_cwork, MAGCAL_ELLIPSOID_FIT_WORKSPACE_LEN(320u) - 1u, &r));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK,
                          magcal_ellipsoid_fit_ws(g_m, 320u, &cfg, g_cwork, MAGCAL_ELLIPSOID_FIT_WORKSPACE_LEN(320u), &r));
    {
        /* a workspace that is 4-byte aligned only (odd multiple of 4): the same result, at the
         * macro's size (the scratch aligns itself inside it) */
        magcal_ellipsoid_result_t r4;
        uint8_t *w4 = (uint8_t *)(void *)g_cwork + ((((uintptr_t)(void *)g_cwork) % 8u == 0u) ? 4u : 0u);
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK,
                              magcal_ellipsoid_fit_ws(g_m, 320u, &cfg, w4, MAGCAL_ELLIPSOID_FIT_WORKSPACE_LEN(320u), &r4));
        assert_same_result(&r, &r4);
    }
    /* the size macro: the fixed scratch + a residual and a verdict byte per sample */
    TEST_ASSERT_EQUAL_UINT32((uint32_t)(MAGCAL_ELLIPSOID_FIT_SCRATCH_BYTES + 320u * 5u),
                             (uint32_t)MAGCAL_ELLIPSOID_FIT_WORKSPACE_LEN(320u));
}


/* The time-sliced fit at budget `budget`: the status, result and stored residuals of the one-shot
 * fit_ws, bit for bit; returns the step calls and (budget UINT32_MAX) the total charged. */
static magcal_ellipsoid_result_t g_sl_out;
static MAGCAL_ELLIPSOID_FIT_WORKSPACE_DECLARE(g_swork, NFIT + NOUT);
static size_t run_sliced(size_t n, const magcal_ellipsoid_cfg_t *cfg, uint32_t budget, magcal_status_t *st,
                         uint32_t *total, uint32_t *max_used)
{
    magcal_ellipsoid_fit_slice_t sl;
    size_t steps = 0u;
    memset(&g_sl_out, 0x5A, sizeof g_sl_out);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipsoid_fit_begin(&sl, g_m, n, cfg, g_swork, sizeof g_swork, &g_sl_out));
    *total = 0u;
    *max_used = 0u;
    do {
        *st = magcal_ellipsoid_fit_step(&sl, budget);
        *total += sl.used_;
        if (sl.used_ > *max_used) {
            *max_used = sl.used_;
        }
        ++steps;
        TEST_ASSERT_TRUE(steps < 2000000u);
    } while (*st == MAGCAL_IN_PROGRESS);
    TEST_ASSERT_EQUAL_INT(*st, magcal_ellipsoid_fit_step(&sl, budget)); /* the final status again */
    return steps;
}

static void assert_slices_same(size_t n, const magcal_ellipsoid_cfg_t *cfg_in, int *n_ok)
{
    static const uint32_t budgets[5] = {1u, 97u, 1000u, 6000u, UINT32_MAX};
    static const magcal_ellipsoid_model_t models[4] = {MAGCAL_ELLIPSOID_MODEL_AUTO, MAGCAL_ELLIPSOID_MODEL_QUADRIC9,
                                                       MAGCAL_ELLIPSOID_MODEL_QUADRIC10, MAGCAL_ELLIPSOID_MODEL_SPHERE};
    static float res_one[NFIT + NOUT];
    magcal_ellipsoid_cfg_t cfg = *cfg_in;
    magcal_ellipsoid_result_t a;
    int i, j;
    for (i = 0; i < 4; ++i) {
        magcal_status_t sa;
        uint32_t total = 0u;
        cfg.model = models[i];
        sa = magcal_ellipsoid_fit_ws(g_m, n, &cfg, g_cwork, sizeof g_cwork, &a);
        memcpy(res_one, (const uint8_t *)(const void *)g_cwork + MAGCAL_ELLIPSOID_FIT_SCRATCH_BYTES, n * sizeof(float));
        for (j = 4; j >= 0; --j) { /* UINT32_MAX first: the total */
            magcal_status_t sb;
            uint32_t tot, mx;
            const size_t steps = run_sliced(n, &cfg, budgets[j], &sb, &tot, &mx);
            TEST_ASSERT_EQUAL_INT(sa, sb);
            if (sa == MAGCAL_OK) {
                assert_same_result(&a, &g_sl_out);
                TEST_ASSERT_EQUAL_MEMORY(res_one, (const uint8_t *)(const void *)g_swork + MAGCAL_ELLIPSOID_FIT_SCRATCH_BYTES,
                                         n * sizeof(float));
            } else {
                TEST_ASSERT_EQUAL_HEX8(0x5A, ((unsigned char *)&g_sl_out)[0]); /* untouched */
            }
            if (budgets[j] == UINT32_MAX) {
                TEST_ASSERT_EQUAL_UINT32(1u, (uint32_t)steps);
                total = tot;
            } else {
                /* every step charged within its budget, or one unit alone (the largest unit: the
                 * 10-parameter inverse iteration, forced model only; else one 9x9 solve <= 7,500) */
                TEST_ASSERT_TRUE(mx <= budgets[j] || mx <= ((models[i] == MAGCAL_ELLIPSOID_MODEL_QUADRIC10) ? 60000u : 7500u) + 600u);
                TEST_ASSERT_EQUAL_UINT32(total, tot); /* the same work, however cut */
            }
            if (budgets[j] == 6000u && models[i] != MAGCAL_ELLIPSOID_MODEL_QUADRIC10) {
                /* steps within 1.6 x total / 6000 + 3: a step ends early only before a unit that
                 * does not fit the rest of its budget (units <= 7,500) */
                TEST_ASSERT_TRUE(steps <= (size_t)((total / 6000u) * 16u / 10u + 3u));
            }
            if (budgets[j] == 6000u) {
                printf("  slices n=%u model=%d: total %u, steps at 6000: %u (total/6000 = %.1f)\n", (unsigned)n, (int)models[i],
                       (unsigned)total, (unsigned)steps, (double)total / 6000.0);
            }
        }
        if (sa == MAGCAL_OK) {
            ++*n_ok;
        }
    }
}

static void test_ellipsoid_fit_step_any_budget_matches_fit_ws_bit_for_bit(void)
{
    const magcal_ellipsoid_cfg_t cfg = cfg_with_field();
    int n_ok = 0;
    size_t k;
    walk_fit_sets(assert_slices_same, &n_ok);
    for (k = 0; k < 120u; ++k) { /* at rest: NO_MOTION through the sphere's robust scale */
        g_m[k].x = 10.0f + 0.01f * (float)(k % 7u);
        g_m[k].y = -5.0f + 0.01f * (float)(k % 5u);
        g_m[k].z = 3.0f + 0.01f * (float)(k % 3u);
    }
    assert_slices_same(120u, &cfg, &n_ok);
    TEST_ASSERT_TRUE(n_ok >= 8); /* the comparison covered OK results of several models */
}

static void test_ellipsoid_fit_step_bad_input_returns_status(void)
{
    const magcal_ellipsoid_cfg_t cfg = MAGCAL_ELLIPSOID_CFG_DEFAULT;
    magcal_ellipsoid_fit_slice_t sl;
    magcal_ellipsoid_result_t r;
    memset(&sl, 0, sizeof sl);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_ellipsoid_fit_step(NULL, 100u));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_ellipsoid_fit_step(&sl, 100u)); /* never begun */
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_ellipsoid_fit_begin(NULL, g_m, 320u, &cfg, g_swork, sizeof g_swork, &r));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_ellipsoid_fit_begin(&sl, g_m, 320u, &cfg, g_swork, sizeof g_swork, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_ellipsoid_fit_step(&sl, 100u)); /* failed begin */
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_WORKSPACE,
                          magcal_ellipsoid_fit_begin(&sl, g_m, 320u, &cfg, g_swork, MAGCAL_ELLIPSOID_FIT_WORKSPACE_LEN(320u) - 1u, &r));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ALIGNMENT,
                          magcal_ellipsoid_fit_begin(&sl, g_m, 320u, &cfg, (uint8_t *)(void *)g_swork + 2, sizeof g_swork - 2u, &r));
}


/* The time-sliced complete calibration: status, result, info and inlier flags of the one-shot
 * call at every budget (the density stage, when it runs, is one unit of its own). */
static MAGCAL_ELLIPSOID_CALIBRATE_WORKSPACE_DECLARE(g_cwork2, NFIT + NOUT);
static uint8_t g_cin2[NFIT + NOUT];
static void assert_calibrate_slices_same(size_t n, const magcal_ellipsoid_calibrate_cfg_t *cc, int *n_ok)
{
    static const uint32_t budgets[5] = {1u, 97u, 1000u, 6000u, UINT32_MAX};
    static uint8_t cin1[NFIT + NOUT];
    magcal_ellipsoid_result_t a, b;
    magcal_ellipsoid_calibrate_info_t ia, ib;
    magcal_status_t sa;
    int j;
    memset(cin1, 0x77, sizeof cin1);
    sa = magcal_ellipsoid_calibrate(cc, g_m, n, g_cwork, sizeof g_cwork, cin1, &a, &ia);
    for (j = 0; j < 5; ++j) {
        magcal_ellipsoid_calibrate_slice_t sl;
        magcal_status_t sb;
        size_t steps = 0u;
        uint32_t mx = 0u;
        memset(g_cin2, 0x77, sizeof g_cin2);
        memset(&b, 0x5A, sizeof b);
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipsoid_calibrate_begin(&sl, cc, g_m, n, g_cwork2, sizeof g_cwork2,
                                                                          g_cin2, &b, &ib));
        do {
            sb = magcal_ellipsoid_calibrate_step(&sl, budgets[j]);
            if (sl.used_ > mx && sl.used_ < 1000000u) { /* the density stage: one unit alone */
                mx = sl.used_;
            }
            TEST_ASSERT_TRUE(++steps < 4000000u);
        } while (sb == MAGCAL_IN_PROGRESS);
        TEST_ASSERT_EQUAL_INT(sa, sb);
        TEST_ASSERT_EQUAL_INT(sb, magcal_ellipsoid_calibrate_step(&sl, budgets[j]));
        TEST_ASSERT_TRUE(mx <= budgets[j] || mx <= 8100u); /* one solve unit alone: <= 7,500 */
        TEST_ASSERT_EQUAL_UINT32(ia.density_ran, ib.density_ran);
        TEST_ASSERT_EQUAL_UINT32((uint32_t)ia.n_density_rejected, (uint32_t)ib.n_density_rejected);
        TEST_ASSERT_EQUAL_MEMORY(&ia.pretest_max_rel, &ib.pretest_max_rel, sizeof(float)); /* NaN too */
        if (sa == MAGCAL_OK) {
            assert_same_result(&a, &b);
            TEST_ASSERT_EQUAL_MEMORY(cin1, g_cin2, n);
        } else {
            TEST_ASSERT_EQUAL_HEX8(0x5A, ((unsigned char *)&b)[0]);
        }
    }
    if (sa == MAGCAL_OK) {
        ++*n_ok;
    }
}

static void test_ellipsoid_calibrate_step_any_budget_matches_calibrate(void)
{
    double w[3][3];
    magcal_ellipsoid_calibrate_cfg_t cc = MAGCAL_ELLIPSOID_CALIBRATE_CFG_DEFAULT;
    int n_ok = 0;
    size_t k;
    test_make_w_full(w);
    make_set(w, 320u, 180.0, 180.0, 0.05, 2024u); /* clean: the pre-test only */
    assert_calibrate_slices_same(320u, &cc, &n_ok);
    cc.mode = MAGCAL_ELLIPSOID_DENSITY_ALWAYS;
    assert_calibrate_slices_same(320u, &cc, &n_ok);
    cc.mode = MAGCAL_ELLIPSOID_DENSITY_AUTO;
    make_set(w, NFIT, 180.0, 180.0, 0.3, 777u);
    for (k = 0; k < NOUT; ++k) { /* a burst: the density stage runs */
        g_m[NFIT + k].x = (float)(V_TRUE[0] + 1.8 * f_ref() * 0.48);
        g_m[NFIT + k].y = (float)(V_TRUE[1] - 1.8 * f_ref() * 0.6);
        g_m[NFIT + k].z = (float)(V_TRUE[2] + 1.8 * f_ref() * 0.64);
    }
    assert_calibrate_slices_same(NFIT + NOUT, &cc, &n_ok);
    cc.mode = MAGCAL_ELLIPSOID_DENSITY_NEVER;
    assert_calibrate_slices_same(NFIT + NOUT, &cc, &n_ok);
    cc.mode = MAGCAL_ELLIPSOID_DENSITY_AUTO;
    make_set(w, NFIT, 0.0, 0.0, 0.05, 77u); /* level ring: fails */
    assert_calibrate_slices_same(NFIT, &cc, &n_ok);
    TEST_ASSERT_TRUE(n_ok >= 3);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_ellipsoid_fit_random_attitudes_recovers_v_and_q);
    RUN_TEST(test_ellipsoid_fit_quadric10_matches_quadric9);
    RUN_TEST(test_ellipsoid_fit_sqrt_variants_satisfy_gtg_equals_q);
    RUN_TEST(test_ellipsoid_fit_tilted_headings_within_1p2_of_floor);
    RUN_TEST(test_ellipsoid_fit_outliers_rejected_by_residual_gate);
    RUN_TEST(test_ellipsoid_fit_rejections_above_limit_return_too_many_outliers);
    RUN_TEST(test_ellipsoid_fit_poor_coverage_falls_back_to_sphere);
    RUN_TEST(test_ellipsoid_fit_level_ring_every_model_returns_single_axis);
    RUN_TEST(test_ellipsoid_fit_hyperboloid_returns_not_ellipsoid);
    RUN_TEST(test_ellipsoid_fit_unknown_field_gives_unit_determinant);
    RUN_TEST(test_ellipsoid_fit_bad_input_returns_status);
    RUN_TEST(test_ellipsoid_outliers_injected_indices_all_flagged);
    RUN_TEST(test_ellipsoid_outliers_tangent_shifts_count_equals_n_rejected);
    RUN_TEST(test_ellipsoid_outliers_borderline_errors_count_equals_n_rejected);
    RUN_TEST(test_ellipsoid_outliers_clean_data_all_zero);
    RUN_TEST(test_ellipsoid_outliers_bad_input_returns_status);
    RUN_TEST(test_ellipsoid_coverage_counts_direction_cells);
    RUN_TEST(test_ellipsoid_apply_known_matrix_and_offset);
    RUN_TEST(test_ellipsoid_fit_field_band_returns_field_magnitude);
    RUN_TEST(test_ellipsoid_fit_at_rest_returns_no_motion);
    RUN_TEST(test_ellipsoid_fit_sphere_on_soft_iron_returns_residual);
    RUN_TEST(test_ellipsoid_fit_trust_cfg_out_of_range_returns_arg);
    RUN_TEST(test_ellipsoid_calibrate_clean_data_skips_density_stage);
    RUN_TEST(test_ellipsoid_calibrate_burst_runs_density_stage_as_composition);
    RUN_TEST(test_ellipsoid_calibrate_bad_input_returns_status);
    RUN_TEST(test_ellipsoid_fit_ws_matches_fit_bit_for_bit);
    RUN_TEST(test_ellipsoid_fit_ws_bad_input_returns_status);
    RUN_TEST(test_ellipsoid_fit_step_any_budget_matches_fit_ws_bit_for_bit);
    RUN_TEST(test_ellipsoid_fit_step_bad_input_returns_status);
    RUN_TEST(test_ellipsoid_calibrate_step_any_budget_matches_calibrate);
    return UNITY_END();
}
