/*
 * The trust gates of the 3-D fit (issue 12, docs/calibration_3d.md "Trust gates"): is the sensor
 * moving (motion SNR from three noise scales), is the answer observable (sandwich covariance of the
 * offset and soft-iron terms; planarity of the field directions), does the model fit (residual),
 * is the field plausible (optional band). Also the storage-free median used by the outlier gate.
 * Phases of the time-sliced fit (src/ellipsoid.c drives them; their state is the run in the
 * fit's scratch, ellipsoid_internal.h).
 */
#include <math.h>
#include <string.h>

#include "ellipsoid_internal.h"

#if MAGCAL_CFG_ENABLE_3D /* whole file: config.h feature switch */

#define MED_BINS MAGCAL_ELL_MED_BINS /* histogram bins per pass of the median |residual|: 2 passes reach 0.1 % on a shell */
#define MED_PASSES 4u    /* refinement passes: resolution (max |r|) / 128^4 at worst */
#define PLANAR_MAX 0.15f /* planarity below this: one rotation axis dominates (SINGLE_AXIS) */
#define INFO_MAX_N MAGCAL_ELL_INFO_N /* centre information: 3 offset + 6 symmetric shape parameters */

/* Weights of the trust phases (estimated Cortex-M4F instructions per visit, measured as those of
 * src/ellipsoid.c). */
#define W_T_UNIT 300u       /* bookkeeping, a gate decision */
#define W_T_SOLVE9 7500u    /* 9x9 LDL^T of the algebraic quadric */
#define W_T_ASNR 85u        /* one algebraic residual */
#define W_T_MED_PASS 900u   /* histogram clear + bin search of one median pass */
#define W_T_MED 60u         /* one sample into the histogram (|r| stored) */
#define W_T_MED_RECOMP 190u  /* the same, gate and residual recomputed */
#define W_T_INFO 440u       /* one sample's information row, 31 moment sums x 2 */
#define W_T_INFO_RECOMP 530u
#define W_T_INFO_DONE 1800u  /* flush, moments expanded, direction scatter */
#define W_T_FACTOR 5000u    /* (J^T J)^-1: the 9x9 LDL^T factorisation */
#define W_T_SUBST 1500u     /* one of its 9 substitutions (a column of the inverse) */
#define W_T_SWM 2000u       /* one row k of the sandwich from the summed meat */
#define W_T_SWP 600u        /* one sample of the exact second sandwich pass */
#define W_T_DIAG 5500u      /* two 3x3 Jacobi eigen-decompositions, the gates */

static float alg_residual(const resid_src_t *src, const magcal_vec3_t *m)
{
    const float *b = src->theta;
    const float x = (m->x - src->mu[0]) * src->inv_s;
    const float y = (m->y - src->mu[1]) * src->inv_s;
    const float z = (m->z - src->mu[2]) * src->inv_s;
    return b[0] * x * x + b[1] * y * y + b[2] * z * z +
           2.0f * (b[3] * y * z + b[4] * x * z + b[5] * x * y + b[6] * x + b[7] * y + b[8] * z) -
           1.0f;
}

static float abs_residual(const resid_src_t *src, const magcal_vec3_t *m)
{
    return fabsf((src->cal != NULL) ? magcal_ell_residual(src->cal, m) : alg_residual(src, m));
}

/*
 * Median of |r| over the `kept` samples that `gate` keeps, without per-sample storage: the bin of
 * a 128-bin histogram of [lo, hi) that holds the median becomes the next [lo, hi), at most
 * MED_PASSES passes (stops once the bin is narrower than 0.1 % of its lower edge).
 */
void magcal_ell_med_start(ell_run_t *r, const resid_src_t *src, const quad_gate_t *gate,
                          const ell_ws_t *ws, size_t kept, float max_abs, uint8_t ret)
{
    ell_med_t *md = &r->med;
    md->src = src;
    md->gate = gate;
    md->ws = *ws;
    md->lo = 0.0f;
    md->hi = max_abs * 1.0001f + 1e-30f;
    md->below = 0u;
    md->target = (kept + 1u) / 2u; /* rank (1-based) of the median */
    md->pass = 0u;
    md->done = 0u;
    md->in_pass = 0u;
    md->ret = ret;
    r->k = 0u;
    r->ph = ELL_PH_MED;
}

/* The end of a median pass: the bin holding the median becomes the next interval. */
static void med_pass_end(ell_med_t *md, const uint32_t *cnt)
{
    size_t acc = md->below;
    size_t b = 0u;
    int found = 0;
    while (b < MED_BINS && found == 0) {
        if (acc + cnt[b] >= md->target) {
            found = 1;
        } else {
            acc += cnt[b];
            ++b;
        }
    }
    if (found == 0) { /* float rounding at the edge: keep the current interval */
        md->done = 1u;
    } else {
        md->lo = md->lo + (float)b * md->width;
        md->hi = md->lo + md->width;
        md->below = acc;
        if (md->width <= 1e-3f * md->lo) {
            md->done = 1u;
        }
    }
}

static MAGCAL_NOINLINE int med_phase(ell_scratch_t *sw, ell_bud_t *b)
{
    ell_run_t *r = &sw->run;
    ell_med_t *md = &r->med;
    uint32_t *cnt = sw->cnt;
    const uint32_t w = (md->ws.res != NULL) ? (uint32_t)W_T_MED : (uint32_t)W_T_MED_RECOMP;
    if (md->in_pass == 0u) {
        if (!(md->pass < MED_PASSES && md->done == 0u)) {
            md->result = 0.5f * (md->lo + md->hi);
            r->ph = md->ret;
            return ELL_CONT;
        }
        if (magcal_ell_can(b, W_T_MED_PASS) == 0) {
            return ELL_YIELD;
        }
        md->width = (md->hi - md->lo) / (float)MED_BINS;
        if (!(md->width > 0.0f)) {
            md->done = 1u;
            md->pass++;
            return ELL_CONT;
        }
        (void)memset(cnt, 0, sizeof(sw->cnt));
        md->in_pass = 1u;
        r->k = 0u;
    }
    {
        const size_t k1 = r->k + magcal_ell_visits(b, w, r->n - r->k);
        const ell_ws_t mws = md->ws;
        const float lo = md->lo;
        const float hi = md->hi;
        const float width = md->width;
        size_t k;
        for (k = r->k; k < k1; ++k) {
            if (magcal_ell_kept(&mws, md->gate, r->m, k) != 0) {
                const float a = (mws.res != NULL) ? fabsf(mws.res[k]) : abs_residual(md->src, &r->m[k]);
                if (a >= lo && a < hi) {
                    const float q = (a - lo) / width;
                    const size_t bin = (size_t)q;
                    cnt[(bin < MED_BINS) ? bin : (MED_BINS - 1u)]++;
                }
            }
        }
        r->k = k1;
    }
    if (r->k < r->n) {
        return ELL_YIELD;
    }
    med_pass_end(md, cnt);
    md->in_pass = 0u;
    md->pass++;
    r->k = 0u;
    return ELL_CONT;
}

/* Jacobian row of the linearised total-field model at one corrected sample (see centre_info). */
static size_t info_row(const float h[3], int sphere, float row[INFO_MAX_N])
{
    const float r = magcal_ell_sqrtf(h[0] * h[0] + h[1] * h[1] + h[2] * h[2]);
    size_t i;
    if (!(r > 0.0f)) {
        return 0u;
    }
    for (i = 0u; i < 3u; ++i) {
        row[i] = h[i] / r;
    }
    if (sphere != 0) {
        row[3] = 1.0f;
        return 4u;
    }
    row[3] = row[0] * row[0];
    row[4] = row[1] * row[1];
    row[5] = row[2] * row[2];
    row[6] = 2.0f * row[1] * row[2];
    row[7] = 2.0f * row[0] * row[2];
    row[8] = 2.0f * row[0] * row[1];
    return INFO_MAX_N;
}

/* Eigenvalues w of a symmetric 3x3 given by its lower triangle (c is mirrored, then overwritten). */
static magcal_status_t eig3(float c[3][3], float w[3], float e[3][3])
{
    size_t i;
    size_t j;
    for (i = 0u; i < 3u; ++i) {
        for (j = 0u; j < i; ++j) {
            c[j][i] = c[i][j];
        }
    }
    return magcal_jacobi_sym(&c[0][0], 3u, w, &e[0][0]);
}

/* Largest eigenvalue of a symmetric 3x3 (lower triangle used); NaN/Inf/failure give +Inf. */
static MAGCAL_NOINLINE float max_eig3(float c[3][3], float w[3], float e[3][3])
{
    float wmax;
    if (eig3(c, w, e) != MAGCAL_OK) {
        return INFINITY;
    }
    wmax = fmaxf(w[0], fmaxf(w[1], w[2]));
    return (magcal_isfinite_f(wmax) && wmax >= 0.0f) ? wmax : INFINITY;
}

/* sqrt(smallest / middle eigenvalue) of a symmetric 3x3 scatter (lower triangle used). */
static MAGCAL_NOINLINE float planarity3(float c[3][3], float w[3], float e[3][3])
{
    float lo;
    float mid;
    float hi;
    if (eig3(c, w, e) != MAGCAL_OK) {
        return 0.0f;
    }
    lo = fminf(w[0], fminf(w[1], w[2]));
    hi = fmaxf(w[0], fmaxf(w[1], w[2]));
    mid = w[0] + w[1] + w[2] - lo - hi;
    if (!(mid > 0.0f)) {
        return 0.0f;
    }
    return sqrtf(fmaxf(lo, 0.0f) / mid);
}

/* One row k of C = inv meat inv from the summed meat (see centre_info below): offset block into
 * cc (lower triangle), shape diagonal into sd[3..np); 0 when the rounding bound is above 1 % of
 * the diagonal term (then the exact second pass decides). */
static MAGCAL_NOINLINE int sandwich_row(ell_scratch_t *sw, size_t np, size_t cnt, size_t k)
{
    const float *meat = sw->meat;
    float(*inv)[INFO_MAX_N] = sw->inv;
    float *w = sw->vec[0];
    float *wa = sw->vec[1];
    const float eps = ((float)cnt + (float)np) * 6e-8f;
    float d = 0.0f;
    float da = 0.0f;
    size_t i;
    size_t j;
    for (i = 0u; i < np; ++i) {
        float e = 0.0f;
        float ea = 0.0f;
        for (j = 0u; j < np; ++j) {
            const float mij = meat[(i >= j) ? magcal_ell_pidx(i, j) : magcal_ell_pidx(j, i)];
            e += mij * inv[k][j];
            ea += fabsf(mij) * fabsf(inv[k][j]);
        }
        w[i] = e;
        wa[i] = ea;
    }
    for (i = 0u; i < np; ++i) {
        d += inv[k][i] * w[i];
        da += fabsf(inv[k][i]) * wa[i];
    }
    if (!(eps * da <= 0.01f * d)) { /* also NaN */
        return 0;
    }
    if (k < 3u) {
        for (j = 0u; j < k; ++j) {
            float c = 0.0f;
            for (i = 0u; i < np; ++i) {
                c += inv[j][i] * w[i];
            }
            sw->cc[k][j] = c;
        }
        sw->cc[k][k] = d;
    } else if (k < INFO_MAX_N) { /* k < np <= INFO_MAX_N (ph_tg): the bound restated at the write */
        sw->sd[k] = d;
    } else {
        return 0;
    }
    return 1;
}

/* The same sandwich from a second pass over the samples: sum r_i^2 (J_i . inv_k)(J_i . inv_l). */
static MAGCAL_NOINLINE int swp_range(ell_scratch_t *sw, ell_bud_t *b)
{
    ell_run_t *r = &sw->run;
    const ell_ws_t *ws = &r->ws;
    const magcal_ellipsoid_cal_t *cal = &sw->cal[0];
    float(*inv)[INFO_MAX_N] = sw->inv;
    float(*cc)[3] = sw->cc;
    float *sd = sw->sd;
    const int sphere = (int)r->sphere;
    const size_t np = r->np;
    size_t i;
    size_t j;
    while (r->k < r->n && magcal_ell_can(b, W_T_SWP) != 0) {
        const size_t k = r->k;
        float *h = sw->h3; /* per-sample vectors in the scratch: off the stack */
        float *row = sw->vec[0];
        float *pr = sw->vec[1];
        float r2;
        r->k++;
        if (magcal_ell_kept(ws, &sw->gate, r->m, k) == 0) {
            continue;
        }
        magcal_ell_correct(cal, &r->m[k], h);
        if (info_row(h, sphere, row) == 0u) {
            continue;
        }
        r2 = (ws->res != NULL) ? ws->res[k]
                               : (magcal_ell_sqrtf(h[0] * h[0] + h[1] * h[1] + h[2] * h[2]) -
                                  cal->field);
        r2 *= r2;
        for (i = 0u; i < np; ++i) {
            float d = 0.0f;
            for (j = 0u; j < np; ++j) {
                d += row[j] * inv[i][j];
            }
            pr[i] = d;
        }
        for (i = 0u; i < 3u; ++i) {
            for (j = 0u; j <= i; ++j) {
                cc[i][j] += r2 * pr[i] * pr[j];
            }
        }
        for (i = 3u; i < np; ++i) {
            sd[i] += r2 * pr[i] * pr[i];
        }
    }
    if (r->k < r->n) {
        return ELL_YIELD;
    }
    r->k = 0u;
    r->stage = 2;
    r->ph = ELL_PH_DIAG;
    return ELL_CONT;
}

/*
 * Observability of the calibration (issue 12, docs/calibration_3d.md "Trust gates"). Linearised
 * total-field model about the fit, r_i = |(I + E)(h_i - dc)| - F with h_i = G (m_i - V): the
 * Jacobian row is J_i = [-n_i, n_i^T E n_i terms] (n_i = h_i / |h_i|; E symmetric, 6 terms, carries
 * the scale and the soft iron) or [-n_i, -1] for the sphere (scale only). The covariance is the
 * heteroscedasticity-robust sandwich C = (J^T J)^-1 (sum r_i^2 J_i J_i^T) (J^T J)^-1, so noise that
 * G amplifies along one axis (strong soft iron) counts where it acts. One pass accumulates J^T J
 * (packed, blocked Kahan, in `acc`), the meat sum r_i^2 J_i J_i^T and the scatter of the directions
 * n_i; np solves give (J^T J)^-1 in `inv`; the offset block and the shape diagonal follow from the
 * meat, or (rounding bound above 1 %: near-singular J^T J) from an exact second pass.
 * Outputs, relative to F: worst 1-sigma offset error (largest eigenvalue of the 3x3 block, through
 * G: output units) and worst soft-iron term; +Inf when J^T J is singular (every n_i on one cone).
 * `dir_planarity`: planarity of the corrected directions (~0 for rotation about one axis).
 */
/*
 * The quadric model's J^T J and meat hold products of the row [n, n_x^2, n_y^2, n_z^2, 2 n_y n_z,
 * 2 n_x n_z, 2 n_x n_y]: moments of the direction n of degree 2 to 4, of which only 31 differ (the
 * 45 packed terms repeat them with factors 1, 2, 4). Per sample the 31 monomials are summed (p:
 * plain, q: weighted by w = r^2); k_mom / k_fac map packed term t to k_fac[t] x moment k_mom[t]
 * (a power of two: exact). 31 products and 62 sums instead of 45 products and 90 sums.
 */
#define INFO_NMOM 31u
static const uint8_t k_mom[(INFO_MAX_N * (INFO_MAX_N + 1u)) / 2u] = {
    0u,  1u,  2u,  3u,  4u,  5u,  6u,  7u,  8u,  16u, 9u,  10u, 11u, 17u, 18u,
    12u, 13u, 14u, 19u, 20u, 21u, 15u, 11u, 13u, 22u, 23u, 24u, 20u, 8u,  15u,
    12u, 25u, 26u, 27u, 30u, 19u, 7u,  9u,  15u, 28u, 29u, 30u, 26u, 22u, 17u};
static const uint8_t k_fac[(INFO_MAX_N * (INFO_MAX_N + 1u)) / 2u] = {
    1u, 1u, 1u, 1u, 1u, 1u, 1u, 1u, 1u, 1u, 1u, 1u, 1u, 1u, 1u, 1u, 1u, 1u, 1u, 1u, 1u, 2u, 2u,
    2u, 2u, 2u, 2u, 4u, 2u, 2u, 2u, 2u, 2u, 2u, 4u, 4u, 2u, 2u, 2u, 2u, 2u, 2u, 4u, 4u, 4u};

static MAGCAL_NOINLINE void moments_add(float *p, float *q, float a, float b, float c, float w)
{
    const float aa = a * a;
    const float ab = a * b;
    const float bb = b * b;
    const float ac = a * c;
    const float bc = b * c;
    const float cc = c * c;
    const float aaa = aa * a;
    const float aab = aa * b;
    const float aac = aa * c;
    const float abb = bb * a;
    const float bbb = bb * b;
    const float bbc = bb * c;
    const float acc = cc * a;
    const float bcc = cc * b;
    const float ccc = cc * c;
    const float abc = ab * c;
    const float aaaa = aa * aa;
    const float aabb = aa * bb;
    const float bbbb = bb * bb;
    const float aacc = aa * cc;
    const float bbcc = bb * cc;
    const float cccc = cc * cc;
    const float aabc = aa * bc;
    const float bbbc = bb * bc;
    const float bccc = cc * bc;
    const float aaac = aa * ac;
    const float abbc = bb * ac;
    const float accc = cc * ac;
    const float aaab = aa * ab;
    const float abbb = bb * ab;
    const float abcc = cc * ab;
    p[0] += aa;
    q[0] += w * aa;
    p[1] += ab;
    q[1] += w * ab;
    p[2] += bb;
    q[2] += w * bb;
    p[3] += ac;
    q[3] += w * ac;
    p[4] += bc;
    q[4] += w * bc;
    p[5] += cc;
    q[5] += w * cc;
    p[6] += aaa;
    q[6] += w * aaa;
    p[7] += aab;
    q[7] += w * aab;
    p[8] += aac;
    q[8] += w * aac;
    p[9] += abb;
    q[9] += w * abb;
    p[10] += bbb;
    q[10] += w * bbb;
    p[11] += bbc;
    q[11] += w * bbc;
    p[12] += acc;
    q[12] += w * acc;
    p[13] += bcc;
    q[13] += w * bcc;
    p[14] += ccc;
    q[14] += w * ccc;
    p[15] += abc;
    q[15] += w * abc;
    p[16] += aaaa;
    q[16] += w * aaaa;
    p[17] += aabb;
    q[17] += w * aabb;
    p[18] += bbbb;
    q[18] += w * bbbb;
    p[19] += aacc;
    q[19] += w * aacc;
    p[20] += bbcc;
    q[20] += w * bbcc;
    p[21] += cccc;
    q[21] += w * cccc;
    p[22] += aabc;
    q[22] += w * aabc;
    p[23] += bbbc;
    q[23] += w * bbbc;
    p[24] += bccc;
    q[24] += w * bccc;
    p[25] += aaac;
    q[25] += w * aaac;
    p[26] += abbc;
    q[26] += w * abbc;
    p[27] += accc;
    q[27] += w * accc;
    p[28] += aaab;
    q[28] += w * aaab;
    p[29] += abbb;
    q[29] += w * abbb;
    p[30] += abcc;
    q[30] += w * abcc;
}

/* The packed terms from moment sums: dst[t] = k_fac[t] x mom[k_mom[t]] (dst may not alias mom). */
static void moments_expand(const float *mom, float *dst)
{
    size_t t;
    for (t = 0u; t < (INFO_MAX_N * (INFO_MAX_N + 1u)) / 2u; ++t) {
        dst[t] = (float)k_fac[t] * mom[k_mom[t]];
    }
}

/* Add a block's sums to the Kahan total of J^T J: packed terms (sphere) or, for the quadric, its
 * moments expanded term by term; the block sums are cleared. */
static void info_flush(quad_acc_t *acc, float *part, size_t npk, int sphere)
{
    size_t t;
    if (sphere != 0) {
        magcal_ell_flush(acc->sum, acc->comp, part, npk);
        return;
    }
    for (t = 0u; t < npk; ++t) {
        magcal_kahan_add(&acc->sum[t], &acc->comp[t], (float)k_fac[t] * part[k_mom[t]]);
    }
    for (t = 0u; t < INFO_NMOM; ++t) {
        part[t] = 0.0f;
    }
}

/* One pass: J^T J (blocked Kahan, in acc) and the sandwich's meat (plain sums: a 1-significant-digit
 * gate), so the covariance needs no second pass over the samples. */
static MAGCAL_NOINLINE int info_range(ell_scratch_t *sw, ell_bud_t *b)
{
    ell_run_t *r = &sw->run;
    const ell_ws_t *ws = &r->ws;
    const magcal_ellipsoid_cal_t *cal = &sw->cal[0];
    const int sphere = (int)r->sphere;
    const size_t np = r->np;
    const size_t npk = (np * (np + 1u)) / 2u;
    quad_acc_t *acc = &sw->acc;
    float *part = sw->part;
    float *meat = sw->meat; /* sum r_i^2 J_i J_i^T, packed */
    const uint32_t w = (ws->res != NULL) ? (uint32_t)W_T_INFO : (uint32_t)W_T_INFO_RECOMP;
    size_t i;
    size_t j;
    const size_t k1 = r->k + magcal_ell_visits(b, w, r->n - r->k);
    size_t k;
    for (k = r->k; k < k1; ++k) {
        float *h = sw->h3; /* per-sample vectors in the scratch: off the stack */
        float *row = sw->vec[0];
        float r2;
        if (magcal_ell_kept(ws, &sw->gate, r->m, k) == 0) {
            continue;
        }
        magcal_ell_correct(cal, &r->m[k], h);
        if (info_row(h, sphere, row) == 0u) {
            continue;
        }
        r2 = (ws->res != NULL) ? ws->res[k]
                               : (magcal_ell_sqrtf(h[0] * h[0] + h[1] * h[1] + h[2] * h[2]) -
                                  cal->field);
        r2 *= r2;
        if (sphere == 0) { /* moment sums: part[0..30] this block's, meat[0..30] all samples' */
            moments_add(part, meat, row[0], row[1], row[2], r2);
        } else {
            size_t p = 0u;
            for (i = 0u; i < np; ++i) { /* packed order: p = pidx(i, j) */
                for (j = 0u; j <= i; ++j) {
                    const float jj = row[i] * row[j];
                    part[p] += jj;
                    meat[p] += r2 * jj;
                    ++p;
                }
            }
        }
        for (i = 0u; i < 3u; ++i) {
            r->sn[i] += row[i];
        }
        r->cnt++;
        if (++r->in_block == MAGCAL_ELL_BLOCK) {
            info_flush(acc, part, npk, sphere);
            r->in_block = 0u;
        }
    }
    r->k = k1;
    if (r->k < r->n) {
        return ELL_YIELD;
    }
    r->k = 0u;
    r->ph = ELL_PH_INFO_DONE;
    return ELL_CONT;
}

/* The pass's last block, the meat's moments into its packed terms, the scatter of the directions
 * about their mean (from the n n^T block); then the inverse (or the diagnostics: too few). */
static MAGCAL_NOINLINE int ph_info_done(ell_scratch_t *sw, ell_bud_t *b)
{
    ell_run_t *r = &sw->run;
    quad_acc_t *acc = &sw->acc;
    const float *sn = r->sn;
    const float cnt = (float)r->cnt;
    if (magcal_ell_can(b, W_T_INFO_DONE) == 0) {
        return ELL_YIELD;
    }
    info_flush(acc, sw->part, (r->np * (r->np + 1u)) / 2u, (int)r->sphere);
    if (r->sphere == 0u) {
        (void)memcpy(sw->mat, sw->meat, INFO_NMOM * sizeof(float));
        moments_expand(sw->mat, sw->meat);
    }
    if (r->cnt >= r->np) {
        size_t i;
        for (i = 0u; i < 3u; ++i) {
            size_t j;
            for (j = 0u; j <= i; ++j) {
                sw->dir[i][j] = magcal_ell_acc_at(acc, i, j) / cnt - (sn[i] / cnt) * (sn[j] / cnt);
            }
        }
        r->ph = ELL_PH_INV;
    } else {
        r->stage = 0; /* too few samples: nothing */
        r->ph = ELL_PH_DIAG;
    }
    return ELL_CONT;
}

/* The factorisation of J^T J (into sw->mat) for its inverse; 0 when singular. */
static MAGCAL_NOINLINE int info_factor(ell_scratch_t *sw, size_t np)
{
    float *a = sw->mat;
    size_t i;
    size_t j;
    for (i = 0u; i < np; ++i) {
        for (j = 0u; j < np; ++j) {
            a[i * np + j] = magcal_ell_acc_at(&sw->acc, i, j);
        }
    }
    return (magcal_ldlt_factor(a, np, 0.0f, NULL) == MAGCAL_OK) ? 1 : 0;
}

/* The observability diagnostics from centre_info's matrices (relative to F). */
static MAGCAL_NOINLINE void centre_diag(const ell_ws_t *ws, int stage, int sphere, float f,
                                        trust_diag_t *res)
{
    ell_scratch_t *sw = ws->s;
    res->centre_std_rel = INFINITY;
    res->shape_std = (sphere != 0) ? 0.0f : INFINITY;
    res->planarity = 0.0f;
    if (stage >= 1) {
        res->planarity = planarity3(sw->dir, sw->w3, sw->e3);
    }
    if (stage < 2) {
        return;
    }
    res->centre_std_rel = sqrtf(max_eig3(sw->cc, sw->w3, sw->e3)) / f;
    if (sphere == 0) {
        float emax = 0.0f;
        size_t i;
        for (i = 3u; i < INFO_MAX_N; ++i) {
            if (!(sw->sd[i] <= emax)) { /* NaN propagates as unobservable */
                emax = sw->sd[i];
            }
        }
        res->shape_std = magcal_isfinite_f(emax) ? (sqrtf(emax) / f) : INFINITY;
    }
}

/* sqrt(smallest / middle eigenvalue) of the samples' scatter (packed xx, yx, yy, zx, zy, zz). */
MAGCAL_NOINLINE float magcal_ell_planarity(const float sc[6], ell_scratch_t *ws)
{
    float(*c)[3] = ws->q3;
    c[0][0] = sc[0];
    c[1][0] = sc[1];
    c[1][1] = sc[2];
    c[2][0] = sc[3];
    c[2][1] = sc[4];
    c[2][2] = sc[5];
    return planarity3(c, ws->w3, ws->e3);
}

/* Cube root of det G (> 0 for both square roots): the mean gain, raw -> output units. */
static float mean_gain(const magcal_ellipsoid_cal_t *cal)
{
    const float(*a)[3] = cal->g; /* magcal_det3's expression, without a copy */
    const float det = a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1]) -
                      a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0]) +
                      a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]);
    return cbrtf(fabsf(det));
}

/*
 * Centre-free, model-free noise scale: the RMS algebraic residual of the 9-parameter quadric
 * (d = -1) of ALL samples in normalised coordinates, from the moments alone:
 * sum (r.theta - 1)^2 = theta^T A theta - 2 theta^T b + N. On a shell of radius ~1 a geometric
 * error delta gives ~2 delta, so motion SNR = 2 / rms: ~2.5 for noise around one point (any model
 * of it), the radius / noise for a rotation (any soft iron, any quadric). Three phases: the solve,
 * the residuals (stored, when there is room, for the median), the median.
 */
static MAGCAL_NOINLINE int ph_asnr0(ell_scratch_t *sw, ell_bud_t *b)
{
    ell_run_t *r = &sw->run;
    const quad_acc_t *acc = &sw->acc;
    float *a = sw->mat;
    size_t i;
    size_t j;
    if (magcal_ell_can(b, W_T_SOLVE9) == 0) {
        return ELL_YIELD;
    }
    for (i = 0u; i < 9u; ++i) {
        for (j = 0u; j < 9u; ++j) {
            a[i * 9u + j] = magcal_ell_acc_at(acc, i, j);
        }
        r->theta[i] = magcal_ell_acc_at(acc, i, 9u);
    }
    if (magcal_ldlt_solve(a, r->theta, 9u, 0.0f, NULL) != MAGCAL_OK) {
        sw->mc.snr_alg = INFINITY; /* singular: a degenerate quadric fits exactly, this is not noise */
        r->k = 0u;
        r->ph = ELL_PH_COV;
        return ELL_CONT;
    }
    r->src_alg.cal = NULL;
    r->src_alg.theta = r->theta;
    r->src_alg.mu = sw->mu;
    r->src_alg.inv_s = r->inv_s;
    r->rmax = 0.0f;
    r->k = 0u;
    r->ph = ELL_PH_ASNR;
    return ELL_CONT;
}

static MAGCAL_NOINLINE int asnr_range(ell_scratch_t *sw, ell_bud_t *b)
{
    ell_run_t *r = &sw->run;
    {
        const size_t k1 = r->k + magcal_ell_visits(b, W_T_ASNR, r->n - r->k);
        float *res = r->ws.res;
        float mx = r->rmax;
        size_t k;
        for (k = r->k; k < k1; ++k) {
            const float rr = alg_residual(&r->src_alg, &r->m[k]);
            if (res != NULL) {
                res[k] = rr;
            }
            if (fabsf(rr) > mx) { /* fmaxf(mx, |r|) without the libm call (NaN ignored alike) */
                mx = fabsf(rr);
            }
        }
        r->k = k1;
        r->rmax = mx;
    }
    if (r->k < r->n) {
        return ELL_YIELD;
    }
    {
        ell_ws_t all_ws = r->ws;
        all_ws.keep = NULL; /* every sample */
        /* robust (median) scale: outliers far off the shell must not make a rotation look like noise */
        magcal_ell_med_start(r, &r->src_alg, &r->all, &all_ws, r->n, r->rmax, ELL_PH_ASNR_DONE);
    }
    return ELL_CONT;
}

/* Motion SNR: the largest of `snr_model` (the final fit's), the algebraic quadric's and, only when
 * both are below `limit` (about to say NO_MOTION), the sphere's with a robust (median) scale. Each
 * can be fooled alone: a far burst drags the least-squares quadric (and any model) but not a
 * median-scaled sphere; strong soft iron spoils the sphere but not the quadric. Noise around one
 * point fools none of them (all ~2.5). Result in r->mot.snr, then phase `ret`. */
static void mot_start(ell_run_t *r, float snr_model, float limit, uint8_t ret)
{
    r->mot.snr_model = snr_model;
    r->mot.limit = limit;
    r->mot.ret = ret;
    r->ph = ELL_PH_MOT0;
}

static MAGCAL_NOINLINE int ph_mot(ell_scratch_t *sw)
{
    ell_run_t *r = &sw->run;
    const motion_ctx_t *mc = &sw->mc;
    ell_mot_t *mo = &r->mot;
    if (r->ph == ELL_PH_MOT0) {
        mo->snr = fmaxf(mo->snr_model, mc->snr_alg);
        if (mo->snr < mo->limit && mc->sphere != NULL) {
            ell_ws_t rw = r->ws; /* recomputed: the stored residuals belong to the fit */
            rw.res = NULL;
            rw.keep = NULL;
            r->src_sph.cal = mc->sphere;
            r->src_sph.theta = NULL;
            r->src_sph.mu = NULL;
            r->src_sph.inv_s = 0.0f;
            magcal_ell_rp_start(r, mc->sphere, &r->all, &rw, ELL_PH_MOT1);
        } else {
            r->ph = mo->ret;
        }
    } else if (r->ph == ELL_PH_MOT1) {
        magcal_ell_med_start(r, &r->src_sph, &r->all, &r->rp.ws, r->rp.kept, r->rp.mx, ELL_PH_MOT2);
    } else { /* ELL_PH_MOT2 */
        const float med = MAGCAL_ELL_MAD_TO_SIGMA * r->med.result / mc->sphere->g[0][0];
        mo->snr = fmaxf(mo->snr, (med > 0.0f) ? (mc->s / med) : INFINITY);
        r->ph = mo->ret;
    }
    return ELL_CONT;
}

/*
 * A failed fit of data that never moved, or that rotate about one axis only, gets the status that
 * says so (the user must move the sensor differently, not retry with the same motion).
 */
void magcal_ell_explain_start(ell_run_t *r, magcal_status_t st)
{
    r->pend = st;
    r->ph = ELL_PH_EXPL0;
}

static MAGCAL_NOINLINE int ph_explain(ell_scratch_t *sw)
{
    ell_run_t *r = &sw->run;
    const magcal_ellipsoid_cfg_t *cfg = r->cfg;
    const magcal_status_t st = r->pend;
    if (r->ph == ELL_PH_EXPL0) {
        if (st == MAGCAL_ERR_NULL || st == MAGCAL_ERR_ARG || st == MAGCAL_ERR_NONFINITE ||
            st == MAGCAL_ERR_DEGENERATE) {
            return st;
        }
        if (cfg->min_motion_snr > 0.0f) {
            mot_start(r, 0.0f, cfg->min_motion_snr, ELL_PH_EXPL1);
        } else {
            r->ph = ELL_PH_EXPL1;
        }
        return ELL_CONT;
    }
    if (cfg->min_motion_snr > 0.0f && r->mot.snr < cfg->min_motion_snr) {
        return MAGCAL_ERR_NO_MOTION;
    }
    if ((cfg->max_centre_std_rel > 0.0f || cfg->max_shape_std > 0.0f) && r->planarity < PLANAR_MAX) {
        return MAGCAL_ERR_SINGLE_AXIS;
    }
    return st;
}

/* Trust gates, first phases: the mean gain and raw radius, the motion SNR, then the information
 * pass of the observability gate. */
static MAGCAL_NOINLINE int ph_tg(ell_scratch_t *sw)
{
    ell_run_t *r = &sw->run;
    const magcal_ellipsoid_cal_t *cal = &sw->cal[0];
    if (r->ph == ELL_PH_TG0) {
        const float gmean = mean_gain(cal);
        r->sphere = (r->model == MAGCAL_ELLIPSOID_MODEL_SPHERE) ? 1u : 0u;
        r->np = (r->sphere != 0u) ? (size_t)4u : (size_t)INFO_MAX_N;
        if (!(gmean > 0.0f) || !magcal_isfinite_f(gmean)) {
            return MAGCAL_ERR_NOT_ELLIPSOID;
        }
        r->gmean = gmean;
        sw->dg.field_raw = cal->field / gmean;
        /* motion: spread against the best noise scale (the fitted model's residual, raw units,
         * after outlier rejection; the algebraic quadric of all samples; the robust sphere) */
        mot_start(r, (r->rms > 0.0f) ? (sw->mc.s * gmean / r->rms) : INFINITY,
                  r->cfg->min_motion_snr, ELL_PH_TG1);
        return ELL_CONT;
    }
    sw->dg.motion_snr = r->mot.snr;
    (void)memset(&sw->acc, 0, sizeof(sw->acc));
    (void)memset(sw->part, 0, sizeof(sw->part));
    (void)memset(sw->meat, 0, sizeof(sw->meat));
    r->sn[0] = 0.0f;
    r->sn[1] = 0.0f;
    r->sn[2] = 0.0f;
    r->cnt = 0u;
    r->in_block = 0u;
    r->k = 0u;
    r->ph = ELL_PH_INFO;
    return ELL_CONT;
}

/* The verdict (order: motion, one axis, residual, observability, field). */
static magcal_status_t gates_verdict(const ell_run_t *r, const trust_diag_t *dg, float f)
{
    const magcal_ellipsoid_cfg_t *cfg = r->cfg;
    const float rms = r->rms;
    float lim;
    int observable = 1;
    if (cfg->min_motion_snr > 0.0f && dg->motion_snr < cfg->min_motion_snr) {
        return MAGCAL_ERR_NO_MOTION;
    }
    if ((cfg->max_centre_std_rel > 0.0f && !(dg->centre_std_rel <= cfg->max_centre_std_rel)) ||
        (cfg->max_shape_std > 0.0f && !(dg->shape_std <= cfg->max_shape_std))) {
        observable = 0;
    }
    lim = (r->sphere != 0u) ? cfg->max_residual_rel_sphere : cfg->max_residual_rel;
    /* one axis: the corrected directions lie on a cone; or the raw samples are planar and the
     * quadric does not even fit them (a G made up along the unseen axis spoils the corrected test;
     * not for the sphere: a sphere that misfits strong soft iron is a residual failure) */
    if (observable == 0 &&
        (dg->planarity < PLANAR_MAX ||
         (r->sphere == 0u && r->planarity < PLANAR_MAX && lim > 0.0f && !(rms <= lim * f)))) {
        return MAGCAL_ERR_SINGLE_AXIS;
    }
    if (lim > 0.0f && !(rms <= lim * f)) {
        return MAGCAL_ERR_RESIDUAL;
    }
    if (observable == 0) {
        return MAGCAL_ERR_ILL_CONDITIONED;
    }
    if (cfg->field_expected > 0.0f &&
        !(dg->field_raw >= cfg->field_band_lo * cfg->field_expected &&
          dg->field_raw <= cfg->field_band_hi * cfg->field_expected)) {
        return MAGCAL_ERR_FIELD_MAGNITUDE;
    }
    return MAGCAL_OK;
}

/*
 * Observability phases after the information pass: (J^T J)^-1, then the sandwich
 * (J^T J)^-1 meat (J^T J)^-1 from the summed meat row by row: the offset block (rows 0..2) and the
 * shape diagonal, C_kl = inv_l . (meat inv_k). Near a singular J^T J the rounding of the summed
 * meat can swamp its tiny component along the weak direction (and make an unobservable offset
 * look fine), so each diagonal term carries a bound of that rounding, (cnt + np) eps |inv_k|^T
 * |meat| |inv_k|; if any bound is above 1 % of its term, the exact per-sample second pass decides
 * instead. Then the diagnostics and the verdict.
 */
static MAGCAL_NOINLINE int ph_centre(ell_scratch_t *sw, ell_bud_t *b)
{
    ell_run_t *r = &sw->run;
    if (r->ph == ELL_PH_INV) { /* (J^T J)^-1: one factorisation, then np substitutions */
        if (magcal_ell_can(b, W_T_FACTOR) == 0) {
            return ELL_YIELD;
        }
        if (info_factor(sw, r->np) == 0) {
            r->stage = 1; /* J^T J singular: the scatter only */
            r->ph = ELL_PH_DIAG;
            return ELL_CONT;
        }
        r->k = 0u;
        r->ph = ELL_PH_INV_SUB;
        return ELL_CONT;
    }
    if (r->ph == ELL_PH_INV_SUB) {
        while (r->k < r->np) {
            float *col = sw->inv[r->k];
            size_t i;
            if (magcal_ell_can(b, W_T_SUBST) == 0) {
                return ELL_YIELD;
            }
            for (i = 0u; i < r->np; ++i) {
                col[i] = (i == r->k) ? 1.0f : 0.0f;
            }
            if (magcal_ldlt_subst(sw->mat, col, r->np) != MAGCAL_OK) {
                r->stage = 1;
                r->ph = ELL_PH_DIAG;
                return ELL_CONT;
            }
            r->k++;
        }
        (void)memset(sw->cc, 0, 9u * sizeof(float));
        (void)memset(sw->sd, 0, INFO_MAX_N * sizeof(float));
        r->k = 0u;
        r->ph = ELL_PH_SWM;
        return ELL_CONT;
    }
    if (r->ph == ELL_PH_SWM) {
        while (r->k < r->np && !(r->k >= 3u && r->sphere != 0u)) {
            if (magcal_ell_can(b, W_T_SWM) == 0) {
                return ELL_YIELD;
            }
            if (sandwich_row(sw, r->np, r->cnt, r->k) == 0) {
                (void)memset(sw->cc, 0, 9u * sizeof(float));
                (void)memset(sw->sd, 0, INFO_MAX_N * sizeof(float));
                r->k = 0u;
                r->ph = ELL_PH_SWP;
                return ELL_CONT;
            }
            r->k++;
        }
        r->k = 0u;
        r->stage = 2;
        r->ph = ELL_PH_DIAG;
        return ELL_CONT;
    }
    /* ELL_PH_DIAG */
    if (magcal_ell_can(b, W_T_DIAG) == 0) {
        return ELL_YIELD;
    }
    centre_diag(&r->ws, (int)r->stage, (int)r->sphere, sw->cal[0].field, &sw->dg);
    {
        const magcal_status_t st = gates_verdict(r, &sw->dg, sw->cal[0].field);
        if (st != MAGCAL_OK) {
            return st;
        }
    }
    r->ph = ELL_PH_OUT;
    return ELL_CONT;
}

int magcal_ell_trust_phase(ell_scratch_t *sw, ell_bud_t *b)
{
    ell_run_t *r = &sw->run;
    switch (r->ph) {
    case ELL_PH_ASNR0:
        return ph_asnr0(sw, b);
    case ELL_PH_ASNR:
        return asnr_range(sw, b);
    case ELL_PH_ASNR_DONE: {
        const float med = MAGCAL_ELL_MAD_TO_SIGMA * r->med.result;
        sw->mc.snr_alg = (med > 0.0f) ? (2.0f / med) : INFINITY; /* 0: exact quadric */
        r->k = 0u;
        r->ph = ELL_PH_COV;
        return ELL_CONT;
    }
    case ELL_PH_MED:
        return med_phase(sw, b);
    case ELL_PH_INFO:
        return info_range(sw, b);
    case ELL_PH_INFO_DONE:
        return ph_info_done(sw, b);
    case ELL_PH_INV:
    case ELL_PH_INV_SUB:
    case ELL_PH_SWM:
    case ELL_PH_DIAG:
        return ph_centre(sw, b);
    case ELL_PH_SWP:
        return swp_range(sw, b);
    default:
        break;
    }
    if (magcal_ell_can(b, W_T_UNIT) == 0) {
        return ELL_YIELD;
    }
    if (r->ph == ELL_PH_TG0 || r->ph == ELL_PH_TG1) {
        return ph_tg(sw);
    }
    if (r->ph == ELL_PH_EXPL0 || r->ph == ELL_PH_EXPL1) {
        return ph_explain(sw);
    }
    return ph_mot(sw); /* ELL_PH_MOT0 .. ELL_PH_MOT2 */
}

#endif /* MAGCAL_CFG_ENABLE_3D */
