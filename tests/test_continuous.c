/*
 * Tests of the continuous 2-D calibrator (include/magcal/continuous.h, src/loop/): synthetic level
 * drives with known truth (test_util.h distortion, fixed seeds), fed in stream order through push
 * + step exactly as firmware does. Every adoption is checked against the truth: never worse than
 * the calibration it replaced (heading RMS over 72 true headings, noiseless).
 */
#if defined(__unix__) && !defined(__arm__)
#define CONT_TEST_THREADS 1 /* host: the ISR is a POSIX thread */
#define _POSIX_C_SOURCE 200809L
#include <pthread.h>
#endif
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "magcal/continuous.h"
#include "test_util.h"
#include "unity.h"

#if defined(__arm__)
/* Target only: SysTick around each call (under `qemu-system-arm -icount shift=0` one tick = 40
 * instructions, tools/bench/m4f_image/main_cycles.c). Printed, never asserted: a measurement. */
#define SYST_CSR (*(volatile uint32_t *)0xE000E010u)
#define SYST_RVR (*(volatile uint32_t *)0xE000E014u)
#define SYST_CVR (*(volatile uint32_t *)0xE000E018u)
static uint32_t g_tmax[3];
#define TICK_START() uint32_t t0_ = SYST_CVR
#define TICK_END(k)                                                                                \
    do {                                                                                           \
        uint32_t d_ = (t0_ - SYST_CVR) & 0xFFFFFFu;                                                \
        if (d_ > g_tmax[k]) {                                                                      \
            g_tmax[k] = d_;                                                                        \
        }                                                                                          \
    } while (0)
#else
#define TICK_START() ((void)0)
#define TICK_END(k) ((void)0)
#endif

void setUp(void) {}
void tearDown(void) {}

#define SLOTS MAGCAL_CONT_SLOTS(36u, 8u)
#define RATE_MS 20u /* 50 Hz */
#define STEPS_PER_ROW 4u /* step() calls per sample: a 200 Hz control loop */

static magcal_intake_slot_t g_slots[SLOTS];
static magcal_vec2_t g_buf[SLOTS];
static MAGCAL_CALIBRATOR_WORKSPACE_DECLARE(g_work, SLOTS);
static magcal_cont_t g_cc;

static const test_distortion_t k_d = {30.0f, {{1.10f, 0.05f}, {0.05f, 0.90f}}, 12.0f, -7.0f};
static const test_distortion_t k_d_step = {30.0f, {{1.10f, 0.05f}, {0.05f, 0.90f}}, 24.0f, -14.0f};

/* truth heading RMS of calibration c on distortion d (72 noiseless headings), degrees */
static double truth_rms(const magcal_cal2d_t *c, const test_distortion_t *d)
{
    double ss = 0.0;
    int k;
    uint32_t rng = 1u;
    for (k = 0; k < 72; ++k) {
        double psi = 5.0 * k;
        magcal_vec2_t p = test_distorted_sample(d, psi, 0.0, &rng);
        float mag = 0.0f, tru = 0.0f;
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_heading_compute(c, p, 0.0f, &mag, &tru));
        ss += test_angle_diff_deg(mag, psi) * test_angle_diff_deg(mag, psi);
    }
    return sqrt(ss / 72.0);
}

typedef struct {
    uint32_t t_ms;
    double psi;
    uint32_t rng;
    unsigned adopted;
    unsigned changes;
    unsigned in_progress_run; /* IN_PROGRESS outcomes of the current solve */
    unsigned max_run;
    magcal_cal2d_t before;     /* installed before the last adoption */
    const test_distortion_t *d; /* truth in force */
    double turn_deg;           /* cumulative turning */
    double turn_at_first;
    double turn_at_change;
    int watch_cov;             /* 1: record the live coverage of every row on which no solve runs */
    float idle_cov;            /* the last such coverage before the first adoption: the store the
                                  adopting solve snapshotted (its snapshot starts after that row) */
    float first_cov;           /* the coverage the first adopted solve reported */
    int gyro;                  /* 0: push; +-1: push_imu with the gyro's rate about z (-1: a frame
                                  mirrored against the magnetometer's) */
    double psi_prev;           /* heading of the row before (the gyro's rotation) */
    double w_spike_dps;        /* added to the next row's gyro rate, then cleared (a gyro glitch) */
} drive_t;

#define GYRO_BIAS_DPS 0.4 /* the test gyro's bias about z, deg/s */

static void drive_init(drive_t *dr, const test_distortion_t *d, uint32_t seed)
{
    memset(dr, 0, sizeof *dr);
    dr->rng = seed;
    dr->d = d;
    dr->turn_at_first = -1.0;
}

/* one row: sample at dr->psi (+ extra field ex, ey), push, step; never-worse check on adoption */
static magcal_cont_outcome_t drive_row(drive_t *dr, float ex, float ey)
{
    magcal_vec2_t p = test_distorted_sample(dr->d, dr->psi, 0.15, &dr->rng);
    magcal_vec3_t m;
    magcal_cont_outcome_t oc;
    m.x = p.x + ex;
    m.y = p.y + ey;
    m.z = 40.0f;
    dr->before = g_cc.cal;
    {
        magcal_status_t st;
        /* a right-handed rotation about up turns the heading anticlockwise: w_z = -dpsi/dt */
        const double rate = -test_angle_diff_deg(dr->psi, dr->psi_prev) / (RATE_MS * 1e-3) + GYRO_BIAS_DPS +
                            dr->w_spike_dps;
        magcal_vec3_t w = {0.0f, 0.0f, (float)((double)dr->gyro * rate * 3.14159265358979 / 180.0)};
        dr->psi_prev = dr->psi;
        dr->w_spike_dps = 0.0;
        TICK_START();
        st = (dr->gyro != 0) ? magcal_cont_push_imu(&g_cc, &m, NULL, &w, dr->t_ms) : magcal_cont_push(&g_cc, &m, dr->t_ms);
        TICK_END(0);
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, st);
    }
    {
        /* the firmware's control loop runs at STEPS_PER_ROW x the sample rate (a sliced solve is
         * ~1000 steps at the default budget): the row's outcome is the one that is not IDLE /
         * IN_PROGRESS, if any */
        unsigned k;
        oc = MAGCAL_CONT_IDLE;
        for (k = 0u; k < STEPS_PER_ROW; ++k) {
            magcal_cont_outcome_t o;
            TICK_START();
            o = magcal_cont_step(&g_cc);
            TICK_END(1);
            if (oc == MAGCAL_CONT_IDLE || oc == MAGCAL_CONT_IN_PROGRESS) {
                oc = o;
            }
        }
    }
    dr->t_ms += RATE_MS;
    if (dr->watch_cov != 0 && dr->adopted == 0u && g_cc.stage == 0u) { /* stage 0: no solve under way */
        magcal_cont_progress_t pw;
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_progress(&g_cc, &pw));
        dr->idle_cov = pw.coverage_deg;
    }
    if (oc == MAGCAL_CONT_IN_PROGRESS) {
        dr->in_progress_run++;
        if (dr->in_progress_run > dr->max_run) {
            dr->max_run = dr->in_progress_run;
        }
    } else {
        dr->in_progress_run = 0u;
    }
    if (oc == MAGCAL_CONT_ADOPTED) {
        dr->adopted++;
        if (dr->turn_at_first < 0.0) {
            dr->turn_at_first = dr->turn_deg;
            dr->first_cov = g_cc.last.coverage_deg;
        }
        if (dr->before.radius > 0.0f && g_cc.state != (uint8_t)MAGCAL_CONT_RELEARNING && dr->changes == 0u) {
            /* never worse on the truth (0.05 deg: float noise of two good calibrations) */
            TEST_ASSERT_TRUE(truth_rms(&g_cc.cal, dr->d) <= truth_rms(&dr->before, dr->d) + 0.05);
        }
    }
    if (oc == MAGCAL_CONT_CHANGE) {
        dr->turn_at_change = dr->turn_deg;
        dr->changes++;
    }
    return oc;
}

static void drive_turn(drive_t *dr, double deg, double dps)
{
    size_t rows = (size_t)(fabs(deg) / dps * 50.0);
    size_t i;
    double inc = deg / (double)rows;
    for (i = 0u; i < rows; ++i) {
        dr->psi = fmod(dr->psi + inc + 360.0, 360.0);
        dr->turn_deg += fabs(inc);
        (void)drive_row(dr, 0.0f, 0.0f);
    }
}

/* straight ahead (no turning) for `seconds` at 50 Hz */
static void drive_straight(drive_t *dr, unsigned seconds)
{
    unsigned i;
    for (i = 0u; i < seconds * 50u; ++i) {
        (void)drive_row(dr, 0.0f, 0.0f);
    }
}

static void cont_init_default(const magcal_cal2d_t *installed)
{
    magcal_cont_cfg_t cfg = MAGCAL_CONT_CFG_DEFAULT;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_init(&g_cc, &cfg, installed, g_slots, SLOTS, g_buf, g_work,
                                                      sizeof g_work));
}

void test_cont_init_bad_args_refused(void)
{
    magcal_cont_cfg_t cfg = MAGCAL_CONT_CFG_DEFAULT;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_cont_init(NULL, &cfg, NULL, g_slots, SLOTS, g_buf, g_work, sizeof g_work));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_WORKSPACE, magcal_cont_init(&g_cc, &cfg, NULL, g_slots, SLOTS - 1u, g_buf, g_work, sizeof g_work));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_WORKSPACE, magcal_cont_init(&g_cc, &cfg, NULL, g_slots, SLOTS, g_buf, g_work, 64u));
    cfg.intake.dims = 3u;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_cont_init(&g_cc, &cfg, NULL, g_slots, SLOTS, g_buf, g_work, sizeof g_work));
    cfg.intake.dims = 2u;
    cfg.drain_per_step = 0u;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_cont_init(&g_cc, &cfg, NULL, g_slots, SLOTS, g_buf, g_work, sizeof g_work));
    cfg.drain_per_step = 2u;
    cfg.mismatch_k = NAN;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_cont_init(&g_cc, &cfg, NULL, g_slots, SLOTS, g_buf, g_work, sizeof g_work));
    TEST_ASSERT_EQUAL_INT(MAGCAL_CONT_IDLE, magcal_cont_step(NULL));
}

/* First adoption within 540 deg of turning from power-up (row 0 a spike), accurate on the truth,
 * the live coverage within one sector of the solve's; the solve is sliced (>= 5 calls). */
void test_cont_stream_first_adoption_accurate(void)
{
    drive_t dr;
    magcal_cont_progress_t pr;
    magcal_vec3_t spike = {900.0f, -700.0f, 40.0f};
    cont_init_default(NULL);
    drive_init(&dr, &k_d, 11u);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_push(&g_cc, &spike, 0u));
    (void)magcal_cont_step(&g_cc);
    drive_turn(&dr, 60.0, 20.0);
    dr.psi = 60.0;
    {
        size_t i;
        for (i = 0u; i < 50u * 60u; ++i) { /* parked a minute: fills its own bins only */
            (void)drive_row(&dr, 0.0f, 0.0f);
        }
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_progress(&g_cc, &pr));
    TEST_ASSERT_TRUE(pr.coverage_deg <= 90.0f);
    TEST_ASSERT_EQUAL_UINT(0u, dr.adopted);
    dr.watch_cov = 1;
    drive_turn(&dr, 480.0, 15.0);
    TEST_ASSERT_TRUE(dr.adopted >= 1u);
    TEST_ASSERT_TRUE(dr.turn_at_first <= 540.0);
    TEST_ASSERT_TRUE(truth_rms(&g_cc.cal, &k_d) < 1.0);
    TEST_ASSERT_TRUE(dr.max_run >= 4u); /* snapshot + prepare + fit + gates: one call each */
    /* live progress agrees with what the solve found on the same store (within one 10-deg bin):
     * the live coverage just before the adopting solve's snapshot; the vehicle keeps turning
     * while a sliced solve runs, so today's live coverage may be larger */
    TEST_ASSERT_FLOAT_WITHIN(10.0f, dr.first_cov, dr.idle_cov);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_progress(&g_cc, &pr));
    TEST_ASSERT_TRUE(pr.coverage_deg >= dr.first_cov - 10.0f);
    printf("first adoption after %.0f deg of turning, truth RMS %.3f deg, est %.3f deg\n", dr.turn_at_first,
           truth_rms(&g_cc.cal, &k_d), (double)g_cc.adopted_err);
}

/* A failed solve does not stop collection; after an adoption it keeps collecting and solving. */
void test_cont_failed_solve_not_sticky(void)
{
    drive_t dr;
    magcal_cont_progress_t pr;
    magcal_cont_outcome_t oc;
    cont_init_default(NULL);
    drive_init(&dr, &k_d, 5u);
    drive_turn(&dr, 100.0, 15.0);
    oc = magcal_cont_solve_blocking(&g_cc, 1);
    TEST_ASSERT_EQUAL_INT(MAGCAL_CONT_FAILED, oc);
    TEST_ASSERT_NOT_EQUAL(MAGCAL_OK, magcal_cont_status(&g_cc));
    drive_turn(&dr, 400.0, 15.0);
    TEST_ASSERT_TRUE(dr.adopted >= 1u);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_progress(&g_cc, &pr));
    {
        uint32_t solves = pr.solves;
        magcal_cont_cfg_t dflt = MAGCAL_CONT_CFG_DEFAULT;
        drive_turn(&dr, 3.0 * 360.0, 15.0);
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_progress(&g_cc, &pr));
        /* either it solved again, or it is waiting for new information (not stuck) */
        TEST_ASSERT_TRUE(pr.solves > solves || pr.new_since_solve < dflt.min_new);
        TEST_ASSERT_NOT_EQUAL(MAGCAL_CONT_RELEARNING, pr.state);
    }
}

/* Ageing: a flash calibration slightly worse than what the data support (about 2.6 x the new
 * one's error, inside the batch margin of 3) is kept at first, replaced once it has aged; the
 * replacement is better on the truth. */
void test_cont_ageing_replaces_mildly_worse(void)
{
    drive_t dr;
    magcal_cal2d_t flash;
    magcal_cont_cfg_t cfg = MAGCAL_CONT_CFG_DEFAULT;
    double r_flash;
    /* the true calibration of k_d, then a small offset error */
    cont_init_default(NULL);
    drive_init(&dr, &k_d, 7u);
    drive_turn(&dr, 720.0, 15.0);
    TEST_ASSERT_TRUE(dr.adopted >= 1u);
    flash = g_cc.cal;
    flash.offset.x += 0.05f;
    r_flash = truth_rms(&flash, &k_d);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_init(&g_cc, &cfg, &flash, g_slots, SLOTS, g_buf, g_work, sizeof g_work));
    drive_init(&dr, &k_d, 8u);
    drive_turn(&dr, 360.0 * 3.0, 15.0); /* 72 s: margin still ~2.8 */
    TEST_ASSERT_TRUE(g_cc.solves >= 1u);
    printf("ageing, first 72 s: solves %u generation %u last %s cur_err %.3f new_param %.3f\n", (unsigned)g_cc.solves,
           (unsigned)g_cc.generation, magcal_status_str(g_cc.last.status), (double)g_cc.last.current_err_deg,
           (double)g_cc.last.est_param_err_deg);
    TEST_ASSERT_EQUAL_UINT32(0u, g_cc.generation); /* within the batch margin: kept */
    drive_turn(&dr, 360.0 * 60.0, 15.0); /* 24 min: margin about 1.6 */
    printf("ageing: solves %u last %s cur_err %.3f new_param %.3f\n", (unsigned)g_cc.solves,
           magcal_status_str(g_cc.last.status), (double)g_cc.last.current_err_deg, (double)g_cc.last.est_param_err_deg);
    printf("ageing: flash truth RMS %.3f, now %.3f, generation %u, aged adoptions %u\n", r_flash,
           truth_rms(&g_cc.cal, &k_d), (unsigned)g_cc.generation, (unsigned)g_cc.aged_adopts);
    TEST_ASSERT_TRUE(g_cc.aged_adopts >= 1u);
    TEST_ASSERT_TRUE(truth_rms(&g_cc.cal, &k_d) < r_flash);
}

/* A hard-iron step (40 % of the field) is declared a change within 720 deg of turning, the rows
 * between are not trusted, the old samples are dropped and the relearned calibration fits the new
 * truth. */
void test_cont_hard_iron_step_relearned(void)
{
    drive_t dr;
    magcal_cont_heading_t hd;
    double t0;
    unsigned untrusted = 0u, rows = 0u;
    cont_init_default(NULL);
    drive_init(&dr, &k_d, 21u);
    drive_turn(&dr, 720.0, 15.0);
    TEST_ASSERT_TRUE(dr.adopted >= 1u);
    dr.d = &k_d_step;
    t0 = dr.turn_deg;
    {
        unsigned gen0 = g_cc.generation;
        size_t i;
        for (i = 0u; i < 50u * 200u && (dr.changes == 0u || g_cc.generation == gen0 ||
                                        g_cc.state == (uint8_t)MAGCAL_CONT_RELEARNING); ++i) {
            magcal_vec2_t p;
            magcal_vec3_t m;
            dr.psi = fmod(dr.psi + 15.0 / 50.0, 360.0);
            dr.turn_deg += 15.0 / 50.0;
            (void)drive_row(&dr, 0.0f, 0.0f);
            p = test_distorted_sample(dr.d, dr.psi, 0.0, &dr.rng);
            m.x = p.x;
            m.y = p.y;
            m.z = 40.0f;
            TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_heading(&g_cc, &m, 0.0f, &hd));
            if (g_cc.generation == gen0) {
                rows++;
                untrusted += hd.trust != MAGCAL_TRUST_OK ? 1u : 0u;
            }
        }
    }
    printf("step: change after %.0f deg, relearned after %.0f deg, untrusted %u of %u rows before relearn\n",
           dr.turn_at_change - t0, dr.turn_deg - t0, untrusted, rows);
    TEST_ASSERT_EQUAL_UINT(1u, dr.changes);
    TEST_ASSERT_TRUE(dr.turn_deg - t0 <= 720.0);
    TEST_ASSERT_TRUE(truth_rms(&g_cc.cal, &k_d_step) < 1.0);
    TEST_ASSERT_TRUE((double)untrusted >= 0.9 * (double)rows);
}

/* A transient (+30 % of the field for 3 s, parked: one sector) is flagged but discards nothing. */
void test_cont_transient_flagged_not_discarded(void)
{
    drive_t dr;
    magcal_cont_progress_t p0, p1;
    magcal_cont_heading_t hd;
    size_t i;
    unsigned flagged = 0u, clean_flag = 0u;
    cont_init_default(NULL);
    drive_init(&dr, &k_d, 31u);
    drive_turn(&dr, 720.0, 15.0);
    TEST_ASSERT_TRUE(dr.adopted >= 1u);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_progress(&g_cc, &p0));
    for (i = 0u; i < 50u * 20u; ++i) {
        int dist = i >= 250u && i < 400u;
        float ey = dist ? 9.0f : 0.0f; /* +30 % of h0 = 30 along the field (heading ~0) */
        magcal_vec2_t p;
        magcal_vec3_t m;
        (void)drive_row(&dr, 0.0f, ey);
        p = test_distorted_sample(dr.d, dr.psi, 0.0, &dr.rng);
        m.x = p.x;
        m.y = p.y + ey;
        m.z = 40.0f;
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_heading(&g_cc, &m, 0.0f, &hd));
        if (dist) {
            flagged += hd.trust == MAGCAL_TRUST_DISTURBED ? 1u : 0u;
        } else {
            clean_flag += hd.trust != MAGCAL_TRUST_OK ? 1u : 0u;
        }
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_progress(&g_cc, &p1));
    TEST_ASSERT_EQUAL_UINT(0u, dr.changes);
    TEST_ASSERT_EQUAL_UINT32(p0.changes, p1.changes);
    TEST_ASSERT_TRUE(p1.stored >= p0.stored); /* nothing discarded */
    TEST_ASSERT_TRUE(flagged >= 135u);        /* >= 90 % of 150 */
    TEST_ASSERT_TRUE(clean_flag <= 17u);      /* <= 2 % of 850 */
}

/* A transient that turns the heading (a field across the vehicle's, up to h0: raised cosine over
 * 2 s while driving straight after the calibration; the heading swings by up to 45 deg, the
 * radius by up to 41 %). Once the flag is up, no heading is OK while the disturbance is above a
 * third of its peak. (On a restore of a biased record, 30-min seed 2, the flag dropped for 17 rows
 * mid-transient, OK 45 deg off: the disturbance's own heading move widened the thresholds and
 * the regression of the biased calibration explained its deviation; here, with a good
 * calibration, it stayed up before that fix too.) Its onset is not seen at once: a field across the
 * vehicle's moves the heading at first order and the radius at second, which a magnetometer
 * alone reads as a turn (measured: 11 rows OK more than 3 deg off before the flag, the worst
 * 14.9 deg; asserted <= 15 rows). After it, at most 2 % of the 15 s of clean rows are flagged. */
void test_cont_transient_turning_the_heading_stays_flagged(void)
{
    drive_t dr;
    magcal_cont_heading_t hd;
    size_t i;
    unsigned onset_ok = 0u, mid_ok = 0u, clean_flag = 0u, flagged = 0u;
    int up = 0;
    double worst_onset = 0.0;
    cont_init_default(NULL);
    drive_init(&dr, &k_d, 37u);
    drive_turn(&dr, 720.0, 15.0);
    TEST_ASSERT_TRUE(dr.adopted >= 1u);
    for (i = 0u; i < 50u * 20u; ++i) {
        const int dist = i >= 150u && i < 250u;
        const double env = dist ? 0.5 * (1.0 - cos(2.0 * 3.14159265358979 * (double)(i - 150u) / 100.0)) : 0.0;
        const float ex = (float)(30.0 * env); /* across the field (heading ~0: the field along y) */
        magcal_vec2_t p;
        magcal_vec3_t m;
        (void)drive_row(&dr, ex, 0.0f);
        p = test_distorted_sample(dr.d, dr.psi, 0.0, &dr.rng);
        m.x = p.x + ex;
        m.y = p.y;
        m.z = 40.0f;
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_heading(&g_cc, &m, 0.0f, &hd));
        if (dist) {
            flagged += hd.trust == MAGCAL_TRUST_DISTURBED ? 1u : 0u;
            up = up != 0 || hd.trust == MAGCAL_TRUST_DISTURBED;
            if (hd.trust == MAGCAL_TRUST_OK && up == 0) {
                const double e = fabs(test_angle_diff_deg(hd.heading_deg, dr.psi));
                onset_ok += e > 3.0 ? 1u : 0u;
                worst_onset = fmax(worst_onset, e);
            } else if (hd.trust == MAGCAL_TRUST_OK && env > 1.0 / 3.0) {
                mid_ok++;
            } else {
                /* flagged, or OK in the tail below a third of the peak */
            }
        } else if (i >= 250u) {
            clean_flag += hd.trust != MAGCAL_TRUST_OK ? 1u : 0u;
        } else {
            /* before it */
        }
    }
    printf("transient turning the heading: %u of 100 rows flagged; %u OK > 3 deg off at its onset (worst %.2f deg), %u OK "
           "after the flag rose above a third of its peak; %u of 750 clean rows after it not OK\n",
           flagged, onset_ok, worst_onset, mid_ok, clean_flag);
    TEST_ASSERT_EQUAL_UINT(0u, mid_ok);
    TEST_ASSERT_TRUE(onset_ok <= 15u);
    TEST_ASSERT_TRUE(clean_flag <= 15u); /* <= 2 % of 750 */
}

/* The gyro heading check (continuous.h "Gyro heading check"): the transient of the test above
 * (across the field, 2 s while driving straight), with the gyro's rate about z (a 0.4 deg/s bias),
 * in the contract's frame and in a mirrored one (its sign found on the turns). Every OK heading
 * under the transient within 3 deg of the truth; the clean rows after it OK; without the gyro
 * (the same stream) the onset's OK headings are off by more. */
/* One row of a straight under a 2-s transient of 0.3 |B| across the field (perpendicular to its
 * horizontal direction) from row `start` of the sequence (k the row's index), raised-cosine
 * envelope: drive the row, read its heading into *hd. Returns 1 under the transient. */
static int across_row(drive_t *dr, size_t k, size_t start, magcal_cont_heading_t *hd)
{
    const int dist = k >= start && k < start + 100u;
    const double env = dist ? 0.5 * (1.0 - cos(2.0 * 3.14159265358979 * (double)(k - start) / 100.0)) : 0.0;
    const double a = dr->psi * 3.14159265358979 / 180.0;
    const float ex = (float)(9.0 * env * cos(a));
    const float ey = (float)(9.0 * env * sin(a));
    magcal_vec2_t p;
    magcal_vec3_t m;
    (void)drive_row(dr, ex, ey);
    p = test_distorted_sample(dr->d, dr->psi, 0.0, &dr->rng);
    m.x = p.x + ex;
    m.y = p.y + ey;
    m.z = 40.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_heading(&g_cc, &m, 0.0f, hd));
    return dist;
}

static void gyro_transient(int gyro, unsigned *onset_ok, double *worst, unsigned *clean_not_ok)
{
    drive_t dr;
    magcal_cont_heading_t hd;
    size_t i;
    cont_init_default(NULL);
    drive_init(&dr, &k_d, 37u);
    dr.gyro = gyro;
    drive_turn(&dr, 720.0, 15.0);
    TEST_ASSERT_TRUE(dr.adopted >= 1u);
    drive_turn(&dr, 360.0, 15.0); /* the sign checked on 180 deg of turning */
    drive_straight(&dr, 70u);    /* the warm-up: 60 s of judged samples */
    *onset_ok = 0u;
    *worst = 0.0;
    *clean_not_ok = 0u;
    for (i = 0u; i < 50u * 20u; ++i) {
        const int dist = across_row(&dr, i, 150u, &hd);
        if (dist && hd.trust == MAGCAL_TRUST_OK) {
            const double e = fabs(test_angle_diff_deg(hd.heading_deg, dr.psi));
            *onset_ok += e > 3.0 ? 1u : 0u;
            *worst = fmax(*worst, e);
        } else if (i >= 250u) {
            *clean_not_ok += hd.trust != MAGCAL_TRUST_OK ? 1u : 0u;
        } else {
            /* flagged under it, or before it */
        }
    }
    printf("gyro %d: sign %d warm %u ms bias %.3f deg/s flags %u\n", gyro, g_cc.rj_sgn, (unsigned)g_cc.rj_ms, (double)g_cc.rj_b, (unsigned)g_cc.rj_flags);
    if (gyro != 0) {
        TEST_ASSERT_EQUAL_INT(gyro > 0 ? -1 : 1, g_cc.rj_sgn); /* the mirrored frame found */
    }
}

void test_cont_gyro_flags_a_disturbance_across_the_field(void)
{
    unsigned onset[3], clean[3];
    double worst[3];
    gyro_transient(0, &onset[0], &worst[0], &clean[0]);
    gyro_transient(1, &onset[1], &worst[1], &clean[1]);
    gyro_transient(-1, &onset[2], &worst[2], &clean[2]);
    printf("gyro heading check, 2-s transient of 0.3 |B| across the field: OK rows > 3 deg off under it "
           "(worst OK) / clean rows after it not OK (of 750): no gyro %u (%.2f deg) / %u; gyro %u (%.2f) / %u; "
           "mirrored gyro %u (%.2f) / %u\n",
           onset[0], worst[0], clean[0], onset[1], worst[1], clean[1], onset[2], worst[2], clean[2]);
    TEST_ASSERT_TRUE(onset[0] >= 3u && worst[0] > 5.0); /* the magnitude judge alone lets the onset through */
    TEST_ASSERT_EQUAL_UINT(0u, onset[1]);
    TEST_ASSERT_EQUAL_UINT(0u, onset[2]);
    TEST_ASSERT_TRUE(clean[1] <= 15u && clean[2] <= 15u); /* <= 2 % */
}

/* A glitch of the gyro (one reading of 3000 deg/s, 60 deg in 20 ms) on a clean straight after the
 * warm-up: the track restarts instead of holding a flag for the 8 s of a coast (before: 400 clean
 * rows DISTURBED); a transient 20 s later is still caught (0 OK rows > 3 deg off). */
void test_cont_gyro_glitch_is_no_disturbance(void)
{
    drive_t dr;
    magcal_cont_heading_t hd;
    size_t i;
    unsigned not_ok = 0u, onset_ok = 0u;
    cont_init_default(NULL);
    drive_init(&dr, &k_d, 41u);
    dr.gyro = 1;
    drive_turn(&dr, 1080.0, 15.0);
    drive_straight(&dr, 70u);
    TEST_ASSERT_TRUE(dr.adopted >= 1u);
    dr.w_spike_dps = 3000.0;
    for (i = 0u; i < 50u * 30u; ++i) {
        const int dist = across_row(&dr, i, 1000u, &hd);
        if (i < 1000u) {
            not_ok += hd.trust != MAGCAL_TRUST_OK ? 1u : 0u;
        } else if (dist && hd.trust == MAGCAL_TRUST_OK) {
            onset_ok += fabs(test_angle_diff_deg(hd.heading_deg, dr.psi)) > 3.0 ? 1u : 0u;
        } else {
            /* flagged under the transient, or after it */
        }
    }
    printf("gyro glitch of 3000 deg/s on a straight: %u of 1000 clean rows after it not OK; the transient after "
           "it: %u OK rows > 3 deg off\n", not_ok, onset_ok);
    TEST_ASSERT_EQUAL_UINT(0u, not_ok);
    TEST_ASSERT_EQUAL_UINT(0u, onset_ok);
}

#ifdef CONT_TEST_THREADS
/* Interrupt / task interleaving: a producer thread pushes (as an ISR would; push_imu, then push)
 * while the task steps and reads headings; every sample is either taken by step or counted as
 * dropped, and the calibrator calibrates. */
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
        double psi = fmod(0.3 * (double)i, 360.0);
        magcal_vec2_t p = test_distorted_sample(&k_d, psi, 0.15, &rng);
        magcal_vec3_t m = {p.x, p.y, 40.0f};
        magcal_status_t st;
        do {
            /* the first two thirds through push_imu (the rate of its 0.3 deg per sample, about z),
             * the rest through push: both producers' state is the ISR's */
            const magcal_vec3_t w = {0.0f, 0.0f, (float)(-0.3 / (RATE_MS * 1e-3) * 3.14159265358979 / 180.0)};
            st = (i < 2u * pr->n / 3u) ? magcal_cont_push_imu(&g_cc, &m, NULL, &w, i * RATE_MS)
                                       : magcal_cont_push(&g_cc, &m, i * RATE_MS);
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

void test_cont_isr_push_interleaved_with_task(void)
{
    pthread_t th;
    producer_t pr;
    magcal_cont_progress_t p;
    magcal_cont_heading_t hd;
    magcal_vec3_t probe = {12.0f, 23.0f, 40.0f};
    uint32_t steps = 0u;
    cont_init_default(NULL);
    memset(&pr, 0, sizeof pr);
    pr.n = 3000u; /* 900 deg */
    TEST_ASSERT_EQUAL_INT(0, pthread_create(&th, NULL, producer, &pr));
    while (!pr.done || g_cc.tail != g_cc.head) {
        (void)magcal_cont_step(&g_cc);
        (void)magcal_cont_heading(&g_cc, &probe, 0.0f, &hd);
        (void)magcal_cont_progress(&g_cc, &p);
        steps++;
        TEST_ASSERT_TRUE(steps < 50000000u);
    }
    TEST_ASSERT_EQUAL_INT(0, pthread_join(th, NULL));
    while (magcal_cont_step(&g_cc) == MAGCAL_CONT_IN_PROGRESS) {
    }
    TEST_ASSERT_EQUAL_UINT32(pr.n, pr.ok);
    TEST_ASSERT_EQUAL_UINT32(pr.n, g_cc.tail); /* every queued sample taken exactly once */
    TEST_ASSERT_EQUAL_UINT32(pr.full, g_cc.dropped);
    TEST_ASSERT_TRUE(g_cc.generation >= 1u);
    TEST_ASSERT_TRUE(truth_rms(&g_cc.cal, &k_d) < 1.0);
}
#endif


/* The sliced solve gives, bit for bit, the outcome, calibration and report of the blocking solve
 * on the same store: the state at the first step of a solve is saved, finished once with
 * solve_blocking(), restored, then finished with step() calls (no pushes) at budgets 1, 97 and
 * 6000 (at budget 1 every step still makes progress: one visit each). */
static magcal_cont_t g_cc_save;
static magcal_intake_slot_t g_slots_save[SLOTS];
static magcal_vec2_t g_buf_save[SLOTS];
static MAGCAL_CALIBRATOR_WORKSPACE_DECLARE(g_work_save, SLOTS);

static void cont_save(void)
{
    memcpy(&g_cc_save, &g_cc, sizeof g_cc);
    memcpy(g_slots_save, g_slots, sizeof g_slots);
    memcpy(g_buf_save, g_buf, sizeof g_buf);
    memcpy(g_work_save, g_work, sizeof g_work);
}

static void cont_restore(void)
{
    memcpy(&g_cc, &g_cc_save, sizeof g_cc);
    memcpy(g_slots, g_slots_save, sizeof g_slots);
    memcpy(g_buf, g_buf_save, sizeof g_buf);
    memcpy(g_work, g_work_save, sizeof g_work);
}

/* The judge's model fields (the field-model fit at an adoption, cont_fzfit.c). */
typedef struct {
    float abc[3];
    float hxy[4];
    float sigma;
    uint32_t cover[2];
    float u0;
    float l[28];
    float s[7];
    float u_prior[2];
    uint8_t on;
    uint8_t skip;
    uint8_t have_u;
} judge_fields_t;

static void judge_fields(const magcal_cont_t *cc, judge_fields_t *j)
{
    memset(j, 0, sizeof *j);
    memcpy(j->abc, cc->fz_abc, sizeof j->abc);
    memcpy(j->hxy, cc->fz_hxy, sizeof j->hxy);
    j->sigma = cc->cal_sigma_rel;
    memcpy(j->cover, cc->fz_cover, sizeof j->cover);
    j->u0 = cc->fz_u0;
    memcpy(j->l, cc->fz_l, sizeof j->l);
    memcpy(j->s, cc->fz_s, sizeof j->s);
    memcpy(j->u_prior, cc->fz_u_prior, sizeof j->u_prior);
    j->on = cc->fz_on;
    j->skip = cc->fz_skip;
    j->have_u = cc->fz_have_u;
}

static void sliced_matches_blocking(uint32_t seed, const test_distortion_t *d, double spike, size_t min_rows)
{
    static const uint32_t budgets[] = {1u, 97u, 6000u};
    drive_t dr;
    magcal_cont_outcome_t ref_oc = MAGCAL_CONT_IDLE;
    magcal_cal2d_t ref_cal;
    magcal_cal_report_t ref_rep;
    judge_fields_t ref_judge;
    judge_fields_t got_judge;
    size_t rows = 0u;
    size_t b;
    uint32_t steps_b1 = 0u;
    cont_init_default(NULL);
    drive_init(&dr, d, seed);
    if (spike != 0.0) {
        magcal_vec3_t m = {(float)spike, (float)-spike, 40.0f};
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_push(&g_cc, &m, 0u));
    }
    /* drive (1 deg per row) until a solve after min_rows rows is under way (its snapshot taken),
     * the ring empty (a solve: not the field-model fit after an earlier adoption, fit_phase != 0) */
    while (!(g_cc.stage != 0u && g_cc.fit_phase == 0u && g_cc.tail == g_cc.head && rows >= min_rows)) {
        dr.psi = fmod(dr.psi + 1.0, 360.0);
        (void)drive_row(&dr, 0.0f, 0.0f);
        TEST_ASSERT_TRUE(++rows < 20000u);
    }
    cont_save();
    ref_oc = magcal_cont_solve_blocking(&g_cc, 0);
    TEST_ASSERT_NOT_EQUAL(MAGCAL_CONT_IDLE, ref_oc);
    TEST_ASSERT_NOT_EQUAL(MAGCAL_CONT_IN_PROGRESS, ref_oc);
    ref_cal = g_cc.cal;
    ref_rep = g_cc.last;
    judge_fields(&g_cc, &ref_judge);
    TEST_ASSERT_EQUAL_UINT(0u, g_cc.stage); /* unlimited: the field-model fit ended in the call */
    for (b = 0u; b < sizeof budgets / sizeof budgets[0]; ++b) {
        magcal_cont_outcome_t oc;
        uint32_t steps = 1u;
        cont_restore();
        g_cc.cfg.step_budget = budgets[b];
        while ((oc = magcal_cont_step(&g_cc)) == MAGCAL_CONT_IN_PROGRESS) {
            steps++;
            TEST_ASSERT_TRUE(steps < 10000000u);
        }
        printf("seed %u budget %5u: %s after %u steps (status %s, used %u of %u)\n", (unsigned)seed,
               (unsigned)budgets[b], oc == MAGCAL_CONT_ADOPTED ? "adopted" : "not adopted", (unsigned)steps,
               magcal_status_str(g_cc.last.status), (unsigned)g_cc.last.used, (unsigned)g_cc.last.samples);
        TEST_ASSERT_EQUAL_INT(ref_oc, oc);
        TEST_ASSERT_EQUAL_INT(ref_rep.status, g_cc.last.status);
        TEST_ASSERT_EQUAL_MEMORY(&ref_cal, &g_cc.cal, sizeof ref_cal);
        TEST_ASSERT_EQUAL_MEMORY(&ref_rep, &g_cc.last, sizeof ref_rep);
        if (budgets[b] == 1u) {
            /* every step does at least one visit; the steps at budget 1 count the visits (what
             * is left of the solve when the ring is first empty: since the pre-test's short path
             * (calibrator cfg.pretest) as few as ~100) */
            TEST_ASSERT_TRUE(steps > 50u);
            steps_b1 = steps;
        } else {
            TEST_ASSERT_TRUE(steps < steps_b1); /* a larger budget: fewer, larger steps */
        }
        if (oc == MAGCAL_CONT_ADOPTED) {
            /* the field-model fit runs in the following steps (the judge radius-only meanwhile);
             * its model equals the unlimited-budget fit's, bit for bit */
            uint32_t fit_steps = 0u;
            TEST_ASSERT_EQUAL_UINT(0u, g_cc.fz_on);
            while (g_cc.stage != 0u) {
                TEST_ASSERT_EQUAL_INT(MAGCAL_CONT_IN_PROGRESS, magcal_cont_step(&g_cc));
                TEST_ASSERT_TRUE(g_cc.stage == 0u || g_cc.fz_on == 0u);
                TEST_ASSERT_TRUE(++fit_steps < 2000000u);
            }
            printf("  field-model fit: %u steps (fz_on %u)\n", (unsigned)fit_steps, (unsigned)g_cc.fz_on);
            judge_fields(&g_cc, &got_judge);
            TEST_ASSERT_EQUAL_MEMORY(&ref_judge, &got_judge, sizeof ref_judge);
        }
    }
}

/* The field-model fit at an adoption, time-sliced (the steps after the adopting one): at budgets
 * 1, 97, 1000 and 6000 its model fields (fz_abc, fz_hxy, cal_sigma_rel, fz_cover, fz_on, the
 * factor, the form) equal those of the unlimited-budget fit (solve_blocking) on the same state,
 * bit for bit; raw z spreads with the row (the u terms' forms are tried). */
void test_cont_sliced_field_fit_matches_unlimited(void)
{
    static const uint32_t budgets[] = {1u, 97u, 1000u, 6000u};
    drive_t dr;
    judge_fields_t ref_judge;
    judge_fields_t got_judge;
    uint32_t tried_at = UINT32_MAX;
    unsigned checked = 0u;
    size_t rows = 0u;
    cont_init_default(NULL);
    drive_init(&dr, &k_d, 5u);
    while (checked < 2u && rows < 6000u) {
        const magcal_vec2_t p = test_distorted_sample(dr.d, dr.psi, 0.15, &dr.rng);
        magcal_vec3_t m;
        m.x = p.x;
        m.y = p.y;
        m.z = (float)(40.0 + 6.0 * sin(0.05 * (double)rows));
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_push(&g_cc, &m, dr.t_ms));
        dr.t_ms += 20u;
        dr.psi = fmod(dr.psi + 1.0, 360.0);
        rows++;
        (void)magcal_cont_step(&g_cc);
        (void)magcal_cont_step(&g_cc);
        if (g_cc.stage == 2u && g_cc.tail == g_cc.head && g_cc.solves != tried_at) {
            magcal_cal2d_t ref_cal;
            size_t b;
            tried_at = g_cc.solves; /* once per solve */
            cont_save();
            if (magcal_cont_solve_blocking(&g_cc, 0) != MAGCAL_CONT_ADOPTED) {
                cont_restore();
                continue;
            }
            TEST_ASSERT_EQUAL_UINT(0u, g_cc.stage);
            ref_cal = g_cc.cal;
            judge_fields(&g_cc, &ref_judge);
            for (b = 0u; b < sizeof budgets / sizeof budgets[0]; ++b) {
                uint32_t steps = 0u;
                uint32_t fit_steps = 0u;
                unsigned adopted = 0u;
                cont_restore();
                g_cc.cfg.step_budget = budgets[b];
                while (g_cc.stage != 0u) {
                    const magcal_cont_outcome_t oc = magcal_cont_step(&g_cc);
                    if (oc == MAGCAL_CONT_ADOPTED) {
                        adopted++;
                        TEST_ASSERT_EQUAL_UINT(0u, g_cc.fz_on); /* radius-only until the fit ends */
                    } else if (adopted != 0u) {
                        fit_steps++;
                    } else {
                        TEST_ASSERT_EQUAL_INT(MAGCAL_CONT_IN_PROGRESS, oc);
                    }
                    TEST_ASSERT_TRUE(g_cc.stage == 0u || g_cc.fz_on == 0u);
                    TEST_ASSERT_TRUE(++steps < 10000000u);
                }
                TEST_ASSERT_EQUAL_UINT(1u, adopted);
                TEST_ASSERT_EQUAL_MEMORY(&ref_cal, &g_cc.cal, sizeof ref_cal);
                judge_fields(&g_cc, &got_judge);
                TEST_ASSERT_EQUAL_MEMORY(&ref_judge, &got_judge, sizeof ref_judge);
                printf("field fit, solve %u budget %5u: %u steps after the adopting one (fz_on %u, form %u, "
                       "sigma %.4f)\n",
                       (unsigned)g_cc.solves, (unsigned)budgets[b], (unsigned)fit_steps, (unsigned)g_cc.fz_on,
                       (unsigned)g_cc.fz_skip, (double)g_cc.cal_sigma_rel);
            }
            g_cc.cfg.step_budget = MAGCAL_SLICE_BUDGET_DEFAULT;
            checked++;
        }
    }
    TEST_ASSERT_TRUE(checked >= 1u);
}

void test_cont_sliced_solve_matches_blocking(void)
{
    sliced_matches_blocking(11u, &k_d, 900.0, 300u); /* a start-up spike; the first adoption */
    sliced_matches_blocking(3u, &k_d_step, 0.0, 400u); /* against an installed calibration */
}


/* ------------------------------------------------------------------ coarse stage (hard iron only) */

/* What one drive saw of a coarse stage (stage 1: the hard-iron circle, `last.coarse`; stage 2: the
 * arc's ellipse, `last.arc`), for the drives of both stages (stage_drive). */
typedef struct {
    unsigned adopted;     /* adoptions of the stage */
    unsigned refused;     /* the stage's solves refused UNOBSERVABLE (the bound above tolerance) */
    double worst_margin;  /* min over the stage's adoptions of bound - truth RMS, deg */
    double bound;         /* bound of the first adoption (report est_param_err_deg) */
    double truth;         /* its truth heading RMS over the whole circle */
    double turn;          /* turning at the first adoption, deg */
} stage_stats_t;

/* The calibrator with stage 1 (the coarse circle) or 2 (the arc, no model term: these data have
 * no model error) on at coverage `cov_deg` with tolerance `tol_deg`. */
static void stage_init(uint8_t stage, float cov_deg, float tol_deg)
{
    magcal_cont_cfg_t cfg = MAGCAL_CONT_CFG_DEFAULT;
    if (stage == 2u) {
        cfg.arc_coverage_deg = cov_deg;
        cfg.arc_max_err_deg = tol_deg;
        cfg.arc_model_deg = 0.0f;
    } else {
        cfg.coarse_coverage_deg = cov_deg;
        cfg.coarse_max_err_deg = tol_deg;
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_init(&g_cc, &cfg, NULL, g_slots, SLOTS, g_buf, g_work, sizeof g_work));
}

/* Turn `deg` at 15 deg/s from the current heading, then stay 40 s at the end heading (the solve
 * under way ends); every adoption the stage marks (stage 1: last.coarse, cal_coarse 1; stage 2:
 * last.arc, cal_coarse 2, on less than 270 deg) has its bound checked against the truth over the
 * WHOLE circle and against the stage's tolerance. */
static void stage_drive(uint8_t stage, drive_t *dr, double deg, stage_stats_t *st)
{
    const size_t rows = (size_t)(fabs(deg) / 15.0 * 50.0);
    size_t i;
    for (i = 0u; i < rows + 2000u; ++i) {
        magcal_cont_outcome_t oc;
        uint8_t marked;
        if (i < rows) {
            dr->psi = fmod(dr->psi + deg / (double)rows + 360.0, 360.0);
            dr->turn_deg += fabs(deg / (double)rows);
        }
        oc = drive_row(dr, 0.0f, 0.0f);
        marked = stage == 2u ? g_cc.last.arc : g_cc.last.coarse;
        if (oc == MAGCAL_CONT_ADOPTED && marked != 0u) {
            const double tr = truth_rms(&g_cc.cal, dr->d);
            const double bd = (double)g_cc.last.est_param_err_deg;
            magcal_vec3_t m = {0.0f, 0.0f, 40.0f};
            magcal_cont_heading_t hd;
            const magcal_vec2_t p = test_distorted_sample(dr->d, dr->psi, 0.0, &dr->rng);
            TEST_ASSERT_EQUAL_UINT8(stage, g_cc.cal_coarse);
            if (stage == 2u) {
                TEST_ASSERT_TRUE(g_cc.last.coverage_deg < 270.0f);
            }
            m.x = p.x;
            m.y = p.y;
            TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_heading(&g_cc, &m, 0.0f, &hd));
            /* never OK; TILTED while the slopes are not yet measured (push alone: the field-model
             * fit after the install measures them, continuous.h "Slopes without gravity") */
            TEST_ASSERT_TRUE(hd.trust == MAGCAL_TRUST_COARSE || hd.trust == MAGCAL_TRUST_DISTURBED ||
                             hd.trust == MAGCAL_TRUST_TILTED);
            if (st->adopted == 0u) {
                st->bound = bd;
                st->truth = tr;
                st->turn = dr->turn_deg;
                st->worst_margin = bd - tr;
            }
            st->worst_margin = fmin(st->worst_margin, bd - tr);
            st->adopted++;
            if (!(tr <= bd)) {
                printf("%s: bound %.2f deg < truth %.2f deg (coverage %.0f, used %u, noise %.3f deg, design %.1f)\n",
                       stage == 2u ? "arc" : "coarse", bd, tr, (double)g_cc.last.coverage_deg,
                       (unsigned)g_cc.last.used, (double)g_cc.last.est_noise_deg, (double)g_cc.last.design_factor);
            }
            TEST_ASSERT_TRUE(tr <= bd); /* the promise: the bound covers the whole circle */
            TEST_ASSERT_TRUE(bd <= (double)(stage == 2u ? g_cc.cfg.arc_max_err_deg : g_cc.cfg.coarse_max_err_deg));
        } else if ((oc == MAGCAL_CONT_FAILED || oc == MAGCAL_CONT_REFUSED) && marked != 0u &&
                   g_cc.last.status == MAGCAL_ERR_UNOBSERVABLE) {
            st->refused++;
            if (stage == 2u) {
                TEST_ASSERT_TRUE(g_cc.last.est_param_err_deg > g_cc.cfg.arc_max_err_deg);
            }
        } else {
            /* nothing about the stage */
        }
    }
}

void test_cont_coarse_bound_covers_truth_on_arcs(void)
{
    /* known hard iron (12, -7) and soft iron from none to strong; arcs 160..250 deg (the drives'
     * headings span 270 deg only after 630..720 deg of turning) */
    static const test_distortion_t ds[3] = {{30.0f, {{1.00f, 0.00f}, {0.00f, 1.00f}}, 12.0f, -7.0f},
                                            {30.0f, {{1.03f, 0.02f}, {0.02f, 0.97f}}, 12.0f, -7.0f},
                                            {30.0f, {{1.10f, 0.05f}, {0.05f, 0.90f}}, 12.0f, -7.0f}};
    static const double arcs[3] = {160.0, 200.0, 250.0};
    unsigned adopted[3] = {0u, 0u, 0u};
    size_t k;
    size_t a;
    uint32_t seed;
    for (k = 0u; k < 3u; ++k) {
        for (a = 0u; a < 3u; ++a) {
            for (seed = 1u; seed <= 8u; ++seed) {
                drive_t dr;
                stage_stats_t cs;
                memset(&cs, 0, sizeof cs);
                stage_init(1u, 150.0f, 12.0f);
                drive_init(&dr, &ds[k], seed);
                dr.psi = 47.0 * (double)seed;
                stage_drive(1u, &dr, arcs[a], &cs);
                printf("coarse: soft iron %zu arc %3.0f seed %u: %u coarse adoptions, %u refused; first after %.0f deg: "
                       "bound %.2f deg, truth %.2f deg (worst margin %.2f)\n",
                       k, arcs[a], (unsigned)seed, cs.adopted, cs.refused, cs.turn, cs.bound,
                       cs.truth, cs.worst_margin);
                adopted[k] += cs.adopted != 0u ? 1u : 0u;
                /* a coarse calibration is never replaced by another circle */
                TEST_ASSERT_TRUE(cs.adopted <= 1u);
            }
        }
    }
    /* without and with mild soft iron the stage must actually deliver (not refuse everything) */
    TEST_ASSERT_TRUE(adopted[0] >= 16u);
    TEST_ASSERT_TRUE(adopted[1] >= 16u);
}

void test_cont_coarse_refused_when_soft_iron_exceeds_tolerance(void)
{
    /* soft iron 1.25 / 0.80 (~9 deg RMS that no circle can remove) against a 4-deg tolerance: the
     * bound exceeds it on every arc, nothing is installed, headings stay uncalibrated */
    static const test_distortion_t strong = {30.0f, {{1.25f, 0.00f}, {0.00f, 0.80f}}, 12.0f, -7.0f};
    uint32_t seed;
    unsigned refused = 0u;
    for (seed = 1u; seed <= 3u; ++seed) {
        drive_t dr;
        stage_stats_t cs;
        magcal_cont_heading_t hd;
        const magcal_cal2d_t id = MAGCAL_CAL2D_IDENTITY;
        magcal_vec3_t m = {10.0f, 20.0f, 40.0f};
        memset(&cs, 0, sizeof cs);
        stage_init(1u, 150.0f, 4.0f);
        drive_init(&dr, &strong, seed);
        dr.psi = 47.0 * (double)seed;
        stage_drive(1u, &dr, 220.0, &cs);
        printf("coarse, strong soft iron, seed %u: %u coarse adoptions, %u refused (last estimate %.2f deg)\n",
               (unsigned)seed, cs.adopted, cs.refused, (double)g_cc.last.est_param_err_deg);
        TEST_ASSERT_EQUAL_UINT(0u, cs.adopted);
        TEST_ASSERT_EQUAL_UINT32(0u, g_cc.generation);
        TEST_ASSERT_EQUAL_MEMORY(&id, &g_cc.cal, sizeof id); /* untouched */
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_heading(&g_cc, &m, 0.0f, &hd));
        TEST_ASSERT_EQUAL_INT(MAGCAL_TRUST_UNCALIBRATED, hd.trust);
        refused += cs.refused;
    }
    TEST_ASSERT_TRUE(refused >= 3u); /* the stage ran and said why */
}

void test_cont_coarse_upgraded_by_full_ellipse(void)
{
    /* a coarse calibration on a 200-deg arc, then the rest of the circle: the full ellipse
     * replaces it (never worse on the truth: drive_row checks every adoption), headings OK */
    drive_t dr;
    stage_stats_t cs;
    magcal_cont_heading_t hd;
    magcal_vec3_t m = {0.0f, 0.0f, 40.0f};
    magcal_vec2_t p;
    memset(&cs, 0, sizeof cs);
    stage_init(1u, 150.0f, 12.0f);
    drive_init(&dr, &k_d, 5u);
    stage_drive(1u, &dr, 200.0, &cs);
    TEST_ASSERT_EQUAL_UINT(1u, cs.adopted);
    TEST_ASSERT_TRUE(cs.turn <= 200.0);
    stage_drive(1u, &dr, 360.0, &cs);
    printf("coarse then full: coarse bound %.2f truth %.2f deg; full after %.0f deg of turning, truth %.2f deg, "
           "estimate %.2f deg, %u adoptions\n", cs.bound, cs.truth, dr.turn_deg, truth_rms(&g_cc.cal, &k_d),
           (double)g_cc.adopted_err, dr.adopted);
    TEST_ASSERT_EQUAL_UINT8(0u, g_cc.cal_coarse);
    TEST_ASSERT_TRUE(dr.adopted >= 2u);
    TEST_ASSERT_TRUE(truth_rms(&g_cc.cal, &k_d) < cs.truth);
    TEST_ASSERT_TRUE(truth_rms(&g_cc.cal, &k_d) <= 1.0);
    p = test_distorted_sample(&k_d, dr.psi, 0.0, &dr.rng);
    m.x = p.x;
    m.y = p.y;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_heading(&g_cc, &m, 0.0f, &hd));
    TEST_ASSERT_EQUAL_INT(MAGCAL_TRUST_OK, hd.trust);
    /* a full calibration is installed: no circle is fitted again (the stage is off for good) */
    TEST_ASSERT_EQUAL_FLOAT(0.0f, g_cc.solver.coarse_min_cov);
}

void test_cont_coarse_cfg_checked(void)
{
    magcal_cont_cfg_t cfg = MAGCAL_CONT_CFG_DEFAULT;
    TEST_ASSERT_EQUAL_FLOAT(0.0f, cfg.coarse_coverage_deg); /* opt-in */
    cfg.coarse_coverage_deg = 150.0f;
    cfg.coarse_max_err_deg = 0.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_cont_init(&g_cc, &cfg, NULL, g_slots, SLOTS, g_buf, g_work, sizeof g_work));
    cfg.coarse_max_err_deg = 12.0f;
    cfg.coarse_coverage_deg = 400.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_cont_init(&g_cc, &cfg, NULL, g_slots, SLOTS, g_buf, g_work, sizeof g_work));
    cfg.coarse_coverage_deg = NAN;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_cont_init(&g_cc, &cfg, NULL, g_slots, SLOTS, g_buf, g_work, sizeof g_work));
}

/* magcal_cont_push_g's level test (continuous.h) with known attitudes, 50 Hz stamps: level
 * (tilt 0.5 deg) is LEVEL, tilt 3 deg (limit 2) and |g| 1.3 x its level (hard braking along z)
 * are TILTED, a NaN or NULL g gives no tilt code (as magcal_cont_push); the codes reach the ring;
 * the ring still overflows as push's (BUFFER_FULL, counted). tilt_limit_deg 0: no code at all. */
static void test_cont_push_g_classifies_level_tilted_and_braking(void)
{
    magcal_cont_cfg_t cfg = MAGCAL_CONT_CFG_DEFAULT;
    const magcal_vec3_t m = {10.0f, 20.0f, -40.0f};
    const double d2r = 3.14159265358979 / 180.0;
    const magcal_vec3_t lv = {0.0f, (float)sin(0.5 * d2r), (float)cos(0.5 * d2r)};
    const magcal_vec3_t tl = {(float)sin(3.0 * d2r), 0.0f, (float)cos(3.0 * d2r)};
    const magcal_vec3_t brake = {0.0f, 0.0f, 1.3f};
    const magcal_vec3_t bad = {NAN, 0.0f, 1.0f};
    uint32_t t = 0u;
    unsigned i;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_init(&g_cc, &cfg, NULL, g_slots, SLOTS, g_buf, g_work, sizeof g_work));
    for (i = 0u; i < 8u; ++i, t += 20u) {
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_push_g(&g_cc, &m, &lv, t));
        TEST_ASSERT_EQUAL_UINT8(MAGCAL_INTAKE_TILT_LEVEL, g_cc.ring_tilt[(g_cc.head - 1u) % MAGCAL_CONT_RING]);
        (void)magcal_cont_step(&g_cc);
    }
    for (i = 0u; i < 400u; ++i, t += 20u) { /* 8 s tilted: the smoothed g follows (0.5 s constant) */
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_push_g(&g_cc, &m, &tl, t));
        (void)magcal_cont_step(&g_cc);
    }
    TEST_ASSERT_EQUAL_UINT8(MAGCAL_INTAKE_TILT_TILTED, g_cc.ring_tilt[(g_cc.head - 1u) % MAGCAL_CONT_RING]);
    for (i = 0u; i < 400u; ++i, t += 20u) { /* back to level */
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_push_g(&g_cc, &m, &lv, t));
        (void)magcal_cont_step(&g_cc);
    }
    TEST_ASSERT_EQUAL_UINT8(MAGCAL_INTAKE_TILT_LEVEL, g_cc.ring_tilt[(g_cc.head - 1u) % MAGCAL_CONT_RING]);
    for (i = 0u; i < 50u; ++i, t += 20u) { /* 1 s of |g| 1.3 g: out of the 10 % band of its level */
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_push_g(&g_cc, &m, &brake, t));
        (void)magcal_cont_step(&g_cc);
    }
    TEST_ASSERT_EQUAL_UINT8(MAGCAL_INTAKE_TILT_TILTED, g_cc.ring_tilt[(g_cc.head - 1u) % MAGCAL_CONT_RING]);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_push_g(&g_cc, &m, &bad, t));
    TEST_ASSERT_EQUAL_UINT8(MAGCAL_INTAKE_TILT_UNKNOWN, g_cc.ring_tilt[(g_cc.head - 1u) % MAGCAL_CONT_RING]);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_push_g(&g_cc, &m, NULL, t));
    TEST_ASSERT_EQUAL_UINT8(MAGCAL_INTAKE_TILT_UNKNOWN, g_cc.ring_tilt[(g_cc.head - 1u) % MAGCAL_CONT_RING]);
    TEST_ASSERT_EQUAL_UINT32(858u, g_cc.g_pushed);
    printf("push_g: %u of %u samples LEVEL\n", (unsigned)g_cc.g_level, (unsigned)g_cc.g_pushed);
    /* 8 + the 400 level ones less ~10 while the smoothed g returns, + ~27 tilted ones and ~2
     * braking ones before the smoothed g leaves the limit / band (0.5 s constant) */
    TEST_ASSERT_TRUE(g_cc.g_level >= 8u + 380u && g_cc.g_level <= 8u + 440u);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_cont_push_g(NULL, &m, &lv, t));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_cont_push_g(&g_cc, NULL, &lv, t));
    for (i = 0u; i < MAGCAL_CONT_RING + 2u; ++i) { /* no step: the ring fills */
        (void)magcal_cont_push_g(&g_cc, &m, &lv, t);
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_BUFFER_FULL, magcal_cont_push_g(&g_cc, &m, &lv, t));
    cfg.intake.tilt_limit_deg = 0.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_init(&g_cc, &cfg, NULL, g_slots, SLOTS, g_buf, g_work, sizeof g_work));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_push_g(&g_cc, &m, &lv, 0u));
    TEST_ASSERT_EQUAL_UINT8(MAGCAL_INTAKE_TILT_UNKNOWN, g_cc.ring_tilt[0]);
    TEST_ASSERT_EQUAL_UINT32(0u, g_cc.g_pushed);
}

/* ---- push_g tilt compensation (continuous.h "Tilt compensation"), known truth. A 3-D sensor
 * model (body x right, y forward, z up; the attitude as tools/gen_drive.py): field B_NED
 * (21, 0, 44) uT (no declination), raw = W h + V, W symmetric in x, y (no rotation the 2-D fit
 * cannot see), V (12, -7, 20), noise 0.1 uT; specific force -C^T e_down. Circles at 15 deg/s,
 * 50 Hz, one push per row; pitch = A sin(psi) + B_c cos(psi): A = 4 deg on every circle (the
 * road climbs heading east: pitch correlated with heading, the bias a store filled on hills
 * takes), B_c in +-3 deg changing per circle (tilt along the field, what k is learnt from). */
#define TC_ROWS_PER_CIRCLE 1200u /* 24 s at 15 deg/s, 50 Hz */
static const double k_tc_w[3][3] = {{1.08, 0.04, 0.0}, {0.04, 0.93, 0.0}, {0.0, 0.0, 1.0}};
static const double k_tc_v[3] = {12.0, -7.0, 20.0};
static const double k_tc_b[3] = {21.0, 0.0, 44.0};

static double g_tc_step[3]; /* a hard-iron step added to k_tc_v (0: none) */
static double g_tc_lat_g;   /* tc_six_circles: the circles' centripetal acceleration, g (0: none) */

/* Raw sample and specific force at heading psi, pitch th (deg), no roll. */
static void tc_sample(double psi_deg, double th_deg, double sigma, uint32_t *rng, magcal_vec3_t *m, magcal_vec3_t *g)
{
    const double d2r = 3.14159265358979 / 180.0;
    const double sp = sin(psi_deg * d2r), cp = cos(psi_deg * d2r), st = sin(th_deg * d2r), ct = cos(th_deg * d2r);
    /* C_b^NED columns (gen_drive.py dcm_ned_batch, roll 0): body x, y, z in NED */
    const double cx[3] = {-sp, cp, 0.0};
    const double cy[3] = {cp * ct, sp * ct, -st};
    const double cz[3] = {-cp * st, -sp * st, -ct};
    const double h[3] = {cx[0] * k_tc_b[0] + cx[1] * k_tc_b[1] + cx[2] * k_tc_b[2],
                         cy[0] * k_tc_b[0] + cy[1] * k_tc_b[1] + cy[2] * k_tc_b[2],
                         cz[0] * k_tc_b[0] + cz[1] * k_tc_b[1] + cz[2] * k_tc_b[2]};
    double r[3];
    int a;
    for (a = 0; a < 3; ++a) {
        r[a] = k_tc_w[a][0] * h[0] + k_tc_w[a][1] * h[1] + k_tc_w[a][2] * h[2] + k_tc_v[a] + g_tc_step[a] +
               sigma * test_rand_normal(rng);
    }
    m->x = (float)r[0];
    m->y = (float)r[1];
    m->z = (float)r[2];
    g->x = (float)(-cx[2]); /* specific force: -(C^T e_down) */
    g->y = (float)(-cy[2]);
    g->z = (float)(-cz[2]);
}

/* The TRUE level heading error of calibration c: RMS over 72 headings at zero pitch (noiseless). */
static double tc_level_rms(const magcal_cal2d_t *c)
{
    double ss = 0.0;
    uint32_t rng = 1u;
    int k;
    for (k = 0; k < 72; ++k) {
        magcal_vec3_t m, g;
        magcal_vec2_t p;
        float mag = 0.0f, tru = 0.0f;
        tc_sample(5.0 * k, 0.0, 0.0, &rng, &m, &g);
        p.x = m.x;
        p.y = m.y;
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_heading_compute(c, p, 0.0f, &mag, &tru));
        ss += test_angle_diff_deg(mag, 5.0 * k) * test_angle_diff_deg(mag, 5.0 * k);
    }
    return sqrt(ss / 72.0);
}

/* The hilly drive, with gravity (push_g, with_g 1) or without (push, 0): first `sweeps` arcs of
 * +-50 deg around north (a winding road: a ring arc for the store's centre, too little coverage
 * for a solve), each at a pitch of its own in +-5 deg (what k is learnt from), then `circles`
 * circles (above); with_g 2: push_g with the field of a level vehicle and only the gravity
 * pitched (the vehicle's own acceleration read as tilt). Returns the adoptions; *before* =
 * adoptions during the arcs. */
static float g_tc_restore_k;          /* tc_drive_from: the tilt compensation restored with `installed` */
static uint8_t g_tc_restore_levelled; /* (magcal_cont_restore_tilt; k 0: none) */
static unsigned tc_drive_from(const magcal_cal2d_t *installed, int with_g, unsigned sweeps, unsigned circles,
                              unsigned *before)
{
    const double d2r = 3.14159265358979 / 180.0;
    magcal_cont_cfg_t cfg = MAGCAL_CONT_CFG_DEFAULT;
    uint32_t rng = 77u;
    uint32_t grng = 78u;
    uint32_t brng = 5u;
    uint32_t t = 0u;
    unsigned adopted = 0u;
    unsigned c, i, k;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_init(&g_cc, &cfg, installed, g_slots, SLOTS, g_buf, g_work, sizeof g_work));
    if (installed != NULL && g_tc_restore_k != 0.0f) {
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_restore_tilt(&g_cc, g_tc_restore_k, g_tc_restore_levelled));
    }
    for (c = 0u; c < sweeps + circles; ++c) {
        const double bc = (c < sweeps ? 10.0 : 6.0) * test_rand_uniform(&brng) - (c < sweeps ? 5.0 : 3.0);
        const unsigned rows = c < sweeps ? TC_ROWS_PER_CIRCLE / 3u : TC_ROWS_PER_CIRCLE; /* 100 or 360 deg */
        if (c == sweeps) {
            *before = adopted;
        }
        for (i = 0u; i < rows; ++i, t += RATE_MS) {
            const double s = (double)i / (double)rows;
            const double psi = c < sweeps ? ((c % 2u) == 0u ? 100.0 * s - 50.0 : 50.0 - 100.0 * s)
                                          : 360.0 * ((double)c + s);
            const double th = c < sweeps ? bc : 4.0 * sin(psi * d2r) + bc * cos(psi * d2r);
            magcal_vec3_t m, g, m_unused;
            tc_sample(psi, with_g == 2 ? 0.0 : th, 0.1, &rng, &m, &g);
            if (with_g == 2) {
                tc_sample(psi, th, 0.0, &grng, &m_unused, &g); /* only the gravity pitched: an acceleration */
            }
            TEST_ASSERT_EQUAL_INT(MAGCAL_OK, with_g != 0 ? magcal_cont_push_g(&g_cc, &m, &g, t) : magcal_cont_push(&g_cc, &m, t));
            for (k = 0u; k < STEPS_PER_ROW; ++k) {
                adopted += (magcal_cont_step(&g_cc) == MAGCAL_CONT_ADOPTED) ? 1u : 0u;
            }
        }
    }
    return adopted;
}

static unsigned tc_drive(int with_g, unsigned sweeps, unsigned circles, unsigned *before)
{
    return tc_drive_from(NULL, with_g, sweeps, circles, before);
}

/* With gravity the vertical field is learnt on the winding road (k within 15 % of the truth:
 * Z_up x sqrt(det W_xy) = -44 x 1.0012) before any calibration is installed, so compensation is
 * on (no field model judges the stream yet); samples are levelled before they are stored, and
 * the installed calibration's true level heading error is <= 1 deg and at most half of what the
 * same drive gives without gravity (the store filled on the hills). */
static void test_cont_push_g_tilt_compensation_levels_the_store(void)
{
    const double k_true = -44.0 * sqrt(k_tc_w[0][0] * k_tc_w[1][1] - k_tc_w[0][1] * k_tc_w[1][0]);
    unsigned ad_g, ad_n, pre_g = 0u, pre_n = 0u;
    double rms_g, rms_n;
    ad_n = tc_drive(0, 60u, 30u, &pre_n);
    TEST_ASSERT_TRUE(ad_n >= 1u);
    rms_n = tc_level_rms(&g_cc.cal);
    TEST_ASSERT_EQUAL_UINT32(0u, g_cc.tc_levelled);
    ad_g = tc_drive(1, 60u, 30u, &pre_g);
    TEST_ASSERT_TRUE(ad_g >= 1u);
    rms_g = tc_level_rms(&g_cc.cal);
    printf("tilt compensation: k %.2f (truth %.2f, rho %.3f) from %u samples, ok %u on %u, %u rows levelled; level heading "
           "RMS %.2f deg with gravity (%u adoptions, %u on the road), %.2f without (%u, %u)\n",
           (double)g_cc.tc_k, k_true, (double)g_cc.tc_rho, (unsigned)g_cc.tc_n, (unsigned)g_cc.tc_ok, (unsigned)g_cc.tc_on,
           (unsigned)g_cc.tc_levelled, rms_g, ad_g, pre_g, rms_n, ad_n, pre_n);
    TEST_ASSERT_EQUAL_UINT(0u, pre_g);
    TEST_ASSERT_EQUAL_UINT8(1u, g_cc.tc_ok);
    TEST_ASSERT_EQUAL_UINT8(1u, g_cc.tc_on);
    TEST_ASSERT_TRUE(fabs((double)g_cc.tc_k - k_true) <= 0.15 * fabs(k_true));
    TEST_ASSERT_TRUE(g_cc.tc_rho >= 0.8f && g_cc.tc_rho <= 1.25f); /* raw z confirms the tilt */
    TEST_ASSERT_TRUE(g_cc.tc_levelled > 0u);
    TEST_ASSERT_TRUE(rms_g <= 1.0);
    TEST_ASSERT_TRUE(rms_g <= 0.5 * rms_n);
}

/* A vehicle's own acceleration reads as tilt in the accelerometer, not in the magnetometer: the
 * winding road of tc_drive with the magnetometer level and only the gravity pitched (+-5 deg per
 * arc, a braking / accelerating car) must not teach k nor level anything: raw z does not confirm
 * the tilt (the share rho = -(z q) / (R q q) stays near 0, below its 0.5 floor), and the
 * determined regression marks the accelerometer's tilt as acceleration (tc_acc: the tilt in the
 * trust predicts nothing from it). The same road with the tilt real gives rho within 0.8..1.25
 * and k (test above). */
static void test_cont_push_g_acceleration_is_not_tilt(void)
{
    unsigned pre = 0u;
    (void)tc_drive(2, 60u, 0u, &pre);
    printf("acceleration read as tilt: %u samples in the regression, k %.2f, rho %.3f, ok %u, %u levelled\n",
           (unsigned)g_cc.tc_n, (double)g_cc.tc_k, (double)g_cc.tc_rho, (unsigned)g_cc.tc_ok,
           (unsigned)g_cc.tc_levelled);
    TEST_ASSERT_TRUE(g_cc.tc_n >= 24u); /* the regression had samples: the refusal is rho's */
    TEST_ASSERT_TRUE(fabs((double)g_cc.tc_rho) < 0.2);
    TEST_ASSERT_EQUAL_UINT8(0u, g_cc.tc_ok);
    TEST_ASSERT_EQUAL_UINT32(0u, g_cc.tc_levelled);
    TEST_ASSERT_EQUAL_UINT8(1u, g_cc.tc_acc); /* determined, and not tilt: the tilt in the trust is off */
}

/* The heading is tilt-compensated as well (continuous.h "Tilt compensation"): after the hilly
 * drive (compensation on, the calibration fitted on levelled samples), the vehicle stands at 5 deg
 * of pitch at 36 headings (3 s each, so the smoothed gravity settles). Every heading comes back
 * levelled (hd.levelled = 1) and its error against the truth is <= 1.5 deg RMS, while the same
 * samples' unlevelled heading under the same calibration is off by the tilt's leak (Z / H x the
 * pitch along the field: about 10 deg facing east or west), >= 4x the levelled RMS. */
static void test_cont_heading_levelled_on_hills(void)
{
    unsigned pre = 0u;
    uint32_t rng = 11u;
    uint32_t t = 900000000u;
    double ss_lv = 0.0, ss_raw = 0.0;
    int h;
    unsigned i;
    TEST_ASSERT_TRUE(tc_drive(1, 60u, 30u, &pre) >= 1u);
    TEST_ASSERT_EQUAL_UINT8(1u, g_cc.tc_on);
    for (h = 0; h < 36; ++h) {
        const double psi = 10.0 * h + 5.0;
        magcal_vec3_t m, g;
        magcal_cont_heading_t hd;
        magcal_vec2_t p;
        float mag = 0.0f, tru = 0.0f;
        for (i = 0u; i < 150u; ++i, t += RATE_MS) {
            tc_sample(psi, 5.0, 0.1, &rng, &m, &g);
            TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_push_g(&g_cc, &m, &g, t));
            (void)magcal_cont_step(&g_cc);
        }
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_heading(&g_cc, &m, 0.0f, &hd));
        TEST_ASSERT_EQUAL_UINT8(1u, hd.levelled);
        ss_lv += test_angle_diff_deg(hd.heading_deg, psi) * test_angle_diff_deg(hd.heading_deg, psi);
        p.x = m.x;
        p.y = m.y;
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_heading_compute(&g_cc.cal, p, 0.0f, &mag, &tru));
        ss_raw += test_angle_diff_deg(mag, psi) * test_angle_diff_deg(mag, psi);
    }
    printf("heading at 5 deg of pitch, 36 headings: levelled RMS %.2f deg, unlevelled %.2f deg (k %.2f)\n",
           sqrt(ss_lv / 36.0), sqrt(ss_raw / 36.0), (double)g_cc.tc_k);
    TEST_ASSERT_TRUE(sqrt(ss_lv / 36.0) <= 1.5);
    TEST_ASSERT_TRUE(sqrt(ss_raw / 36.0) >= 4.0 * sqrt(ss_lv / 36.0));
}

/* An unlevelled calibration (continuous.h "Tilt in the trust", "Tilt compensation"): six circles
 * on a constant 4-deg slope with gravity (every sector sees one pitch: nothing to learn k from)
 * adopt a calibration fitted on pitched samples, with its fit's mean tilt known (tan 4 deg along
 * y). Then the vehicle stands level at 36 headings, 3 s each. While k is unknown the heading is
 * off by the slope's leak (about 8 deg at worst) and must not be OK: it is TILTED (predicted
 * 2.5 R tan 4 deg / R = 10 deg > cfg.tilt_trust_deg 3). The level samples teach k (each sector
 * now has two pitches); the heading then applies the calibration levelled by its fit tilt
 * (cc.levels = 1, cc.cal_conv = 1: its centre moved back by k t_cal), and every heading returned
 * OK from then on is within 2 deg of the truth. That calibration's true level RMS is <= 1 deg
 * and <= half of what was adopted. */
/* Six circles on a hill whose pitch is `slope` + `amp` sin(psi) deg, from a fresh instance, one
 * push_g per row: the adoptions. */
static unsigned tc_six_circles(double slope, double amp, uint32_t *rng, uint32_t *t)
{
    const double d2r = 3.14159265358979 / 180.0;
    magcal_cont_cfg_t cfg = MAGCAL_CONT_CFG_DEFAULT;
    unsigned adopted = 0u, c, i, k;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_init(&g_cc, &cfg, NULL, g_slots, SLOTS, g_buf, g_work, sizeof g_work));
    for (c = 0u; c < 6u; ++c) {
        for (i = 0u; i < TC_ROWS_PER_CIRCLE; ++i, *t += RATE_MS) {
            const double psi = 360.0 * ((double)c + (double)i / (double)TC_ROWS_PER_CIRCLE);
            magcal_vec3_t m, g;
            tc_sample(psi, slope + amp * sin(psi * d2r), 0.1, rng, &m, &g);
            if (c > 0u || i >= TC_ROWS_PER_CIRCLE / 36u) {
                g.x += (float)g_tc_lat_g; /* lateral, once the car is on its circle (after 10 deg) */
            }
            TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_push_g(&g_cc, &m, &g, *t));
            for (k = 0u; k < STEPS_PER_ROW; ++k) {
                adopted += (magcal_cont_step(&g_cc) == MAGCAL_CONT_ADOPTED) ? 1u : 0u;
            }
        }
    }
    return adopted;
}

/* Standing at `pitch` deg (tc_stand_level: level) at 36 headings (3 s each): the heading's trust
 * and true error at each. TILTED ones counted with their squared errors; OK ones with the worst
 * error; the others (DISTURBED) counted; levels_before_tilted: a TILTED heading only while the
 * calibration is not yet levelled. */
typedef struct {
    unsigned n_tilted, n_ok, n_other;
    double ss_tilted, worst_ok;
} tc_level_stats_t;

static void tc_stand_at(double pitch, uint32_t *rng, uint32_t *t, int levels_before_tilted, tc_level_stats_t *st)
{
    unsigned i, k;
    int h;
    st->n_tilted = 0u;
    st->n_ok = 0u;
    st->n_other = 0u;
    st->ss_tilted = 0.0;
    st->worst_ok = 0.0;
    for (h = 0; h < 36; ++h) {
        const double psi = 10.0 * h + 5.0;
        magcal_vec3_t m, g;
        magcal_cont_heading_t hd;
        double e;
        for (i = 0u; i < 150u; ++i, *t += RATE_MS) {
            tc_sample(psi, pitch, 0.1, rng, &m, &g);
            TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_push_g(&g_cc, &m, &g, *t));
            for (k = 0u; k < STEPS_PER_ROW; ++k) {
                (void)magcal_cont_step(&g_cc);
            }
        }
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_heading(&g_cc, &m, 0.0f, &hd));
        e = fabs(test_angle_diff_deg(hd.heading_deg, psi));
        if (hd.trust == MAGCAL_TRUST_TILTED) {
            if (levels_before_tilted != 0) {
                TEST_ASSERT_EQUAL_UINT32(0u, g_cc.levels); /* only before the calibration is levelled */
            }
            st->n_tilted++;
            st->ss_tilted += e * e;
        } else if (hd.trust == MAGCAL_TRUST_OK) {
            st->n_ok++;
            st->worst_ok = fmax(st->worst_ok, e);
        } else {
            st->n_other++; /* another state (DISTURBED) */
        }
    }
}

static void tc_stand_level(uint32_t *rng, uint32_t *t, int levels_before_tilted, tc_level_stats_t *st)
{
    tc_stand_at(0.0, rng, t, levels_before_tilted, st);
}

/* The fit tilt of the calibration in force, its level RMS as adopted and what standing level gave. */
static void tc_fit_report(const char *what, double rms_adopted, const tc_level_stats_t *st)
{
    printf("%s: fit tilt (%.4f, %.4f) spread %.4f, level RMS %.2f deg as adopted; standing level: %u headings "
           "TILTED (RMS %.2f deg), %u OK (worst %.2f deg); k ok %u, levelled %u x\n",
           what, (double)g_cc.cal_tx, (double)g_cc.cal_ty, (double)g_cc.cal_ts, rms_adopted, st->n_tilted,
           st->n_tilted != 0u ? sqrt(st->ss_tilted / (double)st->n_tilted) : 0.0, st->n_ok, st->worst_ok,
           (unsigned)g_cc.tc_ok, (unsigned)g_cc.levels);
}

static void test_cont_unlevelled_calibration_tilted_then_levelled(void)
{
    const double d2r = 3.14159265358979 / 180.0;
    uint32_t rng = 91u;
    uint32_t t = 0u;
    double rms_adopted, rms_after;
    tc_level_stats_t st;
    TEST_ASSERT_TRUE(tc_six_circles(4.0, 0.0, &rng, &t) >= 1u);
    TEST_ASSERT_EQUAL_UINT8(0u, g_cc.tc_ok);
    TEST_ASSERT_EQUAL_UINT8(0u, g_cc.cal_lv);
    TEST_ASSERT_EQUAL_UINT8(1u, g_cc.cal_tk);
    TEST_ASSERT_FLOAT_WITHIN(0.005f, 0.0f, g_cc.cal_tx);
    TEST_ASSERT_FLOAT_WITHIN(0.005f, (float)tan(4.0 * d2r), g_cc.cal_ty);
    rms_adopted = tc_level_rms(&g_cc.cal);
    tc_stand_level(&rng, &t, 1, &st);
    {
        /* the calibration the levelled heading applies: its centre moved back by k t_cal (the
         * installed record itself changes only when a solve on the levelled store confirms it) */
        magcal_cal2d_t c = g_cc.cal;
        TEST_ASSERT_EQUAL_UINT8(1u, g_cc.cal_conv);
        c.offset.x -= g_cc.tc_kl * g_cc.cal_tx;
        c.offset.y -= g_cc.tc_kl * g_cc.cal_ty;
        rms_after = tc_level_rms(&c);
    }
    printf("unlevelled calibration: fit tilt (%.4f, %.4f), level RMS %.2f deg as adopted; standing level: %u "
           "headings TILTED (RMS %.2f deg), %u OK (worst %.2f deg); k %.2f ok %u, levelled %u x, level RMS %.2f deg\n",
           (double)g_cc.cal_tx, (double)g_cc.cal_ty, rms_adopted, st.n_tilted,
           st.n_tilted != 0u ? sqrt(st.ss_tilted / (double)st.n_tilted) : 0.0, st.n_ok, st.worst_ok, (double)g_cc.tc_k,
           (unsigned)g_cc.tc_ok, (unsigned)g_cc.levels, rms_after);
    TEST_ASSERT_TRUE(rms_adopted >= 3.0);
    TEST_ASSERT_TRUE(st.n_tilted >= 1u);
    TEST_ASSERT_TRUE(sqrt(st.ss_tilted / (double)st.n_tilted) >= 3.0); /* the flag was warranted */
    TEST_ASSERT_EQUAL_UINT8(1u, g_cc.tc_ok);
    TEST_ASSERT_EQUAL_UINT32(1u, g_cc.levels);
    TEST_ASSERT_TRUE(st.n_ok >= 8u); /* measured 11: k needs 24 samples, about 23 headings */
    TEST_ASSERT_TRUE(st.worst_ok <= 2.0); /* measured 1.47 */
    TEST_ASSERT_TRUE(rms_after <= 1.0);
    TEST_ASSERT_TRUE(rms_after <= 0.5 * rms_adopted);
}

/* The relevelled calibration judged as its heading is computed (continuous.h "Tilt
 * compensation"; 30-min seed 7: 1,542 clean rows on a straight over a 4.7-deg hill DISTURBED,
 * its headings within 1.6 deg of the truth). The calibration of six circles on a 4-deg slope is
 * levelled by its fit tilt (cal_conv) while standing level, as above; then the vehicle stands at
 * 9 headings of one quarter (no solve confirms the calibration meanwhile) at -3, 2 and 6 deg of
 * pitch, 3 s each, every row's heading checked. Its judge used to see the samples un-levelled
 * against the field model fitted on the one slope: at another pitch the horizontal field moves
 * by Z sin(pitch), and headings levelled and right were DISTURBED. Judged as the heading's
 * sample (levelled, by the radius), they are OK within 2.5 deg of the truth. */
static void test_cont_relevelled_calibration_judged_levelled(void)
{
    static const double pitches[3] = {-3.0, 2.0, 6.0};
    uint32_t rng = 93u;
    uint32_t t = 0u;
    unsigned p, h, i, k;
    tc_level_stats_t st;
    TEST_ASSERT_TRUE(tc_six_circles(4.0, 0.0, &rng, &t) >= 1u);
    tc_stand_level(&rng, &t, 1, &st);
    TEST_ASSERT_EQUAL_UINT8(1u, g_cc.cal_conv);
    for (p = 0u; p < 3u; ++p) {
        unsigned n_ok = 0u, n_dist = 0u, n = 0u;
        double worst = 0.0;
        for (h = 0u; h < 9u; ++h) {
            const double psi = 10.0 * h + 5.0; /* a quarter of the circle: no solve confirms it meanwhile */
            for (i = 0u; i < 150u; ++i, t += RATE_MS) {
                magcal_vec3_t m, g;
                magcal_cont_heading_t hd;
                tc_sample(psi, pitches[p], 0.1, &rng, &m, &g);
                TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_push_g(&g_cc, &m, &g, t));
                for (k = 0u; k < STEPS_PER_ROW; ++k) {
                    (void)magcal_cont_step(&g_cc);
                }
                TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_heading(&g_cc, &m, 0.0f, &hd));
                n++;
                if (hd.trust == MAGCAL_TRUST_OK) {
                    n_ok++;
                    worst = fmax(worst, fabs(test_angle_diff_deg(hd.heading_deg, psi)));
                } else if (hd.trust == MAGCAL_TRUST_DISTURBED) {
                    n_dist++;
                }
            }
        }
        printf("relevelled calibration standing at %.0f deg of pitch: %u of %u headings OK (worst %.2f deg), %u "
               "DISTURBED; levelled by its fit tilt %u\n",
               pitches[p], n_ok, n, worst, n_dist, (unsigned)g_cc.cal_conv);
        TEST_ASSERT_EQUAL_UINT8(1u, g_cc.cal_conv); /* still the relevel's calibration */
        /* measured 53..72 DISTURBED (the heading jumps 10 deg at once between stands: the
         * transient judge's), 1,278..1,297 OK, the worst 2.21 deg (the calibration's own error
         * there); judged un-levelled 301..656 DISTURBED */
        TEST_ASSERT_TRUE(n_dist <= 100u);
        TEST_ASSERT_TRUE(n_ok >= 1200u);
        TEST_ASSERT_TRUE(worst <= 2.5);
    }
}

/* A calibration fitted on a BENT store (30-min drive seed 14 before this test: its store's tilt
 * spread 1.5 deg about a mean of 1.35, k unknown, 920 headings OK at 4.4 deg RMS): circles whose
 * pitch follows the heading, 4 sin(psi) deg on every circle, so the mean tilt is level but each
 * sector is stored at its own tilt and the fit bends the ellipse (no sector sees a tilt change:
 * k stays unknown). The heading's predicted tilt error counts the spread (k sqrt(|t - t_cal|^2 +
 * s^2) / R): standing level after the adoption, no heading is OK unless it is within 2 deg of the
 * truth (the trust state's tolerance 3 deg). Measured: spread 2.7 deg, level RMS 3.03 deg as
 * adopted, 35 headings TILTED (true RMS 3.05 deg), 0 OK; without the spread term 35 OK, the worst
 * 4.83 deg off. */
static void test_cont_bent_store_calibration_not_trusted(void)
{
    uint32_t rng = 93u;
    uint32_t t = 0u;
    double rms_adopted;
    tc_level_stats_t st;
    TEST_ASSERT_TRUE(tc_six_circles(0.0, 4.0, &rng, &t) >= 1u);
    TEST_ASSERT_EQUAL_UINT8(0u, g_cc.tc_ok);
    TEST_ASSERT_EQUAL_UINT8(0u, g_cc.cal_lv);
    TEST_ASSERT_EQUAL_UINT8(1u, g_cc.cal_tk);
    rms_adopted = tc_level_rms(&g_cc.cal);
    tc_stand_level(&rng, &t, 0, &st);
    tc_fit_report("bent store", rms_adopted, &st);
    TEST_ASSERT_TRUE(rms_adopted >= 2.5);  /* the store was bent: the fit is wrong at level */
    TEST_ASSERT_TRUE(st.n_tilted >= 18u);
    TEST_ASSERT_TRUE(sqrt(st.ss_tilted / (double)st.n_tilted) >= 2.5); /* the flag was warranted */
    TEST_ASSERT_TRUE(st.worst_ok <= 2.0);     /* an OK is within the tolerance */
}

/* Circles on a hill while the accelerometer reads the car's own acceleration (continuous.h "Tilt
 * in the trust"): tc_six_circles on a constant 4-deg slope with a centripetal 0.2 g on body x from
 * 10 deg into the first circle on (11 deg of apparent roll, beyond the level test's limit: every
 * later sample has an unknown tilt). The store's samples count with the tilt held from 1..2 s
 * before the last one known (the slope, read on the first 10 deg), so the calibration's fit tilt
 * is known (cal_tk) and is the slope's. Standing level after it: the fit on pitched samples is off (as in
 * test_cont_unlevelled_calibration_tilted_then_levelled) and no heading is OK unless it is within
 * 2 deg of the truth. Measured: fit tilt (0.000, 0.070), level RMS 5.96 deg as adopted; 34
 * headings TILTED (true RMS 6.08 deg), 0 OK. Without the last known tilt (the store's tilt
 * unknown: cal_tk 0, the tilt in the trust off) the same 34 headings were OK, the worst 8.54 deg
 * off. */
static void test_cont_turns_under_acceleration_keep_the_fit_tilt(void)
{
    const double d2r = 3.14159265358979 / 180.0;
    uint32_t rng = 95u;
    uint32_t t = 0u;
    double rms_adopted;
    tc_level_stats_t st;
    g_tc_lat_g = 0.2;
    TEST_ASSERT_TRUE(tc_six_circles(4.0, 0.0, &rng, &t) >= 1u);
    g_tc_lat_g = 0.0;
    TEST_ASSERT_EQUAL_UINT8(0u, g_cc.cal_lv);
    TEST_ASSERT_EQUAL_UINT8(1u, g_cc.cal_tk);
    printf("circles under 0.2 g: fit tilt (%.4f, %.4f)\n", (double)g_cc.cal_tx, (double)g_cc.cal_ty);
    /* the tilt held from 1..2 s before the last one known: not the acceleration ramping in (the
     * last one known holds up to the level test's 2 deg of it: 0.028 here) */
    TEST_ASSERT_FLOAT_WITHIN(0.005f, 0.0f, g_cc.cal_tx);
    TEST_ASSERT_FLOAT_WITHIN(0.005f, (float)tan(4.0 * d2r), g_cc.cal_ty);
    rms_adopted = tc_level_rms(&g_cc.cal);
    tc_stand_level(&rng, &t, 1, &st);
    tc_fit_report("circles under 0.2 g", rms_adopted, &st);
    TEST_ASSERT_TRUE(rms_adopted >= 3.0); /* the fit saw the slope */
    TEST_ASSERT_TRUE(st.n_tilted >= 18u);
    TEST_ASSERT_TRUE(sqrt(st.ss_tilted / (double)st.n_tilted) >= 3.0); /* the flag was warranted */
    TEST_ASSERT_TRUE(st.worst_ok <= 2.0); /* an OK is within the tolerance */
}

/* A calibration restored from flash after a power cycle (its fit tilt unknown): the hilly drive
 * of tc_drive with gravity from the restored calibration of an earlier one. When k is learnt the
 * store is emptied and refills with levelled samples while the restored calibration stays in
 * force, judged on un-levelled samples (cc.relevels = 1); a solve on the levelled store then
 * adopts or confirms a levelled calibration (cc.cal_lv = 1), whose true level RMS is <= 1 deg.
 * Not yet right: the restored calibration has no field model, so the hills' radius change reads
 * as a lasting mismatch and one change is declared (measured 1; an open issue in the closing
 * note), after which the relearn adopts. */
static void test_cont_restored_calibration_relevelled(void)
{
    unsigned pre = 0u, ad;
    magcal_cal2d_t saved;
    double rms_saved, rms_end;
    TEST_ASSERT_TRUE(tc_drive(1, 60u, 30u, &pre) >= 1u);
    saved = g_cc.cal;
    rms_saved = tc_level_rms(&saved);
    ad = tc_drive_from(&saved, 1, 60u, 30u, &pre);
    rms_end = tc_level_rms(&g_cc.cal);
    printf("restored calibration (level RMS %.2f deg): %u relevels, %u changes, %u adoptions (%u on the road), "
           "cal_lv %u, solves %u, level RMS at the end %.2f deg\n",
           rms_saved, (unsigned)g_cc.relevels, (unsigned)g_cc.changes, ad, pre, (unsigned)g_cc.cal_lv,
           (unsigned)g_cc.solves, rms_end);
    TEST_ASSERT_EQUAL_UINT32(1u, g_cc.relevels);
    TEST_ASSERT_EQUAL_UINT32(0u, g_cc.changes); /* was 1 before tilted samples were neutral evidence */
    TEST_ASSERT_EQUAL_UINT8(1u, g_cc.cal_lv);
    TEST_ASSERT_TRUE(rms_end <= 1.0);
}

/* A calibration restored without its tilt state (its fit tilt unknown, k unknown) while the
 * vehicle stands on a 5-deg slope at 36 headings (3 s each): the heading is not levelled, so it
 * is off by the slope's leak (up to about 10 deg facing east or west), and the trust must not say
 * OK for it. The predicted error takes the unknown fit tilt for level (a saved calibration is a
 * level one, or restored levelled with its tilt state): 2.5 R tan 5 deg / R = 12.5 deg > 3.
 * Measured: 29 headings DISTURBED (the judge's radius sees the leak), 7 TILTED (true RMS 10.46
 * deg), 0 OK. Before (the tilt term off for an unknown fit tilt) those 7 were OK, the worst 10.89
 * deg off; legacy-record restores of the generated drives kept 9,531 (60 s1) and 11,033 (60 s3)
 * OK rows more than 5 deg off. */
static void test_cont_restored_without_tilt_state_tilted_on_a_slope(void)
{
    unsigned pre = 0u;
    uint32_t rng = 17u;
    uint32_t t;
    magcal_cal2d_t saved;
    tc_level_stats_t st;
    TEST_ASSERT_TRUE(tc_drive(1, 60u, 30u, &pre) >= 1u);
    saved = g_cc.cal;
    t = g_cc.last_t + RATE_MS;
    cont_init_default(&saved);
    tc_stand_at(5.0, &rng, &t, 0, &st);
    printf("restored without tilt state, on a 5-deg slope: %u headings TILTED (RMS %.2f deg), %u OK (worst %.2f "
           "deg), %u other\n",
           st.n_tilted, st.n_tilted != 0u ? sqrt(st.ss_tilted / (double)st.n_tilted) : 0.0, st.n_ok, st.worst_ok,
           st.n_other);
    TEST_ASSERT_TRUE(st.n_tilted >= 5u);
    TEST_ASSERT_TRUE(sqrt(st.ss_tilted / (double)st.n_tilted) >= 3.0); /* the flag was warranted */
    TEST_ASSERT_TRUE(st.worst_ok <= 2.0);                              /* an OK is within the tolerance */
}

/* The same restored calibration (no field model, no tilt state) through the hilly drive, then a
 * hard-iron step of (8, -5) uT (0.45 R) on the circles over hills: the hills are no change (0
 * before the step), the step is one, declared within two circles, and relearned: the end
 * calibration is within 1 deg RMS of the truth after the step at level. */
static void test_cont_restored_calibration_step_still_detected(void)
{
    const double d2r = 3.14159265358979 / 180.0;
    unsigned pre = 0u, c, i, k;
    unsigned detect_rows = 0u;
    uint32_t rng = 81u;
    uint32_t t;
    magcal_cal2d_t saved;
    double rms_end;
    TEST_ASSERT_TRUE(tc_drive(1, 60u, 30u, &pre) >= 1u);
    saved = g_cc.cal;
    (void)tc_drive_from(&saved, 1, 60u, 30u, &pre);
    TEST_ASSERT_EQUAL_UINT32(0u, g_cc.changes);
    t = g_cc.last_t + RATE_MS;
    g_tc_step[0] = 8.0;
    g_tc_step[1] = -5.0;
    for (c = 0u; c < 12u; ++c) {
        for (i = 0u; i < TC_ROWS_PER_CIRCLE; ++i, t += RATE_MS) {
            const double psi = 360.0 * ((double)c + (double)i / (double)TC_ROWS_PER_CIRCLE);
            magcal_vec3_t m, g;
            tc_sample(psi, 4.0 * sin(psi * d2r) + 2.0 * cos(psi * d2r), 0.1, &rng, &m, &g);
            TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_push_g(&g_cc, &m, &g, t));
            for (k = 0u; k < STEPS_PER_ROW; ++k) {
                (void)magcal_cont_step(&g_cc);
            }
            if (g_cc.changes == 0u) {
                detect_rows++;
            }
        }
    }
    rms_end = tc_level_rms(&g_cc.cal);
    g_tc_step[0] = 0.0;
    g_tc_step[1] = 0.0;
    printf("restored calibration, then a hard-iron step: %u changes, declared after %u rows (%.2f circles), "
           "generation %u, level RMS after the step %.2f deg\n",
           (unsigned)g_cc.changes, detect_rows, (double)detect_rows / (double)TC_ROWS_PER_CIRCLE,
           (unsigned)g_cc.generation, rms_end);
    TEST_ASSERT_EQUAL_UINT32(1u, g_cc.changes);
    TEST_ASSERT_TRUE(detect_rows <= 2u * TC_ROWS_PER_CIRCLE);
    TEST_ASSERT_TRUE(rms_end <= 1.0);
}

/* The same power cycle with the tilt compensation kept in the record (magcal_cont_tilt_state at
 * the end of the first drive, magcal_cont_restore_tilt after init): the samples are levelled from
 * the first push_g on and the restored calibration counts as levelled, so the hills are not read
 * as a change (0 changes, 0 relevels; restored without it: 1 change, above) and >= 90 % of the
 * headings on the winding road, before any solve, are levelled and OK within 2.5 deg of the
 * truth. Bad input
 * to the restore is refused with its status. */
static void test_cont_restored_tilt_compensation_no_false_change(void)
{
    unsigned pre = 0u;
    magcal_cal2d_t saved;
    float k = 0.0f;
    uint8_t lv = 0u;
    double rms_end;
    TEST_ASSERT_TRUE(tc_drive(1, 60u, 30u, &pre) >= 1u);
    saved = g_cc.cal;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_tilt_state(&g_cc, &k, &lv));
    /* the k kept is the vertical field's, within 15 % of the truth Z_up x sqrt(det W_xy) */
    TEST_ASSERT_TRUE(fabs((double)k - (-44.0 * sqrt(k_tc_w[0][0] * k_tc_w[1][1] - k_tc_w[0][1] * k_tc_w[1][0]))) <=
                     0.15 * 44.0);
    TEST_ASSERT_EQUAL_UINT8(1u, lv);
    {
        magcal_cont_cfg_t cfg = MAGCAL_CONT_CFG_DEFAULT;
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_init(&g_cc, &cfg, NULL, g_slots, SLOTS, g_buf, g_work, sizeof g_work));
        TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_STATE, magcal_cont_restore_tilt(&g_cc, k, 1u)); /* no calibration */
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_init(&g_cc, &cfg, &saved, g_slots, SLOTS, g_buf, g_work, sizeof g_work));
        TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_cont_restore_tilt(&g_cc, NAN, 1u));
        TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_cont_restore_tilt(&g_cc, 0.0f, 1u));
        TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_cont_restore_tilt(&g_cc, k, 2u));
        TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_cont_restore_tilt(&g_cc, 1.0e6f, 1u));
    }
    g_tc_restore_k = k;
    g_tc_restore_levelled = lv;
    {
        /* the first 10 arcs of the road only: before any solve, the restored calibration levelled */
        unsigned ok = 0u, n = 0u;
        double worst = 0.0;
        uint32_t rng = 5u;
        uint32_t t = 0u;
        unsigned c, i;
        (void)tc_drive_from(&saved, 1, 0u, 0u, &pre); /* init + restore only */
        for (c = 0u; c < 10u; ++c) {
            const double th = 10.0 * test_rand_uniform(&rng) - 5.0;
            for (i = 0u; i < TC_ROWS_PER_CIRCLE / 3u; ++i, t += RATE_MS) {
                const double s = (double)i / (double)(TC_ROWS_PER_CIRCLE / 3u);
                const double psi = (c % 2u) == 0u ? 100.0 * s - 50.0 : 50.0 - 100.0 * s;
                magcal_vec3_t m, g;
                magcal_cont_heading_t hd;
                tc_sample(psi, th, 0.1, &rng, &m, &g);
                TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_push_g(&g_cc, &m, &g, t));
                (void)magcal_cont_step(&g_cc);
                TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_heading(&g_cc, &m, 0.0f, &hd));
                if (i >= 25u) { /* the gravity smoothing settled at this arc's pitch */
                    n++;
                    if (hd.trust == MAGCAL_TRUST_OK) {
                        ok++;
                        TEST_ASSERT_EQUAL_UINT8(1u, hd.levelled);
                        worst = fmax(worst, fabs(test_angle_diff_deg(hd.heading_deg, psi)));
                    }
                }
            }
        }
        printf("restored with its tilt compensation (k %.2f, levelled %u): on the road %u of %u headings OK, "
               "worst %.2f deg\n", (double)k, (unsigned)lv, ok, n, worst);
        TEST_ASSERT_TRUE(ok >= (n * 9u) / 10u);
        TEST_ASSERT_TRUE(worst <= 2.5); /* measured 1.96 (k -42.5 for -44.1, the soft iron's anisotropy) */
        TEST_ASSERT_EQUAL_UINT32(0u, g_cc.changes);
    }
    (void)tc_drive_from(&saved, 1, 60u, 30u, &pre);
    g_tc_restore_k = 0.0f;
    g_tc_restore_levelled = 0u;
    rms_end = tc_level_rms(&g_cc.cal);
    printf("restored with its tilt compensation, the whole hilly drive: %u relevels, %u changes, cal_lv %u, "
           "level RMS at the end %.2f deg\n", (unsigned)g_cc.relevels, (unsigned)g_cc.changes,
           (unsigned)g_cc.cal_lv, rms_end);
    TEST_ASSERT_EQUAL_UINT32(0u, g_cc.relevels);
    TEST_ASSERT_EQUAL_UINT32(0u, g_cc.changes);
    TEST_ASSERT_EQUAL_UINT8(1u, g_cc.cal_lv);
    TEST_ASSERT_TRUE(rms_end <= 1.0);
}

/* A hard-iron step before any calibration (issue 13, the 30-min drive seed 1 case): the first
 * installation is seen over 250 deg (below the solve's coverage), the centre then moves by
 * (12, -7) (46 % of the radius) and the vehicle turns back over the same headings and 60 deg
 * beyond, so the store holds both. Every calibration adopted after the step is accurate on the
 * current installation (< 1 deg RMS on the truth: the store's bins replace their oldest samples
 * as headings are revisited, and the solver's consistency gate refuses a store where the two
 * rings still compete: INCONSISTENT, the loop then drops the older half and solves again), and
 * one is adopted within 720 deg of turning after the step. */
void test_cont_store_of_two_installations_adopts_current(void)
{
    drive_t dr;
    unsigned i;
    double turn_at_step;
    cont_init_default(NULL);
    drive_init(&dr, &k_d, 21u);
    drive_straight(&dr, 5u); /* 5 s straight */
    drive_turn(&dr, 250.0, 15.0);
    drive_straight(&dr, 20u);
    TEST_ASSERT_EQUAL_UINT(0u, dr.adopted);
    dr.d = &k_d_step; /* the magnet: the hard iron moves */
    turn_at_step = dr.turn_deg;
    drive_straight(&dr, 20u);
    for (i = 0u; i < 310u + 720u && dr.adopted == 0u; ++i) { /* back over the same headings, on */
        drive_turn(&dr, -1.0, 15.0);
    }
    TEST_ASSERT_TRUE(dr.adopted >= 1u);
    printf("two installations in the store: first adoption %.0f deg of turning after the step, %u solves, "
           "truth RMS %.3f deg (the first installation's truth: %.2f deg)\n",
           dr.turn_at_first - turn_at_step, (unsigned)g_cc.solves, truth_rms(&g_cc.cal, &k_d_step),
           truth_rms(&g_cc.cal, &k_d));
    TEST_ASSERT_TRUE(truth_rms(&g_cc.cal, &k_d_step) < 1.0);
    TEST_ASSERT_TRUE(dr.turn_at_first - turn_at_step <= 720.0);
}

/* ------------------------------------------------------------------ arc stage (an ellipse below 270 deg) */
/* (the drive and its stats: stage_drive, stage 2, next to the coarse stage's above) */

/* Known hard iron (12, -7), soft iron none / mild / strong, arcs of 200 / 230 / 260 deg x 8 seeds,
 * noise 0.15 (0.5 % of R): no model error in these data, so the model term is 0 and the
 * covariance part of the bound alone must cover the truth over the whole circle. */
void test_cont_arc_bound_covers_truth_on_arcs(void)
{
    static const test_distortion_t ds[3] = {{30.0f, {{1.00f, 0.00f}, {0.00f, 1.00f}}, 12.0f, -7.0f},
                                            {30.0f, {{1.03f, 0.02f}, {0.02f, 0.97f}}, 12.0f, -7.0f},
                                            {30.0f, {{1.10f, 0.05f}, {0.05f, 0.90f}}, 12.0f, -7.0f}};
    static const double arcs[3] = {200.0, 230.0, 260.0};
    unsigned adopted = 0u;
    double worst = 1.0e9;
    size_t k;
    size_t a;
    uint32_t seed;
    for (k = 0u; k < 3u; ++k) {
        for (a = 0u; a < 3u; ++a) {
            for (seed = 1u; seed <= 8u; ++seed) {
                drive_t dr;
                stage_stats_t as;
                memset(&as, 0, sizeof as);
                stage_init(2u, 180.0f, 4.0f);
                drive_init(&dr, &ds[k], seed);
                dr.psi = 47.0 * (double)seed;
                stage_drive(2u, &dr, arcs[a], &as);
                printf("arc: soft iron %zu arc %3.0f seed %u: %u arc adoptions, %u refused; first after %.0f deg: "
                       "bound %.3f deg, truth %.3f deg\n",
                       k, arcs[a], (unsigned)seed, as.adopted, as.refused, as.turn, as.bound, as.truth);
                adopted += as.adopted != 0u ? 1u : 0u;
                if (as.adopted != 0u) {
                    worst = fmin(worst, as.worst_margin);
                    TEST_ASSERT_TRUE(as.turn <= arcs[a] + 1.0e-6); /* within the arc: before 270 deg were seen */
                }
                TEST_ASSERT_TRUE(as.adopted <= 1u); /* an arc never replaces an arc */
            }
        }
    }
    printf("arc: %u of 72 runs adopted an arc, worst margin bound - truth %.3f deg\n", adopted, worst);
    TEST_ASSERT_TRUE(adopted >= 48u); /* the stage delivers, not refuses everything */
}

/* The same arcs against a tolerance the bound cannot meet (0.05 deg): every arc solve is refused
 * UNOBSERVABLE with the bound reported above it, nothing installed, headings uncalibrated. */
void test_cont_arc_refused_when_bound_too_wide(void)
{
    uint32_t seed;
    unsigned refused = 0u;
    for (seed = 1u; seed <= 3u; ++seed) {
        drive_t dr;
        stage_stats_t as;
        magcal_cont_heading_t hd;
        const magcal_cal2d_t id = MAGCAL_CAL2D_IDENTITY;
        magcal_vec3_t m = {10.0f, 20.0f, 40.0f};
        memset(&as, 0, sizeof as);
        stage_init(2u, 180.0f, 0.05f);
        drive_init(&dr, &k_d, seed);
        dr.psi = 47.0 * (double)seed;
        stage_drive(2u, &dr, 230.0, &as);
        printf("arc, tolerance 0.05 deg, seed %u: %u arc adoptions, %u refused (last bound %.3f deg)\n",
               (unsigned)seed, as.adopted, as.refused, (double)g_cc.last.est_param_err_deg);
        TEST_ASSERT_EQUAL_UINT(0u, as.adopted);
        TEST_ASSERT_EQUAL_UINT32(0u, g_cc.generation);
        TEST_ASSERT_EQUAL_MEMORY(&id, &g_cc.cal, sizeof id); /* untouched */
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_heading(&g_cc, &m, 0.0f, &hd));
        TEST_ASSERT_EQUAL_INT(MAGCAL_TRUST_UNCALIBRATED, hd.trust);
        refused += as.refused;
    }
    TEST_ASSERT_TRUE(refused >= 3u); /* the stage ran and said why */
}

/* An arc calibration on 230 deg, then the rest of the circle: the full ellipse replaces it
 * (never worse on the truth: drive_row checks every adoption), headings OK, the stage off. */
void test_cont_arc_upgraded_by_full_ellipse(void)
{
    drive_t dr;
    stage_stats_t as;
    magcal_cont_heading_t hd;
    magcal_vec3_t m = {0.0f, 0.0f, 40.0f};
    magcal_vec2_t p;
    memset(&as, 0, sizeof as);
    stage_init(2u, 180.0f, 4.0f);
    drive_init(&dr, &k_d, 5u);
    stage_drive(2u, &dr, 230.0, &as);
    TEST_ASSERT_EQUAL_UINT(1u, as.adopted);
    stage_drive(2u, &dr, 360.0, &as);
    printf("arc then full: arc bound %.3f truth %.3f deg after %.0f deg; full after %.0f deg, truth %.3f deg, "
           "%u adoptions\n", as.bound, as.truth, as.turn, dr.turn_deg, truth_rms(&g_cc.cal, &k_d), dr.adopted);
    TEST_ASSERT_EQUAL_UINT8(0u, g_cc.cal_coarse);
    TEST_ASSERT_TRUE(dr.adopted >= 2u);
    TEST_ASSERT_TRUE(truth_rms(&g_cc.cal, &k_d) <= 1.0);
    p = test_distorted_sample(&k_d, dr.psi, 0.0, &dr.rng);
    m.x = p.x;
    m.y = p.y;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_heading(&g_cc, &m, 0.0f, &hd));
    TEST_ASSERT_EQUAL_INT(MAGCAL_TRUST_OK, hd.trust);
    TEST_ASSERT_EQUAL_FLOAT(0.0f, g_cc.solver.arc_min_cov); /* a calibration installed: off */
}

void test_cont_arc_cfg_checked(void)
{
    magcal_cont_cfg_t cfg = MAGCAL_CONT_CFG_DEFAULT;
    TEST_ASSERT_EQUAL_FLOAT(0.0f, cfg.arc_coverage_deg); /* opt-in (docs/calibrator.md "Arc stage") */
    cfg.arc_coverage_deg = 180.0f;
    cfg.arc_max_err_deg = 0.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_cont_init(&g_cc, &cfg, NULL, g_slots, SLOTS, g_buf, g_work, sizeof g_work));
    cfg.arc_max_err_deg = 10.0f;
    cfg.arc_model_deg = -1.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_cont_init(&g_cc, &cfg, NULL, g_slots, SLOTS, g_buf, g_work, sizeof g_work));
    cfg.arc_model_deg = NAN;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_cont_init(&g_cc, &cfg, NULL, g_slots, SLOTS, g_buf, g_work, sizeof g_work));
    cfg.arc_model_deg = 7.0f;
    cfg.arc_coverage_deg = 300.0f; /* above solve_coverage_deg (280) */
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_cont_init(&g_cc, &cfg, NULL, g_slots, SLOTS, g_buf, g_work, sizeof g_work));
    cfg.arc_coverage_deg = 180.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_init(&g_cc, &cfg, NULL, g_slots, SLOTS, g_buf, g_work, sizeof g_work));
    TEST_ASSERT_EQUAL_FLOAT(180.0f, g_cc.solver.arc_min_cov);
}

/* ------------------------------------------------------------------ level shift (before any calibration) */

/* The consistency gate's known gap in stream form (docs/calibrator.md "Consistency gate", "Level
 * shift"): the first installation seen over 0..170 deg, then a magnet (the hard iron moves by 46 %
 * of the radius) while driving straight, and the second installation over 150..300 deg and on round
 * to 140 deg (350 deg of it). With the watch (default): exactly one shift, declared at the step's
 * row + cfg.shift_hold_ms; nothing is adopted before it; every adoption is accurate on the second
 * installation's truth (< 1 deg RMS) and one comes within 720 deg of turning after the step. With
 * the watch off (cfg.shift_rel 0) the same stream is measured and printed, not asserted. */
static void shift_gap_drive(float shift_rel, unsigned *shifts, unsigned *adopted, double *worst_d2, double *turn_after)
{
    drive_t dr;
    unsigned i;
    double turn_at_step;
    magcal_cont_cfg_t cfg = MAGCAL_CONT_CFG_DEFAULT;
    cfg.shift_rel = shift_rel;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_init(&g_cc, &cfg, NULL, g_slots, SLOTS, g_buf, g_work, sizeof g_work));
    drive_init(&dr, &k_d, 23u);
    *worst_d2 = 0.0;
    drive_straight(&dr, 5u);
    drive_turn(&dr, 170.0, 15.0);
    drive_straight(&dr, 10u);
    TEST_ASSERT_EQUAL_UINT(0u, dr.adopted);
    dr.d = &k_d_step; /* the magnet */
    turn_at_step = dr.turn_deg;
    drive_straight(&dr, 10u);
    drive_turn(&dr, -20.0, 15.0);
    for (i = 0u; i < 150u + 200u; ++i) {
        drive_turn(&dr, 1.0, 15.0);
        if (dr.adopted != 0u) {
            *worst_d2 = fmax(*worst_d2, truth_rms(&g_cc.cal, &k_d_step));
        }
    }
    *shifts = (unsigned)g_cc.shifts;
    *adopted = dr.adopted;
    *turn_after = dr.turn_at_first >= 0.0 ? dr.turn_at_first - turn_at_step : -1.0;
}

void test_cont_shift_before_first_calibration_cuts_the_store(void)
{
    unsigned shifts, adopted, shifts_off, adopted_off;
    double worst, worst_off, turn, turn_off;
    shift_gap_drive(0.0f, &shifts_off, &adopted_off, &worst_off, &turn_off);
    shift_gap_drive(0.25f, &shifts, &adopted, &worst, &turn);
    printf("level shift before any calibration: watch on: %u shift, %u adoptions, first %.0f deg after the "
           "step, worst truth RMS %.3f deg (refused for the shift: %u); watch off: %u adoptions, first %.0f deg "
           "after, worst %.3f deg\n",
           shifts, adopted, turn, worst, (unsigned)g_cc.shift_refused, adopted_off, turn_off, worst_off);
    TEST_ASSERT_EQUAL_UINT(0u, shifts_off);
    TEST_ASSERT_EQUAL_UINT(1u, shifts);
    TEST_ASSERT_TRUE(adopted >= 1u);
    TEST_ASSERT_TRUE(worst < 1.0);
    TEST_ASSERT_TRUE(turn > 0.0 && turn <= 720.0);
}

/* The magnet attached while the sensor is saturated (30-min drive seed 10: the hard-iron step
 * came inside a 33-row burst of the y axis at the rail while parked): the first installation over
 * 0..170 deg, parked, 33 rows with y stuck at -800 with the step after the second, parked again,
 * then the second installation on round as in shift_gap_drive. The watch bridges the burst (the
 * jump across it is more than a turn at 45 deg/s could make in 0.66 s): one shift, no adoption
 * before it, and every adoption accurate on the second installation (< 1 deg RMS). Without the
 * bridge the burst broke the chain: no shift, and on seed 10 a solve on both rings adopted a
 * calibration 19 deg off. */
void test_cont_shift_inside_a_rail_burst(void)
{
    drive_t dr;
    unsigned i;
    double worst = 0.0;
    cont_init_default(NULL);
    drive_init(&dr, &k_d, 23u);
    drive_straight(&dr, 5u);
    drive_turn(&dr, 170.0, 15.0);
    drive_straight(&dr, 10u);
    TEST_ASSERT_EQUAL_UINT(0u, dr.adopted);
    for (i = 0u; i < 33u; ++i) {
        if (i == 2u) {
            dr.d = &k_d_step; /* the magnet, inside the burst */
        }
        {
            const magcal_vec2_t p = test_distorted_sample(dr.d, dr.psi, 0.0, &dr.rng);
            (void)drive_row(&dr, 0.0f, -800.0f - p.y); /* y at the rail */
        }
    }
    drive_straight(&dr, 10u);
    drive_turn(&dr, -20.0, 15.0);
    for (i = 0u; i < 150u + 200u; ++i) {
        drive_turn(&dr, 1.0, 15.0);
        if (dr.adopted != 0u) {
            worst = fmax(worst, truth_rms(&g_cc.cal, &k_d_step));
        }
    }
    printf("step inside a rail burst: %u shifts, %u adoptions, worst truth RMS %.3f deg (refused for the "
           "shift: %u)\n",
           (unsigned)g_cc.shifts, dr.adopted, worst, (unsigned)g_cc.shift_refused);
    TEST_ASSERT_EQUAL_UINT32(1u, g_cc.shifts);
    TEST_ASSERT_TRUE(dr.adopted >= 1u);
    TEST_ASSERT_TRUE(worst < 1.0);
}

/* What is not a shift: a stepped transient (+30 % of the field for 3 s: a jump out and one back),
 * glitch bursts (the LSM9DS1 driver's: the y axis stuck far off for 12 samples while x moves; a
 * single-sample spike; a garbage reading 30x the field) and a fast turn (90 deg/s: every increment
 * large, none isolated). No shift is declared, no solve refused for one, and the first
 * adoption is accurate (< 1 deg RMS on the truth). */
void test_cont_shift_not_declared_for_glitches_transients_and_turns(void)
{
    drive_t dr;
    unsigned i, k;
    cont_init_default(NULL);
    drive_init(&dr, &k_d, 29u);
    drive_turn(&dr, 90.0, 15.0);
    for (k = 0u; k < 3u; ++k) {
        for (i = 0u; i < 3u * 50u; ++i) {
            (void)drive_row(&dr, 0.0f, 9.0f); /* stepped transient */
        }
        for (i = 0u; i < 12u; ++i) {
            dr.psi = fmod(dr.psi + 0.3, 360.0);
            dr.turn_deg += 0.3;
            (void)drive_row(&dr, 0.0f, -300.0f - (float)dr.psi + (float)i * 0.0f); /* y stuck far off */
        }
        (void)drive_row(&dr, 1000.0f, 0.0f); /* spike */
        (void)drive_row(&dr, 0.0f, 0.0f);
        drive_turn(&dr, 90.0, 90.0); /* fast */
        drive_turn(&dr, 40.0, 15.0);
    }
    drive_turn(&dr, 360.0, 15.0);
    printf("glitches, stepped transients and fast turns: %u shifts, %u refused for one, %u adoptions, truth RMS "
           "%.3f deg\n",
           (unsigned)g_cc.shifts, (unsigned)g_cc.shift_refused, dr.adopted, truth_rms(&g_cc.cal, &k_d));
    TEST_ASSERT_EQUAL_UINT32(0u, g_cc.shifts);
    TEST_ASSERT_EQUAL_UINT32(0u, g_cc.shift_refused);
    TEST_ASSERT_TRUE(dr.adopted >= 1u);
    TEST_ASSERT_TRUE(truth_rms(&g_cc.cal, &k_d) < 1.0);
}

/* The watch's configuration: shift_rel 0 (off) or 0.15..2, finite; shift_hold_ms >= 1. */
void test_cont_shift_cfg_checked(void)
{
    magcal_cont_cfg_t cfg = MAGCAL_CONT_CFG_DEFAULT;
    TEST_ASSERT_EQUAL_FLOAT(0.25f, cfg.shift_rel);
    TEST_ASSERT_EQUAL_UINT32(6000u, cfg.shift_hold_ms);
    cfg.shift_rel = NAN;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_cont_init(&g_cc, &cfg, NULL, g_slots, SLOTS, g_buf, g_work, sizeof g_work));
    cfg.shift_rel = 0.1f; /* below a single jump's threshold (0.15 R) */
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_cont_init(&g_cc, &cfg, NULL, g_slots, SLOTS, g_buf, g_work, sizeof g_work));
    cfg.shift_rel = 2.5f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_cont_init(&g_cc, &cfg, NULL, g_slots, SLOTS, g_buf, g_work, sizeof g_work));
    cfg.shift_rel = -0.25f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_cont_init(&g_cc, &cfg, NULL, g_slots, SLOTS, g_buf, g_work, sizeof g_work));
    cfg.shift_rel = 0.25f;
    cfg.shift_hold_ms = 0u;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_cont_init(&g_cc, &cfg, NULL, g_slots, SLOTS, g_buf, g_work, sizeof g_work));
    cfg.shift_hold_ms = 1u;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_init(&g_cc, &cfg, NULL, g_slots, SLOTS, g_buf, g_work, sizeof g_work));
    cfg.shift_rel = 0.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_init(&g_cc, &cfg, NULL, g_slots, SLOTS, g_buf, g_work, sizeof g_work));
}

/* ------------------------------------------------------------------ continuity gate (opt-in) */

/* A vehicle parked at start (one bin of field) through a driver's garbage burst (30 readings
 * uniform in +-600, the generated drives' kind), then driven round twice. With the gate on
 * (cfg.continuity 1): the burst never reaches the store (>= 30 samples refused), a calibration is
 * adopted and it is accurate (< 1 deg RMS on the truth). Off (the default): measured and printed
 * (measured: one adoption at 0.032 deg, the survey kept its centre here; on the 60-min seed-7
 * drive, 8 minutes parked, it locked on the garbage: docs/calibrator.md "Continuity gate"). */
static void cg_drive(uint8_t on, unsigned *adopted, double *rms, uint32_t *refused, float *radius)
{
    drive_t dr;
    unsigned i;
    uint32_t g = 99u;
    magcal_cont_cfg_t cfg = MAGCAL_CONT_CFG_DEFAULT;
    cfg.continuity = on;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_init(&g_cc, &cfg, NULL, g_slots, SLOTS, g_buf, g_work, sizeof g_work));
    drive_init(&dr, &k_d, 37u);
    drive_straight(&dr, 60u);
    for (i = 0u; i < 30u; ++i) {
        const float gx = (float)(1200.0 * test_rand_uniform(&g) - 600.0);
        const float gy = (float)(1200.0 * test_rand_uniform(&g) - 600.0);
        (void)drive_row(&dr, gx, gy); /* the garbage (the field is small beside it) */
    }
    drive_straight(&dr, 60u);
    drive_turn(&dr, 720.0, 15.0);
    *adopted = dr.adopted;
    *rms = dr.adopted != 0u ? truth_rms(&g_cc.cal, &k_d) : NAN;
    *refused = g_cc.cg_refused;
    *radius = g_cc.store.radius;
}

void test_cont_continuity_gate_keeps_garbage_out(void)
{
    unsigned ad_off, ad_on;
    double rms_off, rms_on;
    uint32_t ref_off, ref_on;
    float r_off, r_on;
    cg_drive(0u, &ad_off, &rms_off, &ref_off, &r_off);
    cg_drive(1u, &ad_on, &rms_on, &ref_on, &r_on);
    printf("parked start through a garbage burst, then 720 deg: gate off: %u adoptions, truth RMS %.3f deg, store "
           "radius %.1f; gate on: %u refused, %u adoptions, truth RMS %.3f deg, store radius %.1f\n",
           ad_off, rms_off, (double)r_off, (unsigned)ref_on, ad_on, rms_on, (double)r_on);
    TEST_ASSERT_EQUAL_UINT32(0u, ref_off);
    TEST_ASSERT_TRUE(ref_on >= 30u);
    TEST_ASSERT_TRUE(ad_on >= 1u);
    TEST_ASSERT_TRUE(rms_on < 1.0);
}

/* ------------------------------------------------------------------ tilt in the estimate */

/* Circles on a constant 5-degree slope (the vertical field cannot be learnt from one tilt, so
 * nothing is levelled and every stored sample is TILTED under push_g): the first adoption's
 * est_param_err_deg carries cfg.tilt_model_deg x the snapshot's tilted share (about 1: >= 4.0 deg
 * of the 4.5 default); fed without gravity (push: nothing known of the tilt) or with the term off
 * (cfg.tilt_model_deg 0) the same drive's estimate stays the fit's own (< 1.5 deg). The truth at
 * level is printed (the slope's leak is a constant body-frame offset the ellipse takes for hard
 * iron), not asserted against the estimate. */
/* cfg.tilt_model_deg: finite, >= 0 */
static void cfg_tilt_model_checked(void)
{
    magcal_cont_cfg_t cfg = MAGCAL_CONT_CFG_DEFAULT;
    TEST_ASSERT_EQUAL_FLOAT(4.5f, cfg.tilt_model_deg);
    cfg.tilt_model_deg = -1.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_cont_init(&g_cc, &cfg, NULL, g_slots, SLOTS, g_buf, g_work, sizeof g_work));
    cfg.tilt_model_deg = INFINITY;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_cont_init(&g_cc, &cfg, NULL, g_slots, SLOTS, g_buf, g_work, sizeof g_work));
}

static double tilt_slope_est(int with_g, float model_deg, double *truth)
{
    magcal_cont_cfg_t cfg = MAGCAL_CONT_CFG_DEFAULT;
    uint32_t rng = 91u;
    uint32_t t = 0u;
    unsigned i, k;
    double est = NAN;
    cfg.tilt_model_deg = model_deg;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_init(&g_cc, &cfg, NULL, g_slots, SLOTS, g_buf, g_work, sizeof g_work));
    for (i = 0u; i < 3u * TC_ROWS_PER_CIRCLE && isnan(est); ++i, t += RATE_MS) {
        magcal_vec3_t m, g;
        tc_sample(360.0 * (double)i / (double)TC_ROWS_PER_CIRCLE, 5.0, 0.1, &rng, &m, &g);
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, with_g != 0 ? magcal_cont_push_g(&g_cc, &m, &g, t) : magcal_cont_push(&g_cc, &m, t));
        for (k = 0u; k < STEPS_PER_ROW; ++k) {
            if (magcal_cont_step(&g_cc) == MAGCAL_CONT_ADOPTED) {
                est = (double)g_cc.last.est_param_err_deg;
            }
        }
    }
    *truth = isnan(est) ? NAN : tc_level_rms(&g_cc.cal);
    return est;
}

static void test_cont_tilt_share_in_the_estimate(void)
{
    double t_g, t_n, t_off;
    const double e_g = tilt_slope_est(1, 4.5f, &t_g);
    const double e_n = tilt_slope_est(0, 4.5f, &t_n);
    const double e_off = tilt_slope_est(1, 0.0f, &t_off);
    printf("5-deg slope: estimate with gravity %.2f deg (true level error %.2f), without %.2f (%.2f), term off "
           "%.2f (%.2f)\n", e_g, t_g, e_n, t_n, e_off, t_off);
    TEST_ASSERT_TRUE(e_g >= 4.0);
    TEST_ASSERT_TRUE(e_n < 1.5);
    TEST_ASSERT_TRUE(e_off < 1.5);
    cfg_tilt_model_checked();
}

int main(void)
{
#if defined(__arm__)
    SYST_RVR = 0xFFFFFFu;
    SYST_CVR = 0u;
    SYST_CSR = 5u; /* enable, processor clock */
#endif
    UNITY_BEGIN();
    RUN_TEST(test_cont_init_bad_args_refused);
    RUN_TEST(test_cont_stream_first_adoption_accurate);
    RUN_TEST(test_cont_failed_solve_not_sticky);
    RUN_TEST(test_cont_ageing_replaces_mildly_worse);
    RUN_TEST(test_cont_hard_iron_step_relearned);
    RUN_TEST(test_cont_transient_flagged_not_discarded);
    RUN_TEST(test_cont_transient_turning_the_heading_stays_flagged);
    RUN_TEST(test_cont_gyro_flags_a_disturbance_across_the_field);
    RUN_TEST(test_cont_gyro_glitch_is_no_disturbance);
    RUN_TEST(test_cont_sliced_solve_matches_blocking);
    RUN_TEST(test_cont_sliced_field_fit_matches_unlimited);
    RUN_TEST(test_cont_coarse_cfg_checked);
    RUN_TEST(test_cont_coarse_bound_covers_truth_on_arcs);
    RUN_TEST(test_cont_coarse_refused_when_soft_iron_exceeds_tolerance);
    RUN_TEST(test_cont_coarse_upgraded_by_full_ellipse);
    RUN_TEST(test_cont_store_of_two_installations_adopts_current);
#ifdef CONT_TEST_THREADS
    RUN_TEST(test_cont_isr_push_interleaved_with_task);
#endif
#if defined(__arm__)
    printf("largest call, SysTick ticks (x 40 = instructions under -icount shift=0): push %lu, step %lu\n",
           (unsigned long)g_tmax[0], (unsigned long)g_tmax[1]);
#endif
    RUN_TEST(test_cont_push_g_classifies_level_tilted_and_braking);
    RUN_TEST(test_cont_push_g_tilt_compensation_levels_the_store);
    RUN_TEST(test_cont_heading_levelled_on_hills);
    RUN_TEST(test_cont_push_g_acceleration_is_not_tilt);
    RUN_TEST(test_cont_unlevelled_calibration_tilted_then_levelled);
    RUN_TEST(test_cont_relevelled_calibration_judged_levelled);
    RUN_TEST(test_cont_bent_store_calibration_not_trusted);
    RUN_TEST(test_cont_turns_under_acceleration_keep_the_fit_tilt);
    RUN_TEST(test_cont_restored_calibration_relevelled);
    RUN_TEST(test_cont_restored_without_tilt_state_tilted_on_a_slope);
    RUN_TEST(test_cont_restored_calibration_step_still_detected);
    RUN_TEST(test_cont_restored_tilt_compensation_no_false_change);
    RUN_TEST(test_cont_arc_bound_covers_truth_on_arcs);
    RUN_TEST(test_cont_arc_refused_when_bound_too_wide);
    RUN_TEST(test_cont_arc_upgraded_by_full_ellipse);
    RUN_TEST(test_cont_arc_cfg_checked);
    RUN_TEST(test_cont_shift_cfg_checked);
    RUN_TEST(test_cont_shift_before_first_calibration_cuts_the_store);
    RUN_TEST(test_cont_shift_inside_a_rail_burst);
    RUN_TEST(test_cont_shift_not_declared_for_glitches_transients_and_turns);
    RUN_TEST(test_cont_continuity_gate_keeps_garbage_out);
    RUN_TEST(test_cont_tilt_share_in_the_estimate);
    return UNITY_END();
}
