/*
 * Continuous calibrator, gravity under the vehicle's acceleration (continuous.h "Gyro-aided
 * gravity", docs/calibrator.md). An accelerometer in a car reads the car's own acceleration
 * too: a turn's centripetal acceleration reads as roll, braking as pitch, and the tilt that
 * levels the samples and judges their trust is then wrong by degrees (0.2 g: 11 deg). With the
 * gyro of magcal_cont_push_imu the direction of gravity is carried by the body rates and pulled
 * towards the accelerometer only where it reads gravity alone: a complementary filter on the
 * up vector with the gyro's bias as its integral (a Mahony filter without the heading). The
 * accelerometer pulls only when its smoothed magnitude is within GA_BAND of its running level
 * (hard braking, a turn's 0.2 g: off the level), the rate about the up axis is below GA_YAW_DPS
 * (no turn: no centripetal acceleration) and, once locked, the accelerometer is within
 * GA_INNOV_DEG of the estimate (a gentle acceleration on a straight: the gyro saw no pitch).
 * Lock: GA_LOCK_S of pulls within GA_INNOV_DEG under the fast acquisition gains; a lock that
 * sees GA_UNLOCK_S of pulls all beyond it (the estimate wrong, or a long acceleration) is lost
 * and acquired again. A locked estimate replaces the accelerometer's gravity for push_g where
 * the smoothed accelerometer is more than 1 deg from it or 2 % off its level (a turn, braking);
 * where they agree the accelerometer is gravity alone and the better of the two (no gyro noise,
 * bias or scale error). Unlocked, push_g sees the accelerometer as without a gyro. A gap in the
 * rates, or a rate across up no vehicle has (a gyro glitch), restarts it. cc->ga_quiet marks the
 * samples whose accelerometer is within 0.3 deg of the locked estimate: the tilt compensation's k
 * learns only from those (cont_life.c).
 */
#include <math.h>

#include "cont_internal.h"
#include "magcal_internal.h"

#define GA_SMOOTH_MS 500u     /* the accelerometer's smoothing (noise), as push_g's */
#define GA_LEVEL_MS 10000u    /* the running level of its magnitude */
#define GA_BAND 0.003f        /* |a| within this share of its level: no acceleration along it */
#define GA_BAND_ACQ 0.01f     /* the same while acquiring (the level itself still settling) */
#define GA_YAW_DPS 1.0f       /* the rate about up below this: no turn, no centripetal acceleration */
#define GA_INNOV_DEG 1.5f     /* once locked, a pull beyond this is the car's acceleration */
#define GA_USE_COS 0.99984770f /* cos 1 deg: a locked estimate is used where the smoothed
                                 accelerometer is further from it, */
#define GA_USE_BAND 0.02f     /* or its magnitude is off its level by this share (0.2 g across) */
#define GA_QUIET_COS 0.99998629f /* cos 0.3 deg: a locked estimate this close to the smoothed
                                 accelerometer: gravity alone (the tilt compensation's k learns from
                                 it, cont_life.c) */
#define GA_KP 0.05f           /* 1/s: locked pull (a 20-s time constant) */
#define GA_KI 0.002f          /* 1/s^2: locked bias learning (damping 0.56) */
#define GA_KP_ACQ 0.5f        /* 1/s: acquisition */
#define GA_KI_ACQ 0.05f       /* 1/s^2 (damping 1.1) */
#define GA_LOCK_S 30.0f       /* s of consistent pulls to lock */
#define GA_UNLOCK_S 10.0f     /* s of pulls all rejected to lose the lock */
#define GA_MAX_DT_MS 250u     /* a longer gap between rates: the estimate restarts */
#define GA_TILT_DPS 60.0f     /* a rate across the up axis beyond this is no vehicle's pitch or roll
                                 (a gyro glitch): the estimate restarts */

static void ga_cross(const magcal_vec3_t *a, const magcal_vec3_t *b, magcal_vec3_t *out)
{
    out->x = a->y * b->z - a->z * b->y;
    out->y = a->z * b->x - a->x * b->z;
    out->z = a->x * b->y - a->y * b->x;
}

/* Start (again) at the accelerometer's direction, unlocked; the bias learnt is kept. */
static void ga_start(magcal_cont_t *cc, const magcal_vec3_t *a, float n, uint32_t t_ms)
{
    cc->ga_as = *a;
    cc->ga_u.x = a->x / n;
    cc->ga_u.y = a->y / n;
    cc->ga_u.z = a->z / n;
    cc->ga_lvl = n;
    cc->ga_nl = 1u;
    cc->ga_tl = 0.0f;
    cc->ga_tr = 0.0f;
    cc->ga_lock = 0u;
    cc->ga_t = t_ms;
    cc->ga_on = 1u;
}

/* 1 when the pull passes the gates; *e = u x a/|a| (the small rotation that takes u to it). */
static int ga_pull(magcal_cont_t *cc, const magcal_vec3_t *wc, float n, float dt, magcal_vec3_t *e)
{
    const magcal_vec3_t *u = &cc->ga_u;
    const float yaw = (wc->x * u->x + wc->y * u->y + wc->z * u->z) * MAGCAL_DEG_PER_RAD_F;
    const float lim = GA_INNOV_DEG / MAGCAL_DEG_PER_RAD_F;
    magcal_vec3_t ah;
    uint8_t big;
    const float band = (cc->ga_lock != 0u) ? GA_BAND : GA_BAND_ACQ;
    if (!(fabsf(n - cc->ga_lvl) <= band * cc->ga_lvl) || !(fabsf(yaw) < GA_YAW_DPS)) {
        return 0;
    }
    ah.x = cc->ga_as.x / n;
    ah.y = cc->ga_as.y / n;
    ah.z = cc->ga_as.z / n;
    ga_cross(u, &ah, e);
    big = (uint8_t)((e->x * e->x + e->y * e->y + e->z * e->z > lim * lim) ? 1u : 0u);
    if (cc->ga_lock != 0u) {
        if (big == 0u) {
            cc->ga_tr = 0.0f;
            return 1;
        }
        cc->ga_tr += dt;
        if (cc->ga_tr > GA_UNLOCK_S) {
            cc->ga_lock = 0u; /* the estimate is not the accelerometer's for long: acquire again */
            cc->ga_tl = 0.0f;
            cc->ga_unlocks = cc->ga_unlocks + 1u;
        }
        return 0;
    }
    if (big != 0u) {
        cc->ga_tl = 0.0f;
    } else {
        cc->ga_tl += dt;
        if (cc->ga_tl > GA_LOCK_S) {
            cc->ga_lock = 1u;
            cc->ga_tr = 0.0f;
        }
    }
    return 1;
}

/* The estimate's update; 1 when push_g takes it (in cc->ga_g). */
static int ga_update(magcal_cont_t *cc, const magcal_vec3_t *g, const magcal_vec3_t *w, uint32_t t_ms)
{
    const uint32_t dtm = t_ms - cc->ga_t; /* wrapping stamps */
    float ng; /* |g| of this sample */
    float n;  /* |the smoothed accelerometer| */
    float dt;
    float wq;
    magcal_vec3_t wc;
    magcal_vec3_t e;
    magcal_vec3_t du;
    if (g == NULL || !magcal_isfinite_f(g->x) || !magcal_isfinite_f(g->y) || !magcal_isfinite_f(g->z)) {
        return 0;
    }
    ng = sqrtf(g->x * g->x + g->y * g->y + g->z * g->z);
    if (!(ng > 0.0f) || !magcal_isfinite_f(ng)) {
        return 0;
    }
    if (cc->ga_on == 0u || dtm > GA_MAX_DT_MS) {
        ga_start(cc, g, ng, t_ms);
        return 0;
    }
    dt = 0.001f * (float)dtm;
    magcal_cont_ema3(&cc->ga_as, g, magcal_cont_ema_w(dtm, GA_SMOOTH_MS));
    n = sqrtf(cc->ga_as.x * cc->ga_as.x + cc->ga_as.y * cc->ga_as.y + cc->ga_as.z * cc->ga_as.z);
    if (!(n > 0.0f) || !magcal_isfinite_f(n)) {
        cc->ga_on = 0u;
        return 0;
    }
    {
        /* the level: the mean of the samples so far until it is an exponential average's */
        const float wl = magcal_cont_ema_w(dtm, GA_LEVEL_MS);
        cc->ga_nl = (cc->ga_nl < 0xFFFFu) ? (uint16_t)(cc->ga_nl + 1u) : cc->ga_nl;
        cc->ga_lvl += (n - cc->ga_lvl) * fmaxf(wl, 1.0f / (float)cc->ga_nl);
    }
    cc->ga_t = t_ms;
    wc.x = w->x - cc->ga_b.x;
    wc.y = w->y - cc->ga_b.y;
    wc.z = w->z - cc->ga_b.z;
    ga_cross(&cc->ga_u, &wc, &du);
    if (!(du.x * du.x + du.y * du.y + du.z * du.z <=
          (GA_TILT_DPS / MAGCAL_DEG_PER_RAD_F) * (GA_TILT_DPS / MAGCAL_DEG_PER_RAD_F))) {
        ga_start(cc, g, ng, t_ms);
        return 0;
    }
    cc->ga_quiet = 0u;
    if (ga_pull(cc, &wc, n, dt, &e) != 0) {
        float k = (cc->ga_lock != 0u) ? GA_KP : GA_KP_ACQ;
        wc.x -= k * e.x;
        wc.y -= k * e.y;
        wc.z -= k * e.z;
        k = ((cc->ga_lock != 0u) ? GA_KI : GA_KI_ACQ) * dt;
        cc->ga_b.x += k * e.x;
        cc->ga_b.y += k * e.y;
        cc->ga_b.z += k * e.z;
    }
    /* the up vector is fixed in the world: in body axes du/dt = u x w */
    ga_cross(&cc->ga_u, &wc, &du);
    cc->ga_u.x += du.x * dt;
    cc->ga_u.y += du.y * dt;
    cc->ga_u.z += du.z * dt;
    wq = sqrtf(cc->ga_u.x * cc->ga_u.x + cc->ga_u.y * cc->ga_u.y + cc->ga_u.z * cc->ga_u.z);
    if (!(wq > 0.0f) || !magcal_isfinite_f(wq)) {
        cc->ga_on = 0u;
        return 0;
    }
    cc->ga_u.x /= wq;
    cc->ga_u.y /= wq;
    cc->ga_u.z /= wq;
    if (cc->ga_lock == 0u) {
        return 0;
    }
    {
        /* where the accelerometer agrees with the estimate, it is gravity alone and the better
         * of the two (no gyro noise, bias or scale error): push_g takes it */
        const float c = (cc->ga_u.x * cc->ga_as.x + cc->ga_u.y * cc->ga_as.y + cc->ga_u.z * cc->ga_as.z) / n;
        const uint8_t in_band = (uint8_t)((fabsf(n - cc->ga_lvl) <= GA_USE_BAND * cc->ga_lvl) ? 1u : 0u);
        cc->ga_quiet = (uint8_t)((in_band != 0u && c >= GA_QUIET_COS) ? 1u : 0u);
        if (in_band != 0u && c >= GA_USE_COS) {
            return 0;
        }
    }
    cc->ga_g.x = cc->ga_u.x * cc->ga_lvl;
    cc->ga_g.y = cc->ga_u.y * cc->ga_lvl;
    cc->ga_g.z = cc->ga_u.z * cc->ga_lvl;
    return 1;
}

const magcal_vec3_t *magcal_cont_grav(magcal_cont_t *cc, const magcal_vec3_t *g, const magcal_vec3_t *w, uint32_t t_ms)
{
    return (ga_update(cc, g, w, t_ms) != 0) ? &cc->ga_g : g;
}
