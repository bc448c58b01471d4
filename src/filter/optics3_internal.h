/*
 * Internal header of the 3-D OPTICS stage (src/filter/optics3*.c; algorithms.md 4, optics.h
 * "3-D samples"): the ordering loop's context, the automatic rule's record and constants, and the
 * functions each file gives the others. Not installed. Files, in data-flow order:
 *   optics3_grid.c  the 3-D grid of the neighbour search GRID (build, 3x3x3 query);
 *   optics3_order.c the ordering loop (PROCESS, START_CORE), the point checks, magcal_optics_run3;
 *   optics3_auto.c  the automatic parameters (robust centre, thinning, eps' rule),
 *                   magcal_optics_auto_params3;
 *   optics3.c       the filter: extraction, the widest-shell selection, magcal_optics_filter3.
 * Only the coordinates and the neighbour search are 3-D: the seed heap/list, reach updates,
 * on-the-fly extraction and MinPts buffer are optics_core.h (shared with the 2-D stage), and
 * ExtractDBSCAN is optics_extract.c's (it never looks at coordinates).
 */
#ifndef MAGCAL_OPTICS3_INTERNAL_H
#define MAGCAL_OPTICS3_INTERNAL_H

#include <stddef.h>
#include <stdint.h>

#include "magcal/optics.h"
#include "magcal_internal.h"
#include "optics_core.h"

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
} magcal_o3_ctx_t;

/* cppcheck-suppress misra-c2012-2.3 ; deviation D4: a static assert is an unused typedef */
MAGCAL_STATIC_ASSERT(sizeof(magcal_o3_ctx_t) + sizeof(void *) - 4u <= MAGCAL_OPTICS3_CTX_LEN_,
                     optics3_ctx_fits_workspace);

static inline float magcal_o3_dist2(const magcal_vec3_t *a, const magcal_vec3_t *b)
{
    float dx = a->x - b->x;
    float dy = a->y - b->y;
    float dz = a->z - b->z;
    return dx * dx + dy * dy + dz * dz;
}

/* Build the grid over live[] / start[] when mode is GRID and it can help (finite eps, points not
 * all equal); otherwise leave use_grid = 0 (brute force). (optics3_grid.c) */
void magcal_o3_grid_build(magcal_o3_ctx_t *c, float eps, magcal_neighbors_t mode);
/* Distinct buckets of the 3x3x3 cells around point p; returns how many (<= 27). (optics3_grid.c) */
size_t magcal_o3_grid_query(const magcal_o3_ctx_t *c, size_t p, uint16_t *bk);

/* The ordering loop over the context's points (optics3_order.c). */
void magcal_o3_loop(magcal_o3_ctx_t *c);
/* n within [min_n, MAGCAL_MAX_SAMPLES] and every coordinate finite (optics3_order.c). */
magcal_status_t magcal_o3_check_points(const magcal_vec3_t *pts, size_t n, size_t min_n);
/* Carve the run workspace w (layout of MAGCAL_OPTICS3_WORKSPACE_LEN) and build the grid when cfg
 * asks for it; returns the context (optics3_order.c). */
magcal_o3_ctx_t *magcal_o3_ctx_setup(const magcal_optics_cfg_t *cfg, const magcal_vec3_t *pts,
                                     size_t n, uint8_t *w);

/* ---- automatic parameters (optics3_auto.c) ------------------------------------------------- */

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
} magcal_o3_auto_t;

/* cppcheck-suppress misra-c2012-2.3 ; deviation D4: a static assert is an unused typedef */
MAGCAL_STATIC_ASSERT(sizeof(magcal_o3_auto_t) + 4u <= MAGCAL_OPTICS3_AUTO_LEN_, auto_record_fits_its_slot);

/* The record behind the filter workspace's run workspace (optics3_auto.c). */
magcal_o3_auto_t *magcal_o3_auto_record(uint8_t *w, size_t n);
/* The rule of optics.h over w (reach | core | order | run workspace); use: the caller's copy of
 * the configuration, changed here (optics3_auto.c). */
magcal_status_t magcal_o3_auto_run(magcal_optics_cfg_t *use, const magcal_vec3_t *pts, size_t n,
                                   uint8_t *w, magcal_o3_auto_t *au);

#endif /* MAGCAL_OPTICS3_INTERNAL_H */
