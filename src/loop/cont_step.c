/*
 * Continuous calibrator, step: drain the push ring into the intake store (each sample judged
 * first, cont_change.c), decide whether a solve is worth running, and run it in slices within
 * cfg.step_budget estimated Cortex-M4F instructions per call: the snapshot of the store into the
 * solver buffer (bins copied per visit), then the solver's resumable phases
 * (magcal_calibrator_solve_step, calibrator_solve.c). The drain and the solve charge the same
 * budget (continuous.h "Work per step").
 */
#include <math.h>
#include <string.h>

#include "../adopt/calibrator_internal.h"
#include "../intake/intake_internal.h"
#include "magcal/config.h"
#include "cont_internal.h"
#include "magcal_internal.h"

/* cppcheck-suppress misra-c2012-2.3 ; deviation D4: a static assert is an unused typedef */
MAGCAL_STATIC_ASSERT(sizeof(float) == sizeof(uint32_t), cont_park_stamp_bits); /* deviation D15 */

/* Weights, estimated M4F instructions, MEASURED on the target (QEMU mps2-an386 -icount shift=0,
 * cont_trace.elf, tools/bench/cont_weights.py: the largest measured step of that kind on the
 * generated drive and vn100_car_circles_b x 4, rounded up; docs/performance.md "Per call"). */
/* A drained sample is charged by what it did, the step's sweep steps by what each did (issue 14:
 * a flat 4900 per sample, a catch-up step of two samples measured 12,080). Measured on the target
 * (cont_trace.elf, drain-only steps of both drives, 108k steps): the largest step per number of
 * surveyed slots and judge on/off, so measured / charged <= ~1.0 (least squares: push ~600-990,
 * judge ~1140-1330, slot ~340-360, re-bin ~360; the values below cover the largest steps). These
 * charges set the slicing (how many steps a solve takes, so the row it ends at) and stay as
 * measured then, though a surveyed slot now costs ~200 (issue 14, the interleaved solve:
 * src/intake/sweep.c). */
#define CONT_W_PUSH 1200u  /* the store push of one sample (no sweep step), ring read, bookkeeping */
#define CONT_W_JUDGE 1800u /* its judge against the installed calibration (correction, heading, episode) */
#define CONT_W_VISIT 480u  /* one sweep step that surveyed a slot */
#define CONT_W_REBIN 500u  /* one sweep step that re-binned a sample (swap-remove + insert) */
#define CONT_W_JUMP 100u   /* one sweep step that jumped the empty rest of a bin */
#define CONT_W_SWEEP 5500u /* the end of a survey sweep (trimmed extremes, its fits; measured <= 5.1k alone) */
#define CONT_SOLVE_CAP 4u  /* the solver's share of a step: at most CAP / DIV of the budget */
#define CONT_SOLVE_DIV 5u
#define CONT_SOLVE_MIN 2500u /* the least share of a step worth a solve call: a visit of the solver is
                              * indivisible (a PRE_CONS visit measured 3,240 on a 660 share, the 30-min
                              * seed-5 drive's step 10,160: tools/bench/cont_weights.py), so a
                              * step leaves the solve to the next when less is left, and the sweep
                              * part keeps this much for a solve under way (at most a third of
                              * cfg.step_budget: a small budget still progresses, cont_solve_min) */
#define CONT_W_SNAP 21u    /* one sample of the snapshot (was 14: measured 1.42x) */
#define CONT_W_CUT 90u     /* one sample's test of a cut (distance, sqrtf; estimate, as CAL_W_CO_RES) */
#define CONT_W_AGE 12u     /* one sample of a cut's age scan (estimate) */
#define CONT_W_BIN 30u     /* one bin of the snapshot (was 20) */
#define CONT_W_SNAP_END 400u /* the snapshot's end: the solver's begin (small parts measured up to 2.7x before) */
#define CONT_W_PARK 30u    /* one ring sample parked during the field-model fit */

/* Per-step trace, bench-only (MAGCAL_BENCH_TRACE: tools/bench/m4f_image cont_trace.elf, never in a
 * shipped build): what each step did and what it charged, next to the image's SysTick count
 * (tools/bench/cont_weights.py fits the weights from it). Indices: MAGCAL_BENCH_TR_*. */
#ifdef MAGCAL_BENCH_TRACE
enum {
    TR_STAGE_IN = 0, /* stage at entry | fit_phase << 8 */
    TR_STAGE_OUT,    /* stage at exit | fit_phase << 8 */
    TR_DRAINED,      /* samples the drain took */
    TR_SWEEPS,       /* of them, pushes that ended a survey sweep */
    TR_CHARGED,      /* estimate charged outside the solver (drain, park, snapshot, fit) */
    TR_SOLVE_BUDGET, /* budget handed to the solver (0: not called) */
    TR_SOLVE_LEFT,   /* what the solver left of it */
    TR_PHASE_IN,     /* solver phase at entry (calibrator_solve.c magcal_bench_solve_phase) */
    TR_PHASE_OUT,    /* at exit */
    TR_WORTH,        /* 1: the coverage-count step */
    TR_SOLVE_INSN,   /* the solver's own instructions (SysTick around its step, 40 per tick) */
    TR_DRAIN_INSN,   /* the drain's */
    TR_VISITS,       /* sweep steps of the drained samples that surveyed a slot */
    TR_JUDGED,       /* drained samples judged against the installed calibration */
    TR_COUNT_INSN,   /* the coverage count's own instructions (SysTick around it) */
    TR_COUNT_CHARGED, /* its estimate */
    TR_SNAP_INSN,    /* the snapshot's own instructions */
    TR_SNAP_CHARGED, /* its estimate */
    TR_REBINS,       /* sweep steps of the drained samples that re-binned */
    TR_N
};
/* the target's SysTick current value (counts down at the core clock; QEMU -icount shift=0) */
static inline uint32_t cont_trace_ticks(void) { return *(volatile uint32_t *)0xE000E018u; }
uint32_t magcal_bench_cont_trace[TR_N];
unsigned magcal_bench_solve_phase(const magcal_calibrator_t *cal, uint32_t *left);
#define CONT_TRACE(stmt) stmt
#else
#define CONT_TRACE(stmt)
#endif

/* cont_solve inlined into both callers (step, solve_blocking): no frame of its own between them
 * and the solver's phases (the solve path's stack, tools/stack/budgets.txt) */
#if defined(__GNUC__) || defined(__clang__)
#define CONT_INLINE static inline __attribute__((always_inline))
#else
#define CONT_INLINE static inline
#endif

/* cppcheck-suppress misra-c2012-5.7 ; deviation D14 (false positive): the enum has no tag */
/* cppcheck-suppress misra-c2012-2.4 ; deviation D14 (false positive): no tag, so no unused tag */
enum { CONT_STAGE_NONE = 0, CONT_STAGE_SNAPSHOT = 1, CONT_STAGE_SOLVE = 2, CONT_STAGE_FIT = 3 };

/* 1 while the store must not change (the snapshot, or the field-model fit after an adoption):
 * the drain pauses (the ring holds the samples that arrive meanwhile). */
static int cont_store_frozen(const magcal_cont_t *cc)
{
    /* the snapshot's first step drains before it copies a bin (a step that only copied would
     * leave a sample behind) */
    return (cc->stage == (uint8_t)CONT_STAGE_SNAPSHOT && cc->snap_bin != 0u) || cc->stage == (uint8_t)CONT_STAGE_FIT;
}

/* 1 when a drained sample is judged against the installed calibration (cont_screen). */
static int cont_judge_on(const magcal_cont_t *cc)
{
    return cc->state != (uint8_t)MAGCAL_CONT_RELEARNING && cc->has_cal != 0u;
}

/* Judge one sample against the installed calibration (change detection): 1 = do not store it. */
static MAGCAL_NOINLINE int cont_screen(magcal_cont_t *cc, const magcal_vec3_t *m, uint32_t t_ms, int levelled)
{
    magcal_cont_judge_t j;
    magcal_cont_shift_watch(cc, m, t_ms, levelled); /* before any calibration: a jump that stays (cont_shift.c) */
    if (cc->stage == (uint8_t)CONT_STAGE_NONE && magcal_cont_no_gravity(cc) != 0) {
        /* never a gravity: raw z's noise (cont_slope.c), between solves (it is stationary, and the
         * drain's cost while a solve runs counts in m4f_cal2d_interleaved_instr) */
        magcal_cont_slope_noise(cc, m, t_ms);
    }
    if (magcal_cont_continuity(cc, m, t_ms) == 0) {
        magcal_cont_rate_reset(cc); /* a sample the gyro's track does not take restarts it */
        return 1; /* before a calibration judges the stream: a jump from the sample before, never stored */
    }
    if (cc->state == (uint8_t)MAGCAL_CONT_RELEARNING) {
        magcal_cont_rate_reset(cc);
    } else if (magcal_cont_judge(cc, levelled != 0 && cc->cal_lv == 0u ? &cc->jm : m,
                                 (levelled != 0 && cc->cal_conv != 0u) ? 1 : 0, &j) != 0) {
        j.tilted = (uint8_t)((cc->j_tilted != 0u && cc->fz_on == 0u) ? 1u : 0u); /* set by the drain */
        /* the gyro's rotation queued with a ring sample (the drain's, at cc->tail; a parked one has none) */
        magcal_cont_rate(cc, &j, (m != &cc->park_m) ? cc->ring_dy[cc->tail % MAGCAL_CONT_RING] : NAN, t_ms);
        const int changed = magcal_cont_episode(cc, &j, t_ms);
        if (magcal_cont_no_gravity(cc) != 0 && changed == 0 && cc->dist_flag == 0u && j.gross == 0u) {
            /* never a gravity: the slopes of now (cont_slope.c), from samples over the per-sample
             * threshold too (an unlevelled hill is a mismatch of the radius), not from a flagged
             * transient or change evidence (a truck or a step is no slope) */
            magcal_cont_slope(cc, &j, cc->dist_dt);
        }
        if (changed != 0) {
            magcal_cont_declare_change(cc); /* the store restarts with this sample */
        } else if (j.mismatch != 0u) {
            return 1; /* inconsistent with the installed calibration: never stored */
        } else {
            /* consistent: stored */
        }
    } else {
        /* no calibration installed: nothing judges the sample (its gyro track starts at the next one) */
    }
    return 0;
}

/* The drained levelled sample m as push_g received it (cc->jm: what a calibration fitted on
 * unlevelled samples judges): x, y back by k t; z back by the tilt's share of the horizontal
 * field (cont_tc_level, with the k and the centre of now: a change since the push moves it by
 * the change times a tilt of a few degrees). */
static void cont_unlevel(magcal_cont_t *cc, const magcal_vec3_t *m, const magcal_vec3_t *tl)
{
    /* cont_tc_level inverted to the same order: h' = h + k t - (h . t) t / 2, z' = z (1 + t^2 / 2) - t . h' */
    const float t2 = tl->x * tl->x + tl->y * tl->y;
    const float ht = tl->x * (m->x - cc->store.centre.x) + tl->y * (m->y - cc->store.centre.y);
    cc->jm.x = m->x + cc->tc_kl * tl->x - 0.5f * ht * tl->x;
    cc->jm.y = m->y + cc->tc_kl * tl->y - 0.5f * ht * tl->y;
    cc->jm.z = m->z * (1.0f + 0.5f * t2) - tl->x * (cc->jm.x - cc->store.centre.x) - tl->y * (cc->jm.y - cc->store.centre.y);
}

/* A stored sample's tilt into the mean tilt of the store's samples (st_tx, st_ty: what an
 * unlevelled fit of the store sees; cont_relevel): a levelled sample counts as level, a sample
 * whose gravity gave no tilt (a turn, braking) with the tilt push_g held (cc->tc_h, known 1..2 s
 * before the last one: not the acceleration ramping in; tl->z 0.5: circles under 0.2 g of
 * centripetal acceleration on a 4-deg hill otherwise left the fit tilt unknown and the trust's
 * tilt off, headings 8.5 deg off OK), a sample of push (no gravity) is left out. An EMA over
 * CONT_TF_N samples, about the store's turnover on the move (the store keeps the newest of each
 * bin). */
static void cont_fit_tilt(magcal_cont_t *cc, const magcal_vec3_t *tl, int lv)
{
    const float tx = (lv != 0) ? 0.0f : tl->x;
    const float ty = (lv != 0) ? 0.0f : tl->y;
    float w;
    if (!(tl->z > 0.0f)) {
        return;
    }
    if (cc->st_tn < CONT_TF_N) {
        cc->st_tn++;
    }
    w = 1.0f / (float)cc->st_tn;
    cc->st_tx += (tx - cc->st_tx) * w;
    cc->st_ty += (ty - cc->st_ty) * w;
    cc->st_t2 += (tx * tx + ty * ty - cc->st_t2) * w;
}

/* The store's tilt code of a ring code (push_g's levelled samples are LEVEL). */
static magcal_intake_tilt_t cont_store_tilt(uint8_t code)
{
    return code == MAGCAL_CONT_TILT_LEVELLED ? MAGCAL_INTAKE_TILT_LEVEL : (magcal_intake_tilt_t)code;
}

/* Ring samples into the store, read in place (push does not reuse a slot before tail moves past
 * it). The store's push is called from here directly: it is the deep path (its survey fits).
 * At most `max` samples; at least one when the ring is not empty; then only while less than half
 * of the budget is spent (the solve keeps the rest). A push that ended a survey sweep charges
 * CONT_W_SWEEP, which ends the drain. */
/* Parking (cont_park): a FIFO of cc->slots / 2 samples in the solver buffer, park_i / park_n
 * its free-running read / write counts. */
static uint32_t cont_park_cap(const magcal_cont_t *cc)
{
    return (uint32_t)(cc->slots / 2u);
}

/* The next parked sample (older than the ring's), copied into the instance (no stack on the
 * drain's deep path); NULL when none is left. */
static MAGCAL_NOINLINE const magcal_vec3_t *cont_unpark(magcal_cont_t *cc)
{
    const magcal_vec2_t *pk;
    if (cc->park_i == cc->park_n) {
        return NULL;
    }
    pk = &cc->buf[(size_t)2u * (cc->park_i % cont_park_cap(cc))];
    cc->park_m.x = pk[0].x;
    cc->park_m.y = pk[0].y;
    cc->park_m.z = pk[1].x;
    /* cppcheck-suppress misra-c2012-21.15 ; deviation D15: the stamp's 32 bits round-trip through a float slot of the parked sample */
    (void)memcpy(&cc->park_t, &pk[1].y, sizeof cc->park_t);
    {
        const uint32_t q = cc->park_i % cont_park_cap(cc);
        cc->park_tilt = ((cc->park_lv[q / 32u] >> (q % 32u)) & 1u) != 0u ? (uint8_t)MAGCAL_INTAKE_TILT_LEVEL
                                                                          : (uint8_t)MAGCAL_INTAKE_TILT_UNKNOWN;
    }
    cc->park_i++;
    return &cc->park_m;
}

/* 1 when the next store push may end a survey sweep (its sweep steps may reach the last slot:
 * each step visits a slot or jumps the rest of a bin); unlimited budget (solve_blocking), the
 * drain takes such a sample only as its first. */
static int cont_may_end_sweep(const magcal_cont_t *cc)
{
    const magcal_intake_t *st = &cc->store;
    return st->cursor + (uint32_t)st->cfg.sweep_steps * (uint32_t)st->cfg.per_bin >= magcal_intake_nslots(st);
}

/* 1 when the sliced sweep part's first step ends the store's sweep (cont_sweep_part: its fits,
 * CONT_W_SWEEP), so a drain that takes a second sample must leave that much of the budget. */
static int cont_sweep_end_due(const magcal_cont_t *cc)
{
    return (cc->store.cursor >= magcal_intake_nslots(&cc->store)) ? 1 : 0;
}

/* 1 when no solve is under way and the drain is behind: the ring holds a quarter of its size
 * or more, or samples parked during the field-model fit are still queued (while they are, every
 * ring sample joins the queue behind them, and no solve starts until it is empty). The steps
 * that do not drain (the coverage count's, the snapshot's) leave one sample each behind, and a
 * drain of one sample per step (its measured weight is more than half the budget) would never
 * catch up at one push per step (the parked queue would never empty: no solve after the first
 * adoption); such a step takes a second sample (the only steps that do), unless the first ended
 * a sweep (the budget is then spent). */
static int cont_behind(const magcal_cont_t *cc)
{
    return cc->stage == (uint8_t)CONT_STAGE_NONE &&
           (cc->head - cc->tail >= MAGCAL_CONT_RING / 4u || cc->park_n != cc->park_i);
}

/* The store push of a drained sample without its sweep steps (the step runs them once for all
 * the samples it drained, cont_sweep_part): the store's configured count is lent to the step. */
static void cont_push_nosweep(magcal_cont_t *cc, const magcal_vec3_t *m, magcal_intake_tilt_t tilt)
{
    const uint16_t steps = cc->store.cfg.sweep_steps;
    cc->store.cfg.sweep_steps = 0u;
    (void)magcal_intake_push_tilt(&cc->store, m, tilt, NULL);
    cc->store.cfg.sweep_steps = steps;
}

/* Ring samples into the store: the first one always (when the ring or the parked queue is not
 * empty); a further one (at most `max`) only when the drain is behind (cont_behind) and its
 * charge (CONT_W_PUSH, its judge) fits what is left of the budget. Sliced, a sample's push does
 * no sweep step: the step runs cfg.sweep_steps of them after the drain (cont_sweep_part), once
 * per step whatever it drained, so the sweep keeps its pace in time (one push per step: as
 * before) and a catch-up step that takes two samples does not pay two sweeps. Unlimited budget
 * (solve_blocking): every sample's push with its own sweep steps, as magcal_intake_push. */
static MAGCAL_NOINLINE uint32_t cont_drain(magcal_cont_t *cc, uint32_t max, magcal_cal_budget_t *b)
{
    uint32_t k;
    uint32_t pushed = 0u;
    /* cppcheck-suppress misra-c2012-15.4 ; deviation D13: a resumable loop leaves at its pause point (budget, ring empty) */
    for (k = max; k > 0u; --k) {
        const uint32_t t = cc->tail;
        uint32_t w = CONT_W_PUSH;
        const magcal_vec3_t *m;
        const magcal_vec3_t *tl;
        int lv;
        uint8_t code;
        const int judged = cont_judge_on(cc);
        if (judged != 0) {
            w += CONT_W_JUDGE;
        }
        if (k != max && b->unlimited == 0u &&
            (cont_behind(cc) == 0 || w > b->left || (cont_sweep_end_due(cc) != 0 && w + CONT_W_SWEEP > b->left))) {
            break; /* a second sample only when it fits, with the sweep end the sweep part then runs */
        }
        if (k != max && b->unlimited != 0u && cont_may_end_sweep(cc) != 0) {
            break; /* unlimited: a push that may end a sweep is only ever the drain's first sample */
        }
        m = cont_unpark(cc);
        if (m == NULL) {
            if (t == cc->head) {
                break;
            }
            MAGCAL_CONT_BARRIER(); /* the slot was written before head */
            m = &cc->ring[t % MAGCAL_CONT_RING];
        }
        tl = (m != &cc->park_m) ? &cc->ring_tl[t % MAGCAL_CONT_RING] : NULL;
        /* push_g's code of the sample (a parked one is LEVEL or UNKNOWN, never LEVELLED) */
        code = (m == &cc->park_m) ? cc->park_tilt : cc->ring_tilt[t % MAGCAL_CONT_RING];
        lv = 0;
        if (judged != 0) {
            /* as push_g classified it: the judge's change evidence (cont_change.c) */
            cc->j_tilted = (uint8_t)((code == (uint8_t)MAGCAL_INTAKE_TILT_TILTED) ? 1u : 0u);
        }
        if (tl != NULL && code == (uint8_t)MAGCAL_CONT_TILT_LEVELLED) {
            lv = 1;
            if (judged != 0 && cc->cal_conv != 0u) {
                /* levelled as the heading levels it (magcal_cont_heading: the fit tilt's centre) */
                cc->jm.x = m->x + cc->tc_kl * cc->cal_tx;
                cc->jm.y = m->y + cc->tc_kl * cc->cal_ty;
                cc->jm.z = m->z;
            } else if (judged != 0 && cc->cal_lv == 0u) {
                cont_unlevel(cc, m, tl); /* cc->jm: read by cont_screen's judge only then */
                if (tl->x * tl->x + tl->y * tl->y > cc->store.tilt_tan2) {
                    cc->j_tilted = 1u; /* judged as pushed: beyond the level limit */
                }
            } else {
                /* not judged, or under a levelled calibration: the levelled sample itself */
            }
        }
        if (cont_screen(cc, m, m == &cc->park_m ? cc->park_t : cc->ring_t[t % MAGCAL_CONT_RING], lv) == 0) {
            /* stored samples are counted by the store (added + replaced); with the tilt code of
             * push_g (the store's level preference) */
            const magcal_intake_tilt_t tilt = cont_store_tilt(code);
            const uint32_t before = cc->store.ctr.added + cc->store.ctr.replaced;
            if (b->unlimited != 0u) {
                (void)magcal_intake_push_tilt(&cc->store, m, tilt, NULL);
            } else {
                cont_push_nosweep(cc, m, tilt);
            }
            if (tl != NULL && cc->store.ctr.added + cc->store.ctr.replaced != before) {
                cont_fit_tilt(cc, tl, lv);
            }
            pushed++;
        }
        if (m != &cc->park_m) {
            MAGCAL_CONT_BARRIER(); /* read before the slot is handed back */
            cc->tail = t + 1u;
        }
        CONT_TRACE(magcal_bench_cont_trace[TR_DRAINED]++;)
        CONT_TRACE(magcal_bench_cont_trace[TR_JUDGED] += (w > CONT_W_PUSH) ? 1u : 0u;)
        (void)magcal_cal_spend(b, w);
    }
    return pushed; /* samples pushed into the store (judged consistent) */
}

/* The least share of a step worth a solve call: CONT_SOLVE_MIN, at most a third of the budget. */
static uint32_t cont_solve_min(const magcal_cont_t *cc)
{
    const uint32_t third = cc->cfg.step_budget / 3u;
    return third < CONT_SOLVE_MIN ? third : CONT_SOLVE_MIN;
}

/* The step's sweep steps (sliced; after a drain that pushed a sample into the store): up to cfg.sweep_steps, each
 * charged by what it did (a surveyed slot CONT_W_VISIT, a re-bin CONT_W_REBIN, a bin jump
 * CONT_W_JUMP), stopping when the budget is spent; the end of a sweep (its fits, CONT_W_SWEEP) is
 * only ever the part's first step and its only one (as a push's, sweep.c). */
static MAGCAL_NOINLINE void cont_sweep_part(magcal_cont_t *cc, magcal_cal_budget_t *b)
{
    /* the charge of a sweep step by what it did (intake_internal.h INTAKE_SWEEP_*) */
    static const uint16_t w_of[4] = {(uint16_t)CONT_W_JUMP, (uint16_t)CONT_W_VISIT, (uint16_t)CONT_W_REBIN,
                                     (uint16_t)CONT_W_SWEEP};
    /* a solve under way keeps its least share (one sweep step per stored sample) */
    const uint32_t keep = (cc->stage != (uint8_t)CONT_STAGE_NONE) ? cont_solve_min(cc) + CONT_W_REBIN : 0u;
    CONT_TRACE(const uint32_t sweeps0 = cc->store.sweeps;)
    CONT_TRACE(const uint32_t reb0 = cc->store.ctr.rebinned;)
    CONT_TRACE(const uint32_t sv0 = cc->store.sv_n;)
    magcal_intake_sweep_part(&cc->store, w_of, keep, &b->left);
    CONT_TRACE(magcal_bench_cont_trace[TR_SWEEPS] += cc->store.sweeps - sweeps0;)
    CONT_TRACE(magcal_bench_cont_trace[TR_REBINS] += cc->store.ctr.rebinned - reb0;)
    /* the slots surveyed (a part that ends the sweep surveys none) */
    CONT_TRACE(magcal_bench_cont_trace[TR_VISITS] += (cc->store.sweeps == sweeps0) ? cc->store.sv_n - sv0 : 0u;)
}

/* During the field-model fit the store must not change: ring samples are parked, in order, in
 * the solver buffer (free between solves: 2 entries per sample, raw x, y, z and the stamp's bits;
 * a FIFO of cc->slots / 2 samples), so a fit of many steps does not overflow the ring. After the
 * fit the drain takes them first, the ring's samples still join the FIFO behind them (so the
 * ring does not fill while the backlog drains), and no solve starts (no snapshot into the
 * buffer) until it is empty. */
static MAGCAL_NOINLINE void cont_park(magcal_cont_t *cc, magcal_cal_budget_t *b)
{
    /* cppcheck-suppress misra-c2012-15.4 ; deviation D13: a resumable loop leaves at its pause point (budget, ring empty) */
    while (cc->park_n - cc->park_i < cont_park_cap(cc)) {
        const uint32_t t = cc->tail;
        magcal_vec2_t *pk = &cc->buf[(size_t)2u * (cc->park_n % cont_park_cap(cc))];
        if (t == cc->head) {
            break;
        }
        MAGCAL_CONT_BARRIER(); /* the slot was written before head */
        pk[0].x = cc->ring[t % MAGCAL_CONT_RING].x;
        pk[0].y = cc->ring[t % MAGCAL_CONT_RING].y;
        pk[1].x = cc->ring[t % MAGCAL_CONT_RING].z;
        /* cppcheck-suppress misra-c2012-21.15 ; deviation D15: the stamp's 32 bits round-trip through a float slot of the parked sample */
        (void)memcpy(&pk[1].y, &cc->ring_t[t % MAGCAL_CONT_RING], sizeof pk[1].y);
        {
            const uint32_t q = cc->park_n % cont_park_cap(cc);
            const uint32_t bit = (uint32_t)1u << (q % 32u);
            cc->park_lv[q / 32u] = (cont_store_tilt(cc->ring_tilt[t % MAGCAL_CONT_RING]) == MAGCAL_INTAKE_TILT_LEVEL)
                                       ? (cc->park_lv[q / 32u] | bit)
                                       : (cc->park_lv[q / 32u] & ~bit);
        }
        MAGCAL_CONT_BARRIER(); /* read before the slot is handed back */
        cc->tail = t + 1u;
        cc->park_n++;
        if (magcal_cal_spend(b, CONT_W_PARK) != 0) {
            break;
        }
    }
}

/* Worth a solve: enough new information (cheap counters first), then the live coverage, which
 * counts only ring samples (intake progress.c, O(slots)) and so agrees with the solver's. */
/* The cheap half of cont_worth: new information since the last solve, enough samples, and the
 * store changed since the last coverage count (1 = the O(slots) coverage count is due). */
static int cont_worth_due(const magcal_cont_t *cc)
{
    const uint32_t st = cc->store.ctr.added + cc->store.ctr.replaced;
    int due = 0;
    /* a pending cut (an INCONSISTENT solve, cont_adopt.c, or a level shift, cont_shift.c) is new
     * information: the store without its older samples is solved again at once (each cut drops at
     * least the oldest sample) */
    if ((st - cc->stored_at_solve >= cc->cfg.min_new || cc->drop_on != 0u || cc->sh_cut != 0u ||
         (cc->last_status == MAGCAL_ERR_NOT_BETTER && (float)cc->solve_ms_acc >= 0.25f * cc->cfg.age_ms)) &&
        cc->park_n == cc->park_i && cc->store.ctr.stored >= cc->cfg.solver.min_samples &&
        (cc->worth_checked == 0u || cc->worth_seen != st || cc->drop_on != 0u || cc->sh_cut != 0u)) {
        due = 1;
    }
    return due;
}

/* 1 when the store's progress p starts a solve (a centre, no re-binning under way, the coverage
 * of the full solve or of the offset-only relearn: magcal_cont_offset_pick sets which). */
static int cont_progress_starts(magcal_cont_t *cc, const magcal_intake_progress_t *p)
{
    return p->centre_source != MAGCAL_INTAKE_CENTRE_NONE && p->rebinning == 0u &&
           magcal_cont_offset_pick(cc, p->coverage_deg, magcal_cont_solve_cov(cc)) != 0;
}

static int cont_worth(magcal_cont_t *cc)
{
    magcal_intake_progress_t p;
    if (cont_worth_due(cc) == 0) {
        return 0;
    }
    cc->worth_seen = cc->store.ctr.added + cc->store.ctr.replaced;
    cc->worth_checked = 1u;
    (void)magcal_intake_progress(&cc->store, &p);
    return cont_progress_starts(cc, &p);
}

/* Start a solve: the snapshot of the store (the drain pauses until it is complete, so the
 * solver sees one consistent store; it takes ceil(stored x CONT_W_SNAP / budget) steps). */
static void cont_start(magcal_cont_t *cc)
{
    magcal_cont_shift_to_cut(cc); /* a level shift since the last snapshot: cut at its first jump */
    cc->snap_bin = 0u;
    cc->snap_n = 0u;
    cc->snap_lv = 0u;
    cc->snap_stored = cc->store.ctr.added + cc->store.ctr.replaced;
    cc->stage = (uint8_t)CONT_STAGE_SNAPSHOT;
}

/* The coverage count of the sliced step (cont_worth's, resumable over bins, intake progress.c):
 * started when cont_worth_due, continued within what the drain left of the budget (at least one
 * bin), restarted when the store's centre moved meanwhile (its bins mean other directions). The
 * drain keeps running during it: a bin counted before a sample reached it reads as at the count's
 * start. 1 when the count ended and a solve is worth starting. */
static MAGCAL_NOINLINE int cont_count_part(magcal_cont_t *cc, magcal_cal_budget_t *b)
{
    const magcal_intake_t *st = &cc->store;
    magcal_intake_progress_t p;
    uint32_t used;
    if (cc->cnt_on == 0u || cc->cnt_gen != st->gen || cc->cnt_src != st->centre_source) {
        if (cont_worth_due(cc) == 0) {
            cc->cnt_on = 0u;
            return 0;
        }
        cc->worth_seen = st->ctr.added + st->ctr.replaced;
        cc->worth_checked = 1u;
        cc->cnt_on = 1u;
        cc->cnt_bin = 0u;
        cc->cnt_gen = st->gen;
        cc->cnt_src = st->centre_source;
    }
    CONT_TRACE(magcal_bench_cont_trace[TR_WORTH] = 1u;)
    CONT_TRACE(magcal_bench_cont_trace[TR_COUNT_INSN] = cont_trace_ticks();)
    used = magcal_intake_count_step(st, cc->cnt_words, magcal_intake_count_depth(st), &cc->cnt_bin, &cc->cnt_filled,
                                    &cc->cnt_deep, b->left);
    CONT_TRACE(magcal_bench_cont_trace[TR_COUNT_INSN] = ((magcal_bench_cont_trace[TR_COUNT_INSN] - cont_trace_ticks()) & 0xFFFFFFu) * 40u;)
    CONT_TRACE(magcal_bench_cont_trace[TR_COUNT_CHARGED] = used;)
    (void)magcal_cal_spend(b, used);
    if (cc->cnt_bin < st->n_bins) {
        return 0;
    }
    cc->cnt_on = 0u;
    magcal_intake_progress_of(st, cc->cnt_words, cc->cnt_filled, cc->cnt_deep, &p);
    return cont_progress_starts(cc, &p);
}

/* The age scan of a pending cut (drop_on 1), within the step's budget: the oldest stored sample's
 * age, then the cut at half of it (drop_on 2); the copy then starts at bin 0 in the next step. */
static void cont_cut_scan(magcal_cont_t *cc, magcal_cal_budget_t *b)
{
    const magcal_intake_t *st = &cc->store;
    const uint32_t per = st->cfg.per_bin;
    if (cc->snap_bin == 0u) {
        cc->drop_age = 0u;
    }
    while (cc->snap_bin < st->n_bins) {
        const uint32_t base = cc->snap_bin * per;
        const uint32_t cnt = st->count[cc->snap_bin];
        uint32_t k;
        for (k = 0u; k < cnt; ++k) {
            const uint32_t age = (st->seq - st->slots[base + k].seq) & INTAKE_SEQ_MASK;
            cc->drop_age = age > cc->drop_age ? age : cc->drop_age;
        }
        cc->snap_bin++;
        if (magcal_cal_spend(b, CONT_W_BIN + cnt * CONT_W_AGE) != 0) {
            return;
        }
    }
    cc->drop_seq = (st->seq - cc->drop_age / 2u) & INTAKE_SEQ_MASK;
    cc->drop_on = 2u;
    cc->snap_bin = 0u;
}

/* The tilt term of the solve's estimate (continuous.h "Tilt in the estimate"): with push_g's
 * gravity, cfg.tilt_model_deg x the share of the snapshot not level (tilted and not levelled, or
 * accelerating); 0 without gravity (nothing is known of the tilt) or with the term off. */
static float cont_tilt_model(const magcal_cont_t *cc)
{
    uint32_t tilted;
    if (cc->g_pushed == 0u || cc->snap_n == 0u || cc->snap_lv > cc->snap_n) {
        return 0.0f;
    }
    tilted = cc->snap_n - cc->snap_lv;
    return cc->cfg.tilt_model_deg * (float)tilted / (float)cc->snap_n;
}

/* The snapshot's LEVEL samples: those of the bin just copied (what it holds after a cut). */
static void cont_snap_level(magcal_cont_t *cc, uint32_t base)
{
    const magcal_intake_t *st = &cc->store;
    uint32_t k;
    for (k = 0u; k < st->count[cc->snap_bin]; ++k) {
        cc->snap_lv += (st->slots[base + k].seq & INTAKE_SEQ_LEVEL) != 0u ? 1u : 0u;
    }
}

/* Copy bins of the store, in bin order (as magcal_intake_snapshot2), into the solver buffer;
 * then load the solver. 1 when the solve is loaded. A pending cut (an INCONSISTENT solve) first
 * scans the store's ages, then drops what the cut drops while copying. */
static int cont_snapshot(magcal_cont_t *cc, magcal_cal_budget_t *b)
{
    const magcal_intake_t *st = &cc->store;
    const uint32_t per = st->cfg.per_bin;
    if (cc->drop_on == 1u && cc->snap_bin == 0u && cc->drop_changes != cc->changes) {
        cc->drop_on = 0u; /* a change reset the store (and its push counter) since: void */
    }
    if (cc->drop_on == 1u) {
        cont_cut_scan(cc, b);
        return 0;
    }
    while (cc->snap_bin < st->n_bins) {
        const uint32_t base = cc->snap_bin * per;
        const uint32_t cnt = st->count[cc->snap_bin];
        uint32_t w = CONT_W_SNAP;
        if (cc->drop_on != 0u) {
            /* the cut (an INCONSISTENT solve, cont_adopt.c): the bin's samples older than the cut or
             * off the solve's ring by more than half its radius (neither installation: a stored
             * glitch burst would otherwise outweigh what is left) leave the store (the store is
             * frozen meanwhile), the rest is copied */
            magcal_intake_drop_older(&cc->store, cc->snap_bin, cc->drop_seq, &cc->drop_c, cc->drop_r, cc->buf,
                                     cc->slots, &cc->snap_n);
            w = CONT_W_SNAP + CONT_W_CUT;
        } else {
            uint32_t k;
            for (k = 0u; k < cnt && cc->snap_n < cc->slots; ++k) {
                cc->buf[cc->snap_n].x = st->slots[base + k].m.x;
                cc->buf[cc->snap_n].y = st->slots[base + k].m.y;
                cc->snap_n++;
            }
        }
        cont_snap_level(cc, base);
        cc->snap_bin++;
        if (magcal_cal_spend(b, CONT_W_BIN + cnt * w) != 0) {
            return 0;
        }
    }
    if (cc->drop_on != 0u) {
        cc->drop_on = 0u;
        cc->worth_checked = 0u; /* the store lost samples: its coverage is counted again */
    }
    if (cc->off_mode != 0u && magcal_cont_offset_eligible(cc) != 0) {
        magcal_cont_offset_begin(cc); /* the offset-only relearn (calibrator_offset.c) */
    } else {
        cc->off_mode = 0u;
        magcal_calibrator_set_model(&cc->solver, cont_tilt_model(cc));
        (void)magcal_calibrator_solve_begin(&cc->solver, cc->snap_n, 1);
    }
    (void)magcal_cal_spend(b, CONT_W_SNAP_END);
    cc->cand = cc->cal;
    cc->stage = (uint8_t)CONT_STAGE_SOLVE;
    return 1;
}

/* The snapshot part of a step: 1 while the snapshot is unfinished or it spent the budget. */
static MAGCAL_NOINLINE int cont_snapshot_part(magcal_cont_t *cc, magcal_cal_budget_t *b)
{
    if (cc->stage == (uint8_t)CONT_STAGE_SNAPSHOT) {
        int done;
        CONT_TRACE(const uint32_t left0 = b->left;)
        CONT_TRACE(magcal_bench_cont_trace[TR_SNAP_INSN] = cont_trace_ticks();)
        done = cont_snapshot(cc, b);
        CONT_TRACE(magcal_bench_cont_trace[TR_SNAP_INSN] = ((magcal_bench_cont_trace[TR_SNAP_INSN] - cont_trace_ticks()) & 0xFFFFFFu) * 40u;)
        CONT_TRACE(magcal_bench_cont_trace[TR_SNAP_CHARGED] = left0 - b->left;)
        if (done == 0 || (b->unlimited == 0u && b->left == 0u)) {
            return 1;
        }
    }
    return 0;
}

/* A solve ended with st: adoption over time (cont_adopt.c), the outcome. An adoption starts the
 * field-model fit (stage FIT, the following steps; the judge is radius-only until it ends). */
static MAGCAL_NOINLINE magcal_cont_outcome_t cont_end(magcal_cont_t *cc, magcal_status_t st)
{
    cc->stage = (uint8_t)CONT_STAGE_NONE;
    cc->fit_phase = 0u;
    cc->last_outcome = magcal_cont_finish_solve(cc, st);
    if (cc->last_outcome == MAGCAL_CONT_ADOPTED) {
        cc->cal_offset = cc->off_mode; /* the mark of an offset-only relearn (calibrator_offset.c) */
    }
    cc->off_mode = 0u;
    /* new information counts from the store the solve saw (its snapshot), not from its end */
    cc->stored_at_solve = cc->snap_stored;
    if (cc->fit_phase != 0u) {
        cc->stage = (uint8_t)CONT_STAGE_FIT;
    }
    return cc->last_outcome;
}

/* Field-model fit work within the budget (at least one visit): IN_PROGRESS while it lasts, IDLE
 * when it ended. */
static MAGCAL_NOINLINE magcal_cont_outcome_t cont_fit_part(magcal_cont_t *cc, magcal_cal_budget_t *b)
{
    if (magcal_cont_fit_step(cc, b) == 0) {
        return MAGCAL_CONT_IN_PROGRESS;
    }
    cc->stage = (uint8_t)CONT_STAGE_NONE;
    return MAGCAL_CONT_IDLE;
}

/* The solver's share of a step: what the drain and the snapshot left, at most CONT_SOLVE_CAP /
 * CONT_SOLVE_DIV of the budget (its phases' weights are estimates: measured up to ~1.4x over on
 * the target, tools/bench/cont_weights.py, so a step with nothing drained stays well under
 * 10,000 at the default budget), at least 1 (a solver step does at least one visit: progress at
 * any budget; the result never depends on the budget, only the number of steps). */
static uint32_t cont_solver_budget(const magcal_cont_t *cc, const magcal_cal_budget_t *b)
{
    const uint32_t cap = cc->cfg.step_budget - (cc->cfg.step_budget / CONT_SOLVE_DIV) * (CONT_SOLVE_DIV - CONT_SOLVE_CAP);
    uint32_t w = b->left < cap ? b->left : cap;
    if (b->unlimited != 0u) {
        w = UINT32_MAX;
    }
    return w > 0u ? w : 1u;
}

/* Solve work within the budget (at least one visit); the outcome when the solve ended. The
 * snapshot and the end are siblings of the solver's step (not frames above it): only this
 * function's frame sits between step() and the solver's phases (stack budget). */
CONT_INLINE magcal_cont_outcome_t cont_solve(magcal_cont_t *cc, magcal_cal_budget_t *b)
{
    magcal_status_t st;
    magcal_cont_outcome_t oc;
    if (cc->stage == (uint8_t)CONT_STAGE_FIT) {
        return cont_fit_part(cc, b);
    }
    if (cont_snapshot_part(cc, b) != 0) {
        return MAGCAL_CONT_IN_PROGRESS;
    }
    if (cc->off_mode != 0u) {
        /* the offset-only relearn instead of the solver (calibrator_offset.c), the solver's share */
        st = magcal_cont_offset_step(cc, cont_solver_budget(cc, b));
    } else {
        CONT_TRACE(magcal_bench_cont_trace[TR_SOLVE_BUDGET] = cont_solver_budget(cc, b);)
        CONT_TRACE(magcal_bench_cont_trace[TR_PHASE_IN] = magcal_bench_solve_phase(&cc->solver, &magcal_bench_cont_trace[TR_SOLVE_LEFT]);)
        CONT_TRACE(magcal_bench_cont_trace[TR_SOLVE_INSN] = cont_trace_ticks();)
        st = magcal_calibrator_solve_step(&cc->solver, &cc->cand, cont_solver_budget(cc, b), &cc->last);
        CONT_TRACE(magcal_bench_cont_trace[TR_SOLVE_INSN] = ((magcal_bench_cont_trace[TR_SOLVE_INSN] - cont_trace_ticks()) & 0xFFFFFFu) * 40u;)
        CONT_TRACE(magcal_bench_cont_trace[TR_PHASE_OUT] = magcal_bench_solve_phase(&cc->solver, &magcal_bench_cont_trace[TR_SOLVE_LEFT]);)
    }
    if (st == MAGCAL_IN_PROGRESS) {
        return MAGCAL_CONT_IN_PROGRESS;
    }
    oc = cont_end(cc, st);
    if (cc->stage == (uint8_t)CONT_STAGE_FIT && b->unlimited != 0u) {
        (void)cont_fit_part(cc, b); /* unlimited: the whole fit now (else from the next step on) */
    }
    return oc;
}

/* The compensation came on under an installed calibration fitted on unlevelled samples (adopted
 * before k was known, or restored at init): continuous.h "Tilt compensation". Between solves and
 * fits, the store is emptied so that it refills with levelled samples only; the calibration stays
 * in force, judged on un-levelled samples (cont_screen), until a solve on the levelled store adopts
 * a new one or confirms it (cont_adopt.c). When it was adopted here on one slope (its fit's mean
 * tilt known, its spread small), magcal_cont_heading levels at once: cal_conv. */
static MAGCAL_NOINLINE void cont_relevel(magcal_cont_t *cc)
{
    if (cc->tc_on == 0u || cc->has_cal == 0u || cc->cal_lv != 0u || cc->relevel != 0u ||
        cc->state == (uint8_t)MAGCAL_CONT_RELEARNING || cc->stage != (uint8_t)CONT_STAGE_NONE ||
        cc->park_n != cc->park_i) {
        return;
    }
    (void)magcal_intake_reset(&cc->store);
    cc->stored_at_solve = 0u;
    cc->stored_at_adopt = 0u;
    cc->cnt_on = 0u;
    cc->st_tn = 0u;
    if (cc->cal_tk != 0u && cc->cal_ts <= CONT_TF_SPREAD) {
        cc->cal_conv = 1u;
        cc->levels++;
        magcal_cont_transient_reset(cc); /* its samples are judged levelled from now on */
        /* levelled by k times its fit tilt: the tilt term leaves its estimate ("OK tolerance") */
        if (magcal_isfinite_f(cc->adopted_err) != 0) {
            cc->adopted_err = sqrtf(fmaxf(cc->adopted_err * cc->adopted_err - cc->adopted_tilt * cc->adopted_tilt, 0.0f));
        }
    }
    magcal_cont_centre_store(cc);
    cc->relevel = 1u;
    cc->relevels++;
}

/* The body of magcal_cont_step within the budget b (inlined: called once). */
static inline magcal_cont_outcome_t cont_step_in(magcal_cont_t *cc, magcal_cal_budget_t *bp)
{
    cc->change_flag = 0u;
    cont_relevel(cc);
    if (cont_store_frozen(cc) == 0) {
        CONT_TRACE(magcal_bench_cont_trace[TR_DRAIN_INSN] = cont_trace_ticks();)
        /* the parked samples first; then, sliced, the step's sweep steps when a sample was stored */
        if (cont_drain(cc, cc->cfg.drain_per_step, bp) != 0u && bp->unlimited == 0u && cc->change_flag == 0u) {
            cont_sweep_part(cc, bp);
        }
        CONT_TRACE(magcal_bench_cont_trace[TR_DRAIN_INSN] = ((magcal_bench_cont_trace[TR_DRAIN_INSN] - cont_trace_ticks()) & 0xFFFFFFu) * 40u;)
    }
    if (cc->stage == (uint8_t)CONT_STAGE_FIT || cc->park_n != cc->park_i) {
        cont_park(cc, bp); /* the ring's samples behind them (at least one moved) */
    }
    if (cc->change_flag != 0u) {
        cc->cnt_on = 0u;
        return MAGCAL_CONT_CHANGE;
    }
    if (cc->stage == (uint8_t)CONT_STAGE_NONE) {
        if (bp->unlimited == 0u) {
            /* sliced: the coverage count within what the drain left (over several steps) */
            if (bp->left == 0u || cont_count_part(cc, bp) == 0) {
                return MAGCAL_CONT_IDLE;
            }
            cont_start(cc);
            return MAGCAL_CONT_IN_PROGRESS; /* the snapshot from the next step on */
        }
        if (cont_worth(cc) == 0) {
            return MAGCAL_CONT_IDLE;
        }
        cont_start(cc);
    }
    if (bp->unlimited == 0u && (bp->left == 0u || bp->left < cont_solve_min(cc))) {
        return MAGCAL_CONT_IN_PROGRESS; /* the drain spent (nearly) the budget (a sweep end, a catch-up): next step */
    }
    return cont_solve(cc, bp);
}

magcal_cont_outcome_t magcal_cont_step(magcal_cont_t *cc)
{
    magcal_cal_budget_t b;
    magcal_cont_outcome_t oc;
    if (!magcal_cont_ok(cc)) {
        return MAGCAL_CONT_IDLE;
    }
    b.left = cc->cfg.step_budget;
    b.unlimited = (uint8_t)(cc->cfg.step_budget == UINT32_MAX ? 1u : 0u);
    CONT_TRACE((void)memset(magcal_bench_cont_trace, 0, sizeof magcal_bench_cont_trace);)
    CONT_TRACE(magcal_bench_cont_trace[TR_STAGE_IN] = (uint32_t)cc->stage | ((uint32_t)cc->fit_phase << 8);)
    oc = cont_step_in(cc, &b);
    CONT_TRACE(magcal_bench_cont_trace[TR_STAGE_OUT] = (uint32_t)cc->stage | ((uint32_t)cc->fit_phase << 8);)
    CONT_TRACE(magcal_bench_cont_trace[TR_CHARGED] = cc->cfg.step_budget - b.left;)
    return oc;
}

/* Blocking call, first part: start a solve if worth it (or forced). 1 = a solve is under way. */
static MAGCAL_NOINLINE int cont_begin(magcal_cont_t *cc)
{
    if (cc->stage == (uint8_t)CONT_STAGE_NONE) {
        if (cc->force != 0u) {
            cc->off_mode = 0u; /* a forced solve is the full one */
        } else if (cont_worth(cc) == 0) {
            return 0;
        } else {
            /* worth it: the solve cont_worth picked */
        }
        cont_start(cc);
    }
    return cc->stage != (uint8_t)CONT_STAGE_NONE;
}

magcal_cont_outcome_t magcal_cont_solve_blocking(magcal_cont_t *cc, int force)
{
    magcal_cal_budget_t b = {UINT32_MAX, 1u};
    if (cc == NULL || cc->magic != MAGCAL_CONT_MAGIC) {
        return MAGCAL_CONT_IDLE;
    }
    cc->force = (uint8_t)(force != 0 ? 1u : 0u); /* kept in cc: nothing but cc live across calls */
    cont_relevel(cc);
    if (cont_store_frozen(cc) == 0) {
        (void)cont_drain(cc, MAGCAL_CONT_RING + (cc->park_n - cc->park_i), &b);
    }
    if (cont_begin(cc) == 0) {
        return MAGCAL_CONT_IDLE;
    }
    /* unlimited budget: the snapshot and every remaining phase in this one call */
    return cont_solve(cc, &b);
}
