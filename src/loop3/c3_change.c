/*
 * Continuous 3-D calibrator, change detection: every drained sample is judged under the installed
 * calibration by its field norm, rel = |G (m - V)| / F - 1, against a threshold from the
 * calibration's own residual, max(cfg.mismatch_k sigma, cfg.mismatch_min_rel), sigma =
 * residual_rms / F of the solve that installed it (the floor alone for a calibration from flash).
 * Mismatching samples open an episode; the episode records the direction cells (6 cube faces x 4
 * quadrants of the corrected field) and the time (ms of the push stamps) it mismatched;
 * cfg.clear_ms of consistent samples close it. An episode that mismatched for cfg.change_ms over
 * at least cfg.change_cells cells is a change (a new hard iron shows in every direction); a
 * transient (a passing truck, a magnet the device passes: seconds) is flagged (trust DISTURBED)
 * but discards nothing.
 */
#include <math.h>

#include "c3_internal.h"
#include "magcal_internal.h"

#if MAGCAL_CFG_ENABLE_3D /* whole file: config.h feature switch (the 3-D loop needs the ellipsoid fit) */

static unsigned c3_popcount(uint32_t v)
{
    unsigned n = 0u;
    unsigned k;
    for (k = 0u; k < 32u; ++k) {
        n += (unsigned)((v >> k) & 1u);
    }
    return n;
}

/* Cell of a direction: dominant axis and its sign (face), then the signs of the other two. */
static uint8_t c3_cell(const magcal_vec3_t *h)
{
    const float ax = fabsf(h->x);
    const float ay = fabsf(h->y);
    const float az = fabsf(h->z);
    float s0; /* the dominant component */
    float s1; /* the other two, in axis order */
    float s2;
    uint32_t face;
    uint32_t q = 0u;
    if (ax >= ay && ax >= az) {
        face = 0u;
        s0 = h->x;
        s1 = h->y;
        s2 = h->z;
    } else if (ay >= az) {
        face = 2u;
        s0 = h->y;
        s1 = h->x;
        s2 = h->z;
    } else {
        face = 4u;
        s0 = h->z;
        s1 = h->x;
        s2 = h->y;
    }
    if (s0 < 0.0f) {
        face += 1u;
    }
    if (s1 < 0.0f) {
        q |= 1u;
    }
    if (s2 < 0.0f) {
        q |= 2u;
    }
    return (uint8_t)(face * 4u + q);
}

int magcal_c3_judge(const magcal_cont3_t *cc, const magcal_vec3_t *m, magcal_c3_judge_t *j)
{
    magcal_vec3_t h;
    float thr;
    j->rel = NAN;
    j->cell = 0u;
    j->mismatch = 0u;
    if (cc->has_cal == 0u || magcal_ellipsoid_apply(&cc->cal, m, &h) != MAGCAL_OK) {
        return 0;
    }
    j->rel = sqrtf(h.x * h.x + h.y * h.y + h.z * h.z) / cc->cal.field - 1.0f;
    j->cell = c3_cell(&h);
    thr = fmaxf(cc->cfg.mismatch_k * cc->cal_sigma_rel, cc->cfg.mismatch_min_rel);
    j->mismatch = (uint8_t)(!(fabsf(j->rel) <= thr) ? 1u : 0u);
    return 1;
}

uint32_t magcal_c3_tick(magcal_cont3_t *cc, uint32_t t_ms)
{
    uint32_t dt = 0u;
    if (cc->have_t != 0u) {
        dt = t_ms - cc->last_t;
        if (dt > MAGCAL_CONT3_MAX_DT_MS) {
            dt = MAGCAL_CONT3_MAX_DT_MS;
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
    return dt;
}

int magcal_c3_episode_wide(const magcal_cont3_t *cc)
{
    return cc->episode_open != 0u && c3_popcount(cc->mis_cells) >= cc->cfg.change_cells;
}

static void c3_episode_close(magcal_cont3_t *cc)
{
    cc->episode_open = 0u;
    cc->mis_ms = 0u;
    cc->clean_ms = 0u;
    cc->mis_cells = 0u;
}

int magcal_c3_episode(magcal_cont3_t *cc, const magcal_c3_judge_t *j, uint32_t dt)
{
    if (j->mismatch != 0u) {
        cc->episode_open = 1u;
        cc->mis_ms += dt;
        cc->clean_ms = 0u;
        cc->mis_cells |= 1u << j->cell;
    } else if (cc->episode_open != 0u) {
        cc->clean_ms += dt;
        if (cc->clean_ms >= cc->cfg.clear_ms) {
            c3_episode_close(cc);
        }
    } else {
        /* consistent, no episode */
    }
    return cc->episode_open != 0u && cc->mis_ms >= cc->cfg.change_ms && magcal_c3_episode_wide(cc) != 0;
}

void magcal_c3_declare_change(magcal_cont3_t *cc)
{
    (void)magcal_intake_reset(&cc->store);
    cc->state = (uint8_t)MAGCAL_CONT3_RELEARNING;
    cc->stage = MAGCAL_C3_STAGE_NONE; /* a unit under way is abandoned */
    cc->adopt_pass = 0u;
    cc->worth_checked = 0u;
    cc->changes++;
    c3_episode_close(cc);
    cc->stored_at_solve = 0u;
    cc->fail_run = 0u;
    cc->refuse_run = 0u;
    cc->change_flag = 1u;
}

#endif /* MAGCAL_CFG_ENABLE_3D */
