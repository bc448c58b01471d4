/*
 * Benchmark driver for the OPTICS filter: one call on a deterministic noisy ring with 5 % far
 * spikes, so `valgrind --tool=callgrind --toggle-collect=bench_target` counts exactly one run.
 *
 *   bench_optics MODE N [EPS_REL]
 *     MODE: classic-brute | classic-grid | improved-brute | improved-grid | auto-filter | dbscan-grid
 *           | dbscan-brute
 *     N:    number of samples (16..MAGCAL_MAX_SAMPLES)
 *     EPS_REL: eps in ring radii (default: inf for *-brute, 0.1 otherwise), or "auto": the eps of
 *              magcal_optics_auto_params (computed before, not counted)
 * Prints the parameters and a checksum of the outputs (so the work cannot be optimised away).
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "magcal/dbscan.h"
#include "magcal/optics.h"

static magcal_vec2_t g_pts[MAGCAL_MAX_SAMPLES];
static uint32_t g_work[(MAGCAL_OPTICS_FILTER_WORKSPACE_LEN(MAGCAL_MAX_SAMPLES) + 3u) / 4u];
static uint16_t g_order[MAGCAL_MAX_SAMPLES];
static float g_reach[MAGCAL_MAX_SAMPLES];
static float g_core[MAGCAL_MAX_SAMPLES];
static int16_t g_labels[MAGCAL_MAX_SAMPLES];
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

static void make_ring(size_t n)
{
    uint32_t s = 12345u;
    size_t i;
    for (i = 0; i < n; ++i) {
        float a = 6.2831853f * rng_unit(&s);
        float r = 1.0f + 0.02f * (rng_unit(&s) + rng_unit(&s) + rng_unit(&s) - 1.5f);
        g_pts[i].x = 0.3f + r * cosf(a);
        g_pts[i].y = -0.2f + 0.8f * r * sinf(a);
        if (rng_unit(&s) < 0.05f) {
            g_pts[i].y -= 9.0f;
        }
    }
}

/* The measured call (callgrind --toggle-collect=bench_target). */
__attribute__((noinline)) int bench_target(const char *mode, size_t n, float eps)
{
    magcal_optics_cfg_t c = MAGCAL_OPTICS_CFG_DEFAULT;
    c.eps = eps;
    c.min_pts = 4u;
    if (strcmp(mode, "auto-filter") == 0) {
        magcal_optics_cfg_t a = MAGCAL_OPTICS_CFG_DEFAULT;
        return (int)magcal_optics_filter(&a, g_pts, n, g_work, sizeof g_work, g_mask, NULL);
    }
    if (strncmp(mode, "dbscan", 6) == 0) {
        magcal_dbscan_cfg_t d = MAGCAL_DBSCAN_CFG_DEFAULT;
        d.eps = eps;
        d.min_pts = 4u;
        d.neighbors = strstr(mode, "grid") ? MAGCAL_NEIGHBORS_GRID : MAGCAL_NEIGHBORS_BRUTE;
        return (int)magcal_dbscan_run(&d, g_pts, n, g_work, sizeof g_work, g_labels, NULL, NULL);
    }
    c.order = strncmp(mode, "classic", 7) == 0 ? MAGCAL_OPTICS_CLASSIC : MAGCAL_OPTICS_IMPROVED;
    c.neighbors = strstr(mode, "grid") ? MAGCAL_NEIGHBORS_GRID : MAGCAL_NEIGHBORS_BRUTE;
    return (int)magcal_optics_run(&c, g_pts, n, g_work, sizeof g_work, g_order, g_reach, g_core,
                                  NULL, NULL);
}

int main(int argc, char **argv)
{
    size_t n, i;
    float eps;
    double sum = 0.0;
    int st;
    if (argc < 3) {
        fprintf(stderr, "usage: %s MODE N [EPS_REL]\n", argv[0]);
        return 2;
    }
    n = (size_t)strtoul(argv[2], NULL, 10);
    if (n < 16u || n > MAGCAL_MAX_SAMPLES) {
        fprintf(stderr, "N out of range\n");
        return 2;
    }
    eps = argc > 3 ? strtof(argv[3], NULL) : (strstr(argv[1], "brute") ? INFINITY : 0.1f);
    make_ring(n);
    if (argc > 3 && strcmp(argv[3], "auto") == 0) {
        uint16_t mp;
        float ep;
        if (magcal_optics_auto_params(g_pts, n, g_work, sizeof g_work, &eps, &mp, &ep) !=
            MAGCAL_OK) {
            fprintf(stderr, "auto params failed\n");
            return 1;
        }
    }
    st = bench_target(argv[1], n, eps);
    for (i = 0; i < n; ++i) {
        sum += isinf(g_reach[i]) ? 0.0 : (double)g_reach[i];
        sum += (double)g_order[i] + (double)g_labels[i] + (double)g_mask[i];
    }
    printf("mode=%s n=%u eps=%g status=%d checksum=%.6f\n", argv[1], (unsigned)n, (double)eps, st,
           sum);
    return st == 0 ? 0 : 1;
}
