/*
 * Continuous calibrator, step: drain the push ring into the intake store (each sample judged
 * first, cont_change.c), decide whether a solve is worth running, and run it in slices: the
 * snapshot of the store into the solver buffer (plus the solver's load, stage 0), then one stage of
 * the batch pipeline per call (magcal_calibrator_run_stage: prepare, fit, gates, adopt).
 */
#include <math.h>

#include "../calibrator_internal.h"
#include "cont_internal.h"

/* One ring sample into the store. */
static void cont_take(magcal_cont_t *cc, const magcal_vec3_t *m, uint32_t t_ms)
{
    magcal_intake_outcome_t oc = MAGCAL_INTAKE_REFUSED_SPACING;
    magcal_cont_judge_t j;
    if (cc->state != (uint8_t)MAGCAL_CONT_RELEARNING && magcal_cont_judge(cc, m, &j) != 0) {
        if (magcal_cont_episode(cc, &j, t_ms) != 0) {
            magcal_cont_declare_change(cc); /* the store restarts with this sample */
        } else if (j.mismatch != 0u) {
            return; /* inconsistent with the installed calibration: never stored */
        } else {
            /* consistent: stored */
        }
    }
    if (magcal_intake_push(&cc->store, m, &oc) == MAGCAL_OK &&
        (oc == MAGCAL_INTAKE_STORED || oc == MAGCAL_INTAKE_REPLACED)) {
        cc->stored_total++;
    }
}

static void cont_drain(magcal_cont_t *cc, uint32_t max)
{
    uint32_t k;
    for (k = 0u; k < max; ++k) {
        uint32_t t = cc->tail;
        magcal_vec3_t m;
        uint32_t tm;
        if (t == cc->head) {
            break;
        }
        MAGCAL_CONT_BARRIER(); /* the slot was written before head */
        m = cc->ring[t % MAGCAL_CONT_RING];
        tm = cc->ring_t[t % MAGCAL_CONT_RING];
        MAGCAL_CONT_BARRIER(); /* read before the slot is handed back */
        cc->tail = t + 1u;
        cont_take(cc, &m, tm);
    }
}

static int cont_worth(const magcal_cont_t *cc)
{
    magcal_intake_progress_t p;
    (void)magcal_intake_progress(&cc->store, &p);
    return p.centre_source != MAGCAL_INTAKE_CENTRE_NONE && p.coverage_deg >= cc->cfg.solve_coverage_deg && p.stored >= cc->cfg.solver.min_samples &&
           (cc->stored_total - cc->stored_at_solve >= cc->cfg.min_new ||
            (cc->last_status == MAGCAL_ERR_NOT_BETTER &&
             (float)cc->solve_ms_acc >= 0.25f * cc->cfg.age_ms));
}

/* Snapshot the store into the solver buffer and load it (stage 0). */
static magcal_cont_outcome_t cont_start(magcal_cont_t *cc)
{
    size_t n = 0u;
    int done = 0;
    if (magcal_intake_snapshot2(&cc->store, cc->buf, cc->slots, &n) != MAGCAL_OK ||
        magcal_calibrator_run_stage(&cc->solver, 0u, n, &cc->cand, &cc->last, &done) != MAGCAL_OK) {
        return MAGCAL_CONT_IDLE; /* cannot happen with a consistent instance */
    }
    cc->cand = cc->cal;
    cc->stage = 1u;
    return MAGCAL_CONT_IN_PROGRESS;
}

/* One stage of the solve under way. */
static magcal_cont_outcome_t cont_stage(magcal_cont_t *cc)
{
    int done = 0;
    magcal_status_t st =
        magcal_calibrator_run_stage(&cc->solver, cc->stage, 0u, &cc->cand, &cc->last, &done);
    if (done == 0 && st == MAGCAL_OK) {
        cc->stage++;
        return MAGCAL_CONT_IN_PROGRESS;
    }
    cc->stage = 0u;
    return magcal_cont_finish_solve(cc, st);
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
        return cont_stage(cc);
    }
    if (cont_worth(cc) != 0) {
        return cont_start(cc);
    }
    return MAGCAL_CONT_IDLE;
}

magcal_cont_outcome_t magcal_cont_solve_blocking(magcal_cont_t *cc, int force)
{
    magcal_cont_outcome_t oc = MAGCAL_CONT_IDLE;
    unsigned k;
    if (!magcal_cont_ok(cc)) {
        return MAGCAL_CONT_IDLE;
    }
    cont_drain(cc, MAGCAL_CONT_RING);
    if (cc->stage == 0u) {
        if (force == 0 && cont_worth(cc) == 0) {
            return MAGCAL_CONT_IDLE;
        }
        oc = cont_start(cc);
    }
    for (k = 0u; k < 8u && cc->stage != 0u; ++k) {
        oc = cont_stage(cc);
    }
    return oc;
}
