/*
 * OPTICS on 3-D samples: ordering loop (brute-force eps-queries), automatic parameters and the
 * one-call filter (algorithms.md 4; rule and measurements in optics.h and docs/optics.md "3-D").
 * Only the coordinates and the neighbour search are 3-D here: the seed heap/list, reach updates,
 * on-the-fly extraction and MinPts buffer are optics_core.h (shared with optics.c), and
 * ExtractDBSCAN and the largest-cluster rule are optics.c's (they never look at coordinates).
 */
#include <math.h>
#include <string.h>

#include "magcal/optics.h"
#include "magcal_internal.h"
#include "neighbors.h"

#if MAGCAL_CFG_ENABLE_3D /* whole file: config.h feature switch (optics_core.h's static helpers inside) */
#include "optics_core.h"
#include "optics_core_update.h"

/* Everything the ordering loop needs: the dimension-free state (optics_core.h, shared with the
 * 2-D loop) and the 3-D points and neighbour search. */
typedef struct {
    magcal_ocore_t oc;
    const magcal_vec3_t *pts;
    size_t n;
    float eps2;
    uint16_t *live;  /* BRUTE: unprocessed points, compacted; GRID: points sorted by bucket */
    uint16_t *start; /* GRID: G + 1 bucket starts into live[] */
    int use_grid;
    float x0; /* GRID: lower corner of the box */
    float y0;
    float z0;
    float inv_h; /* GRID: 1 / cell side */
    uint32_t gw; /* GRID: cells per axis (<= GRID3_AXIS_CELLS) */
    uint32_t gh;
    uint32_t gd;
    uint32_t nbkt;   /* GRID: buckets G */
    int dense;       /* GRID: gw*gh*gd <= G, row-major cell number is the bucket */
    uint16_t bk[27]; /* GRID: distinct buckets of the current query */
    size_t n_live;
} optics3_ctx_t;

/* cppcheck-suppress misra-c2012-2.3 ; deviation D4: a static assert is an unused typedef */
MAGCAL_STATIC_ASSERT(sizeof(optics3_ctx_t) + sizeof(void *) - 4u <= MAGCAL_OPTICS3_CTX_LEN_,
                     optics3_ctx_fits_workspace);

static float dist2(const magcal_vec3_t *a, const magcal_vec3_t *b)
{
    float dx = a->x - b->x;
    float dy = a->y - b->y;
    float dz = a->z - b->z;
    return dx * dx + dy * dy + dz * dz;
}

/* ---- 3-D grid (neighbour search GRID) -------------------------------------------------------
 * Cell side h = eps * (1 + 2^-6) over the bounding box; cell coordinates are clamped to
 * [0, GRID3_AXIS_CELLS - 1] (monotone, so two points within eps stay in adjacent cells; far
 * outliers only crowd the border cells). A cell (cx, cy, cz) lives in bucket
 * cx + gw (cy + gh cz) when the grid has at most G = MAGCAL_OPTICS_GRID_CELLS(n) cells, else in a
 * spatial hash of it modulo G; points are counting-sorted by bucket. A query visits the distinct
 * buckets of the 3x3x3 block around the point's cell: every point within eps is met exactly once
 * (extra points of colliding cells fail the distance test), so the core distances and reach
 * updates, and therefore every output, are bit-identical to the brute-force search. With at most
 * 2^15 cells per axis the float rounding of a cell coordinate stays below 2^-8 cell, inside the
 * 2^-6 margin of h.
 */
#define GRID3_AXIS_CELLS 32768u
#define GRID3_AXIS_LAST_F 32767.0f /* GRID3_AXIS_CELLS - 1 */
#define GRID3_MARGIN (1.0f + 1.0f / 64.0f)

static uint32_t cell3_of(float v, float v0, float inv_h)
{
    float t = (v - v0) * inv_h;
    uint32_t cidx = GRID3_AXIS_CELLS - 1u;
    if (!(t >= 0.0f)) {
        cidx = 0u; /* not reached: v >= v0 */
    } else if (t < GRID3_AXIS_LAST_F) {
        cidx = (uint32_t)t; /* truncation = floor for t >= 0 */
    } else {
        /* clamped into the last cell */
    }
    return cidx;
}

static uint32_t bucket_of(const optics3_ctx_t *c, uint32_t cx, uint32_t cy, uint32_t cz)
{
    uint32_t b;
    if (c->dense != 0) {
        b = cx + c->gw * (cy + c->gh * cz);
    } else {
        b = ((cx * 73856093u) ^ (cy * 19349663u) ^ (cz * 83492791u)) % c->nbkt;
    }
    return b;
}

static uint32_t point_bucket(const optics3_ctx_t *c, size_t i)
{
    const magcal_vec3_t *q = &c->pts[i];
    return bucket_of(c, cell3_of(q->x, c->x0, c->inv_h), cell3_of(q->y, c->y0, c->inv_h),
                     cell3_of(q->z, c->z0, c->inv_h));
}

/* Build the grid over live[] / start[] when cfg asks for it and it can help (finite eps, points
 * not all equal); otherwise leave use_grid = 0 (brute force). */
static void grid3_build(optics3_ctx_t *c, float eps, magcal_neighbors_t mode)
{
    const magcal_vec3_t *pts = c->pts;
    const size_t n = c->n;
    float lo[3];
    float hi[3];
    uint32_t g[3];
    float h;
    size_t i;
    unsigned a;
    uint64_t cells;
    c->use_grid = 0;
    if (mode != MAGCAL_NEIGHBORS_GRID || !magcal_isfinite_f(eps)) {
        return;
    }
    lo[0] = pts[0].x;
    lo[1] = pts[0].y;
    lo[2] = pts[0].z;
    hi[0] = lo[0];
    hi[1] = lo[1];
    hi[2] = lo[2];
    for (i = 1u; i < n; ++i) {
        lo[0] = pts[i].x < lo[0] ? pts[i].x : lo[0];
        lo[1] = pts[i].y < lo[1] ? pts[i].y : lo[1];
        lo[2] = pts[i].z < lo[2] ? pts[i].z : lo[2];
        hi[0] = pts[i].x > hi[0] ? pts[i].x : hi[0];
        hi[1] = pts[i].y > hi[1] ? pts[i].y : hi[1];
        hi[2] = pts[i].z > hi[2] ? pts[i].z : hi[2];
    }
    if (lo[0] == hi[0] && lo[1] == hi[1] && lo[2] == hi[2]) {
        return; /* all points equal */
    }
    h = eps * GRID3_MARGIN;
    c->inv_h = 1.0f / h;
    c->x0 = lo[0];
    c->y0 = lo[1];
    c->z0 = lo[2];
    for (a = 0u; a < 3u; ++a) {
        g[a] = cell3_of(hi[a], lo[a], c->inv_h) + 1u;
    }
    c->gw = g[0];
    c->gh = g[1];
    c->gd = g[2];
    c->nbkt = (uint32_t)MAGCAL_OPTICS_GRID_CELLS(n);
    cells = (uint64_t)g[0] * (uint64_t)g[1];
    cells *= (uint64_t)g[2];
    c->dense = 0;
    if (cells <= (uint64_t)c->nbkt) {
        c->dense = 1;
        c->nbkt = (uint32_t)cells;
    }
    c->use_grid = 1;
    /* counting sort by bucket: counts in start[b + 1], prefix sums, placement, shift back */
    (void)memset(c->start, 0, ((size_t)c->nbkt + 1u) * sizeof c->start[0]);
    for (i = 0; i < n; ++i) {
        c->start[point_bucket(c, i) + 1u]++;
    }
    for (i = 1u; i <= c->nbkt; ++i) {
        c->start[i] = (uint16_t)(c->start[i] + c->start[i - 1u]);
    }
    for (i = 0; i < n; ++i) {
        const uint32_t b = point_bucket(c, i);
        c->live[c->start[b]] = (uint16_t)i;
        c->start[b]++;
    }
    for (i = c->nbkt; i > 0u; --i) {
        c->start[i] = c->start[i - 1u];
    }
    c->start[0] = 0u;
}

/* Distinct buckets of the 3x3x3 cells around point p; returns how many (<= 27). */
static size_t grid3_query(const optics3_ctx_t *c, size_t p, uint16_t *bk)
{
    const magcal_vec3_t *q = &c->pts[p];
    const uint32_t cx = cell3_of(q->x, c->x0, c->inv_h);
    const uint32_t cy = cell3_of(q->y, c->y0, c->inv_h);
    const uint32_t cz = cell3_of(q->z, c->z0, c->inv_h);
    uint32_t dx;
    uint32_t dy;
    uint32_t dz;
    size_t nb = 0u;
    for (dz = 0u; dz < 3u; ++dz) {
        for (dy = 0u; dy < 3u; ++dy) {
            for (dx = 0u; dx < 3u; ++dx) {
                /* cell coordinate + d - 1, skipped outside [0, g - 1] */
                const uint32_t x = cx + dx;
                const uint32_t y = cy + dy;
                const uint32_t z = cz + dz;
                uint32_t b;
                size_t t;
                int seen = 0;
                if (x == 0u || y == 0u || z == 0u || x > c->gw || y > c->gh || z > c->gd) {
                    continue;
                }
                b = bucket_of(c, x - 1u, y - 1u, z - 1u);
                for (t = 0; t < nb; ++t) {
                    seen |= (bk[t] == b) ? 1 : 0;
                }
                if (seen == 0 && c->start[b] != c->start[b + 1u]) {
                    bk[nb] = (uint16_t)b;
                    ++nb;
                }
            }
        }
    }
    return nb;
}

/* PROCESS(p) with the grid: both passes over the candidate buckets. */
static void process3_grid(optics3_ctx_t *c, size_t p, float core_p0)
{
    float *best = c->oc.best;
    uint16_t *bk = c->bk;
    const size_t m = c->oc.min_pts;
    const magcal_vec3_t *pts = c->pts;
    const magcal_vec3_t *pp = &pts[p];
    const float eps2 = c->eps2;
    const size_t nb = grid3_query(c, p, bk);
    float core_p = core_p0;
    float core2 = INFINITY;
    size_t cnt = 0u;
    size_t t;
    size_t k;
    for (t = 0; t < nb; ++t) {
        for (k = c->start[bk[t]]; k < c->start[bk[t] + 1u]; ++k) {
            float d2 = dist2(&pts[c->live[k]], pp);
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
            float d2 = dist2(&pts[j], pp);
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
static void process3(optics3_ctx_t *c, size_t p)
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
        float d2 = dist2(&pts[k], pp);
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
            float d2 = dist2(&pts[j], pp);
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
static MAGCAL_NOINLINE int is_core3(optics3_ctx_t *c, size_t p)
{
    const magcal_vec3_t *pts = c->pts;
    const magcal_vec3_t *pp = &pts[p];
    const size_t m = c->oc.min_pts;
    size_t cnt = 0u;
    size_t k;
    if (c->use_grid != 0) {
        const size_t nb = grid3_query(c, p, c->bk);
        size_t t;
        for (t = 0; t < nb && cnt < m; ++t) {
            for (k = c->start[c->bk[t]]; k < c->start[c->bk[t] + 1u] && cnt < m; ++k) {
                cnt += dist2(&pts[c->live[k]], pp) <= c->eps2 ? 1u : 0u;
            }
        }
    } else {
        for (k = 0; k < c->n && cnt < m; ++k) {
            cnt += dist2(&pts[k], pp) <= c->eps2 ? 1u : 0u;
        }
    }
    return cnt >= m ? 1 : 0;
}

static void optics3_loop(optics3_ctx_t *c)
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

static magcal_status_t check_points3(const magcal_vec3_t *pts, size_t n, size_t min_n)
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
static optics3_ctx_t *ctx3_setup(const magcal_optics_cfg_t *cfg, const magcal_vec3_t *pts, size_t n,
                                 uint8_t *w)
{
    uint8_t *cw = w + MAGCAL_OPTICS3_BEST_OFFSET_(n) + 4u * (size_t)MAGCAL_MAX_MIN_PTS;
    optics3_ctx_t *c;
    cw += (sizeof(void *) - magcal_misalign(cw, sizeof(void *))) % sizeof(void *);
    c = (optics3_ctx_t *)(void *)cw;
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
    grid3_build(c, cfg->eps, cfg->neighbors);
    return c;
}

magcal_status_t magcal_optics_run3(const magcal_optics_cfg_t *cfg, const magcal_vec3_t *pts,
                                   size_t n, void *work, size_t work_len, uint16_t *order,
                                   float *reach, float *core, uint16_t *pred,
                                   magcal_optics_result_t *info)
{
    optics3_ctx_t *c;
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
    st = check_points3(pts, n, cfg->min_pts);
    if (st != MAGCAL_OK) {
        return st;
    }
    if (work_len < MAGCAL_OPTICS3_WORKSPACE_LEN(n)) {
        return MAGCAL_ERR_WORKSPACE;
    }
    c = ctx3_setup(cfg, pts, n, (uint8_t *)work);
    c->oc.reach = reach;
    c->oc.order = order;
    c->oc.core = core;
    c->oc.pred = pred;
    optics3_loop(c);
    magcal_ocore_fill_info(info, &c->oc, c->use_grid, cfg->eps, cfg->eps);
    return MAGCAL_OK;
}

/* ---- automatic parameters ---------------------------------------------------------------- */

#define AUTO3_MIN_N 16u
#define AUTO3_MIN_PTS 4u
#define AUTO3_MIN_BAND 10u
#define AUTO3_BISECT 20u
#define AUTO3_SAFETY 2.0f /* eps' = 2 x the radius connecting 75 % of the band (docs/optics.md) */
#define AUTO3_BAND 0.5f   /* shell band: | |p-c| - R | <= 0.5 R */
#define AUTO3_TRIM 3.0f   /* centre passes after the first use points within 3 R */
#define AUTO3_TRIM_PASSES 2u
#define AUTO3_MIN_REL (1.0f / 256.0f)
#define AUTO3_MAX_REL 1.0f
#define AUTO3_PAIRS 256u               /* pairs of the clump-proof scale */
#define AUTO3_SEED 0x9E3779B9u         /* their fixed pseudo-random seed */
#define AUTO3_THIN_PAIR (1.0f / 32.0f) /* first thinning cell: pair scale / 32 */
#define AUTO3_THIN_REL (1.0f / 16.0f)  /* later cells: R / 16 */
#define AUTO3_THIN_ROUNDS 2u
#define AUTO3_THIN_N 400u    /* above 400 samples the cells shrink like 1/sqrt(n) */
#define AUTO3_CELL_HALF 128u /* cell coordinates clamped to +-128: exact float keys */

/* What the automatic rule measured and ran. */
typedef struct {
    const magcal_vec3_t *pts;
    size_t n;
    magcal_vec3_t cen;
    float rad;
    float lo2; /* shell band, squared radii */
    float hi2;
    const float *reach; /* the ordering at eps = R, in the workspace */
    const float *core;
    const uint16_t *order;
    const uint8_t *rep; /* thinning representatives (bits), after the run */
    float eps;
    float eps_prime;
    magcal_neighbors_t neighbors;
} auto3_t;

/* cppcheck-suppress misra-c2012-2.3 ; deviation D4: a static assert is an unused typedef */
MAGCAL_STATIC_ASSERT(sizeof(auto3_t) + 4u <= MAGCAL_OPTICS3_AUTO_LEN_, auto_record_fits_its_slot);

/* The record behind the run's workspace (pointer-aligned inside the 4-aligned workspace; the
 * caller has checked work_len >= MAGCAL_OPTICS3_FILTER_WORKSPACE_LEN(n) before it is written). */
static auto3_t *auto_record3(uint8_t *w, size_t n)
{
    uint8_t *p = w + MAGCAL_OPTICS3_FILTER_RUN_OFFSET_(n) + MAGCAL_OPTICS3_WORKSPACE_LEN(n);
    const size_t mis = magcal_misalign(p, sizeof(void *));
    return (auto3_t *)(void *)(p + ((mis == 0u) ? 0u : (sizeof(void *) - mis)));
}

/* Copy coordinate `axis` (0 x, 1 y, 2 z) of the counted points (use == NULL: all; else bit i of
 * use set) within sqrt(lim2) of c (all when lim2 is infinite) into a; returns how many. */
static size_t gather3(const magcal_vec3_t *pts, size_t n, const uint8_t *use,
                      const magcal_vec3_t *c, float lim2, unsigned axis, float *a)
{
    size_t i;
    size_t k = 0u;
    for (i = 0; i < n; ++i) {
        if ((use == NULL || ((unsigned)use[i >> 3] & (1u << (i & 7u))) != 0u) &&
            (lim2 == INFINITY || dist2(&pts[i], c) <= lim2)) {
            a[k] = axis == 0u ? pts[i].x : (axis == 1u ? pts[i].y : pts[i].z);
            ++k;
        }
    }
    return k;
}

/*
 * Robust centre and radius over the counted points (bits of use, NULL = all): coordinate
 * medians, R = median distance; passes after the first use only the points within AUTO3_TRIM R
 * of the previous centre (a far cluster cannot drag the centre). a: float[n] scratch.
 */
static magcal_status_t robust_centre3(const magcal_vec3_t *pts, size_t n, const uint8_t *use,
                                      float *a, magcal_vec3_t *cen_out, float *rad_out)
{
    magcal_vec3_t cen = {0.0f, 0.0f, 0.0f};
    float rad = INFINITY;
    size_t i;
    unsigned pass;
    for (pass = 0; pass <= AUTO3_TRIM_PASSES; ++pass) {
        const float lim2 = pass == 0u ? INFINITY : (AUTO3_TRIM * rad) * (AUTO3_TRIM * rad);
        magcal_vec3_t nc;
        size_t k = gather3(pts, n, use, &cen, lim2, 0u, a);
        if (k < AUTO3_MIN_N) {
            break; /* keep the previous estimate */
        }
        nc.x = magcal_ocore_select_kth(a, k, k / 2u);
        (void)gather3(pts, n, use, &cen, lim2, 1u, a);
        nc.y = magcal_ocore_select_kth(a, k, k / 2u);
        (void)gather3(pts, n, use, &cen, lim2, 2u, a);
        nc.z = magcal_ocore_select_kth(a, k, k / 2u);
        k = 0u;
        for (i = 0; i < n; ++i) {
            if ((use == NULL || ((unsigned)use[i >> 3] & (1u << (i & 7u))) != 0u) &&
                (lim2 == INFINITY || dist2(&pts[i], &cen) <= lim2)) {
                a[k] = sqrtf(dist2(&pts[i], &nc));
                ++k;
            }
        }
        cen = nc;
        rad = magcal_ocore_select_kth(a, k, k / 2u);
        if (!(rad > 0.0f) || !magcal_isfinite_f(rad) || magcal_nbr_eps_ok(rad) == 0) {
            return MAGCAL_ERR_DEGENERATE;
        }
    }
    if (rad == INFINITY) {
        return MAGCAL_ERR_DEGENERATE;
    }
    *cen_out = cen;
    *rad_out = rad;
    return MAGCAL_OK;
}

/* Median distance of AUTO3_PAIRS pseudo-random pairs: a scale a clump of up to 70 % of the
 * samples cannot shrink (a pair falls inside one clump with probability f^2). */
static float pair_scale3(const magcal_vec3_t *pts, size_t n, float *a)
{
    uint32_t state = AUTO3_SEED;
    size_t k;
    const size_t m = n < AUTO3_PAIRS ? n : AUTO3_PAIRS;
    /* cppcheck-suppress knownConditionTrueFalse ; false positive: m = min(n, pairs) >= 16 (check_points) */
    for (k = 0; k < m; ++k) {
        const size_t i = (size_t)(magcal_ocore_rand(&state) % (uint32_t)n);
        const size_t j = (size_t)(magcal_ocore_rand(&state) % (uint32_t)n);
        a[k] = sqrtf(dist2(&pts[i], &pts[j]));
    }
    return magcal_ocore_select_kth(a, m, m / 2u);
}

/* Cell side factor for n samples: 1 up to AUTO3_THIN_N, then sqrt(AUTO3_THIN_N / n) (a shell
 * has (4 pi R^2) / h^2 cells: the shell keeps its majority of representatives at every n). */
static float thin_scale3(size_t n)
{
    return n > AUTO3_THIN_N ? sqrtf((float)AUTO3_THIN_N / (float)n) : 1.0f;
}

/* Cell coordinate of v / h, clamped to +-AUTO3_CELL_HALF (far points share the border cells). */
static float cell3(float v, float h)
{
    const float lim = (float)AUTO3_CELL_HALF;
    float u = floorf(v / h);
    u = u < -lim ? -lim : (u > lim - 1.0f ? lim - 1.0f : u);
    return u + lim;
}

/*
 * Thinning: one representative (lowest index) per cubic cell of side h around c, as bits in rep
 * (n/8 bytes), so a rest phase (noise around one point) counts once. key float[n], idx uint16[n]
 * scratch. Returns the number of representatives.
 */
static size_t thin3(const magcal_vec3_t *pts, size_t n, const magcal_vec3_t *c, float h, float *key,
                    uint16_t *idx, uint8_t *rep)
{
    const float side = 2.0f * (float)AUTO3_CELL_HALF;
    size_t i;
    size_t m = 0u;
    for (i = 0; i < n; ++i) {
        key[i] = (cell3(pts[i].x - c->x, h) * side + cell3(pts[i].y - c->y, h)) * side +
                 cell3(pts[i].z - c->z, h);
        idx[i] = (uint16_t)i;
    }
    (void)memset(rep, 0, (n + 7u) / 8u);
    magcal_ocore_sort_idx(idx, key, n);
    for (i = 0; i < n; ++i) {
        if (i == 0u || key[idx[i]] != key[idx[i - 1u]]) {
            const unsigned p = idx[i];
            rep[p >> 3] = (uint8_t)(rep[p >> 3] | (1u << (p & 7u)));
            ++m;
        }
    }
    return m;
}

/* The rule of optics.h. w holds a float[n], b float[n] and the band list uint16[n] (10 n bytes). */
/*
 * Band representatives in the largest cluster of ExtractDBSCAN at eps' (4.3 over the stored ordering):
 * clusters start at a point with reach > eps' and core <= eps' and collect every later point
 * with reach <= eps' (noise points in between do not end them).
 */
static size_t band_in_largest(const auto3_t *au, float eps_prime)
{
    size_t k;
    size_t best = 0u;
    size_t cur = 0u;
    int started = 0;
    for (k = 0; k < au->n; ++k) {
        const size_t p = au->order[k];
        const float d2 = dist2(&au->pts[p], &au->cen);
        size_t in_band = 0u;
        if (d2 >= au->lo2 && d2 <= au->hi2 &&
            ((unsigned)au->rep[p >> 3] & (1u << (p & 7u))) != 0u) {
            in_band = 1u; /* a representative in the band: a rest phase counts once */
        }
        if (au->reach[p] > eps_prime) {
            if (au->core[p] <= eps_prime) {
                best = cur > best ? cur : best;
                cur = in_band;
                started = 1;
            }
        } else if (started != 0) {
            cur += in_band;
        } else {
            /* not reached: the first point has reach = inf */
        }
    }
    return cur > best ? cur : best;
}

/*
 * The rule of optics.h: robust centre and R, one OPTICS run with eps = R (ordering, reach and
 * core stored in w), then the smallest eps' (geometric bisection over [R/256, R], 20 steps:
 * 5e-6 relative) whose largest cluster holds 75 % of the shell band, times AUTO3_SAFETY.
 * Layout of w: reach float[n] | core float[n] | order uint16[n] | run workspace.
 */
/* (use: the caller's copy of the configuration, changed here) */
static magcal_status_t auto_run3(magcal_optics_cfg_t *use, const magcal_vec3_t *pts, size_t n,
                                 uint8_t *w, auto3_t *au)
{
    float *a = (float *)(void *)w;
    magcal_vec3_t cen = {0.0f, 0.0f, 0.0f};
    optics3_ctx_t *c;
    float rad = INFINITY;
    float lo;
    float hi;
    float e;
    float h;
    size_t i;
    size_t m = 0u;
    size_t target;
    unsigned round;
    int have;
    /* thinning scratch before the run: key float[n] | idx uint16[n] | rep bits; after the run in
     * the run's workspace (free again), where rep survives the bisection */
    uint8_t *rw = w + MAGCAL_OPTICS3_FILTER_RUN_OFFSET_(n);
    uint8_t *rep = rw + 6u * n;

    /* centre and radius with each rest phase (noise around one point) counted once: cells of
     * a fraction of the pair scale first (a clump cannot shrink it), then of the radius found */
    h = pair_scale3(pts, n, a) * AUTO3_THIN_PAIR; /* coarse: out of any clump first */
    if (!(h > 0.0f) || !magcal_isfinite_f(h)) {
        return MAGCAL_ERR_DEGENERATE;
    }
    have = 0;
    if (robust_centre3(pts, n, NULL, a, &cen, &rad) == MAGCAL_OK) {
        have = 1;
    }
    if (have == 0) {
        cen = pts[0]; /* more than half the samples identical: the first grid's origin */
    }
    for (round = 0u; round < AUTO3_THIN_ROUNDS; ++round) {
        if (thin3(pts, n, &cen, h, (float *)(void *)rw, (uint16_t *)(void *)(rw + 4u * n), rep) >=
                AUTO3_MIN_N &&
            robust_centre3(pts, n, rep, a, &cen, &rad) == MAGCAL_OK) {
            have = 1;
            h = rad * AUTO3_THIN_REL * thin_scale3(n);
        }
    }
    if (have == 0) {
        return MAGCAL_ERR_DEGENERATE;
    }
    lo = rad - AUTO3_BAND * rad;
    hi = rad + AUTO3_BAND * rad;
    au->pts = pts;
    au->n = n;
    au->cen = cen;
    au->rad = rad;
    au->lo2 = lo * lo;
    au->hi2 = hi * hi;
    for (i = 0; i < n; ++i) {
        const float d2 = dist2(&pts[i], &cen);
        m += (d2 >= au->lo2 && d2 <= au->hi2) ? 1u : 0u;
    }
    if (m < AUTO3_MIN_BAND) {
        return MAGCAL_ERR_DEGENERATE;
    }
    /* the ordering at eps = R holds every extraction at eps' <= R */
    use->eps = AUTO3_MAX_REL * rad;
    use->min_pts = (uint16_t)AUTO3_MIN_PTS;
    /* at eps = R the 3x3x3 block covers the whole shell: the brute search, whose reach pass
     * shrinks with the unprocessed list, is cheaper (filter at n = 1000: 43.7 M -> 36.7 M) */
    use->neighbors = MAGCAL_NEIGHBORS_BRUTE;
    c = ctx3_setup(use, pts, n, w + MAGCAL_OPTICS3_FILTER_RUN_OFFSET_(n));
    c->oc.reach = (float *)(void *)w;
    c->oc.core = (float *)(void *)(w + 4u * n);
    c->oc.order = (uint16_t *)(void *)(w + 8u * n);
    au->reach = c->oc.reach;
    au->core = c->oc.core;
    au->order = c->oc.order;
    optics3_loop(c);
    au->neighbors = c->use_grid != 0 ? MAGCAL_NEIGHBORS_GRID : MAGCAL_NEIGHBORS_BRUTE;
    au->eps = use->eps;
    /* the representatives again (the run used this memory), counted in the band */
    (void)thin3(pts, n, &cen, rad * AUTO3_THIN_REL * thin_scale3(n), (float *)(void *)rw,
                (uint16_t *)(void *)(rw + 4u * n), rep);
    au->rep = rep;
    m = 0u;
    for (i = 0; i < n; ++i) {
        const float d2 = dist2(&pts[i], &cen);
        if (d2 >= au->lo2 && d2 <= au->hi2 && ((unsigned)rep[i >> 3] & (1u << (i & 7u))) != 0u) {
            ++m;
        }
    }

    target = m - m / 4u; /* 75 % of the band */
    lo = AUTO3_MIN_REL * rad;
    hi = AUTO3_MAX_REL * rad;
    if (band_in_largest(au, hi) < target) {
        e = hi; /* the bulk never connects within R: keep the largest cluster at R */
    } else if (band_in_largest(au, lo) >= target) {
        e = lo;
    } else {
        for (i = 0; i < AUTO3_BISECT; ++i) { /* invariant: lo fails, hi connects */
            const float mid = sqrtf(lo * hi);
            if (band_in_largest(au, mid) >= target) {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        e = AUTO3_SAFETY * hi;
    }
    if (e > AUTO3_MAX_REL * rad) {
        e = AUTO3_MAX_REL * rad;
    }
    au->eps_prime = e;
    return MAGCAL_OK;
}

magcal_status_t magcal_optics_auto_params3(const magcal_vec3_t *pts, size_t n, void *work,
                                           size_t work_len, float *eps, uint16_t *min_pts,
                                           float *eps_prime)
{
    magcal_optics_cfg_t cfg = MAGCAL_OPTICS_CFG_DEFAULT;
    magcal_status_t st;
    auto3_t *au;
    if (pts == NULL || work == NULL || eps == NULL || min_pts == NULL || eps_prime == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (magcal_misalign(work, 4u) != 0u) {
        return MAGCAL_ERR_ALIGNMENT;
    }
    st = check_points3(pts, n, AUTO3_MIN_N);
    if (st != MAGCAL_OK) {
        return st;
    }
    if (work_len < MAGCAL_OPTICS3_FILTER_WORKSPACE_LEN(n)) {
        return MAGCAL_ERR_WORKSPACE;
    }
    au = auto_record3((uint8_t *)work, n);
    st = auto_run3(&cfg, pts, n, (uint8_t *)work, au);
    if (st != MAGCAL_OK) {
        return st;
    }
    *eps = au->eps;
    *eps_prime = au->eps_prime;
    *min_pts = (uint16_t)AUTO3_MIN_PTS;
    return MAGCAL_OK;
}

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

/*
 * Shell selection of the automatic filter: among the clusters of labels (ExtractDBSCAN over
 * au->order: each cluster is one stretch of the ordering, noise in between), keep the one whose
 * shell-band samples occupy the most direction cells around the centre, then the most samples,
 * then the smaller id. A rest phase (one direction) cannot win over the rotation.
 * Returns MAGCAL_ERR_ALL_NOISE (mask untouched) when there is no cluster.
 */
static magcal_status_t keep_widest3(const auto3_t *au, const int16_t *labels, uint8_t *inlier_mask,
                                    int16_t *id_out, uint16_t *count_out)
{
    uint32_t cur[3] = {0u, 0u, 0u};
    uint32_t best_ext = 0u;
    size_t best_count = 0u;
    size_t cur_count = 0u;
    int32_t cur_id = -1;
    int32_t best_id = -1;
    size_t k;
    for (k = 0; k <= au->n; ++k) {
        const size_t p = k < au->n ? au->order[k] : 0u;
        const int32_t lab = k < au->n ? (int32_t)labels[p] : -2;
        if (lab == -2 || (lab >= 0 && lab != cur_id)) {
            if (cur_id >= 0) {
                const uint32_t ext = magcal_ocore_popcount(cur[0]) + magcal_ocore_popcount(cur[1]) +
                                     magcal_ocore_popcount(cur[2]);
                if (ext > best_ext || (ext == best_ext && cur_count > best_count)) {
                    best_ext = ext;
                    best_count = cur_count;
                    best_id = cur_id;
                }
            }
            cur_id = lab;
            cur_count = 0u;
            cur[0] = 0u;
            cur[1] = 0u;
            cur[2] = 0u;
        }
        if (lab >= 0) {
            const float dx = au->pts[p].x - au->cen.x;
            const float dy = au->pts[p].y - au->cen.y;
            const float dz = au->pts[p].z - au->cen.z;
            const float d2 = dx * dx + dy * dy + dz * dz;
            ++cur_count;
            if (d2 >= au->lo2 && d2 <= au->hi2) {
                const unsigned cell = dir_cell3(dx, dy, dz);
                cur[cell >> 5] |= 1u << (cell & 31u);
            }
        }
    }
    if (best_id < 0) {
        return MAGCAL_ERR_ALL_NOISE;
    }
    for (k = 0; k < au->n; ++k) {
        inlier_mask[k] = (int32_t)labels[k] == best_id ? 1u : 0u;
    }
    *id_out = (int16_t)best_id;
    *count_out = (uint16_t)best_count;
    return MAGCAL_OK;
}

magcal_status_t magcal_optics_filter3(const magcal_optics_cfg_t *cfg, const magcal_vec3_t *pts,
                                      size_t n, void *work, size_t work_len, uint8_t *inlier_mask,
                                      magcal_optics_result_t *info)
{
    magcal_optics_cfg_t use;
    optics3_ctx_t *c;
    magcal_status_t st;
    float eps_prime;
    uint8_t *w = (uint8_t *)work;
    if (cfg == NULL || pts == NULL || work == NULL || inlier_mask == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (magcal_misalign(work, 4u) != 0u) {
        return MAGCAL_ERR_ALIGNMENT;
    }
    use = *cfg;
    if (!(cfg->eps > 0.0f)) {
        auto3_t *au = auto_record3(w, n);
        int16_t *labels = (int16_t *)(void *)(w + MAGCAL_OPTICS3_FILTER_RUN_OFFSET_(n));
        uint16_t n_clusters = 0u;
        uint16_t count = 0u;
        int16_t id = MAGCAL_OPTICS_NOISE;
        size_t n_noise = 0u;
        size_t i;
        if (cfg->eps != cfg->eps) {
            return MAGCAL_ERR_ARG; /* NaN is not "auto" */
        }
        use.eps = 1.0f;
        use.min_pts = (uint16_t)AUTO3_MIN_PTS;
        st = magcal_ocore_check_cfg(&use);
        if (st == MAGCAL_OK) {
            st = check_points3(pts, n, AUTO3_MIN_N);
        }
        if (st == MAGCAL_OK && work_len < MAGCAL_OPTICS3_FILTER_WORKSPACE_LEN(n)) {
            st = MAGCAL_ERR_WORKSPACE;
        }
        if (st == MAGCAL_OK) {
            st = auto_run3(&use, pts, n, w, au);
        }
        if (st != MAGCAL_OK) {
            return st;
        }
        /* the run's workspace is free again: labels, then the cluster counts */
        (void)magcal_optics_extract_dbscan(au->order, au->reach, au->core, n, au->eps, au->eps_prime,
                                           labels, &n_clusters);
        for (i = 0; i < n; ++i) {
            n_noise += labels[i] == MAGCAL_OPTICS_NOISE ? 1u : 0u;
        }
        st = keep_widest3(au, labels, inlier_mask, &id, &count);
        if (info != NULL) {
            (void)memset(info, 0, sizeof *info);
            info->eps = au->eps;
            info->eps_prime = au->eps_prime;
            info->min_pts = (uint16_t)AUTO3_MIN_PTS;
            info->neighbors = au->neighbors;
            info->n_clusters = n_clusters;
            info->largest_id = id;
            info->n_inliers = count;
            info->n_noise = (uint16_t)n_noise;
        }
        return st;
    }
    st = magcal_ocore_check_cfg(&use);
    if (st != MAGCAL_OK) {
        return st;
    }
    eps_prime = cfg->eps_prime == 0.0f ? cfg->eps : cfg->eps_prime;
    if (!(eps_prime > 0.0f) || !magcal_isfinite_f(eps_prime) || eps_prime > cfg->eps) {
        return MAGCAL_ERR_ARG;
    }
    st = check_points3(pts, n, use.min_pts);
    if (st != MAGCAL_OK) {
        return st;
    }
    if (work_len < MAGCAL_OPTICS3_FILTER_WORKSPACE_LEN(n)) {
        return MAGCAL_ERR_WORKSPACE;
    }
    c = ctx3_setup(&use, pts, n, w + MAGCAL_OPTICS3_FILTER_RUN_OFFSET_(n));
    c->oc.reach = (float *)work;
    c->oc.labels = (int16_t *)(void *)(w + 4u * n);
    c->oc.eps_prime = eps_prime;
    optics3_loop(c);
    magcal_ocore_fill_info(info, &c->oc, c->use_grid, use.eps, eps_prime);
    return magcal_ocore_filter_out(&c->oc, n, inlier_mask, info);
}

#endif /* MAGCAL_CFG_ENABLE_3D */
