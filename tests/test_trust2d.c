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
    unsigned total = 0u, inside = 0u, unobs = 0u, unobs_in = 0u;
    double unobs_lo = INFINITY, unobs_hi = 0.0;
    unsigned ok_cl[CL_N], in_cl[CL_N], ref_cl[CL_N];
    double lo_cl[CL_N], hi_cl[CL_N], old_lo_cl[CL_N], old_hi_cl[CL_N];
    unsigned old_in_cl[CL_N];
    int cl;
    memset(hist, 0, sizeof hist);
    printf("\nMonte-Carlo of est_heading_err_deg (ratio = estimate / measured heading RMS on new data)\n");
    for (cl = 0; cl < CL_N; ++cl) {
        unsigned k;
        ring_t r;
        ok_cl[cl] = in_cl[cl] = ref_cl[cl] = old_in_cl[cl] = 0u;
        lo_cl[cl] = old_lo_cl[cl] = INFINITY;
        hi_cl[cl] = old_hi_cl[cl] = 0.0;
        for (k = 0u; mc_case(cl, k, &r); ++k) {
            magcal_cal2d_t cur = MAGCAL_CAL2D_IDENTITY;
            outcome_t o;
            double q;
            size_t b;
            run_ring(&r, &cur, &o);
            if (o.st == MAGCAL_ERR_UNOBSERVABLE && isfinite(o.rms)) {
                /* refused by the estimate itself: how honest was it about the calibration it refused? */
                q = (double)o.rep.est_heading_err_deg / o.rms;
                ++unobs;
                unobs_lo = fmin(unobs_lo, q);
                unobs_hi = fmax(unobs_hi, q);
                unobs_in += (q >= 0.5 && q <= 2.0) ? 1u : 0u;
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
            {
                /* the pre-issue-12 formula on the same run: parameter error only */
                double cr = 360.0 / (double)o.rep.coverage_deg;
                double qo = DEG * (double)o.rep.residual_rel * sqrt(5.0 / (double)o.rep.used) * cr * cr / o.rms;
                old_in_cl[cl] += (qo >= 0.5 && qo <= 2.0) ? 1u : 0u;
                old_lo_cl[cl] = fmin(old_lo_cl[cl], qo);
                old_hi_cl[cl] = fmax(old_hi_cl[cl], qo);
            }
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
    printf("%-20s %4s %4s %8s %8s %8s   %s\n", "class", "OK", "ref", "in[.5,2]", "min", "max",
           "old formula: in[.5,2] min max");
    for (cl = 0; cl < CL_N; ++cl) {
        printf("%-20s %4u %4u %8.3f %8.3f %8.3f   %8.3f %8.4f %8.3f\n", g_cl_name[cl], ok_cl[cl], ref_cl[cl],
               ok_cl[cl] ? (double)in_cl[cl] / ok_cl[cl] : 0.0, lo_cl[cl], hi_cl[cl],
               ok_cl[cl] ? (double)old_in_cl[cl] / ok_cl[cl] : 0.0, old_lo_cl[cl], old_hi_cl[cl]);
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
    printf("runs refused as UNOBSERVABLE (estimate of the refused calibration): %u, %.3f within [0.5, 2], "
           "ratio %.3f..%.3f\n",
           unobs, unobs ? (double)unobs_in / unobs : 0.0, unobs_lo, unobs_hi);
    TEST_ASSERT_TRUE(total >= 250u);
    TEST_ASSERT_TRUE((double)inside >= 0.95 * total);
    TEST_ASSERT_TRUE(lo_cl[CL_CLUMP] >= 0.5);
    TEST_ASSERT_TRUE(lo_cl[CL_QUANT] >= 0.5);
    TEST_ASSERT_TRUE(unobs_lo >= 0.5); /* refused calibrations were not understated either */
#undef N_BINS
}

/* ---------------------------------------------------------------- adoption sequences */

/* Parameter error of calibration c in world w: heading RMS over 360 noise-free headings. */
static double cal_err(const magcal_cal2d_t *c, const ring_t *r)
{
    world_t w;
    ring_t clean = *r;
    double ss = 0.0;
    unsigned k;
    uint32_t rng = 1u;
    clean.noise = 0.0;
    clean.quant = 0;
    make_world(&clean, &w);
    for (k = 0; k < 360u; ++k) {
        float h;
        double e;
        if (magcal_heading_compute(c, sample_at(&clean, &w, (double)k, &rng), 0.0f, &h, NULL) != MAGCAL_OK) {
            return INFINITY;
        }
        e = test_angle_diff_deg((double)h, (double)k);
        ss += e * e;
    }
    return sqrt(ss / 360.0);
}

/* The pre-issue-12 estimate of `current`'s error, for comparison: 57.3 sqrt(max(0, V(cur) -
 * V(new))), V = mean (|c(p)| / mean - 1)^2 over the samples the run kept. */
static double old_current_err(const magcal_cal2d_t *cur, const magcal_cal2d_t *next, size_t n)
{
    const magcal_cal2d_t *cs[2];
    double v[2];
    int j;
    cs[0] = cur;
    cs[1] = next;
    for (j = 0; j < 2; ++j) {
        double s1 = 0.0, s2 = 0.0;
        size_t i, k = 0;
        for (i = 0; i < n; ++i) {
            int inl = 0;
            magcal_vec2_t h;
            if (magcal_calibrator_inlier(&g_cal, i, &inl) == MAGCAL_OK && inl &&
                magcal_correct_apply(cs[j], g_pts[i], &h) == MAGCAL_OK) {
                double rho = sqrt((double)h.x * h.x + (double)h.y * h.y);
                s1 += rho;
                s2 += rho * rho;
                ++k;
            }
        }
        v[j] = (s2 / k) / ((s1 / k) * (s1 / k)) - 1.0;
    }
    return DEG * sqrt(fmax(v[0] - v[1], 0.0));
}

/* The reported rule agrees with the documented rule and the reported numbers. */
static void check_rule(const outcome_t *o)
{
    const double cur = (double)o->rep.current_err_deg;
    const double par = (double)o->rep.est_param_err_deg;
    const int better = cur > MAGCAL_CALIBRATOR_ADOPT_MARGIN * par && cur > MAGCAL_CALIBRATOR_ADOPT_MIN_DEG;
    if (o->st == MAGCAL_OK) {
        TEST_ASSERT_TRUE(o->rep.adopt_rule != MAGCAL_ADOPT_NONE);
    }
    if (o->rep.adopt_rule == MAGCAL_ADOPT_BETTER) {
        TEST_ASSERT_TRUE(better);
    } else if (o->rep.adopt_rule == MAGCAL_ADOPT_STALE) {
        TEST_ASSERT_TRUE(!better && o->rep.current_err_z > MAGCAL_CALIBRATOR_STALE_Z && cur >= par);
    } else if (o->st == MAGCAL_ERR_NOT_BETTER) {
        TEST_ASSERT_FALSE(better);
    }
}

/* World of the adoption tests (one installation) and its run kinds. */
static ring_t adopt_world(uint32_t seed, int kind)
{
    ring_t r = base_ring(7u); /* the same soft and hard iron for every run */
    r.seed = seed;
    if (kind == 0) { /* good: long, quiet */
        r.n = 1000;
        r.noise = 0.002;
    } else { /* mediocre: short, noisy */
        r.n = 60;
        r.noise = 0.02;
    }
    return r;
}

/* Good then worse, 20 seeds: every worse run is NOT_BETTER, `current` bit-identical, and its
 * error on the new data is not inflated by their noise (the old estimate read the new run's own
 * noise projection: about its parameter error, whatever `current`'s true error). */
static void test_adopt_good_then_worse_refused_current_err_not_inflated(void)
{
    magcal_cal2d_t good = MAGCAL_CAL2D_IDENTITY;
    outcome_t o;
    ring_t r = adopt_world(1u, 0);
    unsigned s, above = 0u, refused = 0u, ok = 0u, zero = 0u;
    double sum_new = 0.0, sum_old = 0.0, sum_par = 0.0, good_err;
    run_ring(&r, &good, &o);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, o.st);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ADOPT_UNUSABLE, o.rep.adopt_rule);
    good_err = cal_err(&good, &r);
    printf("\ngood calibration: true parameter error %.4f deg, est_param %.4f deg\n", good_err,
           (double)o.rep.est_param_err_deg);
    for (s = 0; s < 20u; ++s) {
        magcal_cal2d_t cur = good;
        double oldv;
        r = adopt_world(100u + s, 1);
        run_ring(&r, &cur, &o);
        check_rule(&o);
        if (o.st == MAGCAL_OK) {
            ++ok;
        }
        if (o.st == MAGCAL_ERR_NOT_BETTER) {
            ++refused;
            TEST_ASSERT_EQUAL_MEMORY(&good, &cur, sizeof cur);
            TEST_ASSERT_EQUAL_INT(MAGCAL_ADOPT_NONE, o.rep.adopt_rule);
            oldv = old_current_err(&good, &o.rep.cal, r.n);
            sum_new += (double)o.rep.current_err_deg;
            sum_old += oldv;
            sum_par += (double)o.rep.est_param_err_deg;
            above += o.rep.current_err_deg > o.rep.est_param_err_deg ? 1u : 0u;
            zero += o.rep.current_err_deg < 0.05f ? 1u : 0u;
            printf("  worse run %2u: est_param %.3f (true %.3f)  current_err %.3f (old estimate %.3f, z %.1f)\n", s,
                   (double)o.rep.est_param_err_deg, cal_err(&o.rep.cal, &r), (double)o.rep.current_err_deg, oldv,
                   (double)o.rep.current_err_z);
        } else {
            printf("  worse run %2u: %s (rule %s) est_param %.3f (true %.3f) current_err %.3f z %.1f\n", s,
                   magcal_status_str(o.st), magcal_adopt_rule_str(o.rep.adopt_rule), (double)o.rep.est_param_err_deg,
                   cal_err(&o.rep.cal, &r), (double)o.rep.current_err_deg, (double)o.rep.current_err_z);
            if (o.st != MAGCAL_OK) {
                TEST_ASSERT_EQUAL_MEMORY(&good, &cur, sizeof cur);
            }
        }
    }
    printf("worse runs: %u NOT_BETTER, %u OK (adopted), others refused by a gate; mean current_err %.3f deg "
           "(old estimate %.3f), %u of them below 0.05 deg, for a %.4f deg calibration; new runs' est_param mean "
           "%.3f\n",
           refused, ok, sum_new / refused, sum_old / refused, zero, good_err, sum_par / refused);
    TEST_ASSERT_EQUAL_UINT(0u, ok);
    TEST_ASSERT_TRUE(refused >= 15u);
    TEST_ASSERT_TRUE(sum_new <= 0.5 * sum_old);
    TEST_ASSERT_TRUE(above <= 5u); /* noise alone: P(X > 8), chi2 with 4 dof = 9 % per run */
    TEST_ASSERT_TRUE(2u * zero > refused); /* median below 0.05 deg (old estimate: 0.29 deg) */
}

/* 20 mediocre runs after a good one: the installed calibration must not drift. Asserted: its
 * true parameter error stays within 1.5 x the good one's. The old rule (c) (same field radius
 * admits) is replayed on the same runs for comparison: it installed every run that passed the
 * gates. */
static void test_adopt_twenty_mediocre_runs_do_not_drift(void)
{
    magcal_cal2d_t cur = MAGCAL_CAL2D_IDENTITY;
    magcal_cal2d_t old_rule;
    outcome_t o;
    ring_t r = adopt_world(2u, 0);
    unsigned s, adopted = 0u, old_adopted = 0u;
    double good_err, worst = 0.0, old_worst = 0.0;
    run_ring(&r, &cur, &o);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, o.st);
    good_err = cal_err(&cur, &r);
    old_rule = cur;
    for (s = 0; s < 20u; ++s) {
        magcal_cal2d_t before = cur;
        double e;
        r = adopt_world(200u + s, 1);
        run_ring(&r, &cur, &o);
        check_rule(&o);
        if (o.st == MAGCAL_OK) {
            ++adopted;
        } else {
            TEST_ASSERT_EQUAL_MEMORY(&before, &cur, sizeof cur);
        }
        if (o.st == MAGCAL_OK || o.st == MAGCAL_ERR_NOT_BETTER) {
            old_rule = o.rep.cal;
            ++old_adopted;
        }
        e = cal_err(&cur, &r);
        worst = fmax(worst, e);
        old_worst = fmax(old_worst, cal_err(&old_rule, &r));
    }
    printf("\n20 mediocre runs after a good one (%.4f deg): now %u adopted, installed error final %.4f worst %.4f "
           "deg; old rule (c) %u adopted, final %.4f worst %.4f deg\n",
           good_err, adopted, cal_err(&cur, &r), worst, old_adopted, cal_err(&old_rule, &r), old_worst);
    TEST_ASSERT_TRUE(worst <= 1.5 * good_err);
}

/* A genuinely better run replaces a worse calibration (rule better), and the installed one is
 * the new run's calibration. */
static void test_adopt_better_replaces_worse(void)
{
    unsigned s;
    for (s = 0; s < 5u; ++s) {
        magcal_cal2d_t cur = MAGCAL_CAL2D_IDENTITY;
        outcome_t o;
        ring_t r = adopt_world(300u + s, 1);
        double e_old, e_new;
        run_ring(&r, &cur, &o);
        if (o.st != MAGCAL_OK) {
            continue; /* a mediocre run refused by a gate: nothing installed to improve on */
        }
        e_old = cal_err(&cur, &r);
        r = adopt_world(400u + s, 0);
        run_ring(&r, &cur, &o);
        e_new = cal_err(&cur, &r);
        printf("better replaces worse: %.3f deg -> %.4f deg (current_err %.3f, est_param %.4f, rule %s)\n", e_old,
               e_new, (double)o.rep.current_err_deg, (double)o.rep.est_param_err_deg,
               magcal_adopt_rule_str(o.rep.adopt_rule));
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, o.st);
        TEST_ASSERT_EQUAL_INT(MAGCAL_ADOPT_BETTER, o.rep.adopt_rule);
        TEST_ASSERT_EQUAL_MEMORY(&o.rep.cal, &cur, sizeof cur);
        TEST_ASSERT_TRUE(e_new < 0.5 * e_old);
    }
}

/* A real change (the hard iron moved by 1, 3 or 10 % of the field) is admitted even by a
 * mediocre run, and the installed calibration is better for the new installation. */
static void test_adopt_hard_iron_moved_admitted(void)
{
    static const double moves[] = {0.01, 0.03, 0.10};
    unsigned m;
    for (m = 0; m < 3u; ++m) {
        magcal_cal2d_t cur = MAGCAL_CAL2D_IDENTITY;
        outcome_t o;
        ring_t r = adopt_world(500u + m, 0);
        double e_before, e_after;
        run_ring(&r, &cur, &o);
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, o.st);
        r = adopt_world(600u + m, m == 0u ? 0 : 1); /* 1 %: a good run is needed to see it */
        r.bx += moves[m];
        e_before = cal_err(&cur, &r);
        run_ring(&r, &cur, &o);
        check_rule(&o);
        e_after = cal_err(&cur, &r);
        printf("hard iron moved %.0f %% of F: current error %.3f deg (estimated %.3f, z %.0f), new est_param %.3f: "
               "%s, rule %s, installed error %.3f deg\n",
               100.0 * moves[m], e_before, (double)o.rep.current_err_deg, (double)o.rep.current_err_z,
               (double)o.rep.est_param_err_deg, magcal_status_str(o.st), magcal_adopt_rule_str(o.rep.adopt_rule),
               e_after);
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, o.st);
        TEST_ASSERT_TRUE(o.rep.adopt_rule == MAGCAL_ADOPT_BETTER || o.rep.adopt_rule == MAGCAL_ADOPT_STALE);
        TEST_ASSERT_TRUE(e_after < 0.5 * e_before);
        /* the current calibration's error is measured within a factor of 2 */
        TEST_ASSERT_TRUE((double)o.rep.current_err_deg >= 0.5 * e_before && (double)o.rep.current_err_deg <= 2.0 * e_before);
    }
}

/* Small hard-iron moves (0.2 .. 1.6 % of F) seen by runs of 300 samples at 1 % noise: which rule
 * fires, and an OK never installs a calibration worse than the one it replaced. */
static void test_adopt_small_moves_rules_and_never_worse(void)
{
    static const double moves[] = {0.002, 0.003, 0.004, 0.005, 0.006, 0.008, 0.012, 0.016};
    unsigned m, s, n_rule[4] = {0u, 0u, 0u, 0u}, refused = 0u;
    for (m = 0; m < 8u; ++m) {
        for (s = 0; s < 4u; ++s) {
            magcal_cal2d_t cur = MAGCAL_CAL2D_IDENTITY;
            outcome_t o;
            ring_t r = adopt_world(700u + 10u * m + s, 0);
            double e_before, e_after;
            run_ring(&r, &cur, &o);
            TEST_ASSERT_EQUAL_INT(MAGCAL_OK, o.st);
            r = adopt_world(800u + 10u * m + s, 0);
            r.n = 300;
            r.noise = 0.01;
            r.bx += moves[m];
            e_before = cal_err(&cur, &r);
            run_ring(&r, &cur, &o);
            check_rule(&o);
            e_after = cal_err(&cur, &r);
            if (o.st == MAGCAL_OK) {
                n_rule[o.rep.adopt_rule]++;
                TEST_ASSERT_TRUE(e_after <= e_before);
            } else {
                TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NOT_BETTER, o.st);
                ++refused;
            }
        }
    }
    printf("small hard-iron moves, 32 runs: better %u, stale %u, not better %u\n", n_rule[MAGCAL_ADOPT_BETTER],
           n_rule[MAGCAL_ADOPT_STALE], refused);
    TEST_ASSERT_TRUE(n_rule[MAGCAL_ADOPT_BETTER] > 0u && refused > 0u);
}

/* ---------------------------------------------------------------- the silent-wrong suite */

typedef struct {
    unsigned cases, ok, refused, silent;
    unsigned by_status[64]; /* refusals by -status */
} tally_t;

static void tally_run(tally_t *t, const char *what, const ring_t *r, const outcome_t *o)
{
    t->cases++;
    if (o->st == MAGCAL_OK) {
        if (o->rms <= FLOOR_RATIO * o->floor) {
            t->ok++;
        } else {
            t->silent++;
            printf("  SILENT WRONG %s: R %.0f noise %.4f quant %d clumps %d w %.0f n %u: rms %.3f floor %.3f (x%.2f) "
                   "est %.3f\n",
                   what, r->R, r->noise, r->quant, r->clumps, r->clump_w, (unsigned)r->n, o->rms, o->floor,
                   o->rms / o->floor, (double)o->rep.est_heading_err_deg);
        }
    } else {
        t->refused++;
        if (-(int)o->st < 64) {
            t->by_status[-(int)o->st]++;
        }
    }
}

static void tally_print(const char *name, const tally_t *t)
{
    unsigned k;
    printf("%-30s cases %4u  OK within 1.2 x floor %4u  refused %4u  silent wrong %u  (refusals:", name, t->cases,
           t->ok, t->refused, t->silent);
    for (k = 1; k < 64u; ++k) {
        if (t->by_status[k] != 0u) {
            printf(" %s %u", magcal_status_str((magcal_status_t)(-(int)k)), t->by_status[k]);
        }
    }
    printf(")\n");
}

/* Quantised rings (2..50 LSB radius, undithered to lightly noisy), clumped rings (3..8 clumps of
 * 0.5..15 deg half-width, 0.2..3 % noise), both at once, and adoption sequences (good then worse,
 * 20 mediocre runs, better replaces worse, hard iron moved): every OK within 1.2 x the floor
 * (adoption: an OK may never install a calibration whose true error is larger than the one it
 * replaced), everything else a non-OK status with `current` untouched. */
static void test_suite_no_silent_wrong_answers(void)
{
    static const double qR[] = {2, 3, 4, 5, 6, 8, 10, 15, 20, 30, 50};
    static const double qnoise[] = {0.0, 0.005, 0.02};
    static const int kk[] = {3, 4, 5, 6, 7, 8};
    static const double kw[] = {0.5, 2.0, 6.0, 15.0};
    static const double knoise[] = {0.002, 0.01, 0.03};
    tally_t tq, tk, tqk, ta;
    unsigned a, b, c, seed;
    memset(&tq, 0, sizeof tq);
    memset(&tk, 0, sizeof tk);
    memset(&tqk, 0, sizeof tqk);
    memset(&ta, 0, sizeof ta);
    printf("\n");
    for (a = 0; a < sizeof qR / sizeof qR[0]; ++a) {
        for (b = 0; b < 3u; ++b) {
            for (seed = 0; seed < 3u; ++seed) {
                magcal_cal2d_t cur = MAGCAL_CAL2D_IDENTITY;
                outcome_t o;
                ring_t r = base_ring(10000u + 100u * a + 10u * b + seed);
                r.R = qR[a];
                r.quant = 1;
                r.noise = qnoise[b];
                run_ring(&r, &cur, &o);
                tally_run(&tq, "quantised", &r, &o);
            }
        }
    }
    for (a = 0; a < 6u; ++a) {
        for (b = 0; b < 4u; ++b) {
            for (c = 0; c < 3u; ++c) {
                for (seed = 0; seed < 2u; ++seed) {
                    magcal_cal2d_t cur = MAGCAL_CAL2D_IDENTITY;
                    outcome_t o;
                    ring_t r = base_ring(20000u + 1000u * a + 100u * b + 10u * c + seed);
                    r.clumps = kk[a];
                    r.clump_w = kw[b];
                    r.noise = knoise[c];
                    run_ring(&r, &cur, &o);
                    tally_run(&tk, "clumped", &r, &o);
                }
            }
        }
    }
    for (a = 1; a < 6u; ++a) {
        for (b = 0; b < 3u; ++b) {
            for (seed = 0; seed < 2u; ++seed) {
                magcal_cal2d_t cur = MAGCAL_CAL2D_IDENTITY;
                outcome_t o;
                ring_t r = base_ring(30000u + 100u * a + 10u * b + seed);
                r.clumps = kk[a];
                r.clump_w = 6.0;
                r.R = b == 0u ? 5.0 : (b == 1u ? 10.0 : 30.0);
                r.quant = 1;
                r.noise = 0.005;
                run_ring(&r, &cur, &o);
                tally_run(&tqk, "quantised+clumped", &r, &o);
            }
        }
    }
    /* adoption sequences: 5 installations, each good -> 20 mediocre -> 1 moved hard iron */
    for (seed = 0; seed < 5u; ++seed) {
        magcal_cal2d_t cur = MAGCAL_CAL2D_IDENTITY;
        outcome_t o;
        ring_t r = base_ring(40000u + seed);
        unsigned k;
        r.n = 1000;
        r.noise = 0.002;
        run_ring(&r, &cur, &o);
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, o.st);
        for (k = 0; k < 22u; ++k) {
            magcal_cal2d_t before = cur;
            double e_before;
            ring_t m = base_ring(40000u + seed); /* same installation */
            m.seed = 41000u + 100u * seed + k;
            m.n = 60u + 20u * (k % 5u);
            m.noise = 0.01 + 0.005 * (k % 4u);
            if (k == 21u) {
                m.bx += 0.05; /* the hard iron moved by 5 % of the field */
            }
            e_before = cal_err(&before, &m);
            run_ring(&m, &cur, &o);
            check_rule(&o);
            ta.cases++;
            if (o.st == MAGCAL_OK) {
                double e_after = cal_err(&cur, &m);
                if (e_after <= e_before && o.rms <= FLOOR_RATIO * o.floor) {
                    ta.ok++;
                } else {
                    ta.silent++;
                    printf("  SILENT WRONG adoption: installed %.4f deg over %.4f deg (rms %.3f floor %.3f)\n", e_after,
                           e_before, o.rms, o.floor);
                }
            } else {
                TEST_ASSERT_EQUAL_MEMORY(&before, &cur, sizeof cur);
                ta.refused++;
                if (-(int)o.st < 64) {
                    ta.by_status[-(int)o.st]++;
                }
            }
        }
        TEST_ASSERT_TRUE(cal_err(&cur, &r) < 3.0); /* sanity: the moved hard iron was taken in */
    }
    tally_print("quantised rings 2-50 LSB", &tq);
    tally_print("clumped rings 3-8 clumps", &tk);
    tally_print("quantised + clumped", &tqk);
    tally_print("adoption sequences", &ta);
    printf("total: %u cases, %u OK within tolerance, %u refused, %u silent wrong answers\n",
           tq.cases + tk.cases + tqk.cases + ta.cases, tq.ok + tk.ok + tqk.ok + ta.ok,
           tq.refused + tk.refused + tqk.refused + ta.refused, tq.silent + tk.silent + tqk.silent + ta.silent);
    TEST_ASSERT_EQUAL_UINT(0u, tq.silent + tk.silent + tqk.silent + ta.silent);
    /* the suite must exercise both answers in every class */
    TEST_ASSERT_TRUE(tq.ok > 0u && tq.refused > 0u);
    TEST_ASSERT_TRUE(tk.ok > 0u && tk.refused > 0u);
    TEST_ASSERT_TRUE(ta.ok >= 5u && ta.refused > 0u);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_estimate_monte_carlo_within_half_to_double);
    RUN_TEST(test_adopt_good_then_worse_refused_current_err_not_inflated);
    RUN_TEST(test_adopt_twenty_mediocre_runs_do_not_drift);
    RUN_TEST(test_adopt_better_replaces_worse);
    RUN_TEST(test_adopt_hard_iron_moved_admitted);
    RUN_TEST(test_adopt_small_moves_rules_and_never_worse);
    RUN_TEST(test_suite_no_silent_wrong_answers);
    return UNITY_END();
}
