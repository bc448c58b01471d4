/*
 * The complete 3-D calibration (issue 14): pre-test fit -> density stage only when the data show a
 * gross outlier -> fit. The pre-test is the fit of all samples itself, so data without outliers
 * (the common case: a hand tumble) cost one fit and one residual pass, and every other case gives
 * exactly the result of the full composition (magcal_optics_filter3, then magcal_ellipsoid_fit on
 * its inliers).
 */
#include <string.h>

#include "ellipsoid_internal.h"
#include "magcal/ellipsoid.h"
#include "magcal/optics.h"
#include "magcal_internal.h"

#if MAGCAL_CFG_ENABLE_3D /* whole file: config.h feature switch */

/* Largest | |G(m - V)| - F | / F over all samples (NaN for a non-positive F): read from the
 * residuals magcal_ellipsoid_fit_ws left in its workspace `fwork` (every sample's, under the
 * returned calibration; the same float operations as recomputing them). */
static float max_residual_rel(const void *fwork, size_t n, const magcal_ellipsoid_cal_t *cal)
{
    const float *res =
        (const float *)(const void *)((const uint8_t *)fwork + MAGCAL_ELLIPSOID_FIT_SCRATCH_BYTES);
    float mx = 0.0f;
    size_t k;
    if (!(cal->field > 0.0f)) {
        return NAN;
    }
    for (k = 0u; k < n; ++k) {
        const float r = fabsf(res[k]);
        if (!(r <= mx)) {
            mx = r;
        }
    }
    return mx / cal->field;
}

static MAGCAL_NOINLINE magcal_status_t density_then_fit(const magcal_ellipsoid_calibrate_cfg_t *cfg,
                                        const magcal_vec3_t *m, size_t n, void *work,
                                        size_t work_len, uint8_t *inlier,
                                        magcal_ellipsoid_result_t *out,
                                        magcal_ellipsoid_calibrate_info_t *info)
{
    magcal_vec3_t *kept = (magcal_vec3_t *)work;
    /* the density mask is written behind the copies' final place: byte k of the mask is read
     * before copy j <= k is written, both run front to back */
    uint8_t *mask = (uint8_t *)work + n * (sizeof(magcal_vec3_t) - 1u);
    void *fwork = (uint8_t *)work + n * sizeof(magcal_vec3_t);
    const size_t flen = work_len - n * sizeof(magcal_vec3_t); /* the density stage's, then the fit's */
    magcal_status_t st;
    size_t k;
    size_t nk = 0u;
    st = magcal_optics_filter3(&cfg->density, m, n, fwork, flen, mask, &info->density);
    if (st != MAGCAL_OK) {
        return st;
    }
    info->density_ran = 1u;
    for (k = 0u; k < n; ++k) {
        const uint8_t keep = mask[k];
        if (inlier != NULL) {
            inlier[k] = keep;
        }
        if (keep != 0u) {
            kept[nk] = m[k];
            ++nk;
        }
    }
    info->n_density_rejected = n - nk;
    return magcal_ellipsoid_fit_ws(kept, nk, &cfg->fit, fwork, flen, out);
}

magcal_status_t magcal_ellipsoid_calibrate(const magcal_ellipsoid_calibrate_cfg_t *cfg,
                                           const magcal_vec3_t *m, size_t n, void *work,
                                           size_t work_len, uint8_t *inlier,
                                           magcal_ellipsoid_result_t *out,
                                           magcal_ellipsoid_calibrate_info_t *info)
{
    magcal_ellipsoid_calibrate_info_t *inf;
    magcal_ellipsoid_result_t *first;
    uint8_t *rest;
    size_t rest_len;
    if (cfg == NULL || m == NULL || work == NULL || out == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if ((cfg->mode != MAGCAL_ELLIPSOID_DENSITY_AUTO && cfg->mode != MAGCAL_ELLIPSOID_DENSITY_ALWAYS &&
         cfg->mode != MAGCAL_ELLIPSOID_DENSITY_NEVER) ||
        !(cfg->pretest_max_rel > 0.0f && cfg->pretest_max_rel <= 1.0f)) {
        return MAGCAL_ERR_ARG;
    }
    if (magcal_misalign(work, 4u) != 0u) {
        return MAGCAL_ERR_ALIGNMENT;
    }
    if (work_len < MAGCAL_ELLIPSOID_CALIBRATE_WORKSPACE_LEN(n)) {
        return MAGCAL_ERR_WORKSPACE;
    }
    /* layout: the pre-test's result | info when the caller gives none | the rest (the pre-test
     * fit's workspace; later the inlier copies, then the density stage's and the final fit's) */
    first = (magcal_ellipsoid_result_t *)(void *)magcal_ell_align_up(work); /* size_t inside */
    inf = (magcal_ellipsoid_calibrate_info_t *)(void *)((uint8_t *)first +
                                                        MAGCAL_ELLIPSOID_CALIBRATE_RESULT_SLOT);
    if (info != NULL) {
        inf = info;
    }
    (void)memset(inf, 0, sizeof(*inf));
    inf->pretest_max_rel = NAN;
    rest = (uint8_t *)work + MAGCAL_ELLIPSOID_CALIBRATE_SLOTS;
    rest_len = work_len - MAGCAL_ELLIPSOID_CALIBRATE_SLOTS;
    if (cfg->mode != MAGCAL_ELLIPSOID_DENSITY_ALWAYS) {
        const magcal_status_t st = magcal_ellipsoid_fit_ws(m, n, &cfg->fit, rest, rest_len, first);
        if (st == MAGCAL_OK) {
            inf->pretest_max_rel = max_residual_rel(rest, n, &first->cal);
        }
        if (cfg->mode == MAGCAL_ELLIPSOID_DENSITY_NEVER ||
            (st == MAGCAL_OK && inf->pretest_max_rel <= cfg->pretest_max_rel)) {
            if (st == MAGCAL_OK) {
                *out = *first;
                if (inlier != NULL) {
                    (void)memset(inlier, 1, n);
                }
            }
            return st;
        }
    }
    return density_then_fit(cfg, m, n, rest, rest_len, inlier, out, inf);
}

#endif /* MAGCAL_CFG_ENABLE_3D */
