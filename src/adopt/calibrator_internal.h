/*
 * Internal interface between the 2-D calibrator's pipeline (calibrator.c) and its estimate and
 * adoption stage (calibrator_adopt.c). Not installed. The maths is in docs/calibrator.md
 * ("Heading-error estimates", "Adoption rule").
 */
#ifndef MAGCAL_CALIBRATOR_INTERNAL_H
#define MAGCAL_CALIBRATOR_INTERNAL_H

#include <stddef.h>
#include <stdint.h>

#include "magcal/calibrator.h"

/*
 * Harmonic analysis of the corrected radius of the masked samples under one calibration:
 * d_i = |c(p_i)| / mean - 1 is fitted by least squares with 1, cos phi, sin phi, cos 2phi,
 * sin 2phi (phi = direction of c(p_i)). A centre error makes a first harmonic, a soft-iron error
 * a second harmonic, each with the same relative amplitude as the heading error it causes; noise
 * spreads over every frequency, so only its projection on the four harmonics is counted, and
 * that projection's expectation is known from the regression's covariance.
 * All squares are rad^2 (mean square heading error over uniformly spread headings).
 */
typedef struct {
    float err2;      /* 1/2 |beta_1..4|^2: raw mean square heading error implied by the harmonics */
    float noise2;    /* 1/2 tr(Sigma_1..4): its expectation from noise alone */
    float noise2_sd; /* sd of err2 under noise alone: sqrt(1/2 tr(Sigma_1..4^2)) */
    float bias2;     /* mean square heading bias of a fit on these headings at this noise */
    float design;    /* |k (G^T G)^-1|_F / 4 over the harmonics: 1 for uniformly spread headings,
                         large when a harmonic rests on the spread inside clumps */
    float sigma_rel; /* residual sd of d after the harmonic fit (dof n - 5) */
    float mean_radius; /* mean |c(p_i)|, output unit */
    uint8_t ok;        /* 0: fewer than 6 samples, zero radius or a singular harmonic design */
} magcal_cal_harm_t;

/* Scale of the O(sigma^2) bias term (docs/calibrator.md: calibrated by tests/test_trust2d.c). */
#define MAGCAL_CAL_BIAS_K 1.5f

/* Rounding errors of a quantised ring that its residuals do not show (the lattice lies almost on
 * a conic) are correlated along the ring: one independent error per this many distinct values
 * (calibrated on the quantised rings of tests/test_trust2d.c, 2..50 LSB radius). */
#define MAGCAL_CAL_LATTICE_K 8.0f

/* Scratch floats magcal_cal_harmonics() needs (two 5x5 matrices, two vectors, the 4x4 block of
 * the inverse). */
#define MAGCAL_CAL_HARM_SCRATCH_FLOATS 76u

/*
 * Analyse calibration c on pts[i] with mask[i] != 0. dup_factor >= 1 multiplies the covariance
 * (samples that repeat the same value carry no independent noise: n / distinct values).
 * scratch: MAGCAL_CAL_HARM_SCRATCH_FLOATS floats, 4-byte aligned.
 */
void magcal_cal_harmonics(const magcal_vec2_t *pts, size_t n, const uint8_t *mask,
                          const magcal_cal2d_t *c, float dup_factor, float sigma_floor,
                          float *scratch, magcal_cal_harm_t *out);

/* Number of distinct values among the masked samples and the smallest positive coordinate step
 * between them (*step: the LSB of quantised samples, ~0 for continuous ones); idx: n uint16. */
size_t magcal_cal_distinct(const magcal_vec2_t *pts, size_t n, const uint8_t *mask, uint16_t *idx,
                           float *step);

/* ------------------------------------------------------------------ time-sliced solve
 * Work budget of one step, in estimated Cortex-M4F instructions (docs/calibrator.md "Work per
 * call"): every visit of an inner loop charges its weight (a CAL_W_* / HARM_W_* #define, host
 * callgrind x 1.2) and the loop stops once the budget is spent; a step always does at least one
 * visit. unlimited: never stops (run(), solve_blocking()). */
typedef struct {
    uint32_t left;
    uint8_t unlimited;
} magcal_cal_budget_t;

/* Charge w; 1 when the budget is spent (stop after this visit). */
static inline int magcal_cal_spend(magcal_cal_budget_t *b, uint32_t w)
{
    if (b->unlimited != 0u) {
        return 0;
    }
    if (w >= b->left) {
        b->left = 0u;
        return 1;
    }
    b->left -= w;
    return 0;
}

/* magcal_cal_spend as one out-of-line function for the solve's phase files (src/adopt): GCC
 * emitted the static inline above as a 24-byte local copy in each of them and called that copy,
 * never inlining it (issue 14: one copy saves the others' flash; the calls are the same). */
int magcal_cal_charge(magcal_cal_budget_t *b, uint32_t w);

/* Resumable harmonic analysis (magcal_cal_harmonics() = begin + step until done). All state here
 * (the calibration is copied); nm / beta / solver copies live in `scratch`
 * (MAGCAL_CAL_HARM_SCRATCH_FLOATS floats). */
typedef struct {
    const magcal_vec2_t *pts;
    const uint8_t *mask;
    float *scratch;
    magcal_cal_harm_t *out;
    magcal_cal2d_t c;
    size_t n;
    float dup;
    float floor;
    float sum;
    float mean;
    float ss;
    float s2;  /* residual variance */
    float s2p; /* noise variance seen by the parameters */
    uint32_t i;
    uint32_t k;
    uint8_t pass; /* 0 mean radius, 1 normal equations, 2 residual, 3 noise, 4..7 the inverse's
                     columns, 8 estimates, 9 done */
} magcal_cal_harm_slice_t;

void magcal_cal_harm_begin(magcal_cal_harm_slice_t *h, const magcal_vec2_t *pts, size_t n,
                           const uint8_t *mask, const magcal_cal2d_t *c, float dup_factor,
                           float sigma_floor, float *scratch, magcal_cal_harm_t *out);
/* Work within budget b; 1 when the analysis is complete (*out final), 0 to be called again. */
int magcal_cal_harm_step(magcal_cal_harm_slice_t *h, magcal_cal_budget_t *b);

/* Resumable distinct-value count (magcal_cal_distinct() = begin + step until done). */
typedef struct {
    const magcal_vec2_t *pts;
    const uint8_t *mask;
    uint16_t *idx;
    size_t n;
    size_t m;        /* masked samples */
    size_t i;        /* cursor */
    size_t j;        /* sort: the hole */
    size_t g;        /* sort: gap index */
    size_t distinct; /* result */
    float step;      /* result: smallest positive step */
    uint16_t v;      /* sort: the moving index */
    uint8_t inner;   /* sort: 1 inside an insertion */
    uint8_t pass;    /* 0 collect, 1 sort, 2 count, 3 done */
} magcal_cal_distinct_slice_t;

void magcal_cal_distinct_begin(magcal_cal_distinct_slice_t *d, const magcal_vec2_t *pts, size_t n,
                               const uint8_t *mask, uint16_t *idx);
/* Work within budget b; 1 when complete (d->distinct, d->step final), 0 to be called again. */
int magcal_cal_distinct_step(magcal_cal_distinct_slice_t *d, magcal_cal_budget_t *b);

/* Shared helpers of calibrator.c (live coverage) and calibrator_solve.c (the stages). */
float magcal_cal_angle_deg(float ux, float uy);
size_t magcal_cal_bin_of(float deg);
/* Coverage of a bin occupancy table (MAGCAL_COVERAGE_BINS entries, != 0 = filled). */
float magcal_cal_coverage_of(const uint16_t *bins, float *miss_start, float *miss_width);

/*
 * The solve (calibrator_solve.c): run()'s stages as resumable phases whose state lives in the
 * workspace (the run state). begin: an empty report; load_bbox != 0 recomputes the bounding box of
 * the caller-filled buffer (n samples, as a sliced pass) instead of using push()'s. step: works
 * within `budget` estimated M4F instructions (UINT32_MAX: to the end) and returns MAGCAL_IN_PROGRESS
 * while work remains, else the final status of run() (state, last_status and the report set as
 * run() sets them; *report, if not NULL, receives a copy). `current` is the caller's installed
 * calibration, passed again on every step (the adopt phase replaces it on success); it must not
 * change between the steps of one solve.
 */
magcal_status_t magcal_calibrator_solve_begin(magcal_calibrator_t *cal, size_t n, int load_bbox);
magcal_status_t magcal_calibrator_solve_step(magcal_calibrator_t *cal, magcal_cal2d_t *current,
                                             uint32_t budget, magcal_cal_report_t *report);
/* 1 while a solve begun with solve_begin has not ended. */
int magcal_calibrator_solving(const magcal_calibrator_t *cal);

/* Coarse stage of the next solves (calibrator.h "Coarse stage"): min_cov > 0 admits a circle fit
 * on an arc of min_cov..cfg.min_coverage_deg whose error bound is <= max_err_deg; current_coarse
 * says the `current` passed to the solves is itself coarse (a full calibration then replaces it
 * with margin 1). min_cov 0: off (the default after init). Not during a solve. */
void magcal_calibrator_set_coarse(magcal_calibrator_t *cal, float min_cov, float max_err_deg,
                                  uint8_t current_coarse);
/* Arc stage (calibrator.h "Arc stage"): the full ellipse may be fitted on an arc of
 * min_cov..cfg.min_coverage_deg whose whole-circle bound (with the model term model_deg) is <=
 * max_err_deg; min_cov 0 or any argument out of range (non-finite, max_err <= 0, model < 0): off
 * (the default after init). Not during a solve. */
void magcal_calibrator_set_arc(magcal_calibrator_t *cal, float min_cov, float max_err_deg, float model_deg);
/* A model-error term of the full solve's estimate (deg, finite, >= 0; else 0): added in quadrature
 * to est_param_err_deg (and so to est_heading_err_deg and the never-worse rule), not to the
 * observability gate. The continuous calibrator sets it from its store's tilt (continuous.h
 * "Tilt in the estimate"). */
void magcal_calibrator_set_model(magcal_calibrator_t *cal, float model_deg);

#endif /* MAGCAL_CALIBRATOR_INTERNAL_H */
