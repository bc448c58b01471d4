/*
 * Continuous 3-D calibrator, lifecycle: init, the ISR-safe push ring, progress, heading with
 * trust. The ring is single-producer (push) / single-consumer (step, c3_step.c): push writes the
 * slot, a barrier, then head; the consumer reads the slot, a barrier, then writes tail.
 */
#include "magcal/continuous3.h"

#include <math.h>
#include <string.h>

#include "c3_internal.h"
#include "magcal/config.h"
#include "magcal/tilt.h"
#include "magcal_internal.h"

#if MAGCAL_CFG_ENABLE_3D /* whole file: config.h feature switch (the 3-D loop needs the ellipsoid fit) */

int magcal_c3_ok(const magcal_cont3_t *cc) { return cc != NULL && cc->magic == MAGCAL_CONT3_MAGIC; }

static magcal_status_t c3_check_cfg(const magcal_cont3_cfg_t *c)
{
    if (c->intake.dims != 3u || c->drain_per_step < 1u || c->step_budget < 1u || c->min_new < 1u ||
        c->min_samples < 10u ||
        c->change_cells < 1u || c->change_cells > MAGCAL_CONT3_CELLS) {
        return MAGCAL_ERR_ARG;
    }
    if (!magcal_isfinite_f(c->solve_fill) || !magcal_isfinite_f(c->age_ms) || !magcal_isfinite_f(c->adopt_margin) ||
        !magcal_isfinite_f(c->mismatch_k) || !magcal_isfinite_f(c->mismatch_min_rel)) {
        return MAGCAL_ERR_NONFINITE;
    }
    if (!(c->solve_fill > 0.0f) || c->solve_fill > 1.0f || !(c->age_ms > 0.0f) || !(c->adopt_margin >= 1.0f) ||
        !(c->mismatch_k > 0.0f) || !(c->mismatch_min_rel > 0.0f)) {
        return MAGCAL_ERR_ARG;
    }
    return MAGCAL_OK;
}

float magcal_c3_raw_radius(const magcal_ellipsoid_cal_t *c)
{
    const float (*g)[3] = c->g;
    const float det = g[0][0] * (g[1][1] * g[2][2] - g[1][2] * g[2][1]) -
                      g[0][1] * (g[1][0] * g[2][2] - g[1][2] * g[2][0]) +
                      g[0][2] * (g[1][0] * g[2][1] - g[1][1] * g[2][0]);
    if (!(det > 0.0f) || !magcal_isfinite_f(det) || !(c->field > 0.0f)) {
        return 0.0f;
    }
    return c->field / cbrtf(det);
}

static magcal_status_t c3_check_cal(const magcal_ellipsoid_cal_t *c)
{
    int i;
    int k;
    for (i = 0; i < 3; ++i) {
        for (k = 0; k < 3; ++k) {
            if (!magcal_isfinite_f(c->g[i][k])) {
                return MAGCAL_ERR_NONFINITE;
            }
        }
    }
    if (!magcal_isfinite_f(c->v.x) || !magcal_isfinite_f(c->v.y) || !magcal_isfinite_f(c->v.z) ||
        !magcal_isfinite_f(c->field)) {
        return MAGCAL_ERR_NONFINITE;
    }
    return magcal_c3_raw_radius(c) > 0.0f ? MAGCAL_OK : MAGCAL_ERR_ARG;
}

magcal_status_t magcal_cont3_init(magcal_cont3_t *cc, const magcal_cont3_cfg_t *cfg,
                                  const magcal_ellipsoid_cal_t *installed, magcal_intake_slot_t *slots,
                                  size_t n_slots, magcal_vec3_t *buf, void *work, size_t work_len)
{
    magcal_status_t st;
    if (cc == NULL || cfg == NULL || slots == NULL || buf == NULL || work == NULL) {
        return MAGCAL_ERR_NULL;
    }
    st = c3_check_cfg(cfg);
    if (st == MAGCAL_OK && installed != NULL) {
        st = c3_check_cal(installed);
    }
    if (st != MAGCAL_OK) {
        return st;
    }
    {
        /* a full store must fit the solve's density stage (magcal_ellipsoid_calibrate) */
        uint16_t nb = 0u;
        if (magcal_intake_bins(&cfg->intake, &nb) != MAGCAL_OK ||
            (size_t)nb * (size_t)cfg->intake.per_bin > (size_t)MAGCAL_MAX_SAMPLES) {
            return MAGCAL_ERR_ARG;
        }
    }
    if (magcal_misalign(work, 4u) != 0u) {
        return MAGCAL_ERR_ALIGNMENT; /* before the size, as magcal_calibrator_init */
    }
    if (n_slots > 65535u || work_len < MAGCAL_CONT3_WORKSPACE_LEN(n_slots)) {
        return MAGCAL_ERR_WORKSPACE;
    }
    (void)memset(cc, 0, sizeof *cc);
    st = magcal_intake_init(&cc->store, &cfg->intake, slots, n_slots); /* checks n_slots >= cells x per_bin */
    if (st != MAGCAL_OK) {
        return st;
    }
    cc->cfg = *cfg;
    cc->buf = buf;
    cc->slots = n_slots;
    cc->work = work;
    cc->work_len = work_len;
    cc->cand_spread = NAN;
    cc->inst_spread = NAN;
    cc->last_status = MAGCAL_OK;
    cc->state = (uint8_t)MAGCAL_CONT3_COLLECTING;
    cc->magic = MAGCAL_CONT3_MAGIC;
    if (installed != NULL) {
        magcal_c3_install(cc, installed, 0.0f);
    }
    return MAGCAL_OK;
}

magcal_status_t magcal_cont3_push(magcal_cont3_t *cc, const magcal_vec3_t *m, uint32_t t_ms)
{
    uint32_t h;
    if (cc == NULL || m == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (cc->magic != MAGCAL_CONT3_MAGIC) {
        return MAGCAL_ERR_NOT_INITIALISED;
    }
    h = cc->head;
    if (h - cc->tail >= MAGCAL_CONT3_RING) {
        cc->dropped = cc->dropped + 1u;
        return MAGCAL_ERR_BUFFER_FULL;
    }
    cc->ring[h % MAGCAL_CONT3_RING] = *m;
    cc->ring_t[h % MAGCAL_CONT3_RING] = t_ms;
    MAGCAL_CONT3_BARRIER();
    cc->head = h + 1u;
    return MAGCAL_OK;
}

magcal_status_t magcal_cont3_progress(const magcal_cont3_t *cc, magcal_cont3_progress_t *out)
{
    magcal_intake_progress_t p;
    if (cc == NULL || out == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (!magcal_c3_ok(cc)) {
        return MAGCAL_ERR_NOT_INITIALISED;
    }
    (void)magcal_intake_progress(&cc->store, &p);
    (void)memset(out, 0, sizeof *out);
    /* the coverage count that decides whether to solve is not a solve */
    out->state = (cc->stage != MAGCAL_C3_STAGE_NONE && cc->stage != MAGCAL_C3_STAGE_COUNT) ? MAGCAL_CONT3_SOLVING
                                                                                        : (magcal_cont3_state_t)cc->state;
    out->cells = p.bins;
    if (p.centre_source != MAGCAL_INTAKE_CENTRE_NONE) {
        /* cells around the raw origin say nothing about coverage: none until there is a centre */
        out->cells_filled = p.bins_filled;
        out->fill = p.fill_fraction;
        (void)magcal_intake_mask(&cc->store, out->mask, sizeof out->mask / sizeof out->mask[0]);
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

magcal_status_t magcal_cont3_status(const magcal_cont3_t *cc)
{
    return magcal_c3_ok(cc) ? cc->last_status : MAGCAL_ERR_NOT_INITIALISED;
}

/* Heading of field f: tilt compensated with accel (inclination into *incl), else level. */
static magcal_status_t c3_heading_of(const magcal_vec3_t *f, const magcal_vec3_t *accel, float *psi, float *incl)
{
    if (accel != NULL) {
        const magcal_tilt_cfg_t tcfg = MAGCAL_TILT_CFG_DEFAULT;
        magcal_tilt_t att;
        magcal_vec3_t lv;
        magcal_status_t st = magcal_tilt_heading(&tcfg, accel, f, psi, &att);
        if (st == MAGCAL_OK && incl != NULL && magcal_tilt_level_field(&att, f, &lv) == MAGCAL_OK) {
            *incl = MAGCAL_DEG_PER_RAD_F * atan2f(-lv.z, sqrtf(lv.x * lv.x + lv.y * lv.y));
        }
        return st;
    }
    {
        magcal_vec2_t h2;
        h2.x = f->x;
        h2.y = f->y;
        return magcal_heading_from_field(h2, psi);
    }
}

magcal_status_t magcal_cont3_heading(const magcal_cont3_t *cc, const magcal_vec3_t *m,
                                     const magcal_vec3_t *accel_g, float declination_deg,
                                     magcal_cont3_heading_t *out)
{
    magcal_status_t st;
    magcal_c3_judge_t j;
    magcal_cont3_heading_t r;
    magcal_vec3_t h;
    if (cc == NULL || out == NULL || m == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (!magcal_c3_ok(cc)) {
        return MAGCAL_ERR_NOT_INITIALISED;
    }
    if (!magcal_isfinite_f(declination_deg) || !magcal_isfinite_f(m->x) || !magcal_isfinite_f(m->y) ||
        !magcal_isfinite_f(m->z)) {
        return MAGCAL_ERR_NONFINITE;
    }
    if (fabsf(declination_deg) > 180.0f) {
        return MAGCAL_ERR_ARG;
    }
    r.field_rel = NAN;
    r.inclination_deg = NAN;
    r.generation = cc->generation;
    st = c3_heading_of(m, accel_g, &r.raw_heading_deg, NULL);
    if (st == MAGCAL_OK) {
        r.raw_heading_deg = magcal_wrap360_deg(r.raw_heading_deg + declination_deg);
    } else if (cc->has_cal != 0u && st == MAGCAL_ERR_ZERO_FIELD) {
        r.raw_heading_deg = NAN; /* the raw field (hard iron included) may point straight up */
    } else {
        return st; /* the attitude gates, or no field at all */
    }
    if (cc->has_cal == 0u) {
        r.heading_deg = r.raw_heading_deg;
        r.trust = MAGCAL_TRUST_UNCALIBRATED;
        *out = r;
        return MAGCAL_OK;
    }
    st = magcal_ellipsoid_apply(&cc->cal, m, &h);
    if (st == MAGCAL_OK) {
        st = c3_heading_of(&h, accel_g, &r.heading_deg, &r.inclination_deg);
    }
    if (st != MAGCAL_OK) {
        return st;
    }
    r.heading_deg = magcal_wrap360_deg(r.heading_deg + declination_deg);
    (void)magcal_c3_judge(cc, m, &j);
    r.field_rel = j.rel;
    if (cc->state == (uint8_t)MAGCAL_CONT3_RELEARNING) {
        r.trust = MAGCAL_TRUST_CHANGED;
    } else if (j.mismatch != 0u || magcal_c3_episode_wide(cc) != 0) {
        r.trust = MAGCAL_TRUST_DISTURBED;
    } else {
        r.trust = MAGCAL_TRUST_OK;
    }
    *out = r;
    return MAGCAL_OK;
}

#endif /* MAGCAL_CFG_ENABLE_3D */
