/* 2-D correction and heading (algorithms.md 1.1, 1.2, 2.4). float32 only. */
#include "magcal/heading.h"

#include <float.h>
#include <math.h>

#include "magcal_internal.h"

magcal_status_t magcal_cal2d_validate(const magcal_cal2d_t *c)
{
    float det;

    if (c == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (c->magic != MAGCAL_CAL2D_MAGIC) {
        return MAGCAL_ERR_NOT_INITIALISED;
    }
    if (!magcal_isfinite_f(c->offset.x) || !magcal_isfinite_f(c->offset.y) ||
        !magcal_isfinite_f(c->m[0][0]) || !magcal_isfinite_f(c->m[0][1]) ||
        !magcal_isfinite_f(c->m[1][0]) || !magcal_isfinite_f(c->m[1][1]) ||
        !magcal_isfinite_f(c->radius)) {
        return MAGCAL_ERR_NONFINITE;
    }
    det = c->m[0][0] * c->m[1][1] - c->m[0][1] * c->m[1][0];
    if (!(det > 0.0f)) {
        return MAGCAL_ERR_DEGENERATE;
    }
    if (c->radius < 0.0f) {
        return MAGCAL_ERR_ARG;
    }
    return MAGCAL_OK;
}

magcal_status_t magcal_correct_apply(const magcal_cal2d_t *c, magcal_vec2_t raw, magcal_vec2_t *out)
{
    magcal_status_t st;
    float ux;
    float uy;
    magcal_vec2_t h;

    if (c == NULL || out == NULL) {
        return MAGCAL_ERR_NULL;
    }
    st = magcal_cal2d_validate(c);
    if (st != MAGCAL_OK) {
        return st;
    }
    if (!magcal_isfinite_f(raw.x) || !magcal_isfinite_f(raw.y)) {
        return MAGCAL_ERR_NONFINITE;
    }
    ux = raw.x - c->offset.x;
    uy = raw.y - c->offset.y;
    h.x = c->m[0][0] * ux + c->m[0][1] * uy;
    h.y = c->m[1][0] * ux + c->m[1][1] * uy;
    if (!magcal_isfinite_f(h.x) || !magcal_isfinite_f(h.y)) { /* overflow of huge inputs */
        return MAGCAL_ERR_NONFINITE;
    }
    *out = h;
    return MAGCAL_OK;
}

magcal_status_t magcal_heading_from_field(magcal_vec2_t h, float *heading_deg)
{
    float deg;

    if (heading_deg == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (!magcal_isfinite_f(h.x) || !magcal_isfinite_f(h.y)) {
        return MAGCAL_ERR_NONFINITE;
    }
    /* |h|^2 below FLT_MIN: the direction is lost in underflow (or h is exactly zero). Computed
     * on the larger component first so huge finite inputs cannot overflow the test. */
    if (fabsf(h.x) < 1.0e-19f && fabsf(h.y) < 1.0e-19f && (h.x * h.x + h.y * h.y) < FLT_MIN) {
        return MAGCAL_ERR_ZERO_FIELD;
    }
    deg = magcal_atan2f(-h.x, h.y) * MAGCAL_DEG_PER_RAD_F; /* (-180, 180] (plus rounding) */
    if (deg < 0.0f) {
        deg += 360.0f;
    }
    if (deg >= 360.0f || deg == 0.0f) { /* -tiny + 360 rounds to 360; also turns -0 into +0 */
        deg = 0.0f;
    }
    *heading_deg = deg;
    return MAGCAL_OK;
}

magcal_status_t magcal_heading_compute(const magcal_cal2d_t *c, magcal_vec2_t raw,
                                       float declination_deg, float *magnetic_deg, float *true_deg)
{
    magcal_status_t st;
    magcal_vec2_t h;
    float mag;

    if (c == NULL || magnetic_deg == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (!magcal_isfinite_f(declination_deg)) {
        return MAGCAL_ERR_NONFINITE;
    }
    if (declination_deg > 180.0f || declination_deg < -180.0f) {
        return MAGCAL_ERR_ARG;
    }
    st = magcal_correct_apply(c, raw, &h);
    if (st != MAGCAL_OK) {
        return st;
    }
    if (c->radius > 0.0f) {
        float lim = MAGCAL_HEADING_ZERO_FIELD_FRAC * c->radius;
        if (fabsf(h.x) < lim && fabsf(h.y) < lim && (h.x * h.x + h.y * h.y) < lim * lim) {
            return MAGCAL_ERR_ZERO_FIELD;
        }
    }
    st = magcal_heading_from_field(h, &mag);
    if (st != MAGCAL_OK) {
        return st;
    }
    *magnetic_deg = mag;
    if (true_deg != NULL) {
        /* mag in [0, 360), declination in [-180, 180]: one add or subtract reaches [0, 360)
         * (no fmodf); a sum that rounds up to 360 reads 0. */
        float t = mag + declination_deg;
        if (t < 0.0f) {
            t += 360.0f;
        } else if (t >= 360.0f) {
            t -= 360.0f;
        } else {
            /* already in range */
        }
        if (t >= 360.0f || t == 0.0f) {
            t = 0.0f;
        }
        *true_deg = t;
    }
    return MAGCAL_OK;
}

/* ---- heading trust (docs/heading_models.md, "Heading trust") ---- */

magcal_status_t magcal_trust_init(magcal_trust_t *t, const magcal_trust_cfg_t *cfg,
                                  float residual_rel)
{
    float tol;
    float incl_tol;
    if (t == NULL || cfg == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (!magcal_isfinite_f(cfg->k) || !magcal_isfinite_f(cfg->floor_rel) ||
        !magcal_isfinite_f(cfg->incl_floor_deg) || !magcal_isfinite_f(residual_rel)) {
        return MAGCAL_ERR_NONFINITE;
    }
    if (!(cfg->k > 0.0f) || cfg->floor_rel < 0.0f || cfg->floor_rel >= 1.0f ||
        cfg->incl_floor_deg < 0.0f || cfg->incl_floor_deg > 90.0f || residual_rel < 0.0f) {
        return MAGCAL_ERR_ARG;
    }
    tol = cfg->k * residual_rel;
    if (!magcal_isfinite_f(tol)) { /* huge k * huge residual: nothing is ever disturbed */
        return MAGCAL_ERR_NONFINITE;
    }
    /* the radial residual over R is the angular noise of the field direction in radians */
    incl_tol = tol * MAGCAL_DEG_PER_RAD_F;
    t->tol_rel = fmaxf(tol, cfg->floor_rel);
    t->incl_tol_deg = fmaxf(incl_tol, cfg->incl_floor_deg);
    t->incl_deg = NAN;
    t->changed = 0u;
    t->magic = MAGCAL_TRUST_MAGIC;
    return MAGCAL_OK;
}

magcal_status_t magcal_trust_set_inclination(magcal_trust_t *t, float incl_deg)
{
    if (t == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (t->magic != MAGCAL_TRUST_MAGIC) {
        return MAGCAL_ERR_NOT_INITIALISED;
    }
    if (!magcal_isfinite_f(incl_deg)) {
        return MAGCAL_ERR_NONFINITE;
    }
    if (incl_deg < -90.0f || incl_deg > 90.0f) {
        return MAGCAL_ERR_ARG;
    }
    t->incl_deg = incl_deg;
    return MAGCAL_OK;
}

magcal_status_t magcal_trust_set_changed(magcal_trust_t *t, uint8_t changed)
{
    if (t == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (t->magic != MAGCAL_TRUST_MAGIC) {
        return MAGCAL_ERR_NOT_INITIALISED;
    }
    if (changed > 1u) {
        return MAGCAL_ERR_ARG;
    }
    t->changed = changed;
    return MAGCAL_OK;
}

magcal_status_t magcal_trust_judge(const magcal_trust_t *t, float field_rel, float incl_deg,
                                   uint8_t *flags)
{
    float tol = MAGCAL_TRUST_TOL_REL_NO_CONTEXT;
    uint8_t f = 0u;
    if (flags == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (t != NULL && t->magic != MAGCAL_TRUST_MAGIC) {
        return MAGCAL_ERR_NOT_INITIALISED;
    }
    /* incl_deg: NaN means "not measured"; an infinity is a caller bug */
    if (!magcal_isfinite_f(field_rel) || (incl_deg == incl_deg && !magcal_isfinite_f(incl_deg))) {
        return MAGCAL_ERR_NONFINITE;
    }
    if (field_rel < 0.0f) {
        return MAGCAL_ERR_ARG;
    }
    if (t != NULL) {
        tol = t->tol_rel;
        if (t->changed != 0u) {
            f |= (uint8_t)MAGCAL_HEADING_FLAG_CHANGED;
        }
        if (incl_deg == incl_deg && t->incl_deg == t->incl_deg &&
            fabsf(incl_deg - t->incl_deg) > t->incl_tol_deg) {
            f |= (uint8_t)MAGCAL_HEADING_FLAG_DISTURBED;
        }
    }
    if (fabsf(field_rel - 1.0f) > tol) {
        f |= (uint8_t)MAGCAL_HEADING_FLAG_DISTURBED;
    }
    *flags = f;
    return MAGCAL_OK;
}

magcal_trust_state_t magcal_trust_from_flags(uint8_t flags)
{
    if ((flags & MAGCAL_HEADING_FLAG_UNCALIBRATED) != 0u) {
        return MAGCAL_TRUST_UNCALIBRATED;
    }
    if ((flags & MAGCAL_HEADING_FLAG_CHANGED) != 0u) {
        return MAGCAL_TRUST_CHANGED;
    }
    if ((flags & MAGCAL_HEADING_FLAG_DISTURBED) != 0u) {
        return MAGCAL_TRUST_DISTURBED;
    }
    return MAGCAL_TRUST_OK;
}

const char *magcal_trust_str(magcal_trust_state_t s)
{
    switch (s) {
    case MAGCAL_TRUST_OK:
        return "ok";
    case MAGCAL_TRUST_UNCALIBRATED:
        return "uncalibrated";
    case MAGCAL_TRUST_DISTURBED:
        return "disturbed";
    case MAGCAL_TRUST_CHANGED:
        return "changed";
    case MAGCAL_TRUST_COARSE:
        return "coarse";
    case MAGCAL_TRUST_TILTED:
        return "tilted";
    default:
        return "unknown";
    }
}

magcal_status_t magcal_heading_get(const magcal_cal2d_t *c, magcal_vec2_t raw,
                                   float declination_deg, magcal_heading_t *out)
{
    return magcal_heading_get_trusted(c, NULL, raw, declination_deg, out);
}

magcal_status_t magcal_heading_get_trusted(const magcal_cal2d_t *c, const magcal_trust_t *t,
                                           magcal_vec2_t raw, float declination_deg,
                                           magcal_heading_t *out)
{
    magcal_status_t st;
    float mag;
    float tru;
    float rel = NAN;
    uint8_t flags = (uint8_t)MAGCAL_HEADING_FLAG_UNCALIBRATED;
    if (out == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (t != NULL && t->magic != MAGCAL_TRUST_MAGIC) {
        return MAGCAL_ERR_NOT_INITIALISED;
    }
    st = magcal_heading_compute(c, raw, declination_deg, &mag, &tru);
    if (st != MAGCAL_OK) {
        return st;
    }
    /* validated by magcal_heading_compute: radius >= 0, so > 0 means "fitted" */
    if (c->radius > 0.0f) {
        magcal_vec2_t h;
        float a;
        float b;
        (void)magcal_correct_apply(c, raw, &h); /* succeeded inside magcal_heading_compute */
        /* |h| without overflow: scale by the larger component */
        a = fmaxf(fabsf(h.x), fabsf(h.y));
        b = fminf(fabsf(h.x), fabsf(h.y)) / a; /* a > 0: the zero-field gate passed */
        rel = (a / c->radius) * sqrtf(1.0f + b * b);
        /* |h| / R overflows (tiny radius, huge sample): judged as the largest float, which is
         * beyond any tolerance, and reported as +Inf (not a clamped number) */
        st = magcal_trust_judge(t, magcal_isfinite_f(rel) ? rel : FLT_MAX, NAN, &flags);
        if (st != MAGCAL_OK) {
            return st;
        }
        if (!magcal_isfinite_f(rel)) {
            rel = INFINITY;
        }
    }
    out->magnetic_deg = mag;
    out->true_deg = tru;
    out->field_rel = rel;
    out->inclination_deg = NAN;
    out->flags = flags;
    out->trust = (uint8_t)magcal_trust_from_flags(flags);
    return MAGCAL_OK;
}
