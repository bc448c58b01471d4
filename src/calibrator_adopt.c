/*
 * Estimates behind the 2-D calibrator's report and adoption rule: the harmonic analysis of the
 * corrected radius (what a calibration's centre and soft-iron errors do to headings, separated
 * from noise) and the count of distinct sample values (quantisation). The rule itself and the
 * formulas are in include/magcal/calibrator.h and docs/calibrator.md.
 */
#include <math.h>
#include <string.h>

#include "calibrator_internal.h"
#include "magcal_internal.h"

#define HARM_K 5u /* 1, cos, sin, cos 2, sin 2 */
#define HARM_PIVOT 1.0e-6f

/* Regressors of one corrected sample h (|h| = rho > 0): 1, cos phi, sin phi, cos 2phi, sin 2phi. */
static void harm_row(magcal_vec2_t h, float rho, float g[HARM_K])
{
    float c = h.x / rho;
    float s = h.y / rho;
    g[0] = 1.0f;
    g[1] = c;
    g[2] = s;
    g[3] = c * c - s * s;
    g[4] = 2.0f * c * s;
}

/* Solve (copy of the lower triangle of) nm x = b; 0 on success. */
static int harm_solve(const float *nm, float *work, float *b)
{
    (void)memcpy(work, nm, (size_t)HARM_K * HARM_K * sizeof(float));
    return magcal_ldlt_solve(work, b, HARM_K, HARM_PIVOT, NULL) == MAGCAL_OK ? 0 : -1;
}

void magcal_cal_harmonics(const magcal_vec2_t *pts, size_t n, const uint8_t *mask,
                          const magcal_cal2d_t *c, float dup_factor, float sigma_floor,
                          float *scratch, magcal_cal_harm_t *out)
{
    float *nm = scratch;                   /* 5x5 normal matrix G^T G */
    float *wk = scratch + (size_t)HARM_K * HARM_K; /* solver copy */
    float *beta = wk + (size_t)HARM_K * HARM_K;    /* 5: G^T d, then the coefficients */
    float *col = beta + HARM_K;            /* 5: columns of the inverse */
    float inv4[4][4];
    float sum = 0.0f;
    float ss = 0.0f;
    float mean;
    float s2;
    float s2p; /* noise variance seen by the parameters */
    size_t k = 0u;
    size_t i;
    size_t r;
    size_t q;

    (void)memset(out, 0, sizeof *out);
    for (i = 0u; i < n; ++i) {
        magcal_vec2_t h;
        if (mask[i] != 0u && magcal_correct_apply(c, pts[i], &h) == MAGCAL_OK) {
            sum += sqrtf(h.x * h.x + h.y * h.y);
            ++k;
        }
    }
    if (k <= HARM_K || !(sum > 0.0f) || !magcal_isfinite_f(sum)) {
        return;
    }
    mean = sum / (float)k;
    out->mean_radius = mean;
    (void)memset(nm, 0, (size_t)HARM_K * HARM_K * sizeof(float));
    (void)memset(beta, 0, HARM_K * sizeof(float));
    for (i = 0u; i < n; ++i) {
        magcal_vec2_t h;
        if (mask[i] != 0u && magcal_correct_apply(c, pts[i], &h) == MAGCAL_OK) {
            float rho = sqrtf(h.x * h.x + h.y * h.y);
            float g[HARM_K];
            float d;
            if (!(rho > 0.0f)) {
                continue;
            }
            d = rho / mean - 1.0f;
            harm_row(h, rho, g);
            for (r = 0u; r < HARM_K; ++r) {
                for (q = 0u; q <= r; ++q) {
                    nm[r * HARM_K + q] += g[r] * g[q];
                }
                beta[r] += g[r] * d;
            }
        }
    }
    if (harm_solve(nm, wk, beta) != 0) {
        return; /* headings too clumped for a first and second harmonic: singular design */
    }
    /* residual variance after the harmonic fit, second pass (no cancellation of sums) */
    for (i = 0u; i < n; ++i) {
        magcal_vec2_t h;
        if (mask[i] != 0u && magcal_correct_apply(c, pts[i], &h) == MAGCAL_OK) {
            float rho = sqrtf(h.x * h.x + h.y * h.y);
            float g[HARM_K];
            float e;
            if (!(rho > 0.0f)) {
                continue;
            }
            harm_row(h, rho, g);
            e = rho / mean - 1.0f;
            for (r = 0u; r < HARM_K; ++r) {
                e -= g[r] * beta[r];
            }
            ss += e * e;
        }
    }
    {
        /* measured residual noise vs the rounding noise of the samples' LSB: rounding not seen in
         * the residuals (a lattice lying almost on a conic) is systematic along the ring, one
         * independent error per MAGCAL_CAL_LATTICE_K distinct values */
        const size_t k_dof = k - HARM_K;
        const float sm2 = ss / (float)k_dof;
        const float hid = fmaxf(sigma_floor * sigma_floor - sm2, 0.0f);
        out->sigma_rel = sqrtf(sm2 + hid);
        s2 = out->sigma_rel * out->sigma_rel;
        s2p = sm2 + MAGCAL_CAL_LATTICE_K * hid;
    }
    /* (G^T G)^-1 restricted to the four harmonics: columns 1..4 */
    for (q = 1u; q < HARM_K; ++q) {
        (void)memset(col, 0, HARM_K * sizeof(float));
        col[q] = 1.0f;
        if (harm_solve(nm, wk, col) != 0) {
            return;
        }
        for (r = 1u; r < HARM_K; ++r) {
            inv4[r - 1u][q - 1u] = col[r];
        }
    }
    {
        float tr = 0.0f;
        float tr2 = 0.0f;
        float b2 = 0.0f;
        for (r = 0u; r < 4u; ++r) {
            tr += inv4[r][r];
            b2 += beta[r + 1u] * beta[r + 1u];
            for (q = 0u; q < 4u; ++q) {
                tr2 += inv4[r][q] * inv4[q][r];
            }
        }
        /* variance of the harmonics (independent samples: dup_factor), and the O(sigma^2)
         * bias of a least-squares fit whose regressors are noisy too: sigma^2 (G^T G / k)^-1,
         * large exactly where the design is weak (clumps: short arcs) */
        out->err2 = 0.5f * b2;
        out->noise2 = 0.5f * s2p * dup_factor * tr;
        out->noise2_sd = sqrtf(0.5f * tr2) * s2p * dup_factor;
        out->design = 0.25f * (float)k * sqrtf(tr2);
        out->bias2 =
            MAGCAL_CAL_BIAS_K * MAGCAL_CAL_BIAS_K * 0.5f * s2 * s2 * (float)k * (float)k * tr2;
    }
    out->ok = 1u;
}

/* Lexicographic (x, y) order of two samples: -1, 0, 1. */
static int dist_cmp(magcal_vec2_t a, magcal_vec2_t b)
{
    if (a.x < b.x) {
        return -1;
    }
    if (a.x > b.x) {
        return 1;
    }
    if (a.y < b.y) {
        return -1;
    }
    return a.y > b.y ? 1 : 0;
}

size_t magcal_cal_distinct(const magcal_vec2_t *pts, size_t n, const uint8_t *mask, uint16_t *idx,
                           float *step)
{
    static const uint16_t gaps[] = {701u, 301u, 132u, 57u, 23u, 10u, 4u, 1u};
    size_t m = 0u;
    size_t g;
    size_t i;
    size_t distinct;
    for (i = 0u; i < n; ++i) {
        if (mask[i] != 0u) {
            idx[m] = (uint16_t)i;
            ++m;
        }
    }
    if (m == 0u) {
        return 0u;
    }
    /* shell sort of the indices by (x, y), Ciura's gaps: bounded, no recursion */
    for (g = 0u; g < sizeof gaps / sizeof gaps[0]; ++g) {
        size_t gap = gaps[g];
        if (gap >= m) {
            continue;
        }
        for (i = gap; i < m; ++i) {
            uint16_t v = idx[i];
            size_t j = i;
            while (j >= gap && dist_cmp(pts[idx[j - gap]], pts[v]) > 0) {
                idx[j] = idx[j - gap];
                j -= gap;
            }
            idx[j] = v;
        }
    }
    /* distinct values; smallest positive step between neighbours in this order: of x between
     * columns, of y inside a column (the LSB of quantised data, ~0 for continuous data) */
    distinct = 1u;
    *step = INFINITY;
    for (i = 1u; i < m; ++i) {
        magcal_vec2_t a = pts[idx[i - 1u]];
        magcal_vec2_t b = pts[idx[i]];
        if (dist_cmp(a, b) != 0) {
            float d = b.x > a.x ? b.x - a.x : b.y - a.y;
            ++distinct;
            if (d > 0.0f && d < *step) {
                *step = d;
            }
        }
    }
    if (!magcal_isfinite_f(*step)) {
        *step = 0.0f;
    }
    return distinct;
}
