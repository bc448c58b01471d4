/*
 * 5-parameter least-squares conic fit x^2 + A xy + B y^2 + C x + D y + E = 0 in float32
 * (algorithms.md 2.1-2.5, 3.1-3.2), and the ellipse-to-circle corrections of 2.4.
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
 */
#include "magcal/ellipse.h"

#include <math.h>

#include "magcal_internal.h"

/* Power sums S_pq = sum x~^p y~^q kept by the accumulator (indices into mom[]). */
#define S10 0u
#define S01 1u
#define S20 2u
#define S11 3u
#define S02 4u
#define S30 5u
#define S21 6u
#define S12 7u
#define S03 8u
#define S31 9u
#define S22 10u
#define S13 11u
#define S04 12u
#define S_COUNT 13u

/* The points a fit uses: pts[idx[k]] for k < n when idx is set, else pts[k] where mask[k] != 0. */
typedef struct {
    const magcal_vec2_t *pts;
    size_t n;
    const uint8_t *mask;
    const uint16_t *idx;
} fit_src_t;

/* Affine normalisation x~ = (x - mx) * isx, y~ = (y - my) * isy. */
typedef struct {
    float mx;
    float my;
    float isx;
    float isy;
} fit_norm_t;

/* The points of a masked fit: pts[k] where mask[k] != 0 (mask NULL: every point). */
static void src_masked(fit_src_t *src, const magcal_vec2_t *pts, size_t n, const uint8_t *mask)
{
    src->pts = pts;
    src->n = n;
    src->mask = mask;
    src->idx = NULL;
}

static int src_point(const fit_src_t *src, size_t k, magcal_vec2_t *p)
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
static magcal_status_t src_scan_range(const fit_src_t *src, size_t k0, size_t k1, size_t *cnt,
                                      float bb[4], float amax[2])
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
static magcal_status_t scan_count_ok(size_t cnt)
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
static magcal_status_t src_scan(const fit_src_t *src, size_t *count, float bb[4], float amax[2])
{
    size_t cnt = 0u;
    magcal_status_t st;
    size_t j;

    for (j = 0u; j < 4u; ++j) {
        bb[j] = 0.0f;
    }
    amax[0] = 0.0f;
    amax[1] = 0.0f;
    st = src_scan_range(src, 0u, src->n, &cnt, bb, amax);
    if (st != MAGCAL_OK) {
        return st;
    }
    st = scan_count_ok(cnt);
    if (st != MAGCAL_OK) {
        return st;
    }
    *count = cnt;
    return MAGCAL_OK;
}

/* Centred normalisation: mid-range of the bounding box, isotropic scale = half its diagonal. */
static magcal_status_t norm_centred(const float bb[4], fit_norm_t *nm, float *scale)
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
static void src_moments_range(const fit_src_t *src, const fit_norm_t *nm, int plain, size_t k0,
                              size_t k1, float mom[S_COUNT], float comp[S_COUNT])
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

static void moments_zero(float mom[S_COUNT], float comp[S_COUNT])
{
    size_t j;
    for (j = 0u; j < S_COUNT; ++j) {
        mom[j] = 0.0f;
        comp[j] = 0.0f;
    }
}

/* Pass 2 over every point of src. */
static MAGCAL_NOINLINE void src_moments(const fit_src_t *src, const fit_norm_t *nm, int plain,
                                         float mom[S_COUNT])
{
    float comp[S_COUNT];
    moments_zero(mom, comp);
    src_moments_range(src, nm, plain, 0u, src->n, mom, comp);
}

/* Collinear (or nearly) points: smaller covariance eigenvalue below a fraction of the larger.
 * det/tr^2 = l1 l2 / (l1 + l2)^2 is the eigenvalue ratio when that ratio is small. Reads only
 * mom[S10..S02] (the first five entries). */
static int moments_collinear(const float *mom, float cnt)
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

/* Normal equations of the rows w = [xy, y^2, x, y, 1], Y = -x^2, solved by equilibrated LDL^T
 * (a: the 5x5 matrix's storage, destroyed; the fit slice lends its scratch, off the stack).
 * On success the coefficients A..E overwrite mom[0..4] (the moments are dead by then; sharing the
 * array keeps the deepest stack path, through magcal_ldlt_solve, short). */
static magcal_status_t moments_solve(float mom[S_COUNT], float cnt, float a[25], float *min_pivot)
{

    a[0] = mom[S22];
    a[5] = mom[S13];
    a[6] = mom[S04];
    a[10] = mom[S21];
    a[11] = mom[S12];
    a[12] = mom[S20];
    a[15] = mom[S12];
    a[16] = mom[S03];
    a[17] = mom[S11];
    a[18] = mom[S02];
    a[20] = mom[S11];
    a[21] = mom[S02];
    a[22] = mom[S10];
    a[23] = mom[S01];
    a[24] = cnt;
    /* upper triangle is not read by magcal_ldlt_solve; fill it anyway for a defined matrix */
    a[1] = a[5];
    a[2] = a[10];
    a[3] = a[15];
    a[4] = a[20];
    a[7] = a[11];
    a[8] = a[16];
    a[9] = a[21];
    a[13] = a[17];
    a[14] = a[22];
    a[19] = a[23];
    /* right-hand side in mom[0..4], solved in place (no separate b[] on the stack); the order
     * writes each entry after its last read: S20 = mom[2] before mom[2] is replaced */
    mom[4] = -mom[S20];
    mom[0] = -mom[S31];
    mom[1] = -mom[S22];
    mom[2] = -mom[S30];
    mom[3] = -mom[S21];
    return magcal_ldlt_solve(a, mom, 5u, MAGCAL_ELLIPSE_PIVOT_TOL, min_pivot);
}

/* moments_solve with the matrix on this frame (the one-shot fits; the slice lends its scratch). */
static MAGCAL_NOINLINE magcal_status_t moments_solve_own(float mom[S_COUNT], float cnt, float *min_pivot)
{
    float a[25];
    return moments_solve(mom, cnt, a, min_pivot);
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
static void src_rms_range(const fit_src_t *src, const float geo[6], size_t k0, size_t k1,
                          float acc[2])
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
static magcal_status_t conic_geometry(const float coef[5], float mx, float my, float s,
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

/* The complete result into out, once the residual RMS is known to be finite (non-finite:
 * residuals of points ~1e19 from the centre overflow): the geometry again, straight into out. */
static magcal_status_t conic_store(const float coef[5], float mx, float my, float s, float rms,
                                   float min_pivot, size_t cnt, magcal_ellipse_t *out)
{
    float geo[6];
    magcal_status_t st;

    if (!magcal_isfinite_f(rms)) {
        return MAGCAL_ERR_ILL_CONDITIONED;
    }
    st = conic_geometry(coef, mx, my, s, out, geo);
    if (st == MAGCAL_OK) {
        out->angle_rad = 0.5f * atan2f(coef[0], 1.0f - coef[1]);
        out->min_pivot = min_pivot;
        out->n_used = (uint16_t)cnt;
        out->residual_rms = rms;
    }
    return st;
}

/* Geometry, residual RMS over the cnt used points of src (NULL: RMS 0) and the result in one go
 * (the seed's fit, the 5-point path, magcal_ellipse_from_conic()). */
static magcal_status_t conic_finish(const float coef[5], float mx, float my, float s,
                                    float min_pivot, size_t cnt, const fit_src_t *src,
                                    magcal_ellipse_t *out)
{
    float geo[6];
    float rms = 0.0f;
    magcal_status_t st = conic_geometry(coef, mx, my, s, NULL, geo);

    if (st != MAGCAL_OK) {
        return st;
    }
    if (src != NULL) {
        float acc[2] = {0.0f, 0.0f};
        src_rms_range(src, geo, 0u, src->n, acc);
        rms = sqrtf(acc[0] / (float)cnt);
    }
    return conic_store(coef, mx, my, s, rms, min_pivot, cnt, out);
}

/* Pass 1 and the centred normalisation, in a frame of their own. */
static magcal_status_t prepare_centred(const fit_src_t *src, size_t *count, fit_norm_t *nm,
                                       float *scale)
{
    float bb[4];
    float amax[2];
    magcal_status_t st = src_scan(src, count, bb, amax);

    if (st != MAGCAL_OK) {
        return st;
    }
    return norm_centred(bb, nm, scale);
}

/* Exact conic through 5 points: Gaussian elimination with partial pivoting on W X = Y. */
/* Exact conic through the 5 normalised points of src: Gaussian elimination with partial pivoting
 * on W X = Y, into coef[5]; *minp gets the smallest pivot. Its own frame (the 5x6 tableau) is not
 * nested under conic_finish(): MAGCAL_NOINLINE keeps the deepest stack path of the fits short. */
static MAGCAL_NOINLINE magcal_status_t five_solve(const fit_src_t *src, const fit_norm_t *nm,
                                                  float coef[5], float *minp)
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
    if (moments_collinear(mom, 5.0f) != 0) {
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
static MAGCAL_NOINLINE magcal_status_t fit_five(const fit_src_t *src, magcal_ellipse_t *out)
{
    float coef[5];
    float s = 1.0f;
    float minp = 1.0f;
    size_t cnt = 0u;
    size_t i;
    size_t j;
    fit_norm_t nm;
    magcal_status_t st;

    for (i = 0u; i < 5u; ++i) {
        for (j = i + 1u; j < 5u; ++j) {
            if (src->idx[i] == src->idx[j]) {
                return MAGCAL_ERR_DEGENERATE;
            }
        }
    }
    st = prepare_centred(src, &cnt, &nm, &s);
    if (st != MAGCAL_OK) {
        return st;
    }
    st = five_solve(src, &nm, coef, &minp);
    if (st != MAGCAL_OK) {
        return st;
    }
    return conic_finish(coef, nm.mx, nm.my, s, minp, 5u, src, out);
}

/*
 * Time-sliced fit. Weights: estimated Cortex-M4F instructions of one visit of each loop, measured
 * on QEMU mps2-an386 -icount shift=0 (arm-none-eabi-gcc -Os: 437 k instructions for 1024 points,
 * real/charged per step of each pass, ~5 % margin); a step stops before the visit that would pass
 * its budget (at least one visit per step).
 */
#define FIT_W_IDX 27u     /* one index range check (magcal_ellipse_fit_idx) */
#define FIT_W_SCAN 147u    /* pass 1: one point */
#define FIT_W_MOM 384u    /* pass 2: 13 Kahan sums of one point */
#define FIT_W_SOLVE 3000u /* collinearity test, normal equations, LDL^T, conic geometry */
#define FIT_W_RMS 144u     /* pass 3: radial residual of one point */
#define FIT_W_STORE 1200u  /* conic geometry again, result written */
#define FIT_W_FIVE 3200u  /* the 5-point exact path as a whole (5 points: O(1)) */

/* 1 when idx[k0..k1-1] < n_pts (the index check of magcal_ellipse_fit_idx). */
static int idx_in_range(const uint16_t *idx, size_t k0, size_t k1, size_t n_pts)
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
 * RANSAC draws call it without a slice on their stack): index check, then fit_five(). */
static MAGCAL_NOINLINE magcal_status_t fit_idx_five(const magcal_vec2_t *pts, size_t n_pts,
                                                    const uint16_t *idx, magcal_ellipse_t *out)
{
    fit_src_t src;
    if (idx_in_range(idx, 0u, MAGCAL_ELLIPSE_MIN_POINTS, n_pts) == 0) {
        return MAGCAL_ERR_ARG;
    }
    src.pts = pts;
    src.n = MAGCAL_ELLIPSE_MIN_POINTS;
    src.mask = NULL;
    src.idx = idx;
    return fit_five(&src, out);
}

/* The slice's tmp_[25] by phase (each pass's data is dead before the next one's is written). */
#define SL_BB(s) (&(s)->tmp_[0])   /* scan: xmin, xmax, ymin, ymax, max|x|, max|y| */
#define SL_COMP(s) (&(s)->tmp_[0]) /* moments: Kahan compensation [13] */
#define SL_A(s) (&(s)->tmp_[0])    /* solve: the 5x5 normal matrix */
#define SL_GEO(s) (&(s)->tmp_[0])  /* residuals: centre, qform, semi-minor axis [6] */
#define SL_ACC(s) (&(s)->tmp_[6])  /* residuals: sum of squares, compensation */

#define FIT_PH_IDX 1u
#define FIT_PH_FIVE 2u
#define FIT_PH_SCAN 3u
#define FIT_PH_MOM 4u
#define FIT_PH_SOLVE 5u
#define FIT_PH_RMS 6u
#define FIT_PH_STORE 7u
#define FIT_PH_DONE 8u

static void slice_start(magcal_ellipse_fit_slice_t *s)
{
    size_t j;
    s->k_ = 0u;
    s->cnt_ = 0u;
    for (j = 0u; j < 6u; ++j) {
        SL_BB(s)[j] = 0.0f; /* bounding box, then the largest magnitudes */
    }
    s->used_ = 0u;
    s->status_ = (int8_t)MAGCAL_IN_PROGRESS;
}

magcal_status_t magcal_ellipse_fit_begin(magcal_ellipse_fit_slice_t *s, const magcal_vec2_t *pts,
                                         size_t n, const uint8_t *mask, magcal_ellipse_t *out)
{
    if (s == NULL || pts == NULL || out == NULL) {
        return MAGCAL_ERR_NULL;
    }
    s->pts_ = pts;
    s->n_ = n;
    s->mask_ = mask;
    s->idx_ = NULL;
    s->n_pts_ = n;
    s->out_ = out;
    slice_start(s);
    s->phase_ = FIT_PH_SCAN;
    return MAGCAL_OK;
}

magcal_status_t magcal_ellipse_fit_idx_begin(magcal_ellipse_fit_slice_t *s, const magcal_vec2_t *pts,
                                             size_t n_pts, const uint16_t *idx, size_t m,
                                             magcal_ellipse_t *out)
{
    if (s == NULL || pts == NULL || idx == NULL || out == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (m > MAGCAL_ELLIPSE_MAX_POINTS) {
        return MAGCAL_ERR_ARG;
    }
    if (m < MAGCAL_ELLIPSE_MIN_POINTS) {
        return MAGCAL_ERR_TOO_FEW_POINTS;
    }
    s->pts_ = pts;
    s->n_ = m;
    s->mask_ = NULL;
    s->idx_ = idx;
    s->n_pts_ = n_pts;
    s->out_ = out;
    slice_start(s);
    s->phase_ = FIT_PH_IDX;
    return MAGCAL_OK;
}

/* Visits of weight w that the rest of the budget pays for (at most left); at least one on a call's
 * first visit (used == 0), 0 = stop here. */
static size_t slice_visits(uint32_t budget, uint32_t used, uint32_t w, size_t left)
{
    uint32_t v = (used < budget) ? (budget - used) / w : 0u;
    if (v == 0u && used == 0u) {
        v = 1u;
    }
    return ((size_t)v < left) ? (size_t)v : left;
}

/* End of pass 1: count rule, centred normalisation; moments pass next. */
static magcal_status_t slice_scan_done(magcal_ellipse_fit_slice_t *s)
{
    fit_norm_t nm;
    magcal_status_t st = scan_count_ok(s->cnt_);
    if (st == MAGCAL_OK) {
        st = norm_centred(SL_BB(s), &nm, &s->norm_[4]);
    }
    if (st == MAGCAL_OK) {
        s->norm_[0] = nm.mx;
        s->norm_[1] = nm.my;
        s->norm_[2] = nm.isx;
        s->norm_[3] = nm.isy;
        moments_zero(s->mom_, SL_COMP(s));
        s->k_ = 0u;
        s->phase_ = FIT_PH_MOM;
    }
    return st;
}

/* Collinearity test, normal equations, geometry (for the residuals of pass 3). */
static magcal_status_t slice_solve(magcal_ellipse_fit_slice_t *s)
{
    magcal_status_t st;
    if (moments_collinear(s->mom_, (float)s->cnt_) != 0) {
        return MAGCAL_ERR_DEGENERATE;
    }
    st = moments_solve(s->mom_, (float)s->cnt_, SL_A(s), &s->minp_);
    if (st == MAGCAL_OK) {
        st = conic_geometry(s->mom_, s->norm_[0], s->norm_[1], s->norm_[4], NULL, SL_GEO(s));
    }
    SL_ACC(s)[0] = 0.0f;
    SL_ACC(s)[1] = 0.0f;
    s->k_ = 0u;
    s->phase_ = FIT_PH_RMS;
    return st;
}

/* The result: the geometry again (cheaper than keeping it in the slice), the RMS, *out. */
static magcal_status_t slice_store(magcal_ellipse_fit_slice_t *s)
{
    return conic_store(s->mom_, s->norm_[0], s->norm_[1], s->norm_[4],
                       sqrtf(SL_ACC(s)[0] / (float)s->cnt_), s->minp_, s->cnt_, s->out_);
}

/* One pass chunk or one fixed visit of the current phase; *used is charged. Returns
 * MAGCAL_IN_PROGRESS to go on, 2 when the budget is spent, or the final status. */
#define SLICE_SPENT ((magcal_status_t)2)
static MAGCAL_NOINLINE magcal_status_t slice_phase(magcal_ellipse_fit_slice_t *s,
                                                   const fit_src_t *src, uint32_t budget,
                                                   uint32_t *used)
{
    static const uint16_t w_of[FIT_PH_DONE] = {0u, FIT_W_IDX, FIT_W_FIVE, FIT_W_SCAN,
                                                FIT_W_MOM, FIT_W_SOLVE, FIT_W_RMS, FIT_W_STORE};
    const uint32_t w = w_of[s->phase_];
    /* a pass phase visits the points left, a fixed phase is one visit */
    const size_t left = (s->phase_ == FIT_PH_IDX || s->phase_ == FIT_PH_SCAN ||
                         s->phase_ == FIT_PH_MOM || s->phase_ == FIT_PH_RMS)
                            ? s->n_ - s->k_
                            : 1u;
    const size_t v = slice_visits(budget, *used, w, left);
    const size_t k1 = s->k_ + v;
    magcal_status_t st = MAGCAL_IN_PROGRESS;
    fit_norm_t nm;

    if (v == 0u && left > 0u) {
        return SLICE_SPENT;
    }
    *used += (uint32_t)v * w;
    switch (s->phase_) {
    case FIT_PH_IDX:
        if (idx_in_range(s->idx_, s->k_, k1, s->n_pts_) == 0) {
            return MAGCAL_ERR_ARG;
        }
        s->k_ = k1;
        if (k1 == s->n_) {
            s->k_ = 0u;
            s->phase_ = (s->n_ == MAGCAL_ELLIPSE_MIN_POINTS) ? FIT_PH_FIVE : FIT_PH_SCAN;
        }
        break;
    case FIT_PH_SCAN:
        st = src_scan_range(src, s->k_, k1, &s->cnt_, SL_BB(s), &SL_BB(s)[4]);
        s->k_ = k1;
        if (st == MAGCAL_OK) {
            st = (k1 == s->n_) ? slice_scan_done(s) : MAGCAL_OK;
        }
        break;
    case FIT_PH_MOM:
        nm.mx = s->norm_[0];
        nm.my = s->norm_[1];
        nm.isx = s->norm_[2];
        nm.isy = s->norm_[3];
        src_moments_range(src, &nm, 0, s->k_, k1, s->mom_, SL_COMP(s));
        s->k_ = k1;
        if (k1 == s->n_) {
            s->phase_ = FIT_PH_SOLVE;
        }
        break;
    case FIT_PH_SOLVE:
        st = slice_solve(s);
        break;
    case FIT_PH_RMS:
        src_rms_range(src, SL_GEO(s), s->k_, k1, SL_ACC(s));
        s->k_ = k1;
        if (k1 == s->n_) {
            s->phase_ = FIT_PH_STORE;
        }
        break;
    default: /* FIT_PH_STORE */
        return slice_store(s);
    }
    return (st == MAGCAL_OK) ? MAGCAL_IN_PROGRESS : st;
}

/* The passes and fixed visits of a step (every phase but the 5-point path, which the caller
 * runs beside this frame); then the slice's bookkeeping. Also the one-shot fits' whole run. */
static MAGCAL_NOINLINE magcal_status_t slice_steps(magcal_ellipse_fit_slice_t *s, uint32_t budget,
                                                   uint32_t *used)
{
    fit_src_t src;
    magcal_status_t st = MAGCAL_IN_PROGRESS;
    src.pts = s->pts_;
    src.n = s->n_;
    src.mask = s->mask_;
    src.idx = s->idx_;
    while (st == MAGCAL_IN_PROGRESS && s->phase_ != FIT_PH_FIVE) {
        st = slice_phase(s, &src, budget, used);
    }
    return st;
}

/* End of a step: what it charged; the final status once done. */
static magcal_status_t slice_end(magcal_ellipse_fit_slice_t *s, magcal_status_t st, uint32_t used)
{
    s->used_ = used;
    if (st == SLICE_SPENT || st == MAGCAL_IN_PROGRESS) {
        return MAGCAL_IN_PROGRESS;
    }
    s->phase_ = FIT_PH_DONE;
    s->status_ = (int8_t)st;
    return st;
}

magcal_status_t magcal_ellipse_fit_step(magcal_ellipse_fit_slice_t *s, uint32_t budget)
{
    uint32_t used = 0u;
    magcal_status_t st;

    if (s == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (s->phase_ == FIT_PH_DONE) {
        s->used_ = 0u;
        return (magcal_status_t)s->status_;
    }
    if (s->phase_ < FIT_PH_IDX || s->phase_ > FIT_PH_STORE) {
        return MAGCAL_ERR_ARG;
    }
    st = slice_steps(s, budget, &used);
    if (st == MAGCAL_IN_PROGRESS && s->phase_ == FIT_PH_FIVE) {
        if (slice_visits(budget, used, FIT_W_FIVE, 1u) == 0u) {
            st = SLICE_SPENT;
        } else { /* beside slice_steps' frame: the deepest path of the minimal sets */
            fit_src_t src;
            src.pts = s->pts_;
            src.n = s->n_;
            src.mask = NULL;
            src.idx = s->idx_;
            used += FIT_W_FIVE;
            st = fit_five(&src, s->out_);
        }
    }
    return slice_end(s, st, used);
}

/*
 * The one-shot least-squares fit: the slice's passes (src_scan_range, src_moments_range,
 * moments_solve, conic_geometry + src_rms_range + conic_store) over every point in one go. Not
 * begin + step(UINT32_MAX): the slice state (216 B on Cortex-M4F) on this frame put the
 * calibrator's run() at 560 B of stack, over its 512-B budget. The sliced fit gives the same
 * result bit for bit (tests/test_ellipse.c, every budget).
 */
static MAGCAL_NOINLINE magcal_status_t fit_normal(const fit_src_t *src, magcal_ellipse_t *out)
{
    float mom[S_COUNT];
    float s = 1.0f;
    float minp = 0.0f;
    size_t cnt = 0u;
    fit_norm_t nm;
    magcal_status_t st;

    st = prepare_centred(src, &cnt, &nm, &s);
    if (st != MAGCAL_OK) {
        return st;
    }
    src_moments(src, &nm, 0, mom);
    if (moments_collinear(mom, (float)cnt) != 0) {
        return MAGCAL_ERR_DEGENERATE;
    }
    st = moments_solve_own(mom, (float)cnt, &minp);
    if (st != MAGCAL_OK) {
        return st;
    }
    return conic_finish(mom, nm.mx, nm.my, s, minp, cnt, src, out);
}

magcal_status_t magcal_ellipse_fit(const magcal_vec2_t *pts, size_t n, const uint8_t *mask,
                                   magcal_ellipse_t *out)
{
    fit_src_t src;

    if (pts == NULL || out == NULL) {
        return MAGCAL_ERR_NULL;
    }
    src_masked(&src, pts, n, mask);
    return fit_normal(&src, out);
}

magcal_status_t magcal_ellipse_fit_idx(const magcal_vec2_t *pts, size_t n_pts, const uint16_t *idx,
                                       size_t m, magcal_ellipse_t *out)
{
    fit_src_t src;

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
    if (idx_in_range(idx, 0u, m, n_pts) == 0) {
        return MAGCAL_ERR_ARG;
    }
    src.pts = pts;
    src.n = m;
    src.mask = NULL;
    src.idx = idx;
    return fit_normal(&src, out);
}

/* Pass 1 and the seed's max-abs normalisation (no centring), in a frame of their own. */
static magcal_status_t prepare_seed(const fit_src_t *src, size_t *count, fit_norm_t *nm)
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
    fit_src_t src;
    float mom[S_COUNT];
    float cu[5];
    float sx;
    float sy;
    float rx;
    float minp = 0.0f;
    size_t cnt = 0u;
    fit_norm_t nm;
    magcal_status_t st;

    if (pts == NULL || out == NULL) {
        return MAGCAL_ERR_NULL;
    }
    src_masked(&src, pts, n, mask);
    st = prepare_seed(&src, &cnt, &nm);
    if (st != MAGCAL_OK) {
        return st;
    }
    src_moments(&src, &nm, 1, mom);
    if (moments_collinear(mom, (float)cnt) != 0) {
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
    return conic_finish(cu, 0.0f, 0.0f, 1.0f, minp, cnt, &src, out);
}

/*
 * Semi-minor axis direction e1 = (cos theta, sin theta) of the quadratic form q = (q11, q12, q22)
 * without trigonometry (sinf/cosf of the angle pulled ~3 KB of argument reduction into every
 * image): e1 is the eigenvector of the larger eigenvalue, with
 * cos 2theta = (q11 - q22)/h, sin 2theta = 2 q12/h, h = |(q11 - q22, 2 q12)|, the same direction
 * as theta = atan2(2 q12, q11 - q22)/2 (algorithms.md 2.3; a circle gives theta = 0). Returns the
 * products cc = cos^2, ss = sin^2, cs = cos sin; the larger of cc, ss comes from (1 +- cos 2theta)/2
 * and the smaller from cs^2 over it, so neither loses its relative precision. -1 when q is not the
 * finite positive form of an ellipse.
 */
static int ell_axis_dir(const float q[3], float *cc, float *ss, float *cs)
{
    float d;
    float b;
    float m;
    float k2;
    float s2;
    if (!magcal_isfinite_f(q[0]) || !magcal_isfinite_f(q[1]) || !magcal_isfinite_f(q[2]) ||
        !(q[0] > 0.0f)) {
        return -1;
    }
    d = 1.0f - q[2] / q[0];   /* (1 - B) of the normalised conic */
    b = 2.0f * (q[1] / q[0]); /* A */
    m = fmaxf(fabsf(d), fabsf(b));
    if (!magcal_isfinite_f(m)) {
        return -1;
    }
    if (!(m > 0.0f)) {
        k2 = 1.0f; /* circle: theta = 0 */
        s2 = 0.0f;
    } else {
        float h;
        d /= m;
        b /= m;
        h = sqrtf(d * d + b * b);
        k2 = d / h;
        s2 = b / h;
    }
    *cs = 0.5f * s2;
    if (k2 >= 0.0f) {
        *cc = 0.5f * (1.0f + k2);
        *ss = (*cs * *cs) / *cc;
    } else {
        *ss = 0.5f * (1.0f - k2);
        *cc = (*cs * *cs) / *ss;
    }
    return 0;
}

/* Validate e for the corrections; returns the axes and the axis direction of qform. */
static magcal_status_t ell_corr_input(const magcal_ellipse_t *e, float *r1, float *r2, float *cc,
                                      float *ss, float *cs)
{
    *r1 = e->semi_minor;
    *r2 = e->semi_major;
    if (!magcal_isfinite_f(*r2) || !magcal_isfinite_f(e->angle_rad) ||
        !magcal_isfinite_f(e->center.x) || !magcal_isfinite_f(e->center.y) || !(*r1 > 0.0f) ||
        !(*r1 <= *r2) || ell_axis_dir(e->qform, cc, ss, cs) != 0) {
        return MAGCAL_ERR_ARG;
    }
    return MAGCAL_OK;
}

#if MAGCAL_CFG_ENABLE_PAPER
/* Outputs of ell_kphi_coef(): ky, cos/sin of phi_p, h_x and sqrt(q11'). */
typedef struct {
    float ky;
    float cp;
    float sp;
    float hx;
    float sq11;
} ell_kphi_coef_t;

/*
 * The documents' coefficients from the geometry. Q = R diag(1/r1^2, 1/r2^2) R^T is taken scaled by
 * r2^2 (q' = r2^2 Q, entries in [1, (r2/r1)^2], no overflow for tiny axes). With T = K Phi_p,
 * T T^T = K Phi_p^2 K = [[1, ky sin 2p], [ky sin 2p, ky^2]] (Phi_p^2 = [[1, sin 2p], [sin 2p, 1]])
 * proportional to Q^-1, so ky = sqrt(q11/q22), sin 2p = -q12/sqrt(q11 q22) and
 * cos 2p = sqrt(det Q/(q11 q22)) = 1/(r1 r2 sqrt(q11 q22)): 2p = atan2(-q12', r2/r1) without
 * cancellation. *sq11 = sqrt(q11') (M = rho sqrt(q11) [[cos p, -sin p/ky], [-sin p, cos p/ky]]).
 * cos p, sin p come from the half-angle forms of cos 2p = (r2/r1)/h, sin 2p = -q12'/h,
 * h = |(-q12', r2/r1)|, not from sinf/cosf of an angle (their argument reduction is ~3.9 KB of
 * libm in every 2-D image): cos 2p > 0 (|p| < pi/4), so cos p = sqrt((1 + cos 2p)/2) is in
 * [0.707, 1] without cancellation and sin p = sin 2p/(2 cos p) keeps its relative precision.
 */
static void ell_kphi_coef(float r1, float r2, float cc, float ss, float cs, ell_kphi_coef_t *k)
{
    float u = r2 / r1;
    float a1 = u * u;
    float q11 = cc * a1 + ss;
    float q12 = cs * (a1 - 1.0f);
    float q22 = ss * a1 + cc;
    float t = -q12 / u; /* tan 2p, |t| = |cs| (u - 1/u) <= u/2: no overflow where a1 is finite */
    float c2 = 1.0f / sqrtf(1.0f + t * t);
    k->ky = sqrtf(q11 / q22);
    k->cp = sqrtf(0.5f * (1.0f + c2));
    k->sp = (0.5f * t * c2) / k->cp;
    k->hx = sqrtf(q22) * r1;
    k->sq11 = sqrtf(q11);
}

magcal_status_t magcal_ellipse_kphi(const magcal_ellipse_t *e, magcal_ellipse_kphi_t *out)
{
    float r1;
    float r2;
    float cc;
    float ss;
    float cs;
    ell_kphi_coef_t c;
    magcal_ellipse_kphi_t k;
    magcal_status_t st;

    if (e == NULL || out == NULL) {
        return MAGCAL_ERR_NULL;
    }
    st = ell_corr_input(e, &r1, &r2, &cc, &ss, &cs);
    if (st != MAGCAL_OK) {
        return st;
    }
    ell_kphi_coef(r1, r2, cc, ss, cs, &c);
    k.ky = c.ky;
    k.phi_p_rad = atan2f(c.sp, c.cp); /* cp > 0: (-pi/4, pi/4) */
    k.h_x = c.hx;
    k.beta_rad = atan2f((c.ky - 1.0f) * c.sp, (1.0f + c.ky) * c.cp);
    k.b = e->center;
    if (!magcal_isfinite_f(k.ky) || !magcal_isfinite_f(k.h_x) || !(k.ky > 0.0f)) {
        return MAGCAL_ERR_ARG;
    }
    *out = k;
    return MAGCAL_OK;
}
#endif /* MAGCAL_CFG_ENABLE_PAPER */

magcal_status_t magcal_ellipse_to_cal(const magcal_ellipse_t *e, magcal_corr_form_t form, float rho,
                                      magcal_cal2d_t *out)
{
    float r1;
    float r2;
    float cc; /* cos^2 theta */
    float ss; /* sin^2 theta */
    float cs; /* cos theta sin theta */
    float out_r;
    magcal_cal2d_t cal;
    magcal_status_t st;

    if (e == NULL || out == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (!magcal_isfinite_f(rho)) {
        return MAGCAL_ERR_NONFINITE;
    }
    st = ell_corr_input(e, &r1, &r2, &cc, &ss, &cs);
    if (st != MAGCAL_OK) {
        return st;
    }
    switch (form) {
    case MAGCAL_CORR_SYMMETRIC:
    case MAGCAL_CORR_KX1: {
        /* M = rho R(theta) diag(1/r1, 1/r2) R(theta)^T; KX1 with rho <= 0 is rho = r1. */
        float i1;
        float i2;
        if (rho > 0.0f) {
            out_r = rho;
        } else if (form == MAGCAL_CORR_KX1) {
            out_r = r1;
        } else {
            out_r = sqrtf(r1) * sqrtf(r2);
        }
        i1 = out_r / r1;
        i2 = out_r / r2;
        cal.m[0][0] = cc * i1 + ss * i2;
        cal.m[0][1] = cs * (i1 - i2);
        cal.m[1][0] = cal.m[0][1];
        cal.m[1][1] = ss * i1 + cc * i2;
        break;
    }
    case MAGCAL_CORR_TRIANGULAR: {
        /* Upper-triangular T with T^T T = rho^2 Q, Q = R diag(1/r1^2, 1/r2^2) R^T (Cholesky of Q
         * from its geometry; det Q = 1/(r1 r2)^2 avoids the cancelling q22 - q12^2/q11). */
        float a1 = 1.0f / (r1 * r1);
        float a2 = 1.0f / (r2 * r2);
        float q11 = cc * a1 + ss * a2;
        float q12 = cs * (a1 - a2);
        float sq = sqrtf(q11);
        out_r = (rho > 0.0f) ? rho : sqrtf(r1) * sqrtf(r2);
        cal.m[0][0] = out_r * sq;
        cal.m[0][1] = out_r * q12 / sq;
        cal.m[1][0] = 0.0f;
        cal.m[1][1] = out_r / (r1 * r2 * sq);
        break;
    }
#if MAGCAL_CFG_ENABLE_PAPER
    case MAGCAL_CORR_KPHI: {
        /* M = rho/h_x (K Phi_p)^-1 = rho sqrt(q11) [[cos p, -sin p/ky], [-sin p, cos p/ky]]
         * (Phi_p^-1 = [[cos p, -sin p], [-sin p, cos p]]/cos 2p; see ell_kphi_coef). */
        ell_kphi_coef_t c;
        float g;
        ell_kphi_coef(r1, r2, cc, ss, cs, &c);
        out_r = (rho > 0.0f) ? rho : c.hx;
        g = out_r * c.sq11 / r2;
        cal.m[0][0] = g * c.cp;
        cal.m[0][1] = -g * c.sp / c.ky;
        cal.m[1][0] = -g * c.sp;
        cal.m[1][1] = g * c.cp / c.ky;
        break;
    }
#endif /* MAGCAL_CFG_ENABLE_PAPER: without it KPHI is an unknown form */
    default: return MAGCAL_ERR_ARG;
    }
    cal.offset = e->center;
    cal.radius = out_r;
    cal.magic = MAGCAL_CAL2D_MAGIC;
    if (!magcal_isfinite_f(cal.m[0][0]) || !magcal_isfinite_f(cal.m[0][1]) ||
        !magcal_isfinite_f(cal.m[1][0]) || !magcal_isfinite_f(cal.m[1][1])) {
        return MAGCAL_ERR_ARG;
    }
    *out = cal;
    return MAGCAL_OK;
}

magcal_status_t magcal_ellipse_from_conic(const float coef[5], magcal_vec2_t norm_center,
                                          float norm_scale, magcal_ellipse_t *out)
{
    size_t i;

    if (coef == NULL || out == NULL) {
        return MAGCAL_ERR_NULL;
    }
    for (i = 0u; i < 5u; ++i) {
        if (!magcal_isfinite_f(coef[i])) {
            return MAGCAL_ERR_NONFINITE;
        }
    }
    if (!magcal_isfinite_f(norm_center.x) || !magcal_isfinite_f(norm_center.y) ||
        !magcal_isfinite_f(norm_scale)) {
        return MAGCAL_ERR_NONFINITE;
    }
    if (!(norm_scale > 0.0f)) {
        return MAGCAL_ERR_ARG;
    }
    return conic_finish(coef, norm_center.x, norm_center.y, norm_scale, 1.0f, 0u, NULL, out);
}
