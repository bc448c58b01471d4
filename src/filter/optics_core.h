/*
 * Internal, dimension-free part of the OPTICS ordering loop (algorithms.md 4.2, 4.3) shared by
 * the 2-D stage (optics_order.c and the files of optics_slice.h) and optics3.c (3-D). Not
 * installed. Only the coordinates and the neighbour search differ between the dimensions;
 * everything that looks at reach values, seeds and the processed bits lives here, once.
 *
 * The loop's functions are defined here, not once with external linkage in a .c file, so each
 * ordering loop compiles them as it did when they were its own static helpers: same inlining,
 * same stack frames (tools/stack/stack_usage.py) and host instruction counts (callgrind,
 * magcal_bench). Only the cold helpers (cfg check: optics.c; median selection and heapsort:
 * optics_prims.c) are one extern copy.
 * All are `static inline` (MISRA 5.9 exempts an inline function defined once in a shared
 * header), so any file of the stage may include this header; the two plain `static` ones of the
 * reach decrease are optics_core_update.h, included by the two ordering loops only.
 */
#ifndef MAGCAL_OPTICS_CORE_H
#define MAGCAL_OPTICS_CORE_H

#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "magcal/optics.h"

#define MAGCAL_OCORE_POS_NONE 0xFFFFu

/* The classic ordering (binary heap with decrease-key, algorithms.md 4.2): compiled in unless the
 * firmware's config sets 0 (include/magcal/config.h); without it, asking for
 * MAGCAL_OPTICS_CLASSIC returns MAGCAL_ERR_ARG (magcal_ocore_check_cfg) in 2-D and 3-D. */
#ifndef MAGCAL_CFG_ENABLE_OPTICS_CLASSIC
#define MAGCAL_CFG_ENABLE_OPTICS_CLASSIC 1
#endif

#ifdef MAGCAL_OPTICS_BENCH_SORTED_LIST
/*
 * Bench-only third seed-list organisation (tools/bench: magcal_bench_sorted, never in a shipped
 * build): the source paper's classic OPTICS, whose ordered queue is re-sorted by reachability
 * whenever it changed before the next point is taken (heapsort of the whole list, O(q log q)),
 * the first element popped. Same (reach, index) key, so its outputs are bit-identical to the two
 * library modes; it exists to reproduce the paper's Table 2 (docs/performance.md).
 */
/* cppcheck-suppress misra-c2012-2.5 ; used only in the bench build (MAGCAL_OPTICS_BENCH_SORTED_LIST) */
#define MAGCAL_OPTICS_SORTED_LIST_ ((magcal_optics_order_t)2)
#endif

/* Dimension-free state of one ordering run; optional outputs are NULL when not wanted. */
typedef struct {
    float *reach;    /* n, working reach (final when a point is processed) */
    uint16_t *seeds; /* heap (CLASSIC) or unordered list (IMPROVED) */
    uint16_t *pos;   /* CLASSIC: heap position of each point or MAGCAL_OCORE_POS_NONE */
    uint8_t *done;   /* processed bits */
    float *best;     /* MinPts insertion buffer (workspace, keeps process() frames small) */
    size_t n_seeds;
    size_t n_done;
    uint16_t *order; /* optional outputs */
    float *core;
    uint16_t *pred;
    /* on-the-fly ExtractDBSCAN (filter) */
    int16_t *labels;
    float eps_prime;
    int32_t id;
    size_t cur_count;
    size_t best_count;
    size_t n_noise;
    /* ring selection (automatic filter): labels[p] holds p's angular sector (0..63, -1 outside
     * the band) until p is labelled; the kept cluster is the one of most sectors, then count */
    uint32_t sec_cur[2];
    uint32_t best_ext;
    int use_sectors;
    int core_start; /* MAGCAL_OPTICS_START_CORE */
#ifdef MAGCAL_OPTICS_BENCH_SORTED_LIST
    size_t head; /* sorted list: the list is seeds[head .. head + n_seeds) */
    int dirty;   /* sorted list: changed since the last sort */
#endif
    int32_t best_id; /* extraction's kept cluster: here, not after cur_count, so no 64-bit padding */
    magcal_optics_order_t mode;
    uint16_t min_pts;
} magcal_ocore_t;

/* Heapsort of idx[0..m-1] by key[idx] ascending, ties by index (iterative). Defined in
 * optics_prims.c (the thinning of both dimensions' automatic parameters, the bench's sorted-list
 * mode). */
void magcal_ocore_sort_idx(uint16_t *idx, const float *key, size_t m);

/* Number of set bits of v (at most 32 rounds: one bit cleared per round). */
static inline uint32_t magcal_ocore_popcount(uint32_t v)
{
    uint32_t x = v;
    uint32_t c = 0u;
    while (x != 0u) {
        x &= x - 1u;
        ++c;
    }
    return c;
}

/* Close the cluster being extracted: it becomes the kept one when it spans more sectors (ring
 * selection) or, at equal extent (always equal without ring selection), holds more points;
 * strict, so ties keep the smaller id. */
static inline void magcal_ocore_close(magcal_ocore_t *o)
{
    uint32_t ext = 0u;
    if (o->id < 0) {
        return;
    }
    if (o->use_sectors != 0) {
        ext = magcal_ocore_popcount(o->sec_cur[0]) + magcal_ocore_popcount(o->sec_cur[1]);
    }
    if (ext > o->best_ext || (ext == o->best_ext && o->cur_count > o->best_count)) {
        o->best_ext = ext;
        o->best_count = o->cur_count;
        o->best_id = o->id;
    }
}

/* Deterministic pseudo-random stream (xorshift32, state != 0) for the pair sample of the
 * automatic parameters: the same data always give the same parameters. */
static inline uint32_t magcal_ocore_rand(uint32_t *state)
{
    uint32_t x = *state;
    x ^= x << 13;
    x ^= x >> 17;
    x ^= x << 5;
    *state = x;
    return x;
}

static inline int magcal_ocore_is_done(const magcal_ocore_t *o, size_t i)
{
    const unsigned bit = ((unsigned)o->done[i >> 3] >> (unsigned)(i & 7u)) & 1u;
    int r = 0;
    if (bit != 0u) {
        r = 1;
    }
    return r;
}

/* (reach, index) lexicographic order: the tie rule that makes every variant identical. */
static inline int magcal_ocore_key_less(const float *reach, uint16_t a, uint16_t b)
{
    const float ra = reach[a];
    const float rb = reach[b];
    return ra < rb || (ra == rb && a < b);
}

#if MAGCAL_CFG_ENABLE_OPTICS_CLASSIC
static inline void magcal_ocore_sift_down(magcal_ocore_t *o, size_t k0)
{
    size_t k = k0;
    uint16_t v = o->seeds[k];
    size_t m = o->n_seeds;
    while (2u * k + 1u < m) { /* k at least doubles: <= log2(m) rounds */
        size_t child = 2u * k + 1u;
        uint16_t cv = o->seeds[child];
        if (child + 1u < m && magcal_ocore_key_less(o->reach, o->seeds[child + 1u], cv)) {
            ++child;
            cv = o->seeds[child];
        }
        if (!magcal_ocore_key_less(o->reach, cv, v)) {
            break;
        }
        o->seeds[k] = cv;
        o->pos[cv] = (uint16_t)k;
        k = child;
    }
    o->seeds[k] = v;
    o->pos[v] = (uint16_t)k;
}
#endif /* MAGCAL_CFG_ENABLE_OPTICS_CLASSIC */

/* Remove and return the seed of least (reach, index): heap root (CLASSIC) or a linear scan of the
 * unordered list (IMPROVED). n_seeds > 0. */
static inline uint16_t magcal_ocore_pop_min(magcal_ocore_t *o)
{
    uint16_t q;
#if MAGCAL_CFG_ENABLE_OPTICS_CLASSIC
    if (o->mode == MAGCAL_OPTICS_CLASSIC) {
        q = o->seeds[0];
        o->n_seeds--;
        o->pos[q] = MAGCAL_OCORE_POS_NONE;
        if (o->n_seeds > 0u) {
            o->seeds[0] = o->seeds[o->n_seeds];
            magcal_ocore_sift_down(o, 0u);
        }
    } else
#endif
#ifdef MAGCAL_OPTICS_BENCH_SORTED_LIST
    if (o->mode == MAGCAL_OPTICS_SORTED_LIST_) {
        if (o->dirty != 0) {
            magcal_ocore_sort_idx(o->seeds + o->head, o->reach, o->n_seeds);
            o->dirty = 0;
        }
        q = o->seeds[o->head];
        o->head++;
        o->n_seeds--;
    } else
#endif
    {
        size_t k;
        size_t best = 0u;
        const float *reach = o->reach;
        uint16_t bq = o->seeds[0];
        float br = reach[bq];
        for (k = 1u; k < o->n_seeds; ++k) {
            uint16_t s = o->seeds[k];
            float r = reach[s];
            if (r < br || (r == br && s < bq)) {
                br = r;
                bq = s;
                best = k;
            }
        }
        q = bq;
        o->n_seeds--;
        o->seeds[best] = o->seeds[o->n_seeds];
    }
    return q;
}

/* ExtractDBSCAN step for the point just processed (same rule as magcal_optics_extract_dbscan). */
static inline void magcal_ocore_extract_step(magcal_ocore_t *o, size_t p, float core_p)
{
    int16_t lab;
    int16_t sec = -1;
    if (o->use_sectors != 0) {
        sec = o->labels[p];
    }
    if (o->reach[p] > o->eps_prime) {
        if (core_p <= o->eps_prime) {
            magcal_ocore_close(o);
            o->id++;
            o->cur_count = 1u;
            o->sec_cur[0] = 0u;
            o->sec_cur[1] = 0u;
            lab = (int16_t)o->id;
        } else {
            lab = MAGCAL_OPTICS_NOISE;
            o->n_noise++;
        }
    } else {
        lab = (int16_t)o->id;
        if (o->id >= 0) {
            o->cur_count++;
        } else {
            o->n_noise++; /* unreachable in practice: the first point has reach = inf */
        }
    }
    if (sec >= 0 && lab >= 0) {
        const unsigned sb = (unsigned)sec;
        o->sec_cur[sb >> 5] |= 1u << (sb & 31u);
    }
    o->labels[p] = lab;
}

/*
 * r = max(core, sqrt(d2)) without the square root when d2 <= core^2 (then r = core exactly:
 * sqrtf is monotone and core = sqrtf(core2)), so most reach candidates cost no sqrt and no bit of
 * the result changes.
 */
static inline float magcal_ocore_reach_of(float d2, float core_p, float core2)
{
    return d2 <= core2 ? core_p : sqrtf(d2);
}

/* Insert d2 into the ascending MinPts buffer best[0..cnt) of capacity m (when full, the largest
 * value drops out); returns the new count. */
static inline size_t magcal_ocore_best_insert(float *best, size_t cnt, size_t m, float d2)
{
    size_t t = m - 1u;
    size_t count = cnt;
    if (count < m) {
        t = count;
        ++count;
    }
    while (t > 0u && best[t - 1u] > d2) {
        best[t] = best[t - 1u];
        --t;
    }
    best[t] = d2;
    return count;
}

/* First step of PROCESS(p): mark p processed and append it to the ordering. */
static inline void magcal_ocore_mark(magcal_ocore_t *o, size_t p)
{
    o->done[p >> 3] = (uint8_t)(o->done[p >> 3] | (1u << (p & 7u)));
    if (o->order != NULL) {
        o->order[o->n_done] = (uint16_t)p;
    }
    o->n_done++;
}

/* Start of a run over n points, in two pieces so the resumable 2-D ordering (optics_order.c)
 * can spread the per-point part over steps: every reach infinite, no
 * predecessor (magcal_ocore_start_point, once per point), then nothing in the heap, nothing
 * processed (magcal_ocore_start_finish, once). */
static inline void magcal_ocore_start_point(magcal_ocore_t *o, size_t i)
{
    o->reach[i] = INFINITY;
    if (o->pred != NULL) {
        o->pred[i] = MAGCAL_OPTICS_NO_PRED;
    }
    if (o->mode == MAGCAL_OPTICS_CLASSIC) {
        o->pos[i] = MAGCAL_OCORE_POS_NONE;
    }
}

static inline void magcal_ocore_start_finish(magcal_ocore_t *o, size_t n)
{
    (void)memset(o->done, 0, (n + 7u) / 8u);
    o->n_seeds = 0u;
    o->n_done = 0u;
#ifdef MAGCAL_OPTICS_BENCH_SORTED_LIST
    o->head = 0u;
    o->dirty = 0;
#endif
}

/* The whole start in one call (the 3-D ordering). */
static inline void magcal_ocore_start(magcal_ocore_t *o, size_t n)
{
    size_t i;
    for (i = 0; i < n; ++i) {
        magcal_ocore_start_point(o, i);
    }
    magcal_ocore_start_finish(o, n);
}

/* End of a run: the last cluster of the on-the-fly extraction competes for the largest. */
static inline void magcal_ocore_finish(magcal_ocore_t *o)
{
    if (o->labels != NULL) {
        magcal_ocore_close(o);
    }
}

/* Fill the run summary (info may be NULL): parameters used, no cluster found yet. */
static inline void magcal_ocore_fill_info(magcal_optics_result_t *info, const magcal_ocore_t *o,
                                          int use_grid, float eps, float eps_prime)
{
    if (info == NULL) {
        return;
    }
    (void)memset(info, 0, sizeof *info);
    info->eps = eps;
    info->eps_prime = eps_prime;
    info->min_pts = o->min_pts;
    info->neighbors = use_grid != 0 ? MAGCAL_NEIGHBORS_GRID : MAGCAL_NEIGHBORS_BRUTE;
    info->largest_id = MAGCAL_OPTICS_NOISE;
}

/* Result of a filter run with on-the-fly extraction over n points: inlier_mask[i] = 1 for the
 * largest cluster and the cluster counts in info (filled by magcal_ocore_fill_info first).
 * Returns MAGCAL_ERR_ALL_NOISE (mask untouched) when no cluster formed, else MAGCAL_OK. */
static inline magcal_status_t magcal_ocore_filter_out(const magcal_ocore_t *o, size_t n,
                                                      uint8_t *inlier_mask,
                                                      magcal_optics_result_t *info)
{
    size_t i;
    if (o->best_id < 0) {
        if (info != NULL) {
            info->n_noise = (uint16_t)o->n_noise;
        }
        return MAGCAL_ERR_ALL_NOISE;
    }
    for (i = 0; i < n; ++i) {
        inlier_mask[i] = (o->labels[i] == o->best_id) ? 1u : 0u;
    }
    if (info != NULL) {
        const int32_t count = o->id + 1;
        info->n_clusters = (uint16_t)count;
        info->largest_id = (int16_t)o->best_id;
        info->n_inliers = (uint16_t)o->best_count;
        info->n_noise = (uint16_t)o->n_noise;
    }
    return MAGCAL_OK;
}

/* Point count checks of every entry point: MAGCAL_ERR_ARG above MAGCAL_MAX_SAMPLES,
 * MAGCAL_ERR_TOO_FEW_POINTS below min_n, else MAGCAL_OK (finiteness is checked per dimension). */
static inline magcal_status_t magcal_ocore_check_n(size_t n, size_t min_n)
{
    magcal_status_t st = MAGCAL_OK;
    if (n > MAGCAL_MAX_SAMPLES) {
        st = MAGCAL_ERR_ARG;
    } else if (n < min_n) {
        st = MAGCAL_ERR_TOO_FEW_POINTS;
    } else {
        /* count in range */
    }
    return st;
}

/* Checks of a magcal_optics_cfg_t shared by both dimensions (eps, MinPts, order, neighbour
 * search); MAGCAL_ERR_ARG or MAGCAL_OK. Defined in optics.c (cold: once per
 * call). */
magcal_status_t magcal_ocore_check_cfg(const magcal_optics_cfg_t *cfg);

/* The entry checks of magcal_optics_run and magcal_optics_run3 (pointers, the configuration,
 * the workspace's 4-byte alignment) before each checks its own points; MAGCAL_ERR_NULL,
 * MAGCAL_ERR_ARG, MAGCAL_ERR_ALIGNMENT or MAGCAL_OK. Defined in optics.c. */
magcal_status_t magcal_ocore_check_run(const magcal_optics_cfg_t *cfg, const void *pts, const void *work,
                                       const uint16_t *order, const float *reach, const float *core);

/* k-th smallest of a[0..n-1], 0 <= k < n (a is permuted). Iterative Hoare selection, no
 * recursion. Defined in optics_prims.c (the automatic parameters of both
 * dimensions). */
float magcal_ocore_select_kth(float *a, size_t n, size_t k);

#endif
