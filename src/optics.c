/* OPTICS ordering, ExtractDBSCAN, largest cluster, automatic parameters (algorithms.md 4). */
#include "magcal/optics.h"

#include <math.h>
#include <string.h>

#include "magcal_internal.h"
#include "neighbors.h"
#include "optics_core.h"

/* Everything the ordering loop needs: the dimension-free state (optics_core.h) and the 2-D
 * points and neighbour search. */
typedef struct {
    magcal_ocore_t oc;
    const magcal_vec2_t *pts;
    size_t n;
    float eps2;
    magcal_nbr_t nb;
    uint16_t *live; /* brute force only: unprocessed points (reuses the unused grid index) */
    size_t n_live;
} optics_ctx_t;

/*
 * Brute-force pass 2 over the compact list of unprocessed points (the point processed last is
 * dropped as it is met, so the k-th pass costs n - k instead of n).
 */
static void live_pass(optics_ctx_t *c, size_t p, float core_p, float core2)
{
    const magcal_vec2_t *pts = c->pts;
    const float px = pts[p].x;
    const float py = pts[p].y;
    const float eps2 = c->eps2;
    uint16_t *live = c->live;
    size_t k;
    size_t w = 0u;
    size_t nl = c->n_live;
    for (k = 0; k < nl; ++k) {
        size_t j = live[k];
        if (j == p) {
            continue; /* the only point processed since the last pass */
        }
        live[w] = (uint16_t)j;
        ++w;
        if (core_p < INFINITY) {
            float dx = pts[j].x - px;
            float dy = pts[j].y - py;
            float d2 = dx * dx + dy * dy;
            if (d2 <= eps2) {
                float r = magcal_ocore_reach_of(d2, core_p, core2);
                if (r < c->oc.reach[j]) {
                    magcal_ocore_update(&c->oc, p, j, r);
                }
            }
        }
    }
    c->n_live = w;
}

static void process(optics_ctx_t *c, size_t p)
{
    float *best = c->oc.best;
    size_t cnt = 0u;
    size_t m = c->oc.min_pts;
    size_t ri;
    size_t k;
    const magcal_vec2_t *pts = c->pts;
    const float px = pts[p].x;
    const float py = pts[p].y;
    const float eps2 = c->eps2;
    float core_p = INFINITY;
    magcal_nbr_ranges_t rg;

    magcal_ocore_mark(&c->oc, p);

    /* Pass 1: core distance = MinPts-th smallest d^2 (p itself included, d = 0), kept in a
     * sorted insertion buffer; once it holds m values only d^2 < best[m-1] (<= eps^2) enters. */
    magcal_nbr_query(&c->nb, p, &rg);
    if (rg.idx == NULL) {
        /* brute force: plain sweep; lim = eps^2 until m values are held, then best[m-1] */
        float lim = eps2;
        size_t n = c->n;
        for (k = 0; k < n; ++k) {
            float dx = pts[k].x - px;
            float dy = pts[k].y - py;
            float d2 = dx * dx + dy * dy;
            if (d2 <= lim && (cnt < m || d2 < lim)) {
                cnt = magcal_ocore_best_insert(best, cnt, m, d2);
                if (cnt == m) {
                    lim = best[m - 1u];
                }
            }
        }
    }
    for (ri = 0; rg.idx != NULL && ri < rg.n_ranges; ++ri) {
        for (k = rg.begin[ri]; k < rg.end[ri]; ++k) {
            size_t j = rg.idx[k];
            float dx = pts[j].x - px;
            float dy = pts[j].y - py;
            float d2 = dx * dx + dy * dy;
            if (d2 <= eps2 && (cnt < m || d2 < best[m - 1u])) {
                cnt = magcal_ocore_best_insert(best, cnt, m, d2);
            }
        }
    }
    if (cnt >= m) {
        core_p = sqrtf(best[m - 1u]);
    }
    if (c->oc.core != NULL) {
        c->oc.core[p] = core_p;
    }
    if (c->oc.labels != NULL) {
        magcal_ocore_extract_step(&c->oc, p, core_p);
    }
    if (c->live != NULL) {
        live_pass(c, p, cnt >= m ? core_p : INFINITY, cnt >= m ? best[m - 1u] : INFINITY);
        return;
    }
    if (cnt < m) {
        return;
    }
    /* Pass 2 (grid): reachability updates of the unprocessed neighbours. */
    for (ri = 0; ri < rg.n_ranges; ++ri) {
        for (k = rg.begin[ri]; k < rg.end[ri]; ++k) {
            size_t j = rg.idx != NULL ? rg.idx[k] : k;
            float dx = pts[j].x - px;
            float dy = pts[j].y - py;
            float d2 = dx * dx + dy * dy;
            if (d2 <= eps2 && magcal_ocore_is_done(&c->oc, j) == 0) {
                float r = magcal_ocore_reach_of(d2, core_p, best[m - 1u]);
                if (r < c->oc.reach[j]) {
                    magcal_ocore_update(&c->oc, p, j, r);
                }
            }
        }
    }
}

/* 1 when p has >= MinPts points (itself included) within eps: the start test of START_CORE. */
static MAGCAL_NOINLINE int is_core(const optics_ctx_t *c, size_t p)
{
    const magcal_vec2_t *pts = c->pts;
    const float px = pts[p].x;
    const float py = pts[p].y;
    const size_t m = c->oc.min_pts;
    size_t cnt = 0u;
    size_t ri;
    size_t k;
    magcal_nbr_ranges_t rg;
    magcal_nbr_query(&c->nb, p, &rg);
    if (rg.idx == NULL) {
        for (k = 0; k < c->n && cnt < m; ++k) {
            const float dx = pts[k].x - px;
            const float dy = pts[k].y - py;
            cnt += (dx * dx + dy * dy <= c->eps2) ? 1u : 0u;
        }
    }
    for (ri = 0; rg.idx != NULL && ri < rg.n_ranges; ++ri) {
        for (k = rg.begin[ri]; k < rg.end[ri] && cnt < m; ++k) {
            const size_t j = rg.idx[k];
            const float dx = pts[j].x - px;
            const float dy = pts[j].y - py;
            cnt += (dx * dx + dy * dy <= c->eps2) ? 1u : 0u;
        }
    }
    return cnt >= m ? 1 : 0;
}

static void optics_loop(optics_ctx_t *c)
{
    size_t s;
    unsigned pass;
    magcal_ocore_start(&c->oc, c->n);
    if (!c->nb.use_grid) {
        size_t i;
        c->live = c->nb.idx;
        for (i = 0; i < c->n; ++i) {
            c->live[i] = (uint16_t)i;
        }
        c->n_live = c->n;
    }

    /* pass 0 (START_CORE only): runs start at unprocessed core points; pass 1: at any point */
    pass = 1u;
    if (c->oc.core_start != 0) {
        pass = 0u;
    }
    for (; pass < 2u; ++pass) {
        for (s = 0; s < c->n; ++s) {
            if (magcal_ocore_is_done(&c->oc, s) != 0 || (pass == 0u && is_core(c, s) == 0)) {
                continue;
            }
            process(c, s);
            while (c->oc.n_seeds > 0u) {
                process(c, magcal_ocore_pop_min(&c->oc));
            }
        }
    }
    magcal_ocore_finish(&c->oc);
}

static magcal_status_t check_points(const magcal_vec2_t *pts, size_t n, size_t min_n)
{
    const magcal_status_t st = magcal_ocore_check_n(n, min_n);
    if (st != MAGCAL_OK) {
        return st;
    }
    return magcal_nbr_check_finite(pts, n);
}

magcal_status_t magcal_ocore_check_cfg(const magcal_optics_cfg_t *cfg)
{
    /* eps^2 is the neighbour threshold: it must be a normal float (neighbors.h) */
    if (magcal_nbr_eps_ok(cfg->eps) == 0) {
        return MAGCAL_ERR_ARG;
    }
    if (cfg->min_pts < 2u || cfg->min_pts > MAGCAL_MAX_MIN_PTS) {
        return MAGCAL_ERR_ARG;
    }
    if (cfg->order != MAGCAL_OPTICS_CLASSIC && cfg->order != MAGCAL_OPTICS_IMPROVED
#ifdef MAGCAL_OPTICS_BENCH_SORTED_LIST
        && cfg->order != MAGCAL_OPTICS_SORTED_LIST_
#endif
    ) {
        return MAGCAL_ERR_ARG;
    }
    if (cfg->neighbors != MAGCAL_NEIGHBORS_BRUTE && cfg->neighbors != MAGCAL_NEIGHBORS_GRID) {
        return MAGCAL_ERR_ARG;
    }
    if (cfg->start != MAGCAL_OPTICS_START_INDEX && cfg->start != MAGCAL_OPTICS_START_CORE) {
        return MAGCAL_ERR_ARG;
    }
    return MAGCAL_OK;
}

/* Carve the run workspace (uint16 seeds, pos, neighbour index, done bits) and build the index. */
/* The context lives in the workspace (MAGCAL_OPTICS_CTX_LEN_ bytes after the MinPts buffer),
 * aligned for pointers: the ordering loop is on the deepest stack path of the 2-D pipeline. */
/* cppcheck-suppress misra-c2012-2.3 ; deviation D4: a static assert is an unused typedef */
MAGCAL_STATIC_ASSERT(sizeof(optics_ctx_t) + sizeof(void *) - 4u <= MAGCAL_OPTICS_CTX_LEN_,
                     optics_ctx_fits_workspace);

static optics_ctx_t *ctx_setup(const magcal_optics_cfg_t *cfg, const magcal_vec2_t *pts, size_t n,
                               uint8_t *w, const float *window)
{
    uint8_t *cw = w + MAGCAL_OPTICS_BEST_OFFSET_(n) + 4u * (size_t)MAGCAL_MAX_MIN_PTS;
    optics_ctx_t *c;
    cw += (sizeof(void *) - magcal_misalign(cw, sizeof(void *))) % sizeof(void *);
    c = (optics_ctx_t *)(void *)cw;
    (void)memset(c, 0, sizeof *c);
    c->pts = pts;
    c->n = n;
    c->eps2 = cfg->eps * cfg->eps;
    c->oc.min_pts = cfg->min_pts;
    c->oc.mode = cfg->order;
    c->oc.core_start = 0;
    if (cfg->start == MAGCAL_OPTICS_START_CORE) {
        c->oc.core_start = 1;
    }
    c->oc.seeds = (uint16_t *)(void *)w;
    c->oc.pos = c->oc.seeds + n;
    c->oc.done = w + 4u * n + MAGCAL_NEIGHBORS_WORKSPACE_LEN(n);
    c->oc.best = (float *)(void *)(w + MAGCAL_OPTICS_BEST_OFFSET_(n));
    c->oc.id = -1;
    c->oc.best_id = -1;
    magcal_nbr_build(&c->nb, pts, n, cfg->eps, cfg->neighbors, w + 4u * n, window);
    return c;
}

magcal_status_t magcal_optics_run(const magcal_optics_cfg_t *cfg, const magcal_vec2_t *pts,
                                  size_t n, void *work, size_t work_len, uint16_t *order,
                                  float *reach, float *core, uint16_t *pred,
                                  magcal_optics_result_t *info)
{
    optics_ctx_t *c;
    magcal_status_t st;
    if (cfg == NULL || pts == NULL || work == NULL || order == NULL || reach == NULL ||
        core == NULL) {
        return MAGCAL_ERR_NULL;
    }
    st = magcal_ocore_check_cfg(cfg);
    if (st != MAGCAL_OK) {
        return st;
    }
    if (magcal_misalign(work, 4u) != 0u) {
        return MAGCAL_ERR_ALIGNMENT;
    }
    st = check_points(pts, n, cfg->min_pts);
    if (st != MAGCAL_OK) {
        return st;
    }
    if (work_len < MAGCAL_OPTICS_WORKSPACE_LEN(n)) {
        return MAGCAL_ERR_WORKSPACE;
    }
    c = ctx_setup(cfg, pts, n, (uint8_t *)work, NULL);
    c->oc.reach = reach;
    c->oc.order = order;
    c->oc.core = core;
    c->oc.pred = pred;
    optics_loop(c);
    magcal_ocore_fill_info(info, &c->oc, c->nb.use_grid, cfg->eps, cfg->eps);
    return MAGCAL_OK;
}

magcal_status_t magcal_optics_extract_dbscan(const uint16_t *order, const float *reach,
                                             const float *core, size_t n, float eps,
                                             float eps_prime, int16_t *labels, uint16_t *n_clusters)
{
    size_t k;
    int32_t id = -1;
    if (order == NULL || reach == NULL || core == NULL || labels == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (n == 0u || n > MAGCAL_MAX_SAMPLES || !(eps > 0.0f) || !(eps_prime >= 0.0f) ||
        !magcal_isfinite_f(eps_prime) || eps_prime > eps) {
        return MAGCAL_ERR_ARG;
    }
    for (k = 0; k < n; ++k) {
        if (order[k] >= n) {
            return MAGCAL_ERR_ARG;
        }
    }
    for (k = 0; k < n; ++k) {
        size_t p = order[k];
        if (reach[p] > eps_prime) {
            if (core[p] <= eps_prime) {
                ++id;
                labels[p] = (int16_t)id;
            } else {
                labels[p] = MAGCAL_OPTICS_NOISE;
            }
        } else {
            labels[p] = (int16_t)id;
        }
    }
    if (n_clusters != NULL) {
        const int32_t count = id + 1;
        *n_clusters = (uint16_t)count;
    }
    return MAGCAL_OK;
}

magcal_status_t magcal_optics_largest_cluster(const int16_t *labels, size_t n, void *work,
                                              size_t work_len, uint8_t *inlier_mask,
                                              int16_t *cluster_id, uint16_t *count)
{
    uint16_t *cnt;
    size_t i;
    size_t best_count = 0u;
    int32_t best = -1;
    int32_t max_id = -1;
    if (labels == NULL || work == NULL || inlier_mask == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (n == 0u || n > MAGCAL_MAX_SAMPLES) {
        return MAGCAL_ERR_ARG;
    }
    if (magcal_misalign(work, 2u) != 0u) {
        return MAGCAL_ERR_ALIGNMENT;
    }
    if (work_len < MAGCAL_OPTICS_LARGEST_WORKSPACE_LEN(n)) {
        return MAGCAL_ERR_WORKSPACE;
    }
    for (i = 0; i < n; ++i) {
        if (labels[i] < -1 || (labels[i] >= 0 && (size_t)labels[i] >= n)) {
            return MAGCAL_ERR_ARG;
        }
        max_id = labels[i] > max_id ? labels[i] : max_id;
    }
    if (max_id < 0) {
        return MAGCAL_ERR_ALL_NOISE;
    }
    cnt = (uint16_t *)work;
    (void)memset(cnt, 0, ((size_t)max_id + 1u) * sizeof *cnt);
    for (i = 0; i < n; ++i) {
        if (labels[i] >= 0) {
            cnt[labels[i]]++;
        }
    }
    for (i = 0; i <= (size_t)max_id; ++i) {
        if (cnt[i] > best_count) { /* strict: ties keep the smaller id */
            best_count = cnt[i];
            best = (int32_t)i;
        }
    }
    for (i = 0; i < n; ++i) {
        inlier_mask[i] = (labels[i] == best) ? 1u : 0u;
    }
    if (cluster_id != NULL) {
        *cluster_id = (int16_t)best;
    }
    if (count != NULL) {
        *count = (uint16_t)best_count;
    }
    return MAGCAL_OK;
}

/* ---- automatic parameters ---------------------------------------------------------------- */

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
 * aligned) | rep uint8[n]: at most 11 n + 3 bytes, inside MAGCAL_OPTICS_FILTER_WORKSPACE_LEN. */
#define AUTO_B_OFF(n) ((6u * (size_t)(n) + 3u) & ~(size_t)3u)
#define AUTO_REP_OFF(n) (AUTO_B_OFF(n) + 4u * (size_t)(n))
#define AUTO_REP 1u      /* thinning flags: representative of its cell */
#define AUTO_CAPPED 2u   /* among the first K (mean occupancy) of its cell */
#define AUTO_SECTORS 64u /* angular sectors of the ring selection */
#define AUTO_PI 3.14159265f

/* (declared in optics_core.h: the 3-D automatic parameters use it too) */
float magcal_ocore_select_kth(float *a, size_t n, size_t k)
{
    size_t lo = 0u;
    size_t hi = n - 1u;
    while (lo < hi) {
        float pivot = a[lo + (hi - lo) / 2u];
        size_t i = lo;
        size_t j = hi;
        size_t guard;
        for (guard = lo; guard <= hi; ++guard) { /* i grows by >= 1 per round: <= hi-lo+1 rounds */
            float t;
            while (a[i] < pivot) {
                ++i;
            }
            while (a[j] > pivot) {
                --j;
            }
            if (i >= j) {
                break;
            }
            t = a[i];
            a[i] = a[j];
            a[j] = t;
            ++i;
            --j;
        }
        /* now a[lo..j] <= pivot <= a[j+1..hi] (Hoare partition, j in [lo, hi-1]) */
        if (k <= j) {
            hi = j;
        } else {
            lo = j + 1u;
        }
    }
    return a[k];
}

/* Heapsort idx[0..m-1] by key[idx] ascending, ties by index (iterative sift). */
static int sort_less(const float *key, uint16_t a, uint16_t b)
{
    const float ka = key[a];
    const float kb = key[b];
    return ka < kb || (ka == kb && a < b);
}

static void sort_sift(uint16_t *idx, const float *key, size_t k0, size_t m)
{
    size_t k = k0;
    uint16_t v = idx[k];
    while (2u * k + 1u < m) {
        size_t child = 2u * k + 1u;
        if (child + 1u < m && sort_less(key, idx[child], idx[child + 1u])) {
            ++child;
        }
        if (!sort_less(key, v, idx[child])) {
            break;
        }
        idx[k] = idx[child];
        k = child;
    }
    idx[k] = v;
}

/* (declared in optics_core.h: the 3-D thinning and the bench's sorted list use it too) */
void magcal_ocore_sort_idx(uint16_t *idx, const float *key, size_t m)
{
    size_t k;
    if (m < 2u) {
        return;
    }
    for (k = m / 2u; k > 0u; --k) {
        sort_sift(idx, key, k - 1u, m);
    }
    for (k = m - 1u; k > 0u; --k) {
        uint16_t t = idx[0];
        idx[0] = idx[k];
        idx[k] = t;
        sort_sift(idx, key, 0u, k);
    }
}

static float dist(const magcal_vec2_t *a, const magcal_vec2_t *b)
{
    float dx = a->x - b->x;
    float dy = a->y - b->y;
    return sqrtf(dx * dx + dy * dy);
}

/*
 * Robust centre and radius over the counted points (use[i] != 0, or every point when use is
 * NULL): coordinate medians, R = median |p - c|; passes 1..AUTO_TRIM_PASSES use only the points
 * within AUTO_TRIM * R of the previous centre, so a far cluster (e.g. 23 % driver glitches 36 R
 * away) cannot drag the centre off the ring. cr = {cx, cy, R}; a: float[n] scratch. (One loop
 * per quantity, no helper call: this is on the filter's deepest stack path.)
 */
static magcal_status_t robust_centre(const magcal_vec2_t *pts, size_t n, const uint8_t *use,
                                     float *a, float cr[3])
{
    float cx = 0.0f;
    float cy = 0.0f;
    float rad = INFINITY;
    unsigned pass;
    for (pass = 0; pass <= AUTO_TRIM_PASSES; ++pass) {
        const float lim2 = pass == 0u ? INFINITY : (AUTO_TRIM * rad) * (AUTO_TRIM * rad);
        float med[3] = {0.0f, 0.0f, 0.0f};
        unsigned q;
        size_t k = 0u;
        for (q = 0u; q < 3u; ++q) { /* x median, y median, then the radius about them */
            size_t i;
            k = 0u;
            for (i = 0; i < n; ++i) {
                const float dx = pts[i].x - cx;
                const float dy = pts[i].y - cy;
                if ((use == NULL || (use[i] & AUTO_REP) != 0u) &&
                    (pass == 0u || dx * dx + dy * dy <= lim2)) {
                    const float ex = pts[i].x - med[0];
                    const float ey = pts[i].y - med[1];
                    a[k] = q == 0u ? pts[i].x : (q == 1u ? pts[i].y : sqrtf(ex * ex + ey * ey));
                    ++k;
                }
            }
            if (k < AUTO_MIN_N) {
                break; /* keep the previous estimate */
            }
            med[q] = magcal_ocore_select_kth(a, k, k / 2u);
        }
        if (k < AUTO_MIN_N) {
            break;
        }
        cx = med[0];
        cy = med[1];
        rad = med[2];
        if (!(rad > 0.0f) || !magcal_isfinite_f(rad)) {
            return MAGCAL_ERR_DEGENERATE;
        }
    }
    if (rad == INFINITY) {
        return MAGCAL_ERR_DEGENERATE; /* fewer than AUTO_MIN_N counted points */
    }
    cr[0] = cx;
    cr[1] = cy;
    cr[2] = rad;
    return MAGCAL_OK;
}

/*
 * Scale of the cloud that a clump cannot shrink: the median distance between AUTO_PAIRS
 * pseudo-random pairs of points. A pair lies inside one clump with probability f^2 for a clump
 * of a fraction f of the samples, so up to f = 0.7 the median is a distance across the ring
 * (about 1.4 R), whatever the order of the samples. a: float[n] scratch.
 */
static float pair_scale(const magcal_vec2_t *pts, size_t n, float *a)
{
    uint32_t state = AUTO_SEED;
    size_t k;
    const size_t m = n < AUTO_PAIRS ? n : AUTO_PAIRS;
    /* cppcheck-suppress knownConditionTrueFalse ; false positive: m = min(n, 256) >= 16 (check_points) */
    for (k = 0; k < m; ++k) {
        const size_t i = (size_t)(magcal_ocore_rand(&state) % (uint32_t)n);
        const size_t j = (size_t)(magcal_ocore_rand(&state) % (uint32_t)n);
        a[k] = dist(&pts[i], &pts[j]);
    }
    return magcal_ocore_select_kth(a, m, m / 2u);
}

/*
 * Cell side factor of the thinning for n samples: 1 up to AUTO_THIN_N, then AUTO_THIN_N / n, so
 * a ring keeps about n / 4 or more representatives (2 pi R / h cells along it) and sparse
 * outliers (one representative each, e.g. 6 % scattered samples at n = 4096) stay a minority.
 */
static float thin_scale(size_t n) { return n > AUTO_THIN_N ? (float)AUTO_THIN_N / (float)n : 1.0f; }

/*
 * Mean occupancy K = ceil(candidates / occupied cells) of idx[0..n) sorted by key (keys >=
 * invalid not counted): the core quantile keeps at most K samples per cell, so a clump (hundreds
 * of samples in one or two cells) is cut to K while the ring and sparse points keep their weight.
 */
static size_t cell_cap(const uint16_t *idx, const float *key, size_t n, float invalid)
{
    size_t i;
    size_t cells = 0u;
    size_t m = 0u;
    for (i = 0; i < n; ++i) {
        const float k = key[idx[i]];
        if (k < invalid) {
            ++m;
            if (i == 0u || k != key[idx[i - 1u]]) {
                ++cells;
            }
        }
    }
    return cells == 0u ? 0u : (m + cells - 1u) / cells;
}

/*
 * Thinning: one representative (the lowest index) per square cell of side h around c, so a
 * clump of near-identical samples (a vehicle parked at one heading) counts as one sample in the
 * centre and in the core-distance quantile. Cell coordinates are clamped to +-AUTO_CELL_HALF
 * (far points share the border cells); the cell number is exact in a float key. key: float[n],
 * idx: uint16[n] scratch; rep[i] = 1 for the representatives. Returns how many.
 */
static size_t thin2(const magcal_vec2_t *pts, size_t n, const float cr[3], float h, float *key,
                    uint16_t *idx, uint8_t *rep, const uint8_t *use)
{
    size_t i;
    size_t m = 0u;
    size_t cap;
    size_t run = 0u;
    const float lim = (float)AUTO_CELL_HALF;
    for (i = 0; i < n; ++i) {
        if (use != NULL && use[i] == 0u) {
            key[i] = 4.0f * lim * lim; /* after every cell: never a representative */
            idx[i] = (uint16_t)i;
            rep[i] = 0u;
            continue;
        }
        float u = floorf((pts[i].x - cr[0]) / h);
        float v = floorf((pts[i].y - cr[1]) / h);
        u = u < -lim ? -lim : (u > lim - 1.0f ? lim - 1.0f : u);
        v = v < -lim ? -lim : (v > lim - 1.0f ? lim - 1.0f : v);
        key[i] = (u + lim) * (2.0f * lim) + (v + lim);
        idx[i] = (uint16_t)i;
        rep[i] = 0u;
    }
    magcal_ocore_sort_idx(idx, key, n);
    cap = cell_cap(idx, key, n, 4.0f * lim * lim);
    for (i = 0; i < n; ++i) {
        run = (i == 0u || key[idx[i]] != key[idx[i - 1u]]) ? 0u : run + 1u;
        if (key[idx[i]] < 4.0f * lim * lim) {
            if (run == 0u) {
                rep[idx[i]] = AUTO_REP;
                ++m;
            }
            if (run < cap) {
                rep[idx[i]] = (uint8_t)(rep[idx[i]] | AUTO_CAPPED);
            }
        }
    }
    return m;
}

/*
 * Step 1 of the rule: centre and radius of the ring, each clump of near-identical samples counted
 * once: cells of a fraction of the pair scale first (a clump cannot shrink it), then of the
 * radius found. cr = {cx, cy, R}; w as auto_params (a, idx, rep). Its own frame (not inlined),
 * so the medians' deep path does not sit under auto_params' link and core locals (stack).
 */
static MAGCAL_NOINLINE magcal_status_t thinned_centre(const magcal_vec2_t *pts, size_t n,
                                                      uint8_t *w, float cr[3])
{
    float *a = (float *)(void *)w;
    uint16_t *idx = (uint16_t *)(void *)(w + 4u * n);
    uint8_t *rep = w + AUTO_REP_OFF(n);
    float h = pair_scale(pts, n, a) * AUTO_THIN_PAIR; /* coarse: out of any clump first */
    unsigned round;
    int have;
    if (!(h > 0.0f) || !magcal_isfinite_f(h)) {
        return MAGCAL_ERR_DEGENERATE;
    }
    have = 0;
    if (robust_centre(pts, n, NULL, a, cr) == MAGCAL_OK) {
        have = 1;
    }
    if (have == 0) {
        /* more than half the samples identical (R = 0): the first grid's origin is any sample */
        cr[0] = pts[0].x;
        cr[1] = pts[0].y;
    }
    for (round = 0u; round < AUTO_THIN_ROUNDS; ++round) {
        if (thin2(pts, n, cr, h, a, idx, rep, NULL) >= AUTO_MIN_N &&
            robust_centre(pts, n, rep, a, cr) == MAGCAL_OK) {
            have = 1;
            h = cr[2] * AUTO_THIN_REL * thin_scale(n);
        }
    }
    return have != 0 ? MAGCAL_OK : MAGCAL_ERR_DEGENERATE;
}

/*
 * Steps 2-4 of the rule of optics.h around the centre and radius cr (thinned_centre; rep[] of w
 * still marks its representatives) and, when sectors is not NULL, each point's angular sector
 * around the centre (0..AUTO_SECTORS-1 in the ring band, -1 outside) for the ring selection of
 * the filter. Layout of w: AUTO_B_OFF / AUTO_REP_OFF.
 */
static MAGCAL_NOINLINE magcal_status_t auto_eps(const magcal_vec2_t *pts, size_t n, uint8_t *w,
                                                const float cr[3], float *eps_prime,
                                                int16_t *sectors)
{
    float *a = (float *)(void *)w;
    uint16_t *idx = (uint16_t *)(void *)(w + 4u * n);
    float *b = (float *)(void *)(w + AUTO_B_OFF(n));
    uint8_t *rep = w + AUTO_REP_OFF(n);
    float cx;
    float cy;
    float rad;
    float lo;
    float hi;
    float link1 = 0.0f;
    float link2 = 0.0f;
    float coreq;
    float e;
    size_t i;
    size_t m = 0u;
    size_t nq = 0u;

    cx = cr[0];
    cy = cr[1];
    rad = cr[2];
    lo = rad - AUTO_BAND * rad;
    hi = rad + AUTO_BAND * rad;
    for (i = 0; i < n; ++i) {
        float dx = pts[i].x - cx;
        float dy = pts[i].y - cy;
        float r = sqrtf(dx * dx + dy * dy);
        a[i] = atan2f(dy, dx);
        if (r >= lo && r <= hi) {
            idx[m] = (uint16_t)i;
            ++m;
        }
    }
    if (m < 2u * AUTO_WIN + 2u) { /* the cyclic windows need distinct neighbours */
        return MAGCAL_ERR_DEGENERATE;
    }
    magcal_ocore_sort_idx(idx, a, m);
    for (i = 0; i < m; ++i) {
        const magcal_vec2_t *p0 = &pts[idx[i]];
        float near[2u * AUTO_WIN];
        float l = INFINITY;
        size_t q;
        size_t t;
        size_t u;
        /* shortest way across the step i -> i+1 that bypasses up to AUTO_WIN - 1 points */
        for (q = 0; q < AUTO_WIN; ++q) {
            for (t = 1u; q + t <= AUTO_WIN; ++t) {
                float dd = dist(&pts[idx[(i + m - q) % m]], &pts[idx[(i + t) % m]]);
                l = dd < l ? dd : l;
            }
        }
        if (l > link1) {
            link2 = link1;
            link1 = l;
        } else if (l > link2) {
            link2 = l;
        } else {
            /* neither of the two longest links */
        }
        if ((rep[idx[i]] & AUTO_CAPPED) == 0u) {
            continue; /* the core quantile counts a clump as K samples (mean cell occupancy) */
        }
        /* core requirement: (MinPts-1)-th nearest of the AUTO_WIN angular neighbours each side */
        for (q = 1u; q <= AUTO_WIN; ++q) {
            near[2u * q - 2u] = dist(p0, &pts[idx[(i + m - q) % m]]);
            near[2u * q - 1u] = dist(p0, &pts[idx[(i + q) % m]]);
        }
        for (t = 1u; t < (size_t)AUTO_WIN * 2u; ++t) { /* insertion sort of 8 values */
            float v = near[t];
            for (u = t; u > 0u; --u) {
                if (!(near[u - 1u] > v)) {
                    break;
                }
                near[u] = near[u - 1u];
            }
            near[u] = v;
        }
        b[nq] = near[AUTO_MIN_PTS - 2u];
        ++nq;
    }
    coreq = 0.0f;
    if (nq > 0u) {
        const size_t last = nq - 1u;
        const float qpos = AUTO_CORE_Q * (float)last;
        coreq = magcal_ocore_select_kth(b, nq, (size_t)qpos);
    }
    e = AUTO_SAFETY * (link2 > coreq ? link2 : coreq);
    if (e < AUTO_MIN_REL * rad) {
        e = AUTO_MIN_REL * rad;
    }
    if (e > AUTO_MAX_REL * rad) {
        e = AUTO_MAX_REL * rad;
    }
    *eps_prime = e;
    if (sectors != NULL) {
        /* a[] still holds the angles; sectors may overlay idx (no longer needed) */
        for (i = 0; i < n; ++i) {
            float dx = pts[i].x - cx;
            float dy = pts[i].y - cy;
            float r = sqrtf(dx * dx + dy * dy);
            int16_t sec = -1;
            if (r >= lo && r <= hi) {
                float f = (a[i] + AUTO_PI) * ((float)AUTO_SECTORS / (2.0f * AUTO_PI));
                int32_t k = (int32_t)f;
                k = k < 0 ? 0 : (k > (int32_t)AUTO_SECTORS - 1 ? (int32_t)AUTO_SECTORS - 1 : k);
                sec = (int16_t)k;
            }
            sectors[i] = sec;
        }
    }
    return MAGCAL_OK;
}

/* The rule of optics.h: step 1 (thinned_centre), then steps 2-4 (auto_eps), each in its own
 * frame so the deepest stack path holds only one of them. cr: the robust centre and radius. */
static magcal_status_t auto_params(const magcal_vec2_t *pts, size_t n, uint8_t *w, float *eps_prime,
                                   float cr[3], int16_t *sectors)
{
    magcal_status_t st = thinned_centre(pts, n, w, cr);
    if (st == MAGCAL_OK) {
        st = auto_eps(pts, n, w, cr, eps_prime, sectors);
    }
    return st;
}

magcal_status_t magcal_optics_auto_params(const magcal_vec2_t *pts, size_t n, void *work,
                                          size_t work_len, float *eps, uint16_t *min_pts,
                                          float *eps_prime)
{
    magcal_status_t st;
    float e;
    float cr[3];
    if (pts == NULL || work == NULL || eps == NULL || min_pts == NULL || eps_prime == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (magcal_misalign(work, 4u) != 0u) {
        return MAGCAL_ERR_ALIGNMENT;
    }
    st = check_points(pts, n, AUTO_MIN_N);
    if (st != MAGCAL_OK) {
        return st;
    }
    if (work_len < MAGCAL_OPTICS_FILTER_WORKSPACE_LEN(n)) {
        return MAGCAL_ERR_WORKSPACE;
    }
    st = auto_params(pts, n, (uint8_t *)work, &e, cr, NULL);
    if (st != MAGCAL_OK) {
        return st;
    }
    *eps = e;
    *eps_prime = e;
    *min_pts = (uint16_t)AUTO_MIN_PTS;
    return MAGCAL_OK;
}

magcal_status_t magcal_optics_filter(const magcal_optics_cfg_t *cfg, const magcal_vec2_t *pts,
                                     size_t n, void *work, size_t work_len, uint8_t *inlier_mask,
                                     magcal_optics_result_t *info)
{
    magcal_optics_cfg_t use;
    optics_ctx_t *c;
    magcal_status_t st;
    float eps_prime;
    float cr[3];
    float window[4];
    const float *win = NULL;
    uint8_t *w = (uint8_t *)work;
    if (cfg == NULL || pts == NULL || work == NULL || inlier_mask == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (magcal_misalign(work, 4u) != 0u) {
        return MAGCAL_ERR_ALIGNMENT;
    }
    use = *cfg;
    if (!(cfg->eps > 0.0f)) {
        if (cfg->eps != cfg->eps) {
            return MAGCAL_ERR_ARG; /* NaN is not "auto" */
        }
        use.eps = 1.0f;
        use.min_pts = (uint16_t)AUTO_MIN_PTS;
        st = magcal_ocore_check_cfg(&use);
        if (st == MAGCAL_OK) {
            st = check_points(pts, n, AUTO_MIN_N);
        }
        if (st == MAGCAL_OK && work_len < MAGCAL_OPTICS_FILTER_WORKSPACE_LEN(n)) {
            st = MAGCAL_ERR_WORKSPACE;
        }
        if (st == MAGCAL_OK) {
            st = auto_params(pts, n, w, &eps_prime, cr, (int16_t *)(void *)(w + 4u * n));
        }
        if (st != MAGCAL_OK) {
            return st;
        }
        use.eps = eps_prime;
        /* grid only over the ring's neighbourhood: far outliers are clamped into border cells */
        window[0] = cr[0] - 1.5f * cr[2] - eps_prime;
        window[1] = cr[1] - 1.5f * cr[2] - eps_prime;
        window[2] = cr[0] + 1.5f * cr[2] + eps_prime;
        window[3] = cr[1] + 1.5f * cr[2] + eps_prime;
        win = window;
    } else {
        st = magcal_ocore_check_cfg(&use);
        if (st != MAGCAL_OK) {
            return st;
        }
        eps_prime = cfg->eps_prime == 0.0f ? cfg->eps : cfg->eps_prime;
        if (!(eps_prime > 0.0f) || !magcal_isfinite_f(eps_prime) || eps_prime > cfg->eps) {
            return MAGCAL_ERR_ARG;
        }
        st = check_points(pts, n, use.min_pts);
        if (st != MAGCAL_OK) {
            return st;
        }
        if (work_len < MAGCAL_OPTICS_FILTER_WORKSPACE_LEN(n)) {
            return MAGCAL_ERR_WORKSPACE;
        }
    }
    c = ctx_setup(&use, pts, n, w + MAGCAL_OPTICS_FILTER_RUN_OFFSET_(n), win);
    c->oc.reach = (float *)work;
    c->oc.labels = (int16_t *)(void *)(w + 4u * n);
    c->oc.eps_prime = eps_prime;
    c->oc.use_sectors = 0; /* automatic mode: labels hold the sectors */
    if (win != NULL) {
        c->oc.use_sectors = 1;
    }
    optics_loop(c);
    magcal_ocore_fill_info(info, &c->oc, c->nb.use_grid, use.eps, eps_prime);
    return magcal_ocore_filter_out(&c->oc, n, inlier_mask, info);
}

/* Largest number of candidates in one thinning cell (w as thin2 left it: keys, sorted idx). */
static size_t max_cell_run(const uint8_t *w, size_t n)
{
    const float *key = (const float *)(const void *)w;
    const uint16_t *idx = (const uint16_t *)(const void *)(w + 4u * n);
    size_t i;
    size_t run = 0u;
    size_t best = 0u;
    for (i = 0; i < n; ++i) {
        run = (i == 0u || key[idx[i]] != key[idx[i - 1u]]) ? 1u : run + 1u;
        if (key[idx[i]] < THIN_INVALID && run > best) {
            best = run;
        }
    }
    return best;
}

magcal_status_t magcal_optics_thin(const magcal_vec2_t *pts, size_t n, const uint8_t *cand,
                                   void *work, size_t work_len, uint8_t *rep_mask)
{
    uint8_t *w = (uint8_t *)work;
    float cr[3];
    size_t i;
    magcal_status_t st;
    if (pts == NULL || work == NULL || rep_mask == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (magcal_misalign(work, 4u) != 0u) {
        return MAGCAL_ERR_ARG;
    }
    st = check_points(pts, n, AUTO_MIN_N);
    if (st != MAGCAL_OK) {
        return st;
    }
    if (work_len < MAGCAL_OPTICS_FILTER_WORKSPACE_LEN(n)) {
        return MAGCAL_ERR_WORKSPACE;
    }
    st = thinned_centre(pts, n, w, cr);
    if (st != MAGCAL_OK) {
        return st;
    }
    (void)thin2(pts, n, cr, cr[2] * AUTO_THIN_REL, (float *)(void *)w,
                (uint16_t *)(void *)(w + 4u * n), w + AUTO_REP_OFF(n), cand);
    if (max_cell_run(w, n) <= AUTO_CLUMP_RATIO * cell_cap((const uint16_t *)(const void *)(w + 4u * n),
                                                          (const float *)(const void *)w, n,
                                                          THIN_INVALID)) {
        /* no clump: every candidate stays (thinning a plain ring only changes which minimal sets
         * are drawn, and on noisy real rings that moved the consensus' fixed point) */
        for (i = 0; i < n; ++i) {
            rep_mask[i] = (uint8_t)((cand == NULL || cand[i] != 0u) ? 1u : 0u);
        }
        return MAGCAL_OK;
    }
    for (i = 0; i < n; ++i) {
        rep_mask[i] = (uint8_t)(w[AUTO_REP_OFF(n) + i] & AUTO_REP);
    }
    return MAGCAL_OK;
}

/* ---- time-sliced filter and thinning (first version: the one-shot inside the first step) ---- */

#define SLICE_MAGIC 0x4F505431u /* "OPT1": a begun slice */

typedef struct {
    uint32_t magic;
    magcal_status_t final;
    int finished;
    magcal_optics_cfg_t cfg;
    const magcal_vec2_t *pts;
    size_t n;
    void *work;
    size_t work_len;
    uint8_t *out_mask;
    const uint8_t *cand;
    magcal_optics_result_t *info;
} slice_state_t;

/* cppcheck-suppress misra-c2012-2.3 ; deviation D4: a static assert is an unused typedef */
MAGCAL_STATIC_ASSERT(sizeof(slice_state_t) <= sizeof(((magcal_optics_filter_slice_t *)0)->priv_),
                     optics_slice_state_fits);

magcal_status_t magcal_optics_filter_begin(magcal_optics_filter_slice_t *s,
                                           const magcal_optics_cfg_t *cfg,
                                           const magcal_vec2_t *pts, size_t n, void *work,
                                           size_t work_len, uint8_t *inlier_mask,
                                           magcal_optics_result_t *info)
{
    slice_state_t *t;
    if (s == NULL || cfg == NULL) {
        return MAGCAL_ERR_NULL;
    }
    t = (slice_state_t *)(void *)&s->priv_;
    (void)memset(t, 0, sizeof *t);
    t->magic = SLICE_MAGIC;
    t->cfg = *cfg;
    t->pts = pts;
    t->n = n;
    t->work = work;
    t->work_len = work_len;
    t->out_mask = inlier_mask;
    t->info = info;
    return MAGCAL_OK;
}

magcal_status_t magcal_optics_filter_step(magcal_optics_filter_slice_t *s, uint32_t budget)
{
    slice_state_t *t;
    (void)budget;
    if (s == NULL) {
        return MAGCAL_ERR_NULL;
    }
    t = (slice_state_t *)(void *)&s->priv_;
    if (t->magic != SLICE_MAGIC) {
        return MAGCAL_ERR_ARG;
    }
    if (t->finished == 0) {
        t->final = magcal_optics_filter(&t->cfg, t->pts, t->n, t->work, t->work_len, t->out_mask,
                                        t->info);
        t->finished = 1;
    }
    return t->final;
}

magcal_status_t magcal_optics_thin_begin(magcal_optics_thin_slice_t *s, const magcal_vec2_t *pts,
                                         size_t n, const uint8_t *cand, void *work,
                                         size_t work_len, uint8_t *rep_mask)
{
    slice_state_t *t;
    if (s == NULL) {
        return MAGCAL_ERR_NULL;
    }
    t = (slice_state_t *)(void *)&s->priv_;
    (void)memset(t, 0, sizeof *t);
    t->magic = SLICE_MAGIC;
    t->pts = pts;
    t->n = n;
    t->cand = cand;
    t->work = work;
    t->work_len = work_len;
    t->out_mask = rep_mask;
    return MAGCAL_OK;
}

magcal_status_t magcal_optics_thin_step(magcal_optics_thin_slice_t *s, uint32_t budget)
{
    slice_state_t *t;
    (void)budget;
    if (s == NULL) {
        return MAGCAL_ERR_NULL;
    }
    t = (slice_state_t *)(void *)&s->priv_;
    if (t->magic != SLICE_MAGIC) {
        return MAGCAL_ERR_ARG;
    }
    if (t->finished == 0) {
        t->final = magcal_optics_thin(t->pts, t->n, t->cand, t->work, t->work_len, t->out_mask);
        t->finished = 1;
    }
    return t->final;
}
