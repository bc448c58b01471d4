/* Internal eps-neighbour search shared by OPTICS and DBSCAN (see neighbors.h). */
#include "neighbors.h"

#include <float.h>
#include <string.h>

#include "magcal_internal.h"

/*
 * Grid margin: h = eps * (1 + 2^-6). algorithms.md 4.4 uses 2^-20, a float64 margin. In float32
 * the rounding of (x - x0) * (1/h) is relative to the grid width: two points eps apart can see
 * their cell coordinates differ by 1/(1+margin) + 6 * 2^-24 * W cells; with W <= 2^15 cells per
 * row that is below 1 for margin >= 0.012. A larger h only adds candidates, never removes a
 * neighbour.
 */
#define NBR_MARGIN 0.015625f
#define NBR_MAX_SIDE 32768.0f

int magcal_nbr_eps_ok(float eps)
{
    const float e2 = eps * eps;
    int ok = 0;
    if (eps > 0.0f &&
        (!magcal_isfinite_f(eps) || (e2 >= FLT_MIN * (1.0f / 1024.0f) && magcal_isfinite_f(e2)))) {
        ok = 1;
    }
    return ok;
}

magcal_status_t magcal_nbr_check_finite(const magcal_vec2_t *pts, size_t n)
{
    size_t i;
    for (i = 0; i < n; ++i) {
        if (!magcal_isfinite_f(pts[i].x) || !magcal_isfinite_f(pts[i].y)) {
            return MAGCAL_ERR_NONFINITE;
        }
    }
    return MAGCAL_OK;
}

static uint16_t nbr_coord(float v, float v0, float inv_h, uint16_t g)
{
    float c = (v - v0) * inv_h;
    if (!(c > 0.0f)) {
        return 0u;
    }
    if (c >= (float)g) {
        return (uint16_t)(g - 1u);
    }
    return (uint16_t)c; /* truncation == floor for c > 0 */
}

static size_t nbr_bucket(const magcal_nbr_t *nb, uint16_t cx, uint16_t cy)
{
    return ((size_t)cy * nb->gw + cx) % nb->nbkt;
}

static size_t nbr_cell(const magcal_nbr_t *nb, size_t i)
{
    uint16_t cx = nbr_coord(nb->pts[i].x, nb->x0, nb->inv_h, nb->gw);
    uint16_t cy = nbr_coord(nb->pts[i].y, nb->y0, nb->inv_h, nb->gh);
    return nbr_bucket(nb, cx, cy);
}

/* Per-visit weights of the build's loops, estimated Cortex-M4F instructions (host callgrind x 1.2,
 * tools/bench_optics/slice_fit.py): bounding box, bucket clear, count, prefix sum, placement,
 * shift; SETUP = the fixed part between the box and the buckets, HGROW one cell-growth round. */
#define NBR_W_BBOX 24
#define NBR_W_ZERO 11
#define NBR_W_CELL 71
#define NBR_W_PREFIX 11
#define NBR_W_PLACE 74
#define NBR_W_SHIFT 10
#define NBR_W_SETUP 185
#define NBR_W_HGROW 18

/* Charging a visit (MAGCAL_OPTICS_SLICE_PROFILE: also counted, after optics.c's weights). */
#ifdef MAGCAL_OPTICS_SLICE_PROFILE
extern unsigned long magcal_optics_slice_prof[];
#define NBR_CHARGE(r, w, id, k)                                                                    \
    ((r) -= (int32_t)(w) * (int32_t)(k), magcal_optics_slice_prof[22 + (id)] /* after optics.c's 22 */ += (unsigned long)(k))
#else
#define NBR_CHARGE(r, w, id, k) ((r) -= (int32_t)(w) * (int32_t)(k))
#endif

#define NBR_B_BBOX 0u
#define NBR_B_SETUP 1u
#define NBR_B_ZERO 2u
#define NBR_B_COUNT 3u
#define NBR_B_PREFIX 4u
#define NBR_B_PLACE 5u
#define NBR_B_SHIFT 6u
#define NBR_B_DONE 7u

void magcal_nbr_build_begin(magcal_nbr_t *nb, magcal_nbr_build_t *b, const magcal_vec2_t *pts,
                            size_t n, float eps, magcal_neighbors_t mode, void *mem,
                            const float *window)
{
    nb->pts = pts;
    nb->n = n;
    nb->use_grid = 0;
    nb->idx = (uint16_t *)mem;
    nb->start = nb->idx + n;
    nb->gw = 1u;
    nb->gh = 1u;
    nb->nbkt = 1u;
    nb->x0 = 0.0f;
    nb->y0 = 0.0f;
    nb->inv_h = 0.0f;
    (void)memset(b, 0, sizeof *b);
    b->eps = eps;
    b->stage = (uint8_t)NBR_B_DONE;
    if (mode != MAGCAL_NEIGHBORS_GRID || !magcal_isfinite_f(eps) || n == 0u) {
        return;
    }
    if (window != NULL) {
        b->use_win = 1u;
        (void)memcpy(b->win, window, sizeof b->win);
    }
    b->xmin = pts[0].x;
    b->xmax = b->xmin;
    b->ymin = pts[0].y;
    b->ymax = b->ymin;
    b->i = 1u;
    b->stage = (uint8_t)NBR_B_BBOX;
}

/* Window clip, cell side and grid shape (one visit); leaves nb on brute force when no grid helps.
 * Returns 1 when a grid is to be built. */
static int nbr_setup(magcal_nbr_t *nb, magcal_nbr_build_t *b, int32_t *rem)
{
    float xmin = b->xmin;
    float xmax = b->xmax;
    float ymin = b->ymin;
    float ymax = b->ymax;
    float w;
    float hgt;
    float h;
    float fw = 0.0f;
    float fh = 0.0f;
    size_t cells;
    size_t cap = MAGCAL_OPTICS_GRID_CELLS(nb->n);
    unsigned it;
    NBR_CHARGE(*rem, NBR_W_SETUP, 0, 1);
    if (b->use_win != 0u) {
        xmin = b->win[0] > xmin ? b->win[0] : xmin;
        ymin = b->win[1] > ymin ? b->win[1] : ymin;
        xmax = b->win[2] < xmax ? b->win[2] : xmax;
        ymax = b->win[3] < ymax ? b->win[3] : ymax;
        if (xmax < xmin) {
            xmax = xmin;
        }
        if (ymax < ymin) {
            ymax = ymin;
        }
    }
    w = xmax - xmin;
    hgt = ymax - ymin;
    if (!magcal_isfinite_f(w) || !magcal_isfinite_f(hgt) || (w <= 0.0f && hgt <= 0.0f)) {
        return 0; /* overflowing extent or all points equal: brute force is as good */
    }
    h = b->eps + b->eps * NBR_MARGIN;
    if (!(h > 0.0f)) {
        return 0;
    }
    /* Only when eps is tiny against the box: grow h until a row has at most 2^15 cells. */
    for (it = 0; it < 256u; ++it) {
        fw = w / h;
        fh = hgt / h;
        if (fw < NBR_MAX_SIDE - 1.0f && fh < NBR_MAX_SIDE - 1.0f) {
            break;
        }
        h *= 2.0f;
    }
    NBR_CHARGE(*rem, NBR_W_HGROW, 1, (int32_t)it);
    if (it == 256u || !magcal_isfinite_f(h)) {
        return 0;
    }
    nb->gw = (uint16_t)((size_t)fw + 1u);
    nb->gh = (uint16_t)((size_t)fh + 1u);
    cells = (size_t)nb->gw * nb->gh;
    nb->nbkt = (uint16_t)(cells < cap ? cells : cap);
    nb->x0 = xmin;
    nb->y0 = ymin;
    nb->inv_h = 1.0f / h;
    return 1;
}

int magcal_nbr_build_step(magcal_nbr_t *nb, magcal_nbr_build_t *b, int32_t *rem)
{
    const magcal_vec2_t *pts = nb->pts;
    const size_t n = nb->n;
    size_t i = b->i;
    int32_t r = *rem;
    int more = 1;
    while (more != 0) {
        const size_t g = nb->nbkt;
        switch (b->stage) {
        case NBR_B_BBOX:
            for (; i < n && r > 0; ++i) {
                b->xmin = pts[i].x < b->xmin ? pts[i].x : b->xmin;
                b->xmax = pts[i].x > b->xmax ? pts[i].x : b->xmax;
                b->ymin = pts[i].y < b->ymin ? pts[i].y : b->ymin;
                b->ymax = pts[i].y > b->ymax ? pts[i].y : b->ymax;
                NBR_CHARGE(r, NBR_W_BBOX, 2, 1);
            }
            if (i < n) {
                more = 0;
                break;
            }
            b->stage = (uint8_t)NBR_B_SETUP;
            break;
        case NBR_B_SETUP:
            if (r <= 0) {
                more = 0;
                break;
            }
            if (nbr_setup(nb, b, &r) == 0) {
                b->stage = (uint8_t)NBR_B_DONE;
                break;
            }
            i = 0u;
            b->stage = (uint8_t)NBR_B_ZERO;
            break;
        case NBR_B_ZERO:
            for (; i <= g && r > 0; ++i) {
                nb->start[i] = 0u;
                NBR_CHARGE(r, NBR_W_ZERO, 3, 1);
            }
            if (i <= g) {
                more = 0;
                break;
            }
            i = 0u;
            b->stage = (uint8_t)NBR_B_COUNT;
            break;
        case NBR_B_COUNT:
            for (; i < n && r > 0; ++i) {
                nb->start[nbr_cell(nb, i) + 1u]++;
                NBR_CHARGE(r, NBR_W_CELL, 4, 1);
            }
            if (i < n) {
                more = 0;
                break;
            }
            i = 0u;
            b->stage = (uint8_t)NBR_B_PREFIX;
            break;
        case NBR_B_PREFIX:
            for (; i < g && r > 0; ++i) {
                nb->start[i + 1u] = (uint16_t)(nb->start[i + 1u] + nb->start[i]);
                NBR_CHARGE(r, NBR_W_PREFIX, 5, 1);
            }
            if (i < g) {
                more = 0;
                break;
            }
            i = 0u;
            b->stage = (uint8_t)NBR_B_PLACE;
            break;
        case NBR_B_PLACE:
            for (; i < n && r > 0; ++i) {
                const size_t c = nbr_cell(nb, i);
                nb->idx[nb->start[c]] = (uint16_t)i;
                nb->start[c]++;
                NBR_CHARGE(r, NBR_W_PLACE, 6, 1);
            }
            if (i < n) {
                more = 0;
                break;
            }
            /* start[c] now holds the end of bucket c = the old start[c+1]: shift back by one */
            i = g;
            b->stage = (uint8_t)NBR_B_SHIFT;
            break;
        case NBR_B_SHIFT:
            for (; i > 0u && r > 0; --i) {
                nb->start[i] = nb->start[i - 1u];
                NBR_CHARGE(r, NBR_W_SHIFT, 7, 1);
            }
            if (i > 0u) {
                more = 0;
                break;
            }
            nb->start[0] = 0u;
            nb->use_grid = 1;
            b->stage = (uint8_t)NBR_B_DONE;
            break;
        default:
            more = 0;
            break;
        }
    }
    b->i = (uint16_t)i;
    *rem = r;
    return b->stage == (uint8_t)NBR_B_DONE ? 1 : 0;
}

void magcal_nbr_build(magcal_nbr_t *nb, const magcal_vec2_t *pts, size_t n, float eps,
                      magcal_neighbors_t mode, void *mem, const float *window)
{
    magcal_nbr_build_t b;
    unsigned guard;
    magcal_nbr_build_begin(nb, &b, pts, n, eps, mode, mem, window);
    for (guard = 0u; guard < 64u; ++guard) { /* one round suffices: the budget is the largest */
        int32_t rem = INT32_MAX;
        if (magcal_nbr_build_step(nb, &b, &rem) != 0) {
            break;
        }
    }
}

void magcal_nbr_query(const magcal_nbr_t *nb, size_t p, magcal_nbr_ranges_t *r)
{
    uint16_t cx;
    uint16_t cy;
    uint16_t x_lo;
    uint16_t x_hi;
    uint16_t y_lo;
    uint16_t y_hi;
    uint16_t x;
    uint16_t y;
    if (!nb->use_grid) {
        r->idx = NULL;
        r->begin[0] = 0u;
        r->end[0] = (uint16_t)nb->n;
        r->n_ranges = 1u;
        return;
    }
    cx = nbr_coord(nb->pts[p].x, nb->x0, nb->inv_h, nb->gw);
    cy = nbr_coord(nb->pts[p].y, nb->y0, nb->inv_h, nb->gh);
    x_lo = cx > 0u ? (uint16_t)(cx - 1u) : 0u;
    x_hi = (uint16_t)(cx + 1u) < nb->gw ? (uint16_t)(cx + 1u) : (uint16_t)(nb->gw - 1u);
    y_lo = cy > 0u ? (uint16_t)(cy - 1u) : 0u;
    y_hi = (uint16_t)(cy + 1u) < nb->gh ? (uint16_t)(cy + 1u) : (uint16_t)(nb->gh - 1u);
    r->idx = nb->idx;
    r->n_ranges = 0u;
    if ((size_t)nb->gw * nb->gh == nb->nbkt) {
        /* dense grid (no folding): the cells of a row are consecutive buckets, 3 ranges */
        for (y = y_lo; y <= y_hi; ++y) {
            size_t row = (size_t)y * nb->gw;
            r->begin[r->n_ranges] = nb->start[row + x_lo];
            r->end[r->n_ranges] = nb->start[row + x_hi + 1u];
            r->n_ranges++;
        }
        return;
    }
    /* folded grid: the 3x3 cells may share buckets; every bucket once (its number parked in end[]
     * while collecting, so no extra stack), one range per distinct bucket */
    for (y = y_lo; y <= y_hi; ++y) {
        for (x = x_lo; x <= x_hi; ++x) {
            uint16_t v = (uint16_t)nbr_bucket(nb, x, y);
            uint16_t t;
            for (t = 0u; t < r->n_ranges && r->end[t] != v; ++t) {
            }
            if (t == r->n_ranges) {
                r->end[r->n_ranges] = v;
                r->n_ranges++;
            }
        }
    }
    for (y = 0u; y < r->n_ranges; ++y) {
        uint16_t v = r->end[y];
        r->begin[y] = nb->start[v];
        r->end[y] = nb->start[v + 1u];
    }
}
