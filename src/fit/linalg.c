/* Small dense float32 kernels shared by the fitting modules (algorithms.md section 3). */
#include <float.h>
#include <math.h>

#include "magcal_internal.h"

size_t magcal_misalign(const void *p, size_t align)
{
    /* Deviation D9 (MISRA 11.6): the alignment of a caller's workspace can only be read from
     * its address. */
    return (size_t)((uintptr_t)p & (uintptr_t)(align - 1u));
}

/*
 * Where magcal_ldlt_solve keeps the equilibration factor of row i: in the strict upper triangle of
 * a (never read as a matrix entry: the factorisation uses the lower triangle only) when it has room
 * (n >= 3: row 0 holds i = 1..n-1, entry (1, 2) holds i = 0), else in the caller's 2-slot array.
 * The solver is on the deepest stack path of every fit; a MAGCAL_LDLT_MAX_N array of factors
 * would add 48 bytes to it.
 */
static float *ldlt_scale(float *a, float *small, size_t n, size_t i)
{
    float *slot;
    if (n < 3u) {
        slot = &small[i];
    } else if (i == 0u) {
        slot = &a[n + 2u];
    } else {
        slot = &a[i];
    }
    return slot;
}

magcal_status_t magcal_ldlt_factor(float *a, size_t n, float tau, float *min_pivot)
{
    float small[2];
    float minp = 1.0f;
    size_t i;
    size_t j;
    size_t k;

    if (a == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (n < 3u || n > MAGCAL_LDLT_MAX_N || !(tau >= 0.0f)) {
        return MAGCAL_ERR_ARG; /* n < 3: the scales need the strict upper triangle (ldlt_scale) */
    }
    /* Equilibrate: a'_ij = a_ij / sqrt(a_ii a_jj) (b'_i = b_i / sqrt(a_ii) in magcal_ldlt_subst). */
    for (i = 0u; i < n; ++i) {
        float dii = a[i * n + i];
        if (!magcal_isfinite_f(dii)) {
            return MAGCAL_ERR_NONFINITE;
        }
        if (!(dii > 0.0f)) {
            return MAGCAL_ERR_DEGENERATE;
        }
        *ldlt_scale(a, small, n, i) = 1.0f / sqrtf(dii);
    }
    for (i = 0u; i < n; ++i) {
        const float si = *ldlt_scale(a, small, n, i);
        for (j = 0u; j <= i; ++j) {
            float v = a[i * n + j];
            if (!magcal_isfinite_f(v)) {
                return MAGCAL_ERR_NONFINITE;
            }
            a[i * n + j] = v * si * *ldlt_scale(a, small, n, j);
        }
    }
    /* LDL^T on the lower triangle: L stored below the diagonal, D on the diagonal (a[k*n+k] is
     * d_k once column k is done: no separate array on the stack). */
    for (j = 0u; j < n; ++j) {
        float dj = a[j * n + j];
        for (k = 0u; k < j; ++k) {
            float ljk = a[j * n + k];
            dj -= ljk * ljk * a[k * n + k];
        }
        if (!(dj > tau)) {
            if (min_pivot != NULL) {
                *min_pivot = dj;
            }
            return MAGCAL_ERR_ILL_CONDITIONED;
        }
        if (dj < minp) {
            minp = dj;
        }
        a[j * n + j] = dj;
        for (i = j + 1u; i < n; ++i) {
            float s = a[i * n + j];
            for (k = 0u; k < j; ++k) {
                s -= a[i * n + k] * a[j * n + k] * a[k * n + k];
            }
            a[i * n + j] = s / dj;
        }
    }
    if (min_pivot != NULL) {
        *min_pivot = minp;
    }
    return MAGCAL_OK;
}

/* The equilibration factor of row i that magcal_ldlt_factor stored (n >= 3: see ldlt_scale). */
static float ldlt_scale_of(const float *a, size_t n, size_t i)
{
    return (i == 0u) ? a[n + 2u] : a[i];
}

magcal_status_t magcal_ldlt_subst(const float *a, float *b, size_t n)
{
    size_t i;
    size_t j;
    size_t k;
    for (i = 0u; i < n; ++i) {
        b[i] *= ldlt_scale_of(a, n, i);
    }
    /* Forward L z = b, scale by D^-1, back L^T x = z. */
    for (i = 0u; i < n; ++i) {
        float s = b[i];
        for (k = 0u; k < i; ++k) {
            s -= a[i * n + k] * b[k];
        }
        b[i] = s;
    }
    for (i = 0u; i < n; ++i) {
        b[i] /= a[i * n + i];
    }
    for (j = 0u; j < n; ++j) {
        float s;
        i = n - 1u - j; /* back substitution runs i = n-1 .. 0 */
        s = b[i];
        for (k = i + 1u; k < n; ++k) {
            s -= a[k * n + i] * b[k];
        }
        b[i] = s;
    }
    for (i = 0u; i < n; ++i) {
        b[i] *= ldlt_scale_of(a, n, i);
        if (!magcal_isfinite_f(b[i])) {
            return MAGCAL_ERR_ILL_CONDITIONED;
        }
    }
    return MAGCAL_OK;
}

magcal_status_t magcal_ldlt_solve(float *a, float *b, size_t n, float tau, float *min_pivot)
{
    float small[2];
    float minp = 1.0f;
    size_t i;
    size_t j;
    size_t k;

    if (a == NULL || b == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (n == 0u || n > MAGCAL_LDLT_MAX_N || !(tau >= 0.0f)) {
        return MAGCAL_ERR_ARG;
    }
    /* Equilibrate: a'_ij = a_ij / sqrt(a_ii a_jj), b'_i = b_i / sqrt(a_ii). */
    for (i = 0u; i < n; ++i) {
        float dii = a[i * n + i];
        if (!magcal_isfinite_f(dii) || !magcal_isfinite_f(b[i])) {
            return MAGCAL_ERR_NONFINITE;
        }
        if (!(dii > 0.0f)) {
            return MAGCAL_ERR_DEGENERATE;
        }
        *ldlt_scale(a, small, n, i) = 1.0f / sqrtf(dii);
    }
    for (i = 0u; i < n; ++i) {
        const float si = *ldlt_scale(a, small, n, i);
        for (j = 0u; j <= i; ++j) {
            float v = a[i * n + j];
            if (!magcal_isfinite_f(v)) {
                return MAGCAL_ERR_NONFINITE;
            }
            a[i * n + j] = v * si * *ldlt_scale(a, small, n, j);
        }
        b[i] *= si;
    }
    /* LDL^T on the lower triangle: L stored below the diagonal, D on the diagonal (a[k*n+k] is
     * d_k once column k is done: no separate array on the stack). */
    for (j = 0u; j < n; ++j) {
        float dj = a[j * n + j];
        for (k = 0u; k < j; ++k) {
            float ljk = a[j * n + k];
            dj -= ljk * ljk * a[k * n + k];
        }
        if (!(dj > tau)) {
            if (min_pivot != NULL) {
                *min_pivot = dj;
            }
            return MAGCAL_ERR_ILL_CONDITIONED;
        }
        if (dj < minp) {
            minp = dj;
        }
        a[j * n + j] = dj;
        for (i = j + 1u; i < n; ++i) {
            float s = a[i * n + j];
            for (k = 0u; k < j; ++k) {
                s -= a[i * n + k] * a[j * n + k] * a[k * n + k];
            }
            a[i * n + j] = s / dj;
        }
    }
    /* Forward L z = b, scale by D^-1, back L^T x = z. */
    for (i = 0u; i < n; ++i) {
        float s = b[i];
        for (k = 0u; k < i; ++k) {
            s -= a[i * n + k] * b[k];
        }
        b[i] = s;
    }
    for (i = 0u; i < n; ++i) {
        b[i] /= a[i * n + i];
    }
    for (j = 0u; j < n; ++j) {
        float s;
        i = n - 1u - j; /* back substitution runs i = n-1 .. 0 */
        s = b[i];
        for (k = i + 1u; k < n; ++k) {
            s -= a[k * n + i] * b[k];
        }
        b[i] = s;
    }
    for (i = 0u; i < n; ++i) {
        b[i] *= *ldlt_scale(a, small, n, i);
        if (!magcal_isfinite_f(b[i])) {
            return MAGCAL_ERR_ILL_CONDITIONED;
        }
    }
    if (min_pivot != NULL) {
        *min_pivot = minp;
    }
    return MAGCAL_OK;
}

/*
 * fmodf(a, 360.0f), bit for bit, without libm's fmodf (about 500 B of flash with its wrapper on
 * the M4F): binary long division by 360 * 2^k, k from the largest with 360 * 2^k <= |a| / 2 down
 * to 0. Each subtraction has m <= r < 2 m, so it is exact (Sterbenz), like fmod itself: the
 * remainder is the exact one, with the sign of a (also -0). A bounded angle (|a| < 720, every
 * caller's difference or sum of two angles) takes at most one subtraction; the loops are bounded
 * by the float range (|a| < 2^128: k <= 118). Non-finite input: NaN, as fmodf.
 */
static float rem360(float a)
{
    float r = fabsf(a);
    float m = 360.0f;
    uint32_t k;
    uint32_t j;

    if (r < 360.0f) {
        return a; /* also -0 and the subnormals, as fmodf */
    }
    if (!(r <= FLT_MAX)) {
        return NAN;
    }
    for (k = 0u; k < 127u; ++k) { /* m = 360 * 2^k, the largest with 2 m > r */
        if (m > 0.5f * r) {
            break;
        }
        m *= 2.0f; /* exact: m <= FLT_MAX / 2 */
    }
    for (j = 0u; j <= k; ++j) { /* m = 360 * 2^(k - j) */
        if (r >= m) {
            r -= m; /* m <= r < 2 m: exact */
        }
        m *= 0.5f;
    }
    return (a < 0.0f) ? -r : r;
}

float magcal_wrap180_deg(float a)
{
    float r = rem360(a); /* (-360, 360) */
    if (r > 180.0f) {
        r -= 360.0f;
    } else if (r <= -180.0f) {
        r += 360.0f;
    } else {
        /* already in (-180, 180] */
    }
    return r;
}

float magcal_wrap360_deg(float a)
{
    float r = rem360(a);
    if (r < 0.0f) {
        r += 360.0f;
    }
    if (r >= 360.0f) { /* -tiny + 360 rounds to 360 */
        r = 0.0f;
    }
    return r;
}

/*
 * atan2 in float without libm's atan2f + atanf (812 B of flash on the M4F with newlib): octant
 * reduction to t = min(|x|, |y|) / max(|x|, |y|) in [0, 1], then t > tan(pi/8) folded to
 * (t - 1) / (t + 1) around pi/4, and atan(t) = t + t^3 P(t^2) on |t| <= tan(pi/8) with a degree-3
 * P fitted on Chebyshev nodes (approximation error 5.4e-9 rad). With the float roundings of the
 * reduction and of the pi/2 and pi constants the measured maximum error against the double
 * atan2 is 1.57e-5 degree (2.75e-7 rad; glibc's atan2f: 1.44e-5), pinned at 2e-5 degree by
 * tests/test_linalg.c (test_atan2_matches_libm_within_bound). Signed zeros as atan2
 * (atan2(-0, -1) = -pi); non-finite input gives NaN (every caller passes finite values).
 */
float magcal_atan2f(float y, float x)
{
    const float ax = fabsf(x);
    const float ay = fabsf(y);
    const uint8_t swap = (ay > ax) ? 1u : 0u;
    const float mx = (swap != 0u) ? ay : ax;
    const float mn = (swap != 0u) ? ax : ay;
    float t;
    float z;
    float r = 0.0f;

    if (mx > 0.0f) {
        t = (mn >= mx) ? 1.0f : mn / mx; /* mn <= mx: equal gives 1 (as the division), also for two infinities */
    } else {
        t = mn + mx; /* both zero: 0; NaN stays NaN */
    }
    if (t > 0.41421356f) { /* tan(pi/8) */
        t = (t - 1.0f) / (t + 1.0f);
        r = 0.78539816340f; /* pi/4 */
    }
    z = t * t;
    r += t + t * z * (-0.33332726f + z * (0.19971037f + z * (-0.13817109f + z * 0.078824282f)));
    if (swap != 0u) {
        r = 1.5707963268f - r;
    }
    if (signbit(x) != 0) {
        r = 3.1415926536f - r;
    }
    return (signbit(y) != 0) ? -r : r;
}

uint32_t magcal_prng_next(uint32_t *state, uint32_t bound)
{
    uint32_t x = *state;
    if (x == 0u) {
        x = 0x9E3779B9u;
    }
    x ^= x << 13;
    x ^= x >> 17;
    x ^= x << 5;
    *state = x;
    if (bound == 0u) {
        return 0u;
    }
    return (uint32_t)(((uint64_t)x * (uint64_t)bound) >> 32);
}

float magcal_det3(float a[3][3])
{
    return a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1]) -
           a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0]) +
           a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]);
}

/* Rotation J(p, q, c, s) applied as a <- J^T a J and e <- e J. */
static void jacobi_rotate(float *a, float *e, size_t n, size_t p, size_t q)
{
    const float apq = a[p * n + q];
    float theta;
    float t;
    float c;
    float s;
    size_t k;
    theta = (a[q * n + q] - a[p * n + p]) / (2.0f * apq);
    t = 1.0f / (fabsf(theta) + sqrtf(theta * theta + 1.0f));
    if (theta < 0.0f) {
        t = -t;
    }
    c = 1.0f / sqrtf(t * t + 1.0f);
    s = t * c;
    for (k = 0u; k < n; ++k) { /* a <- a J (columns p, q) */
        const float akp = a[k * n + p];
        const float akq = a[k * n + q];
        a[k * n + p] = c * akp - s * akq;
        a[k * n + q] = s * akp + c * akq;
    }
    for (k = 0u; k < n; ++k) { /* a <- J^T a (rows p, q) */
        const float apk = a[p * n + k];
        const float aqk = a[q * n + k];
        a[p * n + k] = c * apk - s * aqk;
        a[q * n + k] = s * apk + c * aqk;
    }
    for (k = 0u; k < n; ++k) {
        const float ekp = e[k * n + p];
        const float ekq = e[k * n + q];
        e[k * n + p] = c * ekp - s * ekq;
        e[k * n + q] = s * ekp + c * ekq;
    }
}

magcal_status_t magcal_jacobi_sym(float *a, size_t n, float *w, float *e)
{
    size_t sweep;
    size_t i;
    size_t j;
    float scale = 0.0f;
    if (n == 0u || n > MAGCAL_JACOBI_MAX_N) {
        return MAGCAL_ERR_ARG;
    }
    for (i = 0u; i < n; ++i) {
        for (j = 0u; j < n; ++j) {
            e[i * n + j] = (i == j) ? 1.0f : 0.0f;
            scale += a[i * n + j] * a[i * n + j];
        }
    }
    for (sweep = 0u; sweep < MAGCAL_JACOBI_SWEEPS; ++sweep) {
        size_t p;
        float off = 0.0f;
        for (i = 0u; i < n; ++i) {
            for (j = i + 1u; j < n; ++j) {
                off += a[i * n + j] * a[i * n + j];
            }
        }
        if (off <= 1e-14f * scale) {
            for (i = 0u; i < n; ++i) {
                w[i] = a[i * n + i];
            }
            return MAGCAL_OK;
        }
        for (p = 0u; p + 1u < n; ++p) {
            size_t q;
            for (q = p + 1u; q < n; ++q) {
                if (a[p * n + q] != 0.0f) {
                    jacobi_rotate(a, e, n, p, q);
                }
            }
        }
    }
    return MAGCAL_ERR_NOT_CONVERGED;
}
