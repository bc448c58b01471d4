/*
 * "Silent wrong answer" suite of the 2-D calibrator (issue 12, 2-D half) and the Monte-Carlo
 * calibration of its heading-error estimate. magcal:host-only (a few thousand pipeline runs).
 *
 * Every case is a synthetic ring with known truth (fixed seeds): raw = T h + b + noise, optionally
 * rounded to integer LSB, headings uniform or in clumps, optionally with singular points. A run's
 * truth metric is the heading RMS of its calibration over 720 NEW samples at uniformly spread
 * headings with the same noise and quantisation (what a user sees); the floor is the same RMS with
 * the TRUE calibration on the same samples (tests/test_calibrator.c convention).
 *
 * Tolerance of an OK (the 2-D floor ratio of tests/test_calibrator.c): heading RMS <= 1.2 x floor.
 * An OK outside it is a silent wrong answer; the suite asserts there are none.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "magcal/calibrator.h"
#include "test_util.h"
#include "unity.h"

#define CAP MAGCAL_MAX_SAMPLES
#define N_NEW 720u
#define FLOOR_RATIO 1.2
#define DEG (180.0 / 3.14159265358979323846)

static magcal_calibrator_t g_cal;
static magcal_vec2_t g_buf[CAP];
static uint32_t g_work[(MAGCAL_CALIBRATOR_WORKSPACE_LEN(CAP) + 3u) / 4u];
static magcal_vec2_t g_pts[CAP];
static magcal_vec2_t g_new[N_NEW];
static double g_new_psi[N_NEW];

void setUp(void) {}
void tearDown(void) {}

/* ---------------------------------------------------------------- synthetic rings */

typedef struct {
    double R;          /* field radius, raw units (LSB when quantised) */
    double axis_ratio; /* soft iron: minor / major */
    double angle_deg;  /* soft-iron axis direction */
    double bx, by;     /* hard iron, multiples of R */
    double noise;      /* sigma per axis / R */
    int quant;         /* 1: raw rounded to integers (LSB) */
    int clumps;        /* 0: uniform headings; else headings in this many clumps */
    double clump_w;    /* clump half-width, degrees */
    size_t n;          /* samples pushed */
    double out_frac;   /* fraction of singular points */
    uint32_t seed;
} ring_t;

typedef struct {
    test_distortion_t d;
    magcal_cal2d_t truth;
} world_t;

static void make_world(const ring_t *r, world_t *w)
{
    double a = r->angle_deg / DEG;
    double s1 = sqrt(r->axis_ratio);
    double s2 = 1.0 / s1;
    double c = cos(a), s = sin(a);
    double t00 = c * c * s1 + s * s * s2;
    double t01 = c * s * (s1 - s2);
    double t11 = s * s * s1 + c * c * s2;
    double det = t00 * t11 - t01 * t01;
    magcal_cal2d_t id = MAGCAL_CAL2D_IDENTITY;
    w->d.h0 = (float)r->R;
    w->d.t[0][0] = (float)t00;
    w->d.t[0][1] = (float)t01;
    w->d.t[1][0] = (float)t01;
    w->d.t[1][1] = (float)t11;
    w->d.bx = (float)(r->bx * r->R);
    w->d.by = (float)(r->by * r->R);
    w->truth = id;
    w->truth.offset.x = w->d.bx;
    w->truth.offset.y = w->d.by;
    w->truth.m[0][0] = (float)(t11 / det);
    w->truth.m[0][1] = (float)(-t01 / det);
    w->truth.m[1][0] = (float)(-t01 / det);
    w->truth.m[1][1] = (float)(t00 / det);
    w->truth.radius = (float)r->R;
}

static magcal_vec2_t sample_at(const ring_t *r, const world_t *w, double psi_deg, uint32_t *rng)
{
    magcal_vec2_t p = test_distorted_sample(&w->d, psi_deg, r->noise * r->R, rng);
    if (r->quant) {
        p.x = (float)floor((double)p.x + 0.5);
        p.y = (float)floor((double)p.y + 0.5);
    }
    return p;
}

/* The calibration set: uniform or clumped headings, singular points mixed in. */
static void make_samples(const ring_t *r, const world_t *w)
{
    uint32_t rng = r->seed * 2654435761u + 12345u;
    double c0 = 360.0 * test_rand_uniform(&rng);
    size_t i;
    for (i = 0; i < r->n; ++i) {
        double psi;
        if (r->clumps > 0) {
            int k = (int)(test_rand_uniform(&rng) * r->clumps);
            psi = c0 + 360.0 * k / r->clumps + r->clump_w * (2.0 * test_rand_uniform(&rng) - 1.0);
        } else {
            psi = 360.0 * test_rand_uniform(&rng);
        }
        g_pts[i] = sample_at(r, w, psi, &rng);
        if (test_rand_uniform(&rng) < r->out_frac) {
            if (test_rand_uniform(&rng) < 0.5) { /* far spike */
                g_pts[i].x = (float)(w->d.bx + 3.0 * r->R * (2.0 * test_rand_uniform(&rng) - 1.0));
                g_pts[i].y = (float)(w->d.by + 3.0 * r->R * (2.0 * test_rand_uniform(&rng) - 1.0));
            } else { /* near the ring: radially displaced by 15..50 % */
                double f = 1.15 + 0.35 * test_rand_uniform(&rng);
                g_pts[i].x = (float)(w->d.bx + f * ((double)g_pts[i].x - w->d.bx));
                g_pts[i].y = (float)(w->d.by + f * ((double)g_pts[i].y - w->d.by));
            }
        }
    }
    rng = r->seed * 40503u + 777u;
    for (i = 0; i < N_NEW; ++i) {
        g_new_psi[i] = (i + test_rand_uniform(&rng)) * (360.0 / N_NEW);
        g_new[i] = sample_at(r, w, g_new_psi[i], &rng);
    }
}

/* Heading RMS of calibration c over the new samples against their true headings. */
static double new_rms(const magcal_cal2d_t *c)
{
    double ss = 0.0;
    size_t i;
    for (i = 0; i < N_NEW; ++i) {
        float h = 0.0f;
        double e;
        if (magcal_heading_compute(c, g_new[i], 0.0f, &h, NULL) != MAGCAL_OK) {
            return INFINITY;
        }
        e = test_angle_diff_deg((double)h, g_new_psi[i]);
        ss += e * e;
    }
    return sqrt(ss / N_NEW);
}

typedef struct {
    magcal_status_t st;
    magcal_cal_report_t rep;
    double rms;   /* heading RMS of the run's calibration (rep.cal) on the new samples */
    double floor; /* same with the true calibration */
} outcome_t;

/* One run from `current` (updated when adopted). */
static void run_ring(const ring_t *r, magcal_cal2d_t *current, outcome_t *o)
{
    world_t w;
    size_t i;
    magcal_calibrator_cfg_t cfg = MAGCAL_CALIBRATOR_CFG_DEFAULT;
    make_world(r, &w);
    make_samples(r, &w);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_init(&g_cal, &cfg, g_buf, CAP, g_work, sizeof g_work));
    for (i = 0; i < r->n; ++i) {
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_push(&g_cal, g_pts[i]));
    }
    o->st = magcal_calibrator_run(&g_cal, current, &o->rep);
    o->floor = new_rms(&w.truth);
    o->rms = magcal_cal2d_validate(&o->rep.cal) == MAGCAL_OK ? new_rms(&o->rep.cal) : INFINITY;
}

/* A ring of radius 1000, 1 % noise, 300 samples; soft iron (axis ratio 0.55..1, any direction)
 * and hard iron (up to 1 R per axis) drawn from the seed. */
static ring_t base_ring(uint32_t seed)
{
    ring_t r;
    uint32_t rng = seed * 747796405u + 2891336453u;
    memset(&r, 0, sizeof r);
    r.R = 1000.0;
    r.axis_ratio = 0.55 + 0.45 * test_rand_uniform(&rng);
    r.angle_deg = 180.0 * test_rand_uniform(&rng);
    r.bx = 2.0 * test_rand_uniform(&rng) - 1.0;
    r.by = 2.0 * test_rand_uniform(&rng) - 1.0;
    r.noise = 0.01;
    r.n = 300;
    r.seed = seed;
    return r;
}

/* ---------------------------------------------------------------- Monte-Carlo of the estimate */

enum { CL_NOISE, CL_QUANT, CL_CLUMP, CL_COUNT, CL_OUTL, CL_N };
static const char *const g_cl_name[CL_N] = {"noise 0.1-8 %", "quantised 2-30 LSB", "clumps 3-8",
                                            "count 20-1000", "outliers 5-30 %"};

/* The runs of one class, by index: fills r and returns 0 past the end. */
static int mc_case(int cl, unsigned k, ring_t *r)
{
    static const double noise[] = {0.001, 0.003, 0.01, 0.03, 0.05, 0.08};
    static const double quant_R[] = {2.0, 3.0, 5.0, 8.0, 15.0, 30.0};
    static const int clumps[] = {3, 4, 5, 6, 8};
    static const size_t count[] = {20, 30, 50, 100, 300, 1000};
    static const double outl[] = {0.05, 0.15, 0.30};
    const unsigned seeds = 12u;
    unsigned v = k / seeds;
    *r = base_ring(1000u * (unsigned)cl + k + 1u);
    switch (cl) {
    case CL_NOISE:
        if (v >= 6u) return 0;
        r->noise = noise[v];
        break;
    case CL_QUANT:
        if (v >= 12u) return 0;
        r->R = quant_R[v % 6u];
        r->quant = 1;
        r->noise = v < 6u ? 0.001 : 0.02; /* undithered lattice, then light noise */
        break;
    case CL_CLUMP:
        if (v >= 10u) return 0;
        r->clumps = clumps[v % 5u];
        r->clump_w = 6.0;
        r->noise = v < 5u ? 0.005 : 0.03;
        break;
    case CL_COUNT:
        if (v >= 6u) return 0;
        r->n = count[v];
        break;
    default:
        if (v >= 3u) return 0;
        r->out_frac = outl[v];
        r->n = 400;
        break;
    }
    return 1;
}

static void test_estimate_monte_carlo_within_half_to_double(void)
{
    static const double edges[] = {0.0, 0.25, 0.5, 0.67, 0.8, 0.9, 1.0, 1.1, 1.25, 1.5, 2.0, 4.0, 1e30};
#define N_BINS (sizeof edges / sizeof edges[0] - 1u)
    unsigned hist[CL_N][N_BINS];
    unsigned total = 0u, inside = 0u;
    unsigned ok_cl[CL_N], in_cl[CL_N], ref_cl[CL_N];
    double lo_cl[CL_N], hi_cl[CL_N];
    int cl;
    memset(hist, 0, sizeof hist);
    printf("\nMonte-Carlo of est_heading_err_deg (ratio = estimate / measured heading RMS on new data)\n");
    for (cl = 0; cl < CL_N; ++cl) {
        unsigned k;
        ring_t r;
        ok_cl[cl] = in_cl[cl] = ref_cl[cl] = 0u;
        lo_cl[cl] = INFINITY;
        hi_cl[cl] = 0.0;
        for (k = 0u; mc_case(cl, k, &r); ++k) {
            magcal_cal2d_t cur = MAGCAL_CAL2D_IDENTITY;
            outcome_t o;
            double q;
            size_t b;
            run_ring(&r, &cur, &o);
            if (getenv("T2D_DEBUG") != NULL && atoi(getenv("T2D_DEBUG")) == cl) {
                printf("  dbg R %.0f clumps %d noise %.3f st %d distinct %u used %u rms %.3f floor %.3f act_param %.3f est_param %.3f est_noise %.3f design %.2f\n",
                       r.R, r.clumps, r.noise, (int)o.st, (unsigned)o.rep.distinct, (unsigned)o.rep.used, o.rms, o.floor,
                       sqrt(fmax(o.rms * o.rms - o.floor * o.floor, 0.0)), (double)o.rep.est_param_err_deg,
                       (double)o.rep.est_noise_deg, (double)o.rep.design_factor);
            }
            if (o.st != MAGCAL_OK) {
                ++ref_cl[cl];
                TEST_ASSERT_TRUE(o.st == MAGCAL_ERR_UNOBSERVABLE || o.st == MAGCAL_ERR_COVERAGE ||
                                 isnan(o.rep.est_heading_err_deg) || o.rep.est_heading_err_deg > 0.0f);
                continue;
            }
            q = (double)o.rep.est_heading_err_deg / o.rms;
            if (o.rms > FLOOR_RATIO * o.floor) {
                printf("  beyond 1.2 floor: %s R %.0f noise %.3f quant %d clumps %d n %u out %.2f: rms %.3f floor %.3f "
                       "(x%.2f) param %.3f noise %.3f design %.1f\n",
                       g_cl_name[cl], r.R, r.noise, r.quant, r.clumps, (unsigned)r.n, r.out_frac, o.rms, o.floor,
                       o.rms / o.floor, (double)o.rep.est_param_err_deg, (double)o.rep.est_noise_deg,
                       (double)o.rep.design_factor);
            }
            for (b = 0; b < N_BINS; ++b) {
                if (q >= edges[b] && q < edges[b + 1u]) {
                    hist[cl][b]++;
                }
            }
            ++ok_cl[cl];
            ++total;
            if (q >= 0.5 && q <= 2.0) {
                ++in_cl[cl];
                ++inside;
            }
            if (q < lo_cl[cl]) lo_cl[cl] = q;
            if (q > hi_cl[cl]) hi_cl[cl] = q;
            if (q < 0.5 || q > 2.0) {
                printf("  outside: %s R %.0f noise %.3f quant %d clumps %d n %u out %.2f: est %.3f (param %.3f "
                       "noise %.3f) measured %.3f floor %.3f\n",
                       g_cl_name[cl], r.R, r.noise, r.quant, r.clumps, (unsigned)r.n, r.out_frac,
                       (double)o.rep.est_heading_err_deg, (double)o.rep.est_param_err_deg,
                       (double)o.rep.est_noise_deg, o.rms, o.floor);
            }
        }
    }
    printf("%-20s %4s %4s %8s %8s %8s\n", "class", "OK", "ref", "in[.5,2]", "min", "max");
    for (cl = 0; cl < CL_N; ++cl) {
        printf("%-20s %4u %4u %8.3f %8.3f %8.3f\n", g_cl_name[cl], ok_cl[cl], ref_cl[cl],
               ok_cl[cl] ? (double)in_cl[cl] / ok_cl[cl] : 0.0, lo_cl[cl], hi_cl[cl]);
    }
    printf("histogram of the ratio (OK runs):\n%-20s", "bin lower edge");
    {
        size_t b;
        for (b = 0; b < N_BINS; ++b) {
            printf(" %5.2f", edges[b]);
        }
        printf("\n");
        for (cl = 0; cl < CL_N; ++cl) {
            printf("%-20s", g_cl_name[cl]);
            for (b = 0; b < N_BINS; ++b) {
                printf(" %5u", hist[cl][b]);
            }
            printf("\n");
        }
    }
    printf("all classes: %u OK runs, %.3f within [0.5, 2]\n", total, (double)inside / total);
    TEST_ASSERT_TRUE(total >= 250u);
    TEST_ASSERT_TRUE((double)inside >= 0.95 * total);
    TEST_ASSERT_TRUE(lo_cl[CL_CLUMP] >= 0.5);
    TEST_ASSERT_TRUE(lo_cl[CL_QUANT] >= 0.5);
#undef N_BINS
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_estimate_monte_carlo_within_half_to_double);
    return UNITY_END();
}
