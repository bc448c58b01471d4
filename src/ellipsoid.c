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

static MAGCAL_NOINLINE void accumulate(const magcal_vec3_t *m, size_t n, const float mu[3],
                                       float inv_s, ell_scratch_t *ws)
{
    quad_acc_t *acc = &ws->acc;
    float *part = ws->part;
    size_t k;
    size_t in_block = 0u;
    (void)memset(acc, 0, sizeof(*acc));
    (void)memset(part, 0, sizeof(ws->part));
    for (k = 0u; k < n; ++k) {
        float row[NQ];
        design_row(&m[k], mu, inv_s, row);
        outer10_add(part, row);
        acc->count++;
        if (++in_block == MAGCAL_ELL_BLOCK) {
            magcal_ell_flush(acc->sum, acc->comp, part, MAGCAL_ELL_NPACK);
            in_block = 0u;
        }
    }
    magcal_ell_flush(acc->sum, acc->comp, part, MAGCAL_ELL_NPACK);
}

/*
 * Move the normal matrix `acc` (of the samples `old_gate` keeps) to the samples `new_gate` keeps:
 * only the samples whose verdict changes are added or removed (a refit after rejecting a few
 * outliers costs one residual pass, not a new accumulation). Returns the count `new_gate` keeps.
 */
static MAGCAL_NOINLINE size_t regate(const magcal_vec3_t *m, size_t n, const float mu[3],
                                     float inv_s, const quad_gate_t *old_gate,
                                     const quad_gate_t *new_gate, const ell_ws_t *ws)
{
    quad_acc_t *acc = &ws->s->acc;
    size_t k;
    size_t i;
    size_t j;
    size_t kept = 0u;
    for (k = 0u; k < n; ++k) {
        int was;
        int is;
        float row[NQ];
        float sign;
        size_t p = 0u;
        if (ws->res != NULL) { /* stored: the very predicate gate_keeps evaluates */
            was = 0;
            is = 0;
            if ((ws->keep[k] & 1u) != 0u) {
                was = 1;
            }
            if (fabsf(ws->res[k]) < new_gate->thr) {
                is = 1;
                ws->keep[k] |= (uint8_t)2u; /* bit 1: the next gate's verdict */
            }
        } else {
            was = magcal_ell_gate_keeps(old_gate, &m[k]);
            is = magcal_ell_gate_keeps(new_gate, &m[k]);
        }
        kept += (is != 0) ? 1u : 0u;
        if (was == is) {
            continue;
        }
        sign = (is != 0) ? 1.0f : -1.0f;
        design_row(&m[k], mu, inv_s, row);
        for (i = 0u; i < NQ; ++i) {
            for (j = 0u; j <= i; ++j) {
                magcal_kahan_add(&acc->sum[p], &acc->comp[p], sign * row[i] * row[j]);
                ++p;
            }
        }
    }
    acc->count = kept;
    return kept;
}

/* After regate: the stored verdicts become the next gate's (adopt != 0) or stay the old one's. */
static void regate_settle(const ell_ws_t *ws, size_t n, int adopt)
{
    size_t k;
    if (ws->keep == NULL) {
        return;
    }
    for (k = 0u; k < n; ++k) {
        const uint8_t bit = (adopt != 0) ? (uint8_t)2u : (uint8_t)1u;
        ws->keep[k] = ((ws->keep[k] & bit) != 0u) ? (uint8_t)1u : (uint8_t)0u;
    }
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

static MAGCAL_NOINLINE magcal_status_t fit_model(ell_scratch_t *ws, magcal_ellipsoid_model_t model,
                                 const float mu[3], float s, const magcal_ellipsoid_cfg_t *cfg,
                                 magcal_ellipsoid_cal_t *cal, float *min_pivot)
{
    const quad_acc_t *acc = &ws->acc;
    float *coef = ws->coef;
    magcal_status_t st;
    if (model == MAGCAL_ELLIPSOID_MODEL_SPHERE) {
        if (acc->count < MIN_SPHERE_POINTS) {
            return MAGCAL_ERR_TOO_FEW_POINTS;
        }
        return solve_sphere(acc, ws->mat, mu, s, cfg->field, cfg->pivot_tau, cal, min_pivot);
    }
    if (acc->count < MIN_QUADRIC_POINTS) {
        return MAGCAL_ERR_TOO_FEW_POINTS;
    }
    if (model == MAGCAL_ELLIPSOID_MODEL_QUADRIC10) {
        st = solve_quadric10(acc, ws->mat, cfg->pivot_tau, coef, min_pivot);
    } else {
        st = solve_quadric9(acc, ws->mat, cfg->pivot_tau, coef, min_pivot);
    }
    if (st != MAGCAL_OK) {
        return st;
    }
    return extract_quadric(ws, mu, s, cfg->field, cfg->sqrt_method, cal);
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

static float coverage_of(const magcal_vec3_t *m, size_t n, const float c[3], float tiny)
{
    uint32_t bits[3] = {0u, 0u, 0u};
    const size_t cells = COV_CELLS;
    size_t k;
    size_t filled = 0u;
    for (k = 0u; k < n; ++k) {
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
    for (k = 0u; k < cells; ++k) {
        if (((bits[k / 32u] >> (k % 32u)) & 1u) != 0u) {
            filled++;
        }
    }
    return (float)filled / (float)cells;
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

/* RMS of the residuals under `cal` of the samples kept by `gate`; their count and max |r|.
 * With ws->res: every sample's residual is stored there (regate reads the rejected ones too). */
float magcal_ell_residual_pass(const magcal_vec3_t *m, size_t n, const magcal_ellipsoid_cal_t *cal,
                               const quad_gate_t *gate, const ell_ws_t *ws, size_t *kept,
                               float *max_abs)
{
    float sum = 0.0f;
    float comp = 0.0f;
    float mx = 0.0f;
    size_t k;
    size_t cnt = 0u;
    for (k = 0u; k < n; ++k) {
        float r;
        if (ws->res != NULL) {
            r = magcal_ell_residual(cal, &m[k]);
            ws->res[k] = r;
            if ((ws->keep[k] & 1u) == 0u) {
                continue;
            }
        } else {
            if (!magcal_ell_gate_keeps(gate, &m[k])) {
                continue;
            }
            r = magcal_ell_residual(cal, &m[k]);
        }
        magcal_kahan_add(&sum, &comp, r * r);
        if (fabsf(r) > mx) {
            mx = fabsf(r);
        }
        cnt++;
    }
    *kept = cnt;
    if (max_abs != NULL) {
        *max_abs = mx;
    }
    return (cnt > 0u) ? sqrtf(sum / (float)cnt) : 0.0f;
}

/* Mean and scale s (RMS distance from the mean) of the samples; the scatter about the mean
 * (packed xx, yx, yy, zx, zy, zz) into sc (the accumulator's storage, which pass 3 clears). */
static magcal_status_t normalise(const magcal_vec3_t *m, size_t n, quad_acc_t *acc, float mu[3],
                                 float *s_out)
{
    float comp[3] = {0.0f, 0.0f, 0.0f};
    float *sc = acc->sum;
    float *scc = acc->comp;
    float s;
    size_t k;
    mu[0] = 0.0f;
    mu[1] = 0.0f;
    mu[2] = 0.0f;
    /* Pass 1: mean (Kahan). */
    for (k = 0u; k < n; ++k) {
        if (!magcal_isfinite_f(m[k].x) || !magcal_isfinite_f(m[k].y) ||
            !magcal_isfinite_f(m[k].z)) {
            return MAGCAL_ERR_NONFINITE;
        }
        magcal_kahan_add(&mu[0], &comp[0], m[k].x);
        magcal_kahan_add(&mu[1], &comp[1], m[k].y);
        magcal_kahan_add(&mu[2], &comp[2], m[k].z);
    }
    for (k = 0u; k < 3u; ++k) {
        mu[k] /= (float)n;
    }
    /* Pass 2: scatter about the mean; its trace gives the scale. */
    (void)memset(acc, 0, sizeof(*acc));
    for (k = 0u; k < n; ++k) {
        float dx = m[k].x - mu[0];
        float dy = m[k].y - mu[1];
        float dz = m[k].z - mu[2];
        magcal_kahan_add(&sc[0], &scc[0], dx * dx);
        magcal_kahan_add(&sc[1], &scc[1], dy * dx);
        magcal_kahan_add(&sc[2], &scc[2], dy * dy);
        magcal_kahan_add(&sc[3], &scc[3], dz * dx);
        magcal_kahan_add(&sc[4], &scc[4], dz * dy);
        magcal_kahan_add(&sc[5], &scc[5], dz * dz);
    }
    s = sqrtf((sc[0] + sc[2] + sc[5]) / (float)n);
    if (!(s > 1e-6f * (fabsf(mu[0]) + fabsf(mu[1]) + fabsf(mu[2]))) || !(s > 0.0f) ||
        !magcal_isfinite_f(s)) {
        return MAGCAL_ERR_DEGENERATE;
    }
    *s_out = s;
    return MAGCAL_OK;
}

/* The fit itself (magcal_ellipsoid_fit, magcal_ellipsoid_fit_ws): scratch in ws->s, per-sample
 * residuals and verdicts in ws->res / ws->keep when stored (see ell_ws_t). */
static magcal_status_t fit_core(const magcal_vec3_t *m, size_t n,
                                const magcal_ellipsoid_cfg_t *cfg, const ell_ws_t *ws,
                                magcal_ellipsoid_result_t *out)
{
    ell_scratch_t *sw = ws->s;
    magcal_ellipsoid_cal_t *cal = &sw->cal[0];
    magcal_ellipsoid_cal_t *gate_cal = &sw->cal[1];
    magcal_ellipsoid_cal_t *sphere_cal = &sw->cal[2];
    float *mu = sw->mu;
    float s;
    float inv_s;
    float *cov_centre = sw->cov_centre;
    float coverage;
    float min_pivot = 0.0f;
    motion_ctx_t *mcp = &sw->mc;
    float planarity;
    size_t iter;
    size_t kept = 0u;
    size_t prev_rejected = 0u;
    magcal_ellipsoid_model_t model;
    trust_diag_t *dg = &sw->dg;
    quad_gate_t *gate = &sw->gate;
    magcal_status_t st;
    float rms = 0.0f;
    float rmax;
    int rms_valid = 0;

    gate->cal = NULL; /* no gate yet */
    gate->thr = 0.0f;
    sw->src.cal = NULL;
    sw->src.theta = NULL;
    sw->src.mu = NULL;
    sw->src.inv_s = 0.0f;
    st = ellipsoid_check_cfg(cfg);
    if (st != MAGCAL_OK) {
        return st;
    }
    if (n < ((cfg->model == MAGCAL_ELLIPSOID_MODEL_QUADRIC9 ||
              cfg->model == MAGCAL_ELLIPSOID_MODEL_QUADRIC10)
                 ? MIN_QUADRIC_POINTS
                 : MIN_SPHERE_POINTS)) {
        return MAGCAL_ERR_TOO_FEW_POINTS;
    }
    st = normalise(m, n, &sw->acc, mu, &s);
    if (st != MAGCAL_OK) {
        return st;
    }
    inv_s = 1.0f / s;
    planarity = magcal_ell_planarity(sw->acc.sum, sw);

    /* Pass 3: the normal matrix of every sample; sphere fit gives the provisional centre, the
     * quadric's algebraic residual a noise scale that needs neither centre nor model. */
    accumulate(m, n, mu, inv_s, sw);
    model = cfg->model;
    cov_centre[0] = mu[0];
    cov_centre[1] = mu[1];
    cov_centre[2] = mu[2];
    st = solve_sphere(&sw->acc, sw->mat, mu, s, cfg->field, cfg->pivot_tau, sphere_cal, &min_pivot);
    if (st == MAGCAL_OK) {
        cov_centre[0] = sphere_cal->v.x;
        cov_centre[1] = sphere_cal->v.y;
        cov_centre[2] = sphere_cal->v.z;
    }
    mcp->m = m;
    mcp->n = n;
    mcp->s = s;
    mcp->sphere = (st == MAGCAL_OK) ? sphere_cal : NULL;
    mcp->snr_alg = magcal_ell_algebraic_snr(m, n, mu, inv_s, ws);
    coverage = coverage_of(m, n, cov_centre, 1e-6f * s);
    if (model == MAGCAL_ELLIPSOID_MODEL_AUTO) {
        if (coverage < cfg->min_coverage_sphere) {
            return magcal_ell_explain_failure(MAGCAL_ERR_COVERAGE, mcp, planarity, cfg, ws);
        }
        model = (coverage >= cfg->min_coverage_full && n >= MIN_QUADRIC_POINTS)
                    ? MAGCAL_ELLIPSOID_MODEL_QUADRIC9
                    : MAGCAL_ELLIPSOID_MODEL_SPHERE;
    }
    st = fit_model(sw, model, mu, s, cfg, cal, &min_pivot);
    if (st != MAGCAL_OK) {
        return magcal_ell_explain_failure(st, mcp, planarity, cfg, ws);
    }
    if (ws->keep != NULL) {
        (void)memset(ws->keep, 1, n); /* no gate yet: every sample kept */
    }

    /* Outlier rejection: robust residual gate + refit (the samples are read again; with a
     * workspace their residuals are stored, not recomputed). The scale is 1.4826 x median |r| of
     * the kept samples, not their RMS: a dense burst pulls the first fit towards itself and
     * inflates the RMS enough to hide (issue 12). */
    for (iter = 0u; iter < cfg->max_refits && cfg->outlier_k > 0.0f; ++iter) {
        size_t rejected;
        size_t kept_new;
        quad_gate_t *next = &sw->next;
        resid_src_t *src = &sw->src;
        rms = magcal_ell_residual_pass(m, n, cal, gate, ws, &kept, &rmax);
        rms_valid = 1;
        next->cal = cal;
        src->cal = cal;
        next->thr = cfg->outlier_k * MAGCAL_ELL_MAD_TO_SIGMA *
                   magcal_ell_median_abs(m, n, src, gate, ws, kept, rmax);
        if (next->thr < cfg->outlier_floor_rel * cal->field) {
            next->thr = cfg->outlier_floor_rel * cal->field;
        }
        /* the count under the new gate; acc follows it (unused when the loop ends here) */
        kept_new = regate(m, n, mu, inv_s, gate, next, ws);
        rejected = n - kept_new;
        if (rejected == prev_rejected) {
            regate_settle(ws, n, 0);
            break; /* cal and gate unchanged: rms and kept of this pass are final */
        }
        regate_settle(ws, n, 1);
        if ((float)rejected > cfg->max_reject_frac * (float)n) {
            return magcal_ell_explain_failure(MAGCAL_ERR_TOO_MANY_OUTLIERS, mcp, planarity, cfg,
                                              ws);
        }
        rms_valid = 0;
        *gate_cal = *cal;
        gate->cal = gate_cal;
        gate->thr = next->thr;
        st = fit_model(sw, model, mu, s, cfg, cal, &min_pivot);
        if (st != MAGCAL_OK) {
            return magcal_ell_explain_failure(st, mcp, planarity, cfg, ws);
        }
        prev_rejected = rejected;
    }
    if (rms_valid == 0) {
        rms = magcal_ell_residual_pass(m, n, cal, gate, ws, &kept, NULL);
    }
    if (kept <
        ((model == MAGCAL_ELLIPSOID_MODEL_SPHERE) ? MIN_SPHERE_POINTS : MIN_QUADRIC_POINTS)) {
        return MAGCAL_ERR_TOO_FEW_POINTS;
    }
    st = magcal_ell_trust_gates(m, n, cfg, cal, rms, model, gate, mcp, planarity, ws, dg);
    if (st != MAGCAL_OK) {
        return st;
    }
    out->cal = *cal;
    out->residual_rms = rms;
    out->coverage = coverage;
    out->min_pivot = min_pivot;
    out->n_used = kept;
    out->n_rejected = n - kept;
    out->model = model;
    /* the final pass's gate, for magcal_ellipsoid_outliers (thr 0: no gate) */
    out->gate_cal = (gate->cal != NULL) ? *gate_cal : *cal;
    out->gate_thr = (gate->cal != NULL) ? gate->thr : 0.0f;
    out->motion_snr = dg->motion_snr;
    out->centre_std_rel = dg->centre_std_rel;
    out->shape_std = dg->shape_std;
    out->planarity = dg->planarity;
    out->field_raw = dg->field_raw;
    return MAGCAL_OK;
}

magcal_status_t magcal_ellipsoid_fit(const magcal_vec3_t *m, size_t n,
                                     const magcal_ellipsoid_cfg_t *cfg,
                                     magcal_ellipsoid_result_t *out)
{
    ell_scratch_t scratch; /* no caller workspace: the scratch on the stack (see the header) */
    ell_ws_t ws;
    if (m == NULL || cfg == NULL || out == NULL) {
        return MAGCAL_ERR_NULL;
    }
    ws.s = &scratch;
    ws.res = NULL;
    ws.keep = NULL;
    return fit_core(m, n, cfg, &ws, out);
}

magcal_status_t magcal_ellipsoid_fit_ws(const magcal_vec3_t *m, size_t n,
                                        const magcal_ellipsoid_cfg_t *cfg, void *work,
                                        size_t work_len, magcal_ellipsoid_result_t *out)
{
    ell_ws_t ws;
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
    return fit_core(m, n, cfg, &ws, out);
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
