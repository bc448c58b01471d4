/*
 * Continuous calibrator, lifecycle: init, the ISR-safe push ring (push_g: with the gravity level
 * test that tags each sample LEVEL / TILTED for the store), progress, heading with trust.
 * The ring is single-producer (push) / single-consumer (step, cont_step.c): push writes the slot,
 * a barrier, then head; the consumer reads the slot, a barrier, then writes tail.
 */
#include "magcal/continuous.h"

#include <math.h>
#include <string.h>

#include "../intake/intake_internal.h"
#include "cont_internal.h"
#include "cont_judge_internal.h"
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
        !magcal_isfinite_f(c->coarse_max_err_deg) || !magcal_isfinite_f(c->disturb_onset)) {
        return MAGCAL_ERR_NONFINITE;
    }
    if (c->coarse_coverage_deg < 0.0f || c->coarse_coverage_deg > 360.0f ||
        !(c->coarse_max_err_deg > 0.0f) || !magcal_isfinite_f(c->tilt_comp_deg) ||
        !(c->tilt_comp_deg >= 0.0f && c->tilt_comp_deg <= 30.0f)) {
        return MAGCAL_ERR_ARG;
    }
    if (c->solve_coverage_deg < 0.0f || c->solve_coverage_deg > 360.0f || !(c->age_ms > 0.0f) ||
        !(c->mismatch_k > 0.0f) || !(c->mismatch_min_rel > 0.0f) || !(c->disturb_k > 0.0f) ||
        !(c->disturb_onset > 0.0f && c->disturb_onset <= 1.0f) ||
        c->disturb_tau_ms < 1u) {
        return MAGCAL_ERR_ARG;
    }
    if (!magcal_isfinite_f(c->offset_coverage_deg) || !magcal_isfinite_f(c->offset_max_err_deg) ||
        !magcal_isfinite_f(c->offset_sigma_ratio)) {
        return MAGCAL_ERR_NONFINITE;
    }
    if (c->offset_coverage_deg < 0.0f || c->offset_coverage_deg > 360.0f || !(c->offset_max_err_deg > 0.0f) ||
        !(c->offset_sigma_ratio >= 1.0f)) {
        return MAGCAL_ERR_ARG;
    }
#if !MAGCAL_CFG_ENABLE_COARSE
    if (c->coarse_coverage_deg > 0.0f) {
        return MAGCAL_ERR_ARG; /* the coarse stage is compiled out (config.h): a solve at its coverage would fail */
    }
#endif
    if (!magcal_isfinite_f(c->shift_rel) || !magcal_isfinite_f(c->tilt_model_deg) ||
        !magcal_isfinite_f(c->tilt_trust_deg) || !magcal_isfinite_f(c->rate_trust_deg) ||
        !magcal_isfinite_f(c->ok_max_err_deg)) {
        return MAGCAL_ERR_NONFINITE;
    }
    if (!(c->shift_rel == 0.0f || (c->shift_rel >= 0.15f && c->shift_rel <= 2.0f)) || c->shift_hold_ms < 1u ||
        c->continuity > 1u || c->gyro_gravity > 1u || c->tilt_model_deg < 0.0f || c->tilt_trust_deg < 0.0f || c->rate_trust_deg < 0.0f ||
        c->ok_max_err_deg < 0.0f) {
        return MAGCAL_ERR_ARG;
    }
    return magcal_cont_arc_cfg_check(c);
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
    cc->store.ref_free = 1u; /* the survey drops a ring fit locked on a small circle (sweep.c) */
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
    cc->adopted_tilt = 0.0f;
    cc->last_status = MAGCAL_OK;
    cc->state = (uint8_t)MAGCAL_CONT_COLLECTING;
    if (cfg->tilt_comp_deg > 0.0f) {
        const float t = tanf(cfg->tilt_comp_deg * (MAGCAL_PI_F / 180.0f));
        cc->tc_tan2 = t * t; /* push_g's compensation test needs no trigonometry */
    }
    cc->rj_sgn = -1; /* the gyro heading check's sign in the contract's frame (cont_rate.c) */
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

/* Queue one sample with its tilt code (magcal_intake_tilt_t) and push_g's tilt of it (x, y; z = 1:
 * known, 0.5: the one held from before, the gravity of now giving none; NULL: unknown): the drain
 * un-levels with a known one and keeps the store's mean tilt. */
static magcal_status_t cont_enqueue(magcal_cont_t *cc, const magcal_vec3_t *m, uint32_t t_ms, uint8_t tilt,
                                    const magcal_vec3_t *tl)
{
    const uint32_t h = cc->head;
    if (h - cc->tail >= MAGCAL_CONT_RING) {
        cc->dropped = cc->dropped + 1u;
        return MAGCAL_ERR_BUFFER_FULL;
    }
    cc->ring[h % MAGCAL_CONT_RING] = *m;
    if (tl != NULL) {
        cc->ring_tl[h % MAGCAL_CONT_RING] = *tl;
    } else {
        cc->ring_tl[h % MAGCAL_CONT_RING].x = 0.0f;
        cc->ring_tl[h % MAGCAL_CONT_RING].y = 0.0f;
        cc->ring_tl[h % MAGCAL_CONT_RING].z = 0.0f;
    }
    cc->ring_t[h % MAGCAL_CONT_RING] = t_ms;
    cc->ring_tilt[h % MAGCAL_CONT_RING] = tilt;
    if (cc->gy_pend != 0u) {
        cc->ring_dy[h % MAGCAL_CONT_RING] = cc->gy_acc;
        cc->gy_acc = 0.0f;
    } else {
        cc->ring_dy[h % MAGCAL_CONT_RING] = NAN;
        cc->gy_on = 0u; /* a sample without a rate: the next push_imu starts the rotation again */
    }
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
    return cont_enqueue(cc, m, t_ms, (uint8_t)MAGCAL_INTAKE_TILT_UNKNOWN, NULL);
}

/* The gravity level test of push_g (continuous.h): O(1), no trigonometry. The gravity vector is
 * smoothed first (exponential, time constant MAGCAL_CONT_G_SMOOTH_MS of the stamps: vibration and
 * sensor noise), then the smoothed vector is tested; the running level of its |g|^2 is a slower
 * exponential average (MAGCAL_CONT_G_TAU_MS). A gap in the stamps counts at most one constant. */
float magcal_cont_ema_w(uint32_t dt_ms, uint32_t tau_ms)
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
        magcal_cont_ema3(&cc->g_s, g, magcal_cont_ema_w(t_ms - cc->g_t, MAGCAL_CONT_G_SMOOTH_MS)); /* wrapping stamps */
    }
    h2 = cc->g_s.x * cc->g_s.x + cc->g_s.y * cc->g_s.y;
    v2 = cc->g_s.z * cc->g_s.z;
    n2 = h2 + v2;
    if (!(cc->g_level2 > 0.0f)) {
        cc->g_level2 = n2;
    } else {
        cc->g_level2 += (n2 - cc->g_level2) * magcal_cont_ema_w(t_ms - cc->g_t, MAGCAL_CONT_G_TAU_MS);
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

/* ---- Tilt compensation (continuous.h "Tilt compensation"). A pitch p (roll r) moves the body's
 * horizontal field by Z (sin r, sin p) to first order (Z: the body's vertical field), i.e. by
 * Z g_xy / |g| with g the specific force in body axes: in raw units by k t, t = g_xy / g_z and
 * k = Z times the raw scale. A tilt along the field changes the sample's distance d from the
 * store's centre by k q, q = t . (radial direction); across it, the heading (the error the store
 * must not take). k is the within-sector regression of d on q: in each 10-degree heading sector
 * around the store's centre d = a_sector + k q (the sector's own intercept takes the ellipse's
 * radius there), so every sample of a hill driven at a steady heading counts, not only pairs:
 * k = sum of the sectors' co-variations of (q, d) over the sum of their variations of q, kept as
 * running (Welford) means per sector and sums over all. A sample enters only when its tilt moved
 * by TC_STEP_Q since the last one its sector took (parked rows, a slow hill and circles on one
 * slope are not counted as independent samples); the sectors' means are dropped at a declared change (the hard iron
 * moved) and when the store's centre moves (its distances move with it), the sums stay. */
#define TC_STEP_Q 0.005f     /* the tilt a sector's next sample must have moved by (0.3 deg) */
#define TC_MAX_K 3.0f        /* |k| <= 3 R (inclination < 72 deg); a sample beyond it is refused */
#define TC_MIN_PAIRS 24u     /* samples in the sums (beyond each sector's first) before k is used */
#define TC_GATE_REL 0.2f     /* a sample's gate around the estimate: relative part */
#define TC_GATE_ABS 0.05f    /* and absolute part, x R (noise, the ellipse within a sector) */
#define TC_MAX_SE 0.12f      /* k's standard error must be <= this x R (0.7 deg of heading at 6 deg of pitch) */
#define TC_RING_LO 0.7f      /* a sample on the ring (intake progress.c) */
#define TC_RING_HI 1.4f
#define TC_RHO_LO 0.5f       /* the share of q that raw z confirms as tilt: at least this (a vehicle's */
#define TC_RHO_HI 2.0f       /* accelerations read as tilt lower it) and at most this (z's own scale) */
#define TC_KL_HOLD 0.05f     /* the levelling's k follows the estimate when it moved by this share */
#define TC_Z_REACH 1.5f      /* raw z moves by at most this x R |q| from the sector's mean (a real tilt: R |q|) */
#define TC_HOLD_MS 1000u     /* the held tilt (cc->tc_h) is the one known 1..2 s before the last */
#define TC_NB_MAX 4096u      /* a sector's count stops here: its means then follow the newest samples */

/* 1 when the smoothed gravity of the last push_g is steady (|g|^2 within cfg.intake.g_band_rel of
 * its level), its roll within cfg.intake.tilt_limit_deg and its pitch within cfg.tilt_comp_deg:
 * then *tx, *ty = g_x / g_z, g_y / g_z (the tilt the compensation removes). Turns (centripetal
 * acceleration reads as roll) and hard braking or acceleration are never levelled. */
static int cont_tc_tilt(const magcal_cont_t *cc, float *tx, float *ty)
{
    const magcal_vec3_t *gs = &cc->g_s;
    const float v2 = gs->z * gs->z;
    const float n2 = gs->x * gs->x + gs->y * gs->y + v2;
    if (!(cc->tc_tan2 > 0.0f) || !(cc->g_level2 > 0.0f) || !(v2 > 0.0f) ||
        !(fabsf(n2 - cc->g_level2) <= cc->cfg.intake.g_band_rel * cc->g_level2) ||
        !(gs->x * gs->x <= cc->store.tilt_tan2 * v2) || !(gs->y * gs->y <= cc->tc_tan2 * v2)) {
        return 0;
    }
    *tx = gs->x / gs->z;
    *ty = gs->y / gs->z;
    return 1;
}

/* Sector b's next sample (q, d) into its means and the sums, when it agrees with the estimate:
 * |e_d - k e_q| <= TC_GATE_REL |k e_q| + TC_GATE_ABS R around the sector's means (a transient or
 * a glitch is refused); until k is valid only |e_d| <= TC_MAX_K R |e_q| + TC_GATE_ABS R (no
 * inclination beyond 72 deg); raw z within TC_Z_REACH R |e_q| + TC_GATE_ABS R of the sector's
 * mean (a disturbance arriving with a change of tilt). Then k and its validity; the sample's
 * tilt (cc->tc_t) becomes the sector's last. */
static MAGCAL_NOINLINE void cont_tc_enter(magcal_cont_t *cc, uint32_t b, float q, float d, float z, float r)
{
    const float eq = q - cc->tc_mq[b];
    const float ed = d - cc->tc_md[b];
    const float ez = z - cc->tc_mz[b];
    const uint32_t nb = cc->tc_nb[b];
    float res;
    float band;
    float n;
    float w;
    float kn;
    float var;
    float rho;
    if (nb == 0u) {
        cc->tc_mq[b] = q; /* the sector's first sample: its means */
        cc->tc_md[b] = d;
        cc->tc_mz[b] = z;
        cc->tc_lt[b][0] = cc->tc_t.x;
        cc->tc_lt[b][1] = cc->tc_t.y;
        cc->tc_nb[b] = 1u;
        return;
    }
    res = ed; /* within |k| <= 3 R until k is valid, then around k (a wrong early estimate gated
                 the truth out for good: -15 for -44, tests/test_continuous.c) */
    band = TC_MAX_K * r * fabsf(eq);
    if (cc->tc_ok != 0u) {
        res = ed - cc->tc_k * eq;
        band = TC_GATE_REL * fabsf(cc->tc_k * eq);
    }
    if (!(fabsf(res) <= band + TC_GATE_ABS * r) || !(fabsf(ez) <= TC_Z_REACH * r * fabsf(eq) + TC_GATE_ABS * r)) {
        return;
    }
    n = (float)nb + 1.0f;
    w = (float)nb / n; /* Welford: the co-variation about the updated means */
    cc->tc_mq[b] += eq / n;
    cc->tc_md[b] += ed / n;
    cc->tc_mz[b] += ez / n;
    cc->tc_lt[b][0] = cc->tc_t.x;
    cc->tc_lt[b][1] = cc->tc_t.y;
    if (nb < TC_NB_MAX) {
        cc->tc_nb[b]++;
    }
    cc->tc_s[0] += w * eq * eq;
    cc->tc_s[1] += w * eq * ed;
    cc->tc_s[2] += w * ed * ed;
    cc->tc_s[3] += w * eq * ez;
    cc->tc_n++;
    kn = cc->tc_s[1] / cc->tc_s[0];
    var = (cc->tc_n > 1u) ? (cc->tc_s[2] - kn * cc->tc_s[1]) / ((float)cc->tc_n - 1.0f) : -1.0f;
    /* the tilt the accelerometer reports is the magnetometer's too: a real tilt along the field
     * moves raw z by -R q (z = Z - t . h), an acceleration read as tilt moves nothing; the slope
     * of z on q over -R is the share of q's variation that is real tilt (1 +- the z axis's scale) */
    rho = -cc->tc_s[3] / (r * cc->tc_s[0]);
    cc->tc_rho = rho;
    {
        const uint8_t est = (cc->tc_n >= TC_MIN_PAIRS && var >= 0.0f &&
                             var <= TC_MAX_SE * TC_MAX_SE * r * r * cc->tc_s[0] && fabsf(kn) <= TC_MAX_K * r)
                                ? 1u
                                : 0u;
        if (est != 0u) {
            cc->tc_rst = 0u; /* the stream's own estimate decides from now on */
        }
        if (cc->tc_rst != 0u) {
            return; /* the restored k stays in force (tc_ok, tc_k) until then */
        }
        cc->tc_k = kn;
        cc->tc_ok = (est != 0u && rho >= TC_RHO_LO && rho <= TC_RHO_HI) ? 1u : 0u;
        /* a determined regression whose tilt raw z does not confirm: the accelerometer's tilt is
         * mostly the vehicle's acceleration (the tilt in the trust then predicts nothing) */
        cc->tc_acc = (est != 0u && rho < TC_RHO_LO) ? 1u : 0u;
    }
}

/* One sample into k's regression (raw m, tilt tx, ty): its heading sector (36 around the store's
 * centre) and, when its tilt moved by TC_STEP_Q since the sector's last sample, the sums. Every
 * sector's means are dropped at a declared change and when the store's centre moves. The store's
 * centre and radius are read (a torn read while step recentres misplaces one sample). */
static MAGCAL_NOINLINE void cont_tc_learn(magcal_cont_t *cc, const magcal_vec3_t *m, float tx, float ty)
{
    const float r = cc->store.radius;
    float ux;
    float uy;
    float d;
    float q;
    float a;
    uint32_t b;
    if (cc->store.centre_source == (uint8_t)MAGCAL_INTAKE_CENTRE_NONE || !(r > 0.0f) || cc->dist_flag != 0u) {
        /* no centre yet, or the transient judge has flagged the stream (a sample of a 3-s
         * disturbance across the field opened a sector's means 4 % off the ring and moved k
         * by 5 %: 1 % of radius at 5 deg of pitch, levelled samples then flagged for seconds) */
        return;
    }
    if (cc->tc_changes != cc->changes || cc->tc_gen != cc->store.gen) {
        /* a declared change (the hard iron moved) or a new centre (the distances moved) */
        (void)memset(cc->tc_nb, 0, sizeof cc->tc_nb);
        cc->tc_changes = cc->changes;
        cc->tc_gen = cc->store.gen;
    }
    ux = m->x - cc->store.centre.x;
    uy = m->y - cc->store.centre.y;
    d = sqrtf(ux * ux + uy * uy);
    if (!(d >= TC_RING_LO * r && d <= TC_RING_HI * r)) {
        return; /* off the ring (a glitch, a transient) */
    }
    q = (tx * ux + ty * uy) / d;
    a = atan2f(-ux, uy) * (1.0f / (2.0f * MAGCAL_PI_F)); /* turns, (-0.5, 0.5] */
    if (a < 0.0f) {
        a += 1.0f;
    }
    b = (uint32_t)(a * (float)MAGCAL_CONT_TC_BINS);
    b = (b >= MAGCAL_CONT_TC_BINS) ? MAGCAL_CONT_TC_BINS - 1u : b;
    {
        /* the tilt moved, not only q: on one slope q also moves with the heading within the
         * sector, and circles on it (d moving with the ellipse, q with the heading) taught k
         * the ellipse's slope (-15 and -28 for -44 in tests/test_continuous.c) */
        const float dtx = cc->tc_t.x - cc->tc_lt[b][0]; /* the tilt from cc (push_g set it): */
        const float dty = cc->tc_t.y - cc->tc_lt[b][1]; /* tx, ty need not live across atan2f */
        if (cc->tc_nb[b] == 0u || dtx * dtx + dty * dty >= TC_STEP_Q * TC_STEP_Q) {
            cont_tc_enter(cc, b, q, d, m->z, r);
        }
    }
}

/* The levelled sample of m under the last push_g's gravity (into *out), 1 when compensated. */
static int cont_tc_level(const magcal_cont_t *cc, const magcal_vec3_t *m, magcal_vec3_t *out)
{
    float tx = 0.0f;
    float ty = 0.0f;
    if (cc->tc_on == 0u || cc->tc_ok == 0u || cont_tc_tilt(cc, &tx, &ty) == 0) {
        return 0;
    }
    /* a pitch p turns the horizontal field h (raw, from the store's centre) into h cos p + Z sin p
     * and z into Z cos p - h sin p; with t = tan p the level h = (h' - k sin p) / cos p, to third
     * order h' - k t + (h' . t) t / 2 (the first-order h' - k t alone leaves the cos p: 0.55 % of
     * the radius at 6 deg, above the transient judge's 0.4 % floor on a levelled store), and the
     * level z = (z' + t . h') cos p: a levelled sample is level in z as well, so the store's level
     * model of raw z and the judge's z channel see a level sample */
    {
        const float ht = tx * (m->x - cc->store.centre.x) + ty * (m->y - cc->store.centre.y);
        out->x = m->x - cc->tc_kl * tx + 0.5f * ht * tx;
        out->y = m->y - cc->tc_kl * ty + 0.5f * ht * ty;
        out->z = (m->z + ht) * (1.0f - 0.5f * (tx * tx + ty * ty));
    }
    return 1;
}

/* Tilt in the trust (continuous.h): the heading error the last push_g's tilt predicts for a
 * heading under the installed calibration, in degrees: |k| |t - t_cal| / R rad (the raw x, y
 * moved by k (t - t_cal) against the field's horizontal radius R), where t is the sample's tilt
 * (0 when levelled) and t_cal the calibration's fit tilt (0 when fitted on levelled samples or
 * levelled since, else the mean tilt of its store: cc->cal_tx, cal_ty; then the spread of that
 * tilt, cc->cal_ts, adds in quadrature: a store filled at a different tilt per sector bends the
 * ellipse, an error no current tilt undoes; 0 too when unknown: a calibration restored without
 * its tilt state is taken as a level one, whose unlevelled heading on a slope is off by the
 * slope's leak: legacy-record restores kept up to 11,033 OK rows more than 5 deg off, 10.3 at
 * worst, while it counted nothing). k is the compensation's
 * when valid, else TC_K_UNKNOWN R (an inclination of 68 deg: most of Europe and North America
 * lie below it; 1.5 R under-predicted the generated drives' 64 deg, k / R = 2.1, and left 4.9-deg
 * errors OK on 30-min seed 7). When the accelerometer's tilt is mostly the vehicle's
 * acceleration (a determined regression with rho below TC_RHO_LO: tc_acc), its tilt still counts
 * (the tilt a road and a car's braking show together: ignoring it left 30-min --dyn-accel drives
 * OK 9 to 38 deg off) or, when the gravity of now gives none (unsteady, beyond the limits:
 * hard braking, a turn), the last tilt known (cc->tc_t); and the tilt held from 1..2 s before
 * (cc->tc_h) when it is further from the calibration's. 0 when nothing is known: no
 * gravity yet, or the gravity of now unsteady or beyond the limits while the regression has not
 * shown acceleration (a turn's centripetal roll: the last tilt known there took every OK of
 * vn100_car_circles_a). */
#define TC_K_UNKNOWN 2.5f
static float cont_tilt_err_deg(const magcal_cont_t *cc, uint8_t levelled)
{
    float tx = 0.0f;
    float ty = 0.0f;
    float k;
    float dx;
    float dy;
    float s2 = 0.0f;
    float ox = 0.0f;
    float oy = 0.0f;
    uint8_t lv = levelled;
    if (cc->has_cal == 0u || !(cc->cal_raw_radius > 0.0f)) {
        return 0.0f;
    }
    if (cont_tc_tilt(cc, &tx, &ty) == 0) {
        if (magcal_cont_no_gravity(cc) != 0) {
            /* never a gravity (push alone): the slopes raw z measured (cont_slope.c) */
            return magcal_cont_slope_err_deg(cc, TC_K_UNKNOWN);
        }
        if (cc->tc_acc == 0u || !(cc->tc_h.z > 0.0f)) {
            return 0.0f;
        }
        tx = cc->tc_t.x; /* the last tilt known */
        ty = cc->tc_t.y;
        lv = 0u;
    }
    if (cc->cal_lv == 0u && cc->cal_conv == 0u && cc->cal_tk != 0u) {
        ox = cc->cal_tx; /* the fit tilt, with its spread */
        oy = cc->cal_ty;
        s2 = cc->cal_ts * cc->cal_ts;
    }
    dx = ((lv != 0u) ? 0.0f : tx) - ox;
    dy = ((lv != 0u) ? 0.0f : ty) - oy;
    if (cc->tc_acc != 0u && cc->tc_h.z > 0.0f) {
        /* the accelerometer's tilt is mostly acceleration: the tilt held from 1..2 s before counts
         * too, whichever is further from the calibration's (a road's tilt stays, a braking's
         * does not; the tilt of now alone let one row of a braking on a hill OK 19 deg off on
         * --dyn-accel seed 7) */
        const float ex = cc->tc_h.x - ox;
        const float ey = cc->tc_h.y - oy;
        if (lv == 0u && ex * ex + ey * ey > dx * dx + dy * dy) {
            dx = ex;
            dy = ey;
        }
    }
    k = (cc->tc_ok != 0u) ? fabsf(cc->tc_k) : TC_K_UNKNOWN * cc->cal_raw_radius;
    return k * sqrtf(dx * dx + dy * dy + s2) / cc->cal_raw_radius * MAGCAL_DEG_PER_RAD_F;
}

/* The tilt in the trust with the OK tolerance ("OK tolerance", "Tilt in the trust"): 1 when the
 * tilt's predicted heading error is over cfg.tilt_trust_deg, or, while the tolerance is on, when
 * it and the calibration's own estimate (adopted_err; none for a restored one) add up to more
 * than CONT_OK_SUM x cfg.ok_max_err_deg (an estimate over the tolerance is COARSE whatever the
 * tilt; NaN compares false). Each within its own 3 deg, the two together left headings OK
 * 7 deg off: 30-min seed 20, a calibration adopted at an estimate of 2.9 deg whose OK rows were
 * those where the tilt predicted just under 3 deg (39 of 150 beyond 5 deg, with the sweep held to
 * 2 steps per sample during solves; 2,178 of 3,661 in another variant). */
#define CONT_OK_SUM 1.2f
static int cont_tilt_over(const magcal_cont_t *cc, uint8_t levelled)
{
    const float te = cont_tilt_err_deg(cc, levelled);
    return (te > cc->cfg.tilt_trust_deg ||
            (cc->cfg.ok_max_err_deg > 0.0f && cc->adopted_err <= cc->cfg.ok_max_err_deg &&
             cc->adopted_err + te > CONT_OK_SUM * cc->cfg.ok_max_err_deg))
               ? 1
               : 0;
}

magcal_status_t magcal_cont_push_g(magcal_cont_t *cc, const magcal_vec3_t *m, const magcal_vec3_t *g,
                                   uint32_t t_ms)
{
    uint8_t code;
    float tx = 0.0f;
    float ty = 0.0f;
    if (cc == NULL || m == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (cc->magic != MAGCAL_CONT_MAGIC) {
        return MAGCAL_ERR_NOT_INITIALISED;
    }
    code = cont_tilt_of(cc, g, t_ms);
    if (code != (uint8_t)MAGCAL_INTAKE_TILT_UNKNOWN && magcal_isfinite_f(m->x) && magcal_isfinite_f(m->y) &&
        cont_tc_tilt(cc, &tx, &ty) != 0) {
        cc->tc_t.x = tx;
        cc->tc_t.y = ty;
        cc->tc_t.z = 1.0f;
        if (!(cc->tc_h.z > 0.0f) || t_ms - cc->tc_h_ms >= TC_HOLD_MS) {
            cc->tc_h.x = (cc->tc_h.z > 0.0f) ? cc->tc_hp[0] : tx;
            cc->tc_h.y = (cc->tc_h.z > 0.0f) ? cc->tc_hp[1] : ty;
            cc->tc_h.z = 0.5f;
            cc->tc_hp[0] = tx;
            cc->tc_hp[1] = ty;
            cc->tc_h_ms = t_ms;
        }
        if (cc->gy_pend == 0u || cc->cfg.gyro_gravity == 0u || cc->ga_lock == 0u || cc->ga_quiet != 0u) {
            /* under a locked gyro-carried gravity, k learns only from samples whose accelerometer is
             * within 0.3 deg of the estimate (cont_grav.c ga_quiet): a turn's or a braking's
             * acceleration left inside the 1-deg window is a tilt the magnetometer does not see and
             * biases k towards 0 (30-min s7 --dyn-accel: -32 for -41, a levelled heading 6.5 deg
             * off on a 6-deg hill) */
            cont_tc_learn(cc, m, tx, ty);
        }
        if (cc->tc_ok != 0u && (cc->cal_lv == 0u || !(fabsf(cc->tc_k - cc->tc_kl) <= TC_KL_HOLD * fabsf(cc->tc_kl)))) {
            /* the levelling follows the estimate until a calibration fitted on levelled samples is
             * in force; then it moves only when the estimate left it by TC_KL_HOLD, so that the
             * samples it judges and stores stay levelled as that calibration's were (k moving by
             * 3 % on a straight over hills moved levelled samples by 0.5 % of R at 5 deg: 272 of
             * 4000 clean rows flagged in tests/test_cont_drive.c), but not at an early estimate
             * for good (60-min s3: held at -33 while k converged to -43) */
            cc->tc_kl = cc->tc_k;
        }
        if (cc->tc_ok != 0u) {
            /* an installed calibration fitted on unlevelled samples is levelled by its fit's tilt,
             * or judges un-levelled samples while the store refills levelled (cont_step.c) */
            cc->tc_on = 1u;
        }
        if (cont_tc_level(cc, m, &cc->tc_m) != 0) {
            cc->tc_levelled = cc->tc_levelled + 1u;
            return cont_enqueue(cc, &cc->tc_m, t_ms, MAGCAL_CONT_TILT_LEVELLED, &cc->tc_t);
        }
        return cont_enqueue(cc, m, t_ms, code, &cc->tc_t);
    }
    if (code != (uint8_t)MAGCAL_INTAKE_TILT_UNKNOWN && cc->tc_h.z > 0.0f) {
        return cont_enqueue(cc, m, t_ms, code, &cc->tc_h); /* cont_fit_tilt counts it; nothing levels with it */
    }
    return cont_enqueue(cc, m, t_ms, code, NULL);
}

magcal_status_t magcal_cont_push_imu(magcal_cont_t *cc, const magcal_vec3_t *m, const magcal_vec3_t *g,
                                     const magcal_vec3_t *w, uint32_t t_ms)
{
    magcal_status_t st;
    const magcal_vec3_t *gp = g;
    if (cc == NULL || m == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (cc->magic != MAGCAL_CONT_MAGIC) {
        return MAGCAL_ERR_NOT_INITIALISED;
    }
    if (w != NULL && magcal_isfinite_f(w->x) && magcal_isfinite_f(w->y) && magcal_isfinite_f(w->z)) {
        /* the rate about the up axis: along the smoothed gravity of push_g (z without one) */
        const float n2 = cc->g_s.x * cc->g_s.x + cc->g_s.y * cc->g_s.y + cc->g_s.z * cc->g_s.z;
        const float wv = MAGCAL_DEG_PER_RAD_F *
                         ((n2 > 0.0f) ? (w->x * cc->g_s.x + w->y * cc->g_s.y + w->z * cc->g_s.z) / sqrtf(n2) : w->z);
        const uint32_t dt = t_ms - cc->gy_t; /* wrapping stamps */
        const uint8_t valid = (uint8_t)((fabsf(wv) <= MAGCAL_CONT_RATE_MAX_DPS) ? 1u : 0u);
        if (valid != 0u && cc->gy_on != 0u && dt <= MAGCAL_CONT_RATE_GAP_MS && magcal_isfinite_f(cc->gy_acc)) {
            cc->gy_acc += 0.0005f * (wv + cc->gy_w) * (float)dt; /* trapezoid, deg */
        } else {
            cc->gy_acc = NAN; /* the rotation since the sample before is unknown */
        }
        cc->gy_w = wv;
        cc->gy_t = t_ms;
        cc->gy_on = valid; /* a rate beyond any gyro's range (or an overflow) is no rate */
        cc->gy_pend = 1u;
        if (cc->cfg.gyro_gravity != 0u && valid != 0u) {
            gp = magcal_cont_grav(cc, g, w, t_ms); /* the gyro-carried gravity where needed (cont_grav.c) */
        }
    }
    st = magcal_cont_push_g(cc, m, gp, t_ms);
    cc->gy_pend = 0u;
    return st;
}

magcal_status_t magcal_cont_tilt_state(const magcal_cont_t *cc, float *k, uint8_t *levelled)
{
    if (cc == NULL || k == NULL || levelled == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (cc->magic != MAGCAL_CONT_MAGIC) {
        return MAGCAL_ERR_NOT_INITIALISED;
    }
    *k = (cc->tc_ok != 0u) ? cc->tc_kl : 0.0f;
    *levelled = (cc->tc_ok != 0u && cc->has_cal != 0u && cc->cal_lv != 0u) ? 1u : 0u;
    return MAGCAL_OK;
}

magcal_status_t magcal_cont_restore_tilt(magcal_cont_t *cc, float k, uint8_t levelled)
{
    if (cc == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (cc->magic != MAGCAL_CONT_MAGIC) {
        return MAGCAL_ERR_NOT_INITIALISED;
    }
    if (cc->has_cal == 0u || !(cc->cal_raw_radius > 0.0f) || !(cc->tc_tan2 > 0.0f)) {
        return MAGCAL_ERR_STATE;
    }
    if (!magcal_isfinite_f(k)) {
        return MAGCAL_ERR_NONFINITE;
    }
    if (!(fabsf(k) > 0.0f && fabsf(k) <= TC_MAX_K * cc->cal_raw_radius) || levelled > 1u) {
        return MAGCAL_ERR_ARG;
    }
    cc->tc_k = k;
    cc->tc_kl = k;
    cc->tc_rst = 1u;
    cc->tc_ok = 1u;
    cc->tc_on = 1u;
    cc->cal_lv = levelled;
    return MAGCAL_OK;
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
    out->levelled = 0u;
    if (cc->has_cal == 0u) {
        out->heading_deg = out->raw_heading_deg;
        out->trust = MAGCAL_TRUST_UNCALIBRATED;
        return MAGCAL_OK;
    }
    {
        /* levelled under the last push_g's gravity when the compensation is on (the installed
         * calibration was then fitted on levelled samples): the heading and the judge's sample */
        magcal_vec3_t lm;
        const int lv = (cc->cal_lv != 0u || cc->cal_conv != 0u) ? cont_tc_level(cc, m, &lm) : 0;
        if (lv != 0) {
            raw.x = lm.x;
            raw.y = lm.y;
            if (cc->cal_lv == 0u) {
                /* a relevel of a calibration fitted on one slope (cal_conv): its centre is the
                 * level one moved by k t_cal, so the levelled sample moves by as much */
                raw.x += cc->tc_kl * cc->cal_tx;
                raw.y += cc->tc_kl * cc->cal_ty;
            }
        }
        out->levelled = (uint8_t)lv;
        st = magcal_heading_compute(&cc->cal, raw, declination_deg, &mag_deg, &out->heading_deg);
        if (st != MAGCAL_OK) {
            return st;
        }
        if (lv != 0 && cc->cal_lv == 0u) {
            /* a relevel's (cal_conv): judged as the heading sees it, by the radius (the judge's
             * model is the unlevelled store's, its u terms the hills'); cont_step.c the same */
            lm.x = raw.x;
            lm.y = raw.y;
        }
        (void)magcal_cont_judge(cc, (lv != 0) ? &lm : m, (lv != 0 && cc->cal_lv == 0u) ? 1 : 0, &j);
        /* and by the transient judge with this sample too (the drain is a row or more behind) */
        if (magcal_cont_transient_peek(cc, &j) != 0u || cc->rj_flag != 0u) {
            j.mismatch = 1u; /* or the gyro's check (cont_rate.c) */
        }
    }
    out->radius_rel = j.rel;
    if (cc->state == (uint8_t)MAGCAL_CONT_RELEARNING) {
        out->trust = MAGCAL_TRUST_CHANGED;
    } else if (j.mismatch != 0u || magcal_cont_episode_wide(cc) != 0 || magcal_intake_saturated(&cc->cfg.intake, m) != 0 ||
               (cc->episode_open != 0u && cc->mis_ms >= MAGCAL_CONT_EPISODE_TRUST_MS)) {
        /* an episode with more mismatch than a transient lasts (evidence of a change under way)
         * holds every heading, also the samples that cross the old ring by chance (30-min seed
         * 24: OK rows up to 23.6 deg between a hard-iron step and its declaration) */
        out->trust = MAGCAL_TRUST_DISTURBED;
    } else if (cc->cfg.tilt_trust_deg > 0.0f && cont_tilt_over(cc, out->levelled) != 0) {
        out->trust = MAGCAL_TRUST_TILTED;
    } else {
        /* a full calibration whose error estimate is above the OK tolerance ("OK tolerance"): a
         * restored one has none (NaN) */
        if (cc->cal_coarse != 0u || (cc->cfg.ok_max_err_deg > 0.0f && cc->adopted_err > cc->cfg.ok_max_err_deg) ||
            magcal_cont_transient_settling(cc) != 0) {
            out->trust = MAGCAL_TRUST_COARSE;
        } else {
            out->trust = MAGCAL_TRUST_OK;
        }
    }
    return MAGCAL_OK;
}
