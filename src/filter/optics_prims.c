/*
 * Resumable primitives of the 2-D OPTICS stage (optics_slice.h): Hoare selection and heapsort,
 * each resumable per element step or sift so the sliced sub-machines can pause inside them, and
 * their one-shot wrappers magcal_ocore_select_kth() / magcal_ocore_sort_idx() (optics_core.h),
 * also used by the 3-D stage (optics3.c).
 */
#include <stddef.h>
#include <stdint.h>

#include "optics_core.h"
#include "optics_slice.h"

/* Returns 1 when a[k] is the k-th smallest, 0 when *rem ran out (call again). */
MAGCAL_NOINLINE int magcal_o2_sel_run(magcal_o2_sel_t *q, float *a, int32_t *rem)
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
    magcal_o2_sel_t q;
    unsigned guard;
    magcal_o2_sel_begin(&q, n, k);
    for (guard = 0u; guard < SLICE_ONESHOT_ROUNDS; ++guard) {
        int32_t rem = SLICE_REM_MAX;
        if (magcal_o2_sel_run(&q, a, &rem) != 0) {
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

MAGCAL_NOINLINE int magcal_o2_hsort_run(magcal_o2_hsort_t *h, uint16_t *idx, const float *key,
                                        int32_t *rem)
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
    magcal_o2_hsort_t h;
    unsigned guard;
    magcal_o2_hsort_begin(&h, m);
    for (guard = 0u; guard < SLICE_ONESHOT_ROUNDS; ++guard) {
        int32_t rem = SLICE_REM_MAX;
        if (magcal_o2_hsort_run(&h, idx, key, &rem) != 0) {
            break;
        }
    }
}
