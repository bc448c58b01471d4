/*
 * From a fitted ellipse to a calibration (algorithms.md 2.4): the axis direction, the correction
 * forms of magcal_ellipse_to_cal(), the source paper's k/phi form (MAGCAL_CFG_ENABLE_PAPER) and
 * magcal_ellipse_from_conic().
 */
#include "magcal/ellipse.h"

#include <math.h>

#include "ellipse_internal.h"
#include "magcal_internal.h"

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
    k.phi_p_rad = magcal_atan2f(c.sp, c.cp); /* cp > 0: (-pi/4, pi/4) */
    k.h_x = c.hx;
    k.beta_rad = magcal_atan2f((c.ky - 1.0f) * c.sp, (1.0f + c.ky) * c.cp);
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
    return magcal_efit_conic_finish(coef, norm_center.x, norm_center.y, norm_scale, 1.0f, 0u, NULL,
                                    out);
}
