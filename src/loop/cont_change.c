/*
 * Continuous calibrator, change detection: every drained sample is judged under the installed
 * calibration by its corrected radius, rel = |h| / R - 1, against a threshold from the
 * calibration's own residual, max(cfg.mismatch_k sigma, cfg.mismatch_min_rel). Mismatching
 * samples open an episode; the episode records the sectors (10 deg of corrected heading) and the
 * time (ms of the push stamps) it mismatched; cfg.clear_ms of consistent samples close it. An
 * episode that mismatched for cfg.change_ms over at least cfg.change_bins sectors is a change:
 * a transient (seconds, one or two sectors) is flagged (trust DISTURBED) but discards nothing.
 */
#include <math.h>

#include "cont_internal.h"
#include "magcal_internal.h"

static unsigned cont_popcount(uint32_t v)
{
    unsigned n = 0u;
    unsigned k;
    for (k = 0u; k < 32u; ++k) {
        n += (unsigned)((v >> k) & 1u);
    }
    return n;
}

int magcal_cont_judge(const magcal_cont_t *cc, const magcal_vec3_t *m, magcal_cont_judge_t *j)
{
    magcal_vec2_t h;
    magcal_vec2_t raw;
    float r;
    float thr;
    float deg;
    int sec;
    j->rel = NAN;
    j->heading = 0.0f;
    j->sector = 0u;
    j->mismatch = 0u;
    raw.x = m->x;
    raw.y = m->y;
    if (cc->has_cal == 0u || magcal_correct_apply(&cc->cal, raw, &h) != MAGCAL_OK ||
        !(cc->cal.radius > 0.0f)) {
        return 0;
    }
    r = sqrtf(h.x * h.x + h.y * h.y);
    if (cc->fz_on != 0u) {
        /* total field: |h|^2 - b u - c u^2 stays a while the vehicle pitches (hills) */
        const float u = m->z - cc->fz_u0;
        const float tt = h.x * h.x + h.y * h.y - cc->fz_abc[1] * u - cc->fz_abc[2] * u * u;
        j->rel = sqrtf(fmaxf(tt, 0.0f) / cc->fz_abc[0]) - 1.0f;
    } else {
        j->rel = r / cc->cal.radius - 1.0f;
    }
    deg = MAGCAL_DEG_PER_RAD_F * atan2f(-h.x, h.y);
    if (deg < 0.0f) {
        deg += 360.0f;
    }
    j->heading = deg;
    sec = (int)(deg / (360.0f / (float)MAGCAL_CONT_SECTORS));
    if (sec < 0) {
        sec = 0;
    }
    if (sec >= (int)MAGCAL_CONT_SECTORS) {
        sec = (int)MAGCAL_CONT_SECTORS - 1;
    }
    j->sector = (uint8_t)sec;
    thr = fmaxf(cc->cfg.mismatch_k * cc->cal_sigma_rel, cc->cfg.mismatch_min_rel);
    j->mismatch = (uint8_t)(!(fabsf(j->rel) <= thr) ? 1u : 0u);
    return 1;
}

int magcal_cont_episode_wide(const magcal_cont_t *cc)
{
    return cc->episode_open != 0u &&
           cont_popcount(cc->mis_bins[0]) + cont_popcount(cc->mis_bins[1]) >= cc->cfg.change_bins;
}

int magcal_cont_episode(magcal_cont_t *cc, const magcal_cont_judge_t *j, uint32_t t_ms)
{
    uint32_t dt = 0u;
    if (cc->have_t != 0u) {
        dt = t_ms - cc->last_t;
        if (dt > MAGCAL_CONT_MAX_DT_MS) {
            dt = MAGCAL_CONT_MAX_DT_MS;
        }
    }
    cc->last_t = t_ms;
    cc->have_t = 1u;
    if (cc->age_ms_acc <= UINT32_MAX - dt) {
        cc->age_ms_acc += dt;
    }
    if (cc->solve_ms_acc <= UINT32_MAX - dt) {
        cc->solve_ms_acc += dt;
    }
    if (j->mismatch != 0u) {
        cc->episode_open = 1u;
        cc->mis_ms += dt;
        cc->clean_ms = 0u;
        cc->mis_bins[j->sector / 32u] |= 1u << (j->sector % 32u);
    } else if (cc->episode_open != 0u) {
        cc->clean_ms += dt;
        if (cc->clean_ms >= cc->cfg.clear_ms) {
            cc->episode_open = 0u;
            cc->mis_ms = 0u;
            cc->clean_ms = 0u;
            cc->mis_bins[0] = 0u;
            cc->mis_bins[1] = 0u;
        }
    } else {
        /* consistent, no episode */
    }
    return cc->episode_open != 0u && cc->mis_ms >= cc->cfg.change_ms && magcal_cont_episode_wide(cc) != 0;
}

void magcal_cont_declare_change(magcal_cont_t *cc)
{
    (void)magcal_intake_reset(&cc->store);
    cc->state = (uint8_t)MAGCAL_CONT_RELEARNING;
    cc->stage = 0u;
    cc->changes++;
    cc->episode_open = 0u;
    cc->mis_ms = 0u;
    cc->clean_ms = 0u;
    cc->mis_bins[0] = 0u;
    cc->mis_bins[1] = 0u;
    cc->stored_at_solve = 0u;
    cc->stored_at_adopt = 0u;
    cc->change_flag = 1u;
}

/* Least squares of y = a + b u + c u^2 over the consistent store samples (|h| / R - 1 within
 * +-0.35: hills move the horizontal radius by up to ~20 %), then the judge's noise: the RMS of its
 * relative residual over the samples within 0.1 of the model. Used only when the samples' z spread
 * is at least 2 % of the raw radius and the model is physical (c < 0, a > 0): otherwise the judge
 * compares the horizontal radius with R, and its noise is the solve's est_noise_deg. Bounded:
 * two passes over the store slots. */
void magcal_cont_fit_field(magcal_cont_t *cc)
{
    const magcal_intake_t *st = &cc->store;
    const uint32_t per = st->cfg.per_bin;
    float s[5] = {0.0f, 0.0f, 0.0f, 0.0f, 0.0f}; /* sums of u^0..u^4 */
    float t[3] = {0.0f, 0.0f, 0.0f};            /* sums of y u^0..2 */
    float zs = 0.0f;
    float n = 0.0f;
    uint32_t b;
    uint32_t k;
    float var;
    float det;
    float m00;
    float m01;
    float m02;
    float m11;
    float m12;
    float m22;
    float a0;
    float a1;
    float a2;
    cc->fz_on = 0u;
    for (b = 0u; b < st->n_bins; ++b) {
        for (k = 0u; k < st->count[b]; ++k) {
            zs += st->slots[b * per + k].m.z;
            n += 1.0f;
        }
    }
    if (n < 30.0f) {
        return;
    }
    cc->fz_u0 = zs / n;
    n = 0.0f;
    for (b = 0u; b < st->n_bins; ++b) {
        for (k = 0u; k < st->count[b]; ++k) {
            const magcal_vec3_t *m = &st->slots[b * per + k].m;
            magcal_vec2_t raw;
            magcal_vec2_t h;
            float y;
            float u;
            float u2;
            float rel;
            raw.x = m->x;
            raw.y = m->y;
            if (magcal_correct_apply(&cc->cal, raw, &h) != MAGCAL_OK) {
                continue;
            }
            y = h.x * h.x + h.y * h.y;
            rel = sqrtf(y) / cc->cal.radius - 1.0f;
            if (!(fabsf(rel) <= 0.35f)) {
                continue;
            }
            u = m->z - cc->fz_u0;
            u2 = u * u;
            s[0] += 1.0f;
            s[1] += u;
            s[2] += u2;
            s[3] += u2 * u;
            s[4] += u2 * u2;
            t[0] += y;
            t[1] += y * u;
            t[2] += y * u2;
        }
    }
    if (s[0] < 30.0f) {
        return;
    }
    var = s[2] / s[0] - (s[1] / s[0]) * (s[1] / s[0]);
    if (!(var > (0.02f * cc->cal_raw_radius) * (0.02f * cc->cal_raw_radius))) {
        return;
    }
    m00 = s[0]; m01 = s[1]; m02 = s[2]; m11 = s[2]; m12 = s[3]; m22 = s[4];
    det = m00 * (m11 * m22 - m12 * m12) - m01 * (m01 * m22 - m12 * m02) + m02 * (m01 * m12 - m11 * m02);
    if (!(fabsf(det) > 0.0f)) {
        return;
    }
    a0 = (t[0] * (m11 * m22 - m12 * m12) - m01 * (t[1] * m22 - m12 * t[2]) + m02 * (t[1] * m12 - m11 * t[2])) / det;
    a1 = (m00 * (t[1] * m22 - m12 * t[2]) - t[0] * (m01 * m22 - m12 * m02) + m02 * (m01 * t[2] - t[1] * m02)) / det;
    a2 = (m00 * (m11 * t[2] - t[1] * m12) - m01 * (m01 * t[2] - t[1] * m02) + t[0] * (m01 * m12 - m11 * m02)) / det;
    if (!(a0 > 0.0f) || !(a2 < 0.0f) || !magcal_isfinite_f(a1)) {
        return;
    }
    cc->fz_abc[0] = a0;
    cc->fz_abc[1] = a1;
    cc->fz_abc[2] = a2;
    {
        float ss = 0.0f;
        for (b = 0u; b < st->n_bins; ++b) {
            for (k = 0u; k < st->count[b]; ++k) {
                const magcal_vec3_t *m = &st->slots[b * per + k].m;
                magcal_vec2_t raw;
                magcal_vec2_t h;
                float u;
                float tt;
                float rel;
                raw.x = m->x;
                raw.y = m->y;
                if (magcal_correct_apply(&cc->cal, raw, &h) != MAGCAL_OK) {
                    continue;
                }
                u = m->z - cc->fz_u0;
                tt = h.x * h.x + h.y * h.y - a1 * u - a2 * u * u;
                rel = sqrtf(fmaxf(tt, 0.0f) / a0) - 1.0f;
                if (fabsf(rel) <= 0.1f) {
                    ss += rel * rel;
                    n += 1.0f;
                }
            }
        }
        if (n < 30.0f) {
            return;
        }
        cc->cal_sigma_rel = sqrtf(ss / n);
    }
    cc->fz_on = 1u;
}
