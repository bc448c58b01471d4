/*
 * Continuous calibrator, the judge's field model fitted over the store at each adoption,
 * time-sliced (docs/calibrator.md "Judge and change detection"). A level sensor that pitches
 * (hills) keeps |h|^2 + z_b^2 = F^2, and its raw z is z_b plus a heading-dependent leak of x, y
 * (soft iron, misalignment), so |h|^2 = c0 + c1 u + c2 u^2 + c3 hx + c4 hy + c5 (hx^2 - hy^2) +
 * c6 hx hy (u = raw z - its store mean, h corrected, both scaled to unit radius); without the
 * hx, hy terms the leak alone (about 5 % of |h|) hides a disturbance; c5, c6 absorb a residual
 * shape error of the calibration; the judge's rel = sqrt(model) - 1 (cont_judge.c). The fit also
 * keeps the Cholesky factor of the store's normal matrix (the judge's uncertainty), the sectors
 * the store covered and the model's relative residual on the store (cal_sigma_rel).
 */
#include "cont_judge_internal.h"

#define CONT_FZ_MIN_N 30.0f       /* store samples the total-field model needs */
#define CONT_FIT_RING 0.35f      /* | |h| / R - 1 | of the samples the passes take (hills move the radius by up to ~20 %) */

/* Cholesky in place of the nf x nf normal matrix held packed (lower) in cc->fz_l, scaled by its
 * diagonal (scales into cc->fz_s), then the solve of (F^T F) c = b in place. 0 when not
 * positive definite (a relative pivot below 1e-6: the store cannot separate the terms). */
static int cont_fz_chol_solve(magcal_cont_t *cc, uint32_t nf, float *b)
{
    float *l = cc->fz_l;
    uint32_t p;
    uint32_t q;
    uint32_t k;
    for (p = 0u; p < nf; ++p) {
        if (!(l[p * (p + 1u) / 2u + p] > 0.0f)) {
            return 0;
        }
        cc->fz_s[p] = sqrtf(l[p * (p + 1u) / 2u + p]);
    }
    for (p = 0u; p < nf; ++p) {
        for (q = 0u; q <= p; ++q) {
            float v = l[p * (p + 1u) / 2u + q] / (cc->fz_s[p] * cc->fz_s[q]);
            for (k = 0u; k < q; ++k) {
                v -= l[p * (p + 1u) / 2u + k] * l[q * (q + 1u) / 2u + k];
            }
            if (p == q) {
                if (!(v > 1e-6f)) {
                    return 0;
                }
                l[p * (p + 1u) / 2u + p] = sqrtf(v);
            } else {
                l[p * (p + 1u) / 2u + q] = v / l[q * (q + 1u) / 2u + q];
            }
        }
    }
    /* L L^T z = S^-1 b, c = S^-1 z */
    for (p = 0u; p < nf; ++p) {
        float v = b[p] / cc->fz_s[p];
        for (k = 0u; k < p; ++k) {
            v -= l[p * (p + 1u) / 2u + k] * b[k];
        }
        b[p] = v / l[p * (p + 1u) / 2u + p];
    }
    for (q = 0u; q < nf; ++q) {
        float v;
        p = nf - 1u - q;
        v = b[p];
        for (k = p + 1u; k < nf; ++k) {
            v -= l[k * (k + 1u) / 2u + p] * b[k];
        }
        b[p] = v / l[p * (p + 1u) / 2u + p];
    }
    for (p = 0u; p < nf; ++p) {
        b[p] /= cc->fz_s[p];
    }
    return magcal_isfinite_f(b[0]) ? 1 : 0;
}

/* Time-sliced field-model fit (magcal_cont_fit_begin / _step): passes over the store in bin
 * order, position (fit_bin, fit_k) and sums in cc. Weights, estimated M4F instructions (host
 * callgrind x 1.2, then x 1.2 as measured on QEMU: cont_trace.elf, tools/bench/cont_weights.py):
 * one sample of each pass, one bin advanced, the Cholesky solve of one form. */
#define CONT_W_FIT_Z 240u     /* z mean / variance of one ring sample (its correction + ring test; was 400: measured on target, cont_trace.elf, <= 231 per sample) */
#define CONT_W_FIT_SUM 720u   /* normal-equation sums: one sample (the full form; less without u; was 900: measured p99 705) */
#define CONT_W_FIT_SIGMA 430u /* the model's residual and the sector covered: one sample (was 684: measured <= 415) */
#define CONT_W_FIT_SLOPE 300u /* raw z about the level into the histogram: one sample (cont_slope.c; estimate: the z pass's and cont_sl_in) */
#define CONT_W_FIT_SL 80u     /* the slope sums' share of a z or sigma pass sample (cont_slope.c; estimate), without gravity only */
#define CONT_W_FIT_BIN 13u    /* one bin advanced */
#define CONT_W_FIT_CHOL 3840u /* Cholesky + solve of one model form (7 x 7 at most) */

/* cppcheck-suppress misra-c2012-5.7 ; deviation D14 (false positive): the enum has no tag */
/* cppcheck-suppress misra-c2012-2.4 ; deviation D14 (false positive): no tag, so no unused tag */
enum { CONT_FIT_NONE = 0, CONT_FIT_Z = 1, CONT_FIT_SUMS = 2, CONT_FIT_CHOL = 3, CONT_FIT_SIGMA = 4, CONT_FIT_SLOPE = 5 };

/* Start a pass (phase) over the store with its accumulators cleared. */
static void cont_fit_pass(magcal_cont_t *cc, uint8_t phase)
{
    cc->fit_phase = phase;
    cc->fit_bin = 0u;
    cc->fit_k = 0u;
    cc->fit_acc[0] = 0.0f;
    cc->fit_acc[1] = 0.0f;
    cc->fit_acc[2] = 0.0f;
    if (phase == (uint8_t)CONT_FIT_SUMS) {
        uint32_t p;
        /* packed lower triangle: row p, column q at p (p + 1) / 2 + q */
        for (p = 0u; p < 28u; ++p) {
            cc->fz_l[p] = 0.0f;
        }
        for (p = 0u; p < 7u; ++p) {
            cc->fit_b[p] = 0.0f;
        }
    }
}

/* Corrected x, y of a store sample during the fit: magcal_correct_apply (heading.c) without its
 * per-call validation of cc->cal (validated once at the fit's begin, fit_cal_ok; cc->cal does not
 * change during the fit). 1 when defined. */
static int cont_fit_corrected(const magcal_cont_t *cc, const magcal_vec3_t *m, magcal_vec2_t *h)
{
    float ux;
    float uy;
    if (cc->fit_cal_ok == 0u || !magcal_isfinite_f(m->x) || !magcal_isfinite_f(m->y)) {
        return 0;
    }
    ux = m->x - cc->cal.offset.x;
    uy = m->y - cc->cal.offset.y;
    h->x = cc->cal.m[0][0] * ux + cc->cal.m[0][1] * uy;
    h->y = cc->cal.m[1][0] * ux + cc->cal.m[1][1] * uy;
    return magcal_isfinite_f(h->x) && magcal_isfinite_f(h->y);
}

/* A store sample on the ring for the z and slope passes: corrected (into h) and within
 * CONT_FIT_RING of the radius (a stored spike's z must not move u0, its spread or the level). */
static int cont_fit_on_ring(const magcal_cont_t *cc, const magcal_vec3_t *m, magcal_vec2_t *h)
{
    return (cont_fit_corrected(cc, m, h) != 0 &&
            fabsf(sqrtf(h->x * h->x + h->y * h->y) / cc->cal.radius - 1.0f) <= CONT_FIT_RING)
               ? 1
               : 0;
}

/* One sample of the sums pass: normal equations of |h|^2 = f . c over the samples with
 * | |h| / R - 1 | <= 0.35 (hills move the horizontal radius by up to ~20 %). Unit-radius
 * variables (file comment); fit_acc[2] counts the samples used. */
static void cont_fz_add(magcal_cont_t *cc, const magcal_vec3_t *m)
{
    const uint32_t skip = cc->fit_skip;
    const uint32_t nf = 7u - skip;
    float *a = cc->fz_l;
    magcal_vec2_t h;
    float f[7];
    float y;
    uint32_t p;
    uint32_t q;
    if (cont_fit_corrected(cc, m, &h) == 0) {
        return;
    }
    h.x /= cc->cal.radius;
    h.y /= cc->cal.radius;
    y = h.x * h.x + h.y * h.y;
    if (!(fabsf(sqrtf(y) - 1.0f) <= CONT_FIT_RING)) {
        return;
    }
    {
        const float u = (m->z - cc->fz_u0) / cc->cal_raw_radius;
        (void)magcal_cont_fz_feat(u, h.x, h.y, skip, f);
        if (skip == 2u && cc->fz_have_u != 0u) {
            /* the u terms of an earlier model: the store alone cannot determine them */
            y -= cc->fz_u_prior[0] * u + cc->fz_u_prior[1] * u * u;
        }
    }
    for (p = 0u; p < nf; ++p) {
        const float fp = f[p];
        for (q = 0u; q <= p; ++q) {
            *a++ += fp * f[q]; /* packed: row p, column q at p (p + 1) / 2 + q */
        }
        cc->fit_b[p] += fp * y;
    }
    cc->fit_acc[2] += 1.0f;
}

/* One sample of the current pass: z sums, the normal-equation sums, or the model's residual
 * (the judge's rel) with the sector covered (the judge's sector). */
static void cont_fit_sample(magcal_cont_t *cc, const magcal_vec3_t *m)
{
    magcal_vec2_t h;
    if (cc->fit_phase == (uint8_t)CONT_FIT_SUMS) {
        cont_fz_add(cc, m);
        return;
    }
    if (cc->fit_phase == (uint8_t)CONT_FIT_SLOPE) {
        if (cont_fit_on_ring(cc, m, &h) != 0) {
            magcal_cont_slope_hist(cc, &h, m->z); /* raw z about the refitted level (cont_slope.c) */
        }
        return;
    }
    if (cc->fit_phase == (uint8_t)CONT_FIT_Z) {
        if (cont_fit_on_ring(cc, m, &h) == 0) {
            return; /* the samples the sums use (on the ring) */
        }
        cc->fit_acc[0] += m->z;
        cc->fit_acc[1] += m->z * m->z;
        cc->fit_acc[2] += 1.0f;
        if (cc->sl_on != 0u) {
            magcal_cont_slope_add(cc, &h, m->z); /* the level raw z (cont_slope.c) */
        }
        return;
    }
    if (cont_fit_corrected(cc, m, &h) != 0) {
        /* sigma: RMS of the relative residual over the samples within 0.1 of the model */
        float v[3];
        const float rel = magcal_cont_fz_rel(cc, &h, m->z, v);
        const uint8_t sec = magcal_cont_sector(&h, &v[0]);
        cc->fz_cover[sec / 32u] |= 1u << (sec % 32u);
        if (fabsf(rel) <= 0.1f) {
            cc->fit_acc[0] += rel * rel;
            cc->fit_acc[2] += 1.0f;
            if (cc->sl_on != 0u) {
                magcal_cont_slope_res(cc, &h, m->z);
            }
        }
    }
}

/* The next model form after a failed one (u^2, then u dropped); 1 when none is left. The form
 * without u^2 takes its sums from the full form's (the same products in the same order: its
 * normal matrix is the full one without row and column 2), so only the form without u (whose
 * right-hand side holds the earlier model's u terms) needs a pass of its own. */
static int cont_fit_next_form(magcal_cont_t *cc)
{
    static const uint8_t keep[6] = {0u, 1u, 3u, 4u, 5u, 6u};
    cc->fit_skip++;
    if (cc->fit_skip >= 3u) {
        cc->fit_phase = (uint8_t)CONT_FIT_NONE;
        return 1;
    }
    if (cc->fit_skip == 1u && cc->fit_phase == (uint8_t)CONT_FIT_CHOL) {
        uint32_t r;
        /* the full form's sums had enough samples (so does this form: the same samples) */
        for (r = 0u; r < 6u; ++r) {
            uint32_t c;
            for (c = 0u; c <= r; ++c) {
                cc->fz_l[r * (r + 1u) / 2u + c] = cc->fit_a[keep[r] * (keep[r] + 1u) / 2u + keep[c]];
            }
            cc->fit_b[r] = cc->fit_b0[keep[r]];
        }
        return 0; /* phase CHOL */
    }
    cont_fit_pass(cc, (uint8_t)CONT_FIT_SUMS);
    return 0;
}

/* The Cholesky solve of the current form; on success the model's coefficients, then the cover
 * pass. 1 when the fit ended (no form left). */
static int cont_fit_chol(magcal_cont_t *cc)
{
    const uint32_t skip = cc->fit_skip;
    const uint32_t nf = 7u - skip;
    const float *b = cc->fit_b;
    uint32_t k;
    if (!(cont_fz_chol_solve(cc, nf, cc->fit_b) != 0 && b[0] > 0.0f && (skip != 0u || b[2] < 0.0f))) {
        return cont_fit_next_form(cc);
    }
    cc->fz_skip = (uint8_t)skip;
    cc->fz_abc[0] = b[0];
    if (skip < 2u) {
        cc->fz_abc[1] = b[1];
        cc->fz_abc[2] = skip < 1u ? b[2] : 0.0f;
        cc->fz_u_prior[0] = cc->fz_abc[1];
        cc->fz_u_prior[1] = cc->fz_abc[2];
        cc->fz_have_u = 1u;
    } else {
        cc->fz_abc[1] = cc->fz_have_u != 0u ? cc->fz_u_prior[0] : 0.0f;
        cc->fz_abc[2] = cc->fz_have_u != 0u ? cc->fz_u_prior[1] : 0.0f;
    }
    for (k = 0u; k < 4u; ++k) {
        cc->fz_hxy[k] = b[nf - 4u + k];
    }
    cc->fz_cover[0] = 0u; /* set by the sigma pass */
    cc->fz_cover[1] = 0u;
    cont_fit_pass(cc, (uint8_t)CONT_FIT_SIGMA);
    return 0;
}

/* A pass reached the store's end: the next phase. 1 when the fit ended. */
static int cont_fit_pass_end(magcal_cont_t *cc)
{
    const float n = cc->fit_acc[2];
    if (cc->fit_phase == (uint8_t)CONT_FIT_Z) {
        float var;
        if (n < CONT_FZ_MIN_N || !(cc->cal_raw_radius > 0.0f) || !(cc->cal.radius > 0.0f)) {
            cc->fit_phase = (uint8_t)CONT_FIT_NONE;
            return 1;
        }
        if (cc->sl_on != 0u) {
            magcal_cont_slope_solve(cc);
        }
        cc->fz_u0 = cc->fit_acc[0] / n;
        var = cc->fit_acc[1] / n - cc->fz_u0 * cc->fz_u0;
        cc->fz_u_sd = sqrtf(fmaxf(var, 0.0f)) / cc->cal_raw_radius;
        cc->fit_skip = (uint8_t)(!(var > (0.02f * cc->cal_raw_radius) * (0.02f * cc->cal_raw_radius)) ? 2u : 0u);
        cont_fit_pass(cc, (uint8_t)CONT_FIT_SUMS);
        return 0;
    }
    if (cc->fit_phase == (uint8_t)CONT_FIT_SUMS) {
        if (n >= CONT_FZ_MIN_N) {
            uint32_t p;
            for (p = 0u; p < 28u; ++p) {
                cc->fit_a[p] = cc->fz_l[p]; /* kept for the form without u^2 (cont_fit_next_form) */
            }
            for (p = 0u; p < 7u; ++p) {
                cc->fit_b0[p] = cc->fit_b[p];
            }
            cc->fit_phase = (uint8_t)CONT_FIT_CHOL;
            return 0;
        }
        return cont_fit_next_form(cc);
    }
    if (cc->fit_phase == (uint8_t)CONT_FIT_SIGMA) {
        /* sigma pass: the judge's noise on the store; the model is on only with it */
        const float sg = n >= CONT_FZ_MIN_N ? sqrtf(cc->fit_acc[0] / n) : 0.0f;
        if (!(sg > 0.0f)) {
            cc->fit_phase = (uint8_t)CONT_FIT_NONE;
            return 1;
        }
        cc->cal_sigma_rel = sg;
        if (cc->sl_on != 0u && magcal_cont_slope_refit(cc) != 0) {
            cont_fit_pass(cc, (uint8_t)CONT_FIT_SLOPE); /* the store's slopes (cont_slope.c) */
            return 0;
        }
    } else {
        magcal_cont_slope_end(cc); /* the slope pass ended */
    }
    cc->fit_phase = (uint8_t)CONT_FIT_NONE;
    cc->fz_on = 1u;
    magcal_cont_transient_reset(cc);
    return 1;
}

/* The judge's model at an adoption (file comment): the total-field form with its u terms when
 * the store's raw z spreads by at least 2 % of the raw radius (u^2 kept only when physical,
 * c2 < 0), else the shape form with the u terms of the last model that determined them (the
 * vertical field survives a re-magnetised chassis; a store filled on the flat after a relearn
 * cannot tell them) or without u; c0 > 0. Then the sectors the store covers and the judge's
 * noise on the store. At most five passes over the store slots (z and cover, up to three sums,
 * sigma), in slices (cont_internal.h). */
void magcal_cont_fit_begin(magcal_cont_t *cc)
{
    uint32_t k;
    cc->fz_on = 0u;
    /* the slopes are measured only while no gravity ever came (cont_slope.c): with gravity the
     * fit is what it was, pass for pass */
    cc->sl_on = (uint8_t)magcal_cont_no_gravity(cc);
    cc->sl_ok = CONT_SL_NONE;
    for (k = 0u; k < CONT_SL_ACC; ++k) {
        cc->sl_acc[k] = 0.0f;
    }
    /* the judge's condition on the calibration (cont_corrected), once for the whole fit */
    cc->fit_cal_ok = (uint8_t)(cc->has_cal != 0u && magcal_cal2d_validate(&cc->cal) == MAGCAL_OK && cc->cal.radius > 0.0f
                                   ? 1u
                                   : 0u);
    cont_fit_pass(cc, (uint8_t)CONT_FIT_Z);
}

int magcal_cont_fit_step(magcal_cont_t *cc, magcal_cal_budget_t *b)
{
    const magcal_intake_t *st = &cc->store;
    int spent = 0;
    while (cc->fit_phase != (uint8_t)CONT_FIT_NONE) {
        if (spent != 0) {
            return 0;
        }
        if (cc->fit_phase == (uint8_t)CONT_FIT_CHOL) {
            spent = magcal_cal_spend(b, CONT_W_FIT_CHOL);
            if (cont_fit_chol(cc) != 0) {
                return 1;
            }
        } else if (cc->fit_bin >= st->n_bins) {
            if (cont_fit_pass_end(cc) != 0) {
                return 1;
            }
        } else if (cc->fit_k >= st->count[cc->fit_bin]) {
            cc->fit_bin++;
            cc->fit_k = 0u;
            spent = magcal_cal_spend(b, CONT_W_FIT_BIN);
        } else {
            const uint8_t ph = cc->fit_phase;
            uint32_t sl = 0u;
            if (cc->sl_on != 0u) {
                sl = CONT_W_FIT_SL;
            }
            cont_fit_sample(cc, &st->slots[cc->fit_bin * st->cfg.per_bin + cc->fit_k].m);
            cc->fit_k++;
            spent = magcal_cal_spend(b, ph == (uint8_t)CONT_FIT_Z       ? CONT_W_FIT_Z + sl
                                        : ph == (uint8_t)CONT_FIT_SUMS  ? CONT_W_FIT_SUM
                                        : ph == (uint8_t)CONT_FIT_SLOPE ? CONT_W_FIT_SLOPE
                                                                        : CONT_W_FIT_SIGMA + sl);
        }
    }
    return 1;
}
