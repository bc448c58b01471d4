/*
 * The coarse stage (calibrator.h "Coarse stage", docs/calibrator.md): below the coverage gate, a
 * hard-iron circle of the inliers, its residual threshold and refit, and its own whole-circle
 * heading-error bound from the harmonics (ph_harm_n hands a coarse solve to magcal_coarse_bound).
 */
#include <math.h>
#include <string.h>

#include "calibrator_solve_internal.h"

#if MAGCAL_CFG_ENABLE_COARSE /* whole file: config.h feature switch */

/* The circle's radius from its solved normal equations (b = C, D, E of the centred, scaled
 * inliers: r^2 = (C^2 + D^2) / 4 - E); 0 when it is not a circle. */
int magcal_coarse_radius(cal_prep_t *q)
{
    const float r2 = 0.25f * (q->b[0] * q->b[0] + q->b[1] * q->b[1]) - q->b[2];
    q->cr = r2 > 0.0f ? q->s * sqrtf(r2) : 0.0f;
    return q->cr > 0.0f && magcal_isfinite_f(q->cr) ? 1 : 0;
}

/* Distance of sample p from the coarse circle minus its radius. */
static float cal_coarse_res(const cal_prep_t *q, magcal_vec2_t p)
{
    const float dx = p.x - q->cc.x;
    const float dy = p.y - q->cc.y;
    return sqrtf(dx * dx + dy * dy) - q->cr;
}

/* The coarse stage's residual pass (resumable at r->i): the squared residuals around the circle
 * of the samples `mask` keeps into q->ss, their count into r->m. 1 while paused (budget). */
static int cal_coarse_res_pass(const magcal_calibrator_t *cal, cal_run_t *r, cal_prep_t *q, const uint8_t *mask)
{
    int paused = 0;
    while (paused == 0 && r->i < cal->n) {
        const size_t i = r->i;
        r->i++;
        if (mask[i] != 0u) {
            const float e = cal_coarse_res(q, cal->buf[i]);
            q->ss += e * e;
            r->m++;
            paused = magcal_cal_charge(&r->bud, CAL_W_CO_RES);
        } else {
            paused = magcal_cal_charge(&r->bud, CAL_W_FLAG); /* not an inlier */
        }
    }
    return paused;
}

/* Coarse 1: residual RMS of the inliers (mask_a) around the circle, then the residual threshold
 * as the consensus sets it (k_sigma x RMS, clamped to [min_thr_rel, max_thr_rel] x radius). */
MAGCAL_NOINLINE magcal_status_t magcal_ph_co_res(magcal_calibrator_t *cal, cal_run_t *r)
{
    cal_prep_t *q = cal_prep(cal);
    const magcal_consensus_cfg_t *cc = &cal->cfg.consensus;
    float thr;
    if (r->sub == 0u) {
        r->m = 0u;
        r->sub = 1u;
    }
    if (cal_coarse_res_pass(cal, r, q, cal->mask_a) != 0) {
        return MAGCAL_IN_PROGRESS;
    }
    if (r->m < cal->cfg.min_samples) {
        return MAGCAL_ERR_TOO_FEW_POINTS;
    }
    thr = cc->k_sigma * sqrtf(q->ss / (float)r->m);
    thr = fmaxf(thr, cc->min_thr_rel * q->cr);
    q->thr = fminf(thr, cc->max_thr_rel * q->cr);
    (void)memset(q->a, 0, sizeof q->a);
    (void)memset(q->b, 0, sizeof q->b);
    cal_goto(r, PH_CO_GATE);
    r->m = 0u;
    return MAGCAL_OK;
}

/* Coarse 2: inliers within the threshold into mask_b (flags with the residual bit), and the
 * circle's normal equations of them (the centred, scaled frame of ph_moments). */
MAGCAL_NOINLINE magcal_status_t magcal_ph_co_gate(magcal_calibrator_t *cal, cal_run_t *r)
{
    cal_prep_t *q = cal_prep(cal);
    while (r->i < cal->n) {
        const size_t i = r->i;
        uint8_t in = 0u;
        r->i++;
        if (cal->mask_a[i] != 0u && fabsf(cal_coarse_res(q, cal->buf[i])) <= q->thr) {
            const float u = (cal->buf[i].x - q->mx) / q->s;
            const float v = (cal->buf[i].y - q->my) / q->s;
            const float y = -(u * u + v * v);
            const float w[3] = {u, v, 1.0f};
            magcal_normal_add(q->a, q->b, w, 3u, y);
            in = 1u;
            r->m++;
        }
        cal->mask_b[i] = in;
        cal->flags[i] = (uint8_t)(MAGCAL_CALIBRATOR_FLAG_JUDGED |
                                  (cal->mask_a[i] == 0u ? MAGCAL_CALIBRATOR_FLAG_FILTER : 0u) |
                                  (in == 0u ? MAGCAL_CALIBRATOR_FLAG_RESIDUAL : 0u));
        if (magcal_cal_charge(&r->bud, CAL_W_CO_GATE) != 0) {
            return MAGCAL_IN_PROGRESS;
        }
    }
    cal->n_judged = cal->n;
    if (r->m < cal->cfg.min_samples || r->m < 3u) {
        return MAGCAL_ERR_TOO_FEW_POINTS;
    }
    cal_goto(r, PH_CO_FIT);
    return MAGCAL_OK;
}

/* Coarse 3: the refitted circle, its residual RMS (a pass), the report, the gates of the full
 * solve that apply to a circle, and the calibration (offset = centre, matrix = output scale). */
MAGCAL_NOINLINE magcal_status_t magcal_ph_co_fit(magcal_calibrator_t *cal, cal_run_t *r)
{
    cal_prep_t *q = cal_prep(cal);
    cal_adopt_t *d = cal_adopt(cal);
    magcal_cal_report_t *rep = &r->rep;
    float scale;
    if (r->sub == 0u) {
        magcal_status_t st = magcal_ldlt_solve(q->a, q->b, 3u, 1.0e-6f, NULL);
        (void)magcal_cal_charge(&r->bud, CAL_W_CO_FIT);
        if (st != MAGCAL_OK) {
            return st == MAGCAL_ERR_ILL_CONDITIONED ? MAGCAL_ERR_DEGENERATE : st;
        }
        q->cc.x = q->mx - 0.5f * q->b[0] * q->s;
        q->cc.y = q->my - 0.5f * q->b[1] * q->s;
        if (magcal_coarse_radius(q) == 0) {
            return MAGCAL_ERR_DEGENERATE;
        }
        q->ss = 0.0f;
        r->m = 0u;
        r->sub = 1u;
    }
    if (cal_coarse_res_pass(cal, r, q, cal->mask_b) != 0) {
        return MAGCAL_IN_PROGRESS;
    }
    rep->used = (uint16_t)r->m;
    rep->outliers = (uint16_t)(cal->n - r->m);
    rep->threshold = q->thr;
    rep->radius = q->cr;
    rep->residual_rms = sqrtf(q->ss / (float)r->m);
    rep->residual_rel = rep->residual_rms / q->cr;
    rep->axis_ratio = 1.0f;
    (void)memset(&rep->ellipse, 0, sizeof rep->ellipse);
    rep->ellipse.center = q->cc;
    rep->ellipse.semi_minor = q->cr;
    rep->ellipse.semi_major = q->cr;
    rep->ellipse.residual_rms = rep->residual_rms;
    /* the consistency gate as the full solve's (calibrator_fit.c): the circle's inliers are
     * filter inliers, so the plausible samples it leaves out are the filter's inliers minus them */
    if (rep->rejected_filter <= cal->n && r->m <= cal->n - rep->rejected_filter &&
        magcal_cal_inconsistent(cal, cal->n - rep->rejected_filter, cal->n - rep->rejected_filter - r->m) != 0) {
        return MAGCAL_ERR_INCONSISTENT;
    }
    if ((float)rep->outliers > cal->cfg.max_outlier_frac * (float)cal->n) {
        return MAGCAL_ERR_TOO_MANY_OUTLIERS;
    }
    if ((cal->cfg.min_radius > 0.0f && q->cr < cal->cfg.min_radius) ||
        (cal->cfg.max_radius > 0.0f && q->cr > cal->cfg.max_radius)) {
        return MAGCAL_ERR_RADIUS_RANGE;
    }
    if (!(rep->residual_rel <= cal->cfg.max_residual_rel)) {
        return MAGCAL_ERR_RESIDUAL;
    }
    scale = cal->cfg.output_radius > 0.0f ? cal->cfg.output_radius / q->cr : 1.0f;
    d->next.offset = q->cc;
    d->next.m[0][0] = scale;
    d->next.m[0][1] = 0.0f;
    d->next.m[1][0] = 0.0f;
    d->next.m[1][1] = scale;
    d->next.radius = q->cr * scale;
    d->next.magic = MAGCAL_CAL2D_MAGIC;
    rep->cal = d->next;
    cal_goto(r, PH_COVC);
    return MAGCAL_OK;
}

/* Coarse stage: the circle calibration's heading-error bound from its own harmonics (calibrator.h
 * "Coarse stage"): sqrt(1/2 |beta|^2) + |beta|^2 + 3 x the noise part's RMS + bias (with repeated values the
 * noise part's upper confidence factor, as the full gate), gated by the tolerance. */
magcal_status_t magcal_coarse_bound(const magcal_calibrator_t *cal, cal_run_t *r, const cal_adopt_t *d)
{
    magcal_cal_report_t *rep = &r->rep;
    const magcal_cal_harm_t *hn = &d->hn;
    const float noise = hn->sigma_rel;
    float npart = sqrtf(hn->noise2);
    float bound;
    if (d->distinct < (size_t)rep->used) {
        const float dof = d->distinct > 6u ? (float)d->distinct - 5.0f : 1.0f;
        npart *= 1.0f + 1.0f / sqrtf(2.0f * dof);
    }
    /* + 2 err2: the second-order allowance (the harmonics are the first-order terms of |h| in the
     * centre and soft-iron errors; the next term is O(|beta|^2): 1 x err2 was measured short on
     * tests/test_continuous.c's strong soft iron once the sliced drain changed which samples the
     * circle saw (bound 9.13 deg, truth 9.19): twice it, so the stated bound is an upper one) */
    bound = sqrtf(hn->err2) + 2.0f * hn->err2 + 3.0f * npart + sqrtf(hn->bias2);
    rep->est_noise_deg = MAGCAL_DEG_PER_RAD_F * noise;
    rep->design_factor = hn->design;
    rep->est_param_err_deg = MAGCAL_DEG_PER_RAD_F * bound;
    rep->est_heading_err_deg = MAGCAL_DEG_PER_RAD_F * sqrtf(noise * noise + bound * bound);
    if (!(rep->est_param_err_deg <= cal->coarse_max_err)) {
        return MAGCAL_ERR_UNOBSERVABLE; /* the arc does not bound the unseen soft iron well enough */
    }
    cal_goto(r, PH_VALID);
    return MAGCAL_OK;
}

#endif /* MAGCAL_CFG_ENABLE_COARSE */
