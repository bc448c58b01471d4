/*
 * The complete 3-D calibration (issue 14): pre-test fit -> density stage only when the data show a
 * gross outlier -> fit. The pre-test is the fit of all samples itself, so data without outliers
 * (the common case: a hand tumble) cost one fit and one residual pass, and every other case gives
 * exactly the result of the full composition (magcal_optics_filter3, then magcal_ellipsoid_fit on
 * its inliers). Time-sliced (magcal_ellipsoid_calibrate_begin/step): the fits are sliced
 * (magcal_ellipsoid_fit_step), the density stage too (magcal_optics_filter3_step, its state in
 * the slice), the passes charge per sample.
 */
#include <math.h>
#include <string.h>

#include "ellipsoid_internal.h"
#include "magcal/ellipsoid.h"
#include "magcal/optics.h"
#include "magcal_internal.h"

#if MAGCAL_CFG_ENABLE_3D /* whole file: config.h feature switch */

/* Weights (estimated Cortex-M4F instructions per visit, as src/fit/ellipsoid.c). */
#define CW_UNIT 300u     /* a decision, a result copy */
#define CW_MAXRES 22u    /* one stored residual of the pre-test */
#define CW_INLIER 6u     /* one inlier flag */
#define CW_COPY 40u      /* one density verdict, one copy */
#define CW_DENSITY_CALLS 8u /* step calls of the density stage per calibration step, at most (2^31 each) */

/* cppcheck-suppress misra-c2012-2.4 ; deviation D14 (false positive): no tag, so no unused tag; the constants are the phases of phase_ */
enum { CAL_PH_PRE = 0, CAL_PH_PRE_STEP, CAL_PH_MAXRES, CAL_PH_DECIDE, CAL_PH_INLIER, CAL_PH_DENSITY,
       CAL_PH_DENSITY_STEP, CAL_PH_COPY, CAL_PH_FIT, CAL_PH_FIT_STEP, CAL_PH_DONE };

#define CAL_CONT 100
#define CAL_YIELD 101

/* Charge w if the budget allows it (always the first visit of a step). */
static int cal_can(uint32_t *used, uint32_t budget, uint32_t w)
{
    if (*used == 0u || (*used <= budget && w <= budget - *used)) {
        *used += w;
        return 1;
    }
    return 0;
}

/* Visits of weight w the rest of the budget pays for (at least one on a step's first, at most
 * left_n), charged at once. */
static size_t cal_visits(uint32_t *used, uint32_t budget, uint32_t w, size_t left_n)
{
    size_t v = (*used < budget) ? (size_t)((budget - *used) / w) : 0u;
    if (v == 0u && *used == 0u) {
        v = 1u;
    }
    if (v > left_n) {
        v = left_n;
    }
    *used += (uint32_t)v * w;
    return v;
}

/* The rest of the workspace behind the slots: the pre-test fit's workspace; later the inlier
 * copies, then the density stage's and the final fit's. */
static uint8_t *cal_rest(const magcal_ellipsoid_calibrate_slice_t *s)
{
    return s->work_ + MAGCAL_ELLIPSOID_CALIBRATE_SLOTS;
}

static magcal_ellipsoid_result_t *cal_first(const magcal_ellipsoid_calibrate_slice_t *s)
{
    uint8_t *w = s->work_;
    return (magcal_ellipsoid_result_t *)(void *)magcal_ell_align_up(w); /* size_t inside */
}

/* A sliced fit inside the calibration: begin (phase `ph`), then steps with the rest of the budget. */
static int cal_fit_phase(magcal_ellipsoid_calibrate_slice_t *s, const magcal_vec3_t *m, size_t n,
                         magcal_ellipsoid_result_t *out, uint32_t budget, uint32_t *used)
{
    magcal_status_t st;
    if ((s->phase_ == CAL_PH_PRE || s->phase_ == CAL_PH_FIT)) {
        if (cal_can(used, budget, CW_UNIT) == 0) {
            return CAL_YIELD;
        }
        st = magcal_ellipsoid_fit_begin(&s->fit_, m, n, &s->cfg_->fit, cal_rest(s) + s->fit_off_,
                                        s->work_len_ - MAGCAL_ELLIPSOID_CALIBRATE_SLOTS - s->fit_off_,
                                        out);
        if (st != MAGCAL_OK) {
            return (int)st;
        }
        s->phase_++;
        return CAL_CONT;
    }
    if (*used >= budget) {
        return CAL_YIELD;
    }
    st = magcal_ell_fit_step_in(&s->fit_, budget - *used, (*used == 0u) ? 1 : 0);
    if (st == MAGCAL_IN_PROGRESS && s->fit_.used_ == 0u) {
        return CAL_YIELD; /* the fit's next unit does not fit the rest of this step */
    }
    *used += s->fit_.used_;
    if (st == MAGCAL_IN_PROGRESS) {
        return CAL_YIELD;
    }
    return (int)st;
}

/* The density stage, time-sliced (magcal_optics_filter3_begin / _step within the rest of the
 * budget; its state in the slice, density_): in its own frame beside ecal_phase's, called straight
 * from the step (the stack of its deep path is the calibration's worst). */
static MAGCAL_NOINLINE int cal_density(magcal_ellipsoid_calibrate_slice_t *s, uint32_t budget,
                                       uint32_t *used)
{
    /* the density mask is written behind the copies' final place: byte k of the mask is read
     * before copy j <= k is written, both run front to back */
    const size_t n = s->n_;
    uint8_t *rest = cal_rest(s);
    magcal_status_t st = MAGCAL_IN_PROGRESS;
    unsigned guard;
    if (s->phase_ == CAL_PH_DENSITY) {
        if (cal_can(used, budget, CW_UNIT) == 0) {
            return CAL_YIELD;
        }
        st = magcal_optics_filter3_begin(&s->density_, &s->cfg_->density, s->m_, n,
                                         rest + n * sizeof(magcal_vec3_t),
                                         s->work_len_ - MAGCAL_ELLIPSOID_CALIBRATE_SLOTS - n * sizeof(magcal_vec3_t),
                                         rest + n * (sizeof(magcal_vec3_t) - 1u), &s->info_->density);
        if (st != MAGCAL_OK) {
            return (int)st;
        }
        s->phase_ = CAL_PH_DENSITY_STEP;
        return CAL_CONT;
    }
    /* bounded: a step call does at least one visit, the budget holds at most 2^32 of them; an
     * unlimited budget takes a few calls of 2^31 */
    for (guard = 0u; guard < CW_DENSITY_CALLS && (*used == 0u || *used < budget); ++guard) {
        uint32_t u = 0u;
        st = magcal_optics_filter3_step(&s->density_, (*used < budget) ? (budget - *used) : 1u, &u);
        *used += u;
        if (st != MAGCAL_IN_PROGRESS) {
            break;
        }
    }
    if (st == MAGCAL_IN_PROGRESS) {
        return CAL_YIELD;
    }
    if (st != MAGCAL_OK) {
        return (int)st;
    }
    s->info_->density_ran = 1u;
    s->k_ = 0u;
    s->nk_ = 0u;
    s->phase_ = CAL_PH_COPY;
    return CAL_CONT;
}

static MAGCAL_NOINLINE int ecal_phase(magcal_ellipsoid_calibrate_slice_t *s, uint32_t budget,
                                      uint32_t *used)
{
    const magcal_ellipsoid_calibrate_cfg_t *cfg = s->cfg_;
    magcal_ellipsoid_result_t *first = cal_first(s);
    magcal_ellipsoid_calibrate_info_t *inf = s->info_;
    const size_t n = s->n_;
    switch (s->phase_) {
    case CAL_PH_MAXRES: {
        /* largest | |G(m - V)| - F | over all samples: read from the residuals the fit left in
         * its workspace (every sample's, under the returned calibration) */
        const float *res = (const float *)(const void *)(cal_rest(s) + MAGCAL_ELLIPSOID_FIT_SCRATCH_BYTES);
        const size_t k1 = s->k_ + cal_visits(used, budget, CW_MAXRES, n - s->k_);
        float mx = s->mx_;
        size_t k;
        for (k = s->k_; k < k1; ++k) {
            const float r = fabsf(res[k]);
            if (!(r <= mx)) {
                mx = r;
            }
        }
        s->k_ = k1;
        s->mx_ = mx;
        if (s->k_ < n) {
            return CAL_YIELD;
        }
        inf->pretest_max_rel = (first->cal.field > 0.0f) ? (s->mx_ / first->cal.field) : NAN;
        s->phase_ = CAL_PH_DECIDE;
        return CAL_CONT;
    }
    case CAL_PH_DECIDE:
        if (cal_can(used, budget, CW_UNIT) == 0) {
            return CAL_YIELD;
        }
        if (cfg->mode == MAGCAL_ELLIPSOID_DENSITY_NEVER ||
            (s->pre_st_ == (int8_t)MAGCAL_OK && inf->pretest_max_rel <= cfg->pretest_max_rel)) {
            if (s->pre_st_ != (int8_t)MAGCAL_OK) {
                return (int)s->pre_st_;
            }
            *s->out_ = *first;
            s->k_ = 0u;
            s->phase_ = CAL_PH_INLIER;
            return CAL_CONT;
        }
        s->phase_ = CAL_PH_DENSITY;
        return CAL_CONT;
    case CAL_PH_COPY: {
        magcal_vec3_t *kept = (magcal_vec3_t *)(void *)cal_rest(s);
        const uint8_t *mask = cal_rest(s) + n * (sizeof(magcal_vec3_t) - 1u);
        while (s->k_ < n && cal_can(used, budget, CW_COPY) != 0) {
            const uint8_t keep = mask[s->k_];
            if (s->inlier_ != NULL) {
                s->inlier_[s->k_] = keep;
            }
            if (keep != 0u) {
                kept[s->nk_] = s->m_[s->k_];
                ++s->nk_;
            }
            s->k_++;
        }
        if (s->k_ < n) {
            return CAL_YIELD;
        }
        inf->n_density_rejected = n - s->nk_;
        s->fit_off_ = n * sizeof(magcal_vec3_t);
        s->phase_ = CAL_PH_FIT;
        return CAL_CONT;
    }
    default: /* CAL_PH_INLIER */
        if (s->inlier_ != NULL) {
            const size_t v = cal_visits(used, budget, CW_INLIER, n - s->k_);
            (void)memset(&s->inlier_[s->k_], 1, v);
            s->k_ += v;
            if (s->k_ < n) {
                return CAL_YIELD;
            }
        }
        return (int)MAGCAL_OK;
    }
}

/* The two fits (called straight from the step: their deep path under few frames): the pre-test
 * fit of all samples, or the fit of the density stage's inliers. */
static MAGCAL_NOINLINE int cal_fits(magcal_ellipsoid_calibrate_slice_t *s, uint32_t budget,
                                    uint32_t *used)
{
    if (s->phase_ == CAL_PH_PRE || s->phase_ == CAL_PH_PRE_STEP) {
        const int rc = cal_fit_phase(s, s->m_, s->n_, cal_first(s), budget, used);
        if (rc == CAL_YIELD || rc == CAL_CONT) {
            return rc;
        }
        s->pre_st_ = (int8_t)rc;
        s->k_ = 0u;
        s->mx_ = 0.0f;
        s->phase_ = (rc == (int)MAGCAL_OK) ? CAL_PH_MAXRES : CAL_PH_DECIDE;
        return CAL_CONT;
    }
    return cal_fit_phase(s, (const magcal_vec3_t *)(const void *)cal_rest(s), s->nk_, s->out_, budget,
                         used);
}

/* The checks of begin (and of the one-shot call, before it puts the slice into the workspace). */
static magcal_status_t cal_check(const magcal_ellipsoid_calibrate_cfg_t *cfg, const magcal_vec3_t *m,
                                 size_t n, const void *work, size_t work_len,
                                 const magcal_ellipsoid_result_t *out)
{
    if (cfg == NULL || m == NULL || work == NULL || out == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if ((cfg->mode != MAGCAL_ELLIPSOID_DENSITY_AUTO && cfg->mode != MAGCAL_ELLIPSOID_DENSITY_ALWAYS &&
         cfg->mode != MAGCAL_ELLIPSOID_DENSITY_NEVER) ||
        !(cfg->pretest_max_rel > 0.0f && cfg->pretest_max_rel <= 1.0f)) {
        return MAGCAL_ERR_ARG;
    }
    if (magcal_misalign(work, 4u) != 0u) {
        return MAGCAL_ERR_ALIGNMENT;
    }
    if (work_len < MAGCAL_ELLIPSOID_CALIBRATE_WORKSPACE_LEN(n)) {
        return MAGCAL_ERR_WORKSPACE;
    }
    return MAGCAL_OK;
}

magcal_status_t magcal_ellipsoid_calibrate_begin(magcal_ellipsoid_calibrate_slice_t *s,
                                                 const magcal_ellipsoid_calibrate_cfg_t *cfg,
                                                 const magcal_vec3_t *m, size_t n, void *work,
                                                 size_t work_len, uint8_t *inlier,
                                                 magcal_ellipsoid_result_t *out,
                                                 magcal_ellipsoid_calibrate_info_t *info)
{
    magcal_ellipsoid_calibrate_info_t *inf;
    magcal_status_t st;
    if (s == NULL) {
        return MAGCAL_ERR_NULL;
    }
    s->status_ = (int32_t)MAGCAL_ERR_ARG;
    s->used_ = 0u;
    s->work_ = NULL;
    st = cal_check(cfg, m, n, work, work_len, out);
    if (st != MAGCAL_OK) {
        return st;
    }
    /* layout: the pre-test's result | info when the caller gives none | the rest */
    s->cfg_ = cfg;
    s->m_ = m;
    s->n_ = n;
    s->work_ = (uint8_t *)work;
    s->work_len_ = work_len;
    s->inlier_ = inlier;
    s->out_ = out;
    inf = (magcal_ellipsoid_calibrate_info_t *)(void *)((uint8_t *)cal_first(s) +
                                                        MAGCAL_ELLIPSOID_CALIBRATE_RESULT_SLOT);
    if (info != NULL) {
        inf = info;
    }
    (void)memset(inf, 0, sizeof(*inf));
    inf->pretest_max_rel = NAN;
    s->info_ = inf;
    s->k_ = 0u;
    s->nk_ = 0u;
    s->fit_off_ = 0u;
    s->mx_ = 0.0f;
    s->pre_st_ = 0;
    s->phase_ = (cfg->mode != MAGCAL_ELLIPSOID_DENSITY_ALWAYS) ? (uint8_t)CAL_PH_PRE : (uint8_t)CAL_PH_DENSITY;
    s->status_ = (int32_t)MAGCAL_IN_PROGRESS;
    return MAGCAL_OK;
}

magcal_status_t magcal_ellipsoid_calibrate_step(magcal_ellipsoid_calibrate_slice_t *s, uint32_t budget)
{
    uint32_t used = 0u;
    uint32_t bud = budget;
    int rc = CAL_CONT;
    if (s == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (s->work_ == NULL) {
        return MAGCAL_ERR_ARG;
    }
    if (s->status_ != (int32_t)MAGCAL_IN_PROGRESS) {
        s->used_ = 0u;
        return (magcal_status_t)s->status_;
    }
    if (bud == 0u) {
        bud = 1u; /* a zero budget still makes progress: one visit */
    }
    /* bounded: each CAL_CONT ends a phase (at most 11) or moves a pass */
    while (rc == CAL_CONT) {
        if (s->phase_ == CAL_PH_DENSITY || s->phase_ == CAL_PH_DENSITY_STEP) {
            rc = cal_density(s, bud, &used);
        } else if (s->phase_ == CAL_PH_PRE || s->phase_ == CAL_PH_PRE_STEP ||
                   s->phase_ == CAL_PH_FIT || s->phase_ == CAL_PH_FIT_STEP) {
            rc = cal_fits(s, bud, &used);
        } else {
            rc = ecal_phase(s, bud, &used);
        }
        if (rc == CAL_CONT && used >= bud) {
            rc = CAL_YIELD;
        }
    }
    s->used_ = used;
    if (rc == CAL_YIELD) {
        return MAGCAL_IN_PROGRESS;
    }
    s->phase_ = CAL_PH_DONE;
    s->status_ = (int32_t)rc;
    return (magcal_status_t)rc;
}

uint32_t magcal_ellipsoid_calibrate_in_density(const magcal_ellipsoid_calibrate_slice_t *s)
{
    return (s != NULL && s->status_ == (int32_t)MAGCAL_IN_PROGRESS &&
            (s->phase_ == (uint8_t)CAL_PH_DENSITY || s->phase_ == (uint8_t)CAL_PH_DENSITY_STEP)) ? 1u : 0u;
}

/* The one-shot call's begin, its slice in the workspace slot (off the stack: issue 13's 512 B),
 * in a frame of its own beside the steps'. */
static MAGCAL_NOINLINE magcal_status_t cal_oneshot_begin(
    const magcal_ellipsoid_calibrate_cfg_t *cfg, const magcal_vec3_t *m, size_t n, void *work,
    size_t work_len, uint8_t *inlier, magcal_ellipsoid_result_t *out,
    magcal_ellipsoid_calibrate_info_t *info, magcal_ellipsoid_calibrate_slice_t **sp)
{
    const magcal_status_t st = cal_check(cfg, m, n, work, work_len, out);
    if (st != MAGCAL_OK) {
        return st;
    }
    *sp = (magcal_ellipsoid_calibrate_slice_t *)(void *)(magcal_ell_align_up(work) +
                                                         MAGCAL_ELLIPSOID_CALIBRATE_RESULT_SLOT +
                                                         MAGCAL_ELLIPSOID_CALIBRATE_INFO_SLOT_);
    return magcal_ellipsoid_calibrate_begin(*sp, cfg, m, n, work, work_len, inlier, out, info);
}

magcal_status_t magcal_ellipsoid_calibrate(const magcal_ellipsoid_calibrate_cfg_t *cfg,
                                           const magcal_vec3_t *m, size_t n, void *work,
                                           size_t work_len, uint8_t *inlier,
                                           magcal_ellipsoid_result_t *out,
                                           magcal_ellipsoid_calibrate_info_t *info)
{
    magcal_ellipsoid_calibrate_slice_t *s = NULL;
    const magcal_status_t st = cal_oneshot_begin(cfg, m, n, work, work_len, inlier, out, info, &s);
    if (st != MAGCAL_OK) {
        return st;
    }
    return magcal_ellipsoid_calibrate_step(s, UINT32_MAX);
}

#endif /* MAGCAL_CFG_ENABLE_3D */
