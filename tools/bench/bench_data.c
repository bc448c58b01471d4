/* Deterministic data of the bench (host driver and the M4F cycle image share it): a distorted
 * compass-swing ring (hard iron (300, -200), semi-axes 520 x 410 turned 30 deg, Gaussian noise
 * sigma 3, one full turn with jitter) with 12 % singular points interleaved in the sequence: 6 %
 * scattered over a box 3 R around the ring, 3 % a dense glitch cluster 6 R away, 3 % one burst of
 * consecutive samples 35 % outside the ring. xorshift32 with a fixed seed; double-precision
 * generator (tools only), so two libms may differ in the last bit of a float sample. */
#include "bench_data.h"

#include <math.h>
#include <string.h>

#define BENCH_PI 3.14159265358979323846

static uint32_t g_rng = 0x2545F491u;

static uint32_t rng_next(void)
{
    uint32_t x = g_rng;
    x ^= x << 13;
    x ^= x >> 17;
    x ^= x << 5;
    g_rng = x;
    return x;
}

static double rng_uniform(void) /* (0, 1) */
{
    return ((double)(rng_next() >> 8) + 0.5) / 16777216.0;
}

static double rng_gauss(void)
{
    double u1 = rng_uniform();
    double u2 = rng_uniform();
    return sqrt(-2.0 * log(u1)) * cos(2.0 * BENCH_PI * u2);
}

/* Point of the distorted ring at heading-like angle t (rad), plus radial offset dr (fraction). */
static magcal_vec2_t ring_point(double t, double scale)
{
    const double a = 520.0, b = 410.0, th = 30.0 * BENCH_PI / 180.0;
    const double cx = 300.0, cy = -200.0;
    double u = a * scale * cos(t);
    double v = b * scale * sin(t);
    magcal_vec2_t p;
    p.x = (float)(cx + cos(th) * u - sin(th) * v);
    p.y = (float)(cy + sin(th) * u + cos(th) * v);
    return p;
}

/* Put `count` samples of `kind` evenly through the sequence (next free slot after each target). */
static void place(uint8_t *g_kind, size_t n, size_t count, uint8_t kind, size_t phase_num,
                  size_t phase_den)
{
    size_t j, k;
    for (j = 0u; j < count; ++j) {
        k = ((j * phase_den + phase_num) * n) / (count * phase_den);
        while (g_kind[k % n] != 0u) {
            ++k;
        }
        g_kind[k % n] = kind;
    }
}

void bench_generate(magcal_vec2_t *g_pts, uint8_t *g_kind, size_t n)
{
    const double R = sqrt(520.0 * 410.0);
    size_t n_scatter = (n * 6u) / 100u;
    size_t n_glitch = (n * 3u) / 100u;
    size_t n_burst = (n * 3u) / 100u;
    size_t n_ring = n - n_scatter - n_glitch - n_burst;
    size_t i, r = 0u;

    g_rng = 0x2545F491u;
    memset(g_kind, 0, n);
    for (i = 0u; i < n_burst; ++i) {
        g_kind[n / 3u + i] = 3u; /* one burst of consecutive samples a third into the turn */
    }
    place(g_kind, n, n_scatter, 1u, 1u, 2u);
    place(g_kind, n, n_glitch, 2u, 1u, 4u);
    for (i = 0u; i < n; ++i) {
        double t = 2.0 * BENCH_PI * ((double)r + 0.8 * rng_uniform()) / (double)n_ring;
        if (g_kind[i] == 0u) {
            magcal_vec2_t p = ring_point(t, 1.0);
            p.x = (float)((double)p.x + 3.0 * rng_gauss());
            p.y = (float)((double)p.y + 3.0 * rng_gauss());
            g_pts[i] = p;
            ++r;
        } else if (g_kind[i] == 1u) {
            g_pts[i].x = (float)(300.0 + 3.0 * R * (2.0 * rng_uniform() - 1.0));
            g_pts[i].y = (float)(-200.0 + 3.0 * R * (2.0 * rng_uniform() - 1.0));
        } else if (g_kind[i] == 2u) {
            g_pts[i].x = (float)(300.0 + 6.0 * R + 0.02 * R * rng_gauss());
            g_pts[i].y = (float)(-200.0 - 2.0 * R + 0.02 * R * rng_gauss());
        } else {
            /* burst: where the vehicle is at this point of the turn, 35 % outside the ring */
            magcal_vec2_t p = ring_point(t, 1.35);
            p.x = (float)((double)p.x + 3.0 * rng_gauss());
            p.y = (float)((double)p.y + 3.0 * rng_gauss());
            g_pts[i] = p;
        }
    }
}
