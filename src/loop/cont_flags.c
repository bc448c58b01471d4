/*
 * Continuous calibrator, the transient judge (trust DISTURBED; docs/calibrator.md "Judge and
 * change detection"): rel smoothed over cfg.disturb_tau_ms (the noise of z, amplified by
 * 2 z / |h|, dominates one sample; 3 x faster back towards the baseline) minus a slow baseline
 * (4 s: the model's bias drifts with the hills) against cfg.disturb_k times the RMS of that
 * difference on clean samples (learnt on the stream, at least the store's sigma); the flag is
 * held cfg.disturb_hold_ms after it falls back. A flagged sample is DISTURBED and not stored, but
 * drops nothing and never adds up to a change. A flag longer than cfg.change_ms is the model's
 * own error: the baseline and the noise estimate then follow it.
 */
#include "cont_judge_internal.h"

#define CONT_DIST_MIN_REL 0.004f  /* floor of the transient threshold (relative) */
#define CONT_DIST_CLAMP 0.15f     /* a sample enters the smoothed residual clamped to this */
#define CONT_DIST_GROSS 0.5f      /* |rel| above: a glitch, it does not feed the transient judge */
#define CONT_DIST_BASE_MS 4000.0f /* baseline time constant (hills drift the model's bias) */
#define CONT_DIST_VAR_MS 20000.0f /* variance time constant of the transient judge */
#define CONT_DIST_STORE_K 1.0f    /* transient threshold >= this x the model's sigma on the store */
#define CONT_DIST_VAR0 0.4f       /* initial RMS of the smoothed residual, x the store's sigma */

/* Transient judge: one drained sample's rel after dt ms (file comment). */
void magcal_cont_transient(magcal_cont_t *cc, float rel, uint32_t dt)
{
    const float hold = (float)cc->cfg.disturb_hold_ms;
    float d;
    float thr;
    float x;
    if (!magcal_isfinite_f(rel) || !(fabsf(rel) <= CONT_DIST_GROSS)) {
        return; /* a glitch: flagged by the per-sample judge, the smoothed state keeps its value */
    }
    x = fminf(fmaxf(rel, -CONT_DIST_CLAMP), CONT_DIST_CLAMP);
    if (cc->dist_age_ms <= UINT32_MAX - dt) {
        cc->dist_age_ms += dt;
    }
    if (cc->dist_n == 0u) {
        /* the baseline starts at the stream's value, not at the store's mean (0): where the
         * vehicle is when a fit ends (a hill, a heading the model explains worst) the model's
         * bias is not 0, and a baseline at 0 flagged the clean rows for the 8 s of a held flag
         * and more (seed 1: 400..800 rows after each adoption) */
        cc->dist_e = x;
        cc->dist_base = x;
    } else {
        /* towards the baseline 3 x faster: the flag ends within a fraction of tau of the cause */
        const float tau = fabsf(x - cc->dist_base) < fabsf(cc->dist_e - cc->dist_base)
                              ? (float)cc->cfg.disturb_tau_ms / 3.0f
                              : (float)cc->cfg.disturb_tau_ms;
        cc->dist_e += (float)dt / (tau + (float)dt) * (x - cc->dist_e);
    }
    if (cc->dist_n < UINT32_MAX) {
        cc->dist_n++;
    }
    d = cc->dist_e - cc->dist_base;
    thr = fmaxf(fmaxf(cc->cfg.disturb_k * sqrtf(cc->dist_var), CONT_DIST_STORE_K * cc->cal_sigma_rel),
                CONT_DIST_MIN_REL);
    if (!(fabsf(d) <= thr)) {
        /* flagged: the baseline holds for cfg.change_ms (a transient is shorter), then follows
         * (below), so a lasting offset below the per-sample threshold is absorbed instead of
         * blocking the store for ever */
        if (cc->dist_flag_ms <= UINT32_MAX - dt) {
            cc->dist_flag_ms += dt;
        }
        if (cc->dist_flag_ms > cc->cfg.change_ms) {
            /* longer than any transient: what the judge sees is the model's own error (a
             * model that does not explain the hills, a baseline held while a turn on a hill
             * moved the model's bias): the baseline restarts at the smoothed residual and the
             * noise estimate learns the offset, so the flag ends now instead of following at
             * the clean rate for tens of seconds more (seed 1: false flags 0.051 -> 0.043) */
            const float w = (float)dt / (CONT_DIST_VAR_MS + (float)dt);
            cc->dist_var += w * (d * d - cc->dist_var);
            cc->dist_base = cc->dist_e;
            cc->dist_flag_ms = 0u;
            cc->dist_quiet_ms = cc->cfg.disturb_hold_ms;
            cc->dist_flag = 0u;
            return;
        }
        cc->dist_quiet_ms = 0u;
    } else {
        cc->dist_flag_ms = 0u;
        if (cc->dist_quiet_ms <= UINT32_MAX - dt) {
            cc->dist_quiet_ms += dt;
        }
        if ((float)cc->dist_quiet_ms >= hold) {
            /* clean: the baseline follows the model's slow bias, the variance its noise */
            /* warm-up: the baseline's time constant grows with the time since the reset (a
             * running mean of the first samples, then the 4-s average) */
            const float w = (float)dt / (CONT_DIST_VAR_MS + (float)dt);
            const float tb = fminf(CONT_DIST_BASE_MS, (float)cc->dist_age_ms);
            if (tb + (float)dt > 0.0f) {
                cc->dist_base += (float)dt / (tb + (float)dt) * d;
            }
            cc->dist_var += w * (d * d - cc->dist_var);
        }
    }
    cc->dist_flag = (uint8_t)((float)cc->dist_quiet_ms < hold ? 1u : 0u);
}

/* Reset the transient judge (a new calibration or model): no flag, noise from the store's sigma. */
void magcal_cont_transient_reset(magcal_cont_t *cc)
{
    const float s0 = CONT_DIST_VAR0 * cc->cal_sigma_rel;
    cc->dist_n = 0u;
    cc->dist_flag = 0u;
    cc->dist_flag_ms = 0u;
    cc->dist_quiet_ms = cc->cfg.disturb_hold_ms;
    cc->dist_var = s0 * s0;
    cc->dist_e = 0.0f;
    cc->dist_base = 0.0f;
    cc->dist_age_ms = 0u;
    cc->fz_miss = 0.0f;
    cc->fz_unfit = 0u;
}
