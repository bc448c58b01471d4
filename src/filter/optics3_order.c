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

/* Next candidate slot of the grid scan over the query's buckets bk[t..nb) (k: position in
 * live[]); 0 when the query is exhausted. */
static int grid_next(magcal_o3_ctx_t *c, size_t *slot)
{
    while (c->t < c->nb) { /* <= 27 buckets */
        if (c->k < c->start[c->bk[c->t] + 1u]) {
            *slot = c->k;
            c->k++;
            return 1;
        }
        c->t++;
        if (c->t < c->nb) {
            c->k = c->start[c->bk[c->t]];
        }
    }
    return 0;
}

/* Start a grid scan over the buckets of the 3x3x3 block around point q. */
static void grid_scan_begin(magcal_o3_ctx_t *c, size_t q)
{
    c->nb = (uint8_t)magcal_o3_grid_query(c, q, c->bk);
    c->t = 0u;
    c->k = (c->nb > 0u) ? c->start[c->bk[0]] : 0u;
}

/* One reach update of unprocessed neighbour j at d^2 from p (pass 2). */
static int32_t reach_visit(magcal_o3_ctx_t *c, size_t j, float d2)
{
    int32_t w = 0;
    const float rr = magcal_ocore_reach_of(d2, c->core_p, c->core2);
    if (rr < c->oc.reach[j]) {
        magcal_ocore_update(&c->oc, c->p, j, rr);
        w = (int32_t)W3_UPD;
        if (c->oc.mode != MAGCAL_OPTICS_IMPROVED) {
            w += (int32_t)W3_HEAP;
        }
    }
    return w;
}

/* OR3_INIT (magcal_ocore_start, resumable) and OR3_LIVE (brute force: the unprocessed list). */
static void order_init(magcal_o3_ctx_t *c, int32_t *rem)
{
    magcal_ocore_t *o = &c->oc;
    const size_t n = c->n;
    int32_t r = *rem;
    size_t k = c->k;
    if (c->st == OR3_INIT) {
        for (; k < n && r > 0; ++k) {
            o->reach[k] = INFINITY;
            if (o->pred != NULL) {
                o->pred[k] = MAGCAL_OPTICS_NO_PRED;
            }
            if (o->mode == MAGCAL_OPTICS_CLASSIC) {
                o->pos[k] = MAGCAL_OCORE_POS_NONE;
            }
            r -= (int32_t)W3_INIT;
        }
        if (k == n) {
            (void)memset(o->done, 0, (n + 7u) / 8u);
            o->n_seeds = 0u;
            o->n_done = 0u;
#ifdef MAGCAL_OPTICS_BENCH_SORTED_LIST
            o->head = 0u;
            o->dirty = 0;
#endif
            r -= (int32_t)W3_PHASE;
            k = 0u;
            c->st = (c->use_grid == 0) ? (uint8_t)OR3_LIVE : (uint8_t)OR3_SCAN;
        }
    }
    if (c->st == OR3_LIVE) {
        for (; k < n && r > 0; ++k) {
            c->live[k] = (uint16_t)k;
            r -= (int32_t)W3_INIT;
        }
        if (k == n) {
            c->st = OR3_SCAN;
        }
    }
    if (c->st == OR3_SCAN) {
        c->n_live = n;
        c->s = 0u;
        /* pass 0 (START_CORE only): runs start at unprocessed core points; pass 1: at any point */
        c->pass = (c->oc.core_start != 0) ? (uint8_t)0u : (uint8_t)1u;
    }
    c->k = (uint16_t)k;
    *rem = r;
}

/* OR3_SCAN: the outer scan to the next start point (or the end), OR3_ISCORE its start test. */
static void order_scan(magcal_o3_ctx_t *c, int32_t *rem)
{
    const magcal_vec3_t *pts = c->pts;
    const size_t n = c->n;
    const size_t m = c->oc.min_pts;
    int32_t r = *rem;
    if (c->st == OR3_SCAN) {
        while (r > 0 && c->st == OR3_SCAN) {
            const size_t s = c->s;
            if (s == n) {
                if (c->pass == 0u) {
                    c->pass = 1u;
                    c->s = 0u;
                    r -= (int32_t)W3_PHASE;
                } else {
                    magcal_ocore_finish(&c->oc);
                    c->st = OR3_DONE;
                }
            } else if (magcal_ocore_is_done(&c->oc, s) != 0) {
                c->s++;
                r -= (int32_t)W3_SKIP;
            } else if (c->pass == 0u) {
                c->cnt = 0u;
                c->k = 0u;
                if (c->use_grid != 0) {
                    grid_scan_begin(c, s);
                }
                r -= (int32_t)W3_PSTART;
                c->st = OR3_ISCORE;
            } else {
                c->p = (uint16_t)s;
                c->st = OR3_PSTART;
            }
        }
    } else { /* OR3_ISCORE: >= MinPts points (s itself included) within eps */
        const magcal_vec3_t *pp = &pts[c->s];
        size_t cnt = c->cnt;
        int fin;
        if (c->use_grid != 0) {
            size_t slot = 0u;
            while (cnt < m && r > 0 && grid_next(c, &slot) != 0) {
                cnt += magcal_o3_dist2(&pts[c->live[slot]], pp) <= c->eps2 ? 1u : 0u;
                r -= (int32_t)W3_CAND;
            }
            fin = (cnt >= m || c->t >= c->nb) ? 1 : 0;
        } else {
            size_t k = c->k;
            for (; k < n && cnt < m && r > 0; ++k) {
                cnt += magcal_o3_dist2(&pts[k], pp) <= c->eps2 ? 1u : 0u;
                r -= (int32_t)W3_CAND;
            }
            c->k = (uint16_t)k;
            fin = (cnt >= m || k == n) ? 1 : 0;
        }
        c->cnt = (uint16_t)cnt;
        if (fin != 0) {
            if (cnt >= m) {
                c->p = c->s;
                c->st = OR3_PSTART;
            } else {
                c->s++;
                c->st = OR3_SCAN;
            }
        }
    }
    *rem = r;
}

/*
 * PROCESS(p) of algorithms.md 4.2, resumable per candidate (OR3_PSTART, OR3_P1, OR3_P2). Pass 1
 * sweeps all n points (brute force) or the 3x3x3 buckets (grid) for the core distance (MinPts-th
 * smallest d^2, p itself included, in the workspace buffer `best`); then the extraction step;
 * pass 2 sweeps the compact list of unprocessed points (brute force: dropping p, the only point
 * processed since the previous pass, so the k-th pass costs n - k) or the buckets again (grid,
 * only for a core point) for the reachability updates. r = max(core, d) is taken as core without
 * a square root when d^2 <= core^2 (sqrtf is monotone and core = sqrtf(core^2), so no bit
 * changes).
 */
static void order_process(magcal_o3_ctx_t *c, int32_t *rem)
{
    const magcal_vec3_t *pts = c->pts;
    const size_t n = c->n;
    const size_t m = c->oc.min_pts;
    const float eps2 = c->eps2;
    const magcal_vec3_t *pp = &pts[c->p];
    float *best = c->oc.best;
    int32_t r = *rem;
    if (c->st == OR3_PSTART) {
        magcal_ocore_mark(&c->oc, c->p);
        c->cnt = 0u;
        c->lim = eps2;
        c->core_p = INFINITY;
        c->core2 = INFINITY;
        c->k = 0u;
        if (c->use_grid != 0) {
            grid_scan_begin(c, c->p);
        }
        r -= (int32_t)W3_PSTART;
        c->st = OR3_P1;
    } else if (c->st == OR3_P1) {
        size_t cnt = c->cnt;
        int fin;
        if (c->use_grid != 0) {
            size_t slot = 0u;
            while (r > 0 && grid_next(c, &slot) != 0) {
                const float d2 = magcal_o3_dist2(&pts[c->live[slot]], pp);
                if (d2 <= eps2 && (cnt < m || d2 < best[m - 1u])) {
                    cnt = magcal_ocore_best_insert(best, cnt, m, d2);
                }
                r -= (int32_t)W3_CAND;
            }
            fin = (c->t >= c->nb) ? 1 : 0;
        } else {
            size_t k = c->k;
            float lim = c->lim;
            for (; k < n && r > 0; ++k) {
                const float d2 = magcal_o3_dist2(&pts[k], pp);
                if (d2 <= lim && (cnt < m || d2 < lim)) {
                    cnt = magcal_ocore_best_insert(best, cnt, m, d2);
                    if (cnt == m) {
                        lim = best[m - 1u];
                    }
                }
                r -= (int32_t)W3_CAND;
            }
            c->k = (uint16_t)k;
            c->lim = lim;
            fin = (k == n) ? 1 : 0;
        }
        c->cnt = (uint16_t)cnt;
        if (fin != 0) {
            if (cnt >= m) {
                c->core2 = best[m - 1u];
                c->core_p = sqrtf(c->core2);
            }
            if (c->oc.core != NULL) {
                c->oc.core[c->p] = c->core_p;
            }
            if (c->oc.labels != NULL) {
                magcal_ocore_extract_step(&c->oc, c->p, c->core_p);
            }
            c->k = 0u;
            c->w = 0u;
            c->st = OR3_P2;
            if (c->use_grid != 0) {
                c->t = 0u;
                c->k = (c->nb > 0u) ? c->start[c->bk[0]] : 0u;
                if (cnt < m) {
                    c->st = OR3_SEEDS; /* not a core point: no reach updates */
                }
            }
        }
    } else { /* OR3_P2 */
        if (c->use_grid != 0) {
            size_t slot = 0u;
            while (r > 0 && grid_next(c, &slot) != 0) {
                const size_t j = c->live[slot];
                const float d2 = magcal_o3_dist2(&pts[j], pp);
                if (d2 <= eps2 && magcal_ocore_is_done(&c->oc, j) == 0) {
                    r -= reach_visit(c, j, d2);
                }
                r -= (int32_t)W3_REACH;
            }
            if (c->t >= c->nb) {
                c->st = OR3_SEEDS;
            }
        } else {
            uint16_t *live = c->live;
            const size_t nl = c->n_live;
            size_t k = c->k;
            size_t w = c->w;
            for (; k < nl && r > 0; ++k) {
                const size_t j = live[k];
                r -= (int32_t)W3_REACH;
                if (j == c->p) {
                    continue;
                }
                live[w] = (uint16_t)j;
                ++w;
                if (c->core_p < INFINITY) {
                    const float d2 = magcal_o3_dist2(&pts[j], pp);
                    if (d2 <= eps2) {
                        r -= reach_visit(c, j, d2);
                    }
                }
            }
            c->k = (uint16_t)k;
            c->w = (uint16_t)w;
            if (k == nl) {
                c->n_live = w;
                c->st = OR3_SEEDS;
            }
        }
    }
    *rem = r;
}

/* OR3_SEEDS / OR3_POP: the next point of the run (the seed of least (reach, index)), or back to
 * the outer scan when the seeds are exhausted. IMPROVED: the minimum scan is resumable per seed. */
static void order_seeds(magcal_o3_ctx_t *c, int32_t *rem)
{
    magcal_ocore_t *o = &c->oc;
    int32_t r = *rem;
    if (c->st == OR3_SEEDS) {
        if (o->n_seeds == 0u) {
            c->s++;
            c->st = OR3_SCAN;
            r -= (int32_t)W3_SKIP;
        } else if (o->mode == MAGCAL_OPTICS_IMPROVED) {
            c->pk = 1u;
            c->pbest = 0u;
            c->pbq = o->seeds[0];
            c->pbr = o->reach[c->pbq];
            c->st = OR3_POP;
            r -= (int32_t)W3_POP;
        } else {
            c->p = magcal_ocore_pop_min(o); /* heap: O(log n), one visit */
            c->st = OR3_PSTART;
            r -= (int32_t)W3_HEAP;
        }
    } else { /* OR3_POP: same scan and tie rule as magcal_ocore_pop_min */
        const float *reach = o->reach;
        size_t k = c->pk;
        size_t bst = c->pbest;
        uint16_t bq = c->pbq;
        float br = c->pbr;
        for (; k < o->n_seeds && r > 0; ++k) {
            const uint16_t s = o->seeds[k];
            const float rr = reach[s];
            if (rr < br || (rr == br && s < bq)) {
                br = rr;
                bq = s;
                bst = k;
            }
            r -= (int32_t)W3_POP;
        }
        c->pk = (uint16_t)k;
        c->pbest = (uint16_t)bst;
        c->pbq = bq;
        c->pbr = br;
        if (k >= o->n_seeds) {
            o->n_seeds--;
            o->seeds[bst] = o->seeds[o->n_seeds];
            c->p = bq;
            c->st = OR3_PSTART;
        }
    }
    *rem = r;
}

/* The ordering loop (after the grid build), resumable: returns 1 when the ordering (and the
 * on-the-fly extraction) is complete, 0 when *rem ran out (call again). Every round charges at
 * least one visit, so a call ends within its budget + one visit. */
int magcal_o3_order_run(magcal_o3_ctx_t *c, int32_t *rem)
{
    /* cppcheck-suppress misra-c2012-15.4 ; deviation D13: a resumable loop leaves at its pause point and at its phase end */
    while (c->st != OR3_DONE && *rem > 0) {
        switch (c->st) {
        case OR3_INIT:
        case OR3_LIVE:
            order_init(c, rem);
            break;
        case OR3_SCAN:
        case OR3_ISCORE:
            order_scan(c, rem);
            break;
        case OR3_SEEDS:
        case OR3_POP:
            order_seeds(c, rem);
            break;
        default: /* OR3_PSTART, OR3_P1, OR3_P2 */
            order_process(c, rem);
            break;
        }
    }
    return c->st == OR3_DONE ? 1 : 0;
}

/* The grid build and the ordering with an unlimited budget (the one-shot calls). */
void magcal_o3_order_all(magcal_o3_ctx_t *c, float eps, magcal_neighbors_t mode)
{
    unsigned guard;
    for (guard = 0u; guard < O3_ONESHOT_ROUNDS; ++guard) {
        int32_t rem = O3_REM_MAX;
        if (magcal_o3_grid_run(c, eps, mode, &rem) != 0 && magcal_o3_order_run(c, &rem) != 0) {
            break;
        }
    }
}

magcal_status_t magcal_o3_check_points(const magcal_vec3_t *pts, size_t n, size_t min_n)
{
    size_t i;
    const magcal_status_t st = magcal_ocore_check_n(n, min_n);
    if (st != MAGCAL_OK) {
        return st;
    }
    for (i = 0; i < n; ++i) {
        if (!magcal_isfinite_f(pts[i].x) || !magcal_isfinite_f(pts[i].y) ||
            !magcal_isfinite_f(pts[i].z)) {
            return MAGCAL_ERR_NONFINITE;
        }
    }
    return MAGCAL_OK;
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
    return c; /* grid build (magcal_o3_grid_run) and ordering (magcal_o3_order_run) to follow */
}

magcal_status_t magcal_optics_run3(const magcal_optics_cfg_t *cfg, const magcal_vec3_t *pts,
                                   size_t n, void *work, size_t work_len, uint16_t *order,
                                   float *reach, float *core, uint16_t *pred,
                                   magcal_optics_result_t *info)
{
    magcal_o3_ctx_t *c;
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
    magcal_o3_order_all(c, cfg->eps, cfg->neighbors);
    magcal_ocore_fill_info(info, &c->oc, c->use_grid, cfg->eps, cfg->eps);
    return MAGCAL_OK;
}

#endif /* MAGCAL_CFG_ENABLE_3D */
