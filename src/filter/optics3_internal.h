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

/* ---- weights (estimated Cortex-M4F instructions per visit; host callgrind x 1.2, measured by
 * tools/bench/optics3_steps.sh; the selection and heapsort visits are the 2-D ones, W_SEL, W_HS,
 * W_HSL of optics_slice.h) ---------------------------------------------------------------------- */
#define W3_FIN 36     /* finiteness test of one point */
#define W3_PAIR 70    /* one pair distance of the pair scale (sqrt) */
#define W3_GATHER 40  /* robust centre: one point of a coordinate gather pass */
#define W3_RADIUS 60  /* robust centre: one point of the radius pass (sqrt) */
#define W3_KEY 130    /* thinning: one point's cell key (3 floorf, 3 divisions) */
#define W3_MARK 30    /* thinning: one point of the marking pass; band counts */
#define W3_BAND 30    /* one point of a band count or of one eps' trial (band_in_largest) */
#define W3_GRID 40    /* grid build: one point of a pass (bounding box, bucket, placement) */
#define W3_CELL 12    /* grid build: one bucket of the clear, prefix or shift pass */
#define W3_INIT 24    /* ordering start: one point */
#define W3_SKIP 30    /* ordering: one processed point skipped by the outer scan */
#define W3_PSTART 200 /* ordering: mark, core, extraction of one point; one neighbour query */
#define W3_CAND 30    /* ordering: one candidate of a core-distance (or start-core) pass */
#define W3_REACH 30   /* ordering: one candidate of the reach pass */
#define W3_UPD 60     /* ordering: one reach decrease (seed insert / decrease-key adds W3_HEAP) */
#define W3_HEAP 150   /* ordering, CLASSIC: one heap pop or sift-up */
#define W3_POP 14     /* ordering, IMPROVED: one seed of the minimum scan */
#define W3_WIDE 90    /* filter: one point of the extraction and widest-shell pass */
#define W3_OUT 12     /* filter: one point of the mask */
#define W3_PHASE 150  /* a phase switch (fixed work) */

#define O3_REM_MAX 0x7FFFFFFF /* budget of a one-shot call (int32 remaining count) */
#define O3_ONESHOT_ROUNDS 4096u /* bound of a one-shot loop (each round charges 2^31) */

/* states of the grid build (GB3_*) and of the ordering loop (OR3_*) */
#define GB3_BOX 0u
#define GB3_CLEAR 1u
#define GB3_COUNT 2u
#define GB3_PREFIX 3u
#define GB3_PLACE 4u
#define GB3_SHIFT 5u
#define GB3_DONE 6u
#define OR3_INIT 0u
#define OR3_LIVE 1u
#define OR3_SCAN 2u
#define OR3_ISCORE 3u
#define OR3_PSTART 4u
#define OR3_P1 5u
#define OR3_P2 6u
#define OR3_SEEDS 7u
#define OR3_POP 8u
#define OR3_DONE 9u

/* Everything the ordering loop needs: the dimension-free state (optics_core.h, shared with the
 * 2-D loop), the 3-D points and neighbour search, and the resumable loop's position (it lives in
 * the workspace, so a step can stop inside any scan). */
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
    /* resumable position */
    float lo[3]; /* grid build: bounding box */
    float hi[3];
    float lim;     /* pass 1: current MinPts-th smallest d^2 bound (brute) */
    float core_p;  /* core distance of p (after pass 1) */
    float core2;
    float pbr;     /* IMPROVED minimum scan: best reach so far */
    uint32_t gi;   /* grid build: position */
    uint16_t s;    /* outer scan position */
    uint16_t p;    /* point being processed */
    uint16_t k;    /* candidate position (brute: point or live slot; grid: in bucket bk[t]) */
    uint16_t w;    /* brute pass 2: write position of the compacted live list */
    uint16_t cnt;  /* MinPts buffer count, or the start-core count */
    uint16_t pk;   /* minimum scan position, best slot, best point */
    uint16_t pbest;
    uint16_t pbq;
    uint8_t t;     /* grid: bucket of the query being scanned */
    uint8_t nb;    /* grid: buckets of the query */
    uint8_t pass;  /* 0 (START_CORE only): runs start at core points; 1: at any point */
    uint8_t gst;   /* GB3_* */
    uint8_t st;    /* OR3_* */
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
 * all equal); otherwise leave use_grid = 0 (brute force). Resumable; returns 1 when done, 0 when
 * *rem ran out (optics3_grid.c). */
int magcal_o3_grid_run(magcal_o3_ctx_t *c, float eps, magcal_neighbors_t mode, int32_t *rem);
/* Distinct buckets of the 3x3x3 cells around point p; returns how many (<= 27). (optics3_grid.c) */
size_t magcal_o3_grid_query(const magcal_o3_ctx_t *c, size_t p, uint16_t *bk);

/* The ordering loop over the context's points after the grid build, resumable: 1 when done, 0
 * when *rem ran out (optics3_order.c). */
int magcal_o3_order_run(magcal_o3_ctx_t *c, int32_t *rem);
/* The grid build and the ordering with an unlimited budget (optics3_order.c). */
void magcal_o3_order_all(magcal_o3_ctx_t *c, float eps, magcal_neighbors_t mode);
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
