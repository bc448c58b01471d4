/*
 * The public one-shot 2-D conic fits magcal_ellipse_fit() and magcal_ellipse_fit_idx(): the
 * point source, the index check, then the least-squares fit or (5 points) the exact path, both
 * in ellipse_fit.c.
 */
#include "magcal/ellipse.h"

#include <math.h>

#include "ellipse_internal.h"
#include "magcal_internal.h"

/* 1 when idx[k0..k1-1] < n_pts (the index check of magcal_ellipse_fit_idx). */
int magcal_efit_idx_in_range(const uint16_t *idx, size_t k0, size_t k1, size_t n_pts)
{
    size_t k;
    for (k = k0; k < k1; ++k) {
        if ((size_t)idx[k] >= n_pts) {
            return 0;
        }
    }
    return 1;
}

/* The 5-point exact fit as one unit (the slice's single visit of FIT_PH_IDX + FIT_PH_FIVE; the
 * RANSAC draws call it without a slice on their stack): index check, then
 * magcal_efit_fit_five(). */
static MAGCAL_NOINLINE magcal_status_t fit_idx_five(const magcal_vec2_t *pts, size_t n_pts,
                                                    const uint16_t *idx, magcal_ellipse_t *out)
{
    magcal_efit_src_t src;
    if (magcal_efit_idx_in_range(idx, 0u, MAGCAL_ELLIPSE_MIN_POINTS, n_pts) == 0) {
        return MAGCAL_ERR_ARG;
    }
    src.pts = pts;
    src.n = MAGCAL_ELLIPSE_MIN_POINTS;
    src.mask = NULL;
    src.idx = idx;
    return magcal_efit_fit_five(&src, out);
}

magcal_status_t magcal_ellipse_fit(const magcal_vec2_t *pts, size_t n, const uint8_t *mask,
                                   magcal_ellipse_t *out)
{
    magcal_efit_src_t src;

    if (pts == NULL || out == NULL) {
        return MAGCAL_ERR_NULL;
    }
    magcal_efit_src_masked(&src, pts, n, mask);
    return magcal_efit_fit_normal(&src, out);
}

magcal_status_t magcal_ellipse_fit_idx(const magcal_vec2_t *pts, size_t n_pts, const uint16_t *idx,
                                       size_t m, magcal_ellipse_t *out)
{
    magcal_efit_src_t src;

    if (pts == NULL || idx == NULL || out == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (m > MAGCAL_ELLIPSE_MAX_POINTS) {
        return MAGCAL_ERR_ARG;
    }
    if (m < MAGCAL_ELLIPSE_MIN_POINTS) {
        return MAGCAL_ERR_TOO_FEW_POINTS;
    }
    if (m == MAGCAL_ELLIPSE_MIN_POINTS) {
        return fit_idx_five(pts, n_pts, idx, out);
    }
    if (magcal_efit_idx_in_range(idx, 0u, m, n_pts) == 0) {
        return MAGCAL_ERR_ARG;
    }
    src.pts = pts;
    src.n = m;
    src.mask = NULL;
    src.idx = idx;
    return magcal_efit_fit_normal(&src, out);
}
