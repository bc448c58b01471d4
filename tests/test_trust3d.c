/*
 * "Silent wrong answer" suite of the 3-D fit (issue 12): hostile synthetic data with known truth.
 * For every case and every model (AUTO, QUADRIC9, QUADRIC10, SPHERE) magcal_ellipsoid_fit must
 * either return OK with an accurate calibration, or refuse with a non-OK status. Accurate means:
 * hard iron |V - V_true| <= 2 % of F and tilt-compensated heading within 1 deg of the truth at every
 * test attitude (roll, pitch in {-20, 0, 20} deg, yaw 0..345 deg in 15 deg steps; noise-free samples
 * through the fitted calibration). Truth W is symmetric (soft iron + scale), so G = W^-1 exactly and
 * the attitude-free rotation ambiguity does not enter the heading.
 * Generators: below, fixed seeds (double precision, test code only).
 * magcal:host-only (about 3000 fits; the suite is a host test)
 */
#include <math.h>
#include <stdio.h>
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
#define NMAX 2000
#define TOL_V_REL 0.02
#define TOL_HDG_DEG 1.0
#define TOL_FLOOR_RATIO 1.2

/* NED field (uT): F = 48.37, inclination 65.5 deg; hard iron (uT). */
static const double B_NED[3] = {20.0, 1.2, 44.0};
static const double V_TRUE[3] = {18.0, -11.0, 27.0};

static magcal_vec3_t g_m[NMAX];
static double g_sigma; /* noise (uT, per axis) of the case last generated */

typedef struct {
    const char *name;
    unsigned cases;
    unsigned ok_good;
    unsigned refused;
    unsigned wrong;
    unsigned ok_floor; /* of ok_good: beyond 1 deg at some attitude, within the floor ratio */
    unsigned info;     /* 1: a measured class beyond the spec, not asserted, not in TOTAL */
    unsigned by_status[48]; /* index -status */
} tally_t;

static double f_ref(void)
{
    return sqrt(B_NED[0] * B_NED[0] + B_NED[1] * B_NED[1] + B_NED[2] * B_NED[2]);
}

static void mat_ident(double w[3][3], double s)
{
    int i, j;
    for (i = 0; i < 3; ++i) {
        for (j = 0; j < 3; ++j) {
            w[i][j] = (i == j) ? s : 0.0;
        }
    }
}

/* Symmetric soft iron: R diag(d) R^T, R = Rz(az) Rx(el). */
static void make_w_sym(double d0, double d1, double d2, double az, double el, double w[3][3])
{
    double rz[3][3], rx[3][3], r[3][3], dm[3][3], t[3][3], rt[3][3];
    int i, j;
    test_rot3(2, az, rz);
    test_rot3(0, el, rx);
    test_mat3_mul(rz, rx, r);
    mat_ident(dm, 1.0);
    dm[0][0] = d0;
    dm[1][1] = d1;
    dm[2][2] = d2;
    for (i = 0; i < 3; ++i) {
        for (j = 0; j < 3; ++j) {
            rt[i][j] = r[j][i];
        }
    }
    test_mat3_mul(r, dm, t);
    test_mat3_mul(t, rt, w);
}

static const double W_MILD_D[3] = {1.06, 0.95, 1.01};

static void w_mild(double w[3][3])
{
    make_w_sym(W_MILD_D[0], W_MILD_D[1], W_MILD_D[2], 0.4, 0.3, w);
}

static magcal_vec3_t raw_of(double w[3][3], const double v[3], const double h[3], double sigma, uint32_t *rng)
{
    magcal_vec3_t o;
    double m[3];
    int i;
    for (i = 0; i < 3; ++i) {
        m[i] = w[i][0] * h[0] + w[i][1] * h[1] + w[i][2] * h[2] + v[i] +
               ((sigma > 0.0) ? sigma * test_rand_normal(rng) : 0.0);
    }
    o.x = (float)m[0];
    o.y = (float)m[1];
    o.z = (float)m[2];
    return o;
}

static void body_field(double roll, double pitch, double yaw, double h[3])
{
    double c[3][3];
    int i;
    test_dcm_ned(roll, pitch, yaw, c);
    for (i = 0; i < 3; ++i) {
        h[i] = c[0][i] * B_NED[0] + c[1][i] * B_NED[1] + c[2][i] * B_NED[2];
    }
}

/* Tilt-compensated magnetic heading (deg) of a calibrated body field (algorithms.md 6). */
static double heading_deg(const double h[3], double roll, double pitch)
{
    double cf = cos(roll), sf = sin(roll), ct = cos(pitch), st = sin(pitch);
    double lx = h[0] * cf + h[2] * sf;
    double ly = h[1] * ct + st * (h[0] * sf - h[2] * cf);
    return atan2(-lx, ly) / D2R;
}

/* Worst heading error (deg) of a calibration over the test attitudes, and the offset error / F. */
static void accuracy(const magcal_ellipsoid_cal_t *cal, double w[3][3], double *hdg_max, double *v_rel)
{
    static const double tilts[3] = {-20.0, 0.0, 20.0};
    double worst = 0.0, dx, dy, dz;
    int a, b, y, i;
    for (a = 0; a < 3; ++a) {
        for (b = 0; b < 3; ++b) {
            for (y = 0; y < 24; ++y) {
                double roll = tilts[a] * D2R, pitch = tilts[b] * D2R, yaw = 15.0 * y * D2R;
                double h[3], m[3], e[3], hf[3], d;
                body_field(roll, pitch, yaw, h);
                for (i = 0; i < 3; ++i) {
                    m[i] = w[i][0] * h[0] + w[i][1] * h[1] + w[i][2] * h[2] + V_TRUE[i];
                }
                e[0] = m[0] - cal->v.x;
                e[1] = m[1] - cal->v.y;
                e[2] = m[2] - cal->v.z;
                for (i = 0; i < 3; ++i) {
                    hf[i] = cal->g[i][0] * e[0] + cal->g[i][1] * e[1] + cal->g[i][2] * e[2];
                }
                d = fabs(test_angle_diff_deg(heading_deg(hf, roll, pitch), heading_deg(h, roll, pitch)));
                if (!(d <= worst)) {
                    worst = d;
                }
            }
        }
    }
    dx = cal->v.x - V_TRUE[0];
    dy = cal->v.y - V_TRUE[1];
    dz = cal->v.z - V_TRUE[2];
    *hdg_max = worst;
    *v_rel = sqrt(dx * dx + dy * dy + dz * dz) / f_ref();
}

/*
 * The 2-D floor ratio, in 3-D: heading RMS over noisy samples at the test attitudes (4 draws of the
 * case's noise each) through the fitted calibration, divided by the same through the true one (the
 * floor: what perfect calibration gives on this sensor's noise).
 */
static double floor_ratio(const magcal_ellipsoid_cal_t *cal, double w[3][3])
{
    static const double tilts[3] = {-20.0, 0.0, 20.0};
    double wi[3][3], sf = 0.0, st = 0.0;
    uint32_t rng = 4242u;
    int a, b, y, d, i;
    test_mat3_inv(w, wi);
    for (a = 0; a < 3; ++a) {
        for (b = 0; b < 3; ++b) {
            for (y = 0; y < 24; ++y) {
                for (d = 0; d < 4; ++d) {
                    double roll = tilts[a] * D2R, pitch = tilts[b] * D2R, yaw = 15.0 * y * D2R;
                    double h[3], e[3], et[3], hf[3], ht[3], href;
                    magcal_vec3_t m;
                    body_field(roll, pitch, yaw, h);
                    href = heading_deg(h, roll, pitch);
                    m = raw_of(w, V_TRUE, h, g_sigma, &rng);
                    e[0] = m.x - cal->v.x;
                    e[1] = m.y - cal->v.y;
                    e[2] = m.z - cal->v.z;
                    et[0] = m.x - V_TRUE[0];
                    et[1] = m.y - V_TRUE[1];
                    et[2] = m.z - V_TRUE[2];
                    for (i = 0; i < 3; ++i) {
                        hf[i] = cal->g[i][0] * e[0] + cal->g[i][1] * e[1] + cal->g[i][2] * e[2];
                        ht[i] = wi[i][0] * et[0] + wi[i][1] * et[1] + wi[i][2] * et[2];
                    }
                    sf += pow(test_angle_diff_deg(heading_deg(hf, roll, pitch), href), 2.0);
                    st += pow(test_angle_diff_deg(heading_deg(ht, roll, pitch), href), 2.0);
                }
            }
        }
    }
    return (st > 0.0) ? sqrt(sf / st) : INFINITY;
}

static const magcal_ellipsoid_model_t MODELS[4] = {MAGCAL_ELLIPSOID_MODEL_AUTO, MAGCAL_ELLIPSOID_MODEL_QUADRIC9,
                                                   MAGCAL_ELLIPSOID_MODEL_QUADRIC10, MAGCAL_ELLIPSOID_MODEL_SPHERE};
static int g_verbose;

/* Fit g_m[0..n) with one model and judge it. Returns the status. */
static magcal_status_t judge(tally_t *t, size_t n, double w[3][3], magcal_ellipsoid_model_t model, const char *what)
{
    magcal_ellipsoid_cfg_t cfg = MAGCAL_ELLIPSOID_CFG_DEFAULT;
    magcal_ellipsoid_result_t r;
    magcal_status_t st;
    cfg.model = model;
    st = magcal_ellipsoid_fit(g_m, n, &cfg, &g_fit_scratch, &r);
    t->cases++;
    if (st == MAGCAL_OK) {
        double hmax, vrel;
        double ratio;
        accuracy(&r.cal, w, &hmax, &vrel);
        ratio = floor_ratio(&r.cal, w);
        if (vrel <= TOL_V_REL && (hmax <= TOL_HDG_DEG || ratio <= TOL_FLOOR_RATIO)) {
            t->ok_good++;
            if (hmax > TOL_HDG_DEG) {
                t->ok_floor++;
            }
        } else {
            t->wrong++;
            printf("  %s [%s] %s model %d: heading %.2f deg (floor ratio %.2f), |dV| %.2f %% F, resid %.4f F, "
                   "centre_std %.4f, snr %.1f, planarity %.3f, cov %.2f\n",
                   t->info ? "(info, not asserted) wrong" : "SILENT WRONG", t->name, what, (int)r.model, hmax, ratio, 100.0 * vrel, (double)(r.residual_rms / r.cal.field),
                   (double)r.centre_std_rel, (double)r.motion_snr, (double)r.planarity, (double)r.coverage);
        }
    } else {
        t->refused++;
        if (-(int)st >= 0 && -(int)st < 48) {
            t->by_status[-(int)st]++;
        }
    }
    if (g_verbose) {
        magcal_ellipsoid_cfg_t c0 = cfg;
        magcal_ellipsoid_result_t r0;
        magcal_status_t s0;
        double hmax = NAN, vrel = NAN;
        c0.min_motion_snr = 0.0f;
        c0.max_centre_std_rel = 0.0f;
        c0.max_shape_std = 0.0f;
        c0.max_residual_rel = 0.0f;
        c0.max_residual_rel_sphere = 0.0f;
        s0 = magcal_ellipsoid_fit(g_m, n, &c0, &g_fit_scratch, &r0);
        if (s0 == MAGCAL_OK) {
            accuracy(&r0.cal, w, &hmax, &vrel);
        }
        printf("  [%s] %s m%d: %s | ungated %s m%d hdg %.2f dV %.2f%% res %.4f cstd %.5f snr %.1f pl %.3f\n",
               t->name, what, (int)model, magcal_status_str(st), magcal_status_str(s0), (int)r0.model, hmax,
               100.0 * vrel, (s0 == MAGCAL_OK) ? (double)(r0.residual_rms / r0.cal.field) : NAN,
               (s0 == MAGCAL_OK) ? (double)r0.centre_std_rel : NAN, (s0 == MAGCAL_OK) ? (double)r0.motion_snr : NAN,
               (s0 == MAGCAL_OK) ? (double)r0.planarity : NAN);
    }
    return st;
}

static void judge_all(tally_t *t, size_t n, double w[3][3], const char *what)
{
    int k;
    for (k = 0; k < 4; ++k) {
        (void)judge(t, n, w, MODELS[k], what);
    }
}

static void report(const tally_t *t)
{
    int i;
    printf("%-26s cases %4u  ok-within-tolerance %4u (by floor ratio %u)  refused %4u  silent-wrong %u  |", t->name,
           t->cases, t->ok_good, t->ok_floor, t->refused, t->wrong);
    for (i = 1; i < 48; ++i) {
        if (t->by_status[i] != 0u) {
            const char *nm = magcal_status_str((magcal_status_t)(-i));
            const char *par = strstr(nm, " (");
            printf(" %.*s:%u", (int)((par != NULL) ? (size_t)(par - nm) : strlen(nm)), nm, t->by_status[i]);
        }
    }
    printf("\n");
}

/* ---------------------------------------------------------------- generators */

/* Rotation about one body-fixed axis (tilt from body z, azimuth 30 deg): the field sweeps a cone of
 * half-angle `cone` about it; `wobble` (deg) modulates the cone angle (2 sinusoids). */
static size_t gen_cone(double w[3][3], double tilt_deg, double cone_deg, double wobble_deg, double sigma, size_t n,
                       uint32_t seed)
{
    g_sigma = sigma;
    uint32_t rng = seed;
    double a[3], e1[3], e2[3], f = f_ref(), az = 30.0 * D2R, tl = tilt_deg * D2R;
    double ph = 2.0 * PI_D * test_rand_uniform(&rng);
    size_t k;
    a[0] = sin(tl) * cos(az);
    a[1] = sin(tl) * sin(az);
    a[2] = cos(tl);
    /* e1 = unit(a x x-ish), e2 = a x e1 */
    {
        double t[3] = {0.0, 0.0, 0.0}, nn;
        t[(fabs(a[0]) < 0.9) ? 0 : 1] = 1.0;
        e1[0] = a[1] * t[2] - a[2] * t[1];
        e1[1] = a[2] * t[0] - a[0] * t[2];
        e1[2] = a[0] * t[1] - a[1] * t[0];
        nn = sqrt(e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2]);
        e1[0] /= nn;
        e1[1] /= nn;
        e1[2] /= nn;
        e2[0] = a[1] * e1[2] - a[2] * e1[1];
        e2[1] = a[2] * e1[0] - a[0] * e1[2];
        e2[2] = a[0] * e1[1] - a[1] * e1[0];
    }
    for (k = 0; k < n; ++k) {
        double th = 2.0 * PI_D * (double)k / (double)n * 1.5; /* 1.5 turns */
        double al = (cone_deg + wobble_deg * 0.5 * (sin(3.0 * th + ph) + cos(5.0 * th))) * D2R;
        double h[3];
        int i;
        for (i = 0; i < 3; ++i) {
            h[i] = f * (cos(al) * a[i] + sin(al) * (cos(th) * e1[i] + sin(th) * e2[i]));
        }
        g_m[k] = raw_of(w, V_TRUE, h, sigma, &rng);
    }
    return n;
}

/* Attitudes: yaw uniform, roll/pitch uniform in +-max_tilt; max_tilt >= 90: uniform directions. */
static size_t gen_attitudes(double w[3][3], double max_tilt_deg, double sigma, size_t n, uint32_t seed)
{
    g_sigma = sigma;
    uint32_t rng = seed;
    size_t k;
    for (k = 0; k < n; ++k) {
        double yaw = 2.0 * PI_D * test_rand_uniform(&rng), pitch, roll, h[3];
        if (max_tilt_deg >= 90.0) {
            pitch = asin(2.0 * test_rand_uniform(&rng) - 1.0);
            roll = (2.0 * test_rand_uniform(&rng) - 1.0) * PI_D;
        } else {
            pitch = (2.0 * test_rand_uniform(&rng) - 1.0) * max_tilt_deg * D2R;
            roll = (2.0 * test_rand_uniform(&rng) - 1.0) * max_tilt_deg * D2R;
        }
        body_field(roll, pitch, yaw, h);
        g_m[k] = raw_of(w, V_TRUE, h, sigma, &rng);
    }
    return n;
}

/* Field directions uniform in the band |u . a| <= sin(half_deg) about a random axis a. */
static size_t gen_dir_band(double w[3][3], double half_deg, double sigma, size_t n, uint32_t seed)
{
    g_sigma = sigma;
    uint32_t rng = seed;
    double a[3], e1[3], e2[3], f = f_ref(), zmax = sin(half_deg * D2R);
    double az = 2.0 * PI_D * test_rand_uniform(&rng), el = asin(2.0 * test_rand_uniform(&rng) - 1.0);
    size_t k;
    a[0] = cos(el) * cos(az);
    a[1] = cos(el) * sin(az);
    a[2] = sin(el);
    e1[0] = -sin(az);
    e1[1] = cos(az);
    e1[2] = 0.0;
    e2[0] = a[1] * e1[2] - a[2] * e1[1];
    e2[1] = a[2] * e1[0] - a[0] * e1[2];
    e2[2] = a[0] * e1[1] - a[1] * e1[0];
    for (k = 0; k < n; ++k) {
        double z = (2.0 * test_rand_uniform(&rng) - 1.0) * zmax, th = 2.0 * PI_D * test_rand_uniform(&rng);
        double rho = sqrt(1.0 - z * z), h[3];
        int i;
        for (i = 0; i < 3; ++i) {
            h[i] = f * (z * a[i] + rho * (cos(th) * e1[i] + sin(th) * e2[i]));
        }
        g_m[k] = raw_of(w, V_TRUE, h, sigma, &rng);
    }
    return n;
}

/* Sensor at rest: one attitude, noise only. */
static size_t gen_rest(double w[3][3], double sigma, size_t n, uint32_t seed)
{
    g_sigma = sigma;
    uint32_t rng = seed;
    double h[3];
    size_t k;
    body_field(0.3 * test_rand_uniform(&rng), 0.2, 2.0 * PI_D * test_rand_uniform(&rng), h);
    for (k = 0; k < n; ++k) {
        g_m[k] = raw_of(w, V_TRUE, h, sigma, &rng);
    }
    return n;
}

/* Full rotation plus a burst: `frac` of the samples in one contiguous block where the hard iron
 * moved by `shift` uT (random direction); dense = at one attitude (+-2 deg), else random attitudes. */
static size_t gen_burst(double w[3][3], double frac, double shift, int dense, double sigma, size_t n, uint32_t seed)
{
    uint32_t rng = seed ^ 0x5a5a5a5au;
    size_t nb = (size_t)(frac * (double)n + 0.5), k0, k;
    double dv[3], nn, v2[3], r0, p0, y0;
    (void)gen_attitudes(w, 180.0, sigma, n, seed);
    dv[0] = test_rand_normal(&rng);
    dv[1] = test_rand_normal(&rng);
    dv[2] = test_rand_normal(&rng);
    nn = sqrt(dv[0] * dv[0] + dv[1] * dv[1] + dv[2] * dv[2]);
    for (k = 0; k < 3; ++k) {
        v2[k] = V_TRUE[k] + shift * dv[k] / nn;
    }
    r0 = (2.0 * test_rand_uniform(&rng) - 1.0) * PI_D;
    p0 = asin(2.0 * test_rand_uniform(&rng) - 1.0);
    y0 = 2.0 * PI_D * test_rand_uniform(&rng);
    k0 = (size_t)(test_rand_uniform(&rng) * (double)(n - nb));
    for (k = k0; k < k0 + nb; ++k) {
        double h[3], j = 2.0 * D2R;
        if (dense) {
            body_field(r0 + j * test_rand_normal(&rng), p0 + j * test_rand_normal(&rng),
                       y0 + j * test_rand_normal(&rng), h);
        } else {
            body_field((2.0 * test_rand_uniform(&rng) - 1.0) * PI_D, asin(2.0 * test_rand_uniform(&rng) - 1.0),
                       2.0 * PI_D * test_rand_uniform(&rng), h);
        }
        g_m[k] = raw_of(w, v2, h, sigma, &rng);
    }
    return n;
}

/* ---------------------------------------------------------------- the suite */

static tally_t g_total;

static void add_total(const tally_t *t)
{
    int i;
    g_total.cases += t->cases;
    g_total.ok_good += t->ok_good;
    g_total.refused += t->refused;
    g_total.wrong += t->wrong;
    g_total.ok_floor += t->ok_floor;
    for (i = 0; i < 48; ++i) {
        g_total.by_status[i] += t->by_status[i];
    }
}

static void test_trust3d_cone_sweeps_never_silently_wrong(void)
{
    static const double tilts[7] = {0, 15, 30, 45, 60, 75, 90};
    static const double cones[9] = {10, 30, 50, 70, 90, 110, 130, 150, 170};
    static const double sig[2] = {0.001, 0.005};
    tally_t t0 = {"cone, no wobble", 0, 0, 0, 0, 0, 0, {0}}, t2 = {"cone, 2 deg wobble", 0, 0, 0, 0, 0, 0, {0}};
    double w[3][3];
    int a, c, s, wb;
    char what[64];
    w_mild(w);
    for (wb = 0; wb < 2; ++wb) {
        for (s = 0; s < 2; ++s) {
            for (a = 0; a < 7; ++a) {
                for (c = 0; c < 9; ++c) {
                    size_t n = gen_cone(w, tilts[a], cones[c], wb ? 2.0 : 0.0, sig[s] * f_ref(), 400,
                                        (uint32_t)(100 + a * 10 + c + s * 1000 + wb * 5000));
                    (void)snprintf(what, sizeof what, "tilt %.0f cone %.0f noise %.1f%%", tilts[a], cones[c],
                                   100.0 * sig[s]);
                    judge_all(wb ? &t2 : &t0, n, w, what);
                }
            }
        }
    }
    report(&t0);
    report(&t2);
    add_total(&t0);
    add_total(&t2);
    /* one rotation axis without wobble: the offset along it is not observable at all */
    TEST_ASSERT_EQUAL_UINT(0u, t0.ok_good);
    TEST_ASSERT_EQUAL_UINT(0u, t0.wrong);
    TEST_ASSERT_EQUAL_UINT(0u, t2.wrong);
}

/* Beyond the sweep: more wobble (5 and 10 deg: a car on rough ground, a boat), higher
 * noise and fewer samples, where the offset along the axis becomes observable gradually. */
static void test_trust3d_cone_wobble_sweep_never_silently_wrong(void)
{
    static const double tilts[4] = {0, 30, 60, 90};
    static const double cones[5] = {20, 50, 90, 130, 160};
    static const double wob[2] = {5.0, 10.0};
    static const double sig[2] = {0.005, 0.02};
    static const size_t ns[2] = {150, 600};
    tally_t t = {"cone, 5/10 deg wobble", 0, 0, 0, 0, 0, 0, {0}};
    double w[3][3];
    int a, c, s, wb, j;
    char what[80];
    w_mild(w);
    for (wb = 0; wb < 2; ++wb) {
        for (s = 0; s < 2; ++s) {
            for (j = 0; j < 2; ++j) {
                for (a = 0; a < 4; ++a) {
                    for (c = 0; c < 5; ++c) {
                        size_t n = gen_cone(w, tilts[a], cones[c], wob[wb], sig[s] * f_ref(), ns[j],
                                            (uint32_t)(9000 + a * 10 + c + s * 100 + wb * 1000 + j * 50));
                        (void)snprintf(what, sizeof what, "tilt %.0f cone %.0f wobble %.0f noise %.1f%% n %u",
                                       tilts[a], cones[c], wob[wb], 100.0 * sig[s], (unsigned)ns[j]);
                        judge_all(&t, n, w, what);
                    }
                }
            }
        }
    }
    report(&t);
    add_total(&t);
    TEST_ASSERT_EQUAL_UINT(0u, t.wrong);
}

static void test_trust3d_rest_noise_balls_return_no_motion(void)
{
    static const double sig[3] = {0.005, 0.014, 0.03};
    static const size_t ns[2] = {200, 2000};
    tally_t t = {"stationary noise ball", 0, 0, 0, 0, 0, 0, {0}};
    double w[3][3];
    int s, j, seed, k;
    char what[64];
    w_mild(w);
    for (s = 0; s < 3; ++s) {
        for (j = 0; j < 2; ++j) {
            for (seed = 0; seed < 3; ++seed) {
                size_t n = gen_rest(w, sig[s] * f_ref(), ns[j], (uint32_t)(7 + seed + 10 * s + 100 * j));
                (void)snprintf(what, sizeof what, "noise %.1f%% n %u", 100.0 * sig[s], (unsigned)ns[j]);
                for (k = 0; k < 4; ++k) {
                    TEST_ASSERT_EQUAL_INT_MESSAGE(MAGCAL_ERR_NO_MOTION, judge(&t, n, w, MODELS[k], what), what);
                }
            }
        }
    }
    report(&t);
    add_total(&t);
}

static void test_trust3d_narrow_bands_never_silently_wrong(void)
{
    tally_t tv = {"+-15 deg tilt band", 0, 0, 0, 0, 0, 0, {0}}, td = {"+-15 deg direction band", 0, 0, 0, 0, 0, 0, {0}};
    tally_t tv30 = {"+-30 deg tilt band", 0, 0, 0, 0, 0, 0, {0}}, td30 = {"+-30 deg direction band", 0, 0, 0, 0, 0, 0, {0}};
    double w[3][3], wi[3][3];
    int seed, wk;
    char what[64];
    w_mild(w);
    mat_ident(wi, 1.0);
    static const double half[2] = {15.0, 30.0};
    int hb;
    for (hb = 0; hb < 2; ++hb) {
        tally_t *pv = hb ? &tv30 : &tv, *pd = hb ? &td30 : &td;
        for (wk = 0; wk < 2; ++wk) {
            for (seed = 0; seed < 4; ++seed) {
                size_t n = gen_attitudes(wk ? w : wi, half[hb], 0.005 * f_ref(), 400, (uint32_t)(31 + seed + 100 * hb));
                (void)snprintf(what, sizeof what, "tilt band %.0f W %s seed %d", half[hb], wk ? "mild" : "I", seed);
                judge_all(pv, n, wk ? w : wi, what);
                n = gen_dir_band(wk ? w : wi, half[hb], 0.005 * f_ref(), 400, (uint32_t)(41 + seed + 100 * hb));
                (void)snprintf(what, sizeof what, "dir band %.0f W %s seed %d", half[hb], wk ? "mild" : "I", seed);
                judge_all(pd, n, wk ? w : wi, what);
            }
        }
    }
    report(&tv);
    report(&td);
    report(&tv30);
    report(&td30);
    add_total(&tv);
    add_total(&td);
    add_total(&tv30);
    add_total(&td30);
    TEST_ASSERT_EQUAL_UINT(0u, tv.wrong + td.wrong + tv30.wrong + td30.wrong);
}

static void test_trust3d_strong_soft_iron_never_silently_wrong(void)
{
    static const double ratio[6] = {1.5, 3.0, 5.0, 11.0, 15.0, 20.0};
    tally_t tf = {"soft iron, full rotation", 0, 0, 0, 0, 0, 0, {0}}, tb = {"soft iron, +-15 deg band", 0, 0, 0, 0, 0, 0, {0}};
    double w[3][3];
    int i, seed;
    char what[64];
    for (i = 0; i < 6; ++i) {
        for (seed = 0; seed < 2; ++seed) {
            size_t n;
            make_w_sym(1.0, 1.0 / ratio[i], 1.0, 0.5 + seed, 0.2, w);
            n = gen_attitudes(w, 180.0, 0.005 * f_ref(), 600, (uint32_t)(51 + seed + 10 * i));
            (void)snprintf(what, sizeof what, "ratio %.0f:1 full seed %d", ratio[i], seed);
            judge_all(&tf, n, w, what);
            n = gen_attitudes(w, 15.0, 0.005 * f_ref(), 600, (uint32_t)(61 + seed + 10 * i));
            (void)snprintf(what, sizeof what, "ratio %.0f:1 band seed %d", ratio[i], seed);
            judge_all(&tb, n, w, what);
        }
    }
    report(&tf);
    report(&tb);
    add_total(&tf);
    add_total(&tb);
    TEST_ASSERT_EQUAL_UINT(0u, tf.wrong);
    TEST_ASSERT_EQUAL_UINT(0u, tb.wrong);
}

static void test_trust3d_bursts_without_filter_never_silently_wrong(void)
{
    static const double shifts[3] = {7.0, 15.0, 30.0};
    tally_t td = {"6 % dense burst, 7-30 uT", 0, 0, 0, 0, 0, 0, {0}}, ts = {"6 % spread burst, 7-30 uT", 0, 0, 0, 0, 0, 0, {0}};
    tally_t t12 = {"12 % dense burst (info)", 0, 0, 0, 0, 0, 1, {0}};
    double w[3][3];
    int seed, si;
    unsigned caught = 0u, ok_auto = 0u;
    char what[64];
    w_mild(w);
    for (si = 0; si < 3; ++si) {
        for (seed = 0; seed < 8; ++seed) {
            magcal_ellipsoid_cfg_t cfg = MAGCAL_ELLIPSOID_CFG_DEFAULT;
            magcal_ellipsoid_result_t r;
            size_t n = gen_burst(w, 0.06, shifts[si], 1, 0.005 * f_ref(), 600, (uint32_t)(71 + seed));
            (void)snprintf(what, sizeof what, "dense %.0f uT seed %d", shifts[si], seed);
            judge_all(&td, n, w, what);
            /* the fit's own gate (robust MAD scale) takes the burst out (36 samples) */
            if (magcal_ellipsoid_fit(g_m, n, &cfg, &g_fit_scratch, &r) == MAGCAL_OK) {
                ok_auto++;
                caught += (r.n_rejected >= 34u) ? 1u : 0u;
            }
            n = gen_burst(w, 0.06, shifts[si], 0, 0.005 * f_ref(), 600, (uint32_t)(81 + seed));
            (void)snprintf(what, sizeof what, "spread %.0f uT seed %d", shifts[si], seed);
            judge_all(&ts, n, w, what);
            /* beyond the issue (not asserted, docs/calibration_3d.md "Weak points"): 12 % */
            n = gen_burst(w, 0.12, shifts[si], 1, 0.005 * f_ref(), 600, (uint32_t)(71 + seed));
            (void)snprintf(what, sizeof what, "dense 12%% %.0f uT seed %d", shifts[si], seed);
            judge_all(&t12, n, w, what);
        }
    }
    report(&td);
    report(&ts);
    report(&t12);
    printf("6 %% dense bursts, AUTO: %u of 24 OK, the fit's gate took >= 34 of the 36 burst samples out in %u\n",
           ok_auto, caught);
    add_total(&td);
    add_total(&ts);
    TEST_ASSERT_EQUAL_UINT(0u, td.wrong);
    TEST_ASSERT_EQUAL_UINT(0u, ts.wrong);
    TEST_ASSERT_TRUE(ok_auto >= 20u); /* measured 24 of 24 */
    TEST_ASSERT_TRUE(caught >= 18u);  /* measured 21; the others: nearly tangential shifts, harmless */
}

/* No over-refusal: good full-rotation data (mild soft iron) with AUTO. The gates refuse where the
 * predicted error is too large for the 1 deg promise (small n with high noise); every case with
 * n >= 300 and noise <= 1 % F must pass. */
static void test_trust3d_good_full_rotations_return_ok(void)
{
    static const double sig[4] = {0.0025, 0.005, 0.01, 0.02};
    static const size_t ns[3] = {100, 300, 600};
    tally_t t = {"good full rotation (AUTO)", 0, 0, 0, 0, 0, 0, {0}};
    double w[3][3];
    int s, j, seed;
    unsigned easy = 0u, easy_ok = 0u;
    char what[64];
    w_mild(w);
    for (s = 0; s < 4; ++s) {
        for (j = 0; j < 3; ++j) {
            for (seed = 0; seed < 4; ++seed) {
                size_t n = gen_attitudes(w, 180.0, sig[s] * f_ref(), ns[j], (uint32_t)(91 + seed + 10 * s + 100 * j));
                magcal_status_t st;
                (void)snprintf(what, sizeof what, "noise %.2f%% n %u", 100.0 * sig[s], (unsigned)ns[j]);
                st = judge(&t, n, w, MAGCAL_ELLIPSOID_MODEL_AUTO, what);
                if (sig[s] <= 0.01 && ns[j] >= 300) {
                    easy++;
                    easy_ok += (st == MAGCAL_OK) ? 1u : 0u;
                }
            }
        }
    }
    report(&t);
    add_total(&t);
    printf("over-refusal on good data: %u of %u refused (%.1f %%); n >= 300 and noise <= 1 %% F: %u of %u OK\n",
           t.refused, t.cases, 100.0 * (double)t.refused / (double)t.cases, easy_ok, easy);
    TEST_ASSERT_EQUAL_UINT(0u, t.wrong);
    TEST_ASSERT_EQUAL_UINT(easy, easy_ok);
    TEST_ASSERT_TRUE(t.ok_good * 4u >= t.cases * 3u); /* measured 36 of 48 */
}

static void test_trust3d_totals_have_zero_silent_wrong_answers(void)
{
    report(&g_total);
    TEST_ASSERT_EQUAL_UINT(0u, g_total.wrong);
    TEST_ASSERT_TRUE(g_total.cases > 1000u);
}

int main(int argc, char **argv)
{
    g_total.name = "TOTAL";
    g_verbose = (argc > 1 && strcmp(argv[1], "-v") == 0);
    UNITY_BEGIN();
    RUN_TEST(test_trust3d_cone_sweeps_never_silently_wrong);
    RUN_TEST(test_trust3d_cone_wobble_sweep_never_silently_wrong);
    RUN_TEST(test_trust3d_rest_noise_balls_return_no_motion);
    RUN_TEST(test_trust3d_narrow_bands_never_silently_wrong);
    RUN_TEST(test_trust3d_strong_soft_iron_never_silently_wrong);
    RUN_TEST(test_trust3d_bursts_without_filter_never_silently_wrong);
    RUN_TEST(test_trust3d_good_full_rotations_return_ok);
    RUN_TEST(test_trust3d_totals_have_zero_silent_wrong_answers);
    return UNITY_END();
}
