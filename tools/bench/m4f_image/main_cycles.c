/* Cortex-M4F instruction counts of the pipeline under QEMU mps2-an386 (run_bench.py runs it with
 * `-icount shift=0`: one guest instruction per virtual ns, SysTick at 25 MHz, so one tick is 40
 * instructions, deterministic). Not cycles: a Cortex-M4 needs at least one cycle per instruction
 * (loads, branches and divides take more), so the counts are a lower bound of the cycles.
 * Data: the host bench's generator (../bench_data.c), capacity MAGCAL_MAX_SAMPLES (1024). Prints
 * "M4F <what> <n> <instructions> <status>" lines through semihosting. */
#include <stdint.h>
#include <stdio.h>

#include "magcal/calibrator.h"
#include "magcal/heading.h"
#include "magcal/optics.h"

#include "bench_data.h"

#define CAP ((size_t)MAGCAL_MAX_SAMPLES)
#define SYST_CSR (*(volatile uint32_t *)0xE000E010u)
#define SYST_RVR (*(volatile uint32_t *)0xE000E014u)
#define SYST_CVR (*(volatile uint32_t *)0xE000E018u)
#define INSN_PER_TICK 40u /* -icount shift=0: 1 GHz virtual clock, SysTick 25 MHz */

static magcal_vec2_t g_pts[CAP];
static uint8_t g_kind[CAP];
static uint8_t g_mask[CAP];
static magcal_vec2_t g_buf[CAP];
static uint32_t g_work[(MAGCAL_CALIBRATOR_WORKSPACE_LEN(CAP) + 3u) / 4u];
static magcal_calibrator_t g_cal;

static uint32_t ticks(void) { return SYST_CVR; /* counts down, 24 bits */ }

static unsigned long insn_since(uint32_t t0)
{
    return (unsigned long)((t0 - ticks()) & 0xFFFFFFu) * INSN_PER_TICK;
}

int main(void)
{
    static const size_t ns[] = {100u, 300u, 700u, 1024u};
    size_t k, i;
    int fails = 0;
    SYST_RVR = 0xFFFFFFu; /* 16.7 M ticks = 671 M instructions per wrap: more than one step needs */
    SYST_CVR = 0u;
    SYST_CSR = 5u; /* enable, processor clock, no interrupt */
    for (k = 0u; k < sizeof ns / sizeof ns[0]; ++k) {
        size_t n = ns[k];
        magcal_calibrator_cfg_t cfg = MAGCAL_CALIBRATOR_CFG_DEFAULT;
        magcal_optics_cfg_t ocfg = MAGCAL_OPTICS_CFG_DEFAULT;
        magcal_cal2d_t cal = MAGCAL_CAL2D_IDENTITY;
        magcal_cal_report_t rep;
        magcal_status_t st;
        uint32_t t0;
        unsigned long push_i, run_i;
        bench_generate(g_pts, g_kind, n);

        t0 = ticks();
        st = magcal_optics_filter(&ocfg, g_pts, n, g_work, sizeof g_work, g_mask, NULL);
        printf("M4F optics_filter %u %lu %d\n", (unsigned)n, insn_since(t0), (int)st);
        fails += st != MAGCAL_OK;

        st = magcal_calibrator_init(&g_cal, &cfg, g_buf, CAP, g_work, sizeof g_work);
        t0 = ticks();
        for (i = 0u; st == MAGCAL_OK && i < n; ++i) {
            st = magcal_calibrator_push(&g_cal, g_pts[i]);
        }
        push_i = insn_since(t0);
        t0 = ticks();
        if (st == MAGCAL_OK) {
            st = magcal_calibrator_run(&g_cal, &cal, &rep);
        }
        run_i = insn_since(t0);
        printf("M4F calibration_push %u %lu %d\n", (unsigned)n, push_i, (int)st);
        printf("M4F calibration %u %lu %d\n", (unsigned)n, run_i, (int)st);
        fails += st != MAGCAL_OK;
        if (n == 700u) {
            float mag = 0.0f;
            t0 = ticks();
            st = magcal_heading_compute(&cal, g_pts[1], 2.5f, &mag, NULL);
            printf("M4F heading 1 %lu %d\n", insn_since(t0), (int)st);
            fails += st != MAGCAL_OK;
        }
    }
    return fails == 0 ? 0 : 1;
}
