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
#include "optics_slice.h"

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

/* ---- time-sliced work (slice_contract: budget in estimated M4F instructions) -------------- */

/* Weights: Cortex-M4F instructions per visit, measured: least squares of the instructions of
 * 10,893 density steps of cont3_trace_dirty.elf (QEMU -icount shift=0, the dirty tumble, n ~ 400)
 * against the visits charged in each (tools/bench/cont3_weights.py), times 1.1, rounded up.
 * W3_GRIDP / W3_GRIDB (the given-parameter path's grid, not run by the 3-D loop) and W3_PHASE
 * (8 visits: not fitted) are estimates. */
#define W3_FIN 40      /* finiteness test of one point */
#define W3_PAIR 61     /* one pair distance (sqrt) of the pair scale */
#define W3_GATHER 44   /* robust centre: one point of a median's gather pass */
#define W3_RAD 72      /* robust centre: one point of the radius pass (sqrt) */
#define W3_KEY 171     /* thinning: one point's cell key (3 divisions, floorf) */
#define W3_MARK 31     /* thinning: one point of the representative marking */
#define W3_BAND 62     /* one point of a band count or of an eps' probe */
#define W3_INIT 41     /* ordering start: one point */
#define W3_SKIP 29     /* ordering: one point of the outer scan */
#define W3_CAND 39     /* ordering: one candidate of the core-distance or core-test pass */
#define W3_REACH 53    /* ordering: one candidate of the reach (live list) pass */
#define W3_UPD 46      /* ordering: one reach decrease */
#define W3_POP 24      /* ordering: one seed of the minimum scan */
#define W3_GRIDP 1500  /* ordering, GRID: one whole PROCESS(p) or core test (27 cells) */
#define W3_GRIDB 60    /* grid build: one point (bounding box, counting sort) */
#define W3_LABEL 35    /* extraction: one point */
#define W3_WIDE 97     /* shell selection: one point (its direction cell) */
#define W3_OUT 26      /* filter output: one point of the mask */
#define W3_PHASE 300   /* fixed cost of a phase switch */

/* Charging k visits of weight w: r -= w k. In the bench's trace build (MAGCAL_BENCH_TRACE,
 * cont3_trace*.elf only, never shipped) the visits are also counted per weight, so
 * tools/bench/cont3_weights.py can fit the weights to the measured instructions of each step. */
#ifdef MAGCAL_BENCH_TRACE
enum { P3_W3_FIN, P3_W3_PAIR, P3_W3_GATHER, P3_W3_RAD, P3_W3_KEY, P3_W3_MARK, P3_W3_BAND, P3_W3_INIT, P3_W3_SKIP, P3_W3_CAND, P3_W3_REACH, P3_W3_UPD, P3_W3_POP, P3_W3_GRIDP, P3_W3_GRIDB, P3_W3_LABEL, P3_W3_WIDE, P3_W3_OUT, P3_W3_PHASE, P3_N };
extern uint32_t magcal_bench_o3_visits[P3_N + 1]; /* + the total charged (optics3.c) */
/* cppcheck-suppress misra-c2012-20.10 ; bench-only trace build (MAGCAL_BENCH_TRACE): the counter index from the weight name */
#define CHARGE3_K(r, w, k)                                                                         \
    ((r) -= (int32_t)(w) * (int32_t)(k), magcal_bench_o3_visits[P3_##w] += (uint32_t)(k))
/* cppcheck-suppress misra-c2012-20.10 ; bench-only trace build (MAGCAL_BENCH_TRACE): the counter index from the weight name */
#define CHARGE3(r, w) ((r) -= (int32_t)(w), magcal_bench_o3_visits[P3_##w]++)
#else
#define CHARGE3_K(r, w, k) ((r) -= (int32_t)(w) * (int32_t)(k))
#define CHARGE3(r, w) ((r) -= (int32_t)(w))
#endif

/* The resumable ordering loop (algorithms.md 4.1-4.2, PROCESS and START_CORE), per candidate of
 * every brute-force scan, per seed of the IMPROVED minimum scan and per point of the outer scan;
 * with the grid one PROCESS(p) (at most 27 small cells) is one unit. */
typedef struct {
    float lim;
    float core_p;
    float core2;
    float pbr;      /* minimum scan: best reach so far */
    uint16_t s;     /* outer scan position (the start loop's index) */
    uint16_t p;     /* point being processed */
    uint16_t k;     /* candidate / live list / seed position */
    uint16_t cnt;   /* MinPts buffer count or core-test count */
    uint16_t w;     /* live pass write position */
    uint16_t pbest; /* minimum scan: best slot and point */
    uint16_t pbq;
    uint8_t pass; /* 0 (START_CORE only): runs start at core points; 1: at any point */
    uint8_t st;   /* O3_OR_* */
} magcal_o3_ord_t;

#define O3_OR_INIT 0u
#define O3_OR_SCAN 1u
#define O3_OR_ISCORE 2u
#define O3_OR_P1 3u
#define O3_OR_P2 4u
#define O3_OR_POP 5u
#define O3_OR_DONE 6u
#define O3_OR_GRIDP 7u /* the whole grid PROCESS of o->p, then the seeds */

/* Start the ordering over the context (O(1)). */
void magcal_o3_ord_begin(magcal_o3_ord_t *o);
/* Returns 1 when the ordering is complete, 0 when *rem ran out (call again) (optics3_order.c). */
int magcal_o3_ord_run(magcal_o3_ord_t *o, magcal_o3_ctx_t *c, int32_t *rem);
/* The whole ordering loop in one call (magcal_optics_run3). */
void magcal_o3_loop(magcal_o3_ctx_t *c);
/* Finiteness of pts[*i ..n) per point within *rem: 1 done (all finite), 0 paused, -1 a NaN/Inf. */
int magcal_o3_fin_run(const magcal_vec3_t *pts, size_t n, uint16_t *i, int32_t *rem);
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

/* Robust centre and radius over the counted points (all, or the thinning's representatives):
 * coordinate medians, R = median distance; passes after the first use only the points within
 * AUTO3_TRIM R of the previous centre. Resumable per gathered point and selection step. */
typedef struct {
    magcal_o2_sel_t sel;
    magcal_vec3_t cen; /* previous pass's centre (the trim's) */
    magcal_vec3_t nc;  /* this pass's medians */
    float rad;
    float lim2;
    uint16_t i;
    uint16_t k;
    uint8_t use_rep; /* 1: only the representatives (au->rep bits) */
    uint8_t pass;
    uint8_t axis; /* 0..2 coordinate medians, 3 the radius */
    uint8_t st;   /* 0 gather, 1 select */
} magcal_o3_rc_t;

/* Thinning: one representative (lowest index) per cubic cell of side h (rep bits). */
typedef struct {
    magcal_o2_hsort_t hs;
    float h;
    uint16_t i;
    uint16_t m;
    uint8_t st; /* 0 keys, 1 sort, 2 mark */
} magcal_o3_th_t;

/* The automatic rule's and the filter's tail state (the eps' probes, extraction, selection). */
typedef struct {
    float lo; /* eps' probes: the bracket, the value probed */
    float hi;
    float e;
    float h; /* thinning cell side */
    uint32_t rng;
    int32_t id; /* extraction: current cluster id; selection: the current cluster */
    int32_t best_id;
    uint16_t n_clusters;
    uint16_t best_count;
    uint16_t cur_count;
    uint16_t n_noise;
    uint16_t target;
    uint16_t m; /* a count: pairs, band points */
    uint16_t i; /* a pass's position */
    uint16_t pbest; /* probe: band representatives of the largest cluster so far, of the current */
    uint16_t pcur;
    uint8_t round;
    uint8_t have;
    uint8_t bis;     /* eps' probes done */
    uint8_t started; /* probe: a cluster has started */
} magcal_o3_tail_t;

/* The shell selection's direction cells of the current cluster, and the best cluster's count. */
typedef struct {
    uint32_t cur3[3];
    uint32_t best_ext;
} magcal_o3_wide_t;

/* The time-sliced 3-D filter (optics3.c): lives in the caller's magcal_optics3_slice_t. */
typedef struct {
    const magcal_vec3_t *pts;
    uint8_t *w;
    uint8_t *mask;
    magcal_optics_result_t *info;
    magcal_o3_ctx_t *c;
    magcal_o3_auto_t *au;
    size_t n;
    size_t work_len;
    magcal_optics_cfg_t use;
    /* cppcheck-suppress misra-c2012-19.2 ; deviation D12: the slice state overlays the sub-machines that are never live together, so it fits the workspace budget */
    union {
        magcal_o3_rc_t rc;
        magcal_o3_th_t th;
        magcal_o3_ord_t ord;
        magcal_o2_sel_t sel;
        magcal_o3_wide_t wide;
    /* cppcheck-suppress misra-c2012-19.2 ; deviation D12: the slice state overlays the sub-machines that are never live together, so it fits the workspace budget */
    } u;
    magcal_o3_tail_t t;
    magcal_vec3_t cen; /* the rule's centre and radius so far */
    float rad;
    uint32_t magic;
    int32_t status;
    uint8_t phase;  /* O3S_* (optics3.c) */
    uint8_t params; /* 1: magcal_optics_auto_params3 (stop after eps') */
    uint8_t autom;  /* 1: automatic parameters */
} magcal_o3s_t;

/* cppcheck-suppress misra-c2012-2.3 ; deviation D4: a static assert is an unused typedef */
MAGCAL_STATIC_ASSERT(sizeof(magcal_o3s_t) <= sizeof(magcal_optics3_slice_t), optics3_slice_fits);

/* The record behind the filter workspace's run workspace (optics3_auto.c). */
magcal_o3_auto_t *magcal_o3_auto_record(uint8_t *w, size_t n);
/* The automatic rule of optics.h, resumable (optics3_auto.c): from phase O3S_PAIRS to
 * O3S_AUTO_DONE; returns 1 when done (au filled and s->status still MAGCAL_IN_PROGRESS, or
 * s->status the error), 0 when
 * *rem ran out. */
int magcal_o3_auto_step(magcal_o3s_t *s, int32_t *rem);
/* The rule's ordering at eps = R: its context and state (phase O3S_ORDER with s->c NULL; called
 * by the driver, outside the rule's frames: the stack) (optics3_auto.c). */
void magcal_o3_auto_order_begin(magcal_o3s_t *s);
/* After the rule's ordering (O3S_ORDER, run by the driver in its own frame: the stack): the
 * thinning again, phase O3S_THIN2 (optics3_auto.c). */
void magcal_o3_auto_ordered(magcal_o3s_t *s);

/* Phases of the sliced filter (optics3.c drives; optics3_auto.c runs the rule's). */
#define O3S_FIN 0u
#define O3S_PAIRS 1u   /* rule: pair scale (pairs, then its median) */
#define O3S_PAIRSEL 2u
#define O3S_RC0 3u     /* rule: centre of all points */
#define O3S_THIN 4u    /* rule: thinning round */
#define O3S_RC 5u      /* rule: centre of the representatives */
#define O3S_BAND 6u    /* rule: band count */
#define O3S_ORDER 7u   /* rule: the ordering at eps = R */
#define O3S_THIN2 8u   /* rule: the representatives again */
#define O3S_BANDREP 9u /* rule: representatives in the band */
#define O3S_PROBE 10u  /* rule: the eps' probes */
#define O3S_AUTO_DONE 11u
#define O3S_LABEL 12u  /* filter: ExtractDBSCAN at eps' and the noise count */
#define O3S_WIDE 13u   /* filter: the widest-shell selection */
#define O3S_MASK 14u   /* filter: the mask */
#define O3S_GRID 15u   /* given parameters: grid build (one unit) */
#define O3S_GORDER 16u /* given parameters: the ordering with on-the-fly extraction */
#define O3S_GOUT 17u   /* given parameters: info and mask (one unit) */
#define O3S_DONE 18u

#endif /* MAGCAL_OPTICS3_INTERNAL_H */
