/*
 * Continuous calibrator, the gyro's heading check (trust DISTURBED; continuous.h "Gyro heading
 * check", docs/calibrator.md "Gyro heading check"). magcal_cont_push_imu queues with each sample
 * the rotation about the up axis since the sample before (cont_life.c); the drain (cont_step.c)
 * hands every judged sample with that rotation here. A track of the heading is carried by the
 * gyro and pulled towards the corrected magnetic heading by a proportional-integral loop (natural
 * frequency RJ_WN, critically damped: the integral is the gyro's bias about the up axis). A
 * disturbance across the field turns the magnetic heading while its field magnitude has barely
 * moved (the magnitude judge sees its second order only); the gyro does not turn: the deviation
 * of the magnetic heading from the track flags the heading. While the deviation is over the
 * threshold, or a sample is a glitch or under a transient flag, the track coasts on the gyro (it
 * does not follow the disturbance); a deviation that lasts RJ_COAST_MS is no transient (a lasting
 * change is the change detection's, a worse calibration the adoption's): the track restarts at
 * the magnetic heading. The sign between the gyro's rotation and the heading is the contract's
 * and checked on the turns (a gyro frame mirrored against the magnetometer's is turned to); the
 * flag is held off until the loop has settled (RJ_WARM_MS).
 */
#include "cont_judge_internal.h"

#define RJ_WN 0.1f           /* 1/s: the loop's natural frequency (a 10-s pull; transients are 2..5 s) */
#define RJ_MAX_DT_MS 250u    /* a longer gap between judged samples: the track restarts */
#define RJ_WARM_MS 60000u    /* ms of judged samples before a flag (the bias settled), again after a sign turn */
#define RJ_COAST_MS 8000u    /* a deviation longer than this is no transient: the track restarts */
#define RJ_SIGN_DEG 180.0f   /* degrees of gyro rotation that check the sign */
#define RJ_SIGN_SLOPE 0.5f   /* a regression slope of the other sign beyond this turns it (a heading
                                move's noise, 0.3 deg per sample, averages out in the slope; a
                                per-sample correlation would not reach 0.8) */
#define RJ_TURN_DEG 0.05f    /* a sample's rotation above this informs the sign */
#define RJ_K 4.0f            /* threshold >= this x the deviation's RMS on clean samples */
#define RJ_VAR_MS 20000.0f   /* time constant of that RMS */
#define RJ_HYST 0.6f         /* a flag ends below this x the threshold */
#define RJ_GROSS 0.5f        /* |rel| above: a glitch, the track coasts */
#define RJ_JUMP_DEG 5.0f     /* one sample's magnetic and gyro moves this far apart: a glitch, restart */
#ifndef RJ_TURN_K
#define RJ_TURN_K 0.015f     /* threshold widening per degree of recent rotation (the gyro's scale error,
                                the calibration's heading-dependent error: both grow with the turn) */
#endif

/* The track restarts at the magnetic heading, unflagged. */
static void rj_restart(magcal_cont_t *cc, float heading)
{
    cc->rj_psi = heading;
    cc->rj_coast_ms = 0u;
    cc->rj_flag = 0u;
}

void magcal_cont_rate_reset(magcal_cont_t *cc)
{
    cc->rj_on = 0u;
    cc->rj_flag = 0u;
    cc->rj_coast_ms = 0u;
}

/* The sign of the gyro's rotation against the heading's: -1 at init (the contract's frame: a
 * right-handed rotation about up turns the heading anticlockwise), checked on every RJ_SIGN_DEG of
 * clean turning (dm the magnetic heading's move, dy the gyro's rotation): a regression slope of
 * the other sign (a gyro frame mirrored against the magnetometer's) turns it, and the track
 * starts again with a new warm-up. */
static void rj_check_sign(magcal_cont_t *cc, float dm, float dy, uint8_t clean)
{
    if (clean != 0u && fabsf(dy) > RJ_TURN_DEG) {
        cc->rj_sx += dm * dy;
        cc->rj_sa += dy * dy;
        cc->rj_turn += fabsf(dy);
    }
    if (cc->rj_turn >= RJ_SIGN_DEG) {
        const float c = cc->rj_sx / cc->rj_sa; /* heading move per gyro rotation */
        if (fabsf(c) >= RJ_SIGN_SLOPE && (c > 0.0f) != (cc->rj_sgn > 0)) {
            cc->rj_sgn = (int8_t)(-cc->rj_sgn);
            cc->rj_ms = 0u;
            cc->rj_b = 0.0f;
            cc->rj_var = 0.0f;
            magcal_cont_rate_reset(cc);
        }
        cc->rj_sx = 0.0f;
        cc->rj_sa = 0.0f;
        cc->rj_turn = 0.0f;
    }
}

void magcal_cont_rate(magcal_cont_t *cc, const magcal_cont_judge_t *j, float dy, uint32_t t_ms)
{
    const uint32_t dt = t_ms - cc->rj_t;
    const uint8_t clean = (uint8_t)((j->gross == 0u && cc->dist_flag == 0u && magcal_isfinite_f(j->rel) &&
                                     fabsf(j->rel) <= RJ_GROSS) ? 1u : 0u);
    float d;
    float thr;
    float dts;
    uint8_t warm;
    uint8_t over;
    cc->rj_t = t_ms;
    if (!(cc->cfg.rate_trust_deg > 0.0f) || !magcal_isfinite_f(dy) || !magcal_isfinite_f(j->heading)) {
        magcal_cont_rate_reset(cc);
        return;
    }
    if (cc->rj_on == 0u || dt > RJ_MAX_DT_MS) {
        rj_restart(cc, j->heading);
        cc->rj_prev = j->heading;
        cc->rj_on = 1u;
        return;
    }
    dts = (float)dt * 0.001f;
    d = magcal_wrap180_deg(j->heading - cc->rj_prev);
    cc->rj_prev = j->heading;
    rj_check_sign(cc, d, dy, clean);
    if (cc->rj_on == 0u) {
        return; /* the sign turned: the track starts again with the next sample */
    }
    if (clean != 0u && fabsf((float)cc->rj_sgn * dy - d) > RJ_JUMP_DEG) {
        /* one sample's moves disagree by more than a disturbance's onset turns a heading (1 deg per
         * 20 ms at the most): a glitch of the gyro (a spike read 60 deg off the track and held the
         * flag for the 8 s of a coast) or of the magnetometer the magnitude judge missed: the
         * track restarts at the magnetic heading, no flag */
        rj_restart(cc, j->heading);
        return;
    }
    cc->rj_psi = magcal_wrap180_deg(cc->rj_psi + (float)cc->rj_sgn * dy - cc->rj_b * dts);
    /* the recent rotation: a sum that decays with the loop's time constant */
    cc->rj_rot = cc->rj_rot * (1.0f - fminf(RJ_WN * dts, 1.0f)) + fabsf(dy);
    d = magcal_wrap180_deg(j->heading - cc->rj_psi);
    cc->rj_dev = d;
    thr = fmaxf(cc->cfg.rate_trust_deg, RJ_K * sqrtf(cc->rj_var)) + RJ_TURN_K * cc->rj_rot;
    over = (uint8_t)((fabsf(d) > ((cc->rj_flag != 0u) ? RJ_HYST * thr : thr)) ? 1u : 0u);
    warm = (uint8_t)((cc->rj_ms < RJ_WARM_MS) ? 1u : 0u);
    if (warm != 0u) {
        cc->rj_ms += dt;
        over = 0u;
    }
    if (over != 0u || clean == 0u) {
        /* coast on the gyro: the track does not follow a disturbance */
        cc->rj_coast_ms += dt;
        if (cc->rj_coast_ms > RJ_COAST_MS) {
            rj_restart(cc, j->heading); /* no transient */
            over = 0u;
        }
    } else {
        const float w = (float)dt / (RJ_VAR_MS + (float)dt);
        cc->rj_coast_ms = 0u;
        cc->rj_psi = magcal_wrap180_deg(cc->rj_psi + 2.0f * RJ_WN * d * dts);
        cc->rj_b -= RJ_WN * RJ_WN * d * dts;
        if (warm == 0u) {
            cc->rj_var += w * (d * d - cc->rj_var); /* the bias settled: the deviation's noise */
        }
    }
    if (over != 0u && cc->rj_flag == 0u) {
        cc->rj_flags++;
    }
    cc->rj_flag = over;
}
