/*
 * Per-step instruction counts of the time-sliced 2-D density stage (optics.h "time-sliced"):
 * runs magcal_optics_filter_begin/step (or thin) at a budget on a deterministic dataset, so that
 *
 *   valgrind --tool=callgrind --toggle-collect=magcal_optics_filter_step \
 *            --dump-after=magcal_optics_filter_step slice_bench filter ring 1024 6000
 *
 * writes one callgrind dump per step call (tools/bench_optics/slice_steps.sh sums them up), and
 * `slice_bench filter ring 1024 0` runs the one-shot call instead (--toggle-collect=
 * magcal_optics_filter: the unsliced total).
 *
 *   slice_bench filter|thin ring|parked|burst N BUDGET   (BUDGET 0: the one-shot call)
 *     ring:   noisy ellipse, 5 % far spikes (tools/bench_optics/bench_optics.c's data)
 *     parked: 50 % of the samples parked at one heading (a clump), the rest one 1.25-turn drive
 *     burst:  ring plus 20 % of dense burst 0.7 R outside it
 * Prints the status, the number of steps and a checksum of the mask.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "magcal/optics.h"

#ifdef MAGCAL_OPTICS_SLICE_PROFILE
/* Profile build (slice_fit.py): the visits charged per weight, printed after every step. */
extern unsigned long magcal_optics_slice_prof[];
#define PROF_N 37
static void prof_row(void)
{
    static unsigned long last[PROF_N];
    int k;
    printf("P");
    for (k = 0; k < PROF_N; ++k) {
        printf(" %lu", magcal_optics_slice_prof[k] - last[k]);
        last[k] = magcal_optics_slice_prof[k];
    }
    printf("\n");
}
#else
static void prof_row(void) {}
#endif

static magcal_vec2_t g_pts[MAGCAL_MAX_SAMPLES];
static uint32_t g_work[(MAGCAL_OPTICS_FILTER_WORKSPACE_LEN(MAGCAL_MAX_SAMPLES) + 3u) / 4u];
static uint8_t g_mask[MAGCAL_MAX_SAMPLES];

static uint32_t rng_next(uint32_t *s)
{
    uint32_t x = *s;
    x ^= x << 13;
    x ^= x >> 17;
    x ^= x << 5;
    *s = x;
    return x;
}

static float rng_unit(uint32_t *s) { return (float)(rng_next(s) >> 8) * (1.0f / 16777216.0f); }

static void make_data(const char *kind, size_t n)
{
    uint32_t s = 12345u;
    size_t i;
    for (i = 0; i < n; ++i) {
        float a = 6.2831853f * rng_unit(&s);
        float r = 1.0f + 0.02f * (rng_unit(&s) + rng_unit(&s) + rng_unit(&s) - 1.5f);
        if (strcmp(kind, "parked") == 0) {
            a = i < n / 2u ? 1.0f : 1.0f + 7.85f * (float)(i - n / 2u) / (float)(n - n / 2u);
        }
        g_pts[i].x = 0.3f + r * cosf(a);
        g_pts[i].y = -0.2f + 0.8f * r * sinf(a);
        if (strcmp(kind, "ring") == 0 && rng_unit(&s) < 0.05f) {
            g_pts[i].y -= 9.0f;
        }
        if (strcmp(kind, "burst") == 0 && i >= n - n / 5u) {
            g_pts[i].x = 0.3f + 1.7f * cosf(0.7f) + 0.005f * (rng_unit(&s) - 0.5f);
            g_pts[i].y = -0.2f + 1.7f * sinf(0.7f) + 0.005f * (rng_unit(&s) - 0.5f);
        }
    }
}

int main(int argc, char **argv)
{
    magcal_optics_cfg_t cfg = MAGCAL_OPTICS_CFG_DEFAULT;
    magcal_status_t st;
    unsigned long steps = 0u;
    unsigned long sum = 0u;
    size_t n;
    size_t i;
    unsigned long budget;
    if (argc != 5) {
        fprintf(stderr, "usage: slice_bench filter|thin ring|parked|burst N BUDGET\n");
        return 2;
    }
    n = (size_t)strtoul(argv[3], NULL, 10);
    budget = strtoul(argv[4], NULL, 10);
    if (n < 16u || n > MAGCAL_MAX_SAMPLES) {
        fprintf(stderr, "N must be 16..%u\n", (unsigned)MAGCAL_MAX_SAMPLES);
        return 2;
    }
    make_data(argv[2], n);
    if (strcmp(argv[1], "filter") == 0) {
        if (budget == 0u) {
            st = magcal_optics_filter(&cfg, g_pts, n, g_work, sizeof g_work, g_mask, NULL);
            steps = 1u;
        } else {
            magcal_optics_filter_slice_t s;
            st = magcal_optics_filter_begin(&s, &cfg, g_pts, n, g_work, sizeof g_work, g_mask,
                                            NULL);
            while (st == MAGCAL_OK || st == MAGCAL_IN_PROGRESS) {
                st = magcal_optics_filter_step(&s, (uint32_t)budget);
                prof_row();
                ++steps;
                if (st != MAGCAL_IN_PROGRESS) {
                    break;
                }
            }
        }
    } else {
        if (budget == 0u) {
            st = magcal_optics_thin(g_pts, n, NULL, g_work, sizeof g_work, g_mask);
            steps = 1u;
        } else {
            magcal_optics_thin_slice_t s;
            st = magcal_optics_thin_begin(&s, g_pts, n, NULL, g_work, sizeof g_work, g_mask);
            while (st == MAGCAL_OK || st == MAGCAL_IN_PROGRESS) {
                st = magcal_optics_thin_step(&s, (uint32_t)budget);
                prof_row();
                ++steps;
                if (st != MAGCAL_IN_PROGRESS) {
                    break;
                }
            }
        }
    }
    for (i = 0; i < n; ++i) {
        sum = sum * 31u + g_mask[i];
    }
    printf("%s %s n=%u budget=%lu status=%d steps=%lu mask=%08lx\n", argv[1], argv[2],
           (unsigned)n, budget, (int)st, steps, sum & 0xFFFFFFFFul);
    return st == MAGCAL_OK ? 0 : 1;
}
