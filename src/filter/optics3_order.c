/*
 * The 3-D OPTICS ordering loop (algorithms.md 4.1-4.2; optics3_internal.h): PROCESS with the
 * brute-force or grid neighbour search (optics3_grid.c), START_CORE, the point checks, the run
 * workspace's layout and magcal_optics_run3.
 */
#include <math.h>
#include <string.h>

#include "magcal/optics.h"
#include "magcal_internal.h"

#if MAGCAL_CFG_ENABLE_3D /* whole file: config.h feature switch (optics_core.h inside) */
#include "optics3_internal.h"
#include "optics_core_update.h"

/* PROCESS(p) with the grid: both passes over the candidate buckets (one unit). */
static MAGCAL_NOINLINE void process3_grid(magcal_o3_ctx_t *c, size_t p, float core_p0)
{
    float *best = c->oc.best;
    uint16_t *bk = c->bk;
    const size_t m = c->oc.min_pts;
    const magcal_vec3_t *pts = c->pts;
    const magcal_vec3_t *pp = &pts[p];
    const float eps2 = c->eps2;
    const size_t nb = magcal_o3_grid_query(c, p, bk);
    float core_p = core_p0;
    float core2 = INFINITY;
    size_t cnt = 0u;
    size_t t;
    size_t k;
    for (t = 0; t < nb; ++t) {
        for (k = c->start[bk[t]]; k < c->start[bk[t] + 1u]; ++k) {
            float d2 = magcal_o3_dist2(&pts[c->live[k]], pp);
            if (d2 <= eps2 && (cnt < m || d2 < best[m - 1u])) {
                cnt = magcal_ocore_best_insert(best, cnt, m, d2);
            }
        }
    }
    if (cnt >= m) {
        core2 = best[m - 1u];
        core_p = sqrtf(core2);
    }
    if (c->oc.core != NULL) {
        c->oc.core[p] = core_p;
    }
    if (c->oc.labels != NULL) {
        magcal_ocore_extract_step(&c->oc, p, core_p);
    }
    if (cnt < m) {
        return;
    }
    for (t = 0; t < nb; ++t) {
        for (k = c->start[bk[t]]; k < c->start[bk[t] + 1u]; ++k) {
            size_t j = c->live[k];
            float d2 = magcal_o3_dist2(&pts[j], pp);
            if (d2 <= eps2 && magcal_ocore_is_done(&c->oc, j) == 0) {
                float r = magcal_ocore_reach_of(d2, core_p, core2);
                if (r < c->oc.reach[j]) {
                    magcal_ocore_update(&c->oc, p, j, r);
                }
            }
        }
    }
}

/* 1 when p has >= MinPts points (itself included) within eps, with the grid: the start test of
 * START_CORE (one unit; the brute-force test is ord_iscore's, per candidate). */
static MAGCAL_NOINLINE int is_core3(magcal_o3_ctx_t *c, size_t p)
{
    const magcal_vec3_t *pts = c->pts;
    const magcal_vec3_t *pp = &pts[p];
    const size_t m = c->oc.min_pts;
    const size_t nb = magcal_o3_grid_query(c, p, c->bk);
    size_t cnt = 0u;
    size_t t;
    size_t k;
    for (t = 0; t < nb && cnt < m; ++t) {
        for (k = c->start[c->bk[t]]; k < c->start[c->bk[t] + 1u] && cnt < m; ++k) {
            cnt += magcal_o3_dist2(&pts[c->live[k]], pp) <= c->eps2 ? 1u : 0u;
        }
    }
    return cnt >= m ? 1 : 0;
}

/* Start of PROCESS(p): mark it; then with the grid the whole PROCESS (one unit), else pass 1. */
static void ord_process_begin(magcal_o3_ord_t *o, magcal_o3_ctx_t *c, size_t p)
{
    o->p = (uint16_t)p;
    magcal_ocore_mark(&c->oc, p);
    if (c->use_grid != 0) {
        o->st = (uint8_t)O3_OR_GRIDP; /* the whole PROCESS next, in ord_run's frame (stack) */
    } else {
        o->k = 0u;
        o->cnt = 0u;
        o->lim = c->eps2;
        o->st = (uint8_t)O3_OR_P1;
    }
}

/* After a PROCESS: the next seed (the minimum scan), or the outer scan's next point. */
static void ord_after(magcal_o3_ord_t *o, magcal_o3_ctx_t *c, int32_t *rem)
{
    if (c->oc.n_seeds == 0u) {
        o->s++;
        o->st = (uint8_t)O3_OR_SCAN;
    } else if (c->oc.mode != MAGCAL_OPTICS_IMPROVED) {
        CHARGE3(*rem, W3_UPD); /* a heap pop (CLASSIC) */
        ord_process_begin(o, c, magcal_ocore_pop_min(&c->oc));
    } else {
        o->k = 1u;
        o->pbest = 0u;
        o->pbq = c->oc.seeds[0];
        o->pbr = c->oc.reach[o->pbq];
        o->st = (uint8_t)O3_OR_POP;
    }
}

/*
 * PROCESS(p) of algorithms.md 4.2, brute force: pass 1 sweeps all n points for the core distance
 * (MinPts-th smallest d^2, p itself included); pass 2 sweeps the compact list of unprocessed
 * points for the reachability updates (dropping p, the only point processed since the previous
 * pass), so the k-th call costs n + (n - k) squared distances: about 1.5 n^2 per run.
 * r = max(core, d) is taken as core without a square root when d^2 <= core^2 (sqrtf is monotone
 * and core = sqrtf(core^2), so no bit changes). Pass 1 (o->st O3_OR_P1) per candidate.
 */
static int ord_p1(magcal_o3_ord_t *o, magcal_o3_ctx_t *c, int32_t *rem)
{
    float *best = c->oc.best;
    const size_t m = c->oc.min_pts;
    const size_t n = c->n;
    const magcal_vec3_t *pts = c->pts;
    const magcal_vec3_t *pp = &pts[o->p];
    float lim = o->lim;
    size_t cnt = o->cnt;
    size_t k = o->k;
    int32_t r = *rem;
    while (k < n && r > 0) {
        const float d2 = magcal_o3_dist2(&pts[k], pp);
        CHARGE3(r, W3_CAND);
        if (d2 <= lim && (cnt < m || d2 < lim)) {
            cnt = magcal_ocore_best_insert(best, cnt, m, d2);
            if (cnt == m) {
                lim = best[m - 1u];
            }
        }
        ++k;
    }
    *rem = r;
    o->lim = lim;
    o->cnt = (uint16_t)cnt;
    o->k = (uint16_t)k;
    if (k < n) {
        return 0;
    }
    o->core_p = INFINITY;
    o->core2 = INFINITY;
    if (cnt >= m) {
        o->core2 = best[m - 1u];
        o->core_p = sqrtf(o->core2);
    }
    if (c->oc.core != NULL) {
        c->oc.core[o->p] = o->core_p;
    }
    if (c->oc.labels != NULL) {
        magcal_ocore_extract_step(&c->oc, o->p, o->core_p);
    }
    o->k = 0u;
    o->w = 0u;
    o->st = (uint8_t)O3_OR_P2;
    return 1;
}

/* Pass 2 (O3_OR_P2) per element of the live list. */
static int ord_p2(magcal_o3_ord_t *o, magcal_o3_ctx_t *c, int32_t *rem)
{
    const magcal_vec3_t *pts = c->pts;
    const size_t p = o->p;
    const magcal_vec3_t *pp = &pts[p];
    const float eps2 = c->eps2;
    const float core_p = o->core_p;
    uint16_t *live = c->live;
    const size_t nl = c->n_live;
    size_t w = o->w;
    size_t k = o->k;
    int32_t r = *rem;
    while (k < nl && r > 0) {
        const size_t j = live[k];
        CHARGE3(r, W3_REACH);
        if (j != p) {
            live[w] = (uint16_t)j;
            ++w;
            if (core_p < INFINITY) {
                const float d2 = magcal_o3_dist2(&pts[j], pp);
                if (d2 <= eps2) {
                    const float rr = magcal_ocore_reach_of(d2, core_p, o->core2);
                    if (rr < c->oc.reach[j]) {
                        CHARGE3(r, W3_UPD);
                        magcal_ocore_update(&c->oc, p, j, rr);
                    }
                }
            }
        }
        ++k;
    }
    *rem = r;
    o->w = (uint16_t)w;
    o->k = (uint16_t)k;
    if (k < nl) {
        return 0;
    }
    c->n_live = w;
    return 1;
}

/* The IMPROVED minimum scan (O3_OR_POP) per seed: the seed of least (reach, index), removed as
 * magcal_ocore_pop_min does. */
static int ord_pop(magcal_o3_ord_t *o, magcal_o3_ctx_t *c, int32_t *rem)
{
    const float *reach = c->oc.reach;
    const uint16_t *seeds = c->oc.seeds;
    const size_t ns = c->oc.n_seeds;
    size_t k = o->k;
    int32_t r = *rem;
    while (k < ns && r > 0) {
        const uint16_t q = seeds[k];
        const float rq = reach[q];
        CHARGE3(r, W3_POP);
        if (rq < o->pbr || (rq == o->pbr && q < o->pbq)) {
            o->pbr = rq;
            o->pbq = q;
            o->pbest = (uint16_t)k;
        }
        ++k;
    }
    *rem = r;
    o->k = (uint16_t)k;
    if (k < ns) {
        return 0;
    }
    c->oc.n_seeds--;
    c->oc.seeds[o->pbest] = c->oc.seeds[c->oc.n_seeds];
    return 1;
}

/* START_CORE's test of o->s, brute force per candidate (O3_OR_ISCORE): 1 when decided. */
static int ord_iscore(magcal_o3_ord_t *o, const magcal_o3_ctx_t *c, int32_t *rem)
{
    const magcal_vec3_t *pts = c->pts;
    const magcal_vec3_t *pp = &pts[o->s];
    const size_t m = c->oc.min_pts;
    size_t cnt = o->cnt;
    size_t k = o->k;
    int32_t r = *rem;
    while (k < c->n && cnt < m && r > 0) {
        CHARGE3(r, W3_CAND);
        cnt += magcal_o3_dist2(&pts[k], pp) <= c->eps2 ? 1u : 0u;
        ++k;
    }
    *rem = r;
    o->cnt = (uint16_t)cnt;
    o->k = (uint16_t)k;
    return (k < c->n && cnt < m) ? 0 : 1;
}

void magcal_o3_ord_begin(magcal_o3_ord_t *o)
{
    (void)memset(o, 0, sizeof *o);
    o->st = (uint8_t)O3_OR_INIT;
}

/* The outer scan (O3_OR_SCAN): runs start at unprocessed (core) points, pass by pass. */
static void ord_scan(magcal_o3_ord_t *o, magcal_o3_ctx_t *c, int32_t *rem)
{
    const size_t s = o->s;
    CHARGE3(*rem, W3_SKIP);
    if (s >= c->n) {
        o->pass++;
        o->s = 0u;
        if (o->pass >= 2u) {
            magcal_ocore_finish(&c->oc);
            o->st = (uint8_t)O3_OR_DONE;
        }
    } else if (magcal_ocore_is_done(&c->oc, s) != 0) {
        o->s++;
    } else if (o->pass == 0u && c->use_grid != 0) {
        CHARGE3(*rem, W3_GRIDP);
        if (is_core3(c, s) != 0) {
            ord_process_begin(o, c, s);
        } else {
            o->s++;
        }
    } else if (o->pass == 0u) {
        o->k = 0u;
        o->cnt = 0u;
        o->st = (uint8_t)O3_OR_ISCORE;
    } else {
        ord_process_begin(o, c, s);
    }
}

int magcal_o3_ord_run(magcal_o3_ord_t *o, magcal_o3_ctx_t *c, int32_t *rem)
{
    /* bounded: every round charges at least one visit, and the work is finite (<= 3 n^2 visits) */
    while (*rem > 0 && o->st != (uint8_t)O3_OR_DONE) {
        switch (o->st) {
        case O3_OR_INIT:
            if (o->s < c->n) {
                CHARGE3(*rem, W3_INIT);
                magcal_ocore_start_point(&c->oc, o->s);
                if (c->use_grid == 0) {
                    c->live[o->s] = o->s; /* the live list: every point */
                }
                o->s++;
            } else {
                magcal_ocore_start_finish(&c->oc, c->n);
                c->n_live = c->n;
                o->s = 0u;
                o->pass = (uint8_t)((c->oc.core_start != 0) ? 0u : 1u);
                o->st = (uint8_t)O3_OR_SCAN;
            }
            break;
        case O3_OR_SCAN:
            ord_scan(o, c, rem);
            break;
        case O3_OR_GRIDP:
            CHARGE3(*rem, W3_GRIDP);
            process3_grid(c, o->p, INFINITY);
            ord_after(o, c, rem);
            break;
        case O3_OR_ISCORE:
            if (ord_iscore(o, c, rem) != 0) {
                if (o->cnt >= c->oc.min_pts) {
                    ord_process_begin(o, c, o->s);
                } else {
                    o->s++;
                    o->st = (uint8_t)O3_OR_SCAN;
                }
            }
            break;
        case O3_OR_P1:
            (void)ord_p1(o, c, rem);
            break;
        case O3_OR_P2:
            if (ord_p2(o, c, rem) != 0) {
                ord_after(o, c, rem);
            }
            break;
        default: /* O3_OR_POP */
            if (ord_pop(o, c, rem) != 0) {
                ord_process_begin(o, c, o->pbq);
            }
            break;
        }
    }
    return (o->st == (uint8_t)O3_OR_DONE) ? 1 : 0;
}

void magcal_o3_loop(magcal_o3_ctx_t *c)
{
    magcal_o3_ord_t o;
    unsigned guard;
    magcal_o3_ord_begin(&o);
    for (guard = 0u; guard < SLICE_ONESHOT_ROUNDS; ++guard) {
        int32_t rem = SLICE_REM_MAX;
        if (magcal_o3_ord_run(&o, c, &rem) != 0) {
            break;
        }
    }
}

int magcal_o3_fin_run(const magcal_vec3_t *pts, size_t n, uint16_t *i, int32_t *rem)
{
    size_t k = *i;
    int32_t r = *rem;
    int rc = 1;
    while (k < n && r > 0) {
        CHARGE3(r, W3_FIN);
        if (!magcal_isfinite_f(pts[k].x) || !magcal_isfinite_f(pts[k].y) || !magcal_isfinite_f(pts[k].z)) {
            rc = -1;
            break;
        }
        ++k;
    }
    *rem = r;
    *i = (uint16_t)k;
    if (rc == 1 && k < n) {
        rc = 0;
    }
    return rc;
}

magcal_status_t magcal_o3_check_points(const magcal_vec3_t *pts, size_t n, size_t min_n)
{
    uint16_t i = 0u;
    int32_t rem = SLICE_REM_MAX;
    const magcal_status_t st = magcal_ocore_check_n(n, min_n);
    if (st != MAGCAL_OK) {
        return st;
    }
    return (magcal_o3_fin_run(pts, n, &i, &rem) < 0) ? MAGCAL_ERR_NONFINITE : MAGCAL_OK;
}

/* Carve the run workspace (layout of MAGCAL_OPTICS3_WORKSPACE_LEN); the context sits after the
 * MinPts buffer, aligned for pointers. */
magcal_o3_ctx_t *magcal_o3_ctx_setup(const magcal_optics_cfg_t *cfg, const magcal_vec3_t *pts,
                                     size_t n, uint8_t *w)
{
    uint8_t *cw = w + MAGCAL_OPTICS3_BEST_OFFSET_(n) + 4u * (size_t)MAGCAL_MAX_MIN_PTS;
    magcal_o3_ctx_t *c;
    cw += (sizeof(void *) - magcal_misalign(cw, sizeof(void *))) % sizeof(void *);
    c = (magcal_o3_ctx_t *)(void *)cw;
    (void)memset(c, 0, sizeof *c);
    c->pts = pts;
    c->n = n;
    c->eps2 = cfg->eps * cfg->eps;
    c->oc.min_pts = cfg->min_pts;
    c->oc.mode = cfg->order;
    c->oc.core_start = 0;
    if (cfg->start == MAGCAL_OPTICS_START_CORE) {
        c->oc.core_start = 1;
    }
    c->oc.seeds = (uint16_t *)(void *)w;
    c->oc.pos = c->oc.seeds + n;
    c->live = c->oc.pos + n;
    c->start = c->live + n;
    c->oc.done = w + 6u * n + 2u * (MAGCAL_OPTICS_GRID_CELLS(n) + 1u);
    c->oc.best = (float *)(void *)(w + MAGCAL_OPTICS3_BEST_OFFSET_(n));
    c->oc.id = -1;
    c->oc.best_id = -1;
    magcal_o3_grid_build(c, cfg->eps, cfg->neighbors);
    return c;
}

magcal_status_t magcal_optics_run3(const magcal_optics_cfg_t *cfg, const magcal_vec3_t *pts,
                                   size_t n, void *work, size_t work_len, uint16_t *order,
                                   float *reach, float *core, uint16_t *pred,
                                   magcal_optics_result_t *info)
{
    magcal_o3_ctx_t *c;
    magcal_status_t st;
    st = magcal_ocore_check_run(cfg, pts, work, order, reach, core);
    if (st != MAGCAL_OK) {
        return st;
    }
    st = magcal_o3_check_points(pts, n, cfg->min_pts);
    if (st != MAGCAL_OK) {
        return st;
    }
    if (work_len < MAGCAL_OPTICS3_WORKSPACE_LEN(n)) {
        return MAGCAL_ERR_WORKSPACE;
    }
    c = magcal_o3_ctx_setup(cfg, pts, n, (uint8_t *)work);
    c->oc.reach = reach;
    c->oc.order = order;
    c->oc.core = core;
    c->oc.pred = pred;
    magcal_o3_loop(c);
    magcal_ocore_fill_info(info, &c->oc, c->use_grid, cfg->eps, cfg->eps);
    return MAGCAL_OK;
}

#endif /* MAGCAL_CFG_ENABLE_3D */
