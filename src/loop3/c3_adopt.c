/*
 * Continuous 3-D calibrator, adoption over time. A solve that returns MAGCAL_OK (every gate of
 * magcal_ellipsoid_calibrate passed) gives a candidate; it is adopted only when it is better than
 * the installed calibration on the same samples (never-worse):
 *     spread(candidate) x margin(t) < spread(installed),
 * spread = std / mean of |G (m - V)| over the snapshot samples within MAGCAL_CONT3_SPREAD_CLIP x F
 * of the candidate's shell (the same samples for both: gross outliers the candidate's own gates
 * left out do not decide). Ageing (as NXP ages its fit error with time): the installed
 * calibration's confidence decays with the time t since its adoption (ms of push stamps, gaps
 * count at most 1 s),
 *     margin(t) = max(1 + (cfg.adopt_margin - 1) / (1 + t / cfg.age_ms), 1 + 12 / n),
 * so a genuinely better calibration wins eventually and a stale one does not block for ever. The
 * floor 1 + 12 / n guards against overfit: with Gaussian noise, the least-squares fit of 9
 * parameters lowers the residual sum of squares of its own n samples below the TRUE calibration's
 * by sigma^2 chi^2_9, i.e. its spread by a factor of about 1 - chi^2_9 / (2 n); beating the truth
 * by the floor needs chi^2_9 > 24, probability 0.4 % per solve, and such a candidate is off the
 * truth only at the noise level, ~ sqrt(9 / n) sigma (tests/test_continuous3.c
 * test_cont3_true_calibration_never_replaced).
 */
#include <math.h>

#include "c3_internal.h"
#include "magcal_internal.h"

#if MAGCAL_CFG_ENABLE_3D /* whole file: config.h feature switch (the 3-D loop needs the ellipsoid fit) */

void magcal_c3_install(magcal_cont3_t *cc, const magcal_ellipsoid_cal_t *c, float sigma)
{
    const float r_raw = magcal_c3_raw_radius(c);
    cc->cal = *c;
    cc->has_cal = 1u;
    cc->cal_sigma_rel = magcal_isfinite_f(sigma) && sigma > 0.0f ? sigma : 0.0f;
    if (r_raw > 0.0f) {
        (void)magcal_intake_set_centre(&cc->store, &c->v, r_raw);
    }
    cc->episode_open = 0u;
    cc->mis_ms = 0u;
    cc->clean_ms = 0u;
    cc->mis_cells = 0u;
}

float magcal_c3_spread(const magcal_cont3_t *cc, const magcal_ellipsoid_cal_t *c,
                       const magcal_ellipsoid_cal_t *sel)
{
    float s1 = 0.0f; /* sums of |h| - F (pivoted: no cancellation) */
    float s2 = 0.0f;
    float n = 0.0f;
    float mean_d;
    float var;
    size_t k;
    for (k = 0u; k < cc->snap_n; ++k) {
        magcal_vec3_t h;
        float r;
        if (magcal_ellipsoid_apply(sel, &cc->buf[k], &h) != MAGCAL_OK) {
            continue;
        }
        r = sqrtf(h.x * h.x + h.y * h.y + h.z * h.z);
        if (!(fabsf(r / sel->field - 1.0f) <= MAGCAL_CONT3_SPREAD_CLIP) ||
            magcal_ellipsoid_apply(c, &cc->buf[k], &h) != MAGCAL_OK) {
            continue;
        }
        r = sqrtf(h.x * h.x + h.y * h.y + h.z * h.z) - c->field;
        s1 += r;
        s2 += r * r;
        n += 1.0f;
    }
    if (n < 10.0f) {
        return NAN;
    }
    mean_d = s1 / n;
    var = fmaxf(s2 / n - mean_d * mean_d, 0.0f);
    return sqrtf(var) / (c->field + mean_d);
}

static float c3_margin(const magcal_cont3_t *cc)
{
    const float aged = 1.0f + (cc->cfg.adopt_margin - 1.0f) / (1.0f + (float)cc->age_ms_acc / cc->cfg.age_ms);
    const float floor_m = 1.0f + MAGCAL_CONT3_OVERFIT_K / (float)(cc->snap_n > 9u ? cc->snap_n : 9u);
    return fmaxf(aged, floor_m);
}

magcal_cont3_outcome_t magcal_c3_adopt(magcal_cont3_t *cc)
{
    const magcal_ellipsoid_result_t *r = &cc->cand;
    int adopt;
    cc->solves++;
    cc->solve_ms_acc = 0u;
    cc->inst_spread = NAN;
    cc->cand_spread = NAN;
    if (cc->solve_status != MAGCAL_OK) {
        if (cc->fail_run < 255u) {
            cc->fail_run++;
        }
        cc->last_status = cc->solve_status;
        return MAGCAL_CONT3_FAILED; /* collection goes on; the installed calibration is untouched */
    }
    cc->cand_spread = magcal_c3_spread(cc, &r->cal, &r->cal);
    if (!magcal_isfinite_f(cc->cand_spread)) {
        cc->last_status = MAGCAL_ERR_TOO_FEW_POINTS;
        return MAGCAL_CONT3_FAILED;
    }
    if (cc->has_cal != 0u) {
        const float m = c3_margin(cc);
        cc->inst_spread = magcal_c3_spread(cc, &cc->cal, &r->cal);
        /* an installed calibration that is not finite on these samples is worse than any */
        adopt = 0;
        if (!magcal_isfinite_f(cc->inst_spread) || cc->cand_spread * m < cc->inst_spread) {
            adopt = 1;
        }
        if (adopt != 0 && magcal_isfinite_f(cc->inst_spread) &&
            !(cc->cand_spread * cc->cfg.adopt_margin < cc->inst_spread)) {
            cc->aged_adopts++;
        }
    } else {
        adopt = 1;
    }
    if (adopt == 0) {
        /* fresh data confirm the installed calibration: a declared change is refuted; the next
         * solve waits for more new samples (linear back-off) */
        cc->fail_run = 0u;
        if (cc->refuse_run < 255u) {
            cc->refuse_run++;
        }
        cc->last_status = MAGCAL_ERR_NOT_BETTER;
        cc->state = (uint8_t)MAGCAL_CONT3_COLLECTING;
        return MAGCAL_CONT3_REFUSED;
    }
    cc->fail_run = 0u;
    cc->refuse_run = 0u;
    cc->last = *r;
    magcal_c3_install(cc, &r->cal, r->residual_rms / r->cal.field);
    cc->generation++;
    cc->age_ms_acc = 0u;
    cc->last_status = MAGCAL_OK;
    cc->state = (uint8_t)MAGCAL_CONT3_COLLECTING;
    return MAGCAL_CONT3_ADOPTED;
}

#endif /* MAGCAL_CFG_ENABLE_3D */
