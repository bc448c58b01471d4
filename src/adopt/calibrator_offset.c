/*
 * Offset-only relearn (docs/calibrator.md "Offset-only relearn", continuous.h): after a declared
 * change, while RELEARNING with a full calibration installed, the hard iron is refitted under the
 * installed soft-iron shape on far less arc than a full ellipse needs (NXP's 4-element solver runs
 * first for the same reason: a magnet or a re-magnetised part moves the offset, the shape stays).
 *
 * The snapshot of the store (cc->buf, cont_step.c) is mapped into the installed calibration's unit
 * frame u = M (m - offset) / radius, where the old shape makes the ring a circle. Passes over the
 * snapshot, each a resumable loop charged per sample (bounded work per step):
 *   1. algebraic circle fit of every sample (x^2 + y^2 + D x + E y + F = 0, linear least squares);
 *   2. residual RMS around it, the gate k_sigma x RMS clamped as the consensus clamps it;
 *   3. the circle refitted on the gated samples;
 *   4. the geometric residual model of the gated samples, e = |u - c| - r regressed on
 *      (cos, sin, 1, cos 2t, sin 2t) of their angle t: its first three terms are one Gauss-Newton
 *      step of the geometric circle fit and give the centre's covariance; the last two are a
 *      changed soft iron (a 2nd harmonic the old shape does not explain);
 *   5. the end (two steps): the refined centre, the shape tests, the bound and the calibration.
 * Verdicts: MAGCAL_ERR_SHAPE_CHANGED when the residual sigma exceeds cfg.offset_sigma_ratio x the
 * installed calibration's, or the 2nd harmonic is significant (chi-square of its 2 terms > 13.8,
 * p = 0.001) and larger than a quarter of the tolerance: the change was not a hard-iron one (no
 * further offset fit until the next change; the full solve relearns); MAGCAL_ERR_UNOBSERVABLE when
 * the bound on the heading error over the WHOLE circle,
 *     bound = 3 sqrt(lambda_max(C_c)) / r + |a_2| / r   (radians; C_c the centre's covariance),
 * exceeds cfg.offset_max_err_deg; else MAGCAL_OK with the new offset = offset + M^-1 (radius c).
 */
#include <math.h>
#include <string.h>

#include "../loop/cont_internal.h"
#include "magcal_internal.h"

/* Weights per visit, estimated Cortex-M4F instructions: host callgrind x 1.2 (the CAL_W_*
 * convention), rounded up (tests/test_relearn.c under callgrind: 494 calls of
 * magcal_cont_offset_step, 4.0k instructions each on average; ~160 per sample visit over the
 * four passes, the 3 x 3 solve ~700, a 3 x 3 / 5 x 5 substitution ~310 / ~400). Not measured on
 * the target (docs/calibrator.md "Offset-only relearn"). */
#define OFF_W_FIT 140u   /* pass 1 / 3: one sample's frame map and 3 x 3 normal-equation update */
#define OFF_W_RES 100u   /* pass 2: frame map, distance (sqrtf), residual square */
#define OFF_W_GATE 170u  /* pass 3: as pass 2 plus the update */
#define OFF_W_MODEL 360u /* pass 4: frame map, distance, angle terms, 5 x 5 update */
#define OFF_W_SOLVE 900u /* the end of pass 1 / 3: the 3 x 3 solve */
#define OFF_W_END1 2000u /* end, first step: the 3 x 3 factor, 4 substitutions, the refined centre */
#define OFF_W_END2 3000u /* end, second step: the 5 x 5 factor, 3 substitutions, the tests, the calibration */
#define OFF_CHI2_2DOF 13.8f /* chi-square, 2 degrees of freedom, p = 0.001 */
#define OFF_CHI2_NOISELESS 1.0e30f /* the chi-square of a 2nd harmonic on noiseless samples */
#define OFF_SIGMA_FLOOR 0.01f /* the reference sigma when the installed one is unknown (flash) or tiny */
#define OFF_PIVOT 1.0e-6f
#define OFF_RADIUS_REL 0.03f /* |r - 1| beyond this (and 3 standard errors): the field magnitude under the
                                installed shape moved, not a hard-iron change alone */

int magcal_cont_offset_eligible(const magcal_cont_t *cc)
{
    /* the installed calibration's own error estimate is part of the bound (its shape is kept):
     * a calibration restored from flash has none (adopted_err NaN), so it is never the base */
    return cc->cfg.offset_coverage_deg > 0.0f && cc->state == (uint8_t)MAGCAL_CONT_RELEARNING &&
           cc->has_cal != 0u && cc->cal_coarse == 0u && cc->off_block != cc->changes + 1u &&
           magcal_isfinite_f(cc->adopted_err);
}

int magcal_cont_offset_pick(magcal_cont_t *cc, float coverage_deg, float full)
{
    cc->off_mode = 0u;
    if (coverage_deg >= full) {
        return 1;
    }
    if (magcal_cont_offset_eligible(cc) != 0 && coverage_deg >= cc->cfg.offset_coverage_deg) {
        cc->off_mode = 1u;
        cc->off_cov = coverage_deg;
        return 1;
    }
    return 0;
}

void magcal_cont_offset_begin(magcal_cont_t *cc)
{
    cc->off_pass = 1u;
    cc->off_i = 0u;
    cc->off_n = 0u;
    cc->off_ss = 0.0f;
    (void)memset(cc->off_a, 0, sizeof cc->off_a);
    (void)memset(cc->off_b, 0, sizeof cc->off_b);
}

/* Sample i of the snapshot in the installed calibration's unit frame. */
static void off_map(const magcal_cont_t *cc, uint32_t i, float *ux, float *uy)
{
    const magcal_cal2d_t *c = &cc->cal;
    const float inv = 1.0f / c->radius;
    const float dx = cc->buf[i].x - c->offset.x;
    const float dy = cc->buf[i].y - c->offset.y;
    *ux = (c->m[0][0] * dx + c->m[0][1] * dy) * inv;
    *uy = (c->m[1][0] * dx + c->m[1][1] * dy) * inv;
}

/* Residual of (ux, uy) around the current circle, its distance from the centre into *d. */
static float off_res(const magcal_cont_t *cc, float ux, float uy, float *d)
{
    const float dx = ux - cc->off_c[0];
    const float dy = uy - cc->off_c[1];
    *d = sqrtf(dx * dx + dy * dy);
    return *d - cc->off_c[2];
}

/* Algebraic circle update of one point (3 x 3 lower triangle of off_a, rhs off_b). */
static void off_circle_add(magcal_cont_t *cc, float ux, float uy)
{
    const float w[3] = {ux, uy, 1.0f};
    const float y = -(ux * ux + uy * uy);
    magcal_normal_add(cc->off_a, cc->off_b, w, 3u, y);
    cc->off_n++;
}

/* Solve the circle's normal equations into off_c; the sums are cleared for the next pass. */
static magcal_status_t off_circle_solve(magcal_cont_t *cc)
{
    magcal_status_t st;
    float r2;
    if (cc->off_n < 3u) {
        return MAGCAL_ERR_TOO_FEW_POINTS;
    }
    st = magcal_ldlt_solve(cc->off_a, cc->off_b, 3u, OFF_PIVOT, NULL);
    if (st != MAGCAL_OK) {
        return MAGCAL_ERR_DEGENERATE;
    }
    cc->off_c[0] = -0.5f * cc->off_b[0];
    cc->off_c[1] = -0.5f * cc->off_b[1];
    r2 = cc->off_c[0] * cc->off_c[0] + cc->off_c[1] * cc->off_c[1] - cc->off_b[2];
    if (!(r2 > 0.0f) || !magcal_isfinite_f(r2)) {
        return MAGCAL_ERR_DEGENERATE;
    }
    cc->off_c[2] = sqrtf(r2);
    (void)memset(cc->off_a, 0, sizeof cc->off_a);
    (void)memset(cc->off_b, 0, sizeof cc->off_b);
    cc->off_n = 0u;
    cc->off_ss = 0.0f;
    return MAGCAL_OK;
}

/* The residual model's update of one gated point (5 x 5 lower triangle, rhs, residual square). */
static void off_model_add(magcal_cont_t *cc, float ux, float uy, float d, float e)
{
    const float cs = (ux - cc->off_c[0]) / d;
    const float sn = (uy - cc->off_c[1]) / d;
    const float w[5] = {cs, sn, 1.0f, cs * cs - sn * sn, 2.0f * cs * sn};
    magcal_normal_add(cc->off_a, cc->off_b, w, 5u, e);
    cc->off_ss += e * e;
    cc->off_n++;
}

/* One pass (1..4) over the snapshot within budget b: 1 when it ended. */
static int off_pass_run(magcal_cont_t *cc, magcal_cal_budget_t *b)
{
    const uint32_t n = cc->snap_n;
    /* cppcheck-suppress misra-c2012-15.4 ; deviation D13: a resumable loop leaves at its pause point (budget) */
    while (cc->off_i < n) {
        float ux;
        float uy;
        float d = 0.0f;
        uint32_t w;
        off_map(cc, cc->off_i, &ux, &uy);
        cc->off_i++;
        if (cc->off_pass == 1u) {
            off_circle_add(cc, ux, uy);
            w = OFF_W_FIT;
        } else if (cc->off_pass == 2u) {
            const float e = off_res(cc, ux, uy, &d);
            cc->off_ss += e * e;
            cc->off_n++;
            w = OFF_W_RES;
        } else {
            const float e = off_res(cc, ux, uy, &d);
            w = OFF_W_GATE;
            if (fabsf(e) <= cc->off_thr && d > 0.0f) {
                if (cc->off_pass == 3u) {
                    off_circle_add(cc, ux, uy);
                } else {
                    off_model_add(cc, ux, uy, d, e);
                    w = OFF_W_MODEL;
                }
            }
        }
        if (magcal_cal_charge(b, w) != 0) {
            break;
        }
    }
    return cc->off_i >= n ? 1 : 0;
}

/* The end of a pass: its solve or gate, the next pass. */
static magcal_status_t off_pass_end(magcal_cont_t *cc, magcal_cal_budget_t *b)
{
    magcal_status_t st = MAGCAL_OK;
    if (cc->off_pass == 1u || cc->off_pass == 3u) {
        st = off_circle_solve(cc);
        (void)magcal_cal_charge(b, OFF_W_SOLVE);
    } else if (cc->off_pass == 2u) {
        const magcal_consensus_cfg_t *k = &cc->cfg.solver.consensus;
        const float rms = sqrtf(cc->off_ss / (float)(cc->off_n > 0u ? cc->off_n : 1u));
        float thr = fmaxf(k->k_sigma * rms, k->min_thr_rel * cc->off_c[2]);
        cc->off_thr = fminf(thr, k->max_thr_rel * cc->off_c[2]);
        cc->off_n = 0u;
        cc->off_ss = 0.0f;
    } else {
        /* pass 4 ended: the end steps follow */
    }
    cc->off_i = 0u;
    cc->off_pass++;
    return st;
}

/* End, first step: the geometric refinement of the centre and radius (the Gauss-Newton step of the
 * residual model's first three terms, N_3 g = J_3^T e) and the centre's covariance
 * sigma_3^2 (N_3^-1)_{xy}: its largest eigenvalue into *lam, sigma_3 (the 3-parameter residual
 * after the step) into *s3. The model's sums (off_a, off_b) stay for the second step. */
static magcal_status_t off_end_centre(magcal_cont_t *cc, float *lam, float *s3)
{
    float n3[9];
    float g[3];
    float c0[3] = {1.0f, 0.0f, 0.0f};
    float c1[3] = {0.0f, 1.0f, 0.0f};
    float c2[3] = {0.0f, 0.0f, 1.0f};
    float t;
    float det;
    uint32_t r;
    uint32_t k;
    magcal_status_t st;
    for (r = 0u; r < 3u; ++r) {
        for (k = 0u; k < 3u; ++k) {
            n3[r * 3u + k] = cc->off_a[r * 5u + k];
        }
        g[r] = cc->off_b[r];
    }
    st = magcal_ldlt_factor(n3, 3u, OFF_PIVOT, NULL);
    if (st == MAGCAL_OK) {
        st = magcal_ldlt_subst(n3, g, 3u);
    }
    if (st == MAGCAL_OK) {
        st = magcal_ldlt_subst(n3, c0, 3u);
    }
    if (st == MAGCAL_OK) {
        st = magcal_ldlt_subst(n3, c1, 3u);
    }
    if (st == MAGCAL_OK) {
        st = magcal_ldlt_subst(n3, c2, 3u);
    }
    if (st != MAGCAL_OK) {
        return MAGCAL_ERR_DEGENERATE;
    }
    /* sigma of the 3-parameter model after the step (ss - g . J^T e, dof n - 3) */
    *s3 = sqrtf(fmaxf(cc->off_ss - (g[0] * cc->off_b[0] + g[1] * cc->off_b[1] + g[2] * cc->off_b[2]), 0.0f) /
                ((float)cc->off_n - 3.0f));
    cc->off_c[0] += g[0];
    cc->off_c[1] += g[1];
    cc->off_c[2] += g[2];
    /* largest eigenvalue of the centre's 2 x 2 covariance sigma^2 [c0[0] c0[1]; c1[0] c1[1]] */
    t = 0.5f * (c0[0] + c1[1]);
    det = c0[0] * c1[1] - c0[1] * c1[0];
    *lam = (*s3) * (*s3) * (t + sqrtf(fmaxf(t * t - det, 0.0f)));
    cc->off_sr = (*s3) * sqrtf(fmaxf(c2[2], 0.0f)); /* the radius's standard error */
    return magcal_isfinite_f(*lam) && cc->off_c[2] > 0.0f ? MAGCAL_OK : MAGCAL_ERR_DEGENERATE;
}

/* End, second step: the 2nd harmonic of the residual model (a_2, its chi-square). */
static magcal_status_t off_end_harmonic(magcal_cont_t *cc, float *a2, float *chi2)
{
    float x[5];
    float e3[5] = {0.0f, 0.0f, 0.0f, 1.0f, 0.0f};
    float e4[5] = {0.0f, 0.0f, 0.0f, 0.0f, 1.0f};
    float s5;
    float det;
    magcal_status_t st;
    (void)memcpy(x, cc->off_b, sizeof x);
    st = magcal_ldlt_factor(cc->off_a, 5u, OFF_PIVOT, NULL);
    if (st == MAGCAL_OK) {
        st = magcal_ldlt_subst(cc->off_a, x, 5u);
    }
    if (st == MAGCAL_OK) {
        st = magcal_ldlt_subst(cc->off_a, e3, 5u);
    }
    if (st == MAGCAL_OK) {
        st = magcal_ldlt_subst(cc->off_a, e4, 5u);
    }
    if (st != MAGCAL_OK) {
        /* the arc cannot tell a 2nd harmonic from the centre: the shape is not confirmed */
        return MAGCAL_ERR_UNOBSERVABLE;
    }
    s5 = fmaxf(cc->off_ss - (x[0] * cc->off_b[0] + x[1] * cc->off_b[1] + x[2] * cc->off_b[2] +
                             x[3] * cc->off_b[3] + x[4] * cc->off_b[4]),
               0.0f) /
         ((float)cc->off_n - 5.0f);
    *a2 = sqrtf(x[3] * x[3] + x[4] * x[4]);
    /* chi-square of (x3, x4) under its covariance s5 [e3[3] e3[4]; e4[3] e4[4]] */
    det = s5 * s5 * (e3[3] * e4[4] - e3[4] * e4[3]);
    if (det > 0.0f) {
        *chi2 = s5 * (e4[4] * x[3] * x[3] - (e3[4] + e4[3]) * x[3] * x[4] + e3[3] * x[4] * x[4]) / det;
    } else {
        *chi2 = *a2 > 0.0f ? OFF_CHI2_NOISELESS : 0.0f; /* no noise: any 2nd harmonic is significant */
    }
    return MAGCAL_OK;
}

/* The calibration of the refined centre (offset + M^-1 radius c, radius x r) and its report. */
static magcal_status_t off_finish(magcal_cont_t *cc, float bound, float s3)
{
    const magcal_cal2d_t *o = &cc->cal;
    magcal_cal_report_t *rep = &cc->last;
    magcal_cal2d_t nc = *o;
    const float det = o->m[0][0] * o->m[1][1] - o->m[0][1] * o->m[1][0];
    const float cx = cc->off_c[0] * o->radius;
    const float cy = cc->off_c[1] * o->radius;
    const float sig = s3 / cc->off_c[2];
    if (!(fabsf(det) > 0.0f)) {
        return MAGCAL_ERR_DEGENERATE;
    }
    nc.offset.x = o->offset.x + (o->m[1][1] * cx - o->m[0][1] * cy) / det;
    nc.offset.y = o->offset.y + (-o->m[1][0] * cx + o->m[0][0] * cy) / det;
    nc.radius = o->radius * cc->off_c[2];
    if (magcal_cal2d_validate(&nc) != MAGCAL_OK) {
        return MAGCAL_ERR_DEGENERATE;
    }
    rep->cal = nc;
    rep->radius = cc->cal_raw_radius * cc->off_c[2];
    rep->residual_rel = sig;
    rep->residual_rms = sig * rep->radius;
    rep->axis_ratio = NAN;
    rep->ellipse.center = nc.offset;
    rep->est_noise_deg = MAGCAL_DEG_PER_RAD_F * sig;
    rep->est_param_err_deg = MAGCAL_DEG_PER_RAD_F * bound;
    rep->est_heading_err_deg = MAGCAL_DEG_PER_RAD_F * sqrtf(sig * sig + bound * bound);
    rep->shift_max_deg = NAN;
    rep->shift_rms_deg = NAN;
    cc->cand = nc;
    return MAGCAL_OK;
}

/* The end's verdict (its second step). */
static magcal_status_t off_verdict(magcal_cont_t *cc, float lam, float s3)
{
    const float r = cc->off_c[2];
    const float sig = s3 / r;
    const float sig_ref = fmaxf(cc->cal_sigma_rel, OFF_SIGMA_FLOOR);
    const float tol = cc->cfg.offset_max_err_deg * MAGCAL_RAD_PER_DEG_F;
    float a2 = 0.0f;
    float chi2 = 0.0f;
    float bound;
    magcal_status_t st = off_end_harmonic(cc, &a2, &chi2);
    if (st != MAGCAL_OK) {
        return st;
    }
    if (!(sig <= cc->cfg.offset_sigma_ratio * sig_ref) || (chi2 > OFF_CHI2_2DOF && a2 / r > 0.25f * tol) ||
        !(fabsf(r - 1.0f) <= fmaxf(3.0f * cc->off_sr, OFF_RADIUS_REL))) {
        cc->off_block = cc->changes + 1u; /* not a hard-iron change: the full solve relearns */
        return MAGCAL_ERR_SHAPE_CHANGED;
    }
    bound = 3.0f * sqrtf(lam) / r + a2 / r + cc->adopted_err * MAGCAL_RAD_PER_DEG_F;
    st = off_finish(cc, bound, s3);
    if (st == MAGCAL_OK && !(bound <= tol)) {
        st = MAGCAL_ERR_UNOBSERVABLE; /* too little arc for the whole circle's bound */
    }
    return st;
}

magcal_status_t magcal_cont_offset_step(magcal_cont_t *cc, uint32_t budget)
{
    magcal_cal_budget_t b;
    magcal_status_t st = MAGCAL_OK;
    b.left = budget;
    b.unlimited = (uint8_t)(budget == UINT32_MAX ? 1u : 0u);
    if (cc->off_pass == 1u && cc->off_i == 0u) {
        /* the report of this fit (the full solve's fields that do not apply stay 0 / NaN) */
        (void)memset(&cc->last, 0, sizeof cc->last);
        cc->last.samples = (uint16_t)cc->snap_n;
        cc->last.coverage_deg = cc->off_cov;
        cc->last.est_heading_err_deg = NAN;
        cc->last.est_param_err_deg = NAN;
        cc->last.current_err_deg = NAN;
        cc->last.state = MAGCAL_CALIBRATOR_COLLECTING;
        if (cc->snap_n < (uint32_t)cc->cfg.solver.min_samples) {
            st = MAGCAL_ERR_TOO_FEW_POINTS;
        }
    }
    /* cppcheck-suppress misra-c2012-15.4 ; deviation D13: a resumable loop leaves at its pause point (budget) */
    while (st == MAGCAL_OK && cc->off_pass <= 4u) {
        if (off_pass_run(cc, &b) == 0) {
            return MAGCAL_IN_PROGRESS;
        }
        st = off_pass_end(cc, &b);
        if (b.unlimited == 0u && b.left == 0u && st == MAGCAL_OK) {
            return MAGCAL_IN_PROGRESS;
        }
    }
    if (st == MAGCAL_OK && cc->off_pass == 5u) {
        const uint32_t gated = cc->off_n;
        if (gated < (uint32_t)cc->cfg.solver.min_samples || gated < 8u) {
            st = MAGCAL_ERR_TOO_FEW_POINTS;
        } else if ((float)cc->snap_n - (float)gated > cc->cfg.solver.max_outlier_frac * (float)cc->snap_n) {
            st = MAGCAL_ERR_TOO_MANY_OUTLIERS;
        } else {
            cc->last.used = (uint16_t)gated;
            cc->last.outliers = (uint16_t)(cc->snap_n - gated);
            cc->last.threshold = cc->off_thr * cc->cal_raw_radius;
            st = off_end_centre(cc, &cc->off_lam, &cc->off_s3);
        }
        (void)magcal_cal_charge(&b, OFF_W_END1);
        cc->off_pass = 6u;
        if (st == MAGCAL_OK && b.unlimited == 0u) {
            return MAGCAL_IN_PROGRESS; /* the verdict in the next step */
        }
    }
    if (st == MAGCAL_OK && cc->off_pass == 6u) {
        st = off_verdict(cc, cc->off_lam, cc->off_s3);
        (void)magcal_cal_charge(&b, OFF_W_END2);
        cc->off_pass = 7u;
    }
    cc->last.status = st;
    return st;
}
