/**
 * @file config.h
 * @brief Compile-time limits and build options of magcal.
 *
 * Every value is a default under `#ifndef`: override it with `-D` on the compiler command line or
 * in a user config header named by `MAGCAL_USER_CONFIG` (e.g. `-DMAGCAL_USER_CONFIG=\"my_cfg.h\"`).
 * Sanity rules are checked with C99 static asserts at the end of this file.
 */
#ifndef MAGCAL_CONFIG_H
#define MAGCAL_CONFIG_H

#ifdef MAGCAL_USER_CONFIG
#include MAGCAL_USER_CONFIG
#endif

/** Largest number of samples a calibration buffer may hold (indices are uint16_t). */
#ifndef MAGCAL_MAX_SAMPLES
#define MAGCAL_MAX_SAMPLES 1024u
#endif

/** Largest MinPts accepted by OPTICS/DBSCAN (size of the core-distance insertion buffer). */
#ifndef MAGCAL_MAX_MIN_PTS
#define MAGCAL_MAX_MIN_PTS 32u
#endif

/** Largest number of grid cells the OPTICS/DBSCAN spatial index may use (caller workspace). */
#ifndef MAGCAL_GRID_MAX_CELLS
#define MAGCAL_GRID_MAX_CELLS 4096u
#endif

/** Number of angular bins used to track arc coverage (10 degrees each by default). */
#ifndef MAGCAL_COVERAGE_BINS
#define MAGCAL_COVERAGE_BINS 36u
#endif

/**
 * Internal invariant check. Defaults to nothing (stripped); define it (e.g. to a breakpoint or
 * a call into the firmware's fault handler) to enable. Bad caller input is never checked with
 * this macro: it always returns a status.
 */
#ifndef MAGCAL_ASSERT
#define MAGCAL_ASSERT(cond) ((void)0)
#endif

/**
 * Keep a function out of its callers' frames (stack depth: a large helper frame is then not
 * added to every path through the caller). GCC/Clang attribute; empty for other compilers,
 * where the stack numbers of docs/reliability.md do not apply anyway.
 */
#ifndef MAGCAL_NOINLINE
#if defined(__GNUC__) || defined(__clang__)
#define MAGCAL_NOINLINE __attribute__((noinline))
#else
#define MAGCAL_NOINLINE
#endif
#endif

/* C99 static assert without _Static_assert (negative array size on failure). */
#define MAGCAL_STATIC_ASSERT(cond, name) typedef char magcal_static_assert_##name[(cond) ? 1 : -1]

MAGCAL_STATIC_ASSERT(MAGCAL_MAX_SAMPLES >= 16u, max_samples_at_least_16);
MAGCAL_STATIC_ASSERT(MAGCAL_MAX_SAMPLES <= 65535u, max_samples_fits_uint16);
MAGCAL_STATIC_ASSERT(MAGCAL_MAX_MIN_PTS >= 2u, min_pts_at_least_2);
MAGCAL_STATIC_ASSERT(MAGCAL_GRID_MAX_CELLS >= 9u && MAGCAL_GRID_MAX_CELLS <= 65535u, grid_cells_range);
MAGCAL_STATIC_ASSERT(MAGCAL_COVERAGE_BINS >= 8u && MAGCAL_COVERAGE_BINS <= 360u, coverage_bins_range);

#endif /* MAGCAL_CONFIG_H */
