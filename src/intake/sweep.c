/*
 * Intake sweep: a cursor walks the slots, cfg.sweep_steps per push, and
 *  - re-bins each sample of a bin not yet swept since the last centre change (a sample whose bin
 *    changed is swap-removed and inserted into its new bin, keeping its age);
 *  - surveys every sample it passes.
 * The survey gives the provisional centre at the end of each sweep, in two robust steps:
 *  1. trimmed extremes: per axis the t-th largest and t-th smallest value, t = min(TRIM, 2 + n/16),
 *     so fewer than t outliers on one side of an axis cannot move them (a bounding box would follow
 *     one spike); their midpoint and largest half-spread are the first REFERENCE (c_ref, R_ref);
 *  2. an algebraic circle (2-D) or sphere (3-D) fit (Kasa: |u|^2 + D.u + F = 0) of the samples
 *     within [0.3, 3] R_ref of c_ref ([0.7, 1.3] R_ref once the reference is itself a fit: transient
 *     disturbances of +30 % stay out; its radius may then change by at most 1.5x), in coordinates u = (m - c_ref) / R_ref (float32 stays well
 *     scaled); trimmed this way a spike never enters it. The fit is used only when the samples
 *     form a ring that a centre can be read from: their covariance is not degenerate (smallest /
 *     largest eigenvalue >= FIT_MIN_RATIO, 3-D FIT_MIN_RATIO3: a car's hills never make a sphere), spans an arc (largest std >= FIT_MIN_ARC x R, about
 *     70 degrees) and the radial RMS is <= FIT_MAX_RESID x R (a ring, not a filled blob: a parked
 *     or straight-driving vehicle, hills included, never qualifies); it then becomes the next
 *     sweep's reference too, otherwise the trimmed extremes do. In 2-D, once the arc is long
 *     enough (covariance ratio >= ELL_MIN_RATIO, about 200 degrees) the centre of a conic fit of
 *     the same samples replaces the circle's (soft iron moves a circle fit's centre towards the
 *     arc by up to the axis difference) when it fits at least twice as tightly (radial RMS) and is
 *     an ellipse near the circle; a ring thickened by hills keeps the circle's centre. With
 *     ref_free (the 2-D continuous calibrator), a fit in a fitted reference's tight band that
 *     holds under half the samples surveyed is not used: a lock on a small circle (a clump of the
 *     ring) would otherwise keep itself for good. A fit that moves the centre by more than
 *     cfg.recentre_rel x R starts a re-bin. Until the first usable fit the bins stay around the
 *     origin (the raw sensor frame), where a straight drive fills one direction only.
 */
#include <math.h>
#include <string.h>

#include "intake_internal.h"
#include "magcal_internal.h"

#define SURVEY_MIN 8u         /* samples before a survey may give a reference or a fit */
#define FIT_MIN_RATIO 0.02f   /* 2-D: smallest / largest covariance eigenvalue of a usable fit */
#define FIT_MIN_RATIO3 0.1f   /* 3-D: the same (a car's +-6 deg hills around a cone: about 0.01) */
#define FIT_TIGHT_LO2 0.49f   /* once the reference is a fit: (0.7 R_ref)^2 .. (1.3 R_ref)^2 */
#define FIT_TIGHT_HI2 1.69f
#define FIT_R_JUMP 1.5f       /* a fit's R within R_ref / 1.5 .. 1.5 R_ref of a fitted reference */
#define FIT_MIN_ARC 0.33f     /* largest covariance std / R: an arc of about 70 degrees */
#define ELL_MIN_RATIO 0.2f    /* 2-D: covariance ratio (about 200 degrees of arc) for the ellipse centre */
#define FIT_MAX_RESID 0.2f    /* radial RMS / R of a usable fit (a ring, not a filled blob) */
#define FIT_BAND_LO2 0.09f    /* (0.3 R_ref)^2 */
#define FIT_BAND_HI2 9.0f     /* (3 R_ref)^2 */
#define INNER_R_SCALE 1.5f    /* 2-D: reference radius of an inner cluster / its RMS spread (survey_finish) */

void magcal_intake_survey_clear(magcal_intake_t *st)
{
    st->sv_n = 0u;
    st->fit_n = 0u;
    st->sums.fit_zz = 0.0f;
    (void)memset(st->sums.ell_a, 0, sizeof(st->sums.ell_a));
    (void)memset(st->sums.ell_b, 0, sizeof(st->sums.ell_b));
    st->sums.ell_tt = 0.0f;
    (void)memset(st->sums.fit_a, 0, sizeof(st->sums.fit_a));
    (void)memset(st->sums.fit_b, 0, sizeof(st->sums.fit_b));
    (void)memset(st->sv_in, 0, sizeof(st->sv_in));
}

/* Packed lower-triangle index, i >= j. */
static uint32_t pk(uint32_t i, uint32_t j)
{
    return (i * (i + 1u)) / 2u + j;
}

/* The trimmed extremes of one axis: the TRIM largest values seen by the survey (descending) and
 * the TRIM smallest (ascending). While fewer than TRIM were seen, a value always enters. */
static MAGCAL_NOINLINE void trim_fill(float *hi, float *lo, float v, uint32_t fill)
{
    uint32_t k = fill;
    while (k > 0u && hi[k - 1u] < v) {
        hi[k] = hi[k - 1u];
        k--;
    }
    hi[k] = v;
    k = fill;
    while (k > 0u && lo[k - 1u] > v) {
        lo[k] = lo[k - 1u];
        k--;
    }
    lo[k] = v;
}

/* cppcheck-suppress misra-c2012-2.3 ; deviation D4: a static assert is an unused typedef */
MAGCAL_STATIC_ASSERT(MAGCAL_INTAKE_TRIM == 8u, intake_trim_written_out);

/* A full list of the TRIM largest values, v above its last (trim_hi_enters): the insertion
 * written out (issue 14: ~4,100 insertions of ~4.6 moves each in the 471 steps of vn100's first
 * solve, ~60 M4F instructions each as a loop), each kept value compared and moved once, as the
 * loop does (after the values not below v; the last one drops). */
static MAGCAL_NOINLINE void trim_put_hi(float *l, float v)
{
    float p = l[6];
    if (!(p < v)) {
        l[7] = v;
        return;
    }
    l[7] = p;
    p = l[5];
    if (!(p < v)) {
        l[6] = v;
        return;
    }
    l[6] = p;
    p = l[4];
    if (!(p < v)) {
        l[5] = v;
        return;
    }
    l[5] = p;
    p = l[3];
    if (!(p < v)) {
        l[4] = v;
        return;
    }
    l[4] = p;
    p = l[2];
    if (!(p < v)) {
        l[3] = v;
        return;
    }
    l[3] = p;
    p = l[1];
    if (!(p < v)) {
        l[2] = v;
        return;
    }
    l[2] = p;
    p = l[0];
    if (!(p < v)) {
        l[1] = v;
        return;
    }
    l[1] = p;
    l[0] = v;
}

/* The same for a full list of the TRIM smallest values (ascending), v below its last. */
static MAGCAL_NOINLINE void trim_put_lo(float *l, float v)
{
    float p = l[6];
    if (!(p > v)) {
        l[7] = v;
        return;
    }
    l[7] = p;
    p = l[5];
    if (!(p > v)) {
        l[6] = v;
        return;
    }
    l[6] = p;
    p = l[4];
    if (!(p > v)) {
        l[5] = v;
        return;
    }
    l[5] = p;
    p = l[3];
    if (!(p > v)) {
        l[4] = v;
        return;
    }
    l[4] = p;
    p = l[2];
    if (!(p > v)) {
        l[3] = v;
        return;
    }
    l[3] = p;
    p = l[1];
    if (!(p > v)) {
        l[2] = v;
        return;
    }
    l[2] = p;
    p = l[0];
    if (!(p > v)) {
        l[1] = v;
        return;
    }
    l[1] = p;
    l[0] = v;
}

/* Axis value v into its trimmed extremes (fill: values the survey saw before it, at most TRIM):
 * into the largest when fewer than TRIM were seen or v is above the last kept, the same for the
 * smallest. */
#if defined(__GNUC__) || defined(__clang__)
__attribute__((always_inline)) /* its test is the common case: no call for it (-Os would call) */
#endif
static inline void survey_trim(float *hi, float *lo, float v, uint32_t fill)
{
    if (fill < MAGCAL_INTAKE_TRIM) {
        trim_fill(hi, lo, v, fill);
    } else {
        if (v > hi[MAGCAL_INTAKE_TRIM - 1u]) {
            trim_put_hi(hi, v);
        }
        if (v < lo[MAGCAL_INTAKE_TRIM - 1u]) {
            trim_put_lo(lo, v);
        }
    }
}

/* The survey of one slot in 3-D: the trimmed extremes of the three axes, then the sphere fit's
 * sums of a sample in the band (2-D: survey_add2; d2 summed from x^2 rather than from 0 + x^2, which
 * is the same value, as survey_add2's). */
static void survey_add3(magcal_intake_t *st, const magcal_vec3_t *m)
{
    const uint32_t fill = (st->sv_n < MAGCAL_INTAKE_TRIM) ? st->sv_n : MAGCAL_INTAKE_TRIM;
    survey_trim(st->sv_hi[0], st->sv_lo[0], m->x, fill);
    survey_trim(st->sv_hi[1], st->sv_lo[1], m->y, fill);
    survey_trim(st->sv_hi[2], st->sv_lo[2], m->z, fill);
    st->sv_n++;
    if (st->ref_r > 0.0f) {
        const float inv = 1.0f / st->ref_r;
        const float lo2 = (st->ref_fit != 0u) ? FIT_TIGHT_LO2 : FIT_BAND_LO2;
        const float hi2 = (st->ref_fit != 0u) ? FIT_TIGHT_HI2 : FIT_BAND_HI2;
        const float x = (m->x - st->ref_c.x) * inv;
        const float y = (m->y - st->ref_c.y) * inv;
        const float z = (m->z - st->ref_c.z) * inv;
        const float d2 = x * x + y * y + z * z;
        if (d2 >= lo2 && d2 <= hi2) {
            /* packed lower triangle of r r^T, written out (the sweep's hot loop) */
            float *fa = st->sums.fit_a;
            fa[0] += x * x;
            fa[1] += y * x;
            fa[2] += y * y;
            fa[3] += z * x;
            fa[4] += z * y;
            fa[5] += z * z;
            fa[6] += x;
            fa[7] += y;
            fa[8] += z;
            fa[9] += 1.0f;
            st->sums.fit_b[2] -= z * d2;
            st->sums.fit_b[3] -= d2;
            st->sums.fit_b[0] -= x * d2;
            st->sums.fit_b[1] -= y * d2;
            st->sums.fit_zz += d2 * d2;
            st->fit_n++;
        }
    }
}

/* The 2-D fit sums of one sample in the band (normalised x, y; d2 = x^2 + y^2), without the ones
 * that repeat another (survey_add2). Not inlined: every sum within reach of the one base. */
static MAGCAL_NOINLINE void survey_acc2(magcal_intake_sums_t *sm, float x, float y, float d2)
{
    float *fa = sm->fit_a;
    float *fb = sm->fit_b;
    float *ea = sm->ell_a;
    float *eb = sm->ell_b;
    const float xy = x * y;
    const float yy = y * y;
    const float t = -x * x; /* conic x^2 + B xy + C y^2 + D x + E y + F = 0: e = (xy, yy, x, y, 1) */
    fa[0] += x * x;
    fa[1] += y * x;
    fa[2] += y * y;
    fa[3] += x;
    fa[4] += y;
    fb[0] -= x * d2;
    fb[1] -= y * d2;
    fb[2] -= d2;
    sm->fit_zz += d2 * d2;
    ea[0] += xy * xy;
    ea[1] += yy * xy;
    ea[2] += yy * yy;
    ea[3] += x * xy;
    ea[4] += x * yy;
    ea[6] += y * xy;
    ea[7] += y * yy;
    eb[0] += xy * t;
    eb[1] += yy * t;
    eb[2] += x * t;
    eb[3] += y * t;
    sm->ell_tt += t * t;
}

/* The survey of one slot in 2-D, the sweep's hot path (issue 14: a surveyed slot was ~420 M4F
 * instructions, most of a step's drain during a solve): the same sums in the same order, so bit
 * for bit the same values, without the sums that repeat another one exactly. The conic's normal
 * matrix shares x^2, xy (twice: ell_a[8] and [10], y x = x y), y^2 (twice), x, y and the count with
 * the circle's (ell_a[5, 8, 9, 10, 11, 12, 13, 14] = fit_a[0, 1, 2, 1, 2, 3, 4, 5]: the same
 * products added in the same order), the circle's count fit_a[5] is fit_n (1.0f added fit_n <
 * 2^24 times is exact), and the conic's sum of its targets -x^2 is -fit_a[0] (negation commutes
 * with rounding; the two differ only in the sign of a zero sum, which needs every x^2 zero: the
 * scatter test refuses such a survey before the conic is fitted). survey_dup2 copies them before
 * the fits read them, at the sweep's end. */
static void survey_add2(magcal_intake_t *st, float vx, float vy)
{
    const uint32_t fill = (st->sv_n < MAGCAL_INTAKE_TRIM) ? st->sv_n : MAGCAL_INTAKE_TRIM;
    survey_trim(st->sv_hi[0], st->sv_lo[0], vx, fill);
    survey_trim(st->sv_hi[1], st->sv_lo[1], vy, fill);
    st->sv_n++;
    if (st->ref_r > 0.0f) {
        const float inv = 1.0f / st->ref_r;
        const float dx = vx - st->ref_c.x;
        const float dy = vy - st->ref_c.y;
        const float x = dx * inv;
        const float y = dy * inv;
        const float d2 = x * x + y * y;
        if (st->ref_fit == 0u) {
            if (d2 < FIT_BAND_LO2) {
                st->sv_in[0] += dx; /* inside a trimmed reference's band: the inner cluster (survey_finish) */
                st->sv_in[1] += dy;
                st->sv_in[2] += dx * dx + dy * dy;
                st->sv_in[3] += 1.0f;
            } else if (d2 <= FIT_BAND_HI2) {
                survey_acc2(&st->sums, x, y, d2);
                st->fit_n++;
            } else {
                /* outside the band: not in the fit */
            }
        } else if (d2 >= FIT_TIGHT_LO2 && d2 <= FIT_TIGHT_HI2) {
            survey_acc2(&st->sums, x, y, d2);
            st->fit_n++;
        } else {
            /* outside the tight band: not in the fit */
        }
    }
}

/* The sums survey_add2 leaves out: copies of the ones they repeat (survey_add2). */
static void survey_dup2(magcal_intake_t *st)
{
    st->sums.fit_a[5] = (float)st->fit_n;
    st->sums.ell_a[5] = st->sums.fit_a[0];
    st->sums.ell_a[8] = st->sums.fit_a[1];
    st->sums.ell_a[9] = st->sums.fit_a[2];
    st->sums.ell_a[11] = st->sums.fit_a[2];
    st->sums.ell_a[10] = st->sums.fit_a[1];
    st->sums.ell_a[12] = st->sums.fit_a[3];
    st->sums.ell_a[13] = st->sums.fit_a[4];
    st->sums.ell_a[14] = st->sums.fit_a[5];
    st->sums.ell_b[4] = -st->sums.fit_a[0];
}

/* Scatter of the fit's samples: the extreme eigenvalues of their covariance (normalised units);
 * 0 when it cannot be computed. Own frame (Jacobi), so the stages' frames do not add up. */
static MAGCAL_NOINLINE int fit_scatter(const magcal_intake_t *st, float inv_n, float *wmin, float *wmax)
{
    const uint32_t dims = st->cfg.dims;
    float cov[9];
    float w[3];
    float e[9];
    float mean[3];
    uint32_t i;
    uint32_t j;
    for (i = 0u; i < dims; ++i) {
        mean[i] = st->sums.fit_a[pk(dims, i)] * inv_n;
    }
    for (i = 0u; i < dims; ++i) {
        for (j = 0u; j < dims; ++j) {
            const uint32_t hi = (i > j) ? i : j;
            const uint32_t lo = (i > j) ? j : i;
            cov[i * dims + j] = st->sums.fit_a[pk(hi, lo)] * inv_n - mean[i] * mean[j];
        }
    }
    if (magcal_jacobi_sym(cov, dims, w, e) != MAGCAL_OK) {
        return 0;
    }
    *wmin = w[0];
    *wmax = w[0];
    for (i = 1u; i < dims; ++i) {
        *wmin = (w[i] < *wmin) ? w[i] : *wmin;
        *wmax = (w[i] > *wmax) ? w[i] : *wmax;
    }
    return 1;
}

/* Kasa circle / sphere: centre cu (normalised), R^2 and the mean squared algebraic residual. */
static MAGCAL_NOINLINE int fit_circle(const magcal_intake_t *st, float inv_n, float cu[3], float *r2, float *res)
{
    const uint32_t dims = st->cfg.dims;
    const uint32_t q = dims + 1u;
    float a[16];
    float b[4];
    float bz[4];
    uint32_t i;
    uint32_t j;
    for (i = 0u; i < q; ++i) {
        for (j = 0u; j < q; ++j) {
            const uint32_t hi = (i > j) ? i : j;
            const uint32_t lo = (i > j) ? j : i;
            a[i * q + j] = st->sums.fit_a[pk(hi, lo)] * inv_n;
        }
        b[i] = st->sums.fit_b[i] * inv_n;
        bz[i] = b[i];
    }
    if (magcal_ldlt_solve(a, b, q, 1e-6f, NULL) != MAGCAL_OK) {
        return 0;
    }
    *r2 = -b[dims];
    *res = st->sums.fit_zz * inv_n;
    for (i = 0u; i < q; ++i) { /* algebraic residual at the solution: z.z - x.b (per sample) */
        *res -= b[i] * bz[i];
    }
    for (i = 0u; i < dims; ++i) {
        cu[i] = -0.5f * b[i];
        *r2 += cu[i] * cu[i];
    }
    return (*r2 > 0.0f && magcal_isfinite_f(*r2)) ? 1 : 0;
}

/* 2-D conic centre (normalised) when the samples really are an ellipse: its radial RMS at most
 * half the circle's (res_circle), an ellipse near the circle (a ring thickened by hills in a 2-D
 * install fits a conic no better, and its centre is then worse than the circle's). */
static MAGCAL_NOINLINE int fit_conic(magcal_intake_t *st, float inv_n, float res_circle, float ec[2])
{
    float *ea = st->ell_scratch; /* in the state: the push path's stack stays <= 512 B */
    float eb[5];
    float eb0[5];
    float eres = st->sums.ell_tt * inv_n;
    uint32_t i;
    uint32_t j;
    for (i = 0u; i < 5u; ++i) {
        for (j = 0u; j < 5u; ++j) {
            const uint32_t hi = (i > j) ? i : j;
            const uint32_t lo = (i > j) ? j : i;
            ea[i * 5u + j] = st->sums.ell_a[pk(hi, lo)] * inv_n;
        }
        eb[i] = st->sums.ell_b[i] * inv_n;
        eb0[i] = eb[i];
    }
    if (magcal_ldlt_solve(ea, eb, 5u, 1e-6f, NULL) != MAGCAL_OK) {
        return 0;
    }
    for (i = 0u; i < 5u; ++i) {
        eres -= eb[i] * eb0[i];
    }
    if (!(eres <= 0.25f * res_circle) || !magcal_isfinite_f(eres)) {
        return 0;
    }
    {
        const float bb = eb[0];
        const float cc = eb[1];
        const float det = 4.0f * cc - bb * bb; /* ellipse: > 0; [2 B; B 2C] c = -[D; E] */
        if (!(det > 0.25f && cc > 0.25f && cc < 4.0f)) {
            return 0;
        }
        ec[0] = (-2.0f * cc * eb[2] + bb * eb[3]) / det;
        ec[1] = (bb * eb[2] - 2.0f * eb[3]) / det;
    }
    return (magcal_isfinite_f(ec[0]) && magcal_isfinite_f(ec[1])) ? 1 : 0;
}

/* The survey's circle / sphere fit: 1 and (c, R) when usable. */
static int survey_fit(magcal_intake_t *st, magcal_vec3_t *c, float *r)
{
    const uint32_t dims = st->cfg.dims;
    float inv_n;
    float wmin = 0.0f;
    float wmax = 0.0f;
    float r2 = 0.0f;
    float res = 0.0f;
    float cu[3] = {0.0f, 0.0f, 0.0f};
    if (st->fit_n < SURVEY_MIN || !(st->ref_r > 0.0f)) {
        return 0;
    }
    inv_n = 1.0f / (float)st->fit_n;
    if (fit_scatter(st, inv_n, &wmin, &wmax) == 0 || !(wmax > 0.0f) ||
        !(wmin >= ((dims == 3u) ? FIT_MIN_RATIO3 : FIT_MIN_RATIO) * wmax)) {
        return 0; /* degenerate scatter: a point, a line, a flat ring in 3-D */
    }
    if (fit_circle(st, inv_n, cu, &r2, &res) == 0) {
        return 0;
    }
    /* a ring, not a blob: radial RMS (algebraic residual ~ 2 R dr) and the arc the data spans */
    if (!(res <= 4.0f * r2 * (FIT_MAX_RESID * FIT_MAX_RESID) * r2) || !(wmax >= (FIT_MIN_ARC * FIT_MIN_ARC) * r2)) {
        return 0;
    }
    /* the field's magnitude does not jump: a fitted reference bounds the next radius (a mixture
     * of rings after an installation change must not produce a giant circle) */
    if (st->ref_fit != 0u && !(r2 <= FIT_R_JUMP * FIT_R_JUMP && r2 * (FIT_R_JUMP * FIT_R_JUMP) >= 1.0f)) {
        return 0;
    }
    if (dims == 2u && wmin >= ELL_MIN_RATIO * wmax) {
        /* most of the turn seen: the ellipse centre (soft iron shifts a circle fit's centre
         * towards the arc by up to the axis difference) */
        float ec[2];
        if (fit_conic(st, inv_n, res, ec) != 0) {
            const float dx = ec[0] - cu[0];
            const float dy = ec[1] - cu[1];
            if (dx * dx + dy * dy < 0.25f * r2) {
                cu[0] = ec[0];
                cu[1] = ec[1];
            }
        }
    }
    c->x = st->ref_c.x + st->ref_r * cu[0];
    c->y = st->ref_c.y + st->ref_r * cu[1];
    c->z = (dims == 3u) ? st->ref_c.z + st->ref_r * cu[2] : 0.0f;
    *r = st->ref_r * sqrtf(r2);
    return (magcal_isfinite_f(c->x) && magcal_isfinite_f(c->y) && magcal_isfinite_f(c->z) &&
            magcal_isfinite_f(*r)) ? 1 : 0;
}

/* End of a sweep: next reference, and the provisional centre when the fit is usable (not inlined
 * into the sweep step: the per-slot path keeps a small frame). */
static MAGCAL_NOINLINE void survey_finish(magcal_intake_t *st)
{
    magcal_vec3_t fc = {0.0f, 0.0f, 0.0f};
    float fr = 0.0f;
    int fit_ok;
    uint32_t b;
    int all_swept = 1;
    for (b = 0u; b < st->n_bins; ++b) {
        if (st->bin_gen[b] != st->gen) {
            all_swept = 0;
            break;
        }
    }
    if (all_swept != 0) {
        st->rebin_pending = 0u;
    }
    if (st->cfg.dims == 2u) {
        survey_dup2(st); /* the sums survey_add2 does not repeat */
    }
    fit_ok = survey_fit(st, &fc, &fr);
    if (fit_ok != 0 && st->ref_free != 0u && st->ref_fit != 0u && 2u * st->fit_n < st->sv_n) {
        /* a ring fit in the tight band of a fitted reference that holds under half the samples
         * surveyed: a lock on a small circle (30-min seed 10: r 1.9 on a clump of the 21-uT ring,
         * for the whole drive), not the ring; the trimmed extremes give the next reference */
        fit_ok = 0;
    }
    if (fit_ok != 0) {
        st->ref_c = fc;
        st->ref_r = fr;
        st->ref_fit = 1u;
        if (st->centre_source != (uint8_t)MAGCAL_INTAKE_CENTRE_INSTALLED) {
            const float dx = fc.x - st->centre.x;
            const float dy = fc.y - st->centre.y;
            const float dz = fc.z - st->centre.z;
            const float lim = st->cfg.recentre_rel * fr;
            if (st->centre_source == (uint8_t)MAGCAL_INTAKE_CENTRE_NONE || dx * dx + dy * dy + dz * dz > lim * lim) {
                st->centre_source = (uint8_t)MAGCAL_INTAKE_CENTRE_PROVISIONAL;
                magcal_intake_recentre(st, &fc, fr);
            } else {
                st->radius = fr;
            }
        }
    } else if (st->cfg.dims == 2u && st->ref_fit == 0u && st->ref_r > 0.0f && st->sv_in[3] >= (float)SURVEY_MIN &&
               2.0f * st->sv_in[3] >= (float)st->sv_n) {
        /* 2-D: no usable fit and most samples INSIDE the trimmed reference's band: its extremes
         * were outliers (a driver's garbage burst of more samples than the trim depth: the
         * 30-min seed-4 drive held 38 of 147, the reference radius was ~300 uT and its band never
         * held the 21-uT ring: no centre for the whole drive). The next reference is that inner
         * cluster: its mean, radius INNER_R_SCALE x its RMS spread (an arc's is at most its
         * radius) */
        const float n = st->sv_in[3];
        const float mx = st->sv_in[0] / n;
        const float my = st->sv_in[1] / n;
        const float var = st->sv_in[2] / n - mx * mx - my * my;
        st->ref_c.x += mx;
        st->ref_c.y += my;
        st->ref_c.z = 0.0f;
        st->ref_r = INNER_R_SCALE * sqrtf(var > 0.0f ? var : 0.0f);
        st->ref_fit = 0u;
    } else if (st->sv_n >= SURVEY_MIN) {
        /* no usable fit: the next reference from the trimmed extremes (the first survey, a
         * reference band that missed the data, or data that moved away from the old fit) */
        /* index of the t-th extreme, t = min(TRIM, 2 + n / 16) */
        const uint32_t ti = (st->sv_n / 16u >= MAGCAL_INTAKE_TRIM - 2u) ? MAGCAL_INTAKE_TRIM - 1u : 1u + st->sv_n / 16u;
        float c[3] = {0.0f, 0.0f, 0.0f};
        float r = 0.0f;
        uint32_t a;
        for (a = 0u; a < (uint32_t)st->cfg.dims; ++a) {
            const float half = 0.5f * (st->sv_hi[a][ti] - st->sv_lo[a][ti]);
            c[a] = 0.5f * (st->sv_hi[a][ti] + st->sv_lo[a][ti]);
            r = (half > r) ? half : r;
        }
        st->ref_c.x = c[0];
        st->ref_c.y = c[1];
        st->ref_c.z = c[2];
        st->ref_r = r;
        st->ref_fit = 0u;
    } else {
        /* too few samples for a reference */
    }
    st->sweeps++;
    magcal_intake_survey_clear(st);
}

/* A slot of bin b not swept since the last centre change: its sample moves to its bin under the
 * new centre when that is another one (swap-remove, insert keeping its age; 1), else 0 (not
 * inlined: the per-slot path keeps a small frame). */
static MAGCAL_NOINLINE int sweep_rebin(magcal_intake_t *st, uint32_t c, uint32_t b)
{
    const magcal_intake_slot_t cur = st->slots[c];
    const uint16_t nb = magcal_intake_bin_of(st, &cur.m);
    if (nb == (uint16_t)b) {
        return 0;
    }
    st->slots[c] = st->slots[b * st->cfg.per_bin + (uint32_t)st->count[b] - 1u]; /* swap-remove; re-examine this slot */
    st->count[b]--;
    st->ctr.stored--;
    st->ctr.rebinned++;
    if (magcal_intake_insert(st, nb, &cur.m, cur.seq) != 0) {
        st->ctr.rebin_dropped++;
    }
    return 1;
}

/* One sweep step (per = cfg.per_bin, n = the slots in use); what it did: INTAKE_SWEEP_*. Inlined
 * into the two loops below (the per-slot path is the continuous step's hot loop, issue 14). */
#if defined(__GNUC__) || defined(__clang__)
__attribute__((always_inline))
#endif
static inline uint32_t sweep_one(magcal_intake_t *st, uint32_t per, uint32_t n)
{
    const uint32_t c = st->cursor;
    uint32_t b;
    uint32_t k;
    if (c >= n) {
        survey_finish(st);
        st->cursor = 0u;
        return INTAKE_SWEEP_END;
    }
    b = c / per;
    k = c - b * per;
    if (k >= st->count[b]) { /* rest of this bin is empty: it is swept */
        st->bin_gen[b] = st->gen;
        st->cursor = (b + 1u) * per;
        return INTAKE_SWEEP_JUMP;
    }
    if (st->bin_gen[b] != st->gen && sweep_rebin(st, c, b) != 0) {
        return INTAKE_SWEEP_REBIN;
    }
    if (st->cfg.dims == 2u) {
        survey_add2(st, st->slots[c].m.x, st->slots[c].m.y);
    } else {
        survey_add3(st, &st->slots[c].m);
    }
    st->cursor = c + 1u;
    if (k + 1u == per) {
        st->bin_gen[b] = st->gen;
    }
    return INTAKE_SWEEP_VISIT;
}

void magcal_intake_sweep(magcal_intake_t *st, uint32_t steps)
{
    const uint32_t per = st->cfg.per_bin;
    const uint32_t n = magcal_intake_nslots(st);
    uint32_t s;
    for (s = 0u; s < steps; ++s) {
        (void)sweep_one(st, per, n);
    }
}

void magcal_intake_sweep_part(magcal_intake_t *st, const uint16_t w[4], uint32_t keep, uint32_t *left)
{
    const uint32_t per = st->cfg.per_bin;
    const uint32_t n = magcal_intake_nslots(st);
    const uint32_t steps = st->cfg.sweep_steps;
    uint32_t l = *left;
    uint32_t s;
    /* cppcheck-suppress misra-c2012-15.4 ; deviation D13: a resumable loop leaves at its pause point (sweep end, budget) */
    for (s = 0u; s < steps; ++s) {
        uint32_t kind;
        uint32_t wk;
        if (s != 0u && (st->cursor >= n || l < keep)) {
            break; /* the sweep's end is the next part's first step; the caller's share kept */
        }
        kind = sweep_one(st, per, n);
        wk = w[kind];
        if (wk >= l) {
            l = 0u; /* spent (magcal_cal_spend) */
            break;
        }
        l -= wk;
        if (kind == INTAKE_SWEEP_END) {
            break; /* the sweep's end is the part's only step */
        }
    }
    *left = l;
}
