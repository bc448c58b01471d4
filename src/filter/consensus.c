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
 */
#include "magcal/consensus.h"

#include <math.h>
#include <string.h>

#include "magcal_internal.h"

/* 1 / Phi^-1(3/4): MAD of a normal distribution -> sigma. */
#define CONS_MAD_TO_SIGMA 1.4826f
/* 1 / sqrt(12): standard deviation of a uniform rounding error, in LSB */
#define CONS_INV_SQRT12 0.28867513f

/* Estimated Cortex-M4F instructions per visit, measured on QEMU mps2-an386 -icount shift=0
 * (arm-none-eabi-gcc -Os; real/charged per step of each phase at n = 288 and 1024, with ~10 %
 * margin; docs/performance.md). Over-charging only makes steps smaller. */
#define CONS_W_CHECK 55u  /* finiteness of one sample */
#define CONS_W_COPY 48u   /* one element of a candidate / fill / gather / mask / output loop */
#define CONS_W_SORT 64u   /* one shell-sort move or placement */
#define CONS_W_SEL 32u    /* one quickselect scan step, swap or partition decision */
#define CONS_W_ATAN 256u  /* atan2f of one candidate's direction */
#define CONS_W_RES 224u   /* |radial residual| of one sample */
#define CONS_W_DRAW 3800u /* one minimal set: 6 PRNG draws and the 5-point exact fit */
#define CONS_W_FIX 640u   /* an O(1) phase change (scale, threshold, model copy, result) */
/* a fit slice is stepped only when its largest visit (the normal equations) fits the budget */
#define CONS_W_FIT 3000u

/* Minimal sets are ranked by the LMedS score on a fixed subsample of at most about this many
 * samples (every stride-th sample; all of them up to this count, where the ranking is the full
 * one); only the winner is scored on every sample (issue 14: the 48 full scorings were 87 % of a
 * run at n = 288). */
#define CONS_SUB_TARGET 64u

/* Early end of the draws (issue 14; only above CONS_SUB_TARGET samples, so small sets draw as
 * before): after at least CONS_MIN_DRAWS draws, stop once (1 - w^5)^draws <= CONS_MISS_PROB,
 * w = the best model's inlier fraction on the subsample (|r| <= CONS_INLIER_SIGMAS x its
 * LMedS-scaled sigma, the minimal set's own five left out): the standard RANSAC bound. */
#define CONS_MIN_DRAWS 16u
#define CONS_MISS_PROB 0.001f
#define CONS_INLIER_SIGMAS 2.5f

/* A phase's return: go on with the next phase (MAGCAL_IN_PROGRESS), stop this step (CONS_SPENT)
 * or the run's final status. */
#define CONS_SPENT ((magcal_status_t)2)

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


/* Resumable Hoare quickselect of the k-th smallest of a[0..n-1] (a is reordered): the loop of
 * the one-shot selection, each scan step, swap and partition decision one visit. */
typedef struct {
    float *a;
    size_t n;
    size_t k;
    size_t lo;
    size_t hi;
    size_t i;
    size_t j;
    size_t guard;
    size_t inner;
    size_t s;
    float pivot;
    float val; /* the result once done */
    uint8_t ph;
} cons_sel_t;

/* Resumable shell sort (Ciura's gaps, extended) of key[0..m-1] ascending, idx (may be NULL)
 * moving with the keys. */
typedef struct {
    float *key;
    uint16_t *idx;
    size_t m;
    size_t g;
    size_t i;
    size_t j;
    float kv;
    uint16_t iv;
    uint8_t moving;
} cons_sort_t;

/* State of one run, kept in the workspace (off the stack: the fits are on the deepest stack path
 * of the 2-D pipeline). */
typedef struct {
    magcal_ellipse_t best; /* best minimal model (LMedS) */
    magcal_ellipse_t cur;  /* current refit */
    magcal_ellipse_t cand; /* candidate minimal model, then the next refit */
    magcal_ellipse_fit_slice_t fit;
    cons_sel_t sel;
    cons_sort_t sort;
    const magcal_consensus_cfg_t *cfg;
    const magcal_vec2_t *pts;
    const uint8_t *cand_mask;
    uint8_t *inlier_mask;
    magcal_consensus_result_t *result;
    size_t n;
    size_t m; /* candidates */
    float *res;
    float *scr;
    uint16_t *order; /* candidates in angular order; in step 3 the working inlier mask (bytes) */
    size_t pos;      /* position of the current loop */
    size_t k_in;     /* ones in the working inlier mask; gathered residuals */
    size_t changed;  /* mask entries changed by a rethreshold */
    size_t n_in;
    size_t stride; /* subsample of the scores: samples 0, stride, 2 stride, ... (sub of them) */
    size_t sub;
    size_t sub_c;  /* subsample entries of the minimal set (set to -1) */
    size_t cnt;    /* inliers of a new best on the subsample */
    float best_score; /* LMedS score of best: on the subsample while drawing, then on every sample */
    float sigma;
    float sig_floor; /* quantisation noise of the samples: LSB / sqrt(12) */
    float thr;
    float acc;       /* smallest step (cons_min_step), sum of squares (rethreshold) */
    float ms0;       /* smallest step of the x values */
    float cx;        /* coordinate-wise median of the candidates */
    uint32_t rng;
    uint16_t draws;
    uint16_t valid;
    uint16_t rounds;
    uint16_t round;  /* refine round r */
    uint16_t rescued;
    uint16_t rejected;
    uint16_t idx[5]; /* minimal set; in step 3 the inliers when there are exactly 5 */
    uint16_t best_idx[5]; /* minimal set of best */
    uint16_t need;        /* draws needed for the best's inlier fraction (early end) */
    uint16_t max_out;     /* magcal_consensus_limit_rejects(): 0 = no limit */
    uint8_t phase;
    uint8_t axis;
    uint8_t stop;
} cons_state_t;

/* cppcheck-suppress misra-c2012-2.3 ; deviation D4: a static assert is an unused typedef */
MAGCAL_STATIC_ASSERT(sizeof(cons_state_t) + sizeof(void *) - 1u <= MAGCAL_CONSENSUS_STATE_LEN_,
                     consensus_state_fits_workspace);

/* Phases of a run, in order. */
/* cppcheck-suppress misra-c2012-5.7 ; deviation D14 (false positive): the enum has no tag; misra.py gives every untagged enum the same name, so two units' untagged enums read as one tag declared twice */
/* cppcheck-suppress misra-c2012-2.4 ; deviation D14 (false positive): no tag, so no unused tag; the constants are the phases of cons_state_t.phase */
enum {
    P_CHECK = 0,  /* every sample finite */
    P_CAND,       /* candidate list */
    P_MS_FILL,    /* smallest positive step of x (axis 0) then y: fill, sort, differences */
    P_MS_SORT,
    P_MS_DIFF,
    P_MED_FILL,   /* coordinate-wise median of the candidates: fill, select (x, then y) */
    P_MED_SEL,
    P_ANGLE,      /* angle of each candidate around the median, then the angular sort */
    P_SORT,
    P_DRAW,       /* one minimal set per visit */
    P_SCORE_RES,  /* its residuals, LMedS score */
    P_SCORE_SEL,
    P_SCORE_CNT,  /* a new best: its inlier fraction -> draws needed */
    P_START,      /* start model: best minimal set, or the LS fit of the candidates */
    P_START_FIT,
    P_START_RES,
    P_START_SEL,
    P_RINIT,      /* step 3: start scale and threshold, working mask */
    P_RINIT_MASK,
    P_ROUND,      /* one threshold/refit round: refit, residuals, gather, scale, new mask */
    P_REFIT,
    P_REFIT_RES,
    P_RT_GATHER,
    P_RT_SEL,
    P_RT_MASK,
    P_FINAL_RES,  /* verdict of every sample against the final model, outputs */
    P_OUT
};

/* Visits of weight w the rest of the budget pays for (at most left); at least one on a step's
 * first visit (used == 0). 0: stop this step. */
static size_t cons_visits(uint32_t budget, uint32_t used, uint32_t w, size_t left)
{
    uint32_t v = (used < budget) ? (budget - used) / w : 0u;
    if (v == 0u && used == 0u) {
        v = 1u;
    }
    return ((size_t)v < left) ? (size_t)v : left;
}

/* Charge a loop chunk: the end of the visits this step pays for from pos over [pos, len). When
 * not one more visit is paid for, the budget counts as spent (the phase returns CONS_SPENT). */
static size_t cons_chunk(uint32_t budget, uint32_t *used, uint32_t w, size_t pos, size_t len)
{
    size_t v = cons_visits(budget, *used, w, len - pos);
    if (v == 0u && pos < len) {
        *used = (*used > budget) ? *used : budget;
    }
    *used += (uint32_t)v * w;
    return pos + v;
}

/* Charge one O(1) visit; 0 when the budget is spent. */
static int cons_pay(uint32_t budget, uint32_t *used, uint32_t w)
{
    if (cons_visits(budget, *used, w, 1u) == 0u) {
        return 0;
    }
    *used += w;
    return 1;
}

static void cons_sel_init(cons_sel_t *q, float *a, size_t n, size_t k)
{
    q->a = a;
    q->n = n;
    q->k = k;
    q->lo = 0u;
    q->hi = n - 1u;
    q->guard = 0u;
    q->ph = 0u;
}

/* Run the selection within the budget; 1 when done (q->val). The phases are the one-shot loop
 * nest: 0 outer test, 1 inner test, 2 scan i up, 3 scan j down, 4 swap, 5 partition decision.
 * Each scan step and each swap or partition round is one visit; the indices live in locals
 * during the call (the scans are as tight as the one-shot loop's). */
static int cons_sel_run(cons_sel_t *q, uint32_t budget, uint32_t *used)
{
    float *a = q->a;
    const size_t n = q->n;
    const size_t k = q->k;
    float pivot = q->pivot;
    size_t lo = q->lo;
    size_t hi = q->hi;
    size_t i = q->i;
    size_t j = q->j;
    size_t s = q->s;
    size_t guard = q->guard;
    size_t inner = q->inner;
    const size_t start = cons_visits(budget, *used, CONS_W_SEL, (size_t)-1);
    size_t left = start;
    uint8_t ph = q->ph;
    int done = 0;
    while (left > 0u && done == 0) {
        if (ph == 2u) { /* the scans first: most visits are theirs */
            while (left > 0u && s < n && a[i] < pivot) {
                ++i;
                ++s;
                --left;
            }
            if (left > 0u) {
                s = 0u;
                ph = 3u;
            }
        } else if (ph == 3u) {
            while (left > 0u && s < n && a[j] > pivot) {
                --j;
                ++s;
                --left;
            }
            if (left > 0u) {
                ph = 4u;
            }
        } else if (ph == 4u) {
            --left;
            ph = 1u;
            if (i <= j) {
                float t = a[i];
                a[i] = a[j];
                a[j] = t;
                ++i;
                if (j == 0u) {
                    ph = 5u;
                    continue;
                }
                --j;
            }
            ++inner;
        } else if (ph == 1u) {
            if (inner <= n && i <= j) {
                s = 0u;
                ph = 2u;
            } else {
                ph = 5u;
            }
        } else if (ph == 0u) {
            --left;
            if (!(guard < n + 1u && lo < hi)) {
                done = 1;
            } else {
                pivot = a[lo + (hi - lo) / 2u];
                i = lo;
                j = hi;
                inner = 0u;
                ph = 1u;
            }
        } else {
            --left;
            if (k <= j) {
                hi = j;
            } else if (k >= i) {
                lo = i;
            } else {
                done = 1;
                continue;
            }
            ++guard;
            ph = 0u;
        }
    }
    if (done != 0) {
        q->val = a[k];
    }
    q->pivot = pivot;
    q->lo = lo;
    q->hi = hi;
    q->i = i;
    q->j = j;
    q->s = s;
    q->guard = guard;
    q->inner = inner;
    q->ph = ph;
    *used += (uint32_t)(start - left) * CONS_W_SEL;
    return done;
}

static void sort_init(cons_sort_t *q, float *key, uint16_t *idx, size_t m)
{
    q->key = key;
    q->idx = idx;
    q->m = m;
    q->g = 0u;
    q->i = 0u;
    q->moving = 0u;
}

/* Run the shell sort within the budget; 1 when done. One visit per move or placement; the
 * positions live in locals during the call. */
static int sort_run(cons_sort_t *q, uint32_t budget, uint32_t *used)
{
    static const uint16_t gaps[] = {701u, 301u, 132u, 57u, 23u, 10u, 4u, 1u};
    float *key = q->key;
    uint16_t *idx = q->idx;
    const size_t start = cons_visits(budget, *used, CONS_W_SORT, (size_t)-1);
    size_t left = start;
    size_t i = q->i;
    size_t j = q->j;
    float kv = q->kv;
    uint16_t iv = q->iv;
    int done = 0;
    while (left > 0u) {
        size_t gap;
        if (q->g >= sizeof gaps / sizeof gaps[0]) {
            done = 1;
            break;
        }
        gap = gaps[q->g];
        if (q->moving == 0u) {
            i = (i < gap) ? gap : i;
            if (i >= q->m) {
                ++q->g;
                i = 0u;
                continue;
            }
            kv = key[i];
            iv = (idx != NULL) ? idx[i] : 0u;
            j = i;
            q->moving = 1u;
        }
        while (left > 0u && j >= gap && key[j - gap] > kv) {
            key[j] = key[j - gap];
            if (idx != NULL) {
                idx[j] = idx[j - gap];
            }
            j -= gap;
            --left;
        }
        if (left > 0u) {
            key[j] = kv;
            if (idx != NULL) {
                idx[j] = iv;
            }
            q->moving = 0u;
            ++i;
            --left;
        }
    }
    q->i = i;
    q->j = j;
    q->kv = kv;
    q->iv = iv;
    *used += (uint32_t)(start - left) * CONS_W_SORT;
    return done;
}

/* |residual| of samples pos..end-1. The samples are finite (checked first) and the model comes
 * from a successful fit, so a non-finite residual can only be an overflow of a sample
 * astronomically far from the model (|p - c| above ~1e19): it is stored as +Inf, i.e. always an
 * outlier. Returning an error instead made one such sample veto every minimal set. */
static void cons_residuals(const magcal_ellipse_t *e, const magcal_vec2_t *pts, size_t pos,
                           size_t end, float *r)
{
    size_t i;
    for (i = pos; i < end; ++i) {
        float v = magcal_ellipse_residual(e, pts[i]);
        r[i] = magcal_isfinite_f(v) ? fabsf(v) : INFINITY;
    }
}

/* The residual loop of a phase over every sample: 1 when the last chunk is done. */
static int cons_res_loop(cons_state_t *S, const magcal_ellipse_t *e, uint32_t budget,
                         uint32_t *used)
{
    size_t end = cons_chunk(budget, used, CONS_W_RES, S->pos, S->n);
    cons_residuals(e, S->pts, S->pos, end, S->res);
    S->pos = end;
    return end == S->n;
}

/* One chunk of a fit slice; CONS_SPENT while it runs, then its status. */
static magcal_status_t cons_fit(cons_state_t *S, uint32_t budget, uint32_t *used)
{
    magcal_status_t st;
    if (*used != 0u && (*used >= budget || budget - *used < CONS_W_FIT)) {
        return CONS_SPENT;
    }
    st = magcal_ellipse_fit_step(&S->fit, budget - *used);
    *used += S->fit.used_;
    return (st == MAGCAL_IN_PROGRESS) ? CONS_SPENT : st;
}

/* Samples pos..end-1 of the x (axis 0) or y values of the candidates into scr. */
static void cons_fill_axis(cons_state_t *S, size_t end)
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
static MAGCAL_NOINLINE magcal_status_t cons_prep(cons_state_t *S, uint32_t budget, uint32_t *used)
{
    const size_t n = S->n;
    const size_t m = S->m;
    size_t end;
    size_t i;
    switch (S->phase) {
    case P_CHECK:
        end = cons_chunk(budget, used, CONS_W_CHECK, S->pos, n);
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
        end = cons_chunk(budget, used, CONS_W_COPY, S->pos, n);
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
        cons_fill_axis(S, cons_chunk(budget, used, CONS_W_COPY, S->pos, m));
        if (S->pos == m) {
            if (S->phase == P_MS_FILL) {
                sort_init(&S->sort, S->scr, NULL, m);
                S->phase = P_MS_SORT;
            } else {
                cons_sel_init(&S->sel, S->scr, m, (m - 1u) / 2u);
                S->phase = P_MED_SEL;
            }
        }
        break;
    case P_MS_SORT:
        if (sort_run(&S->sort, budget, used) == 0) {
            return CONS_SPENT;
        }
        S->acc = INFINITY;
        S->pos = 1u;
        S->phase = P_MS_DIFF;
        break;
    case P_MS_DIFF:
        end = cons_chunk(budget, used, CONS_W_COPY, S->pos, m);
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
        if (cons_sel_run(&S->sel, budget, used) == 0) {
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
        end = cons_chunk(budget, used, CONS_W_ATAN, S->pos, m);
        for (i = S->pos; i < end; ++i) {
            const magcal_vec2_t *p = &S->pts[S->order[i]];
            S->scr[i] = atan2f(p->y - S->acc, p->x - S->cx);
        }
        S->pos = end;
        if (end == m) {
            sort_init(&S->sort, S->scr, S->order, m);
            S->phase = P_SORT;
        }
        break;
    default: /* P_SORT */
        if (sort_run(&S->sort, budget, used) == 0) {
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
static void cons_score_init(cons_state_t *S, const uint16_t set[5], size_t stride, size_t cnt)
{
    size_t c = 0u;
    size_t j;
    if (S->n <= 5u) {
        cons_sel_init(&S->sel, S->scr, cnt, (cnt - 1u) / 2u);
        return;
    }
    for (j = 0u; j < 5u; ++j) {
        if ((size_t)set[j] % stride == 0u && (size_t)set[j] / stride < cnt) {
            S->scr[(size_t)set[j] / stride] = -1.0f;
            ++c;
        }
    }
    S->sub_c = c;
    cons_sel_init(&S->sel, S->scr, cnt, c + (cnt - c - 1u) / 2u);
}

/* Draws needed (at most max_iter) so that an all-inlier minimal set is missed with probability
 * <= CONS_MISS_PROB when a fraction w of the samples are inliers: (1 - w^5)^N <= CONS_MISS_PROB.
 * O(max_iter) products, no logf. */
static void cons_need(cons_state_t *S)
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
static void cons_draw_one(cons_state_t *S)
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
static MAGCAL_NOINLINE magcal_status_t cons_draw(cons_state_t *S, uint32_t budget, uint32_t *used)
{
    const size_t n = S->n;
    switch (S->phase) {
    case P_DRAW:
        if (S->draws >= S->cfg->max_iter ||
            (S->n > CONS_SUB_TARGET && S->draws >= CONS_MIN_DRAWS && S->draws >= S->need)) {
            S->phase = P_START;
            break;
        }
        if (cons_pay(budget, used, CONS_W_DRAW) == 0) {
            return CONS_SPENT;
        }
        cons_draw_one(S);
        break;
    case P_SCORE_RES: {
        /* |residual| of the subsample into scr[0..sub-1] (as cons_residuals) */
        const size_t end = cons_chunk(budget, used, CONS_W_RES, S->pos, S->sub);
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
        if (cons_sel_run(&S->sel, budget, used) == 0) {
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
        const size_t end = cons_chunk(budget, used, CONS_W_COPY, S->pos, S->sub);
        size_t t;
        for (t = S->pos; t < end; ++t) {
            if (S->scr[t] >= 0.0f && S->scr[t] <= thr) {
                ++S->cnt;
            }
        }
        S->pos = end;
        if (end == S->sub) {
            if (cons_pay(budget, used, CONS_W_FIX) == 0) {
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
static MAGCAL_NOINLINE magcal_status_t cons_start(cons_state_t *S, uint32_t budget, uint32_t *used)
{
    magcal_status_t st;
    switch (S->phase) {
    case P_START:
        if (cons_pay(budget, used, CONS_W_FIX) == 0) {
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
        st = cons_fit(S, budget, used);
        if (st != MAGCAL_OK) {
            return st;
        }
        S->phase = P_START_RES;
        break;
    case P_START_RES: {
        size_t p0 = S->pos;
        int done = cons_res_loop(S, &S->best, budget, used);
        size_t i;
        for (i = p0; i < S->pos; ++i) {
            S->scr[i] = S->res[i];
        }
        if (done != 0) {
            if (S->valid == 0u) {
                cons_sel_init(&S->sel, S->scr, S->n, (S->n - 1u) / 2u);
            } else {
                cons_score_init(S, S->best_idx, 1u, S->n);
            }
            S->phase = P_START_SEL;
        }
        break;
    }
    default: /* P_START_SEL */
        if (cons_sel_run(&S->sel, budget, used) == 0) {
            return CONS_SPENT;
        }
        S->best_score = S->sel.val;
        S->phase = P_RINIT;
        break;
    }
    return (*used < budget) ? MAGCAL_IN_PROGRESS : CONS_SPENT;
}

/* Working-mask entry i (0/1) of step 3; the first five inliers are kept in idx (a refit of
 * exactly five points is the 5-point exact path, as magcal_ellipse_fit_idx() takes it). */
static void cons_mask_set(cons_state_t *S, size_t i, uint8_t v)
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
static MAGCAL_NOINLINE void cons_rescale(cons_state_t *S)
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
static void cons_refine_init(cons_state_t *S)
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
static MAGCAL_NOINLINE magcal_status_t cons_refine(cons_state_t *S, uint32_t budget, uint32_t *used)
{
    uint8_t *wm = (uint8_t *)S->order;
    const size_t n = S->n;
    size_t end;
    size_t i;
    magcal_status_t st;
    switch (S->phase) {
    case P_RINIT:
        if (cons_pay(budget, used, CONS_W_FIX) == 0) {
            return CONS_SPENT;
        }
        cons_refine_init(S);
        S->phase = P_RINIT_MASK;
        break;
    case P_RINIT_MASK:
        end = cons_chunk(budget, used, CONS_W_COPY, S->pos, n);
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
        if (cons_pay(budget, used, CONS_W_FIX) == 0) {
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
        st = cons_fit(S, budget, used);
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
        if (cons_res_loop(S, &S->cand, budget, used) != 0) {
            S->cur = S->cand;
            S->pos = 0u;
            S->k_in = 0u;
            S->acc = 0.0f;
            S->phase = P_RT_GATHER;
        }
        break;
    case P_RT_GATHER:
        end = cons_chunk(budget, used, CONS_W_COPY, S->pos, n);
        for (i = S->pos; i < end; ++i) {
            if (wm[i] != 0u) {
                S->scr[S->k_in] = S->res[i];
                S->acc += S->res[i] * S->res[i];
                ++S->k_in;
            }
        }
        S->pos = end;
        if (end == n) {
            cons_sel_init(&S->sel, S->scr, S->k_in, (S->k_in - 1u) / 2u);
            S->phase = P_RT_SEL;
        }
        break;
    case P_RT_SEL:
        if (cons_sel_run(&S->sel, budget, used) == 0) {
            return CONS_SPENT;
        }
        cons_rescale(S);
        S->pos = 0u;
        S->k_in = 0u;
        S->changed = 0u;
        S->phase = P_RT_MASK;
        break;
    default: /* P_RT_MASK */
        end = cons_chunk(budget, used, CONS_W_COPY, S->pos, n);
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
static MAGCAL_NOINLINE magcal_status_t cons_finish(cons_state_t *S, uint32_t budget, uint32_t *used)
{
    const size_t n = S->n;
    size_t end;
    size_t i;
    if (S->phase == P_FINAL_RES) {
        size_t p0 = S->pos;
        int done = cons_res_loop(S, &S->cur, budget, used);
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
    end = cons_chunk(budget, used, CONS_W_COPY, S->pos, n);
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
    if (end < n || cons_pay(budget, used, CONS_W_FIX) == 0) {
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

#define CONS_PH_RUN 1u
#define CONS_PH_DONE 2u

magcal_status_t magcal_consensus_begin(magcal_consensus_slice_t *s, const magcal_consensus_cfg_t *cfg,
                                       const magcal_vec2_t *pts, size_t n, const uint8_t *cand,
                                       void *work, size_t work_len, uint8_t *inlier,
                                       magcal_consensus_result_t *res)
{
    cons_state_t *S;
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
    S = (cons_state_t *)(void *)((uint8_t *)work +
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
    cons_state_t *S;
    if (s == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (s->phase_ != CONS_PH_RUN || s->state_ == NULL || max_out < 1u ||
        max_out > (size_t)UINT16_MAX) {
        return MAGCAL_ERR_ARG;
    }
    S = (cons_state_t *)s->state_;
    S->max_out = (uint16_t)max_out;
    return MAGCAL_OK;
}

magcal_status_t magcal_consensus_step(magcal_consensus_slice_t *s, uint32_t budget)
{
    cons_state_t *S;
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
    S = (cons_state_t *)s->state_;
    while (st == MAGCAL_IN_PROGRESS) {
        if (S->phase < P_DRAW) {
            st = cons_prep(S, budget, &used);
        } else if (S->phase < P_START) {
            st = cons_draw(S, budget, &used);
        } else if (S->phase < P_RINIT) {
            st = cons_start(S, budget, &used);
        } else if (S->phase < P_FINAL_RES) {
            st = cons_refine(S, budget, &used);
        } else {
            st = cons_finish(S, budget, &used);
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
    return (s->state_ != NULL && s->phase_ != (uint8_t)CONS_PH_DONE) ? (unsigned)((const cons_state_t *)s->state_)->phase
                                                                     : 0xFFu;
}
#endif
