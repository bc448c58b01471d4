/*
 * The quadric maths of the 3-D fit (algorithms.md 7.2, solvers of 3.1/3.2): design rows and the
 * Kahan-compensated packed 10x10 normal matrix, its accumulation, regate and settle passes, the
 * 9-parameter (LDL^T), 10-parameter (inverse iteration) and sphere solvers, and the extraction
 * of centre and soft-iron matrix (3x3 square root). The phases that drive them: ellipsoid.c.
 */
#include <math.h>
#include <string.h>

#include "ellipsoid_internal.h"

#if MAGCAL_CFG_ENABLE_3D /* whole file: config.h feature switch */

/* One row of the normalised quadric design: x^2, y^2, z^2, 2yz, 2xz, 2xy, 2x, 2y, 2z, 1 of
 * (p - mu) / s. */
static void design_row(const magcal_vec3_t *p, const float mu[3], float inv_s, float row[NQ])
{
    const float x = (p->x - mu[0]) * inv_s;
    const float y = (p->y - mu[1]) * inv_s;
    const float z = (p->z - mu[2]) * inv_s;
    row[0] = x * x;
    row[1] = y * y;
    row[2] = z * z;
    row[3] = 2.0f * y * z;
    row[4] = 2.0f * x * z;
    row[5] = 2.0f * x * y;
    row[6] = 2.0f * x;
    row[7] = 2.0f * y;
    row[8] = 2.0f * z;
    row[9] = 1.0f;
}

/* part += r r^T, packed lower triangle (p = pidx(i, j)), written out: the ten row values stay
 * in FPU registers (the loop form loads both factors and the index for each of the 55 terms). */
static void outer10_add(float *p, const float r[NQ])
{
    const float r0 = r[0];
    const float r1 = r[1];
    const float r2 = r[2];
    const float r3 = r[3];
    const float r4 = r[4];
    const float r5 = r[5];
    const float r6 = r[6];
    const float r7 = r[7];
    const float r8 = r[8];
    const float r9 = r[9];
    p[0] += r0 * r0;
    p[1] += r1 * r0; p[2] += r1 * r1;
    p[3] += r2 * r0; p[4] += r2 * r1; p[5] += r2 * r2;
    p[6] += r3 * r0; p[7] += r3 * r1; p[8] += r3 * r2; p[9] += r3 * r3;
    p[10] += r4 * r0; p[11] += r4 * r1; p[12] += r4 * r2; p[13] += r4 * r3; p[14] += r4 * r4;
    p[15] += r5 * r0; p[16] += r5 * r1; p[17] += r5 * r2;
    p[18] += r5 * r3; p[19] += r5 * r4; p[20] += r5 * r5;
    p[21] += r6 * r0; p[22] += r6 * r1; p[23] += r6 * r2;
    p[24] += r6 * r3; p[25] += r6 * r4; p[26] += r6 * r5; p[27] += r6 * r6;
    p[28] += r7 * r0; p[29] += r7 * r1; p[30] += r7 * r2; p[31] += r7 * r3;
    p[32] += r7 * r4; p[33] += r7 * r5; p[34] += r7 * r6; p[35] += r7 * r7;
    p[36] += r8 * r0; p[37] += r8 * r1; p[38] += r8 * r2; p[39] += r8 * r3;
    p[40] += r8 * r4; p[41] += r8 * r5; p[42] += r8 * r6; p[43] += r8 * r7; p[44] += r8 * r8;
    p[45] += r9 * r0; p[46] += r9 * r1; p[47] += r9 * r2; p[48] += r9 * r3; p[49] += r9 * r4;
    p[50] += r9 * r5; p[51] += r9 * r6; p[52] += r9 * r7; p[53] += r9 * r8; p[54] += r9 * r9;
}

void magcal_ell_acc_start(ell_scratch_t *sw)
{
    (void)memset(&sw->acc, 0, sizeof(sw->acc));
    (void)memset(sw->part, 0, sizeof(sw->part));
    sw->run.in_block = 0u;
    sw->run.k = 0u;
}

/* Pass 3: the normal matrix of every sample (blocked Kahan sums, the block state in the run). */
MAGCAL_NOINLINE int magcal_ell_acc_range(ell_scratch_t *sw, ell_bud_t *b)
{
    ell_run_t *r = &sw->run;
    quad_acc_t *acc = &sw->acc;
    float *part = sw->part;
    const size_t k1 = r->k + magcal_ell_visits(b, W_ACC, r->n - r->k);
    const magcal_vec3_t *m = r->m;
    size_t in_block = r->in_block;
    size_t k;
    for (k = r->k; k < k1; ++k) {
        float row[NQ];
        design_row(&m[k], sw->mu, r->inv_s, row);
        outer10_add(part, row);
        acc->count++;
        if (++in_block == MAGCAL_ELL_BLOCK) {
            magcal_ell_flush(acc->sum, acc->comp, part, MAGCAL_ELL_NPACK);
            in_block = 0u;
        }
    }
    r->k = k1;
    r->in_block = in_block;
    if (r->k < r->n) {
        return ELL_YIELD;
    }
    magcal_ell_flush(acc->sum, acc->comp, part, MAGCAL_ELL_NPACK);
    r->k = 0u;
    r->ph = ELL_PH_SPHERE;
    return ELL_CONT;
}

/*
 * Move the normal matrix `acc` (of the samples the gate keeps) to the samples the next gate
 * keeps: only the samples whose verdict changes are added or removed (a refit after rejecting a
 * few outliers costs one residual pass, not a new accumulation); r->kept_new counts the kept.
 */
MAGCAL_NOINLINE int magcal_ell_regate_range(ell_scratch_t *sw, ell_bud_t *b)
{
    ell_run_t *r = &sw->run;
    const ell_ws_t *ws = &r->ws;
    quad_acc_t *acc = &sw->acc;
    const quad_gate_t *old_gate = &sw->gate;
    const quad_gate_t *new_gate = &sw->next;
    const uint32_t w = (ws->res != NULL) ? (uint32_t)W_REGATE : (uint32_t)W_REGATE_RECOMP;
    const size_t todo = r->n - r->k;         /* r->k <= r->n */
    const uint32_t rest = b->left - b->cost; /* read only when cost <= left */
    /* bulk: the rest of the budget pays for the rest of the range at its worst (every verdict
     * changes) */
    const int bulk = (b->cost <= b->left &&
                      (uint64_t)todo * ((uint64_t)w + (uint64_t)W_REGATE_ROW) <= (uint64_t)rest)
                         ? (int)1
                         : (int)0;
    size_t i;
    size_t j;
    while (r->k < r->n) {
        const size_t k = r->k;
        int was;
        int is;
        float row[NQ];
        float sign;
        size_t p = 0u;
        if (ws->res != NULL) { /* stored: the very predicate gate_keeps evaluates */
            was = ((ws->keep[k] & 1u) != 0u) ? (int)1 : (int)0;
            is = (fabsf(ws->res[k]) < new_gate->thr) ? (int)1 : (int)0;
        } else {
            was = magcal_ell_gate_keeps(old_gate, &r->m[k]);
            is = magcal_ell_gate_keeps(new_gate, &r->m[k]);
        }
        /* charged with its row when the verdict changes (a refused visit is redone next step);
         * no check while the rest of the budget pays for every visit at its worst */
        if (bulk != 0) {
            b->cost += (was == is) ? w : (w + W_REGATE_ROW);
        } else if (magcal_ell_can(b, (was == is) ? w : (w + W_REGATE_ROW)) == 0) {
            break;
        } else {
            /* charged by magcal_ell_can */
        }
        r->k++;
        if (is != 0 && ws->res != NULL) {
            ws->keep[k] |= (uint8_t)2u; /* bit 1: the next gate's verdict */
        }
        r->kept_new += (is != 0) ? 1u : 0u;
        if (was == is) {
            continue;
        }
        sign = (is != 0) ? 1.0f : -1.0f;
        design_row(&r->m[k], sw->mu, r->inv_s, row);
        for (i = 0u; i < NQ; ++i) {
            for (j = 0u; j <= i; ++j) {
                magcal_kahan_add(&acc->sum[p], &acc->comp[p], sign * row[i] * row[j]);
                ++p;
            }
        }
    }
    if (r->k < r->n) {
        return ELL_YIELD;
    }
    acc->count = r->kept_new;
    r->adopt = ((r->n - r->kept_new) == r->prev_rejected) ? (uint8_t)0u : (uint8_t)1u;
    r->k = 0u;
    r->ph = ELL_PH_SETTLE;
    return ELL_CONT;
}

/* After regate: the stored verdicts become the next gate's (adopt) or stay the old one's; then
 * the loop ends (the gate did not change) or the model is fitted again. */
int magcal_ell_settle_range(ell_scratch_t *sw, ell_bud_t *b)
{
    ell_run_t *r = &sw->run;
    uint8_t *keep = r->ws.keep;
    if (keep != NULL) {
        const uint8_t bit = (r->adopt != 0u) ? (uint8_t)2u : (uint8_t)1u;
        const size_t k1 = r->k + magcal_ell_visits(b, W_SETTLE, r->n - r->k);
        size_t k;
        for (k = r->k; k < k1; ++k) {
            keep[k] = ((keep[k] & bit) != 0u) ? (uint8_t)1u : (uint8_t)0u;
        }
        r->k = k1;
        if (r->k < r->n) {
            return ELL_YIELD;
        }
    }
    r->k = 0u;
    r->ph = (r->adopt != 0u) ? ELL_PH_REFIT : ELL_PH_FINAL; /* unchanged: rms and kept final */
    return ELL_CONT;
}

/* G with G^T G = q (q is destroyed; g must not alias q; e, w: scratch of the Jacobi). */
static MAGCAL_NOINLINE magcal_status_t sqrt_spd3(float q[3][3], magcal_ellipsoid_sqrt_t method,
                                                 float g[3][3], float e[3][3], float w[3])
{
    if (method == MAGCAL_ELLIPSOID_SQRT_CHOLESKY) {
        float u00 = q[0][0];
        float u01;
        float u02;
        float u11;
        float u12;
        float u22;
        if (!(u00 > 0.0f)) {
            return MAGCAL_ERR_NOT_ELLIPSOID;
        }
        u00 = sqrtf(u00);
        u01 = q[0][1] / u00;
        u02 = q[0][2] / u00;
        u11 = q[1][1] - u01 * u01;
        if (!(u11 > 0.0f)) {
            return MAGCAL_ERR_NOT_ELLIPSOID;
        }
        u11 = sqrtf(u11);
        u12 = (q[1][2] - u01 * u02) / u11;
        u22 = q[2][2] - u02 * u02 - u12 * u12;
        if (!(u22 > 0.0f)) {
            return MAGCAL_ERR_NOT_ELLIPSOID;
        }
        u22 = sqrtf(u22);
        g[0][0] = u00;
        g[0][1] = u01;
        g[0][2] = u02;
        g[1][0] = 0.0f;
        g[1][1] = u11;
        g[1][2] = u12;
        g[2][0] = 0.0f;
        g[2][1] = 0.0f;
        g[2][2] = u22;
    } else {
        size_t i;
        size_t j;
        magcal_status_t st;
        st = magcal_jacobi_sym(&q[0][0], 3u, w, &e[0][0]); /* destroys q */
        if (st != MAGCAL_OK) {
            return st;
        }
        for (i = 0u; i < 3u; ++i) {
            if (!(w[i] > 0.0f)) {
                return MAGCAL_ERR_NOT_ELLIPSOID;
            }
            w[i] = sqrtf(w[i]);
        }
        for (i = 0u; i < 3u; ++i) {
            for (j = 0u; j < 3u; ++j) {
                g[i][j] =
                    e[i][0] * w[0] * e[j][0] + e[i][1] * w[1] * e[j][1] + e[i][2] * w[2] * e[j][2];
            }
        }
    }
    return MAGCAL_OK;
}

/*
 * Quadric coefficients (a, b, c, f, g, h, p, q, r, d) of
 *   a x^2 + b y^2 + c z^2 + 2f yz + 2g xz + 2h xy + 2p x + 2q y + 2r z + d = 0
 * in normalised coordinates -> calibration in raw coordinates (cal is scratch until MAGCAL_OK).
 */
MAGCAL_NOINLINE magcal_status_t magcal_ell_extract_quadric(ell_scratch_t *ws, const float mu[3],
                                                           float s, float field_cfg,
                                                           magcal_ellipsoid_sqrt_t method,
                                                           magcal_ellipsoid_cal_t *cal)
{
    const float *coef = ws->coef;
    /* the eigenvector's sign is arbitrary: x (+-1) is exact */
    const float sg = (coef[0] + coef[1] + coef[2] < 0.0f) ? -1.0f : 1.0f;
    float(*aq)[3] = ws->q3;
    float u[3];
    float vt[3];
    float i00;
    float i01;
    float i02;
    float i11;
    float i12;
    float i22;
    float det;
    float k;
    float f;
    float detq;
    size_t i;
    size_t j;
    magcal_status_t st;

    aq[0][0] = sg * coef[0];
    aq[1][1] = sg * coef[1];
    aq[2][2] = sg * coef[2];
    aq[1][2] = sg * coef[3];
    aq[2][1] = aq[1][2];
    aq[0][2] = sg * coef[4];
    aq[2][0] = aq[0][2];
    aq[0][1] = sg * coef[5];
    aq[1][0] = aq[0][1];
    u[0] = sg * coef[6];
    u[1] = sg * coef[7];
    u[2] = sg * coef[8];
    det = magcal_det3(aq);
    if (!magcal_isfinite_f(det) || det == 0.0f) {
        return MAGCAL_ERR_NOT_ELLIPSOID;
    }
    i00 = (aq[1][1] * aq[2][2] - aq[1][2] * aq[2][1]) / det;
    i01 = (aq[0][2] * aq[2][1] - aq[0][1] * aq[2][2]) / det;
    i02 = (aq[0][1] * aq[1][2] - aq[0][2] * aq[1][1]) / det;
    i11 = (aq[0][0] * aq[2][2] - aq[0][2] * aq[2][0]) / det;
    i12 = (aq[0][2] * aq[1][0] - aq[0][0] * aq[1][2]) / det;
    i22 = (aq[0][0] * aq[1][1] - aq[0][1] * aq[1][0]) / det;
    vt[0] = -(i00 * u[0] + i01 * u[1] + i02 * u[2]);
    vt[1] = -(i01 * u[0] + i11 * u[1] + i12 * u[2]);
    vt[2] = -(i02 * u[0] + i12 * u[1] + i22 * u[2]);
    k = -(u[0] * vt[0] + u[1] * vt[1] + u[2] * vt[2]) - sg * coef[9];
    if (!(k > 0.0f) || !magcal_isfinite_f(k)) {
        return MAGCAL_ERR_NOT_ELLIPSOID;
    }
    for (i = 0u; i < 3u; ++i) { /* aq becomes qn = A_q / k */
        for (j = 0u; j < 3u; ++j) {
            aq[i][j] = aq[i][j] / k;
        }
    }
    /* Sylvester: leading minors of A_q/k positive. */
    detq = magcal_det3(aq);
    if (!(aq[0][0] > 0.0f) || !(aq[0][0] * aq[1][1] - aq[0][1] * aq[1][0] > 0.0f) ||
        !(detq > 0.0f)) {
        return MAGCAL_ERR_NOT_ELLIPSOID;
    }
    st = sqrt_spd3(aq, method, cal->g, ws->e3, ws->w3);
    if (st != MAGCAL_OK) {
        return st;
    }
    /* Unit-radius form in raw units is qn / s^2; det(Q1) = detq / s^6. */
    f = (field_cfg > 0.0f) ? field_cfg : s * powf(detq, -1.0f / 6.0f);
    if (!magcal_isfinite_f(f) || !(f > 0.0f)) {
        return MAGCAL_ERR_NOT_ELLIPSOID;
    }
    for (i = 0u; i < 3u; ++i) {
        for (j = 0u; j < 3u; ++j) {
            cal->g[i][j] = cal->g[i][j] * (f / s);
        }
    }
    cal->v.x = mu[0] + s * vt[0];
    cal->v.y = mu[1] + s * vt[1];
    cal->v.z = mu[2] + s * vt[2];
    cal->field = f;
    return MAGCAL_OK;
}

MAGCAL_NOINLINE magcal_status_t magcal_ell_solve_quadric9(const quad_acc_t *acc, float *a,
                                                          float tau, float coef[NQ],
                                                          float *min_pivot)
{
    float b[9];
    size_t i;
    size_t j;
    magcal_status_t st;
    for (i = 0u; i < 9u; ++i) {
        for (j = 0u; j < 9u; ++j) {
            a[i * 9u + j] = magcal_ell_acc_at(acc, i, j);
        }
        b[i] = magcal_ell_acc_at(acc, i, 9u); /* D^T 1: the column of the constant term */
    }
    st = magcal_ldlt_solve(a, b, 9u, tau, min_pivot);
    if (st != MAGCAL_OK) {
        return st;
    }
    for (i = 0u; i < 9u; ++i) {
        coef[i] = b[i];
    }
    coef[9] = -1.0f;
    return MAGCAL_OK;
}

/* Smallest eigenvector of D^T D by inverse iteration with a shifted LDL^T (algorithms.md 3.2). */
MAGCAL_NOINLINE magcal_status_t magcal_ell_solve_quadric10(const quad_acc_t *acc, float *a,
                                                           float tau, float coef[NQ],
                                                           float *min_pivot)
{
    float v[NQ];
    float trace = 0.0f;
    float shift;
    size_t i;
    size_t j;
    size_t it;
    size_t attempt;
    magcal_status_t st = MAGCAL_ERR_ILL_CONDITIONED;

    for (i = 0u; i < NQ; ++i) {
        trace += magcal_ell_acc_at(acc, i, i);
    }
    if (!(trace > 0.0f)) {
        return MAGCAL_ERR_DEGENERATE;
    }
    shift = 1e-5f * trace / (float)NQ;
    for (attempt = 0u; attempt < INVITER_SHIFT_TRIES; ++attempt) {
        /* start: the unit sphere x^2 + y^2 + z^2 - 1 = 0 of the normalised data */
        for (i = 0u; i < NQ; ++i) {
            v[i] = 0.0f;
        }
        v[0] = 0.5f;
        v[1] = 0.5f;
        v[2] = 0.5f;
        v[9] = -0.5f;
        for (it = 0u; it < INVITER_STEPS; ++it) {
            for (i = 0u; i < NQ; ++i) {
                for (j = 0u; j < NQ; ++j) {
                    a[i * NQ + j] = magcal_ell_acc_at(acc, i, j);
                }
                a[i * NQ + i] += shift;
            }
            st = magcal_ldlt_solve(a, v, NQ, 0.0f, NULL);
            if (st == MAGCAL_OK) {
                float nrm = 0.0f;
                for (i = 0u; i < NQ; ++i) {
                    nrm += v[i] * v[i];
                }
                nrm = sqrtf(nrm);
                if (!(nrm > 0.0f) || !magcal_isfinite_f(nrm)) {
                    st = MAGCAL_ERR_ILL_CONDITIONED;
                } else {
                    for (i = 0u; i < NQ; ++i) {
                        v[i] /= nrm;
                    }
                }
            }
            if (st != MAGCAL_OK) {
                break;
            }
        }
        if (st == MAGCAL_OK) {
            break;
        }
        shift *= 10.0f;
    }
    if (st != MAGCAL_OK) {
        return st;
    }
    /* Conditioning hint from the unshifted 9x9 block, the same test as the 9-parameter model
     * (in the solver matrix: the iteration is done with it). */
    {
        float b9[9];
        for (i = 0u; i < 9u; ++i) {
            for (j = 0u; j < 9u; ++j) {
                a[i * 9u + j] = magcal_ell_acc_at(acc, i, j);
            }
            b9[i] = 0.0f;
        }
        st = magcal_ldlt_solve(a, b9, 9u, tau, min_pivot);
        if (st != MAGCAL_OK) {
            return st;
        }
    }
    for (i = 0u; i < NQ; ++i) {
        coef[i] = v[i];
    }
    return MAGCAL_OK;
}

/* Sphere x^2+y^2+z^2 + C x + D y + E z + G0 = 0 from the same moments. */
MAGCAL_NOINLINE magcal_status_t magcal_ell_solve_sphere(const quad_acc_t *acc, float *a,
                                                        const float mu[3], float s,
                                                        float field_cfg, float tau,
                                                        magcal_ellipsoid_cal_t *cal,
                                                        float *min_pivot)
{
    float b[4];
    float c[3];
    float r2;
    float rr;
    float f;
    size_t i;
    size_t j;
    magcal_status_t st;
    /* index of x, y, z, 1 in the quadric row and its factor (row holds 2x, 2y, 2z, 1) */
    static const size_t lin[4] = {6u, 7u, 8u, 9u};
    static const float fac[4] = {0.5f, 0.5f, 0.5f, 1.0f};
    for (i = 0u; i < 4u; ++i) {
        for (j = 0u; j < 4u; ++j) {
            a[i * 4u + j] = magcal_ell_acc_at(acc, lin[i], lin[j]) * fac[i] * fac[j];
        }
        b[i] = -(magcal_ell_acc_at(acc, lin[i], 0u) + magcal_ell_acc_at(acc, lin[i], 1u) +
                 magcal_ell_acc_at(acc, lin[i], 2u)) *
               fac[i];
    }
    st = magcal_ldlt_solve(a, b, 4u, tau, min_pivot);
    if (st != MAGCAL_OK) {
        return st;
    }
    for (i = 0u; i < 3u; ++i) {
        c[i] = -0.5f * b[i];
    }
    r2 = c[0] * c[0] + c[1] * c[1] + c[2] * c[2] - b[3];
    if (!(r2 > 0.0f) || !magcal_isfinite_f(r2)) {
        return MAGCAL_ERR_NOT_ELLIPSOID;
    }
    rr = s * sqrtf(r2);
    f = (field_cfg > 0.0f) ? field_cfg : rr;
    for (i = 0u; i < 3u; ++i) {
        for (j = 0u; j < 3u; ++j) {
            cal->g[i][j] = (i == j) ? (f / rr) : 0.0f;
        }
    }
    cal->v.x = mu[0] + s * c[0];
    cal->v.y = mu[1] + s * c[1];
    cal->v.z = mu[2] + s * c[2];
    cal->field = f;
    return MAGCAL_OK;
}

#endif /* MAGCAL_CFG_ENABLE_3D */
