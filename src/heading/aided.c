/*
 * INS/GNSS-aided online 3-D calibration (algorithms.md 7.3-7.8).
 *
 * Unknowns theta (4x3) = [G^T; c~^T] with h/s = theta^T phi, phi = [x~; 1], x~ = (m - V0)/s.
 * State index p = 3 i + j (i: regressor 0..3, j: body axis 0..2).
 *
 * Vector residual (linear, algorithms.md 7.4): y = C_n^b B_ref / s = theta^T phi. Information
 * Lambda (x) I3 / sigma_v^2, Lambda = sum phi phi^T (4x4), right-hand side Z = sum phi y^T (4x3).
 *
 * Total-field residual (algorithms.md 7.3, 7.5, 7.6): r_F = |theta^T phi| - F/s, linearised at the
 * estimate in force when the epoch arrives (recursive Gauss-Newton / EKF in information form):
 * n = h/|h|, J_F = u^T with u_p = n_j phi_i, and J_F theta_i - r_F(theta_i) = F/s, so each epoch
 * adds u u^T / sigma_F^2 to the information and u F/s / sigma_F^2 to the right-hand side. The
 * direction n changes only to second order with an error of the estimate, so the linearisation of
 * early epochs costs little; the term enters once the calibrated gates are in use (an estimate that
 * predicts every heading), never from the raw prior.
 *
 * Solve: eigen-decompose Lambda/N (4x4 Jacobi), freeze directions e_k with too little excitation
 * at the prior theta0 (all three axes, both residuals: the total-field Jacobian u = n (x) phi also
 * lies in span{phi}), and solve for the coefficients a_kj of theta = theta0 + sum_k e_k a_k^T over
 * the kept directions from the reduced normal equations (<= 12 x 12, LDL^T):
 *   [w_v mu_k N delta + w_F (E^T (x) I) H_F (E (x) I)] a = (E^T (x) I)(w_v (Z - Lambda theta0) + w_F (b_F - H_F theta0)).
 * Vector-only (objective VECTOR, or no total-field epoch yet): the system is diagonal,
 *   theta = theta0 + sum_{k kept} e_k e_k^T (Z - Lambda theta0) / (N mu_k).
 * Finally G = theta[0..2]^T, V = V0 - s G^-1 c~.
 */
#include <math.h>
#include <string.h>

#include "magcal/aided.h"
#include "magcal_internal.h"

#if MAGCAL_CFG_ENABLE_AIDED /* whole file: config.h feature switch */

#define AIDED_MAGIC 0x41494433u /* "AID3" */
#define NPHI 4u
#define NPACK4 10u
#define NPAR 12u
#define NPACK12 78u
#define MIN_EPOCHS_LIMIT 8u
#define REF_RATIO 16.0f   /* allowed |B_ref| / s range: [1/16, 16] */
#define RAW_RANGE 1.0e4f  /* allowed |m - V0|_inf / |B_ref| (range of the normalised sums) */
/* The solve's scratch in the instance (aided.h): the reduced system (whose first 16 floats also
 * hold the Jacobi working copy of Lambda/N: dead before the system is built), its right-hand
 * side, the eigenvectors. */
#define SCR_SYS 0u
#define SCR_RHS ((size_t)NPAR * NPAR)
#define SCR_EV (SCR_RHS + NPAR)

/* cppcheck-suppress misra-c2012-2.3 ; deviation D4: a static assert is an unused typedef */
MAGCAL_STATIC_ASSERT(SCR_EV + (size_t)NPHI * NPHI <= (size_t)MAGCAL_AIDED_SCRATCH_LEN, aided_scratch_len);

/* Index of (i, j) in a packed lower triangle (row-major), any order. */
static size_t aided_pidx(size_t i, size_t j)
{
    return (i >= j) ? ((i * (i + 1u)) / 2u + j) : ((j * (j + 1u)) / 2u + i);
}

static int finite3(const magcal_vec3_t *v)
{
    return magcal_isfinite_f(v->x) && magcal_isfinite_f(v->y) && magcal_isfinite_f(v->z);
}

/* x = a^-1 b for a 3x3 by cofactors; returns 0 when |det| is tiny relative to the entries. */
static int solve3(float a[3][3], const float b[3], float x[3])
{
    float det = magcal_det3(a);
    float mag = 0.0f;
    float inv[3][3];
    size_t i;
    size_t j;
    for (i = 0u; i < 3u; ++i) {
        for (j = 0u; j < 3u; ++j) {
            float v = fabsf(a[i][j]);
            mag = (v > mag) ? v : mag;
        }
    }
    if (!(fabsf(det) > 1e-6f * mag * mag * mag) || !magcal_isfinite_f(det)) {
        return 0;
    }
    inv[0][0] = (a[1][1] * a[2][2] - a[1][2] * a[2][1]) / det;
    inv[0][1] = (a[0][2] * a[2][1] - a[0][1] * a[2][2]) / det;
    inv[0][2] = (a[0][1] * a[1][2] - a[0][2] * a[1][1]) / det;
    inv[1][0] = (a[1][2] * a[2][0] - a[1][0] * a[2][2]) / det;
    inv[1][1] = (a[0][0] * a[2][2] - a[0][2] * a[2][0]) / det;
    inv[1][2] = (a[0][2] * a[1][0] - a[0][0] * a[1][2]) / det;
    inv[2][0] = (a[1][0] * a[2][1] - a[1][1] * a[2][0]) / det;
    inv[2][1] = (a[0][1] * a[2][0] - a[0][0] * a[2][1]) / det;
    inv[2][2] = (a[0][0] * a[1][1] - a[0][1] * a[1][0]) / det;
    for (i = 0u; i < 3u; ++i) {
        x[i] = inv[i][0] * b[0] + inv[i][1] * b[1] + inv[i][2] * b[2];
    }
    return 1;
}

magcal_status_t magcal_aided_dcm(float roll_rad, float pitch_rad, float yaw_rad, float c[3][3])
{
    float cf;
    float sf;
    float ct;
    float st;
    float cp;
    float sp;
    if (c == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (!magcal_isfinite_f(roll_rad) || !magcal_isfinite_f(pitch_rad) ||
        !magcal_isfinite_f(yaw_rad)) {
        return MAGCAL_ERR_NONFINITE;
    }
    cf = cosf(roll_rad);
    sf = sinf(roll_rad);
    ct = cosf(pitch_rad);
    st = sinf(pitch_rad);
    cp = cosf(yaw_rad);
    sp = sinf(yaw_rad);
    /* C_b^ENU = R_z(-psi) R_x(theta) R_y(phi); NED rows = (N, E, -U) of ENU. */
    c[0][0] = -sp * cf + cp * st * sf; /* north */
    c[0][1] = cp * ct;
    c[0][2] = -sp * sf - cp * st * cf;
    c[1][0] = cp * cf + sp * st * sf; /* east */
    c[1][1] = sp * ct;
    c[1][2] = cp * sf - sp * st * cf;
    c[2][0] = ct * sf; /* down */
    c[2][1] = -st;
    c[2][2] = -ct * cf;
    return MAGCAL_OK;
}

magcal_status_t magcal_aided_init_checked(magcal_aided_t *inst, const magcal_aided_cfg_t *cfg,
                                          uint32_t config, size_t inst_size)
{
    size_t i;
    size_t j;
    float g0[3][3];
    if (magcal_config_check_fingerprint(config) != MAGCAL_OK || inst_size != sizeof *inst) {
        return MAGCAL_ERR_CONFIG_MISMATCH; /* caller's struct layout is not ours: write nothing */
    }
    if (inst == NULL || cfg == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (!(cfg->lambda >= 0.9f && cfg->lambda <= 1.0f) || !(cfg->max_dop > 0.0f) ||
        !(cfg->gate_raw_rel > 0.0f) || !(cfg->gate_field_rel > 0.0f) ||
        !(cfg->gate_vector_rel > 0.0f) || !(cfg->sigma_rel > 0.0f) || !(cfg->sigma_f_rel > 0.0f) ||
        !(cfg->max_weak_std > 0.0f) ||
        !(cfg->min_eig >= 0.0f && cfg->min_eig < 1.0f) || !(cfg->conv_dg > 0.0f) ||
        !(cfg->conv_dv_rel > 0.0f) || !(cfg->noise_rel >= 0.0f && cfg->noise_rel < 0.1f) ||
        !(cfg->still_field_rel >= 0.0f && cfg->still_field_rel < 1.0f) ||
        (cfg->still_epochs > 0u && !(cfg->still_field_rel > 0.0f))) {
        return MAGCAL_ERR_ARG;
    }
    if (!magcal_isfinite_f(cfg->max_dop) || !magcal_isfinite_f(cfg->gate_raw_rel) ||
        !magcal_isfinite_f(cfg->gate_field_rel) || !magcal_isfinite_f(cfg->gate_vector_rel) ||
        !magcal_isfinite_f(cfg->sigma_rel) || !magcal_isfinite_f(cfg->sigma_f_rel) ||
        !magcal_isfinite_f(cfg->max_weak_std) ||
        !magcal_isfinite_f(cfg->conv_dg) || !magcal_isfinite_f(cfg->conv_dv_rel)) {
        return MAGCAL_ERR_ARG;
    }
    if (cfg->objective != MAGCAL_AIDED_OBJ_COMBINED && cfg->objective != MAGCAL_AIDED_OBJ_VECTOR) {
        return MAGCAL_ERR_ARG;
    }
    if (cfg->min_epochs < MIN_EPOCHS_LIMIT || cfg->conv_window < 1u) {
        return MAGCAL_ERR_ARG;
    }
    if (!finite3(&cfg->prior.v)) {
        return MAGCAL_ERR_NONFINITE;
    }
    for (i = 0u; i < 3u; ++i) {
        for (j = 0u; j < 3u; ++j) {
            if (!magcal_isfinite_f(cfg->prior.g[i][j])) {
                return MAGCAL_ERR_NONFINITE;
            }
            g0[i][j] = cfg->prior.g[i][j];
        }
    }
    {
        float zero[3] = {0.0f, 0.0f, 0.0f};
        float x[3];
        if (!solve3(g0, zero, x)) {
            return MAGCAL_ERR_ARG;
        }
    }
    (void)memset(inst, 0, sizeof(*inst));
    inst->cfg = *cfg;
    inst->cal = cfg->prior;
    inst->min_eig = 0.0f;
    inst->weak_std = 0.0f;
    inst->magic = AIDED_MAGIC;
    return MAGCAL_OK;
}

/*
 * Weight of the total-field residual relative to the vector residual, w_F / w_v. Both residuals
 * carry the same magnetometer noise: the total-field residual is, to first order, the along-field
 * component of the vector residual (attitude errors rotate the vector residual across the field).
 * Summing both with 1/sigma^2 weights would count that noise twice, so the total-field weight is
 * the information the along-field direction has beyond the vector residual's:
 *   w_F = 1/sigma_F^2 - 1/sigma_v^2  (>= 0),
 * which makes the along-field weight exactly 1/sigma_F^2 and the cross-field weight 1/sigma_v^2,
 * the information of one vector measurement with covariance
 * sigma_F^2 n n^T + sigma_v^2 (I - n n^T).
 */
static float aided_wf(const magcal_aided_cfg_t *cfg)
{
    const float r = cfg->sigma_rel / cfg->sigma_f_rel;
    const float wf = r * r - 1.0f;
    return (wf > 0.0f) ? wf : 0.0f;
}

/* Total-field information per epoch at (p, q): H_F / N with the magnetometer noise removed
 * (E[phi phi^T] carries noise_rel^2 on the first three diagonal entries, algorithms.md 7.7). */
static float hf_at(const magcal_aided_t *inst, size_t p, size_t q, float inv_n)
{
    float v = inst->hf[aided_pidx(p, q)];
    if ((p / 3u) == (q / 3u) && (p / 3u) < 3u) {
        const float nr = inst->cfg.noise_rel;
        v -= nr * nr * inst->nn[aided_pidx(p % 3u, q % 3u)];
    }
    return v * inv_n;
}

/* In place: x[(k, j)] = sum_i E_ik x[(i, j)] for the 4 x 3 blocks x[3 i + j] at stride `stride`
 * (the (E^T (x) I3) rotation of one row or column of the 12 x 12 system into Lambda's eigenbasis). */
static void aided_rotate(const float *ev, float *x, size_t stride)
{
    float t[NPHI];
    size_t i;
    size_t j;
    size_t k;
    for (j = 0u; j < 3u; ++j) {
        for (i = 0u; i < NPHI; ++i) {
            t[i] = x[(3u * i + j) * stride];
        }
        for (k = 0u; k < NPHI; ++k) {
            float acc = 0.0f;
            for (i = 0u; i < NPHI; ++i) {
                acc += ev[i * NPHI + k] * t[i];
            }
            x[(3u * k + j) * stride] = acc;
        }
    }
}

/*
 * Combined vector + total-field step over the kept eigen-directions keep[0..nk-1] of Lambda/N
 * (module comment). resid = Z - Lambda theta0 (not divided by N); theta = theta0 on entry.
 * Returns 1 and writes theta on success, 0 when the reduced system is not positive definite
 * (the caller then takes the vector step). About 2.5 k multiply-adds plus a <= 12 x 12 LDL^T.
 * msys (12 x 12) and rhs (12): the instance's scratch (not on the stack: issue 14).
 */
static MAGCAL_NOINLINE int aided_combined(const magcal_aided_t *inst, const float *ev,
                                          const float mu[NPHI], const size_t keep[NPHI], size_t nk,
                                          float resid[NPHI][3], float theta[NPHI][3], float *msys,
                                          float *rhs)
{
    const float neff = inst->info[aided_pidx(3u, 3u)];
    const float inv_n = 1.0f / neff;
    const float wf = aided_wf(&inst->cfg); /* w_F / w_v */
    const size_t n = 3u * nk;
    size_t p;
    size_t q;
    size_t i;
    /* msys = H_F / N (noise-compensated), full symmetric */
    for (p = 0u; p < NPAR; ++p) {
        for (q = 0u; q <= p; ++q) {
            const float v = hf_at(inst, p, q, inv_n);
            msys[p * NPAR + q] = v;
            msys[q * NPAR + p] = v;
        }
    }
    /* right-hand side at theta0: (Z - Lambda theta0)/N + w (b_F - H_F theta0)/N */
    for (p = 0u; p < NPAR; ++p) {
        float acc = inst->bf[p] * inv_n;
        for (q = 0u; q < NPAR; ++q) {
            acc -= msys[p * NPAR + q] * theta[q / 3u][q % 3u];
        }
        rhs[p] = resid[p / 3u][p % 3u] * inv_n + wf * acc;
    }
    /* into Lambda's eigenbasis: rhs <- (E^T (x) I) rhs, msys <- (E^T (x) I) msys (E (x) I) */
    aided_rotate(ev, rhs, 1u);
    for (p = 0u; p < NPAR; ++p) {
        aided_rotate(ev, &msys[p], NPAR); /* column p */
    }
    for (p = 0u; p < NPAR; ++p) {
        aided_rotate(ev, &msys[p * NPAR], 1u); /* row p */
    }
    /* keep the observed directions, compacted in place to an n x n system (every target index
     * is <= its source index and targets are written in increasing order, so no source is
     * overwritten before it is read); the vector information is mu_k on the diagonal */
    for (p = 0u; p < n; ++p) {
        const size_t sp = 3u * keep[p / 3u] + p % 3u;
        for (q = 0u; q < n; ++q) {
            const size_t sq = 3u * keep[q / 3u] + q % 3u;
            msys[p * n + q] = wf * msys[sp * NPAR + sq] + ((p == q) ? mu[keep[p / 3u]] : 0.0f);
        }
        rhs[p] = rhs[sp];
    }
    if (magcal_ldlt_solve(msys, rhs, n, 1e-6f, NULL) != MAGCAL_OK) {
        return 0;
    }
    for (p = 0u; p < n; ++p) {
        const size_t kp = keep[p / 3u];
        for (i = 0u; i < NPHI; ++i) {
            theta[i][p % 3u] += ev[i * NPHI + kp] * rhs[p];
        }
    }
    return 1;
}

/* Lambda/N at (i, j) with the noise variance removed from the first three diagonal entries
 * (errors in variables, aided_solve). */
static float aided_lam(const magcal_aided_t *inst, size_t i, size_t j, float neff)
{
    float v = inst->info[aided_pidx(i, j)] / neff;
    if (i == j && i < 3u) {
        v -= inst->cfg.noise_rel * inst->cfg.noise_rel;
    }
    return v;
}

/* Solve for theta from the sums; updates cal, weak-direction diagnostics and the residual.
 * Its matrices live in inst->scratch (aided.h); its own frame is kept out of the update's. */
static MAGCAL_NOINLINE void aided_solve(magcal_aided_t *inst)
{
    const magcal_aided_cfg_t *cfg = &inst->cfg;
    float *lam = &inst->scratch[SCR_SYS]; /* 4 x 4 working copy, destroyed by the Jacobi sweeps */
    float *ev = &inst->scratch[SCR_EV]; /* eigenvectors, row-major 4 x 4: e_k = column k */
    float mu[NPHI];
    float resid[NPHI][3];
    float theta[NPHI][3];
    float g[3][3];
    float ct[3];
    float vv[3];
    float neff = inst->info[aided_pidx(3u, 3u)];
    float sigma;
    float rss;
    float fmean;
    size_t keep[NPHI];
    size_t nk = 0u;
    size_t i;
    size_t j;
    size_t k;
    size_t kmin = 0u;
    uint32_t nprior = 0u;

    if (!(neff > 0.0f)) {
        return;
    }
    /* Bias compensation: E[x~ x~^T] holds the noise variance on its diagonal; remove it so that a
     * weakly excited direction is not shrunk towards zero (errors in variables, aided_lam). */
    for (i = 0u; i < NPHI; ++i) {
        for (j = 0u; j < NPHI; ++j) {
            lam[i * NPHI + j] = aided_lam(inst, i, j, neff);
        }
    }
    /* prior in normalised coordinates: G0 rows, c~0 = G0 (V0 - V0)/s = 0 */
    for (j = 0u; j < 3u; ++j) {
        for (i = 0u; i < 3u; ++i) {
            theta[i][j] = cfg->prior.g[j][i];
        }
        theta[3][j] = 0.0f;
    }
    /* residual of the (compensated) vector normal equations at the prior: Z - Lambda theta0, taken
     * before the Jacobi sweeps destroy lam (so no copy of it is kept) */
    for (i = 0u; i < NPHI; ++i) {
        for (j = 0u; j < 3u; ++j) {
            float sacc = inst->cross[i * 3u + j];
            for (k = 0u; k < NPHI; ++k) {
                sacc -= neff * lam[i * NPHI + k] * theta[k][j];
            }
            resid[i][j] = sacc;
        }
    }
    if (magcal_jacobi_sym(lam, NPHI, mu, ev) != MAGCAL_OK) {
        return; /* keep the previous estimate */
    }
    sigma = cfg->sigma_rel;
    if (inst->cal.field > 0.0f && inst->resid_rms / inst->cal.field > sigma) {
        sigma = inst->resid_rms / inst->cal.field;
    }
    if (cfg->objective == MAGCAL_AIDED_OBJ_COMBINED && inst->n_tf > 0u) {
        /* predicted std with the total-field information too: along a direction e_k it adds
         * w_F sum n_j^2 (e_k^T phi)^2 for body axis j; take the least-informed axis, min_j of the
         * mean n_j^2 over the total-field epochs, times their share of all epochs */
        float nmin = inst->nn[0];
        nmin = (inst->nn[2] < nmin) ? inst->nn[2] : nmin;
        nmin = (inst->nn[5] < nmin) ? inst->nn[5] : nmin;
        sigma = sigma / sqrtf(1.0f + aided_wf(cfg) * nmin / neff);
    }
    /* observability: keep the directions with enough excitation, freeze the others at the prior */
    for (k = 0u; k < NPHI; ++k) {
        float std = (mu[k] > 0.0f) ? sigma / sqrtf(neff * mu[k]) : 1e30f;
        if (mu[k] < mu[kmin]) {
            kmin = k;
        }
        if (!(mu[k] >= cfg->min_eig) || !(mu[k] > 0.0f) || !(std <= cfg->max_weak_std)) {
            nprior++;
        } else {
            keep[nk] = k;
            nk++;
        }
    }
    if (cfg->objective != MAGCAL_AIDED_OBJ_COMBINED || inst->n_tf == 0u || nk == 0u ||
        !(aided_wf(cfg) > 0.0f) ||
        aided_combined(inst, ev, mu, keep, nk, resid, theta, &inst->scratch[SCR_SYS],
                       &inst->scratch[SCR_RHS]) == 0) {
        /* vector residual only: diagonal in the eigenbasis */
        for (k = 0u; k < nk; ++k) {
            const size_t kk = keep[k];
            for (j = 0u; j < 3u; ++j) {
                float proj = 0.0f;
                for (i = 0u; i < NPHI; ++i) {
                    proj += ev[i * NPHI + kk] * resid[i][j];
                }
                proj /= neff * mu[kk];
                for (i = 0u; i < NPHI; ++i) {
                    theta[i][j] += ev[i * NPHI + kk] * proj;
                }
            }
        }
    }
    inst->min_eig = mu[kmin];
    inst->weak_std = (mu[kmin] > 0.0f) ? sigma / sqrtf(neff * mu[kmin]) : 1e30f;
    for (i = 0u; i < NPHI; ++i) {
        inst->weak_dir[i] = ev[i * NPHI + kmin];
    }
    inst->n_prior_dirs = nprior;
    /* vector residual sum of squares: yy - 2 tr(theta^T Z) + tr(theta^T Lambda theta) */
    rss = inst->yy;
    for (j = 0u; j < 3u; ++j) {
        for (i = 0u; i < NPHI; ++i) {
            float lt = 0.0f;
            for (k = 0u; k < NPHI; ++k) {
                lt += inst->info[aided_pidx(i, k)] * theta[k][j];
            }
            rss += theta[i][j] * (lt - 2.0f * inst->cross[i * 3u + j]);
        }
    }
    /* back to raw coordinates */
    for (j = 0u; j < 3u; ++j) {
        for (i = 0u; i < 3u; ++i) {
            g[j][i] = theta[i][j];
        }
        ct[j] = theta[3][j];
    }
    for (i = 0u; i < 3u; ++i) {
        for (j = 0u; j < 3u; ++j) {
            if (!magcal_isfinite_f(g[i][j])) {
                return;
            }
        }
    }
    if (!magcal_isfinite_f(ct[0]) || !magcal_isfinite_f(ct[1]) || !magcal_isfinite_f(ct[2]) ||
        !solve3(g, ct, vv)) {
        return; /* singular G or a non-finite solution: keep the previous estimate */
    }
    fmean = inst->scale * inst->f_sum / neff;
    {
        const float vx = inst->cfg.prior.v.x - inst->scale * vv[0];
        const float vy = inst->cfg.prior.v.y - inst->scale * vv[1];
        const float vz = inst->cfg.prior.v.z - inst->scale * vv[2];
        if (!magcal_isfinite_f(vx) || !magcal_isfinite_f(vy) || !magcal_isfinite_f(vz) ||
            !magcal_isfinite_f(fmean) || !(fmean > 0.0f)) {
            return;
        }
    }
    (void)memcpy(inst->cal.g, g, sizeof(g));
    inst->cal.v.x = inst->cfg.prior.v.x - inst->scale * vv[0];
    inst->cal.v.y = inst->cfg.prior.v.y - inst->scale * vv[1];
    inst->cal.v.z = inst->cfg.prior.v.z - inst->scale * vv[2];
    inst->cal.field = fmean;
    inst->resid_rms = inst->scale * sqrtf(((rss > 0.0f) ? rss : 0.0f) / (3.0f * neff));
    (void)memcpy(inst->theta, theta, sizeof(theta));
    inst->flags |= MAGCAL_AIDED_FLAG_ESTIMATE;
    if (nprior > 0u) {
        inst->flags |= MAGCAL_AIDED_FLAG_PRIOR_USED;
    } else {
        inst->flags &= ~(uint32_t)MAGCAL_AIDED_FLAG_PRIOR_USED;
    }
}

static void aided_convergence(magcal_aided_t *inst)
{
    float dg = 0.0f;
    float dv;
    float d[3];
    size_t i;
    size_t j;
    if (inst->win_count == 0u) {
        for (i = 0u; i < 3u; ++i) {
            for (j = 0u; j < 3u; ++j) {
                inst->snap[i * 3u + j] = inst->cal.g[i][j];
            }
        }
        inst->snap[9] = inst->cal.v.x;
        inst->snap[10] = inst->cal.v.y;
        inst->snap[11] = inst->cal.v.z;
    }
    inst->win_count++;
    if (inst->win_count < inst->cfg.conv_window) {
        return;
    }
    for (i = 0u; i < 3u; ++i) {
        for (j = 0u; j < 3u; ++j) {
            float a = fabsf(inst->cal.g[i][j] - inst->snap[i * 3u + j]);
            dg = (a > dg) ? a : dg;
        }
    }
    d[0] = inst->cal.v.x - inst->snap[9];
    d[1] = inst->cal.v.y - inst->snap[10];
    d[2] = inst->cal.v.z - inst->snap[11];
    dv = sqrtf(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    if (dg < inst->cfg.conv_dg && dv < inst->cfg.conv_dv_rel * inst->cal.field &&
        inst->n_prior_dirs == 0u) {
        inst->flags |= MAGCAL_AIDED_FLAG_CONVERGED;
        if (inst->converged_at == 0u) {
            inst->converged_at = inst->n_accepted;
        }
    } else {
        inst->flags &= ~(uint32_t)MAGCAL_AIDED_FLAG_CONVERGED;
    }
    inst->win_count = 0u;
}

/* Gate an epoch (header order). h: the field through the calibration used (calibrated once
 * *calibrated is set: then it also linearises the total-field residual). */
static magcal_aided_gate_t aided_gate(const magcal_aided_t *inst, const magcal_aided_epoch_t *ep,
                                      float c[3][3], float bmag, float h[3], int *calibrated)
{
    const magcal_aided_cfg_t *cfg = &inst->cfg;
    const magcal_ellipsoid_cal_t *cal;
    float e[3];
    float hmag;
    int use_cal;
    size_t i;
    *calibrated = 0;
    if (ep->dop > cfg->max_dop) {
        return MAGCAL_AIDED_GATE_DOP;
    }
    /* far outside any field (a saturated or corrupted reading): never enters the sums */
    if (!(fabsf(ep->m.x - cfg->prior.v.x) <= RAW_RANGE * bmag) ||
        !(fabsf(ep->m.y - cfg->prior.v.y) <= RAW_RANGE * bmag) ||
        !(fabsf(ep->m.z - cfg->prior.v.z) <= RAW_RANGE * bmag)) {
        return MAGCAL_AIDED_GATE_RAW;
    }
    /* The calibrated gates need an estimate that predicts the field at every heading: at most one
     * direction on the prior (the out-of-plane one of level driving, harmless for near-level
     * epochs). An early estimate from one straight leg (two or more weak directions) would lock out
     * the new headings it needs, so the loose prior gate is used until then. */
    use_cal = 0;
    if (((inst->flags & MAGCAL_AIDED_FLAG_ESTIMATE) != 0u) && (inst->n_prior_dirs <= 1u)) {
        use_cal = 1;
    }
    cal = (use_cal != 0) ? &inst->cal : &cfg->prior;
    e[0] = ep->m.x - cal->v.x;
    e[1] = ep->m.y - cal->v.y;
    e[2] = ep->m.z - cal->v.z;
    for (i = 0u; i < 3u; ++i) {
        h[i] = cal->g[i][0] * e[0] + cal->g[i][1] * e[1] + cal->g[i][2] * e[2];
    }
    hmag = sqrtf(h[0] * h[0] + h[1] * h[1] + h[2] * h[2]);
    *calibrated = use_cal;
    if (use_cal == 0) {
        /* written as !(x <= limit): a NaN (an overflowed product) is rejected, not accepted */
        return !(fabsf(hmag - bmag) <= cfg->gate_raw_rel * bmag) ? MAGCAL_AIDED_GATE_RAW
                                                               : MAGCAL_AIDED_GATE_NONE;
    }
    if (!(fabsf(hmag - bmag) <= cfg->gate_field_rel * bmag)) {
        return MAGCAL_AIDED_GATE_FIELD;
    }
    {
        float r2 = 0.0f;
        const float b[3] = {ep->b_ref_ned.x, ep->b_ref_ned.y, ep->b_ref_ned.z};
        for (i = 0u; i < 3u; ++i) {
            float ri = c[i][0] * h[0] + c[i][1] * h[1] + c[i][2] * h[2] - b[i];
            r2 += ri * ri;
        }
        if (!(sqrtf(r2) <= cfg->gate_vector_rel * bmag)) {
            return MAGCAL_AIDED_GATE_VECTOR;
        }
    }
    return MAGCAL_AIDED_GATE_NONE;
}

/* Accumulate the linearised total-field residual of an accepted epoch (module comment) and its
 * a-priori value for the windowed RMS. h: calibrated field (output units), phi: regressor. */
static void aided_total_field(magcal_aided_t *inst, const float h[3], const float phi[NPHI], float bmag)
{
    float u[NPAR];
    float nv[3];
    const float hmag = sqrtf(h[0] * h[0] + h[1] * h[1] + h[2] * h[2]);
    const float fs = bmag / inst->scale;
    size_t p;
    size_t q;
    if (!(hmag > 0.0f)) {
        return;
    }
    inst->rf_win += (hmag - bmag) * (hmag - bmag);
    inst->rf_win_n++;
    if (inst->rf_win_n >= inst->cfg.conv_window) {
        inst->resid_f_rms = sqrtf(inst->rf_win / (float)inst->rf_win_n);
        inst->rf_win = 0.0f;
        inst->rf_win_n = 0u;
    }
    if (inst->cfg.objective != MAGCAL_AIDED_OBJ_COMBINED) {
        return;
    }
    for (p = 0u; p < 3u; ++p) {
        nv[p] = h[p] / hmag;
    }
    for (p = 0u; p < NPAR; ++p) {
        u[p] = nv[p % 3u] * phi[p / 3u];
    }
    for (p = 0u; p < NPAR; ++p) {
        for (q = 0u; q <= p; ++q) {
            const size_t k = aided_pidx(p, q);
            magcal_kahan_add(&inst->hf[k], &inst->hf_c[k], u[p] * u[q]);
        }
        magcal_kahan_add(&inst->bf[p], &inst->bf_c[p], fs * u[p]);
    }
    for (p = 0u; p < 3u; ++p) {
        for (q = 0u; q <= p; ++q) {
            inst->nn[aided_pidx(p, q)] += nv[p] * nv[q];
        }
    }
    inst->n_tf++;
}

/*
 * Stationarity: 1 when this accepted epoch is held back. A run starts at an epoch (its regressor the
 * anchor) and lasts while the regressor stays within max(still_field_rel, 8 noise_rel) (max axis,
 * normalised units) of the anchor; its first still_epochs epochs are used, the rest only counted. Exciting motion leaves
 * the ball (about 1.4 deg of yaw at the default) long before still_epochs, so a drive is never
 * thinned; a parked vehicle adds still_epochs epochs per stop instead of one per epoch.
 */
static int aided_still(magcal_aided_t *inst, const float phi[NPHI])
{
    const float rn = 8.0f * inst->cfg.noise_rel; /* noise alone (max of 3 axes, 2 samples) stays inside */
    const float r = (inst->cfg.still_field_rel > rn) ? inst->cfg.still_field_rel : rn;
    size_t i;
    int inside = 0;
    if (inst->cfg.still_epochs == 0u) {
        return 0;
    }
    if (inst->still_run > 0u) {
        inside = 1;
    }
    for (i = 0u; i < 3u && inside != 0; ++i) {
        if (!(fabsf(phi[i] - inst->still_phi[i]) <= r)) {
            inside = 0;
        }
    }
    if (inside == 0) {
        for (i = 0u; i < 3u; ++i) {
            inst->still_phi[i] = phi[i];
        }
        inst->still_run = 1u;
        return 0;
    }
    if (inst->still_run >= inst->cfg.still_epochs) {
        return 1;
    }
    inst->still_run++;
    return 0;
}

/* magcal_aided_update up to the solve: checks, gates, sums. *added = 1 when the epoch entered the
 * sums (accepted and not held back as stationary). Its frame (attitude, regressor, the total-field
 * Jacobian) is gone before aided_solve runs. */
static MAGCAL_NOINLINE magcal_status_t aided_accept(magcal_aided_t *inst,
                                                    const magcal_aided_epoch_t *ep,
                                                    magcal_aided_gate_t *reason, int *added)
{
    float c[3][3];
    float b[3];
    float bmag;
    float phi[NPHI];
    float y[3];
    float h[3];
    float inv_s;
    size_t i;
    size_t j;
    int calibrated = 0;
    magcal_aided_gate_t gate;

    if (inst == NULL || ep == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (inst->magic != AIDED_MAGIC) {
        return MAGCAL_ERR_NOT_INITIALISED;
    }
    if (!finite3(&ep->m) || !finite3(&ep->b_ref_ned) || !magcal_isfinite_f(ep->roll_rad) ||
        !magcal_isfinite_f(ep->pitch_rad) || !magcal_isfinite_f(ep->yaw_rad) ||
        !magcal_isfinite_f(ep->dop)) {
        return MAGCAL_ERR_NONFINITE;
    }
    if (ep->dop < 0.0f || !(fabsf(ep->pitch_rad) < 0.5f * MAGCAL_PI_F)) {
        return MAGCAL_ERR_ARG;
    }
    b[0] = ep->b_ref_ned.x;
    b[1] = ep->b_ref_ned.y;
    b[2] = ep->b_ref_ned.z;
    bmag = sqrtf(b[0] * b[0] + b[1] * b[1] + b[2] * b[2]);
    if (!(bmag > 0.0f)) {
        return MAGCAL_ERR_ZERO_FIELD;
    }
    /* |B_ref| must be representable and stay within REF_RATIO of the normalisation s (the first
     * accepted epoch's |B_ref|): the Earth's field varies by a factor ~3 over the globe, so a
     * larger jump is a unit mix-up, and it would push the normalised sums out of float32 range */
    if (!magcal_isfinite_f(bmag) ||
        (inst->scale > 0.0f && !(bmag <= REF_RATIO * inst->scale && bmag * REF_RATIO >= inst->scale))) {
        return MAGCAL_ERR_ARG;
    }
    (void)magcal_aided_dcm(ep->roll_rad, ep->pitch_rad, ep->yaw_rad, c);
    inst->n_seen++;
    gate = aided_gate(inst, ep, c, bmag, h, &calibrated);
    if (reason != NULL) {
        *reason = gate;
    }
    if (gate != MAGCAL_AIDED_GATE_NONE) {
        inst->gated[gate]++;
        return MAGCAL_ERR_GATED;
    }
    if (inst->scale == 0.0f) {
        inst->scale = bmag; /* fixed normalisation from the first accepted epoch */
    }
    inv_s = 1.0f / inst->scale;
    phi[0] = (ep->m.x - inst->cfg.prior.v.x) * inv_s;
    phi[1] = (ep->m.y - inst->cfg.prior.v.y) * inv_s;
    phi[2] = (ep->m.z - inst->cfg.prior.v.z) * inv_s;
    phi[3] = 1.0f;
    if (aided_still(inst, phi) != 0) {
        inst->n_still++;
        return MAGCAL_OK; /* stationary: no new information, nothing forgotten */
    }
    *added = 1;
    for (i = 0u; i < 3u; ++i) { /* y = C^T B / s: reference field in body axes */
        y[i] = (c[0][i] * b[0] + c[1][i] * b[1] + c[2][i] * b[2]) * inv_s;
    }
    if (inst->cfg.lambda < 1.0f) {
        const float lam = inst->cfg.lambda;
        for (i = 0u; i < NPACK4; ++i) {
            inst->info[i] *= lam;
            inst->info_c[i] *= lam;
        }
        for (i = 0u; i < 12u; ++i) {
            inst->cross[i] *= lam;
            inst->cross_c[i] *= lam;
        }
        inst->yy *= lam;
        inst->yy_c *= lam;
        inst->f_sum *= lam;
        for (i = 0u; i < NPACK12; ++i) {
            inst->hf[i] *= lam;
            inst->hf_c[i] *= lam;
        }
        for (i = 0u; i < NPAR; ++i) {
            inst->bf[i] *= lam;
            inst->bf_c[i] *= lam;
        }
        for (i = 0u; i < 6u; ++i) {
            inst->nn[i] *= lam;
        }
    }
    for (i = 0u; i < NPHI; ++i) {
        for (j = 0u; j <= i; ++j) {
            size_t p = aided_pidx(i, j);
            magcal_kahan_add(&inst->info[p], &inst->info_c[p], phi[i] * phi[j]);
        }
        for (j = 0u; j < 3u; ++j) {
            magcal_kahan_add(&inst->cross[i * 3u + j], &inst->cross_c[i * 3u + j], phi[i] * y[j]);
        }
    }
    magcal_kahan_add(&inst->yy, &inst->yy_c, y[0] * y[0] + y[1] * y[1] + y[2] * y[2]);
    inst->f_sum += bmag * inv_s;
    if (calibrated != 0) {
        aided_total_field(inst, h, phi, bmag);
    }
    inst->n_accepted++;
    return MAGCAL_OK;
}

magcal_status_t magcal_aided_update(magcal_aided_t *inst, const magcal_aided_epoch_t *ep,
                                    magcal_aided_gate_t *reason)
{
    int added = 0;
    const magcal_status_t st = aided_accept(inst, ep, reason, &added);
    if (st == MAGCAL_OK && added != 0 && inst->n_accepted >= inst->cfg.min_epochs) {
        aided_solve(inst);
        aided_convergence(inst);
    }
    return st;
}

magcal_status_t magcal_aided_get(const magcal_aided_t *inst, magcal_aided_result_t *out)
{
    size_t i;
    if (inst == NULL || out == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (inst->magic != AIDED_MAGIC) {
        return MAGCAL_ERR_NOT_INITIALISED;
    }
    if ((inst->flags & MAGCAL_AIDED_FLAG_ESTIMATE) == 0u) {
        return MAGCAL_ERR_TOO_FEW_POINTS;
    }
    out->cal = inst->cal;
    out->flags = inst->flags;
    out->n_accepted = inst->n_accepted;
    out->n_seen = inst->n_seen;
    for (i = 0u; i < (size_t)MAGCAL_AIDED_GATE_COUNT; ++i) {
        out->gated[i] = inst->gated[i];
    }
    out->converged_at = inst->converged_at;
    out->n_prior_dirs = inst->n_prior_dirs;
    out->min_eig = inst->min_eig;
    out->weak_std = inst->weak_std;
    out->resid_rms = inst->resid_rms;
    out->resid_f_rms = inst->resid_f_rms;
    out->n_total_field = inst->n_tf;
    out->n_still = inst->n_still;
    if (inst->n_prior_dirs > 0u) {
        return MAGCAL_ERR_UNOBSERVABLE;
    }
    if ((inst->flags & MAGCAL_AIDED_FLAG_CONVERGED) == 0u) {
        return MAGCAL_ERR_NOT_CONVERGED;
    }
    return MAGCAL_OK;
}

#endif /* MAGCAL_CFG_ENABLE_AIDED */
