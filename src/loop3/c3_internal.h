/*
 * Internal interface of the continuous 3-D calibrator (src/loop3/): lifecycle, push, progress and
 * heading (c3_life.c), step and solve units (c3_step.c), never-worse adoption with ageing
 * (c3_adopt.c), per-sample judge and change detection (c3_change.c). Not installed.
 * docs/calibration_3d.md "Continuous 3-D".
 */
#ifndef MAGCAL_C3_INTERNAL_H
#define MAGCAL_C3_INTERNAL_H

#include "magcal/continuous3.h"

#define MAGCAL_CONT3_MAGIC 0x434F4E33u /* "CON3" */
#define MAGCAL_CONT3_MAX_DT_MS 1000u   /* a gap in the stamps counts at most this much */
#define MAGCAL_CONT3_OVERFIT_K 12.0f  /* adoption margin floor 1 + K / n (c3_adopt.c) */
#define MAGCAL_CONT3_SPREAD_CLIP 0.15f /* adoption spread: samples within this x F of the candidate's shell */

/* Units of a solve (cc->stage): the coverage count that decides whether a solve is worth it, the
 * snapshot of the store into the solver buffer, the sliced solve, the adoption judgement. */
#define MAGCAL_C3_STAGE_NONE 0u
#define MAGCAL_C3_STAGE_SNAPSHOT 1u
#define MAGCAL_C3_STAGE_SOLVE 2u
#define MAGCAL_C3_STAGE_ADOPT 3u
#define MAGCAL_C3_STAGE_COUNT 4u

/* Charge w estimated M4F instructions of the step's budget cc->left_ (UINT32_MAX: unlimited, the
 * blocking call); 1 when it is spent (stop after this visit). */
static inline int magcal_c3_spend(magcal_cont3_t *cc, uint32_t w)
{
    if (cc->left_ == UINT32_MAX) {
        return 0;
    }
    if (w >= cc->left_) {
        cc->left_ = 0u;
        return 1;
    }
    cc->left_ -= w;
    return 0;
}

/* Bench-only per-piece trace (MAGCAL_BENCH_TRACE: tools/bench/m4f_image cont3_trace.elf, never in a
 * shipped build): per kind of resumable work (0 push, 1 survey step, 2 re-bin step, 3 jump, 4 sweep
 * end, 5 count cell of <= 1 sample examined, 6 of more, 7 snapshot cell, 8 adoption candidate
 * sample, 9 installed sample, 10 installed skip) count, largest and summed instructions, weight. */
#ifdef MAGCAL_BENCH_TRACE
extern uint32_t magcal_bench_cont3_piece[11][4]; /* the 11 kinds above */
uint32_t magcal_c3_ticks(void);
void magcal_c3_piece(uint32_t kind, uint32_t t0, uint32_t w);
#define C3_TRACE(stmt) stmt
#else
#define C3_TRACE(stmt)
#endif

/* Verdict of one sample under the installed calibration. */
typedef struct {
    float rel;        /* |h| / F - 1 (NaN without a calibration) */
    uint8_t cell;     /* 0..MAGCAL_CONT3_CELLS-1: direction of h */
    uint8_t mismatch; /* 1: |rel| above the threshold */
} magcal_c3_judge_t;

int magcal_c3_ok(const magcal_cont3_t *cc);
/* Judge raw m under cc->cal: 0 when no calibration is installed (j->mismatch 0). */
int magcal_c3_judge(const magcal_cont3_t *cc, const magcal_vec3_t *m, magcal_c3_judge_t *j);
/* Time bookkeeping of one drained sample at t_ms (ageing, solve timer); returns its dt (ms). */
uint32_t magcal_c3_tick(magcal_cont3_t *cc, uint32_t t_ms);
/* Episode update with one judged sample (dt of the tick); 1 when a change is declared now. */
int magcal_c3_episode(magcal_cont3_t *cc, const magcal_c3_judge_t *j, uint32_t dt);
/* Declare a change: drop the store, relearn. */
void magcal_c3_declare_change(magcal_cont3_t *cc);
/* 1 when an open episode spans at least cfg.change_cells cells (every heading suspect). */
int magcal_c3_episode_wide(const magcal_cont3_t *cc);
/* Install calibration c (relative residual sigma, 0 = unknown) and index the store around it. */
void magcal_c3_install(magcal_cont3_t *cc, const magcal_ellipsoid_cal_t *c, float sigma);
/* The adoption unit (stage MAGCAL_C3_STAGE_ADOPT), resumable: the never-worse judgement of
 * cc->cand against the installed calibration on the snapshot, ageing, install, within the step's
 * budget (cc->left_). Returns 1 when it ended (*oc: the outcome), 0 while work remains. */
int magcal_c3_adopt_step(magcal_cont3_t *cc, magcal_cont3_outcome_t *oc);
/* Raw radius F / det(G)^(1/3) of a calibration (0 when det <= 0 or not finite). */
float magcal_c3_raw_radius(const magcal_ellipsoid_cal_t *c);

#endif /* MAGCAL_C3_INTERNAL_H */
