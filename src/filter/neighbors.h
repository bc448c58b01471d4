/*
 * Internal eps-neighbour search shared by OPTICS and DBSCAN (algorithms.md 4.4 "Grid").
 * Not installed. A query returns up to three ranges of positions into idx[] (one per grid row of
 * the 3x3 block, cells of a row are contiguous after the counting sort); brute force is one range
 * over all points. The caller tests d^2 <= eps^2 itself, so both searches see the same candidate
 * distances computed the same way and give bit-identical results.
 */
#ifndef MAGCAL_NEIGHBORS_H
#define MAGCAL_NEIGHBORS_H

#include <stddef.h>
#include <stdint.h>

#include "magcal/optics.h"

typedef struct {
    const uint16_t *idx; /* NULL: identity (brute force) */
    uint16_t begin[9];
    uint16_t end[9];
    uint16_t n_ranges;
} magcal_nbr_ranges_t;

typedef struct {
    const magcal_vec2_t *pts;
    size_t n;
    int use_grid;
    float x0;
    float y0;
    float inv_h;
    uint16_t gw;     /* cells per row (<= 2^15) */
    uint16_t gh;     /* rows (<= 2^15) */
    uint16_t nbkt;   /* buckets G: cell (cx, cy) lives in bucket (cx + cy*gw) mod G */
    uint16_t *idx;   /* n entries, points sorted by bucket */
    uint16_t *start; /* G + 1 entries */
} magcal_nbr_t;

/*
 * Build the index. mem: MAGCAL_NEIGHBORS_WORKSPACE_LEN(n) bytes, 2-byte aligned. window: NULL
 * (grid over the bounding box) or {xmin, ymin, xmax, ymax}: the grid covers only the window and
 * points outside are clamped into the border cells (still exact: clamping is monotone, so two
 * points within eps stay in adjacent cells; only the border cells get fuller).
 * Uniform grid with cell side h = eps*(1 + 2^-6) over the box; the row-major cell number is
 * folded modulo G = MAGCAL_OPTICS_GRID_CELLS(n) buckets and the points are counting-sorted by
 * bucket. When the grid has no more than G cells this IS the plain dense grid of algorithms.md
 * 4.4; when far outliers stretch the box beyond G cells, distant cells share buckets (a few extra
 * candidates that the distance test rejects) instead of the cell side growing or the search
 * falling back to brute force. A query visits the (deduplicated) buckets of the 3x3 cells.
 * Falls back to brute force when mode is BRUTE, eps is not finite, or the points are all equal.
 */
void magcal_nbr_build(magcal_nbr_t *nb, const magcal_vec2_t *pts, size_t n, float eps,
                      magcal_neighbors_t mode, void *mem, const float *window);

/* State of a resumable magcal_nbr_build (the slice contract, optics.h): its loops over the points
 * and the buckets are charged visit by visit against the caller's remaining budget. */
typedef struct {
    float eps;
    float win[4];
    float xmin;
    float xmax;
    float ymin;
    float ymax;
    uint16_t i;    /* loop position of the current stage (point or bucket) */
    uint8_t stage; /* NBR_B_* in neighbors.c */
    uint8_t use_win;
} magcal_nbr_build_t;

/* Start building the index (arguments as magcal_nbr_build); O(1). */
void magcal_nbr_build_begin(magcal_nbr_t *nb, magcal_nbr_build_t *b, const magcal_vec2_t *pts,
                            size_t n, float eps, magcal_neighbors_t mode, void *mem,
                            const float *window);

/* Continue the build while *rem > 0 (estimated M4F instructions left, decreased per visit; at
 * least one visit per call). Returns 1 when the index is complete, 0 when the budget ran out. */
int magcal_nbr_build_step(magcal_nbr_t *nb, magcal_nbr_build_t *b, int32_t *rem);

/* Candidate ranges for a query at point index p (every point within eps of p is in them). */
void magcal_nbr_query(const magcal_nbr_t *nb, size_t p, magcal_nbr_ranges_t *r);

/*
 * eps accepted by OPTICS and DBSCAN: eps > 0 and, unless eps is +Inf, eps^2 (the threshold on
 * squared distances) finite and at least MAGCAL_NBR_EPS2_MIN = FLT_MIN / 1024, i.e.
 * 3.4e-21 <= eps <= 1.8e19. If eps^2 overflows, every far pair (d^2 = Inf) passes; if it underflows
 * to 0 (or to a few subnormal steps), pairs farther than the grid's cell side round to d^2 <= eps^2
 * and the brute search links pairs the grid never compares (fuzz finding F7). From FLT_MIN / 1024
 * up, a subnormal d^2 keeps >= 13 significant bits, a rounding far below the grid margin 2^-6, and
 * both searches stay bit-identical (test_optics runs eps = 3e-20). Returns 1 when usable, else 0.
 */
int magcal_nbr_eps_ok(float eps);

/* Returns MAGCAL_OK, MAGCAL_ERR_NONFINITE if any coordinate is NaN/Inf. */
magcal_status_t magcal_nbr_check_finite(const magcal_vec2_t *pts, size_t n);

#endif
