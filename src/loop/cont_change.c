/*
 * Continuous calibrator, the judge and change detection (docs/calibrator.md "Judge and change
 * detection"). Every drained sample is judged under the installed calibration by its relative
 * residual `rel` against a model of the field it must show:
 *  - total field (when the store supports it): a level sensor that pitches (hills) keeps
 *    |h|^2 + z_b^2 = F^2, and its raw z is z_b plus a heading-dependent leak of x, y (soft iron,
 *    misalignment), so |h|^2 = c0 + c1 u + c2 u^2 + c3 hx + c4 hy + c5 (hx^2 - hy^2) + c6 hx hy
 *    (u = raw z - its store mean, h corrected, both scaled to unit radius), fitted over the store
 *    at each adoption; without the hx, hy terms the leak alone (about 5 % of |h|) hides a
 *    disturbance; c5, c6 absorb a residual shape error of the calibration; rel = sqrt(model) - 1;
 *  - otherwise rel = |h| / R - 1.
 * Every threshold is widened by sqrt(1 + unc), unc = the model's prediction variance at the
 * sample over its noise variance (f^T (F^T F)^-1 f): one circle cannot separate the pitch from
 * the calibration's shape. Sectors the store did not cover at the fit are stored, not judged per
 * sample (the transient flag and a z out of reach of pitch still flag them).
 * Two judges use it:
 *  - per sample: |rel| > max(cfg.mismatch_k sigma, cfg.mismatch_min_rel), sigma = the relative
 *    residual of the model on the store. Mismatching samples are not stored; those beyond twice
 *    the threshold open or extend an episode (its sectors of corrected heading and its mismatch
 *    time); cfg.clear_ms of consistent samples close it; cfg.change_ms of mismatch over
 *    cfg.change_bins sectors is a lasting change (the store is dropped, cont_step.c relearns);
 *  - transient: rel smoothed over cfg.disturb_tau_ms (the noise of z, amplified by 2 z / |h|,
 *    dominates one sample; 3 x faster back towards the baseline) minus a slow baseline (4 s:
 *    the model's bias drifts with the hills) against cfg.disturb_k times the RMS of that
 *    difference on clean samples (learnt on the stream, at least the store's sigma); the flag
 *    is held cfg.disturb_hold_ms after it falls back. A flagged sample is DISTURBED and not
 *    stored, but drops nothing and never adds up to a change. A flag longer than cfg.change_ms
 *    is the model's own error: the baseline and the noise estimate then follow it.
 * Change evidence (`gross`, what an episode counts): |rel| beyond twice the threshold widened by
 * at most sqrt(1 + CONT_CHANGE_UNC), or a raw z beyond the reach of a road's pitch from the store's.
 * Model health: when a 30 s share of samples over the per-sample threshold exceeds CONT_MISS_ON
 * (no episode open), the model does not explain the stream and its per-sample test stops
 * flagging (and refusing storage) until the share falls below CONT_MISS_OFF.
 */
#include <math.h>

#include "cont_internal.h"
#include "magcal_internal.h"

#define CONT_DIST_MIN_REL 0.004f  /* floor of the transient threshold (relative) */
#define CONT_DIST_CLAMP 0.15f     /* a sample enters the smoothed residual clamped to this */
#define CONT_DIST_GROSS 0.5f      /* |rel| above: a glitch, it does not feed the transient judge */
#define CONT_DIST_BASE_MS 4000.0f /* baseline time constant (hills drift the model's bias) */
#define CONT_DIST_VAR_MS 20000.0f /* variance time constant of the transient judge */
#define CONT_DIST_STORE_K 1.0f    /* transient threshold >= this x the model's sigma on the store */
#define CONT_DIST_VAR0 0.4f       /* initial RMS of the smoothed residual, x the store's sigma */
#define CONT_FZ_MIN_N 30.0f       /* store samples the total-field model needs */
#define CONT_CHANGE_X 2.0f        /* a change counts samples beyond this x the per-sample threshold */
#define CONT_CHANGE_UNC 3.0f      /* the change threshold widens by at most sqrt(1 + this) */
#define CONT_U_SD_K 3.0f          /* z within this x the store's spread of u ... */
#define CONT_MISS_MS 30000.0f     /* time constant of the share of samples over the threshold */
#define CONT_MISS_ON 0.08f        /* above this share the model does not explain the stream ... */
#define CONT_MISS_OFF 0.04f       /* ... until it falls below this one */
#define CONT_U_PITCH 0.25f        /* ... plus this x R (a 6 deg hill moves z by ~0.11 R, 8.5 deg by 0.15 R) */

static unsigned cont_popcount(uint32_t v)
{
    unsigned n = 0u;
    unsigned k;
    for (k = 0u; k < 32u; ++k) {
        n += (unsigned)((v >> k) & 1u);
    }
    return n;
}

/* Features of the judge's model: 1, u, u^2, hx, hy, hx^2 - hy^2, hx hy (unit radius; the last
 * two absorb a residual shape error of the calibration). `skip` drops the leading u terms:
 * 0 keeps both, 1 drops u^2, 2 drops u and u^2. Returns the count written to f. */
static uint32_t cont_fz_feat(float u, float hx, float hy, uint32_t skip, float *f)
{
    uint32_t n = 1u;
    f[0] = 1.0f;
    if (skip < 2u) {
        f[n] = u;
        n++;
    }
    if (skip < 1u) {
        f[n] = u * u;
        n++;
    }
    f[n] = hx;
    f[n + 1u] = hy;
    f[n + 2u] = hx * hx - hy * hy;
    f[n + 3u] = hx * hy;
    return n + 4u;
}


/* Prediction variance of the model at a sample over its noise variance: |L^-1 f|^2 with f the
 * scaled features and L the Cholesky factor of the store's scaled normal matrix (F^T F). Large
 * where the store could not separate the pitch from the calibration's shape (u collinear with
 * the heading terms), or outside the pitch range the store saw. */
static float cont_fz_unc(const magcal_cont_t *cc, float u, float hx, float hy)
{
    float f[7];
    float w[7];
    float q = 0.0f;
    const uint32_t nf = cont_fz_feat(u, hx, hy, cc->fz_skip, f);
    uint32_t p;
    uint32_t k;
    for (p = 0u; p < nf; ++p) {
        float v = f[p] / cc->fz_s[p];
        for (k = 0u; k < p; ++k) {
            v -= cc->fz_l[p * (p + 1u) / 2u + k] * w[k];
        }
        w[p] = v / cc->fz_l[p * (p + 1u) / 2u + p];
        q += w[p] * w[p];
    }
    return q;
}

/* Cholesky in place of the nf x nf normal matrix held packed (lower) in cc->fz_l, scaled by its
 * diagonal (scales into cc->fz_s), then the solve of (F^T F) c = b in place. 0 when not
 * positive definite (a relative pivot below 1e-6: the store cannot separate the terms). */
static int cont_fz_chol_solve(magcal_cont_t *cc, uint32_t nf, float *b)
{
    float *l = cc->fz_l;
    uint32_t p;
    uint32_t q;
    uint32_t k;
    for (p = 0u; p < nf; ++p) {
        if (!(l[p * (p + 1u) / 2u + p] > 0.0f)) {
            return 0;
        }
        cc->fz_s[p] = sqrtf(l[p * (p + 1u) / 2u + p]);
    }
    for (p = 0u; p < nf; ++p) {
        for (q = 0u; q <= p; ++q) {
            float v = l[p * (p + 1u) / 2u + q] / (cc->fz_s[p] * cc->fz_s[q]);
            for (k = 0u; k < q; ++k) {
                v -= l[p * (p + 1u) / 2u + k] * l[q * (q + 1u) / 2u + k];
            }
            if (p == q) {
                if (!(v > 1e-6f)) {
                    return 0;
                }
                l[p * (p + 1u) / 2u + p] = sqrtf(v);
            } else {
                l[p * (p + 1u) / 2u + q] = v / l[q * (q + 1u) / 2u + q];
            }
        }
    }
    /* L L^T z = S^-1 b, c = S^-1 z */
    for (p = 0u; p < nf; ++p) {
        float v = b[p] / cc->fz_s[p];
        for (k = 0u; k < p; ++k) {
            v -= l[p * (p + 1u) / 2u + k] * b[k];
        }
        b[p] = v / l[p * (p + 1u) / 2u + p];
    }
    for (q = 0u; q < nf; ++q) {
        float v;
        p = nf - 1u - q;
        v = b[p];
        for (k = p + 1u; k < nf; ++k) {
            v -= l[k * (k + 1u) / 2u + p] * b[k];
        }
        b[p] = v / l[p * (p + 1u) / 2u + p];
    }
    for (p = 0u; p < nf; ++p) {
        b[p] /= cc->fz_s[p];
    }
    return magcal_isfinite_f(b[0]) ? 1 : 0;
}

/* Per-sample threshold on |rel|. */
static float cont_threshold(const magcal_cont_t *cc)
{
    return fmaxf(cc->cfg.mismatch_k * cc->cal_sigma_rel, cc->cfg.mismatch_min_rel);
}

/* Sector (0..35) of a corrected heading, deg [0, 360) into *deg (the judge's and the fit's cover). */
static uint8_t cont_sector(const magcal_vec2_t *h, float *deg_out)
{
    float deg = MAGCAL_DEG_PER_RAD_F * atan2f(-h->x, h->y);
    int sec;
    if (deg < 0.0f) {
        deg += 360.0f;
    }
    *deg_out = deg;
    sec = (int)(deg / (360.0f / (float)MAGCAL_CONT_SECTORS));
    if (sec < 0) {
        sec = 0;
    }
    if (sec >= (int)MAGCAL_CONT_SECTORS) {
        sec = (int)MAGCAL_CONT_SECTORS - 1;
    }
    return (uint8_t)sec;
}

/* Total-field residual of corrected h and raw z under the model: rel, and v = (hx, hy, u) unit
 * radius. |h|^2 - c1 u - c2 u^2 - c3 hx - c4 hy stays c0 while the vehicle pitches. */
static float cont_fz_rel(const magcal_cont_t *cc, const magcal_vec2_t *h, float z, float *v)
{
    const float hx = h->x / cc->cal.radius;
    const float hy = h->y / cc->cal.radius;
    const float u = (z - cc->fz_u0) / cc->cal_raw_radius;
    const float tt = hx * hx + hy * hy - cc->fz_abc[1] * u - cc->fz_abc[2] * u * u - cc->fz_hxy[0] * hx -
                     cc->fz_hxy[1] * hy - cc->fz_hxy[2] * (hx * hx - hy * hy) - cc->fz_hxy[3] * (hx * hy);
    v[0] = hx;
    v[1] = hy;
    v[2] = u;
    return sqrtf(fmaxf(tt, 0.0f) / cc->fz_abc[0]) - 1.0f;
}

/* Corrected x, y of a raw sample under the installed calibration: 1 when defined. */
static int cont_corrected(const magcal_cont_t *cc, const magcal_vec3_t *m, magcal_vec2_t *h)
{
    magcal_vec2_t raw;
    raw.x = m->x;
    raw.y = m->y;
    return cc->has_cal != 0u && magcal_correct_apply(&cc->cal, raw, h) == MAGCAL_OK && cc->cal.radius > 0.0f;
}

int magcal_cont_judge(const magcal_cont_t *cc, const magcal_vec3_t *m, magcal_cont_judge_t *j)
{
    magcal_vec2_t h;
    float thr;
    j->rel = NAN;
    j->heading = 0.0f;
    j->sector = 0u;
    j->unc = 0.0f;
    j->mismatch = 0u;
    j->gross = 0u;
    j->over = 0u;
    if (cont_corrected(cc, m, &h) == 0) {
        return 0;
    }
    if (cc->fz_on != 0u) {
        float v[3];
        j->rel = cont_fz_rel(cc, &h, m->z, v);
        j->unc = cont_fz_unc(cc, v[2], v[0], v[1]);
        /* a raw z no pitch of a road can reach from the store's (a hard-iron change in z): the
         * model would only be extrapolated there, so it is evidence of a change, not uncertainty */
        if (!(fabsf(v[2]) <= CONT_U_SD_K * cc->fz_u_sd + CONT_U_PITCH)) {
            j->gross = 1u;
        }
    } else {
        j->rel = sqrtf(h.x * h.x + h.y * h.y) / cc->cal.radius - 1.0f;
    }
    j->sector = cont_sector(&h, &j->heading);
    thr = cont_threshold(cc) * sqrtf(1.0f + j->unc);
    if (cc->fz_on != 0u && ((cc->fz_cover[j->sector / 32u] >> (j->sector % 32u)) & 1u) == 0u) {
        /* a sector the store did not cover: the calibration and the model are extrapolated
         * there; such samples are what the next solve needs, so the per-sample test does not
         * judge them (they are stored), but the transient judge's flag and a z out of reach of
         * pitch still do (a 45 % disturbance of a parked car in such a sector was trusted) */
        j->mismatch = (uint8_t)((j->gross != 0u || cc->dist_flag != 0u) ? 1u : 0u);
        return 1;
    }
    /* a change counts samples beyond twice the per-sample threshold, widened for the model's
     * extrapolation at most by sqrt(1 + CONT_CHANGE_UNC): a hard-iron step moves raw z (u) far
     * outside the store, where the unbounded widening made the step look merely uncertain */
    if (!(fabsf(j->rel) <= CONT_CHANGE_X * cont_threshold(cc) * sqrtf(1.0f + fminf(j->unc, CONT_CHANGE_UNC)))) {
        j->gross = 1u;
    }
    /* the transient judge's flag (state of the stream up to the last drained sample) counts too */
    j->over = (uint8_t)(!(fabsf(j->rel) <= thr) ? 1u : 0u);
    /* an open episode (evidence of a change) keeps the per-sample test on whatever its health */
    j->mismatch = (uint8_t)((j->gross != 0u || (j->over != 0u && (cc->fz_unfit == 0u || cc->episode_open != 0u)) ||
                             cc->dist_flag != 0u)
                                ? 1u
                                : 0u);
    return 1;
}

/* Wide: the episode spans change_bins sectors and has lasted 3/4 of change_ms (a 2 to 5 s transient
 * through a turn spans many sectors but must not flag the clean headings after it). */
int magcal_cont_episode_wide(const magcal_cont_t *cc)
{
    return cc->episode_open != 0u && cc->mis_ms >= cc->cfg.change_ms - cc->cfg.change_ms / 4u &&
           cont_popcount(cc->mis_bins[0]) + cont_popcount(cc->mis_bins[1]) >= cc->cfg.change_bins;
}

/* Transient judge: one drained sample's rel after dt ms (file comment). */
static void cont_transient(magcal_cont_t *cc, float rel, uint32_t dt)
{
    const float hold = (float)cc->cfg.disturb_hold_ms;
    float d;
    float thr;
    float x;
    if (!magcal_isfinite_f(rel) || !(fabsf(rel) <= CONT_DIST_GROSS)) {
        return; /* a glitch: flagged by the per-sample judge, the smoothed state keeps its value */
    }
    x = fminf(fmaxf(rel, -CONT_DIST_CLAMP), CONT_DIST_CLAMP);
    if (cc->dist_n == 0u) {
        cc->dist_e = x; /* the baseline starts at 0: the model is centred on the store */
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
             * model that does not explain the hills): the baseline follows it at its clean
             * rate and the noise estimate learns it, so the threshold grows to the model's
             * real error instead of flagging the clean rows for minutes */
            const float w = (float)dt / (CONT_DIST_VAR_MS + (float)dt);
            cc->dist_base += (float)dt / (CONT_DIST_BASE_MS + (float)dt) * d;
            cc->dist_var += w * (d * d - cc->dist_var);
        }
        cc->dist_quiet_ms = 0u;
    } else {
        cc->dist_flag_ms = 0u;
        if (cc->dist_quiet_ms <= UINT32_MAX - dt) {
            cc->dist_quiet_ms += dt;
        }
        if ((float)cc->dist_quiet_ms >= hold) {
            /* clean: the baseline follows the model's slow bias, the variance its noise */
            const float w = (float)dt / (CONT_DIST_VAR_MS + (float)dt);
            cc->dist_base += (float)dt / (CONT_DIST_BASE_MS + (float)dt) * d;
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
    cc->fz_miss = 0.0f;
    cc->fz_unfit = 0u;
}

int magcal_cont_episode(magcal_cont_t *cc, const magcal_cont_judge_t *j, uint32_t t_ms)
{
    uint32_t dt = 0u;
    if (cc->have_t != 0u) {
        dt = t_ms - cc->last_t;
        if (dt > MAGCAL_CONT_MAX_DT_MS) {
            dt = MAGCAL_CONT_MAX_DT_MS;
        }
    }
    cc->last_t = t_ms;
    cc->have_t = 1u;
    if (cc->age_ms_acc <= UINT32_MAX - dt) {
        cc->age_ms_acc += dt;
    }
    if (cc->solve_ms_acc <= UINT32_MAX - dt) {
        cc->solve_ms_acc += dt;
    }
    cont_transient(cc, j->rel / sqrtf(1.0f + j->unc), dt);
    if (cc->fz_on != 0u && j->gross == 0u && cc->dist_flag == 0u && cc->episode_open == 0u) {
        /* the model's health: the share of clean-looking samples over its per-sample threshold.
         * A model fitted on a poor calibration (or with the u terms of an earlier one) reads the
         * hills as mismatches on a large share of the rows: then its per-sample test stops flagging
         * (and refusing storage, so the store gets the hills the next fit needs) until the share
         * falls again; the change evidence (gross) and the transient judge stay on. Not while
         * an episode is open: the samples of a change in progress are not the model's health */
        cc->fz_miss += (float)dt / (CONT_MISS_MS + (float)dt) * ((j->over != 0u ? 1.0f : 0.0f) - cc->fz_miss);
        if (cc->fz_miss > CONT_MISS_ON) {
            cc->fz_unfit = 1u;
        } else if (cc->fz_miss < CONT_MISS_OFF) {
            cc->fz_unfit = 0u;
        } else {
            /* hysteresis */
        }
    }
    /* the episode counts the per-sample judge only (a transient flag must never add up to a change),
     * in covered sectors (the judge's mismatch is 0 elsewhere) */
    if (j->gross != 0u) {
        cc->episode_open = 1u;
        cc->mis_ms += dt;
        cc->clean_ms = 0u;
        cc->mis_bins[j->sector / 32u] |= 1u << (j->sector % 32u);
    } else if (cc->episode_open != 0u) {
        cc->clean_ms += dt;
        if (cc->clean_ms >= cc->cfg.clear_ms) {
            cc->episode_open = 0u;
            cc->mis_ms = 0u;
            cc->clean_ms = 0u;
            cc->mis_bins[0] = 0u;
            cc->mis_bins[1] = 0u;
        }
    } else {
        /* consistent, no episode */
    }
    return cc->episode_open != 0u && cc->mis_ms >= cc->cfg.change_ms && magcal_cont_episode_wide(cc) != 0;
}

void magcal_cont_declare_change(magcal_cont_t *cc)
{
    (void)magcal_intake_reset(&cc->store);
    cc->state = (uint8_t)MAGCAL_CONT_RELEARNING;
    cc->stage = 0u;
    cc->changes++;
    cc->episode_open = 0u;
    cc->mis_ms = 0u;
    cc->clean_ms = 0u;
    cc->mis_bins[0] = 0u;
    cc->mis_bins[1] = 0u;
    cc->stored_at_solve = 0u;
    cc->stored_at_adopt = 0u;
    cc->change_flag = 1u;
}


/* Time-sliced field-model fit (magcal_cont_fit_begin / _step): passes over the store in bin
 * order, position (fit_bin, fit_k) and sums in cc. Weights, estimated M4F instructions (host
 * callgrind x 1.2, then x 1.2 as measured on QEMU: cont_trace.elf, tools/bench/cont_weights.py):
 * one sample of each pass, one bin advanced, the Cholesky solve of one form. */
#define CONT_W_FIT_Z 240u     /* z mean / variance of one ring sample (its correction + ring test; was 400: measured on target, cont_trace.elf, <= 231 per sample) */
#define CONT_W_FIT_SUM 720u   /* normal-equation sums: one sample (the full form; less without u; was 900: measured p99 705) */
#define CONT_W_FIT_SIGMA 430u /* the model's residual and the sector covered: one sample (was 684: measured <= 415) */
#define CONT_W_FIT_BIN 13u    /* one bin advanced */
#define CONT_W_FIT_CHOL 3840u /* Cholesky + solve of one model form (7 x 7 at most) */

/* cppcheck-suppress misra-c2012-5.7 ; deviation D14 (false positive): the enum has no tag */
/* cppcheck-suppress misra-c2012-2.4 ; deviation D14 (false positive): no tag, so no unused tag */
enum { CONT_FIT_NONE = 0, CONT_FIT_Z = 1, CONT_FIT_SUMS = 2, CONT_FIT_CHOL = 3, CONT_FIT_SIGMA = 4 };

/* Start a pass (phase) over the store with its accumulators cleared. */
static void cont_fit_pass(magcal_cont_t *cc, uint8_t phase)
{
    cc->fit_phase = phase;
    cc->fit_bin = 0u;
    cc->fit_k = 0u;
    cc->fit_acc[0] = 0.0f;
    cc->fit_acc[1] = 0.0f;
    cc->fit_acc[2] = 0.0f;
    if (phase == (uint8_t)CONT_FIT_SUMS) {
        uint32_t p;
        /* packed lower triangle: row p, column q at p (p + 1) / 2 + q */
        for (p = 0u; p < 28u; ++p) {
            cc->fz_l[p] = 0.0f;
        }
        for (p = 0u; p < 7u; ++p) {
            cc->fit_b[p] = 0.0f;
        }
    }
}

/* Corrected x, y of a store sample during the fit: magcal_correct_apply (heading.c) without its
 * per-call validation of cc->cal (validated once at the fit's begin, fit_cal_ok; cc->cal does not
 * change during the fit). 1 when defined. */
static int cont_fit_corrected(const magcal_cont_t *cc, const magcal_vec3_t *m, magcal_vec2_t *h)
{
    float ux;
    float uy;
    if (cc->fit_cal_ok == 0u || !magcal_isfinite_f(m->x) || !magcal_isfinite_f(m->y)) {
        return 0;
    }
    ux = m->x - cc->cal.offset.x;
    uy = m->y - cc->cal.offset.y;
    h->x = cc->cal.m[0][0] * ux + cc->cal.m[0][1] * uy;
    h->y = cc->cal.m[1][0] * ux + cc->cal.m[1][1] * uy;
    return magcal_isfinite_f(h->x) && magcal_isfinite_f(h->y);
}

/* One sample of the sums pass: normal equations of |h|^2 = f . c over the samples with
 * | |h| / R - 1 | <= 0.35 (hills move the horizontal radius by up to ~20 %). Unit-radius
 * variables (file comment); fit_acc[2] counts the samples used. */
static void cont_fz_add(magcal_cont_t *cc, const magcal_vec3_t *m)
{
    const uint32_t skip = cc->fit_skip;
    const uint32_t nf = 7u - skip;
    float *a = cc->fz_l;
    magcal_vec2_t h;
    float f[7];
    float y;
    uint32_t p;
    uint32_t q;
    if (cont_fit_corrected(cc, m, &h) == 0) {
        return;
    }
    h.x /= cc->cal.radius;
    h.y /= cc->cal.radius;
    y = h.x * h.x + h.y * h.y;
    if (!(fabsf(sqrtf(y) - 1.0f) <= 0.35f)) {
        return;
    }
    {
        const float u = (m->z - cc->fz_u0) / cc->cal_raw_radius;
        (void)cont_fz_feat(u, h.x, h.y, skip, f);
        if (skip == 2u && cc->fz_have_u != 0u) {
            /* the u terms of an earlier model: the store alone cannot determine them */
            y -= cc->fz_u_prior[0] * u + cc->fz_u_prior[1] * u * u;
        }
    }
    for (p = 0u; p < nf; ++p) {
        const float fp = f[p];
        for (q = 0u; q <= p; ++q) {
            *a++ += fp * f[q]; /* packed: row p, column q at p (p + 1) / 2 + q */
        }
        cc->fit_b[p] += fp * y;
    }
    cc->fit_acc[2] += 1.0f;
}

/* One sample of the current pass: z sums, the normal-equation sums, or the model's residual
 * (the judge's rel) with the sector covered (the judge's sector). */
static void cont_fit_sample(magcal_cont_t *cc, const magcal_vec3_t *m)
{
    magcal_vec2_t h;
    if (cc->fit_phase == (uint8_t)CONT_FIT_SUMS) {
        cont_fz_add(cc, m);
        return;
    }
    if (cc->fit_phase == (uint8_t)CONT_FIT_Z) {
        /* the samples the sums use (on the ring): a stored spike's z must not move u0 or its spread */
        if (cont_fit_corrected(cc, m, &h) == 0 ||
            !(fabsf(sqrtf(h.x * h.x + h.y * h.y) / cc->cal.radius - 1.0f) <= 0.35f)) {
            return;
        }
        cc->fit_acc[0] += m->z;
        cc->fit_acc[1] += m->z * m->z;
        cc->fit_acc[2] += 1.0f;
        return;
    }
    if (cont_fit_corrected(cc, m, &h) != 0) {
        /* sigma: RMS of the relative residual over the samples within 0.1 of the model */
        float v[3];
        const float rel = cont_fz_rel(cc, &h, m->z, v);
        const uint8_t sec = cont_sector(&h, &v[0]);
        cc->fz_cover[sec / 32u] |= 1u << (sec % 32u);
        if (fabsf(rel) <= 0.1f) {
            cc->fit_acc[0] += rel * rel;
            cc->fit_acc[2] += 1.0f;
        }
    }
}

/* The next model form after a failed one (u^2, then u dropped); 1 when none is left. The form
 * without u^2 takes its sums from the full form's (the same products in the same order: its
 * normal matrix is the full one without row and column 2), so only the form without u (whose
 * right-hand side holds the earlier model's u terms) needs a pass of its own. */
static int cont_fit_next_form(magcal_cont_t *cc)
{
    static const uint8_t keep[6] = {0u, 1u, 3u, 4u, 5u, 6u};
    cc->fit_skip++;
    if (cc->fit_skip >= 3u) {
        cc->fit_phase = (uint8_t)CONT_FIT_NONE;
        return 1;
    }
    if (cc->fit_skip == 1u && cc->fit_phase == (uint8_t)CONT_FIT_CHOL) {
        uint32_t r;
        /* the full form's sums had enough samples (so does this form: the same samples) */
        for (r = 0u; r < 6u; ++r) {
            uint32_t c;
            for (c = 0u; c <= r; ++c) {
                cc->fz_l[r * (r + 1u) / 2u + c] = cc->fit_a[keep[r] * (keep[r] + 1u) / 2u + keep[c]];
            }
            cc->fit_b[r] = cc->fit_b0[keep[r]];
        }
        return 0; /* phase CHOL */
    }
    cont_fit_pass(cc, (uint8_t)CONT_FIT_SUMS);
    return 0;
}

/* The Cholesky solve of the current form; on success the model's coefficients, then the cover
 * pass. 1 when the fit ended (no form left). */
static int cont_fit_chol(magcal_cont_t *cc)
{
    const uint32_t skip = cc->fit_skip;
    const uint32_t nf = 7u - skip;
    const float *b = cc->fit_b;
    uint32_t k;
    if (!(cont_fz_chol_solve(cc, nf, cc->fit_b) != 0 && b[0] > 0.0f && (skip != 0u || b[2] < 0.0f))) {
        return cont_fit_next_form(cc);
    }
    cc->fz_skip = (uint8_t)skip;
    cc->fz_abc[0] = b[0];
    if (skip < 2u) {
        cc->fz_abc[1] = b[1];
        cc->fz_abc[2] = skip < 1u ? b[2] : 0.0f;
        cc->fz_u_prior[0] = cc->fz_abc[1];
        cc->fz_u_prior[1] = cc->fz_abc[2];
        cc->fz_have_u = 1u;
    } else {
        cc->fz_abc[1] = cc->fz_have_u != 0u ? cc->fz_u_prior[0] : 0.0f;
        cc->fz_abc[2] = cc->fz_have_u != 0u ? cc->fz_u_prior[1] : 0.0f;
    }
    for (k = 0u; k < 4u; ++k) {
        cc->fz_hxy[k] = b[nf - 4u + k];
    }
    cc->dist_flag = 0u;
    cc->fz_cover[0] = 0u; /* set by the sigma pass */
    cc->fz_cover[1] = 0u;
    cont_fit_pass(cc, (uint8_t)CONT_FIT_SIGMA);
    return 0;
}

/* A pass reached the store's end: the next phase. 1 when the fit ended. */
static int cont_fit_pass_end(magcal_cont_t *cc)
{
    const float n = cc->fit_acc[2];
    if (cc->fit_phase == (uint8_t)CONT_FIT_Z) {
        float var;
        if (n < CONT_FZ_MIN_N || !(cc->cal_raw_radius > 0.0f) || !(cc->cal.radius > 0.0f)) {
            cc->fit_phase = (uint8_t)CONT_FIT_NONE;
            return 1;
        }
        cc->fz_u0 = cc->fit_acc[0] / n;
        var = cc->fit_acc[1] / n - cc->fz_u0 * cc->fz_u0;
        cc->fz_u_sd = sqrtf(fmaxf(var, 0.0f)) / cc->cal_raw_radius;
        cc->fit_skip = (uint8_t)(!(var > (0.02f * cc->cal_raw_radius) * (0.02f * cc->cal_raw_radius)) ? 2u : 0u);
        cont_fit_pass(cc, (uint8_t)CONT_FIT_SUMS);
        return 0;
    }
    if (cc->fit_phase == (uint8_t)CONT_FIT_SUMS) {
        if (n >= CONT_FZ_MIN_N) {
            uint32_t p;
            for (p = 0u; p < 28u; ++p) {
                cc->fit_a[p] = cc->fz_l[p]; /* kept for the form without u^2 (cont_fit_next_form) */
            }
            for (p = 0u; p < 7u; ++p) {
                cc->fit_b0[p] = cc->fit_b[p];
            }
            cc->fit_phase = (uint8_t)CONT_FIT_CHOL;
            return 0;
        }
        return cont_fit_next_form(cc);
    }
    /* sigma pass: the judge's noise on the store; the model is on only with it */
    cc->fit_phase = (uint8_t)CONT_FIT_NONE;
    {
        const float sg = n >= CONT_FZ_MIN_N ? sqrtf(cc->fit_acc[0] / n) : 0.0f;
        if (!(sg > 0.0f)) {
            return 1;
        }
        cc->cal_sigma_rel = sg;
    }
    cc->fz_on = 1u;
    magcal_cont_transient_reset(cc);
    return 1;
}

/* The judge's model at an adoption (file comment): the total-field form with its u terms when
 * the store's raw z spreads by at least 2 % of the raw radius (u^2 kept only when physical,
 * c2 < 0), else the shape form with the u terms of the last model that determined them (the
 * vertical field survives a re-magnetised chassis; a store filled on the flat after a relearn
 * cannot tell them) or without u; c0 > 0. Then the sectors the store covers and the judge's
 * noise on the store. At most five passes over the store slots (z and cover, up to three sums,
 * sigma), in slices (cont_internal.h). */
void magcal_cont_fit_begin(magcal_cont_t *cc)
{
    cc->fz_on = 0u;
    /* the judge's condition on the calibration (cont_corrected), once for the whole fit */
    cc->fit_cal_ok = (uint8_t)(cc->has_cal != 0u && magcal_cal2d_validate(&cc->cal) == MAGCAL_OK && cc->cal.radius > 0.0f
                                   ? 1u
                                   : 0u);
    cont_fit_pass(cc, (uint8_t)CONT_FIT_Z);
}

int magcal_cont_fit_step(magcal_cont_t *cc, magcal_cal_budget_t *b)
{
    const magcal_intake_t *st = &cc->store;
    int spent = 0;
    while (cc->fit_phase != (uint8_t)CONT_FIT_NONE) {
        if (spent != 0) {
            return 0;
        }
        if (cc->fit_phase == (uint8_t)CONT_FIT_CHOL) {
            spent = magcal_cal_spend(b, CONT_W_FIT_CHOL);
            if (cont_fit_chol(cc) != 0) {
                return 1;
            }
        } else if (cc->fit_bin >= st->n_bins) {
            if (cont_fit_pass_end(cc) != 0) {
                return 1;
            }
        } else if (cc->fit_k >= st->count[cc->fit_bin]) {
            cc->fit_bin++;
            cc->fit_k = 0u;
            spent = magcal_cal_spend(b, CONT_W_FIT_BIN);
        } else {
            const uint8_t ph = cc->fit_phase;
            cont_fit_sample(cc, &st->slots[cc->fit_bin * st->cfg.per_bin + cc->fit_k].m);
            cc->fit_k++;
            spent = magcal_cal_spend(b, ph == (uint8_t)CONT_FIT_Z      ? CONT_W_FIT_Z
                                        : ph == (uint8_t)CONT_FIT_SUMS ? CONT_W_FIT_SUM
                                                                       : CONT_W_FIT_SIGMA);
        }
    }
    return 1;
}
