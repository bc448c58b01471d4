/*
 * The 2-D calibrator's solve, time-sliced: run()'s stages (calibrator.h "Pipeline") as resumable
 * phases whose state lives in the run state inside the workspace, never on the stack across calls.
 * magcal_calibrator_run() is begin + one step with an unlimited budget (one code path); the
 * continuous calibrator (src/loop/cont_step.c) calls step() once per loop iteration with its
 * budget. Every O(n) pass keeps its cursor in the run state and charges a per-visit weight
 * (CAL_W_*, estimated Cortex-M4F instructions: host callgrind x 1.2, docs/calibrator.md "Work per
 * call"); the density filter, the thinning, the consensus and the plain fit are the modules' own
 * slices (optics.h, consensus.h, ellipse.h), driven with what is left of the budget.
 * Exceptions (one-shot inside one step, documented in calibrator.h): the DBSCAN filter, the
 * automatic radius with a caller's MinPts, and whatever optics.h documents as one-shot
 * (classic order, caller eps).
 *
 * Phases (in order; each returns MAGCAL_OK to go on or the run's final status):
 *  prepare: [bbox of a loaded buffer] -> pre-checks (count, identical, extent) -> [pre-test:
 *           consensus on every sample; clean -> its mask stands in for the filter's] -> density
 *           filter -> filter masks + flags -> mean, scale, moments of the inliers (collinearity
 *           and the hard-iron circle share them) -> coverage of every sample and of the inliers;
 *  fit:     thinning + consensus (+ filter flags again), or the plain fit + its mask (after a
 *           clean pre-test: its consensus is the fit, straight to the flags);
 *  gates:   flags with residual bits + counts -> report, gates;
 *  adopt:   ellipse -> calibration, corrected coverage, distinct values, harmonics of the new
 *           calibration (observability gate), the heading shift, harmonics of the installed one,
 *           the adoption rule.
 */
#include <float.h>
#include <math.h>
#include <string.h>

#include "calibrator_internal.h"
#include "magcal/calibrator.h"
#include "magcal_internal.h"

#define CAL_SHIFT_STEPS 72u /* heading shift evaluated every 5 degrees (cal_sincos5) */
#define CAL_COLLINEAR_TOL 1.0e-6f
/* Pre-test: a consensus reject farther than this many residual thresholds (k_sigma 3.5: ~21 sigma)
 * from the fit is a singular point (a glitch, a spike), what the density stage is for: the full
 * pipeline runs. A clean store's rejects are the noise tail, 1..4 thresholds (vn100_car_circles_b:
 * at most 3.7; the synthetic spikes: 380). */
#define CAL_PRE_FAR 6.0f

/* Per-visit weights, estimated M4F instructions (measured: docs/calibrator.md "Work per call"). */
#define CAL_W_PHASE 60u     /* a phase switch / O(1) bookkeeping */
#define CAL_W_BBOX 240u     /* bounding box of one loaded sample (fminf / fmaxf calls) */
#define CAL_W_IDENT 25u     /* one identical-samples comparison */
#define CAL_W_FLAG 40u      /* one flag / mask byte pass */
#define CAL_W_MASKS 55u     /* filter mask copy, count and flags of one sample */
#define CAL_W_MEAN 65u      /* one sample of the inliers' mean (two divisions) */
#define CAL_W_SCALE 135u     /* one sample of their scale */
#define CAL_W_MOMENT 215u   /* moments + circle normal equations of one sample */
#define CAL_W_CIRCLE 900u   /* collinearity test + 3x3 circle solve */
#define CAL_W_COVER 300u    /* approximate heading (atan2f) + bin of one sample */
#define CAL_W_COVFIN 1300u   /* coverage of the 36 bins */
#define CAL_W_GATES 62u     /* flags with residual bits and counts of one sample */
#define CAL_W_TOCAL 3750u   /* ellipse -> calibration (eigen decomposition, sqrt, trig) */
#define CAL_W_COVCORR 600u  /* correction + heading + bin of one sample */
#define CAL_W_SHIFT 870u    /* one of the 72 shift headings (inverse map, correction, atan2f) */
/* pre-test: one consensus reject, its |residual| and mask byte (host callgrind, vn100 store: 75 for
 * the residual + ~30 the visit, x 1.2 = 126; charged as consensus.c's CONS_W_RES + ~20, both
 * scaled x 1.6 by the QEMU per-step trace, tools/bench/cont_weights.py). Its inliers' visits are
 * ph_masks' (CAL_W_MASKS). */
#define CAL_W_PRE_RES 250u
/* coarse stage (host estimate x 1.2, as the passes they resemble): one inlier's circle residual
 * (difference, sqrtf), one inlier's re-gate + circle normal equations (as CAL_W_MOMENT + the
 * residual), the refitted circle's 3x3 solve + gates + calibration */
#define CAL_W_CO_RES 150u
#define CAL_W_CO_GATE 330u
#define CAL_W_CO_FIT 1200u
#define CAL_W_ONESHOT UINT32_MAX /* a one-shot call (exceptions): ends the step */

typedef enum {
    PH_BBOX = 0,
    PH_CHECK,
    PH_IDENT,
    PH_EXTENT,
    PH_PRE_CONS,
    PH_PRE_MASK,
    PH_FILTER,
    PH_FILTER_RUN,
    PH_MASKS,
    PH_MEAN,
    PH_SCALE,
    PH_MOMENTS,
    PH_CIRCLE,
    PH_COV_ALL,
    PH_COV_F,
    PH_THIN,
    PH_CONS,
    PH_FLAGS0,
    PH_PLAIN,
    PH_PLAIN_MASK,
    PH_GATES,
    PH_CO_RES,
    PH_CO_GATE,
    PH_CO_FIT,
    PH_TOCAL,
    PH_COVC,
    PH_DIST,
    PH_HARM_N,
    PH_VALID,
    PH_SHIFT,
    PH_HARM_C,
    PH_DONE
} cal_phase_t;

/* State of one solve, kept in the workspace (MAGCAL_CALIBRATOR_RUN_LEN): what every phase needs,
 * plus the modules' slice states (one at a time). */
typedef struct {
    magcal_cal_report_t rep;
    magcal_consensus_result_t cres;
    magcal_optics_cfg_t oc;
    magcal_optics_result_t info;
    magcal_cal_budget_t bud;
    uint32_t i;           /* cursor of the current pass */
    uint32_t m;           /* counted samples */
    magcal_status_t held; /* consensus status, returned after the flag pass */
    uint8_t phase;        /* cal_phase_t */
    uint8_t sub;          /* 0 at a phase's first visit */
    uint8_t cand;         /* consensus candidates: 0 all, 1 filter mask, 2 thinned (flags) */
    uint8_t active;       /* a solve is under way */
    uint8_t pre;          /* 1: the pre-test found the data clean (short path) */
    /* cppcheck-suppress misra-c2012-19.2 ; deviation D12: the run state overlays the stages' slice states, never live together, so it fits MAGCAL_CALIBRATOR_RUN_LEN */
    union {
        magcal_dbscan_cfg_t dc;
        magcal_optics_filter_slice_t filter;
        magcal_optics_thin_slice_t thin;
        magcal_consensus_slice_t cons;
    /* cppcheck-suppress misra-c2012-19.2 ; deviation D12: the run state overlays the stages' slice states, never live together, so it fits MAGCAL_CALIBRATOR_RUN_LEN */
    } u;
} cal_run_t;

/* Accumulators of the prepare phases after the filter (mean, scale, moments, circle, coverage):
 * at the start of the stage scratch, free from the end of the filter to the thinning. */
typedef struct {
    magcal_vec2_t cc; /* hard-iron circle centre */
    float mx;         /* inliers' mean */
    float my;
    float s;          /* their scale */
    float sxx;        /* collinearity moments */
    float syy;
    float sxy;
    float a[9];       /* circle normal equations */
    float b[3];
    float cr;         /* coarse stage: circle radius, residual threshold, sum of squares */
    float thr;
    float ss;
    uint16_t bins[MAGCAL_COVERAGE_BINS];
} cal_prep_t;

/* State of the adopt phases: in the stage scratch (the consensus workspace, free after the fit)
 * behind the estimates' MAGCAL_CAL_HARM_SCRATCH_FLOATS floats and n indices (cal_est_*). */
typedef struct {
    magcal_cal2d_t next;  /* the new calibration */
    magcal_cal_harm_t hn; /* harmonics of the new calibration */
    magcal_cal_harm_t hc; /* of the installed one */
    /* cppcheck-suppress misra-c2012-19.2 ; deviation D12: the adopt state overlays the two estimate passes' slice states, never live together, so it fits the stage scratch */
    union {
        magcal_cal_harm_slice_t harm;
        magcal_cal_distinct_slice_t dist;
    /* cppcheck-suppress misra-c2012-19.2 ; deviation D12: the adopt state overlays the two estimate passes' slice states, never live together, so it fits the stage scratch */
    } u;
    size_t distinct;
    float dup;            /* n / distinct values */
    float floor_rel;      /* quantisation floor */
    float sh_mx;          /* shift: largest, sum of squares, count */
    float sh_ss;
    uint32_t sh_cnt;
    float inv[2][2];      /* shift: inverse of the new matrix */
    uint16_t bins[MAGCAL_COVERAGE_BINS];
    uint8_t unusable;     /* installed calibration unusable: adopt after the shift */
} cal_adopt_t;

/* cppcheck-suppress misra-c2012-2.3 ; deviation D4: a static assert is an unused typedef */
MAGCAL_STATIC_ASSERT(sizeof(cal_run_t) <= MAGCAL_CALIBRATOR_RUN_LEN, run_state_fits_workspace);
/* cppcheck-suppress misra-c2012-2.3 ; deviation D4: a static assert is an unused typedef */
MAGCAL_STATIC_ASSERT(sizeof(cal_prep_t) <= MAGCAL_CONSENSUS_WORKSPACE_LEN(16u), prep_fits_scratch);
/* cppcheck-suppress misra-c2012-2.3 ; deviation D4: a static assert is an unused typedef */
MAGCAL_STATIC_ASSERT(sizeof(magcal_ellipse_fit_slice_t) + 8u <= MAGCAL_CONSENSUS_WORKSPACE_LEN(16u), plain_fits_scratch);
/* cppcheck-suppress misra-c2012-2.3 ; deviation D4: a static assert is an unused typedef */
MAGCAL_STATIC_ASSERT(MAGCAL_CAL_HARM_SCRATCH_FLOATS * sizeof(float) + (size_t)2u * 16u + 8u + sizeof(cal_adopt_t) <=
                         MAGCAL_CONSENSUS_WORKSPACE_LEN(16u),
                     adopt_fits_scratch);

/* The workspace pointers of a const calibrator are `void *const`: their memory is writable. */
static cal_run_t *cal_run(const magcal_calibrator_t *cal)
{
    void *run = cal->run;
    return (cal_run_t *)run;
}

static cal_prep_t *cal_prep(const magcal_calibrator_t *cal)
{
    void *scratch = cal->scratch;
    return (cal_prep_t *)scratch;
}

/* p rounded up to the next multiple of 8 (pointer arithmetic from the workspace address; the
 * alignment is read by magcal_misalign, deviation D9). */
static uint8_t *cal_align8(void *p)
{
    const size_t mis = magcal_misalign(p, 8u);
    return (uint8_t *)p + ((mis == 0u) ? 0u : (8u - mis));
}

/* Scratch of the estimates: the harmonics' floats, then the distinct count's n indices. */
static float *cal_est_scratch(const magcal_calibrator_t *cal)
{
    void *scratch = cal->scratch;
    return (float *)scratch;
}

static uint16_t *cal_est_idx(const magcal_calibrator_t *cal)
{
    return (uint16_t *)(void *)(cal_est_scratch(cal) + MAGCAL_CAL_HARM_SCRATCH_FLOATS);
}

/* The plain fit's slice state: at the start of the stage scratch (8-aligned), unused by it. */
static magcal_ellipse_fit_slice_t *cal_plain_slice(const magcal_calibrator_t *cal)
{
    void *scratch = cal->scratch;
    return (magcal_ellipse_fit_slice_t *)(void *)cal_align8(scratch);
}

/* Budget left for a module's step (UINT32_MAX: to the end). */
static uint32_t cal_left(const cal_run_t *r) { return r->bud.unlimited != 0u ? UINT32_MAX : r->bud.left; }

/* After a module's step ended with st: IN_PROGRESS spends the budget; a final status charges
 * `used` (UINT32_MAX when the module does not report it: the step ends there). */
static magcal_status_t cal_module_done(cal_run_t *r, magcal_status_t st, uint32_t used)
{
    (void)magcal_cal_spend(&r->bud, st == MAGCAL_IN_PROGRESS ? CAL_W_ONESHOT : used);
    return st;
}

/* Behind the indices, 8-aligned (the cursors hold pointers and sizes). */
static cal_adopt_t *cal_adopt(const magcal_calibrator_t *cal)
{
    return (cal_adopt_t *)(void *)cal_align8(cal_est_idx(cal) + cal->capacity);
}

/* Go to phase ph (cursor and sub-state cleared). */
static void cal_goto(cal_run_t *r, cal_phase_t ph)
{
    r->phase = (uint8_t)ph;
    r->sub = 0u;
    r->i = 0u;
}

/* ------------------------------------------------------------------ prepare */

static MAGCAL_NOINLINE magcal_status_t ph_bbox(magcal_calibrator_t *cal, cal_run_t *r)
{
    while (r->i < cal->n) {
        const magcal_vec2_t p = cal->buf[r->i];
        if (r->i == 0u) {
            cal->bb_min = p;
            cal->bb_max = p;
        } else {
            cal->bb_min.x = fminf(cal->bb_min.x, p.x);
            cal->bb_min.y = fminf(cal->bb_min.y, p.y);
            cal->bb_max.x = fmaxf(cal->bb_max.x, p.x);
            cal->bb_max.y = fmaxf(cal->bb_max.y, p.y);
        }
        r->i++;
        if (magcal_cal_spend(&r->bud, CAL_W_BBOX) != 0) {
            return MAGCAL_IN_PROGRESS;
        }
    }
    cal_goto(r, PH_CHECK);
    return MAGCAL_OK;
}

/* 1. pre-checks: enough samples */
static MAGCAL_NOINLINE magcal_status_t ph_check(magcal_calibrator_t *cal, cal_run_t *r)
{
    if (cal->n < cal->cfg.min_samples || cal->n < MAGCAL_ELLIPSE_MIN_POINTS) {
        return MAGCAL_ERR_TOO_FEW_POINTS;
    }
    cal_goto(r, PH_IDENT);
    r->i = 1u;
    return MAGCAL_OK;
}

/* All identical samples (checked before the density filter: far outliers cannot fake it). */
static MAGCAL_NOINLINE magcal_status_t ph_ident(magcal_calibrator_t *cal, cal_run_t *r)
{
    const magcal_vec2_t *p = cal->buf;
    while (r->i < cal->n) {
        const size_t i = r->i;
        r->i++;
        if (p[i].x != p[0].x || p[i].y != p[0].y) {
            cal_goto(r, PH_EXTENT);
            return MAGCAL_OK;
        }
        if (magcal_cal_spend(&r->bud, CAL_W_IDENT) != 0) {
            return MAGCAL_IN_PROGRESS;
        }
    }
    return MAGCAL_ERR_DEGENERATE;
}

/* The pre-test applies with the default filter only (OPTICS grid, automatic eps and MinPts), with
 * the consensus on and at least 16 samples (the automatic filter's own minimum). */
static int cal_pretest_on(const magcal_calibrator_t *cal)
{
    const magcal_calibrator_cfg_t *c = &cal->cfg;
    return (c->pretest != 0u && c->filter == MAGCAL_FILTER_OPTICS_GRID && c->eps <= 0.0f &&
            c->min_pts == 0u && c->use_consensus != 0u && cal->n >= 16u)
               ? 1
               : 0;
}

static MAGCAL_NOINLINE magcal_status_t ph_extent(magcal_calibrator_t *cal, cal_run_t *r)
{
    /* Extent of the samples: when its square is not a normal float32, squared distances and
     * moments lose their precision (the density filter's eps^2 test first): 0 = the points are
     * indistinguishable, otherwise too ill-conditioned for float32 (rings below ~1e-20). */
    const float ex = cal->bb_max.x - cal->bb_min.x;
    const float ey = cal->bb_max.y - cal->bb_min.y;
    const float ext = ex > ey ? ex : ey;
    const float ext2 = ext * ext;
    if (!(ext2 > 0.0f)) {
        return MAGCAL_ERR_DEGENERATE;
    }
    if (ext2 < FLT_MIN) {
        return MAGCAL_ERR_ILL_CONDITIONED;
    }
    cal_goto(r, cal_pretest_on(cal) != 0 ? PH_PRE_CONS : PH_FILTER);
    return MAGCAL_OK;
}

/* ------------------------------------------------------------------ pre-test (cfg.pretest)
 * Issue 14: the density filter and the thinning cost more than the fit; on a clean store they
 * reject nothing the consensus does not. The consensus runs first on every sample; when it
 * succeeds and rejects at most n / MAGCAL_CALIBRATOR_PRETEST_DIV samples, its inlier mask takes
 * the filter mask's place in the prepare phases (so a few glitches cannot move the circle centre
 * of the coverage pre-gate or fake collinearity) and its result is the fit. Otherwise the solve
 * goes on at PH_FILTER exactly as without the pre-test (every later phase rewrites what the
 * pre-test left: the consensus result, mask_b, the union), so its results are today's bit for bit;
 * the pre-test's consensus is then the price of a dirty store. */

/* The consensus on every sample into run->cres and mask_b; then the verdict. */
static MAGCAL_NOINLINE magcal_status_t ph_pre_cons(magcal_calibrator_t *cal, cal_run_t *r)
{
    magcal_status_t st;
    if (r->sub == 0u) {
        (void)memset(&r->cres, 0, sizeof r->cres); /* as ph_cov_f: its padding is copied out */
        st = magcal_consensus_begin(&r->u.cons, &cal->cfg.consensus, cal->buf, cal->n, NULL,
                                    cal->scratch, MAGCAL_CONSENSUS_WORKSPACE_LEN(cal->capacity),
                                    cal->mask_b, &r->cres);
        (void)magcal_cal_spend(&r->bud, CAL_W_PHASE);
        if (st == MAGCAL_OK) {
            /* a round that leaves twice the bound out: a dirty store, the full pipeline (an early
             * end only ever costs the short path, never a result: the full one is today's) */
            st = magcal_consensus_limit_rejects(
                &r->u.cons, 2u * ((size_t)cal->n / MAGCAL_CALIBRATOR_PRETEST_DIV) + 1u);
        }
        if (st != MAGCAL_OK) {
            cal_goto(r, PH_FILTER); /* the full pipeline reports whatever is wrong */
            return MAGCAL_OK;
        }
        r->sub = 1u;
    }
    st = magcal_consensus_step(&r->u.cons, cal_left(r));
    st = cal_module_done(r, st, r->u.cons.used_);
    if (st == MAGCAL_IN_PROGRESS) {
        return st;
    }
    if (st == MAGCAL_OK &&
        (size_t)cal->n - (size_t)r->cres.n_inliers <= (size_t)cal->n / MAGCAL_CALIBRATOR_PRETEST_DIV) {
        cal_goto(r, PH_PRE_MASK);
        r->m = 0u;
    } else {
        cal_goto(r, PH_FILTER);
    }
    return MAGCAL_OK;
}

/* Few rejects: each must lie within CAL_PRE_FAR thresholds of the fit (else the full pipeline).
 * Clean: the consensus inliers are the prepare phases' mask (mask_a), counted, as ph_masks does
 * with the filter's; no sample is a filter reject. */
static MAGCAL_NOINLINE magcal_status_t ph_pre_mask(magcal_calibrator_t *cal, cal_run_t *r)
{
    cal_prep_t *q = cal_prep(cal);
    const float far = CAL_PRE_FAR * r->cres.threshold;
    while (r->i < cal->n) {
        const size_t i = r->i;
        const uint8_t in = cal->mask_b[i];
        uint32_t w = CAL_W_MASKS;
        if (in == 0u) {
            const float res = magcal_ellipse_residual(&r->cres.fit, cal->buf[i]);
            if (!(fabsf(res) <= far)) {
                cal_goto(r, PH_FILTER); /* a singular point: the full pipeline */
                (void)magcal_cal_spend(&r->bud, CAL_W_PRE_RES);
                return MAGCAL_OK;
            }
            w = CAL_W_PRE_RES;
        }
        cal->mask_a[i] = in;
        r->m += in != 0u ? 1u : 0u;
        cal->flags[i] = MAGCAL_CALIBRATOR_FLAG_JUDGED;
        r->i++;
        if (magcal_cal_spend(&r->bud, w) != 0) {
            return MAGCAL_IN_PROGRESS;
        }
    }
    cal->n_judged = cal->n;
    r->rep.rejected_filter = 0u;
    r->rep.filter_eps = 0.0f;
    r->rep.filter_min_pts = 0u;
    r->rep.pretest_clean = 1u;
    r->pre = 1u;
    if (r->m < cal->cfg.min_samples) {
        return MAGCAL_ERR_TOO_FEW_POINTS;
    }
    cal_goto(r, PH_MEAN);
    q->mx = 0.0f;
    q->my = 0.0f;
    return MAGCAL_OK;
}

/* DBSCAN filter (one-shot inside one step: documented exception). */
static MAGCAL_NOINLINE magcal_status_t cal_filter_dbscan(magcal_calibrator_t *cal, cal_run_t *r)
{
#if MAGCAL_CFG_ENABLE_DBSCAN
    static const magcal_dbscan_cfg_t dc_default = MAGCAL_DBSCAN_CFG_DEFAULT;
    const magcal_calibrator_cfg_t *c = &cal->cfg;
    const size_t n = cal->n;
    magcal_dbscan_cfg_t *dc = &r->u.dc;
    int16_t *labels = (int16_t *)cal->scratch;
    size_t lab_len = (2u * n + 3u) & ~(size_t)3u;
    uint8_t *rest = (uint8_t *)cal->scratch + lab_len;
    size_t rest_len = cal->scratch_len - lab_len;
    magcal_status_t st;
    *dc = dc_default;
    if (c->eps > 0.0f) {
        dc->eps = c->eps;
        dc->min_pts = c->min_pts != 0u ? c->min_pts : 4u;
    } else {
        float e;
        float ep;
        uint16_t mp;
        st = magcal_optics_auto_params(cal->buf, n, cal->scratch, cal->scratch_len, &e, &mp, &ep);
        if (st != MAGCAL_OK) {
            return st;
        }
        dc->eps = ep;
        dc->min_pts = c->min_pts != 0u ? c->min_pts : mp;
    }
    st = magcal_dbscan_run(dc, cal->buf, n, rest, rest_len, labels, NULL, NULL);
    if (st != MAGCAL_OK) {
        return st;
    }
    st = magcal_optics_largest_cluster(labels, n, rest, rest_len, cal->flags, NULL, NULL);
    if (st != MAGCAL_OK) {
        return st;
    }
    r->rep.filter_eps = dc->eps;
    r->rep.filter_min_pts = dc->min_pts;
    return MAGCAL_OK;
#else
    (void)cal;
    (void)r;
    return MAGCAL_ERR_ARG; /* DBSCAN compiled out (config.h MAGCAL_CFG_ENABLE_DBSCAN = 0) */
#endif
}

/* OPTICS configuration of the run (the automatic radius with a caller's MinPts is one-shot). */
static MAGCAL_NOINLINE magcal_status_t cal_filter_optics_cfg(magcal_calibrator_t *cal, cal_run_t *r)
{
    static const magcal_optics_cfg_t oc_default = MAGCAL_OPTICS_CFG_DEFAULT;
    const magcal_calibrator_cfg_t *c = &cal->cfg;
    magcal_optics_cfg_t *oc = &r->oc;
    *oc = oc_default;
    if (c->filter == MAGCAL_FILTER_OPTICS_CLASSIC) {
        oc->order = MAGCAL_OPTICS_CLASSIC;
        oc->neighbors = MAGCAL_NEIGHBORS_BRUTE;
    }
    if (c->eps > 0.0f) {
        oc->eps = c->eps;
        oc->eps_prime = c->eps;
        oc->min_pts = c->min_pts != 0u ? c->min_pts : 4u;
    } else if (c->min_pts != 0u) {
        /* automatic radius, caller's MinPts */
        float e;
        float ep;
        uint16_t mp;
        magcal_status_t st =
            magcal_optics_auto_params(cal->buf, cal->n, cal->scratch, cal->scratch_len, &e, &mp, &ep);
        if (st != MAGCAL_OK) {
            return st;
        }
        oc->eps = e;
        oc->eps_prime = ep;
        oc->min_pts = c->min_pts;
        (void)magcal_cal_spend(&r->bud, CAL_W_ONESHOT);
    } else {
        /* fully automatic parameters: the OPTICS defaults */
    }
    return MAGCAL_OK;
}

/* 2. density filter: its 0/1 inlier mask into cal->flags (the scratch is in use until it ends). */
static MAGCAL_NOINLINE magcal_status_t ph_filter(magcal_calibrator_t *cal, cal_run_t *r)
{
    const magcal_calibrator_cfg_t *c = &cal->cfg;
    magcal_status_t st;
    if (c->filter == MAGCAL_FILTER_NONE || (c->eps <= 0.0f && cal->n < 16u)) {
        /* no filter (auto parameters need 16 samples: below that every sample is a candidate) */
        while (r->i < cal->n) {
            cal->flags[r->i] = 1u;
            r->i++;
            if (magcal_cal_spend(&r->bud, CAL_W_FLAG) != 0) {
                return MAGCAL_IN_PROGRESS;
            }
        }
        r->rep.filter_eps = 0.0f;
        r->rep.filter_min_pts = 0u;
    } else if (c->filter == MAGCAL_FILTER_DBSCAN) {
        st = cal_filter_dbscan(cal, r);
        (void)magcal_cal_spend(&r->bud, CAL_W_ONESHOT);
        if (st != MAGCAL_OK) {
            return st;
        }
    } else {
        st = cal_filter_optics_cfg(cal, r);
        if (st == MAGCAL_OK) {
            st = magcal_optics_filter_begin(&r->u.filter, &r->oc, cal->buf, cal->n, cal->scratch,
                                            cal->scratch_len, cal->flags, &r->info);
        }
        if (st != MAGCAL_OK) {
            return st;
        }
        cal_goto(r, PH_FILTER_RUN);
        return MAGCAL_OK;
    }
    cal_goto(r, PH_MASKS);
    return MAGCAL_OK;
}

/* The OPTICS filter's steps (a phase of its own: only this small frame sits above them). */
static MAGCAL_NOINLINE magcal_status_t ph_filter_run(cal_run_t *r)
{
    magcal_status_t st =
        cal_module_done(r, magcal_optics_filter_step(&r->u.filter, cal_left(r)), CAL_W_ONESHOT);
    if (st != MAGCAL_OK) {
        return st; /* MAGCAL_IN_PROGRESS, or the filter's failure */
    }
    r->rep.filter_eps = r->info.eps_prime;
    r->rep.filter_min_pts = r->info.min_pts;
    cal_goto(r, PH_MASKS);
    return MAGCAL_OK;
}

/* The filter mask into mask_a (the scratch is free now), counted; flags become flag bits. */
static MAGCAL_NOINLINE magcal_status_t ph_masks(magcal_calibrator_t *cal, cal_run_t *r)
{
    cal_prep_t *q = cal_prep(cal);
    if (r->sub == 0u) {
        r->m = 0u;
        r->sub = 1u;
    }
    while (r->i < cal->n) {
        const size_t i = r->i;
        const uint8_t in = cal->flags[i];
        cal->mask_a[i] = in;
        if (in != 0u) {
            r->m++;
            cal->flags[i] = MAGCAL_CALIBRATOR_FLAG_JUDGED;
        } else {
            cal->flags[i] = (uint8_t)(MAGCAL_CALIBRATOR_FLAG_JUDGED | MAGCAL_CALIBRATOR_FLAG_FILTER);
        }
        r->i++;
        if (magcal_cal_spend(&r->bud, CAL_W_MASKS) != 0) {
            return MAGCAL_IN_PROGRESS;
        }
    }
    cal->n_judged = cal->n;
    r->rep.rejected_filter = (uint16_t)(cal->n - r->m);
    if (r->m < cal->cfg.min_samples) {
        return MAGCAL_ERR_TOO_FEW_POINTS;
    }
    cal_goto(r, PH_MEAN);
    q->mx = 0.0f;
    q->my = 0.0f;
    return MAGCAL_OK;
}

/* Mean of p / m of the filter inliers (summing p overflowed to Inf for samples near FLT_MAX). */
static MAGCAL_NOINLINE magcal_status_t ph_mean(magcal_calibrator_t *cal, cal_run_t *r)
{
    cal_prep_t *q = cal_prep(cal);
    const float fm = (float)r->m;
    while (r->i < cal->n) {
        const size_t i = r->i;
        if (cal->mask_a[i] != 0u) {
            q->mx += cal->buf[i].x / fm;
            q->my += cal->buf[i].y / fm;
        }
        r->i++;
        if (magcal_cal_spend(&r->bud, CAL_W_MEAN) != 0) {
            return MAGCAL_IN_PROGRESS;
        }
    }
    cal_goto(r, PH_SCALE);
    q->s = 0.0f;
    return MAGCAL_OK;
}

/* Largest deviation from the mean (the moments are scaled by it: they cannot overflow; a ring of
 * radius 1e18 overflowed sxx to Inf and was called degenerate). */
static MAGCAL_NOINLINE magcal_status_t ph_scale(magcal_calibrator_t *cal, cal_run_t *r)
{
    cal_prep_t *q = cal_prep(cal);
    while (r->i < cal->n) {
        const size_t i = r->i;
        if (cal->mask_a[i] != 0u) {
            q->s = fmaxf(q->s, fmaxf(fabsf(cal->buf[i].x - q->mx), fabsf(cal->buf[i].y - q->my)));
        }
        r->i++;
        if (magcal_cal_spend(&r->bud, CAL_W_SCALE) != 0) {
            return MAGCAL_IN_PROGRESS;
        }
    }
    if (!(q->s > 0.0f) || !magcal_isfinite_f(q->s)) {
        return MAGCAL_ERR_DEGENERATE; /* all identical, or a spread float32 cannot represent */
    }
    cal_goto(r, PH_MOMENTS);
    q->sxx = 0.0f;
    q->syy = 0.0f;
    q->sxy = 0.0f;
    (void)memset(q->a, 0, sizeof q->a);
    (void)memset(q->b, 0, sizeof q->b);
    return MAGCAL_OK;
}

/* Second moments (collinearity) and the hard-iron circle's normal equations
 * x^2 + y^2 + C x + D y + E = 0, both of the centred, scaled inliers. */
static MAGCAL_NOINLINE magcal_status_t ph_moments(magcal_calibrator_t *cal, cal_run_t *r)
{
    cal_prep_t *q = cal_prep(cal);
    while (r->i < cal->n) {
        const size_t i = r->i;
        if (cal->mask_a[i] != 0u) {
            const float u = (cal->buf[i].x - q->mx) / q->s;
            const float v = (cal->buf[i].y - q->my) / q->s;
            const float y = -(u * u + v * v);
            float w[3];
            size_t e;
            size_t c;
            q->sxx += u * u;
            q->syy += v * v;
            q->sxy += u * v;
            w[0] = u;
            w[1] = v;
            w[2] = 1.0f;
            for (e = 0u; e < 3u; ++e) {
                for (c = 0u; c <= e; ++c) {
                    q->a[e * 3u + c] += w[e] * w[c];
                }
                q->b[e] += w[e] * y;
            }
        }
        r->i++;
        if (magcal_cal_spend(&r->bud, CAL_W_MOMENT) != 0) {
            return MAGCAL_IN_PROGRESS;
        }
    }
    cal_goto(r, PH_CIRCLE);
    return MAGCAL_OK;
}

/* Inliers collinear (smaller covariance eigenvalue vs larger; on the filter inliers: before the
 * filter, two glitch samples 1e5 R away made a clean ring look collinear), then the circle. */
static MAGCAL_NOINLINE magcal_status_t ph_circle(magcal_calibrator_t *cal, cal_run_t *r)
{
    cal_prep_t *q = cal_prep(cal);
    const float tr = q->sxx + q->syy;
    float det;
    float disc;
    magcal_status_t st;
    if (!(tr > 0.0f)) {
        return MAGCAL_ERR_DEGENERATE;
    }
    det = q->sxx * q->syy - q->sxy * q->sxy;
    disc = sqrtf(fmaxf(0.25f * tr * tr - det, 0.0f));
    if (0.5f * tr - disc <= CAL_COLLINEAR_TOL * (0.5f * tr + disc)) {
        return MAGCAL_ERR_DEGENERATE;
    }
    if (r->m < 3u) {
        return MAGCAL_ERR_TOO_FEW_POINTS;
    }
    st = magcal_ldlt_solve(q->a, q->b, 3u, 1.0e-6f, NULL);
    if (st != MAGCAL_OK) {
        return st == MAGCAL_ERR_ILL_CONDITIONED ? MAGCAL_ERR_DEGENERATE : st;
    }
    q->cc.x = q->mx - 0.5f * q->b[0] * q->s;
    q->cc.y = q->my - 0.5f * q->b[1] * q->s;
    (void)magcal_cal_spend(&r->bud, CAL_W_CIRCLE);
    cal_goto(r, PH_COV_ALL);
    return MAGCAL_OK;
}

/* Bins of the approximate headings around the circle centre: every sample (with_mask 0) or the
 * filter inliers; 1 when the pass is complete. */
static int cal_cover_pass(magcal_calibrator_t *cal, cal_run_t *r, int with_mask)
{
    cal_prep_t *q = cal_prep(cal);
    if (r->sub == 0u) {
        (void)memset(q->bins, 0, sizeof q->bins);
        r->sub = 1u;
    }
    while (r->i < cal->n) {
        const size_t i = r->i;
        r->i++;
        if (with_mask == 0 || cal->mask_a[i] != 0u) {
            q->bins[magcal_cal_bin_of(
                magcal_cal_angle_deg(cal->buf[i].x - q->cc.x, cal->buf[i].y - q->cc.y))] = 1u;
            if (magcal_cal_spend(&r->bud, CAL_W_COVER) != 0) {
                return 0;
            }
        } else if (magcal_cal_spend(&r->bud, CAL_W_FLAG) != 0) {
            return 0;
        } else {
            /* not an inlier */
        }
    }
    return 1;
}

/* The circle's radius from its solved normal equations (b = C, D, E of the centred, scaled
 * inliers: r^2 = (C^2 + D^2) / 4 - E); 0 when it is not a circle. */
static int cal_coarse_radius(cal_prep_t *q)
{
    const float r2 = 0.25f * (q->b[0] * q->b[0] + q->b[1] * q->b[1]) - q->b[2];
    q->cr = r2 > 0.0f ? q->s * sqrtf(r2) : 0.0f;
    return q->cr > 0.0f && magcal_isfinite_f(q->cr) ? 1 : 0;
}

/* Distance of sample p from the coarse circle minus its radius. */
static float cal_coarse_res(const cal_prep_t *q, magcal_vec2_t p)
{
    const float dx = p.x - q->cc.x;
    const float dy = p.y - q->cc.y;
    return sqrtf(dx * dx + dy * dy) - q->cr;
}

/* 3. coverage pre-gate: every sample, around the hard-iron circle centre of the filter inliers
 * (a short arc is reported as COVERAGE, not as whatever conic it happens to fit). */
static MAGCAL_NOINLINE magcal_status_t ph_cov_all(magcal_calibrator_t *cal, cal_run_t *r)
{
    cal_prep_t *q = cal_prep(cal);
    float cov;
    if (cal_cover_pass(cal, r, 0) == 0) {
        return MAGCAL_IN_PROGRESS;
    }
    cov = magcal_cal_coverage_of(q->bins, &r->rep.missing_start_deg, &r->rep.missing_width_deg);
    r->rep.coverage_deg = cov;
    (void)magcal_cal_spend(&r->bud, CAL_W_COVFIN);
    if (cov < cal->cfg.min_coverage_deg) {
        if (cal->coarse_min_cov > 0.0f && cov >= cal->coarse_min_cov && cal_coarse_radius(q) != 0) {
            r->rep.coarse = 1u; /* hard iron only: the circle of the inliers ("Coarse stage") */
            cal_goto(r, PH_CO_RES);
            q->ss = 0.0f;
            return MAGCAL_OK;
        }
        return MAGCAL_ERR_COVERAGE;
    }
    if (r->pre != 0u) {
        /* clean pre-test: its consensus (on every sample) is the fit */
        r->held = MAGCAL_OK;
        cal_goto(r, PH_FLAGS0);
        return MAGCAL_OK;
    }
    cal_goto(r, PH_COV_F);
    return MAGCAL_OK;
}

/* When the filter's inliers alone cover less than the gate while all samples do, the filter split
 * the ring into arcs (bursts leave gaps, algorithms.md 4.3): the consensus then draws its minimal
 * sets from every sample instead (LMedS tolerates up to 50 % outliers). */
static MAGCAL_NOINLINE magcal_status_t ph_cov_f(magcal_calibrator_t *cal, cal_run_t *r)
{
    cal_prep_t *q = cal_prep(cal);
    if (cal_cover_pass(cal, r, 1) == 0) {
        return MAGCAL_IN_PROGRESS;
    }
    if (magcal_cal_coverage_of(q->bins, NULL, NULL) < cal->cfg.min_coverage_deg) {
        r->rep.filter_fragmented = 1u;
    }
    (void)magcal_cal_spend(&r->bud, CAL_W_COVFIN);
    (void)memset(&r->cres, 0, sizeof r->cres);
    cal_goto(r, cal->cfg.use_consensus == 0u ? PH_PLAIN : PH_THIN);
    return MAGCAL_OK;
}

/* ------------------------------------------------------------------ fit */

/* Minimal sets from one candidate per clump (optics.h magcal_optics_thin): samples of a vehicle
 * parked at one heading must not fill the draws; flags hold the thinned mask meanwhile. */
static MAGCAL_NOINLINE magcal_status_t ph_thin(magcal_calibrator_t *cal, cal_run_t *r)
{
    magcal_status_t st = MAGCAL_ERR_ARG;
    if (r->sub == 0u) {
        const uint8_t *cand = r->rep.filter_fragmented != 0u ? NULL : cal->mask_a;
        r->cand = (uint8_t)(r->rep.filter_fragmented != 0u ? 0u : 1u);
        if (cal->n >= 16u) {
            st = magcal_optics_thin_begin(&r->u.thin, cal->buf, cal->n, cand, cal->scratch,
                                          cal->scratch_len, cal->flags);
        }
        r->sub = 1u;
        if (st == MAGCAL_OK) {
            r->sub = 2u;
        }
    }
    if (r->sub == 2u) {
        st = cal_module_done(r, magcal_optics_thin_step(&r->u.thin, cal_left(r)), CAL_W_ONESHOT);
        if (st == MAGCAL_IN_PROGRESS) {
            return st;
        }
        if (st == MAGCAL_OK) {
            r->cand = 2u;
        }
    }
    cal_goto(r, PH_CONS);
    return MAGCAL_OK;
}

/* 4. consensus into run->cres, inlier mask into mask_b. */
static MAGCAL_NOINLINE magcal_status_t ph_cons(magcal_calibrator_t *cal, cal_run_t *r)
{
    magcal_status_t st;
    if (r->sub == 0u) {
        const uint8_t *cand = r->cand == 0u ? NULL : (r->cand == 1u ? cal->mask_a : cal->flags);
        st = magcal_consensus_begin(&r->u.cons, &cal->cfg.consensus, cal->buf, cal->n, cand,
                                    cal->scratch, MAGCAL_CONSENSUS_WORKSPACE_LEN(cal->capacity),
                                    cal->mask_b, &r->cres);
        r->sub = 1u;
        if (st != MAGCAL_OK) {
            r->held = st;
            cal_goto(r, PH_FLAGS0);
            return MAGCAL_OK;
        }
    }
    st = magcal_consensus_step(&r->u.cons, cal_left(r));
    st = cal_module_done(r, st, r->u.cons.used_);
    if (st == MAGCAL_IN_PROGRESS) {
        return st;
    }
    r->held = st;
    cal_goto(r, PH_FLAGS0);
    return MAGCAL_OK;
}

/* The filter flags again (the thinning used the flags; the gates set the residual bits). After a
 * clean pre-test no sample is a filter reject: mask_a becomes all ones (the consensus rejects are
 * residual rejects, counted as such by the gates). */
static MAGCAL_NOINLINE magcal_status_t ph_flags0(magcal_calibrator_t *cal, cal_run_t *r)
{
    while (r->i < cal->n) {
        const size_t i = r->i;
        if (r->pre != 0u) {
            cal->mask_a[i] = 1u;
        }
        cal->flags[i] = cal->mask_a[i] == 0u
                            ? (uint8_t)(MAGCAL_CALIBRATOR_FLAG_JUDGED | MAGCAL_CALIBRATOR_FLAG_FILTER)
                            : (uint8_t)MAGCAL_CALIBRATOR_FLAG_JUDGED;
        r->i++;
        if (magcal_cal_spend(&r->bud, CAL_W_FLAG) != 0) {
            return MAGCAL_IN_PROGRESS;
        }
    }
    cal->n_judged = cal->n;
    if (r->held != MAGCAL_OK) {
        return r->held;
    }
    cal_goto(r, PH_GATES);
    return MAGCAL_OK;
}

/* Plain least-squares fit of the filter inliers (use_consensus = 0). */
static MAGCAL_NOINLINE magcal_status_t ph_plain(magcal_calibrator_t *cal, cal_run_t *r)
{
    magcal_ellipse_fit_slice_t *es = cal_plain_slice(cal);
    magcal_status_t st;
    if (r->sub == 0u) {
        st = magcal_ellipse_fit_begin(es, cal->buf, cal->n, cal->mask_a, &r->cres.fit);
        if (st != MAGCAL_OK) {
            return st;
        }
        r->sub = 1u;
    }
    st = magcal_ellipse_fit_step(es, cal_left(r));
    st = cal_module_done(r, st, es->used_);
    if (st != MAGCAL_OK) {
        return st; /* MAGCAL_IN_PROGRESS, or the fit's failure */
    }
    cal_goto(r, PH_PLAIN_MASK);
    r->m = 0u;
    return MAGCAL_OK;
}

/* Its mask and the classify() threshold: k_sigma * residual RMS, clamped like the consensus's. */
static MAGCAL_NOINLINE magcal_status_t ph_plain_mask(magcal_calibrator_t *cal, cal_run_t *r)
{
    magcal_consensus_result_t *res = &r->cres;
    float rm;
    float thr;
    while (r->i < cal->n) {
        const size_t i = r->i;
        cal->mask_b[i] = cal->mask_a[i];
        if (cal->mask_a[i] != 0u) {
            r->m++;
        }
        r->i++;
        if (magcal_cal_spend(&r->bud, CAL_W_FLAG) != 0) {
            return MAGCAL_IN_PROGRESS;
        }
    }
    rm = sqrtf(res->fit.semi_minor * res->fit.semi_major);
    thr = cal->cfg.consensus.k_sigma * res->fit.residual_rms;
    thr = fmaxf(thr, cal->cfg.consensus.min_thr_rel * rm);
    thr = fminf(thr, cal->cfg.consensus.max_thr_rel * rm);
    res->sigma = res->fit.residual_rms;
    res->threshold = thr;
    res->n_candidates = (uint16_t)r->m;
    res->n_inliers = (uint16_t)r->m;
    res->n_rescued = 0u;
    res->n_rejected = 0u;
    cal_goto(r, PH_GATES);
    return MAGCAL_OK;
}

/* ------------------------------------------------------------------ gates */

/* 4 (cont.) and 5: keep the fit, flags with residual bits, counts, the report, gates. */
static MAGCAL_NOINLINE magcal_status_t ph_gates(magcal_calibrator_t *cal, cal_run_t *r)
{
    const magcal_consensus_result_t *cres = &r->cres;
    magcal_cal_report_t *rep = &r->rep;
    const size_t n = cal->n;
    size_t n_out;
    float radius;
    if (r->sub == 0u) {
        cal->fit = cres->fit;
        cal->threshold = cres->threshold;
        cal->has_fit = 1u;
        r->m = 0u; /* used */
        r->sub = 1u;
    }
    while (r->i < n) {
        const size_t i = r->i;
        uint8_t f = MAGCAL_CALIBRATOR_FLAG_JUDGED;
        if (cal->mask_a[i] == 0u) {
            f = (uint8_t)(f | MAGCAL_CALIBRATOR_FLAG_FILTER);
        }
        if (cal->mask_b[i] == 0u) {
            f = (uint8_t)(f | MAGCAL_CALIBRATOR_FLAG_RESIDUAL);
        }
        cal->flags[i] = f;
        if (cal->mask_b[i] != 0u) {
            r->m++;
            if (cal->mask_a[i] == 0u) {
                rep->rescued_consensus++;
            }
        } else if (cal->mask_a[i] != 0u) {
            rep->rejected_consensus++;
        } else {
            /* rejected by the filter and by the consensus */
        }
        r->i++;
        if (magcal_cal_spend(&r->bud, CAL_W_GATES) != 0) {
            return MAGCAL_IN_PROGRESS;
        }
    }
    cal->n_judged = n;
    rep->used = (uint16_t)r->m;
    rep->outliers = (uint16_t)(n - r->m);
    rep->ellipse = cres->fit;
    rep->threshold = cres->threshold;
    radius = sqrtf(cres->fit.semi_minor * cres->fit.semi_major);
    rep->radius = radius;
    rep->residual_rms = cres->fit.residual_rms;
    rep->residual_rel = radius > 0.0f ? cres->fit.residual_rms / radius : INFINITY;
    rep->axis_ratio =
        cres->fit.semi_major > 0.0f ? cres->fit.semi_minor / cres->fit.semi_major : 0.0f;
    rep->min_pivot = cres->fit.min_pivot;

    /* 5. gates */
    n_out = n - r->m;
    if (r->m < cal->cfg.min_samples) {
        return MAGCAL_ERR_TOO_FEW_POINTS;
    }
    if ((float)n_out > cal->cfg.max_outlier_frac * (float)n) {
        return MAGCAL_ERR_TOO_MANY_OUTLIERS;
    }
    if ((cal->cfg.min_radius > 0.0f && radius < cal->cfg.min_radius) ||
        (cal->cfg.max_radius > 0.0f && radius > cal->cfg.max_radius)) {
        return MAGCAL_ERR_RADIUS_RANGE;
    }
    if (rep->axis_ratio < cal->cfg.min_axis_ratio) {
        return MAGCAL_ERR_AXIS_RATIO;
    }
    if (!(rep->residual_rel <= cal->cfg.max_residual_rel)) {
        return MAGCAL_ERR_RESIDUAL;
    }
    cal_goto(r, PH_TOCAL);
    return MAGCAL_OK;
}


/* ------------------------------------------------------------------ coarse stage */

/* The coarse stage's residual pass (resumable at r->i): the squared residuals around the circle
 * of the samples `mask` keeps into q->ss, their count into r->m. 1 while paused (budget). */
static int cal_coarse_res_pass(const magcal_calibrator_t *cal, cal_run_t *r, cal_prep_t *q, const uint8_t *mask)
{
    int paused = 0;
    while (paused == 0 && r->i < cal->n) {
        const size_t i = r->i;
        r->i++;
        if (mask[i] != 0u) {
            const float e = cal_coarse_res(q, cal->buf[i]);
            q->ss += e * e;
            r->m++;
            paused = magcal_cal_spend(&r->bud, CAL_W_CO_RES);
        } else {
            paused = magcal_cal_spend(&r->bud, CAL_W_FLAG); /* not an inlier */
        }
    }
    return paused;
}

/* Coarse 1: residual RMS of the inliers (mask_a) around the circle, then the residual threshold
 * as the consensus sets it (k_sigma x RMS, clamped to [min_thr_rel, max_thr_rel] x radius). */
static MAGCAL_NOINLINE magcal_status_t ph_co_res(magcal_calibrator_t *cal, cal_run_t *r)
{
    cal_prep_t *q = cal_prep(cal);
    const magcal_consensus_cfg_t *cc = &cal->cfg.consensus;
    float thr;
    if (r->sub == 0u) {
        r->m = 0u;
        r->sub = 1u;
    }
    if (cal_coarse_res_pass(cal, r, q, cal->mask_a) != 0) {
        return MAGCAL_IN_PROGRESS;
    }
    if (r->m < cal->cfg.min_samples) {
        return MAGCAL_ERR_TOO_FEW_POINTS;
    }
    thr = cc->k_sigma * sqrtf(q->ss / (float)r->m);
    thr = fmaxf(thr, cc->min_thr_rel * q->cr);
    q->thr = fminf(thr, cc->max_thr_rel * q->cr);
    (void)memset(q->a, 0, sizeof q->a);
    (void)memset(q->b, 0, sizeof q->b);
    cal_goto(r, PH_CO_GATE);
    r->m = 0u;
    return MAGCAL_OK;
}

/* Coarse 2: inliers within the threshold into mask_b (flags with the residual bit), and the
 * circle's normal equations of them (the centred, scaled frame of ph_moments). */
static MAGCAL_NOINLINE magcal_status_t ph_co_gate(magcal_calibrator_t *cal, cal_run_t *r)
{
    cal_prep_t *q = cal_prep(cal);
    while (r->i < cal->n) {
        const size_t i = r->i;
        uint8_t in = 0u;
        r->i++;
        if (cal->mask_a[i] != 0u && fabsf(cal_coarse_res(q, cal->buf[i])) <= q->thr) {
            const float u = (cal->buf[i].x - q->mx) / q->s;
            const float v = (cal->buf[i].y - q->my) / q->s;
            const float y = -(u * u + v * v);
            const float w[3] = {u, v, 1.0f};
            size_t e;
            size_t c;
            for (e = 0u; e < 3u; ++e) {
                for (c = 0u; c <= e; ++c) {
                    q->a[e * 3u + c] += w[e] * w[c];
                }
                q->b[e] += w[e] * y;
            }
            in = 1u;
            r->m++;
        }
        cal->mask_b[i] = in;
        cal->flags[i] = (uint8_t)(MAGCAL_CALIBRATOR_FLAG_JUDGED |
                                  (cal->mask_a[i] == 0u ? MAGCAL_CALIBRATOR_FLAG_FILTER : 0u) |
                                  (in == 0u ? MAGCAL_CALIBRATOR_FLAG_RESIDUAL : 0u));
        if (magcal_cal_spend(&r->bud, CAL_W_CO_GATE) != 0) {
            return MAGCAL_IN_PROGRESS;
        }
    }
    cal->n_judged = cal->n;
    if (r->m < cal->cfg.min_samples || r->m < 3u) {
        return MAGCAL_ERR_TOO_FEW_POINTS;
    }
    cal_goto(r, PH_CO_FIT);
    return MAGCAL_OK;
}

/* Coarse 3: the refitted circle, its residual RMS (a pass), the report, the gates of the full
 * solve that apply to a circle, and the calibration (offset = centre, matrix = output scale). */
static MAGCAL_NOINLINE magcal_status_t ph_co_fit(magcal_calibrator_t *cal, cal_run_t *r)
{
    cal_prep_t *q = cal_prep(cal);
    cal_adopt_t *d = cal_adopt(cal);
    magcal_cal_report_t *rep = &r->rep;
    float scale;
    if (r->sub == 0u) {
        magcal_status_t st = magcal_ldlt_solve(q->a, q->b, 3u, 1.0e-6f, NULL);
        (void)magcal_cal_spend(&r->bud, CAL_W_CO_FIT);
        if (st != MAGCAL_OK) {
            return st == MAGCAL_ERR_ILL_CONDITIONED ? MAGCAL_ERR_DEGENERATE : st;
        }
        q->cc.x = q->mx - 0.5f * q->b[0] * q->s;
        q->cc.y = q->my - 0.5f * q->b[1] * q->s;
        if (cal_coarse_radius(q) == 0) {
            return MAGCAL_ERR_DEGENERATE;
        }
        q->ss = 0.0f;
        r->m = 0u;
        r->sub = 1u;
    }
    if (cal_coarse_res_pass(cal, r, q, cal->mask_b) != 0) {
        return MAGCAL_IN_PROGRESS;
    }
    rep->used = (uint16_t)r->m;
    rep->outliers = (uint16_t)(cal->n - r->m);
    rep->threshold = q->thr;
    rep->radius = q->cr;
    rep->residual_rms = sqrtf(q->ss / (float)r->m);
    rep->residual_rel = rep->residual_rms / q->cr;
    rep->axis_ratio = 1.0f;
    (void)memset(&rep->ellipse, 0, sizeof rep->ellipse);
    rep->ellipse.center = q->cc;
    rep->ellipse.semi_minor = q->cr;
    rep->ellipse.semi_major = q->cr;
    rep->ellipse.residual_rms = rep->residual_rms;
    if ((float)rep->outliers > cal->cfg.max_outlier_frac * (float)cal->n) {
        return MAGCAL_ERR_TOO_MANY_OUTLIERS;
    }
    if ((cal->cfg.min_radius > 0.0f && q->cr < cal->cfg.min_radius) ||
        (cal->cfg.max_radius > 0.0f && q->cr > cal->cfg.max_radius)) {
        return MAGCAL_ERR_RADIUS_RANGE;
    }
    if (!(rep->residual_rel <= cal->cfg.max_residual_rel)) {
        return MAGCAL_ERR_RESIDUAL;
    }
    scale = cal->cfg.output_radius > 0.0f ? cal->cfg.output_radius / q->cr : 1.0f;
    d->next.offset = q->cc;
    d->next.m[0][0] = scale;
    d->next.m[0][1] = 0.0f;
    d->next.m[1][0] = 0.0f;
    d->next.m[1][1] = scale;
    d->next.radius = q->cr * scale;
    d->next.magic = MAGCAL_CAL2D_MAGIC;
    rep->cal = d->next;
    cal_goto(r, PH_COVC);
    return MAGCAL_OK;
}

/* ------------------------------------------------------------------ adopt */

/* 6. the correction of the new fit. */
static MAGCAL_NOINLINE magcal_status_t ph_tocal(magcal_calibrator_t *cal, cal_run_t *r)
{
    cal_adopt_t *d = cal_adopt(cal);
    magcal_status_t st = magcal_ellipse_to_cal(&r->cres.fit, cal->cfg.form, cal->cfg.output_radius,
                                               &d->next);
    (void)magcal_cal_spend(&r->bud, CAL_W_TOCAL);
    if (st != MAGCAL_OK) {
        return st;
    }
    r->rep.cal = d->next;
    cal_goto(r, PH_COVC);
    return MAGCAL_OK;
}

/* Final coverage: bins of the corrected headings of the consensus inliers. */
static MAGCAL_NOINLINE magcal_status_t ph_covc(magcal_calibrator_t *cal, cal_run_t *r)
{
    cal_adopt_t *d = cal_adopt(cal);
    magcal_cal_report_t *rep = &r->rep;
    float cov;
    if (r->sub == 0u) {
        (void)memset(d->bins, 0, sizeof d->bins);
        r->sub = 1u;
    }
    while (r->i < cal->n) {
        const size_t i = r->i;
        magcal_vec2_t h;
        r->i++;
        if (cal->mask_b[i] != 0u) {
            if (magcal_correct_apply(&d->next, cal->buf[i], &h) == MAGCAL_OK) {
                d->bins[magcal_cal_bin_of(magcal_cal_angle_deg(h.x, h.y))] = 1u;
            }
            if (magcal_cal_spend(&r->bud, CAL_W_COVCORR) != 0) {
                return MAGCAL_IN_PROGRESS;
            }
        } else if (magcal_cal_spend(&r->bud, CAL_W_FLAG) != 0) {
            return MAGCAL_IN_PROGRESS;
        } else {
            /* not an inlier */
        }
    }
    cov = magcal_cal_coverage_of(d->bins, &rep->missing_start_deg, &rep->missing_width_deg);
    rep->coverage_deg = cov;
    (void)magcal_cal_spend(&r->bud, CAL_W_COVFIN);
    if (cov < (rep->coarse != 0u ? cal->coarse_min_cov : cal->cfg.min_coverage_deg) || !(cov > 0.0f)) {
        return MAGCAL_ERR_COVERAGE;
    }
    cal_goto(r, PH_DIST);
    return MAGCAL_OK;
}

/* Distinct values of the inliers: duplicates factor and the quantisation floor. */
static MAGCAL_NOINLINE magcal_status_t ph_dist(magcal_calibrator_t *cal, cal_run_t *r)
{
    cal_adopt_t *d = cal_adopt(cal);
    magcal_cal_report_t *rep = &r->rep;
    magcal_cal_distinct_slice_t *ds = &d->u.dist;
    if (r->sub == 0u) {
        magcal_cal_distinct_begin(ds, cal->buf, cal->n, cal->mask_b, cal_est_idx(cal));
        r->sub = 1u;
    }
    if (magcal_cal_distinct_step(ds, &r->bud) == 0) {
        return MAGCAL_IN_PROGRESS;
    }
    d->distinct = ds->distinct;
    d->dup = ds->distinct > 0u ? (float)rep->used / (float)ds->distinct : 1.0f;
    if (d->dup < 1.0f) {
        d->dup = 1.0f;
    }
    rep->distinct = (uint16_t)ds->distinct;
    /* quantisation: a lattice of few distinct values can lie on a conic far from the truth with
     * almost no residual; its heading noise is at least that of a uniform error of one step */
    d->floor_rel = rep->radius > 0.0f ? ds->step / (rep->radius * 3.4641016f) : 0.0f;
    cal_goto(r, PH_HARM_N);
    return MAGCAL_OK;
}

/* Coarse stage: the circle calibration's heading-error bound from its own harmonics (calibrator.h
 * "Coarse stage"): sqrt(1/2 |beta|^2) + |beta|^2 + 3 x the noise part's RMS + bias (with repeated values the
 * noise part's upper confidence factor, as the full gate), gated by the tolerance. */
static magcal_status_t cal_coarse_bound(const magcal_calibrator_t *cal, cal_run_t *r, const cal_adopt_t *d)
{
    magcal_cal_report_t *rep = &r->rep;
    const magcal_cal_harm_t *hn = &d->hn;
    const float noise = hn->sigma_rel;
    float npart = sqrtf(hn->noise2);
    float bound;
    if (d->distinct < (size_t)rep->used) {
        const float dof = d->distinct > 6u ? (float)d->distinct - 5.0f : 1.0f;
        npart *= 1.0f + 1.0f / sqrtf(2.0f * dof);
    }
    /* + 2 err2: the second-order allowance (the harmonics are the first-order terms of |h| in the
     * centre and soft-iron errors; the next term is O(|beta|^2): 1 x err2 was measured short on
     * tests/test_continuous.c's strong soft iron once the sliced drain changed which samples the
     * circle saw (bound 9.13 deg, truth 9.19): twice it, so the stated bound is an upper one) */
    bound = sqrtf(hn->err2) + 2.0f * hn->err2 + 3.0f * npart + sqrtf(hn->bias2);
    rep->est_noise_deg = MAGCAL_DEG_PER_RAD_F * noise;
    rep->design_factor = hn->design;
    rep->est_param_err_deg = MAGCAL_DEG_PER_RAD_F * bound;
    rep->est_heading_err_deg = MAGCAL_DEG_PER_RAD_F * sqrtf(noise * noise + bound * bound);
    if (!(rep->est_param_err_deg <= cal->coarse_max_err)) {
        return MAGCAL_ERR_UNOBSERVABLE; /* the arc does not bound the unseen soft iron well enough */
    }
    cal_goto(r, PH_VALID);
    return MAGCAL_OK;
}

/* Estimates of the new calibration (report fields est_*) and the observability gate. */
static MAGCAL_NOINLINE magcal_status_t ph_harm_n(magcal_calibrator_t *cal, cal_run_t *r)
{
    cal_adopt_t *d = cal_adopt(cal);
    magcal_cal_report_t *rep = &r->rep;
    const magcal_cal_harm_t *hn = &d->hn;
    const size_t distinct = d->distinct;
    float noise;
    float par;
    if (r->sub == 0u) {
        magcal_cal_harm_begin(&d->u.harm, cal->buf, cal->n, cal->mask_b, &d->next, d->dup,
                              d->floor_rel, cal_est_scratch(cal), &d->hn);
        r->sub = 1u;
    }
    if (magcal_cal_harm_step(&d->u.harm, &r->bud) == 0) {
        return MAGCAL_IN_PROGRESS;
    }
    if (hn->ok == 0u) {
        return MAGCAL_ERR_UNOBSERVABLE; /* headings too clumped to separate centre and soft iron */
    }
    if (rep->coarse != 0u) {
        return cal_coarse_bound(cal, r, d);
    }
    /* per-sample heading noise of new data: the relative radial residual after the harmonics
     * (the fit's own residual, dof corrected); tangential and radial noise have the same RMS
     * over uniformly spread headings */
    noise = hn->sigma_rel;
    rep->est_noise_deg = MAGCAL_DEG_PER_RAD_F * noise;
    rep->design_factor = hn->design;
    rep->est_param_err_deg = MAGCAL_DEG_PER_RAD_F * sqrtf(hn->noise2 + hn->bias2);
    rep->est_heading_err_deg = MAGCAL_DEG_PER_RAD_F * sqrtf(noise * noise + hn->noise2 + hn->bias2);
    /* repeated values (quantisation): the estimate rests on the distinct values only, so the
     * gate uses its upper confidence bound, (1 + 1 / sqrt(2 dof)) with dof = distinct - 5 */
    par = sqrtf(hn->noise2 + hn->bias2);
    if (distinct < (size_t)rep->used) {
        float dof = distinct > 6u ? (float)distinct - 5.0f : 1.0f;
        par *= 1.0f + 1.0f / sqrtf(2.0f * dof);
    }
    if (!(par <= cal->cfg.max_param_err_ratio * noise) ||
        !(hn->design <= cal->cfg.max_design_factor)) {
        return MAGCAL_ERR_UNOBSERVABLE;
    }
    cal_goto(r, PH_VALID);
    return MAGCAL_OK;
}

/* 2x2 inverse of a calibration matrix. */
static int cal_inv2(const float m[2][2], float inv[2][2])
{
    float det = m[0][0] * m[1][1] - m[0][1] * m[1][0];
    if (!(fabsf(det) > 0.0f) || !magcal_isfinite_f(det)) {
        return -1;
    }
    inv[0][0] = m[1][1] / det;
    inv[0][1] = -m[0][1] / det;
    inv[1][0] = -m[1][0] / det;
    inv[1][1] = m[0][0] / det;
    return 0;
}

/* 7. adoption rule (file comment of calibrator.h): an unusable installed calibration is replaced
 * (after the shift from the identity). */
static MAGCAL_NOINLINE magcal_status_t ph_valid(const magcal_calibrator_t *cal, const magcal_cal2d_t *current, cal_run_t *r)
{
    cal_adopt_t *d = cal_adopt(cal);
    d->unusable = (uint8_t)((magcal_cal2d_validate(current) != MAGCAL_OK || !(current->radius > 0.0f))
                                ? 1u
                                : 0u);
    cal_goto(r, PH_SHIFT);
    d->sh_mx = 0.0f;
    d->sh_ss = 0.0f;
    d->sh_cnt = 0u;
    (void)magcal_cal_spend(&r->bud, CAL_W_PHASE);
    return MAGCAL_OK;
}

/* sin and cos of k * 5 deg, k < 72 (quadrant q = k / 18, j = k % 18): the shift's test headings
 * are multiples of 5 deg (CAL_SHIFT_STEPS), so their sines and cosines come from a quarter-wave
 * table of sin(5 j deg), j = 0..18, instead of sinf/cosf (whose argument reduction is ~3 KB of
 * flash). */
static void cal_sincos5(size_t k, float *sn, float *cs)
{
    static const float cal_sin5[19] = {
        0.000000000e+00f, 8.715574275e-02f, 1.736481777e-01f, 2.588190451e-01f, 3.420201433e-01f,
        4.226182617e-01f, 5.000000000e-01f, 5.735764364e-01f, 6.427876097e-01f, 7.071067812e-01f,
        7.660444431e-01f, 8.191520443e-01f, 8.660254038e-01f, 9.063077870e-01f, 9.396926208e-01f,
        9.659258263e-01f, 9.848077530e-01f, 9.961946981e-01f, 1.000000000e+00f};
    size_t q = k / 18u;
    size_t j = k % 18u;
    float a = cal_sin5[j];
    float b = cal_sin5[18u - j];
    switch (q) {
    case 0u:
        *sn = a;
        *cs = b;
        break;
    case 1u:
        *sn = b;
        *cs = -a;
        break;
    case 2u:
        *sn = -a;
        *cs = -b;
        break;
    default:
        *sn = -b;
        *cs = a;
        break;
    }
}

/* cppcheck-suppress misra-c2012-2.3 ; deviation D4: a static assert is an unused typedef */
MAGCAL_STATIC_ASSERT(CAL_SHIFT_STEPS == 72u, shift_steps_match_sine_table);

/* Heading change if `next` replaced `current` (unusable: from the identity), one test heading
 * per visit. */
static MAGCAL_NOINLINE magcal_status_t ph_shift(const magcal_calibrator_t *cal, const magcal_cal2d_t *current, cal_run_t *r)
{
    cal_adopt_t *d = cal_adopt(cal);
    const magcal_cal2d_t *next = &d->next;
    const magcal_cal2d_t *cur = d->unusable != 0u ? NULL : current;
    float rr = next->radius > 0.0f ? next->radius : 1.0f;
    int singular = 0;
    if (r->sub == 0u) {
        singular = cal_inv2(next->m, d->inv);
        r->sub = 1u;
    }
    while (singular == 0 && r->i < CAL_SHIFT_STEPS) {
        const size_t k = r->i;
        float psi = (float)k * (360.0f / (float)CAL_SHIFT_STEPS);
        float sp;
        float cp;
        float hx;
        float hy;
        magcal_vec2_t raw;
        magcal_vec2_t h;
        float ph;
        int ok = 1;
        r->i++;
        cal_sincos5(k, &sp, &cp);
        hx = -rr * sp;
        hy = rr * cp;
        raw.x = d->inv[0][0] * hx + d->inv[0][1] * hy + next->offset.x;
        raw.y = d->inv[1][0] * hx + d->inv[1][1] * hy + next->offset.y;
        if (cur == NULL) {
            h = raw;
        } else if (magcal_correct_apply(cur, raw, &h) != MAGCAL_OK) {
            ok = 0;
        } else {
            /* corrected by the installed calibration */
        }
        if (ok != 0 && magcal_heading_from_field(h, &ph) == MAGCAL_OK) {
            float dd = fabsf(magcal_wrap180_deg(ph - psi));
            d->sh_mx = fmaxf(d->sh_mx, dd);
            d->sh_ss += dd * dd;
            d->sh_cnt++;
        }
        if (magcal_cal_spend(&r->bud, CAL_W_SHIFT) != 0) {
            return MAGCAL_IN_PROGRESS;
        }
    }
    if (singular != 0) {
        r->rep.shift_max_deg = NAN;
        r->rep.shift_rms_deg = NAN;
    } else {
        r->rep.shift_max_deg = d->sh_mx;
        r->rep.shift_rms_deg = d->sh_cnt > 0u ? sqrtf(d->sh_ss / (float)d->sh_cnt) : NAN;
    }
    cal_goto(r, PH_HARM_C);
    return MAGCAL_OK;
}

/* Harmonics of the installed calibration on the new inliers, then the rule. */
static MAGCAL_NOINLINE magcal_status_t ph_harm_c(magcal_cal2d_t *current, magcal_calibrator_t *cal, cal_run_t *r)
{
    cal_adopt_t *d = cal_adopt(cal);
    magcal_cal_report_t *rep = &r->rep;
    const magcal_cal_harm_t *hc = &d->hc;
    if (d->unusable != 0u) {
        rep->adopt_rule = MAGCAL_ADOPT_UNUSABLE;
        *current = d->next;
        cal_goto(r, PH_DONE);
        return MAGCAL_OK;
    }
    if (r->sub == 0u) {
        magcal_cal_harm_begin(&d->u.harm, cal->buf, cal->n, cal->mask_b, current, d->dup,
                              d->floor_rel, cal_est_scratch(cal), &d->hc);
        r->sub = 1u;
    }
    if (magcal_cal_harm_step(&d->u.harm, &r->bud) == 0) {
        return MAGCAL_IN_PROGRESS;
    }
    if (hc->ok == 0u) {
        /* the current calibration maps the new inliers onto a point or leaves no usable radius */
        rep->current_err_deg = INFINITY;
        rep->current_err_z = INFINITY;
    } else {
        float ex = hc->err2 - hc->noise2; /* noise-free mean square error of `current` */
        rep->current_err_deg = MAGCAL_DEG_PER_RAD_F * sqrtf(fmaxf(ex, 0.0f));
        rep->current_err_z =
            hc->noise2_sd > 0.0f ? ex / hc->noise2_sd : (ex > 0.0f ? INFINITY : 0.0f);
    }
    if (rep->coarse != 0u && cal->current_coarse == 0u) {
        return MAGCAL_ERR_NOT_BETTER; /* a coarse calibration never replaces a full one */
    }
    if (rep->current_err_deg > fmaxf((cal->current_coarse != 0u && rep->coarse == 0u ? 1.0f
                                                                                    : MAGCAL_CALIBRATOR_ADOPT_MARGIN) *
                                         rep->est_param_err_deg,
                                     MAGCAL_CALIBRATOR_ADOPT_MIN_DEG)) {
        /* a full calibration replaces a coarse one when not estimated worse (margin 1) */
        rep->adopt_rule = MAGCAL_ADOPT_BETTER;
    } else if (rep->current_err_z > MAGCAL_CALIBRATOR_STALE_Z &&
               rep->current_err_deg >= rep->est_param_err_deg &&
               rep->current_err_deg > MAGCAL_CALIBRATOR_ADOPT_MIN_DEG && hc->ok != 0u &&
               fabsf(hc->mean_radius / current->radius - 1.0f) <= cal->cfg.max_radius_change) {
        rep->adopt_rule = MAGCAL_ADOPT_STALE;
    } else {
        return MAGCAL_ERR_NOT_BETTER;
    }
    *current = d->next;
    cal_goto(r, PH_DONE);
    return MAGCAL_OK;
}

/* ------------------------------------------------------------------ driver */

/* One phase (each a separate function: only the deepest phase's frame sits under step()). */
static MAGCAL_NOINLINE magcal_status_t cal_phase(magcal_calibrator_t *cal, cal_run_t *r,
                                                 magcal_cal2d_t *current)
{
    switch ((cal_phase_t)r->phase) {
    case PH_BBOX: return ph_bbox(cal, r);
    case PH_CHECK: return ph_check(cal, r);
    case PH_IDENT: return ph_ident(cal, r);
    case PH_EXTENT: return ph_extent(cal, r);
    case PH_PRE_CONS: return ph_pre_cons(cal, r);
    case PH_PRE_MASK: return ph_pre_mask(cal, r);
    case PH_FILTER: return ph_filter(cal, r);
    case PH_FILTER_RUN: return ph_filter_run(r);
    case PH_MASKS: return ph_masks(cal, r);
    case PH_MEAN: return ph_mean(cal, r);
    case PH_SCALE: return ph_scale(cal, r);
    case PH_MOMENTS: return ph_moments(cal, r);
    case PH_CIRCLE: return ph_circle(cal, r);
    case PH_COV_ALL: return ph_cov_all(cal, r);
    case PH_COV_F: return ph_cov_f(cal, r);
    case PH_THIN: return ph_thin(cal, r);
    case PH_CONS: return ph_cons(cal, r);
    case PH_FLAGS0: return ph_flags0(cal, r);
    case PH_PLAIN: return ph_plain(cal, r);
    case PH_PLAIN_MASK: return ph_plain_mask(cal, r);
    case PH_GATES: return ph_gates(cal, r);
    case PH_CO_RES: return ph_co_res(cal, r);
    case PH_CO_GATE: return ph_co_gate(cal, r);
    case PH_CO_FIT: return ph_co_fit(cal, r);
    case PH_TOCAL: return ph_tocal(cal, r);
    case PH_COVC: return ph_covc(cal, r);
    case PH_DIST: return ph_dist(cal, r);
    case PH_HARM_N: return ph_harm_n(cal, r);
    case PH_VALID: return ph_valid(cal, current, r);
    case PH_SHIFT: return ph_shift(cal, current, r);
    case PH_HARM_C: return ph_harm_c(current, cal, r);
    default: return MAGCAL_OK; /* PH_DONE */
    }
}

/* The end of a solve: state, status and report as run() sets them. */
static magcal_status_t cal_finish(magcal_calibrator_t *cal, cal_run_t *r, magcal_status_t st,
                                  magcal_cal_report_t *out)
{
    magcal_cal_report_t *rep = &r->rep;
    r->active = 0u;
    rep->status = st;
    if (st == MAGCAL_OK) {
        cal->state = MAGCAL_CALIBRATOR_CALIBRATED;
        rep->adopted = 1u;
    } else {
        cal->state = MAGCAL_CALIBRATOR_FAILED;
        rep->adopted = 0u;
    }
    cal->last_status = st;
    rep->state = cal->state;
    if (out != NULL) {
        *out = *rep;
    }
    return st;
}

magcal_status_t magcal_calibrator_solve_begin(magcal_calibrator_t *cal, size_t n, int load_bbox)
{
    cal_run_t *r;
    magcal_cal_report_t *rep;
    if (cal == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (cal->magic != MAGCAL_CALIBRATOR_MAGIC) {
        return MAGCAL_ERR_NOT_INITIALISED;
    }
    if (n > cal->capacity) {
        return MAGCAL_ERR_ARG;
    }
    r = cal_run(cal);
    rep = &r->rep;
    cal->n = n;
    /* an empty report (estimates NaN: a failed run never reads as a perfect one), no fit,
     * nothing judged */
    (void)memset(rep, 0, sizeof *rep);
    rep->current_err_deg = NAN;
    rep->current_err_z = NAN;
    rep->est_heading_err_deg = NAN;
    rep->est_param_err_deg = NAN;
    rep->est_noise_deg = NAN;
    rep->adopt_rule = MAGCAL_ADOPT_NONE;
    rep->samples = (uint16_t)cal->n;
    cal->has_fit = 0u;
    cal->n_judged = 0u;
    cal_goto(r, load_bbox != 0 ? PH_BBOX : PH_CHECK);
    r->pre = 0u;
    r->active = 1u;
    return MAGCAL_OK;
}

void magcal_calibrator_set_coarse(magcal_calibrator_t *cal, float min_cov, float max_err_deg,
                                  uint8_t current_coarse)
{
    if (cal != NULL && cal->magic == MAGCAL_CALIBRATOR_MAGIC) {
        cal->coarse_min_cov = magcal_isfinite_f(min_cov) && min_cov > 0.0f ? min_cov : 0.0f;
        cal->coarse_max_err = magcal_isfinite_f(max_err_deg) ? max_err_deg : 0.0f;
        cal->current_coarse = current_coarse;
    }
}

int magcal_calibrator_solving(const magcal_calibrator_t *cal)
{
    return cal != NULL && cal->magic == MAGCAL_CALIBRATOR_MAGIC && cal_run(cal)->active != 0u;
}

magcal_status_t magcal_calibrator_solve_step(magcal_calibrator_t *cal, magcal_cal2d_t *current,
                                             uint32_t budget, magcal_cal_report_t *report)
{
    cal_run_t *r;
    size_t k;
    if (cal == NULL || current == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (cal->magic != MAGCAL_CALIBRATOR_MAGIC) {
        return MAGCAL_ERR_NOT_INITIALISED;
    }
    r = cal_run(cal);
    if (r->active == 0u) {
        return MAGCAL_ERR_STATE;
    }
    r->bud.unlimited = (uint8_t)(budget == UINT32_MAX ? 1u : 0u);
    r->bud.left = budget > 0u ? budget : 1u;
    /* bounded: phases only move forward (PH_DONE at most), each call of a phase either advances
     * it, ends the solve or returns with the budget spent */
    for (k = 0u; k <= (size_t)PH_DONE; ++k) {
        magcal_status_t st = cal_phase(cal, r, current);
        if (st == MAGCAL_IN_PROGRESS) {
            return MAGCAL_IN_PROGRESS;
        }
        if (st != MAGCAL_OK || r->phase == (uint8_t)PH_DONE) {
            return cal_finish(cal, r, st, report);
        }
        if (r->bud.unlimited == 0u && r->bud.left == 0u) {
            return MAGCAL_IN_PROGRESS;
        }
    }
    return MAGCAL_IN_PROGRESS;
}

magcal_status_t magcal_calibrator_run(magcal_calibrator_t *cal, magcal_cal2d_t *current,
                                      magcal_cal_report_t *report)
{
    magcal_status_t st;
    if (cal == NULL || current == NULL) {
        return MAGCAL_ERR_NULL;
    }
    st = magcal_calibrator_solve_begin(cal, cal->n, 0);
    if (st != MAGCAL_OK) {
        return st;
    }
    return magcal_calibrator_solve_step(cal, current, UINT32_MAX, report);
}

#ifdef MAGCAL_BENCH_TRACE
/* Bench-only (tools/bench/m4f_image cont_trace.elf, never in a shipped build): the solve's phase
 * (cal_phase_t; the consensus run's own phase << 8 inside PH_CONS) and the budget its last step
 * left, for the per-step trace of the continuous calibrator. */
unsigned magcal_bench_cons_phase(const magcal_consensus_slice_t *s);
unsigned magcal_bench_solve_phase(const magcal_calibrator_t *cal, uint32_t *left);
unsigned magcal_bench_solve_phase(const magcal_calibrator_t *cal, uint32_t *left)
{
    const cal_run_t *r = cal_run(cal);
    unsigned sub = 0xFFu;
    *left = r->bud.left;
    if (r->active == 0u) {
        return 0xFFFFu;
    }
    if (r->phase == (uint8_t)PH_CONS && r->sub != 0u) {
        sub = magcal_bench_cons_phase(&r->u.cons);
    }
    return (unsigned)r->phase | (sub << 8);
}
#endif
