/*
 * Continuous 3-D calibrator, step: drain the push ring into the intake store (each sample judged
 * first, c3_change.c), decide whether a solve is worth running, and run it in three units, one per
 * step() call: (1) the snapshot of the store into the solver buffer (the sliced solve begins on
 * it), (2) the solve, time-sliced: magcal_ellipsoid_calibrate_step with cfg.step_budget per call,
 * as many calls as it needs (its density stage, when the pre-test runs it, is one call of its
 * own: not sliced), (3) the never-worse adoption judgement (c3_adopt.c).
 */
#include "c3_internal.h"
#include "magcal/config.h"

#if MAGCAL_CFG_ENABLE_3D /* whole file: config.h feature switch (the 3-D loop needs the ellipsoid fit) */

/* Judge one sample against the installed calibration (change detection): 1 = do not store it. */
static MAGCAL_NOINLINE int c3_screen(magcal_cont3_t *cc, const magcal_vec3_t *m, uint32_t t_ms)
{
    magcal_c3_judge_t j;
    const uint32_t dt = magcal_c3_tick(cc, t_ms);
    if (cc->state != (uint8_t)MAGCAL_CONT3_RELEARNING && magcal_c3_judge(cc, m, &j) != 0) {
        if (magcal_c3_episode(cc, &j, dt) != 0) {
            magcal_c3_declare_change(cc); /* the store restarts with this sample */
        } else if (j.mismatch != 0u) {
            return 1; /* inconsistent with the installed calibration: never stored */
        } else {
            /* consistent: stored */
        }
    }
    return 0;
}

/* Ring samples into the store, read in place (push does not reuse a slot before tail moves past it). */
static void c3_drain(magcal_cont3_t *cc, uint32_t max)
{
    uint32_t k;
    for (k = 0u; k < max; ++k) {
        uint32_t t = cc->tail;
        if (t == cc->head) {
            break;
        }
        MAGCAL_CONT3_BARRIER(); /* the slot was written before head */
        if (c3_screen(cc, &cc->ring[t % MAGCAL_CONT3_RING], cc->ring_t[t % MAGCAL_CONT3_RING]) == 0) {
            (void)magcal_intake_push(&cc->store, &cc->ring[t % MAGCAL_CONT3_RING], NULL);
        }
        MAGCAL_CONT3_BARRIER(); /* read before the slot is handed back */
        cc->tail = t + 1u;
    }
}

/* New stored samples a solve needs: cfg.min_new, x 2^f after f failed solves in a row (at most
 * x 64), x (1 + r) after r refusals in a row (at most x 64). */
static uint32_t c3_new_needed(const magcal_cont3_t *cc)
{
    const uint32_t f = cc->fail_run < 6u ? cc->fail_run : 6u;
    const uint32_t r = cc->refuse_run < 63u ? cc->refuse_run : 63u;
    return ((uint32_t)cc->cfg.min_new << f) * (1u + r);
}

static int c3_worth(const magcal_cont3_t *cc)
{
    magcal_intake_progress_t p;
    (void)magcal_intake_progress(&cc->store, &p);
    return p.centre_source != MAGCAL_INTAKE_CENTRE_NONE && p.fill_fraction >= cc->cfg.solve_fill &&
           p.stored >= cc->cfg.min_samples &&
           ((cc->store.ctr.added + cc->store.ctr.replaced) - cc->stored_at_solve >= c3_new_needed(cc) ||
            (cc->last_status == MAGCAL_ERR_NOT_BETTER && (float)cc->solve_ms_acc >= 0.25f * cc->cfg.age_ms));
}

/* Unit 1: snapshot the store into the solver buffer; the sliced solve begins on it (O(1)). */
static MAGCAL_NOINLINE magcal_cont3_outcome_t c3_snapshot(magcal_cont3_t *cc)
{
    size_t n = 0u;
    if (magcal_intake_snapshot3(&cc->store, cc->buf, cc->slots, &n) != MAGCAL_OK) {
        return MAGCAL_CONT3_IDLE; /* cannot happen with a consistent instance */
    }
    cc->snap_n = n;
    cc->stored_at_solve = cc->store.ctr.added + cc->store.ctr.replaced;
    cc->solve_status = magcal_ellipsoid_calibrate_begin(&cc->slice, &cc->cfg.solver, cc->buf, n, cc->work,
                                                        cc->work_len, NULL, &cc->cand, NULL);
    cc->stage = (cc->solve_status == MAGCAL_OK) ? 2u : 3u; /* begin failed: stage 3 reports it */
    return MAGCAL_CONT3_IN_PROGRESS;
}

/* Unit 2: the solve, `budget` estimated M4F instructions per call (magcal_ellipsoid_calibrate_step
 * on the snapshot; pushes go on into the ring and the store meanwhile). */
static MAGCAL_NOINLINE magcal_cont3_outcome_t c3_solve(magcal_cont3_t *cc, uint32_t budget)
{
    const magcal_status_t st = magcal_ellipsoid_calibrate_step(&cc->slice, budget);
    if (st != MAGCAL_IN_PROGRESS) {
        cc->solve_status = st;
        cc->stage = 3u;
    }
    return MAGCAL_CONT3_IN_PROGRESS;
}

/* The next unit of a solve under way. */
static magcal_cont3_outcome_t c3_unit(magcal_cont3_t *cc, uint32_t budget)
{
    if (cc->stage == 1u) {
        return c3_snapshot(cc);
    }
    if (cc->stage == 2u) {
        return c3_solve(cc, budget);
    }
    cc->stage = 0u;
    cc->last_outcome = magcal_c3_adopt(cc);
    return cc->last_outcome;
}

magcal_cont3_outcome_t magcal_cont3_step(magcal_cont3_t *cc)
{
    if (!magcal_c3_ok(cc)) {
        return MAGCAL_CONT3_IDLE;
    }
    cc->change_flag = 0u;
    c3_drain(cc, cc->cfg.drain_per_step);
    if (cc->change_flag != 0u) {
        return MAGCAL_CONT3_CHANGE;
    }
    if (cc->stage == 0u && c3_worth(cc) != 0) {
        cc->stage = 1u;
    }
    if (cc->stage == 2u) { /* the solve's deep path under as few frames as possible (stack) */
        return c3_solve(cc, cc->cfg.step_budget);
    }
    if (cc->stage != 0u) {
        return c3_unit(cc, cc->cfg.step_budget);
    }
    return MAGCAL_CONT3_IDLE;
}

magcal_cont3_outcome_t magcal_cont3_solve_blocking(magcal_cont3_t *cc, int force)
{
    unsigned k;
    if (!magcal_c3_ok(cc)) {
        return MAGCAL_CONT3_IDLE;
    }
    cc->change_flag = 0u;
    c3_drain(cc, MAGCAL_CONT3_RING);
    if (cc->stage == 0u) {
        if (force == 0 && c3_worth(cc) == 0) {
            return MAGCAL_CONT3_IDLE;
        }
        cc->stage = 1u;
    }
    /* bounded: the units go 1 -> 2 -> 3 -> 0 (unit 2 in one call: no budget) */
    for (k = 0u; k < 3u && cc->stage != 0u; ++k) {
        (void)c3_unit(cc, UINT32_MAX);
    }
    return cc->last_outcome;
}

#endif /* MAGCAL_CFG_ENABLE_3D */
