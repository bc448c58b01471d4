/*
 * Internals of the geomag module shared between src/heading/geomag.c and the generated
 * src/heading/geomag_schmidt.c (tools/geomag/cof2c.py). Not installed, not part of the public API.
 */
#ifndef MAGCAL_GEOMAG_INTERNAL_H
#define MAGCAL_GEOMAG_INTERNAL_H

#include "magcal/geomag.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Entries of the (n, m) triangle n = 1..MAGCAL_GEOMAG_NMAX, m = 0..n-1 (index n(n-1)/2 + m). */
#define MAGCAL_GEOMAG_TRI_LEN ((MAGCAL_GEOMAG_NMAX * (MAGCAL_GEOMAG_NMAX + 1u)) / 2u)

/** (2n-1)/sqrt(n^2-m^2): factor of mu*P_{n-1}^m in the Schmidt recurrence (algorithms.md 8.4). */
extern const float magcal_geomag_schmidt_a[MAGCAL_GEOMAG_TRI_LEN];
/** sqrt(((n-1)^2-m^2)/(n^2-m^2)): factor of P_{n-2}^m in the same recurrence. */
extern const float magcal_geomag_schmidt_b[MAGCAL_GEOMAG_TRI_LEN];
/** sqrt((2n-1)/(2n)) for n >= 2 (diagonal recurrence); entries 0 and 1 unused. */
extern const float magcal_geomag_schmidt_s[MAGCAL_GEOMAG_NMAX + 1u];

#ifdef __cplusplus
}
#endif

#endif /* MAGCAL_GEOMAG_INTERNAL_H */
