/*
 * The time-sliced 2-D conic fit (ellipse.h magcal_ellipse_fit_begin / _idx_begin / _step): the
 * passes of ellipse_fit.c run in budgeted chunks, the slice's scratch reused by phase; the
 * one-shot fits give the same result bit for bit.
 */
#include "magcal/ellipse.h"

#include <math.h>

#include "ellipse_internal.h"
#include "magcal_internal.h"

/*
 * Time-sliced fit. Weights: estimated Cortex-M4F instructions of one visit of each loop, measured
 * on QEMU mps2-an386 -icount shift=0 (arm-none-eabi-gcc -Os: 437 k instructions for 1024 points,
 * real/charged per step of each pass, ~5 % margin); a step stops before the visit that would pass
 * its budget (at least one visit per step).
 */
#define FIT_W_IDX 27u     /* one index range check (magcal_ellipse_fit_idx) */
#define FIT_W_SCAN 147u    /* pass 1: one point */
#define FIT_W_MOM 384u    /* pass 2: 13 Kahan sums of one point */
#define FIT_W_SOLVE 3000u /* collinearity test, normal equations, LDL^T, conic geometry */
#define FIT_W_RMS 144u     /* pass 3: radial residual of one point */
#define FIT_W_STORE 1200u  /* conic geometry again, result written */
#define FIT_W_FIVE 3200u  /* the 5-point exact path as a whole (5 points: O(1)) */

/* The slice's tmp_[25] by phase (each pass's data is dead before the next one's is written). */
#define SL_BB(s) (&(s)->tmp_[0])   /* scan: xmin, xmax, ymin, ymax, max|x|, max|y| */
#define SL_COMP(s) (&(s)->tmp_[0]) /* moments: Kahan compensation [13] */
#define SL_A(s) (&(s)->tmp_[0])    /* solve: the 5x5 normal matrix */
#define SL_GEO(s) (&(s)->tmp_[0])  /* residuals: centre, qform, semi-minor axis [6] */
#define SL_ACC(s) (&(s)->tmp_[6])  /* residuals: sum of squares, compensation */

#define FIT_PH_IDX 1u
#define FIT_PH_FIVE 2u
#define FIT_PH_SCAN 3u
#define FIT_PH_MOM 4u
#define FIT_PH_SOLVE 5u
#define FIT_PH_RMS 6u
#define FIT_PH_STORE 7u
#define FIT_PH_DONE 8u

static void slice_start(magcal_ellipse_fit_slice_t *s)
{
    size_t j;
    s->k_ = 0u;
    s->cnt_ = 0u;
    for (j = 0u; j < 6u; ++j) {
        SL_BB(s)[j] = 0.0f; /* bounding box, then the largest magnitudes */
    }
    s->used_ = 0u;
    s->status_ = (int8_t)MAGCAL_IN_PROGRESS;
}

magcal_status_t magcal_ellipse_fit_begin(magcal_ellipse_fit_slice_t *s, const magcal_vec2_t *pts,
                                         size_t n, const uint8_t *mask, magcal_ellipse_t *out)
{
    if (s == NULL || pts == NULL || out == NULL) {
        return MAGCAL_ERR_NULL;
    }
    s->pts_ = pts;
    s->n_ = n;
    s->mask_ = mask;
    s->idx_ = NULL;
    s->n_pts_ = n;
    s->out_ = out;
    slice_start(s);
    s->phase_ = FIT_PH_SCAN;
    return MAGCAL_OK;
}

magcal_status_t magcal_ellipse_fit_idx_begin(magcal_ellipse_fit_slice_t *s,
                                             const magcal_vec2_t *pts,
                                             size_t n_pts, const uint16_t *idx, size_t m,
                                             magcal_ellipse_t *out)
{
    if (s == NULL || pts == NULL || idx == NULL || out == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (m > MAGCAL_ELLIPSE_MAX_POINTS) {
        return MAGCAL_ERR_ARG;
    }
    if (m < MAGCAL_ELLIPSE_MIN_POINTS) {
        return MAGCAL_ERR_TOO_FEW_POINTS;
    }
    s->pts_ = pts;
    s->n_ = m;
    s->mask_ = NULL;
    s->idx_ = idx;
    s->n_pts_ = n_pts;
    s->out_ = out;
    slice_start(s);
    s->phase_ = FIT_PH_IDX;
    return MAGCAL_OK;
}

/* Visits of weight w that the rest of the budget pays for (at most left); at least one on a call's
 * first visit (used == 0), 0 = stop here. */
static size_t slice_visits(uint32_t budget, uint32_t used, uint32_t w, size_t left)
{
    uint32_t v = (used < budget) ? (budget - used) / w : 0u;
    if (v == 0u && used == 0u) {
        v = 1u;
    }
    return ((size_t)v < left) ? (size_t)v : left;
}

/* End of pass 1: count rule, centred normalisation; moments pass next. */
static magcal_status_t slice_scan_done(magcal_ellipse_fit_slice_t *s)
{
    magcal_efit_norm_t nm;
    magcal_status_t st = magcal_efit_scan_count_ok(s->cnt_);
    if (st == MAGCAL_OK) {
        st = magcal_efit_norm_centred(SL_BB(s), &nm, &s->norm_[4]);
    }
    if (st == MAGCAL_OK) {
        s->norm_[0] = nm.mx;
        s->norm_[1] = nm.my;
        s->norm_[2] = nm.isx;
        s->norm_[3] = nm.isy;
        magcal_efit_moments_zero(s->mom_, SL_COMP(s));
        s->k_ = 0u;
        s->phase_ = FIT_PH_MOM;
    }
    return st;
}

/* Collinearity test, normal equations, geometry (for the residuals of pass 3). */
static magcal_status_t slice_solve(magcal_ellipse_fit_slice_t *s)
{
    magcal_status_t st;
    if (magcal_efit_moments_collinear(s->mom_, (float)s->cnt_) != 0) {
        return MAGCAL_ERR_DEGENERATE;
    }
    st = magcal_efit_moments_solve(s->mom_, (float)s->cnt_, SL_A(s), &s->minp_);
    if (st == MAGCAL_OK) {
        st = magcal_efit_conic_geometry(s->mom_, s->norm_[0], s->norm_[1], s->norm_[4], NULL,
                                        SL_GEO(s));
    }
    SL_ACC(s)[0] = 0.0f;
    SL_ACC(s)[1] = 0.0f;
    s->k_ = 0u;
    s->phase_ = FIT_PH_RMS;
    return st;
}

/* The result: the geometry again (cheaper than keeping it in the slice), the RMS, *out. */
static magcal_status_t slice_store(magcal_ellipse_fit_slice_t *s)
{
    return magcal_efit_conic_store(s->mom_, s->norm_[0], s->norm_[1], s->norm_[4],
                       sqrtf(SL_ACC(s)[0] / (float)s->cnt_), s->minp_, s->cnt_, s->out_);
}

/* One pass chunk or one fixed visit of the current phase; *used is charged. Returns
 * MAGCAL_IN_PROGRESS to go on, 2 when the budget is spent, or the final status. */
#define SLICE_SPENT ((magcal_status_t)2)
static MAGCAL_NOINLINE magcal_status_t slice_phase(magcal_ellipse_fit_slice_t *s,
                                                   const magcal_efit_src_t *src, uint32_t budget,
                                                   uint32_t *used)
{
    static const uint16_t w_of[FIT_PH_DONE] = {0u, FIT_W_IDX, FIT_W_FIVE, FIT_W_SCAN,
                                                FIT_W_MOM, FIT_W_SOLVE, FIT_W_RMS, FIT_W_STORE};
    const uint32_t w = w_of[s->phase_];
    /* a pass phase visits the points left, a fixed phase is one visit */
    const size_t left = (s->phase_ == FIT_PH_IDX || s->phase_ == FIT_PH_SCAN ||
                         s->phase_ == FIT_PH_MOM || s->phase_ == FIT_PH_RMS)
                            ? s->n_ - s->k_
                            : 1u;
    const size_t v = slice_visits(budget, *used, w, left);
    const size_t k1 = s->k_ + v;
    magcal_status_t st = MAGCAL_IN_PROGRESS;
    magcal_efit_norm_t nm;

    if (v == 0u && left > 0u) {
        return SLICE_SPENT;
    }
    *used += (uint32_t)v * w;
    switch (s->phase_) {
    case FIT_PH_IDX:
        if (magcal_efit_idx_in_range(s->idx_, s->k_, k1, s->n_pts_) == 0) {
            return MAGCAL_ERR_ARG;
        }
        s->k_ = k1;
        if (k1 == s->n_) {
            s->k_ = 0u;
            s->phase_ = (s->n_ == MAGCAL_ELLIPSE_MIN_POINTS) ? FIT_PH_FIVE : FIT_PH_SCAN;
        }
        break;
    case FIT_PH_SCAN:
        st = magcal_efit_src_scan_range(src, s->k_, k1, &s->cnt_, SL_BB(s), &SL_BB(s)[4]);
        s->k_ = k1;
        if (st == MAGCAL_OK) {
            st = (k1 == s->n_) ? slice_scan_done(s) : MAGCAL_OK;
        }
        break;
    case FIT_PH_MOM:
        nm.mx = s->norm_[0];
        nm.my = s->norm_[1];
        nm.isx = s->norm_[2];
        nm.isy = s->norm_[3];
        magcal_efit_src_moments_range(src, &nm, 0, s->k_, k1, s->mom_, SL_COMP(s));
        s->k_ = k1;
        if (k1 == s->n_) {
            s->phase_ = FIT_PH_SOLVE;
        }
        break;
    case FIT_PH_SOLVE:
        st = slice_solve(s);
        break;
    case FIT_PH_RMS:
        magcal_efit_src_rms_range(src, SL_GEO(s), s->k_, k1, SL_ACC(s));
        s->k_ = k1;
        if (k1 == s->n_) {
            s->phase_ = FIT_PH_STORE;
        }
        break;
    default: /* FIT_PH_STORE */
        return slice_store(s);
    }
    return (st == MAGCAL_OK) ? MAGCAL_IN_PROGRESS : st;
}

/* The passes and fixed visits of a step (every phase but the 5-point path, which the caller
 * runs beside this frame); then the slice's bookkeeping. Also the one-shot fits' whole run. */
static MAGCAL_NOINLINE magcal_status_t slice_steps(magcal_ellipse_fit_slice_t *s, uint32_t budget,
                                                   uint32_t *used)
{
    magcal_efit_src_t src;
    magcal_status_t st = MAGCAL_IN_PROGRESS;
    src.pts = s->pts_;
    src.n = s->n_;
    src.mask = s->mask_;
    src.idx = s->idx_;
    while (st == MAGCAL_IN_PROGRESS && s->phase_ != FIT_PH_FIVE) {
        st = slice_phase(s, &src, budget, used);
    }
    return st;
}

/* End of a step: what it charged; the final status once done. */
static magcal_status_t slice_end(magcal_ellipse_fit_slice_t *s, magcal_status_t st, uint32_t used)
{
    s->used_ = used;
    if (st == SLICE_SPENT || st == MAGCAL_IN_PROGRESS) {
        return MAGCAL_IN_PROGRESS;
    }
    s->phase_ = FIT_PH_DONE;
    s->status_ = (int8_t)st;
    return st;
}

magcal_status_t magcal_ellipse_fit_step(magcal_ellipse_fit_slice_t *s, uint32_t budget)
{
    uint32_t used = 0u;
    magcal_status_t st;

    if (s == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (s->phase_ == FIT_PH_DONE) {
        s->used_ = 0u;
        return (magcal_status_t)s->status_;
    }
    if (s->phase_ < FIT_PH_IDX || s->phase_ > FIT_PH_STORE) {
        return MAGCAL_ERR_ARG;
    }
    st = slice_steps(s, budget, &used);
    if (st == MAGCAL_IN_PROGRESS && s->phase_ == FIT_PH_FIVE) {
        if (slice_visits(budget, used, FIT_W_FIVE, 1u) == 0u) {
            st = SLICE_SPENT;
        } else { /* beside slice_steps' frame: the deepest path of the minimal sets */
            magcal_efit_src_t src;
            src.pts = s->pts_;
            src.n = s->n_;
            src.mask = NULL;
            src.idx = s->idx_;
            used += FIT_W_FIVE;
            st = magcal_efit_fit_five(&src, s->out_);
        }
    }
    return slice_end(s, st, used);
}
