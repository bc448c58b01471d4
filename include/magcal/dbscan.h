/**
 * @file dbscan.h
 * @brief Classic DBSCAN (Ester, Kriegel, Sander & Xu 1996) on 2-D samples: the baseline the
 * OPTICS filter is compared against. Shares the neighbour search of optics.h.
 *
 * Definitions as algorithms.md 4.1: N_eps(p) = { q : |p - q| <= eps } includes p; p is a core
 * point when |N_eps(p)| >= MinPts. Clusters are numbered 0, 1, ... in the order of their first
 * core point by index; a border point (non-core, within eps of a core point) takes the cluster that
 * reaches it first; everything else is MAGCAL_OPTICS_NOISE (-1). Use
 * magcal_optics_largest_cluster() on the labels to keep the largest cluster.
 *
 * Units: any consistent unit; eps in the unit of the points. No heap, no recursion (the cluster
 * expansion uses a caller-owned queue).
 *
 * @code
 * static magcal_vec2_t pts[300];
 * static MAGCAL_DBSCAN_WORKSPACE_DECLARE(work, 300);
 * static int16_t labels[300];
 * magcal_dbscan_cfg_t cfg = MAGCAL_DBSCAN_CFG_DEFAULT;
 * uint16_t n_clusters;
 * cfg.eps = 0.05f;  // point unit
 * magcal_status_t st = magcal_dbscan_run(&cfg, pts, 300, work, sizeof work, labels, &n_clusters, NULL);
 * @endcode
 */
#ifndef MAGCAL_DBSCAN_H
#define MAGCAL_DBSCAN_H

#include <stddef.h>
#include <stdint.h>

#include "magcal/config.h"
#include "magcal/optics.h"
#include "magcal/status.h"
#include "magcal/types.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Workspace bytes for magcal_dbscan_run() on n points: queue uint16[n] + spatial index. */
#define MAGCAL_DBSCAN_WORKSPACE_LEN(n)                                                             \
    ((2u * (size_t)(n) + MAGCAL_NEIGHBORS_WORKSPACE_LEN(n) + 3u) & ~(size_t)3u)

/** Declare `name` as a correctly aligned workspace of MAGCAL_DBSCAN_WORKSPACE_LEN(n) bytes (config.h). */
#define MAGCAL_DBSCAN_WORKSPACE_DECLARE(name, n) MAGCAL_WORKSPACE_DECLARE(name, MAGCAL_DBSCAN_WORKSPACE_LEN(n))

/** DBSCAN configuration. */
typedef struct {
    float eps;                    /**< radius > 0 (may be +INFINITY), point unit */
    uint16_t min_pts;             /**< 2..MAGCAL_MAX_MIN_PTS, counting the point itself */
    magcal_neighbors_t neighbors; /**< neighbour search (identical results) */
} magcal_dbscan_cfg_t;

/** Defaults: eps must be set by the caller (0 is rejected), MinPts 4, grid search. */
#define MAGCAL_DBSCAN_CFG_DEFAULT                                                                  \
    {                                                                                              \
        0.0f, 4u, MAGCAL_NEIGHBORS_GRID                                                            \
    }

#if MAGCAL_CFG_ENABLE_DBSCAN
/**
 * @brief Label n points with DBSCAN(eps, MinPts).
 * @param[in]  cfg        eps, min_pts, neighbors.
 * @param[in]  pts        n points, finite.
 * @param[in]  n          cfg->min_pts..MAGCAL_MAX_SAMPLES.
 * @param[out] work       scratch, 4-byte aligned, >= MAGCAL_DBSCAN_WORKSPACE_LEN(n) bytes.
 * @param[in]  work_len   bytes at work.
 * @param[out] labels     n labels: cluster id 0, 1, ... or MAGCAL_OPTICS_NOISE.
 * @param[out] n_clusters optional (NULL): number of clusters.
 * @param[out] used       optional (NULL): neighbour search actually used (GRID -> BRUTE for eps = inf).
 * @return MAGCAL_OK; MAGCAL_ERR_NULL (cfg, pts, work or labels NULL); MAGCAL_ERR_ARG (eps not > 0,
 *         finite eps whose square is below FLT_MIN/1024 or overflows: eps < 3.4e-21 or eps > 1.8e19
 *         (use +INFINITY for "everything"),
 *         min_pts out of range, bad enum, n > MAGCAL_MAX_SAMPLES); MAGCAL_ERR_ALIGNMENT (work
 *         not 4-byte aligned);
 *         MAGCAL_ERR_TOO_FEW_POINTS (n < min_pts); MAGCAL_ERR_NONFINITE; MAGCAL_ERR_WORKSPACE.
 *         labels untouched on failure.
 */
magcal_status_t magcal_dbscan_run(const magcal_dbscan_cfg_t *cfg, const magcal_vec2_t *pts,
                                  size_t n, void *work, size_t work_len, int16_t *labels,
                                  uint16_t *n_clusters, magcal_neighbors_t *used);
#endif /* MAGCAL_CFG_ENABLE_DBSCAN */

#ifdef __cplusplus
}
#endif

#endif /* MAGCAL_DBSCAN_H */
