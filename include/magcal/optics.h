/**
 * @file optics.h
 * @brief OPTICS density filter for 2-D and 3-D magnetometer samples (algorithms.md section 4).
 *
 * OPTICS (Ankerst, Breunig, Kriegel & Sander 1999) orders the points so that density-connected
 * points are adjacent and records, per point, its core distance and its reachability distance.
 * ExtractDBSCAN-Clustering at a radius eps' <= eps then labels the points exactly as DBSCAN(eps',
 * MinPts) would (up to a few border points), and the largest cluster is kept as "normal data"
 * (the ring of a compass swing); everything else is rejected before the ellipse fit.
 *
 * Units: any consistent unit (raw LSB, uT, gauss); eps and eps' are in the unit of the points.
 * Axes: x right, y forward (magcal_vec2_t); only Euclidean distances are used.
 *
 * Determinism: both ordering modes (CLASSIC binary heap with decrease-key, IMPROVED unordered
 * seed list with one linear scan) and both neighbour searches (BRUTE, GRID) produce bit-identical
 * ordering, reachability, core distance and predecessor arrays: the next point is the argmin of
 * (reach, index) among the seeds, and the first unprocessed index when no seed is left
 * (cfg.start = MAGCAL_OPTICS_START_INDEX, scikit-learn's rule) or the first unprocessed core
 * point (MAGCAL_OPTICS_START_CORE, the source documents' rule; docs/optics.md "Start rule").
 *
 * MinPts counts the point itself (p is core when >= MinPts points, p included, lie within eps),
 * as in Ankerst et al. and scikit-learn's min_samples; the documents' threshold m is the same
 * number when their neighbourhood contains p (a reading without p is MinPts = m + 1).
 *
 * Memory: no heap, no recursion. The caller owns every buffer; `work` must be aligned to 4 bytes
 * (declare it as `uint32_t` or `float`) and at least the size macro's length in bytes.
 *
 * Automatic parameters (magcal_optics_auto_params, used by magcal_optics_filter when cfg->eps <= 0):
 *  1. centre c = (median x, median y), radius R = median |p - c|; then twice more over only the
 *     points within 3 R of the previous centre (a far cluster, e.g. 23 % driver glitches 36 R
 *     away, cannot drag the centre). These medians count each clump once: they run over one
 *     representative per square cell (the lowest index in it), cells of S/32 first, S = median
 *     distance of 256 pseudo-random pairs (fixed seed; a clump of up to 70 % of the samples
 *     cannot shrink it), then of R/16 * min(1, 400/n) around the centre found. A vehicle parked
 *     at one or two headings (40-60 % of the samples) then no longer pulls c into its clump and
 *     shrinks R to the clump's noise. Everything below is a multiple of distances measured on the
 *     data, so raw counts and microtesla behave identically (scale invariant).
 *  2. the "ring band" = points with | |p - c| - R | <= 0.5 R, sorted by angle around c.
 *  3. along that angular order (cyclic), link_i = the shortest distance between a point at or
 *     before i and a point after i, bypassing at most 3 points (|p_i-a p_i+b|, a >= 0, b >= 1,
 *     a + b <= 4): the gap the chain must jump there, with isolated off-ring points skipped;
 *     core_i = 3rd smallest distance from p_i to its 4 angular neighbours on each side (the
 *     radius that makes p_i a core point for MinPts = 4); the quantile below counts at most K
 *     samples per cell, K = the mean cell occupancy (a clump's tiny core distances count K times,
 *     not hundreds).
 *  4. eps' = 1.5 * max(second largest link_i, 90th percentile of core_i), clamped to
 *     [R/256, R]; eps = eps'; MinPts = 4. One cut in the cyclic chain leaves an arc, which is
 *     still one cluster, so only the second largest gap must be bridged (a 300 deg arc is not
 *     forced to bridge its 60 deg hole).
 *  Why: algorithms.md 4.3 measured that eps' from local spacing alone (3 x median core distance)
 *  fragments random rings; eps' must bridge the largest gap between consecutive ring samples,
 *  which this rule measures directly instead of guessing it from n. The cap R keeps points more
 *  than R away from every ring point out (driver glitches, a different field); the factor 1.5
 *  absorbs radial noise between the sampled links. Bursts of displaced samples close to the
 *  ring are NOT rejected here (they leave gaps the rule must bridge, so they merge with the
 *  ring); a model-residual stage after this filter handles them. Measurements: docs/optics.md.
 *
 * Kept cluster. With given parameters (cfg->eps > 0) the filter keeps the largest cluster, as the
 * documents do. With automatic parameters it keeps the cluster whose ring-band samples occupy
 * the most of 64 angular sectors around c (ties: more points, then the smaller id): the normal
 * data are the cluster that spans the turn, not the densest one (a clump off the ring with more
 * samples than the ring, a parked phase the eps' rule could not join). The 3-D filter does the
 * same with 96 direction cells (6 cube faces x 4 x 4).
 *
 * @code
 * static magcal_vec2_t pts[512];                       // filled by the caller
 * static MAGCAL_OPTICS_FILTER_WORKSPACE_DECLARE(work, 512);
 * static uint8_t inlier[512];
 * magcal_optics_cfg_t cfg = MAGCAL_OPTICS_CFG_DEFAULT;  // eps = 0: automatic parameters
 * magcal_optics_result_t info;
 * magcal_status_t st = magcal_optics_filter(&cfg, pts, 512, work, sizeof work, inlier, &info);
 * // st == MAGCAL_OK: inlier[i] == 1 for the points of the largest cluster (info.n_inliers)
 * @endcode
 */
#ifndef MAGCAL_OPTICS_H
#define MAGCAL_OPTICS_H

#include <stddef.h>
#include <stdint.h>

#include "magcal/config.h"
#include "magcal/status.h"
#include "magcal/types.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Label of a noise point (ExtractDBSCAN and DBSCAN). Clusters are numbered 0, 1, 2, ... */
#define MAGCAL_OPTICS_NOISE ((int16_t)-1)

/** Predecessor of a point that starts a connected part (no predecessor). */
#define MAGCAL_OPTICS_NO_PRED ((uint16_t)0xFFFFu)

/** Seed-list organisation of the ordering loop (algorithms.md 4.2); outputs are identical. */
typedef enum {
    MAGCAL_OPTICS_CLASSIC = 0, /**< binary min-heap keyed on (reach, index) with decrease-key;
                                    compiled out with MAGCAL_CFG_ENABLE_OPTICS_CLASSIC = 0 (then
                                    every call given it returns MAGCAL_ERR_ARG) */
    MAGCAL_OPTICS_IMPROVED = 1 /**< unordered seed list, one linear scan for the minimum */
} magcal_optics_order_t;

/**
 * Where each run of the ordering loop starts once the seed list is empty (docs/optics.md "Start
 * rule"). Core distance and reachability are defined the same way under both rules; only which
 * points get processed first differs, and with it the ordering and the reach of border points.
 */
typedef enum {
    /** the lowest unprocessed index, core or not (scikit-learn's rule; the default, which the
     *  golden vectors pin): a border point met before its core neighbours is processed alone and
     *  keeps reach = inf, so ExtractDBSCAN labels it noise */
    MAGCAL_OPTICS_START_INDEX = 0,
    /** the lowest unprocessed CORE point (the source documents' rule: each run starts at an
     *  unprocessed core object); points that are neither core nor reachable from one are
     *  processed after every core point, by index. A border point within eps of a core point is
     *  then always reached and joins its cluster. Costs one extra eps-query per non-core start
     *  candidate. */
    MAGCAL_OPTICS_START_CORE = 1
} magcal_optics_start_t;

/** Neighbour search used for the eps-queries; outputs are identical. */
typedef enum {
    MAGCAL_NEIGHBORS_BRUTE = 0, /**< test every point, O(n) per query */
    MAGCAL_NEIGHBORS_GRID = 1   /**< uniform grid, counting sort, 3x3 cell query (brute if eps = inf
                                     or all points equal) */
} magcal_neighbors_t;

/**
 * Buckets G of the spatial index for n points: min(MAGCAL_GRID_MAX_CELLS, max(n, 16)).
 * The grid has cell side eps*(1+2^-6) over the points' bounding box; a grid of at most G cells
 * is stored densely (algorithms.md 4.4), a larger one (far outliers stretching the box) folds its
 * row-major cell number modulo G, so distant cells share buckets and the distance test drops the
 * extra candidates. Results never depend on G; only the speed does.
 */
#define MAGCAL_OPTICS_GRID_CELLS(n)                                                                \
    ((size_t)(n) < 16u                                                                             \
         ? (size_t)16u                                                                             \
         : ((size_t)(n) > (size_t)MAGCAL_GRID_MAX_CELLS ? (size_t)MAGCAL_GRID_MAX_CELLS            \
                                                        : (size_t)(n)))

/** Bytes of the internal spatial index for n points: idx[n] + start[G+1] (uint16). */
#define MAGCAL_NEIGHBORS_WORKSPACE_LEN(n)                                                          \
    (2u * (size_t)(n) + 2u * (MAGCAL_OPTICS_GRID_CELLS(n) + 1u))

/** @cond INTERNAL */
/* Offset of the MinPts insertion buffer in the run workspace (4-byte aligned). */
#define MAGCAL_OPTICS_BEST_OFFSET_(n)                                                              \
    ((4u * (size_t)(n) + MAGCAL_NEIGHBORS_WORKSPACE_LEN(n) + ((size_t)(n) + 7u) / 8u + 3u) &       \
     ~(size_t)3u)
/* Bytes of the loop state (the ordering loop's context and the resumable state of the slice
 * API), kept in the workspace (off the stack) after the MinPts buffer, with slack to align it for
 * pointers; optics.c checks the size with a static assert (24 pointer-sized fields + 140 bytes). */
#ifdef MAGCAL_OPTICS_BENCH_SORTED_LIST /* bench-only seed-list mode (src/optics_core.h): 2 more words */
#define MAGCAL_OPTICS_CTX_LEN_ (26u * sizeof(void *) + 140u)
#else
#define MAGCAL_OPTICS_CTX_LEN_ (24u * sizeof(void *) + 140u)
#endif
/* Offset of the run workspace inside the filter workspace (4-byte aligned). */
#define MAGCAL_OPTICS_FILTER_RUN_OFFSET_(n) ((6u * (size_t)(n) + 3u) & ~(size_t)3u)
/** @endcond */

/**
 * Workspace bytes for magcal_optics_run() on n points: seed heap/list uint16[n], heap position
 * map uint16[n], spatial index, one "processed" bit per point and the MinPts insertion buffer
 * (4 * MAGCAL_MAX_MIN_PTS bytes) and the loop state (24 pointers + 140 bytes, 236 bytes on a 32-bit
 * target), both kept off the stack. About 8.1 bytes per sample + 364 bytes (32-bit);
 * the outputs (order 2 + reach 4 + core 4 bytes per sample) are separate caller arrays.
 */
#define MAGCAL_OPTICS_WORKSPACE_LEN(n)                                                             \
    (MAGCAL_OPTICS_BEST_OFFSET_(n) + 4u * (size_t)MAGCAL_MAX_MIN_PTS + MAGCAL_OPTICS_CTX_LEN_)

/**
 * Workspace bytes for magcal_optics_filter() and magcal_optics_auto_params() on n points:
 * reach float[n] + labels int16[n] + MAGCAL_OPTICS_WORKSPACE_LEN(n). About 14.1 bytes per
 * sample + 364 bytes (32-bit); with the caller's uint8 inlier mask the whole filter needs about 15.1 bytes
 * per sample besides the points (ordering and core distances are consumed on the fly).
 */
#define MAGCAL_OPTICS_FILTER_WORKSPACE_LEN(n)                                                      \
    (MAGCAL_OPTICS_FILTER_RUN_OFFSET_(n) + MAGCAL_OPTICS_WORKSPACE_LEN(n))

/** Workspace bytes for magcal_optics_largest_cluster() on n labels (cluster counts, uint16[n]). */
#define MAGCAL_OPTICS_LARGEST_WORKSPACE_LEN(n) ((2u * (size_t)(n) + 3u) & ~(size_t)3u)

/** Declare `name` as a correctly aligned workspace of MAGCAL_OPTICS_WORKSPACE_LEN(n) bytes (config.h). */
#define MAGCAL_OPTICS_WORKSPACE_DECLARE(name, n) MAGCAL_WORKSPACE_DECLARE(name, MAGCAL_OPTICS_WORKSPACE_LEN(n))
/** Declare `name` as a correctly aligned workspace of MAGCAL_OPTICS_FILTER_WORKSPACE_LEN(n) bytes (config.h). */
#define MAGCAL_OPTICS_FILTER_WORKSPACE_DECLARE(name, n) MAGCAL_WORKSPACE_DECLARE(name, MAGCAL_OPTICS_FILTER_WORKSPACE_LEN(n))
/** Declare `name` as a correctly aligned workspace of MAGCAL_OPTICS_LARGEST_WORKSPACE_LEN(n) bytes (config.h). */
#define MAGCAL_OPTICS_LARGEST_WORKSPACE_DECLARE(name, n) MAGCAL_WORKSPACE_DECLARE(name, MAGCAL_OPTICS_LARGEST_WORKSPACE_LEN(n))

/** OPTICS configuration (validated by every call that takes it). */
typedef struct {
    /** Neighbourhood radius eps > 0 (may be +INFINITY). magcal_optics_filter: eps <= 0 selects
     *  automatic eps, eps' and MinPts (magcal_optics_auto_params); magcal_optics_run: must be > 0. */
    float eps;
    /** Extraction radius eps' (filter only), finite, 0 < eps' <= eps; 0 means eps' = eps (then
     *  eps must be finite). Ignored in auto mode. */
    float eps_prime;
    /** MinPts, counting the point itself: 2..MAGCAL_MAX_MIN_PTS. Ignored in auto mode. p is a
     *  core point when its eps-neighbourhood, p included, holds >= MinPts points (Ankerst et al.,
     *  scikit-learn's min_samples). The source documents' threshold m ("the number of points in
     *  the eps-neighbourhood of p >= m") is the same number when that neighbourhood contains p,
     *  as in the OPTICS paper they cite; a reading without p is MinPts = m + 1. */
    uint16_t min_pts;
    /** Seed-list organisation. */
    magcal_optics_order_t order;
    /** Neighbour search. */
    magcal_neighbors_t neighbors;
    /** Start rule of each run (MAGCAL_OPTICS_START_INDEX by default). */
    magcal_optics_start_t start;
} magcal_optics_cfg_t;

/** Defaults: automatic parameters, improved ordering, grid search (work without tuning). */
#define MAGCAL_OPTICS_CFG_DEFAULT                                                                  \
    {                                                                                              \
        0.0f, 0.0f, 4u, MAGCAL_OPTICS_IMPROVED, MAGCAL_NEIGHBORS_GRID, MAGCAL_OPTICS_START_INDEX   \
    }

/** What a run or filter did (diagnostics). */
typedef struct {
    /** eps used (auto or given), point unit. */
    float eps;
    /** eps' used by the extraction (filter only). */
    float eps_prime;
    /** MinPts used. */
    uint16_t min_pts;
    /** Search actually used (GRID falls back to BRUTE for eps = inf or all points equal). */
    magcal_neighbors_t neighbors;
    /** Clusters found at eps' (filter only). */
    uint16_t n_clusters;
    /** Id of the kept cluster (filter only). */
    int16_t largest_id;
    /** Points in the kept cluster (filter only). */
    uint16_t n_inliers;
    /** Points labelled noise at eps' (filter only). */
    uint16_t n_noise;
} magcal_optics_result_t;

/**
 * @brief Run the OPTICS ordering loop (algorithms.md 4.1-4.2).
 * @param[in]  cfg       eps (> 0, may be +INF), min_pts, order, neighbors; eps_prime ignored.
 * @param[in]  pts       n points, finite.
 * @param[in]  n         number of points, cfg->min_pts..MAGCAL_MAX_SAMPLES.
 * @param[out] work      scratch, 4-byte aligned, >= MAGCAL_OPTICS_WORKSPACE_LEN(n) bytes.
 * @param[in]  work_len  bytes available at work.
 * @param[out] order     n indices: the cluster ordering.
 * @param[out] reach     n reachability distances, indexed by point (INFINITY = undefined).
 * @param[out] core      n core distances, indexed by point (INFINITY = undefined).
 * @param[out] pred      optional (NULL): n predecessors, MAGCAL_OPTICS_NO_PRED for starts.
 * @param[out] info      optional (NULL): eps, min_pts and the neighbour search used.
 * @return MAGCAL_OK; MAGCAL_ERR_NULL (cfg, pts, work, order, reach or core NULL);
 *         MAGCAL_ERR_ARG (eps not > 0 or NaN, finite eps whose square is below FLT_MIN/1024 or overflows,
 *         i.e. eps < 3.4e-21 or eps > 1.8e19 (use +INFINITY for "everything"), min_pts outside
 *         2..MAGCAL_MAX_MIN_PTS, bad enum); MAGCAL_ERR_ALIGNMENT (work not 4-byte aligned);
 *         MAGCAL_ERR_TOO_FEW_POINTS (n < min_pts);
 *         MAGCAL_ERR_ARG also for n > MAGCAL_MAX_SAMPLES; MAGCAL_ERR_NONFINITE (a NaN/Inf point);
 *         MAGCAL_ERR_WORKSPACE (work_len too small). Outputs are untouched on failure.
 */
magcal_status_t magcal_optics_run(const magcal_optics_cfg_t *cfg, const magcal_vec2_t *pts,
                                  size_t n, void *work, size_t work_len, uint16_t *order,
                                  float *reach, float *core, uint16_t *pred,
                                  magcal_optics_result_t *info);

/**
 * @brief ExtractDBSCAN-Clustering at eps' (algorithms.md 4.3).
 * @param[in]  order, reach, core  outputs of magcal_optics_run for n points.
 * @param[in]  n          number of points (1..MAGCAL_MAX_SAMPLES).
 * @param[in]  eps        the eps the ordering was computed with (> 0, may be +INF).
 * @param[in]  eps_prime  extraction radius, 0 <= eps' <= eps, finite.
 * @param[out] labels     n labels indexed by point: 0, 1, ... or MAGCAL_OPTICS_NOISE.
 * @param[out] n_clusters optional (NULL): number of clusters.
 * @return MAGCAL_OK; MAGCAL_ERR_NULL; MAGCAL_ERR_ARG (eps' > eps, eps' < 0 or not finite, n = 0,
 *         an order entry >= n, n > MAGCAL_MAX_SAMPLES).
 *         labels untouched on failure.
 */
magcal_status_t magcal_optics_extract_dbscan(const uint16_t *order, const float *reach,
                                             const float *core, size_t n, float eps,
                                             float eps_prime, int16_t *labels,
                                             uint16_t *n_clusters);

/**
 * @brief Keep the largest cluster: highest count, ties to the smaller id (algorithms.md 4.3).
 * Works on labels from magcal_optics_extract_dbscan or magcal_dbscan_run.
 * @param[in]  labels     n labels (>= 0 cluster id, MAGCAL_OPTICS_NOISE); ids must be < n.
 * @param[in]  n          number of labels (1..MAGCAL_MAX_SAMPLES).
 * @param[out] work       scratch, 2-byte aligned, >= MAGCAL_OPTICS_LARGEST_WORKSPACE_LEN(n) bytes.
 * @param[in]  work_len   bytes at work.
 * @param[out] inlier_mask n bytes: 1 for the points of the kept cluster, else 0.
 * @param[out] cluster_id optional (NULL): id of the kept cluster.
 * @param[out] count      optional (NULL): its size.
 * @return MAGCAL_OK; MAGCAL_ERR_NULL; MAGCAL_ERR_ARG (n = 0, a label < -1 or >= n);
 *         MAGCAL_ERR_ALIGNMENT (work not 2-byte aligned);
 *         MAGCAL_ERR_ARG also for n > MAGCAL_MAX_SAMPLES; MAGCAL_ERR_WORKSPACE;
 *         MAGCAL_ERR_ALL_NOISE (no cluster). Outputs untouched on failure.
 */
magcal_status_t magcal_optics_largest_cluster(const int16_t *labels, size_t n, void *work,
                                              size_t work_len, uint8_t *inlier_mask,
                                              int16_t *cluster_id, uint16_t *count);

/**
 * @brief Automatic eps, MinPts and eps' from the data's own scale (rule in the file comment).
 * @param[in]  pts        n points, finite.
 * @param[in]  n          16..MAGCAL_MAX_SAMPLES.
 * @param[out] work       scratch, 4-byte aligned, >= MAGCAL_OPTICS_FILTER_WORKSPACE_LEN(n) bytes.
 * @param[in]  work_len   bytes at work.
 * @param[out] eps        eps for the ordering (= eps').
 * @param[out] min_pts    MinPts (4).
 * @param[out] eps_prime  extraction radius.
 * @return MAGCAL_OK; MAGCAL_ERR_NULL; MAGCAL_ERR_ALIGNMENT (work not 4-byte aligned);
 *         MAGCAL_ERR_TOO_FEW_POINTS (n < 16); MAGCAL_ERR_ARG also for n > MAGCAL_MAX_SAMPLES;
 *         MAGCAL_ERR_NONFINITE; MAGCAL_ERR_WORKSPACE; MAGCAL_ERR_DEGENERATE (median radius 0 or
 *         fewer than 10 points in the ring band). Outputs untouched on failure.
 */
magcal_status_t magcal_optics_auto_params(const magcal_vec2_t *pts, size_t n, void *work,
                                          size_t work_len, float *eps, uint16_t *min_pts,
                                          float *eps_prime);

/**
 * @brief Points to inlier mask in one call: (auto params), OPTICS, ExtractDBSCAN at eps', kept
 * cluster. Ordering and core distances are consumed on the fly; with given parameters the result
 * equals magcal_optics_run + magcal_optics_extract_dbscan + magcal_optics_largest_cluster, with
 * automatic ones the kept cluster is the one of widest angular extent (file comment).
 * @param[in]  cfg        cfg->eps <= 0: automatic parameters; otherwise eps, eps_prime, min_pts as given.
 * @param[in]  pts        n points, finite.
 * @param[in]  n          cfg->min_pts (16 in auto mode)..MAGCAL_MAX_SAMPLES.
 * @param[out] work       scratch, 4-byte aligned, >= MAGCAL_OPTICS_FILTER_WORKSPACE_LEN(n) bytes.
 * @param[in]  work_len   bytes at work.
 * @param[out] inlier_mask n bytes: 1 = kept (largest cluster), 0 = rejected.
 * @param[out] info       optional (NULL): parameters used and cluster statistics.
 * @return MAGCAL_OK; every status of magcal_optics_run / magcal_optics_auto_params;
 *         MAGCAL_ERR_ARG (eps' > eps or eps' < 0); MAGCAL_ERR_ALL_NOISE (no cluster).
 *         inlier_mask untouched on failure.
 */
magcal_status_t magcal_optics_filter(const magcal_optics_cfg_t *cfg, const magcal_vec2_t *pts,
                                     size_t n, void *work, size_t work_len, uint8_t *inlier_mask,
                                     magcal_optics_result_t *info);

/**
 * @brief One representative per clump: the thinning of the automatic rule as a mask.
 * Square cells of side R/16 around the automatic centre (c, R of the rule above, clumps counted
 * once); in each cell the lowest-index candidate is the representative. A vehicle parked at one
 * heading leaves hundreds of near-identical samples in one or two cells: a stage that draws
 * samples (the consensus' minimal sets, consensus.h) should draw from the representatives, or the
 * clump fills the draws. A ring keeps about 100 to 300 representatives (2 pi R / (R/16) cells
 * along it, more with radial noise), so the mask is for drawing, not for fitting. Without a
 * clump (no cell holds more than 8 x the mean candidates per occupied cell) nothing is thinned:
 * the mask is the candidates (on noisy real rings thinning alone moved the consensus' fixed point
 * and its parameter-error gate refused the bundled glitch recording).
 * @param[in]  pts       n points, finite.
 * @param[in]  n         16..MAGCAL_MAX_SAMPLES.
 * @param[in]  cand      NULL (every point is a candidate) or n bytes, != 0 = candidate; only
 *                       candidates can be representatives.
 * @param[out] work      scratch, 4-byte aligned, >= MAGCAL_OPTICS_FILTER_WORKSPACE_LEN(n) bytes.
 * @param[in]  work_len  bytes at work.
 * @param[out] rep_mask  n bytes: 1 = representative of its cell, 0 = not (or not a candidate).
 * @return MAGCAL_OK; MAGCAL_ERR_NULL (pts, work or rep_mask); MAGCAL_ERR_ARG (misaligned work,
 *         n > MAGCAL_MAX_SAMPLES); MAGCAL_ERR_TOO_FEW_POINTS (n < 16); MAGCAL_ERR_NONFINITE;
 *         MAGCAL_ERR_WORKSPACE; MAGCAL_ERR_DEGENERATE (fewer than 16 distinct cells or median
 *         radius 0: no centre).
 *         rep_mask untouched on failure.
 */
magcal_status_t magcal_optics_thin(const magcal_vec2_t *pts, size_t n, const uint8_t *cand,
                                   void *work, size_t work_len, uint8_t *rep_mask);

/* ---- time-sliced filter and thinning (issues 13 + 14, the slice contract) ----------------- */

/*
 * The same computations as magcal_optics_filter() and magcal_optics_thin(), split into bounded
 * steps so a firmware super-loop or a 100 Hz task can run them: begin() validates and stores the
 * inputs (O(1)), each step() does at most about `budget` estimated Cortex-M4F instructions of
 * work (at least one inner-loop visit, so any budget >= 1 makes progress) and returns
 * MAGCAL_IN_PROGRESS while work remains, then exactly the status and outputs, bit for bit, of
 * the one-shot call (which is itself begin + step(UINT32_MAX): one code path).
 *
 * The slice object holds the loop state (indices, partial sums); the arrays live in `work`.
 * Between begin() and the last step() the caller must keep pts, cand, work and the output arrays
 * alive and unchanged (no copy is taken); nothing else is kept between calls (no statics).
 * A finished slice returns its final status again on further step() calls. Different slice
 * objects with different workspaces are independent (reentrant per instance).
 *
 * Where the state lives: the slice object holds two words; the loop state (about 240 bytes on a
 * 32-bit target) lives in `work`, inside the same MAGCAL_OPTICS_FILTER_WORKSPACE_LEN(n) bytes
 * (the thinning keeps its state within its first 11 n + 3 + ~100 bytes, as its arrays always
 * did). Only one slice per workspace at a time.
 *
 * Granularity (src/filter/optics.c "weights"): every loop over the points, the selection and heapsort
 * steps of the automatic rule, the grid build, each candidate of a neighbour scan and each seed
 * of the IMPROVED minimum scan is one charged visit; the weights were fitted to measured host
 * instruction counts x 1.2 (tools/bench_optics/slice_fit.py). Measured at budget 6000 (host
 * callgrind, tools/bench_optics/slice_steps.sh): largest step 6,992 host instructions at
 * n = 288 and 1024 on rings, parked rings and bursts; fixed cost of a step about 380 host
 * instructions (a resumed neighbour scan recomputes its candidate ranges, charged).
 * Every configuration is sliced the same way; on the non-default paths a few visits are coarse:
 * MAGCAL_OPTICS_CLASSIC charges each heap pop / sift-up as one visit (O(log n)), and with
 * caller-given eps the grid's cell growth (only when eps is below 2^-15 of the box) is one visit
 * of up to 256 rounds; neither is on the default path.
 * Differences from the one-shot calls of before (outputs identical): the finiteness of the points
 * is checked by the first steps, so with both a NaN point and a too small workspace the status is
 * MAGCAL_ERR_WORKSPACE (was MAGCAL_ERR_NONFINITE).
 */

/** State of a time-sliced magcal_optics_filter() (fields private; caller's memory). The loop
 *  state itself lives in the workspace (inside MAGCAL_OPTICS_FILTER_WORKSPACE_LEN). */
typedef struct {
    void *state_;            /* loop state in the workspace; NULL once finished */
    magcal_status_t status_; /* final status once finished */
    uint32_t magic_;         /* set by begin */
} magcal_optics_filter_slice_t;

/** State of a time-sliced magcal_optics_thin() (fields private; caller's memory). */
typedef struct {
    void *state_;
    magcal_status_t status_;
    uint32_t magic_;
} magcal_optics_thin_slice_t;

/**
 * @brief Start a time-sliced magcal_optics_filter() (same inputs, same workspace size).
 * O(1): checks the arguments that need no pass over the points (NULL, alignment, cfg, counts,
 * workspace length) and stores them; the finiteness of the points is checked by the first steps.
 * @param[out] s           slice state (caller's memory), overwritten.
 * @param[in]  cfg         as magcal_optics_filter (read here only: it may go out of scope).
 * @param[in]  pts         n points, kept unchanged until the last step.
 * @param[in]  n           as magcal_optics_filter.
 * @param[out] work        as magcal_optics_filter, kept for the whole run.
 * @param[in]  work_len    bytes at work.
 * @param[out] inlier_mask n bytes, written by the last step only (untouched on failure).
 * @param[out] info        optional (NULL), written by the last step only.
 * @return MAGCAL_OK (call magcal_optics_filter_step); else the status magcal_optics_filter would
 *         return for these arguments (then s is marked finished with that status).
 */
magcal_status_t magcal_optics_filter_begin(magcal_optics_filter_slice_t *s,
                                           const magcal_optics_cfg_t *cfg,
                                           const magcal_vec2_t *pts, size_t n, void *work,
                                           size_t work_len, uint8_t *inlier_mask,
                                           magcal_optics_result_t *info);

/**
 * @brief Do at most about `budget` estimated M4F instructions of the filter.
 * @param[in,out] s       state from magcal_optics_filter_begin.
 * @param[in]     budget  estimated Cortex-M4F instructions for this call (>= 1; UINT32_MAX: to the end).
 * @return MAGCAL_IN_PROGRESS (call again); else exactly magcal_optics_filter's status, with its
 *         outputs; MAGCAL_ERR_NULL (s NULL); MAGCAL_ERR_ARG (s never begun).
 */
magcal_status_t magcal_optics_filter_step(magcal_optics_filter_slice_t *s, uint32_t budget);

/**
 * @brief Start a time-sliced magcal_optics_thin() (same inputs, same workspace size); O(1).
 * @return MAGCAL_OK (call magcal_optics_thin_step); else the status magcal_optics_thin would
 *         return (checks that need no pass over the points).
 */
magcal_status_t magcal_optics_thin_begin(magcal_optics_thin_slice_t *s, const magcal_vec2_t *pts,
                                         size_t n, const uint8_t *cand, void *work,
                                         size_t work_len, uint8_t *rep_mask);

/**
 * @brief Do at most about `budget` estimated M4F instructions of the thinning.
 * @return MAGCAL_IN_PROGRESS (call again); else exactly magcal_optics_thin's status and mask;
 *         MAGCAL_ERR_NULL (s NULL); MAGCAL_ERR_ARG (s never begun).
 */
magcal_status_t magcal_optics_thin_step(magcal_optics_thin_slice_t *s, uint32_t budget);

/* ---- 3-D samples (src/filter/optics3*.c, optics3_internal.h) --------------------------------- */

/*
 * The 3-D functions below apply the same OPTICS definitions (algorithms.md 4.1-4.3) to
 * magcal_vec3_t samples (x right, y forward, z up; any consistent unit) with the Euclidean
 * distance sqrt(dx^2 + dy^2 + dz^2). The ordering loop, tie rule (argmin of (reach, index),
 * first unprocessed index when no seed is left) and both ordering modes are those of the 2-D
 * magcal_optics_run, so CLASSIC and IMPROVED give bit-identical order, reach, core and pred.
 * ExtractDBSCAN and the largest-cluster rule are dimension-free: use
 * magcal_optics_extract_dbscan() and magcal_optics_largest_cluster() on the 3-D run's outputs.
 *
 * Neighbour search: BRUTE tests every point for the core distance and the points not yet
 * processed for the reach updates: about 1.5 n^2 squared distances, O(n^2) whatever eps is.
 * GRID (the default) counting-sorts the points into cubic cells of side eps (1 + 2^-6) (dense
 * row-major buckets when the box has at most MAGCAL_OPTICS_GRID_CELLS(n) cells, else a spatial
 * hash modulo that many buckets; cell coordinates clamped to 2^15 per axis) and visits the 3x3x3
 * block; it falls back to BRUTE for eps = +INF or all points equal (info->neighbors says which).
 * All four combinations give bit-identical outputs. Measured instruction counts: docs/optics.md,
 * section "3-D".
 *
 * Automatic parameters (magcal_optics_auto_params3, used by magcal_optics_filter3 when
 * cfg->eps <= 0), every quantity a multiple of distances measured on the data (scale invariant):
 *  1. centre c = coordinate medians, R = median |p - c|; twice more over only the points within
 *     3 R of the previous centre (a far cluster cannot drag the centre), as in 2-D, and as in 2-D
 *     over one representative per cubic cell (S/32 with the pair scale S, then
 *     R/16 * min(1, sqrt(400/n))): a rest phase (noise around one point) counts once.
 *  2. the "shell band" = points with | |p - c| - R | <= 0.5 R (at least 10 points).
 *  3. one OPTICS run with eps = R, MinPts = 4 (its ordering serves every eps' <= R).
 *  4. r75 = the smallest eps' (geometric bisection over [R/256, R], 5e-6 relative) at which the
 *     largest ExtractDBSCAN cluster holds 75 % of the band's representatives; eps' = 2 r75, at most R
 *     (eps' = R when even R does not reach 75 %); eps = R; MinPts = 4.
 *  Why: the samples of a real calibration are a trajectory on the ellipsoid (dense along the
 *  path, gaps between passes), not independent points, so a spacing statistic (k-distance)
 *  fragments them; this rule measures the radius that actually connects the bulk of the shell.
 *  75 % tolerates up to a quarter of the band being outliers; the factor 2 connects the sparser
 *  rest. Measured (docs/optics.md "3-D"): 9 real tumble recordings and synthetic shells (uniform,
 *  tilt-limited, yaw-only) lose at most 11 of 1000 genuine samples; eps' is about 0.5 R at
 *  n = 300 and 0.36 R at n = 600 for uniform directions, so only samples farther than that from
 *  the shell are rejected here; nearer outliers are for the fit's residual gate.
 *  Cost: the run at eps = R uses the brute search whatever cfg->neighbors says (the grid cannot
 *  help at that radius): O(n^2), about 37 M host instructions at n = 1000.
 *
 * @code
 * static magcal_vec3_t pts3[600];                      // filled by the caller
 * static MAGCAL_OPTICS3_FILTER_WORKSPACE_DECLARE(work3, 600);
 * static uint8_t inlier3[600];
 * magcal_optics_cfg_t cfg3 = MAGCAL_OPTICS_CFG_DEFAULT; // eps = 0: automatic parameters
 * magcal_optics_result_t info3;
 * magcal_status_t st3 = magcal_optics_filter3(&cfg3, pts3, 600, work3, sizeof work3, inlier3, &info3);
 * // st3 == MAGCAL_OK: inlier3[i] == 1 for the samples of the largest cluster; copy them out and
 * // give them to magcal_ellipsoid_fit()
 * @endcode
 */

/** @cond INTERNAL */
/* Offset of the MinPts insertion buffer in the 3-D run workspace (4-byte aligned): seeds, heap
 * positions, unprocessed list / grid index (uint16[n] each), grid bucket starts uint16[G+1],
 * then the processed bits. */
#define MAGCAL_OPTICS3_BEST_OFFSET_(n)                                                             \
    ((6u * (size_t)(n) + 2u * (MAGCAL_OPTICS_GRID_CELLS(n) + 1u) + ((size_t)(n) + 7u) / 8u + 3u) & \
     ~(size_t)3u)
/* Bytes of the 3-D ordering loop's context (off the stack), with slack to align it for pointers;
 * optics3_internal.h checks the size with a static assert. */
#ifdef MAGCAL_OPTICS_BENCH_SORTED_LIST
#define MAGCAL_OPTICS3_CTX_LEN_ (33u * sizeof(void *) + 112u)
#else
#define MAGCAL_OPTICS3_CTX_LEN_ (31u * sizeof(void *) + 112u)
#endif
/* Offset of the run workspace inside the 3-D filter workspace (4-byte aligned): reach float[n],
 * core float[n], order uint16[n] (the automatic rule keeps the whole ordering). */
#define MAGCAL_OPTICS3_FILTER_RUN_OFFSET_(n) ((10u * (size_t)(n) + 3u) & ~(size_t)3u)
/** @endcond */

/**
 * Workspace bytes for magcal_optics_run3() on n points: seed heap/list uint16[n], heap position
 * map uint16[n], unprocessed list or grid index uint16[n], grid bucket starts
 * uint16[MAGCAL_OPTICS_GRID_CELLS(n) + 1], one "processed" bit per point, the MinPts insertion
 * buffer (4 * MAGCAL_MAX_MIN_PTS bytes) and the loop's context (236 bytes on a 32-bit target).
 * About 8.1 bytes per sample + 366 bytes (32-bit, n >= 16); the outputs are separate caller arrays.
 */
#define MAGCAL_OPTICS3_WORKSPACE_LEN(n)                                                            \
    (MAGCAL_OPTICS3_BEST_OFFSET_(n) + 4u * (size_t)MAGCAL_MAX_MIN_PTS + MAGCAL_OPTICS3_CTX_LEN_)

/** @cond INTERNAL */
/* The automatic rule's record (pointers, centre, radius, band, the eps found), behind the run's
 * workspace: off the stack of the density stage (issue 13: <= 512 B per entry point). */
#define MAGCAL_OPTICS3_AUTO_LEN_ 96u
/** @endcond */

/**
 * Workspace bytes for magcal_optics_filter3() and magcal_optics_auto_params3() on n points:
 * reach float[n] + core float[n] + order uint16[n] (the automatic rule keeps the whole ordering)
 * + MAGCAL_OPTICS3_WORKSPACE_LEN(n) + the automatic rule's record (96 B). About 18.1 bytes per
 * sample + 462 bytes (32-bit, n >= 16).
 */
#define MAGCAL_OPTICS3_FILTER_WORKSPACE_LEN(n)                                                     \
    (MAGCAL_OPTICS3_FILTER_RUN_OFFSET_(n) + MAGCAL_OPTICS3_WORKSPACE_LEN(n) + MAGCAL_OPTICS3_AUTO_LEN_)

/** @cond INTERNAL */
/* 64-bit words of magcal_optics3_slice_t (src/filter/optics3_internal.h checks the size with a
 * static assert): 8 pointers or sizes, the configuration copy and the sub-machines' state. */
#define MAGCAL_OPTICS3_SLICE_WORDS_ ((8u * sizeof(void *) + 160u + 7u) / 8u)
/** @endcond */

/** State of a time-sliced magcal_optics_filter3() (magcal_optics_filter3_begin / _step), in the
 *  caller's memory (the continuous 3-D calibrator keeps it in its solve state); contents private. */
typedef struct {
    uint64_t words_[MAGCAL_OPTICS3_SLICE_WORDS_];
} magcal_optics3_slice_t;

/** Declare `name` as a correctly aligned workspace of MAGCAL_OPTICS3_WORKSPACE_LEN(n) bytes (config.h). */
#define MAGCAL_OPTICS3_WORKSPACE_DECLARE(name, n) MAGCAL_WORKSPACE_DECLARE(name, MAGCAL_OPTICS3_WORKSPACE_LEN(n))
/** Declare `name` as a correctly aligned workspace of MAGCAL_OPTICS3_FILTER_WORKSPACE_LEN(n) bytes (config.h). */
#define MAGCAL_OPTICS3_FILTER_WORKSPACE_DECLARE(name, n) MAGCAL_WORKSPACE_DECLARE(name, MAGCAL_OPTICS3_FILTER_WORKSPACE_LEN(n))

#if MAGCAL_CFG_ENABLE_3D
/**
 * @brief Run the OPTICS ordering loop on 3-D points (algorithms.md 4.1-4.2).
 * @param[in]  cfg       eps (> 0, may be +INF), min_pts, order, neighbors; eps_prime ignored.
 * @param[in]  pts       n points (x right, y forward, z up; any unit), finite.
 * @param[in]  n         number of points, cfg->min_pts..MAGCAL_MAX_SAMPLES.
 * @param[out] work      scratch, 4-byte aligned, >= MAGCAL_OPTICS3_WORKSPACE_LEN(n) bytes.
 * @param[in]  work_len  bytes available at work.
 * @param[out] order     n indices: the cluster ordering.
 * @param[out] reach     n reachability distances, indexed by point (INFINITY = undefined).
 * @param[out] core      n core distances, indexed by point (INFINITY = undefined).
 * @param[out] pred      optional (NULL): n predecessors, MAGCAL_OPTICS_NO_PRED for starts.
 * @param[out] info      optional (NULL): eps, min_pts and the neighbour search used.
 * @return MAGCAL_OK; MAGCAL_ERR_NULL (cfg, pts, work, order, reach or core NULL);
 *         MAGCAL_ERR_ARG (eps not > 0 or NaN, finite eps < 3.4e-21 or > 1.8e19 as in
 *         magcal_optics_run, min_pts outside 2..MAGCAL_MAX_MIN_PTS, bad enum,
 *         n > MAGCAL_MAX_SAMPLES); MAGCAL_ERR_ALIGNMENT (work not 4-byte aligned); MAGCAL_ERR_TOO_FEW_POINTS (n < min_pts);
 *         MAGCAL_ERR_NONFINITE (a NaN/Inf coordinate); MAGCAL_ERR_WORKSPACE (work_len too small).
 *         Outputs are untouched on failure.
 */
magcal_status_t magcal_optics_run3(const magcal_optics_cfg_t *cfg, const magcal_vec3_t *pts,
                                   size_t n, void *work, size_t work_len, uint16_t *order,
                                   float *reach, float *core, uint16_t *pred,
                                   magcal_optics_result_t *info);

/**
 * @brief Automatic eps, MinPts and eps' for 3-D samples on a sphere/ellipsoid shell (rule above).
 * @param[in]  pts        n points, finite.
 * @param[in]  n          16..MAGCAL_MAX_SAMPLES.
 * @param[out] work       scratch, 4-byte aligned, >= MAGCAL_OPTICS3_FILTER_WORKSPACE_LEN(n) bytes.
 * @param[in]  work_len   bytes at work.
 * @param[out] eps        eps for the ordering (= R, the robust shell radius).
 * @param[out] min_pts    MinPts (4).
 * @param[out] eps_prime  extraction radius (<= eps).
 * @return MAGCAL_OK; MAGCAL_ERR_NULL; MAGCAL_ERR_ARG (n > MAGCAL_MAX_SAMPLES);
 *         MAGCAL_ERR_ALIGNMENT (work not 4-byte aligned);
 *         MAGCAL_ERR_TOO_FEW_POINTS (n < 16); MAGCAL_ERR_NONFINITE; MAGCAL_ERR_WORKSPACE;
 *         MAGCAL_ERR_DEGENERATE (median radius 0 or outside the eps range of magcal_optics_run3,
 *         or fewer than 10 points in the shell band).
 *         Outputs untouched on failure.
 */
magcal_status_t magcal_optics_auto_params3(const magcal_vec3_t *pts, size_t n, void *work,
                                           size_t work_len, float *eps, uint16_t *min_pts,
                                           float *eps_prime);

/**
 * @brief 3-D points to inlier mask in one call: (auto params), OPTICS, ExtractDBSCAN at eps',
 * kept cluster. With given parameters the result equals magcal_optics_run3 +
 * magcal_optics_extract_dbscan + magcal_optics_largest_cluster; with automatic ones the kept
 * cluster is the one whose shell-band samples occupy the most of 96 direction cells (then the
 * most samples), so a rest phase cannot be kept as the shell while the rotation is rejected.
 * @param[in]  cfg        cfg->eps <= 0: automatic parameters; otherwise eps, eps_prime, min_pts as given.
 * @param[in]  pts        n points, finite.
 * @param[in]  n          cfg->min_pts (16 in auto mode)..MAGCAL_MAX_SAMPLES.
 * @param[out] work       scratch, 4-byte aligned, >= MAGCAL_OPTICS3_FILTER_WORKSPACE_LEN(n) bytes.
 * @param[in]  work_len   bytes at work.
 * @param[out] inlier_mask n bytes: 1 = kept (largest cluster), 0 = rejected.
 * @param[out] info       optional (NULL): parameters used and cluster statistics.
 * @return MAGCAL_OK; every status of magcal_optics_run3 / magcal_optics_auto_params3;
 *         MAGCAL_ERR_ARG (eps NaN, eps' > eps, eps' < 0 or not finite); MAGCAL_ERR_ALL_NOISE
 *         (no cluster). inlier_mask untouched on failure.
 */
magcal_status_t magcal_optics_filter3(const magcal_optics_cfg_t *cfg, const magcal_vec3_t *pts,
                                      size_t n, void *work, size_t work_len, uint8_t *inlier_mask,
                                      magcal_optics_result_t *info);

/**
 * @brief Start a time-sliced magcal_optics_filter3 (O(1): the checks that need no pass over the
 *        points; the finiteness and workspace checks are the first step's, in the one-shot call's
 *        order).
 * @param[out] s the slice state (caller memory, kept until the filter has finished); the other
 *               parameters as magcal_optics_filter3, and pts, work, inlier_mask, info must stay
 *               valid (pts unchanged) until it has finished (cfg is copied).
 * @return MAGCAL_OK (call magcal_optics_filter3_step); MAGCAL_ERR_NULL; MAGCAL_ERR_ALIGNMENT;
 *         MAGCAL_ERR_ARG; MAGCAL_ERR_TOO_FEW_POINTS (as magcal_optics_filter3).
 */
magcal_status_t magcal_optics_filter3_begin(magcal_optics3_slice_t *s, const magcal_optics_cfg_t *cfg,
                                            const magcal_vec3_t *pts, size_t n, void *work,
                                            size_t work_len, uint8_t *inlier_mask,
                                            magcal_optics_result_t *info);

/**
 * @brief Do about `budget` estimated Cortex-M4F instructions of the filter (at least one visit;
 *        the overshoot is at most one visit, or one unit of the given-parameter path's grid build
 *        and output, n x 60 / n x 16). The automatic path is resumable throughout: finiteness
 *        pass, pair scale, robust centres and thinnings, band counts, the ordering at eps = R
 *        (per candidate), the eps' probes, the extraction, the widest-shell selection and the mask.
 * @param[in,out] s     started by magcal_optics_filter3_begin.
 * @param[in]     budget estimated M4F instructions (0 counts as 1).
 * @param[out]    used   NULL, or the instructions charged by this call.
 * @return MAGCAL_IN_PROGRESS while work remains; then exactly the status (and outputs) of
 *         magcal_optics_filter3, returned again by any further call; MAGCAL_ERR_NULL (s NULL);
 *         MAGCAL_ERR_ARG (s not started by a successful begin).
 */
magcal_status_t magcal_optics_filter3_step(magcal_optics3_slice_t *s, uint32_t budget, uint32_t *used);
#endif /* MAGCAL_CFG_ENABLE_3D */

#ifdef __cplusplus
}
#endif

#endif /* MAGCAL_OPTICS_H */
