/* Cortex-M4F instruction counts on QEMU mps2-an386 with -icount shift=0 (1 SysTick tick = 40
 * instructions). Not built by tools/bench_fit/CMakeLists.txt: copy it to tests/test_zbench.c in a
 * tree with the target branch's cross-test infrastructure, build target test_zbench, then run
 *   qemu-system-arm -M mps2-an386 -display none -monitor none -serial null \
 *     -semihosting-config enable=on,target=native -icount shift=0 -kernel test_zbench.elf */
#include <math.h>
#include <stdio.h>
#include "magcal/ellipse.h"
#include "magcal/heading.h"
#include "unity.h"
void setUp(void) {}
void tearDown(void) {}
#define SYST_CSR (*(volatile uint32_t *)0xE000E010u)
#define SYST_RVR (*(volatile uint32_t *)0xE000E014u)
#define SYST_CVR (*(volatile uint32_t *)0xE000E018u)
static magcal_vec2_t pts[700];
static uint32_t t_prev;
static uint32_t lap(void)
{
    uint32_t t = SYST_CVR;
    uint32_t d = (t_prev - t) & 0xFFFFFFu;
    t_prev = t;
    return d;
}
static void test_bench(void)
{
    static const uint16_t idx5[5] = {0u, 140u, 280u, 420u, 560u};
    magcal_ellipse_t e, e5;
    magcal_cal2d_t cal;
    float mag, tru;
    uint32_t d;
    unsigned i;
    uint32_t rng = 12345u;
    magcal_status_t st = MAGCAL_OK;
    for (i = 0u; i < 700u; ++i) {
        float psi = 6.2831853f * (float)i / 700.0f;
        float hx = -1500.0f * sinf(psi), hy = 1500.0f * cosf(psi);
        rng ^= rng << 13;
        rng ^= rng >> 17;
        rng ^= rng << 5;
        pts[i].x = 1.15f * hx + 0.2f * hy + 6000.0f + (float)(rng & 7u) - 3.5f;
        pts[i].y = 0.1f * hx + 0.85f * hy - 4500.0f + (float)((rng >> 3) & 7u) - 3.5f;
    }
    SYST_RVR = 0xFFFFFFu;
    SYST_CVR = 0u;
    SYST_CSR = 5u;
    while (SYST_CVR == 0u) {
    }
    (void)lap();
    (void)lap();
    d = lap();
    printf("empty lap ticks %lu\n", (unsigned long)d);
    (void)lap();
    for (i = 0u; i < 10u; ++i) {
        st |= magcal_ellipse_fit(pts, 700u, NULL, &e);
    }
    d = lap();
    printf("fit700 x10 ticks %lu\n", (unsigned long)d);
    for (i = 0u; i < 100u; ++i) {
        st |= magcal_ellipse_fit_idx(pts, 700u, idx5, 5u, &e5);
    }
    d = lap();
    printf("fit5 x100 ticks %lu\n", (unsigned long)d);
    for (i = 0u; i < 100u; ++i) {
        st |= magcal_ellipse_to_cal(&e, MAGCAL_CORR_SYMMETRIC, 0.0f, &cal);
    }
    d = lap();
    printf("to_cal x100 ticks %lu\n", (unsigned long)d);
    for (i = 0u; i < 100u; ++i) {
        st |= magcal_heading_compute(&cal, pts[i], 3.5f, &mag, &tru);
    }
    d = lap();
    printf("heading x100 ticks %lu\n", (unsigned long)d);
    for (i = 0u; i < 100u; ++i) {
        (void)magcal_ellipse_residual(&e, pts[i]);
    }
    d = lap();
    printf("residual x100 ticks %lu\n", (unsigned long)d);
    TEST_ASSERT_EQUAL_INT(0, st);
}
int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_bench);
    return UNITY_END();
}
