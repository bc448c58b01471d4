/*
 * Resumable primitives of the consensus stage (consensus_internal.h): Hoare quickselect and shell
 * sort as state machines (one visit per scan step, swap or move), the residual loop of a model
 * over the samples and one chunk of an ellipse fit slice.
 */
#include <math.h>
#include <stddef.h>
#include <stdint.h>

#include "consensus_internal.h"

/* Visits of weight w the rest of the budget pays for (at most left); at least one on a step's
 * first visit (used == 0). 0: stop this step. */
static size_t cons_visits(uint32_t budget, uint32_t used, uint32_t w, size_t left)
{
    uint32_t v = (used < budget) ? (budget - used) / w : 0u;
    if (v == 0u && used == 0u) {
        v = 1u;
    }
    return ((size_t)v < left) ? (size_t)v : left;
}

size_t magcal_cons_chunk(uint32_t budget, uint32_t *used, uint32_t w, size_t pos, size_t len)
{
    size_t v = cons_visits(budget, *used, w, len - pos);
    if (v == 0u && pos < len) {
        *used = (*used > budget) ? *used : budget;
    }
    *used += (uint32_t)v * w;
    return pos + v;
}

int magcal_cons_pay(uint32_t budget, uint32_t *used, uint32_t w)
{
    if (cons_visits(budget, *used, w, 1u) == 0u) {
        return 0;
    }
    *used += w;
    return 1;
}

void magcal_cons_sel_init(magcal_cons_sel_t *q, float *a, size_t n, size_t k)
{
    q->a = a;
    q->n = n;
    q->k = k;
    q->lo = 0u;
    q->hi = n - 1u;
    q->guard = 0u;
    q->ph = 0u;
}

/* Run the selection within the budget; 1 when done (q->val). The phases are the one-shot loop
 * nest: 0 outer test, 1 inner test, 2 scan i up, 3 scan j down, 4 swap, 5 partition decision.
 * Each scan step and each swap or partition round is one visit; the indices live in locals
 * during the call (the scans are as tight as the one-shot loop's). */
int magcal_cons_sel_run(magcal_cons_sel_t *q, uint32_t budget, uint32_t *used)
{
    float *a = q->a;
    const size_t n = q->n;
    const size_t k = q->k;
    float pivot = q->pivot;
    size_t lo = q->lo;
    size_t hi = q->hi;
    size_t i = q->i;
    size_t j = q->j;
    size_t s = q->s;
    size_t guard = q->guard;
    size_t inner = q->inner;
    const size_t start = cons_visits(budget, *used, CONS_W_SEL, (size_t)-1);
    size_t left = start;
    uint8_t ph = q->ph;
    int done = 0;
    while (left > 0u && done == 0) {
        if (ph == 2u) { /* the scans first: most visits are theirs */
            while (left > 0u && s < n && a[i] < pivot) {
                ++i;
                ++s;
                --left;
            }
            if (left > 0u) {
                s = 0u;
                ph = 3u;
            }
        } else if (ph == 3u) {
            while (left > 0u && s < n && a[j] > pivot) {
                --j;
                ++s;
                --left;
            }
            if (left > 0u) {
                ph = 4u;
            }
        } else if (ph == 4u) {
            --left;
            ph = 1u;
            if (i <= j) {
                float t = a[i];
                a[i] = a[j];
                a[j] = t;
                ++i;
                if (j == 0u) {
                    ph = 5u;
                    continue;
                }
                --j;
            }
            ++inner;
        } else if (ph == 1u) {
            if (inner <= n && i <= j) {
                s = 0u;
                ph = 2u;
            } else {
                ph = 5u;
            }
        } else if (ph == 0u) {
            --left;
            if (!(guard < n + 1u && lo < hi)) {
                done = 1;
            } else {
                pivot = a[lo + (hi - lo) / 2u];
                i = lo;
                j = hi;
                inner = 0u;
                ph = 1u;
            }
        } else {
            --left;
            if (k <= j) {
                hi = j;
            } else if (k >= i) {
                lo = i;
            } else {
                done = 1;
                continue;
            }
            ++guard;
            ph = 0u;
        }
    }
    if (done != 0) {
        q->val = a[k];
    }
    q->pivot = pivot;
    q->lo = lo;
    q->hi = hi;
    q->i = i;
    q->j = j;
    q->s = s;
    q->guard = guard;
    q->inner = inner;
    q->ph = ph;
    *used += (uint32_t)(start - left) * CONS_W_SEL;
    return done;
}

void magcal_cons_sort_init(magcal_cons_sort_t *q, float *key, uint16_t *idx, size_t m)
{
    q->key = key;
    q->idx = idx;
    q->m = m;
    q->g = 0u;
    q->i = 0u;
    q->moving = 0u;
}

/* Run the shell sort within the budget; 1 when done. One visit per move or placement; the
 * positions live in locals during the call. */
int magcal_cons_sort_run(magcal_cons_sort_t *q, uint32_t budget, uint32_t *used)
{
    static const uint16_t gaps[] = {701u, 301u, 132u, 57u, 23u, 10u, 4u, 1u};
    float *key = q->key;
    uint16_t *idx = q->idx;
    const size_t start = cons_visits(budget, *used, CONS_W_SORT, (size_t)-1);
    size_t left = start;
    size_t i = q->i;
    size_t j = q->j;
    float kv = q->kv;
    uint16_t iv = q->iv;
    int done = 0;
    while (left > 0u) {
        size_t gap;
        if (q->g >= sizeof gaps / sizeof gaps[0]) {
            done = 1;
            break;
        }
        gap = gaps[q->g];
        if (q->moving == 0u) {
            i = (i < gap) ? gap : i;
            if (i >= q->m) {
                ++q->g;
                i = 0u;
                continue;
            }
            kv = key[i];
            iv = (idx != NULL) ? idx[i] : 0u;
            j = i;
            q->moving = 1u;
        }
        while (left > 0u && j >= gap && key[j - gap] > kv) {
            key[j] = key[j - gap];
            if (idx != NULL) {
                idx[j] = idx[j - gap];
            }
            j -= gap;
            --left;
        }
        if (left > 0u) {
            key[j] = kv;
            if (idx != NULL) {
                idx[j] = iv;
            }
            q->moving = 0u;
            ++i;
            --left;
        }
    }
    q->i = i;
    q->j = j;
    q->kv = kv;
    q->iv = iv;
    *used += (uint32_t)(start - left) * CONS_W_SORT;
    return done;
}

/* |residual| of samples pos..end-1. The samples are finite (checked first) and the model comes
 * from a successful fit, so a non-finite residual can only be an overflow of a sample
 * astronomically far from the model (|p - c| above ~1e19): it is stored as +Inf, i.e. always an
 * outlier. Returning an error instead made one such sample veto every minimal set. */
static void cons_residuals(const magcal_ellipse_t *e, const magcal_vec2_t *pts, size_t pos,
                           size_t end, float *r)
{
    size_t i;
    for (i = pos; i < end; ++i) {
        float v = magcal_ellipse_residual(e, pts[i]);
        r[i] = magcal_isfinite_f(v) ? fabsf(v) : INFINITY;
    }
}

/* The residual loop of a phase over every sample: 1 when the last chunk is done. */
int magcal_cons_res_loop(magcal_cons_state_t *S, const magcal_ellipse_t *e, uint32_t budget,
                         uint32_t *used)
{
    size_t end = magcal_cons_chunk(budget, used, CONS_W_RES, S->pos, S->n);
    cons_residuals(e, S->pts, S->pos, end, S->res);
    S->pos = end;
    return end == S->n;
}

/* One chunk of a fit slice; CONS_SPENT while it runs, then its status. */
magcal_status_t magcal_cons_fit(magcal_cons_state_t *S, uint32_t budget, uint32_t *used)
{
    magcal_status_t st;
    if (*used != 0u && (*used >= budget || budget - *used < CONS_W_FIT)) {
        return CONS_SPENT;
    }
    st = magcal_ellipse_fit_step(&S->fit, budget - *used);
    *used += S->fit.used_;
    return (st == MAGCAL_IN_PROGRESS) ? CONS_SPENT : st;
}
