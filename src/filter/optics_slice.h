/*
 * Internal header of the 2-D OPTICS stage (src/filter/optics*.c; algorithms.md 4, optics.h
 * "time-sliced"): the per-visit weights and the rule's constants, the states of the resumable
 * sub-machines (selection, heapsort, robust centre, thinning, thinned centre, the eps' rule, the
 * ordering loop) that the slice state of optics.c overlays in the caller's workspace, and the
 * functions each sub-machine's file gives the driver. Not installed. Files:
 *   optics_prims.c  resumable primitives: Hoare selection, heapsort (and optics3.c's one-shots);
 *   optics_centre.c robust centre, clump thinning, thinned centre (rule step 1, magcal_optics_thin);
 *   optics_params.c the eps' rule (rule steps 2-4) and the ring sectors;
 *   optics_order.c  the ordering loop with on-the-fly ExtractDBSCAN;
 *   optics.c        the slice state, the driver (begin/step) and the public entry points;
 *   optics_extract.c ExtractDBSCAN of a finished ordering and the largest cluster.
 */
#ifndef MAGCAL_OPTICS_SLICE_H
#define MAGCAL_OPTICS_SLICE_H

#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "magcal/optics.h"
#include "magcal_internal.h"
#include "neighbors.h"
#include "optics_core.h"

/* ---- 1. weights (estimated Cortex-M4F instructions per visit: host callgrind x 1.2) -------- */
/* Fitted by tools/bench_optics/slice_fit.py (least squares of the host instructions of 24,000
 * step calls on rings, parked rings and bursts at n = 288 and 1024 against the visits charged in
 * each), times 1.2; W_HEAP (CLASSIC only, not fitted) is 10 levels of a sift. */

#define W_FIN 32     /* finiteness test of one point */
#define W_SEL 29 /* one element step of the selection's partition scan */
#define W_HS 85      /* heapsort: one sift call (fixed part) */
#define W_HSL 41     /* heapsort: one level of a sift */
#define W_PAIR 60    /* one pair distance of the pair scale */
#define W_GATHER 50  /* robust centre: one point of a median's gather pass (sqrt in the radius pass) */
#define W_KEY 91     /* thinning: one point's cell key */
#define W_CAP 30     /* thinning: one point of the occupancy / marking / max-run passes */
#define W_ANGLE 217  /* eps' rule: one point's radius and atan2f */
#define W_LINK 780 /* eps' rule: the link and core requirement of one band point (18 sqrt) */
#define W_SECTOR 42  /* eps' rule: one point's sector */
#define W_INIT 23    /* ordering start: one point */
#define W_SKIP 41    /* ordering: one processed point skipped by the outer scan */
#define W_PSTART 1080 /* ordering: mark, neighbour query, core and extraction of one point */
#define W_CAND 54 /* ordering: one candidate of the core-distance pass */
#define W_REACH 58 /* ordering: one candidate of the reach pass */
#define W_UPD 56     /* ordering: one reach decrease (seed insert / decrease-key adds W_HEAP) */
#define W_HEAP 144   /* ordering, CLASSIC: one heap pop or sift-up (log2 n levels) */
#define W_POP 25      /* ordering, IMPROVED: one seed of the minimum scan */
#define W_OUT 16      /* filter output: one point of the mask */
#define W_QUERY 720   /* ordering: the neighbour query again when a step resumes inside a scan */
#define W_PHASE 430   /* fixed cost of a phase switch */

/* Charging a visit: r -= weight. With MAGCAL_OPTICS_SLICE_PROFILE (tools/bench_optics only, never
 * in a shipped build) every charge is also counted per weight, so the bench can fit the weights
 * to measured instruction counts. */
#ifdef MAGCAL_OPTICS_SLICE_PROFILE
enum { P_W_FIN, P_W_SEL, P_W_HS, P_W_HSL, P_W_PAIR, P_W_GATHER, P_W_KEY, P_W_CAP, P_W_ANGLE, P_W_LINK, P_W_SECTOR, P_W_INIT, P_W_SKIP, P_W_PSTART, P_W_CAND, P_W_REACH, P_W_UPD, P_W_HEAP, P_W_POP, P_W_OUT, P_W_QUERY, P_W_PHASE, P_N_WEIGHTS };
extern unsigned long magcal_optics_slice_prof[P_N_WEIGHTS + 16]; /* optics.c */
/* cppcheck-suppress misra-c2012-20.10 ; bench-only profile build (MAGCAL_OPTICS_SLICE_PROFILE): the counter index from the weight name */
#define CHARGE_K(r, w, k)                                                                          \
    ((r) -= (int32_t)(w) * (int32_t)(k), magcal_optics_slice_prof[P_##w] += (unsigned long)(k))
/* cppcheck-suppress misra-c2012-20.10 ; bench-only profile build (MAGCAL_OPTICS_SLICE_PROFILE): the counter index from the weight name */
#define CHARGE(r, w) ((r) -= (int32_t)(w), magcal_optics_slice_prof[P_##w]++)
#else
#define CHARGE_K(r, w, k) ((r) -= (int32_t)(w) * (int32_t)(k))
#define CHARGE(r, w) ((r) -= (int32_t)(w))
#endif

#define SLICE_MAGIC 0x4F505453u /* "OPTS": a begun slice */
#define SLICE_REM_MAX 0x7FFFFFFF /* budget of a one-shot call (int32 remaining count) */
#define SLICE_ONESHOT_ROUNDS 4096u /* bound of the one-shot loop (each round charges 2^31) */

/* The rule's constants (optics.h "Automatic parameters"). */
#define AUTO_MIN_N 16u
#define AUTO_MIN_PTS 4u
#define AUTO_BAND 0.5f   /* ring band: | |p-c| - R | <= 0.5 R */
#define AUTO_SAFETY 1.5f /* eps' = 1.5 * measured requirement */
#define AUTO_CORE_Q 0.9f /* quantile of the per-point core requirement */
#define AUTO_WIN 4u      /* angular neighbours looked at on each side */
#define AUTO_TRIM 3.0f   /* centre passes after the first use points within 3 R */
#define AUTO_TRIM_PASSES 2u
#define AUTO_MIN_REL (1.0f / 256.0f)
#define AUTO_MAX_REL 1.0f
#define AUTO_PAIRS 256u               /* pairs of the clump-proof scale */
#define AUTO_SEED 0x9E3779B9u         /* their fixed pseudo-random seed */
#define AUTO_THIN_PAIR (1.0f / 32.0f) /* first thinning cell: pair scale / 32 (about R / 23) */
#define AUTO_THIN_REL (1.0f / 16.0f)  /* later cells: R / 16 */
#define AUTO_THIN_ROUNDS 2u
#define AUTO_THIN_N 400u     /* above 400 samples the cells shrink like 1/n */
#define AUTO_CELL_HALF 2048u /* cell coordinates clamped to +-2048: exact float keys */
#define THIN_INVALID (4.0f * (float)AUTO_CELL_HALF * (float)AUTO_CELL_HALF) /* key of a non-candidate */
#define AUTO_CLUMP_RATIO 8u  /* a clump: a cell holding more than 8 x the mean cell count */
/* Layout of the automatic rule's workspace: a float[n] | idx uint16[n] | b float[n] (4-byte
 * aligned) | rep uint8[n]: at most 11 n + 3 bytes, inside MAGCAL_OPTICS_FILTER_WORKSPACE_LEN and
 * below the slice state (which follows the run workspace's MinPts buffer). */
#define AUTO_B_OFF(n) ((6u * (size_t)(n) + 3u) & ~(size_t)3u)
#define AUTO_REP_OFF(n) (AUTO_B_OFF(n) + 4u * (size_t)(n))
#define AUTO_REP 1u      /* thinning flags: representative of its cell */
#define AUTO_CAPPED 2u   /* among the first K (mean occupancy) of its cell */
#define AUTO_SECTORS 64u /* angular sectors of the ring selection */
#define AUTO_PI 3.14159265f

/* ---- 2. resumable primitives (optics_prims.c) ---------------------------------------------- */

/* Hoare selection of the k-th smallest of a[0..n) (iterative, a permuted), resumable per
 * element step of the partition scans. */
typedef struct {
    float pivot;
    uint16_t lo;
    uint16_t hi;
    uint16_t i;
    uint16_t j;
    uint16_t k;
    uint8_t st; /* 0: next partition, 1: scan i, 2: scan j, 3: done */
} magcal_o2_sel_t;

static inline void magcal_o2_sel_begin(magcal_o2_sel_t *q, size_t n, size_t k)
{
    q->lo = 0u;
    q->hi = (uint16_t)(n - 1u);
    q->k = (uint16_t)k;
    q->i = 0u;
    q->j = 0u;
    q->pivot = 0.0f;
    q->st = 0u;
}

/* Returns 1 when a[k] is the k-th smallest, 0 when *rem ran out (call again). */
int magcal_o2_sel_run(magcal_o2_sel_t *q, float *a, int32_t *rem);

/* Resumable heapsort: one sift per visit. */
typedef struct {
    uint16_t k;
    uint16_t m;
    uint8_t st; /* 0: heap build, 1: extraction, 2: done */
} magcal_o2_hsort_t;

static inline void magcal_o2_hsort_begin(magcal_o2_hsort_t *h, size_t m)
{
    h->m = (uint16_t)m;
    h->k = (uint16_t)(m / 2u);
    h->st = m < 2u ? 2u : 0u;
}

/* One sift per visit; returns 1 when idx[0..m) is sorted, 0 when *rem ran out (call again). */
int magcal_o2_hsort_run(magcal_o2_hsort_t *h, uint16_t *idx, const float *key, int32_t *rem);

static inline float magcal_o2_dist(const magcal_vec2_t *a, const magcal_vec2_t *b)
{
    float dx = a->x - b->x;
    float dy = a->y - b->y;
    return sqrtf(dx * dx + dy * dy);
}

/*
 * Cell side factor of the thinning for n samples: 1 up to AUTO_THIN_N, then AUTO_THIN_N / n, so
 * a ring keeps about n / 4 or more representatives (2 pi R / h cells along it) and sparse
 * outliers (one representative each, e.g. 6 % scattered samples at n = 4096) stay a minority.
 */
static inline float magcal_o2_thin_scale(size_t n)
{
    return n > AUTO_THIN_N ? (float)AUTO_THIN_N / (float)n : 1.0f;
}

/* ---- 3. the sub-machines' states ------------------------------------------------------------ */

/* Robust centre and radius (optics.h rule step 1) over the counted points: coordinate medians,
 * R = median |p - c|; passes 1..AUTO_TRIM_PASSES use only the points within AUTO_TRIM * R of the
 * previous centre, so a far cluster (e.g. 23 % driver glitches 36 R away) cannot drag the centre
 * off the ring. Resumable per gathered point and per selection step. */
typedef struct {
    float cx;
    float cy;
    float rad;
    float lim2;
    float med[3];
    magcal_o2_sel_t sel;
    uint16_t i;
    uint16_t k;
    uint8_t pass;
    uint8_t q;
    uint8_t st; /* RC_* */
} magcal_o2_rc_t;

#define RC_PASS 0u
#define RC_GATHER 1u
#define RC_SELECT 2u
#define RC_AFTER 3u
#define RC_FINAL 4u

/*
 * Thinning: one representative (the lowest index) per square cell of side h around c, so a
 * clump of near-identical samples (a vehicle parked at one heading) counts as one sample in the
 * centre and in the core-distance quantile. Cell coordinates are clamped to +-AUTO_CELL_HALF
 * (far points share the border cells); the cell number is exact in a float key. key: float[n],
 * idx: uint16[n]; rep[i] |= AUTO_REP for the representatives (count m), AUTO_CAPPED for the first
 * K = mean occupancy ceil(candidates / occupied cells) of each cell (cap): the core quantile
 * keeps at most K samples per cell, so a clump is cut to K while the ring keeps its weight.
 * Then (magcal_optics_thin only) the largest cell's count (best). Resumable per point.
 */
typedef struct {
    magcal_o2_hsort_t hs;
    float h;
    uint16_t i;
    uint16_t m;
    uint16_t cells;
    uint16_t cap;
    uint16_t run;
    uint16_t best;
    uint8_t st; /* TH_* */
} magcal_o2_th_t;

#define TH_KEYS 0u
#define TH_SORT 1u
#define TH_CAP 2u
#define TH_MARK 3u
#define TH_MAXRUN 4u
#define TH_DONE 5u

/* Start a thinning with cell side h (inline: the driver's frame stays as it was in one file). */
static inline void magcal_o2_th_begin(magcal_o2_th_t *t, float h)
{
    (void)memset(t, 0, sizeof *t);
    t->h = h;
    t->st = (uint8_t)TH_KEYS;
}
/* Returns 1 when done up to stage `last` (TH_MARK or TH_MAXRUN), 0 when the budget ran out. */
int magcal_o2_th_run(magcal_o2_th_t *t, const magcal_vec2_t *pts, size_t n, const float cr[3],
                     uint8_t *w, const uint8_t *use, unsigned last, int32_t *rem);

/*
 * Step 1 of the rule: centre and radius of the ring, each clump of near-identical samples counted
 * once: cells of a fraction of the pair scale S first (S = median distance of AUTO_PAIRS
 * pseudo-random pairs: a pair lies inside one clump with probability f^2 for a clump of a
 * fraction f of the samples, so up to f = 0.7 S is a distance across the ring), then of the
 * radius found. w as the rule's layout (a, idx, rep). Resumable.
 */
typedef struct {
    /* cppcheck-suppress misra-c2012-19.2 ; deviation D12: the slice state overlays the sub-machines that are never live together, so it fits the workspace budget */
    union {
        magcal_o2_sel_t sel;
        magcal_o2_rc_t rc;
        magcal_o2_th_t th;
    /* cppcheck-suppress misra-c2012-19.2 ; deviation D12: the slice state overlays the sub-machines that are never live together, so it fits the workspace budget */
    } u;
    float h;
    uint32_t rng;
    uint16_t k;
    uint8_t round;
    uint8_t have;
    uint8_t st; /* CE_* */
} magcal_o2_ce_t;

#define CE_PAIRS 0u
#define CE_PAIR_SEL 1u
#define CE_RC0 2u
#define CE_THIN 3u
#define CE_RC 4u
#define CE_DONE 5u

/* Start the thinned centre (inline, as magcal_o2_th_begin). */
static inline void magcal_o2_ce_begin(magcal_o2_ce_t *c)
{
    (void)memset(c, 0, sizeof *c);
    c->rng = AUTO_SEED;
    c->st = (uint8_t)CE_PAIRS;
}
/* Returns 1 when done (*st: MAGCAL_OK with cr = {cx, cy, R}, or MAGCAL_ERR_DEGENERATE), else 0. */
int magcal_o2_ce_run(magcal_o2_ce_t *c, const magcal_vec2_t *pts, size_t n, uint8_t *w,
                     float cr[3], magcal_status_t *st, int32_t *rem);

/*
 * Steps 2-4 of the rule of optics.h around the centre and radius cr (magcal_o2_ce_run; rep[] of
 * w still marks its representatives) and, for the filter, each point's angular sector around the
 * centre (0..AUTO_SECTORS-1 in the ring band, -1 outside; overlaying idx) for the ring selection.
 */
typedef struct {
    /* cppcheck-suppress misra-c2012-19.2 ; deviation D12: the slice state overlays the sub-machines that are never live together, so it fits the workspace budget */
    union {
        magcal_o2_hsort_t hs;
        magcal_o2_sel_t sel;
    /* cppcheck-suppress misra-c2012-19.2 ; deviation D12: the slice state overlays the sub-machines that are never live together, so it fits the workspace budget */
    } u;
    float link1;
    float link2;
    uint16_t i;
    uint16_t m;
    uint16_t nq;
    uint8_t st; /* AE_* */
    /* 1 (the filter): also each point's sector, int16 at w + 4 n, overlaying idx. A flag, not a
     * pointer argument: with eight arguments the driver's frame stays 64 B (deepest stack path) */
    uint8_t sectors;
} magcal_o2_ae_t;

#define AE_ANGLES 0u
#define AE_SORT 1u
#define AE_LINKS 2u
#define AE_SEL 3u
#define AE_SECTORS 4u
#define AE_DONE 5u

/* Returns 1 when done (*st: MAGCAL_OK with *eps_prime, or MAGCAL_ERR_DEGENERATE), else 0
 * (optics_params.c). */
int magcal_o2_ae_run(magcal_o2_ae_t *e, const magcal_vec2_t *pts, size_t n, uint8_t *w,
                     const float cr[3], float *eps_prime, magcal_status_t *st, int32_t *rem);

/*
 * The ordering loop (algorithms.md 4.1-4.2) with on-the-fly ExtractDBSCAN, resumable per
 * candidate of every neighbour scan, per seed of the IMPROVED minimum scan and per point of the
 * outer scan. Each PROCESS(p): pass 1 over the candidates = core distance (MinPts-th smallest
 * d^2, p itself included, in the sorted insertion buffer `best`); then the extraction step;
 * then pass 2 = reach updates of the unprocessed neighbours (grid), or for brute force the pass
 * over the compact list of unprocessed points (the point processed last is dropped as it is met,
 * so the k-th pass costs n - k instead of n). The candidate ranges are recomputed from p when a
 * step resumes inside a scan (cheaper than keeping them).
 */
typedef struct {
    float core_p;
    float pbr;       /* minimum scan: best reach so far */
    uint16_t s;      /* outer scan position (also the start loop's index) */
    uint16_t p;      /* point being processed */
    uint16_t k;      /* candidate position in range ri / live list position */
    uint16_t cnt;    /* MinPts buffer count (or the start-core count) */
    uint16_t n_live; /* brute force: unprocessed points in the live list (nb.idx) */
    uint16_t lw;     /* live pass write position */
    uint16_t pk;     /* minimum scan position, best slot and point */
    uint16_t pbest;
    uint16_t pbq;
    uint8_t ri;
    uint8_t pass; /* 0 (START_CORE only): runs start at core points; 1: at any point */
    uint8_t use_live;
} magcal_o2_ord_scan_t;

typedef struct {
    magcal_ocore_t oc;
    magcal_nbr_t nb;
    float eps2;
    /* cppcheck-suppress misra-c2012-19.2 ; deviation D12: the slice state overlays the sub-machines that are never live together, so it fits the workspace budget */
    union { /* the build's state is dead once the scans begin */
        magcal_nbr_build_t nbb;
        magcal_o2_ord_scan_t sc;
    /* cppcheck-suppress misra-c2012-19.2 ; deviation D12: the slice state overlays the sub-machines that are never live together, so it fits the workspace budget */
    } u;
    uint8_t st; /* OR_* */
} magcal_o2_ord_t;

#define OR_BUILD 0u
#define OR_INIT 1u
#define OR_LIVE 2u
#define OR_START 3u
#define OR_SCAN 4u
#define OR_ISCORE 5u
#define OR_P1 6u
#define OR_P2 7u
#define OR_PLIVE 8u
#define OR_SEEDS 9u
#define OR_POP 10u
#define OR_DONE 11u

/* Returns 1 when the ordering (and the extraction) is complete, 0 when the budget ran out
 * (optics_order.c). */
int magcal_o2_ord_run(magcal_o2_ord_t *o, int32_t *rem);

#endif /* MAGCAL_OPTICS_SLICE_H */
