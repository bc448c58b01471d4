/*
 * Continuous calibrator, the per-sample judge (docs/calibrator.md "Judge and change detection"):
 * every drained sample (and every heading) is judged under the installed calibration by its
 * relative residual `rel` against the judge's field model (cont_judge_internal.h; fitted at each
 * adoption, cont_fzfit.c), or |h| / R - 1 without one. Every threshold is widened by
 * sqrt(1 + unc), unc = the model's prediction variance at the sample over its noise variance
 * (f^T (F^T F)^-1 f): one circle cannot separate the pitch from the calibration's shape.
 *  - per sample: |rel| > max(cfg.mismatch_k sigma, cfg.mismatch_min_rel) (sigma = the relative
 *    residual of the model on the store) is a mismatch: the sample is not stored;
 *  - change evidence (`gross`, what an episode counts, cont_change.c): |rel| beyond twice the
 *    threshold widened by at most sqrt(1 + CONT_CHANGE_UNC), or a raw z beyond the reach of a
 *    road's pitch from the store's;
 *  - sectors the store did not cover at the fit are stored, not judged per sample (the
 *    transient flag, cont_flags.c, and a z out of reach of pitch still flag them).
 */
#include "cont_judge_internal.h"

#define CONT_CHANGE_X 2.0f        /* a change counts samples beyond this x the per-sample threshold */
#define CONT_CHANGE_UNC 3.0f      /* the change threshold widens by at most sqrt(1 + this) */
#define CONT_U_SD_K 3.0f          /* z within this x the store's spread of u ... */
#define CONT_EPISODE_ON_MS 1000u  /* mismatch time of an episode that turns the per-sample test back on */
#define CONT_U_PITCH 0.25f        /* ... plus this x R (a 6 deg hill moves z by ~0.11 R, 8.5 deg by 0.15 R) */

/* Prediction variance of the model at a sample over its noise variance: |L^-1 f|^2 with f the
 * scaled features and L the Cholesky factor of the store's scaled normal matrix (F^T F). Large
 * where the store could not separate the pitch from the calibration's shape (u collinear with
 * the heading terms), or outside the pitch range the store saw. */
static float cont_fz_unc(const magcal_cont_t *cc, float u, float hx, float hy)
{
    float f[7];
    float w[7];
    float q = 0.0f;
    const uint32_t nf = magcal_cont_fz_feat(u, hx, hy, cc->fz_skip, f);
    uint32_t p;
    uint32_t k;
    for (p = 0u; p < nf; ++p) {
        float v = f[p] / cc->fz_s[p];
        for (k = 0u; k < p; ++k) {
            v -= cc->fz_l[p * (p + 1u) / 2u + k] * w[k];
        }
        w[p] = v / cc->fz_l[p * (p + 1u) / 2u + p];
        q += w[p] * w[p];
    }
    return q;
}

/* Per-sample threshold on |rel|. */
static float cont_threshold(const magcal_cont_t *cc)
{
    return fmaxf(cc->cfg.mismatch_k * cc->cal_sigma_rel, cc->cfg.mismatch_min_rel);
}

/* Corrected x, y of a raw sample under the installed calibration: 1 when defined. */
static int cont_corrected(const magcal_cont_t *cc, const magcal_vec3_t *m, magcal_vec2_t *h)
{
    magcal_vec2_t raw;
    raw.x = m->x;
    raw.y = m->y;
    return cc->has_cal != 0u && magcal_correct_apply(&cc->cal, raw, h) == MAGCAL_OK && cc->cal.radius > 0.0f;
}

int magcal_cont_judge(const magcal_cont_t *cc, const magcal_vec3_t *m, int radius, magcal_cont_judge_t *j)
{
    magcal_vec2_t h;
    float thr;
    j->rel = NAN;
    j->heading = 0.0f;
    j->sector = 0u;
    j->unc = 0.0f;
    j->mismatch = 0u;
    j->gross = 0u;
    j->over = 0u;
    j->tilted = 0u;
    j->u = NAN;
    j->cs[0] = 1.0f;
    j->cs[1] = 0.0f;
    if (cont_corrected(cc, m, &h) == 0) {
        return 0;
    }
    {
        /* the transient judge's inputs: raw z in radii, the heading's unit vector (heading.c:
         * atan2(-x, y)) */
        const float nh = sqrtf(h.x * h.x + h.y * h.y);
        if (nh > 0.0f) {
            j->cs[0] = h.y / nh;
            j->cs[1] = -h.x / nh;
        }
        if (cc->cal_raw_radius > 0.0f) {
            j->u = m->z / cc->cal_raw_radius;
        }
    }
    if (cc->fz_on != 0u && radius == 0) {
        float v[3];
        j->rel = magcal_cont_fz_rel(cc, &h, m->z, v);
        j->unc = cont_fz_unc(cc, v[2], v[0], v[1]);
        /* a raw z no pitch of a road can reach from the store's (a hard-iron change in z): the
         * model would only be extrapolated there, so it is evidence of a change, not uncertainty */
        if (!(fabsf(v[2]) <= CONT_U_SD_K * cc->fz_u_sd + CONT_U_PITCH)) {
            j->gross = 1u;
        }
    } else {
        j->rel = sqrtf(h.x * h.x + h.y * h.y) / cc->cal.radius - 1.0f;
    }
    j->sector = magcal_cont_sector(&h, &j->heading);
    thr = cont_threshold(cc) * sqrtf(1.0f + j->unc);
    if (cc->fz_on != 0u && ((cc->fz_cover[j->sector / 32u] >> (j->sector % 32u)) & 1u) == 0u) {
        /* a sector the store did not cover: the calibration and the model are extrapolated
         * there; such samples are what the next solve needs, so the per-sample test does not
         * judge them (they are stored), but the transient judge's flag and a z out of reach of
         * pitch still do (a 45 % disturbance of a parked car in such a sector was trusted), and
         * a field CONT_GLITCH_REL off R, which no extrapolation explains (a sensor rail there was
         * OK at 109 deg: 30-min seed 34, tests/test_cont_trust_gaps.c) */
        j->mismatch = (uint8_t)((j->gross != 0u || cc->dist_flag != 0u || !(fabsf(j->rel) <= CONT_GLITCH_REL)) ? 1u : 0u);
        return 1;
    }
    /* a change counts samples beyond twice the per-sample threshold, widened for the model's
     * extrapolation at most by sqrt(1 + CONT_CHANGE_UNC): a hard-iron step moves raw z (u) far
     * outside the store, where the unbounded widening made the step look merely uncertain */
    if (!(fabsf(j->rel) <= CONT_CHANGE_X * cont_threshold(cc) * sqrtf(1.0f + fminf(j->unc, CONT_CHANGE_UNC)))) {
        j->gross = 1u;
    }
    /* the transient judge's flag (state of the stream up to the last drained sample) counts too */
    j->over = (uint8_t)(!(fabsf(j->rel) <= thr) ? 1u : 0u);
    /* an open episode with more mismatch than a glitch burst (evidence of a change) keeps the
     * per-sample test on whatever its health: a burst of 5..40 rail or garbage rows alone opened
     * it and flagged the clean rows of a poorly fitted model for the clear_ms after (seeds 1, 3:
     * 100..400 rows per burst) */
    j->mismatch = (uint8_t)((j->gross != 0u ||
                             (j->over != 0u && (cc->fz_unfit == 0u ||
                                                (cc->episode_open != 0u && cc->mis_ms >= CONT_EPISODE_ON_MS))) ||
                             cc->dist_flag != 0u)
                                ? 1u
                                : 0u);
    return 1;
}
