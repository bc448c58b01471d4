/*
 * Robust centre and radius of the ring (optics.h rule step 1), clump thinning and the thinned
 * centre of the 2-D automatic parameters, and the thinning behind magcal_optics_thin(): every
 * pass resumable per point (the slice contract of optics.h). States in optics_slice.h.
 */
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "optics_core.h"
#include "optics_slice.h"

static void rc_begin(magcal_o2_rc_t *c)
{
    c->cx = 0.0f;
    c->cy = 0.0f;
    c->rad = INFINITY;
    c->pass = 0u;
    c->st = (uint8_t)RC_PASS;
}

/* Returns 1 when done (*st: MAGCAL_OK with cr = {cx, cy, R}, or MAGCAL_ERR_DEGENERATE with cr
 * untouched), 0 when the budget ran out. use: NULL (every point) or the thinning flags. */
static MAGCAL_NOINLINE int rc_run(magcal_o2_rc_t *c, const magcal_vec2_t *pts, size_t n,
                                  const uint8_t *use, float *a, float cr[3], magcal_status_t *st,
                                  int32_t *rem)
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
            magcal_o2_sel_begin(&c->sel, k, k / 2u);
            c->st = (uint8_t)RC_SELECT;
        }
        if (c->st == (uint8_t)RC_SELECT) {
            if (*rem <= 0 || magcal_o2_sel_run(&c->sel, a, rem) == 0) {
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

/* floorf(x) clamped to [-lim, lim - 1] (lim a whole number), without libm's floorf (148 B on the
 * M4F): the clamp first, then truncation toward zero, one down for a negative non-whole x. The
 * same value as the floor-then-clamp for every finite x (the points are checked finite first). */
static float th_cell(float x, float lim)
{
    float q;
    if (!(x < lim - 1.0f)) {
        return lim - 1.0f;
    }
    if (x < -lim) {
        return -lim;
    }
    q = (float)(int32_t)x; /* |x| <= lim < 2^23: exact */
    return (q > x) ? (q - 1.0f) : q;
}

/* TH_KEYS from point i: each point's cell key (own frame: its floats stay off the sort's path).
 * Returns the next point. */
static MAGCAL_NOINLINE size_t th_keys(magcal_o2_th_t *t, const magcal_vec2_t *pts, size_t n,
                                      const float cr[3], uint8_t *w, const uint8_t *use, size_t i0,
                                      int32_t *rem)
{
    const float h = t->h;
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
        const float u = th_cell((pts[i].x - cr[0]) / h, lim);
        const float v = th_cell((pts[i].y - cr[1]) / h, lim);
        key[i] = (u + lim) * (2.0f * lim) + (v + lim);
    }
    if (i >= n) { /* every key: the sort next */
        magcal_o2_hsort_begin(&t->hs, n);
        t->st = (uint8_t)TH_SORT;
    }
    *rem = r;
    return i;
}

/* TH_CAP, TH_MARK, TH_MAXRUN from point i: the passes over the sorted keys, run = rank of a point
 * in its cell (0: the first). TH_CAP counts the candidates (m) and the occupied cells, TH_MARK
 * flags the representatives (count m) and the first cap of each cell, TH_MAXRUN takes the
 * largest number of candidates in one cell (best); at the end of a stage, the next. Own frame:
 * the heapsort's path stays as it was. Returns the next point. */
static MAGCAL_NOINLINE size_t th_pass(magcal_o2_th_t *t, uint8_t *w, size_t n, size_t i0,
                                      int32_t *rem)
{
    const float *key = (const float *)(void *)w;
    const uint16_t *idx = (const uint16_t *)(void *)(w + 4u * n);
    uint8_t *rep = w + AUTO_REP_OFF(n);
    size_t i = i0;
    int32_t r = *rem;
    const uint8_t st = t->st;
    size_t run = t->run;
    size_t m = t->m;
    size_t cells = t->cells;
    size_t best = t->best;
    for (; i < n && r > 0; ++i) {
        const float k = key[idx[i]];
        run = (i == 0u || k != key[idx[i - 1u]]) ? 0u : run + 1u;
        if (k < THIN_INVALID) {
            if (st == (uint8_t)TH_CAP) {
                ++m;
                cells += (run == 0u) ? 1u : 0u;
            } else if (st == (uint8_t)TH_MARK) {
                if (run == 0u) {
                    rep[idx[i]] = AUTO_REP;
                    ++m;
                }
                if (run < t->cap) {
                    rep[idx[i]] = (uint8_t)(rep[idx[i]] | AUTO_CAPPED);
                }
            } else if (run + 1u > best) {
                best = run + 1u;
            } else {
                /* TH_MAXRUN: not the largest so far */
            }
        }
        CHARGE(r, W_CAP);
    }
    t->run = (uint16_t)run;
    t->m = (uint16_t)m;
    t->cells = (uint16_t)cells;
    t->best = (uint16_t)best;
    if (i >= n) { /* the stage is complete: the next one starts at point 0 */
        if (st == (uint8_t)TH_CAP) {
            t->cap = (uint16_t)(cells == 0u ? 0u : (m + cells - 1u) / cells);
            t->m = 0u;
        }
        /* the next stage */
        t->st = (uint8_t)((st == (uint8_t)TH_MAXRUN) ? TH_DONE : (unsigned)st + 1u);
    }
    *rem = r;
    return i;
}

/* Returns 1 when done up to stage `last` (TH_MARK or TH_MAXRUN), 0 when the budget ran out. */
MAGCAL_NOINLINE int magcal_o2_th_run(magcal_o2_th_t *t, const magcal_vec2_t *pts, size_t n,
                                     const float cr[3], uint8_t *w, const uint8_t *use,
                                     unsigned last, int32_t *rem)
{
    float *key = (float *)(void *)w;
    uint16_t *idx = (uint16_t *)(void *)(w + 4u * n);
    size_t i = t->i;
    int32_t r = *rem;
    /* cppcheck-suppress misra-c2012-15.4 ; deviation D13: a resumable loop leaves at its pause point and at its phase end */
    while (t->st <= last) {
        if (t->st == (uint8_t)TH_KEYS) {
            i = th_keys(t, pts, n, cr, w, use, i, &r);
            if (i < n) {
                break;
            }
        } else if (t->st == (uint8_t)TH_SORT) {
            if (r <= 0 || magcal_o2_hsort_run(&t->hs, idx, key, &r) == 0) {
                break;
            }
            i = 0u;
            t->st = (uint8_t)TH_CAP;
        } else if (t->st <= (uint8_t)TH_MAXRUN) {
            i = th_pass(t, w, n, i, &r);
            if (i < n) {
                break;
            }
            i = 0u;
        } else {
            break;
        }
    }
    t->i = (uint16_t)i;
    *rem = r;
    return t->st > last ? 1 : 0;
}

/* CE_PAIRS: the pair distances of the pair scale (own frame); 1 when all m are done. */
static MAGCAL_NOINLINE int ce_pairs(magcal_o2_ce_t *c, const magcal_vec2_t *pts, size_t n,
                                    float *a, size_t m, int32_t *rem)
{
    size_t k = c->k;
    int32_t r = *rem;
    uint32_t rng = c->rng;
    for (; k < m && r > 0; ++k) {
        const size_t i = (size_t)(magcal_ocore_rand(&rng) % (uint32_t)n);
        const size_t j = (size_t)(magcal_ocore_rand(&rng) % (uint32_t)n);
        a[k] = magcal_o2_dist(&pts[i], &pts[j]);
        CHARGE(r, W_PAIR);
    }
    c->k = (uint16_t)k;
    c->rng = rng;
    *rem = r;
    return k < m ? 0 : 1;
}

MAGCAL_NOINLINE int magcal_o2_ce_run(magcal_o2_ce_t *c, const magcal_vec2_t *pts, size_t n,
                                     uint8_t *w, float cr[3], magcal_status_t *st, int32_t *rem)
{
    float *a = (float *)(void *)w;
    const size_t m = n < AUTO_PAIRS ? n : AUTO_PAIRS;
    magcal_status_t s2 = MAGCAL_OK;
    if (w == NULL) { /* never (every entry point checks its workspace); stated for the analysers,
                        which see this file-external function as an entry of its own */
        *st = MAGCAL_ERR_NULL;
        return 1;
    }
    for (;;) {
        if (*rem <= 0) {
            return 0;
        }
        switch (c->st) {
        case CE_PAIRS:
            if (ce_pairs(c, pts, n, a, m, rem) == 0) {
                return 0;
            }
            magcal_o2_sel_begin(&c->u.sel, m, m / 2u);
            c->st = (uint8_t)CE_PAIR_SEL;
            break;
        case CE_PAIR_SEL:
            if (magcal_o2_sel_run(&c->u.sel, a, rem) == 0) {
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
            magcal_o2_th_begin(&c->u.th, c->h);
            c->st = (uint8_t)CE_THIN;
            break;
        case CE_THIN:
        case CE_RC:
            /* a round: the thinning, then the centre of its representatives (none when there are
             * too few); the next round thins again with the new cell side */
            if (c->st == (uint8_t)CE_THIN) {
                if (magcal_o2_th_run(&c->u.th, pts, n, cr, w, NULL, (unsigned)TH_MARK, rem) == 0) {
                    return 0;
                }
                if (c->u.th.m >= AUTO_MIN_N) {
                    rc_begin(&c->u.rc);
                    c->st = (uint8_t)CE_RC;
                    break;
                }
            } else {
                if (rc_run(&c->u.rc, pts, n, w + AUTO_REP_OFF(n), a, cr, &s2, rem) == 0) {
                    return 0;
                }
                if (s2 == MAGCAL_OK) {
                    c->have = 1u;
                    c->h = cr[2] * AUTO_THIN_REL * magcal_o2_thin_scale(n);
                }
            }
            c->round++;
            c->st = (uint8_t)CE_DONE;
            if (c->round < AUTO_THIN_ROUNDS) {
                magcal_o2_th_begin(&c->u.th, c->h);
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

