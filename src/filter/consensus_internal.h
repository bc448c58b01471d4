/*
 * Internal header of the consensus outlier stage (src/filter/consensus*.c, consensus.h): the
 * per-visit weights and the rule's constants, the run state kept in the caller's workspace with
 * its phases, the budget helpers every phase charges with, and the phase functions each file gives
 * the driver. Not installed. Files:
 *   consensus_prims.c  resumable quickselect and shell sort, residual loop, fit slices;
 *   consensus_draw.c   checks, candidates and their order; minimal-set draws ranked by LMedS;
 *                      the start model;
 *   consensus_refine.c threshold/refit rounds and the final verdict of every sample;
 *   consensus.c        begin / step / run (the slicing driver) and the cfg check.
 */
#ifndef MAGCAL_CONSENSUS_INTERNAL_H
#define MAGCAL_CONSENSUS_INTERNAL_H

#include <stddef.h>
#include <stdint.h>

#include "magcal/consensus.h"
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
} magcal_cons_sel_t;

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
} magcal_cons_sort_t;

/* State of one run, kept in the workspace (off the stack: the fits are on the deepest stack path
 * of the 2-D pipeline). */
typedef struct {
    magcal_ellipse_t best; /* best minimal model (LMedS) */
    magcal_ellipse_t cur;  /* current refit */
    magcal_ellipse_t cand; /* candidate minimal model, then the next refit */
    magcal_ellipse_fit_slice_t fit;
    magcal_cons_sel_t sel;
    magcal_cons_sort_t sort;
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
} magcal_cons_state_t;

/* cppcheck-suppress misra-c2012-2.3 ; deviation D4: a static assert is an unused typedef */
MAGCAL_STATIC_ASSERT(sizeof(magcal_cons_state_t) + sizeof(void *) - 1u <= MAGCAL_CONSENSUS_STATE_LEN_,
                     consensus_state_fits_workspace);

/* Phases of a run, in order. */
/* cppcheck-suppress misra-c2012-5.7 ; deviation D14 (false positive): the enum has no tag; misra.py gives every untagged enum the same name, so two units' untagged enums read as one tag declared twice */
/* cppcheck-suppress misra-c2012-2.4 ; deviation D14 (false positive): no tag, so no unused tag; the constants are the phases of magcal_cons_state_t.phase */
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

/* consensus_prims.c: the budget of a step (one copy, not an inline per phase file: issue 14
 * flash). magcal_cons_chunk charges a loop chunk: the end of the visits of weight w this step
 * pays for from pos over [pos, len), at least one on a step's first visit (*used == 0); when not
 * one more visit is paid for, the budget counts as spent (the phase returns CONS_SPENT).
 * magcal_cons_pay charges one O(1) visit; 0 when the budget is spent. */
size_t magcal_cons_chunk(uint32_t budget, uint32_t *used, uint32_t w, size_t pos, size_t len);
int magcal_cons_pay(uint32_t budget, uint32_t *used, uint32_t w);

/* consensus_prims.c: resumable selection (1 when done), shell sort (1 when done), residuals of
 * model e (1 when done), one fit chunk (CONS_SPENT while it runs, then its status) */
void magcal_cons_sel_init(magcal_cons_sel_t *q, float *a, size_t n, size_t k);
int magcal_cons_sel_run(magcal_cons_sel_t *q, uint32_t budget, uint32_t *used);
void magcal_cons_sort_init(magcal_cons_sort_t *q, float *key, uint16_t *idx, size_t m);
int magcal_cons_sort_run(magcal_cons_sort_t *q, uint32_t budget, uint32_t *used);
int magcal_cons_res_loop(magcal_cons_state_t *S, const magcal_ellipse_t *e, uint32_t budget,
                         uint32_t *used);
magcal_status_t magcal_cons_fit(magcal_cons_state_t *S, uint32_t budget, uint32_t *used);

/* consensus_draw.c, and consensus_refine.c below: the phases (MAGCAL_IN_PROGRESS: go on with
 * the next phase, CONS_SPENT: stop this step, else the run's final status) */
magcal_status_t magcal_cons_prep(magcal_cons_state_t *S, uint32_t budget, uint32_t *used);
magcal_status_t magcal_cons_draw(magcal_cons_state_t *S, uint32_t budget, uint32_t *used);
magcal_status_t magcal_cons_start(magcal_cons_state_t *S, uint32_t budget, uint32_t *used);

/* consensus_refine.c */
magcal_status_t magcal_cons_refine(magcal_cons_state_t *S, uint32_t budget, uint32_t *used);
magcal_status_t magcal_cons_finish(magcal_cons_state_t *S, uint32_t budget, uint32_t *used);

#endif /* MAGCAL_CONSENSUS_INTERNAL_H */
