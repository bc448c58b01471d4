/*
 * 5-parameter least-squares conic fit x^2 + A xy + B y^2 + C x + D y + E = 0 in float32
 * (algorithms.md 2.1-2.5, 3.1-3.2); the ellipse-to-circle corrections of 2.4 are ellipse_cal.c.
 *
 * Pipeline of a fit (no workspace, three passes over the caller's samples):
 *   1. scan: count the used points, reject NaN/Inf, bounding box;
 *   2. normalise on the bounding-box mid-range and half-diagonal (|x~|, |y~| <= 1), accumulate
 *      the 13 power sums S_pq (p + q <= 4) with Kahan summation, test collinearity on the 2x2
 *      covariance, assemble W^T W and W^T Y, solve with the equilibrated LDL^T and its pivot test;
 *   3. geometry (centre, axes, angle) in normalised coordinates, mapped back by
 *      c = m + s c~, r = s r~ (angles unchanged), then the RMS radial residual.
 * The 5-point exact path (RANSAC minimal sets) replaces step 2's normal equations by Gaussian
 * elimination with partial pivoting on the 5x5 system itself.
 *
 * This file: the passes of the normalised least-squares fit, the 5-point exact path and the
 * one-shot fits (fit_normal: every point in one go; magcal_ellipse_fit_seed). The other entry
 * points are ellipse.c, the time-sliced fit ellipse_slice.c (ellipse_internal.h); the 5-point
 * path shares this file with conic_finish() so its frames stay as they were in one file.
 */
#include "magcal/ellipse.h"

#include <math.h>

#include "ellipse_internal.h"
#include "magcal_internal.h"

/* The points of a masked fit: pts[k] where mask[k] != 0 (mask NULL: every point). */
void magcal_efit_src_masked(magcal_efit_src_t *src, const magcal_vec2_t *pts, size_t n,
                            const uint8_t *mask)
{
    src->pts = pts;
    src->n = n;
    src->mask = mask;
    src->idx = NULL;
}

static int src_point(const magcal_efit_src_t *src, size_t k, magcal_vec2_t *p)
{
    if (src->idx != NULL) {
        *p = src->pts[src->idx[k]];
        return 1;
    }
    if (src->mask != NULL && src->mask[k] == 0u) {
        return 0;
    }
    *p = src->pts[k];
    return 1;
}

/* Pass 1 over the points k0..k1-1: number of used points *cnt, finiteness, bounding box (bb = xmin,
 * xmax, ymin, ymax) and the largest magnitude per axis (amax = max|x|, max|y|, for the seed's
 * scaling). bb and amax start at 0 with *cnt = 0. */
magcal_status_t magcal_efit_src_scan_range(const magcal_efit_src_t *src, size_t k0, size_t k1,
                                           size_t *cnt, float bb[4], float amax[2])
{
    size_t k;
    magcal_vec2_t p;

    for (k = k0; k < k1; ++k) {
        if (src_point(src, k, &p) == 0) {
            continue;
        }
        if (!magcal_isfinite_f(p.x) || !magcal_isfinite_f(p.y)) {
            return MAGCAL_ERR_NONFINITE;
        }
        if (*cnt == 0u) {
            bb[0] = p.x;
            bb[1] = p.x;
            bb[2] = p.y;
            bb[3] = p.y;
        } else {
            bb[0] = (p.x < bb[0]) ? p.x : bb[0];
            bb[1] = (p.x > bb[1]) ? p.x : bb[1];
            bb[2] = (p.y < bb[2]) ? p.y : bb[2];
            bb[3] = (p.y > bb[3]) ? p.y : bb[3];
        }
        amax[0] = (fabsf(p.x) > amax[0]) ? fabsf(p.x) : amax[0];
        amax[1] = (fabsf(p.y) > amax[1]) ? fabsf(p.y) : amax[1];
        ++*cnt;
    }
    return MAGCAL_OK;
}

/* The count rule after pass 1. */
magcal_status_t magcal_efit_scan_count_ok(size_t cnt)
{
    if (cnt > MAGCAL_ELLIPSE_MAX_POINTS) {
        return MAGCAL_ERR_ARG;
    }
    if (cnt < MAGCAL_ELLIPSE_MIN_POINTS) {
        return MAGCAL_ERR_TOO_FEW_POINTS;
    }
    return MAGCAL_OK;
}

/* Pass 1 over every point of src. */
static magcal_status_t src_scan(const magcal_efit_src_t *src, size_t *count, float bb[4],
                                float amax[2])
{
    size_t cnt = 0u;
    magcal_status_t st;
    size_t j;

    for (j = 0u; j < 4u; ++j) {
        bb[j] = 0.0f;
    }
    amax[0] = 0.0f;
    amax[1] = 0.0f;
    st = magcal_efit_src_scan_range(src, 0u, src->n, &cnt, bb, amax);
    if (st != MAGCAL_OK) {
        return st;
    }
    st = magcal_efit_scan_count_ok(cnt);
    if (st != MAGCAL_OK) {
        return st;
    }
    *count = cnt;
    return MAGCAL_OK;
}

/* Centred normalisation: mid-range of the bounding box, isotropic scale = half its diagonal. */
magcal_status_t magcal_efit_norm_centred(const float bb[4], magcal_efit_norm_t *nm, float *scale)
{
    float wx = bb[1] - bb[0];
    float wy = bb[3] - bb[2];
    float big = (wx > wy) ? wx : wy;
    float small = (wx > wy) ? wy : wx;
    float s;
    float r;

    if (!magcal_isfinite_f(wx) || !magcal_isfinite_f(wy)) {
        return MAGCAL_ERR_ILL_CONDITIONED; /* finite points whose range overflows float32 */
    }
    if (!(big > 0.0f)) {
        return MAGCAL_ERR_DEGENERATE; /* all points identical */
    }
    r = small / big;
    s = 0.5f * big * sqrtf(1.0f + r * r);
    nm->mx = 0.5f * bb[0] + 0.5f * bb[1];
    nm->my = 0.5f * bb[2] + 0.5f * bb[3];
    nm->isx = 1.0f / s;
    nm->isy = nm->isx;
    *scale = s;
    return MAGCAL_OK;
}

/* Pass 2 over the points k0..k1-1: power sums of the normalised points into mom (compensation
 * comp; both start at 0), Kahan-compensated unless plain != 0 (the seed's plain float32
 * accumulation, kept only for magcal_ellipse_fit_seed()). */
void magcal_efit_src_moments_range(const magcal_efit_src_t *src, const magcal_efit_norm_t *nm,
                                   int plain, size_t k0, size_t k1, float mom[S_COUNT],
                                   float comp[S_COUNT])
{
    float v[S_COUNT];
    size_t k;
    size_t j;
    magcal_vec2_t p;

    for (k = k0; k < k1; ++k) {
        float x;
        float y;
        if (src_point(src, k, &p) == 0) {
            continue;
        }
        x = (p.x - nm->mx) * nm->isx;
        y = (p.y - nm->my) * nm->isy;
        v[S10] = x;
        v[S01] = y;
        v[S20] = x * x;
        v[S11] = x * y;
        v[S02] = y * y;
        v[S30] = v[S20] * x;
        v[S21] = v[S20] * y;
        v[S12] = x * v[S02];
        v[S03] = y * v[S02];
        v[S31] = v[S20] * v[S11];
        v[S22] = v[S20] * v[S02];
        v[S13] = v[S11] * v[S02];
        v[S04] = v[S02] * v[S02];
        for (j = 0u; j < S_COUNT; ++j) {
            if (plain != 0) {
                mom[j] += v[j];
            } else {
                magcal_kahan_add(&mom[j], &comp[j], v[j]);
            }
        }
    }
}

void magcal_efit_moments_zero(float mom[S_COUNT], float comp[S_COUNT])
{
    size_t j;
    for (j = 0u; j < S_COUNT; ++j) {
        mom[j] = 0.0f;
        comp[j] = 0.0f;
    }
}

/* Pass 2 over every point of src. */
static MAGCAL_NOINLINE void src_moments(const magcal_efit_src_t *src, const magcal_efit_norm_t *nm,
                                        int plain, float mom[S_COUNT])
{
    float comp[S_COUNT];
    magcal_efit_moments_zero(mom, comp);
    magcal_efit_src_moments_range(src, nm, plain, 0u, src->n, mom, comp);
}

/* Collinear (or nearly) points: smaller covariance eigenvalue below a fraction of the larger.
 * det/tr^2 = l1 l2 / (l1 + l2)^2 is the eigenvalue ratio when that ratio is small. Reads only
 * mom[S10..S02] (the first five entries). */
int magcal_efit_moments_collinear(const float *mom, float cnt)
{
    float inv = 1.0f / cnt;
    float mu = mom[S10] * inv;
    float mv = mom[S01] * inv;
    float cxx = mom[S20] * inv - mu * mu;
    float cxy = mom[S11] * inv - mu * mv;
    float cyy = mom[S02] * inv - mv * mv;
    float tr = cxx + cyy;
    float det = cxx * cyy - cxy * cxy;

    return !(tr > 0.0f) || !(det > MAGCAL_ELLIPSE_COLLINEAR_TOL * tr * tr);
}

/* moments_solve with the matrix on this frame (the one-shot fits; the slice lends its scratch). */
static MAGCAL_NOINLINE magcal_status_t moments_solve_own(float mom[S_COUNT], float cnt,
                                                         float *min_pivot)
{
    float a[25];
    return magcal_efit_moments_solve(mom, cnt, a, min_pivot);
}

/* Signed radial distance of p to the ellipse given by its centre, quadratic form and semi-minor
 * axis (the fields of magcal_ellipse_t that the residual needs). */
static float radial_residual(const float geo[6], magcal_vec2_t p)
{
    float ux = p.x - geo[0];
    float uy = p.y - geo[1];
    float a = (geo[2] * ux + 2.0f * geo[3] * uy) * ux + geo[4] * uy * uy;
    float n2 = ux * ux + uy * uy;
    float nrm;

    if (!(a > 0.0f) || !(n2 > 0.0f)) {
        return -geo[5]; /* at the centre */
    }
    nrm = sqrtf(n2);
    return nrm - nrm / sqrtf(a);
}

float magcal_ellipse_residual(const magcal_ellipse_t *e, magcal_vec2_t p)
{
    float geo[6];

    if (e == NULL || !magcal_isfinite_f(p.x) || !magcal_isfinite_f(p.y)) {
        return NAN;
    }
    geo[0] = e->center.x;
    geo[1] = e->center.y;
    geo[2] = e->qform[0];
    geo[3] = e->qform[1];
    geo[4] = e->qform[2];
    geo[5] = e->semi_minor;
    return radial_residual(geo, p);
}

/* Pass 3 over the points k0..k1-1: sum of squared radial residuals, acc = (sum, compensation). */
void magcal_efit_src_rms_range(const magcal_efit_src_t *src, const float geo[6], size_t k0,
                               size_t k1, float acc[2])
{
    size_t k;
    magcal_vec2_t p;

    for (k = k0; k < k1; ++k) {
        float r;
        if (src_point(src, k, &p) == 0) {
            continue;
        }
        r = radial_residual(geo, p);
        magcal_kahan_add(&acc[0], &acc[1], r * r);
    }
}

/*
 * Geometry of x^2 + A xy + B y^2 + C x + D y + E = 0 given in coordinates x~ = (x - mx)/s
 * (isotropic s, so angles are unchanged and lengths scale by s; algorithms.md 2.3) into geo
 * (centre, qform, semi-minor axis: what the residual needs) and, when e is not NULL, into e (every
 * field but residual_rms, min_pivot and n_used). Deterministic: the fits call it once for the
 * residuals and again, once every check has passed, straight into the caller's result (no
 * ellipse-sized temporary on the deepest stack path).
 */
magcal_status_t magcal_efit_conic_geometry(const float coef[5], float mx, float my, float s,
                                           magcal_ellipse_t *e, float geo[6])
{
    float ca = coef[0];
    float cb = coef[1];
    float delta = 4.0f * cb - ca * ca;
    float fro = 1.0f + 0.5f * ca * ca + cb * cb;
    float x0;
    float y0;
    float kk;
    float l1;
    float r1;
    float r2;
    float cx;
    float cy;
    float q11;
    size_t i;

    if (fabsf(delta) <= MAGCAL_ELLIPSE_PARABOLA_TOL * fro) {
        return MAGCAL_ERR_PARABOLA;
    }
    if (delta < 0.0f) {
        return MAGCAL_ERR_HYPERBOLA;
    }
    x0 = (ca * coef[3] - 2.0f * cb * coef[2]) / delta;
    y0 = (ca * coef[2] - 2.0f * coef[3]) / delta;
    kk = -(coef[4] + 0.5f * (coef[2] * x0 + coef[3] * y0));
    if (!(kk > 0.0f)) {
        return MAGCAL_ERR_IMAGINARY;
    }
    l1 = 0.5f * (1.0f + cb) + 0.5f * sqrtf((1.0f - cb) * (1.0f - cb) + ca * ca);
    r1 = sqrtf(kk / l1) * s;
    /* l2 = det/l1: no cancellation for thin ellipses */
    r2 = sqrtf(kk / ((0.25f * delta) / l1)) * s;
    cx = mx + s * x0;
    cy = my + s * y0;
    q11 = 1.0f / (kk * s * s);
    if (!magcal_isfinite_f(cx) || !magcal_isfinite_f(cy) || !magcal_isfinite_f(r2) ||
        !magcal_isfinite_f(q11) || !(q11 > 0.0f) || !(r1 > 0.0f)) {
        return MAGCAL_ERR_ILL_CONDITIONED; /* under/overflow of a nearly singular conic */
    }
    geo[0] = cx;
    geo[1] = cy;
    geo[2] = q11;
    geo[3] = 0.5f * ca * q11;
    geo[4] = cb * q11;
    geo[5] = r1;
    if (e == NULL) {
        return MAGCAL_OK;
    }
    e->center.x = cx;
    e->center.y = cy;
    e->semi_minor = r1;
    e->semi_major = r2;
    e->angle_rad = 0.0f; /* conic_store (atan2f beside this frame) */
    for (i = 0u; i < 5u; ++i) {
        e->coef[i] = coef[i];
    }
    e->norm_center.x = mx;
    e->norm_center.y = my;
    e->norm_scale = s;
    e->qform[0] = geo[2];
    e->qform[1] = geo[3];
    e->qform[2] = geo[4];
    return MAGCAL_OK;
}

/* Geometry, residual RMS over the cnt used points of src (NULL: RMS 0) and the result in one go
 * (the seed's fit, the 5-point path, magcal_ellipse_from_conic()). */
magcal_status_t magcal_efit_conic_finish(const float coef[5], float mx, float my, float s,
                                         float min_pivot, size_t cnt, const magcal_efit_src_t *src,
                                         magcal_ellipse_t *out)
{
    float geo[6];
    float rms = 0.0f;
    magcal_status_t st = magcal_efit_conic_geometry(coef, mx, my, s, NULL, geo);

    if (st != MAGCAL_OK) {
        return st;
    }
    if (src != NULL) {
        float acc[2] = {0.0f, 0.0f};
        magcal_efit_src_rms_range(src, geo, 0u, src->n, acc);
        rms = sqrtf(acc[0] / (float)cnt);
    }
    return magcal_efit_conic_store(coef, mx, my, s, rms, min_pivot, cnt, out);
}

/* Pass 1 and the centred normalisation, in a frame of their own. */
magcal_status_t magcal_efit_prepare_centred(const magcal_efit_src_t *src, size_t *count,
                                            magcal_efit_norm_t *nm, float *scale)
{
    float bb[4];
    float amax[2];
    magcal_status_t st = src_scan(src, count, bb, amax);

    if (st != MAGCAL_OK) {
        return st;
    }
    return magcal_efit_norm_centred(bb, nm, scale);
}

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

/*
 * The one-shot least-squares fit: the slice's passes (src_scan_range, src_moments_range,
 * moments_solve, conic_geometry + src_rms_range + conic_store) over every point in one go. Not
 * begin + step(UINT32_MAX): the slice state (216 B on Cortex-M4F) on this frame put the
 * calibrator's run() at 560 B of stack, over its 512-B budget. The sliced fit gives the same
 * result bit for bit (tests/test_ellipse.c, every budget).
 */
MAGCAL_NOINLINE magcal_status_t magcal_efit_fit_normal(const magcal_efit_src_t *src,
                                                       magcal_ellipse_t *out)
{
    float mom[S_COUNT];
    float s = 1.0f;
    float minp = 0.0f;
    size_t cnt = 0u;
    magcal_efit_norm_t nm;
    magcal_status_t st;

    st = magcal_efit_prepare_centred(src, &cnt, &nm, &s);
    if (st != MAGCAL_OK) {
        return st;
    }
    src_moments(src, &nm, 0, mom);
    if (magcal_efit_moments_collinear(mom, (float)cnt) != 0) {
        return MAGCAL_ERR_DEGENERATE;
    }
    st = moments_solve_own(mom, (float)cnt, &minp);
    if (st != MAGCAL_OK) {
        return st;
    }
    return magcal_efit_conic_finish(mom, nm.mx, nm.my, s, minp, cnt, src, out);
}

/* Pass 1 and the seed's max-abs normalisation (no centring), in a frame of their own. */
static magcal_status_t prepare_seed(const magcal_efit_src_t *src, size_t *count,
                                    magcal_efit_norm_t *nm)
{
    float bb[4];
    float amax[2];
    magcal_status_t st = src_scan(src, count, bb, amax);

    if (st != MAGCAL_OK) {
        return st;
    }
    if (!(amax[0] > 0.0f) || !(amax[1] > 0.0f)) {
        return MAGCAL_ERR_DEGENERATE; /* a whole axis is zero: collinear */
    }
    nm->mx = 0.0f;
    nm->my = 0.0f;
    nm->isx = 1.0f / amax[0];
    nm->isy = 1.0f / amax[1];
    return MAGCAL_OK;
}

magcal_status_t magcal_ellipse_fit_seed(const magcal_vec2_t *pts, size_t n, const uint8_t *mask,
                                        magcal_ellipse_t *out)
{
    magcal_efit_src_t src;
    float mom[S_COUNT];
    float cu[5];
    float sx;
    float sy;
    float rx;
    float minp = 0.0f;
    size_t cnt = 0u;
    magcal_efit_norm_t nm;
    magcal_status_t st;

    if (pts == NULL || out == NULL) {
        return MAGCAL_ERR_NULL;
    }
    magcal_efit_src_masked(&src, pts, n, mask);
    st = prepare_seed(&src, &cnt, &nm);
    if (st != MAGCAL_OK) {
        return st;
    }
    src_moments(&src, &nm, 1, mom);
    if (magcal_efit_moments_collinear(mom, (float)cnt) != 0) {
        return MAGCAL_ERR_DEGENERATE;
    }
    st = moments_solve_own(mom, (float)cnt, &minp);
    if (st != MAGCAL_OK) {
        return st;
    }
    /* Back to input units (algorithms.md 2.2 with mx = my = 0); geometry extracted there. */
    sx = 1.0f / nm.isx;
    sy = 1.0f / nm.isy;
    rx = sx / sy;
    cu[0] = mom[0] * rx;
    cu[1] = mom[1] * rx * rx;
    cu[2] = mom[2] * sx;
    cu[3] = mom[3] * sx * rx;
    cu[4] = mom[4] * sx * sx;
    return magcal_efit_conic_finish(cu, 0.0f, 0.0f, 1.0f, minp, cnt, &src, out);
}
