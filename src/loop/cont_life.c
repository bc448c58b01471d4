/*
 * Continuous calibrator, lifecycle: init, the ISR-safe push ring (push_g: with the gravity level
 * test that tags each sample LEVEL / TILTED for the store), progress, heading with trust.
 * The ring is single-producer (push) / single-consumer (step, cont_step.c): push writes the slot,
 * a barrier, then head; the consumer reads the slot, a barrier, then writes tail.
 */
#include "magcal/continuous.h"

#include <math.h>
#include <string.h>

#include "cont_internal.h"
#include "magcal_internal.h"

int magcal_cont_ok(const magcal_cont_t *cc) { return cc != NULL && cc->magic == MAGCAL_CONT_MAGIC; }

static magcal_status_t cont_check_cfg(const magcal_cont_cfg_t *c)
{
    if (c->intake.dims != 2u || c->drain_per_step < 1u || c->step_budget < 1u || c->change_bins < 1u ||
        c->change_bins > MAGCAL_CONT_SECTORS) {
        return MAGCAL_ERR_ARG;
    }
    if (!magcal_isfinite_f(c->solve_coverage_deg) || !magcal_isfinite_f(c->age_ms) ||
        !magcal_isfinite_f(c->mismatch_k) || !magcal_isfinite_f(c->mismatch_min_rel) ||
        !magcal_isfinite_f(c->disturb_k) || !magcal_isfinite_f(c->coarse_coverage_deg) ||
        !magcal_isfinite_f(c->coarse_max_err_deg)) {
        return MAGCAL_ERR_NONFINITE;
    }
    if (c->coarse_coverage_deg < 0.0f || c->coarse_coverage_deg > 360.0f ||
        !(c->coarse_max_err_deg > 0.0f)) {
        return MAGCAL_ERR_ARG;
    }
    if (c->solve_coverage_deg < 0.0f || c->solve_coverage_deg > 360.0f || !(c->age_ms > 0.0f) ||
        !(c->mismatch_k > 0.0f) || !(c->mismatch_min_rel > 0.0f) || !(c->disturb_k > 0.0f) ||
        c->disturb_tau_ms < 1u) {
        return MAGCAL_ERR_ARG;
    }
    return MAGCAL_OK;
}

magcal_status_t magcal_cont_init(magcal_cont_t *cc, const magcal_cont_cfg_t *cfg,
                                 const magcal_cal2d_t *installed, magcal_intake_slot_t *slots,
                                 size_t n_slots, magcal_vec2_t *buf, void *work, size_t work_len)
{
    magcal_status_t st;
    if (cc == NULL || cfg == NULL || slots == NULL || buf == NULL || work == NULL) {
        return MAGCAL_ERR_NULL;
    }
    st = cont_check_cfg(cfg);
    if (st != MAGCAL_OK) {
        return st;
    }
    if (installed != NULL) {
        st = magcal_cal2d_validate(installed);
        if (st != MAGCAL_OK) {
            return st;
        }
    }
    if (n_slots < MAGCAL_CONT_SLOTS(cfg->intake.bins, cfg->intake.per_bin) || n_slots > MAGCAL_MAX_SAMPLES) {
        return MAGCAL_ERR_WORKSPACE;
    }
    (void)memset(cc, 0, sizeof *cc);
    cc->cfg = *cfg;
    st = magcal_intake_init(&cc->store, &cfg->intake, slots, n_slots);
    if (st == MAGCAL_OK) {
        st = magcal_calibrator_init(&cc->solver, &cfg->solver, buf, n_slots, work, work_len);
    }
    if (st != MAGCAL_OK) {
        return st;
    }
    cc->buf = buf;
    cc->slots = n_slots;
    {
        const magcal_cal2d_t id = MAGCAL_CAL2D_IDENTITY;
        cc->cal = id;
    }
    cc->last.status = MAGCAL_OK;
    cc->last.est_heading_err_deg = NAN;
    cc->adopted_err = NAN;
    cc->last_status = MAGCAL_OK;
    cc->state = (uint8_t)MAGCAL_CONT_COLLECTING;
    cc->magic = MAGCAL_CONT_MAGIC;
    magcal_cont_coarse_mode(cc);
    if (installed != NULL && installed->radius > 0.0f) {
        /* raw radius of the installed ellipse: |M| scales it by sqrt(det M) */
        float det = installed->m[0][0] * installed->m[1][1] - installed->m[0][1] * installed->m[1][0];
        float r_raw = det > 0.0f ? installed->radius / sqrtf(det) : installed->radius;
        magcal_cont_install(cc, installed, r_raw, 0.0f);
    }
    return MAGCAL_OK;
}

/* Queue one sample with its tilt code (magcal_intake_tilt_t). */
static magcal_status_t cont_enqueue(magcal_cont_t *cc, const magcal_vec3_t *m, uint32_t t_ms, uint8_t tilt)
{
    const uint32_t h = cc->head;
    if (h - cc->tail >= MAGCAL_CONT_RING) {
        cc->dropped = cc->dropped + 1u;
        return MAGCAL_ERR_BUFFER_FULL;
    }
    cc->ring[h % MAGCAL_CONT_RING] = *m;
    cc->ring_t[h % MAGCAL_CONT_RING] = t_ms;
    cc->ring_tilt[h % MAGCAL_CONT_RING] = tilt;
    MAGCAL_CONT_BARRIER();
    cc->head = h + 1u;
    return MAGCAL_OK;
}

magcal_status_t magcal_cont_push(magcal_cont_t *cc, const magcal_vec3_t *m, uint32_t t_ms)
{
    if (cc == NULL || m == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (cc->magic != MAGCAL_CONT_MAGIC) {
        return MAGCAL_ERR_NOT_INITIALISED;
    }
    return cont_enqueue(cc, m, t_ms, (uint8_t)MAGCAL_INTAKE_TILT_UNKNOWN);
}

/* The gravity level test of push_g (continuous.h): O(1), no trigonometry. The gravity vector is
 * smoothed first (exponential, time constant MAGCAL_CONT_G_SMOOTH_MS of the stamps: vibration and
 * sensor noise), then the smoothed vector is tested; the running level of its |g|^2 is a slower
 * exponential average (MAGCAL_CONT_G_TAU_MS). A gap in the stamps counts at most one constant. */
static float cont_ema_w(uint32_t dt_ms, uint32_t tau_ms)
{
    const uint32_t dt = (dt_ms > tau_ms) ? tau_ms : dt_ms;
    return (float)dt / ((float)dt + (float)tau_ms);
}

static uint8_t cont_tilt_of(magcal_cont_t *cc, const magcal_vec3_t *g, uint32_t t_ms)
{
    const float tan2 = cc->store.tilt_tan2;
    float h2;
    float v2;
    float n2;
    if (g == NULL || !(tan2 > 0.0f) || !magcal_isfinite_f(g->x) || !magcal_isfinite_f(g->y) ||
        !magcal_isfinite_f(g->z) || !(g->x * g->x + g->y * g->y + g->z * g->z > 0.0f)) {
        return (uint8_t)MAGCAL_INTAKE_TILT_UNKNOWN;
    }
    cc->g_pushed = cc->g_pushed + 1u;
    if (!(cc->g_level2 > 0.0f)) {
        cc->g_s = *g; /* seeded by the first sample */
    } else {
        const float w = cont_ema_w(t_ms - cc->g_t, MAGCAL_CONT_G_SMOOTH_MS); /* wrapping stamps */
        cc->g_s.x += (g->x - cc->g_s.x) * w;
        cc->g_s.y += (g->y - cc->g_s.y) * w;
        cc->g_s.z += (g->z - cc->g_s.z) * w;
    }
    h2 = cc->g_s.x * cc->g_s.x + cc->g_s.y * cc->g_s.y;
    v2 = cc->g_s.z * cc->g_s.z;
    n2 = h2 + v2;
    if (!(cc->g_level2 > 0.0f)) {
        cc->g_level2 = n2;
    } else {
        cc->g_level2 += (n2 - cc->g_level2) * cont_ema_w(t_ms - cc->g_t, MAGCAL_CONT_G_TAU_MS);
    }
    cc->g_t = t_ms;
    if (!(cc->g_level2 > 0.0f) || !magcal_isfinite_f(cc->g_level2)) {
        cc->g_level2 = 0.0f; /* overflow (|g| ~ 1e19): start again */
        return (uint8_t)MAGCAL_INTAKE_TILT_UNKNOWN;
    }
    if (h2 <= tan2 * v2 && fabsf(n2 - cc->g_level2) <= cc->cfg.intake.g_band_rel * cc->g_level2) {
        cc->g_level = cc->g_level + 1u;
        return (uint8_t)MAGCAL_INTAKE_TILT_LEVEL;
    }
    return (uint8_t)MAGCAL_INTAKE_TILT_TILTED;
}

magcal_status_t magcal_cont_push_g(magcal_cont_t *cc, const magcal_vec3_t *m, const magcal_vec3_t *g,
                                   uint32_t t_ms)
{
    if (cc == NULL || m == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (cc->magic != MAGCAL_CONT_MAGIC) {
        return MAGCAL_ERR_NOT_INITIALISED;
    }
    return cont_enqueue(cc, m, t_ms, cont_tilt_of(cc, g, t_ms));
}

magcal_status_t magcal_cont_progress(const magcal_cont_t *cc, magcal_cont_progress_t *out)
{
    magcal_intake_progress_t p;
    if (cc == NULL || out == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (!magcal_cont_ok(cc)) {
        return MAGCAL_ERR_NOT_INITIALISED;
    }
    (void)magcal_intake_progress(&cc->store, &p);
    (void)memset(out, 0, sizeof *out);
    out->state = (magcal_cont_state_t)cc->state;
    if (p.centre_source == MAGCAL_INTAKE_CENTRE_NONE) {
        /* bins around the raw origin say nothing about the ring's coverage (a start-up spike
         * alone spans half of them): nothing is covered until the store has a centre */
        out->coverage_deg = 0.0f;
        out->missing_start_deg = 0.0f;
        out->missing_width_deg = 360.0f;
    } else {
        out->coverage_deg = p.coverage_deg;
        out->missing_start_deg = p.missing_start_deg;
        out->missing_width_deg = p.missing_width_deg;
    }
    out->completion_pct = p.completion_pct;
    out->stored = p.stored;
    out->new_since_solve = (cc->store.ctr.added + cc->store.ctr.replaced) - cc->stored_at_solve;
    out->generation = cc->generation;
    out->solves = cc->solves;
    out->changes = cc->changes;
    out->dropped = cc->dropped;
    out->episode_open = cc->episode_open;
    return MAGCAL_OK;
}

magcal_status_t magcal_cont_status(const magcal_cont_t *cc)
{
    return magcal_cont_ok(cc) ? cc->last_status : MAGCAL_ERR_NOT_INITIALISED;
}

magcal_status_t magcal_cont_heading(const magcal_cont_t *cc, const magcal_vec3_t *m, float declination_deg,
                                    magcal_cont_heading_t *out)
{
    magcal_status_t st;
    magcal_cont_judge_t j;
    const magcal_cal2d_t id = MAGCAL_CAL2D_IDENTITY;
    float mag_deg;
    magcal_vec2_t raw;
    if (cc == NULL || out == NULL || m == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (!magcal_cont_ok(cc)) {
        return MAGCAL_ERR_NOT_INITIALISED;
    }
    raw.x = m->x;
    raw.y = m->y;
    st = magcal_heading_compute(&id, raw, declination_deg, &mag_deg, &out->raw_heading_deg);
    if (st != MAGCAL_OK) {
        return st;
    }
    out->generation = cc->generation;
    out->radius_rel = NAN;
    if (cc->has_cal == 0u) {
        out->heading_deg = out->raw_heading_deg;
        out->trust = MAGCAL_TRUST_UNCALIBRATED;
        return MAGCAL_OK;
    }
    st = magcal_heading_compute(&cc->cal, raw, declination_deg, &mag_deg, &out->heading_deg);
    if (st != MAGCAL_OK) {
        return st;
    }
    (void)magcal_cont_judge(cc, m, &j);
    out->radius_rel = j.rel;
    if (cc->state == (uint8_t)MAGCAL_CONT_RELEARNING) {
        out->trust = MAGCAL_TRUST_CHANGED;
    } else if (j.mismatch != 0u || magcal_cont_episode_wide(cc) != 0) {
        out->trust = MAGCAL_TRUST_DISTURBED;
    } else {
        out->trust = cc->cal_coarse != 0u ? MAGCAL_TRUST_COARSE : MAGCAL_TRUST_OK;
    }
    return MAGCAL_OK;
}
