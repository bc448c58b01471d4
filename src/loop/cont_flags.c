/*
 * Continuous calibrator, the transient judge (trust DISTURBED; docs/calibrator.md "Judge and
 * change detection"). Two channels, each a value smoothed over cfg.disturb_tau_ms (3 x faster
 * back towards its baseline) minus a slow baseline (4 s: the model's bias drifts with the
 * hills): the residual rel (the noise of z, amplified by 2 z / |h|, dominates one sample) and raw
 * z / R (the vertical channel: a disturbance mostly along z moves rel little when the judge's
 * model has no u terms, a store of level samples). Both deviations are reduced by what the
 * heading's move explains (a regression on cos, sin, cos 2, sin 2 of the corrected heading,
 * learnt on clean samples: the model's and the calibration's heading-dependent error at the
 * current pitch, the soft-iron leak of x, y into z; what the first seconds of a move after a
 * still heading teach it is kept only if no flag rose after them: a transient turns the heading
 * too). The flag: either channel beyond cfg.disturb_k times its own unexplained RMS on clean
 * samples (the residual's at least half the store's sigma and 0.004, the vertical at least
 * 0.02 R), both widened with the heading's move;
 * hysteresis at its end; held cfg.disturb_hold_ms after it falls back. A flagged sample is
 * DISTURBED and not stored, but drops nothing and never adds up to a change. A flag longer than
 * 6 s (or cfg.change_ms) is no transient (2..5 s) but the model's own error: the baselines then
 * restart at the smoothed values and the noise estimates learn the offset.
 */
#include "cont_judge_internal.h"

#define CONT_DIST_MIN_REL 0.004f  /* floor of the transient threshold (relative) */
#define CONT_DIST_CLAMP 0.15f     /* a sample enters the smoothed residual clamped to this */
#define CONT_DIST_BASE_MS 4000.0f /* baseline time constant (hills drift the model's bias) */
#define CONT_DIST_VAR_MS 20000.0f /* variance time constant of the transient judge */
#define CONT_DIST_STORE_K 0.5f    /* transient threshold >= this x the model's sigma on the store */
#define CONT_DIST_VAR0 0.4f       /* initial RMS of the smoothed residual, x the store's sigma */
#define CONT_DIST_NX 4u           /* heading regressors of the bias: cos, sin, cos 2, sin 2 */
#define CONT_DIST_REG_MS 20000.0f /* time constant of the regression's moments (ms of turning) */
#define CONT_DIST_EXC 0.0025f     /* |regressor deviation|^2 above which a sample informs it */
#define CONT_DIST_RIDGE 0.001f    /* ridge of its moments */
#define CONT_DIST_MIN_U 0.02f     /* floor of the vertical channel's threshold (raw z / R) */
#define CONT_DIST_UNC_R 0.02f     /* residual threshold widening per unit of regressor deviation */
#define CONT_DIST_UNC_U 0.05f     /* vertical threshold widening per unit (~3 deg of pitch x the field) */
#define CONT_DIST_LEARN 0.5f      /* the noise learns deviations clipped to this x the thresholds */
#define CONT_DIST_LEARN_REG 0.75f /* the regression learns from samples within this x the thresholds */
#define CONT_DIST_MAX_MS 6000u    /* a flag longer than this (or cfg.change_ms) is no transient (2..5 s) */
#define CONT_DIST_HYST 0.5f       /* a flag ends below this x the residual's threshold */
#define CONT_DIST_HYST_U 0.75f    /* ... and this x the vertical channel's */
#define CONT_DIST_CLAMP_U 1.0f    /* raw z / R enters its smoothing clamped to the baseline +- this */
#define CONT_DIST_WARM_MS 1000u   /* no new flag this long after a reset: the baselines' running mean settles */

#define CONT_DIST_STILL_MS 5000u  /* a heading this long at its baseline: a move's onset is held back ... */
#define CONT_DIST_ONSET_MS 3000u  /* ... its first 3 s of learning (a transient's rise is 1..2.5 s) ... */
#define CONT_DIST_DELAY_MS 1000u  /* ... kept only if no flag rose by 1 s after */

/* Packed lower index of the regression's 4 x 4 moments, their count, and with the residual's and
 * the vertical channel's (the held-back sums, cc->dist_pm). */
#define CONT_DIST_P(i, j) ((i) * ((i) + 1u) / 2u + (j))
#define CONT_DIST_NM 10u
#define CONT_DIST_NP 18u

/* Coefficients of both channels from the moments: one Gauss-Seidel sweep of (M + ridge I) th = m
 * per informative sample (M + ridge I is positive definite, so the sweeps converge; the moments
 * move with a 20-s time constant, so one sweep per sample tracks the solution; an exact solve per
 * sample cost ~1,000 M4F instructions in one step). */
static void cont_dist_solve(magcal_cont_t *cc)
{
    uint32_t i;
    uint32_t k;
    for (i = 0u; i < CONT_DIST_NX; ++i) {
        const float inv = 1.0f / (cc->dist_mx[CONT_DIST_P(i, i)] + CONT_DIST_RIDGE);
        float vr = cc->dist_mr[i];
        float vu = cc->dist_mu[i];
        for (k = 0u; k < CONT_DIST_NX; ++k) {
            if (k != i) {
                const float m = k < i ? cc->dist_mx[CONT_DIST_P(i, k)] : cc->dist_mx[CONT_DIST_P(k, i)];
                vr -= m * cc->dist_th[k];
                vu -= m * cc->dist_th[CONT_DIST_NX + k];
            }
        }
        cc->dist_th[i] = vr * inv;
        cc->dist_th[CONT_DIST_NX + i] = vu * inv;
    }
}

/* Commit (keep != 0) or drop the learning held back since a move's onset. The moments move with a
 * 20-s time constant: a block of samples at once (m <- m (1 - W) + S) is their sequential update
 * to first order in W. */
static void cont_dist_release(magcal_cont_t *cc, int keep)
{
    uint32_t i;
    if (keep != 0) {
        const float w = cc->dist_pw;
        for (i = 0u; i < CONT_DIST_NM; ++i) {
            cc->dist_mx[i] += cc->dist_pm[i] - w * cc->dist_mx[i];
        }
        for (i = 0u; i < CONT_DIST_NX; ++i) {
            cc->dist_mr[i] += cc->dist_pm[CONT_DIST_NM + i] - w * cc->dist_mr[i];
            cc->dist_mu[i] += cc->dist_pm[CONT_DIST_NM + CONT_DIST_NX + i] - w * cc->dist_mu[i];
        }
    }
    for (i = 0u; i < CONT_DIST_NP; ++i) {
        cc->dist_pm[i] = 0.0f;
    }
    cc->dist_pw = 0.0f;
}

/* The onset of a heading move after CONT_DIST_STILL_MS of a still heading (parked, a straight)
 * is the start of a turn or a transient's rise (a disturbance turns the heading too): what the
 * regression learns in its first CONT_DIST_ONSET_MS is held back and kept only if no flag rose
 * by CONT_DIST_DELAY_MS later (a flag drops it). Learnt at once, the first 0.7 s of a transient's
 * rise taught the regression to explain the rise away, and the flag came 15 deg late (60-min
 * seed 2, parked, rows 34976..34992: 64 OK rows up to 15.9 deg off). Within a turn (no still
 * heading before) the regression learns at once, as it must after every reset. q: |dx|^2 of
 * this sample (the regressors' deviations); called for every judged sample. */
static void cont_dist_onset(magcal_cont_t *cc, float q, uint32_t dt)
{
    if (cc->dist_on_ms != 0u) {
        cc->dist_on_ms += dt;
        if (cc->dist_on_ms >= CONT_DIST_ONSET_MS + CONT_DIST_DELAY_MS) {
            cont_dist_release(cc, 1);
            cc->dist_on_ms = 0u;
        }
    }
    if (q > CONT_DIST_EXC) {
        if (cc->dist_on_ms == 0u && cc->dist_still_ms >= CONT_DIST_STILL_MS) {
            cont_dist_release(cc, 0);
            cc->dist_on_ms = 1u;
        }
        cc->dist_still_ms = 0u;
    } else if (cc->dist_still_ms <= UINT32_MAX - dt) {
        cc->dist_still_ms += dt;
    } else {
        /* saturated */
    }
}

/* A clean sample's deviations (residual dr, vertical du, regressors dx from their baselines)
 * into the moments, when the heading moved from its baseline (q = |dx|^2; no information
 * otherwise); into the held-back sums within a move's onset (cont_dist_onset). */
static void cont_dist_learn(magcal_cont_t *cc, float dr, float du, const float *dx, float q, uint32_t dt)
{
    float w;
    uint32_t i;
    uint32_t k;
    if (!(q > CONT_DIST_EXC)) {
        return;
    }
    w = (float)dt / (CONT_DIST_REG_MS + (float)dt);
    if (cc->dist_on_ms != 0u && cc->dist_on_ms < CONT_DIST_ONSET_MS) {
        for (i = 0u; i < CONT_DIST_NX; ++i) {
            for (k = 0u; k <= i; ++k) {
                cc->dist_pm[CONT_DIST_P(i, k)] += w * dx[i] * dx[k];
            }
            cc->dist_pm[CONT_DIST_NM + i] += w * dx[i] * dr;
            cc->dist_pm[CONT_DIST_NM + CONT_DIST_NX + i] += w * dx[i] * du;
        }
        cc->dist_pw += w;
        return;
    }
    for (i = 0u; i < CONT_DIST_NX; ++i) {
        for (k = 0u; k <= i; ++k) {
            cc->dist_mx[CONT_DIST_P(i, k)] += w * (dx[i] * dx[k] - cc->dist_mx[CONT_DIST_P(i, k)]);
        }
        cc->dist_mr[i] += w * (dx[i] * dr - cc->dist_mr[i]);
        cc->dist_mu[i] += w * (dx[i] * du - cc->dist_mu[i]);
    }
    cont_dist_solve(cc);
}

/* The smoothed values after one more sample (x the clamped residual, u raw z / R, f its heading
 * regressors) dt ms after the last: towards the baseline 3 x faster (the flag ends within a
 * fraction of tau of the cause); the vertical channel and the regressors are smoothed alike
 * (their deviations line up). Into e, ue, fe (cc is not written: the peek uses it too; fe may
 * be f: elementwise). */
static void cont_dist_smooth(const magcal_cont_t *cc, float x, float u, const float *f, uint32_t dt, float *e,
                             float *ue, float *fe)
{
    const float tau = fabsf(x - cc->dist_base) < fabsf(cc->dist_e - cc->dist_base) ? (float)cc->cfg.disturb_tau_ms / 3.0f
                                                                                   : (float)cc->cfg.disturb_tau_ms;
    const float a = (float)dt / (tau + (float)dt);
    const float ux = cc->dist_ub + fminf(fmaxf(u - cc->dist_ub, -CONT_DIST_CLAMP_U), CONT_DIST_CLAMP_U);
    uint32_t i;
    *e = cc->dist_e + a * (x - cc->dist_e);
    *ue = cc->dist_ue + a * (ux - cc->dist_ue);
    for (i = 0u; i < CONT_DIST_NX; ++i) {
        fe[i] = cc->dist_fe[i] + a * (f[i] - cc->dist_fe[i]);
    }
}

/* Deviations of smoothed values (e, ue, fe) from the baselines, less what the heading's move
 * explains (the model's and the calibration's heading-dependent error at the current pitch, the
 * soft-iron leak and the hill's share of raw z), into v[0] (residual), v[1] (vertical), with the
 * raw deviations v[2], v[3], the regressors' dx, and the thresholds v[4], v[5] (widened with the
 * heading's move: the coefficients are learnt at other pitches; the hysteresis while flagged);
 * v[6] = |dx|^2.
 * Returns 1 when either channel is over its threshold. */
static uint8_t cont_dist_dev(const magcal_cont_t *cc, float e, float ue, const float *fe, float *dx, float *v)
{
    /* while a flag is up, the heading's move is the one at its rise: the disturbance turns the
     * heading as well, and its own move widened the thresholds and explained its deviation away
     * (a 2-s transient of a moving car: the flag dropped for 17 rows at 45 deg of heading error,
     * a biased record's restore on 30-min seed 2) */
    const float *fm = (cc->dist_flag != 0u) ? cc->dist_fo : fe;
    float q;
    uint32_t i;
    v[2] = e - cc->dist_base;
    v[3] = ue - cc->dist_ub;
    v[0] = v[2];
    v[1] = v[3];
    for (i = 0u; i < CONT_DIST_NX; ++i) {
        dx[i] = fm[i] - cc->dist_fb[i];
        v[0] -= cc->dist_th[i] * dx[i];
        v[1] -= cc->dist_th[CONT_DIST_NX + i] * dx[i];
    }
    v[6] = dx[0] * dx[0] + dx[1] * dx[1] + dx[2] * dx[2] + dx[3] * dx[3];
    q = sqrtf(v[6]);
    v[4] = fmaxf(fmaxf(cc->cfg.disturb_k * sqrtf(cc->dist_var), CONT_DIST_STORE_K * cc->cal_sigma_rel),
                 CONT_DIST_MIN_REL) +
           CONT_DIST_UNC_R * q;
    v[5] = fmaxf(cc->cfg.disturb_k * sqrtf(cc->dist_uvar), CONT_DIST_MIN_U) + CONT_DIST_UNC_U * q;
    if (cc->dist_flag != 0u) {
        /* hysteresis: a flag ends below a fraction of the thresholds (the transient's fall);
         * a milder one for the vertical channel: its baseline, held under the flag, lags a
         * hill's pitch, and at 0.5 a flag outlived a z transient to the 6-s restart
         * (tests/test_cont_drive.c, straight over hills: 232 of 4000 clean rows flagged) */
        v[4] *= CONT_DIST_HYST;
        v[5] *= CONT_DIST_HYST_U;
    }
    return (uint8_t)((!(fabsf(v[0]) <= v[4]) || !(fabsf(v[1]) <= v[5])) ? 1u : 0u);
}

/* The heading regressors of a judged sample: cos, sin, cos 2, sin 2 of its corrected heading. */
static void cont_dist_feat(const magcal_cont_judge_t *j, float *f)
{
    f[0] = j->cs[0];
    f[1] = j->cs[1];
    f[2] = j->cs[0] * j->cs[0] - j->cs[1] * j->cs[1];
    f[3] = 2.0f * j->cs[0] * j->cs[1];
}

/* Transient judge: one judged sample after dt ms (file comment). */
void magcal_cont_transient(magcal_cont_t *cc, const magcal_cont_judge_t *j, uint32_t dt)
{
    const float hold = (float)cc->cfg.disturb_hold_ms;
    const float rel = j->rel;
    float f[CONT_DIST_NX];
    float dx[CONT_DIST_NX];
    float v[7];
    float dr0;
    float du0;
    float d;
    float du;
    float thr;
    float x;
    float thru;
    uint32_t i;
    uint8_t over;
    if (!magcal_isfinite_f(rel) || !(fabsf(rel) <= CONT_GLITCH_REL) || !magcal_isfinite_f(j->u)) {
        return; /* a glitch: flagged by the per-sample judge, the smoothed state keeps its value */
    }
    x = fminf(fmaxf(rel, -CONT_DIST_CLAMP), CONT_DIST_CLAMP);
    cont_dist_feat(j, f);
    if (cc->dist_age_ms <= UINT32_MAX - dt) {
        cc->dist_age_ms += dt;
    }
    cc->dist_dt = dt;
    if (cc->dist_n == 0u) {
        /* the baseline starts at the stream's value, not at the store's mean (0): where the
         * vehicle is when a fit ends (a hill, a heading the model explains worst) the model's
         * bias is not 0, and a baseline at 0 flagged the clean rows for the 8 s of a held flag
         * and more (seed 1: 400..800 rows after each adoption); its age counts from here (the
         * first sample after a reset may come a pause later: the field-model fit) */
        cc->dist_age_ms = 0u;
        cc->dist_e = x;
        cc->dist_base = x;
        cc->dist_ue = j->u;
        cc->dist_ub = j->u;
        for (i = 0u; i < CONT_DIST_NX; ++i) {
            cc->dist_fe[i] = f[i];
            cc->dist_fb[i] = f[i];
        }
    } else {
        float e;
        float ue;
        float fe[CONT_DIST_NX];
        cont_dist_smooth(cc, x, j->u, f, dt, &e, &ue, fe);
        cc->dist_e = e;
        cc->dist_ue = ue;
        for (i = 0u; i < CONT_DIST_NX; ++i) {
            cc->dist_fe[i] = fe[i];
        }
    }
    if (cc->dist_n < UINT32_MAX) {
        cc->dist_n++;
    }
    over = cont_dist_dev(cc, cc->dist_e, cc->dist_ue, cc->dist_fe, dx, v);
    cont_dist_onset(cc, v[6], dt);
    if (cc->dist_age_ms < CONT_DIST_WARM_MS && cc->dist_flag == 0u) {
        /* the baselines started at one sample's value (its noise, up to the threshold): their
         * running mean settles first (a start 0.009 off held a flickering flag, never 6 s long
         * enough to restart, over 604 clean parked rows after 30-min seed 2's relearn) */
        over = 0u;
    }
    d = v[0];
    du = v[1];
    dr0 = v[2];
    du0 = v[3];
    thr = v[4];
    thru = v[5];
    if (over != 0u) {
        /* flagged: the baseline holds for cfg.change_ms (a transient is shorter), then follows
         * (below), so a lasting offset below the per-sample threshold is absorbed instead of
         * blocking the store for ever */
        if (cc->dist_flag_ms <= UINT32_MAX - dt) {
            cc->dist_flag_ms += dt;
        }
        if (cc->dist_flag_ms > (cc->cfg.change_ms < CONT_DIST_MAX_MS ? cc->cfg.change_ms : CONT_DIST_MAX_MS)) {
            /* longer than any transient: what the judge sees is the model's own error (a
             * model that does not explain the hills, a baseline held while a turn on a hill
             * moved the model's bias): the baseline restarts at the smoothed residual and the
             * noise estimate learns the offset, so the flag ends now instead of following at
             * the clean rate for tens of seconds more (seed 1: false flags 0.051 -> 0.043) */
            const float w = (float)dt / (CONT_DIST_VAR_MS + (float)dt);
            cc->dist_var += w * (d * d - cc->dist_var);
            cc->dist_uvar += w * (du * du - cc->dist_uvar);
            cc->dist_base = cc->dist_e;
            cc->dist_ub = cc->dist_ue;
            for (i = 0u; i < CONT_DIST_NX; ++i) {
                cc->dist_fb[i] = cc->dist_fe[i];
            }
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
            /* clean: the baselines follow the slow bias, the variances the noise, the
             * regression what the heading explains */
            /* warm-up: the baseline's time constant grows with the time since the reset (a
             * running mean of the first samples, then the 4-s average) */
            const float w = (float)dt / (CONT_DIST_VAR_MS + (float)dt);
            const float tb = fminf(CONT_DIST_BASE_MS, (float)cc->dist_age_ms);
            if (tb + (float)dt > 0.0f) {
                const float g = (float)dt / (tb + (float)dt);
                cc->dist_base += g * dr0;
                cc->dist_ub += g * du0;
                for (i = 0u; i < CONT_DIST_NX; ++i) {
                    cc->dist_fb[i] += g * dx[i];
                }
            }
            /* the noise learns clipped deviations: the rise of a transient would teach it
             * itself (the flag came 5 rows later, seed 2) */
            const float dc = fminf(fabsf(d), CONT_DIST_LEARN * thr);
            const float duc = fminf(fabsf(du), CONT_DIST_LEARN * thru);
            if (fabsf(d) <= CONT_DIST_LEARN_REG * thr && fabsf(du) <= CONT_DIST_LEARN_REG * thru) {
                cont_dist_learn(cc, dr0, du0, dx, v[6], dt);
            }
            cc->dist_var += w * (dc * dc - cc->dist_var);
            cc->dist_uvar += w * (duc * duc - cc->dist_uvar);
        }
    }
    {
        const uint8_t was = cc->dist_flag;
        cc->dist_flag = (uint8_t)((float)cc->dist_quiet_ms < hold ? 1u : 0u);
        if (was == 0u && cc->dist_flag != 0u) {
            for (i = 0u; i < CONT_DIST_NX; ++i) {
                cc->dist_fo[i] = cc->dist_fe[i];
            }
            cont_dist_release(cc, 0); /* a flag rose after the onset: its learning is dropped */
        }
    }
}

/* Would the transient judge flag after one more sample j (the heading's, not yet drained: the
 * drain judges the ring in order, at least one row behind the heading of the newest)? The
 * smoothing and the test of magcal_cont_transient on the current state, dt the last drained
 * sample's, with the thresholds x cfg.disturb_onset while no flag is up (the onset of a trust
 * flag: a transient's raised-cosine rise stays under the full thresholds for its first 10..15 %,
 * and a heading flagged early costs its availability only, while the store's decisions keep the
 * full thresholds); nothing written. 0 for a glitch or before the judge has a baseline. */
uint8_t magcal_cont_transient_peek(const magcal_cont_t *cc, const magcal_cont_judge_t *j)
{
    float f[CONT_DIST_NX]; /* the regressors, smoothed in place (cont_dist_smooth is elementwise) */
    float dx[CONT_DIST_NX];
    float v[7];
    float e;
    float ue;
    if (cc->dist_n == 0u || !magcal_isfinite_f(j->rel) || !(fabsf(j->rel) <= CONT_GLITCH_REL) ||
        !magcal_isfinite_f(j->u) || (cc->dist_age_ms < CONT_DIST_WARM_MS && cc->dist_flag == 0u)) {
        return 0u; /* (no new flag while the baselines settle, as magcal_cont_transient) */
    }
    cont_dist_feat(j, f);
    cont_dist_smooth(cc, fminf(fmaxf(j->rel, -CONT_DIST_CLAMP), CONT_DIST_CLAMP), j->u, f, cc->dist_dt, &e, &ue, f);
    if (cont_dist_dev(cc, e, ue, f, dx, v) != 0u) {
        return 1u;
    }
    return (uint8_t)((cc->dist_flag == 0u && (!(fabsf(v[0]) <= cc->cfg.disturb_onset * v[4]) ||
                                              !(fabsf(v[1]) <= cc->cfg.disturb_onset * v[5])))
                         ? 1u
                         : 0u);
}

int magcal_cont_transient_settling(const magcal_cont_t *cc)
{
    return cc->dist_flag == 0u && (cc->dist_n == 0u || cc->dist_age_ms < CONT_DIST_WARM_MS);
}

/* Reset the transient judge (a new calibration or model): noise from the store's sigma. The
 * vertical channel's values (raw z / R) and its regression are the vehicle's: rescaled to the new
 * raw radius and kept. A flag up at the reset (a transient in progress while a solve ends, the
 * drain paused over the field-model fit) is kept with the vertical channel's baseline and the
 * regressors'; the residual's baseline starts at the new model's expectation (0) instead of the
 * stream's value: restarted mid-transient, the baselines took the disturbed values, the rest of
 * the transient was trusted and its end flagged for the 6 s of a restart (60-min seed 2, row
 * 88646: 33 rows trusted under it, 258 clean rows flagged after it). Otherwise no flag, and both
 * baselines restart at the stream's values. */
void magcal_cont_transient_reset(magcal_cont_t *cc)
{
    const float s0 = CONT_DIST_VAR0 * cc->cal_sigma_rel;
    const uint8_t held = (uint8_t)(cc->dist_flag != 0u && cc->dist_n != 0u ? 1u : 0u);
    uint32_t i;
    if (cc->dist_ur > 0.0f && cc->cal_raw_radius > 0.0f) {
        const float k = cc->dist_ur / cc->cal_raw_radius;
        cc->dist_ue *= k;
        cc->dist_ub *= k;
        cc->dist_uvar *= k * k;
        for (i = 0u; i < CONT_DIST_NX; ++i) {
            cc->dist_mu[i] *= k;
            cc->dist_th[CONT_DIST_NX + i] *= k;
        }
    }
    cc->dist_ur = cc->cal_raw_radius;
    cc->dist_var = s0 * s0;
    cc->dist_e = 0.0f;
    cc->dist_base = 0.0f;
    cc->dist_age_ms = 0u;
    if (held == 0u) {
        cc->dist_n = 0u;
        cc->dist_flag = 0u;
        cc->dist_flag_ms = 0u;
        cc->dist_quiet_ms = cc->cfg.disturb_hold_ms;
    }
    /* the residual's regression is the model's error: relearnt; the vertical channel's (the
     * soft-iron leak into z, the hill) is the vehicle's: kept */
    for (i = 0u; i < CONT_DIST_NX; ++i) {
        cc->dist_mr[i] = 0.0f;
        cc->dist_th[i] = 0.0f;
    }
    cont_dist_release(cc, 0);
    cc->dist_on_ms = 0u;
    cc->dist_still_ms = 0u;
    cc->fz_miss = 0.0f;
    cc->fz_unfit = 0u;
}
