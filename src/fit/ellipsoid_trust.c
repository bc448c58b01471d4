/*
 * The trust gates of the 3-D fit (issue 12, docs/calibration_3d.md "Trust gates"): is the sensor
 * moving (motion SNR from three noise scales), is the answer observable (sandwich covariance of the
 * offset and soft-iron terms; planarity of the field directions), does the model fit (residual),
 * is the field plausible (optional band). Also the storage-free median used by the outlier gate.
 * Phases of the time-sliced fit (src/fit/ellipsoid.c drives them; their state is the run in the
 * fit's scratch, ellipsoid_internal.h). This file: the residuals, the median, the motion SNR, the
 * gate verdicts and the trust phase driver; the observability (sandwich covariance, planarity)
 * is ellipsoid_obs.c.
 */
#include <math.h>
#include <string.h>

#include "ellipsoid_internal.h"

#if MAGCAL_CFG_ENABLE_3D /* whole file: config.h feature switch */

static float alg_residual(const resid_src_t *src, const magcal_vec3_t *m)
{
    const float *b = src->theta;
    const float x = (m->x - src->mu[0]) * src->inv_s;
    const float y = (m->y - src->mu[1]) * src->inv_s;
    const float z = (m->z - src->mu[2]) * src->inv_s;
    return b[0] * x * x + b[1] * y * y + b[2] * z * z +
           2.0f * (b[3] * y * z + b[4] * x * z + b[5] * x * y + b[6] * x + b[7] * y + b[8] * z) -
           1.0f;
}

static float abs_residual(const resid_src_t *src, const magcal_vec3_t *m)
{
    return fabsf((src->cal != NULL) ? magcal_ell_residual(src->cal, m) : alg_residual(src, m));
}

/*
 * Median of |r| over the `kept` samples that `gate` keeps, without per-sample storage: the bin of
 * a 128-bin histogram of [lo, hi) that holds the median becomes the next [lo, hi), at most
 * MED_PASSES passes (stops once the bin is narrower than 0.1 % of its lower edge).
 */
void magcal_ell_med_start(ell_run_t *r, const resid_src_t *src, const quad_gate_t *gate,
                          const ell_ws_t *ws, size_t kept, float max_abs, uint8_t ret)
{
    ell_med_t *md = &r->med;
    md->src = src;
    md->gate = gate;
    md->ws = *ws;
    md->lo = 0.0f;
    md->hi = max_abs * 1.0001f + 1e-30f;
    md->below = 0u;
    md->target = (kept + 1u) / 2u; /* rank (1-based) of the median */
    md->pass = 0u;
    md->done = 0u;
    md->in_pass = 0u;
    md->ret = ret;
    r->k = 0u;
    r->ph = ELL_PH_MED;
}

/* The end of a median pass: the bin holding the median becomes the next interval. */
static void med_pass_end(ell_med_t *md, const uint32_t *cnt)
{
    size_t acc = md->below;
    size_t b = 0u;
    int found = 0;
    while (b < MED_BINS && found == 0) {
        if (acc + cnt[b] >= md->target) {
            found = 1;
        } else {
            acc += cnt[b];
            ++b;
        }
    }
    if (found == 0) { /* float rounding at the edge: keep the current interval */
        md->done = 1u;
    } else {
        md->lo = md->lo + (float)b * md->width;
        md->hi = md->lo + md->width;
        md->below = acc;
        if (md->width <= 1e-3f * md->lo) {
            md->done = 1u;
        }
    }
}

static MAGCAL_NOINLINE int med_phase(ell_scratch_t *sw, ell_bud_t *b)
{
    ell_run_t *r = &sw->run;
    ell_med_t *md = &r->med;
    uint32_t *cnt = sw->cnt;
    const uint32_t w = (md->ws.res != NULL) ? (uint32_t)W_T_MED : (uint32_t)W_T_MED_RECOMP;
    if (md->in_pass == 0u) {
        if (!(md->pass < MED_PASSES && md->done == 0u)) {
            md->result = 0.5f * (md->lo + md->hi);
            r->ph = md->ret;
            return ELL_CONT;
        }
        if (magcal_ell_can(b, W_T_MED_PASS) == 0) {
            return ELL_YIELD;
        }
        md->width = (md->hi - md->lo) / (float)MED_BINS;
        if (!(md->width > 0.0f)) {
            md->done = 1u;
            md->pass++;
            return ELL_CONT;
        }
        (void)memset(cnt, 0, sizeof(sw->cnt));
        md->in_pass = 1u;
        r->k = 0u;
    }
    {
        const size_t k1 = r->k + magcal_ell_visits(b, w, r->n - r->k);
        const ell_ws_t mws = md->ws;
        const float lo = md->lo;
        const float hi = md->hi;
        const float width = md->width;
        size_t k;
        for (k = r->k; k < k1; ++k) {
            if (magcal_ell_kept(&mws, md->gate, r->m, k) != 0) {
                const float a = (mws.res != NULL) ? fabsf(mws.res[k]) : abs_residual(md->src, &r->m[k]);
                if (a >= lo && a < hi) {
                    const float q = (a - lo) / width;
                    const size_t bin = (size_t)q;
                    cnt[(bin < MED_BINS) ? bin : (MED_BINS - 1u)]++;
                }
            }
        }
        r->k = k1;
    }
    if (r->k < r->n) {
        return ELL_YIELD;
    }
    med_pass_end(md, cnt);
    md->in_pass = 0u;
    md->pass++;
    r->k = 0u;
    return ELL_CONT;
}

/* Cube root of det G (> 0 for both square roots): the mean gain, raw -> output units. */
static float mean_gain(const magcal_ellipsoid_cal_t *cal)
{
    const float(*a)[3] = cal->g; /* magcal_det3's expression, without a copy */
    const float det = a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1]) -
                      a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0]) +
                      a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]);
    return cbrtf(fabsf(det));
}

/*
 * Centre-free, model-free noise scale: the RMS algebraic residual of the 9-parameter quadric
 * (d = -1) of ALL samples in normalised coordinates, from the moments alone:
 * sum (r.theta - 1)^2 = theta^T A theta - 2 theta^T b + N. On a shell of radius ~1 a geometric
 * error delta gives ~2 delta, so motion SNR = 2 / rms: ~2.5 for noise around one point (any model
 * of it), the radius / noise for a rotation (any soft iron, any quadric). Three phases: the solve,
 * the residuals (stored, when there is room, for the median), the median.
 */
static MAGCAL_NOINLINE int ph_asnr0(ell_scratch_t *sw, ell_bud_t *b)
{
    ell_run_t *r = &sw->run;
    const quad_acc_t *acc = &sw->acc;
    float *a = sw->mat;
    size_t i;
    size_t j;
    if (magcal_ell_can(b, W_T_SOLVE9) == 0) {
        return ELL_YIELD;
    }
    for (i = 0u; i < 9u; ++i) {
        for (j = 0u; j < 9u; ++j) {
            a[i * 9u + j] = magcal_ell_acc_at(acc, i, j);
        }
        r->theta[i] = magcal_ell_acc_at(acc, i, 9u);
    }
    if (magcal_ldlt_solve(a, r->theta, 9u, 0.0f, NULL) != MAGCAL_OK) {
        sw->mc.snr_alg = INFINITY; /* singular: a degenerate quadric fits exactly, this is not noise */
        r->k = 0u;
        r->ph = ELL_PH_COV;
        return ELL_CONT;
    }
    r->src_alg.cal = NULL;
    r->src_alg.theta = r->theta;
    r->src_alg.mu = sw->mu;
    r->src_alg.inv_s = r->inv_s;
    r->rmax = 0.0f;
    r->k = 0u;
    r->ph = ELL_PH_ASNR;
    return ELL_CONT;
}

static MAGCAL_NOINLINE int asnr_range(ell_scratch_t *sw, ell_bud_t *b)
{
    ell_run_t *r = &sw->run;
    {
        const size_t k1 = r->k + magcal_ell_visits(b, W_T_ASNR, r->n - r->k);
        float *res = r->ws.res;
        float mx = r->rmax;
        size_t k;
        for (k = r->k; k < k1; ++k) {
            const float rr = alg_residual(&r->src_alg, &r->m[k]);
            if (res != NULL) {
                res[k] = rr;
            }
            if (fabsf(rr) > mx) { /* fmaxf(mx, |r|) without the libm call (NaN ignored alike) */
                mx = fabsf(rr);
            }
        }
        r->k = k1;
        r->rmax = mx;
    }
    if (r->k < r->n) {
        return ELL_YIELD;
    }
    {
        ell_ws_t all_ws = r->ws;
        all_ws.keep = NULL; /* every sample */
        /* robust (median) scale: outliers far off the shell must not make a rotation look like noise */
        magcal_ell_med_start(r, &r->src_alg, &r->all, &all_ws, r->n, r->rmax, ELL_PH_ASNR_DONE);
    }
    return ELL_CONT;
}

/* Motion SNR: the largest of `snr_model` (the final fit's), the algebraic quadric's and, only when
 * both are below `limit` (about to say NO_MOTION), the sphere's with a robust (median) scale. Each
 * can be fooled alone: a far burst drags the least-squares quadric (and any model) but not a
 * median-scaled sphere; strong soft iron spoils the sphere but not the quadric. Noise around one
 * point fools none of them (all ~2.5). Result in r->mot.snr, then phase `ret`. */
static void mot_start(ell_run_t *r, float snr_model, float limit, uint8_t ret)
{
    r->mot.snr_model = snr_model;
    r->mot.limit = limit;
    r->mot.ret = ret;
    r->ph = ELL_PH_MOT0;
}

static MAGCAL_NOINLINE int ph_mot(ell_scratch_t *sw)
{
    ell_run_t *r = &sw->run;
    const motion_ctx_t *mc = &sw->mc;
    ell_mot_t *mo = &r->mot;
    if (r->ph == ELL_PH_MOT0) {
        mo->snr = fmaxf(mo->snr_model, mc->snr_alg);
        if (mo->snr < mo->limit && mc->sphere != NULL) {
            ell_ws_t rw = r->ws; /* recomputed: the stored residuals belong to the fit */
            rw.res = NULL;
            rw.keep = NULL;
            r->src_sph.cal = mc->sphere;
            r->src_sph.theta = NULL;
            r->src_sph.mu = NULL;
            r->src_sph.inv_s = 0.0f;
            magcal_ell_rp_start(r, mc->sphere, &r->all, &rw, ELL_PH_MOT1);
        } else {
            r->ph = mo->ret;
        }
    } else if (r->ph == ELL_PH_MOT1) {
        magcal_ell_med_start(r, &r->src_sph, &r->all, &r->rp.ws, r->rp.kept, r->rp.mx, ELL_PH_MOT2);
    } else { /* ELL_PH_MOT2 */
        const float med = MAGCAL_ELL_MAD_TO_SIGMA * r->med.result / mc->sphere->g[0][0];
        mo->snr = fmaxf(mo->snr, (med > 0.0f) ? (mc->s / med) : INFINITY);
        r->ph = mo->ret;
    }
    return ELL_CONT;
}

/*
 * A failed fit of data that never moved, or that rotate about one axis only, gets the status that
 * says so (the user must move the sensor differently, not retry with the same motion).
 */
void magcal_ell_explain_start(ell_run_t *r, magcal_status_t st)
{
    r->pend = st;
    r->ph = ELL_PH_EXPL0;
}

static MAGCAL_NOINLINE int ph_explain(ell_scratch_t *sw)
{
    ell_run_t *r = &sw->run;
    const magcal_ellipsoid_cfg_t *cfg = r->cfg;
    const magcal_status_t st = r->pend;
    if (r->ph == ELL_PH_EXPL0) {
        if (st == MAGCAL_ERR_NULL || st == MAGCAL_ERR_ARG || st == MAGCAL_ERR_NONFINITE ||
            st == MAGCAL_ERR_DEGENERATE) {
            return st;
        }
        if (cfg->min_motion_snr > 0.0f) {
            mot_start(r, 0.0f, cfg->min_motion_snr, ELL_PH_EXPL1);
        } else {
            r->ph = ELL_PH_EXPL1;
        }
        return ELL_CONT;
    }
    if (cfg->min_motion_snr > 0.0f && r->mot.snr < cfg->min_motion_snr) {
        return MAGCAL_ERR_NO_MOTION;
    }
    if ((cfg->max_centre_std_rel > 0.0f || cfg->max_shape_std > 0.0f) && r->planarity < PLANAR_MAX) {
        return MAGCAL_ERR_SINGLE_AXIS;
    }
    return st;
}

/* Trust gates, first phases: the mean gain and raw radius, the motion SNR, then the information
 * pass of the observability gate. */
static MAGCAL_NOINLINE int ph_tg(ell_scratch_t *sw)
{
    ell_run_t *r = &sw->run;
    const magcal_ellipsoid_cal_t *cal = &sw->cal[0];
    if (r->ph == ELL_PH_TG0) {
        const float gmean = mean_gain(cal);
        r->sphere = (r->model == MAGCAL_ELLIPSOID_MODEL_SPHERE) ? 1u : 0u;
        r->np = (r->sphere != 0u) ? (size_t)4u : (size_t)INFO_MAX_N;
        if (!(gmean > 0.0f) || !magcal_isfinite_f(gmean)) {
            return MAGCAL_ERR_NOT_ELLIPSOID;
        }
        r->gmean = gmean;
        sw->dg.field_raw = cal->field / gmean;
        /* motion: spread against the best noise scale (the fitted model's residual, raw units,
         * after outlier rejection; the algebraic quadric of all samples; the robust sphere) */
        mot_start(r, (r->rms > 0.0f) ? (sw->mc.s * gmean / r->rms) : INFINITY,
                  r->cfg->min_motion_snr, ELL_PH_TG1);
        return ELL_CONT;
    }
    sw->dg.motion_snr = r->mot.snr;
    (void)memset(&sw->acc, 0, sizeof(sw->acc));
    (void)memset(sw->part, 0, sizeof(sw->part));
    (void)memset(sw->meat, 0, sizeof(sw->meat));
    r->sn[0] = 0.0f;
    r->sn[1] = 0.0f;
    r->sn[2] = 0.0f;
    r->cnt = 0u;
    r->in_block = 0u;
    r->k = 0u;
    r->ph = ELL_PH_INFO;
    return ELL_CONT;
}

/* The verdict (order: motion, one axis, residual, observability, field). */
static magcal_status_t gates_verdict(const ell_run_t *r, const trust_diag_t *dg, float f)
{
    const magcal_ellipsoid_cfg_t *cfg = r->cfg;
    const float rms = r->rms;
    float lim;
    int observable = 1;
    if (cfg->min_motion_snr > 0.0f && dg->motion_snr < cfg->min_motion_snr) {
        return MAGCAL_ERR_NO_MOTION;
    }
    if ((cfg->max_centre_std_rel > 0.0f && !(dg->centre_std_rel <= cfg->max_centre_std_rel)) ||
        (cfg->max_shape_std > 0.0f && !(dg->shape_std <= cfg->max_shape_std))) {
        observable = 0;
    }
    lim = (r->sphere != 0u) ? cfg->max_residual_rel_sphere : cfg->max_residual_rel;
    /* one axis: the corrected directions lie on a cone; or the raw samples are planar and the
     * quadric does not even fit them (a G made up along the unseen axis spoils the corrected test;
     * not for the sphere: a sphere that misfits strong soft iron is a residual failure) */
    if (observable == 0 &&
        (dg->planarity < PLANAR_MAX ||
         (r->sphere == 0u && r->planarity < PLANAR_MAX && lim > 0.0f && !(rms <= lim * f)))) {
        return MAGCAL_ERR_SINGLE_AXIS;
    }
    if (lim > 0.0f && !(rms <= lim * f)) {
        return MAGCAL_ERR_RESIDUAL;
    }
    if (observable == 0) {
        return MAGCAL_ERR_ILL_CONDITIONED;
    }
    if (cfg->field_expected > 0.0f &&
        !(dg->field_raw >= cfg->field_band_lo * cfg->field_expected &&
          dg->field_raw <= cfg->field_band_hi * cfg->field_expected)) {
        return MAGCAL_ERR_FIELD_MAGNITUDE;
    }
    return MAGCAL_OK;
}

/*
 * Observability phases after the information pass: (J^T J)^-1, then the sandwich
 * (J^T J)^-1 meat (J^T J)^-1 from the summed meat row by row: the offset block (rows 0..2) and the
 * shape diagonal, C_kl = inv_l . (meat inv_k). Near a singular J^T J the rounding of the summed
 * meat can swamp its tiny component along the weak direction (and make an unobservable offset
 * look fine), so each diagonal term carries a bound of that rounding, (cnt + np) eps |inv_k|^T
 * |meat| |inv_k|; if any bound is above 1 % of its term, the exact per-sample second pass decides
 * instead. Then the diagnostics and the verdict.
 */
static MAGCAL_NOINLINE int ph_centre(ell_scratch_t *sw, ell_bud_t *b)
{
    ell_run_t *r = &sw->run;
    if (r->ph == ELL_PH_INV) { /* (J^T J)^-1: one factorisation, then np substitutions */
        if (magcal_ell_can(b, W_T_FACTOR) == 0) {
            return ELL_YIELD;
        }
        if (magcal_ell_info_factor(sw, r->np) == 0) {
            r->stage = 1; /* J^T J singular: the scatter only */
            r->ph = ELL_PH_DIAG;
            return ELL_CONT;
        }
        r->k = 0u;
        r->ph = ELL_PH_INV_SUB;
        return ELL_CONT;
    }
    if (r->ph == ELL_PH_INV_SUB) {
        while (r->k < r->np) {
            float *col = sw->inv[r->k];
            size_t i;
            if (magcal_ell_can(b, W_T_SUBST) == 0) {
                return ELL_YIELD;
            }
            for (i = 0u; i < r->np; ++i) {
                col[i] = (i == r->k) ? 1.0f : 0.0f;
            }
            if (magcal_ldlt_subst(sw->mat, col, r->np) != MAGCAL_OK) {
                r->stage = 1;
                r->ph = ELL_PH_DIAG;
                return ELL_CONT;
            }
            r->k++;
        }
        (void)memset(sw->cc, 0, 9u * sizeof(float));
        (void)memset(sw->sd, 0, INFO_MAX_N * sizeof(float));
        r->k = 0u;
        r->ph = ELL_PH_SWM;
        return ELL_CONT;
    }
    if (r->ph == ELL_PH_SWM) {
        while (r->k < r->np && !(r->k >= 3u && r->sphere != 0u)) {
            if (magcal_ell_can(b, W_T_SWM) == 0) {
                return ELL_YIELD;
            }
            if (magcal_ell_sandwich_row(sw, r->np, r->cnt, r->k) == 0) {
                (void)memset(sw->cc, 0, 9u * sizeof(float));
                (void)memset(sw->sd, 0, INFO_MAX_N * sizeof(float));
                r->k = 0u;
                r->ph = ELL_PH_SWP;
                return ELL_CONT;
            }
            r->k++;
        }
        r->k = 0u;
        r->stage = 2;
        r->ph = ELL_PH_DIAG;
        return ELL_CONT;
    }
    /* ELL_PH_DIAG */
    if (magcal_ell_can(b, W_T_DIAG) == 0) {
        return ELL_YIELD;
    }
    magcal_ell_centre_diag(&r->ws, (int)r->stage, (int)r->sphere, sw->cal[0].field, &sw->dg);
    {
        const magcal_status_t st = gates_verdict(r, &sw->dg, sw->cal[0].field);
        if (st != MAGCAL_OK) {
            return st;
        }
    }
    r->ph = ELL_PH_OUT;
    return ELL_CONT;
}

int magcal_ell_trust_phase(ell_scratch_t *sw, ell_bud_t *b)
{
    ell_run_t *r = &sw->run;
    switch (r->ph) {
    case ELL_PH_ASNR0:
        return ph_asnr0(sw, b);
    case ELL_PH_ASNR:
        return asnr_range(sw, b);
    case ELL_PH_ASNR_DONE: {
        const float med = MAGCAL_ELL_MAD_TO_SIGMA * r->med.result;
        sw->mc.snr_alg = (med > 0.0f) ? (2.0f / med) : INFINITY; /* 0: exact quadric */
        r->k = 0u;
        r->ph = ELL_PH_COV;
        return ELL_CONT;
    }
    case ELL_PH_MED:
        return med_phase(sw, b);
    case ELL_PH_INFO:
        return magcal_ell_info_range(sw, b);
    case ELL_PH_INFO_DONE:
        return magcal_ell_ph_info_done(sw, b);
    case ELL_PH_INV:
    case ELL_PH_INV_SUB:
    case ELL_PH_SWM:
    case ELL_PH_DIAG:
        return ph_centre(sw, b);
    case ELL_PH_SWP:
        return magcal_ell_swp_range(sw, b);
    default:
        break;
    }
    if (magcal_ell_can(b, W_T_UNIT) == 0) {
        return ELL_YIELD;
    }
    if (r->ph == ELL_PH_TG0 || r->ph == ELL_PH_TG1) {
        return ph_tg(sw);
    }
    if (r->ph == ELL_PH_EXPL0 || r->ph == ELL_PH_EXPL1) {
        return ph_explain(sw);
    }
    return ph_mot(sw); /* ELL_PH_MOT0 .. ELL_PH_MOT2 */
}

#endif /* MAGCAL_CFG_ENABLE_3D */
