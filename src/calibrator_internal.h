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

/* Scratch floats magcal_cal_harmonics() needs (two 5x5 matrices and two vectors). */
#define MAGCAL_CAL_HARM_SCRATCH_FLOATS 60u

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

/* Sliced run (calibrator.c), for the continuous calibrator (src/loop/): the stages of run(),
 * each called directly by its step() (no frame between a step and the deepest stage paths).
 * load: take the first n samples of the caller-filled buffer; then prepare, fit, gates, adopt in
 * order, each MAGCAL_OK to continue, else the final status; end: finish with the final status
 * (state, report) as run() does. rep: magcal_calibrator_stage_report(). */
magcal_status_t magcal_calibrator_stage_load(magcal_calibrator_t *cal, size_t n);
magcal_cal_report_t *magcal_calibrator_stage_report(magcal_calibrator_t *cal);
magcal_status_t magcal_calibrator_stage_prepare(magcal_calibrator_t *cal, magcal_cal_report_t *rep);
magcal_status_t magcal_calibrator_stage_fit(magcal_calibrator_t *cal);
magcal_status_t magcal_calibrator_stage_gates(magcal_calibrator_t *cal, magcal_cal_report_t *rep);
magcal_status_t magcal_calibrator_stage_adopt(magcal_calibrator_t *cal, magcal_cal2d_t *current,
                                              magcal_cal_report_t *rep);
magcal_status_t magcal_calibrator_stage_end(magcal_calibrator_t *cal, magcal_status_t st,
                                            magcal_cal_report_t *report);

#endif /* MAGCAL_CALIBRATOR_INTERNAL_H */
