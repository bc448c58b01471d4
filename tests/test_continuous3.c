/*
 * Tests of the continuous 3-D calibrator (include/magcal/continuous3.h, src/loop3/): synthetic
 * hand tumbles at 50 Hz with known truth (fixed seeds). Model (algorithms.md 6, 7.1): body x right,
 * y forward, z up; attitude C_b^ENU = Rz(-yaw) Rx(pitch) Ry(roll); Earth field B_ENU = (0, H, -Z);
 * raw m = W C^T B + V + n (W symmetric positive definite, so the fit's symmetric G is W^-1 up to
 * scale and the tilt-compensated heading is exact up to noise); accelerometer f = C^T (0, 0, 1) g.
 * Truth calibration: G = W^-1, V, F = |B|.
 * On the QEMU target the interleaving test is left out (it needs a POSIX thread).
 */
#if defined(__unix__) && !defined(__arm__)
#define CONT3_TEST_THREADS 1 /* host: the ISR is a POSIX thread */
#define _POSIX_C_SOURCE 200809L
#include <pthread.h>
#endif
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "magcal/continuous3.h"
#include "test_util.h"
#include "unity.h"

#define SLOTS3 MAGCAL_CONT3_SLOTS(10u, 4u)
#define RATE_MS 20u
#define DEG (3.14159265358979323846 / 180.0)
#define H_FIELD 20.0
#define Z_FIELD 40.0
#define SIGMA 0.15

static magcal_intake_slot_t g_slots[2][SLOTS3];
static magcal_vec3_t g_buf[2][SLOTS3];
static MAGCAL_CONT3_WORKSPACE_DECLARE(g_work0, SLOTS3);
static MAGCAL_CONT3_WORKSPACE_DECLARE(g_work1, SLOTS3);
static magcal_cont3_t g_c3[2];

void setUp(void) {}
void tearDown(void) {}

/* Installation truth: soft iron W (symmetric), hard iron V (uT). */
typedef struct {
    double w[3][3];
    double v[3];
} truth_t;

static const truth_t k_truth = {{{1.08, 0.05, -0.03}, {0.05, 0.95, 0.04}, {-0.03, 0.04, 1.02}}, {25.0, -12.0, 30.0}};

static double field_f(void) { return sqrt(H_FIELD * H_FIELD + Z_FIELD * Z_FIELD); }

/* Attitude of the tumble at time t (s): every direction of the field is visited within ~30 s. */
static void tumble_att(double t, double *roll, double *pitch, double *yaw)
{
    *yaw = 0.9 * t + 0.5 * sin(0.23 * t);
    *pitch = 75.0 * DEG * sin(0.37 * t + 0.4);
    *roll = 160.0 * DEG * sin(0.29 * t);
}

/* C^T x for C = Rz(-yaw) Rx(pitch) Ry(roll) (world ENU -> body). */
static void world_to_body(double roll, double pitch, double yaw, const double x[3], double b[3])
{
    /* C^T = Ry(roll)^T Rx(pitch)^T Rz(-yaw)^T */
    const double cy = cos(yaw), sy = sin(yaw);
    const double cp = cos(pitch), sp = sin(pitch);
    const double cr = cos(roll), sr = sin(roll);
    double a[3], c[3];
    /* Rz(-yaw)^T = Rz(yaw): [c -s; s c] with angle yaw... Rz(a) = [[c,-s,0],[s,c,0],[0,0,1]] */
    a[0] = cy * x[0] - sy * x[1];
    a[1] = sy * x[0] + cy * x[1];
    a[2] = x[2];
    /* Rx(pitch)^T: Rx(a) = [[1,0,0],[0,c,-s],[0,s,c]] */
    c[0] = a[0];
    c[1] = cp * a[1] + sp * a[2];
    c[2] = -sp * a[1] + cp * a[2];
    /* Ry(roll)^T: Ry(a) = [[c,0,s],[0,1,0],[-s,0,c]] */
    b[0] = cr * c[0] - sr * c[2];
    b[1] = c[1];
    b[2] = sr * c[0] + cr * c[2];
}

/* One sample of the installation `tr` at attitude (roll, pitch, yaw), field scaled by `scale`. */
static void sample(const truth_t *tr, double roll, double pitch, double yaw, double scale, uint32_t *rng,
                   magcal_vec3_t *m, magcal_vec3_t *acc)
{
    const double bw[3] = {0.0, H_FIELD * scale, -Z_FIELD * scale};
    const double gw[3] = {0.0, 0.0, 1.0};
    double hb[3], gb[3];
    int i;
    world_to_body(roll, pitch, yaw, bw, hb);
    world_to_body(roll, pitch, yaw, gw, gb);
    for (i = 0; i < 3; ++i) {
        const double r = tr->w[i][0] * hb[0] + tr->w[i][1] * hb[1] + tr->w[i][2] * hb[2] + tr->v[i] +
                         SIGMA * test_rand_normal(rng);
        if (i == 0) {
            m->x = (float)r;
        } else if (i == 1) {
            m->y = (float)r;
        } else {
            m->z = (float)r;
        }
    }
    acc->x = (float)gb[0];
    acc->y = (float)gb[1];
    acc->z = (float)gb[2];
}

static void truth_cal(const truth_t *tr, magcal_ellipsoid_cal_t *c)
{
    const double (*w)[3] = tr->w;
    const double det = w[0][0] * (w[1][1] * w[2][2] - w[1][2] * w[2][1]) - w[0][1] * (w[1][0] * w[2][2] - w[1][2] * w[2][0]) +
                       w[0][2] * (w[1][0] * w[2][1] - w[1][1] * w[2][0]);
    int i, k;
    for (i = 0; i < 3; ++i) {
        for (k = 0; k < 3; ++k) {
            const int i1 = (k + 1) % 3, i2 = (k + 2) % 3, k1 = (i + 1) % 3, k2 = (i + 2) % 3;
            c->g[i][k] = (float)((w[i1][k1] * w[i2][k2] - w[i1][k2] * w[i2][k1]) / det);
        }
    }
    c->v.x = (float)tr->v[0];
    c->v.y = (float)tr->v[1];
    c->v.z = (float)tr->v[2];
    c->field = (float)field_f();
}

/* |B| spread (std / mean of |G (m - V)|) of c over the n samples of a fresh tumble (seed 777). */
static double spread_on_tumble(const magcal_ellipsoid_cal_t *c, const magcal_ellipsoid_cal_t *ref, double *ref_spread)
{
    uint32_t rng = 777u;
    double s[2] = {0.0, 0.0}, s2[2] = {0.0, 0.0};
    const magcal_ellipsoid_cal_t *cs[2] = {c, ref};
    size_t i;
    const size_t n = 3000u;
    int k;
    for (i = 0u; i < n; ++i) {
        double ro, pi, ya;
        magcal_vec3_t m, a, h;
        tumble_att(0.05 * (double)i + 3.0, &ro, &pi, &ya);
        sample(&k_truth, ro, pi, ya, 1.0, &rng, &m, &a);
        for (k = 0; k < 2; ++k) {
            double r;
            TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipsoid_apply(cs[k], &m, &h));
            r = sqrt((double)h.x * h.x + (double)h.y * h.y + (double)h.z * h.z);
            s[k] += r;
            s2[k] += r * r;
        }
    }
    for (k = 0; k < 2; ++k) {
        s[k] /= (double)n;
        s2[k] = sqrt(fmax(s2[k] / (double)n - s[k] * s[k], 0.0)) / s[k];
    }
    *ref_spread = s2[1];
    return s2[0];
}

static double v_err_rel(const magcal_ellipsoid_cal_t *c, const truth_t *tr)
{
    const double dx = c->v.x - tr->v[0], dy = c->v.y - tr->v[1], dz = c->v.z - tr->v[2];
    return sqrt(dx * dx + dy * dy + dz * dz) / field_f();
}

static magcal_status_t init_k(int k, const magcal_cont3_cfg_t *cfg, const magcal_ellipsoid_cal_t *inst)
{
    return magcal_cont3_init(&g_c3[k], cfg, inst, g_slots[k], SLOTS3, g_buf[k], k == 0 ? (void *)g_work0 : (void *)g_work1,
                             k == 0 ? sizeof g_work0 : sizeof g_work1);
}

static void init_default(const magcal_ellipsoid_cal_t *inst)
{
    const magcal_cont3_cfg_t cfg = MAGCAL_CONT3_CFG_DEFAULT;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, init_k(0, &cfg, inst));
}

/* Feed rows [i0, i1) of a tumble (time = i x 20 ms) into instance k: push + step + heading per row.
 * tr_at(i) selects the installation, scale_at(i) the field scale (1 = clean). Returns the trust
 * counts and the first row that adopted / declared a change at or after i0 (-1: none). */
typedef struct {
    long first_adopt;
    long first_change;
    uint32_t adoptions;
    uint32_t trust[4];
    double head_ss; /* squared tilt-compensated heading error over trusted rows (deg^2) */
    uint32_t head_n;
} feed_t;

typedef enum { MOTION_TUMBLE, MOTION_PARKED, MOTION_LEVEL_TURNS } motion_t;

static void feed(int k, motion_t mo, size_t i0, size_t i1, const truth_t *before, const truth_t *after, size_t step_row,
                 size_t dist0, size_t dist1, uint32_t *rng, feed_t *f, uint32_t *dist_flagged, uint32_t *clean_flagged,
                 uint32_t *clean_n)
{
    size_t i;
    memset(f, 0, sizeof *f);
    f->first_adopt = -1;
    f->first_change = -1;
    for (i = i0; i < i1; ++i) {
        const double t = 0.02 * (double)i;
        double ro = 0.0, pi = 0.0, ya = 0.0;
        const int dist = i >= dist0 && i < dist1;
        magcal_vec3_t m, a;
        magcal_cont3_heading_t hd;
        magcal_cont3_outcome_t oc;
        if (mo == MOTION_TUMBLE) {
            tumble_att(t, &ro, &pi, &ya);
        } else if (mo == MOTION_LEVEL_TURNS) {
            ya = 0.6 * t;
        } else {
            ro = 10.0 * DEG;
            pi = 5.0 * DEG;
            ya = 1.0;
        }
        sample(i < step_row ? before : after, ro, pi, ya, dist ? 1.3 : 1.0, rng, &m, &a);
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont3_push(&g_c3[k], &m, (uint32_t)(i * RATE_MS)));
        oc = magcal_cont3_step(&g_c3[k]);
        if (oc == MAGCAL_CONT3_ADOPTED) {
            f->adoptions++;
            if (f->first_adopt < 0) {
                f->first_adopt = (long)i;
            }
        }
        if (oc == MAGCAL_CONT3_CHANGE && f->first_change < 0) {
            f->first_change = (long)i;
        }
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont3_heading(&g_c3[k], &m, &a, 0.0f, &hd));
        TEST_ASSERT_TRUE((unsigned)hd.trust < 4u);
        f->trust[hd.trust]++;
        if (hd.trust == MAGCAL_TRUST_OK) {
            const double yaw_deg = fmod(ya / DEG, 360.0);
            const double e = test_angle_diff_deg((double)hd.heading_deg, yaw_deg < 0.0 ? yaw_deg + 360.0 : yaw_deg);
            f->head_ss += e * e;
            f->head_n++;
        }
        if (dist_flagged != NULL && g_c3[k].generation > 0u && hd.trust != MAGCAL_TRUST_UNCALIBRATED) {
            if (dist) {
                *dist_flagged += hd.trust == MAGCAL_TRUST_DISTURBED ? 1u : 0u;
            } else if (i >= dist1 + 50u || i < dist0) {
                *clean_flagged += hd.trust != MAGCAL_TRUST_OK ? 1u : 0u;
                *clean_n += 1u;
            }
        }
    }
}

static void test_cont3_init_bad_args_refused(void)
{
    magcal_cont3_cfg_t cfg = MAGCAL_CONT3_CFG_DEFAULT;
    magcal_ellipsoid_cal_t bad;
    magcal_cont3_progress_t p;
    magcal_vec3_t m = {1.0f, 2.0f, 3.0f};
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_cont3_init(NULL, &cfg, NULL, g_slots[0], SLOTS3, g_buf[0], g_work0, sizeof g_work0));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_cont3_init(&g_c3[0], &cfg, NULL, g_slots[0], SLOTS3, g_buf[0], NULL, sizeof g_work0));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_WORKSPACE,
                          magcal_cont3_init(&g_c3[0], &cfg, NULL, g_slots[0], SLOTS3, g_buf[0], g_work0,
                                            MAGCAL_CONT3_WORKSPACE_LEN(SLOTS3) - 1u));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_WORKSPACE,
                          magcal_cont3_init(&g_c3[0], &cfg, NULL, g_slots[0], 100u, g_buf[0], g_work0, sizeof g_work0));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ALIGNMENT,
                          magcal_cont3_init(&g_c3[0], &cfg, NULL, g_slots[0], SLOTS3, g_buf[0], (char *)g_work0 + 1, sizeof g_work0 - 4u));
    cfg.intake.dims = 2u;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, init_k(0, &cfg, NULL));
    cfg.intake.dims = 3u;
    cfg.intake.per_bin = 9u; /* 128 cells x 9 > MAGCAL_MAX_SAMPLES: a full store could not be solved */
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, init_k(0, &cfg, NULL));
    cfg.intake.per_bin = 4u;
    cfg.solve_fill = 0.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, init_k(0, &cfg, NULL));
    cfg.solve_fill = NAN;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, init_k(0, &cfg, NULL));
    cfg.solve_fill = 0.5f;
    cfg.adopt_margin = 0.9f; /* a margin below 1 would adopt a worse calibration */
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, init_k(0, &cfg, NULL));
    cfg.adopt_margin = 1.02f;
    truth_cal(&k_truth, &bad);
    bad.g[0][0] = -bad.g[0][0]; /* det G < 0: not a calibration */
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, init_k(0, &cfg, &bad));
    bad.g[0][0] = NAN;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, init_k(0, &cfg, &bad));
    memset(&g_c3[0], 0, sizeof g_c3[0]);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NOT_INITIALISED, magcal_cont3_push(&g_c3[0], &m, 0u));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NOT_INITIALISED, magcal_cont3_progress(&g_c3[0], &p));
    TEST_ASSERT_EQUAL_INT(MAGCAL_CONT3_IDLE, magcal_cont3_step(&g_c3[0]));
    /* the size macros: slots = cells bound x per_bin; workspace = the solve's for that many */
    TEST_ASSERT_EQUAL_UINT((unsigned)MAGCAL_INTAKE_SLOTS_3D(10u, 4u), (unsigned)SLOTS3);
    TEST_ASSERT_EQUAL_UINT((unsigned)MAGCAL_ELLIPSOID_CALIBRATE_WORKSPACE_LEN(SLOTS3), (unsigned)MAGCAL_CONT3_WORKSPACE_LEN(SLOTS3));
    TEST_ASSERT_TRUE(sizeof g_work0 >= MAGCAL_CONT3_WORKSPACE_LEN(SLOTS3));
}

/* First adoption from an empty store: hard iron within 2 % of F, |B| spread on a fresh tumble
 * within 1.2 x the truth's on the same noisy samples, live progress agreeing with the solve. */
static void test_cont3_tumble_first_adoption_accurate(void)
{
    uint32_t rng = 11u;
    feed_t f;
    double sp, sp_truth;
    magcal_ellipsoid_cal_t tc;
    magcal_cont3_progress_t p;
    init_default(NULL);
    feed(0, MOTION_TUMBLE, 0u, 4500u, &k_truth, &k_truth, 1u << 30, 0u, 0u, &rng, &f, NULL, NULL, NULL);
    truth_cal(&k_truth, &tc);
    TEST_ASSERT_TRUE(f.first_adopt > 0);
    TEST_ASSERT_TRUE(g_c3[0].generation >= 1u);
    sp = spread_on_tumble(&g_c3[0].cal, &tc, &sp_truth);
    printf("tumble: first adoption row %ld (%.1f s), %u adoptions, |V - V_true| %.3f %% F, spread %.4f %% "
           "(truth %.4f %%), trusted rows %u, heading RMS %.2f deg\n",
           f.first_adopt, 0.02 * (double)f.first_adopt, (unsigned)g_c3[0].generation, 100.0 * v_err_rel(&g_c3[0].cal, &k_truth),
           100.0 * sp, 100.0 * sp_truth, (unsigned)f.trust[MAGCAL_TRUST_OK],
           f.head_n > 0u ? sqrt(f.head_ss / (double)f.head_n) : -1.0);
    TEST_ASSERT_TRUE(v_err_rel(&g_c3[0].cal, &k_truth) < 0.02);
    TEST_ASSERT_TRUE(sp <= 1.2 * sp_truth);
    /* tilt-compensated heading with the adopted calibration, trusted rows: noise-level error */
    TEST_ASSERT_TRUE(f.head_n > 1000u);
    TEST_ASSERT_TRUE(sqrt(f.head_ss / (double)f.head_n) < 1.5);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont3_progress(&g_c3[0], &p));
    TEST_ASSERT_TRUE(p.fill >= 0.5f);
    TEST_ASSERT_TRUE(p.cells_filled <= p.cells);
    TEST_ASSERT_EQUAL_UINT32(0u, p.changes);
    TEST_ASSERT_TRUE(p.stored > 200u);
    TEST_ASSERT_TRUE(g_c3[0].last.coverage > 0.6f); /* the solve's own 72-cell coverage agrees */
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont3_status(&g_c3[0]) == MAGCAL_ERR_NOT_BETTER ? MAGCAL_OK : magcal_cont3_status(&g_c3[0]));
}

/* Parked for 10 minutes; then, from a fresh start, level turns for 5 minutes: no adoption, every
 * heading uncalibrated; the ring fills less than half of the cells (no solve starts); a forced
 * solve on it says SINGLE_AXIS and leaves nothing installed. */
static void test_cont3_parked_and_single_axis_never_adopt(void)
{
    uint32_t rng = 12u;
    feed_t f;
    magcal_cont3_progress_t p;
    init_default(NULL);
    feed(0, MOTION_PARKED, 0u, 30000u, &k_truth, &k_truth, 1u << 30, 0u, 0u, &rng, &f, NULL, NULL, NULL);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont3_progress(&g_c3[0], &p));
    {
        magcal_intake_progress_t ip;
        (void)magcal_intake_progress(&g_c3[0].store, &ip);
        printf("parked 10 min: stored %u, cells filled %u / %u, solves %u (last %s), store centre source %d, R %.3f\n",
               (unsigned)p.stored, (unsigned)p.cells_filled, (unsigned)p.cells, (unsigned)p.solves,
               magcal_status_str(magcal_cont3_status(&g_c3[0])), (int)ip.centre_source, (double)ip.radius);
    }
    /* The 3-D intake can take the noise ball of a parked sensor for a sphere (R ~ 1.6 sigma: its
     * shell-trimmed survey passes the ring test) and then fills every cell; the solve's NO_MOTION
     * gate refuses it and the failure back-off bounds the solves. */
    TEST_ASSERT_EQUAL_UINT32(0u, p.generation);
    TEST_ASSERT_TRUE(p.solves <= 40u);
    TEST_ASSERT_EQUAL_UINT32(30000u, f.trust[MAGCAL_TRUST_UNCALIBRATED]);
    init_default(NULL);
    feed(0, MOTION_LEVEL_TURNS, 30000u, 45000u, &k_truth, &k_truth, 1u << 30, 0u, 0u, &rng, &f, NULL, NULL, NULL);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont3_progress(&g_c3[0], &p));
    printf("level turns 5 min: stored %u, cells filled %u / %u (fill %.2f), solves %u, generation %u\n", (unsigned)p.stored,
           (unsigned)p.cells_filled, (unsigned)p.cells, (double)p.fill, (unsigned)p.solves, (unsigned)p.generation);
    TEST_ASSERT_EQUAL_UINT32(0u, p.generation);
    TEST_ASSERT_TRUE(p.fill < 0.5f);
    TEST_ASSERT_EQUAL_UINT32(15000u, f.trust[MAGCAL_TRUST_UNCALIBRATED]);
    TEST_ASSERT_EQUAL_INT(MAGCAL_CONT3_FAILED, magcal_cont3_solve_blocking(&g_c3[0], 1));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_SINGLE_AXIS, magcal_cont3_status(&g_c3[0]));
    TEST_ASSERT_EQUAL_UINT32(0u, g_c3[0].generation);
    TEST_ASSERT_EQUAL_UINT8(0u, g_c3[0].has_cal);
}

/* A hard-iron step (a magnet fitted near the sensor: V moves by 0.35 F) after the first adoption:
 * declared a change within change_ms + 4 s, headings `changed` until the relearned calibration,
 * which is within 2 % of F of the new hard iron. */
static void test_cont3_hard_iron_step_detected_relearned(void)
{
    uint32_t rng = 13u;
    feed_t f;
    truth_t after = k_truth;
    const size_t step_row = 3000u; /* 60 s */
    uint32_t changed_before_relearn;
    after.v[0] += 12.0;
    after.v[1] -= 8.0;
    after.v[2] += 6.0; /* |dV| = 15.6 uT = 0.35 F */
    init_default(NULL);
    feed(0, MOTION_TUMBLE, 0u, step_row, &k_truth, &k_truth, 1u << 30, 0u, 0u, &rng, &f, NULL, NULL, NULL);
    TEST_ASSERT_TRUE(g_c3[0].generation >= 1u);
    TEST_ASSERT_EQUAL_UINT32(0u, g_c3[0].changes);
    feed(0, MOTION_TUMBLE, step_row, step_row + 6000u, &k_truth, &after, step_row, 0u, 0u, &rng, &f, NULL, NULL, NULL);
    changed_before_relearn = f.trust[MAGCAL_TRUST_CHANGED];
    printf("hard-iron step at row %u: change declared at row %ld (+%.1f s), relearned (first adoption after) at "
           "row %ld (+%.1f s), changed rows %u, |V - V_new| %.3f %% F\n",
           (unsigned)step_row, f.first_change, 0.02 * (double)(f.first_change - (long)step_row), f.first_adopt,
           0.02 * (double)(f.first_adopt - (long)step_row), (unsigned)changed_before_relearn,
           100.0 * v_err_rel(&g_c3[0].cal, &after));
    TEST_ASSERT_TRUE(f.first_change >= (long)step_row);
    TEST_ASSERT_TRUE(f.first_change - (long)step_row <= (long)((8000u + 4000u) / RATE_MS));
    TEST_ASSERT_EQUAL_UINT32(1u, g_c3[0].changes);
    TEST_ASSERT_TRUE(f.first_adopt > f.first_change);
    /* every row from the change to the relearned adoption reads `changed` */
    TEST_ASSERT_TRUE(changed_before_relearn >= (uint32_t)(f.first_adopt - f.first_change) - 1u);
    TEST_ASSERT_TRUE(v_err_rel(&g_c3[0].cal, &after) < 0.02);
    TEST_ASSERT_EQUAL_INT(MAGCAL_CONT3_COLLECTING, (int)g_c3[0].state);
}

/* A transient (3 s of +30 % field: a passing truck, a magnet passed by) after the adoption: >= 90 %
 * of its rows flagged `disturbed`, <= 2 % of the clean rows, nothing discarded, no change. */
static void test_cont3_transient_flagged_nothing_dropped(void)
{
    uint32_t rng = 14u;
    feed_t f;
    magcal_cont3_progress_t p0, p1;
    uint32_t dist_flagged = 0u, clean_flagged = 0u, clean_n = 0u;
    const size_t d0 = 4000u, d1 = 4150u;
    init_default(NULL);
    feed(0, MOTION_TUMBLE, 0u, 3500u, &k_truth, &k_truth, 1u << 30, 0u, 0u, &rng, &f, NULL, NULL, NULL);
    TEST_ASSERT_TRUE(g_c3[0].generation >= 1u);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont3_progress(&g_c3[0], &p0));
    feed(0, MOTION_TUMBLE, 3500u, 5500u, &k_truth, &k_truth, 1u << 30, d0, d1, &rng, &f, &dist_flagged, &clean_flagged,
         &clean_n);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont3_progress(&g_c3[0], &p1));
    printf("transient 3 s +30 %%: flagged %u / %u rows, clean rows flagged %u / %u, changes %u, stored %u -> %u\n",
           (unsigned)dist_flagged, (unsigned)(d1 - d0), (unsigned)clean_flagged, (unsigned)clean_n, (unsigned)p1.changes,
           (unsigned)p0.stored, (unsigned)p1.stored);
    TEST_ASSERT_EQUAL_UINT32(0u, p1.changes);
    TEST_ASSERT_TRUE(p1.stored >= p0.stored);
    TEST_ASSERT_TRUE(dist_flagged >= (uint32_t)(0.9 * (double)(d1 - d0)));
    TEST_ASSERT_TRUE((double)clean_flagged <= 0.02 * (double)clean_n);
}

/* Never-worse on the truth: (a) the TRUE calibration installed from flash is never replaced over
 * 4 minutes of tumbling (every candidate fits its own samples, none is better than the truth);
 * (b) from a flash calibration 6 % of F off in hard iron, every adoption is better on the truth
 * than the calibration it replaced. */
static void test_cont3_true_calibration_never_replaced(void)
{
    uint32_t rng = 15u;
    feed_t f;
    magcal_ellipsoid_cal_t tc;
    magcal_ellipsoid_cal_t off;
    double prev_err;
    size_t i;
    truth_cal(&k_truth, &tc);
    init_default(&tc);
    feed(0, MOTION_TUMBLE, 0u, 12000u, &k_truth, &k_truth, 1u << 30, 0u, 0u, &rng, &f, NULL, NULL, NULL);
    printf("truth installed, 4 min tumble: solves %u, adoptions %u, refused (not better) last status %s\n",
           (unsigned)g_c3[0].solves, (unsigned)g_c3[0].generation, magcal_status_str(magcal_cont3_status(&g_c3[0])));
    TEST_ASSERT_TRUE(g_c3[0].solves >= 5u);
    TEST_ASSERT_EQUAL_UINT32(0u, g_c3[0].generation);
    TEST_ASSERT_TRUE(f.trust[MAGCAL_TRUST_OK] >= 11800u); /* the flash calibration is trusted */

    off = tc;
    off.v.x += 0.06f * off.field;
    init_default(&off);
    prev_err = v_err_rel(&off, &k_truth);
    for (i = 0u; i < 12000u; i += 50u) {
        const uint32_t gen = g_c3[0].generation;
        feed(0, MOTION_TUMBLE, i, i + 50u, &k_truth, &k_truth, 1u << 30, 0u, 0u, &rng, &f, NULL, NULL, NULL);
        if (g_c3[0].generation != gen) {
            const double e = v_err_rel(&g_c3[0].cal, &k_truth);
            printf("  adoption at row %u: |V - V_true| %.3f %% F (was %.3f %%)\n", (unsigned)i, 100.0 * e, 100.0 * prev_err);
            TEST_ASSERT_TRUE(e < prev_err);
            prev_err = e;
        }
    }
    TEST_ASSERT_TRUE(g_c3[0].generation >= 1u);
    TEST_ASSERT_TRUE(prev_err < 0.01);
}

/* Two magnetometers: two instances side by side, one tumbled and one parked, independent. */
static void test_cont3_two_sensors_independent(void)
{
    uint32_t rng0 = 16u, rng1 = 17u;
    feed_t f0, f1;
    magcal_cont3_cfg_t cfg = MAGCAL_CONT3_CFG_DEFAULT;
    size_t i;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, init_k(0, &cfg, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, init_k(1, &cfg, NULL));
    for (i = 0u; i < 4500u; i += 100u) {
        feed(0, MOTION_TUMBLE, i, i + 100u, &k_truth, &k_truth, 1u << 30, 0u, 0u, &rng0, &f0, NULL, NULL, NULL);
        feed(1, MOTION_PARKED, i, i + 100u, &k_truth, &k_truth, 1u << 30, 0u, 0u, &rng1, &f1, NULL, NULL, NULL);
    }
    TEST_ASSERT_TRUE(g_c3[0].generation >= 1u);
    TEST_ASSERT_TRUE(v_err_rel(&g_c3[0].cal, &k_truth) < 0.02);
    TEST_ASSERT_EQUAL_UINT32(0u, g_c3[1].generation);
    TEST_ASSERT_EQUAL_UINT8(0u, g_c3[1].has_cal);
}

/* A full ring drops and counts; a failed solve does not stop collection (no sticky state). */
static void test_cont3_ring_full_counted_and_failed_not_sticky(void)
{
    magcal_vec3_t m = {10.0f, 20.0f, 30.0f};
    uint32_t i, full = 0u;
    magcal_cont3_progress_t p;
    init_default(NULL);
    for (i = 0u; i < MAGCAL_CONT3_RING + 5u; ++i) {
        if (magcal_cont3_push(&g_c3[0], &m, i) == MAGCAL_ERR_BUFFER_FULL) {
            full++;
        }
    }
    TEST_ASSERT_EQUAL_UINT32(5u, full);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont3_progress(&g_c3[0], &p));
    TEST_ASSERT_EQUAL_UINT32(5u, p.dropped);
    /* forced solve on one point: fails, collection continues, a tumble then adopts (the store
     * still holds the parked clump, so the first solve runs the density stage, time-sliced at the
     * default budget: about 4,500 steps of one per row; first adoption at row 5501) */
    TEST_ASSERT_EQUAL_INT(MAGCAL_CONT3_FAILED, magcal_cont3_solve_blocking(&g_c3[0], 1));
    TEST_ASSERT_TRUE(magcal_cont3_status(&g_c3[0]) != MAGCAL_OK);
    {
        uint32_t rng = 18u;
        feed_t f;
        feed(0, MOTION_TUMBLE, 1000u, 7000u, &k_truth, &k_truth, 1u << 30, 0u, 0u, &rng, &f, NULL, NULL, NULL);
        TEST_ASSERT_TRUE(g_c3[0].generation >= 1u);
        TEST_ASSERT_TRUE(v_err_rel(&g_c3[0].cal, &k_truth) < 0.02);
    }
}

#ifdef CONT3_TEST_THREADS
/* Interrupt / task interleaving: a producer thread pushes (as an ISR would) while the task steps
 * and reads headings; every sample is taken by step exactly once or counted as dropped, and the
 * calibrator calibrates. */
typedef struct {
    uint32_t n;
    uint32_t ok;
    uint32_t full;
    volatile int done;
} producer_t;

static void *producer(void *arg)
{
    producer_t *pr = (producer_t *)arg;
    uint32_t rng = 99u;
    uint32_t i;
    for (i = 0u; i < pr->n; ++i) {
        double ro, pi, ya;
        magcal_vec3_t m, a;
        magcal_status_t st;
        tumble_att(0.02 * (double)i, &ro, &pi, &ya);
        sample(&k_truth, ro, pi, ya, 1.0, &rng, &m, &a);
        do {
            st = magcal_cont3_push(&g_c3[0], &m, i * RATE_MS);
            if (st == MAGCAL_OK) {
                pr->ok++;
            } else {
                pr->full++;
            }
        } while (st != MAGCAL_OK);
    }
    pr->done = 1;
    return NULL;
}

static void test_cont3_isr_push_interleaved_with_task(void)
{
    pthread_t th;
    producer_t pr;
    magcal_cont3_progress_t p;
    magcal_cont3_heading_t hd;
    const magcal_vec3_t probe = {30.0f, 10.0f, 0.0f};
    uint32_t steps = 0u;
    init_default(NULL);
    memset(&pr, 0, sizeof pr);
    pr.n = 3000u;
    TEST_ASSERT_EQUAL_INT(0, pthread_create(&th, NULL, producer, &pr));
    while (!pr.done || g_c3[0].tail != g_c3[0].head) {
        (void)magcal_cont3_step(&g_c3[0]);
        (void)magcal_cont3_heading(&g_c3[0], &probe, NULL, 0.0f, &hd);
        (void)magcal_cont3_progress(&g_c3[0], &p);
        steps++;
        TEST_ASSERT_TRUE(steps < 50000000u);
    }
    TEST_ASSERT_EQUAL_INT(0, pthread_join(th, NULL));
    while (magcal_cont3_step(&g_c3[0]) == MAGCAL_CONT3_IN_PROGRESS) {
    }
    TEST_ASSERT_EQUAL_UINT32(pr.n, pr.ok);
    TEST_ASSERT_EQUAL_UINT32(pr.n, g_c3[0].tail); /* every queued sample taken exactly once */
    TEST_ASSERT_EQUAL_UINT32(pr.full, g_c3[0].dropped);
    TEST_ASSERT_TRUE(g_c3[0].generation >= 1u);
    TEST_ASSERT_TRUE(v_err_rel(&g_c3[0].cal, &k_truth) < 0.02);
}
#endif


/* The solve is time-sliced: at the default budget it takes many step() calls, each charged within
 * cfg.step_budget (estimated M4F instructions) or by one unit alone (a 9x9 solve; the density stage
 * would be one unit of its own),
 * samples pushed meanwhile are stored, and its candidate is bit for bit the one-shot
 * magcal_ellipsoid_calibrate of the same snapshot. */
static void test_cont3_sliced_solve_bounded_and_identical_to_one_shot(void)
{
    uint32_t rng = 5u;
    size_t i = 0u;
    uint32_t steps = 0u, max_used = 0u, stored0;
    magcal_ellipsoid_result_t one;
    magcal_cont3_t *cc = &g_c3[0];
    init_default(NULL);
    TEST_ASSERT_EQUAL_UINT32(MAGCAL_SLICE_BUDGET_DEFAULT, cc->cfg.step_budget);
    for (; i < 20000u && cc->stage != 2u; ++i) { /* until a solve is under way */
        double ro, pi, ya;
        magcal_vec3_t m, a;
        tumble_att(0.02 * (double)i, &ro, &pi, &ya);
        sample(&k_truth, ro, pi, ya, 1.0, &rng, &m, &a);
        (void)magcal_cont3_push(cc, &m, (uint32_t)(20u * i));
        (void)magcal_cont3_step(cc);
    }
    TEST_ASSERT_EQUAL_UINT8(2u, cc->stage);
    stored0 = cc->store.ctr.added + cc->store.ctr.replaced;
    while (cc->stage == 2u) {
        double ro, pi, ya;
        magcal_vec3_t m, a;
        tumble_att(0.02 * (double)i, &ro, &pi, &ya);
        sample(&k_truth, ro, pi, ya, 1.0, &rng, &m, &a);
        (void)magcal_cont3_push(cc, &m, (uint32_t)(20u * i));
        ++i;
        TEST_ASSERT_EQUAL_INT(MAGCAL_CONT3_IN_PROGRESS, magcal_cont3_step(cc));
        if (cc->slice.used_ > max_used) {
            max_used = cc->slice.used_;
        }
        TEST_ASSERT_TRUE(++steps < 100000u);
    }
    TEST_ASSERT_EQUAL_UINT8(3u, cc->stage); /* the adoption unit is next */
    printf("sliced 3-D solve: %u samples, %u steps, largest step %u estimated M4F instructions (budget %u)\n",
           (unsigned)cc->snap_n, (unsigned)steps, (unsigned)max_used, (unsigned)cc->cfg.step_budget);
    TEST_ASSERT_TRUE(steps > 20u);
    /* within the budget, or one solve unit alone (the largest: a 9x9 LDL^T solve, 7,500) */
    TEST_ASSERT_TRUE(max_used <= cc->cfg.step_budget || max_used <= 7500u);
    TEST_ASSERT_TRUE(cc->store.ctr.added + cc->store.ctr.replaced > stored0); /* pushes stored meanwhile */
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipsoid_calibrate(&cc->cfg.solver, cc->buf, cc->snap_n, g_work1,
                                                                sizeof g_work1, NULL, &one, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, cc->solve_status);
    TEST_ASSERT_EQUAL_MEMORY(&one.cal, &cc->cand.cal, sizeof one.cal);
    TEST_ASSERT_EQUAL_MEMORY(&one.residual_rms, &cc->cand.residual_rms, sizeof(float));
    TEST_ASSERT_EQUAL_UINT32((uint32_t)one.n_used, (uint32_t)cc->cand.n_used);
    /* the adoption: sliced too, within the budget (its steps still drain the ring) */
    for (steps = 0u; cc->stage == 3u && steps < 1000u; ++steps) {
        double ro, pi, ya;
        magcal_vec3_t m, a;
        tumble_att(0.02 * (double)i, &ro, &pi, &ya);
        sample(&k_truth, ro, pi, ya, 1.0, &rng, &m, &a);
        (void)magcal_cont3_push(cc, &m, (uint32_t)(20u * i));
        ++i;
        (void)magcal_cont3_step(cc);
    }
    TEST_ASSERT_EQUAL_UINT8(0u, cc->stage);
    TEST_ASSERT_TRUE(steps >= 1u && steps < 1000u);
}

/* One tumble row i into instance cc (time i x 20 ms), then one step; its outcome. */
static magcal_cont3_outcome_t row_step(magcal_cont3_t *cc, size_t i, uint32_t *rng)
{
    double ro, pi, ya;
    magcal_vec3_t m, a;
    tumble_att(0.02 * (double)i, &ro, &pi, &ya);
    sample(&k_truth, ro, pi, ya, 1.0, rng, &m, &a);
    (void)magcal_cont3_push(cc, &m, (uint32_t)(20u * i));
    return magcal_cont3_step(cc);
}

/* |B| spread of c over the solver buffer's samples within 0.15 F of sel's shell, in double. */
static double buf_spread(const magcal_cont3_t *cc, const magcal_ellipsoid_cal_t *c, const magcal_ellipsoid_cal_t *sel)
{
    double s = 0.0, s2 = 0.0, n = 0.0;
    size_t k;
    for (k = 0u; k < cc->snap_n; ++k) {
        magcal_vec3_t h;
        double r;
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipsoid_apply(sel, &cc->buf[k], &h));
        r = sqrt((double)h.x * h.x + (double)h.y * h.y + (double)h.z * h.z);
        if (fabs(r / sel->field - 1.0) <= 0.15) {
            TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipsoid_apply(c, &cc->buf[k], &h));
            r = sqrt((double)h.x * h.x + (double)h.y * h.y + (double)h.z * h.z);
            s += r;
            s2 += r * r;
            n += 1.0;
        }
    }
    s /= n;
    return sqrt(fmax(s2 / n - s * s, 0.0)) / s;
}

/* Every unit of a solve is sliced within the budget and gives what one call gives: the blocking
 * call's coverage count equals the live progress's filled cells; the snapshot, taken cell by cell
 * over steps, equals magcal_intake_snapshot3 of the store it was taken from; the adoption
 * judgement, sliced over many steps while pushes go on, gives bit for bit the spreads and the
 * verdict of the same judgement in one call (a copy of the instance at the same point, unlimited
 * budget), and those spreads are the std / mean of |G (m - V)| over the candidate's shell
 * computed here in double (1e-3 relative). An installed calibration 3 % of F off (from flash) makes
 * the judgement run both passes. */
static void test_cont3_sliced_units_identical_to_one_call(void)
{
    static magcal_vec3_t snap[SLOTS3];
    static magcal_cont3_t ref;
    uint32_t rng = 21u;
    size_t i = 0u, n = 0u;
    uint32_t adopt_steps = 0u;
    int counted = 0;
    magcal_ellipsoid_cal_t tc, off;
    magcal_cont3_t *cc = &g_c3[0];
    magcal_cont3_outcome_t oc = MAGCAL_CONT3_IN_PROGRESS;
    magcal_cont3_outcome_t ref_oc;
    truth_cal(&k_truth, &tc);
    off = tc;
    off.v.x += 0.03f * off.field;
    init_default(&off);
    for (; i < 20000u && cc->stage != 2u; ++i) { /* until a solve is under way */
        if (!counted && cc->stage == 0u && cc->store.ctr.stored >= 100u) {
            magcal_cont3_progress_t p;
            ref = *cc; /* the count in one call, on a copy that drains nothing (the store is shared) */
            ref.tail = ref.head;
            ref.sweep_left = 0u;
            ref.cfg.solve_fill = 1.0f; /* count only: no solve on the shared buffers */
            TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont3_progress(&ref, &p));
            if (magcal_cont3_solve_blocking(&ref, 0) == MAGCAL_CONT3_IDLE && ref.worth_checked != 0u) {
                TEST_ASSERT_EQUAL_UINT16(p.cells_filled, ref.scan_filled);
                counted = 1;
            }
        }
        (void)row_step(cc, i, &rng);
    }
    TEST_ASSERT_TRUE(counted);
    TEST_ASSERT_EQUAL_UINT8(2u, cc->stage);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_snapshot3(&cc->store, snap, SLOTS3, &n));
    TEST_ASSERT_EQUAL_UINT32((uint32_t)n, (uint32_t)cc->snap_n);
    TEST_ASSERT_EQUAL_MEMORY(snap, cc->buf, n * sizeof snap[0]);
    for (; i < 40000u && cc->stage == 2u; ++i) {
        (void)row_step(cc, i, &rng);
    }
    TEST_ASSERT_EQUAL_UINT8(3u, cc->stage);
    ref = *cc; /* the judgement in one call on a copy (the copy drains nothing: the store is shared) */
    ref.tail = ref.head;
    ref.sweep_left = 0u;
    ref_oc = magcal_cont3_solve_blocking(&ref, 0);
    for (; adopt_steps < 1000u && cc->stage == 3u; ++i, ++adopt_steps) {
        oc = row_step(cc, i, &rng);
    }
    printf("sliced adoption: %u samples, %u steps; spreads candidate %.4f %%, installed %.4f %%\n", (unsigned)cc->snap_n,
           (unsigned)adopt_steps, 100.0 * (double)cc->cand_spread, 100.0 * (double)cc->inst_spread);
    TEST_ASSERT_EQUAL_UINT8(0u, cc->stage);
    TEST_ASSERT_TRUE(adopt_steps >= 4u); /* two passes of a few hundred samples: sliced */
    TEST_ASSERT_EQUAL_INT(MAGCAL_CONT3_ADOPTED, ref_oc);
    TEST_ASSERT_EQUAL_INT(ref_oc, oc);
    TEST_ASSERT_EQUAL_MEMORY(&ref.cand_spread, &cc->cand_spread, sizeof(float));
    TEST_ASSERT_EQUAL_MEMORY(&ref.inst_spread, &cc->inst_spread, sizeof(float));
    TEST_ASSERT_FLOAT_WITHIN(1e-3f * cc->cand_spread, (float)buf_spread(cc, &cc->cand.cal, &cc->cand.cal), cc->cand_spread);
    TEST_ASSERT_FLOAT_WITHIN(1e-3f * cc->inst_spread, (float)buf_spread(cc, &off, &cc->cand.cal), cc->inst_spread);
    TEST_ASSERT_TRUE(cc->inst_spread > 2.0f * cc->cand_spread);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_cont3_init_bad_args_refused);
    RUN_TEST(test_cont3_tumble_first_adoption_accurate);
    RUN_TEST(test_cont3_sliced_solve_bounded_and_identical_to_one_shot);
    RUN_TEST(test_cont3_sliced_units_identical_to_one_call);
    RUN_TEST(test_cont3_parked_and_single_axis_never_adopt);
    RUN_TEST(test_cont3_hard_iron_step_detected_relearned);
    RUN_TEST(test_cont3_transient_flagged_nothing_dropped);
    RUN_TEST(test_cont3_true_calibration_never_replaced);
    RUN_TEST(test_cont3_two_sensors_independent);
    RUN_TEST(test_cont3_ring_full_counted_and_failed_not_sticky);
#ifdef CONT3_TEST_THREADS
    RUN_TEST(test_cont3_isr_push_interleaved_with_task);
#endif
    return UNITY_END();
}
