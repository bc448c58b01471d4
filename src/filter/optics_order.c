/*
 * The 2-D OPTICS ordering loop (algorithms.md 4.2, 4.3) with the on-the-fly ExtractDBSCAN of the
 * filter: neighbour build, start scan, core distance, reach updates, seed pops, every loop
 * resumable per candidate (the slice contract of optics.h). The dimension-free parts are
 * optics_core.h / optics_core_update.h (shared with optics3.c); the state is in optics_slice.h.
 */
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "neighbors.h"
#include "optics_core.h"
#include "optics_core_update.h"
#include "optics_slice.h"

/* Start PROCESS(p): mark p, query its candidates; the step continues in pass 1. */
static void ord_process(magcal_o2_ord_t *o, size_t p, magcal_nbr_ranges_t *rg)
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
static MAGCAL_NOINLINE void ord_core_done(magcal_o2_ord_t *o, const magcal_nbr_ranges_t *rg)
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

/* Pass 1 of PROCESS(p): core distance (MinPts smallest d^2 in the insertion buffer), lim = m + 1
 * (the count saturates at m: every candidate). START_CORE (p = s): does s have MinPts points
 * within eps? lim = m: the candidates within eps are counted (the buffer is not touched) and the
 * scan stops after the m-th. One range walk for both (issue 14: it was written twice). */
static MAGCAL_NOINLINE void ord_scan_core(magcal_o2_ord_t *o, const magcal_nbr_ranges_t *rg,
                                          size_t p, size_t lim, int32_t *rem)
{
    const magcal_vec2_t *pts = o->nb.pts;
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
                if (lim > m) {
                    cnt = magcal_ocore_best_insert(best, cnt, m, d2);
                } else {
                    ++cnt; /* the start-core count: a count only, the buffer is not written */
                    if (cnt >= lim) {
                        break; /* its m-th (tested only where cnt grows) */
                    }
                }
            }
            CHARGE(r, W_CAND);
        }
        if (k < end) {
            if (cnt >= lim) { /* the count's m-th candidate was visited; PROCESS(s) follows */
                CHARGE(r, W_CAND);
                ++k;
            }
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
static MAGCAL_NOINLINE void ord_scan_reach(magcal_o2_ord_t *o, const magcal_nbr_ranges_t *rg,
                                           int32_t *rem)
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
static MAGCAL_NOINLINE void ord_scan_live(magcal_o2_ord_t *o, int32_t *rem)
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
static MAGCAL_NOINLINE int ord_scan_min(magcal_o2_ord_t *o, int32_t *rem)
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
static void ord_outer(magcal_o2_ord_t *o, magcal_nbr_ranges_t *rg, size_t *rg_p, int32_t *rem)
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
MAGCAL_NOINLINE int magcal_o2_ord_run(magcal_o2_ord_t *o, int32_t *rem)
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
                magcal_ocore_start_point(oc, i);
                CHARGE(r, W_INIT);
            }
            o->u.sc.s = (uint16_t)i;
            if (i < n) {
                break;
            }
            magcal_ocore_start_finish(oc, n);
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
            ord_scan_core(o, &rg, o->u.sc.s, oc->min_pts, &r);
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
            ord_scan_core(o, &rg, o->u.sc.p, (size_t)oc->min_pts + 1u, &r);
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

