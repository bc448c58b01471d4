/*
 * Post-processing of a finished 2-D or 3-D OPTICS ordering (optics.h): ExtractDBSCAN at eps' of
 * an ordering's reach and core distances, and the largest cluster of a labelling.
 */
#include "magcal/optics.h"

#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "magcal_internal.h"

magcal_status_t magcal_optics_extract_dbscan(const uint16_t *order, const float *reach,
                                             const float *core, size_t n, float eps,
                                             float eps_prime, int16_t *labels, uint16_t *n_clusters)
{
    size_t k;
    int32_t id = -1;
    if (order == NULL || reach == NULL || core == NULL || labels == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (n == 0u || n > MAGCAL_MAX_SAMPLES || !(eps > 0.0f) || !(eps_prime >= 0.0f) ||
        !magcal_isfinite_f(eps_prime) || eps_prime > eps) {
        return MAGCAL_ERR_ARG;
    }
    for (k = 0; k < n; ++k) {
        if (order[k] >= n) {
            return MAGCAL_ERR_ARG;
        }
    }
    for (k = 0; k < n; ++k) {
        size_t p = order[k];
        if (reach[p] > eps_prime) {
            if (core[p] <= eps_prime) {
                ++id;
                labels[p] = (int16_t)id;
            } else {
                labels[p] = MAGCAL_OPTICS_NOISE;
            }
        } else {
            labels[p] = (int16_t)id;
        }
    }
    if (n_clusters != NULL) {
        const int32_t count = id + 1;
        *n_clusters = (uint16_t)count;
    }
    return MAGCAL_OK;
}

magcal_status_t magcal_optics_largest_cluster(const int16_t *labels, size_t n, void *work,
                                              size_t work_len, uint8_t *inlier_mask,
                                              int16_t *cluster_id, uint16_t *count)
{
    uint16_t *cnt;
    size_t i;
    size_t best_count = 0u;
    int32_t best = -1;
    int32_t max_id = -1;
    if (labels == NULL || work == NULL || inlier_mask == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (n == 0u || n > MAGCAL_MAX_SAMPLES) {
        return MAGCAL_ERR_ARG;
    }
    if (magcal_misalign(work, 2u) != 0u) {
        return MAGCAL_ERR_ALIGNMENT;
    }
    if (work_len < MAGCAL_OPTICS_LARGEST_WORKSPACE_LEN(n)) {
        return MAGCAL_ERR_WORKSPACE;
    }
    for (i = 0; i < n; ++i) {
        if (labels[i] < -1 || (labels[i] >= 0 && (size_t)labels[i] >= n)) {
            return MAGCAL_ERR_ARG;
        }
        max_id = labels[i] > max_id ? labels[i] : max_id;
    }
    if (max_id < 0) {
        return MAGCAL_ERR_ALL_NOISE;
    }
    cnt = (uint16_t *)work;
    (void)memset(cnt, 0, ((size_t)max_id + 1u) * sizeof *cnt);
    for (i = 0; i < n; ++i) {
        if (labels[i] >= 0) {
            cnt[labels[i]]++;
        }
    }
    for (i = 0; i <= (size_t)max_id; ++i) {
        if (cnt[i] > best_count) { /* strict: ties keep the smaller id */
            best_count = cnt[i];
            best = (int32_t)i;
        }
    }
    for (i = 0; i < n; ++i) {
        inlier_mask[i] = (labels[i] == best) ? 1u : 0u;
    }
    if (cluster_id != NULL) {
        *cluster_id = (int16_t)best;
    }
    if (count != NULL) {
        *count = (uint16_t)best_count;
    }
    return MAGCAL_OK;
}

