/*
 * The library built with every feature switch of config.h at 0 (tests/switches/CMakeLists.txt):
 * the minimal 2-D firmware of issue 14 (improved OPTICS + consensus + least-squares fit +
 * correction + heading) and the calibrator still work and are checked against known truth, and
 * the configuration values that select a compiled-out feature return MAGCAL_ERR_ARG. A second
 * CTest (check_symbols.cmake) checks that the disabled modules' functions are not in the archive.
 *
 * Data: a ring through a SYMMETRIC soft iron, p = c + S u with S = R(30 deg) diag(1.13, 0.89)
 * R(-30 deg) x 460 and c = (300, -200), u = (-sin psi, cos psi) at the true heading psi, Gaussian
 * noise sigma 3, plus 10 % outliers (6 % scattered over 1.5..2.5 R, 4 % a glitch cluster). The
 * symmetric correction M ~ S^-1 then gives h ~ u, so the corrected heading equals psi (no
 * constant rotation to remove) and each OK result is judged against psi and c.
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "magcal/calibrator.h"
#include "magcal/consensus.h"
#include "magcal/continuous.h"
#include "magcal/ellipse.h"
#include "magcal/heading.h"
#include "magcal/optics.h"
#include "adopt/calibrator_internal.h" /* magcal_calibrator_set_coarse (the continuous calibrator's) */
#include "unity.h"

#if MAGCAL_CFG_ENABLE_DBSCAN || MAGCAL_CFG_ENABLE_OPTICS_CLASSIC || MAGCAL_CFG_ENABLE_PAPER ||       \
    MAGCAL_CFG_ENABLE_3D || MAGCAL_CFG_ENABLE_GEOMAG || MAGCAL_CFG_ENABLE_AIDED ||                  \
    MAGCAL_CFG_ENABLE_SWING || MAGCAL_CFG_ENABLE_COARSE
#error "this test must be compiled with every MAGCAL_CFG_ENABLE_* at 0 (tests/switches/CMakeLists.txt)"
#endif

#define N 400u
#define TPI 6.28318530717958647692
#define CX 300.0
#define CY (-200.0)
#define R0 460.0
#define SIGMA 3.0

static magcal_vec2_t g_pts[N];
static uint8_t g_kind[N]; /* 0 ring, 1 scattered, 2 glitch */
static double g_psi[N];   /* true heading (rad) of ring samples */
static uint8_t g_cand[N];
static uint8_t g_inl[N];
#define WORK_LEN                                                                                   \
    ((MAGCAL_OPTICS_FILTER_WORKSPACE_LEN(N) > MAGCAL_CONSENSUS_WORKSPACE_LEN(N))                    \
         ? MAGCAL_OPTICS_FILTER_WORKSPACE_LEN(N)                                                    \
         : MAGCAL_CONSENSUS_WORKSPACE_LEN(N))
static MAGCAL_WORKSPACE_DECLARE(g_work, WORK_LEN);
static MAGCAL_CALIBRATOR_WORKSPACE_DECLARE(g_cwork, N);
static magcal_vec2_t g_cbuf[N];
static magcal_calibrator_t g_cal;

static uint32_t g_rng;

static double rng_uniform(void) /* (0, 1), xorshift32 */
{
    uint32_t x = g_rng;
    x ^= x << 13;
    x ^= x >> 17;
    x ^= x << 5;
    g_rng = x;
    return ((double)(x >> 8) + 0.5) / 16777216.0;
}

static double rng_gauss(void)
{
    double u1 = rng_uniform();
    double u2 = rng_uniform();
    return sqrt(-2.0 * log(u1)) * cos(TPI * u2);
}

/* c + S u, S = R(th) diag(ka, kb) R(-th) x R0 (symmetric soft iron) */
static magcal_vec2_t distort(double ux, double uy, double scale)
{
    const double th = 30.0 * TPI / 360.0, ka = 1.13, kb = 0.89;
    double c = cos(th), s = sin(th);
    double a = (c * ux + s * uy) * ka; /* R(-th) u, then diag */
    double b = (-s * ux + c * uy) * kb;
    magcal_vec2_t p;
    p.x = (float)(CX + R0 * scale * (c * a - s * b));
    p.y = (float)(CY + R0 * scale * (s * a + c * b));
    return p;
}

static void generate(void)
{
    size_t i;
    g_rng = 0x9E3779B9u;
    for (i = 0u; i < N; ++i) {
        double psi = TPI * ((double)i + 0.3 * rng_uniform()) / (double)N;
        g_kind[i] = (i % 17u == 5u) ? 1u : ((i >= 200u && i < 216u) ? 2u : 0u);
        g_psi[i] = psi;
        if (g_kind[i] == 0u) {
            g_pts[i] = distort(-sin(psi), cos(psi), 1.0);
            g_pts[i].x += (float)(SIGMA * rng_gauss());
            g_pts[i].y += (float)(SIGMA * rng_gauss());
        } else if (g_kind[i] == 1u) {
            double a = TPI * rng_uniform();
            g_pts[i] = distort(cos(a), sin(a), 1.5 + rng_uniform());
        } else {
            g_pts[i].x = (float)(CX + 6.0 * R0 + 2.0 * rng_gauss());
            g_pts[i].y = (float)(CY + 2.0 * rng_gauss());
        }
    }
}

/* Largest |corrected heading - true heading| (deg) over 72 noise-free headings. */
static double worst_heading_err_deg(const magcal_cal2d_t *cal)
{
    double worst = 0.0;
    size_t k;
    for (k = 0u; k < 72u; ++k) {
        double psi = TPI * (double)k / 72.0;
        magcal_vec2_t raw = distort(-sin(psi), cos(psi), 1.0);
        float deg = -1.0f;
        double d;
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_heading_compute(cal, raw, 0.0f, &deg, NULL));
        d = fmod((double)deg - psi * 360.0 / TPI + 540.0, 360.0) - 180.0;
        worst = fmax(worst, fabs(d));
    }
    return worst;
}

void setUp(void) { generate(); }
void tearDown(void) {}

/* improved OPTICS (default cfg, automatic parameters) + consensus + fit + correction + heading */
static void test_minimal_2d_pipeline_meets_truth(void)
{
    magcal_optics_cfg_t oc = MAGCAL_OPTICS_CFG_DEFAULT;
    const magcal_consensus_cfg_t cc = MAGCAL_CONSENSUS_CFG_DEFAULT;
    magcal_consensus_result_t cres;
    magcal_cal2d_t cal;
    size_t i, n_out = 0u, caught = 0u, false_rej = 0u;
    double err;

    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_optics_filter(&oc, g_pts, N, g_work, sizeof g_work, g_cand, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_consensus_run(&cc, g_pts, N, g_cand, g_work, sizeof g_work, g_inl, &cres));
    for (i = 0u; i < N; ++i) {
        if (g_kind[i] != 0u) {
            ++n_out;
            caught += (g_inl[i] == 0u) ? 1u : 0u;
        } else {
            false_rej += (g_inl[i] == 0u) ? 1u : 0u;
        }
    }
    TEST_ASSERT_EQUAL_UINT(n_out, caught);     /* every outlier is >= 0.5 R off the ring */
    TEST_ASSERT_TRUE(false_rej <= N / 100u); /* at most 1 % of the ring (3.5 sigma cut: ~0.05 %) */
    /* centre: sigma 3 over ~360 samples gives ~0.3; 1.5 leaves 5 sigma */
    TEST_ASSERT_FLOAT_WITHIN(1.5f, (float)CX, cres.fit.center.x);
    TEST_ASSERT_FLOAT_WITHIN(1.5f, (float)CY, cres.fit.center.y);
    /* semi-axes 0.89 R0 = 409.4 and 1.13 R0 = 519.8 within 0.5 % */
    TEST_ASSERT_FLOAT_WITHIN(2.0f, (float)(0.89 * R0), cres.fit.semi_minor);
    TEST_ASSERT_FLOAT_WITHIN(2.6f, (float)(1.13 * R0), cres.fit.semi_major);

    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_ellipse_to_cal(&cres.fit, MAGCAL_CORR_SYMMETRIC, 0.0f, &cal));
    err = worst_heading_err_deg(&cal);
    printf("minimal pipeline: %u of %u outliers caught, %u ring samples rejected, centre (%.2f, %.2f), "
           "axes %.1f / %.1f, worst heading error %.3f deg\n", (unsigned)caught, (unsigned)n_out,
           (unsigned)false_rej, (double)cres.fit.center.x, (double)cres.fit.center.y,
           (double)cres.fit.semi_minor, (double)cres.fit.semi_major, err);
    TEST_ASSERT_TRUE(err < 0.3); /* 0.3 deg bound */
    /* KPHI is one of the source documents' variants (MAGCAL_CFG_ENABLE_PAPER = 0): unknown form */
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_ellipse_to_cal(&cres.fit, MAGCAL_CORR_KPHI, 0.0f, &cal));
}

static magcal_status_t run_calibrator(magcal_calibrator_filter_t filter, magcal_cal2d_t *cur)
{
    magcal_calibrator_cfg_t cfg = MAGCAL_CALIBRATOR_CFG_DEFAULT;
    size_t i;
    cfg.filter = filter;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_init(&g_cal, &cfg, g_cbuf, N, g_cwork, sizeof g_cwork));
    for (i = 0u; i < N; ++i) {
        magcal_status_t st = magcal_calibrator_push(&g_cal, g_pts[i]);
        TEST_ASSERT_TRUE(st == MAGCAL_OK || st == MAGCAL_ERR_GATED);
    }
    return magcal_calibrator_run(&g_cal, cur, NULL);
}

/* the calibrator's default pipeline (OPTICS improved) adopts an accurate calibration */
static void test_calibrator_default_meets_truth(void)
{
    magcal_cal2d_t cur = MAGCAL_CAL2D_IDENTITY;
    double err;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, run_calibrator(MAGCAL_FILTER_OPTICS_GRID, &cur));
    err = worst_heading_err_deg(&cur);
    printf("calibrator: offset (%.2f, %.2f), worst heading error %.3f deg\n", (double)cur.offset.x,
           (double)cur.offset.y, err);
    TEST_ASSERT_FLOAT_WITHIN(1.5f, (float)CX, cur.offset.x);
    TEST_ASSERT_FLOAT_WITHIN(1.5f, (float)CY, cur.offset.y);
    TEST_ASSERT_TRUE(err < 0.3);
}

/* filter = DBSCAN selects a compiled-out feature: MAGCAL_ERR_ARG, calibration untouched */
static void test_calibrator_dbscan_is_refused(void)
{
    const magcal_cal2d_t id = MAGCAL_CAL2D_IDENTITY;
    magcal_cal2d_t cur = MAGCAL_CAL2D_IDENTITY;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, run_calibrator(MAGCAL_FILTER_DBSCAN, &cur));
    TEST_ASSERT_EQUAL_MEMORY(&id, &cur, sizeof cur);
}

/* The coarse stage is compiled out (MAGCAL_CFG_ENABLE_COARSE = 0): a 200-degree arc that a
 * coarse-enabled solve (set_coarse: from 90 degrees, bound 30 degrees) would take to the coarse
 * stage fails the coverage gate, calibration untouched, nothing reported coarse. */
static void test_calibrator_coarse_is_absent(void)
{
    const magcal_cal2d_t id = MAGCAL_CAL2D_IDENTITY;
    magcal_cal2d_t cur = MAGCAL_CAL2D_IDENTITY;
    magcal_calibrator_cfg_t cfg = MAGCAL_CALIBRATOR_CFG_DEFAULT;
    magcal_cal_report_t rep;
    size_t i, pushed = 0u;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_init(&g_cal, &cfg, g_cbuf, N, g_cwork, sizeof g_cwork));
    for (i = 0u; i < N; ++i) {
        if (g_kind[i] == 0u && g_psi[i] < 200.0 * TPI / 360.0) {
            magcal_status_t st = magcal_calibrator_push(&g_cal, g_pts[i]);
            TEST_ASSERT_TRUE(st == MAGCAL_OK || st == MAGCAL_ERR_GATED);
            pushed += (st == MAGCAL_OK) ? 1u : 0u;
        }
    }
    TEST_ASSERT_TRUE(pushed >= 150u);
    magcal_calibrator_set_coarse(&g_cal, 90.0f, 30.0f, 0u);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_COVERAGE, magcal_calibrator_run(&g_cal, &cur, &rep));
    printf("coarse stage absent: %u samples, coverage %.1f deg -> %s\n", (unsigned)pushed,
           (double)rep.coverage_deg, magcal_status_str(rep.status));
    /* the arc is inside the coarse stage's range: only its absence explains the refusal */
    TEST_ASSERT_TRUE(rep.coverage_deg >= 90.0f && rep.coverage_deg < cfg.min_coverage_deg);
    TEST_ASSERT_EQUAL_UINT8(0u, rep.coarse);
    TEST_ASSERT_EQUAL_MEMORY(&id, &cur, sizeof cur);
}

/* The continuous calibrator with the coarse stage compiled out: a configuration that asks for it
 * (cfg.coarse_coverage_deg > 0) is refused at init (it would start solves that fail their
 * coverage gate), the default (0) is taken. */
#define CONT_SLOTS MAGCAL_CONT_SLOTS(36u, 8u)
static magcal_intake_slot_t g_cslots[CONT_SLOTS];
static magcal_vec2_t g_cbuf2[CONT_SLOTS];
static MAGCAL_CALIBRATOR_WORKSPACE_DECLARE(g_cwork2, CONT_SLOTS);
static magcal_cont_t g_cc;

static void test_cont_coarse_coverage_refused_when_absent(void)
{
    magcal_cont_cfg_t cfg = MAGCAL_CONT_CFG_DEFAULT;
    TEST_ASSERT_EQUAL_FLOAT(0.0f, cfg.coarse_coverage_deg);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_init(&g_cc, &cfg, NULL, g_cslots, CONT_SLOTS, g_cbuf2, g_cwork2,
                                                      sizeof g_cwork2));
    cfg.coarse_coverage_deg = 150.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_cont_init(&g_cc, &cfg, NULL, g_cslots, CONT_SLOTS, g_cbuf2, g_cwork2,
                                                           sizeof g_cwork2));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_minimal_2d_pipeline_meets_truth);
    RUN_TEST(test_calibrator_default_meets_truth);
    RUN_TEST(test_calibrator_dbscan_is_refused);
    RUN_TEST(test_calibrator_coarse_is_absent);
    RUN_TEST(test_cont_coarse_coverage_refused_when_absent);
    return UNITY_END();
}
