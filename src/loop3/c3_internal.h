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
/* Stage 3: the never-worse judgement of cc->cand against the installed calibration on the
 * snapshot, ageing, install. Returns the outcome. */
magcal_cont3_outcome_t magcal_c3_adopt(magcal_cont3_t *cc);
/* |B| spread (std / mean of |G (m - V)|) of `c` over the buffer samples within
 * MAGCAL_CONT3_SPREAD_CLIP x F of `sel`'s shell; NaN when fewer than 10 samples qualify. */
float magcal_c3_spread(const magcal_cont3_t *cc, const magcal_ellipsoid_cal_t *c,
                       const magcal_ellipsoid_cal_t *sel);
/* Raw radius F / det(G)^(1/3) of a calibration (0 when det <= 0 or not finite). */
float magcal_c3_raw_radius(const magcal_ellipsoid_cal_t *c);

#endif /* MAGCAL_C3_INTERNAL_H */
