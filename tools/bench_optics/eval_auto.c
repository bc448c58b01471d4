/*
 * Evaluation of the automatic OPTICS parameters (magcal_optics_filter with cfg.eps = 0) on
 * synthetic rings with known truth. Prints one line per scenario: fraction of true inliers kept
 * (mean and worst over n = 60, 100, 300, 700, 1024 and 5 seeds), fraction of outliers rejected,
 * median eps'/R. Numbers quoted in docs/optics.md come from `eval_optics_auto`.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "magcal/optics.h"

#define NMAX 1024u
static magcal_vec2_t g_pts[NMAX];
static uint8_t g_truth[NMAX];
static uint8_t g_mask[NMAX];
static uint32_t g_work[(MAGCAL_OPTICS_FILTER_WORKSPACE_LEN(NMAX) + 3u) / 4u];

static double uni(uint32_t *s)
{
    uint32_t x = *s;
    x ^= x << 13;
    x ^= x >> 17;
    x ^= x << 5;
    *s = x;
    return (double)x / 4294967296.0;
}

static double gauss(uint32_t *s)
{
    double u1 = uni(s), u2 = uni(s);
    return sqrt(-2.0 * log(u1 < 1e-300 ? 1e-300 : u1)) * cos(6.283185307179586 * u2);
}

typedef struct {
    const char *name;
    double sigma, arc, ratio, offset, scale;
    int random_angles;
    int kind;          /* 0 none, 1 glitch spikes (-36 R in y), 2 spikes at disp R random dir,
                          3 uniform background in a 3R box, 4 bursts */
    double frac, disp; /* outlier fraction, displacement in radii */
    int nbursts;
} scen_t;

static void gen(const scen_t *sc, size_t n, uint32_t seed)
{
    uint32_t s = seed * 2654435761u + 1u;
    size_t i;
    for (i = 0; i < n; ++i) {
        double psi = sc->random_angles ? sc->arc * uni(&s) : sc->arc * (double)i / (double)n;
        double a = psi * 0.017453292519943295;
        double hx = -sin(a), hy = cos(a);
        double x = hx + 0.1 * hy, y = sc->ratio * hy;
        g_pts[i].x = (float)(sc->scale * (x + sc->offset + sc->sigma * gauss(&s)));
        g_pts[i].y = (float)(sc->scale * (y - 0.6 * sc->offset + sc->sigma * gauss(&s)));
        g_truth[i] = 1u;
    }
    if (sc->kind == 4) {
        size_t per = (size_t)(sc->frac * (double)n / sc->nbursts);
        int b;
        for (b = 0; b < sc->nbursts; ++b) {
            size_t s0 = (size_t)((b + 0.3) * (double)n / sc->nbursts);
            double ang = 6.283185307179586 * uni(&s);
            for (i = s0; i < s0 + per && i < n; ++i) {
                g_pts[i].x += (float)(sc->scale * sc->disp * cos(ang));
                g_pts[i].y += (float)(sc->scale * sc->disp * sin(ang));
                g_truth[i] = 0u;
            }
        }
        return;
    }
    for (i = 0; sc->kind != 0 && i < n; ++i) {
        if (uni(&s) >= sc->frac) {
            continue;
        }
        g_truth[i] = 0u;
        if (sc->kind == 1) {
            g_pts[i].y -= (float)(36.0 * sc->scale);
        } else if (sc->kind == 2) {
            double ang = 6.283185307179586 * uni(&s);
            g_pts[i].x += (float)(sc->scale * sc->disp * cos(ang));
            g_pts[i].y += (float)(sc->scale * sc->disp * sin(ang));
        } else {
            g_pts[i].x = (float)(sc->scale * (sc->offset + 3.0 * uni(&s) - 1.5));
            g_pts[i].y = (float)(sc->scale * (-0.6 * sc->offset + 3.0 * uni(&s) - 1.5));
        }
    }
}

static int cmp_d(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

int main(void)
{
    static const size_t ns[] = {60u, 100u, 300u, 700u, 1024u};
    static const scen_t sc[] = {
        {"clean regular 1%", 0.01, 360, 1, 0, 1, 0, 0, 0, 0, 1},
        {"clean random 1%", 0.01, 360, 1, 0, 1, 1, 0, 0, 0, 1},
        {"heavy noise 5% random", 0.05, 360, 1, 0, 1, 1, 0, 0, 0, 1},
        {"arc 300 deg random", 0.01, 300, 1, 0, 1, 1, 0, 0, 0, 1},
        {"2000 LSB, hi 5R, ratio .55", 0.005, 360, 0.55, 5, 2000, 1, 0, 0, 0, 1},
        {"1e-3 scale, hi 5R, ratio .55", 0.005, 360, 0.55, 5, 1e-3, 1, 0, 0, 0, 1},
        {"glitch spikes 5% (-36 R)", 0.01, 360, 1, 0, 0.25, 1, 1, 0.05, 0, 1},
        {"spikes 5% at 0.3 R", 0.01, 360, 1, 0, 1, 0, 2, 0.05, 0.3, 1},
        {"spikes 5% at 0.5 R", 0.01, 360, 1, 0, 1, 0, 2, 0.05, 0.5, 1},
        {"spikes 5% at 1 R", 0.01, 360, 1, 0, 1, 0, 2, 0.05, 1.0, 1},
        {"spikes 5% at 2 R", 0.01, 360, 1, 0, 1, 0, 2, 0.05, 2.0, 1},
        {"uniform 5% in 3R box", 0.01, 360, 1, 0, 1, 0, 3, 0.05, 0, 1},
        {"burst 10% x1 at 0.5 R", 0.01, 360, 1, 0, 1, 0, 4, 0.10, 0.5, 1},
        {"burst 10% x1 at 2 R", 0.01, 360, 1, 0, 1, 0, 4, 0.10, 2.0, 1},
        {"burst 10% x1 at 4 R", 0.01, 360, 1, 0, 1, 0, 4, 0.10, 4.0, 1},
        {"burst 25% x3 at 0.5 R", 0.01, 360, 1, 0, 1, 0, 4, 0.25, 0.5, 3},
        {"burst 25% x3 at 2 R", 0.01, 360, 1, 0, 1, 0, 4, 0.25, 2.0, 3},
        {"burst 25% x3 at 4 R", 0.01, 360, 1, 0, 1, 0, 4, 0.25, 4.0, 3},
        {"burst 35% x3 at 1 R", 0.01, 360, 1, 0, 1, 0, 4, 0.35, 1.0, 3},
        {"burst 35% x3 at 2 R", 0.01, 360, 1, 0, 1, 0, 4, 0.35, 2.0, 3},
        {"burst 35% x3 at 4 R", 0.01, 360, 1, 0, 1, 0, 4, 0.35, 4.0, 3},
    };
    size_t is, in, i;
    uint32_t seed;
    printf("%-30s %9s %9s %9s %9s %6s\n", "scenario", "kept_mean", "kept_min", "rej_mean", "eps'/R",
           "fails");
    for (is = 0; is < sizeof sc / sizeof sc[0]; ++is) {
        double kept_sum = 0.0, kept_min = 1.0, rej_sum = 0.0, rel[25];
        char rej[16];
        int runs = 0, rej_runs = 0, fails = 0;
        for (in = 0; in < 5u; ++in) {
            for (seed = 1u; seed <= 5u; ++seed) {
                magcal_optics_cfg_t cfg = MAGCAL_OPTICS_CFG_DEFAULT;
                magcal_optics_result_t info;
                size_t n = ns[in], ti = 0u, ki = 0u, to = 0u, ko = 0u;
                double k;
                gen(&sc[is], n, seed + 100u * (uint32_t)in);
                if (magcal_optics_filter(&cfg, g_pts, n, g_work, sizeof g_work, g_mask, &info) !=
                    MAGCAL_OK) {
                    ++fails;
                    rel[runs++] = 0.0;
                    kept_min = 0.0;
                    continue;
                }
                for (i = 0; i < n; ++i) {
                    if (g_truth[i]) {
                        ++ti;
                        ki += g_mask[i];
                    } else {
                        ++to;
                        ko += g_mask[i];
                    }
                }
                k = (double)ki / (double)ti;
                kept_sum += k;
                kept_min = k < kept_min ? k : kept_min;
                if (to > 0u) {
                    rej_sum += 1.0 - (double)ko / (double)to;
                    ++rej_runs;
                }
                rel[runs++] = (double)info.eps_prime / sc[is].scale;
            }
        }
        qsort(rel, (size_t)runs, sizeof rel[0], cmp_d);
        if (rej_runs > 0) {
            snprintf(rej, sizeof rej, "%.3f", rej_sum / rej_runs);
        } else {
            snprintf(rej, sizeof rej, "-");
        }
        printf("%-30s %9.4f %9.4f %9s %9.4f %6d\n", sc[is].name,
               runs > fails ? kept_sum / (runs - fails) : 0.0, kept_min, rej, rel[runs / 2], fails);
    }
    return 0;
}
