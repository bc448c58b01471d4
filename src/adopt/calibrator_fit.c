/*
 * The solve's fit and gates phases (calibrator_solve_internal.h): the thinning and the consensus
 * (or the plain least-squares fit and its mask), the filter flags again, then the flags with
 * residual bits, the counts, the report and the gates of a full ellipse.
 */
#include <math.h>
#include <string.h>

#include "calibrator_solve_internal.h"

/* Minimal sets from one candidate per clump (optics.h magcal_optics_thin): samples of a vehicle
 * parked at one heading must not fill the draws; flags hold the thinned mask meanwhile. */
MAGCAL_NOINLINE magcal_status_t magcal_ph_thin(magcal_calibrator_t *cal, cal_run_t *r)
{
    magcal_status_t st = MAGCAL_ERR_ARG;
    if (r->sub == 0u) {
        const uint8_t *cand = r->rep.filter_fragmented != 0u ? NULL : cal->mask_a;
        r->cand = (uint8_t)(r->rep.filter_fragmented != 0u ? 0u : 1u);
        if (cal->n >= 16u) {
            st = magcal_optics_thin_begin(&r->u.thin, cal->buf, cal->n, cand, cal->scratch,
                                          cal->scratch_len, cal->flags);
        }
        r->sub = 1u;
        if (st == MAGCAL_OK) {
            r->sub = 2u;
        }
    }
    if (r->sub == 2u) {
        st = cal_module_done(r, magcal_optics_thin_step(&r->u.thin, cal_left(r)), CAL_W_ONESHOT);
        if (st == MAGCAL_IN_PROGRESS) {
            return st;
        }
        if (st == MAGCAL_OK) {
            r->cand = 2u;
        }
    }
    cal_goto(r, PH_CONS);
    return MAGCAL_OK;
}

/* 4. consensus into run->cres, inlier mask into mask_b. */
MAGCAL_NOINLINE magcal_status_t magcal_ph_cons(magcal_calibrator_t *cal, cal_run_t *r)
{
    magcal_status_t st;
    if (r->sub == 0u) {
        const uint8_t *cand = r->cand == 0u ? NULL : (r->cand == 1u ? cal->mask_a : cal->flags);
        st = magcal_consensus_begin(&r->u.cons, &cal->cfg.consensus, cal->buf, cal->n, cand,
                                    cal->scratch, MAGCAL_CONSENSUS_WORKSPACE_LEN(cal->capacity),
                                    cal->mask_b, &r->cres);
        r->sub = 1u;
        if (st != MAGCAL_OK) {
            r->held = st;
            cal_goto(r, PH_FLAGS0);
            return MAGCAL_OK;
        }
    }
    st = magcal_consensus_step(&r->u.cons, cal_left(r));
    st = cal_module_done(r, st, r->u.cons.used_);
    if (st == MAGCAL_IN_PROGRESS) {
        return st;
    }
    r->held = st;
    cal_goto(r, PH_FLAGS0);
    return MAGCAL_OK;
}

/* The filter flags again (the thinning used the flags; the gates set the residual bits). After a
 * clean pre-test no sample is a filter reject: mask_a becomes all ones (the consensus rejects are
 * residual rejects, counted as such by the gates). */
MAGCAL_NOINLINE magcal_status_t magcal_ph_flags0(magcal_calibrator_t *cal, cal_run_t *r)
{
    while (r->i < cal->n) {
        const size_t i = r->i;
        if (r->pre != 0u) {
            cal->mask_a[i] = 1u;
        }
        cal->flags[i] = cal->mask_a[i] == 0u
                            ? (uint8_t)(MAGCAL_CALIBRATOR_FLAG_JUDGED | MAGCAL_CALIBRATOR_FLAG_FILTER)
                            : (uint8_t)MAGCAL_CALIBRATOR_FLAG_JUDGED;
        r->i++;
        if (magcal_cal_charge(&r->bud, CAL_W_FLAG) != 0) {
            return MAGCAL_IN_PROGRESS;
        }
    }
    cal->n_judged = cal->n;
    if (r->held != MAGCAL_OK) {
        return r->held;
    }
    cal_goto(r, PH_GATES);
    return MAGCAL_OK;
}

/* Plain least-squares fit of the filter inliers (use_consensus = 0). */
MAGCAL_NOINLINE magcal_status_t magcal_ph_plain(magcal_calibrator_t *cal, cal_run_t *r)
{
    magcal_ellipse_fit_slice_t *es = cal_plain_slice(cal);
    magcal_status_t st;
    if (r->sub == 0u) {
        st = magcal_ellipse_fit_begin(es, cal->buf, cal->n, cal->mask_a, &r->cres.fit);
        if (st != MAGCAL_OK) {
            return st;
        }
        r->sub = 1u;
    }
    st = magcal_ellipse_fit_step(es, cal_left(r));
    st = cal_module_done(r, st, es->used_);
    if (st != MAGCAL_OK) {
        return st; /* MAGCAL_IN_PROGRESS, or the fit's failure */
    }
    cal_goto(r, PH_PLAIN_MASK);
    r->m = 0u;
    return MAGCAL_OK;
}

/* Its mask and the classify() threshold: k_sigma * residual RMS, clamped like the consensus's. */
MAGCAL_NOINLINE magcal_status_t magcal_ph_plain_mask(magcal_calibrator_t *cal, cal_run_t *r)
{
    magcal_consensus_result_t *res = &r->cres;
    float rm;
    float thr;
    while (r->i < cal->n) {
        const size_t i = r->i;
        cal->mask_b[i] = cal->mask_a[i];
        if (cal->mask_a[i] != 0u) {
            r->m++;
        }
        r->i++;
        if (magcal_cal_charge(&r->bud, CAL_W_FLAG) != 0) {
            return MAGCAL_IN_PROGRESS;
        }
    }
    rm = sqrtf(res->fit.semi_minor * res->fit.semi_major);
    thr = cal->cfg.consensus.k_sigma * res->fit.residual_rms;
    thr = fmaxf(thr, cal->cfg.consensus.min_thr_rel * rm);
    thr = fminf(thr, cal->cfg.consensus.max_thr_rel * rm);
    res->sigma = res->fit.residual_rms;
    res->threshold = thr;
    res->n_candidates = (uint16_t)r->m;
    res->n_inliers = (uint16_t)r->m;
    res->n_rescued = 0u;
    res->n_rejected = 0u;
    cal_goto(r, PH_GATES);
    return MAGCAL_OK;
}

/* ------------------------------------------------------------------ gates */

/* Consistency gate (cfg.max_inconsistent_frac, 0 = off): 1 when the residual stage rejected more
 * than that share of the plausible samples (the density filter's inliers). A store that spans a
 * change of the hard iron holds two rings offset by the change; the consensus then keeps one ring
 * and the arcs where both cross, or a compromise between them, and leaves a large share of
 * samples that are neither glitches nor saturated out (30-min drive seed 1: 34 of 88, a
 * calibration halfway between the two installations). One installation's store leaves its noise
 * tail and the samples of transients out (the clean drives: at most 0.29). */
int magcal_cal_inconsistent(const magcal_calibrator_t *cal, size_t plausible, size_t rejected)
{
    const float lim = cal->cfg.max_inconsistent_frac;
    return lim > 0.0f && plausible > 0u && (float)rejected > lim * (float)plausible ? 1 : 0;
}

/* 4 (cont.) and 5: keep the fit, flags with residual bits, counts, the report, gates. */
MAGCAL_NOINLINE magcal_status_t magcal_ph_gates(magcal_calibrator_t *cal, cal_run_t *r)
{
    const magcal_consensus_result_t *cres = &r->cres;
    magcal_cal_report_t *rep = &r->rep;
    const size_t n = cal->n;
    size_t n_out;
    float radius;
    if (r->sub == 0u) {
        cal->fit = cres->fit;
        cal->threshold = cres->threshold;
        cal->has_fit = 1u;
        r->m = 0u; /* used */
        r->sub = 1u;
    }
    while (r->i < n) {
        const size_t i = r->i;
        uint8_t f = MAGCAL_CALIBRATOR_FLAG_JUDGED;
        if (cal->mask_a[i] == 0u) {
            f = (uint8_t)(f | MAGCAL_CALIBRATOR_FLAG_FILTER);
        }
        if (cal->mask_b[i] == 0u) {
            f = (uint8_t)(f | MAGCAL_CALIBRATOR_FLAG_RESIDUAL);
        }
        cal->flags[i] = f;
        if (cal->mask_b[i] != 0u) {
            r->m++;
            if (cal->mask_a[i] == 0u) {
                rep->rescued_consensus++;
            }
        } else if (cal->mask_a[i] != 0u) {
            rep->rejected_consensus++;
        } else {
            /* rejected by the filter and by the consensus */
        }
        r->i++;
        if (magcal_cal_charge(&r->bud, CAL_W_GATES) != 0) {
            return MAGCAL_IN_PROGRESS;
        }
    }
    cal->n_judged = n;
    rep->used = (uint16_t)r->m;
    rep->outliers = (uint16_t)(n - r->m);
    rep->ellipse = cres->fit;
    rep->threshold = cres->threshold;
    radius = sqrtf(cres->fit.semi_minor * cres->fit.semi_major);
    rep->radius = radius;
    rep->residual_rms = cres->fit.residual_rms;
    rep->residual_rel = radius > 0.0f ? cres->fit.residual_rms / radius : INFINITY;
    rep->axis_ratio =
        cres->fit.semi_major > 0.0f ? cres->fit.semi_minor / cres->fit.semi_major : 0.0f;
    rep->min_pivot = cres->fit.min_pivot;

    /* 5. gates */
    n_out = n - r->m;
    if (r->m < cal->cfg.min_samples) {
        return MAGCAL_ERR_TOO_FEW_POINTS;
    }
    if (magcal_cal_inconsistent(cal, (size_t)rep->rejected_consensus + r->m - rep->rescued_consensus,
                                rep->rejected_consensus) != 0) {
        return MAGCAL_ERR_INCONSISTENT;
    }
    if ((float)n_out > cal->cfg.max_outlier_frac * (float)n) {
        return MAGCAL_ERR_TOO_MANY_OUTLIERS;
    }
    if ((cal->cfg.min_radius > 0.0f && radius < cal->cfg.min_radius) ||
        (cal->cfg.max_radius > 0.0f && radius > cal->cfg.max_radius)) {
        return MAGCAL_ERR_RADIUS_RANGE;
    }
    if (rep->axis_ratio < cal->cfg.min_axis_ratio) {
        return MAGCAL_ERR_AXIS_RATIO;
    }
    if (!(rep->residual_rel <= cal->cfg.max_residual_rel)) {
        return MAGCAL_ERR_RESIDUAL;
    }
    cal_goto(r, PH_TOCAL);
    return MAGCAL_OK;
}
