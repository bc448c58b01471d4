/*
 * Tests of the 2-D ellipse fit and the ellipse-to-circle corrections (algorithms.md 1.3, 2.1-2.5).
 *
 * Truth comes from synthetic rings with known distortion Hm = T H + b (tests/support/test_util.h)
 * and from an independent, straightforward double-precision least-squares fit written here
 * (centred on the mean, scaled, per-point normal equations, Gaussian elimination with partial
 * pivoting, geometry in double). The library itself is float32 only.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "magcal/ellipse.h"
#include "magcal/heading.h"
#include "test_util.h"
#include "unity.h"

#define PI_D 3.14159265358979323846
#define DEG_D (180.0 / PI_D)
#define MAX_PTS 2000

void setUp(void) {}
void tearDown(void) {}

static magcal_vec2_t g_pts[MAX_PTS];
static float g_psi[MAX_PTS];

/* ------------------------------------------------------------------ helpers */

static void check_within(double tol, double expected, double actual, const char *what)
{
    char msg[160];
    if (!(fabs(actual - expected) <= tol)) {
        snprintf(msg, sizeof msg, "%s: expected %.9g, got %.9g (|diff| %.3g > tol %.3g)", what,
                 expected, actual, fabs(actual - expected), tol);
        TEST_FAIL_MESSAGE(msg);
    }
}

/* T = R(phis) diag(kx, ky) R(phip) (algorithms.md 1.3). */
static test_distortion_t make_dist(double h0, double kx, double ky, double phis_deg,
                                   double phip_deg, double bx, double by)
{
    test_distortion_t d;
    double cs = cos(phis_deg / DEG_D), ss = sin(phis_deg / DEG_D);
    double cp = cos(phip_deg / DEG_D), sp = sin(phip_deg / DEG_D);
    /* R(phis) diag(kx,ky) = [[cs kx, -ss ky], [ss kx, cs ky]]; times R(phip) = [[cp, -sp], [sp, cp]] */
    d.h0 = (float)h0;
    d.t[0][0] = (float)(cs * kx * cp - ss * ky * sp);
    d.t[0][1] = (float)(-cs * kx * sp - ss * ky * cp);
    d.t[1][0] = (float)(ss * kx * cp + cs * ky * sp);
    d.t[1][1] = (float)(-ss * kx * sp + cs * ky * cp);
    d.bx = (float)bx;
    d.by = (float)by;
    return d;
}

/* Angle difference modulo 180 degrees (axis directions), in (-90, 90]. */
static double axis_diff_deg(double a, double b)
{
    double r = fmod(a - b, 180.0);
    if (r > 90.0) {
        r -= 180.0;
    } else if (r <= -90.0) {
        r += 180.0;
    }
    return r;
}

/* ----------------------------------------------- independent double reference */

typedef struct {
    double cx, cy, r1, r2, theta;
    double coef[5]; /* A..E in INPUT units */
    double delta;
} ref_ellipse_t;

/* Solve the 5x5 system a x = b (double, partial pivoting). Returns 0 on success. */
static int ref_solve5(double a[5][5], double b[5], double x[5])
{
    int i, j, k;
    for (k = 0; k < 5; ++k) {
        int piv = k;
        for (i = k + 1; i < 5; ++i) {
            if (fabs(a[i][k]) > fabs(a[piv][k])) {
                piv = i;
            }
        }
        if (a[piv][k] == 0.0) {
            return -1;
        }
        if (piv != k) {
            double t;
            for (j = 0; j < 5; ++j) {
                t = a[k][j];
                a[k][j] = a[piv][j];
                a[piv][j] = t;
            }
            t = b[k];
            b[k] = b[piv];
            b[piv] = t;
        }
        for (i = k + 1; i < 5; ++i) {
            double f = a[i][k] / a[k][k];
            for (j = k; j < 5; ++j) {
                a[i][j] -= f * a[k][j];
            }
            b[i] -= f * b[k];
        }
    }
    for (k = 4; k >= 0; --k) {
        double s = b[k];
        for (j = k + 1; j < 5; ++j) {
            s -= a[k][j] * x[j];
        }
        x[k] = s / a[k][k];
    }
    return 0;
}

/* Least-squares conic in double. normalise = 1: centre on the mean and scale by the largest
 * distance, then map back (algorithms.md 2.2); 0: raw coordinates. Returns 0 (ellipse), 1
 * (not an ellipse: delta <= 0 or K <= 0; ref->delta tells which), -1 (singular). */
static int ref_fit(const magcal_vec2_t *p, size_t n, int normalise, ref_ellipse_t *ref)
{
    double mx = 0.0, my = 0.0, s = 1.0;
    double nn[5][5] = {{0}}, rhs[5] = {0}, c[5];
    double a, b, cc, d, e, x0, y0, k, l1, l2;
    size_t i;
    int r, j;
    if (normalise) {
        double smax = 0.0;
        for (i = 0; i < n; ++i) {
            mx += p[i].x;
            my += p[i].y;
        }
        mx /= (double)n;
        my /= (double)n;
        for (i = 0; i < n; ++i) {
            double dd = hypot(p[i].x - mx, p[i].y - my);
            smax = dd > smax ? dd : smax;
        }
        s = smax;
    }
    for (i = 0; i < n; ++i) {
        double x = (p[i].x - mx) / s, y = (p[i].y - my) / s;
        double w[5];
        w[0] = x * y;
        w[1] = y * y;
        w[2] = x;
        w[3] = y;
        w[4] = 1.0;
        for (r = 0; r < 5; ++r) {
            rhs[r] += w[r] * (-x * x);
            for (j = 0; j < 5; ++j) {
                nn[r][j] += w[r] * w[j];
            }
        }
    }
    if (ref_solve5(nn, rhs, c) != 0) {
        return -1;
    }
    /* back to input units, algorithms.md 2.2 with sx = sy = s */
    a = c[0];
    b = c[1];
    cc = c[2] * s;
    d = c[3] * s;
    e = c[4] * s * s;
    ref->coef[0] = a;
    ref->coef[1] = b;
    ref->coef[2] = cc - 2.0 * mx - a * my;
    ref->coef[3] = d - 2.0 * b * my - a * mx;
    ref->coef[4] = mx * mx + a * mx * my + b * my * my - cc * mx - d * my + e;
    /* geometry in normalised coordinates, mapped back */
    ref->delta = 4.0 * c[1] - c[0] * c[0];
    if (!(ref->delta > 0.0)) {
        return 1;
    }
    x0 = (c[0] * c[3] - 2.0 * c[1] * c[2]) / ref->delta;
    y0 = (c[0] * c[2] - 2.0 * c[3]) / ref->delta;
    k = -(c[4] + 0.5 * (c[2] * x0 + c[3] * y0));
    if (!(k > 0.0)) {
        return 1;
    }
    l1 = 0.5 * (1.0 + c[1]) + 0.5 * sqrt((1.0 - c[1]) * (1.0 - c[1]) + c[0] * c[0]);
    l2 = 0.5 * (1.0 + c[1]) - 0.5 * sqrt((1.0 - c[1]) * (1.0 - c[1]) + c[0] * c[0]);
    ref->cx = mx + s * x0;
    ref->cy = my + s * y0;
    ref->r1 = s * sqrt(k / l1);
    ref->r2 = s * sqrt(k / l2);
    ref->theta = 0.5 * atan2(c[0], 1.0 - c[1]);
    return 0;
}

/* Largest relative deviation of centre and axes from the reference, relative to r2. */
static double rel_err_vs_ref(const magcal_ellipse_t *e, const ref_ellipse_t *ref)
{
    double ec = hypot(e->center.x - ref->cx, e->center.y - ref->cy);
    double e1 = fabs(e->semi_minor - ref->r1);
    double e2 = fabs(e->semi_major - ref->r2);
    double m = ec > e1 ? ec : e1;
    m = m > e2 ? m : e2;
    return m / ref->r2;
}

/* ------------------------------------------------------------ recovery tests */

static void test_ellipse_fit_alg23_example_recovers_truth(void)
{
    /* algorithms.md 2.3: b = (0.42, -0.27), H0 = 0.35, kx = 1.15, ky = 0.80, phis = 25, phip = -10,
     * 400 points, noise 1e-4: r1 = 0.28, r2 = 0.4025, theta = 115 deg mod 180 (= -65 deg). */
    test_distortion_t d = make_dist(0.35, 1.15, 0.80, 25.0, -10.0, 0.42, -0.27);
    magcal_ellipse_t e;
    test_make_ring(&d, 400, 0.0, 360.0, 1e-4, 11u, g_pts, NULL);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_fit(g_pts, 400, NULL, &e));
    check_within(5e-5, 0.42, e.center.x, "x0");
    check_within(5e-5, -0.27, e.center.y, "y0");
    check_within(1e-4, 0.28, e.semi_minor, "r1");
    check_within(1e-4, 0.4025, e.semi_major, "r2");
    check_within(0.05, 0.0, axis_diff_deg(e.angle_rad * DEG_D, 115.0), "theta = phis + 90 mod 180");
    TEST_ASSERT_TRUE(e.angle_rad > -PI_D / 2 && e.angle_rad <= PI_D / 2);
    check_within(0.05, -65.0, e.angle_rad * DEG_D, "theta in (-90, 90]");
    TEST_ASSERT_EQUAL_UINT16(400, e.n_used);
    /* residual RMS ~ noise sigma (1e-4) */
    TEST_ASSERT_TRUE(e.residual_rms > 0.5e-4f && e.residual_rms < 2e-4f);
}

static void test_ellipse_fit_kx_below_ky_angle_is_phis(void)
{
    /* kx < ky: the minor axis lies along phis (algorithms.md 2.3). Raw-count scale and offset. */
    test_distortion_t d = make_dist(400.0, 0.7, 1.2, -40.0, 30.0, -1500.0, 900.0);
    magcal_ellipse_t e;
    test_make_ring(&d, 700, 3.0, 360.0, 0.5, 12u, g_pts, NULL);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_fit(g_pts, 700, NULL, &e));
    check_within(0.1, -1500.0, e.center.x, "x0");
    check_within(0.1, 900.0, e.center.y, "y0");
    check_within(0.1, 280.0, e.semi_minor, "r1");
    check_within(0.1, 480.0, e.semi_major, "r2");
    check_within(0.05, 0.0, axis_diff_deg(e.angle_rad * DEG_D, -40.0), "theta = phis");
}

static void test_ellipse_fit_circle_has_equal_axes(void)
{
    test_distortion_t d = make_dist(25.0, 1.0, 1.0, 0.0, 0.0, 3.0, -7.0);
    magcal_ellipse_t e;
    test_make_ring(&d, 100, 0.0, 360.0, 0.0, 13u, g_pts, NULL);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_fit(g_pts, 100, NULL, &e));
    check_within(1e-4 * 25.0, 3.0, e.center.x, "x0");
    check_within(1e-4 * 25.0, -7.0, e.center.y, "y0");
    check_within(1e-4 * 25.0, 25.0, e.semi_minor, "r1");
    check_within(1e-4 * 25.0, 25.0, e.semi_major, "r2");
    TEST_ASSERT_TRUE(e.semi_minor <= e.semi_major);
    TEST_ASSERT_TRUE(e.residual_rms < 1e-4f * 25.0f);
}

static void test_ellipse_fit_matches_double_reference_1e4(void)
{
    /* Well-conditioned cases, float32 library vs double reference on the SAME float inputs:
     * centre and axes agree to 1e-4 relative to r2 (measured: ~1e-7). */
    static const double cases[][7] = {
        /* h0, kx, ky, phis, phip, bx, by */
        {0.35, 1.15, 0.80, 25.0, -10.0, 0.42, -0.27},
        {45.0, 1.30, 0.85, 70.0, 5.0, -12.0, 30.0},
        {300.0, 0.95, 1.05, -20.0, 0.0, 1200.0, -800.0},
        {5000.0, 1.10, 0.90, 10.0, 20.0, 9000.0, 6000.0},
    };
    size_t i;
    for (i = 0; i < sizeof cases / sizeof cases[0]; ++i) {
        const double *c = cases[i];
        test_distortion_t d = make_dist(c[0], c[1], c[2], c[3], c[4], c[5], c[6]);
        magcal_ellipse_t e;
        ref_ellipse_t ref;
        double err;
        test_make_ring(&d, 700, 0.0, 360.0, 0.005 * c[0], 100u + (uint32_t)i, g_pts, NULL);
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_fit(g_pts, 700, NULL, &e));
        TEST_ASSERT_EQUAL_INT(0, ref_fit(g_pts, 700, 1, &ref));
        err = rel_err_vs_ref(&e, &ref);
        printf("case %u: float32 vs double rel. err %.2e (theta diff %.2e deg)\n", (unsigned)i, err,
               axis_diff_deg(e.angle_rad * DEG_D, ref.theta * DEG_D));
        check_within(1e-4, 0.0, err, "rel. error vs double reference");
        check_within(0.01, 0.0, axis_diff_deg(e.angle_rad * DEG_D, ref.theta * DEG_D),
                     "theta vs reference");
    }
}

static void test_ellipse_fit_coef_inverse_transform_matches_direct_fit(void)
{
    /* algorithms.md 2.2: the normalised coefficients mapped back to input units equal a direct
     * (un-normalised) double fit; checks the meaning of coef/norm_center/norm_scale. */
    test_distortion_t d = make_dist(0.35, 1.15, 0.80, 25.0, -10.0, 0.42, -0.27);
    magcal_ellipse_t e;
    ref_ellipse_t direct;
    double a, b, c, dd, ee, mx, my, s, back[5];
    size_t i;
    test_make_ring(&d, 400, 0.0, 360.0, 1e-4, 11u, g_pts, NULL);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_fit(g_pts, 400, NULL, &e));
    TEST_ASSERT_EQUAL_INT(0, ref_fit(g_pts, 400, 0, &direct));
    mx = e.norm_center.x;
    my = e.norm_center.y;
    s = e.norm_scale;
    a = e.coef[0];
    b = e.coef[1];
    c = e.coef[2] * s;
    dd = e.coef[3] * s;
    ee = e.coef[4] * s * s;
    back[0] = a;
    back[1] = b;
    back[2] = c - 2.0 * mx - a * my;
    back[3] = dd - 2.0 * b * my - a * mx;
    back[4] = mx * mx + a * mx * my + b * my * my - c * mx - dd * my + ee;
    for (i = 0; i < 5; ++i) {
        /* coefficients are O(1) here; float32 solution agrees to ~1e-6 */
        check_within(2e-4 * (1.0 + fabs(direct.coef[i])), direct.coef[i], back[i], "coefficient");
    }
}

/* ------------------------------------------------------------- conditioning */

static void test_ellipse_fit_offset20_float32_matches_double_seed_fails(void)
{
    /* algorithms.md 2.5 row 1: b = (6000, -5000), r = 300 LSB, N = 2000, noise 2 LSB
     * (offset/radius 26). Seed (max-abs) scaling loses positive definiteness in float32. */
    test_distortion_t d = make_dist(300.0, 1.0, 1.0, 0.0, 0.0, 6000.0, -5000.0);
    magcal_ellipse_t e, es;
    ref_ellipse_t ref;
    magcal_status_t st_seed;
    double err_c;
    test_make_ring(&d, 2000, 0.0, 360.0, 2.0, 21u, g_pts, NULL);
    TEST_ASSERT_EQUAL_INT(0, ref_fit(g_pts, 2000, 1, &ref));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_fit(g_pts, 2000, NULL, &e));
    err_c = hypot(e.center.x - ref.cx, e.center.y - ref.cy);
    printf("offset/radius 20: centred f32 centre err %.2e LSB, rel. err %.2e, min pivot %.3g\n",
           err_c, rel_err_vs_ref(&e, &ref), (double)e.min_pivot);
    check_within(1e-4, 0.0, rel_err_vs_ref(&e, &ref), "centred fit rel. error vs double");
    check_within(0.01, 0.0, err_c, "centred fit centre error (LSB)");
    /* the truth too (noise-limited): centre within 0.2 LSB, radius within 0.2 LSB */
    check_within(0.2, 6000.0, e.center.x, "x0 truth");
    check_within(0.2, -5000.0, e.center.y, "y0 truth");
    check_within(0.2, 300.0, e.semi_major, "r2 truth");
    /* the radial residual works on raw counts far from the origin: RMS = noise sigma (2 LSB) */
    check_within(0.15, 2.0, e.residual_rms, "residual RMS = noise sigma");

    st_seed = magcal_ellipse_fit_seed(g_pts, 2000, NULL, &es);
    if (st_seed == MAGCAL_OK) {
        double err_seed = hypot(es.center.x - ref.cx, es.center.y - ref.cy);
        printf("offset/radius 20: seed status ok, centre err %.3g LSB, min pivot %.3g\n", err_seed,
               (double)es.min_pivot);
        TEST_ASSERT_TRUE_MESSAGE(err_seed > 100.0 * err_c,
                                 "seed scaling should degrade at offset/radius 20");
    } else {
        printf("offset/radius 20: seed status %s\n", magcal_status_str(st_seed));
        TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ILL_CONDITIONED, st_seed);
    }
}

static void test_ellipse_fit_offset5_counts25000_meets_1e4_seed_does_not(void)
{
    /* algorithms.md 2.5 row 2: r = 5000 LSB, offset 25000 (5x), counts up to 30000. */
    test_distortion_t d = make_dist(5000.0, 1.0, 1.0, 0.0, 0.0, 20000.0, -15000.0);
    magcal_ellipse_t e, es;
    ref_ellipse_t ref;
    double rel, rel_seed;
    test_make_ring(&d, 2000, 0.0, 360.0, 2.0, 22u, g_pts, NULL);
    TEST_ASSERT_EQUAL_INT(0, ref_fit(g_pts, 2000, 1, &ref));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_fit(g_pts, 2000, NULL, &e));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_fit_seed(g_pts, 2000, NULL, &es));
    rel = rel_err_vs_ref(&e, &ref);
    rel_seed = rel_err_vs_ref(&es, &ref);
    printf("offset/radius 5, 25000 counts: centred rel. err %.2e (centre %.2e LSB); seed rel. err "
           "%.2e (centre %.2e LSB)\n",
           rel, hypot(e.center.x - ref.cx, e.center.y - ref.cy), rel_seed,
           hypot(es.center.x - ref.cx, es.center.y - ref.cy));
    check_within(1e-5, 0.0, rel, "centred fit rel. error vs double");
    TEST_ASSERT_TRUE_MESSAGE(rel_seed > 1e-4,
                             "seed scaling should miss 1e-4 relative at offset/radius 5");
}

static void test_ellipse_fit_full_int16_range_is_accurate(void)
{
    /* Raw counts near +/-32768 with a 20x offset: b = (-30000, 31000), r = 1500. */
    test_distortion_t d = make_dist(1500.0, 1.05, 0.95, 30.0, 0.0, -30000.0, 31000.0);
    magcal_ellipse_t e;
    ref_ellipse_t ref;
    test_make_ring(&d, 700, 0.0, 360.0, 3.0, 23u, g_pts, NULL);
    TEST_ASSERT_EQUAL_INT(0, ref_fit(g_pts, 700, 1, &ref));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_fit(g_pts, 700, NULL, &e));
    printf("int16 range, offset/radius 29: rel. err %.2e\n", rel_err_vs_ref(&e, &ref));
    check_within(1e-4, 0.0, rel_err_vs_ref(&e, &ref), "rel. error vs double");
}

static void test_ellipse_fit_matches_numpy_golden_values(void)
{
    /* Golden values from tools/ref/ellipse_ref.py: numpy lstsq (QR/SVD, double) on the same rings,
     * regenerated bit for bit in Python from test_util.c's generator. Tolerances: a few float32
     * ulps of the coordinate magnitude. */
    magcal_ellipse_t e;
    test_distortion_t d = make_dist(0.35, 1.15, 0.80, 25.0, -10.0, 0.42, -0.27);
    test_make_ring(&d, 400, 0.0, 360.0, 1e-4, 11u, g_pts, NULL);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_fit(g_pts, 400, NULL, &e));
    check_within(2e-7, 0.419989822, e.center.x, "2.3 x0");
    check_within(2e-7, -0.270003584, e.center.y, "2.3 y0");
    check_within(2e-7, 0.279994714, e.semi_minor, "2.3 r1");
    check_within(2e-7, 0.402489356, e.semi_major, "2.3 r2");
    check_within(1e-4, -64.9986147, e.angle_rad * DEG_D, "2.3 theta");
    d = make_dist(300.0, 1.0, 1.0, 0.0, 0.0, 6000.0, -5000.0);
    test_make_ring(&d, 2000, 0.0, 360.0, 2.0, 21u, g_pts, NULL);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_fit(g_pts, 2000, NULL, &e));
    check_within(2e-3, 6000.01737, e.center.x, "20x x0");
    check_within(2e-3, -5000.00576, e.center.y, "20x y0");
    check_within(2e-3, 299.974704, e.semi_minor, "20x r1");
    check_within(2e-3, 300.151143, e.semi_major, "20x r2");
    d = make_dist(5000.0, 1.0, 1.0, 0.0, 0.0, 20000.0, -15000.0);
    test_make_ring(&d, 2000, 0.0, 360.0, 2.0, 22u, g_pts, NULL);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_fit(g_pts, 2000, NULL, &e));
    check_within(5e-3, 19999.972, e.center.x, "5x x0");
    check_within(5e-3, -15000.1671, e.center.y, "5x y0");
    check_within(5e-3, 4999.88881, e.semi_minor, "5x r1");
    check_within(5e-3, 5000.02329, e.semi_major, "5x r2");
}

static void test_ellipse_fit_half_turn_at_offset20_matches_double_reference(void)
{
    /* 180 deg of arc (the least rotation a calibrator should accept), offset/radius 20: the
     * bounding-box centre is then about r/2 off the true centre; still 1e-4 relative. */
    test_distortion_t d = make_dist(300.0, 1.1, 0.9, 15.0, 0.0, -6000.0, -3000.0);
    magcal_ellipse_t e;
    ref_ellipse_t ref;
    double rel;
    test_make_ring(&d, 700, 100.0, 180.0, 0.5, 24u, g_pts, NULL);
    TEST_ASSERT_EQUAL_INT(0, ref_fit(g_pts, 700, 1, &ref));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_fit(g_pts, 700, NULL, &e));
    rel = rel_err_vs_ref(&e, &ref);
    printf("half turn, offset/radius 20: rel. err %.2e, min pivot %.3g\n", rel,
           (double)e.min_pivot);
    check_within(1e-4, 0.0, rel, "rel. error vs double");
    check_within(2.0, -6000.0, e.center.x, "x0 truth (noise-limited on a half turn)");
    check_within(2.0, -3000.0, e.center.y, "y0 truth");
}

/* --------------------------------------------------------- failure statuses */

static void test_ellipse_fit_60deg_arc_returns_hyperbola(void)
{
    /* algorithms.md 2.5: a 60 degree arc with noise fits a hyperbola. The double reference on
     * the same points agrees that 4B - A^2 < 0. */
    test_distortion_t d = make_dist(0.35, 1.15, 0.80, 25.0, -10.0, 0.42, -0.27);
    magcal_ellipse_t e;
    ref_ellipse_t ref;
    test_make_ring(&d, 200, 30.0, 60.0, 0.01, 31u, g_pts, NULL);
    TEST_ASSERT_EQUAL_INT(1, ref_fit(g_pts, 200, 1, &ref));
    printf("60 deg arc: double reference 4B - A^2 = %.3f\n", ref.delta);
    TEST_ASSERT_TRUE(ref.delta < 0.0);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_HYPERBOLA, magcal_ellipse_fit(g_pts, 200, NULL, &e));
}

static void test_ellipse_fit_bad_input_returns_specific_status(void)
{
    magcal_vec2_t p[8];
    uint8_t mask[8] = {1, 1, 1, 1, 0, 0, 0, 0};
    magcal_ellipse_t e;
    size_t i;
    memset(&e, 0xA5, sizeof e);
    for (i = 0; i < 8; ++i) {
        p[i].x = (float)cos(0.7 * (double)i);
        p[i].y = (float)sin(0.7 * (double)i);
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_ellipse_fit(NULL, 8, NULL, &e));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_ellipse_fit(p, 8, NULL, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_TOO_FEW_POINTS, magcal_ellipse_fit(p, 4, NULL, &e));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_TOO_FEW_POINTS, magcal_ellipse_fit(p, 8, mask, &e));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_TOO_FEW_POINTS, magcal_ellipse_fit(p, 0, NULL, &e));
    p[5].y = NAN;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_ellipse_fit(p, 8, NULL, &e));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_ellipse_fit_seed(p, 8, NULL, &e));
    mask[4] = 1; /* mask excludes the NaN point (5): 5 used points on the unit circle */
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_fit(p, 8, mask, &e));
    check_within(1e-4, 1.0, e.semi_major, "masked fit r2");
    p[5].y = INFINITY;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_ellipse_fit(p, 8, NULL, &e));
    /* the output stays untouched on failure */
    memset(&e, 0xA5, sizeof e);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_ellipse_fit(p, 8, NULL, &e));
    TEST_ASSERT_EACH_EQUAL_HEX8(0xA5, &e, sizeof e);
}

static void test_ellipse_fit_degenerate_points_return_degenerate(void)
{
    magcal_status_t st;
    magcal_vec2_t p[20];
    magcal_ellipse_t e;
    size_t i;
    for (i = 0; i < 20; ++i) { /* identical */
        p[i].x = 123.0f;
        p[i].y = -45.0f;
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_DEGENERATE, magcal_ellipse_fit(p, 20, NULL, &e));
    for (i = 0; i < 20; ++i) { /* collinear, with a large offset */
        p[i].x = 5000.0f + 3.0f * (float)i;
        p[i].y = -2000.0f - 7.0f * (float)i;
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_DEGENERATE, magcal_ellipse_fit(p, 20, NULL, &e));
    /* the seed's uncentred plain sums cannot resolve the covariance: its pivot test fires instead */
    st = magcal_ellipse_fit_seed(p, 20, NULL, &e);
    TEST_ASSERT_TRUE(st == MAGCAL_ERR_DEGENERATE || st == MAGCAL_ERR_ILL_CONDITIONED);
    for (i = 0; i < 20; ++i) { /* vertical line */
        p[i].x = 7.0f;
        p[i].y = (float)i;
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_DEGENERATE, magcal_ellipse_fit(p, 20, NULL, &e));
}

static void test_ellipse_fit_points_on_two_axes_return_ill_conditioned(void)
{
    /* Points on the lines x = 0 and y = 0 lie on the conic xy = 0, whose x^2 coefficient is 0:
     * the normalised 5-parameter system is singular and the pivot test must catch it. */
    magcal_vec2_t p[12];
    magcal_ellipse_t e;
    size_t i;
    for (i = 0; i < 6; ++i) {
        p[i].x = (float)i - 2.5f;
        p[i].y = 0.0f;
        p[6 + i].x = 0.0f;
        p[6 + i].y = (float)i - 2.0f;
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ILL_CONDITIONED, magcal_ellipse_fit(p, 12, NULL, &e));
}

static void test_ellipse_fit_exact_parabola_returns_parabola(void)
{
    /* y = x^2 exactly: x^2 - y = 0, so A = B = 0 and 4B - A^2 = 0. */
    magcal_vec2_t p[9];
    magcal_ellipse_t e;
    size_t i;
    for (i = 0; i < 9; ++i) {
        p[i].x = (float)i - 4.0f;
        p[i].y = p[i].x * p[i].x;
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_PARABOLA, magcal_ellipse_fit(p, 9, NULL, &e));
}

static void test_ellipse_from_conic_classifies_and_maps_back(void)
{
    /* x~^2 + y~^2 + 1 = 0: imaginary; x~^2 - y~^2 - 1: hyperbola; x~^2 - y~ = 0: parabola;
     * x~^2 + 4 y~^2 - 4 = 0: ellipse r = (1, 2)... in normalised units, mapped by centre/scale. */
    static const float imag[5] = {0.0f, 1.0f, 0.0f, 0.0f, 1.0f};
    static const float hyp[5] = {0.0f, -1.0f, 0.0f, 0.0f, -1.0f};
    static const float par[5] = {0.0f, 0.0f, 0.0f, -1.0f, 0.0f};
    static const float ell[5] = {0.0f, 0.25f, 0.0f, 0.0f, -1.0f}; /* x^2 + y^2/4 = 1 */
    magcal_vec2_t c0 = {100.0f, -50.0f};
    magcal_ellipse_t e;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_IMAGINARY, magcal_ellipse_from_conic(imag, c0, 10.0f, &e));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_HYPERBOLA, magcal_ellipse_from_conic(hyp, c0, 10.0f, &e));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_PARABOLA, magcal_ellipse_from_conic(par, c0, 10.0f, &e));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_ellipse_from_conic(ell, c0, 0.0f, &e));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_from_conic(ell, c0, 10.0f, &e));
    check_within(1e-4, 100.0, e.center.x, "x0");
    check_within(1e-4, -50.0, e.center.y, "y0");
    check_within(1e-5, 10.0, e.semi_minor, "r1");
    check_within(1e-5, 20.0, e.semi_major, "r2");
    check_within(1e-6, 0.0, e.angle_rad, "theta: minor axis along x");
}

/* ------------------------------------------------------------ subset fits */

static void test_ellipse_fit_idx_five_points_exact(void)
{
    /* 5 noise-free points of a known ellipse at raw-count scale: the exact path recovers it. */
    test_distortion_t d = make_dist(400.0, 1.2, 0.8, 35.0, 0.0, 2500.0, -1800.0);
    static const uint16_t idx[5] = {3, 40, 77, 121, 160};
    magcal_ellipse_t e;
    test_make_ring(&d, 200, 0.0, 360.0, 0.0, 41u, g_pts, NULL);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_fit_idx(g_pts, 200, idx, 5, &e));
    check_within(1e-4 * 480.0, 2500.0, e.center.x, "x0");
    check_within(1e-4 * 480.0, -1800.0, e.center.y, "y0");
    check_within(1e-4 * 480.0, 320.0, e.semi_minor, "r1");
    check_within(1e-4 * 480.0, 480.0, e.semi_major, "r2");
    check_within(0.01, 0.0, axis_diff_deg(e.angle_rad * DEG_D, 125.0), "theta");
    TEST_ASSERT_EQUAL_UINT16(5, e.n_used);
    TEST_ASSERT_TRUE(e.residual_rms < 1e-4f * 480.0f);
    TEST_ASSERT_TRUE(e.min_pivot > 1e-3f && e.min_pivot <= 1.0f);
}

static void test_ellipse_fit_idx_bad_subsets_return_status(void)
{
    test_distortion_t d = make_dist(400.0, 1.2, 0.8, 35.0, 0.0, 2500.0, -1800.0);
    static const uint16_t dup[5] = {3, 40, 77, 40, 160};
    static const uint16_t out_of_range[5] = {3, 40, 77, 121, 200};
    static const uint16_t close[5] = {10, 10 + 1, 10 + 2, 10 + 3, 10 + 4}; /* 1.8 deg of arc */
    static const uint16_t ok6[6] = {0, 30, 60, 90, 120, 150};
    magcal_ellipse_t e;
    test_make_ring(&d, 200, 0.0, 360.0, 0.0, 41u, g_pts, NULL);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_DEGENERATE, magcal_ellipse_fit_idx(g_pts, 200, dup, 5, &e));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_ellipse_fit_idx(g_pts, 200, out_of_range, 5, &e));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_TOO_FEW_POINTS,
                          magcal_ellipse_fit_idx(g_pts, 200, ok6, 4, &e));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_ellipse_fit_idx(g_pts, 200, NULL, 5, &e));
    printf("5 points on 7.2 deg of arc: %s\n",
           magcal_status_str(magcal_ellipse_fit_idx(g_pts, 200, close, 5, &e)));
    TEST_ASSERT_TRUE(magcal_ellipse_fit_idx(g_pts, 200, close, 5, &e) != MAGCAL_OK);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_fit_idx(g_pts, 200, ok6, 6, &e));
    check_within(1e-4 * 480.0, 2500.0, e.center.x, "6-point LS x0");
}

static void test_ellipse_fit_idx_and_mask_equal_compacted_fit(void)
{
    /* The same subset through fit_idx (m > 5), a mask and a compacted copy gives identical bits. */
    test_distortion_t d = make_dist(50.0, 1.1, 0.9, 10.0, 0.0, 5.0, 8.0);
    static magcal_vec2_t compact[300];
    static uint16_t idx[300];
    static uint8_t mask[600];
    magcal_ellipse_t a, b, c;
    size_t i, m = 0;
    test_make_ring(&d, 600, 0.0, 360.0, 0.3, 42u, g_pts, NULL);
    for (i = 0; i < 600; ++i) {
        mask[i] = (uint8_t)((i % 2u) == 0u || (i % 7u) == 0u);
        if (mask[i] && m < 300) {
            compact[m] = g_pts[i];
            idx[m] = (uint16_t)i;
            ++m;
        } else {
            mask[i] = 0;
        }
        if (mask[i] == 0u && i % 5u == 1u) { /* gross outliers that only the selection removes */
            g_pts[i].x += 200.0f;
        }
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_fit(compact, m, NULL, &a));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_fit(g_pts, 600, mask, &b));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_fit_idx(g_pts, 600, idx, m, &c));
    TEST_ASSERT_EQUAL_FLOAT(a.center.x, b.center.x);
    TEST_ASSERT_EQUAL_FLOAT(a.center.y, b.center.y);
    TEST_ASSERT_EQUAL_FLOAT(a.semi_major, b.semi_major);
    TEST_ASSERT_EQUAL_FLOAT(a.center.x, c.center.x);
    TEST_ASSERT_EQUAL_FLOAT(a.semi_minor, c.semi_minor);
    TEST_ASSERT_EQUAL_UINT16(m, b.n_used);
    check_within(0.1, 5.0, a.center.x, "x0 truth");
}

/* ------------------------------------------------- time-sliced fit (issue 13) */

/* Every field of two fits bit for bit (field by field: padding bytes are unspecified). */
static void assert_same_fit(const magcal_ellipse_t *a, const magcal_ellipse_t *b)
{
    TEST_ASSERT_EQUAL_MEMORY(&a->center, &b->center, sizeof a->center);
    TEST_ASSERT_EQUAL_MEMORY(&a->semi_minor, &b->semi_minor, sizeof(float));
    TEST_ASSERT_EQUAL_MEMORY(&a->semi_major, &b->semi_major, sizeof(float));
    TEST_ASSERT_EQUAL_MEMORY(&a->angle_rad, &b->angle_rad, sizeof(float));
    TEST_ASSERT_EQUAL_MEMORY(a->coef, b->coef, sizeof a->coef);
    TEST_ASSERT_EQUAL_MEMORY(&a->norm_center, &b->norm_center, sizeof a->norm_center);
    TEST_ASSERT_EQUAL_MEMORY(&a->norm_scale, &b->norm_scale, sizeof(float));
    TEST_ASSERT_EQUAL_MEMORY(&a->residual_rms, &b->residual_rms, sizeof(float));
    TEST_ASSERT_EQUAL_MEMORY(&a->min_pivot, &b->min_pivot, sizeof(float));
    TEST_ASSERT_EQUAL_MEMORY(a->qform, b->qform, sizeof a->qform);
    TEST_ASSERT_EQUAL_UINT16(a->n_used, b->n_used);
}

/* Sliced at each budget of the contract: the one-shot status and result; returns the steps at
 * budget 6000 and the total charged at UINT32_MAX. */
static void fit_sliced_matches(size_t n, const uint8_t *mask, const uint16_t *idx, size_t m,
                               const char *what)
{
    static const uint32_t budgets[] = {1u, 97u, 1000u, 6000u, UINT32_MAX};
    magcal_ellipse_t ref, got, untouched;
    magcal_status_t st_ref;
    size_t b;
    uint32_t total = 0u;
    unsigned steps6000 = 0u;
    memset(&ref, 0xA5, sizeof ref);
    memset(&untouched, 0xA5, sizeof untouched);
    st_ref = (idx != NULL) ? magcal_ellipse_fit_idx(g_pts, n, idx, m, &ref) : magcal_ellipse_fit(g_pts, n, mask, &ref);
    for (b = 0u; b < sizeof budgets / sizeof budgets[0]; ++b) {
        magcal_ellipse_fit_slice_t sl;
        magcal_status_t st;
        unsigned steps = 0u;
        uint32_t charged = 0u;
        memset(&got, 0xA5, sizeof got);
        st = (idx != NULL) ? magcal_ellipse_fit_idx_begin(&sl, g_pts, n, idx, m, &got)
                           : magcal_ellipse_fit_begin(&sl, g_pts, n, mask, &got);
        TEST_ASSERT_EQUAL_INT_MESSAGE(MAGCAL_OK, st, what);
        do {
            st = magcal_ellipse_fit_step(&sl, budgets[b]);
            charged += sl.used_;
            ++steps;
            TEST_ASSERT_TRUE(steps < 1000000u);
        } while (st == MAGCAL_IN_PROGRESS);
        TEST_ASSERT_EQUAL_INT_MESSAGE(st_ref, st, what);
        TEST_ASSERT_EQUAL_INT(st_ref, magcal_ellipse_fit_step(&sl, budgets[b]));
        if (st_ref == MAGCAL_OK) {
            assert_same_fit(&ref, &got);
        } else {
            TEST_ASSERT_EQUAL_MEMORY(&untouched, &got, sizeof got);
        }
        if (budgets[b] == UINT32_MAX) {
            TEST_ASSERT_EQUAL_UINT(1u, steps);
            total = charged;
        } else if (budgets[b] == 6000u) {
            steps6000 = steps;
        }
    }
    /* every step but the last spends its budget but less than one visit (the largest: 3200) */
    printf("%-28s: one-shot charges %6lu estimated M4F instructions, %3u steps at budget 6000\n", what,
           (unsigned long)total, steps6000);
    TEST_ASSERT_TRUE_MESSAGE(steps6000 <= total / 2800u + 1u, what);
    if (st_ref == MAGCAL_OK) { /* a failing one-shot call charged its last pass chunk whole */
        TEST_ASSERT_TRUE_MESSAGE((uint64_t)steps6000 * 6000u >= total, what);
    }
}

static void test_ellipse_fit_step_any_budget_matches_one_shot_bit_for_bit(void)
{
    test_distortion_t d = make_dist(1500.0, 1.15, 0.85, 10.0, 5.0, 6000.0, -4500.0);
    static uint8_t mask[1024];
    static uint16_t idx[1024];
    static const uint16_t five[5] = {3u, 200u, 410u, 600u, 800u};
    static const uint16_t five_bad[5] = {3u, 200u, 410u, 600u, 1024u};
    size_t i;
    test_make_ring(&d, 1024, 0.0, 360.0, 3.5, 7u, g_pts, NULL);
    for (i = 0; i < 1024; ++i) {
        mask[i] = (uint8_t)(i % 3u != 1u);
        idx[i] = (uint16_t)(1023u - i);
    }
    fit_sliced_matches(1024, NULL, NULL, 0, "1024 points");
    fit_sliced_matches(288, mask, NULL, 0, "288 points, mask");
    fit_sliced_matches(1024, NULL, idx, 700, "700 indices");
    fit_sliced_matches(1024, NULL, five, 5, "5-point exact path");
    fit_sliced_matches(1024, NULL, five_bad, 5, "index out of range (ARG)");
    fit_sliced_matches(4, NULL, NULL, 0, "4 points (TOO_FEW_POINTS)");
    test_make_ring(&d, 300, 0.0, 60.0, 0.5, 9u, g_pts, NULL);
    fit_sliced_matches(300, NULL, NULL, 0, "60 degree arc (HYPERBOLA)");
    for (i = 0; i < 100; ++i) {
        g_pts[i].x = 1.0f + 0.5f * (float)i;
        g_pts[i].y = -3.0f + 0.25f * (float)i;
    }
    fit_sliced_matches(100, NULL, NULL, 0, "collinear (DEGENERATE)");
    g_pts[57].y = NAN;
    fit_sliced_matches(100, NULL, NULL, 0, "NaN point (NONFINITE)");
}

static void test_ellipse_fit_step_bad_calls_return_status(void)
{
    magcal_ellipse_fit_slice_t sl;
    magcal_ellipse_t e;
    static const uint16_t idx[6] = {0u, 1u, 2u, 3u, 4u, 5u};
    memset(&sl, 0, sizeof sl);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_ellipse_fit_step(NULL, 6000u));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_ellipse_fit_step(&sl, 6000u)); /* never begun */
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_ellipse_fit_begin(&sl, NULL, 10u, NULL, &e));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_ellipse_fit_begin(&sl, g_pts, 10u, NULL, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_ellipse_fit_idx_begin(&sl, g_pts, 10u, NULL, 6u, &e));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_TOO_FEW_POINTS, magcal_ellipse_fit_idx_begin(&sl, g_pts, 10u, idx, 4u, &e));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_ellipse_fit_idx_begin(&sl, g_pts, 10u, idx, 65536u, &e));
}

/* ---------------------------------------------------------------- residual */

static void test_ellipse_residual_is_radial_distance(void)
{
    /* Ellipse r1 = 10 along x, r2 = 20 along y, centre (100, -50) (built from its conic). */
    static const float ell[5] = {0.0f, 0.25f, 0.0f, 0.0f, -1.0f};
    magcal_vec2_t c0 = {100.0f, -50.0f};
    magcal_ellipse_t e;
    magcal_vec2_t p;
    float r;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_from_conic(ell, c0, 10.0f, &e));
    p.x = 113.0f; /* 3 outside along the minor axis */
    p.y = -50.0f;
    check_within(1e-4, 3.0, magcal_ellipse_residual(&e, p), "outside, minor axis");
    p.x = 100.0f; /* 5 inside along the major axis */
    p.y = -65.0f;
    check_within(1e-4, -5.0, magcal_ellipse_residual(&e, p), "inside, major axis");
    p.x = 100.0f + 10.0f * (float)cos(0.3); /* on the ellipse */
    p.y = -50.0f + 20.0f * (float)sin(0.3);
    check_within(1e-4, 0.0, magcal_ellipse_residual(&e, p), "on the ellipse");
    p.x = 100.0f + 2.0f * 10.0f * (float)cos(2.0); /* twice the ray length: residual = ray length */
    p.y = -50.0f + 2.0f * 20.0f * (float)sin(2.0);
    r = magcal_ellipse_residual(&e, p);
    check_within(1e-4, hypot(10.0 * cos(2.0), 20.0 * sin(2.0)), r, "ray-doubled point");
    p = c0;
    check_within(1e-6, -10.0, magcal_ellipse_residual(&e, p), "centre gives -r1");
    p.x = NAN;
    TEST_ASSERT_TRUE(isnan(magcal_ellipse_residual(&e, p)));
    p.x = 0.0f;
    TEST_ASSERT_TRUE(isnan(magcal_ellipse_residual(NULL, p)));
}

/* ------------------------------------------------------------- corrections */

/* Max relative spread of |M (p - c)| over the ring, and its mean. */
static void cal_spread(const magcal_cal2d_t *cal, const magcal_vec2_t *p, size_t n, double *spread,
                       double *mean)
{
    double mn = 1e300, mxr = 0.0, sum = 0.0;
    size_t i;
    for (i = 0; i < n; ++i) {
        magcal_vec2_t h;
        double r;
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_correct_apply(cal, p[i], &h));
        r = hypot(h.x, h.y);
        mn = r < mn ? r : mn;
        mxr = r > mxr ? r : mxr;
        sum += r;
    }
    *mean = sum / (double)n;
    *spread = (mxr - mn) / *mean;
}

/* Constant heading offset psi_meas - psi_true: mean and peak-to-peak, degrees. */
static void cal_heading_offset(const magcal_cal2d_t *cal, const magcal_vec2_t *p, const float *psi,
                               size_t n, double *mean, double *ptp)
{
    double first = 0.0, lo = 1e9, hi = -1e9, sum = 0.0;
    size_t i;
    for (i = 0; i < n; ++i) {
        float mag;
        double dlt;
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_heading_compute(cal, p[i], 0.0f, &mag, NULL));
        dlt = test_angle_diff_deg(mag, psi[i]);
        if (i == 0) {
            first = dlt;
        }
        dlt = first + test_angle_diff_deg(dlt, first); /* unwrap around the first value */
        lo = dlt < lo ? dlt : lo;
        hi = dlt > hi ? dlt : hi;
        sum += dlt;
    }
    *mean = sum / (double)n;
    *ptp = hi - lo;
}

static void test_ellipse_to_cal_all_forms_map_onto_circle(void)
{
    test_distortion_t d = make_dist(0.35, 1.15, 0.80, 25.0, -10.0, 0.42, -0.27);
    magcal_ellipse_t e;
    magcal_cal2d_t sym, kx1, tri, sym1;
    double spread, mean;
    size_t i, j;
    test_make_ring(&d, 400, 0.0, 360.0, 1e-4, 11u, g_pts, g_psi);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_fit(g_pts, 400, NULL, &e));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_to_cal(&e, MAGCAL_CORR_SYMMETRIC, 0.0f, &sym));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_to_cal(&e, MAGCAL_CORR_KX1, 0.0f, &kx1));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_to_cal(&e, MAGCAL_CORR_TRIANGULAR, 1.0f, &tri));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_to_cal(&e, MAGCAL_CORR_SYMMETRIC, 1.0f, &sym1));
    /* noise 1e-4 on radius 0.28..0.40 gives a spread of a few 1e-3 at most (doc: 6e-5 rms) */
    cal_spread(&sym, g_pts, 400, &spread, &mean);
    printf("radius spread: symmetric %.2e", spread);
    check_within(3e-3, 0.0, spread, "symmetric spread");
    check_within(1e-3 * 0.3357, sqrt(0.28 * 0.4025), mean, "symmetric radius = sqrt(r1 r2)");
    check_within(1e-6, sqrt((double)e.semi_minor * e.semi_major), sym.radius,
                 "symmetric radius field");
    cal_spread(&kx1, g_pts, 400, &spread, &mean);
    printf(", kx1 %.2e", spread);
    check_within(3e-3, 0.0, spread, "kx1 spread");
    check_within(1e-3 * 0.28, 0.28, mean, "kx1 radius = r1");
    cal_spread(&tri, g_pts, 400, &spread, &mean);
    printf(", triangular %.2e\n", spread);
    check_within(3e-3, 0.0, spread, "triangular spread");
    check_within(1e-3, 1.0, mean, "triangular radius = rho");
    TEST_ASSERT_EQUAL_FLOAT(0.0f, tri.m[1][0]);
    /* M_k = r1 * M_sym(rho = 1) (algorithms.md 2.4 b) */
    for (i = 0; i < 2; ++i) {
        for (j = 0; j < 2; ++j) {
            check_within(1e-6, (double)e.semi_minor * sym1.m[i][j], kx1.m[i][j], "M_k = r1 M_sym");
        }
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cal2d_validate(&tri));
    TEST_ASSERT_EQUAL_UINT32(MAGCAL_CAL2D_MAGIC, kx1.magic);
    check_within(0.0, e.center.x, sym.offset.x, "offset = centre");
}

static void test_ellipse_to_cal_noise_free_ring_is_circle_to_float_precision(void)
{
    /* Noise-free ring at raw-count scale with a 10x offset: every form maps it onto a circle to
     * float32 precision (radius spread < 1e-5 relative) with the documented radius. */
    test_distortion_t d = make_dist(600.0, 1.3, 0.75, -55.0, 20.0, 4000.0, 5000.0);
    static const magcal_corr_form_t forms[3] = {MAGCAL_CORR_SYMMETRIC, MAGCAL_CORR_KX1,
                                                MAGCAL_CORR_TRIANGULAR};
    magcal_ellipse_t e;
    magcal_cal2d_t cal;
    double spread, mean;
    size_t i;
    test_make_ring(&d, 500, 0.0, 360.0, 0.0, 61u, g_pts, NULL);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_fit(g_pts, 500, NULL, &e));
    check_within(1e-5 * 780.0, 450.0, e.semi_minor, "r1 = 0.75 * 600");
    check_within(1e-5 * 780.0, 780.0, e.semi_major, "r2 = 1.3 * 600");
    for (i = 0; i < 3; ++i) {
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_to_cal(&e, forms[i], 0.0f, &cal));
        cal_spread(&cal, g_pts, 500, &spread, &mean);
        check_within(1e-5, 0.0, spread, "noise-free radius spread");
        check_within(1e-5 * mean, cal.radius, mean, "radius field = mean corrected radius");
        /* rho <= 0: sqrt(r1 r2) for symmetric and triangular, r1 for kx1 */
        check_within(1e-5 * mean, forms[i] == MAGCAL_CORR_KX1 ? 450.0 : sqrt(450.0 * 780.0), mean,
                     "default radius");
    }
}

static void test_ellipse_to_cal_symmetric_offset_is_phis_plus_phip(void)
{
    /* algorithms.md 1.3 / 2.4: T = R(25) diag(1.15, 0.8) R(-10): the symmetric form leaves a
     * constant heading offset phis + phip = 15.000 deg, kx1 the same. The triangular form leaves
     * beta = angle of U T, U = upper Cholesky factor of (T T^T)^-1, computed here in double from
     * the true T (23.8346 deg). Noise-free ring, so the offset must be constant to float rounding. */
    test_distortion_t d = make_dist(0.35, 1.15, 0.80, 25.0, -10.0, 0.42, -0.27);
    magcal_ellipse_t e;
    magcal_cal2d_t cal;
    double mean, ptp, beta;
    double t00 = d.t[0][0], t01 = d.t[0][1], t10 = d.t[1][0], t11 = d.t[1][1];
    /* S = T T^T, Q = S^-1 (up to 1/det, irrelevant for the angle), U = [[u00, u01], [0, u11]] */
    double s00 = t00 * t00 + t01 * t01, s01 = t00 * t10 + t01 * t11, s11 = t10 * t10 + t11 * t11;
    double q00 = s11, q01 = -s01, q11 = s00;
    double u00 = sqrt(q00), u01 = q01 / u00, u11 = sqrt(q11 - u01 * u01);
    double p00 = u00 * t00 + u01 * t10, p10 = u11 * t10;
    beta = atan2(p10, p00) * DEG_D;
    test_make_ring(&d, 400, 0.0, 360.0, 0.0, 11u, g_pts, g_psi);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_fit(g_pts, 400, NULL, &e));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_to_cal(&e, MAGCAL_CORR_SYMMETRIC, 0.35f, &cal));
    cal_heading_offset(&cal, g_pts, g_psi, 400, &mean, &ptp);
    printf("heading offset: symmetric %.4f deg (p-p %.2e)", mean, ptp);
    check_within(0.002, 15.0, mean, "symmetric offset");
    check_within(0.002, 0.0, ptp, "symmetric offset is constant");
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_to_cal(&e, MAGCAL_CORR_KX1, 0.0f, &cal));
    cal_heading_offset(&cal, g_pts, g_psi, 400, &mean, &ptp);
    printf(", kx1 %.4f", mean);
    check_within(0.002, 15.0, mean, "kx1 offset");
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_to_cal(&e, MAGCAL_CORR_TRIANGULAR, 0.0f, &cal));
    cal_heading_offset(&cal, g_pts, g_psi, 400, &mean, &ptp);
    printf(", triangular %.4f (expected %.4f, p-p %.2e)\n", mean, beta, ptp);
    check_within(0.002, beta, mean, "triangular offset");
    check_within(0.01, 23.84, beta, "triangular offset (algorithms.md 2.4)");
    check_within(0.002, 0.0, ptp, "triangular offset is constant");
}

static void test_ellipse_to_cal_symmetric_offset_noisy_mean_is_15deg(void)
{
    /* The same with noise 1e-4 (algorithms.md 2.3 data): per-sample heading noise is about
     * sigma/r = 0.02 deg, so the mean over 400 samples is within 0.005 deg. */
    test_distortion_t d = make_dist(0.35, 1.15, 0.80, 25.0, -10.0, 0.42, -0.27);
    magcal_ellipse_t e;
    magcal_cal2d_t cal;
    double mean, ptp;
    test_make_ring(&d, 400, 0.0, 360.0, 1e-4, 11u, g_pts, g_psi);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_fit(g_pts, 400, NULL, &e));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_to_cal(&e, MAGCAL_CORR_SYMMETRIC, 0.0f, &cal));
    cal_heading_offset(&cal, g_pts, g_psi, 400, &mean, &ptp);
    check_within(0.005, 15.0, mean, "symmetric offset with noise");
    check_within(0.2, 0.0, ptp, "noise-limited spread");
}

static void test_ellipse_to_cal_pure_soft_iron_recovers_heading(void)
{
    /* T symmetric (phip = -phis): M_sym removes it completely, heading error ~ noise only. */
    test_distortion_t d = make_dist(220.0, 1.25, 0.75, 35.0, -35.0, -700.0, 450.0);
    magcal_ellipse_t e;
    magcal_cal2d_t cal;
    double mean, ptp;
    test_make_ring(&d, 700, 0.0, 360.0, 0.0, 51u, g_pts, g_psi);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_fit(g_pts, 700, NULL, &e));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_to_cal(&e, MAGCAL_CORR_SYMMETRIC, 0.0f, &cal));
    cal_heading_offset(&cal, g_pts, g_psi, 700, &mean, &ptp);
    printf("pure soft iron: heading error mean %.2e deg, p-p %.2e deg\n", mean, ptp);
    check_within(0.005, 0.0, mean, "heading bias");
    check_within(0.01, 0.0, ptp, "heading error peak-to-peak");
}

/* The axis direction comes from qform without sinf/cosf: compare every form with the
 * trigonometric construction of algorithms.md 2.4 in double (theta = atan2(A, 1 - B)/2 of the
 * conic), for axes at 0, +-45, 90 deg, general angles, a circle, a near-circle and thin ellipses.
 * Tolerance 4e-6 of the largest entry: a few float32 roundings. */
static void test_ellipse_to_cal_matches_trig_construction(void)
{
    static const float ab[][2] = {{0.0f, 1.0f},   {0.0f, 0.25f}, {0.0f, 4.0f},   {1.0f, 1.0f},
                                  {-1.0f, 1.0f},  {0.6f, 0.3f},  {-0.6f, 3.0f},  {1.0e-4f, 1.0f},
                                  {1.9f, 1.0f},   {0.2f, 0.011f}, {-3.0f, 2.3f}, {0.05f, 90.0f}};
    size_t k;
    for (k = 0; k < sizeof ab / sizeof ab[0]; ++k) {
        float coef[5] = {ab[k][0], ab[k][1], 0.0f, 0.0f, -1.0f};
        magcal_vec2_t c0 = {3.0f, -2.0f};
        magcal_ellipse_t e;
        magcal_cal2d_t sym, kx1, tri;
        double th = 0.5 * atan2((double)ab[k][0], 1.0 - (double)ab[k][1]);
        double c = cos(th), s = sin(th), r1, r2, i1, i2, a1, a2, q11, q12, big, tol;
        double want[3][2][2];
        size_t f, i, j;
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_from_conic(coef, c0, 2.0f, &e));
        r1 = e.semi_minor;
        r2 = e.semi_major;
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_to_cal(&e, MAGCAL_CORR_SYMMETRIC, 1.5f, &sym));
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_to_cal(&e, MAGCAL_CORR_KX1, 0.0f, &kx1));
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_to_cal(&e, MAGCAL_CORR_TRIANGULAR, 1.5f, &tri));
        i1 = 1.5 / r1;
        i2 = 1.5 / r2;
        want[0][0][0] = c * c * i1 + s * s * i2;
        want[0][0][1] = c * s * (i1 - i2);
        want[0][1][0] = want[0][0][1];
        want[0][1][1] = s * s * i1 + c * c * i2;
        for (i = 0; i < 2; ++i) {
            for (j = 0; j < 2; ++j) {
                want[1][i][j] = want[0][i][j] * r1 / 1.5; /* kx1, rho <= 0: radius r1 */
            }
        }
        a1 = 1.0 / (r1 * r1);
        a2 = 1.0 / (r2 * r2);
        q11 = c * c * a1 + s * s * a2;
        q12 = c * s * (a1 - a2);
        want[2][0][0] = 1.5 * sqrt(q11);
        want[2][0][1] = 1.5 * q12 / sqrt(q11);
        want[2][1][0] = 0.0;
        want[2][1][1] = 1.5 / (r1 * r2 * sqrt(q11));
        for (f = 0; f < 3; ++f) {
            const magcal_cal2d_t *got = f == 0 ? &sym : (f == 1 ? &kx1 : &tri);
            big = 0.0;
            for (i = 0; i < 2; ++i) {
                for (j = 0; j < 2; ++j) {
                    big = fmax(big, fabs(want[f][i][j]));
                }
            }
            tol = 4e-6 * big;
            for (i = 0; i < 2; ++i) {
                for (j = 0; j < 2; ++j) {
                    check_within(tol, want[f][i][j], got->m[i][j], "M entry vs trig construction");
                }
            }
        }
    }
}

/* ------------------------------------- the source documents' form (K Phi_p, kx = 1) */

/* The documents' distortion Hm = s K Phi_p H + b, K = diag(1, ky), Phi_p = [[c, s], [s, c]]
 * (OPTICS ellipse paper eq. 8 / compass-swing article, phi_s = 0), in the library's axes. */
static test_distortion_t make_kphi(double h0, double scale, double ky, double phip_deg, double bx,
                                   double by)
{
    test_distortion_t d;
    double c = cos(phip_deg / DEG_D), sn = sin(phip_deg / DEG_D);
    d.h0 = (float)h0;
    d.t[0][0] = (float)(scale * c);
    d.t[0][1] = (float)(scale * sn);
    d.t[1][0] = (float)(scale * ky * sn);
    d.t[1][1] = (float)(scale * ky * c);
    d.bx = (float)bx;
    d.by = (float)by;
    return d;
}

/* beta = atan2((ky - kx) sin p, (kx + ky) cos p): the rotation of the polar decomposition of
 * K Phi_p, in degrees (issue 17). */
static double kphi_beta_deg(double ky, double phip_deg)
{
    return atan2((ky - 1.0) * sin(phip_deg / DEG_D), (1.0 + ky) * cos(phip_deg / DEG_D)) * DEG_D;
}

static void test_ellipse_kphi_recovers_documents_coefficients(void)
{
    /* Noise-free rings of the documents' model: ky, phi_p, h_x = scale * H0 and b come back to
     * float rounding; ky > 1, negative phi_p and a large offset included. */
    static const double cases[][3] = {{0.9, 3.0, 1.0},  {0.8, 5.0, 0.7},   {0.7, 10.0, 1.3},
                                      {1.25, -7.0, 1.0}, {0.6, -30.0, 2.0}, {1.0, 0.0, 1.0}};
    size_t k;
    for (k = 0; k < sizeof cases / sizeof cases[0]; ++k) {
        test_distortion_t d = make_kphi(0.35, cases[k][2], cases[k][0], cases[k][1], 0.42, -1.27);
        magcal_ellipse_t e;
        magcal_ellipse_kphi_t c;
        test_make_ring(&d, 400, 0.0, 360.0, 0.0, 17u, g_pts, g_psi);
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_fit(g_pts, 400, NULL, &e));
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_kphi(&e, &c));
        check_within(2e-5 * cases[k][0], cases[k][0], c.ky, "ky");
        check_within(2e-4, cases[k][1], c.phi_p_rad * DEG_D, "phi_p (deg)");
        check_within(2e-5 * 0.35 * cases[k][2], 0.35 * cases[k][2], c.h_x, "h_x = H0 kx");
        check_within(2e-4, kphi_beta_deg(cases[k][0], cases[k][1]), c.beta_rad * DEG_D, "beta");
        check_within(2e-6, 0.42, c.b.x, "bx");
        check_within(2e-6, -1.27, c.b.y, "by");
    }
}

static void test_ellipse_to_cal_kphi_documents_model_leaves_no_rotation(void)
{
    /* Data from the documents' model: the documents' form leaves no constant heading rotation,
     * the product's symmetric forms leave beta. Issue 17 measured -0.16 / -0.56 / -1.78 deg at
     * (ky, phi_p) = (0.9, 3), (0.8, 5), (0.7, 10). Errors are measured minus true. */
    static const double cases[][3] = {{0.9, 3.0, -0.16}, {0.8, 5.0, -0.56}, {0.7, 10.0, -1.78}};
    size_t k;
    for (k = 0; k < sizeof cases / sizeof cases[0]; ++k) {
        test_distortion_t d = make_kphi(20.0, 1.0, cases[k][0], cases[k][1], 12.0, -7.0);
        magcal_ellipse_t e;
        magcal_cal2d_t cal;
        double m_kphi, m_sym, m_kx1, m_tri, ptp, r;
        double beta = kphi_beta_deg(cases[k][0], cases[k][1]);
        test_make_ring(&d, 720, 0.0, 360.0, 0.0, 23u, g_pts, g_psi);
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_fit(g_pts, 720, NULL, &e));
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_to_cal(&e, MAGCAL_CORR_KPHI, 0.0f, &cal));
        cal_heading_offset(&cal, g_pts, g_psi, 720, &m_kphi, &ptp);
        check_within(0.002, 0.0, m_kphi, "documents' form on documents' model: no rotation");
        check_within(0.002, 0.0, ptp, "documents' form: heading error constant");
        /* default radius h_x = H0 kx = 20 (the documents' inverse with kx = 1 exactly) */
        r = test_radius_spread(&cal, g_pts, NULL, 720);
        check_within(1e-5, 0.0, r, "documents' form maps onto a circle");
        check_within(1e-4, 20.0, cal.radius, "default radius h_x = H0");
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_to_cal(&e, MAGCAL_CORR_SYMMETRIC, 0.0f, &cal));
        cal_heading_offset(&cal, g_pts, g_psi, 720, &m_sym, &ptp);
        check_within(0.002, beta, m_sym, "symmetric form leaves beta");
        check_within(0.002, 0.0, ptp, "symmetric: heading error constant");
        check_within(0.005, cases[k][2], m_sym, "issue 17's measured value");
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_to_cal(&e, MAGCAL_CORR_KX1, 0.0f, &cal));
        cal_heading_offset(&cal, g_pts, g_psi, 720, &m_kx1, &ptp);
        check_within(0.002, beta, m_kx1, "kx1 (symmetric, radius r1) leaves beta");
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_to_cal(&e, MAGCAL_CORR_TRIANGULAR, 0.0f, &cal));
        cal_heading_offset(&cal, g_pts, g_psi, 720, &m_tri, &ptp);
        printf("documents' model ky %.2f phi_p %.0f: KPHI %+.4f, SYMMETRIC %+.4f, KX1 %+.4f, "
               "TRIANGULAR %+.4f deg (beta %+.4f)\n",
               cases[k][0], cases[k][1], m_kphi, m_sym, m_kx1, m_tri, beta);
    }
}

static void test_ellipse_to_cal_kphi_symmetric_soft_iron_leaves_minus_beta(void)
{
    /* Data from a symmetric soft iron T = R(a) diag(k1, k2) R(-a): the symmetric form leaves no
     * rotation, the documents' form leaves -beta of the (ky, phi_p) it fits. beta is computed
     * here in double from the true T: S = T T^T, ky = sqrt(S22/S11), sin 2p = S12/sqrt(S11 S22). */
    static const double cases[][3] = {{1.10, 0.92, 25.0}, {1.2, 0.8, 20.0}, {1.25, 0.75, -35.0}};
    size_t k;
    for (k = 0; k < sizeof cases / sizeof cases[0]; ++k) {
        test_distortion_t d =
            make_dist(20.0, cases[k][0], cases[k][1], cases[k][2], -cases[k][2], -30.0, 18.0);
        double t00 = d.t[0][0], t01 = d.t[0][1], t10 = d.t[1][0], t11 = d.t[1][1];
        double s00 = t00 * t00 + t01 * t01, s01 = t00 * t10 + t01 * t11;
        double s11 = t10 * t10 + t11 * t11;
        double ky = sqrt(s11 / s00), p = 0.5 * asin(s01 / sqrt(s00 * s11)) * DEG_D;
        double beta = kphi_beta_deg(ky, p);
        magcal_ellipse_t e;
        magcal_ellipse_kphi_t c;
        magcal_cal2d_t cal;
        double m_kphi, m_sym, ptp;
        test_make_ring(&d, 720, 0.0, 360.0, 0.0, 29u, g_pts, g_psi);
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_fit(g_pts, 720, NULL, &e));
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_kphi(&e, &c));
        check_within(2e-5, ky, c.ky, "fitted ky");
        check_within(2e-4, p, c.phi_p_rad * DEG_D, "fitted phi_p");
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_to_cal(&e, MAGCAL_CORR_SYMMETRIC, 0.0f, &cal));
        cal_heading_offset(&cal, g_pts, g_psi, 720, &m_sym, &ptp);
        check_within(0.002, 0.0, m_sym, "symmetric form on symmetric soft iron: no rotation");
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_to_cal(&e, MAGCAL_CORR_KPHI, 0.0f, &cal));
        cal_heading_offset(&cal, g_pts, g_psi, 720, &m_kphi, &ptp);
        check_within(0.002, -beta, m_kphi, "documents' form leaves -beta");
        check_within(0.002, 0.0, ptp, "documents' form: heading error constant");
        TEST_ASSERT_TRUE(fabs(beta) > 0.2); /* the cases are chosen so the difference shows */
        printf("symmetric soft iron %.2f/%.2f at %.0f deg: SYMMETRIC %+.4f, KPHI %+.4f deg "
               "(-beta %+.4f; fitted ky %.4f phi_p %.3f)\n",
               cases[k][0], cases[k][1], cases[k][2], m_sym, m_kphi, -beta, c.ky,
               c.phi_p_rad * DEG_D);
    }
}

static void test_ellipse_kphi_bad_input_returns_status(void)
{
    magcal_ellipse_t e;
    magcal_ellipse_kphi_t c;
    magcal_cal2d_t cal;
    float coef[5] = {0.0f, 1.0f, 0.0f, 0.0f, -1.0f};
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_from_conic(coef, (magcal_vec2_t){0.0f, 0.0f},
                                                               1.0f, &e));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_ellipse_kphi(NULL, &c));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_ellipse_kphi(&e, NULL));
    /* circle: ky = 1, phi_p = 0, M = I */
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_kphi(&e, &c));
    check_within(1e-6, 1.0, c.ky, "circle ky");
    check_within(1e-6, 0.0, c.phi_p_rad, "circle phi_p");
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_to_cal(&e, MAGCAL_CORR_KPHI, 0.0f, &cal));
    check_within(1e-6, 1.0, cal.m[0][0], "circle M00");
    check_within(1e-6, 0.0, cal.m[0][1], "circle M01");
    check_within(1e-6, 1.0, cal.m[1][1], "circle M11");
    e.semi_minor = -1.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_ellipse_kphi(&e, &c));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_ellipse_to_cal(&e, MAGCAL_CORR_KPHI, 1.0f, &cal));
}

static void test_ellipse_to_cal_bad_input_returns_status(void)
{
    static const float ell[5] = {0.0f, 0.25f, 0.0f, 0.0f, -1.0f};
    magcal_vec2_t c0 = {0.0f, 0.0f};
    magcal_ellipse_t e;
    magcal_cal2d_t cal;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_from_conic(ell, c0, 1.0f, &e));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL,
                          magcal_ellipse_to_cal(NULL, MAGCAL_CORR_SYMMETRIC, 1.0f, &cal));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL,
                          magcal_ellipse_to_cal(&e, MAGCAL_CORR_SYMMETRIC, 1.0f, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG,
                          magcal_ellipse_to_cal(&e, (magcal_corr_form_t)7, 1.0f, &cal));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE,
                          magcal_ellipse_to_cal(&e, MAGCAL_CORR_SYMMETRIC, NAN, &cal));
    e.semi_minor = 3.0f; /* r1 > r2 */
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG,
                          magcal_ellipse_to_cal(&e, MAGCAL_CORR_SYMMETRIC, 1.0f, &cal));
    e.semi_minor = 0.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG,
                          magcal_ellipse_to_cal(&e, MAGCAL_CORR_TRIANGULAR, 1.0f, &cal));
    /* the axis direction is read from qform: a non-positive q11 or a NaN entry is no ellipse */
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_from_conic(ell, c0, 1.0f, &e));
    e.qform[0] = 0.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG,
                          magcal_ellipse_to_cal(&e, MAGCAL_CORR_SYMMETRIC, 1.0f, &cal));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_from_conic(ell, c0, 1.0f, &e));
    e.qform[1] = NAN;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_ellipse_to_cal(&e, MAGCAL_CORR_KX1, 1.0f, &cal));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_ellipse_fit_alg23_example_recovers_truth);
    RUN_TEST(test_ellipse_fit_kx_below_ky_angle_is_phis);
    RUN_TEST(test_ellipse_fit_circle_has_equal_axes);
    RUN_TEST(test_ellipse_fit_matches_double_reference_1e4);
    RUN_TEST(test_ellipse_fit_coef_inverse_transform_matches_direct_fit);
    RUN_TEST(test_ellipse_fit_offset20_float32_matches_double_seed_fails);
    RUN_TEST(test_ellipse_fit_offset5_counts25000_meets_1e4_seed_does_not);
    RUN_TEST(test_ellipse_fit_full_int16_range_is_accurate);
    RUN_TEST(test_ellipse_fit_half_turn_at_offset20_matches_double_reference);
    RUN_TEST(test_ellipse_fit_matches_numpy_golden_values);
    RUN_TEST(test_ellipse_fit_60deg_arc_returns_hyperbola);
    RUN_TEST(test_ellipse_fit_bad_input_returns_specific_status);
    RUN_TEST(test_ellipse_fit_degenerate_points_return_degenerate);
    RUN_TEST(test_ellipse_fit_points_on_two_axes_return_ill_conditioned);
    RUN_TEST(test_ellipse_fit_exact_parabola_returns_parabola);
    RUN_TEST(test_ellipse_from_conic_classifies_and_maps_back);
    RUN_TEST(test_ellipse_fit_idx_five_points_exact);
    RUN_TEST(test_ellipse_fit_idx_bad_subsets_return_status);
    RUN_TEST(test_ellipse_fit_idx_and_mask_equal_compacted_fit);
    RUN_TEST(test_ellipse_fit_step_any_budget_matches_one_shot_bit_for_bit);
    RUN_TEST(test_ellipse_fit_step_bad_calls_return_status);
    RUN_TEST(test_ellipse_residual_is_radial_distance);
    RUN_TEST(test_ellipse_to_cal_all_forms_map_onto_circle);
    RUN_TEST(test_ellipse_to_cal_noise_free_ring_is_circle_to_float_precision);
    RUN_TEST(test_ellipse_to_cal_symmetric_offset_is_phis_plus_phip);
    RUN_TEST(test_ellipse_to_cal_symmetric_offset_noisy_mean_is_15deg);
    RUN_TEST(test_ellipse_to_cal_pure_soft_iron_recovers_heading);
    RUN_TEST(test_ellipse_to_cal_matches_trig_construction);
    RUN_TEST(test_ellipse_to_cal_bad_input_returns_status);
    RUN_TEST(test_ellipse_kphi_recovers_documents_coefficients);
    RUN_TEST(test_ellipse_to_cal_kphi_documents_model_leaves_no_rotation);
    RUN_TEST(test_ellipse_to_cal_kphi_symmetric_soft_iron_leaves_minus_beta);
    RUN_TEST(test_ellipse_kphi_bad_input_returns_status);
    return UNITY_END();
}
