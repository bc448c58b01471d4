/* Adaptive heading-error models (algorithms.md 5.2 polynomial, 5.3 Fourier). */
#include <math.h>
#include <string.h>

#include "magcal/errmodel.h"
#include "magcal_internal.h"

#if MAGCAL_CFG_ENABLE_PAPER /* whole file: config.h feature switch */

#define EM_MAXC MAGCAL_ERRMODEL_MAX_COEF

/* cppcheck-suppress misra-c2012-2.3 ; deviation D4: a static assert is an unused typedef */
MAGCAL_STATIC_ASSERT(MAGCAL_ERRMODEL_MAX_POLY_ORDER + 1u <= MAGCAL_LDLT_MAX_N,
                     errmodel_poly_fits_solver);
/* cppcheck-suppress misra-c2012-2.3 ; deviation D4: a static assert is an unused typedef */
MAGCAL_STATIC_ASSERT(2u * MAGCAL_ERRMODEL_MAX_FOURIER_ORDER + 1u <= MAGCAL_LDLT_MAX_N,
                     errmodel_fourier_fits_solver);
/* cppcheck-suppress misra-c2012-2.3 ; deviation D4: a static assert is an unused typedef */
MAGCAL_STATIC_ASSERT(MAGCAL_ERRMODEL_MAX_POLY_ORDER + 1u <= EM_MAXC, errmodel_coef_storage);

static size_t em_ncoef(magcal_errmodel_kind_t kind, size_t order)
{
    return (kind == MAGCAL_ERRMODEL_POLY) ? order + 1u : 2u * order + 1u;
}

static size_t em_max_order(magcal_errmodel_kind_t kind)
{
    return (kind == MAGCAL_ERRMODEL_POLY) ? (size_t)MAGCAL_ERRMODEL_MAX_POLY_ORDER
                                          : (size_t)MAGCAL_ERRMODEL_MAX_FOURIER_ORDER;
}

/*
 * Basis at psi (degrees, wrapped to [0, 360)).
 * poly: T_0..T_N at t = psi/180 - 1 (three-term recurrence T_{k+1} = 2 t T_k - T_{k-1});
 * Fourier: 1, cos psi, sin psi, cos 2psi, sin 2psi, ... by the angle-addition recurrence
 * (error grows about linearly with k; < 1e-6 for k <= 5).
 */
static void em_basis(magcal_errmodel_kind_t kind, size_t order, float psi_deg, float *g)
{
    float p = magcal_wrap360_deg(psi_deg);
    size_t k;
    g[0] = 1.0f;
    if (kind == MAGCAL_ERRMODEL_POLY) {
        float t = p / 180.0f - 1.0f;
        if (order >= 1u) {
            g[1] = t;
        }
        for (k = 2u; k <= order; ++k) {
            g[k] = 2.0f * t * g[k - 1u] - g[k - 2u];
        }
    } else {
        float r = p * MAGCAL_RAD_PER_DEG_F;
        float c1 = cosf(r);
        float s1 = sinf(r);
        float ck = 1.0f;
        float sk = 0.0f;
        for (k = 1u; k <= order; ++k) {
            float cn = ck * c1 - sk * s1;
            float sn = sk * c1 + ck * s1;
            ck = cn;
            sk = sn;
            g[2u * k - 1u] = ck;
            g[2u * k] = sk;
        }
    }
}

static float em_eval(magcal_errmodel_kind_t kind, size_t order, const float *coef, float psi_deg)
{
    float g[EM_MAXC];
    float d = 0.0f;
    size_t n = em_ncoef(kind, order);
    size_t i;
    em_basis(kind, order, psi_deg, g);
    for (i = 0u; i < n; ++i) {
        d += coef[i] * g[i];
    }
    return d;
}

magcal_status_t magcal_errmodel_fit(const magcal_errmodel_cfg_t *cfg, const float *psi_c_deg,
                                    const float *psi_ref_deg, size_t m, void *work,
                                    size_t work_len, magcal_errmodel_t *model,
                                    magcal_errmodel_stats_t *stats)
{
    /* the normal matrix (n x n at stride n, lower triangle) and its right-hand side, which the
     * solver turns into the coefficients, in the caller's workspace (issue 14: not on the stack) */
    float *ata;
    float *atb;
    float g[EM_MAXC];
    size_t cap;
    size_t order;
    size_t k;
    size_t i;
    size_t j;
    magcal_errmodel_stats_t last;

    if (cfg == NULL || psi_c_deg == NULL || psi_ref_deg == NULL || work == NULL || model == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (magcal_misalign(work, sizeof(float)) != 0u) {
        return MAGCAL_ERR_ALIGNMENT;
    }
    if (work_len < MAGCAL_ERRMODEL_WORKSPACE_LEN) {
        return MAGCAL_ERR_WORKSPACE;
    }
    ata = (float *)work;
    atb = &ata[(size_t)EM_MAXC * EM_MAXC];
    if ((cfg->kind != MAGCAL_ERRMODEL_POLY && cfg->kind != MAGCAL_ERRMODEL_FOURIER) ||
        !(cfg->threshold_deg > 0.0f) || !magcal_isfinite_f(cfg->threshold_deg) ||
        cfg->max_order < 1u || (size_t)cfg->max_order > em_max_order(cfg->kind) ||
        !(cfg->pivot_tau > 0.0f && cfg->pivot_tau < 1.0f)) {
        return MAGCAL_ERR_ARG;
    }
    if (m < em_ncoef(cfg->kind, 1u)) {
        return MAGCAL_ERR_TOO_FEW_POINTS;
    }
    for (k = 0u; k < m; ++k) {
        if (!magcal_isfinite_f(psi_c_deg[k]) || !magcal_isfinite_f(psi_ref_deg[k])) {
            return MAGCAL_ERR_NONFINITE;
        }
    }
    /* Orders the data allow: N <= M - 1 (poly), K <= (M - 1)/2 (Fourier). */
    cap = (cfg->kind == MAGCAL_ERRMODEL_POLY) ? m - 1u : (m - 1u) / 2u;
    if (cap > (size_t)cfg->max_order) {
        cap = (size_t)cfg->max_order;
    }
    last.order = 0u;
    last.max_abs_deg = 0.0f;
    last.rms_deg = 0.0f;
    for (order = 1u; order <= cap; ++order) {
        size_t n = em_ncoef(cfg->kind, order);
        float maxr = 0.0f;
        float sse = 0.0f;
        magcal_status_t st;
        (void)memset(ata, 0, (size_t)EM_MAXC * EM_MAXC * sizeof(float));
        (void)memset(atb, 0, EM_MAXC * sizeof(float));
        for (k = 0u; k < m; ++k) {
            float delta = magcal_wrap180_deg(psi_ref_deg[k] - psi_c_deg[k]);
            em_basis(cfg->kind, order, psi_c_deg[k], g);
            for (i = 0u; i < n; ++i) {
                atb[i] += g[i] * delta;
                for (j = 0u; j <= i; ++j) {
                    ata[i * n + j] += g[i] * g[j];
                }
            }
        }
        st = magcal_ldlt_solve(ata, atb, n, cfg->pivot_tau, NULL);
        if (st == MAGCAL_ERR_ILL_CONDITIONED || st == MAGCAL_ERR_DEGENERATE) {
            /* order 1 singular: the headings are not spread; higher: the data support no more */
            if (order == 1u) {
                return MAGCAL_ERR_SPREAD;
            }
            break;
        }
        if (st != MAGCAL_OK) {
            return st;
        }
        for (k = 0u; k < m; ++k) {
            float r = magcal_wrap180_deg(psi_ref_deg[k] - psi_c_deg[k]) -
                      em_eval(cfg->kind, order, atb, psi_c_deg[k]);
            sse += r * r;
            maxr = fabsf(r) > maxr ? fabsf(r) : maxr;
        }
        last.order = (uint8_t)order;
        last.max_abs_deg = maxr;
        last.rms_deg = sqrtf(sse / (float)m);
        if (maxr < cfg->threshold_deg) {
            model->kind = cfg->kind;
            model->order = (uint8_t)order;
            for (i = 0u; i < EM_MAXC; ++i) {
                model->coef[i] = (i < n) ? atb[i] : 0.0f;
            }
            if (stats != NULL) {
                *stats = last;
            }
            return MAGCAL_OK;
        }
    }
    if (stats != NULL) {
        *stats = last;
    }
    return MAGCAL_ERR_THRESHOLD;
}

magcal_status_t magcal_errmodel_eval(const magcal_errmodel_t *model, float psi_c_deg,
                                     float *delta_deg)
{
    size_t n;
    size_t i;
    if (model == NULL || delta_deg == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if ((model->kind != MAGCAL_ERRMODEL_POLY && model->kind != MAGCAL_ERRMODEL_FOURIER) ||
        (size_t)model->order > em_max_order(model->kind)) {
        return MAGCAL_ERR_ARG;
    }
    if (!magcal_isfinite_f(psi_c_deg)) {
        return MAGCAL_ERR_NONFINITE;
    }
    n = em_ncoef(model->kind, (size_t)model->order);
    for (i = 0u; i < n; ++i) {
        if (!magcal_isfinite_f(model->coef[i])) {
            return MAGCAL_ERR_NONFINITE;
        }
    }
    *delta_deg = em_eval(model->kind, (size_t)model->order, model->coef, psi_c_deg);
    return MAGCAL_OK;
}

magcal_status_t magcal_errmodel_apply(const magcal_errmodel_t *model, float psi_c_deg,
                                      float *psi_deg)
{
    float d = 0.0f;
    magcal_status_t st;
    if (psi_deg == NULL) {
        return MAGCAL_ERR_NULL;
    }
    st = magcal_errmodel_eval(model, psi_c_deg, &d);
    if (st != MAGCAL_OK) {
        return st;
    }
    *psi_deg = magcal_wrap360_deg(psi_c_deg + d);
    return MAGCAL_OK;
}

/* ------------------------------------------------------------------------------------------- */
/* The patent's power series in radians (error = measured - true) */

magcal_status_t magcal_errmodel_poly_to_power(const magcal_errmodel_t *model,
                                              magcal_errmodel_power_order_t order, float *coef_rad,
                                              size_t cap, size_t *n_coef)
{
    float tkm1[EM_MAXC]; /* T_{k-1}(phi/pi - 1) in powers of phi */
    float tk[EM_MAXC];   /* T_k */
    float acc[EM_MAXC];
    const float s = 1.0f / MAGCAL_PI_F;
    size_t nc;
    size_t k;
    size_t i;

    if (model == NULL || coef_rad == NULL || n_coef == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (model->kind != MAGCAL_ERRMODEL_POLY || model->order < 1u ||
        (size_t)model->order > (size_t)MAGCAL_ERRMODEL_MAX_POLY_ORDER ||
        (order != MAGCAL_ERRMODEL_POWER_ASCENDING && order != MAGCAL_ERRMODEL_POWER_DESCENDING)) {
        return MAGCAL_ERR_ARG;
    }
    nc = (size_t)model->order + 1u;
    if (cap < nc) {
        return MAGCAL_ERR_ARG;
    }
    for (i = 0u; i < nc; ++i) {
        if (!magcal_isfinite_f(model->coef[i])) {
            return MAGCAL_ERR_NONFINITE;
        }
    }
    (void)memset(tkm1, 0, sizeof tkm1);
    (void)memset(tk, 0, sizeof tk);
    (void)memset(acc, 0, sizeof acc);
    tkm1[0] = 1.0f; /* T_0 = 1 */
    tk[0] = -1.0f;  /* T_1 = s phi - 1 */
    tk[1] = s;
    acc[0] = model->coef[0] - model->coef[1];
    acc[1] = model->coef[1] * s;
    for (k = 1u; k + 1u < nc; ++k) {
        /* T_{k+1} = 2 (s phi - 1) T_k - T_{k-1}, degree k + 1 */
        float tn[EM_MAXC];
        for (i = 0u; i <= k + 1u; ++i) {
            float v = -2.0f * tk[i] - tkm1[i];
            if (i >= 1u) {
                v += 2.0f * s * tk[i - 1u];
            }
            tn[i] = v;
        }
        for (i = 0u; i <= k + 1u; ++i) {
            tkm1[i] = tk[i];
            tk[i] = tn[i];
            acc[i] += model->coef[k + 1u] * tn[i];
        }
    }
    for (i = 0u; i < nc; ++i) {
        float v =
            -acc[i] * MAGCAL_RAD_PER_DEG_F; /* degrees -> radians, reference - measured -> error */
        if (!magcal_isfinite_f(v)) {
            return MAGCAL_ERR_NONFINITE;
        }
        acc[i] = v;
    }
    for (i = 0u; i < nc; ++i) {
        coef_rad[i] = (order == MAGCAL_ERRMODEL_POWER_ASCENDING) ? acc[i] : acc[nc - 1u - i];
    }
    *n_coef = nc;
    return MAGCAL_OK;
}

magcal_status_t magcal_errmodel_poly_from_power(const float *coef_rad, size_t n_coef,
                                                magcal_errmodel_power_order_t order,
                                                magcal_errmodel_t *model)
{
    float c[EM_MAXC]; /* Chebyshev coefficients in t = phi/pi - 1 */
    size_t j;
    size_t k;
    size_t n;

    if (coef_rad == NULL || model == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (n_coef < 2u || n_coef > (size_t)MAGCAL_ERRMODEL_MAX_POLY_ORDER + 1u ||
        (order != MAGCAL_ERRMODEL_POWER_ASCENDING && order != MAGCAL_ERRMODEL_POWER_DESCENDING)) {
        return MAGCAL_ERR_ARG;
    }
    for (j = 0u; j < n_coef; ++j) {
        if (!magcal_isfinite_f(coef_rad[j])) {
            return MAGCAL_ERR_NONFINITE;
        }
    }
    /* Horner in the Chebyshev basis: c <- c (pi t + pi) + a_j, from a_N down to a_0, using
     * t T_0 = T_1 and t T_k = (T_{k+1} + T_{k-1})/2. After step m, c has degree m. */
    (void)memset(c, 0, sizeof c);
    n = n_coef - 1u; /* N */
    c[0] = (order == MAGCAL_ERRMODEL_POWER_ASCENDING) ? coef_rad[n] : coef_rad[0];
    for (j = 1u; j <= n; ++j) {
        float tc[EM_MAXC];
        size_t deg = j - 1u; /* degree of c before this step */
        float a = (order == MAGCAL_ERRMODEL_POWER_ASCENDING) ? coef_rad[n - j] : coef_rad[j];
        (void)memset(tc, 0, sizeof tc);
        for (k = 0u; k <= deg; ++k) {
            if (k == 0u) {
                tc[1] += c[0];
            } else {
                tc[k + 1u] += 0.5f * c[k];
                tc[k - 1u] += 0.5f * c[k];
            }
        }
        for (k = 0u; k <= deg + 1u; ++k) {
            c[k] = MAGCAL_PI_F * (tc[k] + c[k]);
        }
        c[0] += a;
    }
    for (k = 0u; k <= n; ++k) {
        float v = -c[k] / MAGCAL_RAD_PER_DEG_F; /* error (rad) -> deviation (deg) */
        if (!magcal_isfinite_f(v)) {
            return MAGCAL_ERR_NONFINITE;
        }
        c[k] = v;
    }
    model->kind = MAGCAL_ERRMODEL_POLY;
    model->order = (uint8_t)n;
    for (k = 0u; k < EM_MAXC; ++k) {
        model->coef[k] = (k <= n) ? c[k] : 0.0f;
    }
    return MAGCAL_OK;
}

#endif /* MAGCAL_CFG_ENABLE_PAPER */
