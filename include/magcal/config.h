/**
 * @file config.h
 * @brief Compile-time limits and build options of magcal.
 *
 * Every value is a default under `#ifndef`: override it with `-D` on the compiler command line or
 * in a user config header named by `MAGCAL_USER_CONFIG` (e.g. `-DMAGCAL_USER_CONFIG=\"my_cfg.h\"`).
 * Sanity rules are checked with C99 static asserts at the end of this file.
 *
 * The library and every translation unit that uses it must agree on these values: the integer
 * limits size public structs (magcal_calibrator_t, magcal_swing_cog_t) and the workspace size
 * macros. Two guards (docs/integration.md "Build configuration"):
 *  - an installed package (CMake find_package, pkg-config) defines MAGCAL_PACKAGE_CONFIG, which
 *    includes the generated `magcal/config_build.h`: the values libmagcal.a was built with, and
 *    an `#error` when a translation unit overrides one of them with another value;
 *  - at run time every stateful init (magcal_calibrator_init, magcal_aided_init,
 *    magcal_swing_cog_init) is a macro that passes MAGCAL_CONFIG_FINGERPRINT and the caller's
 *    sizeof of the instance; the library compares them with its own and returns
 *    MAGCAL_ERR_CONFIG_MISMATCH before writing anything. magcal_config_check() does the same
 *    for firmware that uses only the stateless calls (whose work_len checks already refuse a
 *    workspace smaller than the library's own size macro with MAGCAL_ERR_WORKSPACE).
 * The floating-point tolerances below are used inside the library only: overriding one needs a
 * rebuild of the library (the installed config_build.h records the values it was built with).
 */
#ifndef MAGCAL_CONFIG_H
#define MAGCAL_CONFIG_H

#include <stddef.h>
#include <stdint.h>

#include "magcal/status.h"

#ifdef MAGCAL_USER_CONFIG
#include MAGCAL_USER_CONFIG
#endif

#ifdef MAGCAL_PACKAGE_CONFIG
#include "magcal/config_build.h"
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

/* ---- Time-sliced work (issues 13/14, docs/calibrator.md "Work per call") */
/** Default work per step() of time-sliced calls, in estimated Cortex-M4F instructions
 *  (magcal_cont_cfg_t::step_budget): with the fixed overhead and the largest single visit, a step
 *  stays below the 10,000-instruction per-call bound. 7500, not 4500: one drained sample is
 *  measured at up to ~6k (weight 4900), so 4500 held a sample and no solver work at all. */
#ifndef MAGCAL_SLICE_BUDGET_DEFAULT
#define MAGCAL_SLICE_BUDGET_DEFAULT 7500u
#endif

/* ---- Module limits and numerical tolerances (moved here from the module headers; same values) */

/** Relative pivot threshold of the equilibrated LDL^T solve (algorithms.md 3.2). */
#ifndef MAGCAL_ELLIPSE_PIVOT_TOL
#define MAGCAL_ELLIPSE_PIVOT_TOL 1.0e-6f
#endif

/**
 * Parabola tolerance: the conic is a parabola (MAGCAL_ERR_PARABOLA) when
 * |4B - A^2| <= MAGCAL_ELLIPSE_PARABOLA_TOL * (1 + A^2/2 + B^2) (normalised coefficients; the
 * right side is the squared Frobenius norm of [[1, A/2], [A/2, B]], so the test is invariant to
 * the conic's scale). 1e-6 corresponds to an axis ratio of about 2000, beyond what float32
 * coefficients resolve.
 */
#ifndef MAGCAL_ELLIPSE_PARABOLA_TOL
#define MAGCAL_ELLIPSE_PARABOLA_TOL 1.0e-6f
#endif

/**
 * Collinearity test: the used points are DEGENERATE when the smaller eigenvalue of their 2x2
 * covariance is below this fraction of the larger (width/length below about 1e-3).
 */
#ifndef MAGCAL_ELLIPSE_COLLINEAR_TOL
#define MAGCAL_ELLIPSE_COLLINEAR_TOL 1.0e-6f
#endif

/**
 * Relative zero-field gate of magcal_heading_compute(): when the calibration's radius is known
 * (> 0), a corrected field shorter than this fraction of it gives MAGCAL_ERR_ZERO_FIELD.
 */
#ifndef MAGCAL_HEADING_ZERO_FIELD_FRAC
#define MAGCAL_HEADING_ZERO_FIELD_FRAC 1.0e-3f
#endif

/** Heading bins of the course-over-ground accumulator (10 deg each by default). */
#ifndef MAGCAL_SWING_COG_BINS
#define MAGCAL_SWING_COG_BINS 36u
#endif

/** Largest number of minimal-set draws accepted in magcal_consensus_cfg_t::max_iter. */
#ifndef MAGCAL_CONSENSUS_MAX_ITER
#define MAGCAL_CONSENSUS_MAX_ITER 2000u
#endif

/** Largest number of threshold/refit rounds accepted in magcal_consensus_cfg_t::refine_iter. */
#ifndef MAGCAL_CONSENSUS_MAX_REFINE
#define MAGCAL_CONSENSUS_MAX_REFINE 32u
#endif

/* ---- Feature switches (issue 14): leave out what a firmware does not use ------------------------
 * Each is 1 (compiled) by default; define it to 0 (-D, MAGCAL_USER_CONFIG, or the CMake options
 * MAGCAL_ENABLE_* of the library build) to leave the feature out of libmagcal. A disabled
 * feature's public functions are not declared (its header puts them under the same #if) and not
 * compiled, so a call fails at compile time, not at run time; where a configuration value selects
 * the feature inside a module that stays (magcal_calibrator_cfg_t::filter = MAGCAL_FILTER_DBSCAN,
 * form = MAGCAL_CORR_KPHI), the call returns MAGCAL_ERR_ARG. Types, configuration structs and
 * size macros stay declared (records and instance structs embed them). The library and every
 * caller must see the same values (the CMake target exports them as compile definitions).
 * Checked by the ctest `config_switches_off` (tests/switches/): the library with every switch at
 * 0 links and runs a 2-D calibration. */

/** DBSCAN (dbscan.h) and the calibrator's MAGCAL_FILTER_DBSCAN. */
#ifndef MAGCAL_CFG_ENABLE_DBSCAN
#define MAGCAL_CFG_ENABLE_DBSCAN 1
#endif

/** The classic OPTICS ordering (MAGCAL_OPTICS_CLASSIC, its seed heap; src/filter/optics.c, optics_core.h). */
#ifndef MAGCAL_CFG_ENABLE_OPTICS_CLASSIC
#define MAGCAL_CFG_ENABLE_OPTICS_CLASSIC 1
#endif

/**
 * The source documents' variants that the product's default path does not use: the indoor heading
 * patent's adaptive heading-error models (errmodel.h), the documents' K Phi_p correction form
 * (MAGCAL_CORR_KPHI) and coefficients (magcal_ellipse_kphi()).
 */
#ifndef MAGCAL_CFG_ENABLE_PAPER
#define MAGCAL_CFG_ENABLE_PAPER 1
#endif

/** 3-D calibration: the ellipsoid fit and calibrate (ellipsoid.h) and the 3-D OPTICS stage
 *  (optics.h "3-D samples", src/filter/optics3.c). */
#ifndef MAGCAL_CFG_ENABLE_3D
#define MAGCAL_CFG_ENABLE_3D 1
#endif

/** The geomagnetic reference field (geomag.h: WMM2025, IGRF-14 and their coefficient tables). */
#ifndef MAGCAL_CFG_ENABLE_GEOMAG
#define MAGCAL_CFG_ENABLE_GEOMAG 1
#endif

/** The INS/GNSS-aided 3-D calibration (aided.h). */
#ifndef MAGCAL_CFG_ENABLE_AIDED
#define MAGCAL_CFG_ENABLE_AIDED 1
#endif

/** The compass swing (deviation coefficients A..E, course-over-ground accumulator; swing.h). */
#ifndef MAGCAL_CFG_ENABLE_SWING
#define MAGCAL_CFG_ENABLE_SWING 1
#endif

/**
 * The calibrator's coarse stage (calibrator.h "Coarse stage": a hard-iron circle below the coverage
 * gate, src/adopt/calibrator_coarse.c). At 0 no solve is coarse: a store below
 * cfg.min_coverage_deg fails with MAGCAL_ERR_COVERAGE whatever magcal_calibrator_set_coarse() set
 * (the continuous calibrator's cfg.coarse_coverage_deg then only starts its solves earlier; set it
 * to 0 in such a build).
 */
#ifndef MAGCAL_CFG_ENABLE_COARSE
#define MAGCAL_CFG_ENABLE_COARSE 1
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

/**
 * Fingerprint of the integer limits above (FNV-1a style mix, 32 bits): equal in the library and
 * in a caller exactly when they were compiled with the same values (up to a 2^-32 collision).
 */
#define MAGCAL_CONFIG_MIX_(h, v) ((uint32_t)(((uint32_t)(h) ^ (uint32_t)(v)) * 16777619u))
#define MAGCAL_CONFIG_FINGERPRINT                                                                  \
    MAGCAL_CONFIG_MIX_(                                                                            \
        MAGCAL_CONFIG_MIX_(                                                                        \
            MAGCAL_CONFIG_MIX_(                                                                    \
                MAGCAL_CONFIG_MIX_(                                                                \
                    MAGCAL_CONFIG_MIX_(MAGCAL_CONFIG_MIX_(MAGCAL_CONFIG_MIX_(2166136261u,          \
                                                                             MAGCAL_MAX_SAMPLES),  \
                                                          MAGCAL_MAX_MIN_PTS),                     \
                                       MAGCAL_GRID_MAX_CELLS),                                     \
                    MAGCAL_COVERAGE_BINS),                                                         \
                MAGCAL_SWING_COG_BINS),                                                            \
            MAGCAL_CONSENSUS_MAX_ITER),                                                            \
        MAGCAL_CONSENSUS_MAX_REFINE)

/**
 * Alignment unit of every caller workspace: a workspace declared as an array of it is aligned for
 * pointers, float and uint32_t, whatever the library carves out of it.
 */
typedef struct {
    void *align_p;
    float align_f;
    uint32_t align_u;
} magcal_workspace_t;

/**
 * Declare `name` as a workspace of at least `len` bytes (a size macro), correctly aligned; prefix
 * with `static` as needed and pass `name, sizeof name`. Each module has its own helper built on it,
 * e.g. MAGCAL_CALIBRATOR_WORKSPACE_DECLARE(work, CAP).
 */
#define MAGCAL_WORKSPACE_DECLARE(name, len)                                                        \
    magcal_workspace_t(name)[((size_t)(len) + sizeof(magcal_workspace_t) - 1u) / sizeof(magcal_workspace_t)]

#ifdef __cplusplus
extern "C" {
#endif

/** @brief MAGCAL_CONFIG_FINGERPRINT as the library was compiled. */
uint32_t magcal_config_fingerprint(void);

/**
 * @brief Check a caller's configuration fingerprint against the library's (use the macro
 *        magcal_config_check(), which passes the caller's MAGCAL_CONFIG_FINGERPRINT).
 * @return MAGCAL_OK; MAGCAL_ERR_CONFIG_MISMATCH (compiled with other limits than the library).
 */
magcal_status_t magcal_config_check_fingerprint(uint32_t caller_fingerprint);

/** Boot-time check of this translation unit's configuration against the library's. */
#define magcal_config_check() magcal_config_check_fingerprint(MAGCAL_CONFIG_FINGERPRINT)

/**
 * @brief Version of the library that is linked: MAGCAL_VERSION (magcal.h) of its build,
 *        major * 10000 + minor * 100 + patch. Compare with the header's MAGCAL_VERSION.
 */
uint32_t magcal_version(void);

/** @brief The linked library's version as "MAJOR.MINOR.PATCH" (static string). */
const char *magcal_version_str(void);

#ifdef __cplusplus
}
#endif

/* C99 static assert without _Static_assert (negative array size on failure). */
#define MAGCAL_STATIC_ASSERT(cond, name) typedef char magcal_static_assert_##name[(cond) ? 1 : -1]

MAGCAL_STATIC_ASSERT(MAGCAL_MAX_SAMPLES >= 16u, max_samples_at_least_16);
MAGCAL_STATIC_ASSERT(MAGCAL_MAX_SAMPLES <= 65535u, max_samples_fits_uint16);
MAGCAL_STATIC_ASSERT(MAGCAL_MAX_MIN_PTS >= 2u, min_pts_at_least_2);
MAGCAL_STATIC_ASSERT(MAGCAL_GRID_MAX_CELLS >= 9u && MAGCAL_GRID_MAX_CELLS <= 65535u, grid_cells_range);
MAGCAL_STATIC_ASSERT(MAGCAL_SWING_COG_BINS >= 4u && MAGCAL_SWING_COG_BINS <= 360u, swing_cog_bins_range);
MAGCAL_STATIC_ASSERT(MAGCAL_CONSENSUS_MAX_ITER >= 1u && MAGCAL_CONSENSUS_MAX_ITER <= 65535u, consensus_iter_fits_uint16);
MAGCAL_STATIC_ASSERT(MAGCAL_CONSENSUS_MAX_REFINE >= 1u && MAGCAL_CONSENSUS_MAX_REFINE <= 65535u, consensus_refine_fits_uint16);
MAGCAL_STATIC_ASSERT(MAGCAL_COVERAGE_BINS >= 8u && MAGCAL_COVERAGE_BINS <= 360u, coverage_bins_range);
MAGCAL_STATIC_ASSERT((MAGCAL_CFG_ENABLE_DBSCAN == 0 || MAGCAL_CFG_ENABLE_DBSCAN == 1) &&
                         (MAGCAL_CFG_ENABLE_OPTICS_CLASSIC == 0 || MAGCAL_CFG_ENABLE_OPTICS_CLASSIC == 1) &&
                         (MAGCAL_CFG_ENABLE_PAPER == 0 || MAGCAL_CFG_ENABLE_PAPER == 1) &&
                         (MAGCAL_CFG_ENABLE_3D == 0 || MAGCAL_CFG_ENABLE_3D == 1) &&
                         (MAGCAL_CFG_ENABLE_GEOMAG == 0 || MAGCAL_CFG_ENABLE_GEOMAG == 1) &&
                         (MAGCAL_CFG_ENABLE_AIDED == 0 || MAGCAL_CFG_ENABLE_AIDED == 1) &&
                         (MAGCAL_CFG_ENABLE_SWING == 0 || MAGCAL_CFG_ENABLE_SWING == 1) &&
                         (MAGCAL_CFG_ENABLE_COARSE == 0 || MAGCAL_CFG_ENABLE_COARSE == 1),
                     feature_switches_are_0_or_1);

#endif /* MAGCAL_CONFIG_H */
