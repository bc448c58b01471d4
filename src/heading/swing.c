/* Classical compass swing (algorithms.md 5.1) and the course-over-ground motion swing. */
#include <math.h>
#include <string.h>

#include "magcal/swing.h"
#include "magcal_internal.h"

#if MAGCAL_CFG_ENABLE_SWING /* whole file: config.h feature switch */

#define SWING_N MAGCAL_SWING_NCOEF
#define SWING_COG_MAGIC 0x53574E47u /* "SWNG" */
#define SWING_MAX_ITER 16u
/* Fixed-point inversion contracts by at most this slope bound (checked at fit time). */
#define SWING_MAX_SLOPE 0.9f

/* g = (1, sin psi, cos psi, sin 2psi, cos 2psi) for psi in degrees. */
static void swing_basis(float psi_deg, float g[SWING_N])
{
    float r = magcal_wrap360_deg(psi_deg) * MAGCAL_RAD_PER_DEG_F;
    float s = sinf(r);
    float c = cosf(r);
    g[0] = 1.0f;
    g[1] = s;
    g[2] = c;
    g[3] = 2.0f * s * c;
    g[4] = c * c - s * s;
}

static float swing_eval(const float coef[SWING_N], float psi_deg)
{
    float g[SWING_N];
    float d = 0.0f;
    size_t i;
    swing_basis(psi_deg, g);
    for (i = 0u; i < SWING_N; ++i) {
        d += coef[i] * g[i];
    }
    return d;
}

static magcal_status_t swing_check_cfg(const magcal_swing_cfg_t *cfg)
{
    if (!(cfg->min_spread_pivot > 0.0f && cfg->min_spread_pivot <= 0.5f) ||
        !(cfg->pivot_tau > 0.0f && cfg->pivot_tau < 1.0f) || cfg->iterations < 1u ||
        cfg->iterations > SWING_MAX_ITER) {
        return MAGCAL_ERR_ARG;
    }
    return MAGCAL_OK;
}

/*
 * Smallest pivot of the plain (not equilibrated) LDL^T factorisation of the Gram matrix
 * ata / wsum. The basis functions are bounded by 1 and have mean square 1/2 on a full circle, so
 * unlike the equilibrated solver pivot this is an absolute measure of spread: a column like
 * sin 2psi at the four cardinal headings (rounding noise only) cannot pass.
 * ata: the normal matrix, lower triangle (diagonal included) read only; L is kept transposed in
 * its unused strict upper triangle (L_ij at [j][i]), so the Gram matrix needs no copy of its own
 * (magcal_ldlt_solve reads only the lower triangle and reuses the upper one for its scales).
 */
static float swing_spread_pivot(float ata[SWING_N * SWING_N], float wsum)
{
    float d[SWING_N];
    float minp = 1.0f;
    size_t i;
    size_t j;
    size_t k;
    for (k = 0u; k < SWING_N; ++k) {
        d[k] = 0.0f; /* d[k] is read only for k < j, after it is set: defined for the analysers */
    }
    for (j = 0u; j < SWING_N; ++j) {
        float dj = ata[j * SWING_N + j] / wsum;
        for (k = 0u; k < j; ++k) {
            dj -= ata[k * SWING_N + j] * ata[k * SWING_N + j] * d[k];
        }
        if (!(dj > 1e-12f)) {
            return 0.0f;
        }
        d[j] = dj;
        minp = dj < minp ? dj : minp;
        for (i = j + 1u; i < SWING_N; ++i) {
            float s = ata[i * SWING_N + j] / wsum;
            for (k = 0u; k < j; ++k) {
                s -= ata[k * SWING_N + i] * ata[k * SWING_N + j] * d[k];
            }
            ata[j * SWING_N + i] = s / dj;
        }
    }
    return minp;
}

/*
 * Where the fit's points come from: the caller's arrays (magcal_swing_fit) or, without a copy,
 * the occupied bins of a course-over-ground accumulator (magcal_swing_cog_fit).
 */
typedef struct {
    const float *psi_c_deg;
    const float *psi_ref_deg;
    const float *weights;
    const magcal_swing_cog_t *cog; /* non-NULL: the bins; the arrays are unused */
    size_t n;                      /* points (arrays) or MAGCAL_SWING_COG_BINS (bins) */
    magcal_swing_regressor_t regressor;
} swing_src_t;

/* Point k: weight (0 = unused), regressor heading and wrap(psi_ref - psi_c). */
static float swing_point(const swing_src_t *src, size_t k, float *x, float *delta)
{
    float w;
    float pc;
    float pr;
    if (src->cog != NULL) {
        const float bin_w = 360.0f / (float)MAGCAL_SWING_COG_BINS;
        const magcal_swing_bin_t *b = &src->cog->bins[k];
        if (!(b->weight > 0.0f)) {
            *x = 0.0f; /* unused point: defined outputs all the same */
            *delta = 0.0f;
            return 0.0f;
        }
        w = 1.0f; /* one point per occupied bin, unweighted */
        pc = magcal_wrap360_deg(((float)k + 0.5f) * bin_w + b->psi_c_off_deg);
        pr = magcal_wrap360_deg(pc + b->delta_deg);
    } else {
        w = (src->weights != NULL) ? src->weights[k] : 1.0f;
        pc = src->psi_c_deg[k];
        pr = src->psi_ref_deg[k];
    }
    *x = (src->regressor == MAGCAL_SWING_REG_MEASURED) ? pc : pr;
    *delta = magcal_wrap180_deg(pr - pc);
    return w;
}

/* The fit of magcal_swing_fit on checked points (`used` of them with a positive weight). */
static magcal_status_t swing_fit_src(const magcal_swing_cfg_t *cfg, const swing_src_t *src,
                                     size_t used, magcal_swing_model_t *model,
                                     magcal_swing_stats_t *stats)
{
    float ata[SWING_N * SWING_N];
    float atb[SWING_N];
    float g[SWING_N];
    float wsum = 0.0f;
    float pivot;
    float sse = 0.0f;
    float maxr = 0.0f;
    size_t k;
    size_t i;
    size_t j;
    magcal_status_t st;

    (void)memset(ata, 0, sizeof ata);
    (void)memset(atb, 0, sizeof atb);
    for (k = 0u; k < src->n; ++k) {
        float x;
        float delta;
        const float w = swing_point(src, k, &x, &delta);
        if (!(w > 0.0f)) {
            continue;
        }
        wsum += w;
        swing_basis(x, g);
        for (i = 0u; i < SWING_N; ++i) {
            atb[i] += w * g[i] * delta;
            for (j = 0u; j <= i; ++j) {
                ata[i * SWING_N + j] += w * g[i] * g[j];
            }
        }
    }
    pivot = swing_spread_pivot(ata, wsum);
    if (pivot < cfg->min_spread_pivot) {
        if (stats != NULL) {
            stats->min_spread_pivot = pivot;
        }
        return MAGCAL_ERR_SPREAD;
    }
    st = magcal_ldlt_solve(ata, atb, SWING_N, cfg->pivot_tau, NULL);
    if (st == MAGCAL_ERR_ILL_CONDITIONED || st == MAGCAL_ERR_DEGENERATE) {
        if (stats != NULL) {
            stats->min_spread_pivot = pivot;
        }
        return MAGCAL_ERR_SPREAD;
    }
    if (st != MAGCAL_OK) {
        return st;
    }
    if (src->regressor == MAGCAL_SWING_REG_REFERENCE) {
        /* |d delta/d psi| <= (|B| + |C| + 2|D| + 2|E|) pi/180: the contraction bound of the
         * fixed-point inversion psi_{j+1} = psi_c + delta(psi_j). */
        float slope =
            (fabsf(atb[1]) + fabsf(atb[2]) + 2.0f * fabsf(atb[3]) + 2.0f * fabsf(atb[4])) *
            MAGCAL_RAD_PER_DEG_F;
        if (!(slope < SWING_MAX_SLOPE)) {
            return MAGCAL_ERR_NOT_CONVERGED;
        }
    }
    for (k = 0u; k < src->n; ++k) {
        float x;
        float delta;
        const float w = swing_point(src, k, &x, &delta);
        float r;
        if (!(w > 0.0f)) {
            continue;
        }
        r = delta - swing_eval(atb, x);
        sse += w * r * r;
        maxr = fabsf(r) > maxr ? fabsf(r) : maxr;
    }
    for (i = 0u; i < SWING_N; ++i) {
        model->coef_deg[i] = atb[i];
    }
    model->regressor = src->regressor;
    model->iterations = cfg->iterations;
    if (stats != NULL) {
        stats->rms_deg = sqrtf(sse / wsum);
        stats->max_abs_deg = maxr;
        stats->min_spread_pivot = pivot;
        stats->n_used = used;
    }
    return MAGCAL_OK;
}

magcal_status_t magcal_swing_fit(const magcal_swing_cfg_t *cfg, const float *psi_c_deg,
                                 const float *psi_ref_deg, const float *weights, size_t n,
                                 magcal_swing_regressor_t regressor, magcal_swing_model_t *model,
                                 magcal_swing_stats_t *stats)
{
    swing_src_t src;
    size_t used = 0u;
    size_t k;
    magcal_status_t st;

    if (cfg == NULL || psi_c_deg == NULL || psi_ref_deg == NULL || model == NULL) {
        return MAGCAL_ERR_NULL;
    }
    st = swing_check_cfg(cfg);
    if (st != MAGCAL_OK) {
        return st;
    }
    if (regressor != MAGCAL_SWING_REG_MEASURED && regressor != MAGCAL_SWING_REG_REFERENCE) {
        return MAGCAL_ERR_ARG;
    }
    for (k = 0u; k < n; ++k) {
        float w = (weights != NULL) ? weights[k] : 1.0f;
        if (!magcal_isfinite_f(psi_c_deg[k]) || !magcal_isfinite_f(psi_ref_deg[k]) ||
            !magcal_isfinite_f(w)) {
            return MAGCAL_ERR_NONFINITE;
        }
        if (w < 0.0f) {
            return MAGCAL_ERR_ARG;
        }
        if (w > 0.0f) {
            ++used;
        }
    }
    if (used < MAGCAL_SWING_MIN_POINTS) {
        return MAGCAL_ERR_TOO_FEW_POINTS;
    }
    src.psi_c_deg = psi_c_deg;
    src.psi_ref_deg = psi_ref_deg;
    src.weights = weights;
    src.cog = NULL;
    src.n = n;
    src.regressor = regressor;
    return swing_fit_src(cfg, &src, used, model, stats);
}

static int swing_model_finite(const magcal_swing_model_t *model)
{
    size_t i;
    for (i = 0u; i < SWING_N; ++i) {
        if (!magcal_isfinite_f(model->coef_deg[i])) {
            return 0;
        }
    }
    return 1;
}

magcal_status_t magcal_swing_deviation(const magcal_swing_model_t *model, float psi_deg,
                                       float *delta_deg)
{
    if (model == NULL || delta_deg == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (!magcal_isfinite_f(psi_deg) || !swing_model_finite(model)) {
        return MAGCAL_ERR_NONFINITE;
    }
    *delta_deg = swing_eval(model->coef_deg, psi_deg);
    return MAGCAL_OK;
}

magcal_status_t magcal_swing_apply(const magcal_swing_model_t *model, float psi_c_deg,
                                   float *psi_deg)
{
    float psi;
    uint8_t j;
    if (model == NULL || psi_deg == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (!magcal_isfinite_f(psi_c_deg) || !swing_model_finite(model)) {
        return MAGCAL_ERR_NONFINITE;
    }
    if (model->regressor == MAGCAL_SWING_REG_MEASURED) {
        psi = psi_c_deg + swing_eval(model->coef_deg, psi_c_deg);
    } else if (model->regressor == MAGCAL_SWING_REG_REFERENCE) {
        if (model->iterations < 1u || model->iterations > SWING_MAX_ITER) {
            return MAGCAL_ERR_ARG;
        }
        /* Fixed point of psi = psi_c + delta(psi): the error shrinks by |d delta/d psi| per step
         * (0.1 for 5 deg of one-cycle deviation), so 5 steps reach float32 resolution. */
        psi = psi_c_deg;
        for (j = 0u; j < model->iterations; ++j) {
            psi = psi_c_deg + swing_eval(model->coef_deg, psi);
        }
    } else {
        return MAGCAL_ERR_ARG;
    }
    *psi_deg = magcal_wrap360_deg(psi);
    return MAGCAL_OK;
}

magcal_status_t magcal_swing_model_from_error(const float err_coef_deg[MAGCAL_SWING_NCOEF],
                                              magcal_swing_regressor_t regressor,
                                              uint8_t iterations, magcal_swing_model_t *model)
{
    magcal_swing_model_t m;
    size_t i;
    if (err_coef_deg == NULL || model == NULL) {
        return MAGCAL_ERR_NULL;
    }
    for (i = 0u; i < SWING_N; ++i) {
        if (!magcal_isfinite_f(err_coef_deg[i])) {
            return MAGCAL_ERR_NONFINITE;
        }
        m.coef_deg[i] = -err_coef_deg[i];
    }
    if (regressor == MAGCAL_SWING_REG_MEASURED) {
        m.iterations = 1u;
    } else if (regressor == MAGCAL_SWING_REG_REFERENCE) {
        float slope = (fabsf(m.coef_deg[1]) + fabsf(m.coef_deg[2]) + 2.0f * fabsf(m.coef_deg[3]) +
                       2.0f * fabsf(m.coef_deg[4])) *
                      MAGCAL_RAD_PER_DEG_F;
        if (iterations < 1u || iterations > SWING_MAX_ITER) {
            return MAGCAL_ERR_ARG;
        }
        if (!(slope < SWING_MAX_SLOPE)) {
            return MAGCAL_ERR_NOT_CONVERGED;
        }
        m.iterations = iterations;
    } else {
        return MAGCAL_ERR_ARG;
    }
    m.regressor = regressor;
    *model = m;
    return MAGCAL_OK;
}

magcal_status_t magcal_swing_model_to_error(const magcal_swing_model_t *model,
                                            float err_coef_deg[MAGCAL_SWING_NCOEF])
{
    size_t i;
    if (model == NULL || err_coef_deg == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (!swing_model_finite(model)) {
        return MAGCAL_ERR_NONFINITE;
    }
    for (i = 0u; i < SWING_N; ++i) {
        err_coef_deg[i] = -model->coef_deg[i];
    }
    return MAGCAL_OK;
}

/* ------------------------------------------------------------------------------------------- */
/* Motion swing */

static magcal_status_t swing_cog_check(const magcal_swing_cog_t *acc)
{
    if (acc == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (acc->magic != SWING_COG_MAGIC) {
        return MAGCAL_ERR_NOT_INITIALISED;
    }
    return MAGCAL_OK;
}

static void swing_cog_reset_leg(magcal_swing_cog_t *acc)
{
    acc->sum_ref_off = 0.0f;
    acc->sum_psi_off = 0.0f;
    acc->leg_n = 0u;
    acc->leg_seen = 0u;
}

/* Merge one (psi_c, psi_ref) pair of weight w into the bin of psi_c (weighted running mean). */
static void swing_cog_merge(magcal_swing_cog_t *acc, float psi_c_deg, float psi_ref_deg, float w)
{
    const float bin_w = 360.0f / (float)MAGCAL_SWING_COG_BINS;
    float psi = magcal_wrap360_deg(psi_c_deg);
    const float pos = psi / bin_w;
    size_t idx = (size_t)pos;
    magcal_swing_bin_t *b;
    float off;
    float delta;
    float wn;
    if (idx >= MAGCAL_SWING_COG_BINS) { /* psi just below 360 rounding up */
        idx = MAGCAL_SWING_COG_BINS - 1u;
    }
    b = &acc->bins[idx];
    off = magcal_wrap180_deg(psi - ((float)idx + 0.5f) * bin_w);
    delta = magcal_wrap180_deg(psi_ref_deg - psi);
    wn = b->weight + w;
    if (b->weight > 0.0f) {
        b->psi_c_off_deg += (off - b->psi_c_off_deg) * (w / wn);
        b->delta_deg += magcal_wrap180_deg(delta - b->delta_deg) * (w / wn);
    } else {
        b->psi_c_off_deg = off;
        b->delta_deg = delta;
    }
    b->weight = wn;
    if (b->legs < UINT16_MAX) {
        b->legs++;
    }
}

/* Commit the current leg if it is long enough, then start an empty one. */
static void swing_cog_close_leg(magcal_swing_cog_t *acc)
{
    if (acc->leg_n >= (uint32_t)acc->cfg.min_leg_epochs &&
        acc->leg_t1_s - acc->leg_t0_s >= acc->cfg.min_leg_s) {
        float n = (float)acc->leg_n;
        float psi_c = acc->leg_org_psi_deg + acc->sum_psi_off / n;
        float psi_ref = acc->leg_org_ref_deg + acc->sum_ref_off / n;
        swing_cog_merge(acc, psi_c, psi_ref, n);
        acc->legs_total++;
    }
    swing_cog_reset_leg(acc);
}

magcal_status_t magcal_swing_cog_init_checked(magcal_swing_cog_t *acc, const magcal_swing_cog_cfg_t *cfg,
                                              uint32_t config, size_t inst_size)
{
    magcal_status_t st;
    if (magcal_config_check_fingerprint(config) != MAGCAL_OK || inst_size != sizeof *acc) {
        return MAGCAL_ERR_CONFIG_MISMATCH; /* caller's struct layout is not ours: write nothing */
    }
    if (acc == NULL || cfg == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (!(cfg->min_speed_mps > 0.0f) || !magcal_isfinite_f(cfg->min_speed_mps) ||
        !(cfg->max_cog_rate_dps > 0.0f) || !magcal_isfinite_f(cfg->max_cog_rate_dps) ||
        !(cfg->max_cog_dev_deg > 0.0f) || !(cfg->max_cog_dev_deg <= 180.0f) ||
        !(cfg->max_gap_s > 0.0f) || !magcal_isfinite_f(cfg->max_gap_s) ||
        !(cfg->min_leg_s >= 0.0f) || !magcal_isfinite_f(cfg->min_leg_s) ||
        cfg->min_leg_epochs < 2u || cfg->min_bins < MAGCAL_SWING_MIN_POINTS ||
        cfg->min_bins > MAGCAL_SWING_COG_BINS) {
        return MAGCAL_ERR_ARG;
    }
    st = swing_check_cfg(&cfg->fit);
    if (st != MAGCAL_OK) {
        return st;
    }
    (void)memset(acc, 0, sizeof *acc);
    acc->cfg = *cfg;
    acc->magic = SWING_COG_MAGIC;
    return MAGCAL_OK;
}

magcal_status_t magcal_swing_cog_add(magcal_swing_cog_t *acc, const magcal_swing_epoch_t *ep)
{
    magcal_status_t st = swing_cog_check(acc);
    float psi_ref;
    float dt;
    int straight;
    if (st != MAGCAL_OK) {
        return st;
    }
    if (ep == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (!magcal_isfinite_f(ep->time_s) || !magcal_isfinite_f(ep->psi_c_deg) ||
        !magcal_isfinite_f(ep->cog_deg) || !magcal_isfinite_f(ep->speed_mps) ||
        !magcal_isfinite_f(ep->decl_deg)) {
        swing_cog_close_leg(acc);
        acc->have_last = 0u;
        return MAGCAL_ERR_NONFINITE;
    }
    /* Straight and steady: fast enough, continuous in time, COG rate below the limit. */
    dt = ep->time_s - acc->last_t_s;
    straight = 0;
    if (ep->speed_mps >= acc->cfg.min_speed_mps && acc->have_last != 0u && dt > 0.0f &&
        dt <= acc->cfg.max_gap_s &&
        fabsf(magcal_wrap180_deg(ep->cog_deg - acc->last_cog_deg)) <=
            acc->cfg.max_cog_rate_dps * dt) {
        straight = 1;
    }
    acc->last_t_s = ep->time_s;
    acc->last_cog_deg = ep->cog_deg;
    acc->have_last = 1u;
    if (straight == 0) {
        swing_cog_close_leg(acc);
        return MAGCAL_ERR_GATED;
    }
    psi_ref = ep->cog_deg - ep->decl_deg;
    if (acc->leg_n > 0u) {
        /* Slow curve: COG drifted from the leg mean although each step was below the rate. */
        float mean = acc->leg_org_ref_deg + acc->sum_ref_off / (float)acc->leg_n;
        if (fabsf(magcal_wrap180_deg(psi_ref - mean)) > acc->cfg.max_cog_dev_deg) {
            swing_cog_close_leg(acc);
        }
    }
    if (acc->leg_seen < UINT32_MAX) {
        acc->leg_seen++;
    }
    if (acc->leg_seen <= (uint32_t)acc->cfg.trim_epochs) {
        return MAGCAL_ERR_GATED;
    }
    if (acc->leg_n == 0u) {
        acc->leg_org_ref_deg = psi_ref;
        acc->leg_org_psi_deg = ep->psi_c_deg;
        acc->leg_t0_s = ep->time_s;
    }
    acc->sum_ref_off += magcal_wrap180_deg(psi_ref - acc->leg_org_ref_deg);
    acc->sum_psi_off += magcal_wrap180_deg(ep->psi_c_deg - acc->leg_org_psi_deg);
    acc->leg_t1_s = ep->time_s;
    acc->leg_n++;
    return MAGCAL_OK;
}

magcal_status_t magcal_swing_cog_flush(magcal_swing_cog_t *acc)
{
    magcal_status_t st = swing_cog_check(acc);
    if (st != MAGCAL_OK) {
        return st;
    }
    swing_cog_close_leg(acc);
    return MAGCAL_OK;
}

magcal_status_t magcal_swing_cog_add_pair(magcal_swing_cog_t *acc, float psi_c_deg,
                                          float psi_ref_deg, float weight)
{
    magcal_status_t st = swing_cog_check(acc);
    if (st != MAGCAL_OK) {
        return st;
    }
    if (!magcal_isfinite_f(psi_c_deg) || !magcal_isfinite_f(psi_ref_deg) ||
        !magcal_isfinite_f(weight)) {
        return MAGCAL_ERR_NONFINITE;
    }
    if (!(weight > 0.0f)) {
        return MAGCAL_ERR_ARG;
    }
    swing_cog_merge(acc, psi_c_deg, psi_ref_deg, weight);
    return MAGCAL_OK;
}

magcal_status_t magcal_swing_cog_count(const magcal_swing_cog_t *acc, size_t *bins, size_t *legs)
{
    magcal_status_t st = swing_cog_check(acc);
    size_t i;
    size_t nb = 0u;
    if (st != MAGCAL_OK) {
        return st;
    }
    if (bins == NULL || legs == NULL) {
        return MAGCAL_ERR_NULL;
    }
    for (i = 0u; i < MAGCAL_SWING_COG_BINS; ++i) {
        if (acc->bins[i].weight > 0.0f) {
            ++nb;
        }
    }
    *bins = nb;
    *legs = (size_t)acc->legs_total;
    return MAGCAL_OK;
}

magcal_status_t magcal_swing_cog_fit(const magcal_swing_cog_t *acc, magcal_swing_model_t *model,
                                     magcal_swing_stats_t *stats)
{
    swing_src_t src;
    size_t n = 0u;
    size_t i;
    magcal_status_t st = swing_cog_check(acc);
    if (st != MAGCAL_OK) {
        return st;
    }
    if (model == NULL) {
        return MAGCAL_ERR_NULL;
    }
    for (i = 0u; i < MAGCAL_SWING_COG_BINS; ++i) {
        if (acc->bins[i].weight > 0.0f) {
            ++n;
        }
    }
    if (n < (size_t)acc->cfg.min_bins) {
        return MAGCAL_ERR_TOO_FEW_POINTS;
    }
    /* the occupied bins, read in place (one point each, unweighted): the same sums in the same
     * order as magcal_swing_fit on the bins copied out, without two 36-float copies on the stack;
     * the bins are finite (only finite pairs are merged) and min_bins >= MAGCAL_SWING_MIN_POINTS */
    src.psi_c_deg = NULL;
    src.psi_ref_deg = NULL;
    src.weights = NULL;
    src.cog = acc;
    src.n = MAGCAL_SWING_COG_BINS;
    src.regressor = MAGCAL_SWING_REG_MEASURED;
    return swing_fit_src(&acc->cfg.fit, &src, n, model, stats);
}

#endif /* MAGCAL_CFG_ENABLE_SWING */
