/*
 * Continuous calibrator, step: drain the push ring into the intake store (each sample judged
 * first, cont_change.c), decide whether a solve is worth running, and run it in slices: the
 * snapshot of the store into the solver buffer (plus the solver's load, stage 0), then one stage of
 * the batch pipeline per call (magcal_calibrator_run_stage: prepare, fit, gates, adopt).
 */
#include <math.h>

#include "../calibrator_internal.h"
#include "magcal/config.h"
#include "cont_internal.h"

/* Judge one sample against the installed calibration (change detection): 1 = do not store it. */
static MAGCAL_NOINLINE int cont_screen(magcal_cont_t *cc, const magcal_vec3_t *m, uint32_t t_ms)
{
    magcal_cont_judge_t j;
    if (cc->state != (uint8_t)MAGCAL_CONT_RELEARNING && magcal_cont_judge(cc, m, &j) != 0) {
        if (magcal_cont_episode(cc, &j, t_ms) != 0) {
            magcal_cont_declare_change(cc); /* the store restarts with this sample */
        } else if (j.mismatch != 0u) {
            return 1; /* inconsistent with the installed calibration: never stored */
        } else {
            /* consistent: stored */
        }
    }
    return 0;
}

/* Ring samples into the store, read in place (push does not reuse a slot before tail moves past
 * it). The store's push is called from here directly: it is the deep path (its survey fits). */
static void cont_drain(magcal_cont_t *cc, uint32_t max)
{
    uint32_t k;
    for (k = 0u; k < max; ++k) {
        uint32_t t = cc->tail;
        if (t == cc->head) {
            break;
        }
        MAGCAL_CONT_BARRIER(); /* the slot was written before head */
        if (cont_screen(cc, &cc->ring[t % MAGCAL_CONT_RING], cc->ring_t[t % MAGCAL_CONT_RING]) == 0) {
            /* stored samples are counted by the store (added + replaced) */
            (void)magcal_intake_push(&cc->store, &cc->ring[t % MAGCAL_CONT_RING], NULL);
        }
        MAGCAL_CONT_BARRIER(); /* read before the slot is handed back */
        cc->tail = t + 1u;
    }
}

/* Worth a solve: enough new information (cheap counters first), then the live coverage, which
 * counts only ring samples (intake progress.c, O(slots)) and so agrees with the solver's. */
static int cont_worth(const magcal_cont_t *cc)
{
    magcal_intake_progress_t p;
    const int fresh = (cc->store.ctr.added + cc->store.ctr.replaced) - cc->stored_at_solve >= cc->cfg.min_new ||
                      (cc->last_status == MAGCAL_ERR_NOT_BETTER && (float)cc->solve_ms_acc >= 0.25f * cc->cfg.age_ms);
    if (fresh == 0 || cc->store.ctr.stored < cc->cfg.solver.min_samples) {
        return 0;
    }
    (void)magcal_intake_progress(&cc->store, &p);
    return p.centre_source != MAGCAL_INTAKE_CENTRE_NONE && p.rebinning == 0u && p.coverage_deg >= cc->cfg.solve_coverage_deg;
}

/* Snapshot the store into the solver buffer and load it. */
static magcal_cont_outcome_t cont_start(magcal_cont_t *cc)
{
    size_t n = 0u;
    if (magcal_intake_snapshot2(&cc->store, cc->buf, cc->slots, &n) != MAGCAL_OK ||
        magcal_calibrator_stage_load(&cc->solver, n) != MAGCAL_OK) {
        return MAGCAL_CONT_IDLE; /* cannot happen with a consistent instance */
    }
    cc->cand = cc->cal;
    cc->stage = 1u;
    return MAGCAL_CONT_IN_PROGRESS;
}

/* After a stage returned st: next stage, or the end of the solve. */
static magcal_cont_outcome_t cont_after(magcal_cont_t *cc, magcal_status_t st)
{
    if (st == MAGCAL_OK && cc->stage < 4u) {
        cc->stage++;
        return MAGCAL_CONT_IN_PROGRESS;
    }
    cc->stage = 0u;
    cc->last_outcome = magcal_cont_finish_solve(cc, magcal_calibrator_stage_end(&cc->solver, st, &cc->last));
    return cc->last_outcome;
}

/* One stage, called from here directly: the stages' deep paths (density filter, consensus) then
 * have only the caller's frame above them (stack budget, tools/stack/budgets.txt). */
static MAGCAL_NOINLINE magcal_status_t cont_run_stage(magcal_cont_t *cc)
{
    magcal_cal_report_t *rep = magcal_calibrator_stage_report(&cc->solver);
    switch (cc->stage) {
    case 1u:
        return magcal_calibrator_stage_prepare(&cc->solver, rep);
    case 2u:
        return magcal_calibrator_stage_fit(&cc->solver);
    case 3u:
        return magcal_calibrator_stage_gates(&cc->solver, rep);
    default:
        return magcal_calibrator_stage_adopt(&cc->solver, &cc->cand, rep);
    }
}

magcal_cont_outcome_t magcal_cont_step(magcal_cont_t *cc)
{
    if (!magcal_cont_ok(cc)) {
        return MAGCAL_CONT_IDLE;
    }
    cc->change_flag = 0u;
    cont_drain(cc, cc->cfg.drain_per_step);
    if (cc->change_flag != 0u) {
        return MAGCAL_CONT_CHANGE;
    }
    if (cc->stage != 0u) {
        return cont_after(cc, cont_run_stage(cc));
    }
    if (cont_worth(cc) != 0) {
        return cont_start(cc);
    }
    return MAGCAL_CONT_IDLE;
}

/* Blocking call, first part: drain the ring, start a solve if worth it (or forced). 1 = a solve
 * is under way. */
static MAGCAL_NOINLINE int cont_begin(magcal_cont_t *cc)
{
    if (cc->stage == 0u) {
        if (cc->force == 0u && cont_worth(cc) == 0) {
            return 0;
        }
        (void)cont_start(cc);
    }
    return cc->stage != 0u;
}

magcal_cont_outcome_t magcal_cont_solve_blocking(magcal_cont_t *cc, int force)
{
    if (cc == NULL || cc->magic != MAGCAL_CONT_MAGIC) {
        return MAGCAL_CONT_IDLE;
    }
    cc->force = (uint8_t)(force != 0 ? 1u : 0u); /* kept in cc: nothing but cc live across calls */
    cont_drain(cc, MAGCAL_CONT_RING);
    if (cont_begin(cc) == 0) {
        return MAGCAL_CONT_IDLE;
    }
    /* bounded: every pass moves stage 1 -> 2 -> 3 -> 4, or ends it (0); at most 4 passes. Only
     * cc is live across the calls (the outcome is read back from it): one 8-byte frame above
     * the stages' deep paths. */
    while (cc->stage != 0u) {
        (void)cont_after(cc, cont_run_stage(cc));
    }
    return (magcal_cont_outcome_t)cc->last_outcome;
}
