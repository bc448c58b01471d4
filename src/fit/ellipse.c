/*
 * The 5-point exact conic (RANSAC minimal sets: Gaussian elimination with partial pivoting on the
 * 5x5 system itself, algorithms.md 2.1) and the public one-shot fits magcal_ellipse_fit() and
 * magcal_ellipse_fit_idx(); the least-squares passes they run are ellipse_fit.c.
 */
#include "magcal/ellipse.h"

#include <math.h>

#include "ellipse_internal.h"
#include "magcal_internal.h"

/* Exact conic through 5 points: Gaussian elimination with partial pivoting on W X = Y. */
/* Exact conic through the 5 normalised points of src: Gaussian elimination with partial pivoting
 * on W X = Y, into coef[5]; *minp gets the smallest pivot. Its own frame (the 5x6 tableau) is not
 * nested under magcal_efit_conic_finish(): MAGCAL_NOINLINE keeps the deepest stack path of the
 * fits short. */
static MAGCAL_NOINLINE magcal_status_t five_solve(const magcal_efit_src_t *src,
                                                  const magcal_efit_norm_t *nm, float coef[5],
                                                  float *minp)
{
    float w[5][6];
    float mom[5];
    float ptol = sqrtf(MAGCAL_ELLIPSE_PIVOT_TOL);
    size_t i;
    size_t j;
    size_t k;

    for (i = 0u; i < 5u; ++i) {
        mom[i] = 0.0f;
    }
    /* Rows [xy, y^2, x, y, 1 | -x^2]: |entries| <= 1 and the constant column makes each row's
     * max-abs exactly 1, so the rows are already equilibrated. mom[] gets S10, S01, S20, S11, S02
     * (the first five moment indices) for the collinearity test. */
    for (i = 0u; i < 5u; ++i) {
        magcal_vec2_t p = src->pts[src->idx[i]];
        float x = (p.x - nm->mx) * nm->isx;
        float y = (p.y - nm->my) * nm->isy;
        w[i][0] = x * y;
        w[i][1] = y * y;
        w[i][2] = x;
        w[i][3] = y;
        w[i][4] = 1.0f;
        w[i][5] = -x * x;
        mom[S10] += x;
        mom[S01] += y;
        mom[S20] += x * x;
        mom[S11] += x * y;
        mom[S02] += y * y;
    }
    if (magcal_efit_moments_collinear(mom, 5.0f) != 0) {
        return MAGCAL_ERR_DEGENERATE;
    }
    *minp = 1.0f;
    for (k = 0u; k < 5u; ++k) {
        size_t piv = k;
        float best = fabsf(w[k][k]);
        for (i = k + 1u; i < 5u; ++i) {
            if (fabsf(w[i][k]) > best) {
                best = fabsf(w[i][k]);
                piv = i;
            }
        }
        if (!(best > ptol)) {
            return MAGCAL_ERR_ILL_CONDITIONED;
        }
        *minp = (best < *minp) ? best : *minp;
        if (piv != k) {
            for (j = k; j < 6u; ++j) {
                float t = w[k][j];
                w[k][j] = w[piv][j];
                w[piv][j] = t;
            }
        }
        for (i = k + 1u; i < 5u; ++i) {
            float f = w[i][k] / w[k][k];
            for (j = k + 1u; j < 6u; ++j) {
                w[i][j] -= f * w[k][j];
            }
        }
    }
    for (i = 0u; i < 5u; ++i) { /* back substitution, k = 4 .. 0 */
        float acc;
        k = 4u - i;
        acc = w[k][5];
        for (j = k + 1u; j < 5u; ++j) {
            acc -= w[k][j] * coef[j];
        }
        coef[k] = acc / w[k][k];
    }
    return MAGCAL_OK;
}

/* MAGCAL_NOINLINE: keep the 5-point path out of magcal_ellipse_fit_idx's frame, which also sits
 * on the deepest path fit_normal -> moments_solve -> magcal_ldlt_solve. */
MAGCAL_NOINLINE magcal_status_t magcal_efit_fit_five(const magcal_efit_src_t *src,
                                                     magcal_ellipse_t *out)
{
    float coef[5];
    float s = 1.0f;
    float minp = 1.0f;
    size_t cnt = 0u;
    size_t i;
    size_t j;
    magcal_efit_norm_t nm;
    magcal_status_t st;

    for (i = 0u; i < 5u; ++i) {
        for (j = i + 1u; j < 5u; ++j) {
            if (src->idx[i] == src->idx[j]) {
                return MAGCAL_ERR_DEGENERATE;
            }
        }
    }
    st = magcal_efit_prepare_centred(src, &cnt, &nm, &s);
    if (st != MAGCAL_OK) {
        return st;
    }
    st = five_solve(src, &nm, coef, &minp);
    if (st != MAGCAL_OK) {
        return st;
    }
    return magcal_efit_conic_finish(coef, nm.mx, nm.my, s, minp, 5u, src, out);
}

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
