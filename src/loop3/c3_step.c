/*
 * Continuous 3-D calibrator, step: drain the push ring into the intake store (each sample judged
 * first, c3_change.c), decide whether a solve is worth running, and run it, every unit resumable
 * within cfg.step_budget estimated M4F instructions per step() call (issue 13: no call above
 * 10,000 M4F instructions at the default budget):
 *   drain     piece by piece: a sample's judge and store push, then the store's sweep steps that
 *             push owes, one at a time, each weighed by what it will do (c3_drain); one sample per
 *             step, a second only while the ring is behind (a quarter full) and the budget holds it;
 *   count     the coverage count that decides whether a solve is worth it (cells holding a sample
 *             on the ring, as magcal_intake_progress counts them), cell by cell, after the drain of
 *             the same step; due only when the cheap tests pass (centre, samples, new information)
 *             and the store changed since the last count;
 *   snapshot  the store into the solver buffer, cell by cell (the drain pauses meanwhile: the
 *             solver sees one consistent store, in the order of magcal_intake_snapshot3), then the
 *             sliced solve begins on it;
 *   solve     magcal_ellipsoid_calibrate_step with the budget but a reserve for the drain, then
 *             the drain within what the solver left (c3_solve_step);
 *   adopt     the never-worse judgement, resumable (c3_adopt.c).
 * The weights are measured on the target (QEMU, cont3_trace.elf: tools/bench/cont3_weights.py).
 */
#include "../intake/intake_internal.h"
#include "c3_internal.h"
#include "magcal/config.h"

#if MAGCAL_CFG_ENABLE_3D /* whole file: config.h feature switch (the 3-D loop needs the ellipsoid fit) */

/* Weights, estimated M4F instructions, MEASURED on the target (QEMU mps2-an386 -icount shift=0,
 * cont3_trace.elf, tools/bench/cont3_weights.py: the largest measured piece of that kind on the
 * bench tumble, rounded up, plus the loop's bookkeeping between pieces; docs/calibration_3d.md
 * "Work per call"). */
#define C3_W_PUSH 1000u      /* judge + store push of one sample (its sweep steps apart) */
#define C3_W_SW_SURVEY 600u  /* a sweep step that surveys a slot */
#define C3_W_SW_REBIN 800u   /* a sweep step that re-bins a slot (its new cell, a move) */
#define C3_W_SW_JUMP 100u    /* a sweep step that skips the rest of a cell */
#define C3_W_SW_END 7000u    /* a sweep's end: the survey's fit, a re-centre (O(cells)) */
#define C3_W_RESERVE 4000u   /* of a solve step's budget, kept for the drain (a sample and its sweep) */
#define C3_W_CBIN 60u          /* one cell of the coverage count */
#define C3_W_CSAMP 30u         /* one sample of it examined (distance to the centre) */
#define C3_W_SBIN 40u          /* one cell of the snapshot */
#define C3_W_SNAP 20u          /* one sample copied into the solver buffer */
#define C3_W_BEGIN 300u        /* the solve's begin (O(1)) */

/* The ring band of a filled cell: as src/intake/progress.c (RING_LO2, RING_HI2), so the count
 * that starts a solve agrees with the live progress. */
#define C3_RING_LO2 0.49f
#define C3_RING_HI2 1.96f

/* Per-step trace, bench-only (MAGCAL_BENCH_TRACE: tools/bench/m4f_image cont3_trace.elf, never in
 * a shipped build): what each step did and what it charged, next to the image's SysTick count
 * (tools/bench/cont3_weights.py fits the weights from it). */
#ifdef MAGCAL_BENCH_TRACE
#include <string.h>
enum {
    C3TR_STAGE_IN = 0, /* stage at entry | adopt_pass << 8 | sweep_left << 16 */
    C3TR_STAGE_OUT,    /* stage at exit | adopt_pass << 8 */
    C3TR_DRAINED,      /* samples the drain pushed */
    C3TR_SWEEPS,       /* sweep ends the drain ran */
    C3TR_CHARGED,      /* estimate charged (drain, count, snapshot, adoption, the solver's used) */
    C3TR_SOLVE_USED,   /* the solver's own estimate (slice used_; 0: not called) */
    C3TR_DRAIN_INSN,   /* the drain's instructions (SysTick around it, 40 per tick) */
    C3TR_UNIT_INSN,    /* the whole step body's */
    C3TR_VISITS,       /* count / snapshot cells visited */
    C3TR_N
};
uint32_t magcal_bench_cont3_trace[C3TR_N];
uint32_t magcal_bench_cont3_piece[11][4];

uint32_t magcal_c3_ticks(void) { return *(volatile uint32_t *)0xE000E018u; }

void magcal_c3_piece(uint32_t kind, uint32_t t0, uint32_t w)
{
    const uint32_t c = ((t0 - magcal_c3_ticks()) & 0xFFFFFFu) * 40u;
    uint32_t *p = magcal_bench_cont3_piece[kind];
    p[0]++;
    p[1] = c > p[1] ? c : p[1];
    p[2] += c;
    p[3] = w;
}
#endif

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

/* Weight of the next sweep step, as magcal_intake_sweep will take it (src/intake/sweep.c): the
 * sweep's end, a jump over the rest of a cell, a re-bin check of a slot, or a survey visit. */
static uint32_t c3_w_sweep_step(const magcal_cont3_t *cc)
{
    const magcal_intake_t *st = &cc->store;
    const uint32_t per = st->cfg.per_bin;
    uint32_t b;
    if (st->cursor >= magcal_intake_nslots(st)) {
        return C3_W_SW_END;
    }
    b = st->cursor / per;
    if (st->cursor % per >= (uint32_t)st->count[b]) {
        return C3_W_SW_JUMP;
    }
    return st->bin_gen[b] != st->gen ? C3_W_SW_REBIN : C3_W_SW_SURVEY;
}

/* Weight of the next piece of drain work: a sweep step the last push owes, else a push. */
static uint32_t c3_w_next(const magcal_cont3_t *cc)
{
    return cc->sweep_left != 0u ? c3_w_sweep_step(cc) : C3_W_PUSH;
}

/* 1 when the ring is a quarter full (behind: more than one sample may join a step's drain). */
static int c3_behind(const magcal_cont3_t *cc)
{
    return cc->head - cc->tail >= MAGCAL_CONT3_RING / 4u;
}

/* 1 when a solve step drains only (the solver waits one step): the ring is three quarters full,
 * or the drain's next piece (a sweep's end) is larger than the drain's share of a solve step. */
static int c3_drain_only(const magcal_cont3_t *cc)
{
    return cc->head - cc->tail >= (3u * MAGCAL_CONT3_RING) / 4u ||
           (cc->sweep_left != 0u && c3_w_sweep_step(cc) > C3_W_RESERVE);
}

#ifdef MAGCAL_BENCH_TRACE
static uint32_t c3_piece_kind(uint32_t w)
{
    return w == C3_W_PUSH ? 0u : w == C3_W_SW_SURVEY ? 1u : w == C3_W_SW_REBIN ? 2u : w == C3_W_SW_JUMP ? 3u : 4u;
}
#endif

/* Store one ring sample (judged first); its sweep steps are owed (cc->sweep_left), not run. */
static void c3_push_one(magcal_cont3_t *cc)
{
    const uint32_t t = cc->tail;
    MAGCAL_CONT3_BARRIER(); /* the slot was written before head */
    if (c3_screen(cc, &cc->ring[t % MAGCAL_CONT3_RING], cc->ring_t[t % MAGCAL_CONT3_RING]) == 0) {
        cc->store.cfg.sweep_steps = 0u; /* the push stores; its sweep steps follow, piece by piece */
        (void)magcal_intake_push(&cc->store, &cc->ring[t % MAGCAL_CONT3_RING], NULL);
        cc->store.cfg.sweep_steps = cc->cfg.intake.sweep_steps;
        cc->sweep_left = cc->cfg.intake.sweep_steps;
    }
    MAGCAL_CONT3_BARRIER(); /* read before the slot is handed back */
    cc->tail = t + 1u;
}

/* What the drain does next: 0 stop (the budget does not hold the piece of weight w, unless it is
 * a forced first piece; or nothing to push: the ring is empty, `max` pushed, or a second push while
 * the ring is not behind), 1 a sweep step the last push owes, 2 the next ring sample's push. */
static unsigned c3_drain_next(const magcal_cont3_t *cc, uint32_t w, uint32_t pushed, uint32_t max, int forced)
{
    int unlimited = 0;
    unsigned what = 0u;
    if (cc->left_ == UINT32_MAX) {
        unlimited = 1;
    }
    if (unlimited != 0 || w <= cc->left_ || forced != 0) { /* the budget holds the piece */
        if (cc->sweep_left != 0u) {
            what = 1u;
        } else if (cc->tail != cc->head && pushed < max && (pushed == 0u || unlimited != 0 || c3_behind(cc) != 0)) {
            what = 2u;
        } else {
            /* nothing to push: stop */
        }
    }
    return what;
}

/* The drain, piece by piece within the budget: the sweep steps the last push owes the store (one
 * magcal_intake_sweep step each), then the next ring sample's push (read in place: push does not
 * reuse a slot before tail moves past it), its sweep steps, and so on. A sample's sweep steps all
 * run before the next sample is pushed, so the store goes through the states of pushes that run
 * their own sweep steps (3-D: the store's level band, the only other work of a push after its
 * sweep, is off); the work is only spread over steps. At most `max` pushes, a second one only
 * while the ring is behind. force: the first piece even when the budget does not hold it (the
 * steps that drain first: progress for any budget). */
static MAGCAL_NOINLINE void c3_drain(magcal_cont3_t *cc, uint32_t max, int force)
{
    const uint32_t bound = (max + 1u) * ((uint32_t)cc->cfg.intake.sweep_steps + 1u);
    uint32_t pushed = 0u;
    uint32_t g;
    C3_TRACE(const uint32_t tr0 = magcal_c3_ticks();)
    for (g = 0u; g < bound; ++g) {
        const uint32_t w = c3_w_next(cc);
        const unsigned what = c3_drain_next(cc, w, pushed, max, force != 0 && g == 0u);
        C3_TRACE(const uint32_t tp = magcal_c3_ticks();)
        if (what == 0u) {
            break;
        }
        if (what == 1u) {
            magcal_intake_sweep(&cc->store, 1u);
            cc->sweep_left--;
            C3_TRACE(magcal_bench_cont3_trace[C3TR_SWEEPS] += w == C3_W_SW_END ? 1u : 0u;)
        } else {
            c3_push_one(cc);
            pushed++;
            C3_TRACE(magcal_bench_cont3_trace[C3TR_DRAINED]++;)
        }
        C3_TRACE(magcal_c3_piece(c3_piece_kind(w), tp, w);)
        (void)magcal_c3_spend(cc, w);
    }
    C3_TRACE(magcal_bench_cont3_trace[C3TR_DRAIN_INSN] += ((tr0 - magcal_c3_ticks()) & 0xFFFFFFu) * 40u;)
}

/* New stored samples a solve needs: cfg.min_new, x 2^f after f failed solves in a row (at most
 * x 64), x (1 + r) after r refusals in a row (at most x 64). */
static uint32_t c3_new_needed(const magcal_cont3_t *cc)
{
    const uint32_t f = cc->fail_run < 6u ? cc->fail_run : 6u;
    const uint32_t r = cc->refuse_run < 63u ? cc->refuse_run : 63u;
    return ((uint32_t)cc->cfg.min_new << f) * (1u + r);
}

/* Sum of the store's monotone counters: it changes whenever the cells' contents, the centre or
 * the radius may have (a stored, replaced or re-binned sample, a re-centre, a survey's end). */
static uint32_t c3_store_key(const magcal_cont3_t *cc)
{
    const magcal_intake_t *st = &cc->store;
    return st->ctr.added + st->ctr.replaced + st->ctr.rebinned + st->ctr.recentres + st->sweeps;
}

/* The cheap half of the worth test: a centre, enough samples, enough new information (or the
 * installed calibration has aged since a NOT_BETTER verdict). */
static int c3_worth_cheap(const magcal_cont3_t *cc)
{
    return cc->store.centre_source != (uint8_t)MAGCAL_INTAKE_CENTRE_NONE && cc->store.ctr.stored >= cc->cfg.min_samples &&
           ((cc->store.ctr.added + cc->store.ctr.replaced) - cc->stored_at_solve >= c3_new_needed(cc) ||
            (cc->last_status == MAGCAL_ERR_NOT_BETTER && (float)cc->solve_ms_acc >= 0.25f * cc->cfg.age_ms));
}

/* Start the coverage count (O(1)). */
static void c3_count_start(magcal_cont3_t *cc)
{
    cc->worth_key = c3_store_key(cc);
    cc->worth_checked = 1u;
    cc->scan_bin = 0u;
    cc->scan_filled = 0u;
    cc->stage = (uint8_t)MAGCAL_C3_STAGE_COUNT;
}

/* The coverage count, cell by cell within the budget: 1 when it ended. A cell is filled when it
 * holds a sample on the ring, within [0.7, 1.4] R of the centre (intake progress.c ring_count). */
static int c3_count(magcal_cont3_t *cc)
{
    const magcal_intake_t *st = &cc->store;
    const float r2 = st->radius * st->radius;
    const uint32_t per = st->cfg.per_bin;
    /* bounded: one cell per visit */
    while (cc->scan_bin < st->n_bins) {
        const uint32_t base = (uint32_t)cc->scan_bin * per;
        const uint32_t end = base + st->count[cc->scan_bin];
        uint32_t k;
        uint32_t on = 0u;
        C3_TRACE(const uint32_t tp = magcal_c3_ticks();)
        if (!(st->radius > 0.0f)) {
            if (end > base) {
                on = 1u; /* no radius yet: every sample counts */
            }
            k = base;
        } else {
            for (k = base; k < end && on == 0u; ++k) {
                const float dx = st->slots[k].m.x - st->centre.x;
                const float dy = st->slots[k].m.y - st->centre.y;
                const float dz = st->slots[k].m.z - st->centre.z;
                const float d2 = dx * dx + dy * dy + dz * dz;
                if (d2 >= C3_RING_LO2 * r2 && d2 <= C3_RING_HI2 * r2) {
                    on = 1u;
                }
            }
        }
        cc->scan_filled = (uint16_t)(cc->scan_filled + on);
        cc->scan_bin++;
        C3_TRACE(magcal_bench_cont3_trace[C3TR_VISITS]++;)
        C3_TRACE(magcal_c3_piece(k - base > 1u ? 6u : 5u, tp, C3_W_CBIN + (k - base) * C3_W_CSAMP);)
        if (magcal_c3_spend(cc, C3_W_CBIN + (k - base) * C3_W_CSAMP) != 0 && cc->scan_bin < st->n_bins) {
            return 0;
        }
    }
    return 1;
}

/* The count ended: a solve is worth it when the filled share reaches cfg.solve_fill. */
static int c3_count_says_solve(const magcal_cont3_t *cc)
{
    return (float)cc->scan_filled / (float)cc->store.n_bins >= cc->cfg.solve_fill;
}

/* Start the snapshot (O(1)); the drain pauses until the solve is loaded. */
static void c3_snapshot_start(magcal_cont3_t *cc)
{
    cc->scan_bin = 0u;
    cc->snap_n = 0u;
    cc->stage = (uint8_t)MAGCAL_C3_STAGE_SNAPSHOT;
}

/* The snapshot, cell by cell in bin order (as magcal_intake_snapshot3) within the budget, then the
 * sliced solve begins on it: 1 when the solve is loaded (stage SOLVE, or ADOPT when begin failed). */
static int c3_snapshot(magcal_cont3_t *cc)
{
    const magcal_intake_t *st = &cc->store;
    const uint32_t per = st->cfg.per_bin;
    /* bounded: one cell per visit */
    while (cc->scan_bin < st->n_bins) {
        const uint32_t base = (uint32_t)cc->scan_bin * per;
        const uint32_t cnt = st->count[cc->scan_bin];
        uint32_t k;
        C3_TRACE(const uint32_t tp = magcal_c3_ticks();)
        for (k = 0u; k < cnt && cc->snap_n < cc->slots; ++k) {
            cc->buf[cc->snap_n] = st->slots[base + k].m;
            cc->snap_n++;
        }
        cc->scan_bin++;
        C3_TRACE(magcal_bench_cont3_trace[C3TR_VISITS]++;)
        C3_TRACE(magcal_c3_piece(7u, tp, C3_W_SBIN + cnt * C3_W_SNAP);)
        if (magcal_c3_spend(cc, C3_W_SBIN + cnt * C3_W_SNAP) != 0 && cc->scan_bin < st->n_bins) {
            return 0;
        }
    }
    cc->stored_at_solve = cc->store.ctr.added + cc->store.ctr.replaced;
    cc->solve_status = magcal_ellipsoid_calibrate_begin(&cc->slice, &cc->cfg.solver, cc->buf, cc->snap_n, cc->work,
                                                        cc->work_len, NULL, &cc->cand, NULL);
    cc->adopt_pass = 0u;
    cc->stage = (uint8_t)((cc->solve_status == MAGCAL_OK) ? MAGCAL_C3_STAGE_SOLVE : MAGCAL_C3_STAGE_ADOPT);
    (void)magcal_c3_spend(cc, C3_W_BEGIN);
    return 1;
}

/* The solve, magcal_ellipsoid_calibrate_step on the snapshot, with what is left of the budget
 * after `reserve` (at least 1); the solver's estimate is charged (pushes go on into the ring and
 * the store meanwhile). */
/* inlined into both callers (the solve step, solve_blocking): no frame of its own between them
 * and the solver's phases (the solve path's stack, tools/stack/budgets.txt) */
#if defined(__GNUC__) || defined(__clang__)
#define C3_INLINE static inline __attribute__((always_inline))
#else
#define C3_INLINE static inline
#endif

C3_INLINE magcal_cont3_outcome_t c3_solve(magcal_cont3_t *cc, uint32_t reserve)
{
    const uint32_t bud = cc->left_ == UINT32_MAX ? UINT32_MAX : (cc->left_ > reserve ? cc->left_ - reserve : 1u);
    const magcal_status_t st = magcal_ellipsoid_calibrate_step(&cc->slice, bud);
    C3_TRACE(magcal_bench_cont3_trace[C3TR_SOLVE_USED] = cc->slice.used_;)
    (void)magcal_c3_spend(cc, cc->slice.used_);
    if (st != MAGCAL_IN_PROGRESS) {
        cc->solve_status = st;
        cc->adopt_pass = 0u;
        cc->stage = (uint8_t)MAGCAL_C3_STAGE_ADOPT;
    }
    return MAGCAL_CONT3_IN_PROGRESS;
}

/* A solve step: the solver first, with the budget but C3_W_RESERVE (when there is something to
 * drain; in the density stage but the drain's next piece), then the drain within what is left (a solver visit larger than its share, e.g. the 9x9
 * solve, leaves the ring as it was: c3_drain_only() steps catch up). */
static MAGCAL_NOINLINE magcal_cont3_outcome_t c3_solve_step(magcal_cont3_t *cc)
{
    int more = 0;
    magcal_cont3_outcome_t oc;
    if (cc->tail != cc->head || cc->sweep_left != 0u) {
        more = 1;
    }
    /* the density stage's visits are small (<= 300): it keeps for the drain only what the
     * drain's next piece costs, so it takes ~2x fewer steps (the fits' units are up to 7,500:
     * they keep the fixed reserve) */
    oc = c3_solve(cc, more == 0 ? 0u
                                : (magcal_ellipsoid_calibrate_in_density(&cc->slice) != 0u ? c3_w_next(cc) : C3_W_RESERVE));
    if (more != 0) {
        c3_drain(cc, 1u, 0);
    }
    return cc->change_flag != 0u ? MAGCAL_CONT3_CHANGE : oc;
}

/* The units other than the solve (count, snapshot, adoption) within the budget; the outcome. */
static MAGCAL_NOINLINE magcal_cont3_outcome_t c3_unit(magcal_cont3_t *cc)
{
    magcal_cont3_outcome_t oc = MAGCAL_CONT3_IN_PROGRESS;
    if (cc->stage == (uint8_t)MAGCAL_C3_STAGE_COUNT) {
        if (c3_count(cc) == 0) {
            return MAGCAL_CONT3_IDLE; /* counting is collecting: no solve under way yet */
        }
        if (c3_count_says_solve(cc) == 0) {
            cc->stage = (uint8_t)MAGCAL_C3_STAGE_NONE;
            return MAGCAL_CONT3_IDLE;
        }
        c3_snapshot_start(cc);
    }
    if (cc->stage == (uint8_t)MAGCAL_C3_STAGE_SNAPSHOT) {
        (void)c3_snapshot(cc);
    } else if (cc->stage == (uint8_t)MAGCAL_C3_STAGE_ADOPT) {
        if (magcal_c3_adopt_step(cc, &oc) != 0) {
            cc->stage = (uint8_t)MAGCAL_C3_STAGE_NONE;
            cc->last_outcome = oc;
        }
    } else {
        /* the solve: the caller's */
    }
    return oc;
}

/* The body of step(): one unit of work within the budget cc->left_. */
static magcal_cont3_outcome_t c3_step_in(magcal_cont3_t *cc)
{
    if (cc->stage == (uint8_t)MAGCAL_C3_STAGE_SOLVE && c3_drain_only(cc) == 0) {
        return c3_solve_step(cc); /* the solve's deep path under as few frames as possible (stack) */
    }
    if (cc->stage != (uint8_t)MAGCAL_C3_STAGE_SNAPSHOT) { /* the snapshot's steps do not drain */
        c3_drain(cc, cc->cfg.drain_per_step, 1);
        if (cc->change_flag != 0u) {
            return MAGCAL_CONT3_CHANGE;
        }
        if (cc->stage == (uint8_t)MAGCAL_C3_STAGE_SOLVE) {
            return MAGCAL_CONT3_IN_PROGRESS; /* a drain-only step */
        }
    }
    if (cc->stage == (uint8_t)MAGCAL_C3_STAGE_NONE && c3_worth_cheap(cc) != 0 &&
        (cc->worth_checked == 0u || cc->worth_key != c3_store_key(cc))) {
        c3_count_start(cc);
    }
    return cc->stage != (uint8_t)MAGCAL_C3_STAGE_NONE ? c3_unit(cc) : MAGCAL_CONT3_IDLE;
}

magcal_cont3_outcome_t magcal_cont3_step(magcal_cont3_t *cc)
{
    magcal_cont3_outcome_t oc;
    if (!magcal_c3_ok(cc)) {
        return MAGCAL_CONT3_IDLE;
    }
    cc->left_ = cc->cfg.step_budget;
    cc->change_flag = 0u;
    C3_TRACE((void)memset(magcal_bench_cont3_trace, 0, sizeof magcal_bench_cont3_trace);)
    C3_TRACE(magcal_bench_cont3_trace[C3TR_STAGE_IN] = (uint32_t)cc->stage | ((uint32_t)cc->adopt_pass << 8) | ((uint32_t)cc->sweep_left << 16) | ((uint32_t)cc->store.rebin_pending << 17);)
    C3_TRACE(magcal_bench_cont3_trace[C3TR_UNIT_INSN] = magcal_c3_ticks();)
    oc = c3_step_in(cc);
    C3_TRACE(magcal_bench_cont3_trace[C3TR_UNIT_INSN] = ((magcal_bench_cont3_trace[C3TR_UNIT_INSN] - magcal_c3_ticks()) & 0xFFFFFFu) * 40u;)
    C3_TRACE(magcal_bench_cont3_trace[C3TR_STAGE_OUT] = (uint32_t)cc->stage | ((uint32_t)cc->adopt_pass << 8);)
    C3_TRACE(magcal_bench_cont3_trace[C3TR_CHARGED] = cc->cfg.step_budget - cc->left_;)
    return oc;
}

magcal_cont3_outcome_t magcal_cont3_solve_blocking(magcal_cont3_t *cc, int force)
{
    unsigned k;
    if (!magcal_c3_ok(cc)) {
        return MAGCAL_CONT3_IDLE;
    }
    cc->left_ = UINT32_MAX; /* unlimited: every unit runs to its end in one call */
    cc->change_flag = 0u;
    c3_drain(cc, MAGCAL_CONT3_RING, 1); /* unlimited: the owed sweep steps, then every ring sample */
    if (cc->stage == (uint8_t)MAGCAL_C3_STAGE_NONE || cc->stage == (uint8_t)MAGCAL_C3_STAGE_COUNT) {
        if (force == 0) {
            if (c3_worth_cheap(cc) == 0) {
                cc->stage = (uint8_t)MAGCAL_C3_STAGE_NONE;
                return MAGCAL_CONT3_IDLE;
            }
            c3_count_start(cc);
            (void)c3_count(cc);
            if (c3_count_says_solve(cc) == 0) {
                cc->stage = (uint8_t)MAGCAL_C3_STAGE_NONE;
                return MAGCAL_CONT3_IDLE;
            }
        }
        c3_snapshot_start(cc);
    }
    /* bounded: the units go snapshot -> solve -> adoption -> none, each whole (no budget) */
    for (k = 0u; k < 3u && cc->stage != (uint8_t)MAGCAL_C3_STAGE_NONE; ++k) {
        if (cc->stage == (uint8_t)MAGCAL_C3_STAGE_SOLVE) {
            (void)c3_solve(cc, 0u);
        } else {
            (void)c3_unit(cc);
        }
    }
    return cc->last_outcome;
}

#endif /* MAGCAL_CFG_ENABLE_3D */
