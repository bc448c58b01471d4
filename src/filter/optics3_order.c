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

/* PROCESS(p) with the grid: both passes over the candidate buckets. */
static void process3_grid(magcal_o3_ctx_t *c, size_t p, float core_p0)
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

/*
 * PROCESS(p) of algorithms.md 4.2. Pass 1 sweeps all n points for the core distance (MinPts-th
 * smallest d^2, p itself included); pass 2 sweeps the compact list of unprocessed points for the
 * reachability updates (dropping p, the only point processed since the previous pass), so the
 * k-th call costs n + (n - k) squared distances: about 1.5 n^2 per run.
 * r = max(core, d) is taken as core without a square root when d^2 <= core^2 (sqrtf is monotone
 * and core = sqrtf(core^2), so no bit changes).
 */
static void process3(magcal_o3_ctx_t *c, size_t p)
{
    float *best = c->oc.best;
    size_t cnt = 0u;
    const size_t m = c->oc.min_pts;
    const size_t n = c->n;
    const magcal_vec3_t *pts = c->pts;
    const magcal_vec3_t *pp = &pts[p];
    const float eps2 = c->eps2;
    float lim = eps2;
    float core_p = INFINITY;
    float core2 = INFINITY;
    uint16_t *live = c->live;
    size_t nl = c->n_live;
    size_t w = 0u;
    size_t k;

    magcal_ocore_mark(&c->oc, p);
    if (c->use_grid != 0) {
        process3_grid(c, p, core_p);
        return;
    }

    for (k = 0; k < n; ++k) {
        float d2 = magcal_o3_dist2(&pts[k], pp);
        if (d2 <= lim && (cnt < m || d2 < lim)) {
            cnt = magcal_ocore_best_insert(best, cnt, m, d2);
            if (cnt == m) {
                lim = best[m - 1u];
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
    for (k = 0; k < nl; ++k) {
        size_t j = live[k];
        if (j == p) {
            continue;
        }
        live[w] = (uint16_t)j;
        ++w;
        if (core_p < INFINITY) {
            float d2 = magcal_o3_dist2(&pts[j], pp);
            if (d2 <= eps2) {
                float r = magcal_ocore_reach_of(d2, core_p, core2);
                if (r < c->oc.reach[j]) {
                    magcal_ocore_update(&c->oc, p, j, r);
                }
            }
        }
    }
    c->n_live = w;
}

/* 1 when p has >= MinPts points (itself included) within eps: the start test of START_CORE. */
static MAGCAL_NOINLINE int is_core3(magcal_o3_ctx_t *c, size_t p)
{
    const magcal_vec3_t *pts = c->pts;
    const magcal_vec3_t *pp = &pts[p];
    const size_t m = c->oc.min_pts;
    size_t cnt = 0u;
    size_t k;
    if (c->use_grid != 0) {
        const size_t nb = magcal_o3_grid_query(c, p, c->bk);
        size_t t;
        for (t = 0; t < nb && cnt < m; ++t) {
            for (k = c->start[c->bk[t]]; k < c->start[c->bk[t] + 1u] && cnt < m; ++k) {
                cnt += magcal_o3_dist2(&pts[c->live[k]], pp) <= c->eps2 ? 1u : 0u;
            }
        }
    } else {
        for (k = 0; k < c->n && cnt < m; ++k) {
            cnt += magcal_o3_dist2(&pts[k], pp) <= c->eps2 ? 1u : 0u;
        }
    }
    return cnt >= m ? 1 : 0;
}

void magcal_o3_loop(magcal_o3_ctx_t *c)
{
    size_t s;
    unsigned pass;
    magcal_ocore_start(&c->oc, c->n);
    if (c->use_grid == 0) {
        size_t i;
        for (i = 0; i < c->n; ++i) {
            c->live[i] = (uint16_t)i;
        }
    }
    c->n_live = c->n;
    /* pass 0 (START_CORE only): runs start at unprocessed core points; pass 1: at any point */
    pass = 1u;
    if (c->oc.core_start != 0) {
        pass = 0u;
    }
    for (; pass < 2u; ++pass) {
        for (s = 0; s < c->n; ++s) {
            if (magcal_ocore_is_done(&c->oc, s) != 0 || (pass == 0u && is_core3(c, s) == 0)) {
                continue;
            }
            process3(c, s);
            while (c->oc.n_seeds > 0u) { /* each pop processes one new point: <= n rounds */
                process3(c, magcal_ocore_pop_min(&c->oc));
            }
        }
    }
    magcal_ocore_finish(&c->oc);
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
