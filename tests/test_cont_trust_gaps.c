/*
 * Tests of the continuous 2-D calibrator's heading trust where it used to escape (continuous.h
 * "Heading trust", src/loop/cont_change.c, cont_judge.c): every heading returned OK must be within
 * the tolerance of the truth. Known truth: a ring of radius 30 with soft iron and hard iron
 * (12, -7) (tests/support test_distorted_sample), 0.15 of noise, 50 Hz, push + 2 steps per row as
 * firmware does; the heading of every row is compared with the true one.
 *  - a hard-iron step while the vehicle stands at one heading (a single sector: no change can be
 *    declared) keeps the heading untrusted for as long as the field stays off the calibration
 *    (30-min seed 38: OK at 37 deg of error for 5 minutes, after an episode whose samples hovered
 *    at twice the threshold closed and the model's health test switched the per-sample test off);
 *  - a glitch in a sector the store did not cover (a sensor rail) is not OK;
 *  - a transient that starts just before an adoption is not OK while the transient judge's
 *    baselines settle (30-min seed 34: OK rows up to 14.2 deg in the first second of a relearnt
 *    calibration, where the judge could raise no flag);
 *  - a parked transient that turns the heading is not explained away by the judge's regression
 *    (60-min seed 2: OK rows up to 15.9 deg).
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "magcal/continuous.h"
#include "test_util.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

#define SLOTS MAGCAL_CONT_SLOTS(36u, 8u)
#define RATE_MS 20u
#define OK_TOL_DEG 5.0 /* an OK heading within this of the truth (check_stream.py worst_ok) */

static magcal_intake_slot_t g_slots[SLOTS];
static magcal_vec2_t g_buf[SLOTS];
static MAGCAL_CALIBRATOR_WORKSPACE_DECLARE(g_work, SLOTS);
static magcal_cont_t g_cc;
/* The ring of the file comment: radius 30, soft iron, hard iron (12, -7). */
static const test_distortion_t k_ring = {30.0f, {{1.10f, 0.05f}, {0.05f, 0.90f}}, 12.0f, -7.0f};

typedef struct {
    test_distortion_t d; /* truth in force */
    uint32_t t_ms;
    uint32_t rng;
    double psi;
    unsigned ok_rows;  /* OK headings */
    unsigned bad_ok;   /* of them, further than OK_TOL_DEG from the truth */
    double worst_ok;   /* largest error of an OK heading */
    unsigned untrusted;
    unsigned coarse;   /* of the untrusted, COARSE (installed, above the OK tolerance) */
    double sigma;      /* noise per axis (0: 0.15) */
    int gravity;       /* 1: pushed with a level gravity (magcal_cont_push_g) */
    float ez;          /* added to raw z (a transient's vertical part) */
    double pitch_deg;  /* with gravity: the vehicle's pitch; the vertical field moves raw y by K_Z tan */
} row_t;

#define K_Z (-63.0) /* raw shift per unit of tilt: the vertical field, k / R = -2.1 (inclination 64 deg) */

/* One row at r->psi (raw x, y plus ex, ey; raw z 40): push, two steps, the heading judged. */
static void row(row_t *r, float ex, float ey)
{
    const magcal_vec2_t p = test_distorted_sample(&r->d, r->psi, r->sigma > 0.0 ? r->sigma : 0.15, &r->rng);
    magcal_vec3_t m;
    magcal_cont_heading_t hd;
    m.x = p.x + ex;
    m.y = p.y + ey;
    m.z = 40.0f + r->ez;
    if (r->gravity != 0) {
        const double p = r->pitch_deg * 3.14159265358979323846 / 180.0;
        const magcal_vec3_t g = {0.0f, (float)sin(p), (float)cos(p)};
        m.y += (float)(K_Z * tan(p));
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_push_g(&g_cc, &m, &g, r->t_ms));
    } else {
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_push(&g_cc, &m, r->t_ms));
    }
    (void)magcal_cont_step(&g_cc);
    (void)magcal_cont_step(&g_cc);
    r->t_ms += RATE_MS;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_heading(&g_cc, &m, 0.0f, &hd));
    if (hd.trust == MAGCAL_TRUST_OK) {
        const double e = fabs(test_angle_diff_deg(hd.heading_deg, r->psi));
        r->ok_rows++;
        r->bad_ok += e > OK_TOL_DEG ? 1u : 0u;
        r->worst_ok = e > r->worst_ok ? e : r->worst_ok;
    } else {
        r->untrusted++;
        r->coarse += hd.trust == MAGCAL_TRUST_COARSE ? 1u : 0u;
    }
}

static void turn(row_t *r, double deg, double dps)
{
    const unsigned n = (unsigned)(fabs(deg) / dps * 50.0);
    unsigned i;
    for (i = 0u; i < n; ++i) {
        r->psi = fmod(r->psi + deg / (double)n + 360.0, 360.0);
        row(r, 0.0f, 0.0f);
    }
}

static void counts_clear(row_t *r)
{
    r->ok_rows = 0u;
    r->bad_ok = 0u;
    r->worst_ok = 0.0;
    r->untrusted = 0u;
    r->coarse = 0u;
}

/* A fresh run on the ring of the file comment (noise seed `seed`) and g_cc initialised with cfg
 * (NULL: the defaults). */
static void ring_start(row_t *r, uint32_t seed, const magcal_cont_cfg_t *cfg)
{
    const magcal_cont_cfg_t def = MAGCAL_CONT_CFG_DEFAULT;
    memset(r, 0, sizeof *r);
    r->d = k_ring;
    r->rng = seed;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_init(&g_cc, cfg != NULL ? cfg : &def, NULL, g_slots, SLOTS, g_buf,
                                                      g_work, sizeof g_work));
}

/* One row at r->psi under an external field that turns the true horizontal field
 * (test_distorted_sample's) by env x rot_deg and scales it by 1 + env x rel (env: the transient's
 * envelope, 0..1), in raw axes. */
static void disturbed_row(row_t *r, double env, double rot_deg, double rel)
{
    const double dr = 3.14159265358979323846 / 180.0;
    const double hx = -30.0 * sin(r->psi * dr);
    const double hy = 30.0 * cos(r->psi * dr);
    const double gx = -30.0 * (1.0 + env * rel) * sin((r->psi + env * rot_deg) * dr) - hx;
    const double gy = 30.0 * (1.0 + env * rel) * cos((r->psi + env * rot_deg) * dr) - hy;
    row(r, (float)(r->d.t[0][0] * gx + r->d.t[0][1] * gy), (float)(r->d.t[1][0] * gx + r->d.t[1][1] * gy));
}

/* Calibrated after two full turns at 15 deg/s (the OK headings checked meanwhile). */
static void calibrated(row_t *r, uint32_t seed)
{
    ring_start(r, seed, NULL);
    turn(r, 720.0, 15.0);
    TEST_ASSERT_TRUE(g_cc.generation >= 1u);
    TEST_ASSERT_EQUAL_UINT(0u, r->bad_ok);
}

/* Parked at psi for `minutes` after a hard-iron step of (dx, dy): no OK heading off the truth. */
static void parked_step(double psi, float dx, float dy, double minutes, uint32_t seed)
{
    row_t r;
    unsigned i;
    calibrated(&r, seed);
    turn(&r, fmod(psi - r.psi + 360.0, 360.0), 15.0);
    counts_clear(&r);
    r.d.bx += dx;
    r.d.by += dy;
    for (i = 0u; i < (unsigned)(minutes * 60.0 * 50.0); ++i) {
        row(&r, 0.0f, 0.0f);
    }
    printf("parked at %.0f deg, step (%.1f, %.1f): %u OK rows (%u beyond %.0f deg, worst %.2f), %u untrusted, "
           "%u changes\n", psi, (double)dx, (double)dy, r.ok_rows, r.bad_ok, OK_TOL_DEG, r.worst_ok, r.untrusted,
           (unsigned)g_cc.changes);
    TEST_ASSERT_EQUAL_UINT(0u, r.bad_ok);
}

/* A step of about 0.33 R: the corrected field is 15 to 25 % off at the parked heading, around
 * twice the per-sample threshold, where the change evidence comes and goes. */
void test_trust_parked_step_twice_the_threshold(void)
{
    parked_step(100.0, 8.0f, -5.0f, 6.0, 38u);
    parked_step(250.0, -6.0f, 7.0f, 6.0, 39u);
}

/* A step of size s x R at 45 deg to the raw field at the parked heading: |h| moves by ~0.7 s R
 * and the heading by ~0.7 s rad (here 6 to 7 deg). At s 0.13 .. 0.15 the corrected field hovers
 * around twice the per-sample threshold (0.12 R), where the change evidence comes and goes
 * (30-min seed 38): the episode stays open (before: OK at 7.0 and 8.1 deg on every row after the
 * first 25 s). Below (s 0.09 .. 0.13: never change evidence) the model's health test still turns
 * the per-sample test off and the heading is OK 5 to 7 deg off: known gap, continuous.h. */
static void parked_step_45(double psi, double s, uint32_t seed)
{
    uint32_t rng = 1u;
    const magcal_vec2_t p = test_distorted_sample(&k_ring, psi, 0.0, &rng);
    const double ux = (double)(p.x - k_ring.bx);
    const double uy = (double)(p.y - k_ring.by);
    const double n = sqrt(ux * ux + uy * uy);
    const double a = s * n / sqrt(2.0);
    parked_step(psi, (float)(a * (ux - uy) / n), (float)(a * (uy + ux) / n), 6.0, seed);
}

void test_trust_parked_step_around_the_change_evidence(void)
{
    parked_step_45(100.0, 0.15, 47u);
    parked_step_45(300.0, 0.13, 55u);
}

/* A sensor rail (one axis at 800) in a sector the store did not cover: not OK. The first
 * adoption comes before a full turn, so the headings from RAIL_START_DEG back are not covered;
 * the rails read at about 270 deg (x), 180 deg (y) and at the last heading (z). */
#define RAIL_START_DEG 280.0
void test_trust_rail_glitch_in_an_uncovered_sector(void)
{
    magcal_cont_cfg_t cfg = MAGCAL_CONT_CFG_DEFAULT;
    row_t r;
    unsigned i;
    unsigned rail_ok = 0u;
    cfg.intake.range_limit = 800.0f;
    ring_start(&r, 42u, &cfg);
    r.psi = RAIL_START_DEG;
    for (i = 0u; i < 40u && g_cc.generation == 0u; ++i) {
        turn(&r, 10.0, 15.0); /* up to the first adoption: the headings it did not see stay uncovered */
    }
    TEST_ASSERT_TRUE(g_cc.generation >= 1u);
    printf("rail glitch: calibrated after %u deg from %.0f deg\n", 10u * i, RAIL_START_DEG);
    for (i = 0u; i < 16u; ++i) {
        const magcal_vec2_t p = test_distorted_sample(&r.d, r.psi, 0.15, &r.rng);
        const magcal_vec3_t rail[3] = {{800.0f, p.y, 40.0f}, {p.x, -800.0f, 40.0f}, {p.x, p.y, 800.0f}};
        magcal_cont_heading_t hd;
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_push(&g_cc, &rail[i % 3u], r.t_ms));
        (void)magcal_cont_step(&g_cc);
        r.t_ms += RATE_MS;
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_heading(&g_cc, &rail[i % 3u], 0.0f, &hd));
        rail_ok += hd.trust == MAGCAL_TRUST_OK ? 1u : 0u;
    }
    TEST_ASSERT_EQUAL_UINT(0u, rail_ok);
}

/* The OK tolerance (cfg.ok_max_err_deg): a ring read with 2.0 of noise per axis (R 30: about 4 deg
 * of heading noise per sample) calibrates, but its own estimate is above 3 deg: its headings are
 * COARSE, none OK; with the tolerance off they are OK and 471 of 2,318 more than 5 deg off. The
 * 0.15-noise ring of the tests above stays OK (its estimate is ~0.3 deg). */
static void noisy_ring(float ok_max, row_t *r)
{
    magcal_cont_cfg_t cfg = MAGCAL_CONT_CFG_DEFAULT;
    cfg.ok_max_err_deg = ok_max;
    ring_start(r, 77u, &cfg);
    r->sigma = 2.0;
    turn(r, 1080.0, 15.0);
    printf("noise 2.0, ok_max_err_deg %.0f: %u adoptions (estimate %.2f deg), %u OK rows (%u beyond %.0f deg, "
           "worst %.2f), %u COARSE\n", (double)ok_max, (unsigned)g_cc.generation, (double)g_cc.adopted_err, r->ok_rows,
           r->bad_ok, OK_TOL_DEG, r->worst_ok, r->coarse);
    TEST_ASSERT_TRUE(g_cc.generation >= 1u);
}

void test_trust_ok_tolerance_holds_a_loose_calibration(void)
{
    row_t r;
    magcal_cont_cfg_t cfg = MAGCAL_CONT_CFG_DEFAULT;
    TEST_ASSERT_EQUAL_FLOAT(3.0f, cfg.ok_max_err_deg);
    noisy_ring(0.0f, &r);
    TEST_ASSERT_TRUE(r.bad_ok >= 100u); /* what the tolerance is for */
    noisy_ring(3.0f, &r);
    TEST_ASSERT_TRUE(g_cc.adopted_err > 3.0f);
    TEST_ASSERT_EQUAL_UINT(0u, r.ok_rows);
    TEST_ASSERT_TRUE(r.coarse >= 2000u);
    cfg.ok_max_err_deg = -1.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_cont_init(&g_cc, &cfg, NULL, g_slots, SLOTS, g_buf, g_work, sizeof g_work));
    cfg.ok_max_err_deg = NAN;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_cont_init(&g_cc, &cfg, NULL, g_slots, SLOTS, g_buf, g_work, sizeof g_work));
}

/* 720 deg at 15 deg/s from power-up with a transient starting at row tr0 (none when tr0 is
 * UINT32_MAX): 4 s of raised cosine that turns the corrected field by up to rot_deg and scales it
 * by up to 1 + rel (the external field that does so: mostly across the field, which the
 * per-sample magnitude test barely sees). Returns the row of the first adoption; the counts of
 * the rows after it in r. */
static uint32_t transient_run(uint32_t tr0, double rot_deg, double rel, row_t *r)
{
    const uint32_t dur = 200u;
    uint32_t adopted = UINT32_MAX;
    uint32_t i;
    ring_start(r, 5u, NULL);
    r->gravity = 1; /* (level: without gravity the slopes' measure holds the first 2 s after the install too) */
    for (i = 0u; i < 2400u; ++i) {
        double env = 0.0;
        if (tr0 != UINT32_MAX && i >= tr0 && i < tr0 + dur) {
            env = 0.5 - 0.5 * cos(2.0 * 3.14159265358979323846 * ((double)(i - tr0) + 0.5) / (double)dur);
        }
        r->psi = fmod(r->psi + 0.3, 360.0);
        disturbed_row(r, env, rot_deg, rel);
        if (adopted == UINT32_MAX && g_cc.generation >= 1u) {
            adopted = i;
            counts_clear(r); /* (no OK before an adoption) */
        }
    }
    return adopted;
}

/* The transient (15 deg, 8 %) starts 15 rows (0.3 s) before the first adoption, as on 30-min
 * seed 34 (a relearn): the judge restarts its baselines at the install and can raise no new flag
 * for 1 s. Before, 26 of its rows in that second were OK more than 5 deg off (worst 10.7). Now
 * that second is not OK, on the clean ring too (the judge cannot vouch yet: 50 rows), and the
 * rest is OK. (At 1..5 % of magnitude the same rotation is not seen at all while the vehicle
 * turns: a field turned across itself, the known gap of continuous.h.) */
void test_trust_transient_across_an_adoption(void)
{
    row_t clean;
    row_t r;
    const uint32_t ra = transient_run(UINT32_MAX, 0.0, 0.0, &clean);
    uint32_t rb;
    TEST_ASSERT_TRUE(ra < 2000u);
    printf("clean ring: adopted at row %u; after it %u OK rows (worst %.2f deg), %u not OK (%u COARSE)\n",
           (unsigned)ra, clean.ok_rows, clean.worst_ok, clean.untrusted, clean.coarse);
    TEST_ASSERT_EQUAL_UINT(0u, clean.bad_ok);
    TEST_ASSERT_TRUE(clean.untrusted <= 60u); /* the judge's settling second: 50 rows at 50 Hz */
    rb = transient_run(ra - 15u, 15.0, 0.08, &r);
    printf("transient from row %u: adopted at row %u; after it %u OK rows (%u beyond %.0f deg, worst %.2f), "
           "%u not OK\n", (unsigned)(ra - 15u), (unsigned)rb, r.ok_rows, r.bad_ok, OK_TOL_DEG, r.worst_ok, r.untrusted);
    TEST_ASSERT_EQUAL_UINT(ra, rb); /* the solve's snapshot predates the transient */
    TEST_ASSERT_EQUAL_UINT(0u, r.bad_ok);
    TEST_ASSERT_TRUE(r.ok_rows + 250u >= clean.ok_rows); /* the transient's 4 s and its hold at most */
    {
        /* the same transient starting 0..80 rows before the adoption: printed, not asserted (a
         * known gap, continuous.h under the OK tolerance). At 0 and 5 rows before, the heading
         * regression learns the rise during the judge's settling second and explains it away
         * (22 and 18 OK rows beyond 5 deg, 11.8 at worst); from 20 rows on, the baselines restart
         * on the risen values (the first samples judged are the ones parked during the
         * field-model fit). Holding the regression's learning back for that second fixed 0..10
         * but flagged 260 of test_cont_drive.c's 4,000 clean rows (docs/calibrator.md "Stop 35") */
        static const uint32_t before[] = {0u, 5u, 10u, 20u, 25u, 30u, 40u, 50u, 60u, 80u};
        unsigned q;
        for (q = 0u; q < sizeof before / sizeof before[0]; ++q) {
            row_t rq;
            const uint32_t rr = transient_run(ra - before[q], 15.0, 0.08, &rq);
            printf("transient from %u rows before the adoption: adopted at row %u; %u OK rows after it (%u beyond "
                   "%.0f deg, worst %.2f)\n", (unsigned)before[q], (unsigned)rr, rq.ok_rows, rq.bad_ok, OK_TOL_DEG,
                   rq.worst_ok);
        }
    }
}

/* Calibrated by a slow ring (0.3 deg per row) and parked at once at the adoption: the transient
 * judge's regression has learnt next to nothing (as 60-min seed 2, parked most of the two minutes
 * after its first adoption). 10 s parked, then a transient of dur rows that turns the field by
 * rot_deg, scales it by 1 + rel and adds z to raw z at its peak (raised cosine), then 10 s. */
static void parked_transient(double rot_deg, double rel, double z, uint32_t dur, row_t *r)
{
    uint32_t i;
    ring_start(r, 7u, NULL);
    for (i = 0u; i < 5000u && g_cc.generation == 0u; ++i) {
        r->psi = fmod(r->psi + 0.3, 360.0);
        row(r, 0.0f, 0.0f);
    }
    TEST_ASSERT_TRUE(g_cc.generation >= 1u);
    for (i = 0u; i < 500u; ++i) {
        row(r, 0.0f, 0.0f);
    }
    counts_clear(r);
    for (i = 0u; i < dur + 500u; ++i) {
        double env = 0.0;
        if (i < dur) {
            env = 0.5 - 0.5 * cos(2.0 * 3.14159265358979323846 * ((double)i + 0.5) / (double)dur);
        }
        r->ez = (float)(env * z);
        disturbed_row(r, env, rot_deg, rel);
    }
}

/* A parked transient that turns the heading by 15 deg with 0.08 R on raw z (60-min seed 2's,
 * row 34976: the heading still for minutes, the regression of the transient judge next to
 * empty). Learnt at once, its rise taught the regression to explain it away: the flag came late
 * and the regression it left flagged the parked heading after it (before: 30 and 294 OK rows of
 * 650, 2 each beyond 5 deg). The onset of a move after a still heading is learnt only if no flag
 * rose by 1 s after it (src/loop/cont_flags.c): no OK row beyond 5 deg, and the heading OK again
 * after the transient. The same rotation with the field's magnitude unchanged and less on z, or
 * 30 deg, is printed: the known gap of a field turned across itself (continuous.h "Heading
 * trust"), still OK up to 26 deg off for 10..39 rows without a gyro. */
void test_trust_parked_transient_turns_the_heading(void)
{
    static const double rels[] = {0.0, 0.03};
    unsigned b;
    for (b = 0u; b < 2u; ++b) {
        row_t r;
        parked_transient(15.0, rels[b], 2.5, 150u, &r);
        printf("parked, 15 deg, %.0f %% and 0.08 R on z: %u OK rows (%u beyond %.0f deg, worst %.2f), %u not OK\n",
               100.0 * rels[b], r.ok_rows, r.bad_ok, OK_TOL_DEG, r.worst_ok, r.untrusted);
        TEST_ASSERT_EQUAL_UINT(0u, r.bad_ok);
        TEST_ASSERT_TRUE(r.ok_rows >= 500u); /* the 3-s transient and its hold at most */
    }
    {
        row_t r;
        parked_transient(30.0, 0.0, 1.0, 150u, &r);
        printf("known gap: parked, 30 deg, 0 %% and 0.03 R on z: %u OK rows (%u beyond %.0f deg, worst %.2f)\n",
               r.ok_rows, r.bad_ok, OK_TOL_DEG, r.worst_ok);
    }
}

/* A ring read with sigma of noise per axis (R 30), level, gravity fed; then 720 deg more on a
 * slope of pitch deg, where the vertical field moves raw y by K_Z tan(pitch) (the true tilt error,
 * k / R 2.1), while k is not yet known to the compensation (the tilt in the trust takes 2.5 R).
 * The OK rows of each part (and their errors against the truth) into lvl and slope. */
static void tilt_estimate_run(double sigma, double pitch, row_t *lvl, row_t *slope)
{
    row_t r;
    ring_start(&r, 91u, NULL);
    r.sigma = sigma;
    r.gravity = 1;
    turn(&r, 1080.0, 15.0);
    TEST_ASSERT_TRUE(g_cc.generation >= 1u);
    *lvl = r;
    counts_clear(&r);
    r.pitch_deg = pitch;
    turn(&r, 720.0, 15.0);
    *slope = r;
    printf("noise %.1f (estimate %.2f deg): level %u OK rows (%u beyond %.0f deg, worst %.2f); on %.1f deg of slope "
           "%u OK rows (%u beyond, worst %.2f), %u not OK\n", sigma, (double)g_cc.adopted_err, lvl->ok_rows, lvl->bad_ok,
           OK_TOL_DEG, lvl->worst_ok, pitch, slope->ok_rows, slope->bad_ok, slope->worst_ok, slope->untrusted);
}

/* The calibration's error and the tilt's, each within its own 3 deg (the OK tolerance, the tilt
 * in the trust), add up: 1.2 x the tolerance is what their sum may reach for an OK heading
 * (src/loop/cont_life.c cont_tilt_over). Rings read with 0.6..1.0 of noise (estimates 1.7 to
 * 3.0 deg), then on 0.8..1.6 deg of slope. Before, on the slopes: up to 45 OK rows more than 5 deg
 * off per run, 10.35 deg at worst (noise 1.0, 0.8 deg); with a sum of 1.5 x, still 28 (8.49).
 * Now none. Not solved: the level ring with noise 1.0 (estimate 2.74 deg), 14 of 2,339 OK rows
 * beyond 5 deg (6.13), the per-sample noise's tails (1.9 deg RMS of heading per sample): printed. */
void test_trust_tilt_and_estimate_add_up(void)
{
    static const double sg[] = {0.6, 0.8, 1.0};
    static const double pt[] = {0.8, 1.2, 1.6};
    unsigned a;
    unsigned b;
    for (a = 0u; a < 3u; ++a) {
        for (b = 0u; b < 3u; ++b) {
            row_t lvl;
            row_t slope;
            tilt_estimate_run(sg[a], pt[b], &lvl, &slope);
            TEST_ASSERT_EQUAL_UINT(0u, slope.bad_ok);
            if (a < 2u) {
                TEST_ASSERT_EQUAL_UINT(0u, lvl.bad_ok);
                TEST_ASSERT_TRUE(lvl.ok_rows >= 2000u); /* level: the sum rule costs nothing */
            }
        }
    }
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_trust_parked_step_twice_the_threshold);
    RUN_TEST(test_trust_parked_step_around_the_change_evidence);
    RUN_TEST(test_trust_rail_glitch_in_an_uncovered_sector);
    RUN_TEST(test_trust_ok_tolerance_holds_a_loose_calibration);
    RUN_TEST(test_trust_transient_across_an_adoption);
    RUN_TEST(test_trust_parked_transient_turns_the_heading);
    RUN_TEST(test_trust_tilt_and_estimate_add_up);
    return UNITY_END();
}
