/* Recorded and generated dumps compiled into the tests as const arrays (tools/csv2c.py). */
#ifndef MAGCAL_TEST_DATA_H
#define MAGCAL_TEST_DATA_H

#include <math.h>
#include <stddef.h>

/** One `# key: value` comment line of a dump CSV whose value is a number. */
typedef struct {
    const char *key;
    float value;
} magcal_test_meta_t;

/**
 * Truth of a synthetic dump (tools/gen_dump.py), from the `# key: value` lines at the top of the
 * CSV. Float fields whose key is absent are NAN, counts are 0. Model: Hm = T*H + b + n,
 * H = h0*(-sin psi, cos psi), n ~ N(0, sigma^2 I); rows [0, n_cal) are the calibration turn, the
 * rest are verification rows; floor_deg is the heading RMS on the verification rows with the
 * TRUE correction applied (algorithms.md 9).
 */
typedef struct {
    float h0;
    float t00, t01, t10, t11;
    float bx, by;
    float sigma;
    float floor_deg;
    float arc_deg;
    size_t n_cal;
    size_t n_outliers;
    size_t n_meta;                  /* every numeric key, the named ones included */
    const magcal_test_meta_t *meta; /* n_meta entries, file order */
} magcal_test_truth_t;

typedef struct {
    const char *name;
    size_t n;
    const float *t;
    const float *mx;
    const float *my;
    const float *mz;
    const float *ax;
    const float *ay;
    const float *az;
    const float *heading_ref_deg;
    const float *outlier; /* truth flag (synthetic dumps): 1 = injected singular point */
    const float *glitch;  /* importer's flag on recorded dumps */
    const magcal_test_truth_t *truth; /* NULL when the CSV has no `# key: value` lines */
} magcal_test_dump_t;

#endif
