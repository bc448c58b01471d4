/*
 * Consensus (model-residual) outlier stage: RANSAC/LMedS over 5-point minimal ellipse sets,
 * MAD-scaled residual threshold, refit. See include/magcal/consensus.h for the algorithm.
 *
 * Time-sliced (the slice contract of docs/performance.md): the run is a sequence of phases kept in
 * the run state (in the workspace); every loop over the samples or candidates keeps its position
 * there and charges a weight per visit (CONS_W_*), the selections (Hoare quickselect) and sorts
 * (shell sort) are resumable state machines, the fits are ellipse fit slices. A step stops before
 * the visit that would pass its budget. magcal_consensus_run() is begin + step(UINT32_MAX): the
 * same code path, so the sliced run gives its outputs bit for bit.
 *
 * This file: the cfg check and the slicing driver (begin, step, run). The phases are
 * consensus_draw.c and consensus_refine.c, their primitives consensus_prims.c, the run state
 * consensus_internal.h.
 */
#include "magcal/consensus.h"

#include <math.h>
#include <string.h>

#include "consensus_internal.h"
#include "magcal_internal.h"

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

#define CONS_PH_RUN 1u
#define CONS_PH_DONE 2u

magcal_status_t magcal_consensus_begin(magcal_consensus_slice_t *s, const magcal_consensus_cfg_t *cfg,
                                       const magcal_vec2_t *pts, size_t n, const uint8_t *cand,
                                       void *work, size_t work_len, uint8_t *inlier,
                                       magcal_consensus_result_t *res)
{
    magcal_cons_state_t *S;
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
    /* carve the workspace (aligned for pointers): the run state, res[n], scr[n], order[n] */
    S = (magcal_cons_state_t *)(void *)((uint8_t *)work +
                                 ((sizeof(void *) - magcal_misalign(work, sizeof(void *))) %
                                  sizeof(void *)));
    /* the models' padding is copied into the result: zero, not whatever the workspace held */
    (void)memset(S, 0, sizeof *S);
    S->cfg = cfg;
    S->pts = pts;
    S->cand_mask = cand;
    S->inlier_mask = inlier;
    S->result = res;
    S->n = n;
    S->m = 0u;
    S->res = (float *)(void *)(S + 1);
    S->scr = S->res + n;
    S->order = (uint16_t *)(void *)(S->scr + n);
    S->pos = 0u;
    S->stride = (n + CONS_SUB_TARGET - 1u) / CONS_SUB_TARGET;
    S->sub = (n + S->stride - 1u) / S->stride;
    S->best_score = INFINITY;
    S->need = UINT16_MAX;
    S->sigma = 0.0f;
    S->sig_floor = 0.0f;
    S->thr = 0.0f;
    S->n_in = 0u;
    S->rng = cfg->seed;
    S->draws = 0u;
    S->valid = 0u;
    S->rounds = 0u;
    S->phase = P_CHECK;
    s->state_ = S;
    s->used_ = 0u;
    s->phase_ = CONS_PH_RUN;
    s->status_ = (int8_t)MAGCAL_IN_PROGRESS;
    return MAGCAL_OK;
}

magcal_status_t magcal_consensus_limit_rejects(magcal_consensus_slice_t *s, size_t max_out)
{
    magcal_cons_state_t *S;
    if (s == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (s->phase_ != CONS_PH_RUN || s->state_ == NULL || max_out < 1u ||
        max_out > (size_t)UINT16_MAX) {
        return MAGCAL_ERR_ARG;
    }
    S = (magcal_cons_state_t *)s->state_;
    S->max_out = (uint16_t)max_out;
    return MAGCAL_OK;
}

magcal_status_t magcal_consensus_step(magcal_consensus_slice_t *s, uint32_t budget)
{
    magcal_cons_state_t *S;
    uint32_t used = 0u;
    magcal_status_t st = MAGCAL_IN_PROGRESS;

    if (s == NULL) {
        return MAGCAL_ERR_NULL;
    }
    s->used_ = 0u;
    if (s->phase_ == CONS_PH_DONE) {
        return (magcal_status_t)s->status_;
    }
    if (s->phase_ != CONS_PH_RUN || s->state_ == NULL) {
        return MAGCAL_ERR_ARG;
    }
    S = (magcal_cons_state_t *)s->state_;
    while (st == MAGCAL_IN_PROGRESS) {
        if (S->phase < P_DRAW) {
            st = magcal_cons_prep(S, budget, &used);
        } else if (S->phase < P_START) {
            st = magcal_cons_draw(S, budget, &used);
        } else if (S->phase < P_RINIT) {
            st = magcal_cons_start(S, budget, &used);
        } else if (S->phase < P_FINAL_RES) {
            st = magcal_cons_refine(S, budget, &used);
        } else {
            st = magcal_cons_finish(S, budget, &used);
        }
    }
    s->used_ = used;
    if (st == CONS_SPENT) {
        return MAGCAL_IN_PROGRESS;
    }
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

#ifdef MAGCAL_BENCH_TRACE
/* Bench-only (tools/bench/m4f_image cont_trace.elf, never in a shipped build): the run's
 * internal phase for the per-step trace of the continuous calibrator; 0xFF when none. */
unsigned magcal_bench_cons_phase(const magcal_consensus_slice_t *s);
unsigned magcal_bench_cons_phase(const magcal_consensus_slice_t *s)
{
    return (s->state_ != NULL && s->phase_ != (uint8_t)CONS_PH_DONE) ? (unsigned)((const magcal_cons_state_t *)s->state_)->phase
                                                                     : 0xFFu;
}
#endif
