/*
 * Step 3 of the consensus stage (consensus.h): the MAD-scaled threshold, the threshold/refit
 * rounds on the working mask, and the final verdict of every sample against the final model
 * with the outputs. Resumable per visit (consensus_internal.h).
 */
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "consensus_internal.h"

static float cons_mean_radius(const magcal_ellipse_t *e)
{
    return sqrtf(e->semi_minor * e->semi_major);
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

/* Working-mask entry i (0/1) of step 3; the first five inliers are kept in idx (a refit of
 * exactly five points is the 5-point exact path, as magcal_ellipse_fit_idx() takes it). */
static void cons_mask_set(magcal_cons_state_t *S, size_t i, uint8_t v)
{
    ((uint8_t *)S->order)[i] = v;
    if (v != 0u) {
        if (S->k_in < 5u) {
            S->idx[S->k_in] = (uint16_t)i;
        }
        ++S->k_in;
    }
}

/* New scale and threshold from the gathered residuals of the current inliers (their median in
 * S->sel.val, their sum of squares in S->acc). */
static MAGCAL_NOINLINE void cons_rescale(magcal_cons_state_t *S)
{
    const size_t k = S->k_in;
    float nsig = CONS_MAD_TO_SIGMA * S->sel.val;
    /* residuals of a 5-parameter least-squares fit of its own k inliers are smaller than the
     * noise by sqrt((k - 5) / k): undo it so small sets are not trimmed (k = 20: 13 %) */
    if (k > (size_t)2u * MAGCAL_ELLIPSE_MIN_POINTS) {
        const size_t k_dof = k - MAGCAL_ELLIPSE_MIN_POINTS;
        float dof = (float)k / (float)k_dof;
        /* the MAD has 37 % efficiency: at k = 20 it fell to 0.6 sigma often enough to reject a
         * clean sample in 18 % of the runs. The RMS of the current inliers (already cut at the
         * threshold, so outliers beyond it cannot inflate it) is the efficient scale; the larger
         * of the two is used. */
        nsig = fmaxf(nsig * sqrtf(dof), sqrtf(S->acc / (float)k * dof));
    }
    nsig = fmaxf(nsig, S->sig_floor);
    if (k > (size_t)2u * MAGCAL_ELLIPSE_MIN_POINTS) {
        /* sigma is itself estimated from k - 5 residuals: the threshold is the Student-t quantile
         * of k_sigma (Cornish-Fisher, first order: x (1 + (z^2 + 1) / (4 dof)); 1.24 at k = 20,
         * 1.005 at k = 600) */
        const size_t k_dof = k - MAGCAL_ELLIPSE_MIN_POINTS;
        const float z = S->cfg->k_sigma;
        S->thr = cons_threshold(S->cfg, &S->cur,
                                nsig * (1.0f + (z * z + 1.0f) / (4.0f * (float)k_dof)));
    } else {
        S->thr = cons_threshold(S->cfg, &S->cur, nsig);
    }
    S->sigma = nsig;
}

/* Start of step 3: current model = best, its LMedS scale with Rousseeuw & Leroy's finite-sample
 * factor 1 + 5 / (n - p) (at n = 20 the minimal set with the smallest median fits half of the
 * samples better than the noise, and the plain 1.4826 * median started the refits on a trimmed
 * subset they never left), its threshold. */
static void cons_refine_init(magcal_cons_state_t *S)
{
    S->cur = S->best;
    S->sigma = CONS_MAD_TO_SIGMA * S->best_score;
    if (S->n > MAGCAL_ELLIPSE_MIN_POINTS) {
        const size_t n_dof = S->n - MAGCAL_ELLIPSE_MIN_POINTS;
        S->sigma *= 1.0f + 5.0f / (float)n_dof;
    }
    S->sigma = fmaxf(S->sigma, S->sig_floor);
    S->thr = cons_threshold(S->cfg, &S->cur, S->sigma);
    S->pos = 0u;
    S->k_in = 0u;
}

/* 3. Threshold, inliers over every sample, refit; until the set is stable or refine_iter rounds
 * were done. The working mask (bytes in order[], the candidate list is no longer needed) is
 * fitted directly: the same points in the same order as the one-shot index list. */
MAGCAL_NOINLINE magcal_status_t magcal_cons_refine(magcal_cons_state_t *S, uint32_t budget,
                                                   uint32_t *used)
{
    uint8_t *wm = (uint8_t *)S->order;
    const size_t n = S->n;
    size_t end;
    size_t i;
    magcal_status_t st;
    switch (S->phase) {
    case P_RINIT:
        if (magcal_cons_pay(budget, used, CONS_W_FIX) == 0) {
            return CONS_SPENT;
        }
        cons_refine_init(S);
        S->phase = P_RINIT_MASK;
        break;
    case P_RINIT_MASK:
        end = magcal_cons_chunk(budget, used, CONS_W_COPY, S->pos, n);
        for (i = S->pos; i < end; ++i) {
            cons_mask_set(S, i, (uint8_t)(S->res[i] <= S->thr ? 1u : 0u));
        }
        S->pos = end;
        if (end == n) {
            S->round = 0u;
            S->stop = 0u;
            S->phase = P_ROUND;
            if (S->max_out != 0u && n - S->k_in > (size_t)S->max_out) {
                return MAGCAL_ERR_TOO_MANY_OUTLIERS; /* the caller's early end */
            }
        }
        break;
    case P_ROUND:
        if (magcal_cons_pay(budget, used, CONS_W_FIX) == 0) {
            return CONS_SPENT;
        }
        S->pos = 0u;
        if (!(S->round < S->cfg->refine_iter && S->stop == 0u)) {
            S->n_in = 0u;
            S->phase = P_FINAL_RES;
            break;
        }
        if (S->k_in < MAGCAL_ELLIPSE_MIN_POINTS) {
            return MAGCAL_ERR_TOO_FEW_POINTS;
        }
        st = (S->k_in == MAGCAL_ELLIPSE_MIN_POINTS)
                 ? magcal_ellipse_fit_idx_begin(&S->fit, S->pts, n, S->idx, 5u, &S->cand)
                 : magcal_ellipse_fit_begin(&S->fit, S->pts, n, wm, &S->cand);
        if (st != MAGCAL_OK) {
            return st;
        }
        S->phase = P_REFIT;
        break;
    case P_REFIT:
        st = magcal_cons_fit(S, budget, used);
        if (st == CONS_SPENT) {
            return st;
        }
        if (st != MAGCAL_OK) {
            S->stop = 1u; /* keep the last good model */
            ++S->round;
            S->phase = P_ROUND;
        } else {
            ++S->rounds;
            S->phase = P_REFIT_RES;
        }
        break;
    case P_REFIT_RES:
        if (magcal_cons_res_loop(S, &S->cand, budget, used) != 0) {
            S->cur = S->cand;
            S->pos = 0u;
            S->k_in = 0u;
            S->acc = 0.0f;
            S->phase = P_RT_GATHER;
        }
        break;
    case P_RT_GATHER:
        end = magcal_cons_chunk(budget, used, CONS_W_COPY, S->pos, n);
        for (i = S->pos; i < end; ++i) {
            if (wm[i] != 0u) {
                S->scr[S->k_in] = S->res[i];
                S->acc += S->res[i] * S->res[i];
                ++S->k_in;
            }
        }
        S->pos = end;
        if (end == n) {
            magcal_cons_sel_init(&S->sel, S->scr, S->k_in, (S->k_in - 1u) / 2u);
            S->phase = P_RT_SEL;
        }
        break;
    case P_RT_SEL:
        if (magcal_cons_sel_run(&S->sel, budget, used) == 0) {
            return CONS_SPENT;
        }
        cons_rescale(S);
        S->pos = 0u;
        S->k_in = 0u;
        S->changed = 0u;
        S->phase = P_RT_MASK;
        break;
    default: /* P_RT_MASK */
        end = magcal_cons_chunk(budget, used, CONS_W_COPY, S->pos, n);
        for (i = S->pos; i < end; ++i) {
            uint8_t v = (uint8_t)(S->res[i] <= S->thr ? 1u : 0u);
            if (v != wm[i]) {
                ++S->changed;
            }
            cons_mask_set(S, i, v);
        }
        S->pos = end;
        if (end == n) {
            if (S->changed == 0u) {
                S->stop = 1u;
            }
            ++S->round;
            S->phase = P_ROUND;
            if (S->max_out != 0u && n - S->k_in > (size_t)S->max_out) {
                return MAGCAL_ERR_TOO_MANY_OUTLIERS; /* the caller's early end */
            }
        }
        break;
    }
    return (*used < budget) ? MAGCAL_IN_PROGRESS : CONS_SPENT;
}

/* Final verdict for every sample against cur (res is recomputed: it holds cur's residuals unless
 * the last refit failed), then the outputs. */
MAGCAL_NOINLINE magcal_status_t magcal_cons_finish(magcal_cons_state_t *S, uint32_t budget,
                                                   uint32_t *used)
{
    const size_t n = S->n;
    size_t end;
    size_t i;
    if (S->phase == P_FINAL_RES) {
        size_t p0 = S->pos;
        int done = magcal_cons_res_loop(S, &S->cur, budget, used);
        for (i = p0; i < S->pos; ++i) {
            if (S->res[i] <= S->thr) {
                ++S->n_in;
            }
        }
        if (done != 0) {
            if (S->n_in < MAGCAL_ELLIPSE_MIN_POINTS) {
                return MAGCAL_ERR_TOO_FEW_POINTS;
            }
            S->pos = 0u;
            S->rescued = 0u;
            S->rejected = 0u;
            S->phase = P_OUT;
        }
        return (*used < budget) ? MAGCAL_IN_PROGRESS : CONS_SPENT;
    }
    end = magcal_cons_chunk(budget, used, CONS_W_COPY, S->pos, n);
    for (i = S->pos; i < end; ++i) {
        uint8_t in = (uint8_t)(S->res[i] <= S->thr ? 1u : 0u);
        uint8_t c = (uint8_t)((S->cand_mask == NULL || S->cand_mask[i] != 0u) ? 1u : 0u);
        if (in != 0u && c == 0u) {
            ++S->rescued;
        }
        if (in == 0u && c != 0u) {
            ++S->rejected;
        }
        S->inlier_mask[i] = in;
    }
    S->pos = end;
    if (end < n || magcal_cons_pay(budget, used, CONS_W_FIX) == 0) {
        return CONS_SPENT;
    }
    S->result->fit = S->cur;
    S->result->sigma = S->sigma;
    S->result->threshold = S->thr;
    S->result->best_score = S->best_score;
    S->result->n_candidates = (uint16_t)S->m;
    S->result->n_inliers = (uint16_t)S->n_in;
    S->result->n_rescued = S->rescued;
    S->result->n_rejected = S->rejected;
    S->result->draws = S->draws;
    S->result->valid_models = S->valid;
    S->result->rounds = S->rounds;
    return MAGCAL_OK;
}
