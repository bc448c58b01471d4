/*
 * Internal interface of the 2-D calibrator's time-sliced solve (src/adopt/calibrator_solve*.c,
 * calibrator_prepare.c, calibrator_fit.c, calibrator_coarse.c, calibrator_judge.c): the phases,
 * the run state they share in the workspace, the per-visit weights, and one prototype per phase.
 * Not installed. The driver (calibrator_solve.c) dispatches on cal_phase_t; each phase lives in the
 * file of its stage:
 *   calibrator_prepare.c  pre-checks, pre-test, density filter, masks, mean, scale, moments, the
 *                         hard-iron circle, coverage of every sample and of the inliers;
 *   calibrator_fit.c      thinning + consensus or the plain fit, the flags, the gates;
 *   calibrator_coarse.c   the coarse stage (a hard-iron circle below the coverage gate, its own
 *                         whole-circle heading-error bound: calibrator.h "Coarse stage");
 *   calibrator_judge.c    the new calibration, its corrected coverage, distinct values, harmonics
 *                         (observability gate; an arc's whole-circle bound), the heading shift, the installed calibration's
 *                         harmonics and the adoption rule.
 */
#ifndef MAGCAL_CALIBRATOR_SOLVE_INTERNAL_H
#define MAGCAL_CALIBRATOR_SOLVE_INTERNAL_H

#include <stddef.h>
#include <stdint.h>

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
/* arc stage: one of the 36 headings of the whole-circle bound (two table sines, a 4x4 quadratic
 * form: ~40 multiply-adds, host estimate x 1.2) */
#define CAL_W_ARC 160u
#define CAL_ARC_HEADINGS 36u /* the bound's headings, every 10 degrees (cal_sincos5 index 2k) */
/* Where the harmonic analysis (calibrator_adopt.c) leaves the 4x4 block of (G^T G)^-1 over the
 * harmonics in its scratch once complete: behind the normal matrix, its work copy (5x5 each), the
 * coefficients and the column (5 each); the block is the scratch's last 16 floats. */
#define CAL_HARM_INV4 60u
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
    PH_ARC,
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
    float arc_v2;         /* arc stage: the largest heading-error variance over the headings */
} cal_adopt_t;


/* The workspace pointers of a const calibrator are `void *const`: their memory is writable. */
static inline cal_run_t *cal_run(const magcal_calibrator_t *cal)
{
    void *run = cal->run;
    return (cal_run_t *)run;
}

static inline cal_prep_t *cal_prep(const magcal_calibrator_t *cal)
{
    void *scratch = cal->scratch;
    return (cal_prep_t *)scratch;
}

/* p rounded up to the next multiple of 8 (pointer arithmetic from the workspace address; the
 * alignment is read by magcal_misalign, deviation D9). */
static inline uint8_t *cal_align8(void *p)
{
    const size_t mis = magcal_misalign(p, 8u);
    return (uint8_t *)p + ((mis == 0u) ? 0u : (8u - mis));
}

/* Scratch of the estimates: the harmonics' floats, then the distinct count's n indices. */
static inline float *cal_est_scratch(const magcal_calibrator_t *cal)
{
    void *scratch = cal->scratch;
    return (float *)scratch;
}

static inline uint16_t *cal_est_idx(const magcal_calibrator_t *cal)
{
    return (uint16_t *)(void *)(cal_est_scratch(cal) + MAGCAL_CAL_HARM_SCRATCH_FLOATS);
}

/* The plain fit's slice state: at the start of the stage scratch (8-aligned), unused by it. */
static inline magcal_ellipse_fit_slice_t *cal_plain_slice(const magcal_calibrator_t *cal)
{
    void *scratch = cal->scratch;
    return (magcal_ellipse_fit_slice_t *)(void *)cal_align8(scratch);
}

/* Budget left for a module's step (UINT32_MAX: to the end). */
static inline uint32_t cal_left(const cal_run_t *r) { return r->bud.unlimited != 0u ? UINT32_MAX : r->bud.left; }

/* After a module's step ended with st: IN_PROGRESS spends the budget; a final status charges
 * `used` (UINT32_MAX when the module does not report it: the step ends there). */
static inline magcal_status_t cal_module_done(cal_run_t *r, magcal_status_t st, uint32_t used)
{
    (void)magcal_cal_charge(&r->bud, st == MAGCAL_IN_PROGRESS ? CAL_W_ONESHOT : used);
    return st;
}

/* Behind the indices, 8-aligned (the cursors hold pointers and sizes). */
static inline cal_adopt_t *cal_adopt(const magcal_calibrator_t *cal)
{
    return (cal_adopt_t *)(void *)cal_align8(cal_est_idx(cal) + cal->capacity);
}

/* Go to phase ph (cursor and sub-state cleared). */
static inline void cal_goto(cal_run_t *r, cal_phase_t ph)
{
    r->phase = (uint8_t)ph;
    r->sub = 0u;
    r->i = 0u;
}

/* ------------------------------------------------------------------ phases (cal_phase_t order) */

/* calibrator_prepare.c */
magcal_status_t magcal_ph_bbox(magcal_calibrator_t *cal, cal_run_t *r);
magcal_status_t magcal_ph_check(magcal_calibrator_t *cal, cal_run_t *r);
magcal_status_t magcal_ph_ident(magcal_calibrator_t *cal, cal_run_t *r);
magcal_status_t magcal_ph_extent(magcal_calibrator_t *cal, cal_run_t *r);
magcal_status_t magcal_ph_pre_cons(magcal_calibrator_t *cal, cal_run_t *r);
magcal_status_t magcal_ph_pre_mask(magcal_calibrator_t *cal, cal_run_t *r);
magcal_status_t magcal_ph_filter(magcal_calibrator_t *cal, cal_run_t *r);
magcal_status_t magcal_ph_filter_run(cal_run_t *r);
magcal_status_t magcal_ph_masks(magcal_calibrator_t *cal, cal_run_t *r);
magcal_status_t magcal_ph_mean(magcal_calibrator_t *cal, cal_run_t *r);
magcal_status_t magcal_ph_scale(magcal_calibrator_t *cal, cal_run_t *r);
magcal_status_t magcal_ph_moments(magcal_calibrator_t *cal, cal_run_t *r);
magcal_status_t magcal_ph_circle(magcal_calibrator_t *cal, cal_run_t *r);
magcal_status_t magcal_ph_cov_all(magcal_calibrator_t *cal, cal_run_t *r);
magcal_status_t magcal_ph_cov_f(magcal_calibrator_t *cal, cal_run_t *r);

/* calibrator_fit.c (magcal_cal_inconsistent: the consistency gate, shared with the coarse stage) */
int magcal_cal_inconsistent(const magcal_calibrator_t *cal, size_t plausible, size_t rejected);
magcal_status_t magcal_ph_thin(magcal_calibrator_t *cal, cal_run_t *r);
magcal_status_t magcal_ph_cons(magcal_calibrator_t *cal, cal_run_t *r);
magcal_status_t magcal_ph_flags0(magcal_calibrator_t *cal, cal_run_t *r);
magcal_status_t magcal_ph_plain(magcal_calibrator_t *cal, cal_run_t *r);
magcal_status_t magcal_ph_plain_mask(magcal_calibrator_t *cal, cal_run_t *r);
magcal_status_t magcal_ph_gates(magcal_calibrator_t *cal, cal_run_t *r);

/* calibrator_coarse.c: the phases, the circle radius from the solved normal equations (ph_cov_all
 * enters the stage with it) and the whole-circle bound (ph_harm_n hands a coarse solve to it) */
magcal_status_t magcal_ph_co_res(magcal_calibrator_t *cal, cal_run_t *r);
magcal_status_t magcal_ph_co_gate(magcal_calibrator_t *cal, cal_run_t *r);
magcal_status_t magcal_ph_co_fit(magcal_calibrator_t *cal, cal_run_t *r);
int magcal_coarse_radius(cal_prep_t *q);
magcal_status_t magcal_coarse_bound(const magcal_calibrator_t *cal, cal_run_t *r, const cal_adopt_t *d);

/* calibrator_judge.c */
magcal_status_t magcal_ph_tocal(magcal_calibrator_t *cal, cal_run_t *r);
magcal_status_t magcal_ph_covc(magcal_calibrator_t *cal, cal_run_t *r);
magcal_status_t magcal_ph_dist(magcal_calibrator_t *cal, cal_run_t *r);
magcal_status_t magcal_ph_harm_n(magcal_calibrator_t *cal, cal_run_t *r);
magcal_status_t magcal_ph_arc(magcal_calibrator_t *cal, cal_run_t *r);
magcal_status_t magcal_ph_valid(const magcal_calibrator_t *cal, const magcal_cal2d_t *current, cal_run_t *r);
magcal_status_t magcal_ph_shift(const magcal_calibrator_t *cal, const magcal_cal2d_t *current, cal_run_t *r);
magcal_status_t magcal_ph_harm_c(magcal_cal2d_t *current, magcal_calibrator_t *cal, cal_run_t *r);

#endif /* MAGCAL_CALIBRATOR_SOLVE_INTERNAL_H */
