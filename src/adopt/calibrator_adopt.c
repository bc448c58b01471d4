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

/* Per-visit weights, estimated M4F instructions: host callgrind x 1.2, then x 1.8 (distinct x 1.6)
 * as measured in the continuous calibrator on QEMU (cont_trace.elf, tools/bench/cont_weights.py). */
#define HARM_W_SKIP 60u     /* a sample outside the mask, or a pass switch */
#define HARM_W_SUM 400u     /* correction + radius */
#define HARM_W_NORMAL 740u  /* correction, radius, regressors, 15 + 5 products */
#define HARM_W_RESID 540u   /* correction, radius, regressors, residual */
#define HARM_W_SOLVE1 2700u /* one 5x5 LDL^T solve (copy + factorisation + substitutions) */
#define HARM_W_FINISH 720u  /* the traces and estimates */
#define DIST_W_COLLECT 32u /* one mask test and index write */
#define DIST_W_SORT 80u    /* one comparison (and move) of the shell sort */
#define DIST_W_COUNT 64u   /* one neighbour comparison */

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

void magcal_cal_harm_begin(magcal_cal_harm_slice_t *h, const magcal_vec2_t *pts, size_t n,
                           const uint8_t *mask, const magcal_cal2d_t *c, float dup_factor,
                           float sigma_floor, float *scratch, magcal_cal_harm_t *out)
{
    h->pts = pts;
    h->n = n;
    h->mask = mask;
    h->c = *c;
    h->dup = dup_factor;
    h->floor = sigma_floor;
    h->scratch = scratch;
    h->out = out;
    h->sum = 0.0f;
    h->mean = 0.0f;
    h->ss = 0.0f;
    h->i = 0u;
    h->k = 0u;
    h->pass = 0u;
    (void)memset(out, 0, sizeof *out);
}

/* Pass 0: sum of the corrected radii of the masked samples. */
static int harm_pass_sum(magcal_cal_harm_slice_t *h, magcal_cal_budget_t *b)
{
    while (h->i < h->n) {
        magcal_vec2_t v;
        const size_t i = h->i;
        h->i++;
        if (h->mask[i] != 0u && magcal_correct_apply(&h->c, h->pts[i], &v) == MAGCAL_OK) {
            h->sum += sqrtf(v.x * v.x + v.y * v.y);
            h->k++;
            if (magcal_cal_charge(b, HARM_W_SUM) != 0) {
                return 0;
            }
        } else if (magcal_cal_charge(b, HARM_W_SKIP) != 0) {
            return 0;
        } else {
            /* not masked: next */
        }
    }
    return 1;
}

/* Passes 1 (normal equations, with_res 0) and 2 (residual sum of squares, with_res 1). */
static int harm_pass_fit(magcal_cal_harm_slice_t *h, magcal_cal_budget_t *b, int with_res)
{
    float *nm = h->scratch;
    float *beta = h->scratch + 2u * (size_t)HARM_K * HARM_K;
    while (h->i < h->n) {
        magcal_vec2_t v;
        const size_t i = h->i;
        h->i++;
        if (h->mask[i] != 0u && magcal_correct_apply(&h->c, h->pts[i], &v) == MAGCAL_OK) {
            float rho = sqrtf(v.x * v.x + v.y * v.y);
            float g[HARM_K];
            if (rho > 0.0f) {
                float d = rho / h->mean - 1.0f;
                size_t r;
                harm_row(v, rho, g);
                if (with_res == 0) {
                    size_t q;
                    for (r = 0u; r < HARM_K; ++r) {
                        for (q = 0u; q <= r; ++q) {
                            nm[r * HARM_K + q] += g[r] * g[q];
                        }
                        beta[r] += g[r] * d;
                    }
                } else {
                    for (r = 0u; r < HARM_K; ++r) {
                        d -= g[r] * beta[r];
                    }
                    h->ss += d * d;
                }
            }
            if (magcal_cal_charge(b, with_res == 0 ? HARM_W_NORMAL : HARM_W_RESID) != 0) {
                return 0;
            }
        } else if (magcal_cal_charge(b, HARM_W_SKIP) != 0) {
            return 0;
        } else {
            /* not masked: next */
        }
    }
    return 1;
}

/* Pass 3: the residual noise (measured vs the rounding noise of the samples' LSB: rounding not
 * seen in the residuals, a lattice lying almost on a conic, is systematic along the ring, one
 * independent error per MAGCAL_CAL_LATTICE_K distinct values). */
static void harm_noise(magcal_cal_harm_slice_t *h)
{
    const size_t k_dof = h->k - HARM_K;
    const float sm2 = h->ss / (float)k_dof;
    const float hid = fmaxf(h->floor * h->floor - sm2, 0.0f);
    h->out->sigma_rel = sqrtf(sm2 + hid);
    h->s2 = h->out->sigma_rel * h->out->sigma_rel;
    h->s2p = sm2 + MAGCAL_CAL_LATTICE_K * hid; /* noise variance seen by the parameters */
}

/* Passes 4..7: column q of (G^T G)^-1 restricted to the four harmonics (one 5x5 solve per
 * visit) into inv4 (scratch); 0 when singular. */
static int harm_column(magcal_cal_harm_slice_t *h, size_t q)
{
    float *nm = h->scratch;
    float *wk = h->scratch + (size_t)HARM_K * HARM_K;
    float *col = wk + (size_t)HARM_K * HARM_K + HARM_K;
    float *inv4 = col + HARM_K; /* 4x4, row-major */
    size_t r;
    (void)memset(col, 0, HARM_K * sizeof(float));
    col[q] = 1.0f;
    if (harm_solve(nm, wk, col) != 0) {
        return 0;
    }
    for (r = 1u; r < HARM_K; ++r) {
        inv4[(r - 1u) * 4u + (q - 1u)] = col[r];
    }
    return 1;
}

/* Last visit: the estimates from the harmonics' coefficients and covariance. */
static void harm_estimates(magcal_cal_harm_slice_t *h)
{
    const float *beta = h->scratch + 2u * (size_t)HARM_K * HARM_K;
    const float *inv4 = beta + 2u * (size_t)HARM_K;
    magcal_cal_harm_t *out = h->out;
    const size_t k = h->k;
    float tr = 0.0f;
    float tr2 = 0.0f;
    float b2 = 0.0f;
    size_t r;
    size_t q;
    for (r = 0u; r < 4u; ++r) {
        tr += inv4[r * 4u + r];
        b2 += beta[r + 1u] * beta[r + 1u];
        for (q = 0u; q < 4u; ++q) {
            tr2 += inv4[r * 4u + q] * inv4[q * 4u + r];
        }
    }
    /* variance of the harmonics (independent samples: dup_factor), and the O(sigma^2) bias of a
     * least-squares fit whose regressors are noisy too: sigma^2 (G^T G / k)^-1, large exactly
     * where the design is weak (clumps: short arcs) */
    out->err2 = 0.5f * b2;
    out->noise2 = 0.5f * h->s2p * h->dup * tr;
    out->noise2_sd = sqrtf(0.5f * tr2) * h->s2p * h->dup;
    out->design = 0.25f * (float)k * sqrtf(tr2);
    out->bias2 =
        MAGCAL_CAL_BIAS_K * MAGCAL_CAL_BIAS_K * 0.5f * h->s2 * h->s2 * (float)k * (float)k * tr2;
    out->ok = 1u;
}

int magcal_cal_harm_step(magcal_cal_harm_slice_t *h, magcal_cal_budget_t *b)
{
    float *nm = h->scratch;
    float *wk = h->scratch + (size_t)HARM_K * HARM_K;
    float *beta = wk + (size_t)HARM_K * HARM_K;
    if (h->pass == 0u) {
        if (harm_pass_sum(h, b) == 0) {
            return 0;
        }
        if (h->k <= HARM_K || !(h->sum > 0.0f) || !magcal_isfinite_f(h->sum)) {
            h->pass = 9u;
            return 1; /* out->ok 0 */
        }
        h->mean = h->sum / (float)h->k;
        h->out->mean_radius = h->mean;
        (void)memset(nm, 0, (size_t)HARM_K * HARM_K * sizeof(float));
        (void)memset(beta, 0, HARM_K * sizeof(float));
        h->i = 0u;
        h->pass = 1u;
        if (magcal_cal_charge(b, HARM_W_SKIP) != 0) {
            return 0;
        }
    }
    if (h->pass == 1u) {
        if (harm_pass_fit(h, b, 0) == 0) {
            return 0;
        }
        if (harm_solve(nm, wk, beta) != 0) {
            h->pass = 9u;
            return 1; /* headings too clumped for a first and second harmonic: singular design */
        }
        /* residual variance after the harmonic fit, second pass (no cancellation of sums) */
        h->i = 0u;
        h->pass = 2u;
        if (magcal_cal_charge(b, HARM_W_SOLVE1) != 0) {
            return 0;
        }
    }
    if (h->pass == 2u) {
        if (harm_pass_fit(h, b, 1) == 0) {
            return 0;
        }
        h->pass = 3u;
        if (magcal_cal_charge(b, HARM_W_SKIP) != 0) {
            return 0;
        }
    }
    if (h->pass == 3u) {
        harm_noise(h);
        h->pass = 4u; /* passes 4..7: columns 1..4 of the inverse */
        if (magcal_cal_charge(b, HARM_W_SKIP) != 0) {
            return 0;
        }
    }
    while (h->pass >= 4u && h->pass < 8u) {
        if (harm_column(h, (size_t)h->pass - 3u) == 0) {
            h->pass = 9u;
            return 1; /* singular: out->ok 0 */
        }
        h->pass++;
        if (magcal_cal_charge(b, HARM_W_SOLVE1) != 0) {
            return 0;
        }
    }
    if (h->pass == 8u) {
        harm_estimates(h);
        h->pass = 9u;
        (void)magcal_cal_charge(b, HARM_W_FINISH);
    }
    return 1;
}

void magcal_cal_harmonics(const magcal_vec2_t *pts, size_t n, const uint8_t *mask,
                          const magcal_cal2d_t *c, float dup_factor, float sigma_floor,
                          float *scratch, magcal_cal_harm_t *out)
{
    magcal_cal_harm_slice_t h;
    magcal_cal_budget_t b = {UINT32_MAX, 1u};
    magcal_cal_harm_begin(&h, pts, n, mask, c, dup_factor, sigma_floor, scratch, out);
    (void)magcal_cal_harm_step(&h, &b); /* unlimited: one call completes */
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

/* Ciura's gaps of the shell sort (bounded, no recursion). */
static const uint16_t dist_gaps[] = {701u, 301u, 132u, 57u, 23u, 10u, 4u, 1u};
#define DIST_GAPS (sizeof dist_gaps / sizeof dist_gaps[0])

void magcal_cal_distinct_begin(magcal_cal_distinct_slice_t *d, const magcal_vec2_t *pts, size_t n,
                               const uint8_t *mask, uint16_t *idx)
{
    (void)memset(d, 0, sizeof *d);
    d->pts = pts;
    d->n = n;
    d->mask = mask;
    d->idx = idx;
}

/* Pass 0: the masked indices. */
static int dist_collect(magcal_cal_distinct_slice_t *d, magcal_cal_budget_t *b)
{
    while (d->i < d->n) {
        const size_t i = d->i;
        d->i++;
        if (d->mask[i] != 0u) {
            d->idx[d->m] = (uint16_t)i;
            d->m++;
        }
        if (magcal_cal_charge(b, DIST_W_COLLECT) != 0) {
            return 0;
        }
    }
    return 1;
}

/* Pass 1: shell sort of the indices by (x, y); one comparison per visit (gap g, position i, hole
 * j and the moving index v are the state). */
static int dist_sort(magcal_cal_distinct_slice_t *d, magcal_cal_budget_t *b)
{
    const magcal_vec2_t *pts = d->pts;
    uint16_t *idx = d->idx;
    while (d->g < DIST_GAPS) {
        const size_t gap = dist_gaps[d->g];
        if (d->inner == 0u) {
            if (gap >= d->m || d->i >= d->m) {
                d->g++;
                d->i = d->g < DIST_GAPS ? dist_gaps[d->g] : 0u;
                continue; /* at most DIST_GAPS times per sort */
            }
            d->v = idx[d->i];
            d->j = d->i;
            d->inner = 1u;
        }
        if (d->j >= gap && dist_cmp(pts[idx[d->j - gap]], pts[d->v]) > 0) {
            idx[d->j] = idx[d->j - gap];
            d->j -= gap;
        } else {
            idx[d->j] = d->v;
            d->inner = 0u;
            d->i++;
        }
        if (magcal_cal_charge(b, DIST_W_SORT) != 0) {
            return 0;
        }
    }
    return 1;
}

/* Pass 2: distinct values; smallest positive step between neighbours in this order: of x between
 * columns, of y inside a column (the LSB of quantised data, ~0 for continuous data). */
static int dist_count(magcal_cal_distinct_slice_t *d, magcal_cal_budget_t *b)
{
    while (d->i < d->m) {
        magcal_vec2_t a = d->pts[d->idx[d->i - 1u]];
        magcal_vec2_t c = d->pts[d->idx[d->i]];
        d->i++;
        if (dist_cmp(a, c) != 0) {
            float s = c.x > a.x ? c.x - a.x : c.y - a.y;
            ++d->distinct;
            if (s > 0.0f && s < d->step) {
                d->step = s;
            }
        }
        if (magcal_cal_charge(b, DIST_W_COUNT) != 0) {
            return 0;
        }
    }
    return 1;
}

int magcal_cal_distinct_step(magcal_cal_distinct_slice_t *d, magcal_cal_budget_t *b)
{
    if (d->pass == 0u) {
        if (dist_collect(d, b) == 0) {
            return 0;
        }
        if (d->m == 0u) {
            d->pass = 3u;
            return 1; /* distinct 0, step 0 */
        }
        d->pass = 1u;
        d->g = 0u;
        d->i = dist_gaps[0];
        d->inner = 0u;
    }
    if (d->pass == 1u) {
        if (dist_sort(d, b) == 0) {
            return 0;
        }
        d->pass = 2u;
        d->distinct = 1u;
        d->step = INFINITY;
        d->i = 1u;
    }
    if (d->pass == 2u) {
        if (dist_count(d, b) == 0) {
            return 0;
        }
        if (!magcal_isfinite_f(d->step)) {
            d->step = 0.0f;
        }
        d->pass = 3u;
    }
    return 1;
}

size_t magcal_cal_distinct(const magcal_vec2_t *pts, size_t n, const uint8_t *mask, uint16_t *idx,
                           float *step)
{
    magcal_cal_distinct_slice_t d;
    magcal_cal_budget_t b = {UINT32_MAX, 1u};
    magcal_cal_distinct_begin(&d, pts, n, mask, idx);
    (void)magcal_cal_distinct_step(&d, &b); /* unlimited: one call completes */
    *step = d.step;
    return d.distinct;
}
