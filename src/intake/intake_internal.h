/*
 * Internals shared by the intake store's files (never installed):
 *   bins.c     direction -> bin (2-D sectors, 3-D igloo cells) and the mask geometry;
 *   store.c    init, push (spacing, cap, newest-replaces-oldest), snapshot, counters;
 *   sweep.c    the bounded survey / re-bin sweep that keeps the provisional centre robust;
 *   progress.c live coverage, completion and the filled-bin mask;
 * and the saturation test the continuous calibrator's heading trust shares with the store.
 */
#ifndef MAGCAL_INTAKE_INTERNAL_H
#define MAGCAL_INTAKE_INTERNAL_H

#include <math.h>

#include "magcal/intake.h"

#define INTAKE_MAGIC 0x494e544bu /* "INTK" */
#define INTAKE_SEQ_LEVEL 0x80000000u /* slot.seq bit 31: a LEVEL sample (magcal_intake_push_tilt) */
#define INTAKE_SEQ_MASK 0x7fffffffu  /* slot.seq bits 0..30: push count (ages modulo 2^31 pushes) */

/* 1 when an axis of the raw sample m is at the declared range (cfg->range_limit > 0; a
 * non-finite axis counts too): a saturated axis is a fault, not data. */
static inline int magcal_intake_saturated(const magcal_intake_cfg_t *cfg, const magcal_vec3_t *m)
{
    const float lim = cfg->range_limit;
    return (lim > 0.0f && (!(fabsf(m->x) < lim) || !(fabsf(m->y) < lim) || !(fabsf(m->z) < lim))) ? 1 : 0;
}

/* Bin of a raw sample around the store's centre. */
uint16_t magcal_intake_bin_of(const magcal_intake_t *st, const magcal_vec3_t *m);

/* Cells of a 3-D mask of `bands` bands (0: out of range or more than MAGCAL_INTAKE_MAX_BINS). */
uint16_t magcal_intake_cells_3d(uint16_t bands);

/* Build the 3-D band tables (st->n_bands, band_start, band_cos); returns the cell count or 0. */
uint16_t magcal_intake_build_mask(magcal_intake_t *st, uint16_t bands);

/* Insert m (slot seq: push count and level bit) into bin b: a free slot, else over the bin's
 * oldest non-level sample (a level m: the oldest sample when every one is level; a non-level m
 * into a bin full of level samples is dropped itself). Returns 1 when a sample was dropped. */
int magcal_intake_insert(magcal_intake_t *st, uint16_t b, const magcal_vec3_t *m, uint32_t seq);

/* The cut of an INCONSISTENT solve (the continuous calibrator's snapshot, src/loop/cont_step.c),
 * one bin: the samples pushed before seq_limit (a push count, modulo 2^31 pushes) and, when
 * ring_r > 0, those off the solve's ring (centre, ring_r) by more than half its radius are
 * removed from bin `bin` (compacted in place, order kept; the stored count follows); the x, y of
 * the kept ones are appended to out[*n..] while *n < cap. O(per_bin), no trigonometry. */
void magcal_intake_drop_older(magcal_intake_t *st, uint32_t bin, uint32_t seq_limit, const magcal_vec2_t *centre,
                              float ring_r, magcal_vec2_t *out, size_t cap, uint32_t *n);

/* Survey / re-bin up to `steps` slots (sweep.c). */
void magcal_intake_sweep(magcal_intake_t *st, uint32_t steps);

/* What one sweep step did (the index of its charge in magcal_intake_sweep_part's w): */
#define INTAKE_SWEEP_JUMP 0u  /* jumped the empty rest of a bin */
#define INTAKE_SWEEP_VISIT 1u /* surveyed a slot */
#define INTAKE_SWEEP_REBIN 2u /* re-binned a sample (swap-remove + insert) */
#define INTAKE_SWEEP_END 3u   /* ended the sweep (survey_finish: its fits) */

/* The sliced sweep part of a continuous step (src/loop/cont_step.c): up to cfg.sweep_steps sweep
 * steps, each charged w[what it did] against *left (not unlimited) as magcal_cal_spend does,
 * stopping after a step whose charge reaches *left (*left = 0) or that ended the sweep (which is
 * then the part's only step: before any step but the first, the part stops when the cursor is at
 * the end, or when *left < keep). */
void magcal_intake_sweep_part(magcal_intake_t *st, const uint16_t w[4], uint32_t keep, uint32_t *left);

/* Live coverage, resumable (progress.c): the ring count of bins *bin.. within `budget` estimated
 * M4F instructions (at least one bin; returns what it charged; complete when *bin == n_bins, its
 * words / *filled / *deep cleared when *bin == 0), at the completion depth
 * magcal_intake_count_depth(); then magcal_intake_progress_of() fills the progress as
 * magcal_intake_progress() does (that call is the whole count plus this). */
uint32_t magcal_intake_count_step(const magcal_intake_t *st, uint32_t *words, uint32_t depth, uint32_t *bin,
                                  uint32_t *filled, uint32_t *deep, uint32_t budget);
uint32_t magcal_intake_count_depth(const magcal_intake_t *st);
void magcal_intake_progress_of(const magcal_intake_t *st, const uint32_t *words, uint32_t filled, uint32_t deep,
                               magcal_intake_progress_t *out);

/* Move the centre (z = 0 in 2-D), set the radius and start a re-bin sweep. */
void magcal_intake_recentre(magcal_intake_t *st, const magcal_vec3_t *c, float radius);

/* Clear the survey accumulators. */
void magcal_intake_survey_clear(magcal_intake_t *st);

/* Slots in use by the mask (bins x per_bin). */
static inline uint32_t magcal_intake_nslots(const magcal_intake_t *st)
{
    return (uint32_t)st->n_bins * (uint32_t)st->cfg.per_bin;
}

/* A level model of raw z against the heading, z = a0 + a1 c + a2 s (c, s: the heading's cos and
 * sin; the soft iron's leak of x, y into z): one sample into the sums q (1 c s cc cs ss z zc zs),
 * and the 3 x 3 solve by Cramer's rule into a, 1 when q has at least min_n samples and the
 * matrix is well conditioned (det > det_rel n^3: the headings spread round the ring). The
 * store's level survey (store.c) and the continuous calibrator's slopes (loop/cont_slope.c). */
static inline void magcal_lv_sums(float *q, float z, float c, float s)
{
    q[0] += 1.0f;
    q[1] += c;
    q[2] += s;
    q[3] += c * c;
    q[4] += c * s;
    q[5] += s * s;
    q[6] += z;
    q[7] += z * c;
    q[8] += z * s;
}
int magcal_lv_solve(const float *q, float min_n, float det_rel, float *a);

#endif /* MAGCAL_INTAKE_INTERNAL_H */
