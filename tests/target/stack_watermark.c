/*
 * Measured stack depth of public magcal calls on the target (QEMU mps2-an386), to validate the
 * static bound of tools/stack/stack_usage.py: each wrapper call_X() runs once over a painted
 * stack area and the deepest overwritten byte is reported as `STACK call_X <bytes>`. This file
 * is built with the same -fcallgraph-info flags, so the script knows call_X's static worst case
 * (its own frame + the library call); ctest `stack_static_vs_measured` fails when a measurement
 * exceeds it, i.e. when the static analysis missed a frame or a callee.
 *
 * A measurement is a lower bound (one input, one path); the static number is the bound that
 * matters. Add a case per new public entry point, with an input that exercises its deep path.
 */
#include <stdint.h>
#include <stdio.h>

#include "magcal/ellipse.h"
#include "magcal/heading.h"
#include "magcal_internal.h"
#include "test_util.h"

#define WM_PAINT_BYTES 4096u
#define WM_GUARD_BYTES 64u
#define WM_PAINT 0xA5u
#define WM_RING_N 72u

typedef void (*wm_fn_t)(void);

static magcal_vec2_t g_ring[WM_RING_N];
static float g_psi[WM_RING_N];
static magcal_ellipse_t g_ell;
static magcal_cal2d_t g_cal;
static int g_failures;

static void wm_check(magcal_status_t st)
{
    if (st != MAGCAL_OK) {
        g_failures++;
    }
}

static void call_ellipse_fit(void)
{
    wm_check(magcal_ellipse_fit(g_ring, WM_RING_N, NULL, &g_ell));
}

static void call_ellipse_fit_idx(void)
{
    static const uint16_t idx[5] = {0u, 14u, 29u, 43u, 58u};
    static const uint16_t idx6[6] = {0u, 12u, 24u, 36u, 48u, 60u};
    magcal_ellipse_t e;
    wm_check(magcal_ellipse_fit_idx(g_ring, WM_RING_N, idx, 5u, &e));
    wm_check(magcal_ellipse_fit_idx(g_ring, WM_RING_N, idx6, 6u, &e));
}

static void call_ellipse_fit_seed(void)
{
    magcal_ellipse_t e;
    wm_check(magcal_ellipse_fit_seed(g_ring, WM_RING_N, NULL, &e));
}

static void call_ellipse_to_cal(void)
{
    wm_check(magcal_ellipse_to_cal(&g_ell, MAGCAL_CORR_SYMMETRIC, 40.0f, &g_cal));
}

static void call_heading_compute(void)
{
    float mag = 0.0f;
    float tru = 0.0f;
    wm_check(magcal_heading_compute(&g_cal, g_ring[3], 4.5f, &mag, &tru));
}

static void call_ldlt_solve(void)
{
    float n[9] = {4.0f, 1.0f, 0.5f, 1.0f, 3.0f, 0.25f, 0.5f, 0.25f, 2.0f};
    float b[3] = {1.0f, 2.0f, 3.0f};
    wm_check(magcal_ldlt_solve(n, b, 3u, 1e-6f, NULL));
}

/* Paint WM_PAINT_BYTES below the current stack pointer (leaving a guard for this function's
 * own call), run fn, and return how far below our SP it wrote. fn is called without arguments,
 * so the distance is fn's own worst-case depth on this input. */
static uint32_t __attribute__((noinline)) wm_measure(wm_fn_t fn)
{
    uint32_t sp;
    volatile uint8_t *lo;
    uint32_t i;
    __asm__ volatile("mov %0, sp" : "=r"(sp));
    lo = (volatile uint8_t *)(uintptr_t)(sp - WM_PAINT_BYTES);
    for (i = 0u; i < WM_PAINT_BYTES - WM_GUARD_BYTES; ++i) {
        lo[i] = WM_PAINT;
    }
    fn();
    for (i = 0u; i < WM_PAINT_BYTES - WM_GUARD_BYTES && lo[i] == WM_PAINT; ++i) {
    }
    return WM_PAINT_BYTES - i;
}

static void wm_report(const char *name, wm_fn_t fn)
{
    printf("STACK %s %lu\n", name, (unsigned long)wm_measure(fn));
}

int main(void)
{
    static const test_distortion_t dist = {40.0f, {{1.2f, 0.15f}, {0.15f, 0.85f}}, -210.0f, 95.5f};
    test_make_ring(&dist, WM_RING_N, 1.0, 360.0, 0.05, 77u, g_ring, g_psi);
    wm_report("call_ellipse_fit", call_ellipse_fit);
    wm_report("call_ellipse_fit_idx", call_ellipse_fit_idx);
    wm_report("call_ellipse_fit_seed", call_ellipse_fit_seed);
    wm_report("call_ellipse_to_cal", call_ellipse_to_cal);
    wm_report("call_heading_compute", call_heading_compute);
    wm_report("call_ldlt_solve", call_ldlt_solve);
    if (g_failures != 0) {
        printf("stack_watermark: %d calls failed\n", g_failures);
    }
    return g_failures != 0;
}
