/*
 * Continuous calibrator, the change decision (docs/calibrator.md "Judge and change detection"):
 * the episode update of every judged sample (cont_judge.c). Samples beyond twice the per-sample
 * threshold (`gross`) open or extend an episode (its sectors of corrected heading and its
 * mismatch time); cfg.clear_ms of consistent samples close it; cfg.change_ms of mismatch over
 * cfg.change_bins sectors is a lasting change (the store is dropped, cont_step.c relearns). The
 * same update feeds the transient judge (cont_flags.c), which never adds up to a change.
 * Model health: when a 30 s share of samples over the per-sample threshold exceeds CONT_MISS_ON
 * (no episode open), the model does not explain the stream and its per-sample test stops
 * flagging (and refusing storage) until the share falls below CONT_MISS_OFF.
 */
#include "cont_judge_internal.h"

#define CONT_MISS_MS 30000.0f     /* time constant of the share of samples over the threshold */
#define CONT_MISS_ON 0.08f        /* above this share the model does not explain the stream ... */
#define CONT_MISS_OFF 0.04f       /* ... until it falls below this one */

static unsigned cont_popcount(uint32_t v)
{
    unsigned n = 0u;
    unsigned k;
    for (k = 0u; k < 32u; ++k) {
        n += (unsigned)((v >> k) & 1u);
    }
    return n;
}

/* Wide: the episode spans change_bins sectors and has lasted 3/4 of change_ms (a 2 to 5 s transient
 * through a turn spans many sectors but must not flag the clean headings after it). */
int magcal_cont_episode_wide(const magcal_cont_t *cc)
{
    return cc->episode_open != 0u && cc->mis_ms >= cc->cfg.change_ms - cc->cfg.change_ms / 4u &&
           cont_popcount(cc->mis_bins[0]) + cont_popcount(cc->mis_bins[1]) >= cc->cfg.change_bins;
}

int magcal_cont_episode(magcal_cont_t *cc, const magcal_cont_judge_t *j, uint32_t t_ms)
{
    uint32_t dt = 0u;
    if (cc->have_t != 0u) {
        dt = t_ms - cc->last_t;
        if (dt > MAGCAL_CONT_MAX_DT_MS) {
            dt = MAGCAL_CONT_MAX_DT_MS;
        }
    }
    cc->last_t = t_ms;
    cc->have_t = 1u;
    if (cc->age_ms_acc <= UINT32_MAX - dt) {
        cc->age_ms_acc += dt;
    }
    if (cc->solve_ms_acc <= UINT32_MAX - dt) {
        cc->solve_ms_acc += dt;
    }
    magcal_cont_transient(cc, j, dt);
    if (cc->fz_on != 0u && j->gross == 0u && cc->dist_flag == 0u && cc->episode_open == 0u) {
        /* the model's health: the share of clean-looking samples over its per-sample threshold.
         * A model fitted on a poor calibration (or with the u terms of an earlier one) reads the
         * hills as mismatches on a large share of the rows: then its per-sample test stops flagging
         * (and refusing storage, so the store gets the hills the next fit needs) until the share
         * falls again; the change evidence (gross) and the transient judge stay on. Not while
         * an episode is open: the samples of a change in progress are not the model's health */
        cc->fz_miss += (float)dt / (CONT_MISS_MS + (float)dt) * ((j->over != 0u ? 1.0f : 0.0f) - cc->fz_miss);
        if (cc->fz_miss > CONT_MISS_ON) {
            cc->fz_unfit = 1u;
        } else if (cc->fz_miss < CONT_MISS_OFF) {
            cc->fz_unfit = 0u;
        } else {
            /* hysteresis */
        }
    }
    /* the episode counts the per-sample judge only (a transient flag must never add up to a change),
     * in covered sectors (the judge's mismatch is 0 elsewhere); a tilted sample judged by the
     * radius alone counts neither way (a hill moves the horizontal field by Z sin(pitch), up to
     * 20 % of R at 6 deg: a calibration restored without its field model or tilt state read the
     * first hills after a power cycle as a lasting change) */
    if (j->tilted == 0u && j->gross != 0u) {
        cc->episode_open = 1u;
        cc->mis_ms += dt;
        cc->clean_ms = 0u;
        cc->mis_bins[j->sector / 32u] |= 1u << (j->sector % 32u);
    } else if (j->tilted == 0u && cc->episode_open != 0u && (j->over == 0u || cc->fz_unfit != 0u)) {
        /* consistent: within the per-sample threshold (a sample over it but short of the change
         * evidence is neither: 30-min seed 38's hard-iron step, parked at one heading, read 0.18 to
         * 0.22 R off around twice the threshold; those samples closed the episode, then the model's
         * health switched the per-sample test off and the heading was OK at 37 deg for 5 minutes) */
        cc->clean_ms += dt;
        if (cc->clean_ms >= cc->cfg.clear_ms) {
            cc->episode_open = 0u;
            cc->mis_ms = 0u;
            cc->clean_ms = 0u;
            cc->mis_bins[0] = 0u;
            cc->mis_bins[1] = 0u;
        }
    } else {
        /* consistent with no episode open, or tilted: neither evidence */
    }
    return cc->episode_open != 0u && cc->mis_ms >= cc->cfg.change_ms && magcal_cont_episode_wide(cc) != 0;
}

void magcal_cont_declare_change(magcal_cont_t *cc)
{
    (void)magcal_intake_reset(&cc->store);
    cc->state = (uint8_t)MAGCAL_CONT_RELEARNING;
    cc->relevel = 0u; /* the relearn's store is levelled from the start when the compensation is on */
    cc->st_tn = 0u;   /* and its mean tilt starts again */
    cc->stage = 0u;
    cc->changes++;
    cc->episode_open = 0u;
    cc->mis_ms = 0u;
    cc->clean_ms = 0u;
    cc->mis_bins[0] = 0u;
    cc->mis_bins[1] = 0u;
    cc->stored_at_solve = 0u;
    cc->stored_at_adopt = 0u;
    cc->change_flag = 1u;
}
