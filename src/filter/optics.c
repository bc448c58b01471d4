/*
 * OPTICS ordering, ExtractDBSCAN, largest cluster, automatic parameters and clump thinning for
 * 2-D points (algorithms.md 4), every O(n) loop resumable (the slice contract, optics.h
 * "time-sliced"). Layout of this file:
 *   1. per-visit weights and the rule's constants;
 *   2. resumable primitives: Hoare selection, heapsort (also the one-shot helpers of optics3.c);
 *   3. the slice state (sl_t, in the workspace) and its sub-machines: robust centre, thinning,
 *      thinned centre, the eps' rule, the ordering loop with on-the-fly extraction;
 *   4. the driver (sl_step) and the public entry points: each one-shot call is begin + a step of
 *      unlimited budget on the same machine (one code path).
 */
#include "magcal/optics.h"

#include <math.h>
#include <stddef.h>
#include <string.h>

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
unsigned long magcal_optics_slice_prof[P_N_WEIGHTS + 16];
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

/* ---- 2. resumable primitives ---------------------------------------------------------------- */

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
} sel_t;

static void sel_begin(sel_t *q, size_t n, size_t k)
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
static MAGCAL_NOINLINE int sel_run(sel_t *q, float *a, int32_t *rem)
{
    int32_t r = *rem;
    size_t i = q->i;
    size_t j = q->j;
    float pivot = q->pivot;
    int paused = 0;
    /* cppcheck-suppress misra-c2012-15.4 ; deviation D13: a resumable loop leaves at its pause point and at its phase end */
    while (q->st != 3u && paused == 0) {
        if (q->st == 0u) {
            const size_t lo = q->lo;
            const size_t hi = q->hi;
            if (!(lo < hi)) {
                q->st = 3u;
                break;
            }
            pivot = a[lo + (hi - lo) / 2u];
            i = lo;
            j = hi;
            q->st = 1u;
            CHARGE(r, W_SEL);
        }
        if (q->st == 1u) {
            while (a[i] < pivot && r > 0) {
                ++i;
                CHARGE(r, W_SEL);
            }
            if (a[i] < pivot) {
                break;
            }
            q->st = 2u;
        }
        while (a[j] > pivot && r > 0) {
            --j;
            CHARGE(r, W_SEL);
        }
        if (a[j] > pivot) {
            break;
        }
        if (i >= j) {
            /* now a[lo..j] <= pivot <= a[j+1..hi] (Hoare partition, j in [lo, hi-1]) */
            if (q->k <= j) {
                q->hi = (uint16_t)j;
            } else {
                q->lo = (uint16_t)(j + 1u);
            }
            q->st = 0u;
        } else {
            const float t = a[i];
            a[i] = a[j];
            a[j] = t;
            ++i;
            --j;
            q->st = 1u;
        }
        CHARGE(r, W_SEL);
        if (r <= 0 && q->st != 3u) {
            paused = 1;
        }
    }
    q->i = (uint16_t)i;
    q->j = (uint16_t)j;
    q->pivot = pivot;
    *rem = r;
    return q->st == 3u ? 1 : 0;
}

/* (declared in optics_core.h: the 3-D automatic parameters use it too) */
float magcal_ocore_select_kth(float *a, size_t n, size_t k)
{
    sel_t q;
    unsigned guard;
    sel_begin(&q, n, k);
    for (guard = 0u; guard < SLICE_ONESHOT_ROUNDS; ++guard) {
        int32_t rem = SLICE_REM_MAX;
        if (sel_run(&q, a, &rem) != 0) {
            break;
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

/* One sift of the heap idx[0..m); returns the levels it descended (for the budget). */
static int32_t sort_sift(uint16_t *idx, const float *key, size_t k0, size_t m)
{
    size_t k = k0;
    int32_t levels = 0;
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
        ++levels;
    }
    idx[k] = v;
    return levels;
}

/* Resumable heapsort: one sift per visit. */
typedef struct {
    uint16_t k;
    uint16_t m;
    uint8_t st; /* 0: heap build, 1: extraction, 2: done */
} hsort_t;

static void hsort_begin(hsort_t *h, size_t m)
{
    h->m = (uint16_t)m;
    h->k = (uint16_t)(m / 2u);
    h->st = m < 2u ? 2u : 0u;
}

static MAGCAL_NOINLINE int hsort_run(hsort_t *h, uint16_t *idx, const float *key, int32_t *rem)
{
    int32_t r = *rem;
    size_t k = h->k;
    const size_t m = h->m;
    while (h->st < 2u && r > 0) {
        size_t from = 0u;
        size_t lim = k;
        if (h->st == 0u) {
            /* heap build: sift k-1 within m, k = m/2 .. 1 */
            if (k == 0u) {
                k = m - 1u;
                h->st = 1u;
                continue;
            }
            from = k - 1u;
            lim = m;
        } else {
            /* extraction: the root to k, sift the root within k, k = m-1 .. 1 */
            uint16_t t;
            if (k == 0u) {
                h->st = 2u;
                break;
            }
            t = idx[0];
            idx[0] = idx[k];
            idx[k] = t;
        }
        {
            const int32_t lv = sort_sift(idx, key, from, lim); /* one call site: inlined */
            CHARGE(r, W_HS);
            CHARGE_K(r, W_HSL, lv);
        }
        --k;
    }
    if (h->st == 0u && k == 0u) {
        k = m - 1u;
        h->st = 1u;
    }
    if (h->st == 1u && k == 0u) {
        h->st = 2u;
    }
    h->k = (uint16_t)k;
    *rem = r;
    return h->st == 2u ? 1 : 0;
}

/* (declared in optics_core.h: the 3-D thinning and the bench's sorted list use it too) */
void magcal_ocore_sort_idx(uint16_t *idx, const float *key, size_t m)
{
    hsort_t h;
    unsigned guard;
    hsort_begin(&h, m);
    for (guard = 0u; guard < SLICE_ONESHOT_ROUNDS; ++guard) {
        int32_t rem = SLICE_REM_MAX;
        if (hsort_run(&h, idx, key, &rem) != 0) {
            break;
        }
    }
}

static float dist(const magcal_vec2_t *a, const magcal_vec2_t *b)
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
static float thin_scale(size_t n) { return n > AUTO_THIN_N ? (float)AUTO_THIN_N / (float)n : 1.0f; }

/* ---- 3. the slice state and its sub-machines ------------------------------------------------ */

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
    sel_t sel;
    uint16_t i;
    uint16_t k;
    uint8_t pass;
    uint8_t q;
    uint8_t st; /* RC_* */
} rc_t;

#define RC_PASS 0u
#define RC_GATHER 1u
#define RC_SELECT 2u
#define RC_AFTER 3u
#define RC_FINAL 4u

static void rc_begin(rc_t *c)
{
    c->cx = 0.0f;
    c->cy = 0.0f;
    c->rad = INFINITY;
    c->pass = 0u;
    c->st = (uint8_t)RC_PASS;
}

/* Returns 1 when done (*st: MAGCAL_OK with cr = {cx, cy, R}, or MAGCAL_ERR_DEGENERATE with cr
 * untouched), 0 when the budget ran out. use: NULL (every point) or the thinning flags. */
static MAGCAL_NOINLINE int rc_run(rc_t *c, const magcal_vec2_t *pts, size_t n, const uint8_t *use, float *a,
                  float cr[3], magcal_status_t *st, int32_t *rem)
{
    for (;;) {
        if (c->st == (uint8_t)RC_PASS) {
            if (c->pass > AUTO_TRIM_PASSES) {
                c->st = (uint8_t)RC_FINAL;
                continue;
            }
            c->lim2 = c->pass == 0u ? INFINITY : (AUTO_TRIM * c->rad) * (AUTO_TRIM * c->rad);
            c->med[0] = 0.0f;
            c->med[1] = 0.0f;
            c->med[2] = 0.0f;
            c->q = 0u;
            c->i = 0u;
            c->k = 0u;
            c->st = (uint8_t)RC_GATHER;
        }
        if (c->st == (uint8_t)RC_GATHER) {
            /* x median, y median, then the radius about them */
            size_t i = c->i;
            size_t k = c->k;
            int32_t r = *rem;
            const unsigned q = c->q;
            const float cx = c->cx;
            const float cy = c->cy;
            const float lim2 = c->lim2;
            const float m0 = c->med[0];
            const float m1 = c->med[1];
            for (; i < n && r > 0; ++i) {
                const float dx = pts[i].x - cx;
                const float dy = pts[i].y - cy;
                if ((use == NULL || (use[i] & AUTO_REP) != 0u) &&
                    (c->pass == 0u || dx * dx + dy * dy <= lim2)) {
                    const float ex = pts[i].x - m0;
                    const float ey = pts[i].y - m1;
                    a[k] = q == 0u ? pts[i].x : (q == 1u ? pts[i].y : sqrtf(ex * ex + ey * ey));
                    ++k;
                }
                CHARGE(r, W_GATHER);
            }
            c->i = (uint16_t)i;
            c->k = (uint16_t)k;
            *rem = r;
            if (i < n) {
                return 0;
            }
            if (k < AUTO_MIN_N) {
                c->st = (uint8_t)RC_AFTER; /* keep the previous estimate */
                continue;
            }
            sel_begin(&c->sel, k, k / 2u);
            c->st = (uint8_t)RC_SELECT;
        }
        if (c->st == (uint8_t)RC_SELECT) {
            if (*rem <= 0 || sel_run(&c->sel, a, rem) == 0) {
                return 0;
            }
            c->med[c->q] = a[c->k / 2u];
            c->q++;
            c->i = 0u;
            c->k = 0u;
            c->st = (uint8_t)(c->q < 3u ? RC_GATHER : RC_AFTER);
            if (c->st == (uint8_t)RC_GATHER) {
                continue;
            }
            c->k = AUTO_MIN_N; /* all three medians taken */
        }
        if (c->st == (uint8_t)RC_AFTER) {
            if (c->k < AUTO_MIN_N) {
                c->st = (uint8_t)RC_FINAL;
                continue;
            }
            c->cx = c->med[0];
            c->cy = c->med[1];
            c->rad = c->med[2];
            if (!(c->rad > 0.0f) || !magcal_isfinite_f(c->rad)) {
                *st = MAGCAL_ERR_DEGENERATE;
                return 1;
            }
            c->pass++;
            c->st = (uint8_t)RC_PASS;
            continue;
        }
        /* RC_FINAL */
        if (c->rad == INFINITY) {
            *st = MAGCAL_ERR_DEGENERATE; /* fewer than AUTO_MIN_N counted points */
            return 1;
        }
        cr[0] = c->cx;
        cr[1] = c->cy;
        cr[2] = c->rad;
        *st = MAGCAL_OK;
        return 1;
    }
}

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
    hsort_t hs;
    float h;
    uint16_t i;
    uint16_t m;
    uint16_t cells;
    uint16_t cap;
    uint16_t run;
    uint16_t best;
    uint8_t st; /* TH_* */
} th_t;

#define TH_KEYS 0u
#define TH_SORT 1u
#define TH_CAP 2u
#define TH_MARK 3u
#define TH_MAXRUN 4u
#define TH_DONE 5u

static void th_begin(th_t *t, float h)
{
    (void)memset(t, 0, sizeof *t);
    t->h = h;
    t->st = (uint8_t)TH_KEYS;
}

/* TH_KEYS from point i: each point's cell key (own frame: its floats stay off the sort's path).
 * Returns the next point. */
static MAGCAL_NOINLINE size_t th_keys(const magcal_vec2_t *pts, size_t n, const float cr[3],
                                      float h, uint8_t *w, const uint8_t *use, size_t i0,
                                      int32_t *rem)
{
    float *key = (float *)(void *)w;
    uint16_t *idx = (uint16_t *)(void *)(w + 4u * n);
    uint8_t *rep = w + AUTO_REP_OFF(n);
    const float lim = (float)AUTO_CELL_HALF;
    int32_t r = *rem;
    size_t i = i0;
    for (; i < n && r > 0; ++i) {
        CHARGE(r, W_KEY);
        idx[i] = (uint16_t)i;
        rep[i] = 0u;
        if (use != NULL && use[i] == 0u) {
            key[i] = 4.0f * lim * lim; /* after every cell: never a representative */
            continue;
        }
        float u = floorf((pts[i].x - cr[0]) / h);
        float v = floorf((pts[i].y - cr[1]) / h);
        u = u < -lim ? -lim : (u > lim - 1.0f ? lim - 1.0f : u);
        v = v < -lim ? -lim : (v > lim - 1.0f ? lim - 1.0f : v);
        key[i] = (u + lim) * (2.0f * lim) + (v + lim);
    }
    *rem = r;
    return i;
}

/* Returns 1 when done up to stage `last` (TH_MARK or TH_MAXRUN), 0 when the budget ran out. */
static MAGCAL_NOINLINE int th_run(th_t *t, const magcal_vec2_t *pts, size_t n, const float cr[3], uint8_t *w,
                  const uint8_t *use, unsigned last, int32_t *rem)
{
    float *key = (float *)(void *)w;
    uint16_t *idx = (uint16_t *)(void *)(w + 4u * n);
    uint8_t *rep = w + AUTO_REP_OFF(n);
    size_t i = t->i;
    int32_t r = *rem;
    /* cppcheck-suppress misra-c2012-15.4 ; deviation D13: a resumable loop leaves at its pause point and at its phase end */
    while (t->st <= last) {
        if (t->st == (uint8_t)TH_KEYS) {
            i = th_keys(pts, n, cr, t->h, w, use, i, &r);
            if (i < n) {
                break;
            }
            hsort_begin(&t->hs, n);
            t->st = (uint8_t)TH_SORT;
        } else if (t->st == (uint8_t)TH_SORT) {
            if (r <= 0 || hsort_run(&t->hs, idx, key, &r) == 0) {
                break;
            }
            i = 0u;
            t->st = (uint8_t)TH_CAP;
        } else if (t->st == (uint8_t)TH_CAP) {
            size_t m = t->m;
            size_t cells = t->cells;
            for (; i < n && r > 0; ++i) {
                const float k = key[idx[i]];
                if (k < THIN_INVALID) {
                    ++m;
                    if (i == 0u || k != key[idx[i - 1u]]) {
                        ++cells;
                    }
                }
                CHARGE(r, W_CAP);
            }
            t->m = (uint16_t)m;
            t->cells = (uint16_t)cells;
            if (i < n) {
                break;
            }
            t->cap = (uint16_t)(cells == 0u ? 0u : (m + cells - 1u) / cells);
            t->m = 0u;
            i = 0u;
            t->st = (uint8_t)TH_MARK;
        } else if (t->st == (uint8_t)TH_MARK) {
            size_t run = t->run;
            size_t m = t->m;
            for (; i < n && r > 0; ++i) {
                run = (i == 0u || key[idx[i]] != key[idx[i - 1u]]) ? 0u : run + 1u;
                if (key[idx[i]] < THIN_INVALID) {
                    if (run == 0u) {
                        rep[idx[i]] = AUTO_REP;
                        ++m;
                    }
                    if (run < t->cap) {
                        rep[idx[i]] = (uint8_t)(rep[idx[i]] | AUTO_CAPPED);
                    }
                }
                CHARGE(r, W_CAP);
            }
            t->run = (uint16_t)run;
            t->m = (uint16_t)m;
            if (i < n) {
                break;
            }
            i = 0u;
            t->run = 0u;
            t->st = (uint8_t)TH_MAXRUN;
        } else if (t->st == (uint8_t)TH_MAXRUN) {
            /* largest number of candidates in one cell */
            size_t run = t->run;
            size_t best = t->best;
            for (; i < n && r > 0; ++i) {
                run = (i == 0u || key[idx[i]] != key[idx[i - 1u]]) ? 1u : run + 1u;
                if (key[idx[i]] < THIN_INVALID && run > best) {
                    best = run;
                }
                CHARGE(r, W_CAP);
            }
            t->run = (uint16_t)run;
            t->best = (uint16_t)best;
            if (i < n) {
                break;
            }
            t->st = (uint8_t)TH_DONE;
        } else {
            break;
        }
    }
    t->i = (uint16_t)i;
    *rem = r;
    return t->st > last ? 1 : 0;
}

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
        sel_t sel;
        rc_t rc;
        th_t th;
    /* cppcheck-suppress misra-c2012-19.2 ; deviation D12: the slice state overlays the sub-machines that are never live together, so it fits the workspace budget */
    } u;
    float h;
    uint32_t rng;
    uint16_t k;
    uint8_t round;
    uint8_t have;
    uint8_t st; /* CE_* */
} ce_t;

#define CE_PAIRS 0u
#define CE_PAIR_SEL 1u
#define CE_RC0 2u
#define CE_THIN 3u
#define CE_RC 4u
#define CE_DONE 5u

static void ce_begin(ce_t *c)
{
    (void)memset(c, 0, sizeof *c);
    c->rng = AUTO_SEED;
    c->st = (uint8_t)CE_PAIRS;
}

/* CE_PAIRS: the pair distances of the pair scale (own frame); 1 when all m are done. */
static MAGCAL_NOINLINE int ce_pairs(ce_t *c, const magcal_vec2_t *pts, size_t n, float *a,
                                    size_t m, int32_t *rem)
{
    size_t k = c->k;
    int32_t r = *rem;
    uint32_t rng = c->rng;
    for (; k < m && r > 0; ++k) {
        const size_t i = (size_t)(magcal_ocore_rand(&rng) % (uint32_t)n);
        const size_t j = (size_t)(magcal_ocore_rand(&rng) % (uint32_t)n);
        a[k] = dist(&pts[i], &pts[j]);
        CHARGE(r, W_PAIR);
    }
    c->k = (uint16_t)k;
    c->rng = rng;
    *rem = r;
    return k < m ? 0 : 1;
}

static MAGCAL_NOINLINE int ce_run(ce_t *c, const magcal_vec2_t *pts, size_t n, uint8_t *w, float cr[3],
                  magcal_status_t *st, int32_t *rem)
{
    float *a = (float *)(void *)w;
    const size_t m = n < AUTO_PAIRS ? n : AUTO_PAIRS;
    magcal_status_t s2 = MAGCAL_OK;
    for (;;) {
        if (*rem <= 0) {
            return 0;
        }
        switch (c->st) {
        case CE_PAIRS:
            if (ce_pairs(c, pts, n, a, m, rem) == 0) {
                return 0;
            }
            sel_begin(&c->u.sel, m, m / 2u);
            c->st = (uint8_t)CE_PAIR_SEL;
            break;
        case CE_PAIR_SEL:
            if (sel_run(&c->u.sel, a, rem) == 0) {
                return 0;
            }
            c->h = a[m / 2u] * AUTO_THIN_PAIR; /* coarse: out of any clump first */
            if (!(c->h > 0.0f) || !magcal_isfinite_f(c->h)) {
                *st = MAGCAL_ERR_DEGENERATE;
                return 1;
            }
            rc_begin(&c->u.rc);
            c->st = (uint8_t)CE_RC0;
            break;
        case CE_RC0:
            if (rc_run(&c->u.rc, pts, n, NULL, a, cr, &s2, rem) == 0) {
                return 0;
            }
            if (s2 == MAGCAL_OK) {
                c->have = 1u;
            } else {
                /* more than half the samples identical (R = 0): the first grid's origin is any
                 * sample */
                cr[0] = pts[0].x;
                cr[1] = pts[0].y;
            }
            c->round = 0u;
            th_begin(&c->u.th, c->h);
            c->st = (uint8_t)CE_THIN;
            break;
        case CE_THIN:
            if (th_run(&c->u.th, pts, n, cr, w, NULL, (unsigned)TH_MARK, rem) == 0) {
                return 0;
            }
            if (c->u.th.m >= AUTO_MIN_N) {
                rc_begin(&c->u.rc);
                c->st = (uint8_t)CE_RC;
                break;
            }
            c->round++;
            c->st = (uint8_t)CE_DONE;
            if (c->round < AUTO_THIN_ROUNDS) {
                th_begin(&c->u.th, c->h);
                c->st = (uint8_t)CE_THIN;
            }
            break;
        case CE_RC:
            if (rc_run(&c->u.rc, pts, n, w + AUTO_REP_OFF(n), a, cr, &s2, rem) == 0) {
                return 0;
            }
            if (s2 == MAGCAL_OK) {
                c->have = 1u;
                c->h = cr[2] * AUTO_THIN_REL * thin_scale(n);
            }
            c->round++;
            c->st = (uint8_t)CE_DONE;
            if (c->round < AUTO_THIN_ROUNDS) {
                th_begin(&c->u.th, c->h);
                c->st = (uint8_t)CE_THIN;
            }
            break;
        default:
            *st = c->have != 0u ? MAGCAL_OK : MAGCAL_ERR_DEGENERATE;
            return 1;
        }
        CHARGE(*rem, W_PHASE);
    }
}

/*
 * Steps 2-4 of the rule of optics.h around the centre and radius cr (ce_run; rep[] of w still
 * marks its representatives) and, for the filter, each point's angular sector around the centre
 * (0..AUTO_SECTORS-1 in the ring band, -1 outside; overlaying idx) for the ring selection.
 */
typedef struct {
    /* cppcheck-suppress misra-c2012-19.2 ; deviation D12: the slice state overlays the sub-machines that are never live together, so it fits the workspace budget */
    union {
        hsort_t hs;
        sel_t sel;
    /* cppcheck-suppress misra-c2012-19.2 ; deviation D12: the slice state overlays the sub-machines that are never live together, so it fits the workspace budget */
    } u;
    float link1;
    float link2;
    uint16_t i;
    uint16_t m;
    uint16_t nq;
    uint8_t st; /* AE_* */
} ae_t;

#define AE_ANGLES 0u
#define AE_SORT 1u
#define AE_LINKS 2u
#define AE_SEL 3u
#define AE_SECTORS 4u
#define AE_DONE 5u

/* The link and the core requirement of band point i (of m, sorted by angle): one visit. */
static MAGCAL_NOINLINE void ae_link(ae_t *e, const magcal_vec2_t *pts, const uint16_t *idx, size_t m, size_t i,
                    const uint8_t *rep, float *b)
{
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
    if (l > e->link1) {
        e->link2 = e->link1;
        e->link1 = l;
    } else if (l > e->link2) {
        e->link2 = l;
    } else {
        /* neither of the two longest links */
    }
    if ((rep[idx[i]] & AUTO_CAPPED) == 0u) {
        return; /* the core quantile counts a clump as K samples (mean cell occupancy) */
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
    b[e->nq] = near[AUTO_MIN_PTS - 2u];
    e->nq++;
}

/* eps' = 1.5 * max(second largest link, core quantile), clamped to [R/256, R]. */
static float ae_eps(float link2, float coreq, float rad)
{
    float e = AUTO_SAFETY * (link2 > coreq ? link2 : coreq);
    if (e < AUTO_MIN_REL * rad) {
        e = AUTO_MIN_REL * rad;
    }
    if (e > AUTO_MAX_REL * rad) {
        e = AUTO_MAX_REL * rad;
    }
    return e;
}

/* AE_ANGLES from point i: angles around c into a[], ring band members into idx[] (own frame).
 * Returns the next point. */
static MAGCAL_NOINLINE size_t ae_angles(ae_t *e, const magcal_vec2_t *pts, size_t n, uint8_t *w,
                                        const float cr[3], size_t i0, int32_t *rem)
{
    float *a = (float *)(void *)w;
    uint16_t *idx = (uint16_t *)(void *)(w + 4u * n);
    const float lo = cr[2] - AUTO_BAND * cr[2];
    const float hi = cr[2] + AUTO_BAND * cr[2];
    size_t m = e->m;
    size_t i = i0;
    int32_t r = *rem;
    for (; i < n && r > 0; ++i) {
        float dx = pts[i].x - cr[0];
        float dy = pts[i].y - cr[1];
        float rr = sqrtf(dx * dx + dy * dy);
        a[i] = atan2f(dy, dx);
        if (rr >= lo && rr <= hi) {
            idx[m] = (uint16_t)i;
            ++m;
        }
        CHARGE(r, W_ANGLE);
    }
    e->m = (uint16_t)m;
    *rem = r;
    return i;
}

/* AE_SECTORS from point i: each point's sector (-1 outside the band) from the angles a[]. */
static MAGCAL_NOINLINE size_t ae_sectors(const magcal_vec2_t *pts, size_t n, const float *a,
                                         const float cr[3], int16_t *sectors, size_t i0,
                                         int32_t *rem)
{
    const float lo = cr[2] - AUTO_BAND * cr[2];
    const float hi = cr[2] + AUTO_BAND * cr[2];
    size_t i = i0;
    int32_t r = *rem;
    for (; i < n && r > 0; ++i) {
        float dx = pts[i].x - cr[0];
        float dy = pts[i].y - cr[1];
        float rr = sqrtf(dx * dx + dy * dy);
        int16_t sec = -1;
        if (rr >= lo && rr <= hi) {
            float f = (a[i] + AUTO_PI) * ((float)AUTO_SECTORS / (2.0f * AUTO_PI));
            int32_t k = (int32_t)f;
            k = k < 0 ? 0 : (k > (int32_t)AUTO_SECTORS - 1 ? (int32_t)AUTO_SECTORS - 1 : k);
            sec = (int16_t)k;
        }
        sectors[i] = sec;
        CHARGE(r, W_SECTOR);
    }
    *rem = r;
    return i;
}

/* Returns 1 when done (*st: MAGCAL_OK with *eps_prime, or MAGCAL_ERR_DEGENERATE), else 0. */
static MAGCAL_NOINLINE int ae_run(ae_t *e, const magcal_vec2_t *pts, size_t n, uint8_t *w, const float cr[3],
                  float *eps_prime, int16_t *sectors, magcal_status_t *st, int32_t *rem)
{
    float *a = (float *)(void *)w;
    uint16_t *idx = (uint16_t *)(void *)(w + 4u * n);
    float *b = (float *)(void *)(w + AUTO_B_OFF(n));
    const uint8_t *rep = w + AUTO_REP_OFF(n);
    size_t i = e->i;
    int32_t r = *rem;
    int paused = 0;
    /* cppcheck-suppress misra-c2012-15.4 ; deviation D13: a resumable loop leaves at its pause point and at its phase end */
    while (paused == 0 && e->st != (uint8_t)AE_DONE) {
        if (r <= 0) {
            paused = 1;
            break;
        }
        if (e->st == (uint8_t)AE_ANGLES) {
            i = ae_angles(e, pts, n, w, cr, i, &r);
            if (i < n) {
                paused = 1;
                break;
            }
            if (e->m < 2u * AUTO_WIN + 2u) { /* the cyclic windows need distinct neighbours */
                *st = MAGCAL_ERR_DEGENERATE;
                *rem = r;
                return 1;
            }
            hsort_begin(&e->u.hs, e->m);
            e->st = (uint8_t)AE_SORT;
        } else if (e->st == (uint8_t)AE_SORT) {
            if (hsort_run(&e->u.hs, idx, a, &r) == 0) {
                paused = 1;
                break;
            }
            i = 0u;
            e->st = (uint8_t)AE_LINKS;
        } else if (e->st == (uint8_t)AE_LINKS) {
            const size_t m = e->m;
            for (; i < m && r > 0; ++i) {
                ae_link(e, pts, idx, m, i, rep, b);
                CHARGE(r, W_LINK);
            }
            if (i < m) {
                paused = 1;
                break;
            }
            e->st = (uint8_t)AE_SECTORS; /* via the quantile when there is one */
            if (e->nq > 0u) {
                const size_t last = (size_t)e->nq - 1u;
                const float qpos = AUTO_CORE_Q * (float)last;
                sel_begin(&e->u.sel, e->nq, (size_t)qpos);
                e->st = (uint8_t)AE_SEL;
            } else {
                *eps_prime = ae_eps(e->link2, 0.0f, cr[2]); /* no core requirement counted */
            }
            i = 0u;
        } else if (e->st == (uint8_t)AE_SEL) {
            float coreq;
            if (sel_run(&e->u.sel, b, &r) == 0) {
                paused = 1;
                break;
            }
            coreq = b[e->u.sel.k];
            *eps_prime = ae_eps(e->link2, coreq, cr[2]);
            i = 0u;
            e->st = (uint8_t)AE_SECTORS;
        } else {
            /* AE_SECTORS: a[] still holds the angles; sectors overlay idx (no longer needed) */
            if (sectors == NULL) {
                e->st = (uint8_t)AE_DONE;
                break;
            }
            i = ae_sectors(pts, n, a, cr, sectors, i, &r);
            if (i < n) {
                paused = 1;
                break;
            }
            e->st = (uint8_t)AE_DONE;
        }
    }
    e->i = (uint16_t)i;
    *rem = r;
    if (paused != 0) {
        return 0;
    }
    *st = MAGCAL_OK;
    return 1;
}

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
} ord_scan_t;

typedef struct {
    magcal_ocore_t oc;
    magcal_nbr_t nb;
    float eps2;
    /* cppcheck-suppress misra-c2012-19.2 ; deviation D12: the slice state overlays the sub-machines that are never live together, so it fits the workspace budget */
    union { /* the build's state is dead once the scans begin */
        magcal_nbr_build_t nbb;
        ord_scan_t sc;
    /* cppcheck-suppress misra-c2012-19.2 ; deviation D12: the slice state overlays the sub-machines that are never live together, so it fits the workspace budget */
    } u;
    uint8_t st; /* OR_* */
} ord_t;

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

/* Start PROCESS(p): mark p, query its candidates; the step continues in pass 1. */
static void ord_process(ord_t *o, size_t p, magcal_nbr_ranges_t *rg)
{
    magcal_ocore_mark(&o->oc, p);
    magcal_nbr_query(&o->nb, p, rg);
    o->u.sc.p = (uint16_t)p;
    o->u.sc.cnt = 0u;
    o->u.sc.ri = 0u;
    o->u.sc.k = rg->begin[0];
    o->st = (uint8_t)OR_P1;
}

/* End of pass 1: core distance, extraction step, then the reach pass (or none). */
static MAGCAL_NOINLINE void ord_core_done(ord_t *o, const magcal_nbr_ranges_t *rg)
{
    magcal_ocore_t *oc = &o->oc;
    const size_t m = oc->min_pts;
    const size_t p = o->u.sc.p;
    float core_p = INFINITY;
    if (o->u.sc.cnt >= m) {
        core_p = sqrtf(oc->best[m - 1u]);
    }
    o->u.sc.core_p = core_p;
    if (oc->core != NULL) {
        oc->core[p] = core_p;
    }
    if (oc->labels != NULL) {
        magcal_ocore_extract_step(oc, p, core_p);
    }
    o->u.sc.ri = 0u;
    o->u.sc.k = rg->begin[0];
    if (o->u.sc.use_live != 0u) {
        o->u.sc.k = 0u;
        o->u.sc.lw = 0u;
        o->st = (uint8_t)OR_PLIVE;
    } else if (o->u.sc.cnt < m) {
        o->st = (uint8_t)OR_SEEDS;
    } else {
        o->st = (uint8_t)OR_P2;
    }
}

/*
 * The range scans below visit p's candidates from position (ri, k): one tight loop per range,
 * the budget tested per candidate; they leave (ri, k) where they stopped, ri = n_ranges when the
 * scan is complete. idx NULL: brute force, one range over every point.
 */

/* Pass 1: core distance (MinPts smallest d^2 in the insertion buffer). */
static MAGCAL_NOINLINE void ord_scan_core(ord_t *o, const magcal_nbr_ranges_t *rg, int32_t *rem)
{
    const magcal_vec2_t *pts = o->nb.pts;
    const size_t p = o->u.sc.p;
    const float px = pts[p].x;
    const float py = pts[p].y;
    const float eps2 = o->eps2;
    const size_t m = o->oc.min_pts;
    float *best = o->oc.best;
    const uint16_t *idx = rg->idx;
    size_t ri = o->u.sc.ri;
    size_t k = o->u.sc.k;
    size_t cnt = o->u.sc.cnt;
    int32_t r = *rem;
    while (ri < rg->n_ranges) {
        const size_t end = rg->end[ri];
        for (; k < end && r > 0; ++k) {
            const size_t j = idx != NULL ? idx[k] : k;
            const float dx = pts[j].x - px;
            const float dy = pts[j].y - py;
            const float d2 = dx * dx + dy * dy;
            if (d2 <= eps2 && (cnt < m || d2 < best[m - 1u])) {
                cnt = magcal_ocore_best_insert(best, cnt, m, d2);
            }
            CHARGE(r, W_CAND);
        }
        if (k < end) {
            break;
        }
        ++ri;
        if (ri < rg->n_ranges) {
            k = rg->begin[ri];
        }
    }
    o->u.sc.ri = (uint8_t)ri;
    o->u.sc.k = (uint16_t)k;
    o->u.sc.cnt = (uint16_t)cnt;
    *rem = r;
}

/* START_CORE: does s have MinPts points within eps? (counts until MinPts) */
static MAGCAL_NOINLINE void ord_scan_count(ord_t *o, const magcal_nbr_ranges_t *rg, int32_t *rem)
{
    const magcal_vec2_t *pts = o->nb.pts;
    const size_t p = o->u.sc.s;
    const float px = pts[p].x;
    const float py = pts[p].y;
    const float eps2 = o->eps2;
    const size_t m = o->oc.min_pts;
    const uint16_t *idx = rg->idx;
    size_t ri = o->u.sc.ri;
    size_t k = o->u.sc.k;
    size_t cnt = o->u.sc.cnt;
    int32_t r = *rem;
    while (ri < rg->n_ranges && cnt < m) {
        const size_t end = rg->end[ri];
        for (; k < end && r > 0 && cnt < m; ++k) {
            const size_t j = idx != NULL ? idx[k] : k;
            const float dx = pts[j].x - px;
            const float dy = pts[j].y - py;
            cnt += (dx * dx + dy * dy <= eps2) ? 1u : 0u;
            CHARGE(r, W_CAND);
        }
        if (k < end) {
            break;
        }
        ++ri;
        if (ri < rg->n_ranges) {
            k = rg->begin[ri];
        }
    }
    o->u.sc.ri = (uint8_t)ri;
    o->u.sc.k = (uint16_t)k;
    o->u.sc.cnt = (uint16_t)cnt;
    *rem = r;
}

/* Pass 2 (grid): reach updates of p's unprocessed neighbours. */
static MAGCAL_NOINLINE void ord_scan_reach(ord_t *o, const magcal_nbr_ranges_t *rg, int32_t *rem)
{
    magcal_ocore_t *oc = &o->oc;
    const magcal_vec2_t *pts = o->nb.pts;
    const size_t p = o->u.sc.p;
    const float px = pts[p].x;
    const float py = pts[p].y;
    const float eps2 = o->eps2;
    const float core_p = o->u.sc.core_p;
    const float core2 = oc->best[oc->min_pts - 1u];
    int heap = 0;
    if (oc->mode != MAGCAL_OPTICS_IMPROVED) {
        heap = 1;
    }
    const uint16_t *idx = rg->idx;
    size_t ri = o->u.sc.ri;
    size_t k = o->u.sc.k;
    int32_t r = *rem;
    while (ri < rg->n_ranges) {
        const size_t end = rg->end[ri];
        for (; k < end && r > 0; ++k) {
            const size_t j = idx[k];
            const float dx = pts[j].x - px;
            const float dy = pts[j].y - py;
            const float d2 = dx * dx + dy * dy;
            if (d2 <= eps2 && magcal_ocore_is_done(oc, j) == 0) {
                const float rr = magcal_ocore_reach_of(d2, core_p, core2);
                if (rr < oc->reach[j]) {
                    magcal_ocore_update(oc, p, j, rr);
                    CHARGE(r, W_UPD);
                    CHARGE_K(r, W_HEAP, heap);
                }
            }
            CHARGE(r, W_REACH);
        }
        if (k < end) {
            break;
        }
        ++ri;
        if (ri < rg->n_ranges) {
            k = rg->begin[ri];
        }
    }
    o->u.sc.ri = (uint8_t)ri;
    o->u.sc.k = (uint16_t)k;
    *rem = r;
}

/* Brute force pass 2 over the live list from k (drops p, updates the reach when p is core). */
static MAGCAL_NOINLINE void ord_scan_live(ord_t *o, int32_t *rem)
{
    magcal_ocore_t *oc = &o->oc;
    const magcal_vec2_t *pts = o->nb.pts;
    uint16_t *live = o->nb.idx;
    const size_t p = o->u.sc.p;
    const float px = pts[p].x;
    const float py = pts[p].y;
    const float eps2 = o->eps2;
    const size_t m = oc->min_pts;
    const float core_p = o->u.sc.cnt >= m ? o->u.sc.core_p : INFINITY;
    const float core2 = o->u.sc.cnt >= m ? oc->best[m - 1u] : INFINITY;
    int heap = 0;
    if (oc->mode != MAGCAL_OPTICS_IMPROVED) {
        heap = 1;
    }
    const size_t nl = o->u.sc.n_live;
    size_t k = o->u.sc.k;
    size_t w = o->u.sc.lw;
    int32_t r = *rem;
    for (; k < nl && r > 0; ++k) {
        const size_t j = live[k];
        CHARGE(r, W_REACH);
        if (j == p) {
            continue; /* the only point processed since the last pass */
        }
        live[w] = (uint16_t)j;
        ++w;
        if (core_p < INFINITY) {
            const float dx = pts[j].x - px;
            const float dy = pts[j].y - py;
            const float d2 = dx * dx + dy * dy;
            if (d2 <= eps2) {
                const float rr = magcal_ocore_reach_of(d2, core_p, core2);
                if (rr < oc->reach[j]) {
                    magcal_ocore_update(oc, p, j, rr);
                    CHARGE(r, W_UPD);
                    CHARGE_K(r, W_HEAP, heap);
                }
            }
        }
    }
    o->u.sc.k = (uint16_t)k;
    o->u.sc.lw = (uint16_t)w;
    if (k >= nl) {
        o->u.sc.n_live = (uint16_t)w;
        o->st = (uint8_t)OR_SEEDS;
    }
    *rem = r;
}

/* IMPROVED: the scan of the unordered seed list for the least (reach, index), from pk. */
static MAGCAL_NOINLINE int ord_scan_min(ord_t *o, int32_t *rem)
{
    magcal_ocore_t *oc = &o->oc;
    const float *reach = oc->reach;
    const uint16_t *seeds = oc->seeds;
    const size_t ns = oc->n_seeds;
    size_t k = o->u.sc.pk;
    size_t best = o->u.sc.pbest;
    uint16_t bq = o->u.sc.pbq;
    float br = o->u.sc.pbr;
    int32_t r = *rem;
    for (; k < ns && r > 0; ++k) {
        const uint16_t s = seeds[k];
        const float rs = reach[s];
        if (rs < br || (rs == br && s < bq)) {
            br = rs;
            bq = s;
            best = k;
        }
        CHARGE(r, W_POP);
    }
    o->u.sc.pk = (uint16_t)k;
    o->u.sc.pbest = (uint16_t)best;
    o->u.sc.pbq = bq;
    o->u.sc.pbr = br;
    *rem = r;
    return k >= ns ? 1 : 0;
}

/* Outer scan: the next start point of a run (pass 0: unprocessed core points; pass 1: any). */
static void ord_outer(ord_t *o, magcal_nbr_ranges_t *rg, size_t *rg_p, int32_t *rem)
{
    const size_t n = o->nb.n;
    CHARGE(*rem, W_SKIP);
    if (o->u.sc.pass >= 2u) {
        magcal_ocore_finish(&o->oc);
        o->st = (uint8_t)OR_DONE;
    } else if (o->u.sc.s >= n) {
        o->u.sc.pass++;
        o->u.sc.s = 0u;
    } else if (magcal_ocore_is_done(&o->oc, o->u.sc.s) != 0) {
        o->u.sc.s++;
    } else if (o->u.sc.pass == 0u) {
        magcal_nbr_query(&o->nb, o->u.sc.s, rg);
        *rg_p = (size_t)o->u.sc.s + n; /* ranges of the start-core count (offset: not a PROCESS) */
        o->u.sc.ri = 0u;
        o->u.sc.k = rg->begin[0];
        o->u.sc.cnt = 0u;
        o->st = (uint8_t)OR_ISCORE;
    } else {
        ord_process(o, o->u.sc.s, rg);
        *rg_p = o->u.sc.s;
        CHARGE(*rem, W_PSTART);
    }
}

/* Returns 1 when the ordering (and the extraction) is complete, 0 when the budget ran out. */
static MAGCAL_NOINLINE int ord_run(ord_t *o, int32_t *rem)
{
    magcal_ocore_t *oc = &o->oc;
    const size_t n = o->nb.n;
    magcal_nbr_ranges_t rg;
    size_t rg_p = 2u * (size_t)MAGCAL_MAX_SAMPLES; /* rg valid for: p (process) or s + n */
    /* no ranges until the first query (rg_p matches no point before it); initialised so the
     * analysers see it */
    (void)memset(&rg, 0, sizeof rg);
    int requeried = 0;
    int32_t r = *rem;
    while (r > 0 && o->st != (uint8_t)OR_DONE) {
        switch (o->st) {
        case OR_BUILD:
            if (magcal_nbr_build_step(&o->nb, &o->u.nbb, &r) != 0) {
                o->u.sc.s = 0u;
                o->st = (uint8_t)OR_INIT;
            }
            break;
        case OR_INIT: {
            size_t i = o->u.sc.s;
            for (; i < n && r > 0; ++i) {
                oc->reach[i] = INFINITY;
                if (oc->pred != NULL) {
                    oc->pred[i] = MAGCAL_OPTICS_NO_PRED;
                }
                if (oc->mode == MAGCAL_OPTICS_CLASSIC) {
                    oc->pos[i] = MAGCAL_OCORE_POS_NONE;
                }
                CHARGE(r, W_INIT);
            }
            o->u.sc.s = (uint16_t)i;
            if (i < n) {
                break;
            }
            (void)memset(oc->done, 0, (n + 7u) / 8u);
            oc->n_seeds = 0u;
            oc->n_done = 0u;
#ifdef MAGCAL_OPTICS_BENCH_SORTED_LIST
            oc->head = 0u;
            oc->dirty = 0;
#endif
            o->u.sc.s = 0u;
            o->st = (uint8_t)(o->nb.use_grid != 0 ? OR_START : OR_LIVE);
            o->u.sc.use_live = (uint8_t)(o->nb.use_grid != 0 ? 0u : 1u);
            CHARGE(r, W_PHASE);
            break;
        }
        case OR_LIVE: {
            size_t i = o->u.sc.s;
            for (; i < n && r > 0; ++i) {
                o->nb.idx[i] = (uint16_t)i;
                CHARGE(r, W_INIT);
            }
            o->u.sc.s = (uint16_t)i;
            if (i < n) {
                break;
            }
            o->u.sc.n_live = (uint16_t)n;
            o->st = (uint8_t)OR_START;
            break;
        }
        case OR_START:
            o->u.sc.pass = (uint8_t)(oc->core_start != 0 ? 0u : 1u);
            o->u.sc.s = 0u;
            o->st = (uint8_t)OR_SCAN;
            break;
        case OR_SCAN:
            ord_outer(o, &rg, &rg_p, &r);
            break;
        case OR_ISCORE:
            if (rg_p != (size_t)o->u.sc.s + n) {
                magcal_nbr_query(&o->nb, o->u.sc.s, &rg);
                rg_p = (size_t)o->u.sc.s + n;
                requeried = 1;
            }
            ord_scan_count(o, &rg, &r);
            if (requeried != 0) {
                CHARGE(r, W_QUERY); /* after the scan: a resumed step still visits */
                requeried = 0;
            }
            if (o->u.sc.cnt < oc->min_pts && o->u.sc.ri < rg.n_ranges) {
                break; /* budget ran out inside the count */
            }
            if (o->u.sc.cnt >= oc->min_pts) {
                ord_process(o, o->u.sc.s, &rg);
                rg_p = o->u.sc.p;
                CHARGE(r, W_PSTART);
            } else {
                o->u.sc.s++;
                o->st = (uint8_t)OR_SCAN;
            }
            break;
        case OR_P1:
            if (rg_p != o->u.sc.p) {
                magcal_nbr_query(&o->nb, o->u.sc.p, &rg);
                rg_p = o->u.sc.p;
                requeried = 1;
            }
            ord_scan_core(o, &rg, &r);
            if (requeried != 0) {
                CHARGE(r, W_QUERY); /* after the scan: a resumed step still visits */
                requeried = 0;
            }
            if (o->u.sc.ri >= rg.n_ranges) {
                ord_core_done(o, &rg);
            }
            break;
        case OR_P2:
            if (rg_p != o->u.sc.p) {
                magcal_nbr_query(&o->nb, o->u.sc.p, &rg);
                rg_p = o->u.sc.p;
                requeried = 1;
            }
            ord_scan_reach(o, &rg, &r);
            if (requeried != 0) {
                CHARGE(r, W_QUERY); /* after the scan: a resumed step still visits */
                requeried = 0;
            }
            if (o->u.sc.ri >= rg.n_ranges) {
                o->st = (uint8_t)OR_SEEDS;
            }
            break;
        case OR_PLIVE:
            ord_scan_live(o, &r);
            break;
        case OR_SEEDS:
            if (oc->n_seeds == 0u) {
                o->u.sc.s++;
                o->st = (uint8_t)OR_SCAN;
            } else if (oc->mode == MAGCAL_OPTICS_IMPROVED) {
                o->u.sc.pk = 1u;
                o->u.sc.pbest = 0u;
                o->u.sc.pbq = oc->seeds[0];
                o->u.sc.pbr = oc->reach[o->u.sc.pbq];
                o->st = (uint8_t)OR_POP;
            } else {
                ord_process(o, magcal_ocore_pop_min(oc), &rg);
                rg_p = o->u.sc.p;
                CHARGE(r, W_HEAP);
                CHARGE(r, W_PSTART);
            }
            break;
        default: /* OR_POP */
            if (ord_scan_min(o, &r) != 0) {
                oc->n_seeds--;
                oc->seeds[o->u.sc.pbest] = oc->seeds[oc->n_seeds];
                ord_process(o, o->u.sc.pbq, &rg);
                rg_p = o->u.sc.p;
                CHARGE(r, W_PSTART);
            }
            break;
        }
    }
    *rem = r;
    return o->st == (uint8_t)OR_DONE ? 1 : 0;
}

/* ---- 4. the slice state, the driver and the entry points ------------------------------------ */

#define K_RUN 0u
#define K_FILTER 1u
#define K_AUTO 2u
#define K_THIN 3u
#define PH_FINITE 0u
#define PH_CENTRE 1u
#define PH_AUTOEPS 2u
#define PH_SETUP 3u
#define PH_ORDER 4u
#define PH_OUT 5u
#define PH_THIN 6u
#define PH_THINMASK 7u

/*
 * Everything live between two steps. It lives in the workspace, after the run workspace's MinPts
 * buffer (MAGCAL_OPTICS_CTX_LEN_ bytes, aligned for pointers; the static assert below), so the
 * one-shot calls keep their small stack frames and the public slice objects stay two words.
 * Each sub-machine's state is only live during its phase: they share one union.
 */
typedef struct {
    const magcal_vec2_t *pts;
    uint8_t *w;          /* the caller's workspace */
    uint8_t *out;        /* inlier or representative mask */
    /* cppcheck-suppress misra-c2012-19.2 ; deviation D12: the slice state overlays the sub-machines that are never live together, so it fits the workspace budget */
    union {
        const uint8_t *cand;          /* thinning: candidates (NULL: every point) */
        magcal_optics_result_t *info; /* filter and run: optional summary */
    /* cppcheck-suppress misra-c2012-19.2 ; deviation D12: the slice state overlays the sub-machines that are never live together, so it fits the workspace budget */
    } io;
    float eps; /* of the ordering */
    float eps_prime;
    float cr[3]; /* robust centre and radius */
    uint16_t n;
    uint16_t i; /* loop position of the finiteness and output phases */
    uint16_t min_pts;
    uint8_t kind;  /* K_* */
    uint8_t phase; /* PH_* */
    uint8_t order;
    uint8_t neighbors;
    uint8_t start;
    uint8_t is_auto;
    uint8_t thin_all;
    /* cppcheck-suppress misra-c2012-19.2 ; deviation D12: the slice state overlays the sub-machines that are never live together, so it fits the workspace budget */
    union {
        ce_t ce;
        ae_t ae;
        th_t th;
        ord_t ord;
    /* cppcheck-suppress misra-c2012-19.2 ; deviation D12: the slice state overlays the sub-machines that are never live together, so it fits the workspace budget */
    } u;
} sl_t;

/* cppcheck-suppress misra-c2012-2.3 ; deviation D4: a static assert is an unused typedef */
MAGCAL_STATIC_ASSERT(sizeof(sl_t) + sizeof(void *) - 4u <= MAGCAL_OPTICS_CTX_LEN_,
                     optics_slice_state_fits_workspace);

/* The slice state of a run workspace at runw for n points. */
static sl_t *sl_at(uint8_t *runw, size_t n)
{
    uint8_t *cw = runw + MAGCAL_OPTICS_BEST_OFFSET_(n) + 4u * (size_t)MAGCAL_MAX_MIN_PTS;
    cw += (sizeof(void *) - magcal_misalign(cw, sizeof(void *))) % sizeof(void *);
    return (sl_t *)(void *)cw;
}

/* Bytes of the thinning's state: the common part and the centre's sub-state (no ordering). */
#define SL_THIN_LEN ((size_t)offsetof(sl_t, u) + (size_t)sizeof(ce_t))

/*
 * The thinning's state: in the unused b[] region of the rule's layout when it fits (n >= 44 on a
 * 64-bit host), else right after rep[]. Either way inside the first 11 n + 3 + SL_THIN_LEN bytes,
 * the footprint the thinning has always had: the calibrator keeps its candidate mask in the
 * scratch behind the consensus workspace (10 n + 392 bytes on) while it thins.
 */
static sl_t *sl_thin_at(uint8_t *w, size_t n)
{
    uint8_t *cw = w + AUTO_REP_OFF(n) + n;
    if (4u * n >= (size_t)SL_THIN_LEN + sizeof(void *)) {
        cw = w + AUTO_B_OFF(n);
    }
    cw += (sizeof(void *) - magcal_misalign(cw, sizeof(void *))) % sizeof(void *);
    return (sl_t *)(void *)cw;
}

static sl_t *sl_new(sl_t *t, const magcal_vec2_t *pts, size_t n, unsigned kind)
{
    size_t len = sizeof *t;
    if (kind == (unsigned)K_THIN) {
        len = (size_t)SL_THIN_LEN;
    }
    (void)memset(t, 0, len);
    t->pts = pts;
    t->n = (uint16_t)n;
    t->kind = (uint8_t)kind;
    t->phase = (uint8_t)PH_FINITE;
    t->min_pts = (uint16_t)AUTO_MIN_PTS;
    return t;
}

static void sl_take_cfg(sl_t *t, const magcal_optics_cfg_t *cfg)
{
    t->order = (uint8_t)cfg->order;
    t->neighbors = (uint8_t)cfg->neighbors;
    t->start = (uint8_t)cfg->start;
}

/* Set up the ordering over the run workspace runw (O(1)); window: NULL or the grid window. */
static ord_t *sl_ord_begin(sl_t *t, uint8_t *runw, const float *window)
{
    ord_t *o = &t->u.ord;
    const size_t n = t->n;
    (void)memset(o, 0, sizeof *o);
    o->eps2 = t->eps * t->eps;
    o->oc.min_pts = t->min_pts;
    o->oc.mode = (magcal_optics_order_t)t->order;
    o->oc.core_start = 0;
    if (t->start == (uint8_t)MAGCAL_OPTICS_START_CORE) {
        o->oc.core_start = 1;
    }
    o->oc.seeds = (uint16_t *)(void *)runw;
    o->oc.pos = o->oc.seeds + n;
    o->oc.done = runw + 4u * n + MAGCAL_NEIGHBORS_WORKSPACE_LEN(n);
    o->oc.best = (float *)(void *)(runw + MAGCAL_OPTICS_BEST_OFFSET_(n));
    o->oc.id = -1;
    o->oc.best_id = -1;
    magcal_nbr_build_begin(&o->nb, &o->u.nbb, t->pts, n, t->eps, (magcal_neighbors_t)t->neighbors,
                           runw + 4u * n, window);
    o->st = (uint8_t)OR_BUILD;
    return o;
}

/* Filter: after the parameters, the ordering with on-the-fly extraction (and ring selection). */
static MAGCAL_NOINLINE void sl_filter_setup(sl_t *t)
{
    const size_t n = t->n;
    float window[4];
    const float *win = NULL;
    ord_t *o;
    if (t->is_auto != 0u) {
        /* grid only over the ring's neighbourhood: far outliers are clamped into border cells */
        window[0] = t->cr[0] - 1.5f * t->cr[2] - t->eps_prime;
        window[1] = t->cr[1] - 1.5f * t->cr[2] - t->eps_prime;
        window[2] = t->cr[0] + 1.5f * t->cr[2] + t->eps_prime;
        window[3] = t->cr[1] + 1.5f * t->cr[2] + t->eps_prime;
        win = window;
    }
    o = sl_ord_begin(t, t->w + MAGCAL_OPTICS_FILTER_RUN_OFFSET_(n), win);
    o->oc.reach = (float *)(void *)t->w;
    o->oc.labels = (int16_t *)(void *)(t->w + 4u * n);
    o->oc.eps_prime = t->eps_prime;
    o->oc.use_sectors = 0;
    if (t->is_auto != 0u) {
        o->oc.use_sectors = 1; /* automatic mode: labels hold the sectors */
    }
}

/* The phase after the finiteness check. */
static void sl_after_finite(sl_t *t)
{
    if (t->kind == (uint8_t)K_RUN) {
        t->phase = (uint8_t)PH_ORDER; /* set up by magcal_optics_run */
    } else if (t->kind == (uint8_t)K_FILTER && t->is_auto == 0u) {
        sl_filter_setup(t);
        t->phase = (uint8_t)PH_ORDER;
    } else {
        ce_begin(&t->u.ce);
        t->phase = (uint8_t)PH_CENTRE;
    }
}

/* PH_FINITE from t->i: 0 at a NaN/Inf coordinate, else 1 (own frame: float compares). */
static MAGCAL_NOINLINE int sl_finite(sl_t *t, int32_t *rem)
{
    const size_t n = t->n;
    size_t i = t->i;
    int32_t r = *rem;
    for (; i < n && r > 0; ++i) {
        if (!magcal_isfinite_f(t->pts[i].x) || !magcal_isfinite_f(t->pts[i].y)) {
            return 0;
        }
        CHARGE(r, W_FIN);
    }
    t->i = (uint16_t)i;
    *rem = r;
    return 1;
}

/* Thinning after the centre: cells of R/16 over the candidates (own frame: float math). */
static MAGCAL_NOINLINE void sl_thin_begin(sl_t *t)
{
    th_begin(&t->u.th, t->cr[2] * AUTO_THIN_REL);
    t->phase = (uint8_t)PH_THIN;
}

/* After the ordering: the summary; MAGCAL_OK (run), MAGCAL_ERR_ALL_NOISE, or MAGCAL_IN_PROGRESS
 * with the output phase next (filter). */
static MAGCAL_NOINLINE magcal_status_t sl_order_done(sl_t *t)
{
    ord_t *o = &t->u.ord;
    magcal_ocore_fill_info(t->io.info, &o->oc, o->nb.use_grid, t->eps,
                           t->kind == (uint8_t)K_RUN ? t->eps : t->eps_prime);
    if (t->kind == (uint8_t)K_RUN) {
        return MAGCAL_OK;
    }
    if (o->oc.best_id < 0) {
        return magcal_ocore_filter_out(&o->oc, t->n, t->out, t->io.info); /* ALL_NOISE */
    }
    t->i = 0u;
    t->phase = (uint8_t)PH_OUT;
    return MAGCAL_IN_PROGRESS;
}

/* One step of at most about `budget` estimated M4F instructions; MAGCAL_IN_PROGRESS or final.
 * w is t->w (set by begin only), passed by the caller so the analysers see that the phases'
 * writes into the workspace (the centre's a[], the masks) cannot change it. */
static magcal_status_t sl_step(sl_t *t, uint8_t *w, uint32_t budget)
{
    const size_t n = t->n;
    int32_t rem = budget > (uint32_t)SLICE_REM_MAX ? SLICE_REM_MAX : (int32_t)budget;
    magcal_status_t st = MAGCAL_OK;
    if (rem < 1) {
        rem = 1; /* progress for any budget */
    }
    while (rem > 0) {
        switch (t->phase) {
        case PH_FINITE:
            if (sl_finite(t, &rem) == 0) {
                return MAGCAL_ERR_NONFINITE;
            }
            if (t->i >= n) {
                sl_after_finite(t);
            }
            break;
        case PH_CENTRE:
            if (ce_run(&t->u.ce, t->pts, n, w, t->cr, &st, &rem) == 0) {
                break;
            }
            if (st != MAGCAL_OK) {
                return st;
            }
            if (t->kind == (uint8_t)K_THIN) {
                sl_thin_begin(t);
            } else {
                (void)memset(&t->u.ae, 0, sizeof t->u.ae);
                t->phase = (uint8_t)PH_AUTOEPS;
            }
            break;
        case PH_AUTOEPS:
            if (ae_run(&t->u.ae, t->pts, n, w, t->cr, &t->eps_prime,
                       t->kind == (uint8_t)K_FILTER ? (int16_t *)(void *)(w + 4u * n) : NULL,
                       &st, &rem) == 0) {
                break;
            }
            if (st != MAGCAL_OK || t->kind == (uint8_t)K_AUTO) {
                return st;
            }
            t->eps = t->eps_prime;
            t->phase = (uint8_t)PH_SETUP;
            break;
        case PH_SETUP:
            sl_filter_setup(t);
            t->phase = (uint8_t)PH_ORDER;
            CHARGE(rem, W_PHASE);
            break;
        case PH_ORDER: {
            ord_t *o = &t->u.ord;
            if (ord_run(o, &rem) == 0) {
                break;
            }
            st = sl_order_done(t);
            if (st != MAGCAL_IN_PROGRESS) {
                return st;
            }
            break;
        }
        case PH_OUT: {
            ord_t *o = &t->u.ord;
            const int16_t *labels = o->oc.labels;
            const int32_t id = o->oc.best_id;
            size_t i = t->i;
            for (; i < n && rem > 0; ++i) {
                t->out[i] = (labels[i] == id) ? 1u : 0u;
                CHARGE(rem, W_OUT);
            }
            t->i = (uint16_t)i;
            if (i < n) {
                break;
            }
            if (t->io.info != NULL) {
                const int32_t count = o->oc.id + 1;
                t->io.info->n_clusters = (uint16_t)count;
                t->io.info->largest_id = (int16_t)o->oc.best_id;
                t->io.info->n_inliers = (uint16_t)o->oc.best_count;
                t->io.info->n_noise = (uint16_t)o->oc.n_noise;
            }
            return MAGCAL_OK;
        }
        case PH_THIN:
            if (th_run(&t->u.th, t->pts, n, t->cr, w, t->io.cand, (unsigned)TH_MAXRUN, &rem) ==
                0) {
                break;
            }
            /* no clump: every candidate stays (thinning a plain ring only changes which minimal
             * sets are drawn, and on noisy real rings that moved the consensus' fixed point) */
            t->thin_all = (size_t)t->u.th.best <= AUTO_CLUMP_RATIO * (size_t)t->u.th.cap ? 1u : 0u;
            t->i = 0u;
            t->phase = (uint8_t)PH_THINMASK;
            break;
        default: { /* PH_THINMASK */
            const uint8_t *rep = w + AUTO_REP_OFF(n);
            size_t i = t->i;
            for (; i < n && rem > 0; ++i) {
                if (t->thin_all != 0u) {
                    t->out[i] = (uint8_t)((t->io.cand == NULL || t->io.cand[i] != 0u) ? 1u : 0u);
                } else {
                    t->out[i] = (uint8_t)(rep[i] & AUTO_REP);
                }
                CHARGE(rem, W_OUT);
            }
            t->i = (uint16_t)i;
            if (i >= n) {
                return MAGCAL_OK;
            }
            break;
        }
        }
    }
    return MAGCAL_IN_PROGRESS;
}

/* Run a begun state to its end (the one-shot calls: steps of unlimited budget). */
static magcal_status_t sl_finish(sl_t *t)
{
    uint8_t *const w = t->w;
    magcal_status_t st = MAGCAL_IN_PROGRESS;
    unsigned guard;
    for (guard = 0u; guard < SLICE_ONESHOT_ROUNDS && st == MAGCAL_IN_PROGRESS; ++guard) {
        st = sl_step(t, w, UINT32_MAX);
    }
    return st;
}

/* Public slice objects: the state's address (NULL once finished) and the final status. */
static magcal_status_t slice_step(void **state, magcal_status_t *status, uint32_t magic,
                                  uint32_t budget)
{
    magcal_status_t st;
    sl_t *t;
    if (magic != SLICE_MAGIC) {
        return MAGCAL_ERR_ARG;
    }
    if (*state == NULL) {
        return *status;
    }
    t = (sl_t *)*state;
    st = sl_step(t, t->w, budget);
    if (st != MAGCAL_IN_PROGRESS) {
        *status = st;
        *state = NULL;
    }
    return st;
}

magcal_status_t magcal_optics_run(const magcal_optics_cfg_t *cfg, const magcal_vec2_t *pts,
                                  size_t n, void *work, size_t work_len, uint16_t *order,
                                  float *reach, float *core, uint16_t *pred,
                                  magcal_optics_result_t *info)
{
    sl_t *t;
    ord_t *o;
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
    st = magcal_ocore_check_n(n, cfg->min_pts);
    if (st != MAGCAL_OK) {
        return st;
    }
    if (work_len < MAGCAL_OPTICS_WORKSPACE_LEN(n)) {
        return MAGCAL_ERR_WORKSPACE;
    }
    t = sl_new(sl_at((uint8_t *)work, n), pts, n, (unsigned)K_RUN);
    sl_take_cfg(t, cfg);
    t->eps = cfg->eps;
    t->min_pts = cfg->min_pts;
    t->io.info = info;
    o = sl_ord_begin(t, (uint8_t *)work, NULL);
    o->oc.reach = reach;
    o->oc.order = order;
    o->oc.core = core;
    o->oc.pred = pred;
    return sl_finish(t);
}

magcal_status_t magcal_optics_auto_params(const magcal_vec2_t *pts, size_t n, void *work,
                                          size_t work_len, float *eps, uint16_t *min_pts,
                                          float *eps_prime)
{
    magcal_status_t st;
    sl_t *t;
    if (pts == NULL || work == NULL || eps == NULL || min_pts == NULL || eps_prime == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (magcal_misalign(work, 4u) != 0u) {
        return MAGCAL_ERR_ALIGNMENT;
    }
    st = magcal_ocore_check_n(n, AUTO_MIN_N);
    if (st != MAGCAL_OK) {
        return st;
    }
    if (work_len < MAGCAL_OPTICS_FILTER_WORKSPACE_LEN(n)) {
        return MAGCAL_ERR_WORKSPACE;
    }
    t = sl_new(sl_at((uint8_t *)work + MAGCAL_OPTICS_FILTER_RUN_OFFSET_(n), n), pts, n,
                 (unsigned)K_AUTO);
    t->w = (uint8_t *)work;
    st = sl_finish(t);
    if (st != MAGCAL_OK) {
        return st;
    }
    *eps = t->eps_prime;
    *eps_prime = t->eps_prime;
    *min_pts = (uint16_t)AUTO_MIN_PTS;
    return MAGCAL_OK;
}

magcal_status_t magcal_optics_filter_begin(magcal_optics_filter_slice_t *s,
                                           const magcal_optics_cfg_t *cfg,
                                           const magcal_vec2_t *pts, size_t n, void *work,
                                           size_t work_len, uint8_t *inlier_mask,
                                           magcal_optics_result_t *info)
{
    magcal_optics_cfg_t use;
    magcal_status_t st;
    float eps_prime = 0.0f;
    int is_auto = 0;
    sl_t *t;
    if (s == NULL) {
        return MAGCAL_ERR_NULL;
    }
    s->magic_ = SLICE_MAGIC;
    s->state_ = NULL;
    if (cfg == NULL || pts == NULL || work == NULL || inlier_mask == NULL) {
        st = MAGCAL_ERR_NULL;
    } else if (magcal_misalign(work, 4u) != 0u) {
        st = MAGCAL_ERR_ALIGNMENT;
    } else if (!(cfg->eps > 0.0f)) {
        use = *cfg;
        is_auto = 1;
        use.eps = 1.0f;
        use.min_pts = (uint16_t)AUTO_MIN_PTS;
        st = cfg->eps != cfg->eps ? MAGCAL_ERR_ARG : magcal_ocore_check_cfg(&use); /* NaN: not auto */
        if (st == MAGCAL_OK) {
            st = magcal_ocore_check_n(n, AUTO_MIN_N);
        }
    } else {
        st = magcal_ocore_check_cfg(cfg);
        eps_prime = cfg->eps_prime == 0.0f ? cfg->eps : cfg->eps_prime;
        if (st == MAGCAL_OK &&
            (!(eps_prime > 0.0f) || !magcal_isfinite_f(eps_prime) || eps_prime > cfg->eps)) {
            st = MAGCAL_ERR_ARG;
        }
        if (st == MAGCAL_OK) {
            st = magcal_ocore_check_n(n, cfg->min_pts);
        }
    }
    if (st == MAGCAL_OK && work_len < MAGCAL_OPTICS_FILTER_WORKSPACE_LEN(n)) {
        st = MAGCAL_ERR_WORKSPACE;
    }
    if (st != MAGCAL_OK) {
        s->status_ = st;
        return st;
    }
    t = sl_new(sl_at((uint8_t *)work + MAGCAL_OPTICS_FILTER_RUN_OFFSET_(n), n), pts, n,
                 (unsigned)K_FILTER);
    sl_take_cfg(t, cfg);
    t->w = (uint8_t *)work;
    t->out = inlier_mask;
    t->io.info = info;
    t->is_auto = (uint8_t)is_auto;
    if (is_auto == 0) {
        t->eps = cfg->eps;
        t->eps_prime = eps_prime;
        t->min_pts = cfg->min_pts;
    }
    s->state_ = t;
    s->status_ = MAGCAL_IN_PROGRESS;
    return MAGCAL_OK;
}

magcal_status_t magcal_optics_filter_step(magcal_optics_filter_slice_t *s, uint32_t budget)
{
    if (s == NULL) {
        return MAGCAL_ERR_NULL;
    }
    return slice_step(&s->state_, &s->status_, s->magic_, budget);
}

magcal_status_t magcal_optics_filter(const magcal_optics_cfg_t *cfg, const magcal_vec2_t *pts,
                                     size_t n, void *work, size_t work_len, uint8_t *inlier_mask,
                                     magcal_optics_result_t *info)
{
    magcal_optics_filter_slice_t s;
    magcal_status_t st = magcal_optics_filter_begin(&s, cfg, pts, n, work, work_len, inlier_mask,
                                                    info);
    if (st == MAGCAL_OK) {
        st = sl_finish((sl_t *)s.state_);
    }
    return st;
}

magcal_status_t magcal_optics_thin_begin(magcal_optics_thin_slice_t *s, const magcal_vec2_t *pts,
                                         size_t n, const uint8_t *cand, void *work,
                                         size_t work_len, uint8_t *rep_mask)
{
    magcal_status_t st;
    sl_t *t;
    if (s == NULL) {
        return MAGCAL_ERR_NULL;
    }
    s->magic_ = SLICE_MAGIC;
    s->state_ = NULL;
    if (pts == NULL || work == NULL || rep_mask == NULL) {
        st = MAGCAL_ERR_NULL;
    } else if (magcal_misalign(work, 4u) != 0u) {
        st = MAGCAL_ERR_ARG;
    } else {
        st = magcal_ocore_check_n(n, AUTO_MIN_N);
    }
    if (st == MAGCAL_OK && work_len < MAGCAL_OPTICS_FILTER_WORKSPACE_LEN(n)) {
        st = MAGCAL_ERR_WORKSPACE;
    }
    if (st != MAGCAL_OK) {
        s->status_ = st;
        return st;
    }
    t = sl_new(sl_thin_at((uint8_t *)work, n), pts, n, (unsigned)K_THIN);
    t->w = (uint8_t *)work;
    t->out = rep_mask;
    t->io.cand = cand;
    s->state_ = t;
    s->status_ = MAGCAL_IN_PROGRESS;
    return MAGCAL_OK;
}

magcal_status_t magcal_optics_thin_step(magcal_optics_thin_slice_t *s, uint32_t budget)
{
    if (s == NULL) {
        return MAGCAL_ERR_NULL;
    }
    return slice_step(&s->state_, &s->status_, s->magic_, budget);
}

magcal_status_t magcal_optics_thin(const magcal_vec2_t *pts, size_t n, const uint8_t *cand,
                                   void *work, size_t work_len, uint8_t *rep_mask)
{
    magcal_optics_thin_slice_t s;
    magcal_status_t st = magcal_optics_thin_begin(&s, pts, n, cand, work, work_len, rep_mask);
    if (st == MAGCAL_OK) {
        st = sl_finish((sl_t *)s.state_);
    }
    return st;
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
    if (cfg->order != MAGCAL_OPTICS_IMPROVED
#if MAGCAL_CFG_ENABLE_OPTICS_CLASSIC
        && cfg->order != MAGCAL_OPTICS_CLASSIC
#endif
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

