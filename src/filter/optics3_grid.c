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

/* Build the grid over live[] / start[] when mode is GRID and it can help (finite eps, points
 * not all equal); otherwise leave use_grid = 0 (brute force). Resumable per point of the
 * bounding-box, counting and placement passes and per bucket of the clear, prefix and shift
 * passes (c->gst, c->gi; both 0 from magcal_o3_ctx_setup). Returns 1 when built, 0 when *rem ran
 * out (call again). */
int magcal_o3_grid_run(magcal_o3_ctx_t *c, float eps, magcal_neighbors_t mode, int32_t *rem)
{
    const magcal_vec3_t *pts = c->pts;
    const size_t n = c->n;
    int32_t r = *rem;
    size_t i = c->gi;
    if (c->gst == GB3_BOX && i == 0u) {
        c->use_grid = 0;
        r -= (int32_t)W3_PHASE;
        if (mode != MAGCAL_NEIGHBORS_GRID || !magcal_isfinite_f(eps)) {
            c->gst = GB3_DONE;
        } else {
            c->lo[0] = pts[0].x;
            c->lo[1] = pts[0].y;
            c->lo[2] = pts[0].z;
            c->hi[0] = c->lo[0];
            c->hi[1] = c->lo[1];
            c->hi[2] = c->lo[2];
            i = 1u;
        }
    }
    if (c->gst == GB3_BOX) {
        float *lo = c->lo;
        float *hi = c->hi;
        for (; i < n && r > 0; ++i) {
            lo[0] = pts[i].x < lo[0] ? pts[i].x : lo[0];
            lo[1] = pts[i].y < lo[1] ? pts[i].y : lo[1];
            lo[2] = pts[i].z < lo[2] ? pts[i].z : lo[2];
            hi[0] = pts[i].x > hi[0] ? pts[i].x : hi[0];
            hi[1] = pts[i].y > hi[1] ? pts[i].y : hi[1];
            hi[2] = pts[i].z > hi[2] ? pts[i].z : hi[2];
            r -= (int32_t)W3_GRID;
        }
        if (i == n && r > 0) {
            r -= (int32_t)W3_PHASE;
            if (lo[0] == hi[0] && lo[1] == hi[1] && lo[2] == hi[2]) {
                c->gst = GB3_DONE; /* all points equal */
            } else {
                uint32_t g[3];
                unsigned a;
                uint64_t cells;
                const float h = eps * GRID3_MARGIN;
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
                c->gst = GB3_CLEAR;
                i = 0u;
            }
        }
    }
    /* counting sort by bucket: counts in start[b + 1], prefix sums, placement, shift back */
    if (c->gst == GB3_CLEAR) {
        for (; i <= c->nbkt && r > 0; ++i) {
            c->start[i] = 0u;
            r -= (int32_t)W3_CELL;
        }
        if (i > c->nbkt) {
            c->gst = GB3_COUNT;
            i = 0u;
        }
    }
    if (c->gst == GB3_COUNT) {
        for (; i < n && r > 0; ++i) {
            c->start[point_bucket(c, i) + 1u]++;
            r -= (int32_t)W3_GRID;
        }
        if (i == n) {
            c->gst = GB3_PREFIX;
            i = 1u;
        }
    }
    if (c->gst == GB3_PREFIX) {
        for (; i <= c->nbkt && r > 0; ++i) {
            c->start[i] = (uint16_t)(c->start[i] + c->start[i - 1u]);
            r -= (int32_t)W3_CELL;
        }
        if (i > c->nbkt) {
            c->gst = GB3_PLACE;
            i = 0u;
        }
    }
    if (c->gst == GB3_PLACE) {
        for (; i < n && r > 0; ++i) {
            const uint32_t b = point_bucket(c, i);
            c->live[c->start[b]] = (uint16_t)i;
            c->start[b]++;
            r -= (int32_t)W3_GRID;
        }
        if (i == n) {
            c->gst = GB3_SHIFT;
            i = c->nbkt;
        }
    }
    if (c->gst == GB3_SHIFT) {
        for (; i > 0u && r > 0; --i) {
            c->start[i] = c->start[i - 1u];
            r -= (int32_t)W3_CELL;
        }
        if (i == 0u) {
            c->start[0] = 0u;
            c->gst = GB3_DONE;
        }
    }
    c->gi = (uint32_t)i;
    *rem = r;
    return c->gst == GB3_DONE ? 1 : 0;
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
