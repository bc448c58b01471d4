/*
 * Driver for the bounded-execution measurement (docs/reliability.md "Bounded execution"):
 * fills a calibrator of capacity MAGCAL_MAX_SAMPLES with one scenario and calls
 * magcal_calibrator_run() once. Host: run under valgrind --tool=callgrind
 * --toggle-collect=magcal_calibrator_run (tools/fuzz/bound_calibrator.sh) to count the
 * instructions of run() alone. Cortex-M4F (-DMAGCAL_BOUND_M4F, tools/fuzz/bound_m4f.sh): every
 * scenario in turn, timed with the CMSDK APB timer 0 of the QEMU mps2-an386 board (25 MHz);
 * under `qemu-system-arm -icount shift=0` (one instruction per virtual ns) the instruction count
 * of run() is 40 x ticks. double is used to build the inputs only.
 *
 *   bound_calibrator SCENARIO       prints "SCENARIO status=.. used=.. eps=.. min_pts=.."
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "magcal/calibrator.h"

#define N MAGCAL_MAX_SAMPLES
#define TWO_PI 6.283185307179586

static magcal_vec2_t g_buf[N];
static uint32_t g_work[(MAGCAL_CALIBRATOR_WORKSPACE_LEN(N) + 3u) / 4u];
static magcal_vec2_t g_pts[N];
static uint32_t g_rng = 12345u;

static double urand(void) /* xorshift32, deterministic */
{
    g_rng ^= g_rng << 13;
    g_rng ^= g_rng >> 17;
    g_rng ^= g_rng << 5;
    return (double)g_rng / 4294967296.0;
}

static double nrand(void)
{
    double u1 = urand() + 1e-12;
    double u2 = urand();
    return sqrt(-2.0 * log(u1)) * cos(TWO_PI * u2);
}

static void ring(size_t from, size_t to, double r, double sigma, double turns)
{
    size_t i;
    for (i = from; i < to; ++i) {
        double t = TWO_PI * turns * (double)(i - from) / (double)(to - from);
        double rr = r + sigma * nrand();
        g_pts[i].x = (float)(12.0 + 1.2 * rr * cos(t));
        g_pts[i].y = (float)(-7.0 + 0.9 * rr * sin(t));
    }
}

#ifdef MAGCAL_BOUND_M4F
/* CMSDK APB timer 0 of the mps2-an386 board: down-counter at PCLK (25 MHz in QEMU). */
#define TIMER0_CTRL (*(volatile uint32_t *)0x40000000u)
#define TIMER0_VALUE (*(volatile uint32_t *)0x40000004u)
#define TIMER0_RELOAD (*(volatile uint32_t *)0x40000008u)
static uint32_t g_ticks;
#endif

static int bound_one(const char *s);

#ifdef MAGCAL_BOUND_M4F
int main(void)
{
    static const char *const all[] = {"ring", "disc", "grid_lattice", "clumps4", "clumps6", "clumps8",
                                      "ring_eps_huge_minpts4", "ring_classic_eps_huge_iter2000"};
    size_t k;
    TIMER0_CTRL = 0u;
    TIMER0_RELOAD = 0xFFFFFFFFu;
    TIMER0_VALUE = 0xFFFFFFFFu;
    TIMER0_CTRL = 1u;
    for (k = 0; k < sizeof all / sizeof all[0]; ++k) {
        if (bound_one(all[k]) != 0) {
            return 1;
        }
        printf("  M4F ticks=%lu instructions~%lu\n", (unsigned long)g_ticks, 40ul * (unsigned long)g_ticks);
    }
    return 0;
}
#else
int main(int argc, char **argv)
{
    return bound_one(argc > 1 ? argv[1] : "ring");
}
#endif

static int bound_one(const char *s)
{
    magcal_calibrator_cfg_t cfg = MAGCAL_CALIBRATOR_CFG_DEFAULT;
    magcal_calibrator_t cal;
    magcal_cal2d_t cur = MAGCAL_CAL2D_IDENTITY;
    magcal_cal_report_t rep;
    magcal_status_t st;
    size_t i;
#ifdef MAGCAL_BOUND_M4F
    uint32_t t0;
#endif
    g_rng = 12345u; /* same data whether scenarios run in one process or one each */

    if (strcmp(s, "ring") == 0) { /* clean ring, 2 turns, 0.5 % noise: the normal case */
        ring(0, N, 40.0, 0.2, 2.0);
    } else if (strcmp(s, "ring_noisy") == 0) { /* 25 % radial noise: eps' grows to its cap R */
        ring(0, N, 40.0, 10.0, 2.0);
    } else if (strcmp(s, "disc") == 0) { /* uniform filled disc: large neighbourhoods */
        for (i = 0; i < N; ++i) {
            double r = 40.0 * sqrt(urand());
            double t = TWO_PI * urand();
            g_pts[i].x = (float)(r * cos(t));
            g_pts[i].y = (float)(r * sin(t));
        }
    } else if (strcmp(s, "ring_cluster45") == 0) { /* 55 % ring + 45 % in one tight cluster on it */
        ring(0, 563, 40.0, 0.2, 1.0);
        for (i = 563; i < N; ++i) {
            g_pts[i].x = (float)(12.0 + 48.0 + 0.5 * nrand());
            g_pts[i].y = (float)(-7.0 + 0.5 * nrand());
        }
    } else if (strcmp(s, "ring_spikes45") == 0) { /* 45 % spikes spread over 3 R around it */
        ring(0, N, 40.0, 0.2, 2.0);
        for (i = 0; i < N; i += 2) {
            if (i % 20u < 18u) {
                g_pts[i].x = (float)(120.0 * (urand() - 0.5) * 2.0);
                g_pts[i].y = (float)(120.0 * (urand() - 0.5) * 2.0);
            }
        }
    } else if (strcmp(s, "grid_lattice") == 0) { /* 32 x 32 lattice: every point has 8 equidistant neighbours */
        for (i = 0; i < N; ++i) {
            g_pts[i].x = (float)(i % 32u);
            g_pts[i].y = (float)(i / 32u);
        }
    } else if (strcmp(s, "ring_far_outliers") == 0) { /* 2 samples 1e5 R away stretch the grid bbox */
        ring(0, N, 40.0, 0.2, 2.0);
        g_pts[0].x = 4.0e6f;
        g_pts[0].y = 4.0e6f;
        g_pts[1].x = -4.0e6f;
        g_pts[1].y = -4.0e6f;
    } else if (strncmp(s, "clumps", 6) == 0 && s[6] >= '2' && s[6] <= '9') {
        /* k tight clumps spread evenly on the ring ("clumps4"), "_wide": 0.1 rad spread */
        size_t k = (size_t)(s[6] - '0');
        double sd = strstr(s, "_wide") != NULL ? 0.1 : 0.02;
        for (i = 0; i < N; ++i) {
            double t = TWO_PI * (double)(i % k) / (double)k + sd * nrand();
            g_pts[i].x = (float)(40.0 * cos(t));
            g_pts[i].y = (float)(40.0 * sin(t));
        }
    } else if (strcmp(s, "ring_half_clumps3") == 0) { /* ring (1 turn) with 3 clumps holding half */
        ring(0, N / 2u, 40.0, 0.2, 1.0);
        for (i = N / 2u; i < N; ++i) {
            double t = TWO_PI * (double)(i % 3u) / 3.0 + 0.02 * nrand();
            g_pts[i].x = (float)(12.0 + 48.0 * cos(t));
            g_pts[i].y = (float)(-7.0 + 36.0 * sin(t));
        }
    } else if (strcmp(s, "ring_noisy_lattice") == 0) { /* ring with 25 % noise, coordinates on a coarse lattice */
        ring(0, N, 40.0, 10.0, 2.0);
        for (i = 0; i < N; ++i) {
            g_pts[i].x = (float)floor((double)g_pts[i].x / 4.0) * 4.0f;
            g_pts[i].y = (float)floor((double)g_pts[i].y / 4.0) * 4.0f;
        }
    } else if (strcmp(s, "ring_plus_disc") == 0) { /* half ring, half filled disc inside it */
        ring(0, N / 2u, 40.0, 0.2, 1.0);
        for (i = N / 2u; i < N; ++i) {
            double r = 48.0 * sqrt(urand());
            double t = TWO_PI * urand();
            g_pts[i].x = (float)(12.0 + r * cos(t));
            g_pts[i].y = (float)(-7.0 + r * sin(t));
        }
    } else if (strcmp(s, "annulus_wide") == 0) { /* uniform annulus 0.5 R .. 1.5 R */
        for (i = 0; i < N; ++i) {
            double r = 20.0 + 40.0 * urand();
            double t = TWO_PI * urand();
            g_pts[i].x = (float)(r * cos(t));
            g_pts[i].y = (float)(r * sin(t));
        }
    } else if (strcmp(s, "ring_eps_huge") == 0) { /* user override: eps covers everything */
        ring(0, N, 40.0, 0.2, 2.0);
        cfg.eps = 1.0e3f;
        cfg.min_pts = MAGCAL_MAX_MIN_PTS;
    } else if (strcmp(s, "ring_eps_huge_minpts4") == 0) { /* every sample a neighbour, auto MinPts */
        ring(0, N, 40.0, 0.2, 2.0);
        cfg.eps = 1.0e3f;
        cfg.min_pts = 4u;
    } else if (strcmp(s, "ring_classic_eps_huge_iter2000") == 0) { /* worst user configuration */
        ring(0, N, 40.0, 0.2, 2.0);
        cfg.filter = MAGCAL_FILTER_OPTICS_CLASSIC;
        cfg.eps = 1.0e3f;
        cfg.min_pts = MAGCAL_MAX_MIN_PTS;
        cfg.consensus.max_iter = MAGCAL_CONSENSUS_MAX_ITER;
        cfg.consensus.refine_iter = MAGCAL_CONSENSUS_MAX_REFINE;
    } else if (strcmp(s, "spikes45_iter2000") == 0) {
        ring(0, N, 40.0, 0.2, 2.0);
        for (i = 0; i < N; i += 2) {
            if (i % 20u < 18u) {
                g_pts[i].x = (float)(120.0 * (urand() - 0.5) * 2.0);
                g_pts[i].y = (float)(120.0 * (urand() - 0.5) * 2.0);
            }
        }
        cfg.consensus.max_iter = MAGCAL_CONSENSUS_MAX_ITER;
        cfg.consensus.refine_iter = MAGCAL_CONSENSUS_MAX_REFINE;
    } else {
        fprintf(stderr, "unknown scenario %s\n", s);
        return 2;
    }
    if (magcal_calibrator_init(&cal, &cfg, g_buf, N, g_work, sizeof g_work) != MAGCAL_OK) {
        fprintf(stderr, "init failed\n");
        return 2;
    }
    for (i = 0; i < N; ++i) {
        if (magcal_calibrator_push(&cal, g_pts[i]) != MAGCAL_OK) {
            fprintf(stderr, "push %zu failed\n", i);
            return 2;
        }
    }
#ifdef MAGCAL_BOUND_M4F
    t0 = TIMER0_VALUE;
    st = magcal_calibrator_run(&cal, &cur, &rep);
    g_ticks = t0 - TIMER0_VALUE;
#else
    st = magcal_calibrator_run(&cal, &cur, &rep);
#endif
    if (getenv("BOUND_VERBOSE") != NULL) {
        fprintf(stderr, "cov=%g r1=%g r2=%g c=(%g,%g) resid=%g\n", (double)rep.coverage_deg,
                (double)rep.ellipse.semi_minor, (double)rep.ellipse.semi_major, (double)rep.ellipse.center.x,
                (double)rep.ellipse.center.y, (double)rep.residual_rel);
    }
    printf("%s status=%d used=%u eps=%g min_pts=%u\n", s, (int)st, (unsigned)rep.used,
           (double)rep.filter_eps, (unsigned)rep.filter_min_pts);
    return 0;
}
