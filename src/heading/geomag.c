/*
 * Geomagnetic main-field synthesis in float32 (algorithms.md section 8; docs/geomag.md).
 *
 * Float-safe formulation (no double anywhere):
 * - sines and cosines of angles given in degrees are taken after an exact reduction to
 *   [-45, 45] deg, so cos(90 deg) is exactly 0 at the pole, cos(lat) keeps full relative
 *   precision near the pole and longitudes 0/90/180/270 are exact;
 * - the geocentric latitude is never formed as an angle: sin and cos of it are z/r and p/r, and
 *   the rotation angle psi = phi' - phi enters through sin psi = -e^2 Rc sin(phi) cos(phi) / r
 *   and cos psi = (Rc (1 - e^2 sin^2 phi) + h) / r, both free of cancellation (the textbook
 *   sin(phi')cos(phi) - cos(phi')sin(phi) subtracts numbers of order 1 to get ~3e-3);
 * - Legendre functions by the Schmidt recurrences (all values of order 1), order m outer and
 *   degree n inner, so only the running diagonal and two previous degrees are kept (O(1)
 *   floats per order, ~30 floats of stack in all). For m >= 1, Q = P / cos(phi') is carried
 *   instead of P, which makes the east component finite at the poles.
 * Measured against the official values (tests/test_geomag.c): see docs/geomag.md.
 */
#include <math.h>

#include "geomag_internal.h"
#include "magcal_internal.h"

#if MAGCAL_CFG_ENABLE_GEOMAG /* whole file: config.h feature switch */

#define GEOMAG_A_REF_KM 6371.2f           /* geomagnetic reference radius */
#define GEOMAG_WGS84_A_KM 6378.137f       /* WGS 84 semi-major axis */
#define GEOMAG_WGS84_E2 6.69437999014e-3f /* e^2 = f (2 - f), 1/f = 298.257223563 */

/* Time dependence of the coefficients at one date: c(t) = a + dt * d, with the rate
 * d = (b - sub * a) * scale, where a and b are the coefficients of epoch e and of the next
 * epoch (interpolation: sub = 1, scale = 1/step) or a and the SV (after the last epoch:
 * sub = 0, scale = 1). Degrees above an epoch's trimmed degree are zero. */
typedef struct {
    const float *c0;
    const float *c1;
    unsigned n0;
    unsigned n1;
    float dt;
    float sub;
    float scale;
} geomag_time_t;

/* Geocentric point: mu = sin(lat'), nu = cos(lat') >= 0, cos/sin of the longitude, radius. */
typedef struct {
    float mu;
    float nu;
    float clon;
    float slon;
    float r_km;
} geomag_point_t;

/* sin and cos of an angle in degrees, |deg| <= 360 (caller checks), exact at multiples of 90
 * and accurate to relative precision near them. */
static void sincos_deg(float deg, float *s, float *c)
{
    float k = floorf(deg / 90.0f + 0.5f);               /* nearest quadrant, -4..4 */
    float r = (deg - 90.0f * k) * MAGCAL_RAD_PER_DEG_F; /* deg - 90k is exact, |.| <= 45 deg */
    float s0 = sinf(r);
    float c0 = cosf(r);
    int q = ((int)k % 4 + 4) % 4;
    switch (q) {
    case 0:
        *s = s0;
        *c = c0;
        break;
    case 1:
        *s = c0;
        *c = -s0;
        break;
    case 2:
        *s = -s0;
        *c = -c0;
        break;
    default:
        *s = -c0;
        *c = s0;
        break;
    }
}

static magcal_status_t check_model(const magcal_geomag_model_t *model)
{
    if (model->n_epochs == 0u || model->nmax == 0u || model->nmax > MAGCAL_GEOMAG_NMAX ||
        model->sv_nmax > model->nmax || model->coef == NULL || model->epoch_start == NULL ||
        model->epoch_nmax == NULL || (model->sv == NULL && model->sv_nmax > 0u) ||
        (model->n_epochs > 1u && !(model->epoch_step > 0.0f))) {
        return MAGCAL_ERR_ARG;
    }
    return MAGCAL_OK;
}

/* Coefficient set-up for a date already checked against the model's validity. */
static void time_setup(const magcal_geomag_model_t *model, float year, geomag_time_t *ts)
{
    unsigned last = (unsigned)model->n_epochs - 1u;
    unsigned e = 0u;
    float t0;
    if (last > 0u) {
        float fe = floorf((year - model->epoch_first) / model->epoch_step);
        e = (fe <= 0.0f) ? 0u : ((fe >= (float)last) ? last : (unsigned)fe);
        /* the division may round across an epoch boundary: fix with exact comparisons */
        if (e > 0u && year < model->epoch_first + (float)e * model->epoch_step) {
            --e;
        } else if (e < last) {
            const unsigned e1 = e + 1u;
            if (year >= model->epoch_first + (float)e1 * model->epoch_step) {
                ++e;
            }
        } else {
            /* e is the last epoch */
        }
    }
    t0 = model->epoch_first + (float)e * model->epoch_step;
    ts->c0 = model->coef + model->epoch_start[e];
    ts->n0 = model->epoch_nmax[e];
    ts->dt = year - t0;
    if (e < last) {
        ts->c1 = model->coef + model->epoch_start[e + 1u];
        ts->n1 = model->epoch_nmax[e + 1u];
        ts->sub = 1.0f;
        ts->scale = 1.0f / model->epoch_step;
    } else {
        ts->c1 = model->sv;
        ts->n1 = model->sv_nmax;
        ts->sub = 0.0f;
        ts->scale = 1.0f;
    }
}

/* Coefficient k of degree n at the date: value and rate (nT, nT/yr). */
static void coef_at(const geomag_time_t *ts, unsigned n, unsigned k, float *v, float *rate)
{
    float a = (n <= ts->n0) ? ts->c0[k] : 0.0f;
    float b = (n <= ts->n1) ? ts->c1[k] : 0.0f;
    float d = (b - ts->sub * a) * ts->scale;
    *v = a + ts->dt * d;
    *rate = d;
}

/* Spherical-harmonic synthesis (algorithms.md 8.4-8.5): b[0..2] = X', Y', Z' (nT) and
 * b[3..5] their rates (nT/yr), geocentric north/east/down. */
static void synthesise(const magcal_geomag_model_t *model, const geomag_time_t *ts,
                       const geomag_point_t *pt, float b[6])
{
    const unsigned nmax = model->nmax;
    float rn[MAGCAL_GEOMAG_NMAX + 1u]; /* (a/r)^(n+2) */
    float ar = GEOMAG_A_REF_KM / pt->r_km;
    float q = ar * ar;
    float cm = 1.0f; /* cos(m lon), sin(m lon) by angle addition */
    float sm = 0.0f;
    float umm = 1.0f; /* diagonal: P_0^0, then Q_m^m = P_m^m / nu */
    float dmm = 0.0f; /* diagonal derivative dP_m^m / dtheta */
    float lead[6];    /* the dipole (n = 1) terms, added last (see below) */
    float *acc;
    unsigned n;
    unsigned m;
    for (n = 0u; n < 6u; ++n) {
        b[n] = 0.0f;
        lead[n] = 0.0f;
    }
    rn[0] = q;
    for (n = 1u; n <= nmax; ++n) {
        q *= ar;
        rn[n] = q;
    }
    for (m = 0u; m <= nmax; ++m) {
        float w; /* P = w * u: 1 for m = 0, nu for m >= 1 */
        float u1;
        float u2 = 0.0f;
        float d1;
        float d2 = 0.0f;
        float fm = (float)m;
        if (m == 1u) {
            umm = 1.0f;   /* Q_1^1 = 1 (P_1^1 = nu) */
            dmm = pt->mu; /* dP_1^1/dtheta = mu */
        } else if (m >= 2u) {
            float s = magcal_geomag_schmidt_s[m];
            dmm = s * (pt->nu * dmm + pt->mu * (pt->nu * umm));
            umm = s * pt->nu * umm;
        } else {
            /* m == 0: Q_0^0 = 1, dP_0^0/dtheta = 0 as initialised */
        }
        w = (m == 0u) ? 1.0f : pt->nu;
        u1 = umm;
        d1 = dmm;
        for (n = m; n <= nmax; ++n) {
            unsigned k;
            float g;
            float h = 0.0f;
            float gd;
            float hd = 0.0f;
            float gc;
            float gs;
            float dc;
            float ds;
            float t;
            float p;
            unsigned n1;
            float fn1;
            if (n > m) {
                unsigned tri = (n * (n - 1u)) / 2u + m;
                float a = magcal_geomag_schmidt_a[tri];
                float bb = magcal_geomag_schmidt_b[tri];
                float u = a * pt->mu * u1 - bb * u2;
                float d = a * (pt->mu * d1 - pt->nu * w * u1) - bb * d2;
                u2 = u1;
                u1 = u;
                d2 = d1;
                d1 = d;
            }
            if (n == 0u) {
                continue;
            }
            k = n * n - 1u + ((m == 0u) ? 0u : 2u * m - 1u);
            coef_at(ts, n, k, &g, &gd);
            if (m > 0u) {
                coef_at(ts, n, k + 1u, &h, &hd);
            }
            gc = g * cm + h * sm;
            gs = fm * (g * sm - h * cm);
            dc = gd * cm + hd * sm;
            ds = fm * (gd * sm - hd * cm);
            t = rn[n];
            p = w * u1;
            acc = (n == 1u) ? lead : b;
            n1 = n + 1u;
            fn1 = (float)n1;
            acc[0] += t * gc * d1;
            acc[1] += t * gs * u1;
            acc[2] -= fn1 * t * gc * p;
            acc[3] += t * dc * d1;
            acc[4] += t * ds * u1;
            acc[5] -= fn1 * t * dc * p;
        }
        {
            float c_next = cm * pt->clon - sm * pt->slon;
            sm = sm * pt->clon + cm * pt->slon;
            cm = c_next;
        }
    }
    /* The dipole terms are ~55 000 nT, all others sum to a few thousand: accumulating those
     * first, in a small accumulator, and adding the dipole once keeps the rounding of every
     * addition at the few-thousand level (measured: 0.041 -> see docs/geomag.md). */
    for (n = 0u; n < 6u; ++n) {
        b[n] += lead[n];
    }
}

/* 8.2 geodetic (sin/cos of the latitude, height h km) -> geocentric point, and sin/cos of the
 * rotation angle psi = phi' - phi, in float32 without cancellation:
 *   w = 1 - e^2 s^2, Rc = a_e / sqrt(w), Rc - a_e = a_e e^2 s^2 / (sqrt(w) (1 + sqrt(w)));
 *   A = Rc + h, B = Rc (1 - e^2) + h = A - e^2 Rc, p = A cos(phi), z = B sin(phi);
 *   r^2 = A^2 - s^2 (A - B)(A + B) = A^2 (1 - eps), eps = s^2 e^2 Rc (2A - e^2 Rc) / A^2, so
 *   r - a_e = (Rc - a_e) + h - A eps / (1 + sqrt(1 - eps)): every term is small and exact to
 *   about a centimetre, and r = a_e + (r - a_e) rounds once (0.24 m). The naive
 *   sqrt(p^2 + z^2) is up to 1 m off in float32, i.e. 0.026 nT in the dipole's radial term.
 *   sin psi = (z cos phi - p sin phi) / r = -e^2 Rc sin(phi) cos(phi) / r,
 *   cos psi = (p cos phi + z sin phi) / r = (Rc w + h) / r. */
static void to_geocentric(float sp, float cp, float h, geomag_point_t *pt, float *sin_psi,
                          float *cos_psi)
{
    float s2 = sp * sp;
    float w = 1.0f - GEOMAG_WGS84_E2 * s2;
    float sw = sqrtf(w);
    float rc = GEOMAG_WGS84_A_KM / sw;
    float drc = GEOMAG_WGS84_A_KM * GEOMAG_WGS84_E2 * s2 / (sw * (1.0f + sw));
    float a = rc + h;
    float e2rc = GEOMAG_WGS84_E2 * rc;
    float eps = s2 * e2rc * (2.0f * a - e2rc) / (a * a);
    float r = GEOMAG_WGS84_A_KM + ((drc + h) - a * eps / (1.0f + sqrtf(1.0f - eps)));
    pt->r_km = r;
    pt->mu = (a - e2rc) * sp / r;
    pt->nu = a * cp / r;
    *sin_psi = -e2rc * sp * cp / r;
    *cos_psi = (rc * w + h) / r;
}

static magcal_status_t check_date(const magcal_geomag_model_t *model, float year)
{
    if (!(year >= model->valid_from && year <= model->valid_to)) {
        return MAGCAL_ERR_OUT_OF_VALIDITY;
    }
    return MAGCAL_OK;
}

/* Shared argument checks of both evaluators, in the documented order: non-finite input, latitude /
 * longitude / height (or radius) range, model table, date validity. */
static magcal_status_t check_args(const magcal_geomag_model_t *model, float lat_deg, float lon_deg,
                                  float h, float h_min, float h_max, float year)
{
    magcal_status_t st;
    if (!magcal_isfinite_f(lat_deg) || !magcal_isfinite_f(lon_deg) || !magcal_isfinite_f(h) ||
        !magcal_isfinite_f(year)) {
        return MAGCAL_ERR_NONFINITE;
    }
    if (lat_deg < -90.0f || lat_deg > 90.0f || lon_deg < -360.0f || lon_deg > 360.0f || h < h_min ||
        h > h_max) {
        return MAGCAL_ERR_ARG;
    }
    st = check_model(model);
    if (st != MAGCAL_OK) {
        return st;
    }
    return check_date(model, year);
}

magcal_status_t magcal_geomag_eval(const magcal_geomag_model_t *model, float lat_deg, float lon_deg,
                                   float height_km, float year, magcal_geomag_result_t *out)
{
    geomag_time_t ts;
    geomag_point_t pt;
    magcal_geomag_result_t res;
    magcal_status_t st;
    float sp;
    float cp;
    float sin_psi;
    float cos_psi;
    float b[6];
    float hdot_xy;

    if (model == NULL || out == NULL) {
        return MAGCAL_ERR_NULL;
    }
    st = check_args(model, lat_deg, lon_deg, height_km, model->height_min_km, model->height_max_km, year);
    if (st != MAGCAL_OK) {
        return st;
    }

    /* 8.2 geodetic -> geocentric (sin/cos of phi' directly; see the file comment) */
    sincos_deg(lat_deg, &sp, &cp);
    sincos_deg(lon_deg, &pt.slon, &pt.clon);
    to_geocentric(sp, cp, height_km, &pt, &sin_psi, &cos_psi);

    time_setup(model, year, &ts);
    synthesise(model, &ts, &pt, b);

    /* 8.6 rotate to geodetic north/east/down; derived elements */
    res.x_nt = b[0] * cos_psi - b[2] * sin_psi;
    res.y_nt = b[1];
    res.z_nt = b[0] * sin_psi + b[2] * cos_psi;
    res.x_dot_nt_yr = b[3] * cos_psi - b[5] * sin_psi;
    res.y_dot_nt_yr = b[4];
    res.z_dot_nt_yr = b[3] * sin_psi + b[5] * cos_psi;
    res.h_nt = sqrtf(res.x_nt * res.x_nt + res.y_nt * res.y_nt);
    res.f_nt = sqrtf(res.h_nt * res.h_nt + res.z_nt * res.z_nt);
    res.decl_deg = atan2f(res.y_nt, res.x_nt) * MAGCAL_DEG_PER_RAD_F;
    res.incl_deg = atan2f(res.z_nt, res.h_nt) * MAGCAL_DEG_PER_RAD_F;
    hdot_xy = res.x_nt * res.x_dot_nt_yr + res.y_nt * res.y_dot_nt_yr;
    res.h_dot_nt_yr = 0.0f;
    res.decl_dot_deg_yr = 0.0f;
    res.f_dot_nt_yr = 0.0f;
    res.incl_dot_deg_yr = 0.0f;
    if (res.h_nt > 0.0f) {
        res.h_dot_nt_yr = hdot_xy / res.h_nt;
        res.decl_dot_deg_yr = (res.x_nt * res.y_dot_nt_yr - res.y_nt * res.x_dot_nt_yr) /
                              (res.h_nt * res.h_nt) * MAGCAL_DEG_PER_RAD_F;
    }
    if (res.f_nt > 0.0f) {
        res.f_dot_nt_yr = (hdot_xy + res.z_nt * res.z_dot_nt_yr) / res.f_nt;
        res.incl_dot_deg_yr = (res.h_nt * res.z_dot_nt_yr - res.z_nt * res.h_dot_nt_yr) /
                              (res.f_nt * res.f_nt) * MAGCAL_DEG_PER_RAD_F;
    }
    res.polar = 1u;
    if (lat_deg > MAGCAL_GEOMAG_GRID_LAT_DEG) {
        res.grid_var_deg = magcal_wrap180_deg(res.decl_deg - lon_deg);
    } else if (lat_deg < -MAGCAL_GEOMAG_GRID_LAT_DEG) {
        res.grid_var_deg = magcal_wrap180_deg(res.decl_deg + lon_deg);
    } else {
        res.grid_var_deg = res.decl_deg;
        res.polar = 0u;
    }
    if (res.h_nt < MAGCAL_GEOMAG_BLACKOUT_H_NT) {
        res.zone = MAGCAL_GEOMAG_ZONE_BLACKOUT;
    } else if (res.h_nt < MAGCAL_GEOMAG_CAUTION_H_NT) {
        res.zone = MAGCAL_GEOMAG_ZONE_CAUTION;
    } else {
        res.zone = MAGCAL_GEOMAG_ZONE_NORMAL;
    }
    *out = res;
    return MAGCAL_OK;
}

magcal_status_t magcal_geomag_eval_geocentric(const magcal_geomag_model_t *model, float lat_gc_deg,
                                              float lon_deg, float radius_km, float year,
                                              float xyz_nt[3], float xyz_dot_nt_yr[3])
{
    geomag_time_t ts;
    geomag_point_t pt;
    magcal_status_t st;
    float b[6];
    unsigned i;

    if (model == NULL || xyz_nt == NULL) {
        return MAGCAL_ERR_NULL;
    }
    st = check_args(model, lat_gc_deg, lon_deg, radius_km, MAGCAL_GEOMAG_RADIUS_MIN_KM,
                    MAGCAL_GEOMAG_RADIUS_MAX_KM, year);
    if (st != MAGCAL_OK) {
        return st;
    }
    sincos_deg(lat_gc_deg, &pt.mu, &pt.nu);
    sincos_deg(lon_deg, &pt.slon, &pt.clon);
    pt.r_km = radius_km;
    time_setup(model, year, &ts);
    synthesise(model, &ts, &pt, b);
    for (i = 0u; i < 3u; ++i) {
        xyz_nt[i] = b[i];
        if (xyz_dot_nt_yr != NULL) {
            xyz_dot_nt_yr[i] = b[3u + i];
        }
    }
    return MAGCAL_OK;
}

magcal_status_t magcal_geomag_decimal_year(int year, int month, int day, float *out)
{
    static const unsigned char mdays[12] = {31u, 28u, 31u, 30u, 31u, 30u,
                                            31u, 31u, 30u, 31u, 30u, 31u};
    int leap;
    int doy;
    int ylen;
    int i;
    int dim;
    if (out == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (year < 1900 || year > 2100 || month < 1 || month > 12 || day < 1) {
        return MAGCAL_ERR_ARG;
    }
    leap = 0;
    if (((year % 4 == 0) && (year % 100 != 0)) || (year % 400 == 0)) {
        leap = 1;
    }
    dim = (int)mdays[month - 1] + ((month == 2) ? leap : 0);
    if (day > dim) {
        return MAGCAL_ERR_ARG;
    }
    doy = day;
    for (i = 0; i < month - 1; ++i) {
        doy += (int)mdays[i] + ((i == 1) ? leap : 0);
    }
    doy -= 1;
    ylen = 365 + leap;
    *out = (float)year + (float)doy / (float)ylen;
    return MAGCAL_OK;
}

#endif /* MAGCAL_CFG_ENABLE_GEOMAG */
