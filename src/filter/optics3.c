/*
 * The 3-D OPTICS filter (optics.h magcal_optics_filter3; optics3_internal.h): with given
 * parameters one ordering with on-the-fly extraction (optics3_order.c); with automatic ones the
 * rule (optics3_auto.c), ExtractDBSCAN of its ordering, and the widest-shell selection (a rest
 * phase, one direction, cannot win over the rotation).
 */
#include <math.h>
#include <string.h>

#include "magcal/optics.h"
#include "magcal_internal.h"

#if MAGCAL_CFG_ENABLE_3D /* whole file: config.h feature switch (optics_core.h inside) */
#include "optics3_internal.h"

/* Direction cell (0..95) of d on the cube around the centre: the face of its largest
 * component (6), then 4 x 4 bins of the other two over [-1, 1] (no trigonometry). */
static unsigned dir_cell3(float dx, float dy, float dz)
{
    const float ax = fabsf(dx);
    const float ay = fabsf(dy);
    const float az = fabsf(dz);
    unsigned face;
    float m;
    float u;
    float v;
    float fu;
    float fv;
    int32_t iu;
    int32_t iv;
    if (ax >= ay && ax >= az) {
        face = 1u;
        if (dx >= 0.0f) {
            face = 0u;
        }
        m = ax;
        u = dy;
        v = dz;
    } else if (ay >= az) {
        face = 3u;
        if (dy >= 0.0f) {
            face = 2u;
        }
        m = ay;
        u = dx;
        v = dz;
    } else {
        face = 5u;
        if (dz >= 0.0f) {
            face = 4u;
        }
        m = az;
        u = dx;
        v = dy;
    }
    fu = (u / m + 1.0f) * 2.0f;
    fv = (v / m + 1.0f) * 2.0f;
    iu = (int32_t)fu;
    iv = (int32_t)fv;
    iu = iu < 0 ? 0 : (iu > 3 ? 3 : iu);
    iv = iv < 0 ? 0 : (iv > 3 ? 3 : iv);
    return face * 16u + (unsigned)iu * 4u + (unsigned)iv;
}

/*
 * Shell selection of the automatic filter: among the clusters of labels (ExtractDBSCAN over
 * au->order: each cluster is one stretch of the ordering, noise in between), keep the one whose
 * shell-band samples occupy the most direction cells around the centre, then the most samples,
 * then the smaller id. A rest phase (one direction) cannot win over the rotation.
 * Returns MAGCAL_ERR_ALL_NOISE (mask untouched) when there is no cluster.
 */
static magcal_status_t keep_widest3(const magcal_o3_auto_t *au, const int16_t *labels,
                                    uint8_t *inlier_mask, int16_t *id_out, uint16_t *count_out)
{
    uint32_t cur[3] = {0u, 0u, 0u};
    uint32_t best_ext = 0u;
    size_t best_count = 0u;
    size_t cur_count = 0u;
    int32_t cur_id = -1;
    int32_t best_id = -1;
    size_t k;
    for (k = 0; k <= au->n; ++k) {
        const size_t p = k < au->n ? au->order[k] : 0u;
        const int32_t lab = k < au->n ? (int32_t)labels[p] : -2;
        if (lab == -2 || (lab >= 0 && lab != cur_id)) {
            if (cur_id >= 0) {
                const uint32_t ext = magcal_ocore_popcount(cur[0]) + magcal_ocore_popcount(cur[1]) +
                                     magcal_ocore_popcount(cur[2]);
                if (ext > best_ext || (ext == best_ext && cur_count > best_count)) {
                    best_ext = ext;
                    best_count = cur_count;
                    best_id = cur_id;
                }
            }
            cur_id = lab;
            cur_count = 0u;
            cur[0] = 0u;
            cur[1] = 0u;
            cur[2] = 0u;
        }
        if (lab >= 0) {
            const float dx = au->pts[p].x - au->cen.x;
            const float dy = au->pts[p].y - au->cen.y;
            const float dz = au->pts[p].z - au->cen.z;
            const float d2 = dx * dx + dy * dy + dz * dz;
            ++cur_count;
            if (d2 >= au->lo2 && d2 <= au->hi2) {
                const unsigned cell = dir_cell3(dx, dy, dz);
                cur[cell >> 5] |= 1u << (cell & 31u);
            }
        }
    }
    if (best_id < 0) {
        return MAGCAL_ERR_ALL_NOISE;
    }
    for (k = 0; k < au->n; ++k) {
        inlier_mask[k] = (int32_t)labels[k] == best_id ? 1u : 0u;
    }
    *id_out = (int16_t)best_id;
    *count_out = (uint16_t)best_count;
    return MAGCAL_OK;
}

magcal_status_t magcal_optics_filter3(const magcal_optics_cfg_t *cfg, const magcal_vec3_t *pts,
                                      size_t n, void *work, size_t work_len, uint8_t *inlier_mask,
                                      magcal_optics_result_t *info)
{
    magcal_optics_cfg_t use;
    magcal_o3_ctx_t *c;
    magcal_status_t st;
    float eps_prime;
    uint8_t *w = (uint8_t *)work;
    if (cfg == NULL || pts == NULL || work == NULL || inlier_mask == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (magcal_misalign(work, 4u) != 0u) {
        return MAGCAL_ERR_ALIGNMENT;
    }
    use = *cfg;
    if (!(cfg->eps > 0.0f)) {
        magcal_o3_auto_t *au = magcal_o3_auto_record(w, n);
        int16_t *labels = (int16_t *)(void *)(w + MAGCAL_OPTICS3_FILTER_RUN_OFFSET_(n));
        uint16_t n_clusters = 0u;
        uint16_t count = 0u;
        int16_t id = MAGCAL_OPTICS_NOISE;
        size_t n_noise = 0u;
        size_t i;
        if (cfg->eps != cfg->eps) {
            return MAGCAL_ERR_ARG; /* NaN is not "auto" */
        }
        use.eps = 1.0f;
        use.min_pts = (uint16_t)AUTO3_MIN_PTS;
        st = magcal_ocore_check_cfg(&use);
        if (st == MAGCAL_OK) {
            st = magcal_o3_check_points(pts, n, AUTO3_MIN_N);
        }
        if (st == MAGCAL_OK && work_len < MAGCAL_OPTICS3_FILTER_WORKSPACE_LEN(n)) {
            st = MAGCAL_ERR_WORKSPACE;
        }
        if (st == MAGCAL_OK) {
            st = magcal_o3_auto_run(&use, pts, n, w, au);
        }
        if (st != MAGCAL_OK) {
            return st;
        }
        /* the run's workspace is free again: labels, then the cluster counts */
        (void)magcal_optics_extract_dbscan(au->order, au->reach, au->core, n, au->eps, au->eps_prime,
                                           labels, &n_clusters);
        for (i = 0; i < n; ++i) {
            n_noise += labels[i] == MAGCAL_OPTICS_NOISE ? 1u : 0u;
        }
        st = keep_widest3(au, labels, inlier_mask, &id, &count);
        if (info != NULL) {
            (void)memset(info, 0, sizeof *info);
            info->eps = au->eps;
            info->eps_prime = au->eps_prime;
            info->min_pts = (uint16_t)AUTO3_MIN_PTS;
            info->neighbors = au->neighbors;
            info->n_clusters = n_clusters;
            info->largest_id = id;
            info->n_inliers = count;
            info->n_noise = (uint16_t)n_noise;
        }
        return st;
    }
    st = magcal_ocore_check_cfg(&use);
    if (st != MAGCAL_OK) {
        return st;
    }
    eps_prime = cfg->eps_prime == 0.0f ? cfg->eps : cfg->eps_prime;
    if (!(eps_prime > 0.0f) || !magcal_isfinite_f(eps_prime) || eps_prime > cfg->eps) {
        return MAGCAL_ERR_ARG;
    }
    st = magcal_o3_check_points(pts, n, use.min_pts);
    if (st != MAGCAL_OK) {
        return st;
    }
    if (work_len < MAGCAL_OPTICS3_FILTER_WORKSPACE_LEN(n)) {
        return MAGCAL_ERR_WORKSPACE;
    }
    c = magcal_o3_ctx_setup(&use, pts, n, w + MAGCAL_OPTICS3_FILTER_RUN_OFFSET_(n));
    c->oc.reach = (float *)work;
    c->oc.labels = (int16_t *)(void *)(w + 4u * n);
    c->oc.eps_prime = eps_prime;
    magcal_o3_loop(c);
    magcal_ocore_fill_info(info, &c->oc, c->use_grid, use.eps, eps_prime);
    return magcal_ocore_filter_out(&c->oc, n, inlier_mask, info);
}


#endif /* MAGCAL_CFG_ENABLE_3D */
