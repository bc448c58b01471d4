/*
 * Tests of the gyro-aided gravity of magcal_cont_push_imu (include/magcal/continuous.h
 * "Gyro-aided gravity", src/loop/cont_grav.c), against known truth. A vehicle (body x right,
 * y forward, z up; specific force (0, 0, 1) g level at rest) with a gyro whose bias is
 * (0.3, -0.4, 0.2) deg/s and 0.1 deg/s of noise, an accelerometer with 0.01 g of noise, 50 Hz:
 * parked 40 s on a 3-deg slope, the nose brought level in 3 s, a 60-s circle at 15 deg/s under
 * 0.2 g of centripetal acceleration (11.3 deg of apparent roll), braking at 0.15 g on a straight
 * (8.5 deg of apparent pitch), then a 4-deg hill climbed in 4 s. The truth is the attitude's up
 * vector; the estimate is cc.ga_u, and what push_g levels with is its smoothed gravity cc.g_s.
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
#define DT 0.02
#define D2R 0.017453292519943295

static magcal_intake_slot_t g_slots[SLOTS];
static magcal_vec2_t g_buf[SLOTS];
static MAGCAL_CALIBRATOR_WORKSPACE_DECLARE(g_work, SLOTS);
static magcal_cont_t g_cc;

static const double k_bias[3] = {0.3 * D2R, -0.4 * D2R, 0.2 * D2R};

typedef struct {
    uint32_t t_ms;
    uint32_t rng;
    double pitch;     /* deg, about body x (roll 0 throughout) */
    double psi;       /* heading, deg */
    double worst_est; /* worst angle of cc.ga_u from the truth over the phase, deg */
    double worst_gs;  /* the same for push_g's smoothed gravity cc.g_s */
    double worst_acc; /* and for the accelerometer */
    unsigned rows;    /* rows of the phase */
    unsigned quiet;   /* of them with cc.ga_quiet (the tilt compensation's k may learn) */
} gv_t;

static double gv_angle(double ux, double uy, double uz, double vx, double vy, double vz)
{
    const double c = (ux * vx + uy * vy + uz * vz) /
                     (sqrt(ux * ux + uy * uy + uz * uz) * sqrt(vx * vx + vy * vy + vz * vz));
    return acos(c > 1.0 ? 1.0 : (c < -1.0 ? -1.0 : c)) / D2R;
}

/* One row: the pitch and heading move at dpitch, dpsi deg/s; the accelerometer reads the car's
 * acceleration (lat, lon) g too. rate_glitch: the x rate of this row (deg/s) replaces the true one. */
static void gv_row(gv_t *s, double dpitch, double dpsi, double lat, double lon, double rate_glitch)
{
    magcal_vec3_t m, g, w;
    double up[3];
    s->pitch += dpitch * DT;
    s->psi += dpsi * DT;
    up[0] = 0.0;
    up[1] = sin(s->pitch * D2R);
    up[2] = cos(s->pitch * D2R);
    /* the field turns with the heading (a calibrated level sensor; the gravity test needs no more) */
    m.x = (float)(30.0 * cos(s->psi * D2R));
    m.y = (float)(30.0 * sin(s->psi * D2R));
    m.z = -40.0f;
    g.x = (float)(up[0] + lat + 0.01 * test_rand_normal(&s->rng));
    g.y = (float)(up[1] + lon + 0.01 * test_rand_normal(&s->rng));
    g.z = (float)(up[2] + 0.01 * test_rand_normal(&s->rng));
    /* body rates: the pitch about x (du/dt = u x w gives w_x = d pitch / dt), the heading about up */
    w.x = (float)((rate_glitch != 0.0 ? rate_glitch : dpitch) * D2R + k_bias[0] + 0.1 * D2R * test_rand_normal(&s->rng));
    w.y = (float)(dpsi * D2R * up[1] + k_bias[1] + 0.1 * D2R * test_rand_normal(&s->rng));
    w.z = (float)(dpsi * D2R * up[2] + k_bias[2] + 0.1 * D2R * test_rand_normal(&s->rng));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_push_imu(&g_cc, &m, &g, &w, s->t_ms));
    (void)magcal_cont_step(&g_cc);
    s->t_ms += RATE_MS;
    s->worst_est = fmax(s->worst_est, gv_angle(g_cc.ga_u.x, g_cc.ga_u.y, g_cc.ga_u.z, up[0], up[1], up[2]));
    s->worst_gs = fmax(s->worst_gs, gv_angle(g_cc.g_s.x, g_cc.g_s.y, g_cc.g_s.z, up[0], up[1], up[2]));
    s->worst_acc = fmax(s->worst_acc, gv_angle(g.x, g.y, g.z, up[0], up[1], up[2]));
    s->rows++;
    s->quiet += (g_cc.ga_quiet != 0u) ? 1u : 0u;
}

static void gv_phase_start(gv_t *s)
{
    s->worst_est = 0.0;
    s->worst_gs = 0.0;
    s->worst_acc = 0.0;
    s->rows = 0u;
    s->quiet = 0u;
}

static void gv_init(gv_t *s, uint8_t gyro_gravity)
{
    magcal_cont_cfg_t cfg = MAGCAL_CONT_CFG_DEFAULT;
    cfg.gyro_gravity = gyro_gravity;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_init(&g_cc, &cfg, NULL, g_slots, SLOTS, g_buf, g_work, sizeof g_work));
    memset(s, 0, sizeof *s);
    s->rng = 4242u;
    s->pitch = 3.0;
    s->t_ms = 1000u;
}

/* Parked 40 s on the slope, then the nose level in 3 s, and 2 s level. */
static void gv_park_and_level(gv_t *s)
{
    unsigned i;
    for (i = 0u; i < 2000u; ++i) {
        gv_row(s, 0.0, 0.0, 0.0, 0.0, 0.0);
    }
    for (i = 0u; i < 150u; ++i) {
        gv_row(s, -1.0, 0.0, 0.0, 0.0, 0.0);
    }
    for (i = 0u; i < 100u; ++i) {
        gv_row(s, 0.0, 0.0, 0.0, 0.0, 0.0); /* 2 s level: push_g's 0.5-s smoothing settles */
    }
}

/* A fresh instance (cfg.gyro_gravity as given) through the park, a phase started after it. */
static void gv_start_level(gv_t *s, uint8_t gyro_gravity)
{
    gv_init(s, gyro_gravity);
    gv_park_and_level(s);
    gv_phase_start(s);
}

static void test_gravity_locks_and_learns_the_bias_parked(void)
{
    gv_t s;
    gv_init(&s, 1u);
    gv_park_and_level(&s);
    printf("parked: lock %u, bias (%.3f, %.3f) deg/s (truth 0.3, -0.4), worst %.2f deg levelling\n",
           (unsigned)g_cc.ga_lock, (double)g_cc.ga_b.x / D2R, (double)g_cc.ga_b.y / D2R, s.worst_est);
    TEST_ASSERT_EQUAL_UINT8(1u, g_cc.ga_lock);
    TEST_ASSERT_FLOAT_WITHIN(0.05f, 0.3f, (float)(g_cc.ga_b.x / D2R));
    TEST_ASSERT_FLOAT_WITHIN(0.05f, -0.4f, (float)(g_cc.ga_b.y / D2R));
    TEST_ASSERT_TRUE(s.worst_est <= 1.0); /* the acquisition from the first sample on */
}

/* The circle under 0.2 g and the braking: the estimate stays with the truth while the accelerometer
 * is 11 deg (8.5 deg) off; push_g's gravity is the estimate's once the accelerometer is more than
 * 1 deg from it (the acceleration ramping in passes through that window: push_g's worst is 1 deg
 * plus the estimate's error). */
static void test_gravity_through_a_turn_and_braking(void)
{
    gv_t s;
    unsigned i;
    gv_start_level(&s, 1u);
    for (i = 0u; i < 3000u; ++i) {
        gv_row(&s, 0.0, 15.0, (i < 50u) ? 0.004 * (double)i : 0.2, 0.0, 0.0);
    }
    printf("circle under 0.2 g: estimate worst %.2f deg, push_g's gravity %.2f, the accelerometer %.2f; "
           "%u of %u rows quiet\n", s.worst_est, s.worst_gs, s.worst_acc, s.quiet, s.rows);
    TEST_ASSERT_TRUE(s.quiet <= 20u); /* k learns from none of the circle (the ramp's first 0.3 deg) */
    TEST_ASSERT_EQUAL_UINT8(1u, g_cc.ga_lock);
    TEST_ASSERT_TRUE(s.worst_acc >= 10.0);
    TEST_ASSERT_TRUE(s.worst_est <= 0.5);
    TEST_ASSERT_TRUE(s.worst_gs <= 1.5); /* measured 0.93 (circle), 1.18 (braking) */
    for (i = 0u; i < 250u; ++i) {
        gv_row(&s, 0.0, 0.0, 0.0, 0.0, 0.0); /* out of the turn: straight, 5 s */
    }
    gv_phase_start(&s);
    for (i = 0u; i < 200u; ++i) {
        gv_row(&s, 0.0, 0.0, 0.0, -0.15 * sin(3.14159265358979 * (double)i / 200.0), 0.0);
    }
    printf("braking at 0.15 g: estimate worst %.2f deg, push_g's gravity %.2f, the accelerometer %.2f\n",
           s.worst_est, s.worst_gs, s.worst_acc);
    TEST_ASSERT_TRUE(s.worst_acc >= 8.0);
    TEST_ASSERT_TRUE(s.worst_est <= 0.5);
    TEST_ASSERT_TRUE(s.worst_gs <= 1.5); /* measured 0.93 (circle), 1.18 (braking) */
    gv_phase_start(&s);
    for (i = 0u; i < 200u; ++i) {
        gv_row(&s, 1.0, 0.0, 0.0, 0.0, 0.0); /* a hill: the gyro sees the pitch */
    }
    for (i = 0u; i < 500u; ++i) {
        gv_row(&s, 0.0, 0.0, 0.0, 0.0, 0.0);
    }
    printf("a 4-deg hill: estimate worst %.2f deg, push_g's gravity %.2f (0.5-s smoothing); %u of %u rows quiet\n",
           s.worst_est, s.worst_gs, s.quiet, s.rows);
    TEST_ASSERT_TRUE(s.quiet >= s.rows / 2u); /* the hill's tilt teaches k */
    TEST_ASSERT_TRUE(s.worst_est <= 0.5);
    TEST_ASSERT_EQUAL_UINT32(0u, g_cc.ga_unlocks);
}

/* Off (cfg.gyro_gravity 0): push_g levels with the accelerometer, as push_g alone would. */
static void test_gravity_off_is_the_accelerometer(void)
{
    gv_t s;
    unsigned i;
    gv_start_level(&s, 0u);
    for (i = 0u; i < 1000u; ++i) {
        gv_row(&s, 0.0, 15.0, 0.2, 0.0, 0.0);
    }
    TEST_ASSERT_EQUAL_UINT8(0u, g_cc.ga_on);
    TEST_ASSERT_TRUE(s.worst_gs >= 10.0);
}

/* A gyro glitch (one sample of 1000 deg/s about x) restarts the estimate unlocked: push_g takes
 * the accelerometer's gravity until it has locked again, and nothing of the glitch's rotation
 * is left in the estimate. */
static void test_gravity_gyro_glitch_restarts(void)
{
    gv_t s;
    unsigned i;
    gv_init(&s, 1u);
    gv_park_and_level(&s);
    TEST_ASSERT_EQUAL_UINT8(1u, g_cc.ga_lock);
    gv_row(&s, 0.0, 0.0, 0.0, 0.0, 1000.0);
    TEST_ASSERT_EQUAL_UINT8(0u, g_cc.ga_lock);
    gv_phase_start(&s);
    for (i = 0u; i < 1600u; ++i) {
        gv_row(&s, 0.0, 0.0, 0.0, 0.0, 0.0);
    }
    printf("after a gyro glitch: lock %u again after 32 s, worst %.2f deg\n", (unsigned)g_cc.ga_lock, s.worst_est);
    TEST_ASSERT_EQUAL_UINT8(1u, g_cc.ga_lock);
    TEST_ASSERT_TRUE(s.worst_est <= 1.0);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_gravity_locks_and_learns_the_bias_parked);
    RUN_TEST(test_gravity_through_a_turn_and_braking);
    RUN_TEST(test_gravity_off_is_the_accelerometer);
    RUN_TEST(test_gravity_gyro_glitch_restarts);
    return UNITY_END();
}
