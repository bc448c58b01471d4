/*
 * 3-D ellipsoid (general quadric) calibration fit, algorithms.md 7.2 with the solvers of 3.1/3.2.
 *
 * Data are centred on their mean and scaled by their RMS distance before the normal equations are
 * accumulated (Kahan-compensated float32 sums of one packed 10x10 matrix, from which the 9-parameter,
 * 10-parameter and sphere systems are all taken). Extraction happens in normalised coordinates and
 * is mapped back: V = mu + s*V~, G = (F/s)*sqrt(A~/k~).
 */
#include <math.h>
#include <string.h>

#include "ellipsoid_internal.h"

#if MAGCAL_CFG_ENABLE_3D /* whole file: config.h feature switch */

#define NQ MAGCAL_ELL_NQ
#define COV_CELLS ((size_t)MAGCAL_ELLIPSOID_COV_AZ * MAGCAL_ELLIPSOID_COV_EL)
#define MIN_QUADRIC_POINTS 10u
#define MIN_SPHERE_POINTS 4u
#define MAX_REFITS_LIMIT 8u
#define INVITER_STEPS 8u
#define INVITER_SHIFT_TRIES 3u

/* cppcheck-suppress misra-c2012-2.3 ; deviation D4: a static assert is an unused typedef */
MAGCAL_STATIC_ASSERT(COV_CELLS <= 96u, coverage_cells_fit_three_words);
/* cppcheck-suppress misra-c2012-2.3 ; deviation D4: a static assert is an unused typedef */
MAGCAL_STATIC_ASSERT(MAGCAL_ELLIPSOID_COV_AZ == 12u, azimuth_boundaries_are_30_degrees);
/* cppcheck-suppress misra-c2012-2.3 ; deviation D4: a static assert is an unused typedef */
MAGCAL_STATIC_ASSERT(sizeof(ell_scratch_t) + (MAGCAL_ELL_ALIGN - 4u) <= MAGCAL_ELLIPSOID_FIT_SCRATCH_BYTES &&
                         sizeof(magcal_ellipsoid_fit_scratch_t) >= sizeof(ell_scratch_t) &&
                         MAGCAL_ELLIPSOID_FIT_SCRATCH_BYTES % 4u == 0u,
                     fit_scratch_fits_its_macro);

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

/* Weights of the time-sliced fit: estimated Cortex-M4F instructions of one visit of each phase
 * (docs/calibration_3d.md "Time-sliced fit"): measured per phase on QEMU mps2-an386 (-icount
 * shift=0, tools/bench/m4f_image/main_cont3.c) on a 441-sample tumble at the default budget
 * (a visit inside a chunked pass, loop and budget check included), rounded up. */
#define W_CHECK 400u        /* configuration check */
#define W_N1 110u            /* mean: finiteness + 3 Kahan sums of one sample */
#define W_N2 120u            /* scatter: 6 Kahan sums of one sample */
#define W_NORM_DONE 3300u   /* scale, planarity (3x3 Jacobi) */
#define W_ACC 290u          /* design row + 55 products of one sample, block flush amortised */
#define W_SPHERE 2400u      /* 4x4 sphere solve, coverage centre */
#define W_COV 150u           /* coverage cell of one sample */
#define W_COV_DONE 900u     /* coverage count, model choice */
#define W_SOLVE4 2400u      /* sphere model */
#define W_SOLVE9 7500u      /* 9x9 normal equations, LDL^T */
#define W_SOLVE10 60000u    /* 10-parameter inverse iteration (forced model only; not cut further) */
#define W_EXTRACT 4000u     /* centre, k, Sylvester, 3x3 square root (Jacobi) */
#define W_KEEP 10u           /* one verdict set */
#define W_UNIT 300u         /* loop bookkeeping */
#define W_REGATE 75u        /* stored residual against the new gate */
#define W_REGATE_RECOMP 280u /* both gates' residuals recomputed (no workspace) */
#define W_REGATE_ROW 600u   /* a sample whose verdict changes: design row + 55 Kahan sums */
#define W_SETTLE 15u         /* one verdict settled */
#define W_RP 120u            /* residual pass: one sample (residual stored) */
#define W_RP_RECOMP 220u     /* residual pass: gate and residual recomputed */
#define W_OUT 400u          /* the result written */

static void acc_start(ell_scratch_t *sw)
{
    (void)memset(&sw->acc, 0, sizeof(sw->acc));
    (void)memset(sw->part, 0, sizeof(sw->part));
    sw->run.in_block = 0u;
    sw->run.k = 0u;
}

/* Pass 3: the normal matrix of every sample (blocked Kahan sums, the block state in the run). */
static MAGCAL_NOINLINE int acc_range(ell_scratch_t *sw, ell_bud_t *b)
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
static MAGCAL_NOINLINE int regate_range(ell_scratch_t *sw, ell_bud_t *b)
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
static int settle_range(ell_scratch_t *sw, ell_bud_t *b)
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
static MAGCAL_NOINLINE magcal_status_t extract_quadric(ell_scratch_t *ws, const float mu[3],
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

static MAGCAL_NOINLINE magcal_status_t solve_quadric9(const quad_acc_t *acc, float *a, float tau, float coef[NQ],
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
static MAGCAL_NOINLINE magcal_status_t solve_quadric10(const quad_acc_t *acc, float *a, float tau, float coef[NQ],
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
static MAGCAL_NOINLINE magcal_status_t solve_sphere(const quad_acc_t *acc, float *a, const float mu[3], float s,
                                    float field_cfg, float tau, magcal_ellipsoid_cal_t *cal,
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

static int cell_of(float x, float y, float z, size_t *cell)
{
    /* tan-free sector boundaries of the azimuth cells: cos / sin of 30, 60, 90, 120, 150 degrees */
    static const float k_bound_c[5] = {0.8660254f, 0.5f, 0.0f, -0.5f, -0.8660254f};
    static const float k_bound_s[5] = {0.5f, 0.8660254f, 1.0f, 0.8660254f, 0.5f};
    float r = magcal_ell_sqrtf(x * x + y * y + z * z);
    float sz;
    float u = -x; /* azimuth measured from -x, as atan2f(y, x) + pi, in [0, 2 pi) */
    float v = -y;
    size_t ia = 0u;
    size_t ie;
    if (!(r > 0.0f)) {
        return 0;
    }
    if (v == 0.0f && u >= 0.0f) { /* as atan2f: (0, 0) -> pi (cell 6), y = 0 < x -> 2 pi (cell 11) */
        ia = (size_t)MAGCAL_ELLIPSOID_COV_AZ / 2u;
        if (u > 0.0f) {
            ia = (size_t)MAGCAL_ELLIPSOID_COV_AZ - 1u;
        }
    } else {
        size_t b;
        if (!(v > 0.0f)) { /* lower half: cells 6..11 */
            u = -u;
            v = -v;
            ia = MAGCAL_ELLIPSOID_COV_AZ / 2u;
        }
        for (b = 0u; b < 5u; ++b) { /* angle >= boundary b: one cell further (no atan2f) */
            if (k_bound_c[b] * v - k_bound_s[b] * u >= 0.0f) {
                ++ia;
            }
        }
    }
    sz = z / r + 1.0f; /* [0, 2]: equal-area bands */
    ie = (size_t)(sz * ((float)MAGCAL_ELLIPSOID_COV_EL / 2.0f));
    if (ie >= MAGCAL_ELLIPSOID_COV_EL) {
        ie = MAGCAL_ELLIPSOID_COV_EL - 1u;
    }
    *cell = ie * MAGCAL_ELLIPSOID_COV_AZ + ia;
    return 1;
}

/* The coverage cells of samples k0..k1-1 around c into bits (samples within tiny of c skipped). */
static void coverage_cells(const magcal_vec3_t *m, size_t k0, size_t k1, const float c[3], float tiny,
                           uint32_t bits[3])
{
    size_t k;
    for (k = k0; k < k1; ++k) {
        size_t cell;
        float x = m[k].x - c[0];
        float y = m[k].y - c[1];
        float z = m[k].z - c[2];
        if (fabsf(x) + fabsf(y) + fabsf(z) <= tiny) {
            continue;
        }
        if (cell_of(x, y, z, &cell) != 0) {
            bits[cell / 32u] |= (uint32_t)1u << (cell % 32u);
        }
    }
}

static float coverage_count(const uint32_t bits[3])
{
    const size_t cells = COV_CELLS;
    size_t k;
    size_t filled = 0u;
    for (k = 0u; k < cells; ++k) {
        if (((bits[k / 32u] >> (k % 32u)) & 1u) != 0u) {
            filled++;
        }
    }
    return (float)filled / (float)cells;
}

static float coverage_of(const magcal_vec3_t *m, size_t n, const float c[3], float tiny)
{
    uint32_t bits[3] = {0u, 0u, 0u};
    coverage_cells(m, 0u, n, c, tiny, bits);
    return coverage_count(bits);
}

static magcal_status_t ellipsoid_check_cfg(const magcal_ellipsoid_cfg_t *cfg)
{
    if ((unsigned)cfg->model > (unsigned)MAGCAL_ELLIPSOID_MODEL_SPHERE) {
        return MAGCAL_ERR_ARG;
    }
    if ((unsigned)cfg->sqrt_method > (unsigned)MAGCAL_ELLIPSOID_SQRT_CHOLESKY) {
        return MAGCAL_ERR_ARG;
    }
    if (!magcal_isfinite_f(cfg->field) || cfg->field < 0.0f) {
        return MAGCAL_ERR_ARG;
    }
    if (!(cfg->min_coverage_full >= 0.0f && cfg->min_coverage_full <= 1.0f) ||
        !(cfg->min_coverage_sphere >= 0.0f && cfg->min_coverage_sphere <= 1.0f)) {
        return MAGCAL_ERR_ARG;
    }
    if (!(cfg->outlier_k >= 0.0f && cfg->outlier_k <= 100.0f) ||
        !(cfg->outlier_floor_rel >= 0.0f && cfg->outlier_floor_rel <= 1.0f)) {
        return MAGCAL_ERR_ARG;
    }
    if (cfg->max_refits > MAX_REFITS_LIMIT ||
        !(cfg->max_reject_frac >= 0.0f && cfg->max_reject_frac < 1.0f)) {
        return MAGCAL_ERR_ARG;
    }
    if (!(cfg->pivot_tau >= 0.0f && cfg->pivot_tau <= 0.1f)) {
        return MAGCAL_ERR_ARG;
    }
    if (!(cfg->min_motion_snr >= 0.0f && cfg->min_motion_snr <= 1000.0f) ||
        !(cfg->max_centre_std_rel >= 0.0f && cfg->max_centre_std_rel <= 1.0f) ||
        !(cfg->max_shape_std >= 0.0f && cfg->max_shape_std <= 1.0f) ||
        !(cfg->max_residual_rel >= 0.0f && cfg->max_residual_rel <= 1.0f) ||
        !(cfg->max_residual_rel_sphere >= 0.0f && cfg->max_residual_rel_sphere <= 1.0f)) {
        return MAGCAL_ERR_ARG;
    }
    if (!magcal_isfinite_f(cfg->field_expected) || cfg->field_expected < 0.0f ||
        !(cfg->field_band_lo > 0.0f && cfg->field_band_lo <= 1.0f) ||
        !(cfg->field_band_hi >= 1.0f && cfg->field_band_hi <= 100.0f)) {
        return MAGCAL_ERR_ARG;
    }
    return MAGCAL_OK;
}

/* ---- the residual pass (sub-machine ELL_PH_RP) ---- */

void magcal_ell_rp_start(ell_run_t *r, const magcal_ellipsoid_cal_t *cal, const quad_gate_t *gate,
                         const ell_ws_t *ws, uint8_t ret)
{
    r->rp.cal = cal;
    r->rp.gate = gate;
    r->rp.ws = *ws;
    r->rp.sum = 0.0f;
    r->rp.comp = 0.0f;
    r->rp.mx = 0.0f;
    r->rp.cnt = 0u;
    r->rp.ret = ret;
    r->k = 0u;
    r->ph = ELL_PH_RP;
}

/* RMS of the residuals under rp.cal of the samples kept by rp.gate; their count and max |r|.
 * With ws->res: every sample's residual is stored there (regate reads the rejected ones too). */
static MAGCAL_NOINLINE int rp_range(ell_run_t *r, ell_bud_t *b)
{
    ell_rp_t *rp = &r->rp;
    const uint32_t w = (rp->ws.res != NULL) ? (uint32_t)W_RP : (uint32_t)W_RP_RECOMP;
    const size_t k1 = r->k + magcal_ell_visits(b, w, r->n - r->k);
    const magcal_vec3_t *m = r->m;
    const magcal_ellipsoid_cal_t *cal = rp->cal;
    float *res = rp->ws.res;
    const uint8_t *keep = rp->ws.keep;
    float sum = rp->sum;
    float comp = rp->comp;
    float mx = rp->mx;
    size_t cnt = rp->cnt;
    size_t k;
    for (k = r->k; k < k1; ++k) {
        float rr;
        if (res != NULL) {
            rr = magcal_ell_residual(cal, &m[k]);
            res[k] = rr;
            if ((keep[k] & 1u) == 0u) {
                continue;
            }
        } else {
            if (!magcal_ell_gate_keeps(rp->gate, &m[k])) {
                continue;
            }
            rr = magcal_ell_residual(cal, &m[k]);
        }
        magcal_kahan_add(&sum, &comp, rr * rr);
        if (fabsf(rr) > mx) {
            mx = fabsf(rr);
        }
        cnt++;
    }
    r->k = k1;
    rp->sum = sum;
    rp->comp = comp;
    rp->mx = mx;
    rp->cnt = cnt;
    if (r->k < r->n) {
        return ELL_YIELD;
    }
    rp->kept = rp->cnt;
    rp->rms = (rp->cnt > 0u) ? sqrtf(rp->sum / (float)rp->cnt) : 0.0f;
    r->k = 0u;
    r->ph = rp->ret;
    return ELL_CONT;
}

/* ---- normalisation: mean and scale s (RMS distance from the mean); the scatter about the mean
 *      (packed xx, yx, yy, zx, zy, zz) into acc->sum, which pass 3 clears ---- */

static MAGCAL_NOINLINE int n1_range(ell_scratch_t *sw, ell_bud_t *b)
{
    ell_run_t *r = &sw->run;
    float *mu = sw->mu;
    size_t k;
    const size_t k1 = r->k + magcal_ell_visits(b, W_N1, r->n - r->k);
    float c0 = r->comp3[0];
    float c1 = r->comp3[1];
    float c2 = r->comp3[2];
    float m0 = mu[0];
    float m1 = mu[1];
    float m2 = mu[2];
    for (k = r->k; k < k1; ++k) {
        const magcal_vec3_t *p = &r->m[k];
        if (!magcal_isfinite_f(p->x) || !magcal_isfinite_f(p->y) || !magcal_isfinite_f(p->z)) {
            return MAGCAL_ERR_NONFINITE;
        }
        magcal_kahan_add(&m0, &c0, p->x);
        magcal_kahan_add(&m1, &c1, p->y);
        magcal_kahan_add(&m2, &c2, p->z);
    }
    r->k = k1;
    mu[0] = m0;
    mu[1] = m1;
    mu[2] = m2;
    r->comp3[0] = c0;
    r->comp3[1] = c1;
    r->comp3[2] = c2;
    if (r->k < r->n) {
        return ELL_YIELD;
    }
    for (k = 0u; k < 3u; ++k) {
        mu[k] /= (float)r->n;
    }
    (void)memset(&sw->acc, 0, sizeof(sw->acc));
    r->k = 0u;
    r->ph = ELL_PH_N2;
    return ELL_CONT;
}

static MAGCAL_NOINLINE int n2_range(ell_scratch_t *sw, ell_bud_t *b)
{
    ell_run_t *r = &sw->run;
    const float *mu = sw->mu;
    float *sc = sw->acc.sum;
    float *scc = sw->acc.comp;
    const size_t k1 = r->k + magcal_ell_visits(b, W_N2, r->n - r->k);
    size_t k;
    for (k = r->k; k < k1; ++k) {
        const magcal_vec3_t *p = &r->m[k];
        float dx = p->x - mu[0];
        float dy = p->y - mu[1];
        float dz = p->z - mu[2];
        magcal_kahan_add(&sc[0], &scc[0], dx * dx);
        magcal_kahan_add(&sc[1], &scc[1], dy * dx);
        magcal_kahan_add(&sc[2], &scc[2], dy * dy);
        magcal_kahan_add(&sc[3], &scc[3], dz * dx);
        magcal_kahan_add(&sc[4], &scc[4], dz * dy);
        magcal_kahan_add(&sc[5], &scc[5], dz * dz);
    }
    r->k = k1;
    if (r->k < r->n) {
        return ELL_YIELD;
    }
    r->k = 0u;
    r->ph = ELL_PH_NORM_DONE;
    return ELL_CONT;
}

/* The scale, the planarity of the raw scatter; pass 3 starts. */
static MAGCAL_NOINLINE int ph_norm_done(ell_scratch_t *sw, ell_bud_t *b)
{
    ell_run_t *r = &sw->run;
    const float *mu = sw->mu;
    const float *sc = sw->acc.sum;
    float s;
    if (magcal_ell_can(b, W_NORM_DONE) == 0) {
        return ELL_YIELD;
    }
    s = sqrtf((sc[0] + sc[2] + sc[5]) / (float)r->n);
    if (!(s > 1e-6f * (fabsf(mu[0]) + fabsf(mu[1]) + fabsf(mu[2]))) || !(s > 0.0f) ||
        !magcal_isfinite_f(s)) {
        return MAGCAL_ERR_DEGENERATE;
    }
    r->s = s;
    r->inv_s = 1.0f / s;
    r->planarity = magcal_ell_planarity(sw->acc.sum, sw);
    acc_start(sw);
    r->ph = ELL_PH_ACC;
    return ELL_CONT;
}

/* The sphere fit gives the provisional centre; then the algebraic quadric's noise scale. */
static MAGCAL_NOINLINE int ph_sphere(ell_scratch_t *sw, ell_bud_t *b)
{
    ell_run_t *r = &sw->run;
    magcal_ellipsoid_cal_t *sphere_cal = &sw->cal[2];
    float *cov_centre = sw->cov_centre;
    magcal_status_t st;
    if (magcal_ell_can(b, W_SPHERE) == 0) {
        return ELL_YIELD;
    }
    r->model = r->cfg->model;
    cov_centre[0] = sw->mu[0];
    cov_centre[1] = sw->mu[1];
    cov_centre[2] = sw->mu[2];
    st = solve_sphere(&sw->acc, sw->mat, sw->mu, r->s, r->cfg->field, r->cfg->pivot_tau, sphere_cal,
                      &r->min_pivot);
    if (st == MAGCAL_OK) {
        cov_centre[0] = sphere_cal->v.x;
        cov_centre[1] = sphere_cal->v.y;
        cov_centre[2] = sphere_cal->v.z;
    }
    sw->mc.m = r->m;
    sw->mc.n = r->n;
    sw->mc.s = r->s;
    sw->mc.sphere = (st == MAGCAL_OK) ? sphere_cal : NULL;
    r->bits[0] = 0u;
    r->bits[1] = 0u;
    r->bits[2] = 0u;
    r->ph = ELL_PH_ASNR0; /* -> mc.snr_alg, then ELL_PH_COV */
    return ELL_CONT;
}

static MAGCAL_NOINLINE int cov_range(ell_scratch_t *sw, ell_bud_t *b)
{
    ell_run_t *r = &sw->run;
    const size_t k0 = r->k;
    r->k += magcal_ell_visits(b, W_COV, r->n - r->k);
    coverage_cells(r->m, k0, r->k, sw->cov_centre, 1e-6f * r->s, r->bits);
    if (r->k < r->n) {
        return ELL_YIELD;
    }
    r->k = 0u;
    r->ph = ELL_PH_COV_DONE;
    return ELL_CONT;
}

static int ph_cov_done(ell_scratch_t *sw, ell_bud_t *b)
{
    ell_run_t *r = &sw->run;
    const magcal_ellipsoid_cfg_t *cfg = r->cfg;
    if (magcal_ell_can(b, W_COV_DONE) == 0) {
        return ELL_YIELD;
    }
    r->coverage = coverage_count(r->bits);
    if (r->model == MAGCAL_ELLIPSOID_MODEL_AUTO) {
        if (r->coverage < cfg->min_coverage_sphere) {
            magcal_ell_explain_start(r, MAGCAL_ERR_COVERAGE);
            return ELL_CONT;
        }
        r->model = (r->coverage >= cfg->min_coverage_full && r->n >= MIN_QUADRIC_POINTS)
                       ? MAGCAL_ELLIPSOID_MODEL_QUADRIC9
                       : MAGCAL_ELLIPSOID_MODEL_SPHERE;
    }
    r->fit_ret = ELL_PH_KEEP1;
    r->ph = ELL_PH_FIT_SOLVE;
    return ELL_CONT;
}

/* The model's solve from the normal matrix (the sphere is complete here), then r->fit_ret. */
static MAGCAL_NOINLINE int ph_fit_solve(ell_scratch_t *sw, ell_bud_t *b)
{
    ell_run_t *r = &sw->run;
    const magcal_ellipsoid_cfg_t *cfg = r->cfg;
    const quad_acc_t *acc = &sw->acc;
    magcal_status_t st;
    uint32_t w = W_SOLVE9;
    if (r->model == MAGCAL_ELLIPSOID_MODEL_SPHERE) {
        w = W_SOLVE4;
    } else if (r->model == MAGCAL_ELLIPSOID_MODEL_QUADRIC10) {
        w = W_SOLVE10;
    } else {
        /* the 9-parameter quadric */
    }
    if (magcal_ell_can(b, w) == 0) {
        return ELL_YIELD;
    }
    if (r->model == MAGCAL_ELLIPSOID_MODEL_SPHERE) {
        st = (acc->count < MIN_SPHERE_POINTS)
                 ? MAGCAL_ERR_TOO_FEW_POINTS
                 : solve_sphere(acc, sw->mat, sw->mu, r->s, cfg->field, cfg->pivot_tau, &sw->cal[0],
                                &r->min_pivot);
        r->ph = r->fit_ret;
    } else if (acc->count < MIN_QUADRIC_POINTS) {
        st = MAGCAL_ERR_TOO_FEW_POINTS;
    } else if (r->model == MAGCAL_ELLIPSOID_MODEL_QUADRIC10) {
        st = solve_quadric10(acc, sw->mat, cfg->pivot_tau, sw->coef, &r->min_pivot);
        r->ph = ELL_PH_FIT_EXTRACT;
    } else {
        st = solve_quadric9(acc, sw->mat, cfg->pivot_tau, sw->coef, &r->min_pivot);
        r->ph = ELL_PH_FIT_EXTRACT;
    }
    if (st != MAGCAL_OK) {
        magcal_ell_explain_start(r, st);
    }
    return ELL_CONT;
}

static MAGCAL_NOINLINE int ph_fit_extract(ell_scratch_t *sw, ell_bud_t *b)
{
    ell_run_t *r = &sw->run;
    magcal_status_t st;
    if (magcal_ell_can(b, W_EXTRACT) == 0) {
        return ELL_YIELD;
    }
    st = extract_quadric(sw, sw->mu, r->s, r->cfg->field, r->cfg->sqrt_method, &sw->cal[0]);
    r->ph = r->fit_ret;
    if (st != MAGCAL_OK) {
        magcal_ell_explain_start(r, st);
    }
    return ELL_CONT;
}

/* No gate yet: every sample kept (the stored verdicts). */
static int keep1_range(ell_scratch_t *sw, ell_bud_t *b)
{
    ell_run_t *r = &sw->run;
    if (r->ws.keep != NULL) {
        const size_t v = magcal_ell_visits(b, W_KEEP, r->n - r->k);
        (void)memset(&r->ws.keep[r->k], 1, v);
        r->k += v;
        if (r->k < r->n) {
            return ELL_YIELD;
        }
    }
    r->k = 0u;
    r->iter = 0u;
    r->prev_rejected = 0u;
    r->rms_valid = 0u;
    r->ph = ELL_PH_LOOP;
    return ELL_CONT;
}

/*
 * Outlier rejection: robust residual gate + refit (the samples are read again; with a workspace
 * their residuals are stored, not recomputed). The scale is 1.4826 x median |r| of the kept
 * samples, not their RMS: a dense burst pulls the first fit towards itself and inflates the RMS
 * enough to hide (issue 12). One round: residual pass, median, threshold, regate, settle, refit.
 */
static MAGCAL_NOINLINE int ph_loop_unit(ell_scratch_t *sw, ell_bud_t *b)
{
    ell_run_t *r = &sw->run;
    const magcal_ellipsoid_cfg_t *cfg = r->cfg;
    magcal_ellipsoid_cal_t *cal = &sw->cal[0];
    if (magcal_ell_can(b, W_UNIT) == 0) {
        return ELL_YIELD;
    }
    switch (r->ph) {
    case ELL_PH_LOOP:
        if (r->iter < cfg->max_refits && cfg->outlier_k > 0.0f) {
            magcal_ell_rp_start(r, cal, &sw->gate, &r->ws, ELL_PH_LOOP_MED);
        } else {
            r->ph = ELL_PH_FINAL;
        }
        break;
    case ELL_PH_LOOP_MED:
        r->rms = r->rp.rms;
        r->kept = r->rp.kept;
        r->rmax = r->rp.mx;
        r->rms_valid = 1u;
        sw->next.cal = cal;
        sw->src.cal = cal;
        magcal_ell_med_start(r, &sw->src, &sw->gate, &r->ws, r->kept, r->rmax, ELL_PH_THR);
        break;
    case ELL_PH_THR:
        sw->next.thr = cfg->outlier_k * MAGCAL_ELL_MAD_TO_SIGMA * r->med.result;
        if (sw->next.thr < cfg->outlier_floor_rel * cal->field) {
            sw->next.thr = cfg->outlier_floor_rel * cal->field;
        }
        /* the count under the new gate; acc follows it (unused when the loop ends here) */
        r->kept_new = 0u;
        r->k = 0u;
        r->ph = ELL_PH_REGATE;
        break;
    case ELL_PH_REFIT: {
        const size_t rejected = r->n - r->kept_new;
        if ((float)rejected > cfg->max_reject_frac * (float)r->n) {
            magcal_ell_explain_start(r, MAGCAL_ERR_TOO_MANY_OUTLIERS);
            break;
        }
        r->rms_valid = 0u;
        sw->cal[1] = *cal;
        sw->gate.cal = &sw->cal[1];
        sw->gate.thr = sw->next.thr;
        r->fit_ret = ELL_PH_LOOP_NEXT;
        r->ph = ELL_PH_FIT_SOLVE;
        break;
    }
    case ELL_PH_LOOP_NEXT:
        r->prev_rejected = r->n - r->kept_new;
        r->iter++;
        r->ph = ELL_PH_LOOP;
        break;
    case ELL_PH_FINAL:
        if (r->rms_valid == 0u) {
            magcal_ell_rp_start(r, cal, &sw->gate, &r->ws, ELL_PH_FINAL2);
        } else {
            r->ph = ELL_PH_FINAL2;
        }
        break;
    default: /* ELL_PH_FINAL2 */
        if (r->rms_valid == 0u) {
            r->rms = r->rp.rms;
            r->kept = r->rp.kept;
        }
        if (r->kept < ((r->model == MAGCAL_ELLIPSOID_MODEL_SPHERE) ? MIN_SPHERE_POINTS
                                                                   : MIN_QUADRIC_POINTS)) {
            return MAGCAL_ERR_TOO_FEW_POINTS;
        }
        r->ph = ELL_PH_TG0; /* the trust gates, then ELL_PH_OUT */
        break;
    }
    return ELL_CONT;
}

static int ph_out(ell_scratch_t *sw, ell_bud_t *b)
{
    ell_run_t *r = &sw->run;
    magcal_ellipsoid_result_t *out = r->out;
    const trust_diag_t *dg = &sw->dg;
    const quad_gate_t *gate = &sw->gate;
    if (magcal_ell_can(b, W_OUT) == 0) {
        return ELL_YIELD;
    }
    out->cal = sw->cal[0];
    out->residual_rms = r->rms;
    out->coverage = r->coverage;
    out->min_pivot = r->min_pivot;
    out->n_used = r->kept;
    out->n_rejected = r->n - r->kept;
    out->model = r->model;
    /* the final pass's gate, for magcal_ellipsoid_outliers (thr 0: no gate) */
    out->gate_cal = (gate->cal != NULL) ? sw->cal[1] : sw->cal[0];
    out->gate_thr = (gate->cal != NULL) ? gate->thr : 0.0f;
    out->motion_snr = dg->motion_snr;
    out->centre_std_rel = dg->centre_std_rel;
    out->shape_std = dg->shape_std;
    out->planarity = dg->planarity;
    out->field_raw = dg->field_raw;
    return MAGCAL_OK;
}

static MAGCAL_NOINLINE int ell_ph_check(ell_scratch_t *sw, ell_bud_t *b)
{
    ell_run_t *r = &sw->run;
    magcal_status_t st;
    if (magcal_ell_can(b, W_CHECK) == 0) {
        return ELL_YIELD;
    }
    sw->gate.cal = NULL; /* no gate yet */
    sw->gate.thr = 0.0f;
    sw->src.cal = NULL;
    sw->src.theta = NULL;
    sw->src.mu = NULL;
    sw->src.inv_s = 0.0f;
    r->all.cal = NULL;
    r->all.thr = 0.0f;
    r->min_pivot = 0.0f;
    r->rms = 0.0f;
    r->kept = 0u;
    st = ellipsoid_check_cfg(r->cfg);
    if (st != MAGCAL_OK) {
        return st;
    }
    if (r->n < ((r->cfg->model == MAGCAL_ELLIPSOID_MODEL_QUADRIC9 ||
                 r->cfg->model == MAGCAL_ELLIPSOID_MODEL_QUADRIC10)
                    ? MIN_QUADRIC_POINTS
                    : MIN_SPHERE_POINTS)) {
        return MAGCAL_ERR_TOO_FEW_POINTS;
    }
    sw->mu[0] = 0.0f;
    sw->mu[1] = 0.0f;
    sw->mu[2] = 0.0f;
    r->comp3[0] = 0.0f;
    r->comp3[1] = 0.0f;
    r->comp3[2] = 0.0f;
    r->k = 0u;
    r->ph = ELL_PH_N1;
    return ELL_CONT;
}

/* One phase of the fit: ELL_CONT (go on), ELL_YIELD (budget spent) or the final status. */
static int fit_phase(ell_scratch_t *sw, ell_bud_t *b)
{
    ell_run_t *r = &sw->run;
    if (r->ph >= ELL_PH_TRUST_FIRST) {
        return magcal_ell_trust_phase(sw, b);
    }
    switch (r->ph) {
    case ELL_PH_CHECK:
        return ell_ph_check(sw, b);
    case ELL_PH_N1:
        return n1_range(sw, b);
    case ELL_PH_N2:
        return n2_range(sw, b);
    case ELL_PH_NORM_DONE:
        return ph_norm_done(sw, b);
    case ELL_PH_ACC:
        return acc_range(sw, b);
    case ELL_PH_SPHERE:
        return ph_sphere(sw, b);
    case ELL_PH_COV:
        return cov_range(sw, b);
    case ELL_PH_COV_DONE:
        return ph_cov_done(sw, b);
    case ELL_PH_FIT_SOLVE:
        return ph_fit_solve(sw, b);
    case ELL_PH_FIT_EXTRACT:
        return ph_fit_extract(sw, b);
    case ELL_PH_KEEP1:
        return keep1_range(sw, b);
    case ELL_PH_REGATE:
        return regate_range(sw, b);
    case ELL_PH_SETTLE:
        return settle_range(sw, b);
    case ELL_PH_OUT:
        return ph_out(sw, b);
    case ELL_PH_RP:
        return rp_range(r, b);
    default: /* ELL_PH_LOOP .. ELL_PH_FINAL2 */
        return ph_loop_unit(sw, b);
    }
}

/*
 * Phases until the budget is spent or the fit ends. Bounded: every ELL_CONT either ends a phase
 * (finitely many: at most 2 + max_refits rounds of a fixed sequence) or a pass, and every pass
 * visits each sample once.
 */
static MAGCAL_NOINLINE magcal_status_t fit_steps(ell_scratch_t *sw, uint32_t budget,
                                                 uint32_t *used, int first)
{
    int rc = ELL_CONT;
    *used = 0u;
    while (rc == ELL_CONT) {
        ell_bud_t b;
        b.left = budget - *used;
        b.cost = 0u;
        b.first = (*used == 0u && first != 0) ? (int)1 : (int)0;
        rc = fit_phase(sw, &b);
        *used += b.cost;
        if (rc == ELL_CONT && *used >= budget) {
            rc = ELL_YIELD;
        }
    }
    if (rc == ELL_YIELD) {
        return MAGCAL_IN_PROGRESS;
    }
    sw->run.ph = ELL_PH_DONE;
    return (magcal_status_t)rc;
}

/* Begin on a scratch (the stack's for magcal_ellipsoid_fit, the workspace's otherwise). */
static void fit_begin_on(magcal_ellipsoid_fit_slice_t *s, const ell_ws_t *ws,
                         const magcal_vec3_t *m, size_t n, const magcal_ellipsoid_cfg_t *cfg,
                         magcal_ellipsoid_result_t *out)
{
    ell_run_t *r = &ws->s->run;
    r->m = m;
    r->n = n;
    r->cfg = cfg;
    r->ws = *ws;
    r->out = out;
    r->k = 0u;
    r->ph = ELL_PH_CHECK;
    s->s_ = ws->s;
    s->used_ = 0u;
    s->status_ = (int32_t)MAGCAL_IN_PROGRESS;
}

magcal_status_t magcal_ellipsoid_fit_begin(magcal_ellipsoid_fit_slice_t *s, const magcal_vec3_t *m,
                                           size_t n, const magcal_ellipsoid_cfg_t *cfg, void *work,
                                           size_t work_len, magcal_ellipsoid_result_t *out)
{
    ell_ws_t ws;
    if (s == NULL) {
        return MAGCAL_ERR_NULL;
    }
    s->s_ = NULL;
    s->used_ = 0u;
    s->status_ = (int32_t)MAGCAL_ERR_ARG;
    if (m == NULL || cfg == NULL || work == NULL || out == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (magcal_misalign(work, 4u) != 0u) {
        return MAGCAL_ERR_ALIGNMENT;
    }
    if (n > (SIZE_MAX - MAGCAL_ELLIPSOID_FIT_SCRATCH_BYTES) / (sizeof(float) + 1u) ||
        work_len < MAGCAL_ELLIPSOID_FIT_WORKSPACE_LEN(n)) {
        return MAGCAL_ERR_WORKSPACE;
    }
    /* layout: [0 or 4 B] scratch (8-byte aligned) | n residuals at SCRATCH_BYTES | n verdicts */
    ws.s = (ell_scratch_t *)(void *)magcal_ell_align_up(work);
    ws.res = (float *)(void *)((uint8_t *)work + MAGCAL_ELLIPSOID_FIT_SCRATCH_BYTES);
    ws.keep = (uint8_t *)work + MAGCAL_ELLIPSOID_FIT_SCRATCH_BYTES + n * sizeof(float);
    fit_begin_on(s, &ws, m, n, cfg, out);
    return MAGCAL_OK;
}

magcal_status_t magcal_ell_fit_step_in(magcal_ellipsoid_fit_slice_t *s, uint32_t budget, int first)
{
    uint32_t used = 0u;
    magcal_status_t st;
    if (s == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (s->s_ == NULL) {
        return MAGCAL_ERR_ARG;
    }
    if (s->status_ != (int32_t)MAGCAL_IN_PROGRESS) {
        s->used_ = 0u;
        return (magcal_status_t)s->status_;
    }
    st = fit_steps((ell_scratch_t *)s->s_, (budget > 0u) ? budget : 1u, &used, first);
    s->used_ = used;
    s->status_ = (int32_t)st;
    return st;
}

magcal_status_t magcal_ellipsoid_fit_step(magcal_ellipsoid_fit_slice_t *s, uint32_t budget)
{
    return magcal_ell_fit_step_in(s, budget, 1);
}

magcal_status_t magcal_ellipsoid_fit(const magcal_vec3_t *m, size_t n,
                                     const magcal_ellipsoid_cfg_t *cfg,
                                     magcal_ellipsoid_fit_scratch_t *scratch,
                                     magcal_ellipsoid_result_t *out)
{
    magcal_ellipsoid_fit_slice_t sl;
    ell_ws_t ws;
    if (m == NULL || cfg == NULL || scratch == NULL || out == NULL) {
        return MAGCAL_ERR_NULL;
    }
    ws.s = (ell_scratch_t *)(void *)scratch; /* fixed scratch, no per-sample storage */
    ws.res = NULL;
    ws.keep = NULL;
    fit_begin_on(&sl, &ws, m, n, cfg, out);
    return magcal_ellipsoid_fit_step(&sl, UINT32_MAX);
}

magcal_status_t magcal_ellipsoid_fit_ws(const magcal_vec3_t *m, size_t n,
                                        const magcal_ellipsoid_cfg_t *cfg, void *work,
                                        size_t work_len, magcal_ellipsoid_result_t *out)
{
    magcal_ellipsoid_fit_slice_t sl;
    const magcal_status_t st = magcal_ellipsoid_fit_begin(&sl, m, n, cfg, work, work_len, out);
    if (st != MAGCAL_OK) {
        return st;
    }
    return magcal_ellipsoid_fit_step(&sl, UINT32_MAX);
}

static int cal_isfinite(const magcal_ellipsoid_cal_t *cal)
{
    size_t i;
    size_t j;
    for (i = 0u; i < 3u; ++i) {
        for (j = 0u; j < 3u; ++j) {
            if (!magcal_isfinite_f(cal->g[i][j])) {
                return 0;
            }
        }
    }
    return magcal_isfinite_f(cal->v.x) && magcal_isfinite_f(cal->v.y) &&
           magcal_isfinite_f(cal->v.z) && magcal_isfinite_f(cal->field);
}

magcal_status_t magcal_ellipsoid_outliers(const magcal_ellipsoid_result_t *res,
                                          const magcal_vec3_t *m, size_t n, uint8_t *outlier,
                                          size_t *n_outliers)
{
    quad_gate_t gate;
    size_t k;
    size_t cnt = 0u;
    if (res == NULL || m == NULL || outlier == NULL || n_outliers == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (n == 0u) {
        return MAGCAL_ERR_TOO_FEW_POINTS;
    }
    if (!magcal_isfinite_f(res->gate_thr) || res->gate_thr < 0.0f ||
        cal_isfinite(&res->gate_cal) == 0) {
        return MAGCAL_ERR_ARG;
    }
    /* validate every sample before writing: outputs stay untouched on failure */
    for (k = 0u; k < n; ++k) {
        if (!magcal_isfinite_f(m[k].x) || !magcal_isfinite_f(m[k].y) ||
            !magcal_isfinite_f(m[k].z)) {
            return MAGCAL_ERR_NONFINITE;
        }
    }
    /* the very predicate the fit accumulated with (gate_keeps), so the counts agree bit for bit */
    gate.cal = (res->gate_thr > 0.0f) ? &res->gate_cal : NULL;
    gate.thr = res->gate_thr;
    for (k = 0u; k < n; ++k) {
        if (magcal_ell_gate_keeps(&gate, &m[k]) != 0) {
            outlier[k] = 0u;
        } else {
            outlier[k] = 1u;
            cnt++;
        }
    }
    *n_outliers = cnt;
    return MAGCAL_OK;
}

magcal_status_t magcal_ellipsoid_apply(const magcal_ellipsoid_cal_t *cal, const magcal_vec3_t *m,
                                       magcal_vec3_t *h)
{
    float r[3];
    size_t i;
    if (cal == NULL || m == NULL || h == NULL) {
        return MAGCAL_ERR_NULL;
    }
    magcal_ell_correct(cal, m, r);
    for (i = 0u; i < 3u; ++i) {
        if (!magcal_isfinite_f(r[i])) {
            return MAGCAL_ERR_NONFINITE;
        }
    }
    h->x = r[0];
    h->y = r[1];
    h->z = r[2];
    return MAGCAL_OK;
}

magcal_status_t magcal_ellipsoid_coverage(const magcal_vec3_t *m, size_t n,
                                          const magcal_vec3_t *centre, float *coverage)
{
    float c[3];
    float mag = 0.0f;
    size_t k;
    if (m == NULL || centre == NULL || coverage == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (n == 0u) {
        return MAGCAL_ERR_TOO_FEW_POINTS;
    }
    if (!magcal_isfinite_f(centre->x) || !magcal_isfinite_f(centre->y) ||
        !magcal_isfinite_f(centre->z)) {
        return MAGCAL_ERR_NONFINITE;
    }
    for (k = 0u; k < n; ++k) {
        float a;
        if (!magcal_isfinite_f(m[k].x) || !magcal_isfinite_f(m[k].y) ||
            !magcal_isfinite_f(m[k].z)) {
            return MAGCAL_ERR_NONFINITE;
        }
        a = fabsf(m[k].x - centre->x) + fabsf(m[k].y - centre->y) + fabsf(m[k].z - centre->z);
        if (a > mag) {
            mag = a;
        }
    }
    c[0] = centre->x;
    c[1] = centre->y;
    c[2] = centre->z;
    *coverage = coverage_of(m, n, c, 1e-6f * mag);
    return MAGCAL_OK;
}

#endif /* MAGCAL_CFG_ENABLE_3D */
