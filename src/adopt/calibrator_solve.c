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
 * This file is the driver (begin, step, run, the phase dispatch); the phases live in the files of
 * their stages (calibrator_solve_internal.h: prepare, fit, coarse, judge).
 */
#include <math.h>
#include <string.h>

#include "calibrator_solve_internal.h"

int magcal_cal_charge(magcal_cal_budget_t *b, uint32_t w) { return magcal_cal_spend(b, w); }

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

/* cppcheck-suppress misra-c2012-2.3 ; deviation D4: a static assert is an unused typedef */
MAGCAL_STATIC_ASSERT(CAL_HARM_INV4 + 16u == MAGCAL_CAL_HARM_SCRATCH_FLOATS, arc_reads_the_harmonics_inverse_block);

/* ------------------------------------------------------------------ driver */

/* One phase (each a separate function: only the deepest phase's frame sits under step()). */
static MAGCAL_NOINLINE magcal_status_t cal_phase(magcal_calibrator_t *cal, cal_run_t *r,
                                                 magcal_cal2d_t *current)
{
    switch ((cal_phase_t)r->phase) {
    case PH_BBOX: return magcal_ph_bbox(cal, r);
    case PH_CHECK: return magcal_ph_check(cal, r);
    case PH_IDENT: return magcal_ph_ident(cal, r);
    case PH_EXTENT: return magcal_ph_extent(cal, r);
    case PH_PRE_CONS: return magcal_ph_pre_cons(cal, r);
    case PH_PRE_MASK: return magcal_ph_pre_mask(cal, r);
    case PH_FILTER: return magcal_ph_filter(cal, r);
    case PH_FILTER_RUN: return magcal_ph_filter_run(r);
    case PH_MASKS: return magcal_ph_masks(cal, r);
    case PH_MEAN: return magcal_ph_mean(cal, r);
    case PH_SCALE: return magcal_ph_scale(cal, r);
    case PH_MOMENTS: return magcal_ph_moments(cal, r);
    case PH_CIRCLE: return magcal_ph_circle(cal, r);
    case PH_COV_ALL: return magcal_ph_cov_all(cal, r);
    case PH_COV_F: return magcal_ph_cov_f(cal, r);
    case PH_THIN: return magcal_ph_thin(cal, r);
    case PH_CONS: return magcal_ph_cons(cal, r);
    case PH_FLAGS0: return magcal_ph_flags0(cal, r);
    case PH_PLAIN: return magcal_ph_plain(cal, r);
    case PH_PLAIN_MASK: return magcal_ph_plain_mask(cal, r);
    case PH_GATES: return magcal_ph_gates(cal, r);
#if MAGCAL_CFG_ENABLE_COARSE
    case PH_CO_RES: return magcal_ph_co_res(cal, r);
    case PH_CO_GATE: return magcal_ph_co_gate(cal, r);
    case PH_CO_FIT: return magcal_ph_co_fit(cal, r);
#endif
    case PH_TOCAL: return magcal_ph_tocal(cal, r);
    case PH_COVC: return magcal_ph_covc(cal, r);
    case PH_DIST: return magcal_ph_dist(cal, r);
    case PH_HARM_N: return magcal_ph_harm_n(cal, r);
    case PH_ARC: return magcal_ph_arc(cal, r);
    case PH_VALID: return magcal_ph_valid(cal, current, r);
    case PH_SHIFT: return magcal_ph_shift(cal, current, r);
    case PH_HARM_C: return magcal_ph_harm_c(current, cal, r);
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

/* The arc stage's settings are in range (else the stage is off). */
static int cal_arc_args_ok(float min_cov, float max_err_deg, float model_deg)
{
    return (magcal_isfinite_f(min_cov) && min_cov > 0.0f && magcal_isfinite_f(max_err_deg) && max_err_deg > 0.0f &&
            magcal_isfinite_f(model_deg) && model_deg >= 0.0f)
               ? 1
               : 0;
}

void magcal_calibrator_set_arc(magcal_calibrator_t *cal, float min_cov, float max_err_deg, float model_deg)
{
    if (cal != NULL && cal->magic == MAGCAL_CALIBRATOR_MAGIC) {
        const int on = cal_arc_args_ok(min_cov, max_err_deg, model_deg);
        cal->arc_min_cov = on != 0 ? min_cov : 0.0f;
        cal->arc_max_err = on != 0 ? max_err_deg : 0.0f;
        cal->arc_model = on != 0 ? model_deg : 0.0f;
    }
}

void magcal_calibrator_set_model(magcal_calibrator_t *cal, float model_deg)
{
    if (cal != NULL && cal->magic == MAGCAL_CALIBRATOR_MAGIC) {
        cal->model_deg = (magcal_isfinite_f(model_deg) && model_deg > 0.0f) ? model_deg : 0.0f;
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
