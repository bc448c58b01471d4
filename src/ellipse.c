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

/* Power sums S_pq = sum x~^p y~^q kept by the accumulator. */
enum { S10, S01, S20, S11, S02, S30, S21, S12, S03, S31, S22, S13, S04, S_COUNT };

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

/* Pass 1: number of used points, finiteness, bounding box (bb = xmin, xmax, ymin, ymax) and the
 * largest magnitude per axis (amax = max|x|, max|y|, for the seed's scaling). */
static magcal_status_t src_scan(const fit_src_t *src, size_t *count, float bb[4], float amax[2])
{
    size_t k;
    size_t cnt = 0u;
    magcal_vec2_t p;

    bb[0] = 0.0f;
    bb[1] = 0.0f;
    bb[2] = 0.0f;
    bb[3] = 0.0f;
    amax[0] = 0.0f;
    amax[1] = 0.0f;
    for (k = 0u; k < src->n; ++k) {
        if (!src_point(src, k, &p)) {
            continue;
        }
        if (!magcal_isfinite_f(p.x) || !magcal_isfinite_f(p.y)) {
            return MAGCAL_ERR_NONFINITE;
        }
        if (cnt == 0u) {
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
        ++cnt;
    }
    if (cnt > MAGCAL_ELLIPSE_MAX_POINTS) {
        return MAGCAL_ERR_ARG;
    }
    if (cnt < MAGCAL_ELLIPSE_MIN_POINTS) {
        return MAGCAL_ERR_TOO_FEW_POINTS;
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
        return MAGCAL_ERR_NONFINITE; /* range overflows float32 */
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

static void kahan_add(float *sum, float *comp, float v)
{
    float y = v - *comp;
    float t = *sum + y;
    *comp = (t - *sum) - y;
    *sum = t;
}

/* Pass 2: power sums of the normalised points, Kahan-compensated unless plain != 0 (the seed's
 * plain float32 accumulation, kept only for magcal_ellipse_fit_seed()). */
static void src_moments(const fit_src_t *src, const fit_norm_t *nm, int plain, float mom[S_COUNT])
{
    float comp[S_COUNT];
    float v[S_COUNT];
    size_t k;
    size_t j;
    magcal_vec2_t p;

    for (j = 0u; j < (size_t)S_COUNT; ++j) {
        mom[j] = 0.0f;
        comp[j] = 0.0f;
    }
    for (k = 0u; k < src->n; ++k) {
        float x;
        float y;
        if (!src_point(src, k, &p)) {
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
        for (j = 0u; j < (size_t)S_COUNT; ++j) {
            if (plain) {
                mom[j] += v[j];
            } else {
                kahan_add(&mom[j], &comp[j], v[j]);
            }
        }
    }
}

/* Collinear (or nearly) points: smaller covariance eigenvalue below a fraction of the larger.
 * det/tr^2 = l1 l2 / (l1 + l2)^2 is the eigenvalue ratio when that ratio is small. */
static int moments_collinear(const float mom[S_COUNT], float cnt)
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

/* Normal equations of the rows w = [xy, y^2, x, y, 1], Y = -x^2, solved by equilibrated LDL^T. */
static magcal_status_t moments_solve(const float mom[S_COUNT], float cnt, float coef[5], float *min_pivot)
{
    float a[25];
    float b[5];
    magcal_status_t st;
    size_t i;

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
    b[0] = -mom[S31];
    b[1] = -mom[S22];
    b[2] = -mom[S30];
    b[3] = -mom[S21];
    b[4] = -mom[S20];
    st = magcal_ldlt_solve(a, b, 5u, MAGCAL_ELLIPSE_PIVOT_TOL, min_pivot);
    if (st != MAGCAL_OK) {
        return st;
    }
    for (i = 0u; i < 5u; ++i) {
        coef[i] = b[i];
    }
    return MAGCAL_OK;
}

/*
 * Geometry of x^2 + A xy + B y^2 + C x + D y + E = 0 given in coordinates x~ = (x - mx)/s
 * (isotropic s, so angles are unchanged and lengths scale by s). Fills centre, axes, angle and
 * the input-unit quadratic form of g (algorithms.md 2.3).
 */
static magcal_status_t conic_geometry(const float coef[5], float mx, float my, float s, magcal_ellipse_t *g)
{
    float ca = coef[0];
    float cb = coef[1];
    float cc = coef[2];
    float cd = coef[3];
    float ce = coef[4];
    float delta = 4.0f * cb - ca * ca;
    float fro = 1.0f + 0.5f * ca * ca + cb * cb;
    float x0;
    float y0;
    float kk;
    float hyp;
    float l1;
    float l2;
    float q11;

    if (fabsf(delta) <= MAGCAL_ELLIPSE_PARABOLA_TOL * fro) {
        return MAGCAL_ERR_PARABOLA;
    }
    if (delta < 0.0f) {
        return MAGCAL_ERR_HYPERBOLA;
    }
    x0 = (ca * cd - 2.0f * cb * cc) / delta;
    y0 = (ca * cc - 2.0f * cd) / delta;
    kk = -(ce + 0.5f * (cc * x0 + cd * y0));
    if (!(kk > 0.0f)) {
        return MAGCAL_ERR_IMAGINARY;
    }
    hyp = sqrtf((1.0f - cb) * (1.0f - cb) + ca * ca);
    l1 = 0.5f * (1.0f + cb) + 0.5f * hyp;
    l2 = (0.25f * delta) / l1; /* det/l1: no cancellation for thin ellipses */
    g->angle_rad = 0.5f * atan2f(ca, 1.0f - cb);
    g->semi_minor = sqrtf(kk / l1) * s;
    g->semi_major = sqrtf(kk / l2) * s;
    g->center.x = mx + s * x0;
    g->center.y = my + s * y0;
    q11 = 1.0f / (kk * s * s);
    g->qform[0] = q11;
    g->qform[1] = 0.5f * ca * q11;
    g->qform[2] = cb * q11;
    if (!magcal_isfinite_f(g->center.x) || !magcal_isfinite_f(g->center.y) || !magcal_isfinite_f(g->semi_major) ||
        !magcal_isfinite_f(q11) || !(q11 > 0.0f) || !(g->semi_minor > 0.0f)) {
        return MAGCAL_ERR_ILL_CONDITIONED; /* under/overflow of a nearly singular conic */
    }
    return MAGCAL_OK;
}

float magcal_ellipse_residual(const magcal_ellipse_t *e, magcal_vec2_t p)
{
    float ux;
    float uy;
    float a;
    float n2;
    float nrm;

    if (e == NULL || !magcal_isfinite_f(p.x) || !magcal_isfinite_f(p.y)) {
        return NAN;
    }
    ux = p.x - e->center.x;
    uy = p.y - e->center.y;
    a = (e->qform[0] * ux + 2.0f * e->qform[1] * uy) * ux + e->qform[2] * uy * uy;
    n2 = ux * ux + uy * uy;
    if (!(a > 0.0f) || !(n2 > 0.0f)) {
        return -e->semi_minor; /* at the centre */
    }
    nrm = sqrtf(n2);
    return nrm - nrm / sqrtf(a);
}

/* Pass 3: RMS of the radial residual over the used points. */
static float src_residual_rms(const fit_src_t *src, const magcal_ellipse_t *e, size_t cnt)
{
    float sum = 0.0f;
    float comp = 0.0f;
    size_t k;
    magcal_vec2_t p;

    for (k = 0u; k < src->n; ++k) {
        float r;
        if (!src_point(src, k, &p)) {
            continue;
        }
        r = magcal_ellipse_residual(e, p);
        kahan_add(&sum, &comp, r * r);
    }
    return sqrtf(sum / (float)cnt);
}

/* Centred fit through the normal equations (any count >= 5). */
static magcal_status_t fit_normal(const fit_src_t *src, magcal_ellipse_t *out)
{
    float bb[4];
    float amax[2];
    float mom[S_COUNT];
    float s = 1.0f;
    size_t cnt = 0u;
    fit_norm_t nm;
    magcal_ellipse_t e;
    magcal_status_t st;

    st = src_scan(src, &cnt, bb, amax);
    if (st != MAGCAL_OK) {
        return st;
    }
    st = norm_centred(bb, &nm, &s);
    if (st != MAGCAL_OK) {
        return st;
    }
    src_moments(src, &nm, 0, mom);
    if (moments_collinear(mom, (float)cnt)) {
        return MAGCAL_ERR_DEGENERATE;
    }
    st = moments_solve(mom, (float)cnt, e.coef, &e.min_pivot);
    if (st != MAGCAL_OK) {
        return st;
    }
    st = conic_geometry(e.coef, nm.mx, nm.my, s, &e);
    if (st != MAGCAL_OK) {
        return st;
    }
    e.norm_center.x = nm.mx;
    e.norm_center.y = nm.my;
    e.norm_scale = s;
    e.n_used = (uint16_t)cnt;
    e.residual_rms = src_residual_rms(src, &e, cnt);
    *out = e;
    return MAGCAL_OK;
}

magcal_status_t magcal_ellipse_fit(const magcal_vec2_t *pts, size_t n, const uint8_t *mask, magcal_ellipse_t *out)
{
    fit_src_t src;

    if (pts == NULL || out == NULL) {
        return MAGCAL_ERR_NULL;
    }
    src.pts = pts;
    src.n = n;
    src.mask = mask;
    src.idx = NULL;
    return fit_normal(&src, out);
}

/* Exact conic through 5 points: Gaussian elimination with partial pivoting on W X = Y. */
static magcal_status_t fit_five(const fit_src_t *src, magcal_ellipse_t *out)
{
    float w[5][6];
    float bb[4];
    float amax[2];
    float s = 1.0f;
    float minp = 1.0f;
    float ptol = sqrtf(MAGCAL_ELLIPSE_PIVOT_TOL);
    float mom[S_COUNT];
    size_t cnt = 0u;
    size_t i;
    size_t j;
    size_t k;
    fit_norm_t nm;
    magcal_ellipse_t e;
    magcal_status_t st;

    for (i = 0u; i < 5u; ++i) {
        for (j = i + 1u; j < 5u; ++j) {
            if (src->idx[i] == src->idx[j]) {
                return MAGCAL_ERR_DEGENERATE;
            }
        }
    }
    st = src_scan(src, &cnt, bb, amax);
    if (st != MAGCAL_OK) {
        return st;
    }
    st = norm_centred(bb, &nm, &s);
    if (st != MAGCAL_OK) {
        return st;
    }
    for (i = 0u; i < (size_t)S_COUNT; ++i) {
        mom[i] = 0.0f;
    }
    /* Rows [xy, y^2, x, y, 1 | -x^2]: |entries| <= 1 and the constant column makes each row's
     * max-abs exactly 1, so the rows are already equilibrated. */
    for (i = 0u; i < 5u; ++i) {
        magcal_vec2_t p = src->pts[src->idx[i]];
        float x = (p.x - nm.mx) * nm.isx;
        float y = (p.y - nm.my) * nm.isy;
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
    if (moments_collinear(mom, 5.0f)) {
        return MAGCAL_ERR_DEGENERATE;
    }
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
        minp = (best < minp) ? best : minp;
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
    for (k = 5u; k-- > 0u;) {
        float acc = w[k][5];
        for (j = k + 1u; j < 5u; ++j) {
            acc -= w[k][j] * e.coef[j];
        }
        e.coef[k] = acc / w[k][k];
    }
    e.min_pivot = minp;
    st = conic_geometry(e.coef, nm.mx, nm.my, s, &e);
    if (st != MAGCAL_OK) {
        return st;
    }
    e.norm_center.x = nm.mx;
    e.norm_center.y = nm.my;
    e.norm_scale = s;
    e.n_used = 5u;
    e.residual_rms = src_residual_rms(src, &e, 5u);
    *out = e;
    return MAGCAL_OK;
}

magcal_status_t magcal_ellipse_fit_idx(const magcal_vec2_t *pts, size_t n_pts, const uint16_t *idx, size_t m,
                                       magcal_ellipse_t *out)
{
    fit_src_t src;
    size_t k;

    if (pts == NULL || idx == NULL || out == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (m > MAGCAL_ELLIPSE_MAX_POINTS) {
        return MAGCAL_ERR_ARG;
    }
    if (m < MAGCAL_ELLIPSE_MIN_POINTS) {
        return MAGCAL_ERR_TOO_FEW_POINTS;
    }
    for (k = 0u; k < m; ++k) {
        if ((size_t)idx[k] >= n_pts) {
            return MAGCAL_ERR_ARG;
        }
    }
    src.pts = pts;
    src.n = m;
    src.mask = NULL;
    src.idx = idx;
    if (m == MAGCAL_ELLIPSE_MIN_POINTS) {
        return fit_five(&src, out);
    }
    return fit_normal(&src, out);
}

magcal_status_t magcal_ellipse_fit_seed(const magcal_vec2_t *pts, size_t n, const uint8_t *mask,
                                        magcal_ellipse_t *out)
{
    fit_src_t src;
    float bb[4];
    float amax[2];
    float mom[S_COUNT];
    float c[5];
    float sx;
    float sy;
    float rx;
    size_t cnt = 0u;
    fit_norm_t nm;
    magcal_ellipse_t e;
    magcal_status_t st;

    if (pts == NULL || out == NULL) {
        return MAGCAL_ERR_NULL;
    }
    src.pts = pts;
    src.n = n;
    src.mask = mask;
    src.idx = NULL;
    st = src_scan(&src, &cnt, bb, amax);
    if (st != MAGCAL_OK) {
        return st;
    }
    if (!(amax[0] > 0.0f) || !(amax[1] > 0.0f)) {
        return MAGCAL_ERR_DEGENERATE; /* a whole axis is zero: collinear */
    }
    sx = amax[0];
    sy = amax[1];
    nm.mx = 0.0f;
    nm.my = 0.0f;
    nm.isx = 1.0f / sx;
    nm.isy = 1.0f / sy;
    src_moments(&src, &nm, 1, mom);
    if (moments_collinear(mom, (float)cnt)) {
        return MAGCAL_ERR_DEGENERATE;
    }
    st = moments_solve(mom, (float)cnt, c, &e.min_pivot);
    if (st != MAGCAL_OK) {
        return st;
    }
    /* Back to input units (algorithms.md 2.2 with mx = my = 0). */
    rx = sx / sy;
    e.coef[0] = c[0] * rx;
    e.coef[1] = c[1] * rx * rx;
    e.coef[2] = c[2] * sx;
    e.coef[3] = c[3] * sx * rx;
    e.coef[4] = c[4] * sx * sx;
    st = conic_geometry(e.coef, 0.0f, 0.0f, 1.0f, &e);
    if (st != MAGCAL_OK) {
        return st;
    }
    e.norm_center.x = 0.0f;
    e.norm_center.y = 0.0f;
    e.norm_scale = 1.0f;
    e.n_used = (uint16_t)cnt;
    e.residual_rms = src_residual_rms(&src, &e, cnt);
    *out = e;
    return MAGCAL_OK;
}

magcal_status_t magcal_ellipse_to_cal(const magcal_ellipse_t *e, magcal_corr_form_t form, float rho,
                                      magcal_cal2d_t *out)
{
    float r1;
    float r2;
    float c;
    float sn;
    float out_r;
    magcal_cal2d_t cal;

    if (e == NULL || out == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (!magcal_isfinite_f(rho)) {
        return MAGCAL_ERR_NONFINITE;
    }
    r1 = e->semi_minor;
    r2 = e->semi_major;
    if (!magcal_isfinite_f(r2) || !magcal_isfinite_f(e->angle_rad) || !magcal_isfinite_f(e->center.x) ||
        !magcal_isfinite_f(e->center.y) || !(r1 > 0.0f) || !(r1 <= r2)) {
        return MAGCAL_ERR_ARG;
    }
    c = cosf(e->angle_rad);
    sn = sinf(e->angle_rad);
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
        cal.m[0][0] = c * c * i1 + sn * sn * i2;
        cal.m[0][1] = c * sn * (i1 - i2);
        cal.m[1][0] = cal.m[0][1];
        cal.m[1][1] = sn * sn * i1 + c * c * i2;
        break;
    }
    case MAGCAL_CORR_TRIANGULAR: {
        /* Upper-triangular T with T^T T = rho^2 Q, Q = R diag(1/r1^2, 1/r2^2) R^T (Cholesky of Q
         * from its geometry; det Q = 1/(r1 r2)^2 avoids the cancelling q22 - q12^2/q11). */
        float a1 = 1.0f / (r1 * r1);
        float a2 = 1.0f / (r2 * r2);
        float q11 = c * c * a1 + sn * sn * a2;
        float q12 = c * sn * (a1 - a2);
        float sq = sqrtf(q11);
        out_r = (rho > 0.0f) ? rho : sqrtf(r1) * sqrtf(r2);
        cal.m[0][0] = out_r * sq;
        cal.m[0][1] = out_r * q12 / sq;
        cal.m[1][0] = 0.0f;
        cal.m[1][1] = out_r / (r1 * r2 * sq);
        break;
    }
    default:
        return MAGCAL_ERR_ARG;
    }
    cal.offset = e->center;
    cal.radius = out_r;
    cal.magic = MAGCAL_CAL2D_MAGIC;
    if (!magcal_isfinite_f(cal.m[0][0]) || !magcal_isfinite_f(cal.m[0][1]) || !magcal_isfinite_f(cal.m[1][1])) {
        return MAGCAL_ERR_ARG;
    }
    *out = cal;
    return MAGCAL_OK;
}

magcal_status_t magcal_ellipse_from_conic(const float coef[5], magcal_vec2_t norm_center, float norm_scale,
                                          magcal_ellipse_t *out)
{
    magcal_ellipse_t e;
    magcal_status_t st;
    size_t i;

    if (coef == NULL || out == NULL) {
        return MAGCAL_ERR_NULL;
    }
    for (i = 0u; i < 5u; ++i) {
        if (!magcal_isfinite_f(coef[i])) {
            return MAGCAL_ERR_NONFINITE;
        }
        e.coef[i] = coef[i];
    }
    if (!magcal_isfinite_f(norm_center.x) || !magcal_isfinite_f(norm_center.y) || !magcal_isfinite_f(norm_scale)) {
        return MAGCAL_ERR_NONFINITE;
    }
    if (!(norm_scale > 0.0f)) {
        return MAGCAL_ERR_ARG;
    }
    st = conic_geometry(e.coef, norm_center.x, norm_center.y, norm_scale, &e);
    if (st != MAGCAL_OK) {
        return st;
    }
    e.norm_center = norm_center;
    e.norm_scale = norm_scale;
    e.residual_rms = 0.0f;
    e.min_pivot = 1.0f;
    e.n_used = 0u;
    *out = e;
    return MAGCAL_OK;
}
