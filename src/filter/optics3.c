/*
 * The 3-D OPTICS filter (optics.h magcal_optics_filter3; optics3_internal.h): with given
 * parameters one ordering with on-the-fly extraction (optics3_order.c); with automatic ones the
 * rule (optics3_auto.c), ExtractDBSCAN of its ordering, and the widest-shell selection (a rest
 * phase, one direction, cannot win over the rotation).
 */
#include <math.h>
#include <string.h>

#include "magcal/optics.h"
#include "magcal_internal.h"

#if MAGCAL_CFG_ENABLE_3D /* whole file: config.h feature switch (optics_core.h inside) */
#include "optics3_internal.h"

/* Direction cell (0..95) of d on the cube around the centre: the face of its largest
 * component (6), then 4 x 4 bins of the other two over [-1, 1] (no trigonometry). */
static unsigned dir_cell3(float dx, float dy, float dz)
{
    const float ax = fabsf(dx);
    const float ay = fabsf(dy);
    const float az = fabsf(dz);
    unsigned face;
    float m;
    float u;
    float v;
    float fu;
    float fv;
    int32_t iu;
    int32_t iv;
    if (ax >= ay && ax >= az) {
        face = 1u;
        if (dx >= 0.0f) {
            face = 0u;
        }
        m = ax;
        u = dy;
        v = dz;
    } else if (ay >= az) {
        face = 3u;
        if (dy >= 0.0f) {
            face = 2u;
        }
        m = ay;
        u = dx;
        v = dz;
    } else {
        face = 5u;
        if (dz >= 0.0f) {
            face = 4u;
        }
        m = az;
        u = dx;
        v = dy;
    }
    fu = (u / m + 1.0f) * 2.0f;
    fv = (v / m + 1.0f) * 2.0f;
    iu = (int32_t)fu;
    iv = (int32_t)fv;
    iu = iu < 0 ? 0 : (iu > 3 ? 3 : iu);
    iv = iv < 0 ? 0 : (iv > 3 ? 3 : iv);
    return face * 16u + (unsigned)iu * 4u + (unsigned)iv;
}

#define O3S_MAGIC 0x4F335331u /* "O3S1": a begun slice */

#ifdef MAGCAL_BENCH_TRACE
uint32_t magcal_bench_o3_visits[P3_N + 1];
#endif

static magcal_o3s_t *o3s_of(magcal_optics3_slice_t *sl)
{
    return (magcal_o3s_t *)(void *)sl;
}

static int16_t *labels_of(magcal_o3s_t *s)
{
    uint8_t *w = s->w;
    return (int16_t *)(void *)(w + MAGCAL_OPTICS3_FILTER_RUN_OFFSET_(s->n));
}

/* ExtractDBSCAN of the rule's ordering at its eps' (as magcal_optics_extract_dbscan; the run's
 * workspace is free again: labels there) and the noise count, per point. 1 when done. */
static int label_run(magcal_o3s_t *s, int32_t *rem)
{
    const magcal_o3_auto_t *au = s->au;
    int16_t *labels = labels_of(s);
    const float eps_prime = au->eps_prime;
    magcal_o3_tail_t *t = &s->t;
    size_t k = t->i;
    int32_t r = *rem;
    while (k < s->n && r > 0) {
        const size_t p = au->order[k];
        int16_t lab = (int16_t)t->id;
        CHARGE3(r, W3_LABEL);
        if (au->reach[p] > eps_prime) {
            lab = MAGCAL_OPTICS_NOISE;
            if (au->core[p] <= eps_prime) {
                t->id++;
                lab = (int16_t)t->id;
            }
        }
        labels[p] = lab;
        t->n_noise = (uint16_t)(t->n_noise + ((lab == MAGCAL_OPTICS_NOISE) ? 1u : 0u));
        ++k;
    }
    *rem = r;
    t->i = (uint16_t)k;
    return (k < s->n) ? 0 : 1;
}

/*
 * Shell selection of the automatic filter, per position of the ordering: among the clusters of
 * the labels (each cluster is one stretch of the ordering, noise in between), keep the one whose
 * shell-band samples occupy the most direction cells around the centre, then the most samples,
 * then the smaller id. A rest phase (one direction) cannot win over the rotation. 1 when done.
 */
static int wide_run(magcal_o3s_t *s, int32_t *rem)
{
    const magcal_o3_auto_t *au = s->au;
    const int16_t *labels = labels_of(s);
    magcal_o3_tail_t *t = &s->t;
    size_t k = t->i;
    int32_t r = *rem;
    while (k <= au->n && r > 0) {
        const size_t p = k < au->n ? au->order[k] : 0u;
        const int32_t lab = k < au->n ? (int32_t)labels[p] : -2;
        CHARGE3(r, W3_WIDE);
        if (lab == -2 || (lab >= 0 && lab != t->id)) {
            if (t->id >= 0) {
                const uint32_t ext = magcal_ocore_popcount(s->u.wide.cur3[0]) + magcal_ocore_popcount(s->u.wide.cur3[1]) +
                                     magcal_ocore_popcount(s->u.wide.cur3[2]);
                if (ext > s->u.wide.best_ext || (ext == s->u.wide.best_ext && t->cur_count > t->best_count)) {
                    s->u.wide.best_ext = ext;
                    t->best_count = t->cur_count;
                    t->best_id = t->id;
                }
            }
            t->id = lab;
            t->cur_count = 0u;
            s->u.wide.cur3[0] = 0u;
            s->u.wide.cur3[1] = 0u;
            s->u.wide.cur3[2] = 0u;
        }
        if (lab >= 0) {
            const float dx = au->pts[p].x - au->cen.x;
            const float dy = au->pts[p].y - au->cen.y;
            const float dz = au->pts[p].z - au->cen.z;
            const float d2 = dx * dx + dy * dy + dz * dz;
            t->cur_count++;
            if (d2 >= au->lo2 && d2 <= au->hi2) {
                const unsigned cell = dir_cell3(dx, dy, dz);
                s->u.wide.cur3[cell >> 5] |= 1u << (cell & 31u);
            }
        }
        ++k;
    }
    *rem = r;
    t->i = (uint16_t)k;
    return (k <= au->n) ? 0 : 1;
}

/* The automatic filter's info (written with MAGCAL_OK and MAGCAL_ERR_ALL_NOISE). */
static void auto_info(const magcal_o3s_t *s, int16_t id, uint16_t count)
{
    magcal_optics_result_t *info = s->info;
    if (info != NULL) {
        (void)memset(info, 0, sizeof *info);
        info->eps = s->au->eps;
        info->eps_prime = s->au->eps_prime;
        info->min_pts = (uint16_t)AUTO3_MIN_PTS;
        info->neighbors = s->au->neighbors;
        info->n_clusters = s->t.n_clusters;
        info->largest_id = id;
        info->n_inliers = count;
        info->n_noise = s->t.n_noise;
    }
}

/* The filter's tail (extraction, selection, mask) and the given-parameter path but its ordering.
 * 1 when done. */
static MAGCAL_NOINLINE int tail_pass(magcal_o3s_t *s, int32_t *rem)
{
    magcal_o3_tail_t *t = &s->t;
    const size_t n = s->n;
    int fin = 0;
    switch (s->phase) {
    case O3S_LABEL:
        if (label_run(s, rem) != 0) {
            const int32_t nc = t->id + 1;
            t->n_clusters = (uint16_t)nc;
            (void)memset(&s->u.wide, 0, sizeof s->u.wide);
            s->u.wide.best_ext = 0u;
            t->best_count = 0u;
            t->cur_count = 0u;
            t->id = -1;
            t->best_id = -1;
            t->i = 0u;
            s->phase = (uint8_t)O3S_WIDE;
        }
        break;
    case O3S_WIDE:
        if (wide_run(s, rem) != 0) {
            if (t->best_id < 0) {
                auto_info(s, MAGCAL_OPTICS_NOISE, 0u);
                s->status = (int32_t)MAGCAL_ERR_ALL_NOISE; /* mask untouched */
                fin = 1;
            } else {
                t->i = 0u;
                s->phase = (uint8_t)O3S_MASK;
            }
        }
        break;
    case O3S_MASK: {
        const int16_t *labels = labels_of(s);
        size_t k = t->i;
        while (k < n && *rem > 0) {
            CHARGE3(*rem, W3_OUT);
            s->mask[k] = (int32_t)labels[k] == t->best_id ? 1u : 0u;
            ++k;
        }
        t->i = (uint16_t)k;
        if (k >= n) {
            auto_info(s, (int16_t)t->best_id, t->best_count);
            s->status = (int32_t)MAGCAL_OK;
            fin = 1;
        }
        break;
    }
    case O3S_GRID: {
        uint8_t *w = s->w;
        magcal_o3_ctx_t *c;
        /* one unit: the grid build over n points (brute force: the context only) */
        CHARGE3_K(*rem, W3_GRIDB, (s->use.neighbors == MAGCAL_NEIGHBORS_GRID) ? n : 1u);
        c = magcal_o3_ctx_setup(&s->use, s->pts, n, w + MAGCAL_OPTICS3_FILTER_RUN_OFFSET_(n));
        c->oc.reach = (float *)(void *)w;
        c->oc.labels = (int16_t *)(void *)(w + 4u * n);
        c->oc.eps_prime = s->use.eps_prime;
        s->c = c;
        magcal_o3_ord_begin(&s->u.ord);
        s->phase = (uint8_t)O3S_GORDER;
        break;
    }
    default: /* O3S_GOUT: one unit, the mask over n points */
        CHARGE3_K(*rem, W3_OUT, n);
        magcal_ocore_fill_info(s->info, &s->c->oc, s->c->use_grid, s->use.eps, s->use.eps_prime);
        s->status = (int32_t)magcal_ocore_filter_out(&s->c->oc, n, s->mask, s->info);
        fin = 1;
        break;
    }
    return fin;
}

/* The finiteness pass, then the workspace check (the one-shot call's order of checks). */
static int fin_pass(magcal_o3s_t *s, int32_t *rem)
{
    const int rc = magcal_o3_fin_run(s->pts, s->n, &s->t.i, rem);
    int fin = 0;
    if (rc < 0) {
        s->status = (int32_t)MAGCAL_ERR_NONFINITE;
        fin = 1;
    } else if (rc == 0) {
        /* paused */
    } else if (s->work_len < MAGCAL_OPTICS3_FILTER_WORKSPACE_LEN(s->n)) {
        s->status = (int32_t)MAGCAL_ERR_WORKSPACE;
        fin = 1;
    } else if (s->autom != 0u) {
        s->au = magcal_o3_auto_record(s->w, s->n);
        s->t.i = 0u;
        s->t.rng = AUTO3_SEED;
        s->phase = (uint8_t)O3S_PAIRS;
    } else {
        s->phase = (uint8_t)O3S_GRID;
    }
    return fin;
}

/* Work within *rem; 1 when the filter (or the rule, params) has finished (s->status). */
static int o3s_run(magcal_o3s_t *s, int32_t *rem)
{
    int fin = 0;
    while (*rem > 0 && fin == 0) {
        if (s->phase == O3S_ORDER || s->phase == O3S_GORDER) {
            /* the ordering straight from here: its deep path (the grid PROCESS) under few frames */
            if (s->c == NULL) {
                CHARGE3(*rem, W3_PHASE);
                magcal_o3_auto_order_begin(s);
            } else if (magcal_o3_ord_run(&s->u.ord, s->c, rem) != 0) {
                if (s->phase == O3S_ORDER) {
                    magcal_o3_auto_ordered(s);
                } else {
                    s->phase = (uint8_t)O3S_GOUT;
                }
            } else {
                /* paused inside the ordering */
            }
        } else if (s->phase == O3S_FIN) {
            fin = fin_pass(s, rem);
        } else if (s->phase < O3S_AUTO_DONE) {
            if (magcal_o3_auto_step(s, rem) != 0) {
                if (s->status == (int32_t)MAGCAL_IN_PROGRESS && s->params != 0u) {
                    s->status = (int32_t)MAGCAL_OK; /* magcal_optics_auto_params3: eps' found */
                }
                if (s->status != (int32_t)MAGCAL_IN_PROGRESS) {
                    fin = 1;
                }
                s->t.i = 0u;
                s->t.id = -1;
                s->t.n_noise = 0u;
                s->phase = (uint8_t)O3S_LABEL;
            }
        } else {
            fin = tail_pass(s, rem);
        }
    }
    if (fin != 0) {
        s->phase = (uint8_t)O3S_DONE;
    }
    return fin;
}

/* The checks of the one-shot calls that cost O(1), in their order; the rest in the steps. */
static magcal_status_t o3s_begin(magcal_o3s_t *s, const magcal_optics_cfg_t *cfg, const magcal_vec3_t *pts,
                                 size_t n, void *work, size_t work_len, uint8_t *inlier_mask,
                                 magcal_optics_result_t *info)
{
    magcal_status_t st;
    int autom = 0;
    if (cfg == NULL || pts == NULL || work == NULL || (inlier_mask == NULL && s->params == 0u)) {
        return MAGCAL_ERR_NULL;
    }
    if (magcal_misalign(work, 4u) != 0u) {
        return MAGCAL_ERR_ALIGNMENT;
    }
    s->use = *cfg;
    if (!(cfg->eps > 0.0f)) {
        if (cfg->eps != cfg->eps) {
            return MAGCAL_ERR_ARG; /* NaN is not "auto" */
        }
        s->use.eps = 1.0f;
        s->use.min_pts = (uint16_t)AUTO3_MIN_PTS;
        st = magcal_ocore_check_cfg(&s->use);
        if (st == MAGCAL_OK) {
            st = magcal_ocore_check_n(n, AUTO3_MIN_N);
        }
        autom = 1;
    } else {
        st = magcal_ocore_check_cfg(&s->use);
        if (st == MAGCAL_OK) {
            s->use.eps_prime = cfg->eps_prime == 0.0f ? cfg->eps : cfg->eps_prime;
            if (!(s->use.eps_prime > 0.0f) || !magcal_isfinite_f(s->use.eps_prime) ||
                s->use.eps_prime > cfg->eps) {
                st = MAGCAL_ERR_ARG;
            }
        }
        if (st == MAGCAL_OK) {
            st = magcal_ocore_check_n(n, s->use.min_pts);
        }
    }
    if (st != MAGCAL_OK) {
        return st;
    }
    s->pts = pts;
    s->n = n;
    s->w = (uint8_t *)work;
    s->work_len = work_len;
    s->mask = inlier_mask;
    s->info = info;
    s->c = NULL;
    s->au = NULL; /* the automatic rule's record: written after the workspace check */
    s->autom = (uint8_t)autom;
    s->phase = (uint8_t)O3S_FIN;
    s->status = (int32_t)MAGCAL_IN_PROGRESS;
    s->magic = O3S_MAGIC;
    return MAGCAL_OK;
}

static magcal_status_t o3s_start(magcal_optics3_slice_t *sl, const magcal_optics_cfg_t *cfg,
                                 const magcal_vec3_t *pts, size_t n, void *work, size_t work_len,
                                 uint8_t *inlier_mask, magcal_optics_result_t *info, uint8_t params)
{
    magcal_o3s_t *s;
    if (sl == NULL) {
        return MAGCAL_ERR_NULL;
    }
    s = o3s_of(sl);
    (void)memset(s, 0, sizeof *s);
    s->params = params;
    return o3s_begin(s, cfg, pts, n, work, work_len, inlier_mask, info);
}

magcal_status_t magcal_optics_filter3_begin(magcal_optics3_slice_t *s, const magcal_optics_cfg_t *cfg,
                                            const magcal_vec3_t *pts, size_t n, void *work,
                                            size_t work_len, uint8_t *inlier_mask,
                                            magcal_optics_result_t *info)
{
    return o3s_start(s, cfg, pts, n, work, work_len, inlier_mask, info, 0u);
}

magcal_status_t magcal_optics_filter3_step(magcal_optics3_slice_t *sl, uint32_t budget, uint32_t *used)
{
    magcal_o3s_t *s;
    int32_t r0 = SLICE_REM_MAX;
    int32_t rem;
    if (sl == NULL) {
        return MAGCAL_ERR_NULL;
    }
    s = o3s_of(sl);
    if (used != NULL) {
        *used = 0u;
    }
    if (s->magic != O3S_MAGIC) {
        return MAGCAL_ERR_ARG;
    }
    if (s->status != (int32_t)MAGCAL_IN_PROGRESS) {
        return (magcal_status_t)s->status;
    }
    if (budget < (uint32_t)SLICE_REM_MAX) {
        r0 = (budget == 0u) ? 1 : (int32_t)budget; /* a zero budget still makes progress */
    }
    rem = r0;
    (void)o3s_run(s, &rem);
    if (used != NULL) {
        *used = (uint32_t)r0 - (uint32_t)rem; /* rem >= -(one visit): the charged total */
    }
#ifdef MAGCAL_BENCH_TRACE
    magcal_bench_o3_visits[P3_N] += (uint32_t)r0 - (uint32_t)rem;
#endif
    return (magcal_status_t)s->status;
}

/* begin + the steps' work at an unlimited budget (one code path with the sliced call; the run
 * straight from here, not through the public step: the stack). */
static magcal_status_t o3s_finish(magcal_optics3_slice_t *sl, magcal_status_t st0)
{
    magcal_o3s_t *s = o3s_of(sl);
    unsigned guard;
    if (st0 != MAGCAL_OK) {
        return st0;
    }
    for (guard = 0u; guard < SLICE_ONESHOT_ROUNDS; ++guard) {
        int32_t rem = SLICE_REM_MAX;
        if (o3s_run(s, &rem) != 0) {
            break;
        }
    }
    return (magcal_status_t)s->status;
}

magcal_status_t magcal_optics_filter3(const magcal_optics_cfg_t *cfg, const magcal_vec3_t *pts,
                                      size_t n, void *work, size_t work_len, uint8_t *inlier_mask,
                                      magcal_optics_result_t *info)
{
    magcal_optics3_slice_t sl;
    return o3s_finish(&sl, o3s_start(&sl, cfg, pts, n, work, work_len, inlier_mask, info, 0u));
}

magcal_status_t magcal_optics_auto_params3(const magcal_vec3_t *pts, size_t n, void *work,
                                           size_t work_len, float *eps, uint16_t *min_pts,
                                           float *eps_prime)
{
    static const magcal_optics_cfg_t cfg = MAGCAL_OPTICS_CFG_DEFAULT;
    magcal_optics3_slice_t sl;
    magcal_status_t st;
    if (eps == NULL || min_pts == NULL || eps_prime == NULL) {
        return MAGCAL_ERR_NULL;
    }
    st = o3s_finish(&sl, o3s_start(&sl, &cfg, pts, n, work, work_len, NULL, NULL, 1u));
    if (st == MAGCAL_OK) {
        const magcal_o3s_t *s = o3s_of(&sl);
        *eps = s->au->eps;
        *eps_prime = s->au->eps_prime;
        *min_pts = (uint16_t)AUTO3_MIN_PTS;
    }
    return st;
}

#endif /* MAGCAL_CFG_ENABLE_3D */
