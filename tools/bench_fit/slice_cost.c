/*
 * slice_cost: host driver for the per-step instruction counts of the time-sliced consensus run and
 * ellipse fit (slice contract, issue 13). Data: a distorted ring (r ~ 1500 LSB, hard iron
 * (6000, -4500), +-3.5 LSB noise), directions at golden-angle steps, every 7th sample a spike
 * 300 LSB off the ring.
 *
 *   slice_cost consensus|fit N BUDGET     (N <= 1024; BUDGET 0 = the one-shot call)
 *
 * Per-step counts (one callgrind dump per step call):
 *   LD_BIND_NOW=1 valgrind --tool=callgrind --toggle-collect=magcal_consensus_step \
 *       --dump-after=magcal_consensus_step --callgrind-out-file=/tmp/sc.%p \
 *       build/host/tools/bench_fit/slice_cost consensus 288 6000
 * and the one-shot total with --toggle-collect=magcal_consensus_run ... consensus 288 0.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "magcal/consensus.h"
#include "magcal/ellipse.h"

#define SC_MAX 1024u

static magcal_vec2_t g_pts[SC_MAX];
static uint8_t g_inl[SC_MAX];
static MAGCAL_CONSENSUS_WORKSPACE_DECLARE(g_work, SC_MAX);

static void make_data(size_t n)
{
    uint32_t rng = 12345u;
    size_t i;
    for (i = 0u; i < n; ++i) {
        /* a full turn in a shuffled order (stride 7 mod n... via the golden angle) */
        float psi = 2.3999632f * (float)i;
        float hx = -1500.0f * sinf(psi);
        float hy = 1500.0f * cosf(psi);
        rng ^= rng << 13;
        rng ^= rng >> 17;
        rng ^= rng << 5;
        g_pts[i].x = 1.15f * hx + 0.2f * hy + 6000.0f + (float)(rng & 7u) - 3.5f;
        g_pts[i].y = 0.1f * hx + 0.85f * hy - 4500.0f + (float)((rng >> 3) & 7u) - 3.5f;
        if (i % 7u == 3u) {
            g_pts[i].x += 300.0f;
        }
    }
}

int main(int argc, char **argv)
{
    size_t n;
    unsigned long budget;
    unsigned steps = 0u;
    magcal_status_t st;
    if (argc != 4) {
        fprintf(stderr, "usage: slice_cost consensus|fit N BUDGET\n");
        return 2;
    }
    n = (size_t)strtoul(argv[2], NULL, 10);
    budget = strtoul(argv[3], NULL, 10);
    if (n < 5u || n > SC_MAX || budget > 0xFFFFFFFFul) {
        fprintf(stderr, "N in 5..%u, BUDGET in 0..2^32-1\n", SC_MAX);
        return 2;
    }
    make_data(n);
    if (strcmp(argv[1], "consensus") == 0) {
        magcal_consensus_cfg_t cfg = MAGCAL_CONSENSUS_CFG_DEFAULT;
        magcal_consensus_result_t res;
        if (budget == 0u) {
            st = magcal_consensus_run(&cfg, g_pts, n, NULL, g_work, sizeof g_work, g_inl, &res);
        } else {
            magcal_consensus_slice_t sl;
            st = magcal_consensus_begin(&sl, &cfg, g_pts, n, NULL, g_work, sizeof g_work, g_inl, &res);
            while (st == MAGCAL_OK || st == MAGCAL_IN_PROGRESS) {
                st = magcal_consensus_step(&sl, (uint32_t)budget);
                ++steps;
                if (st != MAGCAL_IN_PROGRESS) {
                    break;
                }
            }
        }
        printf("consensus n %u: status %d, %u steps, inliers %u, draws %u, rounds %u\n", (unsigned)n, (int)st,
               steps, (unsigned)res.n_inliers, (unsigned)res.draws, (unsigned)res.rounds);
    } else {
        magcal_ellipse_t e;
        if (budget == 0u) {
            st = magcal_ellipse_fit(g_pts, n, NULL, &e);
        } else {
            magcal_ellipse_fit_slice_t sl;
            st = magcal_ellipse_fit_begin(&sl, g_pts, n, NULL, &e);
            while (st == MAGCAL_OK || st == MAGCAL_IN_PROGRESS) {
                st = magcal_ellipse_fit_step(&sl, (uint32_t)budget);
                ++steps;
                if (st != MAGCAL_IN_PROGRESS) {
                    break;
                }
            }
        }
        printf("fit n %u: status %d, %u steps\n", (unsigned)n, (int)st, steps);
    }
    return (st == MAGCAL_OK) ? 0 : 1;
}
