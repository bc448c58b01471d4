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

#include "magcal/ellipsoid.h"
#include "magcal_internal.h"

#define NQ 10u                        /* quadric row length */
#define NPACK ((NQ * (NQ + 1u)) / 2u) /* packed lower triangle */
#define COV_CELLS ((size_t)MAGCAL_ELLIPSOID_COV_AZ * MAGCAL_ELLIPSOID_COV_EL)
#define MIN_QUADRIC_POINTS 10u
#define MIN_SPHERE_POINTS 4u
#define MAX_REFITS_LIMIT 8u
#define INVITER_STEPS 8u
#define INVITER_SHIFT_TRIES 3u
#define MED_BINS 32u           /* histogram bins per refinement pass of the median |residual| */
#define MED_PASSES 4u          /* refinement passes: resolution (max |r|) / 32^4 at worst */
#define MAD_TO_SIGMA 1.4826f   /* sigma of a normal distribution = 1.4826 x median |r| */
#define PLANAR_MAX 0.15f       /* planarity below this: one rotation axis dominates (SINGLE_AXIS) */
#define INFO_MAX_N 9u          /* centre information: 3 offset + 6 symmetric shape parameters */

/* cppcheck-suppress misra-c2012-2.3 ; deviation D4: a static assert is an unused typedef */
MAGCAL_STATIC_ASSERT(COV_CELLS <= 96u, coverage_cells_fit_three_words);

/* Normalisation and Kahan-compensated normal matrix. */
typedef struct {
    float sum[NPACK];
    float comp[NPACK];
    size_t count;
} quad_acc_t;

/* Optional gate applied while accumulating: keep samples with | |G(m-V)| - F | < thr. */
typedef struct {
    const magcal_ellipsoid_cal_t *cal; /* NULL: keep every sample */
    float thr;
} quad_gate_t;

static size_t pidx(size_t i, size_t j)
{
    /* packed lower triangle, i >= j */
    return (i * (i + 1u)) / 2u + j;
}

/* h = G (m - V): the correction of one sample. */
static void correct3(const magcal_ellipsoid_cal_t *cal, const magcal_vec3_t *m, float h[3])
{
    float e[3];
    size_t i;
    e[0] = m->x - cal->v.x;
    e[1] = m->y - cal->v.y;
    e[2] = m->z - cal->v.z;
    for (i = 0u; i < 3u; ++i) {
        h[i] = cal->g[i][0] * e[0] + cal->g[i][1] * e[1] + cal->g[i][2] * e[2];
    }
}

static float residual_of(const magcal_ellipsoid_cal_t *cal, const magcal_vec3_t *m)
{
    float h[3];
    correct3(cal, m, h);
    return sqrtf(h[0] * h[0] + h[1] * h[1] + h[2] * h[2]) - cal->field;
}

/* The trust diagnostics of a fit (copied into the result on success). */
typedef struct {
    float motion_snr;
    float centre_std_rel;
    float shape_std;
    float planarity;
    float field_raw;
} trust_diag_t;

/* Which residual a median is taken of: geometric under `cal`, or (cal NULL) the algebraic
 * residual r.theta - 1 of the 9-parameter quadric `theta` in coordinates (m - mu) * inv_s. */
typedef struct {
    const magcal_ellipsoid_cal_t *cal;
    const float *theta;
    const float *mu;
    float inv_s;
} resid_src_t;

static int gate_keeps(const quad_gate_t *gate, const magcal_vec3_t *m)
{
    if (gate->cal == NULL) {
        return 1;
    }
    return fabsf(residual_of(gate->cal, m)) < gate->thr;
}

static void accumulate(const magcal_vec3_t *m, size_t n, const float mu[3], float inv_s,
                       const quad_gate_t *gate, quad_acc_t *acc)
{
    size_t k;
    size_t i;
    size_t j;
    (void)memset(acc, 0, sizeof(*acc));
    for (k = 0u; k < n; ++k) {
        float row[NQ];
        float x;
        float y;
        float z;
        if (!gate_keeps(gate, &m[k])) {
            continue;
        }
        x = (m[k].x - mu[0]) * inv_s;
        y = (m[k].y - mu[1]) * inv_s;
        z = (m[k].z - mu[2]) * inv_s;
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
        for (i = 0u; i < NQ; ++i) {
            for (j = 0u; j <= i; ++j) {
                size_t p = pidx(i, j);
                magcal_kahan_add(&acc->sum[p], &acc->comp[p], row[i] * row[j]);
            }
        }
        acc->count++;
    }
}

static float acc_at(const quad_acc_t *acc, size_t i, size_t j)
{
    return (i >= j) ? acc->sum[pidx(i, j)] : acc->sum[pidx(j, i)];
}

/* G with G^T G = q (q positive definite). */
static magcal_status_t sqrt_spd3(float q[3][3], magcal_ellipsoid_sqrt_t method, float g[3][3])
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
        float w[3];
        float e[3][3];
        float a[3][3];
        size_t i;
        size_t j;
        magcal_status_t st;
        (void)memcpy(a, q, sizeof(a)); /* magcal_jacobi_sym destroys its input */
        st = magcal_jacobi_sym(&a[0][0], 3u, w, &e[0][0]);
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
 * in normalised coordinates -> calibration in raw coordinates.
 */
static magcal_status_t extract_quadric(const float coef_in[NQ], const float mu[3], float s,
                                       float field_cfg, magcal_ellipsoid_sqrt_t method,
                                       magcal_ellipsoid_cal_t *cal)
{
    float coef[NQ];
    float aq[3][3];
    float inv[3][3];
    float u[3];
    float vt[3];
    float det;
    float k;
    float qn[3][3];
    float gn[3][3];
    float f;
    float detq;
    size_t i;
    size_t j;
    magcal_status_t st;

    (void)memcpy(coef, coef_in, sizeof(coef));
    if (coef[0] + coef[1] + coef[2] < 0.0f) { /* eigenvector sign is arbitrary */
        for (i = 0u; i < NQ; ++i) {
            coef[i] = -coef[i];
        }
    }
    aq[0][0] = coef[0];
    aq[1][1] = coef[1];
    aq[2][2] = coef[2];
    aq[1][2] = coef[3];
    aq[2][1] = coef[3];
    aq[0][2] = coef[4];
    aq[2][0] = coef[4];
    aq[0][1] = coef[5];
    aq[1][0] = coef[5];
    u[0] = coef[6];
    u[1] = coef[7];
    u[2] = coef[8];
    det = magcal_det3(aq);
    if (!magcal_isfinite_f(det) || det == 0.0f) {
        return MAGCAL_ERR_NOT_ELLIPSOID;
    }
    inv[0][0] = (aq[1][1] * aq[2][2] - aq[1][2] * aq[2][1]) / det;
    inv[0][1] = (aq[0][2] * aq[2][1] - aq[0][1] * aq[2][2]) / det;
    inv[0][2] = (aq[0][1] * aq[1][2] - aq[0][2] * aq[1][1]) / det;
    inv[1][1] = (aq[0][0] * aq[2][2] - aq[0][2] * aq[2][0]) / det;
    inv[1][2] = (aq[0][2] * aq[1][0] - aq[0][0] * aq[1][2]) / det;
    inv[2][2] = (aq[0][0] * aq[1][1] - aq[0][1] * aq[1][0]) / det;
    inv[1][0] = inv[0][1];
    inv[2][0] = inv[0][2];
    inv[2][1] = inv[1][2];
    for (i = 0u; i < 3u; ++i) {
        vt[i] = -(inv[i][0] * u[0] + inv[i][1] * u[1] + inv[i][2] * u[2]);
    }
    k = -(u[0] * vt[0] + u[1] * vt[1] + u[2] * vt[2]) - coef[9];
    if (!(k > 0.0f) || !magcal_isfinite_f(k)) {
        return MAGCAL_ERR_NOT_ELLIPSOID;
    }
    for (i = 0u; i < 3u; ++i) {
        for (j = 0u; j < 3u; ++j) {
            qn[i][j] = aq[i][j] / k;
        }
    }
    /* Sylvester: leading minors of A_q/k positive. */
    detq = magcal_det3(qn);
    if (!(qn[0][0] > 0.0f) || !(qn[0][0] * qn[1][1] - qn[0][1] * qn[1][0] > 0.0f) ||
        !(detq > 0.0f)) {
        return MAGCAL_ERR_NOT_ELLIPSOID;
    }
    st = sqrt_spd3(qn, method, gn);
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
            cal->g[i][j] = gn[i][j] * (f / s);
        }
    }
    cal->v.x = mu[0] + s * vt[0];
    cal->v.y = mu[1] + s * vt[1];
    cal->v.z = mu[2] + s * vt[2];
    cal->field = f;
    return MAGCAL_OK;
}

static magcal_status_t solve_quadric9(const quad_acc_t *acc, float tau, float coef[NQ],
                                      float *min_pivot)
{
    float a[9u * 9u];
    float b[9];
    size_t i;
    size_t j;
    magcal_status_t st;
    for (i = 0u; i < 9u; ++i) {
        for (j = 0u; j < 9u; ++j) {
            a[i * 9u + j] = acc_at(acc, i, j);
        }
        b[i] = acc_at(acc, i, 9u); /* D^T 1: the column of the constant term */
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
static magcal_status_t solve_quadric10(const quad_acc_t *acc, float tau, float coef[NQ],
                                       float *min_pivot)
{
    float a[NQ * NQ];
    float v[NQ];
    float trace = 0.0f;
    float shift;
    size_t i;
    size_t j;
    size_t it;
    size_t attempt;
    magcal_status_t st = MAGCAL_ERR_ILL_CONDITIONED;

    for (i = 0u; i < NQ; ++i) {
        trace += acc_at(acc, i, i);
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
                    a[i * NQ + j] = acc_at(acc, i, j);
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
    /* Conditioning hint from the unshifted 9x9 block, the same test as the 9-parameter model. */
    {
        float b9[9];
        float a9[81];
        for (i = 0u; i < 9u; ++i) {
            for (j = 0u; j < 9u; ++j) {
                a9[i * 9u + j] = acc_at(acc, i, j);
            }
            b9[i] = 0.0f;
        }
        st = magcal_ldlt_solve(a9, b9, 9u, tau, min_pivot);
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
static magcal_status_t solve_sphere(const quad_acc_t *acc, const float mu[3], float s,
                                    float field_cfg, float tau, magcal_ellipsoid_cal_t *cal,
                                    float *min_pivot)
{
    float a[16];
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
            a[i * 4u + j] = acc_at(acc, lin[i], lin[j]) * fac[i] * fac[j];
        }
        b[i] =
            -(acc_at(acc, lin[i], 0u) + acc_at(acc, lin[i], 1u) + acc_at(acc, lin[i], 2u)) * fac[i];
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

static magcal_status_t fit_model(const quad_acc_t *acc, magcal_ellipsoid_model_t model,
                                 const float mu[3], float s, const magcal_ellipsoid_cfg_t *cfg,
                                 magcal_ellipsoid_cal_t *cal, float *min_pivot)
{
    float coef[NQ];
    magcal_status_t st;
    if (model == MAGCAL_ELLIPSOID_MODEL_SPHERE) {
        if (acc->count < MIN_SPHERE_POINTS) {
            return MAGCAL_ERR_TOO_FEW_POINTS;
        }
        return solve_sphere(acc, mu, s, cfg->field, cfg->pivot_tau, cal, min_pivot);
    }
    if (acc->count < MIN_QUADRIC_POINTS) {
        return MAGCAL_ERR_TOO_FEW_POINTS;
    }
    if (model == MAGCAL_ELLIPSOID_MODEL_QUADRIC10) {
        st = solve_quadric10(acc, cfg->pivot_tau, coef, min_pivot);
    } else {
        st = solve_quadric9(acc, cfg->pivot_tau, coef, min_pivot);
    }
    if (st != MAGCAL_OK) {
        return st;
    }
    return extract_quadric(coef, mu, s, cfg->field, cfg->sqrt_method, cal);
}

static int cell_of(float x, float y, float z, size_t *cell)
{
    float r = sqrtf(x * x + y * y + z * z);
    float az;
    float sz;
    size_t ia;
    size_t ie;
    if (!(r > 0.0f)) {
        return 0;
    }
    az = atan2f(y, x) + MAGCAL_PI_F; /* [0, 2pi] */
    sz = z / r + 1.0f;               /* [0, 2]: equal-area bands */
    ia = (size_t)(az * ((float)MAGCAL_ELLIPSOID_COV_AZ / (2.0f * MAGCAL_PI_F)));
    ie = (size_t)(sz * ((float)MAGCAL_ELLIPSOID_COV_EL / 2.0f));
    if (ia >= MAGCAL_ELLIPSOID_COV_AZ) {
        ia = MAGCAL_ELLIPSOID_COV_AZ - 1u;
    }
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

/* RMS of the residuals under `cal` of the samples kept by `gate`; their count and max |r|. */
static float residual_pass(const magcal_vec3_t *m, size_t n, const magcal_ellipsoid_cal_t *cal,
                           const quad_gate_t *gate, size_t *kept, float *max_abs)
{
    float sum = 0.0f;
    float comp = 0.0f;
    float mx = 0.0f;
    size_t k;
    size_t cnt = 0u;
    for (k = 0u; k < n; ++k) {
        float r;
        if (!gate_keeps(gate, &m[k])) {
            continue;
        }
        r = residual_of(cal, &m[k]);
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

static float alg_residual(const resid_src_t *src, const magcal_vec3_t *m)
{
    const float *b = src->theta;
    const float x = (m->x - src->mu[0]) * src->inv_s;
    const float y = (m->y - src->mu[1]) * src->inv_s;
    const float z = (m->z - src->mu[2]) * src->inv_s;
    return b[0] * x * x + b[1] * y * y + b[2] * z * z +
           2.0f * (b[3] * y * z + b[4] * x * z + b[5] * x * y + b[6] * x + b[7] * y + b[8] * z) - 1.0f;
}

static float abs_residual(const resid_src_t *src, const magcal_vec3_t *m)
{
    return fabsf((src->cal != NULL) ? residual_of(src->cal, m) : alg_residual(src, m));
}

/*
 * Median of |r| over the `kept` samples that `gate` keeps, without per-sample storage: the bin of
 * a 32-bin histogram of [lo, hi) that holds the median becomes the next [lo, hi), at most
 * MED_PASSES passes (stops once the bin is narrower than 0.1 % of its lower edge).
 */
static MAGCAL_NOINLINE float median_abs_residual(const magcal_vec3_t *m, size_t n, const resid_src_t *src,
                                 const quad_gate_t *gate, size_t kept, float max_abs)
{
    uint32_t cnt[MED_BINS];
    float lo = 0.0f;
    float hi = max_abs * 1.0001f + 1e-30f;
    size_t below = 0u;
    const size_t target = (kept + 1u) / 2u; /* rank (1-based) of the median */
    size_t pass;
    size_t k;
    for (pass = 0u; pass < MED_PASSES; ++pass) {
        const float width = (hi - lo) / (float)MED_BINS;
        size_t acc = below;
        size_t b;
        if (!(width > 0.0f)) {
            break;
        }
        (void)memset(cnt, 0, sizeof(cnt));
        for (k = 0u; k < n; ++k) {
            float a;
            if (!gate_keeps(gate, &m[k])) {
                continue;
            }
            a = abs_residual(src, &m[k]);
            if (a >= lo && a < hi) {
                b = (size_t)((a - lo) / width);
                cnt[(b < MED_BINS) ? b : (MED_BINS - 1u)]++;
            }
        }
        for (b = 0u; b < MED_BINS; ++b) {
            if (acc + cnt[b] >= target) {
                break;
            }
            acc += cnt[b];
        }
        if (b == MED_BINS) { /* float rounding at the edge: keep the current interval */
            break;
        }
        lo = lo + (float)b * width;
        hi = lo + width;
        below = acc;
        if (width <= 1e-3f * lo) {
            break;
        }
    }
    return 0.5f * (lo + hi);
}

/* Jacobian row of the linearised total-field model at one corrected sample (see centre_info). */
static size_t info_row(const float h[3], int sphere, float row[INFO_MAX_N])
{
    const float r = sqrtf(h[0] * h[0] + h[1] * h[1] + h[2] * h[2]);
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

/* Largest eigenvalue of a symmetric 3x3 (lower triangle used); NaN/Inf/failure give +Inf. */
static MAGCAL_NOINLINE float max_eig3(float c[3][3])
{
    float w[3];
    float e[3][3];
    float wmax;
    size_t i;
    size_t j;
    for (i = 0u; i < 3u; ++i) {
        for (j = 0u; j < i; ++j) {
            c[j][i] = c[i][j];
        }
    }
    if (magcal_jacobi_sym(&c[0][0], 3u, w, &e[0][0]) != MAGCAL_OK) {
        return INFINITY;
    }
    wmax = fmaxf(w[0], fmaxf(w[1], w[2]));
    return (magcal_isfinite_f(wmax) && wmax >= 0.0f) ? wmax : INFINITY;
}

/* sqrt(smallest / middle eigenvalue) of a symmetric 3x3 scatter (lower triangle used). */
static MAGCAL_NOINLINE float planarity3(float c[3][3])
{
    float w[3];
    float e[3][3];
    float lo;
    float mid;
    float hi;
    size_t i;
    size_t j;
    for (i = 0u; i < 3u; ++i) {
        for (j = 0u; j < i; ++j) {
            c[j][i] = c[i][j];
        }
    }
    if (magcal_jacobi_sym(&c[0][0], 3u, w, &e[0][0]) != MAGCAL_OK) {
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

/*
 * Observability of the calibration (issue 12, docs/calibration_3d.md "Trust gates"). Linearised
 * total-field model about the fit, r_i = |(I + E)(h_i - dc)| - F with h_i = G (m_i - V): the
 * Jacobian row is J_i = [-n_i, n_i^T E n_i terms] (n_i = h_i / |h_i|; E symmetric, 6 terms, carries
 * the scale and the soft iron) or [-n_i, -1] for the sphere (scale only). The covariance is the
 * heteroscedasticity-robust sandwich C = (J^T J)^-1 (sum r_i^2 J_i J_i^T) (J^T J)^-1, so noise that
 * G amplifies along one axis (strong soft iron) counts where it acts. Pass 1 accumulates J^T J
 * (packed, Kahan, in `acc`) and the scatter of the directions n_i; np solves give (J^T J)^-1 in
 * `inv`; pass 2 sums r_i^2 (J_i . inv_k)(J_i . inv_l) for the offset block and the shape diagonal.
 * Outputs, relative to F: worst 1-sigma offset error (largest eigenvalue of the 3x3 block, through
 * G: output units) and worst soft-iron term; +Inf when J^T J is singular (every n_i on one cone).
 * `dir_planarity`: planarity of the corrected directions (~0 for rotation about one axis).
 */
static MAGCAL_NOINLINE void centre_info(const magcal_vec3_t *m, size_t n, const magcal_ellipsoid_cal_t *cal,
                        const quad_gate_t *gate, int sphere, quad_acc_t *acc,
                        trust_diag_t *res)
{
    const size_t np = (sphere != 0) ? 4u : INFO_MAX_N;
    float a[INFO_MAX_N * INFO_MAX_N];
    float inv[INFO_MAX_N][INFO_MAX_N];
    float cc[3][3];
    float sn[3] = {0.0f, 0.0f, 0.0f};
    float sd[INFO_MAX_N];
    float emax = 0.0f;
    size_t cnt = 0u;
    size_t i;
    size_t j;
    size_t k;
    res->centre_std_rel = INFINITY;
    res->shape_std = (sphere != 0) ? 0.0f : INFINITY;
    res->planarity = 0.0f;
    (void)memset(acc, 0, sizeof(*acc));
    for (k = 0u; k < n; ++k) {
        float h[3];
        float row[INFO_MAX_N];
        if (!gate_keeps(gate, &m[k])) {
            continue;
        }
        correct3(cal, &m[k], h);
        if (info_row(h, sphere, row) == 0u) {
            continue;
        }
        for (i = 0u; i < np; ++i) {
            for (j = 0u; j <= i; ++j) {
                size_t p = pidx(i, j);
                magcal_kahan_add(&acc->sum[p], &acc->comp[p], row[i] * row[j]);
            }
        }
        for (i = 0u; i < 3u; ++i) {
            sn[i] += row[i];
        }
        cnt++;
    }
    if (cnt < np) {
        return;
    }
    /* planarity of the directions: scatter of n about its mean, from the n n^T block */
    for (i = 0u; i < 3u; ++i) {
        for (j = 0u; j <= i; ++j) {
            cc[i][j] = acc_at(acc, i, j) / (float)cnt - (sn[i] / (float)cnt) * (sn[j] / (float)cnt);
        }
    }
    res->planarity = planarity3(cc);
    for (k = 0u; k < np; ++k) {
        float b[INFO_MAX_N];
        for (i = 0u; i < np; ++i) {
            for (j = 0u; j < np; ++j) {
                a[i * np + j] = acc_at(acc, i, j);
            }
            b[i] = (i == k) ? 1.0f : 0.0f;
        }
        if (magcal_ldlt_solve(a, b, np, 0.0f, NULL) != MAGCAL_OK) {
            return;
        }
        for (i = 0u; i < np; ++i) {
            inv[k][i] = b[i];
        }
    }
    /* pass 2: sandwich, offset block (6 sums) and shape diagonal (np - 3 sums), no Kahan needed
     * for a 1-significant-digit gate */
    (void)memset(cc, 0, sizeof(cc));
    (void)memset(sd, 0, sizeof(sd));
    for (k = 0u; k < n; ++k) {
        float h[3];
        float row[INFO_MAX_N];
        float pr[INFO_MAX_N];
        float r2;
        if (!gate_keeps(gate, &m[k])) {
            continue;
        }
        correct3(cal, &m[k], h);
        if (info_row(h, sphere, row) == 0u) {
            continue;
        }
        r2 = sqrtf(h[0] * h[0] + h[1] * h[1] + h[2] * h[2]) - cal->field;
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
    res->centre_std_rel = sqrtf(max_eig3(cc)) / cal->field;
    if (sphere == 0) {
        for (i = 3u; i < np; ++i) {
            if (!(sd[i] <= emax)) { /* NaN propagates as unobservable */
                emax = sd[i];
            }
        }
        res->shape_std = magcal_isfinite_f(emax) ? (sqrtf(emax) / cal->field) : INFINITY;
    }
}

/*
 * Centre-free, model-free noise scale: the RMS algebraic residual of the 9-parameter quadric
 * (d = -1) of ALL samples in normalised coordinates, from the moments alone:
 * sum (r.theta - 1)^2 = theta^T A theta - 2 theta^T b + N. On a shell of radius ~1 a geometric
 * error delta gives ~2 delta, so motion SNR = 2 / rms: ~2.5 for noise around one point (any model
 * of it), the radius / noise for a rotation (any soft iron, any quadric). 0 when not solvable.
 */
static MAGCAL_NOINLINE float algebraic_motion_snr(const magcal_vec3_t *m, size_t n, const float mu[3], float inv_s,
                                  const quad_acc_t *acc)
{
    float a[9u * 9u];
    float b[9];
    float mx = 0.0f;
    float med;
    const quad_gate_t all = {NULL, 0.0f};
    resid_src_t src;
    size_t i;
    size_t j;
    size_t k;
    for (i = 0u; i < 9u; ++i) {
        for (j = 0u; j < 9u; ++j) {
            a[i * 9u + j] = acc_at(acc, i, j);
        }
        b[i] = acc_at(acc, i, 9u);
    }
    if (magcal_ldlt_solve(a, b, 9u, 0.0f, NULL) != MAGCAL_OK) {
        return INFINITY; /* singular: a degenerate quadric fits exactly, this is not noise */
    }
    src.cal = NULL;
    src.theta = b;
    src.mu = mu;
    src.inv_s = inv_s;
    for (k = 0u; k < n; ++k) {
        mx = fmaxf(mx, fabsf(alg_residual(&src, &m[k])));
    }
    /* robust (median) scale: outliers far off the shell must not make a rotation look like noise */
    med = MAD_TO_SIGMA * median_abs_residual(m, n, &src, &all, n, mx);
    if (!(med > 0.0f)) {
        return INFINITY; /* exact quadric */
    }
    return 2.0f / med;
}

/* sqrt(smallest / middle eigenvalue) of the samples' scatter (packed xx, yx, yy, zx, zy, zz). */
static MAGCAL_NOINLINE float planarity_of(const float sc[6])
{
    float c[3][3];
    c[0][0] = sc[0];
    c[1][0] = sc[1];
    c[1][1] = sc[2];
    c[2][0] = sc[3];
    c[2][1] = sc[4];
    c[2][2] = sc[5];
    return planarity3(c);
}

/* Cube root of det G (> 0 for both square roots): the mean gain, raw -> output units. */
static float mean_gain(const magcal_ellipsoid_cal_t *cal)
{
    float g[3][3];
    (void)memcpy(g, cal->g, sizeof(g));
    return cbrtf(fabsf(magcal_det3(g)));
}

/* What the motion test needs: the samples, their RMS spread about the mean (raw units), the
 * algebraic-quadric SNR and the provisional sphere (NULL when its fit failed). */
typedef struct {
    const magcal_vec3_t *m;
    size_t n;
    float s;
    float snr_alg;
    const magcal_ellipsoid_cal_t *sphere;
} motion_ctx_t;

/*
 * Motion SNR: the largest of `snr_model` (the final fit's), the algebraic quadric's and, only when
 * both are below `limit` (about to say NO_MOTION), the sphere's with a robust (median) scale. Each
 * can be fooled alone: a far burst drags the least-squares quadric (and any model) but not a
 * median-scaled sphere; strong soft iron spoils the sphere but not the quadric. Noise around one
 * point fools none of them (all ~2.5).
 */
static MAGCAL_NOINLINE float motion_snr(const motion_ctx_t *mc, float snr_model, float limit)
{
    float snr = fmaxf(snr_model, mc->snr_alg);
    if (snr < limit && mc->sphere != NULL) {
        const quad_gate_t all = {NULL, 0.0f};
        resid_src_t src = {NULL, NULL, NULL, 0.0f};
        float mx;
        size_t kept;
        float med;
        src.cal = mc->sphere;
        (void)residual_pass(mc->m, mc->n, mc->sphere, &all, &kept, &mx);
        med = MAD_TO_SIGMA * median_abs_residual(mc->m, mc->n, &src, &all, kept, mx) /
              mc->sphere->g[0][0];
        snr = fmaxf(snr, (med > 0.0f) ? (mc->s / med) : INFINITY);
    }
    return snr;
}

/*
 * A failed fit of data that never moved, or that rotate about one axis only, gets the status that
 * says so (the user must move the sensor differently, not retry with the same motion).
 */
static MAGCAL_NOINLINE magcal_status_t explain_failure(magcal_status_t st, const motion_ctx_t *mc, float planarity,
                                       const magcal_ellipsoid_cfg_t *cfg)
{
    if (st == MAGCAL_ERR_NULL || st == MAGCAL_ERR_ARG || st == MAGCAL_ERR_NONFINITE ||
        st == MAGCAL_ERR_DEGENERATE) {
        return st;
    }
    if (cfg->min_motion_snr > 0.0f &&
        motion_snr(mc, 0.0f, cfg->min_motion_snr) < cfg->min_motion_snr) {
        return MAGCAL_ERR_NO_MOTION;
    }
    if ((cfg->max_centre_std_rel > 0.0f || cfg->max_shape_std > 0.0f) && planarity < PLANAR_MAX) {
        return MAGCAL_ERR_SINGLE_AXIS;
    }
    return st;
}

/*
 * Trust gates on a finished fit (issue 12, docs/calibration_3d.md "Trust gates"), in this order:
 * no motion; one rotation axis; residual; observability (ill-conditioned); field magnitude.
 * Writes the diagnostics into dg.
 */
static MAGCAL_NOINLINE magcal_status_t trust_gates(const magcal_vec3_t *m, size_t n,
                                                   const magcal_ellipsoid_cfg_t *cfg,
                                                   const magcal_ellipsoid_cal_t *cal, float rms,
                                                   magcal_ellipsoid_model_t model, const quad_gate_t *gate,
                                                   const motion_ctx_t *mc, float raw_planarity,
                                                   quad_acc_t *scratch, trust_diag_t *dg)
{
    const int sphere = (model == MAGCAL_ELLIPSOID_MODEL_SPHERE) ? 1 : 0;
    const float gmean = mean_gain(cal);
    const float f = cal->field;
    float lim;
    int observable;
    if (!(gmean > 0.0f) || !magcal_isfinite_f(gmean)) {
        return MAGCAL_ERR_NOT_ELLIPSOID;
    }
    dg->field_raw = f / gmean;
    /* motion: spread against the best noise scale (the fitted model's residual, raw units, after
     * outlier rejection; the algebraic quadric of all samples; the robust sphere) */
    dg->motion_snr = motion_snr(mc, (rms > 0.0f) ? (mc->s * gmean / rms) : INFINITY, cfg->min_motion_snr);
    centre_info(m, n, cal, gate, sphere, scratch, dg);
    if (cfg->min_motion_snr > 0.0f && dg->motion_snr < cfg->min_motion_snr) {
        return MAGCAL_ERR_NO_MOTION;
    }
    observable = !((cfg->max_centre_std_rel > 0.0f && !(dg->centre_std_rel <= cfg->max_centre_std_rel)) ||
                   (cfg->max_shape_std > 0.0f && !(dg->shape_std <= cfg->max_shape_std)));
    lim = (sphere != 0) ? cfg->max_residual_rel_sphere : cfg->max_residual_rel;
    /* one axis: the corrected directions lie on a cone; or the raw samples are planar and the
     * quadric does not even fit them (a G made up along the unseen axis spoils the corrected test;
     * not for the sphere: a sphere that misfits strong soft iron is a residual failure) */
    if (observable == 0 &&
        (dg->planarity < PLANAR_MAX ||
         (sphere == 0 && raw_planarity < PLANAR_MAX && lim > 0.0f && !(rms <= lim * f)))) {
        return MAGCAL_ERR_SINGLE_AXIS;
    }
    if (lim > 0.0f && !(rms <= lim * f)) {
        return MAGCAL_ERR_RESIDUAL;
    }
    if (observable == 0) {
        return MAGCAL_ERR_ILL_CONDITIONED;
    }
    if (cfg->field_expected > 0.0f && !(dg->field_raw >= cfg->field_band_lo * cfg->field_expected &&
                                        dg->field_raw <= cfg->field_band_hi * cfg->field_expected)) {
        return MAGCAL_ERR_FIELD_MAGNITUDE;
    }
    return MAGCAL_OK;
}

magcal_status_t magcal_ellipsoid_fit(const magcal_vec3_t *m, size_t n,
                                     const magcal_ellipsoid_cfg_t *cfg,
                                     magcal_ellipsoid_result_t *out)
{
    float mu[3] = {0.0f, 0.0f, 0.0f};
    float comp[3] = {0.0f, 0.0f, 0.0f};
    float *sc;
    float *scc;
    float s;
    float inv_s;
    float cov_centre[3];
    float coverage;
    float min_pivot = 0.0f;
    motion_ctx_t mc;
    float planarity;
    size_t k;
    size_t iter;
    size_t kept = 0u;
    size_t prev_rejected = 0u;
    magcal_ellipsoid_model_t model;
    magcal_ellipsoid_cal_t cal;
    magcal_ellipsoid_cal_t gate_cal;
    magcal_ellipsoid_cal_t sphere_cal;
    trust_diag_t dg;
    quad_acc_t acc;
    quad_gate_t gate = {NULL, 0.0f};
    magcal_status_t st;
    float rms;
    float rmax;

    if (m == NULL || cfg == NULL || out == NULL) {
        return MAGCAL_ERR_NULL;
    }
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
    /* Pass 2: scatter about the mean (packed xx, yx, yy, zx, zy, zz, in the accumulator's storage,
     * which pass 3 clears); its trace gives the scale. */
    (void)memset(&acc, 0, sizeof(acc));
    sc = acc.sum;
    scc = acc.comp;
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
    inv_s = 1.0f / s;
    planarity = planarity_of(sc);

    /* Pass 3: the normal matrix of every sample; sphere fit gives the provisional centre, the
     * quadric's algebraic residual a noise scale that needs neither centre nor model. */
    accumulate(m, n, mu, inv_s, &gate, &acc);
    model = cfg->model;
    cov_centre[0] = mu[0];
    cov_centre[1] = mu[1];
    cov_centre[2] = mu[2];
    st = solve_sphere(&acc, mu, s, cfg->field, cfg->pivot_tau, &sphere_cal, &min_pivot);
    if (st == MAGCAL_OK) {
        cov_centre[0] = sphere_cal.v.x;
        cov_centre[1] = sphere_cal.v.y;
        cov_centre[2] = sphere_cal.v.z;
    }
    mc.m = m;
    mc.n = n;
    mc.s = s;
    mc.snr_alg = algebraic_motion_snr(m, n, mu, inv_s, &acc);
    mc.sphere = (st == MAGCAL_OK) ? &sphere_cal : NULL;
    coverage = coverage_of(m, n, cov_centre, 1e-6f * s);
    if (model == MAGCAL_ELLIPSOID_MODEL_AUTO) {
        if (coverage < cfg->min_coverage_sphere) {
            return explain_failure(MAGCAL_ERR_COVERAGE, &mc, planarity, cfg);
        }
        model = (coverage >= cfg->min_coverage_full && n >= MIN_QUADRIC_POINTS)
                    ? MAGCAL_ELLIPSOID_MODEL_QUADRIC9
                    : MAGCAL_ELLIPSOID_MODEL_SPHERE;
    }
    st = fit_model(&acc, model, mu, s, cfg, &cal, &min_pivot);
    if (st != MAGCAL_OK) {
        return explain_failure(st, &mc, planarity, cfg);
    }

    /* Outlier rejection: robust residual gate + refit (no per-sample storage; the array is read
     * again). The scale is 1.4826 x median |r| of the kept samples, not their RMS: a dense burst
     * pulls the first fit towards itself and inflates the RMS enough to hide (issue 12). */
    for (iter = 0u; iter < cfg->max_refits && cfg->outlier_k > 0.0f; ++iter) {
        size_t rejected;
        size_t kept_new;
        quad_gate_t next;
        resid_src_t src = {NULL, NULL, NULL, 0.0f};
        (void)residual_pass(m, n, &cal, &gate, &kept, &rmax);
        next.cal = &cal;
        src.cal = &cal;
        next.thr = cfg->outlier_k * MAD_TO_SIGMA * median_abs_residual(m, n, &src, &gate, kept, rmax);
        if (next.thr < cfg->outlier_floor_rel * cal.field) {
            next.thr = cfg->outlier_floor_rel * cal.field;
        }
        (void)residual_pass(m, n, &cal, &next, &kept_new, NULL);
        rejected = n - kept_new;
        if (rejected == prev_rejected) {
            break;
        }
        if ((float)rejected > cfg->max_reject_frac * (float)n) {
            return explain_failure(MAGCAL_ERR_TOO_MANY_OUTLIERS, &mc, planarity, cfg);
        }
        gate_cal = cal;
        gate.cal = &gate_cal;
        gate.thr = next.thr;
        accumulate(m, n, mu, inv_s, &gate, &acc);
        st = fit_model(&acc, model, mu, s, cfg, &cal, &min_pivot);
        if (st != MAGCAL_OK) {
            return explain_failure(st, &mc, planarity, cfg);
        }
        prev_rejected = rejected;
    }
    rms = residual_pass(m, n, &cal, &gate, &kept, NULL);
    if (kept <
        ((model == MAGCAL_ELLIPSOID_MODEL_SPHERE) ? MIN_SPHERE_POINTS : MIN_QUADRIC_POINTS)) {
        return MAGCAL_ERR_TOO_FEW_POINTS;
    }
    st = trust_gates(m, n, cfg, &cal, rms, model, &gate, &mc, planarity, &acc, &dg);
    if (st != MAGCAL_OK) {
        return st;
    }
    out->cal = cal;
    out->residual_rms = rms;
    out->coverage = coverage;
    out->min_pivot = min_pivot;
    out->n_used = kept;
    out->n_rejected = n - kept;
    out->model = model;
    /* the final pass's gate, for magcal_ellipsoid_outliers (thr 0: no gate) */
    out->gate_cal = (gate.cal != NULL) ? gate_cal : cal;
    out->gate_thr = (gate.cal != NULL) ? gate.thr : 0.0f;
    out->motion_snr = dg.motion_snr;
    out->centre_std_rel = dg.centre_std_rel;
    out->shape_std = dg.shape_std;
    out->planarity = dg.planarity;
    out->field_raw = dg.field_raw;
    return MAGCAL_OK;
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
        if (gate_keeps(&gate, &m[k]) != 0) {
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
    correct3(cal, m, r);
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
