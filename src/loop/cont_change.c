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

int magcal_cont_judge(const magcal_cont_t *cc, magcal_vec2_t raw, magcal_cont_judge_t *j)
{
    magcal_vec2_t h;
    float r;
    float thr;
    float deg;
    int sec;
    j->rel = NAN;
    j->heading = 0.0f;
    j->sector = 0u;
    j->mismatch = 0u;
    if (cc->has_cal == 0u || magcal_correct_apply(&cc->cal, raw, &h) != MAGCAL_OK ||
        !(cc->cal.radius > 0.0f)) {
        return 0;
    }
    r = sqrtf(h.x * h.x + h.y * h.y);
    j->rel = r / cc->cal.radius - 1.0f;
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
    cc->stored_total = 0u;
    cc->stored_at_solve = 0u;
    cc->stored_at_adopt = 0u;
    cc->change_flag = 1u;
}
