/*
 * Continuous calibrator, the stream's continuity before a calibration (the drain, task context,
 * O(1) per sample, no trigonometry; docs/calibrator.md "Level shift", "Continuity gate"):
 *  - the level-shift watch (continuous.h "Level shift"): a jump of the raw field that stays is a
 *    change of the installation, and the store's samples from before it are another's;
 *  - the continuity gate (continuous.h "Continuity gate"): a sample that jumps from the one before
 *    it by far more than the stream's typical increment is not stored (a garbage burst's samples
 *    jump from each other; nothing else rejects them before a calibration judges the stream).
 */
#include <math.h>

#include "../intake/intake_internal.h"
#include "cont_internal.h"
#include "magcal_internal.h"

#define SH_JUMP_REL 0.15f  /* a jump: more than this x R between two samples (turning: < 0.03 R at 50 Hz) */
#define SH_MAX_DT_MS 250u  /* ... at most this far apart (a longer gap: the vehicle may have turned) */
#define SH_ISOLATED 16.0f  /* ... and 4 x the increments before and after it in length: a turn (however
                              fast, at whatever rate) moves the field by similar increments, a glitch
                              burst by large ones in a row; an exact repeat is not an increment */
#define SH_TYPICAL 36.0f   /* ... and 6 x the typical increment (an average of their squares, weight
                              SH_TYPICAL_W per sample): sensor noise while parked has tails that
                              beat a neighbour test (the 60-min seed-6 drive, parked at start over a
                              centre on its samples: 6 isolated noise "jumps" in 70 s) */
#define SH_TYPICAL_W (1.0f / 32.0f)
#define SH_FAR_REL 4.0f    /* a sample farther than this x the scale from the store's centre is not a
                              position (a hard-iron step of up to 3 R stays within it) */
#define SH_FAR_RESET_MS 5000u /* far samples only for this long restart the scale (a glitch burst is
                                 shorter; a start on a reading near the centre is not locked out) */
#define SH_SCALE_MS 20000u /* the scale's time constant */
#define SH_BRIDGE_MS 1000u /* a burst of non-positions up to this long is bridged (a glitch burst: 5..40 rows at 50 Hz) */
#define SH_BRIDGE_RATE 0.52f /* a jump across it beyond a turn at 30 deg/s (rad/s; the typical increment times
                                the burst's samples bounds a steady motion, not a parked sensor's noise) */

void magcal_cont_shift_clear(magcal_cont_t *cc)
{
    cc->sh_have = 0u;
    cc->sh_cand_on = 0u;
    cc->sh_open = 0u;
    cc->sh_scale = 0.0f;
    cc->sh_inc2 = 0.0f;
    cc->sh_cut = 0u;
    cc->sh_stale = 0u;
    cc->sh_br_n = 0u;
}

/* 1 when the open episode's jumps so far make a shift: their sum beyond cfg.shift_rel x R and at
 * least half its largest jump (a glitch burst's jumps out and back cancel up to the motion during
 * it: the LSM9DS1 driver's bursts jump 44 R and sum to up to 2 R). */
static int shift_sum_is_shift(const magcal_cont_t *cc, float r)
{
    const float lim = cc->cfg.shift_rel * r;
    const float s2 = cc->sh_sum.x * cc->sh_sum.x + cc->sh_sum.y * cc->sh_sum.y;
    return s2 > lim * lim && s2 > 0.25f * cc->sh_max_n2;
}

/* The episode ended (no jump for cfg.shift_hold_ms): a shift when its jumps add up. */
static void shift_close(magcal_cont_t *cc, float r)
{
    cc->sh_open = 0u;
    if (shift_sum_is_shift(cc, r) != 0) {
        cc->sh_cut = 1u;
        cc->shifts++;
        if (cc->stage != 0u) {
            cc->sh_stale = 1u; /* the solve under way saw the store before it */
        }
    }
}

/* 1 when m is a position of the motion: within SH_FAR_REL x the scale of the distance from the
 * store's centre (a garbage reading far off the ring is not; the store refuses it too). The scale
 * is an exponential average of that distance over the positions (time constant SH_SCALE_MS), the
 * length the thresholds are relative to: the field's radius where the centre is good, its order of
 * magnitude where it is not (the store's own radius can be off by 10x before any calibration: the
 * 30-min seed-10 drive's survey said 1.9 for a ring of 21). Far ones only, for SH_FAR_RESET_MS,
 * start it again. */
static int shift_position(magcal_cont_t *cc, const magcal_vec3_t *m, const magcal_vec3_t *c, uint32_t t_ms)
{
    const float dx = m->x - c->x;
    const float dy = m->y - c->y;
    const float d = sqrtf(dx * dx + dy * dy);
    if (!(cc->sh_scale > 0.0f) || (d > SH_FAR_REL * cc->sh_scale && cc->sh_far != 0u &&
                                   t_ms - cc->sh_far_t >= SH_FAR_RESET_MS)) {
        cc->sh_scale = magcal_isfinite_f(d) ? d : 0.0f;
        cc->sh_far = 0u;
        cc->sh_have = 0u;
        return cc->sh_scale > 0.0f ? 1 : 0;
    }
    if (!(d <= SH_FAR_REL * cc->sh_scale)) {
        if (cc->sh_far == 0u) {
            cc->sh_far = 1u;
            cc->sh_far_t = t_ms;
        }
        return 0;
    }
    cc->sh_far = 0u;
    {
        const uint32_t dt = t_ms - cc->sh_prev_t;
        cc->sh_scale += (d - cc->sh_scale) * magcal_cont_ema_w(dt > MAGCAL_CONT_MAX_DT_MS ? MAGCAL_CONT_MAX_DT_MS : dt,
                                                               SH_SCALE_MS);
    }
    return 1;
}

/* A candidate jump (dx, dy), squared length n2, at t_ms: confirmed by a small increment after it. */
static void shift_candidate(magcal_cont_t *cc, float dx, float dy, float n2, uint32_t t_ms)
{
    cc->sh_cand_on = 1u;
    cc->sh_cand.x = dx;
    cc->sh_cand.y = dy;
    cc->sh_cand_n2 = n2;
    cc->sh_cand_t = t_ms;
    cc->sh_cand_seq = cc->store.seq & INTAKE_SEQ_MASK;
}

/* A candidate jump confirmed (the increment after it is small too): into the episode. */
static void shift_take(magcal_cont_t *cc)
{
    if (cc->sh_open == 0u) {
        cc->sh_open = 1u;
        cc->sh_sum.x = 0.0f;
        cc->sh_sum.y = 0.0f;
        cc->sh_max_n2 = 0.0f;
        cc->sh_seq = cc->sh_cand_seq; /* the jump's sample and later are kept */
    }
    cc->sh_max_n2 = cc->sh_cand_n2 > cc->sh_max_n2 ? cc->sh_cand_n2 : cc->sh_max_n2;
    cc->sh_sum.x += cc->sh_cand.x;
    cc->sh_sum.y += cc->sh_cand.y;
    cc->sh_jump_t = cc->sh_cand_t;
}

void magcal_cont_shift_watch(magcal_cont_t *cc, const magcal_vec3_t *m, uint32_t t_ms, int levelled)
{
    const magcal_intake_t *st = &cc->store;
    const uint8_t lev = (uint8_t)(levelled != 0 ? 1u : 0u);
    float r;
    float dx;
    float dy;
    float n2;
    uint16_t brn;
    if (cc->cfg.shift_rel <= 0.0f || cc->has_cal != 0u || st->centre_source == (uint8_t)MAGCAL_INTAKE_CENTRE_NONE) {
        cc->sh_have = 0u;
        cc->sh_cand_on = 0u;
        cc->sh_open = 0u;
        cc->sh_scale = 0.0f;
        cc->sh_br_n = 0u;
        return;
    }
    if (cc->sh_have != 0u && m->x == cc->sh_prev.x && m->y == cc->sh_prev.y) {
        return; /* the logger repeating a sample: not a sample of the motion */
    }
    if (!magcal_isfinite_f(m->x) || !magcal_isfinite_f(m->y) || shift_position(cc, m, &st->centre, t_ms) == 0) {
        /* not a position: with no episode open, the chain of increments is bridged to the next
         * position when it comes soon (below); otherwise it breaks and an open episode is void
         * (its jump back may be among these: a stepped transient followed by a glitch burst
         * would read as a shift) */
        if (cc->sh_have == 2u && cc->sh_cand_on == 0u && cc->sh_open == 0u && cc->sh_br_n < UINT16_MAX) {
            cc->sh_br_n++;
        } else {
            cc->sh_have = 0u;
            cc->sh_br_n = 0u;
            cc->sh_open = 0u;
        }
        cc->sh_cand_on = 0u;
        return;
    }
    brn = cc->sh_br_n;
    if (brn != 0u) {
        cc->sh_br_n = 0u;
    }
    r = cc->sh_scale;
    dx = m->x - cc->sh_prev.x;
    dy = m->y - cc->sh_prev.y;
    n2 = dx * dx + dy * dy;
    if (brn != 0u && cc->sh_have == 2u) {
        /* the first position after a burst of non-positions (a glitch burst, a sensor saturated
         * while a magnet was brought near it): a jump across it that the motion could not make
         * in the burst's samples (SH_TYPICAL x the typical increment times their number,
         * squared, or a turn at 30 deg/s, whichever is less) is a candidate as any other
         * (30-min seed 10: its hard-iron step came inside a 33-row rail burst while parked; the
         * chain broke there, the shift went unseen and a solve on both rings adopted a
         * calibration 19 deg off) */
        const float k = (float)brn + 1.0f;
        const float lim = SH_JUMP_REL * r;
        const uint32_t gap = t_ms - cc->sh_prev_t;
        const float turn = SH_BRIDGE_RATE * 0.001f * (float)gap * r; /* what a turn moves the field by in it */
        cc->sh_cand_on = 0u;
        if (gap <= SH_BRIDGE_MS && lev == cc->sh_lev && n2 > lim * lim &&
            n2 > fminf(SH_TYPICAL * cc->sh_inc2 * k * k, turn * turn) && magcal_isfinite_f(n2)) {
            shift_candidate(cc, dx, dy, n2, t_ms);
            cc->sh_last_n2 = n2;
            cc->sh_have = 2u;
        } else {
            cc->sh_have = 1u; /* no increment across it */
        }
    } else if (cc->sh_have != 0u && lev != cc->sh_lev) {
        cc->sh_have = 1u; /* the tilt compensation switched on or off (a step of k t): no increment */
        cc->sh_cand_on = 0u;
    } else if (cc->sh_have == 0u || t_ms - cc->sh_prev_t > SH_MAX_DT_MS) {
        cc->sh_have = 1u;
        cc->sh_cand_on = 0u; /* a gap (or a start): the vehicle may have turned; no increment yet, */
        cc->sh_open = 0u;    /* and an open episode is void (as above) */
    } else {
        const float lim = SH_JUMP_REL * r;
        if (cc->sh_cand_on != 0u && n2 * SH_ISOLATED < cc->sh_cand_n2) {
            shift_take(cc); /* small before and after: a jump of the field, not of the motion */
        }
        cc->sh_cand_on = 0u;
        if (cc->sh_have == 2u && n2 > lim * lim && n2 > SH_ISOLATED * cc->sh_last_n2 &&
            n2 > SH_TYPICAL * cc->sh_inc2 && magcal_isfinite_f(n2)) {
            shift_candidate(cc, dx, dy, n2, t_ms);
        }
        if (cc->sh_cand_on == 0u && magcal_isfinite_f(n2)) {
            /* the typical increment (squared), a candidate jump left out */
            cc->sh_inc2 = cc->sh_inc2 > 0.0f ? cc->sh_inc2 + (n2 - cc->sh_inc2) * SH_TYPICAL_W : n2;
        }
        cc->sh_last_n2 = n2;
        cc->sh_have = 2u;
    }
    if (cc->sh_open != 0u && t_ms - cc->sh_jump_t >= cc->cfg.shift_hold_ms) {
        shift_close(cc, r);
    }
    cc->sh_prev.x = m->x;
    cc->sh_prev.y = m->y;
    cc->sh_prev_t = t_ms;
    cc->sh_lev = lev;
}

int magcal_cont_shift_refuses(const magcal_cont_t *cc)
{
    return cc->sh_stale != 0u || (cc->sh_open != 0u && shift_sum_is_shift(cc, cc->sh_scale) != 0);
}

void magcal_cont_shift_to_cut(magcal_cont_t *cc)
{
    if (cc->sh_cut != 0u) {
        cc->sh_cut = 0u;
        cc->sh_stale = 0u;
        /* no change can come between (the watch runs with nothing installed, and an install clears
         * it): the push count sh_seq belongs to this store */
        cc->drop_on = 2u; /* set: the copy drops what is older (no age scan, no ring test) */
        cc->drop_seq = cc->sh_seq;
        cc->drop_changes = cc->changes;
        cc->drop_r = 0.0f;
    }
}

/* ---- continuity gate */
#define CG_K2 36.0f          /* a stored sample is within 6x the typical increment per sample since
                                the last stored one */
#define CG_GROW 4.0f         /* an increment counts into the typical one at most CG_GROW x it: a
                                garbage burst (40 samples) cannot teach it, a turn that starts from
                                rest does within about 12 samples */
#define CG_W_UP (1.0f / 32.0f)  /* the typical increment's weight per sample, growing */
#define CG_W_DOWN (1.0f / 8.0f) /* and shrinking (a start on a spike is forgotten in ~2 s) */
#define CG_RUN 8u            /* refused samples in a row that move as a stream (each within the
                                typical increment of the one before) start again from the last: a
                                lasting jump (a hard-iron step) is not refused for ever */
#define CG_MAX_N 1024u       /* samples since the last stored one: counted up to this */

static void cg_typical(magcal_cont_t *cc, float n2)
{
    if (!(cc->cg_inc2 > 0.0f)) {
        cc->cg_inc2 = n2;
    } else if (n2 < cc->cg_inc2) {
        cc->cg_inc2 += (n2 - cc->cg_inc2) * CG_W_DOWN;
    } else {
        cc->cg_inc2 += ((n2 < CG_GROW * cc->cg_inc2 ? n2 : CG_GROW * cc->cg_inc2) - cc->cg_inc2) * CG_W_UP;
    }
}

/* The anchor: the last stored sample (or the start of a new run). */
static void cg_anchor(magcal_cont_t *cc, const magcal_vec3_t *m)
{
    cc->cg_keep.x = m->x;
    cc->cg_keep.y = m->y;
    cc->cg_keep_n = 1u;
    cc->cg_run = 0u;
}

int magcal_cont_continuity(magcal_cont_t *cc, const magcal_vec3_t *m, uint32_t t_ms)
{
    int keep = 1;
    if (cc->cfg.continuity == 0u || (cc->has_cal != 0u && cc->state != (uint8_t)MAGCAL_CONT_RELEARNING)) {
        cc->cg_have = 0u;
        return 1; /* off, or a calibration judges the stream */
    }
    if (!magcal_isfinite_f(m->x) || !magcal_isfinite_f(m->y)) {
        return 1; /* the store refuses it */
    }
    if (cc->cg_have == 0u || t_ms - cc->cg_prev_t > SH_MAX_DT_MS) {
        /* a start or a gap: no increment; the sample is the anchor (not stored at a start: row 0's
         * start-up spike of the generated drives would otherwise stay in the store) */
        if (cc->cg_have == 0u) {
            keep = 0;
        }
        cc->cg_have = 1u;
        cg_anchor(cc, m);
    } else {
        const float px = m->x - cc->cg_prev.x;
        const float py = m->y - cc->cg_prev.y;
        const float kx = m->x - cc->cg_keep.x;
        const float ky = m->y - cc->cg_keep.y;
        const float n2 = px * px + py * py;
        const float k2 = kx * kx + ky * ky;
        const float nk = (float)cc->cg_keep_n;
        if (magcal_isfinite_f(n2) && n2 > 0.0f) {
            cg_typical(cc, n2); /* an exact repeat is not an increment */
        }
        if (k2 <= CG_K2 * cc->cg_inc2 * nk * nk) {
            cg_anchor(cc, m);
        } else {
            keep = 0;
            cc->cg_run = (n2 <= CG_K2 * cc->cg_inc2) ? cc->cg_run + 1u : 0u;
            cc->cg_keep_n = cc->cg_keep_n < CG_MAX_N ? cc->cg_keep_n + 1u : CG_MAX_N;
            if (cc->cg_run >= CG_RUN) {
                cg_anchor(cc, m); /* the stream moved on: stored from here */
                keep = 1;
            }
        }
    }
    cc->cg_prev.x = m->x;
    cc->cg_prev.y = m->y;
    cc->cg_prev_t = t_ms;
    if (keep == 0) {
        cc->cg_refused++;
    }
    return keep;
}
