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

/* ------------------------------------------------------------------ 3-D sets */

static double rnd3(uint32_t *s)
{
    uint32_t x = *s;
    x ^= x << 13;
    x ^= x >> 17;
    x ^= x << 5;
    *s = x;
    return ((double)(x >> 8) + 0.5) / 16777216.0;
}

static double gauss3(uint32_t *s)
{
    double u1 = rnd3(s), u2 = rnd3(s);
    return sqrt(-2.0 * log(u1)) * cos(6.283185307179586 * u2);
}

void bench_generate3(magcal_vec3_t *pts3, size_t n)
{
    static const double axes[3] = {1.1, 0.93, 1.04};
    static const double off[3] = {300.0, -200.0, 150.0};
    const size_t n_burst = (3u * n) / 100u;
    const size_t b0 = n / 3u;
    uint32_t s = 0x3D3D3D3Du;
    double ub[3] = {0.48, -0.6, 0.64};
    size_t i;
    int a;
    for (i = 0u; i < n; ++i) {
        double u[3], r, sc = 1.0;
        u[0] = gauss3(&s);
        u[1] = gauss3(&s);
        u[2] = gauss3(&s);
        r = sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
        if (i % 20u == 7u) {
            sc = 1.7 + 0.8 * rnd3(&s); /* 5 % scattered */
        }
        if (i >= b0 && i < b0 + n_burst) {
            u[0] = ub[0];
            u[1] = ub[1];
            u[2] = ub[2];
            r = 1.0;
            sc = 1.8; /* stuck burst */
        }
        for (a = 0; a < 3; ++a) {
            double v = off[a] + sc * 500.0 * axes[a] * u[a] / r + (sc == 1.8 ? 0.0 : 3.0 * gauss3(&s));
            if (a == 0) {
                pts3[i].x = (float)v;
            } else if (a == 1) {
                pts3[i].y = (float)v;
            } else {
                pts3[i].z = (float)v;
            }
        }
    }
}

void bench_generate_drive(magcal_aided_epoch_t *ep, size_t n)
{
    static const double w[3][3] = {{1.10, 0.04, -0.03}, {0.05, 0.93, 0.05}, {-0.04, 0.06, 1.04}};
    static const double v[3] = {18.0, -11.0, 27.0};
    static const float b[3] = {20.0f, 1.2f, 44.0f};
    const double d2r = BENCH_PI / 180.0;
    const double a = 0.98;
    const double drive = sqrt(1.0 - a * a) * 1.0 * d2r;
    uint32_t s = 0x0A1DEDu;
    double yaw = 10.0 * d2r, pitch = 0.0, roll = 0.0;
    size_t k, leg = 0u;
    int i;
    for (k = 0u; k < n; ++k) {
        size_t ph = k % 75u;
        float c[3][3];
        double h[3];
        if (ph >= 60u) {
            yaw += ((leg % 4u) == 3u ? -6.0 : 6.0) * d2r;
            if (ph == 74u) {
                leg++;
            }
        }
        pitch = a * pitch + drive * gauss3(&s);
        roll = a * roll + drive * gauss3(&s);
        (void)magcal_aided_dcm((float)roll, (float)pitch, (float)yaw, c);
        for (i = 0; i < 3; ++i) {
            h[i] = (double)c[0][i] * b[0] + (double)c[1][i] * b[1] + (double)c[2][i] * b[2];
        }
        ep[k].m.x = (float)(w[0][0] * h[0] + w[0][1] * h[1] + w[0][2] * h[2] + v[0] + 0.05 * gauss3(&s));
        ep[k].m.y = (float)(w[1][0] * h[0] + w[1][1] * h[1] + w[1][2] * h[2] + v[1] + 0.05 * gauss3(&s));
        ep[k].m.z = (float)(w[2][0] * h[0] + w[2][1] * h[1] + w[2][2] * h[2] + v[2] + 0.05 * gauss3(&s));
        ep[k].roll_rad = (float)(roll + 0.01 * d2r * gauss3(&s));
        ep[k].pitch_rad = (float)(pitch + 0.01 * d2r * gauss3(&s));
        ep[k].yaw_rad = (float)(yaw + 0.05 * d2r * gauss3(&s));
        ep[k].b_ref_ned.x = b[0];
        ep[k].b_ref_ned.y = b[1];
        ep[k].b_ref_ned.z = b[2];
        ep[k].dop = 1.2f;
    }
}

void bench_generate_tumble(magcal_vec3_t *pts3, size_t n, uint32_t seed)
{
    static const double w[3][3] = {{1.04, 0.03, -0.02}, {0.03, 0.97, 0.01}, {-0.02, 0.01, 1.01}};
    static const double off[3] = {28.6, -40.0, -27.4};
    uint32_t s = seed | 1u;
    size_t i;
    int a;
    for (i = 0u; i < n; ++i) {
        /* a hand tumble: a spiral from the south to the north pole, 6 turns, jittered */
        const double t = ((double)i + 0.5) / (double)n;
        const double el = asin(2.0 * t - 1.0) + 0.05 * gauss3(&s);
        const double az = 6.0 * 6.283185307179586 * t + 0.1 * gauss3(&s);
        const double u[3] = {50.0 * cos(el) * cos(az), 50.0 * cos(el) * sin(az), 50.0 * sin(el)};
        double v[3];
        for (a = 0; a < 3; ++a) {
            v[a] = off[a] + w[a][0] * u[0] + w[a][1] * u[1] + w[a][2] * u[2] + 0.4 * gauss3(&s);
        }
        pts3[i].x = (float)v[0];
        pts3[i].y = (float)v[1];
        pts3[i].z = (float)v[2];
    }
}
