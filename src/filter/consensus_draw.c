/*
 * Steps 1 and 2 of the consensus stage (consensus.h): checks, the candidates and their angular
 * order, the quantisation step; minimal 5-point sets drawn and ranked by their LMedS score on a
 * subsample with the RANSAC early end; the start model scored on every sample. Resumable per
 * visit (consensus_internal.h).
 */
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "consensus_internal.h"

/* Samples pos..end-1 of the x (axis 0) or y values of the candidates into scr. */
static void cons_fill_axis(magcal_cons_state_t *S, size_t end)
{
    size_t i;
    for (i = S->pos; i < end; ++i) {
        const magcal_vec2_t *p = &S->pts[S->order[i]];
        S->scr[i] = (S->axis == 0u) ? p->x : p->y;
    }
    S->pos = end;
}

/*
 * 1. Checks, candidates and their angular order around the coordinate-wise median. On the way the
 * smallest positive step between the sorted x or y values of the candidates: the LSB of quantised
 * samples (~0 for continuous ones). A lattice of few distinct values can lie almost exactly on a
 * conic, so the median residual is far below the quantisation noise and a MAD threshold rejected a
 * third of a 5-LSB ring's clean samples; sigma is floored at LSB / sqrt(12), the noise of rounding.
 */
MAGCAL_NOINLINE magcal_status_t magcal_cons_prep(magcal_cons_state_t *S, uint32_t budget,
                                                 uint32_t *used)
{
    const size_t n = S->n;
    const size_t m = S->m;
    size_t end;
    size_t i;
    switch (S->phase) {
    case P_CHECK:
        end = magcal_cons_chunk(budget, used, CONS_W_CHECK, S->pos, n);
        for (i = S->pos; i < end; ++i) {
            if (!magcal_isfinite_f(S->pts[i].x) || !magcal_isfinite_f(S->pts[i].y)) {
                return MAGCAL_ERR_NONFINITE;
            }
        }
        S->pos = end;
        if (end == n) {
            S->pos = 0u;
            S->phase = P_CAND;
        }
        break;
    case P_CAND:
        end = magcal_cons_chunk(budget, used, CONS_W_COPY, S->pos, n);
        for (i = S->pos; i < end; ++i) {
            if (S->cand_mask == NULL || S->cand_mask[i] != 0u) {
                S->order[S->m] = (uint16_t)i;
                ++S->m;
            }
        }
        S->pos = end;
        if (end == n) {
            if (S->m < MAGCAL_ELLIPSE_MIN_POINTS) {
                return MAGCAL_ERR_TOO_FEW_POINTS;
            }
            S->pos = 0u;
            S->axis = 0u;
            S->phase = P_MS_FILL;
        }
        break;
    case P_MS_FILL:
    case P_MED_FILL:
        cons_fill_axis(S, magcal_cons_chunk(budget, used, CONS_W_COPY, S->pos, m));
        if (S->pos == m) {
            if (S->phase == P_MS_FILL) {
                magcal_cons_sort_init(&S->sort, S->scr, NULL, m);
                S->phase = P_MS_SORT;
            } else {
                magcal_cons_sel_init(&S->sel, S->scr, m, (m - 1u) / 2u);
                S->phase = P_MED_SEL;
            }
        }
        break;
    case P_MS_SORT:
        if (magcal_cons_sort_run(&S->sort, budget, used) == 0) {
            return CONS_SPENT;
        }
        S->acc = INFINITY;
        S->pos = 1u;
        S->phase = P_MS_DIFF;
        break;
    case P_MS_DIFF:
        end = magcal_cons_chunk(budget, used, CONS_W_COPY, S->pos, m);
        for (i = S->pos; i < end; ++i) {
            float d = S->scr[i] - S->scr[i - 1u];
            if (d > 0.0f && d < S->acc) {
                S->acc = d;
            }
        }
        S->pos = end;
        if (end == m) {
            float step = magcal_isfinite_f(S->acc) ? S->acc : 0.0f;
            S->pos = 0u;
            if (S->axis == 0u) {
                S->ms0 = step;
                S->axis = 1u;
                S->phase = P_MS_FILL;
            } else {
                S->sig_floor = CONS_INV_SQRT12 * fminf(S->ms0, step);
                S->axis = 0u;
                S->phase = P_MED_FILL;
            }
        }
        break;
    case P_MED_SEL:
        if (magcal_cons_sel_run(&S->sel, budget, used) == 0) {
            return CONS_SPENT;
        }
        S->pos = 0u;
        if (S->axis == 0u) {
            S->cx = S->sel.val;
            S->axis = 1u;
            S->phase = P_MED_FILL;
        } else {
            S->acc = S->sel.val; /* cy */
            S->phase = P_ANGLE;
        }
        break;
    case P_ANGLE:
        end = magcal_cons_chunk(budget, used, CONS_W_ATAN, S->pos, m);
        for (i = S->pos; i < end; ++i) {
            const magcal_vec2_t *p = &S->pts[S->order[i]];
            S->scr[i] = magcal_atan2f(p->y - S->acc, p->x - S->cx);
        }
        S->pos = end;
        if (end == m) {
            magcal_cons_sort_init(&S->sort, S->scr, S->order, m);
            S->phase = P_SORT;
        }
        break;
    default: /* P_SORT */
        if (magcal_cons_sort_run(&S->sort, budget, used) == 0) {
            return CONS_SPENT;
        }
        S->phase = P_DRAW;
        break;
    }
    return (*used < budget) ? MAGCAL_IN_PROGRESS : CONS_SPENT;
}

/*
 * LMedS score of a minimal set over cnt residuals in scr (sample t * stride at scr[t]) except the
 * set's own (which the model passes through exactly: with them, the median of n = 20 samples was
 * the 7th smallest of the 15 real residuals, sigma was 30 % low and 7.6 % of clean samples were
 * rejected). Their entries are set to -1 (below every |residual|) and the selection takes the
 * median of the ranks above them. n <= 5: the plain median.
 */
static void cons_score_init(magcal_cons_state_t *S, const uint16_t set[5], size_t stride,
                            size_t cnt)
{
    size_t c = 0u;
    size_t j;
    if (S->n <= 5u) {
        magcal_cons_sel_init(&S->sel, S->scr, cnt, (cnt - 1u) / 2u);
        return;
    }
    for (j = 0u; j < 5u; ++j) {
        if ((size_t)set[j] % stride == 0u && (size_t)set[j] / stride < cnt) {
            S->scr[(size_t)set[j] / stride] = -1.0f;
            ++c;
        }
    }
    S->sub_c = c;
    magcal_cons_sel_init(&S->sel, S->scr, cnt, c + (cnt - c - 1u) / 2u);
}

/* Draws needed (at most max_iter) so that an all-inlier minimal set is missed with probability
 * <= CONS_MISS_PROB when a fraction w of the samples are inliers: (1 - w^5)^N <= CONS_MISS_PROB.
 * O(max_iter) products, no logf. */
static void cons_need(magcal_cons_state_t *S)
{
    const size_t sub_in = S->sub - S->sub_c; /* subsample minus the minimal set's own points */
    const float w = (float)S->cnt / (float)sub_in;
    const float miss = 1.0f - w * w * w * w * w;
    float prod = 1.0f;
    uint16_t k;
    for (k = 1u; k < S->cfg->max_iter; ++k) {
        prod *= miss;
        if (prod <= CONS_MISS_PROB) {
            break;
        }
    }
    S->need = k;
}

/* One minimal set (one visit): 5 candidates, one per fifth of the angular order from a random
 * rank, and the conic through them; an ellipse is scored next. */
static void cons_draw_one(magcal_cons_state_t *S)
{
    const size_t m = S->m;
    const size_t fifth = m / 5u;
    uint32_t off = magcal_prng_next(&S->rng, (uint32_t)m);
    size_t j;
    for (j = 0u; j < 5u; ++j) {
        uint32_t jit = magcal_prng_next(&S->rng, (uint32_t)fifth);
        S->idx[j] = S->order[((size_t)off + j * fifth + (size_t)jit) % m];
    }
    ++S->draws;
    /* the 5-point exact fit as one visit, its slice in the run state (off the stack) */
    if (magcal_ellipse_fit_idx_begin(&S->fit, S->pts, S->n, S->idx, 5u, &S->cand) == MAGCAL_OK &&
        magcal_ellipse_fit_step(&S->fit, UINT32_MAX) == MAGCAL_OK) {
        ++S->valid;
        S->pos = 0u;
        S->phase = P_SCORE_RES;
    }
}

/* 2. Minimal sets spread over the angular order (one per visit), ranked by their LMedS score on
 * the subsample (cons_score_init). */
MAGCAL_NOINLINE magcal_status_t magcal_cons_draw(magcal_cons_state_t *S, uint32_t budget,
                                                 uint32_t *used)
{
    const size_t n = S->n;
    switch (S->phase) {
    case P_DRAW:
        if (S->draws >= S->cfg->max_iter ||
            (S->n > CONS_SUB_TARGET && S->draws >= CONS_MIN_DRAWS && S->draws >= S->need)) {
            S->phase = P_START;
            break;
        }
        if (magcal_cons_pay(budget, used, CONS_W_DRAW) == 0) {
            return CONS_SPENT;
        }
        cons_draw_one(S);
        break;
    case P_SCORE_RES: {
        /* |residual| of the subsample into scr[0..sub-1] (as cons_residuals) */
        const size_t end = magcal_cons_chunk(budget, used, CONS_W_RES, S->pos, S->sub);
        size_t t;
        for (t = S->pos; t < end; ++t) {
            float v = magcal_ellipse_residual(&S->cand, S->pts[t * S->stride]);
            S->scr[t] = magcal_isfinite_f(v) ? fabsf(v) : INFINITY;
        }
        S->pos = end;
        if (end == S->sub) {
            cons_score_init(S, S->idx, S->stride, S->sub);
            S->phase = P_SCORE_SEL;
        }
        break;
    }
    case P_SCORE_SEL:
        if (magcal_cons_sel_run(&S->sel, budget, used) == 0) {
            return CONS_SPENT;
        }
        S->phase = P_DRAW;
        if (S->sel.val < S->best_score) {
            size_t j;
            S->best_score = S->sel.val;
            S->best = S->cand;
            for (j = 0u; j < 5u; ++j) {
                S->best_idx[j] = S->idx[j];
            }
            if (n > CONS_SUB_TARGET) {
                S->pos = 0u;
                S->cnt = 0u;
                S->phase = P_SCORE_CNT;
            }
        }
        break;
    default: { /* P_SCORE_CNT: scr holds the subsample's residuals (reordered by the selection) */
        const size_t dof = S->sub - MAGCAL_ELLIPSE_MIN_POINTS;
        const float thr = CONS_INLIER_SIGMAS * CONS_MAD_TO_SIGMA * S->best_score *
                          (1.0f + 5.0f / (float)dof);
        const size_t end = magcal_cons_chunk(budget, used, CONS_W_COPY, S->pos, S->sub);
        size_t t;
        for (t = S->pos; t < end; ++t) {
            if (S->scr[t] >= 0.0f && S->scr[t] <= thr) {
                ++S->cnt;
            }
        }
        S->pos = end;
        if (end == S->sub) {
            if (magcal_cons_pay(budget, used, CONS_W_FIX) == 0) {
                return CONS_SPENT;
            }
            cons_need(S);
            S->phase = P_DRAW;
        }
        break;
    }
    }
    return (*used < budget) ? MAGCAL_IN_PROGRESS : CONS_SPENT;
}

/* Start model: the best minimal set, scored again on every sample, or (none valid) the
 * least-squares fit of the candidates (its score the plain median); res gets its residuals. */
MAGCAL_NOINLINE magcal_status_t magcal_cons_start(magcal_cons_state_t *S, uint32_t budget,
                                                  uint32_t *used)
{
    magcal_status_t st;
    switch (S->phase) {
    case P_START:
        if (magcal_cons_pay(budget, used, CONS_W_FIX) == 0) {
            return CONS_SPENT;
        }
        S->pos = 0u;
        if (S->valid == 0u) {
            st = magcal_ellipse_fit_idx_begin(&S->fit, S->pts, S->n, S->order, S->m, &S->best);
            if (st != MAGCAL_OK) {
                return st;
            }
            S->phase = P_START_FIT;
        } else {
            S->phase = P_START_RES;
        }
        break;
    case P_START_FIT:
        st = magcal_cons_fit(S, budget, used);
        if (st != MAGCAL_OK) {
            return st;
        }
        S->phase = P_START_RES;
        break;
    case P_START_RES: {
        size_t p0 = S->pos;
        int done = magcal_cons_res_loop(S, &S->best, budget, used);
        size_t i;
        for (i = p0; i < S->pos; ++i) {
            S->scr[i] = S->res[i];
        }
        if (done != 0) {
            if (S->valid == 0u) {
                magcal_cons_sel_init(&S->sel, S->scr, S->n, (S->n - 1u) / 2u);
            } else {
                cons_score_init(S, S->best_idx, 1u, S->n);
            }
            S->phase = P_START_SEL;
        }
        break;
    }
    default: /* P_START_SEL */
        if (magcal_cons_sel_run(&S->sel, budget, used) == 0) {
            return CONS_SPENT;
        }
        S->best_score = S->sel.val;
        S->phase = P_RINIT;
        break;
    }
    return (*used < budget) ? MAGCAL_IN_PROGRESS : CONS_SPENT;
}
