/*
 * The 2-D calibration pipeline object: configuration, collection (live coverage), lifecycle and
 * the per-sample queries. The solve itself (filter, consensus, fit, gates, adoption; time-sliced)
 * is in calibrator_solve.c, its estimates in calibrator_adopt.c. See include/magcal/calibrator.h
 * for the pipeline, the gates and the adoption rule.
 */
#include "magcal/calibrator.h"

#include <math.h>
#include <stdint.h>
#include <string.h>

#include "calibrator_internal.h"
#include "magcal_internal.h"

#define CAL_MAGIC MAGCAL_CALIBRATOR_MAGIC
#define CAL_BIN_DEG (360.0f / (float)MAGCAL_COVERAGE_BINS)

/* ------------------------------------------------------------------ small helpers */

/* Approximate heading of u (raw, around a centre): atan2(-u.x, u.y) in [0, 360). */
float magcal_cal_angle_deg(float ux, float uy)
{
    float a = magcal_atan2f(-ux, uy) * MAGCAL_DEG_PER_RAD_F;
    if (a < 0.0f) {
        a += 360.0f;
    }
    if (a >= 360.0f) {
        a = 0.0f;
    }
    return a;
}

size_t magcal_cal_bin_of(float deg)
{
    size_t b = (size_t)(deg / CAL_BIN_DEG);
    return b >= MAGCAL_COVERAGE_BINS ? MAGCAL_COVERAGE_BINS - 1u : b;
}

/* Coverage of a bin occupancy table: covered degrees, largest empty circular run. */
float magcal_cal_coverage_of(const uint16_t *bins, float *miss_start, float *miss_width)
{
    size_t filled = 0u;
    size_t best_len = 0u;
    size_t best_start = 0u;
    size_t b;
    for (b = 0u; b < MAGCAL_COVERAGE_BINS; ++b) {
        if (bins[b] != 0u) {
            ++filled;
        }
    }
    if (filled > 0u && filled < MAGCAL_COVERAGE_BINS) {
        /* start scanning right after a filled bin so circular runs are contiguous */
        size_t s0 = 0u;
        size_t run = 0u;
        size_t run_start = 0u;
        size_t k;
        for (b = 0u; b < MAGCAL_COVERAGE_BINS; ++b) {
            if (bins[b] != 0u) {
                s0 = b + 1u;
                break;
            }
        }
        for (k = 0u; k < MAGCAL_COVERAGE_BINS; ++k) {
            size_t bb = (s0 + k) % MAGCAL_COVERAGE_BINS;
            if (bins[bb] == 0u) {
                if (run == 0u) {
                    run_start = bb;
                }
                ++run;
                if (run > best_len) {
                    best_len = run;
                    best_start = run_start;
                }
            } else {
                run = 0u;
            }
        }
    } else if (filled == 0u) {
        best_len = MAGCAL_COVERAGE_BINS;
    } else {
        /* every bin filled: no missing sector */
    }
    if (miss_start != NULL) {
        *miss_start = (float)best_start * CAL_BIN_DEG;
    }
    if (miss_width != NULL) {
        *miss_width = (float)best_len * CAL_BIN_DEG;
    }
    /* the arc is what the largest empty sector leaves: isolated empty bins between samples of a
     * sparse recording are crossed, not missing */
    return 360.0f - (float)best_len * CAL_BIN_DEG;
}

/* The configuration's float fields and their admitted ranges, as tables (one loop instead of a
 * compare chain per field: flash). Every field is checked finite first (MAGCAL_ERR_NONFINITE),
 * then its range (MAGCAL_ERR_ARG): lower bound CAL_LO_*, upper bound k_hi[]. */
#define CAL_N_FIELDS 16u
#define CAL_LO_GE0 0u /* >= 0 */
#define CAL_LO_GT0 1u /* > 0 */
#define CAL_LO_GE1 2u /* >= 1 */
#define CAL_LO_ANY 3u

static magcal_status_t cal_check_cfg(const magcal_calibrator_cfg_t *c)
{
    /* f[k]'s lower bound kind and upper bound (index into k_hi) */
    static const uint8_t k_lo[CAL_N_FIELDS] = {
        CAL_LO_GE0, CAL_LO_GE0, CAL_LO_GE0, CAL_LO_GE0, CAL_LO_GE0, CAL_LO_GE0, CAL_LO_GE0, CAL_LO_GT0,
        CAL_LO_GE0, CAL_LO_ANY, CAL_LO_GT0, CAL_LO_GE1, CAL_LO_GT0, CAL_LO_GE0, CAL_LO_ANY, CAL_LO_GE0};
    static const uint8_t k_hi_of[CAL_N_FIELDS] = {0u, 2u, 3u, 1u, 1u, 0u, 0u, 0u,
                                                  0u, 0u, 0u, 0u, 0u, 0u, 0u, 1u};
    static const float k_hi[4] = {INFINITY, 1.0f, 90.0f, 360.0f};
    const float f[CAL_N_FIELDS] = {c->eps, c->min_spacing_deg, c->min_coverage_deg,
                                   c->max_outlier_frac, c->min_axis_ratio, c->min_radius,
                                   c->max_radius, c->max_residual_rel, c->max_radius_change,
                                   c->output_radius, c->max_param_err_ratio, c->max_design_factor,
                                   c->consensus.k_sigma, c->consensus.min_thr_rel,
                                   c->consensus.max_thr_rel, c->max_inconsistent_frac};
    size_t k;
    for (k = 0u; k < CAL_N_FIELDS; ++k) {
        if (!magcal_isfinite_f(f[k])) {
            return MAGCAL_ERR_NONFINITE;
        }
    }
    for (k = 0u; k < CAL_N_FIELDS; ++k) {
        const float v = f[k];
        const uint8_t lo = k_lo[k];
        if ((lo == CAL_LO_GE0 && v < 0.0f) || (lo == CAL_LO_GT0 && !(v > 0.0f)) ||
            (lo == CAL_LO_GE1 && v < 1.0f) || v > k_hi[k_hi_of[k]]) {
            return MAGCAL_ERR_ARG;
        }
    }
    if ((unsigned)c->filter > (unsigned)MAGCAL_FILTER_NONE) { /* also catches negative values */
        return MAGCAL_ERR_ARG;
    }
    if (c->min_pts == 1u || c->min_pts > MAGCAL_MAX_MIN_PTS || c->use_consensus > 1u ||
        c->pretest > 1u || c->min_samples < 5u) {
        return MAGCAL_ERR_ARG;
    }
    if (c->consensus.max_iter < 1u || c->consensus.max_iter > MAGCAL_CONSENSUS_MAX_ITER ||
        c->consensus.refine_iter < 1u || c->consensus.refine_iter > MAGCAL_CONSENSUS_MAX_REFINE ||
        !(c->consensus.max_thr_rel > c->consensus.min_thr_rel) ||
        (c->max_radius > 0.0f && c->min_radius > c->max_radius)) {
        return MAGCAL_ERR_ARG;
    }
    if ((unsigned)c->form > (unsigned)MAGCAL_CORR_LAST) {
        return MAGCAL_ERR_ARG;
    }
    return MAGCAL_OK;
}

static int cal_ok(const magcal_calibrator_t *cal) { return cal != NULL && cal->magic == CAL_MAGIC; }

/* Recompute the live coverage bins around the bbox midpoint. */
static void cal_rebin(magcal_calibrator_t *cal)
{
    size_t i;
    float hx = 0.5f * (cal->bb_max.x - cal->bb_min.x);
    float hy = 0.5f * (cal->bb_max.y - cal->bb_min.y);
    cal->centre.x = 0.5f * (cal->bb_min.x + cal->bb_max.x);
    cal->centre.y = 0.5f * (cal->bb_min.y + cal->bb_max.y);
    cal->centre_tol = 0.125f * (hx < hy ? hx : hy);
    (void)memset(cal->bins, 0, sizeof cal->bins);
    for (i = 0u; i < cal->n; ++i) {
        size_t b =
            magcal_cal_bin_of(magcal_cal_angle_deg(cal->buf[i].x - cal->centre.x, cal->buf[i].y - cal->centre.y));
        if (cal->bins[b] < 0xFFFFu) {
            cal->bins[b]++;
        }
    }
}

static void cal_update_state(magcal_calibrator_t *cal)
{
    float cov = magcal_cal_coverage_of(cal->bins, NULL, NULL);
    if (cal->n >= cal->cfg.min_samples && cov >= cal->cfg.min_coverage_deg) {
        cal->state = MAGCAL_CALIBRATOR_READY;
    } else {
        cal->state = MAGCAL_CALIBRATOR_COLLECTING;
    }
}

/* ------------------------------------------------------------------ lifecycle */

magcal_status_t magcal_calibrator_init_checked(magcal_calibrator_t *cal, const magcal_calibrator_cfg_t *cfg,
                                               magcal_vec2_t *sample_buf, size_t capacity, void *work,
                                               size_t work_len, uint32_t config, size_t inst_size)
{
    magcal_status_t st;
    uint8_t *w;
    size_t masks;
    if (magcal_config_check_fingerprint(config) != MAGCAL_OK || inst_size != sizeof *cal) {
        return MAGCAL_ERR_CONFIG_MISMATCH; /* caller's struct layout is not ours: write nothing */
    }
    if (cal == NULL || cfg == NULL || sample_buf == NULL || work == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (capacity < 16u || capacity > MAGCAL_MAX_SAMPLES) {
        return MAGCAL_ERR_ARG;
    }
    if (magcal_misalign(work, 4u) != 0u) {
        return MAGCAL_ERR_ALIGNMENT;
    }
    st = cal_check_cfg(cfg);
    if (st != MAGCAL_OK) {
        return st;
    }
    if ((size_t)cfg->min_samples > capacity) {
        return MAGCAL_ERR_ARG; /* the buffer could never hold enough samples to run */
    }
    if (work_len < MAGCAL_CALIBRATOR_WORKSPACE_LEN(capacity)) {
        return MAGCAL_ERR_WORKSPACE;
    }
    (void)memset(cal, 0, sizeof *cal);
    cal->cfg = *cfg;
    cal->buf = sample_buf;
    cal->capacity = capacity;
    w = (uint8_t *)work;
    masks = MAGCAL_CALIBRATOR_MASKS_LEN(capacity);
    cal->flags = w;
    {
        /* the run state and the scratch hold pointers (slice states): pointer-aligned (a 4-aligned
         * workspace on a 64-bit host needs up to 4 bytes of lead, counted in the size macro) */
        const size_t mis = magcal_misalign(w + masks, sizeof(void *));
        masks += mis != 0u ? sizeof(void *) - mis : 0u;
    }
    cal->run = (void *)(w + masks);
    cal->scratch = (void *)(w + masks + MAGCAL_CALIBRATOR_RUN_LEN);
    cal->scratch_len = work_len - masks - MAGCAL_CALIBRATOR_RUN_LEN;
    /* the two stage masks live behind the consensus workspace, in the stage scratch: they are
     * written after the density filter (the largest scratch user) has finished */
    cal->mask_a = (uint8_t *)cal->scratch + MAGCAL_CONSENSUS_WORKSPACE_LEN(capacity);
    cal->mask_b = cal->mask_a + capacity;
    cal->magic = CAL_MAGIC;
    return magcal_calibrator_reset(cal);
}

magcal_status_t magcal_calibrator_reset(magcal_calibrator_t *cal)
{
    if (cal == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (!cal_ok(cal)) {
        return MAGCAL_ERR_NOT_INITIALISED;
    }
    cal->n = 0u;
    cal->n_judged = 0u;
    cal->has_fit = 0u;
    cal->threshold = 0.0f;
    cal->last_bin_deg10 = -1;
    cal->centre_tol = 0.0f;
    (void)memset(cal->bins, 0, sizeof cal->bins);
    cal->state = MAGCAL_CALIBRATOR_COLLECTING;
    cal->last_status = MAGCAL_OK;
    return MAGCAL_OK;
}

magcal_status_t magcal_calibrator_push(magcal_calibrator_t *cal, magcal_vec2_t p)
{
    float ang;
    size_t b;
    if (cal == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (!cal_ok(cal)) {
        return MAGCAL_ERR_NOT_INITIALISED;
    }
    if (!magcal_isfinite_f(p.x) || !magcal_isfinite_f(p.y)) {
        return MAGCAL_ERR_NONFINITE;
    }
    if (cal->n >= cal->capacity) {
        return MAGCAL_ERR_BUFFER_FULL;
    }
    ang = magcal_cal_angle_deg(p.x - cal->centre.x, p.y - cal->centre.y);
    b = magcal_cal_bin_of(ang);
    if (cal->n > 0u) {
        if (cal->cfg.min_spacing_deg > 0.0f && cal->last_bin_deg10 >= 0) {
            float d = fabsf(magcal_wrap180_deg(ang - 0.1f * (float)cal->last_bin_deg10));
            if (d < cal->cfg.min_spacing_deg) {
                return MAGCAL_ERR_GATED;
            }
        }
        if (cal->cfg.max_per_bin > 0u && cal->bins[b] >= cal->cfg.max_per_bin) {
            return MAGCAL_ERR_GATED;
        }
    }
    cal->buf[cal->n] = p;
    cal->n++;
    if (cal->n == 1u) {
        cal->bb_min = p;
        cal->bb_max = p;
    } else {
        if (p.x < cal->bb_min.x) {
            cal->bb_min.x = p.x;
        }
        if (p.y < cal->bb_min.y) {
            cal->bb_min.y = p.y;
        }
        if (p.x > cal->bb_max.x) {
            cal->bb_max.x = p.x;
        }
        if (p.y > cal->bb_max.y) {
            cal->bb_max.y = p.y;
        }
    }
    {
        float mx = 0.5f * (cal->bb_min.x + cal->bb_max.x);
        float my = 0.5f * (cal->bb_min.y + cal->bb_max.y);
        float dx = mx - cal->centre.x;
        float dy = my - cal->centre.y;
        if (cal->n == 1u || dx * dx + dy * dy > cal->centre_tol * cal->centre_tol) {
            cal_rebin(cal); /* the provisional centre moved: re-bin every stored sample */
        } else if (cal->bins[b] < 0xFFFFu) {
            cal->bins[b]++;
        } else {
            /* bin count saturated */
        }
    }
    ang = magcal_cal_angle_deg(p.x - cal->centre.x, p.y - cal->centre.y);
    cal->last_bin_deg10 = (int32_t)(ang * 10.0f);
    if (cal->state != MAGCAL_CALIBRATOR_CALIBRATED && cal->state != MAGCAL_CALIBRATOR_FAILED) {
        cal_update_state(cal);
    }
    return MAGCAL_OK;
}

/* ------------------------------------------------------------------ queries */

/* Shared argument and state checks of the per-sample queries: need_fit selects whether a final
 * fit (inlier) or only a judged run (flags) is required. */
static magcal_status_t cal_query_check(const magcal_calibrator_t *cal, const void *out, size_t i,
                                       uint8_t need_fit)
{
    if (cal == NULL || out == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (!cal_ok(cal)) {
        return MAGCAL_ERR_NOT_INITIALISED;
    }
    if ((need_fit != 0u) ? (cal->has_fit == 0u) : (cal->n_judged == 0u)) {
        return MAGCAL_ERR_STATE;
    }
    if (i >= cal->n_judged) {
        return MAGCAL_ERR_ARG;
    }
    return MAGCAL_OK;
}

magcal_status_t magcal_calibrator_flags(const magcal_calibrator_t *cal, size_t i, uint8_t *flags)
{
    magcal_status_t st = cal_query_check(cal, flags, i, 0u);
    if (st != MAGCAL_OK) {
        return st;
    }
    *flags = cal->flags[i];
    return MAGCAL_OK;
}

magcal_status_t magcal_calibrator_inlier(const magcal_calibrator_t *cal, size_t i, int *is_inlier)
{
    magcal_status_t st = cal_query_check(cal, is_inlier, i, 1u);
    if (st != MAGCAL_OK) {
        return st;
    }
    if ((cal->flags[i] & MAGCAL_CALIBRATOR_FLAG_RESIDUAL) != 0u) {
        *is_inlier = 0;
    } else {
        *is_inlier = 1;
    }
    return MAGCAL_OK;
}

magcal_status_t magcal_calibrator_classify(const magcal_calibrator_t *cal, magcal_vec2_t p,
                                           int *is_outlier)
{
    float r;
    if (cal == NULL || is_outlier == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (!cal_ok(cal)) {
        return MAGCAL_ERR_NOT_INITIALISED;
    }
    if (!magcal_isfinite_f(p.x) || !magcal_isfinite_f(p.y)) {
        return MAGCAL_ERR_NONFINITE;
    }
    if (cal->has_fit == 0u) {
        return MAGCAL_ERR_STATE;
    }
    r = magcal_ellipse_residual(&cal->fit, p);
    if (magcal_isfinite_f(r) && fabsf(r) <= cal->threshold) {
        *is_outlier = 0;
    } else {
        *is_outlier = 1;
    }
    return MAGCAL_OK;
}

const char *magcal_adopt_rule_str(magcal_adopt_rule_t rule)
{
    switch (rule) {
    case MAGCAL_ADOPT_NONE: return "none";
    case MAGCAL_ADOPT_UNUSABLE: return "unusable";
    case MAGCAL_ADOPT_BETTER: return "better";
    case MAGCAL_ADOPT_STALE: return "stale";
    default: return "unknown";
    }
}

magcal_calibrator_state_t magcal_calibrator_state(const magcal_calibrator_t *cal)
{
    return cal_ok(cal) ? cal->state : MAGCAL_CALIBRATOR_INVALID;
}

magcal_status_t magcal_calibrator_last_status(const magcal_calibrator_t *cal)
{
    return cal_ok(cal) ? cal->last_status : MAGCAL_ERR_NOT_INITIALISED;
}

size_t magcal_calibrator_count(const magcal_calibrator_t *cal) { return cal_ok(cal) ? cal->n : 0u; }

float magcal_calibrator_coverage_deg(const magcal_calibrator_t *cal)
{
    return cal_ok(cal) ? magcal_cal_coverage_of(cal->bins, NULL, NULL) : 0.0f;
}
