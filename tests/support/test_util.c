#include "test_util.h"

#include <math.h>

#include "magcal/heading.h"
#include "unity.h"

double test_rand_uniform(uint32_t *state)
{
    uint32_t x = *state ? *state : 0x12345678u;
    x ^= x << 13;
    x ^= x >> 17;
    x ^= x << 5;
    *state = x;
    return (double)x / 4294967296.0;
}

double test_rand_normal(uint32_t *state)
{
    double u1 = test_rand_uniform(state);
    double u2 = test_rand_uniform(state);
    if (u1 < 1e-300) {
        u1 = 1e-300;
    }
    return sqrt(-2.0 * log(u1)) * cos(2.0 * 3.14159265358979323846 * u2);
}

magcal_vec2_t test_distorted_sample(const test_distortion_t *d, double psi_deg, double sigma, uint32_t *rng)
{
    double psi = psi_deg * 3.14159265358979323846 / 180.0;
    double hx = -d->h0 * sin(psi);
    double hy = d->h0 * cos(psi);
    magcal_vec2_t m;
    double nx = sigma > 0.0 ? sigma * test_rand_normal(rng) : 0.0;
    double ny = sigma > 0.0 ? sigma * test_rand_normal(rng) : 0.0;
    m.x = (float)(d->t[0][0] * hx + d->t[0][1] * hy + d->bx + nx);
    m.y = (float)(d->t[1][0] * hx + d->t[1][1] * hy + d->by + ny);
    return m;
}

void test_make_ring(const test_distortion_t *d, size_t n, double start_deg, double arc_deg,
                    double sigma, uint32_t seed, magcal_vec2_t *out, float *psi_out)
{
    uint32_t rng = seed ? seed : 1u;
    size_t k;
    for (k = 0; k < n; ++k) {
        double psi = start_deg + arc_deg * (double)k / (double)n;
        out[k] = test_distorted_sample(d, psi, sigma, &rng);
        if (psi_out) {
            psi_out[k] = (float)fmod(psi + 360.0, 360.0);
        }
    }
}

double test_angle_diff_deg(double a, double b)
{
    double r = fmod(a - b, 360.0);
    if (r > 180.0) {
        r -= 360.0;
    } else if (r <= -180.0) {
        r += 360.0;
    }
    return r;
}

double test_radius_spread(const magcal_cal2d_t *c, const magcal_vec2_t *pts, const uint8_t *skip, size_t n)
{
    double s = 0.0;
    double s2 = 0.0;
    size_t i;
    size_t k = 0u;
    for (i = 0; i < n; ++i) {
        magcal_vec2_t h;
        double r;
        if (skip != NULL && skip[i] != 0u) {
            continue;
        }
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_correct_apply(c, pts[i], &h));
        r = sqrt((double)h.x * h.x + (double)h.y * h.y);
        s += r;
        s2 += r * r;
        ++k;
    }
    TEST_ASSERT_TRUE(k > 0u);
    s /= (double)k;
    return sqrt(s2 / (double)k - s * s) / s;
}
