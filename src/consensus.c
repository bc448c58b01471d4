/*
 * Consensus (model-residual) outlier stage: RANSAC/LMedS over 5-point minimal ellipse sets,
 * MAD-scaled residual threshold, refit. See include/magcal/consensus.h for the algorithm.
 */
#include "magcal/consensus.h"

#include <math.h>
#include <string.h>

#include "magcal_internal.h"

/* 1 / Phi^-1(3/4): MAD of a normal distribution -> sigma. */
#define CONS_MAD_TO_SIGMA 1.4826f
/* 1 / sqrt(12): standard deviation of a uniform rounding error, in LSB */
#define CONS_INV_SQRT12 0.28867513f

/* k-th smallest (0-based) of a[0..n-1]; a is reordered. Iterative Hoare selection, bounded. */
static float cons_select(float *a, size_t n, size_t k)
{
    size_t lo = 0u;
    size_t hi = n - 1u;
    size_t guard;
    for (guard = 0u; guard < n + 1u && lo < hi; ++guard) {
        float pivot = a[lo + (hi - lo) / 2u];
        size_t i = lo;
        size_t j = hi;
        size_t inner;
        for (inner = 0u; inner <= n && i <= j; ++inner) {
            size_t s1;
            size_t s2;
            for (s1 = 0u; s1 < n; ++s1) {
                if (!(a[i] < pivot)) {
                    break;
                }
                ++i;
            }
            for (s2 = 0u; s2 < n; ++s2) {
                if (!(a[j] > pivot)) {
                    break;
                }
                --j;
            }
            if (i <= j) {
                float t = a[i];
                a[i] = a[j];
                a[j] = t;
                ++i;
                if (j == 0u) {
                    break;
                }
                --j;
            }
        }
        if (k <= j) {
            hi = j;
        } else if (k >= i) {
            lo = i;
        } else {
            break;
        }
    }
    return a[k];
}

/* Lower median of a[0..n-1] (n >= 1); a is reordered. */
static float cons_median(float *a, size_t n) { return cons_select(a, n, (n - 1u) / 2u); }

/*
 * Lower median of the residuals of every sample EXCEPT the 5 of the minimal set (which the model
 * passes through exactly: with them, the median of n = 20 samples was the 7th smallest of the 15
 * real residuals, sigma was 30 % low and 7.6 % of clean samples were rejected). The minimal set's
 * entries are set to -1 (below every |residual|) and the median is taken over the ranks above
 * them. a is reordered. Needs n > 5 (n == 5: the plain median of the five zeros).
 */
static MAGCAL_NOINLINE float cons_median_excl5(float *a, size_t n, const uint16_t idx[5])
{
    size_t j;
    if (n <= 5u) {
        return cons_median(a, n);
    }
    for (j = 0u; j < 5u; ++j) {
        a[idx[j]] = -1.0f;
    }
    return cons_select(a, n, 5u + (n - 6u) / 2u);
}

/* Sort idx[0..m-1] by key[0..m-1] ascending (keys move with their indices). Shell sort. */
static void cons_sort(float *key, uint16_t *idx, size_t m)
{
    /* Largest rank a shell-sort gap can reach is n; Ciura's gaps, extended. */
    static const uint16_t cons_gaps[] = {701u, 301u, 132u, 57u, 23u, 10u, 4u, 1u};
    size_t g;
    for (g = 0u; g < sizeof cons_gaps / sizeof cons_gaps[0]; ++g) {
        size_t gap = cons_gaps[g];
        size_t i;
        if (gap >= m) {
            continue;
        }
        for (i = gap; i < m; ++i) {
            float k = key[i];
            uint16_t v = idx[i];
            size_t j = i;
            while (j >= gap && key[j - gap] > k) {
                key[j] = key[j - gap];
                idx[j] = idx[j - gap];
                j -= gap;
            }
            key[j] = k;
            idx[j] = v;
        }
    }
}

/* |residual| of every sample. The samples are finite (checked on entry) and the model comes from a
 * successful fit, so a non-finite residual can only be an overflow of a sample astronomically far
 * from the model (|p - c| above ~1e19): it is stored as +Inf, i.e. always an outlier. Returning an
 * error instead made one such sample veto every minimal set and the run end in NONFINITE. */
static void cons_residuals(const magcal_ellipse_t *e, const magcal_vec2_t *pts, size_t n, float *r)
{
    size_t i;
    for (i = 0u; i < n; ++i) {
        float v = magcal_ellipse_residual(e, pts[i]);
        r[i] = magcal_isfinite_f(v) ? fabsf(v) : INFINITY;
    }
}

static float cons_mean_radius(const magcal_ellipse_t *e)
{
    return sqrtf(e->semi_minor * e->semi_major);
}

static magcal_status_t cons_check_cfg(const magcal_consensus_cfg_t *cfg)
{
    if (!magcal_isfinite_f(cfg->k_sigma) || !magcal_isfinite_f(cfg->min_thr_rel) ||
        !magcal_isfinite_f(cfg->max_thr_rel)) {
        return MAGCAL_ERR_ARG;
    }
    if (cfg->max_iter < 1u || cfg->max_iter > MAGCAL_CONSENSUS_MAX_ITER || cfg->refine_iter < 1u ||
        cfg->refine_iter > MAGCAL_CONSENSUS_MAX_REFINE || !(cfg->k_sigma > 0.0f) ||
        !(cfg->min_thr_rel >= 0.0f) || !(cfg->max_thr_rel > cfg->min_thr_rel)) {
        return MAGCAL_ERR_ARG;
    }
    return MAGCAL_OK;
}

/* threshold from sigma, clamped relative to the fit's mean radius */
static float cons_threshold(const magcal_consensus_cfg_t *cfg, const magcal_ellipse_t *e,
                            float sigma)
{
    float rm = cons_mean_radius(e);
    float thr = cfg->k_sigma * sigma;
    float lo = cfg->min_thr_rel * rm;
    float hi = cfg->max_thr_rel * rm;
    if (thr < lo) {
        thr = lo;
    }
    if (thr > hi) {
        thr = hi;
    }
    return thr;
}

/* State of one run, kept in the workspace: the minimal-set and refit loops call the ellipse fits,
 * which are on the deepest stack path of the 2-D pipeline, so the loops' frames stay small. */
typedef struct {
    magcal_ellipse_t best; /* best minimal model (LMedS) */
    magcal_ellipse_t cur;  /* current refit */
    magcal_ellipse_t cand; /* candidate minimal model */
    magcal_ellipse_t next; /* next refit */
    const magcal_consensus_cfg_t *cfg;
    const magcal_vec2_t *pts;
    size_t n;
    size_t m; /* candidates */
    float *res;
    float *scr;
    uint16_t *order;
    float best_score;
    float sigma;
    float sig_floor; /* quantisation noise of the samples: LSB / sqrt(12) */
    float thr;
    size_t n_in;
    uint32_t rng;
    uint16_t draws;
    uint16_t valid;
    uint16_t rounds;
    uint16_t idx[5];
} cons_state_t;

/* cppcheck-suppress misra-c2012-2.3 ; deviation D4: a static assert is an unused typedef */
MAGCAL_STATIC_ASSERT(sizeof(cons_state_t) + sizeof(void *) - 1u <= MAGCAL_CONSENSUS_STATE_LEN_,
                     consensus_state_fits_workspace);

/*
 * Smallest positive step between the sorted x (axis 0) or y (axis 1) values of the candidates:
 * the LSB of quantised samples (~0 for continuous ones). A lattice of few distinct values can
 * lie almost exactly on a conic, so the median residual is far below the quantisation noise and
 * a MAD threshold rejected a third of a 5-LSB ring's clean samples; sigma is floored at
 * LSB / sqrt(12), the noise of rounding. Uses scr[0..m-1] (shell sort).
 */
static float cons_min_step(float *scr, const magcal_vec2_t *pts, const uint16_t *order, size_t m,
                           int axis)
{
    static const uint16_t gaps[] = {701u, 301u, 132u, 57u, 23u, 10u, 4u, 1u};
    size_t g;
    size_t i;
    float best = INFINITY;
    for (i = 0u; i < m; ++i) {
        scr[i] = axis == 0 ? pts[order[i]].x : pts[order[i]].y;
    }
    for (g = 0u; g < sizeof gaps / sizeof gaps[0]; ++g) {
        size_t gap = gaps[g];
        if (gap >= m) {
            continue;
        }
        for (i = gap; i < m; ++i) {
            float k = scr[i];
            size_t j = i;
            while (j >= gap && scr[j - gap] > k) {
                scr[j] = scr[j - gap];
                j -= gap;
            }
            scr[j] = k;
        }
    }
    for (i = 1u; i < m; ++i) {
        float d = scr[i] - scr[i - 1u];
        if (d > 0.0f && d < best) {
            best = d;
        }
    }
    return magcal_isfinite_f(best) ? best : 0.0f;
}

/* 1. candidates and their angular order around the coordinate-wise median */
static MAGCAL_NOINLINE magcal_status_t cons_order(cons_state_t *S, const uint8_t *cand_mask)
{
    const magcal_vec2_t *pts = S->pts;
    uint16_t *order = S->order;
    float *scr = S->scr;
    size_t i;
    size_t m = 0u;
    float cx;
    float cy;
    for (i = 0u; i < S->n; ++i) {
        if (cand_mask == NULL || cand_mask[i] != 0u) {
            order[m] = (uint16_t)i;
            ++m;
        }
    }
    S->m = m;
    if (m < MAGCAL_ELLIPSE_MIN_POINTS) {
        return MAGCAL_ERR_TOO_FEW_POINTS;
    }
    S->sig_floor = CONS_INV_SQRT12 * fminf(cons_min_step(scr, pts, order, m, 0),
                                           cons_min_step(scr, pts, order, m, 1));
    for (i = 0u; i < m; ++i) {
        scr[i] = pts[order[i]].x;
    }
    cx = cons_median(scr, m);
    for (i = 0u; i < m; ++i) {
        scr[i] = pts[order[i]].y;
    }
    cy = cons_median(scr, m);
    for (i = 0u; i < m; ++i) {
        const magcal_vec2_t *p = &pts[order[i]];
        scr[i] = atan2f(p->y - cy, p->x - cx);
    }
    cons_sort(scr, order, m);
    return MAGCAL_OK;
}

/* 2. minimal sets spread over the angular order; LMedS score over every sample */
static MAGCAL_NOINLINE void cons_draw(cons_state_t *S)
{
    const size_t m = S->m;
    const size_t fifth = m / 5u;
    uint16_t it;
    for (it = 0u; it < S->cfg->max_iter; ++it) {
        uint32_t off = magcal_prng_next(&S->rng, (uint32_t)m);
        size_t j;
        for (j = 0u; j < 5u; ++j) {
            uint32_t jit = magcal_prng_next(&S->rng, (uint32_t)fifth);
            S->idx[j] = S->order[((size_t)off + j * fifth + (size_t)jit) % m];
        }
        ++S->draws;
        if (magcal_ellipse_fit_idx(S->pts, S->n, S->idx, 5u, &S->cand) == MAGCAL_OK) {
            float score;
            cons_residuals(&S->cand, S->pts, S->n, S->res);
            ++S->valid;
            score = cons_median_excl5(S->res, S->n, S->idx);
            if (score < S->best_score) {
                S->best_score = score;
                S->best = S->cand;
            }
        }
    }
}

/* Start model: the best minimal set, or (none valid) the least-squares fit of the candidates;
 * res gets its residuals. */
static MAGCAL_NOINLINE magcal_status_t cons_start(cons_state_t *S)
{
    if (S->valid == 0u) {
        size_t i;
        magcal_status_t st = magcal_ellipse_fit_idx(S->pts, S->n, S->order, S->m, &S->best);
        if (st != MAGCAL_OK) {
            return st;
        }
        cons_residuals(&S->best, S->pts, S->n, S->res);
        for (i = 0u; i < S->n; ++i) {
            S->scr[i] = S->res[i];
        }
        S->best_score = cons_median(S->scr, S->n);
    } else {
        cons_residuals(&S->best, S->pts, S->n, S->res);
    }
    return MAGCAL_OK;
}

/* Working mask wm (0/1 per sample) -> ascending index list in place; returns its length. */
static size_t cons_compact(uint16_t *wm, size_t n)
{
    size_t i;
    size_t k = 0u;
    for (i = 0u; i < n; ++i) {
        if (wm[i] != 0u) {
            wm[k] = (uint16_t)i;
            ++k;
        }
    }
    return k;
}

/* Index list of length k -> 0/1 mask again (backwards keeps entries not yet read). */
static void cons_expand(uint16_t *wm, size_t n, size_t k)
{
    size_t q = k;
    size_t t;
    for (t = n; t > 0u; --t) {
        size_t s = t - 1u;
        if (q > 0u && wm[q - 1u] == (uint16_t)s) {
            --q;
            wm[s] = 1u;
        } else {
            wm[s] = 0u;
        }
    }
}

/* New threshold from the current inliers' residuals, new inlier mask; returns the changed count. */
static MAGCAL_NOINLINE size_t cons_rethreshold(cons_state_t *S, uint16_t *wm)
{
    const size_t n = S->n;
    size_t changed = 0u;
    size_t k = 0u;
    size_t i;
    float nsig;
    float nthr;
    float ss = 0.0f;
    for (i = 0u; i < n; ++i) {
        if (wm[i] != 0u) {
            S->scr[k] = S->res[i];
            ss += S->res[i] * S->res[i];
            ++k;
        }
    }
    /* residuals of a 5-parameter least-squares fit of its own k inliers are smaller than the
     * noise by sqrt((k - 5) / k): undo it so small sets are not trimmed (k = 20: 13 %) */
    nsig = CONS_MAD_TO_SIGMA * cons_median(S->scr, k);
    if (k > (size_t)2u * MAGCAL_ELLIPSE_MIN_POINTS) {
        const size_t k_dof = k - MAGCAL_ELLIPSE_MIN_POINTS;
        float dof = (float)k / (float)k_dof;
        /* the MAD has 37 % efficiency: at k = 20 it fell to 0.6 sigma often enough to reject a
         * clean sample in 18 % of the runs. The RMS of the current inliers (already cut at the
         * threshold, so outliers beyond it cannot inflate it) is the efficient scale; the larger
         * of the two is used. */
        nsig = fmaxf(nsig * sqrtf(dof), sqrtf(ss / (float)k * dof));
    }
    nsig = fmaxf(nsig, S->sig_floor);
    if (k > (size_t)2u * MAGCAL_ELLIPSE_MIN_POINTS) {
        /* sigma is itself estimated from k - 5 residuals: the threshold is the Student-t quantile
         * of k_sigma (Cornish-Fisher, first order: x (1 + (z^2 + 1) / (4 dof)); 1.24 at k = 20,
         * 1.005 at k = 600) */
        const size_t k_dof = k - MAGCAL_ELLIPSE_MIN_POINTS;
        const float z = S->cfg->k_sigma;
        nthr = cons_threshold(
            S->cfg, &S->cur,
            nsig * (1.0f + (z * z + 1.0f) / (4.0f * (float)k_dof)));
    } else {
        nthr = cons_threshold(S->cfg, &S->cur, nsig);
    }
    for (i = 0u; i < n; ++i) {
        uint16_t v = (uint16_t)(S->res[i] <= nthr ? 1u : 0u);
        if (v != wm[i]) {
            ++changed;
            wm[i] = v;
        }
    }
    S->sigma = nsig;
    S->thr = nthr;
    return changed;
}

/* Start of step 3: current model = best, its threshold, the working inlier mask wm. */
static MAGCAL_NOINLINE void cons_refine_init(cons_state_t *S, uint16_t *wm)
{
    size_t i;
    S->cur = S->best;
    /* LMedS scale with Rousseeuw & Leroy's finite-sample factor 1 + 5 / (n - p): at n = 20 the
     * minimal set with the smallest median fits half of the samples better than the noise, and
     * the plain 1.4826 * median started the refits on a trimmed subset they never left */
    S->sigma = CONS_MAD_TO_SIGMA * S->best_score;
    if (S->n > MAGCAL_ELLIPSE_MIN_POINTS) {
        const size_t n_dof = S->n - MAGCAL_ELLIPSE_MIN_POINTS;
        S->sigma *= 1.0f + 5.0f / (float)n_dof;
    }
    S->sigma = fmaxf(S->sigma, S->sig_floor);
    S->thr = cons_threshold(S->cfg, &S->cur, S->sigma);
    for (i = 0u; i < S->n; ++i) {
        wm[i] = (uint16_t)(S->res[i] <= S->thr ? 1u : 0u);
    }
}

/* 3. threshold, inliers over every sample, refit; until the set is stable */
static MAGCAL_NOINLINE magcal_status_t cons_refine(cons_state_t *S)
{
    /* Working inlier set: order[] (the candidate list is no longer needed) as a 0/1 mask per
     * sample; inlier_mask is written only on success. */
    uint16_t *wm = S->order;
    const size_t n = S->n;
    size_t i;
    uint16_t r;
    int stop = 0;
    cons_refine_init(S, wm);
    for (r = 0u; (r < S->cfg->refine_iter) && (stop == 0); ++r) {
        magcal_status_t st;
        /* compact the mask into an ascending index list in place, fit, expand it back */
        const size_t k = cons_compact(wm, n);
        if (k < MAGCAL_ELLIPSE_MIN_POINTS) {
            return MAGCAL_ERR_TOO_FEW_POINTS;
        }
        st = magcal_ellipse_fit_idx(S->pts, n, wm, k, &S->next);
        cons_expand(wm, n, k);
        if (st != MAGCAL_OK) {
            stop = 1; /* keep the last good model */
        } else {
            ++S->rounds;
            cons_residuals(&S->next, S->pts, n, S->res);
            S->cur = S->next;
            if (cons_rethreshold(S, wm) == 0u) {
                stop = 1;
            }
        }
    }
    /* final verdict for every sample against `cur` (res holds cur's residuals unless the
     * last refit failed; recompute to be exact) */
    cons_residuals(&S->cur, S->pts, n, S->res);
    S->n_in = 0u;
    for (i = 0u; i < n; ++i) {
        if (S->res[i] <= S->thr) {
            ++S->n_in;
        }
    }
    if (S->n_in < MAGCAL_ELLIPSE_MIN_POINTS) {
        return MAGCAL_ERR_TOO_FEW_POINTS;
    }
    return MAGCAL_OK;
}

#define CONS_PH_RUN 1u
#define CONS_PH_DONE 2u

magcal_status_t magcal_consensus_begin(magcal_consensus_slice_t *s, const magcal_consensus_cfg_t *cfg,
                                       const magcal_vec2_t *pts, size_t n, const uint8_t *cand,
                                       void *work, size_t work_len, uint8_t *inlier,
                                       magcal_consensus_result_t *res)
{
    magcal_status_t st;

    if (s == NULL || cfg == NULL || pts == NULL || work == NULL || inlier == NULL || res == NULL) {
        return MAGCAL_ERR_NULL;
    }
    st = cons_check_cfg(cfg);
    if (st != MAGCAL_OK) {
        return st;
    }
    if (n > MAGCAL_MAX_SAMPLES) {
        return MAGCAL_ERR_ARG;
    }
    if (n < MAGCAL_ELLIPSE_MIN_POINTS) {
        return MAGCAL_ERR_TOO_FEW_POINTS;
    }
    if (work_len < MAGCAL_CONSENSUS_WORKSPACE_LEN(n)) {
        return MAGCAL_ERR_WORKSPACE;
    }
    s->cfg_ = cfg;
    s->pts_ = pts;
    s->n_ = n;
    s->cand_ = cand;
    s->state_ = (uint8_t *)work + ((sizeof(void *) - magcal_misalign(work, sizeof(void *))) %
                                   sizeof(void *));
    s->inlier_ = inlier;
    s->res_ = res;
    s->phase_ = CONS_PH_RUN;
    s->status_ = (int8_t)MAGCAL_IN_PROGRESS;
    return MAGCAL_OK;
}

/* the whole run (first version: one step) */
static magcal_status_t cons_run_all(magcal_consensus_slice_t *sl)
{
    const magcal_consensus_cfg_t *cfg = sl->cfg_;
    const magcal_vec2_t *pts = sl->pts_;
    const size_t n = sl->n_;
    const uint8_t *cand_mask = sl->cand_;
    uint8_t *inlier_mask = sl->inlier_;
    magcal_consensus_result_t *result = sl->res_;
    cons_state_t *S = (cons_state_t *)sl->state_;
    size_t i;
    magcal_status_t st;

    for (i = 0u; i < n; ++i) {
        if (!magcal_isfinite_f(pts[i].x) || !magcal_isfinite_f(pts[i].y)) {
            return MAGCAL_ERR_NONFINITE;
        }
    }
    S->cfg = cfg;
    S->pts = pts;
    S->n = n;
    S->m = 0u;
    S->res = (float *)(void *)(S + 1);
    S->scr = S->res + n;
    S->order = (uint16_t *)(void *)(S->scr + n);
    S->best_score = INFINITY;
    S->sigma = 0.0f;
    S->sig_floor = 0.0f;
    S->thr = 0.0f;
    S->n_in = 0u;
    S->rng = cfg->seed;
    S->draws = 0u;
    S->valid = 0u;
    S->rounds = 0u;

    st = cons_order(S, cand_mask);
    if (st != MAGCAL_OK) {
        return st;
    }
    cons_draw(S);
    st = cons_start(S);
    if (st != MAGCAL_OK) {
        return st;
    }
    st = cons_refine(S);
    if (st != MAGCAL_OK) {
        return st;
    }

    /* success: write outputs */
    {
        uint16_t rescued = 0u;
        uint16_t rejected = 0u;
        for (i = 0u; i < n; ++i) {
            uint8_t in = (uint8_t)(S->res[i] <= S->thr ? 1u : 0u);
            uint8_t c = (uint8_t)((cand_mask == NULL || cand_mask[i] != 0u) ? 1u : 0u);
            if (in != 0u && c == 0u) {
                ++rescued;
            }
            if (in == 0u && c != 0u) {
                ++rejected;
            }
            inlier_mask[i] = in;
        }
        result->fit = S->cur;
        result->sigma = S->sigma;
        result->threshold = S->thr;
        result->best_score = S->best_score;
        result->n_candidates = (uint16_t)S->m;
        result->n_inliers = (uint16_t)S->n_in;
        result->n_rescued = rescued;
        result->n_rejected = rejected;
        result->draws = S->draws;
        result->valid_models = S->valid;
        result->rounds = S->rounds;
    }
    return MAGCAL_OK;
}

magcal_status_t magcal_consensus_step(magcal_consensus_slice_t *s, uint32_t budget)
{
    magcal_status_t st;

    (void)budget;
    if (s == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (s->phase_ == CONS_PH_DONE) {
        return (magcal_status_t)s->status_;
    }
    if (s->phase_ != CONS_PH_RUN) {
        return MAGCAL_ERR_ARG;
    }
    st = cons_run_all(s);
    s->phase_ = CONS_PH_DONE;
    s->status_ = (int8_t)st;
    return st;
}

magcal_status_t magcal_consensus_run(const magcal_consensus_cfg_t *cfg, const magcal_vec2_t *pts,
                                     size_t n, const uint8_t *cand_mask, void *work,
                                     size_t work_len, uint8_t *inlier_mask,
                                     magcal_consensus_result_t *result)
{
    magcal_consensus_slice_t s;
    magcal_status_t st = magcal_consensus_begin(&s, cfg, pts, n, cand_mask, work, work_len,
                                                inlier_mask, result);
    if (st != MAGCAL_OK) {
        return st;
    }
    return magcal_consensus_step(&s, UINT32_MAX);
}
