/* Classic DBSCAN on 2-D points (baseline for the OPTICS filter), shared neighbour search. */
#include "magcal/dbscan.h"

#include <math.h>

#include "magcal_internal.h"
#include "neighbors.h"

#if MAGCAL_CFG_ENABLE_DBSCAN /* whole file: config.h feature switch */

#define LABEL_UNSEEN ((int16_t)-2)

/* Number of points within eps of p (p included). */
static size_t count_neighbors(const magcal_nbr_t *nb, size_t p, float eps2)
{
    magcal_nbr_ranges_t rg;
    size_t ri;
    size_t k;
    size_t cnt = 0u;
    const magcal_vec2_t *pts = nb->pts;
    magcal_nbr_query(nb, p, &rg);
    for (ri = 0; ri < rg.n_ranges; ++ri) {
        for (k = rg.begin[ri]; k < rg.end[ri]; ++k) {
            size_t j = rg.idx != NULL ? rg.idx[k] : k;
            float dx = pts[j].x - pts[p].x;
            float dy = pts[j].y - pts[p].y;
            if (dx * dx + dy * dy <= eps2) {
                ++cnt;
            }
        }
    }
    return cnt;
}

magcal_status_t magcal_dbscan_run(const magcal_dbscan_cfg_t *cfg, const magcal_vec2_t *pts,
                                  size_t n, void *work, size_t work_len, int16_t *labels,
                                  uint16_t *n_clusters, magcal_neighbors_t *used)
{
    magcal_nbr_t nb;
    magcal_status_t st;
    uint16_t *queue;
    float eps2;
    size_t s;
    size_t i;
    int32_t id = -1;
    if (cfg == NULL || pts == NULL || work == NULL || labels == NULL) {
        return MAGCAL_ERR_NULL;
    }
    /* eps^2 is the neighbour threshold: it must be a normal float (neighbors.h) */
    if (magcal_nbr_eps_ok(cfg->eps) == 0 || cfg->min_pts < 2u ||
        cfg->min_pts > MAGCAL_MAX_MIN_PTS ||
        (cfg->neighbors != MAGCAL_NEIGHBORS_BRUTE && cfg->neighbors != MAGCAL_NEIGHBORS_GRID) ||
        n > MAGCAL_MAX_SAMPLES) {
        return MAGCAL_ERR_ARG;
    }
    if (magcal_misalign(work, 4u) != 0u) {
        return MAGCAL_ERR_ALIGNMENT;
    }
    if (n < cfg->min_pts) {
        return MAGCAL_ERR_TOO_FEW_POINTS;
    }
    st = magcal_nbr_check_finite(pts, n);
    if (st != MAGCAL_OK) {
        return st;
    }
    if (work_len < MAGCAL_DBSCAN_WORKSPACE_LEN(n)) {
        return MAGCAL_ERR_WORKSPACE;
    }
    queue = (uint16_t *)work;
    magcal_nbr_build(&nb, pts, n, cfg->eps, cfg->neighbors, queue + n, NULL);
    eps2 = cfg->eps * cfg->eps;
    for (i = 0; i < n; ++i) {
        labels[i] = LABEL_UNSEEN;
    }
    for (s = 0; s < n; ++s) {
        size_t head = 0u;
        size_t tail = 0u;
        if (labels[s] != LABEL_UNSEEN) {
            continue;
        }
        if (count_neighbors(&nb, s, eps2) < cfg->min_pts) {
            labels[s] = MAGCAL_OPTICS_NOISE; /* may become a border point later */
            continue;
        }
        ++id;
        labels[s] = (int16_t)id;
        queue[tail] = (uint16_t)s;
        ++tail;
        /* Breadth-first expansion; each point enters the queue at most once (labelled on entry). */
        while (head < tail) {
            size_t p = queue[head];
            magcal_nbr_ranges_t rg;
            size_t ri;
            size_t k;
            ++head;
            if (p != s && count_neighbors(&nb, p, eps2) < cfg->min_pts) {
                continue; /* border point: labelled, not expanded */
            }
            magcal_nbr_query(&nb, p, &rg);
            for (ri = 0; ri < rg.n_ranges; ++ri) {
                for (k = rg.begin[ri]; k < rg.end[ri]; ++k) {
                    size_t j = rg.idx != NULL ? rg.idx[k] : k;
                    float dx = pts[j].x - pts[p].x;
                    float dy = pts[j].y - pts[p].y;
                    if (dx * dx + dy * dy > eps2) {
                        continue;
                    }
                    if (labels[j] == LABEL_UNSEEN) {
                        labels[j] = (int16_t)id;
                        queue[tail] = (uint16_t)j;
                        ++tail;
                    } else if (labels[j] == MAGCAL_OPTICS_NOISE) {
                        labels[j] = (int16_t)id; /* border point: non-core, never expanded */
                    } else {
                        /* already in a cluster: nothing to do */
                    }
                }
            }
        }
    }
    if (n_clusters != NULL) {
        const int32_t count = id + 1;
        *n_clusters = (uint16_t)count;
    }
    if (used != NULL) {
        *used = nb.use_grid ? MAGCAL_NEIGHBORS_GRID : MAGCAL_NEIGHBORS_BRUTE;
    }
    return MAGCAL_OK;
}

#endif /* MAGCAL_CFG_ENABLE_DBSCAN */
