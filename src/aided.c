/*
 * INS/GNSS-aided online 3-D calibration (algorithms.md 7.3, 7.4, 7.6, 7.7, 7.8).
 *
 * Linear vector model per epoch: y = C_n^b B_ref / s = G x~ + c~ with x~ = (m - V0)/s, the shared
 * regressor phi = [x~; 1] and theta (4x3) = [G^T; c~^T]. Information-form RLS: Lambda = sum phi phi^T
 * (4x4) and Z = sum phi y^T (4x3), Kahan-compensated float32 sums, optional forgetting. The solve
 * eigen-decomposes Lambda/N_eff (4x4 Jacobi): directions with enough excitation are solved from the
 * data, the others are frozen at the prior theta0 (pseudo-inverse around the prior):
 *   theta = theta0 + sum_{k good} e_k e_k^T (Z - Lambda theta0) / (N_eff mu_k).
 * Finally G = theta[0..2]^T, V = V0 - s G^-1 c~.
 */
#include <math.h>
#include <string.h>

#include "magcal/aided.h"
#include "magcal_internal.h"

#define AIDED_MAGIC 0x41494433u /* "AID3" */
#define NPHI 4u
#define NPACK4 10u
#define JACOBI_SWEEPS 12u
#define MIN_EPOCHS_LIMIT 8u

static size_t pidx4(size_t i, size_t j)
{
    return (i >= j) ? ((i * (i + 1u)) / 2u + j) : ((j * (j + 1u)) / 2u + i);
}

static void kahan_add(float *sum, float *comp, float v)
{
    float y = v - *comp;
    float t = *sum + y;
    *comp = (t - *sum) - y;
    *sum = t;
}

static int finite3(const magcal_vec3_t *v)
{
    return magcal_isfinite_f(v->x) && magcal_isfinite_f(v->y) && magcal_isfinite_f(v->z);
}

static float det3(float a[3][3])
{
    return a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1]) - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0]) +
           a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]);
}

/* x = a^-1 b for a 3x3 by cofactors; returns 0 when |det| is tiny relative to the entries. */
static int solve3(float a[3][3], const float b[3], float x[3])
{
    float det = det3(a);
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

/* Cyclic Jacobi on a symmetric 4x4 (a destroyed): eigenvalues w, eigenvectors in the columns of e. */
static magcal_status_t jacobi4(float a[NPHI][NPHI], float w[NPHI], float e[NPHI][NPHI])
{
    size_t sweep;
    size_t i;
    size_t j;
    float scale = 0.0f;
    for (i = 0u; i < NPHI; ++i) {
        for (j = 0u; j < NPHI; ++j) {
            e[i][j] = (i == j) ? 1.0f : 0.0f;
            scale += a[i][j] * a[i][j];
        }
    }
    for (sweep = 0u; sweep < JACOBI_SWEEPS; ++sweep) {
        size_t p;
        float off = 0.0f;
        for (i = 0u; i < NPHI; ++i) {
            for (j = i + 1u; j < NPHI; ++j) {
                off += a[i][j] * a[i][j];
            }
        }
        if (off <= 1e-14f * scale) {
            for (i = 0u; i < NPHI; ++i) {
                w[i] = a[i][i];
            }
            return MAGCAL_OK;
        }
        for (p = 0u; p + 1u < NPHI; ++p) {
            size_t q;
            for (q = p + 1u; q < NPHI; ++q) {
                float apq = a[p][q];
                float theta;
                float t;
                float c;
                float s;
                size_t k;
                if (apq == 0.0f) {
                    continue;
                }
                theta = (a[q][q] - a[p][p]) / (2.0f * apq);
                t = 1.0f / (fabsf(theta) + sqrtf(theta * theta + 1.0f));
                if (theta < 0.0f) {
                    t = -t;
                }
                c = 1.0f / sqrtf(t * t + 1.0f);
                s = t * c;
                for (k = 0u; k < NPHI; ++k) {
                    float akp = a[k][p];
                    float akq = a[k][q];
                    a[k][p] = c * akp - s * akq;
                    a[k][q] = s * akp + c * akq;
                }
                for (k = 0u; k < NPHI; ++k) {
                    float apk = a[p][k];
                    float aqk = a[q][k];
                    a[p][k] = c * apk - s * aqk;
                    a[q][k] = s * apk + c * aqk;
                }
                for (k = 0u; k < NPHI; ++k) {
                    float ekp = e[k][p];
                    float ekq = e[k][q];
                    e[k][p] = c * ekp - s * ekq;
                    e[k][q] = s * ekp + c * ekq;
                }
            }
        }
    }
    return MAGCAL_ERR_NOT_CONVERGED;
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
    if (!magcal_isfinite_f(roll_rad) || !magcal_isfinite_f(pitch_rad) || !magcal_isfinite_f(yaw_rad)) {
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

magcal_status_t magcal_aided_init(magcal_aided_t *inst, const magcal_aided_cfg_t *cfg)
{
    size_t i;
    size_t j;
    float g0[3][3];
    if (inst == NULL || cfg == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (!(cfg->lambda >= 0.9f && cfg->lambda <= 1.0f) || !(cfg->max_dop > 0.0f) ||
        !(cfg->gate_raw_rel > 0.0f) || !(cfg->gate_field_rel > 0.0f) || !(cfg->gate_vector_rel > 0.0f) ||
        !(cfg->sigma_rel > 0.0f) || !(cfg->max_weak_std > 0.0f) || !(cfg->min_eig >= 0.0f && cfg->min_eig < 1.0f) ||
        !(cfg->conv_dg > 0.0f) || !(cfg->conv_dv_rel > 0.0f) || !(cfg->noise_rel >= 0.0f && cfg->noise_rel < 0.1f)) {
        return MAGCAL_ERR_ARG;
    }
    if (!magcal_isfinite_f(cfg->max_dop) || !magcal_isfinite_f(cfg->gate_raw_rel) ||
        !magcal_isfinite_f(cfg->gate_field_rel) || !magcal_isfinite_f(cfg->gate_vector_rel) ||
        !magcal_isfinite_f(cfg->sigma_rel) || !magcal_isfinite_f(cfg->max_weak_std) ||
        !magcal_isfinite_f(cfg->conv_dg) || !magcal_isfinite_f(cfg->conv_dv_rel)) {
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

/* Solve for theta from the sums; updates cal, weak-direction diagnostics and the residual. */
static void aided_solve(magcal_aided_t *inst)
{
    const magcal_aided_cfg_t *cfg = &inst->cfg;
    float lam[NPHI][NPHI];
    float lamc[NPHI][NPHI];
    float ev[NPHI][NPHI];
    float mu[NPHI];
    float theta0[NPHI][3];
    float resid[NPHI][3];
    float theta[NPHI][3];
    float g[3][3];
    float ct[3];
    float vv[3];
    float neff = inst->info[pidx4(3u, 3u)];
    float sigma;
    float rss;
    float fmean;
    size_t i;
    size_t j;
    size_t k;
    size_t kmin = 0u;
    uint32_t nprior = 0u;

    if (!(neff > 0.0f)) {
        return;
    }
    for (i = 0u; i < NPHI; ++i) {
        for (j = 0u; j < NPHI; ++j) {
            lam[i][j] = inst->info[pidx4(i, j)] / neff;
        }
    }
    /* Bias compensation: E[x~ x~^T] holds the noise variance on its diagonal; remove it so that a
     * weakly excited direction is not shrunk towards zero (errors in variables). */
    for (i = 0u; i < 3u; ++i) {
        lam[i][i] -= cfg->noise_rel * cfg->noise_rel;
    }
    (void)memcpy(lamc, lam, sizeof(lam));
    if (jacobi4(lam, mu, ev) != MAGCAL_OK) {
        return; /* keep the previous estimate */
    }
    /* prior in normalised coordinates: G0 rows, c~0 = G0 (V0 - V0)/s = 0 */
    for (j = 0u; j < 3u; ++j) {
        for (i = 0u; i < 3u; ++i) {
            theta0[i][j] = cfg->prior.g[j][i];
        }
        theta0[3][j] = 0.0f;
    }
    /* residual of the (compensated) normal equations at the prior: Z - Lambda theta0 */
    for (i = 0u; i < NPHI; ++i) {
        for (j = 0u; j < 3u; ++j) {
            float sacc = inst->cross[i * 3u + j];
            for (k = 0u; k < NPHI; ++k) {
                sacc -= neff * lamc[i][k] * theta0[k][j];
            }
            resid[i][j] = sacc;
        }
    }
    sigma = cfg->sigma_rel;
    if (inst->cal.field > 0.0f && inst->resid_rms / inst->cal.field > sigma) {
        sigma = inst->resid_rms / inst->cal.field;
    }
    (void)memcpy(theta, theta0, sizeof(theta));
    for (k = 0u; k < NPHI; ++k) {
        float std = (mu[k] > 0.0f) ? sigma / sqrtf(neff * mu[k]) : 1e30f;
        if (mu[k] < mu[kmin]) {
            kmin = k;
        }
        if (!(mu[k] >= cfg->min_eig) || !(mu[k] > 0.0f) || !(std <= cfg->max_weak_std)) {
            nprior++;
            continue;
        }
        for (j = 0u; j < 3u; ++j) {
            float proj = 0.0f;
            for (i = 0u; i < NPHI; ++i) {
                proj += ev[i][k] * resid[i][j];
            }
            proj /= neff * mu[k];
            for (i = 0u; i < NPHI; ++i) {
                theta[i][j] += ev[i][k] * proj;
            }
        }
    }
    inst->min_eig = mu[kmin];
    inst->weak_std = (mu[kmin] > 0.0f) ? sigma / sqrtf(neff * mu[kmin]) : 1e30f;
    for (i = 0u; i < NPHI; ++i) {
        inst->weak_dir[i] = ev[i][kmin];
    }
    inst->n_prior_dirs = nprior;
    /* residual sum of squares: yy - 2 tr(theta^T Z) + tr(theta^T Lambda theta) */
    rss = inst->yy;
    for (j = 0u; j < 3u; ++j) {
        for (i = 0u; i < NPHI; ++i) {
            float lt = 0.0f;
            for (k = 0u; k < NPHI; ++k) {
                lt += inst->info[pidx4(i, k)] * theta[k][j];
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
    if (!solve3(g, ct, vv)) {
        return; /* singular G: keep the previous estimate */
    }
    fmean = inst->scale * inst->f_sum / neff;
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
    if (dg < inst->cfg.conv_dg && dv < inst->cfg.conv_dv_rel * inst->cal.field && inst->n_prior_dirs == 0u) {
        inst->flags |= MAGCAL_AIDED_FLAG_CONVERGED;
        if (inst->converged_at == 0u) {
            inst->converged_at = inst->n_accepted;
        }
    } else {
        inst->flags &= ~(uint32_t)MAGCAL_AIDED_FLAG_CONVERGED;
    }
    inst->win_count = 0u;
}

static magcal_aided_gate_t aided_gate(const magcal_aided_t *inst, const magcal_aided_epoch_t *ep, float c[3][3],
                                      float bmag)
{
    const magcal_aided_cfg_t *cfg = &inst->cfg;
    const magcal_ellipsoid_cal_t *cal;
    float e[3];
    float h[3];
    float hmag;
    int use_cal;
    size_t i;
    if (ep->dop > cfg->max_dop) {
        return MAGCAL_AIDED_GATE_DOP;
    }
    /* The calibrated gates need an estimate that predicts the field at every heading: at most one
     * direction on the prior (the out-of-plane one of level driving, harmless for near-level
     * epochs). An early estimate from one straight leg (two or more weak directions) would lock out
     * the new headings it needs, so the loose prior gate is used until then. */
    use_cal = ((inst->flags & MAGCAL_AIDED_FLAG_ESTIMATE) != 0u) && (inst->n_prior_dirs <= 1u);
    cal = use_cal ? &inst->cal : &cfg->prior;
    e[0] = ep->m.x - cal->v.x;
    e[1] = ep->m.y - cal->v.y;
    e[2] = ep->m.z - cal->v.z;
    for (i = 0u; i < 3u; ++i) {
        h[i] = cal->g[i][0] * e[0] + cal->g[i][1] * e[1] + cal->g[i][2] * e[2];
    }
    hmag = sqrtf(h[0] * h[0] + h[1] * h[1] + h[2] * h[2]);
    if (!use_cal) {
        return (fabsf(hmag - bmag) > cfg->gate_raw_rel * bmag) ? MAGCAL_AIDED_GATE_RAW : MAGCAL_AIDED_GATE_NONE;
    }
    if (fabsf(hmag - bmag) > cfg->gate_field_rel * bmag) {
        return MAGCAL_AIDED_GATE_FIELD;
    }
    {
        float r2 = 0.0f;
        const float b[3] = {ep->b_ref_ned.x, ep->b_ref_ned.y, ep->b_ref_ned.z};
        for (i = 0u; i < 3u; ++i) {
            float ri = c[i][0] * h[0] + c[i][1] * h[1] + c[i][2] * h[2] - b[i];
            r2 += ri * ri;
        }
        if (sqrtf(r2) > cfg->gate_vector_rel * bmag) {
            return MAGCAL_AIDED_GATE_VECTOR;
        }
    }
    return MAGCAL_AIDED_GATE_NONE;
}

magcal_status_t magcal_aided_update(magcal_aided_t *inst, const magcal_aided_epoch_t *ep, magcal_aided_gate_t *reason)
{
    float c[3][3];
    float b[3];
    float bmag;
    float phi[NPHI];
    float y[3];
    float inv_s;
    size_t i;
    size_t j;
    magcal_aided_gate_t gate;

    if (inst == NULL || ep == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (inst->magic != AIDED_MAGIC) {
        return MAGCAL_ERR_NOT_INITIALISED;
    }
    if (!finite3(&ep->m) || !finite3(&ep->b_ref_ned) || !magcal_isfinite_f(ep->roll_rad) ||
        !magcal_isfinite_f(ep->pitch_rad) || !magcal_isfinite_f(ep->yaw_rad) || !magcal_isfinite_f(ep->dop)) {
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
    (void)magcal_aided_dcm(ep->roll_rad, ep->pitch_rad, ep->yaw_rad, c);
    inst->n_seen++;
    gate = aided_gate(inst, ep, c, bmag);
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
    }
    for (i = 0u; i < NPHI; ++i) {
        for (j = 0u; j <= i; ++j) {
            size_t p = pidx4(i, j);
            kahan_add(&inst->info[p], &inst->info_c[p], phi[i] * phi[j]);
        }
        for (j = 0u; j < 3u; ++j) {
            kahan_add(&inst->cross[i * 3u + j], &inst->cross_c[i * 3u + j], phi[i] * y[j]);
        }
    }
    kahan_add(&inst->yy, &inst->yy_c, y[0] * y[0] + y[1] * y[1] + y[2] * y[2]);
    inst->f_sum += bmag * inv_s;
    inst->n_accepted++;
    if (inst->n_accepted >= inst->cfg.min_epochs) {
        aided_solve(inst);
        aided_convergence(inst);
    }
    return MAGCAL_OK;
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
    if (inst->n_prior_dirs > 0u) {
        return MAGCAL_ERR_UNOBSERVABLE;
    }
    if ((inst->flags & MAGCAL_AIDED_FLAG_CONVERGED) == 0u) {
        return MAGCAL_ERR_NOT_CONVERGED;
    }
    return MAGCAL_OK;
}
