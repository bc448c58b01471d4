/*
 * libFuzzer harness for the continuous calibrator (continuous.h) and the intake store (intake.h)
 * under arbitrary call orders: fuzzed configuration (every field within its documented range),
 * fuzzed samples (raw float32 bits: NaN, +/-Inf, subnormals, huge values, or int16 x scale),
 * fuzzed time stamps (wrapping uint32 steps) and an op stream of push / step / heading /
 * progress / solve_blocking / re-init (reset) / trust API calls. A standalone intake store
 * (2-D or 3-D) is fed the same samples and queried in between.
 *
 * Input layout (little endian; missing bytes read as 0):
 *   u8  flags     bit 0 installed calibration from flash at init, bit 1 int16 sample format,
 *                 bit 2 standalone store 3-D (else 2-D), bit 3 declare a range limit,
 *                 bit 4 push also into the standalone store
 *   u8  per_bin   1 + v % 16
 *   u16 bins      2-D sectors 8 + v % (min(480, 1024 / per_bin) - 7)
 *   u8  sweep     1 + v % 16
 *   u8  spacing   min_spacing_rel = 0.5 v / 255
 *   u8  recentre  recentre_rel = (1 + v) / 256
 *   f32 range     |v| when bit 3 and finite (else 0: not declared)
 *   u16 coverage  solve_coverage_deg = v % 361
 *   u8  min_new, u8 drain (the budget: drain_per_step = 1 + v % 64), u16 age (age_ms = 1 + 100 v),
 *   u8  k (mismatch_k = 0.25 + v / 16), u8 rel (mismatch_min_rel = (1 + v) / 512),
 *   u16 change_ms (x 4), u8 change_bins (1 + v % 36), u16 clear_ms (x 4), f32 scale (int16 format)
 *   then ops, each one u8 (op % 12) and its operands:
 *     0..4 push: dt u16 (ms), sample (12 bytes float32 or 6 bytes int16); op 4 is push_g, with
 *     u8 kind and a gravity (kind % 3 == 0: 12 bytes float32, else two int8 / 1000 of a 1 g tilt;
 *     kind % 7 == 6: none); op 3 is push_imu: the gravity of op 4, then u8 kind and a rate
 *     (kind % 3 == 0: 12 bytes float32, else int8 / 100 rad/s about z; kind % 5 == 4: none);
 *     5 step;
 *     6 heading: sample, f32 declination;  7 progress;  8 solve_blocking: u8 force;
 *     9 re-init (the reset: optionally with the current calibration installed);
 *     (steps that do solve work are capped at 24 and blocking solves at 4 per input, so one input
 *     stays well inside libFuzzer's -timeout; later ones are skipped)
 *     10 trust API: f32 residual, f32 field_rel, f32 inclination, u8 changed;
 *     11 standalone store: u8 which (settle, set_centre, snapshot, reset, mask, counters).
 *
 * Invariants: every status is one the header documents for its call; an OK heading is finite and
 * in [0, 360) (calibrated and raw), its trust one of the four states, UNCALIBRATED exactly when
 * no calibration is installed; progress fields in range (coverage and missing width in [0, 360],
 * completion in [0, 100], stored <= slots, state a lifecycle state); generation, solves and
 * changes never go down between re-inits, generation <= solves (+ nothing at init), an ADOPTED
 * step or blocking solve raises generation by exactly one and leaves a calibration that
 * magcal_cal2d_validate() accepts; solve_blocking never leaves a solve under way; the trust API
 * returns the documented statuses and flag bits; the standalone store's counters and snapshot
 * agree with its progress.
 */
#include <math.h>

#include "fuzz_common.h"
#include "magcal/continuous.h"
#include "magcal/heading.h"
#include "magcal/intake.h"

#define FZ_SLOTS_MAX 1024u
#define FZ_SOLVE_STEPS_MAX 24u /* solve stages per input (each up to O(n log n) at 1024 slots) */
#define FZ_BLOCKING_MAX 4u      /* blocking solves per input */

static magcal_intake_slot_t fz_slots[FZ_SLOTS_MAX];
static magcal_vec2_t fz_buf[FZ_SLOTS_MAX];
static uint32_t fz_work[(MAGCAL_CALIBRATOR_WORKSPACE_LEN(FZ_SLOTS_MAX) + 3u) / 4u];
static magcal_cont_t fz_cc;
static magcal_intake_slot_t fz_st_slots[FZ_SLOTS_MAX];
static magcal_vec3_t fz_snap[FZ_SLOTS_MAX];
static magcal_intake_t fz_st;

typedef struct {
    uint32_t generation;
    uint32_t solves;
    uint32_t changes;
    int installed; /* a calibration was installed at init (from flash) */
} fz_mono_t;

static int fz_known(magcal_status_t st)
{
    return st <= MAGCAL_IN_PROGRESS && st >= MAGCAL_ERR_SHAPE_CHANGED;
}

static magcal_vec3_t fz_sample(fuzz_in_t *in, int as_int16, float scale)
{
    magcal_vec3_t m;
    if (as_int16) {
        m.x = (float)(int16_t)fuzz_u16(in) * scale;
        m.y = (float)(int16_t)fuzz_u16(in) * scale;
        m.z = (float)(int16_t)fuzz_u16(in) * scale;
    } else {
        m.x = fuzz_f32(in);
        m.y = fuzz_f32(in);
        m.z = fuzz_f32(in);
    }
    return m;
}

static void fz_check_progress(const magcal_cont_t *cc, fz_mono_t *mono)
{
    magcal_cont_progress_t p;
    magcal_status_t st = magcal_cont_progress(cc, &p);
    FUZZ_CHECK(st == MAGCAL_OK, "progress status");
    FUZZ_CHECK(p.state == MAGCAL_CONT_COLLECTING || p.state == MAGCAL_CONT_SOLVING ||
                   p.state == MAGCAL_CONT_RELEARNING,
               "progress state");
    FUZZ_CHECK(p.coverage_deg >= 0.0f && p.coverage_deg <= 360.0f, "progress coverage range");
    FUZZ_CHECK(p.completion_pct >= 0.0f && p.completion_pct <= 100.0f, "progress completion range");
    FUZZ_CHECK(p.missing_start_deg >= 0.0f && p.missing_start_deg < 360.0f, "missing sector start");
    FUZZ_CHECK(p.missing_width_deg >= 0.0f && p.missing_width_deg <= 360.0f, "missing sector width");
    FUZZ_CHECK(p.stored <= cc->slots, "stored <= slots");
    FUZZ_CHECK(p.episode_open <= 1u, "episode flag");
    FUZZ_CHECK(p.generation >= mono->generation, "generation went down");
    FUZZ_CHECK(p.solves >= mono->solves, "solves went down");
    FUZZ_CHECK(p.changes >= mono->changes, "changes went down");
    FUZZ_CHECK(p.generation <= p.solves, "more adoptions than solves");
    mono->generation = p.generation;
    mono->solves = p.solves;
    mono->changes = p.changes;
    FUZZ_CHECK(fz_known(magcal_cont_status(cc)), "cont_status: unknown status");
}

static void fz_check_heading(const magcal_cont_t *cc, const magcal_vec3_t *m, float decl,
                             const fz_mono_t *mono)
{
    magcal_cont_heading_t hd;
    magcal_status_t st = magcal_cont_heading(cc, m, decl, &hd);
    int finite_in = isfinite(m->x) && isfinite(m->y) && isfinite(m->z);
    FUZZ_CHECK(st == MAGCAL_OK || st == MAGCAL_ERR_NONFINITE || st == MAGCAL_ERR_ZERO_FIELD ||
                   st == MAGCAL_ERR_ARG,
               "heading: undocumented status");
    if (isfinite(decl) && decl >= -180.0f && decl <= 180.0f && finite_in) {
        FUZZ_CHECK(st != MAGCAL_ERR_NONFINITE, "heading: NONFINITE on finite input");
    }
    if (st != MAGCAL_OK) {
        return;
    }
    FUZZ_CHECK(isfinite(hd.heading_deg) && hd.heading_deg >= 0.0f && hd.heading_deg < 360.0f,
               "OK heading outside [0, 360)");
    FUZZ_CHECK(isfinite(hd.raw_heading_deg) && hd.raw_heading_deg >= 0.0f && hd.raw_heading_deg < 360.0f,
               "OK raw heading outside [0, 360)");
    FUZZ_CHECK(hd.trust == MAGCAL_TRUST_OK || hd.trust == MAGCAL_TRUST_UNCALIBRATED ||
                   hd.trust == MAGCAL_TRUST_DISTURBED || hd.trust == MAGCAL_TRUST_CHANGED ||
                   hd.trust == MAGCAL_TRUST_TILTED || hd.trust == MAGCAL_TRUST_COARSE,
               "trust state");
    /* TILTED needs a calibration: with gravity its tilt, without any the slopes raw z shows
     * (continuous.h "Slopes without gravity") */
    FUZZ_CHECK(hd.trust != MAGCAL_TRUST_TILTED || cc->has_cal != 0u, "tilted without a calibration");
    FUZZ_CHECK(hd.trust != MAGCAL_TRUST_COARSE || cc->has_cal != 0u, "coarse without a calibration");
    FUZZ_CHECK(hd.generation == mono->generation, "heading generation differs from progress");
    FUZZ_CHECK(hd.levelled <= 1u && (hd.levelled == 0u || cc->tc_ok != 0u), "levelled flag without a valid k");
    if (mono->generation == 0u && !mono->installed) {
        FUZZ_CHECK(hd.trust == MAGCAL_TRUST_UNCALIBRATED, "trusted heading without a calibration");
    }
    if (hd.trust == MAGCAL_TRUST_UNCALIBRATED) {
        FUZZ_CHECK(hd.heading_deg == hd.raw_heading_deg, "uncalibrated heading is not the raw one");
    }
}

static void fz_after_adopt(const magcal_cont_t *cc, uint32_t gen_before)
{
    magcal_cont_progress_t p;
    (void)magcal_cont_progress(cc, &p);
    FUZZ_CHECK(p.generation == gen_before + 1u, "ADOPTED without exactly one new generation");
    FUZZ_CHECK(magcal_cal2d_validate(&cc->cal) == MAGCAL_OK, "adopted calibration invalid");
    FUZZ_CHECK(isfinite(cc->cal.radius) && cc->cal.radius > 0.0f, "adopted radius");
    FUZZ_CHECK(magcal_cont_status(cc) == MAGCAL_OK, "ADOPTED with a failure status");
}

/* Trust API on the calibrator's installed calibration (heading.h). */
static void fz_trust(fuzz_in_t *in, const magcal_cont_t *cc, const magcal_vec3_t *m)
{
    const magcal_trust_cfg_t tc = MAGCAL_TRUST_CFG_DEFAULT;
    magcal_trust_t t;
    float resid = fuzz_f32(in);
    float rel = fuzz_f32(in);
    float incl = fuzz_f32(in);
    uint8_t changed = fuzz_u8(in);
    uint8_t flags = 0xFFu;
    magcal_status_t st = magcal_trust_init(&t, &tc, resid);
    magcal_heading_t hd;
    magcal_vec2_t raw;
    if (!isfinite(resid)) {
        FUZZ_CHECK(st == MAGCAL_ERR_NONFINITE, "trust_init: non-finite residual");
    } else if (resid < 0.0f) {
        FUZZ_CHECK(st == MAGCAL_ERR_ARG, "trust_init: negative residual");
    } else if (!isfinite(tc.k * resid)) {
        /* k x residual overflows float: heading.c refuses it with NONFINITE (nothing would
         * ever be disturbed); the header's @return names only non-finite inputs */
        FUZZ_CHECK(st == MAGCAL_ERR_NONFINITE, "trust_init: overflowing tolerance");
    } else {
        FUZZ_CHECK(st == MAGCAL_OK, "trust_init: valid residual refused");
    }
    if (st != MAGCAL_OK) {
        return;
    }
    st = magcal_trust_set_inclination(&t, incl);
    FUZZ_CHECK(st == MAGCAL_OK || st == MAGCAL_ERR_NONFINITE || st == MAGCAL_ERR_ARG, "set_inclination status");
    if (isfinite(incl)) {
        FUZZ_CHECK((st == MAGCAL_OK) == (incl >= -90.0f && incl <= 90.0f), "set_inclination range");
    }
    st = magcal_trust_set_changed(&t, changed);
    FUZZ_CHECK((st == MAGCAL_OK) == (changed <= 1u), "set_changed status");
    st = magcal_trust_judge(&t, rel, incl, &flags);
    FUZZ_CHECK(st == MAGCAL_OK || st == MAGCAL_ERR_NONFINITE || st == MAGCAL_ERR_ARG, "judge status");
    if (st == MAGCAL_OK) {
        magcal_trust_state_t s;
        FUZZ_CHECK((flags & (uint8_t)~(MAGCAL_HEADING_FLAG_DISTURBED | MAGCAL_HEADING_FLAG_CHANGED)) == 0u,
                   "judge: flag bits other than DISTURBED / CHANGED");
        if (changed == 1u) {
            FUZZ_CHECK((flags & MAGCAL_HEADING_FLAG_CHANGED) != 0u, "judge: marked context not CHANGED");
        }
        s = magcal_trust_from_flags(flags);
        FUZZ_CHECK(s == (flags == 0u ? MAGCAL_TRUST_OK
                                     : ((flags & MAGCAL_HEADING_FLAG_CHANGED) != 0u ? MAGCAL_TRUST_CHANGED
                                                                                    : MAGCAL_TRUST_DISTURBED)),
                   "from_flags precedence");
        FUZZ_CHECK(magcal_trust_str(s) != NULL && strcmp(magcal_trust_str(s), "unknown") != 0, "trust_str");
    } else {
        FUZZ_CHECK(flags == 0xFFu, "judge wrote flags on failure");
    }
    raw.x = m->x;
    raw.y = m->y;
    st = magcal_heading_get_trusted(&cc->cal, &t, raw, 0.0f, &hd);
    FUZZ_CHECK(fz_known(st), "heading_get_trusted: unknown status");
    if (st == MAGCAL_OK) {
        FUZZ_CHECK(isfinite(hd.magnetic_deg) && hd.magnetic_deg >= 0.0f && hd.magnetic_deg < 360.0f,
                   "trusted heading range");
        FUZZ_CHECK(hd.trust == magcal_trust_from_flags(hd.flags), "trust = from_flags(flags)");
        if (cc->cal.radius == 0.0f) {
            FUZZ_CHECK(hd.trust == MAGCAL_TRUST_UNCALIBRATED, "identity calibration trusted");
        }
    }
}

/* The standalone store: one query or control call, and its invariants. */
static void fz_store_op(uint8_t which, const magcal_vec3_t *m, size_t n_slots)
{
    magcal_intake_progress_t p;
    magcal_intake_counters_t c;
    magcal_status_t st;
    size_t n = 0u;
    uint32_t mask[MAGCAL_INTAKE_MASK_WORDS(MAGCAL_INTAKE_MAX_BINS)];
    switch (which % 6u) {
    case 0u:
        FUZZ_CHECK(magcal_intake_settle(&fz_st) == MAGCAL_OK, "settle status");
        break;
    case 1u:
        st = magcal_intake_set_centre(&fz_st, (which & 0x80u) != 0u ? NULL : m, m->z);
        FUZZ_CHECK(st == MAGCAL_OK || st == MAGCAL_ERR_NONFINITE || st == MAGCAL_ERR_ARG, "set_centre status");
        break;
    case 2u:
        st = magcal_intake_snapshot3(&fz_st, fz_snap, n_slots, &n);
        FUZZ_CHECK(st == MAGCAL_OK, "snapshot status");
        (void)magcal_intake_progress(&fz_st, &p);
        FUZZ_CHECK(n == p.stored, "snapshot count differs from progress");
        break;
    case 3u:
        FUZZ_CHECK(magcal_intake_reset(&fz_st) == MAGCAL_OK, "store reset status");
        (void)magcal_intake_counters(&fz_st, &c);
        FUZZ_CHECK(c.stored == 0u && c.pushed == 0u, "reset left samples");
        break;
    case 4u:
        FUZZ_CHECK(magcal_intake_mask(&fz_st, mask, sizeof mask / sizeof mask[0]) == MAGCAL_OK, "mask status");
        break;
    default:
        break;
    }
    FUZZ_CHECK(magcal_intake_progress(&fz_st, &p) == MAGCAL_OK, "store progress status");
    FUZZ_CHECK(magcal_intake_counters(&fz_st, &c) == MAGCAL_OK, "store counters status");
    FUZZ_CHECK(p.stored == c.stored && p.stored <= n_slots, "store count");
    FUZZ_CHECK(p.bins_filled <= p.bins, "filled bins");
    FUZZ_CHECK(p.fill_fraction >= 0.0f && p.fill_fraction <= 1.0f, "fill fraction");
    FUZZ_CHECK(p.coverage_deg >= 0.0f && p.coverage_deg <= 360.0f, "store coverage range");
    FUZZ_CHECK(p.completion_pct >= 0.0f && p.completion_pct <= 100.0f, "store completion range");
    FUZZ_CHECK(p.missing_width_deg >= 0.0f && p.missing_width_deg <= 360.0f, "store missing width");
    FUZZ_CHECK(c.pushed == c.added + c.replaced + c.refused_spacing + c.refused_saturated + c.refused_nonfinite +
                   c.refused_level,
               "store counters do not add up");
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fuzz_in_t in = {data, size, 0u};
    magcal_cont_cfg_t cfg = MAGCAL_CONT_CFG_DEFAULT;
    magcal_intake_cfg_t scfg;
    const uint8_t flags = fuzz_u8(&in);
    const int as_int16 = (flags & 2u) != 0u;
    const int store_on = (flags & 16u) != 0u;
    magcal_cal2d_t flash = MAGCAL_CAL2D_IDENTITY;
    fz_mono_t mono = {0u, 0u, 0u, 0};
    magcal_status_t st;
    size_t slots, st_slots = FZ_SLOTS_MAX;
    uint32_t t_ms = 0u;
    float scale, rng;
    unsigned ops = 0u;
    unsigned solve_steps = 0u, blocking = 0u;

    cfg.intake.per_bin = (uint8_t)(1u + fuzz_u8(&in) % 16u);
    {
        unsigned max_bins = FZ_SLOTS_MAX / cfg.intake.per_bin;
        max_bins = max_bins > MAGCAL_INTAKE_MAX_BINS ? MAGCAL_INTAKE_MAX_BINS : max_bins;
        cfg.intake.bins = (uint16_t)(8u + fuzz_u16(&in) % (max_bins - 7u));
    }
    cfg.intake.sweep_steps = (uint16_t)(1u + fuzz_u8(&in) % 16u);
    cfg.intake.min_spacing_rel = 0.5f * (float)fuzz_u8(&in) / 255.0f;
    cfg.intake.recentre_rel = (1.0f + (float)fuzz_u8(&in)) / 256.0f;
    rng = fuzz_f32(&in);
    cfg.intake.range_limit = ((flags & 8u) != 0u && isfinite(rng)) ? fabsf(rng) : 0.0f;
    cfg.solve_coverage_deg = (float)(fuzz_u16(&in) % 361u);
    cfg.min_new = fuzz_u8(&in);
    cfg.drain_per_step = (uint16_t)(1u + fuzz_u8(&in) % 64u);
    cfg.age_ms = 1.0f + 100.0f * (float)fuzz_u16(&in);
    cfg.mismatch_k = 0.25f + (float)fuzz_u8(&in) / 16.0f;
    cfg.mismatch_min_rel = (1.0f + (float)fuzz_u8(&in)) / 512.0f;
    cfg.change_ms = 4u * (uint32_t)fuzz_u16(&in);
    cfg.change_bins = (uint16_t)(1u + fuzz_u8(&in) % 36u);
    cfg.clear_ms = 4u * (uint32_t)fuzz_u16(&in);
    /* the stream's continuity before a calibration (continuous.h "Level shift", "Continuity gate")
     * from the flags' high bits (no byte of their own: the seeds keep their meaning) */
    cfg.continuity = (uint8_t)((flags & 32u) != 0u ? 1u : 0u);
    cfg.shift_rel = (flags & 64u) != 0u ? 0.0f : cfg.shift_rel;
    cfg.shift_hold_ms = (flags & 128u) != 0u ? 1u : cfg.shift_hold_ms;
    /* the gyro-aided gravity of push_imu (op 3), on in half of the inputs (no byte of its own) */
    cfg.gyro_gravity = (uint8_t)(((flags >> 1u) ^ (flags >> 6u)) & 1u);
    scale = fuzz_f32(&in);
    if (cfg.solver.min_samples > MAGCAL_CONT_SLOTS(cfg.intake.bins, cfg.intake.per_bin)) {
        cfg.solver.min_samples = (uint16_t)MAGCAL_CONT_SLOTS(cfg.intake.bins, cfg.intake.per_bin);
    }
    slots = MAGCAL_CONT_SLOTS(cfg.intake.bins, cfg.intake.per_bin);
    if (slots < 16u) {
        slots = 16u; /* init needs 16..MAGCAL_MAX_SAMPLES slots */
    }
    if ((flags & 1u) != 0u) { /* a plausible calibration restored from flash */
        flash.offset.x = 12.5f;
        flash.offset.y = -7.25f;
        flash.m[0][0] = 1.1f;
        flash.m[0][1] = 0.05f;
        flash.m[1][0] = 0.05f;
        flash.m[1][1] = 0.9f;
        flash.radius = 40.0f;
        mono.installed = 1;
    }
    st = magcal_cont_init(&fz_cc, &cfg, (flags & 1u) != 0u ? &flash : NULL, fz_slots, slots, fz_buf, fz_work,
                          sizeof fz_work);
    FUZZ_CHECK(st == MAGCAL_OK, "cont_init with an in-range configuration");
    fz_check_progress(&fz_cc, &mono);

    scfg = cfg.intake;
    if ((flags & 4u) != 0u) {
        const magcal_intake_cfg_t d3 = MAGCAL_INTAKE_CFG_DEFAULT_3D;
        scfg.dims = 3u;
        scfg.bins = (uint16_t)(4u + cfg.intake.bins % (MAGCAL_INTAKE_MAX_BANDS - 3u));
        scfg.per_bin = d3.per_bin;
        {
            uint16_t nb = 0u;
            if (magcal_intake_bins(&scfg, &nb) != MAGCAL_OK || (size_t)nb * scfg.per_bin > st_slots) {
                scfg = d3;
            }
        }
    }
    FUZZ_CHECK(magcal_intake_init(&fz_st, &scfg, fz_st_slots, st_slots) == MAGCAL_OK, "intake_init");

    while (fuzz_left(&in) > 0u && ops < 20000u) {
        uint8_t op = (uint8_t)(fuzz_u8(&in) % 12u);
        ops++;
        if (op <= 4u) {
            magcal_vec3_t m;
            magcal_cont_progress_t p0, p1;
            t_ms += fuzz_u16(&in);
            m = fz_sample(&in, as_int16, scale);
            (void)magcal_cont_progress(&fz_cc, &p0);
            if (op == 3u || op == 4u) {
                /* push_g: its gravity level test, the tilt compensation's regression and levelling;
                 * the gravity raw float32 bits (NaN, Inf, huge), or a small tilt of 1 g (int8 / 1000
                 * per axis: the regression sees plausible hills), or none */
                const uint8_t gk = fuzz_u8(&in);
                magcal_vec3_t g;
                if (gk % 3u == 0u) {
                    g = fz_sample(&in, 0, 1.0f);
                } else {
                    g.x = (float)(int8_t)fuzz_u8(&in) * 0.001f;
                    g.y = (float)(int8_t)fuzz_u8(&in) * 0.001f;
                    g.z = 1.0f;
                }
                if (op == 4u) {
                    st = magcal_cont_push_g(&fz_cc, &m, gk % 7u == 6u ? NULL : &g, t_ms);
                } else {
                    /* push_imu: the gyro's rotation about up into the ring, the heading check */
                    const uint8_t wk = fuzz_u8(&in);
                    magcal_vec3_t w;
                    if (wk % 3u == 0u) {
                        w = fz_sample(&in, 0, 1.0f);
                    } else {
                        w.x = 0.0f;
                        w.y = 0.0f;
                        w.z = (float)(int8_t)fuzz_u8(&in) * 0.01f;
                    }
                    st = magcal_cont_push_imu(&fz_cc, &m, gk % 7u == 6u ? NULL : &g, wk % 5u == 4u ? NULL : &w, t_ms);
                }
            } else {
                st = magcal_cont_push(&fz_cc, &m, t_ms);
            }
            (void)magcal_cont_progress(&fz_cc, &p1);
            FUZZ_CHECK(st == MAGCAL_OK || st == MAGCAL_ERR_BUFFER_FULL, "push status");
            FUZZ_CHECK(p1.dropped == p0.dropped + (st == MAGCAL_ERR_BUFFER_FULL ? 1u : 0u), "dropped count");
            if (store_on) {
                magcal_intake_outcome_t o;
                st = magcal_intake_push(&fz_st, &m, &o);
                FUZZ_CHECK(st == MAGCAL_OK || st == MAGCAL_ERR_SATURATED || st == MAGCAL_ERR_NONFINITE,
                           "store push status");
                if (!(isfinite(m.x) && isfinite(m.y) && isfinite(m.z))) {
                    FUZZ_CHECK(st == MAGCAL_ERR_NONFINITE && o == MAGCAL_INTAKE_REFUSED_NONFINITE,
                               "store kept a non-finite sample");
                }
                if (st == MAGCAL_ERR_SATURATED) {
                    FUZZ_CHECK(o == MAGCAL_INTAKE_REFUSED_SATURATED, "saturated outcome");
                }
            }
        } else if (op == 5u && solve_steps < FZ_SOLVE_STEPS_MAX) {
            uint32_t g0 = mono.generation;
            magcal_cont_outcome_t o = magcal_cont_step(&fz_cc);
            solve_steps += (o != MAGCAL_CONT_IDLE && o != MAGCAL_CONT_CHANGE) ? 1u : 0u;
            FUZZ_CHECK((unsigned)o <= (unsigned)MAGCAL_CONT_CHANGE, "step outcome");
            fz_check_progress(&fz_cc, &mono);
            if (o == MAGCAL_CONT_ADOPTED) {
                fz_after_adopt(&fz_cc, g0);
            } else {
                FUZZ_CHECK(mono.generation == g0, "generation moved without ADOPTED");
            }
        } else if (op == 5u || op == 8u) {
            /* the input's solve budget is spent: the op is skipped (its operand byte stays) */
        } else if (op == 6u) {
            magcal_vec3_t m = fz_sample(&in, as_int16, scale);
            float decl = fuzz_f32(&in);
            fz_check_heading(&fz_cc, &m, decl, &mono);
        } else if (op == 7u) {
            fz_check_progress(&fz_cc, &mono);
        } else if (op == 8u && blocking < FZ_BLOCKING_MAX) {
            uint32_t g0 = mono.generation;
            magcal_cont_progress_t p;
            magcal_cont_outcome_t o = magcal_cont_solve_blocking(&fz_cc, (int)(fuzz_u8(&in) & 1u));
            blocking++;
            FUZZ_CHECK(o == MAGCAL_CONT_IDLE || o == MAGCAL_CONT_ADOPTED || o == MAGCAL_CONT_REFUSED ||
                           o == MAGCAL_CONT_FAILED,
                       "solve_blocking outcome");
            (void)magcal_cont_progress(&fz_cc, &p);
            FUZZ_CHECK(p.state != MAGCAL_CONT_SOLVING, "solve_blocking left a solve under way");
            fz_check_progress(&fz_cc, &mono);
            if (o == MAGCAL_CONT_ADOPTED) {
                fz_after_adopt(&fz_cc, g0);
            }
        } else if (op == 9u) { /* reset by init, with the current calibration from "flash" or none */
            magcal_cal2d_t keep = fz_cc.cal;
            int with = (fuzz_u8(&in) & 1u) != 0u && keep.radius > 0.0f;
            st = magcal_cont_init(&fz_cc, &cfg, with ? &keep : NULL, fz_slots, slots, fz_buf, fz_work,
                                  sizeof fz_work);
            FUZZ_CHECK(st == MAGCAL_OK, "re-init with an adopted calibration");
            mono.generation = 0u;
            mono.solves = 0u;
            mono.changes = 0u;
            mono.installed = with;
            fz_check_progress(&fz_cc, &mono);
        } else if (op == 10u) {
            magcal_vec3_t m = {0.0f, 0.0f, 0.0f};
            m.x = fuzz_f32(&in);
            m.y = fuzz_f32(&in);
            fz_trust(&in, &fz_cc, &m);
        } else {
            uint8_t which = fuzz_u8(&in);
            magcal_vec3_t m = fz_sample(&in, 0, 1.0f);
            fz_store_op(which, &m, st_slots);
        }
    }
    return 0;
}
