/* Internal eps-neighbour search shared by OPTICS and DBSCAN (see neighbors.h). */
#include "neighbors.h"

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

void magcal_nbr_build(magcal_nbr_t *nb, const magcal_vec2_t *pts, size_t n, float eps,
                      magcal_neighbors_t mode, void *mem, const float *window)
{
    float xmin, xmax, ymin, ymax, w, hgt, h, fw, fh;
    size_t i, c, g, cells, cap = MAGCAL_OPTICS_GRID_CELLS(n);
    unsigned it;
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
    if (mode != MAGCAL_NEIGHBORS_GRID || !magcal_isfinite_f(eps) || n == 0u) {
        return;
    }
    xmin = xmax = pts[0].x;
    ymin = ymax = pts[0].y;
    for (i = 1; i < n; ++i) {
        xmin = pts[i].x < xmin ? pts[i].x : xmin;
        xmax = pts[i].x > xmax ? pts[i].x : xmax;
        ymin = pts[i].y < ymin ? pts[i].y : ymin;
        ymax = pts[i].y > ymax ? pts[i].y : ymax;
    }
    if (window != NULL) {
        xmin = window[0] > xmin ? window[0] : xmin;
        ymin = window[1] > ymin ? window[1] : ymin;
        xmax = window[2] < xmax ? window[2] : xmax;
        ymax = window[3] < ymax ? window[3] : ymax;
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
        return; /* overflowing extent or all points equal: brute force is as good */
    }
    h = eps + eps * NBR_MARGIN;
    if (!(h > 0.0f)) {
        return;
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
    if (it == 256u || !magcal_isfinite_f(h)) {
        return;
    }
    nb->gw = (uint16_t)((size_t)fw + 1u);
    nb->gh = (uint16_t)((size_t)fh + 1u);
    cells = (size_t)nb->gw * nb->gh;
    nb->nbkt = (uint16_t)(cells < cap ? cells : cap);
    nb->x0 = xmin;
    nb->y0 = ymin;
    nb->inv_h = 1.0f / h;
    nb->use_grid = 1;
    g = nb->nbkt;
    for (c = 0; c <= g; ++c) {
        nb->start[c] = 0u;
    }
    for (i = 0; i < n; ++i) {
        nb->start[nbr_cell(nb, i) + 1u]++;
    }
    for (c = 0; c < g; ++c) {
        nb->start[c + 1u] = (uint16_t)(nb->start[c + 1u] + nb->start[c]);
    }
    for (i = 0; i < n; ++i) {
        c = nbr_cell(nb, i);
        nb->idx[nb->start[c]] = (uint16_t)i;
        nb->start[c]++;
    }
    /* start[c] now holds the end of bucket c = the old start[c+1]: shift back by one. */
    for (c = g; c > 0u; --c) {
        nb->start[c] = nb->start[c - 1u];
    }
    nb->start[0] = 0u;
}

void magcal_nbr_query(const magcal_nbr_t *nb, size_t p, magcal_nbr_ranges_t *r)
{
    uint16_t cx, cy, x_lo, x_hi, y_lo, y_hi, x, y;
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
