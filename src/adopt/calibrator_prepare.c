/*
 * The solve's prepare phases (calibrator_solve_internal.h): pre-checks (count, identical, extent),
 * the pre-test (cfg.pretest), the density filter and its masks, mean, scale and moments of the
 * inliers, the collinearity test and the hard-iron circle, the coverage of every sample (the
 * pre-gate: the coarse stage starts here) and of the filter inliers.
 */
#include <float.h>
#include <math.h>
#include <string.h>

#include "calibrator_solve_internal.h"

/* ------------------------------------------------------------------ prepare */

MAGCAL_NOINLINE magcal_status_t magcal_ph_bbox(magcal_calibrator_t *cal, cal_run_t *r)
{
    while (r->i < cal->n) {
        const magcal_vec2_t p = cal->buf[r->i];
        if (r->i == 0u) {
            cal->bb_min = p;
            cal->bb_max = p;
        } else {
            cal->bb_min.x = fminf(cal->bb_min.x, p.x);
            cal->bb_min.y = fminf(cal->bb_min.y, p.y);
            cal->bb_max.x = fmaxf(cal->bb_max.x, p.x);
            cal->bb_max.y = fmaxf(cal->bb_max.y, p.y);
        }
        r->i++;
        if (magcal_cal_charge(&r->bud, CAL_W_BBOX) != 0) {
            return MAGCAL_IN_PROGRESS;
        }
    }
    cal_goto(r, PH_CHECK);
    return MAGCAL_OK;
}

/* 1. pre-checks: enough samples */
MAGCAL_NOINLINE magcal_status_t magcal_ph_check(magcal_calibrator_t *cal, cal_run_t *r)
{
    if (cal->n < cal->cfg.min_samples || cal->n < MAGCAL_ELLIPSE_MIN_POINTS) {
        return MAGCAL_ERR_TOO_FEW_POINTS;
    }
    cal_goto(r, PH_IDENT);
    r->i = 1u;
    return MAGCAL_OK;
}

/* All identical samples (checked before the density filter: far outliers cannot fake it). */
MAGCAL_NOINLINE magcal_status_t magcal_ph_ident(magcal_calibrator_t *cal, cal_run_t *r)
{
    const magcal_vec2_t *p = cal->buf;
    while (r->i < cal->n) {
        const size_t i = r->i;
        r->i++;
        if (p[i].x != p[0].x || p[i].y != p[0].y) {
            cal_goto(r, PH_EXTENT);
            return MAGCAL_OK;
        }
        if (magcal_cal_charge(&r->bud, CAL_W_IDENT) != 0) {
            return MAGCAL_IN_PROGRESS;
        }
    }
    return MAGCAL_ERR_DEGENERATE;
}

/* The pre-test applies with the default filter only (OPTICS grid, automatic eps and MinPts), with
 * the consensus on and at least 16 samples (the automatic filter's own minimum). */
static int cal_pretest_on(const magcal_calibrator_t *cal)
{
    const magcal_calibrator_cfg_t *c = &cal->cfg;
    return (c->pretest != 0u && c->filter == MAGCAL_FILTER_OPTICS_GRID && c->eps <= 0.0f &&
            c->min_pts == 0u && c->use_consensus != 0u && cal->n >= 16u)
               ? 1
               : 0;
}

MAGCAL_NOINLINE magcal_status_t magcal_ph_extent(magcal_calibrator_t *cal, cal_run_t *r)
{
    /* Extent of the samples: when its square is not a normal float32, squared distances and
     * moments lose their precision (the density filter's eps^2 test first): 0 = the points are
     * indistinguishable, otherwise too ill-conditioned for float32 (rings below ~1e-20). */
    const float ex = cal->bb_max.x - cal->bb_min.x;
    const float ey = cal->bb_max.y - cal->bb_min.y;
    const float ext = ex > ey ? ex : ey;
    const float ext2 = ext * ext;
    if (!(ext2 > 0.0f)) {
        return MAGCAL_ERR_DEGENERATE;
    }
    if (ext2 < FLT_MIN) {
        return MAGCAL_ERR_ILL_CONDITIONED;
    }
    cal_goto(r, cal_pretest_on(cal) != 0 ? PH_PRE_CONS : PH_FILTER);
    return MAGCAL_OK;
}

/* ------------------------------------------------------------------ pre-test (cfg.pretest)
 * Issue 14: the density filter and the thinning cost more than the fit; on a clean store they
 * reject nothing the consensus does not. The consensus runs first on every sample; when it
 * succeeds and rejects at most n / MAGCAL_CALIBRATOR_PRETEST_DIV samples, its inlier mask takes
 * the filter mask's place in the prepare phases (so a few glitches cannot move the circle centre
 * of the coverage pre-gate or fake collinearity) and its result is the fit. Otherwise the solve
 * goes on at PH_FILTER exactly as without the pre-test (every later phase rewrites what the
 * pre-test left: the consensus result, mask_b, the union), so its results are today's bit for bit;
 * the pre-test's consensus is then the price of a dirty store. */

/* The consensus on every sample into run->cres and mask_b; then the verdict. */
MAGCAL_NOINLINE magcal_status_t magcal_ph_pre_cons(magcal_calibrator_t *cal, cal_run_t *r)
{
    magcal_status_t st;
    if (r->sub == 0u) {
        (void)memset(&r->cres, 0, sizeof r->cres); /* as ph_cov_f: its padding is copied out */
        st = magcal_consensus_begin(&r->u.cons, &cal->cfg.consensus, cal->buf, cal->n, NULL,
                                    cal->scratch, MAGCAL_CONSENSUS_WORKSPACE_LEN(cal->capacity),
                                    cal->mask_b, &r->cres);
        (void)magcal_cal_charge(&r->bud, CAL_W_PHASE);
        if (st == MAGCAL_OK) {
            /* a round that leaves twice the bound out: a dirty store, the full pipeline (an early
             * end only ever costs the short path, never a result: the full one is today's) */
            st = magcal_consensus_limit_rejects(
                &r->u.cons, 2u * ((size_t)cal->n / MAGCAL_CALIBRATOR_PRETEST_DIV) + 1u);
        }
        if (st != MAGCAL_OK) {
            cal_goto(r, PH_FILTER); /* the full pipeline reports whatever is wrong */
            return MAGCAL_OK;
        }
        r->sub = 1u;
    }
    st = magcal_consensus_step(&r->u.cons, cal_left(r));
    st = cal_module_done(r, st, r->u.cons.used_);
    if (st == MAGCAL_IN_PROGRESS) {
        return st;
    }
    if (st == MAGCAL_OK &&
        (size_t)cal->n - (size_t)r->cres.n_inliers <= (size_t)cal->n / MAGCAL_CALIBRATOR_PRETEST_DIV) {
        cal_goto(r, PH_PRE_MASK);
        r->m = 0u;
    } else {
        cal_goto(r, PH_FILTER);
    }
    return MAGCAL_OK;
}

/* Few rejects: each must lie within CAL_PRE_FAR thresholds of the fit (else the full pipeline).
 * Clean: the consensus inliers are the prepare phases' mask (mask_a), counted, as ph_masks does
 * with the filter's; no sample is a filter reject. */
MAGCAL_NOINLINE magcal_status_t magcal_ph_pre_mask(magcal_calibrator_t *cal, cal_run_t *r)
{
    cal_prep_t *q = cal_prep(cal);
    const float far = CAL_PRE_FAR * r->cres.threshold;
    while (r->i < cal->n) {
        const size_t i = r->i;
        const uint8_t in = cal->mask_b[i];
        uint32_t w = CAL_W_MASKS;
        if (in == 0u) {
            const float res = magcal_ellipse_residual(&r->cres.fit, cal->buf[i]);
            if (!(fabsf(res) <= far)) {
                cal_goto(r, PH_FILTER); /* a singular point: the full pipeline */
                (void)magcal_cal_charge(&r->bud, CAL_W_PRE_RES);
                return MAGCAL_OK;
            }
            w = CAL_W_PRE_RES;
        }
        cal->mask_a[i] = in;
        r->m += in != 0u ? 1u : 0u;
        cal->flags[i] = MAGCAL_CALIBRATOR_FLAG_JUDGED;
        r->i++;
        if (magcal_cal_charge(&r->bud, w) != 0) {
            return MAGCAL_IN_PROGRESS;
        }
    }
    cal->n_judged = cal->n;
    r->rep.rejected_filter = 0u;
    r->rep.filter_eps = 0.0f;
    r->rep.filter_min_pts = 0u;
    r->rep.pretest_clean = 1u;
    r->pre = 1u;
    if (r->m < cal->cfg.min_samples) {
        return MAGCAL_ERR_TOO_FEW_POINTS;
    }
    cal_goto(r, PH_MEAN);
    q->mx = 0.0f;
    q->my = 0.0f;
    return MAGCAL_OK;
}

/* DBSCAN filter (one-shot inside one step: documented exception). */
static MAGCAL_NOINLINE magcal_status_t cal_filter_dbscan(magcal_calibrator_t *cal, cal_run_t *r)
{
#if MAGCAL_CFG_ENABLE_DBSCAN
    static const magcal_dbscan_cfg_t dc_default = MAGCAL_DBSCAN_CFG_DEFAULT;
    const magcal_calibrator_cfg_t *c = &cal->cfg;
    const size_t n = cal->n;
    magcal_dbscan_cfg_t *dc = &r->u.dc;
    int16_t *labels = (int16_t *)cal->scratch;
    size_t lab_len = (2u * n + 3u) & ~(size_t)3u;
    uint8_t *rest = (uint8_t *)cal->scratch + lab_len;
    size_t rest_len = cal->scratch_len - lab_len;
    magcal_status_t st;
    *dc = dc_default;
    if (c->eps > 0.0f) {
        dc->eps = c->eps;
        dc->min_pts = c->min_pts != 0u ? c->min_pts : 4u;
    } else {
        float e;
        float ep;
        uint16_t mp;
        st = magcal_optics_auto_params(cal->buf, n, cal->scratch, cal->scratch_len, &e, &mp, &ep);
        if (st != MAGCAL_OK) {
            return st;
        }
        dc->eps = ep;
        dc->min_pts = c->min_pts != 0u ? c->min_pts : mp;
    }
    st = magcal_dbscan_run(dc, cal->buf, n, rest, rest_len, labels, NULL, NULL);
    if (st != MAGCAL_OK) {
        return st;
    }
    st = magcal_optics_largest_cluster(labels, n, rest, rest_len, cal->flags, NULL, NULL);
    if (st != MAGCAL_OK) {
        return st;
    }
    r->rep.filter_eps = dc->eps;
    r->rep.filter_min_pts = dc->min_pts;
    return MAGCAL_OK;
#else
    (void)cal;
    (void)r;
    return MAGCAL_ERR_ARG; /* DBSCAN compiled out (config.h MAGCAL_CFG_ENABLE_DBSCAN = 0) */
#endif
}

/* OPTICS configuration of the run (the automatic radius with a caller's MinPts is one-shot). */
static MAGCAL_NOINLINE magcal_status_t cal_filter_optics_cfg(magcal_calibrator_t *cal, cal_run_t *r)
{
    static const magcal_optics_cfg_t oc_default = MAGCAL_OPTICS_CFG_DEFAULT;
    const magcal_calibrator_cfg_t *c = &cal->cfg;
    magcal_optics_cfg_t *oc = &r->oc;
    *oc = oc_default;
    if (c->filter == MAGCAL_FILTER_OPTICS_CLASSIC) {
        oc->order = MAGCAL_OPTICS_CLASSIC;
        oc->neighbors = MAGCAL_NEIGHBORS_BRUTE;
    }
    if (c->eps > 0.0f) {
        oc->eps = c->eps;
        oc->eps_prime = c->eps;
        oc->min_pts = c->min_pts != 0u ? c->min_pts : 4u;
    } else if (c->min_pts != 0u) {
        /* automatic radius, caller's MinPts */
        float e;
        float ep;
        uint16_t mp;
        magcal_status_t st =
            magcal_optics_auto_params(cal->buf, cal->n, cal->scratch, cal->scratch_len, &e, &mp, &ep);
        if (st != MAGCAL_OK) {
            return st;
        }
        oc->eps = e;
        oc->eps_prime = ep;
        oc->min_pts = c->min_pts;
        (void)magcal_cal_charge(&r->bud, CAL_W_ONESHOT);
    } else {
        /* fully automatic parameters: the OPTICS defaults */
    }
    return MAGCAL_OK;
}

/* 2. density filter: its 0/1 inlier mask into cal->flags (the scratch is in use until it ends). */
MAGCAL_NOINLINE magcal_status_t magcal_ph_filter(magcal_calibrator_t *cal, cal_run_t *r)
{
    const magcal_calibrator_cfg_t *c = &cal->cfg;
    magcal_status_t st;
    if (c->filter == MAGCAL_FILTER_NONE || (c->eps <= 0.0f && cal->n < 16u)) {
        /* no filter (auto parameters need 16 samples: below that every sample is a candidate) */
        while (r->i < cal->n) {
            cal->flags[r->i] = 1u;
            r->i++;
            if (magcal_cal_charge(&r->bud, CAL_W_FLAG) != 0) {
                return MAGCAL_IN_PROGRESS;
            }
        }
        r->rep.filter_eps = 0.0f;
        r->rep.filter_min_pts = 0u;
    } else if (c->filter == MAGCAL_FILTER_DBSCAN) {
        st = cal_filter_dbscan(cal, r);
        (void)magcal_cal_charge(&r->bud, CAL_W_ONESHOT);
        if (st != MAGCAL_OK) {
            return st;
        }
    } else {
        st = cal_filter_optics_cfg(cal, r);
        if (st == MAGCAL_OK) {
            st = magcal_optics_filter_begin(&r->u.filter, &r->oc, cal->buf, cal->n, cal->scratch,
                                            cal->scratch_len, cal->flags, &r->info);
        }
        if (st != MAGCAL_OK) {
            return st;
        }
        cal_goto(r, PH_FILTER_RUN);
        return MAGCAL_OK;
    }
    cal_goto(r, PH_MASKS);
    return MAGCAL_OK;
}

/* The OPTICS filter's steps (a phase of its own: only this small frame sits above them). */
MAGCAL_NOINLINE magcal_status_t magcal_ph_filter_run(cal_run_t *r)
{
    magcal_status_t st =
        cal_module_done(r, magcal_optics_filter_step(&r->u.filter, cal_left(r)), CAL_W_ONESHOT);
    if (st != MAGCAL_OK) {
        return st; /* MAGCAL_IN_PROGRESS, or the filter's failure */
    }
    r->rep.filter_eps = r->info.eps_prime;
    r->rep.filter_min_pts = r->info.min_pts;
    cal_goto(r, PH_MASKS);
    return MAGCAL_OK;
}

/* The filter mask into mask_a (the scratch is free now), counted; flags become flag bits. */
MAGCAL_NOINLINE magcal_status_t magcal_ph_masks(magcal_calibrator_t *cal, cal_run_t *r)
{
    cal_prep_t *q = cal_prep(cal);
    if (r->sub == 0u) {
        r->m = 0u;
        r->sub = 1u;
    }
    while (r->i < cal->n) {
        const size_t i = r->i;
        const uint8_t in = cal->flags[i];
        cal->mask_a[i] = in;
        if (in != 0u) {
            r->m++;
            cal->flags[i] = MAGCAL_CALIBRATOR_FLAG_JUDGED;
        } else {
            cal->flags[i] = (uint8_t)(MAGCAL_CALIBRATOR_FLAG_JUDGED | MAGCAL_CALIBRATOR_FLAG_FILTER);
        }
        r->i++;
        if (magcal_cal_charge(&r->bud, CAL_W_MASKS) != 0) {
            return MAGCAL_IN_PROGRESS;
        }
    }
    cal->n_judged = cal->n;
    r->rep.rejected_filter = (uint16_t)(cal->n - r->m);
    if (r->m < cal->cfg.min_samples) {
        return MAGCAL_ERR_TOO_FEW_POINTS;
    }
    cal_goto(r, PH_MEAN);
    q->mx = 0.0f;
    q->my = 0.0f;
    return MAGCAL_OK;
}

/* Mean of p / m of the filter inliers (summing p overflowed to Inf for samples near FLT_MAX). */
MAGCAL_NOINLINE magcal_status_t magcal_ph_mean(magcal_calibrator_t *cal, cal_run_t *r)
{
    cal_prep_t *q = cal_prep(cal);
    const float fm = (float)r->m;
    while (r->i < cal->n) {
        const size_t i = r->i;
        if (cal->mask_a[i] != 0u) {
            q->mx += cal->buf[i].x / fm;
            q->my += cal->buf[i].y / fm;
        }
        r->i++;
        if (magcal_cal_charge(&r->bud, CAL_W_MEAN) != 0) {
            return MAGCAL_IN_PROGRESS;
        }
    }
    cal_goto(r, PH_SCALE);
    q->s = 0.0f;
    return MAGCAL_OK;
}

/* Largest deviation from the mean (the moments are scaled by it: they cannot overflow; a ring of
 * radius 1e18 overflowed sxx to Inf and was called degenerate). */
MAGCAL_NOINLINE magcal_status_t magcal_ph_scale(magcal_calibrator_t *cal, cal_run_t *r)
{
    cal_prep_t *q = cal_prep(cal);
    while (r->i < cal->n) {
        const size_t i = r->i;
        if (cal->mask_a[i] != 0u) {
            q->s = fmaxf(q->s, fmaxf(fabsf(cal->buf[i].x - q->mx), fabsf(cal->buf[i].y - q->my)));
        }
        r->i++;
        if (magcal_cal_charge(&r->bud, CAL_W_SCALE) != 0) {
            return MAGCAL_IN_PROGRESS;
        }
    }
    if (!(q->s > 0.0f) || !magcal_isfinite_f(q->s)) {
        return MAGCAL_ERR_DEGENERATE; /* all identical, or a spread float32 cannot represent */
    }
    cal_goto(r, PH_MOMENTS);
    q->sxx = 0.0f;
    q->syy = 0.0f;
    q->sxy = 0.0f;
    (void)memset(q->a, 0, sizeof q->a);
    (void)memset(q->b, 0, sizeof q->b);
    return MAGCAL_OK;
}

/* Second moments (collinearity) and the hard-iron circle's normal equations
 * x^2 + y^2 + C x + D y + E = 0, both of the centred, scaled inliers. */
MAGCAL_NOINLINE magcal_status_t magcal_ph_moments(magcal_calibrator_t *cal, cal_run_t *r)
{
    cal_prep_t *q = cal_prep(cal);
    while (r->i < cal->n) {
        const size_t i = r->i;
        if (cal->mask_a[i] != 0u) {
            const float u = (cal->buf[i].x - q->mx) / q->s;
            const float v = (cal->buf[i].y - q->my) / q->s;
            const float y = -(u * u + v * v);
            float w[3];
            q->sxx += u * u;
            q->syy += v * v;
            q->sxy += u * v;
            w[0] = u;
            w[1] = v;
            w[2] = 1.0f;
            magcal_normal_add(q->a, q->b, w, 3u, y);
        }
        r->i++;
        if (magcal_cal_charge(&r->bud, CAL_W_MOMENT) != 0) {
            return MAGCAL_IN_PROGRESS;
        }
    }
    cal_goto(r, PH_CIRCLE);
    return MAGCAL_OK;
}

/* Inliers collinear (smaller covariance eigenvalue vs larger; on the filter inliers: before the
 * filter, two glitch samples 1e5 R away made a clean ring look collinear), then the circle. */
MAGCAL_NOINLINE magcal_status_t magcal_ph_circle(magcal_calibrator_t *cal, cal_run_t *r)
{
    cal_prep_t *q = cal_prep(cal);
    const float tr = q->sxx + q->syy;
    float det;
    float disc;
    magcal_status_t st;
    if (!(tr > 0.0f)) {
        return MAGCAL_ERR_DEGENERATE;
    }
    det = q->sxx * q->syy - q->sxy * q->sxy;
    disc = sqrtf(fmaxf(0.25f * tr * tr - det, 0.0f));
    if (0.5f * tr - disc <= CAL_COLLINEAR_TOL * (0.5f * tr + disc)) {
        return MAGCAL_ERR_DEGENERATE;
    }
    if (r->m < 3u) {
        return MAGCAL_ERR_TOO_FEW_POINTS;
    }
    st = magcal_ldlt_solve(q->a, q->b, 3u, 1.0e-6f, NULL);
    if (st != MAGCAL_OK) {
        return st == MAGCAL_ERR_ILL_CONDITIONED ? MAGCAL_ERR_DEGENERATE : st;
    }
    q->cc.x = q->mx - 0.5f * q->b[0] * q->s;
    q->cc.y = q->my - 0.5f * q->b[1] * q->s;
    (void)magcal_cal_charge(&r->bud, CAL_W_CIRCLE);
    cal_goto(r, PH_COV_ALL);
    return MAGCAL_OK;
}

/* Bins of the approximate headings around the circle centre: every sample (with_mask 0) or the
 * filter inliers; 1 when the pass is complete. */
static int cal_cover_pass(magcal_calibrator_t *cal, cal_run_t *r, int with_mask)
{
    cal_prep_t *q = cal_prep(cal);
    if (r->sub == 0u) {
        (void)memset(q->bins, 0, sizeof q->bins);
        r->sub = 1u;
    }
    while (r->i < cal->n) {
        const size_t i = r->i;
        r->i++;
        if (with_mask == 0 || cal->mask_a[i] != 0u) {
            q->bins[magcal_cal_bin_of(
                magcal_cal_angle_deg(cal->buf[i].x - q->cc.x, cal->buf[i].y - q->cc.y))] = 1u;
            if (magcal_cal_charge(&r->bud, CAL_W_COVER) != 0) {
                return 0;
            }
        } else if (magcal_cal_charge(&r->bud, CAL_W_FLAG) != 0) {
            return 0;
        } else {
            /* not an inlier */
        }
    }
    return 1;
}

/* 3. coverage pre-gate: every sample, around the hard-iron circle centre of the filter inliers
 * (a short arc is reported as COVERAGE, not as whatever conic it happens to fit); below the gate
 * the arc stage (an ellipse judged by its whole-circle bound) or the coarse stage when enabled. */
MAGCAL_NOINLINE magcal_status_t magcal_ph_cov_all(magcal_calibrator_t *cal, cal_run_t *r)
{
    cal_prep_t *q = cal_prep(cal);
    float cov;
    if (cal_cover_pass(cal, r, 0) == 0) {
        return MAGCAL_IN_PROGRESS;
    }
    cov = magcal_cal_coverage_of(q->bins, &r->rep.missing_start_deg, &r->rep.missing_width_deg);
    r->rep.coverage_deg = cov;
    (void)magcal_cal_charge(&r->bud, CAL_W_COVFIN);
    if (cov < cal->cfg.min_coverage_deg) {
        if (cal->arc_min_cov > 0.0f && cov >= cal->arc_min_cov) {
            r->rep.arc = 1u; /* the full ellipse on an arc, judged by its whole-circle bound ("Arc stage") */
        } else {
#if MAGCAL_CFG_ENABLE_COARSE
            if (cal->coarse_min_cov > 0.0f && cov >= cal->coarse_min_cov && magcal_coarse_radius(q) != 0) {
                r->rep.coarse = 1u; /* hard iron only: the circle of the inliers ("Coarse stage") */
                cal_goto(r, PH_CO_RES);
                q->ss = 0.0f;
                return MAGCAL_OK;
            }
#endif
            return MAGCAL_ERR_COVERAGE;
        }
    }
    if (r->pre != 0u) {
        /* clean pre-test: its consensus (on every sample) is the fit */
        r->held = MAGCAL_OK;
        cal_goto(r, PH_FLAGS0);
        return MAGCAL_OK;
    }
    cal_goto(r, PH_COV_F);
    return MAGCAL_OK;
}

/* When the filter's inliers alone cover less than the gate while all samples do, the filter split
 * the ring into arcs (bursts leave gaps, algorithms.md 4.3): the consensus then draws its minimal
 * sets from every sample instead (LMedS tolerates up to 50 % outliers). */
MAGCAL_NOINLINE magcal_status_t magcal_ph_cov_f(magcal_calibrator_t *cal, cal_run_t *r)
{
    cal_prep_t *q = cal_prep(cal);
    if (cal_cover_pass(cal, r, 1) == 0) {
        return MAGCAL_IN_PROGRESS;
    }
    if (magcal_cal_coverage_of(q->bins, NULL, NULL) < (r->rep.arc != 0u ? cal->arc_min_cov : cal->cfg.min_coverage_deg)) {
        r->rep.filter_fragmented = 1u;
    }
    (void)magcal_cal_charge(&r->bud, CAL_W_COVFIN);
    (void)memset(&r->cres, 0, sizeof r->cres);
    cal_goto(r, cal->cfg.use_consensus == 0u ? PH_PLAIN : PH_THIN);
    return MAGCAL_OK;
}
