/*
 * libFuzzer harness for the continuous 3-D calibrator (continuous3.h): arbitrary byte streams as
 * configurations, samples, time stamps and call orders through push / step / solve_blocking /
 * heading / progress / status.
 *
 * Input layout (little endian; missing bytes read as 0):
 *   u8 cfg flags: bit 0 drain_per_step from the input (u8, 0 allowed: must be refused), bit 1
 *                 min_new (u8), bit 2 solve_fill (raw f32), bit 3 mismatch_min_rel (raw f32),
 *                 bit 4 change_ms / clear_ms small (u8 x 10 ms each), bit 5 installed calibration
 *                 (9 + 3 + 1 raw f32), bit 6 raw samples (else synthetic tumble), bit 7 step_budget
 *                 (u16, 0 allowed: must be refused; small budgets cut the sliced solve finely)
 *   then ops until the input ends, one u8 each: low 3 bits = op (0-3 push, 4 step, 5 heading,
 *   6 solve_blocking(force = bit 3), 7 progress); a push reads its sample (raw: 3 x f32, synthetic:
 *   3 x i8 angle steps (x 0.05 rad) + 3 x i8 noise (x 0.01 uT)) and a u8 time step (ms); a heading
 *   reads 3 x i8 field components (bit 3: with gravity (0, 0, 1) g). Seeds: make_corpus.py.
 *
 * Invariants: documented statuses only; outcomes in the enum; generation never decreases and
 * moves only on ADOPTED; an installed calibration is finite with F > 0; progress stays inside the
 * store (cells_filled <= cells, stored <= slots, fill in [0, 1]); every sample pushed is taken
 * or counted dropped; a heading that returns OK is in [0, 360) with a known trust state.
 */
#include <math.h>

#include "fuzz_common.h"
#include "magcal/continuous3.h"

#define FZ3_SLOTS MAGCAL_CONT3_SLOTS(10u, 4u)

static magcal_intake_slot_t fz3_slots[FZ3_SLOTS];
static magcal_vec3_t fz3_buf[FZ3_SLOTS];
static MAGCAL_CONT3_WORKSPACE_DECLARE(fz3_work, FZ3_SLOTS);
static magcal_cont3_t fz3;

static int fz3_status_ok(magcal_status_t st) { return st <= MAGCAL_IN_PROGRESS && st >= MAGCAL_ERR_INCONSISTENT; }

static void fz3_check_cal(const magcal_cont3_t *c)
{
    int i, k;
    if (c->has_cal == 0u) {
        return;
    }
    for (i = 0; i < 3; ++i) {
        for (k = 0; k < 3; ++k) {
            FUZZ_CHECK(isfinite(c->cal.g[i][k]), "installed G finite");
        }
    }
    FUZZ_CHECK(isfinite(c->cal.v.x) && isfinite(c->cal.v.y) && isfinite(c->cal.v.z), "installed V finite");
    FUZZ_CHECK(c->cal.field > 0.0f && isfinite(c->cal.field), "installed F > 0");
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fuzz_in_t in = {data, size, 0u};
    magcal_cont3_cfg_t cfg = MAGCAL_CONT3_CFG_DEFAULT;
    magcal_ellipsoid_cal_t inst;
    const uint8_t fl = fuzz_u8(&in);
    magcal_status_t st;
    uint32_t t = 0u, pushed_ok = 0u, pushed_full = 0u, gen = 0u, ops = 0u;
    double yaw = 0.0, pitch = 0.0, roll = 0.0;
    if ((fl & 1u) != 0u) {
        cfg.drain_per_step = fuzz_u8(&in);
    }
    if ((fl & 2u) != 0u) {
        cfg.min_new = fuzz_u8(&in);
    }
    if ((fl & 4u) != 0u) {
        cfg.solve_fill = fuzz_f32(&in);
    }
    if ((fl & 8u) != 0u) {
        cfg.mismatch_min_rel = fuzz_f32(&in);
    }
    if ((fl & 16u) != 0u) {
        cfg.change_ms = 10u * fuzz_u8(&in);
        cfg.clear_ms = 10u * fuzz_u8(&in);
    }
    if ((fl & 128u) != 0u) {
        cfg.step_budget = fuzz_u16(&in);
    }
    if ((fl & 32u) != 0u) {
        int i, k;
        for (i = 0; i < 3; ++i) {
            for (k = 0; k < 3; ++k) {
                inst.g[i][k] = fuzz_f32(&in);
            }
        }
        inst.v.x = fuzz_f32(&in);
        inst.v.y = fuzz_f32(&in);
        inst.v.z = fuzz_f32(&in);
        inst.field = fuzz_f32(&in);
    }
    (void)memset(&fz3, 0, sizeof fz3); /* libFuzzer runs every input in one process */
    st = magcal_cont3_init(&fz3, &cfg, (fl & 32u) != 0u ? &inst : NULL, fz3_slots, FZ3_SLOTS, fz3_buf, fz3_work,
                           sizeof fz3_work);
    FUZZ_CHECK(fz3_status_ok(st), "init status");
    if (st != MAGCAL_OK) {
        magcal_vec3_t m = {1.0f, 2.0f, 3.0f};
        FUZZ_CHECK(magcal_cont3_push(&fz3, &m, 0u) == MAGCAL_ERR_NOT_INITIALISED,
                   "a refused configuration leaves the instance unusable");
        return 0;
    }
    fz3_check_cal(&fz3);
    while (fuzz_left(&in) > 0u && ops < 20000u) {
        const uint8_t op = fuzz_u8(&in);
        ops++;
        switch (op & 7u) {
        case 0u:
        case 1u:
        case 2u:
        case 3u: {
            magcal_vec3_t m;
            if ((fl & 64u) != 0u) {
                m.x = fuzz_f32(&in);
                m.y = fuzz_f32(&in);
                m.z = fuzz_f32(&in);
            } else {
                /* synthetic tumble: W = I, V = (20, -10, 30), B = (0, 20, -40), noise */
                const double by = 20.0, bz = -40.0;
                double a0, a1, b0, b1, b2;
                yaw += 0.05 * (double)(int8_t)fuzz_u8(&in);
                pitch += 0.05 * (double)(int8_t)fuzz_u8(&in);
                roll += 0.05 * (double)(int8_t)fuzz_u8(&in);
                a0 = -sin(yaw) * by;
                a1 = cos(yaw) * by;
                b0 = a0;
                b1 = cos(pitch) * a1 + sin(pitch) * bz;
                b2 = -sin(pitch) * a1 + cos(pitch) * bz;
                m.x = (float)(cos(roll) * b0 - sin(roll) * b2 + 20.0 + 0.01 * (double)(int8_t)fuzz_u8(&in));
                m.y = (float)(b1 - 10.0 + 0.01 * (double)(int8_t)fuzz_u8(&in));
                m.z = (float)(sin(roll) * b0 + cos(roll) * b2 + 30.0 + 0.01 * (double)(int8_t)fuzz_u8(&in));
            }
            t += fuzz_u8(&in);
            st = magcal_cont3_push(&fz3, &m, t);
            FUZZ_CHECK(st == MAGCAL_OK || st == MAGCAL_ERR_BUFFER_FULL, "push status");
            if (st == MAGCAL_OK) {
                pushed_ok++;
            } else {
                pushed_full++;
            }
            break;
        }
        case 4u:
        case 6u: {
            const magcal_cont3_outcome_t oc = (op & 7u) == 4u ? magcal_cont3_step(&fz3)
                                                              : magcal_cont3_solve_blocking(&fz3, (op & 8u) != 0u);
            FUZZ_CHECK((unsigned)oc <= (unsigned)MAGCAL_CONT3_CHANGE, "outcome in the enum");
            FUZZ_CHECK(fz3.generation >= gen, "generation never decreases");
            FUZZ_CHECK(fz3.generation == gen || oc == MAGCAL_CONT3_ADOPTED, "generation moves only on ADOPTED");
            FUZZ_CHECK(oc != MAGCAL_CONT3_ADOPTED || fz3.generation == gen + 1u, "one adoption per outcome");
            gen = fz3.generation;
            FUZZ_CHECK(fz3_status_ok(magcal_cont3_status(&fz3)), "solve status");
            fz3_check_cal(&fz3);
            break;
        }
        case 5u: {
            magcal_cont3_heading_t hd;
            magcal_vec3_t m, a = {0.0f, 0.0f, 1.0f};
            m.x = (float)(int8_t)fuzz_u8(&in);
            m.y = (float)(int8_t)fuzz_u8(&in);
            m.z = (float)(int8_t)fuzz_u8(&in);
            st = magcal_cont3_heading(&fz3, &m, (op & 8u) != 0u ? &a : NULL, 0.0f, &hd);
            FUZZ_CHECK(fz3_status_ok(st) && st != MAGCAL_IN_PROGRESS, "heading status");
            if (st == MAGCAL_OK) {
                FUZZ_CHECK(hd.heading_deg >= 0.0f && hd.heading_deg < 360.0f, "heading range");
                FUZZ_CHECK((unsigned)hd.trust <= (unsigned)MAGCAL_TRUST_CHANGED, "trust state");
                FUZZ_CHECK(hd.generation == fz3.generation, "heading generation");
            }
            break;
        }
        default: {
            magcal_cont3_progress_t p;
            FUZZ_CHECK(magcal_cont3_progress(&fz3, &p) == MAGCAL_OK, "progress status");
            FUZZ_CHECK(p.cells_filled <= p.cells && p.stored <= FZ3_SLOTS, "progress inside the store");
            FUZZ_CHECK(p.fill >= 0.0f && p.fill <= 1.0f, "fill range");
            FUZZ_CHECK(p.dropped == pushed_full, "ring drops counted");
            break;
        }
        }
    }
    (void)magcal_cont3_solve_blocking(&fz3, 0);
    FUZZ_CHECK(fz3.tail == fz3.head && fz3.head == pushed_ok, "every queued sample taken exactly once");
    fz3_check_cal(&fz3);
    return 0;
}
