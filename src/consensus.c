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

/* Largest rank a shell-sort gap can reach is n; Ciura's gaps, extended. */
static const uint16_t cons_gaps[] = {701u, 301u, 132u, 57u, 23u, 10u, 4u, 1u};

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
            for (s1 = 0u; s1 < n && a[i] < pivot; ++s1) {
                ++i;
            }
            for (s2 = 0u; s2 < n && a[j] > pivot; ++s2) {
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
static float cons_median(float *a, size_t n)
{
    return cons_select(a, n, (n - 1u) / 2u);
}

/* Sort idx[0..m-1] by key[0..m-1] ascending (keys move with their indices). Shell sort. */
static void cons_sort(float *key, uint16_t *idx, size_t m)
{
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

/* |residual| of every sample to e, into r; returns 0, or -1 when a residual is not finite. */
static int cons_residuals(const magcal_ellipse_t *e, const magcal_vec2_t *pts, size_t n, float *r)
{
    size_t i;
    for (i = 0u; i < n; ++i) {
        float v = magcal_ellipse_residual(e, pts[i]);
        if (!magcal_isfinite_f(v)) {
            return -1;
        }
        r[i] = fabsf(v);
    }
    return 0;
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
static float cons_threshold(const magcal_consensus_cfg_t *cfg, const magcal_ellipse_t *e, float sigma)
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

magcal_status_t magcal_consensus_run(const magcal_consensus_cfg_t *cfg, const magcal_vec2_t *pts, size_t n,
                                     const uint8_t *cand_mask, void *work, size_t work_len,
                                     uint8_t *inlier_mask, magcal_consensus_result_t *result)
{
    uintptr_t base;
    float *res;
    float *scr;
    uint16_t *order;
    size_t i;
    size_t m = 0u;
    uint32_t rng;
    magcal_ellipse_t best;
    magcal_ellipse_t cur;
    float best_score = INFINITY;
    uint16_t draws = 0u;
    uint16_t valid = 0u;
    uint16_t rounds = 0u;
    float sigma;
    float thr;
    size_t n_in = 0u;
    magcal_status_t st;

    if (cfg == NULL || pts == NULL || work == NULL || inlier_mask == NULL || result == NULL) {
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
    for (i = 0u; i < n; ++i) {
        if (!magcal_isfinite_f(pts[i].x) || !magcal_isfinite_f(pts[i].y)) {
            return MAGCAL_ERR_NONFINITE;
        }
    }

    /* carve the workspace: res[n], scr[n] (4-aligned), order[n] */
    base = ((uintptr_t)work + 3u) & ~(uintptr_t)3u;
    res = (float *)base;
    scr = res + n;
    order = (uint16_t *)(void *)(scr + n);

    /* 1. candidates and their angular order around the coordinate-wise median */
    for (i = 0u; i < n; ++i) {
        if (cand_mask == NULL || cand_mask[i] != 0u) {
            order[m] = (uint16_t)i;
            ++m;
        }
    }
    if (m < MAGCAL_ELLIPSE_MIN_POINTS) {
        return MAGCAL_ERR_TOO_FEW_POINTS;
    }
    {
        float cx;
        float cy;
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
    }

    /* 2. minimal sets spread over the angular order; LMedS score over every sample */
    rng = cfg->seed;
    {
        size_t fifth = m / 5u;
        uint16_t it;
        for (it = 0u; it < cfg->max_iter; ++it) {
            uint16_t idx[5];
            uint32_t off = magcal_prng_next(&rng, (uint32_t)m);
            size_t j;
            magcal_ellipse_t cand;
            float score;
            for (j = 0u; j < 5u; ++j) {
                uint32_t jit = magcal_prng_next(&rng, (uint32_t)fifth);
                idx[j] = order[((size_t)off + j * fifth + (size_t)jit) % m];
            }
            ++draws;
            if (magcal_ellipse_fit_idx(pts, n, idx, 5u, &cand) != MAGCAL_OK) {
                continue;
            }
            if (cons_residuals(&cand, pts, n, res) != 0) {
                continue;
            }
            ++valid;
            score = cons_median(res, n);
            if (score < best_score) {
                best_score = score;
                best = cand;
            }
        }
    }
    if (valid == 0u) {
        /* no minimal set gave an ellipse: start from the least-squares fit of the candidates */
        st = magcal_ellipse_fit_idx(pts, n, order, m, &best);
        if (st != MAGCAL_OK) {
            return st;
        }
        if (cons_residuals(&best, pts, n, res) != 0) {
            return MAGCAL_ERR_NONFINITE;
        }
        for (i = 0u; i < n; ++i) {
            scr[i] = res[i];
        }
        best_score = cons_median(scr, n);
    } else if (cons_residuals(&best, pts, n, res) != 0) {
        return MAGCAL_ERR_NONFINITE;
    }

    /* 3. threshold, inliers over every sample, refit; until the set is stable */
    cur = best;
    sigma = CONS_MAD_TO_SIGMA * best_score;
    thr = cons_threshold(cfg, &cur, sigma);
    {
        /* Working inlier set: order[] (the candidate list is no longer needed) as a 0/1 mask per
         * sample; inlier_mask is written only on success. */
        uint16_t *wm = order;
        uint16_t r;
        for (i = 0u; i < n; ++i) {
            wm[i] = (uint16_t)(res[i] <= thr ? 1u : 0u);
        }
        for (r = 0u; r < cfg->refine_iter; ++r) {
            magcal_ellipse_t next;
            size_t k = 0u;
            size_t changed = 0u;
            float nsig;
            float nthr;
            /* compact the mask into an ascending index list in place, fit, expand it back */
            for (i = 0u; i < n; ++i) {
                if (wm[i] != 0u) {
                    wm[k] = (uint16_t)i;
                    ++k;
                }
            }
            if (k < MAGCAL_ELLIPSE_MIN_POINTS) {
                return MAGCAL_ERR_TOO_FEW_POINTS;
            }
            st = magcal_ellipse_fit_idx(pts, n, wm, k, &next);
            /* restore wm as a 0/1 mask from the list (backwards keeps entries not yet read) */
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
            if (st != MAGCAL_OK) {
                break; /* keep the last good model */
            }
            ++rounds;
            if (cons_residuals(&next, pts, n, res) != 0) {
                break;
            }
            cur = next;
            /* sigma from the current inliers' residuals */
            k = 0u;
            for (i = 0u; i < n; ++i) {
                if (wm[i] != 0u) {
                    scr[k] = res[i];
                    ++k;
                }
            }
            nsig = CONS_MAD_TO_SIGMA * cons_median(scr, k);
            nthr = cons_threshold(cfg, &cur, nsig);
            for (i = 0u; i < n; ++i) {
                uint16_t v = (uint16_t)(res[i] <= nthr ? 1u : 0u);
                if (v != wm[i]) {
                    ++changed;
                    wm[i] = v;
                }
            }
            sigma = nsig;
            thr = nthr;
            if (changed == 0u) {
                break;
            }
        }
        /* final verdict for every sample against `cur` (res holds cur's residuals unless the
         * last refit failed; recompute to be exact) */
        if (cons_residuals(&cur, pts, n, res) != 0) {
            return MAGCAL_ERR_NONFINITE;
        }
        n_in = 0u;
        for (i = 0u; i < n; ++i) {
            if (res[i] <= thr) {
                ++n_in;
            }
        }
        if (n_in < MAGCAL_ELLIPSE_MIN_POINTS) {
            return MAGCAL_ERR_TOO_FEW_POINTS;
        }
    }

    /* success: write outputs */
    {
        uint16_t rescued = 0u;
        uint16_t rejected = 0u;
        for (i = 0u; i < n; ++i) {
            uint8_t in = (uint8_t)(res[i] <= thr ? 1u : 0u);
            uint8_t c = (uint8_t)((cand_mask == NULL || cand_mask[i] != 0u) ? 1u : 0u);
            if (in != 0u && c == 0u) {
                ++rescued;
            }
            if (in == 0u && c != 0u) {
                ++rejected;
            }
            inlier_mask[i] = in;
        }
        result->fit = cur;
        result->sigma = sigma;
        result->threshold = thr;
        result->best_score = best_score;
        result->n_candidates = (uint16_t)m;
        result->n_inliers = (uint16_t)n_in;
        result->n_rescued = rescued;
        result->n_rejected = rejected;
        result->draws = draws;
        result->valid_models = valid;
        result->rounds = rounds;
    }
    return MAGCAL_OK;
}
