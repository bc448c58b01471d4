/*
 * The solve's adopt phases (calibrator_solve_internal.h): the new calibration, its corrected
 * coverage, the distinct values, its harmonics (observability gate; a coarse solve's bound is
 * calibrator_coarse.c's; an arc solve's whole-circle bound is ph_arc), the heading shift, the installed calibration's harmonics and the
 * adoption rule (calibrator.h file comment).
 */
#include <math.h>
#include <string.h>

#include "calibrator_solve_internal.h"

static void cal_sincos5(size_t k, float *sn, float *cs);

/* 6. the correction of the new fit. */
MAGCAL_NOINLINE magcal_status_t magcal_ph_tocal(magcal_calibrator_t *cal, cal_run_t *r)
{
    cal_adopt_t *d = cal_adopt(cal);
    magcal_status_t st = magcal_ellipse_to_cal(&r->cres.fit, cal->cfg.form, cal->cfg.output_radius,
                                               &d->next);
    (void)magcal_cal_charge(&r->bud, CAL_W_TOCAL);
    if (st != MAGCAL_OK) {
        return st;
    }
    r->rep.cal = d->next;
    cal_goto(r, PH_COVC);
    return MAGCAL_OK;
}

/* Final coverage: bins of the corrected headings of the consensus inliers. */
MAGCAL_NOINLINE magcal_status_t magcal_ph_covc(magcal_calibrator_t *cal, cal_run_t *r)
{
    cal_adopt_t *d = cal_adopt(cal);
    magcal_cal_report_t *rep = &r->rep;
    float cov;
    if (r->sub == 0u) {
        (void)memset(d->bins, 0, sizeof d->bins);
        r->sub = 1u;
    }
    while (r->i < cal->n) {
        const size_t i = r->i;
        magcal_vec2_t h;
        r->i++;
        if (cal->mask_b[i] != 0u) {
            if (magcal_correct_apply(&d->next, cal->buf[i], &h) == MAGCAL_OK) {
                d->bins[magcal_cal_bin_of(magcal_cal_angle_deg(h.x, h.y))] = 1u;
            }
            if (magcal_cal_charge(&r->bud, CAL_W_COVCORR) != 0) {
                return MAGCAL_IN_PROGRESS;
            }
        } else if (magcal_cal_charge(&r->bud, CAL_W_FLAG) != 0) {
            return MAGCAL_IN_PROGRESS;
        } else {
            /* not an inlier */
        }
    }
    cov = magcal_cal_coverage_of(d->bins, &rep->missing_start_deg, &rep->missing_width_deg);
    rep->coverage_deg = cov;
    (void)magcal_cal_charge(&r->bud, CAL_W_COVFIN);
    if (rep->coarse == 0u && cov < cal->cfg.min_coverage_deg && cal->arc_min_cov > 0.0f) {
        rep->arc = 1u; /* the pre-gate passed around the circle centre, the corrected headings span
                          less: an arc, judged by its whole-circle bound ("Arc stage") */
    }
    if (cov < (rep->coarse != 0u ? cal->coarse_min_cov
                                 : (rep->arc != 0u ? cal->arc_min_cov : cal->cfg.min_coverage_deg)) ||
        !(cov > 0.0f)) {
        return MAGCAL_ERR_COVERAGE;
    }
    cal_goto(r, PH_DIST);
    return MAGCAL_OK;
}

/* Distinct values of the inliers: duplicates factor and the quantisation floor. */
MAGCAL_NOINLINE magcal_status_t magcal_ph_dist(magcal_calibrator_t *cal, cal_run_t *r)
{
    cal_adopt_t *d = cal_adopt(cal);
    magcal_cal_report_t *rep = &r->rep;
    magcal_cal_distinct_slice_t *ds = &d->u.dist;
    if (r->sub == 0u) {
        magcal_cal_distinct_begin(ds, cal->buf, cal->n, cal->mask_b, cal_est_idx(cal));
        r->sub = 1u;
    }
    if (magcal_cal_distinct_step(ds, &r->bud) == 0) {
        return MAGCAL_IN_PROGRESS;
    }
    d->distinct = ds->distinct;
    d->dup = ds->distinct > 0u ? (float)rep->used / (float)ds->distinct : 1.0f;
    if (d->dup < 1.0f) {
        d->dup = 1.0f;
    }
    rep->distinct = (uint16_t)ds->distinct;
    /* quantisation: a lattice of few distinct values can lie on a conic far from the truth with
     * almost no residual; its heading noise is at least that of a uniform error of one step */
    d->floor_rel = rep->radius > 0.0f ? ds->step / (rep->radius * 3.4641016f) : 0.0f;
    cal_goto(r, PH_HARM_N);
    return MAGCAL_OK;
}

/* Estimates of the new calibration (report fields est_*) and the observability gate. */
MAGCAL_NOINLINE magcal_status_t magcal_ph_harm_n(magcal_calibrator_t *cal, cal_run_t *r)
{
    cal_adopt_t *d = cal_adopt(cal);
    magcal_cal_report_t *rep = &r->rep;
    const magcal_cal_harm_t *hn = &d->hn;
    const size_t distinct = d->distinct;
    float noise;
    float par;
    if (r->sub == 0u) {
        magcal_cal_harm_begin(&d->u.harm, cal->buf, cal->n, cal->mask_b, &d->next, d->dup,
                              d->floor_rel, cal_est_scratch(cal), &d->hn);
        r->sub = 1u;
    }
    if (magcal_cal_harm_step(&d->u.harm, &r->bud) == 0) {
        return MAGCAL_IN_PROGRESS;
    }
    if (hn->ok == 0u) {
        return MAGCAL_ERR_UNOBSERVABLE; /* headings too clumped to separate centre and soft iron */
    }
#if MAGCAL_CFG_ENABLE_COARSE
    if (rep->coarse != 0u) {
        return magcal_coarse_bound(cal, r, d);
    }
#endif
    /* per-sample heading noise of new data: the relative radial residual after the harmonics
     * (the fit's own residual, dof corrected); tangential and radial noise have the same RMS
     * over uniformly spread headings */
    noise = hn->sigma_rel;
    rep->est_noise_deg = MAGCAL_DEG_PER_RAD_F * noise;
    rep->design_factor = hn->design;
    {
        /* the caller's model-error term (magcal_calibrator_set_model: the continuous store's tilt) */
        const float m = cal->model_deg / MAGCAL_DEG_PER_RAD_F;
        rep->est_param_err_deg = MAGCAL_DEG_PER_RAD_F * sqrtf(hn->noise2 + hn->bias2 + m * m);
        rep->est_heading_err_deg = MAGCAL_DEG_PER_RAD_F * sqrtf(noise * noise + hn->noise2 + hn->bias2 + m * m);
    }
    /* repeated values (quantisation): the estimate rests on the distinct values only, so the
     * gate uses its upper confidence bound, (1 + 1 / sqrt(2 dof)) with dof = distinct - 5 */
    par = sqrtf(hn->noise2 + hn->bias2);
    if (distinct < (size_t)rep->used) {
        float dof = distinct > 6u ? (float)distinct - 5.0f : 1.0f;
        par *= 1.0f + 1.0f / sqrtf(2.0f * dof);
    }
    if (rep->arc != 0u) {
        rep->est_param_err_deg = NAN; /* the bound replaces the estimate (ph_arc) */
        rep->est_heading_err_deg = NAN;
        cal_goto(r, PH_ARC); /* judged by its whole-circle bound instead (ph_arc) */
        d->arc_v2 = 0.0f;
        return MAGCAL_OK;
    }
    if (!(par <= cal->cfg.max_param_err_ratio * noise) ||
        !(hn->design <= cal->cfg.max_design_factor)) {
        return MAGCAL_ERR_UNOBSERVABLE;
    }
    cal_goto(r, PH_VALID);
    return MAGCAL_OK;
}

/* Arc stage (calibrator.h "Arc stage"): the new ellipse's heading-error variance at 36 headings
 * of the WHOLE circle, one per visit, from the harmonics' covariance C = s_p^2 dup (G^T G)^-1
 * (4x4 block over cos, sin, cos 2, sin 2 of the corrected direction phi: calibrator_adopt.c). A
 * parameter error beta gives the heading error -b1 sin phi + b2 cos phi - b3 sin 2phi + b4 cos 2phi
 * (docs/calibrator.md "Heading-error estimate"), so its variance at phi is w^T C w with
 * w = (-sin phi, cos phi, -sin 2phi, cos 2phi); the headings the arc never saw are where it is
 * largest. Then the bound and its gate. */
MAGCAL_NOINLINE magcal_status_t magcal_ph_arc(magcal_calibrator_t *cal, cal_run_t *r)
{
    cal_adopt_t *d = cal_adopt(cal);
    magcal_cal_report_t *rep = &r->rep;
    const magcal_cal_harm_t *hn = &d->hn;
    const float *inv4 = cal_est_scratch(cal) + CAL_HARM_INV4;
    const float c = d->u.harm.s2p * d->u.harm.dup;
    float npart;
    float bound;
    while (r->i < CAL_ARC_HEADINGS) {
        const size_t k = r->i;
        float w[4];
        float v = 0.0f;
        size_t a;
        size_t b;
        r->i++;
        cal_sincos5(2u * k, &w[0], &w[1]);
        cal_sincos5((4u * k) % CAL_SHIFT_STEPS, &w[2], &w[3]);
        w[0] = -w[0];
        w[2] = -w[2];
        for (a = 0u; a < 4u; ++a) {
            for (b = 0u; b < 4u; ++b) {
                v += w[a] * inv4[a * 4u + b] * w[b];
            }
        }
        d->arc_v2 = fmaxf(d->arc_v2, c * v);
        if (magcal_cal_charge(&r->bud, CAL_W_ARC) != 0) {
            return MAGCAL_IN_PROGRESS;
        }
    }
    npart = sqrtf(d->arc_v2);
    if (d->distinct < (size_t)rep->used) {
        const float dof = d->distinct > 6u ? (float)d->distinct - 5.0f : 1.0f;
        npart *= 1.0f + 1.0f / sqrtf(2.0f * dof); /* repeated values: upper confidence, as the full gate */
    }
    /* the bound, rad: what the fit's own harmonics still show, 3 x the largest sd over the whole
     * circle, the O(sigma^2) bias and the model term (what a partial arc cannot see: a tilt or a
     * vertical-field leak the fit absorbs; measured on the drives, docs/calibrator.md) */
    bound = sqrtf(hn->err2) + 3.0f * npart + sqrtf(hn->bias2) + cal->arc_model / MAGCAL_DEG_PER_RAD_F;
    rep->est_param_err_deg = MAGCAL_DEG_PER_RAD_F * bound;
    rep->est_heading_err_deg = MAGCAL_DEG_PER_RAD_F * sqrtf(hn->sigma_rel * hn->sigma_rel + bound * bound);
    (void)magcal_cal_charge(&r->bud, CAL_W_PHASE);
    /* less coverage needs a stronger check: the consistency gate at MAGCAL_CALIBRATOR_ARC_INCONSISTENT
     * (a store of two installations seen over arcs is fitted by a compromise the bound cannot see:
     * 30-min drives s3, s4, 35 deg off at a share of 0.20..0.22) */
    if ((float)rep->rejected_consensus >
        MAGCAL_CALIBRATOR_ARC_INCONSISTENT * ((float)rep->rejected_consensus + (float)rep->used - (float)rep->rescued_consensus)) {
        return MAGCAL_ERR_INCONSISTENT;
    }
    if (!(rep->est_param_err_deg <= cal->arc_max_err)) {
        return MAGCAL_ERR_UNOBSERVABLE; /* the arc does not bound the whole circle well enough */
    }
    cal_goto(r, PH_VALID);
    return MAGCAL_OK;
}

/* 2x2 inverse of a calibration matrix. */
static int cal_inv2(const float m[2][2], float inv[2][2])
{
    float det = m[0][0] * m[1][1] - m[0][1] * m[1][0];
    if (!(fabsf(det) > 0.0f) || !magcal_isfinite_f(det)) {
        return -1;
    }
    inv[0][0] = m[1][1] / det;
    inv[0][1] = -m[0][1] / det;
    inv[1][0] = -m[1][0] / det;
    inv[1][1] = m[0][0] / det;
    return 0;
}

/* 7. adoption rule (file comment of calibrator.h): an unusable installed calibration is replaced
 * (after the shift from the identity). */
MAGCAL_NOINLINE magcal_status_t magcal_ph_valid(const magcal_calibrator_t *cal, const magcal_cal2d_t *current, cal_run_t *r)
{
    cal_adopt_t *d = cal_adopt(cal);
    d->unusable = (uint8_t)((magcal_cal2d_validate(current) != MAGCAL_OK || !(current->radius > 0.0f))
                                ? 1u
                                : 0u);
    cal_goto(r, PH_SHIFT);
    d->sh_mx = 0.0f;
    d->sh_ss = 0.0f;
    d->sh_cnt = 0u;
    (void)magcal_cal_charge(&r->bud, CAL_W_PHASE);
    return MAGCAL_OK;
}

/* sin and cos of k * 5 deg, k < 72 (quadrant q = k / 18, j = k % 18): the shift's test headings
 * are multiples of 5 deg (CAL_SHIFT_STEPS), so their sines and cosines come from a quarter-wave
 * table of sin(5 j deg), j = 0..18, instead of sinf/cosf (whose argument reduction is ~3 KB of
 * flash). */
static void cal_sincos5(size_t k, float *sn, float *cs)
{
    static const float cal_sin5[19] = {
        0.000000000e+00f, 8.715574275e-02f, 1.736481777e-01f, 2.588190451e-01f, 3.420201433e-01f,
        4.226182617e-01f, 5.000000000e-01f, 5.735764364e-01f, 6.427876097e-01f, 7.071067812e-01f,
        7.660444431e-01f, 8.191520443e-01f, 8.660254038e-01f, 9.063077870e-01f, 9.396926208e-01f,
        9.659258263e-01f, 9.848077530e-01f, 9.961946981e-01f, 1.000000000e+00f};
    size_t q = k / 18u;
    size_t j = k % 18u;
    float a = cal_sin5[j];
    float b = cal_sin5[18u - j];
    switch (q) {
    case 0u:
        *sn = a;
        *cs = b;
        break;
    case 1u:
        *sn = b;
        *cs = -a;
        break;
    case 2u:
        *sn = -a;
        *cs = -b;
        break;
    default:
        *sn = -b;
        *cs = a;
        break;
    }
}

/* cppcheck-suppress misra-c2012-2.3 ; deviation D4: a static assert is an unused typedef */
MAGCAL_STATIC_ASSERT(CAL_SHIFT_STEPS == 72u, shift_steps_match_sine_table);

/* Heading change if `next` replaced `current` (unusable: from the identity), one test heading
 * per visit. */
MAGCAL_NOINLINE magcal_status_t magcal_ph_shift(const magcal_calibrator_t *cal, const magcal_cal2d_t *current, cal_run_t *r)
{
    cal_adopt_t *d = cal_adopt(cal);
    const magcal_cal2d_t *next = &d->next;
    const magcal_cal2d_t *cur = d->unusable != 0u ? NULL : current;
    float rr = next->radius > 0.0f ? next->radius : 1.0f;
    int singular = 0;
    if (r->sub == 0u) {
        singular = cal_inv2(next->m, d->inv);
        r->sub = 1u;
    }
    while (singular == 0 && r->i < CAL_SHIFT_STEPS) {
        const size_t k = r->i;
        float psi = (float)k * (360.0f / (float)CAL_SHIFT_STEPS);
        float sp;
        float cp;
        float hx;
        float hy;
        magcal_vec2_t raw;
        magcal_vec2_t h;
        float ph;
        int ok = 1;
        r->i++;
        cal_sincos5(k, &sp, &cp);
        hx = -rr * sp;
        hy = rr * cp;
        raw.x = d->inv[0][0] * hx + d->inv[0][1] * hy + next->offset.x;
        raw.y = d->inv[1][0] * hx + d->inv[1][1] * hy + next->offset.y;
        if (cur == NULL) {
            h = raw;
        } else if (magcal_correct_apply(cur, raw, &h) != MAGCAL_OK) {
            ok = 0;
        } else {
            /* corrected by the installed calibration */
        }
        if (ok != 0 && magcal_heading_from_field(h, &ph) == MAGCAL_OK) {
            float dd = fabsf(magcal_wrap180_deg(ph - psi));
            d->sh_mx = fmaxf(d->sh_mx, dd);
            d->sh_ss += dd * dd;
            d->sh_cnt++;
        }
        if (magcal_cal_charge(&r->bud, CAL_W_SHIFT) != 0) {
            return MAGCAL_IN_PROGRESS;
        }
    }
    if (singular != 0) {
        r->rep.shift_max_deg = NAN;
        r->rep.shift_rms_deg = NAN;
    } else {
        r->rep.shift_max_deg = d->sh_mx;
        r->rep.shift_rms_deg = d->sh_cnt > 0u ? sqrtf(d->sh_ss / (float)d->sh_cnt) : NAN;
    }
    cal_goto(r, PH_HARM_C);
    return MAGCAL_OK;
}

/* Harmonics of the installed calibration on the new inliers, then the rule. */
MAGCAL_NOINLINE magcal_status_t magcal_ph_harm_c(magcal_cal2d_t *current, magcal_calibrator_t *cal, cal_run_t *r)
{
    cal_adopt_t *d = cal_adopt(cal);
    magcal_cal_report_t *rep = &r->rep;
    const magcal_cal_harm_t *hc = &d->hc;
    if (d->unusable != 0u) {
        rep->adopt_rule = MAGCAL_ADOPT_UNUSABLE;
        *current = d->next;
        cal_goto(r, PH_DONE);
        return MAGCAL_OK;
    }
    if (r->sub == 0u) {
        magcal_cal_harm_begin(&d->u.harm, cal->buf, cal->n, cal->mask_b, current, d->dup,
                              d->floor_rel, cal_est_scratch(cal), &d->hc);
        r->sub = 1u;
    }
    if (magcal_cal_harm_step(&d->u.harm, &r->bud) == 0) {
        return MAGCAL_IN_PROGRESS;
    }
    if (hc->ok == 0u) {
        /* the current calibration maps the new inliers onto a point or leaves no usable radius */
        rep->current_err_deg = INFINITY;
        rep->current_err_z = INFINITY;
    } else {
        float ex = hc->err2 - hc->noise2; /* noise-free mean square error of `current` */
        rep->current_err_deg = MAGCAL_DEG_PER_RAD_F * sqrtf(fmaxf(ex, 0.0f));
        rep->current_err_z =
            hc->noise2_sd > 0.0f ? ex / hc->noise2_sd : (ex > 0.0f ? INFINITY : 0.0f);
    }
    if ((rep->coarse != 0u || rep->arc != 0u) && cal->current_coarse == 0u) {
        return MAGCAL_ERR_NOT_BETTER; /* a coarse or arc calibration never replaces a full one */
    }
    if (rep->current_err_deg > fmaxf((cal->current_coarse != 0u && rep->coarse == 0u && rep->arc == 0u ? 1.0f
                                                                                    : MAGCAL_CALIBRATOR_ADOPT_MARGIN) *
                                         rep->est_param_err_deg,
                                     MAGCAL_CALIBRATOR_ADOPT_MIN_DEG)) {
        /* a full calibration replaces a coarse one when not estimated worse (margin 1) */
        rep->adopt_rule = MAGCAL_ADOPT_BETTER;
    } else if (rep->current_err_z > MAGCAL_CALIBRATOR_STALE_Z &&
               rep->current_err_deg >= rep->est_param_err_deg &&
               rep->current_err_deg > MAGCAL_CALIBRATOR_ADOPT_MIN_DEG && hc->ok != 0u &&
               fabsf(hc->mean_radius / current->radius - 1.0f) <= cal->cfg.max_radius_change) {
        rep->adopt_rule = MAGCAL_ADOPT_STALE;
    } else {
        return MAGCAL_ERR_NOT_BETTER;
    }
    *current = d->next;
    cal_goto(r, PH_DONE);
    return MAGCAL_OK;
}
