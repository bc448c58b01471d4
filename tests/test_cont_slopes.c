/*
 * Tests of the continuous 2-D calibrator without gravity on slopes (continuous.h "Slopes without
 * gravity", src/loop/cont_slope.c). A calibrator fed by magcal_cont_push alone cannot level a
 * sample: on a slope its heading is off by up to tan(inclination) x the slope. Known truth: a
 * field of inclination 63.4 deg (H 30, Z 60), a sensor with soft iron, hard iron (12, -7, 8) and a
 * leak of x, y into z, 0.15 of noise per axis, 50 Hz, push + 2 steps per row as firmware does,
 * turning at 15 deg/s; pitch and roll given per row. Every OK heading is compared with the truth:
 *  - flat: OK once the field-model fit has measured the store's slopes (2 s after it), every
 *    OK heading within 5 deg;
 *  - +-5 deg hills right after the calibration: no OK heading more than 5 deg off (before: 3,642
 *    of 9,744 OK rows beyond 5 deg, 15.5 at worst), most rows TILTED;
 *  - the same hills after 4 flat minutes (the measure learnt the flat): no OK heading more than
 *    5 deg off (before: 2,102 of 5,124 beyond 5 deg, 15.4 at worst; the slope is seen at the first
 *    headings whose raw z shows it, and held, not after the mean's minutes).
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
#define D2R (3.14159265358979323846 / 180.0)

static magcal_intake_slot_t g_slots[SLOTS];
static magcal_vec2_t g_buf[SLOTS];
static MAGCAL_CALIBRATOR_WORKSPACE_DECLARE(g_work, SLOTS);
static magcal_cont_t g_cc;

typedef struct {
    uint32_t t_ms;
    uint32_t rng;
    double psi;      /* true heading, deg */
    unsigned rows;   /* rows since counts_clear */
    unsigned ok;     /* OK headings */
    unsigned bad_ok; /* of them, further than OK_TOL_DEG from the truth */
    double worst_ok;
    unsigned tilted; /* TILTED headings */
    unsigned off;    /* rows whose heading is further than OK_TOL_DEG from the truth, whatever its trust */
} drive_t;

/* One row at d->psi with pitch p and roll r (deg): the body field, the sensor's distortion, push,
 * two steps, the heading judged against the truth. */
static void row(drive_t *d, double p, double r)
{
    const double h = 30.0;
    const double zv = 60.0;
    const double bx = -h * sin(d->psi * D2R);
    const double by0 = h * cos(d->psi * D2R);
    const double bz0 = -zv;
    /* pitch about the body x axis, then roll about y */
    const double by = by0 * cos(p * D2R) + bz0 * sin(p * D2R);
    const double bz1 = -by0 * sin(p * D2R) + bz0 * cos(p * D2R);
    const double bx2 = bx * cos(r * D2R) - bz1 * sin(r * D2R);
    const double bz = bx * sin(r * D2R) + bz1 * cos(r * D2R);
    magcal_vec3_t m;
    magcal_cont_heading_t hd;
    m.x = (float)(1.10 * bx2 + 0.05 * by + 12.0 + 0.15 * test_rand_normal(&d->rng));
    m.y = (float)(0.05 * bx2 + 0.90 * by - 7.0 + 0.15 * test_rand_normal(&d->rng));
    m.z = (float)(bz + 0.05 * bx2 - 0.03 * by + 8.0 + 0.15 * test_rand_normal(&d->rng));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_push(&g_cc, &m, d->t_ms));
    (void)magcal_cont_step(&g_cc);
    (void)magcal_cont_step(&g_cc);
    d->t_ms += RATE_MS;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_heading(&g_cc, &m, 0.0f, &hd));
    {
        const double e = fabs(test_angle_diff_deg(hd.heading_deg, d->psi));
        d->rows++;
        d->off += e > OK_TOL_DEG ? 1u : 0u;
        if (hd.trust == MAGCAL_TRUST_OK) {
            d->ok++;
            d->bad_ok += e > OK_TOL_DEG ? 1u : 0u;
            d->worst_ok = e > d->worst_ok ? e : d->worst_ok;
        }
        d->tilted += hd.trust == MAGCAL_TRUST_TILTED ? 1u : 0u;
    }
}

static void counts_clear(drive_t *d)
{
    d->rows = 0u;
    d->ok = 0u;
    d->bad_ok = 0u;
    d->worst_ok = 0.0;
    d->tilted = 0u;
    d->off = 0u;
}

/* `seconds` of turning at 15 deg/s; hills of +-amp deg from level (pitch period 60 s, roll a
 * quarter of it with period 37 s) when amp > 0. */
static void drive(drive_t *d, double seconds, double amp)
{
    const unsigned n = (unsigned)(seconds * 50.0);
    unsigned i;
    for (i = 0u; i < n; ++i) {
        const double t = (double)i / 50.0;
        d->psi = fmod(d->psi + 0.3, 360.0);
        row(d, amp * sin(2.0 * 3.14159265358979323846 * t / 60.0), 0.25 * amp * sin(2.0 * 3.14159265358979323846 * t / 37.0));
    }
}

/* Calibrated on the flat from power-up (720 deg at 15 deg/s). */
static void calibrated(drive_t *d)
{
    magcal_cont_cfg_t cfg = MAGCAL_CONT_CFG_DEFAULT;
    memset(d, 0, sizeof *d);
    d->rng = 11u;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_init(&g_cc, &cfg, NULL, g_slots, SLOTS, g_buf, g_work, sizeof g_work));
    drive(d, 48.0, 0.0);
    TEST_ASSERT_TRUE(g_cc.generation >= 1u);
    TEST_ASSERT_EQUAL_UINT(0u, d->bad_ok);
    counts_clear(d);
}

static void report(const char *what, const drive_t *d)
{
    printf("%s: %u rows, %u OK (%u beyond %.0f deg, worst %.2f), %u TILTED; %u rows beyond %.0f deg whatever the trust\n",
           what, d->rows, d->ok, d->bad_ok, OK_TOL_DEG, d->worst_ok, d->tilted, d->off, OK_TOL_DEG);
}

/* `first` then `next` seconds on the flat (what, for the report): no OK heading beyond 5 deg in
 * either, and at least 95 % of the `next` rows OK. */
static void flat_then_ok(drive_t *d, const char *what, double first, double next)
{
    char label[64];
    drive(d, first, 0.0);
    (void)snprintf(label, sizeof label, "%s, first %.0f s", what, first);
    report(label, d);
    TEST_ASSERT_EQUAL_UINT(0u, d->bad_ok);
    counts_clear(d);
    drive(d, next, 0.0);
    (void)snprintf(label, sizeof label, "%s, next %.0f s", what, next);
    report(label, d);
    TEST_ASSERT_EQUAL_UINT(0u, d->bad_ok);
    TEST_ASSERT_TRUE(d->ok >= d->rows * 95u / 100u);
}

/* Flat: OK once the field-model fit after the install has measured the store (and 2 s more). */
void test_slopes_flat_is_ok_after_the_warm_up(void)
{
    drive_t d;
    calibrated(&d);
    flat_then_ok(&d, "flat", 120.0, 180.0);
}

/* Hills of +-5 deg right after a flat calibration: the heading is up to ~10 deg off on them, and
 * none of those headings may be OK. */
void test_slopes_hills_after_calibration_are_not_ok(void)
{
    drive_t d;
    calibrated(&d);
    drive(&d, 300.0, 5.0);
    report("hills +-5 deg, 5 min", &d);
    TEST_ASSERT_TRUE(d.off >= 3000u); /* what the test is about */
    TEST_ASSERT_EQUAL_UINT(0u, d.bad_ok);
    TEST_ASSERT_TRUE(d.tilted >= d.rows / 2u);
}

/* The same hills after 4 flat minutes (the measure learnt the flat): seen as they come. */
void test_slopes_hills_after_a_flat_stretch_are_not_ok(void)
{
    drive_t d;
    calibrated(&d);
    drive(&d, 240.0, 0.0);
    TEST_ASSERT_EQUAL_UINT(0u, d.bad_ok);
    TEST_ASSERT_TRUE(d.ok > 0u);
    counts_clear(&d);
    drive(&d, 180.0, 5.0);
    report("hills +-5 deg after 4 flat min, 3 min", &d);
    TEST_ASSERT_TRUE(d.off >= 2000u);
    TEST_ASSERT_EQUAL_UINT(0u, d.bad_ok);
}

/* A calibration restored at init (from flash) has no field model, so without gravity its slopes
 * are unmeasured and its headings TILTED: the first full solve that confirms it (NOT_BETTER,
 * here 2.4 min after the restore) fits the model on its store, and the flat headings are OK
 * again (before that fit, never: every row of the 5 minutes TILTED). */
void test_slopes_restored_calibration_is_measured(void)
{
    drive_t d;
    magcal_cal2d_t saved;
    magcal_cont_cfg_t cfg = MAGCAL_CONT_CFG_DEFAULT;
    calibrated(&d);
    drive(&d, 60.0, 0.0);
    saved = g_cc.cal;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_init(&g_cc, &cfg, &saved, g_slots, SLOTS, g_buf, g_work, sizeof g_work));
    counts_clear(&d);
    flat_then_ok(&d, "restored, flat", 180.0, 120.0);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_slopes_flat_is_ok_after_the_warm_up);
    RUN_TEST(test_slopes_hills_after_calibration_are_not_ok);
    RUN_TEST(test_slopes_hills_after_a_flat_stretch_are_not_ok);
    RUN_TEST(test_slopes_restored_calibration_is_measured);
    return UNITY_END();
}
