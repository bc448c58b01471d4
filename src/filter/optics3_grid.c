/*
 * The 3-D grid of the neighbour search GRID (optics3_internal.h): bucket layout, counting sort of
 * the points by bucket, and the 3x3x3 query of the ordering loop (optics3_order.c).
 */
#include <string.h>

#include "magcal/optics.h"
#include "magcal_internal.h"

#if MAGCAL_CFG_ENABLE_3D /* whole file: config.h feature switch */
#include "optics3_internal.h"

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

static uint32_t bucket_of(const magcal_o3_ctx_t *c, uint32_t cx, uint32_t cy, uint32_t cz)
{
    uint32_t b;
    if (c->dense != 0) {
        b = cx + c->gw * (cy + c->gh * cz);
    } else {
        b = ((cx * 73856093u) ^ (cy * 19349663u) ^ (cz * 83492791u)) % c->nbkt;
    }
    return b;
}

static uint32_t point_bucket(const magcal_o3_ctx_t *c, size_t i)
{
    const magcal_vec3_t *q = &c->pts[i];
    return bucket_of(c, cell3_of(q->x, c->x0, c->inv_h), cell3_of(q->y, c->y0, c->inv_h),
                     cell3_of(q->z, c->z0, c->inv_h));
}

/* Build the grid over live[] / start[] when cfg asks for it and it can help (finite eps, points
 * not all equal); otherwise leave use_grid = 0 (brute force). */
void magcal_o3_grid_build(magcal_o3_ctx_t *c, float eps, magcal_neighbors_t mode)
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
size_t magcal_o3_grid_query(const magcal_o3_ctx_t *c, size_t p, uint16_t *bk)
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


#endif /* MAGCAL_CFG_ENABLE_3D */
