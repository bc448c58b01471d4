/* Per-call Cortex-M4F instruction counts of the continuous calibrator (issue 13: no single call
 * above 10,000 instructions at the default budget; issue 14: one complete 2-D calibration from the
 * default store of a drive <= 2.0 M) under QEMU mps2-an386 with `-icount shift=0` (SysTick at
 * 25 MHz: one tick = 40 instructions; every count is quantised to 40).
 *
 * The calibrator runs at its DEFAULT configuration (MAGCAL_CONT_CFG_DEFAULT, the continuous.h
 * example: 36 sectors x 8 = 288 slots, the shipped MAGCAL_MAX_SAMPLES) and is fed, row by row in
 * file order, the drives of the generated header BENCH_DRIVES_H (run_bench.py writes it at bench
 * time: a tools/gen_drive.py drive with a fixed seed, and the shared real vn100_car_circles_b
 * repeated when ../shared exists; never committed). The one setting taken from the drive is the
 * sensor's declared range (cfg.intake.range_limit, as the port would declare it: 800 uT for the
 * generated drive, whose glitch bursts stick an axis at that rail; 0 = undeclared). Per row, exactly what a firmware does:
 * magcal_cont_push() (magcal_cont_push_imu() with the drive's gravity and gyro when it has them:
 * the generated drive), magcal_cont_step(), magcal_cont_heading(), SysTick read around each call.
 *
 * A solve runs from the step that starts it (the first IN_PROGRESS after a non-IN_PROGRESS) to the
 * step that ends it (ADOPTED, REFUSED or FAILED); its cost is the sum of those step calls,
 * including the intake each of them drains. A change declared while a solve is under way aborts
 * it (outcome CHANGE): counted as aborted, never as a complete solve.
 *
 * Output (semihosting stdout), one fact per line, parsed by run_bench.py (m4f_cont()):
 *   CONT <drive> rows <n> <reps>
 *   CONT <drive> call <push|step|heading> <max> <p99> <median> <max_row>
 *   CONT <drive> solve <k> <start_row> <end_row> <steps> <total_instr> <largest_step> <outcome> <status>
 *   CONT <drive> first_adopted_steps <instr of each step of the first adopted solve, in order>
 *   CONT <drive> summary <adoptions> <solves> <aborted> <changes> <ok_headings> <trusted_rows>
 *   CONT <drive> isolated <start_row> <steps> <total_instr> <largest_step> <outcome> <attempts>
 *     (run_isolated: the first adopted solve with no pushes during it)
 * Exit status: 0, or 1 when a call broke its contract (a status push/heading may not return, an
 * OK heading outside [0, 360) or not finite, a generation that went down, no solve at all). */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>

#include "magcal/continuous.h"

#ifdef MAGCAL_BENCH_TRACE
/* cont_trace.elf: the library's per-step trace (src/loop/cont_step.c, TR_* indices) */
#define BENCH_TR_N 19u
extern uint32_t magcal_bench_cont_trace[BENCH_TR_N];
#endif

/* One drive of the generated header: rows of raw samples and ms stamps, fed `reps` times in a
 * row (stamps of repetition r shifted by r x period_ms). */
typedef struct {
    const char *name;
    const magcal_vec3_t *m;
    const uint32_t *t_ms;
    const int16_t (*g)[3]; /* gravity in milli-g (pushed with magcal_cont_push_g), NULL = none */
    const int16_t (*w)[3]; /* gyro rates in 1e-4 rad/s (with g: magcal_cont_push_imu), NULL = none */
    uint32_t n;
    uint32_t reps;
    uint32_t period_ms;
    float range_limit; /* the sensor's declared range (intake cfg.range_limit; 0 = not declared) */
} bench_drive_t;

#include BENCH_DRIVES_H /* g_drives[], BENCH_DRIVE_MAX_ROWS (rows x reps of the longest drive) */

#define SYST_CSR (*(volatile uint32_t *)0xE000E010u)
#define SYST_RVR (*(volatile uint32_t *)0xE000E014u)
#define SYST_CVR (*(volatile uint32_t *)0xE000E018u)
#define INSN_PER_TICK 40u

#define SLOTS MAGCAL_CONT_SLOTS(36u, 8u) /* the defaults: MAGCAL_INTAKE_CFG_DEFAULT_2D */
#define N_SOLVE_MAX 4096u

static magcal_intake_slot_t g_slots[SLOTS];
static magcal_vec2_t g_solve_buf[SLOTS];
static MAGCAL_CALIBRATOR_WORKSPACE_DECLARE(g_work, SLOTS);
static magcal_cont_t g_cc;
static uint32_t g_call[3][BENCH_DRIVE_MAX_ROWS]; /* push, step, heading: instructions per row */
#define N_SOLVE_STEPS_MAX 4096u
static uint32_t g_solve_step[N_SOLVE_STEPS_MAX]; /* the steps of the solve under way */

static const char *const k_call_name[3] = {"push", "step", "heading"};

static uint32_t ticks(void)
{
    return SYST_CVR; /* counts down, 24 bits */
}

static uint32_t insn_since(uint32_t t0)
{
    return ((t0 - ticks()) & 0xFFFFFFu) * INSN_PER_TICK;
}

static int cmp_u32(const void *a, const void *b)
{
    uint32_t x = *(const uint32_t *)a;
    uint32_t y = *(const uint32_t *)b;
    return (x > y) - (x < y);
}

static const char *outcome_name(magcal_cont_outcome_t o)
{
    switch (o) {
    case MAGCAL_CONT_ADOPTED:
        return "adopted";
    case MAGCAL_CONT_REFUSED:
        return "refused";
    case MAGCAL_CONT_FAILED:
        return "failed";
    case MAGCAL_CONT_CHANGE:
        return "aborted_change";
    default:
        return "other";
    }
}

/* Largest, 99th percentile (nearest rank) and lower median of one call's counts; sorts in place
 * after the row of the largest was found. */
static void report_call(const char *drive, unsigned which, uint32_t n)
{
    uint32_t *v = g_call[which];
    uint32_t i, max_row = 0u;
    for (i = 1u; i < n; ++i) {
        if (v[i] > v[max_row]) {
            max_row = i;
        }
    }
    {
        uint32_t mx = v[max_row];
        uint32_t r99 = (uint32_t)(((uint64_t)n * 99u + 99u) / 100u); /* ceil(0.99 n) */
        qsort(v, n, sizeof v[0], cmp_u32);
        printf("CONT %s call %s %lu %lu %lu %lu\n", drive, k_call_name[which], (unsigned long)mx,
               (unsigned long)v[r99 - 1u], (unsigned long)v[(n - 1u) / 2u], (unsigned long)max_row);
    }
}

/* Row i's push: magcal_cont_push_imu with the drive's gravity and gyro (the tilt compensation and
 * the gyro heading check, continuous.h), magcal_cont_push_g with its gravity alone, else
 * magcal_cont_push. */
static magcal_status_t bench_push(const bench_drive_t *d, uint32_t i, uint32_t t_ms)
{
    if (d->g != NULL) {
        magcal_vec3_t g;
        g.x = (float)d->g[i][0] * 0.001f;
        g.y = (float)d->g[i][1] * 0.001f;
        g.z = (float)d->g[i][2] * 0.001f;
        if (d->w != NULL) {
            magcal_vec3_t w;
            w.x = (float)d->w[i][0] * 1e-4f;
            w.y = (float)d->w[i][1] * 1e-4f;
            w.z = (float)d->w[i][2] * 1e-4f;
            return magcal_cont_push_imu(&g_cc, &d->m[i], &g, &w, t_ms);
        }
        return magcal_cont_push_g(&g_cc, &d->m[i], &g, t_ms);
    }
    return magcal_cont_push(&g_cc, &d->m[i], t_ms);
}

static int run_drive(const bench_drive_t *d)
{
    magcal_cont_cfg_t cfg = MAGCAL_CONT_CFG_DEFAULT;
    magcal_status_t st;
    uint32_t rows = d->n * d->reps;
    uint32_t r, row = 0u;
    uint32_t gen = 0u, adoptions = 0u, solves = 0u, aborted = 0u, changes = 0u;
    uint32_t ok_headings = 0u, trusted = 0u;
    int in_solve = 0;
    uint32_t s_start = 0u, s_steps = 0u, s_total = 0u, s_max = 0u;
    int fails = 0;

    cfg.intake.range_limit = d->range_limit; /* what the port declares; nothing else changed */
    st = magcal_cont_init(&g_cc, &cfg, NULL, g_slots, SLOTS, g_solve_buf, g_work, sizeof g_work);
    if (st != MAGCAL_OK) {
        printf("CONT %s init_failed %d\n", d->name, (int)st);
        return 1;
    }
    printf("CONT %s rows %lu %lu\n", d->name, (unsigned long)rows, (unsigned long)d->reps);
    for (r = 0u; r < d->reps; ++r) {
        uint32_t i;
        for (i = 0u; i < d->n; ++i, ++row) {
            const magcal_vec3_t *m = &d->m[i];
            uint32_t t_ms = d->t_ms[i] + r * d->period_ms;
            magcal_cont_outcome_t o;
            magcal_cont_heading_t hd;
            uint32_t t0, c;

            t0 = ticks();
            st = bench_push(d, i, t_ms);
            g_call[0][row] = insn_since(t0);
            fails += st != MAGCAL_OK; /* one push per step at drain 2: the ring never fills */

            t0 = ticks();
            o = magcal_cont_step(&g_cc);
            c = insn_since(t0);
            g_call[1][row] = c;
            if (o == MAGCAL_CONT_IN_PROGRESS && !in_solve) {
                in_solve = 1;
                s_start = row;
                s_steps = 0u;
                s_total = 0u;
                s_max = 0u;
            }
            if (in_solve) {
                if (s_steps < N_SOLVE_STEPS_MAX) {
                    g_solve_step[s_steps] = c;
                }
                s_steps++;
                s_total += c;
                s_max = c > s_max ? c : s_max;
            }
#ifdef MAGCAL_BENCH_TRACE
            /* every step that did more than the idle minimum, with what the library charged:
             * TR <drive> <row> <measured> <the BENCH_TR_N trace words> <outcome> */
            if (c >= 1000u || magcal_bench_cont_trace[0] != 0u || magcal_bench_cont_trace[1] != 0u) {
                const uint32_t *tr = magcal_bench_cont_trace;
                unsigned w;
                printf("TR %s %lu %lu", d->name, (unsigned long)row, (unsigned long)c);
                for (w = 0u; w < BENCH_TR_N; ++w) {
                    printf(" %lu", (unsigned long)tr[w]);
                }
                printf(" %d\n", (int)o);
            }
#endif
            if (o == MAGCAL_CONT_CHANGE) {
                changes++;
            }
            if (in_solve && o != MAGCAL_CONT_IN_PROGRESS) {
                in_solve = 0;
                if (o == MAGCAL_CONT_CHANGE) {
                    aborted++;
                } else {
                    solves++;
                    adoptions += o == MAGCAL_CONT_ADOPTED;
                    if (o == MAGCAL_CONT_ADOPTED && adoptions == 1u) { /* per stage (today) or slice */
                        uint32_t k, nk = s_steps < N_SOLVE_STEPS_MAX ? s_steps : N_SOLVE_STEPS_MAX;
                        printf("CONT %s first_adopted_steps", d->name);
                        for (k = 0u; k < nk; ++k) {
                            printf(" %lu", (unsigned long)g_solve_step[k]);
                        }
                        printf("\n");
                    }
                }
                if (solves + aborted <= N_SOLVE_MAX) {
                    printf("CONT %s solve %lu %lu %lu %lu %lu %lu %s %d\n", d->name,
                           (unsigned long)(solves + aborted), (unsigned long)s_start, (unsigned long)row,
                           (unsigned long)s_steps, (unsigned long)s_total, (unsigned long)s_max,
                           outcome_name(o), (int)magcal_cont_status(&g_cc));
                }
            }

            t0 = ticks();
            st = magcal_cont_heading(&g_cc, m, 0.0f, &hd);
            g_call[2][row] = insn_since(t0);
            if (st == MAGCAL_OK) {
                ok_headings++;
                trusted += hd.trust == MAGCAL_TRUST_OK;
                if (!(hd.heading_deg >= 0.0f && hd.heading_deg < 360.0f) || hd.generation < gen) {
                    printf("CONT %s bad_heading row %lu\n", d->name, (unsigned long)row);
                    fails++;
                }
                gen = hd.generation;
            } else if (st != MAGCAL_ERR_NONFINITE && st != MAGCAL_ERR_ZERO_FIELD) {
                printf("CONT %s bad_heading_status row %lu %d\n", d->name, (unsigned long)row, (int)st);
                fails++;
            } else {
                /* a glitch row: no heading, as documented */
            }
        }
    }
    report_call(d->name, 0u, rows);
    report_call(d->name, 1u, rows);
    report_call(d->name, 2u, rows);
    printf("CONT %s summary %lu %lu %lu %lu %lu %lu\n", d->name, (unsigned long)adoptions,
           (unsigned long)solves, (unsigned long)aborted, (unsigned long)changes,
           (unsigned long)ok_headings, (unsigned long)trusted);
    if (solves == 0u) {
        printf("CONT %s no_solve\n", d->name); /* the drive measured no solve: the bench would lie */
        fails++;
    }
    return fails;
}

/* One complete 2-D calibration from the default store, no samples pushed meanwhile (issue 14's
 * m4f_cal2d_total_instr): the drive fed as above (push, step, heading per row) until a step starts
 * a solve; then no more pushes, only steps until the solve ends. A solve that does not adopt
 * (failed, refused) is counted as an attempt and the drive goes on from the next row; the first
 * adopted solve is reported:
 *   CONT <drive> isolated <start_row> <steps> <total_instr> <largest_step> <outcome> <attempts> */
static int run_isolated(const bench_drive_t *d)
{
    magcal_cont_cfg_t cfg = MAGCAL_CONT_CFG_DEFAULT;
    uint32_t rows = d->n * d->reps;
    uint32_t row, attempts = 0u;
    cfg.intake.range_limit = d->range_limit;
    if (magcal_cont_init(&g_cc, &cfg, NULL, g_slots, SLOTS, g_solve_buf, g_work, sizeof g_work) != MAGCAL_OK) {
        return 1;
    }
    for (row = 0u; row < rows; ++row) {
        const magcal_vec3_t *m = &d->m[row % d->n];
        uint32_t t_ms = d->t_ms[row % d->n] + (row / d->n) * d->period_ms;
        magcal_cont_heading_t hd;
        magcal_cont_outcome_t o;
        uint32_t t0, c;
        (void)bench_push(d, row % d->n, t_ms);
        t0 = ticks();
        o = magcal_cont_step(&g_cc);
        c = insn_since(t0);
        if (o == MAGCAL_CONT_IN_PROGRESS && g_cc.stage != 0u && g_cc.stage != 3u) { /* a solve (not the field fit) */
            uint32_t steps = 1u, total = c, largest = c, k;
            for (k = 0u; k < 10000000u && o == MAGCAL_CONT_IN_PROGRESS; ++k) {
                t0 = ticks();
                o = magcal_cont_step(&g_cc);
                c = insn_since(t0);
                steps++;
                total += c;
                largest = c > largest ? c : largest;
            }
            attempts++;
            if (o == MAGCAL_CONT_ADOPTED) {
                printf("CONT %s isolated %lu %lu %lu %lu %s %lu\n", d->name, (unsigned long)row, (unsigned long)steps,
                       (unsigned long)total, (unsigned long)largest, outcome_name(o), (unsigned long)attempts);
                /* the field-model fit after the adoption: to its end, not part of the figure */
                while (magcal_cont_step(&g_cc) == MAGCAL_CONT_IN_PROGRESS && k++ < 20000000u) {
                }
                return 0;
            }
        }
        (void)magcal_cont_heading(&g_cc, m, 0.0f, &hd);
    }
    printf("CONT %s isolated_none %lu\n", d->name, (unsigned long)attempts);
    return 0;
}

int main(void)
{
    size_t k;
    int fails = 0;
    SYST_RVR = 0xFFFFFFu; /* 16.7 M ticks = 671 M instructions per wrap: more than any call */
    SYST_CVR = 0u;
    SYST_CSR = 5u; /* enable, processor clock, no interrupt */
    for (k = 0u; k < sizeof g_drives / sizeof g_drives[0]; ++k) {
        fails += run_drive(&g_drives[k]);
        fails += run_isolated(&g_drives[k]);
    }
    printf("CONT done %d\n", fails);
    return fails == 0 ? 0 : 1;
}
