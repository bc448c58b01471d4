/*
 * Internal interface of the judge (src/loop/): the total-field model's features, residual and
 * sector that the per-sample judge (cont_judge.c) and the field-model fit (cont_fzfit.c) share,
 * and the transient judge (cont_flags.c) that the episode update (cont_change.c) feeds. Not
 * installed. docs/calibrator.md "Judge and change detection".
 */
#ifndef MAGCAL_CONT_JUDGE_INTERNAL_H
#define MAGCAL_CONT_JUDGE_INTERNAL_H

#include <math.h>

#include "cont_internal.h"
#include "magcal_internal.h"

/* |rel| beyond this is a glitch wherever the sample lies: it does not feed the transient judge
 * (cont_flags.c), and it is a mismatch even in a sector the store did not cover (cont_judge.c) */
#define CONT_GLITCH_REL 0.5f

/* Features of the judge's model: 1, u, u^2, hx, hy, hx^2 - hy^2, hx hy (unit radius; the last
 * two absorb a residual shape error of the calibration). `skip` drops the leading u terms:
 * 0 keeps both, 1 drops u^2, 2 drops u and u^2. Returns the count written to f. */
static inline uint32_t magcal_cont_fz_feat(float u, float hx, float hy, uint32_t skip, float *f)
{
    uint32_t n = 1u;
    f[0] = 1.0f;
    if (skip < 2u) {
        f[n] = u;
        n++;
    }
    if (skip < 1u) {
        f[n] = u * u;
        n++;
    }
    f[n] = hx;
    f[n + 1u] = hy;
    f[n + 2u] = hx * hx - hy * hy;
    f[n + 3u] = hx * hy;
    return n + 4u;
}

/* Sector (0..35) of a corrected heading, deg [0, 360) into *deg (the judge's and the fit's cover). */
static inline uint8_t magcal_cont_sector(const magcal_vec2_t *h, float *deg_out)
{
    float deg = MAGCAL_DEG_PER_RAD_F * atan2f(-h->x, h->y);
    int sec;
    if (deg < 0.0f) {
        deg += 360.0f;
    }
    *deg_out = deg;
    sec = (int)(deg / (360.0f / (float)MAGCAL_CONT_SECTORS));
    if (sec < 0) {
        sec = 0;
    }
    if (sec >= (int)MAGCAL_CONT_SECTORS) {
        sec = (int)MAGCAL_CONT_SECTORS - 1;
    }
    return (uint8_t)sec;
}

/* Total-field residual of corrected h and raw z under the model: rel, and v = (hx, hy, u) unit
 * radius. |h|^2 - c1 u - c2 u^2 - c3 hx - c4 hy stays c0 while the vehicle pitches. */
static inline float magcal_cont_fz_rel(const magcal_cont_t *cc, const magcal_vec2_t *h, float z, float *v)
{
    const float hx = h->x / cc->cal.radius;
    const float hy = h->y / cc->cal.radius;
    const float u = (z - cc->fz_u0) / cc->cal_raw_radius;
    const float tt = hx * hx + hy * hy - cc->fz_abc[1] * u - cc->fz_abc[2] * u * u - cc->fz_hxy[0] * hx -
                     cc->fz_hxy[1] * hy - cc->fz_hxy[2] * (hx * hx - hy * hy) - cc->fz_hxy[3] * (hx * hy);
    v[0] = hx;
    v[1] = hy;
    v[2] = u;
    return sqrtf(fmaxf(tt, 0.0f) / cc->fz_abc[0]) - 1.0f;
}

/* Transient judge (cont_flags.c): one judged sample (its rel widened by its uncertainty, its raw
 * z and heading) after dt ms; sets cc->dist_flag. */
void magcal_cont_transient(magcal_cont_t *cc, const magcal_cont_judge_t *j, uint32_t dt);
/* 1 when the transient judge would flag after one more sample j (not written: the heading's
 * sample, which the drain has not judged yet). */
uint8_t magcal_cont_transient_peek(const magcal_cont_t *cc, const magcal_cont_judge_t *j);
/* 1 while the transient judge cannot flag (its baselines settle after a reset, no flag up): it
 * cannot vouch for a heading then. */
int magcal_cont_transient_settling(const magcal_cont_t *cc);

#endif /* MAGCAL_CONT_JUDGE_INTERNAL_H */
