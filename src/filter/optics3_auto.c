/*
 * The automatic parameters of the 3-D OPTICS stage (optics.h "Automatic parameters", docs/optics.md
 * "3-D"; optics3_internal.h): robust centre and radius with clump thinning, one ordering at
 * eps = R (optics3_order.c), the eps' rule over the stored ordering, magcal_optics_auto_params3.
 */
#include <math.h>
#include <string.h>

#include "magcal/optics.h"
#include "magcal_internal.h"
#include "neighbors.h"

#if MAGCAL_CFG_ENABLE_3D /* whole file: config.h feature switch (optics_core.h inside) */
#include "optics3_internal.h"


/* The record behind the run's workspace (pointer-aligned inside the 4-aligned workspace; the
 * caller has checked work_len >= MAGCAL_OPTICS3_FILTER_WORKSPACE_LEN(n) before it is written). */
magcal_o3_auto_t *magcal_o3_auto_record(uint8_t *w, size_t n)
{
    uint8_t *p = w + MAGCAL_OPTICS3_FILTER_RUN_OFFSET_(n) + MAGCAL_OPTICS3_WORKSPACE_LEN(n);
    const size_t mis = magcal_misalign(p, sizeof(void *));
    return (magcal_o3_auto_t *)(void *)(p + ((mis == 0u) ? 0u : (sizeof(void *) - mis)));
}

/* Bit i of the representatives' bits. */
static unsigned rep_bit(const uint8_t *rep, size_t i)
{
    return ((unsigned)rep[i >> 3] >> (i & 7u)) & 1u;
}

static uint8_t *run_ws(magcal_o3s_t *s)
{
    uint8_t *w = s->w;
    return w + MAGCAL_OPTICS3_FILTER_RUN_OFFSET_(s->n);
}

/* The representatives' bits (thinning), behind its key float[n] and idx uint16[n] scratch. */
static uint8_t *rep_bits(magcal_o3s_t *s)
{
    return run_ws(s) + 6u * s->n;
}

/* ---- robust centre and radius (resumable) ---------------------------------------------------
 * Coordinate medians, R = median distance over the counted points (all, or the representatives);
 * passes after the first use only the points within AUTO3_TRIM R of the previous centre (a far
 * cluster cannot drag the centre). a = float[n] at the workspace's start. */
static void rc3_begin(magcal_o3_rc_t *q, uint8_t use_rep)
{
    (void)memset(q, 0, sizeof *q);
    q->rad = INFINITY;
    q->lim2 = INFINITY;
    q->use_rep = use_rep;
}

/* Returns 1 when done (*st MAGCAL_OK with q->cen, q->rad; or MAGCAL_ERR_DEGENERATE), 0 paused. */
static MAGCAL_NOINLINE int rc3_run(magcal_o3_rc_t *q, magcal_o3s_t *s, magcal_status_t *st, int32_t *rem)
{
    float *a = (float *)(void *)s->w;
    const uint8_t *rep = rep_bits(s);
    const magcal_vec3_t *pts = s->pts;
    const size_t n = s->n;
    int done = 0;
    while (*rem > 0 && done == 0) {
        if (q->st == 0u) { /* gather a coordinate (axis 0..2) or a distance (axis 3) */
            size_t i = q->i;
            size_t k = q->k;
            int32_t r = *rem;
            while (i < n && r > 0) {
                if ((q->use_rep == 0u || rep_bit(rep, i) != 0u) &&
                    (q->lim2 == INFINITY || magcal_o3_dist2(&pts[i], &q->cen) <= q->lim2)) {
                    if (q->axis == 3u) {
                        CHARGE3(r, W3_RAD);
                        a[k] = sqrtf(magcal_o3_dist2(&pts[i], &q->nc));
                    } else {
                        CHARGE3(r, W3_GATHER);
                        a[k] = q->axis == 0u ? pts[i].x : (q->axis == 1u ? pts[i].y : pts[i].z);
                    }
                    ++k;
                } else {
                    CHARGE3(r, W3_GATHER);
                }
                ++i;
            }
            *rem = r;
            q->i = (uint16_t)i;
            q->k = (uint16_t)k;
            if (i < n) {
                return 0;
            }
            if (q->axis == 0u && k < AUTO3_MIN_N) {
                done = 1; /* keep the previous estimate */
            } else {
                magcal_o2_sel_begin(&q->sel, k, k / 2u);
                q->st = 1u;
            }
        } else {
            const size_t k = q->k;
            if (magcal_o2_sel_run(&q->sel, a, rem) == 0) {
                return 0;
            }
            q->i = 0u;
            q->k = 0u;
            q->st = 0u;
            if (q->axis == 0u) {
                q->nc.x = a[k / 2u];
            } else if (q->axis == 1u) {
                q->nc.y = a[k / 2u];
            } else if (q->axis == 2u) {
                q->nc.z = a[k / 2u];
            } else {
                q->cen = q->nc;
                q->rad = a[k / 2u];
                if (!(q->rad > 0.0f) || !magcal_isfinite_f(q->rad) || magcal_nbr_eps_ok(q->rad) == 0) {
                    *st = MAGCAL_ERR_DEGENERATE;
                    return 1;
                }
                q->pass++;
                if (q->pass > AUTO3_TRIM_PASSES) {
                    done = 1;
                }
                q->lim2 = (AUTO3_TRIM * q->rad) * (AUTO3_TRIM * q->rad);
            }
            q->axis = (uint8_t)((q->axis + 1u) & 3u);
        }
    }
    if (done == 0) {
        return 0;
    }
    *st = (q->rad == INFINITY) ? MAGCAL_ERR_DEGENERATE : MAGCAL_OK;
    return 1;
}
/* Cell side factor for n samples: 1 up to AUTO3_THIN_N, then sqrt(AUTO3_THIN_N / n) (a shell
 * has (4 pi R^2) / h^2 cells: the shell keeps its majority of representatives at every n). */
static float thin_scale3(size_t n)
{
    return n > AUTO3_THIN_N ? sqrtf((float)AUTO3_THIN_N / (float)n) : 1.0f;
}

/* Cell coordinate of v / h, clamped to +-AUTO3_CELL_HALF (far points share the border cells). */
static float cell3(float v, float h)
{
    const float lim = (float)AUTO3_CELL_HALF;
    float u = floorf(v / h);
    u = u < -lim ? -lim : (u > lim - 1.0f ? lim - 1.0f : u);
    return u + lim;
}

/*
 * Thinning: one representative (lowest index) per cubic cell of side q->h around c, as bits in
 * rep (n/8 bytes), so a rest phase (noise around one point) counts once. Scratch in the run
 * workspace: key float[n], idx uint16[n]. Resumable per point and per sift; q->m counts the
 * representatives. Returns 1 when done, 0 paused.
 */
static void th_begin(magcal_o3_th_t *q, float h)
{
    (void)memset(q, 0, sizeof *q);
    q->h = h;
}

static MAGCAL_NOINLINE int th_run(magcal_o3_th_t *q, magcal_o3s_t *s, const magcal_vec3_t *c, int32_t *rem)
{
    const float side = 2.0f * (float)AUTO3_CELL_HALF;
    const magcal_vec3_t *pts = s->pts;
    const size_t n = s->n;
    float *key = (float *)(void *)run_ws(s);
    uint16_t *idx = (uint16_t *)(void *)(run_ws(s) + 4u * n);
    uint8_t *rep = rep_bits(s);
    size_t i = q->i;
    int32_t r = *rem;
    if (q->st == 0u) {
        while (i < n && r > 0) {
            CHARGE3(r, W3_KEY);
            key[i] = (cell3(pts[i].x - c->x, q->h) * side + cell3(pts[i].y - c->y, q->h)) * side +
                     cell3(pts[i].z - c->z, q->h);
            idx[i] = (uint16_t)i;
            ++i;
        }
        if (i < n) {
            q->i = (uint16_t)i;
            *rem = r;
            return 0;
        }
        (void)memset(rep, 0, (n + 7u) / 8u);
        magcal_o2_hsort_begin(&q->hs, n);
        q->st = 1u;
        q->i = 0u;
        i = 0u;
    }
    if (q->st == 1u) {
        if (r <= 0 || magcal_o2_hsort_run(&q->hs, idx, key, &r) == 0) {
            *rem = r;
            return 0;
        }
        q->st = 2u;
    }
    while (i < n && r > 0) {
        CHARGE3(r, W3_MARK);
        if (i == 0u || key[idx[i]] != key[idx[i - 1u]]) {
            const unsigned p = idx[i];
            rep[p >> 3] = (uint8_t)(rep[p >> 3] | (1u << (p & 7u)));
            q->m++;
        }
        ++i;
    }
    q->i = (uint16_t)i;
    *rem = r;
    return (i < n) ? 0 : 1;
}

/*
 * One probe of the eps' rule, per point of the stored ordering: band representatives in the
 * largest cluster of ExtractDBSCAN at eps' = t->e (4.3): clusters start at a point with reach >
 * eps' and core <= eps' and collect every later point with reach <= eps' (noise points in
 * between do not end them). Returns 1 when done (the count in t->pbest), 0 paused.
 */
static int probe_run(magcal_o3_tail_t *t, const magcal_o3_auto_t *au, int32_t *rem)
{
    const float eps_prime = t->e;
    size_t k = t->i;
    size_t best = t->pbest;
    size_t cur = t->pcur;
    int32_t r = *rem;
    while (k < au->n && r > 0) {
        const size_t p = au->order[k];
        const float d2 = magcal_o3_dist2(&au->pts[p], &au->cen);
        size_t in_band = 0u;
        CHARGE3(r, W3_BAND);
        if (d2 >= au->lo2 && d2 <= au->hi2 && rep_bit(au->rep, p) != 0u) {
            in_band = 1u; /* a representative in the band: a rest phase counts once */
        }
        if (au->reach[p] > eps_prime) {
            if (au->core[p] <= eps_prime) {
                best = cur > best ? cur : best;
                cur = in_band;
                t->started = 1u;
            }
        } else if (t->started != 0u) {
            cur += in_band;
        } else {
            /* not reached: the first point has reach = inf */
        }
        ++k;
    }
    *rem = r;
    t->i = (uint16_t)k;
    t->pcur = (uint16_t)cur;
    t->pbest = (uint16_t)(cur > best ? cur : best);
    if (k < au->n) {
        t->pbest = (uint16_t)best;
        return 0;
    }
    return 1;
}

static void probe_begin(magcal_o3_tail_t *t, float e)
{
    t->e = e;
    t->i = 0u;
    t->pbest = 0u;
    t->pcur = 0u;
    t->started = 0u;
}

/* Count the band points (all, or the representatives) within *rem: 1 when done (t->m). */
static int band_run(magcal_o3s_t *s, int use_rep, int32_t *rem)
{
    const magcal_o3_auto_t *au = s->au;
    const uint8_t *rep = rep_bits(s);
    size_t i = s->t.i;
    size_t m = s->t.m;
    int32_t r = *rem;
    while (i < s->n && r > 0) {
        const float d2 = magcal_o3_dist2(&s->pts[i], &au->cen);
        CHARGE3(r, W3_BAND);
        if (d2 >= au->lo2 && d2 <= au->hi2 && (use_rep == 0 || rep_bit(rep, i) != 0u)) {
            ++m;
        }
        ++i;
    }
    *rem = r;
    s->t.i = (uint16_t)i;
    s->t.m = (uint16_t)m;
    return (i < s->n) ? 0 : 1;
}

/* The next eps' probe, or the end of the rule: the smallest eps' (geometric bisection over
 * [R/256, R], AUTO3_BISECT steps) whose largest cluster holds 75 % of the band, times
 * AUTO3_SAFETY; R when the bulk never connects within R. Returns 1 when eps' is decided. */
static int probe_next(magcal_o3s_t *s)
{
    magcal_o3_tail_t *t = &s->t;
    unsigned ok = 0u;
    int fin = 0;
    float e = t->hi;
    if (t->pbest >= t->target) {
        ok = 1u;
    }
    if (t->bis == 0u) {
        if (ok == 0u) {
            fin = 1; /* the bulk never connects within R: keep the largest cluster at R */
        }
    } else if (t->bis == 1u) {
        if (ok != 0u) {
            fin = 1;
        }
        e = t->lo;
    } else {
        if (ok != 0u) { /* invariant: lo fails, hi connects */
            t->hi = t->e;
        } else {
            t->lo = t->e;
        }
        if (t->bis >= AUTO3_BISECT + 1u) {
            fin = 1;
            e = AUTO3_SAFETY * t->hi;
        }
    }
    t->bis++;
    if (fin != 0) {
        if (e > AUTO3_MAX_REL * s->rad) {
            e = AUTO3_MAX_REL * s->rad;
        }
        s->au->eps_prime = e;
        return 1;
    }
    probe_begin(t, (t->bis == 1u) ? t->lo : sqrtf(t->lo * t->hi));
    return 0;
}

/* After the thinning rounds: the shell band around the centre found, then its count. */
static int after_rounds(magcal_o3s_t *s)
{
    magcal_o3_auto_t *au = s->au;
    const float lo = s->rad - AUTO3_BAND * s->rad;
    const float hi = s->rad + AUTO3_BAND * s->rad;
    if (s->t.have == 0u) {
        s->status = (int32_t)MAGCAL_ERR_DEGENERATE;
        return 1;
    }
    au->pts = s->pts;
    au->n = s->n;
    au->cen = s->cen;
    au->rad = s->rad;
    au->lo2 = lo * lo;
    au->hi2 = hi * hi;
    s->t.i = 0u;
    s->t.m = 0u;
    s->phase = (uint8_t)O3S_BAND;
    return 0;
}

/* The ordering at eps = R (it holds every extraction at eps' <= R), brute force: at eps = R the
 * 3x3x3 block covers the whole shell, and the brute reach pass shrinks with the unprocessed list
 * (filter at n = 1000: 43.7 M -> 36.7 M host instructions). Layout of w: reach float[n] |
 * core float[n] | order uint16[n] | run workspace. */
void magcal_o3_auto_order_begin(magcal_o3s_t *s)
{
    magcal_o3_ctx_t *c;
    uint8_t *w = s->w;
    s->use.eps = AUTO3_MAX_REL * s->rad;
    s->use.min_pts = (uint16_t)AUTO3_MIN_PTS;
    s->use.neighbors = MAGCAL_NEIGHBORS_BRUTE;
    c = magcal_o3_ctx_setup(&s->use, s->pts, s->n, run_ws(s));
    c->oc.reach = (float *)(void *)w;
    c->oc.core = (float *)(void *)(w + 4u * s->n);
    c->oc.order = (uint16_t *)(void *)(w + 8u * s->n);
    s->au->reach = c->oc.reach;
    s->au->core = c->oc.core;
    s->au->order = c->oc.order;
    s->c = c;
    magcal_o3_ord_begin(&s->u.ord);
}

void magcal_o3_auto_ordered(magcal_o3s_t *s)
{
    s->au->neighbors = s->c->use_grid != 0 ? MAGCAL_NEIGHBORS_GRID : MAGCAL_NEIGHBORS_BRUTE;
    s->au->eps = s->use.eps;
    /* the representatives again (the run used this memory), counted in the band */
    th_begin(&s->u.th, s->rad * AUTO3_THIN_REL * thin_scale3(s->n));
    s->phase = (uint8_t)O3S_THIN2;
}

/* After a robust centre (O3S_RC0: of all points; O3S_RC: of a round's representatives): keep it
 * when it is good, then the next thinning round or the band. 1 when the rule has failed. */
static MAGCAL_NOINLINE int auto_centred(magcal_o3s_t *s, magcal_status_t st)
{
    magcal_o3_tail_t *t = &s->t;
    int fin = 0;
    if (st == MAGCAL_OK) {
        t->have = 1u;
        s->cen = s->u.rc.cen;
        s->rad = s->u.rc.rad;
        if (s->phase == O3S_RC) {
            t->h = s->rad * AUTO3_THIN_REL * thin_scale3(s->n);
        }
    } else if (s->phase == O3S_RC0) {
        s->cen = s->pts[0]; /* more than half the samples identical: the first grid's origin */
    } else {
        /* this round's centre failed: keep the previous */
    }
    if (s->phase == O3S_RC) {
        t->round++;
    }
    if (t->round >= AUTO3_THIN_ROUNDS) {
        fin = after_rounds(s);
    } else {
        th_begin(&s->u.th, t->h);
        s->phase = (uint8_t)O3S_THIN;
    }
    return fin;
}

/* After a thinning round: the centre of its representatives when there are enough, else the
 * next round. 1 when the rule has failed. */
static MAGCAL_NOINLINE int auto_thinned(magcal_o3s_t *s)
{
    magcal_o3_tail_t *t = &s->t;
    int fin = 0;
    if (s->u.th.m >= AUTO3_MIN_N) {
        rc3_begin(&s->u.rc, 1u);
        s->phase = (uint8_t)O3S_RC;
    } else {
        t->round++;
        if (t->round >= AUTO3_THIN_ROUNDS) {
            fin = after_rounds(s);
        } else {
            th_begin(&s->u.th, t->h);
        }
    }
    return fin;
}

/* The rule's band counts and eps' probes (magcal_o3_auto_step's other phases). */
static MAGCAL_NOINLINE int auto_pass(magcal_o3s_t *s, int32_t *rem)
{
    magcal_o3_tail_t *t = &s->t;
    int fin = 0;
    switch (s->phase) {
    case O3S_BAND:
        if (band_run(s, 0, rem) != 0) {
            if (t->m < AUTO3_MIN_BAND) {
                s->status = (int32_t)MAGCAL_ERR_DEGENERATE;
                fin = 1;
            } else {
                s->c = NULL; /* the ordering's setup: the driver's (magcal_o3_auto_order_begin) */
                s->phase = (uint8_t)O3S_ORDER;
            }
        }
        break;
    case O3S_BANDREP:
        if (band_run(s, 1, rem) != 0) {
            t->target = (uint16_t)(t->m - t->m / 4u); /* 75 % of the band */
            t->lo = AUTO3_MIN_REL * s->rad;
            t->hi = AUTO3_MAX_REL * s->rad;
            t->bis = 0u;
            probe_begin(t, t->hi);
            s->phase = (uint8_t)O3S_PROBE;
        }
        break;
    default: /* O3S_PROBE */
        if (probe_run(t, s->au, rem) != 0 && probe_next(s) != 0) {
            fin = 1; /* s->status stays MAGCAL_IN_PROGRESS: the filter's tail is next */
        }
        break;
    }
    return fin;
}

/*
 * The rule of optics.h, resumable: the pair scale S (median distance of AUTO3_PAIRS pseudo-random
 * pairs: a clump of up to 70 % of the samples cannot shrink it), robust centre and R with each
 * rest phase counted once (thinning cells of S / 32 first, then of R / 16), one OPTICS run with
 * eps = R (ordering, reach and core stored in w), then the smallest eps' (geometric bisection over
 * [R/256, R], 20 steps: 5e-6 relative) whose largest cluster holds 75 % of the shell band, times
 * AUTO3_SAFETY.
 */
int magcal_o3_auto_step(magcal_o3s_t *s, int32_t *rem)
{
    magcal_o3_tail_t *t = &s->t;
    float *a = (float *)(void *)s->w;
    int fin = 0;
    /* the ordering (O3S_ORDER) is the driver's: back to it there */
    while (*rem > 0 && fin == 0 && s->phase != (uint8_t)O3S_ORDER) {
        if (s->phase == O3S_PAIRS) {
            const size_t n = s->n;
            const size_t m = n < AUTO3_PAIRS ? n : AUTO3_PAIRS;
            size_t k = t->i;
            /* cppcheck-suppress knownConditionTrueFalse ; false positive: k = t->i < m until the pairs are done (m = min(n, pairs) >= 16) */
            while (k < m && *rem > 0) {
                const size_t i = (size_t)(magcal_ocore_rand(&t->rng) % (uint32_t)n);
                const size_t j = (size_t)(magcal_ocore_rand(&t->rng) % (uint32_t)n);
                CHARGE3(*rem, W3_PAIR);
                a[k] = sqrtf(magcal_o3_dist2(&s->pts[i], &s->pts[j]));
                ++k;
            }
            t->i = (uint16_t)k;
            /* cppcheck-suppress knownConditionTrueFalse ; false positive: the loop above pauses with k < m when the budget runs out */
            if (k >= m) {
                t->m = (uint16_t)m;
                magcal_o2_sel_begin(&s->u.sel, m, m / 2u);
                s->phase = (uint8_t)O3S_PAIRSEL;
            }
        } else if (s->phase == O3S_PAIRSEL) {
            if (magcal_o2_sel_run(&s->u.sel, a, rem) != 0) {
                t->h = a[t->m / 2u] * AUTO3_THIN_PAIR; /* coarse: out of any clump first */
                if (!(t->h > 0.0f) || !magcal_isfinite_f(t->h)) {
                    s->status = (int32_t)MAGCAL_ERR_DEGENERATE;
                    fin = 1;
                } else {
                    t->have = 0u;
                    t->round = 0u;
                    s->cen.x = 0.0f;
                    s->cen.y = 0.0f;
                    s->cen.z = 0.0f;
                    s->rad = INFINITY;
                    rc3_begin(&s->u.rc, 0u);
                    s->phase = (uint8_t)O3S_RC0;
                }
            }
        } else if (s->phase == O3S_RC0 || s->phase == O3S_RC) {
            magcal_status_t st = MAGCAL_OK;
            if (rc3_run(&s->u.rc, s, &st, rem) != 0) {
                fin = auto_centred(s, st);
            }
        } else if (s->phase == O3S_THIN) {
            if (th_run(&s->u.th, s, &s->cen, rem) != 0) {
                fin = auto_thinned(s);
            }
        } else if (s->phase == O3S_THIN2) {
            if (th_run(&s->u.th, s, &s->cen, rem) != 0) {
                s->au->rep = rep_bits(s);
                t->i = 0u;
                t->m = 0u;
                s->phase = (uint8_t)O3S_BANDREP;
            }
        } else {
            fin = auto_pass(s, rem);
        }
    }
    if (fin != 0) {
        s->phase = (uint8_t)O3S_AUTO_DONE;
    }
    return fin;
}

#endif /* MAGCAL_CFG_ENABLE_3D */
