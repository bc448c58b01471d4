/* Tilt compensation (algorithms.md section 6): pitch about x (right), roll about y (forward). */
#include <float.h>
#include <math.h>

#include "magcal/tilt.h"
#include "magcal_internal.h"

/* Sine and cosine of roll and pitch. */
typedef struct {
    float sr;
    float cr;
    float sp;
    float cp;
} tilt_trig_t;

static magcal_status_t tilt_check_cfg(const magcal_tilt_cfg_t *cfg)
{
    if (!(cfg->free_fall_g > 0.0f && cfg->free_fall_g < 1.0f) || !(cfg->accel_norm_tol_g > 0.0f) ||
        !magcal_isfinite_f(cfg->accel_norm_tol_g) ||
        !(cfg->max_pitch_deg > 0.0f && cfg->max_pitch_deg < 90.0f) ||
        !(cfg->min_horiz_ratio >= 0.0f && cfg->min_horiz_ratio < 1.0f)) {
        return MAGCAL_ERR_ARG;
    }
    return MAGCAL_OK;
}

static int tilt_vec_finite(const magcal_vec3_t *v)
{
    return magcal_isfinite_f(v->x) && magcal_isfinite_f(v->y) && magcal_isfinite_f(v->z);
}

/*
 * Attitude gates and trigonometry straight from the specific force, without atan2/sin/cos:
 * cos(theta) = sqrt(fx^2 + fz^2)/|f|, sin(theta) = fy/|f|, cos(phi) = fz/r, sin(phi) = -fx/r
 * with r = sqrt(fx^2 + fz^2). The pitch gate |theta| <= max compares
 * |fy| <= |f| sin(max) so no angle is needed either.
 */
static magcal_status_t tilt_trig(const magcal_tilt_cfg_t *cfg, const magcal_vec3_t *f,
                                 tilt_trig_t *t)
{
    float rxz2;
    float norm;
    float rxz;
    if (!tilt_vec_finite(f)) {
        return MAGCAL_ERR_NONFINITE;
    }
    rxz2 = f->x * f->x + f->z * f->z;
    norm = sqrtf(rxz2 + f->y * f->y);
    if (!magcal_isfinite_f(norm)) { /* overflow of the squares */
        return MAGCAL_ERR_ACCEL_NORM;
    }
    if (norm < cfg->free_fall_g) {
        return MAGCAL_ERR_FREE_FALL;
    }
    if (fabsf(norm - 1.0f) > cfg->accel_norm_tol_g) {
        return MAGCAL_ERR_ACCEL_NORM;
    }
    rxz = sqrtf(rxz2);
    if (fabsf(f->y) > norm * sinf(cfg->max_pitch_deg * MAGCAL_RAD_PER_DEG_F) || !(rxz > 0.0f)) {
        return MAGCAL_ERR_GIMBAL;
    }
    t->sp = f->y / norm;
    t->cp = rxz / norm;
    t->sr = -f->x / rxz;
    t->cr = f->z / rxz;
    return MAGCAL_OK;
}

/* m_L = R_x(theta) R_y(phi) m (algorithms.md section 6). */
static void tilt_rotate(const tilt_trig_t *t, const magcal_vec3_t *m, magcal_vec3_t *l)
{
    float w = m->x * t->sr - m->z * t->cr;
    l->x = m->x * t->cr + m->z * t->sr;
    l->y = m->y * t->cp + t->sp * w;
    l->z = m->y * t->sp - t->cp * w;
}

magcal_status_t magcal_tilt_attitude(const magcal_tilt_cfg_t *cfg, const magcal_vec3_t *accel_g,
                                     magcal_tilt_t *att)
{
    tilt_trig_t t;
    magcal_status_t st;
    if (cfg == NULL || accel_g == NULL || att == NULL) {
        return MAGCAL_ERR_NULL;
    }
    st = tilt_check_cfg(cfg);
    if (st != MAGCAL_OK) {
        return st;
    }
    st = tilt_trig(cfg, accel_g, &t);
    if (st != MAGCAL_OK) {
        return st;
    }
    att->pitch_deg = atan2f(t.sp, t.cp) * MAGCAL_DEG_PER_RAD_F;
    att->roll_deg = atan2f(t.sr, t.cr) * MAGCAL_DEG_PER_RAD_F;
    return MAGCAL_OK;
}

magcal_status_t magcal_tilt_level_field(const magcal_tilt_t *att, const magcal_vec3_t *mag,
                                        magcal_vec3_t *level)
{
    tilt_trig_t t;
    float r;
    float p;
    if (att == NULL || mag == NULL || level == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (!tilt_vec_finite(mag) || !magcal_isfinite_f(att->roll_deg) ||
        !magcal_isfinite_f(att->pitch_deg)) {
        return MAGCAL_ERR_NONFINITE;
    }
    r = att->roll_deg * MAGCAL_RAD_PER_DEG_F;
    p = att->pitch_deg * MAGCAL_RAD_PER_DEG_F;
    t.sr = sinf(r);
    t.cr = cosf(r);
    t.sp = sinf(p);
    t.cp = cosf(p);
    tilt_rotate(&t, mag, level);
    return MAGCAL_OK;
}

magcal_status_t magcal_tilt_heading(const magcal_tilt_cfg_t *cfg, const magcal_vec3_t *accel_g,
                                    const magcal_vec3_t *mag, float *heading_deg, magcal_tilt_t *att)
{
    tilt_trig_t t;
    magcal_vec3_t l;
    magcal_status_t st;
    float mnorm;
    float hnorm;
    if (cfg == NULL || accel_g == NULL || mag == NULL || heading_deg == NULL) {
        return MAGCAL_ERR_NULL;
    }
    st = tilt_check_cfg(cfg);
    if (st != MAGCAL_OK) {
        return st;
    }
    if (!tilt_vec_finite(mag)) {
        return MAGCAL_ERR_NONFINITE;
    }
    st = tilt_trig(cfg, accel_g, &t);
    if (st != MAGCAL_OK) {
        return st;
    }
    /* Scale the field to its largest component first so the squares cannot overflow. */
    mnorm = fmaxf(fabsf(mag->x), fmaxf(fabsf(mag->y), fabsf(mag->z)));
    if (!(mnorm > 0.0f)) {
        return MAGCAL_ERR_ZERO_FIELD;
    }
    {
        magcal_vec3_t ms;
        float inv = 1.0f / mnorm;
        ms.x = mag->x * inv;
        ms.y = mag->y * inv;
        ms.z = mag->z * inv;
        tilt_rotate(&t, &ms, &l);
        mnorm = sqrtf(ms.x * ms.x + ms.y * ms.y + ms.z * ms.z);
    }
    hnorm = sqrtf(l.x * l.x + l.y * l.y);
    if (!(hnorm > cfg->min_horiz_ratio * mnorm) || !(hnorm > 0.0f)) {
        return MAGCAL_ERR_ZERO_FIELD;
    }
    *heading_deg = magcal_wrap360_deg(atan2f(-l.x, l.y) * MAGCAL_DEG_PER_RAD_F);
    if (att != NULL) {
        att->pitch_deg = atan2f(t.sp, t.cp) * MAGCAL_DEG_PER_RAD_F;
        att->roll_deg = atan2f(t.sr, t.cr) * MAGCAL_DEG_PER_RAD_F;
    }
    return MAGCAL_OK;
}

magcal_status_t magcal_tilt_heading_get(const magcal_tilt_cfg_t *cfg, const magcal_trust_t *t,
                                        const magcal_vec3_t *accel_g, const magcal_vec3_t *mag,
                                        float field, float declination_deg, magcal_heading_t *out)
{
    magcal_tilt_t att;
    magcal_vec3_t l;
    magcal_status_t st;
    float psi;
    float mnorm;
    float rel = NAN;
    float incl;
    uint8_t flags = (uint8_t)MAGCAL_HEADING_FLAG_UNCALIBRATED;
    if (out == NULL || mag == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (t != NULL && t->magic != MAGCAL_TRUST_MAGIC) {
        return MAGCAL_ERR_NOT_INITIALISED;
    }
    if (!magcal_isfinite_f(field) || !magcal_isfinite_f(declination_deg)) {
        return MAGCAL_ERR_NONFINITE;
    }
    if (field < 0.0f || declination_deg > 180.0f || declination_deg < -180.0f) {
        return MAGCAL_ERR_ARG;
    }
    st = magcal_tilt_heading(cfg, accel_g, mag, &psi, &att);
    if (st != MAGCAL_OK) {
        return st;
    }
    /* heading passed: mag finite and non-zero. Scale before squaring (no overflow). */
    mnorm = fmaxf(fabsf(mag->x), fmaxf(fabsf(mag->y), fabsf(mag->z)));
    {
        magcal_vec3_t ms;
        float inv = 1.0f / mnorm;
        float h;
        ms.x = mag->x * inv;
        ms.y = mag->y * inv;
        ms.z = mag->z * inv;
        (void)magcal_tilt_level_field(&att, &ms, &l);
        h = sqrtf(l.x * l.x + l.y * l.y);
        incl = atan2f(-l.z, h) * MAGCAL_DEG_PER_RAD_F;
        if (field > 0.0f) {
            rel = (mnorm / field) * sqrtf(ms.x * ms.x + ms.y * ms.y + ms.z * ms.z);
        }
    }
    if (field > 0.0f) {
        /* |m| / F overflows: judged as the largest float (beyond any tolerance), reported +Inf */
        st = magcal_trust_judge(t, magcal_isfinite_f(rel) ? rel : FLT_MAX, incl, &flags);
        if (st != MAGCAL_OK) {
            return st;
        }
        if (!magcal_isfinite_f(rel)) {
            rel = INFINITY;
        }
    }
    {
        float tr = psi + declination_deg; /* [0,360) + [-180,180]: one wrap */
        out->true_deg = magcal_wrap360_deg(tr);
    }
    out->magnetic_deg = psi;
    out->field_rel = rel;
    out->inclination_deg = incl;
    out->flags = flags;
    out->trust = (uint8_t)magcal_trust_from_flags(flags);
    return MAGCAL_OK;
}
