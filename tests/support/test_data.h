/* Recorded and generated dumps compiled into the tests as const arrays (tools/csv2c.py). */
#ifndef MAGCAL_TEST_DATA_H
#define MAGCAL_TEST_DATA_H

#include <math.h>
#include <stddef.h>

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
} magcal_test_dump_t;

#endif
