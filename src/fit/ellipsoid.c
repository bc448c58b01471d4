/*
 * 3-D ellipsoid (general quadric) calibration fit, algorithms.md 7.2 with the solvers of 3.1/3.2.
 *
 * Data are centred on their mean and scaled by their RMS distance before the normal equations are
 * accumulated (Kahan-compensated float32 sums of one packed 10x10 matrix, from which the 9-parameter,
 * 10-parameter and sphere systems are all taken). Extraction happens in normalised coordinates and
 * is mapped back: V = mu + s*V~, G = (F/s)*sqrt(A~/k~).
 *
 * This file: the configuration check and the phases of the time-sliced fit with its entry points
 * (begin / step / one-shot). The quadric maths is ellipsoid_solve.c, the coverage and the small
 * helpers ellipsoid_cov.c, the trust gates ellipsoid_trust.c (ellipsoid_internal.h).
 */
#include <math.h>
#include <string.h>

#include "ellipsoid_internal.h"

#if MAGCAL_CFG_ENABLE_3D /* whole file: config.h feature switch */

/* cppcheck-suppress misra-c2012-2.3 ; deviation D4: a static assert is an unused typedef */
MAGCAL_STATIC_ASSERT(COV_CELLS <= 96u, coverage_cells_fit_three_words);
/* cppcheck-suppress misra-c2012-2.3 ; deviation D4: a static assert is an unused typedef */
MAGCAL_STATIC_ASSERT(MAGCAL_ELLIPSOID_COV_AZ == 12u, azimuth_boundaries_are_30_degrees);
/* cppcheck-suppress misra-c2012-2.3 ; deviation D4: a static assert is an unused typedef */
MAGCAL_STATIC_ASSERT(sizeof(ell_scratch_t) + (MAGCAL_ELL_ALIGN - 4u) <= MAGCAL_ELLIPSOID_FIT_SCRATCH_BYTES &&
                         sizeof(magcal_ellipsoid_fit_scratch_t) >= sizeof(ell_scratch_t) &&
                         MAGCAL_ELLIPSOID_FIT_SCRATCH_BYTES % 4u == 0u,
                     fit_scratch_fits_its_macro);

static magcal_status_t ellipsoid_check_cfg(const magcal_ellipsoid_cfg_t *cfg)
{
    if ((unsigned)cfg->model > (unsigned)MAGCAL_ELLIPSOID_MODEL_SPHERE) {
        return MAGCAL_ERR_ARG;
    }
    if ((unsigned)cfg->sqrt_method > (unsigned)MAGCAL_ELLIPSOID_SQRT_CHOLESKY) {
        return MAGCAL_ERR_ARG;
    }
    if (!magcal_isfinite_f(cfg->field) || cfg->field < 0.0f) {
        return MAGCAL_ERR_ARG;
    }
    if (!(cfg->min_coverage_full >= 0.0f && cfg->min_coverage_full <= 1.0f) ||
        !(cfg->min_coverage_sphere >= 0.0f && cfg->min_coverage_sphere <= 1.0f)) {
        return MAGCAL_ERR_ARG;
    }
    if (!(cfg->outlier_k >= 0.0f && cfg->outlier_k <= 100.0f) ||
        !(cfg->outlier_floor_rel >= 0.0f && cfg->outlier_floor_rel <= 1.0f)) {
        return MAGCAL_ERR_ARG;
    }
    if (cfg->max_refits > MAX_REFITS_LIMIT ||
        !(cfg->max_reject_frac >= 0.0f && cfg->max_reject_frac < 1.0f)) {
        return MAGCAL_ERR_ARG;
    }
    if (!(cfg->pivot_tau >= 0.0f && cfg->pivot_tau <= 0.1f)) {
        return MAGCAL_ERR_ARG;
    }
    if (!(cfg->min_motion_snr >= 0.0f && cfg->min_motion_snr <= 1000.0f) ||
        !(cfg->max_centre_std_rel >= 0.0f && cfg->max_centre_std_rel <= 1.0f) ||
        !(cfg->max_shape_std >= 0.0f && cfg->max_shape_std <= 1.0f) ||
        !(cfg->max_residual_rel >= 0.0f && cfg->max_residual_rel <= 1.0f) ||
        !(cfg->max_residual_rel_sphere >= 0.0f && cfg->max_residual_rel_sphere <= 1.0f)) {
        return MAGCAL_ERR_ARG;
    }
    if (!magcal_isfinite_f(cfg->field_expected) || cfg->field_expected < 0.0f ||
        !(cfg->field_band_lo > 0.0f && cfg->field_band_lo <= 1.0f) ||
        !(cfg->field_band_hi >= 1.0f && cfg->field_band_hi <= 100.0f)) {
        return MAGCAL_ERR_ARG;
    }
    return MAGCAL_OK;
}

/* ---- the residual pass (sub-machine ELL_PH_RP) ---- */
void magcal_ell_rp_start(ell_run_t *r, const magcal_ellipsoid_cal_t *cal, const quad_gate_t *gate,
                         const ell_ws_t *ws, uint8_t ret)
{
    r->rp.cal = cal;
    r->rp.gate = gate;
    r->rp.ws = *ws;
    r->rp.sum = 0.0f;
    r->rp.comp = 0.0f;
    r->rp.mx = 0.0f;
    r->rp.cnt = 0u;
    r->rp.ret = ret;
    r->k = 0u;
    r->ph = ELL_PH_RP;
}

/* RMS of the residuals under rp.cal of the samples kept by rp.gate; their count and max |r|.
 * With ws->res: every sample's residual is stored there (regate reads the rejected ones too). */
static MAGCAL_NOINLINE int rp_range(ell_run_t *r, ell_bud_t *b)
{
    ell_rp_t *rp = &r->rp;
    const uint32_t w = (rp->ws.res != NULL) ? (uint32_t)W_RP : (uint32_t)W_RP_RECOMP;
    const size_t k1 = r->k + magcal_ell_visits(b, w, r->n - r->k);
    const magcal_vec3_t *m = r->m;
    const magcal_ellipsoid_cal_t *cal = rp->cal;
    float *res = rp->ws.res;
    const uint8_t *keep = rp->ws.keep;
    float sum = rp->sum;
    float comp = rp->comp;
    float mx = rp->mx;
    size_t cnt = rp->cnt;
    size_t k;
    for (k = r->k; k < k1; ++k) {
        float rr;
        if (res != NULL) {
            rr = magcal_ell_residual(cal, &m[k]);
            res[k] = rr;
            if ((keep[k] & 1u) == 0u) {
                continue;
            }
        } else {
            if (!magcal_ell_gate_keeps(rp->gate, &m[k])) {
                continue;
            }
            rr = magcal_ell_residual(cal, &m[k]);
        }
        magcal_kahan_add(&sum, &comp, rr * rr);
        if (fabsf(rr) > mx) {
            mx = fabsf(rr);
        }
        cnt++;
    }
    r->k = k1;
    rp->sum = sum;
    rp->comp = comp;
    rp->mx = mx;
    rp->cnt = cnt;
    if (r->k < r->n) {
        return ELL_YIELD;
    }
    rp->kept = rp->cnt;
    rp->rms = (rp->cnt > 0u) ? sqrtf(rp->sum / (float)rp->cnt) : 0.0f;
    r->k = 0u;
    r->ph = rp->ret;
    return ELL_CONT;
}

/* ---- normalisation: mean and scale s (RMS distance from the mean); the scatter about the mean
 *      (packed xx, yx, yy, zx, zy, zz) into acc->sum, which pass 3 clears ---- */
static MAGCAL_NOINLINE int n1_range(ell_scratch_t *sw, ell_bud_t *b)
{
    ell_run_t *r = &sw->run;
    float *mu = sw->mu;
    size_t k;
    const size_t k1 = r->k + magcal_ell_visits(b, W_N1, r->n - r->k);
    float c0 = r->comp3[0];
    float c1 = r->comp3[1];
    float c2 = r->comp3[2];
    float m0 = mu[0];
    float m1 = mu[1];
    float m2 = mu[2];
    for (k = r->k; k < k1; ++k) {
        const magcal_vec3_t *p = &r->m[k];
        if (!magcal_isfinite_f(p->x) || !magcal_isfinite_f(p->y) || !magcal_isfinite_f(p->z)) {
            return MAGCAL_ERR_NONFINITE;
        }
        magcal_kahan_add(&m0, &c0, p->x);
        magcal_kahan_add(&m1, &c1, p->y);
        magcal_kahan_add(&m2, &c2, p->z);
    }
    r->k = k1;
    mu[0] = m0;
    mu[1] = m1;
    mu[2] = m2;
    r->comp3[0] = c0;
    r->comp3[1] = c1;
    r->comp3[2] = c2;
    if (r->k < r->n) {
        return ELL_YIELD;
    }
    for (k = 0u; k < 3u; ++k) {
        mu[k] /= (float)r->n;
    }
    (void)memset(&sw->acc, 0, sizeof(sw->acc));
    r->k = 0u;
    r->ph = ELL_PH_N2;
    return ELL_CONT;
}

static MAGCAL_NOINLINE int n2_range(ell_scratch_t *sw, ell_bud_t *b)
{
    ell_run_t *r = &sw->run;
    const float *mu = sw->mu;
    float *sc = sw->acc.sum;
    float *scc = sw->acc.comp;
    const size_t k1 = r->k + magcal_ell_visits(b, W_N2, r->n - r->k);
    size_t k;
    for (k = r->k; k < k1; ++k) {
        const magcal_vec3_t *p = &r->m[k];
        float dx = p->x - mu[0];
        float dy = p->y - mu[1];
        float dz = p->z - mu[2];
        magcal_kahan_add(&sc[0], &scc[0], dx * dx);
        magcal_kahan_add(&sc[1], &scc[1], dy * dx);
        magcal_kahan_add(&sc[2], &scc[2], dy * dy);
        magcal_kahan_add(&sc[3], &scc[3], dz * dx);
        magcal_kahan_add(&sc[4], &scc[4], dz * dy);
        magcal_kahan_add(&sc[5], &scc[5], dz * dz);
    }
    r->k = k1;
    if (r->k < r->n) {
        return ELL_YIELD;
    }
    r->k = 0u;
    r->ph = ELL_PH_NORM_DONE;
    return ELL_CONT;
}

/* The scale, the planarity of the raw scatter; pass 3 starts. */
static MAGCAL_NOINLINE int ph_norm_done(ell_scratch_t *sw, ell_bud_t *b)
{
    ell_run_t *r = &sw->run;
    const float *mu = sw->mu;
    const float *sc = sw->acc.sum;
    float s;
    if (magcal_ell_can(b, W_NORM_DONE) == 0) {
        return ELL_YIELD;
    }
    s = sqrtf((sc[0] + sc[2] + sc[5]) / (float)r->n);
    if (!(s > 1e-6f * (fabsf(mu[0]) + fabsf(mu[1]) + fabsf(mu[2]))) || !(s > 0.0f) ||
        !magcal_isfinite_f(s)) {
        return MAGCAL_ERR_DEGENERATE;
    }
    r->s = s;
    r->inv_s = 1.0f / s;
    r->planarity = magcal_ell_planarity(sw->acc.sum, sw);
    magcal_ell_acc_start(sw);
    r->ph = ELL_PH_ACC;
    return ELL_CONT;
}

/* The sphere fit gives the provisional centre; then the algebraic quadric's noise scale. */
static MAGCAL_NOINLINE int ph_sphere(ell_scratch_t *sw, ell_bud_t *b)
{
    ell_run_t *r = &sw->run;
    magcal_ellipsoid_cal_t *sphere_cal = &sw->cal[2];
    float *cov_centre = sw->cov_centre;
    magcal_status_t st;
    if (magcal_ell_can(b, W_SPHERE) == 0) {
        return ELL_YIELD;
    }
    r->model = r->cfg->model;
    cov_centre[0] = sw->mu[0];
    cov_centre[1] = sw->mu[1];
    cov_centre[2] = sw->mu[2];
    st = magcal_ell_solve_sphere(&sw->acc, sw->mat, sw->mu, r->s, r->cfg->field, r->cfg->pivot_tau,
                                 sphere_cal, &r->min_pivot);
    if (st == MAGCAL_OK) {
        cov_centre[0] = sphere_cal->v.x;
        cov_centre[1] = sphere_cal->v.y;
        cov_centre[2] = sphere_cal->v.z;
    }
    sw->mc.m = r->m;
    sw->mc.n = r->n;
    sw->mc.s = r->s;
    sw->mc.sphere = (st == MAGCAL_OK) ? sphere_cal : NULL;
    r->bits[0] = 0u;
    r->bits[1] = 0u;
    r->bits[2] = 0u;
    r->ph = ELL_PH_ASNR0; /* -> mc.snr_alg, then ELL_PH_COV */
    return ELL_CONT;
}

static MAGCAL_NOINLINE int cov_range(ell_scratch_t *sw, ell_bud_t *b)
{
    ell_run_t *r = &sw->run;
    const size_t k0 = r->k;
    r->k += magcal_ell_visits(b, W_COV, r->n - r->k);
    magcal_ell_coverage_cells(r->m, k0, r->k, sw->cov_centre, 1e-6f * r->s, r->bits);
    if (r->k < r->n) {
        return ELL_YIELD;
    }
    r->k = 0u;
    r->ph = ELL_PH_COV_DONE;
    return ELL_CONT;
}

static int ph_cov_done(ell_scratch_t *sw, ell_bud_t *b)
{
    ell_run_t *r = &sw->run;
    const magcal_ellipsoid_cfg_t *cfg = r->cfg;
    if (magcal_ell_can(b, W_COV_DONE) == 0) {
        return ELL_YIELD;
    }
    r->coverage = magcal_ell_coverage_count(r->bits);
    if (r->model == MAGCAL_ELLIPSOID_MODEL_AUTO) {
        if (r->coverage < cfg->min_coverage_sphere) {
            magcal_ell_explain_start(r, MAGCAL_ERR_COVERAGE);
            return ELL_CONT;
        }
        r->model = (r->coverage >= cfg->min_coverage_full && r->n >= MIN_QUADRIC_POINTS)
                       ? MAGCAL_ELLIPSOID_MODEL_QUADRIC9
                       : MAGCAL_ELLIPSOID_MODEL_SPHERE;
    }
    r->fit_ret = ELL_PH_KEEP1;
    r->ph = ELL_PH_FIT_SOLVE;
    return ELL_CONT;
}

/* The model's solve from the normal matrix (the sphere is complete here), then r->fit_ret. */
static MAGCAL_NOINLINE int ph_fit_solve(ell_scratch_t *sw, ell_bud_t *b)
{
    ell_run_t *r = &sw->run;
    const magcal_ellipsoid_cfg_t *cfg = r->cfg;
    const quad_acc_t *acc = &sw->acc;
    magcal_status_t st;
    uint32_t w = W_SOLVE9;
    if (r->model == MAGCAL_ELLIPSOID_MODEL_SPHERE) {
        w = W_SOLVE4;
    } else if (r->model == MAGCAL_ELLIPSOID_MODEL_QUADRIC10) {
        w = W_SOLVE10;
    } else {
        /* the 9-parameter quadric */
    }
    if (magcal_ell_can(b, w) == 0) {
        return ELL_YIELD;
    }
    if (r->model == MAGCAL_ELLIPSOID_MODEL_SPHERE) {
        st = (acc->count < MIN_SPHERE_POINTS)
                 ? MAGCAL_ERR_TOO_FEW_POINTS
                 : magcal_ell_solve_sphere(acc, sw->mat, sw->mu, r->s, cfg->field, cfg->pivot_tau,
                                           &sw->cal[0], &r->min_pivot);
        r->ph = r->fit_ret;
    } else if (acc->count < MIN_QUADRIC_POINTS) {
        st = MAGCAL_ERR_TOO_FEW_POINTS;
    } else if (r->model == MAGCAL_ELLIPSOID_MODEL_QUADRIC10) {
        st = magcal_ell_solve_quadric10(acc, sw->mat, cfg->pivot_tau, sw->coef, &r->min_pivot);
        r->ph = ELL_PH_FIT_EXTRACT;
    } else {
        st = magcal_ell_solve_quadric9(acc, sw->mat, cfg->pivot_tau, sw->coef, &r->min_pivot);
        r->ph = ELL_PH_FIT_EXTRACT;
    }
    if (st != MAGCAL_OK) {
        magcal_ell_explain_start(r, st);
    }
    return ELL_CONT;
}

static MAGCAL_NOINLINE int ph_fit_extract(ell_scratch_t *sw, ell_bud_t *b)
{
    ell_run_t *r = &sw->run;
    magcal_status_t st;
    if (magcal_ell_can(b, W_EXTRACT) == 0) {
        return ELL_YIELD;
    }
    st = magcal_ell_extract_quadric(sw, sw->mu, r->s, r->cfg->field, r->cfg->sqrt_method,
                                    &sw->cal[0]);
    r->ph = r->fit_ret;
    if (st != MAGCAL_OK) {
        magcal_ell_explain_start(r, st);
    }
    return ELL_CONT;
}

/* No gate yet: every sample kept (the stored verdicts). */
static int keep1_range(ell_scratch_t *sw, ell_bud_t *b)
{
    ell_run_t *r = &sw->run;
    if (r->ws.keep != NULL) {
        const size_t v = magcal_ell_visits(b, W_KEEP, r->n - r->k);
        (void)memset(&r->ws.keep[r->k], 1, v);
        r->k += v;
        if (r->k < r->n) {
            return ELL_YIELD;
        }
    }
    r->k = 0u;
    r->iter = 0u;
    r->prev_rejected = 0u;
    r->rms_valid = 0u;
    r->ph = ELL_PH_LOOP;
    return ELL_CONT;
}

/*
 * Outlier rejection: robust residual gate + refit (the samples are read again; with a workspace
 * their residuals are stored, not recomputed). The scale is 1.4826 x median |r| of the kept
 * samples, not their RMS: a dense burst pulls the first fit towards itself and inflates the RMS
 * enough to hide (issue 12). One round: residual pass, median, threshold, regate, settle, refit.
 */
static MAGCAL_NOINLINE int ph_loop_unit(ell_scratch_t *sw, ell_bud_t *b)
{
    ell_run_t *r = &sw->run;
    const magcal_ellipsoid_cfg_t *cfg = r->cfg;
    magcal_ellipsoid_cal_t *cal = &sw->cal[0];
    if (magcal_ell_can(b, W_UNIT) == 0) {
        return ELL_YIELD;
    }
    switch (r->ph) {
    case ELL_PH_LOOP:
        if (r->iter < cfg->max_refits && cfg->outlier_k > 0.0f) {
            magcal_ell_rp_start(r, cal, &sw->gate, &r->ws, ELL_PH_LOOP_MED);
        } else {
            r->ph = ELL_PH_FINAL;
        }
        break;
    case ELL_PH_LOOP_MED:
        r->rms = r->rp.rms;
        r->kept = r->rp.kept;
        r->rmax = r->rp.mx;
        r->rms_valid = 1u;
        sw->next.cal = cal;
        sw->src.cal = cal;
        magcal_ell_med_start(r, &sw->src, &sw->gate, &r->ws, r->kept, r->rmax, ELL_PH_THR);
        break;
    case ELL_PH_THR:
        sw->next.thr = cfg->outlier_k * MAGCAL_ELL_MAD_TO_SIGMA * r->med.result;
        if (sw->next.thr < cfg->outlier_floor_rel * cal->field) {
            sw->next.thr = cfg->outlier_floor_rel * cal->field;
        }
        /* the count under the new gate; acc follows it (unused when the loop ends here) */
        r->kept_new = 0u;
        r->k = 0u;
        r->ph = ELL_PH_REGATE;
        break;
    case ELL_PH_REFIT: {
        const size_t rejected = r->n - r->kept_new;
        if ((float)rejected > cfg->max_reject_frac * (float)r->n) {
            magcal_ell_explain_start(r, MAGCAL_ERR_TOO_MANY_OUTLIERS);
            break;
        }
        r->rms_valid = 0u;
        sw->cal[1] = *cal;
        sw->gate.cal = &sw->cal[1];
        sw->gate.thr = sw->next.thr;
        r->fit_ret = ELL_PH_LOOP_NEXT;
        r->ph = ELL_PH_FIT_SOLVE;
        break;
    }
    case ELL_PH_LOOP_NEXT:
        r->prev_rejected = r->n - r->kept_new;
        r->iter++;
        r->ph = ELL_PH_LOOP;
        break;
    case ELL_PH_FINAL:
        if (r->rms_valid == 0u) {
            magcal_ell_rp_start(r, cal, &sw->gate, &r->ws, ELL_PH_FINAL2);
        } else {
            r->ph = ELL_PH_FINAL2;
        }
        break;
    default: /* ELL_PH_FINAL2 */
        if (r->rms_valid == 0u) {
            r->rms = r->rp.rms;
            r->kept = r->rp.kept;
        }
        if (r->kept < ((r->model == MAGCAL_ELLIPSOID_MODEL_SPHERE) ? MIN_SPHERE_POINTS
                                                                   : MIN_QUADRIC_POINTS)) {
            return MAGCAL_ERR_TOO_FEW_POINTS;
        }
        r->ph = ELL_PH_TG0; /* the trust gates, then ELL_PH_OUT */
        break;
    }
    return ELL_CONT;
}

static int ph_out(ell_scratch_t *sw, ell_bud_t *b)
{
    ell_run_t *r = &sw->run;
    magcal_ellipsoid_result_t *out = r->out;
    const trust_diag_t *dg = &sw->dg;
    const quad_gate_t *gate = &sw->gate;
    if (magcal_ell_can(b, W_OUT) == 0) {
        return ELL_YIELD;
    }
    out->cal = sw->cal[0];
    out->residual_rms = r->rms;
    out->coverage = r->coverage;
    out->min_pivot = r->min_pivot;
    out->n_used = r->kept;
    out->n_rejected = r->n - r->kept;
    out->model = r->model;
    /* the final pass's gate, for magcal_ellipsoid_outliers (thr 0: no gate) */
    out->gate_cal = (gate->cal != NULL) ? sw->cal[1] : sw->cal[0];
    out->gate_thr = (gate->cal != NULL) ? gate->thr : 0.0f;
    out->motion_snr = dg->motion_snr;
    out->centre_std_rel = dg->centre_std_rel;
    out->shape_std = dg->shape_std;
    out->planarity = dg->planarity;
    out->field_raw = dg->field_raw;
    return MAGCAL_OK;
}

static MAGCAL_NOINLINE int ell_ph_check(ell_scratch_t *sw, ell_bud_t *b)
{
    ell_run_t *r = &sw->run;
    magcal_status_t st;
    if (magcal_ell_can(b, W_CHECK) == 0) {
        return ELL_YIELD;
    }
    sw->gate.cal = NULL; /* no gate yet */
    sw->gate.thr = 0.0f;
    sw->src.cal = NULL;
    sw->src.theta = NULL;
    sw->src.mu = NULL;
    sw->src.inv_s = 0.0f;
    r->all.cal = NULL;
    r->all.thr = 0.0f;
    r->min_pivot = 0.0f;
    r->rms = 0.0f;
    r->kept = 0u;
    st = ellipsoid_check_cfg(r->cfg);
    if (st != MAGCAL_OK) {
        return st;
    }
    if (r->n < ((r->cfg->model == MAGCAL_ELLIPSOID_MODEL_QUADRIC9 ||
                 r->cfg->model == MAGCAL_ELLIPSOID_MODEL_QUADRIC10)
                    ? MIN_QUADRIC_POINTS
                    : MIN_SPHERE_POINTS)) {
        return MAGCAL_ERR_TOO_FEW_POINTS;
    }
    sw->mu[0] = 0.0f;
    sw->mu[1] = 0.0f;
    sw->mu[2] = 0.0f;
    r->comp3[0] = 0.0f;
    r->comp3[1] = 0.0f;
    r->comp3[2] = 0.0f;
    r->k = 0u;
    r->ph = ELL_PH_N1;
    return ELL_CONT;
}

/* One phase of the fit: ELL_CONT (go on), ELL_YIELD (budget spent) or the final status. */
static int fit_phase(ell_scratch_t *sw, ell_bud_t *b)
{
    ell_run_t *r = &sw->run;
    if (r->ph >= ELL_PH_TRUST_FIRST) {
        return magcal_ell_trust_phase(sw, b);
    }
    switch (r->ph) {
    case ELL_PH_CHECK:
        return ell_ph_check(sw, b);
    case ELL_PH_N1:
        return n1_range(sw, b);
    case ELL_PH_N2:
        return n2_range(sw, b);
    case ELL_PH_NORM_DONE:
        return ph_norm_done(sw, b);
    case ELL_PH_ACC:
        return magcal_ell_acc_range(sw, b);
    case ELL_PH_SPHERE:
        return ph_sphere(sw, b);
    case ELL_PH_COV:
        return cov_range(sw, b);
    case ELL_PH_COV_DONE:
        return ph_cov_done(sw, b);
    case ELL_PH_FIT_SOLVE:
        return ph_fit_solve(sw, b);
    case ELL_PH_FIT_EXTRACT:
        return ph_fit_extract(sw, b);
    case ELL_PH_KEEP1:
        return keep1_range(sw, b);
    case ELL_PH_REGATE:
        return magcal_ell_regate_range(sw, b);
    case ELL_PH_SETTLE:
        return magcal_ell_settle_range(sw, b);
    case ELL_PH_OUT:
        return ph_out(sw, b);
    case ELL_PH_RP:
        return rp_range(r, b);
    default: /* ELL_PH_LOOP .. ELL_PH_FINAL2 */
        return ph_loop_unit(sw, b);
    }
}

/*
 * Phases until the budget is spent or the fit ends. Bounded: every ELL_CONT either ends a phase
 * (finitely many: at most 2 + max_refits rounds of a fixed sequence) or a pass, and every pass
 * visits each sample once.
 */
static MAGCAL_NOINLINE magcal_status_t fit_steps(ell_scratch_t *sw, uint32_t budget,
                                                 uint32_t *used, int first)
{
    int rc = ELL_CONT;
    *used = 0u;
    while (rc == ELL_CONT) {
        ell_bud_t b;
        b.left = budget - *used;
        b.cost = 0u;
        b.first = (*used == 0u && first != 0) ? (int)1 : (int)0;
        rc = fit_phase(sw, &b);
        *used += b.cost;
        if (rc == ELL_CONT && *used >= budget) {
            rc = ELL_YIELD;
        }
    }
    if (rc == ELL_YIELD) {
        return MAGCAL_IN_PROGRESS;
    }
    sw->run.ph = ELL_PH_DONE;
    return (magcal_status_t)rc;
}

/* Begin on a scratch (the stack's for magcal_ellipsoid_fit, the workspace's otherwise). */
static void fit_begin_on(magcal_ellipsoid_fit_slice_t *s, const ell_ws_t *ws,
                         const magcal_vec3_t *m, size_t n, const magcal_ellipsoid_cfg_t *cfg,
                         magcal_ellipsoid_result_t *out)
{
    ell_run_t *r = &ws->s->run;
    r->m = m;
    r->n = n;
    r->cfg = cfg;
    r->ws = *ws;
    r->out = out;
    r->k = 0u;
    r->ph = ELL_PH_CHECK;
    s->s_ = ws->s;
    s->used_ = 0u;
    s->status_ = (int32_t)MAGCAL_IN_PROGRESS;
}

magcal_status_t magcal_ellipsoid_fit_begin(magcal_ellipsoid_fit_slice_t *s, const magcal_vec3_t *m,
                                           size_t n, const magcal_ellipsoid_cfg_t *cfg, void *work,
                                           size_t work_len, magcal_ellipsoid_result_t *out)
{
    ell_ws_t ws;
    if (s == NULL) {
        return MAGCAL_ERR_NULL;
    }
    s->s_ = NULL;
    s->used_ = 0u;
    s->status_ = (int32_t)MAGCAL_ERR_ARG;
    if (m == NULL || cfg == NULL || work == NULL || out == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (magcal_misalign(work, 4u) != 0u) {
        return MAGCAL_ERR_ALIGNMENT;
    }
    if (n > (SIZE_MAX - MAGCAL_ELLIPSOID_FIT_SCRATCH_BYTES) / (sizeof(float) + 1u) ||
        work_len < MAGCAL_ELLIPSOID_FIT_WORKSPACE_LEN(n)) {
        return MAGCAL_ERR_WORKSPACE;
    }
    /* layout: [0 or 4 B] scratch (8-byte aligned) | n residuals at SCRATCH_BYTES | n verdicts */
    ws.s = (ell_scratch_t *)(void *)magcal_ell_align_up(work);
    ws.res = (float *)(void *)((uint8_t *)work + MAGCAL_ELLIPSOID_FIT_SCRATCH_BYTES);
    ws.keep = (uint8_t *)work + MAGCAL_ELLIPSOID_FIT_SCRATCH_BYTES + n * sizeof(float);
    fit_begin_on(s, &ws, m, n, cfg, out);
    return MAGCAL_OK;
}

magcal_status_t magcal_ell_fit_step_in(magcal_ellipsoid_fit_slice_t *s, uint32_t budget, int first)
{
    uint32_t used = 0u;
    magcal_status_t st;
    if (s == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (s->s_ == NULL) {
        return MAGCAL_ERR_ARG;
    }
    if (s->status_ != (int32_t)MAGCAL_IN_PROGRESS) {
        s->used_ = 0u;
        return (magcal_status_t)s->status_;
    }
    st = fit_steps((ell_scratch_t *)s->s_, (budget > 0u) ? budget : 1u, &used, first);
    s->used_ = used;
    s->status_ = (int32_t)st;
    return st;
}

magcal_status_t magcal_ellipsoid_fit_step(magcal_ellipsoid_fit_slice_t *s, uint32_t budget)
{
    return magcal_ell_fit_step_in(s, budget, 1);
}

magcal_status_t magcal_ellipsoid_fit(const magcal_vec3_t *m, size_t n,
                                     const magcal_ellipsoid_cfg_t *cfg,
                                     magcal_ellipsoid_fit_scratch_t *scratch,
                                     magcal_ellipsoid_result_t *out)
{
    magcal_ellipsoid_fit_slice_t sl;
    ell_ws_t ws;
    if (m == NULL || cfg == NULL || scratch == NULL || out == NULL) {
        return MAGCAL_ERR_NULL;
    }
    ws.s = (ell_scratch_t *)(void *)scratch; /* fixed scratch, no per-sample storage */
    ws.res = NULL;
    ws.keep = NULL;
    fit_begin_on(&sl, &ws, m, n, cfg, out);
    return magcal_ellipsoid_fit_step(&sl, UINT32_MAX);
}

magcal_status_t magcal_ellipsoid_fit_ws(const magcal_vec3_t *m, size_t n,
                                        const magcal_ellipsoid_cfg_t *cfg, void *work,
                                        size_t work_len, magcal_ellipsoid_result_t *out)
{
    magcal_ellipsoid_fit_slice_t sl;
    const magcal_status_t st = magcal_ellipsoid_fit_begin(&sl, m, n, cfg, work, work_len, out);
    if (st != MAGCAL_OK) {
        return st;
    }
    return magcal_ellipsoid_fit_step(&sl, UINT32_MAX);
}

#endif /* MAGCAL_CFG_ENABLE_3D */
