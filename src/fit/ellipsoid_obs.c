/*
 * Observability gates of the 3-D fit (issue 12, docs/calibration_3d.md "Trust gates"): the
 * information rows of the linearised total-field model, the sandwich covariance of the offset and
 * soft-iron terms (one accumulation pass, the (J^T J)^-1 solves, the exact second pass when the
 * rounding bound asks for it) and the planarity of the field directions. Phases of the trust
 * gates (ellipsoid_trust.c drives them; state in ellipsoid_internal.h).
 */
#include <math.h>
#include <string.h>

#include "ellipsoid_internal.h"

#if MAGCAL_CFG_ENABLE_3D /* whole file: config.h feature switch */

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
MAGCAL_NOINLINE int magcal_ell_sandwich_row(ell_scratch_t *sw, size_t np, size_t cnt, size_t k)
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
MAGCAL_NOINLINE int magcal_ell_swp_range(ell_scratch_t *sw, ell_bud_t *b)
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
MAGCAL_NOINLINE int magcal_ell_info_range(ell_scratch_t *sw, ell_bud_t *b)
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
MAGCAL_NOINLINE int magcal_ell_ph_info_done(ell_scratch_t *sw, ell_bud_t *b)
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
MAGCAL_NOINLINE int magcal_ell_info_factor(ell_scratch_t *sw, size_t np)
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
MAGCAL_NOINLINE void magcal_ell_centre_diag(const ell_ws_t *ws, int stage, int sphere, float f,
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

#endif /* MAGCAL_CFG_ENABLE_3D */
