/*
 * The 2-D calibration pipeline object: collect, filter (OPTICS/DBSCAN), consensus, fit, gate,
 * adopt. See include/magcal/calibrator.h for the pipeline, the gates and the adoption rule.
 */
#include "magcal/calibrator.h"

#include <float.h>
#include <math.h>
#include <string.h>

#include "calibrator_internal.h"
#include "magcal_internal.h"

#define CAL_MAGIC MAGCAL_CALIBRATOR_MAGIC
#define CAL_BIN_DEG (360.0f / (float)MAGCAL_COVERAGE_BINS)
#define CAL_SHIFT_STEPS 72u /* heading shift evaluated every 5 degrees (cal_sincos5) */
#define CAL_COLLINEAR_TOL 1.0e-6f

/* State of one run(), kept in the workspace: the deepest stack paths of run() go through the
 * filter and the consensus fits, so run()'s own frame must stay small. */
typedef struct {
    magcal_cal_report_t rep;
    magcal_consensus_result_t cres;
    magcal_cal2d_t next;
    magcal_optics_cfg_t oc;
    magcal_optics_result_t info;
    magcal_dbscan_cfg_t dc;
} cal_run_t;

/* cppcheck-suppress misra-c2012-2.3 ; deviation D4: a static assert is an unused typedef */
MAGCAL_STATIC_ASSERT(sizeof(cal_run_t) <= MAGCAL_CALIBRATOR_RUN_LEN, run_state_fits_workspace);

/* ------------------------------------------------------------------ small helpers */

/* Approximate heading of u (raw, around a centre): atan2(-u.x, u.y) in [0, 360). */
static float cal_angle_deg(float ux, float uy)
{
    float a = atan2f(-ux, uy) * MAGCAL_DEG_PER_RAD_F;
    if (a < 0.0f) {
        a += 360.0f;
    }
    if (a >= 360.0f) {
        a = 0.0f;
    }
    return a;
}

static size_t cal_bin_of(float deg)
{
    size_t b = (size_t)(deg / CAL_BIN_DEG);
    return b >= MAGCAL_COVERAGE_BINS ? MAGCAL_COVERAGE_BINS - 1u : b;
}

/* Coverage of a bin occupancy table: covered degrees, largest empty circular run. */
static float cal_coverage_of(const uint16_t *bins, float *miss_start, float *miss_width)
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

static int cal_finite_cfg_f(float v) { return magcal_isfinite_f(v); }

static magcal_status_t cal_check_cfg(const magcal_calibrator_cfg_t *c)
{
    if (!cal_finite_cfg_f(c->eps) || !cal_finite_cfg_f(c->min_spacing_deg) ||
        !cal_finite_cfg_f(c->min_coverage_deg) || !cal_finite_cfg_f(c->max_outlier_frac) ||
        !cal_finite_cfg_f(c->min_axis_ratio) || !cal_finite_cfg_f(c->min_radius) ||
        !cal_finite_cfg_f(c->max_radius) || !cal_finite_cfg_f(c->max_residual_rel) ||
        !cal_finite_cfg_f(c->max_radius_change) || !cal_finite_cfg_f(c->output_radius) ||
        !cal_finite_cfg_f(c->max_param_err_ratio) || !cal_finite_cfg_f(c->max_design_factor) ||
        !cal_finite_cfg_f(c->consensus.k_sigma) || !cal_finite_cfg_f(c->consensus.min_thr_rel) ||
        !cal_finite_cfg_f(c->consensus.max_thr_rel)) {
        return MAGCAL_ERR_NONFINITE;
    }
    if ((unsigned)c->filter > (unsigned)MAGCAL_FILTER_NONE) { /* also catches negative values */
        return MAGCAL_ERR_ARG;
    }
    if (c->eps < 0.0f || c->min_pts == 1u || c->min_pts > MAGCAL_MAX_MIN_PTS) {
        return MAGCAL_ERR_ARG;
    }
    if (c->use_consensus > 1u) {
        return MAGCAL_ERR_ARG;
    }
    if (c->consensus.max_iter < 1u || c->consensus.max_iter > MAGCAL_CONSENSUS_MAX_ITER ||
        c->consensus.refine_iter < 1u || c->consensus.refine_iter > MAGCAL_CONSENSUS_MAX_REFINE ||
        !(c->consensus.k_sigma > 0.0f) || c->consensus.min_thr_rel < 0.0f ||
        !(c->consensus.max_thr_rel > c->consensus.min_thr_rel)) {
        return MAGCAL_ERR_ARG;
    }
    if (c->min_spacing_deg < 0.0f || c->min_spacing_deg > 90.0f || c->min_samples < 5u ||
        c->min_coverage_deg < 0.0f || c->min_coverage_deg > 360.0f || c->max_outlier_frac < 0.0f ||
        c->max_outlier_frac > 1.0f || c->min_axis_ratio < 0.0f || c->min_axis_ratio > 1.0f ||
        c->min_radius < 0.0f || c->max_radius < 0.0f ||
        (c->max_radius > 0.0f && c->min_radius > c->max_radius) || !(c->max_residual_rel > 0.0f) ||
        c->max_radius_change < 0.0f || !(c->max_param_err_ratio > 0.0f) ||
        !(c->max_design_factor >= 1.0f)) {
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
            cal_bin_of(cal_angle_deg(cal->buf[i].x - cal->centre.x, cal->buf[i].y - cal->centre.y));
        if (cal->bins[b] < 0xFFFFu) {
            cal->bins[b]++;
        }
    }
}

static void cal_update_state(magcal_calibrator_t *cal)
{
    float cov = cal_coverage_of(cal->bins, NULL, NULL);
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
    ang = cal_angle_deg(p.x - cal->centre.x, p.y - cal->centre.y);
    b = cal_bin_of(ang);
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
    ang = cal_angle_deg(p.x - cal->centre.x, p.y - cal->centre.y);
    cal->last_bin_deg10 = (int32_t)(ang * 10.0f);
    if (cal->state != MAGCAL_CALIBRATOR_CALIBRATED && cal->state != MAGCAL_CALIBRATOR_FAILED) {
        cal_update_state(cal);
    }
    return MAGCAL_OK;
}

/* ------------------------------------------------------------------ run() stages */

/* All identical samples (checked before the density filter: far outliers cannot fake it). */
static int cal_identical(const magcal_vec2_t *p, size_t n)
{
    size_t i;
    for (i = 1u; i < n; ++i) {
        if (p[i].x != p[0].x || p[i].y != p[0].y) {
            return 0;
        }
    }
    return 1;
}

/* Masked samples (mask NULL: all) identical or collinear: smaller covariance eigenvalue vs larger.
 * Run on the density-filter inliers: before the filter, two glitch samples 1e5 R away made a
 * clean ring look collinear (eigenvalue ratio ~1e-8). */
static int cal_degenerate(const magcal_vec2_t *p, size_t n, const uint8_t *mask)
{
    float mx = 0.0f;
    float my = 0.0f;
    float sxx = 0.0f;
    float syy = 0.0f;
    float sxy = 0.0f;
    float tr;
    float det;
    float disc;
    float l1;
    float l2;
    float s = 0.0f;
    float fm;
    size_t m = 0u;
    size_t i;
    for (i = 0u; i < n; ++i) {
        if (mask == NULL || mask[i] != 0u) {
            ++m;
        }
    }
    if (m == 0u) {
        return 1;
    }
    fm = (float)m;
    /* mean of p/m and deviations scaled by their largest magnitude: the sums cannot overflow
     * (a ring of radius 1e18 overflowed sxx to Inf and was called degenerate) */
    for (i = 0u; i < n; ++i) {
        if (mask == NULL || mask[i] != 0u) {
            mx += p[i].x / fm;
            my += p[i].y / fm;
        }
    }
    for (i = 0u; i < n; ++i) {
        if (mask == NULL || mask[i] != 0u) {
            s = fmaxf(s, fmaxf(fabsf(p[i].x - mx), fabsf(p[i].y - my)));
        }
    }
    if (!(s > 0.0f) || !magcal_isfinite_f(s)) {
        return 1; /* all identical, or a spread float32 cannot represent */
    }
    for (i = 0u; i < n; ++i) {
        if (mask == NULL || mask[i] != 0u) {
            float dx = (p[i].x - mx) / s;
            float dy = (p[i].y - my) / s;
            sxx += dx * dx;
            syy += dy * dy;
            sxy += dx * dy;
        }
    }
    tr = sxx + syy;
    if (!(tr > 0.0f)) {
        return 1;
    }
    det = sxx * syy - sxy * sxy;
    disc = sqrtf(fmaxf(0.25f * tr * tr - det, 0.0f));
    l1 = 0.5f * tr + disc;
    l2 = 0.5f * tr - disc;
    return l2 <= CAL_COLLINEAR_TOL * l1;
}

/* Hard-iron circle fit x^2 + y^2 + C x + D y + E = 0 of the masked points (centred, scaled). */
static MAGCAL_NOINLINE magcal_status_t cal_circle_centre(const magcal_vec2_t *p, size_t n,
                                                         const uint8_t *mask, magcal_vec2_t *centre)
{
    float mx = 0.0f;
    float my = 0.0f;
    float s = 0.0f;
    float a[9];
    float b[3];
    size_t i;
    size_t m = 0u;
    magcal_status_t st;
    for (i = 0u; i < n; ++i) {
        if (mask[i] != 0u) {
            ++m;
        }
    }
    if (m < 3u) {
        return MAGCAL_ERR_TOO_FEW_POINTS;
    }
    /* mean of p/m: summing p overflowed to Inf for samples near FLT_MAX (NaN centre, and the
     * solver's NONFINITE reached run(), which does not document it) */
    for (i = 0u; i < n; ++i) {
        if (mask[i] != 0u) {
            mx += p[i].x / (float)m;
            my += p[i].y / (float)m;
        }
    }
    for (i = 0u; i < n; ++i) {
        if (mask[i] != 0u) {
            float d = fmaxf(fabsf(p[i].x - mx), fabsf(p[i].y - my));
            s = fmaxf(s, d);
        }
    }
    if (!(s > 0.0f)) {
        return MAGCAL_ERR_DEGENERATE;
    }
    if (!magcal_isfinite_f(s)) {
        return MAGCAL_ERR_ILL_CONDITIONED; /* spread beyond float32: reported as DEGENERATE */
    }
    (void)memset(a, 0, sizeof a);
    (void)memset(b, 0, sizeof b);
    for (i = 0u; i < n; ++i) {
        if (mask[i] != 0u) {
            float u = (p[i].x - mx) / s;
            float v = (p[i].y - my) / s;
            float w[3];
            float y = -(u * u + v * v);
            size_t r;
            size_t c;
            w[0] = u;
            w[1] = v;
            w[2] = 1.0f;
            for (r = 0u; r < 3u; ++r) {
                for (c = 0u; c <= r; ++c) {
                    a[r * 3u + c] += w[r] * w[c];
                }
                b[r] += w[r] * y;
            }
        }
    }
    st = magcal_ldlt_solve(a, b, 3u, 1.0e-6f, NULL);
    if (st != MAGCAL_OK) {
        return st;
    }
    centre->x = mx - 0.5f * b[0] * s;
    centre->y = my - 0.5f * b[1] * s;
    return MAGCAL_OK;
}

/* Bins of the masked (NULL: all) points' approximate headings around centre. */
static MAGCAL_NOINLINE float cal_coverage_around(const magcal_vec2_t *p, size_t n,
                                                 const uint8_t *mask, magcal_vec2_t c,
                                                 float *miss_start, float *miss_width)
{
    uint16_t bins[MAGCAL_COVERAGE_BINS];
    size_t i;
    (void)memset(bins, 0, sizeof bins);
    for (i = 0u; i < n; ++i) {
        if (mask == NULL || mask[i] != 0u) {
            bins[cal_bin_of(cal_angle_deg(p[i].x - c.x, p[i].y - c.y))] = 1u;
        }
    }
    return cal_coverage_of(bins, miss_start, miss_width);
}

/* Bins of the corrected headings of the masked points (coverage of the final calibration). */
static MAGCAL_NOINLINE float cal_coverage_corrected(const magcal_vec2_t *p, size_t n,
                                                    const uint8_t *mask, const magcal_cal2d_t *c,
                                                    float *miss_start, float *miss_width)
{
    uint16_t bins[MAGCAL_COVERAGE_BINS];
    size_t i;
    (void)memset(bins, 0, sizeof bins);
    for (i = 0u; i < n; ++i) {
        magcal_vec2_t h;
        if (mask[i] != 0u && magcal_correct_apply(c, p[i], &h) == MAGCAL_OK) {
            bins[cal_bin_of(cal_angle_deg(h.x, h.y))] = 1u;
        }
    }
    return cal_coverage_of(bins, miss_start, miss_width);
}

/* Density filter: its 0/1 inlier mask into cal->flags (the scratch is in use until it returns). */
static MAGCAL_NOINLINE magcal_status_t cal_filter(magcal_calibrator_t *cal,
                                                  magcal_cal_report_t *rep)
{
    cal_run_t *run = (cal_run_t *)cal->run;
    const magcal_calibrator_cfg_t *c = &cal->cfg;
    size_t n = cal->n;
    magcal_status_t st;
    if (c->filter == MAGCAL_FILTER_NONE || (c->eps <= 0.0f && n < 16u)) {
        /* no filter (auto parameters need 16 samples: below that every sample is a candidate) */
        size_t i;
        for (i = 0u; i < n; ++i) {
            cal->flags[i] = 1u;
        }
        rep->filter_eps = 0.0f;
        rep->filter_min_pts = 0u;
        return MAGCAL_OK;
    }
    if (c->filter == MAGCAL_FILTER_DBSCAN) {
#if MAGCAL_CFG_ENABLE_DBSCAN
        static const magcal_dbscan_cfg_t dc_default = MAGCAL_DBSCAN_CFG_DEFAULT;
        magcal_dbscan_cfg_t *dc = &run->dc;
        int16_t *labels = (int16_t *)cal->scratch;
        size_t lab_len = (2u * n + 3u) & ~(size_t)3u;
        uint8_t *rest = (uint8_t *)cal->scratch + lab_len;
        size_t rest_len = cal->scratch_len - lab_len;
        *dc = dc_default;
        if (c->eps > 0.0f) {
            dc->eps = c->eps;
            dc->min_pts = c->min_pts != 0u ? c->min_pts : 4u;
        } else {
            float e;
            float ep;
            uint16_t mp;
            st = magcal_optics_auto_params(cal->buf, n, cal->scratch, cal->scratch_len, &e, &mp,
                                           &ep);
            if (st != MAGCAL_OK) {
                return st;
            }
            dc->eps = ep;
            dc->min_pts = c->min_pts != 0u ? c->min_pts : mp;
        }
        st = magcal_dbscan_run(dc, cal->buf, n, rest, rest_len, labels, NULL, NULL);
        if (st != MAGCAL_OK) {
            return st;
        }
        st = magcal_optics_largest_cluster(labels, n, rest, rest_len, cal->flags, NULL, NULL);
        if (st != MAGCAL_OK) {
            return st;
        }
        rep->filter_eps = dc->eps;
        rep->filter_min_pts = dc->min_pts;
        return MAGCAL_OK;
#else
        return MAGCAL_ERR_ARG; /* DBSCAN compiled out (config.h MAGCAL_CFG_ENABLE_DBSCAN = 0) */
#endif
    }
    {
        static const magcal_optics_cfg_t oc_default = MAGCAL_OPTICS_CFG_DEFAULT;
        magcal_optics_cfg_t *oc = &run->oc;
        magcal_optics_result_t *info = &run->info;
        *oc = oc_default;
        if (c->filter == MAGCAL_FILTER_OPTICS_CLASSIC) {
            oc->order = MAGCAL_OPTICS_CLASSIC;
            oc->neighbors = MAGCAL_NEIGHBORS_BRUTE;
        }
        if (c->eps > 0.0f) {
            oc->eps = c->eps;
            oc->eps_prime = c->eps;
            oc->min_pts = c->min_pts != 0u ? c->min_pts : 4u;
        } else if (c->min_pts != 0u) {
            /* automatic radius, caller's MinPts */
            float e;
            float ep;
            uint16_t mp;
            st = magcal_optics_auto_params(cal->buf, n, cal->scratch, cal->scratch_len, &e, &mp,
                                           &ep);
            if (st != MAGCAL_OK) {
                return st;
            }
            oc->eps = e;
            oc->eps_prime = ep;
            oc->min_pts = c->min_pts;
        } else {
            /* fully automatic parameters: the OPTICS defaults */
        }
        st =
            magcal_optics_filter(oc, cal->buf, n, cal->scratch, cal->scratch_len, cal->flags, info);
        if (st != MAGCAL_OK) {
            return st;
        }
        rep->filter_eps = info->eps_prime;
        rep->filter_min_pts = info->min_pts;
    }
    return MAGCAL_OK;
}

/* 2x2 inverse of a calibration matrix. */
static int cal_inv2(const float m[2][2], float inv[2][2])
{
    float det = m[0][0] * m[1][1] - m[0][1] * m[1][0];
    if (!(fabsf(det) > 0.0f) || !magcal_isfinite_f(det)) {
        return -1;
    }
    inv[0][0] = m[1][1] / det;
    inv[0][1] = -m[0][1] / det;
    inv[1][0] = -m[1][0] / det;
    inv[1][1] = m[0][0] / det;
    return 0;
}

/* sin and cos of k * 5 deg, k < 72 (quadrant q = k / 18, j = k % 18): the shift's test headings
 * are multiples of 5 deg (CAL_SHIFT_STEPS), so their sines and cosines come from a quarter-wave
 * table of sin(5 j deg), j = 0..18, instead of sinf/cosf (whose argument reduction is ~3 KB of
 * flash). */
static void cal_sincos5(size_t k, float *sn, float *cs)
{
    static const float cal_sin5[19] = {
        0.000000000e+00f, 8.715574275e-02f, 1.736481777e-01f, 2.588190451e-01f, 3.420201433e-01f,
        4.226182617e-01f, 5.000000000e-01f, 5.735764364e-01f, 6.427876097e-01f, 7.071067812e-01f,
        7.660444431e-01f, 8.191520443e-01f, 8.660254038e-01f, 9.063077870e-01f, 9.396926208e-01f,
        9.659258263e-01f, 9.848077530e-01f, 9.961946981e-01f, 1.000000000e+00f};
    size_t q = k / 18u;
    size_t j = k % 18u;
    float a = cal_sin5[j];
    float b = cal_sin5[18u - j];
    switch (q) {
    case 0u:
        *sn = a;
        *cs = b;
        break;
    case 1u:
        *sn = b;
        *cs = -a;
        break;
    case 2u:
        *sn = -a;
        *cs = -b;
        break;
    default:
        *sn = -b;
        *cs = a;
        break;
    }
}

/* cppcheck-suppress misra-c2012-2.3 ; deviation D4: a static assert is an unused typedef */
MAGCAL_STATIC_ASSERT(CAL_SHIFT_STEPS == 72u, shift_steps_match_sine_table);

/* Heading change if `next` replaced `cur` (cur NULL = identity). */
static MAGCAL_NOINLINE void cal_shift(const magcal_cal2d_t *cur, const magcal_cal2d_t *next,
                                      float *max_deg, float *rms_deg)
{
    float inv[2][2];
    float r = next->radius > 0.0f ? next->radius : 1.0f;
    float mx = 0.0f;
    float ss = 0.0f;
    size_t k;
    size_t cnt = 0u;
    if (cal_inv2(next->m, inv) != 0) {
        *max_deg = NAN;
        *rms_deg = NAN;
        return;
    }
    for (k = 0u; k < CAL_SHIFT_STEPS; ++k) {
        float psi = (float)k * (360.0f / (float)CAL_SHIFT_STEPS);
        float sp;
        float cp;
        float hx;
        float hy;
        magcal_vec2_t raw;
        magcal_vec2_t h;
        float ph;
        float d;
        cal_sincos5(k, &sp, &cp);
        hx = -r * sp;
        hy = r * cp;
        raw.x = inv[0][0] * hx + inv[0][1] * hy + next->offset.x;
        raw.y = inv[1][0] * hx + inv[1][1] * hy + next->offset.y;
        if (cur != NULL) {
            if (magcal_correct_apply(cur, raw, &h) != MAGCAL_OK) {
                continue;
            }
        } else {
            h = raw;
        }
        if (magcal_heading_from_field(h, &ph) != MAGCAL_OK) {
            continue;
        }
        d = fabsf(magcal_wrap180_deg(ph - psi));
        mx = fmaxf(mx, d);
        ss += d * d;
        ++cnt;
    }
    *max_deg = mx;
    *rms_deg = cnt > 0u ? sqrtf(ss / (float)cnt) : NAN;
}

static void cal_set_flags(magcal_calibrator_t *cal, int with_residual)
{
    size_t i;
    for (i = 0u; i < cal->n; ++i) {
        uint8_t f = MAGCAL_CALIBRATOR_FLAG_JUDGED;
        if (cal->mask_a[i] == 0u) {
            f = (uint8_t)(f | MAGCAL_CALIBRATOR_FLAG_FILTER);
        }
        if (with_residual != 0 && cal->mask_b[i] == 0u) {
            f = (uint8_t)(f | MAGCAL_CALIBRATOR_FLAG_RESIDUAL);
        }
        cal->flags[i] = f;
    }
    cal->n_judged = cal->n;
}

/* Plain least-squares fit of the filter inliers (use_consensus = 0). The classify() threshold
 * is k_sigma * residual RMS of the fit, clamped like the consensus threshold. */
static MAGCAL_NOINLINE magcal_status_t cal_plain_fit(magcal_calibrator_t *cal,
                                                     magcal_consensus_result_t *res)
{
    size_t n = cal->n;
    size_t i;
    size_t k = 0u;
    float rm;
    float thr;
    magcal_status_t st = magcal_ellipse_fit(cal->buf, n, cal->mask_a, &res->fit);
    if (st != MAGCAL_OK) {
        return st;
    }
    for (i = 0u; i < n; ++i) {
        cal->mask_b[i] = cal->mask_a[i];
        if (cal->mask_a[i] != 0u) {
            ++k;
        }
    }
    rm = sqrtf(res->fit.semi_minor * res->fit.semi_major);
    thr = cal->cfg.consensus.k_sigma * res->fit.residual_rms;
    thr = fmaxf(thr, cal->cfg.consensus.min_thr_rel * rm);
    thr = fminf(thr, cal->cfg.consensus.max_thr_rel * rm);
    res->sigma = res->fit.residual_rms;
    res->threshold = thr;
    res->n_candidates = (uint16_t)k;
    res->n_inliers = (uint16_t)k;
    res->n_rescued = 0u;
    res->n_rejected = 0u;
    return MAGCAL_OK;
}

static magcal_status_t cal_finish(magcal_calibrator_t *cal, magcal_status_t st,
                                  magcal_cal_report_t *rep, magcal_cal_report_t *out)
{
    rep->status = st;
    if (st == MAGCAL_OK) {
        cal->state = MAGCAL_CALIBRATOR_CALIBRATED;
        rep->adopted = 1u;
    } else {
        cal->state = MAGCAL_CALIBRATOR_FAILED;
        rep->adopted = 0u;
    }
    cal->last_status = st;
    rep->state = cal->state;
    if (out != NULL) {
        *out = *rep;
    }
    return st;
}

/*
 * run() is a sequence of stages, each MAGCAL_NOINLINE with its own frame, sharing the state in the
 * workspace (cal_run_t): the deepest stack paths (the consensus fits, the density filter) then
 * sit under a small run() frame instead of one frame holding every stage's locals. Each stage
 * returns MAGCAL_OK to continue or the run's final status.
 */

/* 1-3: pre-checks, density filter, collinearity of its inliers, coverage pre-gate. */
MAGCAL_NOINLINE magcal_status_t magcal_calibrator_stage_prepare(magcal_calibrator_t *cal,
                                                         magcal_cal_report_t *rep)
{
    const size_t n = cal->n;
    size_t i;
    size_t filt_in = 0u;
    magcal_status_t st;

    /* 1. pre-checks */
    if (n < cal->cfg.min_samples || n < MAGCAL_ELLIPSE_MIN_POINTS) {
        return MAGCAL_ERR_TOO_FEW_POINTS;
    }
    if (cal_identical(cal->buf, n) != 0) {
        return MAGCAL_ERR_DEGENERATE;
    }
    {
        /* Extent of the samples: when its square is not a normal float32, squared distances and
         * moments lose their precision (the density filter's eps^2 test first): 0 = the points are
         * indistinguishable, otherwise too ill-conditioned for float32 (rings below ~1e-20). */
        const float ex = cal->bb_max.x - cal->bb_min.x;
        const float ey = cal->bb_max.y - cal->bb_min.y;
        const float ext = ex > ey ? ex : ey;
        const float ext2 = ext * ext;
        if (!(ext2 > 0.0f)) {
            return MAGCAL_ERR_DEGENERATE;
        }
        if (ext2 < FLT_MIN) {
            return MAGCAL_ERR_ILL_CONDITIONED;
        }
    }

    /* 2. density filter */
    st = cal_filter(cal, rep);
    if (st != MAGCAL_OK) {
        return st;
    }
    (void)memcpy(cal->mask_a, cal->flags, n); /* the scratch is free now; flags become flag bits */
    for (i = 0u; i < n; ++i) {
        if (cal->mask_a[i] != 0u) {
            ++filt_in;
        }
    }
    rep->rejected_filter = (uint16_t)(n - filt_in);
    cal_set_flags(cal, 0);
    if (filt_in < cal->cfg.min_samples) {
        return MAGCAL_ERR_TOO_FEW_POINTS;
    }
    if (cal_degenerate(cal->buf, n, cal->mask_a) != 0) {
        return MAGCAL_ERR_DEGENERATE;
    }

    /* 3. coverage pre-gate: every sample, around the hard-iron circle centre of the filter inliers
     * (a short arc is reported as COVERAGE, not as whatever conic it happens to fit). When the
     * filter's inliers alone cover less than the gate while all samples do, the filter split the
     * ring into arcs (bursts leave gaps, algorithms.md 4.3): the consensus then draws its minimal
     * sets from every sample instead (LMedS tolerates up to 50 % outliers). */
    {
        magcal_vec2_t cc;
        float cov;
        float cov_f;
        st = cal_circle_centre(cal->buf, n, cal->mask_a, &cc);
        if (st != MAGCAL_OK) {
            return st == MAGCAL_ERR_ILL_CONDITIONED ? MAGCAL_ERR_DEGENERATE : st;
        }
        cov = cal_coverage_around(cal->buf, n, NULL, cc, &rep->missing_start_deg,
                                  &rep->missing_width_deg);
        rep->coverage_deg = cov;
        if (cov < cal->cfg.min_coverage_deg) {
            return MAGCAL_ERR_COVERAGE;
        }
        cov_f = cal_coverage_around(cal->buf, n, cal->mask_a, cc, NULL, NULL);
        if (cov_f < cal->cfg.min_coverage_deg) {
            rep->filter_fragmented = 1u;
        }
    }
    return MAGCAL_OK;
}

/* 4. consensus (or plain fit) into run->cres: nothing else on this frame. Also the fit slice of
 * the continuous calibrator (calibrator_internal.h), called there straight from its step(). */
MAGCAL_NOINLINE magcal_status_t magcal_calibrator_stage_fit(magcal_calibrator_t *cal)
{
    cal_run_t *run = (cal_run_t *)cal->run;
    (void)memset(&run->cres, 0, sizeof run->cres);
    if (cal->cfg.use_consensus == 0u) {
        return cal_plain_fit(cal, &run->cres);
    }
    {
        const uint8_t *cand = run->rep.filter_fragmented != 0u ? NULL : cal->mask_a;
        magcal_status_t st;
        /* minimal sets from one candidate per clump (optics.h magcal_optics_thin): samples of a
         * vehicle parked at one heading must not fill the draws; flags hold the mask meanwhile */
        if (cal->n >= 16u && magcal_optics_thin(cal->buf, cal->n, cand, cal->scratch,
                                                cal->scratch_len, cal->flags) == MAGCAL_OK) {
            cand = cal->flags;
        }
        st = magcal_consensus_run(&cal->cfg.consensus, cal->buf, cal->n, cand, cal->scratch,
                                  MAGCAL_CONSENSUS_WORKSPACE_LEN(cal->capacity), cal->mask_b,
                                  &run->cres);
        cal_set_flags(cal, 0); /* the filter flags again (the gates set the residual bits) */
        return st;
    }
}

/* 4 (cont.) and 5: keep the fit, count, fill the report, gates. */
MAGCAL_NOINLINE magcal_status_t magcal_calibrator_stage_gates(magcal_calibrator_t *cal,
                                                       magcal_cal_report_t *rep)
{
    const magcal_consensus_result_t *cres = &((const cal_run_t *)cal->run)->cres;
    const size_t n = cal->n;
    size_t i;
    size_t used = 0u;
    size_t n_out;
    float radius;

    cal->fit = cres->fit;
    cal->threshold = cres->threshold;
    cal->has_fit = 1u;
    cal_set_flags(cal, 1);
    for (i = 0u; i < n; ++i) {
        if (cal->mask_b[i] != 0u) {
            ++used;
            if (cal->mask_a[i] == 0u) {
                rep->rescued_consensus++;
            }
        } else if (cal->mask_a[i] != 0u) {
            rep->rejected_consensus++;
        } else {
            /* rejected by the filter and by the consensus */
        }
    }
    rep->used = (uint16_t)used;
    rep->outliers = (uint16_t)(n - used);
    rep->ellipse = cres->fit;
    rep->threshold = cres->threshold;
    radius = sqrtf(cres->fit.semi_minor * cres->fit.semi_major);
    rep->radius = radius;
    rep->residual_rms = cres->fit.residual_rms;
    rep->residual_rel = radius > 0.0f ? cres->fit.residual_rms / radius : INFINITY;
    rep->axis_ratio =
        cres->fit.semi_major > 0.0f ? cres->fit.semi_minor / cres->fit.semi_major : 0.0f;
    rep->min_pivot = cres->fit.min_pivot;

    /* 5. gates */
    n_out = n - used;
    if (used < cal->cfg.min_samples) {
        return MAGCAL_ERR_TOO_FEW_POINTS;
    }
    if ((float)n_out > cal->cfg.max_outlier_frac * (float)n) {
        return MAGCAL_ERR_TOO_MANY_OUTLIERS;
    }
    if ((cal->cfg.min_radius > 0.0f && radius < cal->cfg.min_radius) ||
        (cal->cfg.max_radius > 0.0f && radius > cal->cfg.max_radius)) {
        return MAGCAL_ERR_RADIUS_RANGE;
    }
    if (rep->axis_ratio < cal->cfg.min_axis_ratio) {
        return MAGCAL_ERR_AXIS_RATIO;
    }
    if (!(rep->residual_rel <= cal->cfg.max_residual_rel)) {
        return MAGCAL_ERR_RESIDUAL;
    }
    return MAGCAL_OK;
}

/* 6 (cont.): estimates of the new calibration (report fields est_*) and the observability gate.
 * Scratch: the consensus workspace (free after the fit; the masks live behind it). */
static MAGCAL_NOINLINE magcal_status_t cal_stage_estimate(magcal_calibrator_t *cal,
                                                          magcal_cal_report_t *rep,
                                                          magcal_cal_harm_t *hn, float *dup,
                                                          float *floor_rel)
{
    cal_run_t *run = (cal_run_t *)cal->run;
    float *fs = (float *)cal->scratch;
    uint16_t *idx = (uint16_t *)(void *)(fs + MAGCAL_CAL_HARM_SCRATCH_FLOATS);
    float step = 0.0f;
    size_t distinct = magcal_cal_distinct(cal->buf, cal->n, cal->mask_b, idx, &step);
    float noise;
    *dup = distinct > 0u ? (float)rep->used / (float)distinct : 1.0f;
    if (*dup < 1.0f) {
        *dup = 1.0f;
    }
    rep->distinct = (uint16_t)distinct;
    /* quantisation: a lattice of few distinct values can lie on a conic far from the truth with
     * almost no residual; its heading noise is at least that of a uniform error of one step */
    *floor_rel = rep->radius > 0.0f ? step / (rep->radius * 3.4641016f) : 0.0f;
    magcal_cal_harmonics(cal->buf, cal->n, cal->mask_b, &run->next, *dup, *floor_rel, fs, hn);
    if (hn->ok == 0u) {
        return MAGCAL_ERR_UNOBSERVABLE; /* headings too clumped to separate centre and soft iron */
    }
    /* per-sample heading noise of new data: the relative radial residual after the harmonics
     * (the fit's own residual, dof corrected); tangential and radial noise have the same RMS
     * over uniformly spread headings */
    noise = hn->sigma_rel;
    rep->est_noise_deg = MAGCAL_DEG_PER_RAD_F * noise;
    rep->design_factor = hn->design;
    rep->est_param_err_deg = MAGCAL_DEG_PER_RAD_F * sqrtf(hn->noise2 + hn->bias2);
    rep->est_heading_err_deg = MAGCAL_DEG_PER_RAD_F * sqrtf(noise * noise + hn->noise2 + hn->bias2);
    {
        /* repeated values (quantisation): the estimate rests on the distinct values only, so the
         * gate uses its upper confidence bound, (1 + 1 / sqrt(2 dof)) with dof = distinct - 5 */
        float par = sqrtf(hn->noise2 + hn->bias2);
        if (distinct < (size_t)rep->used) {
            float dof = distinct > 6u ? (float)distinct - 5.0f : 1.0f;
            par *= 1.0f + 1.0f / sqrtf(2.0f * dof);
        }
        if (!(par <= cal->cfg.max_param_err_ratio * noise) ||
            !(hn->design <= cal->cfg.max_design_factor)) {
            return MAGCAL_ERR_UNOBSERVABLE;
        }
    }
    return MAGCAL_OK;
}

/* 6. correction, final coverage (corrected headings of the inliers), estimates; 7. adoption. */
MAGCAL_NOINLINE magcal_status_t magcal_calibrator_stage_adopt(magcal_calibrator_t *cal,
                                                       magcal_cal2d_t *current,
                                                       magcal_cal_report_t *rep)
{
    cal_run_t *run = (cal_run_t *)cal->run;
    magcal_cal2d_t *next = &run->next;
    const size_t n = cal->n;
    magcal_status_t st;
    float cov;
    float dup = 1.0f;
    float floor_rel = 0.0f;
    magcal_cal_harm_t hn;
    magcal_cal_harm_t hc;

    st = magcal_ellipse_to_cal(&run->cres.fit, cal->cfg.form, cal->cfg.output_radius, next);
    if (st != MAGCAL_OK) {
        return st;
    }
    rep->cal = *next;
    cov = cal_coverage_corrected(cal->buf, n, cal->mask_b, next, &rep->missing_start_deg,
                                 &rep->missing_width_deg);
    rep->coverage_deg = cov;
    if (cov < cal->cfg.min_coverage_deg || !(cov > 0.0f)) {
        return MAGCAL_ERR_COVERAGE;
    }
    st = cal_stage_estimate(cal, rep, &hn, &dup, &floor_rel);
    if (st != MAGCAL_OK) {
        return st;
    }

    /* 7. adoption rule (file comment of calibrator.h) */
    if (magcal_cal2d_validate(current) != MAGCAL_OK || !(current->radius > 0.0f)) {
        cal_shift(NULL, next, &rep->shift_max_deg, &rep->shift_rms_deg);
        rep->adopt_rule = MAGCAL_ADOPT_UNUSABLE;
        *current = *next;
        return MAGCAL_OK;
    }
    cal_shift(current, next, &rep->shift_max_deg, &rep->shift_rms_deg);
    magcal_cal_harmonics(cal->buf, n, cal->mask_b, current, dup, floor_rel, (float *)cal->scratch,
                         &hc);
    if (hc.ok == 0u) {
        /* the current calibration maps the new inliers onto a point or leaves no usable radius */
        rep->current_err_deg = INFINITY;
        rep->current_err_z = INFINITY;
    } else {
        float ex = hc.err2 - hc.noise2; /* noise-free mean square error of `current` */
        rep->current_err_deg = MAGCAL_DEG_PER_RAD_F * sqrtf(fmaxf(ex, 0.0f));
        rep->current_err_z =
            hc.noise2_sd > 0.0f ? ex / hc.noise2_sd : (ex > 0.0f ? INFINITY : 0.0f);
    }
    if (rep->current_err_deg > fmaxf(MAGCAL_CALIBRATOR_ADOPT_MARGIN * rep->est_param_err_deg,
                                     MAGCAL_CALIBRATOR_ADOPT_MIN_DEG)) {
        rep->adopt_rule = MAGCAL_ADOPT_BETTER;
    } else if (rep->current_err_z > MAGCAL_CALIBRATOR_STALE_Z &&
               rep->current_err_deg >= rep->est_param_err_deg &&
               rep->current_err_deg > MAGCAL_CALIBRATOR_ADOPT_MIN_DEG && hc.ok != 0u &&
               fabsf(hc.mean_radius / current->radius - 1.0f) <= cal->cfg.max_radius_change) {
        rep->adopt_rule = MAGCAL_ADOPT_STALE;
    } else {
        return MAGCAL_ERR_NOT_BETTER;
    }
    *current = *next;
    return MAGCAL_OK;
}

/* Start of a solve: an empty report (estimates NaN: a failed run never reads as a perfect one),
 * no fit, nothing judged. */
static void cal_solve_reset(magcal_calibrator_t *cal, magcal_cal_report_t *rep)
{
    (void)memset(rep, 0, sizeof *rep);
    rep->current_err_deg = NAN;
    rep->current_err_z = NAN;
    rep->est_heading_err_deg = NAN;
    rep->est_param_err_deg = NAN;
    rep->est_noise_deg = NAN;
    rep->adopt_rule = MAGCAL_ADOPT_NONE;
    rep->samples = (uint16_t)cal->n;
    cal->has_fit = 0u;
    cal->n_judged = 0u;
}

magcal_status_t magcal_calibrator_run(magcal_calibrator_t *cal, magcal_cal2d_t *current,
                                      magcal_cal_report_t *report)
{
    magcal_cal_report_t *rep;
    magcal_status_t st;

    if (cal == NULL || current == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (!cal_ok(cal)) {
        return MAGCAL_ERR_NOT_INITIALISED;
    }
    rep = &((cal_run_t *)cal->run)->rep;
    cal_solve_reset(cal, rep);

    st = magcal_calibrator_stage_prepare(cal, rep);
    if (st == MAGCAL_OK) {
        st = magcal_calibrator_stage_fit(cal);
    }
    if (st == MAGCAL_OK) {
        st = magcal_calibrator_stage_gates(cal, rep);
    }
    if (st == MAGCAL_OK) {
        st = magcal_calibrator_stage_adopt(cal, current, rep);
    }
    return cal_finish(cal, st, rep, report);
}

/*
 * Sliced run for the continuous calibrator (src/loop/): the stages of run() called one per step,
 * the state kept in the workspace between calls (calibrator_internal.h). load takes the first n
 * samples the caller wrote into the sample buffer; end writes the report as run() does.
 */
magcal_status_t magcal_calibrator_stage_load(magcal_calibrator_t *cal, size_t n)
{
    magcal_cal_report_t *rep;
    size_t i;
    if (cal == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (!cal_ok(cal)) {
        return MAGCAL_ERR_NOT_INITIALISED;
    }
    if (n > cal->capacity) {
        return MAGCAL_ERR_ARG;
    }
    rep = &((cal_run_t *)cal->run)->rep;
    cal->n = n;
    if (n > 0u) {
        cal->bb_min = cal->buf[0];
        cal->bb_max = cal->buf[0];
    }
    for (i = 1u; i < n; ++i) {
        cal->bb_min.x = fminf(cal->bb_min.x, cal->buf[i].x);
        cal->bb_min.y = fminf(cal->bb_min.y, cal->buf[i].y);
        cal->bb_max.x = fmaxf(cal->bb_max.x, cal->buf[i].x);
        cal->bb_max.y = fmaxf(cal->bb_max.y, cal->buf[i].y);
    }
    cal_solve_reset(cal, rep);
    return MAGCAL_OK;
}

magcal_cal_report_t *magcal_calibrator_stage_report(magcal_calibrator_t *cal)
{
    return &((cal_run_t *)cal->run)->rep;
}

magcal_status_t magcal_calibrator_stage_end(magcal_calibrator_t *cal, magcal_status_t st,
                                            magcal_cal_report_t *report)
{
    return cal_finish(cal, st, &((cal_run_t *)cal->run)->rep, report);
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
    return cal_ok(cal) ? cal_coverage_of(cal->bins, NULL, NULL) : 0.0f;
}
