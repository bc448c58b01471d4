/* Cortex-M4F instruction counts of the pipeline under QEMU mps2-an386 (run_bench.py runs it with
 * `-icount shift=0`: one guest instruction per virtual ns, SysTick at 25 MHz, so one tick is 40
 * instructions, deterministic). Not cycles: a Cortex-M4 needs at least one cycle per instruction
 * (loads, branches and divides take more), so the counts are a lower bound of the cycles.
 * Data: the host bench's generators (../bench_data.c: the 2-D ring, the 3-D shell, the road drive
 * of the aided estimator), capacity MAGCAL_MAX_SAMPLES (1024). Prints
 * "M4F <what> <n> <instructions> <status>" lines through semihosting. */
#include <stdint.h>
#include <stdio.h>

#include "magcal/aided.h"
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
static magcal_vec3_t g_pts3[CAP];
static uint32_t g_work3[(MAGCAL_OPTICS3_FILTER_WORKSPACE_LEN(CAP) + 3u) / 4u];
#define N_EPOCHS 2000u
static magcal_aided_epoch_t g_ep[N_EPOCHS];
static magcal_aided_t g_aided;

static uint32_t ticks(void) { return SYST_CVR; /* counts down, 24 bits */ }

static unsigned long insn_since(uint32_t t0)
{
    return (unsigned long)((t0 - ticks()) & 0xFFFFFFu) * INSN_PER_TICK;
}

/* 3-D: the density stage at n = 300, 600, 1000 and the aided estimator per epoch. */
static int three_d(void)
{
    static const size_t ns3[] = {300u, 600u, 1000u};
    const magcal_aided_cfg_t acfg = MAGCAL_AIDED_CFG_DEFAULT;
    magcal_status_t st;
    uint32_t t0;
    unsigned long ins;
    size_t k, i;
    int fails = 0;
    for (k = 0u; k < sizeof ns3 / sizeof ns3[0]; ++k) {
        magcal_optics_cfg_t c3 = MAGCAL_OPTICS_CFG_DEFAULT;
        bench_generate3(g_pts3, ns3[k]);
        t0 = ticks();
        st = magcal_optics_filter3(&c3, g_pts3, ns3[k], g_work3, sizeof g_work3, g_mask, NULL);
        printf("M4F optics3_filter %u %lu %d\n", (unsigned)ns3[k], insn_since(t0), (int)st);
        fails += st != MAGCAL_OK;
    }
    bench_generate_drive(g_ep, N_EPOCHS);
    st = magcal_aided_init(&g_aided, &acfg);
    t0 = ticks();
    for (i = 0u; st == MAGCAL_OK && i < N_EPOCHS; ++i) {
        st = magcal_aided_update(&g_aided, &g_ep[i], NULL);
        if (st == MAGCAL_ERR_GATED) {
            st = MAGCAL_OK;
        }
    }
    ins = insn_since(t0);
    printf("M4F aided_update %u %lu %d\n", (unsigned)N_EPOCHS, ins / N_EPOCHS, (int)st);
    fails += st != MAGCAL_OK;
    return fails;
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
    fails += three_d();
    return fails == 0 ? 0 : 1;
}
