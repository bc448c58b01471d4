/*
 * The 2-D OPTICS stage's slice state and driver, and its public entry points (optics.h): the
 * state (sl_t) lives in the caller's workspace and overlays the sub-machines of optics_centre.c,
 * optics_params.c and optics_order.c (their states: optics_slice.h); sl_step runs the phases
 * (finiteness, centre, eps' rule, ordering, output, thinning) within a budget. Each one-shot call
 * is begin + a step of unlimited budget on the same machine (one code path). Also the cfg check
 * shared with the 3-D stage (optics_core.h).
 */
#include "magcal/optics.h"

#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "magcal_internal.h"
#include "neighbors.h"
#include "optics_core.h"
#include "optics_slice.h"

#ifdef MAGCAL_OPTICS_SLICE_PROFILE
unsigned long magcal_optics_slice_prof[P_N_WEIGHTS + 16]; /* optics_slice.h: bench-only profile counts */
#endif

/* ---- 4. the slice state, the driver and the entry points ------------------------------------ */

#define K_RUN 0u
#define K_FILTER 1u
#define K_AUTO 2u
#define K_THIN 3u
#define PH_FINITE 0u
#define PH_CENTRE 1u
#define PH_AUTOEPS 2u
#define PH_SETUP 3u
#define PH_ORDER 4u
#define PH_OUT 5u
#define PH_THIN 6u
#define PH_THINMASK 7u

/*
 * Everything live between two steps. It lives in the workspace, after the run workspace's MinPts
 * buffer (MAGCAL_OPTICS_CTX_LEN_ bytes, aligned for pointers; the static assert below), so the
 * one-shot calls keep their small stack frames and the public slice objects stay two words.
 * Each sub-machine's state is only live during its phase: they share one union.
 */
typedef struct {
    const magcal_vec2_t *pts;
    uint8_t *w;          /* the caller's workspace */
    uint8_t *out;        /* inlier or representative mask */
    /* cppcheck-suppress misra-c2012-19.2 ; deviation D12: the slice state overlays the sub-machines that are never live together, so it fits the workspace budget */
    union {
        const uint8_t *cand;          /* thinning: candidates (NULL: every point) */
        magcal_optics_result_t *info; /* filter and run: optional summary */
    /* cppcheck-suppress misra-c2012-19.2 ; deviation D12: the slice state overlays the sub-machines that are never live together, so it fits the workspace budget */
    } io;
    float eps; /* of the ordering */
    float eps_prime;
    float cr[3]; /* robust centre and radius */
    uint16_t n;
    uint16_t i; /* loop position of the finiteness and output phases */
    uint16_t min_pts;
    uint8_t kind;  /* K_* */
    uint8_t phase; /* PH_* */
    uint8_t order;
    uint8_t neighbors;
    uint8_t start;
    uint8_t is_auto;
    uint8_t thin_all;
    /* cppcheck-suppress misra-c2012-19.2 ; deviation D12: the slice state overlays the sub-machines that are never live together, so it fits the workspace budget */
    union {
        magcal_o2_ce_t ce;
        magcal_o2_ae_t ae;
        magcal_o2_th_t th;
        magcal_o2_ord_t ord;
    /* cppcheck-suppress misra-c2012-19.2 ; deviation D12: the slice state overlays the sub-machines that are never live together, so it fits the workspace budget */
    } u;
} sl_t;

/* cppcheck-suppress misra-c2012-2.3 ; deviation D4: a static assert is an unused typedef */
MAGCAL_STATIC_ASSERT(sizeof(sl_t) + sizeof(void *) - 4u <= MAGCAL_OPTICS_CTX_LEN_,
                     optics_slice_state_fits_workspace);

/* The slice state of a run workspace at runw for n points. */
static sl_t *sl_at(uint8_t *runw, size_t n)
{
    uint8_t *cw = runw + MAGCAL_OPTICS_BEST_OFFSET_(n) + 4u * (size_t)MAGCAL_MAX_MIN_PTS;
    cw += (sizeof(void *) - magcal_misalign(cw, sizeof(void *))) % sizeof(void *);
    return (sl_t *)(void *)cw;
}

/* Bytes of the thinning's state: the common part and the centre's sub-state (no ordering). */
#define SL_THIN_LEN ((size_t)offsetof(sl_t, u) + (size_t)sizeof(magcal_o2_ce_t))

/*
 * The thinning's state: in the unused b[] region of the rule's layout when it fits (n >= 44 on a
 * 64-bit host), else right after rep[]. Either way inside the first 11 n + 3 + SL_THIN_LEN bytes,
 * the footprint the thinning has always had: the calibrator keeps its candidate mask in the
 * scratch behind the consensus workspace (10 n + 392 bytes on) while it thins.
 */
static sl_t *sl_thin_at(uint8_t *w, size_t n)
{
    uint8_t *cw = w + AUTO_REP_OFF(n) + n;
    if (4u * n >= (size_t)SL_THIN_LEN + sizeof(void *)) {
        cw = w + AUTO_B_OFF(n);
    }
    cw += (sizeof(void *) - magcal_misalign(cw, sizeof(void *))) % sizeof(void *);
    return (sl_t *)(void *)cw;
}

static sl_t *sl_new(sl_t *t, const magcal_vec2_t *pts, size_t n, unsigned kind)
{
    size_t len = sizeof *t;
    if (kind == (unsigned)K_THIN) {
        len = (size_t)SL_THIN_LEN;
    }
    (void)memset(t, 0, len);
    t->pts = pts;
    t->n = (uint16_t)n;
    t->kind = (uint8_t)kind;
    t->phase = (uint8_t)PH_FINITE;
    t->min_pts = (uint16_t)AUTO_MIN_PTS;
    return t;
}

static void sl_take_cfg(sl_t *t, const magcal_optics_cfg_t *cfg)
{
    t->order = (uint8_t)cfg->order;
    t->neighbors = (uint8_t)cfg->neighbors;
    t->start = (uint8_t)cfg->start;
}

/* Set up the ordering over the run workspace runw (O(1)); window: NULL or the grid window. */
static magcal_o2_ord_t *sl_ord_begin(sl_t *t, uint8_t *runw, const float *window)
{
    magcal_o2_ord_t *o = &t->u.ord;
    const size_t n = t->n;
    (void)memset(o, 0, sizeof *o);
    o->eps2 = t->eps * t->eps;
    o->oc.min_pts = t->min_pts;
    o->oc.mode = (magcal_optics_order_t)t->order;
    o->oc.core_start = 0;
    if (t->start == (uint8_t)MAGCAL_OPTICS_START_CORE) {
        o->oc.core_start = 1;
    }
    o->oc.seeds = (uint16_t *)(void *)runw;
    o->oc.pos = o->oc.seeds + n;
    o->oc.done = runw + 4u * n + MAGCAL_NEIGHBORS_WORKSPACE_LEN(n);
    o->oc.best = (float *)(void *)(runw + MAGCAL_OPTICS_BEST_OFFSET_(n));
    o->oc.id = -1;
    o->oc.best_id = -1;
    magcal_nbr_build_begin(&o->nb, &o->u.nbb, t->pts, n, t->eps, (magcal_neighbors_t)t->neighbors,
                           runw + 4u * n, window);
    o->st = (uint8_t)OR_BUILD;
    return o;
}

/* Filter: after the parameters, the ordering with on-the-fly extraction (and ring selection). */
static MAGCAL_NOINLINE void sl_filter_setup(sl_t *t)
{
    const size_t n = t->n;
    float window[4];
    const float *win = NULL;
    magcal_o2_ord_t *o;
    if (t->is_auto != 0u) {
        /* grid only over the ring's neighbourhood: far outliers are clamped into border cells */
        window[0] = t->cr[0] - 1.5f * t->cr[2] - t->eps_prime;
        window[1] = t->cr[1] - 1.5f * t->cr[2] - t->eps_prime;
        window[2] = t->cr[0] + 1.5f * t->cr[2] + t->eps_prime;
        window[3] = t->cr[1] + 1.5f * t->cr[2] + t->eps_prime;
        win = window;
    }
    o = sl_ord_begin(t, t->w + MAGCAL_OPTICS_FILTER_RUN_OFFSET_(n), win);
    o->oc.reach = (float *)(void *)t->w;
    o->oc.labels = (int16_t *)(void *)(t->w + 4u * n);
    o->oc.eps_prime = t->eps_prime;
    o->oc.use_sectors = 0;
    if (t->is_auto != 0u) {
        o->oc.use_sectors = 1; /* automatic mode: labels hold the sectors */
    }
}

/* The phase after the finiteness check. */
static void sl_after_finite(sl_t *t)
{
    if (t->kind == (uint8_t)K_RUN) {
        t->phase = (uint8_t)PH_ORDER; /* set up by magcal_optics_run */
    } else if (t->kind == (uint8_t)K_FILTER && t->is_auto == 0u) {
        sl_filter_setup(t);
        t->phase = (uint8_t)PH_ORDER;
    } else {
        magcal_o2_ce_begin(&t->u.ce);
        t->phase = (uint8_t)PH_CENTRE;
    }
}

/* PH_FINITE from t->i: 0 at a NaN/Inf coordinate, else 1 (own frame: float compares). */
static MAGCAL_NOINLINE int sl_finite(sl_t *t, int32_t *rem)
{
    const size_t n = t->n;
    size_t i = t->i;
    int32_t r = *rem;
    for (; i < n && r > 0; ++i) {
        if (!magcal_isfinite_f(t->pts[i].x) || !magcal_isfinite_f(t->pts[i].y)) {
            return 0;
        }
        CHARGE(r, W_FIN);
    }
    t->i = (uint16_t)i;
    *rem = r;
    return 1;
}

/* Thinning after the centre: cells of R/16 over the candidates (own frame: float math). */
static MAGCAL_NOINLINE void sl_thin_begin(sl_t *t)
{
    magcal_o2_th_begin(&t->u.th, t->cr[2] * AUTO_THIN_REL);
    t->phase = (uint8_t)PH_THIN;
}

/* After the ordering: the summary; MAGCAL_OK (run), MAGCAL_ERR_ALL_NOISE, or MAGCAL_IN_PROGRESS
 * with the output phase next (filter). */
static MAGCAL_NOINLINE magcal_status_t sl_order_done(sl_t *t)
{
    magcal_o2_ord_t *o = &t->u.ord;
    magcal_ocore_fill_info(t->io.info, &o->oc, o->nb.use_grid, t->eps,
                           t->kind == (uint8_t)K_RUN ? t->eps : t->eps_prime);
    if (t->kind == (uint8_t)K_RUN) {
        return MAGCAL_OK;
    }
    if (o->oc.best_id < 0) {
        return magcal_ocore_filter_out(&o->oc, t->n, t->out, t->io.info); /* ALL_NOISE */
    }
    t->i = 0u;
    t->phase = (uint8_t)PH_OUT;
    return MAGCAL_IN_PROGRESS;
}

/* One step of at most about `budget` estimated M4F instructions; MAGCAL_IN_PROGRESS or final.
 * w is t->w (set by begin only), passed by the caller so the analysers see that the phases'
 * writes into the workspace (the centre's a[], the masks) cannot change it. */
static magcal_status_t sl_step(sl_t *t, uint8_t *w, uint32_t budget)
{
    const size_t n = t->n;
    int32_t rem = budget > (uint32_t)SLICE_REM_MAX ? SLICE_REM_MAX : (int32_t)budget;
    magcal_status_t st = MAGCAL_OK;
    if (rem < 1) {
        rem = 1; /* progress for any budget */
    }
    while (rem > 0) {
        switch (t->phase) {
        case PH_FINITE:
            if (sl_finite(t, &rem) == 0) {
                return MAGCAL_ERR_NONFINITE;
            }
            if (t->i >= n) {
                sl_after_finite(t);
            }
            break;
        case PH_CENTRE:
            if (magcal_o2_ce_run(&t->u.ce, t->pts, n, w, t->cr, &st, &rem) == 0) {
                break;
            }
            if (st != MAGCAL_OK) {
                return st;
            }
            if (t->kind == (uint8_t)K_THIN) {
                sl_thin_begin(t);
            } else {
                (void)memset(&t->u.ae, 0, sizeof t->u.ae);
                t->u.ae.sectors = t->kind == (uint8_t)K_FILTER ? 1u : 0u;
                t->phase = (uint8_t)PH_AUTOEPS;
            }
            break;
        case PH_AUTOEPS:
            if (magcal_o2_ae_run(&t->u.ae, t->pts, n, w, t->cr, &t->eps_prime, &st, &rem) == 0) {
                break;
            }
            if (st != MAGCAL_OK || t->kind == (uint8_t)K_AUTO) {
                return st;
            }
            t->eps = t->eps_prime;
            t->phase = (uint8_t)PH_SETUP;
            break;
        case PH_SETUP:
            sl_filter_setup(t);
            t->phase = (uint8_t)PH_ORDER;
            CHARGE(rem, W_PHASE);
            break;
        case PH_ORDER: {
            magcal_o2_ord_t *o = &t->u.ord;
            if (magcal_o2_ord_run(o, &rem) == 0) {
                break;
            }
            st = sl_order_done(t);
            if (st != MAGCAL_IN_PROGRESS) {
                return st;
            }
            break;
        }
        case PH_OUT: {
            magcal_o2_ord_t *o = &t->u.ord;
            const int16_t *labels = o->oc.labels;
            const int32_t id = o->oc.best_id;
            size_t i = t->i;
            for (; i < n && rem > 0; ++i) {
                t->out[i] = (labels[i] == id) ? 1u : 0u;
                CHARGE(rem, W_OUT);
            }
            t->i = (uint16_t)i;
            if (i < n) {
                break;
            }
            if (t->io.info != NULL) {
                const int32_t count = o->oc.id + 1;
                t->io.info->n_clusters = (uint16_t)count;
                t->io.info->largest_id = (int16_t)o->oc.best_id;
                t->io.info->n_inliers = (uint16_t)o->oc.best_count;
                t->io.info->n_noise = (uint16_t)o->oc.n_noise;
            }
            return MAGCAL_OK;
        }
        case PH_THIN:
            if (magcal_o2_th_run(&t->u.th, t->pts, n, t->cr, w, t->io.cand, (unsigned)TH_MAXRUN,
                                 &rem) == 0) {
                break;
            }
            /* no clump: every candidate stays (thinning a plain ring only changes which minimal
             * sets are drawn, and on noisy real rings that moved the consensus' fixed point) */
            t->thin_all = (size_t)t->u.th.best <= AUTO_CLUMP_RATIO * (size_t)t->u.th.cap ? 1u : 0u;
            t->i = 0u;
            t->phase = (uint8_t)PH_THINMASK;
            break;
        default: { /* PH_THINMASK */
            const uint8_t *rep = w + AUTO_REP_OFF(n);
            size_t i = t->i;
            for (; i < n && rem > 0; ++i) {
                if (t->thin_all != 0u) {
                    t->out[i] = (uint8_t)((t->io.cand == NULL || t->io.cand[i] != 0u) ? 1u : 0u);
                } else {
                    t->out[i] = (uint8_t)(rep[i] & AUTO_REP);
                }
                CHARGE(rem, W_OUT);
            }
            t->i = (uint16_t)i;
            if (i >= n) {
                return MAGCAL_OK;
            }
            break;
        }
        }
    }
    return MAGCAL_IN_PROGRESS;
}

/* Run a begun state to its end (the one-shot calls: steps of unlimited budget). */
static magcal_status_t sl_finish(sl_t *t)
{
    uint8_t *const w = t->w;
    magcal_status_t st = MAGCAL_IN_PROGRESS;
    unsigned guard;
    for (guard = 0u; guard < SLICE_ONESHOT_ROUNDS && st == MAGCAL_IN_PROGRESS; ++guard) {
        st = sl_step(t, w, UINT32_MAX);
    }
    return st;
}

/* Public slice objects: the state's address (NULL once finished) and the final status. */
static magcal_status_t slice_step(void **state, magcal_status_t *status, uint32_t magic,
                                  uint32_t budget)
{
    magcal_status_t st;
    sl_t *t;
    if (magic != SLICE_MAGIC) {
        return MAGCAL_ERR_ARG;
    }
    if (*state == NULL) {
        return *status;
    }
    t = (sl_t *)*state;
    st = sl_step(t, t->w, budget);
    if (st != MAGCAL_IN_PROGRESS) {
        *status = st;
        *state = NULL;
    }
    return st;
}

magcal_status_t magcal_optics_run(const magcal_optics_cfg_t *cfg, const magcal_vec2_t *pts,
                                  size_t n, void *work, size_t work_len, uint16_t *order,
                                  float *reach, float *core, uint16_t *pred,
                                  magcal_optics_result_t *info)
{
    sl_t *t;
    magcal_o2_ord_t *o;
    magcal_status_t st;
    st = magcal_ocore_check_run(cfg, pts, work, order, reach, core);
    if (st != MAGCAL_OK) {
        return st;
    }
    st = magcal_ocore_check_n(n, cfg->min_pts);
    if (st != MAGCAL_OK) {
        return st;
    }
    if (work_len < MAGCAL_OPTICS_WORKSPACE_LEN(n)) {
        return MAGCAL_ERR_WORKSPACE;
    }
    t = sl_new(sl_at((uint8_t *)work, n), pts, n, (unsigned)K_RUN);
    sl_take_cfg(t, cfg);
    t->eps = cfg->eps;
    t->min_pts = cfg->min_pts;
    t->io.info = info;
    o = sl_ord_begin(t, (uint8_t *)work, NULL);
    o->oc.reach = reach;
    o->oc.order = order;
    o->oc.core = core;
    o->oc.pred = pred;
    return sl_finish(t);
}

magcal_status_t magcal_optics_auto_params(const magcal_vec2_t *pts, size_t n, void *work,
                                          size_t work_len, float *eps, uint16_t *min_pts,
                                          float *eps_prime)
{
    magcal_status_t st;
    sl_t *t;
    if (pts == NULL || work == NULL || eps == NULL || min_pts == NULL || eps_prime == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (magcal_misalign(work, 4u) != 0u) {
        return MAGCAL_ERR_ALIGNMENT;
    }
    st = magcal_ocore_check_n(n, AUTO_MIN_N);
    if (st != MAGCAL_OK) {
        return st;
    }
    if (work_len < MAGCAL_OPTICS_FILTER_WORKSPACE_LEN(n)) {
        return MAGCAL_ERR_WORKSPACE;
    }
    t = sl_new(sl_at((uint8_t *)work + MAGCAL_OPTICS_FILTER_RUN_OFFSET_(n), n), pts, n,
                 (unsigned)K_AUTO);
    t->w = (uint8_t *)work;
    st = sl_finish(t);
    if (st != MAGCAL_OK) {
        return st;
    }
    *eps = t->eps_prime;
    *eps_prime = t->eps_prime;
    *min_pts = (uint16_t)AUTO_MIN_PTS;
    return MAGCAL_OK;
}

magcal_status_t magcal_optics_filter_begin(magcal_optics_filter_slice_t *s,
                                           const magcal_optics_cfg_t *cfg,
                                           const magcal_vec2_t *pts, size_t n, void *work,
                                           size_t work_len, uint8_t *inlier_mask,
                                           magcal_optics_result_t *info)
{
    magcal_optics_cfg_t use;
    magcal_status_t st;
    float eps_prime = 0.0f;
    int is_auto = 0;
    sl_t *t;
    if (s == NULL) {
        return MAGCAL_ERR_NULL;
    }
    s->magic_ = SLICE_MAGIC;
    s->state_ = NULL;
    if (cfg == NULL || pts == NULL || work == NULL || inlier_mask == NULL) {
        st = MAGCAL_ERR_NULL;
    } else if (magcal_misalign(work, 4u) != 0u) {
        st = MAGCAL_ERR_ALIGNMENT;
    } else if (!(cfg->eps > 0.0f)) {
        use = *cfg;
        is_auto = 1;
        use.eps = 1.0f;
        use.min_pts = (uint16_t)AUTO_MIN_PTS;
        st = cfg->eps != cfg->eps ? MAGCAL_ERR_ARG : magcal_ocore_check_cfg(&use); /* NaN: not auto */
        if (st == MAGCAL_OK) {
            st = magcal_ocore_check_n(n, AUTO_MIN_N);
        }
    } else {
        st = magcal_ocore_check_cfg(cfg);
        eps_prime = cfg->eps_prime == 0.0f ? cfg->eps : cfg->eps_prime;
        if (st == MAGCAL_OK &&
            (!(eps_prime > 0.0f) || !magcal_isfinite_f(eps_prime) || eps_prime > cfg->eps)) {
            st = MAGCAL_ERR_ARG;
        }
        if (st == MAGCAL_OK) {
            st = magcal_ocore_check_n(n, cfg->min_pts);
        }
    }
    if (st == MAGCAL_OK && work_len < MAGCAL_OPTICS_FILTER_WORKSPACE_LEN(n)) {
        st = MAGCAL_ERR_WORKSPACE;
    }
    if (st != MAGCAL_OK) {
        s->status_ = st;
        return st;
    }
    t = sl_new(sl_at((uint8_t *)work + MAGCAL_OPTICS_FILTER_RUN_OFFSET_(n), n), pts, n,
                 (unsigned)K_FILTER);
    sl_take_cfg(t, cfg);
    t->w = (uint8_t *)work;
    t->out = inlier_mask;
    t->io.info = info;
    t->is_auto = (uint8_t)is_auto;
    if (is_auto == 0) {
        t->eps = cfg->eps;
        t->eps_prime = eps_prime;
        t->min_pts = cfg->min_pts;
    }
    s->state_ = t;
    s->status_ = MAGCAL_IN_PROGRESS;
    return MAGCAL_OK;
}

magcal_status_t magcal_optics_filter_step(magcal_optics_filter_slice_t *s, uint32_t budget)
{
    if (s == NULL) {
        return MAGCAL_ERR_NULL;
    }
    return slice_step(&s->state_, &s->status_, s->magic_, budget);
}

magcal_status_t magcal_optics_filter(const magcal_optics_cfg_t *cfg, const magcal_vec2_t *pts,
                                     size_t n, void *work, size_t work_len, uint8_t *inlier_mask,
                                     magcal_optics_result_t *info)
{
    magcal_optics_filter_slice_t s;
    magcal_status_t st = magcal_optics_filter_begin(&s, cfg, pts, n, work, work_len, inlier_mask,
                                                    info);
    if (st == MAGCAL_OK) {
        st = sl_finish((sl_t *)s.state_);
    }
    return st;
}

magcal_status_t magcal_optics_thin_begin(magcal_optics_thin_slice_t *s, const magcal_vec2_t *pts,
                                         size_t n, const uint8_t *cand, void *work,
                                         size_t work_len, uint8_t *rep_mask)
{
    magcal_status_t st;
    sl_t *t;
    if (s == NULL) {
        return MAGCAL_ERR_NULL;
    }
    s->magic_ = SLICE_MAGIC;
    s->state_ = NULL;
    if (pts == NULL || work == NULL || rep_mask == NULL) {
        st = MAGCAL_ERR_NULL;
    } else if (magcal_misalign(work, 4u) != 0u) {
        st = MAGCAL_ERR_ARG;
    } else {
        st = magcal_ocore_check_n(n, AUTO_MIN_N);
    }
    if (st == MAGCAL_OK && work_len < MAGCAL_OPTICS_FILTER_WORKSPACE_LEN(n)) {
        st = MAGCAL_ERR_WORKSPACE;
    }
    if (st != MAGCAL_OK) {
        s->status_ = st;
        return st;
    }
    t = sl_new(sl_thin_at((uint8_t *)work, n), pts, n, (unsigned)K_THIN);
    t->w = (uint8_t *)work;
    t->out = rep_mask;
    t->io.cand = cand;
    s->state_ = t;
    s->status_ = MAGCAL_IN_PROGRESS;
    return MAGCAL_OK;
}

magcal_status_t magcal_optics_thin_step(magcal_optics_thin_slice_t *s, uint32_t budget)
{
    if (s == NULL) {
        return MAGCAL_ERR_NULL;
    }
    return slice_step(&s->state_, &s->status_, s->magic_, budget);
}

magcal_status_t magcal_optics_thin(const magcal_vec2_t *pts, size_t n, const uint8_t *cand,
                                   void *work, size_t work_len, uint8_t *rep_mask)
{
    magcal_optics_thin_slice_t s;
    magcal_status_t st = magcal_optics_thin_begin(&s, pts, n, cand, work, work_len, rep_mask);
    if (st == MAGCAL_OK) {
        st = sl_finish((sl_t *)s.state_);
    }
    return st;
}

magcal_status_t magcal_ocore_check_run(const magcal_optics_cfg_t *cfg, const void *pts, const void *work,
                                       const uint16_t *order, const float *reach, const float *core)
{
    magcal_status_t st;
    if (cfg == NULL || pts == NULL || work == NULL || order == NULL || reach == NULL ||
        core == NULL) {
        return MAGCAL_ERR_NULL;
    }
    st = magcal_ocore_check_cfg(cfg);
    if (st != MAGCAL_OK) {
        return st;
    }
    if (magcal_misalign(work, 4u) != 0u) {
        return MAGCAL_ERR_ALIGNMENT;
    }
    return MAGCAL_OK;
}

magcal_status_t magcal_ocore_check_cfg(const magcal_optics_cfg_t *cfg)
{
    /* eps^2 is the neighbour threshold: it must be a normal float (neighbors.h) */
    if (magcal_nbr_eps_ok(cfg->eps) == 0) {
        return MAGCAL_ERR_ARG;
    }
    if (cfg->min_pts < 2u || cfg->min_pts > MAGCAL_MAX_MIN_PTS) {
        return MAGCAL_ERR_ARG;
    }
    if (cfg->order != MAGCAL_OPTICS_IMPROVED
#if MAGCAL_CFG_ENABLE_OPTICS_CLASSIC
        && cfg->order != MAGCAL_OPTICS_CLASSIC
#endif
#ifdef MAGCAL_OPTICS_BENCH_SORTED_LIST
        && cfg->order != MAGCAL_OPTICS_SORTED_LIST_
#endif
    ) {
        return MAGCAL_ERR_ARG;
    }
    if (cfg->neighbors != MAGCAL_NEIGHBORS_BRUTE && cfg->neighbors != MAGCAL_NEIGHBORS_GRID) {
        return MAGCAL_ERR_ARG;
    }
    if (cfg->start != MAGCAL_OPTICS_START_INDEX && cfg->start != MAGCAL_OPTICS_START_CORE) {
        return MAGCAL_ERR_ARG;
    }
    return MAGCAL_OK;
}
